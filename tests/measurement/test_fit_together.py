"""``compare --fit`` (and every ``next:`` line) calibrates given effects from two starts (issue 42, point 2: one figure,
never worse than what was given).

The independent generator's (``tests/independent_rig``, sharing no code with the package) coil current rate-limited
at 150 mA/s, every closed-loop run started from rest without a fade-in.  The recalibrated baseline (beta and K fitted
with no effect) runs to the ends of both ranges, standing in for the limit's start; from there the limit given at
its true value fits to 1.31 sensor-noise variances (two runs of 2 s), while the same value on the rig's own beta and K
leaves 1.09: the valley of a rate limit from rest is about 1 % wide, narrower than the fit's steps.  ``fit_together`` fits from both
and keeps the better (:func:`ehas_env.diagnosis.candidates.fit_together`).
"""
from __future__ import annotations

import sys
from pathlib import Path

from ehas_env.diagnosis.candidates import covering, fit_null, fit_together, own_params, recal_params
from ehas_env.diagnosis.fitting import fit, replay_cost
from ehas_env.measurement.campaign import read_campaign
from ehas_env.measurement.replay import ModelSpec, Replayer

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.independent_rig import campaign as gen  # noqa: E402
from tests.independent_rig.start_conditions import options  # noqa: E402

GIVEN = {"aug_slew_coil": {"S": 150.0}}
#: two of the generator's closed-loop runs (the others' exact bounds cost a minute to generate)
PLAN = [(1, 35.0, 3.0), (3, 20.0, 1.0)]


def test_given_values_are_calibrated_from_the_rig_s_own_numbers_too(tmp_path):
    runs, truth = gen.simulate({"current_slew": {"S": 150.0}}, seed=924, rig="book", duration=2.0, plan=PLAN,
                               valve=False, **options("rest", "book", 2.0))
    rep = Replayer(read_campaign(gen.write(tmp_path / "camp", runs, truth, overwrite=True)), hypotheses=True)
    null = fit_null(rep)
    got = fit_together(rep, GIVEN, null)
    # never worse than either start: the given values on the recalibrated baseline, or on the rig's own numbers
    on_null = replay_cost(rep, rep.simulate(ModelSpec(effects=GIVEN, beta=null.model.beta, K=null.model.K)))
    on_own = replay_cost(rep, rep.simulate(ModelSpec(effects=GIVEN)))
    assert got.cost <= min(on_null, on_own) * (1.0 + 1e-9), (got.cost, on_null, on_own)
    assert got.cost < 1.3, got.cost  # near the noise: the limit and the rig's numbers hold the start from rest
    # the mutation: from the recalibrated baseline's numbers alone the fit stays far above it
    free = [covering(fp, 150.0) for fp in own_params("aug_slew_coil")] + recal_params(GIVEN)
    model = ModelSpec(effects=GIVEN, beta=null.model.beta, K=null.model.K)
    alone = fit(rep, free, {(fp.effect, fp.name): 150.0 if fp.effect else getattr(model, fp.name) for fp in free},
                model)
    assert got.cost < 0.9 * alone.cost, (got.cost, alone.cost)
    assert abs(got.model.effects["aug_slew_coil"]["S"] - 150.0) < 3.0
