"""Naming a flexible term: the few physical forms (laws with units) that keep most of what it explains.

:func:`ehas_env.diagnosis.proposal.propose` finds *where* the model lacks a term (the place of its best
sparse terms).  There, every coefficient of that place's term class
(:mod:`ehas_env.measurement.proposal_terms`) is fitted together inside the full model: the **flexible term**,
a function of the place's local quantities (position, velocity, pressures, flows, current, their signs and
products).  This module then **names** it: among the physical forms of :data:`FORMS` (one table: each form's
place, kind, law, words and the coefficients it sets), it selects the sparse set of one or two forms that keeps
most of the flexible term's gain, by the evidence score the proposal uses (10 log10 of the residual ratio less
:data:`PENALTY_PER_TERM_DB` per coefficient; a second form must add :data:`ADD_TERM_DB`: the rules
by which :mod:`ehas_env.diagnosis.proposal` keeps its sparse terms, held here).  Candidates are ranked on the flexible fit's linearisation
(:func:`linear_predictor`: one Jacobian, no further replays), and the chosen forms are refitted inside the model.

``keeps_share`` is a share of the excess over noise: (R_base - R_named) / (R_base - R_flexible), with R the
residual x noise (the fit cost, 1 = noise, as the proposal's ``residual_x_noise_before`` reports it), the measure
of honesty rule 1
(:func:`ehas_env.diagnosis.honesty.term_refused`), which no named form may fail: a form whose refit removes less
than 10 % of the residual's excess over noise is not named, and when none passes ``named`` is empty and the text
says where the residual is, what it follows and that no term was found.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ehas_env.diagnosis.honesty import TERM_SHARE, share_removed, term_refused
from ehas_env.physics.land_terms import LAND_FORMS
from ehas_env.physics.term_grammar import TERM_PLACES, NamedForm, named_forms

#: what a named form is
KINDS = ("friction", "leakage/flow", "compliance", "geometry/area", "valve", "sensor", "command path", "load",
         "fluid property", "supply/return")
#: where a named form acts (the model's places, the lands' supply and return boundaries apart)
PLACES = ("valve_current", "coil_current", "chamber_flows", "piston_force", "crank_torque", "supply", "return",
          "position_reading")
#: the evidence score's penalty per fitted coefficient, dB (the proposal's sparse terms and the named forms)
PENALTY_PER_TERM_DB = 0.2
#: a further form (or sparse term) must lower the residual by at least this much, dB
ADD_TERM_DB = 1.0
MAX_NAMED = 2  # forms per named set
FLEX_NFEV = 8  # least-squares steps of the flexible fit
NAMED_NFEV = 8  # ... of a named set's refit


#: one physical form: a law with units that sets some coefficients of a term class (its ``key`` written to the
#: JSON's ``named[].form``, its ``place`` one of :data:`PLACES`, its ``kind`` one of :data:`KINDS`)
Form = NamedForm


_PF, _CT = "proposal_piston_force", "proposal_crank_torque"
#: the two places of one mechanical load (the piston's force, the crank's torque through the lever r cos theta):
#: the naming fits the flexible term at both when the proposal's terms sit at one (:func:`name_terms`)
MECHANICAL_TWIN = {_PF: _CT, _CT: _PF}


#: every named form: its place, kind, law, words and coefficients -- the grammar's (its places' descriptions), then
#: the lands' (:data:`ehas_env.physics.land_terms.LAND_FORMS`: the orifice law's gain by direction, port and load,
#: its metering law, the lines', the supply's and the return's pressures)
FORMS = tuple(f for place in TERM_PLACES.values() for f in named_forms(place)) + LAND_FORMS
assert all(f.kind in KINDS and f.place in PLACES for f in FORMS)
#: the parameters whose sign a form's words state -- a dry friction, a damping, a leak, a resistance, a friction that
#: *rises*, a spring that *hardens*, a path that *saturates* are positive: fitted negative, the words would say the
#: opposite of what the data show, and the form is not named (:func:`wrong_sign`)
POSITIVE = {f.key: f.positive for f in FORMS if f.positive}
assert all(any(f.key == k and set(v) <= {p for p, _, _ in f.params} for f in FORMS) for k, v in POSITIVE.items())


def wrong_sign(combo, terms: dict) -> list:
    """The forms of ``combo`` whose fitted parameters contradict their words' sign (:data:`POSITIVE`).

    Parameters
    ----------
    combo : sequence of Form
    terms : dict
        The fitted coefficients {coefficient: SI value}.

    Returns
    -------
    list of Form

    Examples
    --------
    >>> f = next(f for f in FORMS if f.key == "piston_force.friction_load")
    >>> [g.key for g in wrong_sign([f], {"proposal_piston_force.c_plsv": 2.6e-5})]   # a < 0: falls with P_L
    ['piston_force.friction_load']
    >>> wrong_sign([f], {"proposal_piston_force.c_plsv": -2.6e-5})
    []
    """
    out = []
    for f in combo:
        pos = POSITIVE.get(f.key, ())
        if any(sign * terms.get(coef, 0.0) < 0.0 for name, coef, sign in f.params if name in pos):
            out.append(f)
    return out


def class_of(coef: str) -> str:
    """The term class of a coefficient key.

    Parameters
    ----------
    coef : str
        ``proposal_<class>.<coef>``.

    Returns
    -------
    str
        ``proposal_<class>``.
    """
    return coef.split(".", 1)[0]


def forms_of(cls: str, forms=FORMS) -> list:
    """The forms whose coefficients all belong to one term class.

    Parameters
    ----------
    cls : str
        The term class (``proposal_piston_force`` ...).
    forms : sequence of Form
        The table searched (default :data:`FORMS`).

    Returns
    -------
    list of Form
    """
    return [f for f in forms if all(class_of(c) == cls for c in f.coefs)]


def candidates(forms, max_named: int = MAX_NAMED) -> list:
    """Every set of one to ``max_named`` forms in which no two set the same coefficient.

    Parameters
    ----------
    forms : sequence of Form
        The forms of a place.
    max_named : int
        The most forms in a set.

    Returns
    -------
    list of tuple of Form
    """
    out = [(f,) for f in forms]
    for n in range(2, max_named + 1):
        for combo in itertools.combinations(forms, n):
            cs = [c for f in combo for c in f.coefs]
            if len(cs) == len(set(cs)):
                out.append(combo)
    return out


def coefs_of(combo) -> list:
    """The distinct coefficients a set of forms sets, in order.

    Parameters
    ----------
    combo : sequence of Form

    Returns
    -------
    list of str
    """
    out = []
    for f in combo:
        for c in f.coefs:
            if c not in out:
                out.append(c)
    return out


def score(base_cost: float, cost: float, n_coefs: int) -> float:
    """The evidence score of a set: the cost it removes, dB, less the proposal's penalty per coefficient.

    Parameters
    ----------
    base_cost, cost : float
        Fit costs without the set and with it.
    n_coefs : int
        The coefficients the set fits.

    Returns
    -------
    float
        dB.
    """
    return 10.0 * math.log10(base_cost / max(cost, 1e-300)) - PENALTY_PER_TERM_DB * n_coefs


def select(combos, predict, base_cost: float) -> tuple:
    """The sparse set of forms by the evidence score: the best single form, or the best pair when it adds at
    least :data:`ADD_TERM_DB`.

    Parameters
    ----------
    combos : list of tuple of Form
        The candidate sets (:func:`candidates`).
    predict : callable
        predict(list of coefficient keys) -> the cost of the model with those coefficients alone fitted.
    base_cost : float
        The cost without any term at this place.

    Returns
    -------
    (tuple of Form, float)
        The set chosen and its predicted cost; ((), base_cost) when no set beats the noise
        (:func:`ehas_env.diagnosis.fitting.beats_noise`).
    """
    from ehas_env.diagnosis.fitting import beats_noise

    best: dict[int, tuple] = {}
    for combo in combos:
        c = predict(coefs_of(combo))
        if not beats_noise(base_cost, c, len(coefs_of(combo))):  # the fit's own gate: nothing named for noise
            continue
        s = score(base_cost, c, len(coefs_of(combo)))
        n = len(combo)
        if n not in best or s > best[n][0]:
            best[n] = (s, combo, c)
    if 1 not in best or best[1][2] >= base_cost:
        return (), base_cost
    chosen = best[1]
    for n in sorted(k for k in best if k > 1):
        if 10.0 * math.log10(chosen[2] / max(best[n][2], 1e-300)) >= ADD_TERM_DB and best[n][0] > chosen[0]:
            chosen = best[n]
    return chosen[1], chosen[2]


def linear_predictor(J: np.ndarray, r0: np.ndarray, u_flex: np.ndarray, u_zero: np.ndarray, keys: list,
                     sizes: list, weights: list):
    """The cost of any subset of the flexible term's coefficients, fitted alone, on the flexible fit's
    linearisation (the others at zero).

    Parameters
    ----------
    J : ndarray (n, m)
        Jacobian of the weighted residual with respect to the m coefficients (in the fit's u).
    r0 : ndarray (n,)
        The weighted residual at the flexible fit ``u_flex``.
    u_flex, u_zero : ndarray (m,)
        The flexible fit and the coefficients' zero, in u.
    keys : list of str
        The coefficients, in the columns' order.
    sizes, weights : list
        Sizes and weights of the residual's blocks (the cost is the geometric mean of their mean squares).

    Returns
    -------
    callable
        predict(list of keys) -> (cost, u of the subset's least-squares fit).
    """
    idx = {k: i for i, k in enumerate(keys)}
    bounds = np.cumsum([0] + list(sizes))

    def cost_of(r):
        n = bounds[-1]
        tot = 0.0
        for b, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
            seg = r[lo:hi] / weights[b]
            tot += (hi - lo) * math.log(max(float(np.dot(seg, seg)) / max(hi - lo, 1), 1e-300))
        return math.exp(tot / n)

    def predict(subset):
        S = [idx[k] for k in subset]
        du = u_zero - u_flex
        mask = np.ones(len(keys), bool)
        mask[S] = False
        r = r0 + J[:, mask] @ du[mask]
        u = u_zero.copy()
        if S:
            d, *_ = np.linalg.lstsq(J[:, S], -r, rcond=None)
            r = r + J[:, S] @ d
            u[S] = u_flex[S] + d
        return cost_of(r), u

    return predict


def x_noise(cost: float) -> float:
    """The residual "x noise" of a fit cost, as the proposal and the verdict report it (1 = noise).

    Parameters
    ----------
    cost : float
        A fit cost (:meth:`ehas_env.measurement.replay.Replayer.log_cost`: the geometric mean over runs and
        signals of the mean square residual over the noise's).

    Returns
    -------
    float
        The cost itself (the proposal's ``residual_x_noise_before`` / ``_after`` are its costs).
    """
    return max(float(cost), 0.0)


def keeps_share(base_cost: float, flex_cost: float, named_cost: float) -> float:
    """The share of the flexible term's removal of the residual's excess over noise that the named forms keep.

    Parameters
    ----------
    base_cost, flex_cost, named_cost : float
        Fit costs without a term, with the flexible term and with the named forms.

    Returns
    -------
    float
        (R_base - R_named) / (R_base - R_flexible), R x noise (:func:`x_noise`); 0 when the flexible
        term removes nothing.
    """
    b, f, n = x_noise(base_cost), x_noise(flex_cost), x_noise(named_cost)
    if b - f <= 0.0:
        return 0.0
    return (b - n) / (b - f)


def named_entry(combo, values: dict, ci: dict, share: float, removed: float) -> list:
    """The JSON entries (one per form) of a named set.

    Parameters
    ----------
    combo : sequence of Form
        The named forms.
    values : dict
        Their fitted coefficients {coefficient: SI value}.
    ci : dict
        95 % intervals {coefficient: (low, high)} (may be empty: ``low`` and ``high`` are then None).
    share : float
        :func:`keeps_share` of the set.
    removed : float
        The share of the residual's excess over noise the set's refit removes.

    Returns
    -------
    list of dict
        ``{place, kind, form, law, words, params: {name: {value, low, high, unit}}, keeps_share,
        removes_share_of_excess}``.
    """
    from ehas_env.measurement.proposal_terms import term_param

    out = []
    for f in combo:
        params = {}
        for name, coef, sign in f.params:
            v = sign * values.get(coef, 0.0)
            lo_hi = ci.get(coef)
            lo = hi = None
            if lo_hi is not None:
                a, b = sign * lo_hi[0], sign * lo_hi[1]
                lo, hi = float(f"{min(a, b):.4g}"), float(f"{max(a, b):.4g}")
            params[name] = {"value": float(f"{v:.4g}"), "low": lo, "high": hi, "unit": term_param(coef).unit}
        out.append({"place": f.place, "kind": f.kind, "form": f.key, "law": f.law, "words": f.words, "params": params,
                    "keeps_share": round(share, 3), "removes_share_of_excess": round(removed, 3)})
    return out


@dataclass
class Naming:
    """What the naming found: the named forms (JSON entries), the flexible term's fit and the text."""

    named: list
    flexible: list  # [{"class", "coefficients", "residual_x_noise_before", "..._after"}]
    text: str
    model_terms: dict  # the named forms' coefficients (SI), {} when none is named
    cost: float | None = None  # the fit cost of the named model (None: none named)
    fit: object = None  # its Fit

    def to_json(self) -> dict:
        return {"flexible": self.flexible, "text": self.text,
                "keeps_share_is": "share of the excess over noise (residual x noise, the fit cost) that the flexible "
                                  "term removes which the named forms keep"}


def name_terms(rep, base, terms: dict, ranges: dict, *, fixed_model=None, confidence=None, say=None) -> Naming:
    """Fit the flexible term at each place of ``terms`` inside the model, then name it.

    Parameters
    ----------
    rep : Replayer
        The fit data.
    base : Fit
        The model without any proposed term (the diagnosis' final model).
    terms : dict
        The proposal's sparse terms {coefficient: SI value}: where the flexible term is fitted (their classes, at
        most two, and the other place of a mechanical load, :data:`MECHANICAL_TWIN`) and its start.
    ranges : dict
        The largest coefficient magnitude of each coefficient (:func:`ehas_env.diagnosis.proposal.coefficient_range`).
    fixed_model : ModelSpec, optional
        The effects, beta and K held while the flexible term and the named forms are fitted: the proposal's fit
        (fitted with its terms); default ``base``'s.
    confidence : callable, optional
        confidence(rep, fit) -> {(effect, name): (low, high)} for the named forms' intervals.
    say : callable, optional
        Progress text.

    Returns
    -------
    Naming
    """
    from ehas_env.diagnosis import fitting as D
    from ehas_env.measurement.proposal_terms import TERM_CLASSES
    from ehas_env.measurement.replay import ModelSpec

    say = say or (lambda _msg: None)
    held = fixed_model if fixed_model is not None else base.model
    fixed = ModelSpec(effects=held.effects, beta=held.beta, K=held.K)
    by_name = {c.name: c for c in TERM_CLASSES.values()}
    flexible, best = [], None
    for cls in _places(terms, ranges):
        keys = [f"{cls}.{p.name}" for p in by_name[cls].params if ranges.get(f"{cls}.{p.name}", 0.0) > 0]
        if not keys:
            continue
        say(f"  flexible term at {cls.replace('proposal_', '')}: {len(keys)} coefficients fitted together")
        free = [D.FreeParam(D.TERM, k, -ranges[k], ranges[k], False) for k in keys]
        flex, predict = _flexible_fit(rep, base, free, terms, fixed)
        flex_cost = flex.cost
        # what the flexible term follows: the coefficient whose removal costs most
        follows = max(keys, key=lambda k: predict([c for c in keys if c != k])[0])
        flexible.append({"class": cls, "coefficients": {k: float(f"{flex.model.terms[k]:.4g}") for k in keys},
                         "residual_x_noise_before": round(x_noise(base.cost), 3),
                         "residual_x_noise_after": round(x_noise(flex_cost), 3), "follows": follows})
        forms = forms_of(cls)
        combo, _ = select(candidates(forms), lambda ks: predict(ks)[0], base.cost)
        if not combo:
            continue
        ks = coefs_of(combo)
        _, u_sub = predict(ks)
        nfree = [fp for fp in free if fp.name in ks]
        nstart = {(D.TERM, fp.name): fp.value(u_sub[keys.index(fp.name)]) for fp in nfree}
        say(f"  naming it: {', '.join(f.key for f in combo)} refitted in the model")
        named = D.fit(rep, nfree, nstart, fixed, max_nfev=NAMED_NFEV)
        if best is None or named.cost < best[2].cost:
            best = (cls, combo, named, flex_cost, predict)
    if best is None:
        return Naming([], flexible, _none_text(flexible), {})
    cls, combo, named, flex_cost, predict = best
    before, after = x_noise(base.cost), x_noise(named.cost)
    kept = honest_forms(combo, base.cost, named.cost, lambda ks: predict(ks)[0])
    bad = wrong_sign(kept, named.model.terms)
    kept = [f for f in kept if f not in bad]
    if not kept:
        return Naming([], flexible, _none_text(flexible, after=after, wrong=bad), {})
    if len(kept) < len(combo):  # refit what is left
        ks = coefs_of(kept)
        nfree = [D.FreeParam(D.TERM, k, -ranges[k], ranges[k], False) for k in ks]
        named = D.fit(rep, nfree, {(D.TERM, k): named.model.terms.get(k, 0.0) for k in ks}, fixed,
                      max_nfev=NAMED_NFEV)
        after = x_noise(named.cost)
        bad = wrong_sign(kept, named.model.terms)
        if term_refused(before, after) is not None or bad:
            return Naming([], flexible, _none_text(flexible, after=after, wrong=bad), {})
    share = keeps_share(base.cost, flex_cost, named.cost)
    removed = share_removed(before, after)
    words = "; ".join(f"{f.words} ({f.law}, {f.kind}, at {f.place.replace('_', ' ')})" for f in kept)
    text = (f"named: {words}; it keeps {100 * share:.0f} % of what the flexible term at "
            f"{cls.replace('proposal_', '').replace('_', ' ')} removes (residual {before:.3g}x -> "
            f"{x_noise(flex_cost):.3g}x noise flexible, {after:.3g}x named)")
    ci = {}
    if confidence is not None:
        ci = {name: lohi for (eff, name), lohi in confidence(rep, named).items() if eff == D.TERM}
    entries = named_entry(kept, named.model.terms, ci, share, removed)
    return Naming(entries, flexible, text, dict(named.model.terms), named.cost, named)


def _places(terms: dict, ranges: dict) -> list:
    """The term classes where the flexible term is fitted: those of the two largest sparse terms (relative to
    their ranges), and the other place of a mechanical load (:data:`MECHANICAL_TWIN`) -- the piston's force and the
    crank's torque are one load seen through the lever r cos theta: where the terms sit at one, the data choose."""
    classes = []
    for k in sorted(terms, key=lambda k: -abs(terms[k]) / max(ranges.get(k, 1.0), 1e-300)):
        if class_of(k) not in classes:
            classes.append(class_of(k))
    classes = classes[:2]
    for cls in list(classes):
        twin = MECHANICAL_TWIN.get(cls)
        if twin is not None and twin not in classes:
            classes.append(twin)
    return classes


def _flexible_fit(rep, base, free: list, terms: dict, fixed) -> tuple:
    """Every coefficient of one place fitted together inside the model (the flexible term), from the sparse terms;
    returns (its Fit, the linear predictor of any subset's cost around it, :func:`linear_predictor`)."""
    from ehas_env.diagnosis import fitting as D

    keys = [fp.name for fp in free]
    start = {(D.TERM, fp.name): float(np.clip(terms.get(fp.name, 0.0), fp.lo, fp.hi)) for fp in free}
    flex = D.fit(rep, free, start, fixed, max_nfev=FLEX_NFEV)
    if flex.cost >= base.cost and any(start.values()):
        # the sparse terms of this class alone can be a poor start: the proposal may have found them together
        # with another place's (a damping at the piston and its opposite at the crank that together make
        # one rising toward the stroke's ends); then start where the term is zero, the model as it stands
        zero = D.fit(rep, free, {key: 0.0 for key in start}, fixed, max_nfev=FLEX_NFEV)
        flex = zero if zero.cost < flex.cost else flex
    u_flex = np.array([fp.u(flex.model.terms[fp.name]) for fp in free])
    u_zero = np.array([fp.u(0.0) for fp in free])
    return flex, linearised(rep, free, fixed, u_flex, u_zero, keys)


def linearised(rep, free: list, fixed, u: np.ndarray, u_zero: np.ndarray, keys: list):
    """:func:`linear_predictor` of the fit of ``free`` (``fixed`` the rest of the model) linearised at ``u``: one
    forward-difference Jacobian of its weighted residual, weighted as the log cost's gradient there.

    Parameters
    ----------
    rep : Replayer
        The fit data.
    free : list of FreeParam
        The fitted numbers, in the order of ``u``, ``u_zero`` and ``keys``.
    fixed : ModelSpec
        Everything else of the model.
    u, u_zero : ndarray
        The point linearised at, and each number's "left out" value (in the fit's u).
    keys : list of str
        A name per number (what the predictor's subsets list).

    Returns
    -------
    callable
        predict(list of keys) -> (cost, u), as :func:`linear_predictor`'s.
    """
    from ehas_env.diagnosis import fitting as D

    obj = D.Objective(rep, free, fixed)
    w = obj.weights(u)
    sizes = [b.size for b in obj.blocks([u])[0]]
    return linear_predictor(obj.jacobian(u, w), obj.weighted(u, w), u, u_zero, keys, sizes, w)


def honest_forms(combo, base_cost: float, named_cost: float, predict) -> list:
    """Honesty rule 1 (:func:`ehas_env.diagnosis.honesty.term_refused`) for every form of a named set.

    The set's refit must remove :data:`ehas_env.diagnosis.honesty.TERM_SHARE` of the residual's excess over
    noise; of two forms, each must also remove that share of what the other alone leaves.

    Parameters
    ----------
    combo : tuple of Form
        The named set.
    base_cost, named_cost : float
        Fit costs (mean squares over noise's) without any term and with the set refitted.
    predict : callable
        predict(list of coefficient keys) -> cost of those coefficients alone fitted.

    Returns
    -------
    list of Form
        The forms that may be named (empty when none may).
    """
    after = x_noise(named_cost)
    if term_refused(x_noise(base_cost), after) is not None:
        return []
    kept = []
    for f in combo:
        others = coefs_of([g for g in combo if g is not f])
        if not others or term_refused(x_noise(predict(others)), after) is None:
            kept.append(f)
    return kept


def judge_on_all_data(prop, residual_all, before: float) -> str | None:
    """Honesty rule 1 for the named forms on all data: ``prop.named`` is emptied (and ``prop.naming["text"]``
    says why) when the named forms' refit removes less than the share a term must of the residual's excess over
    noise on every run.

    Parameters
    ----------
    prop : Proposal
        A proposal with ``named`` and ``named_model`` (:func:`ehas_env.diagnosis.proposal.propose`).
    residual_all : callable
        residual_all(model) -> the all-data residual (x what does not repeat) of ``model`` (a ModelSpec).
    before : float
        The final model's all-data residual without a term.

    Returns
    -------
    str or None
        Why the named forms were refused (None when they stand or none was named).
    """
    if not prop.named or prop.named_model is None:
        return None
    after = residual_all(prop.named_model)
    refused = term_refused(before, after)
    for e in prop.named:
        e["residual_x_noise_all_after"] = round(float(after), 3)
    if refused is None:
        return None
    prop.named = []
    prop.naming["text"] = "no form named on all data: " + refused
    return refused


def _none_text(flexible: list, after: float | None = None, wrong=()) -> str:
    """Honesty rule 1 in words when no form is named: where the residual is, what it follows, no term found (and
    the forms whose fitted sign belied their words, ``wrong``)."""
    from ehas_env.measurement.proposal_terms import term_param

    if not flexible:
        return "no flexible term could be fitted at any place: no term was found"
    fl = min(flexible, key=lambda f: f["residual_x_noise_after"])
    where = fl["class"].replace("proposal_", "").replace("_", " ")
    follows = f"{fl['follows'].split('.', 1)[1]} ({term_param(fl['follows']).doc})"
    return (f"the residual is at the {where} (a flexible term there takes it from {fl['residual_x_noise_before']:.3g}x "
            f"to {fl['residual_x_noise_after']:.3g}x noise) and follows {follows}; no physical form of that place "
            f"removes {100 * TERM_SHARE:.0f} % of the residual's excess over noise"
            + (f" (the best named leaves {after:.3g}x)" if after is not None else "")
            + (f"; {', '.join(f.key for f in wrong)} fitted with the sign opposite to its words" if wrong else "")
            + ": no term was found")
