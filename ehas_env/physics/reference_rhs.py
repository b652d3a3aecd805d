"""Plain-Python right-hand side of the plant, written from the reference model.

A readable twin of the compiled model's ``derivatives``
(:mod:`ehas_env.physics.codegen`), used by the tests to hold the compiled code to
the equations.  The baseline is written out here in the spec's own form
(Merritt's per-land law, chamber continuity, crank dynamics), independently of
:mod:`ehas_env.physics.baseline`; each effect's terms are its own plain Python
functions, called here by name with named arguments.  It takes the named slots
of :meth:`ehas_env.simulation.plant.Plant.slots` and a named state.
"""
from __future__ import annotations

import math

from ehas_env.physics.effects import REGISTRY


def _root(dp: float, half_drop: float) -> float:
    """Signed root of a land's pressure drop over the rated per-land drop."""
    return math.copysign(math.sqrt(abs(dp) / half_drop), dp)


def _term(name: str, place: str, p: dict, ctx: dict):
    """The value of effect ``name``'s term at ``place``: each argument one of its parameters or constants (from
    ``p``), a quantity or its own state (from ``ctx``), or a baseline slot (from ``p``)."""
    cls = REGISTRY[name]
    own = {q.name for q in cls.params + cls.constants}
    kwargs = {}
    for arg in cls.term_args(place):
        if arg in own:
            kwargs[arg] = p[f"{name}.{arg}"]
        elif arg in ctx:
            kwargs[arg] = ctx[arg]
        elif f"{name}.{arg}" in ctx:
            kwargs[arg] = ctx[f"{name}.{arg}"]
        else:
            kwargs[arg] = p[arg]
    return getattr(cls, place)(**kwargs)


def _terms(place: str, p: dict, ctx: dict) -> list:
    """Values of the terms at ``place`` of every effect that is on, in name order."""
    return [(name, _term(name, place, p, ctx)) for name in sorted(n for n in REGISTRY if p.get(f"{n}.on"))
            if place in REGISTRY[name].terms()]


def _chain(place: str, p: dict, on_only: bool = True) -> list:
    """Names of the effects with a term at ``place`` (those on, or all), in chain order."""
    return sorted((n for n in REGISTRY if (p.get(f"{n}.on") or not on_only) and place in REGISTRY[n].terms()),
                  key=lambda n: (REGISTRY[n].chain_order, n))


def valve_current(i_cmd: float, p: dict) -> float:
    """Amplifier clip, then the effects of the current chain in their order."""
    i = min(max(i_cmd, -p["i_max"]), p["i_max"])
    for name in _chain("valve_current", p):
        i = _term(name, "valve_current", p, {"i": i})
    return i


def _own_rates(name: str, p: dict, ctx: dict) -> dict:
    """The rates of effect ``name``'s own states, by ``effect.state`` (0 while it is off)."""
    cls = REGISTRY[name]
    keys = [f"{name}.{st[0]}" for st in cls.states]
    if not (p.get(f"{name}.on") and "state_rates" in cls.terms()):
        return dict.fromkeys(keys, 0.0)
    val = _term(name, "state_rates", p, ctx)
    return dict(zip(keys, list(val) if len(keys) > 1 else [val]))


def coil_current(state: dict, i: float, p: dict) -> tuple[float, dict]:
    """The current the torque motor acts on, and the rates of the coil effects' states (by ``effect.state``)."""
    rates = {}
    for name in _chain("coil_current", p, on_only=False):
        ctx = {**state, "i": i}
        rates.update(_own_rates(name, p, ctx))
        if p.get(f"{name}.on"):
            i = _term(name, "coil_current", p, ctx)
    return i, rates


def lands(qc: float, pa: float, pb: float, ps: float, p: dict, own: dict | None = None) -> tuple:
    """Merritt's per-land law between the pressures at the supply and return lands (the supply's and the tank's 0,
    unless the effects' ``land_pressures`` chain changes them), each land's flow then as the ``land_flows`` chain
    changes it: (Q into A, Q into B, Q from supply -- the orifice law's).  ``own``: the effects' own states by
    their full names (a line's volume at a land reads its state)."""
    half = p["rated_drop"] / 2.0
    p_sup, p_ret = ps, 0.0
    for name in _chain("land_pressures", p):
        p_sup, p_ret = _term(name, "land_pressures", p, {**(own or {}), "qc": qc, "ps": ps, "p_sup": p_sup,
                                                          "p_ret": p_ret})
    if qc >= 0.0:
        q_a = qc * _root(p_sup - pa, half)
        q_b, q_s = -qc * _root(pb - p_ret, half), q_a
    else:
        q_b = -qc * _root(p_sup - pb, half)
        q_a, q_s = qc * _root(pa - p_ret, half), q_b
    for name in _chain("land_flows", p):
        q_a, q_b = _term(name, "land_flows", p, {"qc": qc, "pa": pa, "pb": pb, "ps": ps, "q_a": q_a, "q_b": q_b})
    return q_a, q_b, q_s


def metered_flow(state: dict, p: dict) -> float:
    """The flow the meter in line A reads before its chain: the land's flow at the ports' pressures (the chambers'
    unless a ``port_pressures`` term puts a line between) and the valve-side effects' flows there."""
    qc, ps = state["qc"], state["ps"]
    own = {k: v for k, v in state.items() if "." in k}
    pva, pvb = state["pa"], state["pb"]
    for name in _chain("port_pressures", p):
        pva, pvb = _term(name, "port_pressures", p, {**own, "pa": pva, "pb": pvb})
    q_a, q_b, q_s = lands(qc, pva, pvb, ps, p, own)
    ctx = {"qc": qc, "pa": pva, "pb": pvb, "ps": ps, "p_load": pva - pvb, "q_a": q_a, "q_b": q_b, "q_supply": q_s}
    side = [n for n in _chain("chamber_flows", p) if REGISTRY[n].valve_side]
    return q_a + sum(_term(n, "chamber_flows", p, ctx)[0] for n in sorted(side))


def rhs(state: dict, i_valve_mA: float, p: dict) -> dict:
    """Time derivatives of the named state for the valve current ``i_valve_mA`` (after the current chain)."""
    th, om = state["theta"], state["omega"]
    qc, qcd = state["qc"], state["qc_dot"]
    pa, pb, ps = state["pa"], state["pb"], state["ps"]
    r, A = p["radius"], p["area"]
    d = {}
    i_valve_mA, coil_rates = coil_current(state, i_valve_mA, p)
    d.update(coil_rates)

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

    # per-land orifice law, between the pressures at the lands
    own = {k: v for k, v in state.items() if "." in k}  # the effects' own states, by their full names
    q_a, q_b, q_supply = lands(qc, pa, pb, ps, p, own)

    joint = any(p.get(f"{n}.on") and "joint_force" in REGISTRY[n].terms() for n in REGISTRY)
    if joint:
        x, xd = state["xp"], state["vp"]
    else:
        x, xd = r * math.sin(th) - p.get("piston_offset", 0.0), r * math.cos(th) * om
    ctx = {"theta": th, "omega": om, "qc": qc, "qc_dot": qcd, "pa": pa, "pb": pb, "ps": ps, "xp": state["xp"],
           "vp": state["vp"], "i": i_valve_mA, "p_load": pa - pb, "q_a": q_a, "q_b": q_b, "q_supply": q_supply,
           "x": x, "v": xd, **own}
    for _, (dqa, dqb) in _terms("chamber_flows", p, ctx):
        q_a += dqa
        q_b += dqb
    force = A * (pa - pb) + sum(v for _, v in _terms("piston_force", p, ctx))
    m = sum(v for _, v in _terms("moving_mass", p, ctx))
    torque = sum(v for _, v in _terms("crank_torque", p, ctx))

    if joint:
        ctx["gap"] = x - (r * math.sin(th) - p.get("piston_offset", 0.0))
        ctx["gap_rate"] = xd - r * math.cos(th) * om
        joint_force = sum(v for _, v in _terms("joint_force", p, ctx))
        m_min = max([p[f"{n}.m_min"] for n in REGISTRY if p.get(f"{n}.on") and f"{n}.m_min" in p] or [0.0])
        d["xp"], d["vp"] = xd, (force - joint_force) / max(m, m_min)
        d["theta"], d["omega"] = om, (joint_force * r * math.cos(th) + torque) / p["inertia"]
    else:
        # rigid rod: I th'' = (F - m x'') r cos th + T with x = r sin th
        c, s = math.cos(th), math.sin(th)
        d["theta"] = om
        d["omega"] = (force * r * c + torque + m * r * r * s * c * om * om) / (p["inertia"] + m * (r * c) ** 2)
        d["xp"], d["vp"] = xd, 0.0

    v0 = A * p["half_stroke"] + p["dead_volume"]
    d["pa"] = p["beta"] / (v0 + A * x) * (q_a - A * xd)
    d["pb"] = p["beta"] / (v0 - A * x) * (q_b + A * xd)
    d["ps"] = sum(v for _, v in _terms("supply_rate", p, ctx))
    # the sensors' quantities move at these rates (a lag of a pressure reading follows them)
    ctx.update(pa_rate=d["pa"], pb_rate=d["pb"], ps_rate=d["ps"], f_rate=A * (d["pa"] - d["pb"]))
    ctx["q"] = metered_flow(state, p)  # the flow meter's reading has no rate: its followers get the reading
    for name in sorted(n for n in REGISTRY if REGISTRY[n].states and "coil_current" not in REGISTRY[n].terms()):
        d.update(_own_rates(name, p, ctx))
    return d
