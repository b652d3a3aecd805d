"""``ehas simulate-campaign``: write a synthetic measurement campaign with hidden effects.

The campaign itself is made by :mod:`ehas_env.measurement.synthetic`.
"""
from __future__ import annotations

import argparse
import sys

from ehas_env.measurement.synthetic import BETA_PERTURB, DURATION, K_PERTURB, write_simulated_campaign


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--effects", default=None,
                        help="hidden effects, e.g. coulomb_friction:Fc=300,viscous_friction:b=2000 (default: none)")
    parser.add_argument("--out", required=True, help="campaign folder to write (must not exist or be empty)")
    from ehas_env.ranges import number, option

    parser.add_argument("--seed", type=option("--seed", "seed"), default=0,
                        help="seed of the sensor noise and perturbations (default 0)")
    parser.add_argument("--perturb", action="store_true",
                        help=f"perturb beta by up to +-{100 * BETA_PERTURB:g} %% and K by up to +-{100 * K_PERTURB:g} %%")
    parser.add_argument("--duration", type=number("--duration", "s", 0.2, 120, lo_open=True), default=DURATION,
                        help=f"seconds per run, (0.2, 120] (default {DURATION:g})")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing campaign folder")
    from ehas_env.measurement.formats import formats

    writable = [f.name.lower() for f in formats() if f.write is not None]
    parser.add_argument("--format", choices=writable, default="csv",
                        help="the runs' data files: " + ", ".join(writable) + " (default csv; "
                             "docs/measurement-format.md)")


def run(args) -> int:
    from ehas_env.output.outputs import OutputSet
    from ehas_env.physics.effects import parse_spec, resolve_effects

    model = None
    if getattr(args, "model", None):
        from ehas_env.simulation.model_file import load_model

        model = load_model(args.model)
    effects = parse_spec(args.effects) if args.effects else {}
    resolve_effects(effects)  # bad values refused before any work
    outputs = OutputSet(args.out, "--out", overwrite=args.overwrite)
    argv = " ".join(sys.argv[1:]) if sys.argv and sys.argv[0].endswith("ehas") else None
    with outputs as tmp:
        _, truth = write_simulated_campaign(tmp, effects, seed=args.seed, perturb=args.perturb,
                                            duration=args.duration, overwrite=True, model=model, fmt=args.format,
                                            command=f"ehas {argv}" if argv else None)
    folder = args.out
    print(f"wrote {folder}: {len(truth['plan'])} closed-loop runs + valve chirp, {args.duration:g} s each"
          + (f", rig {model.label}" if model is not None else ""))
    print(f"hidden: {truth['effects'] or 'no effect'}; beta = {truth['beta']:.4g} Pa, K = {truth['K']:.5g} LPM/mA "
          f"(truth.json)")
    return 0
