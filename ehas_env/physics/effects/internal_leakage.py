"""Cross-piston (internal) leakage."""
from ehas_env.physics.effects.base import Effect, Param


class InternalLeakage(Effect):
    name = "internal_leakage"
    title = "internal leakage across the piston"
    params = (
        Param("C_leak", "m^3/s/Pa", 1.0e-12, (0.0, 1.0e-10),
              "laminar leakage coefficient across the piston seal (assumed: 0.6 LPM at 100 bar)",
              typical=(3.0e-13, 3.0e-12), log_scale=True),
    )
    main_param = "C_leak"
    explanation = (
        "A worn or damaged piston seal lets oil pass from the high- to the low-pressure chamber, "
        "Q_leak = C_leak (P_A - P_B). The valve must supply that flow on top of A x', so more current is "
        "needed for the same speed and the load pressure leaks away, which damps the hydraulic resonance."
    )
    signature = (
        "current residual proportional to the load pressure (the controller's integrator supplies the "
        "leak); flow in line A exceeds A x' by C_leak P_L; the hydraulic mode rings less; pressure "
        "peaks lower than the model's."
    )

    @staticmethod
    def chamber_flows(p_load, C_leak):
        leak = C_leak * p_load
        return -leak, leak
