"""The compiled model: baseline + effects' terms + drivers, generated into real modules.

The plant is defined once: the baseline's pieces in :mod:`ehas_env.physics.baseline`,
each effect's terms in its own file (static methods named after the places of
:data:`~ehas_env.physics.effects.base.PLACES`), each compiled controller's law in
its own file.  This module writes them, with the assembled right-hand side
(``valve_current``, ``derivatives``, ``project``, ``measure``) and the compiled
parts that drive it (the one RK4 integrator, the open/closed-loop drivers and the
valve bench, the environment's step), into Python files named by the hash of
their text, then imports them.  numba compiles their functions on first use and
caches them beside them.  Two builds of the same text:

* ``inline`` (the environments, the batched kernel, benchmark grids): one file,
  everything a step runs inlined into one compiled body (no function pointers:
  numba first-class function tuples cost ~75 % more per step here);
* ``quick`` (every :class:`~ehas_env.simulation.plant.Plant`: replay, fits, single
  runs): linked modules -- the library (baseline and the functions no effect
  changes), one per effect's terms, one for the controller laws, and the model
  (assembled right-hand side and drivers) importing them -- each compiled once
  and called.  A new user effect compiles its own terms and the model module;
  the library and every other effect load from numba's cache;
* ``interpreted`` (an environment's first steps while the inlined build compiles in a background process, see
  :mod:`ehas_env.physics.compile_behind`): the inlined build's very text run as plain Python, ``njit`` replaced by
  a stand-in that returns the function -- nothing to compile, the same numbers bit for bit, about a hundred times
  slower a step (2,455 against 246,862 environment steps per CPU-second, results/first_step.md).

In both, a changed effect file, a new user effect or a new controller law gives
a new text, hence a new file and a fresh compile -- a stale cache can never run;
every simulator of the project (single env, batched env, benchmark, replay of
logs, valve bench, linearisation) runs the same functions.

Effects that are part of a model but switched off in a row of parameters are
skipped by their ``<effect>.on`` slot, so one model serves plants with any
subset of its effects (domain randomisation over effects needs this).

Examples
--------
>>> from ehas_env.physics.codegen import build_model
>>> from ehas_env.simulation.control_laws import all_laws
>>> m = build_model(laws=all_laws(), inline=False)
>>> m.STATE_NAMES[:3], "coulomb_friction.Fc" in m.IDX
(('theta', 'omega', 'qc'), True)
"""
from __future__ import annotations

import importlib.util
import json
import os
import statistics
import sys
import threading
from pathlib import Path

from ehas_env.physics.model_source import ModelSource, _digest, _header

_MODELS: dict[str, object] = {}  # by the generated model's module name (the hash of its text)
_BY_PARTS: dict[tuple, object] = {}  # by the effect classes and law functions it was made from


def cache_dir() -> Path:
    """Where generated models live: ``$EHAS_CACHE_DIR`` or ``~/.cache/ehas/models``."""
    env = os.environ.get("EHAS_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "ehas" / "models"


_BUILD_LOCK = threading.RLock()
#: the numba import of every generated module's header, and what the interpreted build has in its place
NUMBA_IMPORT = "from numba import njit, prange\n"
INTERPRETED_STANDINS = '''
# ---- the interpreted build: numba's njit and prange, and math as numba runs it ----------------------------------
import math as _math


def njit(*args, **options):
    """Stand-in for numba.njit: the function itself, run by Python (a function called from outside, not inlined,
    runs with numpy's floating-point warnings off: numba's compiled code has none)."""
    def make(fn):
        if options.get("inline") == "always":
            return fn

        def entry(*a):
            with np.errstate(all="ignore"):
                return fn(*a)
        entry.__name__, entry.__doc__, entry.__wrapped__ = fn.__name__, fn.__doc__, fn
        return entry
    return make(args[0]) if args and callable(args[0]) else make


prange = range


class _IEEEMath:
    """``math`` as numba's compiled code runs it: a domain error or an overflow gives nan or inf (numpy's
    function of the same name), not Python's exception."""

    def __init__(self):
        for name in dir(_math):
            if not name.startswith("_"):
                f, g = getattr(_math, name), getattr(np, name, None)
                setattr(self, name, self._ieee(f, g) if callable(f) and callable(g) else f)

    @staticmethod
    def _ieee(f, g):
        def call(*args):
            try:
                return f(*args)
            except (ValueError, OverflowError):
                with np.errstate(all="ignore"):
                    return float(g(*args))
        return call


math = _IEEEMath()
'''


def build_model(effects=None, laws=(), inline: bool = True, interpreted: bool = False):
    """The compiled model module of ``effects`` and the controller ``laws``.

    Writes the generated file on first use (atomically) and imports it; later
    calls with the same text return the loaded module.

    Parameters
    ----------
    effects : list of Effect classes, optional
        The effects the model holds (default: every registered effect).
    laws : sequence of (name, function)
        The compiled controller laws, numbered in this order (the simulation layer's registry,
        :func:`ehas_env.simulation.control_laws.all_laws`, gives them).
    inline : bool
        Inline every model function into the drivers (fastest step, longest compile) or compile each once.
    interpreted : bool
        The inlined build's text run as plain Python (``inline`` is then ignored): no compile, the same
        numbers, a slow step (an environment's first steps while its fast build compiles behind it).

    Returns
    -------
    module
        The generated model module.
    """
    with _BUILD_LOCK:  # a second thread must not take a module the first is still writing or importing
        return _build_model(effects, laws, "interpreted" if interpreted else ("inline" if inline else "quick"))


def _build_model(effects, laws, build: str):
    from ehas_env.physics.effects import REGISTRY
    from ehas_env.physics.numba_start import answer_blas_probe

    answer_blas_probe()  # before the model's first compiled call: numba's start without importing scipy.linalg
    effects = list(REGISTRY.values()) if effects is None else list(effects)
    laws = list(laws)
    # the same classes and laws give the same text: skip regenerating it (every Plant asks for its model)
    key = (tuple(effects), tuple(laws), build)
    if key in _BY_PARTS:
        return _BY_PARTS[key]
    spec = ModelSource(effects, laws)
    if build == "inline":
        text = spec.source()
        mods = [(f"ehas_model_{_digest(text)}", text)]
    elif build == "interpreted":
        text, head = spec.source(), _header("one compiled model")
        if not text.startswith(head) or NUMBA_IMPORT not in head:
            raise RuntimeError("the generated model does not start with the header whose numba import it replaces")
        text = head.replace(NUMBA_IMPORT, "") + INTERPRETED_STANDINS + text[len(head):]
        mods = [(f"ehas_py_{_digest(text)}", text)]
    else:
        mods = spec.modules()
    name = mods[-1][0]
    if name in _MODELS:
        _BY_PARTS[key] = _MODELS[name]
        return _MODELS[name]
    fresh = []
    for dep, text in mods:  # the library, effects and laws first: the model imports them by name
        module = _load(dep, text, fresh)
    if fresh and build != "interpreted" and os.environ.get("EHAS_QUIET_COMPILE") != "1":
        # announced when numba starts compiling them (numba compiles lazily)
        if build == "quick":
            build = "quick" if fresh[0].startswith("ehas_lib_") else "quick, library cached"
        _watch_compiles(fresh, build)
    module.SPEC = spec
    _MODELS[name] = module
    _BY_PARTS[key] = module
    return module


def _load(name: str, text: str, fresh: list):
    """The generated module ``name`` (already imported, or written beside numba's cache and imported; its name
    is appended to ``fresh`` when this process wrote its file)."""
    if name in sys.modules:
        return sys.modules[name]
    folder = cache_dir()
    path = folder / f"{name}.py"
    if not path.exists() or path.read_text() != text:
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / f".{name}.{os.getpid()}.tmp"
        tmp.write_text(text)
        os.replace(tmp, path)
        fresh.append(name)
    mspec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(mspec)
    sys.modules[name] = module
    try:
        mspec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


#: measured CPU seconds to compile what a command first runs of each build (results/compile.md, compile_quiet.md;
#: the environment's step alone: results/first_step.md; a benchmark grid's driver alone: the "inline" figure)
COMPILE_CPU_S = {"inline": 90.0, "quick": 16.0, "quick, library cached": 9.0,
                 "inline, environment step": 36.0, "inline, benchmark grid": 90.0}
#: measured CPU seconds a kilobyte of freshly generated text takes to compile, by build: a model's compile grows with
#: the text it compiles (a quick build of the registered effects, 58.7 kB: 7.9 s; with the diagnosis' hypotheses and
#: blocks, 229 kB of new effect and model modules over a cached library: 27.6 s, where the seconds of
#: :data:`COMPILE_CPU_S` say 9; both at load 1.3-1.4 a core, divided by :func:`load_scale`; 2026-12-02).  Used for
#: the announced compile of a model whose text size is known; this machine's record of its own rates wins
COMPILE_CPU_S_PER_KB = {"quick": 0.117, "quick, library cached": 0.101}
#: the record's key of a build's per-kilobyte rates (:data:`COMPILE_RECORD`)
PER_KB = " per kB"
#: the compiled functions whose first compile compiles the whole model (its right-hand side ``derivatives`` and what
#: calls it): only such a compile is announced with the size-based estimate and recorded; a first call of another
#: (``reference_series``, a sensor chain read in Python) compiles a small part -- the replays of a diagnosis run on
#: the C drivers (:mod:`ehas_env.physics.c_drivers`), so only such parts of its models compile, in a fraction of
#: a second -- and is said only if it takes longer than :data:`HEARTBEAT_S`
WHOLE_MODEL = frozenset({"derivatives", "rates", "rk4_substep", "advance", "run_open_loop", "run_valve_test",
                         "closed_loop", "closed_loop_batch", "run_relay", "single_reset", "single_step",
                         "batch_reset", "batch_step_serial", "batch_step_parallel"})
_WATCH = {"depth": 0, "start": 0.0, "name": "", "thread": None, "est": 0.0, "build": None, "scale": 1.0,
          "mods": set(), "spent": 0.0, "going": False, "first": False, "kb": None}
HEARTBEAT_S = 10.0
_FRESH: dict[str, tuple] = {}  # modules written by this process, not yet compiled: (build, their model's module)


def compile_estimate_s(build: str, kb: float | None = None) -> float:
    """Seconds a first compile of ``build`` should take now: the quiet figure scaled by the load.

    Parameters
    ----------
    build : {"inline", "quick", "quick, library cached", "inline, environment step"}
        The build (see :func:`build_model`); "quick, library cached": a new effect set whose library module
        numba already holds (only the effects' terms and the assembled model compile); "inline, environment
        step": the inlined build's ``single_reset`` and ``single_step`` alone (what an environment compiles);
        "inline, benchmark grid": its ``closed_loop_batch`` alone (what a benchmark grid compiles).
    kb : float, optional
        Kilobytes of generated text the compile covers (:func:`quiet_compile_s`).

    Returns
    -------
    float
        :func:`quiet_compile_s` times the square root of the run queue per core when above one.
    """
    return quiet_compile_s(build, kb) * load_scale()


#: the file in :func:`cache_dir` holding this machine's measured compile times: ``{build: [s, ...]}`` (the last
#: :data:`COMPILE_KEPT` of each build, each its wall time over :func:`load_scale` at its start)
COMPILE_RECORD = "compile_times.json"
COMPILE_KEPT = 5


def quiet_compile_s(build: str, kb: float | None = None) -> float:
    """A quiet machine's seconds for a first compile of ``build``: the median of this machine's last compiles of
    it (:data:`COMPILE_RECORD`), else :data:`COMPILE_CPU_S`'s figure; for a compile of ``kb`` kilobytes of
    generated text, that size times the median of this machine's last rates per kilobyte of the build, else
    :data:`COMPILE_CPU_S_PER_KB`'s (a build without a measured rate: its seconds, as without ``kb``).

    The figures of :data:`COMPILE_CPU_S` were measured once for one kind of model (results/compile.md); a model
    whose effects add states compiles more (a coil lag's: 37 CPU s where the table says 9; the diagnosis' model,
    229 kB of new text, 23 s), so the size of what compiles and the machine's own record of what its compiles
    took are the better guess.

    Parameters
    ----------
    build : str
        A key of :data:`COMPILE_CPU_S`.
    kb : float, optional
        Kilobytes of newly generated text the compile covers.

    Returns
    -------
    float

    Examples
    --------
    >>> import os, tempfile
    >>> before = os.environ.get("EHAS_CACHE_DIR")
    >>> os.environ["EHAS_CACHE_DIR"] = tempfile.mkdtemp()  # no record yet: the tables
    >>> quiet_compile_s("quick, library cached"), round(quiet_compile_s("quick, library cached", kb=229.0), 1)
    (9.0, 23.1)
    >>> quiet_compile_s("inline", kb=100.0)  # no rate per kB measured for this build: its seconds
    90.0
    >>> _ = os.environ.pop("EHAS_CACHE_DIR") if before is None else os.environ.update(EHAS_CACHE_DIR=before)
    """
    record = _record()
    rates = record.get(build + PER_KB)
    if kb is not None and (rates or build in COMPILE_CPU_S_PER_KB):
        return float(kb) * (statistics.median(rates) if rates else COMPILE_CPU_S_PER_KB[build])
    seen = record.get(build)
    return statistics.median(seen) if seen else COMPILE_CPU_S[build]


def _record() -> dict:
    """This machine's record of its compiles (:data:`COMPILE_RECORD`): {key: [figures]}, the figures that are
    plausible only; empty when there is none or it cannot be read."""
    try:
        doc = json.loads((cache_dir() / COMPILE_RECORD).read_text())
        return {k: kept for k, v in doc.items() if isinstance(v, list)
                and (kept := [float(x) for x in v if isinstance(x, (int, float)) and 0.0 < x < 1e5])}
    except (OSError, ValueError, AttributeError):
        return {}


def record_compile_s(build: str, seconds: float, new: bool = True) -> None:
    """Add one measured compile of ``build`` (seconds at a quiet machine's pace) to this machine's record, keeping
    the last :data:`COMPILE_KEPT` (``new=False``: the figure replaces the last one, a model's compile that went on
    in another of its functions); a record that cannot be written is left as it was (the estimate is a guess)."""
    path = cache_dir() / COMPILE_RECORD
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        doc = {}  # none yet, or not readable: started again
    try:
        if not isinstance(doc, dict):
            doc = {}
        kept = [float(x) for x in doc.get(build) or [] if isinstance(x, (int, float))]
        doc[build] = ((kept if new or not kept else kept[:-1]) + [float(f"{float(seconds):.4g}")])[-COMPILE_KEPT:]
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
        os.replace(tmp, path)
    except (OSError, ValueError, TypeError):
        pass


def load_scale() -> float:
    """Wall seconds per CPU second to expect now: the square root of the run queue per core when above one.

    Measured: wall / CPU of a compile was ~1.5 at 2.5-3.5 runnable processes per core (results/compile.md), far
    below the run queue's share: other jobs are not always runnable.

    Returns
    -------
    float
        At least 1.
    """
    try:
        load = os.getloadavg()[0] / max(1, os.cpu_count() or 1)
    except OSError:
        load = 1.0
    return max(1.0, load) ** 0.5


def take_fresh(module) -> tuple[str, float | None, list] | None:
    """The build and the kilobytes of new generated text of ``module``'s model, when this process wrote its files
    and numba has not compiled them yet, taken off the compile watcher's list: their compile runs in another
    process, which is announced there (:class:`ehas_env.physics.compile_behind.FastBuildBehind`), and a load of
    what it compiled is no compile to announce or record here.  None when there is no such text (the files were
    there before: numba's cache may hold the model).

    Parameters
    ----------
    module : module
        A generated model module (:func:`build_model`).

    Returns
    -------
    (str, float or None, list of str) or None
        (build, kB, the modules taken): :func:`put_fresh` gives them back.
    """
    mods = [m for m, (_, of) in _FRESH.items() if of == module.__name__]
    if not mods:
        return None
    build = _FRESH[mods[0]][0]
    kb = _text_kb(mods)
    for m in mods:
        del _FRESH[m]
    return build, kb, mods


def put_fresh(module, taken: tuple) -> None:
    """Give back to the compile watcher what :func:`take_fresh` took of ``module``'s model, ``taken`` (the
    background compile gave up: it compiles here, announced and recorded as any first compile of this process)."""
    build, _, mods = taken
    _FRESH.update(dict.fromkeys(mods, (build, module.__name__)))


def _text_kb(modules) -> float | None:
    """Kilobytes of the generated files of ``modules`` (names of imported modules); None when one has no file."""
    try:
        return sum(os.path.getsize(sys.modules[m].__file__) for m in modules) / 1000.0
    except (KeyError, TypeError, OSError):
        return None


def _watch_compiles(modules: list, build: str) -> None:
    """Announce the first compile of the new generated ``modules`` (one model's) and print a line every HEARTBEAT_S while
    numba compiles (numba's compile events say when it does; a cached function's load is one too, hence only
    modules whose file was just written are announced)."""
    import threading
    import time

    from numba.core import event

    _FRESH.update(dict.fromkeys(modules, (build, modules[-1])))
    if _WATCH["thread"] is not None:
        return

    class _Listener(event.Listener):
        def on_start(self, ev):
            fn = getattr(ev.data.get("dispatcher"), "py_func", None)
            if _WATCH["depth"] == 0:
                _WATCH["start"] = time.monotonic()
                _WATCH["name"] = getattr(fn, "__name__", "?")
                mod = getattr(fn, "__module__", "")
                if mod in _WATCH["mods"]:  # the announced model compiles another of its functions: still its time
                    _WATCH["going"] = True
                if mod in _FRESH and _WATCH["name"] not in WHOLE_MODEL:
                    _WATCH["est"] = None  # a part of a new model: not announced, not recorded (the heartbeat stays)
                elif mod in _FRESH:
                    build, model = _FRESH[mod]
                    mods = [m for m, (_, of) in _FRESH.items() if of == model]
                    for m in mods:  # one line for one model
                        del _FRESH[m]
                    kb = _text_kb(mods)
                    _WATCH["est"] = compile_estimate_s(build, kb)
                    _WATCH.update(build=build, scale=load_scale(), mods=set(mods), spent=0.0, going=True,
                                  first=True, kb=kb)
                    what = "fast-step build" if build == "inline" else f"{build} build"
                    print(f"ehas: compiling the simulator for this set of effects and controllers ({what}, "
                          f"{_WATCH['name']}; first run only; about {_WATCH['est']:.0f} s at this machine's load)",
                          file=sys.stderr, flush=True)
            _WATCH["depth"] += 1

        def on_end(self, ev):
            _WATCH["depth"] = max(0, _WATCH["depth"] - 1)
            if _WATCH["depth"] == 0 and _WATCH["going"]:
                # an announced model's compile (all its functions compiled so far: one figure) ended: what it
                # took, kept for the next estimate of its build
                _WATCH["spent"] += (time.monotonic() - _WATCH["start"]) / _WATCH["scale"]
                record_compile_s(_WATCH["build"], _WATCH["spent"], new=_WATCH["first"])
                if _WATCH["kb"]:  # and its rate per kilobyte of the text it compiled
                    record_compile_s(_WATCH["build"] + PER_KB, _WATCH["spent"] / _WATCH["kb"], new=_WATCH["first"])
                _WATCH["going"] = _WATCH["first"] = False

    def beat():
        said = 0  # heartbeats printed for the compile under way
        while True:
            time.sleep(1.0)
            if _WATCH["depth"] == 0:
                said = 0
                continue
            spent = time.monotonic() - _WATCH["start"]
            if spent >= (said + 1) * HEARTBEAT_S:
                said = int(spent // HEARTBEAT_S)
                est = "" if _WATCH["est"] is None else f", about {_WATCH['est']:.0f} s in all"
                print(f"ehas: still compiling the simulator ({_WATCH['name']}): {spent:.0f} s so far{est}",
                      file=sys.stderr, flush=True)

    event.register("numba:compile", _Listener())
    _WATCH["thread"] = threading.Thread(target=beat, name="ehas-compile-heartbeat", daemon=True)
    _WATCH["thread"].start()
