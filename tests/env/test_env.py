"""The tracking environment against independent truth: the plant's own closed-loop
simulators (the model's compiled closed_loop and Plant's Python loop), the % error
definition of ehas_env.simulation.metrics, gymnasium's and stable-baselines3's checkers, and
invariants (same seed -> same episode, a valve at null holds the crank still)."""
from __future__ import annotations

import doctest
import importlib
import math
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

import ehas_env  # noqa: F401  (registers ehas/Tracking-v0)
from ehas_env.env import batch_kernel as bk
from ehas_env.physics import layout as K  # baseline indices: the same in every model
from ehas_env.env.parts import MultiSine, draw_episode
from ehas_env.simulation.metrics import tracking_errors
from ehas_env.simulation.plant import Plant, RigController
from ehas_env.simulation.reference import SineReference
from ehas_env.physics.rig import THETA_STROKE_END, VALVE_WN, VALVE_ZETA
from ehas_env.simulation.sensors import Sensors
from ehas_env.env.tracking_env import TrackingEnv

ZERO = np.zeros(1, np.float32)


def book_controller() -> RigController:
    """The spec's classical controller, written from its definition (reference-model.md)."""
    kv = 1.0 / 56.25
    return RigController(Kp=1.0, Ki=2.0, Kv=kv, Ka=kv * 2.0 * VALVE_ZETA / VALVE_WN)


def run_episode(env, action=ZERO, seed=0):
    """Reset, step to the episode's end; returns the infos (reset's first) and the last step's returns."""
    obs, info = env.reset(seed=seed)
    infos = [info]
    while True:
        obs, r, term, trunc, info = env.step(action)
        infos.append(info)
        if term or trunc:
            return infos, (obs, r, term, trunc, info)


def column(infos, key):
    return np.array([i[key] for i in infos])


# -- registration and checkers ----------------------------------------------

def test_registered_with_time_limit_and_vector_entry_point():
    env = gym.make("ehas/Tracking-v0")
    assert env.spec.max_episode_steps is not None and env.spec.max_episode_steps >= 3000
    assert isinstance(env.unwrapped, TrackingEnv)
    assert env.spec.vector_entry_point == "ehas_env.env.vector_env:TrackingVectorEnv"
    env.close()


@pytest.mark.parametrize("imports", ["import gymnasium", "import ehas_env, sys; assert 'numpy' not in sys.modules; "
                                                        "import gymnasium"])
def test_make_without_prior_registration(imports):
    # 1: gymnasium imports ehas_env from the id's prefix; 2: ehas_env first (light: no numpy), gymnasium after
    env_id = "ehas_env:ehas/Tracking-v0" if imports == "import gymnasium" else "ehas/Tracking-v0"
    code = (f"{imports}; e = gymnasium.make('{env_id}'); o, _ = e.reset(seed=1); "
            "print(type(e.unwrapped).__name__, o.shape)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["TrackingEnv", "(13,)"]


def test_gymnasium_env_checker_passes_without_warnings():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("ehas/Tracking-v0", render_mode="rgb_array", sensors="realistic",
                   randomise={"disc_sets": (1, 7)}).unwrapped
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    assert not [str(w.message) for w in caught if "gymnasium" in str(w.filename) or "WARN" in str(w.message)]


def test_stable_baselines3_env_checker_passes_without_warnings():
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = TrackingEnv(controller=RigController.book())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(env, warn=True)
    assert not [str(w.message) for w in caught if "stable_baselines3" in str(w.filename)]


# -- acceptance: physics invariants and the classical controller -------------------

def test_zero_action_holds_the_crank_still_for_a_whole_episode():
    env = gym.make("ehas/Tracking-v0", disc_sets=1)
    infos, (obs, r, term, trunc, info) = run_episode(env)
    assert trunc and not term and len(infos) == 3001
    assert np.abs(column(infos, "theta_deg")).max() < 1e-12
    assert np.abs(column(infos, "omega_deg_s")).max() < 1e-12
    # the chambers stay at Ps/2 (reference model's initial state): nothing moves
    assert np.allclose(column(infos, "p_a_bar"), 110.0, atol=1e-9)
    assert np.allclose(column(infos, "p_b_bar"), 110.0, atol=1e-9)
    # zero motion is 100 % error over the window: rms of a sine = 1/sqrt(2)
    assert info["rms_error_pct"] == pytest.approx(100 / math.sqrt(2), rel=1e-6)


def test_book_controller_in_residual_mode_tracks_within_one_percent():
    env = gym.make("ehas/Tracking-v0", controller=book_controller(), disc_sets=3, amplitude_deg=20.0, freq_hz=1.0,
                   cycles=3)
    infos, (obs, r, term, trunc, info) = run_episode(env)
    assert trunc and not term
    assert info["metric_complete"] and info["episode_steps"] == 3000
    assert info["rms_error_pct"] < 1.0
    # the env's running metric equals the project's definition on the samples the benchmark scores
    # (t_0 .. t_{n-1}; the observation after the last step is not scored)
    t, ref, th = column(infos, "t")[:-1], column(infos, "theta_ref_deg")[:-1], column(infos, "theta_deg")[:-1]
    expect = tracking_errors(t, ref, th, 20.0, 1.0)
    assert info["rms_error_pct"] == pytest.approx(expect["rms_error_pct"], rel=1e-9)
    assert info["peak_error_pct"] == pytest.approx(expect["peak_error_pct"], rel=1e-9)


@pytest.mark.parametrize("effects", [None, {"coulomb_friction": {"Fc": 300}, "transport_delay": {"tau": 0.004}},
                                     {"backlash": {}, "supply_droop": {}}])
def test_residual_zero_action_reproduces_the_plant_closed_loop(effects):
    # Independent path: the compiled closed_loop (Plant.simulate_closed_loop)
    sensors = Sensors(theta_noise_deg=0.0, pressure_noise_bar=0.0, flow_noise_lpm=0.0)  # ADC/DAC, no noise
    ctrl = book_controller()
    res = Plant(disc_sets=5, effects=effects, sensors=sensors).simulate_closed_loop(
        ctrl, amplitude_deg=25.0, freq_hz=2.0, cycles=3)
    env = TrackingEnv(controller=ctrl, disc_sets=5, effects=effects, sensors=sensors, amplitude_deg=25.0, freq_hz=2.0,
                      cycles=3)
    infos, _ = run_episode(env)
    n = res.t.size
    assert np.max(np.abs(column(infos, "theta_deg")[:n] - res.theta_deg)) < 1e-9
    assert np.max(np.abs(column(infos, "current_mA")[1:n + 1] - res.current_mA)) < 1e-9
    assert np.max(np.abs(column(infos, "p_a_bar")[:n] - res.p_a_bar)) < 1e-9


class PythonPIFF:
    """A controller called in Python: PI on the sensed angle plus velocity feed-forward."""

    def __init__(self):
        self.reset()

    def reset(self):
        self.integ = 0.0

    def act(self, m):
        e = m["theta_ref_deg"] - m["theta_deg"]
        self.integ += e * 1e-3
        return 1.5 * e + 2.0 * self.integ + m["theta_ref_dot"] / 56.25 + 1e-3 * m["p_b_bar"]


def test_python_controller_residual_mode_reproduces_the_plant_python_loop():
    res = Plant(disc_sets=2).simulate_closed_loop(PythonPIFF(), amplitude_deg=15.0, freq_hz=1.5, cycles=2)
    env = TrackingEnv(controller=PythonPIFF(), disc_sets=2, amplitude_deg=15.0, freq_hz=1.5, cycles=2)
    infos, _ = run_episode(env)
    n = res.t.size
    assert np.max(np.abs(column(infos, "theta_deg")[:n] - res.theta_deg)) < 1e-9
    assert np.max(np.abs(column(infos, "current_mA")[1:n + 1] - res.current_mA)) < 1e-9


def test_residual_action_is_added_to_the_controller_and_clipped():
    env = TrackingEnv(controller=book_controller(), disc_sets=3)
    env.reset(seed=0)
    for a in (0.1, -0.3, 1.0, -1.0, 0.05):
        _, _, _, _, info = env.step(np.array([a], np.float32))
        expect = min(max(info["u_controller_mA"] + 20.0 * float(np.float32(a)), -20.0), 20.0)
        assert info["current_mA"] == pytest.approx(expect, abs=1e-12)


# -- actions: clipping and refusal --------------------------------------------------

@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_actions_are_refused_and_change_nothing(bad):
    env = gym.make("ehas/Tracking-v0")
    env.reset(seed=0)
    for _ in range(50):
        env.step(np.array([0.3], np.float32))
    keep = np.arange(env.unwrapped._X.size) != bk.X_FLAGS  # all but the status bits
    before = env.unwrapped._X[keep].copy()
    with pytest.raises(ValueError, match="action"):
        env.step(np.array([bad], np.float32))
    assert np.array_equal(env.unwrapped._X[keep], before)
    obs, r, term, trunc, info = env.step(ZERO)  # the env goes on
    assert np.all(np.isfinite(obs)) and math.isfinite(r)


def test_out_of_range_actions_are_clipped():
    a, b = TrackingEnv(), TrackingEnv()
    a.reset(seed=0)
    b.reset(seed=0)
    for big, one in ((7.0, 1.0), (-1e300, -1.0), (1.5, 1.0)):
        oa, ra, *_, ia = a.step(np.array([big]))
        ob, rb, *_, ib = b.step(np.array([one]))
        assert np.array_equal(oa, ob) and ra == rb and ia["action"] == one
        assert np.all(np.isfinite(oa))


def test_action_of_wrong_size_is_a_clear_error():
    env = TrackingEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="exactly one value"):
        env.step(np.zeros(3))


def test_stroke_end_terminates_with_a_penalty_and_finite_values():
    env = TrackingEnv(disc_sets=1)
    env.reset(seed=0)
    k = 0
    while True:
        obs, r, term, trunc, info = env.step(np.ones(1, np.float32))
        k += 1
        if term or trunc:
            break
    assert term and info["termination"] == "stroke_end"
    assert info["theta_deg"] == pytest.approx(math.degrees(THETA_STROKE_END), abs=1e-6)
    assert r <= -(3000 - k)  # the rest of the episode charged at the amplitude
    assert np.all(np.isfinite(obs)) and math.isfinite(r)
    assert np.all(np.abs(obs) <= 10.0)


def test_non_finite_state_terminates_and_restores_a_finite_state():
    env = TrackingEnv()
    env.reset(seed=0)
    env.step(np.array([0.2], np.float32))
    env._C[bk.C_P + env._model.IDX["beta"]] = np.inf  # a corrupted parameter makes the state non-finite
    obs, r, term, trunc, info = env.step(np.array([0.2], np.float32))
    assert term and info["termination"] == "non_finite_state"
    assert np.all(np.isfinite(obs)) and math.isfinite(r)
    assert np.all(np.isfinite(env._X))


# -- observation, reward, info ----------------------------------------------------

def test_observation_is_the_scaled_info_and_reward_follows_its_formula():
    env = TrackingEnv(amplitude_deg=20.0, preview_ms=(10.0, 40.0), rate_penalty=0.05)
    _, info = env.reset(seed=0)
    assert info["omega_sensed_deg_s"] == 0.0
    th_prev = info["theta_sensed_deg"]
    rng = np.random.default_rng(3)
    prev = 0.0
    th_end = math.degrees(THETA_STROKE_END)
    for k in range(300):
        a = float(rng.uniform(-0.2, 0.2))
        obs, r, term, trunc, info = env.step(np.array([a]))
        assert obs.dtype == np.float32 and obs.shape == (12,)
        t = info["t"]
        ref = SineReference(20.0, 1.0)
        assert info["omega_sensed_deg_s"] == pytest.approx((info["theta_sensed_deg"] - th_prev) / 1e-3, rel=1e-9)
        th_prev = info["theta_sensed_deg"]
        expect = [info["error_deg"] / 20.0, info["theta_sensed_deg"] / th_end,
                  info["omega_sensed_deg_s"] / (30 * 6 * math.pi),
                  ref(t)[0] / th_end, ref(t)[1] / (30 * 6 * math.pi), ref(t)[2] / (30 * 36 * math.pi ** 2),
                  ref(t + 0.01)[0] / th_end, ref(t + 0.04)[0] / th_end,
                  2 * info["p_a_bar"] / 220 - 1, 2 * info["p_b_bar"] / 220 - 1, a, 0.0]
        assert np.allclose(obs, expect, rtol=1e-6, atol=1e-6)
        e = info["theta_ref_deg"] - info["theta_deg"]
        assert r == pytest.approx(-(e / 20.0) ** 2 - 0.05 * (a - prev) ** 2, rel=1e-12, abs=1e-15)
        assert r <= 0.0
        prev = a


def test_multisine_reference_matches_its_analytic_sum():
    ms = MultiSine((SineReference(10.0, 1.0), SineReference(4.0, 3.0, phase=0.5)))
    env = TrackingEnv(reference=ms, cycles=3)
    infos, (_, _, _, _, info) = run_episode(env)
    t = column(infos, "t")
    r, rd, rdd = ms(t)
    assert np.allclose(column(infos, "theta_ref_deg"), r, atol=1e-9)
    assert np.allclose(column(infos, "theta_ref_dot"), rd, atol=1e-7)
    assert np.allclose(column(infos, "theta_ref_ddot"), rdd, atol=1e-5)
    assert info["rms_error_pct"] == pytest.approx(
        tracking_errors(t[:-1], r[:-1], column(infos, "theta_deg")[:-1], 14.0, 1.0)["rms_error_pct"], rel=1e-9)


# -- a trained policy as a controller: the observation from a measurement -------------

def policy(obs):
    """A fixed stand-in for a trained policy (a linear map of the observation)."""
    o = obs.astype(float)
    return np.array([np.clip(0.4 * o[0] - 0.02 * o[2] + 0.1 * (o[6] - o[3]) + 0.05 * o[-1], -1.0, 1.0)])


class PolicyController:
    """Policy + MeasurementObserver behind the controller interface (what an agent's act() does)."""

    def __init__(self, observer):
        self.observer = observer
        self.obs = []

    def reset(self):
        self.observer.reset()

    def act(self, m):
        obs = self.observer.observation(m)
        self.obs.append(obs)
        return self.observer.current(policy(obs), m)


def test_measurement_observer_reproduces_the_env_under_a_policy():
    from ehas_env.env.tracking_env import MeasurementObserver

    kw = dict(disc_sets=4, amplitude_deg=15.0, freq_hz=2.0, cycles=3)
    env = TrackingEnv(controller=book_controller(), **kw)
    obs, info = env.reset(seed=0)
    env_obs, theta = [obs], [info["theta_deg"]]
    while True:
        obs, r, term, trunc, info = env.step(policy(obs))
        env_obs.append(obs)
        theta.append(info["theta_deg"])
        if term or trunc:
            break
    ctrl = PolicyController(MeasurementObserver(env, SineReference(15.0, 2.0)))
    res = Plant(disc_sets=4).simulate_closed_loop(ctrl, amplitude_deg=15.0, freq_hz=2.0, cycles=3)
    n = res.t.size
    assert np.max(np.abs(np.array(ctrl.obs) - np.array(env_obs[:n]))) < 1e-5
    assert np.max(np.abs(res.theta_deg - np.array(theta[:n]))) < 1e-6


def test_measurement_observer_infers_a_sine_reference_after_its_fade_in():
    from ehas_env.env.tracking_env import MeasurementObserver

    env = TrackingEnv(controller=book_controller(), amplitude_deg=25.0, freq_hz=3.0, cycles=3)
    observer = MeasurementObserver(env)  # reference unknown: inferred from the measurements
    observer.reset()
    obs, info = env.reset(seed=0)
    keys = ("t", "theta_ref_deg", "theta_ref_dot", "theta_ref_ddot", "theta_ref_dddot", "p_a_bar", "p_b_bar", "p_s_bar")
    worst_late, worst_early = 0.0, 0.0
    while True:
        m = {k: info[k] for k in keys}
        m["theta_deg"] = info["theta_sensed_deg"]
        diff = float(np.max(np.abs(observer.observation(m) - obs)))
        if info["t"] >= 1 / 3.0:  # after the fade-in cycle
            worst_late = max(worst_late, diff)
        else:
            worst_early = max(worst_early, diff)
        a = policy(obs)
        u = observer.current(a, m)
        obs, r, term, trunc, info = env.step(a)
        assert u == pytest.approx(info["current_mA"], abs=1e-9)  # the same base controller and residual
        if term or trunc:
            break
    assert worst_late < 1e-5
    assert worst_early < 1.0  # fade-in: the previews are extrapolated


# -- episodes: seeds, options, randomisation ----------------------------------------

RANDOM = {"disc_sets": (1, 7), "amplitude_deg": (5.0, 30.0), "freq_hz": [1.0, 2.0, 3.0], "theta0_deg": (-3.0, 3.0),
          "effects": {"coulomb_friction": {"Fc": (100.0, 400.0)}, "internal_leakage": "typical"}}


def rollout(env, seed, steps=400):
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [obs]
    infos = [info["episode"]]
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(rng.uniform(-0.3, 0.3, 1).astype(np.float32))
        out.append(obs)
        infos.append((r, info["theta_sensed_deg"]))
        if term or trunc:
            obs, info = env.reset()
            infos.append(info["episode"])
    return np.array(out), infos


def test_same_seed_gives_identical_episodes_and_another_seed_differs():
    kw = dict(randomise=RANDOM, sensors="realistic", cycles=2)
    o1, i1 = rollout(gym.make("ehas/Tracking-v0", **kw), 11)
    o2, i2 = rollout(gym.make("ehas/Tracking-v0", **kw), 11)
    assert np.array_equal(o1, o2) and i1 == i2
    o3, i3 = rollout(gym.make("ehas/Tracking-v0", **kw), 12)
    assert i3[0] != i1[0]


def test_sensor_noise_is_seeded_and_has_the_set_spread():
    env = TrackingEnv(sensors=Sensors(theta_noise_deg=0.05, adc_bits=0, dac_bits=0))
    infos, _ = run_episode(env, seed=5)
    noise = column(infos, "theta_sensed_deg") - column(infos, "theta_deg")
    assert np.std(noise) == pytest.approx(0.05, rel=0.05) and abs(np.mean(noise)) < 0.005


def test_randomised_episodes_stay_inside_their_ranges():
    rng = np.random.default_rng(0)
    seen = set()
    for _ in range(200):
        ep = draw_episode({}, {"randomise": RANDOM}, rng)
        seen.add(ep.disc_sets)
        assert 1 <= ep.disc_sets <= 7 and 5.0 <= ep.amplitude_deg <= 30.0 and ep.freq_hz in (1.0, 2.0, 3.0)
        assert 100.0 <= ep.effects["coulomb_friction"]["Fc"] <= 400.0
        assert 3.0e-13 <= ep.effects["internal_leakage"]["C_leak"] <= 3.0e-12  # Param.typical
    assert seen == set(range(1, 8))


def test_reset_options_hold_for_one_episode():
    env = gym.make("ehas/Tracking-v0")
    _, info = env.reset(seed=0, options={"disc_sets": 7, "amplitude_deg": 10.0, "effects": "viscous_friction"})
    assert info["episode"]["disc_sets"] == 7 and info["episode"]["amplitude_deg"] == 10.0
    assert "viscous_friction" in info["episode"]["effects"]
    _, info = env.reset()
    assert info["episode"]["disc_sets"] == 3 and info["episode"]["effects"] == {}


@pytest.mark.parametrize("kwargs, match", [
    ({"disc_sets": 9}, "disc_sets"),
    ({"amplitude_deg": 50.0}, "amplitude_deg"),
    ({"effects": {"no_such_effect": {}}}, "unknown effect"),
    ({"randomise": {"amplitude_deg": (30.0, 5.0)}}, "low"),
    ({"randomise": {"colour": (1, 2)}}, "cannot be randomised"),
    ({"preview_ms": (-1.0,)}, "preview_ms"),
    ({"controller": object()}, "controller"),
    ({"plant_kwargs": {"dt": 0.1}}, "plant_kwargs"),
])
def test_bad_settings_are_clear_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TrackingEnv(**kwargs)


def test_unknown_reset_option_is_named():
    env = TrackingEnv()
    with pytest.raises(ValueError, match="unknown episode option 'colour'"):
        env.reset(options={"colour": "red"})


def test_plant_kwargs_reach_the_plant():
    env = TrackingEnv(plant_kwargs={"inertia": 1.0})
    env.reset(seed=0)
    assert env._C[bk.C_P + env._model.IDX["inertia"]] == 1.0


# -- rendering ----------------------------------------------------------------------

def test_rgb_array_shows_dial_and_traces():
    env = gym.make("ehas/Tracking-v0", render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(1250):  # t = 1.25 s: the reference is at +20 deg, the crank (zero current) at 0
        env.step(ZERO)
    frame = env.render()
    assert frame.shape == (320, 640, 3) and frame.dtype == np.uint8
    blue = (frame[..., 2] > 150) & (frame[..., 0] < 100)  # crank: tab:blue
    orange = (frame[..., 0] > 200) & (frame[..., 1] > 100) & (frame[..., 1] < 180) & (frame[..., 2] < 80)
    dial = slice(0, 250)  # the dial's axes span x = 13..243, centre 128
    assert blue[:, dial].sum() > 100 and orange[:, dial].sum() > 50
    assert blue[:, 320:].sum() > 100 and orange[:, 320:].sum() > 50  # the traces
    assert abs(np.nonzero(blue[:, dial])[1].mean() - 128) < 5  # the crank stands upright
    assert np.nonzero(orange[:, dial])[1].mean() > 140  # the reference leans right (clockwise, +20 deg)
    env.close()


def test_human_render_runs_headless():
    """The human window shows, refreshed at render_fps (every 33 steps of 1 ms at 30 fps), the same
    picture as rgb_array at that step; render() returns nothing; close() closes the window."""
    import matplotlib.pyplot as plt

    env = TrackingEnv(render_mode="human", cycles=0.1)  # 100 steps
    env.reset(seed=0)
    for _ in range(40):
        env.step(ZERO)
    twin = TrackingEnv(render_mode="rgb_array", cycles=0.1)
    twin.reset(seed=0)
    for _ in range(round(1000 / 30)):  # the last refresh of the human window: step 33
        twin.step(ZERO)
    fig, img = env._renderer._window
    assert plt.fignum_exists(fig.number)
    np.testing.assert_array_equal(np.asarray(img.get_array()), twin.render())
    assert env.render() is None  # human mode draws; it returns no frame
    for _ in range(26):  # step 66: the next refresh moves the picture on
        assert env.step(ZERO)[2:4] == (False, False)
    assert not np.array_equal(np.asarray(img.get_array()), twin.render())
    env.close()
    twin.close()
    assert not plt.fignum_exists(fig.number) and env._renderer is None


# -- the compiled step's parts ---------------------------------------------------------

def test_counter_based_noise_is_standard_normal():
    z = np.array([bk.gauss_noise(77, k) for k in range(20000)])
    assert abs(z.mean()) < 0.03 and abs(z.std() - 1.0) < 0.03
    assert z[5] == bk.gauss_noise(77, 5) and z[5] != bk.gauss_noise(78, 5)


# env.vector_env: 177 s on 2 loaded cores (the batched kernel's compile); slow here, its docstring still runs in the
# default suite through --doctest-modules (ehas_env/env/vector_env.py)
@pytest.mark.parametrize("module", ["env.batch_kernel", "env.parts", "env.tracking_env",
                                    pytest.param("env.vector_env", marks=pytest.mark.slow), "cli.perf"])
def test_docstring_examples_run(module):
    result = doctest.testmod(importlib.import_module(f"ehas_env.{module}"), optionflags=doctest.ELLIPSIS)
    assert result.failed == 0
