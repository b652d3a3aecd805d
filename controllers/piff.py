"""The rig's PI + feed-forward controller, its model-inversion and pressure-feedback variants, gain schedules.

One law covers the three controllers of the issue (RMC70-like, 1 kHz, zero-order hold)::

    i = Kp e + Ki int(e) + Kv r' + Ka r'' + Kj r''' - Kdp dP_L,      e = theta_ref - theta

* **PI + velocity/acceleration feed-forward** (the rig's controller, ``Kj = Kdp = 0``);
* **model-inversion feed-forward**: ``Kj != 0``, the jerk term that inverts the
  valve's second-order lag (and the chambers' compliance);
* **load-pressure feedback** ``Kdp != 0``: static (``dp_hp = 0``) or "dynamic",
  high-passed at ``dp_hp`` rad/s so that only pressure *changes* are fed back -
  the hydraulic engineer's classic way to damp a heavy inertia's resonance.

The output is clipped to +-``i_max`` with conditional-integration anti-windup
and optionally quantized to a ``output_bits`` DAC (the rig's RMC70: 12 bits over
+-20 mA).  The law is written once, :func:`pi_ff_law`: compiled into the model
(registered as ``"pi_ff"``) for the benchmark, ``Plant``, the environment's
residual mode and the replay of logs, and called as plain Python by
:meth:`PIFF.act`.

Examples
--------
>>> from ehas_controllers.piff import PIFF
>>> c = PIFF.book()
>>> c
PIFF 'book' [PI+FF]: Kp=1 mA/deg, Ki=2 mA/(deg s), Kv=0.01778 mA/(deg/s), Ka=0.0002296 mA/(deg/s^2)
>>> c.rig_gains().Kp
1.0
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ehas_env.ranges import check_field
from ehas_env.simulation.control_laws import N_MEM
from ehas_env.simulation.pi_ff_law import GAIN_NAMES, GAIN_UNITS, pi_ff_law
from ehas_env.simulation.rig_controller import RigController

from .base import Controller, check_measurement, gains_field, register_type

DAC_SPAN_MA = 40.0  # +-20 mA output span (docs/rig.md: RMC70 12-bit current output)


@register_type("piff")
@dataclass
class PIFF(RigController, Controller):
    """PI + velocity/acceleration(/jerk) feed-forward with optional load-pressure feedback.

    The gains and the compiled law are :class:`~ehas_env.simulation.rig_controller.RigController`'s (this
    class is one, so the compiled model runs it directly); this class adds the controller's output limit,
    DAC, name, JSON file and the law run in Python (:meth:`act`).

    Attributes
    ----------
    Kp : float
        Proportional gain, mA/deg.
    Ki : float
        Integral gain, mA/(deg s).
    Kv : float
        Velocity feed-forward, mA/(deg/s) (book: 1/56.25, the inverse of the
        plant's no-load velocity gain).
    Ka : float
        Acceleration feed-forward, mA/(deg/s^2).
    Kj : float
        Jerk feed-forward, mA/(deg/s^3) (model inversion; 0 on the rig).
    Kdp : float
        Load-pressure feedback, mA/bar (0: off).
    dp_hp : float
        Corner of the pressure feedback's first-order high-pass, rad/s (0: static).
    i_max : float
        Output limit, mA (rig: +-20 mA servo amplifier).
    output_bits : int
        DAC resolution of the output over +-20 mA (rig: 12); 0: unquantized.
    rate_hz : float
        Sample rate, Hz (rig: 1 kHz).
    name : str
        Label in tables and files.
    """

    # Kp, Ki, Kv, Ka, Kj, Kdp, dp_hp, rate_hz: RigController's fields
    i_max: float = 20.0
    output_bits: int = 0
    name: str = "PI+FF"
    kind = "classical"
    _mem: np.ndarray = field(default=None, init=False, repr=False, compare=False)
    _gains: np.ndarray = field(default=None, init=False, repr=False, compare=False)
    _checked: bool = field(default=False, init=False, repr=False, compare=False)

    def __post_init__(self):
        for name in (*GAIN_NAMES, "i_max", "rate_hz"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"PIFF: {name} must be a finite number in {GAIN_UNITS.get(name, '')}, got {v!r}".rstrip())
            setattr(self, name, float(v))
        # the ranges RigController holds its gains to (a gain of 1e308 overflows the loop; ehas_env.ranges)
        for name in (*GAIN_NAMES, "rate_hz"):
            check_field("rate_hz" if name == "rate_hz" else "gain", getattr(self, name), f"PIFF: {name}")
        if self.dp_hp < 0:
            raise ValueError(f"PIFF: dp_hp must be >= 0 rad/s (0: static pressure feedback), got {self.dp_hp!r}")
        if not 0 < self.i_max <= 20.0:
            raise ValueError(f"PIFF: i_max must be in (0, 20] mA (the servo amplifier's range), got {self.i_max!r}")
        if self.rate_hz <= 0:
            raise ValueError(f"PIFF: rate_hz must be positive, got {self.rate_hz!r}")
        if not (isinstance(self.output_bits, int) and 0 <= self.output_bits <= 24):
            raise ValueError(f"PIFF: output_bits must be an integer 0..24 (0: no DAC quantization), got {self.output_bits!r}")

    # -- constructors ---------------------------------------------------------
    @classmethod
    def book(cls) -> "PIFF":
        """The reference model's baseline: Kp 1, Ki 2, Kv 1/56.25, Ka = Kv 2 zeta / wn.

        Returns
        -------
        PIFF
            The book's gains (Kp 1 mA/deg, Ki 2 mA/(deg s), Kv 1/56.25 mA/(deg/s),
            Ka = Kv 2 (0.691) / 107 mA/(deg/s^2)), +-20 mA, no DAC, 1 kHz, named ``"book"``.
        """
        return cls(name="book")

    @classmethod
    def from_rig_controller(cls, rc, name: str = "PI+FF") -> "PIFF":
        """Wrap an :class:`ehas_env.simulation.plant.RigController`.

        Parameters
        ----------
        rc : RigController
            The gains (``Kp`` ... ``dp_hp``, in :data:`GAIN_UNITS`) and ``rate_hz`` (Hz) to take.
        name : str
            Label of the new controller in tables and files.

        Returns
        -------
        PIFF
            A controller with ``rc``'s gains and rate, the default output limit (+-20 mA) and no DAC.
        """
        return cls(**{k: getattr(rc, k) for k in GAIN_NAMES}, rate_hz=rc.rate_hz, name=name)

    @classmethod
    def from_dict(cls, data: dict) -> "PIFF":
        """Rebuild a PIFF from its JSON description (:meth:`to_dict`, a controller file).

        Parameters
        ----------
        data : dict
            ``{"gains": {gain: value}, ...}`` with gains of :data:`GAIN_NAMES` in their units
            (missing ones take the book's values) and optionally ``i_max`` (mA), ``output_bits``,
            ``rate_hz`` (Hz) and ``name``; a bare ``{gain: value}`` dict is accepted too.

        Returns
        -------
        PIFF
            The controller.

        Raises
        ------
        ValueError
            No or empty ``gains``, an unknown gain, or a value :class:`PIFF` refuses.
        """
        if "gains" not in data and data and set(data) <= set(GAIN_NAMES):
            data = {"gains": data}  # a bare {gain: value} dict (Python API)
        gains = gains_field(data, GAIN_NAMES)
        kw = {k: gains[k] for k in GAIN_NAMES if k in gains}
        for key in ("i_max", "output_bits", "rate_hz", "name"):
            if key in data:
                kw[key] = data[key]
        return cls(**kw)

    def to_dict(self) -> dict:
        """JSON-able description; :meth:`from_dict` rebuilds the controller from it.

        Returns
        -------
        dict
            ``type`` (``"piff"``), ``kind``, ``name``, ``variant``, ``gains`` (:meth:`gains`), their
            ``units``, ``i_max`` (mA), ``output_bits`` and ``rate_hz`` (Hz).
        """
        return {"type": self.type_name, "kind": self.kind, "name": self.name, "variant": self.variant,
                "gains": self.gains(), "units": dict(GAIN_UNITS), "i_max": self.i_max,
                "output_bits": self.output_bits, "rate_hz": self.rate_hz}

    # -- description ------------------------------------------------------------
    def gains(self) -> dict[str, float]:
        """The law's gains by name.

        Returns
        -------
        dict of str to float
            ``Kp``, ``Ki``, ``Kv``, ``Ka``, ``Kj``, ``Kdp``, ``dp_hp`` in the units of
            :data:`GAIN_UNITS` (mA/deg, mA/(deg s), mA/(deg/s), mA/(deg/s^2), mA/(deg/s^3), mA/bar, rad/s).
        """
        return {k: getattr(self, k) for k in GAIN_NAMES}

    def with_gains(self, **gains) -> "PIFF":
        """A copy with some gains replaced (state reset).

        Parameters
        ----------
        **gains : float
            New values of fields by name (``Kp=1.5``), in the units of the class's Attributes;
            checked as the constructor checks them.

        Returns
        -------
        PIFF
            The copy (:func:`dataclasses.replace`), with fresh internal state.
        """
        return replace(self, **gains)

    @property
    def variant(self) -> str:
        """``PI+FF``, ``PI+FF+jerk``, with ``+dP static`` / ``+dP dynamic`` for pressure feedback."""
        v = "PI+FF+jerk" if self.Kj != 0.0 else "PI+FF"
        if self.Kdp != 0.0:
            v += " +dP dynamic" if self.dp_hp > 0 else " +dP static"
        return v

    def __repr__(self) -> str:
        shown = [k for k in GAIN_NAMES if k in ("Kp", "Ki", "Kv", "Ka") or getattr(self, k) != 0.0]
        if self.Kdp == 0.0 and "dp_hp" in shown:
            shown.remove("dp_hp")
        text = ", ".join(f"{k}={getattr(self, k):.4g} {GAIN_UNITS[k]}" for k in shown)
        extra = []
        if self.output_bits:
            extra.append(f"{self.output_bits}-bit output")
        if self.i_max != 20.0:
            extra.append(f"+-{self.i_max:g} mA")
        return f"PIFF '{self.name}' [{self.variant}]: {text}" + (f" ({', '.join(extra)})" if extra else "")

    # -- the compiled path ------------------------------------------------------
    def rig_gains(self, disc_sets: int | None = None):
        """The gains alone (a :class:`RigController`: no output limit, DAC or name).

        Parameters
        ----------
        disc_sets : int, optional
            Ignored: a PIFF has one set of gains for every plant (the argument is the
            :class:`~ehas_controllers.base.Controller` protocol's).

        Returns
        -------
        RigController
            The gains and ``rate_hz``, the compiled loop's form of this controller.
        """
        return RigController(**self.gains(), rate_hz=self.rate_hz)

    @property
    def dac_lsb(self) -> float:
        """Output quantization step, mA (0: none)."""
        return DAC_SPAN_MA / 2**self.output_bits if self.output_bits else 0.0

    # -- the law, run in Python ------------------------------------------------
    def reset(self) -> None:
        self._mem = np.zeros(N_MEM)
        self._gains = np.array([getattr(self, n) for n in GAIN_NAMES])
        self._checked = False

    def act(self, measurement: dict) -> float:
        """Current command, mA: :func:`pi_ff_law` on the measurement, then the DAC.

        Parameters
        ----------
        measurement : dict of str to float
            :data:`~ehas_controllers.base.MEASUREMENT_KEYS`: ``t`` (s), ``theta_deg`` (deg),
            ``theta_ref_deg`` and its derivatives (deg/s^k), ``p_a_bar``, ``p_b_bar``, ``p_s_bar`` (bar);
            checked on the first call after :meth:`reset`.

        Returns
        -------
        float
            The current in mA, clipped to +-``i_max`` and quantized to the DAC's step when
            ``output_bits`` is set.

        Raises
        ------
        ValueError
            If the measurement lacks one of the keys.
        """
        m = measurement
        if self._mem is None:
            self.reset()
        if not self._checked:
            check_measurement(m, "PIFF")
            self._checked = True
        u = pi_ff_law(self._gains, self._mem, m["t"], 1.0 / self.rate_hz, m["theta_deg"], m["theta_ref_deg"],
                      m["theta_ref_dot"], m["theta_ref_ddot"], m["theta_ref_dddot"], m["p_a_bar"] - m["p_b_bar"],
                      m.get("p_s_bar", 0.0), self.i_max)
        lsb = self.dac_lsb
        if lsb > 0.0:
            u = lsb * math.floor(u / lsb + 0.5)
        return float(u)


@register_type("schedule")
class GainSchedule(Controller):
    """PIFF gains scheduled on the number of disc sets (the load inertia).

    ``entries`` maps disc sets (1..7) to a :class:`PIFF`; a plant between two
    scheduled points gets gains interpolated linearly in the inertia (disc
    sets), one outside them the nearest entry's.  ``act`` needs the plant known:
    call :meth:`select` (or use :meth:`for_plant`, which returns the PIFF).

    Parameters
    ----------
    entries : dict of int to PIFF
        Disc sets (1..7; an integer or its text, as in a JSON file) -> the controller tuned for them.
    name : str
        Label in tables and files; an entry picked for a plant is named ``name@disc_sets``.
    basis : str
        Free text saying how the schedule was obtained (``ehas tune`` writes e.g. ``"relay per disc set"``).

    Raises
    ------
    ValueError
        No entries, a key that is not a number of disc sets in 1..7, or an entry that is not a PIFF.

    Examples
    --------
    >>> s = GainSchedule({1: PIFF(Kp=1.0), 3: PIFF(Kp=2.0)}, name="demo")
    >>> s.for_plant(2).Kp, s.for_plant(7).Kp
    (1.5, 2.0)
    """

    kind = "classical"

    def __init__(self, entries: dict, name: str = "schedule", basis: str = ""):
        if not entries:
            raise ValueError("GainSchedule needs at least one entry disc_sets -> PIFF")
        clean = {}
        for key, ctrl in entries.items():
            n = int(key)
            if str(n) != str(key).strip() and n != key:
                raise ValueError(f"GainSchedule: key {key!r} is not a number of disc sets")
            if not 1 <= n <= 7:
                raise ValueError(f"GainSchedule: disc sets {n} outside 1..7")
            if not isinstance(ctrl, PIFF):
                raise ValueError(f"GainSchedule: entry {n} must be a PIFF, got {type(ctrl).__name__}")
            clean[n] = ctrl
        self.entries = dict(sorted(clean.items()))
        self.name = name
        self.basis = basis
        self._active: PIFF | None = None

    @property
    def variant(self) -> str:
        """``schedule of`` and the entries' variants (:attr:`PIFF.variant`), e.g. ``schedule of PI+FF``."""
        return "schedule of " + ", ".join(sorted({c.variant for c in self.entries.values()}))

    def for_plant(self, disc_sets: int) -> PIFF:
        """The PIFF for a plant with ``disc_sets`` sets of discs.

        Parameters
        ----------
        disc_sets : int or float
            Number of disc sets of the plant (proportional to its load inertia).

        Returns
        -------
        PIFF
            An entry's controller, with gains interpolated linearly in the disc sets between the two
            nearest entries (the nearest entry's outside them); its output limit, DAC and rate are the
            lower entry's; named ``name@disc_sets``.
        """
        keys = list(self.entries)
        n = float(disc_sets)
        if n <= keys[0]:
            base = self.entries[keys[0]]
            return replace(base, name=f"{self.name}@{disc_sets}")
        if n >= keys[-1]:
            base = self.entries[keys[-1]]
            return replace(base, name=f"{self.name}@{disc_sets}")
        hi = next(k for k in keys if k >= n)
        lo = max(k for k in keys if k <= n)
        if hi == lo:
            return replace(self.entries[lo], name=f"{self.name}@{disc_sets}")
        w = (n - lo) / (hi - lo)
        a, b = self.entries[lo], self.entries[hi]
        gains = {k: (1 - w) * getattr(a, k) + w * getattr(b, k) for k in GAIN_NAMES}
        return replace(a, **gains, name=f"{self.name}@{disc_sets}")

    def select(self, disc_sets: int) -> "GainSchedule":
        """Use the gains for ``disc_sets`` in :meth:`act` from now on.

        Parameters
        ----------
        disc_sets : int
            Number of disc sets of the plant the schedule will control.

        Returns
        -------
        GainSchedule
            This schedule (for chaining).
        """
        self._active = self.for_plant(disc_sets)
        return self

    def rig_gains(self, disc_sets: int | None = None):
        """The compiled form of the schedule's controller for a plant.

        Parameters
        ----------
        disc_sets : int, optional
            Number of disc sets of the plant; None: the plant chosen with :meth:`select`.

        Returns
        -------
        RigController
            The gains (:meth:`PIFF.rig_gains`) of :meth:`for_plant` ``(disc_sets)``.

        Raises
        ------
        ValueError
            If ``disc_sets`` is None and no plant was selected.
        """
        if disc_sets is None:
            if self._active is None:
                raise ValueError(f"GainSchedule '{self.name}': which disc sets? pass disc_sets or call select() first")
            return self._active.rig_gains()
        return self.for_plant(disc_sets).rig_gains()

    def reset(self) -> None:
        if self._active is not None:
            self._active.reset()

    def act(self, measurement: dict) -> float:
        """Current command, mA, of the selected plant's PIFF (:meth:`select` first).

        Parameters
        ----------
        measurement : dict of str to float
            :data:`~ehas_controllers.base.MEASUREMENT_KEYS` in s, deg, deg/s^k and bar (see
            :meth:`PIFF.act`).

        Returns
        -------
        float
            The current in mA (:meth:`PIFF.act` of the selected entry).

        Raises
        ------
        ValueError
            If no plant was selected.
        """
        if self._active is None:
            raise ValueError(f"GainSchedule '{self.name}': no plant selected; call select(disc_sets) before act()")
        return self._active.act(measurement)

    def to_dict(self) -> dict:
        """JSON-able description; :meth:`from_dict` rebuilds the schedule from it.

        Returns
        -------
        dict
            ``type`` (``"schedule"``), ``kind``, ``name``, ``variant``, ``basis``, gain ``units`` and
            ``entries``: disc sets (text) -> ``gains``, ``variant``, ``i_max`` (mA), ``output_bits``,
            ``rate_hz`` (Hz).
        """
        return {"type": self.type_name, "kind": self.kind, "name": self.name, "variant": self.variant,
                "basis": self.basis, "units": dict(GAIN_UNITS),
                "entries": {str(n): {"gains": c.gains(), "variant": c.variant, "i_max": c.i_max,
                                     "output_bits": c.output_bits, "rate_hz": c.rate_hz}
                            for n, c in self.entries.items()}}

    @classmethod
    def from_dict(cls, data: dict) -> "GainSchedule":
        """Rebuild a schedule from its JSON description (:meth:`to_dict`, a controller file).

        Parameters
        ----------
        data : dict
            ``{"entries": {disc_sets: {"gains": {...}, ...}}, "name": ..., "basis": ...}``; each
            entry as :meth:`PIFF.from_dict` takes it.

        Returns
        -------
        GainSchedule
            The schedule; entry ``k`` is named ``name@k``.

        Raises
        ------
        ValueError
            No entries, or an entry that is not a valid PIFF description (named in the message).
        """
        entries = data.get("entries")
        if not isinstance(entries, dict) or not entries:
            raise ValueError("a schedule needs 'entries': {disc_sets: {gains: {...}}}")
        name = data.get("name", "schedule")
        built = {}
        for k, v in entries.items():
            if not isinstance(v, dict):
                raise ValueError(f"entries[{k!r}] must be an object {{gains: {{...}}}}, got {v!r}")
            try:
                built[k] = PIFF.from_dict({**v, "name": f"{name}@{k}"})
            except ValueError as exc:
                raise ValueError(f"entries[{k!r}]: {exc}") from None
        return cls(built, name=name, basis=data.get("basis", ""))

    def __repr__(self) -> str:
        lines = [f"GainSchedule '{self.name}' over disc sets {list(self.entries)}" + (f" ({self.basis})" if self.basis else "")]
        for n, c in self.entries.items():
            lines.append(f"  {n} sets: " + repr(c).split(": ", 1)[1])
        return "\n".join(lines)


def gains_table(ctrl) -> list[tuple[str, float, str]]:
    """(gain, value, unit) rows of a PIFF, for printing."""
    return [(k, getattr(ctrl, k), GAIN_UNITS[k]) for k in GAIN_NAMES]


def as_array(ctrl: PIFF) -> np.ndarray:
    """The gains in the order of the compiled law :func:`pi_ff_law`."""
    return np.array([getattr(ctrl, k) for k in GAIN_NAMES], dtype=float)
