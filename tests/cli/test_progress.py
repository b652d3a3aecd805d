"""No long command is silent: each says on stderr what it is doing before it does it.

The commands run as users start them (a fresh process) and are stopped as soon
as they have spoken.  What is asserted is the order (a status line while the
command still runs, before its work), not a time: a loaded machine is slower,
and the figure of how soon a command speaks is not a test's business.
"""
from __future__ import annotations

import os
import select
import subprocess
import sys
import time

import pytest

from ehas_env.output import progress

#: only a guard against a hung command: no assertion is made on the time taken
HANG_S = 300.0

COMMANDS = {
    "demo": ["-m", "ehas_env.cli.main", "demo", "--out", "{tmp}/demo"],
    "curves": ["-m", "ehas_env.cli.main", "curves", "--out", "{tmp}/curves"],
    "compare --fit": ["-m", "ehas_env.cli.main", "compare", "{campaign}", "--effects", "coulomb_friction", "--fit"],
    "book_valve": ["-m", "ehas_env.identification.book_valve", "--out", "{tmp}/identification"],
}


def first_stderr_bytes(argv, timeout: float) -> tuple[bytes, bool]:
    """Start ``python argv``; return what it first wrote to stderr, and whether it was still running then."""
    env = {k: v for k, v in os.environ.items() if k != "EHAS_QUIET"}
    p = subprocess.Popen([sys.executable, *argv], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    try:
        ready, _, _ = select.select([p.stderr], [], [], timeout)
        running = p.poll() is None
        return (os.read(p.stderr.fileno(), 4096) if ready else b""), running
    finally:
        p.kill()
        p.wait()
        p.stderr.close()


@pytest.mark.parametrize("name", list(COMMANDS))
def test_long_commands_speak_before_their_work(name, tmp_path):
    from pathlib import Path

    campaign = Path(__file__).resolve().parents[2] / "results" / "demo" / "campaign"
    argv = [a.format(tmp=tmp_path, campaign=campaign) for a in COMMANDS[name]]
    out, running = first_stderr_bytes(argv, HANG_S)
    assert out.strip(), f"{name}: nothing on stderr"
    assert running, f"{name}: its first words came when it had finished: {out.decode(errors='replace')}"
    first = out.decode(errors="replace").splitlines()[0]
    assert first.startswith(("[", "ehas:")), first  # a status line ([command] ... or ehas: compiling ...)
    assert b"Traceback" not in out, out.decode(errors="replace")


def test_working_repeats_its_status_with_the_elapsed_time(capsys, monkeypatch):
    monkeypatch.delenv("EHAS_QUIET", raising=False)
    with progress.working("fitting", "compare", interval=0.05):
        time.sleep(0.18)
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "[compare] fitting ..."
    assert any(line.startswith("[compare] fitting ... ") and line.endswith(" s") for line in err[1:-1])
    assert err[-1].startswith("[compare] fitting: done in ")


def test_quiet_silences_status_lines(capsys, monkeypatch):
    monkeypatch.setenv("EHAS_QUIET", "1")
    progress.status("hello", "demo")
    with progress.working("x", "demo", interval=0.01):
        time.sleep(0.03)
    assert capsys.readouterr().err == ""
