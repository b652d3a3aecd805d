"""The time a diagnosis says at its start (ehas_env.diagnosis.estimate, issue 44 point 5): its parts, against the
count of replays the search makes and a campaign's own book figure."""
from __future__ import annotations

import pytest

from ehas_env.diagnosis import estimate as E
from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.measurement.replay import Replayer
from ehas_env.measurement.synthetic import simulate_campaign


def _rep(effects, seed):
    runs, _ = simulate_campaign(effects, seed=seed, duration=1.0, plan=((3, 20.0, 1.0), (1, 30.0, 3.0)))
    return Replayer(Campaign(None, [validate_run(n, c, m) for n, c, m in runs]))


def test_the_estimate_counts_replays_by_the_book_figure_and_the_library_and_leaves_the_search_count_alone():
    clean = _rep(None, 4401)
    friction = _rep({"coulomb_friction": {"Fc": 900.0}}, 4402)  # one library effect ends it
    lag = _rep({"hyp_return_pressure": {"p_t": 20.0}}, 4403)  # nothing of the library does (a return line at 20 bar)
    a, b, c = E.estimate(clean), E.estimate(friction), E.estimate(lag)
    assert clean.n_evals == friction.n_evals == lag.n_evals == 0  # the timing and probing replays are not the search's
    assert a["book_x_noise"] < 2.0 < 4.0 < min(b["book_x_noise"], c["book_x_noise"])
    assert a["replays"] == E.REPLAYS[0][1]
    assert (b["replays"], b["library_effect"]) == (E.LIBRARY_REPLAYS, "coulomb_friction")
    assert b["library_share_left"] <= E.LIBRARY_SHARE < c["library_share_left"]
    assert c["replays"] == E.REPLAYS[-1][1]
    first = E.REPLAYS[0][1]  # replays as timed; those beyond cost SEARCH_REPLAY_COST times as much
    for est in (a, b, c):
        assert est["replay_s"] > 0.0
        n = est["replays"]
        assert est["estimate_s"] == pytest.approx(
            E.FIXED_S + est["replay_s"] * (min(n, first) + E.SEARCH_REPLAY_COST * max(n - first, 0)),
            abs=0.1 + n * E.SEARCH_REPLAY_COST * 5e-5)
    # the search beyond the library's rounds is the dearer part: the long estimate more than its count's share
    assert c["estimate_s"] / c["replay_s"] > 1.5 * c["replays"]
    loaded = E.estimate(clean, load_scale=2.0)  # its replays timed anew: compare with its own replay time
    assert loaded["estimate_s"] == pytest.approx(2.0 * E.FIXED_S + loaded["replays"] * loaded["replay_s"],
                                                 abs=0.1 + loaded["replays"] * 5e-5)
    assert "expected: about" in E.in_words(c) and f"{c['replays']} replays" in E.in_words(c)


def test_a_miss_in_one_reading_that_the_overall_figure_dilutes_counts_as_a_search_that_goes_on():
    """An offset of 1 bar in chamber B's reading leaves the book model's overall figure at or below 2 (one signal of
    five) but that reading far above what the verdict calls explained: the hypotheses and the states run, so the
    estimate counts the replays of a figure between 2 and 4, not a clean campaign's."""
    from ehas_env.measurement.replay import COST_SIGNALS, ModelSpec
    from ehas_env.measurement.verdict import BLOCK_EXPLAINED_X, blocks_of, grade

    rep = _rep({"aug_offset_pb_reading": {"c": 1.0e5}}, 4404)
    g = grade(blocks_of(rep, rep.simulate(ModelSpec()), COST_SIGNALS))
    assert g["residual_x_noise"] <= E.REPLAYS[0][0] < 1.0 + BLOCK_EXPLAINED_X < g["worst"]["residual_x_noise"]
    assert E.estimate(rep)["replays"] == E.REPLAYS[1][1]
