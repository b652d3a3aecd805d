"""The independent generator's measurement chain (its own figures, comparable to the package's Sensors).

=================  =====================================================  =====================================
channel            chain                                                  source
=================  =====================================================  =====================================
LVDT               white noise 9 um (0.01 deg at r = 50 mm) on the        assumed; the rig's 16-bit NI card
                   piston position, 16-bit ADC over the stroke (+-h),     (docs/rig.md)
                   then the logger's asin(x / r)
pressures          white noise 0.25 bar, 16-bit ADC over 0-400 bar        assumed; 400 bar transducers (book)
flow               white noise 0.06 LPM, 16-bit ADC over +-40 LPM         assumed; 0.03-40 LPM turbine meters
current command    12-bit DAC over +-20 mA (no noise: a digital command)  book: RMC70 12-bit output
=================  =====================================================  =====================================

The LVDT is quantized in position (the transducer measures the piston), not in
angle as the reference model's sensor layer does: another rig's chain.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .rig import Rig


def _quantize(x, step: float):
    """x rounded to a multiple of step (a converter); step 0 (0 bits): unchanged."""
    if step <= 0.0:
        return np.asarray(x, float)
    return step * np.floor(np.asarray(x, float) / step + 0.5)


def _step(span: float, bits: int) -> float:
    return span / 2 ** bits if bits else 0.0


@dataclass(frozen=True)
class Chain:
    """Noise and converters of the logged signals.

    Parameters
    ----------
    lvdt_noise_m : float
        Std of the LVDT's position noise, m.
    pressure_noise_bar : float
        Std of the pressure transducers' noise, bar.
    flow_noise_lpm : float
        Std of the flow meter's noise, LPM.
    adc_bits : int
        ADC resolution, bits (0: none).
    dac_bits : int
        Current-output resolution over +-20 mA, bits (0: none).
    """

    lvdt_noise_m: float = 9.0e-6
    pressure_noise_bar: float = 0.25
    flow_noise_lpm: float = 0.06
    adc_bits: int = 16
    dac_bits: int = 12

    @classmethod
    def ideal(cls) -> "Chain":
        """No noise, no converters."""
        return cls(0.0, 0.0, 0.0, 0, 0)

    def to_dict(self) -> dict:
        return asdict(self)

    def angle(self, theta_deg: float, rig: Rig, rng: np.random.Generator) -> float:
        """The logged (and controller's) crank angle: noisy, quantized LVDT position, then asin(x/r), deg."""
        x = rig.radius * math.sin(math.radians(theta_deg))
        if self.lvdt_noise_m:
            x += rng.normal(0.0, self.lvdt_noise_m)
        x = float(_quantize(x, _step(2.0 * rig.half_stroke, self.adc_bits)))
        return math.degrees(math.asin(max(-1.0, min(1.0, x / rig.radius))))

    def dac(self, current_mA: float) -> float:
        """The controller's command after the DAC, mA."""
        return float(_quantize(current_mA, _step(40.0, self.dac_bits)))

    def pressure(self, p_bar: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        y = np.asarray(p_bar, float) + rng.normal(0.0, self.pressure_noise_bar, np.shape(p_bar))
        return _quantize(y, _step(400.0, self.adc_bits))

    def flow(self, q_lpm: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        y = np.asarray(q_lpm, float) + rng.normal(0.0, self.flow_noise_lpm, np.shape(q_lpm))
        return _quantize(y, _step(80.0, self.adc_bits))
