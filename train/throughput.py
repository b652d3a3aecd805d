"""Training throughput: env-steps per second of SB3 training, batched VecEnv vs ``DummyVecEnv``.

:func:`measure` trains one configuration for a fixed number of agent steps on
each kind of vector env, in the same process (rounds alternate between the
kinds; medians count), and reports:

* ``agent_steps_per_s``: the agent's transitions per second of ``learn()``
  (rollout collection + gradient steps, callbacks off);
* ``env_steps_per_s``: control periods per second (agent steps x ``action_repeat``),
  the environment's own unit;
* ``env_share``: share of the training time spent in the vector env's
  ``step_wait`` (everything below SB3's ``VecEnv`` interface: Python wrappers
  and environments for ``DummyVecEnv``, the adapter and the compiled step for
  the batched env);
* ``plant_share`` (batched only): share spent in the compiled plant step itself.

``ehas perf`` runs it for PPO and SAC (``--training``); ``python -m ehas_train.throughput``
prints one measurement.
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

CONFIGS = {"ppo": "ppo", "sac": "residual_sac_gentle"}  # bundled configs measured by ``ehas perf``


class _Timed:
    """Wraps a VecEnv's ``step_wait`` to add up its time."""

    def __init__(self, venv):
        self.total = 0.0
        from stable_baselines3.common.vec_env import VecEnvWrapper

        inner = venv
        while isinstance(inner, VecEnvWrapper):
            inner = inner.venv
        self.inner = inner
        orig = inner.step_wait

        def step_wait():
            t0 = time.perf_counter()
            out = orig()
            self.total += time.perf_counter() - t0
            return out

        inner.step_wait = step_wait


def _model(cfg, venv):
    from stable_baselines3.common.vec_env import VecNormalize

    from .config import algo_class
    from .trainer import _algo_kwargs, silent_logger

    env = VecNormalize(venv, norm_obs=True, norm_reward=cfg.norm_reward, clip_obs=cfg.clip_obs,
                       gamma=cfg.hyper.get("gamma", 0.99)) if cfg.vecnormalize else venv
    model = algo_class(cfg.algo)("MlpPolicy", env, seed=cfg.seed, device="cpu", verbose=0,
                                 **_algo_kwargs(cfg, venv.action_space.shape[0]))
    silent_logger(model)
    return model


def measure_once(cfg, vec_env: str, steps: int, warmup: int, controller_desc=None) -> dict:
    """One timed ``learn()`` of ``steps`` agent steps after ``warmup`` untimed ones."""
    import torch

    from .batched import make_training_vec_env

    torch.set_num_threads(cfg.torch_threads)
    venv = make_training_vec_env(cfg, controller_desc=controller_desc, vec_env=vec_env)
    model = _model(cfg, venv)
    model.learn(total_timesteps=warmup)
    timer = _Timed(venv)
    plant0 = getattr(timer.inner, "plant_time_s", None)
    n0 = model.num_timesteps
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    wall = time.perf_counter() - t0
    done = model.num_timesteps - n0
    out = {"vec_env": vec_env, "agent_steps": int(done), "wall_s": wall, "agent_steps_per_s": done / wall,
           "env_steps_per_s": done * cfg.action_repeat / wall, "env_share": timer.total / wall}
    if plant0 is not None:
        out["plant_share"] = (timer.inner.plant_time_s - plant0) / wall
    venv.close()
    return out


def measure(cfg, *, steps: int, warmup: int, repeats: int = 1, kinds=("batched", "dummy"),
            controller_desc=None) -> dict:
    """Median figures of each vector-env kind, rounds alternating (see the module docstring)."""
    from . import envs as E

    if cfg.residual and controller_desc is None:
        controller_desc = E.resolve_controller_spec(cfg.controller)
    rounds = {k: [] for k in kinds}
    for r in range(repeats):
        for k in (kinds if r % 2 == 0 else tuple(reversed(kinds))):
            rounds[k].append(measure_once(cfg, k, steps, warmup, controller_desc))
    out = {"algo": cfg.algo, "config": cfg.source, "residual": cfg.residual, "n_envs": cfg.n_envs,
           "action_repeat": cfg.action_repeat, "steps": steps, "warmup": warmup, "repeats": repeats,
           "base": (controller_desc or {}).get("source") if cfg.residual else None}
    for k, rows in rounds.items():
        med = {key: statistics.median(r[key] for r in rows) for key in rows[0] if key not in ("vec_env",)}
        out[k] = {**med, "rounds": rows}
    if "batched" in out and "dummy" in out:
        out["speedup"] = out["batched"]["agent_steps_per_s"] / out["dummy"]["agent_steps_per_s"]
    return out


def bundled(algo: str, n_envs: int | None = None):
    """The bundled config ``ehas perf`` measures for ``algo`` (optionally with ``n_envs``)."""
    from .config import bundled_config, load_config

    cfg = load_config(bundled_config(CONFIGS[algo]))
    return cfg.replace(n_envs=n_envs) if n_envs else cfg


def with_learning_starts(cfg, n: int):
    """``cfg`` with ``[algo] learning_starts = n`` (the throughput after it does not depend on it)."""
    from .config import parse_config

    raw = cfg.to_file_dict()
    raw["algo"]["learning_starts"] = int(n)
    return parse_config(raw, source=cfg.source)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--algo", choices=tuple(CONFIGS), default="ppo")
    p.add_argument("--n-envs", type=int, default=None)
    p.add_argument("--steps", type=int, default=20_000)
    p.add_argument("--warmup", type=int, default=2_000)
    p.add_argument("--repeats", type=int, default=1)
    a = p.parse_args(argv)
    res = measure(bundled(a.algo, a.n_envs), steps=a.steps, warmup=a.warmup, repeats=a.repeats)
    for k in ("batched", "dummy"):
        r = res[k]
        print(f"{a.algo} {k}: {r['agent_steps_per_s']:.0f} agent steps/s, {r['env_steps_per_s']:.0f} env-steps/s, "
              f"env share {r['env_share']:.1%}" + (f", plant share {r['plant_share']:.1%}" if "plant_share" in r else ""))
    print(f"speed-up {res['speedup']:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
