"""Calibrated model files: the rig as measured, for the environment, tuners and benchmark.

A model file is JSON::

    {"format": "ehas-model", "version": 1,
     "baseline": {"beta_Pa": 9.6e8, "K_lpm_per_mA": 1.281},
     "effects": {"coulomb_friction": {"Fc": 412.0}},
     "units": {"coulomb_friction.Fc": "N", ...},
     "calibration": {"campaign": "...", "fit_percent_before": 83.4, "fit_percent_after": 98.1,
                     "command": "ehas compare DIR --effects coulomb_friction --fit --save-model m.json"}}

``baseline`` holds the recalibrated numbers of the reference model (bulk modulus
in Pa, valve gain in LPM/mA); ``effects`` the added effects with their fitted
values in the effects' units.  :func:`load_model` turns it into keyword
arguments of :class:`~ehas_env.simulation.plant.Plant`, so anything that builds a plant
accepts ``--model FILE``: ``Plant(disc_sets=3, **load_model(path))`` or
:func:`plant_from_model`.

Examples
--------
>>> import tempfile, os
>>> path = os.path.join(tempfile.mkdtemp(), "rig.json")
>>> _ = save_model(path, {"coulomb_friction": {"Fc": 412.0}}, beta=9.6e8, K=1.281)
>>> kw = load_model(path)
>>> kw["effects"], kw["rig"].beta, kw["rig"].K
({'coulomb_friction': {'Fc': 412.0}}, 960000000.0, 1.281)
>>> plant_from_model(path, disc_sets=5)
Plant(disc_sets=5, inertia=1.915 kg m^2, effects=[coulomb_friction(Fc=412)])
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from ehas_env.physics.effects import get_effect, resolve_effects
from ehas_env.output.files import atomic_write_text
from ehas_env.physics.rig import BULK_MODULUS, VALVE_K, RigParams

FORMAT = "ehas-model"
VERSION = 1
#: accepted ranges of the baseline numbers (the bulk_modulus and valve_dynamics bounds)
BETA_BOUNDS = (5.0e7, 2.5e9)  # Pa
K_BOUNDS = (0.3, 3.0)  # LPM/mA


def model_dict(effects: dict, *, beta: float = BULK_MODULUS, K: float = VALVE_K, calibration: dict | None = None) -> dict:
    """The JSON document of a calibrated model."""
    effects = resolve_effects(effects)
    units = {f"{n}.{p}": get_effect(n).param(p).unit for n, ps in effects.items() for p in ps}
    return {"format": FORMAT, "version": VERSION,
            "baseline": {"beta_Pa": float(beta), "K_lpm_per_mA": float(K)},
            "effects": effects, "units": units, "calibration": calibration or {}}


def save_model(path, effects: dict, *, beta: float = BULK_MODULUS, K: float = VALVE_K,
               calibration: dict | None = None) -> Path:
    """Write a model file atomically (validated by loading it back first)."""
    doc = model_dict(effects, beta=beta, K=K, calibration=calibration)
    _check(doc, str(path))
    return atomic_write_text(path, json.dumps(doc, indent=2) + "\n")


def load_model(path) -> dict:
    """Plant keyword arguments ``{"rig": RigParams, "effects": {...}}`` from a model file.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not a model file; the message names the key and what is expected.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"model file {path} does not exist")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    beta, K, effects = _check(doc, str(path))
    return {"rig": RigParams(beta=beta, K=K), "effects": effects}


def plant_from_model(path, disc_sets: int = 3, **kwargs):
    """A :class:`~ehas_env.simulation.plant.Plant` of the calibrated rig with ``disc_sets`` sets of discs."""
    from ehas_env.simulation.plant import Plant

    return Plant(disc_sets=disc_sets, **load_model(path), **kwargs)


def _check(doc, where: str):
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{where}: not an ehas model file (expected a JSON object with \"format\": \"{FORMAT}\")")
    if doc.get("version") != VERSION:
        raise ValueError(f"{where}: key 'version' = {doc.get('version')!r}; this ehas reads version {VERSION}")
    base = doc.get("baseline", {})
    if not isinstance(base, dict):
        raise ValueError(f"{where}: key 'baseline' must be an object with beta_Pa and K_lpm_per_mA")
    beta = _num(base, "beta_Pa", BULK_MODULUS, BETA_BOUNDS, f"{where}, baseline")
    K = _num(base, "K_lpm_per_mA", VALVE_K, K_BOUNDS, f"{where}, baseline")
    eff = doc.get("effects", {})
    if not isinstance(eff, dict) or not all(isinstance(v, dict) for v in eff.values()):
        raise ValueError(f"{where}: key 'effects' must map effect names to {{parameter: value}} objects")
    try:
        effects = resolve_effects(eff)
    except ValueError as exc:
        raise ValueError(f"{where}, effects: {exc}") from None
    return beta, K, effects


def _num(obj: dict, key: str, default: float, bounds, where: str) -> float:
    v = obj.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not bounds[0] <= v <= bounds[1]:
        raise ValueError(f"{where}: key '{key}' = {v!r}; expected a number in [{bounds[0]:g}, {bounds[1]:g}]")
    return float(v)
