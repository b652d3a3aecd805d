"""Replaceable parts of the tracking environment: references, episodes, randomisation.

The environment (:mod:`ehas_env.env.tracking_env`) and its batched twin
(:mod:`ehas_env.env.vector_env`) share these parts, so an episode drawn from the
same seed is the same episode in both:

* reference generators (a sine, a sum of sines) and their encoding for the
  compiled step (:func:`reference_components`);
* the episode's settings (:class:`Episode`), merged from the constructor's
  defaults, ``reset(options=...)`` and randomisation ranges
  (:func:`draw_episode`);
* the packing of an episode into the compiled step's constant row
  (:func:`pack_episode`), which builds the plant through
  :class:`ehas_env.simulation.plant.Plant` so that every effect works in the environment.

Examples
--------
>>> import numpy as np
>>> ep = draw_episode({"amplitude_deg": 10.0}, {"randomise": {"disc_sets": (1, 7)}}, np.random.default_rng(0))
>>> ep.amplitude_deg, 1 <= ep.disc_sets <= 7
(10.0, True)
>>> MultiSine((SineReference(10.0, 1.0), SineReference(5.0, 3.0))).amplitude_deg
15.0
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ehas_env.env import batch_kernel as bk
from ehas_env.physics import layout as K
from ehas_env.physics.effects import get_effect, resolve_effects
from ehas_env.simulation.control_laws import compiled_form
from ehas_env.simulation.metrics import percent_errors, steady_window
from ehas_env.simulation.plant import Plant, RigController
from ehas_env.simulation.reference import SineReference, check_amplitude
from ehas_env.physics.rig import MAX_SETS, MIN_SETS, RATED_CURRENT, check_disc_sets
from ehas_env.simulation.sensors import Sensors

#: observation scales (deg/s, deg/s^2): the rig's design point, +-30 deg at 3 Hz (rig.md)
V_SCALE_DEG_S = 30.0 * 2.0 * math.pi * 3.0
A_SCALE_DEG_S2 = 30.0 * (2.0 * math.pi * 3.0) ** 2
#: normalised observations are clipped to +-OBS_CLIP (only abnormal states reach it)
OBS_CLIP = 10.0
#: the episode settings a user may give (constructor kwargs and reset options)
EPISODE_KEYS = ("disc_sets", "amplitude_deg", "freq_hz", "cycles", "effects", "sensors", "theta0_deg", "reference")
#: the settings that accept a randomisation range
RANDOMISABLE = ("disc_sets", "amplitude_deg", "freq_hz", "cycles", "theta0_deg", "effects")


# ---------------------------------------------------------------------------
# references
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class MultiSine:
    """A sum of sines, theta_ref = sum_j A_j sin(2 pi f_j t + phi_j), deg.

    ``amplitude_deg`` (the % error's normaliser) is the sum of the amplitudes,
    ``freq_hz`` (the % error's cycle) the lowest frequency.

    Examples
    --------
    >>> ms = MultiSine((SineReference(10.0, 1.0, ramp_cycles=0), SineReference(5.0, 2.0, phase=1.0, ramp_cycles=0)))
    >>> r, rd, rdd = ms(0.0)
    >>> round(float(r), 6) == round(5.0 * math.sin(1.0), 6)
    True
    """

    components: tuple

    def __post_init__(self):
        comps = tuple(self.components)
        if not 1 <= len(comps) <= bk.MAX_COMPONENTS or not all(isinstance(c, SineReference) for c in comps):
            raise ValueError(f"MultiSine: components must be 1..{bk.MAX_COMPONENTS} SineReference objects, got {comps!r}")
        object.__setattr__(self, "components", comps)
        check_amplitude(self.amplitude_deg)

    @property
    def amplitude_deg(self) -> float:
        return float(sum(c.amplitude_deg for c in self.components))

    @property
    def freq_hz(self) -> float:
        return float(min(c.freq_hz for c in self.components))

    def __call__(self, t):
        """(theta_ref, theta_ref', theta_ref'') at t, deg, deg/s, deg/s^2."""
        parts = [c(t) for c in self.components]
        return tuple(sum(p[j] for p in parts) for j in range(3))


def reference_components(ref) -> list[np.ndarray]:
    """The kernel vector (amplitude deg, f Hz, phase rad, fade-in s) of each sine of ``ref``.

    The compiled step evaluates a sum of sines (kind ``REF_SUM_OF_SINES``), each
    by ``kernel.reference_point``; a new kind of reference (a chirp) adds a
    kind code and its block there.
    """
    comps = ref.components if isinstance(ref, MultiSine) else (ref,)
    if not all(isinstance(c, SineReference) for c in comps):
        raise ValueError(f"reference must be a SineReference or a MultiSine, got {ref!r}")
    return [np.asarray(c.kernel_vector(), dtype=float) for c in comps]


# ---------------------------------------------------------------------------
# episodes
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Episode:
    """The settings of one episode (validated).

    Attributes
    ----------
    disc_sets : int
        Disc sets on the crank, 1..7 (0.383 kg m^2 each, book).
    amplitude_deg, freq_hz : float
        Sine reference theta_ref = amplitude sin(2 pi f t), deg and Hz.
    cycles : float
        Episode length in reference periods (the % error needs >= 2 whole cycles).
    effects : dict
        Effects switched on, resolved to {name: {param: value}}.
    sensors : Sensors
        Measurement chain (ideal by default).
    theta0_deg : float
        Crank angle at the start (at rest, P_A = P_B = Ps/2), deg.
    reference : SineReference or MultiSine or None
        Overrides ``amplitude_deg``/``freq_hz`` when given.
    noise_seed : int
        Seed of the episode's sensor-noise stream (drawn from the env's RNG).
    """

    disc_sets: int = 3
    amplitude_deg: float = 20.0
    freq_hz: float = 1.0
    cycles: float = 3.0
    effects: dict = field(default_factory=dict)
    sensors: Sensors = field(default_factory=Sensors.ideal)
    theta0_deg: float = 0.0
    reference: object = None
    noise_seed: int = 0

    @property
    def ref(self):
        """The reference generator of the episode."""
        return self.reference if self.reference is not None else SineReference(self.amplitude_deg, self.freq_hz)

    def to_dict(self) -> dict:
        ref = self.ref
        return {"disc_sets": self.disc_sets, "amplitude_deg": ref.amplitude_deg, "freq_hz": ref.freq_hz,
                "cycles": self.cycles, "effects": self.effects, "sensors": self.sensors.to_dict(),
                "theta0_deg": self.theta0_deg, "reference": repr(ref)}


def _number(name, value, lo=-math.inf, hi=math.inf, lo_open=False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < lo or v > hi or (lo_open and v == lo):
        raise ValueError(f"{name} = {value!r} is outside its range {'(' if lo_open else '['}{lo:g}, {hi:g}]")
    return v


def _sensors(value) -> Sensors:
    if value is None or value == "ideal":
        return Sensors.ideal()
    if value == "realistic":
        return Sensors()
    if isinstance(value, Sensors):
        return value
    if isinstance(value, dict):
        try:
            return Sensors(**value)
        except TypeError as exc:
            raise ValueError(f"sensors: {exc}; fields are those of ehas_env.simulation.sensors.Sensors") from None
    raise ValueError(f"sensors must be 'ideal', 'realistic', a Sensors or a dict of its fields, got {value!r}")


def _range(name, spec, lo=-math.inf, hi=math.inf):
    if not (isinstance(spec, (tuple, list)) and len(spec) == 2):
        raise ValueError(f"randomise['{name}'] must be a (low, high) pair or a list of >= 3 values, got {spec!r}")
    a = _number(f"randomise['{name}'] low", spec[0], lo, hi)
    b = _number(f"randomise['{name}'] high", spec[1], lo, hi)
    if a > b:
        raise ValueError(f"randomise['{name}']: low {a:g} is above high {b:g}")
    return a, b


def _choices(name, spec, lo=-math.inf, hi=math.inf):
    """The values of a list of >= 3 choices, or None for a (low, high) range."""
    if isinstance(spec, (tuple, list)) and len(spec) >= 3:
        return [_number(f"randomise['{name}'] value", v, lo, hi) for v in spec]
    return None


def _draw(name, spec, rng, lo=-math.inf, hi=math.inf, log=False, integer=False) -> float:
    """One value from a range (uniform, log-uniform if ``log``) or from a list of choices."""
    values = _choices(name, spec, lo, hi)
    if values is not None:
        return values[int(rng.integers(len(values)))]
    a, b = _range(name, spec, lo, hi)
    if integer:
        return int(rng.integers(math.ceil(a), math.floor(b) + 1))
    if log and a > 0.0:
        return float(math.exp(rng.uniform(math.log(a), math.log(b))))
    return float(rng.uniform(a, b))


def _draw_effects(spec, rng) -> dict:
    """Effects with parameters drawn from their ranges (uniform; log-uniform for log-scale ones)."""
    if not isinstance(spec, dict):
        raise ValueError(f"randomise['effects'] must map effect names to 'typical' or {{param: (low, high)}}, got {spec!r}")
    out = {}
    for name, params in spec.items():
        eff = get_effect(name)
        if params == "typical":
            params = {p.name: p.typical for p in eff.params if p.typical is not None}
        if not isinstance(params, dict):
            raise ValueError(f"randomise['effects']['{name}'] must be 'typical' or {{param: (low, high)}}, got {params!r}")
        for key in params:
            eff.param(key)  # names an unknown parameter
        # a draw that breaks the effect's own constraints (Stribeck: breakaway >= sliding force) is
        # drawn again: the ranges of two parameters can overlap where their values may not
        for _attempt in range(100):
            values = {}
            for p in eff.params:  # the effect's order, not the user's: same draws for the same ranges
                if p.name not in params:
                    continue
                r = params[p.name]
                if isinstance(r, (int, float)):
                    values[p.name] = float(r)
                    continue
                values[p.name] = _draw(f"effects.{name}.{p.name}", r, rng, *p.bounds, log=p.log_scale)
            try:
                eff.resolve(values)
                break
            except ValueError as exc:
                error = exc
        else:
            raise ValueError(f"randomise['effects']['{name}']: 100 draws from {params} all broke the effect's "
                             f"constraints ({error})")
        out[name] = values
    return out


def draw_episode(defaults: dict, options: dict | None, rng: np.random.Generator) -> Episode:
    """The episode for ``reset(options=...)``: defaults, then options, then random draws.

    ``defaults`` and ``options`` hold :data:`EPISODE_KEYS` and ``randomise``:
    ``{"disc_sets": (1, 7), "amplitude_deg": (5, 30), "freq_hz": [1, 2, 3],
    "cycles": (2, 4), "theta0_deg": (-5, 5), "effects": {"coulomb_friction": {"Fc": (150, 600)},
    "viscous_friction": "typical"}}``.  A pair is a range (uniform; integers for
    ``disc_sets``; log-uniform for an effect's log-scale parameters), a list of
    three or more values a set of equally likely choices, ``"typical"`` an
    effect's realistic ranges (``Param.typical``).  Options hold for one
    episode only; a randomised setting overrides the fixed one.  The draws use
    ``rng`` in a fixed order, so the same seed gives the same episode.
    """
    opts = dict(options or {})
    opts.pop("reset_mask", None)  # vector envs only
    allowed = EPISODE_KEYS + ("randomise",)
    for key in opts:
        if key not in allowed:
            raise ValueError(f"unknown episode option '{key}'; options are: {', '.join(allowed)}")
    cfg = {**defaults, **opts}
    randomise = cfg.pop("randomise", None) or {}
    if not isinstance(randomise, dict):
        raise ValueError(f"randomise must be a dict of ranges, got {randomise!r}")
    for key in randomise:
        if key not in RANDOMISABLE:
            raise ValueError(f"randomise: '{key}' cannot be randomised; randomisable: {', '.join(RANDOMISABLE)}")
    for key in RANDOMISABLE:  # fixed order: reproducible draws
        if key not in randomise:
            continue
        spec = randomise[key]
        if key == "disc_sets":
            cfg[key] = int(_draw(key, spec, rng, MIN_SETS, MAX_SETS, integer=True))
        elif key == "effects":
            drawn = _draw_effects(spec, rng)
            merged = dict(resolve_effects(cfg.get("effects")))
            for name, values in drawn.items():
                merged[name] = {**merged.get(name, {}), **values}
            cfg[key] = merged
        else:
            cfg[key] = _draw(key, spec, rng)
    noise_seed = int(rng.integers(0, 2**52))

    check_disc_sets(cfg.get("disc_sets", 3))
    ref = cfg.get("reference")
    if ref is not None:
        reference_components(ref)
    else:
        SineReference(cfg.get("amplitude_deg", 20.0), cfg.get("freq_hz", 1.0))  # validates both
    effects = resolve_effects(cfg.get("effects"))
    for name in effects:
        if get_effect(name).kind == "hypothesis":
            # the environments' compiled model leaves the diagnosis' hypotheses out (compile time)
            raise ValueError(f"effects: '{name}' is a structural hypothesis of the diagnosis, not an effect the "
                             "environments simulate; write it as your own effect file (ehas diagnose CAMPAIGN "
                             "--write-effect DIR/NAME.py) and load it with effects_path")
    return Episode(
        disc_sets=int(cfg.get("disc_sets", 3)),
        amplitude_deg=_number("amplitude_deg", cfg.get("amplitude_deg", 20.0)),
        freq_hz=_number("freq_hz", cfg.get("freq_hz", 1.0)),
        cycles=_number("cycles", cfg.get("cycles", 3.0), 0.0, 1.0e6, lo_open=True),
        effects=effects,
        sensors=_sensors(cfg.get("sensors")),
        theta0_deg=_number("theta0_deg", cfg.get("theta0_deg", 0.0), -40.0, 40.0),
        reference=ref,
        noise_seed=noise_seed,
    )


# ---------------------------------------------------------------------------
# controllers
# ---------------------------------------------------------------------------
def controller_mode(controller, dt: float) -> tuple[int, np.ndarray]:
    """(mode code, gains) of the residual mode's base controller.

    ``None``: no base controller (the action is the current).  A
    :class:`~ehas_env.simulation.plant.RigController`: compiled into the step.  Any object
    with ``act(measurement) -> mA``: called in Python every step.
    """
    gains = np.zeros(bk.N_GAIN_SLOTS)
    if controller is None:
        return bk.MODE_DIRECT, gains, 0
    compiled = compiled_form(controller)
    if compiled is not None:
        rate = getattr(controller, "rate_hz", getattr(compiled, "rate_hz", 1.0 / dt))
        if abs(rate * dt - 1.0) > 1e-9:
            raise ValueError(f"controller rate_hz {rate:g} must equal the env's 1/dt = {1 / dt:g} Hz")
        g = np.asarray(compiled.gains_vector(), dtype=float)
        gains[:g.size] = g
        return bk.MODE_RIG, gains, int(compiled.law_id())
    if callable(getattr(controller, "act", None)):
        return bk.MODE_EXTERNAL, gains, 0
    raise ValueError("controller must have a compiled law (law_id() and gains_vector(), or rig_gains()) or "
                     f"act(measurement) -> mA, got {controller!r}")


# ---------------------------------------------------------------------------
# packing for the compiled step
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class StepSettings:
    """What stays fixed for an environment's life (constructor arguments).

    Attributes
    ----------
    dt : float
        Control period, s (rig: 1 ms).
    substeps : int
        RK4 sub-steps per period (>= 10: the chambers are stiff).
    mode : int
        Base-controller mode (:func:`controller_mode`).
    gains : ndarray
        The compiled base controller's gains (mode ``MODE_RIG``).
    law : int
        Its compiled law's number (``control_laws.law_id``).
    rate_penalty : float
        Weight of the action-rate term of the reward.
    termination_penalty : float
        Reward charged per remaining step when the episode terminates early.
    preview_s : tuple of float
        Reference preview offsets, s.
    plant_kwargs : dict
        Extra keyword arguments for :class:`~ehas_env.simulation.plant.Plant` (``rig=``,
        ``inertia=``: the hook for a calibrated model).
    """

    dt: float = 1.0e-3
    substeps: int = 10
    mode: int = bk.MODE_DIRECT
    gains: np.ndarray = field(default_factory=lambda: np.zeros(bk.N_GAIN_SLOTS))
    law: int = 0
    rate_penalty: float = 0.01
    termination_penalty: float = 1.0
    preview_s: tuple = (0.01, 0.02, 0.05)
    plant_kwargs: dict = field(default_factory=dict)

    @property
    def n_obs(self) -> int:
        return bk.N_OBS_BASE + len(self.preview_s)


def episode_steps(ep: Episode, dt: float) -> int:
    """Number of control periods of the episode (``cycles`` reference periods)."""
    return max(1, int(round(ep.cycles / ep.ref.freq_hz / dt)))


def pack_episode(ep: Episode, st: StepSettings) -> tuple[np.ndarray, dict]:
    """The compiled step's constant row for ``ep``, and a description for ``info``."""
    plant = Plant(ep.disc_sets, ep.effects, sensors=ep.sensors, dt=st.dt, substeps=st.substeps, **st.plant_kwargs)
    rig = plant.rig
    ref = ep.ref
    comps = reference_components(ref)
    n = episode_steps(ep, st.dt)
    t = np.arange(n) * st.dt  # the samples the benchmark scores (t_0 .. t_{n-1}): one window for every metric
    try:
        idx = np.flatnonzero(steady_window(t, ref.freq_hz))
        win0, win1, complete = int(idx[0]), int(idx[-1]) + 1, True
    except (ValueError, IndexError):
        win0, win1, complete = -1, n + 1, False  # under 2 whole cycles: every sample (win0 < 0 flags it)
    C = np.zeros(bk.C_P + plant.model.N_SLOTS)
    C[bk.C_P:] = plant.param_vector
    C[bk.C_LAW] = st.law
    C[bk.C_DT] = st.dt
    C[bk.C_NSUB] = st.substeps
    C[bk.C_MODE] = st.mode
    C[bk.C_ACT_SCALE] = RATED_CURRENT
    C[bk.C_UMAX] = rig.i_max
    C[bk.C_GAINS:bk.C_GAINS + bk.N_GAIN_SLOTS] = st.gains
    C[bk.C_ADC] = ep.sensors.theta_lsb
    C[bk.C_DAC] = ep.sensors.current_lsb
    C[bk.C_GAIN_ERR] = ep.sensors.lvdt_gain_error
    C[bk.C_NOISE_STD] = ep.sensors.theta_noise_deg
    C[bk.C_SEED] = ep.noise_seed
    C[bk.C_AMP] = ref.amplitude_deg
    C[bk.C_REF_KIND] = bk.REF_SUM_OF_SINES
    C[bk.C_NCOMP] = len(comps)
    for j, vec in enumerate(comps):
        if vec.size != bk.N_REF:
            raise ValueError(f"reference kernel vector {vec!r} must hold {', '.join(bk.REF_FIELDS)}")
        C[bk.C_COMP + bk.N_REF * j:bk.C_COMP + bk.N_REF * (j + 1)] = vec
    C[bk.C_NSTEPS] = n
    C[bk.C_WIN0] = win0
    C[bk.C_WIN1] = win1
    C[bk.C_RATE_W] = st.rate_penalty
    C[bk.C_TERM_W] = st.termination_penalty
    C[bk.C_TH_SCALE] = math.degrees(rig.theta_stroke_end)
    C[bk.C_V_SCALE] = V_SCALE_DEG_S
    C[bk.C_A_SCALE] = A_SCALE_DEG_S2
    C[bk.C_P_SCALE] = rig.supply
    C[bk.C_OBS_CLIP] = OBS_CLIP
    C[bk.C_NPREV] = len(st.preview_s)
    C[bk.C_PREV:bk.C_PREV + len(st.preview_s)] = st.preview_s
    s0 = plant.initial_state(ep.theta0_deg)
    if s0.size > bk.MAX_STATES:
        raise ValueError(f"the model has {s0.size} states; the environment holds at most {bk.MAX_STATES}")
    C[bk.C_S0:bk.C_S0 + s0.size] = s0
    desc = {"episode": ep.to_dict(), "episode_steps": n, "metric_window_s": (max(win0, 0) * st.dt, (win1 - 1) * st.dt),
            "metric_window_complete": complete}
    return C, desc


def episode_metrics(X: np.ndarray, C: np.ndarray) -> dict:
    """rms and peak % position error of the episode so far (docs/metric.md).

    Over the whole cycles after the first when the episode has reached them;
    otherwise (an early end) over every sample so far, flagged by
    ``metric_complete = False``.
    """
    complete = C[bk.C_WIN0] >= 0 and X[bk.X_K] + 1 >= C[bk.C_WIN1] and X[bk.X_NW] > 0
    if complete:
        s, n, m = X[bk.X_SUMW], X[bk.X_NW], X[bk.X_MAXW]
    else:
        s, n, m = X[bk.X_SUMA], X[bk.X_NA], X[bk.X_MAXA]
    return {**percent_errors(float(s), float(n), float(m), float(C[bk.C_AMP])), "metric_complete": bool(complete)}
