"""The ``ehas`` command line.

Each subcommand lives in its own module, which defines ``add_arguments(parser)``
and ``run(args) -> int``.  Those modules keep heavy imports (numba kernels,
torch, matplotlib) inside ``run`` so that building the parser stays cheap.
"""
from __future__ import annotations

import os
import re
import signal
import sys


# -- Ctrl-C and SIGTERM (issue 14) ----------------------------------------------------------------
# When ``ehas`` runs as a program (the console script or ``python -m ehas_env.cli.main``), a Ctrl-C
# (SIGINT) or a SIGTERM at any moment ends it with one line ``ehas CMD: interrupted`` and status 130:
# never a traceback, never death by the signal, never status 0.  The handler is installed here, the
# first thing the entry point runs (before argparse and the commands' imports), and acts by phase:
#
# ``start``     before the command runs (imports, parsing; nothing written): exit 130 at once;
# ``work``      the command runs: the first signal raises KeyboardInterrupt, which unwinds the
#               command (its OutputSet keeps the previous complete output or none) to :func:`main`;
# ``stopping``  unwinding after that signal: a second signal is ignored so the cleanup finishes
#               (a third one exits 130 at once);
# ``done``      the command has finished (its outputs are complete) or has been reported
#               interrupted: a signal exits 130 at once, with the line unless it was printed.
#
# At interpreter exit the last atexit callback ends the process with main()'s status (os._exit):
# after it Python restores the default handlers while it tears modules down, and a Ctrl-C there
# would kill the process by the signal.  Left: a signal in the interpreter's start-up, before this
# module runs (the first ~30 ms: Python's own initialisation, site and its .pth files, the import of
# ehas_env), is Python's: death by the signal, or a KeyboardInterrupt traceback (status 1 in site).


class _Stop:
    """The interrupt state of the ``ehas`` process (see the comment above)."""

    armed = False  # the handlers below are installed: ehas runs as a program
    phase = "start"
    signals = 0  # SIGINT/SIGTERM received (with those delivered again)
    signum = signal.SIGINT  # the last one
    redelivered = 0  # signals raised again after a callback dropped their KeyboardInterrupt
    said = False  # the "interrupted" line was printed
    name = "ehas"  # "ehas CMD" once the command is known
    depth = 0  # nested main() calls (ehas demo runs ehas size)
    rc: int | None = None  # main()'s status, for the exit at the end


def _command_name() -> str:
    """``ehas CMD`` (from sys.argv while the parser is not built yet), or ``ehas``."""
    if _Stop.name == "ehas":
        cmd = next((a for a in sys.argv[1:2] if re.fullmatch(r"[a-z][a-z-]*", a)), None)
        return f"ehas {cmd}" if cmd else "ehas"
    return _Stop.name


def _flush() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except BaseException:  # noqa: BLE001 - a closed pipe, a reentrant call inside a handler: go on
            pass


def _say(name: str | None = None) -> None:
    """Print ``ehas CMD: interrupted`` on stderr (once, when ehas runs as a program)."""
    if not _Stop.armed:
        print(f"{name or 'ehas'}: interrupted", file=sys.stderr)
        return
    if _Stop.said:
        return
    _Stop.said = True
    try:
        sys.stderr.flush()
    except BaseException:  # noqa: BLE001 - the handler may run inside a write to stderr
        pass
    try:  # os.write: a print here could be a reentrant call into stderr's buffer
        os.write(2, f"{name or _command_name()}: interrupted\n".encode())
    except OSError:
        pass


def _exit_interrupted() -> None:
    _say()
    _flush()
    os._exit(130)


def _on_signal(signum, frame):
    _Stop.signals += 1
    _Stop.signum = signum
    if _Stop.phase == "work":
        _Stop.phase = "stopping"
        raise KeyboardInterrupt
    if _Stop.phase == "stopping" and _Stop.signals - _Stop.redelivered < 3:
        return  # the first signal is being handled: let the command's cleanup finish
    _exit_interrupted()


def _on_unraisable(unraisable, _default=sys.unraisablehook):
    if isinstance(unraisable.exc_value, KeyboardInterrupt):
        # raised inside a callback that cannot pass it on (a ctypes callback of numba's compiler, a weakref
        # callback, __del__) and dropped there: no traceback; the signal is delivered again a moment later,
        # out of the callback, to stop the command at its next step (a few times at most; main() reports
        # the run interrupted anyway).  Not from here: raising it in this hook would be dropped as well.
        if _Stop.phase == "stopping" and _Stop.redelivered < 20:
            import threading

            _Stop.redelivered += 1
            timer = threading.Timer(0.01, _redeliver)
            timer.daemon = True
            timer.start()
            _Stop.phase = "work"
        return
    if _Stop.signals:
        return  # after an interrupt: the __del__ of an object the KeyboardInterrupt left half-built (llvmlite's)
    _default(unraisable)


def _redeliver() -> None:
    import threading

    if _Stop.phase != "work":
        _Stop.redelivered -= 1  # the command ended meanwhile: nothing to deliver
        return
    try:
        signal.pthread_kill(threading.main_thread().ident, _Stop.signum)
    except (ValueError, OSError, AttributeError):
        pass


def _at_exit() -> None:
    if _Stop.rc is not None:
        _flush()
        # The point of no return.  A signal whose C handler ran but whose Python handler has not run
        # yet would be lost in os._exit: blocking the signals runs it first (pthread_sigmask checks for
        # pending handlers), and it ends the process with 130.  A signal after the block stays pending
        # and the process exits with main()'s status: it came after the exit (SigBlk in /proc tells).
        try:
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        except (ValueError, OSError):  # pragma: no cover - not the main thread
            pass
        os._exit(_Stop.rc)


def _is_program() -> bool:
    """True in the ``ehas`` console script and in ``python -m ehas_env.cli.main``."""
    argv0 = (getattr(sys, "argv", None) or [""])[0]
    if not argv0:
        return False
    if os.path.splitext(os.path.basename(argv0))[0] == "ehas":
        return True
    try:
        return os.path.realpath(argv0) == os.path.realpath(__file__)
    except (OSError, ValueError):
        return False


def _arm() -> None:
    if _Stop.armed:
        return
    try:
        # an ignored signal (a background job's SIGINT, nohup) stays ignored
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _on_signal)
        if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
            signal.signal(signal.SIGTERM, _on_signal)
    except (ValueError, OSError):  # not the main thread
        return
    import atexit

    _Stop.armed = True
    sys.unraisablehook = _on_unraisable
    atexit.register(_at_exit)  # registered first: runs last


if __name__ != "__main__" and _is_program():
    _arm()

import argparse  # noqa: E402 - after the handlers
import importlib  # noqa: E402

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
    "plan-test": ("ehas_env.cli.plan_test", "design the runs that tell apart the explanations a diagnosis lists"),
    "report": ("ehas_env.cli.report", "one self-contained HTML page of a diagnosis or comparison folder"),
    "train": ("ehas_train.train_cli", "train a learned controller with stable-baselines3"),
    "model": ("ehas_env.cli.model", "read, write and compare model files: the plant as one file (docs/model-file.md)"),
    "export-drive": ("ehas_env.cli.export_drive", "write a learning controller's learned feed-forward as drive files "
                                                  "(CSV + JSON sidecar)"),
    "export-controller": ("ehas_env.cli.export_controller", "write a controller as C for the rig's controller "
                                                            "(one .h and one .c; docs/export.md)"),
    "export-fmu": ("ehas_env.cli.export_fmu", "write the rig's model as an FMI 2.0 co-simulation FMU (docs/export.md)"),
}


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``ehas CMD: error: --opt must be ..., got 'x'`` and exit status 2."""

    def error(self, message: str):  # noqa: D401 - argparse's hook
        # "argument --cycles: --cycles must be ..." -> "--cycles must be ..."
        m = re.match(r"argument ([^:]+): (.*)$", message, flags=re.S)
        if m and any(m.group(2).startswith(name) for name in m.group(1).split("/")):
            message = m.group(2)
        message = " ".join(message.split())
        # "invalid choice: 'diagnos' (choose from 'demo', ...)": the closest choices first
        m = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)$", message)
        if m:
            hint = did_you_mean(m.group(1), re.findall(r"'([^']*)'", m.group(2)) or m.group(2).split(", "))
            if hint:
                message = f"{message[:m.end(1) + 1]}; {hint} {message[m.end(1) + 2:]}"
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def did_you_mean(word: str, choices) -> str:
    """``did you mean 'x'?`` (or ``'x' or 'y'``) naming the 1-3 ``choices`` closest to ``word``; "" when none is close.

    Parameters
    ----------
    word : str
        What the user typed.
    choices : iterable of str
        What is allowed.

    Returns
    -------
    str
        The hint, or an empty string.
    """
    import difflib

    choices = [str(c) for c in choices]
    close = difflib.get_close_matches(word, choices, n=3, cutoff=0.6)
    if not close and word.startswith("--"):  # an option: compare the words without the dashes too
        bare = {c[2:]: c for c in choices if c.startswith("--")}
        close = [bare[c] for c in difflib.get_close_matches(word[2:], list(bare), n=3, cutoff=0.6)]
    if not close:
        return ""
    return "did you mean " + " or ".join(f"'{c}'" for c in close) + "?"


def _unknown_options(parser, args, extra: list[str]) -> str:
    """The one-line error for options (or words) no parser of the command took, with the closest options."""
    sub = _subparser(parser, args.command) if args.command else parser
    options = [o for a in _all_actions(sub, args) for o in a.option_strings]
    parts = []
    for word in extra:
        hint = did_you_mean(word.split("=", 1)[0], options) if word.startswith("-") else ""
        parts.append(f"{word} ({hint})" if hint else word)
    what = "argument" if len(extra) == 1 else "arguments"
    return f"unrecognized {what}: {', '.join(parts)}"


def _subparser(parser, command: str):
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[command]


def _all_actions(sub, args) -> list:
    """The actions of ``sub`` and of the nested command chosen in it (``ehas model show``)."""
    out = list(sub._actions)
    for a in sub._actions:
        if isinstance(a, argparse._SubParsersAction):
            chosen = getattr(args, a.dest, None)
            if chosen in a.choices:
                out += _all_actions(a.choices[chosen], args)
    return out


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``ehas`` parser; with ``command`` only that command's options are built (its module alone is
    imported: every command's start skips the others' imports), otherwise every command's."""
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
        if command is not None and name != command:
            continue  # not the command being run: its name and help line are enough
        module = _load(module_name)
        if module is not None:
            module.add_arguments(p)
        if name in MODEL_COMMANDS and not any("--model" in a.option_strings for a in p._actions):
            p.add_argument("--model", default=None, metavar="FILE",
                           help="model file of the plant (rig, valve, effects; default: the book's rig; "
                                "docs/model-file.md)")
        if name in CONTROLLER_PATH_COMMANDS:
            p.add_argument("--controller-path", action="append", metavar="FILE.py",
                           help="your own Python controller file to load first, for a training config or an agent "
                                "folder that names it (they never import code themselves); repeatable")
        if name in EFFECT_COMMANDS:
            p.add_argument("--effects-path", action="append", metavar="DIR",
                           help="folder (or .py file) of your own effect files to load first; repeatable "
                                "(docs/effects-and-controllers.md)")
    return parser


#: commands that build plants (or size one): they take --model FILE (docs/model-file.md)
MODEL_COMMANDS = ("simulate", "bench", "tune", "compare", "diagnose", "simulate-campaign", "train", "curves", "size")

#: commands that may meet a Python controller file named in a config or an agent folder: --controller-path
CONTROLLER_PATH_COMMANDS = ("simulate", "bench", "train")

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
    130   interrupted (Ctrl-C, or SIGTERM: a job scheduler's stop, ``kill``):
          one line ``ehas CMD: interrupted``; the previous complete output (or
          none) is left in place, or the new complete one if the signal came
          after the command had finished
    141   the reader of stdout went away (``ehas CMD | head``): quietly
    ====  =====================================================================

    Run as a program (the console script, ``python -m ehas_env.cli.main``) the
    signal is handled at any moment, from the first import to the exit (see the
    comment on ``_Stop``).  Called from Python (``main([...])``) a SIGTERM raises
    KeyboardInterrupt for the duration of the call, and the interrupt is
    reported as above.
    """
    program = _Stop.armed and _Stop.depth == 0 and argv is None
    nested = _Stop.depth > 0
    _Stop.depth += 1
    previous = None
    try:
        if not program and not nested:
            previous = _catch_sigterm()
        rc = _main(argv, program)
    except KeyboardInterrupt:
        if nested:
            raise  # ehas demo running ehas size: the outer command reports it
        _say(_Stop.name if program else "ehas")
        rc = 130
    except BrokenPipeError:
        # the reader went away (| head): stop quietly; point stdout at devnull so the
        # interpreter's final flush does not complain either
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        rc = 141
    finally:
        _Stop.depth -= 1
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if program:
        if _Stop.signals and rc != 130:
            _say(_Stop.name)  # the interrupt was swallowed inside the command: it still ends as one
            rc = 130
        _Stop.rc = rc
        _Stop.phase = "done"
    return rc


def _catch_sigterm():
    """Called from Python: SIGTERM raises KeyboardInterrupt until the call returns (the previous handler)."""
    def _terminate(signum, frame):
        raise KeyboardInterrupt

    try:
        return signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread: leave the signal alone
        return None


def _main(argv, program: bool = False) -> int:
    if program:
        _Stop.name = _command_name()
    words = sys.argv[1:] if argv is None else list(argv)
    first = next((w for w in words if not w.startswith("-")), None)
    parser = build_parser(first if first in COMMANDS else None)
    try:
        args, extra = parser.parse_known_args(argv)
    except SystemExit as exc:  # argparse's usage error (status 2) or --help/--version (0): a status, not an exit
        return exc.code if isinstance(exc.code, int) else 2
    if extra:  # what argparse's parse_args refuses, with the command's closest options
        prog = f"ehas {args.command}" if args.command else "ehas"
        print(f"{prog}: error: {_unknown_options(parser, args, extra)} (see {prog} --help)", file=sys.stderr)
        return 2
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
    for path in getattr(args, "controller_path", None) or []:
        from ehas_controllers.base import load_controller

        try:
            load_controller(path)
        except (ValueError, OSError) as exc:
            print(f"ehas {args.command}: error: --controller-path: {_one_line(exc)}", file=sys.stderr)
            return 2
    module = _load(args._module)
    if module is None:
        parser.error(f"command '{args.command}' is not available in this installation")
    name = f"ehas {args.command}"
    if program:
        _Stop.name = name
    import warnings

    def _show(message, category, filename, lineno, file=None, line=None):
        # a warning is one line too, in the command's name (not Python's file:line and source line)
        print(f"{name}: warning: {_one_line(message)}", file=sys.stderr if file is None else file)

    shown, warnings.showwarning = warnings.showwarning, _show
    from ehas_env.output import files as _outputs

    _outputs.begin()  # the command's outputs are placed when it succeeds; a failure leaves none (--json too)
    placed = False
    try:
        if program:
            _Stop.phase = "work"  # from here the first signal raises KeyboardInterrupt
        rc = int(module.run(args) or 0)
        placed = True
        _outputs.finish(True)
        if program:
            _Stop.phase = "done"  # the outputs are complete: a signal now ends the process at once (status 130)
        sys.stdout.flush()  # a closed pipe shows here, inside the handlers
        return rc
    except BrokenPipeError:
        raise
    except KeyboardInterrupt:
        if _Stop.depth > 1:
            raise  # nested (ehas demo running ehas size): the outer command reports it
        try:
            sys.stdout.flush()
        except (OSError, ValueError):
            pass
        _say(name)
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
        if not placed:
            _outputs.finish(False)
        if program and _Stop.phase == "work":
            _Stop.phase = "done"  # a failure: no signal raises past here (main() reports it as status 130)
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
    # run the one imported module (ehas demo imports it too), armed as the console script is
    from ehas_env.cli.main import main as _entry

    sys.exit(_entry())
