"""A campaign of many runs screens its candidates on the runs that span its conditions (issue 44, point 3).

The state stage's screens replay the fit data once per scanned value and step: with 15 closed-loop runs fitted that is
four times the replays of a 5-run campaign's.  :func:`candidates.screening_runs` picks at most
``SCREEN_CLOSED_LOOP`` closed-loop runs that span the disc sets, amplitudes and frequencies (and the valve bench's
run); what lowers the final model's cost there is costed again on every fitted run.  Truth: the subset's
definition (a campaign of few runs is not touched; the corners of the plan are taken), the package's own simulator's
hidden block (kept, with its value), and the replay counts.
"""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.diagnosis import candidates as C
from ehas_env.diagnosis.candidates import FIT_WINDOW_S, fit_null, screening_runs
from ehas_env.diagnosis.search import data_stage
from ehas_env.diagnosis.states import state_stage
from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.measurement.replay import Replayer
from ehas_env.measurement.synthetic import simulate_campaign

#: a plan of 9 closed-loop runs: the corners of (disc sets, amplitude, frequency) and the middle
PLAN = ((1, 10.0, 1.0), (7, 10.0, 1.0), (1, 30.0, 3.0), (7, 30.0, 3.0), (4, 20.0, 2.0), (1, 30.0, 1.0),
        (7, 10.0, 3.0), (3, 15.0, 2.0), (5, 25.0, 1.5))


def _rep(plan, effects=None, seed=7, duration=2.0):
    runs, _ = simulate_campaign(effects, seed=seed, duration=duration, plan=plan)
    return Replayer(Campaign(None, [validate_run(n, c, m) for n, c, m in runs]))


def test_a_campaign_of_few_runs_screens_on_all_of_them():
    rep = _rep(PLAN[:4], duration=0.5)
    assert screening_runs(rep) is rep


def test_many_runs_screen_on_those_that_span_the_conditions_and_the_valve_bench():
    rep = _rep(PLAN, duration=0.5)
    scr = screening_runs(rep)
    names = [c.run.name for c in scr.cases]
    kinds = [c.run.kind for c in scr.cases]
    assert kinds.count("closed_loop") == C.SCREEN_CLOSED_LOOP and "valve_open_loop" in kinds
    taken = {(c.run.meta["disc_sets"], c.run.meta["reference"]["amplitude_deg"], c.run.meta["reference"]["freq_hz"])
             for c in scr.cases if c.run.kind == "closed_loop"}
    # every one a corner of the plan (the middle and the inner runs span less), both ends of each condition
    corners = {p for p in PLAN if p[0] in (1, 7) and p[1] in (10.0, 30.0) and p[2] in (1.0, 3.0)}
    assert taken <= corners
    for k in range(3):
        assert {t[k] for t in taken} == {min(p[k] for p in PLAN), max(p[k] for p in PLAN)}
    assert set(names) <= {c.run.name for c in rep.cases}


def test_a_subset_keeps_each_runs_measured_input():
    rep = _rep(PLAN, duration=0.5)
    name = rep.cases[2].run.name
    ps = np.full(rep.cases[2].run.n, 140.0)
    with_input = Replayer(rep.campaign, inputs={name: {"p_s_bar": ps}})
    sub = with_input.subset([2, 3])
    assert list(sub.inputs) == [name] and sub.inputs[name]["p_s_bar"] is ps
    assert [c.run.name for c in sub.cases] == [rep.cases[2].run.name, rep.cases[3].run.name]


@pytest.mark.slow  # a 10-run campaign, two blocks screened on 4 of its 8 fitted closed-loop runs (about 2 min)
def test_the_stage_keeps_the_hidden_block_screened_on_the_subset():
    runs, _ = simulate_campaign({"aug_lag_position_sensor": {"T": 8.0}}, seed=3301, duration=3.5, plan=PLAN)
    s = data_stage(Campaign(None, [validate_run(n, c, m) for n, c, m in runs]), window_s=FIT_WINDOW_S,
                   hypotheses=True)
    null = fit_null(s.rep)
    assert screening_runs(s.rep) is not s.rep
    n0 = s.rep.n_evals
    fit, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: None,
                           names=["aug_lag_coil", "aug_lag_position_sensor"])
    assert rec["kept"] == "aug_lag_position_sensor", rec
    assert rec["params"]["T"] == pytest.approx(8.0, rel=0.3)
    assert s.rep.n_evals > n0  # the screens' replays are counted with the diagnosis'


@pytest.mark.slow  # a 10-run campaign's library stage (about 1 min on 2 cores)
def test_the_library_screens_on_the_subset_and_ranks_on_every_fitted_run():
    runs, _ = simulate_campaign({"coulomb_friction": {"Fc": 400.0}}, seed=12, duration=3.5, plan=PLAN)
    camp = Campaign(None, [validate_run(n, c, m) for n, c, m in runs])
    s = data_stage(camp, window_s=FIT_WINDOW_S, hypotheses=False)
    assert screening_runs(s.rep) is not s.rep
    d = C.diagnose(camp, replayer=s.rep, candidates=["coulomb_friction", "viscous_friction", "valve_null_bias"])
    best = d.ranking[0]
    assert best.effect == "coulomb_friction" and best.beats_noise
    assert best.fit.model.effects["coulomb_friction"]["Fc"] == pytest.approx(400.0, rel=0.1)
    # every fit of the ranking is costed on every fitted run (its table holds them all)
    assert all(len(e.fit.sims) == len(s.rep.cases) for e in d.ranking)
