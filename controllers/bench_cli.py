"""``ehas bench``: the % position error benchmark of any list of controllers.

    ehas bench                                   # the book's gains + each tuner's result
    ehas bench results/controllers/*.json        # these controllers
    ehas bench ctrl.json --model my_rig.json     # on a calibrated model's plant
    ehas bench ctrl.json --executor ray --address auto   # simulations on a Ray cluster

The executor options (``--executor``, ``--workers``, ``--address``) change where
the simulations run, not their results, so the regenerating command written into
the files leaves them out.

Controller files are loaded by type (``ehas_controllers.base.load_controller``):
controller JSONs (``ehas tune``) today; learned agents register their loader.
With no files, the tuners' results are read from ``OUT/controllers/`` where
present and tuned (with ``ehas tune``'s defaults) and saved there otherwise.
"""
from __future__ import annotations

import argparse
import shlex
from pathlib import Path

DEFAULT_TUNERS = (  # (file stem, ehas tune arguments)
    ("model", ["--method", "model"]),
    ("relay", ["--method", "relay"]),
    ("optimize", ["--method", "optimize"]),
    ("schedule_model", ["--method", "schedule", "--base", "model"]),
    ("schedule_optimize", ["--method", "schedule", "--base", "optimize"]),
)


#: the files of one benchmark run (its output set in --out)
BENCH_FILES = ("benchmark.csv", "benchmark.md", "benchmark_robustness.csv", "benchmark_timing.json", "heatmap_*.png")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("controllers", nargs="*", metavar="CONTROLLER_FILE",
                        help="controller files (default: the book's gains plus each tuner's result)")
    parser.add_argument("--out", default="results", help="output folder (default results)")
    parser.add_argument("--model", default=None, help="model file whose plant to run (ehas_env.simulation.model_file)")
    from ehas_env.ranges import number

    parser.add_argument("--cycles", type=number("--cycles", "reference periods", 2, 100, lo_open=True), default=5.0, help="reference periods per run, first excluded (default 5)")
    parser.add_argument("--long-test", type=number("--long-test", "reference cycles", 7, 1000, integer=True), nargs="?", const=30.0,
                        default=None, metavar="N",
                        help="also run the long test: N reference cycles from rest per condition (default 30), "
                             "steady-state rms %% over the last 5, cycles to settle, worst cycle; writes OUT/long_test/")
    parser.add_argument("--long-test-only", action="store_true",
                        help="with --long-test: skip the 4-cycle benchmark (its files in OUT are left as they are)")
    parser.add_argument("--long-test-robustness", action="store_true",
                        help="with --long-test: also run each learning controller on plants with +-30%% on beta, K "
                             "and friction (18 conditions each); writes long_test_robustness.csv")
    parser.add_argument("--sensors", action="store_true",
                        help="with --long-test: the plant's sensor layer on (LVDT noise 0.01 deg, 16-bit ADC, 12-bit "
                             "DAC; ehas_env.simulation.sensors); the long test then writes OUT/long_test_sensors/ "
                             "(with --model: OUT/long_test_model[_sensors]/)")
    parser.add_argument("--no-robustness", action="store_true", help="skip the robustness table (13 x 63 runs per controller)")
    parser.add_argument("--no-book", action="store_true", help="leave the book's baseline gains out")
    parser.add_argument("--retune", action="store_true", help="with no files: re-run the tuners even if their files exist")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument("--allow-pickle", action="store_true",
                        help="also load legacy pickled agent folders (model.zip, vecnormalize.pkl): unpickling runs "
                             "any code the files hold, so only for agents you trained yourself or trust as a program "
                             "(convert them once with python -m ehas_train.agent_convert)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace the benchmark files of an earlier run in --out (benchmark*, heatmap_*.png)")
    from ehas_env.simulation.executors import add_executor_arguments

    add_executor_arguments(parser)


def default_controllers(out: Path, retune: bool, progress: bool) -> list:
    """The tuners' results under ``out/controllers`` (tuned and saved when missing)."""
    from .base import load_controller
    from .tune_cli import add_arguments as tune_args
    from .tune_cli import run as tune_run

    ctrls = []
    for stem, argv in DEFAULT_TUNERS:
        path = out / "controllers" / f"{stem}.json"
        if retune or not path.exists():
            p = argparse.ArgumentParser(prog="ehas tune")
            tune_args(p)
            targs = p.parse_args(argv + ["--out", str(path)] + ([] if progress else ["--no-progress"])
                                 + (["--overwrite"] if path.exists() else []))
            print(f"[bench] tuning: ehas tune {' '.join(shlex.quote(a) for a in [*argv, '--out', str(path)])}", flush=True)
            tune_run(targs)
        ctrls.append(load_controller(path))
    return ctrls


def _long_dir(args) -> str:
    """The long test's folder in --out: long_test, with _model (--model) and _sensors (--sensors)."""
    return "long_test" + ("_model" if args.model else "") + ("_sensors" if args.sensors else "")


def run(args) -> int:
    from ehas_env.simulation.executors import executor_from_args

    from .base import load_controller
    from .benchmark import run_benchmark
    from .piff import PIFF
    from .tune_cli import plant_kwargs_from_model

    from ehas_env.output.outputs import OutputSet

    from . import base

    base.LOAD_OPTIONS["allow_pickle"] = bool(getattr(args, "allow_pickle", False))
    if (args.long_test_only or args.sensors or args.long_test_robustness) and args.long_test is None:
        raise ValueError("--long-test-only, --long-test-robustness and --sensors go with --long-test [N]")
    out = Path(args.out)
    plant_kw = plant_kwargs_from_model(args.model)
    # the output set, checked before any work: the benchmark's files in --out (other files there are left alone)
    outputs = (None if args.long_test is not None and args.long_test_only else
               OutputSet(out, "--out", overwrite=args.overwrite, members=BENCH_FILES, last=("benchmark.md",)))
    if args.long_test is not None:  # checked before any work, as the benchmark's own files
        from .long_test import LONG_FILES

        OutputSet(out / _long_dir(args), "--out", overwrite=args.overwrite,
                  members=LONG_FILES, last=("long_test.md",))
    executor = executor_from_args(args)
    controllers = [] if args.no_book else [PIFF.book()]
    if args.controllers:
        controllers += [load_controller(p) for p in args.controllers]
    else:
        controllers += default_controllers(out, args.retune, not args.no_progress)
    if not controllers:
        raise ValueError("no controllers to benchmark (--no-book and no files)")
    parts = ["ehas", "bench", *args.controllers]
    if args.out != "results":
        parts += ["--out", args.out]
    if args.model:
        parts += ["--model", args.model]
    if args.cycles != 5.0:
        parts += ["--cycles", f"{args.cycles:g}"]
    for flag in ("no_robustness", "no_book"):
        if getattr(args, flag):
            parts.append("--" + flag.replace("_", "-"))
    if args.long_test is not None:
        parts += ["--long-test"] + ([] if args.long_test == 30 else [f"{args.long_test:g}"])
        parts += [flag for flag, on in (("--long-test-only", args.long_test_only), ("--sensors", args.sensors),
                                        ("--long-test-robustness", args.long_test_robustness)) if on]
    command = " ".join(shlex.quote(p) for p in parts)
    if args.long_test is not None:
        from .long_test import LONG_FILES, run_long_test

        long_out = out / _long_dir(args)
        long_set = OutputSet(long_out, "--out", overwrite=args.overwrite, members=LONG_FILES, last=("long_test.md",))
        long_kw = dict(plant_kw)
        label = "book rig" if not args.model else f"model {args.model}"
        if args.sensors:
            from ehas_env.simulation.sensors import Sensors

            long_kw["sensors"] = Sensors()
            label += ", sensor layer on"
        with long_set as tmp:
            long_res = run_long_test(controllers, tmp, cycles=int(args.long_test), plant_kwargs=long_kw,
                                     command=command, progress=not args.no_progress, plant_label=label,
                                     robustness=args.long_test_robustness)
        print(f"long test ({int(args.long_test)} cycles, steady state = last 5; {label}):")
        print(f"{'controller':<34} {'mean steady rms %':>17} {'worst steady rms %':>18} {'mean settle':>11} "
              f"{'flags':>5}")
        for name, s in long_res["summary"].items():
            print(f"{name:<34} {s['mean_steady_rms_pct']:>17.4f} {s['worst_steady_rms_pct']:>18.4f} "
                  f"{s['mean_settle_cycles']:>11.1f} {s['transient_flags']:>5d}")
        for r in long_res["robustness"]:
            print(f"robustness {r['controller']} on {r['plant']}: mean steady rms {r['mean_steady_rms_pct']:.4f} %, "
                  f"{r['divergent']} divergent of {r['conditions']}")
        print(f"wrote {long_out / 'long_test.csv'}, {long_out / 'long_test.md'} and heatmaps")
        if args.long_test_only:
            return 0
    with outputs as tmp:
        res = run_benchmark(controllers, tmp, cycles=args.cycles, plant_kwargs=plant_kw,
                            robustness=not args.no_robustness, command=command, progress=not args.no_progress,
                            executor=executor)
    t = res["timing"]
    print(f"63-condition grid for one controller: {t['best_s']:.2f} s on the {t.get('build', 'fast-step')} build "
          f"(first run {t['first_s']:.2f} s; target < 10 s)")
    print(f"{'controller':<28} {'kind':<9} {'mean rms %':>10} {'worst rms %':>11} {'30/3/7 rms %':>12} {'stroke hits':>11} {'book beaten':>11}")
    for name, s in res["summary"].items():
        print(f"{name:<28} {s['kind']:<9} {s['mean_rms_error_pct']:>10.3f} {s['worst_rms_error_pct']:>11.3f} "
              f"{s['rms_30deg_3hz_7sets']:>12.3f} {s['stroke_end_hits']:>11d} {s['book_wins']:>9d}/7")
    print("(rms_error_pct: 100 RMS(theta_ref - theta)/amplitude over whole cycles after the first)")
    print(f"wrote {out / 'benchmark.csv'}, {out / 'benchmark.md'}, heatmaps and {out / 'benchmark_timing.json'}")
    return 0
