"""The small-residual rule beyond the case it was found on (slow).

``pipeline.proposal_stage``: where the state stage's blocks alone leave a small structured residual on a model that was
unexplained without them, the term is proposed on the model without those blocks too, and replaces them when it lowers
the all-data figure by ``TERM_BEATS_KEPT`` of theirs.  It was found on one campaign (the unlisted set's land flow
forces, mild, generator seed 720: a load-pressure term at the piston and a cubic crank-angle term kept at 1.40x, where
the lands' metering law closes it).  Here the same hidden physics at new seeds, faded in and started from rest, on the
rig it was found on: the diagnosis names the right place and kind (the lands' flow, a valve kind) and the model it
recommends is closed (at most 2x what does not repeat).  Truth: the independent generator's hidden effect
(``tests/independent_rig``, no code shared with the package) and the judge of the unlisted set.
"""
from __future__ import annotations

import json

import pytest

from tests.independent_rig import acceptance as acc
from tests.independent_rig import start_conditions as sc
from tests.independent_rig.effects import UNLISTED
from tests.independent_rig.judge import judge_place_kind, worded_items

pytestmark = pytest.mark.slow

#: new seeds (the rule was set on seed 720).  Seed 731 is a known miss, kept as one (strict: it fails the day it
#: passes): a term of the load pressure at the piston, a stand-in of a wrong kind, explains it within the verdict's
#: bar (1.42x faded in, 1.36x from rest), so no small structured residual is left for the rule to act on
SEEDS = (730, pytest.param(731, marks=pytest.mark.xfail(strict=True, reason="a load-pressure stand-in explains it")))


@pytest.mark.parametrize("variant", ["fade", "rest"])
@pytest.mark.parametrize("seed", SEEDS)
def test_land_flow_forces_are_named_at_new_seeds_faded_in_and_from_rest(tmp_path, seed, variant):
    effects = {"land_flow_forces": UNLISTED["land_flow_forces"].values(0)}
    case = {"id": f"lff_{seed}", "effects": effects, "seed": seed, "rig": "rig_c", "duration": 3.0}
    camp = tmp_path / variant
    sc._generate(case, variant, camp)
    out = tmp_path / "diag.json"
    cmd = [acc.ehas_exe(), "diagnose", str(camp), "--json", str(out), "--quiet", "--overwrite",
           "--model", str(acc.rig_model("rig_c"))]
    code, stdout, stderr, _ = acc._run(cmd, log=tmp_path / "diagnose.log")
    assert code == 0, (stderr or stdout)[-2000:]
    diag = json.loads(out.read_text())
    j = judge_place_kind(effects, worded_items(diag))
    assert j["right"], (j, diag.get("verdict"), diag.get("residual_x_noise"))
    assert sc.recommended_figure(diag) <= 2.0, diag.get("residual_x_noise")
