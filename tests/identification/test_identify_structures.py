"""``ehas identify --structure arx|armax|oe|bj|ss``: the black-box models on the command line, against truth.

Runs are simulated by scipy.signal.lfilter from a known discrete plant and noise model (numpy noise, fixed
seeds); the JSON's coefficients are checked against that truth within 4 of their own standard errors.
"""
from __future__ import annotations

import json

import control
import numpy as np
import pytest
from scipy.signal import lfilter

from ehas_env.cli.main import main
from ehas_env.identification.export import read_model
from ehas_env.measurement.runfile import write_run

N = 3000
DT = 1e-3
B, F, C, D = [1.0, 0.5], [1.0, -1.5, 0.7], [1.0, 0.5], [1.0, -0.9]


def run_file(path, noise="bj", seed=1, n=N):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.normal(size=n))
    e = 0.2 * rng.normal(size=n)
    y = lfilter([0.0] + B, F, u) + (lfilter(C, D, e) if noise == "bj" else e)
    data, _ = write_run(path, {"t": np.arange(n) * DT, "current_mA": u, "flow_lpm": y},
                        {"kind": "valve_open_loop", "supply_bar": 70.0})
    return str(data), u, y


@pytest.fixture(scope="module")
def bj_run(tmp_path_factory):
    return run_file(tmp_path_factory.mktemp("bj") / "bj")


def test_bj_on_the_command_line_recovers_the_truth_with_white_residuals(bj_run, tmp_path, capsys):
    run, u, y = bj_run
    js = tmp_path / "bj.json"
    assert main(["identify", run, "--structure", "bj", "--nc", "1", "--nd", "1", "--json", str(js),
                 "--no-plots"]) == 0
    doc = json.loads(js.read_text())
    assert doc["structure"] == "bj" and doc["orders"] == {"nb": 2, "nc": 1, "nd": 1, "nf": 2, "nk": 1}
    truth = {"b1": 1.0, "b2": 0.5, "c1": 0.5, "d1": -0.9, "f1": -1.5, "f2": 0.7}
    for k, v in truth.items():
        p = doc["parameters"][k]
        assert abs(p["value"] - v) < 4 * p["std"], (k, p)
    assert doc["dt"] == pytest.approx(DT) and doc["tf_z"]["dt"] == pytest.approx(DT)
    # the fit is the NRMSE of the noise-free simulation, computed here by python-control from the JSON's tf
    G = control.tf(doc["tf_z"]["num"], doc["tf_z"]["den"], doc["dt"])
    ys = control.forced_response(G, U=u).outputs
    assert doc["fit_percent"] == pytest.approx(100 * (1 - np.linalg.norm(y - ys) / np.linalg.norm(y - y.mean())),
                                               abs=1e-6)
    assert doc["residual_tests"]["autocorrelation"]["pass"] and doc["residual_tests"]["cross_correlation"]["pass"]
    assert "BJ [2 1 1 2 1]" in capsys.readouterr().out


def test_oe_on_bj_data_fails_the_whiteness_test_in_the_json(bj_run, tmp_path):
    run, _, _ = bj_run
    js = tmp_path / "oe.json"
    assert main(["identify", run, "--structure", "oe", "--json", str(js), "--no-plots"]) == 0
    doc = json.loads(js.read_text())
    assert doc["structure"] == "oe" and set(doc["polynomials"]) == {"B", "F"}
    assert doc["residual_tests"]["autocorrelation"]["pass"] is False
    # the plant is still right: OE is consistent whatever the noise colour
    assert doc["parameters"]["f1"]["value"] == pytest.approx(-1.5, abs=4 * doc["parameters"]["f1"]["std"])


def test_the_default_structure_is_the_transfer_function_unchanged(bj_run, tmp_path):
    run, _, _ = bj_run
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(["identify", run, "--json", str(a), "--no-plots"]) == 0
    assert main(["identify", run, "--structure", "tf", "--json", str(b), "--no-plots"]) == 0
    da, db = json.loads(a.read_text()), json.loads(b.read_text())
    assert da["structure"] == "tf" and da["num"] == db["num"] and da["den"] == db["den"]
    assert len(da["den"]) == 3  # 2 poles, as before


def test_orders_table_puts_black_box_structures_beside_the_transfer_functions(bj_run, tmp_path, capsys):
    run, _, _ = bj_run
    js = tmp_path / "t.json"
    assert main(["identify", run, "--orders", "1:2", "--compare", "arx,oe,bj", "--predict", "1", "--json", str(js),
                 "--no-plots"]) == 0
    table = json.loads(js.read_text())["orders"]
    labels = [r["label"] for r in table["rows"]]
    assert labels == ["1p0z", "ARX [1 1 1]", "OE [1 1 1]", "BJ [1 1 1 1 1]", "2p0z", "2p1z", "ARX [2 2 1]",
                      "OE [2 2 1]", "BJ [2 2 2 2 1]"]
    rows = {r["label"]: r for r in table["rows"]}
    # OE [2 2 1] is the sampled form of a 2-pole 1-zero transfer function: the same validation fit
    assert rows["OE [2 2 1]"]["validation"]["fit_percent"] == pytest.approx(
        rows["2p1z"]["validation"]["fit_percent"], abs=0.2)
    # BJ's own noise model predicts one step ahead better than OE's (none)
    assert rows["BJ [2 2 2 2 1]"]["validation"]["predict_fit_percent"] > \
        rows["OE [2 2 1]"]["validation"]["predict_fit_percent"] + 5
    assert "ARX [2 2 1]" in capsys.readouterr().out


def test_export_of_a_black_box_model_reads_back_as_a_discrete_transfer_function(bj_run, tmp_path, capsys):
    run, u, _ = bj_run
    path = tmp_path / "m.json"
    js = tmp_path / "m_fit.json"
    assert main(["identify", run, "--structure", "armax", "--export", str(path), "--json", str(js),
                 "--no-plots"]) == 0
    G = read_model(path)
    assert G.dt == pytest.approx(DT)
    doc = json.loads(js.read_text())
    A, Bq = doc["polynomials"]["A"], doc["polynomials"]["B"]
    y_lf = lfilter([0.0] + Bq, A, u)
    assert np.allclose(control.forced_response(G, U=u).outputs, y_lf, atol=1e-9 * np.max(np.abs(y_lf)))


def test_structure_ss_on_the_command_line(bj_run, tmp_path):
    pytest.importorskip("nfoursid", reason="structure ss needs the optional package nfoursid (ehas[ident])")
    run, _, _ = bj_run
    js = tmp_path / "ss.json"
    assert main(["identify", run, "--structure", "ss", "--nx", "2", "--json", str(js), "--no-plots"]) == 0
    doc = json.loads(js.read_text())
    poles = np.sort_complex([complex(*p) for p in doc["poles"]])
    assert np.allclose(np.sort_complex(np.roots(F)), poles, atol=0.01)
    assert doc["structure"] == "ss" and doc["fit_percent"] > 80


# -- refusals: one line each, naming the option --------------------------------------------------------------

def _one_line(argv, capsys):
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    return rc, err


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    return run_file(tmp_path_factory.mktemp("small") / "small", n=400)[0]


@pytest.mark.parametrize("option", ["--na", "--nb", "--nc", "--nd", "--nf", "--nk", "--nx", "--structure",
                                    "--compare"])
@pytest.mark.parametrize("value", ["nan", "-1", "1e308", "2.5", "x"])
def test_bad_values_of_the_structure_options_are_one_line(option, value, small_run, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    structure = {"--na": "armax", "--nc": "bj", "--nd": "bj", "--nf": "oe", "--nx": "ss"}.get(option, "arx")
    argv = ["identify", small_run, option, value, "--no-plots"]
    if option not in ("--structure", "--compare"):
        argv += ["--structure", structure]
    if option == "--compare":
        argv += ["--orders", "2"]
    rc, err = _one_line(argv, capsys)
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith("ehas identify:") and option in err[0], err[0]
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("argv, words", [
    (["--structure", "armax", "--nf", "2"], "--nf does not belong to structure armax"),
    (["--structure", "oe", "--poles", "3"], "--poles applies to --structure tf"),
    (["--structure", "oe", "--delay", "0.01"], "give the input delay in samples with --nk"),
    (["--structure", "bj", "--covariance", "white"], "--covariance applies to --structure tf"),
    (["--na", "2"], "--na goes with a black-box --structure"),
    (["--compare", "oe"], "--compare goes with --orders"),
    (["--structure", "arx", "--nb", "0"], "--nb must be"),
])
def test_inconsistent_structure_options_are_one_line(argv, words, small_run, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, err = _one_line(["identify", small_run, *argv, "--no-plots"], capsys)
    assert rc == 2 and len(err) == 1 and words in err[0], err


def test_a_fit_that_ends_unstable_is_not_usable():
    """TFEstimate.usable: a right-half-plane pole (or a diverging simulation) is refused where a model is chosen
    (ehas identify, the order table); the same record with a stable model is usable."""
    from ehas_env.identification.fit import IdData, TFEstimate

    t = np.arange(200) * 1e-3
    data = IdData(t=t, u=np.ones_like(t), y=np.zeros_like(t), dt=1e-3)
    den_ok, den_bad = np.array([1.0, 3.0, 2.0]), np.array([1.0, -1.0, 2.0])  # poles -1, -2 / 0.5 +- 1.32j

    def est(den, y_sim):
        return TFEstimate(tf=control.tf([1.0], den), num=np.array([1.0]), den=den, n_poles=2, n_zeros=0,
                          fit_percent=50.0, data=data, y_sim=y_sim, intersample="zoh", x0=np.zeros(2))

    assert est(den_ok, np.zeros_like(t)).usable()
    assert not est(den_bad, np.zeros_like(t)).usable()
    assert not est(den_ok, np.full_like(t, np.inf)).usable()
