"""The baseline plant's physics, written once.

Identified (or white-box) servo valve -> per-land orifice law -> compressible
chambers -> actuator -> crank -> disc inertia, with spool and stroke end stops.
The functions here are the baseline's pieces; :mod:`ehas_env.physics.codegen`
copies this module's source into every generated model, where the assembled
right-hand side (``derivatives``) calls them with the effects' terms added at
their places.  They are plain, self-contained functions of numbers (SI, valve
current in mA), compiled by numba and inlined.

Examples
--------
>>> from ehas_env.physics.baseline import land_flows
>>> qa, qb, qs = land_flows(1e-4, 110e5, 110e5, 220e5, 0.0, 70e5)
>>> round(qa / 1e-4, 4), qa == qs      # 110 bar across a 35-bar-rated land: sqrt(110/35)
(1.7728, True)
"""
from __future__ import annotations

import math

from numba import njit

from ehas_env.physics.layout import (I_IMAX, I_K, I_WN, I_ZETA, I_VALVE_MODEL, I_WB_AN, I_WB_AV, I_WB_BA, I_WB_BFF, I_WB_JA, I_WB_K2,
                                     I_WB_K3, I_WB_KF, I_WB_KFF, I_WB_KJET, I_WB_KT, I_WB_KW, I_WB_PREF, I_WB_R,
                                     I_WB_XF0, I_WB_XVMAX, WHITE_BOX)


@njit(cache=True, inline="always")
def signed_root(z):
    """sign(z) * sqrt(|z|): the orifice law's root of a signed pressure ratio."""
    return math.sqrt(z) if z >= 0.0 else -math.sqrt(-z)


@njit(cache=True, inline="always")
def amplifier(i_cmd, i_max):
    """Servo amplifier: the command current clipped to +-i_max, mA."""
    return min(max(i_cmd, -i_max), i_max)


@njit(cache=True, inline="always")
def land_flows(qc, pa, pb, ps, pt, rated_drop):
    """Per-land orifice law, critically lapped: (Q into A, Q into B, Q from supply), m^3/s.

    ``qc`` is the valve's no-load flow at the rated drop (both lands in series),
    so each land passes qc * sqrt(dp / (rated_drop / 2)); ``ps`` is the pressure at
    the supply land, ``pt`` at the return lands (the book's: the supply's and the
    tank's 0; the model's ``lands`` applies the effects' ``land_pressures``).
    """
    half = 0.5 * rated_drop
    if qc >= 0.0:
        qs = qc * signed_root((ps - pa) / half)
        return qs, -qc * signed_root((pb - pt) / half), qs
    qs = -qc * signed_root((ps - pb) / half)
    return qc * signed_root((pa - pt) / half), qs, qs


@njit(cache=True, inline="always")
def grey_box_valve_accel(qc, qcd, i_valve, K, wn, zeta):
    """The identified valve: q_c'' = wn^2 (K i - q_c) - 2 zeta wn q_c' (q_c in m^3/s, K in m^3/s/mA)."""
    return wn * wn * (K * i_valve - qc) - 2.0 * zeta * wn * qcd


@njit(cache=True, inline="always")
def white_box_rates(qc, theta_a, omega_a, i_valve, ps, p_load, P):
    """(theta_a', omega_a', q_c') of the white-box valve; see ehas_env.physics.white_box_valve.

    Armature: Ja th'' = Kt i - (Kf - r^2 kjet Ps) th - Ba th' - Kw x_v - r A_N P_p;
    pilot flow K2 r th - Kc P_p fills the spool ends (A_v x_v'), spool force
    A_v P_p = kff dP x_v + bff sqrt(dP) x_v' (flow forces), dP = Ps - sign(x_v) P_L;
    K2 grows with sqrt(Ps), Kc = K2 x_f0 / Ps.  q_c = K3 x_v.  ``P`` holds the
    baseline slots (``layout.BASE_SLOTS``).
    """
    k3 = P[I_WB_K3]
    xv = qc / k3
    ps_pilot = max(ps, 1.0e5)  # the pilot law needs a supply; 1 bar floor
    k2 = P[I_WB_K2] * math.sqrt(ps_pilot / P[I_WB_PREF])
    kc = k2 * P[I_WB_XF0] / ps_pilot
    dpv = ps - math.copysign(1.0, xv) * p_load
    if dpv < 0.0:
        dpv = 0.0
    k_flow = P[I_WB_KFF] * dpv
    b_flow = P[I_WB_BFF] * math.sqrt(dpv)
    av, r = P[I_WB_AV], P[I_WB_R]
    xv_dot = (k2 * r * theta_a - kc * k_flow * xv / av) / (av + kc * b_flow / av)
    p_pilot = (k_flow * xv + b_flow * xv_dot) / av
    torque = (P[I_WB_KT] * i_valve - (P[I_WB_KF] - r * r * P[I_WB_KJET] * ps) * theta_a - P[I_WB_BA] * omega_a
              - P[I_WB_KW] * xv - r * P[I_WB_AN] * p_pilot)
    return omega_a, torque / P[I_WB_JA], k3 * xv_dot


@njit(cache=True, inline="always")
def chamber_rates(x, v, qa_in, qb_in, area, half_stroke, dead_volume, beta):
    """Chamber continuity: (P_A', P_B') = beta / V (Q -+ A x'), V = A (half stroke +- x) + dead volume, Pa/s."""
    v0 = area * half_stroke + dead_volume
    return beta / (v0 + area * x) * (qa_in - area * v), beta / (v0 - area * x) * (qb_in + area * v)


@njit(cache=True, inline="always")
def crank_accel(c, sn, omega, force, torque, m, inertia, r):
    """Rigid rod: I th'' = (F - m x'') r cos th + T with x = r sin th, solved for th'', rad/s^2.

    ``c``, ``sn``: cos and sin of the crank angle; ``force`` acts on the piston along +x,
    ``torque`` directly on the crank, ``m`` is the piston's moving mass.
    """
    return (force * r * c + torque + m * r * r * sn * c * omega * omega) / (inertia + m * r * r * c * c)


@njit(cache=True, inline="always")
def stop(s, j, jr, limit):
    """State j held within +-limit; its rate state jr (if >= 0) zeroed outward at the stop."""
    if s[j] >= limit:
        s[j] = limit
        if jr >= 0 and s[jr] > 0.0:
            s[jr] = 0.0
    elif s[j] <= -limit:
        s[j] = -limit
        if jr >= 0 and s[jr] < 0.0:
            s[jr] = 0.0


@njit(cache=True, inline="always")
def spool_stops(s, P):
    """Spool at its end stops for |q_c| >= i_max K: clip q_c, zero q_c' outward.

    White box: the spool stops at +-wb_xv_max and the flapper stops on a nozzle
    (|theta_a| = x_f0 / r, outward rate zeroed).
    """
    if P[I_VALVE_MODEL] == WHITE_BOX:
        s[3] = 0.0
        stop(s, 2, -1, P[I_WB_K3] * P[I_WB_XVMAX])
        stop(s, 9, 10, P[I_WB_XF0] / P[I_WB_R])
        return
    stop(s, 2, 3, P[I_K] * P[I_IMAX])


@njit(cache=True, inline="always")
def valve_rates(s, i_valve, ps, p_load, P, ds):
    """The valve's state rates into ds (grey box: q_c, q_c'; white box: q_c, theta_a, omega_a)."""
    if P[I_VALVE_MODEL] == WHITE_BOX:
        ds[9], ds[10], ds[2] = white_box_rates(s[2], s[9], s[10], i_valve, ps, p_load, P)
        ds[3] = 0.0
    else:
        ds[2] = s[3]
        ds[3] = grey_box_valve_accel(s[2], s[3], i_valve, P[I_K], P[I_WN], P[I_ZETA])
        ds[9] = 0.0
        ds[10] = 0.0
