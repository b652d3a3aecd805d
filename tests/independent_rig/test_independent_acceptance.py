"""A small part of the out-of-library acceptance, run end to end (slow: it runs ehas diagnose and compare)."""
from __future__ import annotations

import json

import pytest

from independent_rig import acceptance


@pytest.mark.slow
def test_acceptance_harness_on_a_clean_and_an_out_of_library_campaign(tmp_path):
    """A clean campaign of the other engine is explained down to noise with nothing named; a strong
    out-of-library load (an unbalance on the crank) is flagged unexplained with a proposal and its residual
    before stays far above noise.  The harness checkpoints each case and writes its table."""
    out, work = tmp_path / "out", tmp_path / "work"
    ids = "clean_rig_c_s0,ool_crank_unbalance_strong"
    assert acceptance.main(["--out", str(out), "--work", str(work), "--only", ids]) == 0
    clean = json.loads((out / "cases" / "clean_rig_c_s0.json").read_text())
    assert clean["verdict"] == "explained" and clean["named"] == [] and clean["residual_before"] < 1.5
    ool = json.loads((out / "cases" / "ool_crank_unbalance_strong.json").read_text())
    assert ool["verdict"] == "unexplained" and ool["residual_before"] > 10
    assert ool["proposal"] is not None and (out / ool["effect_file"]).exists()
    text = (out / "README.md").read_text()
    assert "ool_crank_unbalance_strong" in text and "clean_rig_c_s0" in text
    # resumable: a second run finds both done and runs nothing
    assert acceptance.main(["--out", str(out), "--work", str(work), "--only", ids]) == 0


@pytest.mark.slow
@pytest.mark.parametrize("rig_name,sets,amp,freq", [("book", 1, 35.0, 3.0), ("rig_c", 5, 30.0, 2.0)])
def test_the_two_engines_agree_on_a_clean_run(rig_name, sets, amp, freq):
    """Ideal sensors, nominal rig: the independent generator and ehas's compiled model (another integrator,
    another code) give the same closed-loop run to far below the sensor noise (0.01 deg, 0.25 bar, 0.06 LPM)."""
    import numpy as np

    from ehas_env.simulation.plant import Plant, RigController
    from ehas_env.simulation.sensors import Sensors
    from independent_rig.campaign import rig_named
    from independent_rig.sensors import Chain
    from independent_rig.simulate import closed_loop

    rig, path = rig_named(rig_name)
    cols, _, meta = closed_loop(rig, sets, amp, freq, 1.5, {}, Chain.ideal(), np.random.default_rng(0))
    g = meta["controller"]
    res = Plant(disc_sets=sets, model=str(path) if path else None, sensors=Sensors.ideal()).simulate_closed_loop(
        RigController(Kp=g["Kp"], Ki=g["Ki"], Kv=g["Kv"], Ka=g["Ka"]), amplitude_deg=amp, freq_hz=freq, duration=1.5)
    tol = {"theta_deg": 1e-3, "current_mA": 1e-3, "p_a_bar": 5e-3, "p_b_bar": 5e-3, "flow_lpm": 2e-3}
    for key, atol in tol.items():
        np.testing.assert_allclose(cols[key], getattr(res, key), atol=atol, rtol=0, err_msg=key)


@pytest.mark.slow
@pytest.mark.parametrize("case_id,effect,param,truth_effect,truth_param", [
    ("ool_turbulent_leakage_mild", "hyp_turbulent_leakage", "q_100", "turbulent_leakage", "q100"),
    ("ool_lugre_friction_mild", "hyp_lugre_friction", "Fc", "lugre_friction", "Fc"),
])
def test_an_orifice_leak_and_a_bristle_friction_of_the_other_engine_are_named(tmp_path, case_id, effect, param,
                                                                              truth_effect, truth_param):
    """The other engine's orifice-law leakage (Q = q100 sqrt(|dp| / 100 bar)) and LuGre friction are explained
    by the hypothesis of that law, at the generator's value (its case table), and nothing else is kept.  (The
    leak once lost to a laminar leakage and a sensor hypothesis: the hypothesis' laminar rounding reached up
    into the working pressures, so it fitted different q_100 on slow and fast runs.)"""
    out, work = tmp_path / "out", tmp_path / "work"
    assert acceptance.main(["--out", str(out), "--work", str(work), "--only", case_id]) == 0
    rec = json.loads((out / "cases" / f"{case_id}.json").read_text())
    assert rec["verdict"] == "explained" and rec["residual_after"] < 2.0, rec
    assert rec["kept"] == [effect], rec["kept"]
    truth = rec["effects"][truth_effect][truth_param]
    assert rec["kept_params"][effect][param] == pytest.approx(truth, rel=0.1)


def test_a_missed_effect_counts_as_right_only_when_the_data_do_not_resolve_it():
    """The acceptance's resolution rule on built records: a missed effect is forgiven only when its oracle fit was
    below resolution; a wrong kind named is never forgiven; a right record stays right."""
    right = {"judge": {"right_kind": True, "missed": [], "wrong": []}}
    missed = {"judge": {"right_kind": False, "missed": ["lvdt_offset"], "wrong": []}}
    wrong = {"judge": {"right_kind": False, "missed": ["lvdt_offset"], "wrong": ["coulomb_friction"]}}
    assert acceptance.right_kind_resolved(right)
    assert not acceptance.right_kind_resolved(missed)  # no oracle run: not forgiven
    missed["resolution"] = {"lvdt_offset": {"below_resolution": False}}
    assert not acceptance.right_kind_resolved(missed)
    missed["resolution"] = {"lvdt_offset": {"below_resolution": True}}
    assert acceptance.right_kind_resolved(missed)
    wrong["resolution"] = {"lvdt_offset": {"below_resolution": True}}
    assert not acceptance.right_kind_resolved(wrong)


def test_an_oracle_resolves_an_effect_only_with_the_share_and_the_score_the_diagnosis_asks():
    """The resolution bar is the diagnosis' own: the share of the excess removed, and the score (dB less 0.2 dB per
    parameter, at least 0.3 dB); fitted together, each effect must score on top of the other fitted alone."""
    ref = {"floors": 1.2, "sensor": 1.5}

    def rec(floors, sensor, n):
        return {"after": {"floors": floors, "sensor": sensor}, "fitted": [{}] * n,
                "share_removed": {"floors": (1.2 - floors) / 0.2, "sensor": (1.5 - sensor) / 0.5}}

    assert acceptance.oracle_score(1.5, 1.5 / 10 ** 0.05, 1) == pytest.approx(0.3)
    assert acceptance.oracle_resolves(rec(1.05, 1.2, 1), ref)  # 75 % of the excess, 0.77 dB
    assert not acceptance.oracle_resolves(rec(1.15, 1.4, 1), ref)  # 25 %: too small a share
    # half the excess in floors but hardly anything in the cost: 0.13 dB - 0.2 dB
    assert not acceptance.oracle_resolves(rec(1.1, 1.455, 1), ref)
    # the same share and score spread over eight parameters: 0.77 - 1.6 dB
    assert not acceptance.oracle_resolves(rec(1.05, 1.2, 8), ref)
    pair, a, b = rec(1.04, 1.1, 2), rec(1.12, 1.3, 1), rec(1.1, 1.25, 1)
    # each on top of the other alone: 1.3 -> 1.1 scores 0.53 dB, 1.25 -> 1.1 0.36 dB ...
    assert acceptance.oracle_resolves(pair, ref, [a, b])
    assert not acceptance.oracle_resolves(pair, ref, [a, rec(1.05, 1.12, 1)])  # ... 1.12 -> 1.1: -0.12 dB


@pytest.mark.slow
def test_a_load_path_spring_put_in_place_at_the_end_takes_the_effects_it_covered_with_it(tmp_path):
    """The other engine's spring in the load path (25 N/um), its runs started from rest without a fade-in: the
    library keeps a piston leakage and a softer oil first; the alternatives find the spring better than the softer
    oil and put it in its place.  The leakage was kept only because the spring was missing: it goes too, as it goes
    when a hypothesis is kept in a round.  (Before, the diagnosis ended with leakage + spring damped at 0.04 of
    critical, small structured residual 1.64x, where the twin started with a fade-in is explained at 1.11x.)"""
    from ehas_env.diagnosis.pipeline import diagnose_open
    from ehas_env.measurement.campaign import read_campaign
    from independent_rig import start_conditions as sc

    case = next(c for c in sc.cases() if c["id"] == "load_compliance")
    sc._generate(case, "rest", tmp_path / "rest")
    res = diagnose_open(read_campaign(tmp_path / "rest"))
    assert set(res.model.effects) == {"hyp_load_compliance"}, res.kept
    assert res.verdict == "explained", res.verdict
    k_true = case["effects"]["load_compliance"]["k"] * 1e3  # N/mm -> N/m
    assert res.model.effects["hyp_load_compliance"]["k_load"] == pytest.approx(k_true, rel=0.1)
    assert any(s.effect == "internal_leakage" and "stands in for hyp_load_compliance" in s.reason for s in res.steps)
