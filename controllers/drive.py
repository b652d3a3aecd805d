"""Drive files: a learning controller's learned feed-forward as a table a rig controller plays back.

A sine-test system iterates *drive files*: per test condition, one period of the signal added to the
servo loop's output.  :func:`export_drives` writes, for each condition a learning controller
(:mod:`.ilc`, :mod:`.harmonic`) learned (its JSON's ``learned`` records), two files:

``<stem>.csv``
    one reference period of the learned current, one row per sample, columns ``time_s`` (s from the
    start of the period: phase 0, where the reference crosses its mean rising) and ``current_mA`` (mA,
    added to the base loop's output);
``<stem>.json``
    the sidecar (``"format": "ehas-drive"``, version 1): ``table`` (the CSV's file name),
    ``condition`` (``disc_sets``, ``amplitude_deg`` in deg, ``freq_hz`` in Hz), ``period_s``,
    ``samples``, ``sample_rate_hz`` (samples per second of the table: ``samples / period_s``),
    ``control_rate_hz`` (the base loop's rate), ``start_cycle`` (the first reference cycle the table is
    played in; before it the base loop runs alone: cycle 0 is the reference's fade-in), ``units``,
    ``base`` (the fixed-gain base loop for that plant, a ``piff`` description) and ``provenance``
    (the learning controller, what it reached, its guard's state, the writing command);

and ``drive.json``, a controller file (``"type": "drive"``) naming the sidecars, so that ehas replays
the tables on their base loops (:class:`DriveController`) anywhere a controller file goes.

Reading a drive file reads numbers and text only (``csv``, ``json``): it never executes anything.
"""
from __future__ import annotations

import copy
import csv
import json
import math
from pathlib import Path

import numpy as np

from .base import Controller, register_type
from .learning import CycleTable, condition_key

DRIVE_FORMAT = "ehas-drive"
DRIVE_VERSION = 1
COLUMNS = ("time_s", "current_mA")
#: sidecar fields and what they hold (the errors name them)
SIDECAR_FIELDS = ("format", "version", "table", "condition", "period_s", "samples", "sample_rate_hz",
                  "control_rate_hz", "start_cycle", "units", "base", "provenance")


def drive_stem(name: str, disc_sets: int, amplitude_deg: float, freq_hz: float) -> str:
    """File stem of one condition's drive: ``<controller>_<n>sets_<amp>deg_<f>hz`` (``.`` as ``p``)."""
    from .benchmark import _slug

    return f"{_slug(name)}_{int(disc_sets)}sets_{amplitude_deg:g}deg_{freq_hz:g}hz".replace(".", "p")


def drive_members(name: str) -> tuple[str, str, str]:
    """Glob patterns of the files :func:`export_drives` writes into a folder for the controller ``name``: its
    drive tables and sidecars of every condition (:func:`drive_stem`) and ``drive.json`` -- an export's output
    set, and nothing else of the folder (not the controller file, not a user's own CSV or JSON).

    Parameters
    ----------
    name : str
        The learning controller's name.

    Returns
    -------
    tuple of str
        ``<stem>*.csv``, ``<stem>*.json`` patterns and ``drive.json``.

    Examples
    --------
    >>> drive_members("ILC on book")
    ('ilc_on_book_*sets_*deg_*hz.csv', 'ilc_on_book_*sets_*deg_*hz.json', 'drive.json')
    """
    from .benchmark import _slug

    stem = f"{_slug(name)}_*sets_*deg_*hz"
    return f"{stem}.csv", f"{stem}.json", "drive.json"


def export_drives(controller, out_dir, *, conditions=None, command: str = "", out_label: str | None = None) -> list[Path]:
    """Write the drive files of every condition ``controller`` learned (module docstring).

    Parameters
    ----------
    controller : CycleLearner
        A learning controller with ``learned`` records (run it, or load a JSON that holds them).
    out_dir : str or path
        Folder to write into.
    conditions : list of str, optional
        Condition keys (:func:`~.learning.condition_key`) to export; default: every one learned.
    command : str
        The writing command, recorded in each sidecar's provenance.
    out_label : str, optional
        The folder as the user named it (the paths written into ``drive.json``); default ``out_dir``.

    Returns
    -------
    list of Path
        The sidecars written, then ``drive.json``.

    Raises
    ------
    ValueError
        One line: not a learning controller, nothing learned, an unknown condition.
    """
    from ehas_env import __version__
    from ehas_env.output.files import atomic_write_text

    from .base import FILE_FORMAT, FILE_VERSION, _jsonable
    from .learning import CycleLearner, base_to_dict

    if not isinstance(controller, CycleLearner):
        raise ValueError(f"{getattr(controller, 'source', 'the controller')} is a "
                         f"{type(controller).__name__}; drive files come from a learning controller (ilc, harmonic)")
    learned = {condition_key(r["disc_sets"], r["amplitude_deg"], r["freq_hz"]): r for r in controller.learned_state()}
    where = getattr(controller, "source", controller.name)
    if not learned:
        raise ValueError(f"{where}: field 'learned' is empty or missing: the controller has learned "
                         "nothing yet (run it, e.g. the long test, and save it; docs/learning-control.md)")
    keys = list(learned) if conditions is None else list(conditions)
    for k in keys:
        if k not in learned:
            raise ValueError(f"{where}: nothing learned at {k}; learned at: {', '.join(learned)}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    label = Path(out_label) if out_label is not None else out
    written, names = [], []
    for k in keys:
        rec = learned[k]
        loop = controller.base.for_plant(rec["disc_sets"])
        rate = float(loop.rate_hz)
        table = controller.feedforward_table(k, rate)
        f = float(rec["freq_hz"])
        n = table.size
        stem = drive_stem(controller.name, rec["disc_sets"], rec["amplitude_deg"], f)
        lines = ["time_s,current_mA"] + [f"{j / (n * f):.9g},{x:.9g}" for j, x in enumerate(table)]
        atomic_write_text(out / f"{stem}.csv", "\n".join(lines) + "\n")
        steady = rec["cycle_error_pct"][-5:]
        side = {"format": DRIVE_FORMAT, "version": DRIVE_VERSION, "table": f"{stem}.csv",
                "condition": {"disc_sets": rec["disc_sets"], "amplitude_deg": rec["amplitude_deg"], "freq_hz": f},
                "period_s": 1.0 / f, "samples": n, "sample_rate_hz": n * f, "control_rate_hz": rate,
                "start_cycle": controller.start_cycle + 1,
                "units": {"time_s": "s from the start of the reference period (phase 0: the reference crosses its "
                                    "mean rising)", "current_mA": "mA added to the base loop's output",
                          "amplitude_deg": "deg", "freq_hz": "Hz", "period_s": "s", "sample_rate_hz": "Hz",
                          "control_rate_hz": "Hz"},
                "base": {"format": FILE_FORMAT, "version": FILE_VERSION, **base_to_dict(loop)},
                "provenance": {"controller": controller.name, "type": controller.to_dict()["type"],
                               "source": str(where), "cycles_learned": rec["cycles"],
                               "last_cycles_error_pct": steady, "guard_state": rec["guard_state"],
                               "guard_events": len(rec["events"]), "ehas_version": __version__,
                               "command": command}}
        atomic_write_text(out / f"{stem}.json", json.dumps(_jsonable(side), indent=2) + "\n")
        written.append(out / f"{stem}.json")
        names.append(str(label / f"{stem}.json"))
    index = {"format": FILE_FORMAT, "version": FILE_VERSION, "type": "drive", "kind": "classical",
             "name": f"drive of {controller.name}", "files": names}
    if command:
        index["command"] = command
    atomic_write_text(out / "drive.json", json.dumps(index, indent=2) + "\n")
    return written + [out / "drive.json"]


def read_drive(path) -> dict:
    """Read one drive file (its sidecar and the CSV it names) as data, checked.

    Parameters
    ----------
    path : str or path
        The sidecar (``.json``); the CSV is the sidecar's ``table``, in the same folder.

    Returns
    -------
    dict
        ``disc_sets``, ``amplitude_deg`` (deg), ``freq_hz`` (Hz), ``table`` (ndarray, mA per sample over one
        period), ``start_cycle``, ``base`` (PIFF), ``sidecar`` (the JSON) and ``path``.

    Raises
    ------
    ValueError
        One line naming the file and the field: a missing sidecar or CSV, a wrong format, columns other
        than ``time_s,current_mA``, a row count or a time step that does not match ``samples`` /
        ``sample_rate_hz``, a rate that does not match ``samples / period_s``, a non-finite number.
    """
    from ehas_env.ranges import check_field, check_number

    from .piff import PIFF

    side_path = Path(path)
    if not side_path.is_file():
        raise ValueError(f"drive file {side_path}: sidecar not found (a drive is a .json sidecar beside its .csv "
                         "table, written by ehas export-drive)")
    try:
        side = json.loads(side_path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"drive file {side_path}: not JSON ({' '.join(str(exc).split())})") from None
    w = f"drive file {side_path}"
    if not isinstance(side, dict):
        raise ValueError(f"{w}: expected a JSON object with \"format\": \"{DRIVE_FORMAT}\"")
    if side.get("format") != DRIVE_FORMAT:
        raise ValueError(f"{w}: field 'format' = {side.get('format')!r}; expected {DRIVE_FORMAT!r}")
    if side.get("version") != DRIVE_VERSION:
        raise ValueError(f"{w}: field 'version' = {side.get('version')!r}; this ehas reads version {DRIVE_VERSION}")
    for k in ("table", "condition", "period_s", "samples", "sample_rate_hz", "start_cycle", "base"):
        if k not in side:
            raise ValueError(f"{w}: no field '{k}'")
    cond = side["condition"]
    if not isinstance(cond, dict) or any(k not in cond for k in ("disc_sets", "amplitude_deg", "freq_hz")):
        raise ValueError(f"{w}: field 'condition' must be {{\"disc_sets\", \"amplitude_deg\", \"freq_hz\"}}, got {cond!r}")
    n_sets = int(check_field("disc_sets", cond["disc_sets"], f"{w}: field 'condition.disc_sets'"))
    amp = float(check_field("amplitude_deg", cond["amplitude_deg"], f"{w}: field 'condition.amplitude_deg'"))
    freq = float(check_field("freq_hz", cond["freq_hz"], f"{w}: field 'condition.freq_hz'"))
    period = float(check_number(side["period_s"], f"{w}: field 'period_s'", "s", 0, 1e4, lo_open=True))
    samples = int(check_number(side["samples"], f"{w}: field 'samples'", "", 8, 1e7, integer=True))
    rate = float(check_number(side["sample_rate_hz"], f"{w}: field 'sample_rate_hz'", "Hz", 0, 1e7, lo_open=True))
    start = int(check_number(side["start_cycle"], f"{w}: field 'start_cycle'", "cycles", 0, 1000, integer=True))
    if abs(period * freq - 1.0) > 1e-6:
        raise ValueError(f"{w}: field 'period_s' = {period:g} s is not 1 / condition.freq_hz = {1 / freq:g} s")
    if abs(rate * period - samples) > 1e-6 * samples:
        raise ValueError(f"{w}: field 'sample_rate_hz' = {rate:g} Hz does not match samples / period_s = "
                         f"{samples / period:g} Hz (rate mismatch)")
    if not isinstance(side["table"], str) or Path(side["table"]).name != side["table"]:
        raise ValueError(f"{w}: field 'table' must be the CSV's file name beside the sidecar, got {side['table']!r}")
    base = side["base"]
    if not isinstance(base, dict) or base.get("type", "piff") != "piff":
        raise ValueError(f"{w}: field 'base' must be a piff controller description (the base loop for this plant)")
    try:
        loop = PIFF.from_dict(base)
    except (ValueError, TypeError, KeyError) as exc:
        raise ValueError(f"{w}: field 'base': {exc}") from None
    csv_path = side_path.parent / side["table"]
    wc = f"drive file {csv_path}"
    if not csv_path.is_file():
        raise ValueError(f"{w}: field 'table': {csv_path} not found")
    with csv_path.open(newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.reader(fh) if r]
    if not rows or tuple(c.strip() for c in rows[0]) != COLUMNS:
        raise ValueError(f"{wc}: columns {','.join(rows[0]) if rows else '(empty file)'}; expected "
                         f"{','.join(COLUMNS)} (s, mA)")
    data = rows[1:]
    if len(data) != samples:
        raise ValueError(f"{wc}: {len(data)} rows; the sidecar's field 'samples' says {samples}")
    try:
        arr = np.array([[float(a), float(b)] for a, b in data])
    except ValueError:
        bad = next(i for i, r in enumerate(data) if len(r) != 2 or not _floats(r))
        raise ValueError(f"{wc}: row {bad + 2}: expected two numbers time_s,current_mA, got {','.join(data[bad])}") from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{wc}: a non-finite number in column {COLUMNS[int(np.argwhere(~np.isfinite(arr))[0][1])]}")
    step = np.diff(arr[:, 0])
    if arr[0, 0] != 0.0 or (step.size and np.max(np.abs(step * rate - 1.0)) > 1e-4):
        raise ValueError(f"{wc}: column time_s must start at 0 and step by 1 / sample_rate_hz = {1 / rate:.6g} s "
                         f"(the sidecar's field 'sample_rate_hz'); rate mismatch")
    if np.max(np.abs(arr[:, 1])) > 20.0:
        raise ValueError(f"{wc}: column current_mA beyond the servo amplifier's +-20 mA")
    return {"disc_sets": n_sets, "amplitude_deg": amp, "freq_hz": freq, "table": arr[:, 1].copy(),
            "start_cycle": start, "base": loop, "sidecar": side, "path": str(side_path)}


def _floats(row) -> bool:
    try:
        [float(x) for x in row]
    except ValueError:
        return False
    return True


@register_type("drive")
class DriveController(Controller):
    """Replay drive files: the base loop of each plus its table, from its ``start_cycle`` on.

    Parameters
    ----------
    files : list of str
        Drive sidecars (:func:`read_drive`), one per condition (read when the controller is built).
    name : str
        Label in tables and files.

    A run picks the drive of its plant's disc sets and the reference's amplitude and frequency (within
    1e-9 relative); a condition without a drive is refused in one line naming the conditions there are.
    """

    kind = "classical"

    def __init__(self, files, name: str = "drive"):
        if isinstance(files, (str, Path)):
            files = [files]
        if not isinstance(files, (list, tuple)) or not files:
            raise ValueError(f"drive: 'files' must be a non-empty list of drive sidecars (.json), got {files!r}")
        self.files = [str(f) for f in files]
        self.drives = {}
        for f in self.files:
            d = read_drive(f)
            self.drives[condition_key(d["disc_sets"], d["amplitude_deg"], d["freq_hz"])] = d
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"drive: 'name' must be a non-empty text, got {name!r}")
        self.name = name
        self.disc_sets = None
        self.reset()

    def for_plant(self, disc_sets: int) -> "DriveController":
        """A fresh copy for a plant with ``disc_sets`` disc sets.

        Parameters
        ----------
        disc_sets : int
            Number of disc sets, 1..7.

        Returns
        -------
        DriveController
            The copy (its drive is picked on the first sample, from the reference).
        """
        new = copy.copy(self)
        new.disc_sets = int(disc_sets)
        new.reset()
        return new

    def reset(self) -> None:
        self._drive = None
        self._loop = None
        self._ct = None

    def act(self, measurement: dict) -> float:
        """Current command, mA: the drive's base loop plus its table at this phase (from ``start_cycle`` on).

        Parameters
        ----------
        measurement : dict of str to float
            The closed loop's sample (:data:`~ehas_controllers.base.MEASUREMENT_KEYS`) with the reference's
            ``amplitude_deg`` (deg) and ``freq_hz`` (Hz).

        Returns
        -------
        float
            The current in mA, clipped to the base loop's +-``i_max``.
        """
        m = measurement
        if self._drive is None:
            self._pick(m)
        c, ff = self._ct.at(m["t"], self._drive["table"])
        u = self._loop.act(m) + (ff if c >= self._drive["start_cycle"] else 0.0)
        lim = self._loop.i_max
        return min(max(u, -lim), lim)

    def _pick(self, m: dict) -> None:
        if self.disc_sets is None:
            raise ValueError(f"drive '{self.name}': which plant? call for_plant(disc_sets) before running it")
        if "freq_hz" not in m or "amplitude_deg" not in m:
            raise ValueError("DriveController.act: measurement has no 'freq_hz'/'amplitude_deg' (Plant.simulate_"
                             "closed_loop passes them)")
        key = condition_key(self.disc_sets, m["amplitude_deg"], m["freq_hz"])
        d = self.drives.get(key)
        if d is None:
            d = next((x for x in self.drives.values() if x["disc_sets"] == self.disc_sets
                      and math.isclose(x["amplitude_deg"], m["amplitude_deg"], rel_tol=1e-9)
                      and math.isclose(x["freq_hz"], m["freq_hz"], rel_tol=1e-9)), None)
        if d is None:
            raise ValueError(f"drive '{self.name}': no drive file for {key}; drives for: {', '.join(self.drives)}")
        self._drive = d
        self._loop = copy.deepcopy(d["base"])
        self._loop.reset()
        self._ct = CycleTable(d["freq_hz"], d["table"].size * d["freq_hz"])

    def to_dict(self) -> dict:
        """JSON-able description: ``type`` ``"drive"``, ``kind``, ``name`` and ``files`` (the sidecars' paths)."""
        return {"type": "drive", "kind": self.kind, "name": self.name, "files": list(self.files)}

    @classmethod
    def from_dict(cls, data: dict) -> "DriveController":
        """Build the controller from ``{"type": "drive", "files": [sidecar paths], "name": ...}``.

        Parameters
        ----------
        data : dict
            The description (``files`` are paths as the user's working folder sees them).

        Returns
        -------
        DriveController
            The controller, every drive file read and checked.
        """
        allowed = {"type", "kind", "name", "files", "format", "version", "command", "metrics", "notes",
                   "mean_rms_error_pct"}
        unknown = sorted(set(map(str, data)) - allowed)
        if unknown:
            raise ValueError(f"drive: unknown key(s) {', '.join(unknown)}; expected some of {', '.join(sorted(allowed))}")
        if "files" not in data:
            raise ValueError("drive: no 'files' field; expected \"files\": [drive sidecars written by ehas export-drive]")
        return cls(data["files"], name=data.get("name", "drive"))

    def __repr__(self) -> str:
        return f"DriveController '{self.name}': {len(self.drives)} drive file(s) ({', '.join(self.drives)})"
