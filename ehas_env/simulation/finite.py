"""A run that went NaN or infinite stops with one line naming who and when.

The compiled model cannot raise from inside numba, so the check runs on what a
run returns: the first sample where the valve current (the controller's output,
after the effects on the current) or a state is not finite names the time and,
by which went first, the controller law or the plant's effect terms.
"""
from __future__ import annotations

import numpy as np


def check_run(out: np.ndarray, dt: float, current_col: int, controller: str, effects) -> None:
    """ValueError when ``out`` (samples x outputs) holds NaN or inf.

    Parameters
    ----------
    out : ndarray
        The run's outputs, one row per control period.
    dt : float
        Control period, s.
    current_col : int
        Column of the valve current.
    controller : str
        How to name the controller (its name or law).
    effects : iterable of str
        The plant's effects.

    Raises
    ------
    ValueError
        One line: the time of the first non-finite sample and what produced it.
    """
    bad = ~np.isfinite(out)
    if not bad.any():
        return
    rows = np.flatnonzero(bad.any(axis=1))
    k = int(rows[0])
    t = k * dt
    others = np.delete(bad[k], current_col)
    effects = list(effects or [])
    if bad[k, current_col] and not others.any():
        who = f"the controller ({controller}) returned a current that is NaN or inf"
    else:
        who = ("the plant's state became NaN or inf (an effect term returned NaN or inf, or the run diverged; "
               f"effects: {', '.join(effects) or 'none'})")
    raise ValueError(f"simulation stopped: at t = {t:.4f} s {who}; nothing was written")


def check_metrics(metrics: np.ndarray, conditions, controller: str) -> None:
    """ValueError when a batched run's metrics hold NaN or inf (names the first condition)."""
    bad = ~np.isfinite(np.asarray(metrics, dtype=float))
    if not bad.any():
        return
    j = int(np.flatnonzero(bad.any(axis=1))[0])
    c = conditions[j]
    eff = ", ".join(n for n, _ in getattr(c, "effects", ())) or "none"
    raise ValueError(f"simulation stopped: the run of {controller} at {c.disc_sets} disc sets, {c.freq_hz:g} Hz, "
                     f"{c.amplitude_deg:g} deg gave NaN or inf (its law or an effect term returned NaN or inf; "
                     f"effects: {eff})")
