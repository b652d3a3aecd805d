"""Tuners: the margins they report, the relay's ultimate gain, the optimiser's guarantee, schedules.

Truth used: python-control's own margin computation on the linear model, the
nonlinear plant (ehas_env's kernel) for steps and the relay test, and the
independent closed loop of Plant.simulate_closed_loop for the optimiser's result.
"""
from __future__ import annotations

import math

import control
import numpy as np
import pytest

from ehas_controllers.batch_sim import Batch, Condition, grid
from ehas_controllers.linear_model import LinearPlant, operating_flow_lpm
from ehas_controllers.piff import PIFF, GainSchedule
from ehas_controllers.tuners import (design_pi, relay_experiment, tune_model_based, tune_optimize, tune_relay,
                                     tune_schedule)
from ehas_env.simulation.plant import Plant


def _loop(ctrl, lp):
    return control.tf([ctrl.Kp, ctrl.Ki], [1.0, 0.0]) * lp.tf(ctrl.Kdp, ctrl.dp_hp)


@pytest.mark.parametrize("n, pm", [(1, 40.0), (3, 50.0), (7, 60.0)])
def test_model_based_loop_has_the_phase_margin_it_reports(n, pm, tmp_path):
    res = tune_model_based(n, phase_margin_deg=pm, bode_path=tmp_path / "bode.png")
    assert res.report["phase_margin_deg"] == pytest.approx(pm, abs=1.0)
    # python-control on a freshly built linear model at the reported operating point
    lp = LinearPlant(Plant(disc_sets=n), flow_lpm=operating_flow_lpm(20.0, 2.0))
    gm, pm_check, _, _, wgc, _ = control.stability_margins(_loop(res.controller, lp))
    assert pm_check == pytest.approx(res.report["phase_margin_deg"], abs=0.05)
    assert wgc / (2 * math.pi) == pytest.approx(res.report["crossover_hz"], rel=1e-3)
    assert 20 * math.log10(gm) >= 6.0 - 1e-6
    assert (tmp_path / "bode.png").stat().st_size > 10_000
    assert any("phase margin" in line for line in res.lines)


def _step_overshoot_nonlinear(ctrl, n, step_deg=0.2):
    batch = Batch([Condition(n, 2.0, step_deg)], cycles=3, step=True)
    _, tr = batch.run(np.array([ctrl.Kp, ctrl.Ki, 0, 0, 0, ctrl.Kdp, ctrl.dp_hp]), trace=True)
    return 100.0 * (tr[0, :, 0].max() / step_deg - 1.0)


def _step_overshoot_linear(ctrl, lp):
    t = np.arange(0.0, 1.0, 1e-4)
    _, y = control.step_response(control.feedback(_loop(ctrl, lp), 1), t)
    return 100.0 * (y.max() - 1.0)


@pytest.mark.parametrize("n", [1, 3, 7])
def test_nonlinear_step_overshoot_is_consistent_with_the_margin(n):
    """A 0.2 deg step on the nonlinear plant overshoots as the linear loop at that operating point.

    A small step runs the valve near null flow, so the linear model at null flow is
    the one to compare; and the overshoot falls as the designed margin rises.
    """
    lp0 = LinearPlant(Plant(disc_sets=n), flow_lpm=0.0)
    overshoots = []
    for pm in (35.0, 50.0, 65.0):
        ctrl = tune_model_based(n, phase_margin_deg=pm).controller
        os_nl = _step_overshoot_nonlinear(ctrl, n)
        os_lin = _step_overshoot_linear(ctrl, lp0)
        assert os_nl == pytest.approx(os_lin, abs=2.5)
        overshoots.append(os_nl)
    assert overshoots[0] > overshoots[1] > overshoots[2] > 0.0


def test_bandwidth_target_is_met_or_refused():
    lp = LinearPlant(disc_sets=3, flow_lpm=3.0)
    d = design_pi(lp.tf(), phase_margin_deg=60.0, bandwidth_hz=2.0)
    assert d["crossover_hz"] == pytest.approx(2.0, rel=0.01)
    assert d["phase_margin_deg"] == pytest.approx(60.0, abs=0.5)
    with pytest.raises(ValueError, match="lower the bandwidth"):
        design_pi(lp.tf(), phase_margin_deg=60.0, bandwidth_hz=12.0)


@pytest.mark.parametrize("n", range(1, 8))
def test_relay_ultimate_gain_matches_the_linear_model(n):
    rel = relay_experiment(disc_sets=n, relay_mA=1.0)
    ku_lin, wu_lin = LinearPlant(disc_sets=n).ultimate()
    assert rel["Ku"] == pytest.approx(ku_lin, rel=0.10)
    assert rel["wu"] == pytest.approx(wu_lin, rel=0.10)


def test_relay_rules():
    zn = tune_relay(3, rule="zn")
    tl = tune_relay(3, rule="tl")
    ku, tu = zn.report["Ku"], zn.report["Tu"]
    assert zn.controller.Kp == pytest.approx(0.45 * ku) and zn.controller.Ki == pytest.approx(0.45 * ku / (tu / 1.2))
    assert tl.controller.Kp == pytest.approx(ku / 3.2) and tl.controller.Ki == pytest.approx(ku / 3.2 / (2.2 * tu))
    with pytest.raises(ValueError, match="rule must be one of"):
        tune_relay(3, rule="magic")


@pytest.mark.parametrize("amp", [1e-308, 0.001, 0.0, -1.0, float("nan"), 25.0])
def test_relay_amplitude_out_of_range_names_relay_mA(amp):
    """Below one step of the rig's 12-bit output (0.0098 mA) the relay does not move the valve."""
    with pytest.raises(ValueError, match=r"relay_mA \(the relay amplitude\) must be a number in \[0.01, 20\] mA"):
        relay_experiment(disc_sets=3, relay_mA=amp)


def test_relay_without_oscillation_names_relay_mA():
    with pytest.raises(ValueError, match=r"no sustained oscillation in 0.05 s with relay_mA = 1 mA \(--relay-mA\)"):
        relay_experiment(disc_sets=3, relay_mA=1.0, duration_s=0.05)


def test_cli_relay_amplitude_too_small(tmp_path, capsys):
    from ehas_env.cli.main import main

    assert main(["tune", "--method", "relay", "--relay-mA", "1e-308", "--out", str(tmp_path / "c.json"),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--relay-mA must be a number in [0.01, 20] mA, got '1e-308'" in err[0], err
    assert not list(tmp_path.iterdir())


def _independent_cost(ctrl, conds, cycles):
    """Mean rms % error (+100 per stroke-end hit) from Plant.simulate_closed_loop, not the batch simulator."""
    total = 0.0
    for c in conds:
        run = Plant(disc_sets=c.disc_sets).simulate_closed_loop(ctrl.rig_gains(), amplitude_deg=c.amplitude_deg,
                                                                freq_hz=c.freq_hz, cycles=cycles)
        total += run.tracking_errors()["rms_error_pct"] + 100.0 * run.hit_stroke_end
    return total / len(conds)


@pytest.mark.parametrize("start", [
    tune_model_based(4).controller,  # a good start: few evaluations rarely improve it
    PIFF(Kp=0.05, Ki=0.0, Kv=0.012, Ka=0.0),  # a poor start
])
def test_optimiser_never_returns_gains_worse_than_its_start(start):
    conds = [Condition(4, 3.0, 20.0), Condition(4, 1.0, 30.0)]
    res = tune_optimize(start, conds, max_evals=12, cycles=3, progress=False)
    before = _independent_cost(start, conds, 3)
    after = _independent_cost(res.controller, conds, 3)
    assert res.report["objective_start"] == pytest.approx(before, rel=1e-9)
    assert after <= before + 1e-12
    assert after == pytest.approx(res.report["objective_best"], rel=1e-9)


def test_optimiser_improves_a_poor_start_in_worst_case_mode():
    start = PIFF(Kp=0.05, Ki=0.0, Kv=0.012, Ka=0.0)
    res = tune_optimize(start, [Condition(2, 2.0, 20.0), Condition(2, 1.0, 10.0)], objective="worst", max_evals=30,
                        cycles=3, progress=False)
    assert res.report["objective_best"] < 0.8 * res.report["objective_start"]
    with pytest.raises(ValueError, match="objective must be"):
        tune_optimize(start, grid([1]), objective="median")
    with pytest.raises(ValueError, match="unknown gain"):
        tune_optimize(start, grid([1]), params=["Kz"])


def test_schedule_holds_one_design_per_disc_set():
    res = tune_schedule("model", [1, 7])
    sched = res.controller
    assert isinstance(sched, GainSchedule) and list(sched.entries) == [1, 7]
    # the heavier load has less gain margin, so its proportional gain is lower
    assert sched.entries[7].Kp < sched.entries[1].Kp
    assert sched.entries[1].Kp == pytest.approx(tune_model_based(1).controller.Kp)
    assert sched.for_plant(4).Kp == pytest.approx(0.5 * (sched.entries[1].Kp + sched.entries[7].Kp))
    with pytest.raises(ValueError, match="schedule method"):
        tune_schedule("guess", [1])
