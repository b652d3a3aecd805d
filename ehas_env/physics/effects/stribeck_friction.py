"""Stribeck friction: breakaway force above the Coulomb level at low speed."""
import math

from ehas_env.physics.effects.base import Effect, Param


class StribeckFriction(Effect):
    name = "stribeck_friction"
    title = "Stribeck seal friction (static breakaway + Coulomb)"
    params = (
        Param("Fc", "N", 200.0, (0.0, 3000.0), "Coulomb (sliding) friction level (assumed)", typical=(100.0, 400.0)),
        Param("Fs", "N", 450.0, (0.0, 5000.0), "static (breakaway) friction level (assumed)", typical=(250.0, 900.0)),
        Param("vs", "m/s", 0.01, (1.0e-4, 0.5), "Stribeck velocity: how fast the force falls from Fs to Fc (assumed)",
              typical=(0.005, 0.03), log_scale=True),
    )
    smooth = False
    main_param = "Fs"
    explanation = (
        "Seals stick harder than they slide: at rest the force needed to break away is Fs, and as the "
        "lubricating film builds up with speed it falls towards the sliding level Fc, "
        "F = -(Fc + (Fs - Fc) exp(-(x'/vs)^2)) tanh(x'/1 mm/s). The drop with speed is a negative "
        "damping that can make slow motion jerky (stick-slip)."
    )
    signature = (
        "like Coulomb friction (a jump of the load residual at zero velocity) but larger near zero speed "
        "than at high speed: residual-vs-|velocity| decays from Fs to Fc within a few vs; position error "
        "spikes just after reversals."
    )

    @classmethod
    def validate(cls, values):
        """Breakaway is at or above sliding: a static force Fs below the Coulomb level Fc is refused."""
        if values["Fs"] < values["Fc"]:
            raise ValueError(f"effect 'stribeck_friction': breakaway force Fs = {values['Fs']:g} N must be at least the "
                             f"sliding force Fc = {values['Fc']:g} N (Fs >= Fc)")

    @staticmethod
    def piston_force(v, Fc, Fs, vs, v_tanh):
        return -((Fc + (Fs - Fc) * math.exp(-((v / vs) ** 2))) * math.tanh(v / v_tanh))
