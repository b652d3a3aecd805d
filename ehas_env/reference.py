"""Reference generators: the position command and its analytic derivatives."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .rig import THETA_STROKE_END


@dataclass(frozen=True)
class SineReference:
    """theta_ref = amplitude sin(2 pi f t + phase), in degrees.

    Examples
    --------
    >>> ref = SineReference(20.0, 1.0)
    >>> r, rd, rdd = ref(0.25)
    >>> round(r, 6), round(rd, 6)
    (20.0, 0.0)
    """

    amplitude_deg: float
    freq_hz: float
    phase: float = 0.0

    def __post_init__(self):
        check_amplitude(self.amplitude_deg)
        if not (math.isfinite(self.freq_hz) and self.freq_hz > 0):
            raise ValueError(f"freq_hz must be a positive number of Hz, got {self.freq_hz!r}")

    def __call__(self, t):
        """(theta_ref, theta_ref', theta_ref'') at t, deg, deg/s, deg/s^2."""
        w = 2.0 * math.pi * self.freq_hz
        wt = w * np.asarray(t, dtype=float) + self.phase
        a = self.amplitude_deg
        return a * np.sin(wt), a * w * np.cos(wt), -a * w * w * np.sin(wt)

    def kernel_vector(self) -> np.ndarray:
        return np.array([self.amplitude_deg, self.freq_hz, self.phase], dtype=float)

    @property
    def period(self) -> float:
        return 1.0 / self.freq_hz


def check_amplitude(amplitude_deg) -> None:
    """Amplitudes must stay inside the stroke ends (44.43 deg)."""
    lim = math.degrees(THETA_STROKE_END)
    if not (isinstance(amplitude_deg, (int, float)) and math.isfinite(amplitude_deg) and 0 < amplitude_deg < lim):
        raise ValueError(f"amplitude_deg must be a number in (0, {lim:.2f}) deg (the stroke ends), got {amplitude_deg!r}")
