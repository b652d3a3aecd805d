"""The one linearisation (numerical, from the compiled model) held to Merritt's hand-derived model."""
from __future__ import annotations

import math

import numpy as np
import pytest
from merritt import Merritt

from ehas_controllers.linear_model import LinearPlant
from ehas_env.simulation.plant import Plant

W = np.geomspace(1.0, 3000.0, 25)
LEAK = {"internal_leakage": {"C_leak": 3e-12}}
MASS = {"piston_mass": {"m": 20.0}}
VISC = {"viscous_friction": {"b": 3000.0}}
# Where Merritt's model is exact: its single compliance C needs mid-stroke or no flow-pressure slope
# K_c (off mid-stroke with flow the pressure sum couples in); it has no operating-point terms, so no
# moving piston mass (with flow the piston moves: centripetal terms) and no external leakage (the
# chambers drain: P = Ps/2 is then no operating point at rest).
CASES = [(e, 0.0, 0.0) for e in (None, LEAK, MASS, VISC, {**LEAK, **VISC})] + \
        [(e, 20.0, 0.0) for e in (None, LEAK, MASS, VISC)] + [(e, 0.0, 4.0) for e in (None, LEAK, VISC)]


@pytest.mark.parametrize("effects, theta_deg, flow_lpm", CASES)
def test_numerical_linearisation_is_merritts_model(effects, theta_deg, flow_lpm):
    plant = Plant(disc_sets=4, effects=effects)
    lp = LinearPlant(plant, theta_deg=theta_deg, flow_lpm=flow_lpm)
    hand = Merritt.of(plant, theta_deg=theta_deg, flow_lpm=flow_lpm)
    got = lp.tf(delay=False)(1j * W)
    np.testing.assert_allclose(got, hand.freqresp(W), rtol=2e-5)
    assert lp.hydraulic_wn == pytest.approx(hand.hydraulic_wn, rel=1e-5)
    assert lp.velocity_gain == pytest.approx(hand.velocity_gain, rel=1e-5)


@pytest.mark.parametrize("kdp, hp", [(0.02, 0.0), (0.01, 25.0)])
def test_pressure_feedback_closes_as_the_hand_model_says(kdp, hp):
    plant = Plant(disc_sets=6)
    lp = LinearPlant(plant, flow_lpm=3.0)
    hand = Merritt.of(plant, flow_lpm=3.0)
    np.testing.assert_allclose(lp.tf(kdp, hp, delay=False)(1j * W), hand.freqresp(W, kdp, hp), rtol=2e-5)


def test_non_smooth_effects_are_left_out_deliberately():
    plain = LinearPlant(Plant(disc_sets=3))
    dry = LinearPlant(Plant(disc_sets=3, effects={"coulomb_friction": {"Fc": 400.0}, "valve_deadband": {"d": 0.3}}))
    np.testing.assert_allclose(dry.tf(delay=False)(1j * W), plain.tf(delay=False)(1j * W), rtol=1e-9)
    from ehas_env.physics.linearise import linearise

    # asked for, the smoothed sign function's slope Fc / v_tanh appears as a huge damping
    lin = linearise(Plant(disc_sets=3, effects={"coulomb_friction": {"Fc": 400.0}}), keep_nonsmooth=True)
    om = lin.states.index("omega")
    r = 0.05
    assert lin.A[om, om] == pytest.approx(-400.0 / 1e-3 * r * r / (3 * 0.383), rel=1e-3)
    assert math.isfinite(lin.hydraulic_wn_hz())
