"""``ehas simulate --controller FILE``: a saved controller instead of --gains, and the run replays."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from ehas_env.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def test_simulate_a_saved_controller_writes_its_gains(tmp_path, capsys):
    ctrl = ROOT / "results" / "controllers" / "model.json"
    assert main(["simulate", "--controller", str(ctrl), "--disc-sets", "7", "--out", str(tmp_path / "run")]) == 0
    out = capsys.readouterr().out
    assert str(ctrl) in out and "rms % position error" in out
    gains = json.loads(ctrl.read_text())
    meta = json.loads((tmp_path / "run.json").read_text())
    saved = gains.get("gains", gains)
    assert meta["controller"]["Kp"] == pytest.approx(saved["Kp"])
    # the run is a valid measurement: the model replays it with the controller the sidecar names
    from ehas_env.measurement.campaign import read_run

    assert read_run(tmp_path / "run.csv").meta["controller"]["Ki"] == pytest.approx(saved["Ki"])


def test_controller_and_gains_are_exclusive(tmp_path, capsys):
    rc = main(["simulate", "--controller", str(ROOT / "results" / "controllers" / "model.json"), "--gains", "Kp=1",
               "--out", str(tmp_path / "run")])
    assert rc == 2
    assert "--controller and --gains" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
