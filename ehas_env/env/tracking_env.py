"""``ehas/Tracking-v0``: make the crank follow a reference by commanding the servo valve.

The plant is the project's reference model (:class:`ehas_env.simulation.plant.Plant`:
identified servo valve, orifice law, compressible chambers, actuator, crank and
disc inertia, plus any effect of the library), integrated with RK4 at
``substeps`` sub-steps per 1 ms control period by the shared numba kernel.  The
agent commands the servo current; the goal is the rig's test: follow a sine of
given amplitude and frequency (faded in over its first cycle, as
:class:`~ehas_env.simulation.reference.SineReference` does) with the least % position
error.  One step is one compiled call (:mod:`ehas_env.env.batch_kernel`) doing the
physics, observation and reward; ``ehas perf`` measures its speed.

>>> import gymnasium, ehas_env
>>> env = gymnasium.make("ehas/Tracking-v0")
>>> obs, info = env.reset(seed=0)
>>> obs.shape, round(info["theta_ref_deg"], 6)
((13,), 0.0)

Action space
------------
``Box(-1, 1, (1,), float32)``: the servo current, normalised, ``i = 20 mA * a``.

=================  ==========================================================
direct mode        ``i = 20 mA * a`` (default, ``controller=None``)
residual mode      ``i = clip(u_controller + 20 mA * a, -20, 20) mA``: the action
                   is added to a classical controller's output (``controller=``
                   a :class:`~ehas_env.simulation.plant.RigController`, compiled into the
                   step, or any object with ``reset()`` and ``act(measurement) -> mA``,
                   called in Python with the keys of ``Plant.simulate_closed_loop``)
out of range       clipped to [-1, 1]
NaN / inf          refused: ``ValueError`` naming the action; nothing is simulated
=================  ==========================================================

The current then passes the controller's 12-bit DAC when ``sensors`` model it.

Observation space
-----------------
``Box(-10, 10, (10 + len(preview_ms),), float32)``, each entry scaled to about
[-1, 1] and clipped to +-10 (reached only in abnormal states).  ``info`` holds
the same quantities unscaled (next table, right column).

======  ===============  ==========================================  ====================
index   name             quantity                                    scale (info key)
======  ===============  ==========================================  ====================
0       error            theta_ref - theta_sensed                    / amplitude (error_deg)
1       theta            sensed crank angle                          / 44.43 deg stroke end (theta_sensed_deg)
2       omega            sensed rate: theta_sensed's backward        / 565 deg/s (omega_sensed_deg_s)
                         difference (the rig has no rate sensor)
3       theta_ref        reference                                   / 44.43 deg (theta_ref_deg)
4       theta_ref_dot    its analytic 1st derivative                 / 565 deg/s (theta_ref_dot)
5       theta_ref_ddot   its analytic 2nd derivative                 / 10659 deg/s^2 (theta_ref_ddot)
6..     preview          theta_ref(t + d) for d in ``preview_ms``    / 44.43 deg
-4      p_a              chamber A pressure                          2 p / Ps - 1 (p_a_bar)
-3      p_b              chamber B pressure                          2 p / Ps - 1 (p_b_bar)
-2      prev_action      the previous action (clipped)               1 (action)
-1      u_controller     the base controller's output (residual)     / 20 mA (u_controller_mA)
======  ===============  ==========================================  ====================

The velocity and acceleration scales are the rig's design point, +-30 deg at
3 Hz (rig.md): 30 * 2 pi 3 deg/s and 30 * (2 pi 3)^2 deg/s^2.  theta_sensed is
the LVDT reading with the sensor chain's gain error, noise and 16-bit ADC (the
physical angle when ``sensors`` is ideal, the default).  Everything observed is
available to a controller on the rig: :class:`MeasurementObserver` builds the
same observation from the controller interface's measurement, so a trained
policy runs as a controller in ``Plant.simulate_closed_loop`` or the benchmark.

Info
----
Every step's ``info`` holds the unscaled values of the new sample: ``t`` (s),
``theta_deg`` (physical LVDT angle), ``theta_sensed_deg``, ``omega_deg_s``
(model), ``omega_sensed_deg_s``, ``theta_ref_deg`` and its derivatives
``theta_ref_dot``, ``theta_ref_ddot``, ``theta_ref_dddot`` (deg/s^n),
``error_deg`` (theta_ref - theta_sensed), ``p_a_bar``, ``p_b_bar``,
``p_s_bar``, ``flow_lpm``, ``load_kN``, and of the step just simulated:
``current_mA`` (commanded), ``u_controller_mA`` (the base controller's part),
``action`` (clipped).  ``reset`` adds ``episode`` (the drawn settings),
``episode_steps`` and ``metric_window_s``.

Reward
------
``r = -(e / A)^2 - rate_penalty * (a - a_prev)^2`` per step, with ``e`` the
error on the physical angle, ``A`` the reference amplitude and ``a`` the
(clipped) action.  On early termination the step also pays
``termination_penalty`` per remaining step of the episode, as if the error
stayed at the amplitude: ending early never pays.  Bounds:
``-(1 + 44.43 deg / A)^2 - 4 rate_penalty - termination_penalty * n_steps <= r <= 0``.

Episode end
-----------
=================  ==========================================================
terminated         the piston touches a stroke end (``info["termination"] =
                   "stroke_end"``) or the state turns non-finite (the step is
                   undone, ``"non_finite_state"``); observations and rewards are
                   never NaN
truncated          after ``cycles`` reference periods (3000 steps by default);
                   the registered TimeLimit (60 000 steps) is only a safety cap
final ``info``     ``rms_error_pct``, ``peak_error_pct``: 100 RMS and max of
                   (theta_ref - theta) / amplitude over the whole cycles after
                   the first (reference-model.md), ``metric_complete`` (False
                   when the episode ended before the window), ``episode_steps``
=================  ==========================================================

Options
-------
Constructor keyword arguments set the defaults; ``reset(options=...)`` may
override any episode setting for that one episode:

=================  ==========================================================
disc_sets          1..7 disc sets (0.383 kg m^2 each), default 3
amplitude_deg      sine amplitude, deg (0 < A < 44.43), default 20
freq_hz            sine frequency, Hz, default 1
cycles             episode length in reference periods, default 3
effects            effects of the library: ``{"coulomb_friction": {"Fc": 300}}``
sensors            ``"ideal"`` (default), ``"realistic"`` or a ``Sensors``
theta0_deg         initial crank angle, deg, default 0
reference          a ``SineReference`` or ``env_parts.MultiSine`` (overrides
                   amplitude/frequency)
randomise          drawn at each reset from the env's RNG (seeded by
                   ``reset(seed=)``): a pair is a range, a list of >= 3 values a
                   set of choices, ``"typical"`` an effect's realistic ranges,
                   e.g. ``{"disc_sets": (1, 7), "amplitude_deg": (5, 30),
                   "freq_hz": [1, 2, 3], "cycles": (2, 4), "theta0_deg": (-5, 5),
                   "effects": {"coulomb_friction": {"Fc": (150, 600)},
                   "viscous_friction": "typical"}}``
=================  ==========================================================

Constructor only: ``long_test`` (N: the long-test protocol, docs/learning-control.md: episodes of N whole
reference cycles, and at the episode's end ``info`` adds ``steady_rms_pct`` over the last five cycles,
``settle_cycles``, ``worst_cycle_pct`` and ``cycle_rms_pct`` of :mod:`ehas_env.simulation.long_test`),
``controller`` (residual mode), ``rate_penalty`` (0.01),
``termination_penalty`` (1.0), ``preview_ms`` ((10, 20, 50)), ``dt`` (1e-3 s),
``substeps`` (10), ``plant_kwargs`` (forwarded to ``Plant``: ``rig=``,
``inertia=``), ``model`` (a model file or ``PlantModel``: the rig, valve and
effects it describes, docs/model-file.md; episode effects add to its effects),
``render_mode``.

Rendering
---------
``rgb_array``: a 320 x 640 RGB image, crank dial (actual crank solid,
reference dashed, stroke ends marked) beside the last 2 s of reference and
position.  ``human``: the same image in a matplotlib window, refreshed at
``metadata["render_fps"]`` frames per simulated second.
"""
from __future__ import annotations

import copy
import math
import warnings

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ehas_env.env import batch_kernel as bk
from ehas_env.env import parts
from ehas_env.physics import layout as K
from ehas_env.simulation.compiled_model import fast_model_behind
from ehas_env.simulation.control_laws import N_MEM, all_laws
from ehas_env.simulation.plant import TAU_MAX

_META_KEYS = ("t", "theta_deg", "theta_ref_deg", "theta_ref_dot", "theta_ref_ddot", "theta_ref_dddot",
              "p_a_bar", "p_b_bar", "p_s_bar")
_META_RAW = (bk.R_T, bk.R_THS, bk.R_REF, bk.R_REFD, bk.R_REFDD, bk.R_REFDDD, bk.R_PA, bk.R_PB, bk.R_PS)
_ENDED = bk.FLAG_STROKE_END | bk.FLAG_NONFINITE


def step_settings(controller, rate_penalty, termination_penalty, preview_ms, dt, substeps, plant_kwargs):
    """Validate the constructor-only arguments shared by the single and the vector env."""
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and 0 < dt <= 0.01):
        raise ValueError(f"dt must be a control period in (0, 0.01] s, got {dt!r}")
    if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise ValueError(f"substeps must be a positive integer (>= 10 recommended), got {substeps!r}")
    for name, v in (("rate_penalty", rate_penalty), ("termination_penalty", termination_penalty)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a non-negative number, got {v!r}")
    prev = tuple(preview_ms)
    if len(prev) > bk.MAX_PREVIEW or not all(isinstance(d, (int, float)) and math.isfinite(d) and d > 0 for d in prev):
        raise ValueError(f"preview_ms must be up to {bk.MAX_PREVIEW} positive offsets in ms, got {preview_ms!r}")
    plant_kwargs = dict(plant_kwargs or {})
    for key in plant_kwargs:
        if key not in ("rig", "inertia", "model"):
            raise ValueError(f"plant_kwargs: '{key}' is not accepted; allowed: rig, inertia, model "
                             "(the episode settings are keyword arguments of the env)")
    mode, gains, law = parts.controller_mode(controller, float(dt))
    return parts.StepSettings(dt=float(dt), substeps=int(substeps), mode=mode, gains=gains, law=law,
                              rate_penalty=float(rate_penalty), termination_penalty=float(termination_penalty),
                              preview_s=tuple(float(d) * 1e-3 for d in prev), plant_kwargs=plant_kwargs)


def model_plant_kwargs(model, plant_kwargs):
    """``plant_kwargs`` with the model (file, dict or PlantModel) routed to ``Plant(model=)``."""
    if model is None:
        return plant_kwargs
    from ehas_env.simulation.model_file import as_model

    return {**(plant_kwargs or {}), "model": as_model(model)}


def observation_space(n_obs: int) -> spaces.Box:
    return spaces.Box(-parts.OBS_CLIP, parts.OBS_CLIP, (n_obs,), np.float32)


ACTION_SPACE = spaces.Box(-1.0, 1.0, (1,), np.float32)


class EpisodePacker:
    """Episodes to constant rows, caching the plant build of repeated settings."""

    def __init__(self, st: parts.StepSettings):
        self.st = st
        self._cache: dict = {}
        self._size = None

    def __call__(self, ep: parts.Episode) -> tuple[np.ndarray, dict]:
        key = repr((ep.disc_sets, ep.amplitude_deg, ep.freq_hz, ep.cycles, ep.effects, ep.sensors, ep.theta0_deg,
                    ep.reference))
        hit = self._cache.get(key)
        if hit is None:
            if len(self._cache) > 256:
                self._cache.clear()
            hit = self._cache[key] = parts.pack_episode(ep, self.st)
            if self._size is None:
                self._size = hit[0].size
            elif hit[0].size != self._size:  # the plant is on another compiled model than the env's
                raise ValueError("effects or controller laws were loaded after this environment was made; "
                                 "make the environment again (or load them first, e.g. effects_path=)")
        C, desc = hit
        C = C.copy()
        C[bk.C_SEED] = ep.noise_seed
        return C, desc


class TrackingEnv(gym.Env):
    """Position tracking of the crank with the servo valve (see the module docstring).

    Parameters
    ----------
    disc_sets : int
        Episode default: number of disc sets on the crank, 1..7 (0.383 kg m^2 each).
    amplitude_deg : float
        Episode default: amplitude of the sine reference in degrees, in (0, 44.43).
    freq_hz : float
        Episode default: frequency of the sine reference in Hz, in (0, 50].
    cycles : float
        Episode default: episode length in reference periods (the episode is truncated after them).
    effects : dict, list of str or str, optional
        Episode default: effects of the library to switch on, as :class:`~ehas_env.simulation.plant.Plant`
        takes them (``{"coulomb_friction": {"Fc": 300}}``); added to the model's effects.
    sensors : {"ideal", "realistic"}, Sensors or dict, optional
        Episode default: the measurement chain, a :class:`~ehas_env.simulation.sensors.Sensors` or a
        dict of its fields (None: ideal, no noise or quantization).
    theta0_deg : float
        Episode default: initial crank angle in degrees, in [-40, 40].
    reference : SineReference or MultiSine, optional
        Episode default: the reference signal, overriding ``amplitude_deg`` and ``freq_hz``.
    randomise : dict, optional
        Settings drawn at each reset from the environment's RNG (seeded by ``reset(seed=)``): a pair
        is a range, a list of >= 3 values a set of choices, ``"typical"`` an effect's realistic ranges
        (see the module docstring, Options).
    controller : RigController or object, optional
        Base controller of the residual mode (the action is added to its current): a controller
        with a compiled law (``RigController``, ``PIFF``) is compiled into the step; any other object
        with ``act(measurement) -> mA`` (and optionally ``reset()``) is called in Python every step.
        None (default): direct mode, the action is the current.
    rate_penalty : float
        Weight (>= 0) of the squared change of the normalised action in the reward.
    termination_penalty : float
        Penalty (>= 0) per remaining step of the episode on early termination.
    preview_ms : sequence of float
        Offsets in milliseconds (positive, at most ``batch_kernel.MAX_PREVIEW`` of them) of the
        reference preview entries of the observation.
    dt : float
        Control period in seconds, in (0, 0.01] (rig: 1 ms).
    substeps : int
        RK4 sub-steps per control period, >= 1 (>= 10 recommended: the chambers are stiff).
    plant_kwargs : dict, optional
        Keyword arguments forwarded to :class:`~ehas_env.simulation.plant.Plant`: ``rig``,
        ``inertia`` (kg m^2) or ``model`` only.
    render_mode : {"rgb_array", "human"}, optional
        How :meth:`render` shows the run (None: no rendering).
    effects_path : str, Path or list, optional
        Folders (or files) of user effect files to load before the model is built.
    model : PlantModel, str, Path or dict, optional
        A model file (its path, its JSON document or its
        :class:`~ehas_env.simulation.model_file.PlantModel`): the rig, valve and effects it describes
        (docs/model-file.md).
    long_test : int, optional
        The long-test protocol: episodes of ``long_test`` (7..1000) whole reference cycles (it sets
        ``cycles``), and the final ``info`` adds the long test's figures (module docstring).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 30}

    def __init__(self, disc_sets: int = 3, amplitude_deg: float = 20.0, freq_hz: float = 1.0, cycles: float = 3.0,
                 effects=None, sensors=None, theta0_deg: float = 0.0, reference=None, randomise: dict | None = None,
                 controller=None, rate_penalty: float = 0.01, termination_penalty: float = 1.0,
                 preview_ms=(10.0, 20.0, 50.0), dt: float = 1.0e-3, substeps: int = 10, plant_kwargs: dict | None = None,
                 render_mode: str | None = None, effects_path=None, model=None, long_test: int | None = None):
        from ehas_env.physics.effects import load_effects_path
        from ehas_env.ranges import check_number

        self._long = None if long_test is None else int(check_number(long_test, "long_test", "reference cycles", 7,
                                                                     1000, integer=True))
        if self._long is not None:  # N whole cycles: a hundredth of a period more
            cycles = self._long + 0.01

        load_effects_path(effects_path)  # user effect files: registered before the model is built
        plant_kwargs = model_plant_kwargs(model, plant_kwargs)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self._st = step_settings(controller, rate_penalty, termination_penalty, preview_ms, dt, substeps, plant_kwargs)
        self.controller = controller
        self._defaults = {"disc_sets": disc_sets, "amplitude_deg": amplitude_deg, "freq_hz": freq_hz,
                          "cycles": cycles, "effects": effects, "sensors": sensors, "theta0_deg": theta0_deg,
                          "reference": reference, "randomise": randomise}
        self._packer = EpisodePacker(self._st)
        # build one episode now: bad settings fail at construction, and the arrays hold a valid episode
        C0, self._desc = self._packer(parts.draw_episode(self._defaults, None, np.random.default_rng(0)))

        self.observation_space = observation_space(self._st.n_obs)
        self.action_space = ACTION_SPACE
        hist = K.history_length(TAU_MAX, self._st.dt)
        self._X = np.zeros(bk.x_length(hist))
        self._C = np.zeros(C0.size)
        self._W = np.zeros(bk.W_SHAPE)
        self._obs = np.zeros(self._st.n_obs, np.float32)
        self._raw = np.zeros(bk.N_RAW)
        self._external = self._st.mode == bk.MODE_EXTERNAL
        self._C[:] = C0
        # the fast-step build, or (its first time on this machine) the interpreted build while it compiles behind
        arrays = (self._X, self._C, self._W)
        self._builds = fast_model_behind({"single_reset": arrays + (self._obs, self._raw),
                                          "single_step": arrays + (0.0, 0.0, self._obs, self._raw)},
                                         "the environment's step", "inline, environment step")
        self._model = self._builds.model
        self._model.single_reset(self._X, self._C, self._W, self._obs, self._raw)
        self._trace = None
        self._long_trace = []
        self._frame_every = max(1, int(round(1.0 / (self.metadata["render_fps"] * self._st.dt))))
        self._renderer = None

    # -- gymnasium API ------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start a new episode (gymnasium API).

        Parameters
        ----------
        seed : int, optional
            Seed of the environment's RNG (the randomised settings and the sensor noise); None
            keeps the current RNG.
        options : dict, optional
            Episode settings for this episode only (keys ``disc_sets``, ``amplitude_deg``, ``freq_hz``,
            ``cycles``, ``effects``, ``sensors``, ``theta0_deg``, ``reference``, ``randomise``, in the
            constructor's units), overriding the constructor's defaults.

        Returns
        -------
        obs : ndarray of float32
            The first observation, shape ``(10 + len(preview_ms),)``, scaled (module docstring).
        info : dict
            The unscaled quantities of the first sample (deg, deg/s, bar, LPM, kN, mA) plus
            ``episode`` (the drawn settings), ``episode_steps`` and ``metric_window_s``.
        """
        super().reset(seed=seed)
        ep = parts.draw_episode(self._defaults, options, self.np_random)
        C, self._desc = self._packer(ep)
        self._C[:] = C
        if self._external and callable(getattr(self.controller, "reset", None)):
            self.controller.reset()
        if not self._builds.done or self._model is not self._builds.model:
            self._model = self._builds.poll()
        self._model.single_reset(self._X, self._C, self._W, self._obs, self._raw)
        if self.render_mode is not None:
            self._trace = _Trace(int(round(2.0 / self._st.dt)) + 1)
            self._trace.add(self._raw)
            if self.render_mode == "human":
                self.render()
        info = self._info()
        info.update(copy.deepcopy(self._desc))  # users keep infos: never share the cached description
        self._long_trace = []  # (t, theta_ref - theta) of each step, for the long test
        return self._obs.copy(), info

    def step(self, action):
        """Advance one control period (gymnasium API).

        Parameters
        ----------
        action : float or array_like of one float
            Normalised servo current in [-1, 1] (``i = 20 mA * a``, added to the base controller's
            current in residual mode); out-of-range values are clipped, NaN and inf refused.

        Returns
        -------
        obs : ndarray of float32
            The observation of the new sample.
        reward : float
            ``-(e / A)^2 - rate_penalty (a - a_prev)^2`` (plus the termination penalty on early end).
        terminated : bool
            True when the piston touched a stroke end or the state turned non-finite.
        truncated : bool
            True after ``cycles`` reference periods.
        info : dict
            The unscaled quantities of the new sample; at the episode's end also ``rms_error_pct``,
            ``peak_error_pct``, ``metric_complete``, ``episode_steps`` and ``termination``.

        Raises
        ------
        ValueError
            If the action is not one finite number.
        """
        if type(action) is np.ndarray and action.shape == (1,):
            a = float(action[0])
        else:
            a = _action_value(action)
        u_ext = self._external_act() if self._external else 0.0
        if not self._builds.done or self._model is not self._builds.model:
            self._model = self._builds.poll()
        reward = self._model.single_step(self._X, self._C, self._W, a, u_ext, self._obs, self._raw)
        flags = int(self._X[bk.X_FLAGS])
        if self._long is not None:
            self._long_trace.append((self._raw[bk.R_T], self._raw[bk.R_REF] - self._raw[bk.R_THETA]))
        if self._trace is not None:
            self._trace.add(self._raw)
            if self.render_mode == "human" and int(self._X[bk.X_K]) % self._frame_every == 0:
                self.render()
        if flags == 0:
            return self._obs.copy(), reward, False, False, dict(zip(bk.RAW_NAMES, self._raw.tolist()))
        return self._end_step(flags, reward, a)

    def render(self):
        """Draw the crank dial and the last 2 s of reference and position.

        Returns
        -------
        ndarray or None
            With ``render_mode="rgb_array"`` the frame, a 320 x 640 x 3 uint8 RGB image; with
            ``"human"`` None (the frame is shown in a matplotlib window); None with a warning when
            the environment has no render mode.
        """
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; make the env with render_mode='rgb_array' or 'human'")
            return None
        if self._trace is None:
            raise RuntimeError("render(): call reset() first")
        if self._renderer is None:
            self._renderer = _Renderer(self._C[bk.C_TH_SCALE])
        frame = self._renderer.draw(self._trace, self._C[bk.C_AMP])
        if self.render_mode == "rgb_array":
            return frame
        self._renderer.show(frame, 1.0 / self.metadata["render_fps"])
        return None

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # -- helpers --------------------------------------------------------------
    @property
    def episode(self) -> dict:
        """The current episode's settings, length and metric window."""
        return copy.deepcopy(self._desc)

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

    def episode_metrics(self) -> dict:
        """rms/peak % position error of the episode so far (see the module docstring).

        Returns
        -------
        dict
            ``rms_error_pct`` and ``peak_error_pct`` (float, % of the reference amplitude) over the
            whole cycles after the first, or over every sample so far when the episode has not reached
            them, and ``metric_complete`` (bool, False in that case).
        """
        return parts.episode_metrics(self._X, self._C)

    def _info(self) -> dict:
        return dict(zip(bk.RAW_NAMES, self._raw.tolist()))

    def _external_act(self) -> float:
        raw = self._raw
        meas = {key: float(raw[j]) for key, j in zip(_META_KEYS, _META_RAW)}
        # the reference, as Plant's closed loop gives it (learning controllers index their cycle by the frequency)
        meas["amplitude_deg"] = float(self._C[bk.C_AMP])
        meas["freq_hz"] = float(self._desc["episode"]["freq_hz"])
        u = float(self.controller.act(meas))
        if not math.isfinite(u):
            raise ValueError(f"controller {type(self.controller).__name__} returned a non-finite current {u!r} "
                             f"at t = {meas['t']:g} s")
        return u

    def _end_step(self, flags: int, reward: float, a: float):
        if flags & bk.FLAG_BAD_ACTION:
            raise ValueError(f"action {a!r} is not finite: expected a normalised current in [-1, 1] "
                             "(NaN and inf are refused, out-of-range values are clipped)")
        terminated = bool(flags & _ENDED)
        truncated = bool(flags & bk.FLAG_TRUNCATED) and not terminated
        info = self._info()
        info.update(self.episode_metrics())
        info["episode_steps"] = int(self._X[bk.X_K])
        if self._long is not None:
            from ehas_env.simulation.long_test import long_test_metrics

            tr = np.array(self._long_trace, dtype=float).reshape(-1, 2)
            try:
                info.update(long_test_metrics(tr[:, 0], tr[:, 1], np.zeros(len(tr)), self._C[bk.C_AMP],
                                              self._desc["episode"]["freq_hz"]))
                info["long_test_complete"] = True
            except (ValueError, IndexError):  # ended before N cycles (stroke end)
                info["long_test_complete"] = False
        if flags & bk.FLAG_NONFINITE:
            info["termination"] = "non_finite_state"
        elif flags & bk.FLAG_STROKE_END:
            info["termination"] = "stroke_end"
        else:
            info["termination"] = None
        return self._obs.copy(), float(reward), terminated, truncated, info


def _action_value(action) -> float:
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action must be a number or an array of one number in [-1, 1], got {action!r}") from None
    if arr.size != 1:
        raise ValueError(f"action must hold exactly one value (normalised current in [-1, 1]), got shape {arr.shape}")
    return float(arr.reshape(-1)[0])


class _Trace:
    """The last few seconds of (t, theta, theta_ref) for rendering."""

    def __init__(self, n: int):
        self.data = np.full((n, 3), np.nan)
        self.i = 0

    def add(self, raw):
        self.data[self.i % self.data.shape[0]] = (raw[bk.R_T], raw[bk.R_THETA], raw[bk.R_REF])
        self.i += 1

    def ordered(self) -> np.ndarray:
        n = self.data.shape[0]
        if self.i <= n:
            return self.data[:self.i]
        j = self.i % n
        return np.concatenate([self.data[j:], self.data[:j]])


class _Renderer:
    """Crank dial and traces drawn with matplotlib's Agg canvas (no screen needed)."""

    def __init__(self, theta_end_deg: float):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.fig = Figure(figsize=(6.4, 3.2), dpi=100)
        self.canvas = FigureCanvasAgg(self.fig)
        self.ax_dial = self.fig.add_axes((0.02, 0.1, 0.36, 0.8))
        self.ax_tr = self.fig.add_axes((0.5, 0.17, 0.47, 0.7))
        ax = self.ax_dial
        ax.set_aspect("equal")
        ax.set_xlim(-1.2, 1.2)
        ax.set_ylim(-1.2, 1.2)
        ax.axis("off")
        circ = np.linspace(0, 2 * np.pi, 200)
        ax.plot(np.cos(circ), np.sin(circ), color="0.6", lw=1)
        end = math.radians(theta_end_deg)
        for sgn in (-1.0, 1.0):  # stroke ends; theta = 0 points up, positive clockwise
            ax.plot([0.9 * math.sin(sgn * end), 1.1 * math.sin(sgn * end)],
                    [0.9 * math.cos(sgn * end), 1.1 * math.cos(sgn * end)], color="red", lw=2)
        (self.pos_line,) = ax.plot([0, 0], [0, 1], "-", color="tab:blue", lw=3, label="crank")
        (self.ref_line,) = ax.plot([0, 0], [0, 1], "--", color="tab:orange", lw=2, label="reference")
        ax.plot([0], [0], "o", color="k")
        self.text = ax.text(0.0, -1.18, "", ha="center", va="bottom", fontsize=8)
        tr = self.ax_tr
        (self.pos_tr,) = tr.plot([], [], "-", color="tab:blue", lw=2.0, label="theta")
        (self.ref_tr,) = tr.plot([], [], "--", color="tab:orange", lw=1.2, label="theta_ref")
        tr.set_xlabel("t [s]", fontsize=8)
        tr.set_ylabel("deg", fontsize=8)
        tr.tick_params(labelsize=7)
        tr.set_ylim(-1.05 * theta_end_deg, 1.05 * theta_end_deg)
        tr.legend(loc="upper right", fontsize=7)
        self._window = None

    def draw(self, trace: _Trace, amp: float) -> np.ndarray:
        d = trace.ordered()
        t, th, ref = d[-1]
        for line, ang in ((self.pos_line, th), (self.ref_line, ref)):
            a = math.radians(ang)
            line.set_data([0.0, math.sin(a)], [0.0, math.cos(a)])
        self.text.set_text(f"t = {t:.3f} s   e = {ref - th:+.3f} deg ({100 * (ref - th) / amp:+.2f} %)")
        self.ref_tr.set_data(d[:, 0], d[:, 2])
        self.pos_tr.set_data(d[:, 0], d[:, 1])
        self.ax_tr.set_xlim(max(0.0, t - 2.0), max(t, 2.0))
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[:, :, :3].copy()

    def show(self, frame: np.ndarray, pause: float):
        import matplotlib.pyplot as plt

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # non-interactive backends (Agg) cannot show
            if self._window is None:
                fig = plt.figure("ehas/Tracking-v0", figsize=(6.4, 3.2))
                ax = fig.add_axes((0, 0, 1, 1))
                ax.axis("off")
                self._window = (fig, ax.imshow(frame))
                plt.show(block=False)
            fig, img = self._window
            img.set_data(frame)
            fig.canvas.draw_idle()
            plt.pause(pause)

    def close(self):
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None


class MeasurementObserver:
    """The environment's observation and current, from the controller interface's measurement.

    Lets a policy trained on the environment act as a controller (``act(measurement)
    -> mA``) in ``Plant.simulate_closed_loop``, the benchmark or on the rig:
    :meth:`observation` builds the observation the environment gives for the
    measurement (keys ``t, theta_deg, theta_ref_deg, theta_ref_dot, theta_ref_ddot,
    theta_ref_dddot, p_a_bar, p_b_bar, p_s_bar``; ``theta_deg`` is the sensed angle),
    :meth:`current` turns the policy's action into mA as the environment does
    (the residual mode's base controller included).  Call :meth:`reset` before a
    run, then :meth:`observation` and :meth:`current` once per sample.

    The reference preview and the error's normaliser (the amplitude) come from
    ``reference`` when it is known (or :meth:`set_reference`); otherwise they are
    inferred from the measurement's reference derivatives, exactly for a sine
    once its fade-in cycle is over (the cycle the % error excludes); during the
    fade-in the amplitude is the environment's episode amplitude and the preview
    a third-order Taylor extrapolation.

    Parameters
    ----------
    env : TrackingEnv (or a wrapper of one)
        Supplies the settings: scales, preview, dt, the base controller.
    reference : SineReference or MultiSine, optional
        The reference the measurements follow.

    Examples
    --------
    >>> from ehas_env.simulation.plant import Plant
    >>> from ehas_env.simulation.reference import SineReference
    >>> env = TrackingEnv()
    >>> obs_of = MeasurementObserver(env, SineReference(20.0, 1.0))
    >>> class Zero:
    ...     def reset(self): obs_of.reset()
    ...     def act(self, m): return obs_of.current(0.0 * obs_of.observation(m)[0], m)
    >>> run = Plant().simulate_closed_loop(Zero(), amplitude_deg=20.0, freq_hz=1.0, cycles=2)
    >>> float(abs(run.theta_deg).max())
    0.0
    """

    def __init__(self, env, reference=None):
        env = getattr(env, "unwrapped", env)
        st = env._st
        C = env._C
        self.dt = st.dt
        self.preview = st.preview_s
        self.mode = st.mode
        self.gains = np.asarray(st.gains, dtype=float)
        self.law = all_laws()[st.law][1]
        self._model = env._model
        self.base = env.controller
        self.th_scale = float(C[bk.C_TH_SCALE])
        self.p_scale_bar = float(C[bk.C_P_SCALE]) / 1.0e5
        self.act_scale = float(C[bk.C_ACT_SCALE])
        self.u_max = float(C[bk.C_UMAX])
        self._default_amp = float(C[bk.C_AMP])
        self.set_reference(reference)
        self.reset()

    def set_reference(self, reference) -> None:
        """Use ``reference`` (None: infer it from the measurements)."""
        if reference is None:
            self._vecs, self._amp = None, None
        else:
            self._vecs = parts.reference_components(reference)
            self._amp = float(reference.amplitude_deg)

    def reset(self) -> None:
        self._th_prev = None
        self._a_prev = 0.0
        self._u_prev = 0.0
        self._mem = np.zeros(N_MEM)
        self._amp_est = self._default_amp
        if self.mode == bk.MODE_EXTERNAL and callable(getattr(self.base, "reset", None)):
            self.base.reset()

    def _reference(self, m) -> tuple[float, list]:
        t = float(m["t"])
        if self._vecs is not None:
            prev = [sum(self._model.reference_point(v, t + d)[0] for v in self._vecs) for d in self.preview]
            return self._amp, prev
        r, rd, rdd, rddd = (float(m[k]) for k in ("theta_ref_deg", "theta_ref_dot", "theta_ref_ddot", "theta_ref_dddot"))
        den = rd * rd - r * rdd  # A^2 w^2 for a sine
        num = rdd * rdd - rd * rddd  # A^2 w^4
        scale = abs(r * rddd) + abs(rd * rdd)
        if den > 0.0 and num > 0.0 and abs(r * rddd - rd * rdd) <= 1e-9 * scale:  # a pure sine: r d3r = dr d2r
            w = math.sqrt(num / den)
            self._amp_est = math.sqrt(r * r + (rd / w) ** 2)
            return self._amp_est, [r * math.cos(w * d) + rd / w * math.sin(w * d) for d in self.preview]
        # fading in (or not a sine): the last amplitude seen (the env's until then), a Taylor preview
        return self._amp_est, [r + d * (rd + d * (rdd / 2.0 + d * rddd / 6.0)) for d in self.preview]

    def observation(self, m: dict) -> np.ndarray:
        """The observation (float32) the environment gives at the measurement ``m``."""
        th = float(m["theta_deg"])
        r = float(m["theta_ref_deg"])
        amp, prev = self._reference(m)
        omega = 0.0 if self._th_prev is None else (th - self._th_prev) / self.dt
        self._th_prev = th
        v = [(r - th) / amp, th / self.th_scale, omega / parts.V_SCALE_DEG_S, r / self.th_scale,
             float(m["theta_ref_dot"]) / parts.V_SCALE_DEG_S, float(m["theta_ref_ddot"]) / parts.A_SCALE_DEG_S2,
             *[p / self.th_scale for p in prev],
             2.0 * float(m["p_a_bar"]) / self.p_scale_bar - 1.0, 2.0 * float(m["p_b_bar"]) / self.p_scale_bar - 1.0]
        obs = np.clip(np.array(v + [0.0, 0.0]), -parts.OBS_CLIP, parts.OBS_CLIP)
        obs[-2] = self._a_prev
        obs[-1] = min(max(self._u_prev / self.act_scale, -parts.OBS_CLIP), parts.OBS_CLIP)
        return obs.astype(np.float32)

    def current(self, action, m: dict) -> float:
        """The current (mA) the environment commands for ``action`` at the measurement ``m``."""
        a = _action_value(action)
        if not math.isfinite(a):
            raise ValueError(f"action {a!r} is not finite: expected a normalised current in [-1, 1]")
        a = min(max(a, -1.0), 1.0)
        if self.mode == bk.MODE_RIG:
            u_base = self._rig_law(m)
        elif self.mode == bk.MODE_EXTERNAL:
            u_base = min(max(float(self.base.act(m)), -self.u_max), self.u_max)
        else:
            u_base = 0.0
        self._a_prev = a
        self._u_prev = u_base
        return min(max(u_base + a * self.act_scale, -self.u_max), self.u_max)

    def _rig_law(self, m) -> float:
        """The compiled base controller's law, run in Python on the measurement."""
        return self.law(self.gains, self._mem, float(m["t"]), self.dt, float(m["theta_deg"]), float(m["theta_ref_deg"]),
                        float(m["theta_ref_dot"]), float(m["theta_ref_ddot"]), float(m["theta_ref_dddot"]),
                        float(m["p_a_bar"]) - float(m["p_b_bar"]), float(m.get("p_s_bar", 0.0)), self.u_max)
