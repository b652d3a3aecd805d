"""``ehas train``: train a learned controller with stable-baselines3.

Examples::

    ehas train --algo sac --residual --config train/configs/residual_sac.toml --out runs/residual_sac
    ehas train --algo ppo --out runs/ppo --total-steps 20000          # bundled train/configs/ppo.toml
    ehas train --algo ppo --out runs/ppo --resume --total-steps 40000 # continue to 40k steps
    ehas train --sweep --config sweep.toml --out runs/sweep --executor ray  # hyper-parameter sweep on Ray Tune
"""
from __future__ import annotations

import argparse

ALGOS = ("ppo", "sac", "td3")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--algo", choices=ALGOS, help="algorithm (required unless --sweep: the config names it)")
    parser.add_argument("--residual", action="store_true",
                        help="residual RL: the action is added to the tuned classical controller's current")
    parser.add_argument("--config", metavar="FILE",
                        help="TOML config (default: the bundled ALGO.toml, or residual_ALGO.toml with --residual)")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="output folder (model, statistics, metrics; with --sweep: the trials and best config)")
    parser.add_argument("--sweep", action="store_true",
                        help="hyper-parameter sweep over the [sweep] table of --config (ehas_train.sweep): one "
                             "training per trial, results and best_config.toml in --out")
    from ehas_env.simulation.executors import add_executor_arguments

    add_executor_arguments(parser)
    parser.add_argument("--resume", action="store_true", help="continue from the last checkpoint in --out")
    from ehas_env.ranges import option

    parser.add_argument("--total-steps", type=option("--total-steps", "total_steps"), metavar="N",
                        help="override [train] total_steps")
    parser.add_argument("--seed", type=option("--seed", "seed"), metavar="S", help="override [train] seed")
    parser.add_argument("--n-envs", type=option("--n-envs", "n_envs"), metavar="N", help="override [train] n_envs")
    parser.add_argument("--vec-env", choices=("batched", "dummy", "subproc"), default=None,
                        help="override [train] vec_env: batched (default: the native batched environment behind "
                             "an SB3 VecEnv, ehas_train.batched), dummy (SB3's DummyVecEnv, for comparison) or subproc")
    parser.add_argument("--max-minutes", type=option("--max-minutes", "max_minutes"), metavar="M",
                        help="wall-clock budget: stop (and save) after M minutes even before --total-steps")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--no-tensorboard", action="store_true", help="no TensorBoard logs")
    parser.add_argument("--drop-checkpoints", action="store_true",
                        help="remove DIR/checkpoints once training completes (keeps the output small)")


def resolve_config(args):
    """The configuration the arguments ask for (bundled default, overrides applied)."""
    from .config import bundled_config, load_config

    if args.config:
        cfg = load_config(args.config)
    else:
        name = f"residual_{args.algo}" if args.residual else args.algo
        cfg = load_config(bundled_config(name))
    if cfg.algo != args.algo:
        raise ValueError(f"--config {cfg.source} trains {cfg.algo!r} but --algo is {args.algo!r}; "
                         "pass a config for that algorithm")
    changes = {}
    if args.total_steps is not None:
        changes["total_steps"] = args.total_steps
    if args.seed is not None:
        changes["seed"] = args.seed
    if args.n_envs is not None:
        changes["n_envs"] = args.n_envs
    if getattr(args, "vec_env", None) is not None:
        changes["vec_env"] = args.vec_env
    if changes:
        cfg = cfg.replace(**changes)
    if args.residual and not cfg.residual:
        from .config import parse_config

        raw = cfg.to_file_dict()
        raw["env"]["residual"] = True
        cfg = parse_config(raw, source=cfg.source)
    if getattr(args, "model", None):  # train on a model file's plant (docs/model-file.md): [env.kwargs] model
        from pathlib import Path

        from ehas_env.simulation.model_file import load_model

        from .config import parse_config

        load_model(args.model)  # refused here, before anything is created
        raw = cfg.to_file_dict()
        raw["env"].setdefault("kwargs", {})["model"] = str(Path(args.model).resolve())
        cfg = parse_config(raw, source=cfg.source)
    elif isinstance(cfg.env_kwargs.get("model"), str):
        from ehas_env.simulation.model_file import load_model

        load_model(cfg.env_kwargs["model"])
    return cfg


def _command(args) -> str:
    """The ``ehas train`` command line that reproduces this run (without --resume)."""
    import shlex

    parts = ["ehas", "train", "--algo", args.algo]
    if args.residual:
        parts.append("--residual")
    if args.config:
        parts += ["--config", args.config]
    parts += ["--out", args.out]
    for flag, value in (("--total-steps", args.total_steps), ("--seed", args.seed), ("--n-envs", args.n_envs),
                        ("--vec-env", getattr(args, "vec_env", None)), ("--max-minutes", args.max_minutes),
                        ("--model", getattr(args, "model", None))):
        if value is not None:
            parts += [flag, str(value)]
    for flag in ("no_tensorboard", "drop_checkpoints"):
        if getattr(args, flag):
            parts.append("--" + flag.replace("_", "-"))
    return " ".join(shlex.quote(p) for p in parts)


def run_sweep_command(args) -> int:
    """``ehas train --sweep``: every trial through the executor; the driver writes --out."""
    import shlex

    from ehas_env.simulation.executors import executor_from_args

    from .sweep import load_sweep, run_sweep

    if not args.config:
        raise ValueError("--sweep needs --config FILE with a [sweep] table (see ehas_train.sweep)")
    for flag in ("resume", "residual"):
        if getattr(args, flag):
            raise ValueError(f"--{flag} does not combine with --sweep (put it in the config file)")
    for flag in ("total_steps", "seed", "n_envs", "vec_env", "max_minutes"):
        if getattr(args, flag, None) is not None:
            raise ValueError(f"--{flag.replace('_', '-')} does not combine with --sweep: set it in the config "
                             "file or sweep it in [sweep.space]")
    spec = load_sweep(args.config)
    algo = spec.base.get("train", {}).get("algo")
    if args.algo is not None and algo != args.algo:
        raise ValueError(f"--config {args.config} trains {algo!r} but --algo is {args.algo!r}")
    # where the trials run does not change their results: the executor options stay out of the command
    command = " ".join(shlex.quote(p) for p in ["ehas", "train", "--sweep", "--config", args.config, "--out", args.out])
    res = run_sweep(spec, args.out, executor=executor_from_args(args), command=command)
    for r in res["trials"]:
        obj = "-" if r["objective"] is None else f"{r['objective']:.4g}"
        print(f"trial {r['trial']}: {spec.metric} {obj}  " + ", ".join(f"{k}={v}" for k, v in r["params"].items()))
    if res["best"] is not None:
        print(f"best: trial {res['best']} -> {args.out}/best_config.toml")
    print(f"wrote {args.out}/sweep_trials.csv, sweep_results.json, README.md")
    return 0


def run(args) -> int:
    import logging
    import sys

    from .trainer import TrainingInterrupted, train

    if getattr(args, "sweep", False):
        return run_sweep_command(args)
    if args.algo is None:
        raise ValueError("--algo is required (ppo, sac or td3)")
    from pathlib import Path

    from ehas_env.output.outputs import OutputError, check_parent

    # the whole configuration and the output folder, checked before anything is created
    cfg = resolve_config(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} is a file; expected a folder (new or empty, or with --resume a training's)")
    check_parent(out, "--out")
    if not args.resume and out.is_dir() and any(p for p in out.iterdir() if not p.name.startswith(".")):
        raise OutputError(f"--out {out} is not empty; use --resume to continue its training or choose another --out")
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s", stream=sys.stderr)
    try:
        metrics = train(cfg, args.out, resume=args.resume, progress=not args.no_progress,
                        tensorboard=not args.no_tensorboard, keep_checkpoints=not args.drop_checkpoints,
                        command=_command(args), max_minutes=args.max_minutes)
    except TrainingInterrupted as exc:
        print(f"ehas train: {exc}", file=sys.stderr)
        return 130
    from .agent import trust_agent

    trust_agent(args.out)  # trained here: loading it does not warn about pickles (ehas_train.agent)
    ev = metrics.get("final_evaluation", {})
    line = (f"trained {cfg.algo}{' residual' if cfg.residual else ''}: {metrics['num_timesteps']} steps in "
            f"{metrics['train_time_s']:.0f} s -> {args.out}")
    if metrics.get("stopped_by_time_limit"):
        line += f" (stopped by --max-minutes {args.max_minutes:g} before {cfg.total_steps} steps)"
    if "mean_rms_error_pct" in ev:
        line += f"; deterministic evaluation: mean rms error {ev['mean_rms_error_pct']:.3f} %"
    elif "mean_return" in ev:
        line += f"; deterministic evaluation: mean return {ev['mean_return']:.4g}"
    print(line)
    return 0
