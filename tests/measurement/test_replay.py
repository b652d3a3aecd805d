"""Replay: the model re-simulates a campaign exactly as it was run.

Independent truth: a campaign simulated with ideal sensors is reproduced to
rounding by replaying it with the model that made it; with noisy sensors the
true model's residuals sit at the sensor noise level; fit % follows its
definition in measurements.md (NRMSE, mean over runs, then over signals).
"""
from __future__ import annotations

import pickle

import numpy as np
import pytest

from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.measurement.synthetic import simulate_campaign
from ehas_env.simulation.metrics import fit_percent
from ehas_env.measurement.replay import ModelSpec, Replayer, noise_level
from ehas_env.simulation.sensors import Sensors

PLAN = ((2, 18.0, 2.0), (6, 25.0, 1.0))
HIDDEN = {"internal_leakage": {"C_leak": 1.7e-12}}


def campaign(effects, seed, sensors=None, perturb=True, duration=1.5):
    runs, truth = simulate_campaign(effects, seed=seed, perturb=perturb, duration=duration, plan=PLAN, sensors=sensors)
    return Campaign(None, [validate_run(n, c, m) for n, c, m in runs]), truth


def true_model(truth):
    return ModelSpec(effects=truth["effects"], beta=truth["beta"], K=truth["K"])


def test_ideal_campaign_is_reproduced_by_its_own_model():
    camp, truth = campaign(HIDDEN, seed=21, sensors=Sensors.ideal())
    rep = Replayer(camp)
    sims = rep.simulate(true_model(truth))
    for case, sim in zip(rep.cases, sims):
        for s in case.signals:
            np.testing.assert_allclose(sim[s], case.measured[s], rtol=0, atol=1e-9, err_msg=f"{case.run.name} {s}")
    # ... and any other model does not
    other = rep.simulate(ModelSpec(beta=truth["beta"], K=truth["K"]))
    assert max(np.abs(o["current_mA"] - c.measured["current_mA"]).max() for o, c in zip(other, rep.cases)
               if c.run.kind == "closed_loop") > 0.01


def test_replay_resamples_a_log_slower_than_the_controller():
    """A 500 Hz log of a 1 kHz controller: the replay samples its 1 kHz simulation at the logged times."""
    runs, truth = simulate_campaign(HIDDEN, seed=22, duration=1.0, plan=PLAN[:1], sensors=Sensors.ideal(), valve=False)
    name, cols, meta = runs[0]
    slow = {k: v[::2] for k, v in cols.items()}
    full = Replayer(Campaign(None, [validate_run(name, cols, meta)])).simulate(true_model(truth))[0]
    rep = Replayer(Campaign(None, [validate_run(name, slow, meta)]))
    assert rep.cases[0].resample and rep.cases[0].run.dt == pytest.approx(2e-3)
    sim = rep.simulate(true_model(truth))[0]
    for s in ("theta_deg", "current_mA", "p_a_bar", "flow_lpm"):
        np.testing.assert_allclose(sim[s], full[s][::2], rtol=0, atol=1e-9)


def test_true_model_leaves_only_sensor_noise():
    camp, truth = campaign(HIDDEN, seed=23)
    rep = Replayer(camp)
    true_sims = rep.simulate(true_model(truth))
    base_sims = rep.simulate(ModelSpec())
    assert rep.cost(true_sims) < 1.6  # mean squared residual in noise variances
    assert rep.cost(base_sims) > 3 * rep.cost(true_sims)
    sensors = Sensors()
    expected_noise = {"theta_deg": sensors.theta_noise_deg, "p_a_bar": sensors.pressure_noise_bar,
                      "flow_lpm": sensors.flow_noise_lpm}
    for case, sim in zip(rep.cases, true_sims):
        for s, sigma in expected_noise.items():
            if s in case.signals:
                assert case.noise[s] == pytest.approx(sigma, rel=0.15)  # estimated from the data alone
                rms = float(np.sqrt(np.mean((case.measured[s] - sim[s]) ** 2)))
                assert rms < 2.0 * sigma, (case.run.name, s, rms)
    assert rep.fit_table(true_sims).overall > rep.fit_table(base_sims).overall


def test_fit_percent_follows_its_definition():
    camp, truth = campaign(HIDDEN, seed=24)
    rep = Replayer(camp)
    sims = rep.simulate(ModelSpec())
    table = rep.fit_table(sims)
    expected = {}
    for case, sim in zip(rep.cases, sims):
        for s in case.signals:
            if s == "p_s_bar":  # regulated supply: noise only, left out of the fit
                assert s not in table.per_run[case.run.name]
                assert table.rms[case.run.name][s] < 0.5
                continue
            f = fit_percent(case.measured[s], sim[s])
            assert table.per_run[case.run.name][s] == pytest.approx(f, abs=1e-12)
            expected.setdefault(s, []).append(f)
    assert set(table.per_signal) == set(expected)
    for s, fs in expected.items():
        assert table.per_signal[s] == pytest.approx(np.mean(fs), abs=1e-12)
    assert table.overall == pytest.approx(np.mean([np.mean(v) for v in expected.values()]), abs=1e-12)
    # the valve run's current is its input, not a fitted output
    valve = next(c for c in rep.cases if c.run.kind == "valve_open_loop")
    assert valve.signals == ("flow_lpm",)


def test_noise_level_estimator_recovers_white_noise_on_smooth_signals():
    rng = np.random.default_rng(5)
    t = np.arange(5000) * 1e-3
    for sigma, clean in [(0.2, 110 + 30 * np.sin(2 * np.pi * 2 * t)), (0.01, 35 * np.sin(2 * np.pi * 3 * t)),
                         (0.05, 20 * np.sign(np.sin(2 * np.pi * t)))]:
        assert noise_level(clean + rng.normal(0, sigma, t.size)) == pytest.approx(sigma, rel=0.06)


def test_batch_and_serial_replays_agree():
    """Replays side by side on threads (each in buffers of its own) give, bit for bit, what one thread gives
    one replay at a time, for several models at once and for each alone."""
    camp, truth = campaign(HIDDEN, seed=25, duration=0.8)
    rep = Replayer(camp, threads=3)
    one = Replayer(camp, threads=1)
    models = [ModelSpec(effects={"coulomb_friction": {"Fc": f}}) for f in (150.0, 450.0)] + [true_model(truth)]
    batch = rep.simulate_many(models)
    assert len(batch) == 3 and all(len(b) == len(camp.runs) for b in batch)
    for m, b in zip(models, batch):
        for s_b, s_s in zip(b, one.simulate(m)):
            for k in s_s:
                np.testing.assert_array_equal(s_b[k], s_s[k])
    # the models differ: a mixed-up buffer would make two of them equal
    assert not np.array_equal(batch[0][0]["current_mA"], batch[1][0]["current_mA"])
    # a replayer sent to another process (pickled) leaves its threads behind and makes its own there
    for s_p, s_b in zip(pickle.loads(pickle.dumps(rep)).simulate(models[0]), batch[0]):
        np.testing.assert_array_equal(s_p["flow_lpm"], s_b["flow_lpm"])


def test_a_replay_runs_on_the_structural_hypotheses_model_only_when_it_names_one(monkeypatch):
    """With ``hypotheses=True`` (a diagnosis) the baseline and a library effect replay on the model of the
    registered effects, a structural hypothesis on the one that also holds them; the larger model gives the
    library's replay bit for bit (its other effects are off and skipped), so a diagnosis the library ends never
    compiles it."""
    from ehas_env.measurement import replay
    from ehas_env.simulation.plant import Plant

    camp, _ = campaign(HIDDEN, seed=27, duration=0.5)
    run = camp.runs[0]
    rep = Replayer(camp, hypotheses=True)
    lib = rep.compiled(ModelSpec(), run)[0]
    assert not any(n.startswith(("hyp_", "aug_")) for n in lib.EFFECTS)
    friction = ModelSpec(effects={"coulomb_friction": {"Fc": 200.0}})
    assert rep.compiled(friction, run)[0] is lib
    hyp = rep.compiled(ModelSpec(effects={"hyp_rod_area": {"d_area": 0.1}}), run)[0]
    assert hyp is not lib and "hyp_rod_area" in hyp.EFFECTS and "coulomb_friction" in hyp.EFFECTS
    # the library's replay on the larger model: the same numbers
    sims = rep.simulate(friction)
    monkeypatch.setattr(replay, "Plant", lambda *a, **k: Plant(*a, **{**k, "hypotheses": True}))
    assert rep.compiled(friction, run)[0] is hyp
    for a, b in zip(sims, rep.simulate(friction)):
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])


def test_a_proposed_term_at_zero_changes_nothing_when_the_extended_model_has_more_states():
    """A proposal runs on the extended model (every registered effect and the term classes), whose states
    differ from a library model's once a registered effect has a state of its own (hyp_lugre_friction's bristle
    deflection): the run starts from the plant's state, by name, and a term of zero adds nothing.  (The plant's
    state vector once went into the extended model as it was: 11 numbers into 12, an error in the batched
    replay and a read past the vector's end in the serial one.)"""
    camp, _ = campaign(HIDDEN, seed=26, duration=0.6)
    rep = Replayer(camp)
    plain = ModelSpec(effects={"coulomb_friction": {"Fc": 250.0}})
    zero_term = ModelSpec(effects={"coulomb_friction": {"Fc": 250.0}}, terms={"proposal_piston_force.c_v": 0.0})
    assert rep.compiled(zero_term, camp.runs[0])[0].N_STATES > rep.compiled(plain, camp.runs[0])[0].N_STATES
    ref = rep.simulate(plain)
    for sims in (rep.simulate(zero_term), rep.simulate_many([zero_term])[0]):
        for case, a, b in zip(rep.cases, ref, sims):
            for k in a:
                np.testing.assert_allclose(b[k], a[k], rtol=1e-9, atol=1e-9, err_msg=f"{case.run.name} {k}")


def test_a_load_the_logger_computes_from_the_pressures_is_not_compared_and_a_load_cells_reading_is():
    """A logged load that is the logged pressures' combination (a logger's A (P_A - P_B)) carries nothing of its
    own: it is not compared (a pressure reading's offset would be counted twice, in the pressure and in the load);
    a load cell's reading (here ehas's sensor layer, the piston force read apart from chamber B's lagged pressure
    reading) is."""
    camp, truth = campaign(None, 5101)
    rep = Replayer(camp)
    for case in rep.cases:
        if case.run.kind == "closed_loop":
            c = case.run.columns
            cols = {"t": case.run.t, **c, "load_kN": 0.3 * c["p_a_bar"] - 0.28 * c["p_b_bar"]}
            logger = Campaign(None, [validate_run(case.run.name, cols, case.run.meta)])
            (own,) = Replayer(logger).cases
            assert "load_kN" not in own.signals and own.derived == ("load_kN",)
            # and the user is told, by run, in the words compare and diagnose print
            assert Replayer(logger).not_compared() == {case.run.name: ["load_kN"]}
            assert Replayer(logger).not_compared_text().startswith("not compared: load_kN in 1 of 1 runs")
    cell, _ = campaign({"aug_lag_pb_reading": {"T": 15.0}}, 5102)
    for case in Replayer(cell).cases:
        if case.run.kind == "closed_loop":
            assert "load_kN" in case.signals and case.derived == ()
    assert Replayer(cell).not_compared() == {} and Replayer(cell).not_compared_text() is None
