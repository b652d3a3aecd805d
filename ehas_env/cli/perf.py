"""``ehas perf``: speed benchmark of the tracking environment.

Writes ``results/perf.md`` and ``results/perf.json`` (each names the command
that regenerates it).  Every figure is measured in the same run, on the same
machine, next to gymnasium's ``Pendulum-v1`` (the reference of a cheap
classic-control environment):

* the single environment through ``gymnasium.make`` (all default wrappers:
  TimeLimit, OrderEnforcing, PassiveEnvChecker), stepped with presampled
  actions, resetting at episode ends -- against ``gymnasium.make("Pendulum-v1")``
  stepped the same way; rounds alternate between the two and the medians count;
* the batched environment (``gymnasium.make_vec(..., vectorization_mode=
  "vector_entry_point")``) at N = 1, 64, 1024, 8192 in env-steps/s -- against
  ``Pendulum-v1`` in gymnasium's ``SyncVectorEnv`` at the same N;
* the peak resident memory of a fresh process that imports, builds and steps
  the N = 8192 batch (a subprocess, so that nothing else in this run counts;
  a first short process fills the compiled-code cache, so compiling does not);
* the plant's two builds (the compile-time options, ``results/compile.md`` has
  their compile times): steps per second of one closed-loop run of the book
  controller in the quick-compile build (linked modules, functions called: what
  replay and fits run) and the fast-step build (everything inlined: what the
  environments, the batched kernel and benchmark grids run), rounds alternating;
* training throughput (when stable-baselines3 is installed; ``--training-steps 0``
  skips it): env-steps per second of PPO and SAC training (``ehas_train.throughput``,
  the bundled ``ppo`` and ``residual_sac_gentle`` configs) with the batched
  ``VecEnv`` adapter against SB3's ``DummyVecEnv``, same config, same run, rounds
  alternating, and the share of a training step spent in the vector env and in
  the compiled plant step.

The machine is shared (other processes may be running): the load average at
the start and the end is recorded beside the figures.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

DEFAULT_SIZES = "1,64,1024,8192"
TRAINING_STEPS = 16_384  # agent steps per timed training run (PPO: 4 rollouts of 8 x 512; SAC: after learning_starts)
PARALLEL_MIN_ENVS = 1024  # batches from this size are also measured with the opt-in prange loop
TARGETS = {
    "single_vs_pendulum": 1.2,  # single env steps/s over Pendulum-v1's
    "batched_8192_env_steps_per_s": 1.0e6,
    "rss_8192_mb": 500.0,
    "substeps": 10,
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="results", help="output folder (default results/)")
    from ehas_env.ranges import number

    parser.add_argument("--seconds", type=number("--seconds", "s", 0, 3600, lo_open=True), default=3.0,
                        help="duration of each measurement, s, (0, 3600] (default 3)")
    parser.add_argument("--repeats", type=number("--repeats", "rounds", 1, 1000, integer=True), default=3,
                        help="alternating rounds per comparison, 1..1000 (default 3)")
    parser.add_argument("--sizes", default=DEFAULT_SIZES, help=f"batch sizes (default {DEFAULT_SIZES})")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier perf.md / perf.json in --out")
    parser.add_argument("--training-steps", type=number("--training-steps", "agent steps", 0, 10_000_000, integer=True),
                        default=None,
                        help=f"agent steps of each timed training run (default {TRAINING_STEPS} x --seconds / 3; "
                             "0 skips the training throughput)")
    parser.add_argument("--rss-envs", type=number("--rss-envs", "environments", 0, 1_000_000, integer=True), default=8192,
                        help="batch size of the peak-memory run in a fresh process (default 8192; 0 skips it)")


def _command(args) -> str:
    parts = ["ehas perf"]
    if args.out != "results":
        parts.append(f"--out {args.out}")
    if args.seconds != 3.0:
        parts.append(f"--seconds {args.seconds:g}")
    if args.repeats != 3:
        parts.append(f"--repeats {args.repeats}")
    if args.sizes != DEFAULT_SIZES:
        parts.append(f"--sizes {args.sizes}")
    if args.rss_envs != 8192:
        parts.append(f"--rss-envs {args.rss_envs}")
    if getattr(args, "training_steps", None) is not None:
        parts.append(f"--training-steps {args.training_steps}")
    return " ".join(parts)


def _parse_sizes(text: str) -> list[int]:
    from ehas_env.ranges import split_list

    items = split_list(text, "--sizes", "positive integers", max_items=32)
    try:
        sizes = [int(s) for s in items]
    except ValueError:
        raise ValueError(f"--sizes must be comma-separated positive integers, got {text!r}") from None
    if min(sizes) < 1 or max(sizes) > 1_000_000:  # split_list: 1 to 32 of them
        raise ValueError(f"--sizes must be 1 to 32 comma-separated integers in [1, 1000000], got {text!r}")
    return sizes


# -- measurements -----------------------------------------------------------------
def single_rate(env, actions, seconds: float) -> float:
    """Steps/s of ``env`` stepped with the presampled ``actions`` (cycled), resetting at episode ends."""
    env.reset(seed=0)
    n = len(actions)
    k = steps = 0
    t0 = time.perf_counter()
    deadline = t0 + seconds
    while True:
        for _ in range(500):
            _, _, term, trunc, _ = env.step(actions[k])
            k = k + 1 if k + 1 < n else 0
            if term or trunc:
                env.reset()
        steps += 500
        if time.perf_counter() >= deadline:
            return steps / (time.perf_counter() - t0)


def batch_rate(envs, actions, seconds: float, cpu: list | None = None) -> float:
    """Env-steps/s of the vector env ``envs`` stepped with the presampled ``actions`` (cycled).

    ``cpu``, if given, receives the env-steps per second of this process's CPU
    time (all its threads), a figure other processes on the machine barely move.
    """
    envs.reset(seed=0)
    envs.step(actions[0])  # first step outside the clock
    if callable(getattr(envs, "wait_for_fast_step", None)):
        envs.wait_for_fast_step()  # the fast-step build, not the interpreted one it starts on the first time
    n = len(actions)
    k = steps = 0
    c0 = time.process_time()
    t0 = time.perf_counter()
    deadline = t0 + seconds
    while time.perf_counter() < deadline or steps < 3:
        envs.step(actions[k])
        k = k + 1 if k + 1 < n else 0
        steps += 1
    wall = time.perf_counter() - t0
    if cpu is not None:
        cpu.append(steps * envs.num_envs / max(time.process_time() - c0, 1e-9))
    return steps * envs.num_envs / wall


def _presampled(space, n: int, seed: int = 0) -> list:
    space.seed(seed)
    return [space.sample() for _ in range(n)]


def peak_rss_mb() -> float:
    """This process's peak resident memory, MB.

    Linux's VmHWM, which starts afresh at exec; ``ru_maxrss`` would carry the
    peak of the parent that forked this process.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0  # kB
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _rss_child(num_envs: int, seconds: float) -> None:
    """Run in a fresh process: build and step the batch, print peak RSS and speed as JSON."""
    import gymnasium
    import numpy as np

    import ehas_env  # noqa: F401

    rss_import = peak_rss_mb()
    envs = gymnasium.make_vec("ehas/Tracking-v0", num_envs=num_envs, vectorization_mode="vector_entry_point")
    actions = np.asarray(_presampled(envs.action_space, 16))
    rate = batch_rate(envs, actions, seconds)
    peak = peak_rss_mb()
    from ehas_env.simulation.compiled_model import current_model

    m = current_model()
    compiled = any(sum(f.stats.cache_misses.values()) for f in (m.batch_reset, m.batch_step_serial,
                                                                  m.batch_step_parallel))
    print(json.dumps({"num_envs": num_envs, "peak_rss_mb": peak, "import_rss_mb": rss_import,
                      "env_steps_per_s": rate, "compiled": compiled}))


def measure_rss(num_envs: int, seconds: float) -> dict:
    """Peak RSS of a fresh process stepping ``num_envs`` environments.

    Runs until a process loads every compiled function from numba's on-disk
    cache instead of compiling it (LLVM's own memory would otherwise count);
    the first run normally fills the cache.
    """
    out = None
    for attempt in range(4):
        code = f"from ehas_env.cli.perf import _rss_child; _rss_child({int(num_envs)}, {float(seconds)!r})"
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=3600)
        if proc.returncode != 0:
            raise RuntimeError(f"the memory run failed:\n{proc.stderr[-2000:]}")
        out = json.loads(proc.stdout.strip().splitlines()[-1])
        if not out["compiled"]:
            break
    return out


def plant_rate(plant, controller, seconds: float) -> float:
    """Control steps per second of ``plant``'s closed loop (5 sets, 20 deg at 2 Hz, 2 s runs) over ``seconds``."""
    n = 0
    t0 = time.perf_counter()
    while True:
        res = plant.simulate_closed_loop(controller, amplitude_deg=20.0, freq_hz=2.0, cycles=4)
        n += len(res.theta_deg)
        if time.perf_counter() - t0 >= seconds:
            return n / (time.perf_counter() - t0)


def measure_builds(seconds: float, repeats: int, bar=None) -> dict:
    """Step speed of the plant's quick-compile and fast-step builds, rounds alternating (EHAS_BUILD picks one)."""
    from ehas_env.simulation.plant import Plant, RigController

    plants = {}
    saved = os.environ.get("EHAS_BUILD")
    try:
        for build in ("quick", "inline"):
            os.environ["EHAS_BUILD"] = build
            plants[build] = Plant(disc_sets=5)
            plants[build].simulate_closed_loop(RigController.book(), amplitude_deg=20.0, freq_hz=2.0, cycles=1)
    finally:
        if saved is None:
            os.environ.pop("EHAS_BUILD", None)
        else:
            os.environ["EHAS_BUILD"] = saved
    ctrl = RigController.book()
    rounds = []
    for r in range(repeats):
        res = {}
        for build in (("quick", "inline") if r % 2 == 0 else ("inline", "quick")):
            res[build] = plant_rate(plants[build], ctrl, seconds)
            if bar is not None:
                bar.update()
        res["ratio"] = res["inline"] / res["quick"]
        rounds.append(res)
    return {"quick_steps_per_s": statistics.median(x["quick"] for x in rounds),
            "inline_steps_per_s": statistics.median(x["inline"] for x in rounds),
            "inline_over_quick": statistics.median(x["ratio"] for x in rounds), "rounds": rounds}


def _machine() -> dict:
    import gymnasium
    import numba
    import numpy

    cpu = platform.processor() or ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "numba_threads": numba.config.NUMBA_NUM_THREADS,
            "python": platform.python_version(), "numpy": numpy.__version__, "numba": numba.__version__,
            "gymnasium": gymnasium.__version__, "platform": platform.platform()}


def _load() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


# -- the command --------------------------------------------------------------------
def run(args) -> int:
    import gymnasium
    import numpy as np
    from tqdm import tqdm

    import ehas_env  # noqa: F401  (registers ehas/Tracking-v0)

    from ehas_env.output.files import atomic_write_text

    from ehas_env.output.outputs import OutputSet

    sizes = _parse_sizes(args.sizes)
    out = Path(args.out)
    outputs = OutputSet(out, "--out", overwrite=args.overwrite, members=("perf.md", "perf.json"), last=("perf.md",))
    command = _command(args)
    load_start = _load()

    t0 = time.perf_counter()
    env = gymnasium.make("ehas/Tracking-v0")
    env.reset(seed=0)
    env.step(env.action_space.sample())  # on the fast-step build, or on the interpreted one while it compiles
    first_step = time.perf_counter() - t0
    env.unwrapped.wait_for_fast_step()  # nothing is timed before the fast-step build is in use
    warmup = time.perf_counter() - t0
    substeps = env.unwrapped._st.substeps
    pend = gymnasium.make("Pendulum-v1")
    acts_e = _presampled(env.action_space, 20_000)
    acts_p = _presampled(pend.action_space, 20_000)

    from ehas_env.env.vector_env import TrackingVectorEnv

    n_both = sum(1 for n in sizes if n >= PARALLEL_MIN_ENVS)
    total = 2 * args.repeats * (2 + len(sizes)) + args.repeats * n_both + (1 if args.rss_envs else 0)
    bar = tqdm(total=total, desc="ehas perf", unit="run")
    rounds = []
    for r in range(args.repeats):
        order = ("ehas", "pendulum") if r % 2 == 0 else ("pendulum", "ehas")
        res = {}
        for name in order:
            res[name] = single_rate(env if name == "ehas" else pend, acts_e if name == "ehas" else acts_p, args.seconds)
            bar.update()
        res["ratio"] = res["ehas"] / res["pendulum"]
        rounds.append(res)
    single = {"ehas_steps_per_s": statistics.median(x["ehas"] for x in rounds),
              "pendulum_steps_per_s": statistics.median(x["pendulum"] for x in rounds),
              "ratio": statistics.median(x["ratio"] for x in rounds), "substeps": substeps,
              "wrappers": str(env), "rounds": rounds}
    env.close()
    pend.close()

    batched = []
    for n in sizes:
        venv = gymnasium.make_vec("ehas/Tracking-v0", num_envs=n, vectorization_mode="vector_entry_point")
        penv = gymnasium.make_vec("Pendulum-v1", num_envs=n, vectorization_mode="sync")
        va = np.asarray(_presampled(venv.action_space, 16))
        pa = np.asarray(_presampled(penv.action_space, 16))
        rr = []
        cpu: list = []
        for r in range(args.repeats):
            order = ("ehas", "pendulum") if r % 2 == 0 else ("pendulum", "ehas")
            res = {}
            for name in order:
                if name == "ehas":
                    res[name] = batch_rate(venv, va, args.seconds, cpu)
                else:
                    res[name] = batch_rate(penv, pa, args.seconds)
                bar.update()
            rr.append(res)
        row = {"num_envs": n, "parallel": bool(venv.parallel),
               "ehas_env_steps_per_s": statistics.median(x["ehas"] for x in rr),
               "pendulum_sync_env_steps_per_s": statistics.median(x["pendulum"] for x in rr),
               "ehas_env_steps_per_cpu_s": statistics.median(cpu),
               "ehas_prange_env_steps_per_s": None, "rounds": rr}
        venv.close()
        penv.close()
        if n >= PARALLEL_MIN_ENVS:  # the opt-in loop on every core, for comparison
            penv2 = TrackingVectorEnv(n, parallel=True)
            par = []
            for r in range(args.repeats):
                par.append(batch_rate(penv2, va, args.seconds))
                bar.update()
            row["ehas_prange_env_steps_per_s"] = statistics.median(par)
        batched.append(row)

    builds = measure_builds(args.seconds, args.repeats, bar)
    memory = None
    if args.rss_envs:
        memory = measure_rss(args.rss_envs, args.seconds)
        bar.update()
    bar.close()
    steps = getattr(args, "training_steps", None)
    training = measure_training(max(64, round(TRAINING_STEPS * args.seconds / 3.0)) if steps is None else steps,
                                args.repeats)
    load_end = _load()

    targets = [
        {"what": "single env steps/s over Pendulum-v1's (same run)", "target": f">= {TARGETS['single_vs_pendulum']}",
         "measured": round(single["ratio"], 3), "met": single["ratio"] >= TARGETS["single_vs_pendulum"]},
        {"what": "RK4 sub-steps per 1 ms step", "target": f">= {TARGETS['substeps']}", "measured": substeps,
         "met": substeps >= TARGETS["substeps"]},
    ]
    b8192 = next((b for b in batched if b["num_envs"] == 8192), None)
    if b8192 is not None:
        targets.append({"what": "batched N = 8192, env-steps/s", "target": ">= 1e6",
                        "measured": round(b8192["ehas_env_steps_per_s"]),
                        "met": b8192["ehas_env_steps_per_s"] >= TARGETS["batched_8192_env_steps_per_s"]})
    if memory is not None and memory["num_envs"] == 8192:
        targets.append({"what": "peak resident memory of the N = 8192 run, MB", "target": "< 500",
                        "measured": round(memory["peak_rss_mb"], 1), "met": memory["peak_rss_mb"] < TARGETS["rss_8192_mb"]})

    report = {
        "command": command,
        "generated": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": _machine(),
        "load_average_start": load_start,
        "load_average_end": load_end,
        "settings": {"seconds_per_measurement": args.seconds, "repeats": args.repeats, "dt_s": 1e-3,
                     "substeps": substeps, "warmup_s": round(warmup, 2),
                     "first_step_s": round(first_step, 2)},
        "single": single,
        "batched": batched,
        "memory": memory,
        "builds": builds,
        "training": training,
        "targets": targets,
    }
    out.mkdir(parents=True, exist_ok=True)
    with outputs as tmp:
        atomic_write_text(tmp / "perf.json", json.dumps(report, indent=2) + "\n")
        atomic_write_text(tmp / "perf.md", render_markdown(report))
    for t in targets:
        print(f"{'MET ' if t['met'] else 'MISS'}  {t['what']}: {t['measured']} (target {t['target']})")
    print(f"wrote {out / 'perf.md'} and {out / 'perf.json'}")
    return 0


def measure_training(steps: int, repeats: int) -> list[dict] | None:
    """PPO and SAC training throughput, batched adapter vs DummyVecEnv (None without stable-baselines3)."""
    if not steps:
        return None
    try:
        from ehas_train import throughput
    except ImportError:  # the rl extra is not installed
        return None
    out = []
    for algo, n_envs in (("ppo", None), ("sac", None), ("ppo", 64)):  # the bundled configs, and PPO on 64 envs
        cfg = throughput.bundled(algo, n_envs)
        if algo == "sac":  # gradient steps from 1000 transitions on: the timed steps are training steps
            cfg = throughput.with_learning_starts(cfg, min(int(cfg.hyper.get("learning_starts", 100)), 1_000))
            warmup = int(cfg.hyper["learning_starts"]) + 500
        else:  # one rollout, so that the timed part is whole rollouts and updates
            warmup = cfg.n_envs * int(cfg.hyper.get("n_steps", 2048))
        print(f"ehas perf: {algo.upper()} training throughput ({cfg.n_envs} envs), batched vs DummyVecEnv ({steps} "
              f"agent steps x {repeats} rounds each)", file=sys.stderr)
        out.append(throughput.measure(cfg, steps=steps, warmup=warmup, repeats=repeats))
    return out


def _training_md(rows: list[dict]) -> list[str]:
    lines = [
        "",
        "## Training throughput (stable-baselines3, batched VecEnv vs DummyVecEnv)",
        "",
        "Each bundled config trained with SB3 on the same machine in the same run, once through the batched "
        "adapter (`ehas_train.batched.BatchedTrackingVecEnv`: every environment stepped in one compiled call, "
        "the default of `ehas train`) and once through SB3's `DummyVecEnv` of `ehas/Tracking-v0` environments "
        "(`[train] vec_env = \"dummy\"`); rounds alternate, medians count. Agent steps: transitions the agent "
        "sees (each action held `action_repeat` control periods); env-steps: 1 ms control periods. Env share: "
        "time in the vector env's `step_wait` over the training time; plant share: time in the compiled plant "
        "step (batched only). The rest is SB3 and torch (policy, buffers, gradient steps).",
        "",
        "| algorithm (config) | envs | action repeat | vector env | agent steps/s | env-steps/s | env share | "
        "plant share | speed-up |",
        "|---|---:|---:|---|---:|---:|---:|---:|---:|",
    ]
    for t in rows:
        for kind in ("batched", "dummy"):
            r = t[kind]
            ps = f"{r['plant_share']:.1%}" if "plant_share" in r else "-"
            sp = f"{t['speedup']:.2f}x" if kind == "batched" else ""
            lines.append(f"| {t['algo'].upper()}{' residual' if t['residual'] else ''} (`{Path(t['config']).name}`) | "
                         f"{t['n_envs']} | {t['action_repeat']} | {kind} | {r['agent_steps_per_s']:,.0f} | "
                         f"{r['env_steps_per_s']:,.0f} | {r['env_share']:.1%} | {ps} | {sp} |")
    lines += ["", f"Timed: {rows[0]['steps']} agent steps per run (PPO: whole rollouts, so at least one rollout of "
              "envs x n_steps) after an untimed warm-up (PPO: one rollout; SAC: `learning_starts`, lowered to 1000 "
              "here, + 500 steps, so that gradient steps are timed). The last PPO row is the bundled config with 64 "
              "environments: the batched env makes many environments cheap, DummyVecEnv does not."]
    return lines


def render_markdown(rep: dict) -> str:
    m = rep["machine"]
    s = rep["single"]
    lines = [
        "# Speed of the tracking environment",
        "",
        f"Regenerate with `{rep['command']}` (writes this file and `perf.json`).",
        "",
        f"Measured {rep['generated']} on {m['cpu']} ({m['cores']} cores, numba threads {m['numba_threads']}), "
        f"Python {m['python']}, numpy {m['numpy']}, numba {m['numba']}, gymnasium {m['gymnasium']}. "
        f"Load average (1, 5, 15 min) at the start {rep['load_average_start']}, at the end "
        f"{rep['load_average_end']}: the machine is shared, and a load above the core count means other "
        "processes took part of it during the run. Every comparison below was measured in the same run, "
        f"alternating {rep['settings']['repeats']} rounds of {rep['settings']['seconds_per_measurement']:g} s "
        "between the two environments; the medians are reported.",
        "",
        "## Targets",
        "",
        "| what | target | measured | met |",
        "|---|---|---|---|",
    ]
    for t in rep["targets"]:
        lines.append(f"| {t['what']} | {t['target']} | {t['measured']} | {'yes' if t['met'] else 'NO'} |")
    lines += [
        "",
        "## Single environment (`gymnasium.make`, presampled actions, resets included)",
        "",
        f"Wrappers: `{s['wrappers']}`; {s['substeps']} RK4 sub-steps per 1 ms step.",
        "",
        "| environment | steps/s |",
        "|---|---|",
        f"| ehas/Tracking-v0 | {s['ehas_steps_per_s']:,.0f} |",
        f"| Pendulum-v1 | {s['pendulum_steps_per_s']:,.0f} |",
        f"| ratio (median of the rounds' ratios) | {s['ratio']:.2f} |",
        "",
        "## Batched environment (`gymnasium.make_vec`, vector entry point)",
        "",
        "Pendulum-v1 has no native vector env: it runs in gymnasium's `SyncVectorEnv`.",
        "",
        "The env steps its rows in one serial numba loop (the default); `parallel=True` spreads them over "
        "every core with a `prange` loop, which pays only when the cores are free (its figure is given beside).",
        "",
        "Per CPU-second: env-steps per second of CPU time used by the benchmark process (all its threads); "
        "other processes on the machine barely change it, and a batch with every core to itself steps about "
        "this many env-steps per second per core.",
        "",
        "| N | ehas env-steps/s | loop | same batch, prange loop | ehas env-steps per CPU-second | "
        "Pendulum-v1 (sync) env-steps/s | ratio |",
        "|---|---|---|---|---|---|---|",
    ]
    for b in rep["batched"]:
        serial = b.get("ehas_prange_env_steps_per_s")
        lines.append(f"| {b['num_envs']} | {b['ehas_env_steps_per_s']:,.0f} | "
                     f"{'prange (all cores)' if b['parallel'] else 'serial'} | "
                     f"{'-' if serial is None else f'{serial:,.0f}'} | "
                     f"{b['ehas_env_steps_per_cpu_s']:,.0f} | "
                     f"{b['pendulum_sync_env_steps_per_s']:,.0f} | "
                     f"{b['ehas_env_steps_per_s'] / b['pendulum_sync_env_steps_per_s']:.1f} |")
    mem = rep["memory"]
    if mem is not None:
        lines += [
            "",
            "## Memory",
            "",
            f"A fresh Python process that imports gymnasium and ehas_env, builds the N = {mem['num_envs']} batch and "
            f"steps it for {rep['settings']['seconds_per_measurement']:g} s peaks at **{mem['peak_rss_mb']:.1f} MB** "
            f"resident (after the imports alone: {mem['import_rss_mb']:.1f} MB); it stepped "
            f"{mem['env_steps_per_s']:,.0f} env-steps/s.",
        ]
    if rep.get("builds"):
        b = rep["builds"]
        lines += ["", "## The plant's two builds (the compile-time options)", "",
                  "One closed-loop run of the book controller (5 sets, 20 deg at 2 Hz, 10 RK4 sub-steps per 1 ms "
                  "step), control steps per second, rounds alternating. Their compile times are in "
                  "`results/compile.md` (`python -m ehas_env.cli.compile_bench`): the quick build compiles a new "
                  "effect in seconds and runs replay and fits; the fast-step build compiles for a minute or more "
                  "and runs the environments, the batched kernel and benchmark grids, where the step speed counts.",
                  "", "| build | steps/s |", "|---|---|",
                  f"| quick-compile (linked modules, functions called) | {b['quick_steps_per_s']:,.0f} |",
                  f"| fast-step (everything inlined) | {b['inline_steps_per_s']:,.0f} |",
                  f"| fast-step over quick (median of the rounds' ratios) | {b['inline_over_quick']:.2f} |"]
    if rep.get("training"):
        lines += _training_md(rep["training"])
    lines += ["", f"First step (make, reset, step): {rep['settings'].get('first_step_s', '?')} s; the fast-step build "
              f"in use (compiled or loaded from the cache) after {rep['settings']['warmup_s']} s.", ""]
    return "\n".join(lines)
