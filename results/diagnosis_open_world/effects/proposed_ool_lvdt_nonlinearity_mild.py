"""proposed_ool_lvdt_nonlinearity_mild: gain error and nonlinearity of the position sensor (LVDT), found by ehas diagnose on /tmp/ow/work/ool_lvdt_nonlinearity_mild/campaign.

The position sensor's scale is off by -0.0018 % and its reading bends by +1 % of the half stroke at the stroke ends.
gain = -0.00182 % (95 % CI -0.01461 to 0.01097)
bend = 1.001 % (95 % CI 0.9947 to 1.006)
Residual against what does not repeat: 2.04x -> 1.06x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolLvdtNonlinearityMild(Effect):
    name = "proposed_ool_lvdt_nonlinearity_mild"
    title = "gain error and nonlinearity of the position sensor (LVDT)"
    params = (
        Param("gain", "%", -0.00182007, (-20.0, 20.0),
              "error of the sensor's scale factor (assumed range: a miscalibrated or wrongly set-up LVDT)",
              typical=(0.000910037, 0.00364015), si=0.01),
        Param("bend", "%", 1.00056, (-20.0, 20.0),
              "the reading's departure from a straight line at the stroke ends, per cent of the half stroke "
              "(an odd, cubic nonlinearity: LVDTs lose linearity toward the ends of their range)",
              typical=(0.500278, 2.00111), si=0.01),
    )
    main_param = "bend"
    explanation = (
        "An LVDT is linear only over part of its range and its scale is set by a calibration: it reads "
        "x (1 + gain) + bend h (x / h)^3 for a true position x (h: the half stroke). The rig's angle and its "
        "controller use the reading, so the piston's true travel is smaller or larger than the logged one, "
        "increasingly toward the stroke ends."
    )
    signature = (
        "residuals that grow with the amplitude of the run (large-amplitude runs only, largest at the stroke "
        "ends); flow and pressure residuals in proportion to the speed as if the area or the inertia were off."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"the position sensor's scale is off by {params['gain']:+.2g} % and its reading bends by "
                f"{params['bend']:+.2g} % of the half stroke at the stroke ends")

    @staticmethod
    def position_reading(x, half_stroke, gain, bend):
        u = x / half_stroke
        return x * (1.0 + gain) + bend * half_stroke * u * u * u
