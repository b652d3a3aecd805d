"""Measured inputs: a logged quantity the model holds constant, fed to the replay as a boundary (issue 33 item 4).

The model holds the supply pressure at the sidecar's ``supply_bar``.  A rig whose pump ripples, or whose supply
sags under a flow demand, logs a ``p_s_bar`` that varies, and the constant-supply model leaves a residual that no
term of its own explains (the flows through the metering lands go with sqrt(P_S - p)).  Taken as a *measured
input*, the logged supply drives the model instead: each step of the replay runs at the logged value.

How the logged series becomes the model's input (:func:`measured` makes the replayer, steps 1-2 are
:func:`smoothed_log`, step 3 is the replayer's, ``Replayer(..., inputs=)``):

1. gaps (empty cells) are filled by linear interpolation in time;
2. the sensor noise is filtered out with a zero-phase low-pass (4th-order Butterworth, run forward and backward,
   ``scipy.signal.sosfiltfilt``: no lag) whose cutoff is :data:`LINE_MARGIN` times the highest spectral line of the
   logged supply (:func:`ehas_env.diagnosis.disturbances.spectral_lines`), at least :data:`MIN_CUTOFF_HZ` and at
   most :data:`MAX_CUTOFF_NYQUIST` of the Nyquist frequency (no filter then): a ripple's line passes with less
   than 0.5 % loss, the white noise above the cutoff is gone;
3. it is resampled to the simulation's steps: a closed-loop run's supply is held over each control period at the
   period's mid-point value (the period's mean to second order: no half-period lag), the run starting at rest at
   it (P_A = P_B = P_S / 2); the valve bench's metered flow at sample k is taken at the supply of sample k.

In the compiled model the supply state takes the value of the step and the chambers are held below the highest
value of the run, the supply's setting (``closed_loop(..., supply)`` in ``ehas_env/simulation/loops.py``,
``run_valve_test(..., supply_log)`` in ``ehas_env/physics/integrator.py``): a chamber above a falling supply
discharges through its land, it is not clipped to it; a supply effect's own dynamics (``supply_droop``) is
overridden.  A quantity
taken as an input is no longer an output compared: ``p_s_bar`` leaves the runs' signals (cost, fit %, verdict).
Only the supply pressure is a measurable input today: the measurement format logs no return-line pressure.

The diagnosis' stage (:func:`measured_input_stage`) tries it when the logged supply varies beyond its noise, and
keeps it only when the all-data residual falls by at least :data:`ehas_env.diagnosis.honesty.TERM_SHARE` of its
excess over the noise (:func:`ehas_env.diagnosis.honesty.term_refused`).

Examples
--------
>>> t = np.arange(0.0, 2.0, 1e-3)
>>> rng = np.random.default_rng(1)
>>> y = 140.0 + 1.5 * np.sin(2 * np.pi * 37.0 * t) + 0.1 * rng.standard_normal(t.size)
>>> round(cutoff_hz(y, 1e-3), 1)
74.0
>>> s = smoothed(y, 1e-3)
>>> bool(np.std(s - 140.0 - 1.5 * np.sin(2 * np.pi * 37.0 * t)) < 0.04)
True
"""
from __future__ import annotations

import time

import numpy as np

from ehas_env.measurement.campaign import Run
from ehas_env.diagnosis.disturbances import SAME_LINE, spectral_lines
from ehas_env.measurement.replay import COST_SIGNALS, NOISE_FLOOR, UNITS, noise_level

#: logged quantities a replay can take as measured inputs, and what they are
MEASURABLE = {"p_s_bar": "the supply pressure"}
#: the smoothing's cutoff: at least this, Hz (slow sags and the test's harmonics pass) ...
MIN_CUTOFF_HZ = 50.0
#: ... and this many times the highest line of the logged quantity (4th-order Butterworth run twice: a line at half
#: the cutoff keeps 99.6 % of its amplitude) ...
LINE_MARGIN = 2.0
#: ... and at most this share of the Nyquist frequency (above it: no filter)
MAX_CUTOFF_NYQUIST = 0.8
FILTER_ORDER = 4
#: the logged quantity varies when its smoothed series' standard deviation exceeds this many noise levels
VARIES_X = 3.0


def check_inputs(inputs) -> tuple:
    """``inputs`` checked: each a quantity of :data:`MEASURABLE`.

    Parameters
    ----------
    inputs : iterable of str
        Names of logged quantities.

    Returns
    -------
    tuple of str

    Raises
    ------
    ValueError
        One line naming the bad entry and what is allowed.
    """
    out = tuple(inputs)
    for name in out:
        if name not in MEASURABLE:
            raise ValueError(f"measured input {name!r}: not a logged quantity the model can take as an input; "
                             f"allowed: {', '.join(MEASURABLE)}")
    return out


def _filled(y: np.ndarray, t: np.ndarray) -> np.ndarray | None:
    """``y`` with its empty cells (nan) interpolated in time; None when fewer than half its samples are there."""
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(y)
    if ok.sum() < max(2, y.size // 2):
        return None
    if ok.all():
        return y
    return np.interp(t, t[ok], y[ok])


def cutoff_hz(y: np.ndarray, dt: float) -> float:
    """The smoothing's cutoff for the logged series ``y`` sampled every ``dt`` s (see the module's step 2).

    Parameters
    ----------
    y : numpy.ndarray
        The logged series, no gaps.
    dt : float
        Sample period, s.

    Returns
    -------
    float
        Hz; at or above :data:`MAX_CUTOFF_NYQUIST` of the Nyquist frequency when no filter is applied.
    """
    lines = spectral_lines(y - np.mean(y), dt, None)
    top = max((f for f, _ in lines), default=0.0)
    return float(min(max(MIN_CUTOFF_HZ, LINE_MARGIN * top), MAX_CUTOFF_NYQUIST * 0.5 / dt))


def smoothed(y: np.ndarray, dt: float) -> np.ndarray:
    """The logged series ``y`` without its sensor noise: zero-phase low-pass at :func:`cutoff_hz`.

    Parameters
    ----------
    y : numpy.ndarray
        The logged series, no gaps.
    dt : float
        Sample period, s.

    Returns
    -------
    numpy.ndarray
        Same length; ``y`` itself when the cutoff reaches :data:`MAX_CUTOFF_NYQUIST` of Nyquist or the series is
        too short to filter.
    """
    from scipy.signal import butter, sosfiltfilt

    y = np.asarray(y, dtype=float)
    fc = cutoff_hz(y, dt)
    if y.size < 60 or fc >= MAX_CUTOFF_NYQUIST * 0.5 / dt * (1.0 - 1e-12):
        return y
    sos = butter(FILTER_ORDER, fc, fs=1.0 / dt, output="sos")
    return sosfiltfilt(sos, y)


def smoothed_log(run: Run, name: str) -> np.ndarray | None:
    """The logged quantity ``name`` of ``run`` as a measured input: gaps filled, noise filtered (module's steps 1
    and 2), at the run's samples, in its unit.

    Parameters
    ----------
    run : Run
        A validated run.
    name : str
        A quantity of :data:`MEASURABLE`.

    Returns
    -------
    numpy.ndarray or None
        None when the run does not log ``name`` (or fewer than half its samples).
    """
    if name not in run.columns:
        return None
    y = _filled(run.columns[name], run.t - run.t[0])
    return None if y is None else smoothed(y, run.dt)


def measured(rep, names=("p_s_bar",)):
    """``rep``'s campaign and model replayed with the logged ``names`` as measured inputs (each run that logs them).

    Parameters
    ----------
    rep : Replayer
        A replayer (:class:`ehas_env.measurement.replay.Replayer`).
    names : tuple of str
        Quantities of :data:`MEASURABLE`.

    Returns
    -------
    Replayer
        The same runs, substeps, model file, hypotheses and threads, with ``inputs`` = {run: {name: the
        :func:`smoothed_log`}}; ``rep`` itself when ``names`` is empty.

    Examples
    --------
    >>> from ehas_env.measurement.campaign import Campaign
    >>> from ehas_env.measurement.replay import Replayer
    >>> measured(Replayer(Campaign(None, [])), ("p_t_bar",))
    Traceback (most recent call last):
    ...
    ValueError: measured input 'p_t_bar': not a logged quantity the model can take as an input; allowed: p_s_bar
    """
    from ehas_env.measurement.replay import Replayer

    names = check_inputs(names)
    if not names:
        return rep
    inputs = {}
    for run in rep.campaign.runs:
        got = {n: y for n in names if (y := smoothed_log(run, n)) is not None}
        if got:
            inputs[run.name] = got
    return Replayer(rep.campaign, rep.substeps, model=rep.model, hypotheses=rep.hypotheses, threads=rep.threads,
                    inputs=inputs)


def input_names(rep) -> tuple:
    """The quantities ``rep`` takes as measured inputs (empty for a replayer without): what a replayer made for some
    of its runs (one run alone, a group) passes to :func:`measured` to replay them as ``rep`` does.

    Parameters
    ----------
    rep : Replayer

    Returns
    -------
    tuple of str
    """
    return tuple(sorted({q for given in rep.inputs.values() for q in given}))


# -- the diagnosis' stage ----------------------------------------------------------------------------------------
def variation(full, name: str = "p_s_bar") -> dict | None:
    """How the logged quantity ``name`` varies over the campaign's runs.

    Parameters
    ----------
    full : Replayer
        Every run, full length.
    name : str
        A quantity of :data:`MEASURABLE`.

    Returns
    -------
    dict or None
        None when no run logs it.  Else ``half_range`` (largest half peak-to-peak of the smoothed series over the
        runs, 1st to 99th percentile, in the quantity's unit), ``std``, ``noise`` (the run's noise level there),
        ``x_noise`` (std over noise, the largest over runs), ``run`` (where), ``lines`` (the spectral lines of the
        logged series at least :data:`VARIES_X` noise levels high, strongest first, [{frequency_hz, amplitude,
        runs}]), ``varies`` (x_noise above :data:`VARIES_X`, or a line).
    """
    best = None
    lines: dict = {}
    for case in full.cases:
        run = case.run
        if name not in run.columns:
            continue
        y = _filled(run.columns[name], run.t - run.t[0])
        if y is None:
            continue
        nz = max(noise_level(y), NOISE_FLOOR[name])
        s = smoothed(y, run.dt)
        k0 = case.skip
        std = float(np.std(s[k0:]))
        lo, hi = np.percentile(s[k0:], [1.0, 99.0])
        item = {"half_range": float(0.5 * (hi - lo)), "std": std, "noise": nz, "x_noise": std / nz, "run": run.name}
        if best is None or item["x_noise"] > best["x_noise"]:
            best = item
        for f, a in spectral_lines(y[k0:] - np.mean(y[k0:]), run.dt, None):
            if a < VARIES_X * nz:
                continue
            key = next((g for g in lines if abs(g - f) <= SAME_LINE * f), f)  # one line over the runs
            e = lines.setdefault(key, {"frequency_hz": f, "amplitude": 0.0, "runs": []})
            e["amplitude"] = max(e["amplitude"], a)
            e["runs"].append(run.name)
    if best is None:
        return None
    best["lines"] = sorted(({"frequency_hz": round(v["frequency_hz"], 2), "amplitude": float(f"{v['amplitude']:.3g}"),
                             "runs": v["runs"]} for v in lines.values()), key=lambda d: -d["amplitude"])
    best["varies"] = bool(best["x_noise"] > VARIES_X or best["lines"])
    return best


def residual_x_noise(rep, sims, without=()) -> float:
    """The all-data residual (x what does not repeat, the verdict's measure) over the compared signals, less
    ``without`` (a quantity taken as an input is compared in neither model).

    Parameters
    ----------
    rep : Replayer
    sims : list
        Its simulated runs.
    without : iterable of str
        Signals left out.

    Returns
    -------
    float
    """
    from ehas_env.measurement.verdict import blocks_of, grade

    return float(grade(blocks_of(rep, sims, [s for s in COST_SIGNALS if s not in set(without)]))["residual_x_noise"])


def measured_input_stage(full, rep, final_fit, parts, say=None) -> tuple:
    """The diagnosis' stage of measured inputs: when the logged supply pressure varies beyond its noise, the final
    model refitted with it as a measured input, kept when it removes at least
    :data:`ehas_env.diagnosis.honesty.TERM_SHARE` of the all-data residual's excess over the noise.

    Parameters
    ----------
    full : Replayer
        Every run, full length (the diagnosis' ``full``).
    rep : Replayer
        The fit data (the diagnosis' ``rep``: windows of the fit runs).
    final_fit : Fit
        The final model, fitted on ``rep``: its free parameters are refitted from its values.
    parts : dict
        The validation samples ({case index of ``full``: first sample}); the record gives the residual of the runs
        they are in (whole runs, the verdict's measure) before and after (None when empty).
    say : callable, optional
        Progress text.

    Returns
    -------
    (Fit or None, dict)
        The refitted model (on ``measured(rep, record["inputs"])``) when kept, else None; and the record, in the
        diagnosis JSON's terms: ``quantity``, ``logged``, ``variation`` (:func:`variation`), ``tried``, ``kept``,
        ``inputs`` (what the replayers must take from now on: ``[]`` unless kept), ``residual_x_noise_before`` /
        ``_after`` (all data, without the input's own signal), ``share_removed``, ``refused`` (honesty rule 1's
        words, or None), ``validation_before`` / ``_after``, ``elapsed_s`` and ``text``.
    """
    from ehas_env.diagnosis.fitting import _value_of, fit
    from ehas_env.diagnosis.honesty import TERM_SHARE, share_removed, term_refused

    say = say or (lambda msg: None)
    t0 = time.perf_counter()
    name = "p_s_bar"
    what = MEASURABLE[name]
    rec = {"quantity": name, "logged": False, "variation": None, "tried": False, "kept": False, "inputs": [],
           "residual_x_noise_before": None, "residual_x_noise_after": None, "share_removed": None, "refused": None,
           "validation_before": None, "validation_after": None, "elapsed_s": 0.0, "text": ""}

    trial = []  # (replayer, its copy with the input): the copy's replays are counted on the replayer

    def done(f, text):
        for r, copy in trial:
            r.n_evals += copy.n_evals
        rec["text"] = text
        rec["elapsed_s"] = round(time.perf_counter() - t0, 2)
        say("  " + text)
        return f, rec

    var = variation(full, name)
    if var is None:
        return done(None, f"{what} is not logged: it stays the sidecars' constant")
    rec["logged"] = True
    rec["variation"] = {k: (float(f"{v:.4g}") if isinstance(v, float) else v) for k, v in var.items()}
    unit = UNITS[name]
    how = f"{what} logged varies by +-{var['half_range']:.3g} {unit} (std {var['x_noise']:.1f}x its noise level"
    how += f", in {var['run']})"
    if var["lines"]:
        ln = var["lines"][0]
        how += f" with a line at {ln['frequency_hz']:.2f} Hz ({ln['amplitude']:.3g} {unit} amplitude)"
    if not var["varies"]:
        return done(None, f"{how}: within its noise, so it stays the sidecars' constant")
    say(f"{how}: refitting the final model with it as a measured input")
    rec["tried"] = True
    full_in, rep_in = measured(full, (name,)), measured(rep, (name,))
    trial += [(full, full_in)] + ([(rep, rep_in)] if rep is not full else [])
    before_sims = full.simulate(final_fit.model)
    before = residual_x_noise(full, before_sims, without=(name,))
    start = {(fp.effect, fp.name): _value_of(final_fit.model, fp) for fp in final_fit.free}
    refit = fit(rep_in, final_fit.free, start, final_fit.model) if final_fit.free else None
    model = refit.model if refit is not None else final_fit.model
    after_sims = full_in.simulate(model)
    after = residual_x_noise(full_in, after_sims)
    rec["residual_x_noise_before"], rec["residual_x_noise_after"] = round(before, 3), round(after, 3)
    rec["share_removed"] = round(share_removed(before, after), 3)
    if parts:
        from ehas_env.measurement.verdict import blocks_of, grade

        def val(r, sims, without=()):
            sub = [s for s in COST_SIGNALS if s not in without]
            blocks = [b for b in blocks_of(r, sims, sub) if b.run in {r.cases[i].run.name for i in parts}]
            return round(float(grade(blocks)["residual_x_noise"]), 3) if blocks else None

        rec["validation_before"] = val(full, before_sims, (name,))
        rec["validation_after"] = val(full_in, after_sims)
    if term_refused(before, after) is not None:  # honesty rule 1, as for a term
        rec["refused"] = (f"{what} as a measured input, the model refitted, takes the residual from {before:.3g}x to "
                          f"{after:.3g}x noise on all data: it removes {100 * rec['share_removed']:.0f} % of the "
                          f"excess over the noise, less than the {100 * TERM_SHARE:.0f} % it must remove")
        return done(None, f"{how}; used as a measured input, the residual goes {before:.3g} -> {after:.3g}x noise "
                          f"({100 * rec['share_removed']:.0f} % of the excess over the noise, less than the "
                          f"{100 * TERM_SHARE:.0f} % it must remove): not used")
    rec["kept"], rec["inputs"] = True, [name]
    if refit is None:  # nothing free to refit: the final model itself, on the fit data with the input
        from ehas_env.diagnosis.fitting import Fit

        sims = rep_in.simulate(model)
        refit = Fit(model=model, cost=rep_in.log_cost(sims), free=[], sims=sims, table=rep_in.fit_table(sims))
    return done(refit, f"{how}; used as a measured input, the residual falls {before:.3g} -> {after:.3g}x noise "
                       f"({100 * rec['share_removed']:.0f} % of the excess over the noise)")
