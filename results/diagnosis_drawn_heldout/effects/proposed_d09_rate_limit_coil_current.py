"""proposed_d09_rate_limit_coil_current: a term proposed by ehas diagnose for /tmp/s1/work_ho/d09_rate_limit@coil_current/campaign.

i_valve [mA] += c_i3·i^3   with c_i3 = -8.664e-05 1/mA^2 (95 % CI -9.786e-05 to -7.542e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.96 -> 2.54; fit 94.9 % -> 95.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD09RateLimitCoilCurrent(Effect):
    name = "proposed_d09_rate_limit_coil_current"
    title = "proposed term (valve current)"
    params = (
        Param("i_i3", "1/mA^2", 8.66402e-05, (0.0, 0.0017328),
              "cubic current: a gain that falls (c < 0, saturation) or rises with |i| (fitted: -8.664e-05, 95 % CI -9.786e-05 to -7.542e-05)", typical=(4.33201e-05, 0.00017328)),
    )
    main_param = "i_i3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_i3·i^3 with c_i3 = -8.664e-05 1/mA^2 (95 % CI -9.786e-05 to -7.542e-05)'
    signature = 'the residual it was fitted to: i^3'

    @staticmethod
    def valve_current(i, i_i3):
        return i + -(i_i3 * i ** 3)
