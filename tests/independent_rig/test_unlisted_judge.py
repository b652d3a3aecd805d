"""The judge of the group ``unlisted`` (right place and right kind, in physical words; the honesty figures), on
hand-made diagnosis JSONs: each rule is shown passing on a case built for it and failing on one built to break it."""
from __future__ import annotations

import json

import pytest

from independent_rig.effects import UNLISTED
from independent_rig.judge import (NAMED_FORM_KIND, PLACE_KINDS, canonical_place, honesty, judge_place_kind,
                                   named_entry_kinds, worded_items)


def _diag(named=None, terms=None, kept=(), hypothesis=None, disturbances=(), validation=None, residual=1.5,
          proposal_validation=None):
    prop = None
    if named is not None or terms is not None:
        prop = {"terms": list(terms or []), "validation": proposal_validation or {}}
        if named is not None:
            prop["named"] = list(named)
    return {"stack": [{"effect": k, "kept": True} for k in kept], "hypothesis": hypothesis,
            "unexplained": {"proposal": prop} if prop else None, "disturbances": list(disturbances),
            "validation": validation or {}, "residual_x_noise": residual}


def _named(place, form, words="a physical law", kind="", params=None):
    return {"place": place, "form": form, "kind": kind, "law": "F = ...", "words": words, "params": params or {},
            "keeps_share": 0.9}


BORE = {"bore_wear_friction": UNLISTED["bore_wear_friction"].values(1)}


def test_the_right_form_at_the_right_place_is_right():
    j = judge_place_kind(BORE, worded_items(_diag(named=[_named("piston_force", "piston_force.friction_x2")])))
    assert j["right"] and j["per_effect"]["bore_wear_friction"] == {"right_kind": True, "right_place": True,
                                                                    "right_kind_any_form": True}


def test_the_right_kind_at_a_place_where_the_effect_does_not_act_is_not_right():
    # crank_torque.friction_angle is friction, but a worn bore acts on the piston
    j = judge_place_kind(BORE, worded_items(_diag(named=[_named("crank_torque", "crank_torque.friction_angle")])))
    assert not j["right"]
    assert j["per_effect"]["bore_wear_friction"]["right_kind"] and not j["per_effect"]["bore_wear_friction"][
        "right_place"]


def test_the_kind_is_judged_by_the_form_not_by_the_packages_own_word():
    # the package calls a spring "friction": the judge reads the form (a spring is a load) and says wrong
    e = _named("piston_force", "piston_force.spring", kind="friction")
    assert named_entry_kinds(e) == {"load"}
    j = judge_place_kind(BORE, worded_items(_diag(named=[e])))
    assert not j["right"] and j["wrong"]


def test_a_form_unknown_to_the_judge_takes_the_place_kind_when_the_place_allows_one():
    # a generic sensor state (a lag of the reading) that no named form lists: the place says "sensor"
    e = _named("position_reading", "position_reading.lag", kind="anything")
    assert named_entry_kinds(e) == {"sensor"}
    lag = {"lvdt_lag": UNLISTED["lvdt_lag"].values(0)}
    assert judge_place_kind(lag, worded_items(_diag(named=[e])))["right"]
    # at a place of several kinds the package's word may only choose among them; an impossible word is unknown
    assert named_entry_kinds(_named("piston_force", "piston_force.new", kind="sensor lag")) == {"unknown"}
    assert named_entry_kinds(_named("piston_force", "piston_force.new", kind="seal friction")) == {"friction"}


def test_bare_proposal_constants_are_the_right_ingredients_but_not_words():
    terms = [{"place": "piston_force", "coefficient": "c_x2sv", "form": "x^2 sign(v)", "value": -800.0}]
    j = judge_place_kind(BORE, worded_items(_diag(terms=terms)))
    assert not j["right"]
    assert j["per_effect"]["bore_wear_friction"]["right_kind_any_form"]
    assert not j["per_effect"]["bore_wear_friction"]["right_kind"]


def test_the_package_place_names_map_onto_the_generators():
    assert canonical_place("land_flows") == "chamber_flows"
    flow = {"land_flow_forces": UNLISTED["land_flow_forces"].values(1)}
    named = [_named("land_flows", "chamber_flows.gain_load")]
    assert judge_place_kind(flow, worded_items(_diag(named=named)))["right"]
    # a leak across the piston is a flow at the right place, and an accepted kind of land flow forces
    # (leakage/flow), but a constant force is not
    assert judge_place_kind(flow, worded_items(_diag(named=[_named("chamber_flows",
                                                                   "chamber_flows.leak_across")])))["right"]
    assert not judge_place_kind(flow, worded_items(_diag(named=[_named("piston_force",
                                                                       "piston_force.constant")])))["right"]


def test_a_supply_line_in_the_logged_supply_is_the_supply_boundary_named():
    rip = {"supply_ripple": UNLISTED["supply_ripple"].values(1)}
    d = {"frequency_hz": 23.7, "amplitude": 10.0, "unit": "bar", "signal": "p_s_bar", "boundary": True,
         "text": "a 23.7 Hz line of 10 bar in the supply pressure"}
    assert judge_place_kind(rip, worded_items(_diag(disturbances=[d])))["right"]
    # the same line not on the logged supply (a line in the position only) names no boundary
    assert not judge_place_kind(rip, worded_items(_diag(disturbances=[{**d, "boundary": False}])))["right"]


def test_a_supply_taken_as_a_measured_input_is_the_supply_boundary_named():
    rip = {"supply_ripple": UNLISTED["supply_ripple"].values(1)}
    rec = {"stage": "measured_inputs", "kept": True, "text": "the supply pressure logged varies by +-9.99 bar"}
    d = {**_diag(), "measured_inputs": ["p_s_bar"], "stages": [rec]}
    assert judge_place_kind(rip, worded_items(d))["right"]
    assert not judge_place_kind(rip, worded_items({**d, "measured_inputs": []}))["right"]
    # on a campaign without a hidden supply effect, a measured supply is a worded item of a kind no effect has
    assert not judge_place_kind({}, worded_items(d))["right"]


def test_a_pair_needs_both_and_a_kept_library_effect_counts_where_it_acts():
    pair = {"bearing_friction": UNLISTED["bearing_friction"].values(0),
            "coulomb_friction": {"Fc": 250.0}}
    both = worded_items(_diag(kept=["coulomb_friction"], named=[_named("crank_torque", "crank_torque.friction_joint")]))
    assert judge_place_kind(pair, both)["right"]
    # coulomb_friction alone: friction on the piston is an accepted place of the bearing friction too (the same
    # load through the lever), so that pair is right by place and kind; a sensor item beside it is wrong
    extra = both + worded_items(_diag(named=[_named("position_reading", "position_reading.offset")]))
    j = judge_place_kind(pair, extra)
    assert not j["right"] and any("position_reading" in w for w in j["wrong"])
    lag_pair = {"lvdt_lag": UNLISTED["lvdt_lag"].values(0), "bearing_friction": UNLISTED["bearing_friction"].values(0)}
    only_one = worded_items(_diag(named=[_named("crank_torque", "crank_torque.friction_joint")]))
    j = judge_place_kind(lag_pair, only_one)
    assert not j["right"] and not j["per_effect"]["lvdt_lag"]["right_kind"]


def test_nothing_named_on_a_clean_campaign_is_right_and_anything_worded_is_wrong():
    assert judge_place_kind({}, worded_items(_diag()))["right"]
    assert not judge_place_kind({}, worded_items(_diag(kept=["coulomb_friction"])))["right"]


def test_every_named_form_and_place_has_a_kind_of_the_generators_vocabulary():
    from independent_rig.effects import KINDS, PLACES
    for form, kinds in NAMED_FORM_KIND.items():
        assert canonical_place(form.split(".")[0]) in PLACES and kinds <= set(KINDS), form
    for place, kinds in PLACE_KINDS.items():
        assert place in PLACES and kinds <= set(KINDS)


@pytest.mark.parametrize("baseline, final, closed", [(4.0, 1.5, True), (2.2, 1.9, False), (4.0, 2.3, False),
                                                     (None, 1.2, None)])
def test_closed_means_at_most_twice_the_noise_and_a_fifth_below_the_baseline(baseline, final, closed):
    assert honesty(_diag(), baseline, final)["closed"] is closed


def test_a_recommended_term_that_removes_under_a_tenth_of_the_excess_is_counted_weak():
    weak = _diag(terms=[{"place": "piston_force", "coefficient": "c_v"}],
                 proposal_validation={"residual_x_noise_all_before": 3.06, "residual_x_noise_all_after": 2.95})
    h = honesty(weak, 3.3, 2.95)
    assert h["weak_term"] is True and h["term_share"] == pytest.approx(0.11 / 2.06, abs=1e-4)
    strong = _diag(terms=[{"place": "piston_force", "coefficient": "c_v"}],
                   proposal_validation={"residual_x_noise_all_before": 3.0, "residual_x_noise_all_after": 1.2})
    assert honesty(strong, 3.3, 1.2)["weak_term"] is False
    assert honesty(_diag(), 3.3, 3.3)["weak_term"] is False  # no term recommended
    worse = _diag(terms=[{"place": "piston_force", "coefficient": "c_v"}],
                  proposal_validation={"residual_x_noise_all_before": 1.79, "residual_x_noise_all_after": 1.93})
    assert honesty(worse, 2.0, 1.93)["weak_term"] is True


def test_a_kept_hypothesis_that_worsens_the_all_data_residual_is_counted():
    bad = _diag(kept=["hyp_crank_spring", "hyp_quadratic_drag"], residual=3.89,
                validation={"residual_x_noise_before_hypotheses": 3.68})
    h = honesty(bad, 4.0, 3.89)
    assert h["worsening_hypothesis"] is True and h["hypotheses_kept"] == ["hyp_crank_spring", "hyp_quadratic_drag"]
    good = _diag(kept=["hyp_crank_spring"], residual=1.2, validation={"residual_x_noise_before_hypotheses": 3.68})
    assert honesty(good, 4.0, 1.2)["worsening_hypothesis"] is False
    # no hypothesis kept: a model worse than something is not this rule's business
    assert honesty(_diag(kept=["coulomb_friction"], residual=5.0,
                         validation={"residual_x_noise_before_hypotheses": 3.0}), 4.0, 5.0)[
        "worsening_hypothesis"] is False
    # the kept hypothesis given only by the JSON's "hypothesis" record, with its own before-figure
    only = _diag(hypothesis={"effect": "hyp_rod_area", "residual_x_noise_before": 2.0}, residual=2.5)
    assert honesty(only, 3.0, 2.5)["worsening_hypothesis"] is True


def test_a_land_term_is_judged_under_either_place_name_and_a_boundary_coefficient_acts_on_the_boundary():
    from independent_rig.judge import form_kinds
    assert form_kinds("land_flows", "c_gpl") == form_kinds("chamber_flows", "c_gpl") == {"valve"}
    assert form_kinds("piston_force", "c_nothing") is None
    items = worded_items(_diag(terms=[{"place": "land_flows", "coefficient": "c_sup", "form": "1"}]))
    assert items[0]["places"] == ["supply"] and "supply/return" in items[0]["kinds"] and not items[0]["words"]


def test_a_state_the_state_stage_kept_is_named_where_it_acts():
    lag = {"lvdt_lag": UNLISTED["lvdt_lag"].values(1)}
    diag = {**_diag(), "stages": [{"stage": "states", "kept": "aug_lag_position_sensor", "words": "a 2 ms lag"}]}
    assert judge_place_kind(lag, worded_items(diag))["right"]
    coil = {**_diag(), "stages": [{"stage": "states", "states": {"kept": "aug_lag_coil"}}]}
    j = judge_place_kind(lag, worded_items(coil))
    assert not j["right"] and j["wrong"] == ["aug_lag_coil"]
    hose = {"hose_line": UNLISTED["hose_line"].values(0)}
    assert judge_place_kind(hose, worded_items({**_diag(), "model": {"effects": {"aug_hose_a": {}}}}))["right"]


def _rec(cid, right, closed, weak=False, worse=False, error=False):
    r = {"id": cid, "group": "unlisted", "rig": "book", "effects": {"lvdt_lag": {"T": 2.0}}, "steps": {"total_s": 1.0},
         "verdict": "unexplained"}
    if error:
        return {**r, "error": "diagnose exited 1"}
    return {**r, "place_kind": {"right": right, "wrong": [], "items": [],
                                "per_effect": {"lvdt_lag": {"right_kind": right, "right_place": right,
                                                            "right_kind_any_form": right}}},
            "honesty": {"baseline": 4.0, "final": 1.5 if closed else 3.0, "closed": closed, "weak_term": weak,
                        "worsening_hypothesis": worse}}


def test_the_harness_summary_counts_each_figure_against_the_issues_thresholds():
    from independent_rig.unlisted import COMMAND, readme, summarise
    recs = [_rec("a", True, True), _rec("b", True, True), _rec("c", True, True), _rec("d", False, True, weak=True),
            _rec("e", True, False, worse=True), _rec("f", False, False, error=True)]
    s = summarise(recs)
    assert (s["campaigns"], s["errors"], s["right_place_kind"], s["closed"]) == (6, 1, 4, 4)
    assert s["right_place_kind_share"] == pytest.approx(0.8) and s["closed_share"] == pytest.approx(0.8)
    assert s["weak_terms"] == 1 and s["worsening_hypotheses"] == 1
    assert s["meets"] == {"right_place_kind": True, "closed": True, "weak_terms": False,
                          "worsening_hypotheses": False}
    three = summarise(recs[:2] + recs[3:5])  # 3 of 4 right: 75 % meets; 3 of 4 closed: 75 % does not
    assert three["meets"]["right_place_kind"] and not three["meets"]["closed"]
    text = readme(recs, s, COMMAND)
    assert COMMAND in text and "| a | book |" in text and "error: diagnose exited 1" in text


def test_every_form_the_package_can_name_is_judged_here():
    FORMS = pytest.importorskip("ehas_env.diagnosis.naming").FORMS  # the naming step (issue 33, item 1)
    keys = list(FORMS) if isinstance(FORMS, dict) else [f.key for f in FORMS]
    assert keys and not [k for k in keys if k not in NAMED_FORM_KIND]


def test_a_stored_case_is_judged_again_from_its_stored_diagnosis(tmp_path):
    import json

    from independent_rig.unlisted import rejudge
    (tmp_path / "diag").mkdir()
    diag = {**_diag(), "stages": [{"stage": "states", "kept": "aug_lag_position_sensor"}]}
    (tmp_path / "diag" / "a.json").write_text(json.dumps(diag))
    rec = _rec("a", False, True)
    new = rejudge(rec, tmp_path)
    assert new["place_kind"]["right"] and new["honesty"]["final"] == 1.5 and new["honesty"]["closed"]
    assert rejudge(_rec("b", False, True), tmp_path)["place_kind"]["right"] is False  # no stored diagnosis: as it was


def test_a_stand_in_is_judged_by_whether_the_truths_kind_is_among_its_alternatives():
    """Issue 42's "a stand-in that explains one lists the truth's kind among its alternatives where the logs cannot
    part them" (the start-conditions set's summary, ``start_conditions.stand_in``): viscous friction hidden, the
    campaign called explained with a softer oil kept is a stand-in; listed when a friction is among its alternatives,
    not when none is; no stand-in when a friction was kept, or when the verdict is not explained."""
    from independent_rig.start_conditions import stand_in

    def rec(alts):
        return {"effects": {"viscous_friction": {"b": 8000.0}}, "c": {"rest": {"alternatives": alts}}}

    def diag(kept, verdict="explained"):
        return {"verdict": verdict, "model": {"effects": {k: {} for k in kept}}}

    listed = stand_in(rec(["coulomb_friction", "internal_leakage"]), "rest", diag(["bulk_modulus"]))
    assert listed["missed"] == ["viscous_friction"] and listed["listed"] and listed["named"] == ["bulk_modulus"]
    assert stand_in(rec(["internal_leakage"]), "rest", diag(["bulk_modulus"]))["listed"] is False
    assert stand_in(rec([]), "rest", diag(["bulk_modulus"]))["listed"] is False
    assert stand_in(rec([]), "rest", diag(["viscous_friction"])) is None
    assert stand_in(rec([]), "rest", diag(["bulk_modulus"], "unexplained")) is None
    assert stand_in({"effects": {}}, "rest", diag(["bulk_modulus"])) is None  # a clean campaign


def test_part_c_judges_also_the_figure_of_the_model_each_diagnosis_recommends(tmp_path):
    """Start conditions, part c: the model a diagnosis recommends is its model with the term it proposes (the
    proposal's all-data refit), else its own; a campaign whose variants each propose the term that takes them to the
    same figure agrees there though their figures before the term differ (a start from rest shows more of what the
    book model lacks); a missing stored diagnosis is no verdict either way."""
    from independent_rig.start_conditions import DIAGNOSED, _agree_recommended

    (tmp_path / "diag").mkdir()

    def put(cid, variant, before, after=None):
        prop = None if after is None else {"validation": {"residual_x_noise_all_after": after}}
        name = cid if variant == "rest" else f"{cid}.{variant}"
        (tmp_path / "diag" / f"{name}.json").write_text(json.dumps(
            {"residual_x_noise": before, "unexplained": None if prop is None else {"proposal": prop}}))

    for v, before in zip(DIAGNOSED, (6.2, 8.6, 7.7)):
        put("worn", v, before, 1.0 + 0.01 * len(v))
        put("apart", v, before)
    put("half", "fade", 1.0)
    assert _agree_recommended({"id": "worn"}, tmp_path) is True
    assert _agree_recommended({"id": "apart"}, tmp_path) is False
    assert _agree_recommended({"id": "half"}, tmp_path) is None


def test_a_drawn_block_missed_is_listed_when_its_kind_at_its_place_is_among_the_alternatives():
    """The drawn set's form of the same question (``judge.alternatives_hold``): a term beyond a threshold of the crank
    rate hidden, a quadratic drag named; listed when the alternatives the logs cannot part from it (the alternatives
    stage's ``within`` entries, the states stage's ``within`` blocks) hold a term beyond a threshold at the crank
    torque; not when they hold only other kinds, or the right kind at another balance; a block named right is not
    asked."""
    from independent_rig.judge import alternatives_hold, block_items, judge_blocks

    blocks = [{"place": "crank_torque", "kind": "dead_zone"}]

    def held(alts, within=(), kept=("hyp_quadratic_drag",)):
        diag = {"verdict": "explained", "model": {"effects": {k: {} for k in kept}},
                "alternatives": [{"name": a, "within": True} for a in alts],
                "state": {"within": [{"effect": w} for w in within]}}
        return alternatives_hold(blocks, diag, judge_blocks(blocks, block_items(diag))["per_block"])

    assert held(["aug_cubic_crank_rate", "aug_beyond_crank_rate"])["dead_zone@crank_torque"]["listed"]
    assert held([], within=["aug_beyond_crank_rate"])["dead_zone@crank_torque"]["listed"]
    assert not held(["aug_cubic_crank_rate"])["dead_zone@crank_torque"]["listed"]
    assert not held(["aug_beyond_chamber_a"])["dead_zone@crank_torque"]["listed"]
    assert held(["aug_cubic_crank_rate"], kept=("aug_beyond_crank_rate",)) == {}


def test_a_state_kept_by_its_stage_and_set_aside_later_is_not_counted_as_named():
    from independent_rig.judge import states_kept

    stage = {"stage": "states", "kept": "aug_prop_piston_load_pressure", "more": [{"kept": "aug_cubic_crank_angle"}]}
    d = _diag(named=[_named("chamber_flows", "chamber_flows.metering_law")])
    d["stages"] = [stage]
    assert states_kept(d) == ["aug_prop_piston_load_pressure", "aug_cubic_crank_angle"]  # kept, never set aside
    d["stack"] = [{"effect": "aug_prop_piston_load_pressure", "kept": False},
                  {"effect": "aug_cubic_crank_angle", "kept": False}]
    assert states_kept(d) == []  # the stack reports both not kept in the end, the final model lacks them
    d["model"] = {"effects": {"aug_cubic_crank_angle": {"c": 1.0}}}
    assert states_kept(d) == ["aug_cubic_crank_angle"]  # in the final model: named whatever the stack says
