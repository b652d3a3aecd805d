"""Run data files in every log format: one registry, one module per format.

A run is a data file and its ``RUN.json`` sidecar (docs/measurement-format.md).
The data file may be any format registered here; each module of this package
registers one format with :func:`register` (its suffixes, its ``read`` and
optionally ``write``), and :func:`formats` imports every module of the package,
so **adding a format is adding one file** to this folder.  Both readers of run
files, :func:`ehas_env.measurement.campaign.read_campaign` and
:func:`ehas_env.identification.fit.read_columns`, read through
:func:`read_table`.

A format's ``read(path, keep, group)`` returns a :class:`Table`.  It calls
``keep(names)`` once with every column name of the file, in file order, and
loads only the columns ``keep`` returns (so a logger's text or status channel
that nobody asked for is never converted, and huge unused channels are never
loaded).  ``group`` names the group of a file that has several (a TDMS group, an
HDF5 group); ``None`` means the plain layout.  The values it returns may be any
array-like; :func:`read_table` turns them into 1-D float arrays (NaN: a missing
sample) and refuses, in one line naming the file and the column, what is not a
column of numbers: text, complex numbers, a 2-D array, an infinite value, more
than :data:`~ehas_env.ranges.MAX_SAMPLES` samples.

Reading a file never runs code: no format unpickles, loads a MATLAB object or
an HDF5 filter plug-in, or follows a link to another file; each module says how.

Examples
--------
>>> sorted(f.name for f in formats())
['CSV', 'HDF5', 'MAT', 'Parquet', 'TDMS']
>>> format_for("runs/cl_3sets.MAT").name
'MAT'
>>> format_for("runs/notes.txt")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
ehas_env.measurement.formats.RunFileError: runs/notes.txt: '.txt' is not a run file format; expected one of ...
"""
from __future__ import annotations

import importlib
import numbers
import os
import pkgutil
import stat
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ehas_env.ranges import MAX_SAMPLES

#: the format's columns and their units (the measurement contract, docs/measurement-format.md)
COLUMNS = {
    "t": "s",
    "current_mA": "mA",
    "theta_deg": "deg",
    "theta_ref_deg": "deg",
    "flow_lpm": "LPM",
    "p_a_bar": "bar",
    "p_b_bar": "bar",
    "p_s_bar": "bar",
    "load_kN": "kN",
}
#: fewest samples a run may have
MIN_SAMPLES = 20
#: column order used when writing (readers accept any order)
COLUMN_ORDER = tuple(COLUMNS)

#: how loggers spell the format's units (lower case, spaces dropped) -> the format's unit
UNIT_SPELLINGS = {
    "s": "s", "sec": "s", "second": "s", "seconds": "s",
    "ma": "mA", "milliampere": "mA", "milliamps": "mA",
    "deg": "deg", "degree": "deg", "degrees": "deg", "°": "deg",
    "lpm": "LPM", "l/min": "LPM", "litre/min": "LPM", "liter/min": "LPM", "l/mn": "LPM",
    "bar": "bar",
    "kn": "kN", "kilonewton": "kN",
}


class RunFileError(ValueError):
    """A run data file that cannot be read as a run (the message is one line naming the file)."""


@dataclass
class Table:
    """The columns read from one run data file.

    Attributes
    ----------
    columns : dict of ndarray
        The file's column name -> 1-D float array (NaN: a missing sample), for
        the columns ``keep`` chose, in the order it chose them.
    names : list of str
        Every column name of the file, in file order.
    units : dict
        Column name -> the unit the file states for it (TDMS ``unit_string``,
        an HDF5 ``units`` attribute, ...); columns without one are absent.
    line_offset : int
        Sample k is on line ``k + line_offset`` of a text file (2 for a CSV with
        one header line); 0 for binary files, whose messages name samples.
    """

    columns: dict[str, np.ndarray]
    names: list[str]
    units: dict[str, str] = field(default_factory=dict)
    line_offset: int = 0


Keep = Callable[[list], list]


@dataclass(frozen=True)
class RunFormat:
    """One log format: how to recognise, read and (optionally) write its files.

    Parameters
    ----------
    name : str
        Short name, as users say it (``"TDMS"``).
    suffixes : tuple of str
        File suffixes, lower case with the dot (``(".h5", ".hdf5")``); the first is written.
    read : callable
        ``read(path, keep, group) -> Table`` (see the module docstring).
    layout : str
        The plain layout, for messages: what a file of this format must hold.
    write : callable, optional
        ``write(path, columns, units)``: write ``columns`` (name -> 1-D float
        array) in the plain layout to ``path`` (which does not exist yet; the
        caller renames it into place).
    companions : tuple of str
        Suffixes of files that belong to a data file (a TDMS ``.tdms_index``):
        a campaign folder skips them silently.
    needs : tuple of (module, pip name)
        Libraries the format reads with; a missing one is one line saying what to install.
    """

    name: str
    suffixes: tuple
    read: Callable
    layout: str
    write: Callable | None = None
    companions: tuple = ()
    needs: tuple = ()


_REGISTRY: dict[str, RunFormat] = {}
_LOADED = False


def register(fmt: RunFormat) -> RunFormat:
    """Add a format (called by each module of this package when it is imported)."""
    for s in fmt.suffixes:
        other = _REGISTRY.get(s)
        if other is not None and other.name != fmt.name:
            raise RuntimeError(f"run formats {other.name} and {fmt.name} both claim the suffix {s}")
        _REGISTRY[s] = fmt
    return fmt


def formats() -> list[RunFormat]:
    """Every registered format, in the order of their first suffix (each module of this package imported once)."""
    global _LOADED
    if not _LOADED:
        for mod in pkgutil.iter_modules(__path__):
            if not mod.name.startswith("_"):
                importlib.import_module(f"{__name__}.{mod.name}")
        _LOADED = True
    seen: dict[str, RunFormat] = {}
    for fmt in _REGISTRY.values():
        seen.setdefault(fmt.name, fmt)
    return sorted(seen.values(), key=lambda f: f.suffixes[0])


def data_suffixes() -> list[str]:
    """Every suffix of a run data file (lower case, with the dot)."""
    return [s for f in formats() for s in f.suffixes]


def companion_suffixes() -> list[str]:
    """Suffixes of files that belong to a data file (skipped without a note)."""
    return [s for f in formats() for s in f.companions]


def describe() -> str:
    """``RUN.csv, .h5/.hdf5, .mat, ...``: the data files a run may be, for messages."""
    return ", ".join("/".join(f.suffixes) for f in formats())


def format_for(path) -> RunFormat:
    """The format of a data file, by its suffix (any case), or RunFileError naming the ones allowed."""
    path = Path(path)
    formats()
    fmt = _REGISTRY.get(path.suffix.lower())
    if fmt is None:
        what = f"'{path.suffix}'" if path.suffix else "a name without a suffix"
        raise RunFileError(f"{path}: {what} is not a run file format; expected one of {describe()}")
    return fmt


def by_name(name: str) -> RunFormat:
    """A format by its name or a suffix (``"tdms"``, ``".h5"``, ``"MAT"``), for ``--format`` options."""
    key = str(name).strip().lower()
    for fmt in formats():
        if key == fmt.name.lower() or key in fmt.suffixes or "." + key in fmt.suffixes:
            return fmt
    raise RunFileError(f"format {name!r} is not a run file format; expected one of "
                       f"{', '.join(f.name.lower() for f in formats())}")


def _check_file(path: Path, fmt: RunFormat) -> None:
    """A readable regular file, or the one-line error that says what the path is instead."""
    what = f"a {fmt.name} run file"
    try:
        st = path.stat()
        if stat.S_ISDIR(st.st_mode):
            raise RunFileError(f"{path}: is a folder; expected {what}")
        if not stat.S_ISREG(st.st_mode) and not (fmt.name == "CSV" and stat.S_ISFIFO(st.st_mode)):
            raise RunFileError(f"{path}: not a regular file; expected {what}")
        with open(path, "rb"):
            pass
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: does not exist; expected {what}") from None
    except NotADirectoryError:
        raise FileNotFoundError(f"{path}: does not exist (a part of the path is a file); expected {what}") from None
    except PermissionError:
        raise RunFileError(f"{path}: cannot be read (permission denied); expected {what}") from None
    except OSError as exc:
        raise RunFileError(f"{path}: cannot be read ({exc.strerror or exc}); expected {what}") from None


def read_table(path, keep: Keep, group: str | None = None) -> Table:
    """Read one run data file of any registered format.

    Parameters
    ----------
    path : path
        The data file; its suffix picks the format (:func:`format_for`).
    keep : callable
        ``keep(names) -> names``: given every column name of the file, the ones
        to load (it may raise RunFileError, e.g. for a missing column).
    group : str, optional
        The group of a file with several (TDMS, HDF5); None: the plain layout.

    Returns
    -------
    Table
        The chosen columns as 1-D float arrays, with the file's names and units.

    Raises
    ------
    FileNotFoundError
        No such file.
    RunFileError
        Anything else: not this format, a corrupt file, a layout other than the
        plain one, a column that is not one number per sample; one line naming
        the file and what is allowed.
    """
    path = Path(path)
    fmt = format_for(path)
    _check_file(path, fmt)
    for module, pip_name in fmt.needs:
        try:
            importlib.import_module(module)
        except ImportError:
            raise RunFileError(f"{path}: reading {fmt.name} files needs the Python package {pip_name}: "
                               f"pip install {pip_name}") from None
    try:
        table = fmt.read(path, keep, group)
    except (RunFileError, FileNotFoundError, MemoryError, KeyboardInterrupt):
        raise
    except Exception as exc:  # the library's own error on a corrupt or foreign file: one line, naming it
        msg = " ".join(str(exc).split()) or type(exc).__name__
        raise RunFileError(f"{path}: not a readable {fmt.name} file ({msg[:200]}); expected {fmt.layout}") from None
    where = str(path)
    cols = {}
    for name, values in table.columns.items():
        cols[name] = column_values(values, name, where, COLUMNS.get(name, ""), samples=not table.line_offset)
    table.columns = cols
    return table


#: what numpy's dtype kinds hold, for refusals
KINDS = {"b": "true/false values", "c": "complex numbers", "U": "text", "S": "bytes", "O": "Python objects",
         "M": "dates", "m": "time spans", "V": "records"}


def column_values(values, name: str, where: str, unit: str = "", *, samples: bool = False) -> np.ndarray:
    """One column as a 1-D float array (NaN or None: a missing sample), or RunFileError naming it.

    ``samples``: the values come from a file whose missing samples are NaN
    (not an empty CSV cell), so an infinite value is refused, naming the sample.

    Examples
    --------
    >>> column_values([[0.0], [1.5], [None]], "t", "run.mat", "s")
    array([0. , 1.5, nan])
    >>> column_values(np.ones((3, 2)), "theta_deg", "run.mat", "deg")
    Traceback (most recent call last):
    ...
    ehas_env.measurement.formats.RunFileError: run.mat, column 'theta_deg': expected one number in deg per sample (a 1-D sequence), got an array of shape (3, 2)
    """
    what = f"{where}, column '{name}': expected one number{' in ' + unit if unit else ''} per sample"
    try:
        arr = np.asarray(values)
    except (TypeError, ValueError):  # ragged nested lists
        raise RunFileError(f"{what}, got a ragged {type(values).__name__}") from None
    if arr.ndim == 0 or sum(d > 1 for d in arr.shape) > 1:  # a column vector (n, 1) is one column
        shape = f"the single value {values!r}" if arr.ndim == 0 else f"an array of shape {arr.shape}"
        raise RunFileError(f"{what} (a 1-D sequence), got {shape}")
    if arr.size > MAX_SAMPLES:
        raise RunFileError(f"{where}, column '{name}': {arr.size:,} samples; a run holds at most {MAX_SAMPLES:,} "
                           "samples: split the run")
    arr = arr.ravel()
    if arr.dtype.kind == "O":  # None (a missing sample) among numbers is fine
        k = next((k for k, v in enumerate(arr) if v is not None
                  and (isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real))), None)
        if k is not None:
            text = " text" if isinstance(arr[k], (str, bytes)) else ""
            raise RunFileError(f"{what}, got{text} {arr[k]!r} at sample {k}")
        arr = np.array([np.nan if v is None else float(v) for v in arr])
    if arr.dtype.kind not in "iuf":
        raise RunFileError(f"{what}, got {KINDS.get(arr.dtype.kind, arr.dtype)}")
    arr = np.asarray(arr, dtype=float)
    if samples:
        inf = np.flatnonzero(np.isinf(arr))
        if inf.size:
            raise RunFileError(f"{where}, column '{name}', sample {inf[0]}: {arr[inf[0]]} is not finite; a missing "
                               "sample is NaN")
    return arr


def check_size(path, name: str, shape) -> None:
    """Refuse a column of more than MAX_SAMPLES values before it is loaded."""
    n = int(np.prod(shape)) if len(shape) else 1
    if n > MAX_SAMPLES:
        raise RunFileError(f"{path}, column '{name}': {n:,} values; a run holds at most {MAX_SAMPLES:,} samples: "
                           "split the run")


def unit_of(text) -> str | None:
    """The format's unit for a logger's spelling of it (``"L/min"`` -> ``"LPM"``), None if unknown.

    Examples
    --------
    >>> unit_of("L/min"), unit_of(" Deg "), unit_of("rad")
    ('LPM', 'deg', None)
    """
    key = "".join(str(text).split()).lower()
    return UNIT_SPELLINGS.get(key)


def write_file(path, columns: dict, units: dict | None = None, fmt: RunFormat | None = None) -> Path:
    """Write ``columns`` as a data file of ``fmt`` (default: by ``path``'s suffix), atomically.

    The file is written beside ``path`` under a temporary name and renamed into
    place, so a reader never sees half of it.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    fmt = fmt or format_for(path)
    if fmt.write is None:
        raise RunFileError(f"{path}: ehas reads {fmt.name} files but does not write them")
    names = [c for c in COLUMN_ORDER if c in columns] + [c for c in columns if c not in COLUMN_ORDER]
    cols = {c: np.asarray(columns[c], dtype=float).ravel() for c in names}
    units = {c: COLUMNS[c] for c in names if c in COLUMNS} if units is None else units
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    os.close(fd)
    os.unlink(tmp)  # the libraries create the file themselves
    try:
        fmt.write(Path(tmp), cols, units)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
