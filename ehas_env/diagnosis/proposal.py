"""The missing term, proposed: sparse terms at the model's places, fitted inside the full model.

When the best model of the library leaves residuals above noise, this module
looks for the term the model lacks among the forms of
:mod:`ehas_env.measurement.proposal_terms` (forces on the piston, torques on the
crank, flows into the chambers and at the valve's lands, supply and return, the
valve current, the position reading), in four steps:

1. **sparse regression on the residual force** (campaigns with chamber pressures):
   the force the model misses at the piston, F = -A (P_L,measured - P_L,model),
   is regressed on the force and torque forms evaluated on the model's states by
   pysindy's sequentially thresholded least squares (``pysindy.STLSQ``), which
   keeps the few forms that carry it;
2. **screening inside the model**: every form of every place is added alone to
   the full model (the library effects found, beta and K as fitted), replayed
   once at a small coefficient, and its coefficient scanned over both signs and
   four decades on that linearisation; the forms it ranks best are confirmed by
   replays over three decades of the sign it predicts (:func:`_screen`);
3. **fitting inside the model**: the best screened forms and the sparse set of
   step 1 are fitted with bounded least squares together with beta, K and the
   library effects' parameters, on the noise-weighted residuals of every signal
   (as the diagnosis fits effects); a second and third form are added while
   each lowers the residual by at least :data:`ADD_TERM_DB`.

4. **naming** (:func:`ehas_env.diagnosis.naming.name_terms`): at the places of
   the sparse terms, every coefficient of the place fitted together (the flexible
   term), then the sparse set of physical forms (laws with units, of a kind) that
   keeps most of its gain: ``Proposal.named``.

The result is an equation with units and fitted coefficients (with confidence
intervals), the fit before and after, and :func:`effect_source`, the text of a
user effect file (``--write-effect DIR/NAME.py``) that ``ehas compare CAMPAIGN
--effects-path DIR --effects NAME --fit`` loads.
"""
from __future__ import annotations

import math
import textwrap
import warnings
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from ehas_env.diagnosis import fitting as D
from ehas_env.diagnosis.naming import ADD_TERM_DB, PENALTY_PER_TERM_DB, name_terms
from ehas_env.measurement.proposal_terms import TERM_CLASSES, term_param
from ehas_env.measurement.replay import ModelSpec, Replayer
from ehas_env.physics.land_terms import LAND_ARGS, LAND_TERMS, flow_body
from ehas_env.physics.rig import BAR, LPM, RigParams
from ehas_env.physics.term_grammar import TERM_PLACES, place_atoms, term_class

FIT_TOP = 3  # screened forms fitted fully
MAX_TERMS = 3
SCREEN_MAGS = 4  # magnitudes per sign scanned per form (the confirming replays, :func:`_screen`)
SCREEN_BATCH = 40  # models replayed per batch while screening
#: the finite-difference step of the linearised screen, a share of each form's coefficient range: the smallest
#: magnitude the replayed scan tried (its response is then the tangent's, within the integrator's rounding)
SCREEN_STEP = 1.0e-3
#: forms whose linearised best is confirmed by replays over SCREEN_MAGS magnitudes of the predicted sign: those
#: fitted (FIT_TOP) and those the fit may add (2 per added form, MAX_TERMS - 1 times), and as many again
SCREEN_CONFIRM = 2 * (FIT_TOP + 2 * (MAX_TERMS - 1))
#: coefficients of the linearised cost's scan: this many magnitudes per sign over the range's four decades
SCREEN_GRID = 160

def _grammar_forms() -> dict:
    """{coefficient key: (place, the form in words, the effect file's expression, its arguments)} of the grammar's
    atoms (:mod:`ehas_env.physics.term_grammar`), the lands' family after them."""
    out = {}
    for place in TERM_PLACES.values():
        for a in place_atoms(place):
            expr = None if place.form == "flow_pair" else ("{c}" if a.code == "1.0" else "{c} * " + a.code)
            args = () if place.form == "signal" else a.args
            out[f"{term_class(place.name)}.{a.coef}"] = (place.name, a.text, expr, args)
    for t in LAND_TERMS:
        out[f"{term_class('land_flows')}.{t.coef}"] = ("chamber_flows", t.form, None, LAND_ARGS)
    return out


#: place, the form in words (the coefficient multiplies it), the expression of the effect file, its arguments
FORMS = _grammar_forms()
#: flow forms as code of the effect file (:func:`ehas_env.physics.land_terms.flow_body`): the chambers' leaks from the
#: grammar (whatever the spool's direction), the lands' family by direction where it depends on it
FLOW_CODE = {a.coef: SimpleNamespace(always=tuple(a.flow), pos=(), neg=())
             for a in place_atoms(TERM_PLACES["chamber_flows"])}
FLOW_CODE.update({t.coef: t for t in LAND_TERMS})
#: what the model's right-hand side returns at each place (for the equation)
PLACE_SYMBOL = {"piston_force": "F_piston [N] +=", "crank_torque": "T_crank [N m] +=",
                "chamber_flows": "(Q_A, Q_B) [m^3/s] +=", "valve_current": "i_valve [mA] +=",
                "position_reading": "x_read [m] +="}
SHORT = {"piston_force": "f", "crank_torque": "t", "chamber_flows": "q", "valve_current": "i", "position_reading": "r"}
#: the largest coefficient tried: the form's typical size on this rig times this scale
FORCE_SCALE = 4000.0  # N on the piston (a third of the stall force)
#: the largest coefficient tried at the signal and flow places: the place's scale over the form at the quantities'
#: spans (term_grammar.TermPlace.scale); the lands' family its own (land_terms.LandTerm.span)
FIXED_RANGE = {f"{term_class(p.name)}.{a.coef}": p.scale / a.span_value
               for p in TERM_PLACES.values() if p.scale for a in place_atoms(p)}
FIXED_RANGE.update({f"{term_class('land_flows')}.{t.coef}": t.span for t in LAND_TERMS})


#: a set of forms whose summed response is less than this share of the sum of their responses' sizes cancels
#: (:func:`net_share`): their coefficients mostly undo one another, the data determine only a combination of them,
#: not each, and a set of them is refused.  Measured on the screen's tangents at the model the term is added to, in
#: the start-conditions campaigns of a crank bearing's friction and an end cushion from rest (results at 1226881):
#: the piston's and the crank's load-proportional friction fitted as -0.00348 and +0.00340 m^2, 0.049 (their net,
#: 8e-5 m^2, is what the faded-in campaign's proposal fitted with the piston's form alone); four damping forms at the
#: piston and the crank, each about 1700 times their net, 0.0003; a pair at the two places 0.086.  Two forms of equal
#: size whose responses are at right angles give 0.71, three 0.58
CANCEL_SHARE = 0.25
#: forms whose features (the piston-equivalent force per unit coefficient over the campaign's closed-loop runs)
#: correlate this closely (uncentred) are one column to the sparse regression, the first listed kept: a form at the
#: crank and its twin at the piston (a torque is a force through the lever r cos theta) correlate 0.990-1.000 on the
#: book rig's +-10-35 deg (the same campaign of a crank bearing's friction), and STLSQ given both fitted the twins'
#: difference with cancelling coefficients (-0.00347 and +0.00344 m^2, 5070 N and -258 N m), its ridge
#: notwithstanding; the closest pair of one place there 0.985 (a constant and chamber A's pressure)
TWIN_R = 0.99


def net_share(terms: dict[str, float], tangents: dict[str, np.ndarray]) -> float:
    """The size of a set of forms' summed response over the sum of their responses' sizes, each response its
    coefficient times its tangent (:func:`_screen`'s): 1 for one form or forms that add up, near 0 for forms that
    cancel (:data:`CANCEL_SHARE`).  A form without a tangent (its probe diverged) makes the set count as not
    cancelling: 1.

    Parameters
    ----------
    terms : dict
        {form: coefficient}.
    tangents : dict
        {form: residual change per unit coefficient}.

    Returns
    -------
    float
        In [0, 1].

    Examples
    --------
    >>> t = {"a": np.array([1.0, 0.0]), "b": np.array([1.0, 0.1]), "c": np.array([0.0, 1.0])}
    >>> round(net_share({"a": 1.0, "b": -1.0}, t), 3), round(net_share({"a": 1.0, "c": 1.0}, t), 3)
    (0.05, 0.707)
    """
    if len(terms) < 2 or any(k not in tangents for k in terms):
        return 1.0
    parts = [c * tangents[k] for k, c in terms.items()]
    size = sum(float(np.linalg.norm(x)) for x in parts)
    return 1.0 if size <= 0.0 else min(float(np.linalg.norm(sum(parts))) / size, 1.0)


def _distinct(keys: list, tangents: dict, n: int, taken=()) -> list:
    """The first ``n`` of ``keys`` whose tangents (:func:`_screen`'s) are no twin of one taken before them or of
    ``taken``'s (:func:`without_twins`); a key without a tangent is taken as it comes."""
    known = [k for k in taken if k in tangents]
    out = []
    for k in keys:
        if len(out) >= n:
            break
        if k not in tangents:
            out.append(k)
        elif without_twins({j: tangents[j] for j in known + [k]})[-1:] == [k]:
            out.append(k)
            known.append(k)
    return out


def without_twins(columns: dict[str, np.ndarray], r: float = TWIN_R) -> list[str]:
    """The keys of ``columns`` in their order, each left out whose column correlates (uncentred) at least ``r`` with
    one kept before it: what a regression can part.

    Examples
    --------
    >>> x = np.linspace(0.1, 1.0, 50)
    >>> without_twins({"x": x, "x_twin": 2.0 * x + 1e-4, "x3": x ** 3})
    ['x', 'x3']
    """
    kept, unit = [], {}
    for k, col in columns.items():
        n = float(np.linalg.norm(col))
        if n <= 0.0:
            continue
        u = col / n
        if all(abs(float(u @ unit[j])) < r for j in kept):
            kept.append(k)
            unit[k] = u
    return kept


#: forms refitted without one of them at each step of the proposal's backward elimination (the best ranked by the
#: fit's linearisation, :func:`_drop_order`)
DROP_REFITS = 2


def _drop_order(rep: Replayer, f, fixed: ModelSpec) -> list[str]:
    """The proposed terms of the fit ``f``, the one whose leaving out is predicted to raise its cost least first:
    on the fit's linearisation at ``f`` (one forward-difference Jacobian), each term set to zero and every other
    fitted number refitted linearly (:func:`ehas_env.diagnosis.naming.linearised`)."""
    from ehas_env.diagnosis.naming import linearised

    u = np.array([fp.u(D._value_of(f.model, fp)) for fp in f.free])
    u_zero = np.array([fp.u(0.0) if fp.effect == D.TERM else x for fp, x in zip(f.free, u)])
    keys = [f"{fp.effect}.{fp.name}" for fp in f.free]
    predict = linearised(rep, f.free, fixed, u, u_zero, keys)
    terms = [fp.name for fp in f.free if fp.effect == D.TERM]
    cost = {t: predict([k for k in keys if k != f"{D.TERM}.{t}"])[0] for t in terms}
    return sorted(terms, key=lambda t: cost[t])


def place_of(key: str) -> str:
    return FORMS[key][0]


def si_quantities(case, sim) -> dict[str, np.ndarray]:
    """The model's quantities of a closed-loop run in SI (the arguments of the force and torque forms)."""
    rig = RigParams()
    th = np.radians(sim["theta_deg"])
    w = np.radians(sim["omega_deg_s"])
    return {"theta": th, "omega": w, "x": rig.radius * np.sin(th), "v": rig.radius * np.cos(th) * w,
            "pa": sim["p_a_bar"] * BAR, "pb": sim["p_b_bar"] * BAR, "radius": np.full(th.size, rig.radius),
            "v_tanh": np.full(th.size, 1e-3), "cos": np.cos(th)}


def force_feature(key: str, q: dict) -> np.ndarray:
    """The piston-equivalent force per unit coefficient of a force or torque form (torque / (r cos theta))."""
    place, _, expr, _ = FORMS[key]
    env = {"math": math, "abs": np.abs, "max": np.maximum, **q}
    val = eval(expr.format(c="1.0").replace("math.", "np."), {"np": np, **env})  # noqa: S307 (our own table)
    val = np.broadcast_to(np.asarray(val, dtype=float), q["theta"].shape).astype(float)
    if place == "crank_torque":
        val = val / (q["radius"] * np.maximum(q["cos"], 0.2))
    return val


def _force_cases(rep: Replayer, sims):
    for case, sim in zip(rep.cases, sims):
        if sim is None or case.run.kind != "closed_loop":
            continue
        yield case, sim


def coefficient_range(key: str, rep: Replayer, sims) -> float:
    """Largest coefficient magnitude tried for a form: FORCE_SCALE over the form's RMS on this campaign."""
    if key in FIXED_RANGE:
        return FIXED_RANGE[key]
    vals = [force_feature(key, si_quantities(c, s)) for c, s in _force_cases(rep, sims)]
    if not vals:
        return 0.0
    rms = float(np.sqrt(np.mean(np.concatenate(vals) ** 2)))
    return FORCE_SCALE / rms if rms > 0 else 0.0


def sparse_force_terms(rep: Replayer, sims, threshold: float = 0.08) -> dict[str, float]:
    """pysindy STLSQ on the residual piston force of the runs with chamber pressures: {form: coefficient}."""
    import pysindy as ps

    area = RigParams().area
    ys, X = [], {k: [] for k in FORMS if place_of(k) in ("piston_force", "crank_torque")}
    for case, sim in _force_cases(rep, sims):
        m = case.measured
        if "p_a_bar" in m and "p_b_bar" in m:
            pl = m["p_a_bar"] - m["p_b_bar"]
        elif "load_kN" in m:
            pl = m["load_kN"] * 1e3 / area / BAR
        else:
            continue
        k = case.skip
        ys.append((-(pl - (sim["p_a_bar"] - sim["p_b_bar"])) * BAR * area)[k:])
        q = si_quantities(case, sim)
        for key in X:
            X[key].append(force_feature(key, q)[k:])
    if not ys:
        return {}
    y = np.concatenate(ys)
    keys = [k for k in X if np.ptp(np.concatenate(X[k])) > 0 or k.endswith(".c_1")]
    keys = [k for k in keys if not k.startswith("proposal_crank_torque.c_1")]  # the piston's constant stands for it
    keys = without_twins({k: np.concatenate(X[k]) for k in keys})
    A = np.column_stack([np.concatenate(X[k]) for k in keys])
    scale = np.sqrt(np.mean(A**2, axis=0))
    ys_ = float(np.sqrt(np.mean(y**2))) or 1.0
    An, yn = A / scale, y / ys_
    # the sparsest STLSQ model (thresholds rising) that keeps 95 % of what the densest one explains;
    # the ridge term keeps nearly collinear forms (x and theta, x and x^3) from cancelling each other
    best = None
    for thr in (threshold, 2 * threshold, 4 * threshold, 8 * threshold):
        opt = ps.STLSQ(threshold=thr, alpha=1e-2 * yn.size, max_iter=30, unbias=True)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "sparsity parameter too big": the loop's end
            opt.fit(An, yn[:, None])
        c = np.ravel(opt.coef_)
        r2 = 1.0 - float(np.mean((yn - An @ c) ** 2)) / float(np.mean(yn**2))
        nz = int(np.count_nonzero(c))
        if nz == 0:
            break
        if best is None:
            best = (r2, c)
        elif r2 >= 0.95 * best[0] or nz <= MAX_TERMS < np.count_nonzero(best[1]):
            best = (best[0], c) if r2 >= 0.95 * best[0] else best
    if best is None:
        return {}
    coef = best[1] * ys_ / scale
    return {k: float(c) for k, c in zip(keys, coef) if c != 0.0}


@dataclass
class Proposal:
    """A proposed missing term: forms, fitted coefficients (SI), and what it does to the fit."""

    terms: dict[str, float]
    ci: dict[str, tuple[float, float]]
    cost_before: float
    cost_after: float
    fit_before: float
    fit_after: float
    fit: object  # diagnosis.Fit of the model with the term (on the fit data)
    screened: list = field(default_factory=list)  # [(form, J after screening)], best first
    sparse: dict = field(default_factory=dict)  # the STLSQ selection on the residual force
    #: fitted sets refused because their forms cancel: [{terms, net_share, residual_x_noise}] (:data:`CANCEL_SHARE`)
    cancelling: list = field(default_factory=list)
    validation: dict = field(default_factory=dict)  # filled by the caller: J and fit % on all data
    #: the named physical forms (ehas_env.diagnosis.naming: JSON entries) and the naming's record
    named: list = field(default_factory=list)
    naming: dict = field(default_factory=dict)
    named_model: object = None  # the model with the named forms (a ModelSpec; None when none is named)

    @property
    def places(self) -> list[str]:
        return sorted({place_of(k) for k in self.terms})

    def equation(self) -> str:
        """``T_crank [N m] += c_th * theta, c_th = -1.52e+03 N m/rad [95 % CI ...]``, one line per place."""
        lines = []
        for place in self.places:
            keys = [k for k in self.terms if place_of(k) == place]
            rhs = " + ".join(f"{k.split('.', 1)[1]}·{FORMS[k][1]}" if FORMS[k][1] != "1" else k.split(".", 1)[1]
                             for k in keys)
            vals = "; ".join(_coef_text(k, self.terms[k], self.ci.get(k)) for k in keys)
            lines.append(f"{PLACE_SYMBOL[place]} {rhs}   with {vals}")
        return "\n".join(lines)

    def to_json(self) -> dict:
        out = {"where": self.places, "equation": self.equation(),
               "terms": [{"place": place_of(k), "form": FORMS[k][1], "coefficient": k.split(".", 1)[1],
                          "value": _r(v), "unit": term_param(k).unit, "meaning": term_param(k).doc,
                          "ci95": [_r(x) for x in self.ci[k]] if k in self.ci else None}
                         for k, v in self.terms.items()],
               "residual_x_noise_before": round(self.cost_before, 3), "residual_x_noise_after": round(self.cost_after, 3),
               "fit_percent_before": round(self.fit_before, 2), "fit_percent_after": round(self.fit_after, 2),
               "sparse_regression": {k: _r(v) for k, v in self.sparse.items()},
               "screened": [[k, round(c, 3)] for k, c in self.screened[:6]],
               "refused_cancelling": list(self.cancelling)}
        out["named"] = list(self.named)
        if self.naming:
            out["naming"] = self.naming
        if self.validation:
            out["validation"] = self.validation
        return out


def _r(v: float) -> float:
    return float(f"{v:.4g}")


def _coef_text(key: str, v: float, ci=None) -> str:
    unit = term_param(key).unit
    s = f"{key.split('.', 1)[1]} = {v:.4g} {unit}"
    if ci is not None:
        s += f" (95 % CI {ci[0]:.4g} to {ci[1]:.4g})"
    return s


def _linear_costs(r0: list, dr: list, coefs: np.ndarray) -> np.ndarray:
    """The log cost (:meth:`Replayer.log_cost`) of the residual blocks ``r0 + c dr`` at every ``c`` of ``coefs``.

    Each block's mean square is the quadratic ``(|r0|^2 + 2 c r0.dr + c^2 |dr|^2) / n``: the whole scan from three
    dot products a block, no replay.

    Examples
    --------
    >>> r0, dr = [np.array([1.0, -1.0])], [np.array([-1.0, 1.0])]
    >>> [round(float(x), 6) for x in _linear_costs(r0, dr, np.array([0.0, 0.5, 1.0]))]
    [1.0, 0.25, 0.0]
    """
    n = sum(b.size for b in r0)
    total = np.zeros(coefs.size)
    for a, d in zip(r0, dr):
        ms = (float(a @ a) + 2.0 * coefs * float(a @ d) + coefs ** 2 * float(d @ d)) / a.size
        total += a.size * np.log(np.maximum(ms, 1e-300))
    return np.exp(total / n)


def _screen(rep: Replayer, base, keys: list[str], ranges: dict[str, float],
            tangents: dict | None = None) -> list[tuple[str, float, float]]:
    """Each form alone on top of ``base``, screened on the model's linearisation, the best confirmed by replays.

    The replayed scan this replaces (every form's coefficient over both signs and SCREEN_MAGS magnitudes: 336
    replays of the campaign for 42 forms) spent a quarter of an unexplained campaign's diagnosis.  Here each form
    is replayed once, at a small coefficient (:data:`SCREEN_STEP` of its range): the change of every residual
    block per unit coefficient is its tangent, and the log cost along the tangent is scanned over both signs and
    four decades without a replay (:func:`_linear_costs`).  The :data:`SCREEN_CONFIRM` forms it ranks best are
    then replayed over SCREEN_MAGS magnitudes of their predicted sign (the replayed scan's magnitudes), which
    gives their cost and coefficient as the replayed scan did; a form the tangent misranks below them is not
    fitted (the sparse regression's set is fitted whatever the screen says, :func:`propose`).

    ``tangents``, when given, receives each form's tangent: the change of the residual per unit coefficient, every
    block weighted as the log cost's gradient at ``base`` (1 / its RMS), concatenated (:func:`net_share`).

    Returns
    -------
    list of (str, float, float)
        (form, best J, best coefficient), the confirmed forms first (best first), then the rest by their
        linearised J.
    """
    r0 = rep.cost_blocks(base.sims)
    ref = {k: float(base.model.terms.get(k, 0.0)) for k in keys}
    steps = {k: SCREEN_STEP * ranges[k] for k in keys}

    def model(k: str, c: float) -> ModelSpec:
        return ModelSpec(effects=base.model.effects, beta=base.model.beta, K=base.model.K,
                         terms={**base.model.terms, k: c})

    probes = [model(k, ref[k] + steps[k]) for k in keys]
    sims = [x for i in range(0, len(probes), SCREEN_BATCH) for x in rep.simulate_many(probes[i:i + SCREEN_BATCH])]
    mags = np.geomspace(1e-4, 1.0, SCREEN_GRID)
    linear: dict[str, tuple[float, float]] = {}
    for k, sim in zip(keys, sims):
        blocks = rep.cost_blocks(sim)
        if len(blocks) != len(r0) or not all(np.all(np.isfinite(b)) for b in blocks):
            continue  # the probe failed (a diverging replay): the form is screened by replays below
        dr = [(b - a) / steps[k] for a, b in zip(r0, blocks)]
        if tangents is not None:
            tangents[k] = np.concatenate([d / math.sqrt(max(float(a @ a) / max(a.size, 1), 1e-300))
                                          for a, d in zip(r0, dr)])
        coefs = np.concatenate([-mags[::-1], mags]) * ranges[k]
        costs = _linear_costs(r0, dr, coefs - ref[k])
        j = int(np.argmin(costs))
        linear[k] = (float(costs[j]), float(coefs[j]))
    order = sorted(linear, key=lambda k: linear[k][0])
    confirm = order[:SCREEN_CONFIRM] + [k for k in keys if k not in linear]
    models, index = [], []
    for k in confirm:
        signs = (np.sign(linear[k][1]),) if k in linear and linear[k][1] != 0.0 else (-1.0, 1.0)
        for m in np.geomspace(1e-3, 1.0, SCREEN_MAGS) * ranges[k]:
            for sgn in signs:
                models.append(model(k, sgn * float(m)))
                index.append((k, sgn * float(m)))
    costs = []
    for i in range(0, len(models), SCREEN_BATCH):
        for sims in rep.simulate_many(models[i:i + SCREEN_BATCH]):
            costs.append(rep.log_cost(sims))
    best: dict[str, tuple[float, float]] = {}
    for (k, c), j in zip(index, costs):
        if not math.isfinite(j):
            continue
        if k not in best or j < best[k][0]:
            best[k] = (j, c)
    confirmed = sorted(((k, j, c) for k, (j, c) in best.items()), key=lambda x: x[1])
    rest = [(k, *linear[k]) for k in order if k not in best]
    return confirmed + rest


def propose(rep: Replayer, base, *, confidence=None, name: bool = True, say=None, proven=None) -> Proposal | None:
    """The best sparse term for the residual of ``base`` (a diagnosis Fit), fitted inside the model, then named.

    Parameters
    ----------
    rep : Replayer
        The fit data.
    base : Fit
        The model the term is added to.
    confidence : callable, optional
        ``confidence(rep, fit)`` returns confidence intervals {(effect, name): (lo, hi)}.
    name : bool
        Fit the flexible term at the sparse terms' places and name it (:func:`ehas_env.diagnosis.naming.name_terms`):
        the Proposal's ``named`` (physical forms with units, values and intervals, each passing honesty rule 1 on
        the fit data) and ``naming`` (the flexible fit, the text).
    say : callable, optional
        Progress text.
    proven : callable, optional
        ``proven(model)``: whether a fitted term holds on the runs held out of the fit (its residual there is not
        above the model's without it).  The first of the tries, best scored first, that holds is the one built on;
        one that fits the fit data better and the held-out runs worse fitted noise of the fit data (when none holds,
        the best scored, as without ``proven``).

    Returns
    -------
    Proposal or None
        None when no form lowers the residual.
    """

    keys = list(FORMS)
    ranges = {k: coefficient_range(k, rep, base.sims) for k in keys}
    keys = [k for k in keys if ranges[k] > 0]
    sparse = sparse_force_terms(rep, base.sims)
    tangents: dict[str, np.ndarray] = {}
    screened = _screen(rep, base, keys, ranges, tangents)
    screened = [s for s in screened if s[1] < base.cost * (1.0 - D.SKIP_MARGIN)]
    if not screened and not sparse:
        return None

    def fit_terms(start_terms: dict[str, float]):
        free = [D.FreeParam(D.TERM, k, -4.0 * max(abs(c), 1e-3 * ranges[k]), 4.0 * max(abs(c), 1e-3 * ranges[k]), False)
                for k, c in start_terms.items()]
        free += [fp for n in base.model.effects for fp in D.own_params(n)] + D.recal_params(base.model.effects)
        start = {}
        for fp in free:
            if fp.effect == D.TERM:
                start[(fp.effect, fp.name)] = start_terms[fp.name]
            elif fp.effect is None:
                start[(None, fp.name)] = base.model.beta if fp.name == "beta" else base.model.K
            else:
                start[(fp.effect, fp.name)] = base.model.effects[fp.effect][fp.name]
        return D.fit(rep, free, start, fixed, max_nfev=D.MAX_NFEV)

    fixed = ModelSpec(effects=base.model.effects, beta=base.model.beta, K=base.model.K)

    def score(f) -> float:
        return 10.0 * math.log10(base.cost / f.cost) - PENALTY_PER_TERM_DB * len(f.model.terms)

    coef = {k: c for k, _, c in screened}
    # a form whose screen tangent is a twin of a better one's fits as that one does (the piston's and the crank's
    # load friction screened alike, 5.497 and 5.497): the tries and the forms added are distinct ones
    tries = [{k: coef[k]} for k in _distinct(list(coef), tangents, FIT_TOP)]
    if sparse and set(sparse) not in [set(t) for t in tries]:
        tries.append(dict(sparse))
    cancelling = []  # fitted sets refused: their forms undo one another (net_share below CANCEL_SHARE)

    def holds(f) -> bool:
        share = net_share(f.model.terms, tangents)
        if share >= CANCEL_SHARE:
            return True
        cancelling.append({"terms": {k: _r(v) for k, v in f.model.terms.items()}, "net_share": round(share, 4),
                           "residual_x_noise": round(f.cost, 3)})
        if say is not None:
            say(f"  {', '.join(f.model.terms)} refused: their responses cancel (the sum {100 * share:.2g} % of the "
                "parts), the data fix only a combination of them")
        return False

    fits = [f for f in (fit_terms(t) for t in tries) if holds(f)]
    if not fits:
        return None
    best = _built_on(fits, score, proven, say)
    # add further forms while each lowers the residual clearly
    while len(best.model.terms) < MAX_TERMS:
        extra = _distinct([k for k in coef if k not in best.model.terms], tangents, 2, taken=best.model.terms)
        if not extra:
            break
        cands = [f for f in (fit_terms({**best.model.terms, k: next(c for kk, _, c in screened if kk == k)})
                             for k in extra) if holds(f)]
        if not cands:
            break
        cand = max(cands, key=score)
        if 10.0 * math.log10(best.cost / cand.cost) < ADD_TERM_DB:
            break
        best = cand
    if best.cost >= base.cost * (1.0 - D.SKIP_MARGIN):
        return None
    # drop forms that no longer carry anything (a sparse start can keep one): backward elimination by the rule
    # that adds them, a form stays only when leaving it out raises the residual by at least ADD_TERM_DB
    # (each subset refitted from the larger model's values: a single form's own fit may have stopped short).  The
    # fit's linearisation at the model ranks the forms to leave out (one Jacobian); the DROP_REFITS best ranked are
    # refitted: a sparse regression can start with ten forms, and refitting every subset of every step made
    # thousands of replays
    fitted = {frozenset(f.model.terms): f for f in fits}
    while len(best.model.terms) > 1:
        subs = []
        for drop in _drop_order(rep, best, fixed)[:DROP_REFITS]:
            keep = frozenset(k for k in best.model.terms if k != drop)
            f = fit_terms({k: best.model.terms[k] for k in keep})
            if keep in fitted and fitted[keep].cost < f.cost:
                f = fitted[keep]
            subs.append(f)
        subs = [f for f in subs if holds(f)]
        if not subs:
            break
        sub = min(subs, key=lambda f: f.cost)
        if 10.0 * math.log10(sub.cost / best.cost) >= ADD_TERM_DB:
            break
        best = sub
    ci = {}
    if confidence is not None:
        for (eff, name), lohi in confidence(rep, best).items():
            if eff == D.TERM:
                ci[name] = lohi
    prop = Proposal(terms=dict(best.model.terms), ci=ci, cost_before=base.cost, cost_after=best.cost,
                    fit_before=base.table.overall, fit_after=best.table.overall, fit=best,
                    screened=[(k, j) for k, j, _ in screened], sparse=sparse, cancelling=cancelling)
    if name:
        nm = name_terms(rep, base, prop.terms, ranges, fixed_model=best.model, confidence=confidence, say=say)
        prop.named = nm.named
        prop.naming = nm.to_json()
        prop.named_model = nm.fit.model if nm.named and nm.fit is not None else None
    return prop


def _built_on(fits: list, score, proven, say):
    """The try the proposal builds on: the best scored that holds on the runs held out (``proven``; the best
    scored when none does or no judge is given)."""
    ranked = sorted(fits, key=score, reverse=True)
    best = next((f for f in ranked if proven is None or proven(f.model)), ranked[0])
    if best is not ranked[0] and say is not None:
        say(f"  {', '.join(ranked[0].model.terms)} fits the fit data best but not the runs held out: "
            f"{', '.join(best.model.terms)} is built on")
    return best


# --- the effect file ----------------------------------------------------------------------------


def effect_source(proposal: Proposal, name: str, *, origin: str = "") -> str:
    """The text of a user effect file (docs/effects-and-controllers.md) holding the proposed terms.

    Each coefficient becomes a parameter: its magnitude (the sign is written into the term), default the
    fitted value, typical range half to twice it, bounds 0 to 20 times it.
    """
    cls_name = "".join(part.capitalize() for part in name.split("_") if part) or "Proposed"
    if not cls_name[0].isalpha():
        cls_name = "Proposed" + cls_name
    params, methods, mains = [], [], []
    for place in proposal.places:
        keys = [k for k in proposal.terms if place_of(k) == place]
        args: list[str] = []
        pnames = []
        body = []
        for k in keys:
            coef = k.split(".", 1)[1]
            pname = f"{SHORT[place]}{coef[1:]}"
            v = proposal.terms[k]
            mag = abs(v)
            p = term_param(k)
            ci = proposal.ci.get(k)
            ci_txt = f", 95 % CI {ci[0]:.4g} to {ci[1]:.4g}" if ci else ""
            params.append(f'        Param("{pname}", "{p.unit}", {mag:.6g}, (0.0, {20.0 * mag:.6g}),\n'
                          f'              "{p.doc} (fitted: {v:.4g}{ci_txt})", typical=({0.5 * mag:.6g}, {2.0 * mag:.6g})),')
            pnames.append(pname)
            mains.append((mag, pname))
            sign = "-" if v < 0 else ""
            for a in FORMS[k][3]:
                if a not in args:
                    args.append(a)
            if place == "chamber_flows":
                body.append((coef, sign, pname))
            else:
                expr = FORMS[k][2].format(c=pname)
                body.append(f"{sign}({expr})" if sign else f"({expr})")
        tp = TERM_PLACES.get(place)
        first = [tp.quantities[0].code] if tp is not None and tp.form == "signal" else []
        sig = ", ".join(first + args + pnames)
        lines = [f"    @staticmethod", f"    def {place}({sig}):"]
        if place == "chamber_flows":
            lines += _flow_body(body)
        elif first:
            lines.append(f"        return {first[0]} + " + " + ".join(body))
        else:
            lines.append("        return " + " + ".join(body))
        methods.append("\n".join(lines))
    main = max(mains)[1]
    flows = [k for k in proposal.terms if place_of(k) == "chamber_flows"]
    valve_side = bool(flows) and all(k.startswith("proposal_land_flows.") for k in flows)
    eq = proposal.equation().replace('"', "'")
    doc = (f'"""{name}: a term proposed by ehas diagnose{(" for " + origin) if origin else ""}.\n\n'
           f"{eq}\n\n"
           "Residual (geometric mean of noise-normalised residual energy, 1 = noise): "
           f"{proposal.cost_before:.3g} -> {proposal.cost_after:.3g}; fit {proposal.fit_before:.1f} % -> "
           f"{proposal.fit_after:.1f} %.\n"
           "Rename the file, the class and ``name``, give the parameters physical names and documentation,\n"
           "then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit\n"
           '"""')
    expl = textwrap.shorten("Proposed by the diagnosis, not yet a physical explanation: " + eq.replace("\n", "; "),
                            600)
    sigt = "the residual it was fitted to: " + ", ".join(FORMS[k][1] for k in proposal.terms)
    text = "\n".join([
        doc, "import math", "", "from ehas_env.physics.effects import Effect, Param", "", "",
        f"class {cls_name}(Effect):",
        f'    name = "{name}"',
        f'    title = "proposed term ({", ".join(p.replace("_", " ") for p in proposal.places)})"',
        "    params = (", *params, "    )",
        f'    main_param = "{main}"',
        *(["    valve_side = True"] if valve_side else []),
        f"    explanation = {expl!r}",
        f"    signature = {sigt!r}",
        "", "\n\n".join(methods), ""])
    if "math." not in text.split('import math', 1)[1]:
        text = text.replace("import math\n\n", "", 1)
    return text


def _flow_body(body: list) -> list[str]:
    """The lines of an effect file's ``chamber_flows`` method for the flow terms ``body`` ((coefficient, sign,
    parameter name) each; :data:`FLOW_CODE` holds each form's code, by the spool's direction where it depends on
    it)."""
    return flow_body(((FLOW_CODE[coef], f"{sign}{pname}" if not sign else f"(-{pname})") for coef, sign, pname in body),
                     indent="        ")


def write_effect(path, proposal: Proposal, *, origin: str = "", overwrite: bool = False) -> "Path":
    """Write the effect file ``DIR/NAME.py`` (the effect is named NAME); returns its path."""
    from pathlib import Path

    from ehas_env.output.files import atomic_write_text

    path = Path(path)
    name = path.stem
    if path.suffix != ".py" or not name.isidentifier():
        raise ValueError(f"--write-effect {path}: give DIR/NAME.py with NAME a Python identifier (it names the effect)")
    text = effect_source(proposal, name, origin=origin)
    compile(text, str(path), "exec")
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write_text(path, text)
