"""What an effect is, and the registry that finds effects by name."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar


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

    Subclasses set the class attributes and implement :meth:`apply`, which
    writes the effect's parameter values into the general model's parameter
    slots (see ``ehas_env.physics.kernel.SLOTS``).  Registering happens on subclassing.
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

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.name:
            if cls.name in REGISTRY:
                raise RuntimeError(f"effect name '{cls.name}' registered twice")
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
    def apply(cls, values: dict[str, float], slots: dict[str, float]) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    @classmethod
    def describe(cls) -> str:
        lines = [f"{cls.name}: {cls.title}", "", cls.explanation, "", f"Residual signature: {cls.signature}", "", "Parameters:"]
        for p in cls.params:
            lines.append(f"  {p.name} [{p.unit}] default {p.default:g}, bounds [{p.bounds[0]:g}, {p.bounds[1]:g}]: {p.doc}")
        return "\n".join(lines)


REGISTRY: dict[str, type[Effect]] = {}


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
