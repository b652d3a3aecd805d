"""Structural hypothesis: seal friction that grows with the chamber pressures."""
import math

from ehas_env.physics.effects.base import Effect, Param


class HypPressureFriction(Effect):
    name = "hyp_pressure_friction"
    title = "seal friction proportional to the chamber pressures"
    kind = "hypothesis"
    params = (
        Param("mu_p", "N/bar", 2.0, (0.0, 200.0),
              "friction force per bar of the sum of the two chamber pressures (the seals are pressed on the "
              "rod and bore by the oil; assumed range: a few to 100 N/bar for lip and compact seals)",
              typical=(1.0, 20.0), log_scale=True, si=1.0e-5),
    )
    main_param = "mu_p"
    explanation = (
        "Piston and rod seals are pressed against their surfaces by the pressure they seal: their friction "
        "is F = mu_p (P_A + P_B) opposing the motion (smoothed through zero velocity as the library's "
        "friction is), instead of a constant Coulomb level. It is larger where both chambers are high and "
        "changes with the operating pressure."
    )
    signature = (
        "a friction-like current residual at each reversal whose size follows the chamber pressures' sum; "
        "a Coulomb friction fitted to it differs between runs at different pressures."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"seal friction grows with the chamber pressures: {params['mu_p']:.3g} N per bar of P_A + P_B "
                f"({params['mu_p'] * 100.0:.3g} N at 100 bar)")

    @staticmethod
    def piston_force(v, pa, pb, mu_p, v_tanh):
        return -mu_p * max(pa + pb, 0.0) * math.tanh(v / v_tanh)
