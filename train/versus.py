"""A learned agent against the best classical controller: every condition, and the robustness table.

Writes into the agent's folder (or ``--out``):

* ``vs_classical.md``: the 63-condition table (agent, best classical, difference),
  the count of conditions where the agent is worse by more than 0.05 points, and
  the robustness table: each effect of the library at its typical value
  (``ehas_controllers.benchmark.typical_effects``), agent and best classical
  on the 63 conditions, mean / worst rms % error;
* ``vs_classical.json``: the same numbers.

Both controllers run through the learned agents' evaluation path
(:func:`ehas_train.evaluate.evaluate_policy`: the classical one as a residual
base with zero action), so the comparison is like with like; the best classical
controller is computed by :func:`ehas_train.time_to_beat.best_classical`.

Command line::

    python -m ehas_train.versus results/agents/residual_sac_load
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .time_to_beat import WORSE_TOL, best_classical, compare


def _with_effects(cfg, effects: dict | None):
    from .config import parse_config

    raw = cfg.to_file_dict()
    kw = dict(raw["env"]["kwargs"])
    if effects:
        kw["effects"] = effects
    else:
        kw.pop("effects", None)
    raw["env"]["kwargs"] = kw
    raw["randomise"] = {}
    return parse_config(raw, source=cfg.source)


def evaluate_versus(agent_path, *, controllers="results/controllers", robustness: bool = True,
                    progress: bool = True) -> dict:
    from ehas_controllers.benchmark import typical_effects

    from .agent import load_agent
    from .config import parse_config
    from .evaluate import evaluate_policy, grid_conditions

    agent = load_agent(agent_path, warn=False)
    best = best_classical(controllers)
    desc = {"source": best["source"], "data": json.loads(Path(best["source"]).read_text())}
    grid = grid_conditions()
    rows = evaluate_policy(agent.cfg, agent.predict, grid, controller_desc=agent.controller_desc)
    base_cfg = parse_config({"train": {"algo": "sac"}, "env": {"residual": True}})
    zero = lambda o: np.zeros((len(o), 1), np.float32)  # noqa: E731
    out = {"agent": str(agent_path), "best_classical": {k: v for k, v in best.items() if k != "rows"},
           "tolerance_points": WORSE_TOL, "nominal": compare(rows, best["rows"]),
           "conditions": [{"disc_sets": r["disc_sets"], "freq_hz": r["freq_hz"], "amplitude_deg": r["amplitude_deg"],
                           "agent_rms_error_pct": r["rms_error_pct"], "classical_rms_error_pct": b["rms_error_pct"],
                           "agent_hit_stroke_end": bool(r["hit_stroke_end"]),
                           "classical_hit_stroke_end": bool(b["hit_stroke_end"])}
                          for r, b in zip(rows, best["rows"])], "robustness": []}
    if robustness:
        for name, params in typical_effects().items():
            if progress:
                print(f"  robustness: {name}", file=sys.stderr)
            eff = {name: params}
            ar = evaluate_policy(_with_effects(agent.cfg, eff), agent.predict, grid,
                                 controller_desc=agent.controller_desc)
            br = evaluate_policy(_with_effects(base_cfg, eff), zero, grid, controller_desc=desc)
            c = compare(ar, br)
            out["robustness"].append({"effect": name, "params": params, **c,
                                      "agent_worst": float(max(r["rms_error_pct"] for r in ar)),
                                      "classical_worst": float(max(r["rms_error_pct"] for r in br)),
                                      "classical_stroke_end_hits": int(sum(bool(r["hit_stroke_end"]) for r in br))})
    return out


def render_md(rep: dict, command: str) -> str:
    from ehas_controllers.benchmark import AMPLITUDES, DISC_SETS, FREQS

    b = rep["best_classical"]
    n = rep["nominal"]
    L = [f"# {Path(rep['agent']).name} against the best classical controller", "",
         f"Regenerate with `{command}`.", "",
         f"Best classical controller (the lowest 63-condition mean rms % error of the controller files under "
         f"`results/controllers`): **{b['name']}** (`{b['source']}`, mean {b['benchmark_mean']:.4f} %). Both run "
         "through the learned agents' evaluation path (`ehas_train.evaluate.evaluate_policy`: 5 reference periods "
         "from rest, rms_error_pct = 100 RMS(theta_ref - theta)/amplitude over whole cycles after the first; the "
         "classical controller as a residual base with zero action).", "",
         f"**Nominal plant: mean rms {n['mean_rms_error_pct']:.4f} % vs {n['ref_mean_rms_error_pct']:.4f} %; "
         f"worse by more than {rep['tolerance_points']:g} points on {n['worse_count']} of 63 conditions; largest "
         f"excess {n['max_excess_points']:+.4f} points; stroke-end hits {n['stroke_end_hits']}.**", "",
         "## Per condition (rms % error: agent / best classical, difference in points)", ""]
    cols = [(f, a) for f in FREQS for a in AMPLITUDES]
    by = {(c["disc_sets"], c["freq_hz"], c["amplitude_deg"]): c for c in rep["conditions"]}
    L.append("| disc sets | " + " | ".join(f"{f:g} Hz {a:g}°" for f, a in cols) + " |")
    L.append("|---|" + "---:|" * len(cols))
    for ds in DISC_SETS:
        cells = []
        for f, a in cols:
            c = by[(ds, f, a)]
            d = c["agent_rms_error_pct"] - c["classical_rms_error_pct"]
            mark = " **worse**" if d > rep["tolerance_points"] else ""
            cells.append(f"{c['agent_rms_error_pct']:.3f} / {c['classical_rms_error_pct']:.3f} ({d:+.3f}){mark}")
        L.append(f"| {ds} | " + " | ".join(cells) + " |")
    if rep["robustness"]:
        L += ["", "## Robustness: one effect switched on at its typical value", "",
              "Each effect of the library at the middle of each parameter's `typical` range "
              "(`ehas_controllers.benchmark.typical_effects`, as in `results/benchmark.md`), all 63 conditions.", "",
              "| effect (parameters) | agent mean / worst rms % | best classical mean / worst rms % | agent ahead on the "
              "mean | conditions worse by > 0.05 | agent stroke-end hits | classical stroke-end hits |",
              "|---|---:|---:|---|---:|---:|---:|"]
        ahead = 0
        for r in rep["robustness"]:
            ps = ", ".join(f"{k}={v:.4g}" for k, v in r["params"].items())
            win = r["mean_rms_error_pct"] < r["ref_mean_rms_error_pct"]
            ahead += win
            L.append(f"| {r['effect']} ({ps}) | {r['mean_rms_error_pct']:.3f} / {r['agent_worst']:.3g} | "
                     f"{r['ref_mean_rms_error_pct']:.3f} / {r['classical_worst']:.3g} | {'yes' if win else 'NO'} | "
                     f"{r['worse_count']} | {r['stroke_end_hits']} | {r['classical_stroke_end_hits']} |")
        L += ["", f"Ahead on the mean with {ahead} of {len(rep['robustness'])} effects."]
    L.append("")
    return "\n".join(L)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m ehas_train.versus", description=__doc__.splitlines()[0])
    p.add_argument("agent", help="agent folder")
    p.add_argument("--out", default=None, help="folder for vs_classical.md/.json (default: the agent folder)")
    p.add_argument("--no-robustness", action="store_true")
    p.add_argument("--controllers", default="results/controllers")
    a = p.parse_args(argv)
    import shlex

    from ehas_env.output.files import atomic_write_text

    argv = sys.argv[1:] if argv is None else list(argv)
    command = " ".join(["python -m ehas_train.versus"] + [shlex.quote(x) for x in argv])
    rep = evaluate_versus(a.agent, controllers=a.controllers, robustness=not a.no_robustness)
    rep["command"] = command
    out = Path(a.out or a.agent)
    atomic_write_text(out / "vs_classical.json", json.dumps(rep, indent=2, default=str) + "\n")
    atomic_write_text(out / "vs_classical.md", render_md(rep, command))
    n = rep["nominal"]
    print(f"{a.agent}: mean {n['mean_rms_error_pct']:.4f} % vs {n['ref_mean_rms_error_pct']:.4f} %, worse by > "
          f"{WORSE_TOL} on {n['worse_count']} conditions (largest excess {n['max_excess_points']:+.4f}); wrote "
          f"{out / 'vs_classical.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
