"""A stable-baselines3 ``VecEnv`` over the native batched tracking environment.

:class:`BatchedTrackingVecEnv` steps all N environments of a
:class:`~ehas_env.env.vector_env.TrackingVectorEnv` in one compiled call per
control period, and does on arrays what :class:`~ehas_train.envs.AgentInterface`
does per environment (action scale, shape and hold, reward scale and penalty),
so that training sees exactly the transitions of SB3's ``DummyVecEnv`` over N
``AgentInterface(gym.make("ehas/Tracking-v0"))`` environments seeded alike:
environment i seeded ``s + i`` follows the same episodes (``tests/train``
checks it), without the per-environment Python step.

SB3's ``VecEnv`` contract:

* ``step_async`` / ``step_wait``: an environment whose episode ended is reset
  in the same call; its ``info`` holds ``terminal_observation`` (the last
  observation), ``TimeLimit.truncated``, and the episode's ``rms_error_pct``,
  ``peak_error_pct``, ``metric_complete``, ``hit_stroke_end``,
  ``saturation_frac`` (share of control periods at +-20 mA) and
  ``episode_steps``; other environments' infos are empty (nothing per step is
  read by the trainer);
* ``seed(s)`` then ``reset()``: environment i gets ``s + i``; ``reset()``
  without a seed continues each environment's random stream;
* ``VecNormalize``, ``VecMonitor`` and checkpoints wrap it as any ``VecEnv``.

A residual base given as a gain schedule runs compiled (each episode its disc
sets' entry); the ``DummyVecEnv`` path calls it in Python.

Examples
--------
>>> from ehas_train.config import parse_config
>>> cfg = parse_config({"train": {"algo": "ppo", "n_envs": 4}, "env": {"kwargs": {"cycles": 2}}})
>>> venv = BatchedTrackingVecEnv(cfg)
>>> venv.seed(0)
[0, 1, 2, 3]
>>> venv.reset().shape
(4, 13)
"""
from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from . import envs as E

VEC_ENVS = ("batched", "dummy", "subproc")
I_MAX_MA = 20.0  # servo amplifier clip (docs/rig.md)
_SHAPE_KEYS = ("theta_ref_deg", "theta_ref_dot", "theta_ref_ddot", "theta_ref_dddot", "p_a_bar", "p_b_bar")


def batch_base(desc: dict | None):
    """The residual base for the vector env: a compiled law, or the schedule itself (compiled per episode)."""
    ctrl = E.classical_controller(desc)
    if callable(getattr(ctrl, "for_plant", None)):
        return ctrl
    rig = ctrl.rig_gains() if callable(getattr(ctrl, "rig_gains", None)) else None
    if rig is None:
        raise ValueError(f"the residual base {getattr(ctrl, 'name', type(ctrl).__name__)!r} has no compiled law; "
                         "train it with [train] vec_env = \"dummy\" (its act() is called in Python)")
    return rig


class BatchedTrackingVecEnv(VecEnv):
    """SB3 ``VecEnv`` of ``cfg``'s tracking environments, stepped in one compiled call (module docstring).

    Parameters
    ----------
    cfg : TrainConfig
        Environment settings, randomisation, residual base, agent interface.
    controller_desc : dict, optional
        The resolved residual base (``envs.resolve_controller_spec``).
    n_envs : int, optional
        Number of environments (default ``cfg.n_envs``).
    parallel : bool
        Step the rows on every core (numba ``prange``).
    """

    def __init__(self, cfg, controller_desc: dict | None = None, n_envs: int | None = None, parallel: bool = False):
        import gymnasium as gym

        from ehas_env.env.vector_env import TrackingVectorEnv

        if not E.is_tracking_env(cfg.env_id):
            raise ValueError(f"the batched VecEnv runs {E.EHAS_ID} only, not {cfg.env_id}; use vec_env = \"dummy\"")
        E.register_ehas()
        kw = dict(cfg.env_kwargs)
        if cfg.randomise:
            kw["randomise"] = E.randomise_kwargs(cfg.randomise)
        if cfg.residual:
            kw["controller"] = batch_base(controller_desc)
        n = int(n_envs if n_envs is not None else cfg.n_envs)
        self.venv = TrackingVectorEnv(n, max_episode_steps=gym.spec(E.EHAS_ID).max_episode_steps, parallel=parallel,
                                      **kw)
        self.cfg = cfg
        self.render_mode = None
        self.action_repeat = int(cfg.action_repeat)
        self.action_scale = np.float32(cfg.action_scale_mA / E.RATED_CURRENT_MA)
        self.reward_scale = float(cfg.reward_scale)
        self.action_penalty = float(cfg.action_penalty)
        self.shape = cfg.action_shape
        self.reward_kind = cfg.reward
        super().__init__(n, self.venv.single_observation_space, self.venv.single_action_space)
        self._actions = None
        self._amp = np.ones(n)
        self._nsat = np.zeros(n)
        self._nstep = np.zeros(n)
        self._started = False
        self.plant_time_s = 0.0  # time spent in the compiled step (ehas perf: the plant's share)

    # -- VecEnv API ------------------------------------------------------------
    def reset(self):
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        opts = self._options[0] if self._options and self._options[0] else None
        if any(o != self._options[0] for o in self._options):
            raise ValueError("BatchedTrackingVecEnv: per-environment reset options differ; give one dict for all")
        obs, _ = self.venv.reset(seed=seeds, options=dict(opts) if opts else None)
        self._after_reset(np.ones(self.num_envs, bool))
        self._started = True
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        import time

        n = self.num_envs
        a_agent = np.clip(np.asarray(self._actions, dtype=np.float32).reshape(n, 1), -1.0, 1.0)
        a = a_agent * self.action_scale
        total = np.zeros(n)
        ended = np.zeros(n, bool)
        term = np.zeros(n, bool)
        trunc = np.zeros(n, bool)
        v = self.venv
        t_plant = 0.0
        for _ in range(self.action_repeat):
            active = ~ended
            if self.shape != "constant":
                last = {k: v.raw(k) for k in _SHAPE_KEYS}
                applied = a * np.asarray(E.authority(self.shape, last, v.episode_disc_sets()), np.float32).reshape(n, 1)
            else:
                applied = a
            t0 = time.perf_counter()
            obs, r, te, tr = v.step_rows(applied, active)
            t_plant += time.perf_counter() - t0
            if self.reward_kind == "abs":
                r = -np.abs(v.raw("theta_ref_deg") - v.raw("theta_deg")) / self._amp + np.where(te, r, 0.0)
            total += np.where(active, r, 0.0)
            cur = np.abs(v.raw("current_mA"))
            self._nsat += active & (cur >= I_MAX_MA * (1.0 - 1e-9))
            self._nstep += active
            term |= te & active
            trunc |= tr & active
            ended |= (te | tr) & active
            if ended.all():
                break
        self.plant_time_s += t_plant
        penalty = self.action_penalty * (a_agent * a_agent).sum(axis=1).astype(np.float64)
        rewards = (total * self.reward_scale - penalty).astype(np.float32)
        infos = [{} for _ in range(n)]
        if ended.any():
            idx = np.flatnonzero(ended)
            for i in idx:
                m = v.episode_metrics(int(i))
                infos[i] = {"terminal_observation": obs[i].copy(),
                            "TimeLimit.truncated": bool(trunc[i] and not term[i]),
                            "rms_error_pct": float(m["rms_error_pct"]), "peak_error_pct": float(m["peak_error_pct"]),
                            "metric_complete": bool(m["metric_complete"]), "hit_stroke_end": bool(term[i]),
                            "saturation_frac": float(self._nsat[i] / max(self._nstep[i], 1.0)),
                            "episode_steps": int(self._nstep[i])}
            t0 = time.perf_counter()
            new_obs, _ = v.reset(options={"reset_mask": ended})
            self.plant_time_s += time.perf_counter() - t0
            obs[idx] = new_obs[idx]
            self._after_reset(ended)
        return obs, rewards, ended.copy(), infos

    def _after_reset(self, mask: np.ndarray) -> None:
        self._amp[mask] = self.venv.episode_amplitudes()[mask]
        self._nsat[mask] = 0.0
        self._nstep[mask] = 0.0

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices=None) -> list:
        value = getattr(self, attr_name) if attr_name in ("render_mode",) else getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        idx = list(self._get_indices(indices))
        if len(idx) != self.num_envs:
            raise ValueError("BatchedTrackingVecEnv: attributes are shared by all environments; set them for all")
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        if method_name == "episode_metrics":
            return [self.venv.episode_metrics(i) for i in self._get_indices(indices)]
        raise NotImplementedError(f"BatchedTrackingVecEnv: env_method({method_name!r}) - the environments are rows "
                                  "of one TrackingVectorEnv (self.venv), call it there")

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]


def make_training_vec_env(cfg, *, controller_desc: dict | None = None, n_envs: int | None = None,
                          seed: int | None = None, vec_env: str | None = None):
    """The training environments of ``cfg``, wrapped in ``VecMonitor`` and seeded.

    ``vec_env`` (default ``cfg.vec_env``): ``batched`` (:class:`BatchedTrackingVecEnv`;
    for other environment ids than the tracking env, ``dummy``), ``dummy`` or
    ``subproc`` (SB3's vector envs over :func:`~ehas_train.envs.make_env`).
    """
    from stable_baselines3.common.vec_env import VecMonitor

    kind = vec_env or cfg.vec_env
    if kind not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {', '.join(VEC_ENVS)}, got {kind!r}")
    if kind != "batched" or not E.is_tracking_env(cfg.env_id):
        if cfg.vec_env == kind:
            return E.make_vec_env(cfg, controller_desc=controller_desc, n_envs=n_envs, seed=seed)
        raw = cfg.to_file_dict()
        raw["train"]["vec_env"] = "dummy" if kind == "batched" else kind
        from .config import parse_config

        return E.make_vec_env(parse_config(raw, source=cfg.source), controller_desc=controller_desc, n_envs=n_envs,
                              seed=seed)
    vec = BatchedTrackingVecEnv(cfg, controller_desc, n_envs)
    keys = ("rms_error_pct", "peak_error_pct", "saturation_frac", "hit_stroke_end")
    vec = VecMonitor(vec, info_keywords=keys)
    vec.seed(cfg.seed if seed is None else seed)
    return vec
