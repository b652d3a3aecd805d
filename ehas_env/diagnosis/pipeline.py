"""The open-world diagnosis: a sequence of named stages, each a small function on one :class:`Search`.

::

    campaign ─► data ─► library ─► hypotheses ─► measure ─► per_run ─► verdict ─► proposal ─► alternatives
                 │         │            │            │          │          │           │              │
              holdout,   rounds of   structural   final model  each run's grade,     a term at a    what the logs
              windows,   library     hypotheses   on all runs, parameters, unexpla-  place, fitted  cannot tell
              replayers  effects,    (rivals,     follows,     drift      ined text  and named      apart
                         stacked     pairs, swap, disturban-
                                     honesty 2)   ces, ci95

Each stage reads and writes the fields of :class:`~ehas_env.diagnosis.search.Search` its docstring
names and returns a record (a dict in the JSON's own terms) that :meth:`OpenDiagnosis.to_json` lists under
``stages`` with its time.  Adding a search is adding a function to :data:`STAGES` (docs/diagnosis-pipeline.md).
The rules that judge one candidate live in :mod:`ehas_env.diagnosis.candidates`; the search stages in
:mod:`ehas_env.diagnosis.search`; the honesty rules in :mod:`ehas_env.diagnosis.honesty`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from ehas_env.diagnosis import proposal as P
from ehas_env.diagnosis.estimate import REPLAYS, estimate, in_words
from ehas_env.measurement.campaign import Campaign
from ehas_env.diagnosis.candidates import (
    FIT_WINDOW_S, Diagnosis, Step, _drop_stand_ins, _held_fit, _held_table, _parts_cost, _round, confidence,
    fit_candidate, fit_null, windowed)
from ehas_env.diagnosis.search import (
    Search, data_stage, hypotheses_stage, library_stage, steps_back_to)
from ehas_env.diagnosis.disturbances import disturbances as disturbances_of
from ehas_env.diagnosis.drift import per_run_stage
from ehas_env.diagnosis.fitting import Fit, _unit, _value_of, on_one_blas_thread
from ehas_env.diagnosis.honesty import at_bounds, term_refused
from ehas_env.diagnosis.measured_inputs import measured, measured_input_stage
from ehas_env.diagnosis.naming import judge_on_all_data
from ehas_env.diagnosis.states import described, simpler_kind, state_stage
from ehas_env.physics.augment import Augmentation
from ehas_env.measurement.replay import COST_SIGNALS, ModelSpec, Replayer
from ehas_env.measurement.residuals import follows as follows_of
from ehas_env.measurement.verdict import BLOCK_NAMED_X, blocks_above, blocks_json, blocks_of, grade
from ehas_env.physics.effects import get_effect


@dataclass
class OpenDiagnosis:
    """Result of :func:`diagnose_open`: library ranking, stacked model, verdict, what is left, the proposal."""

    first: Diagnosis  # the first round's ranking (on the fit data)
    rounds: list  # Diagnosis of every round
    steps: list  # Step of every candidate judged
    model: ModelSpec  # the final library model
    fit_train: Fit  # the final model on the fit data (windows of the fitted runs)
    sims_all: list  # the final model on all runs, full length
    baseline_all: list  # the baseline on all runs, full length
    full: Replayer
    train: Replayer
    holdout: list
    cost_all: float
    run_costs: dict
    unexplained: dict | None
    follows: dict
    ci: dict
    proposal: object = None
    alternatives: list = field(default_factory=list)  # other explanations, compared (ehas_env.diagnosis.alternatives)
    validation: dict = field(default_factory=dict)
    per_run: dict | None = None  # parameters fitted on each run alone (ehas_env.diagnosis.drift)
    drift: list = field(default_factory=list)  # parameters that differ between runs, related to the sidecars
    disturbances: list = field(default_factory=list)  # residual lines at no harmonic of the test frequency
    grade: dict = field(default_factory=dict)
    blocks: list = field(default_factory=list)  # the final model's verdict.Block of every run and judged signal
    measured_inputs: list = field(default_factory=list)  # logged quantities replayed as inputs (the supply pressure)
    stages: list = field(default_factory=list)  # one record per stage run (STAGES): stage, elapsed_s, what it found
    elapsed_s: float = 0.0
    n_evals: int = 0

    @property
    def verdict(self) -> str:
        """``explained``, ``small structured residual`` or ``unexplained`` (:func:`ehas_env.measurement.verdict.grade`)."""
        return self.grade["verdict"]

    @property
    def unexplained_threshold(self) -> float:
        return self.grade["thresholds"]["unexplained"]

    @property
    def residual_x_noise(self) -> float:
        """The residual against what does not repeat (:mod:`ehas_env.measurement.verdict`)."""
        return self.grade["residual_x_noise"]

    @property
    def hypothesis(self) -> str | None:
        """The structural hypothesis in the final model, if one was kept (a missing state is :attr:`state`)."""
        return next((n for n in self.model.effects if get_effect(n).kind == "hypothesis"
                     and not issubclass(get_effect(n), Augmentation)), None)

    @property
    def state(self) -> str | None:
        """The first generic augmentation (a missing state, :mod:`ehas_env.physics.augment`) in the final model, if
        one was kept."""
        return next(iter(self.states), None)

    @property
    def states(self) -> list[str]:
        """Every generic augmentation in the final model (the states stage keeps up to ``MAX_STATES``)."""
        return [n for n in self.model.effects if issubclass(get_effect(n), Augmentation)]

    def hypothesis_json(self) -> dict | None:
        """The kept hypothesis: effect, values, 95 % intervals, in words (None when none was kept)."""
        h = self.hypothesis
        if h is None:
            return None
        cls = get_effect(h)
        vals = self.model.effects[h]
        return {"effect": h, "title": cls.title, "words": cls.in_words(vals),
                "params": {k: _round(v) for k, v in vals.items()},
                "units": {p.name: p.unit for p in cls.params},
                "ci95": {n: [_round(lo), _round(hi)] for (e, n), (lo, hi) in self.ci.items() if e == h},
                "residual_x_noise_before": self.validation.get("residual_x_noise_before_hypotheses"),
                "residual_x_noise_after": self.residual_x_noise}

    @property
    def kept(self) -> list[str]:
        return [s.effect for s in self.steps if s.kept]

    def to_json(self) -> dict:
        doc = self.first.to_json()
        doc["verdict"] = self.verdict
        doc["residual_x_noise"] = self.residual_x_noise
        doc["residual_x_sensor_noise"] = round(self.cost_all, 3)
        doc["grade"] = self.grade
        doc["blocks"] = blocks_json(self.blocks)  # every run and signal judged: figure, floor, where the floor came from
        doc["not_compared"] = self.full.not_compared()  # logged columns judged nowhere (a load computed by the logger)
        # beta and K are fitted relative to the book's rig (replay.Replayer.absolute): report the rig's own numbers
        rig = self.full.absolute(self.model)
        scale = {"beta": rig.beta / self.model.beta if self.model.beta else 1.0,
                 "K": rig.K / self.model.K if self.model.K else 1.0}

        def rig_scale(e, n):
            return 1.0 if e else scale.get(n, 1.0)

        doc["model"] = {"effects": {n: {k: _round(v) for k, v in p.items()} for n, p in self.model.effects.items()},
                        "beta": _round(rig.beta), "K": _round(rig.K),
                        "ci95": [{"effect": e or "baseline", "param": n, "value": _round(rig_scale(e, n) * _value_of(self.model, fp)),
                                  "low": _round(rig_scale(e, n) * lo), "high": _round(rig_scale(e, n) * hi), "unit": _unit(e, n)}
                                 for fp in self.fit_train.free for (e, n), (lo, hi) in self.ci.items()
                                 if (fp.effect, fp.name) == (e, n)],
                        "at_bound": at_bounds(self.fit_train, self.model.effects, baseline=True)}  # honesty rule 4
        doc["stack"] = [{"effect": s.effect, "kept": s.kept, "reason": s.reason,
                         "params": {k: _round(v) for k, v in (s.fit.model.effects.get(s.effect, {}) if s.fit else {}).items()},
                         "residual_x_noise_fit": round(s.cost_train, 3),
                         "residual_x_noise_validation": None if s.cost_val is None else round(s.cost_val, 3),
                         "fit_percent_validation": None if s.fit_val is None else round(s.fit_val, 2)}
                        for s in self.steps]
        doc["validation"] = self.validation
        doc["hypothesis"] = self.hypothesis_json()
        doc["follows"] = self.follows
        doc["unexplained"] = self.unexplained
        # what these logs cannot tell apart from the model reported, and what they rule out (issue 34)
        doc["reported_model"] = {"effects": {n: {k: float(v) for k, v in p.items()} for n, p in self.model.effects.items()},
                                 "beta": float(self.model.beta), "K": float(self.model.K),
                                 "rig_model": None if self.full.model is None else self.full.model.label}
        doc["alternatives"] = [a.to_json() for a in self.alternatives if a.within]
        doc["ruled_out"] = [a.to_json() for a in self.alternatives if not a.within]
        doc["per_run"] = self.per_run
        doc["drift"] = self.drift
        doc["disturbances"] = self.disturbances
        doc["stages"] = self.stages
        # a missing state kept (the states stage's record: the augmentation, its values with intervals, in words)
        # every missing state kept, in the order found (the states stage's first search, then those on top of it)
        doc["states"] = [{k: r[k] for k in ("kept", "words", "params", "ci95", "residual_x_noise_all_before",
                                            "residual_x_noise_all_after", "within") if k in r}
                         for st in self.stages if st.get("stage") == "states"
                         for r in [st, *(st.get("more") or [])] if r.get("kept") and r["kept"] in self.model.effects]
        doc["state"] = doc["states"][0] if doc["states"] else None  # the first (as before a second was looked for)
        doc["measured_inputs"] = self.measured_inputs
        return doc





def measured_inputs_stage(s: Search) -> dict:
    """The stage of measured boundaries: a logged quantity the model holds constant (the supply pressure) that varies
    beyond its noise is taken as a measured input when that removes at least a tenth of the residual's excess over
    the noise (:func:`ehas_env.diagnosis.measured_inputs.measured_input_stage`); from then on every replayer
    takes it.

    Parameters
    ----------
    s : Search
        Reads the model kept; when the input is kept, replaces ``rep``, ``full`` and the model kept.

    Returns
    -------
    dict
        The stage's record (``quantity``, ``tried``, ``kept``, ``inputs``, residual before and after, ``text``).
    """
    if not s.options.get("measured_inputs", True):
        return {"skipped": True, "kept": False, "inputs": []}
    f, rec = measured_input_stage(s.full, s.rep, s.current, s.parts, s.say)
    if f is not None:
        full, rep = measured(s.full, rec["inputs"]), measured(s.rep, rec["inputs"])
        full.n_evals, rep.n_evals = s.full.n_evals, s.rep.n_evals  # the campaign's replays go on being counted
        s.full, s.rep = full, rep
        sims = s.full.simulate(f.model)
        s.keep(f, sims, _parts_cost(s.full, sims, s.parts))
    return rec


#: missing blocks the states stage keeps one after another: a second is looked for on top of the first where the
#: first leaves the campaign unexplained (two blocks hidden in one rig: each alone closes only part of the miss)
MAX_STATES = 2


def states_stage(s: Search) -> dict:
    """The stage of missing states: when the model kept leaves more than a residual of ``STATE_TRIGGER`` x noise,
    each generic augmentation (a lag in a signal path, a compliance with a mass in a link, a volume with a
    resistance in a line, play in a joint, a static term at a balance: :mod:`ehas_env.physics.augment`) is tried
    place by place on top of it (:func:`ehas_env.diagnosis.states.state_stage`); the best is kept when it removes a
    tenth of the excess over the noise and lowers the validation residual.  An effect kept before it that it stood in
    for is refitted away (as for a structural hypothesis).  Where one is kept and the residual still asks, the
    search runs again on top of it, up to :data:`MAX_STATES` blocks.

    Parameters
    ----------
    s : Search
        Reads the model kept; appends a step and replaces the model kept when an augmentation is kept.

    Returns
    -------
    dict
        The first search's record (``tried``, ``kept``, ``params``, ``ci95``, residuals before and after, ``words``,
        ``skipped``) and ``more``: the records of the searches on top of it (each as the first's), when any ran.
    """
    if not s.options.get("states", True):
        return {"skipped": "not asked for", "kept": None}
    bare = s.bare[0] if s.bare is not None and not s.full.inputs else None
    # the recalibrated baseline too, where the search began (a measured input kept since changed every replay)
    null = s.rounds[0].null if s.rounds and not s.full.inputs else None
    f, rec = state_stage(s.rep, s.full, s.current, s.parts, s.say, bare=bare, null=null)
    if f is None:
        return rec
    _keep_state(s, f, rec, bare, null)
    more = []
    while len(more) + 1 < MAX_STATES:
        s.say("  states: looking for another on top of it")
        f, again = state_stage(s.rep, s.full, s.current, s.parts, s.say)
        more.append(again)
        if f is None:
            break
        _keep_state(s, f, again, None, None)
    rec["more"] = more
    return rec


def _keep_state(s: Search, f, rec: dict, bare, null) -> None:
    """The augmentation ``rec`` kept (its model ``f``) made the model kept: a step, the effects it stood in for said
    not kept (the structural hypotheses, when it did best on the library's model ``bare``; every effect kept, when
    it did best on the recalibrated baseline ``null``), then any effect kept before that it makes unnecessary
    refitted away."""
    name = rec["kept"]
    sims = s.full.simulate(f.model)
    val = _parts_cost(s.full, sims, s.parts)
    replaced = rec.get("in_place_of") or []
    val_after = rec["residual_x_noise_validation_after"]  # None: the campaign has no validation samples
    why = (f"stands in for {name} ({get_effect(name).title}): with {name} in its place the residual on all "
           f"data is {rec['residual_x_noise_all_after']:.3g}x noise"
           + ("" if val_after is None else f" and the validation residual {val_after:.3g} sensor-noise variances"))
    if bare is not None and replaced and set(replaced) == set(s.current.model.effects) - set(bare.model.effects):
        steps_back_to(s.steps, s.bare[4], why)  # the library's model back, the hypotheses said not kept
        s.base = s.bare[3]
    else:
        for step in s.steps:
            if step.kept and step.effect in replaced:
                step.kept, step.reason = False, why
        if null is not None and replaced and set(replaced) == set(s.current.model.effects) - set(null.model.effects):
            s.bare = None  # kept on the recalibrated baseline: the library's model before the hypotheses went too
    s.steps.append(Step(name, True, f"{rec['words']}; a missing state: removes at least a tenth of the "
                        "residual's excess over the noise and lowers the validation residual", f, f.cost, val,
                        _held_fit(s.full, sims, s.held_idx)))
    s.say(f"  {name}: kept ({rec['words']})")
    # an effect or a structural hypothesis kept before it may have stood in for the missing state
    current, sims, val = _drop_stand_ins(s.rep, s.full, s.parts, f, val, name, s.steps, s.say,
                                         kinds=("physical", "recalibration", "hypothesis"), sims=sims)
    if set(current.model.effects) != set(f.model.effects):  # what it shared its place with is gone
        current, sims, val = _simpler_state(s, current, sims, val, rec)
    s.keep(current, sims, val)


def _simpler_state(s: Search, f, sims, val, rec: dict) -> tuple:
    """The static kind ``rec`` kept (in the model ``f``, its simulation ``sims``, validation cost ``val``) once an
    effect it stood in for went: a simpler kind at its place that now holds it replaces it
    (:func:`ehas_env.diagnosis.states.simpler_kind`), its step and the record (``simpler``: the kinds fitted,
    ``reduced_from``) say so.  Returns the model kept (Fit, simulation of every run, validation cost)."""
    name = rec["kept"]
    found = simpler_kind(s.rep, s.full, f, name, s.parts, val)
    if found is None:
        return f, sims, val
    g, new, made = found
    gs = s.full.simulate(g.model)
    gval = _parts_cost(s.full, gs, s.parts)
    # the rivals listed were the replaced kind's: the record keeps the kinds just fitted against it instead
    rec.update(described(s.rep, g, new)[0], kept=new, reduced_from=name, simpler=made, within=[])
    ratio = next(m["cost_ratio"] for m in made if m["effect"] == new)
    why = (f"the simpler {get_effect(new).title} holds it ({ratio:.4g}x its cost) once the effects it shared its "
           "place with are gone")
    for step in s.steps:
        if step.kept and step.effect == name:
            step.kept, step.reason = False, why
    s.steps.append(Step(new, True, f"{rec['words']}; a missing state: the simplest kind at its place that holds "
                        f"what {name} did", g, g.cost, gval, _held_fit(s.full, gs, s.held_idx)))
    s.say(f"  {name}: replaced by {new} ({rec['words']})")
    return g, gs, gval


def measure_stage(s: Search) -> dict:
    """The stage of the final model measured on every run: its simulation, the residual per run, what the residual
    follows, the disturbances (lines at no harmonic of the test), the 95 % intervals; builds ``s.result``.

    Parameters
    ----------
    s : Search
        Reads the model kept; sets ``result``.

    Returns
    -------
    dict
        ``effects`` (the final model's), ``residual_x_noise``.
    """
    full, final = s.full, s.current
    sims_all = s.cur_sims
    baseline_all = full.simulate(ModelSpec(effects=s.options.get("base_effects") or {}))
    blocks = blocks_of(full, sims_all, COST_SIGNALS)
    run_costs = {}
    for i, case in enumerate(full.cases):
        c = _parts_cost(full, sims_all, {i: 0})
        if c is not None:
            run_costs[case.run.name] = c
    validation = {"holdout": s.held, "fit_window_s": s.window_s,
                  "residual_x_noise_before_hypotheses": s.before_floor,
                  "hypotheses_tried_because": s.hyp_because,
                  "fit_runs": [r.name for r in s.train_runs],
                  "residual_x_noise_validation": None if s.cur_val is None else round(s.cur_val, 3)}
    tb, tf = _held_table(full, baseline_all, s.held_idx), _held_table(full, sims_all, s.held_idx)
    if tb is not None:
        validation["holdout_fit_percent_baseline"] = round(tb.overall, 2)
        validation["holdout_fit_percent_model"] = round(tf.overall, 2)
    s.result = OpenDiagnosis(first=s.rounds[0], rounds=s.rounds, steps=s.steps, model=final.model, fit_train=final,
                             sims_all=sims_all, baseline_all=baseline_all, full=full, train=s.rep, holdout=s.held,
                             cost_all=full.log_cost(sims_all), run_costs=run_costs, unexplained=None,
                             follows=follows_of(full, sims_all), ci=confidence(s.rep, final) if final.free else {},
                             validation=validation, blocks=blocks, grade=grade(blocks),
                             disturbances=disturbances_of(full, sims_all),
                             measured_inputs=sorted({q for given in full.inputs.values() for q in given}))
    # where the search started: the baseline with beta and K recalibrated (the first round's null model), on all
    # data as the sidecars state them (a measured input kept since is part of what the search found)
    null, given = s.rounds[0].null, s.full_as_given or full
    start = sims_all if null is final and given is full else given.simulate(null.model)
    s.result.validation["residual_x_noise_recalibrated_baseline"] = grade(blocks_of(given, start,
                                                                                    COST_SIGNALS))["residual_x_noise"]
    return {"effects": list(final.model.effects), "residual_x_noise": s.result.residual_x_noise,
            "residual_x_noise_recalibrated_baseline": s.result.validation["residual_x_noise_recalibrated_baseline"]}


def measure_again(s: Search, why: str) -> None:
    """The model kept changed after the ``measure`` stage: measure it again, recorded as a second ``measure`` record
    (with ``again_because``, and its own time), so that the figure reported is always the last measure record's.

    Parameters
    ----------
    s : Search
        The search, its model kept just replaced.
    why : str
        Why the model changed.
    """
    t = time.perf_counter()
    book = s.result.validation.get("residual_x_noise_book_model") if s.result is not None else None
    out = measure_stage(s)
    if book is not None:  # the book's figure the model is held to (no_worse_stage) stays in the validation
        s.result.validation.setdefault("residual_x_noise_book_model", book)
    s.records.append({"stage": "measure", "elapsed_s": round(time.perf_counter() - t, 2), "again_because": why,
                      **out})


def no_worse_stage(s: Search) -> dict:
    """The stage that keeps the promise of the noise figure: the model reported is never worse on it than the book's
    rig (the model the campaign was compared with before anything was fitted: the baseline with the ``--with``
    effects at their values) or than the recalibrated baseline (beta and K fitted, where the search started).  When
    the model the stages kept is worse than either, the better of the two is reported instead, every step kept is
    said not kept with why, and the model is measured again (a second ``measure`` record).

    Parameters
    ----------
    s : Search
        Reads ``result`` (after :func:`measure_stage`); may replace the model kept.

    Returns
    -------
    dict
        ``residual_x_noise`` of the model the stages kept, ``book_model`` and ``recalibrated_baseline`` (the two
        figures it is held to), ``replaced_by`` (``"book model"``, ``"recalibrated baseline"`` or None).
    """
    from ehas_env.diagnosis.fitting import Fit

    res = s.result
    x = res.residual_x_noise
    book_x = grade(blocks_of(s.full, res.baseline_all, COST_SIGNALS))["residual_x_noise"]
    res.validation["residual_x_noise_book_model"] = book_x
    rec = {"residual_x_noise": x, "book_model": book_x,
           "recalibrated_baseline": res.validation.get("residual_x_noise_recalibrated_baseline"), "replaced_by": None}
    null = s.rounds[0].null
    options = [("book model", book_x)]
    if (s.full_as_given or s.full) is s.full and rec["recalibrated_baseline"] is not None:  # same replays as the final
        options.append(("recalibrated baseline", rec["recalibrated_baseline"]))
    name, best = min(options, key=lambda kv: kv[1])
    if not x > best:
        return rec
    if name == "recalibrated baseline":
        f, sims = null, s.full.simulate(null.model)
    else:
        spec = ModelSpec(effects={n: dict(p) for n, p in (s.options.get("base_effects") or {}).items()})
        train = s.rep.simulate(spec)
        f, sims = Fit(spec, s.rep.log_cost(train), [], train, s.rep.fit_table(train)), res.baseline_all
    why = (f"the model the search kept leaves {x:.3g}x what does not repeat, worse than the {name} "
           f"({best:.3g}x): the {name} is reported")
    for st in s.steps:
        if st.kept:
            st.kept, st.reason = False, st.reason + f"; not kept in the end: {why}"
    s.say(f"  {why}")
    s.keep(f, sims, _parts_cost(s.full, sims, s.parts))
    measure_again(s, why)  # keeps the book model's figure in the validation
    rec["replaced_by"] = name
    return rec


def per_run_parameters_stage(s: Search) -> dict:
    """The stage of parameters per run: the final model's parameters (and the best effects judged but not kept) fitted
    on each closed-loop run alone, and those that differ between runs, related to the sidecars
    (:func:`ehas_env.diagnosis.drift.per_run_stage`).

    Parameters
    ----------
    s : Search
        Sets ``result.per_run`` and ``result.drift`` (skipped when ``options["per_run"]`` is False).

    Returns
    -------
    dict
        ``drift``: the parameters that differ, in words.
    """
    if not s.options.get("per_run", True):
        return {"skipped": True, "drift": []}
    cl = [r for r in s.campaign.runs if r.kind == "closed_loop"]
    d = per_run_stage(s.rep, cl, windowed(Campaign(s.campaign.path, cl), s.window_s).runs, s.current,
                      not_kept(s.steps, s.current), say=s.say)
    s.result.per_run, s.result.drift = d["per_run"], d["drift"]
    return {"drift": [x["text"] for x in d["drift"]]}


def verdict_stage(s: Search) -> dict:
    """The stage of the verdict: explained, small structured residual or unexplained; when not explained, where the
    residual is, what it follows, the worst run (``unexplained``).

    Parameters
    ----------
    s : Search
        Sets ``result.unexplained`` (its text is completed after the proposal).

    Returns
    -------
    dict
        ``verdict``, ``residual_x_noise``.
    """
    res = s.result
    if res.verdict != "explained":
        fol = res.follows
        where = sorted(((k, v["x_noise"]) for k, v in fol["signals"].items()), key=lambda kv: kv[1], reverse=True)
        worst_run = max(res.run_costs.items(), key=lambda kv: kv[1]) if res.run_costs else ("", 0.0)
        g = res.grade
        res.unexplained = {"residual_x_noise": g["residual_x_noise"], "structured_db": g["structured_db"],
                           "blocks_above": blocks_above(res.blocks, BLOCK_NAMED_X),
                           "threshold": g["thresholds"]["unexplained"], "worst": g["worst"],
                           "worst_run": {"run": worst_run[0], "residual_x_sensor_noise": round(worst_run[1], 3)},
                           "where": [{"signal": k, "rms_x_noise": v} for k, v in where],
                           "follows": list(fol["follows"]),
                           "follows_shares": fol["follows"],
                           "proposal": None,
                           "text": ""}
        res.unexplained["text"] = unexplained_text(res, res.unexplained)
    return {"verdict": res.verdict, "residual_x_noise": res.residual_x_noise}


def proposal_stage(s: Search) -> dict:
    """The stage of the missing term: on an unexplained campaign only, a term at a place of the model fitted inside it
    and named (:func:`propose_stage`), kept when honesty rule 1 allows.  A structured residual below that (within
    twice what does not repeat) is as likely two simulators' numerics as physics, and a term fitted to it names a
    kind of effect that may not be there: no term is proposed on top of it.  But where that small residual is left
    by blocks of the state stage on a model that was unexplained without them, the term is proposed on that model
    (:func:`_term_without_hypotheses`), and replaces the blocks when it lowers the figure on all data by
    :data:`TERM_BEATS_KEPT` of theirs: the blocks, flexible functions of one local quantity, stood in for it.

    Parameters
    ----------
    s : Search
        Sets ``result.proposal`` and ``result.unexplained["proposal"]`` / ``["no_term"]``.

    Returns
    -------
    dict
        ``proposed`` (the term's places, or None), ``refused`` (why a term found was refused, or None).
    """
    res = s.result
    if not s.options.get("propose", True) or res.verdict == "explained":
        return {"proposed": None, "refused": None}
    if res.verdict == "unexplained":
        s.say("proposing the missing term")
        prop, ps, refused = propose_stage(s.rep, s.full, s.current, res.sims_all, s.parts, s.cur_val, res.grade,
                                          s.say)
        stood_in = _term_without_hypotheses(s, prop)
    else:
        # a small structured residual left by the state stage's blocks: the term proposed without them may do
        # better (a structural hypothesis kept names a physics of its own and stays)
        added = set(s.current.model.effects) - set(s.bare[0].model.effects) if s.bare is not None else set()
        stood_in = (_term_without_hypotheses(s, None, small=True) if added and not added & set(s.hyps) else None)
        if stood_in is None:
            return {"proposed": None, "refused": None}
    if stood_in is not None:
        prop, ps, refused = stood_in
        res = s.result
    if prop is not None:
        res.proposal, res.proposal_sims = prop, ps
        res.unexplained["proposal"] = prop.to_json()
    if refused is not None:  # honesty rule 1 (ehas_env.diagnosis.honesty): neither written nor recommended
        res.unexplained["no_term"] = refused
    res.unexplained["text"] = unexplained_text(res, res.unexplained)
    return {"proposed": None if prop is None else res.unexplained["proposal"].get("where"), "refused": refused}


#: the term proposed on the library's model (before the structural hypotheses) replaces the hypotheses kept when
#: its all-data residual is within this share of the term's on top of them: they stood in for the missing term
TERM_STANDS_FOR_HYPOTHESES = 0.02
#: where the blocks kept leave a small structured residual (no term is proposed on top of them), the term proposed
#: without them replaces them only when it lowers the all-data figure by this share of theirs
TERM_BEATS_KEPT = 0.10


def term_replaces_kept(prop, prop_b, x_kept: float, small: bool = False) -> bool:
    """Whether the term proposed on the library's model (``prop_b``) may replace the structural hypotheses (or the
    missing state) kept: only a term found on both models, doing as well without them as with them (within
    :data:`TERM_STANDS_FOR_HYPOTHESES`), and better than the model kept.  A model the stages kept is never set
    aside for a term that was not found on top of it (issue 46: a hypothesis kept at 1.3x was reported as the
    library's model at 5x because nothing was proposable on top of it).

    Parameters
    ----------
    prop, prop_b : Proposal or None
        The term proposed on top of the model kept, and on the library's model.
    x_kept : float
        The model kept's noise figure on all data (:data:`~ehas_env.measurement.verdict.FIGURE_KEY`).
    small : bool
        The model kept leaves a small structured residual (nothing is proposed on top of it): the term without the
        blocks kept must then lower the figure by :data:`TERM_BEATS_KEPT` of theirs.

    Returns
    -------
    bool

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> term = lambda x: NS(validation={"residual_x_noise_all_after": x})
    >>> term_replaces_kept(None, term(1.2), 1.33)  # nothing found on top of the kept hypothesis: it stays
    False
    >>> term_replaces_kept(term(1.10), term(1.11), 1.33)  # the term alone does as well: it stood in for it
    True
    >>> term_replaces_kept(term(1.10), term(1.50), 1.33)
    False
    >>> term_replaces_kept(None, term(1.08), 1.40, small=True)  # the blocks kept leave 1.40x; the term alone 1.08x
    True
    >>> term_replaces_kept(None, term(1.30), 1.40, small=True)  # 7 % lower: the blocks kept stay
    False
    """
    if prop_b is None:
        return False
    x_b = prop_b.validation["residual_x_noise_all_after"]
    if small:  # a small structured residual left: nothing is proposed on top of the blocks kept
        return x_b < x_kept * (1.0 - TERM_BEATS_KEPT)
    if prop is None:
        return False
    return (x_b <= prop.validation["residual_x_noise_all_after"] * (1.0 + TERM_STANDS_FOR_HYPOTHESES)
            and x_b < x_kept)


def _term_without_hypotheses(s: Search, prop, small: bool = False) -> tuple | None:
    """The structural hypotheses (or a missing state) were kept and the campaign is still unexplained (or, with
    ``small``, the state stage's blocks leave a small structured residual): the term is
    proposed again on the model the library gave before them (``s.bare``).  When it does as well there (within
    :data:`TERM_STANDS_FOR_HYPOTHESES` of the all-data residual) and better than the model kept
    (:func:`term_replaces_kept`), the hypotheses stood in for the missing term: the library's model comes back
    (their steps say why), measured and graded again (a second ``measure`` record), with the term on top of it.

    Parameters
    ----------
    s : Search
        The search, after the verdict stage.
    prop : Proposal or None
        The term proposed on top of the model kept.

    Returns
    -------
    tuple or None
        (Proposal, its simulation of every run, why refused) on the library's model when that replaced the model
        kept, else None.
    """
    if s.bare is None or s.bare[0] is s.current or s.full.inputs:  # (a measured input changed the replays since)
        return None
    b_fit, b_sims, b_val, b_base, flags = s.bare
    g = grade(blocks_of(s.full, b_sims, COST_SIGNALS))
    if g["verdict"] != "unexplained":
        return None
    what = "the state stage's blocks" if small else "the structural hypotheses"
    s.say(f"proposing the term on the library's model too (without {what})")
    prop_b, ps_b, refused_b = propose_stage(s.rep, s.full, b_fit, b_sims, s.parts, b_val, g, s.say)
    if not term_replaces_kept(prop, prop_b, s.result.residual_x_noise, small):
        return None
    x_b = prop_b.validation["residual_x_noise_all_after"]
    why = (f"the term proposed without it leaves {x_b:.3g}x noise on all data"
           + ("" if prop is None else f", as well as with it ({prop.validation['residual_x_noise_all_after']:.3g}x)")
           + ": it stood in for the missing term")
    set_aside = [st.effect for st in s.steps[len(flags):] if st.kept]
    steps_back_to(s.steps, flags, why)
    _records_set_aside(s.records, set_aside, why)
    s.say(f"  {what} kept are dropped: {why}")
    s.current, s.cur_sims, s.cur_val, s.base = b_fit, b_sims, b_val, b_base
    # the model reported changed: measured again, and the record says so (the reported figure is the last measure's)
    measure_again(s, why)
    if s.options.get("alternatives", True) and s.result.model.effects:
        from ehas_env.diagnosis.alternatives import find_alternatives

        s.result.alternatives = find_alternatives(s.result, fit_null, fit_candidate, s.say)
    per_run_parameters_stage(s)
    verdict_stage(s)
    return prop_b, ps_b, refused_b


def _records_set_aside(records: list, names: list, why: str) -> None:
    """Mark the earlier stages' records whose ``kept`` names an effect set aside in the end (``not_kept_in_the_end``:
    {name: why}): a reader of a stage's record sees that what it kept is not in the final model."""
    for rec in records:
        kept = rec.get("kept")
        kept = [kept] if isinstance(kept, str) else list(kept) if isinstance(kept, list) else []
        for more in rec.get("more") or []:
            if isinstance(more, dict) and isinstance(more.get("kept"), str):
                kept.append(more["kept"])
        gone = [n for n in kept if n in names]
        if gone:
            rec.setdefault("not_kept_in_the_end", {}).update({n: why for n in gone})


def alternatives_stage(s: Search) -> dict:
    """The stage of the alternatives: the explanations each effect of the final model may be confused with, fitted in
    its place (:func:`ehas_env.diagnosis.alternatives.find_alternatives`); those these logs cannot tell apart are
    listed.  When the logs *prefer* one (it fits better by more than they resolve, and worse on no run by more than
    ``SEPARATED_DB``: :func:`ehas_env.diagnosis.alternatives.prefers`) and it is not worse on the noise figure
    of all data, it becomes the reported explanation, the final model is measured again, and the one it replaced is
    compared in its place (issue 46: a swap preferred on the fit data once reported 244x after 157x).  It runs before the verdict,
    the parameters per run and the proposal, which then see the explanation reported.

    Parameters
    ----------
    s : Search
        Sets ``result.alternatives`` (skipped when ``options["alternatives"]`` is False or nothing was kept); may
        replace the model kept (a step says why).

    Returns
    -------
    dict
        ``within``: the names of the alternatives the logs cannot tell apart; ``preferred``: the explanation the
        logs preferred and put in place of the one first reported (None when none); ``not_fitted``: the kinds at a
        structural hypothesis' balances not fitted, their linearisation removing nothing (each with its share).
    """
    res = s.result
    if not s.options.get("alternatives", True) or not res.model.effects:
        return {"within": [], "preferred": None, "not_fitted": []}
    from ehas_env.diagnosis.alternatives import find_alternatives

    not_fitted = []  # kinds at a hypothesis' balances whose linearisation removes nothing
    res.alternatives = find_alternatives(res, fit_null, fit_candidate, s.say, not_fitted)
    better = sorted((a for a in res.alternatives if a.preferred), key=lambda a: a.score_difference_db)
    swapped = None
    if better:
        a = better[0]
        rest = {n: dict(p) for n, p in s.current.model.effects.items() if n != a.in_place_of}
        f = a.fit
        if f is None or set(f.model.effects) != set(rest) | {a.name}:  # compared from an earlier round: refit here
            f = fit_candidate(s.rep, a.name, fit_null(s.rep, rest), rest)
        sims = s.full.simulate(f.model)
        x_new = grade(blocks_of(s.full, sims, COST_SIGNALS))["residual_x_noise"]
        if x_new > res.residual_x_noise:  # preferred on the fit data, worse on the one figure: the model stays
            s.say(f"  {a.name} in place of {a.in_place_of}: {x_new:.3g}x on all data against "
                  f"{res.residual_x_noise:.3g}x; {a.in_place_of} stays")
            return {"within": [a.name for a in res.alternatives if a.within], "preferred": None,
                    "not_swapped": {"name": a.name, "in_place_of": a.in_place_of, "residual_x_noise": x_new,
                                    "residual_x_noise_kept": res.residual_x_noise}, "not_fitted": not_fitted}
        val = _parts_cost(s.full, sims, s.parts)
        why = (f"these logs prefer {a.name} to {a.in_place_of}: {-a.score_difference_db:.2f} dB better over the "
               f"campaign (they resolve {a.resolvable_db:.2f} dB), worse on no run by more than the logs allow, and "
               f"not worse on all data ({x_new:.3g}x against {res.residual_x_noise:.3g}x)")
        for st in s.steps:
            if st.effect == a.in_place_of and st.kept:
                st.kept = False
                st.reason += f"; replaced in the end: {why}"
        s.steps.append(Step(a.name, True, f"put in place of {a.in_place_of}: {why}", f, f.cost, val,
                            _held_fit(s.full, sims, s.held_idx)))
        s.say(f"  {a.name}: reported in place of {a.in_place_of} ({why})")
        if get_effect(a.name).kind == "hypothesis":
            f, sims, val = _drop_swapped_stand_ins(s, a.name, (f, sims, val), x_new)
        s.keep(f, sims, val)
        # the final model measured again (a second measure record: the reported figure is the last measure's), and
        # the explanation it replaced compared in its place
        measure_again(s, why)
        not_fitted = []  # the record's: those of the model reported now
        s.result.alternatives = find_alternatives(s.result, fit_null, fit_candidate, s.say, not_fitted)
        swapped = {"name": a.name, "in_place_of": a.in_place_of, "score_difference_db": round(a.score_difference_db, 2)}
    return {"within": [a.name for a in s.result.alternatives if a.within], "preferred": swapped,
            "not_fitted": not_fitted}


def _drop_swapped_stand_ins(s: Search, hyp: str, now: tuple, x_now: float) -> tuple:
    """The structural hypothesis ``hyp`` was put in place of an explanation the logs liked less (``now``: its
    Fit, simulation of every run, validation cost; ``x_now`` its figure on all data).  The effects kept before it
    were found without it and may stand in for part of it, as they may when it is kept in a round: each is refitted
    away (:func:`~ehas_env.diagnosis.candidates._drop_stand_ins`).  The model without them is kept only when its
    figure on all data is not worse than ``x_now``: the one figure decides.

    Returns
    -------
    tuple
        (Fit, sims, validation cost) of the model kept.
    """
    f, sims, val = now
    flags = [(st.kept, st.reason) for st in s.steps]
    g, gs, gval = _drop_stand_ins(s.rep, s.full, s.parts, f, val, hyp, s.steps, s.say, sims=sims)
    if g is f:
        return now
    x_g = grade(blocks_of(s.full, gs, COST_SIGNALS))["residual_x_noise"]
    if x_g <= x_now:
        return g, gs, gval
    steps_back_to(s.steps, flags, "")  # worse on the one figure: every step as it was (no step was added)
    s.say(f"  without the effects {hyp} may stand in for: {x_g:.3g}x on all data against {x_now:.3g}x; they stay")
    return now


#: the diagnosis, in order: (name, stage); each takes the Search and returns its record (docs/diagnosis-pipeline.md)
STAGES = (
    ("library", library_stage),
    ("hypotheses", hypotheses_stage),
    ("measured_inputs", measured_inputs_stage),
    ("states", states_stage),
    ("measure", measure_stage),
    ("no_worse", no_worse_stage),
    ("alternatives", alternatives_stage),
    ("per_run", per_run_parameters_stage),
    ("verdict", verdict_stage),
    ("proposal", proposal_stage),
)


def run_stages(s: Search, stages=STAGES) -> list:
    """Run ``stages`` in order on ``s``; each record gets the stage's name and time.

    Parameters
    ----------
    s : Search
        The search (from :func:`~ehas_env.diagnosis.search.data_stage`).
    stages : sequence of (str, callable)
        The stages.

    Returns
    -------
    list of dict
        One record per stage: ``stage``, ``elapsed_s``, ``replays`` (the campaign's replays it made, fit data and
        all data) and what the stage returned.
    """
    def replays():  # of the fit data and of all data (a replay of all data costs more: both are counted)
        return s.rep.n_evals + s.full.n_evals

    for name, stage in stages:
        t, n = time.perf_counter(), replays()
        out = stage(s) or {}
        s.records.append({"stage": name, "elapsed_s": round(time.perf_counter() - t, 2), "replays": replays() - n,
                          **out})
    return s.records


@on_one_blas_thread  # the same numbers in a fleet's worker as here
def diagnose_open(campaign: Campaign, *, candidates=None, base_effects: dict | None = None, holdout=None,
                  stack: bool = True, propose: bool = True, hypotheses: bool = True, window_s: float = FIT_WINDOW_S,
                  progress: bool = False, log=None, model=None,
                  alternatives: bool = True, per_run: bool = True, measured_inputs: bool = True,
                  states: bool = True, stages=None) -> OpenDiagnosis:
    """The open-world diagnosis: the best model of the library, then whether it explains the campaign.

    The stages of :data:`STAGES`, in order, after the data stage (:func:`~ehas_env.diagnosis.search.data_stage`):

    1. Runs named by ``holdout`` (default :func:`~ehas_env.diagnosis.candidates.default_holdout`) are kept out
       of the fit; the others are fitted on their windows; the validation data are the held-out runs and the
       fitted closed-loop runs beyond their windows.
    2. ``library``: rounds of :func:`~ehas_env.diagnosis.candidates.diagnose`; the best candidate that beats
       noise is kept when it is physically sane (after widening a range it ran into), lowers the validation
       residual by at least ``VAL_GAIN`` and fits the same on two separate groups of runs; with ``stack`` the
       kept model is the base of the next round.
    3. ``hypotheses``: the structural hypotheses, when the library's model leaves the campaign unexplained or
       with a structured rest (:func:`~ehas_env.diagnosis.candidates.hypotheses_trigger`), judged alike; never
       kept when they make the all-data residual worse (honesty rule 2).
    4. ``measure``, ``per_run``, ``verdict``: the graded verdict on all data
       (:func:`ehas_env.measurement.verdict.grade`), what the remaining residual follows, confidence intervals,
       the parameters per run and their drift.
    5. ``proposal``: when unexplained, the missing term at a place of the model, fitted and named
       (:func:`ehas_env.diagnosis.proposal.propose`); ``alternatives``: what these logs cannot tell apart.

    Parameters
    ----------
    campaign : Campaign
        The measurements (:func:`ehas_env.measurement.campaign.read_campaign`).
    candidates : list of str, optional
        Effects to try (default: the library's, :func:`~ehas_env.diagnosis.candidates.library_effects`).
    base_effects : dict, optional
        Effects the model has from the start, {name: {param: value}} (refitted with every candidate).
    holdout : list of str, optional
        Names of runs kept out of the fit (default: ``default_holdout``; ``[]``: none).
    stack : bool
        Keep stacking effects while one passes (False: one round).
    propose : bool
        Propose the missing term when the verdict is ``unexplained``.
    hypotheses : bool
        Try the structural hypotheses when the library's effects leave the campaign not explained, or explained
        with a structured rest; and in place of a kept library effect they may be mistaken for.
    window_s : float
        Seconds of each closed-loop run fitted.
    progress : bool
        Show progress bars.
    log : callable, optional
        Called with one line of progress text per step.
    model : PlantModel or str, optional
        A model file's rig to diagnose on (docs/model-file.md; default the book's rig).
    alternatives : bool
        Fit the explanations each effect of the final model may be confused with in its place and list those
        these logs cannot tell apart (:func:`ehas_env.diagnosis.alternatives.find_alternatives`).
    per_run : bool
        Fit the final model's parameters on each closed-loop run alone and report those that differ between runs
        (:func:`ehas_env.diagnosis.drift.per_run_stage`).
    measured_inputs : bool
        Take a logged quantity the model holds constant (the supply pressure) as a measured input when that
        explains the residual (:func:`measured_inputs_stage`).
    states : bool
        Look for a missing state place by place when the model kept leaves a residual (:func:`states_stage`).
    stages : sequence of (str, callable), optional
        The stages after the data stage (default :data:`STAGES`): a search of your own is a function of the
        :class:`~ehas_env.diagnosis.search.Search` returning its record, added where it belongs
        (docs/diagnosis-pipeline.md).  ``measure`` must run before the stages that read ``s.result``.

    Returns
    -------
    OpenDiagnosis
        The rounds, every step judged (kept or not, and why), the final model with confidence intervals,
        its simulation of every run, ``verdict``, ``residual_x_noise`` and ``grade``, ``unexplained`` (the
        remaining residual, where and what it follows, the proposal; None when explained), ``stages`` (each
        stage's record and time), ``elapsed_s``.

    Raises
    ------
    ValueError
        A ``holdout`` name that is no run of the campaign, or every run held out.
    """
    t0 = time.perf_counter()
    s = data_stage(campaign, holdout=holdout, window_s=window_s, model=model, hypotheses=hypotheses,
                   base_effects=base_effects, candidates=candidates, stack=stack, progress=progress, say=log)
    s.options = {"propose": propose, "alternatives": alternatives, "per_run": per_run, "base_effects": base_effects,
                 "measured_inputs": measured_inputs, "states": states}
    from ehas_env.physics.codegen import load_scale

    est = estimate(s.rep, load_scale(), candidates)
    s.say(in_words(est))
    if est["replays"] >= REPLAYS[1][1]:
        # the search will go beyond the library's rounds: the model with the structural hypotheses and blocks
        # compiles on the other core while the library's rounds replay (a first diagnosis on this machine)
        s.rep.compile_behind()
    if s.full.not_compared_text():
        s.say(s.full.not_compared_text())
    s.records.append({"stage": "data", "elapsed_s": round(time.perf_counter() - t0, 2), "holdout": s.held,
                      "fit_runs": [r.name for r in s.train_runs], "estimate": est})
    run_stages(s, STAGES if stages is None else stages)
    res = s.result
    if res is None:
        raise ValueError("stages: the 'measure' stage (measure_stage) must be among the stages; it builds the result")
    res.stages = s.records
    res.elapsed_s = time.perf_counter() - t0
    res.n_evals = s.rep.n_evals + s.full.n_evals
    return res


def propose_stage(rep: Replayer, full: Replayer, final: Fit, sims_all: list, parts: dict, cur_val, g: dict,
                  say) -> tuple:
    """The missing term (:func:`ehas_env.diagnosis.proposal.propose`, built on the best try that holds on the runs
    held out of the fit), judged on all data and by honesty rule 1 (:func:`ehas_env.diagnosis.honesty.term_refused`).

    Parameters
    ----------
    rep, full : Replayer
        The fit data and every run.
    final : Fit
        The final model (on the fit data); ``sims_all`` its simulation of every run.
    sims_all : list
        The final model on every run.
    parts : dict
        The validation samples ({case index: first sample}).
    cur_val : float or None
        The final model's validation residual.
    g : dict
        The final model's grade on all data.
    say : callable
        Progress text.

    Returns
    -------
    (Proposal or None, sims or None, str or None)
        The proposal kept (with its ``validation`` numbers) and its simulation of every run, or None; and why a
        term found was refused (None when none was, or none was found).
    """
    def proven(model) -> bool:  # the term holds on the runs held out of the fit (not above the model without it)
        if not parts or cur_val is None:
            return True
        v = _parts_cost(full, full.simulate(model), parts)
        return v is None or v <= cur_val

    prop = P.propose(rep, final, confidence=confidence, say=say, proven=proven)
    if prop is None:
        return None, None, None
    ps = full.simulate(prop.fit.model)
    val_after = _parts_cost(full, ps, parts)
    prop.validation = {"residual_x_noise_all_before": g["residual_x_noise"],
                       "residual_x_noise_all_after": grade(blocks_of(full, ps, COST_SIGNALS))["residual_x_noise"],
                       "fit_percent_all_before": round(full.fit_table(sims_all).overall, 2),
                       "fit_percent_all_after": round(full.fit_table(ps).overall, 2),
                       "residual_x_noise_validation_before": None if cur_val is None else round(cur_val, 3),
                       "residual_x_noise_validation_after": None if val_after is None else round(val_after, 3)}
    refused = term_refused(prop.validation["residual_x_noise_all_before"], prop.validation["residual_x_noise_all_after"])
    if refused is not None:
        say(f"  no term proposed: {refused}")
        return None, None, refused
    # the named forms (ehas_env.diagnosis.naming) are held to honesty rule 1 on all data too
    judge_on_all_data(prop, lambda m: grade(blocks_of(full, full.simulate(m), COST_SIGNALS))["residual_x_noise"],
                      g["residual_x_noise"])
    return prop, ps, None


#: effects judged but not kept that the per-run stage refits run by run (the first judged: the best ranked)
PER_RUN_NOT_KEPT = 3


def not_kept(steps: list, final: Fit) -> dict:
    """The effects judged but not kept (not in the final model), at most :data:`PER_RUN_NOT_KEPT`, first judged
    first: {effect: its Fit}.  A parameter that changes from run to run makes its effect fit differently on
    separate groups of runs, or fail on the validation runs; refitted run by run
    (:func:`ehas_env.diagnosis.drift.per_run_stage`), it shows.

    Parameters
    ----------
    steps : list of Step
        Every step judged.
    final : Fit
        The final model.

    Returns
    -------
    dict
    """
    out = {}
    for st in steps:
        if len(out) >= PER_RUN_NOT_KEPT:
            break
        if not st.kept and st.fit is not None and st.effect not in final.model.effects and st.effect not in out \
                and st.effect in st.fit.model.effects:
            out[st.effect] = st.fit
    return out


def unexplained_text(res: OpenDiagnosis, u: dict) -> str:
    """The verdict in words."""
    what = "the baseline" + "".join(f" + {n}" for n in res.model.effects)
    where = ", ".join(f"{w['signal']} {w['rms_x_noise']:.1f}x" for w in u["where"][:3])
    fol = ", ".join(f"{n} ({100 * s:.0f} %)" for n, s in list(u["follows_shares"].items())[:3]) or "no listed quantity"
    w = u["worst"] or {}
    found = "the best model found" if res.model.effects else "the baseline (no effect kept)"
    head = (f"unexplained: {found} leaves more than what does not repeat" if res.verdict == "unexplained" else
            f"small structured residual: {found} leaves a repeatable residual above what does not repeat, "
            "but not enough to call the campaign unexplained")
    above = u.get("blocks_above", [])
    text = (f"{head}. The best model found ({what}) leaves residuals at {u['residual_x_noise']:.2f}x what does not "
            f"repeat from cycle to cycle (sensor noise, disturbances; geometric mean over runs and signals; "
            f"explained up to {res.grade['thresholds']['explained']:g}x, unexplained above {u['threshold']:g}x"
            + (f"; structured part {u['structured_db']:+.1f} dB against it" if u["structured_db"] is not None else "")
            + f"), worst {w.get('signal', '')} in run {w.get('run', '')} at {w.get('residual_x_noise', 0.0):.2f}x; "
            f"residual RMS in sensor-noise units: {where}. What is left follows {fol}.")
    if above:
        text += (f" Above {BLOCK_NAMED_X:g}x: " + ", ".join(f"{b['signal']} in run {b['run']} ({b['residual_x_noise']:.1f}x)"
                                                           for b in above[:5])
                 + (f" and {len(above) - 5} more run and signal pairs" if len(above) > 5 else "") + ".")
    p = u.get("proposal")
    if res.verdict != "unexplained":
        text += (" No term is proposed at this level: a residual this small may come from the numerics of two "
                 "simulators of one rig as much as from physics.")
    if res.disturbances:
        text += " Disturbances: " + "; ".join(d["text"] for d in res.disturbances[:3]) + "."
    if res.drift:
        text += " Parameters that differ between runs: " + "; ".join(d["text"] for d in res.drift) + "."
    if u.get("no_term"):
        text += f" No term is proposed: {u['no_term']}."
    if p:
        text += (f" Proposed missing term at {', '.join(p['where'])}: {p['equation']}; residual "
                 f"{p['residual_x_noise_before']:.2f}x -> {p['residual_x_noise_after']:.2f}x noise on the fit data.")
        if p.get("named"):
            text += " Named: " + "; ".join(f"{n['words']} ({n['kind']}, keeps {100 * n['keeps_share']:.0f} % of "
                                           "the flexible term's gain)" for n in p["named"]) + "."
    return text
