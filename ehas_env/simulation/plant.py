"""The reference plant: one API for every simulation in the project.

Identified servo valve (amplifier and spool limits) -> per-land orifice law ->
compressible chambers -> actuator -> 50 mm crank -> disc inertia, with stroke
ends, exactly as the project's reference model (README, "Plant model") says,
plus any effects of the library switched on by name.

Examples
--------
>>> from ehas_env.simulation.plant import Plant, RigController
>>> plant = Plant(disc_sets=5, effects={"coulomb_friction": {"Fc": 300}})
>>> run = plant.simulate_closed_loop(RigController.book(), amplitude_deg=20, freq_hz=1, cycles=3)
>>> run.tracking_errors()["rms_error_pct"] < 2.0
True
>>> round(float(run.theta_deg.max()), 0)
20.0
"""
from __future__ import annotations

import math
import numbers
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ehas_env.physics import layout as K
from ehas_env.simulation.compiled_model import current_model, names_hypothesis
from ehas_env.physics.effects import REGISTRY, get_effect, resolve_effects
from ehas_env.physics.effects.base import effect_slots, mark_effects_on
from ehas_env.ranges import MAX_SAMPLES, check_field, check_number, check_run_length, check_samples
from ehas_env.simulation.finite import check_run
from ehas_env.simulation.control_laws import compiled_form
from ehas_env.simulation.metrics import tracking_errors
from ehas_env.simulation.rig_controller import RigController  # noqa: F401  (Plant's default controller; imported from here too)
from ehas_env.simulation.reference import SineReference
from ehas_env.physics.rig import BAR, LPM, INERTIA_PER_SET, RigParams
from ehas_env.simulation.sensors import Sensors

V_TANH = 1.0e-3  # m/s, friction sign smoothing of the friction effects (reference model: 1 mm/s)
TAU_MAX = 0.05  # s, longest transport delay the command buffers hold (transport_delay's bound)


@dataclass
class SimResult:
    """Outputs of one simulated run, engineering units.

    Attributes
    ----------
    t : ndarray
        Sample times, s.
    current_mA : ndarray
        Command current issued at t_k (held until t_k+1), mA.
    theta_deg : ndarray
        Crank angle as the LVDT shows it (asin(reading / r), the reading of the piston position through the
        sensor's effects, ``position_reading``), deg.
    omega_deg_s : ndarray
        Crank rate from the true piston velocity (asin(x/r))', deg/s.
    theta_crank_deg : ndarray
        True crank angle, deg (differs from theta_deg with backlash, a compliant load path or a sensor effect).
    flow_lpm : ndarray
        Valve flow in line A, LPM.
    p_a_bar, p_b_bar, p_s_bar : ndarray
        Chamber and supply pressures, bar.
    load_kN : ndarray
        A (P_A - P_B), kN.
    theta_ref_deg : ndarray or None
        Reference (closed-loop runs).
    stroke_end : ndarray of bool
        True where the piston touched a stroke end during the period.
    meta : dict
        What the run was (kind, disc_sets, supply_bar, reference, controller, effects, sensors).
    logged : dict
        The channels as the rig's DAQ would log them (sensor noise, quantization);
        equal to the physical outputs with ideal sensors.
    """

    t: np.ndarray
    current_mA: np.ndarray
    theta_deg: np.ndarray
    omega_deg_s: np.ndarray
    theta_crank_deg: np.ndarray
    flow_lpm: np.ndarray
    p_a_bar: np.ndarray
    p_b_bar: np.ndarray
    p_s_bar: np.ndarray
    load_kN: np.ndarray
    stroke_end: np.ndarray
    theta_ref_deg: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    logged: dict = field(default_factory=dict)

    @property
    def hit_stroke_end(self) -> bool:
        """True if the piston touched a stroke end at any sample of the run (any ``stroke_end``)."""
        return bool(np.any(self.stroke_end))

    def tracking_errors(self) -> dict[str, float]:
        """rms/peak % position error over whole cycles after the first (closed loop).

        Returns
        -------
        dict of str to float
            The metrics of :func:`ehas_env.simulation.metrics.tracking_errors` computed on the measured
            angle ``theta_deg`` against ``theta_ref_deg``, in percent of the reference amplitude
            (``rms_error_pct``, ``peak_error_pct``, ...).

        Raises
        ------
        ValueError
            If the run has no reference (an open-loop run).
        """
        if self.theta_ref_deg is None:
            raise ValueError("tracking_errors: this run has no reference (open-loop run)")
        ref = self.meta["reference"]
        return tracking_errors(self.t, self.theta_ref_deg, self.theta_deg, ref["amplitude_deg"], ref["freq_hz"])

    def columns(self, logged: bool = True) -> dict[str, np.ndarray]:
        """The run's columns in the measurement format (logged channels by default).

        Parameters
        ----------
        logged : bool
            True (default): the channels as the DAQ logged them (``logged``: sensor noise and
            quantization) replace the physical ones; False: the physical outputs.

        Returns
        -------
        dict of str to ndarray
            Column name -> samples, engineering units: ``t`` (s), ``current_mA`` (mA),
            ``theta_deg`` (deg), ``flow_lpm`` (LPM), ``p_a_bar``, ``p_b_bar``, ``p_s_bar`` (bar),
            ``load_kN`` (kN), and ``theta_ref_deg`` (deg) for a closed-loop run.
        """
        cols = {
            "t": self.t,
            "current_mA": self.current_mA,
            "theta_deg": self.theta_deg,
            "flow_lpm": self.flow_lpm,
            "p_a_bar": self.p_a_bar,
            "p_b_bar": self.p_b_bar,
            "p_s_bar": self.p_s_bar,
            "load_kN": self.load_kN,
        }
        if self.theta_ref_deg is not None:
            cols["theta_ref_deg"] = self.theta_ref_deg
        if logged:
            cols.update(self.logged)
        return cols



def at_rest(model, s: np.ndarray) -> np.ndarray:
    """``s`` with each effect's states that rest at a baseline state (``Effect.rests_at``: a hose's line pressure
    at its chamber's) set to that state's value; in place.

    Parameters
    ----------
    model : module
        A compiled model (its ``EFFECTS`` and ``STATE_NAMES``).
    s : ndarray
        A state vector of ``model`` whose baseline states are set.

    Returns
    -------
    ndarray
        ``s``.
    """
    names = model.STATE_NAMES
    for name in model.EFFECTS:  # (a proposal's terms are in EFFECTS too, no registered effect: no states)
        for own, base in getattr(REGISTRY.get(name), "rests_at", {}).items():
            s[names.index(f"{name}.{own}")] = s[names.index(base)]
    return s


class Plant:
    """The rig: baseline reference model plus effects, simulated at fixed step.

    Parameters
    ----------
    disc_sets : int
        Number of disc sets on the crank, 1..7 (0.383 kg m^2 each, book).
    effects : dict, list of str or str, optional
        Effects of the library to switch on: ``{"coulomb_friction": {"Fc": 300}}``,
        ``["viscous_friction"]`` (defaults) or ``"coulomb_friction:Fc=300"``.
    inertia : float, optional
        Load inertia in kg m^2, overriding ``disc_sets`` (1e-6 to 1e12; 1e9 holds the crank still).
    rig : RigParams, optional
        Baseline parameters (defaults: the book's rig).
    sensors : Sensors, optional
        Measurement chain; ideal (no noise, no quantization) by default.
    dt : float
        Control/sample period, s, 1e-6 to 0.01 (rig: 1 ms).
    substeps : int
        RK4 sub-steps per period, 1 to 1000 (>= 10 recommended: the chambers are stiff).
    seed : int, optional
        Seed of the sensor noise, 0 to 2**32 - 1; same seed -> bit-identical runs.
    valve : {"grey_box", "white_box"}
        The servo valve: the book's identified transfer function (default) or
        the first-principles model of :mod:`ehas_env.physics.white_box_valve` (torque
        motor, armature, nozzle-flapper, spool, feedback wire, flow forces).
        The ``valve_dynamics`` effect recalibrates the grey box only.
    white_box : WhiteBoxValve, optional
        Parameters of the white-box valve (default: the book's, see that module).
    effects_path : str, Path or list, optional
        Folders (or files) of user effect files to load first (see
        ``ehas_env.physics.effects.loading``).
    model : PlantModel, str or Path, optional
        A model file (or its :class:`~ehas_env.simulation.model_file.PlantModel`):
        the plant it describes (docs/model-file.md) - its rig, inertia per disc
        set, valve, effects and effects path.  ``rig``, ``inertia``, ``valve`` and
        ``white_box`` given as well override the model's; ``effects`` are added to
        the model's (same name: the values given here win).
    hypotheses : bool
        Run on the compiled model that also holds the diagnosis' structural hypotheses, even when no
        effect names one (a diagnosis compiles that one model for all its rounds).  A plant that names a
        hypothesis runs on it anyway.
    """

    VALVES = ("grey_box", "white_box")

    def __init__(self, disc_sets: int = 3, effects=None, *, inertia: float | None = None, rig: RigParams | None = None,
                 sensors: Sensors | None = None, dt: float = 1.0e-3, substeps: int = 10, seed: int | None = None,
                 valve: str = "grey_box", white_box=None, effects_path=None, model=None, hypotheses: bool = False):
        from ehas_env.physics.effects import load_effects_path

        _check_effects_path(effects_path)
        load_effects_path(effects_path)
        disc_sets = check_field("disc_sets", disc_sets)
        effects = _check_effects(effects)
        inertia_where = "inertia"
        if model is not None:  # a model file is the plant (ehas_env.simulation.model_file)
            from ehas_env.simulation.model_file import as_model

            model = as_model(model)  # data: its user effects must be loaded already (effects_path=)
            rig = rig if rig is not None else model.rig
            if inertia is None:
                inertia = float(disc_sets) * model.inertia_per_set
                inertia_where = f"inertia ({disc_sets} disc sets x the model's inertia_per_set_kgm2)"
            effects = {**model.effects, **resolve_effects(effects)}
            valve = model.valve if valve == "grey_box" else valve
            white_box = white_box if white_box is not None else model.white_box_valve()
        self.plant_model = model
        if valve not in self.VALVES:
            raise ValueError(f"valve must be one of {', '.join(self.VALVES)}, got {valve!r}")
        from ehas_env.physics.white_box_valve import WhiteBoxValve

        if white_box is not None and not isinstance(white_box, WhiteBoxValve):
            raise ValueError(f"white_box must be a WhiteBoxValve, got {type(white_box).__name__}")
        self.valve = valve
        self.white_box = white_box if white_box is not None else WhiteBoxValve()
        if rig is not None and not isinstance(rig, RigParams):
            raise ValueError(f"rig must be a RigParams (ehas_env.physics.rig), got {_brief(rig)}")
        rig = rig or RigParams()
        rig = rig.replace(disc_sets=int(disc_sets), inertia=disc_sets * INERTIA_PER_SET)
        if inertia is not None:
            rig = rig.replace(inertia=check_field("inertia_kgm2", inertia, inertia_where))
        dt = check_field("dt", dt)
        substeps = check_field("substeps", substeps)
        self.sensors = _check_sensors(sensors)
        self.seed = None if seed is None else check_field("seed", seed)
        self.rig = rig
        self.effects = resolve_effects(effects)
        self.dt = float(dt)
        self.substeps = substeps
        # every registered effect, so every resolved effect is in it (the diagnosis' structural hypotheses only
        # when one is used); the quick-to-compile build (no inlining): a plant replays, fits and runs single
        # simulations, where the compile, not the step, is the wait
        self._model = current_model(inline=False, hypotheses=bool(hypotheses) or names_hypothesis(self.effects))
        self._P = self._param_vector()
        self._hist_len = K.history_length(TAU_MAX, self.dt)

    def __repr__(self) -> str:
        eff = ", ".join(f"{n}({', '.join(f'{k}={v:g}' for k, v in p.items())})" for n, p in self.effects.items())
        valve = ", valve=white_box" if self.valve == "white_box" else ""
        return f"Plant(disc_sets={self.rig.disc_sets}, inertia={self.rig.inertia:g} kg m^2, effects=[{eff}]{valve})"

    # -- parameters -------------------------------------------------------
    @property
    def model(self):
        """The compiled model module this plant runs on (:mod:`ehas_env.physics.codegen`)."""
        return self._model

    def slots(self) -> dict[str, float]:
        """The model's parameter slots (SI) by name, with the effects applied.

        Returns
        -------
        dict of str to float
            Slot name (``model.SLOTS``) -> value in SI units (inertia in kg m^2, pressures in Pa,
            lengths in m, ...): the rig's baseline, the valve's, each effect's parameters after its
            ``apply`` and ``adjust`` for this plant's sub-step, and the effects' on-flags.
        """
        r = self.rig
        s = dict.fromkeys(self._model.SLOTS, 0.0)
        s.update(inertia=r.inertia, radius=r.radius, area=r.area, half_stroke=r.half_stroke, supply=r.supply,
                 rated_drop=r.rated_drop, beta=r.beta, dead_volume=r.dead_volume, K=r.K * LPM, wn=r.wn, zeta=r.zeta,
                 i_max=r.i_max, v_tanh=V_TANH)
        s.update(self.white_box.kernel_slots())
        s["valve_model"] = K.WHITE_BOX if self.valve == "white_box" else 0.0
        for name in self._model.EFFECTS:
            s.update(effect_slots(name, self.effects.get(name)))
        for name, values in self.effects.items():
            REGISTRY[name].apply(values, s)
        for name in self.effects:
            REGISTRY[name].adjust(s, self.dt / self.substeps)
        return mark_effects_on(s, self._model)

    def _param_vector(self) -> np.ndarray:
        s = self.slots()
        return np.array([s[name] for name in self._model.SLOTS], dtype=float)

    @property
    def param_vector(self) -> np.ndarray:
        """Copy of the flat parameter vector the compiled model uses (layout ``model.SLOTS``)."""
        return self._P.copy()

    def initial_state(self, theta_deg: float = 0.0) -> np.ndarray:
        """At rest where the LVDT reads ``theta_deg``, with P_A = P_B = Ps/2 (reference model).

        Parameters
        ----------
        theta_deg : float
            Initial crank angle as the sensor reads it, deg, in [-90, 90] (a log's first sample; the stroke
            ends lie inside).  With a sensor effect on (place ``position_reading``) the true piston position
            is the one the sensor reads so.

        Returns
        -------
        ndarray
            The model's state vector (layout ``model.STATE_NAMES``, SI units): crank angle in rad,
            zero rate, chamber pressures at half the supply pressure (Pa), the supply pressure, the
            piston position ``r sin(theta)`` in m, and each effect's states at their initial values.
        """
        check_number(theta_deg, "theta_deg", "deg", -90.0, 90.0)  # the crank's geometry; the stroke ends lie inside
        s = np.zeros(self._model.N_STATES)
        for name in self._model.EFFECTS:
            for st in REGISTRY[name].states:
                s[self._model.STATE_NAMES.index(f"{name}.{st[0]}")] = st[2]
        x = self._true_position(self.rig.radius * math.sin(math.radians(theta_deg)))
        x_off = self._P[K.I_XOFF]  # the crank's angle offset (hyp_crank_offset): the piston is r sin(theta) - x_off
        th = math.asin(min(max((x + x_off) / self.rig.radius, -1.0), 1.0))
        s[0] = th
        s[4] = s[5] = 0.5 * self.rig.supply
        s[6] = self.rig.supply
        s[7] = self.rig.radius * math.sin(th) - x_off
        return at_rest(self._model, s)

    def _true_position(self, reading: float) -> float:
        """The piston position at which the sensor reads ``reading`` (m): the sensor chain inverted by a secant
        iteration (the identity without sensor effects)."""
        # at most 32 calls: run in Python (numba's py_func), not compiled -- an environment's construction then
        # compiles nothing of the quick build (the sensor effects' own terms, if on, compile when called)
        fn = getattr(self._model.position_reading, "py_func", self._model.position_reading)
        P = self._P
        rest = np.zeros(self._model.N_STATES)  # a sensor effect's own states at rest (a lag's error: 0)

        def read(x, P):
            return fn(x, P, rest)
        x0, x1 = reading, reading - (read(reading, P) - reading)
        f0, f1 = read(x0, P) - reading, read(x1, P) - reading
        for _ in range(30):
            if f1 == 0.0 or f1 == f0:
                break
            x0, x1, f0 = x1, x1 - f1 * (x1 - x0) / (f1 - f0), f1
            f1 = read(x1, P) - reading
        return x1 if math.isfinite(x1) else reading

    # -- simulation -------------------------------------------------------
    def simulate(self, current_mA, *, theta0_deg: float = 0.0) -> SimResult:
        """Open loop: the command current sequence (mA, one value per period dt).

        Parameters
        ----------
        current_mA : array_like of float
            Command current in mA, one finite value per sample period ``dt`` (a 1-D sequence; each
            value is held for one period).
        theta0_deg : float
            Initial crank angle in degrees, in [-40, 40]; the plant starts at rest there.

        Returns
        -------
        SimResult
            The run (``meta["kind"] == "open_loop"``), one sample per command value.

        Examples
        --------
        >>> r = Plant(disc_sets=1).simulate(np.zeros(100))
        >>> float(abs(r.theta_deg).max())
        0.0
        """
        cmd = _check_current(current_mA, "current_mA")
        check_field("theta0_deg", theta0_deg)
        out = np.zeros((cmd.size, K.N_OUT))
        s = self.initial_state(theta0_deg)
        self._model.run_open_loop(s, self._P, cmd, self.dt, self.substeps, np.zeros(self._hist_len), out)
        return self._result(out, kind="open_loop")

    def simulate_closed_loop(self, controller=None, *, amplitude_deg: float = 20.0, freq_hz: float = 1.0,
                             cycles: float = 3.0, duration: float | None = None, reference=None,
                             theta0_deg: float = 0.0) -> SimResult:
        """Closed loop on a sinusoidal reference.

        ``controller`` is a :class:`RigController` (fast compiled loop; the book's
        gains by default) or any object with ``reset()`` and
        ``act(measurement: dict) -> current mA`` called every ``dt`` with the keys
        ``t, theta_deg, theta_ref_deg, theta_ref_dot, theta_ref_ddot, theta_ref_dddot,
        p_a_bar, p_b_bar, p_s_bar`` (deg, deg/s, deg/s^2, deg/s^3, bar), plus the
        reference's ``amplitude_deg`` (learned controllers normalise the error by it) and ``freq_hz``
        (learning controllers index their cycle table by it).
        The run lasts ``duration`` s, or ``cycles`` reference periods.  Numbers are checked against the
        ranges of ``ehas_env.ranges.FIELDS`` (docs/errors.md): amplitude in (0, 44.43) deg, frequency
        in (0, 50] Hz, cycles in (0, 10000], duration in (0, 600] s, theta0_deg in [-40, 40] deg.

        Parameters
        ----------
        controller : RigController or object, optional
            The controller: a :class:`RigController` (or anything with a compiled form, such as
            :class:`ehas_controllers.piff.PIFF`) runs in the compiled loop; any other object needs
            ``act(measurement) -> current in mA`` (and optionally ``reset()``).  Default: the book's gains.
        amplitude_deg : float
            Amplitude of the sinusoidal reference in degrees, in (0, 44.43); ignored when
            ``reference`` is given.
        freq_hz : float
            Frequency of the sinusoidal reference in Hz, in (0, 50]; ignored when ``reference`` is given.
        cycles : float
            Length of the run in reference periods, in (0, 10000]; ignored when ``duration`` is given.
        duration : float, optional
            Length of the run in seconds, in (0, 600]; overrides ``cycles``.
        reference : SineReference, optional
            The reference signal (:class:`ehas_env.simulation.reference.SineReference`) in place of
            ``amplitude_deg`` and ``freq_hz``.
        theta0_deg : float
            Initial crank angle in degrees, in [-40, 40]; the plant starts at rest there.

        Returns
        -------
        SimResult
            The run (``meta["kind"] == "closed_loop"``) with ``theta_ref_deg`` and, in ``meta``, the
            reference and the controller.

        Raises
        ------
        ValueError
            If a number is out of its range, the controller is no controller (or its ``rate_hz`` is not
            ``1/dt``), or the run turns non-finite.
        """
        controller = RigController.book() if controller is None else controller
        compiled = _check_controller(controller, self.rig.disc_sets)
        if reference is None:
            check_field("amplitude_deg", amplitude_deg)
            check_field("freq_hz", freq_hz)
            ref = SineReference(amplitude_deg, freq_hz)
        else:
            ref = _check_reference(reference)
        check_field("theta0_deg", theta0_deg)
        if duration is None:
            check_field("cycles", cycles)
            duration = cycles / ref.freq_hz
            what = f"cycles {cycles:g} at freq_hz {ref.freq_hz:g}"
        else:
            check_field("duration_s", duration, "duration")
            what = f"duration {duration:g} s"
        check_run_length(duration, self.dt, where=what)
        n = int(round(duration / self.dt))
        check_samples(n, f"{what} ({duration:g} s at dt = {self.dt:g} s)")
        rng = np.random.default_rng(self.seed)
        noise = self.sensors.theta_noise(n, rng)
        out = np.zeros((n, K.N_OUT))
        s = self.initial_state(theta0_deg)
        hist = np.zeros(self._hist_len)
        if compiled is not None:
            rate = getattr(compiled, "rate_hz", 1.0 / self.dt)
            if abs(rate * self.dt - 1.0) > 1e-9:
                raise ValueError(f"controller rate_hz {rate:g} must equal the plant's 1/dt = {1 / self.dt:g} Hz")
            sensor = self.sensors.kernel_vector(self.rig.i_max)
            sub = controller.for_plant(self.rig.disc_sets) if hasattr(controller, "for_plant") else controller
            sensor[3] = min(sensor[3], getattr(sub, "i_max", sensor[3]))  # the controller's own output limit
            sensor[1] = max(sensor[1], getattr(sub, "dac_lsb", 0.0))  # and its DAC, as the benchmark does
            self._model.closed_loop(s, self._P, compiled.law_id(), compiled.gains_vector(), ref.kernel_vector(),
                                    0, self.dt, self.substeps, hist, noise, sensor, 0, n, np.zeros(6), out)
            ctrl_meta = {**compiled.to_dict()}
        else:
            self._python_loop(controller, ref, s, hist, noise, out)
            ctrl_meta = {"name": type(controller).__name__, "repr": repr(controller), "rate_hz": 1.0 / self.dt}
        t = np.arange(n) * self.dt
        check_run(out, self.dt, K.O_CURRENT, ctrl_meta.get("name") or ctrl_meta.get("type") or "controller",
                  self.effects)  # NaN or inf: one line naming who and when (ehas_env.simulation.finite)
        theta_ref = np.atleast_1d(np.asarray(ref(t)[0], dtype=float))
        return self._result(out, kind="closed_loop", theta_ref=theta_ref, rng=rng,
                            extra_meta={"reference": ref.to_dict(),
                                        "controller": ctrl_meta})

    def _python_loop(self, controller, ref, s, hist, noise, out):
        M = self._model
        k1, k2, k3, k4, tmp = (np.empty_like(s) for _ in range(5))
        lsb = self.sensors.theta_lsb
        dac = self.sensors.current_lsb
        if hasattr(controller, "reset"):
            controller.reset()
        ref_vec = ref.kernel_vector()
        amp = float(ref.amplitude_deg)
        freq = float(ref.freq_hz)  # learning controllers (ehas_controllers.ilc) index their cycle table by it
        for k in range(out.shape[0]):
            M.measure(s, self._P, out[k])
            t = k * self.dt
            r, rd, rdd, rddd = M.reference_point(ref_vec, t)
            th = M.sense(out[k, K.O_THETA], self.sensors.lvdt_gain_error, noise[k], lsb)
            out[k, K.O_SENSED] = th
            meas = {"t": t, "theta_deg": th, "theta_ref_deg": r, "theta_ref_dot": rd, "theta_ref_ddot": rdd,
                    "theta_ref_dddot": rddd, "p_a_bar": s[4] / BAR, "p_b_bar": s[5] / BAR, "p_s_bar": s[6] / BAR,
                    "amplitude_deg": amp, "freq_hz": freq}
            raw = controller.act(meas)
            try:
                u = float(raw)
            except (TypeError, ValueError):
                raise ValueError(f"controller {type(controller).__name__}: act() returned {_brief(raw)} at t = {t:g} s; "
                                 "expected a current in mA (one finite number)") from None
            if not math.isfinite(u):
                raise ValueError(f"controller {type(controller).__name__} returned a non-finite current {u!r} at t = {t:g} s")
            u = min(max(u, -self.rig.i_max), self.rig.i_max)
            u = M.quantize(u, dac)
            out[k, K.O_CURRENT] = u
            hist[k % hist.shape[0]] = u
            out[k, K.O_STROKE] = float(M.advance(s, self._P, hist, k, self.dt, self.substeps, 0.0, k1, k2, k3, k4, tmp))

    def simulate_valve_test(self, current_mA, *, supply_bar: float = 70.0) -> "ValveTestResult":
        """The valve alone on the flow bench: control ports joined through the meter.

        Parameters
        ----------
        current_mA : array_like of float
            Command current in mA, one finite value per sample period ``dt`` (a 1-D sequence).
        supply_bar : float
            Supply pressure of the bench in bar, in (0, 350] (the valve's rated drop is at 70 bar).

        Returns
        -------
        ValveTestResult
            Times (s), command current (mA), flow through the meter (LPM) and the valve's current
            (mA), with ``meta["kind"] == "valve_open_loop"``.

        Examples
        --------
        >>> r = Plant().simulate_valve_test(np.full(2000, 20.0))
        >>> round(float(r.flow_lpm[-1]), 2)   # K * 20 mA at the rated 70 bar
        25.45
        """
        cmd = _check_current(current_mA, "current_mA")
        check_field("supply_bar", supply_bar)
        out = np.zeros((cmd.size, 3))
        self._model.run_valve_test(self._P, cmd, self.dt, self.substeps, supply_bar * BAR, np.zeros(self._hist_len), out)
        t = np.arange(cmd.size) * self.dt
        flow = out[:, 0] / LPM
        logged = {}
        if not self.sensors.is_ideal:
            rng = np.random.default_rng(self.seed)
            logged["flow_lpm"] = self.sensors.measure_channel(flow, "flow", rng)
        meta = {"kind": "valve_open_loop", "supply_bar": supply_bar, "effects": self.effects,
                "sensors": self.sensors.to_dict()}
        if self.valve != "grey_box":
            meta["valve"] = self.valve
        return ValveTestResult(t=t, current_mA=cmd, flow_lpm=flow, valve_current_mA=out[:, 2], meta=meta, logged=logged)

    def _result(self, out, *, kind, theta_ref=None, rng=None, extra_meta=None) -> SimResult:
        n = out.shape[0]
        t = np.arange(n) * self.dt
        theta = np.degrees(out[:, K.O_THETA])
        res = SimResult(
            t=t, current_mA=out[:, K.O_CURRENT].copy(), theta_deg=theta, omega_deg_s=np.degrees(out[:, K.O_OMEGA]),
            theta_crank_deg=np.degrees(out[:, K.O_CRANK]), flow_lpm=out[:, K.O_FLOW] / LPM, p_a_bar=out[:, K.O_PA] / BAR,
            p_b_bar=out[:, K.O_PB] / BAR, p_s_bar=out[:, K.O_PS] / BAR, load_kN=out[:, K.O_FORCE] * 1e-3,
            stroke_end=out[:, K.O_STROKE] > 0.5, theta_ref_deg=theta_ref,
        )
        res.meta = {"kind": kind, "disc_sets": self.rig.disc_sets, "inertia_kgm2": self.rig.inertia,
                    "supply_bar": self.rig.supply / BAR, "effects": self.effects, "sensors": self.sensors.to_dict(),
                    "dt": self.dt, "substeps": self.substeps, **(extra_meta or {})}
        if self.valve != "grey_box":
            res.meta["valve"] = self.valve
        if not self.sensors.is_ideal:
            rng = rng if rng is not None else np.random.default_rng(self.seed)
            m = self.sensors.measure_channel
            pa, pb = m(res.p_a_bar, "pressure", rng), m(res.p_b_bar, "pressure", rng)
            res.logged = {
                "theta_deg": out[:, K.O_SENSED].copy() if kind == "closed_loop" else m(res.theta_deg, "theta", rng),
                "flow_lpm": m(res.flow_lpm, "flow", rng), "p_a_bar": pa, "p_b_bar": pb,
                "p_s_bar": m(res.p_s_bar, "pressure", rng),
                # the load cell reads the piston force through its own reading place (a pressure reading's lag or
                # offset is not in it); its noise is assumed the pressure transducers' seen through the area (no
                # draw of its own: the noise of every other channel is what it was)
                "load_kN": res.load_kN + self.rig.area * ((pa - res.p_a_bar) - (pb - res.p_b_bar)) * BAR * 1e-3,
            }
        return res


@dataclass
class ValveTestResult:
    """Flow-bench run of the valve alone (``kind = valve_open_loop``)."""

    t: np.ndarray
    current_mA: np.ndarray
    flow_lpm: np.ndarray
    valve_current_mA: np.ndarray
    meta: dict = field(default_factory=dict)
    logged: dict = field(default_factory=dict)

    def columns(self, logged: bool = True) -> dict[str, np.ndarray]:
        """The run's columns in the measurement format (the logged flow by default)."""
        flow = self.logged.get("flow_lpm", self.flow_lpm) if logged else self.flow_lpm
        return {"t": self.t, "current_mA": self.current_mA, "flow_lpm": flow}


#: what numpy's dtype kinds hold, for refusals
_KINDS = {"b": "booleans", "c": "complex numbers", "U": "text", "S": "bytes", "O": "Python objects",
          "M": "dates", "m": "time spans", "V": "records"}


def _brief(value) -> str:
    """``repr(value)`` on one line, at most 60 characters (an array's repr spans lines)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 60 else text[:57] + "..."


def _check_current(current_mA, name: str) -> np.ndarray:
    what = f"{name} must be a 1-D sequence of currents in mA, one per sample period"
    try:
        arr = np.asarray(current_mA)
    except (TypeError, ValueError):  # ragged nested lists
        raise ValueError(f"{what}; got a ragged {type(current_mA).__name__}") from None
    if arr.dtype.kind not in "iuf":
        held = _brief(arr.item()) if arr.ndim == 0 else f"an array of {_KINDS.get(arr.dtype.kind, arr.dtype)}"
        raise ValueError(f"{what}; got {held}")
    if arr.ndim == 0:
        raise ValueError(f"{what}; got the single number {_brief(arr.item())}")
    if sum(d > 1 for d in arr.shape) > 1:
        raise ValueError(f"{what}; got an array of shape {arr.shape}")
    cmd = np.asarray(arr, dtype=float).ravel()
    if cmd.size == 0:
        raise ValueError(f"{name} is empty; expected one current in mA per sample period")
    if cmd.size > MAX_SAMPLES:
        raise ValueError(f"{name} holds {cmd.size:,} samples; at most {MAX_SAMPLES:,} per run")
    bad = np.flatnonzero(~np.isfinite(cmd))
    if bad.size:
        raise ValueError(f"{name} holds a non-finite value ({float(cmd[bad[0]])!r}) at sample {bad[0]}; "
                         "expected finite mA")
    return cmd


def _check_controller(controller, disc_sets: int):
    """The controller's compiled form (None: a Python ``act``); ValueError for anything that is no controller."""
    if isinstance(controller, type):
        raise ValueError(f"controller must be a controller object, got the class {controller.__name__} "
                         f"(create one: {controller.__name__}(...))")
    compiled = compiled_form(controller, disc_sets)
    if compiled is None and not callable(getattr(controller, "act", None)):
        raise ValueError("controller must be a RigController or an object with act(measurement) -> current in mA, "
                         f"got {_brief(controller)}")
    return compiled


def _check_reference(reference):
    if isinstance(reference, type) or not callable(reference) or not all(
            hasattr(reference, a) for a in ("amplitude_deg", "freq_hz", "kernel_vector", "to_dict")):
        raise ValueError(f"reference must be a SineReference (ehas_env.simulation.reference), got {_brief(reference)}")
    return reference


#: the fields of :class:`Sensors` and their ranges (``ehas_env.ranges.FIELDS``)
SENSOR_FIELDS = ("theta_noise_deg", "pressure_noise_bar", "flow_noise_lpm", "adc_bits", "dac_bits", "lvdt_gain_error")


def _check_sensors(sensors) -> Sensors:
    if sensors is None:
        return Sensors.ideal()
    if not isinstance(sensors, Sensors):
        raise ValueError("sensors must be a Sensors (ehas_env.simulation.sensors: Sensors() realistic, Sensors.ideal() "
                         f"none), got {_brief(sensors)}")
    for name in SENSOR_FIELDS:
        check_field(name, getattr(sensors, name), f"sensors: {name}")
    return sensors


def _check_effects_path(paths) -> None:
    if paths is None or isinstance(paths, (str, os.PathLike)):
        return
    if isinstance(paths, (list, tuple)) and all(isinstance(p, (str, os.PathLike)) for p in paths):
        return
    raise ValueError(f"effects_path must be a folder or file of user effects (a str or Path) or a list of them, "
                     f"got {_brief(paths)}")


def _check_effects(effects):
    """``effects`` as :func:`resolve_effects` takes it, its shape and value types checked (the bounds are the
    effects' own); an iterator of names becomes a list."""
    if effects is None or isinstance(effects, str):
        return effects
    if isinstance(effects, Mapping):
        for name, values in effects.items():
            if values is None:
                continue
            if not isinstance(values, Mapping):
                raise ValueError(f"effects: the parameters of '{name}' must be a dict {{param: value}} (or None for "
                                 f"the defaults), got {_brief(values)}")
            cls = get_effect(name)
            for key, v in values.items():
                if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
                    p = cls.param(key)  # an unknown parameter is named first
                    lo, hi = p.bounds
                    unit = f" {p.unit}" if p.unit else ""
                    raise ValueError(f"effect '{name}': parameter '{key}' must be a number in [{lo:g}, {hi:g}]{unit}, "
                                     f"got {_brief(v)}")
        return effects
    if isinstance(effects, (bytes, numbers.Number)) or not isinstance(effects, Iterable):
        raise ValueError("effects must be a dict {name: {param: value}}, a list of effect names or a spec such as "
                         f"'coulomb_friction:Fc=300', got {_brief(effects)}")
    effects = list(effects)
    for name in effects:
        if not isinstance(name, str):
            raise ValueError(f"effects: a list holds effect names (text), got {_brief(name)}; known effects: "
                             f"{', '.join(sorted(REGISTRY))}")
    return effects
