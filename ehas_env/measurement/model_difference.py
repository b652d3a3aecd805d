"""A calibrated model as a difference from the book's rig: what changed, in engineering units, with intervals.

A diagnosis ends with a model: the book's rig, its bulk modulus and valve gain
recalibrated, and the effects it kept.  This module states that model once, as
the rows in which it differs from the book's rig, each with its 95 % interval
(docs/measurement-format.md, ``model.ci95``).  A baseline value that an effect
of the model sets itself (``bulk_modulus`` sets beta, ``valve_dynamics`` sets
K, wn and zeta: the slots its ``apply`` writes) is not in force, so it is
shown as replaced by that effect's parameter, never as a value of its own.

The diagnose console, its report and the HTML page (``ehas report``) all print
these rows.

Examples
--------
>>> rows = model_difference({"effects": {"bulk_modulus": {"beta": 7.9e8}}, "beta": 9.3e8, "K": 1.2723})
>>> [r["quantity"] for r in rows]
['beta', 'bulk_modulus.beta']
>>> rows[0]["note"]
'not in force: replaced by bulk_modulus.beta'
"""
from __future__ import annotations

import math

#: the baseline's recalibrated numbers: (slot, words, unit shown, factor from the diagnosis JSON's unit to it)
BASELINE = (
    ("beta", "effective bulk modulus of the oil", "GPa", 1e-9),
    ("K", "valve flow gain at the rated drop", "LPM/mA", 1.0),
)


def _book(slot: str) -> float:
    from ehas_env.physics import rig

    return {"beta": rig.BULK_MODULUS, "K": rig.VALVE_K}[slot]


def replaced_slots(effect: str) -> list[str]:
    """The baseline slots that ``effect`` sets itself (its ``apply`` writes them), in the model's slot names.

    Parameters
    ----------
    effect : str
        A registered effect's name.

    Returns
    -------
    list of str
        Slot names (``beta``, ``K``, ...); empty for an effect that acts through terms only.
    """
    from ehas_env.physics import layout
    from ehas_env.physics.effects import get_effect

    eff = get_effect(effect)
    mark = -7.77e-300
    slots = dict.fromkeys(layout.BASE_SLOTS, mark)
    eff.apply(eff.resolve({}), slots)
    return [k for k, v in slots.items() if v != mark]


def _bound(row: dict | None, side: str, scale: float = 1.0) -> float | None:
    """One side of a 95 % interval row in the shown unit; None when not fitted (no row) or when the data do not
    bound that side (stored as null or infinite by ``fitting.interval``; the row's ``fitted`` tells the two apart)."""
    v = None if row is None else row.get(side)
    if v is None or not math.isfinite(float(v)):
        return None
    return float(v) * scale


def model_difference(model: dict) -> list[dict]:
    """The rows in which a diagnosis' final model differs from the book's rig.

    Parameters
    ----------
    model : dict
        The diagnosis JSON's ``model`` object: ``effects`` ({name: {param: value}} in the effects' units),
        ``beta`` (Pa), ``K`` (LPM/mA) and optionally ``ci95`` (list of ``{effect, param, value, low, high,
        unit}``; ``effect`` "baseline" for beta and K).

    Returns
    -------
    list of dict
        One row per difference: ``quantity`` (``beta``, ``K`` or ``effect.param``), ``words``, ``book`` (the
        book rig's value, None for an effect the book's rig does not have), ``value``, ``low``, ``high``
        (the 95 % interval, None when not fitted), ``unit`` and ``note`` (``not in force: replaced by ...``
        for a baseline value an effect sets; its value is then None).
    """
    from ehas_env.physics.effects import get_effect

    effects = model.get("effects") or {}
    ci = {(c["effect"], c["param"]): c for c in model.get("ci95") or []}
    replaced = {}
    for name in effects:
        for slot in replaced_slots(name):
            replaced.setdefault(slot, f"{name}.{slot}" if slot in effects[name] else name)
    rows = []
    for slot, words, unit, scale in BASELINE:
        book = _book(slot)
        value = model.get(slot)
        if slot in replaced:
            rows.append({"quantity": slot, "words": words, "book": book * scale, "value": None, "low": None,
                         "high": None, "unit": unit, "note": f"not in force: replaced by {replaced[slot]}"})
            continue
        if value is None or math.isclose(float(value), book, rel_tol=1e-9):
            continue
        c = ci.get(("baseline", slot))
        rows.append({"quantity": slot, "words": words, "book": book * scale, "value": float(value) * scale,
                     "low": _bound(c, "low", scale), "high": _bound(c, "high", scale), "fitted": c is not None,
                     "unit": unit, "note": f"{100 * (float(value) - book) / book:+.1f} % from the book's"})
    for name, params in effects.items():
        eff = get_effect(name)
        for p, v in params.items():
            c = ci.get((name, p))
            rows.append({"quantity": f"{name}.{p}", "words": eff.param(p).doc, "book": None, "value": float(v),
                         "low": _bound(c, "low"), "high": _bound(c, "high"), "fitted": c is not None,
                         "unit": eff.param(p).unit, "note": f"added: {eff.title}"})
    return rows


def interval_text(row: dict) -> str:
    """A difference row's 95 % interval as ``[low, high]`` (a side the data do not bound: ``unbounded``); ``""``
    when the value was not fitted.

    Parameters
    ----------
    row : dict
        A row of :func:`model_difference`.

    Returns
    -------
    str
    """
    if not row.get("fitted", row["low"] is not None):
        return ""
    side = ["unbounded" if v is None else f"{v:.5g}" for v in (row["low"], row["high"])]
    return f"[{side[0]}, {side[1]}]"


def difference_text(rows: list[dict], title: str = "final model") -> str:
    """The rows of :func:`model_difference` as console text, one line each.

    Parameters
    ----------
    rows : list of dict
        From :func:`model_difference`.
    title : str
        What the model is called in the heading.

    Returns
    -------
    str
    """
    lines = [f"{title}: what differs from the book's rig (fitted values, 95 % intervals; cluster-robust, on the "
             "fit data)"]
    if not rows:
        lines.append("  nothing: the book's rig as it is")
    for r in rows:
        book = "off" if r["book"] is None else f"{r['book']:.5g}"
        if r["value"] is None:
            lines.append(f"  {r['quantity']:<24}{book:>11} {r['unit']:<10} {r['note']}")
            continue
        ci = interval_text(r) and "  " + interval_text(r)
        lines.append(f"  {r['quantity']:<24}{book:>11} -> {r['value']:.5g} {r['unit']}{ci}  ({r['note']})")
    return "\n".join(lines)
