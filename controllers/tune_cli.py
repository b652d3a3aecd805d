"""``ehas tune``: tune the classical controller and write it as a controller JSON.

    ehas tune --method model --disc-sets 5 --freq 3        # gains for 5 disc sets at 3 Hz
    ehas tune --method optimize                            # one set of gains for the whole grid
    ehas tune --method relay --disc-sets 7
    ehas tune --method schedule --base optimize            # per-disc-set gains
    ehas tune --method optimize --starts 4 --executor ray  # 4 optimiser starts side by side on Ray

The file (default ``results/controllers/<method>.json``) holds the gains with
their units, the tuner's report, the command that regenerates it and the
controller's mean rms % error over the 63 benchmark conditions; ``ehas bench``
and the environment load it.
"""
from __future__ import annotations

import argparse
import math
import shlex
from pathlib import Path

METHODS = ("model", "optimize", "relay", "schedule")
DEFAULT_DISC_SETS = 7  # model/relay: the heaviest load has the least margin, so its gains suit every set
#: optimiser's starting pressure-feedback gain, mA/bar (assumed: the middle of what the optimiser settles on,
#: 0.004-0.03, in the runs recorded in results/controllers)
START_KDP = 0.01


def resolve_defaults(args):
    """Fill the method-dependent defaults in place (so the written command shows them)."""
    optimising = args.method == "optimize" or (args.method == "schedule" and args.base == "optimize")
    if args.pressure_feedback is None:
        args.pressure_feedback = "static" if optimising else "none"
    if args.kdp is None and optimising and args.pressure_feedback != "none":
        args.kdp = START_KDP
    return args


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--method", required=True, choices=METHODS, help="tuner: model, optimize, relay or schedule")
    from ehas_env.ranges import number, option

    parser.add_argument("--disc-sets", type=option("--disc-sets", "disc_sets"), default=None,
                        help="disc sets to tune for, 1..7 (model/relay default 7, the least margin; "
                             "optimize default: all seven)")
    parser.add_argument("--freq", type=number("--freq", "Hz", 0, 20, lo_open=True), default=None,
                        help="reference frequency, Hz: model/relay operating point (default 2); "
                             "optimize/schedule: tune at this frequency only (default 1, 2 and 3)")
    parser.add_argument("--amplitude", type=option("--amplitude", "amplitude_deg"), default=None,
                        help="reference amplitude, deg: as --freq (operating point default 20; conditions default 10, 20, 30)")
    parser.add_argument("--out", default=None, help="controller JSON to write (default results/controllers/METHOD.json)")
    parser.add_argument("--model", default=None, help="model file whose plant to tune on (ehas_env.simulation.model_file)")
    g = parser.add_argument_group("model-based")
    g.add_argument("--phase-margin", type=number("--phase-margin", "deg", 0, 90, lo_open=True, hi_open=True), default=50.0, help="phase-margin target, deg (default 50)")
    g.add_argument("--bandwidth", type=number("--bandwidth", "Hz", 0, 100, lo_open=True), default=None, help="crossover target, Hz (default: highest meeting the margins)")
    g.add_argument("--gain-margin", type=number("--gain-margin", "dB", 0, 40, lo_open=True), default=6.0, help="least gain margin, dB (default 6)")
    g.add_argument("--pi-lag", type=number("--pi-lag", "deg", 0, 80), default=3.0,
                   help="phase the PI's integral may cost at crossover, deg (default 3: little integral action, "
                        "which tracks sines best)")
    g.add_argument("--pressure-feedback", choices=("none", "static", "dynamic"), default=None,
                   help="load-pressure feedback variant (default: none for model/relay; static for optimize and "
                        "schedule, whose optimiser then tunes Kdp)")
    g.add_argument("--kdp", type=number("--kdp", "mA/bar", 0, 1), default=None,
                   help="pressure feedback gain, mA/bar (model default: chosen by the tuner; optimiser start "
                        f"default {0.01:g})")
    g.add_argument("--dp-hp", type=number("--dp-hp", "rad/s", 0, 10_000, lo_open=True), default=10.0, help="high-pass corner of dynamic pressure feedback, rad/s (default 10)")
    g.add_argument("--bode", default=None, help="Bode plot PNG (default: next to --out)")
    g = parser.add_argument_group("optimiser")
    g.add_argument("--objective", choices=("mean", "worst"), default="mean", help="mean or worst rms %% error (default mean)")
    g.add_argument("--max-evals", type=number("--max-evals", "evaluations", 1, 100_000, integer=True), default=200, help="objective evaluations per optimisation (default 200)")
    g.add_argument("--start", default=None, help="controller JSON to start from (default: the model-based design)")
    g.add_argument("--starts", type=number("--starts", "starts", 1, 1024, integer=True), default=1,
                   help="optimise from this many starts (the first unperturbed, the others seeded perturbations "
                        "of it) and keep the best; the starts are independent tasks for --executor (default 1)")
    g.add_argument("--seed", type=option("--seed", "seed"), default=0, help="seed of the perturbed starts (default 0)")
    g = parser.add_argument_group("relay")
    g.add_argument("--rule", choices=("zn", "tl"), default="tl",
                   help="PI rule: tl Tyreus-Luyben (default: more gain margin), zn Ziegler-Nichols")
    g.add_argument("--relay-mA", type=option("--relay-mA", "relay_mA"), default=1.0, help="relay amplitude, mA (default 1)")
    g = parser.add_argument_group("schedule")
    g.add_argument("--base", choices=("model", "optimize", "relay"), default="optimize",
                   help="tuner run at each disc set (default optimize)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier --out file (and its Bode plot)")
    from ehas_env.simulation.executors import add_executor_arguments

    add_executor_arguments(parser)


def command_of(args) -> str:
    """The canonical command line that reproduces ``args`` (written into the files)."""
    parts = ["ehas", "tune", "--method", args.method]
    for flag, value in (("--disc-sets", args.disc_sets), ("--freq", args.freq), ("--amplitude", args.amplitude),
                        ("--model", args.model), ("--out", args.out)):
        if value is not None:
            parts += [flag, str(value)]
    resolve_defaults(args)
    method = args.base if args.method == "schedule" else args.method
    if method in ("model", "optimize"):
        parts += ["--phase-margin", f"{args.phase_margin:g}", "--gain-margin", f"{args.gain_margin:g}",
                  "--pi-lag", f"{args.pi_lag:g}",
                  "--pressure-feedback", args.pressure_feedback]
        if args.bandwidth is not None:
            parts += ["--bandwidth", f"{args.bandwidth:g}"]
        if args.kdp is not None:
            parts += ["--kdp", f"{args.kdp:g}"]
        if args.pressure_feedback == "dynamic":
            parts += ["--dp-hp", f"{args.dp_hp:g}"]
    if method == "optimize":
        parts += ["--objective", args.objective, "--max-evals", str(args.max_evals)]
        if getattr(args, "starts", 1) != 1:
            parts += ["--starts", str(args.starts), "--seed", str(args.seed)]
        if args.start:
            parts += ["--start", args.start]
    elif method == "relay":
        parts += ["--rule", args.rule, "--relay-mA", f"{args.relay_mA:g}"]
    if args.method == "schedule":
        parts += ["--base", args.base]
    return " ".join(shlex.quote(p) for p in parts)


def plant_kwargs_from_model(path) -> dict:
    """Plant keyword arguments ``{"model": PlantModel}`` from a model file (docs/model-file.md), or {}."""
    if path is None:
        return {}
    try:
        from ehas_env.simulation.model_file import load_model
    except ImportError:
        raise ValueError(f"--model {path}: model files need ehas_env.simulation.model_file.load_model, which this "
                         "installation does not have") from None
    m = load_model(path)
    return dict(m) if isinstance(m, dict) else {"model": m}


def _check(args) -> None:
    from ehas_env.simulation.reference import check_amplitude
    from ehas_env.physics.rig import check_disc_sets

    if args.disc_sets is not None:
        try:
            check_disc_sets(args.disc_sets)
        except ValueError as exc:
            raise ValueError(f"--disc-sets: {exc}") from None
    if args.freq is not None and not (math.isfinite(args.freq) and 0 < args.freq <= 20):
        raise ValueError(f"--freq must be a frequency in (0, 20] Hz, got {args.freq!r}")
    if args.amplitude is not None:
        try:
            check_amplitude(args.amplitude)
        except ValueError as exc:
            raise ValueError(f"--amplitude: {exc}") from None
    if args.max_evals < 1:
        raise ValueError(f"--max-evals must be >= 1, got {args.max_evals}")
    if getattr(args, "starts", 1) < 1:
        raise ValueError(f"--starts must be >= 1, got {args.starts}")


def tune(args):
    """Run the tuner ``args`` describe; returns a :class:`~ehas_controllers.tuners.TuneResult`."""
    from ehas_env.simulation.executors import executor_from_args
    from ehas_env.simulation.plant import Plant

    from . import tuners as T
    from .base import load_controller
    from .batch_sim import grid

    _check(args)
    resolve_defaults(args)
    pkw = plant_kwargs_from_model(args.model)
    plant_kw = {k: v for k, v in pkw.items() if k != "disc_sets"}
    progress = not args.no_progress
    freqs = (args.freq,) if args.freq is not None else (1.0, 2.0, 3.0)
    amps = (args.amplitude,) if args.amplitude is not None else (10.0, 20.0, 30.0)
    op = {"amplitude_deg": args.amplitude if args.amplitude is not None else 20.0,
          "freq_hz": args.freq if args.freq is not None else 2.0}
    model_kw = dict(phase_margin_deg=args.phase_margin, bandwidth_hz=args.bandwidth, min_gain_margin_db=args.gain_margin,
                    pi_lag_deg=args.pi_lag,
                    pressure_feedback=args.pressure_feedback, Kdp=args.kdp, dp_hp=args.dp_hp, **op)
    if args.method == "model":
        n = args.disc_sets or DEFAULT_DISC_SETS
        bode = getattr(args, "_bode_into", None) or args.bode or str(Path(out_path(args)).with_suffix("")) + "_bode.png"
        return T.tune_model_based(plant=Plant(disc_sets=n, **plant_kw), bode_path=bode,
                                  bode_note=f"regenerate: {command_of(args)}", **model_kw)
    if args.method == "relay":
        n = args.disc_sets or DEFAULT_DISC_SETS
        return T.tune_relay(plant=Plant(disc_sets=n, **plant_kw), rule=args.rule, relay_mA=args.relay_mA, **op)
    if args.method == "optimize":
        sets = [args.disc_sets] if args.disc_sets else list(range(1, 8))
        start = load_controller(args.start) if args.start else T.tune_model_based(
            plant=Plant(disc_sets=max(sets), **plant_kw), **model_kw).controller
        if args.start and not hasattr(start, "Kp"):
            raise ValueError(f"--start {args.start}: the optimiser starts from a single PIFF controller, got {start.name}")
        starts = getattr(args, "starts", 1)
        if starts == 1 and getattr(args, "executor", "local") == "local":
            return T.tune_optimize(start, grid(sets, freqs, amps), objective=args.objective, max_evals=args.max_evals,
                                   plant_kwargs=plant_kw, progress=progress)
        return T.tune_optimize_multistart(start, grid(sets, freqs, amps), starts=starts, seed=args.seed,
                                          executor=executor_from_args(args), objective=args.objective,
                                          max_evals=args.max_evals, plant_kwargs=plant_kw)
    # schedule
    sets = [args.disc_sets] if args.disc_sets else list(range(1, 8))
    if args.base == "model":
        return T.tune_schedule("model", sets, plants={n: Plant(disc_sets=n, **plant_kw) for n in sets}, **model_kw)
    if args.base == "relay":
        return T.tune_schedule("relay", sets, plants={n: Plant(disc_sets=n, **plant_kw) for n in sets},
                               rule=args.rule, relay_mA=args.relay_mA, **op)
    return T.tune_schedule("optimize", sets, freqs=freqs, amplitudes=amps, objective=args.objective,
                           max_evals=args.max_evals, plant_kwargs=plant_kw, progress=progress,
                           start_kwargs=model_kw, executor=executor_from_args(args))


def out_path(args) -> str:
    if args.out:
        return args.out
    name = args.method if args.method != "schedule" else f"schedule_{args.base}"
    return f"results/controllers/{name}.json"


def run(args) -> int:
    from ehas_env.output.outputs import OutputError, OutputSet, check_file

    from .batch_sim import grid
    from .benchmark import _summary, evaluate_controller
    from .tuners import describe_gains

    # every check before any work: the options, the model file, the output paths
    _check(args)
    plant_kwargs_from_model(args.model)
    path = Path(out_path(args))
    if path.suffix.lower() != ".json":
        raise OutputError(f"--out {path}: a controller file name ends in .json")
    members = [path.name]
    if args.method == "model" and not args.bode:
        members.append(path.with_suffix("").name + "_bode.png")
    if args.bode:
        check_file(args.bode, "--bode", overwrite=args.overwrite, suffix=".png")
    outputs = OutputSet(path.parent, "--out", overwrite=args.overwrite, members=members, last=[path.name], shown=path)
    with outputs as tmp:
        if len(members) > 1:
            args._bode_into = str(tmp / members[1])
        try:
            _tune_and_save(args, tmp / path.name, grid, _summary, evaluate_controller, describe_gains)
        finally:
            args._bode_into = None
    print(f"wrote {path}")
    write_folder_readme(path.parent)
    return 0


def _tune_and_save(args, target, grid, _summary, evaluate_controller, describe_gains) -> None:
    res = tune(args)
    if getattr(args, "_bode_into", None) and "bode_png" in res.report:  # where it lands, not the temporary folder
        res.report["bode_png"] = str(Path(out_path(args)).with_suffix("")) + "_bode.png"
    ctrl = res.controller
    ctrl.name = _default_name(args) if ctrl.name in ("optimised",) or ctrl.name.startswith(("model-based", "relay", "schedule")) else ctrl.name
    for line in res.lines:
        print(line)
    print(f"gains ({ctrl.variant}):")
    for line in describe_gains(ctrl):
        print("  " + line)
    pkw = plant_kwargs_from_model(args.model)
    summary = _summary(evaluate_controller(ctrl, grid(), plant_kwargs={k: v for k, v in pkw.items() if k != "disc_sets"}))
    print(f"on the 63 benchmark conditions: mean rms % error {summary['mean_rms_error_pct']:.3f} %, worst "
          f"{summary['worst_rms_error_pct']:.3f} %, stroke-end hits {summary['stroke_end_hits']}")
    notes = {k: v for k, v in res.report.items() if isinstance(v, (int, float, str, list, dict)) or v is None}
    ctrl.save(target, command=command_of(args), metrics={**summary, "metric": "rms_error_pct over the 63 benchmark "
                                                        "conditions (ehas bench)"}, notes=notes)


def write_folder_readme(folder) -> None:
    """(Re)write ``folder/README.md``: each controller JSON there and the command that regenerates it."""
    import json

    from ehas_env.output.files import atomic_write_text

    folder = Path(folder)
    lines = ["# Tuned controllers", "", "Controller files written by `ehas tune` (loaded by `ehas bench` and the "
             "environment). Each file, and the command that regenerates it (also inside the JSON as `command`):", "",
             "| file | controller | mean rms % over the 63 conditions | command |", "|---|---|---:|---|"]
    for p in sorted(folder.glob("*.json")):
        try:
            data = json.loads(p.read_text())
        except (OSError, ValueError):
            continue
        if not isinstance(data, dict) or data.get("format") != "ehas-controller":
            continue
        cmd = data.get("command", "(not recorded)")
        rms = data.get("mean_rms_error_pct")
        lines.append(f"| `{p.name}` | {data.get('name', '')} | {rms:.3f} |" if isinstance(rms, (int, float))
                     else f"| `{p.name}` | {data.get('name', '')} | |")
        lines[-1] += f" `{cmd}` |"
        bode = p.with_name(p.stem + "_bode.png")
        if bode.exists():
            lines.append(f"| `{bode.name}` | Bode plot of the loop above | | `{cmd}` |")
    atomic_write_text(folder / "README.md", "\n".join(lines) + "\n")


def _default_name(args) -> str:
    parts = {"model": "model-based", "optimize": "optimised", "relay": f"relay-{args.rule}"}
    if args.method == "schedule":
        return f"schedule ({parts[args.base]})"
    name = parts[args.method]
    if args.method in ("model", "relay"):
        name += f" @{args.disc_sets or DEFAULT_DISC_SETS} sets"
    if args.model:  # the rig it was tuned on
        from ehas_env.simulation.model_file import load_model

        name += f" on {load_model(args.model).name}"
    return name
