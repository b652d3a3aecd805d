"""The measurements of issue 34's acceptance (tests/measurement/plan_loop.py, alternatives_spurious.py) count what
they say: the realised separation, the truth named, a spurious alternative.  Figures by hand."""
from __future__ import annotations

import math

import pytest

from ehas_env.diagnosis.alternatives import rivals_of
from ehas_env.physics.effects import REGISTRY
from tests.independent_rig.effects import ALL
from tests.measurement.alternatives_spurious import spurious
from tests.measurement.plan_loop import CASES, _named, realised, table


def test_every_case_is_a_generator_effect_whose_ehas_name_has_rivals():
    """Each case hides one effect of the independent generator (its parameters as the generator names them), and
    the ehas explanation that is its truth has listed rivals: the pairs the acceptance is about."""
    places = set()
    for name, (place, gen, values, truth) in CASES.items():
        assert gen in ALL, name
        assert set(values) == {p.name for p in ALL[gen].params}, name
        for t in truth:
            assert t in REGISTRY and rivals_of(t), (name, t)
        places.add(place.split(" ")[0])
    assert {"fluid", "mechanics", "sensors", "valve", "leakage"} <= places


def test_a_case_of_another_campaign_names_the_generators_options_and_says_so():
    """A case whose campaign is not the standard one (CAMPAIGNS) passes options the generator has, and its record
    and row say which campaign it was."""
    import inspect

    from tests.independent_rig.campaign import simulate
    from tests.measurement.plan_loop import CAMPAIGNS

    known = set(inspect.signature(simulate).parameters)
    for name, (options, words) in CAMPAIGNS.items():
        assert name in CASES and set(options) <= known and words, name
    row = table([_case(campaign="the closed-loop runs only, no valve bench run")]).split("\n")[-8]
    assert "(campaign: the closed-loop runs only, no valve bench run)" in table(
        [_case(campaign="the closed-loop runs only, no valve bench run")])
    assert "(campaign:" not in table([_case(campaign="standard")]) and row


def test_the_realised_separation_is_the_mean_ratio_over_the_planned_runs():
    second = {"alternatives": [], "ruled_out": [
        {"name": "b", "in_place_of": "a", "per_run_db": {"plan_1": 10 * math.log10(2.0), "plan_2": 0.0,
                                                         "cl_old": 20.0}}]}
    # (2 + 1) / 2 = 1.5 over the two planned runs; the campaign's own run does not count
    assert math.isclose(realised(second, "a", "b", ["plan_1", "plan_2"]), 10 * math.log10(1.5), rel_tol=1e-12)
    assert realised(second, "b", "a", ["plan_1"]) == pytest.approx(10 * math.log10(2.0))
    assert realised(second, "a", "c", ["plan_1"]) is None
    assert realised(second, "a", "b", ["plan_9"]) is None


def _case(**kw):
    r = {"case": "x", "place": "fluid", "truth": {"e": {"p": 1.0}}, "truth_listed_first": True,
         "first": {"reported": ["t"], "alternatives": ["u"], "ruled_out": []}, "plan": ["plan_1"],
         "pairs": [{"a": "t", "b": "u", "predicted_db": 5.0, "realised_db": 4.0}],
         "second": {"reported": ["t"], "alternatives": []}, "truth_named_second": True}
    r.update(kw)
    return r


def test_the_table_counts_named_and_agreeing_cases():
    good = _case()
    left = _case(case="y", second={"reported": ["t"], "alternatives": ["u"]}, truth_named_second=False,
                 pairs=[{"a": "t", "b": "u", "predicted_db": 9.5, "realised_db": 0.0}])
    decided = _case(case="z", plan=[], pairs=[], second=None, truth_named_second=None,
                    first={"reported": ["t"], "alternatives": [], "ruled_out": ["u"]})
    assert _named(good) == "yes" and _named(left) == "no" and _named(decided) == "no plan needed"
    text = table([good, left, decided])
    assert "in the first diagnosis: 3 of 3" in text
    assert "Cases with a plan: 2; the second diagnosis names the truth (reported, no alternative left within) in 1" \
        in text
    assert "within 3 dB: 1 of 2 pairs" in text
    # the plan predicts the size of a separation: one realised the other way round (the alternative better) agrees
    flipped = _case(case="w", pairs=[{"a": "t", "b": "u", "predicted_db": 5.8, "realised_db": -5.7}])
    assert "within 3 dB: 2 of 2 pairs" in table([good, flipped])
    assert "Genuinely ambiguous (the first diagnosis lists an alternative these logs cannot tell from the reported " \
        "one): 2 of 3 cases" in text
    assert "names the truth (reported, no alternative left within) in 1 of 2" in text
    # distinct pairs: the same two explanations in two cases count once, another pair once more
    other = _case(case="v", first={"reported": ["s"], "alternatives": ["u"], "ruled_out": []})
    assert "2 of 3 cases, 1 distinct pairs or triples (t vs u)" in text
    assert "3 of 4 cases, 2 distinct pairs or triples (s vs u; t vs u)" in table([good, left, decided, other])
    assert "| 9e76d75 |" in table([_case(commit="9e76d75")]) and "| unknown |" in text


def test_an_alternative_the_data_separate_is_spurious():
    within = {"name": "b", "in_place_of": "a", "score_difference_db": 0.1, "per_run_db": {"r1": 0.2, "r2": -0.1}}
    assert spurious({"alternatives": [within]}) == []
    one_run = {**within, "per_run_db": {"r1": 3.2, "r2": -0.1}}
    out = spurious({"alternatives": [within, one_run]})
    assert len(out) == 1 and out[0]["run"] == "r1" and out[0]["max_run_db"] == 3.2
    overall = {**within, "score_difference_db": 3.1}
    assert len(spurious({"alternatives": [overall]})) == 1
    assert spurious({"alternatives": [{**within, "per_run_db": {}}]}) == []
    assert spurious({}) == []


def test_the_spurious_set_is_part_of_the_acceptance_set_and_covers_its_groups():
    from tests.independent_rig.cases import all_cases
    from tests.measurement.alternatives_spurious import DEFAULT

    known = {c["id"]: c for c in all_cases()}
    assert set(DEFAULT) <= set(known) and len(set(DEFAULT)) == len(DEFAULT)
    assert {known[c]["group"] for c in DEFAULT} == {"clean", "library", "ool"}
    assert {known[c]["rig"] for c in DEFAULT} == {"book", "rig_b", "rig_c"}
