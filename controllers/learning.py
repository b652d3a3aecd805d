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
  magnitude squared ``1 / (1 + (f / f_c)^(2 n))`` on each harmonic of the cycle.

The design model is the book's plant (``design_model`` None) or a model file of
the rig (docs/model-file.md), read as data.
"""
from __future__ import annotations

import copy
import math
from functools import lru_cache

import numpy as np

from .base import Controller


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
    starts learning from, its design model and its name; and a fresh copy per plant.

    Subclasses call :meth:`_layer` from their ``__init__`` (it checks and sets these, then ``reset()``).
    """

    kind = "classical"

    def _layer(self, base, start_cycle, design_model, name, who: str) -> None:
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
            A fresh copy (same type) whose base loop is ``base.for_plant(disc_sets)``.
        """
        new = copy.copy(self)
        new._loop = copy.deepcopy(self.base.for_plant(disc_sets))
        new.disc_sets = int(disc_sets)
        new.reset()
        return new

    def act(self, measurement: dict) -> float:
        """Current command, mA: the base loop's, plus the learned feed-forward at this phase of the cycle.

        The cycle's error is recorded sample by sample; at the end of each cycle from ``start_cycle`` on,
        the subclass learns from it (``_learn``).

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
        done = self._table.add(m["t"], m["theta_ref_deg"] - m["theta_deg"])
        if done is not None and done[0] >= self.start_cycle:
            self._learn(done[1])
        u = self._loop.act(m) + self._feedforward(m["t"])
        lim = self._loop.i_max
        return min(max(u, -lim), lim)

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
