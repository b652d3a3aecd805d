"""``ehas export-controller CONTROLLER.json --format c --out DIR``: a controller as C for the rig's controller.

Writes ``DIR/<name>.h`` and ``DIR/<name>.c`` (C99, fixed step, no allocation); the C is made by
:mod:`ehas_controllers.export_c` (what each controller type exports, what stays in ehas); docs/export.md.
The two files are members of the shared folder DIR, swapped in together (an earlier pair is replaced only
with ``--overwrite``; other files in DIR stay).
"""
from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("controller", metavar="CONTROLLER.json",
                        help="a controller JSON: piff, schedule, ilc or harmonic (with what it learned), drive")
    parser.add_argument("--format", choices=("c",), default="c", help="output language (c: one .h and one .c)")
    parser.add_argument("--out", required=True, metavar="DIR", help="folder for NAME.h and NAME.c")
    parser.add_argument("--name", default=None,
                        help="C name of the controller (files NAME.h/NAME.c, functions NAME_init/NAME_step); "
                             "default: the controller's name")
    parser.add_argument("--overwrite", action="store_true", help="replace NAME.h and NAME.c of an earlier export")


def run(args) -> int:
    import shlex

    from ehas_controllers.base import load_controller
    from ehas_controllers.export_c import c_identifier, write_controller_c
    from ehas_env.output.outputs import OutputSet

    if args.name is not None and not str(args.name).strip():
        raise ValueError("--name: empty; give a C name such as rig_piff")
    ctrl = load_controller(args.controller)
    if getattr(ctrl, "source", None) is None:
        ctrl.source = args.controller  # the file its refusals name (an agent folder's loader sets none)
    cname = c_identifier(args.name if args.name is not None else ctrl.name)
    parts = ["ehas", "export-controller", args.controller, "--format", args.format, "--out", args.out]
    if args.name:
        parts += ["--name", args.name]
    out = OutputSet(args.out, "--out", overwrite=args.overwrite, members=(f"{cname}.h", f"{cname}.c"))
    with out as tmp:
        write_controller_c(ctrl, tmp, cname, command=shlex.join(parts))
    print(f"wrote {args.out}/{cname}.h and {args.out}/{cname}.c ({type(ctrl).__name__} '{ctrl.name}'; "
          f"{cname}_init then {cname}_step once per period; docs/export.md)")
    return 0
