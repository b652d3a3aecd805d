"""Characteristic curves and the position loop against analytic truth and the
nonlinear plant (the margins must predict where the simulated loop goes unstable)."""
from __future__ import annotations

import math

import control
import numpy as np
import pytest

from ehas_env.identification import curves as C
from ehas_env.cli.main import main
from ehas_env.simulation.plant import Plant, RigController
from ehas_env.physics.white_box_valve import WhiteBoxValve


def test_flow_vs_current_and_the_current_for_full_flow():
    # Merritt, no load: Q = K i sqrt(Ps / 70 bar); the rated test gives K x 20 mA
    assert C.flow_vs_current(20.0, 70.0) == pytest.approx(1.2723 * 20.0)
    assert C.flow_vs_current(10.0, 280.0) == pytest.approx(1.2723 * 10.0 * 2.0)
    assert C.flow_vs_current(30.0, 70.0) == C.flow_vs_current(20.0, 70.0)  # amplifier limit
    need = [C.current_for_flow(25.0, ps) for ps in (70.0, 140.0, 220.0)]
    assert need[0] > need[1] > need[2]  # a higher supply needs less current
    assert need[2] == pytest.approx(25.0 / (1.2723 * math.sqrt(220 / 70)))


def test_lap_flow_gains():
    v = WhiteBoxValve()
    kq = v.K3 * math.sqrt(220 / 70) / 1e-3 * 60 / 1e3  # LPM per mm, critically lapped
    x = np.array([-0.02e-3, 0.02e-3])
    assert np.diff(C.lap_flow(x, 0.0))[0] / 0.04 == pytest.approx(kq)
    assert np.diff(C.lap_flow(x, C.LAP))[0] / 0.04 == pytest.approx(2 * kq)  # both lands meter inside the underlap
    assert np.all(C.lap_flow(x, -C.LAP) == 0.0)  # dead zone inside the overlap
    far = np.array([0.2e-3, 0.25e-3])
    for lap in (C.LAP, 0.0, -C.LAP):  # beyond the lap every spool has the critical gain
        assert np.diff(C.lap_flow(far, lap))[0] / 0.05 == pytest.approx(kq)


def test_blocked_port_pressure():
    x = np.linspace(-0.2e-3, 0.2e-3, 41)
    for lap in (C.LAP, 0.0, -C.LAP):
        p = C.lap_pressure(x, lap)
        np.testing.assert_allclose(p, -p[::-1], atol=1e-6)  # antisymmetric
        assert np.all(np.diff(p) > 0) and p[-1] == pytest.approx(220.0, rel=0.01)
    kp = {lap: C.pressure_gain(lap) for lap in (C.LAP, 0.0, -C.LAP)}
    assert kp[0.0] > 5 * max(kp[C.LAP], kp[-C.LAP])
    # underlap, orifices only: P_L = Ps ((U+x)^2 - (U-x)^2) / ((U+x)^2 + (U-x)^2) -> slope 2 Ps / U at null
    assert kp[C.LAP] == pytest.approx(2 * 220 / (C.LAP * 1e6), rel=0.25)
    # overlap, laminar leakage only: P_A = Ps (O + x) / 2 O -> slope Ps / O
    assert kp[-C.LAP] == pytest.approx(220 / (C.LAP * 1e6), rel=0.1)


def test_linear_plant_follows_the_nonlinear_plant_for_a_small_step():
    plant = Plant(disc_sets=3)
    G = C.linear_plant(plant)
    u = np.r_[0.0, np.full(199, 0.2)]
    t = np.arange(200) * 1e-3
    lin = control.forced_response(control.sample_system(G[0, 0], 1e-3, "zoh"), t, u).outputs
    sim = plant.simulate(u).theta_deg
    np.testing.assert_allclose(sim[50:], lin[50:], rtol=0.01)


def test_hydraulic_resonance_of_the_linear_plant():
    # mid-stroke oil column written out (rig.py's numbers): w_h^2 = beta A^2 r^2 (2 / V0) / I,
    # V0 = A 35 mm + 20 cm^3, I = 0.383 kg m^2 per set; reference-model.md: ~64 Hz at 1 set, ~24 Hz at 7
    v0 = 7.658e-4 * 0.035 + 2.0e-5
    for n, approx_hz in ((1, 64.0), (7, 24.0)):
        f_h = math.sqrt(1.0e9 * 7.658e-4**2 * 0.05**2 * (2 / v0) / (0.383 * n)) / (2 * math.pi)
        assert f_h == pytest.approx(approx_hz, abs=0.5)
        assert C.position_loop(Plant(disc_sets=n))["hydraulic_hz"] == pytest.approx(f_h, rel=1e-6)


def _late_oscillation(plant, ctrl) -> float:
    """Largest 10-30 Hz error (deg) in the last 0.5 s of a 2.5 s run on a small reference, no feed-forward."""
    from scipy.signal import butter, filtfilt

    res = plant.simulate_closed_loop(ctrl, amplitude_deg=0.5, freq_hz=0.5, cycles=1.25)
    e = res.theta_ref_deg - res.theta_deg
    b, a = butter(2, [10 / 500, 30 / 500], "band")
    return float(np.abs(filtfilt(b, a, e))[-700:-200].max())


def test_gain_margin_predicts_where_the_nonlinear_loop_goes_unstable():
    plant = Plant(disc_sets=3)
    book = RigController.book()
    loop = C.position_loop(plant, book)
    assert loop["closed_loop_stable"] and loop["gain_margin_db"] > 3
    gm = loop["gain_margin"]
    scaled = lambda f: RigController(Kp=book.Kp * gm * f, Ki=book.Ki * gm * f, Kv=0.0, Ka=0.0)
    assert _late_oscillation(plant, scaled(0.8)) < 1e-3  # below the margin: no oscillation builds up
    assert _late_oscillation(plant, scaled(1.25)) > 0.05  # beyond it: an oscillation of the phase crossover grows
    assert not C.position_loop(plant, scaled(1.25))["closed_loop_stable"]


def test_transport_delay_costs_phase_margin_omega_tau():
    base = C.position_loop(Plant(disc_sets=3))
    delayed = C.position_loop(Plant(disc_sets=3, effects={"transport_delay": {"tau": 0.004}}))
    wc = 2 * math.pi * base["crossover_hz"]
    assert delayed["crossover_hz"] == pytest.approx(base["crossover_hz"], rel=1e-3)  # a delay leaves |L| alone
    assert base["phase_margin_deg"] - delayed["phase_margin_deg"] == pytest.approx(math.degrees(wc * 0.004), abs=0.3)


def test_feed_forward_does_not_change_the_margins():
    a = C.position_loop(Plant(), RigController(Kp=1.0, Ki=2.0, Kv=0.0, Ka=0.0))
    b = C.position_loop(Plant(), RigController(Kp=1.0, Ki=2.0, Kv=0.05, Ka=0.01))
    assert a["gain_margin_db"] == b["gain_margin_db"] and a["phase_margin_deg"] == b["phase_margin_deg"]


def test_curves_command_writes_figures_and_summary(tmp_path, capsys):
    assert main(["curves", "--out", str(tmp_path), "--disc-sets", "5", "--gains", "Kp=0.8,Ki=1"]) == 0
    names = {p.name for p in tmp_path.iterdir()}
    assert {"flow_vs_current.png", "flow_gain_vs_stroke.png", "pressure_gain.png", "valve_bode.png",
            "position_loop_bode.png", "README.md"} <= names
    text = (tmp_path / "README.md").read_text()
    loop = C.position_loop(Plant(disc_sets=5), RigController(Kp=0.8, Ki=1.0))
    assert f"{loop['phase_margin_deg']:.1f}" in text and "Regenerate: `ehas curves" in text
    assert f"phase margin {loop['phase_margin_deg']:.1f} deg" in capsys.readouterr().out
    assert main(["curves", "--out", str(tmp_path / "x"), "--supplies", "70,-3"]) == 2
    assert "--supplies" in capsys.readouterr().err
