"""A grammar of hidden physics: blocks drawn as (place, kind, magnitude) (issue 43, point 5).

The older groups of hidden physics (:mod:`.effects`) are lists: each class written by hand where someone thought
of it.  Here a block of hidden physics is drawn from a product:

* a **place** (:data:`PLACES`): a signal or a balance of the generator's own model structure
  (:mod:`.physics`, :mod:`.simulate`): the amplifier's command current, the coil current, each land's flow, each
  chamber's flow balance, the supply and return pressures at the valve, the piston force and crank torque
  balances, the position, pressure and flow readings and the load reading.  A *signal* is a value passed on (a
  block transforms it); a *balance* is a sum (a block adds a term to it, a function of the place's local
  quantities); the supply and return pressures are *steady* signals (constant in the plan), which a static block
  changes by a term that is a function of the flow through the valve;
* a **kind** (:data:`KINDS`): one class each, fitting every place of a compatible type: static (offset, gain
  change, dead zone, saturation, piecewise-linear, smooth (cubic)) and dynamic (first-order lag, rate limit,
  pure delay, play on a signal; a compliance with a mass in a mechanical balance; a line volume behind a
  resistance in a hydraulic path);
* a **magnitude**: log-uniform within the kind's range, scaled by the place's typical size on the rig
  (:class:`Place`, ``scale``), so that a dead zone in the coil current is in mA and in the flow meter's reading
  in LPM.

:func:`drawn_cases` draws the published set with the fixed :data:`SEED` and the redraw rule of
:func:`draw_block` (a block whose effect is below :data:`DB_LOW` or above :data:`DB_HIGH` dB over the sensor noise
on its best key signal, measured as :func:`.start_conditions.effect_db` measures it, is redrawn at another
magnitude).  The measures are kept in :data:`SCREEN_PATH` so that the list prints in a second.

Units: every parameter is SI inside, except currents, which the generator holds in mA (as :mod:`.physics`); the
words give engineering units.  docs/independent-generator.md, "The drawn set", publishes all of it.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import campaign as gen
from .physics import COMPLIANCE_DAMPING, CRANK_MASS, PISTON_MASS, SLEW_T
from .rig import BAR, LPM, Rig
from .simulate import DT

#: the draw's seed, fixed and published before anything was tuned on the drawn set (never change it)
SEED = 20261128
#: single campaigns (one block) and pairs (two blocks at two places) in the drawn set
N_SINGLES, N_PAIRS = 30, 8
#: the redraw rule: a block's effect on its best key signal must lie within [DB_LOW, DB_HIGH] dB over the noise
DB_LOW, DB_HIGH = 10.0, 60.0
#: magnitudes tried for one (place, kind) before the kind and place are drawn again
MAX_TRIES = 6
#: kinds tried for one block before the draw gives up (it has not happened with SEED)
MAX_KINDS = 8
#: rigs a case may be drawn on (the book's and the model files of rigs/)
RIGS = ("book", "rig_b", "rig_c")
#: where the screen's measures are kept (a cache: delete it to measure every candidate again, about 10 minutes)
SCREEN_PATH = Path(__file__).with_name("drawn_screen.json")
#: oil volume of a drawn line (a hose of 0.8 m of 8 mm bore; assumed, between hose_line's 20 and 50 cm^3)
LINE_VOLUME = 40.0e-6
#: breakpoint of a signal's piecewise-linear block, share of the place's scale (assumed: inside every run's swing)
PWL_BREAK = 0.3
#: threshold of a balance's dead zone and break of its piecewise-linear term, share of the local quantity's scale
#: (assumed: the outer half of the swing)
TERM_BREAK = 0.5
#: knee of a balance's saturating term, share of the local quantity's scale (assumed: a tenth, friction-like)
TERM_KNEE = 0.1
#: slope of a balance's piecewise-linear term beyond its break, times the slope inside (assumed)
TERM_SLOPE_RATIO = 3.0


# -- the rig's typical sizes (SI), from its numbers and the plan's fastest run --------------------------------------
def crank_rate(rig: Rig) -> float:
    """Peak crank rate of the plan's fastest run, rad/s (35 deg at 3 Hz: 11.5 rad/s)."""
    return max(math.radians(a) * 2.0 * math.pi * f for _, a, f in gen.PLAN)


def top_frequency() -> float:
    """The plan's highest reference frequency, rad/s (the slope of a signal of size S is about S times this)."""
    return max(2.0 * math.pi * f for _, _, f in gen.PLAN)


def piston_speed(rig: Rig) -> float:
    """Peak piston speed of the plan, m/s."""
    return rig.radius * crank_rate(rig)


def peak_flow(rig: Rig) -> float:
    """Peak flow into a chamber, A v, m^3/s (26.5 LPM on the book rig)."""
    return rig.area * piston_speed(rig)


def peak_current(rig: Rig) -> float:
    """The current that passes the peak flow with half the supply across each land, mA (11.7 mA on the book rig)."""
    return peak_flow(rig) / (rig.K * math.sqrt(rig.supply / rig.rated_drop))


def pressure_swing(rig: Rig) -> float:
    """A quarter of the supply, Pa: about the chambers' swing about Ps/2 in the plan (55 bar on the book rig)."""
    return 0.25 * rig.supply


def force_scale(rig: Rig) -> float:
    """A quarter of the stall force A Ps, N: about the plan's peak load (4.2 kN on the book rig)."""
    return 0.25 * rig.area * rig.supply


def oil_stiffness(rig: Rig) -> float:
    """The oil columns' stiffness at mid-stroke, 4 beta A^2 / V_t, N/m (V_t both chambers: 2.5e7 N/m on the book)."""
    return 4.0 * rig.beta * rig.area ** 2 / (2.0 * (rig.area * rig.half_stroke + rig.dead_volume))


# -- places ----------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Quantity:
    """A local quantity of a place: what a block's term there may be a function of.

    Parameters
    ----------
    name : str
        Its key in the hook's local quantities (:class:`.physics.Hooks`).
    words : str
        Its name in words.
    unit : str
        Engineering unit of the words.
    si : float
        SI per engineering unit.
    scale : callable
        ``scale(rig)``: its typical size on the rig, SI.
    """

    name: str
    words: str
    unit: str
    si: float
    scale: object


@dataclass(frozen=True)
class Place:
    """A signal or a balance of the generator's model, where a block may act.

    Parameters
    ----------
    name : str
        Its name (the hook's key).
    words : str
        Its name in words ("chamber B's pressure reading").
    unit, si : str, float
        Engineering unit of its value in words, and SI per that unit.
    role : str
        ``signal`` (a value passed on) or ``balance`` (a sum of forces, torques or flows).
    scale : callable
        ``scale(rig)``: its typical size on the rig, SI (magnitudes are drawn relative to it).
    locals : tuple of Quantity
        What a block's term there may be a function of (balances and steady signals).
    where : str
        Where the generator computes it: ``held`` (the amplifier's command, constant over a control period),
        ``rhs`` (inside the integration), ``sampled`` (a logged reading, as the logger samples it).
    centre : callable or None
        ``centre(rig)``: the value a signal swings about, SI (None: zero; the signal is *centred*).
    steady : bool
        Constant in the plan (the supply and return pressures): a block changes it by a term.
    path : str
        ``mechanical`` or ``hydraulic`` for the balances and lines a structural kind can split; else empty.
    sign : int
        Sign of a term a block adds (-1 at a balance: against the local quantity, a damping, a restoring force, a
        leak out; at the supply a drop; +1 at the return a rise).
    signed_offset : bool
        Whether an offset there may have either sign (the return pressure only rises).
    diag : tuple of str
        The diagnosis' place names (docs/measurement-format.md) that name this place (the judge's).
    pattern : str
        Regular expression of words that name it (the judge's, lower case).
    side : str
        ``a`` or ``b`` for the places of one chamber's side.
    stiffness : callable or None
        ``stiffness(rig)``: the stiffness a compliance there is drawn relative to (N/m, or N m/rad).
    body : callable or None
        ``body(rig)``: the mass (kg) or inertia (kg m^2) a compliance there splits off.
    """

    name: str
    words: str
    unit: str
    si: float
    role: str
    scale: object
    locals: tuple = ()
    where: str = "rhs"
    centre: object = None
    steady: bool = False
    path: str = ""
    sign: int = -1
    signed_offset: bool = True
    diag: tuple = ()
    pattern: str = ""
    side: str = ""
    stiffness: object = None
    body: object = None

    @property
    def centred(self) -> bool:
        """Whether the signal swings about zero (no current, no flow, mid-stroke, no load)."""
        return self.centre is None and not self.steady

    @property
    def term_mode(self) -> bool:
        """Whether a static block here adds a term (balances and steady signals) rather than transforming."""
        return self.role == "balance" or self.steady

    def centre_of(self, rig: Rig) -> float:
        """The value the signal swings about on ``rig``, SI."""
        return 0.0 if self.centre is None else self.centre(rig)


def _q(name, words, unit, si, scale) -> Quantity:
    """A :class:`Quantity`, positionally."""
    return Quantity(name, words, unit, si, scale)


_SPOOL = _q("q", "the spool's opening (as no-load flow)", "LPM", LPM, lambda r: r.K * peak_current(r))
_V = _q("v", "the piston velocity", "m/s", 1.0, piston_speed)
_X = _q("x", "the piston position", "mm", 1e-3, lambda r: r.half_stroke)
_PL = _q("pL", "the load pressure p_A - p_B", "bar", BAR, pressure_swing)
_W = _q("w", "the crank rate", "rad/s", 1.0, crank_rate)
_TH = _q("th", "the crank angle", "deg", math.pi / 180.0, lambda r: r.stroke_end)


def _chamber(side: str) -> tuple:
    """The local quantities of one chamber's flow balance (the hook passes chamber B's with B's signs)."""
    s, o = side.upper(), ("B" if side == "a" else "A")
    return (_q("p", f"chamber {s}'s pressure", "bar", BAR, lambda r: 0.5 * r.supply),
            _q("dp", f"the pressure across the piston p_{s} - p_{o}", "bar", BAR, pressure_swing),
            _q("v", f"chamber {s}'s rate of expansion (as piston velocity)", "m/s", 1.0, piston_speed))


def _signal(name, words, unit, si, scale, **kw) -> Place:
    """A signal :class:`Place`."""
    return Place(name, words, unit, si, "signal", scale, **kw)


def _balance(name, words, unit, si, scale, locals_, **kw) -> Place:
    """A balance :class:`Place` with its local quantities."""
    return Place(name, words, unit, si, "balance", scale, locals_, **kw)


_SIDE_A = r"(chamber|port|land|side|hose|line)[\s_]+a\b"
_SIDE_B = r"(chamber|port|land|side|hose|line)[\s_]+b\b"
#: every place of the grammar, in the order of the docs' table
PLACES = {p.name: p for p in (
    _signal("command_current", "the amplifier's command current", "mA", 1.0, peak_current, where="held",
            diag=("valve_current", "coil_current"), pattern=r"command|amplifier|servo current|drive current"),
    _signal("coil_current", "the valve's coil current", "mA", 1.0, peak_current,
            diag=("coil_current", "valve_current"), pattern=r"coil|torque motor"),
    _signal("land_a", "land A's flow (out of valve port A)", "LPM", LPM, peak_flow, side="a",
            diag=("chamber_flows",), pattern=r"\bland|metering|valve port"),
    _signal("land_b", "land B's flow (out of valve port B)", "LPM", LPM, peak_flow, side="b",
            diag=("chamber_flows",), pattern=r"\bland|metering|valve port"),
    _balance("chamber_a", "chamber A's flow balance", "LPM", LPM, lambda r: 0.1 * peak_flow(r), _chamber("a"),
             side="a", path="hydraulic", diag=("chamber_flows",), pattern=r"chamber|cylinder|leak|hose|line"),
    _balance("chamber_b", "chamber B's flow balance", "LPM", LPM, lambda r: 0.1 * peak_flow(r), _chamber("b"),
             side="b", path="hydraulic", diag=("chamber_flows",), pattern=r"chamber|cylinder|leak|hose|line"),
    _signal("supply", "the supply pressure at the valve", "bar", BAR, pressure_swing, locals=(_SPOOL,),
            steady=True, path="hydraulic", sign=-1, diag=("supply",), pattern=r"supply|pump"),
    _signal("return", "the return (tank) pressure at the valve", "bar", BAR, pressure_swing, locals=(_SPOOL,),
            steady=True, path="hydraulic", sign=+1, signed_offset=False, diag=("return",),
            pattern=r"return|tank|back[- ]pressure"),
    _balance("piston_force", "the piston force balance", "N", 1.0, force_scale, (_V, _X, _PL), path="mechanical",
             diag=("piston_force", "crank_torque"), pattern=r"piston|rod|actuator force|cylinder force|seal",
             stiffness=oil_stiffness, body=lambda r: PISTON_MASS),
    _balance("crank_torque", "the crank torque balance", "N m", 1.0, lambda r: force_scale(r) * r.radius, (_W, _TH),
             path="mechanical", diag=("crank_torque", "piston_force"), pattern=r"crank|disc|torque|shaft|bearing",
             stiffness=lambda r: oil_stiffness(r) * r.radius ** 2, body=lambda r: CRANK_MASS * r.radius ** 2),
    _signal("position_reading", "the position sensor's reading", "mm", 1e-3, lambda r: r.half_stroke,
            where="sampled", diag=("position_reading",), pattern=r"position|lvdt|angle (sensor|reading)"),
    _signal("pressure_reading_a", "chamber A's pressure reading", "bar", BAR, pressure_swing, where="sampled",
            centre=lambda r: 0.5 * r.supply, side="a", diag=("pressure_reading_a", "pressure_reading"),
            pattern=r"pressure (reading|sensor|transducer)|p_a (reading|sensor)"),
    _signal("pressure_reading_b", "chamber B's pressure reading", "bar", BAR, pressure_swing, where="sampled",
            centre=lambda r: 0.5 * r.supply, side="b", diag=("pressure_reading_b", "pressure_reading"),
            pattern=r"pressure (reading|sensor|transducer)|p_b (reading|sensor)"),
    _signal("flow_reading", "the flow meter's reading", "LPM", LPM, peak_flow, where="sampled",
            diag=("flow_reading",), pattern=r"flow (meter|reading|sensor)"),
    _signal("load_reading", "the load reading", "kN", 1e3, force_scale, where="sampled",
            diag=("load_reading",), pattern=r"load (cell|reading|sensor)"),
)}
SIDE_PATTERNS = {"a": _SIDE_A, "b": _SIDE_B}


# -- sampled operators (a reading as the logger samples it; play on the held command) --------------------------------
class _Steps:
    """A discrete operator on a sequence, one value per sample (``init`` None: at rest on the first value)."""

    def __init__(self, params: dict, init=None):
        self.p = params
        self.s = init
        self.prev = init

    def step(self, u: float) -> float:
        if self.s is None:
            self.s = self.prev = u
            return self.first(u)
        out = self.next(u)
        self.prev = u
        return out

    def first(self, u: float) -> float:
        return u


class _LagSteps(_Steps):
    """First-order lag T of a signal sampled every DT, exact for a signal linear between samples:
    s_k = e s_(k-1) + (1 - e) u_(k-1) + (u_k - u_(k-1)) (1 - T (1 - e) / DT), e = exp(-DT / T)."""

    def next(self, u):
        T = self.p["T"]
        e = math.exp(-DT / T)
        self.s = e * self.s + (1.0 - e) * self.prev + (u - self.prev) * (1.0 - T * (1.0 - e) / DT)
        return self.s


class _RateSteps(_Steps):
    """Rate limit R: the output moves toward the input by at most R DT per sample."""

    def next(self, u):
        d = self.p["R"] * DT
        self.s += min(max(u - self.s, -d), d)
        return self.s


class _PlaySteps(_Steps):
    """Play (backlash) of half-width delta: the output stays put until the input is delta away, then follows it."""

    def next(self, u):
        d = self.p["delta"]
        self.s = min(max(self.s, u - d), u + d)
        return self.s


class _DelaySteps(_Steps):
    """Pure delay tau of a sampled signal: the value at t_k - tau, linear between the samples (before the first
    sample, the first: at rest)."""

    def __init__(self, params, init=None):
        super().__init__(params, init)
        self.hist = []

    def step(self, u):
        self.hist.append(u)
        j = len(self.hist) - 1 - self.p["tau"] / DT
        if j <= 0.0:
            return self.hist[0]
        lo = int(math.floor(j))
        f = j - lo
        return self.hist[lo] if f == 0.0 else self.hist[lo] + f * (self.hist[lo + 1] - self.hist[lo])


# -- kinds -----------------------------------------------------------------------------------------------------------
def _dz(z: float, d: float) -> float:
    """Dead zone: 0 within +-d, z -+ d beyond."""
    return z - d if z > d else (z + d if z < -d else 0.0)


def _fmt(x: float) -> str:
    """Three significant digits."""
    return f"{x:.3g}"


def _eng(x: float, si: float, unit: str, signed: bool = False) -> str:
    """An SI value in its engineering unit, for the words."""
    v = x / si
    return (f"{v:+.3g}" if signed else _fmt(v)) + f" {unit}"


@dataclass(frozen=True)
class Range:
    """A kind's main magnitude: drawn log-uniformly in [lo, hi] (times ``relative_to`` at the place).

    ``stronger`` is +1 when a larger value is a stronger block (a wider dead zone), -1 when weaker (a higher
    saturation level, a faster rate limit, a stiffer compliance)."""

    name: str
    lo: float
    hi: float
    unit: str
    relative_to: str
    stronger: int = 1

    def value(self, u: float) -> float:
        """The value at strength u in [0, 1] (0 the weakest, 1 the strongest)."""
        a, b = (self.lo, self.hi) if self.stronger > 0 else (self.hi, self.lo)
        return a * (b / a) ** u


class Kind:
    """A kind of block: how it acts, where it fits, its magnitude, its words (one subclass per kind).

    Class attributes
    ----------------
    name : str
        Its name.
    noun : str
        Its name in words ("a first-order lag").
    pattern : str
        Regular expression of words that name it (the judge's, lower case).
    accept : tuple of str
        Other kinds a diagnosis may name it as and be right, with ``why``.
    source : str
        Where the physics is described, and what is assumed.
    """

    name = ""
    noun = ""
    pattern = ""
    accept: tuple = ()
    why = ""
    source = ""

    def fits(self, place: Place) -> bool:
        raise NotImplementedError

    def mechanism(self, place: Place) -> str:
        """How the generator applies it at ``place`` (:class:`.physics.Hooks`)."""
        return "static"

    def range(self, place: Place) -> Range:
        raise NotImplementedError

    def n_states(self, place: Place) -> int:
        return 0

    def atol(self, place: Place) -> list:
        return []

    def rest(self, place: Place, rig: Rig) -> list:
        return [0.0] * self.n_states(place)

    def shape(self, place: Place, rng: np.random.Generator) -> dict:
        """What the draw chooses besides the magnitude (a sign, a local quantity), before it."""
        return {}

    def make(self, place: Place, rig: Rig, u: float, shape: dict) -> dict:
        """The block's parameters (SI) at strength ``u`` on ``rig``."""
        raise NotImplementedError

    #: the parameter that is the block's magnitude, and its value at zero magnitude (the block does nothing)
    zero = ("", 0.0)

    def is_null(self, params: dict) -> bool:
        """Whether the block does nothing (zero magnitude)."""
        key, value = self.zero_of(params)
        return params[key] == value

    def zero_of(self, params: dict) -> tuple:
        """(key, value): the parameter that sets the magnitude and its value at zero magnitude."""
        return self.zero

    def zeroed(self, params: dict) -> dict:
        """``params`` at zero magnitude."""
        key, value = self.zero_of(params)
        return {**params, key: value}

    def words(self, place: Place, params: dict) -> str:
        raise NotImplementedError

    # runtime: a signal inside the integration, a term, a reading's transform, a sampled operator
    def apply(self, params, u, y, dy, k):
        return self.transform(params, u)

    def transform(self, params, u):
        raise NotImplementedError(f"{self.name} does not transform a signal")

    def term(self, params, loc):
        raise NotImplementedError(f"{self.name} adds no term")

    def stepper(self, params, init=None):
        raise NotImplementedError(f"{self.name} is not applied sample by sample")


class StaticKind(Kind):
    """A static function: of the signal itself (a transform), or, at a balance or a steady signal, an added term
    ``a f(q / q0)`` of one local quantity q (its scale q0), of the sign the place gives (:attr:`Place.sign`)."""

    #: the magnitude when the block transforms a signal, and when it adds a term
    signal_range: Range = None
    term_range = Range("a", 0.02, 0.5, "-", "the place's scale")

    def fits(self, place):
        return True

    def range(self, place):
        return self.term_range if place.term_mode else self.signal_range

    def shape(self, place, rng):
        if place.term_mode:
            q = place.locals[int(rng.integers(len(place.locals)))]
            return {"of": q.name, "sign": place.sign}
        return {"sign": 1 if rng.random() < 0.5 else -1}

    def quantity(self, place: Place, params: dict) -> Quantity:
        return next(q for q in place.locals if q.name == params["of"])

    def make(self, place, rig, u, shape):
        m = self.range(place).value(u)
        if place.term_mode:
            q = next(q for q in place.locals if q.name == shape["of"])
            return {"a": shape["sign"] * m * place.scale(rig), "of": q.name, "q0": q.scale(rig)}
        return self.make_signal(place, rig, m, shape)

    def make_signal(self, place, rig, m, shape):
        raise NotImplementedError

    #: the signal mode's magnitude parameter and its zero
    signal_zero = ("a", 0.0)

    def zero_of(self, params):
        return ("a", 0.0) if "of" in params else self.signal_zero

    def term(self, params, loc):
        return params["a"] * self.law(loc[params["of"]] / params["q0"])

    def law(self, z: float) -> float:
        """The term's shape, f(z) with f(1) = 1 (odd in z)."""
        raise NotImplementedError

    def stepper(self, params, init=None):
        kind = self

        class _Static(_Steps):
            def first(self, u):
                return kind.transform(params, u)

            def next(self, u):
                return kind.transform(params, u)

        return _Static(params, init)

    def term_words(self, place, params, what: str) -> str:
        q = self.quantity(place, params)
        return (f"{what} {q.words} ({_eng(params['a'], place.si, place.unit, signed=True)} at "
                f"{_eng(params['q0'], q.si, q.unit)}) added to {place.words}")


class Offset(StaticKind):
    """u + a; at a balance a constant term a (a constant force, torque or flow)."""

    name, noun = "offset", "an offset"
    pattern = r"offset|bias|zero shift|constant"
    signal_range = Range("a", 0.005, 0.15, "-", "the place's scale")
    source = "Jelali & Kroll 2003 (sensor and amplifier offsets; constant loads and leaks)"

    def shape(self, place, rng):
        if place.term_mode and not place.signed_offset:
            return {"sign": place.sign}
        return {"sign": 1 if rng.random() < 0.5 else -1}

    def make(self, place, rig, u, shape):
        return {"a": shape["sign"] * self.range(place).value(u) * place.scale(rig)}

    def transform(self, params, u):
        return u + params["a"]

    def term(self, params, loc):
        return params["a"]

    def zero_of(self, params):
        return ("a", 0.0)

    def words(self, place, params):
        what = "a constant term" if place.term_mode else "an offset"
        link = "added to" if place.term_mode else "in"
        return f"{what} of {_eng(params['a'], place.si, place.unit, signed=True)} {link} {place.words}"


class Gain(StaticKind):
    """u (1 + g); at a balance a term linear in a local quantity (a spring, a damping, a laminar leak)."""

    name, noun = "gain", "a gain change"
    pattern = r"\bgain|scale factor|sensitivity|proportional|viscous|laminar|linear"
    signal_range = Range("g", 0.02, 0.3, "-", "none (a share of the signal)")
    signal_zero = ("g", 0.0)
    source = "Merritt 1967 (linearised loads and leaks); Jelali & Kroll 2003 (gain errors of sensors and valves)"

    def make_signal(self, place, rig, m, shape):
        return {"g": shape["sign"] * m}

    def transform(self, params, u):
        return u * (1.0 + params["g"])

    def law(self, z):
        return z

    def words(self, place, params):
        if place.term_mode:
            return self.term_words(place, params, "a term proportional to")
        return f"a gain change of {100 * params['g']:+.3g} % in {place.words}"


class DeadZone(StaticKind):
    """Nothing passes within +-d of the centre, the rest less d; at a balance a term beyond +-d of a local quantity
    (a spring that meets a gap, a relief that cracks)."""

    name, noun = "dead_zone", "a dead zone"
    pattern = r"dead[- ]?(zone|band)|deadband|threshold|gap|lap\b|overlap"
    signal_range = Range("d", 0.005, 0.15, "-", "the place's scale")
    signal_zero = ("d", 0.0)
    source = "Merritt 1967 (overlapped valves: a dead band); Jelali & Kroll 2003 (dead zones of drives and sensors)"

    def fits(self, place):
        return place.term_mode or place.centred

    def make_signal(self, place, rig, m, shape):
        return {"d": m * place.scale(rig), "c": place.centre_of(rig)}

    def make(self, place, rig, u, shape):
        p = super().make(place, rig, u, shape)
        if place.term_mode:
            p["d"] = TERM_BREAK * p["q0"]
        return p

    def transform(self, params, u):
        return params["c"] + _dz(u - params["c"], params["d"])

    def term(self, params, loc):
        return params["a"] * _dz(loc[params["of"]], params["d"]) / (params["q0"] - params["d"])

    def words(self, place, params):
        if place.term_mode:
            q = self.quantity(place, params)
            return (f"a term beyond +-{_eng(params['d'], q.si, q.unit)} of {q.words} "
                    f"({_eng(params['a'], place.si, place.unit, signed=True)} at {_eng(params['q0'], q.si, q.unit)}) "
                    f"added to {place.words}")
        return f"a dead zone of +-{_eng(params['d'], place.si, place.unit)} in {place.words}"


class Saturation(StaticKind):
    """The signal clipped at +-L about its centre; at a balance a term that rises to a at a tenth of the local
    quantity's scale and holds (friction-like)."""

    name, noun = "saturation", "a saturation"
    pattern = r"saturat|clip|coulomb|limit(ed)? at|friction"
    signal_range = Range("L", 0.3, 1.0, "-", "the place's scale", stronger=-1)
    signal_zero = ("L", math.inf)
    source = "Jelali & Kroll 2003 (amplifier and sensor ranges; Coulomb-like friction as a saturated damping)"

    def make_signal(self, place, rig, m, shape):
        return {"L": m * place.scale(rig), "c": place.centre_of(rig)}

    def make(self, place, rig, u, shape):
        p = super().make(place, rig, u, shape)
        if place.term_mode:
            p["qk"] = TERM_KNEE * p["q0"]
        return p

    def transform(self, params, u):
        c, L = params["c"], params["L"]
        return c + min(max(u - c, -L), L)

    def term(self, params, loc):
        return params["a"] * min(max(loc[params["of"]] / params["qk"], -1.0), 1.0)

    def words(self, place, params):
        if place.term_mode:
            q = self.quantity(place, params)
            return (f"a saturating term of {q.words} ({_eng(params['a'], place.si, place.unit, signed=True)}, "
                    f"reached at {_eng(params['qk'], q.si, q.unit)}) added to {place.words}")
        c = "" if params["c"] == 0.0 else f" about {_eng(params['c'], place.si, place.unit)}"
        return f"a saturation at +-{_eng(params['L'], place.si, place.unit)}{c} of {place.words}"


class PiecewiseLinear(StaticKind):
    """Two slopes: the signal's slope changes by s beyond +-b (b = 0.3 of the scale); at a balance a term whose slope
    triples beyond half the local quantity's scale."""

    name, noun = "piecewise_linear", "a piecewise-linear function"
    pattern = r"piecewise|two slopes|break ?point|kink|slope change|by direction"
    accept = ("smooth",)
    why = "a static nonlinearity whose shape the logs at this noise tell from a smooth one only at its break"
    signal_range = Range("s", 0.05, 0.8, "-", "none (a change of slope)")
    signal_zero = ("s", 0.0)
    source = "Jelali & Kroll 2003 (piecewise-linear characteristics of valves and sensors); assumed break points"

    def make_signal(self, place, rig, m, shape):
        return {"s": shape["sign"] * m, "b": PWL_BREAK * place.scale(rig), "c": place.centre_of(rig)}

    def make(self, place, rig, u, shape):
        p = super().make(place, rig, u, shape)
        if place.term_mode:
            p["b"] = TERM_BREAK * p["q0"]
        return p

    def transform(self, params, u):
        z = u - params["c"]
        return u + params["s"] * math.copysign(max(abs(z) - params["b"], 0.0), z)

    def law(self, z):
        r, b = TERM_SLOPE_RATIO, TERM_BREAK
        # slope 1 within +-b, r beyond, normalised to f(1) = 1
        return (z + (r - 1.0) * math.copysign(max(abs(z) - b, 0.0), z)) / (1.0 + (r - 1.0) * (1.0 - b))

    def words(self, place, params):
        if place.term_mode:
            q = self.quantity(place, params)
            return (f"a piecewise-linear term of {q.words}, its slope x{TERM_SLOPE_RATIO:g} beyond "
                    f"+-{_eng(params['b'], q.si, q.unit)} ({_eng(params['a'], place.si, place.unit, signed=True)} "
                    f"at {_eng(params['q0'], q.si, q.unit)}) added to {place.words}")
        return (f"a piecewise-linear function: the slope changes by {100 * params['s']:+.3g} % beyond "
                f"+-{_eng(params['b'], place.si, place.unit)} in {place.words}")


class Smooth(StaticKind):
    """A cubic: u + a ((u - c) / S)^3; at a balance a term a (q / q0)^3 of a local quantity."""

    name, noun = "smooth", "a smooth (cubic) function"
    pattern = r"cubic|polynomial|tanh|quadratic|smooth|nonlinear|hardening|bow|square"
    accept = ("piecewise_linear",)
    why = "a static nonlinearity whose shape the logs at this noise tell from two slopes only near a break"
    signal_range = Range("a", 0.02, 0.5, "-", "the place's scale")
    source = "Jelali & Kroll 2003 (nonlinear characteristics: hardening springs, sensor bow); Merritt 1967"

    def make_signal(self, place, rig, m, shape):
        return {"a": shape["sign"] * m * place.scale(rig), "S": place.scale(rig), "c": place.centre_of(rig)}

    def transform(self, params, u):
        return u + params["a"] * ((u - params["c"]) / params["S"]) ** 3

    def law(self, z):
        return z ** 3

    def words(self, place, params):
        if place.term_mode:
            return self.term_words(place, params, "a cubic term in")
        return (f"a cubic nonlinearity of {_eng(params['a'], place.si, place.unit, signed=True)} at "
                f"+-{_eng(params['S'], place.si, place.unit)} in {place.words}")


class _SignalDynamics(Kind):
    """A dynamic block on a signal that changes in the plan (not the steady supply or return)."""

    def fits(self, place):
        return place.role == "signal" and not place.steady

    def atol(self, place):
        return [1e-8 if place.unit == "mA" else 1e-12] * self.n_states(place)

    def n_states(self, place):
        return 1 if self.mechanism(place) == "state" else 0

    def mechanism(self, place):
        return "sampled" if place.where == "sampled" else "state"


class Lag(_SignalDynamics):
    """First-order lag T: T s' = u - s, the place passes s (inside the integration, or on the sampled reading)."""

    name, noun = "lag", "a first-order lag"
    pattern = r"\blag|first[- ]order|time constant|low[- ]pass|filter"
    source = "Jelali & Kroll 2003 (coil inductance, transducer and demodulator filters); Merritt 1967"

    def range(self, place):
        return Range("T", 0.3e-3, 10e-3, "s", "none")

    def make(self, place, rig, u, shape):
        return {"T": self.range(place).value(u)}

    zero = ("T", 0.0)

    def apply(self, params, u, y, dy, k):
        dy[k] = (u - y[k]) / params["T"]
        return y[k]

    def stepper(self, params, init=None):
        return _LagSteps(params, init)

    def words(self, place, params):
        return f"a first-order lag of {_fmt(params['T'] * 1e3)} ms in {place.words}"


class RateLimit(_SignalDynamics):
    """The place's value never changes faster than R: s' = R tanh((u - s) / (R T_s)) inside the integration (T_s =
    physics.SLEW_T, the follower's small-signal time constant), a step of at most R DT per sample on a reading."""

    name, noun = "rate_limit", "a rate limit"
    pattern = r"rate[- ]limit|slew|rate of (rise|change)"
    source = "Jelali & Kroll 2003 (voltage-limited current drivers, slew-limited electronics)"

    def range(self, place):
        return Range("R", 0.1, 1.5, "-", "the place's scale times the plan's top frequency (2 pi 3 Hz)",
                     stronger=-1)

    def make(self, place, rig, u, shape):
        return {"R": self.range(place).value(u) * place.scale(rig) * top_frequency()}

    zero = ("R", math.inf)

    def apply(self, params, u, y, dy, k):
        R = params["R"]
        dy[k] = R * math.tanh((u - y[k]) / (R * SLEW_T))
        return y[k]

    def stepper(self, params, init=None):
        return _RateSteps(params, init)

    def words(self, place, params):
        return f"a rate limit of {_eng(params['R'], place.si, place.unit + '/s')} on {place.words}"


class _HeldOrSampled(_SignalDynamics):
    """A block the generator applies exactly only where the signal's past is known: the amplifier's held command
    (constant over each control period) and a reading the logger samples; not a signal inside the integration."""

    def fits(self, place):
        return place.role == "signal" and place.where in ("held", "sampled")


class Delay(_HeldOrSampled):
    """A pure delay tau: the held command switches at t_k + tau (exact, as the transport delay); a reading shows
    the value of t_k - tau, linear between the logger's samples."""

    name, noun = "delay", "a pure delay"
    pattern = r"\bdelay|dead[- ]time|transport|latency"
    source = "Jelali & Kroll 2003 (transport delays of digital drives and transducers)"

    def mechanism(self, place):
        return "tau" if place.where == "held" else "sampled"

    def range(self, place):
        return Range("tau", 0.3e-3, 10e-3, "s", "none")

    def make(self, place, rig, u, shape):
        return {"tau": self.range(place).value(u)}

    zero = ("tau", 0.0)

    def stepper(self, params, init=None):
        return _DelaySteps(params, init)

    def words(self, place, params):
        return f"a pure delay of {_fmt(params['tau'] * 1e3)} ms in {place.words}"


class Play(_HeldOrSampled):
    """Play (backlash) of half-width delta: the output holds until the input is delta away, then follows it
    (the held command once per control period; a reading once per sample)."""

    name, noun = "play", "a play (backlash)"
    pattern = r"\bplay\b|backlash|hysteres|lost motion"
    source = "Jelali & Kroll 2003 (backlash in drives and sensor linkages)"

    def mechanism(self, place):
        return "sequence" if place.where == "held" else "sampled"

    def range(self, place):
        return Range("delta", 0.002, 0.05, "-", "the place's scale")

    def make(self, place, rig, u, shape):
        return {"delta": self.range(place).value(u) * place.scale(rig)}

    zero = ("delta", 0.0)

    def stepper(self, params, init=None):
        return _PlaySteps(params, init)

    def words(self, place, params):
        return f"a play (backlash) of +-{_eng(params['delta'], place.si, place.unit)} in {place.words}"


class Compliance(Kind):
    """A spring k (damping ratio physics.COMPLIANCE_DAMPING) and a body split off a mechanical balance: at the piston
    force, the piston (physics.PISTON_MASS) on a compliant rod to the crank (the generator's two-body states); at
    the crank torque, the crank (the piston and rod seen through it, physics.CRANK_MASS r^2) on a torsion spring
    to the discs."""

    name, noun = "compliance", "a compliance with a mass"
    pattern = r"complian|stiffness|elastic|flexib|spring between|torsion|two[- ]body|link"
    source = ("Merritt 1967 (structural compliance between actuator and load); Jelali & Kroll 2003; "
              "masses assumed (physics.PISTON_MASS, physics.CRANK_MASS)")

    def fits(self, place):
        return place.path == "mechanical"

    def mechanism(self, place):
        return "structural"

    def n_states(self, place):
        return 2 if place.name == "crank_torque" else 0

    def atol(self, place):
        return [1e-10, 1e-8] * (self.n_states(place) // 2)

    def range(self, place):
        return Range("k", 1.5, 15.0, "-", "the oil columns' stiffness 4 beta A^2 / V_t (seen at the place)",
                     stronger=-1)

    def make(self, place, rig, u, shape):
        k = self.range(place).value(u) * place.stiffness(rig)
        return {"k": k, "c": 2.0 * COMPLIANCE_DAMPING * math.sqrt(k * place.body(rig)), "m": place.body(rig)}

    zero = ("k", math.inf)

    def words(self, place, params):
        if place.name == "crank_torque":
            return (f"a compliance of {_fmt(params['k'])} N m/rad between the crank ({_fmt(params['m'])} kg m^2) "
                    f"and the discs in {place.words}")
        return (f"a compliance of {_fmt(params['k'] * 1e-3)} N/mm between the piston ({_fmt(params['m'])} kg) and "
                f"the crank in {place.words}")


class Volume(Kind):
    """A line volume V (:data:`LINE_VOLUME`) behind a laminar resistance R in a hydraulic path: its pressure p_v' =
    beta / V (Q_in - Q_out).  At a chamber the hose between the valve's port and the chamber (the flow meter at the
    port, the pressure transducer at the chamber); at the supply the line from the pump; at the return the line to
    the tank."""

    name, noun = "volume", "a line volume behind a resistance"
    pattern = r"hose|line volume|\bvolume|capacitance|accumulator|\bline\b|pipe"
    source = "Merritt 1967 (hydraulic lines: lumped resistance and capacitance); Jelali & Kroll 2003"

    def fits(self, place):
        return place.path == "hydraulic"

    def mechanism(self, place):
        return "structural"

    def n_states(self, place):
        return 1

    def atol(self, place):
        return [1e-2]

    def rest(self, place, rig):
        return [{"supply": rig.supply, "return": 0.0}.get(place.name, 0.5 * rig.supply)]

    def range(self, place):
        return Range("dp", 0.01, 0.1, "-", "the supply pressure (the drop at the peak flow A v)")

    def make(self, place, rig, u, shape):
        dp = self.range(place).value(u) * rig.supply
        return {"R": dp / peak_flow(rig), "V": LINE_VOLUME, "dp": dp, "Q": peak_flow(rig)}

    zero = ("V", 0.0)  # no line at all (a line of no resistance would still add its volume)

    def words(self, place, params):
        return (f"a line volume of {_fmt(params['V'] * 1e6)} cm^3 behind a resistance of "
                f"{_fmt(params['dp'] / BAR)} bar at {_fmt(params['Q'] / LPM)} LPM in {place.words}")


#: every kind of the grammar, one class each
KINDS = {k.name: k for k in (Offset(), Gain(), DeadZone(), Saturation(), PiecewiseLinear(), Smooth(), Lag(),
                             RateLimit(), Delay(), Play(), Compliance(), Volume())}


def places_of(kind: Kind) -> list:
    """The places ``kind`` fits."""
    return [p for p in PLACES.values() if kind.fits(p)]


# -- blocks ----------------------------------------------------------------------------------------------------------
@dataclass(eq=False)
class Block:
    """A drawn block: a kind at a place with its parameters (SI; currents in mA).

    Read by :class:`.physics.Hooks` through ``place``, ``kind``, ``mechanism``, ``null``, ``n_states``, ``atol``,
    ``params`` and the methods below.
    """

    place: Place
    kind: Kind
    params: dict
    #: the strength in [0, 1] it was drawn at (None when made from its record)
    u: float | None = None

    @property
    def mechanism(self) -> str:
        return self.kind.mechanism(self.place)

    @property
    def null(self) -> bool:
        return self.kind.is_null(self.params)

    @property
    def n_states(self) -> int:
        return self.kind.n_states(self.place)

    @property
    def atol(self) -> list:
        return self.kind.atol(self.place)

    @property
    def words(self) -> str:
        return self.kind.words(self.place, self.params)

    def apply(self, u, y, dy, k):
        return self.kind.apply(self.params, u, y, dy, k)

    def term(self, loc):
        return self.kind.term(self.params, loc)

    def transform(self, u):
        return self.kind.transform(self.params, u)

    def stepper(self, init=None):
        return self.kind.stepper(self.params, init)

    def rest(self, rig):
        return self.kind.rest(self.place, rig)

    def to_dict(self) -> dict:
        """The truth as recorded: place, kind, params (SI), words."""
        return {"place": self.place.name, "kind": self.kind.name, "params": dict(self.params), "words": self.words}


def block_from_dict(d: dict) -> Block:
    """A :class:`Block` from its record ``{"place", "kind", "params"[, "words"]}`` (unknown names refused)."""
    if d["place"] not in PLACES:
        raise KeyError(f"unknown place {d['place']!r}; known: {', '.join(PLACES)}")
    if d["kind"] not in KINDS:
        raise KeyError(f"unknown kind {d['kind']!r}; known: {', '.join(KINDS)}")
    place, kind = PLACES[d["place"]], KINDS[d["kind"]]
    if not kind.fits(place):
        raise ValueError(f"a {kind.name} does not fit {place.name}")
    return Block(place, kind, dict(d["params"]))


def make_block(place: str, kind: str, rig: Rig, u: float, shape: dict | None = None) -> Block:
    """The block of ``kind`` at ``place`` at strength u in [0, 1] on ``rig`` (``shape``: sign and local quantity,
    default the place's sign and first local quantity)."""
    p, k = PLACES[place], KINDS[kind]
    if shape is None:
        shape = {"sign": p.sign if p.term_mode else 1, **({"of": p.locals[0].name} if p.term_mode else {})}
    return Block(p, k, k.make(p, rig, u, shape), u)


# -- the screen: a block's own effect on the logs ---------------------------------------------------------------------
def screen_key(block: Block, rig: str, seed: int) -> str:
    """The cache's key of a block's measure on a rig and noise seed."""
    return f"{rig}|{seed}|{block.place.name}|{block.kind.name}|{json.dumps(block.params, sort_keys=True)}"


class Screen:
    """The effect measure of the redraw rule, cached in a JSON file.

    A block's measure is the campaign with it minus the same campaign without it (same rig, same noise seed), its
    energy over each run in the signal's noise variance, in dB, on the best run and key signal:
    :func:`.start_conditions.effect_db`.  A campaign that fails to integrate or gives non-finite logs has no measure
    (``best_db`` None, with its ``error``) and counts as too strong; one the block does not change at all has
    ``best_db`` None without an error (-inf dB).

    Parameters
    ----------
    path : Path or None
        The cache (None: kept in memory only).
    progress : callable, optional
        ``progress(text)`` after each new measure.
    """

    def __init__(self, path=SCREEN_PATH, progress=None):
        self.path = Path(path) if path else None
        self.progress = progress
        self.entries = {}
        if self.path is not None and self.path.exists():
            self.entries = json.loads(self.path.read_text()).get("entries", {})
        self.clean = {}
        self.measured = 0

    def __call__(self, block: Block, rig: str, seed: int) -> dict:
        key = screen_key(block, rig, seed)
        if key not in self.entries:
            self.entries[key] = self.measure(block, rig, seed)
            self.measured += 1
            self.save()
            if self.progress:
                self.progress(f"screened {block.words} on {rig} (seed {seed}): {self.entries[key]}")
        return self.entries[key]

    def measure(self, block: Block, rig: str, seed: int) -> dict:
        from .start_conditions import effect_db  # its harness imports the package's runner: only when measuring

        if (rig, seed) not in self.clean:
            self.clean[(rig, seed)] = gen.simulate({}, seed=seed, rig=rig)[0]
        try:
            runs = gen.simulate({}, seed=seed, rig=rig, blocks=[block.to_dict()])[0]
        except (RuntimeError, ValueError, FloatingPointError) as e:
            return {"best_db": None, "error": str(e)[:200]}
        if not all(np.all(np.isfinite(np.asarray(v, float))) for _, cols, _ in runs for v in cols.values()):
            return {"best_db": None, "error": "non-finite logs"}
        m = effect_db(runs, self.clean[(rig, seed)], rig)
        return {"best_db": m["best_db"], "best": m["best"]}

    def save(self) -> None:
        if self.path is None:
            return
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        tmp.write_text(json.dumps({"about": "effect measures of the drawn set's candidates (tests/independent_rig/"
                                            "grammar.py, Screen): a cache", "seed": SEED,
                                   "entries": dict(sorted(self.entries.items()))}, indent=1) + "\n")
        os.replace(tmp, self.path)


# -- the draw --------------------------------------------------------------------------------------------------------
def kind_deck(seed: int = SEED, singles: int = N_SINGLES, pairs: int = N_PAIRS) -> list:
    """The kinds of the drawn blocks in order: shuffled rounds of every kind, so that each is drawn about equally
    often (the singles first, then the pairs' blocks two by two)."""
    rng = np.random.default_rng([seed, 0])
    names = list(KINDS)
    deck = []
    while len(deck) < singles + 2 * pairs:
        deck += [names[i] for i in rng.permutation(len(names))]
    return deck


def draw_block(rng: np.random.Generator, kind: str, rig: str, seed: int, measure, taken=()) -> tuple:
    """One block, redrawn until its effect lies within [DB_LOW, DB_HIGH] dB (the redraw rule).

    The place is drawn uniformly among the places ``kind`` fits (not in ``taken``), then the kind's shape (a sign,
    a local quantity), then the strength u uniformly in [0, 1] (the magnitude log-uniform in the kind's range).  A
    block below DB_LOW (or with no effect at all) is redrawn with u uniform above it, one above DB_HIGH (or whose
    campaign failed to integrate) with u below it,
    up to :data:`MAX_TRIES` magnitudes; then the kind is drawn again uniformly and its place with it (at most
    :data:`MAX_KINDS` times).

    Returns
    -------
    block : Block
    screen : dict
        ``best_db``, ``best``, ``tries`` (the magnitudes tried, with their measures).
    """
    r, _ = gen.rig_named(rig)
    tries = []
    for _ in range(MAX_KINDS):
        k = KINDS[kind]
        places = [p for p in places_of(k) if p.name not in taken]
        place = places[int(rng.integers(len(places)))]
        shape = k.shape(place, rng)
        lo, hi = 0.0, 1.0
        for _ in range(MAX_TRIES):
            u = float(rng.uniform(lo, hi))
            b = Block(place, k, k.make(place, r, u, shape), u)
            m = measure(b, rig, seed)
            db = m.get("best_db")
            tries.append({"place": place.name, "kind": k.name, "u": round(u, 4), "best_db": db})
            if db is not None and DB_LOW <= db <= DB_HIGH:
                return b, {"best_db": db, "best": m.get("best"), "tries": tries}
            if "error" not in m and (db is None or db < DB_LOW):  # None: no effect at all (-inf dB)
                lo = u
            else:  # too strong, or the campaign failed to integrate
                hi = u
        kind = list(KINDS)[int(rng.integers(len(KINDS)))]
    raise RuntimeError(f"no block within [{DB_LOW}, {DB_HIGH}] dB after {MAX_KINDS} kinds: {tries}")


def _rig_and_seed(rng: np.random.Generator) -> tuple:
    """A case's rig (uniform among :data:`RIGS`) and noise seed."""
    return RIGS[int(rng.integers(len(RIGS)))], int(rng.integers(10_000, 100_000))


def _case(cid: str, blocks: list, screens: list, rig: str, seed: int) -> dict:
    """A case dict for :func:`.acceptance.run_case`, the blocks as the truth records them."""
    return {"id": cid, "group": "drawn", "effects": {}, "seed": seed, "rig": rig, "duration": gen.DURATION,
            "blocks": [b.to_dict() for b in blocks], "screen": screens}


def drawn_cases(seed: int = SEED, measure=None, singles: int = N_SINGLES, pairs: int = N_PAIRS) -> list:
    """The drawn set: :data:`N_SINGLES` single campaigns and :data:`N_PAIRS` pairs, deterministic for ``seed``.

    Each case has its own random stream (``numpy.random.default_rng([seed, group, index])``), so that a redraw in
    one case leaves the others as they are: it draws the rig uniformly among :data:`RIGS`, the noise seed, and the
    block(s) by :func:`draw_block` with the kind from :func:`kind_deck` (a pair's second block at another place).

    Parameters
    ----------
    seed : int
        The draw's seed (:data:`SEED` for the published set).
    measure : callable, optional
        ``measure(block, rig, seed) -> {"best_db", "best"}`` (default: :class:`Screen` with its cache).
    singles, pairs : int
        How many of each (a held-out draw with another seed may be smaller; the published set is
        :data:`N_SINGLES` and :data:`N_PAIRS`).

    Returns
    -------
    list of dict
        Cases for :func:`.acceptance.run_case`: ``id``, ``group`` ("drawn"), ``effects`` ({}), ``seed``, ``rig``,
        ``duration``, ``blocks`` (the truth: place, kind, params, words), ``screen`` (each block's measure).
    """
    measure = measure or Screen()
    deck = kind_deck(seed, singles, pairs)
    cases = []
    for i in range(singles):
        rng = np.random.default_rng([seed, 1, i])
        rig, noise = _rig_and_seed(rng)
        b, s = draw_block(rng, deck[i], rig, noise, measure)
        cases.append(_case(f"d{i:02d}_{b.kind.name}@{b.place.name}", [b], [s], rig, noise))
    for j in range(pairs):
        rng = np.random.default_rng([seed, 2, j])
        rig, noise = _rig_and_seed(rng)
        k1, k2 = deck[singles + 2 * j], deck[singles + 2 * j + 1]
        b1, s1 = draw_block(rng, k1, rig, noise, measure)
        b2, s2 = draw_block(rng, k2, rig, noise, measure, taken=(b1.place.name,))
        cases.append(_case(f"p{j}_{b1.kind.name}@{b1.place.name}+{b2.kind.name}@{b2.place.name}", [b1, b2],
                           [s1, s2], rig, noise))
    return cases


def case_named(cid: str, seed: int = SEED) -> dict:
    """The drawn case ``cid`` (KeyError naming the known ids otherwise)."""
    cases = drawn_cases(seed)
    for c in cases:
        if c["id"] == cid:
            return c
    raise KeyError(f"no drawn case {cid!r}; known: {', '.join(c['id'] for c in cases)}")


def describe(case: dict) -> str:
    """One line of the list: id, rig, noise seed, each block's words and measure."""
    blocks = "; ".join(f"{b['words']} [{s['best_db']:.1f} dB on {s['best']['signal']}, {s['best']['run']}]"
                       for b, s in zip(case["blocks"], case["screen"]))
    return f"{case['id']}  rig={case['rig']} seed={case['seed']}  {blocks}"


def counts(cases: list) -> dict:
    """Blocks per kind and per place over ``cases``."""
    by_kind, by_place = {k: 0 for k in KINDS}, {p: 0 for p in PLACES}
    for c in cases:
        for b in c["blocks"]:
            by_kind[b["kind"]] += 1
            by_place[b["place"]] += 1
    return {"kinds": by_kind, "places": by_place}
