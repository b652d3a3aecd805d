"""Learned controllers (ehas_train): configs, training, checkpoints/resume, agents as controllers.

The training runs are tiny (a few thousand steps of PPO on one easy condition,
bundled ``ppo_smoke.toml``); one agent is trained once per module and shared.
"""
from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from ehas_train import envs as E  # noqa: E402
from ehas_train.agent import PickleWarning, load_agent  # noqa: E402
from ehas_train.config import bundled_config, load_config, parse_config  # noqa: E402
from ehas_train.trainer import Checkpointer, TrainingInterrupted, read_curve, train  # noqa: E402

SMOKE = "ppo_smoke"


@pytest.fixture(scope="module")
def smoke_cfg():
    return load_config(bundled_config(SMOKE))


@pytest.fixture(scope="module")
def trained(tmp_path_factory, smoke_cfg):
    out = tmp_path_factory.mktemp("agent") / "ppo"
    metrics = train(smoke_cfg, out, progress=False, tensorboard=False)
    return out, metrics


def _episode_return(cfg, policy, seeds):
    env = E.make_env(cfg)
    total = []
    for s in seeds:
        obs, _ = env.reset(seed=s)
        ret, done = 0.0, False
        while not done:
            obs, r, term, trunc, _ = env.step(policy(obs))
            ret += r
            done = term or trunc
        total.append(ret)
    return float(np.mean(total))


# -- configs ------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(p.stem for p in bundled_config("ppo").parent.glob("*.toml")))
def test_bundled_configs_are_valid(name):
    cfg = load_config(bundled_config(name))
    assert cfg.algo in ("ppo", "sac", "td3")
    assert cfg.residual == name.startswith("residual")


@pytest.mark.parametrize("raw, message", [
    ({"train": {"algo": "sac", "total_step": 10}}, "unknown key 'total_step'"),
    ({"train": {"algo": "sac", "n_envs": 0}}, "n_envs must be an integer in [1, 65536]"),
    ({"train": {"algo": "sac"}, "algo": {"clip_range": 0.2}}, "unknown hyper-parameter 'clip_range' for SAC"),
    ({"train": {"algo": "sac"}, "randomise": {"freq_hz": [3.0, 1.0]}}, "freq_hz range [low, high] has low > high"),
    ({"train": {"algo": "sac"}, "randomise": {"disc_sets": [0, 7]}}, "disc_sets values must be numbers in [1, 7]"),
    ({"train": {"algo": "sac"}, "randomise": {"effects": {"coulomb_frictio": {"Fc": [0, 1]}}}}, "unknown effect"),
    ({"train": {"algo": "sac"}, "env": {"action_scale_mA": 30.0}}, "action_scale_mA must be a number in (0, 20] mA"),
    ({"train": {"algo": "ppo"}, "algo": {"action_noise_std": 0.1}}, "applies to sac/td3"),
    ({"format": "ehas-model", "train": {"algo": "sac"}}, "format = 'ehas-model': not a training configuration"),
    ({"version": 2, "train": {"algo": "sac"}}, "version = 2 is a newer layout"),
    ({"version": "1", "train": {"algo": "sac"}}, "version must be a whole number from 1 to 1"),
    ({"train": {"algo": "sac", "validate_grid": 1}}, "validate_grid must be true or false"),
])
def test_config_errors_name_the_key(raw, message):
    with pytest.raises(ValueError) as exc:
        parse_config(raw, source="my.toml")
    assert message in str(exc.value) and "my.toml" in str(exc.value)


@pytest.mark.parametrize("change, message", [
    (("algo", "batch_size", 1), "[algo]: `batch_size` must be greater than 1"),
    (("kwargs", "dics_sets", 3), "[env]: TrackingVectorEnv.__init__() got an unexpected keyword argument 'dics_sets'"),
    (("env", "id", "ehas/Bogus-v0"), "[env]: Environment `Bogus` doesn't exist"),
])
def test_config_errors_found_by_the_libraries_are_one_line_and_leave_nothing(tmp_path, smoke_cfg, change, message):
    """stable-baselines3's and gymnasium's own refusals (before training starts) name the section; no folder is left."""
    raw = smoke_cfg.to_file_dict()
    section, key, value = change
    (raw["env"]["kwargs"] if section == "kwargs" else raw[section])[key] = value
    cfg = parse_config(raw, source="my.toml")
    with pytest.raises(ValueError) as exc:
        train(cfg, tmp_path / "run", progress=False, tensorboard=False)
    assert str(exc.value).startswith("my.toml: ") and message in str(exc.value), str(exc.value)
    assert not (tmp_path / "run").exists()


def test_bad_toml_file_names_the_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[train\nalgo = 'sac'\n")
    with pytest.raises(ValueError, match="bad.toml: not valid TOML"):
        load_config(p)


def test_cli_reports_bad_config_in_one_line(tmp_path, capsys):
    from ehas_env.cli.main import main

    p = tmp_path / "c.toml"
    p.write_text("[train]\nalgo = 'sac'\nseed = -1\n")
    assert main(["train", "--algo", "sac", "--config", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "[train] seed must be an integer in [0, 4294967295], got -1" in err[0]


def test_cli_refuses_config_of_another_algorithm(tmp_path, capsys):
    from ehas_env.cli.main import main

    assert main(["train", "--algo", "td3", "--config", str(bundled_config("sac_smoke")), "--out",
                 str(tmp_path / "o")]) == 2
    assert "trains 'sac' but --algo is 'td3'" in capsys.readouterr().err


# -- environments -----------------------------------------------------------------
def test_agent_interface_scales_and_holds_the_action(smoke_cfg):
    """action_scale_mA and action_repeat: one agent step = repeat periods at scale x 20 mA."""
    raw = parse_config({**smoke_cfg.to_file_dict(), "env": {**smoke_cfg.to_file_dict()["env"], "action_repeat": 4,
                                                            "action_scale_mA": 5.0}})
    env = E.make_env(raw)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([1.0], np.float32))
    assert info["t"] == pytest.approx(4e-3)  # four 1 ms periods
    assert info["current_mA"] == pytest.approx(5.0)


def test_power_shaped_residual_has_no_authority_at_rest_or_without_load():
    """action_shape = power: the residual vanishes where the reference is still or the load light."""
    assert E.authority("power", {"theta_ref_dot": 0.0, "p_a_bar": 200.0, "p_b_bar": 20.0}) == 0.0
    assert E.authority("power", {"theta_ref_dot": 565.0, "p_a_bar": 110.0, "p_b_bar": 110.0}) == 0.0
    assert E.authority("power", {"theta_ref_dot": 1e4, "p_a_bar": 220.0, "p_b_bar": 0.0}) == 1.0  # capped
    assert E.authority("velocity", {"theta_ref_dot": -E.V_SCALE_DEG_S / 2, "p_a_bar": 0.0, "p_b_bar": 0.0}) == 0.5
    cfg = parse_config({"train": {"algo": "sac"}, "env": {"residual": True, "controller": "book",
                                                         "action_scale_mA": 4.0, "action_shape": "power"}})
    env = E.make_env(cfg)
    base = E.make_env(cfg)
    env.reset(seed=0)
    base.reset(seed=0)
    _, _, _, _, info = env.step(np.array([1.0], np.float32))
    _, _, _, _, info0 = base.step(np.array([0.0], np.float32))
    assert info["current_mA"] == info0["current_mA"]  # at t = 0 the reference is at rest: no authority
    for _ in range(60):  # one agent step holds the action (1 ms here); the authority follows the plant
        prev = info
        _, _, _, _, info = env.step(np.array([1.0], np.float32))
    extra = info["current_mA"] - info["u_controller_mA"]  # the residual applied in the last period
    assert 0.0 < extra < 4.0 and extra == pytest.approx(4.0 * E.authority("power", prev), rel=1e-6)


def test_residual_base_schedule_follows_the_episode():
    """A gain-schedule base uses each episode's disc-set entry: zero action reproduces the plant's closed loop."""
    from ehas_controllers.piff import PIFF, GainSchedule
    from ehas_env.simulation.plant import Plant

    sched = GainSchedule({1: PIFF(Kp=1.5), 7: PIFF(Kp=0.5, Ki=1.0)}, name="s")
    desc = {"source": "test", "data": sched.to_dict()}
    cfg = parse_config({"train": {"algo": "sac"}, "env": {"residual": True, "kwargs": {"cycles": 3.0}},
                        "randomise": {"disc_sets": [1, 7]}})
    env = E.make_env(cfg, controller_desc=desc)
    seen = set()
    for seed in (0, 1):
        _, info = env.reset(seed=seed)
        n = info["episode"]["disc_sets"]
        seen.add(n)
        done = False
        while not done:
            _, _, term, trunc, info = env.step(np.zeros(1, np.float32))
            done = term or trunc
        ref = Plant(disc_sets=n).simulate_closed_loop(sched.for_plant(n).rig_gains(), amplitude_deg=20.0,
                                                     freq_hz=1.0, cycles=3.0)
        assert env.unwrapped.controller.active.Kp == pytest.approx(sched.for_plant(n).Kp)
        assert info["rms_error_pct"] == pytest.approx(ref.tracking_errors()["rms_error_pct"], rel=1e-3)
    assert len(seen) == 2


# -- training ---------------------------------------------------------------------
def test_short_training_beats_random_and_still_policies(trained, smoke_cfg):
    """A seeded short run tracks: its return beats uniform random actions and holding zero current."""
    out, metrics = trained
    agent = load_agent(out, warn=False)
    seeds = [101, 102]
    learned = _episode_return(smoke_cfg, lambda o: agent.predict(o[None, :])[0], seeds)
    rng = np.random.default_rng(0)
    random = _episode_return(smoke_cfg, lambda o: rng.uniform(-1, 1, 1).astype(np.float32), seeds)
    still = _episode_return(smoke_cfg, lambda o: np.zeros(1, np.float32), seeds)
    assert learned > random and learned > still
    assert learned > 0.2 * still  # at least 5x less squared error than not moving
    assert metrics["num_timesteps"] == smoke_cfg.total_steps
    for name in ("policy.safetensors", "policy.json", "obs_norm.json", "config.json", "metrics.json",
                 "learning_curve.csv", "learning_curve.png"):
        assert (out / name).exists(), name
    saved = json.loads((out / "config.json").read_text())
    assert saved["algo"] == "ppo" and saved["env_kwargs"]["disc_sets"] == 1


def test_saved_agent_acts_deterministically(trained):
    out, _ = trained
    a1 = load_agent(out, warn=False)
    a2 = load_agent(out, warn=False)
    assert a1.kind == "learned"
    obs = np.random.default_rng(1).normal(size=(16, a1.model.observation_space.shape[0])).astype(np.float32)
    np.testing.assert_array_equal(a1.predict(obs), a2.predict(obs))
    np.testing.assert_array_equal(a1.predict(obs), a1.predict(obs))


def test_agent_in_the_plant_closed_loop_matches_the_environment(trained):
    """act() (the controller interface, as ehas bench calls it) reproduces the environment's run.

    Same plant, reference and policy; the only difference is the reference
    preview during the fade-in cycle (exact in the env, extrapolated from the
    measurement in act()), which the % error excludes.
    """
    from ehas_env.simulation.plant import Plant
    from ehas_train.evaluate import evaluate_agent

    out, _ = trained
    agent = load_agent(out, warn=False).for_plant(1)
    run1 = Plant(disc_sets=1).simulate_closed_loop(agent, amplitude_deg=10.0, freq_hz=1.0, cycles=3)
    run2 = Plant(disc_sets=1).simulate_closed_loop(agent, amplitude_deg=10.0, freq_hz=1.0, cycles=3)
    np.testing.assert_array_equal(run1.current_mA, run2.current_mA)  # deterministic through act()
    env_row = evaluate_agent(agent, [(1, 1.0, 10.0)], cycles=3)[0]
    assert run1.tracking_errors()["rms_error_pct"] == pytest.approx(env_row["rms_error_pct"], rel=0.05)


def test_loading_reads_data_only_and_acts_as_the_training_pickle(trained):
    """The agent loads from safetensors + JSON; it acts bit for bit as the stable-baselines3 zip the training
    wrote (loaded here behind allow_pickle, this test's own file)."""
    out, _ = trained
    import pickle
    from unittest import mock

    with mock.patch.object(pickle, "load", side_effect=AssertionError("unpickled")), \
            mock.patch.object(pickle, "loads", side_effect=AssertionError("unpickled")):
        agent = load_agent(out)
    legacy = load_agent(out / "model.zip", allow_pickle=True, warn=False)
    legacy.obs_stats = __import__("ehas_train.agent_format", fromlist=["read_norm"]).read_norm(out / "obs_norm.json")
    obs = np.random.default_rng(3).normal(size=(256, agent.model.observation_space.shape[0])).astype(np.float32)
    np.testing.assert_array_equal(agent.predict(obs), legacy.predict(obs))
    with pytest.raises(FileNotFoundError, match="no agent at"):
        load_agent(out / "nothing_here")


def test_bench_registry_loads_agent_folders(trained):
    from ehas_controllers.base import load_controller

    out, _ = trained
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # data only: nothing to warn about
        ctrl = load_controller(out)
    assert ctrl.kind == "learned"


def test_interrupted_training_resumes_from_its_last_checkpoint(tmp_path, smoke_cfg, monkeypatch):
    """A crash between checkpoints loses only the steps since the last one; resume continues the count.  Neither
    training leaves a folder of its logger in the system's temporary folder (stable-baselines3's own logger made an
    empty one there at every ``learn()``)."""
    import tempfile

    from stable_baselines3.common.callbacks import BaseCallback

    system_tmp = tmp_path.parent / f"{tmp_path.name}_system_tmp"
    system_tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(system_tmp))

    cfg = smoke_cfg.replace(total_steps=4800, checkpoint_every=1600)

    class Crash(BaseCallback):
        def _on_step(self):
            if self.num_timesteps >= 4000:
                raise RuntimeError("simulated crash")
            return True

    with pytest.raises(RuntimeError, match="simulated crash"):
        train(cfg, tmp_path, progress=False, tensorboard=False, callbacks=[Crash()])
    state = Checkpointer(tmp_path / "checkpoints").state()
    assert state["num_timesteps"] == 3200  # the last checkpoint before the crash
    assert not (tmp_path / "model.zip").exists()

    class Record(BaseCallback):
        first = None

        def _on_step(self):
            if Record.first is None:
                Record.first = self.num_timesteps
            return True

    with pytest.raises(ValueError, match="not empty; use --resume"):
        train(cfg, tmp_path, progress=False, tensorboard=False)
    metrics = train(cfg, tmp_path, resume=True, progress=False, tensorboard=False, callbacks=[Record()])
    assert Record.first == 3200 + cfg.n_envs  # the count continued from the checkpoint
    assert metrics["num_timesteps"] == 4800
    steps = [r["timesteps"] for r in read_curve(tmp_path / "learning_curve.csv")]
    assert steps == sorted(steps) and steps[-1] <= 4800 and len(steps) > 10
    assert metrics["train_time_s"] > state["train_time_s"]
    assert [p.name for p in system_tmp.iterdir() if p.name.startswith("SB3-")] == []


@pytest.mark.parametrize("file, content, message", [
    ("config.json", "{", "config.json: not valid JSON at line 1"),
    ("config.json", "[1]", "config.json: expected a JSON object"),
    ("config.json", '{"format": "ehas-model", "algo": "ppo"}', "format = 'ehas-model'; expected 'ehas-agent-config'"),
    ("config.json", '{"format": "ehas-agent-config", "version": 9, "algo": "ppo"}', "version = 9; this ehas reads"),
    ("config.json", '{"n_envs": 4}', "config.json: no 'algo' key"),
    ("policy.safetensors", "not tensors", "policy.safetensors: not a safetensors file of policy weights"),
    ("obs_norm.json", "garbage", "obs_norm.json: not valid JSON"),
    ("obs_norm.json", '{"format": "ehas-obs-norm", "version": 1, "mean": [0], "var": [1], "count": 1, '
     '"clip_obs": 10, "epsilon": 1e-8, "gamma": 0.9, "gamma": 0.9}', "key 'gamma' appears twice"),
    ("policy.json", '{"format": "ehas-agent-policy", "version": 1, "algo": "ppo", "policy": "ActorCriticPolicy", '
     '"observation_space": {}, "action_space": {}}', "observation_space must be an object"),
    ("policy.json", '{"format": "ehas-agent-policy", "version": 1.0}', "version = 1.0"),
])
def test_a_damaged_agent_folder_is_refused_naming_the_file(trained, tmp_path, capsys, file, content, message):
    import shutil

    from ehas_env.cli.main import main

    folder = tmp_path / "agent"
    shutil.copytree(trained[0], folder)
    (folder / file).write_text(content)
    with pytest.raises(ValueError, match=re.escape(message)):
        load_agent(folder, warn=False)
    assert main(["bench", str(folder), "--out", str(tmp_path / "bench")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1] and err[-1].startswith("ehas bench: error: ")
    # the pickle warning is one line in the command's name, not Python's file:line and source line
    assert all(line.startswith("ehas bench: ") for line in err), err
    assert not (tmp_path / "bench").exists()


def test_agent_config_json_carries_its_format(trained):
    doc = json.loads((trained[0] / "config.json").read_text())
    assert doc["format"] == "ehas-agent-config" and doc["version"] == 1


def test_resume_refuses_a_different_task(tmp_path, smoke_cfg):
    cfg = smoke_cfg.replace(total_steps=800, checkpoint_every=400, eval_episodes=0)
    train(cfg, tmp_path, progress=False, tensorboard=False)
    raw = cfg.to_file_dict()
    raw["env"]["kwargs"]["disc_sets"] = 7
    with pytest.raises(ValueError, match="env_kwargs"):
        train(parse_config(raw), tmp_path, resume=True, progress=False, tensorboard=False)


def test_ctrl_c_writes_a_checkpoint(tmp_path, smoke_cfg):
    from stable_baselines3.common.callbacks import BaseCallback

    class CtrlC(BaseCallback):
        def _on_step(self):
            if self.num_timesteps >= 1000:
                raise KeyboardInterrupt
            return True

    cfg = smoke_cfg.replace(total_steps=4000, checkpoint_every=4000)
    with pytest.raises(TrainingInterrupted, match="--resume"):
        train(cfg, tmp_path, progress=False, tensorboard=False, callbacks=[CtrlC()])
    assert Checkpointer(tmp_path / "checkpoints").state()["num_timesteps"] == 1000
    # mid-rollout (PPO collects 800 steps per rollout here): the resumed run still ends at total_steps,
    # where SB3 alone would finish its last rollout (1000 + 4 x 800 = 4200)
    metrics = train(cfg.replace(eval_episodes=0), tmp_path, resume=True, progress=False, tensorboard=False)
    assert metrics["num_timesteps"] == 4000


@pytest.mark.parametrize("name", ["sac_smoke", "td3_smoke", "residual_sac_smoke"])
def test_off_policy_configs_train_and_checkpoint_their_replay_buffer(tmp_path, name):
    cfg = load_config(bundled_config(name))
    metrics = train(cfg, tmp_path, progress=False, tensorboard=False)
    assert metrics["num_timesteps"] == cfg.total_steps
    files = Checkpointer(tmp_path / "checkpoints").state()["files"]
    assert "replay_buffer" in files and (tmp_path / "checkpoints" / files["replay_buffer"]).exists()
    agent = load_agent(tmp_path, warn=False)
    assert agent.cfg.residual == name.startswith("residual")
    if cfg.validate_every:  # the best validated model is the result
        sel = metrics["selected_by_validation"]
        rows = read_curve(tmp_path / "validation.csv")
        assert len(rows) == cfg.total_steps // cfg.validate_every + 1
        assert sel["mean_rms_error_pct"] == pytest.approx(min(r["mean_rms_error_pct"] for r in rows), rel=1e-5)
        assert (tmp_path / "model.zip").read_bytes() == (tmp_path / "best_checkpoint" / "model.zip").read_bytes()
