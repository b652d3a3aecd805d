"""Transfer-function estimation against independent truth: a simulated valve of
known parameters, the book's own coefficients, python-control's simulation,
a hand-written NRMSE and textbook correlation properties."""
from __future__ import annotations

import dataclasses
import json
import math

import control
import numpy as np
import pytest

from conftest import read_book_csv
from ehas_env.identification import fit as ID
from ehas_env.cli.main import main
from ehas_env.identification.excitation import chirp, prbs, prms
from ehas_env.simulation.plant import Plant
from ehas_env.simulation.sensors import Sensors

KNOWN = {"K": 1.10, "wn": 150.0, "zeta": 0.50}  # a valve that is not the default one


def known_valve_run(signal, seed=3, noise=0.05):
    sensors = dataclasses.replace(Sensors(), flow_noise_lpm=noise)
    plant = Plant(effects={"valve_dynamics": KNOWN}, sensors=sensors, seed=seed)
    res = plant.simulate_valve_test(signal.current_mA, supply_bar=70.0)
    return res.t, res.current_mA, res.logged["flow_lpm"]


# -- acceptance: a noisy chirp run of a known valve ----------------------------

def test_noisy_chirp_of_a_known_valve_gives_K_wn_zeta_within_2_percent():
    sig = chirp(duration=8.0, f0=0.5, f1=40.0, amplitude=12.0, method="log")
    t, u, y = known_valve_run(sig)
    est = ID.tfest(t, u, y, n_poles=2, n_zeros=0)
    so = est.second_order()
    for key, truth in KNOWN.items():
        assert so[key] == pytest.approx(truth, rel=0.02), key
    # the noise is 0.05 LPM white: the residual is that noise and nothing else
    assert np.std(est.residuals) == pytest.approx(0.05, rel=0.1)
    ra = ID.residual_analysis(est.residuals, u)
    assert ra.auto_outside() <= 2 and ra.cross_outside() <= 2


def test_the_book_coefficients_give_the_book_parameters(tmp_path, capsys):
    row = read_book_csv("valve_identification.csv")[0]  # independent truth in tests/data/book
    num, den = [float(row["b0"])], [1.0, float(row["a1"]), float(row["a0"])]
    p = ID.second_order_parameters(num, den)
    assert (round(p["K"], 3), round(p["wn"], 1), round(p["zeta"], 3)) == (1.272, 107.0, 0.691)
    out = tmp_path / "book.json"
    assert main(["identify", "--num", row["b0"], "--den", f"1,{row['a1']},{row['a0']}", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "K = 1.2723" in text and "wn = 107.00 rad/s" in text and "zeta = 0.691" in text
    js = json.loads(out.read_text())
    assert js["den"] == [1.0, 147.83, 11449.86] and round(js["K"], 3) == 1.272 and js["fit_percent"] is None


# -- the fitted model simulates as python-control does --------------------------

@pytest.mark.parametrize("intersample", ["foh", "zoh"])
def test_simulated_output_equals_control_forced_response(intersample):
    sig = prms(duration=3.0, amplitude=15.0, hold=0.005, seed=2)
    t, u, y = known_valve_run(sig)
    est = ID.tfest(t, u, y, 2, 1, intersample=intersample)
    if intersample == "foh":
        ref = control.forced_response(est.tf, t, u).outputs  # linear interpolation between samples
    else:
        ref = control.forced_response(control.sample_system(est.tf, t[1] - t[0], "zoh"), t, u).outputs
    np.testing.assert_allclose(est.y_sim, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())


def test_fit_percent_is_the_nrmse_computed_by_hand():
    sig = chirp(duration=4.0, f0=0.5, f1=30.0, amplitude=15.0, method="log")
    t, u, y = known_valve_run(sig, noise=0.5)
    est = ID.tfest(t, u, y, 2, 0)
    y_hat = control.forced_response(control.sample_system(est.tf, 1e-3, "zoh"), t, u).outputs
    by_hand = 100.0 * (1.0 - math.sqrt(sum((a - b) ** 2 for a, b in zip(y, y_hat)))
                       / math.sqrt(sum((a - y.mean()) ** 2 for a in y)))
    assert est.fit_percent == pytest.approx(by_hand, abs=1e-8)
    assert 90 < est.fit_percent < 99.5  # the 0.5 LPM noise costs a few per cent


def test_exact_recovery_of_a_third_order_model_with_a_zero():
    truth = control.tf([30.0, 600.0], np.polymul([1.0, 10.0], [1.0, 2 * 0.3 * 40.0, 1600.0]))
    sig = prbs(duration=6.0, amplitude=1.0, hold=0.004, seed=1)
    y = ID.simulate_tf(truth, sig.t, sig.current_mA)
    est = ID.tfest(sig.t, sig.current_mA, y, n_poles=3, n_zeros=1)
    np.testing.assert_allclose(est.den, np.squeeze(truth.den[0][0]), rtol=1e-6)
    np.testing.assert_allclose(est.num, np.squeeze(truth.num[0][0]), rtol=1e-6)
    assert est.fit_percent > 99.9999


def test_a_larger_model_never_fits_worse_on_the_same_data():
    sig = chirp(duration=5.0, f0=0.5, f1=2.0, amplitude=20.0)
    t, u, y = known_valve_run(sig, noise=0.8)
    fits = [ID.tfest(t, u, y, 2, nz).fit_percent for nz in (0, 1)]
    assert fits[1] >= fits[0] - 1e-9


def test_initial_state_estimation_for_a_record_cut_mid_run():
    truth = control.tf([1.27 * 107.0**2], [1.0, 2 * 0.69 * 107.0, 107.0**2])
    sig = prbs(duration=4.0, amplitude=10.0, hold=0.01, seed=5)
    y = ID.simulate_tf(truth, sig.t, sig.current_mA)
    cut = 1505  # mid-flight: the valve is moving when the record starts
    t, u, y = sig.t[cut:] - sig.t[cut], sig.current_mA[cut:], y[cut:]
    at_rest = ID.tfest(t, u, y, 2, 0)
    free = ID.tfest(t, u, y, 2, 0, initial_state="estimate")
    assert free.fit_percent > 99.99 > at_rest.fit_percent
    assert free.second_order()["wn"] == pytest.approx(107.0, rel=1e-5)


# -- bad data --------------------------------------------------------------------

def _good(n=2000):
    t = np.arange(n) * 1e-3
    u = np.sin(2 * np.pi * 3 * t)
    return t, u, 1.3 * u


@pytest.mark.parametrize("mutate, words", [
    (lambda t, u, y: (t[:30], u[:30], y[:30]), "too short: 30 samples"),
    (lambda t, u, y: (t, np.full_like(u, 4.0), y), "input 'u' is constant"),
    (lambda t, u, y: (t, u, np.where((t > 0.5) & (t < 0.52), np.nan, y)), "misses 19 samples in a row from row 502"),
    (lambda t, u, y: (np.r_[t[:700], t[700:] + 0.0004], u, y), "non-uniform time: the step before row 701"),
    (lambda t, u, y: (np.r_[t[:10], t[9], t[11:]], u, y), "not increasing at row 11"),
    (lambda t, u, y: (t, u, np.zeros_like(y)), "output 'y' is constant"),
])
def test_bad_data_is_refused_with_a_clear_error(mutate, words):
    with pytest.raises(ValueError, match=words):
        ID.tfest(*mutate(*_good()), 2, 0)


def test_too_few_samples_for_the_parameters():
    t, u, y = _good(60)
    with pytest.raises(ValueError, match="too short: 60 samples for 9 parameters"):
        ID.tfest(t, u, y, 4, 4)


def test_short_gaps_are_interpolated_and_counted():
    t, u, y = _good()
    y[100:103] = np.nan
    d = ID.prepare(t, u, y)
    assert d.interpolated == {"y": 3}
    np.testing.assert_allclose(d.y[100:103], 1.3 * u[100:103], atol=2e-3)


def test_identify_cli_names_the_file_and_row_of_a_nan_island(tmp_path, capsys):
    t, u, y = _good()
    rows = ["t,current_mA,flow_lpm"] + [f"{a:.6f},{b:.6f}," + ("" if 300 <= k < 310 else f"{c:.6f}")
                                        for k, (a, b, c) in enumerate(zip(t, u, y))]
    path = tmp_path / "gappy.csv"
    path.write_text("\n".join(rows) + "\n")
    rc = main(["identify", str(path), "--out", str(tmp_path / "plots")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert str(path) in err[0] and "'flow_lpm' misses 10 samples in a row from row 301" in err[0]
    rc = main(["identify", str(path), "--output", "p_a_bar"])
    assert rc == 2 and "no column 'p_a_bar'" in capsys.readouterr().err


# -- the command on an excited run ---------------------------------------------

def test_excite_then_identify_writes_json_and_plots(tmp_path, capsys):
    stem = tmp_path / "chirp"
    assert main(["excite", "chirp", "--f0", "0.5", "--f1", "40", "--method", "log", "--amplitude", "12",
                 "--duration", "5", "--out", str(stem)]) == 0
    js, plots = tmp_path / "fit.json", tmp_path / "plots"
    assert main(["identify", str(stem) + ".csv", "--poles", "2", "--zeros", "0", "--json", str(js),
                 "--out", str(plots)]) == 0
    out = capsys.readouterr().out
    assert "fit = " in out and "K = 1.272" in out
    res = json.loads(js.read_text())
    assert {"num", "den", "K", "wn", "zeta", "fit_percent"} <= set(res)
    assert res["den"][0] == 1.0 and len(res["den"]) == 3 and len(res["num"]) == 1
    assert res["wn"] == pytest.approx(107.0, rel=0.01) and res["zeta"] == pytest.approx(0.691, rel=0.02)
    assert res["fit_percent"] > 99
    assert {"overlay.png", "bode.png", "residuals.png", "identify.md"} <= {p.name for p in plots.iterdir()}


# -- residual analysis (MATLAB resid) ------------------------------------------------

def test_residual_correlations_match_numpy_and_textbook_cases():
    rng = np.random.default_rng(11)
    N = 20000
    u = rng.normal(size=N)
    # white residual: autocorrelation inside the band at about 99 % of the lags
    ra = ID.residual_analysis(rng.normal(size=N), u, max_lag=200)
    assert ra.auto_band == pytest.approx(2.5758293 / math.sqrt(N))
    assert ra.auto_outside() <= 8
    # AR(1) residual: r(k) = a^k
    e = np.zeros(N)
    w = rng.normal(size=N)
    for k in range(1, N):
        e[k] = 0.8 * e[k - 1] + w[k]
    ra = ID.residual_analysis(e, u, max_lag=5)
    np.testing.assert_allclose(ra.auto, 0.8 ** np.arange(6), atol=0.03)
    # independent computation of the normalised cross-correlation with numpy
    for lag in (-3, 0, 3):
        direct = np.sum(e[max(lag, 0):N + min(lag, 0)] * u[max(-lag, 0):N - max(lag, 0)]) / N  # sum e(n + lag) u(n)
        assert ra.cross[list(ra.cross_lags).index(lag)] == pytest.approx(
            direct / math.sqrt(np.mean(e * e) * np.mean(u * u)), rel=1e-9, abs=1e-12)
    # a residual that follows the input by 4 samples: unmodelled dynamics at lag +4
    e = np.r_[np.zeros(4), u[:-4]] + 0.1 * rng.normal(size=N)
    ra = ID.residual_analysis(e, u, max_lag=10)
    assert ra.cross_lags[np.argmax(np.abs(ra.cross))] == 4
    assert "correlated with the input" in ra.verdict()
