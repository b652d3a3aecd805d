"""proposed_ool_lvdt_offset_strong: zero offset of the position sensor (LVDT), found by ehas diagnose on /tmp/ow/work/ool_lvdt_offset_strong/campaign.

The position sensor reads +1.05 mm at the piston's true mid-stroke (a zero offset of the LVDT).
x0 = 1.055 mm (95 % CI 0.989 to 1.121)
Residual against what does not repeat: 1.3x -> 1.04x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolLvdtOffsetStrong(Effect):
    name = "proposed_ool_lvdt_offset_strong"
    title = "zero offset of the position sensor (LVDT)"
    params = (
        Param("x0", "mm", 1.05487, (-10.0, 10.0),
              "what the LVDT reads when the piston is at mid-stroke (a zero set wrongly, a shifted mounting, "
              "electronics' offset; assumed range: up to 10 mm either way)", typical=(0.527435, 2.10974), si=1.0e-3),
    )
    main_param = "x0"
    explanation = (
        "The rig's angle is computed from the LVDT's reading of the piston, and its controller closes the loop "
        "on it. A sensor that reads x + x0 makes the rig track the reference with the piston displaced by -x0: "
        "the logged angle follows the reference as before, but the chambers work about a shifted mid-stroke, "
        "and the current and pressures show it."
    )
    signature = (
        "pressure residuals of opposite sign in the two chambers, nearly constant over each run (a shifted "
        "chamber volume); a small constant current residual; the logged angle's residual small and largest "
        "near the stroke ends."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"the position sensor reads {params['x0']:+.3g} mm at the piston's true mid-stroke (a zero "
                f"offset of the LVDT)")

    @staticmethod
    def position_reading(x, x0):
        return x + x0
