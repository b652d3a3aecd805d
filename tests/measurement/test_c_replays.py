"""Replays on the C compiler's build of the drivers (ehas_env/physics/c_drivers.py) are numba's, element for
element.

The truth is numba's compile of the very same text (the drivers ``closed_loop`` and ``run_valve_test`` with the
model they call): a translation that changed an operation's order, a rounding, a branch or an argument would show
as a difference in some sample of some signal.  Cases: the book model and library effects (closed loop and the
valve bench), a measured supply (the optional argument given, on both drivers), a state of an effect's own, and --
slow, the larger model's numba compile takes about half a minute -- a structural hypothesis, a block with a state
and a proposed term.
"""
from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest

from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.measurement.replay import ModelSpec, Replayer
from ehas_env.measurement.synthetic import simulate_campaign
from ehas_env.physics.c_drivers import c_drivers
from ehas_env.physics.rig import BAR

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None,
                                reason="no C compiler on this machine")


@pytest.fixture(scope="module")
def campaign():
    runs, _ = simulate_campaign({"coulomb_friction": {"Fc": 300.0}}, seed=3, perturb=True, duration=1.0,
                                plan=((3, 20.0, 2.0), (6, 15.0, 1.0)))
    return Campaign(None, [validate_run(*r) for r in runs])


def _both(rep: Replayer, model: ModelSpec) -> list:
    """Every run of ``rep`` replayed with ``model`` on numba's drivers and on the C build: [(numba out, C out)]."""
    pairs = []
    for case in rep.cases:
        outs = []
        for built in (False, True):
            job = rep._prepare(model, case)
            name = "run_valve_test" if job.s0 is None else "closed_loop"
            fn = getattr(c_drivers(job.mod), name) if built else getattr(job.mod, name)
            fn(*rep._driver_args(job))
            outs.append(job.out.copy())
        pairs.append(tuple(outs))
    return pairs


def _same(pairs) -> None:
    assert pairs
    for numba_out, c_out in pairs:
        assert numba_out.shape == c_out.shape and np.isfinite(numba_out).all()
        assert np.abs(numba_out).max() > 0.0  # a replay that ran
        np.testing.assert_array_equal(c_out, numba_out)


@pytest.mark.parametrize("effects", [{}, {"coulomb_friction": {"Fc": 250.0}, "internal_leakage": {}},
                                     {"valve_dynamics": {}}])
def test_a_replay_on_the_c_drivers_is_numbas_element_for_element(campaign, effects):
    rep = Replayer(campaign)
    assert {c.run.kind for c in rep.cases} == {"closed_loop", "valve_open_loop"}
    _same(_both(rep, ModelSpec(effects=effects)))


def test_with_a_measured_supply_both_drivers_take_it_and_agree(campaign):
    rep = Replayer(campaign)
    t = [np.arange(c.n_sim if c.run.kind == "closed_loop" else c.run.n) for c in rep.cases]
    # a supply that ripples 8 bar at 23 Hz about 70 bar, one value per simulation step (Pa)
    rep.cases = [dataclasses.replace(c, supply=(70.0 + 8.0 * np.sin(2 * np.pi * 23.0 * k * c.dt)) * BAR)
                 for c, k in zip(rep.cases, t)]
    pairs = _both(rep, ModelSpec(effects={"coulomb_friction": {"Fc": 250.0}}))
    _same(pairs)
    plain = _both(Replayer(campaign), ModelSpec(effects={"coulomb_friction": {"Fc": 250.0}}))
    assert any(not np.array_equal(a[0], b[0]) for a, b in zip(pairs, plain))  # the supply was used


def test_the_replayer_runs_on_the_c_drivers_unless_told_numba(campaign, monkeypatch):
    rep = Replayer(campaign)
    job = rep._prepare(ModelSpec(), rep.cases[0])
    assert job.driver is not getattr(job.mod, job.driver.__name__)  # the C build's
    c_sims = rep.simulate(ModelSpec())
    monkeypatch.setenv("EHAS_DRIVERS", "numba")
    assert rep._prepare(ModelSpec(), rep.cases[0]).driver is getattr(job.mod, job.driver.__name__)
    numba_sims = rep.simulate(ModelSpec())
    for a, b in zip(c_sims, numba_sims):
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def test_a_driver_called_wrongly_is_refused_in_one_line(campaign):
    rep = Replayer(campaign)
    job = rep._prepare(ModelSpec(), rep.cases[0])
    args = list(rep._driver_args(job))
    with pytest.raises(TypeError, match="closed_loop: out must be a C-ordered float64 array of 2 dimension"):
        job.driver(*args[:-1], np.asfortranarray(args[-1]) if args[-1].shape[0] > 1 else args[-1][:, :1].T)
    with pytest.raises(TypeError, match="closed_loop takes 16 arguments"):
        job.driver(*args[:3])


@pytest.mark.slow
def test_the_larger_models_replays_on_the_c_drivers_are_numbas(campaign):
    """A structural hypothesis, a block with a state of its own and a proposed term (the extended model)."""
    rep = Replayer(campaign, hypotheses=True)
    _same(_both(rep, ModelSpec(effects={"hyp_coil_lag": {"T": 2.0}, "aug_lag_force_reading": {}})))
    _same(_both(rep, ModelSpec(effects={"coulomb_friction": {"Fc": 250.0}},
                               terms={"proposal_piston_force": {"c_v": 800.0}})))


def test_a_library_built_before_is_loaded_not_built_again(campaign, tmp_path, monkeypatch):
    from ehas_env.physics.c_drivers import CDrivers

    monkeypatch.setenv("EHAS_CACHE_DIR", str(tmp_path))
    rep = Replayer(campaign)
    job = rep._prepare(ModelSpec(), rep.cases[0])
    first = CDrivers(job.mod)  # built here: the empty cache has no library
    (lib,) = (tmp_path / "c").glob("*.so")
    assert not [p for p in (tmp_path / "c").iterdir() if p.name.startswith(".")]  # no half-written file left
    built_at = lib.stat().st_mtime_ns
    again = CDrivers(job.mod)  # loaded: not built again, the signatures read from the model's text
    assert lib.stat().st_mtime_ns == built_at and again.signatures == first.signatures
    outs = []
    for drivers in (first, again):
        job = rep._prepare(ModelSpec(), rep.cases[0])
        drivers.closed_loop(*rep._driver_args(job))
        outs.append(job.out.copy())
    np.testing.assert_array_equal(outs[0], outs[1])
