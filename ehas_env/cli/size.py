"""``ehas size``: the book's chapter-1 sizing, for the book's design or any other.

With no arguments it prints the book's tables 1.1-1.6 recomputed, the design
summary beside the book's printed numbers, the rig tests (tables 1.9-1.15)
analytic vs measured, and the NAS 1638 table.  Design arguments (``--disc-sets``,
``--amplitude`` ...) switch the default to the summary of that one design.

Engineering units live here (deg, bar, kN, LPM, mm); :mod:`ehas_env.book.sizing`
works in SI.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
from dataclasses import dataclass

TABLES = ("all", "loads", "flows", "design", "rig", "nas")
FORMATS = ("text", "csv", "json")
DESIGN_ARGS = ("disc_sets", "inertia", "radius", "amplitude", "freq", "supply_bar", "safety_factor", "area")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``size`` options to ``parser`` (no heavy imports here)."""
    parser.add_argument("--table", choices=TABLES, default=None,
                        help="what to print (default: all; 'design' when a design argument is given)")
    parser.add_argument("--format", choices=FORMATS, default="text",
                        help="text (default), or csv / json records of one table")
    from ehas_env.ranges import number, option

    load = parser.add_mutually_exclusive_group()
    load.add_argument("--disc-sets", type=option("--disc-sets", "disc_sets"), default=None,
                      help="load as sets of 2 discs, 1..7 (2.68/7 kg m^2 each); default 7")
    load.add_argument("--inertia", type=number("--inertia", "kg m^2", 1e-6, 1e4), default=None, help="load inertia about the crank axis, kg m^2")
    parser.add_argument("--radius", type=number("--radius", "m", 1e-3, 10), default=None, help="crank radius, m (default 0.05)")
    parser.add_argument("--amplitude", type=number("--amplitude", "deg", 0, 90, lo_open=True, hi_open=True), default=None,
                        help="command amplitude, deg, below the stroke end (44.43 deg on a 50 mm crank); default 30")
    parser.add_argument("--freq", type=number("--freq", "Hz", 1e-3, 1000), default=None, help="command frequency, Hz (default 3)")
    parser.add_argument("--supply-bar", type=number("--supply-bar", "bar", 1, 10_000), default=None, help="supply pressure, bar (default 220)")
    parser.add_argument("--safety-factor", type=number("--safety-factor", "", 1, 100), default=None, help="factor of safety on the force (default 1.5)")
    parser.add_argument("--area", type=number("--area", "m^2", 1e-6, 10), default=None,
                        help="net piston area used for pressure and flow, m^2 (default the rig's 7.658e-4)")
    parser.add_argument("--nas-counts", default=None, metavar="N1,N2,N3,N4,N5",
                        help="particles per 100 ml in the bands 5-15,15-25,25-50,50-100,>100 um -> NAS 1638 class")
    parser.add_argument("--nas-class", default=None, help="NAS 1638 class (00, 0, 1..12) -> allowed counts")


# --- table model ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Column:
    """One output column: CSV/JSON key, text header and decimals (None: as a plain number)."""

    key: str
    label: str
    decimals: int | None = None
    left: bool = False  # left-align in text (words rather than numbers)


@dataclass(frozen=True)
class Table:
    """Rows of raw values keyed by column, plus the text-only extras."""

    name: str
    title: str
    columns: tuple[Column, ...]
    rows: list[dict]
    notes: tuple[str, ...] = ()


def _format(value, decimals: int | None) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return value
    if decimals is None:
        # whole numbers in full (NAS counts reach 1 000 000), others as short as exact
        return str(int(value)) if float(value).is_integer() else f"{value:g}"
    return f"{value:.{decimals}f}"


def _json_value(value, decimals: int | None):
    if value is None or isinstance(value, str):
        return value
    if decimals is None:
        return int(value) if float(value).is_integer() else value
    return round(float(value), decimals)


def render(table: Table, fmt: str) -> str:
    """Render ``table`` as aligned text, CSV (header + rows) or a JSON list of records."""
    if fmt == "json":
        records = [{c.key: _json_value(row.get(c.key), c.decimals) for c in table.columns} for row in table.rows]
        return json.dumps(records, indent=1)
    cells = [[_format(row.get(c.key), c.decimals) for c in table.columns] for row in table.rows]
    if fmt == "csv":
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow([c.key for c in table.columns])
        writer.writerows(cells)
        return out.getvalue().rstrip("\n")
    return _text(table, cells)


def _text(table: Table, cells: list[list[str]]) -> str:
    headers = [c.label for c in table.columns]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h) for i, h in enumerate(headers)]
    lines = [table.title, "=" * len(table.title)]
    def line(values):
        return "  ".join(v.ljust(w) if c.left else v.rjust(w)
                         for v, w, c in zip(values, widths, table.columns)).rstrip()

    lines += [line(headers), "  ".join("-" * w for w in widths)]
    lines += [line(row) for row in cells]
    lines += [f"  {note}" for note in table.notes]
    return "\n".join(lines)


# --- the tables ------------------------------------------------------------------------------

LOAD_COLUMNS = (
    Column("amplitude_deg", "amp (deg)"), Column("disc_sets", "sets"), Column("discs", "discs"),
    Column("inertia_kgm2", "I (kg m^2)", 2), Column("freq_hz", "f (Hz)"),
    Column("max_force_kN", "F_max (kN)", 2), Column("max_delta_p_bar", "dP_max (bar)", 2),
)
FLOW_COLUMNS = (
    Column("amplitude_deg", "amp (deg)"), Column("freq_hz", "f (Hz)"),
    Column("max_angular_velocity_rad_s", "w_max (rad/s)", 2), Column("max_linear_velocity_m_s", "V_max (m/s)", 2),
    Column("max_flow_lpm", "Q_max (LPM)", 2),
)
NOTE_COLUMN = Column("note", "book differs", left=True)


def _book_differences(row: dict, book_row, columns) -> str:
    """Cells where the recomputed value, at the book's rounding, differs from the book."""
    diffs = [f"{c.key}: book {getattr(book_row, c.key):.{c.decimals}f}"
             for c in columns if c.decimals is not None
             and _format(row[c.key], c.decimals) != f"{getattr(book_row, c.key):.{c.decimals}f}"]
    return "; ".join(diffs)


def _with_book_notes(rows: list[dict], book_rows, columns, text: bool) -> tuple[tuple[Column, ...], list[dict]]:
    if not text:
        return columns, rows
    for row, book_row in zip(rows, book_rows):
        row["note"] = _book_differences(row, book_row, columns)
    return columns + (NOTE_COLUMN,), rows


def loads_table(sizing, book_tables, radius: float, area: float, text: bool) -> Table:
    """Tables 1.1-1.3 recomputed; text adds a column flagging cells the book prints differently."""
    rows = [{
        "amplitude_deg": p.amplitude / sizing.DEG, "disc_sets": p.disc_sets, "discs": 2 * p.disc_sets,
        "inertia_kgm2": p.inertia, "freq_hz": p.freq,
        "max_force_kN": p.force / 1e3, "max_delta_p_bar": p.delta_p / sizing.BAR,
    } for p in sizing.load_table(radius, area)]
    columns, rows = _with_book_notes(rows, book_tables.analytic_loads(), LOAD_COLUMNS, text)
    return Table("loads", f"Tables 1.1-1.3: peak actuator load (r = {radius:g} m, fixed A = {area:.4e} m^2)",
                 columns, rows,
                 ("I = sets x 2.68/7 kg m^2 (the book's 0.383 per set does not reproduce these tables).",))


def flows_table(sizing, book_tables, radius: float, area: float, text: bool) -> Table:
    """Tables 1.4-1.6 recomputed (independent of the load)."""
    rows = [{
        "amplitude_deg": p.amplitude / sizing.DEG, "freq_hz": p.freq,
        "max_angular_velocity_rad_s": p.omega_max, "max_linear_velocity_m_s": p.speed,
        "max_flow_lpm": p.flow / sizing.LPM,
    } for p in sizing.flow_table(radius, area)]
    columns, rows = _with_book_notes(rows, book_tables.analytic_flows(), FLOW_COLUMNS, text)
    return Table("flows", f"Tables 1.4-1.6: peak actuator flow (r = {radius:g} m, A = {area:.4e} m^2)",
                 columns, rows,
                 ("Book erratum: its 22.65 LPM at 30 deg, 3 Hz is A x 0.493 m/s (speed rounded first);"
                  " A x r x w_max = 22.67 LPM.",))


DESIGN_COLUMNS = (Column("quantity", "quantity", left=True), Column("value", "value"),
                  Column("unit", "unit", left=True), Column("book", "book"), Column("note", "note", left=True))


def _design_row(quantity, value, unit, decimals, book=None, note=""):
    # values are pre-formatted so that each row keeps its own precision in every format
    return {"quantity": quantity, "value": _format(value, decimals), "unit": unit,
            "book": "" if book is None else _format(book, decimals), "note": note}


def design_table(sizing, book_tables, design, is_book_design: bool, name: str | None = None) -> Table:
    """Summary of one design; the book's printed numbers beside it for the book's design."""
    s = sizing.size(design)
    b = book_tables.BOOK_DESIGN if is_book_design else None

    def book(attr):
        return getattr(b, attr) if b is not None else None

    bores = s.line_bores
    rows = [
        _design_row("load inertia I", design.inertia, "kg m^2", 3),
        _design_row("amplitude theta_max", design.amplitude / sizing.DEG, "deg", 2,
                    note=f"stroke end {sizing.stroke_end_angle(design.radius, design.half_stroke) / sizing.DEG:.2f} deg"),
        _design_row("frequency f", design.freq, "Hz", 2),
        _design_row("crank radius r", design.radius, "m", 3),
        _design_row("peak crank rate w_max", s.omega_max, "rad/s", 2),
        _design_row("peak crank acceleration a_max", s.alpha_max, "rad/s^2", 2),
        _design_row("peak force F = I a/(r cos theta)", s.force / 1e3, "kN", 2, book("force_kN")),
        _design_row(f"design force F x {design.safety_factor:g}", s.design_force / 1e3, "kN", 2,
                    None if b is None else b.design_force_N / 1e3,
                    "book prints '17265 kN' (N; from the rounded 11.51 kN)" if b else ""),
        _design_row("required area F x FoS / Ps", s.required_area * 1e4, "cm^2", 3, None,
                    f"at Ps = {design.supply_pressure / sizing.BAR:g} bar"
                    + ("; the book's 17265 N / 220 bar = 7.848 cm^2, yet it uses 7.658" if b else "")),
        _design_row("actuator area used A", design.area * 1e4, "cm^2", 3,
                    None if b is None else b.area_m2 * 1e4),
        _design_row("peak pressure difference F/A", s.delta_p / sizing.BAR, "bar", 2, None,
                    _pressure_margin_note(sizing, s, design)),
        _design_row("peak piston speed V = r w_max", s.speed, "m/s", 3, book("speed_m_s"),
                    "book once misprints 0.463" if b else ""),
        _design_row("peak flow Q = A V", s.flow / sizing.LPM, "LPM", 2, book("flow_lpm"),
                    "book multiplies A by V rounded to 0.493 m/s" if b else ""),
        _design_row("pump flow (next 5 LPM)", s.pump_flow / sizing.LPM, "LPM", 2, book("pump_flow_lpm")),
        _design_row("pump flow", s.pump_flow / sizing.GPM, "GPM", 3, book("pump_flow_gpm"),
                    "book uses 3.785 L/gal" if b else ""),
        _design_row("motor sizing pressure", s.motor_pressure / sizing.PSI, "psi", 0, book("motor_pressure_psi"),
                    "supply rounded up to 100 psi"),
        _design_row("pump power GPM psi/1714", s.power / sizing.HORSEPOWER, "HP", 2, book("power_hp")),
        _design_row("motor (standard rating)", s.motor_hp, "HP", None, book("motor_hp"), "NEMA"),
        _design_row("motor (standard rating)", s.motor_kw, "kW", None, book("motor_kw"), "IEC"),
        _design_row("pressure line bore", bores["pressure"] * 1e3, "mm", 2, None,
                    f"v <= {sizing.line_velocity_limit('pressure', design.supply_pressure):g} m/s at the pump flow"),
        _design_row("return line bore", bores["return"] * 1e3, "mm", 2, None,
                    f"v <= {sizing.line_velocity_limit('return'):g} m/s"),
        _design_row("suction line bore", bores["suction"] * 1e3, "mm", 2, None,
                    f"v <= {sizing.line_velocity_limit('suction'):g} m/s"),
    ]
    title = ("Design summary" + (f" of {name}" if name else "")
             + (" (the book's design point: 7 disc sets, +-30 deg, 3 Hz)" if is_book_design else ""))
    return Table("design", title, DESIGN_COLUMNS, rows)


def _pressure_margin_note(sizing, s, design) -> str:
    # the area actually used need not meet the sizing rule (the book's own does not quite)
    needed = s.delta_p * design.safety_factor / sizing.BAR
    supply = design.supply_pressure / sizing.BAR
    verdict = "within" if needed <= supply else "EXCEEDS"
    return f"x {design.safety_factor:g} = {needed:.1f} bar, {verdict} Ps = {supply:g} bar"


RIG_COLUMNS = (
    Column("amplitude_deg", "amp (deg)"), Column("freq_hz", "f (Hz)"), Column("discs", "discs"),
    Column("disc_sets", "sets"), Column("pos_error_percent", "pos err (%)"),
    Column("load_analytic_kN", "F book (kN)", 2), Column("load_computed_kN", "F ours (kN)", 2),
    Column("load_test_kN", "F test (kN)", 2), Column("load_excess_kN", "test-ours (kN)", 2),
    Column("flow_analytic_lpm", "Q book (LPM)", 2), Column("flow_computed_lpm", "Q ours (LPM)", 2),
    Column("flow_test_lpm", "Q test (LPM)", 2), Column("flow_excess_lpm", "test-ours (LPM)", 2),
)


def rig_table(sizing, book_tables, radius: float, area: float) -> Table:
    """Tables 1.9-1.15: the book's rig tests, its analytic values, ours and the measured ones."""
    rows = []
    for test in book_tables.rig_tests():
        if test.discs != 2 * test.disc_sets:
            raise ValueError(f"rig_tests.csv: {test.discs} discs is not 2 x {test.disc_sets} sets")
        amplitude = sizing.check_amplitude(test.amplitude_deg * sizing.DEG, radius)
        force = sizing.peak_actuator_force(sizing.disc_inertia(test.disc_sets), amplitude, test.freq_hz, radius)
        flow = sizing.actuator_flow(sizing.piston_speed(amplitude, test.freq_hz, radius), area)
        rows.append({
            "amplitude_deg": test.amplitude_deg, "freq_hz": test.freq_hz, "discs": test.discs,
            "disc_sets": test.disc_sets, "pos_error_percent": test.pos_error_percent,
            "load_analytic_kN": test.load_analytic_kN, "load_computed_kN": force / 1e3,
            "load_test_kN": test.load_test_kN, "load_excess_kN": test.load_test_kN - force / 1e3,
            "flow_analytic_lpm": test.flow_analytic_lpm, "flow_computed_lpm": flow / sizing.LPM,
            "flow_test_lpm": test.flow_test_lpm, "flow_excess_lpm": test.flow_test_lpm - flow / sizing.LPM,
        })
    mean_excess = sum(r["load_excess_kN"] for r in rows) / len(rows)
    return Table("rig", "Tables 1.9-1.15: rig tests, analytic vs measured", RIG_COLUMNS, rows, (
        "discs = 2 x sets.  'pos err' is the book's, undefined there.",
        f"Measured loads exceed the pure-inertia analysis by {mean_excess:.2f} kN on average:"
        " the analysis has no friction, piston mass or pressure dynamics.",
    ))


def nas_table(sizing, book_tables, counts_text: str | None, nas_class: str | None) -> Table:
    """Table 1.16, or the answer to a ``--nas-counts`` / ``--nas-class`` query."""
    bands = book_tables.NAS_BANDS
    columns = (Column("class", "class"),) + tuple(Column(b, f"{b} um") for b in bands)
    if counts_text is None and nas_class is None:
        rows = [{"class": r.nas_class, **dict(zip(bands, r.counts))} for r in book_tables.nas1638()]
        return Table("nas", "Table 1.16: NAS 1638 classes, particles per 100 ml", columns, rows,
                     ("Rig target: class 8; it must still work at class 10.",))
    rows = []
    if counts_text is not None:
        counts = _parse_counts(counts_text, len(bands))
        rows.append({"class": sizing.nas_class(counts), **dict(zip(bands, counts))})
    if nas_class is not None:
        rows.append({"class": str(nas_class), **dict(zip(bands, sizing.nas_counts(nas_class)))})
    return Table("nas", "NAS 1638 lookup (particles per 100 ml)", columns, rows)


def _parse_counts(text: str, bands: int) -> list[float]:
    try:
        counts = [float(part) for part in text.split(",")]
    except ValueError:
        counts = []
    if len(counts) != bands:
        raise ValueError(f"--nas-counts needs {bands} comma-separated numbers (particles per 100 ml per band), "
                         f"got {text!r}")
    return counts


# --- run ------------------------------------------------------------------------------------


def _design(sizing, args, model=None):
    """The design the arguments ask for; a model file (--model, docs/model-file.md) gives the rig's defaults."""
    sets = args.disc_sets if args.disc_sets is not None else sizing.DESIGN_DISC_SETS
    if model is not None:
        inertia = args.inertia if args.inertia is not None else sets * model.inertia_per_set
        radius, area, supply = model.rig.radius, model.rig.area, model.rig.supply
        half_stroke = model.rig.half_stroke
    else:
        inertia = args.inertia if args.inertia is not None else sizing.disc_inertia(sets)
        radius, area, supply = sizing.CRANK_RADIUS, sizing.ACTUATOR_AREA, sizing.SUPPLY_PRESSURE
        half_stroke = sizing.HALF_STROKE
    sizing.check_positive("--inertia", inertia, "kg m^2")
    amplitude = sizing.DESIGN_AMPLITUDE_DEG if args.amplitude is None else args.amplitude
    return sizing.Design(
        inertia=inertia,
        amplitude=amplitude * sizing.DEG,
        freq=sizing.DESIGN_FREQUENCY_HZ if args.freq is None else args.freq,
        radius=radius if args.radius is None else sizing.check_positive("--radius", args.radius, "m"),
        area=area if args.area is None else args.area,
        supply_pressure=supply if args.supply_bar is None else args.supply_bar * sizing.BAR,
        safety_factor=sizing.SAFETY_FACTOR if args.safety_factor is None else args.safety_factor,
        half_stroke=half_stroke,
    )


def model_loads_table(sizing, model, text: bool) -> Table:
    """Tables 1.1-1.3's grid for a model file's rig (its radius, area, inertia per set and stroke)."""
    r = model.rig
    rows = [{
        "amplitude_deg": p.amplitude / sizing.DEG, "disc_sets": p.disc_sets, "discs": 2 * p.disc_sets,
        "inertia_kgm2": p.inertia, "freq_hz": p.freq,
        "max_force_kN": p.force / 1e3, "max_delta_p_bar": p.delta_p / sizing.BAR,
    } for p in sizing.load_table(r.radius, r.area, model.inertia_per_set, r.half_stroke)]
    return Table("loads", f"Peak actuator load of {model.label} (r = {r.radius:g} m, A = {r.area:.4e} m^2, "
                          f"{model.inertia_per_set:g} kg m^2 per set)", LOAD_COLUMNS, rows,
                 ("Pure inertia: F = I alpha_max / (r cos theta_max), dP = F / A (the book's chapter-1 method).",))


def model_flows_table(sizing, model, text: bool) -> Table:
    r = model.rig
    rows = [{
        "amplitude_deg": p.amplitude / sizing.DEG, "freq_hz": p.freq,
        "max_angular_velocity_rad_s": p.omega_max, "max_linear_velocity_m_s": p.speed,
        "max_flow_lpm": p.flow / sizing.LPM,
    } for p in sizing.flow_table(r.radius, r.area, r.half_stroke)]
    return Table("flows", f"Peak actuator flow of {model.label} (r = {r.radius:g} m, A = {r.area:.4e} m^2; valve "
                          f"rated {r.K * r.i_max:.3g} LPM at {r.rated_drop / sizing.BAR:g} bar)", FLOW_COLUMNS, rows)


def table_arg_is(args, name: str) -> bool:
    return args.table == name


def _chosen_table(args) -> str:
    if args.table is not None:
        return args.table
    if any(getattr(args, name) is not None for name in DESIGN_ARGS):
        return "design"
    if args.nas_counts is not None or args.nas_class is not None:
        return "nas"
    return "all"


def run(args: argparse.Namespace) -> int:
    """Print the requested sizing tables; bad input raises ValueError (exit 2 via the CLI)."""
    from ehas_env.book import tables as book_tables
    from ehas_env.book import sizing

    model = None
    if getattr(args, "model", None):
        from ehas_env.simulation.model_file import load_model

        model = load_model(args.model)
    design = _design(sizing, args, model)  # validates every design argument, even for the grid tables
    radius, area = design.radius, design.area
    text = args.format == "text"
    builders = {
        "loads": lambda: loads_table(sizing, book_tables, radius, area, text),
        "flows": lambda: flows_table(sizing, book_tables, radius, area, text),
        "design": lambda: design_table(sizing, book_tables, design, design == sizing.Design()),
        "rig": lambda: rig_table(sizing, book_tables, radius, area),
        "nas": lambda: nas_table(sizing, book_tables, args.nas_counts, args.nas_class),
    }
    if model is not None and not model.is_book:  # another rig: its own grid, no book columns
        builders["loads"] = lambda: model_loads_table(sizing, model, text)
        builders["flows"] = lambda: model_flows_table(sizing, model, text)
        builders["design"] = lambda: design_table(sizing, book_tables, design, False, model.label)
        if table_arg_is(args, "rig"):
            raise ValueError(f"--table rig: the book's rig tests are for the book's rig, not {model.label}")
        builders.pop("rig")
    table = _chosen_table(args)
    names = list(builders) if table == "all" else [table]
    if args.format == "csv" and len(names) > 1:
        raise ValueError("--format csv prints one table: add --table loads|flows|design|rig|nas")
    tables = [builders[name]() for name in names]
    if args.format == "json" and len(tables) > 1:
        print(json.dumps({t.name: json.loads(render(t, "json")) for t in tables}, indent=1))
    else:
        print("\n\n".join(render(t, args.format) for t in tables))
    return 0
