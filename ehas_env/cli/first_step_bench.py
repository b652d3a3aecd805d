"""The environment's first step, timed as whole processes (``results/first_step.md``).

Run as ``python -m ehas_env.cli.first_step_bench [--out results/first_step.md]``.  Each row is one new
``python`` process that imports ehas, makes ``gymnasium.make("ehas/Tracking-v0")``, resets it and steps it
once:

1. in an empty model cache (``EHAS_CACHE_DIR`` a new folder): the step runs on the interpreted build while
   the fast-step build compiles in a background process (:mod:`ehas_env.physics.compile_behind`), which the
   timed process ends when it has its figure -- ``--runs`` processes, each in its own empty cache;
2. once more in an empty cache, stepping on until the environment switches to the fast-step build: the
   wall time to the switch, the background compile's own CPU time (its log) and the estimate the message
   printed;
3. in that filled cache: the fast-step build from the first step on (``--runs`` processes);
4. in one process, the steps per CPU-second of the fast-step and of the interpreted build.

Wall time and CPU time (user + system of the timed process; the background compile is not in it) are
reported with the load average, since the machine may be shared.
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: what each timed process runs; argv[1]: "first" (end the background compile after the first step) or "switch"
SCRIPT = r"""
import sys, time
t0 = time.perf_counter()
import gymnasium, numpy as np, ehas_env
env = gymnasium.make("ehas/Tracking-v0").unwrapped
env.reset(seed=0)
env.step(np.array([0.1], np.float32))
t1 = time.perf_counter()
build = env._model.__name__.split("_")[1]
if sys.argv[1] == "switch":
    k = 0
    while not env.wait_for_fast_step(timeout=0.0):
        obs, r, term, trunc, info = env.step(np.array([0.1], np.float32))
        k += 1
        if term or trunc:
            env.reset()
    print(f"switched {time.perf_counter() - t0:.2f} {k}")
proc = getattr(env._builds, "_proc", None)
if proc is not None and proc.poll() is None:
    proc.terminate()  # not waited for: its CPU time is not this process's
print(f"first_step {t1 - t0:.3f} {build}")
"""

#: steps per CPU-second of the fast-step and the interpreted build, one process (a filled cache)
SPEED = r"""
import time
import numpy as np
from ehas_env.env.tracking_env import TrackingEnv
from ehas_env.simulation.compiled_model import current_model
for name, model in (("fast", current_model()), ("interpreted", current_model(interpreted=True))):
    env = TrackingEnv()
    env._builds.model = env._builds.fast = env._model = model
    env._builds.done = True
    env.reset(seed=0)
    a = np.array([0.1], np.float32)
    for _ in range(50):
        env.step(a)
    c0, n = time.process_time(), 0
    while time.process_time() - c0 < 3.0:
        for _ in range(100):
            _, _, te, tr, _ = env.step(a)
            if te or tr:
                env.reset()
        n += 100
    print(f"speed_{name} {n / (time.process_time() - c0):.0f}")
"""


def _run(mode: str, cache: Path, script: str = SCRIPT) -> dict:
    env = {**os.environ, "EHAS_CACHE_DIR": str(cache)}
    env.pop("EHAS_BUILD", None)
    env.pop("EHAS_COMPILE_BEHIND", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", script, mode], env=env, capture_output=True, text=True, timeout=3600)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        raise SystemExit(f"first_step_bench: the timed process failed:\n{out.stderr[-2000:]}")
    row = {"wall": wall, "cpu": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)}
    for line in out.stdout.splitlines():
        key, *vals = line.split()
        row[key] = vals
    est = re.search(r"compiles in a background process \(about (\d+(?:-\d+)?) s", out.stderr)
    row["estimate"] = est.group(1) if est else "?"
    return row


def _busy(*loads: str) -> str:
    """A note when a load average was above the core count (other processes shared the machine)."""
    try:
        high = max(float(x) for x in loads) > (os.cpu_count() or 1)
    except ValueError:  # "unknown"
        return ""
    return " (above the core count: other processes shared the machine)" if high else ""


def _load() -> str:
    try:
        return f"{os.getloadavg()[0]:.1f}"
    except OSError:
        return "?"


def _median(rows, key) -> float:
    return statistics.median(r[key] for r in rows)


def main(argv=None) -> int:
    """Time the first step in an empty and a filled model cache; write the table.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success.
    """
    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.progress import status

    ap = argparse.ArgumentParser(prog="python -m ehas_env.cli.first_step_bench", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/first_step.md", help="the table to write (default results/first_step.md)")
    ap.add_argument("--runs", type=int, default=5, help="processes per cold and warm row, 1..50 (default 5)")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = ap.parse_args(argv)
    if not 1 <= args.runs <= 50:
        ap.error(f"--runs must be in 1..50, got {args.runs}")
    out = Path(args.out)
    if out.exists() and not args.overwrite:
        ap.error(f"--out {out} already exists; pass --overwrite")
    load0 = _load()
    with tempfile.TemporaryDirectory(prefix="ehas-first-step-") as tmp:
        cold = []
        for k in range(args.runs):
            status(f"first step in an empty model cache, run {k + 1}/{args.runs} ...", "first_step_bench")
            cold.append(_run("first", Path(tmp) / f"cold{k}"))
        status("first step in an empty cache, stepping on until the fast-step build is in use ...", "first_step_bench")
        cache = Path(tmp) / "filled"
        sw = _run("switch", cache)
        logs = list(cache.glob("*.compile.log"))
        m = re.search(r"in ([\d.]+) s of CPU", logs[0].read_text()) if logs else None
        bg_cpu = float(m.group(1)) if m else float("nan")
        warm = []
        for k in range(args.runs):
            status(f"first step in the filled cache, run {k + 1}/{args.runs} ...", "first_step_bench")
            warm.append(_run("first", cache))
        status("steps per CPU-second of the two builds ...", "first_step_bench")
        speed = _run("speed", cache, SPEED)
    load1 = _load()
    builds = {r["first_step"][1] for r in cold}
    warm_builds = {r["first_step"][1] for r in warm}
    lines = [
        "# The environment's first step",
        "",
        f"Regenerate with `python -m ehas_env.cli.first_step_bench --runs {args.runs} --out {out.as_posix()}"
        f"{' --overwrite' if args.overwrite else ''}`.",
        "",
        f"Measured {time.strftime('%Y-%m-%dT%H:%M:%S%z')} on {os.cpu_count()} cores; 1-min load average {load0} "
        f"before, {load1} after{_busy(load0, load1)}. Each row: new "
        "`python` processes that import ehas, make `gymnasium.make(\"ehas/Tracking-v0\")`, reset and step it once; "
        "wall and CPU (user + system) of the whole process, median of the runs (min-max in brackets). The first "
        "step's build: `py` the interpreted build, `model` the fast-step (inlined, compiled) build.",
        "",
        "| row | build of the first step | process wall s | process CPU s | time to the first step s |",
        "|---|---|---:|---:|---:|",
        f"| empty model cache ({args.runs} runs, each its own cache) | {', '.join(sorted(builds))} | "
        f"{_median(cold, 'wall'):.2f} ({min(r['wall'] for r in cold):.2f}-{max(r['wall'] for r in cold):.2f}) | "
        f"{_median(cold, 'cpu'):.2f} | {statistics.median(float(r['first_step'][0]) for r in cold):.2f} |",
        f"| filled cache ({args.runs} runs) | {', '.join(sorted(warm_builds))} | "
        f"{_median(warm, 'wall'):.2f} ({min(r['wall'] for r in warm):.2f}-{max(r['wall'] for r in warm):.2f}) | "
        f"{_median(warm, 'cpu'):.2f} | {statistics.median(float(r['first_step'][0]) for r in warm):.2f} |",
        "",
        f"From an empty cache, stepping on: the environment switched to the fast-step build "
        f"{float(sw['switched'][0]):.1f} s after the process started, after {sw['switched'][1]} steps on the "
        f"interpreted build; the background compile took {bg_cpu:.1f} s of CPU; the message had estimated "
        f"about {sw['estimate']} s at the load of that moment.",
        "",
        f"Steps per CPU-second of one environment (one process, the same 3 s of CPU each): fast-step build "
        f"{float(speed['speed_fast'][0]):,.0f}, interpreted build {float(speed['speed_interpreted'][0]):,.0f} "
        f"({float(speed['speed_fast'][0]) / float(speed['speed_interpreted'][0]):.0f} times fewer).",
        "",
    ]
    atomic_write_text(out, "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
