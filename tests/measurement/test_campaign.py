"""Campaign I/O: the measurement format of measurements.md, read, validated, written.

Each failure mode of the spec is refused with a message naming the file, the
line or key, and what is expected; nothing is written half-way.
"""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from ehas_env.measurement.campaign import (MAX_GAP, CampaignError, read_campaign, read_run, validate_meta, write_campaign,
                               write_run)
from ehas_env.measurement.synthetic import simulate_campaign
from ehas_env.cli.main import main

PLAN = ((2, 12.0, 2.0),)


@pytest.fixture(scope="module")
def small_runs():
    """A short synthetic campaign (one closed-loop run, one valve run), in memory."""
    runs, truth = simulate_campaign({"viscous_friction": {"b": 2700.0}}, seed=41, perturb=True, duration=0.6,
                                    plan=PLAN)
    return runs, truth


@pytest.fixture
def campaign_dir(tmp_path, small_runs):
    runs, _ = small_runs
    return write_campaign(tmp_path / "camp", runs)


def rewrite_csv(path: Path, edit):
    lines = path.read_text().splitlines()
    path.write_text("\n".join(edit(lines)) + "\n")


def rewrite_json(path: Path, edit):
    meta = json.loads(path.read_text())
    edit(meta)
    path.write_text(json.dumps(meta))


CL = "cl_2sets_12deg_2hz"


# --- round trip ------------------------------------------------------------------------------


def test_written_campaign_reads_back_identically(campaign_dir, small_runs):
    runs, _ = small_runs
    camp = read_campaign(campaign_dir)
    assert [r.name for r in camp.runs] == sorted(name for name, _, _ in runs)
    for name, cols, meta in runs:
        run = next(r for r in camp.runs if r.name == name)
        assert run.kind == meta["kind"] and run.interpolated == {}
        assert run.dt == pytest.approx(1e-3)
        for c, v in cols.items():
            got = run.t if c == "t" else run.columns[c]
            # written with 10 significant digits
            np.testing.assert_allclose(got, v, rtol=1e-9, atol=1e-9 * max(1.0, float(np.abs(v).max())))
    assert camp.ignored == ["truth.json"] or camp.ignored == []


def test_sidecars_do_not_reveal_the_hidden_effect(tmp_path):
    from ehas_env.measurement.synthetic import write_simulated_campaign

    folder, truth = write_simulated_campaign(tmp_path / "c", {"coulomb_friction": {"Fc": 333.0}}, seed=8,
                                             perturb=True, duration=0.5, plan=PLAN)
    for js in folder.glob("*.json"):
        text = js.read_text()
        if js.name == "truth.json":
            assert "coulomb_friction" in text
        else:
            assert "coulomb" not in text and "effects" not in text and "Fc" not in text
    camp = read_campaign(folder)
    assert camp.ignored == ["README.md", "truth.json"]
    assert abs(truth["beta"] / 1e9 - 1) <= 0.05 and abs(truth["K"] / 1.2723 - 1) <= 0.01


def test_same_seed_same_campaign_other_seed_other_noise():
    a, _ = simulate_campaign({"valve_null_bias": {"i_bias": 0.5}}, seed=3, duration=0.4, plan=PLAN)
    b, _ = simulate_campaign({"valve_null_bias": {"i_bias": 0.5}}, seed=3, duration=0.4, plan=PLAN)
    c, _ = simulate_campaign({"valve_null_bias": {"i_bias": 0.5}}, seed=4, duration=0.4, plan=PLAN)
    for (_, ca, _), (_, cb, _), (_, cc, _) in zip(a, b, c):
        for k in ca:
            np.testing.assert_array_equal(ca[k], cb[k])
        assert not np.array_equal(ca["flow_lpm"], cc["flow_lpm"])


def test_short_gaps_are_interpolated_linearly_and_counted(campaign_dir):
    csv = campaign_dir / f"{CL}.csv"
    header = csv.read_text().splitlines()[0].split(",")
    j = header.index("p_a_bar")
    original = read_run(csv).columns["p_a_bar"].copy()

    def blank(lines):
        for line_no in range(101, 101 + MAX_GAP):  # MAX_GAP cells in a row, lines 101..105
            cells = lines[line_no - 1].split(",")
            cells[j] = ""
            lines[line_no - 1] = ",".join(cells)
        cells = lines[499].split(",")
        cells[j] = "NaN"
        lines[499] = ",".join(cells)
        return lines

    rewrite_csv(csv, blank)
    run = read_run(csv)
    assert run.interpolated == {"p_a_bar": MAX_GAP + 1}
    # samples 99..103 (file lines 101..105) lie on the line between samples 98 and 104
    k = np.arange(99, 104)
    expected = original[98] + (original[104] - original[98]) * (k - 98) / 6.0
    np.testing.assert_allclose(run.columns["p_a_bar"][k], expected, rtol=1e-12)
    camp = read_campaign(campaign_dir)
    assert camp.interpolated_total == MAX_GAP + 1
    assert f"{MAX_GAP + 1} missing samples interpolated" in camp.summary()


# --- each failure mode, with a message naming where and what --------------------------------


def refused(folder, *patterns):
    with pytest.raises(CampaignError) as exc:
        read_campaign(folder)
    msg = str(exc.value)
    for p in patterns:
        assert p in msg, msg
    return msg


def test_missing_required_column(campaign_dir):
    csv = campaign_dir / f"{CL}.csv"

    def drop_ref(lines):
        j = lines[0].split(",").index("theta_ref_deg")
        return [",".join(c for i, c in enumerate(line.split(",")) if i != j) for line in lines]

    rewrite_csv(csv, drop_ref)
    refused(campaign_dir, csv.name, "required column 'theta_ref_deg' is missing", "closed_loop")


def test_unknown_unit_and_unknown_column(campaign_dir):
    csv = campaign_dir / f"{CL}.csv"
    rewrite_csv(csv, lambda lines: [lines[0].replace("p_a_bar", "p_a_psi")] + lines[1:])
    refused(campaign_dir, csv.name, "'p_a_psi'", "unit 'psi'", "expected 'p_a_bar' (bar)")
    rewrite_csv(csv, lambda lines: [lines[0].replace("p_a_psi", "oil_temp_C")] + lines[1:])
    camp = read_campaign(campaign_dir)  # a column the format does not know is ignored and reported
    assert any("oil_temp_C" in w for w in camp.warnings)


def test_duplicate_column(campaign_dir):
    csv = campaign_dir / f"{CL}.csv"
    rewrite_csv(csv, lambda lines: [lines[0].replace("p_b_bar", "p_a_bar")] + lines[1:])
    refused(campaign_dir, "column 'p_a_bar' appears twice")


def test_non_monotonic_time(campaign_dir):
    csv = campaign_dir / f"{CL}.csv"

    def swap(lines):
        lines[10], lines[11] = lines[11], lines[10]
        return lines

    rewrite_csv(csv, swap)
    refused(campaign_dir, csv.name, "line 12", "strictly increasing time order")


def test_non_uniform_time(campaign_dir):
    csv = campaign_dir / f"{CL}.csv"

    def stretch(lines):
        out = [lines[0]]
        for k, line in enumerate(lines[1:]):
            cells = line.split(",")
            if k >= 200:
                cells[0] = f"{float(cells[0]) + 0.0005:.10g}"
            out.append(",".join(cells))
        return out

    rewrite_csv(csv, stretch)
    refused(campaign_dir, csv.name, "line 202", "time step 0.0015 s", "uniform")


def test_nan_island_longer_than_a_few_samples(campaign_dir):
    csv = campaign_dir / "valve_chirp.csv"

    def blank(lines):
        for line_no in range(300, 300 + MAX_GAP + 1):
            t, cur, _ = lines[line_no - 1].split(",")
            lines[line_no - 1] = f"{t},{cur},"
        return lines

    rewrite_csv(csv, blank)
    refused(campaign_dir, csv.name, "column 'flow_lpm'", f"{MAX_GAP + 1} missing samples in a row",
            "line 300 to 305", f"at most {MAX_GAP}")


def test_missing_time_and_bad_cells(campaign_dir):
    csv = campaign_dir / "valve_chirp.csv"
    good = csv.read_text()
    rewrite_csv(csv, lambda lines: lines[:50] + ["," + lines[50].split(",", 1)[1]] + lines[51:])
    refused(campaign_dir, "line 51", "time 't' is missing")
    csv.write_text(good)
    rewrite_csv(csv, lambda lines: lines[:50] + [lines[50].rsplit(",", 1)[0] + ",12.x"] + lines[51:])
    refused(campaign_dir, "line 51", "column 'flow_lpm'", "'12.x' is not a number", "LPM")
    csv.write_text(good)
    rewrite_csv(csv, lambda lines: lines[:50] + [lines[50] + ",7"] + lines[51:])
    refused(campaign_dir, "line 51", "4 cells, expected 3")
    csv.write_text("")
    refused(campaign_dir, "empty file")


@pytest.mark.parametrize("sets", [0, 8, 2.5, "3", True])
def test_disc_count_outside_1_to_7(campaign_dir, sets):
    js = campaign_dir / f"{CL}.json"
    rewrite_json(js, lambda m: m.__setitem__("disc_sets", sets))
    refused(campaign_dir, js.name, "key 'disc_sets'", "integer number of disc sets from 1 to 7")


def test_unparsable_and_missing_sidecar(campaign_dir):
    js = campaign_dir / f"{CL}.json"
    js.write_text('{"kind": "closed_loop",\n "disc_sets": 3,,}')
    refused(campaign_dir, js.name, "not valid JSON at line 2")
    js.write_text("[1, 2]")
    refused(campaign_dir, js.name, "expected a JSON object")
    js.unlink()
    refused(campaign_dir, f"{CL}.csv", f"sidecar {CL}.json is missing")


@pytest.mark.parametrize("edit, patterns", [
    (lambda m: m.__setitem__("kind", "open_loop"), ["key 'kind'", "closed_loop, valve_open_loop"]),
    (lambda m: m.pop("supply_bar"), ["key 'supply_bar' is missing", "bar"]),
    (lambda m: m.pop("reference"), ["key 'reference' is missing", "amplitude_deg"]),
    (lambda m: m["reference"].__setitem__("amplitude_deg", 50), ["reference: key 'amplitude_deg' = 50", "44.43"]),
    (lambda m: m["controller"].__setitem__("Kd", 0.1), ["controller: key 'Kd'", "Kp, Ki, Kv, Ka, rate_hz"]),
    (lambda m: m["controller"].pop("Ki"), ["controller: key 'Ki' is missing"]),
    (lambda m: m["reference"].__setitem__("freq_hz", 2.5), ["theta_ref_deg", "sidecar's reference", "freq_hz 2.5"]),
])
def test_sidecar_keys_are_checked(campaign_dir, edit, patterns):
    js = campaign_dir / f"{CL}.json"
    rewrite_json(js, edit)
    refused(campaign_dir, *patterns)


def test_no_runs_and_no_folder(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(CampaignError, match="no runs found"):
        read_campaign(tmp_path / "empty")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_campaign(tmp_path / "nope")


def test_low_sample_rate_refused():
    t = np.arange(100) * 0.02
    with pytest.raises(CampaignError, match="50 Hz; expected at least 100 Hz"):
        write_run("/nonexistent/never_written", {"t": t, "current_mA": t, "flow_lpm": t},
                  {"kind": "valve_open_loop", "supply_bar": 70})


def test_validate_meta_normalises_defaults():
    meta = validate_meta({"kind": "closed_loop", "disc_sets": 4.0, "supply_bar": 200,
                          "reference": {"amplitude_deg": 20, "freq_hz": 1},
                          "controller": {"Kp": 1, "Ki": 2, "Kv": 0.01, "Ka": 0.0001, "rate_hz": 1000}})
    assert meta["disc_sets"] == 4 and isinstance(meta["disc_sets"], int)
    assert meta["reference"]["ramp_cycles"] == 0.0 and meta["reference"]["phase_rad"] == 0.0
    assert meta["controller"]["Kj"] == 0.0 and meta["controller"]["Kdp"] == 0.0


# --- nothing written half-way ----------------------------------------------------------------


def test_write_campaign_validates_everything_before_writing(tmp_path, small_runs):
    runs, _ = small_runs
    name, cols, meta = runs[0]
    bad = (name + "_bad", cols, {**meta, "disc_sets": 9})
    with pytest.raises(CampaignError, match="disc_sets"):
        write_campaign(tmp_path / "out", [runs[1], bad])
    assert not (tmp_path / "out").exists()
    assert [p.name for p in tmp_path.iterdir()] == []  # no temporary folder left either
    write_campaign(tmp_path / "out", runs)
    with pytest.raises(CampaignError, match="not empty"):
        write_campaign(tmp_path / "out", runs)
    write_campaign(tmp_path / "out", runs[:1], overwrite=True)
    assert sorted(p.stem for p in (tmp_path / "out").glob("*.csv")) == [runs[0][0]]


@pytest.mark.parametrize("command", ["diagnose", "compare"])
def test_cli_refuses_malformed_campaign_and_writes_nothing(campaign_dir, tmp_path, capsys, command):
    js = campaign_dir / f"{CL}.json"
    rewrite_json(js, lambda m: m.__setitem__("disc_sets", 0))
    out_dir, out_json, model = tmp_path / "report", tmp_path / "d.json", tmp_path / "m.json"
    argv = [command, str(campaign_dir), "--out", str(out_dir)]
    argv += ["--json", str(out_json)] if command == "diagnose" else ["--save-model", str(model)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"ehas {command}: error:") and "disc_sets" in err[0]
    assert not out_dir.exists() and not out_json.exists() and not model.exists()


def test_simulate_campaign_cli(tmp_path, capsys):
    out = tmp_path / "camp"
    assert main(["simulate-campaign", "--effects", "valve_deadband:d=0.7", "--out", str(out), "--seed", "12",
                 "--duration", "0.5"]) == 0
    camp = read_campaign(out)
    assert len(camp.runs) == 5 and {r.kind for r in camp.runs} == {"closed_loop", "valve_open_loop"}
    truth = json.loads((out / "truth.json").read_text())
    assert truth["effects"] == {"valve_deadband": {"d": 0.7}} and truth["beta"] == 1e9
    assert "ehas simulate-campaign" in (out / "README.md").read_text()
    assert main(["simulate-campaign", "--out", str(out)]) == 2  # exists: refused, untouched
    assert "not empty" in capsys.readouterr().err
    assert main(["simulate-campaign", "--effects", "nope:x=1", "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()
