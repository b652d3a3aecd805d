"""Batched closed-loop simulation: many conditions and controllers in one serial numba loop.

Built on ``ehas_env.physics.kernel`` (``advance``, ``measure``, ``reference_point``): the
controller law is the one of ``kernel.run_rig_controller`` (PI + velocity /
acceleration / jerk feed-forward, load-pressure feedback, anti-windup, DAC), the
plant is :class:`ehas_env.simulation.plant.Plant`'s parameter vector with any effects.  Each
condition is simulated from rest and only its metrics are kept, so a grid of
hundreds of runs needs no trace memory.

Metrics per condition (``METRICS``):

* ``rms_error_pct``, ``peak_error_pct``: as ``ehas_env.simulation.metrics`` - 100 RMS / max of
  (theta_ref - theta) / amplitude over whole reference cycles after the first;
* ``max_current_mA``: largest |command| over the whole run;
* ``saturation_frac``: fraction of the run's periods with the command at +-i_max;
* ``peak_delta_p_bar``: largest |P_A - P_B| over the whole run, bar;
* ``hit_stroke_end``: 1 if the piston touched a stroke end at any time.

(The hardware figures cover the whole run, warm-up included: the rig sees it too.)

Examples
--------
>>> from ehas_controllers.batch_sim import Condition, evaluate
>>> from ehas_controllers.piff import PIFF
>>> rows = evaluate(PIFF.book(), [Condition(3, 1.0, 20.0)], cycles=3)
>>> round(rows[0]["rms_error_pct"], 3)
0.207
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ehas_env.physics import kernel as K

METRICS = ("rms_error_pct", "peak_error_pct", "max_current_mA", "saturation_frac", "peak_delta_p_bar", "hit_stroke_end")
N_METRICS = len(METRICS)
REF_SINE, REF_STEP = 0, 1
DEFAULT_CYCLES = 5.0  # reference periods per run: one warm-up, three whole cycles measured (see steady_window)


@dataclass(frozen=True)
class Condition:
    """One benchmark condition: plant (disc sets, effects) and sine reference.

    Attributes
    ----------
    disc_sets : int
        Disc sets on the crank, 1..7.
    freq_hz : float
        Reference frequency, Hz.
    amplitude_deg : float
        Reference amplitude, deg.
    effects : tuple
        Effects switched on, as a tuple of (name, ((param, value), ...)) (see :meth:`with_effects`).
    """

    disc_sets: int
    freq_hz: float
    amplitude_deg: float
    effects: tuple = field(default=())

    @staticmethod
    def with_effects(disc_sets: int, freq_hz: float, amplitude_deg: float, effects: dict | None) -> "Condition":
        eff = tuple(sorted((n, tuple(sorted((p or {}).items()))) for n, p in (effects or {}).items()))
        return Condition(int(disc_sets), float(freq_hz), float(amplitude_deg), eff)

    @property
    def effects_dict(self) -> dict:
        return {n: dict(p) for n, p in self.effects}


def grid(disc_sets=range(1, 8), freqs=(1.0, 2.0, 3.0), amplitudes=(10.0, 20.0, 30.0), effects: dict | None = None):
    """The benchmark's conditions, disc sets slowest, then frequency, then amplitude."""
    return [Condition.with_effects(n, f, a, effects) for n in disc_sets for f in freqs for a in amplitudes]


@njit(cache=True)
def _closed_loop(s, P, gains, ref, kind, dt, nsub, n, hist, noise, sensor, k0, k1, metrics, trace):
    """One closed-loop run (the law of kernel.run_rig_controller); metrics and optional trace."""
    k1v = np.empty_like(s)
    k2v = np.empty_like(s)
    k3v = np.empty_like(s)
    k4v = np.empty_like(s)
    tmp = np.empty_like(s)
    out = np.zeros(K.N_OUT)
    adc, dac, gain_err, u_max = sensor[0], sensor[1], sensor[2], sensor[3]
    mem = np.zeros(2)
    hist[:] = 0.0
    se2 = 0.0
    emax = 0.0
    umax_seen = 0.0
    nsat = 0
    dpmax = 0.0
    hit_any = False
    keep = trace.shape[0] > 0
    for k in range(n):
        K.measure(s, P, out)
        t = k * dt
        if kind == 0:
            r, rd, rdd, rddd = K.reference_point(ref, t)
        else:
            r = ref[0] if t >= ref[2] else 0.0
            rd, rdd, rddd = 0.0, 0.0, 0.0
        th_true = math.degrees(out[K.O_THETA])
        th = th_true * (1.0 + gain_err) + noise[k]
        th = K.quantize(th, adc)
        dp = (s[4] - s[5]) * 1e-5
        u = K.quantize(K.rig_control_law(gains, r - th, rd, rdd, rddd, dp, dt, u_max, mem), dac)
        # metrics: tracking on the true (LVDT) angle as ehas_env.simulation.metrics does
        if k >= k0 and k < k1:
            et = r - th_true
            se2 += et * et
            if abs(et) > emax:
                emax = abs(et)
        if abs(u) > umax_seen:
            umax_seen = abs(u)
        if abs(u) >= u_max * (1.0 - 1e-9):
            nsat += 1
        if abs(dp) > dpmax:
            dpmax = abs(dp)
        if keep:
            trace[k, 0] = th_true
            trace[k, 1] = r
            trace[k, 2] = u
            trace[k, 3] = dp
        hist[k % hist.shape[0]] = u
        if K.advance(s, P, hist, k, dt, nsub, 0.0, k1v, k2v, k3v, k4v, tmp):
            hit_any = True
    amp = abs(ref[0])
    cnt = max(k1 - k0, 1)
    metrics[0] = 100.0 * math.sqrt(se2 / cnt) / amp
    metrics[1] = 100.0 * emax / amp
    metrics[2] = umax_seen
    metrics[3] = nsat / n
    metrics[4] = dpmax
    metrics[5] = 1.0 if hit_any else 0.0
    if not math.isfinite(metrics[0]):
        metrics[0] = 1e9


@njit(cache=True)
def _run_batch(S0, P, G, R, kinds, dt, nsub, n_steps, win, hist_len, noise, sensor, metrics, trace):
    hist = np.zeros(hist_len)
    for c in range(S0.shape[0]):
        s = S0[c].copy()
        _closed_loop(s, P[c], G[c], R[c], kinds[c], dt, nsub, n_steps[c], hist, noise[c], sensor[c],
                     win[c, 0], win[c, 1], metrics[c], trace[c])


@njit(cache=True)
def run_relay(s, P, d, hyst, bias, dt, nsub, hist, theta_out, u_out):
    """Relay experiment (Astrom-Hagglund) on the plant: u = bias +- d switching on e = -theta.

    The set point is 0 deg; the relay starts at +d and switches when the error
    crosses +-hyst deg.  theta_out (deg) and u_out (mA) receive the run.
    """
    k1 = np.empty_like(s)
    k2 = np.empty_like(s)
    k3 = np.empty_like(s)
    k4 = np.empty_like(s)
    tmp = np.empty_like(s)
    out = np.zeros(K.N_OUT)
    hist[:] = 0.0
    state = 1.0
    for k in range(theta_out.shape[0]):
        K.measure(s, P, out)
        th = math.degrees(out[K.O_THETA])
        e = -th
        if e > hyst:
            state = 1.0
        elif e < -hyst:
            state = -1.0
        u = bias + state * d
        theta_out[k] = th
        u_out[k] = u
        hist[k % hist.shape[0]] = u
        K.advance(s, P, hist, k, dt, nsub, 0.0, k1, k2, k3, k4, tmp)


class Batch:
    """A prepared set of conditions that can be run with many gain vectors quickly.

    Parameters
    ----------
    conditions : list of Condition
        Plants and references.
    cycles : float
        Reference periods per run (the first is warm-up).
    sensors : ehas_env.simulation.sensors.Sensors, optional
        Measurement chain of every plant (ideal by default).
    seed : int
        Seed of the sensor noise (per condition: the same noise as ``Plant(seed=seed)``).
    plant_kwargs : dict, optional
        Extra :class:`ehas_env.simulation.plant.Plant` keyword arguments (e.g. a model file's ``rig``).
    step : bool
        Step references of ``amplitude_deg`` at t = 0 instead of sines (``cycles`` then counts
        periods of ``1/freq_hz`` for the duration; metrics use the same window).
    """

    def __init__(self, conditions, *, cycles: float = DEFAULT_CYCLES, sensors=None, seed: int = 0,
                 plant_kwargs: dict | None = None, step: bool = False):
        from ehas_env.physics.effects import resolve_effects
        from ehas_env.simulation.metrics import steady_window
        from ehas_env.simulation.plant import TAU_MAX, Plant
        from ehas_env.simulation.reference import SineReference

        self.conditions = list(conditions)
        if not self.conditions:
            raise ValueError("Batch: no conditions")
        if not (math.isfinite(cycles) and cycles > 2):
            raise ValueError(f"cycles must be > 2 reference periods (the first is warm-up, then whole cycles), got {cycles!r}")
        self.cycles = float(cycles)
        m = len(self.conditions)
        plants = {}
        kw = dict(plant_kwargs or {})
        kw.pop("disc_sets", None)  # each condition sets its own
        base_effects = resolve_effects(kw.pop("effects", None))
        if sensors is not None:
            kw["sensors"] = sensors
        self.plants = []
        for c in self.conditions:
            key = (c.disc_sets, c.effects)
            if key not in plants:
                effects = {**base_effects, **c.effects_dict}
                plants[key] = Plant(disc_sets=c.disc_sets, effects=effects or None, seed=seed, **kw)
            self.plants.append(plants[key])
        p0 = self.plants[0]
        self.dt, self.nsub = p0.dt, p0.substeps
        if any(p.dt != self.dt or p.substeps != self.nsub for p in self.plants):
            raise ValueError("Batch: every plant must share dt and substeps")
        self.hist_len = K.history_length(TAU_MAX, self.dt)
        self.S0 = np.array([p.initial_state() for p in self.plants])
        self.P = np.array([p.param_vector for p in self.plants])
        self.R = np.zeros((m, 4))
        self.kinds = np.full(m, REF_STEP if step else REF_SINE, dtype=np.int64)
        self.n_steps = np.zeros(m, dtype=np.int64)
        self.win = np.zeros((m, 2), dtype=np.int64)
        for j, c in enumerate(self.conditions):
            if step:
                self.R[j] = (c.amplitude_deg, c.freq_hz, 0.0, 0.0)
            else:
                self.R[j] = SineReference(c.amplitude_deg, c.freq_hz).kernel_vector()
            n = int(round(self.cycles / c.freq_hz / self.dt))  # as Plant.simulate_closed_loop
            self.n_steps[j] = n
            mask = steady_window(np.arange(n) * self.dt, c.freq_hz)
            idx = np.flatnonzero(mask)
            self.win[j] = (idx[0], idx[-1] + 1)
        nmax = int(self.n_steps.max())
        self.noise = np.zeros((m, nmax))
        for j, p in enumerate(self.plants):
            rng = np.random.default_rng(p.seed)
            self.noise[j, : self.n_steps[j]] = p.sensors.theta_noise(int(self.n_steps[j]), rng)
        self.sensor = np.array([p.sensors.kernel_vector(p.rig.i_max) for p in self.plants])

    def __len__(self) -> int:
        return len(self.conditions)

    def run(self, gains, *, i_max=None, dac_lsb=None, trace: bool = False):
        """Metrics (len, 6) for gains (7,) shared or (len, 7) per condition.

        ``i_max`` / ``dac_lsb`` (scalars or per-condition arrays) override the controller's
        output limit and DAC step (default: the plant's +-20 mA, the sensors' DAC).
        With ``trace=True`` also returns an array (len, n_max, 4): theta deg, theta_ref deg,
        current mA, load pressure bar.
        """
        m = len(self)
        G = np.asarray(gains, dtype=float)
        if G.ndim == 1:
            G = np.broadcast_to(G, (m, G.size))
        if G.shape != (m, 7):
            raise ValueError(f"gains must have shape (7,) or ({m}, 7), got {G.shape}")
        if not np.all(np.isfinite(G)):
            raise ValueError("gains must be finite")
        sensor = self.sensor.copy()
        if i_max is not None:
            sensor[:, 3] = i_max
        if dac_lsb is not None:
            sensor[:, 1] = np.maximum(sensor[:, 1], dac_lsb)
        metrics = np.zeros((m, N_METRICS))
        # without a trace each condition gets a (0, 4) view: nothing is stored
        tr = np.zeros((m, int(self.n_steps.max()) if trace else 0, 4))
        _run_batch(self.S0, self.P, np.ascontiguousarray(G), self.R, self.kinds, self.dt, self.nsub, self.n_steps,
                   self.win, self.hist_len, self.noise, sensor, metrics, tr)
        return (metrics, tr) if trace else metrics

    def rows(self, metrics) -> list[dict]:
        """Metrics as a list of dicts with the condition's fields."""
        out = []
        for c, m in zip(self.conditions, metrics):
            row = {"disc_sets": c.disc_sets, "freq_hz": c.freq_hz, "amplitude_deg": c.amplitude_deg,
                   "effects": c.effects_dict}
            row.update({k: float(v) for k, v in zip(METRICS, m)})
            row["hit_stroke_end"] = bool(m[5] > 0.5)
            out.append(row)
        return out


def controller_gains(controller, conditions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-condition gain matrix, output limit and DAC step of a RigController-expressible controller."""
    G, imax, dac = [], [], []
    for c in conditions:
        sub = controller.for_plant(c.disc_sets) if hasattr(controller, "for_plant") else controller
        rc = sub.rig_gains(c.disc_sets) if hasattr(sub, "rig_gains") else sub
        if rc is None:
            raise ValueError(f"controller {getattr(controller, 'name', controller)!r} has no compiled form (rig_gains)")
        G.append(rc.gains_vector())
        imax.append(getattr(sub, "i_max", 20.0))
        dac.append(getattr(sub, "dac_lsb", 0.0))
    return np.array(G), np.array(imax), np.array(dac)


def evaluate(controller, conditions, *, cycles: float = DEFAULT_CYCLES, sensors=None, seed: int = 0,
             plant_kwargs: dict | None = None, batch: Batch | None = None) -> list[dict]:
    """Metrics of ``controller`` (a PIFF, GainSchedule or RigController) on each condition."""
    batch = batch or Batch(conditions, cycles=cycles, sensors=sensors, seed=seed, plant_kwargs=plant_kwargs)
    G, imax, dac = controller_gains(controller, batch.conditions)
    return batch.rows(batch.run(G, i_max=imax, dac_lsb=dac))
