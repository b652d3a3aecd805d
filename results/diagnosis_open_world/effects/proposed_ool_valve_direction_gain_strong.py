"""proposed_ool_valve_direction_gain_strong: valve gain per spool direction, found by ehas diagnose on /tmp/ow/work/ool_valve_direction_gain_strong/campaign.

The valve's gain for negative current is 0.74 of its gain for positive current.
g_dir = 0.15 - (95 % CI 0.1499 to 0.1501)
Residual against what does not repeat: 49.4x -> 1.06x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolValveDirectionGainStrong(Effect):
    name = "proposed_ool_valve_direction_gain_strong"
    title = "valve gain per spool direction"
    params = (
        Param("g_dir", "-", 0.150027, (-0.6, 0.6),
              "relative gain difference: the valve acts as if the current were (1 + g_dir) i for i > 0 and "
              "(1 - g_dir) i for i < 0 (assumed range: worn or asymmetric metering edges)",
              typical=(0.0750133, 0.300053)),
    )
    main_param = "g_dir"
    explanation = (
        "The baseline valve has one gain K for both spool directions. Worn, chamfered or unequally lapped "
        "metering edges make the flow per mA larger one way than the other: K (1 + g_dir) for positive "
        "current, K (1 - g_dir) for negative."
    )
    signature = (
        "flow residual proportional to |i| (even in the current); closed loop: a current residual that "
        "changes sign with the spool direction; valve runs: the flow gain differs between the two halves of "
        "each cycle."
    )

    chain_order = 20

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        g = params["g_dir"]
        return (f"the valve's gain for negative current is {(1.0 - g) / (1.0 + g):.2f} of its gain for positive "
                f"current")

    @staticmethod
    def valve_current(i, g_dir):
        if i >= 0.0:
            return i * (1.0 + g_dir)
        return i * (1.0 - g_dir)
