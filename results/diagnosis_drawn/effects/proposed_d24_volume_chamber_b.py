"""proposed_d24_volume_chamber_b: a term proposed by ehas diagnose for /tmp/dr1_work/d24_volume@chamber_b/campaign.

T_crank [N m] += c_th3·theta^3   with c_th3 = -34.43 N m/rad^3 (95 % CI -39.36 to -29.51)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 4.27 -> 3.77; fit 81.7 % -> 82.0 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD24VolumeChamberB(Effect):
    name = "proposed_d24_volume_chamber_b"
    title = "proposed term (crank torque)"
    params = (
        Param("t_th3", "N m/rad^3", 34.4327, (0.0, 688.653),
              "hardening spring: torque per rad^3 (fitted: -34.43, 95 % CI -39.36 to -29.51)", typical=(17.2163, 68.8653)),
    )
    main_param = "t_th3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_th3·theta^3 with c_th3 = -34.43 N m/rad^3 (95 % CI -39.36 to -29.51)'
    signature = 'the residual it was fitted to: theta^3'

    @staticmethod
    def crank_torque(theta, t_th3):
        return -(t_th3 * theta ** 3)
