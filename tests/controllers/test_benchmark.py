"""The benchmark: its conditions, files, the Python-loop path for learned agents, the CLIs.

Truth used: the book's rig tests in /work/shared (read independently of the
shipped copy), the effects' declared typical ranges, and the compiled closed loop
for the Python path.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from ehas_controllers.base import Controller
from ehas_controllers.batch_sim import Condition, grid
from ehas_controllers.benchmark import (CSV_COLUMNS, book_conditions, demo_section, evaluate_controller,
                                        run_benchmark, typical_effects)
from ehas_controllers.piff import PIFF
from ehas_env.cli.main import main as cli_main
from ehas_env.physics.effects import REGISTRY

SHARED = Path(__file__).resolve().parents[3] / "shared"


def test_grid_is_the_63_conditions():
    conds = grid()
    assert len(conds) == 63 == len(set(conds))
    assert {c.disc_sets for c in conds} == set(range(1, 8))
    assert {c.freq_hz for c in conds} == {1.0, 2.0, 3.0} and {c.amplitude_deg for c in conds} == {10.0, 20.0, 30.0}


def test_book_conditions_are_the_books_rig_tests():
    path = SHARED / "data" / "book" / "rig_tests.csv"
    if not path.exists():
        pytest.skip("shared book data not present")
    rows = list(csv.DictReader(line for line in path.read_text().splitlines() if not line.startswith("#")))
    got = book_conditions()
    assert len(got) == len(rows) == 7
    for (cond, err), row in zip(got, rows):
        assert 2 * cond.disc_sets == int(row["discs"])  # discs = 2 x disc sets
        assert (cond.freq_hz, cond.amplitude_deg, err) == (float(row["freq_hz"]), float(row["amplitude_deg"]),
                                                           float(row["pos_error_percent"]))


def test_typical_effects_are_the_middle_of_the_typical_ranges():
    eff = typical_effects()
    assert set(eff) == set(REGISTRY)
    for name, params in eff.items():
        for p in REGISTRY[name].params:
            lo, hi = p.typical if p.typical else (p.default, p.default)
            assert lo <= params[p.name] <= hi
            assert params[p.name] == pytest.approx(0.5 * (lo + hi))
        REGISTRY[name].resolve(params)  # every value is inside its effect's bounds


class _PythonOnly(Controller):
    """A controller with no compiled form, as a learned agent is: only ``act``."""

    kind = "learned"
    name = "python-only"

    def __init__(self, inner):
        self.inner = inner

    def reset(self):
        self.inner.reset()

    def act(self, measurement):
        return self.inner.act(measurement)


def test_python_loop_path_gives_the_batch_metrics():
    ctrl = PIFF(Kp=1.1, Ki=1.0, Kj=2e-6)
    conds = [Condition(3, 3.0, 20.0), Condition.with_effects(5, 2.0, 10.0, {"coulomb_friction": {"Fc": 300.0}})]
    fast = evaluate_controller(ctrl, conds, cycles=3)
    slow = evaluate_controller(_PythonOnly(ctrl), conds, cycles=3)
    for f, s in zip(fast, slow):
        for key in ("rms_error_pct", "peak_error_pct", "max_current_mA", "saturation_frac", "peak_delta_p_bar"):
            assert s[key] == pytest.approx(f[key], rel=1e-9, abs=1e-12)
        assert s["hit_stroke_end"] == f["hit_stroke_end"]


def test_run_benchmark_writes_every_file(tmp_path):
    tuned = PIFF(Kp=0.8, Ki=0.5, Kj=2.4e-6, name="tuned")
    res = run_benchmark([PIFF.book(), tuned], tmp_path, robustness=False, command="pytest", progress=False)
    lines = [ln for ln in (tmp_path / "benchmark.csv").read_text().splitlines() if not ln.startswith("#")]
    rows = list(csv.DictReader(lines))
    assert tuple(rows[0]) == CSV_COLUMNS and len(rows) == 2 * 63
    assert {r["kind"] for r in rows} == {"classical"}
    assert (tmp_path / "benchmark.csv").read_text().startswith("# % position error benchmark, regenerate with: pytest")
    md = (tmp_path / "benchmark.md").read_text()
    assert "rms_error_pct" in md and "Regenerate with `pytest`" in md and "book % pos error" in md
    for name in ("book", "tuned"):
        assert (tmp_path / f"heatmap_{name}.png").stat().st_size > 10_000
    timing = json.loads((tmp_path / "benchmark_timing.json").read_text())
    assert timing["conditions"] == 63 and timing["best_s"] > 0
    assert res["summary"]["book"]["book_wins"] == sum(
        float(r["rms_error_pct"]) < b for (c, b) in book_conditions() for r in rows
        if r["controller"] == "book" and (int(r["disc_sets"]), float(r["freq_hz"]), float(r["amplitude_deg"])) ==
        (c.disc_sets, c.freq_hz, c.amplitude_deg))


def test_robustness_table_has_every_effect(tmp_path):
    run_benchmark([PIFF.book()], tmp_path, robustness=True, command="pytest", progress=False, disc_sets=(1, 7))
    lines = [ln for ln in (tmp_path / "benchmark_robustness.csv").read_text().splitlines() if not ln.startswith("#")]
    rows = list(csv.DictReader(lines))
    assert {r["effect"] for r in rows} == set(REGISTRY) | {"none"}
    none = next(r for r in rows if r["effect"] == "none")
    delay = next(r for r in rows if r["effect"] == "transport_delay")
    # a 6 ms delay costs the book's loop tracking accuracy
    assert float(delay["mean_rms_error_pct"]) > float(none["mean_rms_error_pct"])


def test_demo_section(tmp_path):
    md = demo_section(tmp_path)
    assert "rms_error_pct" in md and "beats the book" in md
    assert (tmp_path / "tuned_controller.json").exists() and (tmp_path / "tuned_vs_book.csv").exists()


# -- CLIs --------------------------------------------------------------------------
def test_tune_and_bench_commands(tmp_path, capsys):
    out = tmp_path / "relay.json"
    assert cli_main(["tune", "--method", "relay", "--disc-sets", "2", "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "Ku =" in printed and "mA/deg" in printed and "mA/(deg/s^2)" in printed
    data = json.loads(out.read_text())
    assert data["command"].startswith("ehas tune --method relay --disc-sets 2")
    assert data["metrics"]["mean_rms_error_pct"] > 0
    assert cli_main(["bench", str(out), "--out", str(tmp_path / "b"), "--no-robustness", "--no-progress"]) == 0
    rows = (tmp_path / "b" / "benchmark.csv").read_text()
    assert "relay-tl @2 sets" in rows and "book" in rows


def test_commands_refuse_bad_input(tmp_path, capsys):
    assert cli_main(["tune", "--method", "model", "--disc-sets", "9"]) == 2
    assert "--disc-sets" in capsys.readouterr().err
    assert cli_main(["tune", "--method", "model", "--amplitude", "50"]) == 2
    assert "--amplitude" in capsys.readouterr().err
    assert cli_main(["bench", str(tmp_path / "missing.json"), "--out", str(tmp_path)]) == 2
    assert "missing.json does not exist" in capsys.readouterr().err


def test_bench_model_option_is_forwarded_or_refused_clearly(tmp_path, capsys, monkeypatch):
    import sys
    import types

    ctrl = PIFF.book().save(tmp_path / "c.json")
    monkeypatch.setitem(sys.modules, "ehas_env.measurement.model_file", None)  # as if the module did not exist
    assert cli_main(["bench", str(ctrl), "--model", "rig.json", "--out", str(tmp_path), "--no-robustness"]) == 2
    assert "ehas_env.measurement.model_file" in capsys.readouterr().err
    seen = {}

    def load_model(path):
        seen["path"] = path
        return {"effects": {"coulomb_friction": {"Fc": 400.0}}}

    monkeypatch.setitem(sys.modules, "ehas_env.measurement.model_file", types.SimpleNamespace(load_model=load_model))
    out = tmp_path / "m"
    assert cli_main(["bench", str(ctrl), "--model", "rig.json", "--out", str(out), "--no-robustness",
                     "--no-progress", "--no-book"]) == 0
    assert seen["path"] == "rig.json"
    with_friction = [r for r in csv.DictReader(ln for ln in (out / "benchmark.csv").read_text().splitlines()
                                                if not ln.startswith("#"))]
    base = evaluate_controller(PIFF.book(), [Condition(1, 1.0, 10.0)])[0]["rms_error_pct"]
    first = next(r for r in with_friction if r["disc_sets"] == "1" and r["freq_hz"] == "1" and r["amplitude_deg"] == "10")
    assert float(first["rms_error_pct"]) != pytest.approx(base, rel=1e-3)  # the model's friction was simulated
    assert np.isfinite(float(first["rms_error_pct"]))
