"""What the controllers that learn the cycle share: the design model, the cycle table, the Q filter.

A sine-test controller that learns (:mod:`.ilc`, :mod:`.harmonic`) adds a
periodic feed-forward current to a fixed-gain loop (a :class:`~.piff.PIFF` or a
:class:`~.piff.GainSchedule`) and corrects it once per reference cycle from the
error of the cycle before.  Three pieces are common to them and live here, once:

* :func:`process_sensitivity` - the response of the crank angle to a current
  added at the plant input with the fixed-gain loop closed,
  ``P(jw) = G / (1 + C G)``, ``G = theta/u`` (deg/mA) the project's one
  linearisation (:class:`ehas_env.simulation.linear_model.LinearPlant`, with the
  loop's pressure feedback and its zero-order-hold/transport delay as a Pade
  approximation) at the condition's operating flow, ``C = Kp + Ki/s``.  An added
  current ``du`` changes the error ``e = theta_ref - theta`` by ``-P du``;
* :class:`CycleTable` - the period cut into ``N = round(rate / f)`` phase bins:
  the bin of a sample, the error of the last whole cycle per bin;
* :class:`CycleLearner` - the layer itself: its fixed-gain base loop, the cycle it starts learning
  from, its design model, its name, and a fresh copy per plant (:meth:`CycleLearner.for_plant`);
* :func:`q_filter` - the robustness filter, zero phase: a Butterworth low-pass
  run forwards and backwards over the periodic signal (``filtfilt``), i.e. its
  magnitude squared ``1 / (1 + (f / f_c)^(2 n))`` on each harmonic of the cycle;
* the **guard** (:class:`CycleLearner`, :data:`GUARD_DEFAULTS`): learning that watches itself.  The
  rms % error of every cycle (the project's metric, :func:`ehas_env.simulation.metrics.percent_errors`,
  on the error the controller sees) is compared with the base loop's (the cycles before the first
  learned one, or ``guard.base_error_pct``) and with the best cycle so far; when it stays above
  ``min(growth x best, base) + floor_pct`` for ``patience`` cycles the controller stops learning and
  restores the feed-forward of its best cycle; when even that stays worse than the base loop for
  ``patience`` cycles it halves the feed-forward, again and again, and after ``halvings`` halvings
  drops it (the base loop alone); worse than ``growth`` x the base loop's error, it drops it at once.  When the
  base loop alone then stays worse than it was (``patience`` cycles above ``base + floor_pct``, or one above
  ``growth`` x base: an oscillation the learning started that the loop keeps) the guard **recovers**: the error
  fed to the base loop is scaled by ``recover_gain`` for ``recover_cycles`` cycles, then ramped back to 1 over as
  many, up to ``recoveries`` times a run.  Each step is an event in ``guard_log`` (and in the controller's JSON
  state, ``learned``);
* the **per-harmonic guard** (the guard's ``harmonic_*`` fields): after every learned cycle the error's
  amplitude at each harmonic of the cycle (:func:`harmonic_amplitudes`, the DFT of the cycle's phase bins) is
  compared with its level on the base loop alone (the largest over cycles 1..:attr:`CycleLearner.first_learned_cycle`)
  and with the cycle before.  A harmonic, learned or not, that grew from the cycle before to above
  ``harmonic_growth`` x its base level plus the larger of ``harmonic_floor_pct`` % of the amplitude and
  ``harmonic_ratio`` x the largest fall of a learned harmonic from its base level (what correcting the
  others brings through a nonlinear plant) shows a learning that diverges: the plant answers there far more
  than the design model says.  From that cycle on, every learned harmonic that grew from the cycle before
  beyond ``harmonic_growth`` x its base level + ``harmonic_floor_pct`` % is taken out of the learned set at
  once (the ILC: a notch in L at it and its component of the table set to zero; the harmonic canceller: its
  U_h set to zero and never moved again), for the rest of the run; the others keep learning.  One event
  ``drop`` per harmonic (``harmonic``, ``harmonic_hz``, why);
* the **repeatability gate** (the guard's ``repeat_*`` fields): learning assumes a process that repeats, and
  learning from cycles that do not repeat is learning noise.  Before the first update the base loop alone runs
  until cycle ``repeat_cycle`` (default 3), and the change of that cycle's error from the cycle before, over the
  harmonics the controller learns (:meth:`CycleLearner._learned_band`), is compared with the error: above
  ``repeat_pct`` % of it and above ``repeat_floor_pct`` % of the amplitude the gate closes, nothing is learned in
  the run and the controller is its base loop exactly (state ``"gated"``, event ``gate``).

The design model is the book's plant (``design_model`` None) or a model file of
the rig (docs/model-file.md), read as data.
"""
from __future__ import annotations

import copy
import math
from functools import lru_cache

import numpy as np

from .base import Controller

#: the guard's parameters (``"guard"`` object of a learning controller's JSON) and their defaults
GUARD_DEFAULTS = {
    "enabled": True,          # - : watch the per-cycle error (false: learn whatever happens)
    "patience": 3,            # cycles: consecutive bad cycles before the guard acts
    "growth": 2.0,            # - : a cycle is bad above growth x the best cycle so far (or the base loop's error)
    "floor_pct": 0.02,        # % : absolute slack on top (an error this small is never bad)
    "halvings": 3,            # - : halvings of the feed-forward before it is dropped (base loop alone)
    "base_error_pct": None,   # % : the base loop's per-cycle rms error if measured; None: its own first cycles
    # the repeatability gate: learning starts only on a base loop whose cycles repeat
    "repeat_cycle": 3,        # cycles: the gate compares this cycle with the one before, both on the base loop alone
    "repeat_pct": 20.0,       # % : cycles do not repeat when their change exceeds this % of the error (null: no gate)
    "repeat_floor_pct": 0.5,  # % of the amplitude: a change from cycle to cycle this small always counts as repeating
    # the per-harmonic guard: a learned harmonic whose error grows beyond its base-loop level is taken out of learning
    "harmonic_growth": 2.0,   # - : dropped above this x its error on the base loop alone (null: no per-harmonic guard)
    "harmonic_floor_pct": 0.05,  # % of the amplitude: absolute slack on top of harmonic_growth x the base level
    "harmonic_ratio": 0.3,    # - : a harmonic diverges above growth x base + max(floor, ratio x the largest fall
                              #     of a learned harmonic from its base level): correcting them raises others
    # the recovery: the base loop alone stays worse than it was (an oscillation the learning started and the loop
    # keeps): its feedback gain is lowered for a while, then ramped back, and the plant falls back to its own cycle
    "recover_gain": 0.5,      # - : the base loop's error gain while recovering, (0, 0.99] (null: no recovery)
    "recover_cycles": 1,      # cycles: held at recover_gain this long, then ramped back to 1 over as long
    "recoveries": 2,          # - : recoveries at most in a run
}
#: what each guard field allows: (low, high, integer); growth > 1, base_error_pct > 0 or null, repeat_pct > 0 or null
_GUARD_RANGES = {"patience": (1, 100, True), "growth": (1.0, 100.0, False), "floor_pct": (0.0, 100.0, False),
                 "halvings": (0, 30, True), "base_error_pct": (0.0, 1e6, False), "repeat_cycle": (2, 100, True),
                 "repeat_pct": (0.0, 1000.0, False), "repeat_floor_pct": (0.0, 100.0, False),
                 "harmonic_growth": (1.0, 1000.0, False), "harmonic_floor_pct": (0.0, 100.0, False),
                 "harmonic_ratio": (0.0, 100.0, False), "recover_gain": (0.0, 0.99, False),
                 "recover_cycles": (1, 100, True), "recoveries": (0, 30, True)}
_NULLABLE = ("base_error_pct", "repeat_pct", "harmonic_growth", "recover_gain")


def harmonic_amplitudes(e: np.ndarray) -> np.ndarray:
    """Amplitude of each harmonic k = 0..N/2 of one cycle's error per phase bin (deg; k = 0: the mean's size).

    Parameters
    ----------
    e : ndarray
        One cycle's error per phase bin, deg (N bins).

    Returns
    -------
    ndarray
        ``2 |DFT_k(e)| / N`` for k >= 1 (``|DFT_k| / N`` at k = 0 and, N even, at N/2), deg.
    """
    a = 2.0 * np.abs(np.fft.rfft(e)) / e.size
    a[0] *= 0.5
    if e.size % 2 == 0:
        a[-1] *= 0.5
    return a


def check_number(value, name: str, lo: float, hi: float, who: str, *, lo_open: bool = False,
                 integer: bool = False) -> float:
    """A learning controller's JSON number: :func:`ehas_env.ranges.check_number` naming ``who`` and the field.

    Parameters
    ----------
    value : object
        The value read from a controller JSON or given in Python.
    name : str
        The field's name in the JSON (e.g. ``"learning.gain"``).
    lo, hi : float
        Allowed range.
    who : str
        The controller type, for the message.
    lo_open : bool
        Exclude ``lo``.
    integer : bool
        A whole number.

    Returns
    -------
    float or int
        The checked value.
    """
    from ehas_env.ranges import check_number as _check

    return _check(value, f"{who}: '{name}'", "", lo, hi, lo_open=lo_open, integer=integer)


def sub_object(data: dict, key: str, allowed) -> dict:
    """An optional nested object of a controller JSON (``"learning"``, ``"q_filter"``) with only ``allowed`` keys.

    Parameters
    ----------
    data : dict
        The controller description.
    key : str
        The nested object's key.
    allowed : sequence of str
        Its allowed keys.

    Returns
    -------
    dict
        The object ({} when absent).
    """
    sub = data.get(key, {})
    if not isinstance(sub, dict):
        raise ValueError(f"'{key}' must be an object with some of {', '.join(allowed)}, got {sub!r}")
    unknown = sorted(set(map(str, sub)) - set(allowed))
    if unknown:
        raise ValueError(f"unknown key(s) {', '.join(unknown)} in '{key}'; expected some of {', '.join(allowed)}")
    return sub


def guard_settings(guard, who: str) -> dict:
    """The guard's settings (:data:`GUARD_DEFAULTS` with what ``guard`` gives), checked.

    Parameters
    ----------
    guard : dict or None
        The ``"guard"`` object of a learning controller (some of :data:`GUARD_DEFAULTS`' keys), None
        for the defaults.
    who : str
        The controller type, for the message.

    Returns
    -------
    dict
        Every guard field: ``enabled`` (bool), ``patience`` (cycles), ``growth`` (-), ``floor_pct`` (%),
        ``halvings`` (-), ``base_error_pct`` (% or None), and the repeatability gate's ``repeat_cycle``
        (cycles), ``repeat_pct`` (% of the error, or None: no gate), ``repeat_floor_pct`` (% of the amplitude),
        and the per-harmonic guard's ``harmonic_growth`` (-, or None: off), ``harmonic_floor_pct`` (% of the
        amplitude) and ``harmonic_ratio`` (-).

    Raises
    ------
    ValueError
        One line naming ``guard.FIELD`` and what it allows.
    """
    guard = sub_object({"guard": {} if guard is None else guard}, "guard", tuple(GUARD_DEFAULTS))
    out = dict(GUARD_DEFAULTS)
    for key, value in guard.items():
        if key == "enabled":
            if not isinstance(value, bool):
                raise ValueError(f"{who}: 'guard.enabled' must be true or false, got {value!r}")
            out[key] = value
        elif key in _NULLABLE and value is None:
            out[key] = None
        else:
            lo, hi, integer = _GUARD_RANGES[key]
            v = check_number(value, f"guard.{key}", lo, hi, who, integer=integer,
                             lo_open=key in ("growth", "base_error_pct", "repeat_pct", "harmonic_growth",
                                                     "recover_gain"))
            out[key] = int(v) if integer else float(v)
    return out


def condition_key(disc_sets: int, amplitude_deg: float, freq_hz: float) -> str:
    """The key of one condition in a learning controller's ``learned`` state: ``"7 sets 30 deg 3 Hz"``."""
    return f"{int(disc_sets)} sets {float(amplitude_deg):g} deg {float(freq_hz):g} Hz"


def base_from_dict(data, who: str):
    """The fixed-gain loop nested in a learning controller's JSON (``"base"``): a PIFF or a schedule.

    Parameters
    ----------
    data : dict
        The ``"base"`` object: a controller description of type ``"piff"`` or ``"schedule"``.
    who : str
        The learning controller's type, for the message.

    Returns
    -------
    PIFF or GainSchedule
        The base loop.
    """
    from .base import controller_from_dict
    from .piff import GainSchedule, PIFF

    if not isinstance(data, dict):
        raise ValueError(f"{who}: 'base' must be a controller object {{\"type\": \"piff\" or \"schedule\", ...}}, "
                         f"got {data!r}")
    if data.get("type", "piff") not in ("piff", "schedule"):
        raise ValueError(f"{who}: 'base' type {data.get('type')!r}: a learning controller runs on a fixed-gain loop, "
                         "'piff' or 'schedule'")
    try:
        base = controller_from_dict({"type": "piff", **data})
    except ValueError as exc:
        raise ValueError(f"{who}: 'base': {exc}") from None
    if not isinstance(base, (PIFF, GainSchedule)):
        raise ValueError(f"{who}: 'base' must be a piff or schedule controller")
    return base


def base_to_dict(base) -> dict:
    """The base loop's JSON description, without the file-level keys."""
    d = base.to_dict()
    d.pop("units", None)
    return d


def design_plant(disc_sets: int, design_model: str | None):
    """The plant a learning controller is designed on: the book's, or a model file's.

    Parameters
    ----------
    disc_sets : int
        Number of disc sets, 1..7.
    design_model : str or None
        Path of a model file (docs/model-file.md); None: the book's reference model.

    Returns
    -------
    Plant
        The design plant.
    """
    from ehas_env.simulation.plant import Plant

    if design_model is None:
        return Plant(disc_sets=disc_sets)
    return Plant(disc_sets=disc_sets, model=design_model)  # a model file is read as data


@lru_cache(maxsize=256)
def _loop_parts(gains: tuple, disc_sets: int, design_model, amplitude_deg: float, freq_hz: float):
    from ehas_env.simulation.linear_model import LinearPlant, operating_flow_lpm

    Kp, Ki, Kv, Ka, Kj, Kdp, dp_hp = gains
    lp = LinearPlant(design_plant(disc_sets, design_model), flow_lpm=operating_flow_lpm(amplitude_deg, freq_hz))
    return lp.tf(Kdp, dp_hp), Kp, Ki


def process_sensitivity(piff, disc_sets: int, amplitude_deg: float, freq_hz: float, w,
                        design_model: str | None = None) -> np.ndarray:
    """P(jw) = G/(1 + C G), deg of crank angle per mA added at the plant input, the fixed-gain loop closed.

    Parameters
    ----------
    piff : PIFF
        The fixed-gain loop (its Kp, Ki give C = Kp + Ki/s; Kdp, dp_hp are closed inside G).
    disc_sets : int
        Number of disc sets of the design plant.
    amplitude_deg, freq_hz : float
        The condition (deg, Hz): the linearisation's operating flow is its mean valve flow.
    w : array_like
        Angular frequencies, rad/s (> 0).
    design_model : str, optional
        Model file of the design plant; None: the book's.

    Returns
    -------
    ndarray of complex
        P(jw), deg/mA.
    """
    g, kp, ki = _loop_parts(tuple(float(v) for v in piff.gains().values()), int(disc_sets), design_model,
                            float(amplitude_deg), float(freq_hz))
    s = 1j * np.asarray(w, dtype=float)
    G = np.asarray(g(s), dtype=complex)
    C = kp + ki / s
    return G / (1.0 + C * G)


def q_filter(freq_hz, cutoff_hz: float, order: int) -> np.ndarray:
    """Zero-phase robustness filter: a Butterworth low-pass run forwards and backwards (filtfilt).

    Parameters
    ----------
    freq_hz : array_like
        Frequencies, Hz.
    cutoff_hz : float
        The Butterworth's corner, Hz.
    order : int
        The Butterworth's order (the zero-phase filter has twice that).

    Returns
    -------
    ndarray
        ``|H(j 2 pi f)|^2 = 1 / (1 + (f / f_c)^(2 order))``: real, in (0, 1], no phase.
    """
    f = np.abs(np.asarray(freq_hz, dtype=float))
    return 1.0 / (1.0 + (f / cutoff_hz) ** (2 * order))


class CycleTable:
    """One reference period cut into phase bins; collects the error of the running cycle.

    Parameters
    ----------
    freq_hz : float
        Reference frequency, Hz.
    rate_hz : float
        Control rate, Hz; the table has ``N = max(8, round(rate / f))`` bins.
    """

    def __init__(self, freq_hz: float, rate_hz: float):
        self.freq_hz = float(freq_hz)
        self.n = max(8, int(round(rate_hz / freq_hz)))
        self.harmonic_hz = self.freq_hz * np.arange(self.n // 2 + 1)  # of np.fft.rfft over the table
        self.cycle = 0
        self.bin, self.frac = 0, 0.0  # the bin of the last sample added and its position in it
        self._sum = np.zeros(self.n)
        self._count = np.zeros(self.n)

    def locate(self, t: float) -> tuple[int, int, float]:
        """(cycle index, bin, fraction of the way to the next bin) of the sample at ``t`` s."""
        x = t * self.freq_hz + 1e-9
        c = int(math.floor(x))
        p = (x - c) * self.n
        b = min(int(p), self.n - 1)
        return c, b, min(p - b, 1.0)

    def add(self, t: float, error: float):
        """Record the error (deg) at ``t``; returns the finished cycle's (index, error per bin) or None.

        The sample is shared between its two neighbouring bins in proportion to its phase (linear
        interpolation's transpose), so the bins hold the error at their own phases whether or not
        the period is a whole number of samples.

        Parameters
        ----------
        t : float
            Sample time, s.
        error : float
            theta_ref - theta, deg.

        Returns
        -------
        tuple of (int, ndarray) or None
            When ``t`` starts a new cycle: the index of the cycle just finished and its mean error
            per bin (bins no sample reached interpolated from their neighbours, circularly).
        """
        c, b, w = self.locate(t)
        self.bin, self.frac = b, w
        done = None
        if c != self.cycle:
            done = (self.cycle, self._finish())
            self.cycle = c
        b1 = (b + 1) % self.n
        self._sum[b] += (1.0 - w) * error
        self._count[b] += 1.0 - w
        self._sum[b1] += w * error
        self._count[b1] += w
        return done

    def value(self, table: np.ndarray) -> float:
        """A per-bin table (length N) at the phase of the last sample added, linearly interpolated."""
        b, w = self.bin, self.frac
        return float((1.0 - w) * table[b] + w * table[(b + 1) % self.n])

    def at(self, t: float, table: np.ndarray) -> tuple[int, float]:
        """(cycle index, the per-bin ``table`` at the phase of ``t`` s, linearly interpolated) without recording.

        Parameters
        ----------
        t : float
            Time, s (phase 0 at t = 0).
        table : ndarray
            One value per bin (length N).

        Returns
        -------
        tuple of (int, float)
            The cycle ``t`` falls in and the interpolated value.
        """
        c, b, w = self.locate(t)
        return c, float((1.0 - w) * table[b] + w * table[(b + 1) % self.n])

    def _finish(self) -> np.ndarray:
        hit = self._count > 1e-9
        e = np.zeros(self.n)
        if hit.any():
            idx = np.flatnonzero(hit)
            e[hit] = self._sum[hit] / self._count[hit]
            if not hit.all():
                miss = np.flatnonzero(~hit)
                e[miss] = np.interp(miss, idx, e[idx], period=self.n)
        self._sum[:] = 0.0
        self._count[:] = 0.0
        return e


class CycleLearner(Controller):
    """What a controller that learns the cycle holds besides its law: a fixed-gain base loop, the cycle it
    starts learning from, its design model and its name; a fresh copy per plant; and the **guard**.

    The guard (module docstring; parameters :data:`GUARD_DEFAULTS`) is one law for every learning
    controller: at the end of each cycle the cycle's rms % error (``cycle_error_pct``, the error the
    controller sees: reference minus sensed angle) is compared with the base loop's (``base_error_pct``:
    the cycles run on the base loop alone, 1..:attr:`first_learned_cycle`, or ``guard.base_error_pct``) and the
    best so far; its states are ``"learning"``, ``"stopped"`` (the best cycle's feed-forward restored, no more
    learning), ``"halved"`` (a fraction ``scale`` of it), ``"base"`` (none: the base loop alone) and ``"gated"``
    (the repeatability gate closed: nothing was learned).  In ``"base"``, ``patience`` cycles above
    ``base + floor_pct`` (one above ``growth x base + floor_pct``) start a **recovery** (event ``recover``): the
    base loop's feedback works on ``recover_gain`` x the error for ``recover_cycles`` cycles, then on a gain
    ramped back to 1 over as many (:meth:`_loop_gain`), at most ``recoveries`` times a run.
    Before the first update the **repeatability gate** (:meth:`_gate`) compares cycle ``repeat_cycle`` with the
    one before it, both on the base loop alone: when they do not repeat the state is ``"gated"`` and nothing
    is learned in the run (``repeat_pct`` null or ``enabled`` false: no gate, learning from ``start_cycle``).
    While learning, a cycle is bad above ``min(growth x best, base) + floor_pct``; once stopped, above
    ``base + floor_pct`` (a halving); ``patience`` bad cycles in a row make one step.  One cycle above
    ``growth x base + floor_pct`` (far worse than the base loop: never noise) is enough: learning stops at
    once, and once stopped the feed-forward is dropped at once.
    Before the whole-cycle law, the **per-harmonic guard** (:meth:`_watch_harmonics`) takes the harmonics that
    diverge out of the learned set (``dropped``, event ``drop``) while the others keep learning.
    Every step is appended to ``guard_log`` (dicts: ``cycle``, ``event``, ``cycle_error_pct``,
    ``best_error_pct``, ``base_error_pct``, ``scale``, ``why``; a ``drop`` also ``harmonic`` and ``harmonic_hz``).

    What each run learned is kept per condition (:func:`condition_key`) in a record shared by the
    controller and its :meth:`for_plant` copies and written by :meth:`learned_state` into the JSON
    (``"learned"``): the final feed-forward, the per-cycle errors and the guard's events.

    Subclasses call :meth:`_layer` from their ``__init__`` (it checks and sets these, then ``reset()``) and
    implement ``_begin``, ``_learn``, ``_feedforward``, ``_snapshot`` / ``_restore`` (the learned signal),
    ``_scale``, ``_table_of`` (the signal over one period, for drive files) and ``_learned_band`` (the
    harmonics it learns, for the gate).
    """

    kind = "classical"

    def _layer(self, base, start_cycle, design_model, name, who: str, guard=None, learned=None) -> None:
        """Check and set the layer's common parameters (one-line errors naming ``who`` and the field)."""
        self._who = who
        from .piff import GainSchedule, PIFF

        if not isinstance(base, (PIFF, GainSchedule)):
            raise ValueError(f"{who}: base must be a PIFF or GainSchedule (a fixed-gain loop), got {type(base).__name__}")
        self.base = base
        self.start_cycle = int(check_number(start_cycle, "start_cycle", 0, 100, who, integer=True))
        if design_model is not None and not (isinstance(design_model, str) and design_model.strip()):
            raise ValueError(f"{who}: 'design_model' must be a model file's path or null, got {design_model!r}")
        self.design_model = design_model
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"{who}: 'name' must be a non-empty text, got {name!r}")
        self.name = name
        self.guard = guard_settings(guard, who)
        self._memory: dict = {}  # condition key -> what was learned there; shared with the for_plant copies
        if learned is not None:
            self._memory.update(read_learned(learned, who))
        self.disc_sets: int | None = None
        self._loop = base if isinstance(base, PIFF) else None
        self.reset()

    def for_plant(self, disc_sets: int) -> "CycleLearner":
        """A fresh copy for a plant with ``disc_sets`` disc sets (the base loop's entry; the design plant).

        Parameters
        ----------
        disc_sets : int
            Number of disc sets of the plant, 1..7.

        Returns
        -------
        CycleLearner
            A fresh copy (same type) whose base loop is ``base.for_plant(disc_sets)``; what it learns is
            recorded in this controller's ``learned`` state too.
        """
        new = copy.copy(self)
        new._loop = copy.deepcopy(self.base.for_plant(disc_sets))
        new.disc_sets = int(disc_sets)
        new.reset()
        return new

    def reset(self) -> None:
        """Forget the run: the base loop's state, the table, what was learned and the guard's state."""
        if self._loop is not None:
            self._loop.reset()
        self._table = None
        self._reset_guard()
        self._reset_learning()

    def _reset_guard(self) -> None:
        self.cycle_error_pct: list[float] = []  # rms % error of each finished cycle (the controller's view)
        self.guard_log: list[dict] = []
        self.guard_state = "learning"
        self.base_error_pct = self.guard["base_error_pct"]
        self._best = (math.inf, None, -1)  # (error %, snapshot, cycle)
        self._bad = 0
        self._halvings = 0
        self.scale = 1.0
        self._sums = [0.0, 0, 0.0]  # sum e^2 (deg^2), samples, max|e| (deg) of the running cycle
        self._amp = self._freq = None
        self._prev_e = None  # the error per bin of the base-loop cycle the gate compares with (deg)
        self._base_amps = None  # per harmonic: largest error amplitude of the base-loop cycles (deg)
        self._prev_amps = None  # per harmonic: the last cycle's error amplitude (deg)
        self._unlearned = None  # the learned signal before the first update (nothing learned: zero)
        self.dropped = np.zeros(0, dtype=bool)  # per harmonic k of the table: taken out of learning by the guard
        self.diverged: dict | None = None  # the per-harmonic guard's trigger (cycle, harmonic, amplitude_deg, ...)
        self.repeat: dict | None = None  # the gate's measurement (cycle, change_pct, ratio_pct, open)
        self._recover_t0 = None  # s: start of the running recovery (None: none)
        self._recoveries = 0

    @property
    def gated(self) -> bool:
        """Whether the repeatability gate is on (``guard.enabled`` and ``guard.repeat_pct`` not null)."""
        return bool(self.guard["enabled"] and self.guard["repeat_pct"] is not None)

    @property
    def first_learned_cycle(self) -> int:
        """The first cycle learned from: ``start_cycle``, or with the gate on not before ``guard.repeat_cycle``."""
        return max(self.start_cycle, self.guard["repeat_cycle"]) if self.gated else self.start_cycle

    def _reset_learning(self) -> None:
        """Clear the subclass's learned signal (called by :meth:`reset`)."""

    def act(self, measurement: dict) -> float:
        """Current command, mA: the base loop's, plus the learned feed-forward at this phase of the cycle.

        The cycle's error is recorded sample by sample; at the end of each cycle its rms % error goes to
        the guard, and from ``start_cycle`` on, while the guard lets it, the subclass learns from it
        (``_learn``).

        Parameters
        ----------
        measurement : dict of str to float
            :data:`~ehas_controllers.base.MEASUREMENT_KEYS` (s, deg, deg/s^k, bar) plus the
            reference's ``amplitude_deg`` (deg) and ``freq_hz`` (Hz).

        Returns
        -------
        float
            The current in mA, clipped to the base loop's +-``i_max``.
        """
        m = measurement
        if self._table is None:
            self._start(m)
        e = m["theta_ref_deg"] - m["theta_deg"]
        done = self._table.add(m["t"], e)
        if done is not None:
            self._end_of_cycle(done[0], done[1], m["t"])
        sums = self._sums
        sums[0] += e * e
        sums[1] += 1
        if abs(e) > sums[2]:
            sums[2] = abs(e)
        if self._recover_t0 is not None:
            g = self._loop_gain(m["t"])
            if g != 1.0:  # the base loop sees g x the error: its P and I act on less, its damping is as it was
                m = dict(m, theta_deg=m["theta_ref_deg"] - g * e)
        u = self._loop.act(m) + self._feedforward(m["t"])
        lim = self._loop.i_max
        return min(max(u, -lim), lim)

    def _end_of_cycle(self, cycle: int, e: np.ndarray, t: float) -> None:
        """A cycle finished at ``t`` (s): its error to the guard, then (if the guard lets it) to the learning law."""
        from ehas_env.simulation.metrics import percent_errors

        s2, n, peak = self._sums
        self._sums = [0.0, 0, 0.0]
        err = percent_errors(s2, n, peak, self._amp)["rms_error_pct"]
        self.cycle_error_pct.append(err)
        first = self.first_learned_cycle
        amps = harmonic_amplitudes(e)
        if cycle <= first and (cycle >= 1 or first == 0):  # a cycle on the base loop alone (not the fade-in)
            self._base_amps = amps if self._base_amps is None else np.maximum(self._base_amps, amps)
        if cycle < first:
            self._prev_e = e.copy()  # the gate compares the first learned cycle with this one
            self._prev_amps = amps
            return
        if cycle == first:  # the last cycle on the base loop alone: its error is the base loop's
            if self.guard["base_error_pct"] is None:
                base = self.cycle_error_pct[1:cycle + 1] or self.cycle_error_pct[:1]
                self.base_error_pct = float(np.sqrt(np.mean(np.square(base))))
            self._best = (err, self._snapshot(), cycle)
            self._unlearned = self._snapshot()  # nothing learned yet: what the per-harmonic guard puts back
            if self.gated and not self._gate(cycle, e):
                self._remember(cycle)
                return
        elif self.guard["enabled"]:
            if self.guard_state == "learning" and self.guard["harmonic_growth"] is not None:
                self._watch_harmonics(cycle, amps)
            self._watch(cycle, err, t)
        self._prev_amps = amps
        if self.guard_state == "learning":
            self._learn(e)
        self._remember(cycle)

    def _watch_harmonics(self, cycle: int, amps: np.ndarray) -> None:
        """The per-harmonic guard after learned cycle ``cycle`` (module docstring): drop the harmonics that grew.

        Once a harmonic k >= 1, learned or not, grew from the cycle before to above ``harmonic_growth`` x its
        level on the base loop alone + max(``harmonic_floor_pct`` % of the amplitude, ``harmonic_ratio`` x the
        largest fall of a learned harmonic from its base level) (``diverged`` records the first such), every
        learned harmonic (weight > 0 in :meth:`_learned_band`, k >= 1, not dropped yet) that grew from the cycle
        before to above ``harmonic_growth`` x its base level + ``harmonic_floor_pct`` % of the amplitude is taken
        out of the learned set for the rest of the run: its learned component goes back to zero, its value before
        the first update (:meth:`_with_harmonics`, in the best cycle's snapshot too) and it is not learned again
        (:meth:`_notch`).  One event ``drop`` per harmonic.

        Parameters
        ----------
        cycle : int
            The cycle just finished (after the first learned update).
        amps : ndarray
            Its error's amplitude per harmonic k = 0..N/2 of the cycle table, deg (:func:`harmonic_amplitudes`).
        """
        g = self.guard
        band = self._learned_band()
        band[0] = 0.0  # the mean is the base loop's integrator's
        floor = g["harmonic_growth"] * self._base_amps + g["harmonic_floor_pct"] * 1e-2 * self._amp
        rising = amps > self._prev_amps
        rising[0] = False
        if self.diverged is None:  # has any harmonic, learned or not, grown beyond what the correction explains?
            fell = float(np.max(np.where(band > 0.0, self._base_amps - amps, 0.0)))  # the largest correction so far
            limit = g["harmonic_growth"] * self._base_amps + np.maximum(g["harmonic_floor_pct"] * 1e-2 * self._amp,
                                                                         g["harmonic_ratio"] * fell)
            over = rising & (amps > limit)
            if not over.any():
                return
            k = int(np.argmax(np.where(over, amps - limit, -np.inf)))
            self.diverged = {"cycle": int(cycle), "harmonic": k, "amplitude_deg": float(amps[k]),
                             "limit_deg": float(limit[k]), "fell_deg": fell}
        ks = np.flatnonzero((band > 0.0) & rising & (amps > floor) & ~self.dropped)
        if ks.size == 0:
            return
        self.dropped[ks] = True
        self._restore(self._with_harmonics(self._snapshot(), self._unlearned, ks))
        self._best = (self._best[0], self._with_harmonics(self._best[1], self._unlearned, ks), self._best[2])
        self._notch(ks)
        f, d = self._table.freq_hz, self.diverged
        why = (f"harmonic {d['harmonic']} ({d['harmonic'] * f:g} Hz) diverged at cycle {d['cycle']}: "
               f"{d['amplitude_deg']:.3g} deg, above {g['harmonic_growth']:g} x its level on the base loop alone + "
               f"the larger of {g['harmonic_floor_pct']:g} % of the amplitude and {g['harmonic_ratio']:g} x the "
               f"largest fall of a learned harmonic from its base level ({d['fell_deg']:.3g} deg), "
               f"{d['limit_deg']:.3g} deg")
        for k in ks:
            self._event(cycle, "drop", self.cycle_error_pct[-1],
                        f"harmonic {k} ({k * f:g} Hz) grew to {amps[k]:.3g} deg from {self._prev_amps[k]:.3g} deg "
                        f"the cycle before, above {g['harmonic_growth']:g} x its {self._base_amps[k]:.3g} deg on the "
                        f"base loop alone + {g['harmonic_floor_pct']:g} % of the amplitude ({floor[k]:.3g} deg), and "
                        f"{why}: taken out of learning, its learned component put back to zero (the base loop's)",
                        harmonic=int(k), harmonic_hz=float(k * f))

    def _gate(self, cycle: int, e: np.ndarray) -> bool:
        """The repeatability gate before the first update: do the base loop's cycles repeat? (class docstring)

        Parameters
        ----------
        cycle : int
            The cycle just finished on the base loop alone (``first_learned_cycle``).
        e : ndarray
            Its error per phase bin, deg; ``self._prev_e`` holds the cycle before's.

        Returns
        -------
        bool
            True: learning may start. False: the gate closed (state ``"gated"``, event ``gate``): nothing is
            learned in this run, the controller runs its base loop alone.
        """
        g = self.guard
        band = self._learned_band()  # weight of each harmonic k = 0..N/2 of the table in what is learned

        def rms(x):  # rms (deg) of the periodic signal x restricted to the learned harmonics (Parseval)
            X = np.abs(band * np.fft.rfft(x)) ** 2
            twice = np.full(X.size, 2.0)
            twice[0] = 1.0
            if x.size % 2 == 0:
                twice[-1] = 1.0
            return float(np.sqrt(np.sum(twice * X)) / x.size)

        change, level = rms(e - self._prev_e), rms(e)
        change_pct = 100.0 * change / self._amp
        ratio_pct = 100.0 * change / max(level, 1e-300)
        is_open = not (ratio_pct > g["repeat_pct"] and change_pct > g["repeat_floor_pct"])
        self.repeat = {"cycle": int(cycle), "change_pct": change_pct, "ratio_pct": ratio_pct, "open": is_open}
        if not is_open:
            self.guard_state = "gated"
            self._event(cycle, "gate", self.cycle_error_pct[-1],
                        f"the base loop's cycles do not repeat: {ratio_pct:.3g} % change from cycle {cycle - 1} to "
                        f"cycle {cycle} over the harmonics learned ({change_pct:.3g} % of the amplitude; above "
                        f"{g['repeat_pct']:g} % and {g['repeat_floor_pct']:g} %); nothing learned: the base loop alone")
        return is_open

    def _learned_band(self) -> np.ndarray:
        """Weight (0..1) of each harmonic k = 0..N/2 of the cycle table in what the controller learns."""
        raise NotImplementedError

    def _watch(self, cycle: int, err: float, t: float) -> None:
        """The guard's law (class docstring) after cycle ``cycle``, ended at ``t`` s, whose rms error was ``err`` %."""
        g, base = self.guard, self.base_error_pct
        if self.guard_state == "gated":
            return
        if self.guard_state == "learning" and err < self._best[0]:
            self._best = (err, self._snapshot(), cycle)
        best = self._best[0]
        if self.guard_state == "learning":
            limit = min(g["growth"] * best, base) + g["floor_pct"]
        else:  # stopped, halved or base: only worse than the base loop calls for more
            limit = base + g["floor_pct"]
        if self.guard_state == "base" and (g["recover_gain"] is None or self._recover_t0 is not None
                                           or self._recoveries >= g["recoveries"]):
            self._bad = 0  # no recovery to start: none allowed, one running, or all used
            return
        if err <= limit:
            self._bad = 0
            return
        gross = err > g["growth"] * base + g["floor_pct"]  # far worse than the base loop: no waiting
        self._bad = g["patience"] if gross else self._bad + 1
        if self._bad < g["patience"]:
            return
        self._bad = 0
        if self.guard_state == "base":
            self._recover(cycle, err, t)
        elif self.guard_state == "learning":
            self._restore(self._best[1])
            self.guard_state = "stopped"
            why = (f"a cycle at {err:.4g} %, above {g['growth']:g} x the base loop's {base:.4g} % + "
                   f"{g['floor_pct']:g} %" if gross else
                   f"{g['patience']} cycles above {limit:.4g} % (the smaller of {g['growth']:g} x the best "
                   f"{best:.4g} % and the base loop's {base:.4g} %, + {g['floor_pct']:g} %)")
            self._event(cycle, "stop", err, f"{why}: learning stopped, the feed-forward of cycle {self._best[2]} "
                        "restored")
        elif gross:  # far worse than the base loop even so: no halving steps
            self.scale = 0.0
            self._scale(0.0)
            self.guard_state = "base"
            self._event(cycle, "base", err, f"above {g['growth']:g} x the base loop's {base:.4g} % (+ "
                        f"{g['floor_pct']:g} %) after the stop: feed-forward dropped, the base loop alone")
        elif self._halvings < g["halvings"]:
            self._halvings += 1
            self.scale *= 0.5
            self._scale(0.5)
            self.guard_state = "halved"
            self._event(cycle, "halve", err, f"{g['patience']} cycles worse than the base loop ({base:.4g} % + "
                        f"{g['floor_pct']:g} %): feed-forward halved (x{self.scale:g})")
        else:
            self.scale = 0.0
            self._scale(0.0)
            self.guard_state = "base"
            self._event(cycle, "base", err, f"{g['patience']} cycles worse than the base loop after "
                        f"{g['halvings']} halvings: feed-forward dropped, the base loop alone")

    def _loop_gain(self, t: float) -> float:
        """The base loop's error gain at ``t`` (s) during a recovery: ``recover_gain`` for ``recover_cycles``
        cycles from its start, then a linear ramp to 1 over as many; 1 outside one."""
        g, n = self.guard["recover_gain"], self.guard["recover_cycles"]
        x = (t - self._recover_t0) * self._freq / n  # recovery's length in units of its hold
        if x < 1.0:
            return g
        if x < 2.0:
            return g + (1.0 - g) * (x - 1.0)
        self._recover_t0 = None
        return 1.0

    def _recover(self, cycle: int, err: float, t: float) -> None:
        """Start a recovery at ``t`` (s), after cycle ``cycle`` (``err`` %) on the base loop alone stayed worse than the
        base loop was (class docstring)."""
        g = self.guard
        self._recoveries += 1
        self._recover_t0 = t
        n = g["recover_cycles"]
        self._event(cycle, "recover", err, f"the base loop alone at {err:.4g} %, worse than its "
                    f"{self.base_error_pct:.4g} % (+ {g['floor_pct']:g} %): its feedback on {g['recover_gain']:g} x "
                    f"the error for {n} cycle{'s' if n > 1 else ''}, then ramped back over as many "
                    f"(recovery {self._recoveries} of {g['recoveries']})")

    def _event(self, cycle: int, event: str, err: float, why: str, **extra) -> None:
        self.guard_log.append({"cycle": int(cycle), "event": event, "cycle_error_pct": float(err),
                               "best_error_pct": float(self._best[0]), "base_error_pct": float(self.base_error_pct),
                               "scale": float(self.scale), **extra, "why": why})

    def _remember(self, cycle: int) -> None:
        """Record this run's state for its condition in the shared ``learned`` record."""
        key = condition_key(self.disc_sets, self._amp, self._freq)
        self._memory[key] = {"disc_sets": int(self.disc_sets), "amplitude_deg": float(self._amp),
                             "freq_hz": float(self._freq), "cycles": int(cycle) + 1,
                             "cycle_error_pct": list(self.cycle_error_pct),
                             "base_error_pct": self.base_error_pct, "guard_state": self.guard_state,
                             "scale": self.scale, "events": list(self.guard_log), "repeat": self.repeat,
                             "dropped_harmonics": [int(k) for k in np.flatnonzero(self.dropped)],
                             "feedforward": self._feedforward_state}

    @property
    def _feedforward_state(self):
        """The learned signal as stored (a copy; the subclass's form), for :meth:`learned_state`."""
        raise NotImplementedError

    def learned_state(self) -> list[dict]:
        """What each run learned, one record per condition (the JSON's ``"learned"``).

        Returns
        -------
        list of dict
            Per condition: ``disc_sets``, ``amplitude_deg`` (deg), ``freq_hz`` (Hz), ``cycles`` (cycles
            run), ``cycle_error_pct`` (rms % per cycle, the controller's view), ``base_error_pct`` (%),
            ``guard_state``, ``scale`` (-), ``events`` (the guard's) and ``feedforward`` (the subclass's
            learned signal: ``{"table_mA": [...]}`` over the period's phase bins, or
            ``{"harmonics": [[re, im] mA, ...]}``).
        """
        out = []
        for key in sorted(self._memory, key=lambda k: (self._memory[k]["disc_sets"], self._memory[k]["freq_hz"],
                                                       self._memory[k]["amplitude_deg"])):
            rec = dict(self._memory[key])
            ff = rec["feedforward"]
            rec["feedforward"] = ({"table_mA": [float(f"{x:.9g}") for x in np.asarray(ff)]} if not np.iscomplexobj(ff)
                                  else {"harmonics": [[float(z.real), float(z.imag)] for z in np.asarray(ff)]})
            rec["cycle_error_pct"] = [float(f"{x:.6g}") for x in rec["cycle_error_pct"]]
            out.append(rec)
        return out

    def feedforward_table(self, key: str, rate_hz: float | None = None) -> np.ndarray:
        """The feed-forward learned at one condition over one period, mA per phase bin (a drive file's table).

        Parameters
        ----------
        key : str
            The condition (:func:`condition_key`), one of the ``learned`` records.
        rate_hz : float, optional
            Control rate, Hz (the table has ``round(rate / f)`` bins); default: the base loop's.

        Returns
        -------
        ndarray
            The current at phase ``k / N`` of the period, k = 0..N-1, mA (after the guard's scale).
        """
        if key not in self._memory:
            raise ValueError(f"{self._who} '{self.name}': nothing learned at {key}; learned at: "
                             f"{', '.join(sorted(self._memory)) or 'no condition (run it first)'}")
        rec = self._memory[key]
        rate = float(rate_hz) if rate_hz is not None else self.base.for_plant(rec["disc_sets"]).rate_hz
        return self._table_of(rec["feedforward"], CycleTable(rec["freq_hz"], rate))

    def _table_of(self, feedforward, table: "CycleTable") -> np.ndarray:
        """The stored learned signal as a table over ``table``'s phase bins, mA."""
        raise NotImplementedError

    def _start(self, m: dict) -> None:
        """The first sample of a run: check the plant and the measurement, then the subclass's ``_begin``."""
        from .base import check_measurement

        if self._loop is None or self.disc_sets is None:
            raise ValueError(f"{self._who} '{self.name}': which plant? call for_plant(disc_sets) before running it")
        check_measurement(m, type(self).__name__)
        if "freq_hz" not in m or "amplitude_deg" not in m:
            raise ValueError(f"{type(self).__name__}.act: measurement has no 'freq_hz'/'amplitude_deg'; a learning "
                             "controller needs the reference's period (Plant.simulate_closed_loop passes them)")
        self._table = CycleTable(float(m["freq_hz"]), self._loop.rate_hz)
        self._amp, self._freq = float(m["amplitude_deg"]), float(m["freq_hz"])
        self.dropped = np.zeros(self._table.n // 2 + 1, dtype=bool)
        try:
            self._begin(float(m["amplitude_deg"]), float(m["freq_hz"]))
        except BaseException:
            self._table = None  # a refused design leaves the controller as it was: the next run starts again
            raise

    def _begin(self, amplitude_deg: float, freq_hz: float) -> None:
        """Design for this reference and clear what is learned (``self._table`` is set)."""
        raise NotImplementedError

    def _learn(self, e: np.ndarray) -> None:
        """Learn from the last whole cycle's error ``e`` (deg, one value per phase bin)."""
        raise NotImplementedError

    def _feedforward(self, t: float) -> float:
        """The learned current at time ``t``, mA."""
        raise NotImplementedError

    def _snapshot(self):
        """A copy of the learned signal (what :meth:`_restore` puts back)."""
        raise NotImplementedError

    def _restore(self, snapshot) -> None:
        """Put back a learned signal taken by :meth:`_snapshot`."""
        raise NotImplementedError

    def _scale(self, factor: float) -> None:
        """Multiply the learned signal by ``factor``."""
        raise NotImplementedError

    def _with_harmonics(self, snapshot, source, ks: np.ndarray):
        """A copy of the learned signal ``snapshot`` whose harmonics ``ks`` (of the cycle table) are ``source``'s."""
        raise NotImplementedError

    def _notch(self, ks: np.ndarray) -> None:
        """Learn nothing more at harmonics ``ks`` of the cycle table (``self.dropped`` is already set)."""
        raise NotImplementedError

    def guard_to_dict(self) -> dict:
        """The guard's settings as written in the JSON (``"guard"``)."""
        return dict(self.guard)


def read_learned(learned, who: str) -> dict:
    """A learning controller's ``"learned"`` records (:meth:`CycleLearner.learned_state`), read back as data.

    Parameters
    ----------
    learned : list of dict
        The records.
    who : str
        The controller type, for the message.

    Returns
    -------
    dict
        Condition key -> record (``feedforward`` as an ndarray: real table or complex harmonics).

    Raises
    ------
    ValueError
        One line naming ``learned[i].FIELD``.
    """
    from ehas_env.ranges import check_field

    if not isinstance(learned, list):
        raise ValueError(f"{who}: 'learned' must be a list of records (disc_sets, amplitude_deg, freq_hz, "
                         f"feedforward, ...), got {type(learned).__name__}")
    out = {}
    for i, rec in enumerate(learned):
        where = f"{who}: 'learned[{i}]"
        if not isinstance(rec, dict):
            raise ValueError(f"{where}' must be an object, got {rec!r}")
        for k in ("disc_sets", "amplitude_deg", "freq_hz", "feedforward"):
            if k not in rec:
                raise ValueError(f"{where}' has no '{k}'")
        n = check_field("disc_sets", rec["disc_sets"], f"{where}.disc_sets'")
        a = check_field("amplitude_deg", rec["amplitude_deg"], f"{where}.amplitude_deg'")
        f = check_field("freq_hz", rec["freq_hz"], f"{where}.freq_hz'")
        ff = rec["feedforward"]
        try:
            if isinstance(ff, dict) and set(ff) == {"table_mA"}:
                arr = np.asarray(ff["table_mA"], dtype=float)
                ok = arr.ndim == 1 and arr.size >= 8
            elif isinstance(ff, dict) and set(ff) == {"harmonics"}:
                h = np.asarray(ff["harmonics"], dtype=float)
                ok = h.ndim == 2 and h.shape[1] == 2 and h.shape[0] >= 1
                arr = h[:, 0] + 1j * h[:, 1] if ok else h
            else:
                ok = False
        except (TypeError, ValueError):
            ok = False
        if not ok or not np.all(np.isfinite(arr)):
            raise ValueError(f"{where}.feedforward' must be {{\"table_mA\": [>= 8 finite numbers]}} or "
                             f"{{\"harmonics\": [[re, im], ...]}} (mA)")
        out[condition_key(n, a, f)] = {**rec, "disc_sets": int(n), "amplitude_deg": float(a), "freq_hz": float(f),
                                       "feedforward": arr}
    return out
