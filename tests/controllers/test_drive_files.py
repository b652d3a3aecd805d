"""Drive files: a learning controller's learned feed-forward written as CSV + JSON sidecar and replayed.

Truths used: the learning controller's own steady figure on the same condition (the replay on the base
loop must reach it within 2 %), the table's own definition (one period of the current, sampled at
``samples / period``), and files broken by hand.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from ehas_controllers.base import load_controller
from ehas_controllers.batch_sim import Condition
from ehas_controllers.drive import DriveController, export_drives, read_drive
from ehas_controllers.harmonic import HarmonicCanceller
from ehas_controllers.ilc import ILC
from ehas_controllers.long_test import run_condition
from ehas_controllers.piff import PIFF
from ehas_env.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
CONDS = (Condition(4, 2.0, 20.0), Condition(2, 1.0, 10.0))


@pytest.fixture(scope="module")
def learned(tmp_path_factory):
    """ILC and harmonic (the guard long test's files) run 30 cycles on two conditions, saved, exported."""
    out = {}
    root = tmp_path_factory.mktemp("drives")
    for stem in ("ilc", "harmonic"):
        ctrl = load_controller(ROOT / "results" / "long_test_guard" / f"{stem}.json")
        rows = [run_condition(ctrl, c, cycles=30) for c in CONDS]
        path = ctrl.save(root / f"{stem}.json")
        assert main(["export-drive", str(path), "--out", str(root / f"drive_{stem}")]) == 0
        out[stem] = (ctrl, rows, root / f"drive_{stem}")
    return out


@pytest.mark.parametrize("stem", ["ilc", "harmonic"])
def test_replayed_drive_reaches_the_learning_controllers_steady_figure(learned, stem):
    ctrl, rows, folder = learned[stem]
    drive = load_controller(folder / "drive.json")
    assert isinstance(drive, DriveController) and len(drive.drives) == len(CONDS)
    for c, row in zip(CONDS, rows):
        replay = run_condition(drive, c, cycles=30)
        assert replay["steady_rms_pct"] == pytest.approx(row["steady_rms_pct"], rel=0.02)
        base = run_condition(ctrl.base, c, cycles=30)
        assert replay["steady_rms_pct"] < 0.2 * base["steady_rms_pct"]  # the table carries what was learned


def test_drive_table_is_one_period_of_the_learned_current(learned):
    ctrl, _, folder = learned["harmonic"]
    side = json.loads((folder / "harmonic_on_schedule_model_based_4sets_20deg_2hz.json").read_text())
    assert side["format"] == "ehas-drive" and side["condition"] == {"disc_sets": 4, "amplitude_deg": 20.0,
                                                                     "freq_hz": 2.0}
    assert side["samples"] == 500 and side["sample_rate_hz"] == pytest.approx(1000.0) and side["period_s"] == 0.5
    assert side["base"]["type"] == "piff" and side["base"]["gains"] == ctrl.base.for_plant(4).gains()
    assert side["provenance"]["controller"] == ctrl.name and side["units"]["current_mA"].startswith("mA")
    with (folder / side["table"]).open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time_s", "current_mA"] and len(rows) == 501
    t = np.array([float(r[0]) for r in rows[1:]])
    i = np.array([float(r[1]) for r in rows[1:]])
    assert np.allclose(np.diff(t), 1e-3)
    # the harmonic canceller's current sum_h Re(U_h e^{j h w t}), evaluated here from its learned record
    rec = next(r for r in ctrl.learned_state() if r["disc_sets"] == 4)
    U = np.array([complex(a, b) for a, b in rec["feedforward"]["harmonics"]])
    h = np.arange(1, U.size + 1)
    direct = np.real(np.exp(2j * np.pi * 2.0 * np.outer(t, h)) @ U)
    assert np.allclose(i, direct, atol=1e-8)


def _copy_drive(learned, tmp_path, stem="ilc"):
    _, _, folder = learned[stem]
    side = next(p for p in sorted(folder.glob("*.json")) if p.name != "drive.json")
    data = json.loads(side.read_text())
    table = (folder / data["table"]).read_text()
    (tmp_path / data["table"]).write_text(table)
    new = tmp_path / side.name
    new.write_text(json.dumps(data))
    return new, data, tmp_path / data["table"]


@pytest.mark.parametrize("breakage, words", [
    ("no_sidecar", "sidecar not found"),
    ("no_csv", "field 'table'"),
    ("columns", "columns t,i; expected time_s,current_mA"),
    ("rate", "field 'sample_rate_hz' = 999 Hz does not match samples / period_s"),
    ("time_step", "column time_s must start at 0 and step by 1 / sample_rate_hz"),
    ("rows", "rows; the sidecar's field 'samples' says"),
    ("condition", "field 'condition.freq_hz'"),
    ("format", "field 'format' = 'ehas-controller'; expected 'ehas-drive'"),
    ("number", "expected two numbers time_s,current_mA"),
])
def test_bad_drive_files_give_one_line_errors(learned, tmp_path, breakage, words):
    side, data, table = _copy_drive(learned, tmp_path)
    lines = table.read_text().splitlines()
    if breakage == "no_sidecar":
        side.unlink()
    elif breakage == "no_csv":
        table.unlink()
    elif breakage == "columns":
        table.write_text("\n".join(["t,i"] + lines[1:]) + "\n")
    elif breakage == "rate":
        data["sample_rate_hz"] = 999
    elif breakage == "time_step":
        table.write_text("\n".join(lines[:1] + [f"{2 * float(r.split(',')[0]):.9g},{r.split(',')[1]}"
                                                 for r in lines[1:]]) + "\n")
    elif breakage == "rows":
        table.write_text("\n".join(lines[:-3]) + "\n")
    elif breakage == "condition":
        data["condition"]["freq_hz"] = -1
    elif breakage == "format":
        data["format"] = "ehas-controller"
    elif breakage == "number":
        table.write_text("\n".join(lines[:5] + ["0.005,__import__('os')"] + lines[6:]) + "\n")
    if side.exists() and breakage in ("rate", "condition", "format"):
        side.write_text(json.dumps(data))
    with pytest.raises(ValueError) as err:
        read_drive(side)
    msg = str(err.value)
    assert words in msg and "\n" not in msg, msg
    assert str(side) in msg or str(table) in msg  # names the file


def test_drive_controller_refuses_a_condition_it_has_no_table_for(learned):
    from ehas_env.simulation.plant import Plant

    drive = load_controller(learned["ilc"][2] / "drive.json").for_plant(4)
    with pytest.raises(ValueError, match=r"no drive file for 4 sets 30 deg 2 Hz; drives for: 2 sets 10 deg 1 Hz, "
                                         r"4 sets 20 deg 2 Hz"):
        Plant(disc_sets=4).simulate_closed_loop(drive, amplitude_deg=30.0, freq_hz=2.0, cycles=1)


def test_export_drive_refuses_a_controller_that_learned_nothing(tmp_path, capsys):
    path = HarmonicCanceller(PIFF.book()).save(tmp_path / "fresh.json")
    assert main(["export-drive", str(path), "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err.strip()
    assert "field 'learned' is empty or missing" in err and str(path) in err and err.count("\n") == 0
    piff = PIFF.book().save(tmp_path / "piff.json")
    assert main(["export-drive", str(piff), "--out", str(tmp_path / "d")]) == 2
    assert "drive files come from a learning controller" in capsys.readouterr().err


def test_export_one_condition_in_python(tmp_path):
    ctrl = ILC(PIFF.book(), gain=0.5, name="ilc")
    for c in (Condition(3, 2.0, 20.0), Condition(3, 3.0, 10.0)):
        run_condition(ctrl, c, cycles=8)
    files = export_drives(ctrl, tmp_path, conditions=["3 sets 10 deg 3 Hz"])
    assert [f.name for f in files] == ["ilc_3sets_10deg_3hz.json", "drive.json"]
    d = read_drive(files[0])
    assert d["table"].size == 333 and d["freq_hz"] == 3.0 and d["start_cycle"] == 2
    assert np.allclose(d["table"], ctrl.feedforward_table("3 sets 10 deg 3 Hz"), atol=1e-8)
    with pytest.raises(ValueError, match="nothing learned at 7 sets 10 deg 3 Hz; learned at: 3 sets 20 deg 2 Hz, "
                                         "3 sets 10 deg 3 Hz"):
        export_drives(ctrl, tmp_path / "x", conditions=["7 sets 10 deg 3 Hz"])
