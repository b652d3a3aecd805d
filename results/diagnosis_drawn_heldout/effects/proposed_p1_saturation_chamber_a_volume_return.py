"""proposed_p1_saturation_chamber_a_volume_return: a term proposed by ehas diagnose for /tmp/drHC_work/p1_saturation@chamber_a+volume@return/campaign.

F_piston [N] += c_vv·v |v|   with c_vv = -903.7 N s^2/m^2 (95 % CI -928.2 to -879.1)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 4.37 -> 2.7; fit 95.7 % -> 95.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP1SaturationChamberAVolumeReturn(Effect):
    name = "proposed_p1_saturation_chamber_a_volume_return"
    title = "proposed term (piston force)"
    params = (
        Param("f_vv", "N s^2/m^2", 903.658, (0.0, 18073.2),
              "quadratic damping: force per (m/s)^2, signed (fitted: -903.7, 95 % CI -928.2 to -879.1)", typical=(451.829, 1807.32)),
    )
    main_param = "f_vv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_vv·v |v| with c_vv = -903.7 N s^2/m^2 (95 % CI -928.2 to -879.1)'
    signature = 'the residual it was fitted to: v |v|'

    @staticmethod
    def piston_force(v, f_vv):
        return -(f_vv * v * abs(v))
