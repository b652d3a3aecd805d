"""The measurement side of the model: what the position sensor reads (place ``position_reading``).

Independent truth: a sensor changes what is read, not how the rig moves.  Open loop (the same current either
way) the dynamics are the baseline's, so the logged angle must be the analytic map of the baseline's piston
position through the sensor law, asin(reading(r sin theta) / r).
"""
import math

import numpy as np
import pytest

from ehas_env.physics.rig import CRANK_RADIUS, HALF_STROKE
from ehas_env.simulation.plant import Plant


def _current(n=1500):
    t = np.arange(n) * 1e-3
    return 2.0 * np.sin(2 * np.pi * 2.0 * t)


@pytest.fixture(scope="module")
def baseline():
    return Plant(3).simulate(_current())


@pytest.mark.parametrize("effect, params, law", [
    ("hyp_position_offset", {"x0": 1.5}, lambda x: x + 1.5e-3),
    ("hyp_position_shape", {"gain": 2.0, "bend": -4.0},
     lambda x: x * 1.02 - 0.04 * HALF_STROKE * (x / HALF_STROKE) ** 3),
])
def test_open_loop_reading_is_the_sensor_law_of_the_true_position(baseline, effect, params, law):
    # started where the sensor reads the baseline's true start (x = 0), the piston moves as the baseline's
    r = Plant(3, effects={effect: params}).simulate(_current(), theta0_deg=math.degrees(math.asin(law(0.0) / CRANK_RADIUS)))
    x_true = CRANK_RADIUS * np.sin(np.radians(baseline.theta_deg))
    expected = np.degrees(np.arcsin(np.clip(law(x_true) / CRANK_RADIUS, -1, 1)))
    np.testing.assert_allclose(r.theta_deg, expected, atol=1e-9)
    # the moving parts did not change: the flow and the pressures are the baseline's
    np.testing.assert_allclose(r.p_a_bar, baseline.p_a_bar, rtol=1e-12, atol=1e-9)


def test_closed_loop_tracks_the_reading_so_the_true_piston_is_displaced():
    """The controller closes the loop on the reading: with an offset x0 the reading follows the reference as the
    baseline's angle does, and the chambers work about a mid-stroke shifted by -x0 (mean load pressure moves)."""
    base = Plant(3).simulate_closed_loop(amplitude_deg=20, freq_hz=1.0, duration=2.0)
    off = Plant(3, effects={"hyp_position_offset": {"x0": 2.0}}).simulate_closed_loop(
        amplitude_deg=20, freq_hz=1.0, duration=2.0)
    # starting where the sensor reads 0 (the true piston at -x0), the reading tracks as before ...
    assert np.max(np.abs(off.theta_deg - base.theta_deg)) < 0.1
    assert abs(np.radians(off.theta_crank_deg[0]) * 0.05 + 2e-3) < 1e-4
    # ... while the chambers' mean pressures separate: the piston sits 2 mm toward chamber A
    da = float(np.mean(off.p_a_bar - base.p_a_bar))
    db = float(np.mean(off.p_b_bar - base.p_b_bar))
    assert abs(da - db) > 0.05 or math.copysign(1, da) != math.copysign(1, db)
