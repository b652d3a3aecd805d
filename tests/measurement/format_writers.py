"""Run data files written the way loggers and their users write them, with the libraries they use.

Independent of ehas's own writers (``ehas_env.measurement.formats``): MAT v5
through ``scipy.io.savemat`` (what MATLAB's ``save`` writes: one column-vector
variable each), MAT v7.3 through ``hdf5storage.savemat`` (MATLAB's HDF5 layout,
512-byte userblock, ``MATLAB_class`` attributes; cross-checked with ``mat73``),
TDMS through npTDMS's ``TdmsWriter`` (one group, one channel per column, the
unit in ``unit_string`` as NI software writes it), HDF5 through h5py (one
dataset per column at the root) and Parquet through pyarrow.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

UNITS = {"t": "s", "current_mA": "mA", "theta_deg": "deg", "theta_ref_deg": "deg", "flow_lpm": "LPM",
         "p_a_bar": "bar", "p_b_bar": "bar", "p_s_bar": "bar", "load_kN": "kN"}


def as_logged(runs):
    """The runs with every value rounded to 10 significant digits: what the CSV holds, so every format holds
    exactly the same float64 numbers."""
    out = []
    for name, cols, meta in runs:
        out.append((name, {c: np.array([float(f"{v:.10g}") for v in np.asarray(x, dtype=float)])
                           for c, x in cols.items()}, meta))
    return out


def column(v):
    """A vector as MATLAB's column vector (n x 1); anything else as it is."""
    v = np.asarray(v)
    return v.reshape(-1, 1) if v.ndim == 1 else v


def mat5(path: Path, cols: dict) -> None:
    import scipy.io

    scipy.io.savemat(str(path), {c: column(v) for c, v in cols.items()}, format="5")


def mat73(path: Path, cols: dict) -> None:
    import hdf5storage
    import mat73 as reader

    hdf5storage.savemat(str(path), {c: column(v) for c, v in cols.items()}, format="7.3",
                        oned_as="column")
    back = reader.loadmat(str(path))  # an independent reader sees what was meant
    assert set(back) == set(cols) and all(np.array_equal(np.ravel(back[c]), np.ravel(cols[c]), equal_nan=True)
                                          for c in cols)


def tdms(path: Path, cols: dict, group: str = "Measurements", units: dict | None = None) -> None:
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    units = UNITS if units is None else units
    with TdmsWriter(str(path)) as w:
        w.write_segment([GroupObject(group)] + [
            ChannelObject(group, c, np.asarray(v), properties={"unit_string": units[c]} if c in units else {})
            for c, v in cols.items()])


def hdf5(path: Path, cols: dict, units: dict | None = None) -> None:
    import h5py

    units = UNITS if units is None else units
    with h5py.File(path, "w") as f:
        for c, v in cols.items():
            v = np.asarray(v)
            if v.dtype.kind == "U":  # text as h5py stores it
                v = v.astype(object)
            ds = f.create_dataset(c, data=v, compression="gzip", dtype=h5py.string_dtype() if v.dtype.kind == "O"
                                  else v.dtype)
            if c in units:
                ds.attrs["units"] = units[c]


def parquet(path: Path, cols: dict) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({c: np.asarray(v) for c, v in cols.items()}), str(path))


def csv(path: Path, cols: dict) -> None:
    names = list(cols)
    rows = [",".join(names)] + [",".join("" if not np.isfinite(x) else f"{x:.10g}" for x in row)
                                for row in np.column_stack([cols[c] for c in names])]
    path.write_text("\n".join(rows) + "\n")


#: format label -> (suffix, writer)
WRITERS = {"csv": (".csv", csv), "mat5": (".mat", mat5), "mat73": (".mat", mat73), "tdms": (".tdms", tdms),
           "hdf5": (".h5", hdf5), "parquet": (".parquet", parquet)}


def write_run(folder: Path, name: str, cols: dict, meta: dict, label: str) -> Path:
    suffix, writer = WRITERS[label]
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}{suffix}"
    writer(path, cols)
    (folder / f"{name}.json").write_text(json.dumps(meta))
    return path


def write_campaign_as(folder: Path, runs, labels) -> Path:
    """A campaign folder with run k written in format ``labels[k % len(labels)]`` (one label: all alike)."""
    labels = [labels] if isinstance(labels, str) else list(labels)
    for k, (name, cols, meta) in enumerate(runs):
        write_run(folder, name, cols, meta, labels[k % len(labels)])
    return folder
