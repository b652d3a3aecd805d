"""The reference plant against independent truth: analytic solutions, the book's
tables, a plain-Python twin of the right-hand side, and invariants."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ehas_env.physics import layout as K  # baseline indices: the same in every model
from ehas_env.physics.effects import REGISTRY
from ehas_env.simulation.plant import Plant, RigController
from ehas_env.simulation.reference import SineReference
from twin import assert_rhs_matches_twin
from ehas_env.physics.rig import BAR, LPM
from ehas_env.simulation.sensors import Sensors


def run_from_state(plant: Plant, state: np.ndarray, current: np.ndarray) -> np.ndarray:
    out = np.zeros((current.size, K.N_OUT))
    plant.model.run_open_loop(state.copy(), plant.param_vector, current, plant.dt, plant.substeps,
                    np.zeros(K.history_length(0.05, plant.dt)), out)
    return out


# -- the compiled kernel equals the plain-Python equations -------------------

@pytest.mark.parametrize("effect", [None, *sorted(REGISTRY)])
def test_kernel_rhs_matches_reference(effect):
    _assert_matches_twin_at_random_states(Plant(disc_sets=4, effects=[effect] if effect else None), seed=7,
                                          omega=3.0)


def _assert_matches_twin_at_random_states(plant, seed: int, omega: float) -> None:
    """The compiled right-hand side equals the twin's at 20 random states (crank rate within +-omega rad/s)."""
    rng = np.random.default_rng(seed)
    for _ in range(20):
        s = np.array([
            rng.uniform(-0.6, 0.6), rng.uniform(-omega, omega), rng.uniform(-4e-4, 4e-4), rng.uniform(-0.05, 0.05),
            rng.uniform(10e5, 210e5), rng.uniform(10e5, 210e5), rng.uniform(150e5, 220e5), 0.0, rng.uniform(-0.1, 0.1),
        ])
        s[7] = 0.05 * math.sin(s[0]) + rng.uniform(-4e-4, 4e-4)
        assert_rhs_matches_twin(plant, s, rng.uniform(-20, 20))


def _balance_terms():
    from ehas_env.physics.balance_blocks import balance_blocks

    return balance_blocks()


@pytest.mark.parametrize("effect", _balance_terms())
def test_kernel_rhs_matches_reference_with_a_term_at_a_balance(effect):
    """A static term at a balance at a size that acts (its default size is 0: nothing to compare), the break
    inside the states drawn: the compiled right-hand side and the plain-Python twin's agree (the lands' pressures,
    the chambers' flows, the piston's force, the crank's torque)."""
    cls = REGISTRY[effect]
    params = {"c": 0.3 * cls.param("c").bounds[1]}
    if any(p.name == "k" for p in cls.params):
        params["k"] = 0.3 * cls.balance_place.q_span
    _assert_matches_twin_at_random_states(Plant(disc_sets=4, effects={effect: params}), seed=11, omega=12.0)


# -- analytic checks -----------------------------------------------------------

def test_clamped_piston_steady_flow_is_merritt():
    """Clamped piston (huge inertia) with a cross-piston orifice: the steady valve
    flow obeys Q = q_c sqrt((Ps - P_L) / dp_n)."""
    plant = Plant(disc_sets=1, inertia=1e9, effects={"internal_leakage": {"C_leak": 2e-12}})
    for i_mA in (4.0, 10.0, -15.0):
        r = plant.simulate(np.full(3000, i_mA))
        qc = 1.2723 * i_mA  # LPM, steady valve state
        p_l = (r.p_a_bar[-1] - r.p_b_bar[-1]) * BAR
        expected = qc * math.sqrt((220 * BAR - math.copysign(1, qc) * p_l) / (70 * BAR))
        assert abs(r.omega_deg_s[-1]) * math.radians(1) * 0.05 * 7.658e-4 < 1e-4 * abs(r.flow_lpm[-1]) * LPM
        assert r.flow_lpm[-1] == pytest.approx(expected, rel=0.01)
        # and the leak carries exactly that flow
        assert r.flow_lpm[-1] * LPM == pytest.approx(2e-12 * p_l, rel=0.01)


def hydraulic_frequency_written_out(sets: int, theta: float) -> float:
    """Hz: w_h^2 = beta A^2 (r cos theta)^2 (1/V_A + 1/V_B) / I, V = A (L/2 +- x) + V_dead, x = r sin theta.

    The rig's numbers as plain numbers (ehas_env/physics/rig.py, reference-model.md): beta = 1 GPa,
    A = 7.658e-4 m^2, r = 50 mm, L/2 = 35 mm, V_dead = 20 cm^3 per side, I = 0.383 kg m^2 per set.
    """
    beta, area, r, half_stroke, v_dead = 1.0e9, 7.658e-4, 0.05, 0.035, 2.0e-5
    inertia = 0.383 * sets
    x = r * math.sin(theta)
    v_a, v_b = area * (half_stroke + x) + v_dead, area * (half_stroke - x) + v_dead
    return math.sqrt(beta * area**2 * (r * math.cos(theta)) ** 2 * (1 / v_a + 1 / v_b) / inertia) / (2 * math.pi)


def test_hydraulic_frequency_formula_gives_the_reference_models_figures():
    # reference-model.md: "the hydraulic natural frequency is ~24 Hz at 7 sets and ~64 Hz at 1 set"
    assert hydraulic_frequency_written_out(7, 0.0) == pytest.approx(24.0, abs=0.5)
    assert hydraulic_frequency_written_out(1, 0.0) == pytest.approx(64.0, abs=0.5)


@pytest.mark.parametrize("theta_deg", [0.0, 30.0])
@pytest.mark.parametrize("sets", [1, 7])
def test_hydraulic_natural_frequency(sets, theta_deg):
    """Valve shut, small velocity kick at rest at theta: the simulated oil column rings at the
    frequency written out above, and the numerical linearisation's hydraulic mode is the same."""
    f_theory = hydraulic_frequency_written_out(sets, math.radians(theta_deg))
    plant = Plant(disc_sets=sets, dt=1e-4, substeps=4)
    s = plant.initial_state(theta_deg=theta_deg)
    s[1] = 1e-3  # rad/s
    out = run_from_state(plant, s, np.zeros(4000))
    omega = out[:, K.O_OMEGA]
    t = np.arange(omega.size) * plant.dt
    up = np.flatnonzero((omega[:-1] < 0) & (omega[1:] >= 0))
    crossings = t[up] - omega[up] * plant.dt / (omega[up + 1] - omega[up])
    assert crossings.size >= 8  # 0.4 s: 9 cycles at 24 Hz, 25 at 64 Hz
    f_sim = (crossings.size - 1) / (crossings[-1] - crossings[0])
    assert f_sim == pytest.approx(f_theory, rel=1e-5)
    from ehas_env.physics.linearise import linearise

    assert linearise(Plant(disc_sets=sets), theta_deg=theta_deg).hydraulic_wn_hz() == pytest.approx(f_theory, rel=1e-7)


def test_constant_speed_flow_equals_area_times_velocity():
    plant = Plant(disc_sets=1)
    s = plant.initial_state(theta_deg=-35.0)
    out = run_from_state(plant, s, np.full(1500, 2.0))
    theta = out[:, K.O_THETA]
    k = np.argmin(np.abs(theta))  # mid-stroke, long after the start transient
    assert k > 300
    xdot = 0.05 * math.cos(theta[k]) * out[k, K.O_OMEGA]
    assert out[k, K.O_FLOW] == pytest.approx(7.658e-4 * xdot, rel=0.01)


def test_load_equals_inertia_times_acceleration():
    """Mechanics: A (P_A - P_B) = I theta'' / (r cos theta), theta'' by finite differences."""
    plant = Plant(disc_sets=3)
    r = plant.simulate_closed_loop(amplitude_deg=20, freq_hz=2, cycles=3)
    th = np.radians(r.theta_crank_deg)
    acc = (th[2:] - 2 * th[1:-1] + th[:-2]) / plant.dt**2
    load_model = plant.rig.inertia * acc / (0.05 * np.cos(th[1:-1])) * 1e-3
    load = r.load_kN[1:-1]
    err = np.abs(load - load_model)[500:]
    assert err.max() < 0.01 * np.abs(load[500:]).max()


@pytest.mark.parametrize("sets", [1, 2, 3, 4])
@pytest.mark.parametrize("amp", [10, 20, 30])
def test_peak_delta_p_matches_book_tables(book_loads, sets, amp):
    """Tracking a 1 Hz sinusoid well, steady-cycle peak dP matches tables 1.1-1.3 within 5 %.

    Heavier sets (5-7) are not held to 5 %: when the valve reverses, the lightly
    damped hydraulic mode (24-30 Hz) rings and adds to the inertial peak; see
    ``test_heavy_sets_ring_at_hydraulic_mode``.
    """
    row = next(r for r in book_loads if int(r["disc_sets"]) == sets and int(r["amplitude_deg"]) == amp and int(r["freq_hz"]) == 1)
    run = Plant(disc_sets=sets).simulate_closed_loop(amplitude_deg=amp, freq_hz=1, cycles=3)
    steady = run.t >= 1.0
    dp = np.abs(run.p_a_bar - run.p_b_bar)[steady].max()
    assert dp == pytest.approx(float(row["max_delta_p_bar"]), rel=0.05)


def _ringing_near_reversals(run, reversals):
    """Dominant frequency (Hz) and rms (bar) of dP with a cubic trend removed, near each reversal."""
    dp = run.p_a_bar - run.p_b_bar
    freqs, rms = [], []
    for t_rev in reversals:
        m = (run.t > t_rev - 0.03) & (run.t < t_rev + 0.12)
        tt = run.t[m] - run.t[m].mean()
        res = dp[m] - np.polyval(np.polyfit(tt, dp[m], 3), tt)
        spec = np.abs(np.fft.rfft(res * np.hanning(res.size), 8192))
        f = np.fft.rfftfreq(8192, run.t[1] - run.t[0])
        band = f > 5
        freqs.append(f[band][np.argmax(spec[band])])
        rms.append(res.std())
    return float(np.median(freqs)), float(np.mean(rms))


def local_hydraulic_frequency(rig, theta):
    """Hydraulic natural frequency (Hz) with the piston at crank angle theta (rad)."""
    x = rig.radius * math.sin(theta)
    stiffness = rig.beta * rig.area**2 * (1 / (rig.v0 + rig.area * x) + 1 / (rig.v0 - rig.area * x))
    mass = rig.inertia / (rig.radius * math.cos(theta)) ** 2
    return math.sqrt(stiffness / mass) / (2 * math.pi)


def test_heavy_sets_ring_at_hydraulic_mode():
    """Why heavier sets miss the dP tables by more: at each reversal the valve
    passes through null, where its flow-pressure coefficient (the only damping of
    the oil column) vanishes, and the lightly damped hydraulic mode rings.

    With feed-forward alone the ringing is at the local hydraulic frequency of the
    reversal position (30 deg: 23 Hz for 7 sets, 61 Hz for 1 set) and its size grows
    with the inertia.  With the book's Kp = 1 mA/deg the position loop couples
    with that mode and pulls it down (about 14 Hz at 7 sets) - the ringing seen on
    top of the tables' pure-inertia peaks at 5-7 sets.
    """
    reversals = (1.25, 1.75, 2.25)
    rms = {}
    for sets in (1, 7):
        plant = Plant(disc_sets=sets)
        run = plant.simulate_closed_loop(RigController(Kp=0.0, Ki=0.0), amplitude_deg=30, freq_hz=1, cycles=3)
        f_ring, rms[sets] = _ringing_near_reversals(run, reversals)
        assert f_ring == pytest.approx(local_hydraulic_frequency(plant.rig, math.radians(30)), rel=0.1)
    assert rms[7] > 10 * rms[1]
    heavy = Plant(disc_sets=7).simulate_closed_loop(amplitude_deg=30, freq_hz=1, cycles=3)
    f_loop, _ = _ringing_near_reversals(heavy, reversals)
    assert 8.0 < f_loop < 0.8 * local_hydraulic_frequency(Plant(disc_sets=7).rig, math.radians(30))


def test_halving_the_step_changes_little():
    coarse = Plant(disc_sets=5, substeps=10).simulate_closed_loop(amplitude_deg=30, freq_hz=1, duration=2.0)
    fine = Plant(disc_sets=5, substeps=20).simulate_closed_loop(amplitude_deg=30, freq_hz=1, duration=2.0)
    assert np.abs(coarse.theta_deg - fine.theta_deg).max() < 0.001 * 30.0


def test_valve_rated_flow_and_spool_limit():
    r = Plant().simulate_valve_test(np.full(1000, 40.0))  # beyond the amplifier's 20 mA
    assert r.flow_lpm[-1] == pytest.approx(1.2723 * 20, rel=1e-6)
    r70 = Plant().simulate_valve_test(np.full(1000, 20.0), supply_bar=280)
    assert r70.flow_lpm[-1] == pytest.approx(1.2723 * 20 * 2.0, rel=1e-6)


# -- invariants and bad input ------------------------------------------------------

def test_same_seed_bit_identical():
    mk = lambda seed: Plant(disc_sets=2, sensors=Sensors(), seed=seed).simulate_closed_loop(amplitude_deg=10, freq_hz=3)
    a, b, c = mk(11), mk(11), mk(12)
    for name in ("theta_deg", "current_mA", "p_a_bar"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    assert np.array_equal(a.logged["theta_deg"], b.logged["theta_deg"])
    assert not np.array_equal(a.logged["theta_deg"], c.logged["theta_deg"])


@pytest.mark.parametrize("kwargs, words", [
    ({"disc_sets": 0}, "disc_sets"),
    ({"disc_sets": 8}, "disc_sets"),
    ({"inertia": -1.0}, "inertia"),
    ({"effects": {"magic_friction": {}}}, "unknown effect 'magic_friction'"),
    ({"effects": {"coulomb_friction": {"Fk": 3}}}, "no parameter 'Fk'"),
    ({"effects": {"coulomb_friction": {"Fc": -3}}}, "'Fc'"),
])
def test_bad_plant_arguments(kwargs, words):
    with pytest.raises(ValueError, match=words):
        Plant(**kwargs)


def test_bad_run_arguments():
    with pytest.raises(ValueError, match="amplitude_deg"):
        Plant().simulate_closed_loop(amplitude_deg=44.5)
    with pytest.raises(ValueError, match="non-finite"):
        Plant().simulate(np.array([0.0, np.nan]))
    with pytest.raises(ValueError, match="rate_hz"):
        Plant().simulate_closed_loop(RigController(rate_hz=500.0))


def test_book_controller_tracks_design_point():
    """+-30 deg at 3 Hz with 7 sets (the design point) stays off the stroke ends."""
    r = Plant(disc_sets=7).simulate_closed_loop(amplitude_deg=30, freq_hz=3, cycles=4)
    assert not r.hit_stroke_end
    assert np.abs(r.theta_deg).max() < 40.0


def test_reference_fades_in_from_rest():
    run = Plant(disc_sets=1).simulate_closed_loop(amplitude_deg=20, freq_hz=2, cycles=2)
    ref = SineReference(20, 2)
    d = ref.derivatives(np.array([0.0, 0.5, 0.6]))
    assert d[:, 0] == pytest.approx([0, 0, 0, 0], abs=1e-12)  # at rest at t = 0
    w = 4 * math.pi
    assert d[:, 2] == pytest.approx([20 * math.sin(w * 0.6), 20 * w * math.cos(w * 0.6),
                                     -20 * w * w * math.sin(w * 0.6), -20 * w**3 * math.cos(w * 0.6)])
    assert run.theta_ref_deg[0] == 0.0
    # the derivatives are those of the position: finite differences agree during the fade-in
    t = np.linspace(0.0, 0.5, 2001)
    d = ref.derivatives(t)
    for k in range(3):
        np.testing.assert_allclose(np.gradient(d[k], t)[5:-5], d[k + 1][5:-5], atol=2e-3 * np.abs(d[k + 1]).max())


def test_python_controller_loop_equals_compiled_loop():
    class PI:
        def __init__(self, g):
            self.g = g
            self.integ = 0.0

        def reset(self):
            self.integ = 0.0

        def act(self, m):
            e = m["theta_ref_deg"] - m["theta_deg"]
            u_ff = self.g.Kv * m["theta_ref_dot"] + self.g.Ka * m["theta_ref_ddot"]
            u_try = self.g.Kp * e + self.g.Ki * (self.integ + e * 1e-3) + u_ff
            if -20 < u_try < 20 or (u_try >= 20 and e < 0) or (u_try <= -20 and e > 0):
                self.integ += e * 1e-3
            return self.g.Kp * e + self.g.Ki * self.integ + u_ff

    g = RigController.book()
    plant = Plant(disc_sets=2)
    fast = plant.simulate_closed_loop(g, amplitude_deg=20, freq_hz=2, cycles=2)
    slow = plant.simulate_closed_loop(PI(g), amplitude_deg=20, freq_hz=2, cycles=2)
    np.testing.assert_allclose(slow.theta_deg, fast.theta_deg, atol=1e-9)
