"""A generated model's run drivers compiled to C by the system's C compiler: the same numbers as numba's, in a
fraction of its compile time.

A replay of a logged run calls one of the model's drivers -- ``closed_loop`` (``ehas_env/simulation/loops.py``)
or ``run_valve_test`` (``ehas_env/physics/integrator.py``) -- once per run.  numba compiles them, with the whole
model they call, on their first call: about 9 s for the model of the registered effects and 28 s for the one with
every structural hypothesis and block, on one core, each time a model is new to a machine.  The project's one
translator (:mod:`ehas_env.physics.c_source`) turns the very text numba compiles into C99, and the C compiler
builds it into a shared library in well under a second (gcc ``-O2``: 0.2 s and 0.6 s for those two models); the
drivers are then called through :mod:`ctypes`, which lets go of the interpreter's lock as numba's ``nogil``
drivers do, so replays still run side by side in threads.

The numbers are numba's: the C keeps Python's evaluation order and rounding (no fast-math, no contraction of a
multiply and an add into one rounding, ``-ffp-contract=off``) and calls the same C library for every ``math``
function (``tests/measurement/test_c_replays.py`` holds the replays equal to numba's, element for element).

The library is kept beside numba's cache (:func:`ehas_env.physics.codegen.cache_dir`, ``c/``), named by the
model module (whose name is the hash of its text) and the hash of this translator's, the layout's and this file's
own text, so a change to any builds it again; it is written under a temporary name and renamed, so a process
never loads a half-written library.  ``EHAS_DRIVERS=numba`` keeps numba's drivers (as does a machine without a C
compiler).

Examples
--------
>>> compiler_flags()[:3]
('-std=c99', '-O2', '-ffp-contract=off')
"""
from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import shutil
import subprocess
import threading
from pathlib import Path

import numpy as np

#: the drivers a replay calls (each also runs on numba: ``EHAS_DRIVERS=numba``)
DRIVERS = ("closed_loop", "run_valve_test")
#: the C names' prefix of the model's functions
PREFIX = "ehm_"
#: C99, optimised, every operation rounded as Python and numba round it (no fused multiply-add)
_FLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math", "-shared", "-fPIC")

_LOCK = threading.Lock()
#: {model module's name: CDrivers, or the reason it has none}
_BUILT: dict = {}


def compiler_flags() -> tuple:
    """The flags every shared library of generated C is compiled with (before the sources and ``-lm``).

    Returns
    -------
    tuple of str
    """
    return _FLAGS


def compiler() -> str | None:
    """The C compiler: ``$CC``, else ``gcc``, else ``cc`` on the path (None: none found).

    Returns
    -------
    str or None
    """
    return os.environ.get("CC") or _on_path(os.environ.get("PATH", ""))


@functools.lru_cache(maxsize=4)
def _on_path(path: str) -> str | None:
    # looked up once per PATH: every replay asks (a lookup is 0.1 ms, a replay of a run 4 ms)
    return shutil.which("gcc", path=path) or shutil.which("cc", path=path)


def compile_shared(source_path, out_path, hint: str = "") -> None:
    """Compile one C file into a shared library with :func:`compiler` and :func:`compiler_flags`.

    Parameters
    ----------
    source_path, out_path : str or Path
        The C source; the library to write.
    hint : str
        What the user may do instead, appended to the error (e.g. "--no-binary writes the sources only").

    Raises
    ------
    ValueError
        No C compiler found, or it failed (its first error line).
    """
    cc = compiler()
    tail = f"; {hint}" if hint else ""
    if not cc:
        raise ValueError(f"no C compiler found (set CC, or install gcc){tail}")
    try:
        proc = subprocess.run([cc, *_FLAGS, str(source_path), "-o", str(out_path), "-lm"], capture_output=True,
                              text=True, stdin=subprocess.DEVNULL)
    except OSError as exc:
        raise ValueError(f"the C compiler {cc} does not run ({exc.strerror or exc}); set CC to a C "
                         f"compiler{tail}") from None
    if proc.returncode != 0:
        first = next((ln for ln in proc.stderr.splitlines() if "error" in ln), " ".join(proc.stderr.split())[:200])
        raise ValueError(f"the C compiler {cc} failed (status {proc.returncode}){': ' + first if first else ''}")


def wanted() -> bool:
    """Whether replays run on the C drivers: ``EHAS_DRIVERS`` is not ``numba`` and a C compiler is found.

    Returns
    -------
    bool
    """
    return os.environ.get("EHAS_DRIVERS", "c").strip().lower() != "numba" and compiler() is not None


class CDrivers:
    """The drivers of one compiled model module, built into a shared library and loaded.

    Each driver (:data:`DRIVERS`) is an attribute called as numba's is, with the same arguments (NumPy
    ``float64`` arrays, C-ordered, written in place; numbers; an optional array left out or None).

    Parameters
    ----------
    module : module
        A generated model (:func:`ehas_env.physics.codegen.build_model`; its ``SPEC`` is translated).
    """

    def __init__(self, module):
        from ehas_env.physics.c_source import CTranslator, layout_constants, model_c

        self.module_name = module.__name__
        path = _library_path(module.__name__)
        self.signatures = {}
        if not path.exists():
            source, tr = model_c(module.SPEC, roots=DRIVERS, prefix=PREFIX, exported=DRIVERS)
            _build(source, path)
        else:  # built before (this process or another): the drivers' signatures only, no C written
            tr = CTranslator(module.SPEC.source(), layout_constants(), PREFIX)
            tr.analyse(DRIVERS)
        lib = ctypes.CDLL(str(path))
        for name in DRIVERS:
            sig = tr.signature(name)
            fn = getattr(lib, sig["c_name"])
            fn.restype = None
            fn.argtypes = _argtypes(sig)
            self.signatures[name] = sig
            setattr(self, name, _caller(name, fn, sig))


def _argtypes(sig: dict) -> list:
    out = []
    for p in sig["params"]:
        if p in sig["arrays"]:
            out += [ctypes.c_void_p, ctypes.c_long] + ([ctypes.c_long] if p in sig["arrays2d"] else [])
        else:
            out.append(ctypes.c_double)
    return out


def _caller(name: str, fn, sig: dict):
    params, arrays, two_d = sig["params"], set(sig["arrays"]), set(sig["arrays2d"])
    optional = set(sig["optional"])

    def call(*args):
        if len(args) > len(params) or len(args) < len(params) - len(optional):
            raise TypeError(f"{name} takes {len(params)} arguments ({len(args)} given)")
        cargs = []
        for p, a in zip(params, args + (None,) * (len(params) - len(args))):
            if p not in arrays:
                cargs.append(float(a))
            elif a is None:
                if p not in optional:
                    raise TypeError(f"{name}: the array {p} may not be left out")
                cargs += [None, 0]
            else:
                # written in place: the caller's own array, never a converted copy
                if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous
                        and a.ndim == (2 if p in two_d else 1)):
                    raise TypeError(f"{name}: {p} must be a C-ordered float64 array of "
                                    f"{2 if p in two_d else 1} dimension(s)")
                cargs += [a.ctypes.data, a.shape[0]] + ([a.shape[1]] if p in two_d else [])
        fn(*cargs)

    call.__name__ = name
    return call


def _library_path(module_name: str) -> Path:
    from ehas_env.physics import c_source, layout
    from ehas_env.physics.codegen import cache_dir

    h = hashlib.sha256()
    # the model's name hashes its text; the C also holds the layout's constants, the translator's and this
    # file's choices and the flags
    for part in (Path(c_source.__file__).read_bytes(), Path(layout.__file__).read_bytes(),
                 Path(__file__).read_bytes(), " ".join(_FLAGS).encode()):
        h.update(part)
    return cache_dir() / "c" / f"{module_name}_{h.hexdigest()[:16]}.so"


def _build(source: str, path: Path) -> None:
    """Compile ``source`` into ``path`` (written under a temporary name, then renamed)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.{threading.get_ident()}")
    c_file, so_file = tmp.with_suffix(".c"), tmp.with_suffix(".so")
    try:
        c_file.write_text(source)
        compile_shared(c_file, so_file)
        os.replace(so_file, path)
    finally:
        for f in (c_file, so_file):
            f.unlink(missing_ok=True)


def c_drivers(module) -> CDrivers | None:
    """The C drivers of ``module`` (built on the first call for it, then kept), or None when replays run on
    numba's (:func:`wanted` is false, or the model does not translate or compile: said once, numba's used).

    Parameters
    ----------
    module : module
        A generated model.

    Returns
    -------
    CDrivers or None
    """
    if not wanted() or getattr(module, "SPEC", None) is None:
        return None
    got = _BUILT.get(module.__name__)
    if got is None:
        with _LOCK:
            got = _BUILT.get(module.__name__)
            if got is None:
                try:
                    got = CDrivers(module)
                except (ValueError, OSError, AttributeError) as exc:
                    from ehas_env.output.progress import status

                    got = f"{exc}"
                    status(f"the model's C drivers could not be built ({got}); its replays run on numba")
                _BUILT[module.__name__] = got
    return got if isinstance(got, CDrivers) else None
