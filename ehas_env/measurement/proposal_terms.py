"""The dictionary of candidate terms a diagnosis may propose, at the places where physics enters the model.

When no effect of the library explains a campaign, :mod:`ehas_env.diagnosis.proposal`
fits terms of this dictionary inside the full model.  Each place of the model gets one term class whose
parameters are the coefficients of physically meaningful forms.  They are **generated**
(:mod:`ehas_env.physics.term_grammar`): each place is one description of its local quantities (position, motion,
pressures, the load a joint carries, a signal) and a grammar of transformations makes the forms (springs and loads
of a position, viscous, dry and quadratic friction of a motion, a friction whose level rises with a position or a
load, area errors, a signal's offset, gain, bow, cubic bend, gain by direction and step at null, leaks to drain and
across), each with its code, its coefficient's unit from the units' algebra, its words and its kinds:

=================  ==========================================================  ==================
place              forms (coefficient c times ...)                             coefficient unit
=================  ==========================================================  ==================
piston_force       1, x, x^2, x^3, v, tanh(v / v_tanh), v |v|, p_A, p_B,       N, N/m, ..., m^2
                   x^2 tanh(v / v_tanh), |p_L| tanh(v / v_tanh), x^2 v, |p_L| v
crank_torque       1, theta, theta^2, theta^3, omega, tanh(r omega / v_tanh),  N m, N m/rad, ...
                   omega |omega|, theta^2 and the joint's load |p_L| r |cos
                   theta| times tanh(r omega / v_tanh) and omega
chamber_flows      leak to drain (-p_A, -p_B) and across (-(p_A - p_B), +),    m^3/(Pa s),
                   each laminar and turbulent (sign(p) sqrt|p|)                m^3/(Pa^0.5 s)
land_flows         (valve side: the lands' flows, on the bench too) back-       Pa, -, Pa s/m^3, ...
                   pressure of the return line, supply pressure offset, supply
                   drop per supply flow and per its square, flow gain into A /
                   into B / by spool direction, flow gain falling with
                   |p_L| / p_S, a line resistance (drop per flow), a share of
                   the flow that goes with the land drop (laminar)
valve_current      1 (null bias), i, i^2, i^3, |i| (gain by spool direction),   mA, -, 1/mA, ...
                   tanh(i / 0.05 mA) (a step at null)
position_reading   1 (offset), x (gain), x^2, x^3                              m, -, 1/m, 1/m^2
=================  ==========================================================  ==================

The lands' terms (:class:`ProposalLand`) are a family of their own: perturbations of the orifice law at its
boundaries (its supply and return pressures, its drop, its gain by port and direction), each described once in
:mod:`ehas_env.physics.land_terms` and generated from there like the rest.

The classes are *not* registered effects (the registry stays the library plus
the user's effects): :func:`extended_model` compiles them beside the registered
effects into one model, and :class:`~ehas_env.measurement.replay.Replayer`
runs that model whenever a :class:`~ehas_env.measurement.replay.ModelSpec`
carries ``terms``.  A term's coefficients are model slots ``<class>.<coef>``
(SI); a class with every coefficient zero is switched off.
"""
from __future__ import annotations

import math

from ehas_env.physics.effects.augmentation import term_methods
from ehas_env.physics.effects.base import Effect, Param
from ehas_env.physics.land_terms import LAND_TERMS, land_method_source
from ehas_env.physics.term_grammar import TERM_PLACES, method_source, place_atoms, term_class

_WIDE = (-1.0e30, 1.0e30)


def _p(name, unit, doc):
    return Param(name, unit, 0.0, _WIDE, doc)


def _term_class(place) -> type:
    """The term class of a :class:`~ehas_env.physics.term_grammar.TermPlace`: a parameter per atom of the
    grammar there, its one method their sum (unnamed here: naming it would register it as an effect)."""
    atoms = place_atoms(place)
    qual = "Proposal_" + place.name
    body = {"params": tuple(_p(a.coef, a.unit, a.words) for a in atoms), "__module__": __name__,
            "__qualname__": qual, "__doc__": f"The grammar's terms {place.where} (generated).",
            **term_methods(term_class(place.name), [method_source(place, atoms)])}
    if place.chain_order is not None:
        body["chain_order"] = place.chain_order
    return type(Effect)(qual, (Effect,), body)


class ProposalLand(Effect):
    """Terms at the valve's lands and its supply and return ports (:mod:`ehas_env.physics.land_terms`, generated):
    they act wherever a flow is metered (the runs' chambers and the valve bench, ``valve_side``)."""

    valve_side = True
    params = tuple(_p(t.coef, t.unit, t.words) for t in LAND_TERMS)
    locals().update(term_methods(term_class("land_flows"), [land_method_source()]))


#: the term classes by place; their names are set here, after the class bodies, so that
#: defining them does not register them as effects
TERM_CLASSES = {**{name: _term_class(place) for name, place in TERM_PLACES.items()}, "land_flows": ProposalLand}
for _place, _cls in TERM_CLASSES.items():
    _cls.name = term_class(_place)
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
