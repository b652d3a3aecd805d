"""A controller written outside the package, in one file, runs everywhere with no edit of ehas."""
from __future__ import annotations

import textwrap

import numpy as np
import pytest

PD_FILE = textwrap.dedent('''
    """PD + velocity feed-forward: a user's compiled controller in one file."""
    from dataclasses import dataclass

    from ehas_controllers.base import CompiledController


    @dataclass
    class PDFF(CompiledController):
        type_name = "user_pd_ff"
        name = "PD+FF (user)"
        Kp: float = 1.5
        Kd: float = 0.01
        Kv: float = 1.0 / 56.25

        @staticmethod
        def law(gains, mem, t, dt, theta, r, rd, rdd, rddd, p_load, p_s, u_max):
            e = r - theta
            de = (e - mem[0]) / dt if mem[1] > 0.0 else 0.0
            mem[0] = e
            mem[1] = 1.0
            u = gains[0] * e + gains[1] * de + gains[2] * rd
            return min(max(u, -u_max), u_max)
''')


@pytest.fixture(scope="module")
def pd(tmp_path_factory):
    from ehas_controllers.base import load_controller

    path = tmp_path_factory.mktemp("my_controllers") / "my_pd.py"
    path.write_text(PD_FILE)
    return path, load_controller(path)


CONDS = [(2, 1.0, 20.0), (5, 2.0, 10.0)]


def _plant_rows(ctrl):
    """The truth: the same law run in Python, step by step, through Plant (no compiled law used)."""
    from ehas_controllers.batch_sim import DEFAULT_CYCLES
    from ehas_env.simulation.plant import Plant

    class PythonOnly:  # hides the compiled law: Plant calls act() in its Python loop
        def reset(self):
            ctrl.reset()

        def act(self, m):
            return ctrl.act(m)

    out = []
    for n, f, a in CONDS:
        res = Plant(disc_sets=n).simulate_closed_loop(PythonOnly(), amplitude_deg=a, freq_hz=f, cycles=DEFAULT_CYCLES)
        out.append(res.tracking_errors()["rms_error_pct"])
    return np.array(out)


def test_user_controller_runs_in_the_benchmark(pd):
    from ehas_controllers.batch_sim import Condition
    from ehas_controllers.benchmark import evaluate_controller

    _, ctrl = pd
    rows = evaluate_controller(ctrl, [Condition(n, f, a) for n, f, a in CONDS])
    got = np.array([r["rms_error_pct"] for r in rows])
    np.testing.assert_allclose(got, _plant_rows(ctrl), rtol=1e-6)
    assert all(0.0 < g < 20.0 for g in got)


@pytest.mark.slow  # compiles the batched kernel with a user law of its own: 1.5 min
def test_user_controller_is_the_batched_envs_residual_base(pd):
    from ehas_env.env.vector_env import TrackingVectorEnv
    from ehas_env.simulation.plant import Plant

    _, ctrl = pd
    venv = TrackingVectorEnv(2, controller=ctrl, disc_sets=3, amplitude_deg=20.0, freq_hz=1.0, cycles=3.0)
    venv.reset(seed=0)
    thetas = []
    for _ in range(1500):
        _, _, _, _, info = venv.step(np.zeros((2, 1), np.float32))
        thetas.append(info["theta_deg"][0])
    res = Plant(disc_sets=3).simulate_closed_loop(ctrl, amplitude_deg=20.0, freq_hz=1.0, duration=1.6)
    np.testing.assert_allclose(np.array(thetas), res.theta_deg[1:1501], atol=1e-9)


def _learned_agents_base_in_evaluation(pd):
    from ehas_train.config import parse_config
    from ehas_train.evaluate import evaluate_policy
    from ehas_train.envs import resolve_controller_spec

    path, ctrl = pd
    cfg = parse_config({"train": {"algo": "ppo", "total_steps": 1000}, "algo": {},
                        "env": {"id": "ehas/Tracking-v0", "residual": True, "controller": str(path),
                                "action_scale_mA": 3.0, "kwargs": {}}})
    desc = resolve_controller_spec(str(path))
    rows = evaluate_policy(cfg, lambda obs: np.zeros((obs.shape[0], 1)), CONDS, controller_desc=desc)
    np.testing.assert_allclose([r["rms_error_pct"] for r in rows], _plant_rows(ctrl), rtol=1e-6)


@pytest.mark.slow  # compiles the batched kernel's inlined build with the user's law: 343 s on 2 loaded cores
def test_user_controller_is_the_learned_agents_base_in_evaluation(pd):
    _learned_agents_base_in_evaluation(pd)


def test_user_controller_is_the_learned_agents_base_in_evaluation_on_the_quick_build(pd, monkeypatch):
    """The same check on the quick-compile build (EHAS_BUILD=quick, seconds to compile): the default run's."""
    monkeypatch.setenv("EHAS_BUILD", "quick")
    _learned_agents_base_in_evaluation(pd)


# slow: `ehas bench` compiles the fast-step build with a new law (about 1.5 min on 2 cores);
# test_user_controller_runs_in_the_benchmark runs the same file in the benchmark in the default run
@pytest.mark.slow
def test_bench_command_takes_a_controller_file(pd, tmp_path):
    from ehas_env.cli.main import main

    path, _ = pd
    assert main(["bench", str(path), "--out", str(tmp_path / "b"), "--no-robustness"]) == 0
    assert "PD+FF (user)" in (tmp_path / "b" / "benchmark.md").read_text()
