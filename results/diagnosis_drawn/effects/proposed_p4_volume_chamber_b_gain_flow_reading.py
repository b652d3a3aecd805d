"""proposed_p4_volume_chamber_b_gain_flow_reading: a term proposed by ehas diagnose for /tmp/drA_work/p4_volume@chamber_b+gain@flow_reading/campaign.

i_valve [mA] += c_i3·i^3   with c_i3 = -0.0001387 1/mA^2 (95 % CI -0.0001464 to -0.000131)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 11.9 -> 9.52; fit 89.6 % -> 89.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP4VolumeChamberBGainFlowReading(Effect):
    name = "proposed_p4_volume_chamber_b_gain_flow_reading"
    title = "proposed term (valve current)"
    params = (
        Param("i_i3", "1/mA^2", 0.00013871, (0.0, 0.00277421),
              "cubic current: a gain that falls (c < 0, saturation) or rises with |i| (fitted: -0.0001387, 95 % CI -0.0001464 to -0.000131)", typical=(6.93552e-05, 0.000277421)),
    )
    main_param = "i_i3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_i3·i^3 with c_i3 = -0.0001387 1/mA^2 (95 % CI -0.0001464 to -0.000131)'
    signature = 'the residual it was fitted to: i^3'

    @staticmethod
    def valve_current(i, i_i3):
        return i + -(i_i3 * i ** 3)
