"""Train a stable-baselines3 agent from a configuration, with checkpoints and resume.

Output folder (``out``)::

    policy.safetensors    the trained policy's weights, policy.json its architecture (data only, docs/agents.md)
    obs_norm.json         observation-normalisation statistics (when vecnormalize = true)
    model.zip             the training state for --resume (stable-baselines3 zip: a pickle, never loaded as agent)
    vecnormalize.pkl      the normalisation's state for --resume (a pickle, likewise)
    config.json           the resolved configuration (incl. the residual's base controller)
    metrics.json          steps, training time, returns, final deterministic evaluation
    learning_curve.csv    one row per finished training episode
    learning_curve.png    return and rms % error against environment steps
    tb/                   TensorBoard logs (``tensorboard --logdir out/tb``): SB3's scalars and, under
                          ``ehas/``, the training episodes' rms % error, saturation share (periods at
                          +-20 mA), stroke-end share and running count, and at each validation the mean
                          rms % error on the held-out conditions beside the classical reference's
                          (``validation_base_rms_error_pct``: the residual's base, or the tuned
                          controller for a direct agent)
    checkpoints/          last checkpoint: model, statistics, replay buffer, state.json

A checkpoint is written every ``checkpoint_every`` environment steps: the
step-numbered files first, then ``state.json`` (atomically) which names them,
so an interruption at any moment leaves the previous checkpoint usable.
``resume=True`` continues from it with the step count continuing
(``reset_num_timesteps=False``).  Ctrl-C writes a checkpoint before stopping.
"""
from __future__ import annotations

import csv
import io
import json
import logging
import math
import os
import platform
import shutil
import time
from pathlib import Path

import numpy as np

from ehas_env.output.files import atomic_write_bytes, atomic_write_text, read_json, read_text

from .config import TrainConfig, algo_class
from . import envs as E
from .batched import make_training_vec_env

log = logging.getLogger("ehas_train")

NO_WORSE_WEIGHT = 10.0  # validate_metric = "no_worse": weight of the mean excess over the classical reference
FEWEST_WORSE_WEIGHT = 100.0  # validate_metric = "fewest_worse": per condition worse than the classical reference
CURVE_COLUMNS = ("timesteps", "episode", "return", "length", "rms_error_pct", "peak_error_pct", "wall_s")


class TrainingInterrupted(RuntimeError):
    """Training stopped before its total steps (a checkpoint was written)."""


def _activation(name: str):
    import torch.nn as nn

    return {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}[name]


def silent_logger(model) -> None:
    """Give ``model`` a logger that records values (the callbacks read them) and writes nowhere.

    Without TensorBoard, stable-baselines3's own logger of a quiet model writes no file, yet makes an empty
    ``SB3-<date>`` folder in the system's temporary folder at every ``learn()``: hundreds left behind by a test run.

    Parameters
    ----------
    model : stable_baselines3.common.base_class.BaseAlgorithm
        The model (its logger replaced).
    """
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(folder=None, output_formats=[]))


def _algo_kwargs(cfg: TrainConfig, action_dim: int) -> dict:
    hyper = dict(cfg.hyper)
    pk = dict(hyper.pop("policy_kwargs", {}))
    if "activation_fn" in pk:
        pk["activation_fn"] = _activation(pk["activation_fn"])
    if pk:
        hyper["policy_kwargs"] = pk
    std = hyper.pop("action_noise_std", None)
    if std is not None:
        from stable_baselines3.common.noise import NormalActionNoise

        hyper["action_noise"] = NormalActionNoise(np.zeros(action_dim), std * np.ones(action_dim))
    return hyper


# -- checkpoints ------------------------------------------------------------
def _save_bytes(path: Path, save_fn) -> None:
    """Run ``save_fn(buffer)`` and write the bytes atomically to ``path``."""
    buf = io.BytesIO()
    save_fn(buf)
    atomic_write_bytes(path, buf.getvalue())


class Checkpointer:
    """Writes and finds checkpoints in ``folder``."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)

    @property
    def state_path(self) -> Path:
        return self.folder / "state.json"

    def state(self) -> dict | None:
        if not self.state_path.exists():
            return None
        return read_json(self.state_path, "the checkpoint state written by ehas train (state.json)")

    def save(self, model, vecnorm, curve_rows: list, train_time_s: float) -> dict:
        step = int(model.num_timesteps)
        tag = f"{step:012d}"
        files = {"model": f"model_{tag}.zip"}
        _save_bytes(self.folder / files["model"], model.save)
        if vecnorm is not None:
            files["vecnormalize"] = f"vecnormalize_{tag}.pkl"
            _save_bytes(self.folder / files["vecnormalize"], lambda b: b.write(_pickle(vecnorm)))
        if hasattr(model, "replay_buffer") and model.replay_buffer is not None:
            files["replay_buffer"] = f"replay_buffer_{tag}.pkl"
            _save_bytes(self.folder / files["replay_buffer"], model.save_replay_buffer)
        files["curve"] = f"curve_{tag}.csv"
        atomic_write_text(self.folder / files["curve"], _curve_csv(curve_rows))
        state = {"num_timesteps": step, "train_time_s": train_time_s, "files": files, "written": time.time()}
        atomic_write_text(self.state_path, json.dumps(state, indent=2))
        # only now are the older files unreferenced
        keep = set(files.values()) | {"state.json"}
        for p in self.folder.iterdir():
            if p.name not in keep and not p.name.startswith("."):
                p.unlink()
        return state


def _pickle(obj) -> bytes:
    import pickle

    return pickle.dumps(obj)


def _curve_csv(rows: list) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(CURVE_COLUMNS)
    for r in rows:
        w.writerow([_fmt(r.get(c)) for c in CURVE_COLUMNS])
    return buf.getvalue()


def _fmt(v) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def read_curve(path) -> list[dict]:
    """Rows of a learning-curve CSV (numbers as floats, blanks as NaN)."""
    rows = []
    text = read_text(path, "a learning-curve CSV written by ehas train")
    try:
        for row in csv.DictReader(io.StringIO(text, newline="")):
            rows.append({k: (float(v) if v != "" else float("nan")) for k, v in row.items()})
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path}: not a learning curve written by ehas train ({exc})") from None
    return rows


# -- callbacks ----------------------------------------------------------------
def validation_conditions(cfg) -> list[tuple[int, float, float]]:
    """The validation conditions (disc sets, Hz, deg).

    Seeded draws from ``[randomise]``, drawn continuously from the ranges so that
    they are (almost surely) not the benchmark's grid points; with
    ``validate_grid`` the benchmark's 63 grid conditions come first.
    """
    from .evaluate import grid_conditions

    rng = np.random.default_rng(cfg.seed + 7919)
    rnd, kw = cfg.randomise, cfg.env_kwargs
    out = list(grid_conditions()) if getattr(cfg, "validate_grid", False) else []
    for _ in range(cfg.validate_conditions):
        n = int(rng.integers(rnd["disc_sets"][0], rnd["disc_sets"][1] + 1)) if "disc_sets" in rnd else int(kw.get("disc_sets", 3))
        f = float(rng.uniform(*rnd["freq_hz"])) if "freq_hz" in rnd else float(kw.get("freq_hz", 1.0))
        a = float(rng.uniform(*rnd["amplitude_deg"])) if "amplitude_deg" in rnd else float(kw.get("amplitude_deg", 20.0))
        out.append((n, f, a))
    return out


class BestKeeper:
    """Validates the deterministic policy and keeps the best model (``out/best_checkpoint``)."""

    def __init__(self, cfg, out: Path, controller_desc):
        self.cfg = cfg
        self.folder = Path(out) / "best_checkpoint"
        self.controller_desc = controller_desc
        self.conditions = validation_conditions(cfg)
        self.rows: list[dict] = []
        state = self.state()
        if state is not None and (state.get("validate_metric", "mean") != getattr(cfg, "validate_metric", "mean")
                                  or [tuple(c) for c in state["conditions"]] != self.conditions):
            log.info("the kept model was validated on other conditions or by another metric: it competes again")
            state = None
            shutil.rmtree(self.folder, ignore_errors=True)
        self.best = state.get("score", state["mean_rms_error_pct"]) if state else float("inf")
        if (Path(out) / "validation.csv").exists():
            self.rows = read_curve(Path(out) / "validation.csv")

    def reference_score(self) -> float | None:
        """Mean rms % error of the classical reference on the validation conditions (computed once).

        The residual's base controller alone (zero action); for a direct agent, the
        best tuned classical controller (``tuned``) run the same way.
        """
        if not hasattr(self, "_ref"):
            self._ref = None
            try:
                from .config import parse_config
                from .evaluate import evaluate_policy

                desc = self.controller_desc if self.cfg.residual else E.resolve_controller_spec("tuned")
                cfg = self.cfg if self.cfg.residual else parse_config(
                    {"train": {"algo": "sac"}, "env": {"residual": True, "kwargs": dict(self.cfg.env_kwargs)}})
                rows = evaluate_policy(cfg, lambda o: np.zeros((len(o), 1), np.float32), self.conditions,
                                       controller_desc=desc, cycles=self.cycles())
                self._ref_rms = np.array([r["rms_error_pct"] for r in rows])
                self._ref = float(self._ref_rms.mean())
            except (ValueError, FileNotFoundError, KeyError) as exc:
                log.warning("no classical reference for the TensorBoard validation plot: %s", exc)
        return self._ref

    def cycles(self) -> float:
        """Reference periods per validation run: the benchmark's when it validates on the benchmark's grid."""
        from .evaluate import DEFAULT_CYCLES

        if getattr(self.cfg, "validate_grid", False):
            return DEFAULT_CYCLES
        return max(3.0, float(self.cfg.env_kwargs.get("cycles", 3.0)))

    def score(self, rms: np.ndarray) -> tuple[float, int]:
        """(score to minimise, conditions worse than the classical reference by more than WORSE_TOL)."""
        from .evaluate import WORSE_TOL

        mean = float(rms.mean())
        metric = getattr(self.cfg, "validate_metric", "mean")
        if self.reference_score() is None:
            return mean, -1
        excess = rms - self._ref_rms - WORSE_TOL
        worse = int(np.count_nonzero(excess > 0))
        if metric == "mean":
            return mean, worse
        if metric == "no_worse":
            return mean + NO_WORSE_WEIGHT * float(np.maximum(excess, 0.0).mean()), worse
        return FEWEST_WORSE_WEIGHT * worse + mean, worse

    def state(self) -> dict | None:
        p = self.folder / "state.json"
        return read_json(p, "the validation state written by ehas train (state.json)") if p.exists() else None

    def validate(self, model, out: Path, train_time_s: float) -> float:
        from .evaluate import evaluate_policy

        vn = model.get_vec_normalize_env()

        def policy(obs):
            o = vn.normalize_obs(obs) if vn is not None else obs
            return model.predict(o, deterministic=True)[0]

        rows = evaluate_policy(self.cfg, policy, self.conditions, controller_desc=self.controller_desc,
                               cycles=self.cycles())
        rms = np.array([r["rms_error_pct"] for r in rows])
        mean = float(rms.mean())
        score, worse = self.score(rms)
        step = int(model.num_timesteps)
        try:  # TensorBoard: the validation figure beside the base (classical) controller's on the same conditions
            model.logger.record("ehas/validation_rms_error_pct", mean)
            model.logger.record("ehas/validation_score", score)
            model.logger.record("ehas/validation_peak_error_pct", float(np.mean([r["peak_error_pct"] for r in rows])))
            model.logger.record("ehas/validation_saturation_frac", float(np.mean([r["saturation_frac"] for r in rows])))
            ref = self.reference_score()
            if ref is not None:
                model.logger.record("ehas/validation_base_rms_error_pct", ref)
                model.logger.record("ehas/validation_conditions_worse", worse)
        except AttributeError:  # a model without a logger (never trained)
            pass
        if score < self.best:
            self.best = score
            _save_bytes(self.folder / "model.zip", model.save)
            if vn is not None:
                _save_bytes(self.folder / "vecnormalize.pkl", lambda b: b.write(_pickle(vn)))
            atomic_write_text(self.folder / "state.json", json.dumps(
                {"num_timesteps": step, "mean_rms_error_pct": mean, "score": score, "worse": worse,
                 "train_time_s": train_time_s,
                 "validate_metric": getattr(self.cfg, "validate_metric", "mean"), "conditions": self.conditions},
                indent=2))
        self.rows.append({"timesteps": step, "mean_rms_error_pct": mean, "score": score, "best_score": self.best,
                          "worse": worse})
        buf = io.StringIO()
        w = csv.writer(buf)
        # worse: conditions worse than the classical reference by more than WORSE_TOL (-1: no reference)
        w.writerow(["timesteps", "mean_rms_error_pct", "score", "best_score", "worse"])
        for r in self.rows:
            w.writerow([int(r["timesteps"]), f"{r['mean_rms_error_pct']:.6g}", f"{r.get('score', r['mean_rms_error_pct']):.6g}",
                        f"{r.get('best_score', r.get('best_rms_error_pct', float('nan'))):.6g}",
                        int(r.get("worse", -1)) if np.isfinite(r.get("worse", -1)) else -1])
        atomic_write_text(Path(out) / "validation.csv", buf.getvalue())
        log.info("validation at step %d: mean rms %.4f %% over %d conditions, %s worse than classical "
                 "(score %.4f, best %.4f)", step, mean, len(self.conditions), worse if worse >= 0 else "?", score,
                 self.best)
        return score


def _callbacks(cfg, ckpt: Checkpointer, curve_rows: list, clock: dict, progress: bool, extra, keeper=None, out=None):
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList

    class Curve(BaseCallback):
        """Collects one learning-curve row per finished episode; logs progress."""

        def _on_step(self) -> bool:
            for info in self.locals.get("infos", []):
                ep = info.get("episode")
                if ep is None:
                    continue
                rms = _num(info.get("rms_error_pct", ep.get("rms_error_pct")))
                stroke = bool(info.get("hit_stroke_end", info.get("termination") == "stroke_end"))
                if np.isfinite(rms):  # TensorBoard: the controls figures of the training episodes
                    self.logger.record_mean("ehas/episode_rms_error_pct", rms)
                sat = info.get("saturation_frac")
                if sat is not None:
                    self.logger.record_mean("ehas/episode_saturation_frac", float(sat))
                self.logger.record_mean("ehas/stroke_end_share", float(stroke))
                clock["stroke_ends"] = clock.get("stroke_ends", 0) + int(stroke)
                self.logger.record("ehas/stroke_end_terminations", clock["stroke_ends"])
                curve_rows.append({
                    "timesteps": int(self.num_timesteps), "episode": len(curve_rows) + 1, "return": float(ep["r"]),
                    "length": int(ep["l"]), "rms_error_pct": _num(info.get("rms_error_pct", ep.get("rms_error_pct"))),
                    "peak_error_pct": _num(info.get("peak_error_pct", ep.get("peak_error_pct"))),
                    "wall_s": clock["before"] + time.time() - clock["start"],
                })
            now = time.time()
            if now - clock["last_log"] >= cfg.log_interval_s:
                clock["last_log"] = now
                recent = curve_rows[-20:]
                msg = f"step {self.num_timesteps}/{cfg.total_steps}"
                if recent:
                    msg += f", mean return (last {len(recent)} episodes) {np.mean([r['return'] for r in recent]):.4g}"
                    rms = [r["rms_error_pct"] for r in recent if np.isfinite(r["rms_error_pct"])]
                    if rms:
                        msg += f", rms error {np.mean(rms):.3g} %"
                log.info(msg)
            return True

    class Checkpoint(BaseCallback):
        def __init__(self):
            super().__init__()
            self.next_at = None

        def _on_training_start(self) -> None:
            every = cfg.checkpoint_every
            self.next_at = (self.num_timesteps // every + 1) * every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next_at:
                vn = self.model.get_vec_normalize_env()
                ckpt.save(self.model, vn, curve_rows, clock["before"] + time.time() - clock["start"])
                self.next_at = (self.num_timesteps // cfg.checkpoint_every + 1) * cfg.checkpoint_every
            return True

    class Progress(BaseCallback):
        def _on_training_start(self) -> None:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=cfg.total_steps, initial=self.num_timesteps, unit="step", dynamic_ncols=True,
                            desc=f"{cfg.algo}{' residual' if cfg.residual else ''}")

        def _on_step(self) -> bool:
            self.bar.update(self.num_timesteps - self.bar.n)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    class Limits(BaseCallback):
        """Stops learning at ``total_steps`` or once the wall-clock budget (this session's part) is spent.

        SB3 alone stops only at a rollout's end: PPO resumed from a checkpoint written
        mid-rollout (Ctrl-C) would overshoot by up to a rollout.  A rollout that ends at
        ``total_steps`` is left to finish, so that its update is made.
        """

        def _on_step(self) -> bool:
            n, n_roll = self.locals.get("n_steps"), self.locals.get("n_rollout_steps")
            if self.num_timesteps >= cfg.total_steps and n is not None and n_roll is not None and n + 1 < n_roll:
                return False
            if clock["limit_s"] is not None and time.time() - clock["start"] >= clock["limit_s"]:
                clock["stopped_by_time"] = True
                return False
            return True

    class Validate(BaseCallback):
        def _on_training_start(self) -> None:
            every = cfg.validate_every
            self.next_at = (self.num_timesteps // every + 1) * every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next_at:
                keeper.validate(self.model, out, clock["before"] + time.time() - clock["start"])
                self.next_at = (self.num_timesteps // cfg.validate_every + 1) * cfg.validate_every
            return True

    cbs = [Curve(), Checkpoint(), Limits()]
    if keeper is not None:
        cbs.append(Validate())
    if progress:
        cbs.append(Progress())
    cbs.extend(extra or [])
    return CallbackList(cbs)


def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


# -- training ---------------------------------------------------------------
def train(cfg: TrainConfig, out, *, resume: bool = False, progress: bool = True, tensorboard: bool = True,
          keep_checkpoints: bool = True, callbacks=None, command: str | None = None,
          max_minutes: float | None = None) -> dict:
    """Train ``cfg`` into the folder ``out`` and return its metrics.

    Parameters
    ----------
    cfg : TrainConfig
        The validated configuration.
    out : path
        Output folder; must be empty or absent unless ``resume``.
    resume : bool
        Continue from the last checkpoint in ``out/checkpoints`` (or from the
        final model when training ended and ``cfg.total_steps`` is larger).
    progress : bool
        Show a tqdm progress bar.
    tensorboard : bool
        Write TensorBoard logs to ``out/tb``.
    keep_checkpoints : bool
        Keep ``out/checkpoints`` once training completes (else it is removed;
        the final model and statistics stay in ``out``).
    callbacks : list of BaseCallback, optional
        Extra stable-baselines3 callbacks.
    command : str, optional
        The command line that runs this training (kept in ``metrics.json``).
    max_minutes : float, optional
        Wall-clock budget of this call: training stops (and is saved, with
        ``stopped_by_time_limit`` in the metrics) when it is spent; resume to go on.

    Returns
    -------
    dict
        The content of ``metrics.json``.
    """
    import torch
    from stable_baselines3.common.vec_env import VecNormalize

    out = Path(out)
    ckpt = Checkpointer(out / "checkpoints")
    state = ckpt.state() if resume else None
    if not resume and out.exists() and any(p for p in out.iterdir() if not p.name.startswith(".")):
        raise ValueError(f"output folder {out} is not empty; use --resume to continue its training or choose "
                         "another --out")
    if resume and not out.exists():
        raise FileNotFoundError(f"--resume: output folder {out} does not exist")
    torch.set_num_threads(cfg.torch_threads)

    if resume:
        from .agent import read_agent_config

        saved = read_agent_config(out / "config.json") if (out / "config.json").exists() else None
        controller_desc = saved["controller_resolved"] if saved and "controller_resolved" in saved else None
        if saved is not None:
            _check_same_task(cfg, saved)
    else:
        controller_desc = None
    if controller_desc is None and cfg.residual:
        controller_desc = E.resolve_controller_spec(cfg.controller)
    # the environments and the model are built before the output folder is made: a configuration
    # that fails there (an environment argument out of range) leaves nothing behind
    created = not out.exists()
    try:
        venv = make_training_vec_env(cfg, controller_desc=controller_desc)
    except BaseException as exc:
        if created and out.exists() and not resume:
            shutil.rmtree(out, ignore_errors=True)
        if isinstance(exc, TypeError) or type(exc).__module__.startswith("gymnasium"):
            # an [env.kwargs] key the environment does not take, an id gymnasium does not know
            raise ValueError(f"{cfg.source}: [env]: {' '.join(str(exc).split())}") from None
        raise
    cls = algo_class(cfg.algo)
    curve_rows: list[dict] = []
    before = 0.0
    vecnorm = None
    if state is not None:
        files = state["files"]
        if cfg.vecnormalize:
            vecnorm = VecNormalize.load(str(ckpt.folder / files["vecnormalize"]), venv)
        model = cls.load(ckpt.folder / files["model"], env=vecnorm or venv, device="cpu")
        if "replay_buffer" in files:
            model.load_replay_buffer(ckpt.folder / files["replay_buffer"])
        curve_rows = read_curve(ckpt.folder / files["curve"])
        for r in curve_rows:
            r["timesteps"], r["episode"], r["length"] = int(r["timesteps"]), int(r["episode"]), int(r["length"])
        before = float(state["train_time_s"])
        log.info("resuming from the checkpoint at step %d", model.num_timesteps)
    elif resume and (out / "model.zip").exists():
        done = read_json(out / "metrics.json", "the metrics written by ehas train (metrics.json)")
        if cfg.vecnormalize:
            vecnorm = VecNormalize.load(str(out / "vecnormalize.pkl"), venv)
        model = cls.load(out / "model.zip", env=vecnorm or venv, device="cpu")
        if (out / "learning_curve.csv").exists():
            curve_rows = read_curve(out / "learning_curve.csv")
        before = float(done.get("train_time_s", 0.0))
        log.info("resuming from the final model at step %d (no replay buffer)", model.num_timesteps)
    elif resume:
        raise FileNotFoundError(f"--resume: {out} holds neither a checkpoint nor a trained model")
    else:
        if cfg.vecnormalize:
            vecnorm = VecNormalize(venv, norm_obs=True, norm_reward=cfg.norm_reward, clip_obs=cfg.clip_obs,
                                   gamma=cfg.hyper.get("gamma", 0.99))
        try:
            model = cls("MlpPolicy", vecnorm or venv, seed=cfg.seed, device="cpu", verbose=0,
                        tensorboard_log=str(out / "tb") if tensorboard else None,
                        **_algo_kwargs(cfg, venv.action_space.shape[0]))
        except (AssertionError, ValueError, TypeError, RuntimeError) as exc:
            # stable-baselines3's own checks of [algo] (n_steps, batch_size, a network too large to allocate)
            venv.close()
            raise ValueError(f"{cfg.source}: [algo]: {' '.join(str(exc).split())[:300]}") from None
    out.mkdir(parents=True, exist_ok=True)
    from .agent import AGENT_CONFIG_FORMAT, AGENT_CONFIG_VERSION

    resolved = {"format": AGENT_CONFIG_FORMAT, "version": AGENT_CONFIG_VERSION, **cfg.to_dict(),
                "controller_resolved": controller_desc}
    atomic_write_text(out / "config.json", json.dumps(resolved, indent=2, default=str))
    if tensorboard and model.tensorboard_log is None:
        model.tensorboard_log = str(out / "tb")
    if not tensorboard:
        model.tensorboard_log = None
        silent_logger(model)

    keeper = BestKeeper(cfg, out, controller_desc) if cfg.validate_every and E.is_tracking_env(cfg.env_id) else None
    if keeper is not None and resume and keeper.state() is None and int(model.num_timesteps) > 0:
        # no kept model (e.g. --drop-checkpoints): the model resumed from competes too
        keeper.validate(model, out, before)
    remaining = cfg.total_steps - int(model.num_timesteps)
    clock = {"start": time.time(), "before": before, "last_log": time.time(),
             "limit_s": None if max_minutes is None else 60.0 * max_minutes, "stopped_by_time": False}
    if remaining > 0:
        cb = _callbacks(cfg, ckpt, curve_rows, clock, progress, callbacks, keeper, out)
        try:
            model.learn(total_timesteps=remaining, callback=cb, reset_num_timesteps=False, tb_log_name=cfg.algo,
                        log_interval=1 if cfg.algo != "ppo" else 1)
        except KeyboardInterrupt:
            ckpt.save(model, model.get_vec_normalize_env(), curve_rows, before + time.time() - clock["start"])
            venv.close()
            raise TrainingInterrupted(
                f"interrupted at step {model.num_timesteps}; checkpoint written, continue with --resume") from None
    train_time = before + time.time() - clock["start"]
    vn = model.get_vec_normalize_env()
    if remaining > 0:
        ckpt.save(model, vn, curve_rows, train_time)  # the last state, for a resume that extends the run

    selected = None
    if keeper is not None:
        if not keeper.rows or int(keeper.rows[-1]["timesteps"]) != int(model.num_timesteps):
            keeper.validate(model, out, train_time)  # the final model competes too
        selected = keeper.state()
    if selected is not None:
        # the best validated model is the result; the last one stays in checkpoints/
        atomic_write_bytes(out / "model.zip", (keeper.folder / "model.zip").read_bytes())
        if (keeper.folder / "vecnormalize.pkl").exists():
            atomic_write_bytes(out / "vecnormalize.pkl", (keeper.folder / "vecnormalize.pkl").read_bytes())
    else:
        _save_bytes(out / "model.zip", model.save)
        if vn is not None:
            _save_bytes(out / "vecnormalize.pkl", lambda b: b.write(_pickle(vn)))
    # the agent as data (policy.safetensors, policy.json, obs_norm.json: docs/agents.md); model.zip and
    # vecnormalize.pkl, written by this run itself, stay for --resume only (load_agent never reads them)
    from .agent_format import write_safe

    if selected is not None:
        from .agent import _load_pickled

        own = _load_pickled(out, warn=False)
        write_safe(out, own.model, own.obs_stats)
    else:
        write_safe(out, model, vn)
    atomic_write_text(out / "learning_curve.csv", _curve_csv(curve_rows))
    plot_learning_curve(curve_rows, out / "learning_curve.png", title=_title(cfg))
    venv.close()

    evaluation = evaluate_final(out, cfg.eval_episodes) if cfg.eval_episodes else {}
    recent = curve_rows[-max(1, min(100, len(curve_rows) // 5)):] if curve_rows else []
    metrics = {
        "algo": cfg.algo, "residual": cfg.residual, "env_id": cfg.env_id, "seed": cfg.seed,
        "num_timesteps": int(model.num_timesteps), "total_steps": cfg.total_steps,
        "train_time_s": round(train_time, 1), "episodes": len(curve_rows),
        "mean_return_recent": float(np.mean([r["return"] for r in recent])) if recent else None,
        "final_evaluation": evaluation,
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "torch_threads": cfg.torch_threads},
        "config": cfg.source,
        "command": command,
        "stopped_by_time_limit": clock["stopped_by_time"],
        "selected_by_validation": None if selected is None else {
            "num_timesteps": selected["num_timesteps"], "mean_rms_error_pct": selected["mean_rms_error_pct"],
            "conditions": len(selected["conditions"]), "train_time_s": round(selected["train_time_s"], 1)},
    }
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=2, default=_jsonable))
    if not keep_checkpoints:
        for folder in (ckpt.folder, out / "best_checkpoint"):
            if folder.exists():
                shutil.rmtree(folder)
    return metrics


def _jsonable(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    return str(o)


def _check_same_task(cfg: TrainConfig, saved: dict) -> None:
    """Resuming must not silently change the task: algorithm, env, residual, randomisation."""
    for key in ("algo", "env_id", "residual", "env_kwargs", "randomise", "vecnormalize", "hyper", "action_repeat",
                "action_scale_mA", "reward_scale", "action_penalty", "action_shape", "reward"):
        if saved.get(key) != cfg.to_dict().get(key):
            raise ValueError(f"--resume: config key {key!r} differs from the run being resumed "
                             f"({saved.get(key)!r} there, {cfg.to_dict().get(key)!r} now)")


def _title(cfg) -> str:
    return f"{cfg.algo.upper()}{' residual' if cfg.residual else ''} on {cfg.env_id} (seed {cfg.seed})"


def evaluate_final(out, episodes: int, seed: int = 10_000) -> dict:
    """Deterministic episodes of the trained agent in its training distribution."""
    from .agent import load_agent

    agent = load_agent(out, warn=False)
    return agent.rollout_stats(episodes, seed=seed)


def plot_learning_curve(rows: list[dict], path, title: str = "") -> None:
    """Return (and rms % error, when the env reports it) against environment steps.

    Dots are training episodes (exploration noise included), the line their moving
    mean over 20 episodes.  The return axis is cut to the range of the moving mean
    (and the bulk of the episodes) so that a few early disasters do not flatten the
    curve; the episodes left below the axis are counted in the legend.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    has_rms = any(np.isfinite(r.get("rms_error_pct", float("nan"))) for r in rows)
    fig, axes = plt.subplots(2 if has_rms else 1, 1, figsize=(7.5, 5.5 if has_rms else 3), sharex=True, squeeze=False)
    axes = axes[:, 0]
    if rows:
        steps = np.array([r["timesteps"] for r in rows], dtype=float)
        ret = np.array([r["return"] for r in rows], dtype=float)
        sm = _smooth(ret)
        fin = ret[np.isfinite(ret)]
        lo = hi = None
        if fin.size:
            lo = min(np.nanmin(sm), np.percentile(fin, 2.0))
            hi = max(np.nanmax(sm), np.percentile(fin, 99.5))
            pad = 0.08 * max(hi - lo, 1e-9)
            lo, hi = lo - pad, hi + pad
        below = int(np.sum(fin < lo)) if lo is not None else 0
        axes[0].plot(steps, ret, ".", ms=2, alpha=0.3, color="C0",
                     label="training episode" + (f" ({below} below the axis)" if below else ""))
        axes[0].plot(steps, sm, color="C0", lw=1.5, label="moving mean, 20 episodes")
        if lo is not None and lo < hi:
            axes[0].set_ylim(lo, hi)
        axes[0].legend(loc="lower right", fontsize=7)
        if has_rms:
            rms = np.array([r["rms_error_pct"] for r in rows], dtype=float)
            axes[1].semilogy(steps, rms, ".", ms=2, alpha=0.3, color="C1", label="training episode")
            axes[1].semilogy(steps, _smooth(rms), color="C1", lw=1.5, label="moving mean, 20 episodes")
            axes[1].set_ylabel("rms position error,\n% of amplitude (log)")
            axes[1].legend(loc="upper right", fontsize=7)
    axes[0].set_ylabel("episode return (reward sum)")
    axes[-1].set_xlabel("environment steps")
    axes[0].set_title((title + ": " if title else "") + "training episodes, exploration noise included", fontsize=9)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    atomic_write_bytes(Path(path), buf.getvalue())


def _smooth(x: np.ndarray, n: int = 20) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    out = np.empty_like(x)
    for i in range(x.size):
        w = x[max(0, i - n + 1): i + 1]
        w = w[np.isfinite(w)]
        out[i] = w.mean() if w.size else np.nan
    return out
