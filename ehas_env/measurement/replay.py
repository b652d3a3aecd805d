"""Replaying a campaign with the model: simulated signals, residuals and fit %.

Closed-loop runs are re-simulated with the logged controller gains and the
sidecar's reference (the model's controller computes its own current from the
simulated angle, so both the angle and the current are outputs to compare);
valve runs are driven open-loop by the logged current.  The replay's sensors are
ideal: the rig's controller saw a noisy angle, the model's sees the noise-free
one.  Everything runs in the compiled model (``ehas_env.physics.codegen``), about
10 ms per 3 s closed-loop run.

The fit of a signal is the NRMSE fit of :func:`ehas_env.simulation.metrics.fit_percent`;
a campaign's fit per signal is the mean over its runs, and its overall fit the
mean over signals (docs/measurement-format.md).  A signal whose measured variation is at
its noise level (a regulated supply pressure) carries no shape to fit and is
left out of the fit % (it still counts in the calibration cost).

Examples
--------
>>> from ehas_env.measurement.synthetic import simulate_campaign
>>> from ehas_env.measurement.campaign import Campaign, validate_run
>>> runs, truth = simulate_campaign({"coulomb_friction": {"Fc": 350}}, seed=5, duration=1.0,
...                                 plan=DEFAULT_DOC_PLAN)
>>> camp = Campaign(None, [validate_run(n, c, m) for n, c, m in runs])
>>> rep = Replayer(camp)
>>> base = rep.fit_table(rep.simulate(ModelSpec()))
>>> true = rep.fit_table(rep.simulate(ModelSpec(effects=truth["effects"])))
>>> true.overall > base.overall
True
"""
from __future__ import annotations

import contextlib
import contextvars
import functools
import math
import os
import threading
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ehas_env.physics import layout as KN
from ehas_env.simulation.control_laws import N_GAINS
from ehas_env.measurement.campaign import Campaign, Run, reference_of
from ehas_env.measurement.verdict import envelope_cost_block, sine_timing, unpredictable_runs
from ehas_env.physics.c_drivers import c_drivers, wanted as c_drivers_wanted
from ehas_env.physics.effects import resolve_effects
from ehas_env.simulation.metrics import fit_percent
from ehas_env.simulation.plant import TAU_MAX, Plant, RigController, at_rest
from ehas_env.physics.rig import BAR, BULK_MODULUS, LPM, VALVE_K, RigParams
from ehas_env.ranges import check_field

DEFAULT_DOC_PLAN = ((2, 15.0, 2.0),)  # a tiny plan for doctests

#: replays of a model's rest kept for the static blocks at logged readings applied to it (the last few models
#: screened on: a screen's base, the model kept and the library's)
REST_KEPT = 4

#: models compiled behind, in a background process (:meth:`Replayer.compile_behind`): {(process id, id(module)):
#: FastBuildBehind} (a forked child does not wait on its parent's)
_BEHIND: dict = {}
_TAKEN: dict = {}  # ... the compile watcher's entries of each (codegen.take_fresh), given back if it gave up
_BEHIND_LOCK = threading.Lock()


def _wait_behind(mod) -> None:
    """Before the first replay on ``mod``: when a background process compiles it, wait for it and load what it
    compiled (each thread of the screens side by side waits here; one loads)."""
    key = (os.getpid(), id(mod))
    behind = _BEHIND.get(key)
    if behind is None or behind.done:
        return
    with _BEHIND_LOCK:
        from ehas_env.output.progress import status
        from ehas_env.physics.codegen import HEARTBEAT_S

        t0 = time.monotonic()
        while not behind.done:  # nothing silent for long: a line every HEARTBEAT_S while it waits
            behind.wait(HEARTBEAT_S)
            if not behind.done:
                status(f"the diagnosis waits for the background compile of the {behind.fast_name} "
                       f"({time.monotonic() - t0:.0f} s so far)")
        taken = _TAKEN.pop(key, None)
        if taken is not None and not behind.compiled_behind():
            # it gave up: the compile happens here, announced and recorded as one of this process
            from ehas_env.physics.codegen import put_fresh

            put_fresh(mod, taken)


#: closed-loop signals in the order tables show them
CL_SIGNALS = ("theta_deg", "current_mA", "flow_lpm", "p_a_bar", "p_b_bar", "p_s_bar", "load_kN")
VALVE_SIGNALS = ("flow_lpm",)
#: signals that enter the calibration cost and the verdict: every logged signal.  The load reading is judged too:
#: in the model it is A (P_A - P_B) through its reading, so a miss there that the pressures do not show is the load
#: cell's own (a lag, a rate limit, an offset in its reading), and a verdict that left it out called a campaign
#: "explained" with its load cell 40 dB off (issue 42); each run and signal is its own block of the geometric mean,
#: so the pressure difference counted twice only adds one block of seven
COST_SIGNALS = ("theta_deg", "current_mA", "flow_lpm", "p_a_bar", "p_b_bar", "p_s_bar", "load_kN")
#: the logged column of each sensed output (ehas_env.physics.layout.SENSED): what a term at its reading place moves
SENSED_COLUMNS = {"pa": "p_a_bar", "pb": "p_b_bar", "ps": "p_s_bar", "flow_a": "flow_lpm", "force": "load_kN"}
UNITS = {"theta_deg": "deg", "current_mA": "mA", "flow_lpm": "LPM", "p_a_bar": "bar", "p_b_bar": "bar",
         "p_s_bar": "bar", "load_kN": "kN"}
#: least noise level assumed per signal (engineering units): keeps the weights finite for ideal
#: (noise-free) data; about a 16-bit converter's step on each channel's span
NOISE_FLOOR = {"theta_deg": 2e-3, "current_mA": 2e-3, "flow_lpm": 2e-3, "p_a_bar": 1e-2, "p_b_bar": 1e-2,
               "p_s_bar": 1e-2, "load_kN": 1e-3}
#: a signal is informative (enters the fit %) when its std exceeds this many noise levels
INFORMATIVE = 5.0


def noise_level(y: np.ndarray) -> float:
    """Robust estimate of a signal's white-noise std from its third differences.

    Smooth signals sampled fast have small third differences; white noise of
    std s gives third differences of std s sqrt(20).  The median absolute
    deviation keeps spikes out.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(3000) * 1e-3
    >>> round(noise_level(20 * np.sin(2 * np.pi * t) + rng.normal(0, 0.2, t.size)), 2)
    0.2
    """
    d3 = np.diff(np.asarray(y, dtype=float), 3)
    if d3.size < 10:
        return 0.0
    mad = np.median(np.abs(d3 - np.median(d3)))
    return float(1.4826 * mad / math.sqrt(20.0))


#: set while a Ctrl-C stops screens run side by side on threads (:mod:`ehas_env.diagnosis.side_by_side`): a replay
#: asked then raises :class:`ReplaysStopped` at once, so each thread ends at its next replay, not at its fit's end
STOP = threading.Event()


class ReplaysStopped(Exception):
    """A replay asked while :data:`STOP` is set."""


#: the kept rests (:meth:`Replayer.simulate_many`) of one call among calls run side by side: {id(replayer): rests}
_REST_SCOPE = contextvars.ContextVar("ehas_rest_scope", default=None)


@contextlib.contextmanager
def own_rests():
    """Within this context each replayer keeps the rests it replays apart, starting from those it kept before.

    Calls run side by side on threads (:mod:`ehas_env.diagnosis.side_by_side`) would otherwise share them: which
    one replays a rest and which one reads it would depend on which came first, and so would the count of
    replays.  Apart, each call replays what it would replay alone after the calls before the threads began.
    """
    outer = _REST_SCOPE.get()  # within a call that keeps its own: from those
    token = _REST_SCOPE.set({k: dict(v) for k, v in (outer or {}).items()})
    try:
        yield
    finally:
        _REST_SCOPE.reset(token)


@dataclass(frozen=True)
class ModelSpec:
    """The model to replay: baseline (with recalibrated beta and K) plus effects.

    Attributes
    ----------
    effects : dict
        {effect: {param: value}} (defaults filled for missing params).
    beta : float
        Bulk modulus, Pa (the reference model's 1e9 by default); an effect that
        sets beta (``bulk_modulus``) overrides it.
    K : float
        Valve flow gain, LPM/mA (the book's 1.2723); ``valve_dynamics`` overrides it.
    terms : dict
        Coefficients of proposed terms, ``{"<term class>.<coefficient>": SI value}``
        (:mod:`ehas_env.measurement.proposal_terms`); empty for a model of effects only.
    """

    effects: dict = field(default_factory=dict)
    beta: float = BULK_MODULUS
    K: float = VALVE_K
    terms: dict = field(default_factory=dict)

    def resolved(self) -> "ModelSpec":
        return ModelSpec(resolve_effects(self.effects), float(self.beta), float(self.K), dict(self.terms))

    def rig(self, supply_bar: float) -> RigParams:
        return RigParams(beta=self.beta, K=self.K, supply=supply_bar * BAR)


#: a logged load is the logger's own combination of the logged pressures when what the pressures' best
#: combination leaves of it is below this share of its noise level (a load cell's reading leaves its own noise)
DERIVED_SHARE = 0.01


def derived_load(measured: dict, noise: float) -> bool:
    """Whether a run's logged load is computed from its logged chamber pressures (``a P_A - b P_B`` for some
    areas, fitted) rather than read by a load cell: what the best such combination leaves of it is below
    :data:`DERIVED_SHARE` of its noise level.  Such a column is not compared with the model (the pressures are, and
    a miss in them would be counted twice; a pressure reading's own error, an offset, would leave it missed
    however well the model reads the chamber); a load cell's reading is (its own lag or range shows there alone).

    Parameters
    ----------
    measured : dict
        The run's logged signals (``load_kN``, ``p_a_bar``, ``p_b_bar``).
    noise : float
        The load's noise level, kN.

    Returns
    -------
    bool

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> pa, pb = 100 + 40 * rng.standard_normal(500), 100 + 40 * rng.standard_normal(500)
    >>> derived_load({"load_kN": 0.5 * (pa - pb), "p_a_bar": pa, "p_b_bar": pb}, 0.01)
    True
    >>> derived_load({"load_kN": 0.5 * (pa - pb) + 0.01 * rng.standard_normal(500), "p_a_bar": pa,
    ...               "p_b_bar": pb}, 0.01)
    False
    """
    if not {"load_kN", "p_a_bar", "p_b_bar"} <= set(measured):
        return False
    y = np.asarray(measured["load_kN"], dtype=float)
    X = np.column_stack([np.asarray(measured["p_a_bar"], float), -np.asarray(measured["p_b_bar"], float)])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    left = y - X @ coef
    return bool(np.sqrt(np.mean(left ** 2)) <= DERIVED_SHARE * noise)


@dataclass
class _Case:
    """What one run needs for fast replays (arrays built once)."""

    run: Run
    signals: tuple[str, ...]
    measured: dict[str, np.ndarray]
    noise: dict[str, float]
    dt: float  # simulation period (controller period for closed loop)
    n_sim: int
    resample: bool
    gains: np.ndarray | None = None
    ref: np.ndarray | None = None
    zeros: np.ndarray | None = None
    theta0: float = 0.0
    cmd: np.ndarray | None = None
    skip: int = 0  # leading samples left out of cost and fit (the warm-up of a window cut from a valve run)
    supply: np.ndarray | None = None  # the measured supply, Pa, one per simulation step (None: the sidecar's)
    derived: tuple = ()  # logged columns the logger computed from others (:func:`derived_load`): not compared

    @property
    def hist_len(self) -> int:
        """Length of a replay's command history at this run's simulation period (each replay has its own)."""
        return KN.history_length(TAU_MAX, self.dt) + 2


class _Job(NamedTuple):
    """One replay made ready by :meth:`Replayer._prepare`: everything its compiled driver needs."""

    case: _Case
    mod: object  # the compiled model module
    P: np.ndarray
    s0: np.ndarray | None  # initial state (closed loop); None for a valve run
    i_max: float
    out: np.ndarray

    @property
    def driver(self):
        """The compiled function that runs it: the closed loop, or the valve bench; the C compiler's build of it
        where there is one (:mod:`ehas_env.physics.c_drivers`: numba's numbers, no numba compile), else
        numba's."""
        name = "run_valve_test" if self.s0 is None else "closed_loop"
        built = c_drivers(self.mod)
        return getattr(built if built is not None else self.mod, name)


@dataclass
class FitTable:
    """Fit % of a replay: per run and signal, per signal, overall.

    Attributes
    ----------
    per_run : dict
        run name -> {signal: fit %} (informative signals only).
    per_signal : dict
        signal -> mean fit % over the runs that have it.
    overall : float
        Mean of ``per_signal``.
    rms : dict
        run name -> {signal: RMS residual in the signal's unit} (every compared signal).
    """

    per_run: dict[str, dict[str, float]]
    per_signal: dict[str, float]
    overall: float
    rms: dict[str, dict[str, float]]


def log_mean(blocks) -> float:
    """The fit's cost of residual blocks: the geometric mean over blocks of each one's mean square, weighted by its
    samples (:meth:`Replayer.log_cost`; the blocks already in noise units).

    Parameters
    ----------
    blocks : sequence of ndarray
        Noise-normalised residuals, one per run and signal.

    Returns
    -------
    float

    Examples
    --------
    >>> round(log_mean([np.full(10, 2.0), np.full(10, 0.5)]), 6)   # mean squares 4 and 0.25
    1.0
    """
    n = sum(b.size for b in blocks)
    return float(np.exp(sum(b.size * np.log(max(float(np.dot(b, b)) / b.size, 1e-300)) for b in blocks) / n))


class Replayer:
    """Replays a campaign with any :class:`ModelSpec`; computes residuals and fits.

    Parameters
    ----------
    campaign : Campaign
        Validated runs (``ehas_env.measurement.campaign.read_campaign``).
    substeps : int
        RK4 sub-steps per control period (10, as the plant's default).
    model : PlantModel or str, optional
        A model file (docs/model-file.md): the rig every run is replayed on, its
        effects always on.  A :class:`ModelSpec`'s ``beta`` and ``K`` then scale
        the model's own (``beta_model * beta / 1e9``, ``K_model * K / 1.2723``), so
        the recalibration ranges of the diagnosis hold around the model's numbers;
        :meth:`absolute` gives the numbers the plant runs.
    hypotheses : bool
        The replays of a proposal's terms start from the plants of the compiled model that also holds the
        diagnosis' structural hypotheses and blocks (:func:`ehas_env.simulation.compiled_model.current_model`),
        as every replay did before 2026-12-02.  Any other replay runs on the model of the registered effects
        unless it names a hypothesis or block: the same numbers bit for bit (an effect that is off is skipped;
        ``tests/measurement/test_replay.py``), at about 0.067 CPU s a replay of a 5-run campaign against 0.087
        on the larger model; a diagnosis that never names one never compiles the larger model (a clean
        5-run campaign on an empty model cache: 34.7 s -> 13.9 s; one whose alternatives fit a hypothesis
        compiles it there: Coulomb friction kept, 59.1 s -> 54.1 s; 2026-12-02, load 1.2-1.6 on 2 cores).
    threads : int, optional
        Replays run side by side on this many threads, 1 to 1024 (default: one per core this process may use).
    inputs : dict, optional
        Measured inputs: {run name: {quantity: series at the run's samples, in the quantity's unit}}, the only
        quantity today ``p_s_bar`` (the supply pressure, bar), cleared of its noise by
        :func:`ehas_env.diagnosis.measured_inputs.measured` (which makes such a replayer).  A run given one is
        replayed with it instead of the sidecar's constant ``supply_bar`` (a closed-loop run's control period at
        its mid-point value, the bench's sample at its own), starting at rest at it, and the quantity is no longer
        an output compared.  None (default): every run at its sidecar's supply.
    """

    def __init__(self, campaign: Campaign, substeps: int = 10, model=None, hypotheses: bool = False,
                 threads: int | None = None, inputs: dict | None = None):
        from ehas_env.simulation.model_file import as_model

        self.campaign = campaign
        self.substeps = substeps
        self.model = as_model(model)
        self.hypotheses = bool(hypotheses)
        self.threads = None if threads is None else check_field("workers", threads, "threads")
        self.inputs = dict(inputs or {})
        self.cases = [self._case(r) for r in campaign.runs]
        self.n_evals = 0
        self._count = threading.Lock()  # n_evals is counted from screens run side by side (diagnosis.side_by_side)
        self._executor = None  # (pid, ThreadPoolExecutor) of :meth:`_pool`
        self._rests = {}  # replays of models' rests that static blocks at logged readings apply to (simulate_many)

    @property
    def runs(self) -> list[Run]:
        return self.campaign.runs

    # -- setup ------------------------------------------------------------------------------
    def _case(self, run: Run) -> _Case:
        if run.kind == "closed_loop":
            signals = tuple(s for s in CL_SIGNALS if s in run.columns)
            measured = {s: run.columns[s] for s in signals}
            ctrl = run.meta["controller"]
            dt = 1.0 / ctrl["rate_hz"]
            resample = abs(dt - run.dt) > 1e-9 * run.dt
            n_sim = run.n if not resample else int(math.ceil(run.duration / dt)) + 1
            gains = np.zeros(N_GAINS)
            gains[:7] = [ctrl[k] for k in ("Kp", "Ki", "Kv", "Ka", "Kj", "Kdp", "dp_hp")]
            case = _Case(run, signals, measured, {}, dt, n_sim, resample,
                         gains=gains, ref=reference_of(run).kernel_vector(), zeros=np.zeros(n_sim),
                         theta0=float(run.columns["theta_deg"][0]))
        else:
            signals = VALVE_SIGNALS
            measured = {"flow_lpm": run.columns["flow_lpm"]}
            case = _Case(run, signals, measured, {}, run.dt, run.n, False,
                         cmd=np.ascontiguousarray(run.columns["current_mA"], dtype=float))
        case.noise = {s: max(noise_level(y), NOISE_FLOOR[s]) for s, y in measured.items()}
        if "load_kN" in case.signals and derived_load(measured, case.noise["load_kN"]):
            # the logger's A (P_A - P_B) of the logged pressures: nothing of its own to compare (counted twice else)
            case.signals = tuple(s for s in case.signals if s != "load_kN")
            case.derived = ("load_kN",)
        window = run.meta.get("window") or {}
        case.skip = int(window.get("skip", 0))
        for s, nz in (window.get("noise") or {}).items():
            if s in case.noise:
                case.noise[s] = nz
        given = self.inputs.get(run.name, {})
        for q in given:
            if q != "p_s_bar":
                raise ValueError(f"inputs[{run.name!r}]: {q!r} is not a quantity the model can take as a measured "
                                 "input; allowed: p_s_bar")
        if "p_s_bar" in given:
            y = np.asarray(given["p_s_bar"], dtype=float)
            if y.shape != (run.n,) or not np.all(np.isfinite(y)):
                raise ValueError(f"inputs[{run.name!r}]['p_s_bar']: expected {run.n} finite values (bar), one per "
                                 f"sample of the run")
            if run.kind == "closed_loop":  # each control period at its mid-point value
                y = np.interp((np.arange(case.n_sim) + 0.5) * case.dt, run.t - run.t[0], y)
            case.supply = np.ascontiguousarray(y * BAR)
            case.signals = tuple(s for s in case.signals if s != "p_s_bar")
        return case

    def plant(self, model: ModelSpec, run: Run, dt: float | None = None) -> Plant:
        """The :class:`Plant` that ``model`` is for this run (disc sets, supply, period)."""
        sets = run.meta.get("disc_sets", 1)
        hypotheses = self.hypotheses and bool(model.terms)  # otherwise the plant's effects choose the model
        if self.model is not None:  # the model file's rig, its effects with the spec's (docs/model-file.md)
            m = self.absolute(model)
            return Plant(disc_sets=sets, effects=model.effects, model=self.model, dt=dt or run.dt,
                         substeps=self.substeps, hypotheses=hypotheses,
                         rig=self.model.rig.replace(beta=m.beta, K=m.K, supply=run.meta["supply_bar"] * BAR))
        return Plant(disc_sets=sets, effects=model.effects, rig=model.rig(run.meta["supply_bar"]),
                     dt=dt or run.dt, substeps=self.substeps, hypotheses=hypotheses)

    def compiled(self, model: ModelSpec, run: Run, dt: float | None = None):
        """(compiled model module, parameter vector, plant) that ``model`` runs on for this run.

        A model with proposed ``terms`` runs on the extended model of
        :func:`ehas_env.measurement.proposal_terms.extended_model`.
        """
        plant = self.plant(model, run, dt)
        if not model.terms:
            return plant.model, plant.param_vector, plant
        from ehas_env.measurement.proposal_terms import extended_model, term_slots
        from ehas_env.physics.effects.base import mark_effects_on

        ext = extended_model()
        named = plant.slots()
        named.update(term_slots(model.terms))
        mark_effects_on(named, ext)
        return ext, np.array([named.get(n, 0.0) for n in ext.SLOTS], dtype=float), plant

    @staticmethod
    def initial_state(mod, plant: Plant, theta0_deg: float) -> np.ndarray:
        """``plant``'s initial state (:meth:`Plant.initial_state`) laid out for the compiled model ``mod`` it runs
        on: the same vector when ``mod`` is the plant's own model; for the extended model of a proposal (every
        registered effect, :meth:`compiled`) each state by name, and the states of effects the plant does not
        have at their declared initial values.  (An effect with states of its own makes the two layouts
        differ in length and order.)"""
        s = plant.initial_state(theta0_deg)
        if mod is plant.model:
            return s
        from ehas_env.physics.effects import REGISTRY

        out = np.zeros(mod.N_STATES)
        pos = {n: k for k, n in enumerate(mod.STATE_NAMES)}
        for name in mod.STATE_NAMES:
            eff, _, own = name.partition(".")
            if own and eff in REGISTRY:
                out[pos[name]] = next((st[2] for st in REGISTRY[eff].states if st[0] == own), 0.0)
        missing = [n for n in plant.model.STATE_NAMES if n not in pos]
        if missing:
            raise ValueError(f"the extended model has no state {missing[0]!r} of the plant's model")
        for k, name in enumerate(plant.model.STATE_NAMES):
            out[pos[name]] = s[k]
        return at_rest(mod, out)

    def subset(self, indices) -> "Replayer":
        """A replayer of some of this one's runs: the same substeps, model file, hypotheses, threads and measured
        inputs (each run's own).

        Parameters
        ----------
        indices : iterable of int
            Indices into :attr:`cases`.

        Returns
        -------
        Replayer
        """
        runs = [self.cases[i].run for i in indices]
        return Replayer(Campaign(self.campaign.path, runs), substeps=self.substeps, model=self.model,
                        hypotheses=self.hypotheses, threads=self.threads,
                        inputs={r.name: self.inputs[r.name] for r in runs if r.name in self.inputs})

    def absolute(self, model: ModelSpec) -> ModelSpec:
        """``model`` with the bulk modulus (Pa) and valve gain (LPM/mA) the plant runs (see ``model=``)."""
        if self.model is None:
            return model
        from dataclasses import replace

        return replace(model, beta=self.model.rig.beta * model.beta / BULK_MODULUS,
                       K=self.model.rig.K * model.K / VALVE_K)

    # -- simulation -------------------------------------------------------------------------
    def simulate(self, model: ModelSpec, runs=None) -> list[dict[str, np.ndarray] | None]:
        """Simulated signals of every run (or of the run indices ``runs``) at the logged samples.

        Closed-loop entries also hold ``omega_deg_s`` (model's crank rate), useful
        as a regressor.  Entries not simulated are None.
        """
        return self.simulate_many([model], runs)[0]

    def simulate_many(self, models: list[ModelSpec], runs=None) -> list[list[dict[str, np.ndarray] | None]]:
        """:meth:`simulate` for several models at once: every (model, run) replay side by side on the cores.

        The compiled drivers release the GIL, so Python threads run them in parallel (a ``prange`` driver
        did this before and cost a compile of its own, 4 s of a first diagnosis).  A model whose static blocks at
        logged readings may be applied to the replay of the rest (:mod:`ehas_env.measurement.logged_readings`) is
        that: the rest replayed once (and kept for the next call: a screen of such a block tries many values on
        one model), the blocks applied; only the replays of the rest count in ``n_evals``.
        """
        parted = [self._parted(m) for m in models]
        if any(p is not None for p in parted):
            return self._simulate_parted(models, parted, runs)
        return self._simulate_whole(models, runs)

    def _simulate_parted(self, models: list[ModelSpec], parted: list, runs) -> list:
        """:meth:`simulate_many` of models some of which are parted (:meth:`_parted`)."""
        from ehas_env.measurement import logged_readings

        scope = _REST_SCOPE.get()  # kept apart in a call run side by side with others (own_rests)
        kept_rests = self._rests if scope is None else scope.setdefault(id(self), dict(self._rests))
        # the rests this call needs: kept ones (moved to the end: the most recently used stay), the others
        # replayed together (a rest kept from a call on other runs is replayed for these)
        got, todo = {}, {}
        for p in parted:
            if p is None or p[0] in got or p[0] in todo:
                continue
            kept = kept_rests.pop(p[0], None)
            if kept is not None and all(kept[i] is not None or (runs is not None and i not in runs)
                                        for i in range(len(self.cases))):
                got[p[0]] = kept
            else:
                todo[p[0]] = p[1]
        if todo:
            got.update(zip(todo, self.simulate_many(list(todo.values()), runs)))
        kept_rests.update(got)
        while len(kept_rests) > REST_KEPT:
            kept_rests.pop(next(iter(kept_rests)))
        whole = [m for m, p in zip(models, parted) if p is None]
        done = iter(self.simulate_many(whole, runs) if whole else [])
        return [next(done) if p is None else logged_readings.apply(
            [x if runs is None or i in runs else None for i, x in enumerate(got[p[0]])], p[2])
            for p in parted]

    def _simulate_whole(self, models: list[ModelSpec], runs) -> list:
        """:meth:`simulate_many` of models replayed whole."""
        if STOP.is_set():
            raise ReplaysStopped("replays stopped (Ctrl-C)")
        with self._count:
            self.n_evals += len(models)
        jobs = [(m, i) for m in range(len(models)) for i in range(len(self.cases)) if runs is None or i in runs]
        # the plants (and a first compiled model) are made here, one after the other; only the compiled runs go
        # to the threads
        ready = [self._prepare(models[m], self.cases[i]) for m, i in jobs]
        for mod in {id(j.mod): j.mod for j in ready}.values():
            _wait_behind(mod)
        # a driver's first call compiles it (or loads it from numba's cache): that one runs here, where Ctrl-C
        # stops it, not in a thread the interpreter would wait for at exit
        first = {}
        for k, job in enumerate(ready):
            given = job.case.supply is not None  # a measured supply: the driver's specialisation with it
            driver = job.driver
            if hasattr(driver, "signatures") and not any(("omitted" not in str(sig[-1])) == given
                                                         for sig in driver.signatures):  # numba's, not compiled yet
                first.setdefault((id(driver), given), k)
        sims = {k: self._run_case(ready[k]) for k in first.values()}
        rest = [k for k in range(len(ready)) if k not in sims]
        runner = self._pool().map if len(rest) > 1 else map
        sims.update(zip(rest, runner(self._run_case, [ready[k] for k in rest])))
        results = [[None] * len(self.cases) for _ in models]
        for k, (m, i) in enumerate(jobs):
            results[m][i] = sims[k]
        return results

    def _parted(self, model: ModelSpec):
        """(key of the rest, the rest, the blocks) when ``model``'s static blocks at logged readings may be applied
        to a replay of the rest (:func:`ehas_env.measurement.logged_readings.split`); None to replay it whole (a
        model with proposed terms, a block at a reading where another effect acts too -- the model file's own
        included --, a resampled run)."""
        if model.terms or not model.effects or any(c.resample for c in self.cases):
            return None
        from ehas_env.measurement.logged_readings import split

        parted = split(model.effects, getattr(self.model, "effects", None) or ())
        if parted is None:
            return None
        rest, blocks = parted
        spec = ModelSpec(effects=rest, beta=model.beta, K=model.K)
        key = (repr(sorted((n, sorted(dict(v).items())) for n, v in rest.items())), float(model.beta),
               float(model.K))
        return key, spec, blocks

    def _pool(self):
        """The threads replays run on (``threads``, or one per core this process may use), made on first use
        (and again in a forked child: the parent's threads are not there)."""
        if self._executor is None or self._executor[0] != os.getpid():
            from concurrent.futures import ThreadPoolExecutor

            cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
            self._executor = (os.getpid(), ThreadPoolExecutor(max_workers=self.threads or cores,
                                                              thread_name_prefix="ehas-replay"))
        return self._executor[1]

    def __getstate__(self):
        """A replayer sent to another process leaves its threads behind (it makes its own there), and its kept
        replays."""
        return {**self.__dict__, "_executor": None, "_rests": {}, "_count": None}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._count = threading.Lock()

    def _prepare(self, model: ModelSpec, case: _Case) -> _Job:
        """What one replay of ``case`` with ``model`` needs: its compiled model, parameters, initial state and
        buffers of its own (replays run side by side: :meth:`simulate_many`)."""
        mod, P, plant = self.compiled(model, case.run, case.dt)
        if case.run.kind == "valve_open_loop":
            return _Job(case, mod, P, None, plant.rig.i_max, np.zeros((case.run.n, 3)))
        s0 = self.initial_state(mod, plant, case.theta0)
        if case.supply is not None:  # at rest at the measured supply: P_A = P_B = P_S / 2 (as Plant.initial_state)
            s0[KN.S_PA] = s0[KN.S_PB] = 0.5 * case.supply[0]
            s0[KN.S_PS] = case.supply[0]
            at_rest(mod, s0)
        return _Job(case, mod, P, s0, plant.rig.i_max, np.zeros((case.n_sim, KN.N_OUT)))

    def _driver_args(self, job: _Job) -> tuple:
        """The arguments of ``job``'s compiled driver (:attr:`_Job.driver`), a fresh command history among them."""
        case, out = job.case, job.out
        hist = np.zeros(case.hist_len)
        if job.s0 is None:
            args = (job.P, case.cmd, case.dt, self.substeps, case.run.meta["supply_bar"] * BAR, hist, out)
        else:
            args = (job.s0, job.P, RigController.law_id(), case.gains, case.ref, 0, case.dt, self.substeps,
                    hist, case.zeros, np.array([0.0, 0.0, 0.0, job.i_max]), 0, 0, np.zeros(6), out)
        return args if case.supply is None else args + (case.supply,)

    def _run_case(self, job: _Job) -> dict[str, np.ndarray]:
        """Runs one replay :meth:`_prepare` made ready (the compiled drivers release the GIL)."""
        job.driver(*self._driver_args(job))
        if job.s0 is None:
            return {"flow_lpm": job.out[:, 0] / LPM}
        return self._closed_loop_signals(job.case, job.out)

    def compile_behind(self) -> bool:
        """Start compiling, in a background process on the other core, the model a replay of a structural
        hypothesis or a block runs on (every registered effect and hypothesis: the larger model), while this
        process goes on replaying the registered effects; a later replay on it waits for that process and loads
        what it compiled (:meth:`_simulate_whole`).  Only for a replayer that tries the hypotheses, when this
        process has just written that model's files (a first compile: numba's cache cannot hold it) and
        ``EHAS_COMPILE_BEHIND`` is not ``0``.

        Returns
        -------
        bool
            Whether a compile runs behind (or another process of this one's already compiles that model).
        """
        if not self.hypotheses or os.environ.get("EHAS_COMPILE_BEHIND", "") == "0" or c_drivers_wanted():
            return False  # (the C compiler builds the drivers in under a second: nothing to compile behind)
        from ehas_env.physics.codegen import take_fresh
        from ehas_env.physics.effects import REGISTRY
        from ehas_env.physics.compile_behind import FastBuildBehind

        # a hypothesis away from the position sensor: the plant's initial state reads the sensor chain in Python,
        # which would compile an effect there
        hyp = next((c for c in REGISTRY.values() if c.kind == "hypothesis" and "position_reading" not in c.terms()),
                   None)
        if hyp is None:
            return False
        spec = ModelSpec(effects={hyp.name: {p.name: p.default for p in hyp.params}})
        # one replay of each kind of run, made ready on the larger model: the drivers and argument types it needs
        jobs = {}
        for c in self.cases:
            if (c.run.kind, c.supply is None) not in jobs:
                jobs[(c.run.kind, c.supply is None)] = self._prepare(spec, c)
        mod = next(iter(jobs.values())).mod
        if (os.getpid(), id(mod)) in _BEHIND:
            return True
        fresh = take_fresh(mod)
        if fresh is None:
            return False
        _TAKEN[(os.getpid(), id(mod))] = fresh
        # a run without a measured supply calls its driver without that last argument: compiled as left out
        calls = [(job.driver.__name__, self._driver_args(job) + ((None,) if job.case.supply is None else ()))
                 for job in jobs.values()]
        _BEHIND[(os.getpid(), id(mod))] = FastBuildBehind(
            mod, mod, calls, what="the diagnosis", estimate=fresh[0], kb=fresh[1],
            meanwhile_name="model of the registered effects",
            fast_name="model with the structural hypotheses and blocks")
        return True

    def _closed_loop_signals(self, case: _Case, o: np.ndarray) -> dict[str, np.ndarray]:
        run = case.run
        sim = {
            "theta_deg": np.degrees(o[:, KN.O_THETA]),
            "current_mA": o[:, KN.O_CURRENT].copy(),
            "flow_lpm": o[:, KN.O_FLOW] / LPM,
            "p_a_bar": o[:, KN.O_PA] / BAR,
            "p_b_bar": o[:, KN.O_PB] / BAR,
            "p_s_bar": o[:, KN.O_PS] / BAR,
            "load_kN": o[:, KN.O_FORCE] * 1e-3,
            "omega_deg_s": np.degrees(o[:, KN.O_OMEGA]),
        }
        if case.resample:
            ts = np.arange(case.n_sim) * case.dt
            tl = run.t - run.t[0]
            k = np.clip(np.searchsorted(ts, tl, side="right") - 1, 0, case.n_sim - 1)
            # the current is held between controller samples; the physical signals are smooth
            sim = {name: (v[k] if name == "current_mA" else np.interp(tl, ts, v)) for name, v in sim.items()}
        return sim

    # -- residuals and fit ------------------------------------------------------------------
    def residuals(self, sims) -> list[dict[str, np.ndarray] | None]:
        """measured - simulated, per run and signal (None for runs not simulated)."""
        return [None if sim is None else {s: c.measured[s] - sim[s] for s in c.signals}
                for c, sim in zip(self.cases, sims)]

    def cost_blocks(self, sims, runs=None) -> list[np.ndarray]:
        """The fit's residual blocks, one per (run, signal) of the cost: first every run judged sample by sample
        (:meth:`cost_cases`), its residual divided by the signal's noise level; then each run whose logged loop
        does not repeat (:func:`ehas_env.measurement.verdict.unpredictable_runs`) on its cycle envelope, in its
        floors and at least 1 (:func:`ehas_env.measurement.verdict.envelope_cost_block`)."""
        parts = []
        for case, sim in self.cost_cases(sims, runs):
            k = case.skip
            for s in case.signals:
                if s in COST_SIGNALS:
                    parts.append((case.measured[s][k:] - sim[s][k:]) / case.noise[s])
        for case, sim in self.cost_cases(sims, runs, unpredictable=True):
            for s in case.signals:
                if s in COST_SIGNALS:
                    e = envelope_cost_block(case.measured[s], sim[s], case.noise[s], case.run.dt,
                                            sine_timing(case.run)[0], case.skip)
                    if e is not None:
                        parts.append(e)
        return parts

    @functools.cached_property
    def unpredictable(self) -> set[int]:
        """The runs (indices) whose logged loop does not repeat
        (:func:`ehas_env.measurement.verdict.unpredictable_runs`): a property of the logs alone, found once, not at
        every replay's cost (:meth:`cost_cases` is asked twice a cost)."""
        return unpredictable_runs(self.cases)

    def cost_cases(self, sims, runs=None, unpredictable: bool = False):
        """The runs the cost judges sample by sample, in its order: (case, simulated run) of each run simulated (of
        ``runs``, indices, when given) but those whose logged loop does not repeat
        (:func:`ehas_env.measurement.verdict.unpredictable_runs`); with ``unpredictable``, those alone (the cost
        judges them on their envelope)."""
        left_out = self.unpredictable
        for i, (case, sim) in enumerate(zip(self.cases, sims)):
            if sim is not None and (runs is None or i in runs) and (i in left_out) == unpredictable:
                yield case, sim

    def cost_vector(self, sims, runs=None) -> np.ndarray:
        """The blocks of :meth:`cost_blocks` concatenated.

        The sum of squares divided by the vector's length is ~1 when the model
        explains everything but the sensor noise.
        """
        return np.concatenate(self.cost_blocks(sims, runs))

    def cost(self, sims, runs=None) -> float:
        """Mean squared noise-normalised residual (1.0 = at the noise floor)."""
        v = self.cost_vector(sims, runs)
        return float(np.dot(v, v) / v.size)

    def log_cost(self, sims, runs=None) -> float:
        """Geometric mean over (run, signal) blocks of the mean squared noise-normalised residual.

        Minimising it is maximum likelihood when every run and signal has its own
        unknown residual level: a run whose residual cannot be matched sample by
        sample (a limit cycle that noise decides, knocks of a joint with play)
        then weighs by how much it improves relatively, not by its size.  1.0 is
        the noise floor.
        """
        return log_mean(self.cost_blocks(sims, runs))

    def not_compared(self) -> dict[str, list[str]]:
        """The logged columns left out of every comparison, per run: {run: [column, ...]} (only runs with some).

        A load the logger computed from the logged pressures (:func:`derived_load`) has no reading of its own:
        judged, it would count a pressure reading's miss twice.
        """
        return {c.run.name: list(c.derived) for c in self.cases if c.derived}

    def not_compared_text(self) -> str | None:
        """:meth:`not_compared` in one line (None when nothing is left out)."""
        left = self.not_compared()
        if not left:
            return None
        cols = sorted({c for cs in left.values() for c in cs})
        return (f"not compared: {', '.join(cols)} in {len(left)} of {len(self.cases)} runs "
                f"({', '.join(sorted(left))}): the logger computed it from the logged pressures "
                f"(a P_A - b P_B leaves less than {100 * DERIVED_SHARE:g} % of its noise), so it holds no reading "
                "of its own and judging it would count a pressure's miss twice")

    def informative(self, case: _Case, signal: str) -> bool:
        return float(np.std(case.measured[signal])) > INFORMATIVE * case.noise[signal]

    def fit_table(self, sims) -> FitTable:
        """Fit % per run and signal, per signal (mean over runs) and overall (mean over signals)."""
        per_run, rms = {}, {}
        acc: dict[str, list[float]] = {}
        for case, sim in zip(self.cases, sims):
            if sim is None:
                continue
            name = case.run.name
            per_run[name], rms[name] = {}, {}
            k = case.skip
            for s in case.signals:
                e = case.measured[s][k:] - sim[s][k:]
                rms[name][s] = float(np.sqrt(np.mean(e**2)))
                if self.informative(case, s):
                    f = fit_percent(case.measured[s][k:], sim[s][k:])
                    per_run[name][s] = f
                    acc.setdefault(s, []).append(f)
        order = [s for s in CL_SIGNALS if s in acc]
        per_signal = {s: float(np.mean(acc[s])) for s in order}
        overall = float(np.mean(list(per_signal.values()))) if per_signal else float("nan")
        return FitTable(per_run, per_signal, overall, rms)


def format_fit_tables(tables: dict[str, FitTable], runs=None) -> str:
    """Plain-text tables: per signal (columns = the models compared), then per run.

    ``tables`` maps a column title (``baseline``, ``+ coulomb_friction``) to its
    :class:`FitTable`.
    """
    titles = list(tables)
    first = tables[titles[0]]
    signals = list(first.per_signal)
    w = max(12, *(len(t) for t in titles))
    lines = ["fit % (NRMSE) per signal, mean over runs", f"{'signal':<14}" + "".join(f"{t:>{w + 2}}" for t in titles)]
    for s in signals:
        lines.append(f"{s:<14}" + "".join(f"{tables[t].per_signal.get(s, float('nan')):>{w + 2}.1f}" for t in titles))
    lines.append(f"{'overall':<14}" + "".join(f"{tables[t].overall:>{w + 2}.1f}" for t in titles))
    lines.append("")
    lines.append("fit % per run")
    for run in first.per_run:
        lines.append(f"  {run}")
        for s in first.per_run[run]:
            lines.append(f"    {s:<12}" + "".join(f"{tables[t].per_run[run].get(s, float('nan')):>{w + 2}.1f}"
                                                 for t in titles))
    return "\n".join(lines)
