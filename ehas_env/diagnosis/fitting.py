"""Fitting a model's numbers to a campaign: free parameters, the bounded least-squares fit, confidence intervals.

The core the diagnosis (:mod:`ehas_env.diagnosis.candidates`), the proposal of
a missing term (:mod:`ehas_env.diagnosis.proposal`) and ``ehas compare --fit``
share.  Each fitted number is mapped to u in [0, 1] over its fit range
(:class:`FreeParam`); the cost is the geometric mean over runs and signals of
the noise-normalised mean squared residual (:meth:`Replayer.log_cost`),
minimised by iteratively reweighted least squares (:func:`fit`); the
forward-difference Jacobian of the confidence intervals is :meth:`Objective.jacobian`, and the fit's steps
update it by the secant rule between differences (:meth:`Objective.secant`: one replay a step instead of one per
fitted number).

The cost is the verdict's noise figure (:mod:`ehas_env.measurement.verdict`) before its clip at the floor: the same
samples and signals, each run and signal's mean square divided by the sensor noise's instead of by its floor.  A
geometric mean is blind to a constant scale of one of its blocks, so with the floors held the two differ by a
constant factor: what lowers the cost lowers the figure by the same share.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ehas_env.measurement.replay import FitTable, ModelSpec, Replayer, log_mean
from ehas_env.measurement.proposal_terms import term_param
from ehas_env.physics.effects import get_effect
from ehas_env.physics.rig import BULK_MODULUS, VALVE_K

#: recalibration ranges of the baseline's uncertain numbers (relative to nominal).
#: beta: the reference model's 1e9 Pa is an estimate (oil, air, hoses); K: the
#: book's identified gain (fit 95.4 %).  Outside these the bulk_modulus and
#: valve_dynamics effects take over.
BETA_RANGE = (0.93, 1.07)
K_RANGE = (0.97, 1.03)
PENALTY_PER_PARAM = 0.2  # dB per fitted effect parameter
MIN_SCORE = 0.3  # dB: a candidate must remove at least 7 % of the null model's residual energy ...
MIN_GAIN = 0.05  # ... and at least this many noise variances per sample, to beat noise
SCAN_POINTS = 7
IRLS_ROUNDS = 2  # reweighting rounds of the least-squares fit of the log cost
SKIP_MARGIN = 0.002  # a scan must beat the null model by this fraction to be fitted further
SCREEN_NFEV = 8  # least-squares steps per parameter when screening a candidate
MAX_NFEV = 15  # ... when refining one (each step also costs one replay per parameter)
#: a scan zooms between its best point's neighbours at most this many times (:func:`_zoomed`) ...
ZOOM_LEVELS = 6
#: ... the second time on only while both neighbours' costs are above the best's by this share (a valley sharper
#: than the spacing: a smooth valley's neighbours come within it after one zoom, its rest left to the least squares)
ZOOM_SHARP = 0.5
#: ... or while the last zoom lowered the best cost by this share
ZOOM_GAIN = 0.25


def score_db(before: float, after: float, n_params: int) -> float:
    """A candidate's score: the cost it removes, ``10 log10(before / after)`` dB, less :data:`PENALTY_PER_PARAM`
    per fitted parameter.

    Examples
    --------
    >>> round(score_db(2.0, 1.0, 1), 2)
    2.81
    """
    return 10.0 * math.log10(before / after) - PENALTY_PER_PARAM * n_params


def beats_noise(before: float, after: float, n_params: int) -> bool:
    """Whether a fit that took the cost from ``before`` to ``after`` with ``n_params`` parameters beats the noise:
    it scores :data:`MIN_SCORE` (:func:`score_db`) and removes :data:`MIN_GAIN` noise variances per sample."""
    return score_db(before, after, n_params) >= MIN_SCORE and before - after >= MIN_GAIN

#: FreeParam.effect of a proposed term's coefficient (ehas_env.measurement.proposal_terms)
TERM = "proposal"


@dataclass(frozen=True)
class FreeParam:
    """One fitted number, mapped to u in [0, 1] over its fit range (log where it spans decades)."""

    effect: str | None  # None: the baseline's beta / K
    name: str
    lo: float
    hi: float
    log: bool
    step: float = 2e-3  # finite-difference step in u

    def value(self, u: float) -> float:
        u = min(max(float(u), 0.0), 1.0)
        if self.log:
            v = math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        else:
            v = self.lo + u * (self.hi - self.lo)
        return float(min(max(v, self.lo), self.hi))  # rounding must not leave the bounds

    def u(self, value: float) -> float:
        v = min(max(float(value), self.lo), self.hi)
        if self.log:
            return (math.log(v) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return (v - self.lo) / (self.hi - self.lo)

    def end(self, value: float) -> str | None:
        """``"lower"`` or ``"upper"`` when ``value`` sits at that end of the fit range (within 1e-3 of it in u),
        else None: a fit that ran into its range."""
        u = self.u(value)
        return "lower" if u <= 1e-3 else "upper" if u >= 1 - 1e-3 else None


def reopens_baseline(effect: str) -> bool:
    """Whether ``effect`` re-opens the baseline's numbers over their full ranges (its ``kind`` is
    ``"recalibration"``: bulk_modulus for beta, valve_dynamics for the valve's K, wn, zeta)."""
    return get_effect(effect).kind == "recalibration"


def fit_range(effect: str, pname: str) -> FreeParam:
    """The range a parameter is fitted over: its typical range widened 4x (1.6x for the strongly acting
    recalibrations), inside its bounds."""
    p = get_effect(effect).param(pname)
    blo, bhi = p.bounds
    tlo, thi = p.typical or p.bounds
    if blo < 0.0:  # signed (null bias): symmetric
        m = min(4.0 * max(abs(tlo), abs(thi)), bhi, -blo)
        return FreeParam(effect, pname, -m, m, False, _step(effect, pname))
    lo = max(blo, tlo / 4.0) if tlo > 0 else blo
    hi = min(bhi, thi * 4.0)
    if reopens_baseline(effect) or (effect, pname) == ("supply_droop", "p0"):
        # recalibrations and the precharge act strongly (the loop's stability hangs on beta and wn):
        # a narrower range, scanned finely enough to land in the valley
        lo, hi = max(blo, tlo / 1.6), min(bhi, thi * 1.6)
    return spanning(effect, pname, lo, hi, _step(effect, pname))


def spanning(effect: str | None, pname: str, lo: float, hi: float, step: float = 2e-3) -> FreeParam:
    """A fitted number over [lo, hi]: on a log scale where the range lies above zero and spans 8x or more (the
    scale every fit range takes: :func:`fit_range`, :func:`covering`, a range widened by
    :func:`ehas_env.diagnosis.candidates._widen`).

    Examples
    --------
    >>> spanning("coulomb_friction", "Fc", 37.5, 2400.0).log, spanning(None, "x", -2.0, 2.0).log
    (True, False)
    """
    return FreeParam(effect, pname, lo, hi, lo > 0 and hi / lo >= 8.0, step)


def covering(fp: FreeParam, value: float, margin: float = 1.25) -> FreeParam:
    """``fp``'s fit range widened, inside its parameter's bounds, to hold ``value`` ``margin`` inside an end (a
    given value is a start, never clipped to the default range: a diagnosis fits past it when the data ask,
    :func:`ehas_env.diagnosis.candidates._widen`, and its printed command must start where it ended).

    Parameters
    ----------
    fp : FreeParam
        An effect's parameter as fitted by default (:func:`fit_range`).
    value : float
        The value it is given.
    margin : float
        The widened end lies this factor beyond ``value`` (where the bounds allow).

    Returns
    -------
    FreeParam
        ``fp`` itself when its range already holds ``value``.

    Examples
    --------
    >>> fp = FreeParam(None, "x", -2.0, 2.0, False)
    >>> covering(fp, 1.0) is fp
    True
    """
    if fp.lo <= value <= fp.hi:
        return fp
    blo, bhi = get_effect(fp.effect).param(fp.name).bounds if fp.effect else (-math.inf, math.inf)
    if fp.lo < 0.0:  # a signed range stays symmetric about zero (fit_range)
        m = max(fp.hi, min(margin * abs(value), bhi, -blo))
        lo, hi = -m, m
    else:
        lo = max(blo, min(fp.lo, value / margin if value > 0 else margin * value))
        hi = min(bhi, max(fp.hi, value * margin))
    return spanning(fp.effect, fp.name, lo, hi, fp.step)


#: numbers the model resolves in stairs, in integrator sub-steps: the delay is a whole number of sub-steps
STAIRCASE = {("transport_delay", "tau"): 1.0}


def _step(effect: str, pname: str) -> float:
    # the delay acts at the integrator's sub-step resolution (0.1 ms): a staircase
    # cost, so its derivative needs a step spanning several stairs
    return 0.03 if (effect, pname) == ("transport_delay", "tau") else 2e-3


def baseline_params() -> list[FreeParam]:
    return [FreeParam(None, "beta", BULK_MODULUS * BETA_RANGE[0], BULK_MODULUS * BETA_RANGE[1], False),
            FreeParam(None, "K", VALVE_K * K_RANGE[0], VALVE_K * K_RANGE[1], False)]


#: the effect that re-opens each baseline number over its full range (:func:`reopens_baseline`)
REOPENED_BY = {"beta": "bulk_modulus", "K": "valve_dynamics"}


def run_range(fp: FreeParam) -> FreeParam:
    """The range ``fp`` is refitted over on one run alone: a baseline number (beta, K) over the range of the
    effect that re-opens it, every other parameter over its own.

    The baseline's recalibration range (:data:`BETA_RANGE`, :data:`K_RANGE`) holds one value for the whole
    campaign near the rig's; a single run's beta or K can lie well beyond it (the oil warms, takes in air), and a
    run pinned at the campaign's range says nothing of how far.

    Examples
    --------
    >>> wide = run_range(baseline_params()[1])
    >>> wide.effect is None and wide.name == "K" and wide.lo < 0.8 * VALVE_K and wide.hi > 1.2 * VALVE_K
    True
    """
    if fp.effect is not None:
        return fp
    r = fit_range(REOPENED_BY[fp.name], fp.name)
    return FreeParam(None, fp.name, r.lo, r.hi, r.log, fp.step)


def start_value(fp: FreeParam) -> float:
    """Middle of the typical range (geometric on log scale), the fit's start."""
    if fp.effect is None:
        return BULK_MODULUS if fp.name == "beta" else VALVE_K
    p = get_effect(fp.effect).param(fp.name)
    tlo, thi = p.typical or (fp.lo, fp.hi)
    if fp.lo < 0:
        return 0.5 * (tlo + thi)
    return math.sqrt(tlo * thi) if fp.log and tlo > 0 else 0.5 * (tlo + thi)


@dataclass
class Fit:
    """A fitted model."""

    model: ModelSpec
    cost: float
    free: list[FreeParam]
    sims: list
    table: FitTable
    nfev: int = 0


#: the residual, in noise standard deviations, of a sample a model's replay left not finite (it diverged there): far
#: above any residual a replay that holds reaches, so a fit steps away from it rather than stopping on a NaN
DIVERGED = 1.0e6


def finite_blocks(blocks: list) -> list:
    """The residual blocks with every sample that is not finite (a replay that diverged) at :data:`DIVERGED`; a
    block that is finite is returned as it is (the same array: :meth:`Objective.blocks` tells a diverged replay by
    that).

    Parameters
    ----------
    blocks : list of ndarray

    Returns
    -------
    list of ndarray

    Examples
    --------
    >>> finite_blocks([np.array([0.5, np.nan, -np.inf])])[0].tolist()
    [0.5, 1000000.0, 1000000.0]
    """
    return [x if np.all(np.isfinite(x)) else np.where(np.isfinite(x), x, DIVERGED) for x in blocks]


def replay_cost(rep: Replayer, sims: list) -> float:
    """The fit's cost of the replayed runs ``sims`` of ``rep``: :meth:`Objective.cost`'s measure (the log cost, a
    sample left not finite at :data:`DIVERGED`), for a model replayed outside a fit.

    Parameters
    ----------
    rep : Replayer
    sims : list
        :meth:`Replayer.simulate`'s runs.

    Returns
    -------
    float
    """
    return log_mean(finite_blocks(rep.cost_blocks(sims)))


def costed(rep: Replayer, f: Fit) -> Fit:
    """``f``'s model and fitted numbers with its cost, simulation and table on ``rep`` (other runs than those it was
    fitted on: a screen's subset of the fit data, or the whole fit data after a screen on a subset).

    Parameters
    ----------
    rep : Replayer
    f : Fit

    Returns
    -------
    Fit
    """
    sims = rep.simulate(f.model)
    return Fit(model=f.model, cost=replay_cost(rep, sims), free=f.free, sims=sims, table=rep.fit_table(sims),
               nfev=f.nfev)


class Objective:
    """The fit's residuals as a function of u (the free parameters mapped to [0, 1]), memoised.

    One place for the models a fit simulates: a set of u is replayed together
    (:meth:`Replayer.simulate_many`), and the forward-difference Jacobian used by
    :func:`confidence` (and every few steps of :func:`fit`) is :meth:`jacobian`; :meth:`secant` updates it
    between them.

    Parameters
    ----------
    rep : Replayer
        The campaign replayed.
    free : list of FreeParam
        The fitted numbers.
    fixed : ModelSpec, optional
        Everything else of the model.
    """

    def __init__(self, rep: Replayer, free: list[FreeParam], fixed: ModelSpec | None = None):
        self.rep, self.free, self.fixed = rep, free, fixed
        self.memo: dict[bytes, tuple] = {}
        self._secant = None  # (u, unweighted residual, unweighted Jacobian, updates since the last difference)

    def model(self, u) -> ModelSpec:
        """The model at ``u``."""
        return model_from(self.free, {(fp.effect, fp.name): fp.value(x) for fp, x in zip(self.free, u)}, self.fixed)

    def blocks(self, U) -> list:
        """Noise-normalised residual blocks (:meth:`Replayer.cost_blocks`) at every u of ``U``."""
        U = [np.asarray(u, dtype=float) for u in U]
        todo = [u for u in U if u.tobytes() not in self.memo]
        if todo:
            for u, sims in zip(todo, self.rep.simulate_many([self.model(u) for u in todo])):
                raw = self.rep.cost_blocks(sims)
                fin = finite_blocks(raw)
                self.memo[u.tobytes()] = (fin, sims, any(f is not r for f, r in zip(fin, raw)))
        return [self.memo[u.tobytes()][0] for u in U]

    def diverged(self, u) -> bool:
        """Whether the replay at ``u`` left samples that are not finite (:func:`finite_blocks`)."""
        self.blocks([u])
        return self.memo[np.asarray(u, dtype=float).tobytes()][2]

    def sims(self, u) -> list:
        """The simulated runs at ``u``."""
        self.blocks([u])
        return self.memo[np.asarray(u, dtype=float).tobytes()][1]

    def cost(self, u) -> float:
        """Geometric mean over (run, signal) blocks (see :meth:`Replayer.log_cost`)."""
        return log_mean(self.blocks([u])[0])

    def weights(self, u) -> list[float]:
        """Each block's weight at ``u``: 1 / its RMS (the log cost's gradient there)."""
        return [1.0 / math.sqrt(max(float(np.dot(x, x)) / x.size, 1e-12)) for x in self.blocks([u])[0]]

    def weighted(self, u, w) -> np.ndarray:
        """The residual vector at ``u``, block k weighted by ``w[k]``."""
        return np.concatenate([wi * x for wi, x in zip(w, self.blocks([u])[0])])

    def jacobian(self, u, w) -> np.ndarray:
        """Forward-difference Jacobian of :meth:`weighted` at ``u`` (steps toward the inside of [0, 1]; a step whose
        replay diverged where the one at ``u`` holds is taken the other way)."""
        u = np.asarray(u, dtype=float)
        f0 = self.weighted(u, w)

        def steps(flip):
            U, H = [], []
            for i, fp in enumerate(self.free):
                h = fp.step if u[i] + fp.step <= 1.0 else -fp.step
                h = -h if flip[i] and 0.0 <= u[i] - h <= 1.0 else h
                du = u.copy()
                du[i] += h
                U.append(du)
                H.append(h)
            self.blocks(U)
            return U, H

        U, H = steps([False] * len(self.free))
        if not self.diverged(u) and any(self.diverged(du) for du in U):
            U, H = steps([self.diverged(du) for du in U])
        return np.column_stack([(self.weighted(du, w) - f0) / h for du, h in zip(U, H)])

    def _unweighted(self, u) -> np.ndarray:
        return np.concatenate(self.blocks([u])[0])

    def _row_weights(self, u, w) -> np.ndarray:
        return np.concatenate([np.full(x.size, wi) for wi, x in zip(w, self.blocks([u])[0])])

    def secant(self, u, w) -> np.ndarray:
        """The Jacobian of :meth:`weighted` at ``u`` from one replay instead of one per parameter: Broyden's
        rank-one update of the last Jacobian this objective formed, by the change of the residual between the two
        points (the replay at ``u`` the least-squares step made anyway).  A forward difference
        (:meth:`jacobian`) forms the first one and every :data:`SECANT_REFRESH` updates, and whenever the step
        was too short to carry information.  The weights ``w`` may change between calls (the reweighting rounds):
        the Jacobian kept is the unweighted residual's.
        """
        u = np.asarray(u, dtype=float)
        r = self._unweighted(u)
        st = self._secant
        if st is not None and st[3] < SECANT_REFRESH:
            u0, r0, J, n = st
            du = u - u0
            dd = float(du @ du)
            if dd > (1e-3 * min(fp.step for fp in self.free)) ** 2:
                J = J + np.outer(r - r0 - J @ du, du) / dd
                self._secant = (u, r, J, n + 1)
                return self._row_weights(u, w)[:, None] * J
        ones = [1.0] * len(self.blocks([u])[0])
        J = self.jacobian(u, ones)
        self._secant = (u, r, J, 0)
        return self._row_weights(u, w)[:, None] * J


#: a secant Jacobian (:meth:`Objective.secant`) is formed anew by forward differences after this many updates
SECANT_REFRESH = 4
#: the least-squares fits (:func:`fit`) take the secant Jacobian: one replay a step, not one per fitted number.
#: Measured on 6 held-out drawn campaigns and the end-cushion campaign: 6 of 7 the same verdicts, figures (within 0.001),
#: kept blocks and named forms, each fitted value within its interval; 10-34 % fewer replays of the whole diagnosis
#: (docs/diagnosis-pipeline.md; d14 changed for the better).  The confidence intervals keep their forward difference (:func:`confidence`).
SECANT = True


def model_from(free: list[FreeParam], values: dict, fixed: ModelSpec | None = None) -> ModelSpec:
    """``fixed`` (effects, beta, K) with the free values {(effect, name): value} set."""
    fixed = fixed or ModelSpec()
    effects = {n: dict(p) for n, p in fixed.effects.items()}
    terms = dict(fixed.terms)
    beta, K = fixed.beta, fixed.K
    for fp in free:
        v = values[(fp.effect, fp.name)]
        if fp.effect is None:
            if fp.name == "beta":
                beta = v
            else:
                K = v
        elif fp.effect == TERM:
            terms[fp.name] = v
        else:
            effects.setdefault(fp.effect, {})[fp.name] = v
    st = effects.get("stribeck_friction")
    if st and "Fs" in st and "Fc" in st and st["Fs"] < st["Fc"]:
        # Stribeck friction keeps its definition (breakaway at or above sliding, Fs >= Fc; the effect
        # refuses less): where the fit wanders below, the breakaway sits at the sliding level
        effects["stribeck_friction"] = {**st, "Fs": st["Fc"]}
    return ModelSpec(effects=effects, beta=beta, K=K, terms=terms)


def scan_values(fp: FreeParam) -> list[float]:
    """Values of a parameter tried before fitting: log- or linearly spaced over its fit range (the effect's
    ``scan_points`` of them, else ``SCAN_POINTS``); a signed parameter (null bias) gets both signs of
    log-spaced magnitudes."""
    if fp.effect == TERM:  # a proposed term's coefficient: both signs, magnitudes over three decades
        mags = np.geomspace(1e-3 * fp.hi, fp.hi, 5)
        return sorted([float(-m) for m in mags] + [float(m) for m in mags])
    if fp.lo < 0.0:
        p = get_effect(fp.effect).param(fp.name)
        small = max(min(abs(x) for x in p.typical) / 4.0, 1e-3 * fp.hi) if p.typical else 1e-3 * fp.hi
        mags = np.geomspace(small, fp.hi, (SCAN_POINTS + 3) // 2)
        return sorted([float(-m) for m in mags] + [float(m) for m in mags])
    n = (fp.effect is not None and get_effect(fp.effect).scan_points) or SCAN_POINTS  # the effect may ask more
    if fp.log:
        return [float(v) for v in np.geomspace(fp.lo, fp.hi, n)]
    return [float(v) for v in np.linspace(fp.lo, fp.hi, n)]


#: the coarse grid a screen's scan replays first (:func:`coarse_scan`): this many of its values, spread over it
COARSE_POINTS = 3
#: ... and how far above the null model's cost (a share) its best may come for the rest of the grid to be scanned.
#: Set on the scans of 17 drawn campaigns' diagnoses (results/coarse_scan: 3522 scans with a model to beat, 592 that
#: the whole grid sent on to a fit): the best of the coarse grid of those came at most 4.7 % above the model's cost (a
#: knee at the supply); 20 % is four times that, and 24 % of the scans' replays go (26 % at 10 %, 22 % at 30 %)
COARSE_SLACK = 0.2


#: callables given, after every scan against a null model that replayed its whole grid, its record: the scanned
#: number (``effect``, ``param``), ``values`` (sorted; the ``grid`` and the values the data point at, ``extra``), their
#: ``costs``, the ``null`` model's, ``n_free`` and the cost its fit ``final``\ly reached.  Empty in a diagnosis: the
#: survey that set :data:`COARSE_SLACK` fills it (``python -m tests.measurement.coarse_scan_survey``)
SCAN_WATCHERS: list = []


def asks_fine_grid(effect: str | None) -> bool:
    """Whether the numbers of ``effect`` (None: the baseline's; :data:`TERM`: a proposal's) are scanned over a finer
    grid than the default (the effect's ``scan_points``: its valley is narrow, backlash): such a scan is replayed
    whole, without :func:`coarse_scan` first.

    Parameters
    ----------
    effect : str or None

    Returns
    -------
    bool
    """
    return effect is not None and effect != TERM and bool(get_effect(effect).scan_points)


def coarse_scan(values: list, grid: list, extra: list, points: int = COARSE_POINTS,
                each_sign: bool = True) -> list[int]:
    """The indices into ``values`` (the scan's sorted values: the grid ``grid`` and the values the data point at,
    ``extra``) a screen replays first: ``points`` of the grid's values spread evenly over it (its ends among them;
    on a grid of both signs and with ``each_sign``, as many over each sign's) and every value the data point at.  A
    candidate whose best there stays above the null model's cost (by :data:`COARSE_SLACK`) is not scanned further:
    the rest of its grid lies between values that did nothing.

    Parameters
    ----------
    values : list of float
        The scan's values, sorted.
    grid : list of float
        The parameter's own grid (:func:`scan_values`), sorted.
    extra : list of float
        The values the data point at.
    points : int
        Values spread over the grid (over each sign's); the diagnosis' :data:`COARSE_POINTS`, others for the survey
        that judges the rule.
    each_sign : bool
        Spread over each sign's values apart (the diagnosis' rule) or over the whole grid.

    Returns
    -------
    list of int
        Sorted indices into ``values``.

    Examples
    --------
    >>> coarse_scan([1.0, 2.0, 2.5, 3.0, 4.0, 5.0], [1.0, 2.0, 3.0, 4.0, 5.0], [2.5])
    [0, 2, 3, 5]
    >>> coarse_scan([-9.0, -3.0, -1.0, 1.0, 3.0, 9.0], [-9.0, -3.0, -1.0, 1.0, 3.0, 9.0], [])
    [0, 1, 2, 3, 4, 5]
    """
    def spread(side: list) -> set:
        n = len(side)
        return set(side) if n <= points else {side[round(i * (n - 1) / (points - 1))] for i in range(points)}

    negative, positive = [v for v in grid if v < 0.0], [v for v in grid if v >= 0.0]
    picked = spread(negative) | spread(positive) if each_sign and negative and positive else spread(list(grid))
    picked |= set(extra)
    return [j for j, v in enumerate(values) if v in picked]


def one_blas_thread():
    """A context in which the linear algebra (BLAS) runs on one thread: the same numbers wherever a fit runs.

    A least-squares path depends on the last bits of its linear algebra, and BLAS sums in another order on another
    number of threads: a campaign diagnosed in a Ray worker of one CPU (which runs BLAS on one thread) ended a few
    parts in 10^4 away from the same campaign diagnosed here on two (beta 978.6 against 978.5 MPa).  The matrices
    of a fit are small: one thread costs nothing.

    Returns
    -------
    context manager
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def on_one_blas_thread(func):
    """``func`` run inside :func:`one_blas_thread` (a decorator)."""
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return func(*args, **kwargs)

    return wrapper


def fit(rep: Replayer, free: list[FreeParam], start: dict, fixed: ModelSpec | None = None, *,
        scan: FreeParam | None = None, max_nfev: int = MAX_NFEV, tol: float = 1e-4,
        null_cost: float | None = None, scan_extra: tuple = (), secant: bool | None = None) -> Fit:
    """Fit the ``free`` parameters from ``start``: a scan of ``scan`` first, then bounded least squares.

    Works in u in [0, 1] per parameter; the Jacobian is a forward difference whose
    perturbed models are simulated together (:meth:`Replayer.simulate_many`), updated between difference steps by
    the secant rule when ``secant`` (default :data:`SECANT`; :meth:`Objective.secant`).
    With ``null_cost``, a candidate whose scan never beats it is not fitted further
    (it explains nothing anywhere in its range; its best scan point is returned), and the scan replays a coarse
    grid first (:func:`coarse_scan`): a candidate that does nothing there is not scanned further (the best of the
    coarse grid is returned).
    ``scan_extra``: values of ``scan`` the data point at, added to its grid (a saturated reading's peak: the
    valley of a clip level is narrower than the grid's steps).
    """
    if secant is None:
        secant = SECANT
    u0 = np.array([fp.u(start[(fp.effect, fp.name)]) for fp in free])
    evals0 = rep.n_evals
    obj = Objective(rep, free, fixed)
    cost = obj.cost

    def result(u) -> Fit:
        u = np.asarray(u, dtype=float)
        sims = obj.sims(u)
        return Fit(model=obj.model(u), cost=cost(u), free=free, sims=sims, table=rep.fit_table(sims),
                   nfev=rep.n_evals - evals0)

    watched = None
    if scan is not None:
        u0, stop, watched = _scanned(obj, free, u0, scan, null_cost, scan_extra)
        if stop:
            _tell(watched, cost(u0))
            return result(u0)
    # iteratively reweighted least squares for the log cost: each block weighted by its
    # residual level at the round's start point (the log cost's gradient there)
    u_ref = np.clip(u0, 0.0, 1.0)
    for _ in range(IRLS_ROUNDS):
        w = obj.weights(u_ref)

        def fun(u, w=w):
            return obj.weighted(u, w)

        def jac(u, w=w):
            return obj.secant(u, w) if secant else obj.jacobian(u, w)

        res = least_squares(fun, u_ref, jac=jac, bounds=(0.0, 1.0), method="trf", x_scale=1.0,
                            max_nfev=max(max_nfev // IRLS_ROUNDS, 3), xtol=tol, ftol=tol, gtol=1e-8)
        u_new = np.asarray(res.x, dtype=float)
        if cost(u_new) >= cost(u_ref):
            break
        u_ref = u_new
    _tell(watched, cost(u_ref))
    return result(u_ref)


def _scanned(obj: Objective, free: list[FreeParam], u0: np.ndarray, scan: FreeParam, null_cost: float | None,
             scan_extra: tuple) -> tuple:
    """The scan of :func:`fit`: ``scan`` over its grid and the values the data point at (``scan_extra``), the
    coarse grid first when a ``null_cost`` is to be beaten (:func:`coarse_scan`), then a zoom between the best
    point's neighbours.

    Returns
    -------
    (ndarray, bool, dict or None)
        The point the least squares start from, or the best scanned one with True when the candidate is not fitted
        further (it beat ``null_cost`` nowhere); and the scan's record for :data:`SCAN_WATCHERS` (None: unwatched).
    """
    blocks, cost = obj.blocks, obj.cost
    k = free.index(scan)
    grid = []
    extra = [float(v) for v in scan_extra if scan.lo <= v <= scan.hi]
    own = scan_values(scan)
    values = sorted(own + extra)
    for value in values:
        u = u0.copy()
        u[k] = scan.u(value)
        grid.append(u)
    if null_cost is not None and not asks_fine_grid(scan.effect):
        # the coarse grid first: a candidate none of whose coarse values comes near the null model is not
        # scanned further (:func:`coarse_scan`)
        first = coarse_scan(values, own, extra)
        blocks([grid[j] for j in first])
        near = min(first, key=lambda j: cost(grid[j]))
        if cost(grid[near]) >= null_cost * (1.0 - SKIP_MARGIN) * (1.0 + COARSE_SLACK):
            return grid[near], True, None
    blocks(grid)
    costs = [cost(u) for u in grid]
    best = int(np.argmin(costs))
    watched = None
    if null_cost is not None and SCAN_WATCHERS:  # a survey of the scans (tests/measurement/coarse_scan_survey.py)
        watched = {"effect": scan.effect, "param": scan.name, "values": values, "grid": own,
                   "extra": extra, "costs": costs, "null": null_cost, "n_free": len(free)}
    if null_cost is not None and costs[best] >= null_cost * (1.0 - SKIP_MARGIN):
        return grid[best], True, watched
    # the start itself stays a candidate: a scan whose every value is worse than where the fit starts (a valley
    # narrower than the grid's steps, around a start that sits in it) must not move the fit out of it
    start = np.clip(u0, 0.0, 1.0)
    return min(_zoomed(obj, grid, best, k, scan.step) + [start], key=cost), False, watched


def _zoomed(obj: Objective, grid: list, best: int, k: int, step: float) -> list:
    """The scan's points (sorted by the scanned number ``k``) with finer scans between the best point's
    neighbours: one always, and again (up to :data:`ZOOM_LEVELS`) while the valley stays sharper than the
    spacing (both neighbours above the best by :data:`ZOOM_SHARP`, or the last zoom lowered the best by
    :data:`ZOOM_GAIN`: the best sits on a wall of a valley the spacing has not reached) and the spacing is wider
    than the number's difference step.  A valley narrower than the difference step is one the least squares cannot see: the
    Jacobian's step lands beyond it (a rate limit's, from rest, is +-1 % wide: results/verdict_start_conditions).
    """
    cost = obj.cost
    pts = sorted(grid, key=lambda u: u[k])
    best = next(j for j, u in enumerate(pts) if u is grid[best])
    before = math.inf
    for level in range(ZOOM_LEVELS):
        left, right = pts[max(best - 1, 0)], pts[min(best + 1, len(pts) - 1)]
        here = cost(pts[best])
        sharp = min(cost(left), cost(right)) > (1.0 + ZOOM_SHARP) * here or here < (1.0 - ZOOM_GAIN) * before
        if level and not (sharp and (right[k] - left[k]) / 5.0 > step):
            break
        before = here
        fine = []
        for x in np.linspace(left[k], right[k], 6)[1:-1]:
            u = pts[best].copy()
            u[k] = x
            fine.append(u)
        obj.blocks(fine)
        pts = sorted(pts + fine, key=lambda u: u[k])
        best = min(range(len(pts)), key=lambda j: cost(pts[j]))
    return pts


def _tell(watched: dict | None, final: float) -> None:
    """A scan's record (None: not watched) and the cost its fit ended at, to every :data:`SCAN_WATCHERS`."""
    if watched is not None:
        for watcher in SCAN_WATCHERS:
            watcher({**watched, "final": final})


def own_params(effect: str) -> list[FreeParam]:
    return [fit_range(effect, p.name) for p in get_effect(effect).params]


def recal_params(effects) -> list[FreeParam]:
    """beta and K, unless an effect in ``effects`` (bulk_modulus, valve_dynamics) sets them itself."""
    taken = set()
    if "bulk_modulus" in effects:
        taken.add("beta")
    if "valve_dynamics" in effects:
        taken.add("K")
    return [fp for fp in baseline_params() if fp.name not in taken]



CI_BLOCK_S = 0.25  # clusters of the confidence intervals: stretches of this length of each run ...
CI_LAGS = 0  # ... whose covariance with this many following clusters of the same run is counted too


def confidence(rep: Replayer, f: Fit, level: float = 0.95, block_s: float | None = None,
               lags: int | None = None) -> dict:
    """Confidence intervals of every fitted number of ``f``: {(effect, name): (low, high)}.

    The covariance is the cluster-robust ("sandwich") estimate of the weighted least-squares fit,
    H^-1 (sum_c g_c g_c^T) H^-1 with H = J^T J and g_c the gradient of cluster c, the clusters being
    ``block_s`` stretches of each run (all its signals together): it holds when the residual is
    coloured and correlated across signals, and when part of it is model error rather than noise.
    Intervals use Student's t with (clusters - parameters) degrees of freedom; log-scaled
    parameters get multiplicative intervals.  A side the data do not bound is ``inf`` (``-inf``, or 0 for a
    log-scaled number): :func:`interval`.
    """
    from scipy.stats import t as student

    from ehas_env.measurement.replay import COST_SIGNALS

    block_s = CI_BLOCK_S if block_s is None else block_s
    lags = CI_LAGS if lags is None else lags
    free = f.free
    if not free:
        return {}
    u = np.array([fp.u(_value_of(f.model, fp)) for fp in free])

    obj = Objective(rep, free, f.model)
    w = obj.weights(u)
    r0 = obj.weighted(u, w)
    Jm = obj.jacobian(u, w)
    sims0 = obj.sims(u)
    clusters = []
    offset = 0
    for case, _ in rep.cost_cases(sims0):  # the runs of the cost's blocks, in their order
        nblk = int(math.ceil(case.run.n * case.run.dt / block_s)) + 1 + lags  # empty slots: no cross-run lags
        idx = np.arange(case.skip, case.run.n)
        cid = offset + (idx * case.run.dt / block_s).astype(int)
        for s in case.signals:
            if s in COST_SIGNALS:
                clusters.append(cid)
        offset += nblk
    cl = np.concatenate(clusters)
    # the rows of the runs judged sample by sample alone: a run whose loop does not repeat enters the cost on its
    # cycle envelope (rows after these), whose values are no samples' errors to cluster -- the intervals are what
    # the predictable runs say
    r0, Jm = r0[:cl.size], Jm[:cl.size]
    G = len(np.unique(cl))
    p = len(free)
    H = Jm.T @ Jm
    Hi = np.linalg.pinv(H)
    g = np.zeros((offset, p))
    np.add.at(g, cl, Jm * r0[:, None])
    meat = g.T @ g
    # residuals correlated beyond one cluster (a slow limit cycle, model error that follows the sine):
    # Bartlett-weighted covariances of each cluster with the next ``lags`` ones (Newey-West over clusters);
    # clusters of different runs are separated by the empty slot at the end of each run's range
    for lag in range(1, lags + 1):
        w_l = 1.0 - lag / (lags + 1.0)
        c = g[:-lag].T @ g[lag:]
        meat += w_l * (c + c.T)
    cov = Hi @ meat @ Hi * (G / max(G - p, 1))
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    # a number the data do not inform at all (its column of J is zero: a friction on a valve bench run, a supply
    # term on a run that never opens the valve far) has no variance in the pseudo-inverse -- a zero-width interval
    # that would claim it exactly known; it is unbounded either way
    col = np.sqrt(np.sum(Jm * Jm, axis=0))
    sd[col <= UNINFORMED * max(float(np.max(col)), 1e-300)] = math.inf
    tq = float(student.ppf(0.5 + level / 2.0, max(G - p, 1)))
    out = {}
    for fp, ui, si in zip(free, u, sd):
        v = fp.value(ui)
        lo, hi = interval(fp, v, float(si), tq)
        if (fp.effect, fp.name) in STAIRCASE:
            # the model resolves this number only to a stair (the delay to the integrator's sub-step): values
            # within one stair of the fit simulate alike, so the data cannot place the truth closer than that
            res = STAIRCASE[(fp.effect, fp.name)] * min((c.dt for c in rep.cases), default=1e-3) / rep.substeps
            lo, hi = min(lo, v - res), max(hi, v + res)
        if fp.effect not in (None, TERM):
            blo, bhi = get_effect(fp.effect).param(fp.name).bounds
            lo, hi = max(lo, blo), min(hi, bhi)
        out[(fp.effect, fp.name)] = (float(lo), float(hi))
    return out


#: a fitted number whose Jacobian column is at most this share of the largest one is taken as not informed by the
#: data (its interval unbounded: :func:`confidence`): the forward difference of a number that does not enter the
#: replay (a piston's friction on the valve bench) is exactly 0 -- the share leaves room for round-off alone
#: (test_confidence_interval: without it the friction's interval was 300 [300, 300] N)
UNINFORMED = 1.0e-9


def interval(fp: FreeParam, value: float, sd_u: float, tq: float) -> tuple[float, float]:
    """The interval ``value`` +- ``tq`` standard deviations of a fitted number, in its own unit.

    Parameters
    ----------
    fp : FreeParam
        The fitted number: its standard deviation is in u (its fit range mapped to [0, 1]), so a
        log-scaled number gets a multiplicative interval.
    value : float
        The fitted value, in the number's unit.
    sd_u : float
        Its standard deviation in u (infinite or NaN: the data do not determine it).
    tq : float
        Student's t quantile of the interval's level.

    Returns
    -------
    (low, high) : tuple of float
        The bounds in the number's unit.  A number the data bound so loosely that a bound leaves the
        floating-point range is unbounded on that side: ``high`` is ``inf``, ``low`` is ``-inf`` (or 0
        for a log-scaled, positive number); callers print and store such a bound as "unbounded".
    """
    half = tq * sd_u  # in u
    if not math.isfinite(half):
        return (0.0 if fp.log else -math.inf), math.inf
    if fp.log:
        e = half * (math.log(fp.hi) - math.log(fp.lo))
        try:
            hi = value * math.exp(e)
        except OverflowError:  # a poorly determined number: e beyond ~709
            hi = math.inf
        return value * math.exp(-e), hi  # exp(-e) underflows to 0.0 quietly
    d = half * (fp.hi - fp.lo)
    return value - d, value + d


def _value_of(model: ModelSpec, fp: FreeParam) -> float:
    if fp.effect is None:
        return model.beta if fp.name == "beta" else model.K
    if fp.effect == TERM:
        return model.terms[fp.name]
    return model.effects[fp.effect][fp.name]



def _unit(effect, name) -> str:
    if effect is None:
        return "Pa" if name == "beta" else "LPM/mA"
    if effect == TERM:
        return term_param(name).unit
    return get_effect(effect).param(name).unit
