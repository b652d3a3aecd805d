"""numba's start without the scipy.linalg import it makes only to ask whether a BLAS is there.

At the first compiled call of a process numba sets up its CPU target, which
imports ``numba.np.arraymath``; that module asks once whether a BLAS is
available by importing ``scipy.linalg.cython_blas``.  The import loads all of
``scipy.linalg`` (and, through it, ``numpy.f2py``, ``unittest`` and ``pydoc``):
0.2-0.4 s of the 1.2-1.8 s that any process loading one cached numba function
takes on this project's 2-core machine (``results/compile_quiet.md``, the
rows of build ``-``).  A cached replay pays it for nothing: the answer only
decides whether numba compiles a 1-D ``np.dot`` through BLAS or as a loop, and
the model calls neither.

:func:`answer_blas_probe` gives numba the same answer by looking for the
``cython_blas`` extension file in scipy's folder instead of importing it; the
integer-width check numba runs after a successful import is run too (it reads
``scipy.__config__`` only).  Where the file is not found, or numba's internals
are not the ones this was written for (numba 0.68), numba asks in its own way.
``EHAS_NUMBA_BLAS_PROBE=import`` turns this off (the benchmark's comparison).
"""
from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import os
import sys


def _cython_blas_file_present() -> bool:
    spec = importlib.util.find_spec("scipy")     # the package's location; nothing of scipy is executed
    if spec is None or not spec.submodule_search_locations:
        return False
    suffixes = tuple(importlib.machinery.EXTENSION_SUFFIXES)
    for root in spec.submodule_search_locations:
        folder = os.path.join(root, "linalg")
        try:
            names = os.listdir(folder)
        except OSError:
            continue
        if any(n.startswith("cython_blas") and n.endswith(suffixes) for n in names):
            return True
    return False


def answer_blas_probe() -> bool:
    """Let numba's BLAS probe look for scipy's BLAS extension file instead of importing ``scipy.linalg``.

    Call before the first compiled call of the process; it imports ``numba.np.arraymath`` (which that call would
    import anyway) with the probe answered, then puts numba's own probe back for everything later (every
    ``np.linalg`` function still imports scipy's BLAS when it is compiled).

    Returns
    -------
    bool
        True when the probe was answered this way; False when numba had already set up its arrays' functions,
        the switch is off, or numba's internals differ (numba then probes in its own way).
    """
    if os.environ.get("EHAS_NUMBA_BLAS_PROBE", "") == "import" or "numba.np.arraymath" in sys.modules:
        return False
    try:
        import numba.np.linalg as linalg
    except ImportError:
        return False
    original = getattr(linalg, "ensure_blas", None)
    check_width = getattr(linalg, "_check_lapack_int_width", None)
    if original is None or check_width is None:
        return False

    def probe():
        if _cython_blas_file_present():
            check_width()
        else:
            original()   # no file where it should be: numba's own import decides (and raises ImportError)

    linalg.ensure_blas = probe
    try:
        importlib.import_module("numba.np.arraymath")  # its import runs the probe once, with the answer above
    finally:
        linalg.ensure_blas = original
    return True
