"""Static blocks at a logged reading applied to the replay of the rest (ehas_env.measurement.logged_readings): the
same signals as the compiled model's whole replay, for every such block; one replay of the rest for a screen's many
values; the models it may not part replayed whole."""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.measurement import logged_readings as LR
from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.measurement.replay import ModelSpec, Replayer
from ehas_env.measurement.synthetic import simulate_campaign
from ehas_env.physics.augment import reading_blocks
from ehas_env.physics.effects import get_effect

PLAN = ((3, 20.0, 1.0), (1, 30.0, 3.0))


@pytest.fixture(scope="module")
def rep():
    runs, _ = simulate_campaign({"coulomb_friction": {"Fc": 300.0}}, seed=4601, duration=1.0, plan=PLAN)
    return Replayer(Campaign(None, [validate_run(n, c, m) for n, c, m in runs]))


def _whole(rep, models):
    """The compiled model's own replay of every model (nothing parted)."""
    parted = rep._parted
    rep._parted = lambda m: None
    try:
        return rep.simulate_many(models)
    finally:
        rep._parted = parted


def _middle(name: str) -> dict:
    """Each parameter of ``name`` at its typical middle (a block that acts), in its units."""
    out = {}
    for p in get_effect(name).params:
        lo, hi = p.typical if p.typical else p.range
        out[p.name] = 0.5 * (lo + hi)
    return out


AT_LOGGED = [n for n in reading_blocks() if get_effect(n).signal_place.place in LR.READING_SIGNALS]


def test_every_static_block_at_a_logged_reading_is_applied_to_the_rest_as_the_compiled_model_does(rep):
    assert len(AT_LOGGED) >= 20 and all(LR._array_term(n) is not None for n in AT_LOGGED)
    models = [ModelSpec(effects={"coulomb_friction": {"Fc": 280.0}, name: _middle(name)}, beta=1.05e9)
              for name in AT_LOGGED]
    n0 = rep.n_evals
    parted = rep.simulate_many(models)
    assert rep.n_evals - n0 == 1  # one replay of the rest for all of them
    whole = _whole(rep, models)
    moved = 0
    for name, a, b in zip(AT_LOGGED, parted, whole):
        for i, (x, y) in enumerate(zip(a, b)):
            for sig in y:
                np.testing.assert_allclose(x[sig], y[sig], rtol=1e-12, atol=1e-12, err_msg=f"{name} run {i} {sig}")
        base = _whole(rep, [ModelSpec(effects={"coulomb_friction": {"Fc": 280.0}}, beta=1.05e9)])[0]
        signal = LR.READING_SIGNALS[get_effect(name).signal_place.place][0]
        moved += any(not np.array_equal(x[signal], y[signal]) for x, y in zip(a, base) if signal in x)
    assert moved >= len(AT_LOGGED) - 2  # the blocks act (at their typical middle)


def test_a_screen_of_one_block_replays_its_base_once_and_the_next_call_not_at_all(rep):
    name = "aug_sat_flow_a_reading"
    models = [ModelSpec(effects={name: {"L": L / 60000.0}}) for L in (4.0, 6.0, 9.0, 14.0)]
    n0 = rep.n_evals
    rep.simulate_many(models[:2])
    rep.simulate_many(models[2:])
    assert rep.n_evals - n0 == 1
    # the valve bench's flow is the bench's own: its meter's chain does not act there
    sims = rep.simulate(models[0])
    whole = _whole(rep, [models[0]])[0]
    for x, y, case in zip(sims, whole, rep.cases):
        np.testing.assert_allclose(x["flow_lpm"], y["flow_lpm"], rtol=1e-12, atol=1e-12)
        if case.run.kind == "closed_loop":
            assert np.abs(x["flow_lpm"]).max() <= 4.0 + 1e-9


def test_what_may_not_be_parted_is_replayed_whole(rep):
    # two blocks at one reading, a follower at the reading, a block in the loop: the compiled chain decides
    assert LR.split({"aug_offset_pa_reading": {"c": 1e5}, "aug_gain_pa_reading": {"g": 0.05}}) is None
    assert LR.split({"aug_offset_pa_reading": {"c": 1e5}, "aug_lag_pa_reading": {"T": 2.0}}) is None
    assert LR.split({"aug_sat_position_sensor": {"L": 0.02}}) is None and LR._array_term("aug_lag_pa_reading") is None
    rest, blocks = LR.split({"aug_offset_pa_reading": {"c": 1e5}, "aug_lag_pb_reading": {"T": 2.0}})
    assert list(rest) == ["aug_lag_pb_reading"] and [b[0] for b in blocks] == ["aug_offset_pa_reading"]
    # a model file whose own effects act at the reading
    assert LR.split({"aug_offset_pa_reading": {"c": 1e5}}, others=["aug_lag_pa_reading"]) is None
    n0 = rep.n_evals
    rep.simulate_many([ModelSpec(effects={"aug_offset_pa_reading": {"c": 1e5}, "aug_gain_pa_reading": {"g": 0.05}})])
    assert rep.n_evals - n0 == 1  # replayed whole
