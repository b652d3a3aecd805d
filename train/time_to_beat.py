"""Time to beat classical: training wall time until a learned controller beats the best classical one.

The benchmark: train a configuration and, every ``--probe-every`` seconds of
training, evaluate the deterministic policy on the benchmark's 63 conditions
(:func:`ehas_train.evaluate.evaluate_policy`, the evaluation of
``results/learned``); the **time to beat classical** is the training wall time
(probes excluded, validation and checkpoints included) at the first probe whose
63-condition mean rms % error is below the best classical controller's.

The best classical controller is computed, not copied: every classical
controller JSON under ``results/controllers`` is run on the 63 conditions by
the benchmark (``ehas_controllers.benchmark.evaluate_controller``, the figures
of ``results/benchmark.md``); the best one is also run through the learned
agents' evaluation path (residual with zero action); the threshold is the lower
of its two means, so that a learned controller must beat both.

Command line (writes ``OUT/time_to_beat.md``, ``time_to_beat.json``, one
``probes_<name>.csv`` per configuration and the trained agents under ``OUT/runs``)::

    python -m ehas_train.time_to_beat train/configs/residual_sac_fast.toml --out results/time_to_beat

The machine is shared: the load average at the start and the end is recorded.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from .evaluate import WORSE_TOL



def classical_candidates(folder="results/controllers") -> list[Path]:
    """Classical controller JSONs (gains or a schedule) under ``folder``."""
    out = []
    for p in sorted(Path(folder).rglob("*.json")):
        try:
            d = json.loads(p.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(d, dict) and d.get("kind", "classical") == "classical" and ("gains" in d or "entries" in d):
            out.append(p)
    return out


def best_classical(folder="results/controllers") -> dict:
    """The best classical controller on the 63 conditions, by the benchmark and through the agents' path.

    Returns ``{"source", "name", "benchmark_mean", "env_path_mean", "threshold", "rows", "candidates"}``
    (``rows``: its per-condition rows through the agents' evaluation path).
    """
    from ehas_controllers.base import load_controller
    from ehas_controllers.batch_sim import grid
    from ehas_controllers.benchmark import evaluate_controller

    from .config import parse_config
    from .evaluate import evaluate_policy, grid_conditions

    cands = []
    for p in classical_candidates(folder):
        ctrl = load_controller(p)
        rows = evaluate_controller(ctrl, grid())
        cands.append({"source": str(p), "name": getattr(ctrl, "name", p.stem),
                      "mean_rms_error_pct": float(np.mean([r["rms_error_pct"] for r in rows]))})
    if not cands:
        raise FileNotFoundError(f"no classical controller JSON under {folder}: run `ehas tune` first")
    best = min(cands, key=lambda c: c["mean_rms_error_pct"])
    desc = {"source": best["source"], "data": json.loads(Path(best["source"]).read_text())}
    cfg = parse_config({"train": {"algo": "sac"}, "env": {"residual": True}})
    rows = evaluate_policy(cfg, lambda o: np.zeros((len(o), 1), np.float32), grid_conditions(), controller_desc=desc)
    env_mean = float(np.mean([r["rms_error_pct"] for r in rows]))
    return {"source": best["source"], "name": best["name"], "benchmark_mean": best["mean_rms_error_pct"],
            "env_path_mean": env_mean, "threshold": min(env_mean, best["mean_rms_error_pct"]), "rows": rows,
            "candidates": cands}


def compare(rows: list[dict], ref_rows: list[dict], tol: float = WORSE_TOL) -> dict:
    """Mean, worst excess over the reference and the count of conditions worse by more than ``tol`` points."""
    a = np.array([r["rms_error_pct"] for r in rows])
    b = np.array([r["rms_error_pct"] for r in ref_rows])
    d = a - b
    return {"mean_rms_error_pct": float(a.mean()), "ref_mean_rms_error_pct": float(b.mean()),
            "worse_count": int((d > tol).sum()), "max_excess_points": float(d.max()),
            "stroke_end_hits": int(sum(bool(r["hit_stroke_end"]) for r in rows))}


def _probe_callback(cfg, controller_desc, best: dict, every_s: float, stop_when_beaten: bool, log_rows: list,
                    state: dict):
    from stable_baselines3.common.callbacks import BaseCallback

    from .evaluate import evaluate_policy, grid_conditions

    grid = grid_conditions()

    class Probe(BaseCallback):
        def _on_training_start(self) -> None:
            state["start"] = time.time()
            state["probe_s"] = 0.0
            state["next"] = every_s

        def train_time(self) -> float:
            return time.time() - state["start"] - state["probe_s"]

        def probe(self) -> dict:
            t_train = self.train_time()
            t0 = time.time()
            vn = self.model.get_vec_normalize_env()

            def policy(obs):
                o = vn.normalize_obs(obs) if vn is not None else obs
                return self.model.predict(o, deterministic=True)[0]

            rows = evaluate_policy(cfg, policy, grid, controller_desc=controller_desc)
            c = compare(rows, best["rows"])
            row = {"train_time_s": round(t_train, 2), "timesteps": int(self.num_timesteps), **c,
                   "beaten": c["mean_rms_error_pct"] < best["threshold"]}
            state["probe_s"] += time.time() - t0
            log_rows.append(row)
            if row["beaten"] and state.get("beaten") is None:
                state["beaten"] = row
            print(f"  probe at {t_train:6.1f} s, {self.num_timesteps} steps: mean rms {c['mean_rms_error_pct']:.4f} % "
                  f"(threshold {best['threshold']:.4f} %), worse on {c['worse_count']} conditions", file=sys.stderr)
            try:
                self.logger.record("ehas/grid_mean_rms_error_pct", c["mean_rms_error_pct"])
                self.logger.record("ehas/best_classical_mean_rms_error_pct", best["threshold"])
            except Exception:  # noqa: BLE001 - logging is optional
                pass
            return row

        def _on_step(self) -> bool:
            if self.train_time() >= state["next"]:
                state["next"] = self.train_time() + every_s
                row = self.probe()
                if row["beaten"] and stop_when_beaten:
                    return False
            return True

        def _on_training_end(self) -> None:
            if not log_rows or log_rows[-1]["timesteps"] != int(self.num_timesteps):
                self.probe()

    return Probe()


def run_one(config_path, out: Path, best: dict, *, budget_min: float, probe_every_s: float,
            stop_when_beaten: bool, seed: int | None = None, command: str | None = None) -> dict:
    """Train one configuration with grid probes; returns its summary."""
    from . import envs as E
    from .config import load_config
    from .trainer import train

    cfg = load_config(config_path)
    if seed is not None:
        cfg = cfg.replace(seed=seed)
    name = Path(config_path).stem + ("" if seed is None else f"_seed{seed}")
    desc = E.resolve_controller_spec(cfg.controller) if cfg.residual else None
    log_rows: list[dict] = []
    state: dict = {}
    cb = _probe_callback(cfg, desc, best, probe_every_s, stop_when_beaten, log_rows, state)
    run_dir = out / "runs" / name
    if run_dir.exists():
        import shutil

        shutil.rmtree(run_dir)
    t0 = time.time()
    metrics = train(cfg, run_dir, progress=False, tensorboard=True, keep_checkpoints=False, callbacks=[cb],
                    max_minutes=budget_min + 1.0, command=command or f"python -m ehas_train.time_to_beat {config_path}")
    wall = time.time() - t0
    buf = io.StringIO()
    cols = ("train_time_s", "timesteps", "mean_rms_error_pct", "ref_mean_rms_error_pct", "worse_count",
            "max_excess_points", "stroke_end_hits", "beaten")
    w = csv.writer(buf)
    w.writerow(cols)
    for r in log_rows:
        w.writerow([r[c] if not isinstance(r[c], float) else f"{r[c]:.6g}" for c in cols])
    from ehas_env.output.files import atomic_write_text

    atomic_write_text(out / f"probes_{name}.csv", buf.getvalue())
    beaten = state.get("beaten")
    best_probe = min(log_rows, key=lambda r: r["mean_rms_error_pct"]) if log_rows else None
    return {"name": name, "config": str(config_path), "algo": cfg.algo, "residual": cfg.residual,
            "n_envs": cfg.n_envs, "vec_env": cfg.vec_env, "action_repeat": cfg.action_repeat,
            "seed": cfg.seed, "time_to_beat_s": None if beaten is None else beaten["train_time_s"],
            "steps_to_beat": None if beaten is None else beaten["timesteps"], "beaten_probe": beaten,
            "best_probe": best_probe, "probes": len(log_rows), "probe_overhead_s": round(state.get("probe_s", 0.0), 1),
            "process_wall_s": round(wall, 1), "trained_steps": metrics["num_timesteps"],
            "selected_by_validation": metrics.get("selected_by_validation"), "run": str(run_dir)}


def _load() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def render_md(rep: dict) -> str:
    b = rep["best_classical"]
    several = len({r.get("command", rep["command"]) for r in rep["runs"]}) > 1
    regen = ("Regenerate each row with its command (listed under the table; `--append` adds or replaces that row)"
             if several else f"Regenerate with `{rep['command']}`")
    gen = sorted({r.get("generated", rep["generated"]) for r in rep["runs"]} | {rep["generated"]})
    L = ["# Time to beat classical", "",
         f"{regen} (writes this file, `time_to_beat.json`, `probes_<config>.csv` and the trained agents under "
         "`runs/`).", "",
         f"Measured {gen[0]}{'' if len(gen) == 1 else ' to ' + gen[-1]} on {rep['machine']} ({os.cpu_count()} cores), "
         "torch threads 1. Each row gives the load average (1, 5, 15 min) at the start and the end of its run: the "
         "machine is shared, and a load above the core count means other processes took part of it during the run "
         "(timings are then pessimistic).", "",
         "**Time to beat classical**: training wall time (set-up, rollouts, gradient steps, validation and "
         "checkpoints; the grid probes themselves excluded) until the deterministic policy's mean rms % error over "
         "the benchmark's 63 conditions (through `ehas_train.evaluate.evaluate_policy`, 5 reference periods each) "
         "is below the best classical controller's.  Probes every `probe` seconds of training (per row), so the figure "
         "is an upper bound within one probe interval.", "",
         f"Best classical controller (computed over {len(b['candidates'])} controller files under "
         f"`results/controllers`): **{b['name']}** (`{b['source']}`): mean rms {b['benchmark_mean']:.4f} % by the "
         f"benchmark, {b['env_path_mean']:.4f} % through the agents' evaluation path; threshold "
         f"**{b['threshold']:.4f} %** (the lower).", "",
         "| config | algo | envs (vec env) | action repeat | time to beat classical | agent steps then | mean rms % then | "
         "conditions worse by > 0.05 then | best probe: mean rms % (worse count) | budget | probe | load average at start / end |",
         "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in rep["runs"]:
        bp = r["beaten_probe"]
        best = r["best_probe"]
        ttb = "not within the budget" if bp is None else f"**{r['time_to_beat_s'] / 60:.2f} min** ({r['time_to_beat_s']:.0f} s)"
        L.append(f"| `{r['config']}` | {r['algo'].upper()}{' residual' if r['residual'] else ''} | {r['n_envs']} "
                 f"({r['vec_env']}) | {r['action_repeat']} | {ttb} | {'-' if bp is None else bp['timesteps']} | "
                 f"{'-' if bp is None else format(bp['mean_rms_error_pct'], '.4f')} | "
                 f"{'-' if bp is None else bp['worse_count']} | "
                 f"{'-' if best is None else format(best['mean_rms_error_pct'], '.4f')} "
                 f"({'-' if best is None else best['worse_count']}) | {r.get('budget_min', rep['budget_min']):g} min"
                 f"{'' if r.get('stop_when_beaten', True) else ' (kept training)'} | "
                 f"{r.get('probe_every_s', rep['probe_every_s']):g} s | "
                 f"{r.get('load_start', rep['load_start'])} / {r.get('load_end', rep['load_end'])} |")
    L += ["", "Each row's command (rows may come from separate runs, `--append`):", ""]
    L += [f"- `{r['name']}`: `{r.get('command', rep['command'])}`" for r in rep["runs"]]
    L += ["", "Per-probe figures: `probes_<config>.csv` (training time, steps, mean rms %, conditions worse than the "
          "best classical by more than 0.05 points, largest excess).", ""]
    if rep.get("notes"):
        L += ["## Notes", ""] + [f"- {n}" for n in rep["notes"]] + [""]
    return "\n".join(L)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m ehas_train.time_to_beat", description=__doc__.splitlines()[0])
    p.add_argument("configs", nargs="+", help="training configurations (TOML)")
    p.add_argument("--out", default="results/time_to_beat")
    p.add_argument("--budget-min", type=float, default=10.0, help="training budget per configuration, minutes")
    p.add_argument("--probe-every", type=float, default=30.0, help="seconds of training between grid probes")
    p.add_argument("--keep-training", action="store_true",
                   help="train to the budget (or total_steps) instead of stopping at the first probe that beats")
    p.add_argument("--seed", type=int, default=None, help="override [train] seed")
    p.add_argument("--controllers", default="results/controllers", help="folder of classical controller JSONs")
    p.add_argument("--note", action="append", default=[], help="a note for the report (repeatable)")
    p.add_argument("--append", action="store_true",
                   help="add the runs to OUT/time_to_beat.json (replacing runs of the same config) instead of "
                        "starting a new report; each row keeps the command and the machine load of its own run")
    a = p.parse_args(argv)
    import logging
    import platform

    from ehas_env.output.files import atomic_write_text

    logging.basicConfig(level=logging.WARNING)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    argv = sys.argv[1:] if argv is None else list(argv)
    command = " ".join(["python -m ehas_train.time_to_beat"] + [shlex.quote(x) for x in argv])
    load_start = _load()
    best = best_classical(a.controllers)
    print(f"best classical: {best['name']} ({best['source']}): benchmark {best['benchmark_mean']:.4f} %, "
          f"agents' path {best['env_path_mean']:.4f} %", file=sys.stderr)
    from datetime import datetime, timezone

    runs = []
    for c in a.configs:
        t_load = _load()
        runs.append(run_one(c, out, best, budget_min=a.budget_min, probe_every_s=a.probe_every,
                            stop_when_beaten=not a.keep_training, seed=a.seed, command=command))
        r = runs[-1]
        r.update(command=command, load_start=t_load, load_end=_load(), budget_min=a.budget_min,
                 stop_when_beaten=not a.keep_training, probe_every_s=a.probe_every,
                 generated=datetime.now(timezone.utc).isoformat(timespec="seconds"))
        print(f"{r['name']}: time to beat classical "
              f"{'-' if r['time_to_beat_s'] is None else format(r['time_to_beat_s'], '.0f') + ' s'}", file=sys.stderr)
    from datetime import datetime, timezone

    if a.append and (out / "time_to_beat.json").exists():
        earlier = json.loads((out / "time_to_beat.json").read_text())
        names = {r["name"] for r in runs}
        runs = [r for r in earlier.get("runs", []) if r["name"] not in names] + runs
        a.note = list(dict.fromkeys(earlier.get("notes", []) + a.note))
    rep = {"command": command, "generated": datetime.now(timezone.utc).isoformat(timespec="seconds"),
           "machine": platform.processor() or platform.machine(), "cores": os.cpu_count(),
           "load_start": load_start, "load_end": _load(), "budget_min": a.budget_min, "probe_every_s": a.probe_every,
           "best_classical": {k: v for k, v in best.items() if k != "rows"}, "runs": runs, "notes": a.note}
    atomic_write_text(out / "time_to_beat.json", json.dumps(rep, indent=2, default=str) + "\n")
    atomic_write_text(out / "time_to_beat.md", render_md(rep))
    print(f"wrote {out / 'time_to_beat.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
