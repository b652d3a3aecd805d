"""Measurement campaigns: reading, validating and writing folders of runs.

A campaign is a folder of runs, each a data file with one column per signal and
one row per uniformly spaced sample (``RUN.csv``, or a MATLAB ``.mat``, NI
``.tdms``, HDF5 ``.h5`` or ``.parquet`` file: any format of
:mod:`ehas_env.measurement.formats`, mixed freely) with a ``RUN.json`` sidecar
saying what the run was; the format is the project's measurement contract
(``docs/measurement-format.md``, README "Measurement files").  :func:`read_campaign` refuses anything that is
not that format with a message naming the file, the line or key, and what is
expected; short gaps (at most :data:`MAX_GAP` missing samples in a row) are
filled by linear interpolation and counted.

Logs as they come: a UTF-8 byte-order mark, CRLF line ends and ``;`` or tab
separators (with decimal commas under ``;``) are read; columns the format does
not know (a logger's ``oil_temp_C``) are ignored and listed in
:attr:`Campaign.warnings`; ``columns={"theta_deg": "Angle1"}`` (the command
line's ``--columns theta_deg=Angle1``) maps a logger's names onto the format's
(and ``group=NAME`` picks the group of a TDMS or HDF5 file that has several);
units a file states (TDMS ``unit_string``, HDF5 ``units``) must be the format's;
values whose size betrays another unit (theta in rad, pressures in Pa or psi,
current in A or uA, time in ms, load in N) are refused with the likely cause, and
so are values no rig produces (a crank beyond its stroke ends, a flow far beyond
what the valve passes, sampling faster than 1 MHz).  Files
of the folder that are not runs are skipped and each is reported with the
reason.  :func:`write_campaign` validates
every run first and writes the folder all at once, so a failure never leaves a
half-written campaign behind.

Examples
--------
>>> import tempfile, numpy as np
>>> t = np.arange(200) * 1e-3
>>> cols = {"t": t, "current_mA": np.sin(40 * t), "flow_lpm": 1.27 * np.sin(40 * t)}
>>> cols["flow_lpm"][50:53] = np.nan          # three lost samples
>>> meta = {"kind": "valve_open_loop", "supply_bar": 70}
>>> work = tempfile.TemporaryDirectory()
>>> folder = Path(work.name) / "camp"
>>> _ = write_campaign(folder, [("valve", cols, meta)])
>>> camp = read_campaign(folder)
>>> [r.name for r in camp.runs], camp.runs[0].interpolated
(['valve'], {'flow_lpm': 3})
>>> work.cleanup()
"""
from __future__ import annotations

import errno
import json
import math
import os
import shutil
import stat
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ehas_env.ranges import FIELDS
from ehas_env.output.files import atomic_write_text
from ehas_env.output.outputs import RECORD as OUTPUT_RECORD
from ehas_env.physics.rig import (AREA, BAR, CRANK_RADIUS, LPM, MAX_SETS, MIN_SETS, RATED_CURRENT, RATED_VALVE_DROP,
                                  THETA_STROKE_END, VALVE_K)
from ehas_env.measurement import formats
from ehas_env.measurement.formats import COLUMNS, MIN_SAMPLES, RunFileError
from ehas_env.measurement.runfile import write_run as _write_run_files

#: quantity (column name without its unit) -> column name, to name a wrong unit
_QUANTITY = {name.rsplit("_", 1)[0] if "_" in name else name: name for name in COLUMNS}
_QUANTITY["theta_ref"] = "theta_ref_deg"

KINDS = ("closed_loop", "valve_open_loop")
REQUIRED = {
    "closed_loop": ("t", "current_mA", "theta_deg", "theta_ref_deg"),
    "valve_open_loop": ("t", "current_mA", "flow_lpm"),
}
#: the columns a valve run can carry (its other columns are the closed loop's: a mapping of them is not its)
VALVE_RUN_COLUMNS = ("t", "current_mA", "flow_lpm", "p_s_bar")
#: longest run of missing samples that is interpolated; longer gaps are refused
MAX_GAP = 5
#: relative tolerance on the sample spacing (loggers write times rounded)
DT_TOLERANCE = 0.01
MIN_RATE_HZ = 100.0  # the replay's integrator needs at least 100 Hz sampling
#: fastest sampling: the plant's shortest period (``FIELDS["dt"]``, 1 us) and the fastest controller rate
MAX_RATE_HZ = FIELDS["rate_hz"].hi
CONTROLLER_REQUIRED = ("Kp", "Ki", "Kv", "Ka", "rate_hz")
CONTROLLER_OPTIONAL = ("Kj", "Kdp", "dp_hp")
#: the logged reference may differ from the sidecar's by this fraction of the amplitude
REF_TOLERANCE = 0.01


#: the --columns key that names the group of a TDMS or HDF5 file to read (not a column)
GROUP = "group"


class CampaignError(RunFileError):
    """A campaign, run file or sidecar that is not the measurement format (a ValueError)."""


@dataclass
class Run:
    """One validated run.

    Attributes
    ----------
    name : str
        File stem (``RUN`` of ``RUN.csv`` or ``RUN.mat``).
    path : Path
        The data file it came from (None for runs built in memory).
    meta : dict
        The validated sidecar: ``kind``, ``supply_bar`` and, for closed-loop
        runs, ``disc_sets``, ``reference`` (amplitude_deg, freq_hz, phase_rad,
        ramp_cycles) and ``controller`` (Kp, Ki, Kv, Ka, Kj, Kdp, dp_hp, rate_hz).
    t : ndarray
        Sample times, s, uniform (t0 + k dt).
    dt : float
        Sample period, s.
    columns : dict of ndarray
        Every logged column but ``t``, gaps filled (engineering units).
    interpolated : dict
        Column -> number of missing samples that were interpolated.
    ignored_columns : list of str
        Columns of the file that the format does not know (ignored).
    column_map : dict
        Format name -> the file's name, for the columns renamed by ``--columns``.
    """

    name: str
    path: Path | None
    meta: dict
    t: np.ndarray
    dt: float
    columns: dict[str, np.ndarray]
    interpolated: dict[str, int] = field(default_factory=dict)
    ignored_columns: list[str] = field(default_factory=list)
    column_map: dict[str, str] = field(default_factory=dict)

    @property
    def kind(self) -> str:
        return self.meta["kind"]

    @property
    def csv_path(self) -> Path | None:
        """The data file (the name from when runs were CSV only; any format now): :attr:`path`."""
        return self.path

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def duration(self) -> float:
        return self.n * self.dt

    def label(self) -> str:
        """Short description: ``3 sets, 20 deg, 1 Hz`` or ``valve, 70 bar``."""
        m = self.meta
        if self.kind == "closed_loop":
            ref = m["reference"]
            sets = "1 set" if m["disc_sets"] == 1 else f"{m['disc_sets']} sets"
            off = f" about {ref['offset_deg']:+g} deg" if ref.get("offset_deg") else ""
            return f"{sets}, {ref['amplitude_deg']:g} deg{off}, {ref['freq_hz']:g} Hz"
        return f"valve, {m['supply_bar']:g} bar"


@dataclass
class Campaign:
    """A folder of validated runs (sorted by name).

    ``ignored`` lists the folder's files that are not runs (file names);
    ``warnings`` says, one line each, what was skipped or ignored and why
    (files, unknown columns).
    """

    path: Path | None
    runs: list[Run]
    ignored: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def interpolated_total(self) -> int:
        return sum(sum(r.interpolated.values()) for r in self.runs)

    def summary(self) -> str:
        """One line per run plus the interpolation count and what was skipped, for reports."""
        lines = [f"{len(self.runs)} runs in {self.path}:"]
        for r in self.runs:
            gaps = sum(r.interpolated.values())
            extra = f", {gaps} missing samples interpolated" if gaps else ""
            if r.ignored_columns:
                extra += f", ignored columns: {', '.join(r.ignored_columns)}"
            lines.append(f"  {r.name}: {r.kind} ({r.label()}), {r.n} samples at {1 / r.dt:g} Hz{extra}")
        lines.append(f"  {self.interpolated_total} missing samples interpolated in all")
        for w in self.warnings:
            lines.append(f"  note: {w}")
        return "\n".join(lines)


# --- reading ---------------------------------------------------------------------------------


def parse_column_map(text: str | None) -> dict[str, str]:
    """``"theta_deg=Angle1,current_mA=I_cmd"`` -> ``{"theta_deg": "Angle1", ...}`` (format name = logger name).

    ``group=NAME`` is not a column: it names the group of a TDMS or HDF5 file
    whose channels are the columns (files with several groups need it).

    Examples
    --------
    >>> parse_column_map("theta_deg=Angle 1, current_mA=I_cmd")
    {'theta_deg': 'Angle 1', 'current_mA': 'I_cmd'}
    >>> parse_column_map("angle=theta_deg")
    Traceback (most recent call last):
    ...
    ValueError: --columns: 'angle' is not a column of the measurement format; NEW must be one of t, current_mA, theta_deg, theta_ref_deg, flow_lpm, p_a_bar, p_b_bar, p_s_bar, load_kN (or group, the group of a TDMS/HDF5 file)
    """
    from ehas_env.ranges import split_list

    out: dict[str, str] = {}
    for item in split_list(text, "--columns", "NEW=OLD column names") if text else []:
        new, eq, old = item.partition("=")
        new, old = new.strip(), old.strip()
        if not eq or not new or not old:
            raise ValueError(f"--columns: {item.strip()!r} is not NEW=OLD (the format's column name = the "
                             "logger's column name), e.g. --columns theta_deg=Angle1,current_mA=I_cmd")
        if new not in COLUMNS and new != GROUP:
            raise ValueError(f"--columns: {new!r} is not a column of the measurement format; NEW must be one of "
                             f"{', '.join(COLUMNS)} (or {GROUP}, the group of a TDMS/HDF5 file)")
        if new in out:
            raise ValueError(f"--columns: {new!r} is mapped twice")
        out[new] = old
    olds = [old for new, old in out.items() if new != GROUP]
    dup = next((o for o in olds if olds.count(o) > 1), None)
    if dup is not None:
        raise ValueError(f"--columns: the logger's column {dup!r} is mapped to two format columns")
    return out


def check_column_map(columns) -> dict[str, str]:
    """``read_campaign``'s ``columns``: a dict format name -> the logger's column name (what
    :func:`parse_column_map` returns), checked as that function checks ``--columns``."""
    if columns is None:
        return {}
    if not isinstance(columns, dict):
        hint = f" (parse_column_map({columns!r}) makes one)" if isinstance(columns, str) else ""
        raise CampaignError(f"columns must be a dict {{format column: logger column}}, got "
                            f"{type(columns).__name__}{hint}")
    for new, old in columns.items():
        if new not in COLUMNS and new != GROUP:
            raise CampaignError(f"columns: {new!r} is not a column of the measurement format; the keys must be "
                                f"among {', '.join(COLUMNS)} (or {GROUP!r}, the group of a TDMS/HDF5 file)")
        if not isinstance(old, str) or not old.strip():
            what = "the group's name" if new == GROUP else "the logger's column name"
            raise CampaignError(f"columns: {new!r} maps to {old!r}; expected {what} (text)")
    olds = [old for new, old in columns.items() if new != GROUP]
    dup = next((o for o in olds if olds.count(o) > 1), None)
    if dup is not None:
        raise CampaignError(f"columns: the logger's column {dup!r} is mapped to two format columns")
    return columns


def _entry_problem(p: Path) -> str | None:
    """Why a folder entry named like a run file cannot be one (None when it is a readable regular file)."""
    try:
        st = os.stat(p)
    except OSError as exc:
        if p.is_symlink():
            if exc.errno == errno.ELOOP:
                return f"symbolic link that loops ({os.readlink(p)})"
            return f"dangling symbolic link to {os.readlink(p)} (its target does not exist)"
        return f"cannot be opened ({exc.strerror})"
    if stat.S_ISDIR(st.st_mode):
        return "a folder, not a file"
    if not stat.S_ISREG(st.st_mode):
        return "not a regular file"
    return None


def read_campaign(path, columns: dict[str, str] | None = None) -> Campaign:
    """Read and validate every run of a campaign folder: data files with a ``RUN.json`` sidecar beside them.

    A run's data file may be any registered format (:mod:`ehas_env.measurement.formats`:
    CSV, MATLAB ``.mat`` v5 and v7.3, NI ``.tdms``, HDF5 ``.h5``/``.hdf5``,
    ``.parquet``), and one campaign may mix them.  Entries of the folder that
    are not runs (an orphan ``RUN.json``, a dangling or looping symbolic link, a
    folder named ``RUN.csv``, other files) are skipped; :attr:`Campaign.warnings`
    says which and why.

    Parameters
    ----------
    path : str or Path
        The campaign folder.
    columns : dict, optional
        Format column name -> the logger's column name (what
        :func:`parse_column_map` makes of ``--columns``), applied to every run,
        whatever its format; the key ``"group"`` names the group of a TDMS or
        HDF5 file that has several.  Every mapping must rename a column of at
        least one run.

    Returns
    -------
    Campaign
        The validated runs, sorted by name (columns in the format's names and
        units, short gaps filled), what was skipped and the warnings.

    Raises
    ------
    FileNotFoundError
        The folder does not exist.
    CampaignError
        The path is a file, no runs, two data files for one run, an unreadable
        run, or any run that is not the measurement format (the message names
        the file, line or sample, column or key, and what is expected).

    Examples
    --------
    >>> import tempfile
    >>> from ehas_env.measurement.synthetic import simulate_campaign
    >>> runs, _ = simulate_campaign(seed=1, duration=0.2, plan=((3, 20.0, 1.0),))
    >>> work = tempfile.TemporaryDirectory()
    >>> folder = Path(work.name) / "camp"
    >>> _ = write_campaign(folder, runs[:1], fmt="tdms")
    >>> _ = write_campaign(folder, runs[1:], fmt="mat", overwrite=True, keep=True)
    >>> sorted(p.name for p in folder.iterdir())
    ['cl_3sets_20deg_1hz.json', 'cl_3sets_20deg_1hz.tdms', 'valve_chirp.json', 'valve_chirp.mat']
    >>> [(r.name, r.path.suffix, r.n) for r in read_campaign(folder).runs]
    [('cl_3sets_20deg_1hz', '.tdms', 200), ('valve_chirp', '.mat', 200)]
    >>> work.cleanup()
    """
    if not isinstance(path, (str, os.PathLike)):
        raise CampaignError(f"the campaign must be a folder's path (a str or Path), got {type(path).__name__}")
    columns = check_column_map(columns)
    folder = Path(path)
    suffixes = formats.data_suffixes()
    layout = f"a folder of runs, each a data file ({formats.describe()}) with a RUN.json sidecar"
    if folder.exists() and not folder.is_dir():
        hint = (f" (it is a run file: give its folder, {folder.parent})"
                if folder.suffix.lower() in (*suffixes, ".json") else "")
        raise CampaignError(f"{folder} is a file, not a folder; a campaign is {layout}{hint}")
    if not folder.is_dir():
        raise FileNotFoundError(f"campaign folder {folder} does not exist (expected {layout})")
    try:
        entries = sorted(folder.iterdir())
    except PermissionError:
        raise CampaignError(f"{folder}: the folder cannot be listed (permission denied)") from None
    warnings: list[str] = []
    ignored: list[str] = []
    data: dict[str, Path] = {}
    for p in entries:
        if p.suffix.lower() in suffixes:
            why = _entry_problem(p)
            if why is None:
                if p.stem in data:
                    raise CampaignError(f"{folder}: run '{p.stem}' has two data files, {data[p.stem].name} and "
                                        f"{p.name}; keep one data file per RUN.json")
                data[p.stem] = p
                continue
            warnings.append(f"skipped {p.name}: {why}")
            ignored.append(p.name)
    companions = formats.companion_suffixes()
    for p in entries:
        suffix = p.suffix.lower()
        if (suffix in suffixes and data.get(p.stem) == p) or (suffix == ".json" and p.stem in data):
            continue
        if suffix in companions and p.stem in data:
            continue  # a TDMS index beside its file
        if p.name == OUTPUT_RECORD:
            continue  # the record ehas keeps of the files it wrote into the folder (simulate-campaign)
        ignored.append(p.name)
        if suffix == ".json":
            warnings.append(f"skipped {p.name}: no {p.stem}.csv beside it, nor a {p.stem} data file of another format "
                            f"({formats.describe()}): a sidecar without its run, or not a run file")
        else:
            why = _entry_problem(p) if p.is_symlink() else None
            warnings.append(f"skipped {p.name}: {why or ('a folder' if p.is_dir() else f'not a run file ({formats.describe()} + .json)')}")
    if not data:
        skipped = f" ({'; '.join(warnings)})" if warnings else ""
        raise CampaignError(f"{folder}: no runs found; a campaign is {layout}{skipped}")
    runs = [read_run(p, columns=columns) for p in sorted(data.values())]
    for r in runs:
        if r.ignored_columns:
            warnings.append(f"{r.path.name}: ignored columns the format does not know: {', '.join(r.ignored_columns)}")
    unused = [f"{new}={old}" for new, old in (columns or {}).items()
              if new != GROUP and not any(r.column_map.get(new) == old for r in runs)]
    for r in runs:  # a mapping some files use and this one lacks: said, not silently read without that column
        lacks = [f"{new}={old}" for new, old in (columns or {}).items()
                 if new != GROUP and f"{new}={old}" not in unused and r.column_map.get(new) != old
                 and (r.kind == "closed_loop" or new in VALVE_RUN_COLUMNS)]
        if lacks:
            warnings.append(f"{r.path.name}: --columns {', '.join(lacks)}: this file has no such column (read "
                            "without it)")
    if unused:
        # a mapping that renames nothing is a typo: reading on would drop a column the user meant to give
        first = runs[0]  # its logger's column names: those read (under their file names) and those ignored
        names = [first.column_map.get(c, c) for c in ["t", *first.columns]] + first.ignored_columns
        raise CampaignError(f"--columns {', '.join(unused)}: no run in {folder} has such a column (the first "
                            f"run's columns: {', '.join(names)})")
    return Campaign(path=folder, runs=runs, ignored=sorted(ignored), warnings=warnings)


def read_run(path, columns: dict[str, str] | None = None) -> Run:
    """Read and validate one run: its data file (any format of :mod:`ehas_env.measurement.formats`) and the
    ``RUN.json`` sidecar beside it; ``columns`` as for :func:`read_campaign`."""
    path = Path(path)
    columns = check_column_map(columns)
    try:
        formats.format_for(path)
    except RunFileError as exc:
        raise CampaignError(str(exc)) from None
    json_path = path.with_suffix(".json")
    if not json_path.is_file():
        raise CampaignError(f"{path}: sidecar {json_path.name} is missing; every run's data file needs a RUN.json "
                            "saying what the run was (kind, supply_bar, disc_sets, reference, controller)")
    meta = read_sidecar(json_path)
    cols, ignored, used, line_offset = read_data(path, columns)
    run = validate_run(path.stem, cols, meta, where=str(path), line_offset=line_offset, path=path,
                       file_columns=[used.get(c, c) for c in cols] + ignored)
    run.ignored_columns = ignored
    run.column_map = used
    return run


def read_data(path, columns: dict[str, str] | None = None) -> tuple[dict, list[str], dict, int]:
    """The format's columns of one run data file, renamed by ``columns`` and with the units it states checked.

    Returns
    -------
    columns : dict of ndarray
        Format column name -> 1-D float array (NaN: a missing sample).
    ignored : list of str
        The file's columns the format does not know.
    used : dict
        The entries of ``columns`` that renamed a column of this file.
    line_offset : int
        Sample k is on line k + line_offset of a text file (0: name samples).
    """
    path = Path(path)
    rename = {new: old for new, old in (columns or {}).items() if new != GROUP}
    back = {old: new for new, old in rename.items()}
    found: dict = {}

    def keep(raw):
        raw = [str(c) for c in raw]
        names = [back.get(c, c) for c in raw]
        idx, ignored = known_columns(names, str(path), renamed={back[c] for c in raw if c in back})
        found["ignored"] = [c or f"(unnamed column {names.index(c) + 1})" for c in ignored]
        found["used"] = {new: old for new, old in rename.items() if old in raw}
        return [raw[j] for j in idx]

    try:
        table = formats.read_table(path, keep, group=(columns or {}).get(GROUP))
    except CampaignError:
        raise
    except RunFileError as exc:
        raise CampaignError(str(exc)) from None
    cols = {}
    for raw, values in table.columns.items():
        name = back.get(raw, raw)
        stated = table.units.get(raw)
        if stated is not None and formats.unit_of(stated) != COLUMNS[name]:
            raise CampaignError(f"{path}, column '{raw}': the file gives its unit as {stated!r}; expected "
                                f"{COLUMNS[name]} (the format's unit for '{name}'): convert the values, or fix the "
                                "unit the logger writes")
        cols[name] = values
    return cols, found.get("ignored", []), found.get("used", {}), table.line_offset


def _read_text(path: Path, what: str) -> str:
    """The text of a sidecar through the shared checked reader (ehas_env.output.files), as a CampaignError."""
    from ehas_env.output.files import read_text

    try:
        return read_text(path, f"a {what}")
    except (ValueError, FileNotFoundError) as exc:
        raise CampaignError(str(exc)) from None


def read_sidecar(json_path) -> dict:
    """Parse a RUN.json sidecar (validation happens in :func:`validate_meta`)."""
    json_path = Path(json_path)
    text = _read_text(json_path, "JSON object")
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CampaignError(f"{json_path}: not valid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    return meta


def known_columns(names, where: str, renamed=()) -> tuple[list[int], list[str]]:
    """Indices of the format's columns in a header, and the names of the others (ignored).

    Duplicates are refused, and so is a format quantity in an unknown unit
    (``p_a_psi``, ``theta_rad``) or a time column not called ``t`` when the
    format's own column is absent: that is a column the run needs, logged in a
    unit the format does not take.
    """
    seen = set()
    for name in names:
        if name in seen:
            how = " (after --columns)" if name in renamed else ""
            raise CampaignError(f"{where}: column '{name}' appears twice in the header{how}")
        seen.add(name)
    keep, ignored = [], []
    for j, name in enumerate(names):
        if name in COLUMNS:
            keep.append(j)
            continue
        base, _, unit = name.rpartition("_")
        if base in _QUANTITY and _QUANTITY[base] not in seen:
            good = _QUANTITY[base]
            raise CampaignError(f"{where}: column '{name}' has unit '{unit}', which the format does not know; "
                                f"expected '{good}' ({COLUMNS[good]}): convert the values, then name the column '{good}'")
        if name.lower() in ("t_s", "time", "time_s", "t_ms", "time_ms") and "t" not in seen:
            raise CampaignError(f"{where}: column '{name}': time must be the column 't' in seconds "
                                f"(--columns t={name} maps it, if it holds seconds)")
        ignored.append(name)
    return keep, ignored


def check_column_names(names, where: str) -> None:
    """Refuse unknown columns, unknown units and duplicates, naming the column (runs built in memory)."""
    _, ignored = known_columns(list(names), where)
    if ignored:
        known = ", ".join(f"{c} ({u})" for c, u in COLUMNS.items())
        raise CampaignError(f"{where}: unknown column '{ignored[0]}'; the format's columns are: {known}")


def check_units(cols: dict, meta: dict, dt: float | None, where: str) -> None:
    """Refuse values whose size betrays a unit other than the format's, naming the column and the likely unit.

    ``cols`` are the run's columns (format names, engineering units), ``meta``
    its validated sidecar, ``dt`` the median sample step of ``t``.
    """
    def peak(c):
        v = cols.get(c)
        if v is None:
            return None
        v = np.asarray(v, dtype=float)
        v = v[np.isfinite(v)]
        return float(np.max(np.abs(v))) if v.size else None

    def refuse(col, msg):
        raise CampaignError(f"{where}, column '{col}': {msg}")

    if dt is not None and 1.0 / dt < MIN_RATE_HZ and 1.0e3 / dt >= MIN_RATE_HZ and dt >= 0.1:
        refuse("t", f"samples {dt:.6g} apart, which would be {1 / dt:g} Hz in seconds; t looks logged in ms, not s "
                    "(divide by 1000)")
    supply = float(meta.get("supply_bar", 220.0))
    i = peak("current_mA")
    if i is not None and i > 50.0 * RATED_CURRENT:
        why = "the values look like uA, not mA (divide by 1000)" if i < 2e3 * RATED_CURRENT else "expected mA"
        refuse("current_mA", f"peak {i:.4g} mA, far beyond the servo amplifier's +-{RATED_CURRENT:g} mA; {why}")
    q = peak("flow_lpm")
    q_max = VALVE_K * RATED_CURRENT * math.sqrt(supply * BAR / RATED_VALVE_DROP)  # wide open, the whole supply across
    if q is not None and q > 10.0 * q_max:
        refuse("flow_lpm", f"peak {q:.4g} LPM, where the valve passes at most about {q_max:.3g} LPM at {supply:g} bar; "
                           "expected LPM")
    for c in ("p_a_bar", "p_b_bar", "p_s_bar"):
        p = peak(c)
        if p is None:
            continue
        if p > 2.0e4:
            refuse(c, f"peak {p:.4g} bar, against a {supply:g} bar supply; the values look like Pa, not bar "
                      "(divide by 1e5)")
        if p > 1.5 * max(supply, 100.0) and 5.0 * supply < p < 25.0 * max(supply, 100.0):
            refuse(c, f"peak {p:.4g} bar, against a {supply:g} bar supply; the values look like psi, not bar "
                      "(divide by 14.504)")
        if p > 1.5 * max(supply, 100.0):
            refuse(c, f"peak {p:.4g} bar, above 1.5 x the {supply:g} bar supply; expected bar")
    if meta.get("kind") == "closed_loop":
        amp = meta["reference"]["amplitude_deg"]
        f = meta["reference"]["freq_hz"]
        reach = amp + abs(meta["reference"].get("offset_deg", 0.0))  # the largest |angle| the sine asks
        for c in ("theta_deg", "theta_ref_deg"):
            th = peak(c)
            if th is not None and amp >= 2.0 and 0.4 < math.degrees(th) / reach < 2.5:
                refuse(c, f"peak {th:.4g}, where the sidecar's sine reaches {reach:g} deg; {th:.4g} rad = "
                          f"{math.degrees(th):.3g} deg: the angle looks logged in rad, not deg (multiply by 180/pi)")
            lim = math.degrees(THETA_STROKE_END)
            if th is not None and th > 1.1 * lim:
                refuse(c, f"peak {th:.4g} deg, beyond the stroke ends at +-{lim:.2f} deg; expected the crank angle "
                          "in deg")
        # the flow a sine of this amplitude needs, and the current the valve needs for it
        q_lpm = AREA * CRANK_RADIUS * 2.0 * math.pi * f * math.radians(amp) / LPM
        i_need = q_lpm / VALVE_K
        i = peak("current_mA")
        if i is not None and i_need > 0.5 and 0.0 < i < i_need / 30.0:
            refuse("current_mA", f"peak {i:.4g} mA, where following {amp:g} deg at {f:g} Hz takes about "
                                 f"{i_need:.2g} mA; the current looks logged in A, not mA (multiply by 1000)")
        if i is not None and i > 5.0 * RATED_CURRENT and i > 25.0 * max(i_need, 0.5):
            refuse("current_mA", f"peak {i:.4g} mA, where following {amp:g} deg at {f:g} Hz takes about "
                                 f"{i_need:.2g} mA and the servo amplifier gives +-{RATED_CURRENT:g} mA; the current "
                                 "looks logged in uA, not mA (divide by 1000)")
    else:
        i, q = peak("current_mA"), peak("flow_lpm")
        if i is not None and q is not None and i > 0.0 and q > 0.5 and q / i > 50.0 * VALVE_K:
            refuse("current_mA", f"peak {i:.4g} mA for a peak flow of {q:.3g} LPM ({q / i:.3g} LPM/mA, where the "
                                 f"valve gives about {VALVE_K:g} LPM/mA); the current looks logged in A, not mA "
                                 "(multiply by 1000)")
        if i is not None and q is not None and i > 5.0 * RATED_CURRENT and q / i < VALVE_K / 25.0:
            refuse("current_mA", f"peak {i:.4g} mA for a peak flow of {q:.3g} LPM ({q / i:.3g} LPM/mA, where the "
                                 f"valve gives about {VALVE_K:g} LPM/mA); the current looks logged in uA, not mA "
                                 "(divide by 1000)")
    load = peak("load_kN")
    if load is not None:
        max_kn = AREA * supply * BAR / 1e3
        if "p_a_bar" in cols and "p_b_bar" in cols:
            dp = np.asarray(cols["p_a_bar"], dtype=float) - np.asarray(cols["p_b_bar"], dtype=float)
            dp = dp[np.isfinite(dp)]
            from_p = AREA * float(np.max(np.abs(dp))) * BAR / 1e3 if dp.size else 0.0
            in_n = load > 0.05 and load > 100.0 * max(from_p, 1e-3)
        else:
            in_n = load > 2.0 * max_kn
        if in_n:
            refuse("load_kN", f"peak {load:.4g} kN, where the actuator can push at most {max_kn:.3g} kN at "
                              f"{supply:g} bar; the load looks logged in N, not kN (divide by 1000)")


# --- validation ------------------------------------------------------------------------------


def validate_run(name: str, columns: dict, meta, *, where: str | None = None, line_offset: int = 0,
                 path: Path | None = None, file_columns: list[str] | None = None) -> Run:
    """Validate one run's columns and sidecar; fill short gaps.

    ``line_offset`` converts a sample index into a file line number (2 for a CSV
    with its header on line 1); 0 names samples instead of lines.  ``path`` is
    the data file the run was read from (None for a run built in memory).
    ``file_columns`` are the data file's column names as the logger wrote them
    (a missing column's error names them and the ``--columns`` that maps one).
    """
    where = where or name
    if not isinstance(columns, dict):
        raise CampaignError(f"{where}: expected the run's columns as a dict {{name: values}}, got "
                            f"{type(columns).__name__}")
    bad = next((c for c in columns if not isinstance(c, str)), None)
    if bad is not None:
        raise CampaignError(f"{where}: column name {bad!r} is not text; the format's columns are: {', '.join(COLUMNS)}")
    check_column_names(list(columns), where)
    meta = validate_meta(meta, where=(str(Path(where).with_suffix(".json")) if path else f"{where} sidecar"))
    kind = meta["kind"]

    def at(k: int) -> str:
        return f"line {k + line_offset}" if line_offset else f"sample {k}"

    missing = [c for c in REQUIRED[kind] if c not in columns]
    if missing:
        raise CampaignError(_missing_column(where, kind, missing[0], list(columns) if file_columns is None
                                            else file_columns, "run" if file_columns is None else "file"))
    cols = {c: _column_values(v, c, where) for c, v in columns.items()}
    lengths = {c: v.size for c, v in cols.items()}
    if len(set(lengths.values())) > 1:
        raise CampaignError(f"{where}: columns differ in length {lengths}; expected one value per sample in every column")
    t = cols.pop("t")
    if t.size < MIN_SAMPLES:
        raise CampaignError(f"{where}: {t.size} sample{'' if t.size == 1 else 's'}; expected at least {MIN_SAMPLES}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        what = "is missing" if np.isnan(t[bad[0]]) else f"= {t[bad[0]]:g} is not finite"
        raise CampaignError(f"{where}, {at(bad[0])}: time 't' {what}; every row needs its sample time in s")
    d = np.diff(t)
    back = np.flatnonzero(d <= 0)
    if back.size:
        k = back[0] + 1
        raise CampaignError(f"{where}, {at(k)}: t = {t[k]:.9g} s does not come after {t[k - 1]:.9g} s; "
                            "rows must be in strictly increasing time order")
    dt = float(np.median(d))
    off = np.flatnonzero(np.abs(d - dt) > DT_TOLERANCE * dt)
    if off.size:
        k = off[0] + 1
        raise CampaignError(f"{where}, {at(k)}: time step {d[k - 1]:.6g} s where the run samples every {dt:.6g} s; "
                            "sampling must be uniform (a gap in time needs its rows, with empty cells)")
    check_units(cols, meta, dt, where)
    if 1.0 / dt < MIN_RATE_HZ:
        raise CampaignError(f"{where}: sampled at {1 / dt:g} Hz; expected at least {MIN_RATE_HZ:g} Hz (rigs log at 1-5 kHz)")
    if 1.0 / dt > MAX_RATE_HZ:
        raise CampaignError(f"{where}: sampled at {1 / dt:g} Hz ({dt:.3g} s apart); expected at most {MAX_RATE_HZ:g} Hz "
                            "(rigs log at 1-5 kHz; t in s)")
    t = t[0] + dt * np.arange(t.size)

    interpolated = {}
    for c, v in cols.items():
        miss = ~np.isfinite(v)
        if not miss.any():
            continue
        start, length = _longest_gap(miss)
        if length > MAX_GAP:
            span = f"{at(start)}" if length == 1 else f"{at(start)} to {at(start + length - 1).split()[-1]}"
            raise CampaignError(f"{where}, column '{c}': {length} missing samples in a row ({span}); "
                                f"at most {MAX_GAP} in a row can be interpolated")
        good = np.flatnonzero(~miss)
        cols[c] = np.interp(np.arange(v.size), good, v[good])
        interpolated[c] = int(miss.sum())

    run = Run(name=name, path=path, meta=meta, t=t, dt=dt, columns=cols, interpolated=interpolated)
    if kind == "closed_loop":
        _check_reference(run, where, at)
    return run


def _missing_column(where: str, kind: str, missing: str, found: list[str], holder: str = "file") -> str:
    """The error for a required column that is not there: what the run needs, what the file has, and the
    ``--columns`` mapping that reads a column of another name (the closest one, when one is close)."""
    import difflib

    others = [c for c in found if c not in COLUMNS]
    close = difflib.get_close_matches(missing.lower(), [c.lower() for c in others], n=1, cutoff=0.5)
    old = next((c for c in others if c.lower() == close[0]), None) if close else None
    maps = (f"--columns {missing}={old} reads '{old}' as '{missing}' ({COLUMNS[missing]})" if old else
            f"--columns {missing}=NAME reads the {holder}'s column NAME as '{missing}' ({COLUMNS[missing]})")
    have = ", ".join(found) if found else "none"
    return (f"{where}: required column '{missing}' is missing; a {kind} run needs {', '.join(REQUIRED[kind])}; "
            f"the {holder}'s columns: {have}; {maps}")


def _column_values(values, name: str, where: str) -> np.ndarray:
    """A column as a 1-D float array (NaN or None: a missing sample), or CampaignError (the readers' one check)."""
    try:
        return formats.column_values(values, name, where, COLUMNS.get(name, ""))
    except RunFileError as exc:
        raise CampaignError(str(exc)) from None


def _longest_gap(miss: np.ndarray) -> tuple[int, int]:
    """(start, length) of the longest run of True in ``miss``."""
    edges = np.diff(np.r_[0, miss.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    k = int(np.argmax(ends - starts))
    return int(starts[k]), int(ends[k] - starts[k])


def _check_reference(run: Run, where: str, at) -> None:
    """The logged reference must be the sidecar's: the replay regenerates it from there."""
    ref = reference_of(run)
    model = ref(run.t - run.t[0])[0]
    logged = run.columns["theta_ref_deg"]
    err = np.abs(logged - model)
    tol = max(REF_TOLERANCE * ref.amplitude_deg, 0.01)
    if err.max() > tol:
        k = int(np.argmax(err))
        r = run.meta["reference"]
        raise CampaignError(
            f"{where}, {at(k)}: theta_ref_deg = {logged[k]:.4g} deg, but the sidecar's reference (amplitude_deg "
            f"{r['amplitude_deg']:g}, freq_hz {r['freq_hz']:g}, phase_rad {r['phase_rad']:g}, ramp_cycles "
            f"{r['ramp_cycles']:g}, offset_deg {r.get('offset_deg', 0.0):g}) gives {model[k]:.4g} deg at t - t0 = {run.t[k] - run.t[0]:.4g} s; the sidecar must "
            "describe the reference the controller followed")


def reference_of(run: Run):
    """The run's :class:`~ehas_env.simulation.reference.SineReference` (closed-loop runs)."""
    from ehas_env.simulation.reference import SineReference

    r = run.meta["reference"]
    return SineReference(r["amplitude_deg"], r["freq_hz"], phase=r["phase_rad"], ramp_cycles=r["ramp_cycles"],
                         offset_deg=r.get("offset_deg", 0.0))


def _number(obj: dict, key: str, where: str, what: str, *, lo=None, hi=None, lo_open=False, default=None,
            integer=False) -> float:
    if key not in obj:
        if default is not None:
            return default
        raise CampaignError(f"{where}: key '{key}' is missing; expected {what}")
    v = obj[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise CampaignError(f"{where}: key '{key}' = {v!r}; expected {what}")
    if integer and not float(v).is_integer():
        raise CampaignError(f"{where}: key '{key}' = {v!r}; expected {what}")
    if (lo is not None and (v < lo or (lo_open and v == lo))) or (hi is not None and v > hi):
        raise CampaignError(f"{where}: key '{key}' = {v!r}; expected {what}")
    return int(v) if integer else float(v)


def validate_meta(meta, where: str = "sidecar") -> dict:
    """Check a sidecar and return it normalised (defaults filled, numbers as float).

    Examples
    --------
    >>> validate_meta({"kind": "closed_loop", "disc_sets": 9, "supply_bar": 220,
    ...                "reference": {"amplitude_deg": 20, "freq_hz": 1},
    ...                "controller": {"Kp": 1, "Ki": 2, "Kv": 0.0178, "Ka": 0.0002, "rate_hz": 1000}})
    Traceback (most recent call last):
    ...
    ehas_env.measurement.campaign.CampaignError: sidecar: key 'disc_sets' = 9; expected an integer number of disc sets from 1 to 7
    """
    if not isinstance(meta, dict):
        raise CampaignError(f"{where}: expected a JSON object {{\"kind\": ..., ...}}, got {type(meta).__name__}")
    # optional in a hand-written sidecar; when given, another kind of file or a newer layout is refused
    if "format" in meta and meta["format"] != "ehas-run":
        raise CampaignError(f"{where}: key 'format' = {meta['format']!r}; a run sidecar has \"format\": \"ehas-run\" "
                            "(or no 'format' key)")
    if "version" in meta and (type(meta["version"]) is not int or meta["version"] != 1):
        raise CampaignError(f"{where}: key 'version' = {meta['version']!r}; this ehas reads run sidecars of version 1 "
                            "(or without 'version')")
    if "kind" not in meta:
        raise CampaignError(f"{where}: key 'kind' is missing; expected one of {', '.join(KINDS)}")
    kind = meta["kind"]
    if kind not in KINDS:
        raise CampaignError(f"{where}: key 'kind' = {kind!r}; expected one of {', '.join(KINDS)}")
    out = dict(meta)
    out["supply_bar"] = _number(meta, "supply_bar", where, "the supply pressure in bar, in (0, 400]", lo=0.0, hi=400.0,
                                lo_open=True)
    if "notes" in meta and not isinstance(meta["notes"], str):
        raise CampaignError(f"{where}: key 'notes' must be free text (a string)")
    if kind == "valve_open_loop":
        return out
    out["disc_sets"] = _number(meta, "disc_sets", where,
                               f"an integer number of disc sets from {MIN_SETS} to {MAX_SETS}", lo=MIN_SETS,
                               hi=MAX_SETS, integer=True)
    ref = meta.get("reference")
    if not isinstance(ref, dict):
        raise CampaignError(f"{where}: key 'reference' is {'missing' if ref is None else repr(ref)}; expected "
                            "{\"amplitude_deg\": ..., \"freq_hz\": ...}")
    lim = math.degrees(THETA_STROKE_END)
    w = f"{where}, reference"
    out["reference"] = {
        **ref,
        "amplitude_deg": _number(ref, "amplitude_deg", w, f"the sine amplitude in deg, in (0, {lim:.2f})", lo=0.0,
                                 hi=lim - 1e-9, lo_open=True),
        "freq_hz": _number(ref, "freq_hz", w, "the sine frequency in Hz, in (0, 50]", lo=0.0, hi=50.0, lo_open=True),
        "phase_rad": _number(ref, "phase_rad", w, "the sine's phase in rad", default=0.0),
        "ramp_cycles": _number(ref, "ramp_cycles", w, "the fade-in length in reference periods, >= 0", lo=0.0,
                               default=0.0),
    }
    if "offset_deg" in ref:  # the sine's mean angle: the sine stays inside the stroke ends
        amp = out["reference"]["amplitude_deg"]
        out["reference"]["offset_deg"] = _number(
            ref, "offset_deg", w, f"the sine's mean angle in deg, with |offset_deg| + amplitude_deg ({amp:g}) below "
            f"the stroke end ({lim:.2f})", lo=-(lim - amp) + 1e-9, hi=lim - amp - 1e-9)
    ctrl = meta.get("controller")
    if not isinstance(ctrl, dict):
        raise CampaignError(f"{where}: key 'controller' is {'missing' if ctrl is None else repr(ctrl)}; expected the "
                            "rig controller's gains {\"Kp\": mA/deg, \"Ki\": mA/(deg s), \"Kv\": mA/(deg/s), "
                            "\"Ka\": mA/(deg/s^2), \"rate_hz\": Hz}")
    w = f"{where}, controller"
    allowed = CONTROLLER_REQUIRED + CONTROLLER_OPTIONAL
    for key in ctrl:
        if key not in allowed:
            raise CampaignError(f"{w}: key '{key}' is not a setting of the rig's controller; expected "
                                f"{', '.join(CONTROLLER_REQUIRED)} and optionally {', '.join(CONTROLLER_OPTIONAL)}")
    g = FIELDS["gain"]
    gain = f"a gain in [{g.lo:g}, {g.hi:g}]"
    c = {key: _number(ctrl, key, w, gain, lo=g.lo, hi=g.hi) for key in ("Kp", "Ki", "Kv", "Ka")}
    for key in CONTROLLER_OPTIONAL:
        c[key] = _number(ctrl, key, w, gain, lo=g.lo, hi=g.hi, default=0.0)
    c["rate_hz"] = _number(ctrl, "rate_hz", w, f"the controller rate in Hz, in [{MIN_RATE_HZ:g}, {MAX_RATE_HZ:g}]",
                           lo=MIN_RATE_HZ, hi=MAX_RATE_HZ)
    out["controller"] = c
    return out


# --- writing ---------------------------------------------------------------------------------


def write_run(stem, columns: dict, meta: dict, fmt: str = "csv") -> tuple[Path, Path]:
    """Validate one run, then write its data file (``stem.csv`` or another format, see :func:`write_campaign`) and
    ``stem.json`` atomically."""
    stem = Path(stem)
    data_format = _writable(fmt)
    validate_run(stem.stem, columns, meta, where=str(stem))
    return _write_run_files(stem, columns, meta, fmt=data_format.name)


def _writable(fmt: str):
    try:
        data_format = formats.by_name(fmt)
    except RunFileError as exc:
        raise CampaignError(str(exc)) from None
    if data_format.write is None:
        raise CampaignError(f"format {fmt!r}: ehas reads {data_format.name} files but does not write them")
    return data_format


def write_campaign(folder, runs, extra_files: dict[str, str] | None = None, *, overwrite: bool = False,
                   fmt: str = "csv", keep: bool = False) -> Path:
    """Write a campaign folder: all runs validated first, then written at once.

    Parameters
    ----------
    folder : path
        The campaign folder; it must not exist or be empty unless ``overwrite``.
    runs : iterable of (name, columns, meta)
        Runs as column dicts (``t`` and the format's columns) and sidecars.
    extra_files : dict, optional
        File name -> text (a README, a truth file) written beside the runs.
    overwrite : bool
        Replace an existing campaign folder.
    fmt : str
        The data files' format, by name or suffix: ``csv`` (default), ``mat``
        (MATLAB v5), ``tdms``, ``hdf5``, ``parquet`` (:mod:`ehas_env.measurement.formats`).
    keep : bool
        With ``overwrite``, keep the folder's other files (add runs to a campaign,
        e.g. in another format); a run of the same name is replaced.

    Returns
    -------
    Path
        ``folder``.

    The runs are written into a temporary folder beside ``folder`` which is then
    renamed into place, so a reader sees the whole campaign or none of it.
    """
    folder = Path(folder)
    runs = list(runs)
    if not runs:
        raise CampaignError("write_campaign: no runs to write")
    names = [name for name, _, _ in runs]
    if len(set(names)) != len(names):
        raise CampaignError(f"write_campaign: run names repeat: {names}")
    data_format = _writable(fmt)
    suffix = data_format.suffixes[0]
    for name, cols, meta in runs:
        validate_run(name, cols, meta, where=str(folder / f"{name}{suffix}"))
    if folder.exists():
        if not folder.is_dir():
            raise CampaignError(f"{folder} exists and is not a folder")
        if any(folder.iterdir()) and not overwrite:
            raise CampaignError(f"{folder} already exists and is not empty; choose another folder or overwrite it")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=folder.parent))
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it private; a campaign is for sharing
        if keep and folder.is_dir():
            replaced = set(names)
            data = set(formats.data_suffixes()) | set(formats.companion_suffixes()) | {".json"}
            for f in folder.iterdir():
                if f.is_file() and not (f.stem in replaced and f.suffix.lower() in data):
                    shutil.copy2(f, tmp / f.name)
        for name, cols, meta in runs:
            _write_run_files(tmp / name, cols, meta, fmt=data_format.name)
        for fname, text in (extra_files or {}).items():
            atomic_write_text(tmp / fname, text)
        for f in tmp.iterdir():
            os.chmod(f, 0o666 & ~umask)
        if folder.exists():
            old = folder.with_name(f".{folder.name}.old-{os.getpid()}")
            os.replace(folder, old)
            os.replace(tmp, folder)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder
