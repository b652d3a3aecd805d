"""proposed_ool_lugre_friction_strong: a term proposed by ehas diagnose for /tmp/ow_final_work/ool_lugre_friction_strong/campaign.

F_piston [N] += c_vv·v |v|   with c_vv = -145.3 N s^2/m^2 (95 % CI -263.4 to -27.24)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 5.13 -> 4.77; fit 85.4 % -> 85.9 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolLugreFrictionStrong(Effect):
    name = "proposed_ool_lugre_friction_strong"
    title = "proposed term (piston force)"
    params = (
        Param("f_vv", "N s^2/m^2", 145.308, (0.0, 2906.17),
              "quadratic damping: force per (m/s)^2, signed (fitted: -145.3, 95 % CI -263.4 to -27.24)", typical=(72.6541, 290.617)),
    )
    main_param = "f_vv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_vv·v |v| with c_vv = -145.3 N s^2/m^2 (95 % CI -263.4 to -27.24)'
    signature = 'the residual it was fitted to: v |v|'

    @staticmethod
    def piston_force(v, f_vv):
        return -(f_vv * v * abs(v))
