"""Measured disturbances (ehas_env.diagnosis.disturbances, issue 33 item 4).

Truth is analytic: sines of known frequency and amplitude in white noise, and a campaign of the package's
simulator whose logged supply pressure (and chamber pressures) carry a pump's ripple at a frequency unrelated to
the test (added to the logs, so the model cannot have it).
"""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.diagnosis.disturbances import spectral_lines

DT = 1e-3
T = np.arange(0.0, 3.0, DT)


def test_a_line_off_the_harmonics_is_found_with_its_amplitude():
    rng = np.random.default_rng(1)
    e = 0.4 * np.sin(2 * np.pi * 17.3 * T + 0.7) + 0.02 * rng.standard_normal(T.size)
    (f, a), = spectral_lines(e, DT, 2.0)
    assert f == pytest.approx(17.3, abs=0.05) and a == pytest.approx(0.4, rel=0.05)


def test_harmonics_of_the_test_are_the_models_not_disturbances():
    """A missing effect leaves lines at the test frequency and its harmonics: none is a disturbance."""
    rng = np.random.default_rng(2)
    e = sum(0.3 / k * np.sin(2 * np.pi * 2.0 * k * T + k) for k in (1, 2, 3, 5, 7)) + 0.02 * rng.standard_normal(T.size)
    assert spectral_lines(e, DT, 2.0) == []
    # the same lines with no test frequency given are lines
    assert len(spectral_lines(e, DT, None)) >= 3


def test_noise_has_no_lines():
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        coloured = np.convolve(rng.standard_normal(T.size), np.ones(20) / 20, mode="same")  # a smooth wander
        assert spectral_lines(rng.standard_normal(T.size), DT, 1.0) == []
        assert spectral_lines(coloured, DT, 1.0) == []


def _rippled_campaign():
    from ehas_env.measurement.campaign import Campaign, validate_run
    from ehas_env.measurement.synthetic import simulate_campaign

    runs, _ = simulate_campaign({"viscous_friction": {"b": 4000.0}}, seed=7, duration=4.0,
                                plan=((3, 20.0, 1.0), (5, 30.0, 2.0)), valve=False)
    out = []
    for name, cols, meta in runs:
        t = np.asarray(cols["t"])
        ripple = np.sin(2 * np.pi * 23.6 * t)
        cols = {**cols, "p_s_bar": cols["p_s_bar"] + 1.5 * ripple, "p_a_bar": cols["p_a_bar"] + 0.4 * ripple,
                "p_b_bar": cols["p_b_bar"] + 0.4 * ripple}
        out.append(validate_run(name, cols, meta))
    return Campaign(None, out)


def _check(dists):
    d = dists[0]
    assert d["frequency_hz"] == pytest.approx(23.6, abs=0.1)
    assert d["signal"] == "p_s_bar" and d["unit"] == "bar" and d["boundary"]
    assert d["amplitude"] == pytest.approx(1.5, rel=0.1)
    assert d["signals"]["p_a_bar"] == pytest.approx(0.4, rel=0.25)
    assert len(d["runs"]) == 2 and "supply" in d["text"]
    assert not any(abs(x["frequency_hz"] - k * f) < 0.2 for x in dists for f in (1.0, 2.0) for k in range(1, 40))


def test_a_supply_ripple_is_reported_as_a_measured_disturbance():
    """A pump ripple of 1.5 bar at 23.6 Hz on the logged supply (0.4 bar in the chambers), 4 s runs at 1 and 2 Hz
    (after the ramp and a settling cycle, the 1 Hz run keeps 2 s: bins of 0.5 Hz, 23.6 Hz told from 24), replayed
    with the rig's own model (viscous friction 4000 N s/m): reported with its frequency, amplitude and unit,
    strongest in p_s_bar, a disturbance of the supply the model holds constant, seen in the chambers too."""
    from ehas_env.diagnosis.disturbances import disturbances
    from ehas_env.measurement.replay import ModelSpec, Replayer

    rep = Replayer(_rippled_campaign())
    _check(disturbances(rep, rep.simulate(ModelSpec(effects={"viscous_friction": {"b": 4000.0}}))))


@pytest.mark.slow  # a diagnosis: 20-40 s on two cores
def test_the_diagnosis_reports_the_ripple():
    """The same campaign diagnosed (viscous friction the only candidate): the JSON's disturbances say it."""
    from ehas_env.diagnosis.pipeline import diagnose_open

    res = diagnose_open(_rippled_campaign(), candidates=["viscous_friction"], stack=False, hypotheses=False,
                        holdout=[], per_run=False, propose=False)
    _check(res.to_json()["disturbances"])


def _campaign(effects, plan, hum=None):
    """A campaign of the package's simulator with ``effects`` hidden; ``hum`` = (Hz, bar, runs): a line added to the
    logged chamber pressures of those runs (a sensor's mains hum, which knows nothing of the load)."""
    from ehas_env.measurement.campaign import Campaign, validate_run
    from ehas_env.measurement.synthetic import simulate_campaign

    runs, _ = simulate_campaign(effects, seed=3, duration=4.0, plan=plan, valve=False)
    out = []
    for k, (name, cols, meta) in enumerate(runs):
        if hum and k in hum[2]:
            line = hum[1] * np.sin(2 * np.pi * hum[0] * np.asarray(cols["t"]))
            cols = {**cols, "p_a_bar": cols["p_a_bar"] + line, "p_b_bar": cols["p_b_bar"] + line}
        out.append(validate_run(name, cols, meta))
    return Campaign(None, out)


def _closed_loop_damping(effects, sets):
    """The least damping ratio of the book's PI loop (Kp 1 mA/deg, Ki 2 mA/(deg s)) around the linearised plant."""
    import control

    from ehas_env.physics.linearise import linearise
    from ehas_env.simulation.plant import Plant

    lin = linearise(Plant(disc_sets=sets, effects=effects))
    g = control.ss(lin.A, lin.B, lin.C[:1], lin.D[:1])
    poles = control.poles(control.feedback(control.tf([1.0, 2.0], [1.0, 0.0]) * g, 1))
    return min(-p.real / abs(p) for p in poles if p.imag > 0)


RINGING = {"valve_dynamics": {"K": 3.0, "wn": 40.0, "zeta": 0.1}}  # a valve of twice the gain and a tenth the damping


def test_a_rig_that_rings_on_its_own_is_not_called_a_disturbance_from_outside():
    """The truth's loop is unstable (its valve: twice the book's gain, a tenth of its damping; the linearised loop has
    a pair of negative damping at every load) and rings in a limit cycle the current's clip holds; the book's model,
    replayed, is stable.  Its lines move with the load (lower as disc sets are added) and carry harmonics and beats
    with the test: every one is said to be the rig ringing on its own, none a disturbance from outside."""
    from ehas_env.diagnosis.disturbances import disturbances
    from ehas_env.measurement.replay import ModelSpec, Replayer

    plan = ((1, 20.0, 3.0), (4, 20.0, 3.0), (7, 20.0, 3.0))
    assert all(_closed_loop_damping(RINGING, n) < 0.0 < _closed_loop_damping({}, n) for n in (1, 7))
    rep = Replayer(_campaign(RINGING, plan))
    dists = disturbances(rep, rep.simulate(ModelSpec()))
    assert len(dists) >= 3
    assert {d["origin"] for d in dists} == {"mode"}
    assert all("rings on its own" in d["text"] and "from outside the model's loop" not in d["text"] for d in dists)
    fam = sorted(((next(iter(d["disc_sets"].values())), d["frequency_hz"]) for d in dists
                  if "falls as disc sets" in d["origin_why"]), key=lambda x: x[0])
    assert len({n for n, _ in fam}) == 3  # the ringing found at each load


def test_a_line_that_keeps_its_frequency_at_every_load_comes_from_outside():
    """A 17.3 Hz hum of 0.3 bar on both chamber readings of runs at 3 and 5 disc sets (the model of the rig is the
    truth's): one line, the same frequency at both loads, a disturbance from outside the loop."""
    from ehas_env.diagnosis.disturbances import disturbances
    from ehas_env.measurement.replay import ModelSpec, Replayer

    rep = Replayer(_campaign({}, ((3, 20.0, 2.0), (5, 25.0, 2.0)), hum=(17.3, 0.3, (0, 1))))
    (d,) = disturbances(rep, rep.simulate(ModelSpec()))
    assert d["frequency_hz"] == pytest.approx(17.3, abs=0.1) and d["origin"] == "outside"
    assert "from outside the model's loop" in d["text"] and "3 and 5 disc sets" in d["text"]


def test_a_line_seen_at_one_load_only_is_not_placed():
    """The same hum in the 3-set run alone: the words say it may be either, and what would tell."""
    from ehas_env.diagnosis.disturbances import disturbances
    from ehas_env.measurement.replay import ModelSpec, Replayer

    rep = Replayer(_campaign({}, ((3, 20.0, 2.0), (5, 25.0, 2.0)), hum=(17.3, 0.3, (0,))))
    (d,) = disturbances(rep, rep.simulate(ModelSpec()))
    assert d["origin"] == "undetermined" and "runs at other disc sets would tell" in d["text"]
