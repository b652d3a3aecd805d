#!/usr/bin/env python
"""Ctrl-C probe of the ``ehas`` command line (issue 14): a standalone script, not a pytest module.

::

    python tests/cli/interrupt_probe.py [--work DIR] [--delays 15] [--only demo,identify] [--double]
                                        [--signal INT|TERM] [--csv FILE]

For each command (``demo``, ``demo --quick``, ``identify`` on a 1 s chirp,
``simulate --cycles 3``, ``bench`` of a model-tuned controller, ``curves``) it
first runs the command once to completion (the *previous* output, and the run
time T), then runs it again over that output ``--delays`` times, sending the
signal to the command's process group (as a terminal's Ctrl-C does) after a
sweep of delays from 0.05 s to a little past T (geometric, linear, and a few
just before the end, where the exit path runs).  The command is stopped
(SIGSTOP) for the moment of sending, so that a run that had already begun to
exit (gone, or SIGINT blocked at its point of no return) is told apart (it counts as ended, and may exit 0).  Each run is recorded: status,
the last line of stderr, whether a traceback (or "Exception ignored") appeared,
whether the process had a SIGINT handler when the signal was sent
(``/proc/PID/status`` SigCgt: none in the interpreter's first milliseconds, nor
in its teardown after the atexit callbacks, where Python restores the default
and the signal kills the process), and the state of the output folder:

``prev``  the previous complete output, unchanged
``new``   a complete output set (the same files; the run finished its swap)
``none``  no output
``BROKEN`` anything else (missing files, temporaries left)

A run is **good** when it exited 130 (or 0 if it had ended before the signal
was sent) with the last stderr line ``ehas CMD: interrupted``, no traceback,
and an output state other than BROKEN.  The summary table counts, per
command: runs, status 130, tracebacks, killed by a signal, status 0 after the
signal, other statuses, broken outputs, runs whose signal found no handler, and
runs that had ended before the signal (not counted as bad when they exited 0).  Exit status 1 when any run was bad.

Each command runs on one CPU (``os.sched_setaffinity``) with SIGINT at its
default (a background shell job would hand it an ignored SIGINT).
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _child_setup():
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    except (AttributeError, OSError):
        pass


def _ehas() -> list[str]:
    exe = shutil.which("ehas")
    if exe:
        return [exe]
    return [sys.executable, "-m", "ehas_env.cli.main"]


def _proc_status(pid: int) -> tuple[bool | None, str, bool]:
    """(SIGINT has a handler, the state letter: R, S, T stopped, Z exited, '' gone, it is exiting) from /proc.

    *Exiting*: the process is gone, or its main thread blocks SIGINT, which ehas does at its point of no
    return, just before ``os._exit`` (``ehas_env.cli.main._at_exit``): a signal from then on comes after the
    exit, and the process ends with the command's status.
    """
    caught, state, blocked = None, "", False
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                caught = bool(int(line.split()[1], 16) & (1 << (signal.SIGINT - 1)))
            elif line.startswith("SigBlk:"):
                blocked = bool(int(line.split()[1], 16) & (1 << (signal.SIGINT - 1)))
            elif line.startswith("State:"):
                state = line.split()[1]
    except OSError:
        return None, "", True
    return caught, state, blocked or state in ("Z", "")


def _manifest(folder: Path) -> dict[str, str]:
    out = {}
    if not folder.exists():
        return out
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def _state(now: dict, prev: dict) -> str:
    if now == prev:
        return "prev"
    if not now:
        return "none"
    if set(now) == set(prev):
        return "new"
    return "BROKEN"


def cases(work: Path) -> dict[str, dict]:
    inputs = work / "inputs"
    return {
        "demo": {"argv": ["demo", "--out", "{dir}/out"]},
        "demo-quick": {"argv": ["demo", "--quick", "--out", "{dir}/out"]},
        "identify": {"argv": ["identify", str(inputs / "x.csv"), "--out", "{dir}/out", "--overwrite"]},
        "simulate": {"argv": ["simulate", "--cycles", "3", "--out", "{dir}/run", "--overwrite"]},
        "bench": {"argv": ["bench", str(inputs / "model.json"), "--no-robustness", "--no-book", "--cycles", "3",
                           "--no-progress", "--out", "{dir}", "--overwrite"]},
        "curves": {"argv": ["curves", "--out", "{dir}/out", "--overwrite"]},
    }


def _run(argv, timeout=900.0):
    t0 = time.time()
    r = subprocess.run(_ehas() + argv, capture_output=True, text=True, timeout=timeout, preexec_fn=_child_setup)
    return r, time.time() - t0


def prepare(work: Path) -> None:
    inputs = work / "inputs"
    inputs.mkdir(parents=True, exist_ok=True)
    if not (inputs / "x.csv").exists():
        r, _ = _run(["excite", "chirp", "--duration", "1", "--out", str(inputs / "x")])
        assert r.returncode == 0, r.stderr
    if not (inputs / "model.json").exists():
        r, _ = _run(["tune", "--method", "model", "--out", str(inputs / "model.json"), "--no-progress"])
        assert r.returncode == 0, r.stderr


def delays_for(total: float, n: int) -> list[float]:
    lo, hi = 0.05, max(0.1, total * 1.05)
    k = max(2, n // 3)
    geo = [lo * (hi / lo) ** (i / (k - 1)) for i in range(k)]
    lin = [lo + (hi - lo) * (i + 1) / (k + 1) for i in range(k)]
    end = [max(lo, total - d) for d in (0.4, 0.25, 0.15, 0.08, 0.03, 0.0)]
    out = sorted(set(round(d, 3) for d in geo + lin + end))
    while len(out) > n:  # thin the middle, keep both ends
        out.pop(len(out) // 2)
    return out


def one(argv: list[str], delay: float, sig: int, double: bool) -> dict:
    proc = subprocess.Popen(_ehas() + argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_child_setup, start_new_session=True)
    t0 = time.time()
    time.sleep(delay)
    ended_before, caught = proc.poll() is not None, None
    if not ended_before:
        # stop it first, to know whether it had already begun to exit (a signal to an exiting process is lost)
        try:
            os.killpg(proc.pid, signal.SIGSTOP)
            for _ in range(2000):
                caught, state, exiting = _proc_status(proc.pid)
                if state in ("T", "t", "Z", ""):
                    break
                time.sleep(0.001)
            ended_before = exiting
            if not ended_before:
                os.killpg(proc.pid, sig)
            os.killpg(proc.pid, signal.SIGCONT)
            if double and not ended_before:
                time.sleep(0.1)
                os.killpg(proc.pid, sig)
        except ProcessLookupError:
            ended_before = True
    try:
        out, err = proc.communicate(timeout=600)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    return {"delay": delay, "elapsed": round(time.time() - t0, 2), "rc": proc.returncode,
            "ended_before": ended_before, "no_handler": caught is False, "last": lines[-1] if lines else "",
            "traceback": "Traceback" in err or "Exception ignored" in err, "stderr": err}


def verdict(row: dict, name: str) -> bool:
    if row["traceback"] or row["out"] == "BROKEN":
        return False
    if row["ended_before"]:
        return row["rc"] == 0
    return row["rc"] == 130 and row["last"] == f"ehas {name}: interrupted"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, default=None, help="work folder (default: a temporary one, removed)")
    ap.add_argument("--delays", type=int, default=15)
    ap.add_argument("--only", default="", help="comma-separated case names")
    ap.add_argument("--double", action="store_true", help="send the signal twice, 0.1 s apart")
    ap.add_argument("--signal", choices=("INT", "TERM"), default="INT")
    ap.add_argument("--csv", type=Path, default=None, help="write every run here")
    ap.add_argument("--verbose", action="store_true", help="print stderr of bad runs")
    a = ap.parse_args(argv)
    sig = getattr(signal, "SIG" + a.signal)
    work = a.work or Path(tempfile.mkdtemp(prefix="ehas-interrupt-probe-"))
    prepare(work)
    table, rows = [], []
    for name, case in cases(work).items():
        if a.only and name not in a.only.split(","):
            continue
        d = work / name
        d.mkdir(parents=True, exist_ok=True)
        argv_ = [x.replace("{dir}", str(d)) for x in case["argv"]]
        cmd = argv_[0]
        r, total = _run(argv_)
        if r.returncode != 0:
            print(f"{name}: reference run failed ({r.returncode}): {r.stderr.strip()[-500:]}", file=sys.stderr)
            continue
        r, total = _run(argv_)  # a warm run: the time of the sweep's runs
        prev = _manifest(d)
        counts = dict(runs=0, s130=0, traceback=0, killed=0, exit0=0, other=0, broken=0, no_handler=0, ended=0,
                      bad=0)
        for delay in delays_for(total, a.delays):
            row = one(argv_, delay, sig, a.double)
            now = _manifest(d)
            row["out"] = _state(now, prev)
            row["case"] = name
            row["good"] = verdict(row, cmd)
            counts["runs"] += 1
            counts["s130"] += row["rc"] == 130
            counts["traceback"] += row["traceback"]
            counts["killed"] += row["rc"] < 0
            counts["exit0"] += row["rc"] == 0 and not row["ended_before"]
            counts["ended"] += row["ended_before"]
            counts["other"] += row["rc"] not in (0, 130) and row["rc"] >= 0
            counts["broken"] += row["out"] == "BROKEN"
            counts["no_handler"] += row["no_handler"] and not row["ended_before"]
            counts["bad"] += not row["good"]
            rows.append(row)
            flag = "" if row["good"] else "  <-- BAD"
            print(f"{name:11s} t={delay:6.2f}/{total:5.1f}s rc={row['rc']:4d} out={row['out']:6s} "
                  f"tb={int(row['traceback'])} nh={int(row['no_handler'])} | {row['last'][:70]}{flag}", flush=True)
            if not row["good"] and a.verbose:
                print("    " + row["stderr"].strip()[-1500:].replace("\n", "\n    "), flush=True)
            if row["out"] in ("none", "BROKEN"):
                _run(argv_)  # put a complete output back for the next run
                now = _manifest(d)
            if now:
                prev = now
        table.append((name, round(total, 1), counts))
    print()
    head = ("case", "T s", "runs", "130", "traceback", "killed", "exit0", "other", "broken", "no handler", "ended",
            "bad")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for name, total, c in table:
        vals = [name, total, c["runs"], c["s130"], c["traceback"], c["killed"], c["exit0"], c["other"], c["broken"],
                c["no_handler"], c["ended"], c["bad"]]
        print("| " + " | ".join(str(v) for v in vals) + " |")
    if a.csv:
        keys = ["case", "delay", "elapsed", "rc", "ended_before", "no_handler", "out", "traceback", "good", "last"]
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
            w.writeheader()
            w.writerows(rows)
    if a.work is None:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if any(c["bad"] for _, _, c in table) else 0


if __name__ == "__main__":
    sys.exit(main())
