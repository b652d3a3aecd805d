"""Runs whose loop does not repeat: an instability is never floor, and two unstable loops are judged on their envelope.

Issue 42's "a visible miss called explained": on the independent generator's transport-delay campaign the true
model's 5-set run oscillates from stroke end to stroke end, out of phase with the rig's; the floor taken from that
run's change from cycle to cycle was thousands of sensor-noise variances and every block sat at 1.0x. Synthetic
signals whose truth is known by construction (no model is compiled); the runs are replayed through
:func:`ehas_env.measurement.verdict.blocks_of`, the function ``compare`` and ``diagnose`` both grade with.

Mutations this file catches (each checked by hand when it was written):

* the cap on a rig that does not repeat while the model does taken out (``not rig_repeats or`` in
  ``residual_floor``): the broad-band instability below is then floor, and the stable model "explained";
* the envelope judgement taken out (``blocks_of`` judging every run on its samples): the two unstable loops of one
  size and of half the size are then both near 1;
* the validation gate judging a run that does not repeat sample by sample again (``verdict.run_residual``
  without its envelope branch): the model without the instability then beats the one with it;
* the fit's cost taking such a run in sample by sample again (``verdict.unpredictable_runs`` returning none);
* its envelope left out of the fit's cost again, or not floored at 1 (``verdict.envelope_cost_block``);
* the confidence intervals taking the envelope rows into their clusters (``fitting.confidence`` without its cut to
  the sample-by-sample rows: a shape error).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from ehas_env.diagnosis.candidates import _parts_cost, lowers_validation, validation_moved
from ehas_env.measurement.replay import Replayer, log_mean
from ehas_env.measurement.verdict import (
    REPEAT_SHARE, blocks_of, envelope_text, grade, loop_repeats, repeat_share)

DT = 1e-3
F = 2.0
T = np.arange(0.0, 3.0, DT)
REF = 30.0 * np.sin(2 * np.pi * F * T)
NOISE = {"theta_deg": 0.01, "p_a_bar": 0.25}


def _unstable(rng, size=1.0):
    """A loop that takes off: an oscillation about 13 Hz (no harmonic of 2 Hz) grown from noise, its phase
    wandering (a band, not one spectral line), saturating at ``size`` times 15 deg."""
    w = np.convolve(rng.standard_normal(T.size), np.ones(25) / 25, mode="same")
    phase = 2 * np.pi * 13.1 * T + np.cumsum(w) * 0.6
    grow = np.tanh(np.exp(3.0 * (T - 1.2)))
    return size * 15.0 * grow * np.sin(phase)


def _rep(measured: dict, name="cl_5sets_30deg_2hz"):
    run = SimpleNamespace(name=name, kind="closed_loop", dt=DT, n=T.size,
                          meta={"reference": {"freq_hz": F, "ramp_cycles": 0}})
    case = SimpleNamespace(run=run, signals=tuple(measured), measured=measured, noise=NOISE, skip=0)
    return SimpleNamespace(cases=[case])


def _replayer(cases):
    """A Replayer holding ``cases`` alone (its cost reads nothing else; no model is compiled)."""
    rep = object.__new__(Replayer)
    rep.cases = list(cases)
    return rep


def _signals(theta, rng):
    return {"theta_deg": theta + NOISE["theta_deg"] * rng.standard_normal(T.size),
            "p_a_bar": 100.0 + 2.0 * (theta - REF) + NOISE["p_a_bar"] * rng.standard_normal(T.size)}


def _model(theta):
    return {"theta_deg": theta, "p_a_bar": 100.0 + 2.0 * (theta - REF)}


def test_a_clean_loop_repeats_and_is_judged_sample_by_sample():
    rng = np.random.default_rng(1)
    rig = _signals(REF, rng)
    assert repeat_share(rig["theta_deg"], DT, F, 0.0) < 0.01
    g = grade(blocks_of(_rep(rig), [_model(REF)], ["theta_deg", "p_a_bar"]))
    assert g["verdict"] == "explained" and g["envelope_runs"] == [] and envelope_text(g) is None


def test_a_rig_that_does_not_repeat_against_a_model_that_does_is_a_miss_not_a_floor():
    """The rig's loop takes off in a broad-band oscillation; the model's tracks the sine: the oscillation is the
    model's miss (thousands of noise variances), not what does not repeat."""
    rng = np.random.default_rng(2)
    rig = _signals(REF + _unstable(rng), rng)
    assert not loop_repeats(rig["theta_deg"], DT, F, 0.0)
    assert loop_repeats(REF, DT, F, 0.0)
    blocks = blocks_of(_rep(rig), [_model(REF)], ["theta_deg", "p_a_bar"])
    g = grade(blocks)
    assert g["verdict"] == "unexplained", g
    assert min(b.x for b in blocks) > 100.0
    assert all(b.judged_on == "samples" for b in blocks)


def test_two_unstable_loops_of_one_size_agree_on_their_envelope_and_half_the_size_does_not():
    """Rig and model both take off (their oscillations from different noise, out of phase): judged on the envelope,
    a model with the rig's instability is not called unexplained (explained on most noise draws: six cycles give
    the envelope's scatter few degrees of freedom), one whose oscillation is half the size is unexplained on every
    draw."""
    same_x, half_x = [], []
    for s in range(8):
        rng = np.random.default_rng(100 + s)
        rig = _signals(REF + _unstable(rng), rng)
        same = _model(REF + _unstable(np.random.default_rng(200 + s)))
        half = _model(REF + _unstable(np.random.default_rng(300 + s), size=0.5))
        for m in (same, half):
            assert repeat_share(m["theta_deg"], DT, F, 0.0) > REPEAT_SHARE
        g_same = grade(blocks_of(_rep(rig), [same], ["theta_deg", "p_a_bar"]))
        g_half = grade(blocks_of(_rep(rig), [half], ["theta_deg", "p_a_bar"]))
        assert g_same["envelope_runs"] == ["cl_5sets_30deg_2hz"] and "judged on the envelope" in envelope_text(g_same)
        assert g_same["verdict"] != "unexplained", g_same
        assert g_half["verdict"] == "unexplained", g_half
        same_x.append(g_same["residual_x_noise"])
        half_x.append(g_half["residual_x_noise"])
        # sample by sample the same pair is hopeless: the oscillations are out of phase
        e = (rig["theta_deg"] - same["theta_deg"]) / NOISE["theta_deg"]
        assert float(np.mean(e ** 2)) > 1e5
    assert sum(x <= 2.0 for x in same_x) >= 6, same_x
    assert min(half_x) > 3.0 * max(same_x), (same_x, half_x)


def test_the_validation_gate_judges_a_held_out_run_that_does_not_repeat_on_its_envelope_as_the_verdict_does():
    """Issue 42's "one figure": on the generator's transport-delay campaign started from rest, the held-out 5-set
    run takes off; the validation gate, judging it sample by sample, refused the true delay (whose model takes off
    as the rig does, out of phase with it) for a model that does not. Held out (``parts`` {0: 0}), a model with the
    rig's instability must lower the validation residual against one without it and one with half of it, on every
    noise draw, as the verdict ranks them."""
    for s in range(6):
        rng = np.random.default_rng(400 + s)
        rig = _signals(REF + _unstable(rng), rng)
        same = _model(REF + _unstable(np.random.default_rng(500 + s)))
        half = _model(REF + _unstable(np.random.default_rng(600 + s), size=0.5))
        stable = _model(REF)
        rep = _rep(rig)
        cost = {k: _parts_cost(rep, [m], {0: 0}) for k, m in (("same", same), ("half", half), ("stable", stable))}
        assert lowers_validation(cost["stable"], cost["same"]), cost
        assert lowers_validation(cost["half"], cost["same"]), cost
        x = {k: grade(blocks_of(rep, [m], ["theta_deg", "p_a_bar"]))["residual_x_noise"]
             for k, m in (("same", same), ("half", half), ("stable", stable))}
        assert x["same"] < min(x["half"], x["stable"]), x  # the verdict's order is the gate's
        # two models that both take off differ on the held-out run by their envelopes, not their phases
        moved = validation_moved(rep, [same], [_model(REF + _unstable(np.random.default_rng(700 + s)))], {0: 0})
        assert moved < validation_moved(rep, [same], [half], {0: 0}) / 2

    # the fit's cost judges the run that does not repeat on its envelope, not its samples (fitted one by one they
    # would pull the numbers to whatever puts a model's oscillation least out of phase with the rig's): the
    # repeating run's two signals first, at the noise, then the unstable run's two envelope blocks
    stable_rig = _rep(_signals(REF, np.random.default_rng(800)), name="cl_3sets_20deg_1hz").cases[0]
    both = _replayer([rep.cases[0], stable_rig])
    blocks = both.cost_blocks([same, _model(REF)])
    assert len(blocks) == 4 and log_mean(blocks[:2]) < 1.2
    assert [b.size for b in blocks[:2]] == [T.size, T.size]  # the samples of the repeating run
    assert len(_replayer(rep.cases).cost_blocks([same])) == 2  # every run unstable: none judged on its envelope


def test_the_fit_is_pulled_toward_the_rigs_instability_and_not_along_it():
    """The fit's cost of a run whose loop does not repeat (``Replayer.cost_blocks``, its envelope blocks in floors,
    at least 1, as the verdict counts a block): a model without the rig's instability, or with half of it, costs far
    more than one with it; one with it sits at exactly 1 on most noise draws (no pull along the noise-made
    envelope), so the fit is not bent by it once the instability is there.  Mutations: the envelope blocks left
    out of the cost again (a stable model then costs as little as one with the instability), or not floored at 1
    (the same-size model then costs below 1 on every draw)."""
    at_one = 0
    for s in range(6):
        rng = np.random.default_rng(900 + s)
        rig = _signals(REF + _unstable(rng), rng)
        stable_rig = _rep(_signals(REF, np.random.default_rng(950 + s)), name="cl_3sets_20deg_1hz").cases[0]
        both = _replayer([_rep(rig).cases[0], stable_rig])
        same = _model(REF + _unstable(np.random.default_rng(1000 + s)))
        half = _model(REF + _unstable(np.random.default_rng(1100 + s), size=0.5))
        # the envelope blocks' mean squares summed (the repeating run's blocks are the same in all three)
        cost = {k: sum(float(np.mean(b ** 2)) for b in both.cost_blocks([m, _model(REF)])[2:]) for k, m in
                (("same", same), ("half", half), ("stable", _model(REF)))}
        assert cost["stable"] > 5.0 * cost["same"] and cost["half"] > 2.0 * cost["same"], cost
        env = both.cost_blocks([same, _model(REF)])[2:]
        assert all(float(np.mean(b ** 2)) >= 1.0 - 1e-12 for b in env)
        at_one += all(abs(float(np.mean(b ** 2)) - 1.0) < 1e-9 for b in env)
    assert at_one >= 4, at_one


class _SyntheticReplayer(Replayer):
    """A Replayer whose "simulation" is a closed form of one fitted number (``viscous_friction.b`` scales the
    pressure's tracking term), over a repeating run and a run whose loop takes off: the fit's machinery (the
    Objective, the confidence intervals) runs on it without compiling a model."""

    def __init__(self, cases, osc):
        self.cases, self.osc, self.substeps, self.n_evals = list(cases), osc, 10, 0

    def simulate_many(self, models, runs=None):
        out = []
        for m in models:
            g = m.effects["viscous_friction"]["b"] / 1000.0
            sims = []
            for case, osc in zip(self.cases, self.osc):
                theta = REF + osc
                sims.append({"theta_deg": theta, "p_a_bar": 100.0 + g * (theta - REF) + 0.5 * g * REF})
            out.append(sims)
            self.n_evals += 1
        return out


def test_the_confidence_intervals_hold_with_a_run_judged_on_its_envelope_in_the_cost():
    """The fit's cost holds a run that does not repeat on its envelope (rows after the sample-by-sample runs'); the
    confidence intervals' clusters are the sample-by-sample runs': an interval is still computed (37d1a52, which
    put the envelope in the cost without this, stopped the confidence intervals with a shape error) and it is the
    one the repeating run alone gives."""
    from ehas_env.diagnosis.fitting import Fit, FreeParam, confidence
    from ehas_env.measurement.replay import ModelSpec

    rng = np.random.default_rng(1200)
    rig_osc = _unstable(rng)
    b_true = 2000.0
    rig = {"theta_deg": REF + rig_osc + NOISE["theta_deg"] * rng.standard_normal(T.size),
           "p_a_bar": 100.0 + 2.0 * rig_osc + 1.0 * REF + NOISE["p_a_bar"] * rng.standard_normal(T.size)}
    steady = {"theta_deg": REF + NOISE["theta_deg"] * rng.standard_normal(T.size),
              "p_a_bar": 100.0 + 1.0 * REF + NOISE["p_a_bar"] * rng.standard_normal(T.size)}
    unstable_case = _rep(rig).cases[0]
    steady_case = _rep(steady, name="cl_3sets_20deg_1hz").cases[0]
    fp = FreeParam("viscous_friction", "b", 0.0, 10000.0, log=False)
    model = ModelSpec(effects={"viscous_friction": {"b": b_true}})

    def ci(cases, osc):
        rep = _SyntheticReplayer(cases, osc)
        sims = rep.simulate_many([model])[0]
        return rep, confidence(rep, Fit(model, rep.log_cost(sims), [fp], sims, None))[("viscous_friction", "b")]

    rep, both = ci([unstable_case, steady_case], [_unstable(np.random.default_rng(1201)), 0.0 * T])
    assert len(rep.cost_blocks(rep.simulate_many([model])[0])) == 4  # two sample blocks, two envelope blocks
    _, alone = ci([steady_case], [0.0 * T])
    assert both[0] < b_true < both[1]
    assert both == pytest.approx(alone, rel=1e-6)
