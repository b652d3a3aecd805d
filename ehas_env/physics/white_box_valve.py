"""First-principles (white-box) model of the rig's two-stage flapper-nozzle servo valve.

The book's chapters 2 and 5.2 (after Merritt) build the valve from its parts:

    torque motor          T = Kt i
    armature / flapper    Ja theta'' + Ba theta' + Kf theta = T - Kw x_v - r F_n + ...
    flapper at nozzles    x_f = r theta
    nozzle-flapper flow   Q_p = K2 x_f - Kc P_p            (pilot stage)
    spool                 A_v x_v' = Q_p                    (spool mass neglected)
    spool forces          A_v P_p = F_ss + F_tr             (steady and transient flow forces)
    feedback wire         torque Kw x_v on the armature
    load flow             q_c = K3 x_v                      (at the rated 70 bar drop)

With the flow forces and the pilot's pressure-flow coefficient left out, the
steady state is the book's ``Q = K3 Kt i / Kw``: 28.2 LPM at 20 mA with
Table 5.1's numbers, whatever r, A_v, Ja and Ba are.  The book quotes about
26 LPM; that figure cannot come from this chain and these numbers (it would
need Kw = 17.3 in lb/in).  With the flow forces on the spool, the steady spool
force ``0.43 w dP x_v`` must be held by a pilot pressure, which the nozzle-
flapper only delivers with the flapper off centre, and the resulting torque
lowers the gain: 25.1 LPM at 20 mA with the assumptions below.

Parameters (SI inside; book units in the comments):

=========  ======================  ===========================================================
name       value                   source
=========  ======================  ===========================================================
Kt         0.0249 in lb/mA         book, Table 5.1: torque-motor gain
Kw         16 in lb/in             book: feedback-wire torque per spool displacement
Kf         92 in lb/rad            book: net armature (flexure) stiffness
K2         112 in^3/s/in           book: nozzle-flapper flow gain, taken at 70 bar pilot
                                   supply (assumed: the rated test's pressure), scaled
                                   with sqrt(Ps) at other pressures
K3         920 in^3/s/in           book: spool flow gain at the rated 70 bar drop
f_h        735 Hz                  book's omega_h; assumed to be the armature-flapper natural
                                   frequency sqrt(Kf/Ja), which fixes Ja = 4.87e-7 kg m^2
zeta_a     0.4                     assumed: armature damping ratio (Ba = 2 zeta_a Kf / w_h);
                                   flexure-pivot torque motors are lightly damped, 0.2-0.5
r          0.3 in (7.62 mm)        assumed: lever from the armature pivot to the nozzle axis
                                   (rig.md's "pivot to pole face"), typical of 20-40 LPM valves
d_spool    0.25 in (6.35 mm)       assumed: spool diameter, A_v = pi d^2 / 4 = 3.17e-5 m^2
x_f0       0.0015 in (38 um)       assumed: null nozzle-flapper gap, typical 25-50 um
Cdf        0.6                     assumed: nozzle discharge coefficient
Cd, Cv     0.61, 0.98; 69 deg jet  book: orifice and velocity coefficients, jet angle
                                   (steady flow force 2 Cd Cv cos 69 deg = 0.43)
rho        850 kg/m^3              assumed: MIL-H-5606 near 40 degC
L_d        10 mm                   assumed: damping length of the transient flow force
x_v max    1.0 mm                  assumed: spool stops, beyond the 0.79 mm rated stroke
=========  ======================  ===========================================================

Derived: port width ``w = K3 / (Cd sqrt(dp_n / rho)) = 10.7 mm`` (Merritt's
``Q_L = Cd w x_v sqrt((Ps - P_L) / rho)``); nozzle diameter
``D_N = K2 / (Cdf pi sqrt(Ps / rho)) = 0.42 mm`` and pilot pressure-flow
coefficient ``Kc = K2 x_f0 / Ps`` (double nozzle-flapper with fixed upstream
orifices, nozzle pressures Ps/2 at null).

Run ``python -m ehas_env.identification.white_box_comparison`` to write the grey-box comparison
(table, step response, Bode overlay) into ``results/white_box/``.

Examples
--------
>>> v = WhiteBoxValve()
>>> round(v.book_chain_flow_lpm(20.0), 1)           # the book's Q = K3 Kt i / Kw
28.2
>>> round(v.steady_flow_lpm(20.0, supply_bar=70), 1)  # with flow forces, on the 70 bar bench
25.1
>>> round(WhiteBoxValve(flow_forces=False).steady_flow_lpm(20.0), 2) == round(v.book_chain_flow_lpm(20.0), 2)
True
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ehas_env.physics.rig import BAR, LPM, RATED_VALVE_DROP, VALVE_K, VALVE_WN, VALVE_ZETA

IN_LB = 0.1129848290276167  # N m per inch pound-force
INCH = 0.0254  # m

#: the book's own figures at +-20 mA (rig.md): rated, grey-box, white-box flow
BOOK_RATED_LPM = 25.0
BOOK_GREY_LPM = 25.6
BOOK_WHITE_LPM = 26.0


@dataclass(frozen=True)
class WhiteBoxValve:
    """The valve's first-principles parameters (SI; see the module table for sources).

    ``flow_forces=False`` removes the steady and transient flow forces and the
    nozzle forces on the flapper: the book's simplified chain.
    """

    Kt: float = 0.0249 * IN_LB  # N m / mA
    Kw: float = 16.0 * IN_LB / INCH  # N m / m
    Kf: float = 92.0 * IN_LB  # N m / rad
    K2: float = 112.0 * INCH**2  # m^2/s at p_ref
    K3: float = 920.0 * INCH**2  # m^2/s at the rated drop
    f_h: float = 735.0  # Hz
    zeta_a: float = 0.4  # -
    r: float = 0.3 * INCH  # m
    d_spool: float = 0.25 * INCH  # m
    x_f0: float = 0.0015 * INCH  # m
    Cdf: float = 0.6  # -
    Cd: float = 0.61  # -
    Cv: float = 0.98  # -
    jet_angle_deg: float = 69.0  # deg
    rho: float = 850.0  # kg/m^3
    L_damp: float = 0.010  # m
    p_ref: float = 70.0 * BAR  # Pa, pilot supply at which K2 is given
    rated_drop: float = RATED_VALVE_DROP  # Pa
    xv_max: float = 1.0e-3  # m
    flow_forces: bool = True

    # -- derived --------------------------------------------------------------
    @property
    def w_h(self) -> float:
        return 2.0 * math.pi * self.f_h

    @property
    def Ja(self) -> float:
        """Armature-flapper inertia, kg m^2: Kf / w_h^2."""
        return self.Kf / self.w_h**2

    @property
    def Ba(self) -> float:
        """Armature damping, N m s/rad: 2 zeta_a Kf / w_h."""
        return 2.0 * self.zeta_a * self.Kf / self.w_h

    @property
    def A_v(self) -> float:
        return math.pi * self.d_spool**2 / 4.0

    @property
    def w(self) -> float:
        """Port width (area gradient) implied by K3, m."""
        return self.K3 / (self.Cd * math.sqrt(self.rated_drop / self.rho))

    @property
    def D_N(self) -> float:
        """Nozzle diameter implied by K2 at p_ref, m."""
        return self.K2 / (self.Cdf * math.pi * math.sqrt(self.p_ref / self.rho))

    @property
    def A_N(self) -> float:
        return math.pi * self.D_N**2 / 4.0

    @property
    def kff(self) -> float:
        """Steady flow-force coefficient 2 Cd Cv cos(jet) w, N/(m Pa): F = kff dP x_v."""
        return 2.0 * self.Cd * self.Cv * math.cos(math.radians(self.jet_angle_deg)) * self.w if self.flow_forces else 0.0

    @property
    def bff(self) -> float:
        """Transient flow-force coefficient Cd w L sqrt(2 rho), N s/(m sqrt(Pa)): B = bff sqrt(dP)."""
        return self.Cd * self.w * self.L_damp * math.sqrt(2.0 * self.rho) if self.flow_forces else 0.0

    @property
    def kjet(self) -> float:
        """Flapper jet negative-spring coefficient 8 pi Cdf^2 x_f0, m: k = kjet Ps (N/m)."""
        return 8.0 * math.pi * self.Cdf**2 * self.x_f0 if self.flow_forces else 0.0

    @property
    def A_N_eff(self) -> float:
        """Nozzle area on which the pilot pressure pushes the flapper (0 without flow forces)."""
        return self.A_N if self.flow_forces else 0.0

    @property
    def theta_max(self) -> float:
        """Armature angle at which the flapper touches a nozzle, rad."""
        return self.x_f0 / self.r

    def pilot(self, ps: float) -> tuple[float, float]:
        """(K2, Kc) of the nozzle-flapper stage at pilot supply ``ps`` (Pa)."""
        ps = max(ps, 1.0 * BAR)
        k2 = self.K2 * math.sqrt(ps / self.p_ref)
        return k2, k2 * self.x_f0 / ps

    # -- equations -------------------------------------------------------------
    def rhs(self, state, i_mA: float, ps: float, p_load: float = 0.0) -> tuple[float, float, float]:
        """(theta', omega', x_v') for state (theta, omega, x_v), current i (mA), supply ps and load P_L (Pa)."""
        th, om, xv = state
        d_th, d_om, dq = slot_rates(th, om, self.K3 * xv, i_mA, ps, p_load, self.kernel_slots())
        return d_th, d_om, dq / self.K3

    def steady_state(self, i_mA: float, ps: float, p_load: float = 0.0) -> tuple[float, float]:
        """(theta, x_v) at rest for a constant current (below the stops)."""
        k2, kc = self.pilot(ps)
        s = math.copysign(1.0, i_mA) if i_mA else 1.0
        dpv = max(ps - s * p_load, 0.0)
        kf_spring = self.kff * dpv
        # x_v' = 0: K2 r theta = Kc Kff x_v / A_v; pilot pressure Kff x_v / A_v
        th_per_xv = kc * kf_spring / (self.A_v * k2 * self.r)
        stiff = ((self.Kf - self.r**2 * self.kjet * ps) * th_per_xv + self.Kw
                 + self.r * self.A_N_eff * kf_spring / self.A_v)
        xv = self.Kt * i_mA / stiff
        return th_per_xv * xv, xv

    def steady_flow_lpm(self, i_mA: float, supply_bar: float = 70.0, load_bar: float = 0.0) -> float:
        """Steady flow, LPM, at ``supply_bar`` and load pressure ``load_bar`` (0: ports joined, the flow bench)."""
        ps, pl = supply_bar * BAR, load_bar * BAR
        _, xv = self.steady_state(i_mA, ps, pl)
        xv = min(max(xv, -self.xv_max), self.xv_max)
        dp = max(ps - math.copysign(1.0, xv) * pl, 0.0)
        return self.K3 * xv * math.sqrt(dp / self.rated_drop) / LPM

    def book_chain_flow_lpm(self, i_mA: float) -> float:
        """The book's closed form Q = K3 Kt i / Kw, LPM at the rated drop."""
        return self.K3 * self.Kt * i_mA / self.Kw / LPM

    def linearize(self, supply_bar: float = 70.0):
        """Small-signal (A, B, C) at null: states (theta, omega, x_v), input i (mA), output q_c (LPM at rated drop)."""
        ps = supply_bar * BAR
        k2, kc = self.pilot(ps)
        kf_spring, b_flow, av = self.kff * ps, self.bff * math.sqrt(ps), self.A_v
        den = av + kc * b_flow / av
        dxv = np.array([k2 * self.r / den, 0.0, -kc * kf_spring / (av * den)])  # d x_v' / d state
        dpp = (np.array([0.0, 0.0, kf_spring]) + b_flow * dxv) / av  # d p_pilot / d state
        dom = (np.array([-(self.Kf - self.r**2 * self.kjet * ps), -self.Ba, -self.Kw]) - self.r * self.A_N_eff * dpp) / self.Ja
        A = np.array([[0.0, 1.0, 0.0], dom, dxv])
        B = np.array([[0.0], [self.Kt / self.Ja], [0.0]])
        C = np.array([[0.0, 0.0, self.K3 / LPM]])
        return A, B, C

    def transfer_function(self, supply_bar: float = 70.0):
        """q_c / i, LPM/mA at the rated drop (``control.TransferFunction``), linearised at null."""
        import control

        A, B, C = self.linearize(supply_bar)
        return control.ss2tf(control.ss(A, B, C, 0.0))

    def kernel_slots(self) -> dict[str, float]:
        """The plant kernel's white-box parameter slots (``kernel.SLOTS``, names ``wb_*``)."""
        return {"wb_Kt": self.Kt, "wb_Kw": self.Kw, "wb_Kf": self.Kf, "wb_Ja": self.Ja, "wb_Ba": self.Ba,
                "wb_r": self.r, "wb_Av": self.A_v, "wb_K2": self.K2, "wb_p_ref": self.p_ref, "wb_K3": self.K3,
                "wb_xf0": self.x_f0, "wb_kff": self.kff, "wb_bff": self.bff, "wb_AN": self.A_N_eff,
                "wb_kjet": self.kjet, "wb_xv_max": self.xv_max}

    def simulate_bench(self, current_mA, dt: float = 1e-3, substeps: int = 10, supply_bar: float = 70.0):
        """Plain-Python RK4 of the valve on the flow bench (ports joined): flow (LPM) at each t_k.

        Slow (pure Python); the plant's kernel runs the same equations compiled
        (``Plant(valve="white_box").simulate_valve_test``).  Sample k holds the
        state at t_k, before the command of row k acts (zero-order hold).
        """
        cmd = np.asarray(current_mA, dtype=float)
        ps = supply_bar * BAR
        s = np.zeros(3)
        h = dt / substeps
        out = np.empty(cmd.size)
        scale = math.sqrt(ps / self.rated_drop) * self.K3 / LPM
        for k, i in enumerate(cmd):
            out[k] = s[2] * scale
            for _ in range(substeps):
                k1 = np.array(self.rhs(s, i, ps))
                k2 = np.array(self.rhs(s + 0.5 * h * k1, i, ps))
                k3 = np.array(self.rhs(s + 0.5 * h * k2, i, ps))
                k4 = np.array(self.rhs(s + h * k3, i, ps))
                s = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
                s = self.stops(s)
        return out

    def stops(self, s):
        """Flapper touching a nozzle, spool at its end stops: clip and zero the outward rate."""
        s = np.array(s, dtype=float)
        tm = self.theta_max
        if abs(s[0]) >= tm:
            s[0] = math.copysign(tm, s[0])
            if s[1] * s[0] > 0:
                s[1] = 0.0
        s[2] = min(max(s[2], -self.xv_max), self.xv_max)
        return s


def slot_rates(theta_a: float, omega_a: float, qc: float, i_mA: float, ps: float, p_load: float,
               p: dict) -> tuple[float, float, float]:
    """(theta_a', omega_a', q_c') from the kernel's ``wb_*`` slots: the plain-Python twin of
    ``kernel.white_box_rates`` (q_c = K3 x_v, m^3/s; pressures in Pa; i in mA).

    Armature torque balance, pilot flow into the spool ends, spool force balance with the
    steady and transient flow forces, as the module docstring writes them.
    """
    x_v = qc / p["wb_K3"]
    ps_pilot = max(ps, 1.0 * BAR)
    k2 = p["wb_K2"] * math.sqrt(ps_pilot / p["wb_p_ref"])   # nozzle-flapper flow gain
    kc = k2 * p["wb_xf0"] / ps_pilot                          # its pressure-flow coefficient
    dp_valve = max(ps - math.copysign(1.0, x_v) * p_load, 0.0)
    spring = p["wb_kff"] * dp_valve                           # steady flow force, N/m
    damping = p["wb_bff"] * math.sqrt(dp_valve)               # transient flow force, N s/m
    a_v = p["wb_Av"]
    # A_v x_v' = K2 r theta - Kc P_p  with  A_v P_p = spring x_v + damping x_v'
    x_v_dot = (k2 * p["wb_r"] * theta_a - kc * spring * x_v / a_v) / (a_v + kc * damping / a_v)
    p_pilot = (spring * x_v + damping * x_v_dot) / a_v
    torque = (p["wb_Kt"] * i_mA - (p["wb_Kf"] - p["wb_r"] ** 2 * p["wb_kjet"] * ps) * theta_a - p["wb_Ba"] * omega_a
              - p["wb_Kw"] * x_v - p["wb_r"] * p["wb_AN"] * p_pilot)
    return omega_a, torque / p["wb_Ja"], p["wb_K3"] * x_v_dot


def grey_box_tf():
    """The identified valve (book's chirp model as the rig parameters give it), LPM/mA."""
    import control

    return control.tf([VALVE_K * VALVE_WN**2], [1.0, 2.0 * VALVE_ZETA * VALVE_WN, VALVE_WN**2])


def bandwidth(sys_) -> tuple[float, float]:
    """(-3 dB frequency, -90 deg frequency) of a low-pass, rad/s."""
    w = np.geomspace(1.0, 1e5, 20000)
    num, den = np.atleast_1d(np.squeeze(sys_.num[0][0])), np.atleast_1d(np.squeeze(sys_.den[0][0]))
    g = np.polyval(num, 1j * w) / np.polyval(den, 1j * w)
    g0 = num[-1] / den[-1]
    mag = np.abs(g) / abs(g0)
    ph = np.degrees(np.unwrap(np.angle(g)))
    return float(w[np.argmax(mag < 1 / math.sqrt(2))]), float(w[np.argmax(ph < -90.0)])
