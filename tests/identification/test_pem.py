"""ARMAX, OE, BJ (prediction-error method) and N4SID state space against known discrete systems.

Truth: a second-order plant B/F = (q^-1 + 0.5 q^-2) / (1 - 1.5 q^-1 + 0.7 q^-2) with the noise structure of
each model family, simulated by scipy.signal.lfilter / python-control from numpy noise of fixed seeds.  The
tolerance on each coefficient is 4 of its own standard errors (a calibrated estimate is outside with
probability 6e-5); the standard errors are checked for calibration by Monte Carlo.
"""
from __future__ import annotations

import control
import numpy as np
import pytest
from scipy.signal import lfilter

from ehas_env.identification.fit import residual_analysis
from ehas_env.identification.pem import check_orders, estimate

N = 3000
B = [1.0, 0.5]
F = [1.0, -1.5, 0.7]
C = [1.0, 0.5]
D = [1.0, -0.9]
SIGMA = 0.2


def data(structure, seed=3, n=N, sigma=SIGMA):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.normal(size=n))  # a random binary input
    e = sigma * rng.normal(size=n)
    b = [0.0] + B  # nk = 1
    if structure == "armax":
        y = lfilter(b, F, u) + lfilter(C, F, e)
    elif structure == "oe":
        y = lfilter(b, F, u) + e
    elif structure == "bj":
        y = lfilter(b, F, u) + lfilter(C, D, e)
    else:
        raise ValueError(structure)
    return u, y


TRUTH = {  # structure: (orders, true parameters in MATLAB's order a, b, c, d, f)
    "armax": ({"na": 2, "nb": 2, "nc": 1, "nk": 1}, F[1:] + B + C[1:]),
    "oe": ({"nb": 2, "nf": 2, "nk": 1}, B + F[1:]),
    "bj": ({"nb": 2, "nc": 1, "nd": 1, "nf": 2, "nk": 1}, B + C[1:] + D[1:] + F[1:]),
}


def white(m, u):
    ra = residual_analysis(m.residuals, u, max_lag=25)
    return ra.auto_outside() <= max(1, round(0.01 * ra.lags.size))


@pytest.mark.parametrize("structure", ["armax", "oe", "bj"])
def test_matching_structure_recovers_the_truth_within_4_standard_errors_and_leaves_white_residuals(structure):
    u, y = data(structure)
    orders, truth = TRUTH[structure]
    m = estimate(structure, u, y, orders)
    err = np.abs(m.theta - np.asarray(truth))
    assert np.all(err < 4 * m.std), dict(zip(m.names, zip(m.theta, m.std, truth)))
    assert np.all(m.std < 0.05), m.std  # the tolerance is not vacuous
    # the innovation variance is the noise's, and the prediction errors are white
    assert m.noise_variance == pytest.approx(SIGMA ** 2, rel=0.08)
    assert white(m, u)
    # the fit is the NRMSE of the noise-free simulation, and that is the truth's simulation
    y0 = lfilter([0.0] + B, F, u)
    assert np.max(np.abs(m.y_sim - y0)) < 0.05 * np.max(np.abs(y0))


@pytest.mark.parametrize("structure, wrong", [("armax", "oe"), ("bj", "oe"), ("bj", "arx"), ("oe", "arx")])
def test_a_structure_whose_noise_model_is_wrong_leaves_coloured_residuals(structure, wrong):
    u, y = data(structure)
    m = estimate(wrong, u, y, {"arx": {"na": 2, "nb": 2, "nk": 1}, "oe": {"nb": 2, "nf": 2, "nk": 1}}[wrong])
    assert not white(m, u)
    assert white(estimate(structure, u, y, TRUTH[structure][0]), u)


def test_the_standard_errors_are_calibrated_over_seeds():
    """40 seeds of the OE case: each coefficient inside +-2 standard errors in 85..100 % of them (95 % expected)."""
    orders, truth = TRUTH["oe"]
    inside = np.zeros(4)
    for seed in range(40):
        u, y = data("oe", seed=100 + seed, n=1500)
        m = estimate("oe", u, y, orders)
        inside += np.abs(m.theta - truth) < 2 * m.std
    assert np.all(inside >= 0.85 * 40), inside


@pytest.mark.parametrize("structure", ["armax", "oe", "bj"])
def test_models_convert_to_python_control_with_the_same_response(structure):
    u, y = data(structure)
    m = estimate(structure, u, y, TRUTH[structure][0])
    G = m.tf()
    assert G.dt == 1.0
    y_ctrl = control.forced_response(G, U=u).outputs
    assert np.allclose(y_ctrl, m.y_sim, atol=1e-8 * np.max(np.abs(y_ctrl)))
    # its poles are the truth's (within the estimate's accuracy)
    assert np.sort_complex(G.poles()) == pytest.approx(np.sort_complex(np.roots(F)), abs=0.01)
    H = m.noise_tf()
    if structure == "oe":
        assert np.allclose(np.squeeze(H.num[0][0]), np.squeeze(H.den[0][0]))


def test_one_step_prediction_of_armax_is_the_truth_minus_the_innovation():
    """With the true noise model the one-step prediction error is the white noise itself (up to the estimate)."""
    rng = np.random.default_rng(9)
    u = np.sign(rng.normal(size=N))
    e = SIGMA * rng.normal(size=N)
    y = lfilter([0.0] + B, F, u) + lfilter(C, F, e)
    m = estimate("armax", u, y, TRUTH["armax"][0])
    yhat = m.predict(u, y, 1)
    assert np.std((y - yhat)[50:] - e[50:]) < 0.1 * SIGMA
    # k -> large: the prediction tends to the simulation
    assert np.allclose(m.predict(u, y, 400)[500:], m.y_sim[500:], atol=1e-6)


def test_n4sid_state_space_recovers_the_poles_and_the_response():
    pytest.importorskip("nfoursid", reason="structure ss needs the optional package nfoursid (ehas[ident])")
    u, y = data("oe", seed=5)
    m = estimate("ss", u, y, {"nx": 2})
    poles = np.sort_complex(np.linalg.eigvals(m.A))
    assert poles == pytest.approx(np.sort_complex(np.roots(F)), abs=0.01)
    truth = control.tf([0.0, 1.0, 0.5], [1.0, -1.5, 0.7], 1.0)
    y0 = control.forced_response(truth, U=u).outputs
    sys = m.ss()
    assert sys.dt == 1.0 and sys.nstates == 2
    y_ctrl = control.forced_response(sys, U=u).outputs
    assert np.allclose(y_ctrl, m.y_sim, atol=1e-8 * np.max(np.abs(y0)))
    assert 100 * (1 - np.linalg.norm(y0 - m.y_sim) / np.linalg.norm(y0 - y0.mean())) > 98.0
    # the innovations of white output noise are white, with the noise's variance
    assert m.noise_variance == pytest.approx(SIGMA ** 2, rel=0.1)
    assert white(m, u)
    # the subspace's singular values drop after the true order
    sv = m.singular_values
    assert sv[1] > 10 * sv[2]


@pytest.mark.parametrize("structure, orders, words", [
    ("armax", {"nf": 2}, "nf does not belong to structure armax"),
    ("oe", {"nb": 0}, "nb must be an integer in [1, 20]"),
    ("bj", {"nc": -1}, "nc must be an integer in [0, 20]"),
    ("arx", {"na": 2.5}, "na must be an integer"),
    ("ss", {"nx": 10 ** 6}, "nx must be an integer in [1, 20]"),
    ("arx", {"nk": float("nan")}, "nk must be an integer"),
    ("nope", {}, "structure must be one of arx, armax, oe, bj, ss"),
])
def test_bad_orders_are_one_line(structure, orders, words):
    with pytest.raises(ValueError) as info:
        check_orders(structure, orders)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_too_short_a_record_is_refused():
    u, y = data("oe", n=60)
    with pytest.raises(ValueError, match="too short"):
        estimate("bj", u, y, {"nb": 5, "nc": 5, "nd": 5, "nf": 5})
