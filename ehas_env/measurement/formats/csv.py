"""CSV run files: one header line with the column names, one row per sample.

Read as loggers and spreadsheets write them: a UTF-8 byte-order mark, CRLF or
CR line ends, ``,`` ``;`` or tab separators (decimal commas under ``;`` and
tab); an empty cell or ``nan`` is a missing sample.  Only the columns ``keep``
asks for are parsed, so a text status column that nobody asked for is fine.
Errors name the file's line (the header is line 1).
"""
from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from ehas_env.measurement.formats import COLUMNS, MIN_SAMPLES, RunFileError, RunFormat, Table, register
from ehas_env.ranges import MAX_SAMPLES

#: largest run file read, bytes: MAX_SAMPLES rows of nine columns of about 20 characters
MAX_CSV_BYTES = 200 * MAX_SAMPLES
#: separators a logger may use, in the order they are tried on the header line
SEPARATORS = (",", ";", "\t")
LAYOUT = "a text file with one header line naming the columns (t,current_mA,...) and one row per sample"


def _read_text(path: Path) -> str:
    from ehas_env.output.files import read_text

    try:
        size = path.stat().st_size
    except OSError:
        size = 0  # read_text names what is wrong with the path
    if size > MAX_CSV_BYTES:
        raise RunFileError(f"{path}: {size:,} bytes, more than the {MAX_CSV_BYTES:,} a CSV file of a run may have "
                           f"(at most {MAX_SAMPLES:,} samples): split the run")
    try:
        return read_text(path, "a CSV file", max_bytes=MAX_CSV_BYTES)
    except ValueError as exc:
        raise RunFileError(str(exc)) from None


def _separator(header: str, path: Path) -> str:
    found = [s for s in SEPARATORS if s in header]
    if not found:
        return ","  # one column only: the required-column check names what is missing
    if len(found) > 1:
        names = {",": "','", ";": "';'", "\t": "tab"}
        raise RunFileError(f"{path}, line 1: the header mixes separators ({', '.join(names[s] for s in found)}); "
                           "expected one separator throughout (',' preferred)")
    return found[0]


def _numbers_at_once(body: list, sep: str, width: int, index: list):
    """The ``index`` columns of the rows ``body`` through numpy's number parser, all cells in one call.

    A logger's file is usually nothing but numbers, and this reads it 10-20x faster than cell by cell (a 30 s
    run at 1 kHz: 30 000 rows). None when any row or cell needs the careful reading below: a row with another
    number of cells, an empty, quoted or text cell, a NaN or an infinity -- that reading accepts or names it
    with its line, and its numbers are the same (numpy parses a cell as Python's ``float`` does).
    """
    if any(line.count(sep) != width - 1 for line in body):
        return None
    try:
        data = np.array(sep.join(body).split(sep)).reshape(len(body), width)[:, index].astype(float)
    except ValueError:
        return None
    return data if np.isfinite(data).all() else None


def read(path: Path, keep, group=None) -> Table:
    """The columns ``keep`` chooses of a CSV run file (see the package docstring)."""
    text = _read_text(path)
    lines = text.splitlines()  # \n, \r\n and \r line ends alike
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise RunFileError(f"{path}: empty file; expected a header line (t,current_mA,...) and one row per sample")
    if len(lines) == 1:
        raise RunFileError(f"{path}: a header line and no samples; expected one row per sample after it "
                           f"(at least {MIN_SAMPLES})")
    if len(lines) - 1 > MAX_SAMPLES:
        raise RunFileError(f"{path}: {len(lines) - 1:,} rows; a run holds at most {MAX_SAMPLES:,} samples: "
                           "split the run")
    sep = _separator(lines[0], path)
    decimal_comma = sep != "," and any("," in c for c in lines[1].split(sep))
    raw = [c.strip().strip('"') for c in lines[0].split(sep)]
    wanted = list(keep(list(raw)))
    index = [raw.index(c) for c in wanted]
    width = len(raw)
    data = _numbers_at_once(lines[1:], sep, width, index) if not decimal_comma else None
    if data is not None:
        return Table(columns={name: data[:, jj] for jj, name in enumerate(wanted)}, names=raw, line_offset=2)
    data = np.empty((len(lines) - 1, len(index)))
    for k, line in enumerate(lines[1:]):
        cells = line.split(sep)
        if len(cells) != width:
            raise RunFileError(f"{path}, line {k + 2}: {len(cells)} cells, expected {width} (one per column of the "
                               "header)")
        for jj, j in enumerate(index):
            c = cells[j].strip().strip('"')
            if decimal_comma:
                c = c.replace(",", ".")
            if not c or c.lower() == "nan":
                data[k, jj] = np.nan
                continue
            try:
                v = float(c)
            except ValueError:
                unit = COLUMNS.get(raw[j])
                raise RunFileError(f"{path}, line {k + 2}, column '{raw[j]}': {c!r} is not a number "
                                   f"(expected {unit or 'a number'}, or an empty cell for a missing sample)") from None
            if not math.isfinite(v):
                raise RunFileError(f"{path}, line {k + 2}, column '{raw[j]}': {c!r} is not finite "
                                   "(leave the cell empty for a missing sample)")
            data[k, jj] = v
    return Table(columns={name: data[:, jj] for jj, name in enumerate(wanted)}, names=raw, line_offset=2)


def write(path: Path, columns: dict, units: dict) -> None:
    """``columns`` as CSV: a header line, one row per sample, NaN as an empty cell (10 significant digits)."""
    names = list(columns)
    data = np.column_stack([columns[c] for c in names])
    buf = io.StringIO()
    buf.write(",".join(names) + "\n")
    for row in data:
        buf.write(",".join("" if not np.isfinite(v) else f"{v:.10g}" for v in row) + "\n")
    path.write_text(buf.getvalue(), encoding="utf-8")


FORMAT = register(RunFormat(name="CSV", suffixes=(".csv",), read=read, write=write, layout=LAYOUT))
