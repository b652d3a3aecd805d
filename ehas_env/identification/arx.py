"""ARX: the discrete-time equation-error model by linear least squares (MATLAB's ``arx``), for comparison.

``A(q) y(k) = B(q) u(k - nk) + e(k)`` with ``A = 1 + a1 q^-1 + ... + a_na q^-na`` and
``B = b1 + b2 q^-1 + ... + b_nb q^-(nb-1)``: one linear regression, no
iterations, no starting values.  Its price: the noise is assumed to pass
through 1/A; white *measurement* noise on the output (a flow meter's)
biases the estimate, which the output-error fit of
:func:`ehas_env.identification.fit.tfest` does not suffer (tests/identification
compare both on the same data).  The continuous-time equivalent is the
inverse of the zero-order-hold sampling (matrix logarithm), defined when no
pole lies on the negative real axis of the z-plane.

ARMAX, OE, BJ (prediction-error method) and N4SID state space are in
:mod:`ehas_env.identification.pem`, which also wraps this ARX with standard
errors (``estimate("arx", ...)``).

Examples
--------
>>> rng = np.random.default_rng(0)
>>> u = rng.normal(size=4000)
>>> y = np.zeros(4000)
>>> for k in range(2, 4000): y[k] = 1.5 * y[k-1] - 0.7 * y[k-2] + 0.5 * u[k-1] + 0.01 * rng.normal()
>>> m = arx(u, y, 2, 1, 1)
>>> np.round(m.den, 3).tolist(), np.round(m.num, 3).tolist()
([1.0, -1.5, 0.7], [0.5])
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ARXEstimate:
    """A fitted ARX model.

    Attributes
    ----------
    num, den : ndarray
        B and A as polynomials in q^-1 (``den[0] = 1``); the input is delayed by ``nk`` samples.
    nk : int
        Input delay, samples.
    dt : float
        Sample period, s.
    """

    num: np.ndarray
    den: np.ndarray
    nk: int
    dt: float

    def tf(self):
        """The discrete-time ``control.TransferFunction`` (in z, sample time dt)."""
        import control

        na, nb = self.den.size - 1, self.num.size
        n = max(na, nb - 1 + self.nk)
        den = np.r_[self.den, np.zeros(n - na)]
        num = np.r_[np.zeros(self.nk), self.num, np.zeros(n + 1 - self.nk - nb)]
        return control.tf(num, den, self.dt)

    def simulate(self, u) -> np.ndarray:
        """Simulated output (from rest) for the input ``u``."""
        from scipy.signal import lfilter

        b = np.r_[np.zeros(self.nk), self.num]
        return lfilter(b, self.den, np.asarray(u, float))

    def continuous(self):
        """The continuous-time transfer function whose zero-order-hold sampling is this model (``d2c``)."""
        import control
        from scipy.linalg import logm

        sys = control.ss(self.tf())
        n = sys.nstates
        M = np.zeros((n + 1, n + 1))
        M[:n, :n], M[:n, n:] = sys.A, sys.B
        M[n, n] = 1.0
        L = np.real(logm(M)) / self.dt
        return control.tf(control.ss(L[:n, :n], L[:n, n:], sys.C, sys.D))


def arx(u, y, na: int, nb: int, nk: int = 1, dt: float = 1.0) -> ARXEstimate:
    """Least-squares ARX fit.

    Parameters
    ----------
    u, y : array
        Input and output samples.
    na, nb, nk : int
        Orders of A and B and the input delay in samples (MATLAB's ``[na nb nk]``).
    dt : float
        Sample period, s.

    Returns
    -------
    ARXEstimate
    """
    u, y = np.asarray(u, float), np.asarray(y, float)
    for name, v, lo in (("na", na, 0), ("nb", nb, 1), ("nk", nk, 0)):
        if not (isinstance(v, (int, np.integer)) and lo <= v <= 50):
            raise ValueError(f"{name} must be an integer in [{lo}, 50], got {v!r}")
    if u.size != y.size:
        raise ValueError(f"u and y must have equal lengths, got {u.size} and {y.size}")
    k0 = max(na, nb - 1 + nk)
    N = y.size
    if N - k0 < 10 * (na + nb):
        raise ValueError(f"too short: {N} samples for na = {na}, nb = {nb}, nk = {nk}")
    cols = [-y[k0 - i: N - i] for i in range(1, na + 1)] + [u[k0 - nk - j: N - nk - j] for j in range(nb)]
    theta, *_ = np.linalg.lstsq(np.column_stack(cols), y[k0:], rcond=None)
    return ARXEstimate(num=theta[na:], den=np.r_[1.0, theta[:na]], nk=int(nk), dt=float(dt))
