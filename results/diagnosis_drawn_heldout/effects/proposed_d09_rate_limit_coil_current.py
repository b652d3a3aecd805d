"""proposed_d09_rate_limit_coil_current: a term proposed by ehas diagnose for /work/runs/held/d09_rate_limit@coil_current/campaign.

i_valve [mA] += c_i3·i^3   with c_i3 = -8.655e-05 1/mA^2 (95 % CI -9.778e-05 to -7.531e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.96 -> 2.54; fit 94.9 % -> 95.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD09RateLimitCoilCurrent(Effect):
    name = "proposed_d09_rate_limit_coil_current"
    title = "proposed term (valve current)"
    params = (
        Param("i_i3", "1/mA^2", 8.65466e-05, (0.0, 0.00173093),
              "current per mA^3 of the valve current cubed, the valve's current (fitted: -8.655e-05, 95 % CI -9.778e-05 to -7.531e-05)", typical=(4.32733e-05, 0.000173093)),
    )
    main_param = "i_i3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_i3·i^3 with c_i3 = -8.655e-05 1/mA^2 (95 % CI -9.778e-05 to -7.531e-05)'
    signature = 'the residual it was fitted to: i^3'

    @staticmethod
    def valve_current(i, i_i3):
        return i + -(i_i3 * i ** 3)
