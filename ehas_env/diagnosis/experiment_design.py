"""The runs that decide between explanations these logs cannot tell apart (``ehas plan-test``, issue 34).

A diagnosis lists under ``alternatives`` the explanations that fit its campaign
as well as the one reported (:mod:`ehas_env.diagnosis.alternatives`).  This
module simulates candidate runs inside the rig's safe envelope
(:data:`ENVELOPE`: disc sets, amplitude, frequency, a mean angle off centre,
supply pressure, and the valve bench at another supply) with each explanation's
fitted model and chooses the few (at most :data:`MAX_RUNS`, at most
:data:`MAX_LOG_S` s of logging) that separate them most -- optimal experiment
design for model discrimination (Box & Hill 1967; Atkinson & Fedorov's
T-optimal designs).

**Separation.** On a candidate run, the two models' predictions of every signal
the campaign logged differ by ``r = (y_a - y_b) / sigma`` (sigma: the campaign's
noise of that signal).  Each model's parameters are uncertain: the separation
is taken after the best refit of one model's effect parameters to the other's
prediction, each parameter (and the baseline's beta and K) allowed to move within its 95 % interval from the
campaign (a linearised bounded least-squares step on forward-difference
sensitivities), in both directions, the smaller kept -- what remains cannot be
explained away by the uncertainty of either.  With ``J`` the mean of the
remaining ``r^2``, the run separates them by ``10 log10(1 + J)`` dB over the
campaign's noise: the score difference a diagnosis of the logged run would show
(a model that misses by ``J`` noise variances has ``1 + J`` where the right one
has 1).

**Feasible runs.** A candidate is left out when the reported model cannot follow it
(tracking error, stroke end, current at the amplifier's limit) or when any
explanation's own run of it does not repeat from cycle to cycle by more than the
campaign's noise after the fade-in and a settling cycle (a limit cycle: there
two models part by the phase of an oscillation, which a small difference of
any kind decides, not by their physics).

**Choice.** The best run for each pair first, then the runs that raise the
weakest pair's separation most, while the plan stays within its limits; a run's
separation must reach :data:`MIN_SEPARATION_DB` to be chosen at all.  A pair that
no chosen run separates by :data:`~ehas_env.diagnosis.alternatives.SEPARATED_DB`
(what one run decides alone) is decided by the second diagnosis over the whole
campaign, where the planned runs are a share of the data: its next-best runs fill
the plan's limits.

The plan (:func:`plan_json`) is one JSON object: ``format`` ``"ehas-test-plan"``,
``version`` 1, ``campaign``, ``separates`` ``[{a, b, predicted_db}]`` and
``runs``, each a run sidecar of the measurement format
(docs/measurement-format.md) with ``name`` and ``duration_s``;
``valve_open_loop`` runs carry ``excitation`` ``{type "chirp", f0_hz, f1_hz,
amplitude_mA}``.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ehas_env.diagnosis.alternatives import SEPARATED_DB
from ehas_env.measurement.campaign import Campaign, CampaignError, validate_meta, validate_run
from ehas_env.measurement.replay import COST_SIGNALS, ModelSpec, Replayer
from ehas_env.measurement.synthetic import CHIRP, chirp_current
from ehas_env.physics.effects import REGISTRY
from ehas_env.physics.rig import AREA, CRANK_RADIUS, DEAD_VOLUME, HALF_STROKE, RATED_CURRENT, THETA_STROKE_END
from ehas_env.simulation.reference import SineReference

FORMAT = "ehas-test-plan"
VERSION = 1
MAX_RUNS = 4  # runs in a plan ...
MAX_LOG_S = 30.0  # ... and seconds of logging, all runs together
RUN_S = 3.0  # each candidate run: the fade-in, a settling cycle and steady cycles at >= 1 Hz
MIN_SEPARATION_DB = 0.3  # a run that separates no pair by this much (fitting.MIN_SCORE) is not worth logging
STROKE_DEG = math.degrees(THETA_STROKE_END)  # 44.43 deg


@dataclass(frozen=True)
class Envelope:
    """The rig's safe envelope for planned runs (docs/rig.md).

    Attributes
    ----------
    disc_sets : tuple
        Disc sets tried (1 to 7 fit the rig).
    amplitudes_deg, freqs_hz : tuple
        Sine amplitudes (deg) and frequencies (Hz) tried: the span of the book's tables 1.9-1.15.
    stroke_margin_deg : float
        |offset| + amplitude stays this far inside the stroke end (44.43 deg): room for the tracking error.
    supply_bar : tuple
        (lowest, highest) supply, bar: the highest is the pressure filter's 250 bar rating; below 100 bar the
        actuator's force (A x Ps = 7.7 kN) no longer drives the heavy disc sets through the book's sines.
    valve_supply_bar : tuple
        Supplies of the valve bench runs tried (the rated test is 70 bar).
    chirp : tuple
        The bench chirp: f0 Hz, f1 Hz, amplitude mA (at most the amplifier's 20 mA).
    stroke_deg, rated_mA : float
        The rig's stroke end (crank angle, deg: asin(half stroke / crank radius), the book's 44.43) and amplifier
        limit (mA, the book's 20): a model file's rig has its own (:meth:`for_model`).
    max_tracking_pct : float
        A candidate the reported model cannot follow within this RMS error (% of the amplitude) is left out.
    max_saturation : float
        ... nor one whose current sits at the amplifier's limit for more than this share of the samples.
    pressure_margin : float
        ... nor one where any explanation's chamber pressure falls below ``m Ps`` (m this share of the run's
        supply) or rises above the supply, at any time (start included).  Near the tank pressure oil releases its
        air and cavitates; above the supply the load pumps oil back against the pump's check valve: limits of a
        real rig that no candidate model is checked against (a run planned there parts the true rig from every
        model, not the models from each other: in the entrained-air case of results/test_plans the true rig's
        chambers swung between 4 and 150 bar at 150 bar supply).
    max_chamber_ratio : float
        A mean angle off centre goes no further than where the larger chamber holds this many times the smaller's
        oil (:attr:`offset_limit_deg`: 24 deg on the book's rig).  A sine that dwells near a stroke end holds one
        chamber near its dead volume, where its stiffness and pressure swings grow steeply and the loop's margin
        shrinks: the true rig of the entrained-air case of results/test_plans (10 deg about 30 deg, ratio 2.4
        at the mean) fell into a limit cycle there that neither fitted model had.
    rig : RigParams, optional
        The geometry of a model file's rig (:meth:`for_model`); the book's when None.
    """

    disc_sets: tuple = (1, 4, 7)
    amplitudes_deg: tuple = (10.0, 25.0)
    freqs_hz: tuple = (1.0, 3.0)
    stroke_margin_deg: float = 4.0
    supply_bar: tuple = (100.0, 250.0)
    valve_supply_bar: tuple = (140.0, 210.0)
    chirp: tuple = CHIRP
    stroke_deg: float = STROKE_DEG
    rated_mA: float = RATED_CURRENT
    max_tracking_pct: float = 15.0
    max_saturation: float = 0.02
    pressure_margin: float = 0.1
    max_chamber_ratio: float = 2.0
    rig: object = None

    @classmethod
    def for_model(cls, model=None, **kw) -> "Envelope":
        """The envelope of the rig a model file describes (the book's when ``model`` is None).

        Parameters
        ----------
        model : PlantModel, optional
            A model file read by :func:`ehas_env.simulation.model_file.load_model`.
        **kw
            Other fields of the envelope.

        Returns
        -------
        Envelope
        """
        if model is None:
            return cls(**kw)
        rig = model.rig_for(1)
        # the measurement format checks a mean angle against the book's stroke end (reference.check_offset): a
        # rig with a longer stroke is planned within the book's
        stroke = min(math.degrees(math.asin(min(rig.half_stroke / rig.radius, 1.0))), STROKE_DEG)
        return cls(stroke_deg=stroke, rated_mA=float(rig.i_max), rig=rig, **kw)

    @property
    def offset_limit_deg(self) -> float:
        """The largest mean angle off centre: where ``V_A / V_B`` reaches :attr:`max_chamber_ratio` (deg)."""
        lo, hi = 0.0, self.stroke_deg
        if chamber_ratio(hi, self.rig) <= self.max_chamber_ratio:
            return hi
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if chamber_ratio(mid, self.rig) <= self.max_chamber_ratio else (lo, mid)
        return lo

    def offsets(self, amplitude_deg: float) -> tuple:
        """Mean angles tried with an amplitude: centred and as far off centre both ways as the stroke allows."""
        far = math.floor(min(self.stroke_deg - self.stroke_margin_deg - amplitude_deg, self.offset_limit_deg))
        return (0.0, float(far), float(-far)) if far >= 5 else (0.0,)

    def supplies(self, campaign_bar: float) -> tuple:
        """Supplies tried: the campaign's and, in the envelope, about two thirds of it."""
        lo, hi = self.supply_bar
        other = min(max(round(campaign_bar * 2.0 / 3.0 / 10.0) * 10.0, lo), hi)
        return tuple(sorted({min(max(campaign_bar, lo), hi), other}))

    def problem(self, run: dict) -> str | None:
        """Why a planned run is outside the envelope (None when inside).

        Parameters
        ----------
        run : dict
            A run of a plan (a sidecar with ``name`` and ``duration_s``).

        Returns
        -------
        str or None
        """
        lo, hi = self.supply_bar
        if run["kind"] == "valve_open_loop":
            ex = run.get("excitation") or {}
            if not (0 < run["supply_bar"] <= hi):
                return f"supply {run['supply_bar']:g} bar beyond the {hi:g} bar the rig's filters are rated for"
            if not 0 < ex.get("amplitude_mA", 0) <= self.rated_mA:
                return f"chirp amplitude {ex.get('amplitude_mA')!r} mA beyond the amplifier's {self.rated_mA:g} mA"
            return None
        ref = run["reference"]
        reach = ref["amplitude_deg"] + abs(ref.get("offset_deg", 0.0))
        if not 1 <= run["disc_sets"] <= 7:
            return f"{run['disc_sets']} disc sets; the rig takes 1 to 7"
        if reach > self.stroke_deg - self.stroke_margin_deg:
            return f"the sine reaches {reach:g} deg, within {self.stroke_margin_deg:g} deg of the stroke end"
        if abs(ref.get("offset_deg", 0.0)) > self.offset_limit_deg:
            return (f"the mean angle {ref['offset_deg']:g} deg is beyond {self.offset_limit_deg:.1f} deg, where one "
                    f"chamber holds {self.max_chamber_ratio:g}x the other's oil")
        if not lo <= run["supply_bar"] <= hi:
            return f"supply {run['supply_bar']:g} bar outside [{lo:g}, {hi:g}] bar"
        if not 0 < ref["freq_hz"] <= max(self.freqs_hz):
            return f"frequency {ref['freq_hz']:g} Hz beyond {max(self.freqs_hz):g} Hz"
        return None


ENVELOPE = Envelope()


@dataclass
class Explanation:
    """One explanation of the campaign: a name, its model and the 95 % intervals of its effect parameters."""

    name: str
    model: ModelSpec
    ci95: dict  # (effect, param) -> (low, high)
    reason: str = ""


@dataclass
class Candidate:
    """A candidate run, its sidecar and what it shows."""

    meta: dict
    separation: dict = field(default_factory=dict)  # (a, b) -> (J after refit, signal where most)
    feasible: str | None = None  # why not, when the reported model cannot run it inside the envelope

    @property
    def name(self) -> str:
        return self.meta["name"]

    def db(self, pair) -> float:
        j = self.separation.get(pair, (0.0, ""))[0]
        return 10.0 * math.log10(1.0 + j)


# --- the diagnosis ---------------------------------------------------------------------------


def read_diagnosis(path) -> tuple[dict, list[Explanation]]:
    """Read a diagnosis JSON (``ehas diagnose --json``) and its explanations: the reported one and the alternatives.

    Parameters
    ----------
    path : str or Path
        The diagnosis JSON.

    Returns
    -------
    doc : dict
        The whole JSON.
    explanations : list of Explanation
        The reported model first, then each alternative the logs cannot tell from it.

    Raises
    ------
    FileNotFoundError, ValueError
        A missing file, not JSON, not a diagnosis, or one written before alternatives were listed.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such diagnosis file (write one with ehas diagnose CAMPAIGN --json {p})")
    if p.is_dir():
        raise ValueError(f"{p} is a folder; expected the diagnosis JSON that ehas diagnose --json wrote")
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{p}: not a JSON file ({str(exc).splitlines()[0]}); expected the diagnosis JSON that "
                         "ehas diagnose --json wrote") from None
    need = ("verdict", "campaign", "reported_model", "alternatives")
    if not isinstance(doc, dict) or not all(k in doc for k in ("verdict", "campaign")):
        raise ValueError(f"{p}: not a diagnosis JSON (no 'verdict' and 'campaign'); expected the file ehas diagnose "
                         "--json wrote")
    missing = [k for k in need if k not in doc]
    if missing:
        raise ValueError(f"{p}: a diagnosis without '{missing[0]}' (written before ehas listed alternatives); run "
                         "ehas diagnose again")
    rep = doc["reported_model"]
    rows = doc.get("model", {}).get("ci95", [])
    ci = {(None if r.get("effect") in (None, "baseline") else r["effect"], r["param"]): (r["low"], r["high"])
          for r in rows}
    out = [Explanation(" + ".join(rep["effects"]) or "baseline", _spec(rep, p), ci)]
    for a in doc["alternatives"]:
        eff = a["model"]["effects"]
        ci_a = {k: v for k, v in ci.items() if k[0] in eff and k[0] != a["in_place_of"]}
        ci_a.update({(a["name"], n): tuple(v) for n, v in a.get("ci95", {}).items()})
        m = a["model"]
        for n in ("beta", "K"):  # the baseline's numbers: the reported one's interval widths, about its own values
            if (None, n) in ci:
                lo, hi = ci[(None, n)]
                v0 = rep[n]
                ci_a[(None, n)] = (m[n] - (v0 - lo), m[n] + (hi - v0))
        out.append(Explanation(a["name"], _spec(m, p), ci_a, a.get("reason", "")))
    return doc, out


def rig_model(doc: dict, model, where) -> object:
    """The rig a diagnosis' explanations were fitted on: the model file it records (``reported_model.rig_model``,
    its label: name and file name), given as ``model``; None for the book's rig.

    Parameters
    ----------
    doc : dict
        The diagnosis JSON.
    model : str, Path or None
        The model file the user gives (``ehas plan-test --model``).
    where : str
        The diagnosis file, for messages.

    Returns
    -------
    PlantModel or None

    Raises
    ------
    ValueError
        The diagnosis was made on a model file's rig and none (or another) is given, or on the book's and one is.
    """
    from ehas_env.simulation.model_file import load_model

    recorded = doc["reported_model"].get("rig_model")
    if recorded and model is None:
        raise ValueError(f"{where}: diagnosed on the model file's rig {recorded}; give that file with --model FILE "
                         "(the plan is simulated on the rig the explanations were fitted on)")
    if model is None:
        return None
    if not recorded:
        raise ValueError(f"--model {model}: {where} was diagnosed on the book's rig (no --model), so its "
                         "explanations were fitted there; plan without --model, or diagnose again with --model")
    m = load_model(model)
    if m.label != recorded:
        raise ValueError(f"--model {model}: this is the model {m.label!r}, but {where} was diagnosed on "
                         f"{recorded!r}; give that file")
    return m


def _spec(m: dict, path) -> ModelSpec:
    for n in m.get("effects", {}):
        if n not in REGISTRY:
            raise ValueError(f"{path}: effect '{n}' is not loaded (a user effect: give its folder with "
                             "--effects-path)")
    return ModelSpec(effects={n: dict(p) for n, p in m["effects"].items()}, beta=m["beta"], K=m["K"])


# --- candidates ------------------------------------------------------------------------------


def candidates(campaign: Campaign, envelope: Envelope = ENVELOPE) -> list[dict]:
    """The candidate runs' sidecars (with ``name`` and ``duration_s``), inside ``envelope``.

    Parameters
    ----------
    campaign : Campaign
        The campaign diagnosed: its controller and supply.
    envelope : Envelope
        The rig's safe envelope.

    Returns
    -------
    list of dict
    """
    cl = [r for r in campaign.runs if r.kind == "closed_loop"]
    if not cl:
        raise ValueError("the campaign has no closed-loop run: its controller is what planned runs use")
    ctrl = dict(cl[0].meta["controller"])
    supply = cl[0].meta["supply_bar"]
    out = []
    for ps in envelope.supplies(supply):
        for sets in envelope.disc_sets:
            for amp in envelope.amplitudes_deg:
                for f in envelope.freqs_hz:
                    for off in envelope.offsets(amp):
                        name = f"plan_{sets}sets_{amp:g}deg_{f:g}hz_{ps:g}bar" + (
                            f"_off{off:g}deg".replace("-", "m") if off else "")
                        ref = {"amplitude_deg": amp, "freq_hz": f, "phase_rad": 0.0, "ramp_cycles": 1.0}
                        if off:
                            ref["offset_deg"] = off
                        out.append({"name": name.replace(".", "p"), "duration_s": RUN_S, "kind": "closed_loop",
                                    "disc_sets": sets, "supply_bar": ps, "reference": ref, "controller": ctrl})
    f0, f1, amp = envelope.chirp
    for ps in envelope.valve_supply_bar:
        out.append({"name": f"plan_valve_{ps:g}bar".replace(".", "p"), "duration_s": RUN_S,
                    "kind": "valve_open_loop", "supply_bar": ps,
                    "excitation": {"type": "chirp", "f0_hz": f0, "f1_hz": f1, "amplitude_mA": amp}})
    return out


def _run_of(meta: dict, noise: dict, signals: tuple):
    """A run to replay for a planned sidecar: the reference (closed loop) or the chirp (valve), the other
    columns zeros (only their names matter: the replay simulates them), the campaign's noise levels."""
    side = {k: v for k, v in meta.items() if k not in ("name", "duration_s", "excitation")}
    if meta["kind"] == "closed_loop":
        dt = 1.0 / meta["controller"]["rate_hz"]
        n = int(round(meta["duration_s"] / dt))
        t = np.arange(n) * dt
        r = validate_meta(side, where=meta["name"])["reference"]
        ref = SineReference(r["amplitude_deg"], r["freq_hz"], phase=r["phase_rad"], ramp_cycles=r["ramp_cycles"],
                            offset_deg=r.get("offset_deg", 0.0))(t)[0]
        cols = {"t": t, "theta_ref_deg": ref, **{s: np.zeros(n) for s in signals if s != "theta_ref_deg"}}
        for s in ("theta_deg", "current_mA"):
            cols.setdefault(s, np.zeros(n))
    else:
        dt = 1e-3
        n = int(round(meta["duration_s"] / dt))
        ex = meta["excitation"]
        cols = {"t": np.arange(n) * dt, "current_mA": chirp_current(n, dt, ex["f0_hz"], ex["f1_hz"], ex["amplitude_mA"]),
                "flow_lpm": np.zeros(n)}
    side["window"] = {"noise": {s: v for s, v in noise.items() if s in cols}}
    return validate_run(meta["name"], cols, side)


def campaign_noise(campaign: Campaign) -> tuple[dict, tuple]:
    """The campaign's noise level per signal (the median over its runs) and the closed-loop signals it logs."""
    rep = Replayer(campaign)
    levels: dict[str, list] = {}
    logged: set = set()
    for c in rep.cases:
        for s, v in c.noise.items():
            levels.setdefault(s, []).append(v)
        if c.run.kind == "closed_loop":
            logged |= set(c.signals)
    return {s: float(np.median(v)) for s, v in levels.items()}, tuple(sorted(logged))


# --- separation ------------------------------------------------------------------------------


def _residual(case, a: dict, b: dict) -> tuple[np.ndarray, list]:
    """(a - b) / noise over the cost signals of ``case``, stacked; the signal of each block."""
    parts, names = [], []
    for s in case.signals:
        if s in COST_SIGNALS:
            parts.append((a[s] - b[s]) / case.noise[s])
            names.append((s, a[s].size))
    return np.concatenate(parts), names


def _refit_left(r: np.ndarray, S: np.ndarray | None, lo, hi) -> np.ndarray:
    """What is left of r after the best bounded linear refit r ~ S d, lo <= d <= hi."""
    if S is None or S.shape[1] == 0:
        return r
    from scipy.optimize import lsq_linear

    d = lsq_linear(S, r, bounds=(lo, hi), method="bvls").x
    return r - S @ d


def _sensitivities(ex: Explanation) -> list:
    """(effect, param, value, step, low shift, high shift) of each effect parameter with an interval."""
    out = []
    for (e, n), (lo, hi) in ex.ci95.items():
        if e is None and n in ("beta", "K"):
            v = float(getattr(ex.model, n))
        elif e not in ex.model.effects or n not in ex.model.effects[e]:
            continue
        else:
            v = float(ex.model.effects[e][n])
        lo, hi = min(lo, v), max(hi, v)
        if hi - lo <= 0.0:
            continue
        h = 0.25 * (hi - lo)
        out.append((e, n, v, h, lo - v, hi - v))
    return out


def _shifted(model: ModelSpec, e: str | None, n: str, v: float) -> ModelSpec:
    """``model`` with one number set: an effect's parameter, or (``e`` None) beta or K."""
    eff = {k: dict(p) for k, p in model.effects.items()}
    beta, K = model.beta, model.K
    if e is None:
        beta, K = (v, K) if n == "beta" else (beta, v)
    else:
        eff[e][n] = v
    return ModelSpec(effects=eff, beta=beta, K=K, terms=dict(model.terms))


def separations(rep: Replayer, explanations: list[Explanation], pairs: list[tuple], say=None) -> list[dict]:
    """For every run of ``rep`` and pair (i, j) of explanations: (J left after the best refit, signal where most).

    Parameters
    ----------
    rep : Replayer
        The candidate runs.
    explanations : list of Explanation
        The models.
    pairs : list of (int, int)
        Indices into ``explanations``.
    say : callable, optional
        Progress lines.

    Returns
    -------
    rows : list of dict
        Per run: {(i, j): (J, signal)}.
    sims : list
        Each explanation's own simulation of every run (index as ``explanations``).
    """
    say = say or (lambda msg: None)
    models, where = [], {}
    for k, ex in enumerate(explanations):
        where[k] = [len(models)]
        models.append(ex.model)
        for e, n, v, h, _, _ in _sensitivities(ex):
            where[k].append(len(models))
            models.append(_shifted(ex.model, e, n, v + h))
    say(f"simulating {len(rep.cases)} candidate runs with {len(explanations)} models and their sensitivities "
        f"({len(models) * len(rep.cases)} replays)")
    sims = rep.simulate_many(models)
    out = []
    for ci, case in enumerate(rep.cases):
        row = {}
        for i, j in pairs:
            best = None
            for a, b in ((i, j), (j, i)):  # a's prediction as data, b refitted to it
                ya, yb = sims[where[a][0]][ci], sims[where[b][0]][ci]
                if ya is None or yb is None:
                    continue
                r, names = _residual(case, ya, yb)
                sens = _sensitivities(explanations[b])
                cols = [(_residual(case, sims[m][ci], yb)[0]) / h for m, (_, _, _, h, _, _) in
                        zip(where[b][1:], sens)]
                S = np.column_stack(cols) if cols else None
                left = _refit_left(r, S, [s[4] for s in sens], [s[5] for s in sens])
                # J: the mean over the run's signals of each one's mean square (every signal counts alike)
                k0, per = 0, {}
                for s, m in names:
                    per[s] = float(np.mean(left[k0:k0 + m] ** 2))
                    k0 += m
                J = float(np.mean(list(per.values())))
                if best is None or J < best[0]:
                    best = (J, max(per, key=per.get))
            row[(i, j)] = best or (0.0, "")
        out.append(row)
    return out, [sims[where[k][0]] for k in range(len(explanations))]


def feasibility(rep: Replayer, sims, envelope: Envelope = ENVELOPE, others=()) -> list[str | None]:
    """Why a candidate is left out (None: kept): the reported model (``sims``) cannot run it inside the envelope,
    or its run, or another explanation's (``others``: their simulations), does not repeat from cycle to cycle
    by more than the campaign's noise (a limit cycle: two models would part there by the phase of an
    oscillation, not by their physics)."""
    from ehas_env.measurement.verdict import repeat_floor

    out = []
    for ci, (case, sim) in enumerate(zip(rep.cases, sims)):
        if sim is None:
            out.append("the replay failed")
            continue
        if case.run.kind != "closed_loop":
            out.append(None)
            continue
        f = case.run.meta["reference"]["freq_hz"]
        start = (case.run.meta["reference"]["ramp_cycles"] + 1.0) / f
        wobble = None
        for m in (sim, *(o[ci] for o in others)):
            for s in ("theta_deg", "p_a_bar", "p_b_bar"):
                if m is None or s not in m or s not in case.noise:
                    continue
                fl = repeat_floor(m[s], case.run.dt, f, start)
                if fl is not None and fl > case.noise[s] ** 2:
                    wobble = f"the loop does not settle: {s} does not repeat from cycle to cycle " \
                             f"({math.sqrt(fl) / case.noise[s]:.1f}x the campaign's noise)"
                    break
            if wobble:
                break
        if wobble:
            out.append(wobble)
            continue
        near = pressure_limit(case.run.meta["supply_bar"], (sim, *(o[ci] for o in others)), envelope.pressure_margin)
        if near:
            out.append(near)
            continue
        th, ref = sim["theta_deg"], case.run.columns["theta_ref_deg"]
        amp = case.run.meta["reference"]["amplitude_deg"]
        steady = case.run.t - case.run.t[0] > 1.0 / case.run.meta["reference"]["freq_hz"]
        err = 100.0 * float(np.sqrt(np.mean((th[steady] - ref[steady]) ** 2))) / amp
        sat = float(np.mean(np.abs(sim["current_mA"]) >= 0.99 * envelope.rated_mA))
        if np.max(np.abs(th)) > envelope.stroke_deg - 1.0:
            out.append(f"the crank would reach {np.max(np.abs(th)):.1f} deg, at the stroke end")
        elif err > envelope.max_tracking_pct:
            out.append(f"the rig would follow it with {err:.0f} % RMS error")
        elif sat > envelope.max_saturation:
            out.append(f"the current would sit at the amplifier's limit {100 * sat:.0f} % of the time")
        else:
            out.append(None)
    return out


def pressure_limit(supply_bar: float, sims, margin: float) -> str | None:
    """Why a run goes near a pressure limit no model has (None when every chamber pressure of every simulation in
    ``sims`` stays within ``[margin Ps, Ps]``, start included).

    Parameters
    ----------
    supply_bar : float
        The run's supply, bar.
    sims : iterable of dict or None
        Simulations of the run (signal -> array; ``p_a_bar``, ``p_b_bar`` used).
    margin : float
        Share of the supply kept clear above the tank pressure.

    Returns
    -------
    str or None
    """
    lo, hi = margin * supply_bar, supply_bar
    for m in sims:
        for s in ("p_a_bar", "p_b_bar"):
            if m is None or s not in m:
                continue
            pmin, pmax = float(np.min(m[s])), float(np.max(m[s]))
            if pmin < lo:
                return f"{s} would fall to {pmin:.0f} bar, below {lo:.0f} bar ({100 * margin:g} % of the supply): " \
                       "near tank pressure the oil releases air and cavitates, which no model has"
            if pmax > hi:
                return f"{s} would rise to {pmax:.0f} bar, above the {hi:.0f} bar supply: the load would pump oil " \
                       "back against the pump's check valve, which no model has"
    return None


def chamber_ratio(offset_deg: float, rig=None) -> float:
    """V_A / V_B at a crank angle (piston at r sin(theta) from mid-stroke; dead volumes included; ``rig`` a
    :class:`~ehas_env.physics.rig.RigParams`, the book's when None)."""
    r, dv, a, h = (CRANK_RADIUS, DEAD_VOLUME, AREA, HALF_STROKE) if rig is None else (
        rig.radius, rig.dead_volume, rig.area, rig.half_stroke)
    x = r * math.sin(math.radians(offset_deg))
    va = dv + a * (h + x)
    vb = dv + a * (h - x)
    return va / vb


def why_text(meta: dict, campaign_supply: float, db: float, signal: str, a: str, b: str, rig=None) -> str:
    """Why a run separates two explanations, in words (``rig``: the model file's, the book's when None)."""
    bits = []
    if meta["kind"] == "valve_open_loop":
        bits.append(f"the valve bench at {meta['supply_bar']:g} bar (the rated test runs at 70): the valve's flow "
                    "and dynamics at another pressure drop across its lands")
    else:
        off = meta["reference"].get("offset_deg", 0.0)
        if off:
            r = chamber_ratio(off, rig)
            amp = meta["reference"]["amplitude_deg"]
            bits.append(f"at {abs(off):g} deg off centre the crank swings between {off - amp:g} and {off + amp:g} deg "
                        f"and the chamber volumes differ by {max(r, 1 / r):.1f}x at the mean angle: what changes with "
                        "the angle or with the chambers' volumes (the oil's stiffness, a torque that follows the "
                        "angle, a lever's length) departs from what does not, which a centred run does not show")
        if meta["supply_bar"] != campaign_supply:
            bits.append(f"at {meta['supply_bar']:g} bar supply (campaign {campaign_supply:g}) the chambers sit near "
                        f"{meta['supply_bar'] / 2:g} bar: what grows with the pressures (air in the oil, seal friction "
                        "that grows with them, an orifice's leak) changes, what does not stays")
        bits.append(f"{meta['disc_sets']} disc sets, {meta['reference']['amplitude_deg']:g} deg at "
                    f"{meta['reference']['freq_hz']:g} Hz")
    return (f"{meta['name']}: {a} vs {b}: {db:.1f} dB over the campaign's noise after refitting each within its "
            f"intervals, most in {signal}; " + "; ".join(bits))


# --- the plan --------------------------------------------------------------------------------


@dataclass
class Plan:
    """A test plan: the runs chosen, the pairs they separate, why."""

    campaign: str
    names: list  # explanation names
    pairs: list  # (i, j)
    runs: list  # Candidate
    predicted: dict  # (i, j) -> dB over the plan's runs
    why: list  # lines
    n_candidates: int = 0
    left_out: list = field(default_factory=list)  # (name, why) candidates outside what the rig can run

    def to_json(self) -> dict:
        """The plan file's object (``format`` ``ehas-test-plan``, version 1)."""
        return {"format": FORMAT, "version": VERSION, "campaign": self.campaign,
                "separates": [{"a": self.names[i], "b": self.names[j], "predicted_db": round(self.predicted[(i, j)], 2)}
                              for i, j in self.pairs],
                "runs": [c.meta for c in self.runs]}


def _combined_db(chosen: list[Candidate], pair) -> float:
    """Separation of a pair over several runs: ``10 log10(1 + J)``, J the samples' mean over the runs."""
    if not chosen:
        return 0.0
    w = [c.meta["duration_s"] for c in chosen]
    j = sum(wi * c.separation.get(pair, (0.0, ""))[0] for wi, c in zip(w, chosen)) / sum(w)
    return 10.0 * math.log10(1.0 + j)


def choose(cands: list[Candidate], pairs: list, max_runs: int = MAX_RUNS, max_log_s: float = MAX_LOG_S) -> list:
    """The runs of the plan: each pair's best run, then the runs that raise the weakest pair most."""
    ok = [c for c in cands if c.feasible is None]
    chosen: list[Candidate] = []

    def fits(c):
        return (c not in chosen and len(chosen) < max_runs
                and sum(x.meta["duration_s"] for x in chosen) + c.meta["duration_s"] <= max_log_s)

    for p in pairs:
        best = max((c for c in ok if fits(c)), key=lambda c: c.db(p), default=None)
        if best is not None and best.db(p) >= MIN_SEPARATION_DB and \
                not any(x.db(p) >= best.db(p) - 1e-9 for x in chosen):
            chosen.append(best)
    while True:
        weakest = min(pairs, key=lambda p: max((c.db(p) for c in chosen), default=0.0))
        best = max((c for c in ok if fits(c)), key=lambda c: c.db(weakest), default=None)
        if best is None or best.db(weakest) < MIN_SEPARATION_DB or \
                best.db(weakest) <= max((c.db(weakest) for c in chosen), default=0.0):
            break
        chosen.append(best)
    # a pair no chosen run separates by SEPARATED_DB is decided by the second diagnosis over the whole campaign,
    # where the planned runs are a share of the data: its next-best runs fill the plan's limits
    for p in pairs:
        if max((c.db(p) for c in chosen), default=0.0) >= SEPARATED_DB:
            continue
        for c in sorted((c for c in ok if c.db(p) >= MIN_SEPARATION_DB), key=lambda c: -c.db(p)):
            if fits(c):
                chosen.append(c)
    return chosen


def plan_test(doc: dict, explanations: list[Explanation], campaign: Campaign, *, envelope: Envelope | None = None,
              model=None, say=None) -> Plan:
    """Design the runs that separate the diagnosis' explanations.

    Parameters
    ----------
    doc : dict
        The diagnosis JSON (:func:`read_diagnosis`).
    explanations : list of Explanation
        The reported explanation first, then the alternatives.
    campaign : Campaign
        The campaign diagnosed (controller, supply, noise levels).
    envelope : Envelope, optional
        The rig's safe envelope (default: :meth:`Envelope.for_model` of ``model``).
    model : PlantModel, optional
        The model file's rig the diagnosis was made on (:func:`rig_model`); the book's when None.
    say : callable, optional
        Progress lines.

    Returns
    -------
    Plan
    """
    envelope = envelope or Envelope.for_model(model)
    say = say or (lambda msg: None)
    pairs = [(0, j) for j in range(1, len(explanations))]
    names = [e.name for e in explanations]
    if not pairs:
        return Plan(str(doc.get("campaign")), names, [], [], {}, [])
    noise, signals = campaign_noise(campaign)
    metas = candidates(campaign, envelope)
    runs = [_run_of(m, noise, signals) for m in metas]
    rep = Replayer(Campaign(None, runs), hypotheses=True, model=model)
    seps, own = separations(rep, explanations, pairs, say)
    feas = feasibility(rep, own[0], envelope, own[1:])
    cands = []
    for m, s, f in zip(metas, seps, feas):
        if m["kind"] == "closed_loop":
            m = {**m, "reference": {**m["reference"]}}
        cands.append(Candidate(meta=m, separation=s, feasible=f))
    chosen = choose(cands, pairs)
    supply = next(r.meta["supply_bar"] for r in campaign.runs if r.kind == "closed_loop")
    why = []
    for c in chosen:
        p = max(pairs, key=c.db)
        why.append(why_text(c.meta, supply, c.db(p), c.separation[p][1], names[p[0]], names[p[1]],
                            None if model is None else model.rig_for(c.meta.get("disc_sets", 1))))
        reason = explanations[p[1]].reason
        c.meta["notes"] = why[-1] = why[-1] + (f" (why the campaign could not: {reason})" if reason else "")
    predicted = {p: _combined_db(chosen, p) for p in pairs}
    return Plan(str(doc.get("campaign")), names, pairs, chosen, predicted, why, len(cands),
                [(c.name, c.feasible) for c in cands if c.feasible])


def check_plan(plan: dict, envelope: Envelope = ENVELOPE, where: str = "plan") -> None:
    """Check a plan file's object: its keys, every run a valid sidecar inside the envelope, the limits.

    Parameters
    ----------
    plan : dict
        A plan (:meth:`Plan.to_json`, or read back from PLAN.json).
    envelope : Envelope
        The rig's safe envelope.
    where : str
        The file, for messages.

    Raises
    ------
    CampaignError
        The first problem, in one line naming the run and key.
    """
    if not isinstance(plan, dict) or plan.get("format") != FORMAT or plan.get("version") != VERSION:
        raise CampaignError(f"{where}: expected {{\"format\": \"{FORMAT}\", \"version\": {VERSION}, ...}}")
    for key in ("campaign", "separates", "runs"):
        if key not in plan:
            raise CampaignError(f"{where}: key '{key}' is missing")
    runs = plan["runs"]
    if len(runs) > MAX_RUNS or sum(r["duration_s"] for r in runs) > MAX_LOG_S:
        raise CampaignError(f"{where}: {len(runs)} runs, {sum(r['duration_s'] for r in runs):g} s; at most "
                            f"{MAX_RUNS} runs and {MAX_LOG_S:g} s")
    for r in runs:
        w = f"{where}, run {r.get('name')!r}"
        side = {k: v for k, v in r.items() if k not in ("name", "duration_s", "excitation")}
        validate_meta(side, where=w)
        if r["kind"] == "valve_open_loop" and (r.get("excitation") or {}).get("type") != "chirp":
            raise CampaignError(f"{w}: a valve run needs excitation {{\"type\": \"chirp\", ...}}")
        bad = envelope.problem(r)
        if bad:
            raise CampaignError(f"{w}: outside the rig's safe envelope: {bad}")
