"""The proposal's flexible terms act where their physics acts (issue 33 item 1).

Independent truth: a flow gain g at the valve's lands scales the bench's metered flow by exactly (1 + g) on the
side it acts on (the ports joined through the meter see the same factor on both lands, so their pressure does not
move); a leak across the piston is not at the valve and leaves the bench untouched; a term of zero changes nothing.
"""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.measurement.replay import ModelSpec, Replayer
from tests.measurement.test_replay import HIDDEN, campaign


@pytest.fixture(scope="module")
def rep():
    camp, _ = campaign(HIDDEN, seed=26, duration=0.6)
    return Replayer(camp)


def _runs(rep, sims):
    return {c.run.kind: (c, s) for c, s in zip(rep.cases, sims)}


def test_terms_act_where_their_physics_acts(rep):
    zero = ModelSpec(terms={"proposal_land_flows.c_gpos": 0.0, "proposal_position_reading.c_1": 0.0})
    land = ModelSpec(terms={"proposal_land_flows.c_gpos": 0.1})
    leak = ModelSpec(terms={"proposal_chamber_flows.c_int": 2e-12})
    reading = ModelSpec(terms={"proposal_position_reading.c_x2": 0.8})
    ref, z, a, b, c = rep.simulate_many([ModelSpec(), zero, land, leak, reading])
    for k, (case, s) in _runs(rep, ref).items():  # a term of zero is the model without it
        for sig in s:
            np.testing.assert_allclose(_runs(rep, z)[k][1][sig], s[sig], rtol=1e-9, atol=1e-9, err_msg=f"{k} {sig}")
    case, bench = _runs(rep, ref)["valve_open_loop"]
    q0, q_land = bench["flow_lpm"], _runs(rep, a)["valve_open_loop"][1]["flow_lpm"]
    big = np.abs(q0) > 0.3 * np.max(np.abs(q0))
    pos, neg = big & (q0 > 0), big & (q0 < 0)
    assert pos.any() and neg.any()
    # the lands' gain when the spool is open positive: (1 + g) on the bench, nothing when it is open negative
    np.testing.assert_allclose(q_land[pos] / q0[pos], 1.1, rtol=2e-3)
    np.testing.assert_allclose(q_land[neg], q0[neg], rtol=1e-6, atol=1e-9)
    # a leak across the piston is no flow at the valve: the bench does not see it, the closed loop does
    np.testing.assert_allclose(_runs(rep, b)["valve_open_loop"][1]["flow_lpm"], q0, rtol=1e-9, atol=1e-12)
    cl0, cl_leak = _runs(rep, ref)["closed_loop"][1], _runs(rep, b)["closed_loop"][1]
    assert np.max(np.abs(cl_leak["flow_lpm"] - cl0["flow_lpm"])) > 0.05
    # the position reading's error moves the closed loop (its controller sees the reading), never the bench
    assert np.max(np.abs(_runs(rep, c)["closed_loop"][1]["current_mA"] - cl0["current_mA"])) > 0.01
    np.testing.assert_allclose(_runs(rep, c)["valve_open_loop"][1]["flow_lpm"], q0, rtol=1e-9, atol=1e-12)


def test_the_effect_file_of_new_forms_has_its_place_and_side():
    """The written effect file of a lands' term is valve-side (it acts on the bench too) and a reading's term
    sits at position_reading; both compile."""
    import ast

    from ehas_env.diagnosis.proposal import Proposal, effect_source

    def prop(terms):
        return Proposal(terms=terms, ci={}, cost_before=4.0, cost_after=1.5, fit_before=80.0, fit_after=95.0, fit=None)

    land = effect_source(prop({"proposal_land_flows.c_gpl": -0.2, "proposal_land_flows.c_rsup2": 3e13}), "gain_load")
    tree = ast.parse(land)
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef))
    assert "valve_side = True" in land and [f.name for f in cls.body if isinstance(f, ast.FunctionDef)] == \
        ["chamber_flows"]
    mixed = effect_source(prop({"proposal_land_flows.c_gpl": -0.2, "proposal_chamber_flows.c_intsq": 1e-9}), "m")
    assert "valve_side" not in mixed  # a leak across the piston is not at the valve: the file acts in the runs only
    reading = effect_source(prop({"proposal_position_reading.c_x3": 5.0, "proposal_position_reading.c_1": 1e-3}),
                            "lvdt")
    cls = next(n for n in ast.parse(reading).body if isinstance(n, ast.ClassDef))
    meth = [f for f in cls.body if isinstance(f, ast.FunctionDef)]
    assert [f.name for f in meth] == ["position_reading"] and meth[0].args.args[0].arg == "x"
