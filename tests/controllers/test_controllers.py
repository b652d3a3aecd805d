"""Controllers: the shared interface, the PI + feed-forward law, files, the batched simulator, the linear model.

Truth used: the compiled closed loop of ehas_env (the model's compiled closed_loop via
Plant.simulate_closed_loop) and ehas_env.simulation.metrics for the Python twin and the batch
simulator; the rig's analytic numbers (velocity gain, hydraulic frequency) and the
series expansion of the inverse plant written out by hand for the linear model.
"""
from __future__ import annotations

import doctest
import json
import math

import numpy as np
import pytest

from ehas_controllers import base, batch_sim, benchmark, linear_model, piff, tuners
from ehas_controllers.base import Controller, load_controller, register_loader
from ehas_controllers.batch_sim import Batch, Condition, evaluate
from ehas_controllers.linear_model import LinearPlant, operating_flow_lpm
from ehas_controllers.piff import PIFF, GainSchedule
from ehas_env.simulation.metrics import tracking_errors
from ehas_env.simulation.plant import Plant, RigController
from ehas_env.physics.rig import LPM, RigParams
from ehas_env.simulation.sensors import Sensors
from refusals import refused  # tests/ is on sys.path (conftest.py)


@pytest.mark.parametrize("module", [base, piff, batch_sim, linear_model, tuners, benchmark])
def test_docstring_examples_run(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0


# -- the PI + feed-forward law ---------------------------------------------------
@pytest.mark.parametrize("gains", [
    dict(),  # the book's
    dict(Kp=1.3, Ki=4.0, Kj=2.4e-6, Kdp=0.01),  # jerk + static pressure feedback
    dict(Kp=0.8, Ki=1.0, Kj=2.0e-6, Kdp=0.02, dp_hp=15.0),  # dynamic pressure feedback
])
def test_python_act_is_the_compiled_loop(gains):
    ctrl = PIFF(**gains)
    plant = Plant(disc_sets=5, effects={"coulomb_friction": {"Fc": 300}})
    py = plant.simulate_closed_loop(ctrl, amplitude_deg=20, freq_hz=3, cycles=2.5)
    nb = plant.simulate_closed_loop(ctrl.rig_gains(), amplitude_deg=20, freq_hz=3, cycles=2.5)
    np.testing.assert_allclose(py.current_mA, nb.current_mA, rtol=0, atol=1e-9)
    np.testing.assert_allclose(py.theta_deg, nb.theta_deg, rtol=0, atol=1e-9)


def _meas(theta=0.0, ref=0.0, rd=0.0, pa=110.0, pb=110.0):
    return {"t": 0.0, "theta_deg": theta, "theta_ref_deg": ref, "theta_ref_dot": rd, "theta_ref_ddot": 0.0,
            "theta_ref_dddot": 0.0, "p_a_bar": pa, "p_b_bar": pb, "p_s_bar": 220.0}


def test_anti_windup_stops_integrating_while_saturated():
    c = PIFF(Kp=5.0, Ki=50.0, Kv=0.0, Ka=0.0)
    for _ in range(500):  # 0.5 s at a 10 deg error: the output sits at +20 mA
        assert c.act(_meas(theta=0.0, ref=10.0)) == 20.0
    assert c._mem[0] == 0.0  # the law's integral memory
    # once the error reverses the output leaves the limit at once (no wound-up integral)
    assert c.act(_meas(theta=1.0, ref=0.0)) == pytest.approx(-5.0, abs=0.06)


def test_twelve_bit_output_is_quantized():
    c = PIFF(Kp=0.37, Ki=0.0, output_bits=12)
    lsb = 40.0 / 4096
    for th in np.linspace(-3, 3, 37):
        u = c.act(_meas(theta=float(th)))
        assert u / lsb == pytest.approx(round(u / lsb), abs=1e-9)
        assert abs(u - (-0.37 * th)) <= lsb / 2 + 1e-12


def test_pressure_feedback_sign_and_high_pass():
    static = PIFF(Kp=0.0, Ki=0.0, Kv=0.0, Ka=0.0, Kdp=0.05)
    assert static.act(_meas(pa=150.0, pb=50.0)) == pytest.approx(-5.0)  # -Kdp * P_L
    dynamic = PIFF(Kp=0.0, Ki=0.0, Kv=0.0, Ka=0.0, Kdp=0.05, dp_hp=20.0)
    u = [dynamic.act(_meas(pa=150.0, pb=50.0)) for _ in range(3000)]
    assert u[0] == pytest.approx(-5.0 * (1 - 0.02), rel=1e-12)  # one high-pass step
    assert abs(u[-1]) < 1e-6  # a constant load pressure is not fed back


def test_repr_names_gains_with_units_and_variants():
    assert "Kp=1 mA/deg" in repr(PIFF.book()) and "Ki=2 mA/(deg s)" in repr(PIFF.book())
    assert PIFF(Kj=1e-6).variant == "PI+FF+jerk"
    assert PIFF(Kdp=0.01).variant == "PI+FF +dP static"
    assert PIFF(Kdp=0.01, dp_hp=5).variant == "PI+FF +dP dynamic"
    assert "Kdp=0.01 mA/bar" in repr(PIFF(Kdp=0.01, dp_hp=5)) and "dp_hp=5 rad/s" in repr(PIFF(Kdp=0.01, dp_hp=5))


@pytest.mark.parametrize("bad, match", [
    (dict(Kp=float("nan")), "Kp must be a finite number"),
    (dict(i_max=25.0), "i_max must be in"),
    (dict(dp_hp=-1.0), "dp_hp must be >= 0"),
    (dict(output_bits=2.5), "output_bits"),
    # the ranges the compiled loop holds gains to (a gain of 1e308 overflows it; fault campaign cont021, cont033)
    (dict(Kp=1e308), r"PIFF: Kp must be a number in \[-1000000, 1000000\]"),
    (dict(rate_hz=1e9), r"PIFF: rate_hz must be a number in \[1, 1000000\] Hz"),
])
def test_bad_gains_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        PIFF(**bad)


# -- files ---------------------------------------------------------------------------
def test_save_load_round_trip(tmp_path):
    c = PIFF(Kp=1.1, Ki=0.5, Kv=0.0177, Ka=3e-4, Kj=2e-6, Kdp=0.01, dp_hp=12.0, output_bits=12, name="mine")
    path = c.save(tmp_path / "c.json", command="ehas tune --method model", metrics={"mean_rms_error_pct": 1.5})
    data = json.loads(path.read_text())
    assert data["format"] == "ehas-controller" and data["kind"] == "classical"
    assert data["units"]["Kdp"] == "mA/bar" and data["command"] == "ehas tune --method model"
    assert data["mean_rms_error_pct"] == 1.5
    back = load_controller(path)
    assert back == c and back.output_bits == 12 and back.name == "mine"
    assert [p.name for p in tmp_path.iterdir()] == ["c.json"]  # no temporary file left behind


def test_schedule_round_trip_and_interpolation(tmp_path):
    s = GainSchedule({1: PIFF(Kp=1.0, Kj=1e-6), 5: PIFF(Kp=2.0, Kj=3e-6)}, name="s")
    back = load_controller(s.save(tmp_path / "s.json"))
    assert isinstance(back, GainSchedule) and list(back.entries) == [1, 5]
    mid = back.for_plant(3)
    assert mid.Kp == pytest.approx(1.5) and mid.Kj == pytest.approx(2e-6)
    assert back.for_plant(7).Kp == 2.0 and back.rig_gains(1).Kp == 1.0
    with pytest.raises(ValueError, match="select"):
        back.act(_meas())
    assert back.select(5).act(_meas(theta=-1.0)) == pytest.approx(2.0 + 2.0 * 1e-3)


def test_loading_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.json"):
        load_controller(tmp_path / "nope.json")
    (tmp_path / "x.txt").write_text("{}")
    with pytest.raises(ValueError, match="no loader for '.txt'"):
        load_controller(tmp_path / "x.txt")
    (tmp_path / "bad.json").write_text('{"format": "ehas-controller", "version": 1, "type": "rocket"}')
    with pytest.raises(ValueError, match=r"bad.json.*'rocket' is unknown"):
        load_controller(tmp_path / "bad.json")
    (tmp_path / "gain.json").write_text('{"format": "ehas-controller", "version": 1, "type": "piff", "gains": {"Kq": 1}}')
    with pytest.raises(ValueError, match="unknown gain.*Kq"):
        load_controller(tmp_path / "gain.json")
    (tmp_path / "broken.json").write_text('{"type": ')
    with pytest.raises(ValueError, match="not valid JSON"):
        load_controller(tmp_path / "broken.json")


def _file(tmp_path, **change):
    """A controller file as ehas tune writes it, with keys changed (``...``: the key removed)."""
    doc = PIFF(Kp=1.5).to_dict()
    doc = {"format": "ehas-controller", "version": 1, **doc}
    for k, v in change.items():
        if v is ...:
            doc.pop(k)
        else:
            doc[k] = v
    path = tmp_path / "c.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("change, words", [
    (dict(type=None), ["key 'type' = None is not a type name; expected one of", "piff"]),
    (dict(type=["piff"]), ["key 'type' = ['piff'] is not a type name"]),
    (dict(gains=...), ["no 'gains' field; expected \"gains\": {gain name: number} with some of Kp, Ki"]),
    (dict(gains={}), ["'gains' is empty; expected some of Kp, Ki"]),
    (dict(gains=[1, 2]), ["'gains' must be an object"]),
    (dict(kind="bogus"), ["key 'kind' = 'bogus'; expected one of 'classical', 'learned'"]),
    (dict(kind="learned"), ["key 'kind' = 'learned', but a 'piff' controller is 'classical'"]),
    (dict(type="schedule", entries={"3": {"variant": "PI+FF"}}), ["entries['3']: no 'gains' field"]),
])
def test_controller_file_fields_are_refused_naming_file_and_field(tmp_path, change, words):
    path = _file(tmp_path, **change)
    refused(lambda: load_controller(path), f"controller file {path}: ", *words)


@pytest.mark.parametrize("change", [dict(kind=...), dict(kind="classical"), dict(gains={"Kp": 1.0, "Ki": 2.0}),
                                    dict(my_note="hello")])
def test_controller_file_variants_that_are_fine(tmp_path, change):
    assert load_controller(_file(tmp_path, **change)).kind == "classical"


def test_bare_gains_dict_still_builds_a_piff():
    """The Python API's bare {gain: value} dict (no file, no 'gains' key) keeps working."""
    assert PIFF.from_dict({"Kp": 2.0}).Kp == 2.0
    assert base.controller_from_dict({"gains": {"Kp": 2.0}}).Kp == 2.0


@pytest.mark.parametrize("content", [bytes(range(128, 256)), b"\xff\xfe{\x00}\x00"])
def test_controller_file_that_is_not_utf8_text(tmp_path, content):
    path = tmp_path / "c.json"
    path.write_bytes(content)
    refused(lambda: load_controller(path), str(path), "UTF-8", "expected a controller JSON file")


def test_a_folder_named_like_a_controller_file(tmp_path):
    (tmp_path / "c.json").mkdir()
    # a folder is an agent folder to the registry: it says what is missing there
    refused(lambda: load_controller(tmp_path / "c.json"), "c.json", exc=(ValueError, FileNotFoundError))


class _Learned(Controller):
    kind = "learned"
    name = "fake agent"

    def act(self, measurement):
        return 0.0


def test_a_new_file_type_is_one_registration(tmp_path):
    register_loader(".fake", lambda path: _Learned())
    try:
        (tmp_path / "agent.fake").write_text("")
        ctrl = load_controller(tmp_path / "agent.fake")
        assert ctrl.kind == "learned"
    finally:
        base.LOADERS.pop(".fake")


# -- the batched simulator ---------------------------------------------------------
def test_batch_metrics_equal_the_plant_and_metrics_module():
    ctrl = PIFF(Kp=1.2, Ki=3.0, Kj=2e-6, Kdp=0.005, dp_hp=8.0)
    conds = [Condition(2, 3.0, 10.0), Condition.with_effects(6, 1.0, 30.0, {"transport_delay": {"tau": 0.004}})]
    sensors = Sensors()
    rows = evaluate(ctrl, conds, cycles=3, sensors=sensors, seed=7)
    for c, row in zip(conds, rows):
        run = Plant(disc_sets=c.disc_sets, effects=c.effects_dict or None, sensors=sensors, seed=7) \
            .simulate_closed_loop(ctrl.rig_gains(), amplitude_deg=c.amplitude_deg, freq_hz=c.freq_hz, cycles=3)
        truth = tracking_errors(run.t, run.theta_ref_deg, run.theta_deg, c.amplitude_deg, c.freq_hz)
        assert row["rms_error_pct"] == pytest.approx(truth["rms_error_pct"], rel=1e-12)
        assert row["peak_error_pct"] == pytest.approx(truth["peak_error_pct"], rel=1e-12)
        assert row["max_current_mA"] == pytest.approx(np.abs(run.current_mA).max(), rel=1e-12)
        assert row["peak_delta_p_bar"] == pytest.approx(np.abs(run.p_a_bar - run.p_b_bar).max(), rel=1e-12)
        assert row["hit_stroke_end"] == run.hit_stroke_end


def test_batch_flags_saturation_and_stroke_ends():
    # no feed-forward and a huge proportional gain: the command sits at the limits much of the time
    rows = evaluate(PIFF(Kp=40.0, Ki=0.0, Kv=0.0, Ka=0.0), [Condition(1, 3.0, 40.0)], cycles=3)
    assert rows[0]["saturation_frac"] > 0.05 and rows[0]["max_current_mA"] == 20.0
    # positive position feedback runs away into a stroke end
    rows = evaluate(PIFF(Kp=-2.0, Ki=0.0), [Condition(1, 1.0, 10.0)], cycles=3)
    assert rows[0]["hit_stroke_end"] is True
    assert evaluate(PIFF.book(), [Condition(1, 1.0, 10.0)], cycles=3)[0]["hit_stroke_end"] is False


def test_batch_refuses_too_short_runs():
    with pytest.raises(ValueError, match="cycles must be > 2"):
        Batch([Condition(1, 1.0, 10.0)], cycles=2)


# -- the linear model ----------------------------------------------------------------
@pytest.mark.parametrize("n", [1, 4, 7])
def test_linear_model_numbers_are_the_rigs(n):
    lp = LinearPlant(disc_sets=n)
    # mid-stroke oil column, written out with the rig's numbers (rig.py, reference-model.md):
    # w_h^2 = beta A^2 r^2 (1/V_A + 1/V_B) / I, V_A = V_B = A 35 mm + 20 cm^3, I = 0.383 kg m^2 per set
    v0 = 7.658e-4 * 0.035 + 2.0e-5
    wn = math.sqrt(1.0e9 * 7.658e-4**2 * 0.05**2 * (2 / v0) / (0.383 * n))
    assert lp.hydraulic_wn == pytest.approx(wn, rel=1e-12)
    assert RigParams.for_disc_sets(n).hydraulic_natural_frequency() == pytest.approx(wn, rel=1e-12)
    # K * sqrt(Ps / dp_n) / (A r): 56.25 deg/s per mA, the book's 1/Kv
    assert lp.velocity_gain == pytest.approx(56.25, rel=1e-3)
    assert abs(lp.hydraulic_zeta) < 1e-9  # critically lapped valve, no leakage, null flow


@pytest.mark.parametrize("kdp, hp", [(0.0, 0.0), (0.02, 0.0), (0.01, 25.0)])
def test_transfer_function_equals_the_state_space_model(kdp, hp):
    import control

    lp = LinearPlant(disc_sets=5, flow_lpm=4.0)
    ss = lp.state_space(kdp, hp)
    w = np.geomspace(1, 3000, 40)
    for out, tf in ((0, lp.tf(kdp, hp, delay=False)), (1, lp.tf_load(kdp, hp, delay=False))):
        ref = control.ss2tf(ss[out, 0])
        np.testing.assert_allclose(tf(1j * w), ref(1j * w), rtol=1e-6)


def test_inverse_series_is_the_hand_expansion():
    """1/G = Kv s (1 + 2 zeta s / wn + s^2 / wn^2)(1 + Kc I s / a^2 + C I s^2 / a^2) e^{s T}, T = dt/2."""
    from merritt import Merritt

    lp = LinearPlant(disc_sets=6, flow_lpm=5.0, pade_order=2)
    hand = Merritt.of(lp.plant, flow_lpm=5.0)
    kv = 1.0 / hand.velocity_gain
    wn, z, T = hand.wn, hand.zeta, 0.5e-3
    p1, p2 = 2 * z / wn, 1 / wn**2  # valve
    h1, h2 = hand.Kc * hand.I / hand.a**2, hand.C * hand.I / hand.a**2  # chambers on the inertia
    d1, d2 = T, T**2 / 2  # the sample-and-hold's delay
    c1, c2, c3 = lp.inverse_series()
    assert c1 == pytest.approx(kv, rel=1e-9)
    assert c2 == pytest.approx(kv * (p1 + h1 + d1), rel=1e-6)
    assert c3 == pytest.approx(kv * (p2 + h2 + d2 + p1 * h1 + p1 * d1 + h1 * d1), rel=1e-6)


def test_small_current_step_gives_the_linear_velocity():
    plant = Plant(disc_sets=3)
    run = plant.simulate(np.full(400, 0.2))
    rate = np.gradient(run.theta_deg, run.t)[-50:].mean()
    assert rate == pytest.approx(0.2 * LinearPlant(plant).velocity_gain, rel=2e-3)


def test_operating_flow_is_the_mean_valve_flow():
    t = np.linspace(0, 1, 100001)
    rig = RigParams()
    q = rig.area * rig.radius * math.radians(30) * 2 * math.pi * 3 * np.abs(np.cos(2 * math.pi * 3 * t))
    expected = q.mean() / math.sqrt(220 / 70) / LPM
    assert operating_flow_lpm(30.0, 3.0) == pytest.approx(expected, rel=1e-4)


def test_rig_controller_and_piff_agree():
    assert PIFF.from_rig_controller(RigController.book()).gains() == PIFF.book().gains()
