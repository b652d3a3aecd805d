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

For the group ``unlisted`` (:data:`.effects.UNLISTED`) the question is sharper:
**right place and right kind, named in physical words** (:func:`judge_place_kind`).
Items come with the places where they act and whether they are words or a bare
constant of a form (:func:`worded_items`): a kept library effect or structural
hypothesis (physical by construction; its place from :data:`LIBRARY_PLACE`), an
entry of the proposal's ``named`` list (its ``form`` judged here by
:data:`NAMED_FORM_KIND`, not by the package's own ``kind`` string, which is used
only where the place allows one kind alone or to choose among the place's kinds
when the form is not in the map), a disturbance the logged supply pressure carries
(the supply boundary), a logged supply pressure taken as a measured input (``measured_inputs``), and, when
there is no ``named`` list, the bare proposal terms
(right ingredients, but constants: never "in words").  :func:`honesty` records,
per case, the residual before and after, whether it closed, a recommended term too
weak to be written and a kept hypothesis that worsens the all-data residual.

For the drawn set (:mod:`.grammar`: blocks drawn as (place, kind, magnitude)) the same question is asked of
the grammar's places and block kinds (:func:`judge_blocks`): each worded item gets the block kinds its law stands
for (:data:`LIBRARY_BLOCK`, :data:`NAMED_FORM_BLOCK`, else the kinds' words) and the grammar's places it names
(its diagnosis place, narrowed to a side by words; the readings the diagnosis has no place for, by words).
"""
from __future__ import annotations

import re
from pathlib import Path

from .effects import ALL, PLACES

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
    # the state stage's generic augmentations (ehas_env/physics/augment.py), judged by what each is
    "aug_lag_coil": {"command path", "valve"}, "aug_slew_coil": {"command path"},
    "aug_lag_position_sensor": {"sensor"}, "aug_link_rod_crank": {"compliance"}, "aug_link_mount": {"compliance"},
    "aug_hose_a": {"compliance", "leakage/flow"}, "aug_hose_b": {"compliance", "leakage/flow"},
    "aug_hose_ab": {"compliance", "leakage/flow"},
    # a line volume behind a resistance at the valve's supply or return port: the line's drop R q at the lands
    "aug_line_supply": {"supply/return", "compliance"}, "aug_line_return": {"supply/return", "compliance"},
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
    "land_flows.c_ret": {"leakage/flow", "supply/return"},  # return-line back-pressure
    "land_flows.c_sup": {"leakage/flow", "supply/return"},  # supply offset at the valve
    "land_flows.c_ga": {"valve", "geometry/area"},  # one side's flow gain: a land or an area
    "land_flows.c_gb": {"valve", "geometry/area"},
    "land_flows.c_gpos": {"valve"},  # flow gain by spool direction
    "land_flows.c_gneg": {"valve"},
    "valve_current.c_1": {"valve"},  # null bias
    "valve_current.c_i": {"valve"},  # gain
    "valve_current.c_abs": {"valve"},  # gain by direction
}
# the proposal's newer coefficients (ehas_env/measurement/proposal_terms.py), judged here by their law
FORM_KIND.update({
    "piston_force.c_x2sv": {"friction"}, "piston_force.c_x2v": {"friction"}, "piston_force.c_plsv": {"friction"},
    "piston_force.c_x2": {"load"}, "crank_torque.c_th2sw": {"friction"}, "crank_torque.c_jsw": {"friction"},
    "chamber_flows.c_intsq": {"leakage/flow"}, "land_flows.c_gpl": {"valve"},
    "land_flows.c_rline": {"leakage/flow", "compliance"}, "land_flows.c_lam": {"valve", "fluid property"},
    "land_flows.c_rsup": {"supply/return", "leakage/flow"},
    "land_flows.c_rsup2": {"supply/return", "leakage/flow"},
    "valve_current.c_i3": {"command path"}, "valve_current.c_sgn": {"valve", "command path"},
    "position_reading.c_1": {"sensor"}, "position_reading.c_x": {"sensor"}, "position_reading.c_x2": {"sensor"},
    "position_reading.c_x3": {"sensor"},
})
# the grammar's atoms beyond those (ehas_env/physics/term_grammar.py), judged by their law: a viscous level that
# rises with a load or an angle, the crank's quadratic drag and load toward both ends, a turbulent leak to drain,
# a bow of the command path
FORM_KIND.update({
    "piston_force.c_plv": {"friction"}, "crank_torque.c_th2": {"load"}, "crank_torque.c_ww": {"friction"},
    "crank_torque.c_th2w": {"friction"}, "crank_torque.c_jw": {"friction"}, "chamber_flows.c_extsq": {"leakage/flow"},
    "valve_current.c_i2": {"valve", "command path"},
})
#: coefficients that act on a boundary of the lands rather than on the chambers' flows
COEF_PLACE = {"c_sup": "supply", "c_rsup": "supply", "c_rsup2": "supply", "c_ret": "return"}

#: the named physical forms (the proposal's ``named[].form``, helper B's ehas_env/diagnosis/naming.py FORMS as
#: listed in /tmp/helpers/B-forms.txt), each judged here by its law: the kinds it stands for
NAMED_FORM_KIND = {
    "piston_force.coulomb": {"friction"}, "piston_force.viscous": {"friction"},
    "piston_force.friction_x2": {"friction"},  # F = -(F_0 + k x^2) sign(v): friction varying along the stroke
    "piston_force.viscous_x2": {"friction"},  # F = -(b_0 + b_2 x^2) v: a damping rising toward the ends
    "piston_force.friction_load": {"friction"},  # F = -(F_0 + a |P_L|) sign(v)
    "piston_force.quadratic_drag": {"friction"},  # F = -d v|v|: a dissipative drag (disc_drag is friction too)
    "piston_force.spring": {"load"}, "piston_force.hardening_spring": {"load"}, "piston_force.constant": {"load"},
    "piston_force.load_x2": {"load"},
    "piston_force.area_ab": {"geometry/area"}, "piston_force.area_b": {"geometry/area"},
    "crank_torque.coulomb": {"friction"}, "crank_torque.viscous": {"friction"},
    "crank_torque.friction_angle": {"friction"}, "crank_torque.joint_friction": {"friction"},
    "crank_torque.spring": {"load"}, "crank_torque.hardening_spring": {"load"}, "crank_torque.constant": {"load"},
    "chamber_flows.leak_drain": {"leakage/flow"}, "chamber_flows.leak_across": {"leakage/flow"},
    "chamber_flows.leak_across_turbulent": {"leakage/flow"},
    "chamber_flows.gain_by_direction": {"valve"}, "chamber_flows.gain_by_port": {"valve", "geometry/area"},
    "chamber_flows.gain_load": {"valve"},  # q (1 - c |P_L| / P_S): a flow gain falling with the load pressure
    "chamber_flows.line_resistance": {"leakage/flow", "compliance"},  # a drop R q in the line to the chamber
    "chamber_flows.metering_law": {"valve"},  # q ~ sqrt(drop)(1 + c (sqrt(drop/(P_S/2)) - 1)): the lands' own law
    "supply.offset": {"supply/return"}, "supply.line_drop": {"supply/return", "leakage/flow"},
    "supply.line_drop_turbulent": {"supply/return", "leakage/flow"},
    "return.back_pressure": {"supply/return", "leakage/flow"},
    "valve_current.bias": {"valve", "command path"}, "valve_current.gain": {"command path", "valve"},
    "valve_current.gain_by_direction": {"valve"}, "valve_current.saturation": {"command path"},
    "valve_current.dead_band": {"valve", "command path"},
    "position_reading.offset": {"sensor"}, "position_reading.gain": {"sensor"}, "position_reading.bow": {"sensor"},
    "position_reading.cubic": {"sensor"},
    # the grammar's named forms beyond those (ehas_env/physics/term_grammar.py: named_forms), by their law
    "piston_force.viscous_load": {"friction"},  # F = -(b_0 + k |P_L|) v
    "piston_force.area_a": {"geometry/area"},
    "crank_torque.load_th2": {"load"}, "crank_torque.quadratic_drag": {"friction"},
    "crank_torque.friction_joint": {"friction"},  # T = -(T_0 + k |P_L| r |cos theta|) sign(omega)
    "crank_torque.viscous_angle": {"friction"}, "crank_torque.viscous_joint": {"friction"},
    "chamber_flows.leak_drain_turbulent": {"leakage/flow"},
    "valve_current.offset": {"valve", "command path"}, "valve_current.bow": {"command path", "valve"},
    "valve_current.expansion": {"command path"},
    "position_reading.saturation": {"sensor"}, "position_reading.expansion": {"sensor"},
}
#: the package's place names (and spellings it has used) -> the generator's (:data:`.effects.PLACES`)
PLACE_ALIAS = {**{p: p for p in PLACES}, "land_flows": "chamber_flows", "chamber_flow": "chamber_flows",
               "metering": "chamber_flows", "hydraulic_lines": "chamber_flows", "lines": "chamber_flows",
               "command": "valve_current", "command_path": "valve_current", "current": "valve_current",
               "supply_pressure": "supply", "return_pressure": "return", "position": "position_reading",
               "position_sensor": "position_reading", "theta": "position_reading", "sensor": "position_reading"}
#: kinds a term at a place can stand for (for a named form not in :data:`NAMED_FORM_KIND`)
PLACE_KINDS = {"valve_current": {"valve", "command path"}, "coil_current": {"command path", "valve"},
               "chamber_flows": {"leakage/flow", "valve", "geometry/area", "compliance", "fluid property"},
               "piston_force": {"friction", "load", "geometry/area"}, "crank_torque": {"friction", "load"},
               "supply": {"supply/return"}, "return": {"supply/return"}, "position_reading": {"sensor"}}
#: where each library effect and structural hypothesis acts
LIBRARY_PLACE = {
    "coulomb_friction": {"piston_force"}, "viscous_friction": {"piston_force"}, "stribeck_friction": {"piston_force"},
    "internal_leakage": {"chamber_flows"}, "external_leakage": {"chamber_flows"},
    "valve_deadband": {"valve_current"}, "valve_null_bias": {"valve_current"}, "valve_dynamics": {"coil_current"},
    "transport_delay": {"valve_current"}, "supply_droop": {"supply"}, "piston_mass": {"piston_force"},
    "backlash": {"piston_force", "crank_torque"}, "bulk_modulus": {"chamber_flows"},
    "hyp_rod_area": {"piston_force", "chamber_flows"}, "hyp_return_pressure": {"return"},
    "hyp_direction_gain": {"chamber_flows", "valve_current"}, "hyp_turbulent_leakage": {"chamber_flows"},
    "hyp_pressure_friction": {"piston_force"}, "hyp_quadratic_drag": {"crank_torque"},
    "hyp_crank_unbalance": {"crank_torque"}, "hyp_crank_spring": {"crank_torque"}, "hyp_supply_line_loss": {"supply"},
    "hyp_entrained_air": {"chamber_flows"}, "hyp_dead_volume": {"chamber_flows"},
    "hyp_load_compliance": {"piston_force", "crank_torque"}, "hyp_valve_underlap": {"chamber_flows"},
    "hyp_position_offset": {"position_reading"}, "hyp_position_shape": {"position_reading"},
    "hyp_lugre_friction": {"piston_force"}, "hyp_coil_lag": {"coil_current", "valve_current"},
    "hyp_crank_offset": {"crank_torque", "position_reading"},
    "aug_lag_coil": {"coil_current", "valve_current"}, "aug_slew_coil": {"coil_current", "valve_current"},
    "aug_lag_position_sensor": {"position_reading"}, "aug_link_rod_crank": {"piston_force", "crank_torque"}, "aug_link_mount": {"piston_force"},
    "aug_hose_a": {"chamber_flows"}, "aug_hose_b": {"chamber_flows"}, "aug_hose_ab": {"chamber_flows"},
    "aug_line_supply": {"supply"}, "aug_line_return": {"return"},
}
#: ehas's reading places (ehas_env.physics.layout.SENSED: aug_<kind>_<output>_reading) -> the grammar's place (the
#: supply pressure's reading stands for the supply, which the grammar has no reading of)
READING_PLACE = {"pa": "pressure_reading_a", "pb": "pressure_reading_b", "ps": "supply", "flow_a": "flow_reading",
                 "force": "load_reading"}
#: ehas's generated block kinds (the stem of aug_<kind>_<place>) -> the grammar's kind
STEM_BLOCK = {"lag": "lag", "slew": "rate_limit", "offset": "offset", "gain": "gain", "sat": "saturation",
              "dz": "dead_zone", "delay": "delay", "play": "play",
              "knee": "piecewise_linear", "bend": "smooth"}
# the state stage's generated blocks (ehas_env/physics/augment.py, aug_<kind>_<place>): a follower or a static
# block at the position sensor's or at another sensor's reading is a sensor's, at that reading; one in the valve's
# current path (command to coil) is the command path's, there, as the coil's lag is
for _stem in STEM_BLOCK:
    LIBRARY_KIND.setdefault(f"aug_{_stem}_coil", {"command path", "valve"})
    LIBRARY_PLACE.setdefault(f"aug_{_stem}_coil", {"coil_current", "valve_current"})
    LIBRARY_KIND.setdefault(f"aug_{_stem}_position_sensor", {"sensor"})
    LIBRARY_PLACE.setdefault(f"aug_{_stem}_position_sensor", {"position_reading"})
    for _out, _place in READING_PLACE.items():
        LIBRARY_KIND[f"aug_{_stem}_{_out}_reading"] = {"sensor"}
        LIBRARY_PLACE[f"aug_{_stem}_{_out}_reading"] = {_place}
#: ehas's static terms at a balance (ehas_env/physics/balance_blocks.py, aug_<kind>_<place>): the stem -> the grammar's
#: kind, the place -> ehas's place (the side narrowed by the words: "chamber A's flow balance")
BALANCE_STEM_BLOCK = {"const": "offset", "prop": "gain", "beyond": "dead_zone", "saturating": "saturation",
                      "cubic": "smooth", "knee": "piecewise_linear"}
BALANCE_PLACE = {"piston_velocity": ("piston_force", "friction"), "crank_rate": ("crank_torque", "friction"),
                 "chamber_a": ("chamber_flows", "leakage/flow"), "chamber_b": ("chamber_flows", "leakage/flow"),
                 "supply": ("supply", "supply/return"), "return": ("return", "supply/return"),
                 "land_a": ("chamber_flows", "leakage/flow"), "land_b": ("chamber_flows", "leakage/flow"),
                 # the balances with their other local quantities (balance_blocks.OTHER_LOCALS)
                 "piston_position": ("piston_force", "load"), "piston_load_pressure": ("piston_force", "friction"),
                 "crank_angle": ("crank_torque", "load"),
                 "chamber_a_load_pressure": ("chamber_flows", "leakage/flow"),
                 "chamber_b_load_pressure": ("chamber_flows", "leakage/flow"),
                 "chamber_a_velocity": ("chamber_flows", "leakage/flow"),
                 "chamber_b_velocity": ("chamber_flows", "leakage/flow")}
for _stem in BALANCE_STEM_BLOCK:
    for _short, (_place, _kind) in BALANCE_PLACE.items():
        LIBRARY_KIND[f"aug_{_stem}_{_short}"] = {_kind, "load"} if _kind == "friction" else {_kind}
        LIBRARY_PLACE[f"aug_{_stem}_{_short}"] = {_place}
#: words of the package's own kind strings -> kinds (used only to choose among a place's kinds)
KIND_WORDS = (("fric", "friction"), ("damp", "friction"), ("leak", "leakage/flow"), ("flow", "leakage/flow"),
              ("compli", "compliance"), ("area", "geometry/area"), ("geometr", "geometry/area"),
              ("valve", "valve"), ("sensor", "sensor"), ("command", "command path"), ("load", "load"),
              ("fluid", "fluid property"), ("supply", "supply/return"), ("return", "supply/return"))

#: places alone, when a written effect file is read without the JSON
PLACE_KIND = {"piston_force": {"friction", "load", "geometry/area"}, "crank_torque": {"friction", "load"},
              "chamber_flows": {"leakage/flow", "valve", "geometry/area"}, "valve_current": {"valve"},
              "land_flows": {"leakage/flow", "valve", "geometry/area", "supply/return"},
              "position_reading": {"sensor"}}


def form_kinds(place, coefficient) -> set | None:
    """Kinds of the proposal form ``place.coefficient`` (:data:`FORM_KIND`; the lands' coefficients were
    listed under ``chamber_flows`` before the package gave them their own place, ``land_flows``); None if unknown."""
    key = f"{place}.{coefficient}"
    if key in FORM_KIND:
        return set(FORM_KIND[key])
    other = {"chamber_flows": "land_flows", "land_flows": "chamber_flows"}.get(str(place))
    return set(FORM_KIND[f"{other}.{coefficient}"]) if other and f"{other}.{coefficient}" in FORM_KIND else None


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
        items.append({"label": f"{key} ({term.get('form', '?')})",
                      "kinds": sorted(form_kinds(term.get("place"), term.get("coefficient")) or {"unknown"}),
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


def canonical_place(place) -> str | None:
    """The generator's name of a place the package names (``land_flows`` -> ``chamber_flows``); None if unknown."""
    return PLACE_ALIAS.get(str(place or "").strip().lower())


def claimed_kinds(text) -> set:
    """The kinds the package's own ``kind`` string claims (by its words)."""
    t = str(text or "").lower()
    return {k for w, k in KIND_WORDS if w in t}


def named_entry_kinds(entry: dict) -> set:
    """The kinds of one entry of the proposal's ``named`` list, judged by its form and place.

    The form (``named[].form``, ``place.name``) in :data:`NAMED_FORM_KIND` decides; else the coefficients it sets
    (``params``' keys as ``place.coefficient`` in :data:`FORM_KIND`); else the place when it allows one kind only;
    else the package's ``kind`` among the place's kinds; else ``{"unknown"}``.
    """
    place = canonical_place(entry.get("place"))
    form = str(entry.get("form") or "")
    if form in NAMED_FORM_KIND:
        return set(NAMED_FORM_KIND[form])
    found = set().union(set(), *(form_kinds(place, k) or set() for k in (entry.get("params") or {})))
    if found:
        return found
    allowed = PLACE_KINDS.get(place, set())
    if len(allowed) == 1:
        return set(allowed)
    chosen = claimed_kinds(entry.get("kind")) & allowed
    return chosen or {"unknown"}


def states_kept(diag: dict) -> list[str]:
    """Augmentations the state stage kept: ``stages[]`` records (or their ``states``) whose ``kept`` is a name, unless
    the final stack reports it not kept in the end (a later stage set it aside and the final model lacks it), and
    ``aug_*`` effects of the final model."""
    final = (diag.get("model") or {}).get("effects") or {}  # the final model's effects, in its order
    dropped = {str(e.get("effect")) for e in diag.get("stack") or [] if isinstance(e, dict) and e.get("kept") is False}
    names = []
    for st in diag.get("stages") or []:
        for rec in ((st, st.get("states"), *(st.get("more") or [])) if isinstance(st, dict) else ()):
            if isinstance(rec, dict) and isinstance(rec.get("kept"), str) and rec["kept"].startswith("aug_"):
                if rec["kept"] in dropped and rec["kept"] not in final:
                    continue
                names.append(rec["kept"])
    names += [n for n in final if str(n).startswith("aug_")]
    return list(dict.fromkeys(names))


def named_item(name: str, source: str) -> dict:
    """An item named by its effect's name: its kinds and places (:data:`LIBRARY_KIND`, :data:`LIBRARY_PLACE`), in
    words when the judge knows the effect."""
    return {"label": name, "kinds": sorted(LIBRARY_KIND.get(name, {"unknown"})),
            "places": sorted(LIBRARY_PLACE.get(name, set())), "words": name in LIBRARY_KIND, "source": source}


def worded_items(diag: dict) -> list[dict]:
    """What the diagnosis names, with places and whether it is said in physical words.

    Returns
    -------
    list of dict
        ``label``, ``kinds`` (sorted list), ``places`` (sorted list of :data:`.effects.PLACES`), ``words`` (bool),
        ``source`` (library, hypothesis, named, disturbance, proposal).
    """
    items = [named_item(name, "hypothesis" if name.startswith("hyp_") else "library") for name in kept_effects(diag)]
    for name in states_kept(diag):
        if name not in {i["label"] for i in items}:
            items.append(named_item(name, "state"))
    hyp = diag.get("hypothesis")
    if isinstance(hyp, dict) and hyp.get("effect") and hyp["effect"] not in {i["label"] for i in items}:
        items.append(named_item(hyp["effect"], "hypothesis"))
    prop = proposal(diag) or {}
    named = prop.get("named")
    if isinstance(named, list) and named:
        for e in named:
            place = canonical_place(e.get("place"))
            items.append({"label": f"{e.get('form') or e.get('place')}: {e.get('words') or e.get('law') or ''}"[:160],
                          "kinds": sorted(named_entry_kinds(e)), "places": [place] if place else [],
                          "words": bool(str(e.get("words") or "").strip()), "source": "named"})
    else:
        for term in prop.get("terms") or []:
            coef = term.get("coefficient")
            place = COEF_PLACE.get(coef) or canonical_place(term.get("place"))
            items.append({"label": f"{term.get('place')}.{coef} ({term.get('form', '?')})",
                          "kinds": sorted(form_kinds(term.get("place"), coef) or {"unknown"}),
                          "places": [place] if place else [],
                          "words": False, "source": "proposal"})
    # a logged quantity the diagnosis took as a measured input (the supply pressure: the measured_inputs stage,
    # whose record says it in words)
    for q in diag.get("measured_inputs") or []:
        rec = next((r for r in diag.get("stages") or [] if r.get("stage") == "measured_inputs"), {})
        if q == "p_s_bar":
            items.append({"label": f"supply pressure as a measured input: {rec.get('text', '')}"[:160],
                          "kinds": ["supply/return"], "places": ["supply"], "words": True, "source": "measured input"})
    for d in diag.get("disturbances") or []:
        if isinstance(d, dict) and d.get("boundary"):
            items.append({"label": f"supply disturbance {d.get('frequency_hz')} Hz: {d.get('text', '')}"[:160],
                          "kinds": ["supply/return"], "places": ["supply"], "words": True, "source": "disturbance"})
    return items


def truth_places(name: str) -> set:
    """Places where a hidden effect may rightly be named: its own (``places``), a library effect's, else any."""
    spec = ALL[name]
    return set(spec.places) or set(LIBRARY_PLACE.get(name, ())) or set(PLACES)


def judge_place_kind(truth_effects: dict, items: list[dict]) -> dict:
    """Right place and right kind, named in physical words?

    Parameters
    ----------
    truth_effects : dict
        ``{name: params}`` hidden in the campaign.
    items : list of dict
        :func:`worded_items`.

    Returns
    -------
    dict
        ``right`` (bool: every hidden effect is matched by one worded item of an accepted kind at an accepted place,
        and no worded item is of a kind no hidden effect has), ``per_effect`` {name: {"right_kind", "right_place",
        "right_kind_any_form"}} (the last counting bare proposal constants too), ``wrong`` (labels), ``items``.
    """
    per = {}
    worded = [it for it in items if it["words"]]
    for n in truth_effects:
        acc, places = set(ALL[n].accepted_kinds), truth_places(n)
        kind_ok = [it for it in worded if acc & set(it["kinds"])]
        per[n] = {"right_kind": bool(kind_ok),
                  "right_place": any(places & set(it["places"]) for it in kind_ok),
                  "right_kind_any_form": any(acc & set(it["kinds"]) for it in items)}
    union = set().union(*(set(ALL[n].accepted_kinds) for n in truth_effects)) if truth_effects else set()
    wrong = [it["label"] for it in worded if not (set(it["kinds"]) & union)]
    right = all(v["right_kind"] and v["right_place"] for v in per.values()) and not wrong
    return {"right": right, "per_effect": per, "wrong": wrong,
            "items": [{k: it[k] for k in ("label", "kinds", "places", "words", "source")} for it in items]}


#: a term is too weak to be recommended when its refit removes less than this share of the excess over noise
WEAK_TERM_SHARE = 0.10
#: the residual is closed when at most this many times the noise ...
CLOSED_X_NOISE = 2.0
#: ... and at least this share below the baseline's
CLOSED_BELOW_BASELINE = 0.20


def _num(x):
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else None


def honesty(diag: dict, baseline, final) -> dict:
    """Per case: the residual before and after, closed?, a weak recommended term?, a worsening kept hypothesis?

    Parameters
    ----------
    diag : dict
        The diagnosis JSON.
    baseline : float or None
        Residual x noise of the recalibrated baseline (the model with no effect, beta and K fitted).
    final : float or None
        Residual x noise of the diagnosis' final model (with its recommended term, when one is).

    Returns
    -------
    dict
        ``baseline``, ``final``, ``closed`` (final <= :data:`CLOSED_X_NOISE` and at least
        :data:`CLOSED_BELOW_BASELINE` below the baseline; None when a figure is missing), ``weak_term`` (a proposal
        is recommended whose refit on all data removes less than :data:`WEAK_TERM_SHARE` of the excess over noise),
        ``term_share`` (that share), ``worsening_hypothesis`` (a structural hypothesis is kept and the all-data
        residual is above the bare library model's), ``library_residual`` (that model's).
    """
    b, f = _num(baseline), _num(final)
    closed = None if b is None or f is None else (f <= CLOSED_X_NOISE and f <= (1.0 - CLOSED_BELOW_BASELINE) * b)
    prop = proposal(diag)
    share = None
    if prop:
        v = prop.get("validation") or {}
        before = _num(v.get("residual_x_noise_all_before", prop.get("residual_x_noise_before")))
        after = _num(v.get("residual_x_noise_all_after", prop.get("residual_x_noise_after")))
        if before is not None and after is not None:
            share = (before - after) / (before - 1.0) if before > 1.0 else 0.0
    weak = (None if share is None else share < WEAK_TERM_SHARE) if prop else False
    hyps = [k for k in kept_effects(diag) if k.startswith("hyp_")]
    if isinstance(diag.get("hypothesis"), dict) and diag["hypothesis"].get("effect"):
        hyps = sorted(set(hyps) | {diag["hypothesis"]["effect"]})
    lib = _num((diag.get("validation") or {}).get("residual_x_noise_before_hypotheses"))
    if lib is None and isinstance(diag.get("hypothesis"), dict):
        lib = _num(diag["hypothesis"].get("residual_x_noise_before"))
    all_data = _num(diag.get("residual_x_noise"))
    worse = bool(hyps) and lib is not None and all_data is not None and all_data > lib
    return {"baseline": b, "final": f, "closed": closed, "weak_term": weak,
            "term_share": None if share is None else round(share, 4), "worsening_hypothesis": worse,
            "hypotheses_kept": hyps, "library_residual": lib}


# -- the drawn set (tests/independent_rig/grammar.py): right place and right kind of a block ------------------------
#: the block kinds (grammar.KINDS) each library effect, structural hypothesis and state of the diagnosis stands for,
#: by its law: a Coulomb friction is a saturating force of the velocity, a viscous one a term linear in it, a
#: coil lag a first-order lag of the coil current, a hose a line volume behind a resistance, the valve's dynamics its
#: second-order follower and its flow gain K (a gain in the command path: the logs cannot tell it from the coil's)
LIBRARY_BLOCK = {
    "coulomb_friction": {"saturation"}, "viscous_friction": {"gain"}, "stribeck_friction": {"saturation", "smooth"},
    "internal_leakage": {"gain"}, "external_leakage": {"gain"}, "valve_deadband": {"dead_zone"},
    "valve_null_bias": {"offset"}, "valve_dynamics": {"lag", "gain"}, "transport_delay": {"delay"},
    "supply_droop": {"volume"}, "piston_mass": {"compliance"}, "backlash": {"play", "compliance"},
    "bulk_modulus": {"volume"},
    "hyp_rod_area": {"gain"}, "hyp_return_pressure": {"offset"}, "hyp_direction_gain": {"piecewise_linear", "gain"},
    "hyp_turbulent_leakage": {"smooth"}, "hyp_pressure_friction": {"saturation"}, "hyp_quadratic_drag": {"smooth"},
    "hyp_crank_unbalance": {"smooth", "offset"}, "hyp_crank_spring": {"gain"}, "hyp_supply_line_loss": {"smooth"},
    "hyp_entrained_air": {"volume"}, "hyp_dead_volume": {"volume"}, "hyp_load_compliance": {"compliance"},
    "hyp_valve_underlap": {"dead_zone"}, "hyp_position_offset": {"offset"}, "hyp_position_shape": {"smooth"},
    "hyp_lugre_friction": {"saturation"}, "hyp_coil_lag": {"lag"}, "hyp_crank_offset": {"offset"},
    "aug_lag_coil": {"lag"}, "aug_slew_coil": {"rate_limit"}, "aug_lag_position_sensor": {"lag"},
    "aug_link_rod_crank": {"compliance"}, "aug_link_mount": {"compliance"}, "aug_hose_a": {"volume"},
    "aug_hose_b": {"volume"}, "aug_hose_ab": {"volume"}, "aug_line_supply": {"volume"}, "aug_line_return": {"volume"},
}
for _stem, _kind in STEM_BLOCK.items():  # every generated block at every place ehas has
    for _place in ("coil", "position_sensor", *(f"{o}_reading" for o in READING_PLACE)):
        LIBRARY_BLOCK.setdefault(f"aug_{_stem}_{_place}", {_kind})
for _stem, _kind in BALANCE_STEM_BLOCK.items():
    for _short in BALANCE_PLACE:
        LIBRARY_BLOCK.setdefault(f"aug_{_stem}_{_short}", {_kind})
#: the block kinds of the proposal's named forms (:data:`NAMED_FORM_KIND`'s keys), by their law
NAMED_FORM_BLOCK = {
    "piston_force.coulomb": {"saturation"}, "piston_force.viscous": {"gain"}, "piston_force.friction_x2": {"smooth"},
    "piston_force.viscous_x2": {"smooth"}, "piston_force.friction_load": {"saturation"},
    "piston_force.quadratic_drag": {"smooth"}, "piston_force.spring": {"gain"},
    "piston_force.hardening_spring": {"smooth"}, "piston_force.constant": {"offset"},
    "piston_force.load_x2": {"smooth"},
    "piston_force.area_ab": {"gain"}, "piston_force.area_b": {"gain"},
    "crank_torque.coulomb": {"saturation"}, "crank_torque.viscous": {"gain"},
    "crank_torque.friction_angle": {"saturation"}, "crank_torque.joint_friction": {"saturation"},
    "crank_torque.spring": {"gain"}, "crank_torque.hardening_spring": {"smooth"}, "crank_torque.constant": {"offset"},
    "chamber_flows.leak_drain": {"gain"}, "chamber_flows.leak_across": {"gain"},
    "chamber_flows.leak_across_turbulent": {"smooth"}, "chamber_flows.gain_by_direction": {"piecewise_linear"},
    "chamber_flows.gain_by_port": {"gain"}, "chamber_flows.gain_load": {"gain"},
    "chamber_flows.line_resistance": {"volume"}, "chamber_flows.metering_law": {"smooth"},
    "supply.offset": {"offset"}, "supply.line_drop": {"gain"}, "supply.line_drop_turbulent": {"smooth"},
    "return.back_pressure": {"offset"},
    "valve_current.bias": {"offset"}, "valve_current.gain": {"gain"},
    "valve_current.gain_by_direction": {"piecewise_linear"}, "valve_current.saturation": {"saturation"},
    "valve_current.dead_band": {"dead_zone"},
    "position_reading.offset": {"offset"}, "position_reading.gain": {"gain"}, "position_reading.bow": {"smooth"},
    "position_reading.cubic": {"smooth"},
    "piston_force.viscous_load": {"smooth"}, "piston_force.area_a": {"gain"}, "crank_torque.load_th2": {"smooth"},
    "crank_torque.quadratic_drag": {"smooth"}, "crank_torque.friction_joint": {"saturation"},
    "crank_torque.viscous_angle": {"smooth"}, "crank_torque.viscous_joint": {"smooth"},
    "chamber_flows.leak_drain_turbulent": {"smooth"}, "valve_current.offset": {"offset"},
    "valve_current.bow": {"smooth"}, "valve_current.expansion": {"smooth"},
    "position_reading.saturation": {"saturation"}, "position_reading.expansion": {"smooth"},
}
#: the block kinds of the proposal's bare terms (:data:`FORM_KIND`'s keys), for "the right kind among any form"
FORM_BLOCK = {
    "piston_force.c_x": {"gain"}, "piston_force.c_v": {"gain"}, "piston_force.c_sv": {"saturation"},
    "piston_force.c_1": {"offset"}, "piston_force.c_pa": {"gain"}, "piston_force.c_pb": {"gain"},
    "piston_force.c_vv": {"smooth"}, "piston_force.c_x3": {"smooth"}, "crank_torque.c_th": {"gain"},
    "crank_torque.c_w": {"gain"}, "crank_torque.c_sw": {"saturation"}, "crank_torque.c_1": {"offset"},
    "crank_torque.c_th3": {"smooth"}, "chamber_flows.c_ext": {"gain"}, "chamber_flows.c_int": {"gain"},
    "land_flows.c_ret": {"offset"}, "land_flows.c_sup": {"offset"}, "land_flows.c_ga": {"gain"},
    "land_flows.c_gb": {"gain"}, "land_flows.c_gpos": {"piecewise_linear"}, "land_flows.c_gneg": {"piecewise_linear"},
    "valve_current.c_1": {"offset"}, "valve_current.c_i": {"gain"}, "valve_current.c_abs": {"piecewise_linear"},
    "piston_force.c_x2sv": {"smooth"}, "piston_force.c_x2v": {"smooth"}, "piston_force.c_plsv": {"saturation"},
    "piston_force.c_x2": {"smooth"}, "crank_torque.c_th2sw": {"smooth"}, "crank_torque.c_jsw": {"saturation"},
    "chamber_flows.c_intsq": {"smooth"}, "land_flows.c_gpl": {"gain"}, "land_flows.c_rline": {"volume"},
    "land_flows.c_lam": {"smooth"}, "land_flows.c_rsup": {"gain"}, "land_flows.c_rsup2": {"smooth"},
    "valve_current.c_i3": {"smooth"}, "valve_current.c_sgn": {"dead_zone", "offset"},
    "position_reading.c_1": {"offset"}, "position_reading.c_x": {"gain"}, "position_reading.c_x2": {"smooth"},
    "position_reading.c_x3": {"smooth"},
    "piston_force.c_plv": {"smooth"}, "crank_torque.c_th2": {"smooth"}, "crank_torque.c_ww": {"smooth"},
    "crank_torque.c_th2w": {"smooth"}, "crank_torque.c_jw": {"smooth"}, "chamber_flows.c_extsq": {"smooth"},
    "valve_current.c_i2": {"smooth"},
}
#: words that name one side of the actuator (a chamber, its port, land, hose or pressure reading)
SIDE_WORDS = {"a": r"\b(chamber|port|land|side|hose|line|reading|p)[\s_]+a\b",
              "b": r"\b(chamber|port|land|side|hose|line|reading|p)[\s_]+b\b"}


def _grammar():
    from . import grammar  # the grammar imports the generator's campaign writer: read when the drawn set is judged

    return grammar


def block_kinds_of(item: dict) -> set:
    """The block kinds a named item stands for: by its effect's name (:data:`LIBRARY_BLOCK`), its form
    (:data:`NAMED_FORM_BLOCK`, :data:`FORM_BLOCK`), else by the words of its label (each kind's ``pattern``)."""
    label = str(item.get("label") or "")
    if label in LIBRARY_BLOCK:
        return set(LIBRARY_BLOCK[label])
    head = label.split(":")[0].split(" (")[0].strip()
    for table in (NAMED_FORM_BLOCK, FORM_BLOCK):
        if head in table:
            return set(table[head])
    if head.replace("chamber_flows.", "land_flows.") in FORM_BLOCK:
        return set(FORM_BLOCK[head.replace("chamber_flows.", "land_flows.")])
    text = label.lower()
    return {k.name for k in _grammar().KINDS.values() if re.search(k.pattern, text)}


def grammar_places_of(item: dict) -> set:
    """The grammar's places a named item names: those its diagnosis places stand for (``Place.diag``), and, for the
    readings the diagnosis has no place for (or an item with no known place), those its words name (the place's name
    or ``pattern``); narrowed to one side when its words name that side only (:data:`SIDE_WORDS`)."""
    g = _grammar()
    text = str(item.get("label") or "").lower()
    diag = set(item.get("places") or ())
    found = {p.name for p in g.PLACES.values() if diag & set(p.diag)}
    for p in g.PLACES.values():
        if (p.where == "sampled" or not diag) and re.search(rf"{re.escape(p.name)}|{p.pattern}", text):
            found.add(p.name)
    sides = {s for s, w in SIDE_WORDS.items() if re.search(w, text)}
    if len(sides) == 1:
        other = ({"a", "b"} - sides).pop()
        found = {n for n in found if g.PLACES[n].side != other}
    return found


def block_items(diag: dict) -> list[dict]:
    """:func:`worded_items`, each with its block kinds (``block_kinds``) and grammar places (``grammar_places``)."""
    return [_with_blocks(it) for it in worded_items(diag)]


def _with_blocks(item: dict) -> dict:
    """``item`` with its block kinds (``block_kinds``) and grammar places (``grammar_places``), sorted."""
    return {**item, "block_kinds": sorted(block_kinds_of(item)), "grammar_places": sorted(grammar_places_of(item))}


def alternatives_hold(blocks: list[dict], diag: dict, per: dict) -> dict:
    """For each drawn block the diagnosis did not name right (``per``: :func:`judge_blocks`' ``per_block``): is its
    kind at its place among what the logs cannot part from what was named -- the alternatives stage's ``within``
    entries and the states stage's ``within`` blocks (issue 42: "a stand-in that explains one lists the truth's kind
    among its alternatives where the logs cannot part them")?

    Returns
    -------
    dict
        {"kind@place": {"listed": bool, "alternatives": [names]}} over the blocks not named right.
    """
    names = [a.get("name") for a in diag.get("alternatives") or [] if isinstance(a, dict) and a.get("within")]
    for rec in [diag.get("state")] + list(diag.get("states") or []):
        if isinstance(rec, dict):
            names += [w.get("effect") for w in rec.get("within") or [] if isinstance(w, dict)]
    items = [_with_blocks(named_item(n, "alternative")) for n in dict.fromkeys(n for n in names if n)]
    out = {}
    for b in blocks:
        key = f"{b['kind']}@{b['place']}"
        if per[key]["right_kind"] and per[key]["right_place"]:
            continue
        acc = accepted_block_kinds(b["kind"])
        out[key] = {"listed": any(acc & set(it["block_kinds"]) and b["place"] in it["grammar_places"] for it in items),
                    "alternatives": [it["label"] for it in items]}
    return out


def accepted_block_kinds(kind: str) -> set:
    """The block kinds a diagnosis may name a block of ``kind`` as and be right: its own and its ``accept``."""
    return {kind, *_grammar().KINDS[kind].accept}


def judge_blocks(blocks: list[dict], items: list[dict]) -> dict:
    """Right place and right kind of every drawn block, named in physical words?

    Parameters
    ----------
    blocks : list of dict
        The truth: ``{"place", "kind", ...}`` per block (the case's ``blocks``).
    items : list of dict
        :func:`block_items` of the diagnosis.

    Returns
    -------
    dict
        ``right`` (every block matched by one worded item of an accepted block kind at its place, and no worded
        item of a kind no block has), ``per_block`` {"kind@place": {"right_kind", "right_place",
        "right_place_any_kind", "right_kind_any_form"}} (the last counting bare proposal constants too), ``wrong``
        (labels), ``items``.
    """
    worded = [it for it in items if it["words"]]
    per, union = {}, set()
    for b in blocks:
        acc = accepted_block_kinds(b["kind"])
        union |= acc
        kind_ok = [it for it in worded if acc & set(it["block_kinds"])]
        per[f"{b['kind']}@{b['place']}"] = {
            "right_kind": bool(kind_ok),
            "right_place": any(b["place"] in it["grammar_places"] for it in kind_ok),
            "right_place_any_kind": any(b["place"] in it["grammar_places"] for it in worded),
            "right_kind_any_form": any(acc & set(it["block_kinds"]) for it in items)}
    wrong = [it["label"] for it in worded if not (set(it["block_kinds"]) & union)]
    right = bool(per) and all(v["right_kind"] and v["right_place"] for v in per.values()) and not wrong
    return {"right": right, "per_block": per, "wrong": wrong,
            "items": [{k: it.get(k) for k in ("label", "block_kinds", "grammar_places", "words", "source")}
                      for it in items]}
