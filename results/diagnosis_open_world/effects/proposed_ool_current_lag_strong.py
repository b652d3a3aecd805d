"""proposed_ool_current_lag_strong: a term proposed by ehas diagnose for /tmp/ow_final_work/ool_current_lag_strong/campaign.

T_crank [N m] += c_th3·theta^3   with c_th3 = 7.079 N m/rad^3 (95 % CI 4.075 to 10.08)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 8.18 -> 8.09; fit 94.5 % -> 94.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolCurrentLagStrong(Effect):
    name = "proposed_ool_current_lag_strong"
    title = "proposed term (crank torque)"
    params = (
        Param("t_th3", "N m/rad^3", 7.07872, (0.0, 141.574),
              "hardening spring: torque per rad^3 (fitted: 7.079, 95 % CI 4.075 to 10.08)", typical=(3.53936, 14.1574)),
    )
    main_param = "t_th3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_th3·theta^3 with c_th3 = 7.079 N m/rad^3 (95 % CI 4.075 to 10.08)'
    signature = 'the residual it was fitted to: theta^3'

    @staticmethod
    def crank_torque(theta, t_th3):
        return (t_th3 * theta ** 3)
