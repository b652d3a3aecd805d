"""Issue 14 for campaigns: every bad run file, sidecar or argument is one clear line.

``read_campaign`` and ``validate_run`` refuse with a CampaignError (a ValueError)
of one line that names the file and line, column or key, and says what is
expected; nothing escapes as a TypeError, AttributeError or numpy error, and no
absurd value (a current of 1e300 mA, a crank at 12 000 deg, a rate of 1 GHz) is
taken silently.  What ``test_campaign.py`` and ``test_log_import.py`` already
refuse (a missing column or sidecar, a non-number cell, swapped rows, an empty
file, disc_sets 0 or 8, Pa/psi/rad/A/ms/N, an unreadable CSV, a file for the
folder, a folder without runs) is not repeated here.
"""
from __future__ import annotations

import functools
import json
import os
from pathlib import Path

import numpy as np
import pytest
from refusals import refused  # tests/ is on sys.path (conftest.py)

import ehas_env.measurement.campaign as campaign
import ehas_env.measurement.formats.csv as csv_format
from ehas_env.measurement.synthetic import simulate_campaign
from ehas_env.measurement.campaign import CampaignError, read_campaign, validate_run, write_campaign

PLAN = ((2, 12.0, 2.0),)
CL = "cl_2sets_12deg_2hz"
VALVE = "valve_chirp"


@pytest.fixture(scope="module")
def runs():
    runs, _ = simulate_campaign({}, seed=5, duration=0.6, plan=PLAN)
    assert [name for name, _, _ in runs] == [CL, VALVE]
    return runs


@pytest.fixture
def camp(tmp_path, runs):
    return write_campaign(tmp_path / "camp", runs)


refused = functools.partial(refused, exc=CampaignError)  # every refusal here is a CampaignError


def edit_lines(path: Path, fn):
    lines = path.read_text().splitlines()
    path.write_text("\n".join(fn(lines)) + "\n")


def set_cell(path: Path, line_no: int, column: str, value: str):
    def fn(lines):
        j = lines[0].split(",").index(column)
        cells = lines[line_no - 1].split(",")
        cells[j] = value
        lines[line_no - 1] = ",".join(cells)
        return lines

    edit_lines(path, fn)


def scale_column(path: Path, column: str, factor: float):
    def fn(lines):
        j = lines[0].split(",").index(column)
        out = [lines[0]]
        for line in lines[1:]:
            cells = line.split(",")
            if cells[j]:
                cells[j] = repr(float(cells[j]) * factor)
            out.append(",".join(cells))
        return out

    edit_lines(path, fn)


def edit_json(path: Path, fn):
    meta = json.loads(path.read_text())
    fn(meta)
    path.write_text(json.dumps(meta))


# --- run files -----------------------------------------------------------------------------------


@pytest.mark.parametrize("value", ["inf", "-inf", "1e400", "Infinity"])
def test_infinite_cell(camp, value):
    set_cell(camp / f"{VALVE}.csv", 50, "flow_lpm", value)
    refused(lambda: read_campaign(camp), f"{VALVE}.csv, line 50, column 'flow_lpm'", f"'{value}' is not finite",
            "leave the cell empty for a missing sample")


def test_infinite_time_in_memory(runs):
    name, cols, meta = runs[1]
    t = np.array(cols["t"], dtype=float)
    t[-1] = np.inf
    refused(lambda: validate_run(name, {**cols, "t": t}, meta), f"{name}, sample {t.size - 1}", "time 't' = inf",
            "not finite")


def test_duplicated_time(camp):
    edit_lines(camp / f"{VALVE}.csv", lambda lines: lines[:11] + [lines[10]] + lines[11:])  # line 11 twice
    refused(lambda: read_campaign(camp), f"{VALVE}.csv, line 12", "does not come after", "strictly increasing")


@pytest.mark.parametrize("keep, patterns", [
    (2, ["1 sample; expected at least 20"]),
    (1, ["a header line and no samples", "one row per sample", "at least 20"]),  # was "0 samples"
])
def test_too_few_rows(camp, keep, patterns):
    edit_lines(camp / f"{VALVE}.csv", lambda lines: lines[:keep] + [""] * 3)
    refused(lambda: read_campaign(camp), f"{VALVE}.csv", *patterns)


def test_blank_line_inside_the_rows(camp):
    edit_lines(camp / f"{VALVE}.csv", lambda lines: lines[:50] + [""] + lines[50:])
    refused(lambda: read_campaign(camp), f"{VALVE}.csv, line 51", "1 cells, expected 3")


def test_a_trailing_separator_is_an_unnamed_column_that_is_ignored(camp):
    edit_lines(camp / f"{VALVE}.csv", lambda lines: [line + "," for line in lines])
    c = read_campaign(camp)
    assert any(f"{VALVE}.csv" in w and "(unnamed column 4)" in w for w in c.warnings), c.warnings


def test_too_large_a_run_file_is_refused_before_it_is_read(camp, monkeypatch):
    monkeypatch.setattr(csv_format, "MAX_CSV_BYTES", 1000)
    size = (camp / f"{CL}.csv").stat().st_size  # the first run read
    refused(lambda: read_campaign(camp), f"{CL}.csv", f"{size:,} bytes, more than the 1,000", "split the run")


def test_too_many_rows_are_refused_before_they_are_parsed(camp, monkeypatch):
    monkeypatch.setattr(csv_format, "MAX_SAMPLES", 100)
    refused(lambda: read_campaign(camp), ".csv", "rows; a run holds at most 100 samples")


# --- values in no plausible unit -----------------------------------------------------------------


@pytest.mark.parametrize("stem, column, factor, patterns", [
    (CL, "theta_deg", 1e3, ["column 'theta_deg'", "beyond the stroke ends at +-44.43 deg", "in deg"]),
    (CL, "current_mA", 1e3, ["column 'current_mA'", "far beyond the servo amplifier's +-20 mA", "uA, not mA"]),
    (VALVE, "current_mA", 1e3, ["column 'current_mA'", "+-20 mA", "uA, not mA (divide by 1000)"]),
    (CL, "current_mA", 1e300, ["column 'current_mA'", "+-20 mA; expected mA"]),
    (VALVE, "flow_lpm", 1e3, ["column 'flow_lpm'", "the valve passes at most about 25.4 LPM at 70 bar",
                              "expected LPM"]),  # was blamed on current_mA ("logged in A")
    (CL, "flow_lpm", 1e300, ["column 'flow_lpm'", "at most about 45.1 LPM at 220 bar"]),
    (VALVE, "t", 1e-6, ["sampled at 1e+09 Hz", "expected at most 1e+06 Hz"]),
])
def test_absurd_magnitudes(camp, stem, column, factor, patterns):
    """Each was read without a word before."""
    scale_column(camp / f"{stem}.csv", column, factor)
    refused(lambda: read_campaign(camp), f"{stem}.csv", *patterns)


# --- sidecars ------------------------------------------------------------------------------------


@pytest.mark.parametrize("text, patterns", [
    ("null", ["expected a JSON object", "got NoneType"]),
    ('"valve"', ["expected a JSON object", "got str"]),
    ("", ["not valid JSON at line 1 column 1"]),
])
def test_sidecar_that_is_not_an_object(camp, text, patterns):
    (camp / f"{VALVE}.json").write_text(text)
    refused(lambda: read_campaign(camp), f"{VALVE}.json", *patterns)


@pytest.mark.parametrize("stem, edit, patterns", [
    (VALVE, lambda m: m.pop("kind"), ["key 'kind' is missing", "closed_loop, valve_open_loop"]),  # was "= None"
    (VALVE, lambda m: m.__setitem__("kind", ["closed_loop"]), ["key 'kind' = ['closed_loop']", "valve_open_loop"]),
    (VALVE, lambda m: m.__setitem__("supply_bar", float("nan")), ["key 'supply_bar' = nan", "(0, 400]"]),
    (VALVE, lambda m: m.__setitem__("supply_bar", "70"), ["key 'supply_bar' = '70'", "(0, 400]"]),
    (VALVE, lambda m: m.__setitem__("supply_bar", 1e9), ["key 'supply_bar'", "(0, 400]"]),
    (CL, lambda m: m.__setitem__("disc_sets", 9), ["key 'disc_sets' = 9", "from 1 to 7"]),
    (CL, lambda m: m.pop("disc_sets"), ["key 'disc_sets' is missing", "from 1 to 7"]),
    (CL, lambda m: m.__setitem__("reference", [12, 2]), ["key 'reference' is [12, 2]", "amplitude_deg"]),
    (CL, lambda m: m["reference"].__setitem__("amplitude_deg", "12"), ["reference: key 'amplitude_deg' = '12'",
                                                                       "(0, 44.43)"]),
    (CL, lambda m: m["reference"].__setitem__("freq_hz", 1e6), ["reference: key 'freq_hz'", "(0, 50]"]),
    (CL, lambda m: m["controller"].__setitem__("Kp", 1e300),
     ["controller: key 'Kp' = 1e+300", "a gain in [-1e+06, 1e+06]"]),  # was taken
    (CL, lambda m: m["controller"].__setitem__("Kdp", -1e7), ["controller: key 'Kdp'", "[-1e+06, 1e+06]"]),
    (CL, lambda m: m["controller"].__setitem__("rate_hz", 1e300),
     ["controller: key 'rate_hz' = 1e+300", "in [100, 1e+06]"]),  # was taken
    (CL, lambda m: m["controller"].__setitem__("rate_hz", 50), ["controller: key 'rate_hz' = 50", "[100, 1e+06]"]),
    (CL, lambda m: m.__setitem__("controller", [1]), ["key 'controller' is [1]", "Kp"]),
    (CL, lambda m: m.__setitem__("notes", 5), ["key 'notes' must be free text"]),
])
def test_sidecar_keys(camp, stem, edit, patterns):
    edit_json(camp / f"{stem}.json", edit)
    refused(lambda: read_campaign(camp), f"{stem}.json", *patterns)


def _unreadable_sidecar(camp, monkeypatch, chmod: bool):
    js = camp / f"{CL}.json"
    if chmod:
        js.chmod(0)
    else:  # what a user without the permission sees, as root
        real = Path.read_bytes

        def read_bytes(self):
            if self.name == js.name:
                raise PermissionError(13, "Permission denied", str(self))
            return real(self)

        monkeypatch.setattr(Path, "read_bytes", read_bytes)
    refused(lambda: read_campaign(camp), f"{CL}.json", "cannot be read (permission denied)", "JSON object")


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads a file of mode 000")
def test_unreadable_sidecar_chmod(camp, monkeypatch):
    _unreadable_sidecar(camp, monkeypatch, chmod=True)


def test_unreadable_sidecar(camp, monkeypatch):
    _unreadable_sidecar(camp, monkeypatch, chmod=False)


# --- read_campaign's arguments -------------------------------------------------------------------


@pytest.mark.parametrize("path, patterns", [
    (None, ["the campaign must be a folder's path", "got NoneType"]),  # was a TypeError
    (123, ["the campaign must be a folder's path", "got int"]),
])
def test_campaign_path_of_the_wrong_type(path, patterns):
    refused(lambda: read_campaign(path), *patterns)


@pytest.mark.parametrize("columns, patterns", [
    ("theta_deg=Angle1", ["columns must be a dict {format column: logger column}, got str",
                          "parse_column_map('theta_deg=Angle1')"]),  # was an AttributeError
    ({"angle": "theta_deg"}, ["columns: 'angle' is not a column of the measurement format",
                              "t, current_mA, theta_deg"]),  # was "required column 'theta_deg' is missing"
    ({"theta_deg": 5}, ["columns: 'theta_deg' maps to 5", "the logger's column name (text)"]),  # was a warning
    ({"theta_deg": "A", "theta_ref_deg": "A"}, ["logger's column 'A' is mapped to two format columns"]),
])
def test_bad_column_map(camp, columns, patterns):
    refused(lambda: read_campaign(camp, columns=columns), *patterns)
    refused(lambda: campaign.read_run(camp / f"{CL}.csv", columns=columns), *patterns)


# --- validate_run's arguments (runs built in memory) ---------------------------------------------


def flow_column(runs):
    return np.asarray(runs[1][1]["flow_lpm"], dtype=float)


@pytest.mark.parametrize("make, patterns", [
    (lambda cols, q: None, ["x: expected the run's columns as a dict {name: values}, got NoneType"]),
    (lambda cols, q: [1, 2], ["expected the run's columns as a dict", "got list"]),  # was an AttributeError
    (lambda cols, q: {**cols, 5: q}, ["x: column name 5 is not text", "t, current_mA"]),  # AttributeError
    (lambda cols, q: {**cols, "flow_lpm": ["a"] * q.size}, ["x, column 'flow_lpm': expected one number in LPM "
                                                            "per sample, got text"]),  # float()'s ValueError
    (lambda cols, q: {**cols, "flow_lpm": [str(v) for v in q]}, ["column 'flow_lpm'", "got text"]),  # was taken
    (lambda cols, q: {**cols, "flow_lpm": None}, ["column 'flow_lpm'", "1-D sequence", "the single value None"]),
    (lambda cols, q: {**cols, "flow_lpm": 1.0}, ["column 'flow_lpm'", "the single value 1.0"]),
    (lambda cols, q: {k: np.tile(np.asarray(v)[:, None], (1, 2)) for k, v in cols.items()},
     ["column 't'", "an array of shape", ", 2)"]),  # was "t = 0 s does not come after 0 s"
    (lambda cols, q: {**cols, "flow_lpm": q + 1j}, ["column 'flow_lpm'", "complex numbers"]),  # was a warning
    (lambda cols, q: {**cols, "flow_lpm": q > 0}, ["column 'flow_lpm'", "true/false values"]),  # was taken
    (lambda cols, q: {**cols, "flow_lpm": [[1.0, 2.0], [3.0]]}, ["column 'flow_lpm'", "a ragged list"]),
    (lambda cols, q: {**cols, "flow_lpm": [*q[:-1], "x"]}, ["column 'flow_lpm'", "got text"]),
    (lambda cols, q: {**cols, "flow_lpm": [object(), *q[1:]]}, ["column 'flow_lpm'", "<object object",
                                                               "at sample 0"]),
    (lambda cols, q: {"t": [], "current_mA": [], "flow_lpm": []}, ["x: 0 samples; expected at least 20"]),
])
def test_bad_columns_in_memory(runs, make, patterns):
    _, cols, meta = runs[1]
    refused(lambda: validate_run("x", make(cols, flow_column(runs)), meta), *patterns)


def test_bad_sidecar_in_memory(runs):
    _, cols, _ = runs[1]
    refused(lambda: validate_run("x", cols, None), "x sidecar: expected a JSON object", "got NoneType")
    refused(lambda: campaign.write_run("/nonexistent/never_written", cols, {"supply_bar": 70}),
            "never_written sidecar: key 'kind' is missing")


def test_none_among_numbers_is_a_missing_sample(runs):
    """As NaN: interpolated and counted (and a column vector is one column)."""
    name, cols, meta = runs[1]
    q = flow_column(runs)
    gappy = [None if k in (100, 101) else float(v) for k, v in enumerate(q)]
    run = validate_run(name, {**cols, "flow_lpm": gappy, "current_mA": np.asarray(cols["current_mA"])[:, None]},
                       meta)
    assert run.interpolated == {"flow_lpm": 2}
    np.testing.assert_allclose(run.columns["flow_lpm"][[99, 102]], q[[99, 102]])
    np.testing.assert_array_equal(run.columns["current_mA"], np.asarray(cols["current_mA"], dtype=float))


@pytest.mark.parametrize("run", [CL, VALVE])
def test_current_logged_in_microamps(camp, run):
    """x1000 on a run whose true peak is a few mA lands between the servo amplifier's 20 mA and the
    1000 mA beyond which anything is refused: the motion (closed loop) or the flow (valve run) says uA."""
    csv = camp / f"{run}.csv"
    peak = max(abs(float(line.split(",")[1])) for line in csv.read_text().splitlines()[1:])
    factor = 300.0 / peak  # a 300 mA peak: inside the old 1000 mA limit
    assert factor > 20
    scale_column(csv, "current_mA", factor)
    refused(lambda: read_campaign(camp), f"{run}.csv", "column 'current_mA'", "looks logged in uA")


def test_clean_runs_are_not_taken_for_microamps(camp):
    """The true currents (full-scale valve chirp, closed loop with the book's gains) pass."""
    assert len(read_campaign(camp).runs) == 2


def test_a_column_map_that_renames_nothing_is_refused(camp):
    # a typo in --columns would silently leave a column out
    refused(lambda: read_campaign(camp, columns={"theta_deg": "Nope"}), "--columns theta_deg=Nope",
            "no run in", "has such a column", "current_mA")


@pytest.mark.parametrize("key, value, words", [
    ("format", "ehas-controller", ("key 'format' = 'ehas-controller'", "ehas-run")),
    ("version", 2, ("key 'version' = 2", "version 1")),
    ("version", "1", ("key 'version' = '1'",)),
])
def test_sidecar_kind_and_version_are_checked_when_given(camp, key, value, words):
    edit_json(camp / f"{CL}.json", lambda m: m.update({key: value}))
    refused(lambda: read_campaign(camp), f"{CL}.json", *words)


def test_sidecar_with_format_and_version_1_reads(camp):
    edit_json(camp / f"{CL}.json", lambda m: m.update({"format": "ehas-run", "version": 1}))
    assert len(read_campaign(camp).runs) == 2
