"""The search stages of the open-world diagnosis: the data split, the library's effects, the structural hypotheses.

:func:`ehas_env.diagnosis.pipeline.diagnose_open` runs its stages in
order on one :class:`Search`, the state they pass along (docs/diagnosis-pipeline.md
draws it).  This module holds the first three:

* :func:`data_stage`: which runs are fitted and which validate (``holdout``,
  the fit windows), the compiled replayers;
* :func:`library_stage`: rounds of :func:`ehas_env.diagnosis.candidates.diagnose`
  over the library's effects, each best candidate judged (:func:`judge_round`)
  and kept while one passes (stacking);
* :func:`hypotheses_stage`: when the library leaves the campaign unexplained or
  with a structured rest (:func:`ehas_env.diagnosis.candidates.hypotheses_trigger`),
  the same rounds over the structural hypotheses; a hypothesis that lost to a
  kept library effect may be tried in its place (:func:`_swap_branch`); and the
  model kept must not leave a worse all-data residual than the library's
  (honesty rule 2, :func:`keep_no_worse`).

The rules that judge one candidate (sanity, validation gain, agreement on
separate groups of runs, rival hypotheses, pairs) live in
:mod:`ehas_env.diagnosis.candidates`; this module only sequences them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ehas_env.measurement.campaign import Campaign
from ehas_env.diagnosis.candidates import (
    MAX_ROUNDS, QUIET_UNITS, Diagnosis, Step, _drop_stand_ins, _held_fit, _pair_hypotheses, _parts_cost,
    _quiet_measure, _rival_hypotheses, _sane, _share_needed, coulomb_from_stribeck, default_holdout,
    degenerate_stribeck, diagnose, fit_candidate, fit_null, fit_window_samples, hypothesis_effects, library_effects,
    lowers_validation, stands_in, windowed, with_defaults, hypotheses_trigger)
from ehas_env.diagnosis.fitting import MIN_GAIN, MIN_SCORE, Fit
from ehas_env.diagnosis.honesty import worse_than_bare
from ehas_env.measurement.replay import COST_SIGNALS, Replayer
from ehas_env.measurement.verdict import blocks_of, grade
from ehas_env.physics.augment import augmentations
from ehas_env.physics.effects import get_effect


@dataclass
class Search:
    """What the stages of the diagnosis pass along: the data, the model kept so far, every step judged.

    The fields a stage reads and writes are named in its docstring; the JSON names of what they hold are those
    of :meth:`ehas_env.diagnosis.pipeline.OpenDiagnosis.to_json` (``stack``, ``validation``, ``model``).
    """

    campaign: Campaign
    rep: Replayer  # the fit data: the fitted runs' windows
    full: Replayer  # every run, full length (with the measured inputs kept, once the measured_inputs stage keeps one)
    held: list  # names of the held-out runs (``validation.holdout``)
    held_idx: list  # their indices in ``full.cases``
    train_runs: list  # the fitted runs (``validation.fit_runs``)
    parts: dict  # validation samples: {case index: first sample}
    window_s: float
    say: object
    candidates: list | None = None
    hypotheses: bool = True
    stack: bool = True
    progress: bool = False
    base: dict = field(default_factory=dict)  # the effects of the model kept so far, {name: {param: value}}
    rounds: list = field(default_factory=list)  # Diagnosis of every round
    steps: list = field(default_factory=list)  # Step of every candidate judged (``stack``)
    current: Fit | None = None  # the model kept so far, on the fit data
    cur_sims: list | None = None  # ... its simulation of every run
    cur_val: float | None = None  # ... its validation residual (noise variances)
    hyps: list = field(default_factory=list)  # the structural hypotheses that may be tried
    rivals: list = field(default_factory=list)  # ... and the missing states that say whom they may be mistaken for:
    # fitted in place of a kept library effect of the same signature (diagnosis._rival_hypotheses)
    pool: list | None = None  # the candidates of the next round (None: the library's)
    structural: bool = False  # the structural hypotheses are being tried
    quiet: str | None = None  # they are tried on a campaign the library explains: the key of QUIET_UNITS
    before_hyp: float | None = None  # the residual, in those units, when they were started
    hyp_because: str | None = None  # why they were tried (``validation.hypotheses_tried_because``)
    before_floor: float | None = None  # the residual in floors then (``validation.residual_x_noise_before_hypotheses``)
    paired: bool = False  # the pair of hypotheses was tried (once)
    inconsistent: list = field(default_factory=list)  # library effects that fit differently on groups of runs
    lost_rivals: list = field(default_factory=list)  # (library effect kept, hypothesis that lost to it)
    swap: tuple | None = None  # the state before a branch put a hypothesis in the place of effects kept (_start_branch)
    bare: tuple | None = None  # the model before the hypotheses (honesty rule 2 compares with it)
    ended: bool = False  # the rounds ran out (MAX_ROUNDS) or no candidate is left
    records: list = field(default_factory=list)  # one record per stage run: name, elapsed_s, what it found
    options: dict = field(default_factory=dict)  # the caller's switches of the later stages (propose, per_run ...)
    result: object = None  # the OpenDiagnosis, once the measure stage has built it
    full_as_given: Replayer | None = None  # every run as the sidecars state them (no measured input): the start

    def keep(self, f: Fit, sims: list, val) -> None:
        """Make ``f`` (its simulation of every run ``sims``, validation cost ``val``) the model kept so far."""
        self.current, self.cur_sims, self.cur_val = f, sims, val
        self.base = {k: dict(v) for k, v in f.model.effects.items()}

    def grade(self) -> dict:
        """The verdict's grade of the model kept so far, on every run."""
        return grade(blocks_of(self.full, self.cur_sims, COST_SIGNALS))


def data_stage(campaign: Campaign, *, holdout=None, window_s: float, model=None, hypotheses: bool = True,
               base_effects: dict | None = None, candidates=None, stack: bool = True, progress: bool = False,
               say=None) -> Search:
    """The stage of the data: the held-out runs, the fit windows, the replayers of the fit data and of every run.

    Parameters
    ----------
    campaign : Campaign
        The measurements.
    holdout : list of str, optional
        Runs kept out of the fit (default :func:`~ehas_env.diagnosis.candidates.default_holdout`).
    window_s : float
        Seconds of each closed-loop run fitted.
    model : PlantModel or str, optional
        A model file's rig (default the book's).
    hypotheses : bool
        Compile the structural hypotheses into the model (they may be tried).
    base_effects : dict, optional
        Effects the model has from the start.
    candidates : list of str, optional
        The library effects to try (default every one).
    stack, progress : bool
        Keep stacking while a candidate passes; show progress bars.
    say : callable, optional
        Progress text, one line per call.

    Returns
    -------
    Search
        With ``held``, ``train_runs``, ``parts``, ``rep``, ``full`` and ``base`` set.

    Raises
    ------
    ValueError
        A ``holdout`` name that is no run of the campaign, or every run held out.
    """
    names = {r.name for r in campaign.runs}
    held = list(default_holdout(campaign) if holdout is None else holdout)
    for h in held:
        if h not in names:
            raise ValueError(f"--holdout: no run '{h}' in the campaign (runs: {', '.join(sorted(names))})")
    train_runs = [r for r in campaign.runs if r.name not in held]
    if not train_runs:
        raise ValueError("--holdout: every run is held out; nothing is left to fit")
    train_c = windowed(Campaign(campaign.path, train_runs), window_s)
    # the structural hypotheses' model compiled when a replay names one (or a proposal's terms, when they may be tried)
    rep = Replayer(train_c, model=model, hypotheses=hypotheses)
    full = Replayer(campaign, model=rep.model, hypotheses=hypotheses)
    held_idx = [i for i, c in enumerate(full.cases) if c.run.name in held]
    parts = {}
    for i, case in enumerate(full.cases):
        if case.run.name in held:
            parts[i] = 0
        elif case.run.kind == "closed_loop":
            n = fit_window_samples(case.run, window_s)
            if n < case.run.n - 10:
                parts[i] = n
    s = Search(campaign=campaign, rep=rep, full=full, held=held, held_idx=held_idx, train_runs=train_runs,
               parts=parts, window_s=window_s, say=say or (lambda msg: None), candidates=candidates,
               hypotheses=hypotheses, stack=stack, progress=progress, base=with_defaults(base_effects))
    # the library's effects first; then, while the campaign is not explained, the structural hypotheses
    s.full_as_given = full
    s.hyps = [h for h in hypothesis_effects() if h not in s.base and (candidates is None or h not in candidates)]
    s.rivals = s.hyps + ([a for a in augmentations() if get_effect(a).mistaken_for and a not in s.base]
                         if hypotheses else [])
    s.pool = candidates
    return s


def judge_round(s: Search, d: Diagnosis) -> tuple | None:
    """The best candidates of one round (:func:`~ehas_env.diagnosis.candidates.diagnose`), judged in order: the
    first that is sane, lowers the validation residual, (on a quiet campaign) removes the share of the structured
    rest and fits the same on separate groups of runs is kept; a library effect kept may give its place to a
    structural hypothesis it may be mistaken for.

    Parameters
    ----------
    s : Search
        Reads ``base``, ``cur_val``, ``quiet``, ``before_hyp``, ``hyps``; appends to ``steps``,
        ``inconsistent`` and ``lost_rivals``.
    d : Diagnosis
        The round's ranking.

    Returns
    -------
    tuple
        (kept, judged, short): ``kept`` is (effect, Fit, simulation of every run, validation cost) of what is
        kept, or None; ``judged`` the effects judged and ``short`` the hypotheses that failed only on the share of
        a structured rest (the pair of hypotheses may use them).
    """
    rep, full, parts, say = s.rep, s.full, s.parts, s.say
    judged, short = set(), set()
    for e in [e for e in d.ranking if e.beats_noise][:3]:
        effect, f, note = e.effect, e.fit, ""
        if effect == "stribeck_friction" and degenerate_stribeck(f) and "coulomb_friction" not in s.base:
            # no breakaway peak: it is Coulomb friction, refitted from its sliding level
            st = f.model.effects[effect]
            f = coulomb_from_stribeck(rep, f)
            effect = "coulomb_friction"
            note = (f"stands for stribeck_friction, whose breakaway force Fs = {st['Fs']:.4g} N is not above its "
                    f"sliding force Fc = {st['Fc']:.4g} N; ")
            if d.null.cost - f.cost < MIN_GAIN:
                continue
        if effect in judged:
            continue
        judged.add(effect)
        f, why = _sane(rep, f, effect)
        sims = full.simulate(f.model)
        val = _parts_cost(full, sims, parts)
        fval = _held_fit(full, sims, s.held_idx)
        if why is None and val is not None and s.cur_val is not None and not lowers_validation(s.cur_val, val):
            why = (f"does not lower the residual of the validation data enough ({s.cur_val:.3g} -> {val:.3g} "
                   "sensor-noise variances)")
        if why is None and s.quiet and get_effect(effect).kind == "hypothesis":
            # the campaign was explained without it: it must remove a good share of the structured rest, in the
            # measure that made the search start
            x = _quiet_measure(full, sims, s.quiet)
            need = _share_needed(s.before_hyp)
            if x > need:
                why = (f"the campaign is explained without it ({s.before_hyp:.3g} x {QUIET_UNITS[s.quiet]}); it "
                       f"removes too little of the structured rest ({s.before_hyp:.3g} -> {x:.3g}, {need:.3g} "
                       "needed)")
                short.add(effect)
        if why is None:
            why = stands_in(rep, f, effect)
            if why is not None:
                note += "stands in for something else: "
                if get_effect(effect).kind != "hypothesis" and effect not in s.inconsistent:
                    s.inconsistent.append(effect)
        if get_effect(effect).kind == "hypothesis":
            note = get_effect(effect).in_words(f.model.effects[effect]) + "; " + note
        step = Step(effect, why is None, note + (why or "sane, lowers the residual of the fit and validation data, "
                                                 "and fits the same on separate groups of runs"),
                    f, f.cost, val, fval)
        s.steps.append(step)
        say(f"  {effect}: {'kept' if step.kept else 'not kept'} ({step.reason})")
        if why is None:
            kept = (effect, f, sims, val)
            if s.hypotheses and get_effect(effect).kind != "hypothesis":
                kept = _rival_hypotheses(rep, full, parts, s.held_idx, kept, d.null, s.cur_val, s.base, s.rivals,
                                         step, s.steps, say, s.lost_rivals)
            return kept, judged, short
    return None, judged, short


def search_round(s: Search) -> tuple | None:
    """One round: every candidate of ``s.pool`` fitted on top of the model kept so far, ranked, the best judged
    (:func:`judge_round`); what passes becomes the model kept (``s.keep``).  On a quiet campaign where no single
    hypothesis passed, the best pair is tried once.

    Parameters
    ----------
    s : Search
        The search; ``rounds``, ``steps`` and the model kept are updated.

    Returns
    -------
    tuple or None
        What was kept (effect, Fit, sims, validation cost), or None.
    """
    d = diagnose(s.rep.campaign, base_effects=s.base, candidates=s.pool, progress=s.progress, replayer=s.rep)
    s.rounds.append(d)
    if s.current is None:
        sims = s.full.simulate(d.null.model)
        s.current, s.cur_sims, s.cur_val = d.null, sims, _parts_cost(s.full, sims, s.parts)
    s.say(f"round {len(s.rounds)}: best {d.found}" + (f" on top of {', '.join(s.base)}" if s.base else ""))
    kept, judged, short = judge_round(s, d)
    if kept is None and s.structural and s.quiet and not s.paired and \
            not any(st.kept and get_effect(st.effect).kind == "hypothesis" for st in s.steps):
        s.paired = True
        kept = _pair_hypotheses(s.rep, s.full, s.parts, s.held_idx, d, s.base, judged - short, s.cur_val,
                                (s.quiet, s.before_hyp), s.steps, s.say)
    if kept is not None:
        effect, f, sims, val = kept
        s.keep(f, sims, val)
        if s.structural:
            current, sims, val = _drop_stand_ins(s.rep, s.full, s.parts, f, val, effect, s.steps, s.say, sims=sims)
            s.keep(current, sims, val)
            # on top of a structural change, the library's effects may now be seen: try them again too
            s.pool = list(s.candidates or library_effects()) + s.hyps
    return kept


def _rounds_left(s: Search) -> bool:
    """Whether another round may run (rounds below MAX_ROUNDS, a candidate not yet in the model); sets ``ended``."""
    if len(s.rounds) >= MAX_ROUNDS or (s.pool is not None and not [n for n in s.pool if n not in s.base]):
        s.ended = True
    return not s.ended


def library_stage(s: Search) -> dict:
    """The stage of the library: rounds over the library's effects (``candidates``), stacking while one passes.

    Parameters
    ----------
    s : Search
        Updated: ``rounds``, ``steps``, the model kept.

    Returns
    -------
    dict
        The stage's record: ``kept`` (effects kept in this stage), ``rounds``.
    """
    n0 = len(s.steps)
    while _rounds_left(s):
        kept = search_round(s)
        if kept is None or not s.stack:
            break
    return {"kept": [st.effect for st in s.steps[n0:] if st.kept], "rounds": len(s.rounds)}


def hypotheses_stage(s: Search) -> dict:
    """The stage of the structural hypotheses: tried when the library's model leaves the campaign unexplained or with
    a structured rest (:func:`~ehas_env.diagnosis.candidates.hypotheses_trigger`); rounds over them (and the
    library's effects again on top of one kept) until none passes or one explains the campaign; a lost rival may
    be tried in its library effect's place (:func:`_swap_branch`); the model kept must not leave a worse all-data
    residual than the library's (:func:`keep_no_worse`).

    Parameters
    ----------
    s : Search
        Updated: ``structural``, ``quiet``, ``before_hyp``, ``hyp_because``, ``before_floor``, ``bare``, ``rounds``,
        ``steps``, the model kept.

    Returns
    -------
    dict
        The stage's record: ``tried_because`` (None when not tried), ``kept``.
    """
    if s.ended or not s.hypotheses or not s.hyps:
        return {"tried_because": None, "kept": []}
    why = hypotheses_trigger(s.grade(), s.full.log_cost(s.cur_sims), s.inconsistent)
    if why is None:
        return {"tried_because": None, "kept": []}
    s.quiet, s.before_hyp, s.hyp_because = why
    s.before_floor = s.grade()["residual_x_noise"]
    s.say(s.hyp_because)
    s.structural, s.pool = True, s.hyps
    # the bare model, before the hypotheses: honesty rule 2 compares the final model with it on all data
    s.bare = (s.current, s.cur_sims, s.cur_val, {k: dict(v) for k, v in s.base.items()},
              [(st.kept, st.reason) for st in s.steps])
    n0 = len(s.steps)
    # when the rounds find nothing more and the campaign is not explained, two branches, each once: a hypothesis
    # that lost to a kept library effect in its place, then the best hypothesis alone in place of all of them
    branches = [_swap_branch, _restart_branch]
    while True:
        kept = None
        while _rounds_left(s):
            kept = search_round(s)
            if kept is not None and s.grade()["verdict"] == "explained":
                break  # a structural hypothesis explains the campaign: no round of every candidate again on top
            if kept is None or not s.stack:
                break
        if s.swap is not None:
            _settle_swap(s)
            s.swap = None
        if kept is not None or s.ended or s.grade()["verdict"] == "explained":
            break
        while branches and not branches.pop(0)(s):
            pass
        if s.swap is None:
            break
    s.current, s.cur_sims, s.cur_val, s.base = keep_no_worse(s.full, s.bare, (s.current, s.cur_sims, s.cur_val,
                                                                             s.base), s.steps, s.say)
    return {"tried_because": s.hyp_because, "kept": [st.effect for st in s.steps[n0:] if st.kept]}


def _swap_branch(s: Search) -> bool:
    """Nothing more found: a hypothesis that lost to a kept library effect may have lost because of what the
    campaign still misses; it is put in the effect's place and the search goes on on top of it (the branch is
    kept only when it ends better on the validation data: :func:`_settle_swap`).  Returns whether it started."""
    pending = [(e, h) for e, h in s.lost_rivals if e in s.base and h not in s.base]
    if not pending:
        return False
    e_lib, h = pending[0]
    rest = {k: dict(v) for k, v in s.base.items() if k != e_lib}
    f = fit_candidate(s.rep, h, fit_null(s.rep, rest), rest)
    _start_branch(s, (e_lib,), h, f, f"put in place of {e_lib} to search again on top of it",
                  f"put in place of {e_lib}, searching the hypotheses again on top of it")
    s.pool = [n for n in s.hyps if n != h]
    return True


def _start_branch(s: Search, set_aside: tuple, h: str, f, step_words: str, said: str) -> None:
    """Start a branch (:func:`_swap_branch`, :func:`_restart_branch`): the state before it kept in ``s.swap`` (with
    the effects ``set_aside`` for the hypothesis ``h``), ``f`` (the model with ``h`` in their place, on the fit data)
    made the model kept, its step said with ``step_words`` after ``h``'s own words, ``said`` on the progress."""
    s.swap = (set_aside, h, s.current, s.cur_sims, s.cur_val, {k: dict(v) for k, v in s.base.items()}, len(s.steps))
    sims = s.full.simulate(f.model)
    val = _parts_cost(s.full, sims, s.parts)
    s.steps.append(Step(h, True, get_effect(h).in_words(f.model.effects[h]) + "; " + step_words, f, f.cost, val,
                        None))
    s.say(f"  {h}: {said}")
    s.keep(f, sims, val)


#: the share of the library's model's fit-data cost a structural hypothesis alone must leave (at most) for the
#: search to start again from it (:func:`_restart_branch`): what a candidate must score to beat the noise
RESTART_RATIO = 10.0 ** (-MIN_SCORE / 10.0)


def _restart_branch(s: Search) -> bool:
    """Nothing more found on top of the library's effects: the structural hypotheses are screened (and the best
    refined) on the recalibrated baseline without them.  One that alone leaves less than the library's model does
    on the fit data (:data:`RESTART_RATIO` of its cost at most) shows that the library's effects stood in for it
    (a return line's back pressure taken for an internal leakage and a piston mass, a rod's area for a soft oil,
    on campaigns that start from rest, where the first round sees the start's large error alone): the search goes
    on from it, the library's effects set aside and tried again on top; the branch is kept only when it ends
    better on the validation data (:func:`_settle_swap`).  Returns whether it started."""
    lib = tuple(st.effect for st in s.steps if st.kept and st.effect in s.base
                and get_effect(st.effect).kind != "hypothesis")
    hyps = [n for n in s.hyps if n not in s.base]
    if not lib or not hyps or len(s.rounds) >= MAX_ROUNDS - 1:
        return False
    # the effects the search started from (the user's ``--with``) stay: only the library's are set aside
    d = diagnose(s.rep.campaign, base_effects=s.rounds[0].base_effects, candidates=hyps, progress=s.progress,
                 replayer=s.rep)
    s.rounds.append(d)
    best = next((e for e in d.ranking if e.beats_noise and e.effect in hyps), None)
    if best is None or not best.fit.cost <= RESTART_RATIO * s.current.cost:
        s.say(f"round {len(s.rounds)}: the hypotheses without {', '.join(lib)}: none leaves less alone than they do")
        return False
    h = best.effect
    f, why = _sane(s.rep, best.fit, h)
    if why is not None:
        return False
    _start_branch(s, lib, h, f, f"alone it leaves less than {', '.join(lib)} together ({f.cost:.4g} against "
                  f"{s.current.cost:.4g} sensor-noise variances on the fit data): put in their place to search again "
                  "on top of it",
                  f"alone it leaves less than {', '.join(lib)}; put in their place, searching again on top of it")
    s.pool = list(s.candidates or library_effects()) + [n for n in s.hyps if n != h]
    return True


def _settle_swap(s: Search) -> None:
    """The branch of :func:`_swap_branch` or :func:`_restart_branch` ended: kept when better on the validation
    data, else undone."""
    names, h, s_cur, s_sims, s_val, s_base, n_steps = s.swap
    e_lib = ", ".join(names)
    now, was = (s.cur_val, s_val) if s.cur_val is not None and s_val is not None else (s.current.cost, s_cur.cost)
    if lowers_validation(was, now, strict=True):
        for st in s.steps[:n_steps]:
            if st.effect in names and st.kept:
                st.kept = False
                st.reason = (f"stands in for {h} ({get_effect(h).title}): with {h} in its place the search "
                             f"found more, and the residual fell to {now:.4g} sensor-noise variances "
                             f"(with {e_lib}: {was:.4g})")
        s.say(f"  {e_lib}: dropped (stands in for {h}: the search on top of {h} ends better on the validation data)")
        return
    tried = s.steps[n_steps:]  # back to the model before the branch, the branch's steps said as tried
    s.steps[n_steps:] = [Step(h, False, f"tried in place of {e_lib} with the hypotheses searched again on top "
                              f"of it ({', '.join(st.effect for st in tried[1:] if st.kept) or 'nothing kept'}"
                              f"): the residual {now:.4g} sensor-noise variances, not better than "
                              f"{was:.4g} with {e_lib}", tried[0].fit, tried[0].cost_train,
                              tried[0].cost_val, None)]
    s.say(f"  {h} in place of {e_lib}: not better on the validation data; {e_lib} stays")
    s.current, s.cur_sims, s.cur_val, s.base = s_cur, s_sims, s_val, s_base


def keep_no_worse(full: Replayer, bare: tuple, now: tuple, steps: list, say) -> tuple:
    """Honesty rule 2 (:func:`ehas_env.diagnosis.honesty.worse_than_bare`): when the model the structural
    hypotheses led to (``now``: Fit, simulation of every run, validation cost, base effects) leaves a worse
    all-data residual than the ``bare`` model the library gave before them (the same, and every step's
    (kept, reason) then), the bare model is restored and every step kept since is said not kept, with why.

    Parameters
    ----------
    full : Replayer
        Every run, full length.
    bare, now : tuple
        (Fit, sims, validation cost, base effects[, steps' (kept, reason)]).
    steps : list of Step
        Every step judged (changed in place when the bare model is restored).
    say : callable
        Progress text.

    Returns
    -------
    tuple
        The model kept: (Fit, sims, validation cost, base effects).
    """
    b_fit, b_sims, b_val, b_base, flags = bare
    n_fit, n_sims, n_val, n_base = now
    if n_fit is b_fit:
        return now
    x_bare = grade(blocks_of(full, b_sims, COST_SIGNALS))["residual_x_noise"]
    x_now = grade(blocks_of(full, n_sims, COST_SIGNALS))["residual_x_noise"]
    why = worse_than_bare(x_bare, x_now)
    if why is None:
        return now
    steps_back_to(steps, flags, f"with the effects kept since the hypotheses were tried, it {why}")
    say(f"  the hypotheses kept {why}: back to the model without them")
    return b_fit, b_sims, b_val, b_base


def steps_back_to(steps: list, flags: list, why: str) -> None:
    """The steps as they stood when the bare model was set aside: every step kept since is said not kept (with
    ``why``), and the earlier steps get back their (kept, reason) of then (a library effect dropped as a stand-in
    since is kept again).

    Parameters
    ----------
    steps : list of Step
        Every step judged (changed in place).
    flags : list of (bool, str)
        The (kept, reason) of each step when the bare model was set aside.
    why : str
        Why the later steps are not kept in the end.
    """
    for st in steps[len(flags):]:
        if st.kept:
            st.kept = False
            st.reason += f"; not kept in the end: {why}"
    for st, (kept, reason) in zip(steps, flags):
        st.kept, st.reason = kept, reason
