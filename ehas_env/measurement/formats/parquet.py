"""Apache Parquet run files (``.parquet``), read with pyarrow (the ``parquet`` extra: ``pip install 'ehas[parquet]'``).

Plain layout: one numeric column per format column, named as the CSV header;
a column's field metadata ``unit`` or ``units``, when present, must name the
format's unit.  Only the columns asked for are read.  Parquet holds plain typed
columns: reading one (``pyarrow.parquet.read_table``, never ``to_pandas``)
rebuilds no Python object.
"""
from __future__ import annotations

from pathlib import Path

from ehas_env.measurement.formats import RunFormat, Table, check_size, register

LAYOUT = "a Parquet file with one numeric column per format column, named as the CSV header (t, current_mA, ...)"


def read(path: Path, keep, group=None) -> Table:
    """The columns ``keep`` chooses of a Parquet file (see the module docstring)."""
    import pyarrow.parquet as pq

    meta = pq.read_metadata(str(path))
    schema = meta.schema.to_arrow_schema()
    names = list(schema.names)
    wanted = list(keep(list(names)))
    for name in wanted:
        check_size(path, name, (meta.num_rows,))
    table = pq.read_table(str(path), columns=wanted)
    cols, units = {}, {}
    for name in wanted:
        col = table.column(name)
        cols[name] = col.to_numpy(zero_copy_only=False)
        fmeta = schema.field(name).metadata or {}
        for key in (b"unit", b"units"):
            if key in fmeta:
                units[name] = fmeta[key].decode(errors="replace")
    return Table(columns=cols, names=names, units=units)


def write(path: Path, columns: dict, units: dict) -> None:
    """``columns`` as a Parquet file, one float64 column each with its ``unit`` field metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    fields = [pa.field(name, pa.float64(), metadata={"unit": units[name]} if name in units else None)
              for name in columns]
    pq.write_table(pa.table(list(columns.values()), schema=pa.schema(fields)), str(path))


FORMAT = register(RunFormat(name="Parquet", suffixes=(".parquet",), read=read, write=write, layout=LAYOUT,
                            needs=(("pyarrow.parquet", "pyarrow"),)))
