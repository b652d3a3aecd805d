"""The long-test protocol's metric: per-cycle % error, steady state, cycles to settle, worst cycle.

A long test runs N reference cycles from rest (default :data:`DEFAULT_CYCLES`, 30), as a
sine-test lab does, so that controllers that learn the cycle can be judged on what
they reach.  From one run (the same % error as the 4-cycle benchmark,
:func:`ehas_env.simulation.metrics.percent_errors`, over other windows):

* ``cycle_rms_pct[j]``: the rms % error of cycle j (j = 1..N; cycle 1 is the fade-in);
* ``steady_rms_pct``: the rms % error over the last :data:`STEADY_CYCLES` (5) cycles
  together;
* ``settle_cycles``: the first cycle n >= 2 from which every cycle's rms stays within
  :data:`SETTLE_BAND` (10 %) of the steady figure (n = 2: settled as soon as the
  warm-up is over; N + 1 when even the last cycle is outside the band);
* ``worst_cycle_pct``: the largest per-cycle rms over cycles 2..N (the transient
  while the controller learns; cycle 1, the warm-up, is excluded as in the metric).

Cycle j holds the samples with ``t0 + (j-1) T <= t < t0 + j T`` (tolerance 1e-12 s,
as :func:`~ehas_env.simulation.metrics.steady_window`).
"""
from __future__ import annotations

import numpy as np

from .metrics import percent_errors

DEFAULT_CYCLES = 30
STEADY_CYCLES = 5
SETTLE_BAND = 0.10
MIN_CYCLES = STEADY_CYCLES + 2


def cycle_sums(t, theta_ref_deg, theta_deg, freq_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per whole cycle: sum of e^2 (deg^2), sample count and max|e| (deg), e = theta_ref - theta.

    Parameters
    ----------
    t : array_like
        Sample times, s.
    theta_ref_deg, theta_deg : array_like
        Reference and measured angle, deg.
    freq_hz : float
        Reference frequency, Hz.

    Returns
    -------
    tuple of ndarray
        ``(sum_sq, count, max_abs)``, one entry per whole cycle of the run.
    """
    t = np.asarray(t, dtype=float)
    e = np.asarray(theta_ref_deg, dtype=float) - np.asarray(theta_deg, dtype=float)
    period = 1.0 / freq_hz
    n = int(np.floor((t[-1] - t[0]) / period + 1e-9))
    j = np.floor((t - t[0]) / period + 1e-12 / period).astype(int)
    keep = j < n
    j, e = j[keep], e[keep]
    sum_sq = np.bincount(j, weights=e * e, minlength=n)
    count = np.bincount(j, minlength=n).astype(float)
    max_abs = np.zeros(n)
    np.maximum.at(max_abs, j, np.abs(e))
    return sum_sq, count, max_abs


def long_test_metrics(t, theta_ref_deg, theta_deg, amplitude_deg: float, freq_hz: float) -> dict:
    """The long-test figures of one run (module docstring).

    Parameters
    ----------
    t : array_like
        Sample times, s, from rest.
    theta_ref_deg, theta_deg : array_like
        Reference and measured (sensed) angle, deg.
    amplitude_deg : float
        Reference amplitude, deg.
    freq_hz : float
        Reference frequency, Hz.

    Returns
    -------
    dict
        ``cycles`` (whole cycles), ``cycle_rms_pct`` (list, %), ``steady_rms_pct`` (%),
        ``steady_peak_pct`` (%), ``settle_cycles`` (cycle number), ``worst_cycle_pct`` (%) and
        ``worst_cycle`` (its number).

    Raises
    ------
    ValueError
        If the run has fewer than :data:`MIN_CYCLES` whole cycles.

    Examples
    --------
    Ten 1 Hz cycles, error 0.4 deg in cycles 1-3, 0.2 deg after, amplitude 20 deg: the last
    five cycles give 1 %, cycle 4 is the first of the settled run, the worst learning cycle is 2 %.

    >>> t = np.arange(0, 10, 1e-3)
    >>> e = np.where(t < 3, 0.4, 0.2)
    >>> m = long_test_metrics(t, e, 0 * t, 20.0, 1.0)
    >>> round(m["steady_rms_pct"], 9), m["settle_cycles"], round(m["worst_cycle_pct"], 9)
    (1.0, 4, 2.0)
    """
    sum_sq, count, max_abs = cycle_sums(t, theta_ref_deg, theta_deg, freq_hz)
    n = sum_sq.size
    if n < MIN_CYCLES:
        raise ValueError(f"the long test needs at least {MIN_CYCLES} whole reference cycles (the last "
                         f"{STEADY_CYCLES} are the steady state, the first is a warm-up); the run has {n}")
    per = [percent_errors(s, c, m, amplitude_deg)["rms_error_pct"] for s, c, m in zip(sum_sq, count, max_abs)]
    last = slice(n - STEADY_CYCLES, n)
    steady = percent_errors(float(sum_sq[last].sum()), float(count[last].sum()), float(max_abs[last].max()),
                            amplitude_deg)
    band = steady["rms_error_pct"] * (1.0 + SETTLE_BAND)
    settle = n + 1  # n + 1: the last cycle itself is outside the band (not settled within the run)
    for j in range(n - 1, 0, -1):  # cycle numbers j + 1 = n .. 2
        if per[j] > band:
            break
        settle = j + 1
    worst = int(np.argmax(per[1:])) + 1
    return {"cycles": n, "cycle_rms_pct": [float(x) for x in per], "steady_rms_pct": steady["rms_error_pct"],
            "steady_peak_pct": steady["peak_error_pct"], "settle_cycles": int(settle),
            "worst_cycle_pct": float(per[worst]), "worst_cycle": worst + 1}
