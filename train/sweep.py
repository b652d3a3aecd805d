"""RL hyper-parameter sweeps: ``ehas train --sweep --config FILE``.

The search space lives in the training config file, in a ``[sweep]`` table next
to the usual sections (which give every trial's base configuration)::

    [sweep]
    seed = 0                      # seed of the random draws (the trials are drawn by the driver)
    trials = 8                    # random search: this many draws; omit for the full grid of the lists
    metric = "mean_rms_error_pct" # from the trial's final deterministic evaluation (or metrics.json)
    mode = "min"                  # min | max
    [sweep.space]                 # dotted path into the config file -> values
    "algo.learning_rate" = { loguniform = [1e-4, 1e-3] }
    "algo.gamma" = [0.95, 0.99]                 # a list: one of these values
    "train.seed" = { choice = [0, 1, 2] }
    "algo.n_epochs" = { randint = [3, 10] }     # integers lo..hi inclusive
    "env.action_penalty" = { uniform = [0.0, 0.1] }

Every trial's configuration is drawn and validated by the driver before any
training starts, so the same file gives the same trials wherever they run.
Each trial trains with stable-baselines3 in a temporary folder on its worker
and returns its metrics; only the driver writes into ``--out``:
``sweep_trials.csv`` (one row per trial), ``sweep_results.json`` (everything),
``best_config.toml`` (train it with ``ehas train --config``) and ``README.md``.

With ``--executor ray`` the trials are Ray Tune trials (one CPU each; a trial
whose worker dies is restarted up to ``retries`` times); locally they run one
after the other (or in ``--workers`` processes).  A trial that still fails is
recorded as failed and the command ends with an error naming it.

Examples
--------
>>> raw = {"train": {"algo": "ppo"}, "sweep": {"seed": 1, "space": {"algo.gamma": [0.9, 0.99]}}}
>>> spec = parse_sweep(raw, "x.toml")
>>> [t["algo.gamma"] for t in draw_trials(spec)]
[0.9, 0.99]
>>> print(to_toml({"train": {"algo": "ppo", "seed": 0}, "algo": {"policy_kwargs": {"net_arch": [32, 32]}}}))
[train]
algo = "ppo"
seed = 0
<BLANKLINE>
[algo]
[algo.policy_kwargs]
net_arch = [32, 32]
<BLANKLINE>
"""
from __future__ import annotations

import copy
import csv
import io
import itertools
import json
import math
import re
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .config import CONFIG_FORMAT, CONFIG_VERSION

DISTRIBUTIONS = ("choice", "uniform", "loguniform", "randint")
SWEEP_KEYS = ("seed", "trials", "metric", "mode", "space")


@dataclass
class SweepSpec:
    """A validated ``[sweep]`` table and the base configuration (file layout) it varies."""

    base: dict
    space: dict
    seed: int = 0
    trials: int | None = None
    metric: str = "mean_rms_error_pct"
    mode: str = "min"
    source: str = "<dict>"
    order: list = field(default_factory=list)


def load_sweep(path) -> SweepSpec:
    """Read a config file with a ``[sweep]`` table."""
    from .config import read_toml

    return parse_sweep(read_toml(path), str(path))


def parse_sweep(raw: dict, source: str = "<dict>") -> SweepSpec:
    """Validate the ``[sweep]`` table of the parsed config ``raw`` (the rest is the trials' base)."""
    from .config import parse_config

    raw = copy.deepcopy(raw)
    sweep = raw.pop("sweep", None)
    if not isinstance(sweep, dict):
        raise ValueError(f"{source}: --sweep needs a [sweep] table with a [sweep.space] (see ehas_train.sweep)")
    parse_config(raw, source=source)  # the base must be a valid configuration by itself
    where = f"{source}: [sweep]"
    bad = sorted(set(sweep) - set(SWEEP_KEYS))
    if bad:
        raise ValueError(f"{where} unknown key(s) {', '.join(bad)}; allowed: {', '.join(SWEEP_KEYS)}")
    seed, trials = sweep.get("seed", 0), sweep.get("trials")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"{where} seed must be an integer >= 0, got {seed!r}")
    if trials is not None and (isinstance(trials, bool) or not isinstance(trials, int) or trials < 1):
        raise ValueError(f"{where} trials must be an integer >= 1, got {trials!r}")
    mode = sweep.get("mode", "min")
    if mode not in ("min", "max"):
        raise ValueError(f"{where} mode must be 'min' or 'max', got {mode!r}")
    metric = sweep.get("metric", "mean_rms_error_pct")
    if not isinstance(metric, str) or not metric:
        raise ValueError(f"{where} metric must be a metric name string, got {metric!r}")
    space = sweep.get("space")
    if not isinstance(space, dict) or not space:
        raise ValueError(f"{where} needs a non-empty [sweep.space] table: \"section.key\" = values")
    parsed = {}
    for key, spec in space.items():
        w = f"{source}: [sweep.space] {key!r}"
        parts = key.split(".")
        if len(parts) < 2 or parts[0] not in ("train", "algo", "env", "randomise"):
            raise ValueError(f"{w}: keys are dotted paths into the config, e.g. \"algo.learning_rate\"")
        if isinstance(spec, list):
            spec = {"choice": spec}
        if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in DISTRIBUTIONS:
            raise ValueError(f"{w}: expected a list of values or one of {{{' | '.join(d + ' = [...]' for d in DISTRIBUTIONS)}}}, "
                             f"got {spec!r}")
        (dist, vals), = spec.items()
        if not isinstance(vals, list) or not vals:
            raise ValueError(f"{w}: {dist} needs a non-empty list, got {vals!r}")
        if dist != "choice":
            if len(vals) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals) \
                    or not vals[0] <= vals[1]:
                raise ValueError(f"{w}: {dist} needs [low, high] numbers with low <= high, got {vals!r}")
            if dist == "loguniform" and vals[0] <= 0:
                raise ValueError(f"{w}: loguniform needs low > 0, got {vals!r}")
            if dist == "randint" and not all(isinstance(v, int) for v in vals):
                raise ValueError(f"{w}: randint needs integer bounds, got {vals!r}")
        parsed[key] = (dist, vals)
    if trials is None and any(d != "choice" for d, _ in parsed.values()):
        raise ValueError(f"{where} trials is required when [sweep.space] has distributions (only lists make a grid)")
    return SweepSpec(base=raw, space=parsed, seed=seed, trials=trials, metric=metric, mode=mode, source=source,
                     order=list(parsed))


def draw_trials(spec: SweepSpec) -> list[dict]:
    """Each trial's values (dotted path -> value): the grid of the lists, or ``trials`` seeded draws."""
    keys = spec.order
    if spec.trials is None:
        return [dict(zip(keys, combo)) for combo in itertools.product(*(spec.space[k][1] for k in keys))]
    rng = np.random.default_rng(spec.seed)
    out = []
    for _ in range(spec.trials):
        t = {}
        for k in keys:
            dist, vals = spec.space[k]
            if dist == "choice":
                t[k] = copy.deepcopy(vals[int(rng.integers(len(vals)))])
            elif dist == "uniform":
                t[k] = float(rng.uniform(vals[0], vals[1]))
            elif dist == "loguniform":
                t[k] = float(math.exp(rng.uniform(math.log(vals[0]), math.log(vals[1]))))
            else:
                t[k] = int(rng.integers(vals[0], vals[1] + 1))
        out.append(t)
    return out


def trial_config(spec: SweepSpec, values: dict, index: int) -> dict:
    """The file-layout configuration of one trial, validated (errors name the trial and key)."""
    from .config import parse_config

    raw = copy.deepcopy(spec.base)
    for key, v in values.items():
        node = raw
        *path, last = key.split(".")
        for p in path:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise ValueError(f"{spec.source}: [sweep.space] {key!r}: {p} is not a table in the config")
        node[last] = v
    cfg = parse_config(raw, source=f"{spec.source} (sweep trial {index}: {values})")
    return cfg.to_file_dict()


# -- one trial (runs on a worker) ------------------------------------------------------------------
def run_trial(task) -> dict:
    """Train one trial in a temporary folder and return its metrics (the driver writes the files).

    ``task = (index, file-layout config dict)``: module-level and self-contained, the
    trial's seed is inside its config, so it gives the same numbers in any process.
    """
    from .config import parse_config
    from .trainer import train

    index, raw = task
    cfg = parse_config(copy.deepcopy(raw), source=f"sweep trial {index}")
    t0 = time.time()
    with tempfile.TemporaryDirectory(prefix=f"ehas_trial{index}_") as tmp:
        metrics = train(cfg, Path(tmp) / "run", progress=False, tensorboard=False, keep_checkpoints=False)
    return {"trial": index, "metrics": json.loads(json.dumps(metrics, default=str)),
            "wall_s": round(time.time() - t0, 1)}


def ray_tune_trial(config, tasks=None) -> None:
    """Ray Tune trainable: run trial ``config["trial"]`` and report its result."""
    from ray import tune

    result = run_trial(tasks[config["trial"]])
    tune.report({"trial": config["trial"], "result_json": json.dumps(result)})


# -- the sweep (driver) -------------------------------------------------------------------------
def objective(metrics: dict, name: str):
    """The sweep metric from a trial's metrics (its final evaluation first, then the top level)."""
    ev = metrics.get("final_evaluation") or {}
    v = ev.get(name, metrics.get(name))
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def run_sweep(spec: SweepSpec, out, *, executor=None, command: str = "ehas train --sweep", retries: int = 2) -> dict:
    """Run every trial of ``spec`` through ``executor`` and write the sweep files into ``out``.

    Returns ``{"trials": [...], "best": index or None, "failed": [...]}``; raises
    :class:`ehas_env.simulation.executors.TaskFailed` (after writing what finished) when a trial failed.
    """
    from ehas_env.simulation.executors import LocalExecutor, RayExecutor, TaskFailed

    values = draw_trials(spec)
    tasks = [(i, trial_config(spec, v, i)) for i, v in enumerate(values)]
    executor = executor or LocalExecutor(workers=1)
    if isinstance(executor, RayExecutor):
        outcomes = _ray_tune(tasks, executor, retries)
    else:
        try:
            outcomes = [("ok", r) for r in executor.map(run_trial, tasks, desc="sweep trials")]
        except TaskFailed as exc:
            raise TaskFailed(f"sweep: {exc}") from exc
    rows = []
    for (i, raw), v, (status, res) in zip(tasks, values, outcomes):
        m = res["metrics"] if status == "ok" else {}
        rows.append({"trial": i, "status": status, "params": v, "objective": objective(m, spec.metric) if m else None,
                     "wall_s": res.get("wall_s") if status == "ok" else None, "metrics": m, "config": raw})
    scored = [r for r in rows if r["objective"] is not None]
    best = None
    if scored:
        key = (lambda r: r["objective"]) if spec.mode == "min" else (lambda r: -r["objective"])
        best = min(scored, key=key)["trial"]  # ties: the earlier trial
    _write(spec, Path(out), rows, best, command)
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        raise TaskFailed(f"sweep: {len(failed)} of {len(rows)} trials failed: " +
                         "; ".join(f"trial {r['trial']} {r['status']}" for r in failed) +
                         f" (the others are recorded in {Path(out) / 'sweep_trials.csv'})")
    return {"trials": rows, "best": best, "failed": failed}


def _ray_tune(tasks, executor, retries: int) -> list[tuple[str, dict]]:
    """Run the trials as Ray Tune trials; a trial's worker that dies is restarted up to ``retries`` times."""
    executor._init()
    from ray import tune

    trainable = tune.with_resources(tune.with_parameters(ray_tune_trial, tasks=tasks), {"cpu": 1})
    storage = tempfile.mkdtemp(prefix="ehas_sweep_tune_")  # Tune's own bookkeeping, not the results
    tuner = tune.Tuner(trainable, param_space={"trial": tune.grid_search(list(range(len(tasks))))},
                       run_config=tune.RunConfig(name="ehas_sweep", storage_path=storage, verbose=0,
                                                 failure_config=tune.FailureConfig(max_failures=retries)))
    try:
        grid = list(tuner.fit())
    finally:
        shutil.rmtree(storage, ignore_errors=True)
    out: dict[int, tuple[str, dict]] = {}
    for r in grid:
        i = int(r.config["trial"])
        if r.error is not None or not r.metrics or "result_json" not in r.metrics:
            msg = str(r.error).strip().splitlines()[-1][:200] if r.error is not None else "no result reported"
            out[i] = (f"failed after {retries + 1} attempts: {msg}", {})
        else:
            out[i] = ("ok", json.loads(r.metrics["result_json"]))
    return [out.get(i, ("failed: Ray Tune returned no result", {})) for i in range(len(tasks))]


def _write(spec: SweepSpec, out: Path, rows: list, best, command: str) -> None:
    from ehas_env.output.files import atomic_write_text

    out.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    buf.write(f"# RL hyper-parameter sweep of {spec.source}; regenerate with: {command}\n")
    buf.write(f"# objective: {spec.metric} ({spec.mode}) from each trial's final deterministic evaluation\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["trial", "status", *spec.order, spec.metric, "num_timesteps", "train_time_s", "best"])
    for r in rows:
        m = r["metrics"]
        w.writerow([r["trial"], r["status"], *(json.dumps(r["params"][k]) if isinstance(r["params"][k], list)
                                                 else r["params"][k] for k in spec.order),
                    "" if r["objective"] is None else f"{r['objective']:.6g}", m.get("num_timesteps", ""),
                    m.get("train_time_s", ""), int(r["trial"] == best)])
    atomic_write_text(out / "sweep_trials.csv", buf.getvalue())
    atomic_write_text(out / "sweep_results.json", json.dumps(
        {"command": command, "source": spec.source, "metric": spec.metric, "mode": spec.mode, "seed": spec.seed,
         "best_trial": best, "trials": rows}, indent=2, default=str) + "\n")
    lines = ["# RL hyper-parameter sweep", "", f"Regenerate with `{command}`.", "",
             f"{len(rows)} trials of `{spec.source}`; objective **{spec.metric}** ({spec.mode}). "
             "`sweep_trials.csv`: one row per trial; `sweep_results.json`: each trial's values, configuration and "
             "metrics."]
    if best is not None:
        b = rows[best]
        atomic_write_text(out / "best_config.toml",
                          f"# best trial ({best}) of the sweep `{command}`: {spec.metric} = {b['objective']:.6g}\n"
                          f"# train it: ehas train --algo {b['config']['train']['algo']} --config "
                          f"{out / 'best_config.toml'} --out DIR\n"
                          + to_toml({"format": CONFIG_FORMAT, "version": CONFIG_VERSION, **b["config"]}))
        lines += ["", f"Best: trial {best}, {spec.metric} = {b['objective']:.6g}, values "
                  + ", ".join(f"`{k} = {v}`" for k, v in b["params"].items()) + "; its configuration is "
                  "`best_config.toml`."]
    atomic_write_text(out / "README.md", "\n".join(lines) + "\n")


# -- TOML writing (the standard library reads TOML but does not write it) --------------------------
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    if v is None:
        raise ValueError("TOML has no null value")
    raise ValueError(f"cannot write {type(v).__name__} as TOML")


def to_toml(d: dict, prefix: str = "") -> str:
    """Nested dict -> TOML text (tables for nested dicts, inline values otherwise); ``None`` values are left out."""
    lines, subs = [], []
    for k, v in d.items():
        if isinstance(v, dict):
            subs.append((k, v))
        elif v is not None:
            lines.append(f"{_key(k)} = {_value(v)}")
    text = "\n".join(lines) + ("\n" if lines else "")
    for k, v in subs:
        name = f"{prefix}.{_key(k)}" if prefix else _key(k)
        text += ("\n" if text else "") + f"[{name}]\n" + to_toml(v, name)
    return text
