"""Continuous-time transfer functions from sampled data (the role of MATLAB's ``tfest``).

:func:`tfest` fits ``G(s) = B(s) / A(s)`` with a chosen number of poles
(deg A, A monic) and zeros (deg B) to one input and one output sampled at a
uniform rate, minimising the *simulation* error ``y - G u`` (output-error, as
``tfest`` does; its "fit %" is MATLAB's ``compare`` NRMSE,
:func:`ehas_env.simulation.metrics.fit_percent`).  It returns a ``control.TransferFunction``.

How it works:

1. the input's intersample behaviour is a zero-order hold by default (the
   measurement format's convention: row k's command holds until t_k+1, also
   MATLAB's ``iddata`` default) or a first-order hold (``intersample="foh"``,
   linear interpolation, as ``control.forced_response`` assumes); the model is
   simulated *exactly* for that input, through the matrix exponential;
2. a start by the simplified refined instrumental-variable method for
   continuous-time models (SRIVC, Young & Jakeman 1980), from a few
   pre-filter bandwidths spread over the data's band, the best kept;
3. a Levenberg-Marquardt-type refinement of the output error, with the
   numerator (and optionally the initial state) eliminated by linear least
   squares (variable projection) and the denominator parametrised as a product
   of first- and second-order factors with positive coefficients, so that
   every iterate is stable (``tfest``'s default ``EnforceStability``).

All fitting is done on a time axis scaled by a characteristic frequency, so the
polynomial coefficients stay of order one.

Examples
--------
>>> import control
>>> t = np.arange(4000) * 1e-3
>>> u = np.sign(np.sin(2 * np.pi * 1.5 * t))                 # square wave
>>> truth = control.tf([2.0 * 80.0**2], [1.0, 2 * 0.5 * 80.0, 80.0**2])
>>> y = simulate_tf(truth, t, u)
>>> est = tfest(t, u, y, n_poles=2, n_zeros=0)
>>> {k: round(v, 4) for k, v in est.second_order().items()}
{'K': 2.0, 'wn': 80.0, 'zeta': 0.5}
>>> est.fit_percent > 99.99
True
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numba import njit
from scipy.optimize import least_squares

from ehas_env.simulation.metrics import fit_percent

#: longest run of missing samples that is linearly interpolated (measurement format: "short gaps")
MAX_GAP = 5
#: relative tolerance on the sample spacing (loggers write rounded times)
DT_TOLERANCE = 0.01
#: fewest samples accepted at all, and per estimated parameter
MIN_SAMPLES = 50
SAMPLES_PER_PARAMETER = 10
INTERSAMPLE = ("zoh", "foh")
#: offsets=: none, the output's only (a sensor bias), or the operating point (input and output)
OFFSETS = ("none", "output", "estimate")
#: two-sided 99 % point of the standard normal distribution (confidence bands of the residual tests)
Z99 = 2.5758293035489004


# ---------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------

@dataclass
class IdData:
    """One validated input/output record, uniformly sampled, gaps filled.

    Attributes
    ----------
    t, u, y : ndarray
        Sample times (s), input and output.
    dt : float
        Sample period, s.
    input_name, output_name, source : str
        Names used in messages and plots.
    interpolated : dict
        Column name -> number of missing samples filled by linear interpolation.
    """

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    dt: float
    input_name: str = "u"
    output_name: str = "y"
    source: str = "data"
    interpolated: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.t.size


def prepare(t, u, y, *, input_name: str = "u", output_name: str = "y", source: str = "data",
            max_gap: int = MAX_GAP) -> IdData:
    """Validate one record for identification; fill gaps of at most ``max_gap`` samples.

    Raises ValueError naming ``source``, the column and the row (1-based data
    row, as in the CSV after its header) for: unequal lengths, fewer than
    :data:`MIN_SAMPLES` samples, non-finite or non-increasing or non-uniform
    time, a run of missing (NaN) samples longer than ``max_gap``, a constant
    input (it excites nothing) or a constant output.

    Examples
    --------
    >>> d = prepare(np.arange(100) * 1e-3, np.r_[np.nan, np.sin(np.arange(99))], np.cos(np.arange(100)))
    >>> d.interpolated, round(d.dt, 9)
    ({'u': 1}, 0.001)
    """
    t = np.asarray(t, dtype=float).ravel()
    u = np.asarray(u, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if not (t.size == u.size == y.size):
        raise ValueError(f"{source}: t, {input_name} and {output_name} must have equal lengths, "
                         f"got {t.size}, {u.size}, {y.size}")
    n = t.size
    if n < MIN_SAMPLES:
        raise ValueError(f"{source}: too short: {n} samples; identification needs at least {MIN_SAMPLES}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"{source}: column 't' has a missing or non-finite time at row {bad[0] + 1}; "
                         "time must be given on every row")
    d = np.diff(t)
    if np.any(d <= 0):
        k = int(np.flatnonzero(d <= 0)[0])
        raise ValueError(f"{source}: column 't' is not increasing at row {k + 2} (t = {t[k + 1]:.9g} s after "
                         f"{t[k]:.9g} s); rows must be in time order")
    dt = float(np.median(d))
    off = np.abs(d - dt) > DT_TOLERANCE * dt
    if np.any(off):
        k = int(np.flatnonzero(off)[0])
        raise ValueError(f"{source}: non-uniform time: the step before row {k + 2} is {d[k]:.6g} s, the run's "
                         f"sample period is {dt:.6g} s (tolerance {DT_TOLERANCE:.0%}); identification needs "
                         "uniform sampling")
    filled = {}
    u, filled_u = _fill_gaps(u, input_name, source, max_gap)
    y, filled_y = _fill_gaps(y, output_name, source, max_gap)
    if filled_u:
        filled[input_name] = filled_u
    if filled_y:
        filled[output_name] = filled_y
    if np.ptp(u) <= 1e-12 * max(1.0, float(np.abs(u).max())):
        raise ValueError(f"{source}: input '{input_name}' is constant ({u[0]:.6g} throughout): it excites "
                         "nothing, so no transfer function can be identified; use an excitation signal "
                         "(ehas excite)")
    if np.ptp(y) <= 1e-12 * max(1.0, float(np.abs(y).max())):
        raise ValueError(f"{source}: output '{output_name}' is constant ({y[0]:.6g} throughout); its fit is "
                         "undefined")
    return IdData(t=t - 0.0, u=u, y=y, dt=dt, input_name=input_name, output_name=output_name, source=source,
                  interpolated=filled)


def _fill_gaps(x: np.ndarray, name: str, source: str, max_gap: int) -> tuple[np.ndarray, int]:
    miss = ~np.isfinite(x)
    if not miss.any():
        return x, 0
    if miss.all():
        raise ValueError(f"{source}: column '{name}' has no values")
    # lengths of the runs of missing samples
    edges = np.diff(np.r_[0, miss.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    lengths = ends - starts
    worst = int(np.argmax(lengths))
    if lengths[worst] > max_gap:
        raise ValueError(f"{source}: column '{name}' misses {lengths[worst]} samples in a row from row "
                         f"{starts[worst] + 1}; at most {max_gap} consecutive missing samples are interpolated")
    k = np.arange(x.size)
    out = x.copy()
    out[miss] = np.interp(k[miss], k[~miss], x[~miss])
    return out, int(miss.sum())


def read_columns(path, input_name: str = "current_mA", output_name: str = "flow_lpm") -> IdData:
    """Read ``t``, the input and the output columns of a run file and :func:`prepare` them.

    The file is a run data file of any format ehas reads (CSV, MATLAB ``.mat``,
    NI ``.tdms``, HDF5, Parquet: :mod:`ehas_env.measurement.formats`, one reader
    for all); other columns are ignored and no sidecar is needed.

    Parameters
    ----------
    path : path
        The run data file.
    input_name, output_name : str
        The columns of the input and the output.

    Returns
    -------
    IdData
        The validated record (gaps of at most :data:`MAX_GAP` samples filled).
    """
    from ehas_env.measurement.formats import RunFileError, read_table

    path = Path(path)
    wanted = list(dict.fromkeys(("t", input_name, output_name)))

    def keep(names):
        for col in wanted:
            if col not in names:
                raise RunFileError(f"{path}: no column '{col}' in the file; columns are {', '.join(map(str, names))}")
        return wanted

    cols = read_table(path, keep).columns
    return prepare(cols["t"], cols[input_name], cols[output_name], input_name=input_name, output_name=output_name,
                   source=str(path))


# ---------------------------------------------------------------------------
# exact simulation of a continuous-time transfer function
# ---------------------------------------------------------------------------

def _as_num_den(sys_or_num, den=None) -> tuple[np.ndarray, np.ndarray]:
    if den is None:
        import control

        tf = sys_or_num if isinstance(sys_or_num, control.TransferFunction) else control.tf(sys_or_num)
        if tf.ninputs != 1 or tf.noutputs != 1:
            raise ValueError("only single-input single-output transfer functions are supported")
        if tf.isdtime(strict=True):
            raise ValueError("a continuous-time transfer function is expected (dt = 0)")
        num, den = np.atleast_1d(np.squeeze(tf.num[0][0])), np.atleast_1d(np.squeeze(tf.den[0][0]))
    else:
        num, den = np.atleast_1d(np.asarray(sys_or_num, float)), np.atleast_1d(np.asarray(den, float))
    num = np.trim_zeros(num.astype(float), "f")
    den = np.trim_zeros(den.astype(float), "f")
    if den.size == 0:
        raise ValueError("the denominator is zero")
    if num.size == 0:
        num = np.zeros(1)
    if num.size > den.size:
        raise ValueError(f"improper transfer function: numerator degree {num.size - 1} > denominator degree "
                         f"{den.size - 1}")
    return num / den[0], den / den[0]


def companion(num: np.ndarray, den: np.ndarray):
    """Controllable canonical realisation (A, B, C, D) of num/den (den monic).

    Its states are the derivatives of the filtered input: x_1 = s^(n-1)/A u,
    ..., x_n = 1/A u.
    """
    n = den.size - 1
    b = np.r_[np.zeros(n + 1 - num.size), num]
    D = b[0]
    c = b[1:] - D * den[1:]
    A = np.zeros((n, n))
    if n:
        A[0, :] = -den[1:]
        A[1:, :-1] = np.eye(n - 1)
    B = np.zeros(n)
    if n:
        B[0] = 1.0
    return A, B, c, float(D)


@njit(cache=True)
def expm(M):
    """Matrix exponential of a small matrix: scaling and squaring of a degree-16 Taylor series.

    The scaled matrix has 1-norm <= 1/4, where the truncation error is below
    1e-22.  Written out here because LAPACK-threaded ``scipy.linalg.expm`` on
    3x3 matrices can cost milliseconds on a loaded machine.
    """
    n = M.shape[0]
    norm = 0.0
    for j in range(n):
        col = 0.0
        for i in range(n):
            col += abs(M[i, j])
        norm = max(norm, col)
    s = 0
    while norm > 0.25:
        norm *= 0.5
        s += 1
    X = M / (2.0**s)
    E = np.eye(n)
    term = np.eye(n)
    for k in range(1, 17):
        term = term @ X / k
        E += term
    for _ in range(s):
        E = E @ E
    return E


def discretize(A: np.ndarray, B: np.ndarray, dt: float, intersample: str = "zoh"):
    """Exact sampling of x' = A x + B u for a held (``zoh``) or linearly interpolated (``foh``) input.

    Returns (Ad, B0, B1) with x[k+1] = Ad x[k] + B0 u[k] + B1 u[k+1]
    (B1 = 0 for ``zoh``); ``foh`` is the scheme of ``control.forced_response``.
    """
    n = A.shape[0]
    if intersample == "zoh":
        M = np.zeros((n + 1, n + 1))
        M[:n, :n] = A * dt
        M[:n, n] = B * dt
        E = expm(M)
        return E[:n, :n], E[:n, n].copy(), np.zeros(n)
    if intersample == "foh":
        M = np.zeros((n + 2, n + 2))
        M[:n, :n] = A * dt
        M[:n, n] = B * dt
        M[n, n + 1] = 1.0
        E = expm(M)
        b1 = E[:n, n + 1].copy()
        return E[:n, :n], E[:n, n] - b1, b1
    raise ValueError(f"intersample must be one of {INTERSAMPLE}, got {intersample!r}")


@njit(cache=True)
def _lsim(Ad, B0, B1, u, x0, X):
    """States X[k] of x[k+1] = Ad x[k] + B0 u[k] + B1 u[k+1], x[0] = x0."""
    n = Ad.shape[0]
    N = u.shape[0]
    x = x0.copy()
    xn = np.empty(n)
    for k in range(N):
        for i in range(n):
            X[k, i] = x[i]
        if k + 1 < N:
            for i in range(n):
                acc = B0[i] * u[k] + B1[i] * u[k + 1]
                for j in range(n):
                    acc += Ad[i, j] * x[j]
                xn[i] = acc
            for i in range(n):
                x[i] = xn[i]


def _states(A, B, dt, u, intersample, x0=None) -> np.ndarray:
    n = A.shape[0]
    X = np.zeros((u.size, n))
    if n:
        Ad, B0, B1 = discretize(A, B, dt, intersample)
        _lsim(Ad, B0, B1, np.ascontiguousarray(u, dtype=float), np.zeros(n) if x0 is None else np.asarray(x0, float), X)
    return X


def delayed_input(w: np.ndarray, delay_samples: float, intersample: str = "zoh") -> np.ndarray:
    """The input delayed by ``delay_samples`` sample periods, at the sample instants (0 before the record).

    For a held input (``zoh``) the value just after each sample instant
    (``w[k - d - 1]`` for a fractional part f > 0, ``w[k - d]`` for f = 0, with
    d = floor(delay)); for ``foh`` linear interpolation of the samples.

    Examples
    --------
    >>> delayed_input(np.arange(1.0, 6.0), 1.5).tolist()
    [0.0, 0.0, 1.0, 2.0, 3.0]
    >>> delayed_input(np.arange(1.0, 6.0), 1.5, "foh").tolist()
    [0.0, 0.5, 1.5, 2.5, 3.5]
    """
    w = np.asarray(w, dtype=float)
    N = w.size
    d = int(math.floor(delay_samples))
    f = float(delay_samples - d)
    if f < 1e-12:
        f = 0.0
    if intersample == "foh" and f > 0.0:
        k = np.arange(N) - float(delay_samples)
        return np.interp(k, np.arange(-1, N), np.r_[0.0, w], left=0.0)
    shift = d + (1 if f > 0.0 else 0)
    out = np.zeros(N)
    if shift < N:
        out[shift:] = w[: N - shift]
    return out


def _delayed_states(A, B, dt, w, intersample, delay_samples: float = 0.0, x0=None):
    """States and the delayed input at the sample instants for the input ``w`` delayed by ``delay_samples``.

    A held input delayed by a fraction f of a period changes mid-period: the
    exact sampled system is x[k+1] = Ad x[k] + Ga w[k-d-1] + Gb w[k-d] with
    Gb = int_0^((1-f)h) e^(As) ds B and Ga = e^(A(1-f)h) int_0^(fh) e^(As) ds B.
    A linearly interpolated input (``foh``) is interpolated at the shifted
    instants and simulated as ``foh`` (exact for a whole-sample delay).
    """
    wd = delayed_input(w, delay_samples, intersample) if delay_samples > 0 else np.asarray(w, dtype=float)
    n = A.shape[0]
    f = delay_samples - math.floor(delay_samples)
    if intersample != "zoh" or f < 1e-12 or n == 0:
        return _states(A, B, dt, wd, intersample, x0), wd
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = A
    M[:n, n] = B
    E1 = expm(M * ((1.0 - f) * dt))
    E2 = expm(M * (f * dt))
    Ad = E1[:n, :n] @ E2[:n, :n]
    Ga = E1[:n, :n] @ E2[:n, n]
    Gb = E1[:n, n].copy()
    X = np.zeros((wd.size, n))
    _lsim(Ad, Ga, Gb, np.ascontiguousarray(wd), np.zeros(n) if x0 is None else np.asarray(x0, float), X)
    return X, wd


def simulate_tf(sys, t, u, *, intersample: str = "zoh", x0=None, delay_s: float = 0.0) -> np.ndarray:
    """Output of a continuous-time transfer function for the sampled input ``u``, from rest.

    Exact at the sample times for a zero-order-hold (default) or a linearly
    interpolated input (``intersample="foh"``, which equals
    ``control.forced_response(sys, t, u)``).  ``x0`` is the initial state of
    the controllable canonical realisation (:func:`companion`).  ``delay_s``
    delays the input (zero before the record): exact for a held input and
    any delay, exact for ``foh`` at whole sample periods (linear
    interpolation of the samples otherwise).

    Examples
    --------
    >>> import control
    >>> t = np.arange(200) * 1e-2
    >>> y = simulate_tf(control.tf([1.0], [1.0, 1.0]), t, np.ones(200))
    >>> round(float(y[100]), 6), round(1 - math.exp(-1.0), 6)   # unit step into 1/(s+1) at 1 s
    (0.632121, 0.632121)
    """
    num, den = _as_num_den(sys)
    t = np.asarray(t, dtype=float)
    u = np.asarray(u, dtype=float)
    dt = _uniform_dt(t)
    A, B, C, D = companion(num, den)
    if delay_s:
        X, ud = _delayed_states(A, B, dt, u, intersample, float(delay_s) / dt, x0)
        return X @ C + D * ud
    X = _states(A, B, dt, u, intersample, x0)
    return X @ C + D * u


def _uniform_dt(t: np.ndarray) -> float:
    if t.size < 2:
        raise ValueError("at least two sample times are needed")
    d = np.diff(t)
    dt = float(d.mean())
    if not (dt > 0 and np.allclose(d, dt, rtol=DT_TOLERANCE, atol=0.0)):
        raise ValueError("sample times must be uniformly spaced and increasing")
    return dt


# ---------------------------------------------------------------------------
# estimation
# ---------------------------------------------------------------------------

@dataclass
class TFEstimate:
    """A fitted continuous-time transfer function and its evidence.

    Attributes
    ----------
    tf : control.TransferFunction
        The model, ``num / den`` with ``den`` monic, highest power first.
    num, den : ndarray
        Its coefficients.
    n_poles, n_zeros : int
    fit_percent : float
        NRMSE fit of the simulated output to the measured, % (MATLAB ``compare``).
    data : IdData
        The record it was fitted to.
    y_sim : ndarray
        The model's simulated output on that record.
    intersample : str
        ``zoh`` or ``foh``: the input behaviour between samples assumed.
    x0 : ndarray
        Initial state (controllable canonical realisation), zeros unless estimated.
    nfev : int
        Simulations used by the refinement.
    elapsed_s : float
        Wall time of the estimation.
    delay_s : float
        Input delay, s: the model is ``y = G(s) e^(-s delay_s) (u - input_offset) + output_offset``.
    input_offset, output_offset : float
        The operating point the model is at rest at before the record, in the
        run's units (0 unless estimated: ``offsets="estimate"``).
    estimated : tuple of str
        Which of ``"delay"``, ``"input_offset"``, ``"output_offset"``, ``"x0"`` were estimated (they enter
        the covariance).
    """

    tf: object
    num: np.ndarray
    den: np.ndarray
    n_poles: int
    n_zeros: int
    fit_percent: float
    data: IdData
    y_sim: np.ndarray
    intersample: str
    x0: np.ndarray
    nfev: int = 0
    elapsed_s: float = 0.0
    delay_s: float = 0.0
    input_offset: float = 0.0
    output_offset: float = 0.0
    estimated: tuple = ()

    @property
    def residuals(self) -> np.ndarray:
        return self.data.y - self.y_sim

    def poles(self) -> np.ndarray:
        return np.roots(self.den)

    def zeros(self) -> np.ndarray:
        return np.roots(self.num) if self.num.size > 1 else np.zeros(0)

    def usable(self) -> bool:
        """False when the fit ended at an unstable or diverging model (more poles and zeros than the record
        determines): a pole in the right half-plane, or a non-finite simulation or fit.

        Returns
        -------
        bool
        """
        poles = self.poles()
        return bool(np.isfinite(self.fit_percent) and self.fit_percent > -100.0 and np.all(np.isfinite(self.y_sim))
                    and np.all(np.real(poles) <= 1e-6 * np.maximum(np.abs(poles), 1.0)))

    def second_order(self) -> dict | None:
        """K (DC gain), wn, zeta of a 2-pole model; None otherwise."""
        if self.n_poles != 2:
            return None
        return second_order_parameters(self.num, self.den)

    def simulate(self, t, u, x0=None) -> np.ndarray:
        """The model's output for another input (same intersample assumption, delay and offsets)."""
        u = np.asarray(u, dtype=float)
        return simulate_tf(self.tf, t, u - self.input_offset, intersample=self.intersample, x0=x0,
                           delay_s=self.delay_s) + self.output_offset

    def to_json_dict(self) -> dict:
        """``{"num", "den", "K", "wn", "zeta", "fit_percent", ...}`` (den monic, highest power first)."""
        out = {"num": [float(v) for v in self.num], "den": [float(v) for v in self.den]}
        so = self.second_order()
        out.update(so if so else {"K": dc_gain(self.num, self.den), "wn": None, "zeta": None})
        out.update({"fit_percent": float(self.fit_percent), "n_poles": self.n_poles, "n_zeros": self.n_zeros,
                    "input": self.data.input_name, "output": self.data.output_name, "samples": self.data.n,
                    "dt": self.data.dt, "intersample": self.intersample,
                    "poles": [_cjson(p) for p in self.poles()], "zeros": [_cjson(z) for z in self.zeros()]})
        return out

    def summary(self) -> str:
        lines = [f"{self.n_poles} poles, {self.n_zeros} zeros, fitted to {self.data.source} "
                 f"({self.data.n} samples, dt = {self.data.dt:g} s, input {self.data.input_name}, output "
                 f"{self.data.output_name}, {self.intersample} input):",
                 f"  {self.data.output_name}/{self.data.input_name} = ({format_poly(self.num)}) / "
                 f"({format_poly(self.den)})",
                 f"  num = [{', '.join(f'{v:.8g}' for v in self.num)}]",
                 f"  den = [{', '.join(f'{v:.8g}' for v in self.den)}]"]
        so = self.second_order()
        u_in, u_out = signal_unit(self.data.input_name), signal_unit(self.data.output_name)
        if so:
            lines.append(f"  K = {so['K']:.4f} {u_out}/{u_in}, wn = {so['wn']:.2f} rad/s "
                         f"({so['wn'] / (2 * math.pi):.2f} Hz), zeta = {so['zeta']:.3f}")
        else:
            lines.append(f"  DC gain = {dc_gain(self.num, self.den):.6g} {u_out}/{u_in}")
        if self.n_zeros:
            lines.append(f"  zeros: {', '.join(f'{z:.4g}' for z in self.zeros())} rad/s")
        lines.append(f"  poles: {', '.join(f'{p:.4g}' for p in self.poles())} rad/s")
        if self.delay_s or "delay" in self.estimated:
            lines.append(f"  input delay = {1e3 * self.delay_s:.4g} ms" + (" (estimated)" if "delay" in self.estimated
                                                                         else ""))
        if "input_offset" in self.estimated or "output_offset" in self.estimated:
            lines.append(f"  offsets: input {self.data.input_name} = {self.input_offset:.6g} {u_in}, output "
                         f"{self.data.output_name} = {self.output_offset:.6g} {u_out} (estimated; the model: "
                         "y - output = G (u - input))")
        lines.append(f"  fit = {self.fit_percent:.2f} % (NRMSE, as MATLAB compare)")
        if self.data.interpolated:
            lines.append(f"  interpolated missing samples: {self.data.interpolated}")
        return "\n".join(lines)


def _cjson(z: complex):
    z = complex(z)
    return float(z.real) if abs(z.imag) < 1e-12 * max(1.0, abs(z)) else [float(z.real), float(z.imag)]


def format_poly(c: np.ndarray, var: str = "s") -> str:
    """``1 s^2 + 147.8 s + 1.145e+04`` style rendering of a coefficient vector."""
    n = len(c) - 1
    terms = []
    for k, v in enumerate(c):
        p = n - k
        terms.append(f"{v:.6g}" + ("" if p == 0 else f" {var}" if p == 1 else f" {var}^{p}"))
    return " + ".join(terms).replace("+ -", "- ")


#: unit words at the end of a signal's name (``flow_lpm``, ``current_mA``, ``p_a_bar``), as printed
_UNIT_SUFFIX = {"ma": "mA", "a": "A", "lpm": "LPM", "deg": "deg", "rad": "rad", "bar": "bar", "pa": "Pa", "kn": "kN",
                "n": "N", "s": "s", "ms": "ms", "v": "V", "mv": "mV", "m": "m", "mm": "mm"}


def signal_unit(name: str) -> str:
    """The unit a signal's name ends in (``flow_lpm`` -> ``LPM``, ``current_mA`` -> ``mA``), else the name itself.

    Parameters
    ----------
    name : str
        A run file's column name.

    Returns
    -------
    str
        The unit, or ``name`` when the name states none (a gain is then printed as ``y/u``).
    """
    suffix = str(name).rpartition("_")[2].lower()
    return _UNIT_SUFFIX.get(suffix, str(name)) if "_" in str(name) else str(name)


def dc_gain(num, den) -> float:
    """G(0) = num[-1] / den[-1] (inf for a pole at the origin)."""
    num, den = np.asarray(num, float), np.asarray(den, float)
    return float(num[-1] / den[-1]) if den[-1] != 0 else math.inf


def second_order_parameters(num, den) -> dict:
    """K, wn, zeta of a 2-pole transfer function ``num / (a0 s^2 + a1 s + a2)``.

    K is the DC gain num(0)/den(0); wn = sqrt(a2/a0); zeta = a1 / (2 wn a0).

    Examples
    --------
    >>> p = second_order_parameters([14567.29], [1.0, 147.83, 11449.86])   # the book's chirp model
    >>> round(p["K"], 3), round(p["wn"], 1), round(p["zeta"], 3)
    (1.272, 107.0, 0.691)
    """
    num = np.trim_zeros(np.atleast_1d(np.asarray(num, float)), "f")
    den = np.trim_zeros(np.atleast_1d(np.asarray(den, float)), "f")
    if den.size != 3:
        raise ValueError(f"K, wn, zeta are defined for 2-pole models; this denominator has degree {den.size - 1}")
    a0, a1, a2 = den
    if a2 / a0 <= 0:
        raise ValueError(f"the denominator {format_poly(den)} has a pole at or right of the origin; wn undefined")
    wn = math.sqrt(a2 / a0)
    return {"K": dc_gain(num, den), "wn": float(wn), "zeta": float(a1 / (2.0 * wn * a0))}


def tfest(t, u=None, y=None, n_poles: int = 2, n_zeros: int = 0, *, intersample: str = "zoh",
          initial_state: str = "zero", max_nfev: int = 400, offsets: str = "none", delay=0.0,
          max_delay_s: float | None = None) -> TFEstimate:
    """Fit a continuous-time transfer function with ``n_poles`` poles and ``n_zeros`` zeros.

    Parameters
    ----------
    t : array or IdData
        Sample times (s), or a prepared record (then ``u`` and ``y`` are omitted).
    u, y : array
        Input and output samples.
    n_poles, n_zeros : int
        Model orders, 0 <= n_zeros <= n_poles.
    intersample : {"zoh", "foh"}
        Input between samples: held (measurement format, default) or linear.
    initial_state : {"zero", "estimate"}
        Start the model at rest (a run that starts at rest) or also fit its initial state.
    max_nfev : int
        Budget of simulations for the refinement.
    offsets : {"none", "output", "estimate"}
        ``output``: also fit a constant output offset (a sensor's bias; the
        input as given); ``estimate``: fit the operating point (input and output offsets)
        the system rests at before the record, ``y - y0 = G (u - u0)`` (MATLAB's
        ``InputOffset``/``OutputOffset``, estimated instead of given).  The two
        are told apart only by the record's start (a record starting at rest
        away from the operating point); their sum ``y0 - K u0`` always.
    delay : float or "estimate"
        Input delay, s (>= 0, fractional delays exact for a held input), or
        ``"estimate"`` to fit it in [0, ``max_delay_s``].
    max_delay_s : float, optional
        Largest delay searched (default: 100 sample periods or a tenth of the record, the smaller).

    Returns
    -------
    TFEstimate
    """
    t0 = time.perf_counter()
    data = t if isinstance(t, IdData) else prepare(t, u, y)
    if not (isinstance(n_poles, (int, np.integer)) and n_poles >= 0):
        raise ValueError(f"n_poles must be a non-negative integer, got {n_poles!r}")
    if not (isinstance(n_zeros, (int, np.integer)) and 0 <= n_zeros <= n_poles):
        raise ValueError(f"n_zeros must be an integer from 0 to n_poles = {n_poles}, got {n_zeros!r}")
    if intersample not in INTERSAMPLE:
        raise ValueError(f"intersample must be one of {INTERSAMPLE}, got {intersample!r}")
    if initial_state not in ("zero", "estimate"):
        raise ValueError(f"initial_state must be 'zero' or 'estimate', got {initial_state!r}")
    est_delay = isinstance(delay, str)
    if est_delay and delay != "estimate":
        raise ValueError(f"delay must be a number of seconds >= 0 or 'estimate', got {delay!r}")
    T = data.n * data.dt
    if max_delay_s is None:
        max_delay_s = min(100 * data.dt, 0.1 * T)
    if not (isinstance(max_delay_s, (int, float, np.floating, np.integer)) and 0 < max_delay_s <= 0.5 * T):
        raise ValueError(f"max_delay_s must be a number in (0, {0.5 * T:.6g}] s (half the record), got {max_delay_s!r}")
    if not est_delay:
        if isinstance(delay, bool) or not isinstance(delay, (int, float, np.floating, np.integer)) \
                or not math.isfinite(delay) or not 0 <= delay <= 0.5 * T:
            raise ValueError(f"delay must be 'estimate' or a number of seconds in [0, {0.5 * T:.6g}] (half the "
                             f"record), got {delay!r}")
    if offsets not in OFFSETS:
        raise ValueError(f"offsets must be one of {', '.join(OFFSETS)}, got {offsets!r}")
    est_off = offsets == "estimate"
    if est_off and initial_state == "estimate":
        raise ValueError("offsets='estimate' and initial_state='estimate' together are not identifiable (a free "
                         "initial state absorbs the input offset); estimate one of them")
    n, m = int(n_poles), int(n_zeros)
    n_par = n + m + 1 + (n if initial_state == "estimate" else 0) + int(est_delay) + int(est_off) + int(offsets != "none")
    if data.n < SAMPLES_PER_PARAMETER * n_par:
        raise ValueError(f"{data.source}: too short: {data.n} samples for {n_par} parameters; need at least "
                         f"{SAMPLES_PER_PARAMETER * n_par}")
    est_x0 = initial_state == "estimate"
    delay_n = 0.0 if est_delay else float(delay) / data.dt  # samples
    u0 = y0 = 0.0
    if n == 0:
        if est_delay or delay_n:
            raise ValueError("a delay needs a dynamic model (n_poles >= 1)")
        if offsets == "estimate":  # a static model: the operating point taken at the means
            uc, yc = data.u - data.u.mean(), data.y - data.y.mean()
            gain = float(np.dot(uc, yc) / np.dot(uc, uc))
            u0, y0 = float(data.u.mean()), float(data.y.mean())
        elif offsets == "output":
            (gain, y0), *_ = np.linalg.lstsq(np.column_stack([data.u, np.ones(data.n)]), data.y, rcond=None)
            gain, y0 = float(gain), float(y0)
        else:
            gain = float(np.dot(data.u, data.y) / np.dot(data.u, data.u))
        num, den, nfev = np.array([gain]), np.array([1.0]), 0
    else:
        num, den, nfev, delay_n, u0, y0 = _fit(data, n, m, intersample, est_x0, max_nfev, delay=delay_n,
                                               est_delay=est_delay, offsets=offsets,
                                               max_delay=max_delay_s / data.dt)
    if delay_n < 1e-6:  # at the bound: no delay
        delay_n = 0.0
    import control

    tf = control.tf(num, den)
    A, B, C, D = companion(num, den)
    x0 = np.zeros(n)
    if est_x0 and n:
        # free responses of the final realisation; the initial state enters linearly
        X, ud = _delayed_states(A, B, data.dt, data.u - u0, intersample, delay_n)
        forced = X @ C + D * ud + y0
        O = _free_responses(A, C, data.dt, data.n)
        x0 = np.linalg.lstsq(O, data.y - forced, rcond=None)[0]
    y_sim = simulate_tf(tf, data.t, data.u - u0, intersample=intersample, x0=x0 if n else None,
                        delay_s=delay_n * data.dt) + y0
    fit = fit_percent(data.y, y_sim)
    estimated = tuple(k for k, on in (("delay", est_delay), ("input_offset", est_off), ("output_offset", offsets != "none"), ("x0", est_x0 and n > 0)) if on)
    return TFEstimate(tf=tf, num=num, den=den, n_poles=n, n_zeros=m, fit_percent=fit, data=data, y_sim=y_sim,
                      intersample=intersample, x0=x0, nfev=nfev, elapsed_s=time.perf_counter() - t0,
                      delay_s=float(delay_n * data.dt), input_offset=float(u0), output_offset=float(y0),
                      estimated=estimated)


def _free_responses(A: np.ndarray, C: np.ndarray, dt: float, N: int) -> np.ndarray:
    n = A.shape[0]
    Ad = expm(A * dt)
    O = np.empty((N, n))
    zero = np.zeros(n)
    for i in range(n):
        X = np.zeros((N, n))
        _lsim(Ad, zero, zero, np.zeros(N), np.eye(n)[i], X)
        O[:, i] = X @ C
    return O


# -- the denominator as a product of stable factors --------------------------

def _poly_from_z(z: np.ndarray, n: int) -> np.ndarray:
    """Monic degree-n polynomial from log-coefficients of its factors.

    Pairs (z[2i], z[2i+1]) give s^2 + e^z0 s + e^z1; an odd degree adds s + e^z[-1].
    Every such polynomial is Hurwitz (stable).
    """
    p = np.ones(1)
    c = np.exp(z)
    for i in range(n // 2):
        p = np.convolve(p, [1.0, c[2 * i], c[2 * i + 1]])
    if n % 2:
        p = np.convolve(p, [1.0, c[-1]])
    return p


def _z_from_poly(den: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_poly_from_z` (unstable roots reflected into the left half-plane)."""
    n = den.size - 1
    r = np.roots(den)
    r = np.where(r.real >= 0, -np.abs(r.real) - 1e-6 * max(1.0, float(np.abs(r).max())) + 1j * r.imag, r)
    cplx = [z for z in r if z.imag > 1e-12 * max(1.0, abs(z))]
    real = sorted([z.real for z in r if abs(z.imag) <= 1e-12 * max(1.0, abs(z))], reverse=True)
    quads = [(-2.0 * z.real, abs(z) ** 2) for z in cplx]
    while len(real) >= 2 and len(quads) < n // 2:
        a, b = real.pop(0), real.pop(0)
        quads.append((-(a + b), a * b))
    z = []
    for c1, c0 in quads:
        z += [math.log(max(c1, 1e-12)), math.log(max(c0, 1e-24))]
    if n % 2:
        z.append(math.log(max(-real[0], 1e-12)))
    return np.array(z)


class _Problem:
    """The output-error problem on the scaled time axis (s = ws p).

    The nonlinear parameters are ``q = [z, delay?, u0?]``: the log-factors of
    the denominator (:func:`_poly_from_z`), the input delay in sample periods
    (``est_delay``) and the input offset (``offsets="estimate"``); the numerator, the
    output offset and the initial state enter linearly and are eliminated by
    least squares.  ``delay`` is the fixed delay (samples) when not estimated.
    """

    def __init__(self, data: IdData, n: int, m: int, intersample: str, est_x0: bool, ws: float, *,
                 delay: float = 0.0, est_delay: bool = False, offsets: str = "none"):
        self.u, self.y = data.u, data.y
        self.n, self.m, self.intersample, self.est_x0 = n, m, intersample, est_x0
        self.ws = ws
        self.h = data.dt * ws  # the scaled sample period
        self.delay, self.est_delay = float(delay), est_delay
        self.est_offsets = offsets == "estimate"  # the input offset: a nonlinear parameter
        self.est_y0 = offsets != "none"  # the output offset: linear
        self.nfev = 0

    def split(self, q: np.ndarray):
        """(a, delay in samples, input offset) from the nonlinear parameters."""
        n = self.n
        a = _poly_from_z(q[:n], n)
        k = n
        delay = self.delay
        if self.est_delay:
            delay = float(q[k])
            k += 1
        u0 = float(q[k]) if self.est_offsets else 0.0
        return a, delay, u0

    def basis(self, a: np.ndarray, delay: float = None, u0: float = 0.0) -> np.ndarray:
        """Columns p^m/A w, ..., p^0/A w of the delayed offset-free input w (then ones, free responses)."""
        n, m = self.n, self.m
        delay = self.delay if delay is None else delay
        A, B, _, _ = companion(np.ones(1), a)
        X, wd = _delayed_states(A, B, self.h, self.u - u0, self.intersample, delay)
        self.nfev += 1
        cols = []
        for k in range(m, -1, -1):  # p^k / A u is state x_(n-k) (1-based), p^n / A u = u - a.x
            cols.append(wd - X @ a[1:] if k == n else X[:, n - 1 - k])
        if self.est_y0:
            cols.append(np.ones(self.u.size))
        Phi = np.column_stack(cols)
        if self.est_x0:
            Phi = np.column_stack([Phi, _free_basis(A, self.h, self.u.size)])
        return Phi

    def solve_q(self, q: np.ndarray):
        """(numerator, output offset, residual) for the nonlinear parameters q."""
        a, delay, u0 = self.split(q)
        Phi = self.basis(a, delay, u0)
        coef, *_ = np.linalg.lstsq(Phi, self.y, rcond=None)
        y0 = float(coef[self.m + 1]) if self.est_y0 else 0.0
        return coef[: self.m + 1], y0, self.y - Phi @ coef

    def solve(self, a: np.ndarray):
        Phi = self.basis(a)
        coef, *_ = np.linalg.lstsq(Phi, self.y, rcond=None)
        return coef[: self.m + 1], self.y - Phi @ coef

    def residual_z(self, z: np.ndarray) -> np.ndarray:
        return self.solve(_poly_from_z(z, self.n))[1]

    def residual_q(self, q: np.ndarray) -> np.ndarray:
        return self.solve_q(q)[2]

    def unscale(self, b: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients in s from those in p = s / ws."""
        n, m = self.n, self.m
        den = a * self.ws ** np.arange(n + 1)
        num = b * self.ws ** (n - m + np.arange(m + 1))
        return num, den


def _free_basis(A: np.ndarray, h: float, N: int) -> np.ndarray:
    """All n free-response shapes of x' = A x (every state component from every unit start)."""
    n = A.shape[0]
    zero = np.zeros(n)
    X = np.zeros((N, n))
    # from x(0) = B the companion states are the impulse response g of 1/A and its
    # derivatives g', ..., g^(n-1): together they span every free response
    _lsim(expm(A * h), zero, zero, np.zeros(N), np.eye(n)[0], X)
    return X


def _srivc(prob: _Problem, a0: np.ndarray, iters: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Simplified refined instrumental variables for a continuous-time model (scaled time).

    Pre-filters input and output by 1/A(p) (the current denominator), regresses
    the filtered p^n y on the filtered lower derivatives, and uses as
    instruments the same filters applied to the auxiliary model's output.
    """
    n, m, h = prob.n, prob.m, prob.h
    u, y = prob.u, prob.y
    a = a0.copy()
    b = None
    for it in range(iters):
        A, B, _, _ = companion(np.ones(1), a)
        Xu = _states(A, B, h, u, prob.intersample)
        Xy = _states(A, B, h, y, "foh")
        ypn = y - Xy @ a[1:]                      # p^n / A y
        # regressors: -p^(n-1)/A y ... -p^0/A y, p^m/A u ... p^0/A u
        Phi = np.column_stack([-Xy] + [(u - Xu @ a[1:]) if k == n else Xu[:, n - 1 - k] for k in range(m, -1, -1)])
        if b is None:
            Z = Phi
        else:
            Ah, Bh, Ch, Dh = companion(b, a)
            xh = _states(Ah, Bh, h, u, prob.intersample) @ Ch + Dh * u
            Xx = _states(A, B, h, xh, "foh")
            Z = np.column_stack([-Xx, Phi[:, n:]])
        M = Z.T @ Phi
        try:
            theta = np.linalg.solve(M, Z.T @ ypn)
        except np.linalg.LinAlgError:
            theta = np.linalg.lstsq(M, Z.T @ ypn, rcond=None)[0]
        a_new = np.r_[1.0, theta[:n]]
        a_new = _poly_from_z(_z_from_poly(a_new), n)  # keep it stable
        b = theta[n:]
        done = np.max(np.abs(a_new - a) / (np.abs(a_new) + 1e-12)) < 1e-7
        a = a_new
        if done:
            break
    return a, b


def _fit(data: IdData, n: int, m: int, intersample: str, est_x0: bool, max_nfev: int, *, delay: float = 0.0,
         est_delay: bool = False, offsets: str = "none", max_delay: float = 0.0):
    """(num, den, nfev, delay in samples, input offset, output offset) of the output-error optimum.

    ``delay`` (samples) is fixed unless ``est_delay``; then it is searched in
    [0, max_delay] (a scan of at most 41 delays, each with the poles refitted
    briefly, from the best of which all parameters are refined).
    """
    est_offsets = offsets == "estimate"
    T = data.n * data.dt
    w_lo = 2.0 * math.pi * 2.0 / T
    w_hi = 2.0 * math.pi * 0.1 / data.dt
    starts = np.geomspace(w_lo, w_hi, 8) if w_hi > w_lo else np.array([w_lo])
    # the starts see the input delayed by the fixed delay (an estimated one starts at zero); with offsets
    # SRIVC runs on the signals as they are and without their means, and each start is scored on the
    # problem itself (with its offset column)
    start_sets = [data]
    if delay or offsets != "none":
        variants = [False, True] if offsets != "none" else [False]
        start_sets = []
        for demean in variants:
            uu = data.u - (data.u.mean() if demean and est_offsets else 0.0)
            uu = delayed_input(uu, delay, intersample) if delay else uu
            start_sets.append(IdData(t=data.t, u=uu, y=data.y - (data.y.mean() if demean else 0.0), dt=data.dt))
    u0_start = float(data.u.mean()) if est_offsets else 0.0
    cands = []
    for start_data in start_sets:
        for lam in starts:
            prob = _Problem(start_data, n, m, intersample, est_x0, lam)
            a0 = np.poly(-np.ones(n))  # (p + 1)^n: pre-filter of bandwidth lam
            try:
                a, _ = _srivc(prob, a0)
                if start_data is data:
                    _, r = prob.solve(a)
                else:
                    full = _Problem(data, n, m, intersample, est_x0, lam, delay=delay, offsets=offsets)
                    q = np.r_[_z_from_poly(a), [u0_start] if est_offsets else []]
                    r = full.solve_q(q)[2]
            except (np.linalg.LinAlgError, ValueError, FloatingPointError):
                continue
            cost = float(r @ r)
            if np.isfinite(cost):
                num, den = prob.unscale(np.ones(m + 1), a)
                cands.append((cost, den))
    if not cands:
        raise ValueError(f"{data.source}: no start of the estimation converged; check the data")
    cands.sort(key=lambda c: c[0])
    best = None
    nfev = 0
    d_start = None
    for cost0, den0 in cands[:2]:
        ws = float(abs(den0[-1]) ** (1.0 / n))
        prob = _Problem(data, n, m, intersample, est_x0, ws, delay=delay, est_delay=est_delay,
                        offsets=offsets)
        z0 = _z_from_poly(den0 / ws ** np.arange(n + 1))
        # poles beyond ten times the Nyquist frequency are not identifiable from the samples: keep them in reach
        w_max = 10.0 * math.pi / data.dt / ws
        upper = np.array([math.log(2.0 * w_max), math.log(w_max**2)] * (n // 2) + [math.log(w_max)] * (n % 2))
        z0 = np.minimum(z0, upper - 1e-6)
        lower = np.full(n, -np.inf)
        q0, lo, hi = z0, lower, upper
        if est_delay:
            if d_start is None:  # one scan, from the best start
                d_start = _scan_delay(prob, z0, lower, upper, u0_start, max_delay)
            d0 = d_start
            q0, lo, hi = np.r_[q0, d0], np.r_[lo, 0.0], np.r_[hi, max_delay]
        if est_offsets:
            q0, lo, hi = np.r_[q0, u0_start], np.r_[lo, -np.inf], np.r_[hi, np.inf]
        fin_lo, fin_hi = np.isfinite(lo), np.isfinite(hi)
        q0 = np.clip(q0, np.where(fin_lo, lo + 1e-9 * np.maximum(1.0, np.abs(np.where(fin_lo, lo, 0.0))), lo),
                     np.where(fin_hi, hi - 1e-9 * np.maximum(1.0, np.abs(np.where(fin_hi, hi, 0.0))), hi))
        if est_delay or offsets != "none":
            sol = least_squares(prob.residual_q, q0, method="trf", bounds=(lo, hi), x_scale="jac", xtol=1e-12,
                                ftol=1e-12, max_nfev=max_nfev)
            q = sol.x
        else:
            sol = least_squares(prob.residual_z, z0, method="trf", bounds=(-np.inf, upper), x_scale="jac",
                                xtol=1e-12, ftol=1e-12, max_nfev=max_nfev)
            q = sol.x
        a, d, u0 = prob.split(q)
        b, y0, r = prob.solve_q(q)
        nfev += prob.nfev
        cost = float(r @ r)
        if best is None or cost < best[0]:
            num, den = prob.unscale(b, a)
            best = (cost, num, den, d, u0, y0)
    return best[1], best[2], nfev, best[3], best[4], best[5]


def _scan_delay(prob: _Problem, z0, lower, upper, u0: float, max_delay: float) -> float:
    """The delay (samples) of the lowest cost over a grid of [0, max_delay], each with the poles refitted briefly."""
    step = max(1.0, max_delay / 40.0)
    grid = np.arange(0.0, max_delay + 1e-9, step)
    best = (math.inf, 0.0)
    keep_delay, keep_est, keep_off = prob.delay, prob.est_delay, prob.est_offsets
    prob.est_delay = False
    z = z0
    try:
        for d in grid:
            prob.delay = float(d)
            prob.est_offsets = keep_off

            def res(zz):
                return prob.residual_q(np.r_[zz, u0] if keep_off else zz)

            sol = least_squares(res, np.clip(z, lower, upper - 1e-9), method="trf", bounds=(lower, upper),
                                x_scale="jac", max_nfev=8)
            cost = float(sol.fun @ sol.fun)
            if cost < best[0]:
                best = (cost, float(d))
    finally:
        prob.delay, prob.est_delay, prob.est_offsets = keep_delay, keep_est, keep_off
    return min(max(best[1], 1e-6), max_delay)


# ---------------------------------------------------------------------------
# residual analysis (MATLAB resid)
# ---------------------------------------------------------------------------

@dataclass
class ResidualAnalysis:
    """Whiteness and independence tests of the residuals, with 99 % confidence bands.

    Attributes
    ----------
    lags : ndarray
        0..max_lag for the autocorrelation.
    auto : ndarray
        Normalised autocorrelation of the residuals, auto[0] = 1.
    auto_band : float
        Band +-z/sqrt(N) inside which a white residual's values lie with 99 % confidence.
    cross_lags : ndarray
        -max_lag..max_lag.
    cross : ndarray
        Normalised cross-correlation R_eu(tau) = sum e(k + tau) u(k) / (N sqrt(R_ee(0) R_uu(0)));
        tau > 0: the residual follows the input (unmodelled dynamics), tau < 0: feedback.
    cross_band : float
        99 % band for a residual independent of the input,
        z sqrt(sum_k r_ee(k) r_uu(k) / N) (Ljung 1999, sec. 16.6).
    n : int
        Samples.
    """

    lags: np.ndarray
    auto: np.ndarray
    auto_band: float
    cross_lags: np.ndarray
    cross: np.ndarray
    cross_band: float
    n: int

    def auto_outside(self) -> int:
        """Lags >= 1 at which the autocorrelation leaves its band."""
        return int(np.sum(np.abs(self.auto[1:]) > self.auto_band))

    def cross_outside(self) -> int:
        return int(np.sum(np.abs(self.cross) > self.cross_band))

    def verdict(self) -> str:
        a, c = self.auto_outside(), self.cross_outside()
        white = "white" if a <= max(1, round(0.01 * self.lags.size)) else f"not white ({a} lags outside)"
        indep = ("independent of the input" if c <= max(1, round(0.01 * self.cross_lags.size))
                 else f"correlated with the input ({c} lags outside)")
        return f"residuals {white}, {indep} (99 % bands)"


def _xcorr(a: np.ndarray, b: np.ndarray, max_lag: int) -> np.ndarray:
    """(1/N) sum_k a(k + lag) b(k) for lag = -max_lag..max_lag (one FFT; no BLAS calls per lag)."""
    N = a.size
    nfft = 1 << int(math.ceil(math.log2(2 * N)))
    cc = np.fft.irfft(np.fft.rfft(a, nfft) * np.conj(np.fft.rfft(b, nfft)), nfft)
    return np.r_[cc[nfft - max_lag:], cc[: max_lag + 1]] / N


def residual_analysis(e, u, max_lag: int = 25, confidence: float = 0.99) -> ResidualAnalysis:
    """Autocorrelation of the residuals and their cross-correlation with the input, as MATLAB ``resid``.

    No means are removed (a residual offset shows up as correlation at every lag).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> ra = residual_analysis(rng.normal(size=5000), rng.normal(size=5000))
    >>> float(ra.auto[0]), round(ra.auto_band, 4)
    (1.0, 0.0364)
    """
    e = np.asarray(e, dtype=float)
    u = np.asarray(u, dtype=float)
    N = e.size
    if u.size != N:
        raise ValueError(f"residuals ({N}) and input ({u.size}) must have equal lengths")
    if not (isinstance(max_lag, (int, np.integer)) and 1 <= max_lag < N):
        raise ValueError(f"max_lag must be an integer in 1..{N - 1}, got {max_lag!r}")
    if confidence == 0.99:
        z = Z99
    else:
        from scipy.stats import norm

        z = float(norm.ppf(0.5 + confidence / 2.0))
    ree = _xcorr(e, e, max_lag)  # lags -M..M
    ruu = _xcorr(u, u, max_lag)
    reu = _xcorr(e, u, max_lag)
    ree0, ruu0 = ree[max_lag], ruu[max_lag]
    if ree0 == 0 or ruu0 == 0:
        raise ValueError("residual_analysis: the residuals or the input are identically zero")
    lags = np.arange(max_lag + 1)
    auto = ree[max_lag:] / ree0
    cross_lags = np.arange(-max_lag, max_lag + 1)
    cross = reu / math.sqrt(ree0 * ruu0)
    p = float(np.sum((ree / ree0) * (ruu / ruu0)))
    return ResidualAnalysis(lags=lags, auto=auto, auto_band=z / math.sqrt(N), cross_lags=cross_lags, cross=cross,
                            cross_band=z * math.sqrt(max(p, 0.0) / N), n=N)
