"""The coil's place (``coil_current``) and the crank's angle offset, against truth that shares no code with them.

* The right-hand side with ``hyp_crank_offset`` / ``hyp_coil_lag`` against the independent rig's equations
  (tests/independent_rig/physics.py, written from the reference model with its own crank kinematics
  x = r (sin(theta + phi0) - sin phi0) and its own coil state), at random states.
* The valve bench with a coil lag against the closed-form discrete response of the lagged second-order valve,
  K / (T s + 1) * wn^2 / (s^2 + 2 zeta wn s + wn^2), under the zero-order hold of the command.
"""
import math

import numpy as np
import pytest
from scipy import signal

from ehas_env.physics import layout
from ehas_env.physics.rig import VALVE_K, VALVE_WN, VALVE_ZETA
from ehas_env.simulation.plant import Plant
from independent_rig.physics import RigModel
from independent_rig.rig import book_rig

SETS = 3


def _states(rng, n=12):
    for _ in range(n):
        yield dict(theta=rng.uniform(-0.5, 0.5), omega=rng.uniform(-3, 3), qc=rng.uniform(-4e-4, 4e-4),
                   qcd=rng.uniform(-0.05, 0.05), pa=rng.uniform(20e5, 200e5), pb=rng.uniform(20e5, 200e5),
                   iv=rng.uniform(-15, 15), i=rng.uniform(-15, 15))


def _both(plant, ind, st, psi, extra=None):
    """(ehas's rates by state name, the independent rig's rates) at one state."""
    m = plant.model
    s = np.zeros(m.N_STATES)
    s[[0, 1, 2, 3, 4, 5]] = psi, st["omega"], st["qc"], st["qcd"], st["pa"], st["pb"]
    s[6] = plant.rig.supply
    s[7] = plant.rig.radius * math.sin(psi) - plant.slots()["piston_offset"]  # the piston (layout.S_XP)
    for name, value in (extra or {}).items():
        s[m.STATE_NAMES.index(name)] = value
    ds = np.zeros(m.N_STATES)
    m.derivatives(s, m.valve_current(st["i"], plant.param_vector), plant.param_vector, ds)
    y = [st["theta"], st["omega"], st["qc"], st["qcd"], st["pa"], st["pb"], st["iv"], 0.0, 0.0, 0.0]
    return dict(zip(m.STATE_NAMES, ds)), ind.rates(y, st["i"])


@pytest.mark.parametrize("phi0_deg", [8.0, -15.0])
def test_crank_offset_is_the_independent_rigs_kinematics(phi0_deg):
    """Model angle psi = theta + phi0: the same crank, chamber and valve rates as the independent rig's crank at
    theta, and the same logged angle; at rest where the LVDT reads 0 the crank stands at phi0."""
    phi0 = math.radians(phi0_deg)
    plant = Plant(SETS, effects={"hyp_crank_offset": {"phi0": phi0_deg}})
    ind = RigModel(book_rig(), SETS, {"crank_offset": {"phi0": phi0}})
    for st in _states(np.random.default_rng(3)):
        ours, theirs = _both(plant, ind, st, st["theta"] + phi0)
        for name, k in (("theta", 0), ("omega", 1), ("qc", 2), ("qc_dot", 3), ("pa", 4), ("pb", 5)):
            assert ours[name] == pytest.approx(theirs[k], rel=1e-9, abs=1e-12 * max(1.0, abs(theirs[k]))), name
        out = np.zeros(layout.N_OUT + 4)
        s = plant.initial_state()
        s[0] = st["theta"] + phi0
        s[7] = plant.rig.radius * math.sin(s[0]) - plant.slots()["piston_offset"]
        plant.model.measure(s, plant.param_vector, out)
        y = [st["theta"], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        assert math.degrees(out[layout.O_THETA]) == pytest.approx(ind.lvdt_angle_deg(y), abs=1e-9)
    assert plant.initial_state(0.0)[0] == pytest.approx(phi0, abs=1e-9)
    # the baseline is not the same rig: the check above can fail
    base, _ = _both(Plant(SETS), ind, st, st["theta"])
    assert base["omega"] != pytest.approx(theirs[1], rel=1e-3)


def test_coil_lag_is_the_independent_rigs_coil():
    """The spool is driven by the coil's state, and the state relaxes toward the command at 1 / T."""
    t_lag = 4.0e-3
    plant = Plant(SETS, effects={"hyp_coil_lag": {"T": t_lag * 1e3}})
    ind = RigModel(book_rig(), SETS, {"current_lag": {"T": t_lag}})
    for st in _states(np.random.default_rng(5)):
        ours, theirs = _both(plant, ind, st, st["theta"], {"hyp_coil_lag.i_coil": st["iv"]})
        assert ours["hyp_coil_lag.i_coil"] == pytest.approx(theirs[6], rel=1e-12)
        assert ours["qc_dot"] == pytest.approx(theirs[3], rel=1e-9, abs=1e-12)
        assert ours["omega"] == pytest.approx(theirs[1], rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("t_ms", [1.0, 6.0])
def test_coil_lag_on_the_valve_bench_is_the_lagged_second_order_response(t_ms):
    """On the bench (rated drop, ports joined) the metered flow is the lagged valve's response to the held command:
    the exact zero-order-hold discretisation of K wn^2 / ((T s + 1)(s^2 + 2 zeta wn s + wn^2)), sampled at dt."""
    plant = Plant(effects={"hyp_coil_lag": {"T": t_ms}})
    rng = np.random.default_rng(11)
    cmd = np.repeat(rng.uniform(-8.0, 8.0, 30), 20)  # held steps of 20 ms
    flow = plant.simulate_valve_test(cmd, supply_bar=70.0).flow_lpm
    t = t_ms * 1e-3
    den = np.polymul([t, 1.0], [1.0, 2.0 * VALVE_ZETA * VALVE_WN, VALVE_WN ** 2])
    a, b, c, d, _ = signal.cont2discrete(signal.tf2ss([VALVE_K * VALVE_WN ** 2], den), plant.dt, method="zoh")
    _, expected, _ = signal.dlsim((a, b, c, d, plant.dt), cmd)
    expected = np.squeeze(expected)  # a row's flow is the state at its start: the response to the rows before
    np.testing.assert_allclose(flow, expected, atol=1e-6 * np.abs(expected).max())  # RK4 at 0.1 ms: ~1e-8
    lag_free = Plant().simulate_valve_test(cmd, supply_bar=70.0).flow_lpm
    assert np.abs(lag_free - expected).max() > 0.05 * np.abs(expected).max()  # the lag is what is tested


@pytest.mark.parametrize("current", [6.0, -6.0])
def test_crank_offset_stroke_ends_are_where_the_piston_is_at_half_stroke(current):
    """Driven into an end stop, the piston (what the LVDT reads) stops at +-half stroke on both sides, and the
    crank at asin((+-h + r sin phi0) / r) from the perpendicular: the ends lie at unequal crank angles."""
    phi0 = 10.0
    plant = Plant(1, effects={"hyp_crank_offset": {"phi0": phi0}})
    r = plant.simulate(np.full(1500, current))
    h, rad = plant.rig.half_stroke, plant.rig.radius
    sign = math.copysign(1.0, current)
    assert r.stroke_end[-1]
    assert math.radians(r.theta_deg[-1]) == pytest.approx(math.asin(sign * h / rad), abs=1e-9)
    crank = math.asin((sign * h + rad * math.sin(math.radians(phi0))) / rad)
    assert math.radians(r.theta_crank_deg[-1]) == pytest.approx(crank, abs=1e-9)
