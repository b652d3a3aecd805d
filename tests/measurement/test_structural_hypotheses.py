"""The structural hypotheses found inside the full model (issue 20): a campaign whose rig holds a baseline
constant or law the library's effects do not have is explained by the hypothesis that opens it, with the
truth's values, and nothing else is kept.

Truth: campaigns simulated with the hypothesis itself switched on (known values); the independent generator's
wider set (tests/independent_rig, results/diagnosis_open_world) is the acceptance on physics that is not ours.
"""
from __future__ import annotations

import pytest

from ehas_env.measurement.campaign import Campaign, validate_run
from ehas_env.diagnosis.pipeline import diagnose_open
from ehas_env.measurement.synthetic import simulate_campaign

PLAN = ((3, 20.0, 1.0), (5, 30.0, 2.0), (1, 35.0, 3.0), (7, 10.0, 3.0))


def _campaign(effects, seed):
    runs, _ = simulate_campaign(effects, seed=seed, duration=3.0, plan=PLAN)
    return Campaign(None, [validate_run(n, c, m) for n, c, m in runs])


@pytest.mark.slow
def test_an_unbalance_between_the_sine_and_cosine_axes_is_found_whole():
    """The main parameter alone (T_sin, T_cos at 0) cannot beat the null model for an unbalance 60 deg off the
    sine's axis: the screening must fit both together (it once left this unexplained)."""
    res = diagnose_open(_campaign({"hyp_crank_unbalance": {"T_sin": 12.5, "T_cos": 21.65}}, seed=41))
    assert res.verdict == "explained", res.to_json().get("unexplained")
    assert res.hypothesis == "hyp_crank_unbalance"
    fitted = res.model.effects["hyp_crank_unbalance"]
    assert fitted["T_sin"] == pytest.approx(12.5, rel=0.1) and fitted["T_cos"] == pytest.approx(21.65, rel=0.1)
    assert [n for n in res.model.effects if n != "hyp_crank_unbalance"] == []  # nothing kept beside it


@pytest.mark.slow
def test_a_sensor_zero_offset_is_named_on_the_measurement_side():
    res = diagnose_open(_campaign({"hyp_position_offset": {"x0": 2.0}}, seed=42))
    assert res.hypothesis == "hyp_position_offset", (res.kept, res.verdict)
    assert res.model.effects["hyp_position_offset"]["x0"] == pytest.approx(2.0, rel=0.15)


@pytest.mark.slow
def test_a_coil_lag_is_named_not_a_transport_delay_or_a_slower_spool():
    """A coil lag is mistaken for a transport delay or a slower spool by the library (both lower the residual):
    fitted in their place (Effect.mistaken_for) it does better on the validation data and replaces them."""
    res = diagnose_open(_campaign({"hyp_coil_lag": {"T": 5.0}}, seed=43))
    assert res.hypothesis == "hyp_coil_lag", (res.kept, res.verdict)
    assert res.model.effects["hyp_coil_lag"]["T"] == pytest.approx(5.0, rel=0.15)
    assert not {"transport_delay", "valve_dynamics"} & set(res.model.effects)
    stood_in = [s for s in res.steps if s.effect in ("transport_delay", "valve_dynamics") and not s.kept]
    assert stood_in and "stands in for hyp_coil_lag" in stood_in[0].reason


@pytest.mark.slow
def test_a_lugre_friction_is_named_not_the_coulomb_friction_kept_first():
    """LuGre seal friction (450 N sliding, a presliding state) is taken by the library for a Coulomb friction of
    about 300 N; screened on top of it, the LuGre law has no level left to show its presliding state with (the
    independent generator's campaign of it, faded in: unexplained 4.82 with Coulomb friction kept, the law screened
    at -0.8 dB).  Fitted in the Coulomb friction's place (``Effect.mistaken_for``) it replaces it with its level."""
    res = diagnose_open(_campaign({"hyp_lugre_friction": {"Fc": 450.0, "r_s": 1.5, "sigma2": 300.0}}, seed=46))
    assert res.hypothesis == "hyp_lugre_friction", (res.kept, res.verdict)
    assert res.model.effects["hyp_lugre_friction"]["Fc"] == pytest.approx(450.0, rel=0.15)
    assert "coulomb_friction" not in res.model.effects


@pytest.mark.slow
def test_a_transport_delay_stays_a_transport_delay():
    """The converse: a delay (the library's effect) is not replaced by the coil lag it could be mistaken for."""
    res = diagnose_open(_campaign({"transport_delay": {"tau": 0.004}}, seed=44))
    assert "transport_delay" in res.model.effects and "hyp_coil_lag" not in res.model.effects, res.kept
    assert res.model.effects["transport_delay"]["tau"] == pytest.approx(0.004, rel=0.15)


@pytest.mark.slow
def test_a_crank_angle_offset_is_named_with_its_angle():
    res = diagnose_open(_campaign({"hyp_crank_offset": {"phi0": 12.0}}, seed=45))
    assert res.hypothesis == "hyp_crank_offset", (res.kept, res.verdict)
    assert res.model.effects["hyp_crank_offset"]["phi0"] == pytest.approx(12.0, rel=0.15)


@pytest.mark.slow
def test_a_coil_lag_hidden_behind_a_leakage_is_found_by_searching_again_in_its_place():
    """A coil's lag beside an orifice leakage: fitted in place of the spool's dynamics alone, the lag loses on the
    validation data (the faster-fitted spool absorbs part of the leakage), and the leakage found on top of the
    spool's dynamics drifts between groups of runs.  Put in the spool dynamics' place with the hypotheses searched
    again on top of it, both are found."""
    res = diagnose_open(_campaign({"hyp_coil_lag": {"T": 2.0}, "hyp_turbulent_leakage": {"q_100": 0.4}}, seed=46))
    assert {"hyp_coil_lag", "hyp_turbulent_leakage"} <= set(res.model.effects), (res.kept, res.verdict)
    assert res.model.effects["hyp_coil_lag"]["T"] == pytest.approx(2.0, rel=0.2)
    assert res.model.effects["hyp_turbulent_leakage"]["q_100"] == pytest.approx(0.4, rel=0.2)
    assert res.verdict == "explained"


@pytest.mark.slow
def test_air_in_the_oil_is_named_not_a_lower_constant_bulk_modulus():
    """Air in the oil softens it at low pressure only.  The library's constant bulk modulus takes up part of that
    (it lowers the residual and fits alike on separate groups of runs); fitted in its place (Effect.mistaken_for)
    the pressure-dependent law does better on the validation data and replaces it."""
    res = diagnose_open(_campaign({"hyp_entrained_air": {"air": 25.0}}, seed=47))
    assert res.hypothesis == "hyp_entrained_air", (res.kept, res.verdict)
    assert res.model.effects["hyp_entrained_air"]["air"] == pytest.approx(25.0, rel=0.2)
    assert "bulk_modulus" not in res.model.effects
    assert any(s.effect == "bulk_modulus" and "stands in for hyp_entrained_air" in s.reason for s in res.steps)


@pytest.mark.slow
def test_a_lower_constant_bulk_modulus_stays_a_bulk_modulus():
    """The converse: oil that is softer at every pressure (the library's recalibration) is not named air."""
    res = diagnose_open(_campaign({"bulk_modulus": {"beta": 7.5e8}}, seed=48))
    assert "bulk_modulus" in res.model.effects and "hyp_entrained_air" not in res.model.effects, res.kept
    assert res.model.effects["bulk_modulus"]["beta"] == pytest.approx(7.5e8, rel=0.1)


def _perturbed(effects, seed):
    """A campaign as ``ehas simulate-campaign --perturb`` writes it: beta and K drawn, 4 closed-loop runs and a
    valve chirp, 3 s each."""
    runs, _ = simulate_campaign(effects, seed=seed, perturb=True, duration=3.0)
    return Campaign(None, [validate_run(n, c, m) for n, c, m in runs])


@pytest.mark.slow
def test_two_small_effects_neither_of_which_is_kept_alone_are_kept_together():
    """A sensor zero offset of 0.7 mm and a speed-squared drag of 2 N m at 10 rad/s: the library explains the
    campaign (1.3 x what does not repeat) and neither hypothesis alone is kept; fitted together they remove most
    of the rest, each earns its parameter on top of the other, and both are found at the truth's values."""
    res = diagnose_open(_perturbed({"hyp_position_offset": {"x0": 0.7}, "hyp_quadratic_drag": {"T_10": 2.0}}, 5))
    assert res.verdict == "explained"
    assert set(res.model.effects) == {"hyp_position_offset", "hyp_quadratic_drag"}, res.kept
    assert all("kept together with" in s.reason for s in res.steps if s.kept)
    for (e, p), truth in {("hyp_position_offset", "x0"): 0.7, ("hyp_quadratic_drag", "T_10"): 2.0}.items():
        lo, hi = res.ci[(e, p)]
        assert res.model.effects[e][p] == pytest.approx(truth, rel=0.1) and lo < truth * 1.05 and hi > truth * 0.95


@pytest.mark.slow
def test_a_pair_that_does_not_beat_the_noise_together_is_not_kept():
    """A 0.5 mm zero offset with 3 % of air in the oil leave 1.09 x what does not repeat: the diagnosis fits the
    best pair of hypotheses together, and keeps neither when the pair does not beat the noise (the bar every
    effect must clear); the campaign stays explained with nothing named."""
    res = diagnose_open(_perturbed({"hyp_position_offset": {"x0": 0.5}, "hyp_entrained_air": {"air": 3.0}}, 3))
    assert res.verdict == "explained"
    tried = [s for s in res.steps if s.reason.startswith("fitted together with")]
    assert tried and not tried[0].kept and "do not beat the noise" in tried[0].reason, [s.reason for s in res.steps]
    assert not [n for n in res.model.effects if n.startswith("hyp_")], res.kept
