"""Structural hypothesis: a spring on the load, a torque proportional to the crank angle."""
import math

from ehas_env.physics.effects.base import Effect, Param


class HypCrankSpring(Effect):
    name = "hyp_crank_spring"
    title = "a spring on the load: a torque proportional to the crank angle"
    kind = "hypothesis"
    params = (
        Param("k", "N m/rad", 100.0, (0.0, 20000.0),
              "torsional stiffness the load pulls the crank back to its centre with (a return spring, a cable "
              "or hose carrier, a torsion bar, the load spring K_L of Merritt's servo load; assumed range: up "
              "to twice the actuator's stall torque per radian)", typical=(20.0, 1000.0), log_scale=True),
        Param("T_0", "N m", 0.0, (-3000.0, 3000.0),
              "constant torque on the crank (a spring preloaded off the crank's zero: its centre sits at "
              "T_0 / k rad)", typical=(-50.0, 50.0)),
    )
    main_param = "k"
    explanation = (
        "A spring between the load and the frame -- a return spring, a cable carrier, a torsion bar, the "
        "elastic load K_L of Merritt's hydraulic servo -- pulls the crank back to its centre with a torque "
        "T = -k theta + T_0, linear in the angle over the whole stroke (an unbalance follows sin(theta) "
        "instead: the two part at large angles)."
    )
    signature = (
        "load pressure residual proportional to the crank angle: the same at the same angle on the way out and "
        "back, growing linearly with amplitude; a current residual in phase with the angle."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        k, t0 = params["k"], params["T_0"]
        centre = f", centred at {math.degrees(t0 / k):.2g} deg" if k > 0 and abs(t0) > 1e-3 * k else ""
        return f"a spring on the load pulls the crank back to its centre: {k:.4g} N m/rad{centre}"

    @staticmethod
    def crank_torque(theta, k, T_0):
        return -k * theta + T_0
