"""Chapter-1 sizing of the rig: loads, pressures, flows, pump, motor, lines, NAS 1638.

Everything inside is SI (m, kg, s, Pa, m^3/s, rad); engineering units (kN, bar,
LPM, deg, psi, GPM, HP) appear only in the names of the conversion constants
and at the command line (:mod:`ehas_env.cli.size`).

Sources are the book "Electro-Hydraulic Actuation Systems: Design, Testing,
Identification and Validation", chapter 1, as summarised in the project's
``docs/rig.md``, and its tables 1.1-1.6 and 1.16 shipped in :mod:`ehas_env.book.data`.

Where the book contradicts itself (kept here because the tests check them):

* Disc inertia.  The book quotes 0.383 kg m^2 per set of two discs and 2.68 kg m^2
  for 7 sets; its tables 1.1-1.3 are reproduced cell for cell only with
  2.68 / 7 = 0.38286 kg m^2 per set (0.383 per set misses 46 of 126 cells).
* Actuator area.  The tables use A = 7.658e-4 m^2 for the pressure difference
  and the flow; the book's own derivation A = 17265 N / 220 bar gives
  7.848e-4 m^2, which reproduces none of the pressure cells.  7.658e-4 m^2 is,
  to four figures, the annulus of a 40 mm bore / 25 mm rod cylinder; it is
  used as the rig's (fixed) area and the derivation is reported as the
  *required* area.  With it, 1.5 x 150.36 bar = 225.5 bar slightly exceeds the
  220 bar supply: the book's actuator is about 2.5 % short of its own rule.
* Piston speed.  r * omega_max = 0.05 * 9.870 = 0.4935 m/s; the book prints 0.493
  (and, once, 0.463).  0.463 m/s matches no formula; 0.493 is the right one.
* Design flow.  The book's 22.65 LPM (design summary and the last cell of
  table 1.6) is A times the piston speed *rounded to 0.493 m/s*; unrounded,
  A * r * omega_max = 22.67 LPM.  No single area reproduces 2.52, 5.04 and 22.65
  together (they must scale 1 : 2 : 9), so this module returns 22.67 and the
  discrepancy is recorded as a book erratum.
* Motor power.  The book sizes the motor at 3200 psi, i.e. 220 bar (3191 psi)
  rounded up to the next 100 psi; :func:`motor_sizing_pressure` does the same.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ehas_env.physics.rig import BAR, CRANK_RADIUS, DEG, HALF_STROKE, LPM, SUPPLY_PRESSURE  # noqa: F401  (re-exported)

# --- unit conversions (exact by definition unless noted) -------------------------
PSI = 6894.757293168361  # Pa per psi (lbf/in^2)
US_GALLON = 3.785411784e-3  # m^3 per US gallon (the book rounds to 3.785 L)
GPM = US_GALLON / 60.0  # m^3/s per US gallon/minute
HORSEPOWER = 745.6998715822702  # W per mechanical horsepower (550 ft lbf/s)
HYDRAULIC_HP_DIVISOR = 1714.0  # GPM psi per hp: 550*12 in lbf/s / (231 in^3/gal / 60 s), book

# --- the rig (book, via docs/rig.md) -----------------------------------------------------
TOTAL_DISC_INERTIA = 2.68  # kg m^2 for all 7 sets (14 discs), book
MAX_DISC_SETS = 7  # book: 1..7 sets of two discs
DISC_SET_INERTIA = TOTAL_DISC_INERTIA / MAX_DISC_SETS  # kg m^2; book rounds to 0.383 (see module notes)
ACTUATOR_AREA = 7.658e-4  # m^2, net piston area used by the book's tables
SAFETY_FACTOR = 1.5  # -, book's factor of safety on the actuator force

# The book's load and flow tables (1.1-1.6) and its design point.
BOOK_AMPLITUDES_DEG = (10.0, 20.0, 30.0)  # deg, tables 1.1-1.6
BOOK_FREQUENCIES_HZ = (1.0, 2.0, 3.0)  # Hz, tables 1.1-1.6
BOOK_DISC_SETS = tuple(range(1, MAX_DISC_SETS + 1))  # tables 1.1-1.3
DESIGN_AMPLITUDE_DEG = 30.0  # deg, book's design point
DESIGN_FREQUENCY_HZ = 3.0  # Hz, book's design point
DESIGN_DISC_SETS = MAX_DISC_SETS  # book's design point: all 14 discs

# --- selection rules -------------------------------------------------------------------
PUMP_FLOW_STEP = 5.0 * LPM  # m^3/s; assumed: pumps are catalogued in 5 LPM steps (book picks 25 LPM for 22.65)
MOTOR_PRESSURE_STEP = 100.0 * PSI  # Pa; book sizes at 3200 psi for 220 bar, i.e. rounds up to 100 psi
NEMA_MOTOR_HP = (1, 1.5, 2, 3, 5, 7.5, 10, 15, 20, 25, 30, 40, 50, 60, 75, 100)  # hp; assumed: NEMA MG 1 ratings
IEC_MOTOR_KW = (0.75, 1.1, 1.5, 2.2, 3, 4, 5.5, 7.5, 11, 15, 18.5, 22, 30, 37, 45, 55, 75)  # kW; assumed: IEC 60072-1

# Line velocity limits, book chapter 1: <= 5 m/s in pressure lines above 2000 psi,
# <= 3 m/s in low-pressure lines below 100 psi, <= 1 m/s in pump suction lines.
HIGH_PRESSURE_LINE = 2000.0 * PSI  # Pa, book
LOW_PRESSURE_LINE = 100.0 * PSI  # Pa, book
HIGH_PRESSURE_VELOCITY = 5.0  # m/s, book
LOW_PRESSURE_VELOCITY = 3.0  # m/s, book; assumed also between 100 and 2000 psi (book gives no rule, slower is safe)
SUCTION_VELOCITY = 1.0  # m/s, book
LINE_KINDS = ("pressure", "return", "suction")
RETURN_LINE_PRESSURE = 0.0  # Pa gauge; assumed: the return line runs near tank pressure (< 100 psi)

def _scalar_or_array(value):
    """A Python float for scalar results (plain doctest reprs), the array otherwise."""
    array = np.asarray(value, dtype=float)
    return float(array) if array.ndim == 0 else array


# --- input checks ------------------------------------------------------------------------


def check_positive(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` if it is a finite number > 0, else raise ValueError naming it.

    Parameters
    ----------
    name : str
        Argument name used in the message, e.g. ``"--freq"``.
    value : float
        The value to check.
    unit : str, optional
        Unit shown in the message.

    Returns
    -------
    float
        ``value`` as a float.

    Examples
    --------
    >>> check_positive("--freq", 3)
    3.0
    >>> check_positive("--freq", 0, "Hz")
    Traceback (most recent call last):
    ...
    ValueError: --freq must be > 0 Hz, got 0
    """
    number = float(value)
    if not (math.isfinite(number) and number > 0.0):
        unit_text = f" {unit}" if unit else ""
        raise ValueError(f"{name} must be > 0{unit_text}, got {value}")
    return number


def check_disc_sets(disc_sets: int) -> int:
    """Return ``disc_sets`` if it is an integer in 1..7, else raise ValueError.

    Examples
    --------
    >>> check_disc_sets(7)
    7
    >>> check_disc_sets(8)
    Traceback (most recent call last):
    ...
    ValueError: --disc-sets must be an integer in 1..7 (sets of 2 discs), got 8
    """
    if isinstance(disc_sets, bool) or int(disc_sets) != disc_sets or not 1 <= disc_sets <= MAX_DISC_SETS:
        raise ValueError(
            f"--disc-sets must be an integer in 1..{MAX_DISC_SETS} (sets of 2 discs), got {disc_sets}"
        )
    return int(disc_sets)


def stroke_end_angle(radius: float = CRANK_RADIUS, half_stroke: float = HALF_STROKE) -> float:
    """Crank angle at which the actuator reaches its end of stroke, rad.

    The piston moves r*sin(theta); past half the stroke it hits the end cap.  A
    crank shorter than the half stroke never reaches it, and the limit is then
    90 deg, where cos(theta) in the force formula vanishes.

    Examples
    --------
    >>> round(stroke_end_angle() / DEG, 2)  # asin(35 mm / 50 mm)
    44.43
    """
    return math.asin(min(half_stroke / radius, 1.0))


def check_amplitude(amplitude: float, radius: float = CRANK_RADIUS, half_stroke: float = HALF_STROKE) -> float:
    """Return ``amplitude`` (rad) if 0 < amplitude < stroke end, else raise ValueError.

    Examples
    --------
    >>> round(check_amplitude(30 * DEG), 4)
    0.5236
    >>> check_amplitude(45 * DEG)
    Traceback (most recent call last):
    ...
    ValueError: --amplitude must be in (0, 44.43) deg (stroke end: 35 mm on a 50 mm crank), got 45 deg
    """
    limit = stroke_end_angle(radius, half_stroke)
    if not (math.isfinite(amplitude) and 0.0 < amplitude < limit):
        reason = (f"stroke end: {half_stroke * 1e3:g} mm on a {radius * 1e3:g} mm crank"
                  if radius > half_stroke else "the crank force r*cos(theta) vanishes at 90 deg")
        raise ValueError(f"--amplitude must be in (0, {limit / DEG:.2f}) deg ({reason}), got {amplitude / DEG:g} deg")
    return float(amplitude)


# --- kinematics and loads ------------------------------------------------------------


def disc_inertia(disc_sets: int) -> float:
    """Inertia of ``disc_sets`` sets of two discs about the crank axis, kg m^2.

    Examples
    --------
    >>> round(disc_inertia(7), 2), round(disc_inertia(1), 4)
    (2.68, 0.3829)
    """
    return check_disc_sets(disc_sets) * DISC_SET_INERTIA


def peak_angular_velocity(amplitude, freq):
    """Peak crank rate of theta = amplitude*sin(2 pi f t), rad/s.

    Parameters
    ----------
    amplitude : float or ndarray
        Amplitude theta_max, rad.
    freq : float or ndarray
        Frequency f, Hz.

    Examples
    --------
    >>> round(peak_angular_velocity(30 * DEG, 3.0), 2)
    9.87
    """
    return _scalar_or_array(np.multiply(amplitude, 2.0 * np.pi * np.asarray(freq, dtype=float)))


def peak_angular_acceleration(amplitude, freq):
    """Peak crank acceleration of theta = amplitude*sin(2 pi f t), rad/s^2.

    Examples
    --------
    >>> round(peak_angular_acceleration(30 * DEG, 3.0), 2)
    186.04
    """
    return _scalar_or_array(np.multiply(amplitude, (2.0 * np.pi * np.asarray(freq, dtype=float)) ** 2))


def peak_actuator_force(inertia, amplitude, freq, radius=CRANK_RADIUS):
    """Peak actuator force to swing a pure inertia through the crank, N.

    F = I*alpha/(r*cos(theta)).  For a sinusoid alpha = -(2 pi f)^2 theta, so
    |alpha| and 1/cos(theta) both peak at theta = theta_max: the book's
    F_max = I*alpha_max/(r*cos(theta_max)) is exact, not a bound.

    Examples
    --------
    >>> round(peak_actuator_force(2.68, 30 * DEG, 3.0) / 1e3, 2)  # kN, book: 11.51
    11.51
    """
    alpha = peak_angular_acceleration(amplitude, freq)
    return _scalar_or_array(np.multiply(inertia, alpha) / np.multiply(radius, np.cos(amplitude)))


def pressure_difference(force, area=ACTUATOR_AREA):
    """Load pressure difference across the piston that carries ``force``, Pa.

    Examples
    --------
    >>> round(pressure_difference(11514.5, 7.658e-4) / BAR, 2)
    150.36
    """
    return _scalar_or_array(np.divide(force, area))


def required_area(force: float, supply_pressure: float = SUPPLY_PRESSURE,
                  safety_factor: float = SAFETY_FACTOR) -> float:
    """Net piston area that gives ``safety_factor * force`` at the supply pressure, m^2.

    Examples
    --------
    >>> f"{required_area(11510.0, 220 * BAR):.3e}"  # the book's 17265 N / 220 bar
    '7.848e-04'
    """
    return safety_factor * force / supply_pressure


def piston_speed(amplitude, freq, radius=CRANK_RADIUS):
    """Peak piston speed r*omega_max, m/s (at mid stroke, where cos(theta) = 1).

    Examples
    --------
    >>> round(piston_speed(30 * DEG, 3.0), 4)  # the book prints 0.493 (and once 0.463)
    0.4935
    """
    return _scalar_or_array(np.multiply(radius, peak_angular_velocity(amplitude, freq)))


def actuator_flow(speed, area=ACTUATOR_AREA):
    """Flow A*V the actuator swallows at piston speed ``speed``, m^3/s.

    Examples
    --------
    >>> round(actuator_flow(0.4935, 7.658e-4) / LPM, 2)
    22.68
    """
    return _scalar_or_array(np.multiply(area, speed))


# --- pump, motor, lines --------------------------------------------------------------------


def round_up(value: float, step: float) -> float:
    """Smallest multiple of ``step`` that is >= ``value`` (to 1e-9 relative).

    Examples
    --------
    >>> round_up(22.67, 5.0)
    25.0
    """
    # the tolerance keeps an exact multiple (e.g. 25 LPM in m^3/s) from rounding up a step
    return math.ceil(value / step - 1e-9) * step


def pump_flow_rating(flow: float, step: float = PUMP_FLOW_STEP) -> float:
    """Catalogue pump flow for a peak actuator flow, m^3/s (next ``step`` up).

    Examples
    --------
    >>> round(pump_flow_rating(22.67 * LPM) / LPM, 6)
    25.0
    """
    return round_up(flow, step)


def motor_sizing_pressure(supply_pressure: float = SUPPLY_PRESSURE) -> float:
    """Pressure the book sizes the motor at: supply rounded up to 100 psi, Pa.

    Examples
    --------
    >>> round(motor_sizing_pressure(220 * BAR) / PSI, 6)
    3200.0
    """
    return round_up(supply_pressure, MOTOR_PRESSURE_STEP)


def hydraulic_power(flow: float, pressure: float) -> float:
    """Hydraulic power HP = GPM*psi/1714 (book), returned in W.

    Examples
    --------
    >>> round(hydraulic_power(6.605 * GPM, 3200 * PSI) / HORSEPOWER, 2)  # book: 12.33 HP
    12.33
    """
    horsepower = (flow / GPM) * (pressure / PSI) / HYDRAULIC_HP_DIVISOR
    return horsepower * HORSEPOWER


def standard_motor(power: float) -> tuple[float, float]:
    """Smallest standard motor ratings that cover ``power`` W: (hp, kW).

    Examples
    --------
    >>> standard_motor(12.33 * HORSEPOWER)  # book: 15 HP / 11 kW
    (15, 11)
    """
    needed_hp = power / HORSEPOWER
    needed_kw = power / 1e3
    hp = next((h for h in NEMA_MOTOR_HP if h >= needed_hp), None)
    kw = next((k for k in IEC_MOTOR_KW if k >= needed_kw), None)
    if hp is None or kw is None:
        raise ValueError(
            f"motor power {needed_kw:.1f} kW is beyond the largest standard rating "
            f"({IEC_MOTOR_KW[-1]} kW); reduce --freq, --amplitude or the load"
        )
    return hp, kw


def line_velocity_limit(kind: str, pressure: float = 0.0) -> float:
    """Highest fluid velocity the book allows in a line, m/s.

    Parameters
    ----------
    kind : {"pressure", "return", "suction"}
        Line type; suction lines are limited regardless of pressure.
    pressure : float
        Line pressure, Pa gauge.

    Examples
    --------
    >>> line_velocity_limit("pressure", 220 * BAR), line_velocity_limit("suction")
    (5.0, 1.0)
    """
    if kind not in LINE_KINDS:
        raise ValueError(f"line kind must be one of {', '.join(LINE_KINDS)}, got {kind!r}")
    if kind == "suction":
        return SUCTION_VELOCITY
    return HIGH_PRESSURE_VELOCITY if pressure > HIGH_PRESSURE_LINE else LOW_PRESSURE_VELOCITY


def line_bore(flow: float, velocity: float) -> float:
    """Smallest bore d = sqrt(4Q/(pi v)) that keeps flow ``flow`` below ``velocity``, m.

    Examples
    --------
    >>> round(line_bore(25 * LPM, 5.0) * 1e3, 2)  # mm
    10.3
    """
    check_positive("line velocity", velocity, "m/s")
    return math.sqrt(4.0 * flow / (math.pi * velocity))


# --- NAS 1638 ------------------------------------------------------------------------------


@dataclass(frozen=True)
class NasLimit:
    """Upper particle counts per 100 ml for one NAS 1638 class.

    Attributes
    ----------
    label : str
        Class label, ``"00"``, ``"0"``, ``"1"`` ... ``"12"``.
    counts : tuple of int
        Counts per 100 ml in the bands 5-15, 15-25, 25-50, 50-100, >100 micron.
    """

    label: str
    counts: tuple[int, ...]


def _book_nas_limits() -> list[NasLimit]:
    from ehas_env.book.tables import nas1638  # data loading stays out of the pure maths

    return [NasLimit(row.nas_class, row.counts) for row in nas1638()]


def nas_class(counts: Sequence[float], limits: Sequence[NasLimit] | None = None) -> str:
    """NAS 1638 class of a sample: the worst band decides.

    Parameters
    ----------
    counts : sequence of float
        Particles per 100 ml in the five bands 5-15, 15-25, 25-50, 50-100, >100 micron.
    limits : sequence of NasLimit, optional
        Classes from cleanest to dirtiest; default the book's table 1.16.

    Returns
    -------
    str
        The lowest class whose limits every band stays within.

    Examples
    --------
    >>> nas_class([60000, 11000, 1900, 300, 60])
    '8'
    >>> nas_class([60000, 11000, 1900, 300, 100])  # >100 micron band is class 9
    '9'
    """
    limits = _book_nas_limits() if limits is None else list(limits)
    values = np.asarray(counts, dtype=float)
    bands = len(limits[0].counts)
    if values.shape != (bands,) or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError(f"--nas-counts needs {bands} counts >= 0 (particles per 100 ml per band), got {list(counts)}")
    for limit in limits:
        if np.all(values <= np.asarray(limit.counts, dtype=float)):
            return limit.label
    raise ValueError(f"--nas-counts exceed NAS 1638 class {limits[-1].label}, the dirtiest class tabulated")


def nas_counts(label: str, limits: Sequence[NasLimit] | None = None) -> tuple[int, ...]:
    """Particle counts per 100 ml per band allowed in NAS 1638 class ``label``.

    Examples
    --------
    >>> nas_counts("8")
    (64000, 11400, 2000, 360, 64)
    """
    limits = _book_nas_limits() if limits is None else list(limits)
    for limit in limits:
        if limit.label == str(label):
            return limit.counts
    allowed = ", ".join(limit.label for limit in limits)
    raise ValueError(f"--nas-class must be one of {allowed}, got {label}")


# --- a whole design ----------------------------------------------------------------------


@dataclass(frozen=True)
class Design:
    """One sizing case (SI).

    Attributes
    ----------
    inertia : float
        Load inertia about the crank axis, kg m^2.
    amplitude : float
        Command amplitude theta_max, rad.
    freq : float
        Command frequency, Hz.
    radius : float
        Crank radius, m.
    area : float
        Net piston area of the actuator used, m^2.
    supply_pressure : float
        Supply pressure, Pa.
    safety_factor : float
        Factor of safety on the actuator force, -.
    half_stroke : float
        Half the actuator stroke, m (limits the amplitude).
    """

    inertia: float = DESIGN_DISC_SETS * DISC_SET_INERTIA
    amplitude: float = DESIGN_AMPLITUDE_DEG * DEG
    freq: float = DESIGN_FREQUENCY_HZ
    radius: float = CRANK_RADIUS
    area: float = ACTUATOR_AREA
    supply_pressure: float = SUPPLY_PRESSURE
    safety_factor: float = SAFETY_FACTOR
    half_stroke: float = HALF_STROKE

    def __post_init__(self) -> None:
        check_positive("--inertia", self.inertia, "kg m^2")
        check_positive("--radius", self.radius, "m")
        check_amplitude(self.amplitude, self.radius, self.half_stroke)
        check_positive("--freq", self.freq, "Hz")
        check_positive("--area", self.area, "m^2")
        check_positive("--supply-bar", self.supply_pressure / BAR, "bar")
        if not (math.isfinite(self.safety_factor) and self.safety_factor >= 1.0):
            raise ValueError(f"--safety-factor must be >= 1, got {self.safety_factor:g}")


@dataclass(frozen=True)
class Sizing:
    """Results of :func:`size` (SI).

    Attributes
    ----------
    omega_max, alpha_max : float
        Peak crank rate (rad/s) and acceleration (rad/s^2).
    force : float
        Peak actuator force, N.
    design_force : float
        ``safety_factor * force``, N.
    required_area : float
        Area that gives ``design_force`` at the supply pressure, m^2.
    delta_p : float
        Peak load pressure difference with the design's area, Pa.
    speed : float
        Peak piston speed, m/s.
    flow : float
        Peak actuator flow with the design's area, m^3/s.
    pump_flow : float
        Catalogue pump flow, m^3/s.
    motor_pressure : float
        Pressure the motor is sized at, Pa.
    power : float
        Hydraulic power of the pump at that pressure, W.
    motor_hp, motor_kw : float
        Standard motor ratings chosen.
    line_bores : dict of str to float
        Smallest bore of the pressure, return and suction lines at the pump flow, m.
    """

    omega_max: float
    alpha_max: float
    force: float
    design_force: float
    required_area: float
    delta_p: float
    speed: float
    flow: float
    pump_flow: float
    motor_pressure: float
    power: float
    motor_hp: float
    motor_kw: float
    line_bores: dict


def size(design: Design = Design()) -> Sizing:
    """Size actuator, pump, motor and lines for one design.

    Examples
    --------
    >>> s = size()  # the book's design point: 14 discs, +-30 deg, 3 Hz
    >>> round(s.force / 1e3, 2), round(s.design_force / 1e3, 2), round(s.flow / LPM, 2)
    (11.51, 17.27, 22.67)
    >>> round(s.power / HORSEPOWER, 2), s.motor_hp, s.motor_kw
    (12.33, 15, 11)
    """
    force = float(peak_actuator_force(design.inertia, design.amplitude, design.freq, design.radius))
    design_force = design.safety_factor * force
    speed = float(piston_speed(design.amplitude, design.freq, design.radius))
    flow = float(actuator_flow(speed, design.area))
    pump_flow = pump_flow_rating(flow)
    motor_pressure = motor_sizing_pressure(design.supply_pressure)
    power = hydraulic_power(pump_flow, motor_pressure)
    motor_hp, motor_kw = standard_motor(power)
    line_pressures = {"pressure": design.supply_pressure, "return": RETURN_LINE_PRESSURE, "suction": 0.0}
    line_bores = {
        kind: line_bore(pump_flow, line_velocity_limit(kind, pressure)) for kind, pressure in line_pressures.items()
    }
    return Sizing(
        omega_max=float(peak_angular_velocity(design.amplitude, design.freq)),
        alpha_max=float(peak_angular_acceleration(design.amplitude, design.freq)),
        force=force,
        design_force=design_force,
        required_area=required_area(force, design.supply_pressure, design.safety_factor),
        delta_p=float(pressure_difference(force, design.area)),
        speed=speed,
        flow=flow,
        pump_flow=pump_flow,
        motor_pressure=motor_pressure,
        power=power,
        motor_hp=motor_hp,
        motor_kw=motor_kw,
        line_bores=line_bores,
    )


# --- the book's tables ---------------------------------------------------------------------


@dataclass(frozen=True)
class LoadPoint:
    """One row of the book's tables 1.1-1.3 (SI).

    Attributes
    ----------
    amplitude : float
        rad.
    disc_sets : int
        Sets of two discs.
    inertia : float
        kg m^2.
    freq : float
        Hz.
    force : float
        Peak actuator force, N.
    delta_p : float
        Peak pressure difference with the fixed area, Pa.
    """

    amplitude: float
    disc_sets: int
    inertia: float
    freq: float
    force: float
    delta_p: float


@dataclass(frozen=True)
class FlowPoint:
    """One row of the book's tables 1.4-1.6 (SI); independent of the load.

    Attributes
    ----------
    amplitude : float
        rad.
    freq : float
        Hz.
    omega_max : float
        rad/s.
    speed : float
        Peak piston speed, m/s.
    flow : float
        Peak actuator flow, m^3/s.
    """

    amplitude: float
    freq: float
    omega_max: float
    speed: float
    flow: float


def load_table(radius: float = CRANK_RADIUS, area: float = ACTUATOR_AREA, set_inertia: float = DISC_SET_INERTIA,
               half_stroke: float = HALF_STROKE) -> list[LoadPoint]:
    """Tables 1.1-1.3: peak force and pressure over the book's grid, in its row order.

    The pressure uses the fixed area ``area``, as the book does, not the area
    each load would require.  ``set_inertia`` (kg m^2 per disc set) and
    ``half_stroke`` (m) describe another rig (a model file, docs/model-file.md).

    Examples
    --------
    >>> rows = load_table()
    >>> len(rows), round(rows[-1].force / 1e3, 2), round(rows[-1].delta_p / BAR, 2)
    (63, 11.51, 150.36)
    """
    check_positive("--radius", radius, "m")
    check_positive("--area", area, "m^2")
    rows = []
    for amplitude_deg in BOOK_AMPLITUDES_DEG:
        amplitude = check_amplitude(amplitude_deg * DEG, radius, half_stroke)
        for sets in BOOK_DISC_SETS:
            inertia = disc_inertia(sets) if set_inertia == DISC_SET_INERTIA else sets * set_inertia
            for freq in BOOK_FREQUENCIES_HZ:
                force = float(peak_actuator_force(inertia, amplitude, freq, radius))
                rows.append(LoadPoint(amplitude, sets, inertia, freq, force, float(pressure_difference(force, area))))
    return rows


def flow_table(radius: float = CRANK_RADIUS, area: float = ACTUATOR_AREA,
               half_stroke: float = HALF_STROKE) -> list[FlowPoint]:
    """Tables 1.4-1.6: peak crank rate, piston speed and flow over the book's grid.

    Examples
    --------
    >>> rows = flow_table()
    >>> len(rows), round(rows[0].flow / LPM, 2)
    (9, 2.52)
    """
    check_positive("--radius", radius, "m")
    check_positive("--area", area, "m^2")
    rows = []
    for amplitude_deg in BOOK_AMPLITUDES_DEG:
        amplitude = check_amplitude(amplitude_deg * DEG, radius, half_stroke)
        for freq in BOOK_FREQUENCIES_HZ:
            speed = float(piston_speed(amplitude, freq, radius))
            rows.append(FlowPoint(amplitude, freq, float(peak_angular_velocity(amplitude, freq)),
                                  speed, float(actuator_flow(speed, area))))
    return rows
