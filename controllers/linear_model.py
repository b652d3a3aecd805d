"""The plant linearised at an operating point, as python-control transfer functions.

Valve (identified 2nd order) x flow gain at the operating point x actuator /
crank / inertia with chamber compliance::

    q_c'' = wn^2 (K i - q_c) - 2 zeta wn q_c'                 (valve, K in m^3/s per mA)
    C P_L' = Kq q_c - Kce P_L - a omega                       (chambers, C = 1/(beta (1/V_A + 1/V_B)))
    I_eff omega' = a P_L - B omega                            (crank and discs)

with, at the operating point (crank angle theta0, load pressure P_L0, valve flow q_c0):

* ``Kq = sqrt((Ps - P_L0) / dp_n)``: the orifice law's flow gain (sqrt(220/70) = 1.773 at P_L0 = 0);
* ``Kc = |q_c0| / (2 sqrt(dp_n (Ps - P_L0)))``: its flow-pressure coefficient - zero at null
  flow for the critically lapped valve, which is why the hydraulic mode is barely damped there;
* ``Kce = Kc + C_leak + C_ext / 2`` (Merritt's total flow-pressure coefficient);
* ``a = A r cos(theta0)`` (m^3/rad), ``I_eff = I + m_piston (r cos theta0)^2``, ``B = b (r cos theta0)^2``.

The input is the valve current in mA, outputs theta in deg and P_L in bar.  The
controller's sample-and-hold (half a period) and any transport delay are a
Pade approximation at the input.  The controller's load-pressure feedback
(``Kdp``, static or high-passed) can be closed around the plant, giving the
plant the PI sees.

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

from ehas_env.physics.effects.base import effect_value
import numpy as np

from ehas_env.physics.rig import BAR, LPM


class LinearPlant:
    """Small-signal model of the rig around an operating point.

    Parameters
    ----------
    plant : ehas_env.simulation.plant.Plant, optional
        Plant whose parameter slots (effects included) are linearised; default
        ``Plant(disc_sets)``.
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
        if plant is None:
            from ehas_env.simulation.plant import Plant

            plant = Plant(disc_sets=disc_sets)
        s = plant.slots()  # supply droop, backlash, deadband and dry friction have no small-signal term here
        self.disc_sets = plant.rig.disc_sets
        self.slots = s
        self.theta0 = math.radians(theta_deg)
        self.load0 = load_bar * BAR
        self.flow0 = abs(flow_lpm) * LPM
        self.rate_hz = float(rate_hz)
        self.pade_order = int(pade_order)
        if not abs(self.load0) < s["supply"]:
            raise ValueError(f"load_bar must lie within +-{s['supply'] / BAR:g} bar (the supply), got {load_bar!r}")
        r, A = s["radius"], s["area"]
        c = math.cos(self.theta0)
        x0 = r * math.sin(self.theta0)
        va, vb = A * s["half_stroke"] + s["dead_volume"] + A * x0, A * s["half_stroke"] + s["dead_volume"] - A * x0
        self.C = 1.0 / (s["beta"] * (1.0 / va + 1.0 / vb))  # m^3/Pa
        self.Kq = math.sqrt((s["supply"] - abs(self.load0)) / s["rated_drop"])  # -
        self.Kc = self.flow0 / (2.0 * math.sqrt(s["rated_drop"] * (s["supply"] - abs(self.load0))))  # m^3/s/Pa
        self.Kce = self.Kc + effect_value(s, "internal_leakage", "C_leak") + 0.5 * effect_value(s, "external_leakage", "C_ext")
        self.a = A * r * c  # m^3 per rad
        self.I = s["inertia"] + effect_value(s, "piston_mass", "m") * (r * c) ** 2  # kg m^2
        self.B = effect_value(s, "viscous_friction", "b") * (r * c) ** 2  # N m s/rad
        self.delay = 0.5 / self.rate_hz + s["tau"]  # s: zero-order hold + transport delay

    # -- numbers ---------------------------------------------------------------
    @property
    def velocity_gain(self) -> float:
        """Steady crank rate per valve current, deg/s per mA (no load, no leakage)."""
        return math.degrees(self.slots["K"] * self.Kq / self.a)

    @property
    def hydraulic_wn(self) -> float:
        """Hydraulic natural frequency, rad/s: sqrt(a^2 / (C I))."""
        return math.sqrt(self.a**2 / (self.C * self.I))

    @property
    def hydraulic_zeta(self) -> float:
        """Damping ratio of the hydraulic mode from Kce and B (no valve dynamics)."""
        return (self.Kce * self.I + self.B * self.C) / (2.0 * math.sqrt(self.C * self.I) * math.sqrt(self.a**2 + self.Kce * self.B))

    # -- models ----------------------------------------------------------------
    def state_space(self, Kdp: float = 0.0, dp_hp: float = 0.0) -> control.StateSpace:
        """Input current u (mA) -> outputs (theta deg, P_L bar), pressure feedback closed, no delay.

        States: q_c (m^3/s), q_c' , P_L (bar), theta (rad), omega (rad/s)[, low-passed P_L (bar)].
        """
        s = self.slots
        wn, z, Kv = s["wn"], s["zeta"], s["K"]
        A = np.zeros((5, 5))
        Bm = np.zeros((5, 1))
        A[0, 1] = 1.0
        A[1, 0] = -wn * wn
        A[1, 1] = -2.0 * z * wn
        Bm[1, 0] = wn * wn * Kv
        # P_L in bar: C * BAR * P_L' = Kq q_c - Kce BAR P_L - a omega
        A[2, 0] = self.Kq / (self.C * BAR)
        A[2, 2] = -self.Kce / self.C
        A[2, 4] = -self.a / (self.C * BAR)
        A[3, 4] = 1.0
        A[4, 2] = self.a * BAR / self.I
        A[4, 4] = -self.B / self.I
        Cm = np.zeros((2, 5))
        Cm[0, 3] = math.degrees(1.0)
        Cm[1, 2] = 1.0
        if Kdp != 0.0:
            if dp_hp > 0.0:
                # i = u - Kdp (P_L - z), z' = dp_hp (P_L - z): feed back the high-passed pressure
                A = np.pad(A, ((0, 1), (0, 1)))
                Bm = np.pad(Bm, ((0, 1), (0, 0)))
                Cm = np.pad(Cm, ((0, 0), (0, 1)))
                A[5, 2] = dp_hp
                A[5, 5] = -dp_hp
                A[1, 2] -= wn * wn * Kv * Kdp
                A[1, 5] += wn * wn * Kv * Kdp
            else:
                A[1, 2] -= wn * wn * Kv * Kdp
        return control.ss(A, Bm, Cm, np.zeros((2, 1)))

    def delay_tf(self) -> control.TransferFunction:
        """Pade approximation of the input delay (zero-order hold + transport)."""
        if self.pade_order <= 0 or self.delay <= 0:
            return control.tf([1.0], [1.0])
        num, den = control.pade(self.delay, self.pade_order)
        return control.tf(num, den)

    def _polys(self, Kdp: float, dp_hp: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(theta numerator, P_L numerator, common denominator), descending powers, theta deg, P_L bar.

        With V = K wn^2 / Vd the valve, M = (C s + Kce)(I s + B) + a^2 and H the pressure
        feedback's filter (1, or s / (s + dp_hp)), closing i = u - Kdp H P_L gives
        theta/u = Kq a K wn^2 / (s [M Vd + Kdp H Kq K wn^2 (I s + B) / BAR]) (rad), P_L/u alike.
        """
        s = self.slots
        vn = s["K"] * s["wn"] ** 2
        vd = np.array([1.0, 2.0 * s["zeta"] * s["wn"], s["wn"] ** 2])
        load = np.array([self.I, self.B])  # I s + B
        m = np.polyadd(np.polymul([self.C, self.Kce], load), [self.a**2])
        hp = np.array([1.0, dp_hp]) if (Kdp != 0.0 and dp_hp > 0.0) else np.array([1.0])
        hn = np.array([1.0, 0.0]) if (Kdp != 0.0 and dp_hp > 0.0) else np.array([1.0])
        core = np.polymul(np.polymul(m, vd), hp)
        if Kdp != 0.0:
            core = np.polyadd(core, Kdp * self.Kq * vn / BAR * np.polymul(hn, load))
        den = np.polymul(core, [1.0, 0.0])
        num_theta = math.degrees(1.0) * self.Kq * self.a * vn * hp
        num_load = self.Kq * vn / BAR * np.polymul(np.polymul(load, hp), [1.0, 0.0])
        return num_theta, num_load, den

    def tf(self, Kdp: float = 0.0, dp_hp: float = 0.0, delay: bool = True) -> control.TransferFunction:
        """theta (deg) / u (mA), the plant the position loop sees (with pressure feedback ``Kdp``)."""
        num, _, den = self._polys(Kdp, dp_hp)
        g = control.tf(num, den)
        return g * self.delay_tf() if delay else g

    def tf_load(self, Kdp: float = 0.0, dp_hp: float = 0.0, delay: bool = True) -> control.TransferFunction:
        """P_L (bar) / u (mA)."""
        _, num, den = self._polys(Kdp, dp_hp)
        g = control.tf(num, den)
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
