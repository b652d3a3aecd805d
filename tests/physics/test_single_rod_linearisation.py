"""A single-rod actuator (unequal piston areas): its linearisation, its velocity gain, and tuning on it.

Issue 36: ``ehas tune --model M.json`` stopped with "Singular matrix" on a model whose B-side
piston area differs (``hyp_rod_area``): the operating point put Ps/2 in both chambers, which pushes
the piston when the areas differ, and at null flow the linear model had no steady rate.

The independent truth is the orifice law solved by hand for a critically lapped valve feeding a
piston of areas A and A_B = r A at zero load (extending): the force balance ``A pa = A_B pb`` and the
flows ``A v = q_a``, ``A_B v = q_b`` with ``q = k x sqrt(drop / (Delta p_rated / 2))`` per land give
``Ps - pa = Ps / (1 + r^3)``, so ``v = K i sqrt(2 Ps / ((1 + r^3) Delta p_rated)) / A``.
"""
from __future__ import annotations

import math

import numpy as np
import pytest


def _orifice_rate_deg_s_per_mA(rig, r: float) -> float:
    """Steady crank rate per mA (deg/s) of the extending single-rod piston at zero load, by hand (rig.K in LPM/mA)."""
    q_per_mA = rig.K * 1e-3 / 60.0 * math.sqrt(2.0 * rig.supply / ((1.0 + r ** 3) * rig.rated_drop))  # m^3/s into A

    return math.degrees(q_per_mA / rig.area / rig.radius)


@pytest.fixture(scope="module")
def rod_plant():
    from ehas_env.simulation.plant import Plant

    return Plant(disc_sets=7, effects={"hyp_rod_area": {"d_area": 0.3}})


def test_velocity_gain_of_a_single_rod_matches_the_orifice_law(rod_plant):
    from ehas_env.simulation.linear_model import LinearPlant

    rig = rod_plant.rig
    expected = _orifice_rate_deg_s_per_mA(rig, 0.7)
    assert LinearPlant(rod_plant).velocity_gain == pytest.approx(expected, rel=1e-3)  # was: Singular matrix
    assert LinearPlant(rod_plant, flow_lpm=3.6).velocity_gain == pytest.approx(expected, rel=1e-3)
    # the equal-area rig is the book's 56.25 deg/s per mA, and the formula gives it with r = 1
    assert _orifice_rate_deg_s_per_mA(rig, 1.0) == pytest.approx(56.25, rel=1e-3)


def test_operating_point_of_a_single_rod_is_at_rest_and_steady(rod_plant):
    from ehas_env.physics.linearise import linearise, operating_state

    m, P = rod_plant.model, rod_plant.param_vector
    ds = np.zeros(m.N_STATES)
    s0 = operating_state(rod_plant)
    m.derivatives(s0, m.valve_current(0.0, P), P, ds)
    # at rest: no acceleration (Ps/2 in both chambers gave 47 rad/s^2), and pa = r pb balances the piston
    assert abs(ds[1]) < 1e-6
    assert s0[4] == pytest.approx(0.7 * s0[5], rel=1e-9)
    # the pressures of the small-flow limit: Ps - pa = Ps / (1 + r^3)
    ps = rod_plant.rig.supply
    assert ps - s0[4] == pytest.approx(ps / (1.0 + 0.7 ** 3), rel=1e-4)
    # at the operating flow every pole but the crank angle's integrator is stable (was: one at +0.32 /s)
    lin = linearise(rod_plant, flow_lpm=3.6)
    ev = np.linalg.eigvals(lin.A)
    assert ev.real.max() < 1e-6 * np.abs(ev).max()


def test_model_based_tuning_on_a_single_rod_gives_the_orifice_laws_velocity_feedforward(rod_plant):
    from ehas_controllers.tuners import tune_model_based

    res = tune_model_based(plant=rod_plant)  # was: numpy.linalg.LinAlgError: Singular matrix
    expected = _orifice_rate_deg_s_per_mA(rod_plant.rig, 0.7)
    assert res.report["velocity_gain_deg_s_per_mA"] == pytest.approx(expected, rel=1e-3)
    assert 1.0 / res.controller.Kv == pytest.approx(expected, rel=0.02)
    assert res.report["phase_margin_deg"] == pytest.approx(50.0, abs=0.5)


def test_batch_runs_a_plant_with_a_structural_hypothesis(tmp_path):
    """The tuner's check on the benchmark conditions ran on the model without the hypotheses (ValueError)."""
    import json

    from ehas_controllers.batch_sim import Condition
    from ehas_controllers.benchmark import evaluate_controller
    from ehas_controllers.piff import PIFF
    from ehas_controllers.tune_cli import plant_kwargs_from_model

    f = tmp_path / "rod.json"
    f.write_text(json.dumps({"format": "ehas-model", "version": 2, "kind": "plant",
                             "effects": {"hyp_rod_area": {"d_area": 0.3}}}))
    kw = plant_kwargs_from_model(f)
    rows = evaluate_controller(PIFF(Kp=1.0, Ki=2.0, Kv=1 / 56.25), [Condition(7, 1.0, 10.0)], plant_kwargs=kw)
    assert len(rows) == 1 and math.isfinite(rows[0]["rms_error_pct"]) and rows[0]["rms_error_pct"] < 50.0
