"""``ehas curves``: valve characteristic curves and the position loop's Bode plot with margins.

    ehas curves [--out results/curves] [--disc-sets 3] [--gains Kp=1,Ki=2] [--effects ...]
                [--valve grey_box|white_box] [--supplies 70,140,220]

Writes into ``--out``: flow against current at several supply pressures, flow
gain against spool stroke for under-, critically and over-lapped spools, the
blocked-port pressure gain, the valve's Bode plot (grey and white box), the
position loop's Bode plot with gain and phase margins for the given
controller, and ``README.md`` with the tables and this command.
"""
from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="results/curves", help="output folder (default results/curves)")
    parser.add_argument("--disc-sets", type=int, default=3, help="disc sets on the crank, 1..7 (default 3)")
    parser.add_argument("--gains", default="", help="controller gains, e.g. 'Kp=1,Ki=2' (default: the book's)")
    parser.add_argument("--effects", default="", help="effects of the plant, e.g. 'viscous_friction:b=2000'")
    parser.add_argument("--valve", choices=("grey_box", "white_box"), default="grey_box",
                        help="valve model of the position loop (default grey_box)")
    parser.add_argument("--supplies", default="70,140,220", help="supply pressures for flow vs current, bar")


def run(args) -> int:
    import math
    import shlex

    from ehas_env.identification.curves import position_loop, write_curves
    from ehas_env.simulation.plant import Plant
    from ehas_env.cli.simulate import parse_gains

    try:
        supplies = tuple(float(v) for v in args.supplies.split(",") if v.strip())
    except ValueError:
        raise ValueError(f"--supplies: expected comma-separated pressures in bar, got {args.supplies!r}") from None
    if not supplies or not all(math.isfinite(p) and p > 0 for p in supplies):
        raise ValueError(f"--supplies: pressures must be positive numbers of bar, got {args.supplies!r}")
    ctrl = parse_gains(args.gains)
    kw = {"valve": args.valve} if args.valve != "grey_box" else {}
    plant = Plant(disc_sets=args.disc_sets, effects=args.effects or None, **kw)
    parts = ["ehas", "curves"]
    for flag, value, default in (("--out", args.out, "results/curves"), ("--disc-sets", str(args.disc_sets), "3"),
                                 ("--gains", args.gains, ""), ("--effects", args.effects, ""),
                                 ("--valve", args.valve, "grey_box"), ("--supplies", args.supplies, "70,140,220")):
        if value != default:
            parts += [flag, value]
    command = " ".join(shlex.quote(p) for p in parts)
    readme = write_curves(args.out, plant=plant, controller=ctrl, supplies_bar=supplies, valve=args.valve,
                          command=command)
    loop = position_loop(plant, ctrl, args.valve)
    print(f"{plant!r}, valve {args.valve}, Kp {ctrl.Kp:g} mA/deg, Ki {ctrl.Ki:g} mA/(deg s)")
    print(f"position loop: gain crossover {loop['crossover_hz']:.2f} Hz, phase margin {loop['phase_margin_deg']:.1f} deg, "
          f"gain margin {loop['gain_margin_db']:.1f} dB at {loop['phase_crossover_hz']:.1f} Hz "
          f"(hydraulic resonance {loop['hydraulic_hz']:.1f} Hz)")
    print(f"wrote {readme} and the figures beside it")
    return 0
