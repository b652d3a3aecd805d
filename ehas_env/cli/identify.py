"""``ehas identify``: a continuous-time transfer function fitted to a valve run.

    ehas identify RUN.csv --poles 2 --zeros 0 [--input current_mA --output flow_lpm]
                  [--json FILE] [--out DIR] [--offsets none|output|estimate]
                  [--delay SECONDS|estimate] [--orders LO:HI [--validate RUN2]] [--predict K]
                  [--export FILE.mat|FILE.json] [--covariance auto|white|coloured]
    ehas identify RUN.csv --structure arx|armax|oe|bj|ss [--na N --nb N --nc N --nd N --nf N --nk N | --nx N]
                  [--offsets none|output|estimate] [--orders LO:HI [--compare arx,armax,oe,bj,ss|all]] ...

prints the coefficients, K, wn, zeta (2-pole models) and the fit % (NRMSE, as
MATLAB's ``compare``), and writes into DIR (default ``results/identify/RUN/``)
the measured-vs-simulated overlay, the Bode plot (with the data's own
spectral estimate where it is coherent) and the residual analysis (MATLAB
``resid``: autocorrelation of the residuals and their cross-correlation with
the input, 99 % bands).  ``--num/--den`` instead evaluate a given transfer
function: alone they print its K, wn, zeta; with a run they report its fit on it.

A fit also prints (and ``--json`` writes as ``ci95``) the 95 % intervals of its
coefficients and of K, wn, zeta (:mod:`ehas_env.identification.uncertainty`), the
residual tests (``residual_tests``) and warns in one line when the run looks
closed-loop (:mod:`ehas_env.identification.checks`); ``--orders`` adds the table of
structures (:mod:`ehas_env.identification.orders`), ``--export`` the model file
(:mod:`ehas_env.identification.export`).

``--structure`` (default ``tf``, the behaviour above) picks a discrete-time
black box instead (:mod:`ehas_env.identification.pem`), its orders given one
flag each as MATLAB's order vectors name them - arx ``[na nb nk]``, armax
``[na nb nc nk]``, oe ``[nb nf nk]``, bj ``[nb nc nd nf nk]``, ss ``nx``
(N4SID, needs ``pip install 'ehas[ident]'``); an order flag the structure does
not have is refused, and orders left out take 2 (nk: 1).  Its JSON carries
``structure``, ``orders``, the polynomials in q^-1 with each coefficient's
standard error, the transfer function in z (``tf_z``), the fit % and the
residual tests of the one-step prediction errors; ``--offsets output|estimate``
removes the run's output / input and output means first.  ``--compare`` adds
black-box rows "of order n" (every polynomial of degree n, or n states) beside
the transfer functions of ``--orders``, on the same estimation and validation
data (with a black-box ``--structure`` they are added by default).

The plotting functions here are reused by :mod:`ehas_env.identification.book_valve`.
"""
from __future__ import annotations

import argparse
import math
import shlex
from pathlib import Path


from ehas_env.identification.pem import DEFAULT_ORDERS, ORDER_RANGE, ORDERS, STRUCTURES  # noqa: E402

ORDER_FLAGS = ("na", "nb", "nc", "nd", "nf", "nk", "nx")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", nargs="?", help="run file (measurement format CSV); optional with --num/--den")
    from ehas_env.ranges import number

    parser.add_argument("--poles", type=number("--poles", "poles", 1, 10, integer=True), default=None,
                        help="number of poles, 1..10 (default 2; --structure tf)")
    parser.add_argument("--zeros", type=number("--zeros", "zeros", 0, 10, integer=True), default=None,
                        help="number of zeros, 0..10, fewer than the poles (default 0; --structure tf)")
    parser.add_argument("--structure", choices=("tf",) + STRUCTURES, default="tf",
                        help="tf (default): the continuous-time transfer function (--poles, --zeros); or a "
                             "discrete-time black box: arx (--na --nb --nk), armax (--na --nb --nc --nk), oe (--nb "
                             "--nf --nk), bj (--nb --nc --nd --nf --nk), ss (N4SID, --nx; needs ehas[ident])")
    for name, what in (("na", "A (poles of arx/armax)"), ("nb", "B (input terms)"), ("nc", "C (noise zeros)"),
                       ("nd", "D (noise poles of bj)"), ("nf", "F (poles of oe/bj)"), ("nk", "input delay, samples"),
                       ("nx", "states of ss")):
        lo, hi = ORDER_RANGE[name]
        parser.add_argument(f"--{name}", type=number(f"--{name}", "", lo, hi, integer=True), default=None,
                            help=f"order of {what}, {lo}..{hi} (default {DEFAULT_ORDERS[name]}); only with the "
                                 f"structures that have it")
    parser.add_argument("--compare", type=CompareOption(),
                        help="with --orders: black-box structures fitted beside the tf rows at each order n "
                             "(comma list of arx,armax,oe,bj,ss or 'all'; default: the --structure if not tf)")
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
    # issue 24: what a MATLAB System Identification user expects beside the fit
    parser.add_argument("--offsets", choices=("none", "output", "estimate"), default="none",
                        help="none (default); output: fit a constant output offset (a sensor bias); estimate: fit "
                             "the operating point (input and output offsets) the system rests at before the run")
    parser.add_argument("--delay", type=DelayOption(), default=0.0,
                        help="input delay: seconds in [0, 10] (default 0) or 'estimate' (fractional, with its "
                             "95 %% interval)")
    parser.add_argument("--max-delay", type=number("--max-delay", "s", 0, 10, lo_open=True), default=None,
                        help="largest delay --delay estimate searches, s (default: 100 samples or a tenth of the "
                             "run, the smaller)")
    parser.add_argument("--covariance", choices=("auto", "white", "coloured"), default="auto",
                        help="covariance of the estimates: auto (default: coloured when the residuals fail the "
                             "whiteness test), white, coloured")
    parser.add_argument("--orders", type=OrdersOption(),
                        help="compare structures: POLES or LO:HI poles, each with 0..poles-1 zeros (e.g. 1:3): fit "
                             "%%, AIC, BIC, FPE on estimation (first 2/3) and validation (last 1/3 or --validate) "
                             "data; the lowest validation BIC is chosen")
    parser.add_argument("--validate", metavar="RUN2",
                        help="a second run that validates (--orders, and the fit's validation fit %%)")
    parser.add_argument("--predict", type=number("--predict", "steps", 1, 10_000, integer=True),
                        help="also the K-step-ahead prediction fit (AR noise model of the residuals), 1..10000")
    parser.add_argument("--export", metavar="FILE",
                        help="write the model to FILE.mat or FILE.json (num, den, dt = 0, delay_s, offsets)")


class DelayOption:
    """argparse ``type=`` of ``--delay``: ``estimate`` or seconds in [0, 10]."""

    __name__ = "delay"

    def __call__(self, text: str):
        import argparse

        from ehas_env.ranges import Range

        if str(text).strip().lower() == "estimate":
            return "estimate"
        try:
            return Range(0.0, 10.0, "s").parse(text, "--delay")
        except ValueError:
            raise argparse.ArgumentTypeError(f"--delay must be 'estimate' or a number in [0, 10] s, got {text!r}") \
                from None


class OrdersOption:
    """argparse ``type=`` of ``--orders``: ``POLES`` or ``LO:HI`` in 1..10."""

    __name__ = "orders"

    def __call__(self, text: str):
        import argparse

        from ehas_env.identification.orders import parse_orders

        try:
            parse_orders(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return text


class CompareOption:
    """argparse ``type=`` of ``--compare``: a comma list of black-box structures, or ``all``."""

    __name__ = "compare"

    def __call__(self, text: str):
        import argparse

        items = [t.strip().lower() for t in str(text).split(",") if t.strip()]
        if items == ["all"]:
            return list(STRUCTURES)
        bad = [t for t in items if t not in STRUCTURES]
        if not items or bad or len(set(items)) != len(items):
            raise argparse.ArgumentTypeError(f"--compare must be 'all' or a comma list of distinct structures from "
                                             f"{', '.join(STRUCTURES)}, got {text!r}")
        return items


def _command(args) -> str:
    """The command line that regenerates this output, from the parsed arguments."""
    parts = ["ehas", "identify"] + ([args.run] if args.run else [])
    if args.num is not None:
        parts += ["--num", args.num, "--den", args.den]
    elif args.structure == "tf":
        parts += ["--poles", str(args.poles), "--zeros", str(args.zeros)]
    else:
        parts += ["--structure", args.structure]
    for name in ORDER_FLAGS:
        if getattr(args, name) is not None:
            parts += [f"--{name}", str(getattr(args, name))]
    if args.compare:
        parts += ["--compare", ",".join(args.compare)]
    for flag, value, default in (("--input", args.input, "current_mA"), ("--output", args.output, "flow_lpm"),
                                 ("--intersample", args.intersample, "zoh"),
                                 ("--initial-state", args.initial_state, "zero"), ("--json", args.json, None),
                                 ("--out", args.out, None), ("--offsets", args.offsets, "none"),
                                 ("--delay", args.delay, 0.0), ("--max-delay", args.max_delay, None),
                                 ("--covariance", args.covariance, "auto"), ("--orders", args.orders, None),
                                 ("--validate", args.validate, None), ("--predict", args.predict, None),
                                 ("--export", args.export, None)):
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
    _check_structure(args)
    if (args.num is None) != (args.den is None):
        raise ValueError("--num and --den go together")
    if args.num is None and args.structure == "tf" and args.zeros >= args.poles:
        raise ValueError(f"--zeros must be fewer than --poles (a proper transfer function), got --poles {args.poles} "
                         f"--zeros {args.zeros}")
    fitting = args.num is None
    if not fitting:
        for flag, value, default in (("--offsets", args.offsets, "none"), ("--orders", args.orders, None),
                                     ("--max-delay", args.max_delay, None), ("--predict", args.predict, None),
                                     ("--validate", args.validate, None)):
            if value != default:
                raise ValueError(f"{flag} applies to a fit; it does not go with --num/--den")
        if args.delay == "estimate":
            raise ValueError("--delay estimate applies to a fit; with --num/--den give the delay in seconds")
    if args.run is None and args.delay != 0.0:
        raise ValueError("--delay needs a run file")
    if args.max_delay is not None and args.delay != "estimate":
        raise ValueError("--max-delay goes with --delay estimate")
    if args.offsets == "estimate" and args.initial_state == "estimate":
        raise ValueError("--offsets estimate and --initial-state estimate together are not identifiable (a free "
                         "initial state absorbs the input offset); use --offsets output or one of them")
    if args.compare and not args.orders:
        raise ValueError("--compare goes with --orders (it adds black-box rows to the structure table)")
    command = _command(args)
    from ehas_env.output.outputs import OutputSet, check_file, check_not_input

    # the output paths, before any work
    if args.json:
        check_not_input(args.json, "--json", [args.run])
        check_file(args.json, "--json", overwrite=args.overwrite)
    if args.export:
        from ehas_env.identification.export import check_path

        check_path(args.export, "--export")
        check_not_input(args.export, "--export", [args.run, args.validate])
        check_file(args.export, "--export", overwrite=args.overwrite)
    if args.validate is not None and args.run is None:
        raise ValueError("--validate needs a run file to fit")
    outputs = None
    if args.run is not None and not args.no_plots:
        check_not_input(Path(args.out) if args.out else Path("results/identify") / Path(args.run).stem, "--out",
                        [args.run])
        outputs = OutputSet(Path(args.out) if args.out else Path("results/identify") / Path(args.run).stem, "--out",
                            overwrite=args.overwrite)

    if args.structure != "tf":
        return _run_black_box(args, command, outputs)
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
            print(f"K = {so['K']:.4f} (output unit per input unit), wn = {so['wn']:.2f} rad/s "
                  f"({so['wn'] / (2 * math.pi):.2f} Hz), zeta = {so['zeta']:.3f}")
            result.update(so)
        else:
            result.update({"K": ID.dc_gain(num_arr, den_arr), "wn": None, "zeta": None})
        print(f"poles: {', '.join(f'{p:.4g}' for p in np.roots(den_arr))} rad/s")
        if args.run is None:
            result["fit_percent"] = None
            if args.json:
                atomic_write_text(args.json, json.dumps(result, indent=2) + "\n")
                print(f"wrote {args.json}")
            if args.export:
                from ehas_env.identification.export import write_model

                print(f"wrote {write_model(args.export, num_arr, den_arr)}")
            return 0

    data = ID.read_columns(args.run, args.input, args.output)
    validation = None
    if args.validate:
        try:
            validation = ID.read_columns(args.validate, args.input, args.output)
        except (ValueError, OSError) as exc:
            raise ValueError(f"--validate: {exc}") from None
    T = data.n * data.dt
    if isinstance(args.delay, float) and args.delay > 0.5 * T:
        raise ValueError(f"--delay must be at most half the run ({0.5 * T:.6g} s), got {args.delay:g} s")
    if args.max_delay is not None and args.max_delay > 0.5 * T:
        raise ValueError(f"--max-delay must be at most half the run ({0.5 * T:.6g} s), got {args.max_delay:g} s")
    unc = None
    if given is not None:
        y_sim = ID.simulate_tf(given, data.t, data.u, intersample=args.intersample, delay_s=args.delay)
        est = ID.TFEstimate(tf=given, num=num_arr, den=den_arr, n_poles=len(den) - 1,
                            n_zeros=len(np.trim_zeros(num_arr, "f")) - 1, fit_percent=ID.fit_percent(data.y, y_sim),
                            data=data, y_sim=y_sim, intersample=args.intersample, x0=np.zeros(len(den) - 1),
                            delay_s=float(args.delay))
        print(f"fit on {args.run}: {est.fit_percent:.2f} % (NRMSE, {args.intersample} input)")
    else:
        est = ID.tfest(data, n_poles=args.poles, n_zeros=args.zeros, intersample=args.intersample,
                       initial_state=args.initial_state, offsets=args.offsets, delay=args.delay,
                       max_delay_s=args.max_delay)
        if not est.usable():
            # too many poles and zeros for what the run holds: the fit ends at an unstable or diverging model
            raise ValueError(f"--poles {args.poles} --zeros {args.zeros}: the fit to {args.run} ends at an unstable "
                             "model (more poles and zeros than the run determines); give fewer")
        print(est.summary())
        from ehas_env.identification.uncertainty import covariance

        unc = covariance(est, coloured=args.covariance)
        print(unc.summary())
    ra = ID.residual_analysis(est.residuals, data.u, max_lag=min(args.max_lag, data.n - 1))
    print(f"  {ra.verdict()}")
    from ehas_env.identification import checks

    loop = checks.closed_loop_evidence(ra, checks.sidecar_of(args.run))
    if loop["suspected"]:
        import sys

        print(f"ehas identify: {checks.warning_line(loop)}", file=sys.stderr)
    extra = {"structure": "tf", "residual_tests": _residual_tests(ra), "closed_loop": loop}
    if unc is not None:
        extra["ci95"] = unc.ci95
        extra["covariance"] = unc.to_json_dict()
        ci = unc.ci95
        extra["offsets"] = {"input": est.input_offset, "output": est.output_offset, "unit_input": data.input_name,
                            "unit_output": data.output_name, "estimated": args.offsets,
                            "ci95": {k: ci[f"{k}_offset"] for k in ("input", "output") if f"{k}_offset" in ci}}
        extra["delay_s"] = {"value": est.delay_s, "ci95": ci.get("delay_s"), "estimated": args.delay == "estimate"}
    else:
        extra.update(ci95=None, delay_s={"value": est.delay_s, "ci95": None, "estimated": False})
    if validation is not None:
        y_val = est.simulate(validation.t, validation.u)
        vfit = ID.fit_percent(validation.y, y_val)
        print(f"  validation on {args.validate}: fit = {vfit:.2f} % (simulated from rest)")
        extra["validation"] = {"run": args.validate, "fit_percent": float(vfit)}
    if args.predict:
        from ehas_env.identification.orders import fit_ar, predict

        c = fit_ar(est.residuals)
        pfit = ID.fit_percent(data.y, predict(est, args.predict, ar=c))
        print(f"  {args.predict}-step-ahead prediction fit = {pfit:.2f} % beside simulation fit {est.fit_percent:.2f} % "
              f"(noise model AR({c.size}) of the residuals)")
        extra["prediction"] = {"steps": args.predict, "fit_percent": float(pfit), "ar_order": int(c.size),
                               "simulation_fit_percent": float(est.fit_percent)}
        if validation is not None:
            pv = ID.fit_percent(validation.y, predict(est, args.predict, validation.t, validation.u, validation.y, ar=c))
            extra["prediction"]["validation_fit_percent"] = float(pv)
    table = None
    if args.orders:
        from ehas_env.identification.orders import order_table, parse_orders

        table = order_table(data, parse_orders(args.orders), validation=validation, intersample=args.intersample,
                            delay=args.delay, offsets=args.offsets, predict_k=args.predict,
                            max_delay_s=args.max_delay, black_box=args.compare or (),
                            nk=args.nk if args.nk is not None else DEFAULT_ORDERS["nk"])
        print(table.markdown())
        extra["orders"] = table.to_json_dict()
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
        atomic_write_text(args.json, json.dumps({**est.to_json_dict(), **extra}, indent=2) + "\n")
        print(f"wrote {args.json}")
    if args.export:
        from ehas_env.identification.export import write_model

        info = {k: v for k, v in est.to_json_dict().items() if k in ("K", "wn", "zeta", "fit_percent")}
        if unc is not None:
            info["ci95"] = unc.ci95
        print(f"wrote {write_model(args.export, est.num, est.den, delay_s=est.delay_s, input_offset=est.input_offset, output_offset=est.output_offset, input_name=data.input_name, output_name=data.output_name, extra=info)}")
    if outputs is not None:
        label = f"{est.n_poles}p{est.n_zeros}z"
        summary = [est.summary(), *([unc.summary()] if unc is not None else []), f"  {ra.verdict()}"]
        _write_report(outputs, args, command, est, est.tf, label, f"residuals of the {label} model", ra, summary,
                      loop, table, data, validation)
    return 0


def _check_structure(args) -> None:
    """The options of ``--structure`` and its orders, one line each (before any work); fills the defaults."""
    given = {n: getattr(args, n) for n in ORDER_FLAGS if getattr(args, n) is not None}
    if args.structure == "tf":
        for name in given:
            if name == "nk" and args.compare:
                continue
            raise ValueError(f"--{name} goes with a black-box --structure ({', '.join(s for s in STRUCTURES if name in ORDERS[s])}); "
                             f"the transfer function (--structure tf) takes --poles and --zeros")
        args.poles = 2 if args.poles is None else args.poles
        args.zeros = 0 if args.zeros is None else args.zeros
        return
    s = args.structure
    for flag, bad in (("--num/--den", args.num is not None or args.den is not None),
                      ("--poles", args.poles is not None), ("--zeros", args.zeros is not None),
                      ("--delay", args.delay != 0.0), ("--max-delay", args.max_delay is not None),
                      ("--intersample", args.intersample != "zoh"), ("--initial-state", args.initial_state != "zero"),
                      ("--covariance", args.covariance != "auto"), ("--timing", args.timing)):
        if bad:
            hint = {"--delay": "; give the input delay in samples with --nk", "--poles": f"; its orders are "
                    f"{', '.join('--' + n for n in ORDERS[s])}", "--zeros": f"; its orders are "
                    f"{', '.join('--' + n for n in ORDERS[s])}"}.get(flag, "")
            raise ValueError(f"{flag} applies to --structure tf, not to --structure {s}{hint}")
    from ehas_env.identification.pem import check_orders

    args.orders_of_structure = check_orders(s, given, where="--")
    if s == "ss":
        from ehas_env.identification.pem import _import_nfoursid

        try:
            _import_nfoursid()
        except ValueError:
            raise ValueError("--structure ss needs the optional package nfoursid: pip install 'ehas[ident]'") from None


def _run_black_box(args, command: str, outputs) -> int:
    """``--structure arx|armax|oe|bj|ss``: the discrete-time model, its fit, residual tests, table, files."""
    import json
    import sys
    from types import SimpleNamespace

    import numpy as np

    from ehas_env.identification import checks
    from ehas_env.identification import fit as ID
    from ehas_env.identification.pem import estimate
    from ehas_env.output.files import atomic_write_text

    data = ID.read_columns(args.run, args.input, args.output)
    validation = None
    if args.validate:
        try:
            validation = ID.read_columns(args.validate, args.input, args.output)
        except (ValueError, OSError) as exc:
            raise ValueError(f"--validate: {exc}") from None
    # operating point: the run's means (MATLAB detrend(z, 0)) when asked for
    u0 = float(np.mean(data.u)) if args.offsets == "estimate" else 0.0
    y0 = float(np.mean(data.y)) if args.offsets in ("output", "estimate") else 0.0
    m = estimate(args.structure, data.u - u0, data.y - y0, args.orders_of_structure, dt=data.dt)
    y_sim = m.simulate(data.u - u0) + y0
    fit = ID.fit_percent(data.y, y_sim)
    print(m.summary())
    if args.offsets != "none":
        print(f"  offsets (the run's means, removed before the fit): input {u0:.6g} "
              f"{ID.signal_unit(data.input_name)}, output {y0:.6g} {ID.signal_unit(data.output_name)}")
    ra = ID.residual_analysis(m.residuals, data.u - u0, max_lag=min(args.max_lag, data.n - 1))
    print(f"  {ra.verdict()} (one-step prediction errors)")
    loop = checks.closed_loop_evidence(ra, checks.sidecar_of(args.run))
    if loop["suspected"]:
        print(f"ehas identify: {checks.warning_line(loop)}", file=sys.stderr)
    G = m.tf()
    result = {**m.to_json_dict(), "fit_percent": float(fit), "command": command,
              "tf_z": {"num": [float(v) for v in np.squeeze(G.num[0][0])],
                       "den": [float(v) for v in np.squeeze(G.den[0][0])], "dt": float(data.dt)},
              "offsets": {"input": u0, "output": y0, "estimated": args.offsets},
              "residual_tests": _residual_tests(ra), "closed_loop": loop}
    if validation is not None:
        vfit = ID.fit_percent(validation.y, m.simulate(validation.u - u0) + y0)
        print(f"  validation on {args.validate}: fit = {vfit:.2f} % (simulated from rest)")
        result["validation"] = {"run": args.validate, "fit_percent": float(vfit)}
    if args.predict:
        pfit = ID.fit_percent(data.y, m.predict(data.u - u0, data.y - y0, args.predict) + y0)
        print(f"  {args.predict}-step-ahead prediction fit = {pfit:.2f} % beside simulation fit {fit:.2f} % "
              f"(the model's own noise model)")
        result["prediction"] = {"steps": args.predict, "fit_percent": float(pfit), "simulation_fit_percent": float(fit)}
        if validation is not None:
            pv = ID.fit_percent(validation.y, m.predict(validation.u - u0, validation.y - y0, args.predict) + y0)
            result["prediction"]["validation_fit_percent"] = float(pv)
    table = None
    if args.orders:
        from ehas_env.identification.orders import order_table, parse_orders

        table = order_table(data, parse_orders(args.orders), validation=validation, offsets=args.offsets,
                            predict_k=args.predict, black_box=args.compare or [args.structure],
                            nk=args.orders_of_structure.get("nk", DEFAULT_ORDERS["nk"]))
        print(table.markdown())
        result["orders"] = table.to_json_dict()
    if args.json:
        atomic_write_text(args.json, json.dumps(result, indent=2) + "\n")
        print(f"wrote {args.json}")
    if args.export:
        from ehas_env.identification.export import write_model

        print(f"wrote {write_model(args.export, result['tf_z']['num'], result['tf_z']['den'], dt=data.dt, input_offset=u0, output_offset=y0, input_name=data.input_name, output_name=data.output_name, extra={'model': m.to_json_dict()})}")
    if outputs is not None:
        shown = SimpleNamespace(data=data, y_sim=y_sim, fit_percent=fit, residuals=data.y - y_sim)
        _write_report(outputs, args, command, shown, G, m.label, f"one-step prediction errors of the {m.label} model",
                      ra, [m.summary(), f"  {ra.verdict()} (one-step prediction errors)"], loop, table, data, validation)
    return 0


def _write_report(outputs, args, command, shown, model, label, resid_title, ra, summary, loop, table, data,
                  validation) -> None:
    """The plots and ``identify.md`` of one identified model (any structure) into the ``--out`` folder.

    Parameters
    ----------
    outputs : Outputs
        The ``--out`` folder, written as a whole (``ehas_env.output.outputs``).
    args : argparse.Namespace
        The command's options (the run's name).
    command : str
        The command line that regenerates the report.
    shown : object
        What the overlay plots: ``data``, ``y_sim``, ``fit_percent``, ``residuals``.
    model : control.TransferFunction
        The model the Bode plot shows.
    label : str
        The model's short name (``2p0z``, ``ARX [2 2 1]``).
    resid_title : str
        What the residual plot shows.
    ra : ResidualAnalysis
        The residual analysis.
    summary : list of str
        The text block of the report.
    loop : dict
        The closed-loop check (``checks``).
    table : OrderTable or None
        The structures compared (``--orders``), if any.
    data, validation : IdData
        The estimation data and the validation data (None: the estimation data).
    """
    from ehas_env.output.files import atomic_write_text
    from ehas_env.identification import checks
    from ehas_env.output.identification_plots import plot_bode, plot_overlay, plot_residuals

    name = Path(args.run).name
    with outputs as out:
        files = [plot_overlay(shown, out / "overlay.png", title=f"{name}: {label} model"),
                 plot_bode([(label, model)], out / "bode.png", data=data,
                           title=f"{name}: {label} model and the data's spectral estimate"),
                 plot_residuals(ra, out / "residuals.png", title=f"{name}: {resid_title}")]
        if table is not None:
            from ehas_env.output.identification_plots import plot_compare, plot_orders

            files.append(plot_orders(table, out / "orders.png", title=f"{name}: structures compared"))
            files.append(plot_compare(table, data if validation is None else validation, out / "compare.png",
                                      title=f"{name}: the models on the validation data"))
        md = [f"# Identification of {args.run}", "", f"Regenerate: `{command}`", "", "```", *summary, "```", ""]
        if loop["suspected"]:
            md += [checks.warning_line(loop), ""]
        if table is not None:
            md += ["## Structures", "", table.markdown(), ""]
        md += ["Files: " + ", ".join(f"`{f.name}`" for f in files), ""]
        files.append(atomic_write_text(out / "identify.md", "\n".join(md)))
    print(f"wrote {', '.join(str(outputs.path / f.name) for f in files)}")


def _residual_tests(ra) -> dict:
    """The residual analysis as JSON: autocorrelation and input cross-correlation, 99 % bands, verdicts."""
    allowed_a = max(1, round(0.01 * ra.lags.size))
    allowed_c = max(1, round(0.01 * ra.cross_lags.size))
    return {"confidence": 0.99, "samples": ra.n, "max_lag": int(ra.lags[-1]),
            "autocorrelation": {"lags": ra.lags.tolist(), "values": [float(v) for v in ra.auto],
                                "band": float(ra.auto_band), "outside": ra.auto_outside(), "allowed": allowed_a,
                                "pass": ra.auto_outside() <= allowed_a},
            "cross_correlation": {"lags": ra.cross_lags.tolist(), "values": [float(v) for v in ra.cross],
                                  "band": float(ra.cross_band), "outside": ra.cross_outside(),
                                  "allowed": allowed_c, "pass": ra.cross_outside() <= allowed_c},
            "verdict": ra.verdict()}


# ---------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------
