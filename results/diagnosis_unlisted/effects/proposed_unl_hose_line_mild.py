"""proposed_unl_hose_line_mild: a term proposed by ehas diagnose for /tmp/ehas_unlisted_L/unl_hose_line_mild/campaign.

i_valve [mA] += c_i3·i^3   with c_i3 = -0.0001255 1/mA^2 (95 % CI -0.0001298 to -0.0001212)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 3.29 -> 1.83; fit 95.3 % -> 95.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedUnlHoseLineMild(Effect):
    name = "proposed_unl_hose_line_mild"
    title = "proposed term (valve current)"
    params = (
        Param("i_i3", "1/mA^2", 0.000125474, (0.0, 0.00250947),
              "cubic current: a gain that falls (c < 0, saturation) or rises with |i| (fitted: -0.0001255, 95 % CI -0.0001298 to -0.0001212)", typical=(6.27368e-05, 0.000250947)),
    )
    main_param = "i_i3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_i3·i^3 with c_i3 = -0.0001255 1/mA^2 (95 % CI -0.0001298 to -0.0001212)'
    signature = 'the residual it was fitted to: i^3'

    @staticmethod
    def valve_current(i, i_i3):
        return i + -(i_i3 * i ** 3)
