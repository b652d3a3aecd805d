"""The dictionary of candidate terms a diagnosis may propose, at the places where physics enters the model.

When no effect of the library explains a campaign, :mod:`ehas_env.diagnosis.proposal`
fits terms of this dictionary inside the full model.  Each place of the model
(``ehas_env.physics.effects.base.PLACES``) gets one term class whose
parameters are the coefficients of physically meaningful forms:

=================  ==========================================================  ==================
place              forms (coefficient c times ...)                             coefficient unit
=================  ==========================================================  ==================
piston_force       x, v, tanh(v / v_tanh), 1, p_A, p_B, v|v|, x^3, x^2,        N/m, N s/m, N, ...
                   x^2 tanh(v / v_tanh), x^2 v, |p_L| tanh(v / v_tanh)
crank_torque       theta, omega, tanh(r omega / v_tanh), 1, theta^3,           N m/rad, ...
                   theta^2 tanh(r omega / v_tanh),
                   |joint torque per Pa| tanh(r omega / v_tanh)
chamber_flows      leak to drain (-p_A, -p_B), leak across (-(p_A - p_B), +),   m^3/s/Pa, ...
                   turbulent leak across (sign(p_L) sqrt|p_L|)
land_flows         (valve side: the lands' flows, on the bench too) back-       Pa, -, Pa s/m^3, ...
                   pressure of the return line, supply pressure offset, supply
                   drop per supply flow and per its square, flow gain into A /
                   into B / by spool direction, flow gain falling with
                   |p_L| / p_S, a line resistance (drop per flow), a share of
                   the flow that goes with the land drop (laminar)
valve_current      1 (null bias), i (gain), |i| (gain by spool direction),     mA, -, -, 1/mA^2,
                   i^3 (saturation), tanh(i / 0.05 mA) (a step at null)        mA
position_reading   1 (offset), x (gain), x^2, x^3                              m, -, 1/m, 1/m^2
=================  ==========================================================  ==================

The classes are *not* registered effects (the registry stays the library plus
the user's effects): :func:`extended_model` compiles them beside the registered
effects into one model, and :class:`~ehas_env.measurement.replay.Replayer`
runs that model whenever a :class:`~ehas_env.measurement.replay.ModelSpec`
carries ``terms``.  A term's coefficients are model slots ``<class>.<coef>``
(SI); a class with every coefficient zero is switched off.
"""
from __future__ import annotations

import math

from ehas_env.physics.effects.base import Effect, Param

_WIDE = (-1.0e30, 1.0e30)


def _p(name, unit, doc):
    return Param(name, unit, 0.0, _WIDE, doc)


class ProposalPiston(Effect):
    params = (
        _p("c_x", "N/m", "spring on the piston: force per metre of stroke"),
        _p("c_v", "N s/m", "viscous force per m/s"),
        _p("c_sv", "N", "dry (Coulomb-like) force times sign(v)"),
        _p("c_1", "N", "constant force"),
        _p("c_pa", "m^2", "force per Pa of chamber A pressure (area error on side A)"),
        _p("c_pb", "m^2", "force per Pa of chamber B pressure (area error on side B: a single rod)"),
        _p("c_vv", "N s^2/m^2", "quadratic damping: force per (m/s)^2, signed"),
        _p("c_x3", "N/m^3", "hardening spring: force per m^3"),
        _p("c_x2", "N/m^2", "force per m^2 of stroke (a load that rises toward both ends)"),
        _p("c_x2sv", "N/m^2", "dry force that rises with position squared: per m^2, times sign(v)"),
        _p("c_x2v", "N s/m^3", "viscous force that rises with position squared: per m^2 and per m/s"),
        _p("c_plsv", "m^2", "dry force that rises with the load pressure: per Pa of |p_L|, times sign(v)"),
    )

    @staticmethod
    def piston_force(x, v, pa, pb, v_tanh, c_x, c_v, c_sv, c_1, c_pa, c_pb, c_vv, c_x3, c_x2, c_x2sv, c_x2v,
                     c_plsv):
        sv = math.tanh(v / v_tanh)
        return (c_x * x + c_v * v + c_sv * sv + c_1 + c_pa * pa + c_pb * pb
                + c_vv * v * abs(v) + c_x3 * x * x * x + c_x2 * x * x + c_x2sv * x * x * sv + c_x2v * x * x * v
                + c_plsv * abs(pa - pb) * sv)


class ProposalCrank(Effect):
    params = (
        _p("c_th", "N m/rad", "spring on the crank: torque per radian"),
        _p("c_w", "N m s/rad", "viscous torque per rad/s"),
        _p("c_sw", "N m", "dry torque times sign(omega)"),
        _p("c_1", "N m", "constant torque (an offset load, gravity at 0 deg)"),
        _p("c_th3", "N m/rad^3", "hardening spring: torque per rad^3"),
        _p("c_th2sw", "N m/rad^2", "dry torque that rises with angle squared: per rad^2, times sign(omega)"),
        _p("c_jsw", "m^3", "dry torque that rises with the joint's load: per Pa of |p_L| r |cos theta|, "
                           "times sign(omega) (a joint's friction, Pa x m^2 x m)"),
    )

    @staticmethod
    def crank_torque(theta, omega, pa, pb, radius, v_tanh, c_th, c_w, c_sw, c_1, c_th3, c_th2sw, c_jsw):
        sw = math.tanh(radius * omega / v_tanh)
        return (c_th * theta + c_w * omega + c_sw * sw + c_1 + c_th3 * theta * theta * theta
                + c_th2sw * theta * theta * sw + c_jsw * abs(pa - pb) * radius * abs(math.cos(theta)) * sw)


class ProposalFlow(Effect):
    params = (
        _p("c_ext", "m^3/s/Pa", "leakage from each chamber to drain, per Pa"),
        _p("c_int", "m^3/s/Pa", "leakage across the piston, per Pa of load pressure"),
        _p("c_intsq", "m^3/s/Pa^0.5", "turbulent leakage across the piston, per sqrt(Pa) of load pressure"),
    )

    @staticmethod
    def chamber_flows(pa, pb, c_ext, c_int, c_intsq):
        pl = pa - pb
        cross = c_int * pl + c_intsq * math.copysign(math.sqrt(abs(pl)), pl)
        return -c_ext * pa - cross, -c_ext * pb + cross


class ProposalLand(Effect):
    """Terms at the valve's lands and its supply and return ports: they act wherever a flow is metered (the
    runs' chambers and the valve bench, ``valve_side``)."""

    valve_side = True
    params = (
        _p("c_ret", "Pa", "back-pressure of the return line (tank above 0)"),
        _p("c_sup", "Pa", "supply pressure offset at the valve"),
        _p("c_ga", "-", "extra flow gain into or out of chamber A (relative)"),
        _p("c_gb", "-", "extra flow gain into or out of chamber B (relative)"),
        _p("c_gpos", "-", "extra flow gain when the spool is open positive (relative)"),
        _p("c_gneg", "-", "extra flow gain when the spool is open negative (relative)"),
        _p("c_gpl", "-", "flow gain change per unit of |p_L| / p_S (relative)"),
        _p("c_rline", "Pa s/m^3", "resistance of the lines between valve and chambers: pressure drop per flow"),
        _p("c_rsup", "Pa s/m^3", "resistance of the supply line: supply pressure drop per supply flow"),
        _p("c_rsup2", "Pa s^2/m^6", "turbulent supply drop: supply pressure drop per supply flow squared"),
        _p("c_lam", "-", "share of the land flow that goes with the land's drop itself, not its square root "
                         "(laminar metering; relative, at the rated drop p_S / 2)"),
    )

    @staticmethod
    def chamber_flows(pa, pb, ps, q_a, q_b, qc, q_supply, c_ret, c_sup, c_ga, c_gb, c_gpos, c_gneg, c_gpl,
                      c_rline, c_rsup, c_rsup2, c_lam):
        # 1e5 Pa: the least pressure drop a land form divides by (finite where a land closes)
        if qc >= 0.0:
            d_in = max(ps - pa, 1.0e5)
            d_out = max(pb, 1.0e5)
            q_in, q_out = q_a, q_b
            g = c_gpos
        else:
            d_in = max(ps - pb, 1.0e5)
            d_out = max(pa, 1.0e5)
            q_in, q_out = q_b, q_a
            g = c_gneg
        # a pressure change dp at a land changes its flow by q dp / (2 drop) (q ~ sqrt(drop))
        rel_in = (c_sup - c_rsup * abs(q_supply) - c_rsup2 * q_supply * q_supply - c_rline * abs(q_in)) / (2.0 * d_in)
        rel_out = (-c_ret - c_rline * abs(q_out)) / (2.0 * d_out)
        rel = g + c_gpl * abs(pa - pb) / max(ps, 1.0e5)
        lam_in = c_lam * (math.sqrt(d_in / (0.5 * max(ps, 1.0e5))) - 1.0)
        lam_out = c_lam * (math.sqrt(d_out / (0.5 * max(ps, 1.0e5))) - 1.0)
        dq_in = q_in * (rel_in + rel + lam_in)
        dq_out = q_out * (rel_out + rel + lam_out)
        if qc >= 0.0:
            dqa, dqb = dq_in, dq_out
        else:
            dqa, dqb = dq_out, dq_in
        return dqa + c_ga * q_a, dqb + c_gb * q_b


class ProposalCurrent(Effect):
    chain_order = 1000  # after every effect of the current chain
    params = (
        _p("c_1", "mA", "current offset (null bias)"),
        _p("c_i", "-", "relative flow gain change"),
        _p("c_abs", "-", "flow gain change by spool direction: i (1 + c sign(i))"),
        _p("c_i3", "1/mA^2", "cubic current: a gain that falls (c < 0, saturation) or rises with |i|"),
        _p("c_sgn", "mA", "a step of the current at null: c tanh(i / 0.05 mA) (a dead band when c < 0)"),
    )

    @staticmethod
    def valve_current(i, c_1, c_i, c_abs, c_i3, c_sgn):
        return i + c_1 + c_i * i + c_abs * abs(i) + c_i3 * i * i * i + c_sgn * math.tanh(i / 0.05)


class ProposalReading(Effect):
    params = (
        _p("c_1", "m", "offset of the position reading"),
        _p("c_x", "-", "gain error of the position reading (relative)"),
        _p("c_x2", "1/m", "reading error per m^2 of position (a bowed characteristic)"),
        _p("c_x3", "1/m^2", "reading error per m^3 of position (a sensor that compresses its ends)"),
    )

    @staticmethod
    def position_reading(x, c_1, c_x, c_x2, c_x3):
        return x + c_1 + c_x * x + c_x2 * x * x + c_x3 * x * x * x


#: the term classes by place; their names are set here, after the class bodies, so that
#: defining them does not register them as effects
TERM_CLASSES = {"piston_force": ProposalPiston, "crank_torque": ProposalCrank, "chamber_flows": ProposalFlow,
                "land_flows": ProposalLand, "valve_current": ProposalCurrent, "position_reading": ProposalReading}
for _place, _cls in TERM_CLASSES.items():
    _cls.name = f"proposal_{_place}"
    _cls.title = f"proposed term at {_place.replace('_', ' ')}"
_BY_NAME = {c.name: c for c in TERM_CLASSES.values()}

_EXT: dict[tuple, object] = {}


def extended_model():
    """The compiled model of every registered effect plus the term classes (built once per registry)."""
    from ehas_env.physics.codegen import build_model
    from ehas_env.physics.effects import REGISTRY
    from ehas_env.simulation.control_laws import all_laws

    key = tuple(sorted((n, c.__module__) for n, c in REGISTRY.items()))
    if key not in _EXT:
        _EXT[key] = build_model(list(REGISTRY.values()) + list(TERM_CLASSES.values()), laws=all_laws(),
                                inline=False)
    return _EXT[key]


def term_slots(terms: dict) -> dict[str, float]:
    """Slots of the term classes for ``terms`` ({"<class>.<coef>": SI value}): on flags and coefficients."""
    out = {}
    for cls in TERM_CLASSES.values():
        on = False
        for p in cls.params:
            key = f"{cls.name}.{p.name}"
            v = float(terms.get(key, 0.0))
            out[key] = v
            on = on or v != 0.0
        out[f"{cls.name}.on"] = 1.0 if on else 0.0
    return out


def term_param(key: str) -> Param:
    """The :class:`Param` (unit, meaning) of the coefficient ``<class>.<coef>``."""
    cname, pname = key.split(".", 1)
    return _BY_NAME[cname].param(pname)
