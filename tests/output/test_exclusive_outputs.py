"""Issue 22: one writer per output, and a failing command leaves none of its outputs (--json included)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from ehas_env.output import files
from ehas_env.output.outputs import OutputError, OutputSet, check_file, lock, unlock


def test_a_checked_file_is_placed_only_when_the_command_succeeds(tmp_path):
    out = tmp_path / "d.json"
    files.begin()
    check_file(out, "--json")
    files.atomic_write_text(out, "{}\n")
    assert not out.exists()  # waiting for the command's end
    files.finish(False)  # the command failed afterwards (say, its --out report on a full disk)
    assert not out.exists() and os.listdir(tmp_path) == []
    files.begin()
    check_file(out, "--json")
    files.atomic_write_text(out, "{}\n")
    files.finish(True)
    assert out.read_text() == "{}\n" and os.listdir(tmp_path) == ["d.json"]


def test_creation_is_exclusive_without_overwrite(tmp_path):
    out = tmp_path / "m.json"
    files.begin()
    check_file(out, "FILE")
    files.atomic_write_text(out, "mine\n")
    # another run created the file meanwhile (after our check, before our end)
    other = tmp_path / "other.tmp"
    other.write_text("theirs\n")
    os.link(other, out)
    with pytest.raises(files.OutputExists, match="FILE .*m.json was created by another run meanwhile"):
        files.finish(True)
    assert out.read_text() == "theirs\n"  # never replaced
    assert sorted(os.listdir(tmp_path)) == ["m.json", "other.tmp"]  # no temporary left


def test_a_second_writer_of_the_same_output_is_refused_while_the_first_runs(tmp_path):
    target = tmp_path / "report"
    code = ("import sys, time\nfrom ehas_env.output.outputs import lock\n"
            f"lock({str(target)!r}, '--out')\nprint('locked', flush=True)\ntime.sleep(30)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "locked"
        with pytest.raises(OutputError, match=rf"--out {target}: another ehas run \(pid {proc.pid}\) is writing"):
            OutputSet(target, "--out")
    finally:
        proc.kill()
        proc.wait()
    # the first run is gone: its claim is taken over
    s = OutputSet(target, "--out")
    with s as tmp:
        (tmp / "a.txt").write_text("x")
    assert (target / "a.txt").exists() and not any(p.name.endswith("ehas-lock") for p in tmp_path.iterdir())


def test_a_claim_is_released_and_reentrant(tmp_path):
    lk = lock(tmp_path / "x.json", "--json")
    assert lk.exists() and lock(tmp_path / "x.json", "--json") == lk
    unlock(lk)
    assert not lk.exists()


def test_diagnose_failing_after_its_json_leaves_no_json(tmp_path, monkeypatch, capsys):
    """The issue's case: --json written, then the --out report fails (a full disk): neither stays."""
    from ehas_env.cli import main as cli
    from ehas_env.cli import compare

    assert cli.main(["simulate-campaign", "--duration", "0.21", "--out", str(tmp_path / "camp")]) == 0

    def full(*a, **k):
        raise OSError(28, "No space left on device", str(tmp_path / "rep" / "report.md"))

    monkeypatch.setattr(compare, "write_report", full)
    rc = cli.main(["diagnose", str(tmp_path / "camp"), "--json", str(tmp_path / "d.json"), "--out",
                   str(tmp_path / "rep"), "--no-propose", "--no-stack", "--candidates", "coulomb_friction"])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip() and not ln.startswith("[")]
    assert rc == 1 and "No space left on device" in err[-1], err
    assert not (tmp_path / "d.json").exists() and not (tmp_path / "rep").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camp"]
    json.loads((tmp_path / "camp" / "truth.json").read_text())
