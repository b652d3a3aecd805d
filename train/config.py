"""Training configurations: TOML files read with :mod:`tomllib` and validated.

A configuration says *what* is trained (algorithm, direct or residual control,
environment and its domain randomisation) and *how* (batched environments,
seeds, steps, checkpoints, observation normalisation, the algorithm's
hyper-parameters).  Every key is checked: an unknown or ill-typed key is an
error that names the file, the section and the key.

File layout (every section but ``[train]`` optional)::

    format = "ehas-train-config"  # what the file is; optional, checked when given
    version = 1                   # of this layout; optional, checked when given

    [train]
    algo = "sac"                # ppo | sac | td3
    total_steps = 200_000       # environment steps over all batched envs
    n_envs = 8                  # batched environments
    seed = 0
    checkpoint_every = 20_000   # environment steps between checkpoints
    vecnormalize = true         # running mean/std normalisation of observations
    norm_reward = false
    eval_episodes = 7           # deterministic episodes for metrics.json

    [algo]                      # keyword arguments of the stable-baselines3 class
    learning_rate = 3e-4
    [algo.policy_kwargs]
    net_arch = [64, 64]
    activation_fn = "tanh"      # relu | tanh | elu | leaky_relu

    [env]
    id = "ehas/Tracking-v0"     # any registered gymnasium id (Pendulum-v1 works)
    residual = false            # residual RL on top of a classical controller
    controller = "tuned"        # the residual's base: tuned | book | path/to/controller.json
    [env.kwargs]                # keyword arguments of the environment
    cycles = 3

    [randomise]                 # domain randomisation, drawn at every reset
    disc_sets = [1, 2, 3, 4, 5, 6, 7]
    amplitude_deg = [10.0, 30.0]    # [low, high] (uniform) or a list of >= 3 values
    freq_hz = [1.0, 3.0]
    [randomise.effects]         # optional: effect -> {param = [low, high]}
    coulomb_friction = { Fc = [0.0, 300.0] }

Examples
--------
>>> cfg = load_config(bundled_config("ppo_smoke"))
>>> cfg.algo, cfg.n_envs > 0
('ppo', True)
>>> parse_config({"train": {"algo": "dqn"}}, source="x.toml")
Traceback (most recent call last):
...
ValueError: x.toml: [train] algo must be one of 'ppo', 'sac', 'td3', got 'dqn'
"""
from __future__ import annotations

import copy
import inspect
import math
import re
import tomllib
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path

from ehas_env.ranges import ENV_KWARGS, check_field

ALGOS = ("ppo", "sac", "td3")
VALIDATE_METRICS = ("mean", "no_worse", "fewest_worse")
CONFIG_FORMAT = "ehas-train-config"  # the optional top-level format key of a training configuration
CONFIG_VERSION = 1
ACTIVATIONS = ("relu", "tanh", "elu", "leaky_relu")
ACTION_SHAPES = ("constant", "velocity", "power", "reference", "reference_sq", "reference_sq_load")
RESIDUAL_BASES = ("tuned", "book")
# randomised quantities and the bounds each value must respect
RANDOMISE_KEYS = {
    "disc_sets": (1, 7),  # sets of discs (book: 1..7)
    "amplitude_deg": (1e-6, 44.43),  # deg, inside the stroke ends
    "freq_hz": (1e-6, 50.0),  # Hz (assumed bound: far beyond the valve's band)
    "cycles": (1e-6, 1e6),  # reference periods per episode
    "theta0_deg": (-40.0, 40.0),  # initial crank angle, deg
}

_TRAIN_DEFAULTS = {
    "algo": None,
    "total_steps": 100_000,
    "n_envs": 4,
    "seed": 0,
    "checkpoint_every": 10_000,
    "vecnormalize": True,
    "norm_reward": False,
    "clip_obs": 10.0,
    "eval_episodes": 5,
    "torch_threads": 1,
    "vec_env": "batched",
    "log_interval_s": 30.0,
    "validate_every": 0,
    "validate_conditions": 16,
    "validate_grid": False,
    "validate_metric": "mean",
}


@dataclass
class TrainConfig:
    """A validated training configuration (see the module docstring for the file format).

    Attributes
    ----------
    algo : str
        ``ppo``, ``sac`` or ``td3``.
    total_steps : int
        Environment steps to train, summed over the batched environments.
    n_envs : int
        Environments stepped as one batch.
    seed : int
        Seed of the algorithm, the environments and the randomisation.
    checkpoint_every : int
        Environment steps between checkpoints (model, normalisation statistics,
        replay buffer for off-policy algorithms, step count).
    vecnormalize : bool
        Normalise observations with running statistics (``VecNormalize``).
    norm_reward : bool
        Also normalise rewards (``VecNormalize``).
    clip_obs : float
        Clip of the normalised observations.
    eval_episodes : int
        Deterministic episodes evaluated at the end for ``metrics.json``.
    torch_threads : int
        ``torch.set_num_threads``: the machine has 2 cores; 1 keeps the second free
        for the environments.
    vec_env : str
        ``batched`` (default: the native batched environment behind an SB3 ``VecEnv``,
        all environments stepped in one compiled call, :mod:`ehas_train.batched`;
        other environment ids fall back to ``dummy``), ``dummy`` (SB3's
        ``DummyVecEnv`` of Python environments, for comparison) or ``subproc``.
    log_interval_s : float
        Seconds between progress lines in the log.
    validate_every : int
        Agent steps between validations (0: none): the deterministic policy runs
        ``validate_conditions`` conditions drawn once (seeded) from the
        ``[randomise]`` ranges - not the benchmark's grid - and the model with the
        lowest mean rms % error is kept as the result (off-policy training is
        not monotonic; this is early stopping on held-out conditions).
    validate_conditions : int
        Size of that validation set.
    validate_grid : bool
        Add the benchmark's 63 grid conditions to the validation set, all run
        over as many reference periods as the benchmark (5): model selection then
        targets the benchmark itself, and the random conditions and the
        robustness table (``python -m ehas_train.versus``) are what it was not
        selected on.
    validate_metric : str
        What the kept model minimises: ``mean`` (the mean rms % error),
        ``no_worse`` (that mean plus 10 x the mean excess over the classical
        reference on the same conditions beyond 0.05 points: a model that loses
        somewhere to the classical controller is kept only if it gains far more
        elsewhere) or ``fewest_worse`` (first the number of conditions where it
        is worse than the classical reference by more than 0.05 points, then the
        mean: score = 100 x that count + mean).
    hyper : dict
        Keyword arguments of the stable-baselines3 algorithm class.
    env_id : str
        Registered gymnasium id.
    residual : bool
        Residual control: the action is added to a classical controller's current.
    controller : str
        Base controller of residual control: ``tuned``, ``book`` or a JSON path.
    action_repeat : int
        Control periods (1 ms) each action is held for: the policy decides at
        1 kHz / action_repeat while the plant (and the residual's base
        controller) still runs at 1 kHz.
    action_penalty : float
        Reward charged per agent step times the squared action (agent units).
    action_shape : str
        Authority of a full action over time (``ehas_train.envs.authority``):
        ``constant`` (``action_scale_mA`` always), ``velocity`` (scaled by the
        reference rate), ``power`` (by the reference rate and the load
        pressure), ``reference`` (by the reference's velocity x acceleration
        amplitudes, a function of the task alone) or ``reference_sq`` (its
        square): a residual that fades where
        the classical loop is already good, so that the policy's imprecision
        cannot disturb it there.
    reward : str
        ``env`` (the environment's ``-(e/A)^2`` per period) or ``abs``
        (``-|e|/A``, closer to the benchmark's mean of rms errors; see
        ``ehas_train.envs.AgentInterface``).
    action_scale_mA : float
        Current of a full action (+-1), mA: 20 mA for direct control; a residual
        needs only a few mA and explores more gently with less.
    reward_scale : float
        Factor on the environment's reward (its -(e/A)^2 is ~1e-4 per step at
        1 % error: too small for the entropy/critic scales of SAC and TD3).
    env_kwargs : dict
        Keyword arguments of the environment.
    randomise : dict
        Domain randomisation (``disc_sets``, ``amplitude_deg``, ``freq_hz``, ``effects``).
    source : str
        Where the configuration came from.
    """

    algo: str
    total_steps: int = 100_000
    n_envs: int = 4
    seed: int = 0
    checkpoint_every: int = 10_000
    vecnormalize: bool = True
    norm_reward: bool = False
    clip_obs: float = 10.0
    eval_episodes: int = 5
    torch_threads: int = 1
    vec_env: str = "batched"
    log_interval_s: float = 30.0
    validate_every: int = 0
    validate_conditions: int = 16
    validate_grid: bool = False
    validate_metric: str = "mean"
    hyper: dict = field(default_factory=dict)
    env_id: str = "ehas/Tracking-v0"
    residual: bool = False
    controller: str = "tuned"
    action_repeat: int = 1
    action_scale_mA: float = 20.0
    reward_scale: float = 1.0
    action_penalty: float = 0.0
    action_shape: str = "constant"
    reward: str = "env"
    env_kwargs: dict = field(default_factory=dict)
    randomise: dict = field(default_factory=dict)
    source: str = "<dict>"

    def to_dict(self) -> dict:
        """Plain, JSON-serialisable form (the resolved config written beside the model)."""
        return copy.deepcopy(asdict(self))

    def to_file_dict(self) -> dict:
        """The same structure as the TOML file, for :func:`parse_config`."""
        d = self.to_dict()
        train = {k: d[k] for k in _TRAIN_DEFAULTS}
        env = {"id": d["env_id"], "residual": d["residual"], "controller": d["controller"],
               "action_repeat": d["action_repeat"], "action_scale_mA": d["action_scale_mA"],
               "reward_scale": d["reward_scale"], "action_penalty": d["action_penalty"],
               "action_shape": d["action_shape"], "reward": d["reward"], "kwargs": d["env_kwargs"]}
        return {"train": train, "algo": d["hyper"], "env": env, "randomise": d["randomise"]}

    def replace(self, **changes) -> "TrainConfig":
        """A re-validated copy with ``changes`` applied to [train] keys."""
        raw = self.to_file_dict()
        for k, v in changes.items():
            if k not in _TRAIN_DEFAULTS:
                raise ValueError(f"replace: unknown [train] key {k!r}")
            raw["train"][k] = v
        return parse_config(raw, source=self.source)


def config_from_resolved(d: dict, source: str = "<resolved>") -> TrainConfig:
    """Rebuild a :class:`TrainConfig` from its :meth:`TrainConfig.to_dict` form (an agent's config.json)."""
    fields_ = {k: v for k, v in d.items() if k in TrainConfig.__dataclass_fields__ and k != "source"}
    try:
        raw = TrainConfig(**fields_).to_file_dict()
    except (TypeError, AttributeError) as exc:
        raise ValueError(f"{source}: not a resolved training configuration ({' '.join(str(exc).split())})") from None
    return parse_config(raw, source=source)


def bundled_config(name: str) -> Path:
    """Path of a configuration shipped in ``ehas_train/configs`` (``ppo``, ``sac_smoke`` ...).

    Examples
    --------
    >>> bundled_config("sac").name
    'sac.toml'
    """
    base = resources.files("ehas_train") / "configs"
    path = Path(str(base / f"{name}.toml"))
    if not path.exists():
        names = sorted(p.stem for p in Path(str(base)).glob("*.toml"))
        raise FileNotFoundError(f"no bundled config {name!r}; bundled: {', '.join(names)}")
    return path


#: what a training config is, for the errors of the file reader (ehas_env.output.files)
CONFIG_FILE = "a training config (a TOML file, e.g. train/configs/ppo.toml)"


def read_toml(path) -> dict:
    """The parsed TOML file ``path``; one-line errors naming it (missing, a folder, not UTF-8 text, not TOML)."""
    from ehas_env.output.files import read_text

    path = Path(path)
    text = read_text(path, CONFIG_FILE)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML: {exc}") from None


def load_config(path) -> TrainConfig:
    """Read and validate a TOML configuration file."""
    return parse_config(read_toml(path), source=str(path))


def _check_kind(raw: dict, source: str) -> None:
    """The optional ``format`` and ``version`` keys: another kind of file, or a newer layout, is refused."""
    if "format" in raw and raw["format"] != CONFIG_FORMAT:
        raise ValueError(f"{source}: format = {raw['format']!r}: not a training configuration "
                         f"(expected format = {CONFIG_FORMAT!r})")
    if "version" in raw:
        v = raw["version"]
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{source}: version must be a whole number from 1 to {CONFIG_VERSION}, got {v!r}")
        if v > CONFIG_VERSION:
            raise ValueError(f"{source}: version = {v} is a newer layout than this ehas reads (up to "
                             f"{CONFIG_VERSION}); upgrade ehas")


def parse_config(raw: dict, source: str = "<dict>") -> TrainConfig:
    """Validate the parsed TOML ``raw`` and build a :class:`TrainConfig`."""
    if not isinstance(raw, dict):
        raise ValueError(f"{source}: expected a table of sections, got {type(raw).__name__}")
    _no_unknown(raw, ("format", "version", "train", "algo", "env", "randomise"), source, "top level")
    _check_kind(raw, source)
    train = _table(raw, "train", source, required=True)
    _no_unknown(train, tuple(_TRAIN_DEFAULTS), source, "[train]")
    t = {**_TRAIN_DEFAULTS, **train}
    where = f"{source}: [train]"
    if t["algo"] not in ALGOS:
        raise ValueError(f"{where} algo must be one of {', '.join(repr(a) for a in ALGOS)}, got {t['algo']!r}")
    for key in ("total_steps", "n_envs", "checkpoint_every", "eval_episodes", "torch_threads", "validate_every",
                "validate_conditions", "seed"):
        t[key] = check_field(key, t[key], f"{where} {key}")
    for key in ("vecnormalize", "norm_reward", "validate_grid"):
        if not isinstance(t[key], bool):
            raise ValueError(f"{where} {key} must be true or false, got {t[key]!r}")
    for key in ("clip_obs", "log_interval_s"):
        t[key] = check_field(key, t[key], f"{where} {key}")
    if t["validate_metric"] not in VALIDATE_METRICS:
        raise ValueError(f"{where} validate_metric must be one of {', '.join(repr(m) for m in VALIDATE_METRICS)}, "
                         f"got {t['validate_metric']!r}")
    if t["vec_env"] not in ("batched", "dummy", "subproc"):
        raise ValueError(f"{where} vec_env must be 'batched', 'dummy' or 'subproc', got {t['vec_env']!r}")

    hyper = copy.deepcopy(_table(raw, "algo", source))
    _check_hyper(t["algo"], hyper, source, t["n_envs"])

    env = _table(raw, "env", source)
    _no_unknown(env, ("id", "residual", "controller", "action_repeat", "action_scale_mA", "reward_scale",
                      "action_penalty", "action_shape", "reward", "kwargs"),
                source, "[env]")
    env_id = env.get("id", "ehas/Tracking-v0")
    if not isinstance(env_id, str) or not env_id:
        raise ValueError(f"{source}: [env] id must be a gymnasium id string, got {env_id!r}")
    if ":" in env_id:  # gymnasium imports the module before the ':' - a config is data and never imports code
        raise ValueError(f"{source}: [env] id = {env_id!r} names a module to import ('module:Env'); a training "
                         "config never imports code: register the environment in your own script and give its "
                         "plain id (e.g. ehas/Tracking-v0)")
    residual = env.get("residual", False)
    if not isinstance(residual, bool):
        raise ValueError(f"{source}: [env] residual must be true or false, got {residual!r}")
    controller = env.get("controller", "tuned")
    if not isinstance(controller, str) or not controller:
        raise ValueError(f"{source}: [env] controller must be 'tuned', 'book' or a path to a controller JSON, "
                         f"got {controller!r}")
    action_repeat = check_field("action_repeat", env.get("action_repeat", 1), f"{source}: [env] action_repeat")
    action_scale = check_field("action_scale_mA", env.get("action_scale_mA", 20.0), f"{source}: [env] action_scale_mA")
    reward_scale = check_field("reward_scale", env.get("reward_scale", 1.0), f"{source}: [env] reward_scale")
    action_penalty = check_field("action_penalty", env.get("action_penalty", 0.0), f"{source}: [env] action_penalty")
    action_shape = env.get("action_shape", "constant")
    if action_shape not in ACTION_SHAPES:
        raise ValueError(f"{source}: [env] action_shape must be one of {', '.join(repr(a) for a in ACTION_SHAPES)}, "
                         f"got {action_shape!r}")
    reward = env.get("reward", "env")
    if reward not in ("env", "abs"):
        raise ValueError(f"{source}: [env] reward must be 'env' or 'abs', got {reward!r}")
    env_kwargs = copy.deepcopy(_table(env, "kwargs", f"{source}: [env]"))
    if "controller" in env_kwargs:
        raise ValueError(f"{source}: [env.kwargs] controller: set the residual's base with [env] controller instead")
    for key, value in env_kwargs.items():  # the environment's numbers: the same ranges as everywhere
        if key in ENV_KWARGS:
            env_kwargs[key] = check_field(ENV_KWARGS[key], value, f"{source}: [env.kwargs] {key}")

    randomise = copy.deepcopy(_table(raw, "randomise", source))
    _check_randomise(randomise, source)
    return TrainConfig(
        algo=t["algo"], total_steps=t["total_steps"], n_envs=t["n_envs"], seed=t["seed"],
        checkpoint_every=t["checkpoint_every"], vecnormalize=t["vecnormalize"], norm_reward=t["norm_reward"],
        clip_obs=float(t["clip_obs"]), eval_episodes=t["eval_episodes"], torch_threads=t["torch_threads"],
        vec_env=t["vec_env"], log_interval_s=float(t["log_interval_s"]), validate_every=t["validate_every"],
        validate_conditions=t["validate_conditions"], validate_grid=t["validate_grid"],
        validate_metric=t["validate_metric"], hyper=hyper, env_id=env_id,
        residual=residual, controller=controller, action_repeat=action_repeat, action_scale_mA=action_scale,
        reward_scale=reward_scale, action_penalty=float(action_penalty), action_shape=action_shape,
        reward=reward, env_kwargs=env_kwargs, randomise=randomise, source=source,
    )


# -- checks -----------------------------------------------------------------
def _table(raw: dict, key: str, source: str, required: bool = False) -> dict:
    if key not in raw:
        if required:
            raise ValueError(f"{source}: missing section [{key}]")
        return {}
    value = raw[key]
    if not isinstance(value, dict):
        raise ValueError(f"{source}: [{key}] must be a table, got {type(value).__name__}")
    return value


def _no_unknown(table: dict, allowed, source: str, where: str) -> None:
    for key in table:
        if key not in allowed:
            raise ValueError(f"{source}: {where} unknown key {key!r}; allowed: {', '.join(allowed)}")


def _int(value, where: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"{where} must be an integer >= {minimum}, got {value!r}")
    return value


def _positive(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{where} must be a positive number, got {value!r}")
    return float(value)


def algo_class(algo: str):
    """The stable-baselines3 class of ``algo``."""
    import stable_baselines3 as sb3

    return {"ppo": sb3.PPO, "sac": sb3.SAC, "td3": sb3.TD3}[algo]


# constructor arguments the trainer sets itself
_RESERVED = ("policy", "env", "seed", "tensorboard_log", "verbose", "device", "_init_setup_model", "action_noise")


#: the [algo] numbers with a shared range (ehas_env.ranges.FIELDS); the one text value SB3 takes among them is
#: SAC's automatic entropy coefficient, ent_coef = "auto" (or "auto_0.1": its start value)
_ALGO_FIELDS = ("learning_rate", "gamma", "tau", "gae_lambda", "n_steps", "batch_size", "n_epochs", "clip_range",
                "clip_range_vf", "ent_coef", "vf_coef", "max_grad_norm", "target_kl", "buffer_size",
                "learning_starts", "gradient_steps", "policy_delay", "target_policy_noise", "target_noise_clip",
                "stats_window_size")


def _check_hyper(algo: str, hyper: dict, source: str, n_envs: int) -> None:
    cls = algo_class(algo)
    params = inspect.signature(cls.__init__).parameters
    allowed = [p for p in params if p not in ("self",) + _RESERVED] + ["action_noise_std"]
    for key, value in hyper.items():
        if key in _RESERVED:
            raise ValueError(f"{source}: [algo] {key} is set by the trainer, remove it")
        if key not in allowed:
            raise ValueError(f"{source}: [algo] unknown hyper-parameter {key!r} for {cls.__name__}; "
                             f"allowed: {', '.join(sorted(allowed))}")
    if "action_noise_std" in hyper:
        if algo == "ppo":
            raise ValueError(f"{source}: [algo] action_noise_std applies to sac/td3, not ppo")
        check_field("action_noise_std", hyper["action_noise_std"], f"{source}: [algo] action_noise_std")
    pk = hyper.get("policy_kwargs", {})
    if not isinstance(pk, dict):
        raise ValueError(f"{source}: [algo.policy_kwargs] must be a table, got {pk!r}")
    if "activation_fn" in pk and pk["activation_fn"] not in ACTIVATIONS:
        raise ValueError(f"{source}: [algo.policy_kwargs] activation_fn must be one of {', '.join(ACTIVATIONS)}, "
                         f"got {pk['activation_fn']!r}")
    if "net_arch" in pk:
        pk["net_arch"] = _check_net_arch(pk["net_arch"], f"{source}: [algo.policy_kwargs] net_arch",
                                         ("pi", "vf") if algo == "ppo" else ("pi", "qf"))
    for key in _ALGO_FIELDS:
        value = hyper.get(key)
        if key == "ent_coef" and isinstance(value, str) and algo != "ppo":
            if not re.fullmatch(r"auto(_[0-9.eE+-]+)?", value):
                raise ValueError(f"{source}: [algo] ent_coef must be a number in [0, 100], 'auto' or 'auto_START', "
                                 f"got {value!r}")
        elif key in hyper:
            hyper[key] = check_field(key, value, f"{source}: [algo] {key}")
    for key, value in hyper.items():  # every other number: finite (TOML allows inf and nan)
        if isinstance(value, float) and not math.isfinite(value):
            raise ValueError(f"{source}: [algo] {key} must be a finite number, got {value!r}")
    if algo == "ppo":  # a mini-batch larger than the rollout buffer: SB3 would train on nothing
        n_steps, batch = (hyper.get(k, params[k].default) for k in ("n_steps", "batch_size"))
        if batch > n_steps * n_envs:
            raise ValueError(f"{source}: [algo] batch_size {batch} is larger than the rollout (n_steps {n_steps} x "
                             f"n_envs {n_envs} = {n_steps * n_envs} samples); give batch_size <= n_steps x n_envs")


#: hidden layers of a policy or value network ([algo.policy_kwargs] net_arch): at most this many layers of
#: 1 to NET_ARCH_MAX_WIDTH units (a controller's networks have tens to hundreds; a layer of 10^9 units is an
#: allocation of tens of GB, not a network)
NET_ARCH_MAX_LAYERS = 8
NET_ARCH_MAX_WIDTH = 4096


def _check_net_arch(na, where: str, networks=("pi", "vf")):
    """``net_arch``: a list of layer widths, or a table of such lists per network (``networks``), in range."""
    from ehas_env.ranges import check_number

    allowed = (f"a list of at most {NET_ARCH_MAX_LAYERS} layer widths, integers in [1, {NET_ARCH_MAX_WIDTH}] "
               f"(or a table of such lists: {', '.join(networks)})")

    def layers(values, at: str) -> list:
        if not isinstance(values, list) or len(values) > NET_ARCH_MAX_LAYERS:
            raise ValueError(f"{at} must be {allowed}, got {values!r}")
        return [check_number(v, f"{at} layer {k + 1}", "units", 1, NET_ARCH_MAX_WIDTH, integer=True)
                for k, v in enumerate(values)]

    if isinstance(na, dict):
        if not na:
            raise ValueError(f"{where} must be {allowed}, got an empty table")
        for key in na:
            if key not in networks:
                raise ValueError(f"{where}: unknown network {key!r}; allowed: {', '.join(networks)}")
        return {key: layers(v, f"{where}.{key}") for key, v in na.items()}
    return layers(na, where)


def _check_randomise(rnd: dict, source: str) -> None:
    _no_unknown(rnd, tuple(RANDOMISE_KEYS) + ("effects",), source, "[randomise]")
    for key, (lo, hi) in RANDOMISE_KEYS.items():
        if key not in rnd:
            continue
        values = rnd[key]
        where = f"{source}: [randomise] {key}"
        if not (isinstance(values, list) and len(values) == 2):
            raise ValueError(f"{where} must be a [low, high] range (drawn uniformly at each reset), got {values!r}")
        for v in values:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
                raise ValueError(f"{where} values must be numbers in [{lo:g}, {hi:g}], got {v!r}")
        if key == "disc_sets" and not all(isinstance(v, int) for v in values):
            raise ValueError(f"{where} must be integers [low, high] (inclusive), got {values!r}")
        if values[0] > values[1]:
            raise ValueError(f"{where} range [low, high] has low > high: {values!r}")
    effects = rnd.get("effects", {})
    if not isinstance(effects, dict):
        raise ValueError(f"{source}: [randomise.effects] must be a table effect -> \"typical\" or {{param = [low, high]}}")
    if effects:
        from ehas_env.physics.effects import REGISTRY

        for name, params in effects.items():
            where = f"{source}: [randomise.effects] {name}"
            if name not in REGISTRY:
                raise ValueError(f"{where}: unknown effect; known: {', '.join(sorted(REGISTRY))}")
            if params == "typical":
                continue
            if not isinstance(params, dict):
                raise ValueError(f"{where} must be \"typical\" or a table param -> [low, high]")
            for pname, rng in params.items():
                try:
                    par = REGISTRY[name].param(pname)
                except (KeyError, ValueError):
                    raise ValueError(f"{where}: unknown parameter {pname!r}; known: "
                                     f"{', '.join(p.name for p in REGISTRY[name].params)}") from None
                values = rng if isinstance(rng, list) else [rng]
                if isinstance(rng, list) and not (len(rng) == 2 and rng[0] <= rng[1]):
                    raise ValueError(f"{where}.{pname} must be a [low, high] range in {par.unit} or one value, got {rng!r}")
                for v in values:
                    par.check(name, v)
        st = effects.get("stribeck_friction")
        if st is not None:
            from ehas_env.physics.effects import get_effect

            cls = get_effect("stribeck_friction")

            def span(p):
                if isinstance(st, dict) and p in st:
                    v = st[p]
                    return (v[0], v[1]) if isinstance(v, list) else (v, v)
                par = cls.param(p)
                return par.typical if st == "typical" and par.typical else (par.default, par.default)

            if span("Fs")[0] < span("Fc")[1]:
                raise ValueError(f"{source}: [randomise.effects] stribeck_friction: every draw must keep the breakaway "
                                 f"force at or above the sliding force; the Fs range {list(span('Fs'))} N starts below "
                                 f"the top of the Fc range {list(span('Fc'))} N")
