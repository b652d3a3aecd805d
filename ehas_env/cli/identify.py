"""``ehas identify``: a continuous-time transfer function fitted to a valve run.

    ehas identify RUN.csv --poles 2 --zeros 0 [--input current_mA --output flow_lpm]
                  [--json FILE] [--out DIR]

prints the coefficients, K, wn, zeta (2-pole models) and the fit % (NRMSE, as
MATLAB's ``compare``), and writes into DIR (default ``results/identify/RUN/``)
the measured-vs-simulated overlay, the Bode plot (with the data's own
spectral estimate where it is coherent) and the residual analysis (MATLAB
``resid``: autocorrelation of the residuals and their cross-correlation with
the input, 99 % bands).  ``--num/--den`` instead evaluate a given transfer
function: alone they print its K, wn, zeta; with a run they report its fit on it.

The plotting functions here are reused by :mod:`ehas_env.identification.book_valve`.
"""
from __future__ import annotations

import argparse
import math
import shlex
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", nargs="?", help="run file (measurement format CSV); optional with --num/--den")
    from ehas_env.ranges import number

    parser.add_argument("--poles", type=number("--poles", "poles", 1, 10, integer=True), default=2,
                        help="number of poles, 1..10 (default 2)")
    parser.add_argument("--zeros", type=number("--zeros", "zeros", 0, 10, integer=True), default=0,
                        help="number of zeros, 0..10, fewer than the poles (default 0)")
    parser.add_argument("--input", default="current_mA", help="input column (default current_mA)")
    parser.add_argument("--output", default="flow_lpm", help="output column (default flow_lpm)")
    parser.add_argument("--intersample", choices=("zoh", "foh"), default="zoh",
                        help="input between samples: held (zoh, the format's convention, default) or linear (foh)")
    parser.add_argument("--initial-state", choices=("zero", "estimate"), default="zero",
                        help="start the model at rest (default) or also fit its initial state")
    parser.add_argument("--num", help="evaluate this numerator instead of fitting, e.g. '14567.29'")
    parser.add_argument("--den", help="... over this denominator, e.g. '1,147.83,11449.86'")
    parser.add_argument("--json", help="write {num, den, K, wn, zeta, fit_percent, ...} to this file")
    parser.add_argument("--out", help="folder for the plots (default results/identify/RUN)")
    parser.add_argument("--no-plots", action="store_true", help="write no plots")
    parser.add_argument("--max-lag", type=number("--max-lag", "samples", 1, 10_000, integer=True), default=25,
                        help="lags of the residual analysis, 1..10000 (default 25)")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier --out folder / --json file")
    parser.add_argument("--timing", action="store_true", help="repeat the fit 5 times and print the median wall time")


def _command(args) -> str:
    """The command line that regenerates this output, from the parsed arguments."""
    parts = ["ehas", "identify"] + ([args.run] if args.run else [])
    if args.num is not None:
        parts += ["--num", args.num, "--den", args.den]
    else:
        parts += ["--poles", str(args.poles), "--zeros", str(args.zeros)]
    for flag, value, default in (("--input", args.input, "current_mA"), ("--output", args.output, "flow_lpm"),
                                 ("--intersample", args.intersample, "zoh"),
                                 ("--initial-state", args.initial_state, "zero"), ("--json", args.json, None),
                                 ("--out", args.out, None)):
        if value != default:
            parts += [flag, str(value)]
    return " ".join(shlex.quote(p) for p in parts)


def _coeffs(text: str, what: str) -> list[float]:
    import re

    from ehas_env.ranges import split_list

    # commas or blanks between coefficients ("1, 2" and "1 2" too)
    items = split_list(re.sub(r"\s*,\s*|\s+", ",", text.strip()), f"--{what}",
                       "polynomial coefficients (degree 10 at most)", max_items=11, unique=False)
    try:
        vals = [float(v) for v in items]
    except ValueError:
        raise ValueError(f"--{what}: expected comma-separated numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise ValueError(f"--{what}: expected finite comma-separated numbers, got {text!r}")
    if what == "den" and vals[0] == 0:
        raise ValueError(f"--den: the leading coefficient must be non-zero, got {text!r}")
    if max(abs(v) for v in vals) > 1e150:
        raise ValueError(f"--{what}: coefficients must lie in [-1e150, 1e150], got {text!r}")
    return vals


def run(args) -> int:
    import json

    import numpy as np

    from ehas_env.identification import fit as ID
    from ehas_env.output.files import atomic_write_text

    if args.run is None and (args.num is None or args.den is None):
        raise ValueError("give a run file to identify, or --num and --den to evaluate a transfer function")
    if (args.num is None) != (args.den is None):
        raise ValueError("--num and --den go together")
    if args.num is None and args.zeros >= args.poles:
        raise ValueError(f"--zeros must be fewer than --poles (a proper transfer function), got --poles {args.poles} "
                         f"--zeros {args.zeros}")
    command = _command(args)
    from ehas_env.output.outputs import OutputSet, check_file, check_not_input

    # the output paths, before any work
    if args.json:
        check_not_input(args.json, "--json", [args.run])
        check_file(args.json, "--json", overwrite=args.overwrite)
    outputs = None
    if args.run is not None and not args.no_plots:
        check_not_input(Path(args.out) if args.out else Path("results/identify") / Path(args.run).stem, "--out",
                        [args.run])
        outputs = OutputSet(Path(args.out) if args.out else Path("results/identify") / Path(args.run).stem, "--out",
                            overwrite=args.overwrite)

    given = None
    if args.num is not None:
        import control

        num, den = _coeffs(args.num, "num"), _coeffs(args.den, "den")
        if len(num) > len(den):
            raise ValueError(f"--num/--den: improper transfer function (numerator degree {len(num) - 1} > "
                             f"denominator degree {len(den) - 1})")
        den_arr = np.asarray(den) / den[0]
        num_arr = np.asarray(num) / den[0]
        given = control.tf(num_arr, den_arr)
        print(f"G(s) = ({ID.format_poly(num_arr)}) / ({ID.format_poly(den_arr)})")
        result = {"num": num_arr.tolist(), "den": den_arr.tolist()}
        if len(den) == 3:
            so = ID.second_order_parameters(num_arr, den_arr)
            print(f"K = {so['K']:.4f}, wn = {so['wn']:.2f} rad/s ({so['wn'] / (2 * math.pi):.2f} Hz), "
                  f"zeta = {so['zeta']:.3f}")
            result.update(so)
        else:
            result.update({"K": ID.dc_gain(num_arr, den_arr), "wn": None, "zeta": None})
        print(f"poles: {', '.join(f'{p:.4g}' for p in np.roots(den_arr))}")
        if args.run is None:
            result["fit_percent"] = None
            if args.json:
                atomic_write_text(args.json, json.dumps(result, indent=2) + "\n")
                print(f"wrote {args.json}")
            return 0

    data = ID.read_columns(args.run, args.input, args.output)
    if given is not None:
        y_sim = ID.simulate_tf(given, data.t, data.u, intersample=args.intersample)
        est = ID.TFEstimate(tf=given, num=num_arr, den=den_arr, n_poles=len(den) - 1,
                            n_zeros=len(np.trim_zeros(num_arr, "f")) - 1, fit_percent=ID.fit_percent(data.y, y_sim),
                            data=data, y_sim=y_sim, intersample=args.intersample, x0=np.zeros(len(den) - 1))
        print(f"fit on {args.run}: {est.fit_percent:.2f} % (NRMSE, {args.intersample} input)")
    else:
        est = ID.tfest(data, n_poles=args.poles, n_zeros=args.zeros, intersample=args.intersample,
                       initial_state=args.initial_state)
        print(est.summary())
    ra = ID.residual_analysis(est.residuals, data.u, max_lag=min(args.max_lag, data.n - 1))
    print(f"  {ra.verdict()}")
    if args.timing and given is None:
        import time

        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            ID.tfest(data, n_poles=args.poles, n_zeros=args.zeros, intersample=args.intersample,
                     initial_state=args.initial_state)
            times.append(time.perf_counter() - t0)
        print(f"  timing: median {np.median(times):.3f} s over 5 fits of {data.n} samples "
              f"(min {min(times):.3f}, max {max(times):.3f})")
    if args.json:
        atomic_write_text(args.json, json.dumps(est.to_json_dict(), indent=2) + "\n")
        print(f"wrote {args.json}")
    if outputs is not None:
        label = f"{est.n_poles}p{est.n_zeros}z"
        from ehas_env.output.identification_plots import plot_bode, plot_overlay, plot_residuals

        with outputs as out:
            files = [plot_overlay(est, out / "overlay.png", title=f"{Path(args.run).name}: {label} model"),
                     plot_bode([(label, est.tf)], out / "bode.png", data=data,
                               title=f"{Path(args.run).name}: {label} model and the data's spectral estimate"),
                     plot_residuals(ra, out / "residuals.png",
                                    title=f"{Path(args.run).name}: residuals of the {label} model")]
            md = [f"# Identification of {args.run}", "", f"Regenerate: `{command}`", "", "```", est.summary(),
                  f"  {ra.verdict()}", "```", "", "Files: " + ", ".join(f"`{f.name}`" for f in files), ""]
            files.append(atomic_write_text(out / "identify.md", "\n".join(md)))
        print(f"wrote {', '.join(str(outputs.path / f.name) for f in files)}")
    return 0


# ---------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------
