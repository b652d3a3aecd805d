"""proposed_ool_supply_line_loss_strong: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_supply_line_loss_strong/campaign.

F_piston [N] += c_vv·v |v|   with c_vv = -9894 N s^2/m^2 (95 % CI -9947 to -9842)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 15.1 -> 8.1; fit 80.8 % -> 68.8 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolSupplyLineLossStrong(Effect):
    name = "proposed_ool_supply_line_loss_strong"
    title = "proposed term (piston force)"
    params = (
        Param("f_vv", "N s^2/m^2", 9894.05, (0.0, 197881),
              "quadratic damping: force per (m/s)^2, signed (fitted: -9894, 95 % CI -9947 to -9842)", typical=(4947.03, 19788.1)),
    )
    main_param = "f_vv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_vv·v |v| with c_vv = -9894 N s^2/m^2 (95 % CI -9947 to -9842)'
    signature = 'the residual it was fitted to: v |v|'

    @staticmethod
    def piston_force(v, f_vv):
        return -(f_vv * v * abs(v))
