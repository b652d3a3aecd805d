"""The benchmark: its conditions, files, the Python-loop path for learned agents, the CLIs.

Truth used: the book's rig tests in tests/data/book (read independently of the
shipped copy), the effects' declared typical ranges, and the compiled closed loop
for the Python path.
"""
from __future__ import annotations

import csv
import json
import shlex
from pathlib import Path

import numpy as np
import pytest

from conftest import book_path, read_book_csv  # the book's tables in tests/data/book; missing ones fail the test
from ehas_controllers.base import Controller, load_controller
from ehas_controllers.batch_sim import Condition, grid
from ehas_controllers.benchmark import (CSV_COLUMNS, book_conditions, demo_section, evaluate_controller,
                                        run_benchmark, typical_effects)
from ehas_controllers.piff import PIFF
from ehas_env.cli.main import main as cli_main
from ehas_env.physics.effects import REGISTRY

ROOT = Path(__file__).resolve().parents[2]  # the repository: results/ holds the committed benchmark


def test_grid_is_the_63_conditions():
    conds = grid()
    assert len(conds) == 63 == len(set(conds))
    assert {c.disc_sets for c in conds} == set(range(1, 8))
    assert {c.freq_hz for c in conds} == {1.0, 2.0, 3.0} and {c.amplitude_deg for c in conds} == {10.0, 20.0, 30.0}


def test_book_conditions_are_the_books_rig_tests():
    path = book_path("rig_tests.csv")
    rows = list(csv.DictReader(line for line in path.read_text().splitlines() if not line.startswith("#")))
    got = book_conditions()
    assert len(got) == len(rows) == 7
    for (cond, err), row in zip(got, rows):
        assert 2 * cond.disc_sets == int(row["discs"])  # discs = 2 x disc sets
        assert (cond.freq_hz, cond.amplitude_deg, err) == (float(row["freq_hz"]), float(row["amplitude_deg"]),
                                                           float(row["pos_error_percent"]))


def test_typical_effects_are_the_middle_of_the_typical_ranges():
    eff = typical_effects()
    assert set(eff) == {n for n, c in REGISTRY.items() if c.kind != "hypothesis"}  # hypotheses are the diagnosis'
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
    assert {r["effect"] for r in rows} == {n for n, c in REGISTRY.items() if c.kind != "hypothesis"} | {"none"}
    none = next(r for r in rows if r["effect"] == "none")
    delay = next(r for r in rows if r["effect"] == "transport_delay")
    # a 6 ms delay costs the book's loop tracking accuracy
    assert float(delay["mean_rms_error_pct"]) > float(none["mean_rms_error_pct"])


def test_demo_section(tmp_path):
    """The demo's "beats the book on N of 7" is the count of rig tests where the tuned controller's
    rms % error is below the book's measured % error (the book's table in tests/data/book), re-simulated
    here from the saved controller file."""
    md = demo_section(tmp_path)
    assert "rms_error_pct" in md
    rig = read_book_csv("rig_tests.csv")
    assert len(rig) == 7
    rows = list(csv.DictReader(ln for ln in (tmp_path / "tuned_vs_book.csv").read_text().splitlines()
                               if not ln.startswith("#")))
    tuned = load_controller(tmp_path / "tuned_controller.json")
    conds = [Condition(int(r["disc_sets"]), float(r["freq_hz"]), float(r["amplitude_deg"])) for r in rig]
    fresh = evaluate_controller(tuned, conds)
    book_fresh = evaluate_controller(PIFF.book(), conds)
    assert len(rows) == 7
    for row, book, f, g in zip(rows, rig, fresh, book_fresh):
        assert (int(row["disc_sets"]), float(row["freq_hz"]), float(row["amplitude_deg"])) == (
            int(book["disc_sets"]), float(book["freq_hz"]), float(book["amplitude_deg"]))
        assert float(row["book_pos_error_pct"]) == float(book["pos_error_percent"])
        # the CSV prints 5 significant digits
        assert float(row["tuned_rms_error_pct"]) == pytest.approx(f["rms_error_pct"], rel=1e-4)
        assert float(row["book_gains_rms_error_pct"]) == pytest.approx(g["rms_error_pct"], rel=1e-4)
    wins = sum(f["rms_error_pct"] < float(b["pos_error_percent"]) for f, b in zip(fresh, rig))
    assert wins == sum(float(r["tuned_rms_error_pct"]) < float(r["book_pos_error_pct"]) for r in rows)
    assert f"beats the book's number on {wins} of 7 tests" in md
    assert md.count("beats the book") == 1


# -- the committed benchmark, regenerated -------------------------------------------
COMMITTED = ROOT / "results" / "benchmark.csv"
COMMITTED_ROBUSTNESS = ROOT / "results" / "benchmark_robustness.csv"
BENCH_KEY = ("controller", "disc_sets", "freq_hz", "amplitude_deg")
BENCH_NUMBERS = ("rms_error_pct", "peak_error_pct", "max_current_mA", "saturation_frac", "peak_delta_p_bar",
                 "hit_stroke_end")
ROBUST_KEY = ("effect", "params", "controller")
ROBUST_NUMBERS = ("mean_rms_error_pct", "worst_rms_error_pct", "stroke_end_hits", "conditions_over_5pct")


def _data_rows(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(ln for ln in path.read_text().splitlines() if not ln.startswith("#")))


def _committed_bench_args():
    """``ehas bench``'s parsed arguments as the committed CSV's first line says it was produced."""
    import argparse

    from ehas_controllers.bench_cli import add_arguments

    first = COMMITTED.read_text().splitlines()[0]
    marker = "regenerate with: "
    assert marker in first, f"{COMMITTED}: the first line names no regenerating command: {first!r}"
    cmd = shlex.split(first.split(marker, 1)[1])
    assert cmd[:2] == ["ehas", "bench"], first
    parser = argparse.ArgumentParser(prog="ehas bench")
    add_arguments(parser)
    return parser.parse_args(cmd[2:])


def _committed_controller_files(args) -> list[Path]:
    """The controller files that command benchmarks: the ones named, else the tuners' results in
    OUT/controllers (which ``ehas bench`` would tune and write if missing: here they must exist)."""
    from ehas_controllers.bench_cli import DEFAULT_TUNERS

    if args.controllers:
        files = [ROOT / c for c in args.controllers]
    else:
        files = [ROOT / args.out / "controllers" / f"{stem}.json" for stem, _ in DEFAULT_TUNERS]
    missing = [str(f) for f in files if not f.exists()]
    if missing:
        pytest.fail(f"the committed benchmark's controller files are missing: {', '.join(missing)}", pytrace=False)
    return files


def _differences(old_rows, new_rows, key, numbers, strings=()) -> list[str]:
    """Every row whose numbers differ by more than 1e-9 relative (or whose text differs), old -> new."""
    old = {tuple(r[k] for k in key): r for r in old_rows}
    new = {tuple(r[k] for k in key): r for r in new_rows}
    out = [f"only in the committed file: {k}" for k in old if k not in new]
    out += [f"only in the fresh run: {k}" for k in new if k not in old]
    for k in old:
        if k not in new:
            continue
        bad = [f"{c}: {old[k][c]} -> {new[k][c]}" for c in numbers
               if float(new[k][c]) != pytest.approx(float(old[k][c]), rel=1e-9, abs=0.0)]
        bad += [f"{c}: {old[k][c]!r} -> {new[k][c]!r}" for c in strings if old[k][c] != new[k][c]]
        if bad:
            out.append(f"{', '.join(k)}: " + "; ".join(bad))
    return out


def test_fresh_bench_reproduces_the_committed_benchmark_csv(tmp_path, capsys):
    """A fresh ``ehas bench`` of the shipped controllers, run as results/benchmark.csv's first line
    says, gives its 63-condition rows to 1e-9 relative (as printed), row by row."""
    args = _committed_bench_args()
    files = _committed_controller_files(args)
    argv = ["bench", *map(str, files), "--out", str(tmp_path / "b"), "--no-robustness", "--no-progress"]
    argv += ["--cycles", f"{args.cycles:g}"] + (["--model", args.model] if args.model else [])
    argv += ["--no-book"] if args.no_book else []
    assert cli_main(argv) == 0
    capsys.readouterr()
    old, new = _data_rows(COMMITTED), _data_rows(tmp_path / "b" / "benchmark.csv")
    assert len(old) == 63 * (len(files) + (not args.no_book))
    assert [tuple(r[k] for k in BENCH_KEY) for r in new] == [tuple(r[k] for k in BENCH_KEY) for r in old]
    diffs = _differences(old, new, BENCH_KEY, BENCH_NUMBERS, ("kind", "variant"))
    assert not diffs, "fresh ehas bench differs from results/benchmark.csv:\n" + "\n".join(diffs)


def _params_text(params: dict) -> str:
    return ";".join(f"{k}={v:g}" for k, v in params.items())


def test_committed_robustness_table_is_for_todays_typical_effects():
    """results/benchmark_robustness.csv is for today's `typical` middles (regenerate with `ehas bench`)."""
    rows = _data_rows(COMMITTED_ROBUSTNESS)
    committed = {r["effect"]: r["params"] for r in rows if r["effect"] != "none"}
    from ehas_env.physics.effects import REGISTRY

    # the library's effects (user effects other tests loaded into this process are not in the shipped table)
    library = {n for n, c in REGISTRY.items() if c.__module__.startswith("ehas_env.physics.effects.")
               and c.kind != "hypothesis"}
    assert committed == {name: _params_text(p) for name, p in typical_effects().items() if name in library}


@pytest.mark.slow
def test_fresh_robustness_reproduces_the_committed_rows():
    """Each row of results/benchmark_robustness.csv, re-simulated at the parameters it names, gives its
    mean / worst rms % error, stroke-end hits and conditions over 5 % to 1e-9 relative (as printed)."""
    args = _committed_bench_args()
    ctrls = ([] if args.no_book else [PIFF.book()]) + [load_controller(f) for f in _committed_controller_files(args)]
    by_name = {c.name: c for c in ctrls}
    old = _data_rows(COMMITTED_ROBUSTNESS)
    assert {r["controller"] for r in old} == set(by_name)
    new = []
    for r in old:
        params = {k: float(v) for k, v in (kv.split("=") for kv in r["params"].split(";") if kv)}
        effects = None if r["effect"] == "none" else {r["effect"]: params}
        rows = evaluate_controller(by_name[r["controller"]], grid(effects=effects), cycles=args.cycles)
        rms = [x["rms_error_pct"] for x in rows]
        new.append({**{k: r[k] for k in ROBUST_KEY}, "mean_rms_error_pct": f"{np.mean(rms):.5g}",
                    "worst_rms_error_pct": f"{max(rms):.5g}",
                    "stroke_end_hits": str(sum(bool(x["hit_stroke_end"]) for x in rows)),
                    "conditions_over_5pct": str(sum(v > 5.0 for v in rms))})
    diffs = _differences(old, new, ROBUST_KEY, ROBUST_NUMBERS)
    assert not diffs, "fresh robustness rows differ from results/benchmark_robustness.csv:\n" + "\n".join(diffs)


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
    monkeypatch.setitem(sys.modules, "ehas_env.simulation.model_file", None)  # as if the module did not exist
    assert cli_main(["bench", str(ctrl), "--model", "rig.json", "--out", str(tmp_path), "--no-robustness"]) == 2
    assert "ehas_env.simulation.model_file" in capsys.readouterr().err
    seen = {}

    def load_model(path):
        seen["path"] = path
        return {"effects": {"coulomb_friction": {"Fc": 400.0}}}

    monkeypatch.setitem(sys.modules, "ehas_env.simulation.model_file", types.SimpleNamespace(load_model=load_model))
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
