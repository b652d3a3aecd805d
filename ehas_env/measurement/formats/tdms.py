"""NI TDMS run files (``.tdms``, as LabVIEW and NI DAQ software log), read with npTDMS.

Plain layout: one group whose channels are the columns, named as the CSV
header (``t``, ``current_mA``, ...).  A channel's ``unit_string`` property, when
present, must name the format's unit.  A file with several groups is refused
unless ``--columns group=NAME`` (``read_campaign(..., columns={"group": "NAME"})``)
names the one to read.  Without a ``t`` channel, a group of waveform channels
(NI's ``wf_increment`` and ``wf_start_offset`` properties, equal on every
channel) gives ``t`` from them, in s.  A ``RUN.tdms_index`` beside the file
belongs to it and is skipped.

The file is read with ``TdmsFile.open`` (only the channels asked for are
loaded); npTDMS parses the binary layout and runs nothing from the file.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ehas_env.measurement.formats import RunFileError, RunFormat, Table, check_size, register

LAYOUT = ("a TDMS file with one group whose channels are the columns, named as the CSV header (t, current_mA, ...), "
          "or several groups and --columns group=NAME")


def _waveform_time(channels) -> tuple[float, float] | None:
    """(start, increment) shared by every channel of a waveform group, None if they are not waveforms."""
    props = [(c.properties.get("wf_start_offset", 0.0), c.properties.get("wf_increment")) for c in channels]
    if not props or any(inc is None for _, inc in props) or len(set(props)) != 1:
        return None
    start, inc = props[0]
    return float(start), float(inc)


class _Warnings(logging.Filter):
    """npTDMS's warnings on a damaged file (it logs them and reads on): kept from the console, then refused."""

    def __init__(self):
        super().__init__()
        self.messages: list[str] = []

    def filter(self, record):
        if record.levelno >= logging.WARNING:
            self.messages.append(record.getMessage())
        return False


def read(path: Path, keep, group=None) -> Table:
    """The columns ``keep`` chooses of a TDMS file (see the module docstring)."""
    with open(path, "rb") as fh:
        if fh.read(4) != b"TDSm":
            raise RunFileError(f"{path}: not a TDMS file (it does not start with a TDMS segment, 'TDSm'); "
                               f"expected {LAYOUT}")
    import nptdms  # noqa: F401  (its modules' loggers exist once it is imported)

    catch = _Warnings()
    loggers = [logging.getLogger(name) for name in list(logging.root.manager.loggerDict)
               if name == "nptdms" or name.startswith("nptdms.")]
    for log in loggers:
        log.addFilter(catch)
    try:
        table = _read(path, keep, group)
    finally:
        for log in loggers:
            log.removeFilter(catch)
    if catch.messages:
        raise RunFileError(f"{path}: not a readable TDMS file ({catch.messages[0]}: cut short or damaged); "
                           f"expected {LAYOUT}")
    return table


def _read(path: Path, keep, group) -> Table:
    from nptdms import TdmsFile

    with TdmsFile.open(str(path)) as f:
        groups = f.groups()
        names = [g.name for g in groups]
        if group is not None:
            if group not in names:
                raise RunFileError(f"{path}: no group '{group}' (--columns group={group}); the file's groups: "
                                   f"{', '.join(names) or 'none'}")
            chosen = f[group]
        elif len(groups) == 1:
            chosen = groups[0]
        elif not groups:
            raise RunFileError(f"{path}: no groups, so no channels; expected {LAYOUT}")
        else:
            raise RunFileError(f"{path}: {len(groups)} groups ({', '.join(names)}); expected one group whose channels "
                               f"are the columns, or --columns group=NAME to say which to read")
        channels = {c.name: c for c in chosen.channels()}
        if not channels:
            raise RunFileError(f"{path}: group '{chosen.name}' has no channels; expected {LAYOUT}")
        columns = list(channels)
        wave = None if "t" in channels else _waveform_time(channels.values())
        if wave is not None:
            columns.append("t")
        wanted = list(keep(list(columns)))
        cols, units = {}, {}
        for name in wanted:
            if name == "t" and wave is not None:
                n = len(next(iter(channels.values())))
                cols[name] = wave[0] + wave[1] * np.arange(n)
                units[name] = "s"
                continue
            ch = channels[name]
            check_size(path, name, (len(ch),))
            cols[name] = ch[:]
            unit = ch.properties.get("unit_string")
            if unit not in (None, ""):
                units[name] = str(unit)
    return Table(columns=cols, names=columns, units=units)


def write(path: Path, columns: dict, units: dict) -> None:
    """``columns`` as a TDMS file: one group ``run`` with one float64 channel per column and its ``unit_string``."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    with TdmsWriter(str(path)) as w:
        objs = [GroupObject("run")]
        for name, values in columns.items():
            props = {"unit_string": units[name]} if name in units else {}
            objs.append(ChannelObject("run", name, np.asarray(values, dtype=np.float64), properties=props))
        w.write_segment(objs)


FORMAT = register(RunFormat(name="TDMS", suffixes=(".tdms",), read=read, write=write, layout=LAYOUT,
                            companions=(".tdms_index",), needs=(("nptdms", "npTDMS"),)))
