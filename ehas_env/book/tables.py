"""The book's printed tables, as shipped in :mod:`ehas_env.book.data`.

Each CSV starts with one ``#`` line naming its source table, then a header.
The records keep the book's own units and column names (``max_force_kN`` ...),
so that a record's fields are exactly the CSV's columns.  These are the book's
numbers, for comparison only: :mod:`ehas_env.book.sizing` recomputes them.
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, fields
from functools import lru_cache
from importlib import resources
from typing import TypeVar

_PACKAGE = "ehas_env.book.data"


@dataclass(frozen=True)
class LoadRecord:
    """Tables 1.1-1.3 (``analytic_loads.csv``): peak actuator force and pressure difference."""

    amplitude_deg: float
    disc_sets: int
    discs: int
    inertia_kgm2: float
    freq_hz: float
    max_force_kN: float
    max_delta_p_bar: float


@dataclass(frozen=True)
class FlowRecord:
    """Tables 1.4-1.6 (``analytic_flows.csv``): peak crank rate, piston speed and flow."""

    amplitude_deg: float
    freq_hz: float
    max_angular_velocity_rad_s: float
    max_linear_velocity_m_s: float
    max_flow_lpm: float


@dataclass(frozen=True)
class RigTestRecord:
    """Tables 1.9-1.15 (``rig_tests.csv``): closed-loop sine tests, analytic vs measured.

    ``discs`` counts single discs, ``disc_sets`` pairs of them (discs = 2 x sets).
    The book does not define ``pos_error_percent``.
    """

    amplitude_deg: float
    freq_hz: float
    discs: int
    disc_sets: int
    pos_error_percent: float
    load_analytic_kN: float
    load_test_kN: float
    flow_analytic_lpm: float
    flow_test_lpm: float


@dataclass(frozen=True)
class NasRecord:
    """Table 1.16 (``nas1638.csv``): NAS 1638 particle counts per 100 ml by size band.

    Attributes
    ----------
    nas_class : str
        ``"00"``, ``"0"``, ``"1"`` ... ``"12"`` (a string: "00" is not "0").
    counts : tuple of int
        Counts in the bands of :data:`NAS_BANDS`.
    """

    nas_class: str
    counts: tuple[int, ...]


@dataclass(frozen=True)
class BookDesignText:
    """Numbers the book prints in its chapter-1 design summary (docs/rig.md).

    Shown beside the recomputed values; they are not used to compute anything.
    The book's "17265 kN" means N (1.5 x the rounded 11.51 kN); its piston
    speed 0.493 m/s is once misprinted 0.463.
    """

    force_kN: float = 11.51
    design_force_N: float = 17265.0
    area_m2: float = 7.658e-4
    speed_m_s: float = 0.493
    flow_lpm: float = 22.65
    pump_flow_lpm: float = 25.0
    pump_flow_gpm: float = 6.605
    motor_pressure_psi: float = 3200.0
    power_hp: float = 12.33
    motor_hp: float = 15.0
    motor_kw: float = 11.0
    supply_bar: float = 220.0


BOOK_DESIGN = BookDesignText()
NAS_BANDS = ("5-15", "15-25", "25-50", "50-100", ">100")  # micron, table 1.16

Record = TypeVar("Record")


def read_rows(name: str) -> list[dict[str, str]]:
    """Rows of the shipped CSV ``name`` as dicts of strings, the ``#`` line skipped.

    Examples
    --------
    >>> read_rows("analytic_flows.csv")[0]["max_flow_lpm"]
    '2.52'
    """
    text = resources.files(_PACKAGE).joinpath(name).read_text(encoding="utf-8")
    lines = [line for line in io.StringIO(text) if not line.startswith("#")]
    return list(csv.DictReader(lines))


def _typed(record_type: type[Record], name: str) -> tuple[Record, ...]:
    rows = read_rows(name)
    names = [f.name for f in fields(record_type)]
    if rows and list(rows[0]) != names:
        # the records promise the CSV's exact columns; fail loudly if the data drifted
        raise ValueError(f"{name}: columns {list(rows[0])} differ from {record_type.__name__} {names}")
    converters = {f.name: _converter(f.type) for f in fields(record_type)}
    return tuple(record_type(**{k: converters[k](v) for k, v in row.items()}) for row in rows)


def _converter(type_name):
    # dataclass annotations are strings under `from __future__ import annotations`
    return {"int": int, "float": float, "str": str}[str(type_name)]


@lru_cache(maxsize=None)
def analytic_loads() -> tuple[LoadRecord, ...]:
    """The book's tables 1.1-1.3, in its row order.

    Examples
    --------
    >>> analytic_loads()[-1].max_force_kN
    11.51
    """
    return _typed(LoadRecord, "analytic_loads.csv")


@lru_cache(maxsize=None)
def analytic_flows() -> tuple[FlowRecord, ...]:
    """The book's tables 1.4-1.6, in its row order.

    Examples
    --------
    >>> analytic_flows()[-1].max_flow_lpm
    22.65
    """
    return _typed(FlowRecord, "analytic_flows.csv")


@lru_cache(maxsize=None)
def rig_tests() -> tuple[RigTestRecord, ...]:
    """The book's closed-loop rig tests, tables 1.9-1.15.

    Examples
    --------
    >>> [(t.discs, t.disc_sets) for t in rig_tests()][:2]
    [(4, 2), (4, 2)]
    """
    return _typed(RigTestRecord, "rig_tests.csv")


@lru_cache(maxsize=None)
def nas1638() -> tuple[NasRecord, ...]:
    """The book's table 1.16, cleanest class first.

    Examples
    --------
    >>> nas1638()[0].nas_class, nas1638()[-1].counts[0]
    ('00', 1000000)
    """
    rows = read_rows("nas1638.csv")
    if rows and tuple(rows[0])[1:] != NAS_BANDS:
        raise ValueError(f"nas1638.csv: bands {tuple(rows[0])[1:]} differ from {NAS_BANDS}")
    return tuple(NasRecord(row["class"], tuple(int(row[band]) for band in NAS_BANDS)) for row in rows)
