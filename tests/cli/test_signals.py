"""A SIGTERM (a scheduler's stop, ``kill``) ends a command as Ctrl-C does: one line, status 130, nothing half-written."""
from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_sigterm_during_bench_is_a_clean_interrupt(tmp_path):
    out = tmp_path / "bench"
    ehas = shutil.which("ehas") or str(Path(sys.executable).with_name("ehas"))  # the console script users run
    cmd = [ehas, "bench", str(ROOT / "results/controllers/model.json"), "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = proc.stderr.readline()  # the command has started its work (its first status line)
    assert first.startswith("[bench]"), first
    time.sleep(0.3)
    proc.send_signal(signal.SIGTERM)
    rest, err = proc.communicate(timeout=60)
    err = first + err
    assert proc.returncode == 130, err
    lines = [ln for ln in err.strip().splitlines() if "interrupted" in ln]
    assert lines and lines[-1] == "ehas bench: interrupted"
    assert "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())  # no half-written output set
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no leftover temporaries
