"""``ehas excite``: an excitation signal through the valve on the flow bench, written as a run file.

    ehas excite chirp --f0 0.5 --f1 2 --amplitude 20 --duration 10 --out results/excite/chirp
    ehas excite prms --hold 0.02 --levels 5 --seed 1 --out results/excite/prms
    ehas identify results/excite/chirp.csv --poles 2 --zeros 0

The signal drives the plant's valve test (``Plant.simulate_valve_test``: the
valve alone, control ports joined through the flow meter, ``--supply-bar``
70 bar as in the rated test) and the flow is logged through the sensor chain
(turbine-meter noise, 16-bit ADC; ``ehas_env.simulation.sensors.Sensors``).  The run
file is the measurement format, ``kind: valve_open_loop``.
"""
from __future__ import annotations

import argparse

from ehas_env.ranges import check_samples, number, option

#: the signals of ehas_env.identification.excitation (kept here so that building the parser imports no numpy)
KINDS = ("chirp", "prbs", "prms", "multisine")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("kind", choices=KINDS, help="signal: chirp, prbs, prms or multisine")
    parser.add_argument("--amplitude", type=option("--amplitude", "current_mA"), default=20.0,
                        help="amplitude (peak), mA, (0, 20] (default 20)")
    parser.add_argument("--duration", type=number("--duration", "s", 0, 3600, lo_open=True), default=10.0,
                        help="length, s, (0, 3600] (default 10)")
    parser.add_argument("--rate", type=number("--rate", "Hz", 100, 100_000), default=1000.0,
                        help="sample rate, Hz, 100..100000 (default 1000, the rig's)")
    parser.add_argument("--f0", type=number("--f0", "Hz", 0, 50_000, lo_open=True), default=0.5,
                        help="chirp/multisine start frequency, Hz (default 0.5)")
    parser.add_argument("--f1", type=number("--f1", "Hz", 0, 50_000, lo_open=True), default=None,
                        help="chirp/multisine end frequency, Hz (default 2 for a chirp, as the book; 40 for a multisine)")
    parser.add_argument("--method", choices=("linear", "log"), default="linear", help="chirp sweep law (default linear)")
    parser.add_argument("--hold", type=number("--hold", "s", 0, 60, lo_open=True), default=0.01,
                        help="PRBS/PRMS clock period, s (default 0.01)")
    parser.add_argument("--levels", type=number("--levels", "levels", 2, 256, integer=True), default=5,
                        help="PRMS levels, 2..256 (default 5)")
    parser.add_argument("--order", type=number("--order", "", 2, 32, integer=True), default=None,
                        help="PRBS shift-register order (default: fits the run)")
    parser.add_argument("--lines", type=number("--lines", "frequency lines", 1, 100_000, integer=True), default=40,
                        help="multisine frequency lines (default 40)")
    parser.add_argument("--offset", type=option("--offset", "offset_mA"), default=0.0,
                        help="constant added to the signal, mA, -20..20 (default 0)")
    parser.add_argument("--seed", type=option("--seed", "seed"), default=0,
                        help="seed of the random signals and of the sensor noise")
    parser.add_argument("--supply-bar", type=option("--supply-bar", "supply_bar"), default=70.0,
                        help="flow-bench supply, bar, (0, 350] (default 70, rated test)")
    parser.add_argument("--valve", choices=("grey_box", "white_box"), default="grey_box",
                        help="valve model of the plant (default grey_box, the book's identified valve)")
    parser.add_argument("--flow-noise", type=number("--flow-noise", "LPM", 0, 25), default=None,
                        help="flow-meter noise std, LPM (default: the Sensors default, 0.05)")
    parser.add_argument("--ideal", action="store_true", help="no sensor noise or quantization")
    parser.add_argument("--out", default=None, help="output stem: writes STEM.csv and STEM.json (default results/excite/KIND)")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier STEM.csv/STEM.json")


def build_signal(args):
    from ehas_env.identification.excitation import make

    common = {"duration": args.duration, "rate_hz": args.rate, "amplitude": args.amplitude, "offset": args.offset}
    if args.kind == "chirp":
        return make("chirp", f0=args.f0, f1=2.0 if args.f1 is None else args.f1, method=args.method, **common)
    if args.kind == "multisine":
        return make("multisine", f0=args.f0, f1=40.0 if args.f1 is None else args.f1, lines=args.lines,
                    seed=args.seed, **common)
    if args.kind == "prbs":
        return make("prbs", hold=args.hold, order=args.order, seed=args.seed, **common)
    return make("prms", hold=args.hold, levels=args.levels, seed=args.seed, **common)


def run(args) -> int:
    import dataclasses

    from ehas_env.simulation.plant import Plant
    from ehas_env.simulation.sensors import Sensors

    from pathlib import Path

    from ehas_env.output.outputs import stem_set

    check_samples(args.duration * args.rate, f"--duration {args.duration:g} s at --rate {args.rate:g} Hz")
    stem = Path(args.out or f"results/excite/{args.kind}")
    outputs = stem_set(stem, "--out", overwrite=args.overwrite, suffixes=(".csv", ".json"))
    sig = build_signal(args)
    if args.ideal:
        sensors = Sensors.ideal()
    else:
        sensors = Sensors()
        if args.flow_noise is not None:
            sensors = dataclasses.replace(sensors, flow_noise_lpm=args.flow_noise)
    plant_kw = {"valve": args.valve} if args.valve != "grey_box" else {}
    plant = Plant(sensors=sensors, seed=args.seed, dt=1.0 / args.rate, **plant_kw)
    res = plant.simulate_valve_test(sig.current_mA, supply_bar=args.supply_bar)
    res.meta["excitation"] = {"kind": sig.kind, **sig.params}
    res.meta["valve"] = args.valve
    with outputs as tmp:
        from ehas_env.measurement.runfile import write_result
        csv_tmp, _ = write_result(res, tmp / stem.name, notes=f"ehas excite {sig.describe()}, valve {args.valve}, "
                                                             f"{args.supply_bar:g} bar supply, ports joined through the meter")
    csv_path = stem.parent / csv_tmp.name
    json_path = csv_path.with_suffix(".json")
    flow = res.logged.get("flow_lpm", res.flow_lpm)
    print(f"{sig.describe()}")
    print(f"{sig.current_mA.size} samples at {args.rate:g} Hz; current {sig.current_mA.min():.2f} .. "
          f"{sig.current_mA.max():.2f} mA; flow {flow.min():.2f} .. {flow.max():.2f} LPM at {args.supply_bar:g} bar")
    print(f"wrote {csv_path} and {json_path}")
    print(f"next: ehas identify {csv_path} --poles 2 --zeros 0")
    return 0
