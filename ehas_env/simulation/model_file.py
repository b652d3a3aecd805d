"""Model files: the plant as one JSON file (docs/model-file.md).

A model file describes a valve-actuator-crank-inertia rig completely: its
geometry and hydraulics (crank radius, piston area, stroke, inertia per disc
set, dead volume, supply pressure, bulk modulus), its servo valve (rating and
dynamics, grey or white box), the effects switched on (built-in or from user
effect files), how it was calibrated and where it came from.  The book's rig is
the embedded default: a file that names nothing else is the book's rig.

Version 2 (written by this ehas)::

    {"format": "ehas-model", "version": 2, "kind": "plant",
     "name": "rig B", "description": "...",
     "rig":   {"crank_radius_mm": 50, "piston_area_cm2": 7.658, "half_stroke_mm": 35,
               "inertia_per_set_kgm2": 0.383, "dead_volume_cm3": 20, "supply_bar": 220,
               "bulk_modulus_Pa": 1e9},
     "valve": {"model": "grey_box", "K_lpm_per_mA": 1.2723, "wn_rad_s": 107, "zeta": 0.691,
               "rated_drop_bar": 70, "rated_current_mA": 20},
     "effects": {"coulomb_friction": {"Fc": 412.0}, "torsion_spring": {"k": 30.0}},
     "user_effects": {"torsion_spring": {"file": "torsion_spring.py", "sha256": "9f2c..."}},
     "units": {"coulomb_friction.Fc": "N"},
     "calibration": {"campaign": "...", "fit_percent_before": 83.4, "fit_percent_after": 98.1},
     "provenance": {"created_utc": "...", "ehas_version": "0.1.0", "command": "..."}}

Every key may be left out (its default is the book's value).  A model file is
data: reading it never imports code.  ``user_effects`` *names* the user effect
files its effects need (file name and SHA-256 of the file's text); their code
loads only from a folder the user gives (``--effects-path DIR``,
``effects_path=``) or lists in a trust list (``EHAS_TRUSTED_EFFECTS`` or
``~/.config/ehas/trusted_effects.json``), and otherwise reading the file stops
with one line naming the missing effect file.  An ``effects_path`` key of older
files is read and ignored (never imported).  Version 1 files
(``"baseline": {"beta_Pa", "K_lpm_per_mA"}``, written by earlier
``ehas compare --save-model``) are still read: the book's rig with that bulk
modulus and valve gain.

:func:`load_model` gives a :class:`PlantModel`; ``Plant(disc_sets, model=...)``,
``gymnasium.make("ehas/Tracking-v0", model=...)`` and ``--model FILE`` on every
command that builds a plant accept it (or the file's path).

Examples
--------
>>> import tempfile, os
>>> work = tempfile.TemporaryDirectory()
>>> path = os.path.join(work.name, "rig.json")
>>> _ = save_model(path, {"coulomb_friction": {"Fc": 412.0}}, beta=9.6e8, K=1.281)
>>> m = load_model(path)
>>> m.effects, m.rig.beta, m.rig.K
({'coulomb_friction': {'Fc': 412.0}}, 960000000.0, 1.281)
>>> from ehas_env.simulation.plant import Plant
>>> Plant(disc_sets=5, model=m)
Plant(disc_sets=5, inertia=1.915 kg m^2, effects=[coulomb_friction(Fc=412)])
>>> other = PlantModel.from_values(name="rig B", crank_radius_mm=60, inertia_per_set_kgm2=0.5)
>>> [d.split(":")[0] for d in diff_models(PlantModel(), other)]
['name', 'rig.crank_radius_mm', 'rig.inertia_per_set_kgm2']
>>> work.cleanup()
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from ehas_env.ranges import FIELDS as SHARED, Range
from ehas_env.output.files import atomic_write_text
from ehas_env.physics.rig import (BAR, BULK_MODULUS, INERTIA_PER_SET, LPM, VALVE_K, VALVE_WN, VALVE_ZETA, DEG,
                                  RigParams)

FORMAT = "ehas-model"
VERSION = 2
KIND = "plant"
VALVE_MODELS = ("grey_box", "white_box")
#: accepted ranges of version 1's baseline numbers (kept for those files)
BETA_BOUNDS = (5.0e7, 2.5e9)  # Pa
K_BOUNDS = (0.3, 3.0)  # LPM/mA


@dataclass(frozen=True)
class Field:
    """One number of a model file: where it lives, its unit, range, default and source."""

    section: str  # "rig" or "valve"
    key: str  # JSON key (the unit is in the name)
    attr: str  # RigParams attribute, or "inertia_per_set"
    unit: str  # unit of the file's value
    si: float  # SI value of one file unit
    range: Range  # allowed values, in file units
    default: float  # the book rig's value, in file units
    source: str
    text: str

    @property
    def path(self) -> str:
        return f"{self.section}.{self.key}"


_BOOK = RigParams()
FIELDS: tuple[Field, ...] = (
    Field("rig", "crank_radius_mm", "radius", "mm", 1e-3, Range(1, 2000, "mm"), _BOOK.radius * 1e3, "book",
          "crank radius, from the crank axis to the rod joint"),
    Field("rig", "piston_area_cm2", "area", "cm^2", 1e-4, Range(0.01, 1000, "cm^2"), _BOOK.area * 1e4,
          "book (tables 1.1-1.6)", "net piston area of the (symmetric) actuator"),
    Field("rig", "half_stroke_mm", "half_stroke", "mm", 1e-3, Range(1, 2000, "mm"), _BOOK.half_stroke * 1e3,
          "book (70 mm stroke)", "half the actuator stroke; must be shorter than the crank radius"),
    Field("rig", "inertia_per_set_kgm2", "inertia_per_set", "kg m^2", 1.0, Range(0, 1e4, "kg m^2", lo_open=True),
          INERTIA_PER_SET, "book", "load inertia about the crank axis per disc set (1..7 sets)"),
    Field("rig", "dead_volume_cm3", "dead_volume", "cm^3", 1e-6, Range(0, 1e5, "cm^3", lo_open=True),
          _BOOK.dead_volume * 1e6, "reference model (assumed)", "dead volume of each chamber and its line"),
    Field("rig", "supply_bar", "supply", "bar", BAR, SHARED["supply_bar"], _BOOK.supply / BAR, "book",
          "supply pressure Ps"),
    Field("rig", "bulk_modulus_Pa", "beta", "Pa", 1.0, Range(*BETA_BOUNDS, "Pa"), _BOOK.beta,
          "reference model (assumed)", "effective bulk modulus of the oil"),
    Field("valve", "K_lpm_per_mA", "K", "LPM/mA", 1.0, Range(0, 100, "LPM/mA", lo_open=True), _BOOK.K,
          "book (chirp transfer function)", "valve flow gain at the rated drop (rated flow / rated current)"),
    Field("valve", "wn_rad_s", "wn", "rad/s", 1.0, Range(1, 1e4, "rad/s"), _BOOK.wn,
          "book (chirp transfer function)", "valve natural frequency"),
    Field("valve", "zeta", "zeta", "-", 1.0, Range(0.01, 10, ""), _BOOK.zeta,
          "book (chirp transfer function)", "valve damping ratio"),
    Field("valve", "rated_drop_bar", "rated_drop", "bar", BAR, Range(0, 350, "bar", lo_open=True),
          _BOOK.rated_drop / BAR, "book (25 LPM at 70 bar)", "valve drop at which the flow gain is rated"),
    Field("valve", "rated_current_mA", "i_max", "mA", 1.0, Range(0, 1000, "mA", lo_open=True), _BOOK.i_max,
          "book (+-20 mA servo amplifier)", "rated current = the servo amplifier's clip"),
)
FIELD_BY_PATH = {f.path: f for f in FIELDS}
FIELD_BY_KEY = {f.key: f for f in FIELDS}
TOP_KEYS = ("format", "version", "kind", "name", "description", "rig", "valve", "effects", "user_effects",
            "effects_path", "units", "calibration", "provenance")
#: the top-level keys of a version-1 file (the book's rig with a recalibrated beta and K)
V1_KEYS = ("format", "version", "baseline", "effects", "effects_path", "units", "calibration", "provenance")


@dataclass(frozen=True)
class PlantModel:
    """The plant a model file describes (the book's rig by default).

    Attributes
    ----------
    name : str
        A short name; figure titles and tables show it.
    rig : RigParams
        Geometry, hydraulics and valve numbers (SI, valve in LPM/mA, mA);
        ``disc_sets``/``inertia`` are set per plant from ``inertia_per_set``.
    inertia_per_set : float
        Load inertia per disc set, kg m^2.
    valve : str
        ``"grey_box"`` (the identified transfer function) or ``"white_box"``.
    white_box : dict
        Overrides of :class:`~ehas_env.physics.white_box_valve.WhiteBoxValve` (SI).
    effects : dict
        Effects switched on, ``{name: {param: value}}`` in the effects' units.
    user_effects : dict
        ``{name: {"file": file name, "sha256": hex}}`` of the user effects among ``effects`` (the
        code is never loaded from the model file; see the module docstring).
    calibration, provenance : dict
        How the numbers were obtained, and by which command / ehas version.
    description : str
        Free text.
    path : str or None
        The file it was read from.
    """

    name: str = "book rig"
    rig: RigParams = field(default_factory=RigParams)
    inertia_per_set: float = INERTIA_PER_SET
    valve: str = "grey_box"
    white_box: dict = field(default_factory=dict)
    effects: dict = field(default_factory=dict)
    user_effects: dict = field(default_factory=dict)
    calibration: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    description: str = ""
    path: str | None = None

    def __getitem__(self, key: str):
        """The older dict form of :func:`load_model` (``m["rig"]``, ``m["effects"]``) still reads."""
        if key in ("rig", "effects"):
            return getattr(self, key)
        raise KeyError(key)

    # -- building -------------------------------------------------------------------------
    @classmethod
    def from_values(cls, name: str = "book rig", *, effects=None, valve: str = "grey_box", **values) -> "PlantModel":
        """A model from file-unit values by key (``crank_radius_mm=60``), validated as a file is.

        ``rated_flow_lpm`` may be given instead of ``K_lpm_per_mA`` (K = rated flow / rated current).

        Parameters
        ----------
        name : str
            The model's short name (figure titles and tables show it).
        effects : dict, optional
            Effects to switch on, ``{name: {param: value}}`` in the effects' own units.
        valve : {"grey_box", "white_box"}
            The valve model: the identified transfer function or the first-principles valve.
        **values : float
            Model-file fields by key, in the file's engineering units (the unit is in the key):
            ``crank_radius_mm``, ``piston_area_cm2``, ``half_stroke_mm``, ``inertia_per_set_kgm2``,
            ``dead_volume_cm3``, ``supply_bar``, ``bulk_modulus_Pa``, ``K_lpm_per_mA``, ``wn_rad_s``,
            ``zeta``, ``rated_drop_bar``, ``rated_current_mA``, or ``rated_flow_lpm`` (LPM).  Keys left
            out keep the book's values.

        Returns
        -------
        PlantModel
            The model, validated as a model file is (SI inside).

        Raises
        ------
        ValueError
            An unknown key, a value out of its range, or an unknown effect.
        """
        doc = model_doc(PlantModel(name=name))
        flow = values.pop("rated_flow_lpm", None)
        for key, v in values.items():
            if key not in FIELD_BY_KEY:
                raise ValueError(f"{key} is not a model-file field; allowed: {', '.join(FIELD_BY_KEY)}, rated_flow_lpm")
            f = FIELD_BY_KEY[key]
            doc[f.section][key] = v
        if flow is not None:
            doc["valve"]["K_lpm_per_mA"] = Range(0, 1e5, "LPM", lo_open=True).check(flow, "rated_flow_lpm") / \
                float(doc["valve"]["rated_current_mA"])
        doc["valve"]["model"] = valve
        if effects:
            doc["effects"] = effects
        return parse_model(doc, "<values>")

    def value(self, f: Field) -> float:
        """The value of field ``f`` in its file unit.

        Parameters
        ----------
        f : Field
            One of :data:`FIELDS` (for example ``FIELD_BY_KEY["supply_bar"]``).

        Returns
        -------
        float
            The model's value of that field converted from SI to the field's file unit
            (``f.unit``: mm, cm^2, bar, LPM/mA, ...).
        """
        v = self.inertia_per_set if f.attr == "inertia_per_set" else getattr(self.rig, f.attr)
        return v / f.si

    def replace(self, **changes) -> "PlantModel":
        """A copy of this (frozen) model with some attributes changed.

        Parameters
        ----------
        **changes
            New values of attributes by name (``name="rig B"``, ``effects={...}``), in the
            attributes' own units (see the class's Attributes); not validated.

        Returns
        -------
        PlantModel
            The copy (:func:`dataclasses.replace`).
        """
        from dataclasses import replace

        return replace(self, **changes)

    @property
    def is_book(self) -> bool:
        """True when geometry, hydraulics and valve are the book's (effects aside)."""
        return all(math.isclose(self.value(f), f.default, rel_tol=1e-12) for f in FIELDS) and self.valve == "grey_box" \
            and not self.white_box

    @property
    def label(self) -> str:
        """How titles and tables name the model: its name, and its file when read from one."""
        return f"{self.name} ({Path(self.path).name})" if self.path else self.name

    def rig_for(self, disc_sets: int) -> RigParams:
        """The :class:`RigParams` of this rig with ``disc_sets`` sets of discs.

        Parameters
        ----------
        disc_sets : int
            Number of disc sets on the crank.

        Returns
        -------
        RigParams
            This model's rig with ``disc_sets`` and ``inertia = disc_sets * inertia_per_set`` (kg m^2).
        """
        return self.rig.replace(disc_sets=int(disc_sets), inertia=float(disc_sets) * self.inertia_per_set)

    def plant_kwargs(self) -> dict:
        """Keyword arguments of :class:`~ehas_env.simulation.plant.Plant` (besides ``disc_sets``).

        Returns
        -------
        dict
            ``{"model": self}``: ``Plant(disc_sets, **m.plant_kwargs())`` is the plant this model describes.
        """
        return {"model": self}

    def white_box_valve(self):
        """The :class:`WhiteBoxValve` of this model (None for the grey box).

        Returns
        -------
        WhiteBoxValve or None
            The white-box valve with this model's ``white_box`` overrides (SI), or None when the
            valve is the grey box.
        """
        if self.valve != "white_box":
            return None
        from ehas_env.physics.white_box_valve import WhiteBoxValve

        return WhiteBoxValve(**self.white_box)

    def velocity_gain(self) -> float:
        """Current per crank rate at no load, mA/(deg/s): A r / (K sqrt(Ps / rated drop)).

        Returns
        -------
        float
            The current in mA that moves the unloaded crank at 1 deg/s (near 0 deg), in mA/(deg/s).
        """
        r = self.rig
        return r.area * r.radius * DEG / (r.K * LPM * math.sqrt(r.supply / r.rated_drop))

    def controller(self):
        """The book's controller carried over to this rig (:class:`RigController`).

        The rig's gains scaled by the velocity gain of this rig relative to the
        book's (the same velocity-loop crossover, 56 rad/s), acceleration
        feed-forward ``Kv 2 zeta / wn`` with this valve's dynamics.  For the
        book's rig this is exactly ``RigController.book()``.

        Returns
        -------
        RigController
            Kp, Ki and Kv of the book scaled by this rig's velocity gain over the book's
            (mA/deg, mA/(deg s), mA/(deg/s)) and Ka = Kv 2 zeta / wn (mA/(deg/s^2)).
        """
        from ehas_env.simulation.rig_controller import RigController

        book = RigController.book()
        s = self.velocity_gain() / PlantModel().velocity_gain()
        if math.isclose(s, 1.0, rel_tol=1e-12) and self.rig.wn == VALVE_WN and self.rig.zeta == VALVE_ZETA:
            return book
        kv = book.Kv * s
        return RigController(Kp=book.Kp * s, Ki=book.Ki * s, Kv=kv, Ka=kv * 2.0 * self.rig.zeta / self.rig.wn)

    # -- describing -----------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The JSON document (version 2).

        Returns
        -------
        dict
            The model-file document (docs/model-file.md), numbers in the file's engineering units.
        """
        return model_doc(self)

    def summary(self) -> str:
        """Lines with every number, its unit, and whether it is the book's.

        Returns
        -------
        str
            A multi-line, human-readable description: name, rig and valve fields in file units
            (each differing from the book's marked with the book's value), derived stroke ends and
            hydraulic natural frequencies, effects, user effects, calibration and provenance.
        """
        lines = [f"model: {self.label}" + (f" - {self.description}" if self.description else "")]
        for section in ("rig", "valve"):
            lines.append(f"{section}:")
            if section == "valve":
                lines.append(f"  {'model':<22} {self.valve}")
            for f in (f for f in FIELDS if f.section == section):
                v = self.value(f)
                mark = "" if math.isclose(v, f.default, rel_tol=1e-12) else f"   (book {f.default:.6g})"
                lines.append(f"  {f.key:<22} {v:<12.6g} {f.unit:<8} {f.text}{mark}")
            if section == "valve":
                lines.append(f"  {'rated flow':<22} {self.rig.K * self.rig.i_max:<12.6g} {'LPM':<8} "
                             f"K x rated current, at {self.rig.rated_drop / BAR:g} bar")
                for k, v in self.white_box.items():
                    lines.append(f"  white_box.{k:<12} {v:g}")
        r = self.rig
        end = math.degrees(r.theta_stroke_end)
        wh = [f"{RigParams.hydraulic_natural_frequency(self.rig_for(n)) / (2 * math.pi):.1f}" for n in (1, 7)]
        lines.append(f"derived: stroke ends at +-{end:.2f} deg; hydraulic natural frequency {wh[0]} Hz (1 set) "
                     f"to {wh[1]} Hz (7 sets); inertia {self.inertia_per_set:g} to {7 * self.inertia_per_set:g} kg m^2")
        if self.effects:
            lines.append("effects: " + "; ".join(
                f"{n}(" + ", ".join(f"{k}={v:g}" for k, v in ps.items()) + ")" for n, ps in self.effects.items()))
        else:
            lines.append("effects: none")
        if self.user_effects:
            lines.append("user effects: " + ", ".join(f"{n} ({u['file']}, sha256 {u['sha256'][:12]})"
                                                       for n, u in self.user_effects.items()))
        if self.calibration:
            lines.append("calibration: " + json.dumps(self.calibration, sort_keys=True))
        if self.provenance:
            lines.append("provenance: " + json.dumps(self.provenance, sort_keys=True))
        return "\n".join(lines)


def model_doc(m: PlantModel) -> dict:
    """The version-2 JSON document of ``m``."""
    from ehas_env.physics.effects import get_effect

    rig = {f.key: _clean(m.value(f)) for f in FIELDS if f.section == "rig"}
    valve = {"model": m.valve, **{f.key: _clean(m.value(f)) for f in FIELDS if f.section == "valve"}}
    if m.white_box:
        valve["white_box"] = dict(m.white_box)
    units = {}
    for n, ps in m.effects.items():
        for p in ps:
            try:
                units[f"{n}.{p}"] = get_effect(n).param(p).unit
            except (KeyError, ValueError):
                pass
    doc = {"format": FORMAT, "version": VERSION, "kind": KIND, "name": m.name}
    if m.description:
        doc["description"] = m.description
    doc.update({"rig": rig, "valve": valve, "effects": {n: dict(p) for n, p in m.effects.items()},
                "user_effects": {**m.user_effects, **user_effects_of(m.effects)}, "units": units,
                "calibration": dict(m.calibration), "provenance": dict(m.provenance)})
    return doc


def _clean(v: float) -> float | int:
    v = float(f"{v:.12g}")
    return int(v) if v.is_integer() and abs(v) < 1e15 else v


def user_effects_of(effects) -> dict:
    """``{name: {"file", "sha256"}}`` of the loaded user effects among ``effects`` (the library's own are left out)."""
    from ehas_env.physics.effects.loading import effect_source

    out = {}
    for n in effects:
        src = effect_source(n)
        if src is not None:
            out[n] = {"file": Path(src[0]).name, "sha256": src[1]}
    return out


# -- reading ------------------------------------------------------------------------------------
def load_model(path) -> PlantModel:
    """The :class:`PlantModel` of a model file (version 1 or 2); reading it never imports code.

    Parameters
    ----------
    path : str or path
        The model JSON file (docs/model-file.md).  User effects it names in ``user_effects``
        must already be loaded (``--effects-path DIR``, ``effects_path=``, ``EHAS_EFFECTS_PATH``)
        with the recorded SHA-256, or lie in a folder of the user's trust list.

    Returns
    -------
    PlantModel
        The validated model (SI inside, see :class:`PlantModel`).

    Raises
    ------
    ValueError
        Not a model file, a key named twice, a field out of range or of the wrong type, a user
        effect not loaded or loaded from a different file: one line naming the file and the field.
    """
    path = Path(path)
    if str(path) in ("", "."):
        raise ValueError("model file: the path is empty; give a model JSON file (docs/model-file.md)")
    from ehas_env.output.files import read_json

    # read_json names a missing file, a folder, a file that is not UTF-8 text or not JSON
    doc = read_json(path, 'a model JSON file ("format": "ehas-model", docs/model-file.md)')
    return parse_model(doc, str(path))


def as_model(model) -> PlantModel | None:
    """A :class:`PlantModel` from a PlantModel, a model file's path, a JSON document (dict) or None."""
    if model is None or isinstance(model, PlantModel):
        return model
    if isinstance(model, (str, os.PathLike)):
        return load_model(model)
    if isinstance(model, dict):
        return parse_model(model, "<model dict>")
    raise ValueError(f"model must be a PlantModel, a model file's path or its JSON dict, got {type(model).__name__}")


def parse_model(doc, where: str) -> PlantModel:
    """Validate a model document (version 1 or 2); ``where`` names it in errors."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{where}: not an ehas model file (expected a JSON object with \"format\": \"{FORMAT}\"; "
                         "docs/model-file.md)")
    version = doc.get("version")
    if type(version) is int and version == 1:  # 1.0 and true are not versions
        return _parse_v1(doc, where)
    if type(version) is not int or version != VERSION:
        raise ValueError(f"{where}: key 'version' = {version!r}; this ehas reads model-file versions 1 and {VERSION}")
    if "baseline" in doc:  # version 1's block: the label and the content disagree
        raise ValueError(f"{where}: 'baseline' is a version-1 field, but the file says \"version\": {VERSION}; a "
                         "version-2 file gives beta as rig.bulk_modulus_Pa and K as valve.K_lpm_per_mA "
                         "(docs/model-file.md)")
    _no_unknown(doc, TOP_KEYS, where, "")
    kind = doc.get("kind", KIND)
    if kind != KIND:
        raise ValueError(f"{where}: kind = {kind!r}; this ehas reads kind {KIND!r} (a valve-actuator-crank-inertia "
                         "plant)")
    name = _text(doc, "name", "book rig", where)
    description = _text(doc, "description", "", where)
    values = {}
    for section in ("rig", "valve"):
        sec = doc.get(section, {})
        if not isinstance(sec, dict):
            raise ValueError(f"{where}: {section} must be an object of numbers (docs/model-file.md)")
        allowed = [f.key for f in FIELDS if f.section == section] + (["model", "white_box"] if section == "valve" else [])
        _no_unknown(sec, allowed, where, f"{section}.")
        for f in (f for f in FIELDS if f.section == section):
            v = f.range.check(sec.get(f.key, f.default), f"{where}: {f.path}")
            values[f.attr] = v * f.si
    valve_sec = doc.get("valve", {})
    valve = valve_sec.get("model", "grey_box")
    if valve not in VALVE_MODELS:
        raise ValueError(f"{where}: valve.model must be one of {', '.join(VALVE_MODELS)}, got {valve!r}")
    white_box = _white_box(valve_sec.get("white_box", {}), where)
    if values["half_stroke"] >= values["radius"]:
        raise ValueError(f"{where}: rig.half_stroke_mm ({values['half_stroke'] * 1e3:g} mm) must be shorter than "
                         f"rig.crank_radius_mm ({values['radius'] * 1e3:g} mm): the crank would pass 90 deg, where "
                         "the actuator loses all leverage")
    ips = values.pop("inertia_per_set")
    rig = RigParams(**values)
    paths = doc.get("effects_path", [])  # older files: read, never imported (model files are data)
    if not isinstance(paths, list) or not all(isinstance(p, str) for p in paths):
        raise ValueError(f"{where}: effects_path must be a list of texts (older files; it is not used: name user "
                         "effects in user_effects and give their folder with --effects-path)")
    if paths:  # said, not silent: the key no longer loads anything
        import warnings

        warnings.warn(f"{where}: effects_path {paths} is not used (a model file never loads code); give user effect "
                      "folders with --effects-path (docs/model-file.md)", stacklevel=2)
    user = _user_effects(doc.get("user_effects", {}), where)
    effects = _effects(doc.get("effects", {}), user, where, legacy=paths)
    extra = sorted(set(user) - set(effects))
    if extra:
        raise ValueError(f"{where}: user_effects.{extra[0]} names an effect that effects does not switch on")
    for key in ("provenance", "units"):
        _flat(doc.get(key, {}), key, where)
    calibration = _calibration(doc.get("calibration", {}), where)
    return PlantModel(name=name, rig=rig, inertia_per_set=ips, valve=valve, white_box=white_box, effects=effects,
                      user_effects=user, calibration=calibration,
                      provenance=dict(doc.get("provenance", {})), description=description,
                      path=None if where[:1] == "<" else where)


def _parse_v1(doc, where: str) -> PlantModel:
    newer = [k for k in doc if k in TOP_KEYS and k not in V1_KEYS]
    if newer:  # a version-2 file labelled 1 would read as the book's rig: its rig and valve silently dropped
        raise ValueError(f"{where}: '{newer[0]}' is a version-{VERSION} field, but the file says \"version\": 1 "
                         f"(version 1 holds only {', '.join(V1_KEYS)}); set \"version\": {VERSION} "
                         "(docs/model-file.md)")
    _no_unknown(doc, V1_KEYS, where, "")
    base = doc.get("baseline", {})
    if not isinstance(base, dict):
        raise ValueError(f"{where}: baseline must be an object with beta_Pa and K_lpm_per_mA")
    beta = _num(base, "beta_Pa", BULK_MODULUS, BETA_BOUNDS, f"{where}: baseline")
    K = _num(base, "K_lpm_per_mA", VALVE_K, K_BOUNDS, f"{where}: baseline")
    effects = _effects(doc.get("effects", {}), {}, where)
    cal = _calibration(doc.get("calibration", {}), where)
    return PlantModel(name=Path(where).stem if where[:1] != "<" else "book rig (v1)", rig=RigParams(beta=beta, K=K),
                      effects=effects, calibration=dict(cal) if isinstance(cal, dict) else {},
                      provenance={"read_from": "model-file version 1"}, path=None if where[:1] == "<" else where)


_HEX = frozenset("0123456789abcdef")


def _user_effects(user, where: str) -> dict:
    """The ``user_effects`` block: ``{name: {"file": "name.py", "sha256": 64 hex digits}}``."""
    if not isinstance(user, dict):
        raise ValueError(f"{where}: user_effects must map effect names to {{\"file\": ..., \"sha256\": ...}}")
    out = {}
    for n, rec in user.items():
        if not (isinstance(rec, dict) and set(rec) == {"file", "sha256"} and isinstance(rec["file"], str)
                and rec["file"].endswith(".py") and "/" not in rec["file"] and "\\" not in rec["file"]
                and isinstance(rec["sha256"], str) and len(rec["sha256"]) == 64 and set(rec["sha256"]) <= _HEX):
            raise ValueError(f"{where}: user_effects.{n} must be {{\"file\": \"NAME.py\" (a file name, no folder), "
                             "\"sha256\": 64 lower-case hex digits}} (docs/model-file.md)")
        out[n] = dict(rec)
    return out


def _flat(obj, key: str, where: str) -> dict:
    """A block of plain values (texts, numbers, true/false, null; lists of them)."""
    def plain(v, depth=0):
        if isinstance(v, float):
            return math.isfinite(v)
        if depth > 4:
            return False
        if isinstance(v, dict):
            return all(isinstance(k, str) and plain(x, depth + 1) for k, x in v.items())
        return v is None or isinstance(v, (str, int, bool)) or (isinstance(v, list) and all(plain(x, depth + 1)
                                                                                             for x in v))
    if not isinstance(obj, dict):
        raise ValueError(f"{where}: {key} must be an object")
    for k, v in obj.items():
        if not plain(v):
            raise ValueError(f"{where}: {key}.{k} must be texts, finite numbers, true/false, null, or lists and "
                             f"objects of those (at most 4 deep), got {v!r:.60}")
    return dict(obj)


#: the calibration block's keys (docs/model-file.md) and what they hold (runs, ci95: plain values)
_CAL_NUMBERS = ("fit_percent_before", "fit_percent_after")
_CAL_TEXTS = ("campaign", "command", "verdict")
CALIBRATION_KEYS = ("campaign", "runs", "fit_percent_before", "fit_percent_after", "command", "ci95", "verdict",
                    "residual_x_noise", "measured_inputs")


def _calibration(cal, where: str) -> dict:
    cal = _flat(cal, "calibration", where)
    for k in cal:
        if k not in CALIBRATION_KEYS:  # a misspelt key would silently mean "not recorded"
            import difflib

            close = difflib.get_close_matches(k, CALIBRATION_KEYS, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise ValueError(f"{where}: calibration.{k} is not a calibration field{hint} (allowed: "
                             f"{', '.join(CALIBRATION_KEYS)}; docs/model-file.md)")
    for k in _CAL_NUMBERS:
        if k in cal:
            v = cal[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not -1e6 <= v <= 100:
                raise ValueError(f"{where}: calibration.{k} must be a number <= 100 (a fit %), got {v!r}")
    for k in _CAL_TEXTS:
        if k in cal and not isinstance(cal[k], str):
            raise ValueError(f"{where}: calibration.{k} must be a text, got {cal[k]!r:.60}")
    x = cal.get("residual_x_noise")
    if x is not None and (isinstance(x, bool) or not isinstance(x, (int, float)) or not x >= 0):
        raise ValueError(f"{where}: calibration.residual_x_noise must be a number >= 0 (the noise figure the model "
                         f"was graded on), got {x!r:.60}")
    return cal


def _effects(eff, user: dict, where: str, legacy=()) -> dict:
    from ehas_env.physics.effects import REGISTRY, resolve_effects
    from ehas_env.physics.effects.loading import effect_source, load_trusted

    if not isinstance(eff, dict) or not all(isinstance(v, dict) for v in eff.values()):
        raise ValueError(f"{where}: effects must map effect names to {{parameter: value}} objects")
    for n in eff:
        rec = user.get(n)
        if n not in REGISTRY and rec is not None:
            load_trusted(rec["sha256"])  # only a file of the user's trust list with exactly this text
        if n not in REGISTRY:
            if not isinstance(n, str) or n not in user and not legacy:
                break  # an unknown name: resolve_effects says so, with the list of effects
            what = f" (file {rec['file']}, sha256 {rec['sha256'][:12]}...)" if rec else ""
            old = f"; the file's effects_path {legacy} is not loaded: a model file never runs code" if legacy else ""
            raise ValueError(f"{where}: effect '{n}' is a user effect{what} that is not loaded; give the folder "
                             f"holding its file with --effects-path DIR (effects_path= in Python) or list that "
                             f"folder in your trust list (docs/model-file.md){old}")
        src = effect_source(n)
        if rec is not None and src is None:
            raise ValueError(f"{where}: user_effects names '{n}', but the loaded '{n}' is the library's own effect")
        if rec is not None and src[1] != rec["sha256"]:
            raise ValueError(f"{where}: effect '{n}': the loaded file {src[0]} (sha256 {src[1][:12]}...) is not "
                             f"the file the model was saved with (sha256 {rec['sha256'][:12]}...); give the folder "
                             "of that file with --effects-path")
    try:
        return resolve_effects(eff)
    except ValueError as exc:
        raise ValueError(f"{where}: effects: {exc}") from None


def _white_box(wb, where: str) -> dict:
    from dataclasses import fields as dc_fields

    from ehas_env.physics.white_box_valve import WhiteBoxValve

    if not isinstance(wb, dict):
        raise ValueError(f"{where}: valve.white_box must be an object of WhiteBoxValve parameters (SI)")
    names = {f.name: f for f in dc_fields(WhiteBoxValve)}
    out = {}
    for k, v in wb.items():
        if k not in names:
            raise ValueError(f"{where}: valve.white_box.{k} is not a white-box valve parameter; allowed: "
                             f"{', '.join(names)}")
        if k == "flow_forces":
            if not isinstance(v, bool):
                raise ValueError(f"{where}: valve.white_box.flow_forces must be true or false, got {v!r}")
            out[k] = v
        else:
            out[k] = Range(0, 1e12, "(SI)", lo_open=True).check(v, f"{where}: valve.white_box.{k}")
    return out


def _no_unknown(obj: dict, allowed, where: str, prefix: str) -> None:
    for k in obj:
        if k not in allowed:
            raise ValueError(f"{where}: {prefix}{k} is not a model-file field; allowed here: {', '.join(allowed)} "
                             "(docs/model-file.md)")


def _text(doc: dict, key: str, default: str, where: str) -> str:
    v = doc.get(key, default)
    if not isinstance(v, str) or len(v) > 2000:
        raise ValueError(f"{where}: {key} must be a text of at most 2000 characters, got {v!r:.60}")
    return v


def _num(obj: dict, key: str, default: float, bounds, where: str) -> float:
    return Range(bounds[0], bounds[1]).check(obj.get(key, default), f"{where}.{key}")


# -- writing -----------------------------------------------------------------------------------
def provenance(command: str | None = None, **extra) -> dict:
    """When, by which ehas and which command a model file was written."""
    from ehas_env import __version__

    out = {"created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
           "ehas_version": __version__}
    if command:
        out["command"] = command
    out.update(extra)
    return out


def write_model(path, model: PlantModel) -> Path:
    """Write ``model`` as a version-2 file atomically (checked by parsing it back first)."""
    doc = model_doc(model.replace(path=str(path)))
    parse_model(json.loads(json.dumps(doc)), str(path))
    return atomic_write_text(path, json.dumps(doc, indent=2) + "\n")


def save_model(path, effects: dict, *, beta: float | None = None, K: float | None = None,
               calibration: dict | None = None, base: PlantModel | None = None, name: str | None = None,
               command: str | None = None) -> Path:
    """Write a calibrated model: ``base`` (the book's rig by default) with ``effects`` and recalibrated beta, K.

    ``effects`` are the model's whole effect set (the base's own effects are kept
    unless ``effects`` names them again, with new values).

    Parameters
    ----------
    path : str or path
        The model JSON file to write (atomically; checked by reading it back first).
    effects : dict, list of str or str
        Effects to switch on, as :class:`~ehas_env.simulation.plant.Plant` takes them
        (``{"coulomb_friction": {"Fc": 412.0}}``), values in the effects' own units.
    beta : float, optional
        Recalibrated effective bulk modulus of the oil in Pa; None keeps the base's.
    K : float, optional
        Recalibrated valve flow gain at the rated drop in LPM/mA; None keeps the base's.
    calibration : dict, optional
        How the numbers were obtained (``campaign``, ``fit_percent_before``, ``fit_percent_after``,
        ...), stored as the file's ``calibration`` block.
    base : PlantModel, optional
        The model to start from (the book's rig by default).
    name : str, optional
        The model's name; by default the base's, or the file's stem when the base is the book's rig.
    command : str, optional
        The command that produced the model, recorded in ``provenance``.

    Returns
    -------
    Path
        The path of the written file.
    """
    from ehas_env.physics.effects import resolve_effects

    base = base or PlantModel()
    rig = base.rig.replace(**({"beta": float(beta)} if beta is not None else {}),
                           **({"K": float(K)} if K is not None else {}))
    merged = {**base.effects, **resolve_effects(effects)}
    prov = provenance(command, **({"based_on": base.label} if base.path or base.name != "book rig" else {}))
    m = base.replace(rig=rig, effects=merged, calibration=dict(calibration or {}), provenance=prov,
                     name=name or (Path(path).stem if base.name == "book rig" else base.name))
    return write_model(path, m)


# -- comparing ---------------------------------------------------------------------------------
def diff_models(a: PlantModel, b: PlantModel) -> list[str]:
    """Lines ``field: A -> B`` for every field that differs (numbers with units)."""
    out = []
    if a.name != b.name:
        out.append(f"name: {a.name!r} -> {b.name!r}")
    for f in FIELDS:
        va, vb = a.value(f), b.value(f)
        if not math.isclose(va, vb, rel_tol=1e-12):
            rel = f" ({100 * (vb - va) / va:+.2f} %)" if va else ""
            out.append(f"{f.path}: {va:.6g} -> {vb:.6g} {f.unit}{rel}")
    if a.valve != b.valve:
        out.append(f"valve.model: {a.valve} -> {b.valve}")
    for k in sorted(set(a.white_box) | set(b.white_box)):
        if a.white_box.get(k) != b.white_box.get(k):
            out.append(f"valve.white_box.{k}: {a.white_box.get(k, 'default')} -> {b.white_box.get(k, 'default')}")
    for n in sorted(set(a.effects) | set(b.effects)):
        pa, pb = a.effects.get(n), b.effects.get(n)
        if pa is None:
            out.append(f"effects.{n}: added " + ", ".join(f"{k}={v:g}" for k, v in pb.items()))
        elif pb is None:
            out.append(f"effects.{n}: removed")
        else:
            for k in sorted(set(pa) | set(pb)):
                if pa.get(k) != pb.get(k):
                    out.append(f"effects.{n}.{k}: {pa.get(k)} -> {pb.get(k)}")
    for n in sorted(set(a.user_effects) | set(b.user_effects)):
        ua, ub = a.user_effects.get(n), b.user_effects.get(n)
        if ua != ub:
            out.append(f"user_effects.{n}: {(ua or {}).get('sha256', 'none')[:12]} -> {(ub or {}).get('sha256', 'none')[:12]}")
    for key in ("calibration", "provenance"):
        if getattr(a, key) != getattr(b, key):
            out.append(f"{key}: differs")
    return out
