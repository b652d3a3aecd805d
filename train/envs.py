"""Environments for training and evaluation, built from a :class:`~ehas_train.config.TrainConfig`.

One place turns a configuration into environments, so that training, the final
evaluation, the learned controller and ``ehas_train.evaluate`` see exactly the
same observation, action and reward definitions:

* the environment id and keyword arguments, with ``[randomise]`` as the tracking
  environment's ``randomise`` ranges;
* the residual's base controller (``[env] controller``), resolved once at the
  start of training and stored in the agent's ``config.json``: a single PIFF
  runs compiled inside the step (``RigController``); a gain schedule runs in
  Python through :class:`ScheduledBase`, which picks the entry of each
  episode's disc sets;
* :class:`AgentInterface`: the agent's side of the action (scaled to
  ``action_scale_mA``, held for ``action_repeat`` periods) and reward
  (``reward_scale``).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np

EHAS_ID = "ehas/Tracking-v0"
V_SCALE_DEG_S = 30.0 * 2.0 * math.pi * 3.0  # design point's peak rate, +-30 deg at 3 Hz (docs/rig.md)
A_SCALE_DEG_S2 = 30.0 * (2.0 * math.pi * 3.0) ** 2  # design point's peak acceleration (the env's scale)
DP_SCALE_BAR = 110.0  # half the 220 bar supply (docs/rig.md): the ``power`` action shape's load scale
MAX_DISC_SETS = 7  # the rig's heaviest stack (docs/rig.md): the ``reference_sq_load`` action shape's load scale
RATED_CURRENT_MA = 20.0  # the env's action scale: a = 1 is 20 mA (docs/rig.md: +-20 mA servo amplifier)


def is_tracking_env(env_id: str) -> bool:
    """True for the project's tracking environment."""
    return env_id == EHAS_ID


def register_ehas() -> None:
    """Make sure ``ehas/Tracking-v0`` is registered (importing ``ehas_env`` registers it)."""
    if EHAS_ID not in gym.registry:
        import ehas_env  # noqa: F401


# -- residual base controller -----------------------------------------------
def tuned_controller_path(results_dir: str | Path = "results/controllers") -> Path | None:
    """The best tuned classical controller JSON under ``results_dir``, or None.

    "Best" is the lowest ``mean_rms_error_pct`` (mean rms % error over the
    benchmark conditions) the tuner recorded in the file; files without that
    figure are not candidates.
    """
    folder = Path(results_dir)
    if not folder.is_dir():
        return None
    ranked = []
    for path in sorted(folder.rglob("*.json")):
        try:
            data = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError, UnicodeDecodeError):
            continue
        if not isinstance(data, dict) or data.get("format") != "ehas-controller" \
                or data.get("kind", "classical") != "classical":
            continue  # not a controller file of ehas tune (resolve_controller_spec checks the one chosen)
        score = data.get("mean_rms_error_pct")
        if isinstance(score, (int, float)) and np.isfinite(score) and ("gains" in data or "entries" in data):
            ranked.append((float(score), str(path)))
    if not ranked:
        return None
    return Path(min(ranked)[1])


def resolve_controller_spec(spec: str, results_dir: str | Path = "results/controllers") -> dict:
    """Turn ``tuned`` / ``book`` / a JSON path into a self-contained description.

    Returns ``{"source": ..., "data": <controller JSON, or None for the book gains>}``;
    the agent keeps it in its ``config.json``, so it keeps working when
    ``results/controllers`` changes.
    """
    if spec == "book":
        return {"source": "book", "data": None}
    if str(spec).endswith(".py"):  # a controller file in Python, loaded by the user (--controller-path)
        from ehas_controllers.base import loaded_file

        ctrl = loaded_file(spec, "[env] controller")
        return {"source": str(Path(spec).resolve()), "data": ctrl.to_dict(), "file": str(Path(spec).resolve())}
    if spec == "tuned":
        path = tuned_controller_path(results_dir)
        if path is None:
            return {"source": f"book (no tuned controller under {results_dir})", "data": None}
    else:
        path = Path(spec)
        if not path.exists():
            raise FileNotFoundError(f"[env] controller: controller file {path} does not exist")
    from ehas_controllers.base import CONTROLLER_FILE, check_file_header
    from ehas_env.output.files import read_json

    try:
        data = read_json(path, CONTROLLER_FILE)
    except ValueError as exc:
        raise ValueError(f"[env] controller: {exc}") from None
    check_file_header(data, f"[env] controller: controller file {path}")
    return {"source": str(path), "data": data}


def classical_controller(desc: dict | None):
    """The classical controller object of a description (:func:`resolve_controller_spec`)."""
    if desc is None or desc.get("data") is None:
        from ehas_controllers.piff import PIFF

        return PIFF.book()
    from ehas_controllers.base import controller_from_dict, loaded_file

    if desc.get("file"):
        loaded_file(desc["file"], "the agent's base controller")  # its law and type, loaded by the user
    return controller_from_dict(desc["data"])


class ScheduledBase:
    """Residual base that follows a gain schedule: each episode uses its disc sets' entry.

    The tracking environment calls ``reset()`` after drawing an episode, so the
    episode (``env.episode``) is known there.
    """

    kind = "classical"

    def __init__(self, schedule):
        self.schedule = schedule
        self.env = None
        self.active = None

    def reset(self) -> None:
        if self.env is None:
            raise RuntimeError("ScheduledBase: attach the environment (base.env = env) before resetting it")
        self.active = self.schedule.for_plant(int(self.env.unwrapped.episode["episode"]["disc_sets"]))
        self.active.reset()

    def act(self, measurement: dict) -> float:
        return self.active.act(measurement)


def base_for_env(desc: dict | None):
    """What the environment's ``controller=`` gets for the residual base.

    A single PIFF becomes its ``RigController`` (compiled into the step); a
    schedule a :class:`ScheduledBase` (Python, picks the episode's entry).
    """
    ctrl = classical_controller(desc)
    if hasattr(ctrl, "entries"):
        return ScheduledBase(ctrl)
    rig = ctrl.rig_gains()
    if rig is None:
        return ctrl  # any act()-only controller: called in Python
    return rig


# -- the agent's interface to the environment ---------------------------------
class AgentInterface(gym.Wrapper):
    """Action scaling and hold, reward scaling: the agent's side of the environment.

    Parameters
    ----------
    env : gym.Env
        The tracking environment (or any env with a Box action space in [-1, 1]).
    action_repeat : int
        Control periods each action is held for (rewards are summed; an episode
        end stops the hold).
    action_scale : float
        Multiplier from the agent's action to the environment's (for the tracking
        env: action_scale_mA / 20 mA).
    reward_scale : float
        Multiplier on the reward.
    action_penalty : float
        Subtracted per agent step times the squared action (agent units): keeps a
        residual at zero where it does not help.
    reward : str
        ``env``: the environment's reward, ``-(e/A)^2 - rate penalty``; ``abs``:
        ``-|e|/A`` per period (the error on the physical angle; an early end
        still pays the environment's termination penalty).  The benchmark
        averages rms % errors over conditions whose errors span two decades: a
        squared error makes the light conditions' share of the return ~100x
        smaller than the heavy ones', the absolute error ~10x.
    shape : str
        ``constant``, ``velocity``, ``power``, ``reference`` or ``reference_sq``: the action's authority at each
        control period, :func:`authority` of the environment's latest
        ``info`` (reference rate, load pressure).

    Examples
    --------
    >>> import gymnasium as gym
    >>> env = AgentInterface(gym.make("Pendulum-v1"), action_repeat=4, action_scale=0.5)
    >>> _ = env.reset(seed=0)
    >>> env.action_space.shape
    (1,)
    """

    def __init__(self, env: gym.Env, action_repeat: int = 1, action_scale: float = 1.0, reward_scale: float = 1.0,
                 action_penalty: float = 0.0, shape: str = "constant", reward: str = "env"):
        super().__init__(env)
        self.reward = reward
        self._amp = 1.0
        self.shape = shape
        self._last = {}
        self._sets = None
        self.action_penalty = float(action_penalty)
        self.action_repeat = int(action_repeat)
        self.action_scale = float(action_scale)
        self.reward_scale = float(reward_scale)

    def step(self, action):
        a_agent = np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0)
        a = a_agent * np.float32(self.action_scale)
        total = 0.0
        for _ in range(self.action_repeat):
            if self.shape != "constant":
                obs, r, term, trunc, info = self.env.step(a * np.float32(authority(self.shape, self._last,
                                                                                   self._sets)))
                self._last = info
            else:
                obs, r, term, trunc, info = self.env.step(a)
            if self.reward == "abs":
                r = -abs(info["theta_ref_deg"] - info["theta_deg"]) / self._amp + (float(r) if term else 0.0)
            total += float(r)
            if term or trunc:
                break
        penalty = self.action_penalty * float(np.sum(a_agent * a_agent))
        return obs, total * self.reward_scale - penalty, term, trunc, info

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._last = info
        if "episode" in info:
            self._amp = float(info["episode"]["amplitude_deg"])
            self._sets = info["episode"].get("disc_sets")
        return obs, info


def authority(shape: str, m, disc_sets=None) -> float | np.ndarray:
    """Fraction of ``action_scale`` a full action commands now (the ``action_shape``).

    ``m`` holds ``theta_ref_dot`` (deg/s), ``p_a_bar`` and ``p_b_bar`` (scalars
    or arrays: an env's ``info`` or a controller's measurement); ``disc_sets``
    (a scalar or one per row) the load, for ``reference_sq_load``.

    * ``constant``: 1;
    * ``velocity``: ``|theta_ref'| / 565 deg/s`` (the design point's peak rate),
      at most 1 - a correction of the velocity feed-forward;
    * ``power``: that times ``|P_A - P_B| / 110 bar`` (half the supply), at most 1 -
      authority where the valve delivers flow against load, which is where the
      orifice law departs from the linear feed-forward; nil where the reference
      is slow or the load light, so that the policy's imprecision there cannot
      disturb a classical loop that is already good;
    * ``reference``, ``reference_sq``: :func:`reference_authority`, its square;
    * ``reference_sq_load``: ``reference_sq`` times ``disc_sets / 7``: the same
      current accelerates one disc set seven times as much as seven, so a full
      action commands about the same crank acceleration at every load (without
      it, a correction sized for the heavy stacks is a disturbance on the light
      ones).  The disc sets are known on the rig, as the gain schedule knows them.

    Examples
    --------
    >>> authority("power", {"theta_ref_dot": 282.7, "p_a_bar": 165.0, "p_b_bar": 55.0}).round(3)
    np.float64(0.5)
    """
    if shape == "constant":
        return 1.0
    if not m:
        return 0.0 * np.asarray(0.0)
    if shape == "reference":
        return reference_authority(m)
    if shape == "reference_sq":
        return reference_authority(m) ** 2
    if shape == "reference_sq_load":
        if disc_sets is None:
            raise ValueError("action_shape 'reference_sq_load' needs the disc sets of the plant")
        return reference_authority(m) ** 2 * np.asarray(disc_sets, dtype=float) / MAX_DISC_SETS
    f = np.minimum(np.abs(np.asarray(m["theta_ref_dot"], dtype=float)) / V_SCALE_DEG_S, 1.0)
    if shape == "power":
        dp = np.asarray(m["p_a_bar"], dtype=float) - np.asarray(m["p_b_bar"], dtype=float)
        f = f * np.minimum(np.abs(dp) / DP_SCALE_BAR, 1.0)
    return f


def reference_authority(m) -> float | np.ndarray:
    """The ``reference`` action shape: the reference's velocity x acceleration amplitudes over the design point's.

    For a sine ``A sin(w t)``: ``(A w / 565 deg/s) * (A w^2 / 10659 deg/s^2)``, each at most 1,
    from the sample's reference and its derivatives (``rd^2 - r rdd = (A w)^2``,
    ``rdd^2 - rd rddd = (A w^2)^2``): constant over an episode once the fade-in is
    over, a function of the task alone (no feedback through the plant's state,
    which the ``power`` shape has: a correction that raises the load pressure raises
    its own authority), ~0.004 at 10 deg / 1 Hz, 1 at the design point 30 deg / 3 Hz.
    Missing keys count as a reference at rest (authority 0).  ``reference_sq``, its
    square, concentrates the authority further on the fast, large references
    (~2e-5 at 10 deg / 1 Hz, 0.012 at 10 deg / 3 Hz, 0.2 at 20 deg / 3 Hz, 1 at
    30 deg / 3 Hz): the tuned loop is nearly proportional and lightly damped with
    heavy disc stacks, so a bias of a fraction of a mA, or a switching correction, costs
    the slow and small references far more than they could gain.

    Examples
    --------
    >>> import math
    >>> w = 2 * math.pi * 3.0
    >>> float(reference_authority({"theta_ref_deg": 0.0, "theta_ref_dot": 30 * w, "theta_ref_ddot": 0.0,
    ...                            "theta_ref_dddot": -30 * w ** 3}))
    1.0
    """
    def g(key):
        return np.asarray(m.get(key, 0.0), dtype=float)

    r, rd, rdd, rddd = g("theta_ref_deg"), g("theta_ref_dot"), g("theta_ref_ddot"), g("theta_ref_dddot")
    v = np.sqrt(np.maximum(rd * rd - r * rdd, 0.0)) / V_SCALE_DEG_S
    acc = np.sqrt(np.maximum(rdd * rdd - rd * rddd, 0.0)) / A_SCALE_DEG_S2
    return np.minimum(v, 1.0) * np.minimum(acc, 1.0)


def env_kwargs(cfg, controller_desc: dict | None = None) -> dict:
    """Keyword arguments of the environment: the config's, the randomisation, the residual base."""
    kw = dict(cfg.env_kwargs)
    if is_tracking_env(cfg.env_id):
        if cfg.randomise:
            kw["randomise"] = randomise_kwargs(cfg.randomise)
        if cfg.residual:
            kw["controller"] = base_for_env(controller_desc)
    elif cfg.randomise or cfg.residual:
        raise ValueError(f"[randomise] and [env] residual apply to {EHAS_ID} only, not {cfg.env_id}")
    return kw


def randomise_kwargs(rnd: dict) -> dict:
    """``[randomise]`` as the tracking environment's ``randomise`` ranges (tuples)."""
    out = {}
    for key, value in rnd.items():
        if key == "effects":
            out[key] = {name: (params if params == "typical" else
                               {p: (tuple(r) if isinstance(r, list) else r) for p, r in params.items()})
                        for name, params in value.items()}
        else:
            out[key] = tuple(value)
    return out


def make_env(cfg, *, controller_desc: dict | None = None, interface: bool = True, **overrides) -> gym.Env:
    """One environment of ``cfg`` (``overrides`` replace its keyword arguments).

    ``interface=False`` returns the bare environment (actions in the env's units).
    """
    if is_tracking_env(cfg.env_id):
        register_ehas()
    kw = env_kwargs(cfg, controller_desc)
    kw.update(overrides)
    env = gym.make(cfg.env_id, **kw)
    base = kw.get("controller")
    if isinstance(base, ScheduledBase):
        base.env = env
    if not interface:
        return env
    scale = cfg.action_scale_mA / RATED_CURRENT_MA if is_tracking_env(cfg.env_id) else 1.0
    return AgentInterface(env, cfg.action_repeat, scale, cfg.reward_scale, cfg.action_penalty, cfg.action_shape,
                          cfg.reward)


def make_vec_env(cfg, *, controller_desc: dict | None = None, n_envs: int | None = None, seed: int | None = None):
    """The batched training environments of ``cfg``, wrapped in ``VecMonitor``.

    Each episode's final ``info`` holds the tracking env's ``rms_error_pct`` and
    ``peak_error_pct``; ``VecMonitor`` copies them into the episode record.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    n = n_envs if n_envs is not None else cfg.n_envs
    fns = [(lambda: make_env(cfg, controller_desc=controller_desc)) for _ in range(n)]
    vec = SubprocVecEnv(fns) if cfg.vec_env == "subproc" else DummyVecEnv(fns)
    keys = ("rms_error_pct", "peak_error_pct") if is_tracking_env(cfg.env_id) else ()
    vec = VecMonitor(vec, info_keywords=keys)
    vec.seed(cfg.seed if seed is None else seed)
    return vec


def random_policy_return(cfg, episodes: int, seed: int = 12345) -> float:
    """Mean return (the agent's reward units) of uniformly random actions."""
    env = make_env(cfg)
    env.action_space.seed(seed)
    total = []
    for ep in range(episodes):
        env.reset(seed=seed + ep)
        ret, done = 0.0, False
        while not done:
            _, r, term, trunc, _ = env.step(env.action_space.sample())
            ret += float(r)
            done = term or trunc
        total.append(ret)
    env.close()
    return float(np.mean(total))
