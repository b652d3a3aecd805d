"""The batched SB3 VecEnv (ehas_train.batched): VecEnv contract, parity with DummyVecEnv, seeded training."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecMonitor, VecNormalize  # noqa: E402

from ehas_train import envs as E  # noqa: E402
from ehas_train.batched import BatchedTrackingVecEnv, make_training_vec_env  # noqa: E402
from ehas_train.config import bundled_config, load_config, parse_config  # noqa: E402


def smoke_cfg(**train):
    cfg = load_config(bundled_config("residual_sac_smoke"))
    return cfg.replace(**train) if train else cfg


def pair(cfg, n, seed):
    desc = E.resolve_controller_spec(cfg.controller) if cfg.residual else None
    b = BatchedTrackingVecEnv(cfg, desc, n)
    d = DummyVecEnv([lambda: E.make_env(cfg, controller_desc=desc) for _ in range(n)])
    b.seed(seed)
    d.seed(seed)
    return b, d


def test_vecenv_spaces_shapes_dtypes():
    cfg = smoke_cfg()
    venv = BatchedTrackingVecEnv(cfg, None, 3)
    assert isinstance(venv, VecEnv)
    assert venv.num_envs == 3
    assert venv.observation_space.shape == (13,) and venv.observation_space.dtype == np.float32
    assert venv.action_space.shape == (1,) and venv.action_space.dtype == np.float32
    venv.seed(0)
    obs = venv.reset()
    assert obs.shape == (3, 13) and obs.dtype == np.float32
    assert venv.observation_space.contains(obs[0])
    obs, rew, done, infos = venv.step(np.zeros((3, 1), np.float32))
    assert obs.shape == (3, 13) and obs.dtype == np.float32
    assert rew.shape == (3,) and rew.dtype == np.float32
    assert done.shape == (3,) and done.dtype == bool
    assert isinstance(infos, list) and len(infos) == 3 and all(isinstance(i, dict) for i in infos)
    assert venv.get_attr("render_mode") == [None] * 3
    assert venv.env_is_wrapped(VecMonitor) == [False] * 3
    venv.close()


@pytest.mark.parametrize("shape", ["power", "reference", "reference_sq", "reference_sq_load", "constant"])
def test_same_transitions_as_dummy_vec_env(shape):
    """Environment i seeded s + i: the same observations, rewards, ends, terminal observations and metrics."""
    raw = smoke_cfg().to_file_dict()
    raw["env"]["action_shape"] = shape
    cfg = parse_config(raw)
    n = 3
    b, d = pair(cfg, n, 7)
    assert np.array_equal(b.reset(), d.reset())
    rng = np.random.default_rng(0)
    ends = 0
    for k in range(400):
        a = rng.uniform(-1.3, 1.3, (n, 1)).astype(np.float32)  # out-of-range actions are clipped alike
        o1, r1, d1, i1 = b.step(a)
        o2, r2, d2, i2 = d.step(a)
        assert np.array_equal(d1, d2), k
        assert np.array_equal(o1, o2), k
        assert np.array_equal(r1, r2), k
        for i in np.flatnonzero(d1):
            ends += 1
            assert np.array_equal(i1[i]["terminal_observation"], i2[i]["terminal_observation"])
            assert i1[i]["TimeLimit.truncated"] == i2[i]["TimeLimit.truncated"]
            assert i1[i]["rms_error_pct"] == i2[i]["rms_error_pct"]
            assert i1[i]["peak_error_pct"] == i2[i]["peak_error_pct"]
            assert 0.0 <= i1[i]["saturation_frac"] <= 1.0
        for i in np.flatnonzero(~d1):
            assert "terminal_observation" not in i1[i]
    assert ends >= n  # every environment went through an automatic reset


def test_auto_reset_returns_first_observation_of_next_episode():
    cfg = smoke_cfg()
    venv = BatchedTrackingVecEnv(cfg, None, 2)
    venv.seed(0)
    venv.reset()
    for _ in range(1000):
        obs, _, done, infos = venv.step(np.zeros((2, 1), np.float32))
        if done.any():
            i = int(np.flatnonzero(done)[0])
            # a fresh episode starts at rest: reference and angle zero
            assert obs[i][1] == 0.0 and obs[i][3] == 0.0
            assert not np.array_equal(infos[i]["terminal_observation"], obs[i])
            assert np.isfinite(infos[i]["rms_error_pct"])
            return
    pytest.fail("no episode ended")


def test_seeding():
    cfg = smoke_cfg()
    venv = BatchedTrackingVecEnv(cfg, None, 4)

    def roll(seed):
        if seed is not None:
            venv.seed(seed)
        out = [venv.reset()]
        for _ in range(80):
            out.append(venv.step(np.full((4, 1), 0.2, np.float32))[0])
        return np.array(out)

    a, b, c = roll(3), roll(3), roll(4)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert venv.seed(5) == [5, 6, 7, 8]
    # environment i seeded s + i is the single environment seeded s + i
    single = E.make_env(cfg)
    venv.seed(11)
    obs = venv.reset()
    o, _ = single.reset(seed=13)
    assert np.array_equal(obs[2], o)


def test_vecnormalize_vecmonitor_and_episode_records():
    cfg = smoke_cfg()
    venv = make_training_vec_env(cfg, controller_desc=E.resolve_controller_spec(cfg.controller), n_envs=2)
    assert isinstance(venv, VecMonitor)
    vn = VecNormalize(venv, norm_obs=True, norm_reward=False)
    vn.reset()
    got = None
    for _ in range(300):
        _, _, done, infos = vn.step(np.zeros((2, 1), np.float32))
        for i in np.flatnonzero(done):
            got = infos[i]
    assert got is not None
    assert {"r", "l", "rms_error_pct", "saturation_frac", "hit_stroke_end"} <= set(got["episode"])
    assert "terminal_observation" in got


def test_dummy_path_selectable():
    cfg = smoke_cfg()
    venv = make_training_vec_env(cfg, n_envs=2, vec_env="dummy")
    assert isinstance(venv.venv, DummyVecEnv)
    assert isinstance(make_training_vec_env(cfg, n_envs=2).venv, BatchedTrackingVecEnv)
    with pytest.raises(ValueError, match="vec_env"):
        make_training_vec_env(cfg, n_envs=2, vec_env="bogus")
    assert load_config(bundled_config("ppo")).vec_env == "batched"


def test_schedule_base_runs_compiled_per_episode():
    """A gain schedule as residual base: each episode its disc sets' entry, as the Python ScheduledBase."""
    from ehas_controllers.piff import PIFF, GainSchedule

    heavy = PIFF.from_dict(PIFF.book().to_dict()) if hasattr(PIFF, "from_dict") else PIFF.book()
    heavy.Kp = 2.0 * heavy.Kp  # another entry for 4..7 disc sets
    sched = GainSchedule({n: (PIFF.book() if n < 4 else heavy) for n in range(1, 8)}, name="test schedule")
    desc = {"source": "test", "data": sched.to_dict()}
    raw = smoke_cfg().to_file_dict()
    raw["env"]["controller"] = "book"
    cfg = parse_config(raw)
    b = BatchedTrackingVecEnv(cfg, desc, 4)
    d = DummyVecEnv([lambda: E.make_env(cfg, controller_desc=desc) for _ in range(4)])
    b.seed(1)
    d.seed(1)
    np.testing.assert_array_equal(b.reset(), d.reset())
    for _ in range(200):
        a = np.full((4, 1), 0.1, np.float32)
        o1, r1, d1, _ = b.step(a)
        o2, r2, d2, _ = d.step(a)
        assert np.array_equal(d1, d2)
        np.testing.assert_allclose(o1, o2, rtol=0, atol=1e-5)
        np.testing.assert_allclose(r1, r2, rtol=1e-5, atol=1e-6)


def _train(tmp_path, name, **changes):
    from ehas_train.trainer import train

    cfg = smoke_cfg(total_steps=600, validate_every=0, checkpoint_every=300, eval_episodes=0, **changes)
    out = tmp_path / name
    train(cfg, out, progress=False, tensorboard=False)
    import torch

    from stable_baselines3 import SAC

    params = SAC.load(out / "model.zip", device="cpu").policy.state_dict()
    return {k: v.clone() for k, v in params.items()}, (out / "learning_curve.csv").read_text()


def test_seeded_smoke_training_is_reproducible(tmp_path):
    p1, c1 = _train(tmp_path, "a")
    p2, c2 = _train(tmp_path, "b")
    assert c1.splitlines()[1:] and [l.rsplit(",", 1)[0] for l in c1.splitlines()] == \
        [l.rsplit(",", 1)[0] for l in c2.splitlines()]  # the wall-time column aside
    for k in p1:
        assert (p1[k] == p2[k]).all(), k


def test_batched_and_dummy_train_the_same_agent(tmp_path):
    """Same seed, same transitions: the batched and the DummyVecEnv paths give the same weights."""
    p1, _ = _train(tmp_path, "batched", vec_env="batched")
    p2, _ = _train(tmp_path, "dummy", vec_env="dummy")
    for k in p1:
        assert (p1[k] == p2[k]).all(), k


def test_resume_with_batched_env(tmp_path):
    from ehas_train.trainer import train

    cfg = smoke_cfg(total_steps=400, validate_every=0, checkpoint_every=200, eval_episodes=0)
    out = tmp_path / "r"
    train(cfg, out, progress=False, tensorboard=False)
    m = train(cfg.replace(total_steps=800), out, resume=True, progress=False, tensorboard=False)
    assert m["num_timesteps"] >= 800
    assert json.loads((out / "config.json").read_text())["vec_env"] == "batched"


def test_cli_vec_env_override():
    import argparse

    from ehas_train.train_cli import _command, add_arguments, resolve_config

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--algo", "sac", "--residual", "--config", str(bundled_config("residual_sac_smoke")),
                              "--out", "x", "--vec-env", "dummy"])
    assert resolve_config(args).vec_env == "dummy"
    assert "--vec-env dummy" in _command(args)


def test_reference_authority_is_a_function_of_the_task():
    import math

    w = 2 * math.pi
    at = lambda A, f, t: E.reference_authority({  # noqa: E731
        "theta_ref_deg": A * math.sin(f * w * t), "theta_ref_dot": A * f * w * math.cos(f * w * t),
        "theta_ref_ddot": -A * (f * w) ** 2 * math.sin(f * w * t), "theta_ref_dddot": -A * (f * w) ** 3 * math.cos(f * w * t)})
    assert float(at(30.0, 3.0, 0.123)) == pytest.approx(1.0)
    assert float(at(10.0, 1.0, 0.3)) == pytest.approx(float(at(10.0, 1.0, 0.7)))  # constant along the sine
    assert float(at(10.0, 1.0, 0.3)) == pytest.approx((10 * w / E.V_SCALE_DEG_S) * (10 * w * w / E.A_SCALE_DEG_S2))
    m20 = lambda t: {k: v * 20.0 / 30.0 for k, v in {  # noqa: E731  20 deg / 3 Hz: both amplitudes 2/3 of the design point's
        "theta_ref_deg": 30 * math.sin(3 * w * t), "theta_ref_dot": 30 * 3 * w * math.cos(3 * w * t),
        "theta_ref_ddot": -30 * (3 * w) ** 2 * math.sin(3 * w * t),
        "theta_ref_dddot": -30 * (3 * w) ** 3 * math.cos(3 * w * t)}.items()}
    assert float(E.authority("reference", m20(0.05))) == pytest.approx((2 / 3) ** 2)
    assert float(E.authority("reference_sq", m20(0.05))) == pytest.approx((2 / 3) ** 4)
    # the load's share: one disc set gets a seventh of seven's authority (a row per env)
    assert E.authority("reference_sq_load", m20(0.05), np.array([1, 7])) == pytest.approx(
        [(2 / 3) ** 4 / 7, (2 / 3) ** 4])
    with pytest.raises(ValueError, match="needs the disc sets"):
        E.authority("reference_sq_load", m20(0.05))
    assert float(E.authority("reference", {})) == 0.0


def test_tensorboard_scalars(tmp_path):
    """The controls figures reach TensorBoard: episode rms %, saturation, stroke ends, validation vs base."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from ehas_train.trainer import train

    cfg = smoke_cfg(total_steps=600, validate_every=300, checkpoint_every=300, eval_episodes=0)
    out = tmp_path / "tb"
    train(cfg, out, progress=False, tensorboard=True)
    runs = list((out / "tb").iterdir())
    ea = EventAccumulator(str(runs[0]))
    ea.Reload()
    tags = set(ea.Tags()["scalars"])
    assert {"ehas/episode_rms_error_pct", "ehas/episode_saturation_frac", "ehas/stroke_end_terminations",
            "ehas/validation_rms_error_pct", "ehas/validation_base_rms_error_pct"} <= tags


def test_validation_on_the_grid_ranks_by_conditions_worse_first():
    """validate_grid puts the benchmark's 63 conditions first; fewest_worse counts losses before the mean."""
    from ehas_train.evaluate import WORSE_TOL, grid_conditions
    from ehas_train.trainer import BestKeeper, validation_conditions

    raw = smoke_cfg().to_file_dict()
    raw["train"].update(validate_grid=True, validate_conditions=5, validate_metric="fewest_worse")
    cfg = parse_config(raw)
    conds = validation_conditions(cfg)
    assert conds[:63] == grid_conditions() and len(conds) == 68
    assert conds[63:] == validation_conditions(cfg.replace(validate_grid=False))  # the same random draws

    keeper = BestKeeper(cfg, Path("/nonexistent"), None)
    assert keeper.cycles() == 5.0  # as the benchmark scores them
    keeper._ref, keeper._ref_rms = 1.0, np.ones(4)
    at_tol = np.array([1.0 + WORSE_TOL - 1e-9, 0.5, 0.5, 0.5])
    one_worse = np.array([1.0 + WORSE_TOL + 1e-3, 0.1, 0.1, 0.1])
    assert keeper.score(at_tol)[1] == 0 and keeper.score(one_worse)[1] == 1
    assert keeper.score(at_tol)[0] < keeper.score(one_worse)[0]  # though one_worse has the lower mean
    mean_cfg = cfg.replace(validate_metric="mean")
    k2 = BestKeeper(mean_cfg, Path("/nonexistent"), None)
    k2._ref, k2._ref_rms = 1.0, np.ones(4)
    assert k2.score(one_worse) == (pytest.approx(one_worse.mean()), 1)


def test_validate_metric_no_worse_is_checked():
    raw = smoke_cfg().to_file_dict()
    raw["train"]["validate_metric"] = "no_worse"
    assert parse_config(raw).validate_metric == "no_worse"
    raw["train"]["validate_metric"] = "best"
    with pytest.raises(ValueError, match="validate_metric"):
        parse_config(raw)
