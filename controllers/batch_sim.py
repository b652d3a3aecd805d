"""Batched closed-loop simulation: many conditions and controllers in one serial numba loop.

Runs the model's one closed-loop driver (``closed_loop_batch`` of
:mod:`ehas_env.simulation.loops`, compiled into the plant's model) with each
controller's compiled law; the plant is :class:`ehas_env.simulation.plant.Plant`'s
parameter vector with any effects.  A controller with no compiled law (only
``act``) runs through ``Plant.simulate_closed_loop`` in Python, slower.  Each
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

from ehas_env.physics import layout as K
from ehas_env.simulation.compiled_model import current_model, fast_model_behind, names_hypothesis
from ehas_env.simulation.control_laws import N_GAINS, compiled_form
from ehas_env.simulation.loops import METRICS, REF_SINE, REF_STEP
from ehas_env.simulation.metrics import percent_errors

#: from this many conditions on a Batch runs the inlined fast-step build (see Batch.__init__)
FAST_STEP_MIN_CONDITIONS = 32

N_METRICS = len(METRICS)
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
        # a benchmark grid is a hot loop: the inlined build (fast step, long compile); a handful of conditions (the
        # demo's 7 rig tests, a tuner's check) runs in milliseconds on either, so there the compile is the wait and
        # the plants' quick build serves.  Both builds share the plants' parameter layout and give the same numbers.
        fast = len(self.conditions) >= FAST_STEP_MIN_CONDITIONS
        # a plant with a structural hypothesis (a model file's hyp_rod_area) runs on the model that holds them
        hypotheses = any(names_hypothesis(p.effects) for p in self.plants)
        self.model = current_model(inline=fast, hypotheses=hypotheses)
        if any(p.model.SLOTS != self.model.SLOTS for p in self.plants):
            raise ValueError("Batch: every plant must run on the same compiled model")
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
        # the grid's first time on this machine: the quick build (compiled in seconds) runs it while a background
        # process compiles the inlined one; run() switches to it once it is loaded (the same numbers either way)
        self._builds = None
        if fast and not hypotheses:  # the background compile builds the model without the hypotheses
            example = (self.S0, self.P, np.zeros(m, np.int64), np.zeros((m, N_GAINS)), self.R, self.kinds, self.dt,
                       self.nsub, self.hist_len, self.noise, self.n_steps, self.sensor, self.win,
                       np.zeros((m, N_METRICS)), np.zeros((m, 0, K.N_OUT)))
            self._builds = fast_model_behind({"closed_loop_batch": example}, "the benchmark grid",
                                             "inline, benchmark grid", meanwhile="quick")
            self.model = self._builds.model

    def __len__(self) -> int:
        return len(self.conditions)

    @property
    def fast_step(self) -> bool:
        """True when the grid runs on the fast-step build (False: the quick build -- a small batch's, or a large
        one's while the fast-step build compiles in the background)."""
        return self._builds is not None and self._builds.done and self.model is self._builds.fast

    def run(self, gains, *, i_max=None, dac_lsb=None, trace: bool = False, laws=None):
        """Metrics (len, 6) for gains (n,) shared or (len, n) per condition, n <= N_GAINS.

        ``laws``: compiled law number per condition (default: the PI + feed-forward law).
        ``i_max`` / ``dac_lsb`` (scalars or per-condition arrays) override the controller's
        output limit and DAC step (default: the plant's +-20 mA, the sensors' DAC).
        With ``trace=True`` also returns an array (len, n_max, 4): theta deg, theta_ref deg,
        current mA, load pressure bar.
        """
        from ehas_env.simulation.plant import RigController

        m = len(self)
        G = np.asarray(gains, dtype=float)
        if G.ndim == 1:
            G = np.broadcast_to(G, (m, G.size))
        if G.ndim != 2 or G.shape[0] != m or G.shape[1] > N_GAINS:
            raise ValueError(f"gains must have shape (n,) or ({m}, n) with n <= {N_GAINS}, got {G.shape}")
        if not np.all(np.isfinite(G)):
            raise ValueError("gains must be finite")
        Gp = np.zeros((m, N_GAINS))
        Gp[:, :G.shape[1]] = G
        law = np.full(m, RigController.law_id(), dtype=np.int64) if laws is None else np.asarray(laws, dtype=np.int64)
        sensor = self.sensor.copy()
        if i_max is not None:
            sensor[:, 3] = i_max
        if dac_lsb is not None:
            sensor[:, 1] = np.maximum(sensor[:, 1], dac_lsb)
        metrics = np.zeros((m, N_METRICS))
        # without a trace each condition gets a (0, N_OUT) view: nothing is stored
        out = np.zeros((m, int(self.n_steps.max()) if trace else 0, K.N_OUT))
        if self._builds is not None and (not self._builds.done or self.model is not self._builds.model):
            self.model = self._builds.poll()
        self.model.closed_loop_batch(self.S0, self.P, law, Gp, self.R, self.kinds, self.dt, self.nsub, self.hist_len,
                                     self.noise, self.n_steps, sensor, self.win, metrics, out)
        from ehas_env.simulation.finite import check_metrics

        check_metrics(metrics, self.conditions, "the controller" if laws is None else
                      ", ".join(sorted({n for k, (n, _) in enumerate(_laws()) if k in set(law.tolist())})))
        for j in range(m):
            pct = percent_errors(metrics[j, 0], self.win[j, 1] - self.win[j, 0], metrics[j, 1], self.R[j, 0])
            metrics[j, 0], metrics[j, 1] = pct["rms_error_pct"], pct["peak_error_pct"]
        if not trace:
            return metrics
        tr = np.zeros((m, out.shape[1], 4))
        tr[:, :, 0] = np.degrees(out[:, :, K.O_THETA])
        for j in range(m):
            n = int(self.n_steps[j])
            t = np.arange(n) * self.dt
            if self.kinds[j] == REF_SINE:
                tr[j, :n, 1] = [self.model.reference_point(self.R[j], tk)[0] for tk in t]
            else:
                tr[j, :n, 1] = np.where(t >= self.R[j, 2], self.R[j, 0], 0.0)
        tr[:, :, 2] = out[:, :, K.O_CURRENT]
        tr[:, :, 3] = (out[:, :, K.O_PA] - out[:, :, K.O_PB]) * 1e-5
        return metrics, tr

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


def _laws():
    from ehas_env.simulation.control_laws import all_laws

    return all_laws()


def controller_gains(controller, conditions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-condition gains, output limit, DAC step and compiled law number of a compiled controller."""
    G, imax, dac, laws = [], [], [], []
    for c in conditions:
        sub = controller.for_plant(c.disc_sets) if hasattr(controller, "for_plant") else controller
        rc = compiled_form(controller, c.disc_sets)
        if rc is None:
            raise ValueError(f"controller {getattr(controller, 'name', controller)!r} has no compiled law; "
                             "it runs through evaluate() in Python")
        G.append(rc.gains_vector())
        laws.append(rc.law_id())
        imax.append(getattr(sub, "i_max", 20.0))
        dac.append(getattr(sub, "dac_lsb", 0.0))
    return np.array(G), np.array(imax), np.array(dac), np.array(laws, dtype=np.int64)


def evaluate(controller, conditions, *, cycles: float = DEFAULT_CYCLES, sensors=None, seed: int = 0,
             plant_kwargs: dict | None = None, batch: Batch | None = None) -> list[dict]:
    """Metrics of a controller with a compiled law on each condition, in one batched loop.

    (``ehas_controllers.benchmark.evaluate_controller`` also runs controllers that only have a
    Python ``act``.)
    """
    batch = batch or Batch(conditions, cycles=cycles, sensors=sensors, seed=seed, plant_kwargs=plant_kwargs)
    G, imax, dac, laws = controller_gains(controller, batch.conditions)
    return batch.rows(batch.run(G, i_max=imax, dac_lsb=dac, laws=laws))
