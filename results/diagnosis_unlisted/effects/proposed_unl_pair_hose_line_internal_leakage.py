"""proposed_unl_pair_hose_line_internal_leakage: a term proposed by ehas diagnose for /tmp/ehas_unlisted_L/unl_pair_hose_line+internal_leakage/campaign.

i_valve [mA] += c_i3·i^3   with c_i3 = -0.000127 1/mA^2 (95 % CI -0.0001308 to -0.0001232)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 3.11 -> 1.71; fit 95.6 % -> 96.0 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairHoseLineInternalLeakage(Effect):
    name = "proposed_unl_pair_hose_line_internal_leakage"
    title = "proposed term (valve current)"
    params = (
        Param("i_i3", "1/mA^2", 0.000127009, (0.0, 0.00254019),
              "cubic current: a gain that falls (c < 0, saturation) or rises with |i| (fitted: -0.000127, 95 % CI -0.0001308 to -0.0001232)", typical=(6.35047e-05, 0.000254019)),
    )
    main_param = "i_i3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_i3·i^3 with c_i3 = -0.000127 1/mA^2 (95 % CI -0.0001308 to -0.0001232)'
    signature = 'the residual it was fitted to: i^3'

    @staticmethod
    def valve_current(i, i_i3):
        return i + -(i_i3 * i ** 3)
