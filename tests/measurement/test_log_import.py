"""Logs as they come: what a real logger writes is read, or refused with one line that says why.

Each variant is made from a valid synthetic campaign by editing its files the way
a logger or a spreadsheet would: an extra channel, renamed columns, a byte-order
mark, CRLF line ends, ``;`` separators with decimal commas, and values in the
wrong unit (theta in rad, pressures in Pa or psi, current in A, time in ms, load
in N).  Folder reading reports every file it skips and why.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from ehas_env.measurement.synthetic import simulate_campaign
from ehas_env.cli.main import main
from ehas_env.measurement.campaign import CampaignError, parse_column_map, read_campaign, write_campaign

PLAN = ((2, 12.0, 2.0),)
CL = "cl_2sets_12deg_2hz"
VALVE = "valve_chirp"


@pytest.fixture(scope="module")
def runs():
    runs, _ = simulate_campaign({}, seed=3, duration=0.6, plan=PLAN)
    return runs


@pytest.fixture
def camp(tmp_path, runs):
    return write_campaign(tmp_path / "camp", runs)


def reference_values(folder: Path) -> dict:
    """{run: {column: array}} of the campaign as written (before any edit)."""
    c = read_campaign(folder)
    return {r.name: {"t": r.t, **r.columns} for r in c.runs}


def edit_csv(path: Path, fn):
    """Rewrite a CSV through ``fn(header_cells, rows_of_cells) -> (header, rows)``."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    header, rows = fn(header, rows)
    path.write_text("\n".join(",".join(r) for r in [header] + rows) + "\n")


def scale_column(path: Path, column: str, factor: float):
    def fn(header, rows):
        j = header.index(column)
        for r in rows:
            if r[j]:
                r[j] = repr(float(r[j]) * factor)
        return header, rows

    edit_csv(path, fn)


def refused(folder, *patterns, **kw) -> str:
    with pytest.raises(CampaignError) as exc:
        read_campaign(folder, **kw)
    msg = str(exc.value)
    assert "\n" not in msg, msg  # one line
    for p in patterns:
        assert p in msg, msg
    return msg


# --- columns -------------------------------------------------------------------------------------


def test_unknown_logger_channel_is_ignored_and_reported(camp):
    before = reference_values(camp)

    def add_temp(header, rows):
        return header + ["oil_temp_C", "status"], [r + ["41.5", "OK"] for r in rows]

    edit_csv(camp / f"{CL}.csv", add_temp)
    c = read_campaign(camp)
    run = next(r for r in c.runs if r.name == CL)
    assert run.ignored_columns == ["oil_temp_C", "status"]
    assert "oil_temp_C" not in run.columns
    assert any(f"{CL}.csv" in w and "oil_temp_C" in w and "status" in w for w in c.warnings)
    assert "ignored columns: oil_temp_C, status" in c.summary()
    np.testing.assert_array_equal(run.columns["theta_deg"], before[CL]["theta_deg"])


def test_columns_option_maps_a_loggers_names(camp, capsys):
    before = reference_values(camp)
    names = {"t": "Time", "theta_deg": "Angle 1", "theta_ref_deg": "Setpoint", "current_mA": "I_cmd"}
    for stem in (CL, VALVE):
        edit_csv(camp / f"{stem}.csv", lambda h, rows: ([names.get(c, c) for c in h], rows))
    refused(camp, "time must be the column 't'", "--columns t=Time")
    mapping = parse_column_map("t=Time,theta_deg=Angle 1,theta_ref_deg=Setpoint,current_mA=I_cmd")
    c = read_campaign(camp, columns=mapping)
    for r in c.runs:
        for col, v in before[r.name].items():
            np.testing.assert_array_equal(r.t if col == "t" else r.columns[col], v)
    assert next(r for r in c.runs if r.name == CL).column_map == mapping  # the closed-loop run used every entry
    # the command line takes the same option
    assert main(["compare", str(camp), "--columns", "t=Time,theta_deg=Angle 1,theta_ref_deg=Setpoint,current_mA=I_cmd"]) == 0
    assert "fit %" in capsys.readouterr().out


@pytest.mark.parametrize("text, pattern", [
    ("theta_deg", "is not NEW=OLD"),
    ("angle=Angle1", "'angle' is not a column of the measurement format"),
    ("theta_deg=A,theta_deg=B", "mapped twice"),
    ("theta_deg=A,theta_ref_deg=A", "mapped to two format columns"),
])
def test_columns_option_refuses_what_it_cannot_map(text, pattern):
    with pytest.raises(ValueError, match=pattern):
        parse_column_map(text)


def test_columns_option_naming_an_absent_column_is_refused(camp):
    # a mapping that renames nothing is a typo: reading on would leave out the column the user meant
    refused(camp, "--columns p_s_bar=Supply", "no run in", "has such a column", columns={"p_s_bar": "Supply"})


def test_a_mapping_one_closed_loop_file_lacks_is_said(tmp_path):
    """Two closed-loop runs, one logging the load as 'Force', one not logging it: the mapping is used, and the file
    without the column is named in a note (before: read without its load in silence).  The valve run, which never
    logs a load, is not named."""
    runs, _ = simulate_campaign({}, seed=4, duration=0.3, plan=((2, 12.0, 2.0), (3, 15.0, 1.0)))
    camp = write_campaign(tmp_path / "camp", runs)
    stems = sorted(p.stem for p in camp.glob("cl_*.csv"))
    edit_csv(camp / f"{stems[0]}.csv", lambda h, rows: ([("Force" if c == "load_kN" else c) for c in h], rows))
    edit_csv(camp / f"{stems[1]}.csv",
             lambda h, rows: ([c for c in h if c != "load_kN"], [[v for c, v in zip(h, r) if c != "load_kN"]
                                                                 for r in rows]))
    c = read_campaign(camp, columns={"load_kN": "Force"})
    notes = [w for w in c.warnings if "no such column" in w]
    assert notes == [f"{stems[1]}.csv: --columns load_kN=Force: this file has no such column (read without it)"]
    assert "load_kN" in next(r for r in c.runs if r.name == stems[0]).columns
    assert notes[0] in c.summary()


def test_renaming_onto_an_existing_column_is_a_duplicate(camp):
    edit_csv(camp / f"{CL}.csv", lambda h, rows: (h + ["Angle2"], [r + [r[h.index("theta_deg")]] for r in rows]))
    refused(camp, "column 'theta_deg' appears twice", "--columns", columns={"theta_deg": "Angle2"})


# --- encodings, line ends, separators --------------------------------------------------------------


def test_utf8_byte_order_mark(camp):
    before = reference_values(camp)
    p = camp / f"{CL}.csv"
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    js = camp / f"{CL}.json"
    js.write_bytes(b"\xef\xbb\xbf" + js.read_bytes())
    run = next(r for r in read_campaign(camp).runs if r.name == CL)
    np.testing.assert_array_equal(run.t, before[CL]["t"])


def test_crlf_line_ends(camp):
    before = reference_values(camp)
    p = camp / f"{CL}.csv"
    p.write_bytes(p.read_bytes().replace(b"\n", b"\r\n"))
    run = next(r for r in read_campaign(camp).runs if r.name == CL)
    np.testing.assert_array_equal(run.columns["p_a_bar"], before[CL]["p_a_bar"])


def test_semicolon_separator_with_decimal_commas(camp):
    before = reference_values(camp)
    p = camp / f"{CL}.csv"
    p.write_text(p.read_text().replace(",", ";").replace(".", ","))
    run = next(r for r in read_campaign(camp).runs if r.name == CL)
    for col in ("theta_deg", "current_mA", "load_kN"):
        np.testing.assert_array_equal(run.columns[col], before[CL][col])


def test_tab_separator(camp):
    before = reference_values(camp)
    p = camp / f"{VALVE}.csv"
    p.write_text(p.read_text().replace(",", "\t"))
    run = next(r for r in read_campaign(camp).runs if r.name == VALVE)
    np.testing.assert_array_equal(run.columns["flow_lpm"], before[VALVE]["flow_lpm"])


def test_mixed_separators_and_utf16_are_refused(camp):
    p = camp / f"{CL}.csv"
    text = p.read_text()
    header, rest = text.split("\n", 1)
    p.write_text(header.replace(",", ";", 2) + "\n" + rest)
    refused(camp, f"{CL}.csv", "line 1", "mixes separators")
    p.write_bytes(text.encode("utf-16"))
    refused(camp, f"{CL}.csv", "UTF-16", "UTF-8")


# --- implausible units ---------------------------------------------------------------------------


@pytest.mark.parametrize("stem, column, factor, patterns", [
    (CL, "theta_deg", np.pi / 180, ("'theta_deg'", "rad, not deg")),
    (CL, "theta_ref_deg", np.pi / 180, ("'theta_ref_deg'", "rad, not deg")),
    (CL, "p_a_bar", 1e5, ("'p_a_bar'", "Pa, not bar")),
    (CL, "p_s_bar", 1e5, ("'p_s_bar'", "Pa, not bar")),
    (CL, "p_b_bar", 14.5038, ("'p_b_bar'", "psi, not bar")),
    (CL, "current_mA", 1e-3, ("'current_mA'", "A, not mA")),
    (VALVE, "current_mA", 1e-3, ("'current_mA'", "A, not mA")),
    (CL, "t", 1e3, ("'t'", "ms, not s")),
    (VALVE, "t", 1e3, ("'t'", "ms, not s")),
    (CL, "load_kN", 1e3, ("'load_kN'", "N, not kN")),
])
def test_implausible_units_are_refused_with_the_likely_cause(camp, stem, column, factor, patterns):
    scale_column(camp / f"{stem}.csv", column, factor)
    if column == "theta_deg":  # the reference in rad as well: a logger writes both in one unit
        scale_column(camp / f"{stem}.csv", "theta_ref_deg", factor)
    refused(camp, f"{stem}.csv", *patterns)


def test_plausible_small_signals_are_not_taken_for_wrong_units(tmp_path):
    """A gentle run (1 set, 3 deg at 1 Hz) has small currents and pressures swings: it is read."""
    runs, _ = simulate_campaign({}, seed=4, duration=2.2, plan=((1, 3.0, 1.0),), valve=False)
    c = read_campaign(write_campaign(tmp_path / "gentle", runs))
    assert len(c.runs) == 1 and c.warnings == []


# --- the folder ------------------------------------------------------------------------------------


def test_every_skipped_file_is_reported_with_its_reason(camp):
    (camp / "orphan.json").write_text("{}")
    (camp / "notes.txt").write_text("rig log book")
    os.symlink(camp / "gone.csv", camp / "dangling.csv")
    os.symlink(camp / "loop_b.csv", camp / "loop_a.csv")
    os.symlink(camp / "loop_a.csv", camp / "loop_b.csv")
    (camp / "folder_run.csv").mkdir()
    c = read_campaign(camp)
    assert [r.name for r in c.runs] == [CL, VALVE]
    text = "\n".join(c.warnings)
    for name, why in [("orphan.json", "no orphan.csv beside it"), ("notes.txt", "not a run file"),
                      ("dangling.csv", "dangling symbolic link"), ("loop_a.csv", "loops"),
                      ("loop_b.csv", "loops"), ("folder_run.csv", "a folder, not a file")]:
        assert any(name in w and why in w for w in c.warnings), (name, text)
    assert "skipped orphan.json" in c.summary()


def test_unreadable_csv_is_a_clear_error(camp, monkeypatch):
    p = camp / f"{CL}.csv"
    if os.geteuid() == 0:  # root reads anything: simulate what a user without the permission sees
        real = Path.read_bytes

        def read_bytes(self):
            if self.name == p.name:
                raise PermissionError(13, "Permission denied", str(self))
            return real(self)

        monkeypatch.setattr(Path, "read_bytes", read_bytes)
    else:
        p.chmod(0)
    refused(camp, f"{CL}.csv", "cannot be read (permission denied)")


def test_a_file_given_as_the_campaign_folder(camp, capsys):
    refused(camp / f"{CL}.csv", "is a file, not a folder", f"give its folder, {camp}")
    assert main(["diagnose", str(camp / f"{CL}.json")]) == 2
    err = capsys.readouterr().err
    assert "is a file, not a folder" in err and "Traceback" not in err


def test_no_runs_names_what_was_skipped(tmp_path):
    folder = tmp_path / "c"
    folder.mkdir()
    (folder / "run1.json").write_text(json.dumps({"kind": "valve_open_loop", "supply_bar": 70}))
    refused(folder, "no runs found", "skipped run1.json")
