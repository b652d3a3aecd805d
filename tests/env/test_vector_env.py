"""The batched environment against N single environments (the independent truth
here: the same episodes must come out of N TrackingEnv objects stepped one by one)."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ehas_env  # noqa: F401  (registers ehas/Tracking-v0)
from ehas_env.env import batch_kernel as bk
from ehas_env.simulation.plant import RigController
from ehas_env.env.tracking_env import TrackingEnv
from ehas_env.env.vector_env import TrackingVectorEnv

SETTINGS = dict(
    randomise={"disc_sets": (1, 7), "amplitude_deg": (5.0, 30.0), "freq_hz": (2.0, 6.0), "cycles": (2.0, 2.5),
               "theta0_deg": (-2.0, 2.0), "effects": {"coulomb_friction": {"Fc": (0.0, 400.0)},
                                                       "transport_delay": {"tau": (0.0, 0.004)}}},
    sensors="realistic",
)


def compare_with_singles(n_envs, steps, parallel, seed=3, **kw):
    """Step a batch and n single envs with the same actions; returns the largest difference and episode ends."""
    vec = TrackingVectorEnv(n_envs, parallel=parallel, **kw)
    singles = [TrackingEnv(**kw) for _ in range(n_envs)]
    obs, info = vec.reset(seed=seed)
    worst = 0.0
    for i, env in enumerate(singles):
        o, inf = env.reset(seed=seed + i)
        worst = max(worst, np.abs(o - obs[i]).max(), abs(inf["theta_deg"] - info["theta_deg"][i]))
    rng = np.random.default_rng(seed)
    prev_done = np.zeros(n_envs, bool)
    ends = 0
    for _ in range(steps):
        a = rng.uniform(-0.4, 0.4, (n_envs, 1)).astype(np.float32)
        obs, rew, term, trunc, info = vec.step(a)
        for i, env in enumerate(singles):
            if prev_done[i]:  # NEXT_STEP autoreset: this step resets env i
                o, inf = env.reset()
                r, te, tr = 0.0, False, False
            else:
                o, r, te, tr, inf = env.step(a[i])
            assert (te, tr) == (term[i], trunc[i])
            worst = max(worst, np.abs(o.astype(float) - obs[i]).max(), abs(r - rew[i]))
            for key in ("theta_deg", "p_a_bar", "current_mA", "theta_sensed_deg"):
                worst = max(worst, abs(inf[key] - info[key][i]))
            if te or tr:
                assert info["_rms_error_pct"][i]
                worst = max(worst, abs(inf["rms_error_pct"] - info["rms_error_pct"][i]))
        prev_done = term | trunc
        ends += int(prev_done.sum())
    return worst, ends


# parallel=True compiles the prange kernel (about 2 min on 2 cores): slow; the serial loop is the default
@pytest.mark.parametrize("parallel", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_batch_equals_single_environments(parallel):
    worst, ends = compare_with_singles(4, 2500, parallel, **SETTINGS)
    assert ends >= 4  # episodes ended and were reset along the way
    assert worst <= 1e-9


def test_batch_equals_single_environments_in_residual_mode():
    worst, ends = compare_with_singles(3, 1500, False, controller=RigController.book(), cycles=2, freq_hz=1.5,
                                       effects={"viscous_friction": {}})
    assert ends == 3 and worst <= 1e-9


def test_make_vec_uses_the_native_vector_env():
    envs = gym.make_vec("ehas/Tracking-v0", num_envs=5, vectorization_mode="vector_entry_point", disc_sets=2)
    assert isinstance(envs, TrackingVectorEnv)
    assert envs.observation_space.shape == (5, 13) and envs.action_space.shape == (5, 1)
    assert envs.max_episode_steps == gym.spec("ehas/Tracking-v0").max_episode_steps
    obs, info = envs.reset(seed=0)
    assert envs.observation_space.contains(obs)
    obs, rew, term, trunc, info = envs.step(np.zeros((5, 1), np.float32))
    assert envs.observation_space.contains(obs) and rew.shape == (5,) and term.dtype == bool
    assert np.all(info["theta_deg"] == 0.0) and info["_theta_deg"].all()


def test_next_step_autoreset_and_final_metrics():
    vec = TrackingVectorEnv(2, cycles=3, freq_hz=10.0)  # 300-step episodes
    vec.reset(seed=0)
    z = np.zeros((2, 1), np.float32)
    for k in range(300):
        obs, rew, term, trunc, info = vec.step(z)
    assert trunc.all() and not term.any()
    assert info["_rms_error_pct"].all() and info["metric_complete"].all()
    assert np.allclose(info["rms_error_pct"], 100 / np.sqrt(2), rtol=1e-3)  # no motion: a sine's rms
    obs, rew, term, trunc, info = vec.step(z)  # the reset step
    assert np.all(rew == 0.0) and not (term | trunc).any() and np.all(info["t"] == 0.0)
    assert "rms_error_pct" not in info
    obs, rew, term, trunc, info = vec.step(z)
    assert np.allclose(info["t"], 1e-3)


def test_max_episode_steps_truncates():
    vec = TrackingVectorEnv(3, max_episode_steps=50)
    vec.reset(seed=0)
    for k in range(50):
        obs, rew, term, trunc, info = vec.step(np.zeros((3, 1)))
        assert trunc.all() == (k == 49)
    assert not info["metric_complete"].any()


def test_reset_mask_resets_only_the_masked_environments():
    vec = TrackingVectorEnv(3)
    vec.reset(seed=0)
    for _ in range(10):
        _, _, _, _, info = vec.step(np.full((3, 1), 0.2))
    obs, info = vec.reset(options={"reset_mask": np.array([True, False, True])})
    assert info["t"].tolist() == [0.0, 0.01, 0.0]


def test_reset_options_persist_for_autoresets():
    vec = TrackingVectorEnv(2, cycles=2, freq_hz=10.0)
    vec.reset(seed=0, options={"disc_sets": 7})
    assert all(vec._C[i, bk.C_P] == pytest.approx(7 * 0.383) for i in range(2))  # slot 0: inertia
    for _ in range(201):
        vec.step(np.zeros((2, 1)))
    assert all(vec._C[i, bk.C_P] == pytest.approx(7 * 0.383) for i in range(2))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_actions_are_refused_before_any_step(bad):
    vec = TrackingVectorEnv(4)
    vec.reset(seed=0)
    vec.step(np.full((4, 1), 0.1))
    before = vec._X.copy()
    a = np.full((4, 1), 0.1)
    a[2] = bad
    with pytest.raises(ValueError, match=r"environments \[2\]"):
        vec.step(a)
    assert np.array_equal(vec._X, before)


def test_out_of_range_actions_are_clipped():
    vec = TrackingVectorEnv(2)
    vec.reset(seed=0)
    _, _, _, _, info = vec.step(np.array([[5.0], [-3.0]]))
    assert info["action"].tolist() == [1.0, -1.0] and info["current_mA"].tolist() == [20.0, -20.0]


@pytest.mark.parametrize("kwargs, match", [
    ({"num_envs": 0}, "num_envs"),
    ({"num_envs": 2, "controller": object()}, "compiled law"),
    ({"num_envs": 2, "render_mode": "rgb_array"}, "render"),
    ({"num_envs": 2, "disc_sets": 0}, "disc_sets"),
])
def test_bad_arguments_are_clear_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TrackingVectorEnv(**kwargs)


def test_wrong_number_of_actions_is_a_clear_error():
    vec = TrackingVectorEnv(3)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match="one value per environment"):
        vec.step(np.zeros(2))


@pytest.mark.slow  # child processes compile and time the environments: 4 min on 2 loaded cores
def test_perf_command_writes_both_reports_naming_their_command(tmp_path):
    import json

    from ehas_env.cli.main import main

    out = tmp_path / "res"
    argv = ["perf", "--out", str(out), "--seconds", "0.05", "--repeats", "1", "--sizes", "1,4", "--rss-envs", "4"]
    assert main(argv) == 0
    rep = json.loads((out / "perf.json").read_text())
    cmd = f"ehas perf --out {out} --seconds 0.05 --repeats 1 --sizes 1,4 --rss-envs 4"
    assert rep["command"] == cmd and f"Regenerate with `{cmd}`" in (out / "perf.md").read_text()
    assert rep["single"]["substeps"] >= 10
    assert rep["single"]["ehas_steps_per_s"] > 0 and rep["single"]["pendulum_steps_per_s"] > 0
    assert [b["num_envs"] for b in rep["batched"]] == [1, 4]
    assert 0 < rep["memory"]["peak_rss_mb"] < 10_000 and rep["memory"]["num_envs"] == 4
    assert main(["perf", "--out", str(out), "--seconds", "0"]) == 2  # bad input: one clear error line


def test_an_environment_is_reset_once_after_its_episode_ends():
    vec = TrackingVectorEnv(2, cycles=2, freq_hz=10.0)  # 200-step episodes
    vec.reset(seed=0)
    z = np.zeros((2, 1))
    for _ in range(50):
        vec.step(z)
    vec.reset(options={"reset_mask": np.array([False, True])})  # env 1 now runs 50 steps behind
    for _ in range(150):
        _, _, _, trunc, _ = vec.step(z)
    assert trunc.tolist() == [True, False]
    _, _, _, _, info = vec.step(z)  # env 0 resets here
    assert np.allclose(info["t"], [0.0, 0.151], atol=1e-12)
    vec.reset(options={"reset_mask": np.array([False, True])})
    _, _, _, _, info = vec.step(z)
    assert np.allclose(info["t"], [0.001, 0.001], atol=1e-12)  # env 0 was not reset a second time


def test_memory_run_measures_its_own_process_not_the_parent():
    from ehas_env.cli.perf import measure_rss

    ballast = np.ones(40_000_000)  # 320 MB in this (parent) process
    rep = measure_rss(4, 0.01)
    assert ballast[-1] == 1.0 and rep["peak_rss_mb"] < 300 and not rep["compiled"]
