"""The one controller interface shared by classical controllers and learned agents.

A controller is anything with

* ``kind`` - ``"classical"`` or ``"learned"`` (the benchmark's ``kind`` column);
* ``name`` - a short label for tables;
* ``reset()`` - forget the internal state (integrator, filters) before a run;
* ``act(measurement) -> float`` - the command current in mA for one control
  period.  ``measurement`` is exactly the dict the plant's closed loop passes
  (``ehas_env.simulation.plant.Plant._python_loop``): :data:`MEASUREMENT_KEYS` in deg,
  deg/s^k and bar;
* ``save(path)`` / ``load(path)`` - a file that ``ehas bench``, ``ehas tune`` and the
  environment accept;
* a readable ``repr`` of its gains with units.

Classical controllers can also give their compiled form for a given plant
(:meth:`Controller.rig_gains`: an object with ``law_id()`` and ``gains_vector()``;
a :class:`CompiledController` is its own), so simulations run the law compiled
into the model (``closed_loop`` of ``ehas_env/simulation/loops.py``, the batched
:mod:`ehas_controllers.batch_sim`, the environment's step) instead of calling
``act`` from Python every millisecond.

Files are found by type in two registries:

* :data:`LOADERS` maps a file suffix (``".json"``; ``"/"`` for a folder) to a
  loader ``path -> Controller``, or to a lazy ``"module:function"`` string;
* :data:`CONTROLLER_TYPES` maps the ``"type"`` field of a controller JSON to a
  factory ``dict -> Controller``.

Adding learned agents is one line, e.g.
``register_loader(".zip", "ehas_train.agent:load_agent")``.

Examples
--------
>>> from ehas_controllers.base import controller_from_dict
>>> c = controller_from_dict({"type": "piff", "gains": {"Kp": 1.0, "Ki": 2.0, "Kv": 0.0178, "Ka": 0.0002}})
>>> c.kind, round(c.act({"t": 0.0, "theta_deg": -1.0, "theta_ref_deg": 0.0, "theta_ref_dot": 0.0,
...     "theta_ref_ddot": 0.0, "theta_ref_dddot": 0.0, "p_a_bar": 110.0, "p_b_bar": 110.0, "p_s_bar": 220.0}), 6)
('classical', 1.002)
"""
from __future__ import annotations

import importlib
import json
import math
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Callable

#: keys of the measurement dict passed to :meth:`Controller.act` (deg, deg/s^k, bar, s)
MEASUREMENT_KEYS = ("t", "theta_deg", "theta_ref_deg", "theta_ref_dot", "theta_ref_ddot", "theta_ref_dddot",
                    "p_a_bar", "p_b_bar", "p_s_bar")
#: the ``format`` field of controller JSON files
FILE_FORMAT = "ehas-controller"
FILE_VERSION = 1
KINDS = ("classical", "learned")


class Controller(ABC):
    """Base class of every controller (see the module docstring for the contract)."""

    kind: str = "classical"
    name: str = "controller"

    def reset(self) -> None:
        """Forget internal state before a new run (default: stateless)."""

    @abstractmethod
    def act(self, measurement: dict) -> float:
        """Command current in mA for the period starting at ``measurement["t"]``.

        Parameters
        ----------
        measurement : dict of str to float
            The sample the plant's closed loop passes: :data:`MEASUREMENT_KEYS` - ``t`` (s),
            ``theta_deg`` (sensed crank angle, deg), ``theta_ref_deg`` and its derivatives
            ``theta_ref_dot``, ``theta_ref_ddot``, ``theta_ref_dddot`` (deg/s, deg/s^2, deg/s^3),
            ``p_a_bar``, ``p_b_bar``, ``p_s_bar`` (bar) - and the reference's ``amplitude_deg``.

        Returns
        -------
        float
            The servo current in mA, held for one control period (the plant clips it to its
            amplifier's +-20 mA).
        """

    def for_plant(self, disc_sets: int) -> "Controller":
        """The controller to use on a plant with ``disc_sets`` sets (gain schedules pick theirs).

        Parameters
        ----------
        disc_sets : int
            Number of disc sets on the plant's crank, 1..7.

        Returns
        -------
        Controller
            This controller (the base class has one set of gains for every plant).
        """
        return self

    def rig_gains(self, disc_sets: int | None = None):
        """This controller as an :class:`ehas_env.simulation.plant.RigController` for the compiled loop, or None.

        Parameters
        ----------
        disc_sets : int, optional
            Number of disc sets of the plant (a gain schedule's entry); None where the controller
            has one set of gains.

        Returns
        -------
        RigController or None
            The compiled form (an object with ``law_id()`` and ``gains_vector()``); None in the base
            class: the controller runs through :meth:`act` in Python.
        """
        return None

    def to_dict(self) -> dict:
        """JSON-able description; :func:`controller_from_dict` rebuilds the controller from it."""
        raise NotImplementedError(f"{type(self).__name__} cannot be written as a controller JSON")

    def save(self, path, *, command: str | None = None, metrics: dict | None = None, notes: dict | None = None) -> Path:
        """Write the controller as JSON, atomically.

        ``command`` (the command line that regenerates the file), ``metrics``
        (e.g. ``mean_rms_error_pct``) and ``notes`` (tuner report) are stored beside
        the gains.  Returns the path.

        Parameters
        ----------
        path : str or path
            The JSON file to write (``"format": "ehas-controller"``, version 1).
        command : str, optional
            The command line that regenerates the file.
        metrics : dict, optional
            Results of the controller (e.g. ``mean_rms_error_pct`` in %; that one is also stored at
            the top level).
        notes : dict, optional
            Free notes such as the tuner's report.

        Returns
        -------
        Path
            The path of the written file.

        Raises
        ------
        NotImplementedError
            If the controller has no JSON form (:meth:`to_dict`).
        """
        from ehas_env.output.files import atomic_write_text

        data = {"format": FILE_FORMAT, "version": FILE_VERSION, **self.to_dict()}
        if command:
            data["command"] = command
        if metrics:
            data["metrics"] = metrics
            if "mean_rms_error_pct" in metrics:
                data["mean_rms_error_pct"] = metrics["mean_rms_error_pct"]
        if notes:
            data["notes"] = notes
        return atomic_write_text(Path(path), json.dumps(_jsonable(data), indent=2) + "\n")

    @classmethod
    def load(cls, path) -> "Controller":
        """Load a controller file of any registered type (see :func:`load_controller`).

        Parameters
        ----------
        path : str or path
            A controller file (JSON, Python, or an agent folder; see :func:`load_controller`).

        Returns
        -------
        Controller
            The loaded controller, of whatever type the file holds (not necessarily ``cls``).
        """
        return load_controller(path)


class CompiledController(Controller):
    """A controller whose one law is compiled into the model (benchmark, environment, ``Plant``).

    A subclass is a dataclass of gains (floats, units in ``gain_units``) plus one
    static method ``law`` with the signature of
    :mod:`ehas_env.simulation.control_laws`; defining the subclass registers the
    law (under ``type_name``) and the JSON type.  ``act`` runs the same law in
    Python.  A user's controller is one such file, loaded with
    ``load_controller("my_ctrl.py")`` or given to any command as the controller file.
    """

    type_name = ""
    gain_units: dict = {}
    i_max: float = 20.0
    rate_hz: float = 1000.0

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.type_name and "law" in cls.__dict__:
            from ehas_env.simulation.control_laws import register_law

            register_law(cls.type_name, cls.__dict__["law"].__func__)
            CONTROLLER_TYPES[cls.type_name] = cls.from_dict

    def gain_names(self) -> list[str]:
        import dataclasses

        return [f.name for f in dataclasses.fields(self)] if dataclasses.is_dataclass(self) else []

    def gains_vector(self):
        import numpy as np

        from ehas_env.simulation.control_laws import N_GAINS

        names = self.gain_names()
        if len(names) > N_GAINS:
            raise ValueError(f"{type(self).__name__}: at most {N_GAINS} gains, got {len(names)}")
        g = np.zeros(N_GAINS)
        g[:len(names)] = [float(getattr(self, n)) for n in names]
        return g

    def law_id(self) -> int:
        from ehas_env.simulation.control_laws import law_id

        return law_id(self.type_name)

    def rig_gains(self, disc_sets: int | None = None):
        """The compiled form: this controller itself (it has ``law_id`` and ``gains_vector``)."""
        return self

    def reset(self) -> None:
        import numpy as np

        from ehas_env.simulation.control_laws import N_MEM

        self._mem = np.zeros(N_MEM)

    def act(self, measurement: dict) -> float:
        m = measurement
        if getattr(self, "_mem", None) is None:
            self.reset()
        return float(type(self).law(self.gains_vector(), self._mem, m["t"], 1.0 / self.rate_hz, m["theta_deg"],
                                    m["theta_ref_deg"], m["theta_ref_dot"], m["theta_ref_ddot"],
                                    m["theta_ref_dddot"], m["p_a_bar"] - m["p_b_bar"], m.get("p_s_bar", 0.0),
                                    self.i_max))

    def to_dict(self) -> dict:
        return {"type": self.type_name, "gains": {n: float(getattr(self, n)) for n in self.gain_names()}}

    @classmethod
    def from_dict(cls, data: dict) -> "CompiledController":
        import dataclasses

        names = [f.name for f in dataclasses.fields(cls)] if dataclasses.is_dataclass(cls) else []
        return cls(**gains_field(data, names))


def _load_py(path: Path) -> Controller:
    """A controller file in Python: its ``CONTROLLER`` object, or its one Controller subclass with defaults."""
    import hashlib
    import sys

    from ehas_env.plugin_import import import_file

    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:12]
    name = f"ehas_user_controllers.{path.stem}_{digest}"
    module = sys.modules.get(name)
    if module is None:  # with a time limit; exits, hangs and errors become one line naming the file
        module = import_file(path, name, "controller", setup="import ehas_controllers.base")
    ctrl = getattr(module, "CONTROLLER", None)
    if ctrl is None:
        classes = [c for c in vars(module).values() if isinstance(c, type) and issubclass(c, Controller)
                   and c.__module__ == name]
        if len(classes) != 1:
            raise ValueError(f"controller file {path}: define CONTROLLER = <a controller>, or exactly one Controller "
                             f"subclass (found {len(classes)})")
        ctrl = classes[0]()
    if not isinstance(ctrl, Controller):
        raise ValueError(f"controller file {path}: CONTROLLER must be an ehas_controllers.base.Controller")
    if isinstance(ctrl, CompiledController):  # every declared gain a finite number (a NaN default runs as NaN)
        for g in ctrl.gain_names():
            v = getattr(ctrl, g)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"controller file {path}: gain {g} = {v!r}; every gain must be a finite number")
        if not isinstance(getattr(ctrl, "name", ""), str) or not str(getattr(ctrl, "name", "")).strip():
            raise ValueError(f"controller file {path}: name must be a non-empty text")
    ctrl.source = str(path)
    LOADED_FILES[str(path.resolve())] = ctrl
    return ctrl


#: Python controller files loaded in this process (resolved path -> controller): the ones the user named on
#: the command line.  A training config or an agent folder that names a ``.py`` file uses it only from here.
LOADED_FILES: dict = {}


def loaded_file(path, where: str) -> "Controller":
    """The controller of the Python file ``path`` a config or agent folder names, if the user loaded it (command
    line); otherwise a one-line ValueError: data never imports code."""
    key = str(Path(path).resolve())
    if key not in LOADED_FILES:
        raise ValueError(f"{where} names the Python controller file {path}; a config or an agent folder never "
                         f"imports code: give the file on the command line with --controller-path {path}")
    return LOADED_FILES[key]


def gains_field(data: dict, names) -> dict:
    """The ``"gains"`` object of a controller description: present, an object, not empty, only known names.

    The values are checked by the controller itself (finite numbers in their ranges).

    >>> gains_field({"type": "piff"}, ["Kp", "Ki"])
    Traceback (most recent call last):
    ...
    ValueError: no 'gains' field; expected "gains": {gain name: number} with some of Kp, Ki
    """
    names = list(names)
    expected = f"some of {', '.join(names)}" if names else "the controller's gains"
    if "gains" not in data:
        raise ValueError(f"no 'gains' field; expected \"gains\": {{gain name: number}} with {expected}")
    gains = data["gains"]
    if not isinstance(gains, dict):
        raise ValueError(f"'gains' must be an object of gain name -> number ({expected}), got {gains!r}")
    if not gains and names:
        raise ValueError(f"'gains' is empty; expected {expected}")
    unknown = set(gains) - set(names)
    if unknown:
        raise ValueError(f"unknown gain(s) {', '.join(sorted(map(str, unknown)))} in 'gains'; expected {expected}")
    return dict(gains)


def check_measurement(measurement: dict, who: str) -> None:
    """Raise a clear error naming the missing key if ``measurement`` lacks one of :data:`MEASUREMENT_KEYS`."""
    for key in MEASUREMENT_KEYS:
        if key not in measurement:
            raise ValueError(f"{who}.act: measurement has no '{key}'; expected the keys {', '.join(MEASUREMENT_KEYS)}")


# -- registries -----------------------------------------------------------------
CONTROLLER_TYPES: dict[str, Callable[[dict], Controller]] = {}
LOADERS: dict[str, Callable | str] = {}
#: modules imported before loading so that they can register their types/loaders
PLUGIN_MODULES: list[str] = ["ehas_controllers.piff", "ehas_controllers.ilc", "ehas_controllers.harmonic",
                               "ehas_controllers.drive",  # drive files replayed (ehas export-drive)
                               "ehas_train.agent"]  # ehas_train.agent: learned agents


def register_type(name: str):
    """Class decorator: ``cls.from_dict`` builds controllers whose JSON ``type`` is ``name``."""

    def deco(cls):
        CONTROLLER_TYPES[name] = cls.from_dict
        cls.type_name = name
        return cls

    return deco


#: options of the loaders, set by the command line (``--allow-pickle``: a legacy pickled agent folder may load)
LOAD_OPTIONS = {"allow_pickle": False}


def register_loader(suffix: str, loader: Callable | str) -> None:
    """Load files ending in ``suffix`` (``"/"``: folders) with ``loader(path)`` or ``"module:function"``."""
    LOADERS[suffix.lower()] = loader


def _import_plugins() -> None:
    for name in PLUGIN_MODULES:
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise


def controller_from_dict(data: dict) -> Controller:
    """Rebuild a controller from its JSON description (the ``type`` field picks the factory)."""
    _import_plugins()
    if not isinstance(data, dict):
        raise ValueError(f"controller description must be a JSON object, got {type(data).__name__}")
    kind = data.get("type")
    if kind is None and "gains" in data:
        kind = "piff"  # a bare gains file
    if kind not in CONTROLLER_TYPES:
        raise ValueError(f"controller 'type' {kind!r} is unknown; known types: {', '.join(sorted(CONTROLLER_TYPES))}")
    return CONTROLLER_TYPES[kind](data)


#: what a controller JSON file is, for the errors of the file reader (ehas_env.output.files)
CONTROLLER_FILE = f'a controller JSON file ("format": "{FILE_FORMAT}", written by ehas tune)'


def _load_json(path: Path) -> Controller:
    from ehas_env.output.files import read_json

    data = read_json(path, CONTROLLER_FILE)
    where = f"controller file {path}"
    check_file_header(data, where)
    try:
        ctrl = controller_from_dict(data)
    except (ValueError, TypeError, KeyError) as exc:
        raise ValueError(f"{where}: {exc}") from None
    if "kind" in data and data["kind"] != getattr(ctrl, "kind", None):
        raise ValueError(f"{where}: key 'kind' = {data['kind']!r}, but a {data['type']!r} controller is "
                         f"{getattr(ctrl, 'kind', None)!r}; remove the key or set it to {getattr(ctrl, 'kind', None)!r}")
    ctrl.source = str(path)
    return ctrl


def check_file_header(data, where: str) -> None:
    """Refuse a controller JSON without this format's ``format``, ``version`` and a known ``type``.

    The same words for every file format ehas reads: what the key holds and what is expected.
    An optional ``kind`` must be one of :data:`KINDS` (:func:`load_controller` checks it is the
    type's own).
    """
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected a JSON object with \"format\": \"{FILE_FORMAT}\", got {type(data).__name__}")
    if "format" not in data:
        raise ValueError(f"{where}: no 'format' key; expected \"format\": \"{FILE_FORMAT}\" (a file written by "
                         "ehas tune)")
    if data["format"] != FILE_FORMAT:
        raise ValueError(f"{where}: key 'format' = {data['format']!r}; expected {FILE_FORMAT!r}")
    if data.get("version") != FILE_VERSION:
        raise ValueError(f"{where}: key 'version' = {data.get('version')!r}; this ehas reads version {FILE_VERSION}")
    _import_plugins()
    known = ", ".join(sorted(CONTROLLER_TYPES))
    if "type" not in data:
        raise ValueError(f"{where}: no 'type' key; expected one of {known}")
    if not isinstance(data["type"], str) or data["type"] not in CONTROLLER_TYPES:
        what = "is unknown" if isinstance(data["type"], str) else "is not a type name"
        raise ValueError(f"{where}: key 'type' = {data['type']!r} {what}; expected one of {known}")
    if "kind" in data and data["kind"] not in KINDS:
        raise ValueError(f"{where}: key 'kind' = {data['kind']!r}; expected one of {', '.join(map(repr, KINDS))} "
                         "(or no 'kind' key)")


register_loader(".json", _load_json)
register_loader(".py", _load_py)


def load_controller(path) -> Controller:
    """Load a controller from ``path``, choosing the loader by the file's suffix.

    Raises FileNotFoundError for a missing file and ValueError for an unknown type.

    Parameters
    ----------
    path : str or path
        The controller file: a ``.json`` controller file (written by ``ehas tune`` or
        :meth:`Controller.save`), a ``.py`` controller file (its ``CONTROLLER`` object or its one
        Controller subclass), or a folder / other suffix with a loader of :data:`LOADERS` (learned
        agents).

    Returns
    -------
    Controller
        The loaded controller (``kind`` ``"classical"`` or ``"learned"``).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        No loader for the suffix, an invalid file, or a loaded object of an unknown ``kind``.
    """
    _import_plugins()
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"controller file {path} does not exist")
    key = "/" if path.is_dir() else path.suffix.lower()
    loader = LOADERS.get(key)
    if loader is None:
        known = ", ".join(sorted(LOADERS))
        raise ValueError(f"controller file {path}: no loader for '{key}' files; known types: {known}")
    if isinstance(loader, str):
        module, _, func = loader.partition(":")
        loader = getattr(importlib.import_module(module), func)
    ctrl = loader(path)
    kind = getattr(ctrl, "kind", None)
    if kind not in KINDS:
        raise ValueError(f"controller file {path}: loaded object has kind {kind!r}, expected one of {KINDS}")
    return ctrl


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalars
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
