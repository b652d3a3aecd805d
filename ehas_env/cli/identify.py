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
    from ehas_env.cli.options import number

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

    from ehas_env.cli.options import split_list

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

def _save(fig, path) -> Path:
    from ehas_env.output.plots import save_figure

    fig.tight_layout()
    return save_figure(fig, path)


def _output_unit(name: str) -> str:
    """``flow_lpm`` -> ``LPM``; names without a unit suffix -> ``""``."""
    units = {"lpm": "LPM", "ma": "mA", "deg": "deg", "bar": "bar", "kn": "kN", "s": "s"}
    return units.get(name.rsplit("_", 1)[-1].lower(), "") if "_" in name else ""


def plot_overlay(est, path, title: str = "", zoom_s: float | None = None) -> Path:
    """Measured and simulated output: the whole record, a zoom on its last part, and the residual.

    The measurement is drawn first, thick and grey, the model thin on top, so
    neither hides the other; the zoom (``zoom_s``, default a tenth of the
    record, at least 0.5 s) shows how the model follows the measured wave.
    """
    import numpy as np

    from ehas_env.output.plots import _pyplot

    plt = _pyplot()
    d = est.data
    unit = _output_unit(d.output_name)
    ulab = f" [{unit}]" if unit else ""
    t = np.asarray(d.t)
    span = t[-1] - t[0]
    zoom_s = zoom_s or max(0.1 * span, min(0.5, span))
    zsel = t >= t[-1] - zoom_s
    fig = plt.figure(figsize=(12, 6.6))
    gs = fig.add_gridspec(2, 2, height_ratios=[2.2, 1.0], width_ratios=[1.7, 1.0], hspace=0.3, wspace=0.15)
    ax_full, ax_zoom, ax_res = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[0, 1]), fig.add_subplot(gs[1, :])
    for ax, sel in ((ax_full, slice(None)), (ax_zoom, zsel)):
        ax.plot(t[sel], d.y[sel], color="0.55", lw=2.2, label=f"measured {d.output_name}")
        ax.plot(t[sel], est.y_sim[sel], color="tab:blue", lw=0.8, label=f"model (fit {est.fit_percent:.1f} %)")
        ax.grid(alpha=0.25)
        ax.set_xlabel("t [s]")
    ax_full.axvspan(t[-1] - zoom_s, t[-1], color="gold", alpha=0.25, lw=0)
    ax_full.set_ylabel(f"{d.output_name}{ulab}")
    ax_full.legend(loc="upper right", fontsize=8)
    ax_full.set_title("whole record (gold: the zoom)", fontsize=9)
    ax_zoom.set_title(f"zoom: last {zoom_s:.2g} s", fontsize=9)
    ax_res.plot(t, est.residuals, lw=0.6, color="tab:red")
    ax_res.axhline(0.0, color="0.4", lw=0.6)
    ax_res.set_ylabel(f"measured - model{ulab}")
    ax_res.set_xlabel("t [s]")
    ax_res.grid(alpha=0.25)
    if title:
        fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def spectral_estimate(data, nperseg: int | None = None):
    """Non-parametric frequency response of the data, H = P_uy / P_uu (Welch), and its coherence.

    Returns (f Hz, H complex, coherence); use only where the coherence is high.
    """
    import numpy as np
    from scipy import signal

    fs = 1.0 / data.dt
    nperseg = nperseg or int(min(data.n, max(256, 2 ** int(np.log2(data.n / 4)))))
    f, puu = signal.welch(data.u, fs=fs, nperseg=nperseg)
    _, puy = signal.csd(data.u, data.y, fs=fs, nperseg=nperseg)
    _, coh = signal.coherence(data.u, data.y, fs=fs, nperseg=nperseg)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = puy / puu
    # the measured output at t_k reflects the input held over the previous sample: undo that half-sample
    h = h * np.exp(1j * np.pi * f / fs)
    return f, h, coh


def plot_bode(models, path, data=None, title: str = "", f_range=None, coherence_min: float = 0.9) -> Path:
    """Bode plot of ``[(label, TransferFunction), ...]``, with the data's spectral estimate if given."""
    import numpy as np

    from ehas_env.output.plots import _pyplot

    plt = _pyplot()
    fig, ax = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    lo, hi = f_range or (0.1, 200.0)
    if data is not None:
        f, h, coh = spectral_estimate(data)
        ok = (coh >= coherence_min) & (f > 0) & (f <= 0.5 / data.dt)
        if ok.any():
            ax[0].semilogx(f[ok], 20 * np.log10(np.abs(h[ok])), ".", ms=3, color="0.5",
                           label=f"data (Welch, coherence >= {coherence_min:g})")
            ax[1].semilogx(f[ok], np.degrees(np.unwrap(np.angle(h[ok]))), ".", ms=3, color="0.5")
        hi = min(hi, 0.5 / data.dt)
    f = np.geomspace(lo, hi, 400)
    # the first model wide and solid, the others thinner with their own dashes: curves that
    # coincide (a fit on its truth) stay visible one over the other
    styles = [dict(lw=3.0, ls="-", alpha=0.55), dict(lw=1.6, ls="--"), dict(lw=1.6, ls="-."), dict(lw=1.6, ls=":"),
              dict(lw=1.3, ls=(0, (6, 2, 1, 2)))]
    for k, (label, sys_) in enumerate(models):
        num, den = np.squeeze(sys_.num[0][0]), np.squeeze(sys_.den[0][0])
        g = np.polyval(np.atleast_1d(num), 2j * np.pi * f) / np.polyval(np.atleast_1d(den), 2j * np.pi * f)
        st = styles[k % len(styles)]
        ax[0].semilogx(f, 20 * np.log10(np.abs(g)), label=label, color=f"C{k}", **st)
        ax[1].semilogx(f, np.degrees(np.unwrap(np.angle(g))), label=label, color=f"C{k}", **st)
    ax[0].set_ylabel("magnitude, dB")
    ax[1].set_ylabel("phase, deg")
    ax[1].set_xlabel("frequency, Hz")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
    ax[0].legend(loc="lower left", fontsize=8)
    if title:
        ax[0].set_title(title, fontsize=10)
    return _save(fig, path)


def plot_residuals(ra, path, title: str = "") -> Path:
    """MATLAB-``resid``-style figure: residual autocorrelation and input cross-correlation, 99 % bands."""
    from ehas_env.output.plots import _pyplot

    plt = _pyplot()
    fig, ax = plt.subplots(2, 1, figsize=(8, 6))
    ax[0].stem(ra.lags, ra.auto, basefmt=" ")
    ax[0].axhspan(-ra.auto_band, ra.auto_band, color="C0", alpha=0.15, label="99 % band (white)")
    ax[0].set_ylabel("autocorrelation of residuals")
    ax[0].set_xlabel("lag, samples")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[1].stem(ra.cross_lags, ra.cross, basefmt=" ")
    ax[1].axhspan(-ra.cross_band, ra.cross_band, color="C0", alpha=0.15, label="99 % band (independent)")
    ax[1].set_ylabel("cross-corr. input -> residual")
    ax[1].set_xlabel("lag, samples (> 0: residual after input)")
    ax[1].legend(loc="upper right", fontsize=8)
    ax[0].set_title((title + "\n" if title else "") + ra.verdict(), fontsize=9)
    return _save(fig, path)
