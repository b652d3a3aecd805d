"""Measured disturbances: lines in the residual at frequencies that are not harmonics of the test (issue 33 item 4).

A model driven by a sine reference answers at the reference's frequency and its harmonics; whatever it misses of
its own physics leaves a residual there too.  A line in the residual at a frequency that is no harmonic of the
run's test frequency comes from elsewhere: from outside the loop (a pump's ripple on the supply, a mains hum in a
sensor, a vibration of the frame) or from the rig ringing on its own (below).  The diagnosis says what it is,
with its frequency, its amplitude in the signal's unit and the signal where it is strongest (a line
in the logged supply pressure ``p_s_bar``, which the model holds at the sidecar's ``supply_bar``, is a measured
disturbance of a boundary the model treats as constant).

For each closed-loop run and logged signal the residual (measured - model, after the ramp and one settling cycle)
is windowed (Hann) and its periodogram's peaks :data:`LINE_DB` above the median background (over +-
:data:`BACKGROUND_BINS` bins) are lines.  Each line's frequency is refined on a grid of a tenth of a bin and its
amplitude fitted as a sine there; a line within :data:`HARMONIC_TOL` bins (at least) of a multiple of the test
frequency, or below :data:`MIN_FREQ_HZ`, is not a disturbance.  Lines of different runs and signals at the same
frequency (within :data:`SAME_LINE` of it, or one bin) are one disturbance.

Not every such line comes from outside the loop: a rig that rings on its own (a loop near its stability limit, a
softer oil column or line than the model's) leaves a line at a frequency of its own too, which the model, better
damped there, lacks.  The runs tell them apart (:func:`origins`): a source outside the loop (a pump, a mains hum, a
vibration of the frame) keeps its frequency whatever the load, while a mode of the loop and its load moves with the
load's inertia -- its line falls as disc sets are added.  A line seen at one load only cannot be told either way, and
the words say so.

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
#: lines at different loads are one mode of the loop and its load when their frequencies fall as the disc sets rise,
#: within this factor from the lightest load to the heaviest (the rig's 1-7 sets change its inertia about 3.4x: a
#: mode of the load moves by its square root, a loop's mode by less)
MODE_SPAN = 3.0
#: a line of a ringing run at k f_m + j f_test (k <= HARMONIC_K, |j| <= HARMONIC_J), within this share of its
#: frequency (at least 0.1 Hz: the line's frequency is refined to a tenth of a bin), is the ringing's harmonic or beat
HARMONIC_K, HARMONIC_J, COMBINATION_TOL = 4, 2, 0.01
#: what a line's origin is, in the JSON's ``origin``
ORIGINS = ("supply", "outside", "mode", "undetermined")


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
    sets, test_hz = {}, {}  # the disc sets of each closed-loop run (its load), its test frequency
    for case, sim in zip(rep.cases, sims):
        if sim is None or case.run.kind != "closed_loop":
            continue
        n_cl += 1
        sets[case.run.name] = case.run.meta.get("disc_sets")
        ref = case.run.meta["reference"]
        f0 = float(ref["freq_hz"])
        test_hz[case.run.name] = f0
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
             "boundary": "p_s_bar" in sig, "disc_sets": {r: sets.get(r) for r in runs},
             "test_hz": {r: test_hz[r] for r in runs}}
        out.append(d)
    for d, (origin, why) in zip(out, origins(out)):
        d["origin"], d["origin_why"] = origin, why
        d["text"] = disturbance_text(d)
    return out


def _fmt_sets(n) -> str:
    return f"{n} set" + ("" if n == 1 else "s")


def origins(dists: list) -> list[tuple[str, str]]:
    """Where each line comes from, told by the loads of the runs it is seen in: (one of :data:`ORIGINS`, why).

    ``supply``: the logged supply pressure carries it; ``outside``: the same frequency in runs of different disc
    sets (a source that does not know the load); ``mode``: lines of runs of different disc sets whose frequencies fall
    as the sets rise, within :data:`MODE_SPAN` (a mode of the loop and its load, which the rig has and the model lacks
    or damps more); ``undetermined``: seen at one load only.

    Parameters
    ----------
    dists : list of dict
        Disturbances with ``frequency_hz``, ``boundary`` and ``disc_sets`` ({run: disc sets}).

    Returns
    -------
    list of (str, str)
        One per disturbance, in order.

    Examples
    --------
    >>> d = [{"frequency_hz": 7.33, "boundary": False, "disc_sets": {"r7": 7}},
    ...      {"frequency_hz": 8.45, "boundary": False, "disc_sets": {"r5": 5}},
    ...      {"frequency_hz": 23.6, "boundary": False, "disc_sets": {"r3": 3, "r5": 5}}]
    >>> [o for o, _ in origins(d)]
    ['mode', 'mode', 'outside']
    """
    loads = [sorted({n for n in d.get("disc_sets", {}).values() if n is not None}) for d in dists]
    out: list[tuple[str, str] | None] = [None] * len(dists)
    for i, d in enumerate(dists):
        if d.get("boundary"):
            out[i] = ("supply", "the logged supply pressure carries it")
        elif len(loads[i]) >= 2:
            out[i] = ("outside", f"the same frequency at {' and '.join(map(str, loads[i]))} disc sets: a source that "
                                 "does not know the load")
    # lines seen at one load each: a family whose frequency falls as the load rises is one mode
    single = [i for i in range(len(dists)) if out[i] is None and len(loads[i]) == 1]
    for i in single:
        if out[i] is not None:
            continue
        fam = {loads[i][0]: i}
        for j in single:
            if j != i and out[j] is None and loads[j][0] not in fam:
                trial = dict(fam)
                trial[loads[j][0]] = j
                f = [dists[k]["frequency_hz"] for _, k in sorted(trial.items())]
                if all(a > b for a, b in zip(f, f[1:])) and f[0] / f[-1] <= MODE_SPAN:
                    fam = trial
        if len(fam) >= 2:
            words = ", ".join(f"{dists[k]['frequency_hz']:.2f} Hz at {_fmt_sets(n)}" for n, k in sorted(fam.items()))
            for k in fam.values():
                out[k] = ("mode", f"its frequency falls as disc sets are added ({words}), as a mode of the loop and "
                                  "its load does")
    # a line of a run that rings, at a harmonic of the ringing or its beat with the test (k f_m + j f_test), is the
    # ringing's too
    ringing = [(run, dists[k]["frequency_hz"]) for k in range(len(dists)) if out[k] is not None
               and out[k][0] == "mode" for run in dists[k].get("disc_sets", {})]
    for i, d in enumerate(dists):
        if out[i] is not None or len(d.get("disc_sets", {})) != 1:
            continue
        run = next(iter(d["disc_sets"]))
        f, ft = d["frequency_hz"], d.get("test_hz", {}).get(run)
        for r, fm in ringing:
            if r != run or ft is None:
                continue
            hit = next(((k, j) for k in range(1, HARMONIC_K + 1) for j in range(-HARMONIC_J, HARMONIC_J + 1)
                        if (k, j) != (1, 0) and abs(f - (k * fm + j * ft)) <= max(COMBINATION_TOL * f, 0.1)), None)
            if hit is not None:
                k, j = hit
                combo = (f"{k} x " if k > 1 else "") + f"{fm:.2f} Hz" + \
                    ("" if j == 0 else f" {'+-'[j < 0]} " + (f"{abs(j)} x " if abs(j) > 1 else "") + f"{ft:g} Hz")
                out[i] = ("mode", f"at {combo} in {run}: a harmonic of the rig's own ringing at {fm:.2f} Hz there, "
                                  "or its beat with the test")
                break
    for i in range(len(dists)):
        if out[i] is None:
            at = _fmt_sets(loads[i][0]) if loads[i] else "one load"
            out[i] = ("undetermined", f"seen at {at} only")
    return out


def disturbance_text(d: dict) -> str:
    """A disturbance in words."""
    where = "in every closed-loop run" if len(d["runs"]) == d["of_runs"] else f"in {', '.join(d['runs'])}"
    text = (f"a line at {d['frequency_hz']:.2f} Hz, no harmonic of the test frequency, strongest in {d['signal']} "
            f"({d['amplitude']:.3g} {d['unit']} amplitude, {d['x_noise']:.1f}x its noise level), {where}")
    origin, why = d.get("origin", "outside"), d.get("origin_why", "")
    if origin == "supply":
        return text + (": a disturbance from outside the model's loop; the logged supply pressure carries it, which "
                       "the model holds at the sidecar's supply_bar: a measured disturbance of the supply")
    if origin == "outside":
        return text + f": a disturbance from outside the model's loop ({why})"
    if origin == "mode":
        return text + (f": the rig rings on its own, not a disturbance from outside ({why}); the model lacks that "
                       "mode or damps it more: a softer oil column or line, a higher valve gain at null, a loop "
                       "nearer its stability limit than the model's")
    return text + (f": from outside the model's loop, or the rig ringing on its own ({why}: runs at other disc sets "
                   "would tell them apart)")


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
