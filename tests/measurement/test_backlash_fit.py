"""The play of the rod-crank joint is fitted where its cost valley is, not beside it (issue 36).

The cost of ``backlash.delta`` is a narrow valley (about +-25 % of the play: the knock after each reversal
moves with it) in a rugged landscape; the screening's default scan (7 values over 2.5e-5 .. 2e-3 m, x2.1
apart) could step over the valley and leave the fit on a side slope (or, when no scan value beats the
null model, on the lower end of the range).  The effect asks for a finer scan (``scan_points``).

The campaign comes from the independent generator (tests/independent_rig, which shares no code with the
package): its own two-body piston and crank joined through a dead zone of width 2 delta.
"""
from __future__ import annotations

import math

import pytest

from ehas_env.diagnosis.fitting import fit_range, scan_values


def test_the_plays_scan_is_fine_enough_for_its_valley():
    values = scan_values(fit_range("backlash", "delta"))
    ratios = [b / a for a, b in zip(values, values[1:])]
    assert max(ratios) < 1.2  # two values or more inside a +-25 % valley
    assert values[0] == pytest.approx(2.5e-5) and values[-1] == pytest.approx(2e-3)
    # other effects keep the default scan (the diagnosis' cost is unchanged for them)
    assert len(scan_values(fit_range("viscous_friction", "b"))) == 7


@pytest.mark.slow  # the independent generator writes a 5-run campaign (about 20 s on 2 cores), then 70 replays
def test_the_play_of_an_independent_rig_is_found_as_well_as_from_the_truth(tmp_path):
    from independent_rig import campaign as gen

    from ehas_env.diagnosis import candidates as D
    from ehas_env.measurement.campaign import read_campaign
    from ehas_env.diagnosis.fitting import fit, own_params
    from ehas_env.measurement.replay import Replayer

    truth = 1.5e-4  # m (0.15 mm): between the default scan's 1.08e-4 and 2.24e-4
    runs, record = gen.simulate({"backlash": {"delta": truth * 1e3}}, seed=5)
    rep = Replayer(read_campaign(gen.write(tmp_path / "camp", runs, record)))
    null = D.fit_null(rep, {})
    screened = D.screen_candidate(rep, "backlash", null)
    found = screened.model.effects["backlash"]["delta"]
    fp = own_params("backlash")[0]
    from_truth = fit(rep, [fp], {(fp.effect, fp.name): truth}, null.model, tol=1e-3)
    # the default scan stopped on the valley's side: 1.30e-4 m (-13 %), cost 20.1 against 17.7 from the truth
    assert abs(found / truth - 1.0) < 0.05, found
    assert screened.cost <= from_truth.cost * 1.01
    assert screened.cost < 0.5 * null.cost and math.isfinite(found)


@pytest.mark.parametrize("value", [-1, 2.5, True, 1000])
def test_a_bad_scan_points_declaration_is_refused(value):
    from ehas_env.physics.effects.base import Effect, Param

    with pytest.raises(ValueError, match=r"scan_points must be an integer in \[0, 200\]"):
        type("BadScan", (Effect,), {"name": "bad_scan_probe", "title": "t", "explanation": "e", "signature": "s",
                                    "params": (Param("k", "N", 1.0, (0.0, 2.0), "k"),), "scan_points": value,
                                    "piston_force": staticmethod(lambda k: k)})
