"""proposed_ool_crank_offset_mild: angle offset of the crank: the rod pin is off the perpendicular at mid-stroke, found by ehas diagnose on /tmp/ow/work/ool_crank_offset_mild/campaign.

The crank arm stands +4.01 deg off the perpendicular at the piston's mid-stroke (its lever is r cos(theta +4.01 deg)).
phi0 = 4.012 deg (95 % CI 3.958 to 4.067)
Residual against what does not repeat: 2.73x -> 1.04x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedOolCrankOffsetMild(Effect):
    name = "proposed_ool_crank_offset_mild"
    title = "angle offset of the crank: the rod pin is off the perpendicular at mid-stroke"
    params = (
        Param("phi0", "deg", 4.01236, (-25.0, 25.0),
              "angle of the crank arm from the perpendicular to the piston's axis when the piston is at "
              "mid-stroke (an arm clamped at an angle, a keyway cut off its mark; assumed range: up to 25 deg)",
              typical=(2.00618, 8.02472)),
    )
    main_param = "phi0"
    explanation = (
        "The baseline's crank is square to the piston at mid-stroke: x = r sin(theta). An arm fixed at an "
        "angle phi0 off that gives x = r (sin(theta + phi0) - sin(phi0)) with theta from mid-stroke: the lever "
        "r cos(theta + phi0) is longer on one side of the stroke than on the other, the stroke ends lie at "
        "different crank angles, and the angle the rig logs, asin(x / r) from the LVDT, is not the crank's. "
        "The model's crank angle is then measured from the perpendicular, and the piston sits at "
        "r sin(theta) - r sin(phi0) (the baseline slot piston_offset; Merritt sec. 6.4, load kinematics)."
    )
    signature = (
        "a load-pressure residual that grows toward one end of the stroke and shrinks toward the other (the "
        "lever's asymmetry); pressure residuals of opposite sign in the two chambers; at large amplitude a "
        "stroke end reached on one side only; a sensor offset and a dead-volume shift fitted to it each "
        "explain a part, differently on small and large amplitudes."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"the crank arm stands {params['phi0']:+.3g} deg off the perpendicular at the piston's "
                f"mid-stroke (its lever is r cos(theta {params['phi0']:+.3g} deg))")

    @classmethod
    def apply(cls, values, slots):
        slots["piston_offset"] = slots["radius"] * math.sin(math.radians(values["phi0"]))
