"""The independent generator against analytic truth: valve step, crank under a constant force, chamber
pressure build-up through one land, the controller's anti-windup, the bench's underlap gain."""
from __future__ import annotations

import math

import numpy as np
import pytest

from independent_rig.physics import RigModel
from independent_rig.rig import BAR, LPM, book_rig
from independent_rig.sensors import Chain
from independent_rig.simulate import DT, PIFF, _advance, reference, valve_bench


def test_valve_step_follows_the_second_order_law():
    """A current step on the flow bench at the rated drop: q(t) = K i (1 - e^(-z w t)(cos wd t + z/sqrt(1-z^2) sin wd t))."""
    rig = book_rig()
    i = 5.0
    cmd = np.full(200, i)
    cols, _ = valve_bench(rig, cmd, rig.rated_drop / BAR, {}, Chain.ideal(), np.random.default_rng(0))
    t = cols["t"]
    z, w = rig.zeta, rig.wn
    wd = w * math.sqrt(1 - z * z)
    # the command of row k acts from t_k on, and row k logs the flow at t_k
    q = rig.K * i * (1 - np.exp(-z * w * t) * (np.cos(wd * t) + z / math.sqrt(1 - z * z) * np.sin(wd * t))) / LPM
    np.testing.assert_allclose(cols["flow_lpm"], q, atol=1e-5 * rig.K * i / LPM)


def test_crank_under_a_constant_force_turns_with_constant_acceleration():
    """Huge chambers hold the pressures: I theta'' = A dp r cos(theta) ~ A dp r, theta = alpha t^2 / 2 (theta < 0.01 rad)."""
    rig = book_rig().with_(dead_volume=1.0e3)
    m = RigModel(rig, 1, {})
    y = np.array(m.initial_state())
    y[4] += 0.5 * BAR
    y[5] -= 0.5 * BAR
    T = 0.04
    y = _advance(m, y, 0.0, T, 0.0)
    alpha = rig.area * BAR * rig.radius / rig.inertia_per_set
    assert y[0] == pytest.approx(0.5 * alpha * T * T, rel=1e-4)
    assert y[1] == pytest.approx(alpha * T, rel=1e-4)


def test_chamber_pressure_builds_up_as_the_compressibility_law_says():
    """Piston held (huge inertia), valve open at a steady q_c: P_A' = beta/V q_c sqrt((Ps - P_A)/(dp_n/2)),
    so sqrt(Ps - P_A) falls linearly, by beta q_c t / (2 V sqrt(dp_n/2)); likewise sqrt(P_B)."""
    rig = book_rig().with_(inertia_per_set=1.0e12)
    m = RigModel(rig, 1, {})
    i = 2.0
    y = np.array(m.initial_state())
    y[2] = rig.K * i  # the valve at its steady state
    T = 0.01
    y1 = _advance(m, y.copy(), 0.0, T, i)
    v0 = rig.area * rig.half_stroke + rig.dead_volume
    fall = rig.beta * rig.K * i * T / (2 * v0 * math.sqrt(rig.rated_drop / 2))
    assert math.sqrt(rig.supply - y1[4]) == pytest.approx(math.sqrt(rig.supply - y[4]) - fall, rel=1e-6)
    assert math.sqrt(y1[5]) == pytest.approx(math.sqrt(y[5]) - fall, rel=1e-6)
    assert abs(y1[0]) < 1e-12


def test_underlapped_valve_doubles_the_bench_gain_near_null():
    """Lands open by u0 at null: the metered flow (a_1 - a_2, openings u0 +- q_c) is 2 q_c while |q_c| < u0,
    q_c + u0 beyond (at the rated drop)."""
    rig = book_rig()
    u0 = 2.0  # LPM
    cmd = np.full(400, 0.5)  # q_c = 0.64 LPM < u0
    eff = {"valve_underlap": {"u0": u0 * LPM}}
    cols, _ = valve_bench(rig, cmd, rig.rated_drop / BAR, eff, Chain.ideal(), np.random.default_rng(0))
    assert cols["flow_lpm"][-1] == pytest.approx(2 * rig.K * 0.5 / LPM, rel=1e-4)
    cols, _ = valve_bench(rig, np.full(400, 10.0), rig.rated_drop / BAR, eff, Chain.ideal(), np.random.default_rng(0))
    assert cols["flow_lpm"][-1] == pytest.approx(rig.K * 10.0 / LPM + u0, rel=1e-4)


def test_controller_integral_stops_while_clipped():
    """PI + feed-forward: the integral grows by e dt per period, and not while the output is clipped the error's way."""
    c = PIFF({"Kp": 1.0, "Ki": 2.0, "Kv": 0.0, "Ka": 0.0}, 20.0)
    assert c(1.0, 0.0, 0.0) == pytest.approx(1.0 + 2.0 * DT)
    assert c(30.0, 0.0, 0.0) == 20.0
    assert c.integral == pytest.approx(DT)  # held while clipped
    c(-30.0, 0.0, 0.0)
    assert c.integral == pytest.approx(DT)


def test_reference_starts_at_rest_and_its_derivatives_are_consistent():
    """The faded-in sine starts at rest; r' and r'' match finite differences of r."""
    amp, f = 20.0, 2.0
    r0, r1, r2 = reference(0.0, amp, f)
    assert (r0, r1, r2) == (0.0, 0.0, 0.0)
    for t in (0.1, 0.37, 0.8):
        h = 1e-6
        rp, rm = reference(t + h, amp, f), reference(t - h, amp, f)
        assert reference(t, amp, f)[1] == pytest.approx((rp[0] - rm[0]) / (2 * h), rel=1e-6)
        assert reference(t, amp, f)[2] == pytest.approx((rp[1] - rm[1]) / (2 * h), rel=1e-6)
