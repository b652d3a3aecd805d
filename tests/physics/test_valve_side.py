"""Valve-side effects (``Effect.valve_side``) show in the metered flow, against the orifice law worked by hand.

On the bench the control ports are joined through the meter: the valve's spool flow q_c passes P -> A -> meter
-> B -> T.  The baseline meters q_c sqrt(Ps / rated drop); the effects below change the lands, so the metered
flow follows from each land's orifice law at the ports' pressure where inflow equals outflow.
"""
import math

import numpy as np
import pytest

from ehas_env.physics.effects import Effect, Param
from ehas_env.physics.rig import VALVE_K
from ehas_env.simulation.plant import Plant

CMD = 3.0 * np.sin(2 * np.pi * 2.0 * np.arange(800) * 1e-3)


@pytest.fixture(scope="module")
def baseline_flow():
    return Plant(3).simulate_valve_test(CMD).flow_lpm  # q_c sqrt(70 bar / 70 bar): the spool flow itself


def test_return_pressure_lowers_the_bench_flow_by_the_root_of_the_drop_left(baseline_flow):
    # two lands in series across Ps - p_t instead of Ps
    r = Plant(3, effects={"hyp_return_pressure": {"p_t": 15.0}}).simulate_valve_test(CMD)
    np.testing.assert_allclose(r.flow_lpm, baseline_flow * math.sqrt((70.0 - 15.0) / 70.0), rtol=1e-9, atol=1e-12)


def test_underlap_doubles_the_gain_within_the_lap_and_offsets_it_beyond(baseline_flow):
    i_u = 0.5
    r = Plant(3, effects={"hyp_valve_underlap": {"i_u": i_u}}).simulate_valve_test(CMD)
    U = VALVE_K * i_u  # the lap's flow at the rated drop, LPM
    b = baseline_flow
    expected = np.where(np.abs(b) < U, 2.0 * b, b + np.sign(b) * U)
    np.testing.assert_allclose(r.flow_lpm, expected, rtol=1e-9, atol=1e-9)


def test_a_chamber_side_flow_effect_does_not_show_on_the_bench(baseline_flow):
    r = Plant(3, effects={"internal_leakage": {"C_leak": 3e-12}}).simulate_valve_test(CMD)
    assert np.array_equal(r.flow_lpm, baseline_flow)


def test_valve_side_term_may_not_use_the_motion():
    with pytest.raises(ValueError, match="valve_side = True, but its chamber_flows term takes 'v'"):
        type("BadSide", (Effect,), {"name": "bad_side_term", "valve_side": True,
                                    "params": (Param("c", "-", 0.0, (0.0, 1.0), "d"),),
                                    "chamber_flows": staticmethod(lambda v, c: (c * v, 0.0))})
