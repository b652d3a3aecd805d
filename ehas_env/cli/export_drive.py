"""``ehas export-drive CONTROLLER.json --out DIR``: a learning controller's learned feed-forward as drive files.

For each condition the controller learned (its JSON's ``learned`` records: save the controller after a
run, or take the ``learned_*.json`` the guard long test writes), one CSV of one period of the learned
current (``time_s``, ``current_mA``) and its JSON sidecar (condition, sample rate, units, the base
loop's gains, provenance), and ``DIR/drive.json``: a controller file of type ``drive`` that replays
them on their base loops (``ehas bench DIR/drive.json``).  docs/learning-control.md describes the
format (:mod:`ehas_controllers.drive`).  The files are members of the shared folder DIR (this controller's
drive files and ``drive.json``), swapped in together; other files in DIR, the controller file among them, stay.
"""
from __future__ import annotations

import argparse
import shlex


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("controller", metavar="CONTROLLER.json",
                        help="a learning controller's JSON (ilc, harmonic) holding what it learned ('learned')")
    parser.add_argument("--out", required=True, metavar="DIR", help="folder for the drive files")
    parser.add_argument("--condition", action="append", default=None, metavar="SETS,AMP,FREQ",
                        help="export only this condition: disc sets, amplitude (deg), frequency (Hz), e.g. 7,30,3; "
                             "repeatable (default: every condition learned)")
    parser.add_argument("--overwrite", action="store_true", help="replace the drive files of an earlier export")


def _condition(text: str) -> str:
    from ehas_controllers.learning import condition_key
    from ehas_env.ranges import check_field

    parts = text.split(",")
    if len(parts) != 3:
        raise ValueError(f"--condition {text!r}: expected SETS,AMP,FREQ (disc sets, deg, Hz), e.g. 7,30,3")
    try:
        n, a, f = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"--condition {text!r}: expected three numbers SETS,AMP,FREQ, e.g. 7,30,3") from None
    return condition_key(check_field("disc_sets", n, "--condition disc sets"),
                         check_field("amplitude_deg", a, "--condition amplitude"),
                         check_field("freq_hz", f, "--condition frequency"))


def run(args) -> int:
    from fnmatch import fnmatch
    from pathlib import Path

    from ehas_controllers.base import load_controller
    from ehas_controllers.drive import drive_members, export_drives
    from ehas_env.output.outputs import OutputSet

    # a condition given twice is exported once
    conditions = None if args.condition is None else list(dict.fromkeys(_condition(c) for c in args.condition))
    ctrl = load_controller(args.controller)
    if getattr(ctrl, "source", None) is None:
        ctrl.source = args.controller  # the file its refusals name (an agent folder's loader sets none)
    members = drive_members(ctrl.name)
    src = Path(args.controller).absolute().resolve()
    if src.parent == Path(args.out).absolute().resolve() and any(fnmatch(src.name, m) for m in members):
        raise ValueError(f"--out {args.out}: the drive files would replace the input {args.controller}; write them "
                         "into another folder")
    parts = ["ehas", "export-drive", args.controller, "--out", args.out]
    for c in args.condition or []:
        parts += ["--condition", c]
    out = OutputSet(args.out, "--out", overwrite=args.overwrite, members=members, last=("drive.json",))
    with out as tmp:
        written = export_drives(ctrl, tmp, conditions=conditions, command=shlex.join(parts), out_label=args.out)
    print(f"wrote {len(written) - 1} drive file(s) (CSV + JSON sidecar) and {args.out}/drive.json "
          f"(a controller of type 'drive' that replays them: ehas bench {args.out}/drive.json)")
    return 0
