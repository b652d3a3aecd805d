"""The rig's description, read from a model file (docs/model-file.md), in SI.

Only the ``rig`` and ``valve`` sections are read (a grey-box valve); every key
left out takes the book rig's value (docs/rig.md, docs/reference-model.md).
This reader is the independent generator's own: it shares no code with
``ehas_env.simulation.model_file``.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

BAR = 1.0e5  # Pa
LPM = 1.0e-3 / 60.0  # m^3/s

#: the book rig (docs/rig.md and docs/reference-model.md, "Baseline plant")
BOOK = {
    "crank_radius_mm": 50.0, "piston_area_cm2": 7.658, "half_stroke_mm": 35.0, "inertia_per_set_kgm2": 0.383,
    "dead_volume_cm3": 20.0, "supply_bar": 220.0, "bulk_modulus_Pa": 1.0e9,
    "K_lpm_per_mA": 1.2723, "wn_rad_s": 107.0, "zeta": 0.691, "rated_drop_bar": 70.0, "rated_current_mA": 20.0,
}


@dataclass(frozen=True)
class Rig:
    """Geometry and hydraulics of one rig, SI.

    Parameters
    ----------
    radius : float
        Crank radius r, m.
    area : float
        Piston area A (both sides of the symmetric actuator), m^2.
    half_stroke : float
        Half stroke h, m.
    inertia_per_set : float
        Load inertia per disc set, kg m^2.
    dead_volume : float
        Dead volume per side, m^3.
    supply : float
        Supply pressure Ps, Pa.
    beta : float
        Bulk modulus, Pa.
    K : float
        Valve flow gain at the rated drop, m^3/s per mA.
    wn : float
        Valve natural frequency, rad/s.
    zeta : float
        Valve damping ratio, -.
    rated_drop : float
        Valve drop at which K is rated, Pa.
    i_max : float
        Amplifier clip = rated current, mA.
    name : str
        A short name for tables.
    """

    radius: float
    area: float
    half_stroke: float
    inertia_per_set: float
    dead_volume: float
    supply: float
    beta: float
    K: float
    wn: float
    zeta: float
    rated_drop: float
    i_max: float
    name: str = "book rig"

    @property
    def stroke_end(self) -> float:
        """Crank angle of the stroke ends, rad."""
        return math.asin(self.half_stroke / self.radius)

    def controller_gains(self) -> dict:
        """The book's PI + feed-forward carried over to this rig (docs/model-file.md, "The controller
        carried over"): every gain scaled by the rig's velocity gain relative to the book's; Ka = Kv 2 zeta / wn."""
        kv = self.area * self.radius * math.pi / 180.0 / (self.K * math.sqrt(self.supply / self.rated_drop))
        scale = kv * 56.25
        return {"Kp": 1.0 * scale, "Ki": 2.0 * scale, "Kv": kv, "Ka": kv * 2.0 * self.zeta / self.wn,
                "rate_hz": 1000.0}

    def with_(self, **kw) -> "Rig":
        return replace(self, **kw)


def rig_from_numbers(numbers: dict, name: str = "book rig") -> Rig:
    """A :class:`Rig` from the model file's engineering numbers (keys of :data:`BOOK`)."""
    n = {**BOOK, **numbers}
    return Rig(radius=n["crank_radius_mm"] * 1e-3, area=n["piston_area_cm2"] * 1e-4,
               half_stroke=n["half_stroke_mm"] * 1e-3, inertia_per_set=n["inertia_per_set_kgm2"],
               dead_volume=n["dead_volume_cm3"] * 1e-6, supply=n["supply_bar"] * BAR, beta=n["bulk_modulus_Pa"],
               K=n["K_lpm_per_mA"] * LPM, wn=n["wn_rad_s"], zeta=n["zeta"], rated_drop=n["rated_drop_bar"] * BAR,
               i_max=n["rated_current_mA"], name=name)


def book_rig() -> Rig:
    """The book's rig."""
    return rig_from_numbers({})


def read_rig(path) -> Rig:
    """Read a model file (format ``ehas-model``, version 2, grey-box valve) as a :class:`Rig`.

    Parameters
    ----------
    path : str or Path
        The model file.

    Returns
    -------
    Rig
    """
    path = Path(path)
    data = json.loads(path.read_text())
    if data.get("format") != "ehas-model" or data.get("version") != 2:
        raise ValueError(f"{path}: not an ehas-model version 2 file")
    valve = data.get("valve", {})
    if valve.get("model", "grey_box") != "grey_box":
        raise ValueError(f"{path}: the independent generator simulates the grey-box valve only")
    if data.get("effects"):
        raise ValueError(f"{path}: the independent generator reads a bare rig (no effects)")
    numbers = {k: float(v) for sec in ("rig", "valve") for k, v in data.get(sec, {}).items() if k in BOOK}
    return rig_from_numbers(numbers, name=data.get("name", path.stem))
