"""Bad run files of every format: one line naming the file and what is allowed, and nothing in them is run.

Each bad file is made the way it happens (a truncated copy, a logger's 2-D
array, a text channel where a number belongs, a unit the format does not take,
a MATLAB object or function handle, an HDF5 filter plug-in) with the library
that writes that format.  The MATLAB objects come from MATLAB itself
(``data/matlab/PROVENANCE.md``).  What CSV refuses is in ``test_campaign*.py``
and ``test_log_import.py``; here the same refusals hold for the other formats.
"""
from __future__ import annotations

import functools
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from format_writers import UNITS, WRITERS, as_logged, hdf5, mat5, tdms, write_run
from refusals import refused

from ehas_env.measurement import formats
from ehas_env.measurement.campaign import CampaignError, read_campaign
from ehas_env.measurement.synthetic import simulate_campaign

MATLAB = Path(__file__).parent / "data" / "matlab"
PLAN = ((2, 12.0, 2.0),)
CL = "cl_2sets_12deg_2hz"
BINARY = ["mat5", "mat73", "tdms", "hdf5", "parquet"]

refused = functools.partial(refused, exc=CampaignError)


@pytest.fixture(scope="module")
def runs():
    runs, _ = simulate_campaign({}, seed=5, duration=0.5, plan=PLAN, valve=False)
    return as_logged(runs)


def one_run(tmp_path, runs, label, edit=None):
    """A campaign of the closed-loop run written in ``label`` after ``edit(cols)``; its data file."""
    name, cols, meta = runs[0]
    cols = {c: np.array(v) for c, v in cols.items()}
    if edit is not None:
        cols = edit(cols) or cols
    return write_run(tmp_path / "camp", name, cols, meta, label)


def read(path):
    return read_campaign(path.parent)


# -- the same refusals in every format ---------------------------------------------------------------------

@pytest.mark.parametrize("label", BINARY)
def test_corrupt_file(tmp_path, runs, label):
    path = one_run(tmp_path, runs, label)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 3])  # a copy cut short
    msg = refused(lambda: read(path), str(path))
    assert "expected" in msg


@pytest.mark.parametrize("label", BINARY)
def test_not_that_format_at_all(tmp_path, runs, label):
    path = one_run(tmp_path, runs, label)
    path.write_text("t,current_mA\n0,1\n")  # a CSV saved under the wrong suffix
    refused(lambda: read(path), str(path), "expected")


@pytest.mark.parametrize("label", BINARY)
def test_missing_column(tmp_path, runs, label):
    path = one_run(tmp_path, runs, label, lambda c: c.pop("theta_ref_deg") is None)
    refused(lambda: read(path), str(path), "required column 'theta_ref_deg' is missing")


@pytest.mark.parametrize("label", BINARY)
def test_mismatched_lengths(tmp_path, runs, label):
    if label == "parquet":
        pytest.skip("a Parquet table has one length by construction")  # pyarrow refuses to write it

    def edit(c):
        c["theta_deg"] = c["theta_deg"][:-7]
    path = one_run(tmp_path, runs, label, edit)
    refused(lambda: read(path), str(path), "columns differ in length", "one value per sample")


@pytest.mark.parametrize("label", ["mat5", "hdf5"])
def test_two_dimensional_column(tmp_path, runs, label):
    def edit(c):
        c["theta_deg"] = np.column_stack([c["theta_deg"]] * 3)
    path = one_run(tmp_path, runs, label, edit)
    refused(lambda: read(path), str(path), "column 'theta_deg'", "a 1-D sequence", "shape")


@pytest.mark.parametrize("label", BINARY)
def test_infinite_value(tmp_path, runs, label):
    def edit(c):
        c["current_mA"][17] = np.inf
    path = one_run(tmp_path, runs, label, edit)
    refused(lambda: read(path), str(path), "column 'current_mA', sample 17", "not finite", "missing sample is NaN")


@pytest.mark.parametrize("label", BINARY)
def test_nan_is_a_missing_sample_as_an_empty_cell_is(tmp_path, runs, label):
    def edit(c):
        c["p_a_bar"][40:43] = np.nan
    path = one_run(tmp_path, runs, label, edit)
    assert read(path).runs[0].interpolated == {"p_a_bar": 3}

    def edit_long(c):
        c["p_a_bar"][40:50] = np.nan
    path = one_run(tmp_path / "long", runs, label, edit_long)
    refused(lambda: read(path), str(path), "column 'p_a_bar': 10 missing samples in a row (sample 40 to 49)")


@pytest.mark.parametrize("label", ["mat5", "tdms", "hdf5", "parquet"])
def test_text_where_a_number_belongs(tmp_path, runs, label):
    def edit(c):
        c["current_mA"] = np.array([f"{v:.3f}" for v in c["current_mA"]])
    path = one_run(tmp_path, runs, label, edit)
    refused(lambda: read(path), str(path), "column 'current_mA': expected one number in mA per sample", "text")


@pytest.mark.parametrize("label", BINARY)
def test_units_checked_by_value(tmp_path, runs, label):
    """The same size checks as CSV: theta logged in rad."""
    def edit(c):
        c["theta_deg"] = np.radians(c["theta_deg"])
        c["theta_ref_deg"] = c["theta_ref_deg"]
    path = one_run(tmp_path, runs, label, edit)
    refused(lambda: read(path), str(path), "column 'theta_deg'", "rad, not deg")


@pytest.mark.parametrize("label", BINARY)
def test_unknown_columns_are_ignored_and_reported(tmp_path, runs, label):
    def edit(c):
        c["oil_temp_C"] = np.full(c["t"].size, 41.5)
    path = one_run(tmp_path, runs, label, edit)
    camp = read(path)
    assert camp.runs[0].ignored_columns == ["oil_temp_C"]
    assert any(path.name in w and "oil_temp_C" in w for w in camp.warnings)


@pytest.mark.parametrize("label", BINARY)
def test_a_format_quantity_in_another_unit_is_refused(tmp_path, runs, label):
    def edit(c):
        c["p_a_psi"] = c.pop("p_a_bar") * 14.5
    path = one_run(tmp_path, runs, label, edit)
    refused(lambda: read(path), str(path), "column 'p_a_psi' has unit 'psi'")


@pytest.mark.parametrize("label", ["tdms", "hdf5"])
def test_a_unit_the_file_states_must_be_the_formats(tmp_path, runs, label):
    name, cols, meta = runs[0]
    folder = tmp_path / "camp"
    folder.mkdir()
    path = folder / f"{name}{WRITERS[label][0]}"
    units = {**UNITS, "p_a_bar": "psi"}
    (tdms if label == "tdms" else hdf5)(path, cols, units=units)
    (folder / f"{name}.json").write_text(json.dumps(meta))
    refused(lambda: read(path), str(path), "column 'p_a_bar'", "'psi'", "expected bar")
    units = {**UNITS, "flow_lpm": "L/min", "theta_deg": "Degrees"}  # other spellings of the same units
    (tdms if label == "tdms" else hdf5)(path, cols, units=units)
    assert read(path).runs[0].n == cols["t"].size


def test_two_data_files_for_one_run(tmp_path, runs):
    path = one_run(tmp_path, runs, "csv")
    name, cols, meta = runs[0]
    mat5(path.with_suffix(".mat"), cols)
    refused(lambda: read(path), f"run '{name}' has two data files, {name}.csv and {name}.mat", "keep one")


def test_missing_sidecar_names_the_data_file(tmp_path, runs):
    path = one_run(tmp_path, runs, "tdms")
    path.with_suffix(".json").unlink()
    refused(lambda: read(path), str(path), f"sidecar {path.stem}.json is missing")


def test_a_tdms_index_belongs_to_its_file(tmp_path, runs):
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    name, cols, meta = runs[0]
    path = tmp_path / "camp" / f"{name}.tdms"
    path.parent.mkdir()
    with TdmsWriter(str(path), index_file=True) as w:  # as NI software writes: RUN.tdms and RUN.tdms_index
        w.write_segment([GroupObject("g")] + [ChannelObject("g", c, v) for c, v in cols.items()])
    path.with_suffix(".json").write_text(json.dumps(meta))
    assert path.with_suffix(".tdms_index").is_file()
    camp = read(path)
    assert camp.warnings == [] and camp.runs[0].path == path


def test_a_missing_library_is_one_line_naming_it(tmp_path, runs, monkeypatch):
    path = one_run(tmp_path, runs, "tdms")
    monkeypatch.setitem(sys.modules, "nptdms", None)  # as if npTDMS were not installed
    refused(lambda: read(path), str(path), "needs the Python package npTDMS", "pip install npTDMS")


def test_unknown_suffix_and_identify_on_a_folder(tmp_path):
    from ehas_env.identification.fit import read_columns

    with pytest.raises(formats.RunFileError, match=r"'\.xlsx' is not a run file format; expected one of \.csv"):
        read_columns(tmp_path / "run.xlsx")
    (tmp_path / "run.tdms").mkdir()
    with pytest.raises(ValueError, match=r"run\.tdms: is a folder; expected a TDMS run file"):
        read_columns(tmp_path / "run.tdms")
    with pytest.raises(FileNotFoundError, match=r"gone\.h5: does not exist"):
        read_columns(tmp_path / "gone.h5")


# -- MATLAB: objects, function handles, structs, cells -----------------------------------------------------

@pytest.mark.parametrize("fname, what", [
    ("testfunc_7.4_GLNX86.mat", "variable 'testfunc' is a function handle"),
    ("testobject_7.4_GLNX86.mat", "variable 'testobject' is a MATLAB object"),
    ("some_functions.mat", "is a function handle"),
    ("teststruct_7.4_GLNX86.mat", "variable 'teststruct' is a struct"),
    ("testcell_7.4_GLNX86.mat", "variable 'testcell' is a cell array"),
])
def test_matlab_objects_are_refused_unread(tmp_path, monkeypatch, fname, what):
    """MATLAB's own files: refused from the variable listing, before loadmat touches a variable."""
    import scipy.io

    path = tmp_path / "camp" / "run.mat"
    path.parent.mkdir()
    shutil.copy(MATLAB / fname, path)
    path.with_suffix(".json").write_text(json.dumps({"kind": "valve_open_loop", "supply_bar": 70}))
    loaded = []
    monkeypatch.setattr(scipy.io, "loadmat", lambda *a, **k: loaded.append(a) or {})
    refused(lambda: read(path), str(path), what, "only numeric vectors")
    assert loaded == []


def test_matlab_v73_struct_cell_and_object_are_refused(tmp_path, runs):
    import h5py
    import hdf5storage

    name, cols, meta = runs[0]
    base = {c: np.asarray(v).reshape(-1, 1) for c, v in cols.items()}
    cases = {
        "struct": ({**base, "info": {"operator": np.array([1.0])}}, "variable 'info' is a struct"),
        "cell": ({**base, "notes": np.array([np.array([1.0]), np.array([2.0, 3.0])], dtype=object)}, "cell array"),
    }
    for case, (mdict, what) in cases.items():
        path = tmp_path / case / f"{name}.mat"
        path.parent.mkdir()
        hdf5storage.savemat(str(path), mdict, format="7.3")
        path.with_suffix(".json").write_text(json.dumps(meta))
        refused(lambda: read(path), str(path), what)
    # a MATLAB object as MATLAB 7.3 stores one: a uint32 reference into #subsystem#, MATLAB_object_decode set
    path = tmp_path / "object" / f"{name}.mat"
    path.parent.mkdir()
    hdf5storage.savemat(str(path), base, format="7.3")
    with h5py.File(path, "a") as f:
        ds = f.create_dataset("tbl", data=np.array([[3707764736, 2, 1, 1, 1, 1]], dtype=np.uint32))
        ds.attrs["MATLAB_class"] = np.bytes_(b"table")
        ds.attrs["MATLAB_object_decode"] = np.int32(3)
    path.with_suffix(".json").write_text(json.dumps(meta))
    refused(lambda: read(path), str(path), "variable 'tbl' is a MATLAB object")


def test_an_hdf5_file_named_mat_is_not_matlab(tmp_path, runs):
    name, cols, meta = runs[0]
    path = tmp_path / "camp" / f"{name}.mat"
    path.parent.mkdir()
    hdf5(path, cols)
    path.with_suffix(".json").write_text(json.dumps(meta))
    refused(lambda: read(path), str(path), "no MATLAB_class attribute", "name it .h5")


def test_matlab_char_and_logical_columns_are_named(tmp_path, runs):
    import scipy.io

    name, cols, meta = runs[0]
    path = tmp_path / "camp" / f"{name}.mat"
    path.parent.mkdir()
    scipy.io.savemat(str(path), {**{c: v.reshape(-1, 1) for c, v in cols.items()},
                                 "current_mA": np.array(["x" * cols["t"].size])})
    path.with_suffix(".json").write_text(json.dumps(meta))
    refused(lambda: read(path), str(path), "column 'current_mA'", "text")
    scipy.io.savemat(str(path), {**{c: v.reshape(-1, 1) for c, v in cols.items()},
                                 "current_mA": cols["current_mA"].reshape(-1, 1) > 0})
    refused(lambda: read(path), str(path), "column 'current_mA'", "true/false")


# -- HDF5: plug-in filters, links, groups ------------------------------------------------------------------

def test_hdf5_plugin_filter_is_refused_before_reading(tmp_path, runs, monkeypatch):
    """A dataset whose pipeline names a filter plug-in (Blosc, 32001) is refused without reading its data,
    so the HDF5 library never looks for the plug-in's shared library."""
    import h5py

    name, cols, meta = runs[0]
    path = tmp_path / "camp" / f"{name}.h5"
    path.parent.mkdir()
    hdf5(path, {c: v for c, v in cols.items() if c != "theta_deg"})
    with h5py.File(path, "a") as f:
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_chunk((100,))
        dcpl.set_filter(32001, h5py.h5z.FLAG_OPTIONAL, (2, 2, 8, 800))  # optional: written unfiltered here
        space = h5py.h5s.create_simple((cols["t"].size,))
        dsid = h5py.h5d.create(f.id, b"theta_deg", h5py.h5t.IEEE_F64LE, space, dcpl=dcpl)
        dsid.write(h5py.h5s.ALL, h5py.h5s.ALL, np.ascontiguousarray(cols["theta_deg"]))
    path.with_suffix(".json").write_text(json.dumps(meta))
    read_data = []
    real = h5py.Dataset.__getitem__
    monkeypatch.setattr(h5py.Dataset, "__getitem__", lambda self, key: read_data.append(self.name) or real(self, key))
    monkeypatch.setenv("HDF5_PLUGIN_PATH", str(tmp_path / "no_plugins_here"))
    refused(lambda: read(path), str(path), "dataset 'theta_deg' is compressed with filter 32001", "plug-in",
            "built-in one")
    assert "/theta_deg" not in read_data


def test_hdf5_links_to_other_files_are_refused(tmp_path, runs):
    import h5py

    name, cols, meta = runs[0]
    other = tmp_path / "other.h5"
    hdf5(other, {"theta_deg": cols["theta_deg"]})
    path = tmp_path / "camp" / f"{name}.h5"
    path.parent.mkdir()
    hdf5(path, {c: v for c, v in cols.items() if c != "theta_deg"})
    with h5py.File(path, "a") as f:
        f["theta_deg"] = h5py.ExternalLink(str(other), "/theta_deg")
    path.with_suffix(".json").write_text(json.dumps(meta))
    refused(lambda: read(path), str(path), "'theta_deg' is an external link (to another file)")


def test_hdf5_columns_in_a_group(tmp_path, runs):
    import h5py

    name, cols, meta = runs[0]
    path = tmp_path / "camp" / f"{name}.h5"
    path.parent.mkdir()
    with h5py.File(path, "w") as f:
        g = f.create_group("rig1")
        for c, v in cols.items():
            g[c] = v
    path.with_suffix(".json").write_text(json.dumps(meta))
    refused(lambda: read(path), str(path), "no datasets at the root", "rig1", "--columns group=NAME")
    assert read_campaign(path.parent, columns={"group": "rig1"}).runs[0].n == cols["t"].size
    refused(lambda: read_campaign(path.parent, columns={"group": "rig2"}), str(path), "no group 'rig2'", "rig1")


def test_tdms_without_channels_or_groups(tmp_path, runs):
    from nptdms import GroupObject, TdmsWriter

    name, cols, meta = runs[0]
    path = tmp_path / "camp" / f"{name}.tdms"
    path.parent.mkdir()
    with TdmsWriter(str(path)) as w:
        w.write_segment([GroupObject("empty")])
    path.with_suffix(".json").write_text(json.dumps(meta))
    refused(lambda: read(path), str(path), "group 'empty' has no channels")


@pytest.mark.parametrize("label", BINARY)
def test_the_command_line_prints_one_line(tmp_path, runs, label, capfd):
    """``ehas compare`` on a damaged file: status 2 and one line on stderr (no library's own warnings)."""
    from ehas_env.cli.main import main

    path = one_run(tmp_path, runs, label)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    assert main(["compare", str(path.parent)]) == 2
    out, err = capfd.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("ehas compare: error:") and path.name in lines[0], err
