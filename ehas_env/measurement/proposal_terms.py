"""The dictionary of candidate terms a diagnosis may propose, at the places where physics enters the model.

When no effect of the library explains a campaign, :mod:`ehas_env.measurement.proposal`
fits terms of this dictionary inside the full model.  Each place of the model
(``ehas_env.physics.effects.base.PLACES``) gets one term class whose
parameters are the coefficients of physically meaningful forms:

=================  ==========================================================  ==================
place              forms (coefficient c times ...)                             coefficient unit
=================  ==========================================================  ==================
piston_force       x, v, tanh(v / v_tanh), 1, p_A, p_B, v|v|, x^3              N/m, N s/m, N, ...
crank_torque       theta, omega, tanh(r omega / v_tanh), 1, theta^3             N m/rad, ...
chamber_flows      leak to drain (-p_A, -p_B), leak across (-(p_A - p_B), +),   m^3/s/Pa, Pa, -
                   back-pressure of the return line, supply pressure offset,
                   extra flow gain into A / into B, by spool direction
valve_current      1 (null bias), i (gain), |i| (gain by spool direction)       mA, -, -
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
    )

    @staticmethod
    def piston_force(x, v, pa, pb, v_tanh, c_x, c_v, c_sv, c_1, c_pa, c_pb, c_vv, c_x3):
        return (c_x * x + c_v * v + c_sv * math.tanh(v / v_tanh) + c_1 + c_pa * pa + c_pb * pb
                + c_vv * v * abs(v) + c_x3 * x * x * x)


class ProposalCrank(Effect):
    params = (
        _p("c_th", "N m/rad", "spring on the crank: torque per radian"),
        _p("c_w", "N m s/rad", "viscous torque per rad/s"),
        _p("c_sw", "N m", "dry torque times sign(omega)"),
        _p("c_1", "N m", "constant torque (an offset load, gravity at 0 deg)"),
        _p("c_th3", "N m/rad^3", "hardening spring: torque per rad^3"),
    )

    @staticmethod
    def crank_torque(theta, omega, radius, v_tanh, c_th, c_w, c_sw, c_1, c_th3):
        return (c_th * theta + c_w * omega + c_sw * math.tanh(radius * omega / v_tanh) + c_1
                + c_th3 * theta * theta * theta)


class ProposalFlow(Effect):
    params = (
        _p("c_ext", "m^3/s/Pa", "leakage from each chamber to drain, per Pa"),
        _p("c_int", "m^3/s/Pa", "leakage across the piston, per Pa of load pressure"),
        _p("c_ret", "Pa", "back-pressure of the return line (tank above 0)"),
        _p("c_sup", "Pa", "supply pressure offset at the valve"),
        _p("c_ga", "-", "extra flow gain into or out of chamber A (relative)"),
        _p("c_gb", "-", "extra flow gain into or out of chamber B (relative)"),
        _p("c_gpos", "-", "extra flow gain when the spool is open positive (relative)"),
        _p("c_gneg", "-", "extra flow gain when the spool is open negative (relative)"),
    )

    @staticmethod
    def chamber_flows(pa, pb, ps, q_a, q_b, qc, c_ext, c_int, c_ret, c_sup, c_ga, c_gb, c_gpos, c_gneg):
        dqa = -c_ext * pa - c_int * (pa - pb) + c_ga * q_a
        dqb = -c_ext * pb + c_int * (pa - pb) + c_gb * q_b
        if qc >= 0.0:
            dqb += -c_ret * q_b / (2.0 * max(pb, 1.0e5))
            dqa += c_sup * q_a / (2.0 * max(ps - pa, 1.0e5))
            dqa += c_gpos * q_a
            dqb += c_gpos * q_b
        else:
            dqa += -c_ret * q_a / (2.0 * max(pa, 1.0e5))
            dqb += c_sup * q_b / (2.0 * max(ps - pb, 1.0e5))
            dqa += c_gneg * q_a
            dqb += c_gneg * q_b
        return dqa, dqb


class ProposalCurrent(Effect):
    chain_order = 1000  # after every effect of the current chain
    params = (
        _p("c_1", "mA", "current offset (null bias)"),
        _p("c_i", "-", "relative flow gain change"),
        _p("c_abs", "-", "flow gain change by spool direction: i (1 + c sign(i))"),
    )

    @staticmethod
    def valve_current(i, c_1, c_i, c_abs):
        return i + c_1 + c_i * i + c_abs * abs(i)


#: the term classes by place; their names are set here, after the class bodies, so that
#: defining them does not register them as effects
TERM_CLASSES = {"piston_force": ProposalPiston, "crank_torque": ProposalCrank, "chamber_flows": ProposalFlow,
                "valve_current": ProposalCurrent}
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
