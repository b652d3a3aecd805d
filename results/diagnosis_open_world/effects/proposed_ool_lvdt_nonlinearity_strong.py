"""proposed_ool_lvdt_nonlinearity_strong: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_lvdt_nonlinearity_strong/campaign.

T_crank [N m] += c_th3·theta^3   with c_th3 = -9.007 N m/rad^3 (95 % CI -13.06 to -4.949)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 3.75 -> 3.73; fit 94.5 % -> 94.6 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolLvdtNonlinearityStrong(Effect):
    name = "proposed_ool_lvdt_nonlinearity_strong"
    title = "proposed term (crank torque)"
    params = (
        Param("t_th3", "N m/rad^3", 9.00673, (0.0, 180.135),
              "hardening spring: torque per rad^3 (fitted: -9.007, 95 % CI -13.06 to -4.949)", typical=(4.50337, 18.0135)),
    )
    main_param = "t_th3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_th3·theta^3 with c_th3 = -9.007 N m/rad^3 (95 % CI -13.06 to -4.949)'
    signature = 'the residual it was fitted to: theta^3'

    @staticmethod
    def crank_torque(theta, t_th3):
        return -(t_th3 * theta ** 3)
