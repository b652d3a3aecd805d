"""Amplitude/phase control: adaptive cancellation of the first k harmonics of the error, on a fixed-gain loop.

What a commercial sine-test controller does on top of its servo loop: for each of
the first ``harmonics`` multiples h of the reference frequency it keeps a complex
current ``U_h`` (amplitude and phase, mA) and adds ``sum_h Re(U_h e^{j h w t})`` to the
fixed-gain loop's output.  Once per cycle it measures the error's complex amplitude
``E_h`` at each harmonic (from the cycle's error, :class:`~.learning.CycleTable`) and
moves ``U_h`` to cancel it::

    U_h <- U_h + gain * E_h / P_h

``P_h`` is the response of the angle to a current at that harmonic with the loop
closed, first the design model's (:func:`~.learning.process_sensitivity`), then
**adapted** from what the rig showed: after a change ``dU_h`` the error changed by
``dE_h = -P dU_h``, so ``-dE_h/dU_h`` measures ``P_h``; the estimate moves towards it by
``adapt`` per cycle (0: the model is kept).  A measurement further than a factor 2
from the current estimate (noise, a saturated cycle) is ignored.

Before the run the condition ``|1 - gain P_h / P_h(model)| < 1`` is checked on the
design model for every harmonic, as the ILC checks its own (:mod:`.ilc`), and a gain
that fails it is refused with one line.
"""
from __future__ import annotations

import numpy as np

from .base import register_type
from .learning import (CycleLearner, CycleTable, base_from_dict, base_to_dict, check_number, process_sensitivity,
                       sub_object)


@register_type("harmonic")
class HarmonicCanceller(CycleLearner):
    """Adaptive harmonic cancellation / amplitude-phase control (module docstring).

    Parameters
    ----------
    base : PIFF or GainSchedule
        The fixed-gain loop the harmonic currents are added to.
    harmonics : int
        Number of harmonics cancelled (1 = the fundamental alone: amplitude/phase control).
    gain : float
        Fraction of the estimated error cancelled per cycle, - ((0, 1] is monotonic on the model).
    adapt : float
        Weight of each cycle's measured response in the plant estimate, - (0: the model's is kept).
    start_cycle : int
        First cycle (0 = the fade-in cycle) whose error is acted on.
    design_model : str, optional
        Model file the first estimates come from; None: the book's model.
    name : str
        Label in tables and files.
    guard : dict, optional
        The guard's settings (:data:`~.learning.GUARD_DEFAULTS`); None: the defaults.
    learned : list of dict, optional
        What earlier runs learned (the JSON's ``learned``), kept as data for drive files.
    """

    def __init__(self, base, *, harmonics: int = 10, gain: float = 0.5, adapt: float = 0.3, start_cycle: int = 1,
                 design_model: str | None = None, name: str = "harmonic", guard: dict | None = None,
                 learned: list | None = None):
        who = "harmonic"
        self.harmonics = int(check_number(harmonics, "harmonics", 1, 50, who, integer=True))
        self.gain = check_number(gain, "gain", 0.0, 10.0, who, lo_open=True)
        self.adapt = check_number(adapt, "adapt", 0.0, 1.0, who)
        self._layer(base, start_cycle, design_model, name, who, guard, learned)

    def design(self, amplitude_deg: float, freq_hz: float) -> np.ndarray:
        """The model's P_h (deg/mA) at harmonics 1..k, after the convergence check.

        Parameters
        ----------
        amplitude_deg, freq_hz : float
            The reference (deg, Hz).

        Returns
        -------
        ndarray of complex
            P at h f, h = 1..``harmonics``.

        Raises
        ------
        ValueError
            One line, if ``|1 - gain|`` (the contraction on the design model) is not below 1, or no
            plant was chosen.
        """
        if self.disc_sets is None or self._loop is None:
            raise ValueError(f"harmonic '{self.name}': which plant? call for_plant(disc_sets) before running it")
        w = 2 * np.pi * freq_hz * np.arange(1, self.harmonics + 1)
        P = process_sensitivity(self._loop, self.disc_sets, amplitude_deg, freq_hz, w, self.design_model)
        rho = float(np.max(np.abs(1.0 - self.gain * P / P)))
        if not rho < 1.0:
            raise ValueError(f"harmonic '{self.name}': gain {self.gain:g} fails the convergence condition on the "
                             f"design model: |1 - gain| = {rho:.3g} >= 1; use a gain in (0, 1]")
        return P

    def _reset_learning(self) -> None:
        self._U = None
        self._dU = None
        self._E = None

    def _feedforward(self, t: float) -> float:
        x = (t * self._table.freq_hz) % 1.0
        return float(np.real(np.dot(self._U, np.exp(2j * np.pi * self._h * x))))

    def _begin(self, amplitude_deg: float, freq_hz: float) -> None:
        self._h = np.arange(1, self.harmonics + 1)
        if self.harmonics > self._table.n // 2 - 1:
            raise ValueError(f"harmonic '{self.name}': {self.harmonics} harmonics of {freq_hz:g} Hz pass the "
                             f"control rate's Nyquist frequency; use at most {self._table.n // 2 - 1}")
        self.P = self.design(amplitude_deg, freq_hz)
        self._U = np.zeros(self.harmonics, dtype=complex)
        self._dU = None
        self._E = None

    def _learn(self, e: np.ndarray) -> None:
        E = 2.0 * np.fft.rfft(e)[1:self.harmonics + 1] / self._table.n  # complex amplitudes, deg
        if self.adapt > 0.0 and self._dU is not None and self._E is not None:
            ok = np.abs(self._dU) > 1e-6
            meas = np.where(ok, -(E - self._E) / np.where(ok, self._dU, 1.0), self.P)
            ratio = np.abs(meas / self.P)
            take = ok & (ratio < 2.0) & (ratio > 0.5) & (np.abs(np.angle(meas / self.P)) < np.pi / 3)
            self.P = np.where(take, (1.0 - self.adapt) * self.P + self.adapt * meas, self.P)
        self._dU = np.where(self.dropped[self._h], 0.0, self.gain * E / self.P)  # dropped by the guard: no more
        self._U = self._U + self._dU
        self._E = E

    # -- what the guard and the drive files need ---------------------------------------------
    def _learned_band(self) -> np.ndarray:
        band = np.zeros(self._table.n // 2 + 1)
        band[self._h] = 1.0  # the harmonics cancelled, 1..harmonics
        return band

    def _snapshot(self):
        return self._U.copy()

    def _restore(self, snapshot) -> None:
        self._U = np.array(snapshot, dtype=complex)
        self._dU = self._E = None

    def _scale(self, factor: float) -> None:
        self._U = self._U * factor
        self._dU = self._E = None

    def _with_harmonics(self, snapshot, source, ks):
        out = np.array(snapshot, dtype=complex)
        out[ks - 1] = np.asarray(source)[ks - 1]  # harmonic k of the table is U[k - 1]
        return out

    def _notch(self, ks) -> None:
        pass  # _learn leaves the harmonics in self.dropped as they are

    @property
    def _feedforward_state(self):
        return self._U.copy()

    def _table_of(self, feedforward, table: CycleTable) -> np.ndarray:
        U = np.asarray(feedforward, dtype=complex)
        x = np.arange(table.n) / table.n
        h = np.arange(1, U.size + 1)
        return np.real(np.exp(2j * np.pi * np.outer(x, h)) @ U)

    def to_dict(self) -> dict:
        """JSON-able description; :meth:`from_dict` rebuilds the controller from it.

        Returns
        -------
        dict
            ``type`` ``"harmonic"``, ``kind``, ``name``, ``base`` (the fixed-gain loop), ``harmonics``,
            ``gain``, ``adapt``, ``start_cycle``, ``design_model``, ``guard`` (the guard's settings,
            :data:`~.learning.GUARD_DEFAULTS`) and, once it has run, ``learned``
            (:meth:`~.learning.CycleLearner.learned_state`).
        """
        d = {"type": "harmonic", "kind": self.kind, "name": self.name, "base": base_to_dict(self.base),
             "harmonics": self.harmonics, "gain": self.gain, "adapt": self.adapt,
             "start_cycle": self.start_cycle, "design_model": self.design_model, "guard": self.guard_to_dict()}
        if self._memory:
            d["learned"] = self.learned_state()
        return d

    @classmethod
    def from_dict(cls, data: dict) -> "HarmonicCanceller":
        """Rebuild the controller from its JSON description (:meth:`to_dict`).

        Parameters
        ----------
        data : dict
            ``{"type": "harmonic", "base": {...}, "harmonics": k, "gain": ..., "adapt": ...}``.

        Returns
        -------
        HarmonicCanceller
            The controller.
        """
        if "base" not in data:
            raise ValueError("harmonic: no 'base' field; expected \"base\": {\"type\": \"piff\" or \"schedule\", ...}")
        allowed = ("type", "kind", "name", "base", "harmonics", "gain", "adapt", "start_cycle", "design_model",
                   "guard", "learned", "format", "version", "command", "metrics", "notes", "mean_rms_error_pct")
        sub_object({"harmonic": data}, "harmonic", allowed)
        kw = {k: data[k] for k in ("harmonics", "gain", "adapt", "start_cycle", "design_model", "name", "guard",
                                   "learned") if k in data}
        return cls(base_from_dict(data["base"], "harmonic"), **kw)

    def __repr__(self) -> str:
        return (f"HarmonicCanceller '{self.name}': {self.harmonics} harmonics, gain {self.gain:g}, adapt "
                f"{self.adapt:g}, designed on {self.design_model or 'book model'}, on {self.base.name!r}")
