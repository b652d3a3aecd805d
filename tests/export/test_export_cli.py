"""The three export commands as a user runs them: what they write, what they never touch, what they refuse before
any work (the fault campaign, tests/fault_campaign.py, walks their bad input; these are the cases a fix was for)."""
from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import pytest

from ehas_env.cli.main import main
from ehas_env.simulation.fmu import ZIP_DATE, write_fmu

ROOT = Path(__file__).resolve().parents[2]
LEARNED = ROOT / "results" / "long_test_guard" / "learned_harmonic_on_schedule_model_based.json"
SCHEDULE = ROOT / "results" / "controllers" / "schedule_model.json"


def test_export_controller_writes_its_pair_and_leaves_the_folder_alone(tmp_path, capsys):
    out = tmp_path / "rig"
    out.mkdir()
    (out / "notes.txt").write_text("my notes\n")
    argv = ["export-controller", str(SCHEDULE), "--out", str(out), "--name", "rig_sched"]
    assert main(argv) == 0
    header = (out / "rig_sched.h").read_text()
    assert f"ehas export-controller {SCHEDULE} --format c --out {out} --name rig_sched" in header
    assert "int rig_sched_init(rig_sched_state *st" in header
    assert main(argv) == 2 and "--overwrite" in capsys.readouterr().err  # an earlier pair is not replaced silently
    assert main(argv + ["--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "rig_sched.c", "rig_sched.h"]


def test_export_drive_overwrite_keeps_the_input_and_the_users_own_files(tmp_path):
    # the drive files are members of a shared folder: --overwrite once took every *.json and *.csv of the folder
    # with it, the learning controller's own file among them
    d = tmp_path / "d"
    d.mkdir()
    shutil.copy(LEARNED, d / "learned.json")
    (d / "my_notes.json").write_text('{"rig": "B"}\n')
    (d / "rig_log.csv").write_text("t,x\n0,1\n")
    mine = {p.name: p.read_bytes() for p in d.iterdir()}
    argv = ["export-drive", str(d / "learned.json"), "--condition", "7,30,3", "--out", str(d)]
    assert main(argv) == 0
    assert main(argv + ["--overwrite"]) == 0
    assert {p.name: p.read_bytes() for p in d.iterdir() if p.name in mine} == mine
    side = json.loads((d / "drive.json").read_text())
    assert side["type"] == "drive" and len(side["files"]) == 1


def test_export_drive_refuses_to_write_over_its_input(tmp_path, capsys):
    d = tmp_path / "d"
    d.mkdir()
    shutil.copy(LEARNED, d / "drive.json")  # a learning controller's file named as the drive set's controller file
    before = (d / "drive.json").read_bytes()
    assert main(["export-drive", str(d / "drive.json"), "--out", str(d), "--overwrite"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "would replace the input" in err
    assert (d / "drive.json").read_bytes() == before and sorted(p.name for p in d.iterdir()) == ["drive.json"]


def test_export_fmu_refuses_a_controller_without_a_compiled_law_before_writing(tmp_path, capsys):
    out = tmp_path / "f" / "rig.fmu"
    assert main(["export-fmu", "--controller", str(LEARNED), "--out", str(out), "--no-binary"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--controller {LEARNED}" in err and "no compiled law" in err
    assert not out.parent.exists() or not any(out.parent.iterdir())


def test_export_fmu_refuses_an_existing_file_and_a_name_without_fmu(tmp_path, capsys):
    out = tmp_path / "rig.fmu"
    out.write_text("earlier\n")
    assert main(["export-fmu", "--out", str(out), "--no-binary"]) == 2
    assert main(["export-fmu", "--out", str(tmp_path / "rig.zip"), "--no-binary"]) == 2
    err = capsys.readouterr().err
    assert "--overwrite" in err and "expected a .fmu file name" in err
    assert out.read_text() == "earlier\n" and sorted(p.name for p in tmp_path.iterdir()) == ["rig.fmu"]


def test_the_same_model_gives_the_same_fmu_bytes(tmp_path):
    a, b = tmp_path / "a.fmu", tmp_path / "b.fmu"
    write_fmu(a, binary=False)
    write_fmu(b, binary=False)
    assert a.read_bytes() == b.read_bytes()
    with zipfile.ZipFile(a) as z:
        assert {i.date_time for i in z.infolist()} == {ZIP_DATE}  # no clock in the file: a later export is equal
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary left beside it


@pytest.mark.parametrize("argv, culprit", [
    (["export-controller", "{ilc}", "--out", "{tmp}/c"], "learned nothing yet"),
    (["export-drive", "{ilc}", "--out", "{tmp}/c"], "learned nothing yet"),
    (["export-drive", str(LEARNED), "--condition", "7,30,9", "--out", "{tmp}/c"],
     "nothing learned at 7 sets 30 deg 9 Hz"),
])
def test_a_learning_controller_without_the_table_asked_for_is_refused_and_nothing_written(tmp_path, capsys, argv,
                                                                                           culprit):
    ilc = json.loads(LEARNED.read_text())
    ilc.pop("learned")
    (tmp_path / "ilc.json").write_text(json.dumps(ilc))
    argv = [a.replace("{ilc}", str(tmp_path / "ilc.json")).replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and culprit in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ilc.json"]
