"""A model file's silent acceptances turned into one-line errors (issue 36's second bad-input campaign).

Before the fix an unknown key in ``calibration`` was kept (a misspelt ``campain`` meant "no calibration
campaign", so ``ehas compare --model`` called every campaign held out), and a file labelled version 1
that held version 2's ``rig`` block read as the book's rig: its numbers were silently dropped.
"""
from __future__ import annotations

import json

import pytest

from ehas_env.simulation.model_file import load_model, parse_model

V2 = {"format": "ehas-model", "version": 2}


def refused(doc, tmp_path, *words):
    f = tmp_path / "m.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(ValueError) as exc:
        load_model(f)
    text = str(exc.value)
    assert "\n" not in text and text.startswith(f"{f}: ")
    for w in words:
        assert w in text, (w, text)
    return text


def test_an_unknown_calibration_key_is_refused(tmp_path):
    refused({**V2, "calibration": {"campain": "campA"}}, tmp_path, "calibration.campain is not a calibration field",
            "did you mean 'campaign'?", "allowed: campaign, runs, fit_percent_before")


def test_every_calibration_key_ehas_writes_is_accepted():
    cal = {"campaign": "campA", "runs": ["r1", "r2"], "fit_percent_before": 80.0, "fit_percent_after": 98.0,
           "command": "ehas compare campA --effects coulomb_friction --fit --save-model m.json",
           "ci95": [{"effect": "coulomb_friction", "param": "Fc", "value": 300.0, "low": 290.0, "high": None,
                     "unit": "N"}]}
    assert parse_model({**V2, "calibration": cal}, "<doc>").calibration == cal


def test_a_version_1_label_on_version_2_content_is_refused(tmp_path):
    # read as version 1 this was the book's rig: crank radius 50 mm, the file's 60 mm dropped without a word
    refused({"format": "ehas-model", "version": 1, "rig": {"crank_radius_mm": 60}}, tmp_path,
            "'rig' is a version-2 field, but the file says \"version\": 1", "set \"version\": 2")
    refused({"format": "ehas-model", "version": 1, "valve": {"K_lpm_per_mA": 2.0}}, tmp_path, "'valve'")


def test_a_version_2_label_on_version_1_content_is_refused(tmp_path):
    refused({**V2, "baseline": {"beta_Pa": 9e8}}, tmp_path, "'baseline' is a version-1 field",
            "rig.bulk_modulus_Pa", "valve.K_lpm_per_mA")


def test_an_unknown_key_of_a_version_1_file_is_refused(tmp_path):
    refused({"format": "ehas-model", "version": 1, "baselne": {"beta_Pa": 9e8}}, tmp_path,
            "baselne is not a model-file field")


def test_a_true_version_1_file_still_reads():
    m = parse_model({"format": "ehas-model", "version": 1, "baseline": {"beta_Pa": 9.6e8, "K_lpm_per_mA": 1.281},
                     "effects": {"coulomb_friction": {"Fc": 412.0}}, "units": {"coulomb_friction.Fc": "N"},
                     "calibration": {"campaign": "x"}}, "<doc>")
    assert m.rig.beta == 9.6e8 and m.rig.K == 1.281 and m.calibration == {"campaign": "x"}
