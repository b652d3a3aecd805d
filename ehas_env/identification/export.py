"""A fitted transfer function as a file: MATLAB ``.mat`` or JSON, and back into python-control.

Both files hold ``num`` and ``den`` (highest power of s first, ``den``
monic), ``dt = 0`` (continuous time), the input delay ``delay_s`` (MATLAB:
``tf(num, den, 'InputDelay', delay_s)``), the operating point
(``input_offset``, ``output_offset``) and the signal names.  In MATLAB::

    m = load('model.mat');  G = tf(m.num, m.den, 'InputDelay', m.delay_s);

In Python :func:`read_model` returns a ``control.TransferFunction``.

Examples
--------
>>> import tempfile, control
>>> work = tempfile.TemporaryDirectory()
>>> path = Path(work.name) / "g.json"
>>> _ = write_model(path, [14567.29], [1.0, 147.83, 11449.86])
>>> G = read_model(path)
>>> G.dt, float(control.dcgain(G)) == 14567.29 / 11449.86
(0, True)
>>> work.cleanup()
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

FORMAT = "ehas-tf"
SUFFIXES = (".json", ".mat")


def check_path(path, where: str = "--export") -> Path:
    """``path`` as a Path if its suffix is .json or .mat (ValueError naming ``where`` otherwise)."""
    p = Path(str(path))
    if not str(path).strip():
        raise ValueError(f"{where}: the path is empty; give a file ending in .json or .mat")
    if p.suffix.lower() not in SUFFIXES:
        raise ValueError(f"{where} must be a file ending in .json or .mat, got {str(path)!r}")
    return p


def write_model(path, num, den, *, delay_s: float = 0.0, input_offset: float = 0.0, output_offset: float = 0.0,
                input_name: str = "u", output_name: str = "y", extra: dict | None = None, dt: float = 0.0) -> Path:
    """Write a transfer function to ``path`` (.json or .mat, atomically): continuous (dt = 0) or in z (dt > 0).

    Parameters
    ----------
    path : path
        The file; its suffix picks the format.
    num, den : array
        Coefficients, highest power first.
    delay_s, input_offset, output_offset : float
        Input delay (s) and operating point.
    input_name, output_name : str
        Signal names.
    extra : dict, optional
        More JSON-ready fields (JSON only; e.g. K, wn, zeta, ci95).
    dt : float
        0 for a transfer function in s; the sample period for one in z (MATLAB: ``tf(num, den, dt)``).

    Returns
    -------
    Path
    """
    from ehas_env.output.files import atomic_write_bytes, atomic_write_text

    p = check_path(path, "path")
    num = [float(v) for v in np.atleast_1d(num)]
    den = [float(v) for v in np.atleast_1d(den)]
    doc = {"format": FORMAT, "version": 1, "num": num, "den": den, "dt": float(dt), "delay_s": float(delay_s),
           "input_offset": float(input_offset), "output_offset": float(output_offset), "input": input_name,
           "output": output_name}
    if p.suffix.lower() == ".json":
        doc.update(extra or {})
        return atomic_write_text(p, json.dumps(doc, indent=2) + "\n")
    import io

    from scipy.io import savemat

    buf = io.BytesIO()
    mat = {k: (np.array([v]) if k in ("num", "den") else v) for k, v in doc.items()}
    mat["matlab"] = "G = tf(num, den, 'InputDelay', delay_s)" if not dt else "G = tf(num, den, dt)"
    savemat(buf, mat, do_compression=True)
    return atomic_write_bytes(p, buf.getvalue())


def read_model_dict(path) -> dict:
    """The fields of a file of :func:`write_model`: num, den, dt, delay_s, offsets (ValueError naming the file)."""
    p = check_path(path, str(path))
    if not p.is_file():
        raise ValueError(f"{p}: no such file")
    if p.suffix.lower() == ".json":
        try:
            doc = json.loads(p.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"{p}: not valid JSON ({exc})") from None
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise ValueError(f"{p}: not a transfer-function file (its 'format' must be {FORMAT!r})")
    else:
        from scipy.io import loadmat

        try:
            raw = loadmat(str(p), squeeze_me=True)
        except Exception as exc:  # scipy raises several types for a broken file
            raise ValueError(f"{p}: not a readable MATLAB file ({exc})") from None
        doc = {k: v for k, v in raw.items() if not k.startswith("__")}
    out = {}
    for key in ("num", "den"):
        if key not in doc:
            raise ValueError(f"{p}: no '{key}'")
        v = np.atleast_1d(np.asarray(doc[key], dtype=float)).ravel()
        if v.size == 0 or not np.all(np.isfinite(v)):
            raise ValueError(f"{p}: '{key}' must be finite numbers")
        out[key] = v
    for key in ("dt", "delay_s", "input_offset", "output_offset"):
        v = float(np.asarray(doc.get(key, 0.0)))
        if not math.isfinite(v):
            raise ValueError(f"{p}: '{key}' must be a finite number, got {v}")
        out[key] = v
    if out["dt"] < 0:
        raise ValueError(f"{p}: dt = {out['dt']:g}; it must be 0 (continuous time) or a sample period > 0")
    return out


def read_model(path):
    """The ``control.TransferFunction`` of a file of :func:`write_model` (its delay: :func:`read_model_dict`)."""
    import control

    d = read_model_dict(path)
    return control.tf(d["num"], d["den"], d["dt"]) if d["dt"] else control.tf(d["num"], d["den"])
