"""Training inputs from elsewhere (issue 14): agent folders missing a file, net_arch ranges, config files that
are folders or not text.  Each is one line naming the file or the key, before anything is loaded or written.
"""
from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from ehas_env.cli.main import main  # noqa: E402
from ehas_train.agent import PickleWarning, load_agent  # noqa: E402
from ehas_train.config import NET_ARCH_MAX_LAYERS, NET_ARCH_MAX_WIDTH, load_config, parse_config  # noqa: E402
from refusals import refused  # noqa: E402  tests/ is on sys.path (conftest.py)

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def agent(tmp_path):
    folder = tmp_path / "agent"
    shutil.copytree(ROOT / "results" / "agents" / "ppo", folder)
    return folder


@pytest.mark.parametrize("missing, words", [
    ("config.json", ["config.json is missing", "holds config.json (its training configuration), policy.json"]),
    ("obs_norm.json", ["obs_norm.json is missing", "trained with vecnormalize = true"]),
])
def test_agent_folder_missing_a_file_is_refused_before_unpickling(agent, missing, words):
    (agent / missing).unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("error", PickleWarning)  # refused before the pickle warning: nothing is unpickled
        refused(lambda: load_agent(agent), f"agent folder {agent}: ", *words)


def test_agent_folder_missing_a_file_through_the_cli(agent, tmp_path, capsys):
    (agent / "obs_norm.json").unlink()
    rc = main(["simulate", "--cycles", "3", "--controller", str(agent), "--out", str(tmp_path / "o" / "run")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith(f"ehas simulate: error: agent folder {agent}: obs_norm.json is missing"), err
    assert not (tmp_path / "o").exists()


def test_agent_trained_without_normalisation_needs_no_statistics(agent):
    cfg = json.loads((agent / "config.json").read_text())
    cfg["vecnormalize"] = False
    (agent / "config.json").write_text(json.dumps(cfg))
    (agent / "obs_norm.json").unlink()
    assert load_agent(agent, warn=False).obs_stats is None


def test_agent_config_json_that_is_a_folder_or_binary(agent):
    (agent / "config.json").unlink()
    (agent / "config.json").mkdir()
    refused(lambda: load_agent(agent, warn=False), "config.json: is a folder; expected an agent folder's config.json")
    (agent / "config.json").rmdir()
    (agent / "config.json").write_bytes(b"\x80\x81")
    refused(lambda: load_agent(agent, warn=False), "config.json: not a UTF-8 text file (byte 0x80 at offset 0)")


# -- net_arch ----------------------------------------------------------------------------------------------
def _cfg(net_arch, algo="ppo"):
    return {"train": {"algo": algo}, "algo": {"policy_kwargs": {"net_arch": net_arch}}}


@pytest.mark.parametrize("net_arch, words", [
    ([1_000_000_000], f"net_arch layer 1 must be an integer in [1, {NET_ARCH_MAX_WIDTH}] units, got 1000000000"),
    ([64, 0], "net_arch layer 2 must be an integer in [1, 4096] units, got 0"),
    ([64, 2.5], "net_arch layer 2 must be an integer"),
    ([True], "net_arch layer 1 must be an integer"),
    ("big", f"net_arch must be a list of at most {NET_ARCH_MAX_LAYERS} layer widths"),
    ([8] * (NET_ARCH_MAX_LAYERS + 1), f"net_arch must be a list of at most {NET_ARCH_MAX_LAYERS} layer widths"),
    ({"pi": [64], "vf": [10**9]}, "net_arch.vf layer 1 must be an integer in [1, 4096]"),
    ({"pi": [64], "qf": [64]}, "net_arch: unknown network 'qf'; allowed: pi, vf"),
    ({}, "net_arch must be a list of at most"),
])
def test_net_arch_layer_widths_have_a_range(net_arch, words):
    refused(lambda: parse_config(_cfg(net_arch), source="cfg.toml"), "cfg.toml: [algo.policy_kwargs] ", words)


@pytest.mark.parametrize("net_arch, algo", [([64, 64], "ppo"), ([4096] * NET_ARCH_MAX_LAYERS, "ppo"), ([], "ppo"),
                                            ({"pi": [32], "vf": [64]}, "ppo"), ({"pi": [32], "qf": [64]}, "sac")])
def test_net_arch_in_range_is_kept(net_arch, algo):
    assert parse_config(_cfg(net_arch, algo)).hyper["policy_kwargs"]["net_arch"] == net_arch


def test_net_arch_too_wide_through_the_cli(tmp_path, capsys):
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[train]\nalgo = 'ppo'\n[algo.policy_kwargs]\nnet_arch = [1_000_000_000]\n")
    assert main(["train", "--algo", "ppo", "--config", str(cfg), "--out", str(tmp_path / "o"), "--no-progress",
                 "--no-tensorboard"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "[algo.policy_kwargs] net_arch layer 1 must be an integer in [1, 4096]" in err[0], err
    assert not (tmp_path / "o").exists()


# -- the config file itself -----------------------------------------------------------------------------------
def test_config_file_that_is_a_folder_or_not_text(tmp_path):
    refused(lambda: load_config(tmp_path), f"{tmp_path}: is a folder; expected a training config (a TOML file")
    f = tmp_path / "cfg.toml"
    f.write_bytes("[train]\nalgo = 'ppo'\n".encode("utf-16"))
    refused(lambda: load_config(f), "cfg.toml: UTF-16 text", "training config")
    refused(lambda: load_config(tmp_path / "nope.toml"), "nope.toml: does not exist", exc=FileNotFoundError)
