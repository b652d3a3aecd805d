"""Plots that make a model's failure visible (matplotlib, Agg backend, PNG files).

* :func:`overlay`: measured vs model (before and after adding effects), per
  signal, for one run, with the residuals underneath;
* :func:`residual_scatter`: residual of a signal against its best physical
  regressors (the signature of the missing effect), before and after;
* :func:`hysteresis`: load vs velocity loops, measured and modelled (friction
  shows as a step at zero velocity, viscous friction as a tilt, mass as a
  loop that opens with acceleration).

Every function writes one PNG atomically and returns its path.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ehas_env.output.files import atomic_write_bytes
from ehas_env.measurement.replay import UNITS

MEASURED = dict(color="0.25", lw=0.8, label="measured")
STYLES = [dict(color="tab:red", lw=1.0, ls="--"), dict(color="tab:blue", lw=1.0), dict(color="tab:green", lw=1.0)]


def _figure(nrows, ncols=1, size=(9.0, 2.2)):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(nrows, ncols, figsize=(size[0], size[1] * nrows), squeeze=False)
    return plt, fig, axes


def _save(plt, fig, path) -> Path:
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())


def overlay(path, case, models: dict[str, dict], signals=None, window_s: float | None = None) -> Path:
    """Measured and modelled signals of one run, residuals below each.

    ``models`` maps a label (``baseline``, ``+ coulomb_friction``) to that model's
    simulated signals of this run.
    """
    run = case.run
    signals = [s for s in (signals or case.signals) if s in case.measured]
    t = run.t - run.t[0]
    sel = slice(None) if window_s is None else t >= t[-1] - window_s
    plt, fig, axes = _figure(2 * len(signals), size=(9.0, 1.6))
    for k, s in enumerate(signals):
        ax, axr = axes[2 * k, 0], axes[2 * k + 1, 0]
        ax.plot(t[sel], case.measured[s][sel], **MEASURED)
        for (label, sim), st in zip(models.items(), STYLES):
            ax.plot(t[sel], sim[s][sel], label=label, **st)
            axr.plot(t[sel], (case.measured[s] - sim[s])[sel], label=f"residual, {label}", **st)
        ax.set_ylabel(f"{s}\n[{UNITS[s]}]", fontsize=8)
        axr.set_ylabel("resid.", fontsize=8)
        axr.axhspan(-2 * case.noise[s], 2 * case.noise[s], color="0.85", lw=0)
        if k == 0:
            ax.legend(fontsize=7, loc="upper right", ncol=len(models) + 1)
            ax.set_title(f"{run.name} ({run.label()}): measured vs model (grey band: +-2 noise levels)", fontsize=9)
    axes[-1, 0].set_xlabel("t [s]")
    return _save(plt, fig, path)


def residual_scatter(path, rep, sims_by_label: dict[str, list], signal: str, regressor_names: list[str]) -> Path:
    """Residual of ``signal`` (closed-loop runs pooled) against each regressor, per model."""
    from ehas_env.measurement.residuals import regressors

    labels = list(sims_by_label)
    plt, fig, axes = _figure(len(regressor_names), len(labels), size=(4.5 * len(labels) / 2 + 2.5, 2.4))
    for c, label in enumerate(labels):
        for r, reg_name in enumerate(regressor_names):
            ax = axes[r, c]
            for case, sim in zip(rep.cases, sims_by_label[label]):
                if sim is None or signal not in case.signals or case.run.kind != "closed_loop":
                    continue
                reg = regressors(case, sim)
                if reg_name not in reg:
                    continue
                e = case.measured[signal] - sim[signal]
                ax.plot(reg[reg_name][::3], e[::3], ".", ms=1.5, alpha=0.5, label=case.run.name)
            ax.set_xlabel(reg_name, fontsize=8)
            ax.set_ylabel(f"{signal} residual [{UNITS[signal]}]", fontsize=8)
            if r == 0:
                ax.set_title(label, fontsize=9)
    axes[0, 0].legend(fontsize=6, markerscale=4, loc="best")
    return _save(plt, fig, path)


def hysteresis(path, rep, sims_by_label: dict[str, list], run_index: int | None = None) -> Path:
    """Load vs crank velocity loops (steady cycles), measured and per model, one panel per closed-loop run."""
    idx = [i for i, c in enumerate(rep.cases) if c.run.kind == "closed_loop" and "load_kN" in c.measured]
    if run_index is not None:
        idx = [run_index]
    plt, fig, axes = _figure(1, max(len(idx), 1), size=(3.4 * max(len(idx), 1), 3.2))
    for col, i in enumerate(idx):
        ax = axes[0, col]
        case = rep.cases[i]
        ref = case.run.meta["reference"]
        steady = (case.run.t - case.run.t[0]) >= 1.0 / ref["freq_hz"]
        first = next(iter(sims_by_label.values()))[i]
        w = first["omega_deg_s"][steady]
        for (label, sims), st in zip(sims_by_label.items(), STYLES):
            ax.plot(sims[i]["omega_deg_s"][steady], sims[i]["load_kN"][steady], label=label, **st)
        ax.plot(w, case.measured["load_kN"][steady], ".", color="k", ms=1.2, alpha=0.35, label="measured", zorder=3)
        ax.set_xlabel("crank velocity [deg/s]", fontsize=8)
        ax.set_ylabel("load [kN]", fontsize=8)
        ax.set_title(case.run.label(), fontsize=9)
        if col == 0:
            ax.legend(fontsize=7, markerscale=5)
    return _save(plt, fig, path)


def fit_bars(path, tables: dict, title: str = "fit % per signal") -> Path:
    """Grouped bars: fit % per signal for each model (``tables``: label -> FitTable)."""
    labels = list(tables)
    signals = list(tables[labels[0]].per_signal) + ["overall"]
    plt, fig, axes = _figure(1, size=(9.0, 3.2))
    ax = axes[0, 0]
    x = np.arange(len(signals))
    w = 0.8 / len(labels)
    for k, label in enumerate(labels):
        vals = [tables[label].per_signal.get(s, np.nan) for s in signals[:-1]] + [tables[label].overall]
        ax.bar(x + (k - (len(labels) - 1) / 2) * w, vals, w, label=label)
    ax.set_xticks(x, signals, fontsize=8)
    ax.set_ylabel("fit % (NRMSE)")
    lo = min(min(t.per_signal.values(), default=0) for t in tables.values())
    ax.set_ylim(max(min(lo - 5, 90), -100), 100)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    return _save(plt, fig, path)


def valve_overlay(path, case, models: dict[str, dict]) -> Path:
    """Flow vs time and flow vs current of a valve run, measured and modelled."""
    plt, fig, axes = _figure(1, 2, size=(10.0, 3.2))
    t = case.run.t - case.run.t[0]
    i = case.run.columns["current_mA"]
    axes[0, 0].plot(t, case.measured["flow_lpm"], **MEASURED)
    axes[0, 1].plot(i, case.measured["flow_lpm"], ".", color="0.3", ms=1.0, label="measured")
    for (label, sim), st in zip(models.items(), STYLES):
        axes[0, 0].plot(t, sim["flow_lpm"], label=label, **st)
        axes[0, 1].plot(i, sim["flow_lpm"], label=label, **st)
    axes[0, 0].set_xlabel("t [s]")
    axes[0, 0].set_ylabel("flow [LPM]")
    axes[0, 1].set_xlabel("current [mA]")
    axes[0, 0].legend(fontsize=7)
    axes[0, 0].set_title(f"{case.run.name}: flow bench", fontsize=9)
    return _save(plt, fig, path)
