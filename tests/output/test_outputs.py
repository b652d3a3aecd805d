"""The output layer (issue 14): output sets swapped in whole; interrupted or killed runs leave the
previous complete set; leftovers of killed runs are cleaned up by the next run; seeded runs are
byte-identical."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from ehas_env.cli.main import main
from ehas_env.output import outputs as O
from ehas_env.output.outputs import OutputError, OutputSet, clean_stale, stem_set


def snapshot(folder: Path) -> dict:
    """The files and their bytes (a folder set's record of its files aside)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != O.RECORD}


def hidden(folder: Path) -> list:
    """Hidden leftovers (temporaries of a run), not the records of folder sets."""
    return [p.name for p in folder.rglob(".*") if p.name != O.RECORD]


def write_set(out: Path, files: dict, **kw) -> None:
    with OutputSet(out, "--out", **kw) as tmp:
        for name, text in files.items():
            (tmp / name).write_text(text)


def test_folder_set_is_replaced_whole(tmp_path):
    out = tmp_path / "report"
    write_set(out, {"a.md": "1", "b.png": "1"})
    with pytest.raises(OutputError, match="--overwrite"):
        write_set(out, {"a.md": "2"})
    write_set(out, {"a.md": "2"}, overwrite=True)
    assert snapshot(out) == {"a.md": b"2"}  # b.png of the earlier run is gone: no mixed set
    assert hidden(tmp_path) == []


def test_overwrite_never_deletes_files_ehas_did_not_write(tmp_path):
    # a user's own folder given as --out by mistake
    mine = tmp_path / "thesis"
    (mine / "data").mkdir(parents=True)
    (mine / "thesis.tex").write_text("mine")
    (mine / "data" / "rig_log.csv").write_text("t\n0\n")
    before = snapshot(mine)
    with pytest.raises(OutputError, match=r"--out .*thesis holds files no ehas run wrote there "
                                          r"\(data/rig_log.csv, thesis.tex\)"):
        write_set(mine, {"a.md": "1"}, overwrite=True)
    assert snapshot(mine) == before
    # an earlier output (nested folders too) is on its record and is replaced ...
    out = tmp_path / "report"
    with OutputSet(out, "--out") as tmp:
        (tmp / "sub").mkdir()
        (tmp / "sub" / "x.csv").write_text("1")
        (tmp / "a.md").write_text("1")
    assert O.foreign_files(out) == []
    write_set(out, {"a.md": "2"}, overwrite=True)
    assert snapshot(out) == {"a.md": b"2"}
    # ... until the user adds a file of their own to it
    (out / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match=r"holds files no ehas run wrote there \(notes.txt\)"):
        write_set(out, {"a.md": "3"}, overwrite=True)
    assert (out / "notes.txt").read_text() == "mine" and (out / "a.md").read_text() == "2"
    # a damaged record protects everything
    (out / "notes.txt").unlink()
    (out / O.RECORD).write_text("{not json")
    with pytest.raises(OutputError, match=r"\(a.md\)"):
        write_set(out, {"a.md": "3"}, overwrite=True)
    (out / O.RECORD).write_text("[]")  # JSON, but not a record
    with pytest.raises(OutputError, match=r"\(a.md\)"):
        write_set(out, {"a.md": "3"}, overwrite=True)


@pytest.mark.parametrize("exc", [RuntimeError("boom"), KeyboardInterrupt()])
def test_interrupted_write_leaves_the_previous_set(tmp_path, exc):
    out = tmp_path / "report"
    write_set(out, {"a.md": "1", "b.png": "1"})
    before = snapshot(out)
    with pytest.raises(type(exc)):
        with OutputSet(out, "--out", overwrite=True) as tmp:
            (tmp / "a.md").write_text("2")
            raise exc
    assert snapshot(out) == before and hidden(tmp_path) == []


def test_member_set_in_a_shared_folder(tmp_path):
    (tmp_path / "other.txt").write_text("not ours")
    members = ("bench.csv", "bench.md", "heatmap_*.png")
    write_set(tmp_path, {"bench.csv": "1", "bench.md": "1", "heatmap_a.png": "1"}, members=members)
    with pytest.raises(OutputError, match="bench.csv already exists; pass --overwrite"):
        write_set(tmp_path, {"bench.csv": "2"}, members=members)
    write_set(tmp_path, {"bench.csv": "2", "bench.md": "2", "heatmap_b.png": "2"}, members=members, overwrite=True)
    assert snapshot(tmp_path) == {"bench.csv": b"2", "bench.md": b"2", "heatmap_b.png": b"2", "other.txt": b"not ours"}
    assert hidden(tmp_path) == []


def _crash_after(monkeypatch, n):
    """os.replace raises (as a SIGKILL would stop the process) after ``n`` calls."""
    real = os.replace
    calls = {"n": 0}

    def replace(a, b):
        calls["n"] += 1
        if calls["n"] > n:
            raise SystemExit("killed")
        return real(a, b)

    monkeypatch.setattr(O.os, "replace", replace)
    return real


@pytest.mark.parametrize("crash_after", [0, 1, 2, 3, 4, 5])
def test_kill_during_a_member_swap_is_repaired_by_the_next_run(tmp_path, monkeypatch, crash_after):
    members = ("run.csv", "run.json", "run.png")
    write_set(tmp_path, {"run.csv": "old", "run.json": "old", "run.png": "old"}, members=members)
    before = snapshot(tmp_path)
    s = OutputSet(tmp_path, "--out", members=members, overwrite=True, last=("run.json",))
    tmp = s.__enter__()
    for n in members:
        (tmp / n).write_text("new")
    real = _crash_after(monkeypatch, crash_after)
    with pytest.raises(SystemExit):
        s.commit()  # killed: no cleanup runs
    monkeypatch.setattr(O.os, "replace", real)
    monkeypatch.setattr(O, "_alive", lambda pid: False)  # the killed process is gone
    clean_stale(tmp_path)
    after = snapshot(tmp_path)
    assert after == before or after == {k: b"new" for k in before}, after
    assert hidden(tmp_path) == []


@pytest.mark.parametrize("crash_after", [0, 1, 2])
def test_kill_during_a_folder_swap_is_repaired_by_the_next_run(tmp_path, monkeypatch, crash_after):
    out = tmp_path / "camp"
    write_set(out, {"a.csv": "old", "a.json": "old"})
    before = snapshot(out)
    s = OutputSet(out, "--out", overwrite=True)
    tmp = s.__enter__()
    (tmp / "a.csv").write_text("new")
    real = _crash_after(monkeypatch, crash_after)
    with pytest.raises(SystemExit):
        s.commit()
    monkeypatch.setattr(O.os, "replace", real)
    monkeypatch.setattr(O, "_alive", lambda pid: False)
    OutputSet(out, "--out", overwrite=True)  # the next run's checks clean up
    assert snapshot(out) in (before, {"a.csv": b"new"})
    assert hidden(tmp_path) == []


def test_stale_temporaries_of_dead_runs_are_removed(tmp_path):
    dead = 2**22 + 4321
    while True:
        try:
            os.kill(dead, 0)
            dead += 1
        except ProcessLookupError:
            break
    (tmp_path / f".out.ehas-tmp.{dead}").mkdir()
    (tmp_path / f".out.ehas-tmp.{dead}" / "half.csv").write_text("half")
    (tmp_path / f".x.csv.{dead}.ab12cd_3.tmp").write_text("half")
    (tmp_path / f".out.ehas-tmp.{os.getpid()}").mkdir()  # a live run's: left alone
    OutputSet(tmp_path / "out", "--out")  # claims the output (.out.ehas-lock, this live run's)
    assert sorted(hidden(tmp_path)) == [".out.ehas-lock", f".out.ehas-tmp.{os.getpid()}"]


def test_stem_set_names_the_stem(tmp_path):
    (tmp_path / "run.json").write_text("{}")
    with pytest.raises(OutputError, match=r"run.json already exists; pass --overwrite"):
        stem_set(tmp_path / "run")
    with pytest.raises(OutputError, match="is a folder"):
        stem_set(tmp_path)
    stem_set(tmp_path / "run.csv", overwrite=True)


# -- through the commands ------------------------------------------------------------------------------------
def test_interrupted_campaign_overwrite_keeps_the_previous_campaign(tmp_path, monkeypatch, capsys):
    out = tmp_path / "camp"
    assert main(["simulate-campaign", "--duration", "0.3", "--seed", "1", "--out", str(out)]) == 0
    before = snapshot(out)
    import ehas_env.measurement.campaign as C
    from ehas_env.measurement import runfile

    real = runfile.write_run
    calls = {"n": 0}

    def write_run(stem, cols, meta, **kw):  # Ctrl-C after the second run file of the new campaign
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(stem, cols, meta, **kw)

    monkeypatch.setattr(C, "_write_run_files", write_run)
    rc = main(["simulate-campaign", "--duration", "0.3", "--seed", "2", "--out", str(out), "--overwrite"])
    assert rc == 130 and capsys.readouterr().err.strip() == "ehas simulate-campaign: interrupted"
    assert snapshot(out) == before
    assert hidden(tmp_path) == []


def test_seeded_campaign_is_byte_identical(tmp_path, capsys):
    for name in ("a", "b"):
        assert main(["simulate-campaign", "--duration", "0.3", "--seed", "5", "--perturb",
                     "--effects", "coulomb_friction:Fc=300", "--out", str(tmp_path / name)]) == 0
    a, b = snapshot(tmp_path / "a"), snapshot(tmp_path / "b")
    assert a and a == b


def test_seeded_simulate_is_byte_identical_and_refuses_to_overwrite(tmp_path, capsys):
    argv = ["simulate", "--cycles", "3", "--freq", "3", "--sensors", "--seed", "7"]
    assert main(argv + ["--out", str(tmp_path / "a")]) == 0
    assert main(argv + ["--out", str(tmp_path / "b")]) == 0
    for suffix in (".csv", ".json"):
        assert (tmp_path / f"a{suffix}").read_bytes() == (tmp_path / f"b{suffix}").read_bytes()
    before = snapshot(tmp_path)
    capsys.readouterr()
    assert main(argv + ["--out", str(tmp_path / "a")]) == 2  # refused before simulating
    assert "--overwrite" in capsys.readouterr().err
    assert snapshot(tmp_path) == before
    assert main(argv + ["--out", str(tmp_path / "a"), "--overwrite"]) == 0
    assert snapshot(tmp_path) == before  # same seed, same bytes
    assert hidden(tmp_path) == []


@pytest.mark.slow
def test_seeded_bench_is_byte_identical(tmp_path, capsys):
    ctrl = Path(__file__).resolve().parents[2] / "results" / "controllers" / "model.json"
    for name in ("a", "b"):
        assert main(["bench", str(ctrl), "--no-robustness", "--no-progress", "--out", str(tmp_path / name)]) == 0
    a, b = snapshot(tmp_path / "a"), snapshot(tmp_path / "b")
    a.pop("benchmark_timing.json"), b.pop("benchmark_timing.json")  # wall times
    assert a and a == b


@pytest.mark.parametrize("argv, culprit", [
    (["compare", "{camp}", "--out", "{camp}", "--overwrite"], "--out"),
    (["diagnose", "{camp}", "--out", "{tmp}", "--overwrite", "--quiet"], "--out"),  # a folder holding the input
    (["diagnose", "{camp}", "--json", "{camp}/cl_3sets_20deg_1hz.json", "--overwrite", "--quiet"], "--json"),
    (["compare", "{camp}", "--save-model", "{camp}/model.json", "--overwrite"], "--save-model"),
])
def test_outputs_never_replace_the_commands_input(tmp_path, capsys, argv, culprit):
    """Even with --overwrite, a command does not write over (or delete) the campaign it reads."""
    camp = tmp_path / "camp"
    assert main(["simulate-campaign", "--duration", "0.3", "--seed", "1", "--out", str(camp)]) == 0
    capsys.readouterr()
    before = snapshot(camp)
    args = [a.format(camp=camp, tmp=tmp_path) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and culprit in err and "input" in err, err
    assert snapshot(camp) == before


def test_a_folder_inside_an_ehas_output_is_that_outputs_own(tmp_path):
    """ehas demo's campaign (on the demo's record only) is replaced by the command its README gives; a file the
    user added inside it is still protected."""
    demo = tmp_path / "demo"
    with OutputSet(demo, "--out") as tmp:
        (tmp / "campaign").mkdir()
        (tmp / "campaign" / "run.csv").write_text("1")
        (tmp / "README.md").write_text("# demo")
    assert not (demo / "campaign" / O.RECORD).exists()
    assert O.foreign_files(demo / "campaign") == []
    write_set(demo / "campaign", {"run.csv": "2"}, overwrite=True)
    assert snapshot(demo / "campaign") == {"run.csv": b"2"}
    (demo / "campaign" / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match=r"holds files no ehas run wrote there \(notes.txt\)"):
        write_set(demo / "campaign", {"run.csv": "3"}, overwrite=True)
    (demo / "campaign" / "notes.txt").unlink()
    # the outer output again, over the inner one regenerated (its own record, a file the outer record lacks)
    write_set(demo / "campaign", {"run.csv": "4", "truth.json": "{}"}, overwrite=True)
    assert O.foreign_files(demo) == []
    with OutputSet(demo, "--out", overwrite=True) as tmp:
        (tmp / "README.md").write_text("# demo 2")
    assert snapshot(demo) == {"README.md": b"# demo 2"}
