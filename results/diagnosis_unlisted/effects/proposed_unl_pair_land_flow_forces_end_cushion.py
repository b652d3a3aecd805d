"""proposed_unl_pair_land_flow_forces_end_cushion: a term proposed by ehas diagnose for /work/runs/unl/unl_pair_land_flow_forces+end_cushion/campaign.

T_crank [N m] += c_th2w·theta^2 omega   with c_th2w = -5.164 N m s/rad^3 (95 % CI -5.378 to -4.949)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.8 -> 2.3; fit 94.7 % -> 95.4 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairLandFlowForcesEndCushion(Effect):
    name = "proposed_unl_pair_land_flow_forces_end_cushion"
    title = "proposed term (crank torque)"
    params = (
        Param("t_th2w", "N m s/rad^3", 5.16358, (0.0, 103.272),
              "torque per rad^3/s of the crank angle squared times the crank rate, at the crank (fitted: -5.164, 95 % CI -5.378 to -4.949)", typical=(2.58179, 10.3272)),
    )
    main_param = "t_th2w"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: T_crank [N m] += c_th2w·theta^2 omega with c_th2w = -5.164 N m s/rad^3 (95 % CI -5.378 to -4.949)'
    signature = 'the residual it was fitted to: theta^2 omega'

    @staticmethod
    def crank_torque(theta, omega, t_th2w):
        return -(t_th2w * (theta ** 2) * omega)
