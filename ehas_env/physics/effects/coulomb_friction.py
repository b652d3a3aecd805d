"""Coulomb (dry) seal friction at the piston."""
import math

from ehas_env.physics.effects.base import Effect, Param


class CoulombFriction(Effect):
    name = "coulomb_friction"
    title = "Coulomb seal friction at the piston"
    params = (
        Param("Fc", "N", 300.0, (0.0, 3000.0),
              "Coulomb friction force of the piston and rod seals (assumed: typical for a 7.7 cm^2 actuator at 220 bar)",
              typical=(150.0, 600.0)),
    )
    smooth = False
    main_param = "Fc"
    explanation = (
        "The piston and rod seals rub on the bore and rod with a force of nearly constant size that always "
        "opposes the motion: F = -Fc tanh(x'/v_s) with v_s = 1 mm/s smoothing the sign so that the "
        "integrator stays well-behaved through velocity reversals. The actuator must push through it, so "
        "the chamber pressures carry an extra +-Fc/A step each time the piston reverses."
    )
    signature = (
        "load (from the pressures) exceeds I*theta''/(r cos theta) by a square wave of height +-Fc in phase "
        "with sign(velocity); residual vs velocity shows a jump at zero; the load-vs-velocity loop gains a "
        "step at reversal; position error grows at reversals (stick)."
    )

    @staticmethod
    def piston_force(v, Fc, v_tanh):
        return -(Fc * math.tanh(v / v_tanh))
