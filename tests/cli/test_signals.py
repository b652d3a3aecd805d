"""A SIGTERM (a scheduler's stop, ``kill``) ends a command as Ctrl-C does: one line, status 130, nothing half-written."""
from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from interrupt_probe import _proc_status  # tests/cli: the probe's reading of /proc

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


@pytest.mark.slow  # trains PPO in a child process until a checkpoint, then resumes: 536 s on 2 loaded cores; the
# default run keeps tests/train/test_train.py::test_ctrl_c_writes_a_checkpoint (Ctrl-C checkpoints, the resume ends
# at total_steps) and the SIGINT tests below (status 130, one line)
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


# -- Ctrl-C at any moment (issue 14): the process's own handling, from the first import to the exit --------------
# (tests/cli/interrupt_probe.py sweeps the delays over several commands; these are its three decisive moments)

def _ctrl_c_ready():
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # a background job's ignored SIGINT would hide everything


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _ehas_cmd() -> list[str]:
    ehas = shutil.which("ehas")
    return [ehas] if ehas else [sys.executable, "-m", "ehas_env.cli.main"]


def _one_interrupted_line(err: str, name: str) -> None:
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert err.strip().splitlines()[-1] == f"ehas {name}: interrupted", err


def test_ctrl_c_during_the_imports_is_130_and_one_line(tmp_path):
    """SIGINT while the entry point imports the commands (the earlier bug: a traceback and death by the signal)."""
    import os

    env = dict(os.environ, PYTHONPROFILEIMPORTTIME="1")  # stderr shows each import statement as it completes
    out = tmp_path / "demo"
    proc = subprocess.Popen(_ehas_cmd() + ["demo", "--quick", "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, preexec_fn=_ctrl_c_ready)
    seen = []
    for line in proc.stderr:
        seen.append(line)
        if line.rstrip().endswith("ehas_env.ranges"):  # the parser is loading the command modules
            break
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, "".join(seen) + err
    _one_interrupted_line(err, "demo")
    assert not out.exists()  # nothing was written


def test_ctrl_c_mid_run_keeps_the_previous_output(tmp_path):
    out = tmp_path / "demo"
    cmd = _ehas_cmd() + ["demo", "--quick", "--out", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, preexec_fn=_ctrl_c_ready)
    assert r.returncode == 0, r.stderr
    before = _files(out)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_ctrl_c_ready)
    err = ""
    for line in proc.stderr:
        err += line
        if "2/2" in line:  # the design-point simulation has started: the new set is half-written
            break
    proc.send_signal(signal.SIGINT)
    rest, more = proc.communicate(timeout=60)
    err += more
    assert proc.returncode == 130, err
    _one_interrupted_line(err, "demo")
    assert _files(out) == before  # the previous complete set, untouched
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporaries left


def test_ctrl_c_after_the_output_is_written_is_still_130(tmp_path):
    """The signal after the command wrote its output (its return, the interpreter's exit): 130, one line."""
    import os

    import time

    stem = tmp_path / "run"
    cmd = [sys.executable, "-m", "ehas_env.cli.main", "simulate", "--cycles", "3", "--out", str(stem)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_ctrl_c_ready)
    deadline = time.time() + 300
    while not (stem.with_suffix(".json").exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]):
        assert proc.poll() is None and time.time() < deadline, proc.communicate()[1]
        time.sleep(0.002)  # the sidecar is moved in last: the set is complete
    os.kill(proc.pid, signal.SIGSTOP)  # hold it where it is, to know whether it had ended
    while _proc_status(proc.pid)[1] not in ("T", "t", "Z", ""):  # stopped, or it was already exiting
        time.sleep(0.001)
    ended = _proc_status(proc.pid)[2]  # gone, or past its point of no return (SIGINT blocked before os._exit)
    os.kill(proc.pid, signal.SIGINT)
    os.kill(proc.pid, signal.SIGCONT)
    _, err = proc.communicate(timeout=60)
    if ended:  # it had already exited: nothing to interrupt
        assert proc.returncode == 0, err
    else:
        assert proc.returncode == 130, err
        _one_interrupted_line(err, "simulate")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.json"]  # the new complete set


def test_ctrl_c_during_the_swap_waits_until_the_new_set_is_in_place(tmp_path, monkeypatch):
    """OutputSet.commit holds SIGINT: a Ctrl-C between its renames acts after the last one (no half swap)."""
    import os

    from ehas_env.output import outputs

    final = tmp_path / "report"
    with outputs.OutputSet(final, "--out") as tmp:
        (tmp / "a.txt").write_text("old")
    real_replace, calls = os.replace, []

    def replace(src, dst):
        calls.append(dst)
        if len(calls) == 1:
            signal.raise_signal(signal.SIGINT)  # Ctrl-C right after the first rename of the swap
        return real_replace(src, dst)

    monkeypatch.setattr(outputs.os, "replace", replace)
    # Python's own Ctrl-C handler, whatever an earlier test in this worker left installed (ray.init sets its own)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            with outputs.OutputSet(final, "--out", overwrite=True) as tmp:
                (tmp / "a.txt").write_text("new")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(calls) >= 2  # the swap went on after the signal
    assert (final / "a.txt").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]  # no temporaries, no old set aside


@pytest.mark.slow  # a diagnosis up to its library's screens (with a first compile of the diagnosis' model: 1-2 min)
def test_ctrl_c_during_the_screens_side_by_side_stops_every_thread(tmp_path):
    """Ctrl-C while the library's screens run two at a time on threads (ehas_env.diagnosis.side_by_side): 130, one
    line, no JSON; every thread ends at its next replay, so no screen is completed after the signal (a thread left
    running would finish its screen, and the next, before the interpreter could exit)."""
    import re

    from ehas_env.measurement.synthetic import write_simulated_campaign

    camp = tmp_path / "camp"
    write_simulated_campaign(camp, {"coulomb_friction": {"Fc": 400.0}}, seed=3340)
    out = tmp_path / "d.json"
    proc = subprocess.Popen(_ehas_cmd() + ["diagnose", str(camp), "--json", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, preexec_fn=_ctrl_c_ready)
    err = b""
    while b"diagnose: screening" not in err or not re.search(rb"\| ([1-9]\d*)/\d+ ", err.split(b"screening")[-1]):
        ch = proc.stderr.read1(4096)
        assert ch, err.decode(errors="replace")  # the screens started before the command ended
        err += ch
    done = max(int(n) for n in re.findall(rb"\| (\d+)/\d+ ", err.split(b"screening")[-1]))
    proc.send_signal(signal.SIGINT)
    rest, more = proc.communicate(timeout=120)
    err = (err + more).decode(errors="replace")
    assert proc.returncode == 130, err
    _one_interrupted_line(err, "diagnose")
    after = [int(n) for n in re.findall(r"\| (\d+)/\d+ ", err.split("screening")[-1])]
    assert max(after) <= done + 1, (done, after)  # at most the one the bar had not drawn yet
    assert not out.exists()
