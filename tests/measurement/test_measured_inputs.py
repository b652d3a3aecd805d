"""The logged supply pressure as a measured input of the replay, and the diagnosis' stage that uses it
(ehas_env.diagnosis.measured_inputs, issue 33 item 4).

Truth:
- invariants: a constant logged supply equal to the sidecar's leaves the replay as it is (to 1e-9); a constant
  logged supply of another value replays as the sidecar of that value does;
- the orifice law: on the flow bench the metered no-load flow goes with sqrt(P_S), so a step of the logged supply
  from 70 to 140 bar at a held current multiplies the model's flow by sqrt(2);
- campaigns of the independent generator (tests/independent_rig, no package code): a pump whose supply ripples
  (its ``supply_ripple`` at 23.7 Hz, logged in ``p_s_bar``), the same rig without it, and the clean campaign with
  a line added to the supply's log alone (a transducer's artefact: the supply itself is steady).
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.diagnosis.fitting import fit, recal_params, start_value
from ehas_env.diagnosis.measured_inputs import (LINE_MARGIN, MIN_CUTOFF_HZ, cutoff_hz, input_names, measured,
                                                  measured_input_stage, smoothed)
from ehas_env.measurement.replay import ModelSpec, Replayer

PLAN = ((3, 20.0, 2.0), (5, 30.0, 2.0), (1, 35.0, 3.0))  # (disc sets, amplitude deg, Hz): three short runs
RIPPLE_HZ = 23.7  # the independent generator's pump line (tests/independent_rig/physics.py)


def _campaign(runs) -> Campaign:
    return Campaign(None, [validate_run(n, c, m) for n, c, m in runs])


def _with_supply_log(runs, value=None):
    """The runs with a logged ``p_s_bar`` of ``value`` bar (None: each sidecar's ``supply_bar``)."""
    out = []
    for n, c, m in runs:
        c = dict(c)
        c["p_s_bar"] = np.full(len(c["t"]), float(m["supply_bar"] if value is None else value))
        out.append((n, c, m))
    return out


@pytest.fixture(scope="module")
def synthetic_runs():
    from ehas_env.measurement.synthetic import simulate_campaign

    runs, _ = simulate_campaign({"coulomb_friction": {"Fc": 300.0}}, seed=7, duration=1.0,
                                plan=((2, 15.0, 2.0), (5, 25.0, 1.0)))
    return runs


def _max_diff(a: dict, b: dict, signals) -> float:
    return max(float(np.max(np.abs(a[s] - b[s]))) for s in signals)


def test_a_constant_logged_supply_at_the_nominal_replays_as_today(synthetic_runs):
    """Closed-loop runs and the valve bench: the measured input equal to the sidecar's supply changes nothing."""
    camp = _campaign(_with_supply_log(synthetic_runs))
    model = ModelSpec(effects={"coulomb_friction": {"Fc": 300.0}})
    plain = Replayer(camp)
    given = measured(plain)
    a, b = plain.simulate(model), given.simulate(model)
    assert [c.supply is not None for c in given.cases] == [True] * len(camp.runs)
    for case, x, y in zip(given.cases, a, b):
        assert "p_s_bar" not in case.signals  # an input is no longer an output compared
        for s in case.signals:
            assert np.max(np.abs(x[s] - y[s])) <= 1e-9 * max(1.0, float(np.max(np.abs(x[s])))), (case.run.name, s)
    # without the option nothing changes: the supply stays the sidecar's, p_s_bar is compared
    assert all(c.supply is None and "p_s_bar" in c.signals for c in plain.cases if c.run.kind == "closed_loop")
    assert input_names(plain) == () and measured(plain, input_names(plain)) is plain
    assert input_names(given) == ("p_s_bar",)


@pytest.mark.parametrize("shift_bar", [-30.0, 30.0])
def test_a_constant_logged_supply_replays_as_a_sidecar_of_that_supply(synthetic_runs, shift_bar):
    """A logged supply 30 bar under (or over) the sidecar's runs the model at the logged value: the same replay as
    the sidecar saying that value (closed loop and bench, pressures capped at it), and not the sidecar's own."""
    logged, declared = [], []
    for n, c, m in _with_supply_log(synthetic_runs):
        logged.append((n, {**c, "p_s_bar": c["p_s_bar"] + shift_bar}, m))
        declared.append((n, c, {**m, "supply_bar": m["supply_bar"] + shift_bar}))
    rep = measured(Replayer(_campaign(logged)))
    a = rep.simulate(ModelSpec())
    b = Replayer(_campaign(declared)).simulate(ModelSpec())
    o = Replayer(_campaign(synthetic_runs)).simulate(ModelSpec())
    for case, x, y, z in zip(rep.cases, a, b, o):
        assert _max_diff(x, y, case.signals) <= 1e-9 * 200.0, case.run.name
        assert _max_diff(x, z, case.signals) > 1e-3, case.run.name


def test_the_bench_flow_follows_the_orifice_law_through_a_step_of_the_logged_supply():
    """At a held current the metered no-load flow is q_c sqrt(P_S / dp_n): a logged step 70 -> 140 bar
    multiplies it by sqrt(2)."""
    dt, n = 1e-3, 2000
    t = np.arange(n) * dt
    cols = {"t": t, "current_mA": np.full(n, 4.0), "flow_lpm": np.zeros(n),
            "p_s_bar": np.where(t < 1.0, 70.0, 140.0)}
    camp = _campaign([("bench_step", cols, {"kind": "valve_open_loop", "supply_bar": 70.0})])
    q = measured(Replayer(camp)).simulate(ModelSpec())[0]["flow_lpm"]
    before, after = q[(t > 0.3) & (t < 0.8)], q[(t > 1.2) & (t < 1.8)]  # the smoothing's edges left out
    assert np.ptp(before) < 1e-9 * before.mean() and np.ptp(after) < 1e-9 * after.mean()
    assert after.mean() / before.mean() == pytest.approx(np.sqrt(2.0), rel=1e-6)
    # without the option the bench stays at the sidecar's 70 bar
    q0 = Replayer(camp).simulate(ModelSpec())[0]["flow_lpm"]
    assert q0[(t > 1.2) & (t < 1.8)].mean() == pytest.approx(before.mean(), rel=1e-9)


def test_the_smoothing_keeps_a_ripple_and_removes_the_noise():
    dt = 1e-3
    t = np.arange(0.0, 3.0, dt)
    rng = np.random.default_rng(4)
    line = 2.0 * np.sin(2 * np.pi * RIPPLE_HZ * t + 0.3)
    noise = 0.3 * rng.standard_normal(t.size)
    y = 210.0 + line + noise
    assert cutoff_hz(y, dt) == pytest.approx(max(MIN_CUTOFF_HZ, LINE_MARGIN * RIPPLE_HZ), rel=0.01)
    s = smoothed(y, dt)
    k = slice(200, -200)  # away from the ends
    amp = np.linalg.lstsq(np.column_stack([np.sin(2 * np.pi * RIPPLE_HZ * t), np.cos(2 * np.pi * RIPPLE_HZ * t)]),
                          s - 210.0, rcond=None)[0]
    assert np.hypot(*amp) == pytest.approx(2.0, rel=0.01)
    assert np.std((s - 210.0 - line)[k]) < 0.4 * np.std(noise)  # most of the white noise is gone
    lag = np.argmax(np.correlate(s[k] - s[k].mean(), line[k], mode="full")) - (s[k].size - 1)
    assert lag == 0  # zero phase


def test_an_unknown_measured_input_is_refused_in_one_line(synthetic_runs):
    camp = _campaign(synthetic_runs)
    with pytest.raises(ValueError, match=r"measured input 'p_t_bar'.*allowed: p_s_bar"):
        measured(Replayer(camp), ("p_t_bar",))
    name = camp.runs[0].name
    with pytest.raises(ValueError, match=rf"inputs\['{name}'\]: 'p_t_bar' is not a quantity.*allowed: p_s_bar"):
        Replayer(camp, inputs={name: {"p_t_bar": np.zeros(camp.runs[0].n)}})
    with pytest.raises(ValueError, match=rf"inputs\['{name}'\]\['p_s_bar'\]: expected {camp.runs[0].n} finite"):
        Replayer(camp, inputs={name: {"p_s_bar": np.zeros(3)}})


# -- the stage, on campaigns of the independent generator -------------------------------------------------------
def _independent(effects: dict, seed: int):
    from tests.independent_rig import campaign as gen

    runs, _ = gen.simulate(effects, seed=seed, duration=1.5, plan=PLAN, perturb=True, valve=False)
    return runs


def _stage(runs):
    camp = _campaign(runs)
    full = Replayer(camp)
    free = recal_params({})
    final = fit(full, free, {(fp.effect, fp.name): start_value(fp) for fp in free}, ModelSpec())
    notes = []
    n = full.n_evals
    f, rec = measured_input_stage(full, full, final, {}, notes.append)
    # the replays it made with the logged input (on copies of the replayer) are counted on the replayer: at least
    # the final model's before and after (the diagnosis' record of the stage counted them as negative)
    assert full.n_evals >= n + (2 if rec["tried"] else 0)
    return f, rec, notes


@pytest.fixture(scope="module")
def clean_runs():
    return _independent({}, seed=11)


def test_a_rippling_supply_is_taken_as_a_measured_input_and_the_residual_falls():
    f, rec, notes = _stage(_independent({"supply_ripple": {"a": 5.0}}, seed=11))
    assert rec["tried"] and rec["kept"] and rec["inputs"] == ["p_s_bar"] and f is not None
    assert rec["variation"]["lines"][0]["frequency_hz"] == pytest.approx(RIPPLE_HZ, abs=0.1)
    assert rec["variation"]["half_range"] == pytest.approx(5.0, rel=0.1)
    before, after = rec["residual_x_noise_before"], rec["residual_x_noise_after"]
    assert after < before and rec["share_removed"] >= 0.5
    assert after < 1.3  # the ripple was what was left: near what does not repeat
    assert re.search(r"varies by \+-[45]\.\d+ bar .* with a line at 23\.[67]\d Hz", rec["text"]), rec["text"]
    assert f"the residual falls {before:.3g} -> {after:.3g}x noise" in rec["text"]
    assert notes  # said while it ran


def test_a_steady_supply_is_left_alone(clean_runs):
    f, rec, _ = _stage(clean_runs)
    assert f is None and rec["logged"] and not rec["tried"] and not rec["kept"] and rec["inputs"] == []
    assert "within its noise" in rec["text"]


def test_a_line_in_the_supply_log_alone_is_tried_and_refused(clean_runs):
    """The transducer shows a line the supply does not have: used as an input it makes the model worse, and
    honesty rule 1 refuses it."""
    runs = []
    for n, c, m in clean_runs:
        t = np.asarray(c["t"])
        runs.append((n, {**c, "p_s_bar": np.asarray(c["p_s_bar"]) + 5.0 * np.sin(2 * np.pi * RIPPLE_HZ * t)}, m))
    f, rec, _ = _stage(runs)
    assert rec["tried"] and not rec["kept"] and f is None and rec["inputs"] == []
    assert rec["share_removed"] < 0.1 and rec["refused"] and "not used" in rec["text"]


def test_the_docs_state_the_numbers_the_code_uses():
    from pathlib import Path

    import ehas_env.diagnosis.measured_inputs as mi
    from ehas_env.diagnosis.honesty import TERM_SHARE

    doc = " ".join((Path(__file__).parents[2] / "docs" / "measurement-format.md").read_text(encoding="utf-8").split())
    words = {2.0: "twice", 4: "4th-order"}
    assert f"{words[mi.FILTER_ORDER]} Butterworth" in doc
    assert f"cutoff is {words[mi.LINE_MARGIN]} the highest spectral line" in doc
    assert f"at least {mi.MIN_CUTOFF_HZ:g} Hz and at most {mi.MAX_CUTOFF_NYQUIST:g} of the Nyquist" in doc
    assert f"above {mi.VARIES_X:g} noise levels" in doc
    assert f"at least {100 * TERM_SHARE:.0f} % of its excess over the noise" in doc


@pytest.mark.slow
def test_the_diagnosis_keeps_a_rippling_supply_and_its_next_line_replays_it(tmp_path):
    """End to end (issue 33, items 4 and 5): ``ehas diagnose`` on a campaign whose supply ripples keeps the logged
    supply as a measured input (the ``measured_inputs`` stage), and the ``next:`` it prints replays the final model
    with it: the comparison's residual is the diagnosis'."""
    import json
    import shlex
    import subprocess
    import sys

    from tests.independent_rig import campaign as gen

    runs, truth = gen.simulate({"supply_ripple": {"a": 5.0}}, seed=12, duration=1.5, plan=PLAN, perturb=True,
                               valve=False)
    camp = gen.write(tmp_path / "camp", runs, truth)
    out = subprocess.run([sys.executable, "-m", "ehas_env.cli.main", "diagnose", str(camp), "--json", "d.json"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    doc = json.loads((tmp_path / "d.json").read_text())
    assert doc["measured_inputs"] == ["p_s_bar"]
    stage = next(r for r in doc["stages"] if r["stage"] == "measured_inputs")
    assert stage["kept"] and stage["share_removed"] >= 0.5
    nxt = re.search(r"^next: (ehas compare .*)$", out.stdout, flags=re.M).group(1)
    assert "--measured-input p_s_bar" in nxt
    args = shlex.split(nxt)[1:] + ["--overwrite"]
    out2 = subprocess.run([sys.executable, "-m", "ehas_env.cli.main", *args], cwd=tmp_path, capture_output=True,
                          text=True, timeout=900)
    assert out2.returncode == 0, out2.stderr[-2000:]
    cmp = json.loads((tmp_path / "compare.json").read_text())
    after = cmp["residual_x_noise"]["after"] if isinstance(cmp["residual_x_noise"], dict) else cmp["residual_x_noise"]
    assert after == pytest.approx(doc["residual_x_noise"], rel=0.15)
