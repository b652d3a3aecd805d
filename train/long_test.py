"""Learned controllers under the long-test protocol, against the best classical controller per condition.

The agents run in the environment they were trained in (``ehas/Tracking-v0``, batched:
:func:`ehas_train.evaluate.evaluate_policy` with ``long_test=N``): N whole reference
cycles from rest per condition, and the long test's figures
(:mod:`ehas_env.simulation.long_test`: steady-state rms % over the last five cycles,
cycles to settle, worst cycle).  The classical figures are read from the long test of
``ehas bench --long-test`` (its ``long_test.csv``, data), and each agent is set beside the
best classical controller - the one with the lowest mean steady-state rms %, a learning
controller where one was benchmarked - condition by condition.

Command line::

    python -m ehas_train.long_test results/agents/residual_sac_load results/agents/ppo \\
        --classical-csv results/long_test/long_test.csv --out results/long_test/learned

writes ``learned_long_test.csv`` (one row per agent and condition) and
``learned_long_test.md`` (summary, the standing per condition, the regenerating command).
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import sys
import time
from pathlib import Path

import numpy as np

from ehas_env.simulation.long_test import DEFAULT_CYCLES, STEADY_CYCLES

from .evaluate import AMPLITUDES, DISC_SETS, FREQS, _train_info, evaluate_policy, grid_conditions

CSV_COLUMNS = ("controller", "kind", "disc_sets", "freq_hz", "amplitude_deg", "steady_rms_pct", "steady_peak_pct",
               "settle_cycles", "worst_cycle_pct", "hit_stroke_end", "cycle_rms_pct")


def read_classical(path) -> dict[str, dict[tuple, dict]]:
    """The rows of a long test's ``long_test.csv``: controller -> (disc sets, Hz, deg) -> figures.

    Parameters
    ----------
    path : str or path
        A ``long_test.csv`` written by ``ehas bench --long-test``.

    Returns
    -------
    dict
        Per controller name: per condition ``kind``, ``steady_rms_pct`` (%), ``settle_cycles``,
        ``worst_cycle_pct`` (%).

    Raises
    ------
    ValueError
        One line naming the file, if it is not such a CSV.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"--classical-csv {path}: no such file (write it with ehas bench ... --long-test)")
    lines = [ln for ln in path.read_text(encoding="utf-8").splitlines() if ln and not ln.startswith("#")]
    rows = list(csv.DictReader(lines))
    need = {"controller", "kind", "disc_sets", "freq_hz", "amplitude_deg", "steady_rms_pct", "settle_cycles",
            "worst_cycle_pct"}
    if not rows or not need <= set(rows[0]):
        raise ValueError(f"--classical-csv {path}: not a long_test.csv of ehas bench --long-test (columns "
                         f"{', '.join(sorted(need))} expected)")
    out: dict[str, dict[tuple, dict]] = {}
    for r in rows:
        try:
            key = (int(r["disc_sets"]), float(r["freq_hz"]), float(r["amplitude_deg"]))
            out.setdefault(r["controller"], {})[key] = {
                "kind": r["kind"], "steady_rms_pct": float(r["steady_rms_pct"]),
                "settle_cycles": int(r["settle_cycles"]), "worst_cycle_pct": float(r["worst_cycle_pct"])}
        except (TypeError, ValueError):
            raise ValueError(f"--classical-csv {path}: a row of {r.get('controller')!r} has a non-numeric "
                             "condition or figure") from None
    return out


def run(agent_paths, classical_csv, out_dir, *, cycles: int = DEFAULT_CYCLES, command: str = "",
        progress: bool = True) -> dict:
    """Long-test the agents and write their standing against the best classical controller.

    Parameters
    ----------
    agent_paths : list of str
        Agent folders (written by ``ehas train``).
    classical_csv : str or path
        The classical controllers' ``long_test.csv`` (same protocol, same ``cycles``).
    out_dir : str or path
        Output folder.
    cycles : int
        Reference cycles per run (as in the classical long test).
    command : str
        The regenerating command, written into the files.
    progress : bool
        Progress messages.

    Returns
    -------
    dict
        ``summary`` (name -> figures) and ``best_classical`` (its name).
    """
    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.progress import status, working

    from .agent import load_agent

    classical = read_classical(classical_csv)
    grid = grid_conditions()
    for name, by in classical.items():
        missing = [c for c in grid if c not in by]
        if missing:
            raise ValueError(f"--classical-csv {classical_csv}: controller {name!r} lacks {len(missing)} of the 63 "
                             "conditions; run the long test on the whole grid")
    mean = {n: float(np.mean([by[c]["steady_rms_pct"] for c in grid])) for n, by in classical.items()}
    best = min(mean, key=mean.get)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from ehas_controllers.base import LOAD_OPTIONS

    results, summary = {}, {}
    for p in agent_paths:
        agent = load_agent(p, warn=False, allow_pickle=LOAD_OPTIONS["allow_pickle"])
        status(f"long test of {agent.name}: 63 conditions x {cycles} cycles through ehas/Tracking-v0", "long-test")
        t0 = time.perf_counter()
        with working(f"long test of {agent.name}", "long-test"):
            rows = evaluate_policy(agent.cfg, agent.predict, grid, controller_desc=agent.controller_desc,
                                   long_test=cycles, progress=progress)
        results[agent.name] = rows
        steady = np.array([r["steady_rms_pct"] for r in rows])
        ref = np.array([classical[best][c]["steady_rms_pct"] for c in grid])
        summary[agent.name] = {"variant": agent.variant, "mean_steady_rms_pct": float(steady.mean()),
                               "worst_steady_rms_pct": float(steady.max()),
                               "mean_settle_cycles": float(np.mean([r["settle_cycles"] for r in rows])),
                               "wins": int(np.sum(steady < ref)), "losses": int(np.sum(steady >= ref)),
                               "eval_s": time.perf_counter() - t0, "backend": f"stable-baselines3 {agent.cfg.algo.upper()}",
                               **_train_info(p)}
    atomic_write_text(out / "learned_long_test.csv", _csv(results, cycles, command))
    atomic_write_text(out / "learned_long_test.json", json.dumps(
        {"command": command, "cycles": cycles, "best_classical": best, "best_classical_mean_steady_rms_pct": mean[best],
         "classical_mean_steady_rms_pct": mean, "learned": summary}, indent=2) + "\n")
    atomic_write_text(out / "learned_long_test.md", _markdown(results, summary, classical, mean, best, cycles, command,
                                                              classical_csv))
    return {"summary": summary, "best_classical": best, "classical_mean": mean}


def _csv(results, cycles, command) -> str:
    buf = io.StringIO()
    buf.write(f"# learned controllers, long test ({cycles} cycles from rest, steady state = last {STEADY_CYCLES}), "
              f"through ehas/Tracking-v0; regenerate with: {command}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for name, rows in results.items():
        for r in rows:
            w.writerow([name, "learned", r["disc_sets"], f"{r['freq_hz']:g}", f"{r['amplitude_deg']:g}",
                        f"{r['steady_rms_pct']:.6g}", f"{r['steady_peak_pct']:.6g}", r["settle_cycles"],
                        f"{r['worst_cycle_pct']:.6g}", int(bool(r["hit_stroke_end"])),
                        ";".join(f"{x:.4g}" for x in r["cycle_rms_pct"])])
    return buf.getvalue()


def _markdown(results, summary, classical, mean, best, cycles, command, classical_csv) -> str:
    grid = grid_conditions()
    L = ["# Learned controllers under the long test", "", f"Regenerate with `{command}`.", "",
         f"Protocol (`ehas_env.simulation.long_test`, docs/learning-control.md): {cycles} reference cycles from rest "
         f"per condition, **steady rms %** = 100 · RMS(θ_ref − θ)/θ_amp over the last {STEADY_CYCLES} cycles. The "
         "agents run in the environment they were trained in (`ehas/Tracking-v0`, batched); the classical "
         f"controllers' figures are those of `{classical_csv}` (`ehas bench --long-test`, the plant's closed loop, "
         "same model, same metric).", "",
         "| controller | kind | mean steady rms % (63) | worst steady rms % | mean settle cycle | "
         f"conditions beating {best} | training time (2 cores), backend |", "|---|---|---:|---:|---:|---:|---|"]
    rows = []
    for n, by in classical.items():
        st = [by[c]["steady_rms_pct"] for c in grid]
        kind = next(iter(by.values()))["kind"]
        rows.append((mean[n], f"| {n} | {kind} | {mean[n]:.4f} | {max(st):.4f} | "
                              f"{np.mean([by[c]['settle_cycles'] for c in grid]):.1f} | | |"))
    for n, s in summary.items():
        rows.append((s["mean_steady_rms_pct"], f"| {n} | learned ({s['variant']}) | {s['mean_steady_rms_pct']:.4f} | "
                                               f"{s['worst_steady_rms_pct']:.4f} | {s['mean_settle_cycles']:.1f} | "
                                               f"{s['wins']} / 63 | {_train_time(s)} |"))
    L += [r for _, r in sorted(rows, key=lambda x: x[0])]
    bl = min(summary, key=lambda n: summary[n]["mean_steady_rms_pct"]) if summary else None
    if bl is not None:
        s = summary[bl]
        verdict = "beats" if s["mean_steady_rms_pct"] < mean[best] else "does NOT beat"
        L += ["", f"Best classical by the long test: **{best}**, mean steady rms {mean[best]:.4f} %. Best learned: "
              f"**{bl}**, {s['mean_steady_rms_pct']:.4f} % ({verdict} it; better on {s['wins']} of 63 conditions)."]
    ref = classical[best]
    for name, rs in results.items():
        L += ["", f"## {name} against {best}", "",
              "Steady rms %: learned / classical (**bold** where the learned controller is better):", ""]
        by = {(r["disc_sets"], r["freq_hz"], r["amplitude_deg"]): r for r in rs}
        cols = [(f, a) for f in FREQS for a in AMPLITUDES]
        L += ["| disc sets | " + " | ".join(f"{f:g} Hz {a:g}°" for f, a in cols) + " |", "|---|" + "---:|" * len(cols)]
        for n in DISC_SETS:
            cells = []
            for f, a in cols:
                mine, theirs = by[(n, f, a)]["steady_rms_pct"], ref[(n, f, a)]["steady_rms_pct"]
                txt = f"{mine:.3g} / {theirs:.3g}"
                cells.append(f"**{txt}**" if mine < theirs else txt)
            L.append(f"| {n} | " + " | ".join(cells) + " |")
    return "\n".join(L) + "\n"


def _train_time(s: dict) -> str:
    tt = s.get("train_time_s")
    return (f"{tt / 60:.1f} min, " if tt else "not recorded, ") + s["backend"] + \
        (f" ({s['num_timesteps']} steps)" if s.get("num_timesteps") else "")


def main(argv=None) -> int:
    """``python -m ehas_train.long_test AGENT... --classical-csv CSV --out DIR``.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default: the command line).

    Returns
    -------
    int
        0 on success, 2 on a one-line error.
    """
    from ehas_env.ranges import number

    parser = argparse.ArgumentParser(prog="python -m ehas_train.long_test", description=__doc__.split("\n\n")[0])
    parser.add_argument("agents", nargs="+", help="agent folders (written by ehas train)")
    parser.add_argument("--classical-csv", required=True, help="long_test.csv of ehas bench --long-test")
    parser.add_argument("--out", default="results/long_test/learned", help="output folder")
    parser.add_argument("--cycles", type=number("--cycles", "reference cycles", 7, 1000, integer=True),
                        default=DEFAULT_CYCLES, help="reference cycles per run (default 30, as ehas bench --long-test)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    args = parser.parse_args(argv)
    command = "python -m ehas_train.long_test " + " ".join(sys.argv[1:] if argv is None else argv)
    try:
        res = run(args.agents, args.classical_csv, args.out, cycles=int(args.cycles), command=command,
                  progress=not args.no_progress)
    except (ValueError, FileNotFoundError) as exc:
        print(f"python -m ehas_train.long_test: {exc}", file=sys.stderr)
        return 2
    for name, s in res["summary"].items():
        print(f"{name:30s} mean steady rms {s['mean_steady_rms_pct']:.4f} %, better than {res['best_classical']} on "
              f"{s['wins']} of 63 conditions")
    print(f"best classical {res['best_classical']}: {res['classical_mean'][res['best_classical']]:.4f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
