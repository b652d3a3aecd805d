"""numba's start with its BLAS probe answered from scipy's folder: the same answer, no scipy.linalg import."""
from __future__ import annotations

import json
import os
import subprocess
import sys

PROBED = """
import json, sys
import numba.np.linalg as L
original = L.ensure_blas
from ehas_env.physics.numba_start import answer_blas_probe
first = answer_blas_probe()
second = answer_blas_probe()
import numba.np.arraymath as AM
from numba import njit
import numpy as np
total = njit(lambda a: a.sum())(np.arange(3.0))          # the target's set-up: the first compiled call
after_start = "scipy.linalg" in sys.modules
dot = njit(lambda a, b: np.dot(a, b))(np.arange(3.0), np.arange(3.0))   # BLAS itself: imported now, as numba does
print(json.dumps({"answered": first, "again": second, "have_blas": AM._HAVE_BLAS, "dot": float(dot),
                  "scipy_linalg": after_start, "restored": L.ensure_blas is original}))
"""

NUMBA_ITSELF = """
import json, sys
import numba.np.arraymath as AM
print(json.dumps({"have_blas": AM._HAVE_BLAS, "scipy_linalg": "scipy.linalg" in sys.modules}))
"""


def _run(code: str, **env) -> dict:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, **env})
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_probe_gives_numbas_own_answer_without_importing_scipy_linalg():
    mine, numbas = _run(PROBED), _run(NUMBA_ITSELF)
    assert numbas["scipy_linalg"] is True            # numba's own probe imports it (what this saves)
    assert mine["answered"] is True and mine["again"] is False
    assert mine["have_blas"] == numbas["have_blas"]
    assert mine["scipy_linalg"] is False
    assert mine["restored"] is True                  # np.linalg functions compiled later probe in numba's own way
    assert mine["dot"] == 5.0                         # 0*0 + 1*1 + 2*2


def test_the_probe_can_be_switched_off():
    mine = _run(PROBED, EHAS_NUMBA_BLAS_PROBE="import")
    assert mine["answered"] is False and mine["scipy_linalg"] is True
