"""A screen's scan replays a coarse grid first (issue 44, point 3: a cheap proxy first).

A candidate that does nothing at the coarse grid's values (its ends, its middle and the values the data point at)
is not scanned further; one that does is scanned, zoomed and fitted exactly as with the whole grid at once.
Truth: the hidden effect's own value (the package's simulator), the clean campaign's (nothing to find), and the same
screen with the whole grid replayed at once.
"""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.diagnosis import fitting as D
from ehas_env.diagnosis.candidates import fit_null, screen_candidate
from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.measurement.replay import Replayer
from ehas_env.measurement.synthetic import simulate_campaign


def _rep(hidden):
    runs, _ = simulate_campaign(hidden, seed=5, perturb=True, duration=2.0,
                                plan=((3, 20.0, 1.0), (5, 25.0, 2.0), (1, 30.0, 3.0)))
    return Replayer(Campaign(None, [validate_run(*r) for r in runs]))


def _whole_grid(values, grid, extra):
    return list(range(len(values)))


def test_a_candidate_the_coarse_grid_keeps_is_screened_as_with_the_whole_grid(monkeypatch):
    rep = _rep({"coulomb_friction": {"Fc": 400.0}})
    null = fit_null(rep)
    coarse = screen_candidate(rep, "coulomb_friction", null)
    monkeypatch.setattr(D, "coarse_scan", _whole_grid)
    whole = screen_candidate(rep, "coulomb_friction", null)
    assert coarse.cost == whole.cost
    assert coarse.model.effects == whole.model.effects
    assert coarse.model.effects["coulomb_friction"]["Fc"] == pytest.approx(400.0, rel=0.05)


def test_a_candidate_that_does_nothing_on_the_coarse_grid_is_not_scanned_further(monkeypatch):
    rep = _rep({})  # a clean campaign: friction explains nothing
    null = fit_null(rep)
    main = next(fp for fp in D.own_params("coulomb_friction") if fp.name == "Fc")
    start = {(main.effect, main.name): D.start_value(main)}
    n0 = rep.n_evals
    f = D.fit(rep, [main], start, null.model, scan=main, null_cost=null.cost, max_nfev=8)
    coarse_replays = rep.n_evals - n0
    assert f.cost >= null.cost * (1.0 - D.SKIP_MARGIN)
    assert coarse_replays == D.COARSE_POINTS < len(D.scan_values(main))
    monkeypatch.setattr(D, "coarse_scan", _whole_grid)
    n0 = rep.n_evals
    g = D.fit(rep, [main], start, null.model, scan=main, null_cost=null.cost, max_nfev=8)
    assert rep.n_evals - n0 == len(D.scan_values(main))
    assert g.cost >= null.cost * (1.0 - D.SKIP_MARGIN)  # the whole grid said the same: nothing to fit


def test_the_coarse_grid_holds_the_grids_ends_and_every_value_the_data_point_at():
    grid = [float(v) for v in np.geomspace(1.0, 1000.0, 7)]
    extra = [3.3, 470.0]
    values = sorted(grid + extra)
    picked = [values[j] for j in D.coarse_scan(values, grid, extra)]
    assert grid[0] in picked and grid[-1] in picked and grid[3] in picked
    assert set(extra) <= set(picked)
    assert len(picked) == D.COARSE_POINTS + len(extra)


def test_on_a_grid_of_both_signs_the_coarse_grid_spreads_over_each_sign():
    """A signed number (a constant term at a balance) whose valley lies on one side: the coarse grid reaches the
    small and the large magnitudes of both signs (three points over the whole grid would leave one side with its
    largest magnitude alone)."""
    grid = sorted([-m for m in np.geomspace(0.01, 10.0, 5)] + list(np.geomspace(0.01, 10.0, 5)))
    picked = [grid[j] for j in D.coarse_scan(grid, grid, [])]
    for sign in (-1.0, 1.0):
        side = sorted(abs(v) for v in picked if v * sign > 0)
        assert side[0] == pytest.approx(0.01) and side[-1] == pytest.approx(10.0) and len(side) == D.COARSE_POINTS


def test_the_package_rule_cuts_no_recorded_candidate_that_went_on_to_a_fit():
    """The committed scans (results/coarse_scan, 17 drawn campaigns): the diagnosis' own coarse grid and slack cut
    none of the candidates the whole grid sent on, and save replays."""
    from pathlib import Path

    from tests.measurement.coarse_scan_survey import judge, read_records

    recs = read_records([Path(__file__).resolve().parents[2] / "results/coarse_scan/scans_bad8e6b.jsonl.gz"])
    j = judge(recs, D.COARSE_POINTS, True, D.COARSE_SLACK)
    assert j["cut"] == 0 and j["replays_saved"] > 0


def test_a_bad_record_file_is_refused_in_one_line_naming_file_and_line(tmp_path):
    from tests.measurement.coarse_scan_survey import read_records

    bad = tmp_path / "scans.jsonl"
    bad.write_text('{"effect": "x", "values": [1.0], "grid": [1.0], "extra": [], "costs": [1.0], "null": 1.0, '
                   '"final": 1.0}\n{"effect": \n')
    with pytest.raises(ValueError, match=r"scans.jsonl, line 2: not JSON") as e:
        read_records([bad])
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match=r"nope.jsonl: cannot be read"):
        read_records([tmp_path / "nope.jsonl"])
