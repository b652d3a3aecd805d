"""The ``ehas`` command line.

Each subcommand lives in its own module, which defines ``add_arguments(parser)``
and ``run(args) -> int``.  Those modules keep heavy imports (numba kernels,
torch, matplotlib) inside ``run`` so that building the parser stays cheap.
"""
from __future__ import annotations

import argparse
import importlib
import os
import re
import sys

#: set to 1 to get the traceback of an unexpected error (otherwise: one line)
DEBUG_ENV = "EHAS_DEBUG"

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
    "model": ("ehas_env.cli.model", "read, write and compare model files: the plant as one file (docs/model-file.md)"),
}


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``ehas CMD: error: --opt must be ..., got 'x'`` and exit status 2."""

    def error(self, message: str):  # noqa: D401 - argparse's hook
        # "argument --cycles: --cycles must be ..." -> "--cycles must be ..."
        m = re.match(r"argument ([^:]+): (.*)$", message, flags=re.S)
        if m and any(m.group(2).startswith(name) for name in m.group(1).split("/")):
            message = m.group(2)
        message = " ".join(message.split())
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
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
        if name in MODEL_COMMANDS and not any("--model" in a.option_strings for a in p._actions):
            p.add_argument("--model", default=None, metavar="FILE",
                           help="model file of the plant (rig, valve, effects; default: the book's rig; "
                                "docs/model-file.md)")
        if name in EFFECT_COMMANDS:
            p.add_argument("--effects-path", action="append", metavar="DIR",
                           help="folder (or .py file) of your own effect files to load first; repeatable "
                                "(docs/effects-and-controllers.md)")
    return parser


#: commands that build plants (or size one): they take --model FILE (docs/model-file.md)
MODEL_COMMANDS = ("simulate", "bench", "tune", "compare", "diagnose", "simulate-campaign", "train", "curves", "size")

#: commands that build plants: they take --effects-path
EFFECT_COMMANDS = ("simulate", "bench", "tune", "compare", "diagnose", "simulate-campaign", "train", "effects", "perf",
                   "curves")


def _load(module_name: str):
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name == module_name:
            return None  # command not built in this checkout
        raise


def main(argv: list[str] | None = None) -> int:
    """Run one ``ehas`` command; every failure is one line on stderr and a non-zero status.

    ====  =====================================================================
    0     done
    1     the command failed while working (a file could not be written, a
          sweep task failed, an unexpected error: set EHAS_DEBUG=1 for the
          traceback)
    2     bad input: an option, a file or an output path (nothing was written)
    130   interrupted (Ctrl-C); the previous complete output is left in place
    ====  =====================================================================

    ``ehas CMD | head`` ends quietly when the reader closes the pipe.  A SIGTERM (a job
    scheduler's stop, ``kill``) is handled as Ctrl-C: outputs stay whole, status 130.
    """
    import signal

    def _terminate(signum, frame):
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread: leave the signal alone
        previous = None
    try:
        return _main(argv)
    except BrokenPipeError:
        # the reader went away (| head): stop quietly; point stdout at devnull so the
        # interpreter's final flush does not complain either
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 141
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _main(argv) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse's usage error (status 2) or --help/--version (0): a status, not an exit
        return exc.code if isinstance(exc.code, int) else 2
    except KeyboardInterrupt:
        print("ehas: interrupted", file=sys.stderr)
        return 130
    if args.command is None:
        parser.print_help()
        return 0
    empty = _empty_value(parser, args)
    if empty:
        # argparse takes '' as a value; the commands would read it as "not given" (or as the current folder)
        print(f"ehas {args.command}: error: {empty}: the value is empty; give a value (see ehas {args.command} "
              "--help)", file=sys.stderr)
        return 2
    if getattr(args, "effects_path", None):
        from ehas_env.physics.effects import load_effects_path

        try:
            load_effects_path(args.effects_path)
        except ValueError as exc:
            print(f"ehas {args.command}: error: --effects-path: {exc}", file=sys.stderr)
            return 2
    module = _load(args._module)
    if module is None:
        parser.error(f"command '{args.command}' is not available in this installation")
    name = f"ehas {args.command}"
    import warnings

    def _show(message, category, filename, lineno, file=None, line=None):
        # a warning is one line too, in the command's name (not Python's file:line and source line)
        print(f"{name}: warning: {_one_line(message)}", file=sys.stderr if file is None else file)

    shown, warnings.showwarning = warnings.showwarning, _show
    try:
        rc = int(module.run(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, inside the handlers
        return rc
    except BrokenPipeError:
        raise
    except KeyboardInterrupt:
        try:
            sys.stdout.flush()
        except (OSError, ValueError):
            pass
        print(f"{name}: interrupted", file=sys.stderr)
        return 130
    except (ValueError, FileNotFoundError, NotADirectoryError, IsADirectoryError, FileExistsError) as exc:
        # bad input: one clear line, no traceback
        text = _os_error(exc) if isinstance(exc, OSError) and exc.filename else _one_line(exc)
        print(f"{name}: error: {text}", file=sys.stderr)
        return 2
    except MemoryError:
        print(f"{name}: error: out of memory; use smaller options (docs/errors.md lists the allowed ranges)",
              file=sys.stderr)
        return 1
    except OSError as exc:
        # the disk is full, a folder is read-only, ...: name the path
        print(f"{name}: error: {_os_error(exc)}", file=sys.stderr)
        return 1
    except RuntimeError as exc:
        from ehas_env.simulation.executors import TaskFailed

        if isinstance(exc, TaskFailed):
            # a task of a sweep failed on every attempt (ehas_env.simulation.executors): say which, no traceback
            print(f"{name}: error: {_one_line(exc)}", file=sys.stderr)
            return 1
        return _unexpected(name, exc)
    except Exception as exc:  # noqa: BLE001 - the last line of defence: one line, traceback on request
        return _unexpected(name, exc)
    finally:
        warnings.showwarning = shown


def _empty_value(parser, args) -> str | None:
    """The option (or argument) given an empty string, if any."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[args.command]
    for action in sub._actions:
        value = getattr(args, action.dest, None)
        if value is action.default or value == action.default:
            continue  # not given
        values = value if isinstance(value, list) else [value]
        if any(isinstance(v, str) and v.strip() == "" for v in values):
            return action.option_strings[-1] if action.option_strings else action.metavar or action.dest
    return None


def _one_line(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    return " ".join(text.split())


def _os_error(exc: OSError) -> str:
    """``PATH: what went wrong`` from an OSError (ENOSPC, EACCES, ...)."""
    path = exc.filename
    what = exc.strerror or _one_line(exc)
    if path is None:
        return _one_line(exc)
    if exc.filename2:
        return f"{path} -> {exc.filename2}: {what}"
    return f"{path}: {what}"


def _unexpected(name: str, exc: BaseException) -> int:
    if os.environ.get(DEBUG_ENV, "") not in ("", "0"):
        import traceback

        traceback.print_exception(exc)
    print(f"{name}: internal error: {type(exc).__name__}: {_one_line(exc)} "
          f"(set {DEBUG_ENV}=1 for the traceback and report it)", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
