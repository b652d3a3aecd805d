"""Is what a diagnosis names physically the right kind of effect?

The diagnosis names two things (docs/measurement-format.md, "The diagnosis JSON"):
library effects it kept (``stack[].kept`` / ``model.effects``) and, when the
campaign stays unexplained, a proposed term: its ``terms[]`` each with a
``place`` (piston_force, crank_torque, chamber_flows, valve_current) and a
``coefficient`` (c_x, c_th, c_gb, ...); the effect file ``--write-effect``
writes carries the same places (its static methods) and parameter names.

Each named item is mapped to the physical kinds it stands for (:data:`LIBRARY_KIND`,
:data:`FORM_KIND`; a form may stand for two kinds, e.g. an extra flow gain into one
chamber is an unmatched valve land or an area mismatch).  The campaign's truth
has effects, each with the kinds it may be named as (:mod:`.effects`, ``accept``).
The verdict:

* **right kind**: every true effect is matched by at least one named item whose
  kinds meet its accepted kinds, and every named item meets the accepted kinds
  of some true effect (nothing of a wrong kind is named);
* for a campaign without effects (clean), nothing may be named;
* an item whose place or coefficient is not in the maps is of kind "unknown"
  and never right.
"""
from __future__ import annotations

import re
from pathlib import Path

from .effects import ALL

#: kinds of ehas's library effects (docs/reference-model.md, "Effects")
LIBRARY_KIND = {
    "coulomb_friction": {"friction"}, "viscous_friction": {"friction"}, "stribeck_friction": {"friction"},
    "internal_leakage": {"leakage/flow"}, "external_leakage": {"leakage/flow"},
    "valve_deadband": {"valve"}, "valve_null_bias": {"valve"}, "valve_dynamics": {"valve"},
    "transport_delay": {"command path"}, "supply_droop": {"leakage/flow"},
    "piston_mass": {"load"}, "backlash": {"compliance"}, "bulk_modulus": {"fluid property", "compliance"},
    # the diagnosis' structural hypotheses (ehas_env/physics/effects/hyp_*.py, kind "hypothesis")
    "hyp_rod_area": {"geometry/area"}, "hyp_return_pressure": {"leakage/flow"}, "hyp_direction_gain": {"valve"},
    "hyp_turbulent_leakage": {"leakage/flow"}, "hyp_pressure_friction": {"friction"},
    "hyp_quadratic_drag": {"friction"}, "hyp_crank_unbalance": {"load"}, "hyp_crank_spring": {"load"}, "hyp_supply_line_loss": {"leakage/flow"},
    "hyp_entrained_air": {"fluid property"}, "hyp_dead_volume": {"compliance", "fluid property"},
    "hyp_load_compliance": {"compliance"}, "hyp_valve_underlap": {"valve"}, "hyp_position_offset": {"sensor"},
    "hyp_position_shape": {"sensor"}, "hyp_lugre_friction": {"friction"}, "hyp_coil_lag": {"command path", "valve"},
    "hyp_crank_offset": {"geometry/area"},
}

#: kinds of the proposal's forms, "place.coefficient" (ehas_env/measurement/proposal_terms.py's dictionary as
#: docs/measurement-format.md lists it)
FORM_KIND = {
    "piston_force.c_x": {"load"},  # spring on the piston
    "piston_force.c_v": {"friction"},
    "piston_force.c_sv": {"friction"},
    "piston_force.c_1": {"load"},  # a constant force
    "piston_force.c_pa": {"geometry/area"},  # force per Pa of one chamber: an area error
    "piston_force.c_pb": {"geometry/area"},
    "piston_force.c_vv": {"friction"},  # quadratic damping
    "piston_force.c_x3": {"load"},
    "crank_torque.c_th": {"load"},
    "crank_torque.c_w": {"friction"},
    "crank_torque.c_sw": {"friction"},
    "crank_torque.c_1": {"load"},
    "crank_torque.c_th3": {"load"},
    "chamber_flows.c_ext": {"leakage/flow"},
    "chamber_flows.c_int": {"leakage/flow"},
    "chamber_flows.c_ret": {"leakage/flow"},  # return-line back-pressure
    "chamber_flows.c_sup": {"leakage/flow"},  # supply offset at the valve
    "chamber_flows.c_ga": {"valve", "geometry/area"},  # one side's flow gain: a land or an area
    "chamber_flows.c_gb": {"valve", "geometry/area"},
    "chamber_flows.c_gpos": {"valve"},  # flow gain by spool direction
    "chamber_flows.c_gneg": {"valve"},
    "valve_current.c_1": {"valve"},  # null bias
    "valve_current.c_i": {"valve"},  # gain
    "valve_current.c_abs": {"valve"},  # gain by direction
}
#: places alone, when a written effect file is read without the JSON
PLACE_KIND = {"piston_force": {"friction", "load", "geometry/area"}, "crank_torque": {"friction", "load"},
              "chamber_flows": {"leakage/flow", "valve", "geometry/area"}, "valve_current": {"valve"}}


def kept_effects(diag: dict) -> list[str]:
    """Library effects the diagnosis kept, in the order kept."""
    stack = diag.get("stack")
    if isinstance(stack, list) and stack:
        return [s.get("effect") for s in stack if s.get("kept")]
    model = diag.get("model") or {}
    if isinstance(model.get("effects"), dict):
        return list(model["effects"])
    rk = diag.get("ranking") or []
    return [rk[0]["effect"]] if rk and rk[0].get("effect") not in (None, "none") else []


def proposal(diag: dict) -> dict | None:
    un = diag.get("unexplained")
    if isinstance(un, dict) and isinstance(un.get("proposal"), dict):
        return un["proposal"]
    return None


def named_items(diag: dict) -> list[dict]:
    """What the diagnosis names: ``{"label", "kinds", "source"}`` per kept effect and proposed term."""
    items = []
    for name in kept_effects(diag):
        items.append({"label": name, "kinds": sorted(LIBRARY_KIND.get(name, {"unknown"})), "source": "library"})
    prop = proposal(diag)
    for term in (prop or {}).get("terms") or []:
        key = f"{term.get('place')}.{term.get('coefficient')}"
        items.append({"label": f"{key} ({term.get('form', '?')})", "kinds": sorted(FORM_KIND.get(key, {"unknown"})),
                      "source": "proposal"})
    return items


def effect_file_items(path) -> list[dict]:
    """Named items read from a written effect file's text (its places and parameter names); not imported."""
    text = Path(path).read_text()
    places = [p for p in PLACE_KIND if re.search(rf"def\s+{p}\s*\(", text)]
    params = re.findall(r"Param\(\s*[\"'](\w+)[\"']", text)
    items = []
    for place in places:
        keys = [f"{place}.{c}" for c in params if f"{place}.{c}" in FORM_KIND]
        kinds = set().union(*(FORM_KIND[k] for k in keys)) if keys else PLACE_KIND[place]
        items.append({"label": f"{place}({', '.join(params)})", "kinds": sorted(kinds), "source": "effect file"})
    return items


def judge(truth_effects: dict, items: list[dict]) -> dict:
    """Right kind?  See the module's docstring.

    Parameters
    ----------
    truth_effects : dict
        ``{name: params}`` hidden in the campaign.
    items : list of dict
        :func:`named_items`.

    Returns
    -------
    dict
        ``right_kind`` (bool), ``missed`` (true effects no item matches), ``wrong`` (items of no true kind),
        ``true_kinds``, ``named_kinds``.
    """
    accepted = {n: set(ALL[n].accepted_kinds) for n in truth_effects}
    missed = [n for n, acc in accepted.items() if not any(acc & set(it["kinds"]) for it in items)]
    union = set().union(*accepted.values()) if accepted else set()
    wrong = [it["label"] for it in items if not (set(it["kinds"]) & union)]
    return {"right_kind": not missed and not wrong, "missed": missed, "wrong": wrong,
            "true_kinds": {n: ALL[n].kind for n in truth_effects},
            "named_kinds": [{"label": it["label"], "kinds": it["kinds"]} for it in items]}
