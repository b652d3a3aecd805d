"""The rig's baseline parameters, SI units, each with its source.

Sources: the book "Electro-Hydraulic Actuation Systems: Design, Testing,
Identification and Validation" as summarised in the project's ``rig.md`` and
``reference-model.md``.  Values marked *assumed* are not in the book; the reason
is given beside them.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

BAR = 1.0e5  # Pa per bar
LPM = 1.0e-3 / 60.0  # m^3/s per litre/minute
DEG = math.pi / 180.0  # rad per degree
MA = 1.0e-3  # A per mA (the valve model works in mA, see ValveParams)

CRANK_RADIUS = 0.05  # m, book
INERTIA_PER_SET = 0.383  # kg m^2 per set of two discs, book
MIN_SETS, MAX_SETS = 1, 7  # book: 1..7 sets (2..14 discs)
AREA = 7.658e-4  # m^2, actuator net area, book (F = 1.5 x 11.51 kN at 220 bar)
HALF_STROKE = 0.035  # m, book: 70 mm stroke
THETA_STROKE_END = math.asin(HALF_STROKE / CRANK_RADIUS)  # rad, 44.43 deg
SUPPLY_PRESSURE = 220.0 * BAR  # Pa, book
RATED_VALVE_DROP = 70.0 * BAR  # Pa, book: rated 25 LPM at 70 bar valve drop
RATED_CURRENT = 20.0  # mA, book: +-20 mA servo amplifier
VALVE_K = 1.2723  # LPM/mA, book's chirp 2p0z model 14567.29/11449.86
VALVE_WN = 107.0  # rad/s, book's transfer function sqrt(11449.86) (its text's 132 rad/s is wrong)
VALVE_ZETA = 0.691  # -, book: 147.83 / (2 * 107.0)
BULK_MODULUS = 1.0e9  # Pa, reference-model.md
DEAD_VOLUME = 2.0e-5  # m^3 per side, reference-model.md (hoses and port volume)
CONTROL_RATE = 1000.0  # Hz, RMC70 loop rate (reference-model.md)


@dataclass(frozen=True)
class RigParams:
    """Baseline plant parameters (SI).

    Attributes
    ----------
    disc_sets : int
        Number of disc sets, 1..7 (book).
    inertia : float
        Load inertia about the crank axis, kg m^2 (0.383 per set, book).
    radius : float
        Crank radius, m (book: 0.05).
    area : float
        Actuator net piston area, m^2 (book: 7.658e-4).
    half_stroke : float
        Half the actuator stroke, m (book: 0.035).
    supply : float
        Supply pressure Ps, Pa (book: 220 bar).
    rated_drop : float
        Valve drop at which the no-load flow q_c is rated, Pa (book: 70 bar).
    beta : float
        Effective bulk modulus of the oil, Pa (reference model: 1e9).
    dead_volume : float
        Dead volume of each chamber plus its line, m^3 (reference model: 2e-5).
    K : float
        Valve flow gain at the rated drop, LPM/mA (book's identified model).
    wn : float
        Valve natural frequency, rad/s (book's identified model).
    zeta : float
        Valve damping ratio, - (book's identified model).
    i_max : float
        Servo amplifier saturation, mA (book: +-20 mA).
    """

    disc_sets: int = 3
    inertia: float = 3 * INERTIA_PER_SET
    radius: float = CRANK_RADIUS
    area: float = AREA
    half_stroke: float = HALF_STROKE
    supply: float = SUPPLY_PRESSURE
    rated_drop: float = RATED_VALVE_DROP
    beta: float = BULK_MODULUS
    dead_volume: float = DEAD_VOLUME
    K: float = VALVE_K
    wn: float = VALVE_WN
    zeta: float = VALVE_ZETA
    i_max: float = RATED_CURRENT

    @classmethod
    def for_disc_sets(cls, disc_sets: int, **overrides) -> "RigParams":
        """Parameters of the rig with ``disc_sets`` sets of discs (1..7)."""
        check_disc_sets(disc_sets)
        return cls(disc_sets=int(disc_sets), inertia=disc_sets * INERTIA_PER_SET, **overrides)

    @property
    def v0(self) -> float:
        """Chamber volume at mid-stroke, m^3: A * half stroke + dead volume."""
        return self.area * self.half_stroke + self.dead_volume

    @property
    def theta_stroke_end(self) -> float:
        """Crank angle at the stroke ends, rad."""
        return math.asin(min(self.half_stroke / self.radius, 1.0))

    def hydraulic_natural_frequency(self) -> float:
        """Small-signal hydraulic natural frequency at mid-stroke, rad/s.

        ``sqrt(2 beta A^2 / (V0 * I / r^2))``: two chambers of volume V0 as springs
        on the inertia reflected to the piston.

        Examples
        --------
        >>> round(RigParams.for_disc_sets(7).hydraulic_natural_frequency() / (2 * math.pi), 1)
        24.3
        """
        m_eq = self.inertia / self.radius**2
        return math.sqrt(2.0 * self.beta * self.area**2 / (self.v0 * m_eq))

    def replace(self, **changes) -> "RigParams":
        return replace(self, **changes)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))


def check_disc_sets(disc_sets) -> None:
    """Raise ValueError unless ``disc_sets`` is an integer in 1..7."""
    if isinstance(disc_sets, bool) or not float(disc_sets).is_integer() or not MIN_SETS <= disc_sets <= MAX_SETS:
        raise ValueError(f"disc_sets must be an integer from {MIN_SETS} to {MAX_SETS}, got {disc_sets!r}")
