"""What an effect is, and the registry that finds effects by name.

An effect is one class in one file: its parameters (unit, default, bounds,
typical range), its explanation and residual signature in words, and its
physics: static methods named after the *places* of the model where it acts
(:data:`PLACES`).  :mod:`ehas_env.physics.codegen` copies those methods into
the compiled model; the plain-Python twin calls them as they are.
"""
from __future__ import annotations

import inspect
import math
from dataclasses import dataclass
from typing import ClassVar

#: where an effect's terms enter the model: place -> what the term returns
PLACES = {
    "valve_current": "the valve current after this effect, mA (gets the current so far as argument i)",
    "chamber_flows": "(flow added into chamber A, into chamber B), m^3/s",
    "piston_force": "force on the piston along +x (toward chamber B), N",
    "crank_torque": "torque on the crank along +theta, N m",
    "moving_mass": "mass added to the piston and rod, kg",
    "supply_rate": "rate of the supply pressure P_S, Pa/s (makes the supply a dynamic state)",
    "joint_force": ("force the rod-crank joint carries, N (makes piston and crank separate bodies; a constant "
                    "m_min, kg, of the effect is the least piston mass then)"),
    "state_rates": "time derivatives of the effect's own states (tuple, in the order of ``states``)",
}
#: quantities a term may take as arguments, besides its own parameters and constants and the
#: baseline slots (``layout.BASE_SLOTS``): SI values at the current instant
QUANTITIES = {
    "theta": "crank angle, rad", "omega": "crank rate, rad/s", "x": "piston position, m",
    "v": "piston velocity, m/s", "pa": "chamber A pressure, Pa", "pb": "chamber B pressure, Pa",
    "ps": "supply pressure, Pa", "p_load": "load pressure P_A - P_B, Pa", "qc": "valve no-load flow, m^3/s",
    "q_a": "valve flow into A, m^3/s", "q_b": "valve flow into B, m^3/s", "q_supply": "flow drawn from supply, m^3/s",
    "i": "valve current, mA", "xp": "piston position state, m", "vp": "piston velocity state, m/s",
    "gap": "rod-joint gap x - r sin(theta), m (joint_force)", "gap_rate": "its rate, m/s (joint_force)",
}


@dataclass(frozen=True)
class Param:
    """One parameter of an effect.

    Attributes
    ----------
    name : str
        The name users type (``Fc``, ``tau`` ...).
    unit : str
        SI unit.
    default : float
        Value used when the effect is switched on without this parameter.
    bounds : tuple of float
        (low, high) for fitting, and the range a user-given value must lie in.
    doc : str
        What the parameter is and where its default comes from.
    typical : tuple of float
        Realistic range for this rig (robustness tables, synthetic campaigns).
    log_scale : bool
        Fit on a log scale (parameters spanning decades, e.g. leakage).
    """

    name: str
    unit: str
    default: float
    bounds: tuple[float, float]
    doc: str
    typical: tuple[float, float] | None = None
    log_scale: bool = False
    #: factor from ``unit`` to SI: the terms see ``value * si`` (e.g. 1e5 for bar)
    si: float = 1.0

    def check(self, effect: str, value) -> float:
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"effect '{effect}': parameter '{self.name}' must be a number in {self.unit}, got {value!r}") from None
        lo, hi = self.bounds
        if not math.isfinite(v) or not lo <= v <= hi:
            raise ValueError(
                f"effect '{effect}': parameter '{self.name}' = {value!r} is outside its allowed range "
                f"[{lo:g}, {hi:g}] {self.unit}"
            )
        return v


class Effect:
    """A named physical addition to the baseline plant.

    Subclasses set the class attributes and write their physics as static
    methods named after :data:`PLACES` (or, for a recalibration of baseline
    numbers, :meth:`apply`).  Registering happens on subclassing; the contract
    is docs/effects-and-controllers.md.
    """

    name: ClassVar[str] = ""
    title: ClassVar[str] = ""
    params: ClassVar[tuple[Param, ...]] = ()
    main_param: ClassVar[str] = ""
    explanation: ClassVar[str] = ""
    signature: ClassVar[str] = ""
    #: "physical" effects are candidates for diagnosis; "recalibration" effects
    #: (bulk modulus, valve dynamics) re-fit baseline numbers.
    kind: ClassVar[str] = "physical"
    #: fixed values the terms read (Param objects; not fitted, not set by users)
    constants: ClassVar[tuple[Param, ...]] = ()
    #: the effect's own states: (name, unit, initial value in SI)
    states: ClassVar[tuple[tuple[str, str, float], ...]] = ()
    #: order in the valve-current chain (lower first)
    chain_order: ClassVar[int] = 0
    #: False for terms with no small-signal meaning at rest (sign functions, deadbands, play):
    #: the linearisation switches them off (ehas_env.physics.linearise)
    smooth: ClassVar[bool] = True

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.name:
            # a misspelt place would add nothing, silently
            strays = [k for k, v in vars(cls).items()
                      if isinstance(v, staticmethod) and not k.startswith("_") and k not in PLACES]
            if strays:
                raise ValueError(f"effect '{cls.name}': static method '{strays[0]}' is not a place where physics "
                                 f"enters; the places are {', '.join(PLACES)} (name a helper _{strays[0]})")
            if not cls.terms() and getattr(cls.apply, "__func__", None) is Effect.apply.__func__:
                raise ValueError(f"effect '{cls.name}' holds no physics: write at least one static method named "
                                 f"after a place ({', '.join(PLACES)}), or apply() for a recalibration")
            old = REGISTRY.get(cls.name)
            if old is not None and (old.__module__, old.__qualname__) != (cls.__module__, cls.__qualname__):
                raise RuntimeError(f"effect name '{cls.name}' registered twice: by {old.__module__} and {cls.__module__}")
            REGISTRY[cls.name] = cls

    @classmethod
    def param(cls, name: str) -> Param:
        for p in cls.params:
            if p.name == name:
                return p
        allowed = ", ".join(p.name for p in cls.params)
        raise ValueError(f"effect '{cls.name}' has no parameter '{name}'; its parameters are: {allowed}")

    @classmethod
    def resolve(cls, values: dict | None) -> dict[str, float]:
        """Defaults completed with ``values``, each checked against its bounds."""
        values = dict(values or {})
        out = {}
        for p in cls.params:
            out[p.name] = p.check(cls.name, values.pop(p.name)) if p.name in values else p.default
        if values:
            cls.param(next(iter(values)))  # raises naming the unknown parameter
        cls.validate(out)
        return out

    @classmethod
    def validate(cls, values: dict[str, float]) -> None:
        """Cross-parameter checks (override where parameters constrain each other)."""

    @classmethod
    def apply(cls, values: dict[str, float], slots: dict[str, float]) -> None:
        """Set baseline slots this effect recalibrates (bulk modulus, valve dynamics, delay).

        Effects that act through terms need not override it: their own slots
        (``"name.param"``, SI) are filled by :func:`effect_slots`.
        """

    @classmethod
    def adjust(cls, slots: dict[str, float], substep_s: float) -> None:
        """Last look at the finished slots (after every effect), e.g. to keep the model integrable."""

    @classmethod
    def terms(cls) -> dict:
        """{place: function} of the physics this effect contributes."""
        return {place: getattr(cls, place) for place in PLACES if callable(getattr(cls, place, None))}

    @classmethod
    def term_args(cls, place: str) -> list[str]:
        return list(inspect.signature(getattr(cls, place)).parameters)

    @classmethod
    def slot_names(cls) -> list[str]:
        """This effect's slots in a model: its on flag, parameters, then constants."""
        return [f"{cls.name}.on"] + [f"{cls.name}.{p.name}" for p in cls.params + cls.constants]

    @classmethod
    def describe(cls) -> str:
        lines = [f"{cls.name}: {cls.title}", "", cls.explanation, "", f"Residual signature: {cls.signature}", "", "Parameters:"]
        for p in cls.params:
            lines.append(f"  {p.name} [{p.unit}] default {p.default:g}, bounds [{p.bounds[0]:g}, {p.bounds[1]:g}]: {p.doc}")
        return "\n".join(lines)


REGISTRY: dict[str, type[Effect]] = {}


def effect_value(slots: dict, name: str, param: str) -> float:
    """Value (SI) of parameter ``param`` of effect ``name`` in a model's named slots, 0 when the effect is off."""
    return slots.get(f"{name}.{param}", 0.0) if slots.get(f"{name}.on") else 0.0


def mark_effects_on(slots: dict) -> dict:
    """Set the ``effects_on`` slot from the effects' on flags (0 lets the compiled model take the
    baseline's short path); call after changing any ``<effect>.on``.  Returns ``slots``."""
    slots["effects_on"] = 1.0 if any(v for k, v in slots.items() if k.endswith(".on")) else 0.0
    return slots


def effect_slots(name: str, values: dict[str, float] | None) -> dict[str, float]:
    """The model slots of effect ``name``: on flag 1 (0 when ``values`` is None), values in SI."""
    cls = get_effect(name)
    out = {f"{name}.on": 0.0 if values is None else 1.0}
    for p in cls.params:
        v = p.default if values is None else values[p.name]
        out[f"{name}.{p.name}"] = v * p.si
    for c in cls.constants:
        out[f"{name}.{c.name}"] = c.default * c.si
    return out


def get_effect(name: str) -> type[Effect]:
    """The effect class registered as ``name`` (ValueError naming the choices otherwise)."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown effect '{name}'; known effects: {', '.join(sorted(REGISTRY))}") from None


def resolve_effects(effects) -> dict[str, dict[str, float]]:
    """Normalise a user's effects spec to {name: {param: value}} with defaults.

    Accepts a mapping name -> params (or None for defaults), an iterable of
    names, or a string ``"name:p=v,p=v;name2"``-style spec (see :func:`parse_spec`).
    """
    if effects is None:
        return {}
    if isinstance(effects, str):
        effects = parse_spec(effects)
    if not isinstance(effects, dict):
        effects = {name: None for name in effects}
    return {name: get_effect(name).resolve(values) for name, values in effects.items()}


def parse_spec(text: str) -> dict[str, dict[str, float]]:
    """Parse the command-line form ``coulomb_friction:Fc=300,viscous_friction:b=2000``.

    A parameter assignment after a comma belongs to the last named effect.

    Examples
    --------
    >>> parse_spec("coulomb_friction:Fc=300,viscous_friction")
    {'coulomb_friction': {'Fc': 300.0}, 'viscous_friction': {}}
    >>> parse_spec("stribeck_friction:Fc=200,Fs=350")
    {'stribeck_friction': {'Fc': 200.0, 'Fs': 350.0}}
    """
    out: dict[str, dict[str, float]] = {}
    current = None
    for raw in text.replace(";", ",").split(","):
        item = raw.strip()
        if not item:
            continue
        if ":" in item:
            current, item = (part.strip() for part in item.split(":", 1))
            get_effect(current)
            out.setdefault(current, {})
            if not item:
                continue
        if "=" in item:
            if current is None:
                raise ValueError(f"effects spec: parameter '{item}' comes before any effect name")
            key, val = (part.strip() for part in item.split("=", 1))
            try:
                out[current][key] = float(val)
            except ValueError:
                raise ValueError(f"effects spec: value of '{current}:{key}' must be a number, got {val!r}") from None
        else:
            current = item
            get_effect(current)
            out.setdefault(current, {})
    return out
