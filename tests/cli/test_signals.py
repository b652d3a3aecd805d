"""A SIGTERM (a scheduler's stop, ``kill``) ends a command as Ctrl-C does: one line, status 130, nothing half-written."""
from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

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


def test_ctrl_c_during_training_checkpoints_and_the_resume_ends_at_total_steps(tmp_path):
    """Ctrl-C: one line naming the step and --resume, status 130; the resumed run ends at total_steps exactly."""
    import json

    from ehas_train.config import bundled_config

    out = tmp_path / "run"
    ehas = shutil.which("ehas") or str(Path(sys.executable).with_name("ehas"))
    cmd = [ehas, "train", "--algo", "ppo", "--config", str(bundled_config("ppo_smoke")), "--out", str(out),
           "--no-progress", "--no-tensorboard", "--total-steps", "400000"]
    # a shell's background job ignores SIGINT, and children inherit that: give the command the default, as a
    # terminal's Ctrl-C finds it
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 600  # a fresh machine compiles the simulator first
    while not (out / "checkpoints" / "state.json").exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.2)
    if not (out / "checkpoints" / "state.json").exists():
        proc.kill()
        pytest.fail(f"no checkpoint within 600 s: {proc.communicate()[1][-2000:]}")
    time.sleep(0.5)  # mid-rollout, most likely
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("ehas train: interrupted at step ") and "--resume" in last, err
    cmd[cmd.index("400000")] = "14000"
    r = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "metrics.json").read_text())["num_timesteps"] == 14000
