"""Iterative learning control (ILC) of the sine test, on top of a fixed-gain loop.

A feed-forward current table over one reference period (:class:`~.learning.CycleTable`)
is added to the output of a fixed-gain loop (PI+FF, a gain schedule, with or
without pressure feedback) and updated once per cycle from the last cycle's
error (Bristow, Tharayil & Alleyne 2006, "A survey of iterative learning
control", IEEE Control Systems 26(3))::

    u_{j+1} = Q (u_j + L e_j)

* ``L``, the learning filter, from the model's linearisation: the inverse of the
  process sensitivity ``P = G/(1 + C G)`` (:func:`~.learning.process_sensitivity`)
  times a learning gain (``"inverse"``), or a gain with a phase lead of
  ``lead_ms`` (``"lead"``, the classic phase-lead ILC);
* ``Q``, the robustness filter: a Butterworth low-pass applied forwards and
  backwards, zero phase (:func:`~.learning.q_filter`), and optionally nothing at all above
  ``stop_hz`` (``q_filter.stop_hz``): where the plant's response has fallen far, ``L = gain / P``
  is large and what does not repeat there (sample instants that wander, sensor noise) would be
  learned into a large current that a wandering hold turns into more of it;
* both applied non-causally over the whole recorded cycle, on its harmonics.

Before a run learns anything the monotonic-convergence condition
``sup_k |Q(jw_k) (1 - L(jw_k) P(jw_k))| < 1`` is evaluated on the design model at
every harmonic ``w_k = 2 pi k f`` the table can hold (k = 1..N/2: for a periodic
table that is its whole frequency axis; the mean, k = 0, is the base loop's
integrator's), and a design that fails it is refused with a one-line error.

The table learns from the end of cycle ``start_cycle`` (default 1: the
reference's fade-in cycle is not periodic and is not learned from).

Examples
--------
>>> from ehas_controllers.ilc import ILC
>>> from ehas_controllers.piff import PIFF
>>> c = ILC(PIFF.book(), gain=0.8)
>>> c.to_dict()["learning"]
{'filter': 'inverse', 'gain': 0.8, 'lead_ms': 0.0}
"""
from __future__ import annotations

import numpy as np

from .base import register_type
from .learning import (CycleLearner, CycleTable, base_from_dict, base_to_dict, check_number, process_sensitivity,
                       q_filter, sub_object)

FILTERS = ("inverse", "lead")


@register_type("ilc")
class ILC(CycleLearner):
    """Iterative learning control on a fixed-gain loop (module docstring).

    Parameters
    ----------
    base : PIFF or GainSchedule
        The fixed-gain loop the table is added to.
    gain : float
        Learning gain: for ``"inverse"`` a fraction of the model inverse (-; (0, 1] converges
        monotonically on the design model, 2 or more never does); for ``"lead"`` in mA/deg.
    learning : str
        ``"inverse"`` (L = gain / P of the design model) or ``"lead"`` (L = gain e^{jw lead}).
    lead_ms : float
        Phase lead of the ``"lead"`` filter, ms (ignored by ``"inverse"``).
    q_cutoff_hz : float
        Corner of the zero-phase Butterworth Q filter, Hz.
    q_order : int
        Order of the Butterworth (the zero-phase filter has twice the order).
    q_stop_hz : float, optional
        Harmonics above this frequency, Hz, are not learned at all (Q = 0 there); None: the Butterworth alone.
    start_cycle : int
        First cycle (0 = the fade-in cycle) whose error is learned from.
    design_model : str, optional
        Model file (docs/model-file.md) of the plant the learning filter and the check use; None:
        the book's reference model.
    name : str
        Label in tables and files.
    guard : dict, optional
        The guard's settings (:data:`~.learning.GUARD_DEFAULTS`: ``enabled``, ``patience`` in cycles,
        ``growth`` (-), ``floor_pct`` (%), ``halvings``, ``base_error_pct`` (% or None)); None: the defaults.
    learned : list of dict, optional
        What earlier runs learned (the JSON's ``learned``, :meth:`~.learning.CycleLearner.learned_state`),
        kept as data for drive files; a run always starts learning from zero.
    """

    def __init__(self, base, *, gain: float = 0.8, learning: str = "inverse", lead_ms: float = 0.0,
                 q_cutoff_hz: float = 40.0, q_order: int = 2, q_stop_hz: float | None = None, start_cycle: int = 1,
                 design_model: str | None = None, name: str = "ILC", guard: dict | None = None,
                 learned: list | None = None):
        who = "ilc"
        if learning not in FILTERS:
            raise ValueError(f"{who}: 'learning.filter' must be one of {', '.join(FILTERS)}, got {learning!r}")
        self.learning = learning
        self.gain = check_number(gain, "learning.gain", 0.0, 100.0, who, lo_open=True)
        self.lead_ms = check_number(lead_ms, "learning.lead_ms", 0.0, 100.0, who)
        self.q_cutoff_hz = check_number(q_cutoff_hz, "q_filter.cutoff_hz", 0.0, 500.0, who, lo_open=True)
        self.q_order = int(check_number(q_order, "q_filter.order", 1, 8, who, integer=True))
        self.q_stop_hz = (None if q_stop_hz is None else
                          check_number(q_stop_hz, "q_filter.stop_hz", 0.0, 500.0, who, lo_open=True))
        self._layer(base, start_cycle, design_model, name, who, guard, learned)

    # -- design ---------------------------------------------------------------------
    def design(self, amplitude_deg: float, freq_hz: float, rate_hz: float = 1000.0) -> dict:
        """L and Q on the cycle's harmonics, and the monotonic-convergence check on the design model.

        Parameters
        ----------
        amplitude_deg, freq_hz : float
            The reference (deg, Hz).
        rate_hz : float
            Control rate, Hz (sets the table's length).

        Returns
        -------
        dict
            ``L`` (mA/deg) and ``Q`` (-) per harmonic k = 0..N/2 of the table, ``harmonic_hz``, and
            ``contraction``: sup_k |Q (1 - L P)| over k >= 1 on the design model, with the
            frequency where it is reached (``worst_hz``).

        Raises
        ------
        ValueError
            One line, if the contraction is not below 1 (the learning would not converge
            monotonically on the design model), or no plant was chosen (:meth:`for_plant`).
        """
        if self.disc_sets is None:
            raise ValueError(f"ilc '{self.name}': which plant? call for_plant(disc_sets) before running it")
        table = CycleTable(freq_hz, rate_hz)
        fk = table.harmonic_hz
        P = np.zeros(fk.size, dtype=complex)
        P[1:] = process_sensitivity(self._loop, self.disc_sets, amplitude_deg, freq_hz, 2 * np.pi * fk[1:],
                                    self.design_model)
        L = np.zeros(fk.size, dtype=complex)
        if self.learning == "inverse":
            L[1:] = self.gain / P[1:]
        else:
            L[1:] = self.gain * np.exp(2j * np.pi * fk[1:] * self.lead_ms * 1e-3)
        Q = q_filter(fk, self.q_cutoff_hz, self.q_order)
        if self.q_stop_hz is not None:
            Q = np.where(fk > self.q_stop_hz, 0.0, Q)
        rho = np.abs(Q[1:] * (1.0 - L[1:] * P[1:]))
        k = int(np.argmax(rho)) + 1
        out = {"L": L, "Q": Q, "harmonic_hz": fk, "contraction": float(rho[k - 1]), "worst_hz": float(fk[k])}
        if not out["contraction"] < 1.0:
            raise ValueError(
                f"ilc '{self.name}': learning gain {self.gain:g} ({self.learning}) fails the monotonic-convergence "
                f"condition on the design model: sup|Q(1 - L P)| = {out['contraction']:.3g} >= 1 at "
                f"{out['worst_hz']:g} Hz ({self.disc_sets} disc sets, {amplitude_deg:g} deg, {freq_hz:g} Hz); "
                + ("use a gain in (0, 1]" if self.learning == "inverse" else "lower the gain or change lead_ms"))
        return out

    # -- the law ------------------------------------------------------------------------
    def _reset_learning(self) -> None:
        self._u = None
        self._plan = None
        self.cycle_log: list[float] = []  # rms of the table's update per learned cycle, mA

    def _begin(self, amplitude_deg: float, freq_hz: float) -> None:
        self._plan = self.design(amplitude_deg, freq_hz, self._loop.rate_hz)
        self._u = np.zeros(self._table.n)

    def _feedforward(self, t: float) -> float:
        return self._table.value(self._u)

    def _learn(self, e: np.ndarray) -> None:
        n = self._table.n
        U = np.fft.rfft(self._u) + self._plan["L"] * np.fft.rfft(e)
        new = np.fft.irfft(self._plan["Q"] * U, n)
        self.cycle_log.append(float(np.sqrt(np.mean((new - self._u) ** 2))))
        self._u = new

    # -- what the guard and the drive files need ---------------------------------------------
    def _learned_band(self) -> np.ndarray:
        band = np.array(self._plan["Q"], dtype=float)  # Q: what an update keeps of each harmonic
        band[0] = 0.0  # the mean is the base loop's integrator's
        return band

    def _snapshot(self):
        return self._u.copy()

    def _restore(self, snapshot) -> None:
        self._u = np.array(snapshot, dtype=float)

    def _scale(self, factor: float) -> None:
        self._u = self._u * factor

    def _with_harmonics(self, snapshot, source, ks):
        U = np.fft.rfft(snapshot)
        U[ks] = np.fft.rfft(source)[ks]
        return np.fft.irfft(U, self._table.n)

    def _notch(self, ks) -> None:
        self._plan["L"] = np.where(self.dropped, 0.0, self._plan["L"])  # a notch in L: nothing more learned there

    @property
    def _feedforward_state(self):
        return self._u.copy()

    def _table_of(self, feedforward, table: CycleTable) -> np.ndarray:
        u = np.asarray(feedforward, dtype=float)
        if u.size == table.n:
            return u.copy()
        # learned at another rate: the periodic table at the new bins' phases, linearly interpolated
        return np.interp(np.arange(table.n) / table.n, np.arange(u.size) / u.size, u, period=1.0)

    # -- file ------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-able description; :meth:`from_dict` rebuilds the controller from it.

        Returns
        -------
        dict
            ``type`` ``"ilc"``, ``kind``, ``name``, ``base`` (the fixed-gain loop's description),
            ``learning`` (``filter``, ``gain``, ``lead_ms`` in ms), ``q_filter`` (``cutoff_hz`` in Hz,
            ``order``, and ``stop_hz`` in Hz when set), ``start_cycle``, ``design_model`` (a model file's path or null), ``guard`` (the
            guard's settings, :data:`~.learning.GUARD_DEFAULTS`) and, once it has run, ``learned``
            (:meth:`~.learning.CycleLearner.learned_state`).
        """
        d = {"type": "ilc", "kind": self.kind, "name": self.name, "base": base_to_dict(self.base),
             "learning": {"filter": self.learning, "gain": self.gain, "lead_ms": self.lead_ms},
             "q_filter": {"cutoff_hz": self.q_cutoff_hz, "order": self.q_order},
             "start_cycle": self.start_cycle, "design_model": self.design_model, "guard": self.guard_to_dict()}
        if self.q_stop_hz is not None:
            d["q_filter"]["stop_hz"] = self.q_stop_hz
        if self._memory:
            d["learned"] = self.learned_state()
        return d

    @classmethod
    def from_dict(cls, data: dict) -> "ILC":
        """Rebuild an ILC from its JSON description (:meth:`to_dict`).

        Parameters
        ----------
        data : dict
            ``{"type": "ilc", "base": {...}, "learning": {...}, "q_filter": {...}, ...}``; missing
            ``learning``/``q_filter`` fields take the defaults.

        Returns
        -------
        ILC
            The controller.

        Raises
        ------
        ValueError
            One line naming the field: a missing or bad ``base``, an unknown key in ``learning`` or
            ``q_filter``, a value out of its range.
        """
        if "base" not in data:
            raise ValueError("ilc: no 'base' field; expected \"base\": {\"type\": \"piff\" or \"schedule\", ...}")
        allowed = ("type", "kind", "name", "base", "learning", "q_filter", "start_cycle", "design_model", "guard",
                   "learned", "format", "version", "command", "metrics", "notes", "mean_rms_error_pct")
        sub_object({"ilc": data}, "ilc", allowed)
        base = base_from_dict(data["base"], "ilc")
        learning = sub_object(data, "learning", ("filter", "gain", "lead_ms"))
        q = sub_object(data, "q_filter", ("cutoff_hz", "order", "stop_hz"))
        kw = {"learning": learning.get("filter", "inverse"), "gain": learning.get("gain", 0.8),
              "lead_ms": learning.get("lead_ms", 0.0), "q_cutoff_hz": q.get("cutoff_hz", 40.0),
              "q_order": q.get("order", 2), "q_stop_hz": q.get("stop_hz"), "start_cycle": data.get("start_cycle", 1),
              "design_model": data.get("design_model"), "name": data.get("name", "ILC"),
              "guard": data.get("guard"), "learned": data.get("learned")}
        return cls(base, **kw)

    def __repr__(self) -> str:
        law = (f"L = {self.gain:g} / P (model inverse)" if self.learning == "inverse"
               else f"L = {self.gain:g} mA/deg, lead {self.lead_ms:g} ms")
        src = self.design_model or "book model"
        stop = f", nothing above {self.q_stop_hz:g} Hz" if self.q_stop_hz is not None else ""
        return (f"ILC '{self.name}': {law}, zero-phase Q Butterworth {self.q_cutoff_hz:g} Hz order {self.q_order}{stop}, "
                f"designed on {src}, on {self.base.name!r}")

