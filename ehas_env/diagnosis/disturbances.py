"""Measured disturbances: lines in the residual at frequencies that are not harmonics of the test (issue 33 item 4).

A model driven by a sine reference answers at the reference's frequency and its harmonics; whatever it misses of
its own physics leaves a residual there too.  A line in the residual at a frequency that is no harmonic of the
run's test frequency comes from outside the loop: a pump's ripple on the supply, a mains hum in a sensor, a
vibration of the frame.  No term of the model explains it, and the diagnosis should say what it is: a
disturbance, with its frequency, its amplitude in the signal's unit and the signal where it is strongest (a line
in the logged supply pressure ``p_s_bar``, which the model holds at the sidecar's ``supply_bar``, is a measured
disturbance of a boundary the model treats as constant).

For each closed-loop run and logged signal the residual (measured - model, after the ramp and one settling cycle)
is windowed (Hann) and its periodogram's peaks :data:`LINE_DB` above the median background (over +-
:data:`BACKGROUND_BINS` bins) are lines.  Each line's frequency is refined on a grid of a tenth of a bin and its
amplitude fitted as a sine there; a line within :data:`HARMONIC_TOL` bins (at least) of a multiple of the test
frequency, or below :data:`MIN_FREQ_HZ`, is not a disturbance.  Lines of different runs and signals at the same
frequency (within :data:`SAME_LINE` of it, or one bin) are one disturbance.

Examples
--------
>>> t = np.arange(0.0, 3.0, 1e-3)
>>> rng = np.random.default_rng(0)
>>> e = 0.5 * np.sin(2 * np.pi * 23.6 * t) + 0.3 * np.sin(2 * np.pi * 4.0 * t) + 0.05 * rng.standard_normal(t.size)
>>> [(round(f, 1), round(a, 2)) for f, a in spectral_lines(e, 1e-3, 2.0)]
[(23.6, 0.5)]
"""
from __future__ import annotations

import math

import numpy as np

#: a line stands this many dB above the residual's median background spectrum (white noise: the periodogram
#: exceeds its median by 20 dB with probability about 1e-30 per bin)
LINE_DB = 20.0
BACKGROUND_BINS = 15  # the background is the median over this many bins either side
#: a line this many frequency bins (1 / run length) or less from a harmonic of the test frequency is the model's
HARMONIC_TOL = 0.6
MIN_FREQ_HZ = 0.5  # slower lines are drifts of a run, not disturbances
SAME_LINE = 0.02  # lines of runs and signals within this share of their frequency are one disturbance
MAX_LINES = 5  # per run and signal, the strongest


def spectral_lines(e: np.ndarray, dt: float, f0: float | None) -> list[tuple[float, float]]:
    """The lines of a residual that are no harmonics of ``f0``: [(frequency Hz, amplitude in e's unit)].

    Parameters
    ----------
    e : numpy.ndarray
        The residual, uniformly sampled.
    dt : float
        Sample period, s.
    f0 : float or None
        The run's test frequency, Hz (None: no harmonics excluded).

    Returns
    -------
    list of (float, float)
        Strongest first, at most :data:`MAX_LINES`.
    """
    e = np.asarray(e, dtype=float)
    n = e.size
    if n < 8 * BACKGROUND_BINS:
        return []
    e = e - e.mean()
    w = np.hanning(n)
    spec = np.abs(np.fft.rfft(e * w)) ** 2
    freqs = np.fft.rfftfreq(n, dt)
    df = freqs[1]
    pad = np.pad(spec, BACKGROUND_BINS, mode="reflect")
    from numpy.lib.stride_tricks import sliding_window_view

    bg = np.median(sliding_window_view(pad, 2 * BACKGROUND_BINS + 1), axis=1)[: spec.size]
    ratio = spec / np.maximum(bg, 1e-300)
    thr = 10.0 ** (LINE_DB / 10.0)
    peaks = [k for k in range(2, spec.size - 1)
             if ratio[k] >= thr and spec[k] >= spec[k - 1] and spec[k] >= spec[k + 1] and freqs[k] >= MIN_FREQ_HZ]
    peaks.sort(key=lambda k: spec[k], reverse=True)
    t = np.arange(n) * dt
    out: list[tuple[float, float]] = []
    for k in peaks:
        # the frequency on a grid of a tenth of a bin, where the windowed sine's projection is largest
        grid = freqs[k] + df * np.linspace(-1.0, 1.0, 21)
        proj = [abs(np.dot(e * w, np.exp(-2j * np.pi * f * t))) for f in grid]
        f = float(grid[int(np.argmax(proj))])
        if f0:
            h = round(f / f0)
            if h >= 1 and abs(f - h * f0) <= max(HARMONIC_TOL * df, 1e-9):
                continue
        if any(abs(f - g) <= max(SAME_LINE * f, 2 * df) for g, _ in out):
            continue
        # the amplitude: a least-squares sine (and cosine) at f
        X = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
        a, b = np.linalg.lstsq(X, e, rcond=None)[0]
        out.append((f, float(math.hypot(a, b))))
        if len(out) >= MAX_LINES:
            break
    return out


def disturbances(rep, sims) -> list[dict]:
    """The disturbances in the residual of a replay: lines no harmonic of the runs' test frequencies explains.

    Parameters
    ----------
    rep : Replayer
        The campaign replayed (:class:`ehas_env.measurement.replay.Replayer`).
    sims : list
        Its simulated runs (the final model).

    Returns
    -------
    list of dict
        Strongest first (in noise units): ``frequency_hz``, ``amplitude`` and ``unit`` and ``signal`` where it is
        strongest against that signal's noise, ``x_noise`` (amplitude over the noise level there), ``runs`` (the
        runs it is seen in, of ``of_runs`` closed-loop runs), ``signals`` {signal: amplitude}, ``boundary`` (True
        when seen in a logged quantity the model holds constant: the supply pressure), ``text``.
    """
    from ehas_env.measurement.replay import UNITS
    from ehas_env.measurement.verdict import SETTLE_CYCLES

    found = []  # (f, amplitude, x_noise, run, signal)
    n_cl = 0
    for case, sim in zip(rep.cases, sims):
        if sim is None or case.run.kind != "closed_loop":
            continue
        n_cl += 1
        ref = case.run.meta["reference"]
        f0 = float(ref["freq_hz"])
        k0 = max(case.skip, int(round((float(ref.get("ramp_cycles", 1.0)) + SETTLE_CYCLES) / f0 / case.run.dt)))
        for s in case.signals:
            if s not in sim or s == "load_kN":  # the load is A (P_A - P_B): its lines are the pressures'
                continue
            e = case.measured[s][k0:] - sim[s][k0:]
            for f, a in spectral_lines(e, case.run.dt, f0):
                found.append((f, a, a / case.noise[s], case.run.name, s))
    groups: list[list] = []
    for item in sorted(found, key=lambda x: -x[2]):
        g = next((g for g in groups if abs(item[0] - g[0][0]) <= SAME_LINE * item[0]), None)
        if g is None:
            groups.append([item])
        else:
            g.append(item)
    out = []
    for g in groups:
        f, a, x, run, s = g[0]  # the strongest, in noise units
        runs = sorted({it[3] for it in g})
        sig = {}
        for it in g:
            sig[it[4]] = max(sig.get(it[4], 0.0), it[1])
        d = {"frequency_hz": round(float(np.median([it[0] for it in g])), 2), "amplitude": float(f"{a:.3g}"),
             "unit": UNITS.get(s, ""), "signal": s, "x_noise": round(x, 1), "runs": runs, "of_runs": n_cl,
             "signals": {k: float(f"{v:.3g}") for k, v in sorted(sig.items(), key=lambda kv: -kv[1])},
             "boundary": "p_s_bar" in sig}
        d["text"] = disturbance_text(d)
        out.append(d)
    return out


def disturbance_text(d: dict) -> str:
    """A disturbance in words."""
    where = "in every closed-loop run" if len(d["runs"]) == d["of_runs"] else f"in {', '.join(d['runs'])}"
    text = (f"a line at {d['frequency_hz']:.2f} Hz, no harmonic of the test frequency, strongest in {d['signal']} "
            f"({d['amplitude']:.3g} {d['unit']} amplitude, {d['x_noise']:.1f}x its noise level), {where}: a "
            "disturbance from outside the model's loop")
    if d["boundary"]:
        text += ("; the logged supply pressure carries it, which the model holds at the sidecar's supply_bar: a "
                 "measured disturbance of the supply")
    return text


def disturbance_lines(dists: list) -> list[str]:
    """The disturbances in words, for the console and the report (empty when there are none).

    Parameters
    ----------
    dists : list of dict
        The diagnosis' ``disturbances``.

    Returns
    -------
    list of str
    """
    if not dists:
        return []
    return ["disturbances (lines in the residual at no harmonic of the test frequency):"] + \
        ["  " + d["text"] for d in dists]
