"""Runs of the independent rig: closed-loop sine tracking with the rig's controller, and the valve flow bench.

Integration: ``scipy.integrate.solve_ivp`` with the adaptive Dormand-Prince
5(4) pair (``RK45``, rtol 1e-7), restarted at every instant the valve's current
changes (each 1 ms control period, and the delayed command's switch inside it),
so the zero-order hold is exact and the step size is the method's own choice
-- unlike the reference model's fixed 0.1 ms RK4.  The delay is exact (the
switch instant t_k + tau), not resolved to a sub-step.

The controller (docs/reference-model.md §9), re-implemented from the docs:
``i = Kp e + Ki I + Kv r' + Ka r''``, ``e = r - theta_sensed`` in deg, ``I``
the rectangle-rule integral of e that stops while the output is clipped and e
would drive it further, clipped to +-i_max, then the 12-bit DAC.  Reference
``r = s(t/T) (offset + A sin(2 pi f t + phase))`` with the smoothstep
``s = 10x^3 - 15x^4 + 6x^5`` over the fade-in T = ramp_cycles / f (by default one
period; none with ramp_cycles 0), derivatives by the product rule.

Start conditions as rigs record them (:func:`closed_loop`'s options; the defaults
are the runs ehas plans): a run that starts from rest without a fade-in
(``ramp_cycles=0``), a reference that starts away from 0 (``phase_rad``, with the
rig at rest at 0 or where the reference starts, ``rest="start"``), and a short
external torque pulse on the crank that no model knows of (:class:`Bump`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .physics import N, RigModel
from .rig import BAR, LPM, Rig
from .sensors import Chain

DT = 1.0e-3  # s: the RMC70's control period
#: stroke-end impacts resolved in one piece before the driver gives up (a bouncing piston would need many; the
#: stops are inelastic: one, then held)
MAX_IMPACTS = 8
RTOL = 1.0e-7
#: absolute tolerances per state (theta, omega, qc, qcd, pa, pb, iv, xp, vp, z)
ATOL = np.array([1e-10, 1e-8, 1e-12, 1e-10, 1e-2, 1e-2, 1e-8, 1e-11, 1e-9, 1e-12])


def reference(t: float, amp: float, freq: float, offset: float = 0.0, ramp_cycles: float = 1.0,
              phase: float = 0.0) -> tuple:
    """(r, r', r'') in deg, deg/s, deg/s^2: the sine about the mean angle ``offset`` (the sidecar's
    ``reference.offset_deg``, docs/measurement-format.md), mean angle and amplitude faded in over the first
    ``ramp_cycles`` periods (0: no fade-in, the sine from t = 0), the sine's phase ``phase`` in rad."""
    w = 2.0 * math.pi * freq
    T = ramp_cycles / freq
    if t < T:
        x = t / T
        s = x ** 3 * (10.0 - 15.0 * x + 6.0 * x * x)
        s1 = (30.0 * x ** 2 - 60.0 * x ** 3 + 30.0 * x ** 4) / T
        s2 = (60.0 * x - 180.0 * x ** 2 + 120.0 * x ** 3) / T ** 2
    else:
        s, s1, s2 = 1.0, 0.0, 0.0
    sn, cs = math.sin(w * t + phase), math.cos(w * t + phase)
    r = amp * s * sn + offset * s
    r1 = amp * (s1 * sn + s * w * cs) + offset * s1
    r2 = amp * (s2 * sn + 2.0 * s1 * w * cs - s * w * w * sn) + offset * s2
    return r, r1, r2


@dataclass(frozen=True)
class Bump:
    """A short external torque pulse on the crank (a knock on the discs) that no model of the rig holds.

    ``torque_Nm sin(pi (t - t_s) / width_s)`` over ``[t_s, t_s + width_s)``, zero elsewhere (a half sine: a
    knock's force rises and falls).  ``t_s`` and ``width_s`` are rounded to the 1 ms control period, so the
    pulse's edges fall where the integration restarts.

    Parameters
    ----------
    t_s : float
        Start of the pulse, s from the run's start.
    width_s : float
        Its length, s (20-50 ms: a knock, not a change of the rig).
    torque_Nm : float
        Its peak torque on the crank, N m (positive: toward rising angle).
    """

    t_s: float
    width_s: float
    torque_Nm: float

    def __post_init__(self):
        if not (self.t_s >= 0.0 and self.width_s >= DT and math.isfinite(self.torque_Nm)):
            raise ValueError(f"bump: t_s >= 0 s, width_s >= {DT:g} s and a finite torque_Nm, got {self}")

    @property
    def k0(self) -> int:
        """First control period of the pulse."""
        return int(round(self.t_s / DT))

    @property
    def periods(self) -> int:
        """Its length in control periods."""
        return max(1, int(round(self.width_s / DT)))

    def torque(self, t: float) -> float:
        """The pulse's torque at t, N m."""
        a, w = self.k0 * DT, self.periods * DT
        return self.torque_Nm * math.sin(math.pi * (t - a) / w) if a <= t < a + w else 0.0

    def to_dict(self) -> dict:
        return {"t_s": self.k0 * DT, "width_s": self.periods * DT, "torque_Nm": self.torque_Nm}


class _Bumped:
    """A :class:`.physics.RigModel` with a :class:`Bump` on its crank (every other method is the model's)."""

    def __init__(self, model: RigModel, bump: Bump):
        self._m = model
        self._bump = bump

    def __getattr__(self, name):
        return getattr(self._m, name)

    def rates(self, y, i_cmd: float, t: float = 0.0) -> list:
        dy = self._m.rates(y, i_cmd, t)
        dy[1] += self._bump.torque(t) / self._m.inertia
        return dy


def rest_at(model: RigModel, angle_deg: float) -> list:
    """The state at rest where the LVDT reads ``angle_deg`` (noise aside), both chambers at Ps/2.

    The piston position whose reading is ``angle_deg`` (through the sensor effects: offset, nonlinearity) is
    found by bisection; the crank, the piston of a compliant load path and a lagging reading all sit there.

    Parameters
    ----------
    model : RigModel
    angle_deg : float
        The reading, deg, inside the stroke.

    Returns
    -------
    list
        The state vector.
    """
    from scipy.optimize import brentq

    rig = model.rig
    y = model.initial_state()
    h = rig.half_stroke

    def reading(x):
        z = list(y)
        z[0] = math.asin(min(1.0, max(-1.0, x / rig.radius + math.sin(model.phi0)))) - model.phi0
        z[7] = x
        if model.i_xr is not None:
            z[model.i_xr] = x
        return model.lvdt_angle_deg(z) - angle_deg

    if reading(-h) * reading(h) > 0.0:
        raise ValueError(f"rest at {angle_deg:g} deg: outside the readings of the stroke")
    x = brentq(reading, -h, h, xtol=1e-12)
    y[0] = math.asin(min(1.0, max(-1.0, x / rig.radius + math.sin(model.phi0)))) - model.phi0
    if model.two_body:
        y[7] = x
    if model.i_xr is not None:
        y[model.i_xr] = x
    model.rest_at_angle(y)
    return y


class PIFF:
    """The rig's PI + velocity and acceleration feed-forward, 1 kHz, with conditional-integration anti-windup."""

    def __init__(self, gains: dict, i_max: float):
        self.g = gains
        self.i_max = i_max
        self.integral = 0.0

    def __call__(self, e: float, r1: float, r2: float) -> float:
        g = self.g
        ff = g["Kv"] * r1 + g["Ka"] * r2
        trial = g["Kp"] * e + g["Ki"] * (self.integral + e * DT) + ff
        clipped = abs(trial) >= self.i_max
        if not (clipped and trial * e > 0.0):
            self.integral += e * DT
        u = g["Kp"] * e + g["Ki"] * self.integral + ff
        return max(-self.i_max, min(self.i_max, u))


def _advance(model: RigModel, y: np.ndarray, t0: float, t1: float, i_cmd: float) -> np.ndarray:
    if t1 - t0 <= 1e-12:
        return y
    atol = ATOL if len(y) == N else np.concatenate([ATOL, model.extra_atol()])
    events = None
    if getattr(model, "exact_bounds", False):
        # a stroke end is met where it is (the impact at its instant), not at the next piece's boundary
        def events(t, s):
            return model.stroke_end(s)
        events.terminal, events.direction = True, -1.0
    for _ in range(MAX_IMPACTS + 1):
        sol = solve_ivp(lambda t, s: model.rates(s, i_cmd, t), (t0, t1), y, method="RK45", rtol=RTOL, atol=atol,
                        first_step=min(t1 - t0, 2.5e-4), events=events)
        if not sol.success:
            raise RuntimeError(f"integration failed at t = {t0:g} s: {sol.message}")
        y = sol.y[:, -1].copy()
        if sol.status == 1:
            model.impact(y)  # at the end's instant: the outward velocity gone, then on to the piece's end
        model.apply_stops(y)
        if sol.status != 1 or sol.t[-1] >= t1 - 1e-12:
            return y
        t0 = float(sol.t[-1])
    raise RuntimeError(f"more than {MAX_IMPACTS} stroke-end impacts in one piece at t = {t0:g} s")


def _period(model: RigModel, y, k: int, cmds: list) -> np.ndarray:
    """Advance over period k: the valve sees the command of t - tau (exact switch instant)."""
    tau = model.tau
    m = int(math.floor(tau / DT + 1e-12))
    f = tau - m * DT
    t0 = k * DT

    def cmd(j):
        return cmds[j] if j >= 0 else 0.0

    if f > 1e-12:
        y = _advance(model, y, t0, t0 + f, cmd(k - m - 1))
        return _advance(model, y, t0 + f, t0 + DT, cmd(k - m))
    return _advance(model, y, t0, t0 + DT, cmd(k - m))


@dataclass
class Run:
    """One run: logged columns (format units) and its sidecar."""

    name: str
    columns: dict
    meta: dict


def closed_loop(rig: Rig, disc_sets: int, amplitude_deg: float, freq_hz: float, duration: float, effects_si: dict,
                chain: Chain, rng: np.random.Generator, gains: dict | None = None, progress=None,
                offset_deg: float = 0.0, ramp_cycles: float = 1, phase_rad: float = 0.0, rest: str = "zero",
                bump: Bump | None = None, state_ramp: bool = True, exact_bounds: bool = False,
                blocks=None) -> tuple:
    """A closed-loop sine run.

    Parameters
    ----------
    rig : Rig
        The rig.
    disc_sets : int
        Disc sets, 1-7.
    amplitude_deg, freq_hz : float
        The reference sine.
    duration : float
        Run length, s.
    effects_si : dict
        Hidden effects, SI (:func:`.effects.to_si`).
    chain : Chain
        Measurement chain.
    rng : numpy.random.Generator
        Noise source.
    gains : dict, optional
        The controller's gains (Kp, Ki, Kv, Ka; default: the book's carried over to ``rig``).
    progress : callable, optional
        Called with the fraction done every 500 periods.
    offset_deg : float
        The sine's mean angle, deg (0: centred on the stroke).
    ramp_cycles : float
        The fade-in, reference periods (0: the sine from t = 0, a start from rest without a fade-in).
    phase_rad : float
        The sine's phase, rad (with ``ramp_cycles`` 0 the reference starts at offset + A sin(phase)).
    rest : str
        Where the rig is at rest at t = 0: ``"zero"`` (mid-stroke, as ehas's runs) or ``"start"`` (where the
        reference starts: the operator jogged it there before switching the sine on).
    bump : Bump, optional
        An external torque pulse on the crank during the run.
    state_ramp : bool
        The sidecar states ``ramp_cycles`` (False: the key is left out, the format's default 0; only with
        ``ramp_cycles`` 0).
    exact_bounds : bool
        The chamber pressures held within [0, Ps] inside the integration too (:class:`.physics.RigModel`), not only
        between pieces: for runs that drive a chamber to a bound.
    blocks : list, optional
        Drawn blocks of hidden physics (:class:`.grammar.Block`), hooked into the model (:class:`.physics.Hooks`)
        and into the readings.

    Returns
    -------
    columns : dict
        Logged columns of the measurement format.
    true : dict
        Noise-free theta_deg (LVDT angle), p_a_bar, p_b_bar, flow_lpm (the readings, with their blocks).
    meta : dict
        The sidecar.
    """
    if rest not in ("zero", "start"):
        raise ValueError(f"rest must be 'zero' or 'start', got {rest!r}")
    if not state_ramp and ramp_cycles:
        raise ValueError(f"state_ramp=False leaves ramp_cycles out of the sidecar (read as 0): ramp_cycles must be "
                         f"0, got {ramp_cycles!r}")
    model = RigModel(rig, disc_sets, effects_si, exact_bounds=exact_bounds, blocks=blocks)
    hooks = model.hooks
    lvdt_steps = hooks is not None and "position_reading" in hooks.sampled
    gains = dict(gains or rig.controller_gains())
    ctrl = PIFF(gains, rig.i_max)
    n = int(round(duration / DT))
    if rest == "start":
        y = np.array(rest_at(model, reference(0.0, amplitude_deg, freq_hz, offset_deg, ramp_cycles, phase_rad)[0]))
    else:
        y = np.array(model.initial_state())
    if bump is not None:
        model = _Bumped(model, bump)
    cols = {k: np.zeros(n) for k in ("t", "current_mA", "theta_deg", "theta_ref_deg", "flow_lpm", "p_a_bar",
                                     "p_b_bar", "p_s_bar")}
    true = {k: np.zeros(n) for k in ("theta_deg", "flow_lpm", "p_a_bar", "p_b_bar")}
    cmds: list = []
    for k in range(n):
        t = k * DT
        if lvdt_steps:  # the reading's dynamic blocks, sample by sample (the controller sees what they pass)
            th_true = model.angle_of(hooks.step_reading("position_reading", model.lvdt_reading(y)))
        else:
            th_true = model.lvdt_angle_deg(y)
        th = chain.angle(th_true, rig, rng)
        r, r1, r2 = reference(t, amplitude_deg, freq_hz, offset_deg, ramp_cycles, phase_rad)
        u = chain.dac(ctrl(r - th, r1, r2))
        cmds.append(model.hold(u))
        out = model.outputs(y, t)
        cols["t"][k] = t
        cols["current_mA"][k] = u
        cols["theta_deg"][k] = th
        cols["theta_ref_deg"][k] = r
        true["theta_deg"][k] = th_true
        for key in ("flow_lpm", "p_a_bar", "p_b_bar"):
            true[key][k] = out[key]
        y = _period(model, y, k, cmds)
        if progress is not None and k % 500 == 0:
            progress(k / n)
    if hooks is not None:
        _read_blocks(hooks, true)
    cols["flow_lpm"] = chain.flow(true["flow_lpm"], rng)
    cols["p_a_bar"] = chain.pressure(true["p_a_bar"], rng)
    cols["p_b_bar"] = chain.pressure(true["p_b_bar"], rng)
    # the supply transducer sits at the pump's regulated outlet
    cols["p_s_bar"] = chain.pressure(np.full(n, rig.supply / BAR) if not model.ripple else
                                     np.array([model.supply(k * DT) for k in range(n)]) / BAR, rng)
    cols["load_kN"] = rig.area * (cols["p_a_bar"] - cols["p_b_bar"]) * BAR * 1e-3
    if hooks is not None and hooks.reads("load_reading"):
        load = rig.area * (true["p_a_bar"] - true["p_b_bar"]) * BAR  # N: the logger's load, noise aside
        cols["load_kN"] = cols["load_kN"] + (hooks.read_series("load_reading", load) - load) * 1e-3
    meta = {"kind": "closed_loop", "disc_sets": int(disc_sets), "supply_bar": rig.supply / BAR,
            "reference": {"amplitude_deg": amplitude_deg, "freq_hz": freq_hz, "phase_rad": phase_rad,
                          **({"ramp_cycles": ramp_cycles} if state_ramp else {}),
                          **({"offset_deg": offset_deg} if offset_deg else {})},
            "controller": {k: float(v) for k, v in gains.items()}}
    return cols, true, meta


#: the logged readings a block may act on: (place, column of ``true``, SI per column unit)
READINGS = (("pressure_reading_a", "p_a_bar", BAR), ("pressure_reading_b", "p_b_bar", BAR),
            ("flow_reading", "flow_lpm", LPM))


def _read_blocks(hooks, true: dict) -> None:
    """The noise-free readings through the blocks at their transducers, in place (the noise is added after)."""
    for place, col, si in READINGS:
        if hooks.reads(place):
            true[col] = hooks.read_series(place, true[col] * si) / si


def chirp(n: int, f0: float, f1: float, amp: float) -> np.ndarray:
    """Logarithmic sweep f0 -> f1 Hz over n periods, amplitude amp mA."""
    t = np.arange(n) * DT
    T = n * DT
    c = math.log(f1 / f0) / T
    return amp * np.sin(2.0 * math.pi * f0 * (np.exp(c * t) - 1.0) / c)


def valve_bench(rig: Rig, command: np.ndarray, supply_bar: float, effects_si: dict, chain: Chain,
                rng: np.random.Generator, blocks=None) -> tuple:
    """The valve alone on the flow bench, ports A and B joined through the flow meter.

    The two open lands in series share the drop Ps - p_t, so the metered flow is
    q_c sqrt((Ps - p_t) / dp_n) for a critically lapped valve; an underlapped one
    passes (a_1 - a_2) sqrt((Ps - p_t) / dp_n) with the lands' openings
    a_1 = max(u0 + q_c, 0), a_2 = max(u0 - q_c, 0) (by symmetry the meter sits at
    (Ps + p_t) / 2); a supply line loss lowers Ps by dp (Q / 20 LPM)^2.  Drawn blocks act here where the bench
    has their place: the amplifier's command and the coil current (the same valve and amplifier) and the flow
    meter's reading (the same meter); the bench has its own regulated supply and return, and no load.

    Returns
    -------
    columns : dict
        t, current_mA, flow_lpm (logged).
    meta : dict
        The sidecar.
    """
    model = RigModel(rig, 1, effects_si, blocks=blocks)
    ps = supply_bar * BAR
    y = np.zeros(model.n)
    flows = np.zeros(command.size)
    drop = rig.rated_drop
    cmds = [model.hold(float(c)) for c in command]
    for k in range(command.size):
        qc = y[2]
        a1, a2 = max(model.u0 + qc, 0.0), max(model.u0 - qc, 0.0)
        net = a1 - a2
        if model.k_line:
            # Q^2 = net^2 (ps - k Q^2 - p_t) / dp_n, solved for Q^2
            q2 = net * net * (ps - model.p_t) / drop / (1.0 + model.k_line * net * net / drop)
            flows[k] = math.copysign(math.sqrt(q2), net) / LPM
        elif model.gamma:  # each of the two lands in series takes half the drop, by its own law
            flows[k] = net * model.land(0.5 * max(ps - model.p_t, 0.0)) / LPM
        else:
            flows[k] = net * math.sqrt(max(ps - model.p_t, 0.0) / drop) / LPM
        y = _period_valve(model, y, k, cmds)
    if model.hooks is not None and model.hooks.reads("flow_reading"):
        flows = model.hooks.read_series("flow_reading", flows * LPM) / LPM
    cols = {"t": np.arange(command.size) * DT, "current_mA": np.asarray(command, float),
            "flow_lpm": chain.flow(flows, rng)}
    meta = {"kind": "valve_open_loop", "supply_bar": supply_bar}
    return cols, meta


def _period_valve(model: RigModel, y, k: int, cmds: list) -> np.ndarray:
    """As :func:`_period` with only the valve's states moving (chambers and mechanics frozen)."""
    frozen = _ValveOnly(model)
    return _period(frozen, y, k, cmds)


class _ValveOnly:
    """The valve's part of :class:`RigModel` (coil lag and spool), for the bench."""

    def __init__(self, model: RigModel):
        self.m = model
        self.tau = model.tau
        self.moving = model.valve_states()

    def rates(self, y, i_cmd, t=0.0):
        dy = self.m.rates(y, i_cmd, t)
        out = [0.0] * len(dy)
        for j in self.moving:
            out[j] = dy[j]
        return out

    def extra_atol(self):
        return self.m.extra_atol()

    def apply_stops(self, y):
        rig = self.m.rig
        q_stop = rig.K * rig.i_max
        if abs(y[2]) > q_stop:
            y[2] = math.copysign(q_stop, y[2])
            if y[3] * y[2] > 0.0:
                y[3] = 0.0
        return False
