"""Other explanations that fit a campaign as well as the one reported: what these logs cannot tell apart.

A diagnosis keeps the first explanation that fits; from runs at one supply
pressure, centred on the stroke, another physical explanation may fit the logs
as well and predict a different rig under other conditions (issue 34): a
compliant actuator mount and a softer oil both put a spring in series with the
piston; air in the oil is a softer oil at one pressure; seal friction growing
with the chamber pressures is a constant Coulomb force at one supply.

:func:`find_alternatives` takes each effect of the final model, fits every
effect it may be confused with (:func:`rivals_of`: the pairs of
:data:`CONFUSABLE`, and the effects' own ``mistaken_for``) in its place on the
same fit data (the rest of the model refitted with it), and compares the two on
all the campaign's data (every run, whole length, held-out runs included) by
the diagnosis' evidence score (:func:`~ehas_env.diagnosis.fitting.score_db`):
the score difference is ``10 log10(J_alt / J_reported)`` dB less
:data:`~ehas_env.diagnosis.fitting.PENALTY_PER_PARAM` per parameter the
reported one has more.  Effects that were ranked in the same round as the
reported one and beat the noise are compared the same way (their fits are on
the same base; no new fit), unless one extends the other's law (its parameters
include all of the other's: Stribeck friction's Fc, Fs, vs hold Coulomb
friction's Fc), which is the same explanation with more freedom.

**The rule for "within".** The score difference is a mean over the fit data; its
own uncertainty is that of a paired comparison.  The residuals of both models
are cut into the clusters the confidence intervals use
(:data:`~ehas_env.diagnosis.fitting.CI_BLOCK_S` stretches of each run, all its
signals together); in each cluster the difference ``d_c = 10 log10(e_alt /
e_reported)`` of the mean squared noise-normalised residuals is taken.  The
logs resolve a difference of ``max(2 SE, MIN_SCORE)`` dB with SE = std(d_c) /
sqrt(clusters) (two standard errors: 95 %; never finer than
:data:`~ehas_env.diagnosis.fitting.MIN_SCORE`, what a candidate must score to
beat the noise at all).  An alternative whose score is not lower than the
reported one's by more than that, nor by more than :data:`SEPARATED_DB` (3 dB) over
the campaign or on any one of its runs, is *within*: listed under ``alternatives``,
and the verdict says these logs cannot tell them apart.  One that is lower by
more is *decided*: the verdict says by how many dB the data rule it out.

Examples
--------
>>> sorted(rivals_of("bulk_modulus"))
['hyp_entrained_air', 'hyp_load_compliance']
>>> resolvable_db(np.array([0.1, -0.1, 0.2, 0.0]))
0.3
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ehas_env.diagnosis.fitting import (
    CI_BLOCK_S, MIN_SCORE, PENALTY_PER_PARAM, Fit, Objective, _value_of, confidence, own_params, start_value)
from ehas_env.diagnosis.states import proxy_bar, term_at
from ehas_env.measurement.replay import COST_SIGNALS, Replayer
from ehas_env.physics.effects import REGISTRY, get_effect

#: dB: an alternative whose residual is twice the reported one's (J doubled: one more noise variance left), over the
#: campaign or on any one run, is told apart however much the clusters' differences spread (their spread widens
#: the resolution of the paired rule beyond 3 dB when one run separates the two and the others do not; a run's J
#: over thousands of samples is not doubled by chance)
SEPARATED_DB = 3.0

#: pairs of effects that put the same signature into runs at one supply pressure, centred on the stroke, and why.
#: (An effect file may also declare the library effects it can be mistaken for: ``Effect.mistaken_for``.)
CONFUSABLE = {
    frozenset({"bulk_modulus", "hyp_load_compliance"}):
        "a softer oil and a compliant actuator mount or load path both put a spring in series with the piston; "
        "at the chamber volumes of runs centred on the stroke their stiffness is alike (off centre the oil's "
        "stiffness changes with the chamber volumes, the mount's does not)",
    frozenset({"bulk_modulus", "hyp_entrained_air"}):
        "air in the oil softens it most at low pressure; at one supply pressure the chambers stay near one "
        "pressure and a constant softer oil fits as well (at another supply pressure the air's share changes)",
    frozenset({"hyp_entrained_air", "hyp_load_compliance"}):
        "air in the oil and a compliant mount both soften the actuator's spring (the air's share falls with the "
        "pressure, the mount's spring does not)",
    frozenset({"coulomb_friction", "hyp_pressure_friction"}):
        "seal friction that grows with the chamber pressures is nearly constant at one supply pressure, where the "
        "chambers sit near half the supply: a constant Coulomb force fits it (at another supply it changes)",
    frozenset({"internal_leakage", "hyp_turbulent_leakage"}):
        "a leak across the piston that grows with the square root of the pressure difference and a laminar one "
        "fit alike over the one range of pressure differences of runs at one supply (at another supply they part)",
    frozenset({"internal_leakage", "hyp_valve_underlap"}):
        "a valve open at null and a leak across the piston both pass flow between the chambers near rest (the "
        "valve bench shows the lap, which a piston leak does not reach)",
    frozenset({"hyp_position_offset", "hyp_crank_offset"}):
        "a zero offset of the position sensor and a crank set off its mid-stroke both shift the logged angle "
        "against the piston; in centred runs both read as a constant shift (off centre the lever's length changes "
        "with the crank offset, not with the sensor's)",
    frozenset({"viscous_friction", "hyp_pressure_friction"}):
        "seal friction that grows with the chamber pressures grows with the load, which grows with the speed on "
        "an inertial load: a viscous force fits part of it (at another supply or disc set it does not)",
    frozenset({"viscous_friction", "hyp_quadratic_drag"}):
        "a drag growing with the square of the speed and a viscous one growing with the speed fit alike over the "
        "one range of speeds of a campaign's runs (on a run much slower or faster than those they part)",
    frozenset({"hyp_crank_unbalance", "hyp_crank_spring"}):
        "an unbalanced load's weight and a spring both pull the crank back toward a rest angle with a torque "
        "that grows with the angle; over the angles of runs centred on the stroke sin(theta) is nearly theta "
        "(off centre the weight's torque bends away from the spring's line)",
    frozenset({"stribeck_friction", "hyp_lugre_friction"}):
        "a LuGre friction's steady state is a Stribeck curve (with a viscous part: Canudas de Wit et al. 1995); in "
        "runs that keep the seal sliding they fit alike, the bristles' presliding spring shows only in the small "
        "motions about a reversal or at rest (a slow, small run)",
    frozenset({"piston_mass", "hyp_load_compliance"}):
        "a stiff spring in the load path lets the load lag the piston the loop moves: on a sine of one frequency "
        "and one disc set the force it adds is that of a heavier piston (about M^2 w^2 / k, M the load's mass "
        "at the piston); the mass it stands for grows with the frequency squared and the load's mass squared, so "
        "runs at another frequency or disc set part them",
}


def prefers(score_difference_db: float, resolvable_db: float, per_run_db: dict) -> bool:
    """Whether the data prefer an alternative to the reported explanation: it fits better by more than the logs
    resolve (at most :data:`SEPARATED_DB` asked), or by more than :data:`SEPARATED_DB` on one run, and is worse by
    more than that on none (the figures of an :class:`Alternative` or its JSON entry).

    Parameters
    ----------
    score_difference_db, resolvable_db : float
        The reported explanation's score less the alternative's, and what the logs resolve, dB.
    per_run_db : dict
        Run -> ``10 log10(J_alt / J_reported)``.

    Returns
    -------
    bool
    """
    runs = list(per_run_db.values())
    if max(runs, default=0.0) > SEPARATED_DB:
        return False
    return score_difference_db < -min(resolvable_db, SEPARATED_DB) or min(runs, default=0.0) < -SEPARATED_DB


def rivals_of(effect: str) -> list[str]:
    """The effects ``effect`` may be confused with (:data:`CONFUSABLE` and ``mistaken_for`` either way).

    Parameters
    ----------
    effect : str
        An effect of the registry.

    Returns
    -------
    list of str
        Registered effect names, sorted.
    """
    out = set()
    for pair in CONFUSABLE:
        if effect in pair:
            out |= pair - {effect}
    mine = REGISTRY.get(effect)
    out |= set(getattr(mine, "mistaken_for", ()) or ())
    out |= {n for n, c in REGISTRY.items() if effect in (getattr(c, "mistaken_for", ()) or ())}
    out.discard(effect)
    return sorted(n for n in out if n in REGISTRY)


def kinds_at_its_balances(effect: str) -> list[str]:
    """The static kinds at the balances where the structural hypothesis ``effect`` puts a term: every kind of
    :mod:`ehas_env.physics.balance_blocks` at each of those balances' places ([] for an effect that is no
    structural hypothesis, or one that is itself such a kind: the states stage compared the kinds at its place).

    A hypothesis is one law written for one place; a term of another kind at the same balance (a drag that sets in
    beyond a speed where a drag grows with the speed's square) fits the same place's residual, and which of them
    the logs prefer is theirs to say, not the list of hypotheses'.

    Parameters
    ----------
    effect : str
        An effect of the registry.

    Returns
    -------
    list of str
        Registered effect names, in :func:`~ehas_env.physics.balance_blocks.balance_blocks` order.

    Examples
    --------
    >>> kinds_at_its_balances("hyp_quadratic_drag")[:3]
    ['aug_const_crank_rate', 'aug_prop_crank_rate', 'aug_prop_crank_angle']
    >>> kinds_at_its_balances("viscous_friction"), kinds_at_its_balances("aug_beyond_crank_rate")
    ([], [])
    """
    from ehas_env.physics.balance_blocks import balance_blocks

    cls = REGISTRY.get(effect)
    if cls is None or cls.kind != "hypothesis" or getattr(cls, "balance_place", None) is not None:
        return []
    places = set(cls.terms())
    return [n for n in balance_blocks() if REGISTRY[n].balance_place.place in places]


def why_confused(a: str, b: str) -> str:
    """Why ``a`` and ``b`` can look alike (the reason of :data:`CONFUSABLE`, else the effect files' words)."""
    reason = CONFUSABLE.get(frozenset({a, b}))
    if reason:
        return reason
    kind = next((n for n in (a, b) if n in kinds_at_its_balances(b if n == a else a)), None)
    if kind is not None:  # a kind at a balance where the other, a structural hypothesis, puts its term
        place = get_effect(kind).balance_place
        return (f"{get_effect(a).title} and {get_effect(b).title} are both terms in {place.where}: over the range of "
                f"{place.words} these runs reach they may fit alike (beyond it their laws part)")
    return f"{get_effect(a).title} and {get_effect(b).title} leave the same signature in these runs"


def resolvable_db(d: np.ndarray) -> float:
    """The smallest score difference the logs resolve, dB: ``max(2 SE, MIN_SCORE)`` of the per-cluster differences.

    Parameters
    ----------
    d : ndarray
        The per-cluster score differences (dB), one per stretch of a run.

    Returns
    -------
    float
        dB.
    """
    d = np.asarray(d, dtype=float)
    if d.size < 2:
        return float("inf")
    se = float(np.std(d, ddof=1)) / math.sqrt(d.size)
    return max(2.0 * se, MIN_SCORE)


def cluster_differences(rep: Replayer, sims_reported, sims_alt, block_s: float = CI_BLOCK_S) -> np.ndarray:
    """Per cluster (a ``block_s`` stretch of one run, all its cost signals together) ``10 log10(e_alt /
    e_reported)`` of the mean squared noise-normalised residuals.

    Parameters
    ----------
    rep : Replayer
        The campaign both models were fitted on.
    sims_reported, sims_alt : list
        The two models' simulations of its runs (:meth:`Replayer.simulate`).
    block_s : float
        Cluster length, s.

    Returns
    -------
    ndarray
        One difference (dB) per cluster.
    """
    out = []
    for case, a, b in zip(rep.cases, sims_reported, sims_alt):
        if a is None or b is None:
            continue
        k0 = case.skip
        n = case.run.n - k0
        m = max(int(round(block_s / case.run.dt)), 2)
        for j in range(0, n - m // 2, m):
            ea = eb = 0.0
            for s in case.signals:
                if s not in COST_SIGNALS:
                    continue
                y = case.measured[s][k0 + j:k0 + j + m]
                ra = (y - a[s][k0 + j:k0 + j + m]) / case.noise[s]
                rb = (y - b[s][k0 + j:k0 + j + m]) / case.noise[s]
                ea += float(np.dot(ra, ra)) / ra.size
                eb += float(np.dot(rb, rb)) / rb.size
            if ea > 0.0 and eb > 0.0:
                out.append(10.0 * math.log10(eb / ea))
    return np.array(out)


@dataclass
class Alternative:
    """Another explanation of a campaign, compared with the one reported.

    Attributes
    ----------
    name : str
        The effect fitted in place of ``in_place_of``.
    in_place_of : str
        The reported effect it replaces.
    params : dict
        Its fitted values (the effect's units).
    ci95 : dict
        Parameter -> [low, high], 95 % intervals (:func:`~ehas_env.diagnosis.fitting.confidence`).
    score_difference_db : float
        The reported explanation's score less this one's, dB (> 0: the reported one fits better).
    resolvable_db : float
        The smallest difference these logs resolve (the rule of the module's docstring), dB.
    model : dict
        The whole model with it: ``effects``, ``beta``, ``K`` (a :class:`ModelSpec`'s numbers).
    reason : str
        Why the two may look alike.
    per_run_db : dict
        Run -> ``10 log10(J_alt / J_reported)`` on that run (all runs, held-out ones included; J the mean over its
        signals of the mean squared noise-normalised residual): where the logs separate them.
    """

    name: str
    in_place_of: str
    params: dict
    ci95: dict
    score_difference_db: float
    resolvable_db: float
    model: dict
    reason: str
    per_run_db: dict = field(default_factory=dict)
    fit: Fit | None = field(default=None, repr=False)

    @property
    def preferred(self) -> bool:
        """The data prefer it to the reported explanation (:func:`prefers`): a diagnosis should report it instead."""
        return prefers(self.score_difference_db, self.resolvable_db, self.per_run_db)

    @property
    def within(self) -> bool:
        """The logs cannot tell it from the reported one: the score difference within what they resolve and within
        :data:`SEPARATED_DB`, and no run where it is worse by more than :data:`SEPARATED_DB`."""
        if self.score_difference_db > min(self.resolvable_db, SEPARATED_DB):
            return False
        return max(self.per_run_db.values(), default=0.0) <= SEPARATED_DB

    def to_json(self) -> dict:
        """The diagnosis JSON's entry (docs/measurement-format.md)."""
        return {"name": self.name, "in_place_of": self.in_place_of, "title": get_effect(self.name).title,
                "words": words(self.name, self.params),
                "params": {k: _round(v) for k, v in self.params.items()},
                "units": {p.name: p.unit for p in get_effect(self.name).params},
                "ci95": {k: [_round(lo), _round(hi)] for k, (lo, hi) in self.ci95.items()},
                "score_difference_db": round(self.score_difference_db, 2),
                "resolvable_db": round(self.resolvable_db, 2), "within": self.within, "preferred": self.preferred,
                "model": self.model, "reason": self.reason,
                "per_run_db": {k: round(v, 2) for k, v in self.per_run_db.items()}}


def words(effect: str, params: dict) -> str:
    """An effect with its values in words: the hypothesis' own sentence, else its title and values with units.

    Parameters
    ----------
    effect : str
        A registered effect.
    params : dict
        Its values.

    Returns
    -------
    str
    """
    cls = get_effect(effect)
    if hasattr(cls, "in_words"):
        return cls.in_words(params)
    units = {p.name: p.unit for p in cls.params}
    return f"{cls.title}, " + ", ".join(f"{k} = {v:.4g} {units.get(k, '')}".rstrip() for k, v in params.items())


def _round(v: float) -> float:
    return float(f"{v:.4g}")


def model_json(model) -> dict:
    """A :class:`~ehas_env.measurement.replay.ModelSpec`'s numbers: ``effects``, ``beta``, ``K`` (what
    ``ehas plan-test`` replays)."""
    return {"effects": {n: {k: float(v) for k, v in p.items()} for n, p in model.effects.items()},
            "beta": float(model.beta), "K": float(model.K)}


def compare(rep: Replayer, reported: Fit, effect: str, alt: Fit, name: str, full: Replayer | None = None,
            sims_full: tuple | None = None) -> Alternative:
    """``alt`` (``name`` in place of ``effect``) against ``reported``, both fitted on ``rep``.

    The evidence is all the campaign's data when ``full`` is given (every run, whole length, held-out runs
    included: both models were fitted without them alike), else the fit data.

    Parameters
    ----------
    rep : Replayer
        The fit data.
    reported, alt : Fit
        The two fits (same runs, same base).
    effect, name : str
        The reported effect and the alternative.
    full : Replayer, optional
        Every run of the campaign.
    sims_full : tuple, optional
        (reported, alternative) simulations of ``full``'s runs (simulated here when not given).

    Returns
    -------
    Alternative
    """
    n_rep = len(own_params(effect))
    n_alt = len(own_params(name))
    if full is None:
        data, sr, sa, jr, ja = rep, reported.sims, alt.sims, reported.cost, alt.cost
    else:
        sr, sa = sims_full if sims_full is not None else (full.simulate(reported.model), full.simulate(alt.model))
        data, jr, ja = full, full.log_cost(sr), full.log_cost(sa)
    diff = 10.0 * math.log10(ja / jr) - PENALTY_PER_PARAM * (n_rep - n_alt)
    d = cluster_differences(data, sr, sa)
    ci = {n: v for (e, n), v in confidence(rep, alt).items() if e == name} if alt.free else {}
    out = Alternative(name=name, in_place_of=effect, params=dict(alt.model.effects.get(name, {})), ci95=ci,
                      score_difference_db=diff, resolvable_db=resolvable_db(d), model=model_json(alt.model),
                      reason=why_confused(effect, name), fit=alt)
    if full is not None:
        out.per_run_db = per_run_db(full, sr, sa)
    return out


#: the size a kind's linearisation is probed at, as a share of its typical size: the response of a term at its
#: typical size may be far from proportional to it (a cubic term of the crank rate on drawn case d09: 0.0001 of the
#: residual's energy at its typical size, 0.179 at a hundredth of it, where the drag kept removes 0.202 and the
#: cubic term fits within the logs' resolution of it)
PROBE_SCALE = 0.01


def find_alternatives(res, fit_null, fit_candidate, say=None, not_fitted: list | None = None) -> list[Alternative]:
    """Every explanation that may stand for an effect of ``res``'s final model, fitted and compared.

    A static kind at the balances of a structural hypothesis (:func:`kinds_at_its_balances`) is fitted only when
    its linearisation, beside a linearised refit of the rest (:func:`linearised_gains`, its size at
    :data:`PROBE_SCALE` of its typical one: one replay each and one per number of the rest), removes what the
    state stage asks of a term it screens (:func:`ehas_env.diagnosis.states.proxy_bar`), or half what the
    hypothesis' own change removes alike when that is less: one that removes nothing at any size cannot fit the
    campaign as well as the effect it would stand for (air in the oil: 32 kinds at the chambers, 1600 replays
    fitted, the best leaving a cost 42 % above its).

    Parameters
    ----------
    res : OpenDiagnosis
        A diagnosis (:func:`ehas_env.diagnosis.pipeline.diagnose_open`).
    fit_null, fit_candidate : callable
        The diagnosis' own fits (``fit_null(rep, base)``: the base recalibrated; ``fit_candidate(rep, effect,
        null, base)``: an effect on top of it), passed in so that this module does not import the diagnosis
        that calls it.
    say : callable, optional
        Called with one line of progress per alternative fitted.
    not_fitted : list, optional
        Appended with ``{"name", "in_place_of", "linear_share", "bar"}`` for each kind not fitted.

    Returns
    -------
    list of Alternative
        Within and decided ones, best (smallest score difference) first.
    """
    say = say or (lambda msg: None)
    rep = res.train
    final = res.fit_train
    effects = dict(final.model.effects)
    out: dict[tuple, Alternative] = {}
    for effect in effects:
        rest = {n: dict(p) for n, p in effects.items() if n != effect}
        rivals = [r for r in rivals_of(effect) if r not in effects]
        kinds = [r for r in kinds_at_its_balances(effect) if r not in effects and r not in rivals]
        null = fit_null(rep, rest) if rivals or kinds else None
        gains = linearised_gains(rep, null, [final.model] + [_probe(r, null.model) for r in kinds]) if kinds else [0]
        for r, share in zip(kinds, gains[1:]):
            cls = REGISTRY[r]
            bar = min(proxy_bar(cls), 0.5 * gains[0])
            if share >= bar:
                rivals.append(r)
                continue
            say(f"alternatives: {r} not fitted in place of {effect}: its linearisation removes {100 * share:.2g} % "
                f"of the residual's energy (a fit needs {100 * bar:.2g} %)")
            if not_fitted is not None:
                not_fitted.append({"name": r, "in_place_of": effect, "linear_share": round(share, 4),
                                   "bar": round(bar, 4)})
        for r in rivals:
            say(f"alternatives: {r} fitted in place of {effect}")
            alt = fit_candidate(rep, r, null, rest)
            out[(effect, r)] = compare(rep, final, effect, alt, r, res.full,
                                       (res.sims_all, res.full.simulate(alt.model)))
    # effects ranked in the round that kept an effect, on the same base: no new fit
    for d in res.rounds:
        chosen = next((e for e in d.ranking if e.effect in effects and e.fit is not None), None)
        if chosen is None:
            continue
        for e in d.ranking:
            if e is chosen or not e.beats_noise or e.fit is None or e.effect in effects:
                continue
            if (chosen.effect, e.effect) in out or _extends(e.effect, chosen.effect):
                continue
            a = compare(rep, chosen.fit, chosen.effect, e.fit, e.effect, res.full)
            a.model = model_json(_swapped(final.model, chosen.effect, e.effect, e.fit))
            out[(chosen.effect, e.effect)] = a
    return sorted(out.values(), key=lambda a: a.score_difference_db)


#: the share of a change's size that must lie off the span of the base's Jacobian for :func:`linearised_gains` to
#: count it: below it the change is one the base's numbers make, and what is left is their forward differences'
#: curvature (the bulk modulus moved 0.2 % on a Coulomb campaign: 0.0015 of it off the span, where it would have
#: counted 5.5 % of the residual's energy; the friction's change 0.58, a constant crank torque's 0.998)
OFF_SPAN = 0.02


def _probe(name: str, base):
    """``base`` with the kind ``name`` added, its main parameter at :data:`PROBE_SCALE` of its typical size and its
    others at their starts."""
    main = next(fp for fp in own_params(name) if fp.name == REGISTRY[name].main_param)
    return term_at(name, base, {main.name: PROBE_SCALE * start_value(main)})


def linearised_gains(rep: Replayer, base: Fit, models: list) -> list[float]:
    """The share of ``base``'s residual energy each of ``models`` would remove beyond a refit of ``base``'s own
    numbers, to first order: the residual (each run and signal's block weighted by 1 / its RMS, as the fit weighs
    it) projected off the span of ``base``'s Jacobian (one replay per fitted number), then its squared correlation
    with the model's change of the residual projected alike (one replay per model).  A change that the base's
    numbers can make too (a term at the crank rate beside a viscous term kept) counts only for what they cannot,
    and not at all when less than :data:`OFF_SPAN` of it is left.

    Parameters
    ----------
    rep : Replayer
        The fit data.
    base : Fit
        The model the others would be fitted on (their rest, recalibrated).
    models : list of ModelSpec
        Each ``base.model`` with something added.

    Returns
    -------
    list of float
        In [0, 1], one per model.
    """
    obj = Objective(rep, base.free, base.model)
    u = np.array([fp.u(_value_of(base.model, fp)) for fp in base.free])
    w = obj.weights(u)
    r = obj.weighted(u, w)
    q = np.linalg.qr(obj.jacobian(u, w))[0] if base.free else np.zeros((r.size, 0))

    def off(v):  # v without its part in the span of the base's numbers
        return v - q @ (q.T @ v)

    r_off, rr = off(r), float(r @ r)
    out = []
    for sims in rep.simulate_many(models):
        d_all = np.concatenate([wi * x for wi, x in zip(w, rep.cost_blocks(sims))]) - r
        d = off(d_all)
        dd = float(d @ d)
        if dd <= (OFF_SPAN * OFF_SPAN) * float(d_all @ d_all) or rr <= 0.0:
            out.append(0.0)  # a change the base's numbers make (what is left is their Jacobian's curvature)
        else:
            out.append(min(float(r_off @ d) ** 2 / (dd * rr), 1.0))
    return out


def per_run_db(rep: Replayer, sims_reported, sims_alt) -> dict:
    """Run -> ``10 log10(J_alt / J_reported)``, J the mean over the run's cost signals of the mean squared
    noise-normalised residual (the measure ``ehas plan-test`` predicts a run's separation in).

    Parameters
    ----------
    rep : Replayer
        All runs.
    sims_reported, sims_alt : list
        The two models' simulations.

    Returns
    -------
    dict
    """
    out = {}
    for case, a, b in zip(rep.cases, sims_reported, sims_alt):
        if a is None or b is None:
            continue
        k = case.skip
        ja, jb = [], []
        for s in case.signals:
            if s in COST_SIGNALS:
                ja.append(float(np.mean(((case.measured[s][k:] - a[s][k:]) / case.noise[s]) ** 2)))
                jb.append(float(np.mean(((case.measured[s][k:] - b[s][k:]) / case.noise[s]) ** 2)))
        if ja and np.mean(ja) > 0.0:
            out[case.run.name] = 10.0 * math.log10(float(np.mean(jb)) / float(np.mean(ja)))
    return out


def _extends(a: str, b: str) -> bool:
    """Whether one effect extends the other's law (its parameters include all of the other's, as Stribeck friction's
    Fc, Fs, vs hold Coulomb friction's Fc): the same explanation with more freedom, not another one."""
    pa, pb = {p.name for p in get_effect(a).params}, {p.name for p in get_effect(b).params}
    return pa >= pb or pb >= pa


def _swapped(model, effect: str, name: str, f: Fit):
    """``model`` with ``effect`` replaced by ``name`` at its values in ``f`` (beta, K from ``f``)."""
    from ehas_env.measurement.replay import ModelSpec

    eff = {n: dict(p) for n, p in model.effects.items() if n != effect}
    eff[name] = dict(f.model.effects[name])
    return ModelSpec(effects=eff, beta=f.model.beta, K=f.model.K)


def alternatives_text(alts: list[Alternative], reported: dict) -> str:
    """The verdict's words about the alternatives: which these logs cannot tell apart, which they rule out by how
    much.

    Parameters
    ----------
    alts : list of Alternative
        From :func:`find_alternatives`.
    reported : dict
        The final model's effects {name: {param: value}}.

    Returns
    -------
    str
        Empty when there is nothing to compare.
    """
    lines = []
    for a in alts:
        rep_words = words(a.in_place_of, reported.get(a.in_place_of, {}))
        alt_words = words(a.name, a.params)
        if a.preferred:
            run = min(a.per_run_db, key=a.per_run_db.get, default=None)
            on_run = (f"; on {run} {-a.per_run_db[run]:.1f} dB better" if run is not None
                      and a.per_run_db[run] < -SEPARATED_DB else "")
            lines.append(f"these logs prefer {a.name} ({alt_words}) to {a.in_place_of} ({rep_words}): "
                         f"{-a.score_difference_db:.2f} dB better over the campaign (they resolve "
                         f"{a.resolvable_db:.2f} dB){on_run}; {a.name} is the likelier explanation")
        elif a.within:
            lines.append(f"these logs cannot tell apart {a.in_place_of} ({rep_words}) and {a.name} ({alt_words}): "
                         f"score difference {a.score_difference_db:+.2f} dB, within the {a.resolvable_db:.2f} dB "
                         f"they resolve; {a.reason}. `ehas plan-test` designs the runs that decide.")
        else:
            run = max(a.per_run_db, key=a.per_run_db.get, default=None)
            by_run = (f"; on {run} {a.per_run_db[run]:.1f} dB worse" if run is not None
                      and a.per_run_db[run] > SEPARATED_DB else "")
            lines.append(f"{a.name} ({alt_words}) in place of {a.in_place_of}: ruled out by these logs, "
                         f"{a.score_difference_db:.2f} dB worse (they resolve {a.resolvable_db:.2f} dB){by_run}")
    return "\n".join(lines)
