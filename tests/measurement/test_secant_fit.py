"""The fits' secant Jacobian (issue 44, point 1: fewer replays per least-squares step).

Each step of a fit needs the Jacobian of the residual; a forward difference replays the campaign once per fitted
number.  The secant rule (Broyden's rank-one update) takes it from the replay the step made anyway, with a forward
difference every few steps.  Truth: the hidden effect's own values (the package's simulator) and the same fit with
forward differences at every step.
"""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.diagnosis import fitting as D
from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.measurement.replay import Replayer
from ehas_env.measurement.synthetic import simulate_campaign


def _rep(hidden):
    runs, _ = simulate_campaign(hidden, seed=5, perturb=True, duration=2.0,
                                plan=((3, 20.0, 1.0), (5, 25.0, 2.0), (1, 30.0, 3.0)))
    return Replayer(Campaign(None, [validate_run(*r) for r in runs]))


@pytest.mark.parametrize("hidden", [{"coulomb_friction": {"Fc": 400.0}},
                                    {"viscous_friction": {"b": 5000.0}, "internal_leakage": {"C_leak": 4e-12}}],
                         ids=["coulomb", "viscous+leakage"])
def test_the_secant_fit_lands_where_forward_differences_land_with_fewer_replays(hidden):
    rep = _rep(hidden)
    free = [fp for n in hidden for fp in D.own_params(n)] + D.recal_params({})
    start = {(fp.effect, fp.name): D.start_value(fp) for fp in free}
    fits, replays = {}, {}
    for secant in (False, True):
        n0 = rep.n_evals
        fits[secant] = D.fit(rep, free, start, secant=secant)
        replays[secant] = rep.n_evals - n0
    assert fits[True].cost == pytest.approx(fits[False].cost, rel=1e-4)
    for name, params in hidden.items():
        for p, truth in params.items():
            got = fits[True].model.effects[name][p]
            assert got == pytest.approx(fits[False].model.effects[name][p], rel=1e-3)
            assert got == pytest.approx(truth, rel=0.05)
    assert replays[True] < replays[False]


def test_the_secant_jacobian_meets_the_step_it_was_updated_by():
    """After a step du the updated Jacobian maps du onto the residual's change (the secant condition), and at the
    first call it is the forward difference itself."""
    rep = _rep({"coulomb_friction": {"Fc": 400.0}})
    free = D.own_params("coulomb_friction") + D.recal_params({})
    obj = D.Objective(rep, free)
    u0 = np.full(len(free), 0.4)
    w = obj.weights(u0)
    J0 = obj.secant(u0, w)
    assert np.allclose(J0, obj.jacobian(u0, w))
    u1 = u0 + np.array([0.05, -0.02, 0.01])[: len(free)]
    J1 = obj.secant(u1, w)
    dr = obj.weighted(u1, w) - obj.weighted(u0, w)
    assert np.allclose(J1 @ (u1 - u0), dr, rtol=1e-9, atol=1e-9 * np.abs(dr).max())
