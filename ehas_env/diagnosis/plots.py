"""Plots that make a model's failure visible (matplotlib, Agg backend, PNG files).

* :func:`overlay`: measured vs model (before and after adding effects), per
  signal, for one run, with the residuals underneath;
* :func:`residual_scatter`: residual of a signal against its best physical
  regressors (the signature of the missing effect), before and after;
* :func:`hysteresis`: load vs velocity loops, measured and modelled (friction
  shows as a step at zero velocity, viscous friction as a tilt, mass as a
  loop that opens with acceleration);
* :func:`verdict_bars`: the verdict's noise figure per run and signal against
  its thresholds, the overall figure in the title (and in the PNG's
  ``Description`` text chunk).

Every function writes one PNG atomically and returns its path.  A function that shows runs takes
``holdout`` (the names of the runs a diagnosis held out for validation) and marks each such run "held out
for validation" (:data:`HELD_OUT`) wherever it names it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ehas_env.output.plots import save_figure
from ehas_env.measurement.replay import UNITS

MEASURED = dict(color="black", lw=1.6, alpha=0.45, label="measured")
STYLES = [dict(color="tab:red", lw=1.0, ls="--"), dict(color="tab:blue", lw=1.1), dict(color="tab:green", lw=1.0)]

#: the signals an overlay shows, in order (closed-loop runs): the angle the loop tracks, the command that
#: drives it, the load that reveals forces, and the flow that reveals the valve; pressures only without a load
OVERLAY_SIGNALS = ("theta_deg", "current_mA", "load_kN", "flow_lpm")
#: units of the regressors of :func:`ehas_env.measurement.residuals.regressors`
REGRESSOR_UNITS = {"velocity": "deg/s", "sign(velocity)": "-", "position": "deg", "acceleration": "deg/s^2",
                   "load pressure": "bar", "mean chamber pressure": "bar", "|flow|": "LPM", "current": "mA",
                   "sign(current)": "-", "current rate": "mA/s", "supply pressure": "bar"}
#: how a figure or table marks a run that a diagnosis held out of the fit for validation
HELD_OUT = "held out for validation"
NAMES = {"theta_deg": "angle", "current_mA": "current", "load_kN": "load", "flow_lpm": "flow A",
         "p_a_bar": "pressure A", "p_b_bar": "pressure B", "p_s_bar": "supply pressure"}


def regressor_label(name: str) -> str:
    """``velocity [deg/s]``; lagged currents ``current 5 ms earlier [mA]``."""
    unit = REGRESSOR_UNITS.get(name, "mA" if name.startswith("current ") else "")
    return f"{name} [{unit}]" if unit else name


def run_label(name: str, holdout=(), text: str = "") -> str:
    """A run's name as a figure shows it: ``cl_5sets (3 sets, 30 deg, 2 Hz; held out for validation)``.

    Parameters
    ----------
    name : str
        The run's name.
    holdout : iterable of str
        The runs held out for validation.
    text : str
        Words about the run (its label), in the brackets.

    Returns
    -------
    str
    """
    words = [w for w in (text, HELD_OUT if name in set(holdout or ()) else "") if w]
    return f"{name} ({'; '.join(words)})" if words else name


def _figure(nrows, ncols=1, size=(9.0, 2.2)):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(nrows, ncols, figsize=(size[0], size[1] * nrows), squeeze=False)
    return plt, fig, axes


def _save(plt, fig, path) -> Path:
    """Lay ``fig`` out (unless it placed its axes itself) and write it as one PNG, atomically."""
    if not getattr(fig, "_ehas_layout", False):
        fig.tight_layout()
    return save_figure(fig, path)


def overlay_signals(case) -> list[str]:
    """The signals worth a look for this run (at most four)."""
    have = [s for s in case.signals if s in case.measured]
    if case.run.kind != "closed_loop":
        return have[:4]
    out = [s for s in OVERLAY_SIGNALS if s in have]
    if "load_kN" not in have:
        out += [s for s in ("p_a_bar", "p_b_bar") if s in have]
    return out[:4]


def failure_window(case, sim: dict, signals, width_s: float) -> tuple[float, float]:
    """(t0, t1) of the stretch, ``width_s`` long, where the model's residuals are largest in noise units.

    The whole run is searched (the ramp-in included: a model that fails most there fails most there), so the
    zoom's title "where the model fails most" holds for the run shown.

    Parameters
    ----------
    case : Case
        One run of a replayer (measured signals, noise levels, sample times).
    sim : dict
        The model's simulated signals of that run.
    signals : iterable of str
        The signals whose noise-normalised residual energies are summed.
    width_s : float
        Length of the window, s.

    Returns
    -------
    tuple of float
        (t0, t1), s from the run's start.
    """
    t = case.run.t - case.run.t[0]
    e = np.zeros(t.size)
    for s in signals:
        e += ((case.measured[s] - sim[s]) / max(case.noise[s], 1e-12)) ** 2
    n = min(max(int(round(width_s / case.run.dt)), 1), t.size)
    energy = np.convolve(e, np.ones(n), mode="valid")
    k = int(np.argmax(energy)) if energy.size else 0
    return float(t[k]), float(t[min(k + n, t.size - 1)])


def overlay(path, case, models: dict[str, dict], signals=None, window_s: float | None = None, holdout=()) -> Path:
    """Measured and modelled signals of one run with their residuals (in the signal's units), whole run and zoom.

    ``models`` maps a label (``baseline``, ``+ coulomb_friction``) to that model's
    simulated signals of this run; the last is the model the figure is about
    (the only one in a "before" figure, the final model in an "after" figure),
    and its failure in this run picks the zoom window (``window_s`` long,
    default one reference period or 0.5 s).  Left column: the whole run; right
    column: the window where that model's residuals in this run are largest
    (shaded on the left), its title naming the model.  Each signal has its
    residual panel underneath, with the band of +-2 noise levels in grey.  ``holdout``: the runs held out
    for validation (the title says so when this is one).
    """
    from matplotlib.gridspec import GridSpec

    run = case.run
    signals = [s for s in (signals or overlay_signals(case)) if s in case.measured]
    t = run.t - run.t[0]
    ref = run.meta.get("reference")
    width = window_s or (min(1.0 / ref["freq_hz"], 1.0) if ref else 0.5)
    judged = list(models)[-1]
    w0, w1 = failure_window(case, models[judged], signals, width)
    zoom = (t >= w0) & (t <= w1)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(13.0, 1.0 + 2.9 * len(signals)))
    gs = GridSpec(2 * len(signals), 2, figure=fig, height_ratios=[1.7, 1.0] * len(signals), width_ratios=[1.6, 1.0],
                  hspace=0.12, wspace=0.16)
    handles = []
    for k, s in enumerate(signals):
        unit = UNITS[s]
        for col, sel in enumerate((slice(None), zoom)):
            ax = fig.add_subplot(gs[2 * k, col])
            axr = fig.add_subplot(gs[2 * k + 1, col], sharex=ax)
            h = ax.plot(t[sel], case.measured[s][sel], **MEASURED)
            if k == 0 and col == 0:
                handles += h
            axr.axhspan(-2 * case.noise[s], 2 * case.noise[s], color="0.85", lw=0)
            axr.axhline(0.0, color="0.5", lw=0.6)
            for (label, sim), st in zip(models.items(), STYLES):
                h = ax.plot(t[sel], sim[s][sel], label=label, **st)
                axr.plot(t[sel], (case.measured[s] - sim[s])[sel], **st)
                if k == 0 and col == 0:
                    handles += h
            if col == 0:
                ax.axvspan(w0, w1, color="gold", alpha=0.25, lw=0)
                axr.axvspan(w0, w1, color="gold", alpha=0.25, lw=0)
                ax.set_ylabel(f"{NAMES.get(s, s)} [{unit}]", fontsize=9)
                axr.set_ylabel(f"residual [{unit}]", fontsize=8)
            if k == 0:
                ax.set_title("whole run (gold: the zoom window)" if col == 0 else
                             f"zoom, t = {w0:.2f}-{w1:.2f} s: where the {judged} model\nfails most in this run",
                             fontsize=9)
            ax.tick_params(labelbottom=False, labelsize=8)
            axr.tick_params(labelsize=8, labelbottom=(k == len(signals) - 1))
            if k == len(signals) - 1:
                axr.set_xlabel("t [s]", fontsize=9)
            ax.grid(alpha=0.25)
            axr.grid(alpha=0.25)
    h_in = fig.get_figheight()
    fig.suptitle(f"{run_label(run.name, holdout, run.label())}: measured vs model; residual = measured - model "
                 "(grey band: +-2 noise levels)", fontsize=10, y=1.0 - 0.08 / h_in, va="top")
    fig.legend(handles=handles, labels=[h.get_label() for h in handles], loc="upper center", ncol=len(handles),
               fontsize=9, frameon=False, bbox_to_anchor=(0.5, 1.0 - 0.3 / h_in))
    fig.subplots_adjust(left=0.07, right=0.99, top=1.0 - 1.05 / h_in, bottom=0.5 / h_in)
    fig._ehas_layout = True
    return _save(plt, fig, path)


def residual_scatter(path, rep, sims_by_label: dict[str, list], signal: str, regressor_names: list[str],
                     holdout=()) -> Path:
    """Residual of ``signal`` (closed-loop runs pooled) against each regressor, per model; the legend names
    each run, ``holdout`` ones as held out for validation."""
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
                ax.plot(reg[reg_name][::3], e[::3], ".", ms=1.5, alpha=0.5, label=run_label(case.run.name, holdout))
            ax.set_xlabel(regressor_label(reg_name), fontsize=8)
            ax.set_ylabel(f"{signal} residual [{UNITS[signal]}]", fontsize=8)
            ax.axhline(0.0, color="0.5", lw=0.6)
            ax.grid(alpha=0.25)
            if r == 0:
                ax.set_title(f"model: {label}", fontsize=9)
    for r in range(len(regressor_names)):  # one residual scale per row: the error falling is seen at a glance
        lo = min(axes[r, c].get_ylim()[0] for c in range(len(labels)))
        hi = max(axes[r, c].get_ylim()[1] for c in range(len(labels)))
        for c in range(len(labels)):
            axes[r, c].set_ylim(lo, hi)
    # the runs' legend on the first panel that has points (a regressor some runs lack leaves a panel empty)
    filled = next((ax for ax in axes.ravel() if ax.get_legend_handles_labels()[0]), None)
    if filled is not None:
        filled.legend(fontsize=7, markerscale=6, loc="best", title="run", title_fontsize=7)
    fig.suptitle(f"residual of {NAMES.get(signal, signal)} (measured - model) against its physical regressors, "
                 "closed-loop runs pooled", fontsize=9)
    return _save(plt, fig, path)


def hysteresis(path, rep, sims_by_label: dict[str, list], run_index: int | None = None, holdout=()) -> Path:
    """Load vs crank velocity loops (steady cycles), measured and per model, one panel per closed-loop run (its
    title the run's name and label; ``holdout`` ones marked held out for validation)."""
    idx = [i for i, c in enumerate(rep.cases) if c.run.kind == "closed_loop" and "load_kN" in c.measured]
    if run_index is not None:
        idx = [run_index]
    # at least 6.5 in wide: a single run's panel holds its legend (the models' labels) and the title's lines
    plt, fig, axes = _figure(1, max(len(idx), 1), size=(max(3.4 * len(idx), 6.5), 3.4))
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
        name = case.run.name + (f"\n{HELD_OUT}" if case.run.name in set(holdout or ()) else "")
        ax.set_title(f"{case.run.label()}\n{name}", fontsize=8)
        if col == 0:
            ax.legend(fontsize=7, markerscale=5)
    fig.suptitle("actuator load against crank velocity over the steady cycles (after the first): measured (black dots) "
                 "and each model, one panel per closed-loop run", fontsize=9)  # wrapped to the width by save_figure
    return _save(plt, fig, path)


def fit_bars(path, tables: dict, title: str = "") -> Path:
    """Grouped bars: fit % per signal for each model (``tables``: label -> FitTable), values printed on the bars."""
    labels = list(tables)
    signals = list(tables[labels[0]].per_signal) + ["overall"]
    plt, fig, axes = _figure(1, size=(9.5, 3.8))
    ax = axes[0, 0]
    x = np.arange(len(signals))
    w = 0.8 / len(labels)
    lo = min(min(t.per_signal.values(), default=0) for t in tables.values())
    bottom = max(min(lo - 5, 90), -100)
    for k, label in enumerate(labels):
        vals = [tables[label].per_signal.get(s, np.nan) for s in signals[:-1]] + [tables[label].overall]
        bars = ax.bar(x + (k - (len(labels) - 1) / 2) * w, vals, w, label=label)
        for b, v in zip(bars, vals):
            if np.isfinite(v):
                ax.text(b.get_x() + b.get_width() / 2, max(v, bottom) + 0.5, f"{v:.1f}", ha="center", va="bottom",
                        fontsize=6, rotation=90)
    ax.set_xticks(x, [NAMES.get(s, s) if s != "overall" else "overall (all signals)" for s in signals], fontsize=8)
    ax.set_ylabel("fit %, 100 (1 - NRMSE)")
    ax.set_ylim(bottom, 108)
    ax.axhline(100, color="0.5", lw=0.6)
    ax.set_title(title or ("fit % per signal, measurement against each model (100 % = the model reproduces it)\n"
                           "models: " + " -> ".join(labels)), fontsize=9)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0), borderaxespad=0.2)
    return _save(plt, fig, path)


def valve_overlay(path, case, models: dict[str, dict], window_s: float = 0.4, holdout=()) -> Path:
    """A valve run: flow in two zoomed windows (the slowest and the fastest part of a chirp), residuals below.

    The whole record of a chirp is a tangle at page scale; the two windows show the
    shape (and any lag) of measured and modelled flow, and the residual over the
    whole record shows where the model fails (LPM, grey band: +-2 noise levels).  ``holdout``: the runs
    held out for validation (the title says so when this is one).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.gridspec import GridSpec

    t = case.run.t - case.run.t[0]
    y = case.measured["flow_lpm"]
    fig = plt.figure(figsize=(12.0, 6.4))
    gs = GridSpec(2, 2, figure=fig, height_ratios=[1.6, 1.0], hspace=0.35, wspace=0.15)
    windows = [(t[0], min(t[0] + window_s, t[-1])), (max(t[-1] - window_s, t[0]), t[-1])]
    handles = []
    for col, (a, b) in enumerate(windows):
        ax = fig.add_subplot(gs[0, col])
        sel = (t >= a) & (t <= b)
        handles = ax.plot(t[sel], y[sel], **MEASURED)
        for (label, sim), st in zip(models.items(), STYLES):
            handles += ax.plot(t[sel], sim["flow_lpm"][sel], label=label, **st)
        ax.set_title(f"{'start' if col == 0 else 'end'} of the record, t = {a:.2f}-{b:.2f} s", fontsize=9)
        ax.set_xlabel("t [s]", fontsize=9)
        ax.set_ylabel("flow A [LPM]" if col == 0 else "", fontsize=9)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.25)
    axr = fig.add_subplot(gs[1, :])
    axr.axhspan(-2 * case.noise["flow_lpm"], 2 * case.noise["flow_lpm"], color="0.85", lw=0)
    for (label, sim), st in zip(models.items(), STYLES):
        axr.plot(t, y - sim["flow_lpm"], **{**st, "lw": 0.7})
    for a, b in windows:
        axr.axvspan(a, b, color="gold", alpha=0.25, lw=0)
    axr.set_xlabel("t [s]", fontsize=9)
    axr.set_ylabel("residual [LPM]", fontsize=9)
    axr.set_title("residual = measured - model over the whole record (gold: the windows above; grey: +-2 noise "
                  "levels)", fontsize=9)
    axr.tick_params(labelsize=8)
    axr.grid(alpha=0.25)
    fig.suptitle(f"{run_label(case.run.name, holdout, case.run.label())}: valve on the flow bench", fontsize=10)
    fig.legend(handles=handles, labels=[h.get_label() for h in handles], loc="upper center", ncol=len(handles),
               fontsize=9, frameon=False, bbox_to_anchor=(0.5, 0.955))
    fig.subplots_adjust(left=0.07, right=0.99, top=0.86, bottom=0.08)
    fig._ehas_layout = True
    return _save(plt, fig, path)


def verdict_bars(path, blocks, grading: dict, label: str = "final model", holdout=()) -> Path:
    """The verdict as a figure: each run and signal's residual in what does not repeat, against the thresholds.

    Parameters
    ----------
    path : str or Path
        The PNG to write.
    blocks : list of ehas_env.measurement.verdict.Block
        Every run and judged signal of the model (:func:`ehas_env.measurement.verdict.blocks_of`).
    grading : dict
        :func:`ehas_env.measurement.verdict.grade` of those blocks (the verdict, its figure, thresholds).
    label : str
        What the model is called.
    holdout : iterable of str
        The runs held out for validation: their bars hatched, their names marked "held out for validation".
        Runs judged on their cycle envelope (a loop that does not repeat) are marked "(envelope)".

    Returns
    -------
    Path
    """
    from matplotlib.patches import Patch

    from ehas_env.measurement.verdict import FIGURE_KEY, figure_text

    text = f"{label}: {grading['verdict']}, residual {figure_text(grading[FIGURE_KEY])}"
    t = grading["thresholds"]
    held = set(holdout or ())
    names = [f"{b.run} {b.signal}" + (" (envelope)" if b.judged_on == "envelope" else "")
             + (f" ({HELD_OUT})" if b.run in held else "") for b in blocks]
    xs = np.array([b.x for b in blocks], dtype=float)
    plt, fig, axes = _figure(1, size=(9.0, 1.2 + 0.22 * max(len(blocks), 4)))
    ax = axes[0, 0]
    colors = ["tab:green" if v <= t["block_explained"] else "tab:orange" if v <= t["block_unexplained"] else "tab:red"
              for v in xs]
    bars = ax.barh(np.arange(len(xs)), np.maximum(xs, 1e-3), color=colors)
    for bar, b in zip(bars, blocks):
        if b.run in held:
            bar.set_hatch("///")
            bar.set_edgecolor("0.2")
    ax.set_yticks(np.arange(len(xs)))
    ax.set_yticklabels(names, fontsize=7)
    ax.invert_yaxis()
    ax.set_xscale("log")
    for v, st, what in ((t["explained"], "-.", "explained up to (overall)"),
                        (t["block_explained"], ":", "explained up to (one run and signal)"),
                        (t["block_unexplained"], "--", "unexplained above (one run and signal)")):
        ax.axvline(v, color="0.4", ls=st, lw=1.0, label=f"{what}: {v:g}x")
    ax.axvline(grading[FIGURE_KEY], color="k", lw=1.4, label=f"overall: {figure_text(grading[FIGURE_KEY])}")
    ax.set_xlabel("residual / what does not repeat from cycle to cycle (1 = nothing structured left)", fontsize=8)
    handles = ax.get_legend_handles_labels()[0]
    if held & {b.run for b in blocks}:
        handles.append(Patch(facecolor="white", edgecolor="0.2", hatch="///",
                             label=f"hatched: {', '.join(sorted(held & {b.run for b in blocks}))}, {HELD_OUT}"))
    ax.legend(handles=handles, fontsize=7, loc="lower right")
    ax.set_title(text, fontsize=10)
    ax.grid(alpha=0.25, axis="x")
    fig.tight_layout()
    return save_figure(fig, path, metadata={"Description": text})
