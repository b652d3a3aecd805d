"""The confidence interval of one fitted number (issue 36): never an OverflowError, an unbounded side said as such.

``ehas diagnose --stack`` stopped with "internal error: OverflowError: math range error" on a campaign
with supply-pressure droop and friction: a poorly determined log-scaled number had a standard deviation
(in its fit range mapped to [0, 1]) so large that ``exp(t sd log(hi/lo))`` left the floating-point range.
"""
from __future__ import annotations

import json
import math

import pytest

from ehas_env.diagnosis.fitting import FreeParam, interval


BETA = FreeParam(None, "beta", 1e8, 1e10, log=True)  # spans two decades: L = ln(100)
FC = FreeParam("coulomb_friction", "Fc", 0.0, 1000.0, log=False)


def test_a_log_scaled_interval_is_multiplicative():
    # sd 0.1 of the range in u, t = 2: the interval is v x/÷ 100^0.2 = 2.51188643...
    lo, hi = interval(BETA, 1e9, 0.1, 2.0)
    assert hi == pytest.approx(1e9 * 2.51188643150958, rel=1e-12)
    assert lo == pytest.approx(1e9 / 2.51188643150958, rel=1e-12)


def test_a_linear_interval_is_symmetric():
    assert interval(FC, 300.0, 0.05, 2.0) == pytest.approx((200.0, 400.0), rel=1e-12)


def test_a_poorly_determined_log_number_is_unbounded_above_not_an_overflow():
    # sd 500 in u: exp(2 * 500 * ln 100) = exp(4605) overflows a float (was: OverflowError: math range error)
    lo, hi = interval(BETA, 1e9, 500.0, 2.0)
    assert hi == math.inf
    assert lo == 0.0
    # just below the edge it is still a number
    e_max = math.log(1.7e308 / 1e9)
    lo, hi = interval(BETA, 1e9, 0.999 * e_max / (2.0 * math.log(100.0)), 2.0)
    assert math.isfinite(hi) and hi > 1e300


@pytest.mark.parametrize("sd", [math.inf, math.nan])
def test_an_undetermined_number_is_unbounded_on_both_sides(sd):
    assert interval(BETA, 1e9, sd, 2.0) == (0.0, math.inf)
    assert interval(FC, 300.0, sd, 2.0) == (-math.inf, math.inf)


def test_compare_prints_and_stores_an_unbounded_interval_as_such():
    """ehas compare's rows: an infinite bound is null in JSON (strict JSON has no Infinity) and "unbounded" in print."""
    from ehas_env.cli.compare import describe_model
    from ehas_env.measurement.replay import ModelSpec

    row = {"effect": "coulomb_friction", "param": "Fc", "value": 300.0, "low": 12.5, "high": None, "unit": "N"}
    json.dumps([row], allow_nan=False)
    text = describe_model(ModelSpec(effects={"coulomb_friction": {"Fc": 300.0}}), ci=[row])
    assert "Fc = 300 N (95 % CI 12.5 to unbounded)" in text


def test_a_number_the_data_do_not_inform_is_unbounded_not_exactly_known():
    """On the valve bench alone (its ports joined through the meter, no piston) the valve's gain K is fitted and
    known to a fraction of a percent; a friction on the piston does not enter the bench's replay at all: its
    interval is the whole range the effect allows, not the zero width the pseudo-inverse gives a number with no
    variance."""
    from ehas_env.diagnosis.fitting import baseline_params, confidence, fit, own_params, start_value
    from ehas_env.measurement.campaign import Campaign, validate_run
    from ehas_env.measurement.replay import ModelSpec, Replayer
    from ehas_env.measurement.synthetic import simulate_campaign
    from ehas_env.physics.effects import get_effect

    runs, _ = simulate_campaign(seed=5, plan=(), duration=2.0)
    rep = Replayer(Campaign(None, [validate_run(n, c, m) for n, c, m in runs]))
    assert [c.run.kind for c in rep.cases] == ["valve_open_loop"]
    free = [fp for fp in baseline_params() if fp.name == "K"] + own_params("coulomb_friction")
    f = fit(rep, free, {(fp.effect, fp.name): start_value(fp) for fp in free},
            ModelSpec(effects={"coulomb_friction": {}}), max_nfev=8, tol=1e-3)
    ci = confidence(rep, f)
    k_lo, k_hi = ci[(None, "K")]
    assert 0.0 < (k_hi - k_lo) < 0.05 * f.model.K
    # unbounded either way: the whole range the effect allows
    assert ci[("coulomb_friction", "Fc")] == get_effect("coulomb_friction").param("Fc").bounds
