"""The diagnosis is a sequence of named stages (issue 33, item 6): the JSON lists each with its record, a stage of
one's own is added by adding a function, and the documented example runs as written."""
import contextlib
import io
import re
from pathlib import Path

import pytest

from ehas_env.diagnosis.pipeline import STAGES, diagnose_open

DOC = Path(__file__).resolve().parents[2] / "docs" / "diagnosis-pipeline.md"


def test_the_stages_are_named_functions_in_the_documented_order():
    names = [n for n, _ in STAGES]
    assert names == ["library", "hypotheses", "measured_inputs", "states", "measure", "no_worse", "alternatives",
                     "per_run", "verdict", "proposal"]
    text = DOC.read_text()
    for n, fn in STAGES:  # each stage is drawn and tabled in the docs, by name and function
        assert f"| {n} |" in text and fn.__name__ in text, n
    # the drawing shows them in this order
    drawing = text.split("```\n", 2)[1]
    pos = [re.search(rf"(?<![\w_]){n}(?![\w_])", drawing).start() for n in ["data"] + names]
    assert pos == sorted(pos)


def test_the_documented_example_runs_and_a_stage_of_ones_own_is_recorded():
    block = re.search(r"```python\n(.*?)\n```", DOC.read_text(), flags=re.S).group(1)
    out = io.StringIO()
    ns = {}
    with contextlib.redirect_stdout(out):
        exec(compile(block, str(DOC), "exec"), ns)
    res = ns["res"]
    stages = [r["stage"] for r in res.stages]
    assert stages == ["data", "library", "hypotheses", "measured_inputs", "states", "measure", "worst_run",
                      "no_worse", "alternatives", "per_run", "verdict", "proposal"]
    rec = res.to_json()["stages"][6]
    assert rec["worst_run"] in res.run_costs and rec["residual_x_sensor_noise"] == pytest.approx(
        max(res.run_costs.values()), abs=1e-3)
    assert all(r["elapsed_s"] >= 0.0 for r in res.stages)
    # the library stage found the friction hidden in the campaign, and its record says so
    lib = res.stages[1]
    assert "coulomb_friction" in lib["kept"] and "coulomb_friction" in res.model.effects
    assert "worst_run" in out.getvalue()


def test_without_the_measure_stage_the_diagnosis_refuses_in_one_line():
    from ehas_env.diagnosis.acceptance import SEED, memory_campaign

    camp = memory_campaign({}, SEED, duration=0.6, plan=((3, 20.0, 1.0),))[0]
    with pytest.raises(ValueError, match="'measure' stage"):
        diagnose_open(camp, stages=STAGES[:2], holdout=[], hypotheses=False)


def test_a_stage_record_says_what_it_kept_was_set_aside_in_the_end():
    """A later stage that sets aside what an earlier one kept marks that record (the JSON's stages[] no longer
    says a block is kept that the final model lacks), and only the records that kept it."""
    from ehas_env.diagnosis.pipeline import _records_set_aside

    recs = [{"stage": "library", "kept": ["coulomb_friction"]},
            {"stage": "states", "kept": "aug_lag_coil", "more": [{"kept": "aug_hose_b"}]},
            {"stage": "hypotheses", "kept": ["hyp_rod_area"]}]
    _records_set_aside(recs, ["aug_lag_coil", "aug_hose_b"], "the term stood in")
    assert recs[1]["not_kept_in_the_end"] == {"aug_lag_coil": "the term stood in", "aug_hose_b": "the term stood in"}
    assert "not_kept_in_the_end" not in recs[0] and "not_kept_in_the_end" not in recs[2]
    assert recs[1]["kept"] == "aug_lag_coil" and recs[0]["kept"] == ["coulomb_friction"]  # the records' own keys stay
