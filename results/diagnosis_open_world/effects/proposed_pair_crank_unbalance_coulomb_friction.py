"""proposed_pair_crank_unbalance_coulomb_friction: unbalanced load: a torque that depends on the crank angle, found by ehas diagnose on /tmp/ow/work/pair_crank_unbalance+coulomb_friction/campaign.

A torque that follows the crank angle pulls the crank back toward -60 deg: T = -25 sin(theta + 60 deg) N m (an unbalance hanging there, or a centring spring of 25 N m/rad about it).
T_sin = 12.45 N m (95 % CI 12.34 to 12.55)
T_cos = 21.67 N m (95 % CI 21.59 to 21.74)
Residual against what does not repeat: 10.3x -> 1.05x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedPairCrankUnbalanceCoulombFriction(Effect):
    name = "proposed_pair_crank_unbalance_coulomb_friction"
    title = "unbalanced load: a torque that depends on the crank angle"
    params = (
        Param("T_sin", "N m", 12.4452, (-3000.0, 3000.0),
              "torque on the crank along -theta proportional to sin(theta): an unbalance whose heavy side is at "
              "the crank's zero with gravity across the stroke, or a centring spring (assumed range: up to the "
              "actuator's stall torque)", typical=(6.2226, 24.8904)),
        Param("T_cos", "N m", 21.666, (-3000.0, 3000.0),
              "torque on the crank along -theta proportional to cos(theta): the same unbalance turned a quarter "
              "turn, gravity along the stroke", typical=(10.833, 43.3321)),
    )
    main_param = "T_sin"
    explanation = (
        "A disc stack whose centre of mass is a distance e off the crank's axis, or a crank not mounted level, "
        "feels gravity's torque m g e sin(theta - theta_0): written T_sin sin(theta) + T_cos cos(theta) with "
        "both signs allowed, the amplitude and the angle of the heavy side follow. A spring centring the crank "
        "gives the sin(theta) part too."
    )
    signature = (
        "load pressure residual that follows the crank angle (not its rate): the same at the same angle on the "
        "way out and back, larger on the large-amplitude runs; a current residual in phase with the angle."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        a = math.hypot(params["T_sin"], params["T_cos"])
        phi = math.degrees(math.atan2(params["T_cos"], params["T_sin"]))
        # T = -a sin(theta + phi): it pulls the crank back toward theta = -phi
        eq = round(-phi) + 0  # + 0: no "-0"
        arg = "theta" if eq == 0 else (f"theta - {eq} deg" if eq > 0 else f"theta + {-eq} deg")
        return (f"a torque that follows the crank angle pulls the crank back toward {eq} deg: T = -{a:.3g} "
                f"sin({arg}) N m (an unbalance hanging there, or a centring spring of {a:.3g} N m/rad about it)")

    @staticmethod
    def crank_torque(theta, T_sin, T_cos):
        return -(T_sin * math.sin(theta) + T_cos * math.cos(theta))
