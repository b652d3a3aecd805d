"""Learned controllers on the benchmark's 63 conditions and the book's rig tests, through the environment.

Agents are evaluated in the environment they were trained in
(``ehas/Tracking-v0``), batched: one :class:`ehas_env.env.vector_env.TrackingVectorEnv`
per disc-set count holds that count's conditions (its residual base compiled
in), and the policy acts on all of them in one forward pass.  Each condition
runs from rest for the benchmark's number of reference periods, and the rows
carry the benchmark's columns (``ehas_controllers.benchmark.CSV_COLUMNS``) with
``kind = learned``:

* ``rms_error_pct``, ``peak_error_pct``: the environment's episode metric -
  100 RMS / max (theta_ref - theta) / amplitude over the whole cycles after the
  first, as ``ehas_env.simulation.metrics`` and the benchmark define it;
* ``max_current_mA``, ``saturation_frac`` (share of periods at +-20 mA),
  ``peak_delta_p_bar`` (|P_A - P_B|) and ``hit_stroke_end`` over the whole run.

The residual agents' base controller is evaluated through the very same path
(zero action), so the table compares like with like; the classical benchmark's
own figures (compiled loop, reference faded in over the warm-up cycle) are
printed beside them.

Command line::

    python -m ehas_train.evaluate results/agents/* --out results/learned
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from ehas_controllers.batch_sim import DEFAULT_CYCLES, METRICS
from ehas_controllers.benchmark import AMPLITUDES, CSV_COLUMNS, DISC_SETS, FREQS  # noqa: F401
from ehas_controllers.benchmark import rows_csv as benchmark_rows_csv

from ehas_env.output.files import read_json

from . import envs as E

I_MAX = 20.0  # mA, servo amplifier (docs/rig.md)
DESIGN_POINT = (7, 3.0, 30.0)  # disc sets, Hz, deg: the rig's design point (docs/rig.md)
#: what an agent folder's metrics.json is, for the errors of the file reader
METRICS_FILE = "the metrics written by ehas train (metrics.json)"
WORSE_TOL = 0.05  # points of rms % error: a learned controller counts as worse than a classical one beyond this
#: where the learned-vs-classical standing is published from now on (the long test, docs/learning-control.md)
LONG_TEST_NOTE = ("These are 4-cycle figures against fixed-gain classical controllers. The standing of learned against "
                  "classical controllers is the long test's (30 cycles from rest, the controllers that learn the cycle "
                  "included): `results/long_test/learned/learned_long_test.md` (`python -m ehas_train.long_test`).")


def grid_conditions() -> list[tuple[int, float, float]]:
    """(disc sets, Hz, deg) of the benchmark's 63 conditions, in its order (sets, then frequency, then amplitude)."""
    return [(n, f, a) for n in DISC_SETS for f in FREQS for a in AMPLITUDES]


def book_conditions() -> list[tuple[tuple[int, float, float], float]]:
    """The book's 7 rig tests: ((disc sets, Hz, deg), the book's % pos error)."""
    from ehas_env.book.tables import rig_tests

    return [((int(r.disc_sets), float(r.freq_hz), float(r.amplitude_deg)), float(r.pos_error_percent))
            for r in rig_tests()]


# -- batched evaluation through the environment ----------------------------------
def evaluate_policy(cfg, policy, conditions, *, controller_desc=None, cycles: float = DEFAULT_CYCLES,
                    progress: bool = False, long_test: int | None = None) -> list[dict]:
    """Metrics of ``policy`` on ``conditions`` in ``cfg``'s environment (batched per disc-set count).

    Parameters
    ----------
    cfg : TrainConfig
        Environment settings of the agent (keyword arguments, action hold and
        scale, residual base) - randomisation is off: each row is one condition.
    policy : callable
        ``obs (n, n_obs) -> actions (n, 1)`` in the agent's units [-1, 1]; for
        the base controller alone, ``lambda obs: zeros``.
    conditions : list of (disc_sets, freq_hz, amplitude_deg)
    controller_desc : dict, optional
        The residual base (the agent's resolved ``[env] controller``).
    cycles : float
        Reference periods per run.
    progress : bool
        Show a progress bar over the disc-set groups.
    long_test : int, optional
        Run the long-test protocol instead: ``long_test`` whole reference cycles from rest, each
        row adding the figures of :func:`ehas_env.simulation.long_test.long_test_metrics`
        (``steady_rms_pct`` over the last five cycles, ``settle_cycles``, ``worst_cycle_pct``, ...)
        computed from the environment's error at every step.

    Returns
    -------
    list of dict
        One row per condition, in the order given, with :data:`METRICS`.
    """
    from ehas_env.env.vector_env import TrackingVectorEnv
    from ehas_env.simulation.control_laws import compiled_form

    E.register_ehas()
    kw = {k: v for k, v in cfg.env_kwargs.items() if k not in ("disc_sets", "amplitude_deg", "freq_hz", "randomise")}
    if long_test is not None:  # N whole cycles: a hundredth of a period more (>= 3 samples at 1 kHz, 3 Hz)
        cycles = float(long_test) + 0.01
    kw.update(cycles=cycles)
    base = E.classical_controller(controller_desc) if cfg.residual else None
    scale = cfg.action_scale_mA / E.RATED_CURRENT_MA
    rows: dict[tuple, dict] = {}
    groups: dict[int, list] = {}
    for c in conditions:
        groups.setdefault(int(c[0]), []).append(c)
    from tqdm.auto import tqdm

    for n, conds in tqdm(sorted(groups.items()), desc="disc sets", disable=not progress, leave=False):
        rig = None
        if base is not None:
            rig = compiled_form(base, n)
            if rig is None:  # never score a residual agent without its base
                raise ValueError(f"the residual base controller {getattr(base, 'name', type(base).__name__)!r} has "
                                 "no compiled law; the batched evaluation needs one (ehas_controllers.base."
                                 "CompiledController)")
        venv = TrackingVectorEnv(len(conds), controller=rig, disc_sets=n, **kw)
        m = len(conds)
        obs = np.zeros((m, venv.single_observation_space.shape[0]), np.float32)
        last0 = {key: np.zeros(m) for key in ("theta_ref_dot", "p_a_bar", "p_b_bar")}
        for i, (_, f, a) in enumerate(conds):
            mask = np.zeros(m, bool)
            mask[i] = True
            o, inf = venv.reset(seed=i, options={"freq_hz": f, "amplitude_deg": a, "reset_mask": mask})
            obs[i] = o[i]
            for key in last0:
                last0[key][i] = inf[key][i]
        live = np.ones(m, bool)
        stats = {"imax": np.zeros(m), "nsat": np.zeros(m), "nstep": np.zeros(m), "dp": np.zeros(m)}
        final = [None] * m
        k = 0
        action = np.zeros((m, 1), np.float32)
        last = last0
        trace = []  # (t, theta_ref - theta) of every step, for the long test
        while live.any():
            if k % cfg.action_repeat == 0:
                action = np.clip(np.asarray(policy(obs), np.float32).reshape(m, 1), -1.0, 1.0) * np.float32(scale)
            applied = action
            if cfg.action_shape != "constant":
                applied = action * np.asarray(E.authority(cfg.action_shape, last, n), np.float32)[:, None]
            obs, _, term, trunc, info = venv.step(applied)
            last = info
            if long_test is not None:
                trace.append((np.array(info["t"], dtype=float),  # the metric's error: on the physical angle
                              np.asarray(info["theta_ref_deg"], dtype=float) - np.asarray(info["theta_deg"], dtype=float)))
            cur = np.abs(info["current_mA"])
            dp = np.abs(info["p_a_bar"] - info["p_b_bar"])
            idx = np.flatnonzero(live)
            stats["imax"][idx] = np.maximum(stats["imax"][idx], cur[idx])
            stats["nsat"][idx] += cur[idx] >= I_MAX * (1.0 - 1e-9)
            stats["nstep"][idx] += 1
            stats["dp"][idx] = np.maximum(stats["dp"][idx], dp[idx])
            for i in np.flatnonzero(live & (term | trunc)):
                final[i] = {"rms_error_pct": float(info["rms_error_pct"][i]),
                            "peak_error_pct": float(info["peak_error_pct"][i]),
                            "metric_complete": bool(info["metric_complete"][i]), "hit_stroke_end": bool(term[i])}
                live[i] = False
            k += 1
        venv.close()
        if long_test is not None:
            from ehas_env.simulation.long_test import long_test_metrics

            ts = np.array([tr[0] for tr in trace])
            es = np.array([tr[1] for tr in trace])
            for i, (_, f, a) in enumerate(conds):
                steps = int(stats["nstep"][i])
                t_i, e_i = ts[:steps, i], es[:steps, i]
                try:
                    final[i].update(long_test_metrics(t_i, e_i, np.zeros_like(e_i), a, f))
                except ValueError:  # ended early (stroke end): scored by what it ran, never settled
                    r_i = final[i]["rms_error_pct"]
                    final[i].update({"cycles": int(t_i[-1] * f), "cycle_rms_pct": [], "steady_rms_pct": r_i,
                                     "steady_peak_pct": final[i]["peak_error_pct"], "settle_cycles": long_test + 1,
                                     "worst_cycle_pct": r_i, "worst_cycle": 0})
        for i, (_, f, a) in enumerate(conds):
            # the start (t = 0, at rest, P_A = P_B) carries no current and no load difference
            rows[(n, f, a)] = {"disc_sets": n, "freq_hz": f, "amplitude_deg": a, **final[i],
                               "max_current_mA": float(stats["imax"][i]),
                               "saturation_frac": float(stats["nsat"][i] / max(stats["nstep"][i], 1)),
                               "peak_delta_p_bar": float(stats["dp"][i])}
    return [rows[(int(c[0]), c[1], c[2])] for c in conditions]


def evaluate_agent(agent, conditions=None, *, cycles: float = DEFAULT_CYCLES, progress: bool = False) -> list[dict]:
    """The agent's rows on ``conditions`` (default: the 63-condition grid)."""
    conditions = grid_conditions() if conditions is None else conditions
    return evaluate_policy(agent.cfg, agent.predict, conditions, controller_desc=agent.controller_desc, cycles=cycles,
                           progress=progress)


def evaluate_base(agent, conditions=None, *, cycles: float = DEFAULT_CYCLES) -> list[dict]:
    """The residual agent's base controller alone (zero action) through the same path."""
    conditions = grid_conditions() if conditions is None else conditions
    return evaluate_policy(agent.cfg, lambda obs: np.zeros((len(obs), 1), np.float32), conditions,
                           controller_desc=agent.controller_desc, cycles=cycles)


def summary(rows: list[dict]) -> dict:
    """Mean and worst rms % error, the design point, stroke-end hits of a grid's rows."""
    rms = np.array([r["rms_error_pct"] for r in rows])
    out = {"mean_rms_error_pct": float(rms.mean()), "worst_rms_error_pct": float(rms.max()),
           "stroke_end_hits": int(sum(bool(r["hit_stroke_end"]) for r in rows))}
    for r in rows:
        if (r["disc_sets"], r["freq_hz"], r["amplitude_deg"]) == DESIGN_POINT:
            out["rms_30deg_3hz_7sets"] = r["rms_error_pct"]
    return out


# -- files ---------------------------------------------------------------------------
def rows_csv(named_rows: list[tuple[str, str, str, list[dict]]], command: str) -> str:
    """Benchmark-format CSV of (name, kind, variant, rows) blocks."""
    return benchmark_rows_csv(named_rows, f"learned vs classical controllers through ehas/Tracking-v0, "
                                          f"regenerate with: {command}")


def _grid_md(rows) -> list[str]:
    cols = [(f, a) for f in FREQS for a in AMPLITUDES]
    by = {(r["disc_sets"], r["freq_hz"], r["amplitude_deg"]): r for r in rows}
    lines = ["| disc sets | " + " | ".join(f"{f:g} Hz {a:g}°" for f, a in cols) + " |", "|---|" + "---:|" * len(cols)]
    for n in DISC_SETS:
        cells = []
        for f, a in cols:
            r = by.get((n, f, a))
            cells.append("" if r is None else f"{r['rms_error_pct']:.3g}" + (" S" if r["hit_stroke_end"] else ""))
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return lines


def run(agent_paths, out_dir, *, classical=None, cycles: float = DEFAULT_CYCLES, command: str = "",
        progress: bool = True, curves_dir=None, readmes: bool = False) -> dict:
    """Evaluate agents (and, for comparison, classical controllers) and write the results.

    Writes ``learned_benchmark.csv`` (benchmark columns, ``kind = learned`` for
    agents), ``learned_benchmark.md`` (summary, where the learned controllers
    lose, per-condition tables), ``learned_summary.json``, and copies each
    agent's learning curve into ``curves_dir`` (default
    ``results/learning_curves``).
    """
    from ehas_env.output.files import atomic_write_bytes, atomic_write_text

    from .agent import load_agent

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    grid = grid_conditions()
    blocks, summaries, timings = [], {}, {}
    bases_done = set()
    agents = []
    from ehas_controllers.base import LOAD_OPTIONS

    for p in agent_paths:
        agent = load_agent(p, allow_pickle=LOAD_OPTIONS["allow_pickle"])
        agents.append(agent)
        t0 = time.perf_counter()
        rows = evaluate_agent(agent, grid, cycles=cycles, progress=progress)
        timings[agent.name] = time.perf_counter() - t0
        blocks.append((agent.name, "learned", agent.variant, rows))
        summaries[agent.name] = {"kind": "learned", "variant": agent.variant, **summary(rows), **_train_info(p)}
        if agent.cfg.residual:
            src = (agent.controller_desc or {}).get("source", "book")
            key = json.dumps(agent.controller_desc, sort_keys=True, default=str)
            if key not in bases_done:
                bases_done.add(key)
                name = f"base of residual: {Path(src).stem if src.endswith('.json') else src}"
                brows = evaluate_base(agent, grid, cycles=cycles)
                blocks.append((name, "classical", "residual base, zero action", brows))
                summaries[name] = {"kind": "classical", "variant": "residual base, zero action", **summary(brows),
                                   "source": src}
    for ctrl in classical or []:
        from .config import parse_config

        cfg = parse_config({"train": {"algo": "sac"}, "env": {"residual": True}})
        desc = {"source": getattr(ctrl, "source", ctrl.name), "data": ctrl.to_dict()}
        brows = evaluate_policy(cfg, lambda obs: np.zeros((len(obs), 1), np.float32), grid, controller_desc=desc,
                                cycles=cycles)
        blocks.append((ctrl.name, "classical", getattr(ctrl, "variant", ""), brows))
        summaries[ctrl.name] = {"kind": "classical", "variant": getattr(ctrl, "variant", ""), **summary(brows),
                                "source": desc["source"]}
    if readmes:
        base_of = {}
        for name, s in summaries.items():
            if s["kind"] == "classical" and "source" in s:
                base_of[s["source"]] = s
        for p, agent in zip(agent_paths, agents):
            src = (agent.controller_desc or {}).get("source", "book")
            write_agent_readme(p, summaries[agent.name], base_of.get(src) if agent.cfg.residual else None, command)
        write_agents_index(agent_paths, agents, summaries, command, out)
    atomic_write_text(out / "learned_benchmark.csv", rows_csv(blocks, command))
    atomic_write_text(out / "learned_summary.json", json.dumps({"command": command, "cycles": cycles,
                                                               "summary": summaries, "eval_time_s": timings},
                                                              indent=2) + "\n")
    atomic_write_text(out / "learned_benchmark.md", _markdown(blocks, summaries, command, cycles))
    curves = Path(curves_dir) if curves_dir is not None else Path("results/learning_curves")
    for p, agent in zip(agent_paths, agents):
        for ext in ("png", "csv"):
            src = Path(p) / f"learning_curve.{ext}"
            if src.exists():
                atomic_write_bytes(curves / f"{agent.name}.{ext}", src.read_bytes())
    if any((curves / f"{a.name}.png").exists() for a in agents):
        atomic_write_text(curves / "README.md",
                          "# Learning curves\n\nOne per shipped agent (episode return and rms % position error of "
                          "the training episodes, exploration noise included, against environment steps), copied "
                          f"from `results/agents/<name>/` by `{command}`.\nEach agent's README gives the command "
                          "that retrains it (and so regenerates its curve).\n")
    return summaries


def write_agent_readme(path, summary_row: dict, base_row: dict | None, eval_command: str) -> Path:
    """README.md of a shipped agent folder: what it is, the command that retrains it, its training time, its figures."""
    from ehas_env.output.files import atomic_write_text

    from .agent import load_agent

    path = Path(path)
    metrics = read_json(path / "metrics.json", METRICS_FILE) if (path / "metrics.json").exists() else {}
    from ehas_controllers.base import LOAD_OPTIONS

    agent = load_agent(path, warn=False, allow_pickle=LOAD_OPTIONS["allow_pickle"])
    cfg = agent.cfg
    cmd = metrics.get("command") or f"ehas train --algo {cfg.algo}{' --residual' if cfg.residual else ''} --config {cfg.source} --out {path}"
    tt = metrics.get("train_time_s")
    base = ""
    if cfg.residual:
        base = f" on the classical controller `{(agent.controller_desc or {}).get('source', 'book')}`"
    L = [f"# {agent.name}: {agent.variant}{base}", "",
         f"{'Residual' if cfg.residual else 'Direct'} current control of `ehas/Tracking-v0` trained with "
         f"stable-baselines3 {cfg.algo.upper()}: the policy acts every {cfg.action_repeat} ms with "
         f"+-{cfg.action_scale_mA:g} mA" + (" added to its base controller's current" if cfg.residual else "")
         + "; domain randomisation " + (", ".join(f"{k} {v}" for k, v in cfg.randomise.items()) or "none") + ".", "",
         "## Retrain", "", "```bash", cmd, "```", "",
         f"Measured training time on this machine (2 cores, torch {cfg.torch_threads} thread): "
         + (f"**{tt / 60:.1f} min** for {metrics.get('num_timesteps')} agent steps" if tt else "not recorded") + ".", "",
         "## Figures", "", f"Regenerate with `{eval_command}` (`learned_benchmark.md` there). "
         "rms_error_pct = 100 RMS(theta_ref - theta) / amplitude over whole cycles after the first, 63 conditions "
         "(7 disc sets x {1, 2, 3} Hz x {10, 20, 30} deg), 5 reference periods each, through the environment.", "",
         "| controller | mean rms % (63) | worst rms % | rms % at 30°/3 Hz/7 sets |", "|---|---:|---:|---:|",
         f"| {agent.name} | {summary_row['mean_rms_error_pct']:.4f} | {summary_row['worst_rms_error_pct']:.3f} | "
         f"{summary_row.get('rms_30deg_3hz_7sets', float('nan')):.3f} |"]
    if base_row is not None:
        L.append(f"| its base controller alone | {base_row['mean_rms_error_pct']:.4f} | {base_row['worst_rms_error_pct']:.3f} | "
                 f"{base_row.get('rms_30deg_3hz_7sets', float('nan')):.3f} |")
    if (path / "vs_classical.md").exists():
        vs = read_json(path / "vs_classical.json", "the comparison written by ehas train (vs_classical.json)") \
            if (path / "vs_classical.json").exists() else {}
        n = vs.get("nominal", {})
        L += ["", "## Against the best classical controller", "",
              f"[vs_classical.md](vs_classical.md) (`{vs.get('command', 'python -m ehas_train.versus ' + str(path))}`): "
              "every one of the 63 conditions beside the best classical controller, and the robustness table (each "
              "library effect at its typical value)"
              + (f"; worse by more than {vs.get('tolerance_points', 0.05):g} points on **{n['worse_count']}** of 63 "
                 f"conditions (largest excess {n['max_excess_points']:+.3f} points)" if n else "") + "."]
    L += ["", "## Files", "",
          "- `policy.safetensors`: the policy's weights; `policy.json`: its architecture (data only, docs/agents.md);",
          "- `obs_norm.json`: observation normalisation statistics;" if (path / "obs_norm.json").exists() else "",
          "- `config.json`: the resolved training configuration (environment, action hold and scale, base controller);",
          "- `metrics.json`: steps, training time, final evaluation; `learning_curve.csv` / `.png`: training episodes.", "",
          "Loading the agent reads only data (safetensors and JSON): nothing is unpickled.", "",
          "```python", "from ehas_train.agent import load_agent", f"agent = load_agent('{path}')",
          "from ehas_env.simulation.plant import Plant",
          "run = Plant(disc_sets=7).simulate_closed_loop(agent.for_plant(7), amplitude_deg=30, freq_hz=3, cycles=5)",
          "print(run.tracking_errors())", "```", "",
          f"As a controller file: `ehas bench {path}`.", ""]
    return atomic_write_text(path / "README.md", "\n".join(line for line in L if line is not None) + "\n")


def write_agents_index(agent_paths, agents, summaries, command: str, results_dir) -> None:
    """README.md of the folder(s) holding the agents: one line per agent with its command and figures."""
    from ehas_env.output.files import atomic_write_text

    folders = {}
    for p, agent in zip(agent_paths, agents):
        folders.setdefault(Path(p).resolve().parent, []).append((Path(p), agent))
    for folder, items in folders.items():
        L = ["# Shipped learned controllers", "",
             "Each folder holds a trained stable-baselines3 agent (small files) and a README with the exact command "
             "that retrains it and its measured training time on this 2-core machine. Loading an agent reads only data "
             "(safetensors and JSON, docs/agents.md): nothing is unpickled.", "",
             f"Figures: `{command}` -> `{results_dir}/learned_benchmark.md` (63 conditions through "
             "`ehas/Tracking-v0`, rms_error_pct = 100 RMS(theta_ref - theta)/amplitude over whole cycles after the "
             "first).", "",
             "| agent | variant | mean rms % (63) | rms % at 30°/3 Hz/7 sets | training time | retrain |",
             "|---|---|---:|---:|---:|---|"]
        for p, agent in items:
            s = summaries[agent.name]
            m = read_json(p / "metrics.json", METRICS_FILE) if (p / "metrics.json").exists() else {}
            tt = m.get("train_time_s")
            L.append(f"| [{agent.name}]({p.name}/README.md) | {agent.variant} | {s['mean_rms_error_pct']:.4f} | "
                     f"{s.get('rms_30deg_3hz_7sets', float('nan')):.3f} | "
                     f"{'' if tt is None else f'{tt / 60:.1f} min'} | `{m.get('command', '')}` |")
        atomic_write_text(folder / "README.md", "\n".join(L) + "\n")


def _train_info(path) -> dict:
    p = Path(path) / "metrics.json"
    if not p.exists():
        return {}
    m = read_json(p, METRICS_FILE)
    return {"train_time_s": m.get("train_time_s"), "num_timesteps": m.get("num_timesteps")}


def _markdown(blocks, summaries, command, cycles) -> str:
    by_name = {name: rows for name, _, _, rows in blocks}
    classical = [n for n, s in summaries.items() if s["kind"] == "classical"]
    learned = [n for n, s in summaries.items() if s["kind"] == "learned"]
    L = ["# Learned vs classical controllers (ehas/Tracking-v0)", "", f"Regenerate with `{command}`.", "",
         "Every controller runs in the same environment and the same batched path (`ehas_train.evaluate`): "
         f"{cycles:g} reference periods from rest, baseline plant, ideal sensors. Metric: **rms_error_pct** = "
         "100 · RMS(θ_ref − θ) / θ_amp over whole reference cycles after the first (the book never defines its "
         "\"% pos error\"). Classical rows are the residual agents' base controllers with zero action.", "",
         "| controller | kind | variant | mean rms % (63) | worst rms % | rms % at 30°/3 Hz/7 sets | stroke-end hits | "
         "training time |", "|---|---|---|---:|---:|---:|---:|---:|"]
    for name, s in sorted(summaries.items(), key=lambda kv: kv[1]["mean_rms_error_pct"]):
        tt = s.get("train_time_s")
        L.append(f"| {name} | {s['kind']} | {s['variant']} | {s['mean_rms_error_pct']:.4f} | "
                 f"{s['worst_rms_error_pct']:.3f} | {s.get('rms_30deg_3hz_7sets', float('nan')):.3f} | "
                 f"{s['stroke_end_hits']} | {'' if tt is None else f'{tt / 60:.1f} min'} |")
    if classical and learned:
        best_c = min(classical, key=lambda n: summaries[n]["mean_rms_error_pct"])
        best_l = min(learned, key=lambda n: summaries[n]["mean_rms_error_pct"])
        sc, sl = summaries[best_c], summaries[best_l]
        L += ["", f"Best learned **{best_l}**: mean rms {sl['mean_rms_error_pct']:.4f} % vs best classical "
              f"**{best_c}** {sc['mean_rms_error_pct']:.4f} % "
              f"({'beats' if sl['mean_rms_error_pct'] < sc['mean_rms_error_pct'] else 'does NOT beat'} it); "
              f"at 30°/3 Hz/7 sets {sl.get('rms_30deg_3hz_7sets', float('nan')):.3f} % vs "
              f"{sc.get('rms_30deg_3hz_7sets', float('nan')):.3f} % "
              f"({'beats' if sl.get('rms_30deg_3hz_7sets', 1e9) < sc.get('rms_30deg_3hz_7sets', 0) else 'does NOT beat'} it).",
              "", LONG_TEST_NOTE,
              "", "### Where the learned controllers lose", "",
              f"Conditions where each learned controller's rms % error is above the best classical ({best_c}):", ""]
        cref = {(r["disc_sets"], r["freq_hz"], r["amplitude_deg"]): r["rms_error_pct"] for r in by_name[best_c]}
        for name in learned:
            worse = [(r, r["rms_error_pct"] - cref[(r["disc_sets"], r["freq_hz"], r["amplitude_deg"])])
                     for r in by_name[name]]
            lose = sorted([w for w in worse if w[1] > 0], key=lambda w: -w[1])
            desc = ", ".join(f"{r['disc_sets']} sets {r['freq_hz']:g} Hz {r['amplitude_deg']:g}° "
                             f"(+{d:.3g} points)" for r, d in lose[:8])
            L.append(f"- **{name}**: loses on {len(lose)} of {len(worse)} conditions" + (f"; largest: {desc}" if lose else ""))
    for name, _, _, rows in blocks:
        L += ["", f"## {name}", "", "rms_error_pct (S: stroke end touched):", ""]
        L += _grid_md(rows)
    try:
        book = book_conditions()
    except Exception:  # noqa: BLE001 - the book table is optional decoration here
        book = []
    if book:
        L += ["", "## The book's rig tests", "", "| amplitude | f | discs (sets) | book % pos error | "
              + " | ".join(f"{n} rms %" for n, _, _, _ in blocks) + " |", "|---:|---:|---:|---:|" + "---:|" * len(blocks)]
        for (n, f, a), b in book:
            cells = []
            for _, _, _, rows in blocks:
                r = next(r for r in rows if (r["disc_sets"], r["freq_hz"], r["amplitude_deg"]) == (n, f, a))
                cells.append(f"{r['rms_error_pct']:.3f}")
            L.append(f"| {a:g}° | {f:g} Hz | {2 * n} ({n}) | {b:g} | " + " | ".join(cells) + " |")
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ehas_train.evaluate", description=__doc__.split("\n\n")[0])
    parser.add_argument("agents", nargs="+", help="agent folders (written by ehas train)")
    parser.add_argument("--out", default="results/learned", help="output folder (default results/learned)")
    parser.add_argument("--classical", nargs="*", default=[], help="classical controller JSON files to compare")
    parser.add_argument("--cycles", type=float, default=DEFAULT_CYCLES, help="reference periods per run")
    parser.add_argument("--curves", default="results/learning_curves", help="folder for the learning-curve copies")
    parser.add_argument("--readme", action="store_true", help="(re)write each agent folder's README.md")
    parser.add_argument("--allow-pickle", action="store_true",
                        help="also load legacy pickled agent folders (model.zip, vecnormalize.pkl): unpickling runs "
                             "any code the files hold; only for agents you trust as a program")
    args = parser.parse_args(argv)
    from ehas_controllers.base import LOAD_OPTIONS, load_controller

    LOAD_OPTIONS["allow_pickle"] = args.allow_pickle

    command = "python -m ehas_train.evaluate " + " ".join(sys.argv[1:] if argv is None else argv)
    classical = [load_controller(p) for p in args.classical]
    summaries = run(args.agents, args.out, classical=classical, cycles=args.cycles, command=command,
                    curves_dir=args.curves, readmes=args.readme)
    for name, s in sorted(summaries.items(), key=lambda kv: kv[1]["mean_rms_error_pct"]):
        print(f"{name:40s} {s['kind']:9s} mean rms {s['mean_rms_error_pct']:.4f} %  "
              f"30deg/3Hz/7sets {s.get('rms_30deg_3hz_7sets', float('nan')):.3f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
