"""A small part of the out-of-library acceptance, run end to end (slow: it runs ehas diagnose and compare)."""
from __future__ import annotations

import json

import pytest

from independent_rig import acceptance


@pytest.mark.slow
def test_acceptance_harness_on_a_clean_and_an_out_of_library_campaign(tmp_path):
    """A clean campaign of the other engine is explained down to noise with nothing named; a strong
    out-of-library load (an unbalance on the crank) is flagged unexplained with a proposal and its residual
    before stays far above noise.  The harness checkpoints each case and writes its table."""
    out, work = tmp_path / "out", tmp_path / "work"
    ids = "clean_rig_c_s0,ool_crank_unbalance_strong"
    assert acceptance.main(["--out", str(out), "--work", str(work), "--only", ids]) == 0
    clean = json.loads((out / "cases" / "clean_rig_c_s0.json").read_text())
    assert clean["verdict"] == "explained" and clean["named"] == [] and clean["residual_before"] < 1.5
    ool = json.loads((out / "cases" / "ool_crank_unbalance_strong.json").read_text())
    assert ool["verdict"] == "unexplained" and ool["residual_before"] > 10
    assert ool["proposal"] is not None and (out / ool["effect_file"]).exists()
    text = (out / "README.md").read_text()
    assert "ool_crank_unbalance_strong" in text and "clean_rig_c_s0" in text
    # resumable: a second run finds both done and runs nothing
    assert acceptance.main(["--out", str(out), "--work", str(work), "--only", ids]) == 0
