"""Importing a user's plug-in file (an effect or a controller): with a time limit, failing in one line.

A plug-in file is code by contract (docs/effects-and-controllers.md), but a
misbehaving one must not take the command with it.  :func:`import_file`

1. proves the file safe to import in a child process first (``python -c``, the same
   import and the same registration checks, within :func:`time_limit` seconds): a
   ``sys.exit``/``os._exit`` at import, an endless loop at import or in a term the
   registration check calls, or a crash of the interpreter becomes one line naming the
   file.  A file that passed is remembered by its SHA-256 (``~/.cache/ehas/plugins_ok``),
   so the check costs its ~0.1 s once per file text;
2. then imports it in this process, under a watchdog (``signal.setitimer`` in the main
   thread), turning ``SystemExit``, ``KeyboardInterrupt`` and any other exception into
   one ``ValueError`` naming the file.

``EHAS_PLUGIN_TIMEOUT`` (seconds, default 30) sets the limit.
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

ENV_TIMEOUT = "EHAS_PLUGIN_TIMEOUT"
DEFAULT_TIMEOUT = 30.0
_OK_MARK = "ehas-plugin-import-ok"


def time_limit() -> float:
    """Seconds a plug-in import may take (``EHAS_PLUGIN_TIMEOUT``, default 30)."""
    try:
        v = float(os.environ.get(ENV_TIMEOUT, DEFAULT_TIMEOUT))
        return v if 0 < v < 1e6 else DEFAULT_TIMEOUT
    except ValueError:
        return DEFAULT_TIMEOUT


def _cache_dir() -> Path:
    return Path(os.environ.get("EHAS_CACHE_DIR") or Path.home() / ".cache" / "ehas") / "plugins_ok"


class _Timeout(BaseException):
    pass


def _precheck(path: Path, digest: str, kind: str, setup: str) -> None:
    """Import ``path`` in a child process within the time limit; one-line ValueError when it cannot."""
    mark = _cache_dir() / f"{kind}-{digest}"
    if mark.exists():
        return
    limit = time_limit()
    code = (f"{setup}\nimport importlib.util, sys\n"
            f"spec = importlib.util.spec_from_file_location('ehas_plugin_check', {str(path)!r})\n"
            "m = importlib.util.module_from_spec(spec)\nsys.modules['ehas_plugin_check'] = m\n"
            "try:\n    spec.loader.exec_module(m)\nexcept Exception:\n    pass\n"  # the real import names it
            f"print({_OK_MARK!r}, flush=True)\n")
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    try:
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=limit, env=env,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise ValueError(f"{kind} file {path}: importing it did not finish within {limit:g} s (an endless loop at "
                         f"import or in a term its check calls?); {ENV_TIMEOUT} sets the limit") from None
    if _OK_MARK not in proc.stdout:
        how = f"exit status {proc.returncode}" if proc.returncode >= 0 else f"signal {-proc.returncode}"
        tail = " ".join((proc.stderr or "").strip().splitlines()[-1:])[:200]
        raise ValueError(f"{kind} file {path}: importing it ended the process ({how}{': ' + tail if tail else ''}); "
                         "a plug-in file must not call sys.exit/os._exit or end the interpreter at import")
    try:
        mark.parent.mkdir(parents=True, exist_ok=True)
        mark.write_text(str(path) + "\n")
    except OSError:  # an unwritable cache: the check runs again next time
        pass


def import_file(path, module_name: str, kind: str = "plug-in", setup: str = ""):
    """Import the Python file ``path`` as ``module_name`` (time limit, one-line errors).

    Parameters
    ----------
    path : path
        The user's ``.py`` file.
    module_name : str
        Name of the module in ``sys.modules``.
    kind : str
        What the file is (``"effect"``, ``"controller"``): the error says it.
    setup : str
        Python run in the child before the pre-check import (e.g. ``import ehas_env.physics.effects``).

    Returns
    -------
    module
        The imported module.

    Raises
    ------
    ValueError
        One line naming the file: it raised, exited, hung, or is not readable.
    """
    path = Path(path).resolve()
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{kind} file {path}: cannot be read ({exc.strerror or exc})") from None
    digest = hashlib.sha256(text).hexdigest()
    _precheck(path, digest, kind, setup)
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    limit = time_limit()
    watchdog = threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer")
    old = None
    if watchdog:
        def _raise(signum, frame):
            raise _Timeout()

        old = signal.signal(signal.SIGALRM, _raise)
        signal.setitimer(signal.ITIMER_REAL, limit)
    try:
        spec.loader.exec_module(module)
    except _Timeout:
        sys.modules.pop(module_name, None)
        raise ValueError(f"{kind} file {path}: importing it did not finish within {limit:g} s; {ENV_TIMEOUT} sets "
                         "the limit") from None
    except (SystemExit, KeyboardInterrupt) as exc:
        sys.modules.pop(module_name, None)
        raise ValueError(f"{kind} file {path}: importing it raised {type(exc).__name__}"
                         f"{'(' + repr(exc.code) + ')' if isinstance(exc, SystemExit) else ''}; a plug-in file must "
                         "not exit at import") from None
    except BaseException as exc:  # a user's file: one line naming it, whatever went wrong inside
        sys.modules.pop(module_name, None)
        text = " ".join(str(exc).split())
        raise ValueError(f"{kind} file {path}: {type(exc).__name__}: {text}"[:600]) from None
    finally:
        if watchdog:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old if old is not None else signal.SIG_DFL)
    return module
