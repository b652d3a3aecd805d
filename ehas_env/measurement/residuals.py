"""Where the model fails: residual signatures against physical regressors.

A residual is measured minus simulated.  Each effect of the library leaves its
own signature in the residuals of the signals it touches (the effects'
``signature`` texts): Coulomb friction a load residual that tracks
sign(velocity), viscous friction one that tracks velocity, piston mass one in
phase with acceleration, leakage a current residual that tracks the load
pressure, null bias a constant, a delay a residual correlated with the current
some milliseconds earlier, and so on.  This module measures those signatures:

* the share of each residual's energy explained by each physical regressor
  (velocity and its sign, position, acceleration, load and mean chamber
  pressure, supply pressure, flow magnitude, current, its sign and lagged
  copies), and by a constant;
* the residual's size in units of the signal's own noise level;
* its spectrum (dominant frequency) and a whiteness test (share of the first
  50 autocorrelation lags outside the 99 % band of white noise);
* its cross-correlation with the input current (the classical residual test
  for unmodelled input dynamics): peak value and lag.

Regressors come from the noise-free model run (velocity and acceleration of a
noisy angle would be noise) except the supply pressure, which is measured.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ehas_env.measurement.replay import COST_SIGNALS, UNITS, Replayer
from ehas_env.measurement.verdict import FIGURE_KEY, blocks_of, figure_text, grade

LAGS_MS = (2, 5, 10)
WHITE_LAGS = 50
Z99 = 2.576  # two-sided 99 % point of the normal distribution


def regressors(case, sim: dict) -> dict[str, np.ndarray]:
    """Physical regressors of one run (model's noise-free states, measured supply pressure)."""
    run = case.run
    dt = run.dt
    if run.kind == "valve_open_loop":
        i = run.columns["current_mA"]
        reg = {"current": i, "sign(current)": np.sign(i), "current rate": np.gradient(i, dt)}
    else:
        w = sim["omega_deg_s"]
        wmax = max(float(np.max(np.abs(w))), 1e-9)
        i = sim["current_mA"]
        reg = {
            "velocity": w,
            "sign(velocity)": np.tanh(w / (0.01 * wmax)),
            "position": sim["theta_deg"],
            "acceleration": np.gradient(w, dt),
            "load pressure": sim["p_a_bar"] - sim["p_b_bar"],
            "mean chamber pressure": 0.5 * (sim["p_a_bar"] + sim["p_b_bar"]),
            "|flow|": np.abs(sim["flow_lpm"]),
            "current": i,
            "sign(current)": np.sign(i),
        }
        if "p_s_bar" in run.columns:
            reg["supply pressure"] = run.columns["p_s_bar"]
    for lag in LAGS_MS:
        k = int(round(lag * 1e-3 / dt))
        if 0 < k < i.size:
            reg[f"current {lag} ms earlier"] = np.r_[np.full(k, i[0]), i[:-k]]
    return reg


def explained_shares(e: np.ndarray, reg: dict[str, np.ndarray]) -> dict[str, float]:
    """Share of the residual's energy (mean square) explained by each regressor.

    ``constant`` is the share of the mean; for a regressor x it is the share of
    the energy that a straight line in x explains beyond the mean
    (squared correlation times variance / mean square).

    Examples
    --------
    >>> x = np.linspace(-1, 1, 201)
    >>> s = explained_shares(2.0 * x, {"x": x, "x^2": x**2})
    >>> round(s["x"], 3), round(s["x^2"], 3), round(s["constant"], 3)
    (1.0, 0.0, 0.0)
    """
    ms = float(np.mean(e**2))
    out = {"constant": float(np.mean(e)) ** 2 / ms if ms > 0 else 0.0}
    ec = e - e.mean()
    var = float(np.mean(ec**2))
    for name, x in reg.items():
        xc = x - x.mean()
        sx = float(np.sqrt(np.mean(xc**2)))
        if sx == 0.0 or var == 0.0:
            out[name] = 0.0
            continue
        r = float(np.mean(ec * xc)) / (sx * math.sqrt(var))
        out[name] = r * r * var / ms
    return out


def whiteness(e: np.ndarray, lags: int = WHITE_LAGS) -> float:
    """Share of autocorrelation lags 1..lags outside the 99 % band of white noise (0 = white)."""
    ec = e - e.mean()
    n = ec.size
    den = float(np.dot(ec, ec))
    if den == 0.0 or n <= lags:
        return 0.0
    r = np.array([np.dot(ec[:-k], ec[k:]) / den for k in range(1, lags + 1)])
    return float(np.mean(np.abs(r) > Z99 / math.sqrt(n)))


def input_correlation(e: np.ndarray, u: np.ndarray, dt: float, max_lag_s: float = 0.03) -> tuple[float, float, bool]:
    """Peak |normalised cross-correlation| of residual e with earlier input u: (value, lag s, significant)."""
    ec, uc = e - e.mean(), u - u.mean()
    den = math.sqrt(float(np.dot(ec, ec)) * float(np.dot(uc, uc)))
    if den == 0.0:
        return 0.0, 0.0, False
    n = e.size
    kmax = min(int(max_lag_s / dt), n // 4)
    c = np.array([np.dot(ec[k:], uc[:n - k]) / den for k in range(kmax + 1)])
    k = int(np.argmax(np.abs(c)))
    return float(c[k]), k * dt, bool(abs(c[k]) > Z99 / math.sqrt(n))


def dominant_frequency(e: np.ndarray, dt: float) -> float:
    """Frequency (Hz) of the residual spectrum's peak (Welch), ignoring DC."""
    from scipy.signal import welch

    f, p = welch(e - e.mean(), fs=1.0 / dt, nperseg=min(1024, e.size))
    if p.size < 2:
        return 0.0
    return float(f[1 + int(np.argmax(p[1:]))])


@dataclass
class SignalSignature:
    """Residual statistics of one signal over a set of runs (energy-weighted)."""

    signal: str
    kind: str  # closed_loop or valve_open_loop
    rms: float  # in the signal's unit
    noise: float  # estimated noise level, same unit
    shares: dict[str, float]  # regressor -> share of residual energy explained
    nonwhite: float  # share of autocorrelation lags outside the white band
    peak_hz: float
    xcorr: float
    xcorr_lag_s: float
    xcorr_significant: bool
    energy: float  # noise-normalised residual energy (sum of squares / noise^2)

    @property
    def ratio(self) -> float:
        return self.rms / self.noise if self.noise > 0 else float("inf")

    @property
    def key(self) -> str:
        return self.signal if self.kind == "closed_loop" else f"{self.signal} (valve)"

    def top(self, k: int = 2) -> list[tuple[str, float]]:
        return sorted(self.shares.items(), key=lambda kv: kv[1], reverse=True)[:k]


def signatures(rep: Replayer, sims) -> dict[str, SignalSignature]:
    """Residual signature per signal (closed-loop runs pooled; valve runs apart)."""
    pools: dict[tuple[str, str], list] = {}
    for case, sim in zip(rep.cases, sims):
        if sim is None:
            continue
        reg = regressors(case, sim)
        u = case.run.columns["current_mA"]
        for s in case.signals:
            e = case.measured[s] - sim[s]
            pools.setdefault((s, case.run.kind), []).append((e, reg, case.noise[s], case.run.dt, u))
    out = {}
    for (s, kind), items in pools.items():
        energies = np.array([float(np.sum(e**2)) for e, *_ in items])
        w = energies / energies.sum() if energies.sum() > 0 else np.full(len(items), 1.0 / len(items))
        shares: dict[str, float] = {}
        nonwhite = peak = 0.0
        best_xc = (0.0, 0.0, False)
        for wk, (e, reg, noise, dt, u) in zip(w, items):
            if s == "p_s_bar":  # the measured supply pressure is this signal itself
                reg = {k: v for k, v in reg.items() if k != "supply pressure"}
            for name, v in explained_shares(e, reg).items():
                shares[name] = shares.get(name, 0.0) + wk * v
            nonwhite += wk * whiteness(e)
            xc = input_correlation(e, u, dt)
            if abs(xc[0]) > abs(best_xc[0]):
                best_xc = xc
        k_big = int(np.argmax(energies))
        peak = dominant_frequency(items[k_big][0], items[k_big][3])
        n = sum(e.size for e, *_ in items)
        rms = math.sqrt(energies.sum() / n)
        noise = math.sqrt(sum(nz**2 * e.size for e, _, nz, _, _ in items) / n)
        norm_energy = sum(float(np.sum(e**2)) / nz**2 for e, _, nz, _, _ in items)
        out[s if kind == "closed_loop" else f"{s} (valve)"] = SignalSignature(
            s, kind, rms, noise, shares, nonwhite, peak, best_xc[0], best_xc[1], best_xc[2], norm_energy)
    return out


def where_it_fails(rep: Replayer, sims, title: str = "baseline") -> str:
    """Plain-text table: per signal, residual vs noise, whiteness, spectrum peak, best regressors."""
    sig = signatures(rep, sims)
    lines = [f"where the {title} fails (residual = measured - model)",
             f"{'signal':<18}{'RMS resid':>11}{'RMS/noise':>10}{'non-white':>10}{'peak Hz':>9}  "
             "residual tracks (share of its energy)"]
    for key, s in sorted(sig.items(), key=lambda kv: kv[1].ratio, reverse=True):
        tops = ", ".join(f"{n} {100 * v:.0f}%" for n, v in s.top(3))
        lines.append(f"{key:<18}{s.rms:>8.3g} {UNITS[s.signal]:<3}{s.ratio:>9.1f}{100 * s.nonwhite:>9.0f}%"
                     f"{s.peak_hz:>9.1f}  {tops}")
    xs = [s for s in sig.values() if s.xcorr_significant and abs(s.xcorr) > 0.2]
    for s in sorted(xs, key=lambda s: abs(s.xcorr), reverse=True)[:3]:
        lines.append(f"  {s.key}: residual correlates with the current {1e3 * s.xcorr_lag_s:.0f} ms earlier "
                     f"(r = {s.xcorr:+.2f}, beyond the 99 % band of white noise)")
    return "\n".join(lines)


def _fmt_params(effect: str, params: dict) -> str:
    from ehas_env.physics.effects import get_effect

    cls = get_effect(effect)
    return ", ".join(f"{k} = {v:.3g} {cls.param(k).unit}" for k, v in params.items())


def evidence_text(rep: Replayer, null, entry) -> str:
    """Words on what a candidate's fit removed from the null model's residuals."""
    before = signatures(rep, null.sims)
    total = sum(s.energy for k, s in before.items() if s.signal in COST_SIGNALS)
    if entry is None:
        # the model's residual as the verdict states it (one noise figure, ehas_env.measurement.verdict); the
        # recalibrated beta and K are not repeated here (the final model is printed once, as a difference from
        # the book's rig, and an effect such as bulk_modulus may have replaced them)
        what = "baseline" + "".join(f" + {n}" for n in null.model.effects)
        g = grade(blocks_of(rep, null.sims, COST_SIGNALS))
        w = g["worst"] or {}
        where = (f"worst: {w['signal']} in run {w['run']}, {w[FIGURE_KEY]:.2f}x" if w else "")
        if g["verdict"] != "explained":
            return (f"no effect of the library explains the residual: the recalibrated {what} leaves a residual of "
                    f"{figure_text(g[FIGURE_KEY])} ({g['verdict']}; {where}), and no candidate removes a "
                    "significant share of it: see the verdict and the proposed term")
        return (f"nothing beats noise: the recalibrated {what} leaves a residual of {figure_text(g[FIGURE_KEY])} "
                f"({where}), and no effect removes a significant share of it")
    after = signatures(rep, entry.fit.sims)
    # the (signal, regressor) whose explained residual energy fell most
    best = None
    for key, b in before.items():
        a = after.get(key)
        if a is None:
            continue
        for reg, share in b.shares.items():
            drop = share * b.energy - a.shares.get(reg, 0.0) * a.energy
            if best is None or drop > best[0]:
                best = (drop, key, reg, share, a.shares.get(reg, 0.0))
    drops = sorted(((b.energy - after[k].energy, k) for k, b in before.items() if k in after), reverse=True)
    removed = 100.0 * (null.cost - entry.cost) / null.cost if null.cost > 0 else 0.0
    parts = [f"{_fmt_params(entry.effect, entry.params)}"]
    if removed <= 0:
        parts.append(f"does not help: the fit's residual energy rises by {-removed:.0f} % over the recalibrated "
                     "baseline's, even at the smallest realistic value")
        return "; ".join(parts)
    parts.append(f"removes {removed:.0f} % of the recalibrated baseline's residual energy")
    if best is not None and best[0] > 0.02 * total:
        _, key, reg, sb, sa = best
        parts.append(f"the {key} residual tracked {reg} ({100 * sb:.0f} % of its energy) and no longer does "
                     f"({100 * sa:.0f} %)" if sa < 0.5 * sb else
                     f"it removes most of the {key} residual that tracked {reg} ({100 * sb:.0f} % of its energy)")
    for _, key in drops[:2]:
        b, a = before[key], after[key]
        if b.energy > 0 and (b.energy - a.energy) > 0.05 * total:
            parts.append(f"{key} residual {b.rms:.3g} -> {a.rms:.3g} {UNITS[b.signal]} RMS "
                         f"({b.ratio:.1f} -> {a.ratio:.1f} times its sensor noise, RMS)")
    if not entry.beats_noise:
        parts.append("too little to beat noise")
    return "; ".join(parts)


# --- what the remaining residual follows ------------------------------------------------------

#: the physical quantities a residual is regressed on (names of the diagnosis JSON)
QUANTITY_DOC = {
    "theta": "crank angle", "omega": "crank rate", "sign_omega": "sign of the crank rate",
    "alpha": "crank acceleration", "p_a": "chamber A pressure", "p_b": "chamber B pressure",
    "p_load": "load pressure P_A - P_B", "p_s": "supply pressure", "current": "valve current",
    "sign_current": "sign of the valve current (spool direction)", "abs_flow": "|flow| (valve opening)",
    "current_lag_5ms": "the current 5 ms earlier", "current_rate": "rate of the current",
    "abs_current": "|current|", "constant": "a constant", "time": "time since the run's start",
}
FOLLOW_MIN_SHARE = 0.02  # a quantity is listed when it explains at least this share of the residual energy
FOLLOW_MAX_TERMS = 5


def quantities(case, sim: dict) -> dict[str, np.ndarray]:
    """The physical quantities of one run at its samples (model's noise-free states; measured supply)."""
    run = case.run
    dt = run.dt
    t = np.arange(run.n) * dt
    if run.kind == "valve_open_loop":
        i = run.columns["current_mA"]
        return {"current": i, "sign_current": np.sign(i), "abs_current": np.abs(i),
                "current_rate": np.gradient(i, dt), "constant": np.ones_like(i), "time": t}
    w = np.radians(sim["omega_deg_s"])
    wmax = max(float(np.max(np.abs(w))), 1e-9)
    i = sim["current_mA"]
    k = int(round(5e-3 / dt))
    q = {
        "theta": np.radians(sim["theta_deg"]), "omega": w, "sign_omega": np.tanh(w / (0.01 * wmax)),
        "alpha": np.gradient(w, dt), "p_a": sim["p_a_bar"], "p_b": sim["p_b_bar"],
        "p_load": sim["p_a_bar"] - sim["p_b_bar"],
        "p_s": run.columns["p_s_bar"] if "p_s_bar" in run.columns else sim["p_s_bar"],
        "current": i, "sign_current": np.sign(i), "abs_flow": np.abs(sim["flow_lpm"]),
        "current_lag_5ms": np.r_[np.full(k, i[0]), i[:-k]] if 0 < k < i.size else i,
        "constant": np.ones_like(i), "time": t,
    }
    return q


def _forward_selection(e: np.ndarray, X: dict[str, np.ndarray], max_terms: int) -> list[tuple[str, float]]:
    """Greedy least squares: the quantity that removes most residual energy first, then the next given it.

    Shares are of the residual's energy (sum of squares, noise included).
    """
    total = float(np.dot(e, e))
    if total <= 0.0:
        return []
    names = [n for n, x in X.items() if np.ptp(x) > 0 or n == "constant"]
    cols = {n: X[n] / max(float(np.sqrt(np.mean(X[n] ** 2))), 1e-300) for n in names}
    chosen: list[str] = []
    out = []
    left = total
    for _ in range(max_terms):
        best = None
        for n in names:
            if n in chosen:
                continue
            A = np.column_stack([cols[m] for m in chosen + [n]])
            coef, *_ = np.linalg.lstsq(A, e, rcond=None)
            r = e - A @ coef
            ss = float(np.dot(r, r))
            if best is None or ss < best[1]:
                best = (n, ss)
        if best is None:
            break
        gain = left - best[1]
        if gain < FOLLOW_MIN_SHARE * total:
            break
        chosen.append(best[0])
        out.append((best[0], gain / total))
        left = best[1]
    return out


def follows(rep: Replayer, sims, runs=None) -> dict:
    """What the residual of each signal follows, and overall, strongest first.

    Per signal, the closed-loop runs are pooled (one coefficient per quantity for
    every run: a spring and an inertia error, which are both in phase with the
    angle in any one sine run, part across runs of different frequency) and the
    residual, in units of each run's noise level, is regressed on the
    quantities of :func:`quantities` by forward selection.

    Returns
    -------
    dict
        ``signals``: {signal: {"x_noise": residual RMS / noise, "follows": [[quantity, share], ...]}};
        ``follows``: the quantities over all signals, strongest first, each with its share of the
        residual energy above noise ({quantity: share}).
    """
    pools: dict[str, tuple[list, dict]] = {}
    for idx, (case, sim) in enumerate(zip(rep.cases, sims)):
        if sim is None or (runs is not None and idx not in runs):
            continue
        q = quantities(case, sim)
        k = case.skip
        for s in case.signals:
            key = s if case.run.kind == "closed_loop" else f"{s} (valve)"
            es, qs = pools.setdefault(key, ([], {}))
            es.append((case.measured[s][k:] - sim[s][k:]) / case.noise[s])
            for n, x in q.items():
                if n == "p_s" and s == "p_s_bar":
                    continue
                qs.setdefault(n, []).append(x[k:])
    per_signal = {}
    overall: dict[str, float] = {}
    for key, (es, qs) in pools.items():
        e = np.concatenate(es)
        X = {n: np.concatenate(v) for n, v in qs.items() if len(v) == len(es)}
        ms = float(np.mean(e**2))
        sel = _forward_selection(e, X, FOLLOW_MAX_TERMS)
        per_signal[key] = {"x_noise": round(math.sqrt(ms), 3), "follows": [[n, round(v, 3)] for n, v in sel]}
        excess = max(float(np.sum(e**2)) - e.size, 0.0)
        for n, v in sel:
            overall[n] = overall.get(n, 0.0) + excess * v
    tot = sum(overall.values())
    ranked = sorted(overall.items(), key=lambda kv: kv[1], reverse=True)
    return {"signals": per_signal, "follows": {n: round(v / tot, 3) for n, v in ranked} if tot > 0 else {}}


def follows_text(fol: dict, title: str) -> str:
    """Plain-text table of :func:`follows`."""
    lines = [f"what the residual of the {title} follows (share of each signal's residual energy, noise included)"]
    for key, d in sorted(fol["signals"].items(), key=lambda kv: kv[1]["x_noise"], reverse=True):
        tops = ", ".join(f"{n} {100 * v:.0f}%" for n, v in d["follows"]) or "nothing beyond noise"
        lines.append(f"  {key:<18}RMS {d['x_noise']:>5.2f}x its sensor noise  {tops}")
    if fol["follows"]:
        lines.append("  overall, strongest first: " + ", ".join(f"{n} ({100 * v:.0f} %)" for n, v in fol["follows"].items()))
    return "\n".join(lines)
