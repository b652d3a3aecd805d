"""proposed_ool_lvdt_nonlinearity_strong: gain error and nonlinearity of the position sensor (LVDT), found by ehas diagnose on /tmp/ow/work/ool_lvdt_nonlinearity_strong/campaign.

The position sensor's scale is off by -0.0029 % and its reading bends by +3 % of the half stroke at the stroke ends.
gain = -0.002911 % (95 % CI -0.02028 to 0.01446)
bend = 2.997 % (95 % CI 2.986 to 3.008)
Residual against what does not repeat: 4.78x -> 1.03x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolLvdtNonlinearityStrong(Effect):
    name = "proposed_ool_lvdt_nonlinearity_strong"
    title = "gain error and nonlinearity of the position sensor (LVDT)"
    params = (
        Param("gain", "%", -0.00291081, (-20.0, 20.0),
              "error of the sensor's scale factor (assumed range: a miscalibrated or wrongly set-up LVDT)",
              typical=(0.0014554, 0.00582162), si=0.01),
        Param("bend", "%", 2.99692, (-20.0, 20.0),
              "the reading's departure from a straight line at the stroke ends, per cent of the half stroke "
              "(an odd, cubic nonlinearity: LVDTs lose linearity toward the ends of their range)",
              typical=(1.49846, 5.99385), si=0.01),
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
