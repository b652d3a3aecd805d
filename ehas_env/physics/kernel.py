"""Fixed-step RK4 kernel of the plant (numba), shared by every simulator.

The plant is one general model whose optional physical terms are switched on by
the effects library (``ehas_env.physics.effects``): each effect writes its parameters
into slots of a flat float64 parameter vector ``P`` (layout :data:`SLOTS`), with
neutral values (zero friction, zero leakage, zero delay, ...) when it is off.
One compiled kernel therefore serves every combination of effects and a batch
of plants with different parameters can be stepped in one loop.

Units are SI throughout (valve current in mA, as the identified model is).

State vector (:data:`STATE_NAMES`)::

    0 theta   crank angle, rad
    1 omega   crank angular velocity, rad/s
    2 qc      valve no-load flow at the rated drop, m^3/s
    3 qc_dot  its derivative, m^3/s^2
    4 pa      chamber A pressure, Pa
    5 pb      chamber B pressure, Pa
    6 ps      supply pressure, Pa (a state only with supply droop)
    7 xp      piston position, m (differs from r sin(theta) only with backlash)
    8 vp      piston velocity, m/s
    9 theta_a armature (torque-motor) rotation, rad    } white-box valve only
   10 omega_a its rate, rad/s                          } (valve_model = 1)

The valve is the identified grey box (slot ``valve_model`` = 0, states 2-3) or
the first-principles white box of :mod:`ehas_env.physics.white_box_valve`
(``valve_model`` = 1): then state 2 holds q_c = K3 x_v (the spool position in
flow units, so the orifice law and the outputs are shared), state 3 stays 0 and
states 9-10 carry the armature.

A plain-Python twin of :func:`derivatives` lives in ``ehas_env.physics.reference_rhs``
and the tests hold the two together.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

STATE_NAMES = ("theta", "omega", "qc", "qc_dot", "pa", "pb", "ps", "xp", "vp", "theta_a", "omega_a")
N_STATES = len(STATE_NAMES)

# Parameter-vector slots.  Base slots come from RigParams; the rest are the
# general model's optional terms, neutral by default and set by effects.
SLOTS = (
    "inertia",  # kg m^2
    "radius",  # m
    "area",  # m^2
    "half_stroke",  # m
    "supply",  # Pa, nominal supply (relief setting with droop)
    "rated_drop",  # Pa
    "beta",  # Pa
    "dead_volume",  # m^3
    "K",  # m^3/s per mA (converted from LPM/mA)
    "wn",  # rad/s
    "zeta",  # -
    "i_max",  # mA
    "deadband",  # mA, valve_deadband
    "i_bias",  # mA, valve_null_bias
    "tau",  # s, transport_delay
    "Fc",  # N, coulomb_friction
    "Fc_s",  # N, stribeck_friction Coulomb level
    "Fs_s",  # N, stribeck_friction static level
    "vs_s",  # m/s, stribeck_friction Stribeck velocity
    "b",  # N s/m, viscous_friction
    "v_tanh",  # m/s, velocity scale of the friction sign function (spec: 1 mm/s)
    "C_leak",  # m^3/s/Pa, internal_leakage
    "C_ext",  # m^3/s/Pa, external_leakage
    "droop",  # 1.0 when supply_droop is on
    "Q_pump",  # m^3/s
    "V_acc",  # m^3
    "p0",  # Pa, accumulator precharge
    "V_line",  # m^3, pressure-line volume between pump and valve
    "m_piston",  # kg, piston_mass
    "delta",  # m, backlash half-play
    "k_joint",  # N/m, joint contact stiffness (backlash)
    "c_joint",  # N s/m, joint contact damping (backlash)
    "m_backlash",  # kg, minimum piston mass used with backlash
    # white-box valve (ehas_env.physics.white_box_valve; appended, so earlier indices never move)
    "valve_model",  # 0: identified grey box (K, wn, zeta), 1: white box
    "wb_Kt",  # N m/mA, torque-motor gain
    "wb_Kw",  # N m/m, feedback-wire torque per spool displacement
    "wb_Kf",  # N m/rad, armature stiffness
    "wb_Ja",  # kg m^2, armature-flapper inertia
    "wb_Ba",  # N m s/rad, armature damping
    "wb_r",  # m, lever from the armature pivot to the nozzles
    "wb_Av",  # m^2, spool end area
    "wb_K2",  # m^2/s, nozzle-flapper flow gain at wb_p_ref
    "wb_p_ref",  # Pa, pilot supply at which wb_K2 holds
    "wb_K3",  # m^2/s, spool flow gain at the rated drop
    "wb_xf0",  # m, null nozzle-flapper gap
    "wb_kff",  # m, steady flow force coefficient 0.43 w (F = kff dP x_v)
    "wb_bff",  # N s/(m sqrt(Pa)), transient flow force coefficient Cd w L sqrt(2 rho)
    "wb_AN",  # m^2, nozzle area (pilot pressure force on the flapper)
    "wb_kjet",  # m, flapper jet negative spring 8 pi Cdf^2 x_f0 (k = kjet Ps)
    "wb_xv_max",  # m, spool stops
)
IDX = {name: k for k, name in enumerate(SLOTS)}
N_SLOTS = len(SLOTS)

# numba sees module-level ints as compile-time constants
I_INERTIA, I_RADIUS, I_AREA, I_HALF_STROKE, I_SUPPLY, I_DROP, I_BETA, I_VDEAD = range(8)
I_K, I_WN, I_ZETA, I_IMAX, I_DEADBAND, I_BIAS, I_TAU = range(8, 15)
I_FC, I_FC_S, I_FS_S, I_VS_S, I_B, I_VTANH, I_CLEAK, I_CEXT = range(15, 23)
I_DROOP, I_QPUMP, I_VACC, I_P0, I_VLINE, I_MP, I_DELTA, I_KJ, I_CJ, I_MBL = range(23, 33)
I_VALVE_MODEL, I_WB_KT, I_WB_KW, I_WB_KF, I_WB_JA, I_WB_BA, I_WB_R, I_WB_AV = range(33, 41)
I_WB_K2, I_WB_PREF, I_WB_K3, I_WB_XF0, I_WB_KFF, I_WB_BFF, I_WB_AN, I_WB_KJET, I_WB_XVMAX = range(41, 50)
assert N_SLOTS == 50
assert SLOTS[I_VALVE_MODEL] == "valve_model" and SLOTS[I_WB_XVMAX] == "wb_xv_max"
WHITE_BOX = 1.0  # valve_model value of the white-box valve

# Output channels written by the simulators (SI)
# theta/omega are what the LVDT sees (piston position through asin(x/r));
# theta_sensed is the controller's reading of it in degrees (noise, gain error, ADC).
OUT_NAMES = ("theta", "omega", "flow_a", "pa", "pb", "ps", "force", "theta_crank", "current", "stroke_end", "theta_sensed")
N_OUT = len(OUT_NAMES)
O_THETA, O_OMEGA, O_FLOW, O_PA, O_PB, O_PS, O_FORCE, O_CRANK, O_CURRENT, O_STROKE, O_SENSED = range(N_OUT)


@njit(cache=True, inline="always")
def signed_root(z):
    """sign(z) * sqrt(|z|): the orifice law's root of a signed pressure ratio."""
    return math.sqrt(z) if z >= 0.0 else -math.sqrt(-z)


@njit(cache=True)
def valve_current(i_cmd, P):
    """Current that reaches the valve: amplifier limit, then deadband and null bias, mA."""
    i_max = P[I_IMAX]
    i = min(max(i_cmd, -i_max), i_max)
    d = P[I_DEADBAND]
    if d > 0.0:
        a = abs(i) - d
        i = math.copysign(a, i) if a > 0.0 else 0.0
    return i + P[I_BIAS]


@njit(cache=True)
def land_flows(qc, pa, pb, ps, P):
    """Per-land orifice law: (Q_A into A, Q_B into B, Q_S drawn from supply), m^3/s."""
    half = 0.5 * P[I_DROP]
    if qc >= 0.0:
        qs = qc * signed_root((ps - pa) / half)
        return qs, -qc * signed_root(pb / half), qs
    qs = -qc * signed_root((ps - pb) / half)
    return qc * signed_root(pa / half), qs, qs


@njit(cache=True)
def friction_force(v, P):
    """Seal friction on the piston (a force opposing v), N."""
    if P[I_FC] == 0.0 and P[I_FC_S] == 0.0 and P[I_FS_S] == 0.0:
        # no dry friction: skip the sign function, the hot path's costliest call (same result)
        return -(P[I_B] * v)
    vt = P[I_VTANH]
    sgn = math.tanh(v / vt)
    f = P[I_FC] * sgn + P[I_B] * v
    if P[I_FC_S] > 0.0 or P[I_FS_S] > 0.0:
        vs = P[I_VS_S]
        f += (P[I_FC_S] + (P[I_FS_S] - P[I_FC_S]) * math.exp(-((v / vs) ** 2))) * sgn
    return -f


@njit(cache=True, inline="always")
def valve_accel(qc, qcd, i_valve, P):
    """The identified valve: q_c'' = wn^2 (K i - q_c) - 2 zeta wn q_c' (q_c in m^3/s)."""
    wn = P[I_WN]
    return wn * wn * (P[I_K] * i_valve - qc) - 2.0 * P[I_ZETA] * wn * qcd


@njit(cache=True, inline="always")
def white_box_rates(s, i_valve, ps, p_load, P):
    """(theta_a', omega_a', q_c') of the white-box valve; see ehas_env.physics.white_box_valve.

    Armature: Ja th'' = Kt i - (Kf - r^2 kjet Ps) th - Ba th' - Kw x_v - r A_N P_p;
    pilot flow K2 r th - Kc P_p fills the spool ends (A_v x_v'), spool force
    A_v P_p = kff dP x_v + bff sqrt(dP) x_v' (flow forces), dP = Ps - sign(x_v) P_L;
    K2 grows with sqrt(Ps), Kc = K2 x_f0 / Ps.  State 2 holds q_c = K3 x_v.
    """
    k3 = P[I_WB_K3]
    xv = s[2] / k3
    th = s[9]
    ps_pilot = max(ps, 1.0e5)  # the pilot law needs a supply; 1 bar floor
    k2 = P[I_WB_K2] * math.sqrt(ps_pilot / P[I_WB_PREF])
    kc = k2 * P[I_WB_XF0] / ps_pilot
    dpv = ps - math.copysign(1.0, xv) * p_load
    if dpv < 0.0:
        dpv = 0.0
    k_flow = P[I_WB_KFF] * dpv
    b_flow = P[I_WB_BFF] * math.sqrt(dpv)
    av, r = P[I_WB_AV], P[I_WB_R]
    xv_dot = (k2 * r * th - kc * k_flow * xv / av) / (av + kc * b_flow / av)
    p_pilot = (k_flow * xv + b_flow * xv_dot) / av
    torque = (P[I_WB_KT] * i_valve - (P[I_WB_KF] - r * r * P[I_WB_KJET] * ps) * th - P[I_WB_BA] * s[10]
              - P[I_WB_KW] * xv - r * P[I_WB_AN] * p_pilot)
    return s[10], torque / P[I_WB_JA], k3 * xv_dot


@njit(cache=True, inline="always")
def spool_stops(s, P):
    """Spool at its end stops for |q_c| >= i_max K: clip q_c, zero q_c' outward.

    White box: the spool stops at +-wb_xv_max and the flapper stops on a nozzle
    (|theta_a| = x_f0 / r, outward rate zeroed).
    """
    if P[I_VALVE_MODEL] == WHITE_BOX:
        qw = P[I_WB_K3] * P[I_WB_XVMAX]
        s[3] = 0.0
        if s[2] > qw:
            s[2] = qw
        elif s[2] < -qw:
            s[2] = -qw
        tm = P[I_WB_XF0] / P[I_WB_R]
        if s[9] >= tm:
            s[9] = tm
            if s[10] > 0.0:
                s[10] = 0.0
        elif s[9] <= -tm:
            s[9] = -tm
            if s[10] < 0.0:
                s[10] = 0.0
        return
    qmax = P[I_K] * P[I_IMAX]
    if s[2] >= qmax:
        s[2] = qmax
        if s[3] > 0.0:
            s[3] = 0.0
    elif s[2] <= -qmax:
        s[2] = -qmax
        if s[3] < 0.0:
            s[3] = 0.0


@njit(cache=True)
def derivatives(s, i_valve, P, ds):
    """Right-hand side ds = f(s) for the valve current ``i_valve`` (mA, after deadband/bias)."""
    theta, omega, qc, qcd, pa, pb, ps, xp, vp = s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8]
    r, A = P[I_RADIUS], P[I_AREA]
    c, sn = math.cos(theta), math.sin(theta)
    if P[I_VALVE_MODEL] == WHITE_BOX:
        ds[9], ds[10], ds[2] = white_box_rates(s, i_valve, ps, pa - pb, P)
        ds[3] = 0.0
    else:
        ds[2] = qcd
        ds[3] = valve_accel(qc, qcd, i_valve, P)
        ds[9] = 0.0
        ds[10] = 0.0

    qa_in, qb_in, q_supply = land_flows(qc, pa, pb, ps, P)
    leak = P[I_CLEAK] * (pa - pb)
    qa_in -= leak + P[I_CEXT] * pa
    qb_in += leak - P[I_CEXT] * pb

    f_h = A * (pa - pb)
    if P[I_DELTA] > 0.0:
        # backlash: piston and crank are separate bodies joined through the play
        x, xd = xp, vp
        gap = xp - r * sn
        gap_d = vp - r * c * omega
        delta = P[I_DELTA]
        f_joint = 0.0
        if gap > delta:
            f_joint = P[I_KJ] * (gap - delta) + P[I_CJ] * gap_d
        elif gap < -delta:
            f_joint = P[I_KJ] * (gap + delta) + P[I_CJ] * gap_d
        m = max(P[I_MP], P[I_MBL])
        ds[7] = vp
        ds[8] = (f_h + friction_force(vp, P) - f_joint) / m
        ds[0] = omega
        ds[1] = f_joint * r * c / P[I_INERTIA]
    else:
        x, xd = r * sn, r * c * omega
        m = P[I_MP]
        f = f_h + friction_force(xd, P)
        ds[0] = omega
        ds[1] = (f * r * c + m * r * r * sn * c * omega * omega) / (P[I_INERTIA] + m * r * r * c * c)
        ds[7] = xd
        ds[8] = 0.0  # slaved to the crank; set after each step

    v0 = A * P[I_HALF_STROKE] + P[I_VDEAD]
    beta = P[I_BETA]
    ds[4] = beta / (v0 + A * x) * (qa_in - A * xd)
    ds[5] = beta / (v0 - A * x) * (qb_in + A * xd)

    if P[I_DROOP] > 0.0:
        # isothermal gas accumulator plus line volume, fed by the pump, drained by the valve
        cap = P[I_VLINE] / beta
        if ps > P[I_P0]:
            cap += P[I_VACC] * P[I_P0] / (ps * ps)
        dps = (P[I_QPUMP] - q_supply) / cap
        if ps >= P[I_SUPPLY] and dps > 0.0:
            dps = 0.0  # relief valve holds the setting
        ds[6] = dps
    else:
        ds[6] = 0.0


@njit(cache=True)
def project(s, P):
    """Hard limits after a step: spool end stops, pressure range, stroke ends.

    Returns True when the piston sits at a stroke end.
    """
    spool_stops(s, P)
    ps_cap = P[I_SUPPLY]
    if s[6] > ps_cap:
        s[6] = ps_cap
    if s[6] < 0.0:
        s[6] = 0.0
    ps = s[6]
    for j in (4, 5):
        if s[j] < 0.0:
            s[j] = 0.0
        elif s[j] > ps:
            s[j] = ps
    r = P[I_RADIUS]
    hit = False
    if P[I_DELTA] > 0.0:
        if abs(s[7]) >= P[I_HALF_STROKE]:
            hit = True
            s[7] = math.copysign(P[I_HALF_STROKE], s[7])
            if s[8] * s[7] > 0.0:
                s[8] = 0.0
    else:
        ratio = min(P[I_HALF_STROKE] / r, 1.0)
        if abs(s[0]) >= ratio:  # asin(x) >= x: only past this can the crank reach a stroke end (saves the asin)
            th_end = math.asin(ratio)
            if abs(s[0]) >= th_end:
                hit = True
                s[0] = math.copysign(th_end, s[0])
                if s[1] * s[0] > 0.0:
                    s[1] = 0.0
        s[7] = r * math.sin(s[0])
        s[8] = r * math.cos(s[0]) * s[1]
    return hit


@njit(cache=True)
def rk4_substep(s, i_valve, P, h, k1, k2, k3, k4, tmp):
    """One classical RK4 step of length h (s updated in place)."""
    n = N_STATES  # a compile-time constant, so the loops unroll (s always has N_STATES entries)
    derivatives(s, i_valve, P, k1)
    for j in range(n):
        tmp[j] = s[j] + 0.5 * h * k1[j]
    derivatives(tmp, i_valve, P, k2)
    for j in range(n):
        tmp[j] = s[j] + 0.5 * h * k2[j]
    derivatives(tmp, i_valve, P, k3)
    for j in range(n):
        tmp[j] = s[j] + h * k3[j]
    derivatives(tmp, i_valve, P, k4)
    for j in range(n):
        s[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@njit(cache=True)
def delayed_command(hist, k, j, nsub, dt, tau, i_initial):
    """Command applied at sub-step j of period k with transport delay tau.

    ``hist[m % len(hist)]`` holds the command issued at step m (zero-order hold).
    """
    if tau <= 0.0:
        return hist[k % hist.shape[0]]
    t = (k + j / nsub) * dt - tau
    m = int(math.floor(t / dt + 1e-9))
    if m < 0:
        return i_initial
    return hist[m % hist.shape[0]]


@njit(cache=True)
def advance(s, P, hist, k, dt, nsub, i_initial, k1, k2, k3, k4, tmp):
    """Integrate one control period [k dt, (k+1) dt] with nsub RK4 sub-steps.

    Returns True if a stroke end was touched during the period.
    """
    h = dt / nsub
    tau = P[I_TAU]
    hit = False
    for j in range(nsub):
        i_cmd = delayed_command(hist, k, j, nsub, dt, tau, i_initial)
        rk4_substep(s, valve_current(i_cmd, P), P, h, k1, k2, k3, k4, tmp)
        if project(s, P):
            hit = True
    return hit


@njit(cache=True)
def measure(s, P, out):
    """Write the physical outputs of state s into out[0:8] (SI, noise-free)."""
    r = P[I_RADIUS]
    ratio = min(max(s[7] / r, -1.0), 1.0)
    th = math.asin(ratio)
    out[O_THETA] = th
    out[O_OMEGA] = s[8] / (r * math.cos(th))
    qa, _, _ = land_flows(s[2], s[4], s[5], s[6], P)
    out[O_FLOW] = qa
    out[O_PA] = s[4]
    out[O_PB] = s[5]
    out[O_PS] = s[6]
    out[O_FORCE] = P[I_AREA] * (s[4] - s[5])
    out[O_CRANK] = s[0]


def history_length(tau_max: float, dt: float) -> int:
    """Ring-buffer length that covers a delay of tau_max at control period dt."""
    return int(math.ceil(max(tau_max, 0.0) / dt)) + 2


@njit(cache=True)
def run_open_loop(s, P, cmd, dt, nsub, hist, out):
    """Simulate from a command current sequence (mA, zero-order hold at dt).

    Row k of ``out`` holds the outputs at t_k and the command issued then.
    """
    k1 = np.empty_like(s)
    k2 = np.empty_like(s)
    k3 = np.empty_like(s)
    k4 = np.empty_like(s)
    tmp = np.empty_like(s)
    n = cmd.shape[0]
    hist[:] = 0.0
    for k in range(n):
        measure(s, P, out[k])
        out[k, O_CURRENT] = cmd[k]
        hist[k % hist.shape[0]] = cmd[k]
        hit = advance(s, P, hist, k, dt, nsub, 0.0, k1, k2, k3, k4, tmp)
        out[k, O_STROKE] = 1.0 if hit else 0.0


@njit(cache=True)
def reference_point(ref, t):
    """theta_ref and its first three derivatives (deg, deg/s^k) at t.

    ref = (amplitude deg, f Hz, phase rad[, ramp s]).  With a ramp time T > 0
    the amplitude fades in with the smoothstep 10x^3 - 15x^4 + 6x^5, x = t/T, so
    the command starts at rest: a rig operator never steps a heavy inertia to
    full sine velocity at t = 0.
    """
    amp, w, ph = ref[0], 2.0 * math.pi * ref[1], ref[2]
    T = ref[3] if ref.shape[0] > 3 else 0.0
    s, s1, s2, s3 = 1.0, 0.0, 0.0, 0.0
    if T > 0.0 and t < T:
        x = max(t, 0.0) / T
        s = x * x * x * (10.0 + x * (-15.0 + 6.0 * x))
        s1 = 30.0 * x * x * (1.0 - x) * (1.0 - x) / T
        s2 = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / (T * T)
        s3 = (60.0 - 360.0 * x + 360.0 * x * x) / (T * T * T)
    sn, cs = math.sin(w * t + ph), math.cos(w * t + ph)
    r = amp * s * sn
    rd = amp * (s1 * sn + s * w * cs)
    rdd = amp * (s2 * sn + 2.0 * s1 * w * cs - s * w * w * sn)
    rddd = amp * (s3 * sn + 3.0 * s2 * w * cs - 3.0 * s1 * w * w * sn - s * w * w * w * cs)
    return r, rd, rdd, rddd


@njit(cache=True)
def quantize(x, lsb):
    if lsb <= 0.0:
        return x
    return lsb * math.floor(x / lsb + 0.5)


@njit(cache=True, inline="always")
def rig_control_law(gains, e, rd, rdd, rddd, dp, dt, u_max, mem):
    """The rig controller's output for the error e (deg), mA, clipped to +-u_max.

    gains as in :func:`run_rig_controller`; rd, rdd, rddd: the reference's
    derivatives; dp: load pressure, bar; mem = [integral of e, low-passed dp],
    updated in place.  The integral stops while the output is clamped and the
    error would drive it further (anti-windup).
    """
    kp, ki, kv, ka, kj, kdp, whp = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5], gains[6]
    if whp > 0.0:
        # first-order high-pass: feed back only the pressure's changes
        mem[1] += dt * whp * (dp - mem[1])
        dp_fb = dp - mem[1]
    else:
        dp_fb = dp
    u_ff = kv * rd + ka * rdd + kj * rddd - kdp * dp_fb
    u = kp * e + ki * (mem[0] + e * dt) + u_ff
    if (u < u_max and u > -u_max) or (u >= u_max and e < 0.0) or (u <= -u_max and e > 0.0):
        mem[0] += e * dt
    u = kp * e + ki * mem[0] + u_ff
    return min(max(u, -u_max), u_max)


@njit(cache=True)
def run_rig_controller(s, P, gains, ref, dt, nsub, hist, theta_noise, sensor, out):
    """Closed loop with the rig's PI + velocity/acceleration feed-forward controller.

    gains = (Kp mA/deg, Ki mA/(deg s), Kv mA/(deg/s), Ka mA/(deg/s^2), Kj mA/(deg/s^3),
    Kdp mA/bar, dp_hp rad/s); ref = (amplitude deg, frequency Hz, phase rad[, ramp s]),
    see :func:`reference_point`;
    sensor = (theta ADC lsb deg, DAC lsb mA, LVDT gain error, i_max of the
    controller output mA).  The controller runs at 1/dt with zero-order hold,
    clamps its output and stops integrating while clamped (anti-windup).  A
    pressure-feedback term ``-Kdp * (high-passed) load pressure`` is optional
    (Kdp = 0 switches it off; dp_hp = 0 makes it static).
    """
    k1 = np.empty_like(s)
    k2 = np.empty_like(s)
    k3 = np.empty_like(s)
    k4 = np.empty_like(s)
    tmp = np.empty_like(s)
    n = out.shape[0]
    adc, dac, gain_err, u_max = sensor[0], sensor[1], sensor[2], sensor[3]
    mem = np.zeros(2)
    hist[:] = 0.0
    for k in range(n):
        measure(s, P, out[k])
        r, rd, rdd, rddd = reference_point(ref, k * dt)
        th = math.degrees(out[k, O_THETA]) * (1.0 + gain_err) + theta_noise[k]
        th = quantize(th, adc)
        out[k, O_SENSED] = th
        u = rig_control_law(gains, r - th, rd, rdd, rddd, (s[4] - s[5]) * 1e-5, dt, u_max, mem)
        u = quantize(u, dac)
        out[k, O_CURRENT] = u
        hist[k % hist.shape[0]] = u
        hit = advance(s, P, hist, k, dt, nsub, 0.0, k1, k2, k3, k4, tmp)
        out[k, O_STROKE] = 1.0 if hit else 0.0


@njit(cache=True)
def run_valve_test(P, cmd, dt, nsub, supply, hist, out):
    """Valve alone, control ports joined through the flow meter (rated test).

    Two lands in series share the supply drop, so the metered flow is
    q_c * sqrt(supply / rated_drop).  out[k] = (flow m^3/s, q_c m^3/s, valve current mA).
    The valve uses the same state slots 2, 3 (grey box) or 2, 9, 10 (white
    box, no load pressure across the joined ports) as the full plant.
    """
    s = np.zeros(N_STATES)
    if P[I_VALVE_MODEL] == WHITE_BOX:
        _white_box_valve_test(s, P, cmd, dt, nsub, supply, hist, out)
        return
    h = dt / nsub
    tau = P[I_TAU]
    scale = math.sqrt(max(supply, 0.0) / P[I_DROP])
    hist[:] = 0.0
    for k in range(cmd.shape[0]):
        out[k, 0] = s[2] * scale
        out[k, 1] = s[2]
        hist[k % hist.shape[0]] = cmd[k]
        for j in range(nsub):
            i_v = valve_current(delayed_command(hist, k, j, nsub, dt, tau, 0.0), P)
            if j == 0:
                out[k, 2] = i_v
            q, qd = s[2], s[3]
            a1 = valve_accel(q, qd, i_v, P)
            a2 = valve_accel(q + 0.5 * h * qd, qd + 0.5 * h * a1, i_v, P)
            a3 = valve_accel(q + 0.5 * h * (qd + 0.5 * h * a1), qd + 0.5 * h * a2, i_v, P)
            a4 = valve_accel(q + h * (qd + 0.5 * h * a2), qd + h * a3, i_v, P)
            s[2] = q + h / 6.0 * (qd + 2.0 * (qd + 0.5 * h * a1) + 2.0 * (qd + 0.5 * h * a2) + qd + h * a3)
            s[3] = qd + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            spool_stops(s, P)


@njit(cache=True)
def _white_box_valve_test(s, P, cmd, dt, nsub, supply, hist, out):
    """run_valve_test for the white-box valve: RK4 on (q_c, theta_a, omega_a)."""
    h = dt / nsub
    tau = P[I_TAU]
    scale = math.sqrt(max(supply, 0.0) / P[I_DROP])
    tmp = np.zeros(N_STATES)
    hist[:] = 0.0
    for k in range(cmd.shape[0]):
        out[k, 0] = s[2] * scale
        out[k, 1] = s[2]
        hist[k % hist.shape[0]] = cmd[k]
        for j in range(nsub):
            i_v = valve_current(delayed_command(hist, k, j, nsub, dt, tau, 0.0), P)
            if j == 0:
                out[k, 2] = i_v
            a1, b1, c1 = white_box_rates(s, i_v, supply, 0.0, P)
            tmp[9], tmp[10], tmp[2] = s[9] + 0.5 * h * a1, s[10] + 0.5 * h * b1, s[2] + 0.5 * h * c1
            a2, b2, c2 = white_box_rates(tmp, i_v, supply, 0.0, P)
            tmp[9], tmp[10], tmp[2] = s[9] + 0.5 * h * a2, s[10] + 0.5 * h * b2, s[2] + 0.5 * h * c2
            a3, b3, c3 = white_box_rates(tmp, i_v, supply, 0.0, P)
            tmp[9], tmp[10], tmp[2] = s[9] + h * a3, s[10] + h * b3, s[2] + h * c3
            a4, b4, c4 = white_box_rates(tmp, i_v, supply, 0.0, P)
            s[9] += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
            s[10] += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
            s[2] += h / 6.0 * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
            spool_stops(s, P)
