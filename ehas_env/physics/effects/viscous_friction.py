"""Viscous friction at the piston."""
from ehas_env.physics.effects.base import Effect, Param


class ViscousFriction(Effect):
    name = "viscous_friction"
    title = "viscous friction at the piston"
    params = (
        Param("b", "N s/m", 2000.0, (0.0, 1.0e5),
              "viscous friction coefficient (assumed: oil film shear in seals and guides)",
              typical=(1000.0, 6000.0)),
    )
    main_param = "b"
    explanation = (
        "Oil films in the seals and guides shear at a rate proportional to the piston speed, giving a force "
        "-b x' that grows linearly with velocity. It damps the load and costs pressure in proportion to "
        "the speed, so it shows most at high frequency and amplitude."
    )
    signature = (
        "load residual proportional to velocity (a straight line through the origin in residual-vs-velocity), "
        "in quadrature with the inertial load; larger at 3 Hz than at 1 Hz; no jump at zero velocity."
    )

    @staticmethod
    def piston_force(v, b):
        return -(b * v)
