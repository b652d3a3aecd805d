"""The tracking metric (% position error) and the NRMSE fit.

``rms_error_pct`` = 100 RMS(theta_ref - theta) / theta_amp and
``peak_error_pct`` = 100 max|theta_ref - theta| / theta_amp, over whole reference
cycles after the first (the first is a warm-up), as docs/reference-model.md defines
them.  The book never defines its "% pos error"; these do.
"""
from __future__ import annotations

import numpy as np


def steady_window(t: np.ndarray, freq_hz: float) -> np.ndarray:
    """Boolean mask of the samples in whole cycles after the first."""
    t = np.asarray(t, dtype=float)
    period = 1.0 / freq_hz
    t0 = t[0]
    n_cycles = int(np.floor((t[-1] - t0) / period + 1e-9))
    if n_cycles < 2:
        raise ValueError(
            f"the run covers {n_cycles} whole reference cycle(s) of {period:g} s; the % error needs at least 2 "
            "(the first is a warm-up)"
        )
    return (t >= t0 + period - 1e-12) & (t < t0 + n_cycles * period - 1e-12)


def percent_errors(sum_sq: float, count: float, max_abs: float, amplitude_deg: float) -> dict[str, float]:
    """The metric from its running sums: 100 sqrt(sum e^2 / n) / amp and 100 max|e| / amp.

    The one place the % error is computed: the compiled loops (benchmark, environment)
    accumulate ``sum_sq``, ``count`` and ``max_abs`` of e in deg over the window of
    :func:`steady_window` and hand them here.  A non-finite rms (a run that blew up)
    is reported as 1e9 %.

    Examples
    --------
    >>> percent_errors(4 * 0.01, 4, 0.1, 20.0)   # e = 0.1 deg on 4 samples, amplitude 20 deg
    {'rms_error_pct': 0.5, 'peak_error_pct': 0.5}
    """
    amp = abs(float(amplitude_deg))
    rms = 100.0 * np.sqrt(sum_sq / max(count, 1.0)) / amp
    return {"rms_error_pct": float(rms) if np.isfinite(rms) else 1e9, "peak_error_pct": float(100.0 * max_abs / amp)}


def tracking_errors(t, theta_ref_deg, theta_deg, amplitude_deg, freq_hz) -> dict[str, float]:
    """rms and peak % position error over the steady cycles of a recorded run.

    Examples
    --------
    A sine lagging by 1 % of a period: e = 20 (sin wt - sin(wt - 0.02 pi)), so the rms
    is 2 sin(0.01 pi) / sqrt(2) of the amplitude and the peak sqrt(2) times that:

    >>> t = np.arange(0, 3, 1e-3)
    >>> ref = 20 * np.sin(2 * np.pi * t)
    >>> e = tracking_errors(t, ref, 20 * np.sin(2 * np.pi * (t - 0.01)), 20.0, 1.0)
    >>> round(e["rms_error_pct"], 2), round(float(200 * np.sin(0.01 * np.pi) / np.sqrt(2)), 2)
    (4.44, 4.44)
    >>> round(e["peak_error_pct"], 2), round(float(200 * np.sin(0.01 * np.pi)), 2)
    (6.28, 6.28)
    """
    m = steady_window(t, freq_hz)
    e = np.asarray(theta_ref_deg, dtype=float)[m] - np.asarray(theta_deg, dtype=float)[m]
    return percent_errors(float(np.sum(e * e)), e.size, float(np.max(np.abs(e))), amplitude_deg)


def fit_percent(y, y_hat) -> float:
    """NRMSE fit, 100 (1 - ||y - y_hat|| / ||y - mean(y)||), as MATLAB's ``compare``.

    Examples
    --------
    >>> fit_percent([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])
    100.0
    """
    y = np.asarray(y, dtype=float)
    y_hat = np.asarray(y_hat, dtype=float)
    den = np.linalg.norm(y - y.mean())
    if den == 0.0:
        raise ValueError("fit_percent: the measured signal is constant, its fit is undefined")
    return float(100.0 * (1.0 - np.linalg.norm(y - y_hat) / den))
