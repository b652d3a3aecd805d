"""The fast-step build compiled behind a quicker one: an environment's first step in seconds.

The inlined build (:func:`ehas_env.physics.codegen.build_model`, ``inline=True``) steps fastest and takes
the longest to compile (tens of seconds of CPU for a new set of effects).  :class:`FastBuildBehind` lets a
caller start at once on the *interpreted* build -- the same generated text run as plain Python, the same
numbers bit for bit -- while a separate process (``python -m ehas_env.physics.compile_behind``) compiles the
inlined build's entry points into numba's cache, on the other core.  When that process is done, a thread
of the caller loads the compiled functions from the cache and the caller switches to them between two calls.

What is compiled is said by the calls themselves: the entry points' names and one set of example
arguments (the caller's own arrays and numbers, copied), written as a ``.npz`` beside the generated module
(data: read back with ``allow_pickle=False``).  The child imports the generated module from its file --
named by the hash of its text, so a stale cache can never run -- compiles each entry point for the numba
types of those arguments (nothing is run; numba caches it beside the file) and then writes one marker per
entry point, ``<module>.<entry>.ready``.  A later process whose markers are all there loads the inlined
build at once.  One child per module at a time: a ``<module>.compiling`` file holds its process id; the
others wait for its markers.  A child that fails leaves its log, ``<module>.compile.log``; the caller then
compiles in its own process, as before, and says so.

Examples
--------
>>> from pathlib import Path
>>> from ehas_env.physics.compile_behind import ready_path
>>> ready_path(Path("models/ehas_model_0123456789abcdef.py"), "single_step").name
'ehas_model_0123456789abcdef.single_step.ready'
"""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from ehas_env.output.files import atomic_write_text
from ehas_env.output.progress import status
from ehas_env.physics import codegen

#: seconds between two looks at the background process (a look is a few microseconds; a step can be faster)
POLL_S = 0.25
#: a ``.compiling`` file older than this is taken as left by a process that died (s)
STALE_LOCK_S = 1800.0
_OURS: set[int] = set()  # process ids of the background compiles this process started
_TOLD: set[tuple] = set()  # (module file, process id) pairs a message already named: said once per process


def ready_path(module_file: Path, entry: str) -> Path:
    """The marker saying ``entry`` of the generated module in ``module_file`` is in numba's cache.

    Parameters
    ----------
    module_file : Path
        The generated module's file (``<cache dir>/ehas_model_<hash>.py``; numba's cache is beside it).
    entry : str
        One of its compiled functions.

    Returns
    -------
    Path
        ``<folder>/<module name>.<entry>.ready``.
    """
    return module_file.with_name(f"{module_file.stem}.{entry}.ready")


def is_ready(module_file: Path, entries) -> bool:
    """True when every entry point of ``entries`` has its ready marker (see :func:`ready_path`).

    Parameters
    ----------
    module_file : Path
        The generated module's file.
    entries : iterable of str
        Entry point names.

    Returns
    -------
    bool
        Whether all the markers exist.
    """
    return all(ready_path(module_file, e).exists() for e in entries)


def _beside(module_file: Path, suffix: str) -> Path:
    return module_file.with_name(module_file.stem + suffix)


def _lock_alive(path: Path) -> bool:
    """True when ``path`` names a process still running and is not older than STALE_LOCK_S."""
    try:
        pid = int(path.read_text().strip() or "0")
        age = time.time() - path.stat().st_mtime
    except (OSError, ValueError):
        return False
    if pid <= 0 or age > STALE_LOCK_S:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _copy(a):
    """A copy of the argument ``a`` of the same numba type (an array keeps its read-only flag)."""
    if not isinstance(a, np.ndarray):
        return a
    c = np.ascontiguousarray(a).copy()
    c.flags.writeable = a.flags.writeable
    return c


def _pack_args(calls: list) -> dict:
    """``[(entry, args), ...]`` as named arrays for ``np.savez``: ``<call>|<entry>|<k>|<w, r or n>`` is argument k of
    call number ``call`` (a number as a 0-d array; ``r``: a read-only array, a type of its own for numba; ``n``: None,
    an optional argument left out, compiled as its default)."""
    out = {}
    for i, (entry, args) in enumerate(calls):
        for k, a in enumerate(args):
            if a is None:  # an optional argument left out: its default's type (numba's Omitted)
                out[f"{i}|{entry}|{k}|n"] = np.asarray(0.0)
                continue
            if isinstance(a, np.ndarray):
                v = a
            elif isinstance(a, (bool, np.bool_)):
                v = np.asarray(bool(a))
            elif isinstance(a, (int, np.integer)):
                v = np.asarray(a, np.int64)
            elif isinstance(a, (float, np.floating)):
                v = np.asarray(a, np.float64)
            else:
                raise TypeError(f"compile_behind: argument {k} of {entry} is a {type(a).__name__}; "
                                "allowed: numpy arrays, bool, int, float")
            ro = "r" if isinstance(a, np.ndarray) and not a.flags.writeable else "w"
            out[f"{i}|{entry}|{k}|{ro}"] = v
    return out


def _unpack_args(data) -> list:
    """The inverse of :func:`_pack_args`: ``[(entry, [args in order]), ...]`` (0-d arrays back to numpy scalars)."""
    calls: dict[tuple, dict[int, object]] = {}
    for key in data.files:
        i, entry, k, ro = key.split("|")
        a = data[key]
        if ro == "n":
            v = None
        elif a.ndim == 0:
            v = a[()]
        else:
            v = np.ascontiguousarray(a)
            v.flags.writeable = ro == "w"
        calls.setdefault((int(i), entry), {})[int(k)] = v
    return [(entry, [by_k[k] for k in sorted(by_k)]) for (_, entry), by_k in sorted(calls.items())]


def _compile_all(module, calls: list) -> None:
    """Compile each entry point of ``module`` for the types of its example arguments, or load it from numba's
    cache (nothing is run: the arguments' values do not matter)."""
    from numba import typeof, types

    for entry, args in calls:
        getattr(module, entry).compile(tuple(types.Omitted(None) if a is None else typeof(a) for a in args))


def _estimate(build: str, kb: float | None = None) -> str:
    """How long the background compile of ``build`` (``kb`` kilobytes of new text, when known) should take now,
    as a range: the quiet CPU figure (:func:`~ehas_env.physics.codegen.quiet_compile_s`) scaled by the square root
    of the run queue per core (the project's compile estimate) up to the run queue per core itself (a process that
    gets its share of the cores and no more: measured 272 s for 36.2 s of CPU at 11 runnable processes per core,
    results/first_step.md)."""
    low = codegen.compile_estimate_s(build, kb)
    high = codegen.quiet_compile_s(build, kb) * codegen.load_scale() ** 2
    return f"about {low:.0f} s" if high < 1.2 * low else f"about {low:.0f}-{high:.0f} s"


class FastBuildBehind:
    """A quicker build now, the inlined (fast-step) build as soon as a background process compiled it.

    Parameters
    ----------
    fast : module
        The inlined build (:func:`~ehas_env.physics.codegen.build_model` with ``inline=True``).
    meanwhile : module
        The build to run until then: the interpreted build of the same effects and laws (``interpreted=True``:
        no compile, a slow step) or the quick build (``inline=False``: compiled in seconds, a step a few
        times slower; what a benchmark grid runs meanwhile).
    calls : dict or list of (str, tuple)
        ``{entry point name: example arguments}`` or ``[(entry point name, example arguments), ...]`` (an
        entry point called with arguments of several types: one pair each): the functions the caller runs and
        arguments of the types it passes (numpy arrays -- read-only ones are a type of their own -- bool, int,
        float); they are copied, never changed.
    what : str
        What runs on the build, for the messages ("the environment's step").
    estimate : str
        The key of :data:`~ehas_env.physics.codegen.COMPILE_CPU_S` whose figure the message's estimate scales.
    meanwhile_name : str
        How the messages call the ``meanwhile`` build.
    fast_name : str
        How the messages call the ``fast`` build.
    kb : float, optional
        Kilobytes of new generated text the compile covers (the estimate grows with it).

    Attributes
    ----------
    model : module
        The build to call now: ``fast`` when it is ready, else ``meanwhile``; :meth:`poll` updates it.
    """

    def __init__(self, fast, meanwhile, calls, what: str = "the environment's step", estimate: str = "inline",
                 meanwhile_name: str = "interpreted build (same numbers, slower step)",
                 fast_name: str = "fast-step build", kb: float | None = None):
        self.fast = fast
        self.meanwhile = meanwhile
        self.meanwhile_name = meanwhile_name
        self.fast_name = fast_name
        self.estimate = estimate
        self.kb = kb
        self.what = what
        pairs = calls.items() if isinstance(calls, dict) else calls
        self._calls = [(e, tuple(_copy(a) for a in args)) for e, args in pairs]
        self._entries = sorted({e for e, _ in self._calls})
        self._file = Path(fast.__file__)
        self._proc = None
        self._thread = None
        self._error: BaseException | None = None
        self._next = 0.0
        self._t0 = time.monotonic()
        if is_ready(self._file, self._entries):
            self.model = fast  # numba loads it from its cache on the first call
            self.done = True
            return
        self.model = meanwhile
        self.done = False
        self._start()

    # -- the background process -------------------------------------------
    def _start(self) -> None:
        lock = _beside(self._file, ".compiling")
        est = _estimate(self.estimate, self.kb)
        if lock.exists() and _lock_alive(lock):
            try:
                pid = int(lock.read_text().strip() or "0")
            except (OSError, ValueError):
                pid = 0
            if pid in _OURS or (self._file, pid) in _TOLD:
                return  # already said: environments made by the hundred (validation, evaluation) say it once
            _TOLD.add((self._file, pid))
            status(f"{self.what} runs on the {self.meanwhile_name} while another process compiles the "
                   f"{self.fast_name} ({est} at this machine's load); it switches when that is done")
            return
        lock.unlink(missing_ok=True)
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:  # another process took it just now: wait for its markers
            return
        except OSError as exc:
            self._give_up(f"could not start the background compile ({exc})")
            return
        args = _beside(self._file, f".{os.getpid()}.args.npz")
        log = _beside(self._file, ".compile.log")
        try:
            np.savez(args, **_pack_args(self._calls))
            with open(log, "w") as out:
                env = {**os.environ, "EHAS_QUIET_COMPILE": "1"}
                self._proc = subprocess.Popen(
                    [sys.executable, "-m", "ehas_env.physics.compile_behind", str(self._file), str(args), str(lock)],
                    stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT, env=env)
            os.write(fd, str(self._proc.pid).encode())
            _OURS.add(self._proc.pid)
        except OSError as exc:
            os.close(fd)
            lock.unlink(missing_ok=True)
            self._give_up(f"could not start the background compile ({exc})")
            return
        os.close(fd)
        status(f"{self.what} runs on the {self.meanwhile_name} while its {self.fast_name} "
               f"compiles in a background process ({est} at this machine's load; log {log}); it "
               "switches when that is done")

    def _give_up(self, why: str) -> None:
        status(f"{why}; compiling the {self.fast_name} here")
        self.model = self.fast
        self.done = True

    def _load(self) -> None:
        try:
            _compile_all(self.fast, self._calls)
        except BaseException as exc:  # noqa: BLE001 -- said by poll(), in the caller's thread
            self._error = exc

    # -- the caller's side ------------------------------------------------------
    def compiled_behind(self) -> bool:
        """True when the background process compiled every entry point (their markers are there), False when
        the caller compiles them itself (it gave up) or it has not finished.

        Returns
        -------
        bool
        """
        return is_ready(self._file, self._entries)

    def poll(self):
        """The build to call now (switches to the fast one once it is compiled and loaded).

        Returns
        -------
        module
            ``self.model``.
        """
        if self.done:
            return self.model
        now = time.monotonic()
        if now < self._next:
            return self.model
        self._next = now + POLL_S
        if self._thread is None:
            if self._proc is not None:
                rc = self._proc.poll()
                if rc is None:
                    return self.model
                self._proc = None
                if rc != 0 or not is_ready(self._file, self._entries):
                    self._give_up(f"the background compile stopped with exit status {rc} (log "
                                  f"{_beside(self._file, '.compile.log')})")
                    return self.model
            elif not is_ready(self._file, self._entries):
                if not _lock_alive(_beside(self._file, ".compiling")):  # the other process is gone without markers
                    self._start()
                    if self._proc is None and not self.done and not _lock_alive(_beside(self._file, ".compiling")):
                        self._give_up("no background compile could start")
                return self.model
            self._thread = threading.Thread(target=self._load, name="ehas-load-fast-build", daemon=True)
            self._thread.start()
            return self.model
        if self._thread.is_alive():
            return self.model
        if self._error is not None:
            self._give_up(f"loading the {self.fast_name} failed ({type(self._error).__name__}: {self._error})")
            return self.model
        self.model = self.fast
        self.done = True
        if (self._file, "switched") in _TOLD:
            return self.model
        _TOLD.add((self._file, "switched"))
        status(f"{self.what} switched to the {self.fast_name} ({time.monotonic() - self._t0:.0f} s after it started "
               f"on the {self.meanwhile_name.split(' (')[0]})")
        return self.model

    def wait(self, timeout: float | None = None):
        """Block until the fast build is in use (or ``timeout`` seconds passed).

        Parameters
        ----------
        timeout : float, optional
            Seconds to wait at most (None: until it is).

        Returns
        -------
        module
            The build in use afterwards.
        """
        end = None if timeout is None else time.monotonic() + timeout
        while True:  # one look at least, even with timeout 0
            self._next = 0.0
            self.poll()
            if self.done or (end is not None and time.monotonic() >= end):
                return self.model
            time.sleep(0.05)


def main(argv=None) -> int:
    """The background process: compile the entry points of one generated module, then write their markers.

    Parameters
    ----------
    argv : list of str, optional
        ``MODULE_FILE ARGS_NPZ LOCK_FILE`` (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 when every entry point compiled, 1 otherwise.
    """
    import importlib.util
    import signal

    module_file, args_file, lock_file = [Path(a) for a in (argv if argv is not None else sys.argv[1:])]
    if argv is None:  # the background process: ended by its caller, it still removes its lock and arguments
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    try:
        with np.load(args_file, allow_pickle=False) as data:
            calls = _unpack_args(data)
        name = module_file.stem
        # a model of several generated modules (the quick build) imports the others by name, from its folder
        sys.path.insert(0, str(module_file.parent))
        spec = importlib.util.spec_from_file_location(name, module_file)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        t0 = time.process_time()
        _compile_all(module, calls)
        for entry in sorted({e for e, _ in calls}):
            atomic_write_text(ready_path(module_file, entry), f"compiled in {time.process_time() - t0:.1f} s of CPU\n")
        print(f"compiled {', '.join(sorted({e for e, _ in calls}))} of {name} in {time.process_time() - t0:.1f} s of CPU", flush=True)
        return 0
    except Exception as exc:  # noqa: BLE001 -- the log says it; the caller compiles in its own process
        print(f"background compile failed: {type(exc).__name__}: {exc}", flush=True)
        return 1
    finally:
        args_file.unlink(missing_ok=True)
        lock_file.unlink(missing_ok=True)


if __name__ == "__main__":
    sys.exit(main())
