"""Structural hypothesis: the valve's gain differs between the two spool directions."""
from ehas_env.physics.effects.base import Effect, Param


class HypDirectionGain(Effect):
    name = "hyp_direction_gain"
    title = "valve gain per spool direction"
    kind = "hypothesis"
    params = (
        Param("g_dir", "-", 0.0, (-0.6, 0.6),
              "relative gain difference: the valve acts as if the current were (1 + g_dir) i for i > 0 and "
              "(1 - g_dir) i for i < 0 (assumed range: worn or asymmetric metering edges)",
              typical=(0.05, 0.3)),
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
