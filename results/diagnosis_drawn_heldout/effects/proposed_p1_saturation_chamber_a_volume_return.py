"""proposed_p1_saturation_chamber_a_volume_return: a term proposed by ehas diagnose for /tmp/drG_work/p1_saturation@chamber_a+volume@return/campaign.

F_piston [N] += c_v·v   with c_v = -569.2 N s/m (95 % CI -590 to -548.5)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 13 -> 9.32; fit 80.3 % -> 79.8 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP1SaturationChamberAVolumeReturn(Effect):
    name = "proposed_p1_saturation_chamber_a_volume_return"
    title = "proposed term (piston force)"
    params = (
        Param("f_v", "N s/m", 569.222, (0.0, 11384.4),
              "viscous force per m/s (fitted: -569.2, 95 % CI -590 to -548.5)", typical=(284.611, 1138.44)),
    )
    main_param = "f_v"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_v·v with c_v = -569.2 N s/m (95 % CI -590 to -548.5)'
    signature = 'the residual it was fitted to: v'

    @staticmethod
    def piston_force(v, f_v):
        return -(f_v * v)
