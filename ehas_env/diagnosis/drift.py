"""Parameters that change between runs: fitted per run, tested, related to what the sidecars record (issue 33).

A diagnosis fits one value of each parameter to the whole campaign.  A rig whose friction rises as it warms up,
whose oil takes in air over a day, or whose valve wears, has parameters that differ from run to run; the one
value then stands for none of them, and the check that an effect fits the same on two groups of runs
(:mod:`ehas_env.diagnosis.keeping`) rejects it without saying which runs differ, by how much, or against what.
This stage, run after the final model is chosen, says it:

1. **Per run** (:func:`fit_per_run`): every fitted parameter of the final model (and the parameters of the best
   effects judged but not kept: a parameter that changes between runs makes its effect fit differently on two
   groups of runs, or fail on the validation runs) is refitted on each closed-loop run alone (its fit window),
   from the campaign's values, with its cluster-robust 95 % interval (:func:`ehas_env.diagnosis.fitting.confidence`).
2. **Differ beyond their intervals?** (:func:`differ`): the chi-square test of one common value against the per-run
   values, each run's standard deviation its 95 % half-width / 1.96, never below the model-error floor of the
   agreement rule (:data:`ehas_env.diagnosis.keeping.MODEL_ERROR_FLOOR`); estimates at the end of their fit range
   are left out (no point estimate).  A parameter *drifts* when p < :data:`DRIFT_P`; or, when its values rise or
   fall at every step of the recording order over at least :data:`TREND_RUNS` runs (a steady change in time), or
   of a condition the sidecars record (an oil temperature: the model's own errors follow the runs' settings, not
   what the operator measures beside them), when the same test with the floor lowered to :data:`TREND_FLOOR` gives
   p < :data:`DRIFT_P`.
3. **Against what?** (:func:`relate`): Spearman's rank correlation of the per-run values with each quantity the
   sidecars record (:func:`run_features`: recording order, from the optional sidecar key ``recorded``, an ISO 8601
   start time, else the file order; disc sets; amplitude; frequency; supply pressure; the logged mean chamber
   pressure).  The one of largest magnitude (at least :data:`FOLLOW_RHO`) is what the parameter follows; the size
   is the ratio of a straight line through the per-run values (weighted by their intervals) from the first run to
   the last, in that quantity's order.

The JSON of the diagnosis (docs/measurement-format.md) holds ``per_run`` and ``drift``.

Examples
--------
>>> p, chi2, dof = differ([100.0, 101.0, 99.0], [(95.0, 105.0), (96.0, 106.0), (94.0, 104.0)])
>>> p > 0.5 and dof == 2
True
>>> differ([100.0, 180.0, 260.0], [(98.0, 102.0), (176.0, 184.0), (255.0, 265.0)])[0] < 1e-6
True
>>> r = relate([100.0, 180.0, 260.0], [(98.0, 102.0), (176.0, 184.0), (255.0, 265.0)],
...            {"recording order": [1, 2, 3], "disc sets": [5, 1, 3]})
>>> r["follows"], r["direction"], round(r["ratio_first_last"], 2)
('recording order', 'rises', 2.6)
"""
from __future__ import annotations

import math
from datetime import datetime

import numpy as np

from ehas_env.measurement.campaign import Campaign
from ehas_env.diagnosis.fitting import SCREEN_NFEV, Fit, FreeParam, _unit, _value_of, confidence, fit, run_range
from ehas_env.diagnosis.keeping import MODEL_ERROR_FLOOR
from ehas_env.diagnosis.measured_inputs import input_names, measured
from ehas_env.measurement.replay import ModelSpec, Replayer

#: per-run values differ beyond their intervals when the chi-square test of one common value gives p below this
#: (several parameters are tested per campaign: a strict level keeps false alarms on clean campaigns rare)
DRIFT_P = 1e-3
#: a drifting parameter follows a recorded quantity when their rank correlation is at least this in magnitude
FOLLOW_RHO = 0.8
#: fewest runs with a point estimate a parameter needs for the test
MIN_RUNS = 3
#: a steady change in time: with at least TREND_RUNS runs whose values rise (or fall) at every step of the
#: recording order, the per-run values are tested with the model-error floor lowered to TREND_FLOOR (a perfectly
#: ordered sequence of 5 runs comes by chance once in 60; the model's own errors, which follow the runs' settings,
#: not the time, rarely part per-run values by more than this: K per run on clean campaigns within 1 %)
TREND_RUNS = 5
TREND_FLOOR = 0.05
#: a quantity the logs show (the mean chamber pressure) is related to only when the runs' values of it span at
#: least this share of its level: a symmetric valve holds the mean near Ps / 2 in every run (109.9-110.1 bar on
#: five runs of the conditions set), and a parameter ranked along such a spread follows chance or the runs'
#: settings, not it (beta that fell along the oil temperature, rank correlation -0.8, was reported as "40.7 % per
#: 0.1 bar of mean chamber pressure", -0.9)
LOGGED_SPAN = 0.01
#: the sidecar key of a run's start time (ISO 8601, e.g. "2026-11-27T09:30:00"); optional
RECORDED_KEY = "recorded"


def _label(fp: FreeParam) -> str:
    return f"{fp.effect or 'baseline'}.{fp.name}"


def _std(v: float, lo: float, hi: float, floor: float = MODEL_ERROR_FLOOR) -> float:
    """Standard deviation of an estimate from its 95 % interval, at least the model-error floor's."""
    half = max(0.5 * (hi - lo), floor * abs(v))
    return max(half / 1.959964, 1e-300)


def differ(values, intervals, floor: float = MODEL_ERROR_FLOOR) -> tuple[float, float, int]:
    """The chi-square test of one common value against per-run estimates.

    Parameters
    ----------
    values : sequence of float
        One estimate per run.
    intervals : sequence of (low, high)
        Their 95 % intervals.
    floor : float
        Least 95 % half-width, relative to the estimate (the model-error floor).

    Returns
    -------
    (p, chi2, dof)
        p-value of "one common value", the statistic and its degrees of freedom (runs - 1).
    """
    from scipy.stats import chi2 as chi2_dist

    v = np.asarray(values, dtype=float)
    s = np.array([_std(x, lo, hi, floor) for x, (lo, hi) in zip(v, intervals)])
    w = 1.0 / s**2
    m = float(np.sum(w * v) / np.sum(w))
    c = float(np.sum(w * (v - m) ** 2))
    dof = len(v) - 1
    return (float(chi2_dist.sf(c, dof)) if dof > 0 else 1.0), c, dof


def relate(values, intervals, features: dict) -> dict:
    """What per-run values follow among the recorded quantities, which way and by how much.

    Parameters
    ----------
    values : sequence of float
        One estimate per run.
    intervals : sequence of (low, high)
        Their 95 % intervals.
    features : dict
        {quantity: one value per run} (:func:`run_features`); constant ones are skipped.

    Returns
    -------
    dict
        ``follows`` (the quantity, or None when no rank correlation reaches :data:`FOLLOW_RHO`), ``rho``,
        ``rho_p`` (its p-value), ``direction`` ("rises"/"falls" along it), ``first``, ``last`` (a straight line
        through the values at the first and last run in that order), ``ratio_first_last`` (None when a sign
        changes), ``correlations`` {quantity: rho}.
    """
    from scipy.stats import spearmanr

    v = np.asarray(values, dtype=float)
    s = np.array([_std(x, lo, hi) for x, (lo, hi) in zip(v, intervals)])
    cors = {}
    for name, x in features.items():
        x = np.asarray(x, dtype=float)
        if len(x) != len(v) or np.ptp(x) == 0.0 or np.ptp(v) == 0.0:
            continue
        r = spearmanr(x, v)
        rho = float(r.statistic if hasattr(r, "statistic") else r[0])
        if math.isfinite(rho):  # (a quantity with a NaN among its values has none)
            cors[name] = (rho, float(r.pvalue if hasattr(r, "pvalue") else r[1]))
    out = {"follows": None, "rho": None, "rho_p": None, "direction": None, "first": None, "last": None,
           "quantity_from": None, "quantity_to": None,
           "ratio_first_last": None, "correlations": {k: round(c[0], 3) for k, c in cors.items()}}
    if not cors:
        return out
    def line(name):  # a straight line through the values in that quantity, weighted by their intervals
        x = np.asarray(features[name], dtype=float)
        mu, span = float(np.mean(x)), float(np.ptp(x))  # fitted on (x - mu) / span: any magnitude of a condition
        A = np.column_stack([np.ones_like(x), (x - mu) / span]) / s[:, None]
        (c0, c1), *_ = np.linalg.lstsq(A, v / s, rcond=None)
        try:
            se = math.sqrt(max(float(np.linalg.inv(A.T @ A)[1, 1]), 0.0)) / span
        except np.linalg.LinAlgError:
            se = float("nan")
        b = c1 / span
        return x, c0 - b * mu, b, se, float(np.sum((A @ np.array([c0, c1]) - v / s) ** 2))

    # the strongest; on a tie (few runs rank alike by chance), the one a straight line fits best, then the first
    # listed (recording order before the run's settings, the sidecars' conditions before what the logs show)
    top = max(round(abs(c[0]), 6) for c in cors.values())
    lines = {k: line(k) for k in cors if round(abs(cors[k][0]), 6) == top}
    best = min(lines, key=lambda k: (round(lines[k][4], 9), list(features).index(k)))
    rho, p = cors[best]
    x, a, b, se, _ = lines[best]
    first, last = a + b * x.min(), a + b * x.max()
    out["law"] = law(a, b, se, x, best)
    out.update(rho=round(rho, 3), rho_p=p, first=float(first), last=float(last),
               quantity_from=float(x.min()), quantity_to=float(x.max()),
               direction="rises" if last > first else "falls",
               ratio_first_last=float(last / first) if first * last > 0 else None)
    if abs(rho) >= FOLLOW_RHO - 1e-9:  # a rank correlation is a ratio of integers: 0.8 comes out as 0.7999999...
        out["follows"] = best
    return out


def law(a: float, b: float, se: float, x: np.ndarray, quantity: str) -> dict | None:
    """A parameter's straight line along a recorded quantity as a law: its change per a round step of the quantity,
    in % of its value at the quantity's mean, with the 95 % interval of the slope (None: the value there is 0).

    Parameters
    ----------
    a, b : float
        Intercept and slope of the weighted line (value = a + b x).
    se : float
        The slope's standard error.
    x : ndarray
        The quantity per run.
    quantity : str
        Its name.

    Returns
    -------
    dict or None
        ``per`` (the step, in the quantity's unit), ``pct`` (change per step, % of the value at the mean),
        ``pct_ci95`` [low, high], ``slope``, ``slope_ci95``, ``quantity``.

    Examples
    --------
    >>> x = np.array([20.0, 40.0, 60.0])
    >>> law(1.2e9, -2.4e6, 2e5, x, "oil_temperature_C")["pct"]  # -2.4e6 per degree at 1.104e9: -2.2 % per 10
    -2.17
    """
    mid = a + b * float(np.mean(x))
    if mid == 0.0:
        return None
    span = float(np.ptp(x))
    step = 10.0 ** math.floor(math.log10(span)) if span > 0 else 1.0
    half = 1.959964 * se
    pct = float(100.0 * b * step / mid)
    ci = sorted([float(100.0 * (b - half) * step / mid), float(100.0 * (b + half) * step / mid)])
    return {"quantity": quantity, "per": step, "pct": round(pct, 2), "pct_ci95": [round(c, 2) for c in ci],
            "slope": float(f"{b:.4g}"), "slope_ci95": [float(f"{b - half:.4g}"), float(f"{b + half:.4g}")]}


def run_features(runs) -> tuple[dict, str]:
    """The quantities each run's sidecar and log record: {quantity: one value per run}, and the order's name.

    Parameters
    ----------
    runs : list of Run
        Closed-loop runs.

    Returns
    -------
    (dict, str)
        ``recording order`` (by the sidecar's ``recorded`` start time when every run has one, else the file
        order, named ``file order``), ``disc sets``, ``amplitude (deg)``, ``frequency (Hz)``, ``supply (bar)``,
        every condition each sidecar records as a number (:func:`recorded_conditions`: a rig's
        ``oil_temperature_C``), ``mean chamber pressure (bar)`` (when both chamber pressures are logged and its
        values span at least :data:`LOGGED_SPAN` of its level); and the order's name.

    Raises
    ------
    ValueError
        A ``recorded`` value that is not an ISO 8601 date and time.
    """
    times = []
    for r in runs:
        t = r.meta.get(RECORDED_KEY)
        if t is None:
            times = None
            break
        try:
            times.append(datetime.fromisoformat(str(t)).timestamp())
        except ValueError:
            raise ValueError(f"{r.name}.json: key '{RECORDED_KEY}' = {t!r}; expected the run's start time as an ISO "
                             "8601 date and time, e.g. \"2026-11-27T09:30:00\"") from None
    order_name = "recording order" if times is not None else "file order"
    order = np.argsort(np.argsort(times, kind="stable")) + 1 if times is not None else np.arange(1, len(runs) + 1)
    feats = {order_name: [float(o) for o in order],
             "disc sets": [float(r.meta["disc_sets"]) for r in runs],
             "amplitude (deg)": [float(r.meta["reference"]["amplitude_deg"]) for r in runs],
             "frequency (Hz)": [float(r.meta["reference"]["freq_hz"]) for r in runs],
             "supply (bar)": [float(r.meta["supply_bar"]) for r in runs]}
    conds = recorded_conditions(runs)
    logged = {}
    if all("p_a_bar" in r.columns and "p_b_bar" in r.columns for r in runs):
        mean_p = [float(np.mean(0.5 * (r.columns["p_a_bar"] + r.columns["p_b_bar"]))) for r in runs]
        if np.ptp(mean_p) >= LOGGED_SPAN * abs(float(np.mean(mean_p))):
            logged["mean chamber pressure (bar)"] = mean_p
    return {**feats, **conds, **logged}, order_name


#: sidecar keys the format gives a meaning of its own (docs/measurement-format.md): not conditions to relate to
FORMAT_KEYS = {"version", "disc_sets", "supply_bar"}  # the numbers a run sidecar's format defines


def _conditions(run) -> dict:
    """A run's recorded conditions: the numbers of its sidecar's ``conditions`` object and the numeric top-level
    keys the format does not define (a rig's ``oil_temperature_C``, ``hours_run``)."""
    out = {k: v for k, v in run.meta.items() if k not in FORMAT_KEYS}
    extra = run.meta.get("conditions")
    if isinstance(extra, dict):
        out.update(extra)
    return {k: v for k, v in out.items() if isinstance(v, (int, float)) and not isinstance(v, bool)
            and math.isfinite(v)}


def recorded_conditions(runs) -> dict:
    """The conditions every run's sidecar records as a number (:func:`_conditions`): {key: one value per run}, in
    the first run's order.

    Examples
    --------
    >>> from types import SimpleNamespace as R
    >>> runs = [R(meta={"kind": "closed_loop", "oil_temperature_C": 30 + 10 * i, "conditions": {"hours": i}})
    ...         for i in range(3)]
    >>> recorded_conditions(runs)
    {'oil_temperature_C': [30.0, 40.0, 50.0], 'hours': [0.0, 1.0, 2.0]}
    """
    per_run = [_conditions(r) for r in runs]
    if not per_run:
        return {}
    return {k: [float(c[k]) for c in per_run] for k in per_run[0] if all(k in c for c in per_run[1:])}


def fit_per_run(rep: Replayer, runs: list, fixed: ModelSpec, free: list[FreeParam]) -> list[dict]:
    """Refit ``free`` on each run alone, from the values of ``fixed``, with 95 % intervals.

    Parameters
    ----------
    rep : Replayer
        Gives the compiled model (its ``model``, ``substeps``, ``hypotheses``); its ``n_evals`` counts the replays.
    runs : list of Run
        The runs (each its fit window, :func:`ehas_env.diagnosis.candidates.windowed`).
    fixed : ModelSpec
        The model (and the start values).
    free : list of FreeParam
        The parameters refitted (the baseline's beta and K over the ranges of the effects that re-open them,
        :func:`ehas_env.diagnosis.fitting.run_range`).

    Returns
    -------
    list of dict
        Per run: ``run`` and {label: (value, (low, high), at_range_end)} under ``params``.
    """
    out = []
    free = [run_range(fp) for fp in free]  # a run's beta or K may lie beyond the campaign's recalibration range
    start = {(fp.effect, fp.name): _value_of(fixed, fp) for fp in free}
    for run in runs:
        sub = Replayer(Campaign(rep.campaign.path, [run]), substeps=rep.substeps, model=rep.model,
                       hypotheses=rep.hypotheses)
        sub = measured(sub, input_names(rep))  # a logged supply the diagnosis took as an input stays one
        f = fit(sub, free, start, fixed, max_nfev=SCREEN_NFEV * len(free), tol=1e-3)
        ci = confidence(sub, f)
        rep.n_evals += sub.n_evals
        params = {}
        for fp in free:
            v = _value_of(f.model, fp)
            params[_label(fp)] = (v, ci[(fp.effect, fp.name)], fp.end(v) is not None)
        out.append({"run": run.name, "params": params})
    return out


def drift_of(per_run: list[dict], features: dict, units: dict, steady_along=None) -> list[dict]:
    """The parameters whose per-run values differ beyond their intervals, each related to the recorded quantities.

    Parameters
    ----------
    per_run : list of dict
        :func:`fit_per_run`'s result.
    features : dict
        :func:`run_features`' quantities (one value per run of ``per_run``).
    units : dict
        {label: unit}.
    steady_along : sequence of str, optional
        The quantities along which values that rise (or fall) at every step over at least :data:`TREND_RUNS` runs
        are tested with the floor lowered to :data:`TREND_FLOOR` (default: the first of ``features``, the recording
        order).  Only what the sidecars record apart from the runs' settings belongs here -- the time and the
        measured conditions (an oil temperature): the model's own errors follow the settings (disc sets,
        amplitude, frequency), never these.

    Returns
    -------
    list of dict
        Per drifting parameter: ``parameter``, ``unit``, ``p_value``, ``chi2``, ``dof``, ``follows``, ``rho``,
        ``direction``, ``first``, ``last``, ``ratio_first_last``, ``correlations``, ``text``.
    """
    out = []
    labels = list(per_run[0]["params"]) if per_run else []
    for lab in labels:
        ests = [(i, *r["params"][lab]) for i, r in enumerate(per_run)]
        inner = [(i, v, ci) for i, v, ci, pinned in ests if not pinned and all(map(math.isfinite, (v, *ci)))]
        if len(inner) < MIN_RUNS:
            continue
        idx = [i for i, _, _ in inner]
        vals = [v for _, v, _ in inner]
        cis = [ci for _, _, ci in inner]
        p, c, dof = differ(vals, cis)
        along = [next(iter(features))] if steady_along is None and features else list(steady_along or ())
        steady = any(ordered(vals, [features[q][i] for i in idx]) for q in along if q in features)
        if p >= DRIFT_P and steady and len(vals) >= TREND_RUNS:
            p, c, dof = differ(vals, cis, TREND_FLOOR)  # a steady change in time (see TREND_FLOOR)
        if p >= DRIFT_P:
            continue
        rel = relate(vals, cis, {k: [x[i] for i in idx] for k, x in features.items()})
        d = {"parameter": lab, "unit": units.get(lab, ""), "p_value": float(f"{p:.3g}"), "chi2": round(c, 2),
             "dof": dof, **{k: rel[k] for k in ("follows", "rho", "direction", "correlations", "quantity_from",
                                                "quantity_to")},
             "first": None if rel["first"] is None else float(f"{rel['first']:.4g}"),
             "last": None if rel["last"] is None else float(f"{rel['last']:.4g}"),
             "ratio_first_last": None if rel["ratio_first_last"] is None else round(rel["ratio_first_last"], 3),
             "law": rel.get("law") if rel["follows"] is not None else None,
             "runs": [per_run[i]["run"] for i in idx]}
        d["text"] = drift_text(d)
        out.append(d)
    return out


def ordered(values, order) -> bool:
    """Whether ``values`` rise at every step, or fall at every step, taken in ``order`` (no ties in it).

    Examples
    --------
    >>> ordered([1.0, 3.0, 2.0], [1, 3, 2]), ordered([1.0, 3.0, 2.0], [1, 2, 3])
    (True, False)
    """
    o = np.asarray(order, dtype=float)
    if len(np.unique(o)) < len(o):
        return False
    d = np.diff(np.asarray(values, dtype=float)[np.argsort(o)])
    return bool(np.all(d > 0) or np.all(d < 0))


def way(d: dict) -> str:
    """Which way a drifting parameter goes, in words: its ``direction``, but for a term signed negative by its law
    (a friction torque c < 0 against the motion), whose number falls as its size grows: said as what it does.

    Parameters
    ----------
    d : dict
        A drift record: ``direction`` ("rises"/"falls") and ``ratio_first_last`` (None when a sign changes).

    Returns
    -------
    str

    Examples
    --------
    >>> way({"direction": "falls", "ratio_first_last": 2.27}), way({"direction": "falls", "ratio_first_last": 0.6})
    ('grows in size', 'falls')
    >>> way({"direction": "rises", "ratio_first_last": 0.44})
    'shrinks in size'
    """
    r = d.get("ratio_first_last")
    if r is not None and (d["direction"] == "falls") == (r >= 1.0):  # same sign, number and size opposite: negative
        return "grows in size" if r >= 1.0 else "shrinks in size"
    return d["direction"]


def drift_text(d: dict) -> str:
    """One drifting parameter in words: "coulomb_friction.Fc rises 2.4x from the first run to the last, in
    recording order (...)"."""
    u = f" {d['unit']}" if d["unit"] and d["unit"] != "-" else ""
    test = (f"per-run values differ beyond their 95 % intervals (chi-square {d['chi2']:.3g} on {d['dof']} degrees of "
            f"freedom, p = {d['p_value']:.2g})")
    if d["follows"] is None:
        best = max(d["correlations"].items(), key=lambda kv: abs(kv[1]), default=(None, 0.0))
        return (f"{d['parameter']} differs between runs but follows none of the recorded quantities (largest rank "
                f"correlation {best[1]:+.2f}, with {best[0]}); {test}")
    size = (f"{d['ratio_first_last']:.2g}x" if d["ratio_first_last"] is not None and d["ratio_first_last"] >= 1 else
            f"to {d['ratio_first_last']:.2g}x" if d["ratio_first_last"] is not None else
            f"by {d['last'] - d['first']:+.3g}{u}")
    if d["follows"] in ("recording order", "file order"):
        along = f"from the first run to the last, in {d['follows']}"
    else:  # the parameter follows a run setting: its change is along that setting, not along the runs' order
        along = (f"as {d['follows']} goes from {d.get('quantity_from', float('nan')):.4g} to "
                 f"{d.get('quantity_to', float('nan')):.4g}")
    lw = d.get("law")
    per = ""
    if lw is not None and d["follows"] not in ("recording order", "file order"):
        per = (f": {'rises' if lw['pct'] > 0 else 'falls'} {abs(lw['pct']):.3g} % per {lw['per']:g} of "
               f"{d['follows']} (95 % interval {lw['pct_ci95'][0]:+.3g} to {lw['pct_ci95'][1]:+.3g} %)")
    return (f"{d['parameter']} {way(d)} {size} {along} ({d['first']:.4g} -> "
            f"{d['last']:.4g}{u}; rank correlation {d['rho']:+.2f}){per}; {test}")


def per_run_stage(rep: Replayer, runs: list, windows: list, final: Fit, also: dict | None = None, *,
                  say=None) -> dict:
    """The stage of the diagnosis: per-run parameters and their drift, in the diagnosis JSON's terms.

    Parameters
    ----------
    rep : Replayer
        The diagnosis' fit replayer (its compiled model).
    runs : list of Run
        The campaign's closed-loop runs (held-out runs included), in file order.
    windows : list of Run
        The same runs cut to their fit windows (:func:`ehas_env.diagnosis.candidates.windowed`).
    final : Fit
        The final model, fitted: its free parameters are refitted per run.
    also : dict, optional
        {effect: Fit} of effects judged but not kept (they fitted differently on separate groups of runs, or failed
        on the validation runs: what a parameter that changes from run to run does): each is refitted per run
        too (its own parameters), added to the final model.
    say : callable, optional
        Progress text.

    Returns
    -------
    dict
        ``{"per_run": {"runs": [...], "order": str}, "drift": [...]}``; ``per_run`` None when fewer than
        :data:`MIN_RUNS` closed-loop runs.
    """
    from ehas_env.diagnosis.fitting import own_params

    say = say or (lambda msg: None)
    if len(runs) < MIN_RUNS or not final.free:
        return {"per_run": None, "drift": []}
    feats, order = run_features(runs)
    steady_along = [order, *recorded_conditions(runs)]  # recorded apart from the settings (see drift_of)
    wins = list(windows)
    say(f"fitting the model's {len(final.free)} parameters on each of {len(runs)} runs alone (drift between runs)")
    groups = [(None, final.model, list(final.free))]
    for effect, g in (also or {}).items():
        fixed = ModelSpec(effects={**{n: dict(p) for n, p in final.model.effects.items()},
                                   effect: dict(g.model.effects[effect])},
                          beta=final.model.beta, K=final.model.K, terms=dict(final.model.terms))
        groups.append((effect, fixed, own_params(effect)))
    per, drift = [{"run": r.name, "params": {}} for r in runs], []
    units = {}
    for effect, fixed, free in groups:
        if effect is not None:
            say(f"  {effect} (judged, not kept): refitted on each run")
        res = fit_per_run(rep, wins, fixed, free)
        units.update({_label(fp): _unit(fp.effect, fp.name) for fp in free})
        for row, r in zip(per, res):
            row["params"].update({k: v for k, v in r["params"].items() if k not in row["params"]})
        drift += [d for d in drift_of(res, feats, units, steady_along) if d["parameter"] not in {x["parameter"] for x in drift}]
    for d in drift:
        say("  " + d["text"])
    rows = []
    for r, row in zip(runs, per):
        rows.append({"run": row["run"], "recorded": r.meta.get(RECORDED_KEY),
                     "params": {k: {"value": _r(v), "low": _r(ci[0]), "high": _r(ci[1]), "at_range_end": bool(pin)}
                                for k, (v, ci, pin) in row["params"].items()}})
    return {"per_run": {"order": order, "units": units, "runs": rows}, "drift": drift}


def _r(v: float) -> float:
    return float(f"{v:.4g}")


def drift_lines(drift: list, per_run: dict | None) -> list[str]:
    """The drift stage in words, for the console and the report: one line per drifting parameter, or that none
    differs (empty when no per-run fit was made).

    Parameters
    ----------
    drift : list of dict
        The diagnosis' ``drift``.
    per_run : dict or None
        The diagnosis' ``per_run``.

    Returns
    -------
    list of str
    """
    if per_run is None:
        return []
    n = len(per_run["runs"])
    if not drift:
        return [f"parameters per run ({n} closed-loop runs, each fitted alone): none differs between runs beyond its "
                "95 % intervals"]
    return [f"parameters per run ({n} closed-loop runs, each fitted alone, {per_run['order']}):"] + \
        ["  " + d["text"] for d in drift]
