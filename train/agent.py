"""A trained agent as a controller: load, act deterministically, evaluate.

An agent folder (what ``ehas train`` writes) is data (docs/agents.md):
``config.json`` (the resolved training configuration: environment, action hold
and scale, residual base controller), ``policy.safetensors`` (the policy's
weights), ``policy.json`` (its architecture, classes by name from fixed lists)
and ``obs_norm.json`` (observation statistics, when trained with
``vecnormalize = true``).  Loading it never unpickles (:mod:`.agent_format`).
A missing or damaged file is refused naming it.

Older folders (``model.zip``, ``vecnormalize.pkl``: Python pickles, which run
any code they hold when loaded) and bare stable-baselines3 ``.zip`` files load
only with ``allow_pickle=True`` (``--allow-pickle``), with the
:class:`PickleWarning` unless their files are on the per-user list of agents
trained here (:func:`trust_agent`); ``python -m ehas_train.agent_convert``
converts them once.

``ehas bench`` finds agents through the controller registry of
``ehas_controllers.base``: importing this module registers agent folders and
``.zip`` files.
"""
from __future__ import annotations

import copy
import json
import pickle
import warnings
import zipfile
from pathlib import Path

import numpy as np

from . import envs as E
from . import agent_format as AF
from .config import algo_class, config_from_resolved, parse_config

PICKLE_WARNING = ("agent files ({what}) are Python pickles, which can execute arbitrary code when loaded: "
                  "load agents only from trusted sources")


class PickleWarning(UserWarning):
    """Loading an agent file unpickles it: trusted sources only."""


class LearnedController:
    """A trained stable-baselines3 policy behind the shared controller interface.

    Build one with :func:`load_agent`.  :meth:`act` takes the measurement dict
    the plant's closed loop passes to every controller and returns a current in
    mA (deterministic policy); bulk evaluation goes through the environment
    (``ehas_train.evaluate``).

    Attributes
    ----------
    kind : str
        ``"learned"`` (the benchmark's ``kind`` column).
    name : str
        Name of the agent (its folder's name).
    variant : str
        Algorithm and mode, e.g. ``SAC residual``.
    cfg : TrainConfig
        The configuration it was trained with.
    """

    kind = "learned"

    def __init__(self, model, cfg, controller_desc=None, obs_stats=None, name: str = "agent", path: str | None = None):
        self.model = model
        self.cfg = cfg
        self.controller_desc = controller_desc
        self.obs_stats = obs_stats
        self.name = name
        self.path = path
        self.disc_sets: int | None = None
        self._observer = None

    @classmethod
    def load(cls, path, warn: bool = True, allow_pickle: bool = False) -> "LearnedController":
        """See :func:`load_agent`."""
        return load_agent(path, warn=warn, allow_pickle=allow_pickle)

    def save(self, path) -> Path:
        """Write the agent folder (``config.json``, ``policy.json``, ``policy.safetensors``, ``obs_norm.json``)."""
        from ehas_env.output.files import atomic_write_text

        path = Path(path)
        path.mkdir(parents=True, exist_ok=True)
        AF.write_safe(path, self.model, self.obs_stats)
        resolved = {**self.cfg.to_dict(), "controller_resolved": self.controller_desc}
        atomic_write_text(path / "config.json", json.dumps(resolved, indent=2, default=str))
        return path

    @property
    def variant(self) -> str:
        return f"{self.cfg.algo.upper()}{' residual' if self.cfg.residual else ' direct'}"

    def __repr__(self) -> str:
        base = ""
        if self.cfg.residual:
            base = f" on {(self.controller_desc or {}).get('source', 'book')}"
        return (f"LearnedController '{self.name}' [{self.variant}{base}]: action held {self.cfg.action_repeat} ms, "
                f"+-{self.cfg.action_scale_mA:g} mA")

    # -- acting ------------------------------------------------------------
    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """Observation(s) as the policy saw them in training (running-statistics normalisation)."""
        obs = np.asarray(obs, dtype=np.float32)
        if self.obs_stats is None:
            return obs
        return self.obs_stats.normalize_obs(obs)

    def predict(self, obs: np.ndarray) -> np.ndarray:
        """Deterministic action(s), in [-1, 1], for raw environment observation(s) of shape (n, n_obs)."""
        action, _ = self.model.predict(self.normalize(obs), deterministic=True)
        return action

    def for_plant(self, disc_sets: int) -> "LearnedController":
        """The agent for a plant of ``disc_sets`` sets (a residual's scheduled base picks its entry)."""
        twin = copy.copy(self)
        twin.disc_sets = int(disc_sets)
        twin._observer = None
        return twin

    def reset(self) -> None:
        """Start a new run: clears the observation history used by :meth:`act`."""
        self._observer = MeasurementObserver(self)

    def act(self, measurement: dict) -> float:
        """Current in mA for one control period (the plant's closed-loop interface).

        Rebuilds the environment's observation from the measurement dict
        (:class:`MeasurementObserver`), holds each action for ``action_repeat``
        periods and, for a residual agent, adds it to its base controller.
        """
        if self._observer is None:
            self.reset()
        return self._observer.act(measurement)

    # -- evaluation ----------------------------------------------------------
    def rollout_stats(self, episodes: int, seed: int = 10_000, **env_overrides) -> dict:
        """Mean return and errors of ``episodes`` deterministic episodes in the training distribution."""
        env = E.make_env(self.cfg, controller_desc=self.controller_desc, **env_overrides)
        returns, rms, peak = [], [], []
        for ep in range(episodes):
            obs, _ = env.reset(seed=seed + ep)
            ret, done, info = 0.0, False, {}
            while not done:
                obs, r, term, trunc, info = env.step(self.predict(obs[None, :])[0])
                ret += float(r)
                done = term or trunc
            returns.append(ret)
            if "rms_error_pct" in info:
                rms.append(float(info["rms_error_pct"]))
                peak.append(float(info.get("peak_error_pct", np.nan)))
        env.close()
        out = {"episodes": episodes, "mean_return": float(np.mean(returns)), "std_return": float(np.std(returns))}
        if rms:
            out["mean_rms_error_pct"] = float(np.mean(rms))
            out["mean_peak_error_pct"] = float(np.nanmean(peak))
        return out


class MeasurementObserver:
    """The agent in the plant's closed loop: measurement -> observation -> action -> current.

    The observation and the current come from the environment's own
    :class:`ehas_env.env.tracking_env.MeasurementObserver` (the one definition of the
    observation), built for the agent's environment settings and, for a residual
    agent, its base controller on this plant (a schedule's entry for
    ``disc_sets``).  The amplitude that normalises the error is the
    measurement's ``amplitude_deg`` when the loop provides it
    (``Plant.simulate_closed_loop`` does), so that the warm-up cycle matches the
    environment too.  This class holds each action for ``action_repeat``
    periods and shapes it (``action_shape``), as the training did.
    """

    def __init__(self, agent: "LearnedController"):
        cfg = agent.cfg
        if not E.is_tracking_env(cfg.env_id):
            raise ValueError(f"act(): the agent was trained on {cfg.env_id}, not {E.EHAS_ID}")
        if cfg.residual and agent.disc_sets is None and _is_schedule(agent.controller_desc):
            raise ValueError("act(): the agent's base controller is a gain schedule; call agent.for_plant(disc_sets) "
                             "first (ehas bench does)")
        self.agent = agent
        self.repeat = cfg.action_repeat
        self.scale = cfg.action_scale_mA / E.RATED_CURRENT_MA
        self.inner = None
        self.k = 0
        self.a_held = 0.0

    def _build(self, m: dict):
        from ehas_env.env.tracking_env import MeasurementObserver as EnvObserver

        agent, cfg = self.agent, self.agent.cfg
        kw = {k: v for k, v in cfg.env_kwargs.items() if k not in ("randomise",)}
        if "amplitude_deg" in m:
            kw["amplitude_deg"] = float(m["amplitude_deg"])
        if agent.disc_sets is not None:
            kw["disc_sets"] = agent.disc_sets
        if cfg.residual:
            base = E.classical_controller(agent.controller_desc)
            if hasattr(base, "for_plant"):
                base = base.for_plant(agent.disc_sets if agent.disc_sets is not None else kw.get("disc_sets", 3))
            rig = base.rig_gains()
            kw["controller"] = rig if rig is not None else base
        E.register_ehas()
        import gymnasium as gym

        return EnvObserver(gym.make(cfg.env_id, **kw))

    def act(self, m: dict) -> float:
        if self.inner is None:
            self.inner = self._build(m)
        obs = self.inner.observation(m)
        if self.k % self.repeat == 0:
            a = float(np.clip(self.agent.predict(obs[None, :])[0][0], -1.0, 1.0))
            self.a_held = min(max(a * self.scale, -1.0), 1.0)
        self.k += 1
        a = self.a_held
        if self.agent.cfg.action_shape != "constant":
            sets = self.agent.disc_sets if self.agent.disc_sets is not None else self.agent.cfg.env_kwargs.get(
                "disc_sets", 3)
            a *= float(E.authority(self.agent.cfg.action_shape, m, sets))
        return float(self.inner.current(a, m))


def _is_schedule(desc) -> bool:
    return bool(desc and isinstance(desc.get("data"), dict) and "entries" in desc["data"])


def load_agent(path, warn: bool = True, allow_pickle: bool = False) -> LearnedController:
    """Load an agent folder: its weights and statistics are data (nothing is unpickled).

    Parameters
    ----------
    path : path
        Agent folder (``config.json``, ``policy.json``, ``policy.safetensors`` and, when trained with
        ``vecnormalize = true``, ``obs_norm.json``; docs/agents.md).  With ``allow_pickle`` also an
        older folder (``model.zip``, ``vecnormalize.pkl``) or a bare stable-baselines3 ``.zip``.
    warn : bool
        With ``allow_pickle``: emit the :class:`PickleWarning` for files not on the trust list.
    allow_pickle : bool
        Load a legacy pickled agent (``--allow-pickle``): unpickling runs whatever code the file
        holds, so only for agents you trained yourself or trust as you trust a program.

    Returns
    -------
    LearnedController
        The agent as a controller.

    Raises
    ------
    ValueError
        A folder without ``config.json`` or its weights, a legacy pickled agent without
        ``allow_pickle``, a damaged file (named, in one line).
    """
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    safe = path.is_dir() and (folder / AF.POLICY_JSON).exists()
    if not safe:
        legacy = (path / "model.zip") if path.is_dir() else path
        if path.is_dir() and not legacy.is_file():
            raise FileNotFoundError(f"no agent at {path}: expected a folder holding config.json, policy.json and "
                                    "policy.safetensors (docs/agents.md)")
        if not path.exists():
            raise FileNotFoundError(f"no agent at {path}: expected an agent folder (config.json, policy.json, "
                                    "policy.safetensors)")
        if not allow_pickle:
            raise ValueError(f"agent {path}: a pickled stable-baselines3 agent ({legacy.name}"
                             f"{', vecnormalize.pkl' if (folder / 'vecnormalize.pkl').exists() else ''}); "
                             "unpickling can run any code, so ehas does not load it; convert it once with "
                             f"`python -m ehas_train.agent_convert {path}` if you trust it, or pass "
                             "--allow-pickle (allow_pickle=True)")
        return _load_pickled(path, warn)
    cfg_path = folder / "config.json"
    if not cfg_path.exists():
        raise ValueError(f"agent folder {folder}: config.json is missing; an agent folder written by ehas train "
                         "holds config.json (its training configuration), policy.json, policy.safetensors and, "
                         "when trained with vecnormalize = true, obs_norm.json")
    saved = read_agent_config(cfg_path)
    controller_desc = saved.pop("controller_resolved", None)
    cfg = config_from_resolved(saved, source=str(cfg_path))
    norm_path = folder / AF.NORM_JSON
    if cfg.vecnormalize and not norm_path.is_file():
        raise ValueError(f"agent folder {folder}: obs_norm.json is missing; config.json says the agent was "
                         "trained with vecnormalize = true, so its policy needs those observation statistics")
    policy = AF.read_safe(folder, cfg.algo)
    obs_stats = AF.read_norm(norm_path) if norm_path.is_file() else None
    return LearnedController(policy, cfg, controller_desc, obs_stats, name=folder.name, path=str(path))


def _load_pickled(path: Path, warn: bool) -> LearnedController:
    """A legacy agent (``model.zip``, ``vecnormalize.pkl``): unpickles, behind ``allow_pickle`` only."""
    if path.is_dir():
        folder, model_path = path, path / "model.zip"
    else:
        folder, model_path = path.parent, path
    cfg_path = folder / "config.json"
    norm_path = folder / "vecnormalize.pkl"
    in_folder = path.is_dir()
    if in_folder:
        if not cfg_path.exists():
            raise ValueError(f"agent folder {folder}: config.json is missing; an agent folder written by ehas train "
                             "holds model.zip, config.json (its training configuration) and, when trained with "
                             "vecnormalize = true, vecnormalize.pkl (a bare model zip loads as FOLDER/model.zip)")
        saved = read_agent_config(cfg_path)
        controller_desc = saved.pop("controller_resolved", None)
        cfg = config_from_resolved(saved, source=str(cfg_path))
        if cfg.vecnormalize and not norm_path.is_file():
            raise ValueError(f"agent folder {folder}: vecnormalize.pkl is missing; config.json says the agent was "
                             "trained with vecnormalize = true, so its policy needs those observation statistics")
    else:
        controller_desc = None
        cfg = parse_config({"train": {"algo": _algo_of_zip(model_path)}}, source=str(model_path))
    # the folder is whole (checked above, from its JSON): only now unpickle, after the warning
    pickles = [p for p in (model_path, norm_path) if p.exists() and (in_folder or p == model_path)]
    if warn and not _trusted(pickles):
        what = ", ".join(p.name for p in pickles)
        warnings.warn(PICKLE_WARNING.format(what=what), PickleWarning, stacklevel=3)
    try:
        model = algo_class(cfg.algo).load(model_path, device="cpu")
    except (OSError, EOFError, KeyError, ValueError, RuntimeError, pickle.UnpicklingError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{model_path}: not a {cfg.algo.upper()} model saved by stable-baselines3 "
                         f"({' '.join(str(exc).split()) or type(exc).__name__})") from None
    obs_stats = None
    if in_folder and norm_path.exists():
        try:
            with norm_path.open("rb") as fh:
                obs_stats = pickle.load(fh)
        except Exception as exc:  # noqa: BLE001 - unpickling other bytes fails in any way: the file is not the stats
            raise ValueError(f"{norm_path}: not the observation statistics of a training (VecNormalize): "
                             f"{' '.join(str(exc).split()) or type(exc).__name__}") from None
        if not hasattr(obs_stats, "normalize_obs"):
            raise ValueError(f"{norm_path}: holds a {type(obs_stats).__name__}, not the observation statistics "
                             "of a training (VecNormalize)")
        obs_stats.training = False
        obs_stats.norm_reward = False
    return LearnedController(model, cfg, controller_desc, obs_stats, name=folder.name if in_folder else path.stem,
                             path=str(path))


AGENT_CONFIG_FORMAT = "ehas-agent-config"  # config.json of an agent folder (the resolved training configuration)
AGENT_CONFIG_VERSION = 1


def read_agent_config(path: Path) -> dict:
    """An agent folder's ``config.json``: JSON, an object, the resolved configuration of ``ehas train``.

    Its ``format`` and ``version`` keys (agents trained before they were written lack them) are checked.
    """
    from ehas_env.output.files import read_json

    saved = read_json(path, f"an agent folder's config.json (\"format\": \"{AGENT_CONFIG_FORMAT}\", written by "
                            "ehas train)")
    if not isinstance(saved, dict):
        raise ValueError(f"{path}: expected a JSON object (the resolved training configuration written by "
                         f"ehas train), got {type(saved).__name__}")
    fmt = saved.pop("format", AGENT_CONFIG_FORMAT)
    if fmt != AGENT_CONFIG_FORMAT:
        raise ValueError(f"{path}: format = {fmt!r}; expected {AGENT_CONFIG_FORMAT!r} (an agent folder's config.json)")
    version = saved.pop("version", AGENT_CONFIG_VERSION)
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= AGENT_CONFIG_VERSION:
        raise ValueError(f"{path}: version = {version!r}; this ehas reads versions 1 to {AGENT_CONFIG_VERSION}")
    if not isinstance(saved.get("algo"), str):
        raise ValueError(f"{path}: no 'algo' key; expected the resolved training configuration written by ehas train")
    return saved


TRUST_ENV = "EHAS_TRUSTED_AGENTS"


def _trust_file() -> Path:
    import os

    return Path(os.environ.get(TRUST_ENV) or Path.home() / ".cache" / "ehas" / "trusted_agents.json")


def _sha256(path: Path) -> str:
    import hashlib

    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _trusted(files) -> bool:
    try:
        known = json.loads(_trust_file().read_text())
        return bool(files) and all(_sha256(f) in known for f in files)
    except (OSError, ValueError, AttributeError, TypeError):
        return False


def trust_agent(path) -> None:
    """Record the SHA-256 of an agent's pickle files (trained or saved here): loading them will not warn."""
    from ehas_env.output.files import atomic_write_text

    path = Path(path)
    files = [path / "model.zip", path / "vecnormalize.pkl"] if path.is_dir() else [path]
    try:
        tf = _trust_file()
        known = json.loads(tf.read_text()) if tf.exists() else {}
        if not isinstance(known, dict):
            known = {}
        known.update({_sha256(f): str(f.resolve()) for f in files if f.is_file()})
        tf.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(tf, json.dumps(known, indent=1) + "\n")
    except OSError:  # an unwritable home: the warning stays, nothing else changes
        pass


def _algo_of_zip(path: Path) -> str:
    """Algorithm of a bare stable-baselines3 zip (from its stored policy class)."""
    try:
        with zipfile.ZipFile(path) as z:
            data = z.read("data").decode("utf-8", errors="replace")
    except (zipfile.BadZipFile, KeyError, OSError) as exc:
        raise ValueError(f"{path}: not a model saved by stable-baselines3 (a zip holding 'data'): "
                         f"{' '.join(str(exc).split()) or type(exc).__name__}") from None
    for algo, marker in (("sac", "stable_baselines3.sac"), ("td3", "stable_baselines3.td3"),
                         ("ppo", "ActorCriticPolicy")):
        if marker in data:
            return algo
    raise ValueError(f"{path}: cannot tell which algorithm saved this zip; load its agent folder instead")


def _register() -> None:
    """Let ``ehas_controllers.base.load_controller`` (``ehas bench``) load agent folders and zips."""
    try:
        from ehas_controllers import base
    except ImportError:  # pragma: no cover - the controllers package is part of the project
        return
    def load(path):
        return load_agent(path, allow_pickle=base.LOAD_OPTIONS.get("allow_pickle", False))

    base.register_loader(".zip", load)
    base.register_loader("/", load)


_register()
