"""The ``ehas`` command line.

Each subcommand lives in its own module, which defines ``add_arguments(parser)``
and ``run(args) -> int``.  Those modules keep heavy imports (numba kernels,
torch, matplotlib) inside ``run`` so that building the parser stays cheap.
"""
from __future__ import annotations

import argparse
import importlib
import sys

# command name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("ehas_env.cli.demo", "run the main job on embedded defaults and write results/demo/"),
    "size": ("ehas_env.cli.size", "the book's chapter-1 sizing calculations"),
    "effects": ("ehas_env.cli.effects", "list the effects library, or explain one effect"),
    "simulate": ("ehas_env.cli.simulate", "simulate one closed-loop run of the plant and write it as a run file"),
    "perf": ("ehas_env.cli.perf", "speed benchmark of the environment (writes results/perf.md, perf.json)"),
    "tune": ("ehas_controllers.tune_cli", "tune the classical controller (model-based, optimiser, relay, schedule)"),
    "bench": ("ehas_controllers.bench_cli", "percent position error benchmark of controllers over the 63 conditions"),
    "excite": ("ehas_env.cli.excite", "excitation signals (chirp, PRBS, PRMS, multisine) through the valve test"),
    "identify": ("ehas_env.cli.identify", "continuous-time transfer-function fit of a valve run"),
    "curves": ("ehas_env.cli.curves", "valve characteristic curves and Bode plots"),
    "simulate-campaign": ("ehas_env.cli.campaign", "generate a synthetic measurement campaign"),
    "compare": ("ehas_env.cli.compare", "compare the model with a measurement campaign"),
    "diagnose": ("ehas_env.cli.diagnose", "find which physical effect the model is missing"),
    "train": ("ehas_train.train_cli", "train a learned controller with stable-baselines3"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ehas",
        description="Electro-hydraulic actuation systems toolkit.",
    )
    from ehas_env import __version__

    parser.add_argument("--version", action="version", version=f"ehas {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module_name, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(_module=module_name)
        module = _load(module_name)
        if module is not None:
            module.add_arguments(p)
    return parser


def _load(module_name: str):
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name == module_name:
            return None  # command not built in this checkout
        raise


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    module = _load(args._module)
    if module is None:
        parser.error(f"command '{args.command}' is not available in this installation")
    try:
        return int(module.run(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        # Bad input: one clear line, no traceback.
        print(f"ehas {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:
        from ehas_env.simulation.executors import TaskFailed

        if not isinstance(exc, TaskFailed):
            raise
        # a task of a sweep failed on every attempt (ehas_env.simulation.executors): say which, no traceback
        print(f"ehas {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
