"""HDF5 run files (``.h5``, ``.hdf5``), read with h5py.

Plain layout: one 1-D dataset per column at the file's root, named as the CSV
header (``/t``, ``/current_mA``, ...); a ``units`` (or ``unit``) attribute on a
dataset, when present, must name the format's unit.  A file whose columns sit in
a group is read with ``--columns group=NAME`` (``read_campaign(...,
columns={"group": "NAME"})``).  Datasets that are not columns of the format are
ignored and reported; subgroups are skipped.

Nothing in the file is run or followed elsewhere: a dataset compressed with a
filter that is not built into HDF5 or h5py (a plug-in, which the HDF5 library
would load as a shared library from ``HDF5_PLUGIN_PATH``) is refused before
any of its data is read, and so are external and soft links, virtual datasets
and datasets stored in external files.
"""
from __future__ import annotations

from pathlib import Path

from ehas_env.measurement.formats import RunFileError, RunFormat, Table, check_size, register

LAYOUT = ("an HDF5 file with one 1-D dataset per column at its root, named as the CSV header (/t, /current_mA, ...), "
          "or in the group named by --columns group=NAME")
#: filters compiled into the HDF5 library or into h5py itself (no plug-in is loaded for them)
BUILTIN_FILTERS = {1: "deflate (gzip)", 2: "shuffle", 3: "fletcher32", 4: "szip", 5: "nbit", 6: "scaleoffset",
                   32000: "lzf"}


def check_dataset(path: Path, name: str, ds) -> None:
    """Refuse a dataset whose reading would load a filter plug-in or read another file (before reading it)."""
    if ds.is_virtual:
        raise RunFileError(f"{path}: dataset '{name}' is a virtual dataset (its data lives in other files); expected "
                           "the samples in the file itself")
    dcpl = ds.id.get_create_plist()
    if dcpl.get_external_count():
        raise RunFileError(f"{path}: dataset '{name}' keeps its data in an external file; expected the samples in the "
                           "file itself")
    for k in range(dcpl.get_nfilters()):
        code, _, _, label = dcpl.get_filter(k)
        if code not in BUILTIN_FILTERS:
            label = label.decode(errors="replace") if isinstance(label, bytes) else str(label)
            raise RunFileError(f"{path}: dataset '{name}' is compressed with filter {code} ({label or 'unnamed'}), an "
                               f"HDF5 plug-in, which ehas does not load; expected no filter or a built-in one "
                               f"({', '.join(BUILTIN_FILTERS.values())}): rewrite the file with gzip compression")
    check_size(path, name, ds.shape)


def _unit(ds) -> str | None:
    for key in ("units", "unit", "Unit", "Units"):
        if key in ds.attrs:
            v = ds.attrs[key]
            if hasattr(v, "tolist"):
                v = v.tolist()
            if isinstance(v, list) and len(v) == 1:
                v = v[0]
            return v.decode(errors="replace") if isinstance(v, bytes) else str(v)
    return None


def read(path: Path, keep, group=None) -> Table:
    """The columns ``keep`` chooses of an HDF5 file (see the module docstring)."""
    import h5py

    with h5py.File(path, "r") as f:
        where = f
        if group is not None:
            link = f.get(group, getlink=True)
            if link is None or not isinstance(f.get(group), h5py.Group):
                groups = [k for k in f if isinstance(f.get(k, getlink=True), h5py.HardLink)
                          and isinstance(f[k], h5py.Group)]
                raise RunFileError(f"{path}: no group '{group}' (--columns group={group}); the file's groups: "
                                   f"{', '.join(groups) or 'none (the columns are at the root: drop group=)'}")
            where = f[group]
        datasets, units = {}, {}
        for name in where:
            link = where.get(name, getlink=True)
            if not isinstance(link, h5py.HardLink):
                kind = "an external link (to another file)" if isinstance(link, h5py.ExternalLink) else "a link"
                raise RunFileError(f"{path}: '{name}' is {kind}; expected {LAYOUT}")
            obj = where[name]
            if isinstance(obj, h5py.Dataset):
                datasets[name] = obj
                u = _unit(obj)
                if u is not None:
                    units[name] = u
        if not datasets:
            groups = [k for k in where if isinstance(where[k], h5py.Group)]
            hint = (f"; its groups: {', '.join(groups)} (--columns group=NAME reads one)" if groups
                    else " (an empty file)")
            raise RunFileError(f"{path}: no datasets at {'the root' if group is None else group}{hint}; expected "
                               f"{LAYOUT}")
        names = list(datasets)
        wanted = list(keep(list(names)))
        cols = {}
        for name in wanted:
            check_dataset(path, name, datasets[name])
            cols[name] = datasets[name][()]
    return Table(columns=cols, names=names, units={k: v for k, v in units.items() if k in cols})


def write(path: Path, columns: dict, units: dict) -> None:
    """``columns`` as an HDF5 file: one gzip-compressed dataset per column at the root, with a ``units`` attribute."""
    import h5py

    with h5py.File(path, "w") as f:
        for name, values in columns.items():
            ds = f.create_dataset(name, data=values, compression="gzip")
            if name in units:
                ds.attrs["units"] = units[name]


FORMAT = register(RunFormat(name="HDF5", suffixes=(".h5", ".hdf5", ".he5"), read=read, write=write, layout=LAYOUT,
                            needs=(("h5py", "h5py"),)))
