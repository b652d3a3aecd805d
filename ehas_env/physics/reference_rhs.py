"""Plain-Python right-hand side of the plant, written from the reference model.

A readable twin of :func:`ehas_env.physics.kernel.derivatives`, used by the tests to
hold the compiled kernel to the equations of the reference model.  It takes
named parameters (the slots dict of :meth:`ehas_env.simulation.plant.Plant.slots`) and a
named state, and is deliberately written in the spec's own form (Merritt's
per-land law, chamber continuity, crank dynamics) rather than the kernel's.
"""
from __future__ import annotations

import math


def _root(dp: float, half_drop: float) -> float:
    """Signed root of a land's pressure drop over the rated per-land drop."""
    return math.copysign(math.sqrt(abs(dp) / half_drop), dp)


def rhs(state: dict, i_valve_mA: float, p: dict) -> dict:
    """Time derivatives of the named state for the valve current ``i_valve_mA``."""
    th, om = state["theta"], state["omega"]
    qc, qcd = state["qc"], state["qc_dot"]
    pa, pb, ps = state["pa"], state["pb"], state["ps"]
    r, A = p["radius"], p["area"]
    half = p["rated_drop"] / 2.0
    d = {}

    if p.get("valve_model", 0.0) == 1.0:
        # white-box valve (ehas_env.physics.white_box_valve): q_c = K3 x_v, armature states
        from ehas_env.physics.white_box_valve import slot_rates

        d["theta_a"], d["omega_a"], d["qc"] = slot_rates(state["theta_a"], state["omega_a"], qc, i_valve_mA, ps,
                                                         pa - pb, p)
        d["qc_dot"] = 0.0
    else:
        # identified valve:  q'' = wn^2 (K i - q) - 2 zeta wn q'
        d["qc"] = qcd
        d["qc_dot"] = p["wn"] ** 2 * (p["K"] * i_valve_mA - qc) - 2.0 * p["zeta"] * p["wn"] * qcd
        d["theta_a"] = d["omega_a"] = 0.0

    # per-land orifice law, tank at 0
    if qc >= 0.0:
        q_a = qc * _root(ps - pa, half)
        q_b = -qc * _root(pb - 0.0, half)
        q_supply = q_a
    else:
        q_a = qc * _root(pa - 0.0, half)
        q_b = -qc * _root(ps - pb, half)
        q_supply = q_b
    q_a -= p["C_leak"] * (pa - pb) + p["C_ext"] * pa
    q_b += p["C_leak"] * (pa - pb) - p["C_ext"] * pb

    def friction(v):
        sgn = math.tanh(v / p["v_tanh"])
        f = p["Fc"] * sgn + p["b"] * v
        if p["Fc_s"] > 0.0 or p["Fs_s"] > 0.0:
            f += (p["Fc_s"] + (p["Fs_s"] - p["Fc_s"]) * math.exp(-((v / p["vs_s"]) ** 2))) * sgn
        return -f

    force = A * (pa - pb)
    if p["delta"] > 0.0:
        x, xd = state["xp"], state["vp"]
        gap = x - r * math.sin(th)
        gap_rate = xd - r * math.cos(th) * om
        if abs(gap) > p["delta"]:
            pen = gap - math.copysign(p["delta"], gap)
            joint = p["k_joint"] * pen + p["c_joint"] * gap_rate
        else:
            joint = 0.0
        m = max(p["m_piston"], p["m_backlash"])
        d["xp"], d["vp"] = xd, (force + friction(xd) - joint) / m
        d["theta"], d["omega"] = om, joint * r * math.cos(th) / p["inertia"]
    else:
        # rigid rod: I th'' = (F - m x'') r cos th with x = r sin th
        x, xd = r * math.sin(th), r * math.cos(th) * om
        m = p["m_piston"]
        c, s = math.cos(th), math.sin(th)
        d["theta"] = om
        d["omega"] = ((force + friction(xd)) * r * c + m * r * r * s * c * om * om) / (p["inertia"] + m * (r * c) ** 2)
        d["xp"], d["vp"] = xd, 0.0

    v0 = A * p["half_stroke"] + p["dead_volume"]
    d["pa"] = p["beta"] / (v0 + A * x) * (q_a - A * xd)
    d["pb"] = p["beta"] / (v0 - A * x) * (q_b + A * xd)

    if p["droop"] > 0.0:
        capacity = p["V_line"] / p["beta"] + (p["V_acc"] * p["p0"] / ps**2 if ps > p["p0"] else 0.0)
        dps = (p["Q_pump"] - q_supply) / capacity
        d["ps"] = 0.0 if (ps >= p["supply"] and dps > 0.0) else dps
    else:
        d["ps"] = 0.0
    return d
