"""The Python -> C translator (ehas_env/physics/c_source.py): the C it writes computes what Python computes
(the same text run by the interpreter is the independent truth), and every effect of the library translates."""
from __future__ import annotations

import ctypes
import shutil
import subprocess

import numpy as np
import pytest

from ehas_env.physics.c_source import TranslationError, model_c, translate

CC = shutil.which("gcc") or shutil.which("cc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler on this machine")

TEXT = '''
import math

def pair(a, b):
    return a % b, a // b

def helper(x, k):
    return x * k if x > 0.0 else -x

def f(x, y, arr, out):
    """Python's meaning where C's differs: %, //, /, min/max, chained comparisons, tuples, loops."""
    q, r = pair(x, y)
    n = 0
    for j in range(3):
        n += j
    i = 7 // 2
    s = 0.0
    for v in (1, 2.5, -3):
        s += v * arr[n % arr.shape[0]]
    out[0] = q
    out[1] = r
    out[2] = n / 4
    out[3] = min(x, y, 0.5) + max(abs(x), 2)
    out[4] = 1.0 if -1.0 < x <= 2.0 < y else 0.0
    out[5] = s + i
    k = 0
    while k < 5 and x > -100.0:
        k += 1
        x -= 0.5
    out[6] = x + k + math.copysign(2.0, y) + math.degrees(0.1)
    out[7] = helper(y, 3) + pair(y, 1.5)[1] + arr[-1]
    return out[0] + out[7]
'''


def compile_lib(code, tmp_path, name="t"):
    src = tmp_path / f"{name}.c"
    src.write_text(code)
    lib = tmp_path / f"lib{name}.so"
    subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-ffp-contract=off", "-shared", "-fPIC", str(src), "-o", str(lib),
                    "-lm"], check=True, capture_output=True, text=True)
    return ctypes.CDLL(str(lib))


def test_translated_function_computes_what_python_computes(tmp_path):
    code = translate(TEXT, ["f"], prefix="t_")
    code += ("\ndouble call_f(double x, double y, double *arr, long n, double *out)"
             " { return t_f(x, y, arr, n, out, 8); }\n")
    lib = compile_lib(code, tmp_path)
    lib.call_f.restype = ctypes.c_double
    lib.call_f.argtypes = [ctypes.c_double, ctypes.c_double, ctypes.c_void_p, ctypes.c_long, ctypes.c_void_p]
    namespace = {}
    exec(compile(TEXT, "text", "exec"), namespace)
    rng = np.random.default_rng(1)
    for x, y in [(-7.5, 2.0), (7.5, -2.0), (0.0, 3.0), (1.5, 2.5), *rng.uniform(-9, 9, (40, 2))]:
        arr = rng.normal(size=5)
        out_py, out_c = np.zeros(8), np.zeros(8)
        r_py = namespace["f"](float(x), float(y), arr, out_py)
        r_c = lib.call_f(float(x), float(y), arr.ctypes.data, arr.size, out_c.ctypes.data)
        assert np.array_equal(out_py, out_c), (x, y, out_py, out_c)
        assert r_py == r_c


def test_outside_the_subset_is_refused_naming_function_and_line():
    with pytest.raises(TranslationError, match=r"g \(line 3\): a call of np.interp does not translate to C"):
        translate("import numpy as np\ndef g(x):\n    return np.interp(x, x, x)\n", ["g"])


def test_every_registered_effect_and_law_translates_and_compiles(tmp_path):
    from ehas_env.physics.model_source import ModelSource
    from ehas_env.physics.effects import REGISTRY
    from ehas_env.simulation.control_laws import all_laws

    spec = ModelSource(list(REGISTRY.values()), all_laws())
    code, tr = model_c(spec)
    assert tr.signature("advance")["returns"] in ("long", "double")
    assert len(spec.effects) >= 13
    compile_lib(code, tmp_path, "model")


ARRAYS_TEXT = '''
import numpy as np

N_ROW = 3
FIRST, SECOND = 1, 2

def scratch(a):
    return np.empty_like(a), np.zeros_like(a)

def fill(v, out):
    for j in range(v.shape[0]):
        out[j] = 2.0 * v[j]

def g(s, P, table, weights=None):
    """What a driver needs: arrays of its own, a table of rows, an argument that may be left out."""
    row = np.zeros(N_ROW)
    work, zero = scratch(s)
    fill(s, work)
    if weights is not None:
        P = P.copy()
        P[0] = np.max(weights)
    total = 0.0
    for k in range(table.shape[0]):
        for j in range(table.shape[1]):
            table[k, j] = work[j % work.shape[0]] * P[0] + k + zero[0]
            row[j % N_ROW] += table[k, j]
    if weights is None:
        total = -1.0
    return total + row[FIRST] + row[SECOND] + P[0]
'''


def test_local_arrays_tables_and_left_out_arguments_compute_what_python_computes(tmp_path):
    code = translate(ARRAYS_TEXT, ["g"], prefix="a_")
    code += ("\ndouble call_g(double *s, long ns, double *P, long nP, double *t, long n0, long n1, double *w, long nw)"
             " { return a_g(s, ns, P, nP, t, n0, n1, w, nw); }\n")
    lib = compile_lib(code, tmp_path, "arrays")
    lib.call_g.restype = ctypes.c_double
    lib.call_g.argtypes = [ctypes.c_void_p, ctypes.c_long] * 2 + [ctypes.c_void_p, ctypes.c_long, ctypes.c_long,
                                                                  ctypes.c_void_p, ctypes.c_long]
    namespace = {}
    exec(compile(ARRAYS_TEXT, "text", "exec"), namespace)
    rng = np.random.default_rng(2)
    for given in (False, True):
        s, P, w = rng.normal(size=4), rng.normal(size=2), rng.normal(size=5)
        t_py, t_c = np.zeros((3, 5)), np.zeros((3, 5))
        P_py, P_c = P.copy(), P.copy()
        r_py = namespace["g"](s, P_py, t_py, w if given else None)
        r_c = lib.call_g(s.ctypes.data, 4, P_c.ctypes.data, 2, t_c.ctypes.data, 3, 5,
                         w.ctypes.data if given else None, 5 if given else 0)
        assert r_py == r_c
        assert np.array_equal(t_py, t_c)
        assert np.array_equal(P_c, P), "P.copy() must leave the caller's array as it was"


def test_an_array_given_anything_but_a_copy_of_itself_is_refused():
    text = "import numpy as np\ndef h(P, Q):\n    P = Q.copy()\n    return P[0]\n"
    with pytest.raises(TranslationError, match=r"h \(line 3\): an array argument given anything but a copy"):
        translate(text, ["h"])
