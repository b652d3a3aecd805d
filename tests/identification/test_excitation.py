"""Excitation signals against independent truth (scipy's chirp, the textbook
properties of maximum-length sequences, the DFT of a multisine) and the
``ehas excite`` run file."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal as sps

from ehas_env.identification import excitation as ex
from ehas_env.cli.main import main


@pytest.mark.parametrize("method, scipy_method", [("linear", "linear"), ("log", "logarithmic")])
def test_chirp_equals_scipy(method, scipy_method):
    sig = ex.chirp(duration=8.0, rate_hz=1000.0, f0=0.5, f1=20.0, amplitude=15.0, method=method)
    ref = 15.0 * sps.chirp(sig.t, f0=0.5, t1=8.0, f1=20.0, method=scipy_method, phi=-90.0)
    np.testing.assert_allclose(sig.current_mA, ref, atol=1e-9)
    assert sig.current_mA[0] == 0.0 and np.abs(sig.current_mA).max() <= 15.0


def test_chirp_instantaneous_frequency_sweeps_f0_to_f1():
    sig = ex.chirp(duration=10.0, f0=0.5, f1=2.0, amplitude=20.0)
    zc = np.flatnonzero(np.diff(np.signbit(sig.current_mA)))  # zero crossings: half periods
    t_mid = 0.5 * (sig.t[zc[1:]] + sig.t[zc[:-1]])
    f_est = 0.5 / np.diff(sig.t[zc])
    np.testing.assert_allclose(f_est, 0.5 + 1.5 * t_mid / 10.0, rtol=0.03)


@pytest.mark.parametrize("order", [5, 7, 9])
def test_prbs_is_a_maximum_length_sequence(order):
    m = 2**order - 1
    sig = ex.prbs(duration=m * 0.004, rate_hz=1000.0, amplitude=3.0, hold=0.004, order=order, seed=2)
    chips = sig.current_mA[::4]
    assert chips.size == m and set(np.unique(sig.current_mA)) == {-3.0, 3.0}
    # held for exactly 4 samples
    assert np.all(sig.current_mA.reshape(-1, 4) == chips[:, None])
    # balanced: one more +1 than -1, and a two-valued periodic autocorrelation (1 at lag 0, -1/m elsewhere)
    x = chips / 3.0
    assert x.sum() == 1.0
    r = np.array([np.dot(x, np.roll(x, k)) for k in range(m)]) / m
    assert r[0] == 1.0 and np.allclose(r[1:], -1.0 / m)


def test_random_signals_are_reproducible_by_seed():
    for gen in (ex.prms, ex.prbs):
        a, b, c = (gen(duration=2.0, hold=0.01, seed=s).current_mA for s in (4, 4, 5))
        assert np.array_equal(a, b) and not np.array_equal(a, c)
    a, b = (ex.multisine(duration=2.0, phases="random", seed=s).current_mA for s in (1, 1))
    assert np.array_equal(a, b)


def test_prms_levels_hold_and_balance():
    sig = ex.prms(duration=50.0, rate_hz=1000.0, amplitude=20.0, hold=0.01, levels=5, seed=7)
    u = sig.current_mA
    assert set(np.unique(u)) == {-20.0, -10.0, 0.0, 10.0, 20.0}
    blocks = u.reshape(-1, 10)
    assert np.all(blocks == blocks[:, :1])
    chips = blocks[:, 0]
    # independent uniform levels: mean 0 within 4 standard errors, every level about 1/5 of the time
    assert abs(chips.mean()) < 4 * chips.std() / np.sqrt(chips.size)
    counts = np.array([np.sum(chips == v) for v in (-20, -10, 0, 10, 20)]) / chips.size
    assert np.all(np.abs(counts - 0.2) < 0.03)


def test_multisine_power_sits_on_its_lines_only():
    sig = ex.multisine(duration=4.0, rate_hz=1000.0, f0=0.5, f1=40.0, amplitude=10.0, lines=20)
    assert np.abs(sig.current_mA).max() == pytest.approx(10.0, rel=1e-12)
    spec = np.abs(np.fft.rfft(sig.current_mA)) ** 2
    f = np.fft.rfftfreq(sig.current_mA.size, 1e-3)
    lines = np.isin(np.round(f, 9), np.round(sig.params["freqs_hz"], 9))
    assert lines.sum() == sig.params["lines"]
    assert spec[~lines].sum() < 1e-20 * spec[lines].sum()
    # equal amplitudes on every line
    assert np.ptp(spec[lines]) < 1e-9 * spec[lines].max()
    # the phases keep the crest factor low: a single sine has sqrt(2) = 1.41, aligned cosines sqrt(2 n)
    crest = lambda x: np.abs(x).max() / np.sqrt(np.mean(x**2))
    aligned = np.sum([np.cos(2 * np.pi * fk * sig.t) for fk in sig.params["freqs_hz"]], axis=0)
    schroeder = ex.multisine(duration=4.0, f0=0.5, f1=40.0, amplitude=10.0, lines=20, phases="schroeder")
    assert crest(sig.current_mA) < min(2.5, crest(schroeder.current_mA)) < 0.5 * crest(aligned)
    assert sig.params["crest_factor"] == pytest.approx(crest(sig.current_mA))


@pytest.mark.parametrize("call, words", [
    (lambda: ex.chirp(f0=0.5, f1=600.0), "below the Nyquist frequency"),
    (lambda: ex.chirp(f0=3.0, f1=2.0), "0 < f0 < f1"),
    (lambda: ex.chirp(method="cubic"), "'linear' or 'log'"),
    (lambda: ex.prms(hold=0.0025), "whole number"),
    (lambda: ex.prms(levels=1), "levels must be an integer >= 2"),
    (lambda: ex.prbs(order=25), "order must be an integer"),
    (lambda: ex.chirp(duration=-1.0), "duration must be a positive"),
    (lambda: ex.multisine(amplitude=float("nan")), "amplitude must be a positive"),
    (lambda: ex.make("sawtooth"), "unknown excitation 'sawtooth'"),
])
def test_bad_arguments_are_refused_clearly(call, words):
    with pytest.raises(ValueError, match=words):
        call()


def test_excite_writes_a_valve_run_in_the_measurement_format(tmp_path, capsys):
    from ehas_env.cli import excite as excite_cli

    assert excite_cli.KINDS == ex.KINDS
    stem = tmp_path / "prms"
    assert main(["excite", "prms", "--hold", "0.005", "--duration", "2", "--seed", "3", "--out", str(stem)]) == 0
    header = (tmp_path / "prms.csv").read_text().splitlines()[0].split(",")
    assert header == ["t", "current_mA", "flow_lpm"]
    data = np.loadtxt(tmp_path / "prms.csv", delimiter=",", skiprows=1)
    meta = json.loads((tmp_path / "prms.json").read_text())
    assert meta["kind"] == "valve_open_loop" and meta["supply_bar"] == 70.0
    assert meta["excitation"]["kind"] == "prms" and meta["excitation"]["hold_s"] == 0.005
    u = ex.prms(duration=2.0, hold=0.005, seed=3).current_mA
    np.testing.assert_allclose(data[:, 1], u, atol=1e-9)
    # the logged flow is the valve's flow plus meter noise: close to K i at low frequency, never identical
    from ehas_env.simulation.plant import Plant

    clean = Plant().simulate_valve_test(u, supply_bar=70.0).flow_lpm
    resid = data[:, 2] - clean
    assert 0.03 < resid.std() < 0.07  # Sensors: 0.05 LPM
    assert "ehas identify" in capsys.readouterr().out


def test_excite_bad_argument_is_one_line(tmp_path, capsys):
    rc = main(["excite", "chirp", "--f1", "900", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "Nyquist" in err[0]
    assert not list(tmp_path.iterdir())
