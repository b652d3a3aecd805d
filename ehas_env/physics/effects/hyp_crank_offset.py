"""Structural hypothesis: the crank's zero is off the piston's mid-stroke by an angle (load kinematics)."""
import math

from ehas_env.physics.effects.base import Effect, Param


class HypCrankOffset(Effect):
    name = "hyp_crank_offset"
    title = "angle offset of the crank: the rod pin is off the perpendicular at mid-stroke"
    kind = "hypothesis"
    params = (
        Param("phi0", "deg", 0.0, (-25.0, 25.0),
              "angle of the crank arm from the perpendicular to the piston's axis when the piston is at "
              "mid-stroke (an arm clamped at an angle, a keyway cut off its mark; assumed range: up to 25 deg)",
              typical=(-8.0, 8.0), si=math.pi / 180.0),
    )
    main_param = "phi0"
    explanation = (
        "The baseline's crank is square to the piston at mid-stroke: x = r sin(theta). An arm fixed at an "
        "angle phi0 off that gives x = r (sin(theta + phi0) - sin(phi0)) with theta from mid-stroke: the lever "
        "r cos(theta + phi0) is longer on one side of the stroke than on the other, and the angle the rig logs, "
        "asin(x / r) from the LVDT, is not the crank's. In the model's crank angle psi = theta + phi0 this is "
        "the baseline's crank with the piston, its chambers and the LVDT all shifted by r sin(phi0) along the "
        "stroke: one angle moves the chambers' volumes (A r sin(phi0) from one side to the other) and the "
        "reading together (Merritt sec. 6.4, load kinematics)."
    )
    signature = (
        "a load-pressure residual that grows toward one end of the stroke and shrinks toward the other (the "
        "lever's asymmetry), odd in the logged angle's square; pressure residuals of opposite sign in the two "
        "chambers; a sensor offset and a dead-volume shift fitted to it each explain half."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"the crank arm stands {params['phi0']:+.3g} deg off the perpendicular at the piston's "
                f"mid-stroke (its lever is r cos(theta {params['phi0']:+.3g} deg))")

    @staticmethod
    def position_reading(x, radius, phi0):
        # the LVDT reads the piston, r sin(psi) - r sin(phi0) in the model's crank angle psi
        return x - radius * math.sin(phi0)

    @staticmethod
    def chamber_flows(x, q_a, q_b, v, area, half_stroke, dead_volume, radius, phi0):
        # the piston sits r sin(phi0) toward A: chamber A holds A r sin(phi0) less oil, B as much more; as
        # hyp_dead_volume's volume change, the rate scaled by V / (V + dV)
        dv = area * radius * math.sin(phi0)
        va = area * (half_stroke + x) + dead_volume
        vb = area * (half_stroke - x) + dead_volume
        return (-(q_a - area * v) * (-dv) / (va - dv), -(q_b + area * v) * dv / (vb + dv))
