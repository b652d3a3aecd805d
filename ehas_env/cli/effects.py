"""``ehas effects [NAME]``: the effects library, or one effect in full."""
from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", nargs="?", help="an effect's name: print its explanation, signature and parameters")


def run(args) -> int:
    from ehas_env.physics.effects import REGISTRY, get_effect

    if args.name:
        print(get_effect(args.name).describe())
        return 0
    width = max(map(len, REGISTRY))
    for name in sorted(REGISTRY):
        cls = REGISTRY[name]
        params = ", ".join(f"{p.name} [{p.unit}]" for p in cls.params)
        print(f"{name:<{width}}  {cls.title}  ({params})")
    print("\n`ehas effects NAME` explains one; switch effects on with --effects NAME:PARAM=VALUE,...")
    return 0
