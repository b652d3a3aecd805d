"""Reference generators: the position command and its analytic derivatives."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ehas_env.physics.rig import THETA_STROKE_END


@dataclass(frozen=True)
class SineReference:
    """theta_ref = offset + amplitude sin(2 pi f t + phase), in degrees, faded in.

    ``offset_deg`` is the sine's mean angle (0: centred on the stroke); |offset| +
    amplitude must stay below the stroke end (44.43 deg).  A run off centre
    makes the two chambers' volumes differ (their stiffness with them), which
    a run centred on the stroke cannot show.

    The amplitude fades in over ``ramp_cycles`` periods with a smoothstep
    (C2-continuous), as an operator ramps a rig in: a sine that starts at full
    velocity asks a heavy inertia for infinite acceleration at t = 0 and the
    start-up overshoot can reach the stroke ends.  The mean angle fades in with
    the amplitude (the rig starts at rest at 0).  The fade-in lies inside the
    first cycle, which the % error metric excludes as warm-up.  ``ramp_cycles=0``
    gives the plain sine.

    Examples
    --------
    >>> ref = SineReference(20.0, 1.0)
    >>> r, rd, rdd = ref(1.25)
    >>> round(float(r), 6), round(float(rd), 6)
    (20.0, 0.0)
    >>> float(ref(0.0)[1])   # starts at rest
    0.0
    >>> round(float(SineReference(20.0, 1.0, offset_deg=-15.0)(1.25)[0]), 6)
    5.0
    """

    amplitude_deg: float
    freq_hz: float
    phase: float = 0.0
    ramp_cycles: float = 1.0
    offset_deg: float = 0.0

    def __post_init__(self):
        check_amplitude(self.amplitude_deg)
        check_offset(self.offset_deg, self.amplitude_deg)
        if not (math.isfinite(self.freq_hz) and self.freq_hz > 0):
            raise ValueError(f"freq_hz must be a positive number of Hz, got {self.freq_hz!r}")
        if not (math.isfinite(self.ramp_cycles) and self.ramp_cycles >= 0):
            raise ValueError(f"ramp_cycles must be >= 0 reference periods, got {self.ramp_cycles!r}")

    def __call__(self, t):
        """(theta_ref, theta_ref', theta_ref'') at t, deg, deg/s, deg/s^2."""
        r = self.derivatives(t)
        return r[0], r[1], r[2]

    def derivatives(self, t) -> np.ndarray:
        """theta_ref and its first three derivatives (deg, deg/s^k), shape (4,) or (4, len(t))."""
        from ehas_env.simulation.compiled_model import current_model

        reference_series = current_model(inline=False).reference_series  # the quick-compile build

        scalar = np.ndim(t) == 0
        t = np.ascontiguousarray(np.atleast_1d(np.asarray(t, dtype=float)))
        out = reference_series(self.kernel_vector(), t)
        return out[:, 0] if scalar else out

    @property
    def ramp_time(self) -> float:
        return self.ramp_cycles / self.freq_hz

    def kernel_vector(self) -> np.ndarray:
        """(amplitude deg, frequency Hz, phase rad, ramp s[, offset deg]) for the kernels.

        The offset is appended only when it is not 0, so a centred sine keeps the
        four-field vector the environment's and the benchmark's layouts hold
        (``ehas_env.env.batch_kernel.REF_FIELDS``); ``loops.reference_point`` reads a
        fifth field as the mean angle.
        """
        vec = [self.amplitude_deg, self.freq_hz, self.phase, self.ramp_time]
        if self.offset_deg != 0.0:
            vec.append(self.offset_deg)
        return np.array(vec, dtype=float)

    def to_dict(self) -> dict:
        """The sidecar's ``reference`` object (``offset_deg`` only when not 0)."""
        out = {"amplitude_deg": self.amplitude_deg, "freq_hz": self.freq_hz, "phase_rad": self.phase,
               "ramp_cycles": self.ramp_cycles}
        if self.offset_deg != 0.0:
            out["offset_deg"] = self.offset_deg
        return out

    @property
    def period(self) -> float:
        return 1.0 / self.freq_hz


def check_amplitude(amplitude_deg) -> None:
    """Amplitudes must stay inside the stroke ends (44.43 deg)."""
    lim = math.degrees(THETA_STROKE_END)
    if not (isinstance(amplitude_deg, (int, float)) and math.isfinite(amplitude_deg) and 0 < amplitude_deg < lim):
        raise ValueError(f"amplitude_deg must be a number in (0, {lim:.2f}) deg (the stroke ends), got {amplitude_deg!r}")


def check_offset(offset_deg, amplitude_deg) -> None:
    """The mean angle must keep the sine inside the stroke ends: |offset| + amplitude < 44.43 deg."""
    lim = math.degrees(THETA_STROKE_END)
    if not (isinstance(offset_deg, (int, float)) and not isinstance(offset_deg, bool) and math.isfinite(offset_deg)
            and abs(offset_deg) + amplitude_deg < lim):
        raise ValueError(f"offset_deg must be a number with |offset_deg| + amplitude_deg ({amplitude_deg:g}) below "
                         f"{lim:.2f} deg (the stroke ends), got {offset_deg!r}")
