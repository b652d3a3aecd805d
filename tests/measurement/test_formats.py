"""One campaign, every log format: CSV, MATLAB v5 and v7.3, NI TDMS, HDF5, Parquet and a mix read the same.

The files are written with the libraries real loggers' files are written and
read with (``format_writers``: scipy, hdf5storage + mat73, npTDMS, h5py,
pyarrow), not with ehas's writers; the truth is the CSV campaign, the format
ehas has always read.  ``read_campaign`` must give identical arrays, the
model-vs-measurement comparison identical numbers (the Python API ``ehas
compare`` prints from, and its printed output), ``ehas diagnose --json``
identical numbers (slow), and ``ehas identify``'s reader the same record.  The
registry finds a format from its one file.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from format_writers import as_logged, write_campaign_as

from ehas_env.cli.main import main
from ehas_env.measurement import formats
from ehas_env.measurement.campaign import read_campaign, write_campaign
from ehas_env.measurement.synthetic import simulate_campaign

PLAN = ((2, 12.0, 2.0), (4, 20.0, 1.0))
HIDDEN = {"coulomb_friction": {"Fc": 300.0}}
LABELS = ["mat5", "mat73", "tdms", "hdf5", "parquet"]
MIXED = ["tdms", "mat73", "csv"]  # three runs, three formats


@pytest.fixture(scope="module")
def runs():
    runs, _ = simulate_campaign(HIDDEN, seed=11, duration=1.0, plan=PLAN)
    return as_logged(runs)


@pytest.fixture(scope="module")
def folders(runs, tmp_path_factory):
    root = tmp_path_factory.mktemp("formats")
    out = {label: write_campaign_as(root / label, runs, label) for label in ["csv", *LABELS]}
    out["mixed"] = write_campaign_as(root / "mixed", runs, MIXED)
    return out


def assert_same_campaign(a, b):
    assert [r.name for r in a.runs] == [r.name for r in b.runs]
    for ra, rb in zip(a.runs, b.runs):
        assert ra.meta == rb.meta and ra.dt == rb.dt and ra.interpolated == rb.interpolated
        assert np.array_equal(ra.t, rb.t)
        assert list(ra.columns) == list(rb.columns) or set(ra.columns) == set(rb.columns)
        for c in ra.columns:
            assert np.array_equal(ra.columns[c], rb.columns[c]), (rb.path, c)


@pytest.mark.parametrize("label", LABELS + ["mixed"])
def test_every_format_reads_as_the_csv(folders, label):
    csv, other = read_campaign(folders["csv"]), read_campaign(folders[label])
    assert_same_campaign(csv, other)
    assert other.warnings == []
    if label == "mixed":
        assert [r.path.suffix for r in other.runs] == [".tdms", ".mat", ".csv"]


@pytest.mark.parametrize("label", LABELS + ["mixed"])
def test_the_comparison_gives_the_same_numbers(folders, label):
    """What ``ehas compare`` prints comes from Replayer.fit_table: every number of it, exactly."""
    from ehas_env.measurement.replay import ModelSpec, Replayer

    def numbers(folder):
        rep = Replayer(read_campaign(folder))
        table = rep.fit_table(rep.simulate(ModelSpec(effects=HIDDEN)))
        return table.overall, table.per_signal, table.per_run

    want, got = numbers(folders["csv"]), numbers(folders[label])
    assert got == want
    assert 90.0 < want[0] <= 100.0  # the hidden effect added back explains the runs: a comparison worth comparing


@pytest.mark.parametrize("label", ["tdms", "mixed"])
def test_ehas_compare_prints_the_same(folders, label, capsys):
    def printed(folder):
        assert main(["compare", str(folder), "--effects", "coulomb_friction:Fc=300"]) == 0
        out = capsys.readouterr().out
        return [line for line in out.splitlines() if str(folder) not in line and not line.startswith("elapsed")]

    want, got = printed(folders["csv"]), printed(folders[label])
    assert got == want and any("overall fit:" in line for line in want)


@pytest.mark.slow
@pytest.mark.parametrize("label", LABELS + ["mixed"])
def test_ehas_diagnose_json_gives_the_same_numbers(folders, label, tmp_path, capsys):
    """About 6 s per campaign once the models are compiled."""
    def diagnosis(folder):
        out = tmp_path / f"{folder.name}.json"
        assert main(["diagnose", str(folder), "--json", str(out), "--quiet"]) == 0
        doc = json.loads(out.read_text())
        doc.pop("campaign"), doc.pop("elapsed_s")
        return doc

    want = diagnosis(folders["csv"])
    assert diagnosis(folders[label]) == want
    assert want["ranking"][0]["effect"] in ("coulomb_friction", "stribeck_friction")


@pytest.mark.parametrize("label", ["csv", *LABELS])
def test_identify_reads_every_format_alike(folders, label):
    """``ehas identify``'s reader goes through the same registry (no sidecar needed)."""
    from ehas_env.identification.fit import read_columns

    path = next(p for p in folders[label].iterdir() if p.stem == "valve_chirp" and p.suffix != ".json")
    (folders[label] / "valve_chirp.json").rename(folders[label] / "valve_chirp.json.off")
    try:
        got = read_columns(path)
    finally:
        (folders[label] / "valve_chirp.json.off").rename(folders[label] / "valve_chirp.json")
    want = read_columns(folders["csv"] / "valve_chirp.csv")
    assert np.array_equal(got.t, want.t) and np.array_equal(got.u, want.u) and np.array_equal(got.y, want.y)
    assert got.dt == want.dt and got.n == 1000


@pytest.mark.parametrize("fmt", ["csv", "mat", "tdms", "hdf5", "parquet"])
def test_ehas_writes_every_format_it_reads(runs, fmt, tmp_path):
    folder = write_campaign(tmp_path / fmt, runs, fmt=fmt)
    suffix = formats.by_name(fmt).suffixes[0]
    assert sorted(p.suffix for p in folder.iterdir()) == sorted([suffix, ".json"] * len(runs))
    assert_same_campaign(read_campaign(folder), read_campaign(write_campaign(tmp_path / "reference", runs)))


def test_columns_mapping_and_group_apply_to_tdms(runs, tmp_path):
    """A test engineer's TDMS: their channel names, a second group; --columns maps names and picks the group."""
    from format_writers import tdms
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    names = {"t": "Time", "current_mA": "I_cmd", "theta_deg": "Angle1", "theta_ref_deg": "Setpoint"}
    folder = tmp_path / "eng"
    folder.mkdir()
    for name, cols, meta in runs[:1]:
        renamed = {names.get(c, c): v for c, v in cols.items()}
        path = folder / f"{name}.tdms"
        units = {names.get(c, c): u for c, u in {"t": "s", "current_mA": "mA", "theta_deg": "deg"}.items()}
        tdms(path, renamed, group="Data", units=units)
        with TdmsWriter(str(path), mode="a") as w:  # a second group, as NI software writes a header group
            w.write_segment([GroupObject("Info"), ChannelObject("Info", "operator", np.array(["me"] * 3))])
        (folder / f"{name}.json").write_text(json.dumps(meta))
    from ehas_env.measurement.campaign import CampaignError

    with pytest.raises(CampaignError, match=r"\.tdms: 2 groups \(Data, Info\).*--columns group=NAME"):
        read_campaign(folder)
    mapping = {**{k: v for k, v in names.items()}, "group": "Data"}
    got = read_campaign(folder, columns=mapping)
    want = read_campaign(write_campaign(tmp_path / "csv", runs[:1]))
    assert_same_campaign(want, got)
    assert got.runs[0].column_map == names


def test_tdms_waveform_channels_give_the_time(runs, tmp_path):
    """NI loggers write waveforms: no time channel, wf_start_offset and wf_increment on every channel."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    name, cols, meta = runs[-1]
    dt = float(cols["t"][1] - cols["t"][0])
    path = tmp_path / f"{name}.tdms"
    props = {"wf_start_offset": float(cols["t"][0]), "wf_increment": dt}
    with TdmsWriter(str(path)) as w:
        w.write_segment([GroupObject("wave")] + [ChannelObject("wave", c, v, properties=props)
                                                 for c, v in cols.items() if c != "t"])
    (tmp_path / f"{name}.json").write_text(json.dumps(meta))
    run = read_campaign(tmp_path).runs[0]
    assert run.dt == pytest.approx(dt, rel=1e-12) and run.n == cols["t"].size
    assert np.array_equal(run.columns["flow_lpm"], cols["flow_lpm"])


def test_a_matlab_written_v73_file_reads(tmp_path):
    """MATLAB 7.4's own HDF5 MAT file (tests/measurement/data/matlab/PROVENANCE.md): its variable, its values."""
    path = Path(__file__).parent / "data" / "matlab" / "testhdf5_7.4_GLNX86.mat"
    table = formats.read_table(path, lambda names: names)
    assert table.names == ["testdouble"]
    assert np.allclose(table.columns["testdouble"], np.arange(9) * np.pi / 4, rtol=0, atol=1e-15)


def test_a_format_is_one_file_in_one_folder(runs, tmp_path, monkeypatch):
    """A new format module dropped beside the others is found and read; nothing else is edited."""
    plugin = tmp_path / "pkg"
    plugin.mkdir()
    (plugin / "whitespace.py").write_text(
        "import numpy as np\n"
        "from ehas_env.measurement.formats import RunFormat, Table, register\n"
        "def read(path, keep, group=None):\n"
        "    lines = path.read_text().split('\\n')\n"
        "    names = lines[0].split()\n"
        "    data = np.array([[float(x) for x in ln.split()] for ln in lines[1:] if ln.strip()])\n"
        "    return Table(columns={n: data[:, names.index(n)] for n in keep(names)}, names=names)\n"
        "register(RunFormat(name='WS', suffixes=('.ws',), read=read, layout='whitespace-separated columns'))\n")
    monkeypatch.setattr(formats, "__path__", [*formats.__path__, str(plugin)])
    monkeypatch.setattr(formats, "_REGISTRY", dict(formats._REGISTRY))
    monkeypatch.setattr(formats, "_LOADED", False)
    monkeypatch.delitem(sys.modules, "ehas_env.measurement.formats.whitespace", raising=False)
    folder = tmp_path / "camp"
    folder.mkdir()
    for name, cols, meta in runs:
        names = list(cols)
        rows = [" ".join(names)] + [" ".join(f"{x:.10g}" for x in row) for row in np.column_stack(list(cols.values()))]
        (folder / f"{name}.ws").write_text("\n".join(rows) + "\n")
        (folder / f"{name}.json").write_text(json.dumps(meta))
    assert_same_campaign(read_campaign(write_campaign(tmp_path / "csv", runs)), read_campaign(folder))
    sys.modules.pop("ehas_env.measurement.formats.whitespace", None)


def test_a_csv_of_numbers_reads_the_same_as_pythons_csv_and_float_cell_by_cell(tmp_path):
    """The all-at-once reading of a numbers-only file against the standard library's csv module and float(),
    on cells written every way a logger writes them; a single empty cell takes the careful path, same numbers."""
    import csv as std_csv

    from ehas_env.measurement.formats import csv as csv_format

    rng = np.random.default_rng(7)
    x = rng.normal(0, 1e3, size=(3000, 4)) * 10.0 ** rng.integers(-6, 6, size=(3000, 4))
    styles = [lambda v: f"{v:.10g}", lambda v: f"{v:e}", lambda v: f" {v:.3f}", lambda v: f"{round(v)}"]
    rows = [[styles[(i + j) % 4](v) for j, v in enumerate(r)] for i, r in enumerate(x)]
    for name, body in (("numbers.csv", rows), ("one_empty.csv", [r if i != 1234 else [r[0], "", *r[2:]]
                                                               for i, r in enumerate(rows)])):
        f = tmp_path / name
        f.write_text("t,a,b,c\n" + "\n".join(",".join(r) for r in body) + "\n")
        table = csv_format.read(f, lambda names: names)
        at_once = csv_format._numbers_at_once(f.read_text().splitlines()[1:], ",", 4, [0, 1, 2, 3])
        assert (at_once is None) == (name == "one_empty.csv")     # which path read it
        with f.open(newline="") as fh:
            ref = list(std_csv.reader(fh))[1:]
        for j, col in enumerate(("t", "a", "b", "c")):
            expected = np.array([float(r[j]) if r[j].strip() else np.nan for r in ref])
            np.testing.assert_array_equal(table.columns[col], expected)
