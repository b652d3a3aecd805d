"""The generator's unlisted classes (effects.UNLISTED) against analytic truth and invariants: off at magnitude 0,
the LVDT lag's first-order response, the driver's slew limit, the hose's resistance and conservation of oil, the
supply ripple at the valve and in the log, the flow exponent, and the three frictions' law and sign (they dissipate)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from independent_rig import campaign as gen
from independent_rig.effects import UNLISTED, to_si
from independent_rig.physics import (BEARING_W_TANH, CUSHION_START, HOSE_REF_FLOW, HOSE_VOLUME, RIPPLE_HZ, SLEW_T,
                                     V_TANH, RigModel)
from independent_rig.rig import BAR, LPM, book_rig
from independent_rig.sensors import Chain
from independent_rig.simulate import _advance, closed_loop


def test_at_magnitude_zero_every_class_gives_the_clean_campaign():
    zero = {n: {p.name: 0.0 for p in e.params} for n, e in UNLISTED.items()}
    a, _ = gen.simulate(zero, seed=4, duration=0.15)
    b, _ = gen.simulate({}, seed=4, duration=0.15)
    for (na, ca, _), (nb, cb, _) in zip(a, b):
        assert na == nb and ca.keys() == cb.keys()
        for k in ca:
            np.testing.assert_array_equal(ca[k], cb[k], err_msg=f"{na}.{k}")


def test_each_class_at_its_strong_magnitude_changes_the_campaign():
    plan = ((1, 35.0, 3.0),)  # to the first peak of 35 deg (0.82 of the half stroke: into the cushions)
    b, _ = gen.simulate({}, seed=4, duration=0.45, plan=plan)
    for n, e in UNLISTED.items():
        a, _ = gen.simulate({n: e.values(1)}, seed=4, duration=0.45, plan=plan)
        assert any(not np.array_equal(ca[k], cb[k]) for (_, ca, _), (_, cb, _) in zip(a, b) for k in ca), n


def _coasting(effects):
    """The crank turning freely at 1 rad/s (inertia huge, equal chambers, valve shut)."""
    rig = book_rig().with_(inertia_per_set=1.0e12)
    m = RigModel(rig, 1, to_si(effects))
    y = np.array(m.initial_state())
    y[1] = 1.0
    return rig, m, y


def test_the_lvdt_lag_is_a_first_order_filter_of_the_piston_position():
    """x = r sin(t) (theta = t); T x_r' = x - x_r, x_r(0) = 0 gives
    x_r = r / (1 + T^2) (sin t - T cos t) + r T / (1 + T^2) e^(-t/T); the reading's phase lag at w is atan(w T)."""
    T = 4e-3
    rig, m, y = _coasting({"lvdt_lag": {"T": T * 1e3}})
    t = 0.05
    y1 = _advance(m, y, 0.0, t, 0.0)
    assert y1[0] == pytest.approx(t, rel=1e-6)
    r = rig.radius
    xr = r / (1 + T * T) * (math.sin(t) - T * math.cos(t)) + r * T / (1 + T * T) * math.exp(-t / T)
    assert y1[m.i_xr] == pytest.approx(xr, rel=1e-5)
    assert m.lvdt_angle_deg(y1) == pytest.approx(math.degrees(math.asin(y1[m.i_xr] / r)), rel=1e-12)
    # steady state: the reading lags the position by atan(w T) (here w = 1 rad/s)
    steady = r / (1 + T * T) * (math.sin(t) - T * math.cos(t))
    assert steady == pytest.approx(r / math.sqrt(1 + T * T) * math.sin(t - math.atan(T)), rel=1e-12)


def test_the_current_driver_slews_at_S_and_follows_small_steps_with_its_own_time_constant():
    S = 150.0
    rig = book_rig()
    m = RigModel(rig, 1, to_si({"current_slew": {"S": S}}))
    y = np.array(m.initial_state())
    y1 = _advance(m, y.copy(), 0.0, 0.02, 10.0)  # a 10 mA step: far from the target, the rate is S
    assert y1[6] == pytest.approx(S * 0.02, rel=1e-3)
    small = 1e-3  # a 1 uA step: far below S SLEW_T = 30 uA, a first-order lag of SLEW_T
    y2 = _advance(m, y.copy(), 0.0, 3e-4, small)
    assert y2[6] == pytest.approx(small * (1 - math.exp(-3e-4 / SLEW_T)), rel=1e-3)


def test_the_hose_passes_its_rated_flow_at_its_rated_drop_and_keeps_the_oil():
    dp = 12.0
    rig = book_rig()
    m = RigModel(rig, 1, to_si({"hose_line": {"dp": dp, "V": 30.0}}))
    y = np.array(m.initial_state())
    k = m.i_hose
    y[k] = y[4] + dp * BAR  # port A dp above chamber A, valve shut, piston at rest
    dy = m.rates(y, 0.0)
    va = rig.area * rig.half_stroke + rig.dead_volume
    assert dy[4] == pytest.approx(rig.beta / va * HOSE_REF_FLOW, rel=1e-9)  # 20 LPM into the chamber
    # valve shut: the oil leaving the port's hose is the oil entering the chamber (V p'/beta sums to 0)
    assert 30.0e-6 * dy[k] + va * dy[4] == pytest.approx(0.0, abs=1e-9 * va * abs(dy[4]))
    assert RigModel(rig, 1, to_si({"hose_line": {"dp": dp}})).hose_v == HOSE_VOLUME  # V left out: 50 cm^3
    # the flow meter sits at the valve's port: with the valve open it sees the land's flow at the port pressure
    y[2] = rig.K * 4.0
    half = 0.5 * rig.rated_drop
    q = m.outputs(y)["flow_lpm"] * LPM
    assert q == pytest.approx(rig.K * 4.0 * math.sqrt((rig.supply - y[k]) / half), rel=1e-12)


def test_the_supply_ripple_is_in_the_valves_supply_and_in_the_logged_supply():
    a = 10.0
    rig = book_rig()
    m = RigModel(rig, 1, to_si({"supply_ripple": {"a": a}}))
    t = 0.25 / RIPPLE_HZ  # sin = 1
    qc, pa, pb = rig.K * 5.0, 100e5, 120e5
    half = 0.5 * rig.rated_drop
    qa, _ = m.land_flows(qc, pa, pb, t)
    assert qa == pytest.approx(qc * math.sqrt((rig.supply + a * BAR - pa) / half), rel=1e-12)
    cols, _, _ = closed_loop(rig, 1, 10.0, 1.0, 0.1, to_si({"supply_ripple": {"a": a}}), Chain.ideal(),
                             np.random.default_rng(0))
    np.testing.assert_allclose(cols["p_s_bar"], rig.supply / BAR + a * np.sin(2 * math.pi * RIPPLE_HZ * cols["t"]),
                               atol=1e-9)


@pytest.mark.parametrize("ratio", [0.25, 1.0, 4.0])
def test_the_land_flow_exponent_falls_by_gamma_and_equals_the_orifice_law_at_the_rated_drop(ratio):
    g = 0.12
    rig = book_rig()
    m = RigModel(rig, 1, to_si({"land_flow_forces": {"gamma": g}}))
    d = ratio * 0.5 * rig.rated_drop
    assert m.land(d) == pytest.approx(ratio ** (0.5 - g), rel=1e-12)
    assert m.land(-d) == pytest.approx(-ratio ** (0.5 - g), rel=1e-12)
    assert RigModel(rig, 1, {}).land(d) == pytest.approx(math.sqrt(ratio), rel=1e-12)


def _state(m, theta, omega, pa, pb):
    y = np.array(m.initial_state())
    y[0], y[1], y[4], y[5] = theta, omega, pa, pb
    return y


@pytest.mark.parametrize("name", ["bore_wear_friction", "end_cushion", "bearing_friction"])
def test_the_frictions_follow_their_law_and_only_dissipate(name):
    rig = book_rig()
    eff = to_si({name: UNLISTED[name].values(1)})[name]
    m, bare = RigModel(rig, 1, {name: eff}), RigModel(rig, 1, {})
    rng = np.random.default_rng(1)
    h, r, inertia = rig.half_stroke, rig.radius, rig.inertia_per_set
    for _ in range(200):
        theta = rng.uniform(-0.95, 0.95) * rig.stroke_end
        omega = rng.normal(0.0, 3.0)
        pa, pb = rng.uniform(10e5, 210e5, 2)
        y = _state(m, theta, omega, pa, pb)
        extra = (m.rates(y, 0.0)[1] - bare.rates(y, 0.0)[1]) * inertia  # torque the class adds, N m
        assert extra * omega <= 1e-12  # it takes energy out, never puts it in
        x, v = r * math.sin(theta), r * math.cos(theta) * omega
        lever = r * math.cos(theta)
        if name == "bore_wear_friction":
            law = -eff["Fw"] * (x / h) ** 2 * math.tanh(v / V_TANH) * lever
        elif name == "end_cushion":
            s = max(0.0, (abs(x) / h - CUSHION_START) / (1 - CUSHION_START))
            law = -eff["ce"] * v * s * s * lever
        else:
            law = -eff["mur"] * abs(rig.area * (pa - pb)) * math.tanh(omega / BEARING_W_TANH)
        assert extra == pytest.approx(law, rel=1e-9, abs=1e-9)


def test_the_unlisted_classes_are_whole_specs_spread_over_the_places():
    from independent_rig.cases import unlisted_cases
    from independent_rig.effects import KINDS, LIBRARY, OUT_OF_LIBRARY, PLACES

    assert len(UNLISTED) >= 8
    assert not set(UNLISTED) & (set(OUT_OF_LIBRARY) | set(LIBRARY))
    for name, e in UNLISTED.items():
        assert e.values(0) != e.values(1) and e.kind in KINDS and set(e.accepted_kinds) <= set(KINDS), name
        assert e.places and set(e.places) <= set(PLACES) and e.source and e.doc, name
        assert len(e.accepted_kinds) == 1 or e.why, name  # a second accepted kind says why
    assert len({e.places[0] for e in UNLISTED.values()}) >= 6  # where each acts first: spread over the model
    cases = unlisted_cases()
    assert len({c["id"] for c in cases}) == len(cases)
    for name in UNLISTED:  # each class at both magnitudes, alone
        assert sum(1 for c in cases if set(c["effects"]) == {name}) == 2
    pairs = [c for c in cases if len(c["effects"]) == 2]
    assert len(pairs) >= 4 and any(set(c["effects"]) & set(LIBRARY) for c in pairs)


def test_on_the_flow_bench_the_flow_forces_show_only_away_from_the_rated_drop():
    """Two lands in series share the bench's drop: at the rated drop (70 bar) each takes dp_n/2 and the flow is the
    orifice law's; at twice it, the flow is 2^(1/2 - gamma) times the rated one instead of sqrt(2)."""
    from independent_rig.simulate import valve_bench
    g = 0.06
    rig = book_rig()
    cmd = np.full(300, 5.0)
    eff = to_si({"land_flow_forces": {"gamma": g}})
    for bar, factor in ((70.0, 1.0), (140.0, 2.0 ** (0.5 - g))):
        with_, _ = valve_bench(rig, cmd, bar, eff, Chain.ideal(), np.random.default_rng(0))
        rated, _ = valve_bench(rig, cmd, 70.0, {}, Chain.ideal(), np.random.default_rng(0))
        np.testing.assert_allclose(with_["flow_lpm"], factor * rated["flow_lpm"], rtol=1e-12, atol=1e-15)
