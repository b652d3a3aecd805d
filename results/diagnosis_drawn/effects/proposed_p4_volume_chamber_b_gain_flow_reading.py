"""proposed_p4_volume_chamber_b_gain_flow_reading: a term proposed by ehas diagnose for /tmp/drLC_work/p4_volume@chamber_b+gain@flow_reading/campaign.

F_piston [N] += c_x3·x^3   with c_x3 = -4.802e+06 N/m^3 (95 % CI -5.431e+06 to -4.172e+06)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 1.66 -> 1.61; fit 95.0 % -> 95.0 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP4VolumeChamberBGainFlowReading(Effect):
    name = "proposed_p4_volume_chamber_b_gain_flow_reading"
    title = "proposed term (piston force)"
    params = (
        Param("f_x3", "N/m^3", 4.80164e+06, (0.0, 9.60328e+07),
              "hardening spring: force per m^3 (fitted: -4.802e+06, 95 % CI -5.431e+06 to -4.172e+06)", typical=(2.40082e+06, 9.60328e+06)),
    )
    main_param = "f_x3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x3·x^3 with c_x3 = -4.802e+06 N/m^3 (95 % CI -5.431e+06 to -4.172e+06)'
    signature = 'the residual it was fitted to: x^3'

    @staticmethod
    def piston_force(x, f_x3):
        return -(f_x3 * x ** 3)
