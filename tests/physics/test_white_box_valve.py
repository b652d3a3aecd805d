"""The white-box valve against independent truth: the book's numbers in its own
units, its closed-form steady state, a finite-difference Jacobian, the
compiled kernel against the plain-Python equations, and the plant's API."""
from __future__ import annotations

import math

import control
import numpy as np
import pytest

from ehas_env.physics import layout as K  # baseline indices: the same in every model
from ehas_env.simulation.plant import Plant, RigController
from twin import assert_rhs_matches_twin
from ehas_env.identification.white_box_comparison import comparison
from ehas_env.physics.white_box_valve import WhiteBoxValve, slot_rates

IN3_PER_S_TO_LPM = 16.387064e-3 * 60.0  # 1 in^3 = 16.387064 cm^3


def test_book_parameters_in_si():
    v = WhiteBoxValve()
    lbf_in = 4.4482216152605 * 0.0254  # N m
    assert v.Kt == pytest.approx(0.0249 * lbf_in, rel=1e-12)
    assert v.Kw == pytest.approx(16 * lbf_in / 0.0254, rel=1e-12)
    assert v.Kf == pytest.approx(92 * lbf_in, rel=1e-12)
    assert v.K2 == pytest.approx(112 * 0.0254**2, rel=1e-12)
    assert v.K3 == pytest.approx(920 * 0.0254**2, rel=1e-12)
    # the assumed reading of the book's 735 Hz: the armature's natural frequency sqrt(Kf / Ja), so
    # Ja = Kf / (2 pi 735 Hz)^2 with Kf = 92 in lb/rad: 10.3946 N m/rad / 4618.1^2 = 4.874e-7 kg m^2
    ja = 92 * 4.4482216152605 * 0.0254 / (2 * math.pi * 735.0) ** 2
    assert ja == pytest.approx(4.874e-7, rel=1e-3)
    assert v.Ja == pytest.approx(ja, rel=1e-9)
    # and the equations ring there: armature alone (no flow forces, spool and armature at rest at
    # null but for a small angle), theta'' = -Kf theta / Ja = -(2 pi 735)^2 theta; damping 2 zeta_a w_h
    chain = WhiteBoxValve(flow_forces=False)
    for ps in (70e5, 220e5):
        assert chain.rhs((1e-6, 0.0, 0.0), 0.0, ps)[1] == pytest.approx(-(2 * math.pi * 735.0) ** 2 * 1e-6, rel=1e-9)
        assert chain.rhs((0.0, 1.0, 0.0), 0.0, ps)[1] == pytest.approx(-2 * 0.4 * 2 * math.pi * 735.0, rel=1e-9)
    # port width from Merritt's orifice law at the book's rated point: K3 = Cd w sqrt(dp_n / rho), so
    # w = 920 in^3/s/in / (0.61 sqrt(70 bar / 850 kg/m^3)) = 0.59355 m^2/s / 55.36 m/s = 10.72 mm
    w = 920 * 0.0254**2 / (0.61 * math.sqrt(70e5 / 850.0))
    assert w == pytest.approx(10.72e-3, rel=1e-3)
    assert v.w == pytest.approx(w, rel=1e-9)
    # the book's steady flow force 0.43 w dP x_v (Cd 0.61, Cv 0.98, 69 deg jet) uses that width
    assert v.kff == pytest.approx(0.43 * w, rel=0.01)


def test_book_chain_steady_state_is_28_2_lpm():
    # rig.md: Q = K3 Kt i / Kw gives 28.2 LPM at 20 mA, computed here in the book's units
    q_book = 920 * 0.0249 * 20 / 16 * IN3_PER_S_TO_LPM
    assert round(q_book, 1) == 28.2
    v = WhiteBoxValve()
    assert v.book_chain_flow_lpm(20.0) == pytest.approx(q_book, rel=1e-9)
    # without flow forces the model's steady state is that chain, whatever the assumed geometry
    for geom in ({}, {"r": 0.01, "d_spool": 0.005, "zeta_a": 0.7}):
        chain = WhiteBoxValve(flow_forces=False, **geom)
        assert chain.steady_flow_lpm(20.0) == pytest.approx(q_book, rel=1e-9)


@pytest.mark.parametrize("i_mA, supply", [(20.0, 70.0), (-20.0, 70.0), (8.0, 70.0), (20.0, 220.0)])
def test_simulated_steady_flow_equals_the_analytic_steady_state(i_mA, supply):
    v = WhiteBoxValve()
    res = Plant(valve="white_box").simulate_valve_test(np.full(300, i_mA), supply_bar=supply)
    assert res.flow_lpm[-1] == pytest.approx(v.steady_flow_lpm(i_mA, supply), rel=1e-6)
    assert res.flow_lpm[-1] == pytest.approx(-v.steady_flow_lpm(-i_mA, supply), rel=1e-9)  # symmetric


def test_flow_forces_lower_the_gain_below_the_book_chain():
    v = WhiteBoxValve()
    q = v.steady_flow_lpm(20.0)
    assert 24.0 < q < v.book_chain_flow_lpm(20.0)
    # a larger nozzle gap means a larger pilot pressure-flow coefficient: more loss of gain
    assert WhiteBoxValve(x_f0=50e-6).steady_flow_lpm(20.0) < q < WhiteBoxValve(x_f0=25e-6).steady_flow_lpm(20.0)


def test_linearisation_equals_finite_differences_of_the_equations():
    v = WhiteBoxValve()
    ps = 150e5
    A, B, C = v.linearize(ps / 1e5)
    f = lambda x, i=0.0: np.array(v.rhs(x, i, ps))
    J = np.zeros((3, 3))
    x0 = np.array([0.0, 0.0, 1e-9])  # just off null, on the side the linearisation takes (sign(+0) = +1)
    for j, h in enumerate((1e-7, 1e-3, 1e-9)):
        dx = np.zeros(3)
        dx[j] = h
        J[:, j] = (f(x0 + dx) - f(x0 - dx)) / (2 * h)
    np.testing.assert_allclose(J, A, rtol=1e-5, atol=1e-6 * np.abs(A).max())
    np.testing.assert_allclose((f(x0, 1.0) - f(x0, -1.0)) / 2, B[:, 0], rtol=1e-9)


def test_small_signal_step_follows_the_linearisation():
    v = WhiteBoxValve()
    i = np.r_[0.0, np.full(79, 0.5)]
    t = np.arange(80) * 1e-3
    sim = Plant(valve="white_box").simulate_valve_test(i, supply_bar=70.0).flow_lpm
    lin = control.forced_response(control.sample_system(v.transfer_function(70.0), 1e-3, "zoh"), t, i).outputs
    np.testing.assert_allclose(sim, lin, atol=2e-3 * abs(lin[-1]))


def test_compiled_kernel_equals_the_python_equations():
    rng = np.random.default_rng(5)
    plant = Plant(disc_sets=2, valve="white_box")
    for _ in range(30):
        s = np.zeros(11)
        s[:9] = [rng.uniform(-0.6, 0.6), rng.uniform(-3, 3), rng.uniform(-4e-4, 4e-4), 0.0,
                 rng.uniform(10e5, 210e5), rng.uniform(10e5, 210e5), rng.uniform(150e5, 220e5), 0.0, 0.0]
        s[7] = 0.05 * math.sin(s[0])
        s[9], s[10] = rng.uniform(-4e-3, 4e-3), rng.uniform(-5, 5)
        i_v = rng.uniform(-20, 20)
        # against the plant's plain-Python twin (which calls white_box_valve.slot_rates)
        ds = assert_rhs_matches_twin(plant, s, i_v)
        # and against the dataclass form of the valve (x_v instead of q_c = K3 x_v)
        v = plant.white_box
        d = v.rhs((s[9], s[10], s[2] / v.K3), i_v, s[6], s[4] - s[5])
        np.testing.assert_allclose([ds[9], ds[10], ds[2] / v.K3], d, rtol=1e-10)


def test_kernel_bench_equals_the_plain_python_integration():
    v = WhiteBoxValve()
    i = np.r_[np.zeros(5), np.full(40, 20.0), np.full(40, -12.0)]
    np.testing.assert_allclose(Plant(valve="white_box").simulate_valve_test(i).flow_lpm, v.simulate_bench(i),
                               rtol=1e-10, atol=1e-10)


def test_plant_with_the_white_box_valve():
    p = Plant(disc_sets=3, valve="white_box")
    assert "valve=white_box" in repr(p) and p.param_vector[K.I_VALVE_MODEL] == K.WHITE_BOX
    a = p.simulate_closed_loop(RigController.book(), amplitude_deg=20, freq_hz=1, cycles=3)
    b = Plant(disc_sets=3, valve="white_box").simulate_closed_loop(RigController.book(), amplitude_deg=20,
                                                                    freq_hz=1, cycles=3)
    assert np.array_equal(a.theta_deg, b.theta_deg) and a.meta["valve"] == "white_box"
    assert a.tracking_errors()["rms_error_pct"] < 2.0
    with pytest.raises(ValueError, match="valve must be one of grey_box, white_box"):
        Plant(valve="black_box")


def test_grey_box_ignores_the_white_box_slots():
    g1 = Plant().simulate_closed_loop(RigController.book(), amplitude_deg=20, freq_hz=2, cycles=3)
    g2 = Plant(white_box=WhiteBoxValve(r=0.02, d_spool=0.01)).simulate_closed_loop(
        RigController.book(), amplitude_deg=20, freq_hz=2, cycles=3)
    assert np.array_equal(g1.theta_deg, g2.theta_deg) and "valve" not in g1.meta
    assert Plant().param_vector[K.I_VALVE_MODEL] == 0.0


def test_comparison_table_shows_the_book_figures_and_the_models(tmp_path):
    text = comparison(tmp_path).read_text()
    v = WhiteBoxValve()
    for figure in ("| 25 |", "| 25.6 |", "| 26 |", "25.45 / -25.45", f"{v.book_chain_flow_lpm(20):.2f}",
                   f"{v.steady_flow_lpm(20):.2f} / {-v.steady_flow_lpm(20):.2f}", "Regenerate:"):
        assert figure in text, figure
    assert (tmp_path / "step.png").exists() and (tmp_path / "bode.png").exists()
