"""The diagnosis' honesty rules, each enforced here and nowhere else (issue 33).

1. **No term that removes too little** (:func:`term_refused`): a proposed missing term is written or recommended
   only when its refit removes at least :data:`TERM_SHARE` of the residual's excess over the noise (the residual
   in the verdict's units, "x what does not repeat", on all data: 1 is noise).  Otherwise the diagnosis says where
   the residual is and what it follows, and that no term was found.
2. **No hypothesis that makes the all-data residual worse** (:func:`worse_than_bare`): the structural hypotheses
   (and what was stacked on them) are kept only when the final model's all-data residual is not above the bare
   model's, the model the library's effects gave before the hypotheses were tried.
3. **No block its intervals cannot tell from nothing** (:func:`size_not_shown`): a block whose sizes (its signed
   numbers, nothing at 0) each have a 95 % interval that holds 0 is not kept: the data do not show it acts.
4. **A fit on a bound says so** (:func:`at_bounds`): every fitted parameter of a library effect that sits at the
   end of its fit range (and so is no point estimate) is listed, with the range and whether that end is the
   parameter's physical bound, in the JSON (``model.at_bound``, ``ranking[].at_bound``); so are the final model's
   recalibrated beta and K at an end of their recalibration range (``model.at_bound``).

Examples
--------
>>> share_removed(3.06, 3.06), share_removed(3.0, 2.0)
(0.0, 0.5)
>>> term_refused(3.34, 3.42) is not None, term_refused(3.0, 1.5) is None
(True, True)
>>> worse_than_bare(3.68, 3.89) is not None, worse_than_bare(3.68, 2.1) is None
(True, True)
>>> from ehas_env.physics.effects import get_effect
>>> size_not_shown(get_effect("aug_offset_pb_reading"), {"c": [-923.6, 555.3]}) is not None
True
>>> size_not_shown(get_effect("aug_offset_pb_reading"), {"c": [-5e5, -3e5]}) is None
True
>>> size_not_shown(get_effect("aug_knee_chamber_a"), {"c": [-5e-8, 1e-7], "d": [-1.7e-6, -1.5e-6], "k": [4e6, 5e6]})
>>> size_not_shown(get_effect("aug_saturating_supply"), {"c": [-3e6, 3e6], "k": [1e-6, 8e-4]}) is None
True
"""
from __future__ import annotations

#: a proposed term must remove at least this share of the residual's excess over the noise (1 x what does not
#: repeat) on all data to be written or recommended (issue 33: terms that took 3.06x to 3.06x were written)
TERM_SHARE = 0.1
#: a final model whose all-data residual exceeds the bare model's by more than this share (rounding of two
#: simulations of one model) is worse than it
WORSE_TOLERANCE = 1e-3


def share_removed(before: float, after: float, floor: float = 1.0) -> float:
    """The share of ``before``'s excess over ``floor`` that ``after`` removes (negative when it adds).

    Parameters
    ----------
    before, after : float
        Residuals before and after, in units of the floor (x what does not repeat).
    floor : float
        The residual of a model that explains everything (1: the noise).

    Returns
    -------
    float
        (before - after) / (before - floor); 0 when ``before`` is at or below the floor.
    """
    excess = before - floor
    if excess <= 0.0:
        return 0.0
    return (before - after) / excess


def term_refused(before: float, after: float) -> str | None:
    """Why a proposed term may not be written or recommended (None when it may): its refit removes less than
    :data:`TERM_SHARE` of the residual's excess over the noise.

    Parameters
    ----------
    before, after : float
        The all-data residual (x what does not repeat) of the final model without and with the term.

    Returns
    -------
    str or None
        The refusal in words, with the numbers.
    """
    s = share_removed(before, after)
    if s >= TERM_SHARE:
        return None
    return (f"the best term of the dictionary, refitted in the full model, takes the residual from {before:.3g}x to "
            f"{after:.3g}x noise on all data: it removes {100 * s:.0f} % of the excess over the noise, less than the "
            f"{100 * TERM_SHARE:.0f} % a term must remove; no term was found")


def worse_than_bare(bare: float, final: float) -> str | None:
    """Why a model is worse than the bare model (None when it is not): its all-data residual is above the bare
    model's (beyond :data:`WORSE_TOLERANCE`).

    Parameters
    ----------
    bare, final : float
        The all-data residuals (x what does not repeat) of the bare model and of the model with the hypotheses.

    Returns
    -------
    str or None
    """
    if final <= bare * (1.0 + WORSE_TOLERANCE):
        return None
    return (f"makes the residual on all data worse than the model without the hypotheses ({bare:.3g}x -> "
            f"{final:.3g}x what does not repeat)")


def size_not_shown(cls, ci: dict) -> str | None:
    """Why a fitted block may not be kept (None when it may): each of its sizes -- the signed numbers with 0 their
    default and inside their range, where the block does nothing (an offset, a scale error, a balance's term; a
    piecewise-linear term's slope within and its change beyond) -- has a 95 % interval ``ci[name] = (lo, hi)``
    that holds 0, both its ends inside the size's range.  A block with no such number (a lag's time constant, a
    saturation's level) passes, and so does one with a size whose interval is clear of 0 or reaches an end of the
    range (drawn case d01: a saturating term at the supply whose size's interval is its whole range, +-30 bar, its
    level and its break trading off -- the linearised interval shows nothing, it does not show nothing).

    Parameters
    ----------
    cls : type
        The block (an effect class with ``params``).
    ci : dict
        {parameter: (lo, hi)}, the fit's 95 % intervals in the parameters' units.

    Returns
    -------
    str or None
        The refusal in words, with the intervals.
    """
    sizes = [q for q in getattr(cls, "params", ()) if q.default == 0.0 and q.bounds[0] < 0.0 < q.bounds[1]]

    def nothing(q) -> bool:  # an interval inside the range that holds 0 (one out to an end of the range is the
        lo, hi = ci[q.name]  # linearisation failing, numbers that trade off: it shows nothing either way)
        return q.bounds[0] < lo <= 0.0 <= hi < q.bounds[1]

    if not sizes or any(q.name not in ci or not nothing(q) for q in sizes):
        return None
    held = ", ".join(f"{q.name} [{ci[q.name][0]:.3g}, {ci[q.name][1]:.3g}] {q.unit}" for q in sizes)
    return (f"the 95 % interval of its size{'s' if len(sizes) > 1 else ''} ({held}) hold{'' if len(sizes) > 1 else 's'}"
            " 0, where it does nothing: the data do not show it")


def range_not_narrowed(fit, effect: str, ci: dict) -> str | None:
    """Why a fitted block may not be kept (None when it may): the 95 % interval of its main number runs from one
    end of its fit range to the other, so the data do not determine it (a value in the middle of a flat valley is
    a value the fit happened to stop at, not one the data show: a dead zone of a load reading the model misses by
    far, +-5.08 kN with the interval [0.005, 10] kN, its whole range).  A number whose range end is still its
    block's physics (``Param.limit``) passes.

    Parameters
    ----------
    fit : Fit
        The fit holding the block (its ``free`` numbers give the ranges).
    effect : str
        The block.
    ci : dict
        {parameter: (lo, hi)}, the fit's 95 % intervals in the parameters' units.

    Returns
    -------
    str or None
        The refusal in words, with the interval.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from ehas_env.diagnosis.fitting import FreeParam
    >>> f = SimpleNamespace(free=[FreeParam("aug_dz_force_reading", "d", 5.0, 1.0e4, True, 2e-3)])
    >>> range_not_narrowed(f, "aug_dz_force_reading", {"d": (5.0, 1.0e4)})[:40]
    'the data do not determine it: the 95 % i'
    >>> range_not_narrowed(f, "aug_dz_force_reading", {"d": (4.0e3, 6.0e3)}) is None
    True
    """
    from ehas_env.physics.effects import get_effect

    cls = get_effect(effect)
    main = getattr(cls, "main_param", None)
    for fp in fit.free:
        if fp.effect != effect or fp.name != main or fp.name not in ci:
            continue
        lo, hi = ci[fp.name]
        p = cls.param(fp.name)
        whole = fp.u(max(lo, fp.lo)) <= NOT_NARROWED and fp.u(min(hi, fp.hi)) >= 1.0 - NOT_NARROWED
        if whole and p.limit_at("lower") is None and p.limit_at("upper") is None:
            return (f"the data do not determine it: the 95 % interval of {fp.name}, [{lo:.4g}, {hi:.4g}] {p.unit}, "
                    f"is its whole range [{fp.lo:.4g}, {fp.hi:.4g}]")
    return None


#: an interval that reaches within this share of its range (in the fit's [0, 1] scale) of both ends is the whole range
NOT_NARROWED = 0.02


def at_bounds(fit, effects=None, baseline: bool = False) -> list[dict]:
    """The fitted parameters of library effects that sit at an end of their fit range.

    Parameters
    ----------
    fit : Fit
        A fit (:class:`ehas_env.diagnosis.fitting.Fit`): its ``free`` parameters and ``model``.
    effects : iterable of str, optional
        Only these effects (default: every effect of the fit; proposed terms are not library effects and are left
        out).
    baseline : bool
        Also the recalibrated beta and K (:func:`baseline_at_bound`), listed first: the final model's, not each
        candidate's.

    Returns
    -------
    list of dict
        {effect, param, value, unit, end ("lower"/"upper"), range [lo, hi], physical_bound (bool), text}.
    """
    from ehas_env.diagnosis.fitting import TERM, _value_of
    from ehas_env.physics.effects import get_effect

    out = []
    if fit is None:
        return out
    if baseline:
        out += [b for b in (baseline_at_bound(fp, _value_of(fit.model, fp)) for fp in fit.free if fp.effect is None)
                if b is not None]
    wanted = None if effects is None else set(effects)
    for fp in fit.free:
        if fp.effect in (None, TERM) or (wanted is not None and fp.effect not in wanted):
            continue
        if fp.effect not in fit.model.effects:
            continue
        v = _value_of(fit.model, fp)
        end = fp.end(v)
        if end is None:
            continue
        p = get_effect(fp.effect).param(fp.name)
        bound = p.bounds[0] if end == "lower" else p.bounds[1]
        physical = abs((fp.lo if end == "lower" else fp.hi) - bound) <= 1e-9 * max(abs(bound), 1e-300)
        text = (f"{fp.effect}.{fp.name} = {v:.4g} {p.unit} sits at the {end} end of its fit range "
                f"[{fp.lo:.4g}, {fp.hi:.4g}]" + (" (its physical bound)" if physical else "")
                + (f": {p.limit_at(end)}, no point estimate" if p.limit_at(end)
                   else ": no point estimate, the data ask for a value beyond it"))
        out.append({"effect": fp.effect, "param": fp.name, "value": float(f"{v:.4g}"), "unit": p.unit, "end": end,
                    "range": [float(f"{fp.lo:.4g}"), float(f"{fp.hi:.4g}")], "physical_bound": bool(physical),
                    "text": text})
    return out


def baseline_at_bound(fp, value: float) -> dict | None:
    """The entry of :func:`at_bounds` for the baseline's recalibrated beta or K (``fp``, fitted at ``value``) when it
    sits at an end of its recalibration range, else None.

    The recalibration range keeps one value for the whole campaign near the book's (+-7 % for beta, +-3 % for K:
    :data:`~ehas_env.diagnosis.fitting.BETA_RANGE`, :data:`~ehas_env.diagnosis.fitting.K_RANGE`); a value pinned at
    its end is no point estimate: the data ask for one beyond it, which the effect that re-opens the number
    (``bulk_modulus``, ``valve_dynamics``) would fit, or which a kept effect stands in for.

    Parameters
    ----------
    fp : FreeParam
        ``beta`` (Pa) or ``K`` (LPM/mA) of the baseline (its ``effect`` None).
    value : float
        Its fitted value.

    Returns
    -------
    dict or None

    Examples
    --------
    >>> from ehas_env.diagnosis.fitting import baseline_params
    >>> beta, K = baseline_params()
    >>> baseline_at_bound(beta, beta.hi)["text"]
    'beta = 1.07 GPa sits at the upper end of its recalibration range [0.93, 1.07] GPa: no point estimate, the data ask for a value beyond it (bulk_modulus re-opens it)'
    >>> baseline_at_bound(K, 0.5 * (K.lo + K.hi)) is None
    True
    """
    from ehas_env.diagnosis.fitting import REOPENED_BY

    end = fp.end(value)
    if end is None:
        return None
    scale, unit = (1e-9, "GPa") if fp.name == "beta" else (1.0, "LPM/mA")
    text = (f"{fp.name} = {value * scale:.4g} {unit} sits at the {end} end of its recalibration range "
            f"[{fp.lo * scale:.4g}, {fp.hi * scale:.4g}] {unit}: no point estimate, the data ask for a value beyond "
            f"it ({REOPENED_BY[fp.name]} re-opens it)")
    return {"effect": "baseline", "param": fp.name, "value": float(f"{value * scale:.4g}"), "unit": unit,
            "end": end, "range": [float(f"{fp.lo * scale:.4g}"), float(f"{fp.hi * scale:.4g}")],
            "physical_bound": False, "text": text}


def at_bound_lines(at_bound: list) -> list[str]:
    """Honesty rule 3 in words, for the console and the report (empty when no fit sits on a bound).

    Parameters
    ----------
    at_bound : list of dict
        :func:`at_bounds`' entries.

    Returns
    -------
    list of str
    """
    return ["  on a bound: " + b["text"] for b in at_bound]
