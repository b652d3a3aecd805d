"""Discrete-time black-box models: ARX, ARMAX, OE, BJ by the prediction-error method, and N4SID state space.

The polynomial family is MATLAB's ``idpoly``, in the delay operator q^-1::

    A(q) y(t) = B(q) / F(q) u(t - nk) + C(q) / D(q) e(t)

with ``A = 1 + a1 q^-1 + ... + a_na q^-na`` (C, D, F alike, monic) and
``B = b1 + b2 q^-1 + ... + b_nb q^-(nb-1)``; e is white.  The structures are
its special cases (orders as MATLAB's order vectors):

=========  ====================  ==========================================  ====================
structure  orders                model                                       noise model H
=========  ====================  ==========================================  ====================
``arx``    na, nb, nk            A y = B u(t-nk) + e                         1 / A
``armax``  na, nb, nc, nk        A y = B u(t-nk) + C e                       C / A
``oe``     nb, nf, nk            y = B / F u(t-nk) + e                       1
``bj``     nb, nc, nd, nf, nk    y = B / F u(t-nk) + C / D e                 C / D
``ss``     nx                    x+ = A x + B u + K e,  y = C x + e          C (zI - A)^-1 K + 1
=========  ====================  ==========================================  ====================

How each is estimated (:func:`estimate`):

* **ARX**: linear least squares (:func:`ehas_env.identification.arx.arx`);
* **ARMAX, OE, BJ**: the prediction-error method - the sum of squared one-step
  prediction errors ``e = D / C (A y - B / F u)`` minimised by
  ``scipy.optimize.least_squares`` (trust-region reflective), every filter
  started from rest and the first ``max order + nk`` errors left out of the
  criterion.  Starting values: ARMAX from Hannan-Rissanen (a long ARX gives
  the innovations, one least-squares fit on them gives A, B, C); OE from
  the instrumental-variable method (instruments simulated by an ARX model,
  two refinements, IV4-like); BJ from the OE estimate plus an ARMA(nd, nc)
  fit of its residuals (Hannan-Rissanen).  Unstable roots of C and F in a
  start are reflected into the unit circle; an iterate with C or F unstable
  is refused by a penalty (the predictor would diverge);
* **ss**: N4SID subspace identification by the package ``nfoursid``
  (optional: ``pip install 'ehas[ident]'``; it gives A and C from the
  subspace and the noise covariances), then B by linear least squares of the
  simulation error given A and C (D = 0: a sampled plant has no
  feedthrough), and the Kalman predictor gain K from the covariances (a
  Riccati equation).

Why ``nfoursid`` (evaluated beside ``sysidentpy`` and ``harold``; the
measurements are in results/identification/structures.md): on a simulated
second-order system with 0.3 white output noise (4000 samples) ``nfoursid``
found the poles 0.7499 +- 0.3706j (truth 0.75 +- 0.3708j) and a simulation
fit of 99.75 % against the noise-free output, in 0.9 s; it is MIT-licensed,
pure Python over numpy and pandas (both already installed wherever ``ray``
is).  ``sysidentpy`` (BSD) is a NARMAX toolkit: its linear FROLS fit is an
equation-error (ARX-like) least squares, biased by the same output noise
(a1, a2 = -1.434, 0.636 against -1.5, 0.7; simulation fit 89.3 %), and it has
no subspace method.  ``harold`` (MIT) has no identification at all.

Every estimate gives a discrete-time python-control model (``.tf()``, and for
``ss`` also ``.ss()``, sample time ``dt``), its simulation fit % on the data
(NRMSE from rest, as MATLAB's ``compare``), its one-step prediction errors
(``.residuals``, for the residual tests) and, for the polynomial structures,
standard errors of the coefficients (``sigma^2 (J'J)^-1`` at the optimum,
J the Jacobian of the prediction errors).

Examples
--------
>>> from scipy.signal import lfilter
>>> rng = np.random.default_rng(0)
>>> u = np.sign(rng.normal(size=3000))
>>> e = 0.1 * rng.normal(size=3000)
>>> y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1, 0.5], [1, -1.5, 0.7], e)
>>> m = estimate("armax", u, y, {"na": 2, "nb": 2, "nc": 1, "nk": 1})
>>> np.round(m.A, 2).tolist(), np.round(m.B, 2).tolist(), np.round(m.C, 1).tolist()
([1.0, -1.5, 0.7], [1.0, 0.5], [1.0, 0.5])
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ehas_env.simulation.metrics import fit_percent


def lfilter(b, a, x):
    """``scipy.signal.lfilter``, imported on first use: every command's parser imports this module (through
    ``ehas identify``'s choices), and scipy.signal costs 1.5 s to import."""
    from scipy.signal import lfilter as _lfilter

    return _lfilter(b, a, x)

#: the black-box structures and their orders, in MATLAB's order-vector order
ORDERS = {"arx": ("na", "nb", "nk"), "armax": ("na", "nb", "nc", "nk"), "oe": ("nb", "nf", "nk"),
          "bj": ("nb", "nc", "nd", "nf", "nk"), "ss": ("nx",)}
STRUCTURES = tuple(ORDERS)
#: allowed range of each order (nb >= 1: a model with no input is not an input-output model)
ORDER_RANGE = {"na": (0, 20), "nb": (1, 20), "nc": (0, 20), "nd": (0, 20), "nf": (0, 20), "nk": (0, 50),
               "nx": (1, 20)}
#: default orders (a sampled second-order plant: two poles, B of two terms after one sample of delay)
DEFAULT_ORDERS = {"na": 2, "nb": 2, "nc": 2, "nd": 2, "nf": 2, "nk": 1, "nx": 2}
#: fewest samples per estimated parameter
SAMPLES_PER_PARAMETER = 10


def check_orders(structure: str, orders: dict, where: str = "") -> dict:
    """The orders of ``structure`` (defaults filled in), each checked; a one-line ValueError otherwise.

    Parameters
    ----------
    structure : str
        One of :data:`STRUCTURES`.
    orders : dict
        ``{"na": 2, ...}``; names the structure does not have are refused.
    where : str
        Prefix of the option names in errors (``"--"`` on the command line).

    Returns
    -------
    dict
        The structure's orders, in MATLAB's order.

    Examples
    --------
    >>> check_orders("oe", {"nf": 3})
    {'nb': 2, 'nf': 3, 'nk': 1}
    """
    if structure not in ORDERS:
        raise ValueError(f"structure must be one of {', '.join(STRUCTURES)}, got {structure!r}")
    names = ORDERS[structure]
    out = {}
    for key, value in orders.items():
        if key not in names:
            raise ValueError(f"{where}{key} does not belong to structure {structure} (its orders: "
                             f"{', '.join(where + n for n in names)})")
    for name in names:
        v = orders.get(name, DEFAULT_ORDERS[name])
        lo, hi = ORDER_RANGE[name]
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
            raise ValueError(f"{where}{name} must be an integer in [{lo}, {hi}], got {v!r}")
        out[name] = int(v)
    return out


def _stabilise(p: np.ndarray) -> np.ndarray:
    """The monic polynomial (in q^-1) with its roots outside the unit circle reflected inside."""
    p = np.asarray(p, float)
    if p.size <= 1:
        return p
    r = np.roots(p)
    bad = np.abs(r) >= 1.0
    if not bad.any():
        return p
    r[bad] = 1.0 / np.conj(r[bad])
    r[np.abs(r) >= 1.0] *= 0.98
    return np.real(np.poly(r))


def _stable(p: np.ndarray) -> bool:
    return p.size <= 1 or bool(np.all(np.abs(np.roots(p)) < 1.0))


def _lags(x: np.ndarray, lags, k0: int) -> np.ndarray:
    """Columns x(t - l) for l in lags, rows t = k0..N-1 (x before 0 taken as 0)."""
    N = x.size
    cols = []
    for lag in lags:
        c = np.zeros(N - k0)
        lo = max(k0, lag)
        c[lo - k0:] = x[lo - lag: N - lag]
        cols.append(c)
    return np.column_stack(cols) if cols else np.zeros((N - k0, 0))


# ---------------------------------------------------------------------------
# polynomial models
# ---------------------------------------------------------------------------

@dataclass
class PolyEstimate:
    """A fitted ARX, ARMAX, OE or BJ model (see the module docstring).

    Attributes
    ----------
    structure : str
        ``arx``, ``armax``, ``oe`` or ``bj``.
    orders : dict
        The orders (na, nb, nc, nd, nf, nk as the structure has them).
    A, B, C, D, F : ndarray
        The polynomials in q^-1 (A, C, D, F monic, ``[1.0]`` where the structure has none).
    dt : float
        Sample period, s.
    names : list of str
        Parameter names (``a1, ..., b1, ..., c1, ..., d1, ..., f1, ...``).
    theta, std : ndarray
        Estimated parameters and their standard errors.
    noise_variance : float
        Variance of the one-step prediction errors (the innovations).
    residuals : ndarray
        One-step prediction errors on the estimation data (filters from rest).
    y_sim : ndarray
        Simulated (noise-free) output on the estimation data, from rest.
    fit_percent : float
        Simulation fit on the estimation data (NRMSE %, MATLAB ``compare``).
    """

    structure: str
    orders: dict
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    F: np.ndarray
    dt: float
    names: list
    theta: np.ndarray
    std: np.ndarray
    noise_variance: float
    residuals: np.ndarray = field(repr=False)
    y_sim: np.ndarray = field(repr=False)
    fit_percent: float = math.nan
    cov: np.ndarray = field(repr=False, default=None)

    @property
    def nk(self) -> int:
        return self.orders["nk"]

    @property
    def n_parameters(self) -> int:
        return int(self.theta.size)

    @property
    def label(self) -> str:
        return f"{self.structure.upper()} [{' '.join(str(v) for v in self.orders.values())}]"

    def _b(self) -> np.ndarray:
        return np.r_[np.zeros(self.nk), self.B]

    def simulate(self, u) -> np.ndarray:
        """Noise-free output ``B / (A F) u(t - nk)`` from rest."""
        return lfilter(self._b(), np.convolve(self.A, self.F), np.asarray(u, float))

    def innovations(self, u, y) -> np.ndarray:
        """One-step prediction errors ``D / C (A y - B / F u)`` (filters from rest)."""
        return _prediction_errors(self.A, self._b(), self.C, self.D, self.F, np.asarray(u, float),
                                  np.asarray(y, float))

    def noise_impulse(self, k: int) -> np.ndarray:
        """The first k terms of the noise model's impulse response ``h = C / (A D)`` (h0 = 1)."""
        imp = np.zeros(k)
        imp[0] = 1.0
        return lfilter(self.C, np.convolve(self.A, self.D), imp)

    def predict(self, u, y, k: int = 1) -> np.ndarray:
        """k-step-ahead prediction ``yhat(t | t-k) = y(t) - sum_{i<k} h_i e(t-i)`` (e the innovations)."""
        y = np.asarray(y, float)
        return y - lfilter(self.noise_impulse(int(k)), [1.0], self.innovations(u, y))

    def poles(self) -> np.ndarray:
        """The plant's poles, the roots of ``A F`` in z (those a transfer function of a zero B would cancel too)."""
        return np.roots(np.convolve(self.A, self.F))

    def tf(self):
        """``B / (A F)`` with the input delay, as a discrete-time ``control.TransferFunction`` (sample time dt)."""
        return _tf_q(self._b(), np.convolve(self.A, self.F), self.dt)

    def noise_tf(self):
        """The noise model ``C / (A D)`` as a discrete-time ``control.TransferFunction``."""
        return _tf_q(self.C, np.convolve(self.A, self.D), self.dt)

    def coefficients(self) -> dict:
        """``{"A": [...], "B": [...], ...}``: the polynomials the structure has, in q^-1."""
        have = {"arx": "AB", "armax": "ABC", "oe": "BF", "bj": "BCDF"}[self.structure]
        return {p: [float(v) for v in getattr(self, p)] for p in have}

    def to_json_dict(self) -> dict:
        return {"structure": self.structure, "orders": dict(self.orders), "dt": self.dt,
                "polynomials": self.coefficients(), "variable": "q^-1",
                "parameters": {n: {"value": float(v), "std": float(s)} for n, v, s in
                               zip(self.names, self.theta, self.std)},
                "noise_variance": float(self.noise_variance), "fit_percent": float(self.fit_percent)}

    def summary(self) -> str:
        lines = [f"{self.label} (discrete time, dt = {self.dt:g} s, polynomials in q^-1):"]
        for p, c in self.coefficients().items():
            lines.append(f"  {p} = {', '.join(f'{v:.6g}' for v in c)}")
        lines.append("  parameters +- standard error: " + ", ".join(
            f"{n} = {v:.5g} +- {s:.2g}" for n, v, s in zip(self.names, self.theta, self.std)))
        lines.append(f"  fit = {self.fit_percent:.2f} % (simulation from rest, NRMSE); innovation variance "
                     f"{self.noise_variance:.4g}")
        return "\n".join(lines)


def _tf_q(b: np.ndarray, a: np.ndarray, dt: float):
    """``b(q^-1) / a(q^-1)`` as a transfer function in z."""
    import control

    n = max(b.size, a.size)
    return control.tf(np.r_[b, np.zeros(n - b.size)], np.r_[a, np.zeros(n - a.size)], dt)


def _prediction_errors(A, b, C, D, F, u, y) -> np.ndarray:
    w = lfilter(b, F, u)
    v = lfilter(A, [1.0], y) - w
    return lfilter(D, C, v)


def _split(theta, o: dict):
    """theta -> A, B, C, D, F (monic ones with their leading 1)."""
    i = 0
    out = {}
    for name, poly in (("na", "A"), ("nb", "B"), ("nc", "C"), ("nd", "D"), ("nf", "F")):
        n = o.get(name, 0)
        part = theta[i: i + n]
        i += n
        out[poly] = part.copy() if poly == "B" else np.r_[1.0, part]
    return out["A"], out["B"], out["C"], out["D"], out["F"]


def _names(o: dict) -> list:
    return [f"{p}{i}" for key, p in (("na", "a"), ("nb", "b"), ("nc", "c"), ("nd", "d"), ("nf", "f"))
            for i in range(1, o.get(key, 0) + 1)]


def _hannan_rissanen(v: np.ndarray, u, na: int, nb: int, nc: int, nk: int, long_order: int):
    """A, B, C of ``A v = B u(t-nk) + C e`` (u None: ARMA) from a long ARX model's innovations."""
    N = v.size
    lags_u = [nk + j for j in range(nb)] if u is not None else []
    # 1. the long model: its residuals estimate the innovations
    k0 = max(long_order, (max(lags_u) if lags_u else 0))
    X = np.column_stack([-_lags(v, range(1, long_order + 1), k0)] +
                        ([_lags(u, range(nk, nk + long_order), k0)] if u is not None else []))
    th, *_ = np.linalg.lstsq(X, v[k0:], rcond=None)
    ehat = np.zeros(N)
    ehat[k0:] = v[k0:] - X @ th
    # 2. one regression on the estimated innovations
    k1 = k0 + max(na, nc, max(lags_u) if lags_u else 0)
    X = np.column_stack([-_lags(v, range(1, na + 1), k1), _lags(u, lags_u, k1) if u is not None else
                         np.zeros((N - k1, 0)), _lags(ehat, range(1, nc + 1), k1)])
    th, *_ = np.linalg.lstsq(X, v[k1:], rcond=None)
    return np.r_[1.0, th[:na]], th[na: na + len(lags_u)], _stabilise(np.r_[1.0, th[na + len(lags_u):]])


def _iv_oe(u, y, nb: int, nf: int, nk: int, iterations: int = 3):
    """B, F of an output-error model by instrumental variables (instruments: an ARX model's simulation)."""
    from ehas_env.identification.arx import arx

    N = y.size
    lags_u = [nk + j for j in range(nb)]
    k0 = max(nf, max(lags_u))
    m = arx(u, y, nf, nb, nk)
    F, B = _stabilise(m.den), m.num
    phi = np.column_stack([-_lags(y, range(1, nf + 1), k0), _lags(u, lags_u, k0)])
    for _ in range(iterations):
        x = lfilter(np.r_[np.zeros(nk), B], F, u)
        Z = np.column_stack([-_lags(x, range(1, nf + 1), k0), _lags(u, lags_u, k0)])
        th = np.linalg.lstsq(Z.T @ phi, Z.T @ y[k0:], rcond=None)[0]
        F, B = _stabilise(np.r_[1.0, th[:nf]]), th[nf:]
    return B, F


def _pem(u, y, o: dict, theta0: np.ndarray, structure: str, dt: float, max_nfev: int) -> PolyEstimate:
    from scipy.optimize import least_squares

    N = y.size
    nk = o["nk"]
    k0 = min(N // 4, max(o.get("na", 0), o.get("nb", 0) + nk, o.get("nc", 0), o.get("nd", 0), o.get("nf", 0)) + nk)
    scale = float(np.std(y)) or 1.0
    penalty = np.full(N - k0, 1e3 * scale)

    def residual(theta):
        A, B, C, D, F = _split(theta, o)
        if not (_stable(C) and _stable(F)):
            return penalty
        e = _prediction_errors(A, np.r_[np.zeros(nk), B], C, D, F, u, y)[k0:]
        if not np.all(np.isfinite(e)):
            return penalty
        return e

    res = least_squares(residual, theta0, method="trf", x_scale="jac", max_nfev=max_nfev)
    theta = res.x
    e = residual(theta)
    p = theta.size
    sigma2 = float(e @ e) / max(e.size - p, 1)
    J = res.jac
    try:
        cov = sigma2 * np.linalg.inv(J.T @ J)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        cov, std = None, np.full(p, np.nan)
    return _make(structure, o, theta, std, cov, u, y, dt, k0)


def _make(structure, o, theta, std, cov, u, y, dt, k0) -> PolyEstimate:
    A, B, C, D, F = _split(theta, o)
    est = PolyEstimate(structure=structure, orders=dict(o), A=A, B=B, C=C, D=D, F=F, dt=float(dt),
                       names=_names(o), theta=np.asarray(theta, float), std=np.asarray(std, float),
                       noise_variance=math.nan, residuals=np.zeros(0), y_sim=np.zeros(0), cov=cov)
    est.residuals = est.innovations(u, y)
    est.noise_variance = float(np.mean(est.residuals[k0:] ** 2))
    est.y_sim = est.simulate(u)
    est.fit_percent = fit_percent(y, est.y_sim)
    return est


def _arx(u, y, o: dict, dt: float) -> PolyEstimate:
    from ehas_env.identification.arx import arx

    na, nb, nk = o["na"], o["nb"], o["nk"]
    m = arx(u, y, na, nb, nk, dt=dt)
    theta = np.r_[m.den[1:], m.num]
    k0 = max(na, nb - 1 + nk)
    cols = [-y[k0 - i: y.size - i] for i in range(1, na + 1)] + [u[k0 - nk - j: u.size - nk - j] for j in range(nb)]
    X = np.column_stack(cols)
    e = y[k0:] - X @ theta
    sigma2 = float(e @ e) / max(e.size - theta.size, 1)
    cov = sigma2 * np.linalg.inv(X.T @ X)
    return _make("arx", o, theta, np.sqrt(np.diag(cov)), cov, u, y, dt, k0)


# ---------------------------------------------------------------------------
# state space by N4SID
# ---------------------------------------------------------------------------

@dataclass
class SSEstimate:
    """A state-space model in innovation form from N4SID (see the module docstring).

    Attributes
    ----------
    A, B, C, D, K : ndarray
        ``x(t+1) = A x + B u + K e``, ``y = C x + D u + e``.
    dt : float
        Sample period, s.
    singular_values : ndarray
        The subspace's singular values (a gap after the n-th suggests order n).
    noise_variance : float
        Variance of the innovations (one-step prediction errors).
    residuals, y_sim, fit_percent
        As :class:`PolyEstimate`.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    K: np.ndarray
    dt: float
    singular_values: np.ndarray
    noise_variance: float = math.nan
    residuals: np.ndarray = field(repr=False, default=None)
    y_sim: np.ndarray = field(repr=False, default=None)
    fit_percent: float = math.nan
    block_rows: int = 0
    structure: str = "ss"

    @property
    def orders(self) -> dict:
        return {"nx": int(self.A.shape[0])}

    @property
    def n_parameters(self) -> int:
        """Free parameters of a canonical SISO innovation form: n (A) + n (B) + n (K)."""
        return 3 * self.A.shape[0]

    @property
    def label(self) -> str:
        return f"SS [{self.A.shape[0]}]"

    def poles(self) -> np.ndarray:
        """The plant's poles, the eigenvalues of A (those a transfer function of a zero B would cancel too)."""
        return np.linalg.eigvals(self.A)

    def ss(self):
        """The plant ``(A, B, C, D)`` as a discrete-time ``control.StateSpace`` (sample time dt)."""
        import control

        return control.ss(self.A, self.B, self.C, self.D, self.dt)

    def tf(self):
        import control

        return control.tf(self.ss())

    def _filter(self, A, B, C, D, x) -> np.ndarray:
        from scipy.signal import ss2tf

        num, den = ss2tf(A, B.reshape(-1, 1), C, D.reshape(1, 1))
        return lfilter(np.ravel(num), den, x)

    def simulate(self, u) -> np.ndarray:
        return self._filter(self.A, self.B, self.C, self.D, np.asarray(u, float))

    def innovations(self, u, y) -> np.ndarray:
        """``e = y - yhat(t | t-1)``: the Kalman predictor ``x+ = (A - K C) x + (B - K D) u + K y`` from rest."""
        u, y = np.asarray(u, float), np.asarray(y, float)
        Ak = self.A - np.outer(self.K, self.C[0])
        yhat = self._filter(Ak, self.B - self.K * self.D[0], self.C, self.D, u) + \
            self._filter(Ak, self.K, self.C, np.zeros(1), y)
        return y - yhat

    def noise_impulse(self, k: int) -> np.ndarray:
        h = np.zeros(k)
        h[0] = 1.0
        x = self.K.copy()
        for i in range(1, k):
            h[i] = float(self.C[0] @ x)
            x = self.A @ x
        return h

    def predict(self, u, y, k: int = 1) -> np.ndarray:
        y = np.asarray(y, float)
        return y - lfilter(self.noise_impulse(int(k)), [1.0], self.innovations(u, y))

    def to_json_dict(self) -> dict:
        return {"structure": "ss", "orders": self.orders, "dt": self.dt,
                "matrices": {k: np.atleast_2d(getattr(self, k)).tolist() for k in ("A", "B", "C", "D", "K")},
                "poles": [[float(p.real), float(p.imag)] for p in self.poles()],
                "singular_values": [float(v) for v in self.singular_values],
                "block_rows": self.block_rows, "noise_variance": float(self.noise_variance),
                "fit_percent": float(self.fit_percent), "method": "N4SID (nfoursid), B by least squares, D = 0"}

    def summary(self) -> str:
        poles = ", ".join(f"{p:.5g}" for p in self.poles())
        return (f"{self.label} (discrete time, dt = {self.dt:g} s, N4SID with {self.block_rows} block rows):\n"
                f"  poles (z): {poles}\n  singular values: "
                f"{', '.join(f'{v:.4g}' for v in self.singular_values[:8])}\n"
                f"  fit = {self.fit_percent:.2f} % (simulation from rest, NRMSE); innovation variance "
                f"{self.noise_variance:.4g}")


def _import_nfoursid():
    try:
        from nfoursid.nfoursid import NFourSID
    except ImportError:
        raise ValueError("structure ss needs the optional package nfoursid: pip install 'ehas[ident]'") from None
    return NFourSID


def n4sid(u, y, nx: int, dt: float = 1.0, block_rows: int | None = None) -> SSEstimate:
    """N4SID state-space estimate of order ``nx`` (see the module docstring).

    Parameters
    ----------
    u, y : array
        Input and output samples.
    nx : int
        Model order, 1..20.
    dt : float
        Sample period, s.
    block_rows : int, optional
        Rows of the block Hankel matrices (default max(10, 2 nx)).

    Returns
    -------
    SSEstimate
    """
    import pandas as pd
    from scipy.linalg import solve_discrete_are

    NFourSID = _import_nfoursid()
    u, y = np.asarray(u, float), np.asarray(y, float)
    i = int(block_rows or max(10, 2 * nx))
    n4 = NFourSID(pd.DataFrame({"u": u, "y": y}), output_columns=["y"], input_columns=["u"], num_block_rows=i)
    n4.subspace_identification()
    model, covariance = n4.system_identification(rank=nx)
    A, C = np.asarray(model.a, float), np.asarray(model.c, float).reshape(1, -1)
    sv = np.abs(np.diag(n4.R32_decomposition.eigenvalues))  # singular values (an SVD)
    # B by least squares of the simulation error: y_sim = sum_j B_j (response of state j)
    basis = np.column_stack([lfilter(*_ss_tf(A, np.eye(nx)[j], C), u) for j in range(nx)])
    B = np.linalg.lstsq(basis, y, rcond=None)[0]
    # the Kalman predictor gain from the subspace's noise covariances [[R, S'], [S, Q]]
    R = np.atleast_2d(covariance[:1, :1])
    S = covariance[1:, :1]
    Q = covariance[1:, 1:]
    try:
        P = solve_discrete_are(A.T, C.T, Q, R, s=S)
        K = ((A @ P @ C.T + S) @ np.linalg.inv(C @ P @ C.T + R)).ravel()
    except (np.linalg.LinAlgError, ValueError):
        K = np.zeros(nx)
    est = SSEstimate(A=A, B=B, C=C, D=np.zeros(1), K=K, dt=float(dt), singular_values=sv, block_rows=i)
    est.y_sim = est.simulate(u)
    est.fit_percent = fit_percent(y, est.y_sim)
    est.residuals = est.innovations(u, y)
    est.noise_variance = float(np.mean(est.residuals[i:] ** 2))
    return est


def _ss_tf(A, b, C):
    from scipy.signal import ss2tf

    num, den = ss2tf(A, np.reshape(b, (-1, 1)), C, np.zeros((1, 1)))
    return np.ravel(num), den


# ---------------------------------------------------------------------------
# the entry point
# ---------------------------------------------------------------------------

def estimate(structure: str, u, y, orders: dict | None = None, dt: float = 1.0, max_nfev: int = 200):
    """Estimate a black-box model of ``structure`` with ``orders`` (see the module docstring).

    Parameters
    ----------
    structure : str
        ``arx``, ``armax``, ``oe``, ``bj`` or ``ss``.
    u, y : array
        Input and output samples (offsets removed by the caller: the models have none).
    orders : dict, optional
        ``{"na": 2, "nb": 2, "nk": 1}`` etc.; missing orders take :data:`DEFAULT_ORDERS`.
    dt : float
        Sample period, s.
    max_nfev : int
        Most evaluations of the prediction errors (``least_squares``'s ``max_nfev``).

    Returns
    -------
    PolyEstimate or SSEstimate
    """
    o = check_orders(structure, dict(orders or {}))
    u, y = np.asarray(u, float).ravel(), np.asarray(y, float).ravel()
    if u.size != y.size:
        raise ValueError(f"u and y must have equal lengths, got {u.size} and {y.size}")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
        raise ValueError("u and y must be finite")
    p = 3 * o["nx"] if structure == "ss" else sum(v for k, v in o.items() if k != "nk")
    lag = max([v for k, v in o.items() if k != "nk"] + [0]) + o.get("nk", 0)
    if y.size < SAMPLES_PER_PARAMETER * p + lag + 20:
        raise ValueError(f"too short: {y.size} samples for {structure} {o} ({p} parameters need at least "
                         f"{SAMPLES_PER_PARAMETER * p + lag + 20})")
    if structure == "ss":
        return n4sid(u, y, o["nx"], dt=dt)
    if structure == "arx":
        return _arx(u, y, o, dt)
    nb, nk = o["nb"], o["nk"]
    long_order = int(min(max(20, 3 * max(o.values())), y.size // 20))
    if structure == "armax":
        A, B, C = _hannan_rissanen(y, u, o["na"], nb, o["nc"], nk, long_order)
        theta0 = np.r_[A[1:], B, C[1:]]
    elif structure == "oe":
        B, F = _iv_oe(u, y, nb, o["nf"], nk)
        theta0 = np.r_[B, F[1:]]
    else:  # bj: OE for the plant, then an ARMA model of its residuals
        B, F = _iv_oe(u, y, nb, o["nf"], nk)
        oe = _pem(u, y, {"nb": nb, "nf": o["nf"], "nk": nk}, np.r_[B, F[1:]], "oe", dt, max_nfev)
        v = y - oe.y_sim
        Dn, _, Cn = _hannan_rissanen(v, None, o["nd"], 0, o["nc"], 0, long_order)
        theta0 = np.r_[oe.B, Cn[1:], _stabilise(Dn)[1:], oe.F[1:]]
    return _pem(u, y, o, theta0, structure, dt, max_nfev)
