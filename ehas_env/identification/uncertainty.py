"""Parameter covariance and 95 % intervals of a fitted transfer function (MATLAB's ``getcov`` / ``present``).

The output-error estimate minimises ``sum e_k^2`` with ``e = y - yhat(theta)``.
At the optimum, the sensitivity ``psi_k = d yhat_k / d theta`` (central
differences of the exact simulation; the initial state's columns are its free
responses) gives, by the usual first-order (delta-method) argument
(Ljung 1999, sec. 9.3):

* white residuals: ``Cov theta = sigma^2 (Psi^T Psi)^-1`` with
  ``sigma^2 = e^T e / (N - p)``;
* coloured residuals (an output-error model does not model the noise, so a
  coloured disturbance is legitimate but makes the white formula too
  optimistic): ``Cov theta = (Psi^T Psi)^-1 Q (Psi^T Psi)^-1`` with
  ``Q = sum_|tau|<=L w_tau R_e(tau) sum_k psi_k psi_(k-tau)^T``, ``R_e`` the
  residual autocovariance and ``w`` a Bartlett window over L lags, L five
  times the lag at which the residual autocorrelation first falls inside the
  white band (Ljung 1999, eq. 9.54; the "effective sample size" correction
  done properly).

``method="auto"`` (default) uses the coloured form when the residuals fail
the whiteness test of :func:`ehas_env.identification.fit.residual_analysis`
(99 % band, 25 lags).

K, wn and zeta (and the DC gain of any model) get their intervals from the
coefficients' covariance by the delta method: ``var g = grad g^T Cov grad g``.
Intervals are ``value +- 1.96 se`` (normal; N - p is in the thousands).

Examples
--------
>>> import control
>>> from ehas_env.identification.fit import simulate_tf, tfest
>>> rng = np.random.default_rng(0)
>>> t = np.arange(3000) * 1e-3
>>> u = np.sign(np.sin(2 * np.pi * 2.0 * t))
>>> y = simulate_tf(control.tf([2.0 * 80.0**2], [1.0, 80.0, 80.0**2]), t, u) + 0.05 * rng.normal(size=t.size)
>>> unc = covariance(tfest(t, u, y, 2, 0))
>>> lo, hi = unc.ci95["K"]
>>> bool(lo < 2.0 < hi), unc.method
(True, 'white')
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: two-sided 95 % point of the standard normal distribution
Z95 = 1.959963984540054
COLOURED = ("auto", "white", "coloured")


@dataclass
class Uncertainty:
    """Covariance of the estimated parameters and 95 % intervals.

    Attributes
    ----------
    names : list of str
        Parameter names: ``a{k}`` the denominator's coefficient of s^k (monic,
        the leading one is not estimated), ``b{k}`` the numerator's,
        ``delay_s``, ``input_offset``, ``output_offset``, ``x0[i]``.
    values : ndarray
        Their estimates.
    cov : ndarray
        Their covariance.
    derived : dict
        ``K`` (DC gain) and for 2-pole models ``wn``, ``zeta``: name -> (value, standard error).
    noise_std : float
        Residual standard deviation (N - p degrees of freedom).
    method : str
        ``white`` or ``coloured`` (which covariance formula was used).
    lags : int
        Lags of the coloured formula's window (0 for ``white``).
    n, p : int
        Samples and parameters.
    """

    names: list
    values: np.ndarray
    cov: np.ndarray
    derived: dict
    noise_std: float
    method: str
    lags: int
    n: int
    p: int
    z: float = Z95
    _ci: dict = field(default=None, repr=False)
    units: dict = field(default_factory=dict)  # name -> unit, for the printed intervals

    @property
    def se(self) -> np.ndarray:
        """Standard errors of :attr:`values`."""
        return np.sqrt(np.maximum(np.diag(self.cov), 0.0))

    @property
    def ci95(self) -> dict:
        """name -> [lo, hi]: the derived quantities first (K, wn, zeta), then every parameter except x0."""
        out = {k: [v - self.z * s, v + self.z * s] for k, (v, s) in self.derived.items()}
        for name, v, s in zip(self.names, self.values, self.se):
            if not name.startswith("x0"):
                lo = float(v - self.z * s)
                out[name] = [max(lo, 0.0) if name == "delay_s" else lo, float(v + self.z * s)]  # a delay is >= 0
        return {k: [float(a), float(b)] for k, (a, b) in out.items()}

    def interval(self, name: str) -> tuple[float, float]:
        """The 95 % interval of one parameter or derived quantity."""
        lo, hi = self.ci95[name]
        return lo, hi

    def correlation(self) -> np.ndarray:
        s = self.se
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.cov / np.outer(s, s)

    def to_json_dict(self) -> dict:
        """``{"names", "values", "matrix", "noise_std", "method", "lags"}`` (JSON-ready)."""
        return {"names": list(self.names), "values": [float(v) for v in self.values],
                "matrix": [[float(v) for v in row] for row in self.cov], "noise_std": float(self.noise_std),
                "method": self.method, "lags": int(self.lags), "samples": int(self.n), "parameters": int(self.p)}

    def summary(self) -> str:
        """Lines ``name = value +- half-width (95 %)``."""
        lines = [f"  95 % intervals ({self.method} residuals"
                 + (f", {self.lags}-lag window" if self.method == "coloured" else "") + "):"]
        rows = [(k, v, s) for k, (v, s) in self.derived.items()]
        rows += [(k, v, s) for k, v, s in zip(self.names, self.values, self.se) if not k.startswith("x0")]
        for k, v, s in rows:
            rel = f" ({100 * self.z * s / abs(v):.2g} %)" if v else ""
            unit = f" {self.units[k]}" if self.units.get(k) else ""
            lines.append(f"    {k:>14s} = {v:.6g} +- {self.z * s:.3g}{unit}{rel}")
        return "\n".join(lines)


def parameter_names(n: int, m: int, estimated=()) -> list[str]:
    """Names of the parameter vector of :func:`covariance`.

    >>> parameter_names(2, 0, ("delay", "input_offset", "output_offset"))
    ['a1', 'a0', 'b0', 'delay_s', 'input_offset', 'output_offset']
    """
    names = [f"a{k}" for k in range(n - 1, -1, -1)] + [f"b{k}" for k in range(m, -1, -1)]
    if "delay" in estimated:
        names.append("delay_s")
    if "input_offset" in estimated:
        names.append("input_offset")
    if "output_offset" in estimated:
        names.append("output_offset")
    if "x0" in estimated:
        names += [f"x0[{i}]" for i in range(n)]
    return names


def _output(est, den_tail, num, delay_s, u0, y0) -> np.ndarray:
    """The model's output on the estimate's record for these parameters (its initial state as estimated)."""
    from ehas_env.identification.fit import _delayed_states, companion

    d = est.data
    A, B, C, D = companion(np.asarray(num, float), np.r_[1.0, den_tail])
    x0 = est.x0 if "x0" in est.estimated else None
    X, ud = _delayed_states(A, B, d.dt, d.u - u0, est.intersample, delay_s / d.dt, x0)
    return X @ C + D * ud + y0


def sensitivity(est) -> np.ndarray:
    """d yhat / d theta at the estimate (N x p), theta as named by :func:`parameter_names`."""
    from ehas_env.identification.fit import _free_responses, companion

    n, m = est.n_poles, est.n_zeros
    den_tail = np.asarray(est.den[1:], float)
    num = np.asarray(est.num[-(m + 1):], float)
    d = est.data
    base = dict(den_tail=den_tail, num=num, delay_s=est.delay_s, u0=est.input_offset, y0=est.output_offset)
    cols = []

    def central(key, idx, step):
        lo, hi = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in base.items()}, \
            {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in base.items()}
        if idx is None:
            lo[key] -= step
            hi[key] += step
        else:
            lo[key][idx] -= step
            hi[key][idx] += step
        return (_output(est, **hi) - _output(est, **lo)) / (2.0 * step)

    for i in range(n):
        cols.append(central("den_tail", i, 1e-6 * max(abs(den_tail[i]), 1e-8 * np.abs(den_tail).max(), 1e-300)))
    for i in range(m + 1):
        cols.append(central("num", i, 1e-6 * max(abs(num[i]), 1e-8 * np.abs(num).max(), 1e-300)))
    if "delay" in est.estimated:
        step = 1e-3 * d.dt
        if est.delay_s < step:  # one-sided at the bound 0
            cols.append((_output(est, **{**base, "delay_s": est.delay_s + step}) - _output(est, **base)) / step)
        else:
            cols.append(central("delay_s", None, step))
    if "input_offset" in est.estimated:
        cols.append(central("u0", None, 1e-6 * max(abs(est.input_offset), float(np.std(d.u)))))
    if "output_offset" in est.estimated:
        cols.append(np.ones(d.n))
    if "x0" in est.estimated:
        A, _, C, _ = companion(est.num, est.den)
        O = _free_responses(A, C, d.dt, d.n)
        cols += list(O.T)
    return np.column_stack(cols)


def _inverse(J: np.ndarray) -> np.ndarray:
    """(J^T J)^-1 with the columns scaled to unit norm first (pseudo-inverse of rank-deficient parts)."""
    s = np.linalg.norm(J, axis=0)
    s[s == 0] = 1.0
    Js = J / s
    return np.linalg.pinv(Js.T @ Js, rcond=1e-13) / np.outer(s, s)


def _coloured_lags(e: np.ndarray) -> int:
    from ehas_env.identification.fit import _xcorr

    N = e.size
    M = min(N // 10, 2000)
    r = _xcorr(e, e, M)[M:]
    rho = r / r[0]
    band = Z95 / math.sqrt(N)
    inside = np.flatnonzero(np.abs(rho[1:]) < band)
    first = int(inside[0]) + 1 if inside.size else M
    return int(min(max(10, 5 * first), N // 10))


def covariance(est, coloured: str = "auto") -> Uncertainty:
    """Covariance of an output-error estimate's parameters and the 95 % intervals of them and of K, wn, zeta.

    Parameters
    ----------
    est : TFEstimate
        A fit of :func:`ehas_env.identification.fit.tfest`.
    coloured : {"auto", "white", "coloured"}
        Which covariance formula: ``auto`` picks ``coloured`` when the residuals
        fail the 99 % whiteness test.

    Returns
    -------
    Uncertainty
    """
    if coloured not in COLOURED:
        raise ValueError(f"coloured must be one of {', '.join(COLOURED)}, got {coloured!r}")
    from ehas_env.identification.fit import residual_analysis

    n, m = est.n_poles, est.n_zeros
    e = np.asarray(est.residuals, float)
    N = e.size
    names = parameter_names(n, m, est.estimated)
    values = np.r_[np.asarray(est.den[1:], float), np.asarray(est.num[-(m + 1):], float)]
    if "delay" in est.estimated:
        values = np.r_[values, est.delay_s]
    if "input_offset" in est.estimated:
        values = np.r_[values, est.input_offset]
    if "output_offset" in est.estimated:
        values = np.r_[values, est.output_offset]
    if "x0" in est.estimated:
        values = np.r_[values, est.x0]
    J = sensitivity(est)
    p = J.shape[1]
    sigma2 = float(e @ e) / max(N - p, 1)
    Pinv = _inverse(J)
    method = coloured
    if coloured == "auto":
        ra = residual_analysis(e, est.data.u, max_lag=min(25, N - 1))
        white = ra.auto_outside() <= max(1, round(0.01 * ra.lags.size))
        method = "white" if white else "coloured"
    L = 0
    if method == "white":
        cov = sigma2 * Pinv
    else:
        L = _coloured_lags(e)
        Q = float(e @ e) / N * (J.T @ J)
        for tau in range(1, L + 1):
            w = 1.0 - tau / (L + 1.0)
            re = float(e[tau:] @ e[:-tau]) / N
            S = J[tau:].T @ J[:-tau]
            Q += w * re * (S + S.T)
        cov = Pinv @ Q @ Pinv
        cov = 0.5 * (cov + cov.T)
    derived = _derived(est, cov)
    return Uncertainty(names=names, values=values, cov=cov, derived=derived, noise_std=math.sqrt(sigma2),
                       method=method, lags=L, n=N, p=p, units=parameter_units(est, names))


def parameter_units(est, names) -> dict:
    """name -> unit of each parameter and derived quantity of an estimate (the signals' units from their names).

    ``a{k}`` multiplies s^k in a monic denominator of degree n: 1/s^(n-k); ``b{k}`` the same, times the
    gain's unit (output per input); K is output per input, wn rad/s, zeta none.

    Parameters
    ----------
    est : TFEstimate
        The estimate (its data's input and output names carry the units).
    names : list of str
        Parameter names (:func:`parameter_names`).

    Returns
    -------
    dict
        name -> unit text ("" for a number without unit).
    """
    from ehas_env.identification.fit import signal_unit

    u_in, u_out = signal_unit(est.data.input_name), signal_unit(est.data.output_name)
    gain = f"{u_out}/{u_in}"
    n = est.n_poles

    def per_s(k):
        return "" if k == 0 else "1/s" if k == 1 else f"1/s^{k}"

    out = {"K": gain, "wn": "rad/s", "zeta": "", "delay_s": "s", "input_offset": u_in, "output_offset": u_out}
    for name in names:
        if name[:1] in "ab" and name[1:].isdigit():
            k = n - int(name[1:])
            s_k = "s" if k == 1 else f"s^{k}"
            out[name] = per_s(k) if name[0] == "a" else (f"{u_out}/({u_in} {s_k})" if k else gain)
    return out


def _derived(est, cov: np.ndarray) -> dict:
    """K (DC gain) and, for 2 poles, wn and zeta with their standard errors (delta method)."""
    n, m = est.n_poles, est.n_zeros
    den, num = np.asarray(est.den, float), np.asarray(est.num[-(m + 1):], float)
    a0, b0 = den[-1], num[-1]
    i_a0, i_b0 = n - 1, n + m  # positions in theta
    out = {}
    if n == 0 or a0 == 0:
        return out
    g = np.zeros(cov.shape[0])
    g[i_b0] = 1.0 / a0
    g[i_a0] = -b0 / a0**2
    out["K"] = (float(b0 / a0), float(math.sqrt(max(g @ cov @ g, 0.0))))
    if n == 2 and a0 > 0:
        a1 = den[1]
        wn = math.sqrt(a0)
        g = np.zeros(cov.shape[0])
        g[1] = 0.5 / wn
        out["wn"] = (wn, float(math.sqrt(max(g @ cov @ g, 0.0))))
        g = np.zeros(cov.shape[0])
        g[0] = 0.5 / wn
        g[1] = -a1 / (4.0 * a0**1.5)
        out["zeta"] = (float(a1 / (2.0 * wn)), float(math.sqrt(max(g @ cov @ g, 0.0))))
    return out
