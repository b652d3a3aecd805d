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


def tracking_errors(t, theta_ref_deg, theta_deg, amplitude_deg, freq_hz) -> dict[str, float]:
    """rms and peak % position error over the steady cycles.

    Examples
    --------
    >>> t = np.arange(0, 3, 1e-3)
    >>> ref = 20 * np.sin(2 * np.pi * t)
    >>> round(tracking_errors(t, ref, ref - 0.2, 20.0, 1.0)["rms_error_pct"], 9)
    1.0
    """
    m = steady_window(t, freq_hz)
    e = np.asarray(theta_ref_deg, dtype=float)[m] - np.asarray(theta_deg, dtype=float)[m]
    return {
        "rms_error_pct": float(100.0 * np.sqrt(np.mean(e**2)) / amplitude_deg),
        "peak_error_pct": float(100.0 * np.max(np.abs(e)) / amplitude_deg),
    }


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
