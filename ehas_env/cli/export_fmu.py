"""``ehas export-fmu [MODEL.json] --out rig.fmu``: the rig's model as an FMI 2.0 co-simulation FMU.

The FMU is made by :mod:`ehas_env.simulation.fmu` (C sources translated from the text numba compiles, the FMI
driver, the library compiled here); docs/export.md tells how to use it in other tools.  The ``.fmu`` file is
checked before any work and written atomically when the command succeeds: an earlier file is replaced only with
``--overwrite``, an interrupted or failed export leaves none.
"""
from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ehas_env.ranges import option

    parser.add_argument("model", nargs="?", default=None, metavar="MODEL.json",
                        help="a model file (docs/model-file.md); without one, the book's rig")
    parser.add_argument("--out", required=True, metavar="FILE.fmu", help="the FMU to write")
    parser.add_argument("--controller", default=None, metavar="CONTROLLER.json",
                        help="close the loop in the FMU with this controller's compiled law (piff, schedule, a "
                             "compiled controller of your own); default: the book's PI + feed-forward, open loop "
                             "until the closed_loop parameter is set")
    parser.add_argument("--disc-sets", type=option("--disc-sets", "disc_sets"), default=3,
                        help="disc sets of the FMU's plant, 1..7 (default 3; a parameter of the FMU too)")
    parser.add_argument("--closed-loop", action="store_true",
                        help="start value of the closed_loop parameter: the law tracks the FMU's sine reference")
    parser.add_argument("--no-binary", action="store_true",
                        help="write the sources only (no C compiler here; the importing tool compiles them)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing FILE.fmu")


def run(args) -> int:
    from ehas_env.output.outputs import check_file
    from ehas_env.simulation.fmu import closing_form, step_size, write_fmu

    check_file(args.out, "--out", overwrite=args.overwrite, suffix=".fmu")
    ctrl = None
    if args.controller:
        from ehas_controllers.base import load_controller

        ctrl = load_controller(args.controller)
        closing_form(ctrl, args.disc_sets, f"--controller {args.controller}")  # refused before any work
    files = write_fmu(args.out, args.model, controller=ctrl, disc_sets=args.disc_sets, closed_loop=args.closed_loop,
                      binary=not args.no_binary)
    what = "sources only" if args.no_binary else "sources + binaries/linux64"
    print(f"wrote {args.out} (FMI 2.0 co-simulation, {what}; {len(files)} files; step "
          f"{1e3 * step_size(files):g} ms; docs/export.md)")
    return 0
