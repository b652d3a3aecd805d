"""Moving mass of the piston and rod."""
from ehas_env.physics.effects.base import Effect, Param


class PistonMass(Effect):
    name = "piston_mass"
    title = "moving mass of the piston and rod"
    # typical 5-30 kg: piston, rod, rod eye and the in-line load cell of a 31 mm bore, 70 mm stroke
    # actuator (the former 20-120 kg is more than such an actuator carries)
    params = (
        Param("m", "kg", 5.0, (0.0, 500.0), "mass of piston, rod and rod eye (assumed: steel, 70 mm stroke)",
              typical=(5.0, 30.0)),
    )
    main_param = "m"
    explanation = (
        "The baseline treats the piston as massless. The piston, rod and rod eye move with x = r sin theta, "
        "so the pressures must also accelerate m: the load gains m x'' = m r (cos theta theta'' - sin theta theta'^2)."
    )
    signature = (
        "load residual in phase with acceleration (proportional to x''), largest at 3 Hz and large "
        "amplitude, relatively larger with few disc sets; lowers the hydraulic natural frequency."
    )

    @staticmethod
    def moving_mass(m):
        return m
