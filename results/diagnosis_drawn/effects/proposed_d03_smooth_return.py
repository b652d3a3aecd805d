"""proposed_d03_smooth_return: a term proposed by ehas diagnose for /tmp/drawnBw/d03_smooth@return/campaign.

i_valve [mA] += c_i3·i^3   with c_i3 = -0.0001414 1/mA^2 (95 % CI -0.0001461 to -0.0001367)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.46 -> 1.59; fit 96.1 % -> 96.3 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD03SmoothReturn(Effect):
    name = "proposed_d03_smooth_return"
    title = "proposed term (valve current)"
    params = (
        Param("i_i3", "1/mA^2", 0.000141397, (0.0, 0.00282794),
              "cubic current: a gain that falls (c < 0, saturation) or rises with |i| (fitted: -0.0001414, 95 % CI -0.0001461 to -0.0001367)", typical=(7.06985e-05, 0.000282794)),
    )
    main_param = "i_i3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_i3·i^3 with c_i3 = -0.0001414 1/mA^2 (95 % CI -0.0001461 to -0.0001367)'
    signature = 'the residual it was fitted to: i^3'

    @staticmethod
    def valve_current(i, i_i3):
        return i + -(i_i3 * i ** 3)
