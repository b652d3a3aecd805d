"""The places' quantities are read from the generated model (issue 43, point 1: places from the model's structure).

``PLACE_QUANTITIES`` is what the assembled right-hand side has bound where each place's terms are called
(:func:`ehas_env.physics.model_source.place_scopes`, on a probe model that marks every call site), filtered to the
quantities the model describes.  Independent checks: the reading of a function's bound names on known code (a name
bound only in a branch that returns is not bound after it; one bound on both branches is), and, on the text of a
real model of every registered effect, each term's quantity arguments are bound where its call actually stands.
"""
from __future__ import annotations

import ast
import re

from ehas_env.physics.effects import REGISTRY
from ehas_env.physics.effects.base import PLACE_QUANTITIES, PLACES, VALVE_SIDE_QUANTITIES
from ehas_env.physics.model_source import ModelSource, _scopes_in, place_scopes

KNOWN = '''
def f(s, i_cmd, P):
    a = 1
    if P[0] == 0.0:
        b = 2
        return a
    if P[1] != 0.0:
        c = 3
    else:
        c, d = 4, 5
    __place__("after", "a")
    if P[2] != 0.0:
        e = 6
        __place__("inside")
'''


def _sites(text: str) -> dict:
    out = {}
    for node in ast.parse(text).body:
        if isinstance(node, ast.FunctionDef):
            _scopes_in(node.body, {a.arg for a in node.args.args}, out)
    return out


def test_the_names_bound_on_every_path_to_a_call():
    sites = _sites(KNOWN)
    # b is bound only in a branch that returns; d on one branch only; the arrays (s, P) are no quantities
    assert sites["after"].bound == {"i_cmd", "a", "c"} and sites["after"].chain == ("a",)
    assert sites["inside"].bound == {"i_cmd", "a", "c", "e"} and sites["inside"].chain == ()


def test_every_place_is_called_and_its_quantities_are_the_models():
    sites = place_scopes()
    assert set(PLACES) <= set(sites)
    for place, quantities in PLACE_QUANTITIES.items():
        site = sites[place]
        assert set(site.chain) <= quantities <= site.bound | set(site.chain), place
    # the balances see the model's state and kinematics; a reading place its reading alone
    assert {"x", "v", "theta", "omega", "p_load", "q_a"} <= PLACE_QUANTITIES["piston_force"]
    assert {"gap", "gap_rate"} <= PLACE_QUANTITIES["joint_force"] and "gap" not in PLACE_QUANTITIES["piston_force"]
    assert PLACE_QUANTITIES["force_reading"] == {"f"} and PLACE_QUANTITIES["valve_current"] == {"i"}
    # the piston force summed so far (``f`` in the right-hand side) is the model's working, not the load reading
    assert "f" not in PLACE_QUANTITIES["crank_torque"]
    assert set(VALVE_SIDE_QUANTITIES) == {"qc", "pa", "pb", "ps", "p_load", "q_a", "q_b", "q_supply"}


def test_every_terms_quantities_are_bound_where_a_real_model_calls_it():
    effects = [REGISTRY[n] for n in sorted(REGISTRY)]
    text = ModelSource(effects, [])._assembled()
    lines = []
    call = re.compile(r"_t_(\w+?)__(\w+)\(")
    for ln in text.splitlines():
        m = call.search(ln)
        if m and "def " not in ln:  # mark the statement that calls the term, at its indent
            indent = len(ln) - len(ln.lstrip())
            lines.append(" " * indent + f"__place__({m.group(1) + '|' + m.group(2)!r})")
        lines.append(ln)
    sites = _sites("\n".join(lines))
    ident = {re.sub(r"\W", "_", c.name): c for c in effects}
    checked = 0
    for key, site in sites.items():
        name, place = key.split("|")
        cls = ident[name]
        for arg in cls.term_args(place):
            if cls.arg_kind(arg, place) == "quantity":
                assert arg in site.bound, (cls.name, place, arg)
                checked += 1
    assert len(sites) > 100 and checked > 100, (len(sites), checked)
