"""Batched ``ehas/Tracking-v0``: N environments stepped in one compiled loop.

A native :class:`gymnasium.vector.VectorEnv`: the N plants live in two float
arrays (see :mod:`ehas_env.env.batch_kernel`) and one numba call steps them all
with the very code of the single environment, so environment ``i`` of a batch
seeded ``s`` follows exactly the episodes of ``TrackingEnv`` reset with seed
``s + i`` and given the same actions.  Settings, spaces, reward and
termination are those of :mod:`ehas_env.env.tracking_env`; the differences:

* autoreset ``NEXT_STEP`` (gymnasium's default): the step after an episode's
  end resets that environment and returns its first observation, reward 0;
* ``max_episode_steps`` (passed by ``gymnasium.make_vec``) truncates longer
  episodes, as the single environment's TimeLimit does;
* ``info`` holds each unscaled quantity as an array over the environments and,
  for the environments whose episode ended, ``rms_error_pct``,
  ``peak_error_pct``, ``metric_complete``, ``episode_steps`` with their
  ``_key`` masks;
* the base controller of residual mode must have a compiled law (``RigController``, ``PIFF``, a user law),
  or be a gain schedule (``for_plant(disc_sets)`` returning such a controller): each
  episode then runs its disc sets' entry, compiled;
* :meth:`TrackingVectorEnv.step_rows` steps a subset of rows without autoreset
  and :meth:`TrackingVectorEnv.episode_amplitudes` gives each row's reference
  amplitude: what an adapter that holds actions or resets rows itself needs
  (``ehas_train.batched``);
* rows are stepped by one serial numba loop (the default, fastest on the
  shared 2-core machine: ``ehas perf`` measures both) or, with
  ``parallel=True``, by a ``prange`` loop on every core, which pays only when
  the cores are free; both give the same numbers.

Examples
--------
>>> import gymnasium, numpy as np, ehas_env
>>> envs = gymnasium.make_vec("ehas/Tracking-v0", num_envs=4, vectorization_mode="vector_entry_point")
>>> obs, info = envs.reset(seed=0)
>>> obs.shape
(4, 13)
>>> obs, rew, term, trunc, info = envs.step(np.zeros((4, 1), np.float32))
>>> float(np.abs(info["theta_deg"]).max())
0.0
"""
from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ehas_env.env import batch_kernel as bk
from ehas_env.env import parts
from ehas_env.physics import layout as K
from ehas_env.simulation.compiled_model import current_model, fast_model_behind
from ehas_env.simulation.plant import TAU_MAX
from ehas_env.env.tracking_env import ACTION_SPACE, EpisodePacker, model_plant_kwargs, observation_space, step_settings



class TrackingVectorEnv(VectorEnv):
    """N tracking environments in one compiled loop (see the module docstring).

    Parameters
    ----------
    num_envs : int
        Number of environments.
    max_episode_steps : int, optional
        Truncate episodes after this many steps (``gymnasium.make_vec`` passes
        the registration's cap).
    parallel : bool
        Step the rows on every core (numba ``prange``) instead of one serial loop.
    disc_sets : int
        Episode default: number of disc sets on the crank, 1..7 (0.383 kg m^2 each).
    amplitude_deg : float
        Episode default: amplitude of the sine reference in degrees, in (0, 44.43).
    freq_hz : float
        Episode default: frequency of the sine reference in Hz, in (0, 50].
    cycles : float
        Episode default: episode length in reference periods.
    effects : dict, list of str or str, optional
        Episode default: effects of the library to switch on (``{"coulomb_friction": {"Fc": 300}}``).
    sensors : {"ideal", "realistic"}, Sensors or dict, optional
        Episode default: the measurement chain (None: ideal).
    theta0_deg : float
        Episode default: initial crank angle in degrees, in [-40, 40].
    reference : SineReference or MultiSine, optional
        Episode default: the reference signal, overriding ``amplitude_deg`` and ``freq_hz``.
    randomise : dict, optional
        Settings drawn at each row's reset from that row's RNG (pairs are ranges, lists of >= 3
        values choices, ``"typical"`` an effect's realistic ranges), as for ``TrackingEnv``.
    controller : RigController, PIFF, GainSchedule or None
        Base controller of the residual mode: it must have a compiled law, or be a gain schedule
        (``for_plant(disc_sets)``), whose entry for each episode's disc sets is compiled into the
        step.  A controller with only ``act()`` is refused (use ``TrackingEnv``).  None: direct mode.
    rate_penalty : float
        Weight (>= 0) of the squared change of the normalised action in the reward.
    termination_penalty : float
        Penalty (>= 0) per remaining step of the episode on early termination.
    preview_ms : sequence of float
        Offsets in milliseconds (positive) of the reference preview entries of the observation.
    dt : float
        Control period in seconds, in (0, 0.01] (rig: 1 ms).
    substeps : int
        RK4 sub-steps per control period, >= 1 (>= 10 recommended).
    plant_kwargs : dict, optional
        Keyword arguments forwarded to :class:`~ehas_env.simulation.plant.Plant`: ``rig``,
        ``inertia`` (kg m^2) or ``model`` only.
    render_mode : None
        Must be None: the vector environment does not render (render a single ``TrackingEnv``).
    effects_path : str, Path or list, optional
        Folders (or files) of user effect files to load before the model is built.
    model : PlantModel, str, Path or dict, optional
        A model file (its path, JSON document or ``PlantModel``): the rig, valve and effects it
        describes (docs/model-file.md).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, *, max_episode_steps: int | None = None, parallel: bool = False,
                 disc_sets: int = 3, amplitude_deg: float = 20.0, freq_hz: float = 1.0, cycles: float = 3.0,
                 effects=None, sensors=None, theta0_deg: float = 0.0, reference=None, randomise: dict | None = None,
                 controller=None, rate_penalty: float = 0.01, termination_penalty: float = 1.0,
                 preview_ms=(10.0, 20.0, 50.0), dt: float = 1.0e-3, substeps: int = 10,
                 plant_kwargs: dict | None = None, render_mode: str | None = None,
                 effects_path=None, model=None):
        from ehas_env.physics.effects import load_effects_path

        load_effects_path(effects_path)  # user effect files: registered before the model is built
        plant_kwargs = model_plant_kwargs(model, plant_kwargs)
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if max_episode_steps is not None and (not isinstance(max_episode_steps, (int, np.integer)) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be a positive integer or None, got {max_episode_steps!r}")
        if render_mode is not None:
            raise ValueError("TrackingVectorEnv does not render; render a single TrackingEnv instead")
        self._schedule = None
        if controller is not None and callable(getattr(controller, "for_plant", None)):
            self._schedule, self._schedule_laws = controller, {}
            controller = self._schedule_law(int(disc_sets))
        if controller is not None and parts.controller_mode(controller, float(dt))[0] != bk.MODE_RIG:
            raise ValueError("the vector env's residual mode takes a controller with a compiled law (compiled into "
                             f"the step); {type(controller).__name__} has only act(): use TrackingEnv, which calls "
                             "it in Python")
        self.num_envs = int(num_envs)
        self.render_mode = None
        self.max_episode_steps = max_episode_steps
        self.parallel = bool(parallel)
        self._st = step_settings(controller, rate_penalty, termination_penalty, preview_ms, dt, substeps, plant_kwargs)
        self._defaults = {"disc_sets": disc_sets, "amplitude_deg": amplitude_deg, "freq_hz": freq_hz,
                          "cycles": cycles, "effects": effects, "sensors": sensors, "theta0_deg": theta0_deg,
                          "reference": reference, "randomise": randomise}
        self._packer = EpisodePacker(self._st)
        self._packer(parts.draw_episode(self._defaults, None, np.random.default_rng(0)))  # fail early

        self.single_observation_space = observation_space(self._st.n_obs)
        self.single_action_space = ACTION_SPACE
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

        n = self.num_envs
        self._model = current_model()
        self._X = np.zeros((n, bk.x_length(K.history_length(TAU_MAX, self._st.dt))))
        self._C = np.zeros((n, bk.C_P + self._model.N_SLOTS))
        self._W = np.zeros((n, *bk.W_SHAPE))
        self._obs = np.zeros((n, self._st.n_obs), np.float32)
        self._raw = np.zeros((n, bk.N_RAW))
        self._sets = np.zeros(n)
        self._rew = np.zeros(n)
        self._n_done = 0  # environments whose episode ended at the last step (reset at the next)
        self._done = np.zeros(n, bool)
        self._rngs: list = [None] * n
        self._options: dict | None = None
        self._all = np.ones(n, bool)
        self._all.flags.writeable = False
        self._raw_masks = {"_" + name: self._all for name in bk.RAW_NAMES}
        self._started = False
        # the fast-step build, or (its first time on this machine) the interpreted build while it compiles behind;
        # a read-only mask (self._all) and a writable one are two types for numba: both are compiled
        rows = (self._X, self._C, self._W)
        out = (self._obs, self._raw)
        ends = (self._rew, np.zeros(n, bool), np.zeros(n, bool))
        step = "batch_step_parallel" if self.parallel else "batch_step_serial"
        calls = [(entry, args) for mask in (self._all, np.ones(n, bool))
                 for entry, args in (("batch_reset", rows + (mask,) + out),
                                     (step, rows + (np.zeros(n), mask) + out + ends))]
        self._builds = fast_model_behind(calls, "the environments' step", "inline, environment step")
        self._model = self._builds.model

    # -- gymnasium API ------------------------------------------------------
    def reset(self, *, seed=None, options: dict | None = None):
        """Reset every environment (or those of ``options["reset_mask"]``).

        ``seed``: an int (environment i gets ``seed + i``), a list of N seeds
        (None entries draw fresh entropy) or None.  ``options`` hold episode
        settings, as for ``TrackingEnv.reset``; they stay in force for the
        automatic resets that follow.

        Parameters
        ----------
        seed : int, list of int or None, optional
            Environment i's RNG seed: ``seed + i`` for an int, ``seed[i]`` for a list of ``num_envs``
            seeds (None entries draw fresh entropy); None keeps the RNGs (fresh ones on the first reset).
        options : dict, optional
            Episode settings (``disc_sets``, ``amplitude_deg``, ``freq_hz``, ``cycles``, ``effects``,
            ``sensors``, ``theta0_deg``, ``reference``, ``randomise``, in the constructor's units) and
            ``reset_mask``, a boolean array of shape ``(num_envs,)`` choosing the rows to reset.

        Returns
        -------
        obs : ndarray of float32
            The observations, shape ``(num_envs, 10 + len(preview_ms))``.
        info : dict
            Each unscaled quantity (deg, deg/s, bar, LPM, kN, mA) as an array over the environments,
            with its ``_key`` mask.
        """
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        mask = self._all if mask is None else np.asarray(mask, bool)
        if mask.shape != (self.num_envs,):
            raise ValueError(f"reset_mask must be a boolean array of shape ({self.num_envs},), got shape {mask.shape}")
        if seed is None:
            seeds = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed must be an int, None or a list of {self.num_envs} seeds, got {len(seeds)}")
        if seed is not None or not self._started:
            for i in np.flatnonzero(mask):
                self._rngs[i] = seeding.np_random(seeds[i])[0]
            if seed is not None:
                self._np_random, self._np_random_seed = seeding.np_random(seeds[0])
        self._options = options
        self._started = True
        self._reset_rows(mask)
        self._done = self._done & ~mask
        self._n_done = int(self._done.sum())
        return self._obs.copy(), self._raw_info()

    def step(self, actions):
        """Advance every environment one control period, resetting the ones whose episode ended.

        Parameters
        ----------
        actions : array_like of float
            One normalised servo current in [-1, 1] per environment, shape ``(num_envs, 1)`` (or
            ``num_envs`` values); out-of-range values are clipped, NaN and inf refused.

        Returns
        -------
        obs : ndarray of float32
            The observations, shape ``(num_envs, 10 + len(preview_ms))``.
        rewards : ndarray of float
            Each environment's reward (0 for the environments reset at this step).
        terminated, truncated : ndarray of bool
            Each environment's end flags (stroke end or non-finite state; ``cycles`` reached or
            ``max_episode_steps``).
        info : dict
            The unscaled quantities as arrays over the environments and, for the environments whose
            episode ended, ``rms_error_pct``, ``peak_error_pct``, ``metric_complete``,
            ``episode_steps`` with their ``_key`` masks.
        """
        a = np.asarray(actions, dtype=np.float64)
        if a.size != self.num_envs:
            raise ValueError(f"actions must hold one value per environment, shape ({self.num_envs}, 1); got shape {a.shape}")
        a = a.reshape(self.num_envs)
        if not np.isfinite(a).all():
            i = np.flatnonzero(~np.isfinite(a))
            raise ValueError(f"actions of environments {i[:10].tolist()} are not finite ({a[i[0]]!r}): expected "
                             "normalised currents in [-1, 1] (NaN and inf are refused, out-of-range values are clipped)")
        if not self._started:
            raise RuntimeError("step() before reset()")
        if self._n_done:
            resetting = self._done.copy()
            self._reset_rows(resetting)
            active = ~resetting
        else:
            active = self._all
        terminated = np.empty(self.num_envs, bool)
        truncated = np.empty(self.num_envs, bool)
        if not self._builds.done or self._model is not self._builds.model:
            self._model = self._builds.poll()
        self._n_done = self._model.batch_step(self._X, self._C, self._W, a, active, self._obs, self._raw, self._rew,
                                     terminated, truncated, parallel=self.parallel)
        info = self._raw_info()
        if self._n_done:
            self._done = terminated | truncated
            self._final_info(info, self._done)
        else:
            self._done[:] = False  # the rows reset at this step are done with
        return self._obs.copy(), self._rew.copy(), terminated, truncated, info

    def close_extras(self, **kwargs):
        """Nothing to release (gymnasium's ``VectorEnv.close`` hook).

        Parameters
        ----------
        **kwargs
            Ignored (passed on by ``VectorEnv.close``).
        """
        pass

    # -- helpers --------------------------------------------------------------
    def _reset_rows(self, mask: np.ndarray):
        idx = np.flatnonzero(mask)
        for i in idx:
            if self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(None)[0]
            ep = parts.draw_episode(self._defaults, self._options, self._rngs[i])
            self._sets[i] = ep.disc_sets
            C, _ = self._packer(ep)
            if self._schedule is not None:  # the episode's entry of the gain schedule
                _, gains, law = parts.controller_mode(self._schedule_law(ep.disc_sets), self._st.dt)
                C[bk.C_GAINS:bk.C_GAINS + bk.N_GAIN_SLOTS] = gains
                C[bk.C_LAW] = law
            if self.max_episode_steps is not None:
                C[bk.C_NSTEPS] = min(C[bk.C_NSTEPS], self.max_episode_steps)
            self._C[i] = C
        if not self._builds.done or self._model is not self._builds.model:
            self._model = self._builds.poll()
        self._model.batch_reset(self._X, self._C, self._W, mask, self._obs, self._raw)

    def _schedule_law(self, disc_sets: int):
        hit = self._schedule_laws.get(disc_sets)
        if hit is None:
            entry = self._schedule.for_plant(int(disc_sets))
            hit = self._schedule_laws[disc_sets] = entry.rig_gains() if callable(getattr(entry, "rig_gains", None)) else entry
        return hit

    def step_rows(self, actions, active):
        """Step only the rows with ``active[i]``, without autoreset: ``(obs, rewards, terminated, truncated)``.

        Rows whose episode ended stay ended until the caller resets them
        (``reset(options={"reset_mask": mask})``); inactive rows get reward 0
        and no end flags.  Unscaled values of the latest sample:
        :meth:`raw`.  Not to be mixed with :meth:`step`'s autoreset in one
        episode.

        Parameters
        ----------
        actions : array_like of float
            One normalised servo current in [-1, 1] per environment (``num_envs`` values; inactive
            rows' are ignored).
        active : array_like of bool
            Shape ``(num_envs,)``: the rows to step.

        Returns
        -------
        obs : ndarray of float32
            The observations of every row, shape ``(num_envs, 10 + len(preview_ms))``.
        rewards : ndarray of float
            Each row's reward (0 for inactive rows).
        terminated, truncated : ndarray of bool
            Each row's end flags at this step (False for inactive rows).
        """
        a = np.asarray(actions, dtype=np.float64).reshape(self.num_envs)
        if not np.isfinite(a).all():
            raise ValueError("step_rows: actions must be finite (normalised currents in [-1, 1])")
        if not self._started:
            raise RuntimeError("step_rows() before reset()")
        terminated = np.empty(self.num_envs, bool)
        truncated = np.empty(self.num_envs, bool)
        if not self._builds.done or self._model is not self._builds.model:
            self._model = self._builds.poll()
        self._model.batch_step(self._X, self._C, self._W, a, np.asarray(active, bool), self._obs, self._raw,
                               self._rew, terminated, truncated, parallel=self.parallel)
        return self._obs.copy(), self._rew.copy(), terminated, truncated

    def raw(self, name: str) -> np.ndarray:
        """The unscaled quantity ``name`` (a key of ``info``: ``theta_deg``, ``p_a_bar`` ...) of every row, a view.

        Parameters
        ----------
        name : str
            A key of ``info`` (``batch_kernel.RAW_NAMES``), for example ``theta_deg`` or ``p_a_bar``.

        Returns
        -------
        ndarray
            Shape ``(num_envs,)``, in the key's unit (s, deg, deg/s^n, bar, LPM, kN, mA; ``action`` is
            normalised); a view that the next step overwrites.
        """
        return self._raw[:, bk.RAW_NAMES.index(name)]

    def episode_disc_sets(self) -> np.ndarray:
        """Each row's disc sets (its episode's load).

        Returns
        -------
        ndarray of float
            Shape ``(num_envs,)``: the number of disc sets of each row's current episode (a copy).
        """
        return self._sets.copy()

    def episode_amplitudes(self) -> np.ndarray:
        """Each row's reference amplitude, deg (the % error's normaliser).

        Returns
        -------
        ndarray of float
            Shape ``(num_envs,)``: the reference amplitude of each row's current episode in degrees (a copy).
        """
        return self._C[:, bk.C_AMP].copy()

    def _raw_info(self) -> dict:
        info = dict(zip(bk.RAW_NAMES, self._raw.T.copy()))
        info.update(self._raw_masks)
        return info

    def _final_info(self, info: dict, done: np.ndarray):
        n = self.num_envs
        rms = np.zeros(n)
        peak = np.zeros(n)
        complete = np.zeros(n, bool)
        steps = np.zeros(n, np.int64)
        for i in np.flatnonzero(done):
            m = parts.episode_metrics(self._X[i], self._C[i])
            rms[i], peak[i], complete[i] = m["rms_error_pct"], m["peak_error_pct"], m["metric_complete"]
            steps[i] = int(self._X[i, bk.X_K])
        for key, val in (("rms_error_pct", rms), ("peak_error_pct", peak), ("metric_complete", complete),
                         ("episode_steps", steps)):
            info[key] = val
            info["_" + key] = done.copy()

    def wait_for_fast_step(self, timeout: float | None = None) -> bool:
        """Wait until the step runs on the fast-step build (see :mod:`ehas_env.physics.compile_behind`).

        The first time a set of effects and laws is used on a machine, the step runs on the interpreted
        build (the same numbers, a slower step) while the fast one compiles in a background process; a
        benchmark waits here before it times anything.

        Parameters
        ----------
        timeout : float, optional
            Seconds to wait at most (None: until it is).

        Returns
        -------
        bool
            True when the fast-step build is in use.
        """
        self._model = self._builds.wait(timeout)
        return self._builds.done and self._model is self._builds.fast

    def episode_metrics(self, i: int) -> dict:
        """rms/peak % position error of environment ``i``'s episode so far.

        Parameters
        ----------
        i : int
            Row (environment) index, 0 to ``num_envs - 1``.

        Returns
        -------
        dict
            ``rms_error_pct`` and ``peak_error_pct`` (float, % of the reference amplitude) and
            ``metric_complete`` (bool: False when the episode has not reached the whole cycles after
            the first, the metric then covering every sample so far).
        """
        return parts.episode_metrics(self._X[i], self._C[i])
