"""The generator side of tests/independent_rig/conditions.py (issue 43, point 4), without a diagnosis.

* the conditions per run and the condition a law follows are drawn from the published seed, alike on every call;
* they are unrelated to the recording order and to the runs' settings (rank correlations within the limits);
* the law a case states is what the generator's per-run schedule applies, run by run;
* the sidecars carry the conditions where the diagnosis reads them;
* the judge accepts a right report and refuses a wrong condition, direction, size or quantity; a control refuses
  any reported parameter.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from tests.independent_rig import conditions as C
from tests.independent_rig import drift as D
from tests.independent_rig.campaign import _scheduled
from tests.independent_rig.effects import to_si
from tests.independent_rig.rig import book_rig

FOLLOW = [c for c in C.CASES if c["quantity"]]
CONTROLS = [c for c in C.CASES if not c["quantity"]]


def test_the_cases_are_enough_and_distinct():
    assert len(FOLLOW) >= 8 and len(CONTROLS) >= 4
    assert len({(c["case"], c["seed"]) for c in C.CASES}) == len(C.CASES)
    assert {c["quantity"] for c in FOLLOW} <= set(D.NAMES)
    assert C.SEED == 4304  # published before the cases were run: a change redraws every case


def test_the_draw_is_seeded_and_reproducible():
    first = [C.draw_conditions(c["seed"]) for c in C.CASES]
    C._draw.cache_clear()
    again = [C.draw_conditions(c["seed"]) for c in C.CASES]
    assert first == again
    assert C.draw_conditions(1) != C.draw_conditions(2)
    for conds, follows in first:
        assert list(conds) == list(C.CONDITIONS) and follows in C.CONDITIONS
        for k, v in conds.items():
            _, lo, hi = C.CONDITIONS[k]
            assert len(v) == len(C.PLAN) and len(set(v)) == len(v) and all(lo <= x <= hi for x in v)
    # the condition a law follows is drawn, not the same every time
    assert len({f for _, f in first}) > 1


def test_the_conditions_do_not_follow_the_recording_order_the_settings_or_each_other():
    from scipy.stats import spearmanr

    for c in C.CASES:
        conds, _ = C.draw_conditions(c["seed"])
        for k, v in conds.items():
            assert abs(C.rank_corr(v, C.SETTINGS["recording order"])) <= C.MAX_RHO_ORDER + 1e-9, (c, k)
            others = [x for n, x in C.SETTINGS.items() if n != "recording order"] + \
                     [x for n, x in conds.items() if n != k]
            for x in others:
                r = C.rank_corr(v, x)
                assert abs(r) <= C.MAX_RHO + 1e-9, (c, k)
                assert r == pytest.approx(spearmanr(v, x)[0], abs=1e-6)


@pytest.mark.parametrize("case", FOLLOW, ids=[f"{c['case']}-{c['seed']}" for c in FOLLOW])
def test_the_law_is_what_the_schedule_applies_run_by_run(case):
    conds, follows = C.draw_conditions(case["seed"])
    c = np.asarray(conds[follows])
    sched = C.schedule_of(case, conds, follows)
    rig = book_rig()
    q, ratio = case["quantity"], case["ratio"]
    start = case["effects"][C.EFFECT_OF[q][0]][C.EFFECT_OF[q][1]] if q in C.EFFECT_OF else 1.0
    vals = []
    for k in range(len(C.PLAN)):
        actual, eff = _scheduled(rig, case["effects"], sched, k)
        if q in C.EFFECT_OF:
            name, par = C.EFFECT_OF[q]
            v = eff[name][par] / to_si({name: {par: 1.0}})[name][par]
        else:
            v = {"beta": actual.beta / rig.beta, "K": actual.K / rig.K}[q]
            other = {"beta": actual.K / rig.K, "K": actual.beta / rig.beta}[q]
            assert other == pytest.approx(1.0)  # only the drawn quantity moves
        expected = start * (1.0 + (ratio - 1.0) * (c[k] - c.min()) / (c.max() - c.min()))
        assert v == pytest.approx(expected, rel=1e-12)
        vals.append(v)
    # from the coldest (least) to the hottest (largest) recorded value: the case's ratio
    assert vals[int(np.argmax(c))] / vals[int(np.argmin(c))] == pytest.approx(ratio, rel=1e-12)
    # the truth's law as the diagnosis words one: the slope per round step, % of the value at the mean
    law = C.truth_law(case, conds, follows)
    slope, icpt = np.polyfit(c, vals, 1)
    step = 10.0 ** math.floor(math.log10(np.ptp(c)))
    assert law["pct"] == pytest.approx(100 * slope * step / (icpt + slope * c.mean()), abs=0.01)
    assert law["quantity"] == follows and law["from"] == c.min() and law["to"] == c.max()
    # the other conditions are left alone by the law
    for k, v in conds.items():
        if k != follows:
            assert abs(C.rank_corr(v, vals)) <= C.MAX_RHO + 1e-9


def test_a_control_changes_nothing_between_runs():
    for case in CONTROLS:
        conds, follows = C.draw_conditions(case["seed"])
        sched = C.schedule_of(case, conds, follows)
        rig = book_rig()
        for k in range(len(C.PLAN)):
            actual, eff = _scheduled(rig, case["effects"], sched, k)
            assert actual.beta == rig.beta and actual.K == rig.K and eff == to_si(case["effects"])
        assert C.truth_law(case, conds, follows) is None


def test_the_sidecars_carry_the_conditions_where_the_diagnosis_reads_them():
    from ehas_env.diagnosis.drift import recorded_conditions

    conds, _ = C.draw_conditions(3)
    runs = [(f"r{k}", {}, {"kind": "closed_loop", "disc_sets": 5, "supply_bar": 220.0,
                           "reference": {"amplitude_deg": 20.0, "freq_hz": 2.0}, "recorded": "2026-11-27T08:00:00"})
            for k in range(len(C.PLAN))]
    C.dress(runs, conds)
    assert runs[0][2]["oil_temperature_C"] == conds["oil_temperature_C"][0]
    assert runs[2][2]["conditions"]["air_content_pct"] == conds["air_content_pct"][2]
    read = recorded_conditions([SimpleNamespace(meta=m) for _, _, m in runs])
    assert read == {k: [float(x) for x in v] for k, v in conds.items()}  # supply_bar is the format's, not one


def _entry(parameter, follows, ratio, direction=None, p=1e-8):
    """A drift entry shaped like the diagnosis JSON's (results/diagnosis_drift/drift.json)."""
    direction = direction or ("rises" if ratio is not None and ratio > 1 else "falls")
    return {"parameter": parameter, "unit": "Pa", "p_value": p, "chi2": 60.0, "dof": 4, "follows": follows,
            "rho": 1.0 if direction == "rises" else -1.0, "direction": direction,
            "correlations": {"recording order": 0.1, follows or "disc sets": 1.0},
            "quantity_from": 23.9, "quantity_to": 50.6, "first": 1.2e9, "last": None if ratio is None else 1.2e9 * ratio,
            "ratio_first_last": ratio, "law": None, "runs": ["a", "b", "c", "d", "e"],
            "text": f"{parameter} {direction} ..."}


BETA = {"quantity": "beta", "ratio": 0.6}
T = "oil_temperature_C"


def test_the_judge_accepts_a_right_report():
    j = C.judge([_entry("bulk_modulus.beta", T, 0.66)], BETA, T)  # 0.34 against 0.4: 15 % off
    assert j["ok"] and j["named"] == "bulk_modulus.beta" and j["error"] == pytest.approx(0.15, abs=1e-3)
    assert j["other_laws"] == [] and j["following"] == ["bulk_modulus.beta ~ oil_temperature_C"]
    # a stand-in beside it, following the same condition, does not spoil it
    j = C.judge([_entry("hyp_dead_volume.dV_a", T, None, "rises"), _entry("baseline.beta", T, 0.58)], BETA, T)
    assert j["ok"] and j["named"] == "baseline.beta"
    # one following another condition besides is counted, not refused
    j = C.judge([_entry("bulk_modulus.beta", T, 0.62), _entry("valve_dynamics.K", "air_content_pct", 1.3)],
                BETA, T)
    assert j["ok"] and j["other_laws"] == ["valve_dynamics.K ~ air_content_pct"]


@pytest.mark.parametrize("entry", [
    _entry("bulk_modulus.beta", "ambient_temperature_C", 0.6),  # the wrong condition
    _entry("bulk_modulus.beta", "recording order", 0.6),  # the recording order stands in for it
    _entry("bulk_modulus.beta", None, 0.6),  # follows nothing
    _entry("bulk_modulus.beta", T, 1.6, "rises"),  # the wrong direction
    _entry("bulk_modulus.beta", T, 0.75),  # 0.25 against 0.4: 38 % off
    _entry("bulk_modulus.beta", T, 0.4),  # 0.6 against 0.4: 50 % off
    _entry("valve_dynamics.K", T, 0.6),  # the wrong quantity
], ids=["condition", "order", "none", "direction", "small", "large", "quantity"])
def test_the_judge_refuses_a_wrong_report(entry):
    assert not C.judge([entry], BETA, T)["ok"]


def test_the_judge_of_the_sizes_edge_and_of_friction_names():
    fc = {"quantity": "Fc", "ratio": 2.4}
    assert C.judge([_entry("coulomb_friction.Fc", "air_content_pct", 1.0 + 1.4 * 1.29)], fc, "air_content_pct")["ok"]
    assert not C.judge([_entry("coulomb_friction.Fc", "air_content_pct", 1.0 + 1.4 * 1.31)], fc,
                       "air_content_pct")["ok"]
    assert C.judge([_entry("hyp_pressure_friction.mu_p", "air_content_pct", 2.2)], fc, "air_content_pct")["ok"]
    assert not C.judge([_entry("viscous_friction.b", "air_content_pct", 2.4)], fc, "air_content_pct")["ok"]


def test_a_control_refuses_any_reported_parameter():
    ctl = {"quantity": None, "ratio": 1.0}
    assert C.judge([], ctl, None)["ok"]
    j = C.judge([_entry("valve_dynamics.K", T, 1.3)], ctl, None)
    assert not j["ok"] and j["other_laws"] == ["valve_dynamics.K ~ oil_temperature_C"]
    j = C.judge([_entry("valve_dynamics.K", None, 1.3)], ctl, None)  # differs, follows nothing: still reported
    assert not j["ok"] and j["following"] == []


def test_the_drift_judge_still_reads_the_recording_order_by_default():
    e = _entry("coulomb_friction.Fc", "recording order", 2.2)
    assert D.judge([e], "Fc", 2.4)["ok"] and not D.judge([e], "Fc", 2.4, follows=T)["ok"]


def test_summary_and_readme_from_records():
    conds, follows = C.draw_conditions(5)
    case = C.CASES[5]
    rec = {"case": case["case"], "seed": 5, "quantity": "beta", "ratio_true": 0.6, "follows_true": follows,
           "law_true": C.truth_law(case, conds, follows), "drift": [_entry("bulk_modulus.beta", follows, 0.62)],
           "verdict": "explained", "elapsed_s": 50.0, "ehas_commit": "abc1234", "ehas_env_edited": False,
           "finished_utc": "2026-11-29 01:00"}
    ctl = {"case": "nothing follows (clean)", "seed": 11, "quantity": None, "ratio_true": 1.0, "follows_true": None,
           "law_true": None, "drift": [_entry("valve_dynamics.K", None, 1.2)], "verdict": "explained",
           "elapsed_s": 20.0, "ehas_commit": "abc1234", "ehas_env_edited": False, "finished_utc": "2026-11-29 01:02"}
    recs = [C.rejudge(dict(rec)), C.rejudge(dict(ctl))]
    s = C.summarise(recs)
    assert (s["named"], s["follow_cases"], s["controls_reporting_a_law"], s["controls_reporting_any"]) == (1, 1, 0, 1)
    assert s["pass_named"] and not s["pass_controls"]
    text = C.readme(recs, s, "python -m tests.independent_rig.conditions --out X")
    assert f"SEED = {C.SEED}" in text and "abc1234" in text and "1/1 (100 %)" in text
    assert "beta falls 19.6 % per 10 of oil_temperature_C (0.6x over 23.9 -> 50.6)" in text
