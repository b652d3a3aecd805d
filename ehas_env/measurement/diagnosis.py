"""Which physical effect is the model missing?  Fit every candidate, rank, explain.

The baseline's uncertain numbers (bulk modulus beta within +-7 %, valve gain K
within +-3 % of nominal) are recalibrated first: that is the *null* model, the
best the baseline can do.  Then every effect of the library
(``ehas_env.physics.effects.REGISTRY``) is tried in turn: added to the null model, its
parameters fitted on the whole campaign together with beta and K
(``bulk_modulus`` frees beta over its full range, ``valve_dynamics`` frees K),
by a coarse scan of the main parameter followed by bounded least squares
(``scipy.optimize.least_squares``) on the noise-normalised residuals of every
logged signal of every run.

The cost J is the mean squared residual in units of each signal's own noise
level (estimated from the measurements), taken per run and signal and
averaged geometrically over them (:meth:`Replayer.log_cost`: maximum
likelihood when each run and signal has its own residual level, so a run whose
limit cycle or joint knocks cannot be matched sample by sample does not swamp
the others); J ~ 1 means "explained down to the sensor noise".  It is
minimised by iteratively reweighted least squares.  A candidate's score is the
reduction of J in decibels, 10 log10(J_null / J_candidate), less
:data:`PENALTY_PER_PARAM` dB per fitted parameter of the effect (so an effect
with more parameters must explain clearly more to rank higher: Stribeck
friction over Coulomb friction only when the breakaway peak is really there).
It *beats noise* when it scores at least :data:`MIN_SCORE` and lowers J by at
least :data:`MIN_GAIN`; when no candidate does, the diagnosis is ``"none"``.
Effects stack: :func:`diagnose` accepts effects already added
(``base_effects``), refits them with each new candidate, and finds the next.

Examples
--------
>>> from ehas_env.cli.campaign import simulate_campaign
>>> from ehas_env.measurement.campaign import Campaign, validate_run
>>> runs, _ = simulate_campaign({"viscous_friction": {"b": 4200}}, seed=11, duration=0.5,
...                             plan=((1, 30.0, 3.0),), valve=False)
>>> camp = Campaign(None, [validate_run(n, c, m) for n, c, m in runs])
>>> d = diagnose(camp, candidates=["viscous_friction", "coulomb_friction"])
>>> d.ranking[0].effect, round(d.ranking[0].params["b"], -2)
('viscous_friction', 4200.0)
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ehas_env.measurement.campaign import Campaign
from ehas_env.physics.effects import REGISTRY, get_effect
from ehas_env.measurement.replay import FitTable, ModelSpec, Replayer
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
REFINE_TOP = 3  # at most this many candidates are refined with beta, K (and the base effects) ...
REFINE_WITHIN_DB = 3.0  # ... those screened within this many dB of the best


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
    if effect in ("valve_dynamics", "bulk_modulus") or (effect, pname) == ("supply_droop", "p0"):
        # recalibrations and the precharge act strongly (the loop's stability hangs on beta and wn):
        # a narrower range, scanned finely enough to land in the valley
        lo, hi = max(blo, tlo / 1.6), min(bhi, thi * 1.6)
    log = lo > 0 and hi / lo >= 8.0
    return FreeParam(effect, pname, lo, hi, log, _step(effect, pname))


def _step(effect: str, pname: str) -> float:
    # the delay acts at the integrator's sub-step resolution (0.1 ms): a staircase
    # cost, so its derivative needs a step spanning several stairs
    return 0.03 if (effect, pname) == ("transport_delay", "tau") else 2e-3


def baseline_params() -> list[FreeParam]:
    return [FreeParam(None, "beta", BULK_MODULUS * BETA_RANGE[0], BULK_MODULUS * BETA_RANGE[1], False),
            FreeParam(None, "K", VALVE_K * K_RANGE[0], VALVE_K * K_RANGE[1], False)]


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


def model_from(free: list[FreeParam], values: dict, fixed: ModelSpec | None = None) -> ModelSpec:
    """``fixed`` (effects, beta, K) with the free values {(effect, name): value} set."""
    fixed = fixed or ModelSpec()
    effects = {n: dict(p) for n, p in fixed.effects.items()}
    beta, K = fixed.beta, fixed.K
    for fp in free:
        v = values[(fp.effect, fp.name)]
        if fp.effect is None:
            if fp.name == "beta":
                beta = v
            else:
                K = v
        else:
            effects.setdefault(fp.effect, {})[fp.name] = v
    st = effects.get("stribeck_friction")
    if st and "Fs" in st and "Fc" in st and st["Fs"] < st["Fc"]:
        # Stribeck friction keeps its definition (breakaway at or above sliding, Fs >= Fc; the effect
        # refuses less): where the fit wanders below, the breakaway sits at the sliding level
        effects["stribeck_friction"] = {**st, "Fs": st["Fc"]}
    return ModelSpec(effects=effects, beta=beta, K=K)


def scan_values(fp: FreeParam) -> list[float]:
    """Values of a parameter tried before fitting: log- or linearly spaced over its fit range;
    a signed parameter (null bias) gets both signs of log-spaced magnitudes."""
    if fp.lo < 0.0:
        p = get_effect(fp.effect).param(fp.name)
        small = max(min(abs(x) for x in p.typical) / 4.0, 1e-3 * fp.hi) if p.typical else 1e-3 * fp.hi
        mags = np.geomspace(small, fp.hi, (SCAN_POINTS + 3) // 2)
        return sorted([float(-m) for m in mags] + [float(m) for m in mags])
    if fp.log:
        return [float(v) for v in np.geomspace(fp.lo, fp.hi, SCAN_POINTS)]
    return [float(v) for v in np.linspace(fp.lo, fp.hi, SCAN_POINTS)]


def fit(rep: Replayer, free: list[FreeParam], start: dict, fixed: ModelSpec | None = None, *,
        scan: FreeParam | None = None, max_nfev: int = MAX_NFEV, tol: float = 1e-4,
        null_cost: float | None = None) -> Fit:
    """Fit the ``free`` parameters from ``start``: a scan of ``scan`` first, then bounded least squares.

    Works in u in [0, 1] per parameter; the Jacobian is a forward difference whose
    perturbed models are simulated together (:meth:`Replayer.simulate_many`).
    With ``null_cost``, a candidate whose scan never beats it is not fitted further
    (it explains nothing anywhere in its range; its best scan point is returned).
    """
    u0 = np.array([fp.u(start[(fp.effect, fp.name)]) for fp in free])
    evals0 = rep.n_evals
    memo: dict[bytes, tuple] = {}

    def model_u(u):
        return model_from(free, {(fp.effect, fp.name): fp.value(x) for fp, x in zip(free, u)}, fixed)

    def blocks(U):
        todo = [u for u in U if u.tobytes() not in memo]
        if todo:
            for u, sims in zip(todo, rep.simulate_many([model_u(u) for u in todo])):
                memo[u.tobytes()] = (rep.cost_blocks(sims), sims)
        return [memo[u.tobytes()][0] for u in U]

    def cost(u) -> float:
        """Geometric mean over (run, signal) blocks (see :meth:`Replayer.log_cost`)."""
        b = blocks([np.asarray(u, dtype=float)])[0]
        n = sum(x.size for x in b)
        return float(np.exp(sum(x.size * np.log(max(float(np.dot(x, x)) / x.size, 1e-300)) for x in b) / n))

    def result(u) -> Fit:
        cost(u)
        sims = memo[u.tobytes()][1]
        return Fit(model=model_u(u), cost=cost(u), free=free, sims=sims, table=rep.fit_table(sims),
                   nfev=rep.n_evals - evals0)

    if scan is not None:
        k = free.index(scan)
        grid = []
        for value in scan_values(scan):
            u = u0.copy()
            u[k] = scan.u(value)
            grid.append(u)
        blocks(grid)
        costs = [cost(u) for u in grid]
        best = int(np.argmin(costs))
        if null_cost is not None and costs[best] >= null_cost * (1.0 - SKIP_MARGIN):
            return result(grid[best])
        # zoom: a finer scan between the best point's neighbours
        left = grid[max(best - 1, 0)][k]
        right = grid[min(best + 1, len(grid) - 1)][k]
        fine = []
        for x in np.linspace(left, right, 6)[1:-1]:
            u = grid[best].copy()
            u[k] = x
            fine.append(u)
        blocks(fine)
        u0 = min(grid + fine, key=cost)
    # iteratively reweighted least squares for the log cost: each block weighted by its
    # residual level at the round's start point (the log cost's gradient there)
    u_ref = np.clip(u0, 0.0, 1.0)
    for _ in range(IRLS_ROUNDS):
        w = [1.0 / np.sqrt(max(float(np.dot(x, x)) / x.size, 1e-12)) for x in blocks([u_ref])[0]]

        def fun(u, w=w):
            return np.concatenate([wi * x for wi, x in zip(w, blocks([np.asarray(u, dtype=float)])[0])])

        def jac(u, w=w):
            u = np.asarray(u, dtype=float)
            f0 = fun(u)
            U, H = [], []
            for i, fp in enumerate(free):
                h = fp.step if u[i] + fp.step <= 1.0 else -fp.step
                du = u.copy()
                du[i] += h
                U.append(du)
                H.append(h)
            blocks(U)
            return np.column_stack([(fun(du) - f0) / h for du, h in zip(U, H)])

        res = least_squares(fun, u_ref, jac=jac, bounds=(0.0, 1.0), method="trf", x_scale=1.0,
                            max_nfev=max(max_nfev // IRLS_ROUNDS, 3), xtol=tol, ftol=tol, gtol=1e-8)
        u_new = np.asarray(res.x, dtype=float)
        if cost(u_new) >= cost(u_ref):
            break
        u_ref = u_new
    return result(u_ref)


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


@dataclass
class Entry:
    """One ranked candidate."""

    effect: str
    params: dict[str, float]
    fit_percent: float
    score: float
    evidence: str
    cost: float
    beats_noise: bool
    fit: Fit | None = None

    def to_json(self) -> dict:
        return {"effect": self.effect, "params": {k: _round(v) for k, v in self.params.items()},
                "fit_percent": round(self.fit_percent, 2), "score": round(self.score, 2), "evidence": self.evidence}


def _round(v: float) -> float:
    return float(f"{v:.4g}")


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`."""

    baseline: Fit  # nominal baseline (+ base effects at their given values), nothing fitted
    null: Fit  # baseline with beta, K (and base effects) recalibrated
    ranking: list[Entry]
    base_effects: dict = field(default_factory=dict)
    elapsed_s: float = 0.0
    n_evals: int = 0

    @property
    def top(self) -> Entry:
        return self.ranking[0]

    @property
    def found(self) -> str:
        """Name of the effect found, or ``"none"``."""
        return self.ranking[0].effect

    def to_json(self) -> dict:
        """The JSON of docs/measurement-format.md."""
        return {"baseline": {"fit_percent": round(self.baseline.table.overall, 2),
                             "per_signal": {k: round(v, 2) for k, v in self.baseline.table.per_signal.items()}},
                "ranking": [e.to_json() for e in self.ranking]}


def fit_null(rep: Replayer, base_effects: dict | None = None) -> Fit:
    """The baseline's best: beta and K (and the base effects' parameters) recalibrated."""
    base_effects = base_effects or {}
    free = [fp for n in base_effects for fp in own_params(n)] + recal_params(base_effects)
    start = {(fp.effect, fp.name): (base_effects[fp.effect][fp.name] if fp.effect else start_value(fp)) for fp in free}
    return fit(rep, free, start, ModelSpec(effects=base_effects), scan=_beta(free))


def _beta(free: list[FreeParam]) -> FreeParam | None:
    """The recalibrated beta, scanned before fitting: where a run's residual is a limit cycle or
    joint knocks, the cost is rough in beta and a local fit stays where it starts."""
    return next((fp for fp in free if fp.effect is None and fp.name == "beta"), None)


#: an effect that extends another starts from the other's fit: Stribeck friction is Coulomb
#: friction plus a breakaway peak, so its sliding level starts at the Coulomb level found
NESTED = {"stribeck_friction": ("coulomb_friction", {"Fc": "Fc"})}


def screen_candidate(rep: Replayer, effect: str, null: Fit, screened: dict | None = None) -> Fit:
    """Stage 1: the effect's own parameters only, on top of the null model (scan, then a short fit).

    ``screened`` holds the fits of effects screened before (warm starts, see :data:`NESTED`).
    """
    free = own_params(effect)
    start = {(fp.effect, fp.name): start_value(fp) for fp in free}
    inner, mapping = NESTED.get(effect, (None, {}))
    prev = (screened or {}).get(inner)
    if prev is not None and prev.cost < null.cost * (1.0 - SKIP_MARGIN):
        for mine, theirs in mapping.items():
            start[(effect, mine)] = prev.model.effects[inner][theirs]
    main = next(fp for fp in free if fp.name == get_effect(effect).main_param)
    return fit(rep, free, start, null.model, scan=main, max_nfev=SCREEN_NFEV * len(free), tol=1e-3,
               null_cost=null.cost)


def refine_candidate(rep: Replayer, effect: str, screened: Fit, null: Fit, base_effects: dict) -> Fit:
    """Stage 2: the effect's parameters with beta, K and the base effects, from the screening fit."""
    effects = {**base_effects, effect: {}}
    free = own_params(effect) + [fp for n in base_effects for fp in own_params(n)] + recal_params(effects)
    m = screened.model
    start = {}
    for fp in free:
        if fp.effect is None:
            start[(None, fp.name)] = m.beta if fp.name == "beta" else m.K
        else:
            start[(fp.effect, fp.name)] = m.effects[fp.effect][fp.name]
    f = fit(rep, free, start, m, scan=_beta(free))
    return f if f.cost <= screened.cost else screened


def fit_candidate(rep: Replayer, effect: str, null: Fit, base_effects: dict | None = None) -> Fit:
    """Add ``effect`` to the null model and fit it fully (screen, then refine with beta, K, base effects)."""
    return refine_candidate(rep, effect, screen_candidate(rep, effect, null), null, base_effects or {})


def diagnose(campaign: Campaign, *, base_effects: dict | None = None, candidates=None, progress: bool = False,
             replayer: Replayer | None = None) -> Diagnosis:
    """Rank the library's effects by how much of the baseline's misfit each explains.

    Parameters
    ----------
    campaign : Campaign
        The measurements.
    base_effects : dict, optional
        Effects already added ({name: {param: value}}): refitted with every
        candidate, so the next effect is found on top of them.
    candidates : iterable of str, optional
        Effects to try (default: every effect of the registry not in ``base_effects``).
    progress : bool
        Show a progress bar.
    """
    from ehas_env.measurement.residuals import evidence_text

    t0 = time.perf_counter()
    rep = replayer or Replayer(campaign)
    base_effects = {n: dict(p) for n, p in (base_effects or {}).items()}
    names = [n for n in (candidates or REGISTRY) if n not in base_effects]
    for n in names:
        get_effect(n)
    baseline_sims = rep.simulate(ModelSpec(effects=base_effects))
    baseline = Fit(ModelSpec(effects=base_effects), rep.log_cost(baseline_sims), [], baseline_sims,
                   rep.fit_table(baseline_sims))
    null = fit_null(rep, base_effects)
    fits = {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(names) + min(REFINE_TOP, len(names)), desc="diagnose", unit="fit")
    # nested effects after the effects they extend (warm starts)
    names.sort(key=lambda n: n in NESTED)
    for n in names:
        fits[n] = screen_candidate(rep, n, null, fits)
        if bar:
            bar.update()
    helpful = [n for n in sorted(fits, key=lambda n: fits[n].cost) if fits[n].cost < null.cost * (1.0 - SKIP_MARGIN)]
    # refine the best, and whoever screened within REFINE_WITHIN_DB of it (a close call is decided
    # after beta and K have been refitted with each)
    near = [n for n in helpful if 10.0 * math.log10(fits[n].cost / fits[helpful[0]].cost) <= REFINE_WITHIN_DB]
    if bar:
        bar.total = len(names) + len(near[:REFINE_TOP])
        bar.refresh()
    for n in near[:REFINE_TOP]:
        fits[n] = refine_candidate(rep, n, fits[n], null, base_effects)
        if bar:
            bar.update()
    if bar:
        bar.close()
    entries = []
    for n, f in fits.items():
        k = len(get_effect(n).params)
        gain = null.cost - f.cost
        score = 10.0 * math.log10(null.cost / f.cost) - PENALTY_PER_PARAM * k
        beats = score >= MIN_SCORE and gain >= MIN_GAIN
        entries.append(Entry(effect=n, params=dict(f.model.effects.get(n, {})), fit_percent=f.table.overall,
                             score=score, evidence="", cost=f.cost, beats_noise=beats, fit=f))
    entries.sort(key=lambda e: e.score, reverse=True)
    for e in entries:
        e.evidence = evidence_text(rep, null, e)
    if not entries or not entries[0].beats_noise:
        none = Entry(effect="none", params={}, fit_percent=null.table.overall, score=0.0,
                     evidence=evidence_text(rep, null, None), cost=null.cost, beats_noise=False, fit=null)
        entries.insert(0, none)
    return Diagnosis(baseline=baseline, null=null, ranking=entries, base_effects=base_effects,
                     elapsed_s=time.perf_counter() - t0, n_evals=rep.n_evals)


def calibrate(campaign_or_replayer, effects: dict, *, scan: bool = True) -> tuple[Fit, Fit]:
    """Fit ``effects`` (added one after another, then refitted together) with beta and K.

    Parameters
    ----------
    campaign_or_replayer : Campaign or Replayer
    effects : dict
        {name: {param: value}}; given values are start values (no scan for an
        effect whose main parameter is given).
    scan : bool
        Scan the main parameter of effects given without values.

    Returns
    -------
    null, fitted : Fit
        The recalibrated baseline and the calibrated model.
    """
    rep = campaign_or_replayer if isinstance(campaign_or_replayer, Replayer) else Replayer(campaign_or_replayer)
    for n in effects:
        get_effect(n)
    null = fit_null(rep)
    current = null
    added: dict = {}
    for n, given in effects.items():
        given = dict(given or {})
        free = own_params(n)
        start = {(fp.effect, fp.name): given.get(fp.name, start_value(fp)) for fp in free}
        main = next(fp for fp in free if fp.name == get_effect(n).main_param)
        screened = fit(rep, free, start, current.model, scan=main if scan and main.name not in given else None,
                       max_nfev=SCREEN_NFEV, tol=1e-3)
        current = refine_candidate(rep, n, screened, current, added)
        added = {k: dict(v) for k, v in current.model.effects.items()}
    return null, current
