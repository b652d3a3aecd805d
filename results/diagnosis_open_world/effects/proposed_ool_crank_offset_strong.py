"""proposed_ool_crank_offset_strong: a term proposed by ehas diagnose for /tmp/snapA/work/ool_crank_offset_strong/campaign.

T_crank [N m] += c_th3·theta^3   with c_th3 = 27.02 N m/rad^3 (95 % CI 2.383 to 51.65)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 6.29 -> 6.22; fit 89.3 % -> 89.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolCrankOffsetStrong(Effect):
    name = "proposed_ool_crank_offset_strong"
    title = "proposed term (crank torque)"
    params = (
        Param("t_th3", "N m/rad^3", 27.0164, (0.0, 540.327),
              "hardening spring: torque per rad^3 (fitted: 27.02, 95 % CI 2.383 to 51.65)", typical=(13.5082, 54.0327)),
    )
    main_param = "t_th3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_th3·theta^3 with c_th3 = 27.02 N m/rad^3 (95 % CI 2.383 to 51.65)'
    signature = 'the residual it was fitted to: theta^3'

    @staticmethod
    def crank_torque(theta, t_th3):
        return (t_th3 * theta ** 3)
