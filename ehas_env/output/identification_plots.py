"""Figures of identification results: time overlays, Bode plots with the data's spectral estimate, residual tests.

Used by ``ehas identify``, ``ehas curves``, the book's valve identification and the white-box valve.
"""
from __future__ import annotations

from pathlib import Path


def save(fig, path) -> Path:
    import warnings

    from ehas_env.output.plots import save_figure

    with warnings.catch_warnings():
        # a figure with a legend or table axes tight_layout cannot place: matplotlib's warning is for the
        # programmer, not the user of the command; the layout it leaves is the one drawn
        warnings.filterwarnings("ignore", message=".*not compatible with tight_layout.*")
        fig.tight_layout()
    return save_figure(fig, path)


def output_unit(name: str) -> str:
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
    unit = output_unit(d.output_name)
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
    return save(fig, path)


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
    """Bode plot of ``[(label, TransferFunction), ...]`` (in s, or in z with their dt), with the data's estimate."""
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
        x = 2j * np.pi * f if not sys_.dt else np.exp(2j * np.pi * f * float(sys_.dt))  # s, or z of a sampled model
        g = np.polyval(np.atleast_1d(num), x) / np.polyval(np.atleast_1d(den), x)
        if sys_.dt:  # with the half-sample advance the data's estimate has (see spectral_estimate)
            g = g * np.exp(1j * np.pi * f * float(sys_.dt))
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
    return save(fig, path)


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
    return save(fig, path)


def plot_orders(table, path, title: str = "") -> Path:
    """Fit % of every structure of an order table (estimation, validation, k-step prediction) and its BIC."""
    import numpy as np

    from ehas_env.output.plots import _pyplot

    plt = _pyplot()
    rows = table.rows
    labels = [r.label for r in rows]
    x = np.arange(len(rows))
    fig, ax = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    series = [("estimation (simulation)", [r.estimation["fit_percent"] for r in rows]),
              ("validation (simulation)", [r.validation["fit_percent"] for r in rows])]
    if table.predict_k:
        series.append((f"validation ({table.predict_k}-step prediction)",
                       [r.validation["predict_fit_percent"] for r in rows]))
    w = 0.8 / len(series)
    for i, (lab, vals) in enumerate(series):
        ax[0].bar(x + (i - (len(series) - 1) / 2) * w, vals, w, label=lab)
    lo = min(min(v) for _, v in series)
    hi = max(max(v) for _, v in series)
    ax[0].set_ylim(max(lo - 0.1 * (hi - lo + 1e-9), min(0.0, lo)) if lo < 0 else lo - 0.1 * (hi - lo + 1e-9) - 0.01,
                   hi + 0.1 * (hi - lo + 1e-9) + 0.01)
    ax[0].set_ylabel("fit %")
    ax[0].legend(loc="lower right", fontsize=8)
    ax[0].grid(axis="y", alpha=0.3)
    bic = [r.validation["BIC"] for r in rows]
    colors = ["tab:green" if r is table.chosen else "tab:gray" for r in rows]
    ax[1].bar(x, np.asarray(bic) - min(bic), color=colors)
    ax[1].set_ylabel("validation BIC - lowest")
    ax[1].set_xticks(x, labels)
    ax[1].grid(axis="y", alpha=0.3)
    ax[1].set_title(f"chosen: {table.chosen.label} ({table.rule}, green)", fontsize=9)
    if title:
        ax[0].set_title(title, fontsize=10)
    return save(fig, path)


def plot_compare(table, data, path, title: str = "") -> Path:
    """Every structure's simulated output over the validation data, with the measurement (MATLAB ``compare``)."""
    import numpy as np

    from ehas_env.output.plots import _pyplot

    plt = _pyplot()
    n_val = table.n_validation
    t = np.asarray(data.t)[-n_val:]
    y = np.asarray(data.y)[-n_val:]
    fig, ax = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    ax[0].plot(t, y, color="0.55", lw=2.2, label=f"measured {data.output_name}")
    for k, r in enumerate(table.rows):
        lw = 1.4 if r is table.chosen else 0.8
        ax[0].plot(t, r.y_val, lw=lw, color=f"C{k}", label=f"{r.label}: fit {r.validation['fit_percent']:.2f} %")
        ax[1].plot(t, y - r.y_val, lw=lw, color=f"C{k}")
    unit = output_unit(data.output_name)
    ax[0].set_ylabel(f"{data.output_name}" + (f" [{unit}]" if unit else ""))
    ax[0].legend(loc="upper right", fontsize=8)
    ax[1].set_ylabel("measured - model")
    ax[1].set_xlabel("t [s]")
    for a in ax:
        a.grid(alpha=0.25)
    if title:
        ax[0].set_title(title, fontsize=10)
    return save(fig, path)
