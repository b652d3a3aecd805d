"""Time to the first number with a new effect, for each build of the compiled model (``results/compile.md``).

Run as ``python -m ehas_env.cli.compile_bench [--out results/compile.md]``.  For each build
(``EHAS_BUILD=quick``: functions compiled once and called; ``EHAS_BUILD=inline``: every function inlined into
the drivers, the environments' build) and in a fresh model cache, it times as whole processes:

1. ``ehas compare CAMP``: the library's model, first run (compile included) -- once per machine;
2. ``ehas compare CAMP --effects-path FX --effects NAME`` with an effect file this cache has never seen
   (library model cached): the user's first replay;
3. the same command again (everything cached), and again with numba's own BLAS probe
   (``EHAS_NUMBA_BLAS_PROBE=import``, :mod:`ehas_env.physics.numba_start`): median of ``REPEATS`` runs;

beside numba's own floor in a new process: importing it, and calling one cached one-line function (with
numba's BLAS probe and with the one ehas answers);

and, unless ``--no-diagnose``, the user's loop on a fresh 5-run campaign (3 s runs) from a rig with a hidden
torsion spring of 800 N m/rad (a user effect the diagnosis is not given), in an empty model cache (every compile
included): ``ehas diagnose CAMP --write-effect DIR/found.py``, then the ``next:`` compare it prints, run as
printed.

Wall time and the processes' CPU time (user + system, the figure a quiet machine's wall time approaches) are
reported with the load average, since the machine may be shared.
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ehas_env.physics.effects.example_file import spring_effect



def _timed(cmd, env, cwd=None) -> tuple[float, float, str]:
    """Wall and CPU seconds of the process ``cmd``, and its standard output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, env=env, check=True, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                         cwd=cwd).stdout
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), out


#: numba's own floor, beside the cached rows: a new process that loads one cached one-line function pays the
#: imports of Python, numpy and numba and the set-up of numba's CPU target, whatever the function
_FLOOR_SCRIPT = """import numpy as np
import numba


@numba.njit(cache=True)
def total(x):
    return x.sum()


total(np.ones(3))
"""


#: runs of every row that can be repeated (the cached ones and the floor): their median is reported
REPEATS = 5


def _timed_median(cmd, env, n: int = REPEATS) -> tuple[float, float]:
    """Median wall and CPU seconds of ``n`` runs of the process ``cmd``."""
    import statistics

    runs = [_timed(cmd, env)[:2] for _ in range(n)]
    return statistics.median(w for w, _ in runs), statistics.median(c for _, c in runs)


def _floor_rows(tmp: Path) -> list:
    """Rows for numba itself in a new process: importing it, and calling one cached one-line function (with
    numba's own BLAS probe, and with the probe ehas answers, :mod:`ehas_env.physics.numba_start`)."""
    script = tmp / "numba_floor.py"
    script.write_text(_FLOOR_SCRIPT)
    probed = tmp / "numba_floor_probed.py"
    probed.write_text("from ehas_env.physics.numba_start import answer_blas_probe\n\nanswer_blas_probe()\n"
                      + _FLOOR_SCRIPT)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp / "cache-numba-floor")}
    print("compile_bench: numba's floor (import; one cached one-line function) ...", file=sys.stderr, flush=True)
    for s in (script, probed):
        subprocess.run([sys.executable, str(s)], env=env, check=True)  # compiles and caches it
    rows = []
    for what, cmd in (("numba alone: `import numpy, numba` (no function)",
                       [sys.executable, "-c", "import numpy, numba"]),
                      ("numba alone: one cached one-line `@njit` function, called once (the floor of any cached run)",
                       [sys.executable, str(script)]),
                      ("the same, numba's BLAS probe answered without importing scipy.linalg (as ehas does)",
                       [sys.executable, str(probed)])):
        load0 = os.getloadavg()[0]
        wall, cpu = _timed_median(cmd, env)
        rows.append(("-", what, wall, cpu, load0, os.getloadavg()[0]))
    return rows


def _diagnose_rows(ehas, tmp: Path) -> list:
    """The diagnose -> next: compare loop on a fresh campaign with a hidden spring, in an empty model cache."""
    env = {**os.environ, "EHAS_CACHE_DIR": str(tmp / "cache-diagnose")}
    hidden = tmp / "fx-hidden"
    hidden.mkdir()
    (hidden / "hidden_spring.py").write_text(spring_effect("hidden_spring", "HiddenSpring"))
    camp = tmp / "camp-spring"
    print("compile_bench: writing a 5-run campaign with a hidden 800 N m/rad spring ...", file=sys.stderr, flush=True)
    subprocess.run(ehas + ["simulate-campaign", "--seed", "2", "--out", str(camp), "--effects-path", str(hidden),
                           "--effects", "hidden_spring:k=800"], env={**env, "EHAS_CACHE_DIR": str(tmp / "cache-gen")},
                   check=True, stdout=subprocess.DEVNULL)
    rows = []
    print("compile_bench: quick build: ehas diagnose --write-effect (empty model cache) ...", file=sys.stderr,
          flush=True)
    load0 = os.getloadavg()[0]
    wall, cpu, out = _timed(ehas + ["diagnose", str(camp), "--write-effect", str(tmp / "found" / "found.py")], env,
                            cwd=tmp)
    rows.append(("quick", "`ehas diagnose CAMP --write-effect DIR/found.py` (empty model cache)", wall, cpu, load0,
                 os.getloadavg()[0]))
    m = re.search(r"^next: ehas (compare .*)$", out, flags=re.M)
    if m is None:
        raise SystemExit("compile_bench: the diagnosis printed no next: command:\n" + out[-2000:])
    print("compile_bench: quick build: the printed next: compare ...", file=sys.stderr, flush=True)
    load0 = os.getloadavg()[0]
    wall, cpu, _ = _timed(ehas + shlex.split(m.group(1)), env, cwd=tmp)
    rows.append(("quick", "the printed `next:` compare, run as printed", wall, cpu, load0, os.getloadavg()[0]))
    rows.append(("quick", "**diagnose + next: together**", rows[-2][2] + rows[-1][2], rows[-2][3] + rows[-1][3],
                 rows[-2][4], rows[-1][5]))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m ehas_env.cli.compile_bench", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/compile.md", help="markdown file to write (default results/compile.md)")
    ap.add_argument("--builds", default="quick,inline", help="builds to time, comma-separated (quick, inline)")
    ap.add_argument("--no-diagnose", action="store_true", help="leave out the diagnose -> next: compare rows")
    args = ap.parse_args(argv)
    builds = [b for b in args.builds.split(",") if b]
    if not builds or any(b not in ("quick", "inline") for b in builds):
        ap.error("--builds takes quick and/or inline")
    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.outputs import OutputError, check_file

    try:  # before minutes of work: a folder, a path under a file or an unwritable folder is refused now
        check_file(args.out, "--out", overwrite=True, suffix=".md")
    except OutputError as exc:
        ap.error(str(exc))
    ehas = [sys.executable, "-m", "ehas_env.cli.main"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="ehas-compile-bench-") as tmp:
        tmp = Path(tmp)
        camp = tmp / "camp"
        env0 = {**os.environ, "EHAS_CACHE_DIR": str(tmp / "cache-campaign")}
        print("compile_bench: writing a 5-run campaign (2 s runs) ...", file=sys.stderr, flush=True)
        subprocess.run(ehas + ["simulate-campaign", "--duration", "2", "--seed", "1", "--out", str(camp)], env=env0,
                       check=True, stdout=subprocess.DEVNULL)
        rows += _floor_rows(tmp)
        for k, build in enumerate(builds):
            env = {**os.environ, "EHAS_BUILD": build, "EHAS_CACHE_DIR": str(tmp / f"cache-{build}")}
            fx = tmp / f"fx-{build}"
            fx.mkdir()
            (fx / "bench_spring.py").write_text(spring_effect(f"bench_spring_{k}", f"BenchSpring{k}"))
            with_effect = ehas + ["compare", str(camp), "--effects-path", str(fx), "--effects", f"bench_spring_{k}"]
            # (row, command, environment, repeated: a cached run can be repeated, the median of REPEATS is given)
            steps = [("library model, first run (once per machine)", ehas + ["compare", str(camp)], env, False),
                     ("new user effect, first replay", with_effect, env, False),
                     ("same command again (cached)", with_effect, env, True),
                     ("same command again, numba's own BLAS probe (`EHAS_NUMBA_BLAS_PROBE=import`)", with_effect,
                      {**env, "EHAS_NUMBA_BLAS_PROBE": "import"}, True)]
            for what, cmd, step_env, repeated in steps:
                print(f"compile_bench: {build} build: {what} ...", file=sys.stderr, flush=True)
                load0 = os.getloadavg()[0]
                wall, cpu = _timed_median(cmd, step_env) if repeated else _timed(cmd, step_env)[:2]
                rows.append((build, what, wall, cpu, load0, os.getloadavg()[0]))
        if not args.no_diagnose:
            rows += _diagnose_rows(ehas, tmp)
    text = ["# Compile time: the user's first number with a new effect", "",
            f"Regenerate with `python -m ehas_env.cli.compile_bench --builds {','.join(builds)}"
            f"{' --no-diagnose' if args.no_diagnose else ''} --out {args.out}`.", "",
            f"Measured {time.strftime('%Y-%m-%dT%H:%M:%S%z')} on {os.cpu_count()} cores. Each row is one `ehas` "
            "process: the compare rows on a 5-run campaign (2 s runs) in a fresh model cache per build, the diagnose "
            "rows on a 5-run campaign (3 s runs) with a hidden 800 N m/rad torsion spring in an empty model cache; CPU = user + system time of "
            "the process, the figure a quiet machine's wall time approaches; load = 1-min load average before / "
            "after (above the core count, other processes shared the machine). The rows of build `-` time numba "
            f"itself in a new process, the floor under every cached row. The cached rows and the floor are the "
            f"median of {REPEATS} runs each, the other rows one run (a first compile happens once).", "",
            "| build | step | wall s | CPU s | load |", "|---|---|---:|---:|---|"]
    for build, what, wall, cpu, l0, l1 in rows:
        text.append(f"| {build} | {what} | {wall:.1f} | {cpu:.1f} | {l0:.1f} / {l1:.1f} |")
    text += ["", "`quick` is the build every `Plant` runs (replay, fits, single runs, the campaign generator); "
             "`inline` the one of the environments, the batched kernel and benchmark grids (see "
             "`ehas_env.simulation.compiled_model.current_model`). Both give the same numbers bit for bit "
             "(tests/physics/test_model_cache.py)."]
    atomic_write_text(args.out, "\n".join(text) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
