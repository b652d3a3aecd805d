"""Structural hypothesis: seal friction with a presliding (bristle) state, the LuGre law."""
import math

from ehas_env.physics.effects.base import Effect, Param


class HypLugreFriction(Effect):
    name = "hyp_lugre_friction"
    title = "dynamic (LuGre) seal friction with a presliding bristle state"
    kind = "hypothesis"
    params = (
        Param("Fc", "N", 200.0, (1.0, 3000.0),
              "Coulomb (sliding) friction level of the piston and rod seals (assumed range as coulomb_friction's)",
              typical=(100.0, 600.0)),
        Param("r_s", "-", 1.5, (1.0, 4.0),
              "breakaway (static) force over the sliding force, Fs / Fc (assumed: 1 without a Stribeck peak, "
              "up to a few for dry, unlubricated seals)",
              typical=(1.2, 2.5)),
        Param("sigma0", "N/m", 1.0e6, (1.0e4, 1.0e8),
              "stiffness of the seal's bristles: the force builds up over Fc / sigma0 of travel after a reversal "
              "(assumed range: a presliding distance of some 10 um to some mm)",
              typical=(2.0e5, 5.0e6), log_scale=True),
        Param("sigma2", "N s/m", 500.0, (0.0, 1.0e5),
              "viscous friction of the sliding seal (the LuGre law's sigma2; assumed range as viscous_friction's)",
              typical=(100.0, 3000.0)),
    )
    constants = (
        Param("vs", "m/s", 0.01, (1.0e-4, 0.5),
              "Stribeck velocity: how fast the force falls from the breakaway to the sliding level (assumed, as "
              "stribeck_friction's default)"),
        Param("sigma1", "N s/m", 1.0e3, (0.0, 1.0e6),
              "damping of the bristles' deflection rate (assumed: Canudas de Wit et al. 1995 take "
              "sqrt(sigma0 m); it acts only while the bristles deflect)"),
        Param("k_max", "1/s", 5.0e3, (1.0, 1.0e9),
              "fastest relaxation of the bristles the integrator resolves (set from its sub-step by adjust(): "
              "half the sub-step's rate; only a presliding distance shorter than |v| / k_max is stretched)"),
    )
    main_param = "Fc"
    # its sliding level is a dry friction: a Coulomb (or Stribeck) friction kept first holds that level, and the
    # law screened on top of it has none left to show its presliding state with; fitted in its place instead
    mistaken_for = ("coulomb_friction", "stribeck_friction")
    #: |v| in the bristles' rate and the switch to the resolved relaxation: no small-signal meaning at rest
    smooth = False
    states = (("z", "m", 0.0),)
    explanation = (
        "Seal friction is not a function of the velocity alone: before the seal slides its lips (bristles) "
        "deflect like springs, and the force builds up over a short presliding travel after each reversal. "
        "The LuGre law (Canudas de Wit, Olsson, Astrom, Lischinsky 1995) gives the mean bristle deflection z "
        "a state: z' = v - sigma0 |v| z / g(v), g(v) = Fc + (Fs - Fc) exp(-(v/vs)^2) with Fs = r_s Fc, and "
        "the force on the piston F = -(sigma0 z + sigma1 z' + sigma2 v). Sliding steadily it is Stribeck "
        "friction plus viscous friction; at reversal the force turns over Fc / sigma0 of travel, not at a "
        "speed threshold, and a small motion stays stuck on the bristles' spring."
    )
    signature = (
        "like Coulomb friction a step of the load residual at each reversal, but the step is spread over a "
        "travel (a slope in load vs position after reversal, a hysteresis loop at small amplitude), larger "
        "just after breakaway than in steady sliding; a Coulomb or viscous friction fitted to it comes out "
        "different on slow and on fast runs."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"the seals' friction has a presliding state (LuGre): {params['Fc']:.3g} N sliding, breakaway "
                f"{params['r_s']:.3g} x that, built up over {1e6 * params['Fc'] / params['sigma0']:.3g} um of "
                f"travel after a reversal, plus {params['sigma2']:.3g} N s/m viscous")

    @classmethod
    def adjust(cls, slots, substep_s):
        # the bristles relax at sigma0 |v| / g, which a stiff bristle at speed makes faster than the RK4
        # sub-step resolves: cap it at half the sub-step's rate (h k <= 0.5)
        # (by cls.name: the file --write-effect writes renames the effect)
        if slots.get(f"{cls.name}.on"):
            slots[f"{cls.name}.k_max"] = 0.5 / substep_s

    @staticmethod
    def state_rates(v, z, Fc, r_s, sigma0, vs, k_max):
        g = Fc * (1.0 + (r_s - 1.0) * math.exp(-((v / vs) ** 2)))
        k = sigma0 * abs(v) / g
        if k <= k_max:
            return v - k * z
        # faster than the integrator resolves: relax toward the sliding deflection at the resolved rate
        return k_max * (math.copysign(g / sigma0, v) - z)

    @staticmethod
    def piston_force(v, z, Fc, r_s, sigma0, sigma1, sigma2, vs, k_max):
        g = Fc * (1.0 + (r_s - 1.0) * math.exp(-((v / vs) ** 2)))
        k = sigma0 * abs(v) / g
        if k <= k_max:
            zd = v - k * z
        else:
            zd = k_max * (math.copysign(g / sigma0, v) - z)
        return -(sigma0 * z + sigma1 * zd + sigma2 * v)
