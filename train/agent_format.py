"""The agent folder's data-only format: weights that cannot run code.

An agent folder holds (docs/agents.md):

``policy.safetensors``
    The policy's ``state_dict`` (safetensors: tensors and their names, nothing
    executable).
``policy.json``
    ``{"format": "ehas-agent-policy", "version": 1, "algo": "sac", "policy": "SACPolicy",
    "observation_space": {...}, "action_space": {...}, "kwargs": {...}}``: what rebuilds the
    stable-baselines3 policy around those weights (network sizes, activation by name).
``obs_norm.json``
    The observation statistics of training (``VecNormalize``): ``mean``, ``var``, ``count``,
    ``clip_obs``, ``epsilon``, ``gamma`` (JSON numbers: Python's float text round-trips
    exactly, so the normalised observation is bit for bit the pickled one's).
``config.json``
    The resolved training configuration (as before).

:func:`write_safe` writes the three files from a stable-baselines3 model and its
``VecNormalize``; :func:`read_safe` rebuilds a policy and :class:`ObsNorm` from them
without unpickling.  Older folders (``model.zip``, ``vecnormalize.pkl``: Python pickles)
load only through ``load_agent(..., allow_pickle=True)`` / ``--allow-pickle``.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

POLICY_FILE = "policy.safetensors"
POLICY_JSON = "policy.json"
NORM_JSON = "obs_norm.json"
POLICY_FORMAT = "ehas-agent-policy"
NORM_FORMAT = "ehas-obs-norm"
VERSION = 1
#: the policy classes, activations, optimisers and feature extractors a policy.json may name (by name: nothing
#: else is looked up)
POLICIES = {"ppo": "ActorCriticPolicy", "sac": "SACPolicy", "td3": "TD3Policy"}
ACTIVATIONS = ("Tanh", "ReLU", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid")
OPTIMIZERS = ("Adam", "AdamW", "RMSprop", "SGD")
EXTRACTORS = ("FlattenExtractor",)


class ObsNorm:
    """Observation normalisation of a training (``VecNormalize.normalize_obs``, read from JSON).

    Parameters
    ----------
    mean, var : array
        Running mean and variance of the observations (float64).
    count : float
        Observations counted.
    clip_obs, epsilon : float
        Clip of the normalised observation; epsilon under the square root.
    gamma : float
        Discount of the reward statistics (kept for the record).
    """

    def __init__(self, mean, var, count: float, clip_obs: float, epsilon: float, gamma: float = 0.99):
        self.mean = np.asarray(mean, dtype=np.float64)
        self.var = np.asarray(var, dtype=np.float64)
        self.count, self.clip_obs, self.epsilon, self.gamma = float(count), float(clip_obs), float(epsilon), float(gamma)

    def normalize_obs(self, obs):
        """The observation as the policy saw it in training (float32), as ``VecNormalize.normalize_obs``."""
        return np.clip((obs - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip_obs,
                       self.clip_obs).astype(np.float32)

    def to_dict(self) -> dict:
        return {"format": NORM_FORMAT, "version": VERSION, "mean": [float(v) for v in self.mean],
                "var": [float(v) for v in self.var], "count": self.count, "clip_obs": self.clip_obs,
                "epsilon": self.epsilon, "gamma": self.gamma}


def _box(space) -> dict:
    return {"low": [float(v) for v in np.ravel(space.low)], "high": [float(v) for v in np.ravel(space.high)],
            "shape": [int(v) for v in space.shape], "dtype": str(space.dtype)}


def _kwargs(policy) -> dict:
    """The policy's constructor parameters as JSON (classes by name, from the allow-lists)."""
    out = {}
    for k, v in policy._get_constructor_parameters().items():
        if k in ("observation_space", "action_space", "lr_schedule"):
            continue
        if isinstance(v, type):
            v = v.__name__
        out[k] = v
    return out


def write_safe(folder, model, vecnorm=None) -> None:
    """Write ``policy.safetensors``, ``policy.json`` and (with ``vecnorm``) ``obs_norm.json`` into ``folder``.

    Parameters
    ----------
    folder : path
        The agent folder.
    model : stable_baselines3 model or policy
        Its ``policy`` (or itself, a policy) gives weights and architecture.
    vecnorm : VecNormalize or ObsNorm or None
        The observation statistics.
    """
    from safetensors.torch import save as st_save

    from ehas_env.output.files import atomic_write_bytes, atomic_write_text

    folder = Path(folder)
    policy = getattr(model, "policy", model)
    algo = next((a for a, name in POLICIES.items() if type(policy).__name__ == name), None)
    if algo is None:
        raise ValueError(f"{folder}: cannot store a {type(policy).__name__} (known: {', '.join(POLICIES.values())})")
    state = {k: v.detach().cpu().clone().contiguous() for k, v in policy.state_dict().items()}
    doc = {"format": POLICY_FORMAT, "version": VERSION, "algo": algo, "policy": POLICIES[algo],
           "observation_space": _box(policy.observation_space), "action_space": _box(policy.action_space),
           "kwargs": _kwargs(policy)}
    atomic_write_bytes(folder / POLICY_FILE, st_save(state))
    atomic_write_text(folder / POLICY_JSON, json.dumps(doc, indent=1) + "\n")
    if vecnorm is not None:
        if not isinstance(vecnorm, ObsNorm):
            rms = vecnorm.obs_rms
            vecnorm = ObsNorm(rms.mean, rms.var, rms.count, vecnorm.clip_obs, vecnorm.epsilon,
                              getattr(vecnorm, "gamma", 0.99))
        atomic_write_text(folder / NORM_JSON, json.dumps(vecnorm.to_dict(), indent=1) + "\n")


def _fail(path, text):
    raise ValueError(f"{path}: {text}")


def _numbers(path, doc, key, n=None) -> list:
    v = doc.get(key)
    if not isinstance(v, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                                          for x in v) or (n is not None and len(v) != n):
        _fail(path, f"{key} must be a list of {n or ''} finite numbers".replace("  ", " "))
    return v


def _space(path, doc, key):
    from gymnasium.spaces import Box

    sp = doc.get(key)
    if not isinstance(sp, dict) or set(sp) != {"low", "high", "shape", "dtype"}:
        _fail(path, f"{key} must be an object with low, high, shape, dtype")
    shape = sp["shape"]
    if not (isinstance(shape, list) and len(shape) == 1 and isinstance(shape[0], int) and 0 < shape[0] < 10_000):
        _fail(path, f"{key}.shape must be [n], one positive integer")
    if sp["dtype"] not in ("float32", "float64"):
        _fail(path, f"{key}.dtype must be float32 or float64")
    low, high = _numbers(path, sp, "low", shape[0]), _numbers(path, sp, "high", shape[0])
    return Box(np.array(low, dtype=sp["dtype"]), np.array(high, dtype=sp["dtype"]), dtype=sp["dtype"])


def _arch(path, v):
    ints = lambda x: isinstance(x, list) and all(isinstance(i, int) and not isinstance(i, bool) and 0 < i <= 4096
                                                 for i in x) and len(x) <= 16  # noqa: E731
    if ints(v) or (isinstance(v, dict) and set(v) <= {"pi", "vf", "qf"} and all(ints(x) for x in v.values())):
        return v
    _fail(path, "kwargs.net_arch must be a list of layer sizes or {pi, vf, qf: [sizes]}")


def read_norm(path) -> ObsNorm:
    """The :class:`ObsNorm` of an ``obs_norm.json`` (one-line ValueError naming the file and the key)."""
    from ehas_env.output.files import read_json

    doc = read_json(path, f"the observation statistics of an agent (\"format\": \"{NORM_FORMAT}\")")
    if not isinstance(doc, dict) or doc.get("format") != NORM_FORMAT:
        _fail(path, f"not the observation statistics of an agent (expected \"format\": \"{NORM_FORMAT}\")")
    if type(doc.get("version")) is not int or doc.get("version") != VERSION:
        _fail(path, f"version = {doc.get('version')!r}; this ehas reads version {VERSION}")
    mean = _numbers(path, doc, "mean")
    var = _numbers(path, doc, "var", len(mean))
    if any(v < 0 for v in var):
        _fail(path, "var must not be negative")
    vals = {}
    for k in ("count", "clip_obs", "epsilon", "gamma"):
        v = doc.get(k)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or v < 0:
            _fail(path, f"{k} must be a finite number >= 0, got {v!r}")
        vals[k] = v
    return ObsNorm(mean, var, **vals)


def read_safe(folder, algo: str):
    """The stable-baselines3 policy of an agent folder, from ``policy.json`` and ``policy.safetensors``.

    Parameters
    ----------
    folder : path
        The agent folder.
    algo : str
        The algorithm its ``config.json`` names (must match ``policy.json``).

    Returns
    -------
    torch.nn.Module
        The policy (``predict(obs, deterministic=True)``), in evaluation mode.
    """
    import torch
    from safetensors import SafetensorError
    from safetensors.torch import load as st_load

    from ehas_env.output.files import read_json

    folder = Path(folder)
    pj = folder / POLICY_JSON
    doc = read_json(pj, f"an agent policy description (\"format\": \"{POLICY_FORMAT}\")")
    if not isinstance(doc, dict) or doc.get("format") != POLICY_FORMAT:
        _fail(pj, f"not an agent policy description (expected \"format\": \"{POLICY_FORMAT}\")")
    if type(doc.get("version")) is not int or doc.get("version") != VERSION:
        _fail(pj, f"version = {doc.get('version')!r}; this ehas reads version {VERSION}")
    if doc.get("algo") != algo or doc.get("policy") != POLICIES.get(algo):
        _fail(pj, f"algo/policy = {doc.get('algo')!r}/{doc.get('policy')!r}; config.json says {algo!r} "
                  f"({POLICIES.get(algo)})")
    obs_space, act_space = _space(pj, doc, "observation_space"), _space(pj, doc, "action_space")
    kw = dict(doc.get("kwargs") or {})
    if not isinstance(doc.get("kwargs", {}), dict):
        _fail(pj, "kwargs must be an object")
    names = {"activation_fn": (torch.nn, ACTIVATIONS), "optimizer_class": (torch.optim, OPTIMIZERS)}
    for key, (mod, allowed) in names.items():
        if key in kw:
            if kw[key] not in allowed:
                _fail(pj, f"kwargs.{key} = {kw[key]!r}; allowed: {', '.join(allowed)}")
            kw[key] = getattr(mod, kw[key])
    if "features_extractor_class" in kw:
        if kw["features_extractor_class"] not in EXTRACTORS:
            _fail(pj, f"kwargs.features_extractor_class = {kw['features_extractor_class']!r}; allowed: "
                      f"{', '.join(EXTRACTORS)}")
        from stable_baselines3.common import torch_layers

        kw["features_extractor_class"] = getattr(torch_layers, kw["features_extractor_class"])
    if "net_arch" in kw:
        kw["net_arch"] = _arch(pj, kw["net_arch"])
    for k, v in kw.items():
        if not (callable(v) or isinstance(v, (int, float, str, bool, list, dict, type(None)))):
            _fail(pj, f"kwargs.{k}: not a plain value")
    if algo == "ppo":
        from stable_baselines3.common.policies import ActorCriticPolicy as P
    elif algo == "sac":
        from stable_baselines3.sac.policies import SACPolicy as P
    else:
        from stable_baselines3.td3.policies import TD3Policy as P
    try:
        policy = P(obs_space, act_space, lambda _: 0.0, **kw)
    except (TypeError, ValueError) as exc:
        _fail(pj, f"kwargs do not build a {P.__name__}: {' '.join(str(exc).split())}")
    wp = folder / POLICY_FILE
    try:
        state = st_load(wp.read_bytes())
    except FileNotFoundError:
        _fail(wp, "missing; an agent folder holds policy.safetensors (the policy weights) beside policy.json")
    except (OSError, SafetensorError, ValueError) as exc:
        _fail(wp, f"not a safetensors file of policy weights ({' '.join(str(exc).split()) or type(exc).__name__})")
    try:
        policy.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        _fail(wp, f"the weights do not fit the policy policy.json describes: {' '.join(str(exc).split())[:300]}")
    policy.set_training_mode(False)
    return policy
