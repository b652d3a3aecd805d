"""A fit steered by coarse replays (issue 44, point 3: less work per replay): the scan's grid and the least-squares
steps' Jacobian on the replayer at fewer integrator sub-steps (``fitting.COARSE_SUBSTEPS``), trusted only where a full
replay at the same point agrees within ``fitting.COARSE_TOL`` of the noise; every cost a decision reads stays the
full replay's.  Truth here: the same fit on full replays alone (an independent path through the same code), and a
stiff model that the guard must refuse."""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.diagnosis import fitting
from ehas_env.diagnosis.fitting import Objective, fit, own_params, start_value
from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.measurement.replay import ModelSpec, Replayer
from ehas_env.measurement.synthetic import simulate_campaign


@pytest.fixture(scope="module")
def rep():
    runs, _ = simulate_campaign({"coulomb_friction": {"Fc": 350.0}}, seed=41, duration=1.5)
    return Replayer(Campaign(None, [validate_run(n, c, m) for n, c, m in runs]))


def test_a_coarse_replayer_counts_its_replays_in_its_owner_and_refuses_more_substeps(rep):
    c = rep.coarse(fitting.COARSE_SUBSTEPS)
    assert c.substeps == fitting.COARSE_SUBSTEPS and c.cases is rep.cases and rep.coarse(rep.substeps) is rep
    n, k = rep.n_evals, rep.n_coarse
    c.simulate_many([ModelSpec(), ModelSpec()])
    assert (rep.n_evals - n, rep.n_coarse - k, c.n_evals) == (2, 2, 0)
    with pytest.raises(ValueError, match="coarse substeps: expected 1 to 9"):
        rep.coarse(12)


def test_the_fit_steered_by_coarse_replays_lands_where_the_full_replays_alone_land(rep, monkeypatch):
    """A Coulomb friction fitted from the middle of its range with a scan: the same value within a tenth of its
    own interval's scale (0.5 N of 350), the same cost within 1e-4 of itself, with at least a third of the
    replays coarse."""
    free = own_params("coulomb_friction")
    start = {(fp.effect, fp.name): start_value(fp) for fp in free}
    fixed = ModelSpec(effects={"coulomb_friction": {}})
    n0, c0 = rep.n_evals, rep.n_coarse
    steered = fit(rep, free, start, fixed, scan=free[0])
    n1, c1 = rep.n_evals - n0, rep.n_coarse - c0
    monkeypatch.setattr(fitting, "COARSE_SUBSTEPS", rep.substeps)  # no coarse replays: the full path
    full = fit(rep, free, start, fixed, scan=free[0])
    assert rep.n_coarse - c0 == c1 and c1 >= n1 / 3
    a, b = steered.model.effects["coulomb_friction"]["Fc"], full.model.effects["coulomb_friction"]["Fc"]
    assert a == pytest.approx(350.0, rel=0.05) and a == pytest.approx(b, abs=0.5)
    assert steered.cost == pytest.approx(full.cost, rel=1e-4)


def test_the_guard_refuses_coarse_replays_of_a_stiff_model_and_the_jacobian_is_then_the_full_one(rep):
    """The stiffest rod-crank link (its spring at the top of its fit range): 4 sub-steps a control period miss
    it by far more than the tolerance, so the objective drops them and its Jacobian is the full replays'."""
    free = own_params("aug_link_rod_crank")
    fixed = ModelSpec(effects={"aug_link_rod_crank": {}})
    u = np.array([1.0 if fp.name == "k_link" else fp.u(start_value(fp)) for fp in free])
    stiff = Objective(rep, free, fixed, coarse=True)
    assert stiff.cheap is not None
    w = stiff.weights(u)
    J = stiff.jacobian(u, w)
    assert stiff.cheap is None  # not trusted at u
    J_full = Objective(rep, free, fixed).jacobian(u, w)
    np.testing.assert_array_equal(J, J_full)


def test_a_trusted_coarse_jacobian_is_the_full_one_within_the_integration_error(rep):
    free = own_params("coulomb_friction")
    fixed = ModelSpec(effects={"coulomb_friction": {}})
    u = np.array([fp.u(300.0) for fp in free])
    obj = Objective(rep, free, fixed, coarse=True)
    w = obj.weights(u)
    J = obj.jacobian(u, w)
    assert obj.cheap is not None  # trusted
    J_full = Objective(rep, free, fixed).jacobian(u, w)
    assert np.linalg.norm(J - J_full) <= 0.01 * np.linalg.norm(J_full)
