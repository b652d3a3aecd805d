"""The state stage (ehas_env.diagnosis.states): its gates, and the augmentation it keeps on campaigns
simulated with one (the package's synthetic campaign writer: a consistency test) and on a clean campaign."""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.diagnosis.candidates import FIT_WINDOW_S, fit_null
from ehas_env.diagnosis.search import data_stage
from ehas_env.diagnosis import states
from ehas_env.diagnosis.states import judge, state_stage
from ehas_env.measurement.synthetic import simulate_campaign
from ehas_env.physics.augment import reading_blocks
from ehas_env.physics.balance_blocks import BALANCE_KINDS, balance_blocks
from ehas_env.physics.effects import REGISTRY, get_effect

#: what the stage tries in these tests: a lag at each of its two places and a link at each of its two (the hoses
#: and the play are tried by the full list; four keep the test's replays few)
TRIED = ["aug_lag_coil", "aug_lag_position_sensor", "aug_link_rod_crank", "aug_link_mount"]


def test_judge_keeps_what_removes_enough_and_lowers_the_validation():
    assert judge(3.0, 2.0, 4.0, 3.0) is None
    assert judge(3.0, 2.0, None, None) is None  # no validation samples: the all-data rule alone


def test_judge_refuses_what_removes_less_than_a_tenth_of_the_excess():
    # 3.0 -> 2.81 removes 9.5 % of the excess 2.0 over the noise; 2.79 removes 10.5 %
    assert "less than the 10 %" in judge(3.0, 2.81, 4.0, 3.0)
    assert judge(3.0, 2.79, 4.0, 3.0) is None


def test_judge_refuses_what_does_not_lower_the_validation_residual():
    assert "validation residual" in judge(3.0, 2.0, 4.0, 4.1)
    assert "validation residual" in judge(3.0, 2.0, 4.0, 3.95)  # lower, but by less than the share (2 %)


def test_a_block_the_held_out_runs_never_reach_must_remove_half_the_excess():
    """The validation gate cannot judge a block the held-out runs never reach (it moves them by less than
    UNEXERCISED): it must then remove half the all-data excess, not a tenth (the unlisted pair of a pump's ripple and
    a rate limit at the coil kept a knee of the position sensor's reading that removed 11.5 %)."""
    unreached = 0.5 * states.UNEXERCISED
    # 3.0 -> 2.2 removes 40 % of the excess 2.0: enough for a proven block, not for an unproven one
    assert "held-out runs never reach it" in judge(3.0, 2.2, 4.0, 4.0, val_moved=unreached)
    assert "40 %" in judge(3.0, 2.2, 4.0, 4.0, val_moved=unreached)
    assert judge(3.0, 1.9, 4.0, 4.0, val_moved=unreached) is None  # 55 %
    assert judge(3.0, 2.2, 4.0, 3.0, val_moved=1.0) is None  # reached, and the validation residual falls
    assert judge(3.0, 2.2, None, None, val_moved=None) is None  # no validation samples: the all-data rule alone


def test_the_blocks_the_fitted_runs_cannot_part_from_the_kept_one_are_listed_closest_first():
    """Within 0.3 dB of the kept block's screened cost (x1.072): listed with their cost over its, closest first; a
    block screened on two bases once, at its better; one 0.35 dB above, not."""
    from types import SimpleNamespace as NS

    cost = {("aug_offset_pa_reading", None): 0.7519, ("aug_offset_pb_reading", None): 0.7553,
            ("aug_const_return", None): 0.7855, ("aug_const_return", ("hyp_x",)): 0.7700,
            ("aug_lag_pb_reading", None): 0.7519 * 10 ** 0.035}
    screened = {k: (NS(cost=c), None) for k, c in cost.items()}
    near = states._within(screened, ("aug_offset_pa_reading", None))
    assert [n["effect"] for n in near] == ["aug_offset_pb_reading", "aug_const_return"]
    assert near[1]["cost_ratio"] == pytest.approx(0.77 / 0.7519, abs=1e-4)
    assert "return pressure" in near[1]["where"]


def _refine_table(monkeypatch, refit: dict, insane=()):
    """``states.refine_candidate`` and ``states.sanity`` replaced by tables: a block's refit costs ``refit[name]``;
    a block in ``insane`` ran to an end of its range (screen and refit alike); the refits made are counted."""
    from types import SimpleNamespace as NS

    made = []

    def refine(rep, name, f, base, effects):
        made.append(name)
        return NS(cost=refit[name], name=name)

    monkeypatch.setattr(states, "refine_candidate", refine)
    monkeypatch.setattr(states, "sanity", lambda f, name: "at an end" if getattr(f, "name", name) in insane
                        and not hasattr(f, "refit_sane") else None)
    monkeypatch.setattr(states, "_projected_start", lambda rep, name, lead, fit: None)  # its own test below
    return made


def _screens(costs: dict) -> dict:
    from types import SimpleNamespace as NS

    return {(n, None): (NS(cost=c), NS(model=NS(effects={}))) for n, c in costs.items()}


def test_the_place_is_chosen_on_the_refitted_cost_among_the_first_places(monkeypatch):
    """Screens (own numbers alone) rank an offset of chamber A's reading first and the return's constant term 0.19
    dB behind; refitted with the model's numbers the return's term is far ahead (drawn case d00: the recalibrated
    beta and K had taken over part of a back pressure at the return): the return is the place.  A place more than
    PLACE_DB (0.3 dB) behind the best screen is not refitted; one refit per place refitted."""
    made = _refine_table(monkeypatch, {"aug_offset_pa_reading": 0.75, "aug_offset_pb_reading": 0.755,
                                       "aug_const_return": 0.46, "aug_lag_pb_reading": 0.1})
    lower = _screens({"aug_offset_pa_reading": 0.7519, "aug_offset_pb_reading": 0.7553, "aug_const_return": 0.7855,
                      "aug_lag_pb_reading": 0.7519 * 10 ** 0.035})
    key, refined, rec = states._refined_choice(None, dict(lower), lower)
    assert key == ("aug_const_return", None) and refined[key].cost == 0.46
    # the places' best refitted once each, the kind at the place chosen again from where it stopped (no gain: once)
    assert sorted(made) == ["aug_const_return", "aug_const_return", "aug_offset_pa_reading", "aug_offset_pb_reading"]
    assert [r["effect"] for r in rec] == sorted(set(made), key=made.index)
    assert rec[-1]["refined_ratio"] == pytest.approx(0.46 / 0.7519, abs=1e-4) and rec[-1]["rounds"] == 1
    assert [r["rounds"] for r in rec[:-1]] == [0, 0]  # the readings' offsets: one refit each, no more
    # the kept block's rivals are compared on the refitted costs where they were refitted (the readings' offsets:
    # parted from it), on the screens where not (the lag: 1.038x its screen, within 0.3 dB, listed)
    assert [n["effect"] for n in states._within(lower, key, refined)] == ["aug_lag_pb_reading"]


def test_at_the_place_the_simplest_kind_the_refits_cannot_part_is_kept(monkeypatch):
    """At the return: a saturating term (two numbers) refits 0.1 dB below a proportional one (one number): the logs
    cannot part them (WITHIN_DB, 0.3 dB), the proportional term is kept (drawn case d21: a saturating term whose
    knee lies beyond the logged openings).  Refitted 0.5 dB below it, the saturating term is kept -- also when its
    screen ran to an end of its range (the held numbers pushed its break out of place) and its refit is sane; a
    kind whose screen is more than KIND_DB (1 dB) behind the place's best is not refitted."""
    screens = {"aug_prop_return": 0.80, "aug_saturating_return": 0.82, "aug_cubic_return": 0.80 * 10 ** 0.11}
    lower = _screens(screens)
    _refine_table(monkeypatch, {"aug_prop_return": 0.50, "aug_saturating_return": 0.50 * 10 ** -0.01,
                                "aug_cubic_return": 0.1})
    key, refined, _ = states._refined_choice(None, dict(lower), lower)
    assert key == ("aug_prop_return", None)
    made = _refine_table(monkeypatch, {"aug_prop_return": 0.50, "aug_saturating_return": 0.50 * 10 ** -0.05,
                                       "aug_cubic_return": 0.1})
    better = {k: v for k, v in lower.items() if k[0] != "aug_saturating_return"}
    key, refined, _ = states._refined_choice(None, better, lower)
    assert key == ("aug_saturating_return", None) and "aug_cubic_return" not in made
    made = _refine_table(monkeypatch, {"aug_prop_return": 0.50, "aug_saturating_return": 0.40,
                                       "aug_cubic_return": 0.1}, insane={"aug_saturating_return"})
    key, refined, _ = states._refined_choice(None, better, lower)
    assert key == ("aug_prop_return", None) and "aug_saturating_return" in made  # refitted, and still at its end


def test_a_kind_with_more_numbers_must_also_lower_the_validation_residual(monkeypatch):
    """At chamber A's balance a piecewise-linear term (three numbers) refits 0.8 dB below a term beyond a threshold
    (two): kept when its refit also lowers the beyond term's validation residual by the keep gate's share (2 %),
    else the simpler kind is (drawn case d15: a relief above 45 bar named a piecewise-linear term); the validation
    residuals are in the record."""
    from types import SimpleNamespace as NS

    costs = {"aug_knee_chamber_a": 0.50, "aug_beyond_chamber_a": 0.50 * 10 ** 0.08}
    lower = _screens({"aug_knee_chamber_a": 0.80, "aug_beyond_chamber_a": 0.80 * 10 ** 0.08})
    monkeypatch.setattr(states, "refine_candidate",
                        lambda rep, name, f, base, eff: NS(cost=costs[name], model=NS(name=name)))
    monkeypatch.setattr(states, "sanity", lambda f, name: None)
    monkeypatch.setattr(states, "_projected_start", lambda rep, name, lead, fit: None)
    full = NS(simulate=lambda model: model.name)  # a "simulation" is the refit's name: _parts_cost looks it up
    for v_knee, kept in ((1.30 * 0.97, "aug_knee_chamber_a"), (1.30 * 0.99, "aug_beyond_chamber_a"),
                         (1.40, "aug_beyond_chamber_a")):
        vals = {"aug_knee_chamber_a": v_knee, "aug_beyond_chamber_a": 1.30}
        monkeypatch.setattr(states, "_parts_cost", lambda full, sims, parts: vals[sims])
        key, refined, rec = states._refined_choice(None, dict(lower), lower, full, {0: 0})
        assert key == (kept, None), (v_knee, rec)
        assert {r["effect"]: r["validation"] for r in rec} == pytest.approx(vals, rel=1e-3)
    # without validation samples the fit alone decides
    monkeypatch.setattr(states, "_parts_cost", lambda full, sims, parts: None)
    key, _, _ = states._refined_choice(None, dict(lower), lower, full, {})
    assert key == ("aug_knee_chamber_a", None)


def test_the_kinds_at_the_place_are_compared_refitted_while_that_pays(monkeypatch):
    """A term beyond a threshold whose first refit leaves its break out of place (0.60) and whose second finds it
    (0.45) is compared at its best with a piecewise-linear term that a number more lets cover for the misplaced
    break at once (0.50): the term beyond the threshold is kept (drawn case d15)."""
    from types import SimpleNamespace as NS

    lower = _screens({"aug_knee_chamber_a": 0.80, "aug_beyond_chamber_a": 0.81})
    steps = {"aug_knee_chamber_a": [0.50], "aug_beyond_chamber_a": [0.60, 0.45]}

    def refine(rep, name, f, base, effects):
        seq = steps[name]
        return NS(cost=seq.pop(0) if len(seq) > 1 else seq[0], name=name)

    monkeypatch.setattr(states, "refine_candidate", refine)
    monkeypatch.setattr(states, "sanity", lambda f, name: None)
    monkeypatch.setattr(states, "_projected_start", lambda rep, name, lead, fit: None)
    key, refined, rec = states._refined_choice(None, dict(lower), lower)
    assert key == ("aug_beyond_chamber_a", None) and refined[key].cost == 0.45, rec


def test_a_kind_left_in_a_valley_is_refitted_from_the_best_kinds_term(monkeypatch):
    """Chamber A's balance: a relief above 45 bar.  The piecewise-linear term (three numbers) finds it, its slope
    within nil; the term beyond a threshold, from its own screen's break at 1 bar, stops in a valley 1.2x behind.
    Refitted from the piecewise-linear term's fitted term (its nearest numbers: the break at 45 bar), it reaches it,
    and the simpler kind is kept; a projection that does not help leaves the first refit (and the choice) as it was.
    The fit here is a table of where a start leads: a refit from a break within 10 % of 45 bar reaches the valley's
    floor."""
    from types import SimpleNamespace as NS

    pa = np.linspace(1.0e5, 1.1e7, 400)
    knee = {"c": 0.0, "d": -2.0e-6, "k": 4.5e6}
    lead = NS(cost=0.50, model=states.ModelSpec(effects={"aug_knee_chamber_a": knee}), sims=["sim"])
    monkeypatch.setattr(states, "_balance_quantity", lambda rep, sims, cls: [pa[:200], pa[200:]])

    def refine(rep, name, f, base, effects):
        if name == "aug_knee_chamber_a":
            return lead
        k = f.model.effects.get(name, {}).get("k", 1.0e5)  # the screen's start: 1 bar
        return NS(cost=0.50 * 10 ** 0.01 if abs(k / 4.5e6 - 1.0) < 0.1 else 0.60, name=name,
                  model=NS(effects={name: {"k": k}}))

    monkeypatch.setattr(states, "refine_candidate", refine)
    monkeypatch.setattr(states, "sanity", lambda f, name: None)
    lower = {("aug_knee_chamber_a", None): (NS(cost=0.80), NS(model=NS(effects={}))),
             ("aug_beyond_chamber_a", None): (NS(cost=0.81, model=NS(effects={})), NS(model=NS(effects={})))}
    key, refined, rec = states._refined_choice(None, dict(lower), lower)
    assert key == ("aug_beyond_chamber_a", None) and refined[key].cost == pytest.approx(0.50 * 10 ** 0.01), rec
    beyond = [r for r in rec if r["effect"] == "aug_beyond_chamber_a"][0]
    assert beyond["projected_ratio"] == pytest.approx(0.50 * 10 ** 0.01 / 0.80, abs=1e-4)
    # the start it was given: the knee's term as a term beyond a threshold (the break, the slope beyond)
    start = states._projected_start(None, "aug_beyond_chamber_a", "aug_knee_chamber_a", lead)
    assert start.model.effects["aug_beyond_chamber_a"] == pytest.approx({"c": -2.0e-6, "k": 4.5e6}, rel=1e-3)
    assert "aug_knee_chamber_a" not in start.model.effects
    # blocks that are not two static kinds at one balance: no projection
    assert states._projected_start(None, "aug_lag_pb_reading", "aug_knee_chamber_a", lead) is None
    assert states._projected_start(None, "aug_beyond_chamber_b", "aug_knee_chamber_a", lead) is None
    # a projection that leads nowhere better: the kind keeps its own refit, the knee is kept
    monkeypatch.setattr(states, "refine_candidate", lambda rep, name, f, base, effects: lead if name ==
                        "aug_knee_chamber_a" else NS(cost=0.60, name=name, model=NS(effects={})))
    key, refined, rec = states._refined_choice(None, dict(lower), lower)
    assert key == ("aug_knee_chamber_a", None) and refined[("aug_beyond_chamber_a", None)].cost == 0.60


def _search(effects, seed):
    runs, truth = simulate_campaign(effects, seed=seed, duration=3.5)
    camp = Campaign(None, [validate_run(n, c, m) for n, c, m in runs])
    s = data_stage(camp, window_s=FIT_WINDOW_S, hypotheses=True)
    return s, fit_null(s.rep)


@pytest.mark.slow  # a 5-run campaign, four augmentations screened (about 2 min on 2 cores)
@pytest.mark.parametrize("effect,params,main,seed", [
    ("aug_lag_position_sensor", {"T": 8.0}, "T", 3301),
    ("aug_link_rod_crank", {"k_link": 3.0e6, "m_link": 20.0}, "k_link", 3302),
])
def test_the_stage_keeps_the_augmentation_the_campaign_was_simulated_with(effect, params, main, seed):
    s, null = _search({effect: params}, seed)
    lines = []
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lines.append, names=TRIED)
    assert rec["kept"] == effect, rec
    assert [t["effect"] for t in rec["tried"]] == TRIED and len(lines) >= len(TRIED)
    assert fit is not None and effect in fit.model.effects
    assert rec["params"][main] == pytest.approx(params[main], rel=0.3)
    lo, hi = rec["ci95"][main]
    assert lo <= rec["params"][main] <= hi
    assert rec["residual_x_noise_all_after"] < rec["residual_x_noise_all_before"]
    assert rec["words"].startswith(("a first-order lag of", "a spring of"))


@pytest.mark.slow  # as above
def test_a_clean_campaign_keeps_no_augmentation():
    s, null = _search(None, 3303)
    # the gates alone (trigger 0: the stage runs however little is left) ...
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=TRIED, trigger=0.0)
    assert fit is None and rec["kept"] is None and rec["words"] and rec["skipped"] is None, rec
    assert len(rec["tried"]) == len(TRIED)
    # ... and by default the stage does not run on a model the campaign leaves at the noise
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=TRIED)
    assert fit is None and rec["tried"] == [] and "no state is looked for" in rec["skipped"]


@pytest.mark.slow  # a 5-run campaign, a delay fitted, then the rate limit screened and refitted (about 2 min)
def test_a_state_that_fails_on_top_of_its_stand_in_is_kept_in_its_place():
    """A campaign simulated with a rate-limited coil current (the package's synthetic writer): a transport delay
    fitted first stands in for it.  The stage keeps the rate limit -- on top of the delay when that passes the
    gates, else in its place (``in_place_of``) with the delay gone -- and finds S."""
    from ehas_env.diagnosis.candidates import fit_candidate

    s, null = _search({"aug_slew_coil": {"S": 250.0}}, 3308)
    delayed = fit_candidate(s.rep, "transport_delay", null)
    assert delayed.cost < null.cost  # the delay does stand in for part of it
    fit, rec = state_stage(s.rep, s.full, delayed, s.parts, lambda m: None, names=["aug_slew_coil"], trigger=0.0)
    assert rec["kept"] == "aug_slew_coil", rec
    assert rec["params"]["S"] == pytest.approx(250.0, rel=0.3)
    assert ("transport_delay" in fit.model.effects) == (rec["in_place_of"] is None)
    assert rec["residual_x_noise_all_after"] < rec["residual_x_noise_all_before"]


@pytest.mark.slow
def test_refit_without_refits_the_model_without_the_effect():
    from ehas_env.diagnosis.candidates import fit_candidate, refit_without

    s, null = _search({"aug_slew_coil": {"S": 250.0}}, 3308)
    both = fit_candidate(s.rep, "aug_slew_coil", fit_candidate(s.rep, "transport_delay", null),
                         {"transport_delay": {}})
    g = refit_without(s.rep, both, "transport_delay")
    assert set(g.model.effects) == set(both.model.effects) - {"transport_delay"}
    # without the stand-in the rate limit alone explains the campaign it made (to the noise, 1 = noise)
    assert g.cost < 1.5


@pytest.mark.slow  # a 5-run campaign, a bulk modulus fitted, then a pair of hoses screened on two models
def test_a_state_behind_a_stand_in_is_found_on_the_model_without_it():
    """A campaign simulated with a pair of small hoses (the package's synthetic writer): a soft bulk modulus takes
    over part of the lines' compliance first.  Screened on that model alone the hoses do not fit (what they add
    the bulk modulus holds); screened also on the model without it (``bare``) they are kept in its place, with
    their volume and resistance near the campaign's."""
    from ehas_env.diagnosis.candidates import fit_candidate

    s, null = _search({"aug_hose_ab": {"V_line": 15.0, "R_line": 0.2}}, 3309)
    soft = fit_candidate(s.rep, "bulk_modulus", null)
    assert soft.cost < null.cost  # the bulk modulus does stand in for part of it
    fit, rec = state_stage(s.rep, s.full, soft, s.parts, lambda m: None, names=["aug_hose_ab"], trigger=0.0,
                           bare=null)
    assert rec["kept"] == "aug_hose_ab", rec
    assert rec["in_place_of"] == ["bulk_modulus"] and "bulk_modulus" not in fit.model.effects
    assert rec["params"]["R_line"] == pytest.approx(0.2, rel=0.3)
    assert "cost_ratio_without_hypotheses" in rec["tried"][0]


def test_a_reading_state_is_tried_only_where_that_reading_misses():
    """A follower at a sensor's reading moves that reading alone: where the model already meets it (the book model
    on its own campaign) it is skipped with the reason; a reading the model misses is tried; the position sensor,
    whose reading the loop feeds back, is always tried."""
    from ehas_env.measurement.replay import ModelSpec, Replayer
    from ehas_env.diagnosis.states import _quiet_reading
    from ehas_env.physics.effects import get_effect

    runs, truth = simulate_campaign({"aug_lag_pb_reading": {"T": 15.0}}, seed=3310, duration=3.0, perturb=False)
    full = Replayer(Campaign(None, [validate_run(n, c, m) for n, c, m in runs]), hypotheses=True)
    sims = full.simulate(ModelSpec(beta=truth["beta"], K=truth["K"]))
    why = _quiet_reading(full, sims, get_effect("aug_lag_pa_reading"), 1.5)
    assert why is not None and "p_a_bar" in why and "at or below" in why
    assert _quiet_reading(full, sims, get_effect("aug_lag_pb_reading"), 1.5) is None  # chamber B's reading lags
    assert _quiet_reading(full, sims, get_effect("aug_lag_position_sensor"), 1.5) is None
    # the load reading is judged (issue 42): here it is A (P_A - P_B) of the true pressures, which the model meets
    assert "at or below" in _quiet_reading(full, sims, get_effect("aug_lag_force_reading"), 1.5)


@pytest.mark.slow  # a 5-run campaign, four followers screened (about 2 min on 2 cores)
def test_the_stage_finds_a_lag_in_a_pressure_reading_among_the_followers():
    s, null = _search({"aug_lag_pb_reading": {"T": 6.0}}, 3311)
    names = ["aug_lag_coil", "aug_lag_pa_reading", "aug_lag_pb_reading", "aug_slew_pb_reading"]
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=names)
    assert rec["kept"] == "aug_lag_pb_reading", rec
    assert rec["params"]["T"] == pytest.approx(6.0, rel=0.3)
    assert "chamber B's pressure reading" in rec["words"]


@pytest.mark.slow  # a 5-run campaign, two reading offsets screened (about 1 min on 2 cores)
def test_a_reading_block_that_leaves_most_of_its_reading_is_not_kept():
    """A sensor's own error leaves its reading at the noise once fitted: an offset of chamber A's reading fitted
    where both chambers carry a missed physics (Coulomb friction the model lacks) lowers the residual but leaves
    most of p_a_bar's excess, and is refused with the reason; a true offset of that reading is kept."""
    s, null = _search({"coulomb_friction": {"Fc": 700.0}}, 3312)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=["aug_offset_pa_reading"])
    assert rec["kept"] is None, rec
    # it would pass the all-data rule (20.7x -> 17.5x removes 16 % of the excess): the reading's own rule refuses it
    assert rec["residual_x_noise_all_after"] < rec["residual_x_noise_all_before"] - 0.1 * (
        rec["residual_x_noise_all_before"] - 1.0)
    assert "reading's excess over the noise" in rec["words"] and "p_a_bar" in rec["words"]
    s, null = _search({"aug_offset_pa_reading": {"c": 3.0e5}}, 3313)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=["aug_offset_pa_reading"])
    assert rec["kept"] == "aug_offset_pa_reading", rec
    assert rec["params"]["c"] == pytest.approx(3.0e5, rel=0.1)


def test_a_miss_in_one_reading_that_the_overall_figure_dilutes_is_looked_for():
    """A 2 ms lag in chamber B's pressure reading leaves the campaign at about 1.25x overall (the geometric mean
    over every run and signal dilutes it), below the stage's trigger, but 9x in the 3 Hz run's B pressure: the
    verdict calls that unexplained, so the stage looks (it skipped such campaigns: the drawn set's lag in a reading
    ended "unexplained, no state looked for") and keeps the lag, near the truth."""
    s, null = _search({"aug_lag_pb_reading": {"T": 2.0}}, 3311)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=["aug_lag_pb_reading"])
    assert rec["residual_x_noise_all_before"] <= 1.5 and rec["skipped"] is None, rec
    assert rec["kept"] == "aug_lag_pb_reading", rec
    assert rec["params"]["T"] == pytest.approx(2.0, rel=0.3)


def _at_place(effect: str) -> list:
    """Every static block at the reading ``effect`` is put at (its rivals there)."""
    place = effect.split("_", 2)[2]
    return [n for n in reading_blocks() if n.endswith(place)]


FOLLOWERS_PB = ["aug_lag_pb_reading", "aug_delay_pb_reading", "aug_slew_pb_reading"]


@pytest.mark.parametrize("effect,param,value,seed,rivals,rel", [
    # the static kinds a range or a threshold makes, among the reading blocks of their place (the scan of the main
    # parameter finds where the clip acts; from the default the block does nothing)
    ("aug_sat_flow_a_reading", "L", 8.0 / 60000.0, 3314, None, 0.2),  # the flow meter's range ends at 8 L/min
    ("aug_dz_force_reading", "d", 300.0, 3315, None, 0.2),  # the load reading dead within +-0.3 kN
    # a play of +-0.8 bar in chamber B's reading, among the followers there and its static blocks
    ("aug_play_pb_reading", "b", 0.8e5, 3321, FOLLOWERS_PB + ["aug_play_pb_reading", "aug_offset_pb_reading"], 0.2),
    # a pure delay (gain 1, phase growing with frequency) and a first-order lag (gain falling, phase saturating) of
    # chamber B's reading, each screened against the other and a rate limit at the same place
    ("aug_delay_pb_reading", "tau", 4.0, 3316, FOLLOWERS_PB, 0.1),
    ("aug_lag_pb_reading", "T", 3.0, 3316, FOLLOWERS_PB, 0.1),
])
def test_a_reading_block_is_told_from_its_rivals_at_its_place_with_its_size(effect, param, value, seed, rivals, rel):
    """The state stage keeps the truth's kind among its rivals at the same reading, with its size."""
    s, null = _search({effect: {param: value}}, seed)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=rivals or _at_place(effect))
    assert rec["kept"] == effect, rec
    assert rec["params"][param] == pytest.approx(value, rel=rel)


def test_a_smooth_bend_in_a_reading_is_told_from_a_knee_and_a_scale_error_with_its_size():
    """The flow meter's reading bent by 4 % of its span (25 L/min) at one span (a cubic nonlinearity): among the
    blocks of that reading (a knee and a scale error are its nearest rivals) the stage keeps the bend, with its
    size."""
    s, null = _search({"aug_bend_flow_a_reading": {"b": 0.04}}, 3343)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=_at_place("aug_bend_flow_a_reading"))
    assert rec["kept"] == "aug_bend_flow_a_reading", rec
    assert rec["params"]["b"] == pytest.approx(0.04, rel=0.2)
    assert "cubic bend" in rec["words"] and "flow meter" in rec["words"]


def test_a_knee_in_a_reading_is_found_with_its_slope_change_and_its_knee():
    """The load reading's slope 50 % steeper beyond +-0.3 kN (a piecewise-linear characteristic): among the blocks
    of the load reading the stage keeps the knee, with both numbers (the drawn set's d28, a slope change of
    +50 % beyond +-0.675 kN in the load reading, had nothing that could say it)."""
    s, null = _search({"aug_knee_force_reading": {"g": 0.5, "k": 300.0}}, 3322)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=_at_place("aug_knee_force_reading"))
    assert rec["kept"] == "aug_knee_force_reading", rec
    assert rec["params"]["g"] == pytest.approx(0.5, rel=0.2) and rec["params"]["k"] == pytest.approx(300.0, rel=0.2)


@pytest.mark.parametrize("effect,param,value,seed,rivals", [
    # the valve's current path clipped at 8 mA (the 1-set 35 deg 3 Hz run asks 12), among the static blocks of the
    # coil and its followers (a lag and a rate limit of the current: the loop late, the current slowed)
    ("aug_sat_coil", "L", 8.0, 3341, ["aug_sat_coil", "aug_knee_coil", "aug_lag_coil", "aug_slew_coil"]),
    # the position sensor dead within +-0.5 mm about its zero, among the static blocks of that reading and its play
    ("aug_dz_position_sensor", "d", 5.0e-4, 3342,
     ["aug_dz_position_sensor", "aug_sat_position_sensor", "aug_knee_position_sensor", "aug_play_position_sensor"]),
])
def test_a_static_block_in_the_loop_is_found_with_its_size(effect, param, value, seed, rivals):
    """The static kinds are put at every signal place, the coil's current and the position sensor's reading
    included (but for the kinds the library holds there: the coil's null bias and deadband, the sensor's zero and
    scale): a block there is kept among its rivals at its place, with its size."""
    from ehas_env.physics import augment

    held = {place.place: dict(place.held) for place in augment.SIGNAL_PLACES}
    assert set(held["coil_current"]) == {"offset", "dz", "gain", "delay"}  # the delay: the command's transport_delay
    assert set(held["position_reading"]) == {"offset", "gain", "bend"}
    made = set(reading_blocks())
    assert {"aug_offset_coil", "aug_dz_coil", "aug_gain_coil", "aug_offset_position_sensor",
            "aug_gain_position_sensor"}.isdisjoint(made) and set(rivals) <= made | set(augment.followers())
    s, null = _search({effect: {param: value}}, seed)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=rivals)
    assert rec["kept"] == effect, rec
    assert rec["params"][param] == pytest.approx(value, rel=0.2)


def _at_balance(effect: str) -> list:
    """Every static term at the balance place ``effect`` is put at (its rivals there: the other kinds)."""
    place = "_" + effect.split("_", 2)[2]
    return [n for n in balance_blocks() if n.endswith(place)]


@pytest.mark.parametrize("effect,params,seed", [
    # a relief from chamber A that cracks above 45 bar (the drawn set's d15 had only a leak to drain to say it)
    ("aug_beyond_chamber_a", {"c": -1.5e-6, "k": 4.5e6}, 3331),
    pytest.param("aug_saturating_crank_rate", {"c": -6.0, "k": 1.0}, 3332, marks=pytest.mark.slow),
    # a damping of the piston that triples beyond +-0.25 m/s (drawn cases d11, d22, p3: a piecewise-linear term at a
    # body's balance, named a term beyond a break plus a saturating one, when no kind had two slopes)
    ("aug_knee_piston_velocity", {"c": -500.0, "d": -1000.0, "k": 0.25}, 3334),
])
def test_a_term_at_a_balance_is_told_from_the_other_kinds_there_with_its_size(effect, params, seed):
    """A term of a balance's local quantity: among the kinds at that balance the state stage keeps the truth's,
    with its size and its break within 20 %."""
    s, null = _search({effect: params}, seed)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=_at_balance(effect))
    assert len(_at_balance(effect)) == len(BALANCE_KINDS)  # the constant term among them
    assert rec["kept"] == effect, rec
    for name, value in params.items():
        assert rec["params"][name] == pytest.approx(value, rel=0.2), rec


# about 58 s on 2 cores with an empty model cache (the default suite's 10 minutes): slow; the state stage's
# screening of the terms at a balance stays in the default run through the aug_beyond_chamber_a case above
@pytest.mark.slow
def test_terms_at_other_balances_are_not_screened_where_their_linearisation_removes_nothing():
    """Every static term at every balance, on a campaign with a relief from chamber A: the terms at the piston, the
    crank and the lands remove nothing on their linearisation (one replay each) and are not screened, with why; the
    truth is screened and kept, with its size."""
    s, null = _search({"aug_beyond_chamber_a": {"c": -1.5e-6, "k": 4.5e6}}, 3331)
    n0 = s.rep.n_evals
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=balance_blocks())
    assert rec["kept"] == "aug_beyond_chamber_a" and rec["params"]["k"] == pytest.approx(4.5e6, rel=0.1), rec
    by = {t["effect"]: t for t in rec["tried"]}
    for name, t in by.items():
        if "piston" in name or "crank" in name or name.endswith(("_supply", "_return")):
            # below its kind's bar: 1 % with a break to place, half of what a kept term removes without one
            assert "linearisation removes" in t["skipped"] and t["linear_share"] < states.proxy_bar(
                REGISTRY[name]) <= 0.034, t
    assert "skipped" not in by["aug_beyond_chamber_a"] and by["aug_beyond_chamber_a"]["linear_share"] > 0.1
    # one replay for each term's linearisation; a screen of 15-45 for each screened, the refits that choose the kind
    # among them (measured: 347 in all for the 40 terms, 10 of them screened -- those at chamber A and B and at the
    # lands A and B, whose flows fill them; 486 with the kinds at chamber A refitted again while that pays and each
    # simpler kind fitted from the kept one's term, 47731b2 and after)
    screened = [t for t in rec["tried"] if "skipped" not in t]
    assert len(screened) <= 12 and s.rep.n_evals - n0 < len(rec["tried"]) + 45 * len(screened)


def test_a_block_that_runs_to_an_end_of_its_range_is_not_kept_and_the_right_kind_is():
    """A load reading rate-limited at 10 kN/s (its sensor's span is 50 kN: a fifth of a span a second): a dead zone
    of the reading lowers the residual only by running to the widest its range allows (zeroing a reading the model
    misses by far), and is not kept, with why; the rate limit is, with its rate (drawn set d05: the dead zone at
    +-10 [10, 10] kN was kept)."""
    s, null = _search({"aug_slew_force_reading": {"S": 1.0e4}}, 3317)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=["aug_dz_force_reading"])
    # its width runs to an end of its range, or stops inside a valley that is flat to both ends (its interval the
    # whole range): either way the data do not size it
    assert rec["kept"] is None and ("end of its range" in rec["words"] or "whole range" in rec["words"]), rec
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None,
                           names=["aug_dz_force_reading", "aug_slew_force_reading"])
    assert rec["kept"] == "aug_slew_force_reading", rec
    assert rec["params"]["S"] == pytest.approx(1.0e4, rel=0.1)
    assert "kN/s in the load reading" in rec["words"]


def test_a_reading_saturated_in_one_run_only_is_found_from_its_peak():
    """The flow meter's reading saturated at 24 L/min, which only the 1-set 35 deg 3 Hz run reaches (27 L/min):
    the clip level's valley is narrower than the scan's steps; a saturated reading never reports more than L, so
    its logged peak is scanned with the grid (``Saturation.scan_hint``) and the stage keeps the saturation at it."""
    s, null = _search({"aug_sat_flow_a_reading": {"L": 24.0 / 60000.0}}, 3318)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=["aug_sat_flow_a_reading"])
    assert rec["kept"] == "aug_sat_flow_a_reading", rec
    assert rec["params"]["L"] * 60000.0 == pytest.approx(24.0, rel=0.02)


def test_a_load_reading_saturated_far_below_its_sensors_span_is_found():
    """The load reading saturated at 1 kN, 2 % of its place's 50 kN span (a rig that uses a small part of its load
    cell's range: drawn case d26, a saturation at 0.906 kN on rig C, whose loads peak near 1 kN; the saturation's
    range then ended at 2.5 kN, and a knee at the end of its own range stood in): kept, with its level."""
    s, null = _search({"aug_sat_force_reading": {"L": 1000.0}}, 3319)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=_at_place("aug_sat_force_reading"))
    assert rec["kept"] == "aug_sat_force_reading", rec
    assert rec["params"]["L"] == pytest.approx(1000.0, rel=0.02)


def test_a_position_reading_rate_limited_at_the_fastest_runs_peak_is_found_from_its_logged_rate():
    """The position sensor's reading limited to 0.55 m/s, which only the 1-set 35 deg 3 Hz run's peaks exceed
    (0.59 m/s): the limit's valley is far narrower than the scan's steps (a factor 6 apart); a rate-limited reading
    never changes faster than S, so its logged largest rate (from the angle, x = r sin theta) is scanned with the
    grid (``RateLimit.scan_hint``) and the stage keeps the rate limit at it.  (The drawn set's d20, a limit of
    557 mm/s, was screened at 1.02x the final model's cost without it: not found.)"""
    s, null = _search({"aug_slew_position_sensor": {"S": 0.55}}, 3319)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=["aug_slew_position_sensor"])
    assert rec["kept"] == "aug_slew_position_sensor", rec
    assert rec["params"]["S"] == pytest.approx(0.55, rel=0.03)


def test_a_block_the_held_out_run_never_reaches_leaves_its_validation_samples_as_they_were():
    """``validation_moved``: a flow-meter saturation at 24 L/min, which only the 1-set 35 deg 3 Hz run reaches (the
    held-out run peaks far below), moves the validation samples by nothing; a Coulomb friction of 200 N moves them
    by many noise variances.  The validation gate lets the first be judged on the fitted runs alone (the drawn
    set's d19: refused at 1.42 -> 1.42 before)."""
    from ehas_env.diagnosis.candidates import UNEXERCISED, validation_moved
    from ehas_env.measurement.replay import ModelSpec

    s, null = _search({}, 3323)
    assert s.held and all("1set" not in h for h in s.held)
    base = s.full.simulate(null.model)
    clipped = ModelSpec(effects={"aug_sat_flow_a_reading": {"L": 24.0 / 60000.0}}, beta=null.model.beta,
                        K=null.model.K)
    rubbing = ModelSpec(effects={"coulomb_friction": {"Fc": 200.0}}, beta=null.model.beta, K=null.model.K)
    held = {i: 0 for i in s.held_idx}  # the held-out run alone (the fitted runs' tails beyond 3 s validate too)
    assert validation_moved(s.full, base, s.full.simulate(clipped), held) < UNEXERCISED
    assert validation_moved(s.full, base, s.full.simulate(rubbing), held) > 100 * UNEXERCISED
    # the tail of the 1-set run beyond its fit window reaches the clip: there it moves
    assert validation_moved(s.full, base, s.full.simulate(clipped), s.parts) > UNEXERCISED
    assert validation_moved(s.full, base, s.full.simulate(clipped), {}) is None


@pytest.mark.slow  # two searches of three blocks on a 5-run campaign (about 1 min on 2 cores)
def test_the_stage_keeps_a_second_block_on_top_of_the_first(monkeypatch):
    """Two blocks hidden in one rig -- an offset of 2 bar in chamber B's pressure reading and a land A that passes
    0.6 L/min less than the orifice law -- each alone closes only part of the miss: the states stage keeps one,
    looks again on top of it and keeps the other (``MAX_STATES``), each with its size; the diagnosis' ``states``
    lists both.  With one search (``MAX_STATES`` = 1, as before) the second is lost."""
    from ehas_env.diagnosis import pipeline
    from ehas_env.diagnosis.candidates import _parts_cost

    truth = {"aug_offset_pb_reading": {"c": 2.0e5}, "aug_const_land_a": {"c": -0.6 / 60000.0}}
    names = ["aug_offset_pb_reading", "aug_const_land_a", "aug_lag_pb_reading"]
    real = pipeline.state_stage
    monkeypatch.setattr(pipeline, "state_stage", lambda *a, **k: real(*a, **{**k, "names": names}))

    def stage(max_states):
        s, null = _search(truth, 3340)
        sims = s.full.simulate(null.model)
        s.keep(null, sims, _parts_cost(s.full, sims, s.parts))
        monkeypatch.setattr(pipeline, "MAX_STATES", max_states)
        return s, pipeline.states_stage(s)

    s, rec = stage(2)
    kept = [rec["kept"]] + [r["kept"] for r in rec["more"]]
    assert sorted(kept) == sorted(truth), rec
    for r in [rec, *rec["more"]]:
        assert r["params"]["c"] == pytest.approx(truth[r["kept"]]["c"], rel=0.2), r
    assert set(truth) <= set(s.current.model.effects)
    s1, rec1 = stage(1)
    assert rec1["more"] == [] and len(set(truth) & set(s1.current.model.effects)) == 1


def test_a_simpler_kind_is_fitted_from_the_best_kinds_term_whatever_its_screen(monkeypatch):
    """The crank torque balance: a piecewise-linear term refits best, its break beyond every rate the runs reach
    (drawn case d22: 15.7 rad/s, the runs to 11.5) -- a proportional term, which screened more than KIND_DB behind
    (its own screen's start) and was not refitted.  Fitted from the knee's term it reaches its cost: the
    proportional term is kept, and its start is the knee's slope within; a simpler kind whose refit stays behind
    is not kept, nor one whose refit ran to an end of its range."""
    from types import SimpleNamespace as NS

    w = np.linspace(-11.5, 11.5, 400)
    lead = NS(cost=0.50, model=states.ModelSpec(effects={"aug_knee_crank_rate": {"c": -14.7, "d": 14.3, "k": 15.7}}),
              sims=["sim"])
    monkeypatch.setattr(states, "_balance_quantity", lambda rep, sims, cls: [w])
    starts = []

    def refine(rep, name, f, base, effects):
        if name == "aug_knee_crank_rate":
            return lead
        starts.append(dict(f.model.effects.get(name, {})))
        return NS(cost=reach if f.model.effects.get(name) else 0.7, name=name, model=NS(effects={}))

    monkeypatch.setattr(states, "refine_candidate", refine)
    lower = {(n, None): (NS(cost=c, model=NS(effects={})), NS(model=NS(effects={})))
             for n, c in {"aug_knee_crank_rate": 0.80, "aug_prop_crank_rate": 0.80 * 10 ** 0.15}.items()}
    for reach, insane, kept in ((0.50 * 10 ** 0.01, False, "aug_prop_crank_rate"),
                                (0.50 * 10 ** 0.05, False, "aug_knee_crank_rate"),
                                (0.50, True, "aug_knee_crank_rate")):
        monkeypatch.setattr(states, "sanity", lambda f, name: "at an end" if insane and name != "aug_knee_crank_rate"
                            else None)
        starts.clear()
        key, refined, rec = states._refined_choice(None, dict(lower), lower)
        assert key == (kept, None), (reach, rec)
        assert starts[0] == pytest.approx({"c": -14.7}, rel=1e-3)
        # the proportional term screened; then the kinds never screened there that hold the knee's term over the
        # rates reached (a saturating term whose break lies beyond them, a term beyond a break near 0)
        assert [r["effect"] for r in rec][:2] == ["aug_knee_crank_rate", "aug_prop_crank_rate"]
        assert "aug_saturating_crank_rate" in [r["effect"] for r in rec][2:], rec
        assert all(r["screened_ratio"] is None for r in rec[2:]), rec


def test_a_block_whose_size_the_fit_cannot_tell_from_nothing_is_not_kept(monkeypatch):
    """The stage's last gate (honesty.size_not_shown): a block that passes every rule on the residuals but whose
    size's 95 % interval holds 0 is not named (drawn case d22: an offset of chamber B's reading of -0.0018
    [-0.0092, 0.0056] bar kept in place of a supply line's loss, the residual's fall the loss' removal); the same
    block with its interval clear of 0 is kept, and so is one whose interval is its whole range (the linearised
    interval failing: drawn case d01, a saturating term whose level and break trade off).  The stage's fits and replays here are tables."""
    from types import SimpleNamespace as NS

    name = "aug_offset_pb_reading"
    kept_fit = NS(cost=0.5, model=states.ModelSpec(effects={name: {"c": -184.0}}), free=[])
    final = NS(cost=1.0, model=states.ModelSpec(effects={}))
    full = NS(simulate=lambda model: "after" if model.effects else "before")
    monkeypatch.setattr(states, "blocks_of", lambda full, sims, signals: sims)
    monkeypatch.setattr(states, "grade", lambda sims: {"residual_x_noise": 1.28 if sims == "before" else 1.09})
    monkeypatch.setattr(states, "_quiet", lambda g, trigger: False)
    monkeypatch.setattr(states, "_parts_cost", lambda full, sims, parts: None)
    monkeypatch.setattr(states, "screening_runs", lambda rep: rep)
    monkeypatch.setattr(states, "_screen_all", lambda *a: {(name, None): (kept_fit, final)})
    monkeypatch.setattr(states, "_refined_choice", lambda *a: ((name, None), {(name, None): kept_fit}, []))
    monkeypatch.setattr(states, "sanity", lambda f, n: None)
    monkeypatch.setattr(states, "term_refused", lambda a, b: None)
    monkeypatch.setattr(states, "validation_moved", lambda *a: None)
    monkeypatch.setattr(states, "_reading_not_closed", lambda *a: None)
    span = get_effect(name).param("c").bounds  # an interval out to the range's ends shows nothing either way
    for ci, kept in (((-923.6, 555.3), None), ((-300.0, -80.0), name), (span, name)):
        monkeypatch.setattr(states, "confidence", lambda rep, f: {(name, "c"): ci})
        fit, rec = state_stage(None, full, final, {}, lambda m: None, names=[name], trigger=0.0)
        assert rec["kept"] == kept, rec
        if kept is None:
            assert fit is None and "holds 0" in rec["words"] and "[-924, 555]" in rec["words"], rec


def test_a_kind_kept_is_replaced_by_a_simpler_one_that_holds_it_once_its_neighbours_go(monkeypatch):
    """Drawn case d15: a piecewise-linear term at chamber A kept beside an external leak; the leak refitted away,
    its slope within is nil and the simpler term beyond a threshold holds it (0.04 dB behind): it replaces it,
    fitted from the knee's term (the break and the slope beyond).  Not when the knee also lowers its validation
    residual by the keep gate's share, nor when no simpler kind comes within 0.3 dB; not for a block that is no
    static kind."""
    from types import SimpleNamespace as NS

    pa = np.linspace(1.0e5, 1.1e7, 300)
    knee = {"c": 2.6e-8, "d": -1.58e-6, "k": 4.43e6}
    fit = NS(cost=0.5, model=states.ModelSpec(effects={"aug_knee_chamber_a": knee, "valve_dynamics": {"wn": 1.0}}),
             sims=["sim"])
    monkeypatch.setattr(states, "_balance_quantity", lambda rep, sims, cls: [pa])
    costs = {"aug_beyond_chamber_a": 0.5 * 10 ** 0.004, "aug_prop_chamber_a": 0.8, "aug_saturating_chamber_a": 0.7,
             "aug_cubic_chamber_a": 0.9, "aug_const_chamber_a": 0.95}
    starts = {}

    def refine(rep, name, f, null, base):
        starts[name] = dict(f.model.effects[name])
        assert base == {"valve_dynamics": {"wn": 1.0}}
        return NS(cost=costs[name], name=name, model=NS(name=name))

    monkeypatch.setattr(states, "refine_candidate", refine)
    monkeypatch.setattr(states, "sanity", lambda f, name: None)
    full = NS(simulate=lambda model: model.name)
    for val_beyond, kept in ((1.32, "aug_beyond_chamber_a"), (1.32 / 0.97, None)):
        monkeypatch.setattr(states, "_parts_cost", lambda full, sims, parts: val_beyond)
        found = states.simpler_kind(None, full, fit, "aug_knee_chamber_a", {0: 0}, 1.32)
        assert (found and found[1]) == kept, found
    # the simpler kinds at the place that imitate the knee's term over the values to 10 % of its energy (a
    # proportional, a saturating or a constant term cannot hold a term that sets in at 44 bar), none elsewhere
    assert set(starts) == {"aug_beyond_chamber_a", "aug_cubic_chamber_a"}
    assert starts["aug_beyond_chamber_a"] == pytest.approx({"c": -1.58e-6 + 2.6e-8, "k": 4.43e6}, rel=2e-2)
    g, name, made = states.simpler_kind(None, full, fit, "aug_knee_chamber_a", {}, None)
    assert {m["effect"]: m["cost_ratio"] for m in made} == pytest.approx({"aug_beyond_chamber_a": 10 ** 0.004,
                                                                         "aug_cubic_chamber_a": 1.8}, abs=1e-4)
    costs["aug_beyond_chamber_a"] = 0.5 * 10 ** 0.05
    assert states.simpler_kind(None, full, fit, "aug_knee_chamber_a", {}, None) is None
    assert states.simpler_kind(None, full, fit, "valve_dynamics", {}, None) is None


def test_the_pipeline_replaces_the_kept_kind_and_says_so(monkeypatch):
    """pipeline._keep_state: once the effect a kept piecewise-linear term shared its chamber with is refitted away,
    the simpler kind that holds it becomes the model kept, the knee's step says why, a step keeps the new one and
    the state's record names it (reduced_from, simpler); with nothing dropped no simpler kind is looked for."""
    from types import SimpleNamespace as NS

    from ehas_env.diagnosis import pipeline

    knee_fit = NS(cost=0.5, model=states.ModelSpec(effects={"external_leakage": {}, "aug_knee_chamber_a": {}}))
    alone = NS(cost=0.5, model=states.ModelSpec(effects={"aug_knee_chamber_a": {}}))
    beyond = NS(cost=0.501, model=states.ModelSpec(effects={"aug_beyond_chamber_a": {"c": -1.5e-6, "k": 4.5e6}}))
    asked = []
    monkeypatch.setattr(pipeline, "simpler_kind", lambda *a: asked.append(a[3]) or (
        beyond, "aug_beyond_chamber_a", [{"effect": "aug_beyond_chamber_a", "cost_ratio": 1.002}]))
    monkeypatch.setattr(pipeline, "described", lambda rep, g, n: ({"params": {"c": -1.5e-6}, "ci95": {},
                                                                   "words": "a term above 45 bar"}, {}))
    monkeypatch.setattr(pipeline, "_parts_cost", lambda full, sims, parts: 1.3)
    monkeypatch.setattr(pipeline, "_held_fit", lambda full, sims, idx: None)
    for dropped in (True, False):
        monkeypatch.setattr(pipeline, "_drop_stand_ins", lambda *a, **k: (alone if dropped else knee_fit, "s", 1.3))
        kept = []
        s = NS(rep=None, full=NS(simulate=lambda m: "sims"), parts={}, steps=[], say=lambda m: None, held_idx=[],
               current=knee_fit, keep=lambda f, sims, val: kept.append(f))
        rec = {"kept": "aug_knee_chamber_a", "words": "a piecewise-linear term", "residual_x_noise_all_after": 1.1,
               "residual_x_noise_validation_after": 1.3, "within": [{"effect": "aug_knee_piston_velocity"}]}
        asked.clear()
        pipeline._keep_state(s, knee_fit, rec, None, None)
        if dropped:
            assert kept == [beyond] and rec["kept"] == "aug_beyond_chamber_a", rec
            assert rec["reduced_from"] == "aug_knee_chamber_a" and rec["words"] == "a term above 45 bar"
            assert rec["within"] == [] and rec["simpler"][0]["effect"] == "aug_beyond_chamber_a"  # not the knee's
            assert [(x.effect, x.kept) for x in s.steps] == [("aug_knee_chamber_a", False),
                                                            ("aug_beyond_chamber_a", True)]
            assert "holds it (1.002x its cost)" in s.steps[0].reason
        else:
            assert kept == [knee_fit] and asked == [] and rec["kept"] == "aug_knee_chamber_a"


def test_rivals_not_refitted_are_compared_with_the_screen_the_kept_place_was_chosen_on():
    """Drawn case d01: a saturating term at the supply kept from a piecewise-linear term's term screened 1.62x the
    best screen and refitted far below it; blocks elsewhere that were not refitted must not be listed as rivals
    "the runs cannot part" at 0.73x its cost (their screens against its poor own screen).  Against the place's
    best screen (1.0): a term at the piston 1.17x is parted from it, one 1.05x is not."""
    from types import SimpleNamespace as NS

    scr = {"aug_knee_supply": 1.0, "aug_saturating_supply": 1.62, "aug_beyond_piston_velocity": 1.17,
           "aug_cubic_crank_rate": 1.05}
    screened = {(n, None): (NS(cost=c), None) for n, c in scr.items()}
    refined = {("aug_knee_supply", None): NS(cost=0.5596), ("aug_saturating_supply", None): NS(cost=0.5541)}
    near = states._within(screened, ("aug_saturating_supply", None), refined)
    assert {n["effect"]: n["cost_ratio"] for n in near} == pytest.approx(
        {"aug_knee_supply": 0.5596 / 0.5541, "aug_cubic_crank_rate": 1.05}, abs=1e-4)


def test_terms_at_a_balance_are_screened_on_the_recalibrated_baseline_too_past_their_proxy(monkeypatch):
    """A third base, the recalibrated baseline before the library's effects: a term at a balance is screened there
    when its linearisation passes its bar, under the key of every effect it sets aside, a hose in full; a block at a
    signal (a lag of the coil) is not screened there at all, and a term below its bar is not screened."""
    from types import SimpleNamespace as NS

    final = NS(cost=2.0, model=NS(effects={"external_leakage": {}, "valve_null_bias": {}}))
    null = NS(cost=18.0, model=NS(effects={}))
    share = {("aug_prop_chamber_a", id(final)): 0.001, ("aug_prop_chamber_a", id(null)): 0.6,
             ("aug_prop_chamber_b", id(final)): 0.001, ("aug_prop_chamber_b", id(null)): 0.002}
    screens = []
    monkeypatch.setattr(states, "_quiet_reading", lambda full, sims, cls, trigger: None)
    monkeypatch.setattr(states, "_scan_hint", lambda full, cls, sims=None: ([], {}))
    monkeypatch.setattr(states, "linear_share", lambda rep, base, name, start_at: share[(name, id(base))])

    def screen(rep, name, base, scan_extra=None, start_at=None):
        screens.append((name, id(base)))
        return NS(cost=1.0 if base is null else 1.9)

    monkeypatch.setattr(states, "screen_candidate", screen)
    monkeypatch.setattr(states, "_sane", lambda rep, f, name: (f, None))
    tried = []
    bases = [(final, None, False), (null, ["external_leakage", "valve_null_bias"], True)]
    got = states._screen_all(None, None, final, None, ["aug_prop_chamber_a", "aug_prop_chamber_b", "aug_lag_coil",
                                                       "aug_hose_b"], bases, 0.0, tried, lambda m: None)
    set_aside = ("external_leakage", "valve_null_bias")
    assert set(got) == {("aug_prop_chamber_a", set_aside), ("aug_lag_coil", None), ("aug_hose_b", None),
                        ("aug_hose_b", set_aside)}
    assert screens == [("aug_prop_chamber_a", id(null)), ("aug_lag_coil", id(final)), ("aug_hose_b", id(final)),
                       ("aug_hose_b", id(null))]
    assert tried[0]["cost_ratio_on_recalibrated_baseline"] == 0.5 and tried[0]["linear_share"] == 0.6
    assert "skipped" in tried[1] and "cost_ratio" in tried[2]


def test_a_term_the_library_stood_in_for_is_found_on_the_recalibrated_baseline_in_its_place():
    """A campaign simulated with a leak from chamber A alone (a term proportional to its pressure; the package's
    synthetic writer): the library's leak from both chambers fitted first holds part of it, and on top of it the
    term's linearisation removes too little to be screened.  Screened also on the recalibrated baseline (``null``),
    it is kept in the leak's place with its size (-3.3e-6 m^3/s per its unit of pressure: -0.198 L/min per 100
    bar)."""
    from ehas_env.diagnosis.candidates import fit_candidate

    s, null = _search({"aug_prop_chamber_a": {"c": -3.3e-6}}, 3311)
    leak = fit_candidate(s.rep, "external_leakage", null)
    assert leak.cost < 0.5 * null.cost  # the symmetric leak does stand in for much of it
    names = ["aug_prop_chamber_a", "aug_lag_coil"]
    fit, rec = state_stage(s.rep, s.full, leak, s.parts, lambda m: None, names=names, trigger=0.0)
    assert fit is None and "skipped" in rec["tried"][0]  # on top of the stand-in it is not even screened
    fit, rec = state_stage(s.rep, s.full, leak, s.parts, lambda m: None, names=names, trigger=0.0, null=null)
    assert rec["kept"] == "aug_prop_chamber_a" and rec["in_place_of"] == ["external_leakage"], rec
    assert set(fit.model.effects) == {"aug_prop_chamber_a"}
    assert rec["params"]["c"] == pytest.approx(-3.3e-6, rel=0.05)
    assert rec["residual_x_noise_all_after"] < 1.5 < rec["residual_x_noise_all_before"]


def test_a_term_beyond_its_fit_range_is_screened_again_over_a_wider_one_and_kept_with_its_size():
    """A campaign simulated with a supply pressure that drops beyond 7.5 L/min of the valve's opening by 26 bar per
    25 L/min (the package's synthetic writer; drawn case p5's size), 2.2 times the end of the size's fit range
    (+-12 bar): the screen runs into that end, is fitted again with the range widened toward the bounds (+-30 bar),
    and the refit keeps the wider range: the term is kept with its size and break."""
    s, null = _search({"aug_beyond_supply": {"c": -2.6e6, "k": 7.5 / 60000.0}}, 3312)
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=["aug_beyond_supply"], trigger=0.0)
    assert rec["kept"] == "aug_beyond_supply", rec
    assert rec["params"]["c"] == pytest.approx(-2.6e6, rel=0.1)
    assert rec["params"]["k"] == pytest.approx(7.5 / 60000.0, rel=0.1)
    assert rec["residual_x_noise_all_after"] < 1.5 < rec["residual_x_noise_all_before"]


def test_a_hose_the_librarys_softer_oil_stood_in_for_is_found_on_the_recalibrated_baseline_in_its_place():
    """A campaign simulated with a hose at chamber B (40 cm^3 behind 0.73 bar/(L/min); drawn case d24's numbers, the
    package's synthetic writer): the library's softer oil fitted first holds part of its compliance.  Screened on the
    recalibrated baseline too (no ``bare`` model: no hypothesis was kept), the hose is kept in the oil's place with
    its volume and resistance."""
    from ehas_env.diagnosis.candidates import fit_candidate

    s, null = _search({"aug_hose_b": {"V_line": 40.0, "R_line": 0.73}}, 3313)
    soft = fit_candidate(s.rep, "bulk_modulus", null)
    assert soft.cost < null.cost
    fit, rec = state_stage(s.rep, s.full, soft, s.parts, lambda m: None, names=["aug_hose_b"], trigger=0.0, null=null)
    assert rec["kept"] == "aug_hose_b" and rec["in_place_of"] == ["bulk_modulus"], rec
    assert "bulk_modulus" not in fit.model.effects
    assert rec["params"]["V_line"] == pytest.approx(40.0, rel=0.15)
    assert rec["params"]["R_line"] == pytest.approx(0.73, rel=0.15)
    assert "cost_ratio_on_recalibrated_baseline" in rec["tried"][0]


def test_a_term_of_another_local_quantity_of_a_balance_is_found_there_not_at_the_balances_own_quantity():
    """A campaign simulated with a saturating term of the load pressure p_A - p_B in the piston's force balance
    (-484 N reached at 20 bar: held-out drawn case d07's size, its break wider; the package's synthetic writer): the
    balance's own quantity (the piston velocity) cannot hold it -- a friction-like term of the velocity changes sign
    at the reversals, this one where the load pressure does -- and the place of the same balance with the load
    pressure (balance_blocks.OTHER_LOCALS) is kept with its size and break.  (d07's own break, 5.5 bar, is passed
    within milliseconds at each reversal: a term that steep in a quantity the oil's stiffness sets leaves even the
    truth 2.1 noise variances from its own campaign's replay.)"""
    s, null = _search({"aug_saturating_piston_load_pressure": {"c": -484.0, "k": 2.0e6}}, 3314)
    names = ["aug_saturating_piston_velocity", "aug_saturating_piston_load_pressure"]
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None, names=names, trigger=0.0)
    assert rec["kept"] == "aug_saturating_piston_load_pressure", rec
    assert rec["params"]["c"] == pytest.approx(-484.0, rel=0.1)
    assert rec["params"]["k"] == pytest.approx(2.0e6, rel=0.2)
    assert rec["residual_x_noise_all_after"] < 1.5 < rec["residual_x_noise_all_before"]
