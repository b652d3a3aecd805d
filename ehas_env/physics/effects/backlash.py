"""Play in the rod-crank joint."""
from ehas_env.physics.effects.base import Effect, Param


class Backlash(Effect):
    name = "backlash"
    title = "backlash (play) in the rod-crank joint"
    params = (
        Param("delta", "m", 2.0e-4, (0.0, 3.0e-3), "half the total play 2 delta of the joint (assumed: worn pin)",
              typical=(1.0e-4, 5.0e-4)),
    )
    main_param = "delta"
    explanation = (
        "A worn pin or rod eye leaves play of total width 2 delta between the rod and the crank. At each "
        "reversal the piston crosses the play unloaded before it picks up the crank again, with a knock. "
        "The LVDT measures the piston, so the crank lags the measured position by up to delta/(r cos theta). "
        "The piston is given a mass (at least 5 kg, assumed) and the joint a contact stiffness of 2e7 N/m and "
        "damping of 3e3 N s/m (assumed: steel pin and eye)."
    )
    signature = (
        "load collapses to ~0 for a moment after each reversal, then knocks; the load-vs-position loop "
        "has flat sections of width 2 delta; pressure ringing after reversals."
    )

    @classmethod
    def apply(cls, values, slots):
        slots["delta"] = values["delta"]
