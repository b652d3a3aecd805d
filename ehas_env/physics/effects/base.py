"""What an effect is, and the registry that finds effects by name.

An effect is one class in one file: its parameters (unit, default, bounds,
typical range), its explanation and residual signature in words, and its
physics: static methods named after the *places* of the model where it acts
(:data:`PLACES`).  :mod:`ehas_env.physics.codegen` copies those methods into
the compiled model; the plain-Python twin calls them as they are.
"""
from __future__ import annotations

import builtins
import dis
import inspect
import math
import numbers
import re
import types
from dataclasses import dataclass
from typing import ClassVar

from ehas_env.physics.layout import RATE_QUANTITIES as _RATE_QUANTITIES
from ehas_env.physics.model_source import place_scopes as _place_scopes
from ehas_env.physics.layout import SENSED as _SENSED
from ehas_env.physics.layout import STATE_NAMES as _BASELINE_STATES

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
    "coil_current": ("the current the valve's torque motor acts on, mA (gets the current after the current chain "
                     "as argument i; evaluated inside the right-hand side and on the valve bench, so it may read the "
                     "effect's own states: a lag of the coil current)"),
    "position_reading": ("the piston position the position sensor (LVDT) reads, m (gets the reading so far as "
                         "argument x; the angle the rig logs and its controller sees is asin(reading / r); it "
                         "may read the effect's own states: a lag of the reading)"),
    "land_pressures": ("(pressure at the valve's supply land, at its return lands), Pa: what the lands meter "
                       "between (gets them so far as arguments p_sup, p_ret: the supply pressure and the tank's 0 "
                       "unless an effect puts a line's drop or a back pressure between; it may use the valve's "
                       "opening qc and the supply pressure ps)"),
    "land_flows": ("(flow out of the valve's port A, out of port B), m^3/s: what each land passes (gets them so far "
                   "as arguments q_a, q_b: the orifice law's between the lands' pressures unless an effect changes a "
                   "land's flow; it may use the valve's opening qc, the ports' pressures pa, pb and the supply "
                   "pressure ps; the supply's draw stays the orifice law's)"),
    "port_pressures": ("(pressure at the valve's port A, at its port B), Pa: where the flow meter in line A "
                       "meters the land's flow (gets the ports' pressures so far as arguments pa, pb, the "
                       "chambers' unless an effect puts something between; it may read the effect's own states: "
                       "a hose's line pressure)"),
}
for _out, (_arg, _unit, _rate, _words, _span) in _SENSED.items():
    PLACES[f"{_out}_reading"] = (f"{_words}, {_unit} (gets the reading so far as argument {_arg}; it may read the "
                                 f"effect's own states: a lag of the reading)")
@dataclass(frozen=True)
class Local:
    """One quantity of the model a term may take as an argument, described once (the balances' blocks of
    :mod:`ehas_env.physics.balance_blocks` and the proposal's grammar of :mod:`ehas_env.physics.term_grammar` read
    their units, sizes and words from here).

    Attributes
    ----------
    arg : str
        Its argument name in a term (``x``, ``omega``, ``p_load``).
    name : str
        Its name in a place's short name (``position``, ``load_pressure``).
    unit : str
        Its SI unit (the valve's current: mA, as everywhere in the model).
    words : str
        What it is.
    symbol : str
        Its symbol in a law (``x``, ``p_A``).
    span : float
        Its typical size on the book's rig (0: not sized; a term of it is not tried).
    shown : tuple
        How words show it: (factor from the SI unit, unit).
    """

    arg: str
    name: str
    unit: str
    words: str
    symbol: str = ""
    span: float = 0.0
    shown: tuple = (1.0, "")


_BAR_SHOWN = (1.0e-5, "bar")
_LPM_SHOWN = (60000.0, "L/min")
#: every quantity a term may take as an argument, besides its own parameters and constants and the baseline slots
#: (``layout.BASE_SLOTS``): SI values at the current instant.  Spans (assumed, the book's rig): the piston's +-25 mm
#: at +-30 deg of the 50 mm crank, 0.5 m/s at 3 Hz; the crank's +-30 deg and 10 rad/s; a load and a chamber's
#: pressure of 100 bar; the valve's rated 25 L/min; its current's 7.5 mA of a 10 mA rating
LOCALS = {q.arg: q for q in (
    Local("theta", "angle", "rad", "the crank angle", "theta", 0.5236, (180.0 / math.pi, "deg")),
    Local("omega", "rate", "rad/s", "the crank rate", "omega", 10.0, (1.0, "rad/s")),
    Local("x", "position", "m", "the piston position", "x", 0.025, (1.0e3, "mm")),
    Local("v", "velocity", "m/s", "the piston velocity", "v", 0.5, (1.0, "m/s")),
    Local("pa", "pressure_a", "Pa", "chamber A's pressure", "p_A", 1.0e7, _BAR_SHOWN),
    Local("pb", "pressure_b", "Pa", "chamber B's pressure", "p_B", 1.0e7, _BAR_SHOWN),
    Local("ps", "supply_pressure", "Pa", "the supply pressure", "p_S", 1.0e7, _BAR_SHOWN),
    Local("p_load", "load_pressure", "Pa", "the load pressure p_A - p_B", "p_L", 1.0e7, _BAR_SHOWN),
    Local("qc", "opening", "m^3/s", "the valve's no-load flow", "q_c", 25.0 / 60000.0, _LPM_SHOWN),
    Local("q_a", "flow_a", "m^3/s", "land A's flow", "q_A", 25.0 / 60000.0, _LPM_SHOWN),
    Local("q_b", "flow_b", "m^3/s", "land B's flow", "q_B", 25.0 / 60000.0, _LPM_SHOWN),
    Local("q_supply", "supply_flow", "m^3/s", "the flow drawn from the supply", "q_S"),
    Local("i", "current", "mA", "the valve current", "i", 7.5, (1.0, "mA")),
    Local("xp", "position_state", "m", "the piston position state", "x_p"),
    Local("vp", "velocity_state", "m/s", "the piston velocity state", "v_p"),
    Local("gap", "gap", "m", "the rod-joint gap x - r sin(theta) (joint_force)", "g"),
    Local("gap_rate", "gap_rate", "m/s", "the rod-joint gap's rate (joint_force)", "g'"),
    Local("qc_dot", "opening_rate", "m^3/s^2", "the rate of the valve's no-load flow", "q_c'"),
    Local("q", "metered_flow", "m^3/s", "the flow the meter in line A meters, before its reading chain", "q"),
)}
#: the same in one line each (the registry's messages)
QUANTITIES = {q.arg: f"{q.words}, {q.unit}" for q in LOCALS.values()}
#: the sensed outputs' rates, known where the effects' state rates are computed (after the balances)
RATE_QUANTITIES = _RATE_QUANTITIES


def _place_quantities(site) -> frozenset:
    """The quantities a term may take at a place: the values its chain passes on and every quantity the model
    describes (:data:`LOCALS`, :data:`RATE_QUANTITIES`) that the generated model has bound where the place's terms
    are called (:func:`ehas_env.physics.model_source.place_scopes`); the model's other names there (the piston force
    summed so far, sin theta) are its own workings, not quantities."""
    return frozenset(site.chain) | (site.bound & (set(LOCALS) | set(RATE_QUANTITIES)))


_SITES = _place_scopes()
_UNCALLED = sorted(set(PLACES) - set(_SITES))
if _UNCALLED:  # a place the generated model never calls would take terms that never act
    raise RuntimeError(f"places the generated model calls no term at: {', '.join(_UNCALLED)} "
                       "(ehas_env.physics.model_source.ModelSource._assembled)")
#: the quantities the compiled model has defined where each place's terms are called, read from the generated model
#: itself (:func:`_place_quantities`; a term's arguments resolve through :meth:`Effect.arg_kind`, in the check at
#: registration and in :mod:`ehas_env.physics.codegen`): a quantity the assembled right-hand side computes before a
#: place is one a term there may take, without a list beside it
PLACE_QUANTITIES = {place: _place_quantities(_SITES[place]) for place in PLACES}
#: the quantities a valve-side chamber_flows term (``Effect.valve_side``) may take: the valve's own, known
#: wherever a flow is metered (a run's line A, the valve bench): what ``valve_side_flows`` of the generated model has
VALVE_SIDE_QUANTITIES = tuple(sorted(_place_quantities(_SITES["valve_side"])))
#: what an effect is (Effect.kind)
KINDS = ("physical", "recalibration", "hypothesis")
#: how many numbers a term returns at each place (state_rates: one per state, a number for one state)
RETURNS = {"chamber_flows": 2, "port_pressures": 2, "land_pressures": 2, "land_flows": 2}
#: the only outside names a term's body may use: the compiled model copies the body alone into a module
#: that imports these (ehas_env.physics.codegen)
TERM_GLOBALS = ("math", "np")
#: what an effect's name (and its parameters' and states' names) may be: it is typed in
#: ``--effects NAME:param=value`` and becomes part of Python names in the compiled model
NAME_RULE = "letters, digits and _, not starting with a digit"
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


@dataclass(frozen=True)
class Param:
    """One parameter of an effect.

    Attributes
    ----------
    name : str
        The name users type (``Fc``, ``tau`` ...).
    unit : str
        Unit of the values users give and see: SI, or an engineering unit (bar, LPM, L) with
        ``si`` its factor to SI.
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
    si : float
        Factor from ``unit`` to SI (1 for SI units, 1e5 for bar): the terms see ``value * si``.
    limit : tuple of str, optional
        ``(end, words)``: the end of the range (``"lower"`` or ``"upper"``) where the block takes a limit that is
        still the same physics, and what it is there (a hose's volume at its lower end: the line's resistance
        alone, its oil too little for the logs to resolve).  A fit at that end is no sign that the block stands
        in for another; at any other end it is.
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
    #: (end, words): the end of the range where the block takes a limit that is still its physics (None: none)
    limit: tuple[str, str] | None = None

    def limit_at(self, end: str | None) -> str | None:
        """What the block is at ``end`` of the range when it takes its limit there.

        Parameters
        ----------
        end : str or None
            ``"lower"`` or ``"upper"`` (a fit's :meth:`~ehas_env.diagnosis.fitting.FreeParam.end`; None: inside).

        Returns
        -------
        str or None
            The words of :attr:`limit` at that end; else None (a fit at that end is then no value of the block).

        Examples
        --------
        >>> p = Param("V", "m^3", 1.0, (0.5, 2.0), "a volume", limit=("lower", "a resistance alone"))
        >>> p.limit_at("lower"), p.limit_at("upper")
        ('a resistance alone', None)
        """
        return self.limit[1] if self.limit is not None and self.limit[0] == end else None

    def problem(self) -> str | None:
        """What is wrong with this declaration (None when nothing): the rules every effect's parameters and
        constants are held to when the effect registers.

        Returns
        -------
        str or None
            One sentence naming the first broken rule (name, unit, bounds, default, typical range,
            ``si``, doc, ``log_scale``, a name taken by a model quantity), or None.
        """
        def real(v):
            return isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)

        def pair(v):
            return isinstance(v, (tuple, list)) and len(v) == 2 and all(real(x) for x in v)

        if not isinstance(self.name, str) or not _NAME.match(self.name):
            return f"name {self.name!r} is not allowed: use {NAME_RULE} (it is typed in --effects NAME:{self.name}=value)"
        if not isinstance(self.unit, str):
            return f"unit must be a string (e.g. 'N', '-'), got {self.unit!r}"
        if not pair(self.bounds):
            return f"bounds must be (low, high), two finite numbers, got {self.bounds!r}"
        lo, hi = self.bounds
        if lo > hi:
            return f"bounds ({lo:g}, {hi:g}) are reversed: give (low, high) with low <= high"
        if not real(self.default):
            return f"default must be a finite number in {self.unit}, got {self.default!r}"
        if not lo <= self.default <= hi:
            return f"default {self.default:g} is outside its bounds [{lo:g}, {hi:g}] {self.unit}"
        if self.typical is not None:
            if not pair(self.typical):
                return f"typical must be (low, high), two finite numbers, or None, got {self.typical!r}"
            tlo, thi = self.typical
            if not lo <= tlo <= thi <= hi:
                return (f"typical ({tlo:g}, {thi:g}) must be a range (low <= high) inside its bounds "
                        f"[{lo:g}, {hi:g}] {self.unit}")
        if not real(self.si) or self.si <= 0:
            return f"si must be a positive number (the factor from {self.unit} to SI), got {self.si!r}"
        if not isinstance(self.doc, str):
            return f"doc must be a string, got {self.doc!r}"
        if not isinstance(self.log_scale, bool):
            return f"log_scale must be True or False, got {self.log_scale!r}"
        if self.limit is not None and not (isinstance(self.limit, tuple) and len(self.limit) == 2
                                           and self.limit[0] in ("lower", "upper") and isinstance(self.limit[1], str)
                                           and self.limit[1]):
            return (f"limit must be None or (end, words) with end 'lower' or 'upper' and words what the block is "
                    f"there, got {self.limit!r}")
        if self.name in QUANTITIES:
            return (f"name {self.name!r} is a model quantity a term can take ({QUANTITIES.get(self.name, self.name)}); "
                    "a parameter needs a name of its own")
        return None

    def check(self, effect: str, value) -> float:
        """A user-given value of this parameter, checked against its bounds.

        Parameters
        ----------
        effect : str
            Name of the effect the parameter belongs to (named in the error).
        value : float
            The value, in the parameter's ``unit`` (not SI-converted); text and booleans are refused.

        Returns
        -------
        float
            ``value`` as a float, in the parameter's ``unit``.

        Raises
        ------
        ValueError
            If the value is not a finite number within ``bounds``.
        """
        try:
            if isinstance(value, (str, bytes, bool)):  # a file's "300" or true is not a number: say so
                raise TypeError
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
    #: (bulk modulus, valve dynamics) re-fit baseline numbers; "hypothesis" effects open a structural
    #: constant of the baseline (an area, the return pressure, a gain per direction): the diagnosis tries
    #: them when the library's effects leave the campaign unexplained.
    kind: ClassVar[str] = "physical"
    #: fixed values the terms read (Param objects; not fitted, not set by users)
    constants: ClassVar[tuple[Param, ...]] = ()
    #: the effect's own states: (name, unit, initial value in SI)
    states: ClassVar[tuple[tuple[str, str, float], ...]] = ()
    #: own states that at rest equal a state of the baseline ({own state: baseline state name}, e.g. a hose's line
    #: pressure its chamber's): they start where that one starts, whatever the rig's supply, not at the declared
    #: value (:func:`ehas_env.simulation.plant.at_rest`)
    rests_at: ClassVar[dict] = {}
    #: (hypotheses) library effects that fit this hypothesis' residual as well, being another law of the same
    #: signature (a transport delay for a coil's lag): when the diagnosis keeps one of them, it fits this
    #: hypothesis in its place and keeps whichever the validation data prefer (the other is named a stand-in)
    mistaken_for: ClassVar[tuple[str, ...]] = ()
    #: order in the valve-current chain (lower first)
    chain_order: ClassVar[int] = 0
    #: False for terms with no small-signal meaning at rest (sign functions, deadbands, play):
    #: the linearisation switches them off (ehas_env.physics.linearise)
    smooth: ClassVar[bool] = True
    #: True when the effect's ``chamber_flows`` term is flow through the valve's metering lands (a lap, the
    #: return or supply pressure at the lands): it then shows in the flows a meter reads (line A in a run, the
    #: bench's meter with the ports joined), not only in the chambers.  Such a term may use the valve's
    #: quantities only (:data:`VALVE_SIDE_QUANTITIES`).
    valve_side: ClassVar[bool] = False
    #: values of the main parameter the diagnosis' scan tries before it fits (0: the fit's default,
    #: ehas_env.diagnosis.fitting.SCAN_POINTS): a cost whose valley is narrower than the default scan's
    #: spacing (the play of a joint) needs a finer scan, or the fit starts beside the valley
    scan_points: ClassVar[int] = 0

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.name:
            cls._check_declaration()
            # a misspelt place would add nothing, silently
            strays = [k for k, v in vars(cls).items()
                      if isinstance(v, staticmethod) and not k.startswith("_") and k not in PLACES]
            if strays:
                raise ValueError(f"effect '{cls.name}': static method '{strays[0]}' is not a place where physics "
                                 f"enters; the places are {', '.join(PLACES)} (name a helper _{strays[0]})")
            odd = [k for k in PLACES if k in vars(cls) and not isinstance(vars(cls)[k], staticmethod)]
            if odd:  # a number or a plain method at a place would be skipped, silently
                raise ValueError(f"effect '{cls.name}': {odd[0]} must be a @staticmethod (the place's physics term), "
                                 f"got {type(vars(cls)[odd[0]]).__name__}")
            if not cls.terms() and getattr(cls.apply, "__func__", None) is Effect.apply.__func__:
                raise ValueError(f"effect '{cls.name}' holds no physics: write at least one static method named "
                                 f"after a place ({', '.join(PLACES)}), or apply() for a recalibration")
            cls._check_terms()
            old = REGISTRY.get(cls.name)
            if old is not None and (old.__module__, old.__qualname__) != (cls.__module__, cls.__qualname__):
                raise RuntimeError(f"effect name '{cls.name}' registered twice: by {old.__module__} and {cls.__module__}")
            REGISTRY[cls.name] = cls

    @classmethod
    def _check_declaration(cls) -> None:
        """The rules of an effect's declaration, the library's and a user's alike (one-line ValueErrors naming
        the effect, its class and the field)."""
        if not isinstance(cls.name, str) or not _NAME.match(cls.name):
            hint = re.sub(r"\W", "_", cls.name) if isinstance(cls.name, str) else "my_effect"
            raise ValueError(f"effect class {cls.__qualname__}: name {cls.name!r} is not allowed: use {NAME_RULE} "
                             f"(it is typed in --effects NAME:param=value), e.g. {hint!r}")
        who = f"effect '{cls.name}' (class {cls.__qualname__})"
        names: dict[str, str] = {}
        for field in ("params", "constants"):
            items = getattr(cls, field)
            if isinstance(items, list):
                items = tuple(items)
                setattr(cls, field, items)
            if not isinstance(items, tuple):
                raise ValueError(f"{who}: {field} must be a tuple of Param(...), e.g. {field} = (Param(...),) "
                                 f"(mind the comma after a single one), got {type(items).__name__}")
            for k, p in enumerate(items):
                if not isinstance(p, Param):
                    raise ValueError(f"{who}: {field}[{k}] must be a Param(...), got {type(p).__name__} {p!r:.60}")
                problem = p.problem()
                if problem:
                    what = "parameter" if field == "params" else "constant"
                    raise ValueError(f"{who}: {what} '{p.name}': {problem}")
                if p.name in names:
                    where = f"in {field}" if names[p.name] == field else f"in {names[p.name]} and {field}"
                    raise ValueError(f"{who}: '{p.name}' is declared twice ({where}); parameters and constants "
                                     "need distinct names")
                names[p.name] = field
        states = cls.states
        if isinstance(states, list):
            states = cls.states = tuple(states)
        if not isinstance(states, tuple):
            raise ValueError(f"{who}: states must be a tuple of (name, unit, initial value in SI), got "
                             f"{type(states).__name__}")
        for k, st in enumerate(states):
            if not (isinstance(st, tuple) and len(st) == 3 and isinstance(st[0], str) and isinstance(st[1], str)
                    and isinstance(st[2], numbers.Real) and not isinstance(st[2], bool) and math.isfinite(st[2])):
                raise ValueError(f"{who}: states[{k}] must be (name, unit, initial value in SI) with a finite "
                                 f"initial value, got {st!r}")
            if not _NAME.match(st[0]):
                raise ValueError(f"{who}: state name {st[0]!r} is not allowed: use {NAME_RULE}")
            if st[0] in names:
                raise ValueError(f"{who}: '{st[0]}' is declared twice (in {names[st[0]]} and states); parameters, "
                                 "constants and states need distinct names")
            names[st[0]] = "states"
        if "state_rates" in cls.terms() and not states:
            raise ValueError(f"{who}: state_rates gives the rates of the effect's own states, but it declares no "
                             "states = ((name, unit, initial value in SI), ...)")
        mine = [st[0] for st in states]
        for own_state, base in dict(cls.rests_at).items():
            if own_state not in mine or base not in _BASELINE_STATES:
                raise ValueError(f"{who}: rests_at maps one of its own states ({', '.join(mine) or 'none'}) to a "
                                 f"state of the baseline ({', '.join(_BASELINE_STATES)}), got {own_state!r}: {base!r}")
        own = [p.name for p in cls.params]
        if not isinstance(cls.main_param, str):
            raise ValueError(f"{who}: main_param must be the name of one of its parameters "
                             f"({', '.join(own) or 'it has none'}), got {cls.main_param!r}")
        if cls.main_param and cls.main_param not in own:
            raise ValueError(f"{who}: main_param '{cls.main_param}' is not one of its parameters "
                             f"({', '.join(own) or 'it has none'})")
        if not cls.main_param and own:
            cls.main_param = own[0]  # documented default: the first parameter
        if type(cls.scan_points) is not int or not 0 <= cls.scan_points <= 200:
            raise ValueError(f"{who}: scan_points must be an integer in [0, 200] (0: the fit's default), got "
                             f"{cls.scan_points!r}")
        for flag in ("smooth", "valve_side"):
            if not isinstance(getattr(cls, flag), bool):
                raise ValueError(f"{who}: {flag} must be True or False, got {getattr(cls, flag)!r}")
        if cls.valve_side and "chamber_flows" in cls.terms():
            fn = getattr(cls.terms()["chamber_flows"], "__func__", cls.terms()["chamber_flows"])
            for arg in inspect.signature(fn).parameters:
                if arg in QUANTITIES and arg not in VALVE_SIDE_QUANTITIES:
                    raise ValueError(f"{who}: valve_side = True, but its chamber_flows term takes '{arg}': a term "
                                     f"at the valve's lands may use {', '.join(VALVE_SIDE_QUANTITIES)} only")
        if isinstance(cls.mistaken_for, list):
            cls.mistaken_for = tuple(cls.mistaken_for)
        if not isinstance(cls.mistaken_for, tuple) or not all(isinstance(n, str) and _NAME.match(n)
                                                              for n in cls.mistaken_for):
            raise ValueError(f"{who}: mistaken_for must be a tuple of effect names, e.g. ('transport_delay',), "
                             f"got {cls.mistaken_for!r}")
        if isinstance(cls.chain_order, bool) or not isinstance(cls.chain_order, int):
            raise ValueError(f"{who}: chain_order must be an integer, got {cls.chain_order!r}")
        for text in ("explanation", "signature", "title"):
            if hasattr(cls, text) and not isinstance(getattr(cls, text), str):
                raise ValueError(f"{who}: {text} must be a text, got {type(getattr(cls, text)).__name__}")
        if cls.kind not in KINDS:
            raise ValueError(f"{who}: kind must be one of {', '.join(repr(k) for k in KINDS)}, got {cls.kind!r}")
        try:
            cls.validate({p.name: p.default for p in cls.params})
        except ValueError as exc:
            raise ValueError(f"{who}: its parameters' defaults fail its own validate(): {exc}") from None

    @classmethod
    def _check_terms(cls) -> None:
        """Call each term once, as plain Python, with realistic values; what it returns must be what its
        place takes (compiling a wrong one fails deep inside numba).  One-line ValueErrors naming the
        effect and the term."""
        who = f"effect '{cls.name}' (class {cls.__qualname__})"
        point = _sample_point()
        own = {p.name: p.default * p.si for p in cls.params + cls.constants}
        own_states = {st[0]: float(st[2]) for st in cls.states}
        for place, fn in cls.terms().items():
            fn = getattr(fn, "__func__", fn)
            code = getattr(fn, "__code__", None)
            if code is None:
                raise ValueError(f"{who}: {place} must be a static method (def {place}(...)), got {fn!r:.60}")
            sig = inspect.signature(fn)
            odd = [p.name for p in sig.parameters.values()
                   if p.kind not in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
            if odd:
                raise ValueError(f"{who}: term {place} takes '{odd[0]}': a term's arguments are plain names, looked "
                                 "up by name (no *args, **kwargs or keyword-only arguments)")
            source = {"param": own, "quantity": point, "state": own_states, "slot": point["slots"]}
            kwargs = {arg: source[cls.arg_kind(arg, place, who)][arg] for arg in sig.parameters}
            outside = []
            for name in sorted(_globals_used(code)):
                if name in fn.__globals__:
                    value = fn.__globals__[name]
                    if name in TERM_GLOBALS and isinstance(value, types.ModuleType) and value.__name__ in (
                            "math", "numpy"):
                        continue
                    outside.append(f"'{name}'")
                elif not hasattr(builtins, name):
                    raise ValueError(f"{who}: term {place} uses '{name}', which its file does not define (a term "
                                     "may use its own arguments and math; numpy only imported as np)")
            if outside:
                raise ValueError(f"{who}: term {place} uses {', '.join(outside)} from its file, but the compiled "
                                 "model copies the term's own lines alone: a term may use its own arguments (a "
                                 "fixed number goes in constants = (Param(...),)) and math; numpy only as np")
            try:
                out = fn(**kwargs)
            except Exception as exc:
                at = ", ".join(f"{k}={v:.4g}" for k, v in kwargs.items())
                text = " ".join(str(exc).split())
                raise ValueError(f"{who}: term {place}({at}) raised {type(exc).__name__}: {text} (terms are "
                                 "called once with realistic values when the effect registers)") from None
            n = RETURNS.get(place, len(cls.states) if place == "state_rates" else 1)
            what = PLACES[place] if place != "state_rates" else (
                "one number, the rate of its state" if n == 1 else f"a tuple of {n} numbers, the rates of its states")
            if n == 1:
                ok = _number(out)
            else:
                ok = isinstance(out, tuple) and len(out) == n and all(_number(v) for v in out)
            if not ok:
                got = (f"a tuple of {len(out)}" if isinstance(out, tuple) else f"{type(out).__name__} {out!r:.40}")
                must = ("one number" if n == 1 else f"a tuple of {n} numbers")
                raise ValueError(f"{who}: term {place} returned {got}; it must return {must}: {what}")
            vals = out if isinstance(out, tuple) else (out,)
            if not all(math.isfinite(v) for v in vals):
                at = ", ".join(f"{k}={v:.4g}" for k, v in kwargs.items())
                raise ValueError(f"{who}: term {place}({at}) returned {out!r}, not a finite number (terms are "
                                 "called once with realistic values when the effect registers)")

    @classmethod
    def param(cls, name: str) -> Param:
        """The declaration of one of this effect's parameters.

        Parameters
        ----------
        name : str
            The parameter's name (``Fc``, ``tau`` ...).

        Returns
        -------
        Param
            The parameter's declaration (unit, default, bounds, ...).

        Raises
        ------
        ValueError
            If the effect has no such parameter (the message lists its parameters).
        """
        for p in cls.params:
            if p.name == name:
                return p
        allowed = ", ".join(p.name for p in cls.params)
        raise ValueError(f"effect '{cls.name}' has no parameter '{name}'; its parameters are: {allowed}")

    @classmethod
    def resolve(cls, values: dict | None) -> dict[str, float]:
        """Defaults completed with ``values``, each checked against its bounds.

        Parameters
        ----------
        values : dict of str to float or None
            Parameter name -> value in the parameter's ``unit``; parameters left out take their
            defaults (None: all defaults).

        Returns
        -------
        dict of str to float
            Every parameter of the effect -> its value in the parameter's ``unit`` (not SI-converted),
            after the cross-parameter :meth:`validate`.

        Raises
        ------
        ValueError
            An unknown parameter, a value out of its bounds, or a failed :meth:`validate`.
        """
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
        """Cross-parameter checks (override where parameters constrain each other).

        Parameters
        ----------
        values : dict of str to float
            Every parameter -> its value in the parameter's ``unit``.  An override raises
            ``ValueError`` for a combination it refuses; the base class accepts everything.
        """

    @classmethod
    def apply(cls, values: dict[str, float], slots: dict[str, float]) -> None:
        """Set baseline slots this effect recalibrates (bulk modulus, valve dynamics, delay).

        Effects that act through terms need not override it: their own slots
        (``"name.param"``, SI) are filled by :func:`effect_slots`.

        Parameters
        ----------
        values : dict of str to float
            The effect's resolved parameters (:meth:`resolve`), in the parameters' units.
        slots : dict of str to float
            The model's parameter slots by name, SI; an override changes them in place.  The base
            class changes nothing.
        """

    @classmethod
    def adjust(cls, slots: dict[str, float], substep_s: float) -> None:
        """Last look at the finished slots (after every effect), e.g. to keep the model integrable.

        Parameters
        ----------
        slots : dict of str to float
            The model's parameter slots by name, SI, after every effect's :meth:`apply`; an override
            changes them in place.  The base class changes nothing.
        substep_s : float
            The integrator's sub-step in seconds (``dt / substeps``).
        """

    @classmethod
    def terms(cls) -> dict:
        """{place: function} of the physics this effect contributes.

        Returns
        -------
        dict of str to callable
            Each place of :data:`PLACES` where the effect defines a term -> that static method.
        """
        return {place: getattr(cls, place) for place in PLACES if callable(getattr(cls, place, None))}

    @classmethod
    def term_args(cls, place: str) -> list[str]:
        """The argument names of the effect's term at ``place``.

        Parameters
        ----------
        place : str
            One of :data:`PLACES` where the effect defines a term.

        Returns
        -------
        list of str
            The term's argument names in order (parameters, quantities, states or slots; see
            :meth:`arg_kind`).
        """
        return list(inspect.signature(getattr(cls, place)).parameters)

    @classmethod
    def arg_kind(cls, name: str, place: str, who: str | None = None) -> str:
        """What the argument ``name`` of the term at ``place`` stands for, looked up in this order: ``"param"``
        (one of its parameters or constants), ``"quantity"`` (a model quantity available at the place:
        :data:`PLACE_QUANTITIES`), ``"state"`` (its own state) or ``"slot"`` (a baseline slot).  The check at
        registration and the code generator both resolve through here.

        Parameters
        ----------
        name : str
            The argument's name.
        place : str
            The place (:data:`PLACES`) of the term that takes the argument.
        who : str, optional
            How the error names the effect (default: ``effect '<name>'``).

        Returns
        -------
        str
            ``"param"``, ``"quantity"``, ``"state"`` or ``"slot"``.

        Raises
        ------
        ValueError
            If the name is none of these.
        """
        from ehas_env.physics import layout

        if name in {p.name for p in cls.params + cls.constants}:
            return "param"
        available = PLACE_QUANTITIES[place]
        if place == "state_rates" and "coil_current" in cls.terms():
            # a coil effect's states move with the current alone: their rates are computed where the coil's
            # current is, in the right-hand side and on the valve bench (no load there)
            available = PLACE_QUANTITIES["coil_current"]
        if name in available:
            return "quantity"
        if name in {st[0] for st in cls.states}:
            return "state"
        if name in layout.BASE_SLOTS:
            return "slot"
        raise ValueError(
            f"{who or f'effect {cls.name!r}'}: argument '{name}' of its term '{place}' is neither one of its "
            f"parameters or constants, nor its own state, nor a model quantity available there "
            f"({', '.join(sorted(available))}), nor a baseline slot")

    @classmethod
    def slot_names(cls) -> list[str]:
        """This effect's slots in a model: its on flag, parameters, then constants.

        Returns
        -------
        list of str
            ``"<effect>.on"``, then ``"<effect>.<param>"`` for each parameter and constant.
        """
        return [f"{cls.name}.on"] + [f"{cls.name}.{p.name}" for p in cls.params + cls.constants]

    @classmethod
    def describe(cls) -> str:
        """A plain-text description of the effect for users (what ``ehas effects NAME`` prints).

        Returns
        -------
        str
            Name and title, explanation, residual signature, and one line per parameter with its
            unit, default, bounds and doc.
        """
        lines = [f"{cls.name}: {cls.title}", "", cls.explanation, "", f"Residual signature: {cls.signature}", "", "Parameters:"]
        for p in cls.params:
            lines.append(f"  {p.name} [{p.unit}] default {p.default:g}, bounds [{p.bounds[0]:g}, {p.bounds[1]:g}]: {p.doc}")
        return "\n".join(lines)


REGISTRY: dict[str, type[Effect]] = {}


def _number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _globals_used(code) -> set[str]:
    """Global names a function's code reads (its nested functions' and comprehensions' too)."""
    names = {ins.argval for ins in dis.get_instructions(code) if ins.opname in ("LOAD_GLOBAL", "LOAD_NAME")}
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            names |= _globals_used(c)
    return names


_POINT: dict = {}


def _sample_point() -> dict:
    """Realistic values of the model quantities and baseline slots (the book's rig, mid-motion, 5 mA):
    what a term is called with once when its effect registers."""
    if not _POINT:
        from ehas_env.physics import layout, rig

        th, om = 0.2, 0.5
        x, v = rig.CRANK_RADIUS * math.sin(th), rig.CRANK_RADIUS * math.cos(th) * om
        _POINT.update(theta=th, omega=om, x=x, v=v, xp=x, vp=v, pa=12.0e6, pb=9.0e6, ps=rig.SUPPLY_PRESSURE,
                      p_load=3.0e6, qc=2.0e-4, qc_dot=1.0e-3, q_a=1.5e-4, q_b=-1.5e-4, q_supply=1.5e-4, i=5.0,
                      gap=1.0e-4, gap_rate=0.01, q=1.5e-4, f=rig.AREA * 3.0e6, pa_rate=1.0e8, pb_rate=-1.0e8, ps_rate=0.0,
                      f_rate=rig.AREA * 2.0e8, p_sup=rig.SUPPLY_PRESSURE, p_ret=0.0)
        slots = dict.fromkeys(layout.BASE_SLOTS, 1.0)
        slots.update(inertia=2 * rig.INERTIA_PER_SET, radius=rig.CRANK_RADIUS, area=rig.AREA,
                     half_stroke=rig.HALF_STROKE, supply=rig.SUPPLY_PRESSURE, rated_drop=rig.RATED_VALVE_DROP,
                     beta=rig.BULK_MODULUS, dead_volume=rig.DEAD_VOLUME, K=rig.VALVE_K * rig.LPM, wn=rig.VALVE_WN,
                     zeta=rig.VALVE_ZETA, i_max=rig.RATED_CURRENT, tau=0.003, v_tanh=1.0e-3, valve_model=0.0,
                     effects_on=1.0)
        _POINT["slots"] = slots
    return _POINT


def effect_value(slots: dict, name: str, param: str) -> float:
    """Value (SI) of parameter ``param`` of effect ``name`` in a model's named slots, 0 when the effect is off."""
    return slots.get(f"{name}.{param}", 0.0) if slots.get(f"{name}.on") else 0.0


def mark_effects_on(slots: dict, model=None) -> dict:
    """Set the ``effects_on`` slot from the effects' on flags (0 lets the compiled model take the
    baseline's short path); with the compiled ``model``, also each group's all-off slot and the states its
    integrator moves.  Call after changing any ``<effect>.on``.

    Parameters
    ----------
    slots : dict
        The model's slots by name.
    model : module, optional
        The compiled model (:mod:`ehas_env.physics.codegen`) the slots are for: its ``GROUPS`` ((all-off slot,
        the on-slots of its effects) pairs: each all-off slot 1 when every one of those is 0) and its
        ``STATE_GROUPS`` ((on-slot, state indices) pairs: ``moved.n`` and ``moved.<k>`` list the baseline's
        states and those of the effects on).  Turning an effect off afterwards in the vector is safe (its rates
        are 0); turning one on is not: mark again.

    Returns
    -------
    dict
        ``slots``, changed in place.
    """
    slots["effects_on"] = 1.0 if any(v for k, v in slots.items() if k.endswith(".on")) else 0.0
    if model is not None:
        for name, members in model.GROUPS:
            slots[name] = 0.0 if any(slots.get(m) for m in members) else 1.0
        moved = list(range(model.N_BASE_STATES))
        moved += [k for on, ks in model.STATE_GROUPS if slots.get(on) for k in ks]
        from ehas_env.physics.layout import MOVED

        slots[MOVED + "n"] = float(len(moved))
        for a, k in enumerate(moved):
            slots[f"{MOVED}{a}"] = float(k)
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


def closest_effects(word: str, n: int = 3) -> list[str]:
    """The 1-``n`` registered effect names closest to ``word`` (a typo), or [] when none is close.

    A name is close as a whole (``coulomb_fricton``) or by one of its words (``frictoin``: the
    frictions, closest whole names first).

    Parameters
    ----------
    word : str
        What the user typed.
    n : int
        At most this many names.

    Returns
    -------
    list of str
        Effect names, the closest first.
    """
    import difflib

    names = sorted(REGISTRY)
    close = difflib.get_close_matches(word, names, n=n, cutoff=0.6)
    if close:
        return close
    parts = {part for name in names for part in name.split("_") if len(part) > 2}
    near = set(difflib.get_close_matches(word, sorted(parts), n=n, cutoff=0.75))
    hits = [name for name in names if near & set(name.split("_"))]
    return sorted(hits, key=lambda c: -difflib.SequenceMatcher(None, word, c).ratio())[:n]


def get_effect(name: str) -> type[Effect]:
    """The effect class registered as ``name`` (ValueError naming the choices otherwise).

    Parameters
    ----------
    name : str
        An effect's name.

    Returns
    -------
    type
        Its :class:`Effect` subclass.  An unknown name is a ValueError naming the 1-3 closest names
        (a typo), or every name when none is close.
    """
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        close = closest_effects(str(name))
        if close:
            raise ValueError(f"unknown effect '{name}'; did you mean {' or '.join(repr(c) for c in close)}? "
                             f"(ehas effects lists all {len(REGISTRY)})") from None
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
    from ehas_env.ranges import split_list

    for item in split_list(text.replace(";", ","), "effects spec", "NAME[:PARAM=VALUE] items", unique=False):
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
