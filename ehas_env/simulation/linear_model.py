"""The plant linearised at an operating point, as python-control models, for the tuners and curves.

The linearisation is the compiled model's own right-hand side differentiated
numerically (:func:`ehas_env.physics.linearise.linearise`): every effect the
plant carries, built-in or a user's file, is in it.  Here it is put in the
coordinates a hydraulic engineer reads -- valve states, load pressure
P_L = P_A - P_B (bar), crank angle and rate -- with the pressure sum dropped
where nothing depends on it, and the controller's load-pressure feedback
(``Kdp``, static or high-passed) closed around it.  Merritt's hand-derived
model (``C P_L' = Kq q_c - Kce P_L - a omega``, ``I omega' = a P_L - B omega``,
the identified valve) is the tests' oracle for it.

The input is the valve current in mA, outputs theta in deg and P_L in bar.  The
controller's sample-and-hold (half a period) and any transport delay are a
Pade approximation at the input.

Examples
--------
>>> from ehas_controllers.linear_model import LinearPlant
>>> lp = LinearPlant(disc_sets=7)
>>> round(lp.velocity_gain, 2)          # deg/s per mA (the book's 56.25 -> Kv = 1/56.25)
56.25
>>> round(lp.hydraulic_wn / (2 * 3.141592653589793), 1)   # Hz
24.3
"""
from __future__ import annotations

import math

import control
import numpy as np

from ehas_env.physics.rig import BAR, LPM


#: LPM: the valve flow at which a rate "at null flow" is taken when null flow has none (unequal piston areas)
SMALL_FLOW_LPM = 1e-3


class LinearPlant:
    """Small-signal model of the rig around an operating point.

    Parameters
    ----------
    plant : ehas_env.simulation.plant.Plant, optional
        Plant (effects included) to linearise; default ``Plant(disc_sets)``.
    disc_sets : int
        Used when ``plant`` is not given.
    theta_deg : float
        Operating crank angle, deg.
    load_bar : float
        Operating load pressure P_L0, bar.
    flow_lpm : float
        Operating valve no-load flow |q_c0| (at the rated drop), LPM; 0 = null flow.
    rate_hz : float
        Controller rate; its zero-order hold adds half a period of delay.
    pade_order : int
        Order of the Pade approximation of the delay (0: no delay).
    """

    def __init__(self, plant=None, *, disc_sets: int = 3, theta_deg: float = 0.0, load_bar: float = 0.0,
                 flow_lpm: float = 0.0, rate_hz: float = 1000.0, pade_order: int = 2):
        from ehas_env.physics.linearise import linearise

        if plant is None:
            from ehas_env.simulation.plant import Plant

            plant = Plant(disc_sets=disc_sets)
        s = plant.slots()
        if not abs(load_bar * BAR) < s["supply"]:
            raise ValueError(f"load_bar must lie within +-{s['supply'] / BAR:g} bar (the supply), got {load_bar!r}")
        self.plant = plant
        self.disc_sets = plant.rig.disc_sets
        self.slots = s
        self.rate_hz = float(rate_hz)
        self.pade_order = int(pade_order)
        self.delay = 0.5 / self.rate_hz + s["tau"]  # s: zero-order hold + transport delay
        lin = linearise(plant, theta_deg=theta_deg, load_bar=load_bar, flow_lpm=abs(flow_lpm))
        self.operating_point = {"theta_deg": theta_deg, "load_bar": load_bar, "flow_lpm": abs(flow_lpm)}
        self.lin = lin
        self.A, self.B, self.states = _load_pressure_coordinates(lin)
        self.C = np.zeros((2, len(self.states)))
        self.C[0, self.states.index("theta")] = math.degrees(1.0)
        self.C[1, self.states.index("p_load")] = 1.0

    # -- numbers ---------------------------------------------------------------
    def _index(self, *names) -> list[int]:
        return [self.states.index(n) for n in names]

    @property
    def velocity_gain(self) -> float:
        """Steady crank rate per valve current, deg/s per mA (the crank free: theta's own terms left out).

        With unequal piston areas at null flow (the pressure sum kept, a critically lapped valve
        without leakage: no flow-pressure coefficient) the linear model has no steady rate; the
        rate is then the limit of a small flow (``SMALL_FLOW_LPM``), where the chamber pressures
        share the valve flow as the two areas take it.
        """
        keep = [j for j, n in enumerate(self.states) if n != "theta"]
        try:
            x = np.linalg.solve(self.A[np.ix_(keep, keep)], -self.B[keep, 0])
        except np.linalg.LinAlgError:
            if self.operating_point["flow_lpm"] > 0.0 or "p_sum" not in self.states:
                raise
            small = LinearPlant(self.plant, theta_deg=self.operating_point["theta_deg"],
                                load_bar=self.operating_point["load_bar"], flow_lpm=SMALL_FLOW_LPM,
                                rate_hz=self.rate_hz, pade_order=0)
            return small.velocity_gain
        return math.degrees(float(x[keep.index(self.states.index("omega"))]))

    def _hydraulic_pair(self) -> complex:
        idx = self._index("p_load", "theta", "omega")
        ev = np.linalg.eigvals(self.A[np.ix_(idx, idx)])
        return complex(max(ev, key=abs))

    @property
    def hydraulic_wn(self) -> float:
        """Natural frequency of the crank-oil mode, rad/s (eigenvalues of the load-pressure/crank block)."""
        return abs(self._hydraulic_pair())

    @property
    def hydraulic_zeta(self) -> float:
        """Damping ratio of the crank-oil mode (no valve dynamics)."""
        lam = self._hydraulic_pair()
        return float(-lam.real / abs(lam)) if abs(lam) > 0 else 0.0

    # -- models ----------------------------------------------------------------
    def state_space(self, Kdp: float = 0.0, dp_hp: float = 0.0) -> control.StateSpace:
        """Input current u (mA) -> outputs (theta deg, P_L bar), pressure feedback closed, no delay.

        States: those of the linearisation with P_L (bar) for the two chamber pressures
        [, the pressure feedback's low-passed P_L (bar)].
        """
        A, B, C = self.A.copy(), self.B.copy(), self.C.copy()
        pl = self.states.index("p_load")
        if Kdp != 0.0:
            if dp_hp > 0.0:
                # i = u - Kdp (P_L - z), z' = dp_hp (P_L - z): feed back the high-passed pressure
                n = A.shape[0]
                A = np.pad(A, ((0, 1), (0, 1)))
                B = np.pad(B, ((0, 1), (0, 0)))
                C = np.pad(C, ((0, 0), (0, 1)))
                A[n, pl] = dp_hp
                A[n, n] = -dp_hp
                A[:, pl] -= B[:, 0] * Kdp
                A[:, n] += B[:, 0] * Kdp
            else:
                A[:, pl] -= B[:, 0] * Kdp
        return control.ss(A, B, C, np.zeros((2, 1)))

    def delay_tf(self) -> control.TransferFunction:
        """Pade approximation of the input delay (zero-order hold + transport)."""
        if self.pade_order <= 0 or self.delay <= 0:
            return control.tf([1.0], [1.0])
        num, den = control.pade(self.delay, self.pade_order)
        return control.tf(num, den)

    def _tf(self, out: int, Kdp: float, dp_hp: float) -> control.TransferFunction:
        ss = self.state_space(Kdp, dp_hp)
        g = control.ss2tf(ss.A, ss.B, ss.C[out:out + 1], ss.D[out:out + 1])
        return control.minreal(g, tol=1e-9 * max(1.0, float(np.abs(ss.A).max())) ** 0, verbose=False)

    def tf(self, Kdp: float = 0.0, dp_hp: float = 0.0, delay: bool = True) -> control.TransferFunction:
        """theta (deg) / u (mA), the plant the position loop sees (with pressure feedback ``Kdp``)."""
        g = self._tf(0, Kdp, dp_hp)
        return g * self.delay_tf() if delay else g

    def tf_load(self, Kdp: float = 0.0, dp_hp: float = 0.0, delay: bool = True) -> control.TransferFunction:
        """P_L (bar) / u (mA)."""
        g = self._tf(1, Kdp, dp_hp)
        return g * self.delay_tf() if delay else g

    def open_loop_poles(self, Kdp: float = 0.0, dp_hp: float = 0.0) -> np.ndarray:
        """Poles of the plant with the pressure feedback closed (delay excluded)."""
        return np.linalg.eigvals(self.state_space(Kdp, dp_hp).A)

    # -- design helpers -----------------------------------------------------------
    def inverse_series(self, Kdp: float = 0.0, dp_hp: float = 0.0, order: int = 3, delay: bool = True) -> np.ndarray:
        """Taylor coefficients c_1..c_order of 1/G(s) = sum c_k s^k, G = theta/u (mA/(deg/s^k)).

        These are the model-inversion feed-forward gains: Kv = c_1, Ka = c_2, Kj = c_3.
        ``c_0`` is zero because the plant integrates (it is dropped).
        """
        g = self.tf(Kdp, dp_hp, delay=delay)
        num = np.asarray(g.num[0][0], dtype=float)[::-1]  # ascending powers
        den = np.asarray(g.den[0][0], dtype=float)[::-1]
        c = _series_divide(den, num, order + 1)
        return c[1:]

    def ultimate(self, Kdp: float = 0.0, dp_hp: float = 0.0) -> tuple[float, float]:
        """(Ku mA/deg, wu rad/s): gain and frequency at the first -180 deg crossing of G."""
        g = self.tf(Kdp, dp_hp)
        w = np.logspace(0, 4, 20000)
        resp = g(1j * w)
        ph = np.unwrap(np.angle(resp))
        below = np.flatnonzero(ph <= -math.pi)
        if below.size == 0:
            raise ValueError("the plant's phase never reaches -180 deg below 1e4 rad/s")
        j = below[0]
        # refine by bisection on the phase
        lo, hi = w[j - 1], w[j]
        for _ in range(60):
            mid = math.sqrt(lo * hi)
            p = _phase_at(g, mid, ph[j - 1])
            if p > -math.pi:
                lo = mid
            else:
                hi = mid
        wu = math.sqrt(lo * hi)
        return 1.0 / abs(g(1j * wu)), wu


def _load_pressure_coordinates(lin) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(A, B, state names) of a linearisation with (pa, pb) replaced by P_L = pa - pb in bar and the
    pressure sum, which is dropped when nothing else depends on it (the usual case)."""
    names = list(lin.states)
    ia, ib = names.index("pa"), names.index("pb")
    n = len(names)
    # x_new = T x_old: p_load = (pa - pb) / BAR, p_sum = (pa + pb) / BAR
    T = np.eye(n)
    T[ia, :] = 0.0
    T[ib, :] = 0.0
    T[ia, ia], T[ia, ib] = 1.0 / BAR, -1.0 / BAR
    T[ib, ia], T[ib, ib] = 1.0 / BAR, 1.0 / BAR
    Ti = np.linalg.inv(T)
    A = T @ lin.A @ Ti
    B = T @ lin.B
    names[ia], names[ib] = "p_load", "p_sum"
    others = [j for j in range(n) if j != ib]
    scale = np.abs(A).max()
    if np.all(np.abs(A[others, ib]) <= 1e-12 * scale):  # nothing depends on the sum: drop it
        A = A[np.ix_(others, others)]
        B = B[others]
        names = [names[j] for j in others]
    return A, B, tuple(names)


def _phase_at(g, w, near):
    """Phase of g(jw) unwrapped to the branch nearest ``near``."""
    p = np.angle(g(1j * w))
    return p + 2 * math.pi * round((near - p) / (2 * math.pi))


def _series_divide(num_asc: np.ndarray, den_asc: np.ndarray, n: int) -> np.ndarray:
    """First n coefficients of num(s)/den(s) as a power series in s (ascending)."""
    num = np.zeros(n)
    num[: min(n, num_asc.size)] = num_asc[:n]
    den = np.zeros(n)
    den[: min(n, den_asc.size)] = den_asc[:n]
    if den[0] == 0.0:
        raise ValueError("series division: the denominator vanishes at s = 0")
    c = np.zeros(n)
    for k in range(n):
        c[k] = (num[k] - np.dot(den[1: k + 1], c[k - 1:: -1][:k])) / den[0]
    return c


def operating_flow_lpm(amplitude_deg: float, freq_hz: float, rig=None) -> float:
    """Mean |q_c| over a sine cycle, LPM: (2/pi) x peak actuator flow / Kq (no load).

    Examples
    --------
    >>> round(operating_flow_lpm(30.0, 3.0), 2)     # 22.65 LPM peak actuator flow at the design point
    8.14
    """
    from ehas_env.physics.rig import RigParams

    rig = rig or RigParams()
    w = 2.0 * math.pi * freq_hz
    q_peak = rig.area * rig.radius * math.radians(amplitude_deg) * w  # m^3/s
    return (2.0 / math.pi) * q_peak / math.sqrt(rig.supply / rig.rated_drop) / LPM
