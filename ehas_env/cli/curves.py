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
    from ehas_env.ranges import option

    parser.add_argument("--disc-sets", type=option("--disc-sets", "disc_sets"), default=3,
                        help="disc sets on the crank, 1..7 (default 3)")
    parser.add_argument("--gains", default=None, help="controller gains, e.g. 'Kp=1,Ki=2' (default: the book's)")
    parser.add_argument("--effects", default=None, help="effects of the plant, e.g. 'viscous_friction:b=2000'")
    parser.add_argument("--valve", choices=("grey_box", "white_box"), default="grey_box",
                        help="valve model of the position loop (default grey_box)")
    parser.add_argument("--supplies", default="70,140,220", help="supply pressures for flow vs current, bar, (0, 350]")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier --out folder")


def run(args) -> int:
    import shlex

    from ehas_env.identification.curves import position_loop, write_curves
    from ehas_env.simulation.plant import Plant
    from ehas_env.cli.simulate import parse_gains

    from ehas_env.ranges import FIELDS
    from ehas_env.output.outputs import OutputSet

    from ehas_env.ranges import split_list

    items = split_list(args.supplies, "--supplies", "pressures in bar", max_items=20)
    supplies = tuple(FIELDS["supply_bar"].parse(v, "--supplies: each pressure") for v in items)
    model = None
    if getattr(args, "model", None):
        from ehas_env.simulation.model_file import load_model

        model = load_model(args.model)
    ctrl = parse_gains(args.gains) if args.gains or model is None else model.controller()
    outputs = OutputSet(args.out, "--out", overwrite=args.overwrite)
    kw = {"valve": args.valve} if args.valve != "grey_box" else {}
    if model is not None:
        kw["model"] = model
    plant = Plant(disc_sets=args.disc_sets, effects=args.effects or None, **kw)
    parts = ["ehas", "curves"]
    for flag, value, default in (("--out", args.out, "results/curves"), ("--disc-sets", str(args.disc_sets), "3"),
                                 ("--gains", args.gains, None), ("--effects", args.effects, None),
                                 ("--valve", args.valve, "grey_box"), ("--supplies", args.supplies, "70,140,220"),
                                 ("--model", getattr(args, "model", None) or "", "")):
        if value != default:
            parts += [flag, value]
    command = " ".join(shlex.quote(p) for p in parts)
    with outputs as tmp:
        readme = write_curves(tmp, plant=plant, controller=ctrl, supplies_bar=supplies, valve=args.valve,
                              command=command)
    readme = outputs.path / readme.name
    loop = position_loop(plant, ctrl, args.valve)
    print(f"{plant!r}, valve {args.valve}, Kp {ctrl.Kp:g} mA/deg, Ki {ctrl.Ki:g} mA/(deg s)")
    print(f"position loop: gain crossover {loop['crossover_hz']:.2f} Hz, phase margin {loop['phase_margin_deg']:.1f} deg, "
          f"gain margin {loop['gain_margin_db']:.1f} dB at {loop['phase_crossover_hz']:.1f} Hz "
          f"(hydraulic resonance {loop['hydraulic_hz']:.1f} Hz)")
    print(f"wrote {readme} and the figures beside it")
    return 0
