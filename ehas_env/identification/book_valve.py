"""The book's valve identification (chapter 5), reproduced in simulation.

The book identified its servo valve twice on the flow bench (+-20 mA, 70 bar,
ports joined through the flow meter):

* chirp 0.5-2 Hz: Q/i = 14567.29 / (s^2 + 147.83 s + 11449.86), fit 95.4 % (2p0z),
  89.3 % (2p1z);
* pseudo-random multilevel signal (PRMS): 217400 / (s^2 + 1114 s + 166300),
  fit 81.4 % (2p0z), 81.3 % (2p1z) - rejected as a poor fit.

Here the valve's *truth* is the book's chirp model (the project's grey-box
valve, :class:`ehas_env.simulation.plant.Plant`), excited as the book did, logged
through a noisy flow meter, and identified with :func:`ehas_env.identification.fit.tfest`.
Two noise levels: the sensor model's turbine meter (0.05 LPM, 16-bit ADC) and
a "book-level" noise whose standard deviation is set so that the true model's
own fit to the book's chirp run equals the book's 95.4 % (everything the rig's
residual held: meter noise, pulsation, unmodelled effects).

Run ``python -m ehas_env.identification.book_valve`` (about a minute); it writes
``results/identification/README.md`` (tables, findings, the command) and its figures.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

from ehas_env.book.tables import read_rows
from ehas_env.identification.excitation import Excitation, chirp, multisine, prms
from ehas_env.identification.fit import fit_percent, prepare, second_order_parameters, simulate_tf, tfest

SUPPLY_BAR = 70.0  # rated flow-bench test (docs/rig.md)
BOOK_CHIRP_FIT = 95.4  # %, the book's 2p0z chirp fit (valve_identification.csv)
DURATION = 10.0  # s per run (assumed: the book does not give its record length); 10 000 samples at 1 kHz


def book_models() -> list[dict]:
    """The book's identified models (ehas_env/book/data/valve_identification.csv), with K, wn, zeta.

    Examples
    --------
    >>> m = book_models()[0]
    >>> m["excitation"], round(m["K"], 3), round(m["wn"], 1), round(m["zeta"], 3)
    ('chirp_0.5-2Hz_20mA', 1.272, 107.0, 0.691)
    """
    out = []
    for row in read_rows("valve_identification.csv"):
        rec = {"excitation": row["excitation"], "poles": int(row["poles"]), "zeros": int(row["zeros"]),
               "fit_percent": float(row["fit_percent"])}
        if row["b0"]:
            num, den = [float(row["b0"])], [1.0, float(row["a1"]), float(row["a0"])]
            rec.update(num=num, den=den, **second_order_parameters(num, den))
        out.append(rec)
    return out


def truth():
    """The simulated valve's transfer function at the rated drop: the book's chirp model, LPM/mA."""
    import control

    m = book_models()[0]
    return control.tf(m["num"], m["den"])


def valve_run(signal: Excitation, noise_lpm: float, seed: int):
    """(clean flow, logged flow) of the grey-box valve on the 70 bar bench for ``signal``."""
    from ehas_env.simulation.plant import Plant
    from ehas_env.simulation.sensors import Sensors

    sensors = dataclasses.replace(Sensors(), flow_noise_lpm=noise_lpm)
    res = Plant(sensors=sensors, seed=seed).simulate_valve_test(signal.current_mA, supply_bar=SUPPLY_BAR)
    return res.flow_lpm, res.logged["flow_lpm"]


def book_noise_level() -> float:
    """Flow noise std (LPM) at which the true model's fit on the book's chirp run is the book's 95.4 %.

    For white noise the NRMSE of the true model is sigma / std(y), so
    sigma = (1 - 0.954) std(y_clean).
    """
    y, _ = valve_run(book_chirp(), 0.0, 0)
    return (1.0 - BOOK_CHIRP_FIT / 100.0) * float(np.std(y))


def book_chirp() -> Excitation:
    return chirp(DURATION, f0=0.5, f1=2.0, amplitude=20.0)


def signals() -> dict[str, Excitation]:
    """The excitations compared: the book's two and better ones."""
    return {
        "book chirp 0.5-2 Hz, +-20 mA": book_chirp(),
        "book-like PRMS +-20 mA, 1 ms clock": prms(DURATION, amplitude=20.0, hold=0.001, levels=5, seed=1),
        "PRMS +-20 mA, 10 ms clock": prms(DURATION, amplitude=20.0, hold=0.01, levels=5, seed=1),
        "PRMS +-15 mA, 10 ms clock": prms(DURATION, amplitude=15.0, hold=0.01, levels=5, seed=1),
        "log chirp 0.5-40 Hz, +-15 mA": chirp(DURATION, f0=0.5, f1=40.0, amplitude=15.0, method="log"),
        "multisine 0.5-40 Hz, +-15 mA": multisine(DURATION, f0=0.5, f1=40.0, amplitude=15.0, lines=40),
    }


def _params(est) -> dict:
    den, num = est.den, est.num
    wn = math.sqrt(den[2])
    return {"K": float(num[-1] / den[-1]), "wn": wn, "zeta": float(den[1] / (2 * wn)), "fit": est.fit_percent}


def _fmt_tf(num, den) -> str:
    n = " ".join(f"{v:+.5g}" for v in num)
    return f"[{n}] / [1 {den[1]:+.5g} {den[2]:+.5g}]"


def study(out: Path, seeds: int = 10, quiet: bool = False) -> Path:
    """Run every experiment and write ``out/README.md`` and figures; returns the README path."""
    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.identification_plots import plot_bode, plot_overlay
    from ehas_env.output.progress import bar, status

    def step(what):
        if not quiet:
            status(what, "book_valve")

    step(f"the book's valve identification, about 30 s on two cores: writing {out}")

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    G = truth()
    K0, wn0, z0 = (second_order_parameters(G.num[0][0], G.den[0][0])[k] for k in ("K", "wn", "zeta"))
    sig_meter = 0.05
    sig_book = book_noise_level()
    sigs = signals()
    book = book_models()
    md: list[str] = []
    cmd = "python -m ehas_env.identification.book_valve" + (f" --out {out}" if str(out) != "results/identification" else "") + \
          (f" --seeds {seeds}" if seeds != 10 else "")
    md += ["# The book's valve identification, reproduced", "",
           f"Regenerate everything in this folder: `{cmd}` (identification: `ehas_env/identification/fit.py`; "
           f"a single fit from the command line: `ehas excite ...` then `ehas identify RUN.csv --poles 2 --zeros 0`).",
           "",
           "Truth: the book's chirp model (the project's grey-box valve) on the 70 bar flow bench, ports joined "
           "through the meter, 1 kHz sampling, 10 s records (10 000 samples; the book gives no record length). "
           f"Noise: the turbine meter of `Sensors` ({sig_meter:g} LPM, 16-bit ADC), or *book-level* noise "
           f"{sig_book:.3f} LPM std, set so that the true model itself fits the book's chirp run at the book's "
           f"{BOOK_CHIRP_FIT} %. Fits: output error, zero-order-hold input, start at rest.", ""]

    # -- 1. the book's own coefficients --------------------------------------
    md += ["## 1. K, wn, zeta from the book's own coefficients", "",
           "`ehas identify --num 14567.29 --den 1,147.83,11449.86`", "",
           "| book model | fit (book) | K, LPM/mA | wn, rad/s | zeta | poles, rad/s |", "|---|---|---|---|---|---|"]
    for m in book:
        if "num" in m:
            poles = ", ".join(f"{p:.4g}" for p in np.roots(m["den"]))
            md.append(f"| {m['excitation']} {m['poles']}p{m['zeros']}z: `{_fmt_tf(m['num'], m['den'])}` | "
                      f"{m['fit_percent']} % | {m['K']:.3f} | {m['wn']:.1f} | {m['zeta']:.3f} | {poles} |")
    md += ["", "The book's text says wn = 132 rad/s; its transfer function gives 107.0 rad/s (docs/rig.md: use the "
           "transfer function). The PRMS model is overdamped (zeta 1.37): two real poles.", ""]

    # -- 2. the book's experiments, one realisation ----------------------------
    step("1/5 chirp and PRMS experiments, fits with 2 poles, 0 and 1 zeros")
    book_prms_tf = None
    for m in book:
        if m["excitation"].startswith("prms") and "num" in m:
            import control

            book_prms_tf = control.tf(m["num"], m["den"])
    md += ["## 2. The book's two experiments, simulated (book-level noise, seed 0)", "",
           "| excitation | model | K, LPM/mA | wn, rad/s | zeta | fit % | true model's fit % | static gain's fit % | "
           "book's PRMS model's fit % | std(flow)/noise |", "|---|---|---|---|---|---|---|---|---|---|"]
    overlay_runs = {}
    nested_ok = True
    prms_model_fit, fitted_fit = {}, {}
    for name in ("book chirp 0.5-2 Hz, +-20 mA", "book-like PRMS +-20 mA, 1 ms clock"):
        sig = sigs[name]
        y_clean, y = valve_run(sig, sig_book, 0)
        true_fit = fit_percent(y, y_clean)
        static = tfest(sig.t, sig.current_mA, y, 0, 0)
        prms_fit = fit_percent(y, simulate_tf(book_prms_tf, sig.t, sig.current_mA)) if book_prms_tf else float("nan")
        fits = {}
        for nz in (0, 1):
            est = tfest(prepare(sig.t, sig.current_mA, y, input_name="current_mA", output_name="flow_lpm"),
                        n_poles=2, n_zeros=nz)
            fits[nz] = est.fit_percent
            p = _params(est)
            zero = f", zero {est.zeros()[0]:.4g}" if nz else ""
            md.append(f"| {name} | 2p{nz}z{zero} | {p['K']:.4f} | {p['wn']:.1f} | {p['zeta']:.3f} | "
                      f"{p['fit']:.1f} | {true_fit:.1f} | {static.fit_percent:.1f} | {prms_fit:.1f} | "
                      f"{np.std(y_clean) / sig_book:.1f} |")
            if nz == 0:
                overlay_runs[name] = est
                prms_model_fit[name], fitted_fit[name] = prms_fit, est.fit_percent
        nested_ok &= fits[1] >= fits[0] - 1e-6
    md += ["", f"Truth: K = {K0:.4f} LPM/mA, wn = {wn0:.1f} rad/s, zeta = {z0:.3f}. For 2p1z models K is the DC "
           "gain and wn, zeta those of the denominator.", ""]

    # -- 3. PRMS clock sweep -------------------------------------------------
    step("2/5 PRMS clock sweep (7 clock periods)")
    holds = [0.001, 0.002, 0.003, 0.005, 0.01, 0.02, 0.05]
    sweep = []
    for hold in holds:
        sig = prms(DURATION, amplitude=20.0, hold=hold, levels=5, seed=1)
        y_clean, y = valve_run(sig, sig_book, 0)
        est = tfest(sig.t, sig.current_mA, y, 2, 0)
        at_stop = float(np.mean(np.abs(y_clean) >= 20.0 * K0 * math.sqrt(SUPPLY_BAR / 70.0) * (1 - 1e-9)))
        sweep.append((hold, float(np.std(y_clean)), fit_percent(y, y_clean), est.fit_percent, _params(est), at_stop))
    md += ["## 3. PRMS +-20 mA: fit % against the clock period (book-level noise)", "",
           "| clock, ms | std(flow), LPM | true model's fit % | fitted 2p0z fit % | K | wn | zeta | time at spool stops |",
           "|---|---|---|---|---|---|---|---|"]
    for hold, sd, tf_fit, e_fit, p, stop in sweep:
        md.append(f"| {hold * 1e3:g} | {sd:.2f} | {tf_fit:.1f} | {e_fit:.1f} | {p['K']:.4f} | {p['wn']:.1f} | "
                  f"{p['zeta']:.3f} | {100 * stop:.1f} % |")
    md.append("")

    # -- 4. Monte Carlo over noise seeds --------------------------------------
    rows = {}
    it = [(name, lvl, s) for name in sigs for lvl in ("book", "meter") for s in range(seeds)]
    step(f"3/5 Monte Carlo: {len(it)} fits")
    for name, lvl, s in bar(it, desc="[book_valve] Monte Carlo fits", unit="fit", disable=quiet):
        sig = sigs[name]
        _, y = valve_run(sig, sig_book if lvl == "book" else sig_meter, 100 + s)
        p = _params(tfest(sig.t, sig.current_mA, y, 2, 0))
        rows.setdefault((name, lvl), []).append(p)
    md += [f"## 4. Which excitation identifies the valve: {seeds} noise realisations per cell, 2p0z", "",
           "Error of the estimate against the truth, mean +- std over the realisations, in %.", "",
           "| excitation | noise | K error % | wn error % | zeta error % | fit % |", "|---|---|---|---|---|---|"]
    for (name, lvl), ps in rows.items():
        e = {k: np.array([100 * (p[k] / ref - 1) for p in ps]) for k, ref in (("K", K0), ("wn", wn0), ("zeta", z0))}
        fits = np.array([p["fit"] for p in ps])
        md.append(f"| {name} | {'book-level' if lvl == 'book' else 'meter'} | {e['K'].mean():+.2f} +- {e['K'].std():.2f} | "
                  f"{e['wn'].mean():+.2f} +- {e['wn'].std():.2f} | {e['zeta'].mean():+.2f} +- {e['zeta'].std():.2f} | "
                  f"{fits.mean():.1f} |")
    md.append("")

    # -- 5. timing -------------------------------------------------------------
    step("4/5 timing the fit")
    sig = sigs["book chirp 0.5-2 Hz, +-20 mA"]
    _, y = valve_run(sig, sig_book, 0)
    timing = {}
    for nz in (0, 1):
        tfest(sig.t, sig.current_mA, y, 2, nz)  # warm (numba's compiled code is cached on disk)
        ts = []
        for _ in range(5):
            t0 = time.perf_counter()
            tfest(sig.t, sig.current_mA, y, 2, nz)
            ts.append(time.perf_counter() - t0)
        timing[nz] = ts
    md += ["## 5. Speed: identification of a 10 000-sample run", "",
           "| model | median wall time, s | min | max | target |", "|---|---|---|---|---|"]
    for nz, ts in timing.items():
        md.append(f"| 2p{nz}z, book chirp, 10 000 samples | {np.median(ts):.3f} | {min(ts):.3f} | {max(ts):.3f} | "
                  f"< 2 s: {'met' if np.median(ts) < 2 else 'MISSED'} |")
    md += ["", "Five repeats after one warm-up fit, on this machine (2 cores shared with other jobs).", ""]

    # -- findings -------------------------------------------------------------
    chirp_static = None
    for line in md:
        if line.startswith("| book chirp 0.5-2 Hz, +-20 mA | 2p0z"):
            chirp_static = line.split("|")[8].strip()
    prms1 = sweep[0]
    mc = {k: v for k, v in rows.items()}

    def spread(name, key, ref, lvl="book"):
        arr = np.array([100 * (p[key] / ref - 1) for p in mc[(name, lvl)]])
        return float(np.sqrt(np.mean(arr**2)))

    chirp_wn = spread("book chirp 0.5-2 Hz, +-20 mA", "wn", wn0)
    chirp_z = spread("book chirp 0.5-2 Hz, +-20 mA", "zeta", z0)
    prms_wn = spread("book-like PRMS +-20 mA, 1 ms clock", "wn", wn0)
    ranking = []
    for name in sigs:
        ew, ez = spread(name, "wn", wn0), spread(name, "zeta", z0)
        ranking.append((name, ew, ez))
    ranking.sort(key=lambda r: math.hypot(r[1], r[2]))
    stop10 = next(sw[5] for sw in sweep if sw[0] == 0.01)

    def mean_err(name, key, ref):
        return float(np.mean([100 * (p[key] / ref - 1) for p in mc[(name, "book")]]))

    k20 = mean_err("PRMS +-20 mA, 10 ms clock", "K", K0)
    k15 = mean_err("PRMS +-15 mA, 10 ms clock", "K", K0)
    md += ["## Findings", "",
           f"1. **The PRMS fit % was poor because of where a fast PRMS puts its power, not because the model was "
           f"poor.** A +-20 mA PRMS clocked at 1 ms spreads its power flat to ~440 Hz, far above the valve's "
           f"17 Hz bandwidth, so the valve's flow varies little (std {prms1[1]:.1f} LPM against "
           f"{np.std(valve_run(book_chirp(), 0.0, 0)[0]):.1f} LPM for the chirp) and the same noise takes a "
           f"large share of the NRMSE. With book-level noise the *true* model scores only {prms1[2]:.1f} % on that "
           f"run, and clocks of 1-2 ms give {sweep[0][2]:.0f}-{sweep[1][2]:.0f} % (table 3), bracketing the book's "
           "81.4 %. The parameters fitted to the same data are still close to the truth (tables 2 and 4): fit % "
           "measures how well the noisy record is predicted, and is not comparable between excitations.",
           f"2. **The book's PRMS model itself does not describe a valve whose truth is the book's chirp model**: "
           "on the simulated runs it scores " + " and ".join(
               f"{prms_model_fit[n]:.1f} % on the {n.split(',')[0]} run (the fitted 2p0z: {fitted_fit[n]:.1f} %)"
               for n in prms_model_fit) + " (table 2). An output-error fit of PRMS data from that valve returns the chirp model's parameters, not "
           "wn = 408 rad/s, zeta = 1.37; so the two book models cannot both describe one linear valve, and the "
           "book's PRMS estimate is more likely an estimator artefact (its start or convergence) than a property "
           "of the signal. Supporting evidence from the book's own numbers: a 2p1z model contains the 2p0z model, "
           "so at the optimum its fit cannot be lower, yet the book reports 89.3 % < 95.4 % (chirp) and 81.3 % < "
           "81.4 % (PRMS): on the same data that means the book's fits did not all reach their optimum. " + (
               "Here every 2p1z fit is >= its 2p0z fit (table 2)." if nested_ok else
               "(Here too a 2p1z fit came out below its 2p0z fit: see table 2.)"),
           f"3. **The book's chirp (0.5-2 Hz) barely excites the dynamics.** 2 Hz is an eighth of the valve's "
           f"natural frequency, where the phase lag is ~9 deg: a static gain alone fits that run at "
           f"{chirp_static} %. Its high fit says the gain is right; its wn and zeta are weakly determined "
           f"(rms error over the realisations: wn {chirp_wn:.1f} %, zeta {chirp_z:.1f} % at book-level noise, "
           "table 4).",
           f"4. **What does better** (table 4, book-level noise, ranked by rms error of wn and zeta): "
           + "; ".join(f"{name}: wn {ew:.2f} %, zeta {ez:.2f} %" for name, ew, ez in ranking) + ". "
           "Power that covers the valve's band up to 2-3x its natural frequency (0.5-40 Hz) pins wn and zeta "
           "down; the log chirp spends equal time per decade and keeps a high output level throughout. A PRMS "
           f"clocked at 10 ms (power flat to ~45 Hz) also works, but at +-20 mA its full-scale steps overshoot "
           f"into the spool's end stops ({100 * stop10:.1f} % of the time, table 3), a non-linearity that biases "
           f"K ({k20:+.2f} % against {k15:+.2f} % at +-15 mA). Report fit % together with the residual tests and "
           "the parameter spread, never alone.",
           ""]

    # -- figures ----------------------------------------------------------------
    step("5/5 figures")
    figs = []
    for name, est in overlay_runs.items():
        fname = "overlay_chirp.png" if "chirp" in name else "overlay_prms.png"
        figs.append(plot_overlay(est, out / fname, title=f"valve (grey box, 70 bar bench) flow: {name}, book-level "
                                 f"noise; model: 2p0z fitted", zoom_s=1.0 if "chirp" in name else 0.25))
    models = [("truth (book chirp model)", G)]
    if book_prms_tf is not None:
        models.append(("book PRMS model", book_prms_tf))
    for name, est in overlay_runs.items():
        models.append((f"fitted to {name}", est.tf))
    figs.append(plot_bode(models, out / "bode.png", title="valve Q/i, LPM/mA: truth, the book's PRMS model, fits",
                          f_range=(0.1, 200.0)))
    figs.append(_plot_spectra(sigs, G, out / "spectra.png"))
    figs.append(_plot_sweep(sweep, out / "prms_clock_sweep.png"))
    md += ["## Files", "", ", ".join(f"`{f.name}`" for f in figs) + ": overlays of the book's two experiments, "
           "Bode plot of the models, input power spectra against the valve's response, fit % against the PRMS "
           "clock.", "", f"_Generated in {time.perf_counter() - t_start:.0f} s._", ""]
    return atomic_write_text(out / "README.md", "\n".join(md))


def _plot_spectra(sigs: dict, G, path) -> Path:
    from scipy import signal as sps

    from ehas_env.output.identification_plots import save
    from ehas_env.output.plots import _pyplot

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 5))
    for name, sig in sigs.items():
        f, p = sps.welch(sig.current_mA, fs=1.0 / sig.dt, nperseg=2048)
        ax.loglog(f[1:], p[1:], lw=0.9, label=name)
    f = np.geomspace(0.1, 500, 400)
    num, den = np.atleast_1d(np.squeeze(G.num[0][0])), np.atleast_1d(np.squeeze(G.den[0][0]))
    g = np.abs(np.polyval(num, 2j * np.pi * f) / np.polyval(den, 2j * np.pi * f)) / (num[-1] / den[-1])
    ax2 = ax.twinx()
    ax2.semilogx(f, 20 * np.log10(g), "k--", lw=1.2, label="valve |G|/K")
    ax2.set_ylabel("valve |G| / K, dB")
    ax2.set_ylim(-60, 5)
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel("input power spectral density, mA^2/Hz")
    ax.set_ylim(1e-4, 1e4)
    ax.legend(loc="lower left", fontsize=7)
    ax2.legend(loc="upper right", fontsize=8)
    ax.set_title("where each excitation puts its power, and where the valve responds", fontsize=10)
    return save(fig, path)


def _plot_sweep(sweep, path) -> Path:
    from ehas_env.output.identification_plots import save
    from ehas_env.output.plots import _pyplot

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    h = [s[0] * 1e3 for s in sweep]
    ax.semilogx(h, [s[2] for s in sweep], "o-", label="true model on the noisy run")
    ax.semilogx(h, [s[3] for s in sweep], "s--", label="fitted 2p0z")
    ax.axhline(81.4, color="C3", lw=1, label="book's PRMS fit 81.4 %")
    ax.axhline(95.4, color="C2", lw=1, label="book's chirp fit 95.4 %")
    ax.set_xlabel("PRMS clock period, ms")
    ax.set_ylabel("fit %, NRMSE")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("PRMS +-20 mA with book-level noise: fit % follows the output's share of power", fontsize=10)
    return save(fig, path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ehas_env.identification.book_valve", description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="results/identification", help="output folder (default results/identification)")
    parser.add_argument("--seeds", type=int, default=10, help="noise realisations per Monte Carlo cell (default 10)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if args.seeds < 2:
        parser.error("--seeds must be at least 2")
    path = study(Path(args.out), seeds=args.seeds, quiet=args.quiet)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
