"""Play in the rod-crank joint."""
from ehas_env.physics.effects.base import Effect, Param


class Backlash(Effect):
    name = "backlash"
    title = "backlash (play) in the rod-crank joint"
    params = (
        Param("delta", "m", 2.0e-4, (0.0, 3.0e-3), "half the total play 2 delta of the joint (assumed: worn pin)",
              typical=(1.0e-4, 5.0e-4)),
    )
    constants = (
        Param("k_joint", "N/m", 2.0e7, (0.0, 1e12), "joint contact stiffness (assumed: steel pin and eye)"),
        Param("c_joint", "N s/m", 3.0e3, (0.0, 1e9), "joint contact damping (assumed)"),
        Param("m_min", "kg", 5.0, (0.0, 1e3), "least piston mass once the joint has play (assumed)"),
    )
    smooth = False
    main_param = "delta"
    # the cost's valley around the play is about +-25 % wide (the knock's timing moves with delta): the default
    # 7-point scan over 2.5e-5..2e-3 m (x2.1 apart) can step over it and leave the fit at its lower end;
    # 31 points are x1.16 apart, two or more inside the valley
    scan_points = 31
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

    @staticmethod
    def joint_force(gap, gap_rate, delta, k_joint, c_joint):
        if gap > delta:
            return k_joint * (gap - delta) + c_joint * gap_rate
        if gap < -delta:
            return k_joint * (gap + delta) + c_joint * gap_rate
        return 0.0

    @classmethod
    def adjust(cls, slots, substep_s):
        # A light piston with seal friction is stiff: keep the friction's sign smoothing
        # wide enough for the RK4 sub-step (h F / (m v) < 1).
        if not slots.get("backlash.on"):
            return
        f_max = (slots.get("coulomb_friction.on", 0.0) * slots.get("coulomb_friction.Fc", 0.0)
                 + slots.get("stribeck_friction.on", 0.0) * max(slots.get("stribeck_friction.Fs", 0.0),
                                                                  slots.get("stribeck_friction.Fc", 0.0)))
        m = max(slots.get("piston_mass.on", 0.0) * slots.get("piston_mass.m", 0.0), slots["backlash.m_min"])
        slots["v_tanh"] = max(slots["v_tanh"], substep_s * f_max / m)
