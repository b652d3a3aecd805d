"""Sensor and converter realism, kept apart from the physics.

The rig's DAQ is a 16-bit ADC; the controller's current output a 12-bit DAC
(docs/rig.md).  Noise levels are assumed (typical for the rig's transducers) and
documented per field.  A :class:`Sensors` with ``ideal=True`` (the default of
:meth:`Sensors.ideal`) leaves signals untouched.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ehas_env.physics.rig import CRANK_RADIUS, HALF_STROKE

# full-scale spans of the converters (the range each sensor's ADC channel covers)
THETA_SPAN_DEG = 2.0 * np.degrees(np.arcsin(HALF_STROKE / CRANK_RADIUS))  # LVDT +-35 mm
PRESSURE_SPAN_BAR = 400.0  # docs/rig.md: 3 x 400 bar transducers
FLOW_SPAN_LPM = 80.0  # turbine meter 0.03-40 LPM, signed channel +-40
CURRENT_SPAN_MA = 40.0  # +-20 mA


def lsb(span: float, bits: int) -> float:
    """Quantization step of a converter of ``bits`` over ``span``."""
    return span / (2**bits)


@dataclass(frozen=True)
class Sensors:
    """Noise, quantization and gain errors of the measurement chain.

    Attributes
    ----------
    theta_noise_deg : float
        Std of LVDT noise, deg (assumed 0.01 deg).
    pressure_noise_bar : float
        Std of pressure-transducer noise, bar (assumed 0.2 bar, 0.05 % FS).
    flow_noise_lpm : float
        Std of turbine-meter noise, LPM (assumed 0.05 LPM).
    adc_bits : int
        ADC resolution (rig: 16-bit NI card); 0 disables quantization.
    dac_bits : int
        Controller output resolution (rig: 12-bit RMC70 output); 0 disables it.
    lvdt_gain_error : float
        Relative gain error of the LVDT, - (assumed 0).
    """

    theta_noise_deg: float = 0.01
    pressure_noise_bar: float = 0.2
    flow_noise_lpm: float = 0.05
    adc_bits: int = 16
    dac_bits: int = 12
    lvdt_gain_error: float = 0.0

    @classmethod
    def ideal(cls) -> "Sensors":
        """No noise, no quantization, no gain error."""
        return cls(0.0, 0.0, 0.0, 0, 0, 0.0)

    @property
    def is_ideal(self) -> bool:
        return self == Sensors.ideal()

    @property
    def theta_lsb(self) -> float:
        return lsb(THETA_SPAN_DEG, self.adc_bits) if self.adc_bits else 0.0

    @property
    def current_lsb(self) -> float:
        return lsb(CURRENT_SPAN_MA, self.dac_bits) if self.dac_bits else 0.0

    def to_dict(self) -> dict:
        return asdict(self)

    def kernel_vector(self, i_max: float) -> np.ndarray:
        """(theta lsb deg, DAC lsb mA, LVDT gain error, output limit mA) for the closed-loop kernel."""
        return np.array([self.theta_lsb, self.current_lsb, self.lvdt_gain_error, i_max], dtype=float)

    def theta_noise(self, n: int, rng: np.random.Generator) -> np.ndarray:
        if self.theta_noise_deg <= 0.0:
            return np.zeros(n)
        return rng.normal(0.0, self.theta_noise_deg, n)

    def measure_channel(self, x: np.ndarray, channel: str, rng: np.random.Generator) -> np.ndarray:
        """Add noise and ADC quantization to one logged channel (engineering units)."""
        std, span = {
            "pressure": (self.pressure_noise_bar, PRESSURE_SPAN_BAR),
            "flow": (self.flow_noise_lpm, FLOW_SPAN_LPM),
            "theta": (self.theta_noise_deg, THETA_SPAN_DEG),
        }[channel]
        y = np.asarray(x, dtype=float)
        if std > 0.0:
            y = y + rng.normal(0.0, std, y.shape)
        if self.adc_bits:
            q = lsb(span, self.adc_bits)
            y = q * np.floor(y / q + 0.5)
        return y
