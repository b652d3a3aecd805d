"""MATLAB ``.mat`` run files, version 5 (``save``'s default up to R2006) and 7.3 (HDF5-based, ``save -v7.3``).

Plain layout: one numeric vector variable per column, named as the CSV header
(``t``, ``current_mA``, ...), as ``save('run.mat', 't', 'current_mA', ...)``
writes from a workspace of column vectors.  Variables that are not columns of
the format (a ``notes`` char array, a gain) are ignored and reported.

Nothing in the file is run: version 5 files are listed with
``scipy.io.whosmat`` first and refused when they hold a MATLAB object, a
function handle, a struct, a cell array, a sparse matrix or an opaque class
(scipy never unpickles, but these are not columns and a reader should not
touch them); only the numeric variables asked for are then loaded.  Version
7.3 files are read with h5py as HDF5 (not through hdf5storage or mat73, which
may rebuild Python objects): each variable's ``MATLAB_class`` attribute must
be a numeric class, an object (``MATLAB_object_decode``), a struct, a cell or a
reference refuses the file, and filters other than HDF5's built-in ones
(MATLAB compresses with deflate) are refused before any data is read.  MATLAB
stores arrays transposed in a 7.3 file; a vector is a vector either way.
"""
from __future__ import annotations

from pathlib import Path

from ehas_env.measurement.formats import COLUMNS, RunFileError, RunFormat, Table, check_size, register

LAYOUT = ("a MATLAB .mat file (v5 or v7.3) with one numeric vector variable per column, named as the CSV header "
          "(t, current_mA, ...)")
#: MATLAB classes a column may be (logical and char are listed so that a column of them is named, then refused)
NUMERIC = {"double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"}
HARMLESS = NUMERIC | {"char", "logical"}
#: what each refused class is, for the one-line refusal
REFUSED = {"function": "a function handle", "function_handle": "a function handle", "object": "a MATLAB object",
           "opaque": "a MATLAB object (opaque class)", "struct": "a struct", "cell": "a cell array",
           "sparse": "a sparse matrix"}
HDF5 = b"\x89HDF\r\n\x1a\n"  # the HDF5 format signature


def _refuse(path: Path, var: str, cls: str):
    what = REFUSED.get(cls, f"a variable of class '{cls}'")
    raise RunFileError(f"{path}: variable '{var}' is {what}; a run MAT file holds only numeric vectors, one per "
                       "column (save('run.mat', 't', 'current_mA', ...)); nothing else is read")


def _numeric(path: Path, name: str, cls: str) -> None:
    """A column of class char or logical is named and refused (scipy would load a logical as numbers)."""
    if cls not in NUMERIC:
        what = "text (a char array)" if cls == "char" else "true/false values (a logical array)"
        unit = COLUMNS.get(name)
        raise RunFileError(f"{path}, column '{name}': expected one number{' in ' + unit if unit else ''} per "
                           f"sample, got {what}")


def read(path: Path, keep, group=None) -> Table:
    """The columns ``keep`` chooses of a MAT file (see the module docstring)."""
    with open(path, "rb") as fh:
        head = fh.read(520)
    # version 0x0200 in the 128-byte header, and the HDF5 signature after the 512-byte userblock (or a bare HDF5 file)
    if head[124:128] in (b"\x00\x02IM", b"\x02\x00MI") or HDF5 in (head[:8], head[512:520]):
        return _read_v73(path, keep)
    if not head.startswith(b"MATLAB 5.0 MAT-file") and head[126:128] not in (b"IM", b"MI"):
        raise RunFileError(f"{path}: not a MAT file (no MATLAB 5.0 or 7.3 header); expected {LAYOUT}")
    return _read_v5(path, keep)


def _read_v5(path: Path, keep) -> Table:
    import scipy.io

    try:
        listing = scipy.io.whosmat(str(path))
    except NotImplementedError as exc:  # scipy's "please use HDF reader" for a v7.3 file without the header text
        raise RunFileError(f"{path}: not a MAT file of version 5 or 7.3 ({exc}); expected {LAYOUT}") from None
    if not listing:
        raise RunFileError(f"{path}: no variables; expected {LAYOUT}")
    for name, shape, cls in listing:
        if cls not in HARMLESS:
            _refuse(path, name, cls)
    names = [name for name, _, _ in listing]
    wanted = list(keep(names))
    for name, shape, cls in listing:
        if name in wanted:
            _numeric(path, name, cls)
            check_size(path, name, shape)
    data = scipy.io.loadmat(str(path), variable_names=wanted, squeeze_me=False, struct_as_record=True,
                            chars_as_strings=False, mat_dtype=False) if wanted else {}
    return Table(columns={name: data[name] for name in wanted}, names=names)


def _read_v73(path: Path, keep) -> Table:
    try:
        import h5py
    except ImportError:
        raise RunFileError(f"{path}: a MAT file of version 7.3 (HDF5) needs the Python package h5py: pip install h5py") \
            from None

    from ehas_env.measurement.formats.hdf5 import check_dataset

    with h5py.File(path, "r") as f:
        names, kinds, kinds_cls = [], {}, {}
        for name in f:
            if name in ("#refs#", "#subsystem#"):
                # MATLAB's store for the contents of cells, structs and objects: a plain run has none
                _refuse(path, name, "object" if name == "#subsystem#" else "cell")
            link = f.get(name, getlink=True)
            if not isinstance(link, h5py.HardLink):
                raise RunFileError(f"{path}: variable '{name}' is a link to elsewhere; expected {LAYOUT}")
            obj = f[name]
            cls = obj.attrs.get("MATLAB_class")
            cls = cls.decode() if isinstance(cls, bytes) else str(cls) if cls is not None else None
            if "MATLAB_object_decode" in obj.attrs:
                _refuse(path, name, "object")
            if isinstance(obj, h5py.Group):
                _refuse(path, name, cls or "struct")
            if cls is None:
                raise RunFileError(f"{path}: dataset '{name}' has no MATLAB_class attribute: an HDF5 file, not a "
                                   f"MATLAB v7.3 MAT file (name it .h5); expected {LAYOUT}")
            if cls not in HARMLESS:
                _refuse(path, name, cls)
            names.append(name)
            kinds[name] = obj
            kinds_cls[name] = cls
        wanted = list(keep(list(names)))
        cols = {}
        for name in wanted:
            ds = kinds[name]
            check_dataset(path, name, ds)
            _numeric(path, name, kinds_cls[name])
            if "MATLAB_empty" in ds.attrs and ds.attrs["MATLAB_empty"]:
                cols[name] = []
                continue
            cols[name] = ds[()]
    return Table(columns=cols, names=names)


def write(path: Path, columns: dict, units: dict) -> None:
    """``columns`` as a version 5 MAT file, one column vector variable each (as MATLAB's ``save`` writes)."""
    import numpy as np
    import scipy.io

    scipy.io.savemat(str(path), {c: np.asarray(v, dtype=float).reshape(-1, 1) for c, v in columns.items()},
                     format="5", do_compression=True, oned_as="column")


FORMAT = register(RunFormat(name="MAT", suffixes=(".mat",), read=read, write=write, layout=LAYOUT,
                            needs=(("scipy.io", "scipy"),)))
