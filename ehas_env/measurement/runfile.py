"""Writing one run in the measurement format: a data file and its JSON sidecar.

The format is the project's measurement contract (README, "Measurement files"):
``RUN.csv`` (or ``RUN.mat``, ``RUN.tdms``, ``RUN.h5``, ``RUN.parquet``: the
formats of :mod:`ehas_env.measurement.formats`) with one column per signal and
one row per sample, and ``RUN.json`` saying what the run was.  Reading and
validating campaigns lives in ``ehas_env.measurement.campaign``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ehas_env.measurement import formats
from ehas_env.output.files import atomic_write_text


def write_run(stem, columns: dict[str, np.ndarray], meta: dict, fmt: str = "csv") -> tuple[Path, Path]:
    """Write the data file and ``stem.json`` atomically; return their paths.

    Parameters
    ----------
    stem : path
        The run's path without suffix (a data file's or ``.json`` suffix is dropped).
    columns : dict
        Column names of the format -> equal-length arrays; NaN is a missing
        sample (an empty cell in CSV).
    meta : dict
        The sidecar.
    fmt : str
        The data file's format, by name or suffix (``csv``, ``mat``, ``tdms``,
        ``hdf5``, ``parquet``).

    Returns
    -------
    data_path, json_path : Path
    """
    stem = Path(stem)
    if stem.suffix.lower() in (*formats.data_suffixes(), ".json"):
        stem = stem.with_suffix("")
    data_format = formats.by_name(fmt)
    data_path = formats.write_file(stem.with_suffix(data_format.suffixes[0]), columns, fmt=data_format)
    json_path = atomic_write_text(stem.with_suffix(".json"), json.dumps(meta, indent=2, sort_keys=False) + "\n")
    return data_path, json_path


def write_result(result, stem, notes: str = "", fmt: str = "csv") -> tuple[Path, Path]:
    """Write a simulated run (a :class:`~ehas_env.simulation.plant.Plant`'s result) in the measurement format.

    The logged channels are written (what a rig's DAQ would record) with the run's sidecar.

    Parameters
    ----------
    result : SimResult or ValveTestResult
        A run of :meth:`Plant.simulate_closed_loop`, ``simulate_open_loop`` or the valve bench.
    stem : path
        The run's path without suffix.
    notes : str
        Free text stored as the sidecar's ``notes``.
    fmt : str
        The data file's format (see :func:`write_run`).

    Returns
    -------
    data_path, json_path : Path

    Examples
    --------
    >>> import tempfile
    >>> from ehas_env.simulation.plant import Plant
    >>> run = Plant().simulate_valve_test([0.5] * 100)
    >>> work = tempfile.TemporaryDirectory()
    >>> data, side = write_result(run, work.name + "/step", notes="a step")
    >>> data.suffix, side.suffix
    ('.csv', '.json')
    >>> work.cleanup()
    """
    meta = dict(result.meta)
    if notes:
        meta["notes"] = notes
    return write_run(stem, result.columns(logged=True), meta, fmt=fmt)
