"""A health trend over campaigns recorded weeks apart: parameters per campaign, and which changed (issue 33).

``ehas diagnose CAMP1 CAMP2 ...`` diagnoses each campaign on its own (:func:`ehas_env.diagnosis.pipeline.
diagnose_open`), then sets the final models' fitted parameters side by side, each with its 95 % interval, and
tests each parameter found in at least two campaigns with the chi-square test of one common value
(:func:`ehas_env.diagnosis.drift.differ`, the per-run test's, with its model-error floor): a parameter changed
when p < :data:`ehas_env.diagnosis.drift.DRIFT_P`; its size is the ratio of the last campaign's value to the
first's, in the order given.  An effect kept in some campaigns and not in others is said so.

Examples
--------
>>> rows = [{"effect": "coulomb_friction", "param": "Fc", "value": 300.0, "low": 290.0, "high": 310.0, "unit": "N"}]
>>> later = [{**rows[0], "value": 450.0, "low": 440.0, "high": 460.0}]
>>> t = trend([("week1", rows), ("week5", later)])
>>> t["changed"][0]["text"].split(" (")[0]
'coulomb_friction.Fc rises 1.5x from week1 to week5'
"""
from __future__ import annotations

from ehas_env.diagnosis.drift import DRIFT_P, differ


def trend(campaigns: list[tuple[str, list[dict]]]) -> dict:
    """Parameters per campaign and which changed.

    Parameters
    ----------
    campaigns : list of (name, rows)
        In the order recorded; ``rows`` the diagnosis JSON's ``model.ci95`` (``effect``, ``param``, ``value``,
        ``low``, ``high``, ``unit``).

    Returns
    -------
    dict
        ``campaigns`` (names), ``parameters`` {"effect.param": {"unit", "values": [value or None per campaign],
        "ci95": [[low, high] or None, ...]}}, ``changed`` [{parameter, unit, p_value, direction, first, last,
        ratio_first_last, text}], ``unchanged`` [parameter], ``only_in`` {parameter: [campaigns]}.
    """
    names = [n for n, _ in campaigns]
    params: dict[str, dict] = {}
    for k, (_, rows) in enumerate(campaigns):
        for r in rows:
            key = f"{r['effect']}.{r['param']}"
            p = params.setdefault(key, {"unit": r.get("unit", ""), "values": [None] * len(names),
                                        "ci95": [None] * len(names)})
            p["values"][k] = r["value"]
            p["ci95"][k] = [r["low"], r["high"]]
    changed, unchanged, only = [], [], {}
    for key, p in params.items():
        idx = [k for k, v in enumerate(p["values"]) if v is not None]
        if len(idx) < len(names):
            only[key] = [names[k] for k in idx]
        if len(idx) < 2:
            continue
        vals = [p["values"][k] for k in idx]
        pv, chi2, dof = differ(vals, [tuple(p["ci95"][k]) for k in idx])
        if pv >= DRIFT_P:
            unchanged.append(key)
            continue
        first, last = vals[0], vals[-1]
        ratio = last / first if first * last > 0 else None
        d = {"parameter": key, "unit": p["unit"], "p_value": float(f"{pv:.3g}"),
             "direction": "rises" if last > first else "falls", "first": first, "last": last,
             "ratio_first_last": None if ratio is None else round(ratio, 3),
             "from": names[idx[0]], "to": names[idx[-1]]}
        u = f" {p['unit']}" if p["unit"] and p["unit"] != "-" else ""
        size = f"{ratio:.2g}x" if ratio is not None and ratio >= 1 else (f"to {ratio:.2g}x" if ratio else
                                                                         f"by {last - first:+.3g}{u}")
        d["text"] = (f"{key} {d['direction']} {size} from {d['from']} to {d['to']} ({first:.4g} -> {last:.4g}{u}; "
                     f"the values differ beyond their 95 % intervals, p = {pv:.2g})")
        changed.append(d)
    return {"campaigns": names, "parameters": params, "changed": changed, "unchanged": unchanged, "only_in": only}


def trend_text(t: dict) -> str:
    """The trend as a table and sentences.

    Parameters
    ----------
    t : dict
        :func:`trend`'s result.

    Returns
    -------
    str
    """
    names = t["campaigns"]
    w = max([len("parameter")] + [len(k) for k in t["parameters"]]) + 2
    lines = ["health trend: the final model's parameters per campaign (95 % intervals)",
             "  " + "parameter".ljust(w) + "".join(n[:24].ljust(26) for n in names)]
    for key, p in t["parameters"].items():
        cells = []
        for v, ci in zip(p["values"], p["ci95"]):
            cells.append(("-" if v is None else f"{v:.4g} [{ci[0]:.4g}, {ci[1]:.4g}]").ljust(26))
        lines.append("  " + key.ljust(w) + "".join(cells) + (p["unit"] or ""))
    if not t["parameters"]:
        lines.append("  nothing fitted")
    for d in t["changed"]:
        lines.append("  changed: " + d["text"])
    if t["unchanged"]:
        lines.append("  unchanged within their intervals: " + ", ".join(t["unchanged"]))
    for key, where in t["only_in"].items():
        lines.append(f"  {key} only in {', '.join(where) or 'none'}")
    return "\n".join(lines)
