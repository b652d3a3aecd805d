"""``ehas simulate``: one closed-loop run of the plant, written as a run file."""
from __future__ import annotations

import argparse

from ehas_env.ranges import FIELDS, check_run_length, number, option


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--disc-sets", type=option("--disc-sets", "disc_sets"), default=3,
                        help="disc sets on the crank, 1..7 (default 3)")
    parser.add_argument("--amplitude", type=option("--amplitude", "amplitude_deg"), default=20.0,
                        help="reference amplitude, deg, below the stroke end 44.43 (default 20)")
    parser.add_argument("--freq", type=option("--freq", "freq_hz"), default=1.0,
                        help="reference frequency, Hz, (0, 50] (default 1)")
    parser.add_argument("--cycles", type=number("--cycles", "reference cycles", 3, 10_000), default=4.0,
                        help="reference cycles to run, 3..10000 (the first is warm-up; default 4); "
                             "at most 600 s of simulated time")
    parser.add_argument("--effects", default=None, help="effects, e.g. 'coulomb_friction:Fc=300,viscous_friction:b=2000'")
    parser.add_argument("--gains", default=None, help="controller gains, e.g. 'Kp=1,Ki=2' (default: the book's; with "
                                                    "--model, the book's carried over to that rig)")
    parser.add_argument("--controller", default=None, metavar="FILE",
                        help="a saved controller instead of --gains: a controller JSON (ehas tune --out) or a "
                             "learned agent's folder (ehas train --out)")
    parser.add_argument("--sensors", action="store_true", help="add sensor noise and ADC/DAC quantization")
    parser.add_argument("--seed", type=option("--seed", "seed"), default=0, help="seed of the sensor noise (default 0)")
    parser.add_argument("--out", default="results/simulate/run", help="output stem: writes STEM.csv and STEM.json")
    parser.add_argument("--plot", action="store_true", help="also write STEM.png")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier STEM.csv/STEM.json/STEM.png")


def parse_gains(text: str):
    from ehas_env.simulation.plant import RigController

    from ehas_env.ranges import split_list

    if text is None:  # not given: the book's gains
        return RigController()
    values = {}
    for item in split_list(text, "--gains", "NAME=VALUE gains, e.g. Kp=1.2,Ki=3"):
        key, eq, val = (part.strip() for part in item.partition("="))
        if not eq:
            raise ValueError(f"--gains: {item!r} is not NAME=VALUE, e.g. --gains Kp=1.2,Ki=3")
        if key in values:
            raise ValueError(f"--gains: {key} is given twice in {text!r}")
        if key not in RigController.__dataclass_fields__:
            raise ValueError(f"--gains: unknown gain '{key}'; expected some of {', '.join(RigController.__dataclass_fields__)}")
        if key == "rate_hz":
            values[key] = GAIN_RATE.parse(val, f"--gains {key}")
        else:
            values[key] = GAIN_RANGE.parse(val, f"--gains {key}")
    return RigController(**values)


def load_saved_controller(path, disc_sets: int):
    """(what ``Plant.simulate_closed_loop`` runs, the loaded controller) of a controller file.

    A classical controller whose limits are the rig's (±20 mA, no output
    quantization) becomes the rig controller's gains (a gain schedule: those for
    ``disc_sets``), so the run file's sidecar carries them and ``ehas compare``
    can replay it; any other controller (a learned agent) runs through its own
    ``act``.
    """
    from ehas_controllers.base import load_controller

    ctrl = load_controller(path)
    if hasattr(ctrl, "select"):
        ctrl.select(disc_sets)
    if hasattr(ctrl, "rig_gains") and getattr(ctrl, "i_max", 20.0) == 20.0 and not getattr(ctrl, "output_bits", 0):
        return ctrl.rig_gains(disc_sets), ctrl
    return ctrl, ctrl


#: controller gains on the command line (--gains): finite, and small enough that the loop's arithmetic stays finite
GAIN_RANGE = FIELDS["gain"]
GAIN_RATE = FIELDS["rate_hz"]


def run(args) -> int:
    from ehas_env.simulation.plant import Plant
    from ehas_env.simulation.sensors import Sensors

    from pathlib import Path

    from ehas_env.output.outputs import stem_set

    # every check before any work: the options, the run's length, the output paths
    check_run_length(args.cycles / args.freq, where=f"--cycles {args.cycles:g} at --freq {args.freq:g} Hz")
    if args.controller and args.gains:
        raise ValueError("--controller and --gains both give the controller; use one of them")
    model = None
    if getattr(args, "model", None):
        from ehas_env.simulation.model_file import load_model

        model = load_model(args.model)
    gains, loaded = load_saved_controller(args.controller, args.disc_sets) if args.controller else (parse_gains(args.gains), None)
    if model is not None and not args.controller and not args.gains:
        gains = model.controller()  # the book's gains carried over to this rig (docs/model-file.md)
    outputs = stem_set(args.out, "--out", overwrite=args.overwrite)
    plant = Plant(disc_sets=args.disc_sets, effects=args.effects or None,
                  sensors=Sensors() if args.sensors else None, seed=args.seed, model=model)
    res = plant.simulate_closed_loop(gains, amplitude_deg=args.amplitude, freq_hz=args.freq, cycles=args.cycles)
    err = res.tracking_errors()
    stem = Path(args.out)
    with outputs as tmp:
        where = f", model {model.label}" if model is not None else ""
        from ehas_env.measurement.runfile import write_result
        csv_tmp, _ = write_result(res, tmp / stem.name, notes=f"ehas simulate, {plant!r}{where}")
        if args.plot:
            from ehas_env.output.plots import plot_run

            ctrl_name = getattr(loaded, "name", None) or ("gains " + (args.gains or ("book's, carried over" if model
                                                                                   else "book's")))
            plot_run(res, csv_tmp.with_suffix(".png"),
                     title=f"{model.label if model is not None else 'book rig'}, {args.disc_sets} disc sets; "
                           f"controller {ctrl_name}")
    csv_path = stem.parent / csv_tmp.name
    if model is not None:
        print(f"model {model.label}: " + ("the book's rig" if model.is_book else "rig from the model file")
              + ("" if args.controller or args.gains else
                 f"; controller: the book's gains carried over to this rig (Kp {gains.Kp:.4g} mA/deg, "
                 f"Kv {gains.Kv:.4g} mA/(deg/s))"))
    print(f"{plant!r}: +-{args.amplitude:g} deg at {args.freq:g} Hz"
          + (f", controller {args.controller} ({getattr(loaded, 'name', type(loaded).__name__)})" if loaded is not None else ""))
    print(f"rms % position error {err['rms_error_pct']:.3f} %, peak {err['peak_error_pct']:.3f} % "
          f"(whole cycles after the first, % of amplitude)")
    print(f"wrote {csv_path} and {csv_path.with_suffix('.json')}")
    if args.plot:
        print(f"wrote {csv_path.with_suffix('.png')}")
    return 0
