"""``ehas simulate``: one closed-loop run of the plant, written as a run file."""
from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--disc-sets", type=int, default=3, help="disc sets on the crank, 1..7 (default 3)")
    parser.add_argument("--amplitude", type=float, default=20.0, help="reference amplitude, deg (default 20)")
    parser.add_argument("--freq", type=float, default=1.0, help="reference frequency, Hz (default 1)")
    parser.add_argument("--cycles", type=float, default=4.0, help="reference cycles to run (default 4)")
    parser.add_argument("--effects", default="", help="effects, e.g. 'coulomb_friction:Fc=300,viscous_friction:b=2000'")
    parser.add_argument("--gains", default="", help="controller gains, e.g. 'Kp=1,Ki=2' (default: the book's)")
    parser.add_argument("--sensors", action="store_true", help="add sensor noise and ADC/DAC quantization")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    parser.add_argument("--out", default="results/simulate/run", help="output stem: writes STEM.csv and STEM.json")
    parser.add_argument("--plot", action="store_true", help="also write STEM.png")


def parse_gains(text: str):
    from ehas_env.simulation.plant import RigController

    values = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        key, _, val = item.partition("=")
        if key not in RigController.__dataclass_fields__:
            raise ValueError(f"--gains: unknown gain '{key}'; expected some of {', '.join(RigController.__dataclass_fields__)}")
        try:
            values[key] = float(val)
        except ValueError:
            raise ValueError(f"--gains: value of '{key}' must be a number, got {val!r}") from None
    return RigController(**values)


def run(args) -> int:
    from ehas_env.simulation.plant import Plant
    from ehas_env.simulation.sensors import Sensors

    plant = Plant(disc_sets=args.disc_sets, effects=args.effects or None,
                  sensors=Sensors() if args.sensors else None, seed=args.seed)
    res = plant.simulate_closed_loop(parse_gains(args.gains), amplitude_deg=args.amplitude, freq_hz=args.freq,
                                     cycles=args.cycles)
    csv_path, json_path = res.to_csv(args.out, notes=f"ehas simulate, {plant!r}")
    err = res.tracking_errors()
    print(f"{plant!r}: +-{args.amplitude:g} deg at {args.freq:g} Hz")
    print(f"rms % position error {err['rms_error_pct']:.3f} %, peak {err['peak_error_pct']:.3f} % "
          f"(whole cycles after the first, % of amplitude)")
    print(f"wrote {csv_path} and {json_path}")
    if args.plot:
        from ehas_env.output.plots import plot_run

        png = plot_run(res, csv_path.with_suffix(".png"))
        print(f"wrote {png}")
    return 0
