"""``ehas compare``: the model against a measurement campaign, before and after adding effects.

``ehas compare CAMPAIGN_DIR [--effects NAME[,NAME...]] [--fit] [--out DIR] [--save-model FILE]``
replays every run with the baseline and with the baseline plus the named
effects (``--fit`` first calibrates their parameters, with the baseline's beta
and K, on the campaign), prints fit % per signal and per run before and after,
and with ``--out`` writes overlays, residual plots, load-velocity loops and a
``report.md`` that reads top to bottom: the campaign, where the baseline
fails, what was tried, what was added (fitted values with units), the error
drop.  ``--save-model`` writes the calibrated model for ``--model FILE``
(``ehas_env.simulation.model_file``).

The campaign is validated completely before anything is computed or written.
"""
from __future__ import annotations

import argparse
import math
import shlex
import sys
import time
from pathlib import Path


#: the label of the baseline with beta and K refitted alone (``--fit``), in the tables and the JSON's ``recalibrated``
RECALIBRATED = "baseline, beta/K recal."


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("campaign", metavar="CAMPAIGN_DIR", help="folder of RUN.csv + RUN.json pairs (docs/measurement-format.md)")
    parser.add_argument("--effects", default=None,
                        help="effects to add: NAME[,NAME...], optionally with values (coulomb_friction:Fc=300); "
                             "see `ehas diagnose` for which one is missing")
    parser.add_argument("--fit", action="store_true",
                        help="calibrate the effects' parameters (and beta, K) on the campaign first")
    parser.add_argument("--out", default=None, help="folder for report.md and the plots (default: print only)")
    parser.add_argument("--save-model", default=None, metavar="FILE",
                        help="write the (calibrated) model as a model file for --model FILE")
    parser.add_argument("--json", default=None, metavar="FILE",
                        help="write the comparison as JSON: residual_x_noise (the diagnosis' definition), fit %% per "
                             "signal and per run before and after, fitted values with 95 %% intervals "
                             "(docs/measurement-format.md)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier --out folder / --save-model / --json file")
    parser.add_argument("--columns", default=None, metavar="NEW=OLD[,NEW=OLD...]",
                        help="map a logger's column names onto the format's, e.g. theta_deg=Angle1,current_mA=I_cmd "
                             "(docs/measurement-format.md)")
    parser.add_argument("--measured-input", default=None, metavar="QUANTITY",
                        help="replay a logged quantity the model holds constant as a measured input, from the log "
                             "(p_s_bar: the supply pressure; the diagnosis' next: line gives it when it kept one)")


def run(args) -> int:
    from ehas_env.measurement.campaign import parse_column_map, read_campaign
    from ehas_env.physics.effects import parse_spec, resolve_effects
    from ehas_env.measurement.replay import ModelSpec, Replayer, format_fit_tables
    from ehas_env.output.progress import status, working
    from ehas_env.simulation.compiled_model import names_hypothesis

    from ehas_env.output.outputs import OutputSet, check_file, check_not_input

    t0 = time.perf_counter()
    requested = parse_spec(args.effects) if args.effects else {}
    if args.fit and not requested and not getattr(args, "measured_input", None):
        raise ValueError("--fit needs --effects NAME[,NAME...] (the effects whose parameters to calibrate) or "
                         "--measured-input (then beta and K are calibrated with the logged input)")
    if not args.fit and requested:
        resolve_effects(requested)  # bad values refused before any work
    # the output paths, before any work
    if args.save_model:
        check_not_input(args.save_model, "--save-model", [args.campaign])
        check_file(args.save_model, "--save-model", overwrite=args.overwrite)
    if args.out:
        check_not_input(args.out, "--out", [args.campaign])
    if getattr(args, "json", None):
        check_not_input(args.json, "--json", [args.campaign])
        check_file(args.json, "--json", overwrite=args.overwrite)
    outputs = OutputSet(args.out, "--out", overwrite=args.overwrite) if args.out else None
    base_model = None
    if getattr(args, "model", None):  # a saved model: the baseline, validated on this campaign (docs/model-file.md)
        from ehas_env.simulation.model_file import load_model

        base_model = load_model(args.model)
    campaign = read_campaign(args.campaign, columns=parse_column_map(args.columns))
    status(f"{len(campaign.runs)} runs read from {campaign.path}", "compare")
    # one compiled model for the baseline and the effects: with the structural hypotheses when one is named
    rep = Replayer(campaign, model=base_model, hypotheses=names_hypothesis(requested))
    if getattr(args, "measured_input", None):  # a logged supply as the model's input (docs/measurement-format.md)
        from ehas_env.diagnosis.measured_inputs import measured

        rep = measured(rep, tuple(q.strip() for q in args.measured_input.split(",") if q.strip()))
    with working("replaying the campaign with the baseline model", "compare"):
        baseline_sims = rep.simulate(ModelSpec())
    tables = {"baseline": rep.fit_table(baseline_sims)}
    sims = {"baseline": baseline_sims}
    null = fitted = None
    ci = None
    if args.fit:
        from ehas_env.diagnosis.candidates import calibrate

        n_par = sum(len(p) for p in resolve_effects(requested).values())
        what = f"{', '.join(requested)} ({n_par} parameter(s)) with beta and K" if requested else "beta and K"
        with working(f"calibrating {what} on {len(campaign.runs)} runs", "compare"):
            null, fitted = calibrate(rep, requested)
        with working("confidence intervals of the fitted numbers", "compare"):
            ci = fit_intervals(rep, fitted)
        absolute = rep.absolute(fitted.model)
        for r in ci:  # beta and K as the plant runs them (a --model rig scales them)
            if r["effect"] == "baseline":
                f = (absolute.beta / fitted.model.beta) if r["param"] == "beta" else (absolute.K / fitted.model.K)
                r.update(value=r["value"] * f, low=None if r["low"] is None else r["low"] * f,
                         high=None if r["high"] is None else r["high"] * f)
        after_model = fitted.model
        tables[RECALIBRATED] = null.table
        sims[RECALIBRATED] = null.sims
    elif requested:
        after_model = ModelSpec(effects=resolve_effects(requested))
    else:
        after_model = None
    label_after = None
    if after_model is not None:
        label_after = "+ " + " + ".join(list(after_model.effects) or ["measured " + str(args.measured_input)])
        sims[label_after] = sims.get(label_after) or rep.simulate(after_model)
        tables[label_after] = rep.fit_table(sims[label_after])

    print(campaign.summary())
    if rep.not_compared_text():
        print(rep.not_compared_text())
    print()
    if base_model is not None:
        print(held_out_text(base_model, campaign, tables["baseline"]))
        print()
    print(format_fit_tables(tables))
    if after_model is not None:
        print()
        print(describe_model(rep.absolute(after_model), fitted=args.fit, ci=ci))
        before, after = tables["baseline"].overall, tables[label_after].overall
        print(f"\noverall fit: {before:.1f} % -> {after:.1f} % ({after - before:+.1f} points)")
    print()
    print(verdict_text(rep, sims, label_after))
    command = "ehas compare " + " ".join(shlex.quote(a) for a in _argv())
    if args.save_model:
        from ehas_env.simulation.model_file import save_model

        model = rep.absolute(after_model or ModelSpec())
        cal = _calibration(campaign, tables, label_after, command)
        if ci:
            cal["ci95"] = ci
        path = save_model(args.save_model, model.effects, beta=model.beta, K=model.K, base=base_model,
                          calibration=cal, command=command)
        print(f"model file: {path}")
    if outputs is not None:
        with outputs as tmp, working("writing the report and its figures", "compare"):
            report = write_report(tmp, rep, sims, tables, campaign=campaign, command=command,
                                  after_label=label_after, after_model=after_model, fitted=args.fit, ci=ci,
                                  **({"title": f"Model vs measurement: {base_model.label}"} if base_model else {}))
        print(f"report: {Path(args.out) / report.name}")
    if getattr(args, "json", None):
        import json

        from ehas_env.output.files import atomic_write_text

        doc = comparison_doc(rep, sims, tables, label_after, ci, campaign.path, command,
                             time.perf_counter() - t0)
        doc["next"] = next_step(args, campaign.path)
        atomic_write_text(args.json, json.dumps(doc, indent=2) + "\n")
        print(f"json: {args.json}")
    print("next: " + next_step(args, campaign.path))
    print(f"elapsed {time.perf_counter() - t0:.1f} s")
    return 0


def verdict_text(rep, sims: dict, label_after: str | None) -> str:
    """The verdict of every model compared, in the noise figure ``ehas diagnose`` grades (one measure of a model
    against a campaign: :func:`ehas_env.measurement.verdict.noise_figure`), and a warning when the model compared
    or fitted is worse on it than the book's rig.

    Parameters
    ----------
    rep : Replayer
        The campaign replayed.
    sims : dict
        {label: the model's simulation of every run}; ``"baseline"`` first.
    label_after : str or None
        The model compared (None: the baseline alone).

    Returns
    -------
    str
        Lines.
    """
    from ehas_env.measurement.replay import COST_SIGNALS
    from ehas_env.measurement.verdict import blocks_of, envelope_text, figure_text, grade

    grades = {label: grade(blocks_of(rep, s, COST_SIGNALS)) for label, s in sims.items()}
    w = max(len(k) for k in grades)
    lines = ["verdict (the noise figure ehas diagnose grades: the residual over every sample against what does not "
             "repeat):"]
    lines += [f"  {label:<{w}}  {g['verdict']}, {figure_text(g['residual_x_noise'])}" for label, g in grades.items()]
    envelope = envelope_text(grades[label_after] if label_after is not None else grades["baseline"])
    if envelope:
        lines.append("  " + envelope)
    if label_after is not None and label_after != "baseline":
        x_after, x_book = grades[label_after]["residual_x_noise"], grades["baseline"]["residual_x_noise"]
        if x_after > x_book:
            lines.append(f"  note: {label_after} is worse on this figure than the book's rig ({x_after:.3g}x against "
                         f"{x_book:.3g}x): keep the book's rig, or diagnose the campaign (ehas diagnose)")
    return "\n".join(lines)


def next_folder(campaign_path) -> str:
    """Where a printed next command writes: a folder beside the campaign named after it (``CAMP-calibrated``), not
    the current folder (a clone's root, when a README block runs it).

    Parameters
    ----------
    campaign_path : str or Path
        The campaign folder as the user named it.

    Returns
    -------
    str

    Examples
    --------
    >>> next_folder("runs/camp/")
    'runs/camp-calibrated'
    """
    p = Path(str(campaign_path).rstrip("/") or ".")
    return str(p.with_name(p.name + "-calibrated"))


def next_step(args, campaign_path) -> str:
    """The command to run after this comparison, runnable as printed.

    The baseline alone (or a ``--model`` validated): ``ehas diagnose`` finds what the model misses.
    Effects named without ``--fit``: the same comparison calibrating them.  Calibrated without
    ``--save-model``: the same, saving the model file.  A model file saved: ``ehas tune`` on it.

    Parameters
    ----------
    args : argparse.Namespace
        This command's arguments.
    campaign_path : str or Path
        The campaign compared.

    Returns
    -------
    str
        One shell command line.
    """
    q = shlex.quote
    if args.save_model and (args.fit or not args.effects):
        return f"ehas tune --method model --model {q(str(args.save_model))}"
    keep = [f"--effects-path {q(str(p))}" for p in (getattr(args, "effects_path", None) or [])]
    if getattr(args, "model", None):
        keep.append(f"--model {q(str(args.model))}")
    if getattr(args, "columns", None):
        keep.append(f"--columns {q(args.columns)}")
    if not args.effects:
        return " ".join(["ehas diagnose", q(str(campaign_path)), *keep])
    return " ".join(["ehas compare", q(str(campaign_path)), *keep, f"--effects {q(args.effects)}", "--fit",
                     f"--save-model {q(str(args.save_model or Path(next_folder(campaign_path)) / 'model.json'))}"] + (["--overwrite"] if args.save_model
                                                                                  else []))


def comparison_doc(rep, sims: dict, tables: dict, label_after, ci, campaign_path, command: str,
                   elapsed_s: float) -> dict:
    """The JSON of ``ehas compare --json`` (docs/measurement-format.md).

    Parameters
    ----------
    rep : Replayer
        The campaign replayed.
    sims, tables : dict
        Simulated runs and :class:`~ehas_env.measurement.replay.FitTable` per model label (first: the baseline).
    label_after : str or None
        The label of the model with the effects.
    ci : list of dict or None
        Fitted values with 95 % intervals (:func:`fit_intervals`).
    campaign_path, command, elapsed_s
        Provenance.

    Returns
    -------
    dict
        ``before`` and ``after`` (each: ``residual_x_noise`` and ``verdict`` as the diagnosis defines them,
        ``envelope_runs`` (runs judged on their cycle envelope), ``residual_x_sensor_noise``, ``fit_percent``
        overall, ``per_signal``, ``per_run``), ``residual_x_noise`` (after), ``recalibrated`` (with ``--fit``:
        the baseline with beta and K refitted alone, the same keys as ``before``), ``fitted`` (value, ci95 [low, high], unit per parameter), ``not_compared`` ({run: [column]}:
        logged columns judged nowhere, :meth:`~ehas_env.measurement.replay.Replayer.not_compared`), ``command``,
        ``elapsed_s``.
    """
    from ehas_env.measurement.replay import COST_SIGNALS
    from ehas_env.measurement.verdict import blocks_json, blocks_of, grade

    def side(label):
        t = tables[label]
        blocks = blocks_of(rep, sims[label], COST_SIGNALS)
        g = grade(blocks)
        return {"model": label, "residual_x_noise": g["residual_x_noise"], "verdict": g["verdict"],
                "worst": g["worst"], "envelope_runs": g["envelope_runs"], "blocks": blocks_json(blocks),
                "residual_x_sensor_noise": round(rep.log_cost(sims[label]), 3),
                "fit_percent": round(t.overall, 2),
                "per_signal": {k: round(v, 2) for k, v in t.per_signal.items()},
                "per_run": {r: {k: round(v, 2) for k, v in d.items()} for r, d in t.per_run.items()}}

    before = side(next(iter(tables)))
    after = side(label_after) if label_after else before
    recal = {"recalibrated": side(RECALIBRATED)} if RECALIBRATED in tables else {}
    return {"campaign": str(campaign_path), "command": command, "elapsed_s": round(elapsed_s, 1),
            "residual_x_noise": after["residual_x_noise"], "verdict": after["verdict"],
            "before": before, **recal, "after": after, "not_compared": rep.not_compared(),
            "fitted": [{"effect": r["effect"], "param": r["param"], "value": r["value"],
                        "ci95": [r["low"], r["high"]], "unit": r["unit"]} for r in (ci or [])]}


def _argv() -> list[str]:
    argv = sys.argv[1:]
    return argv[1:] if argv and argv[0] == "compare" else argv


def _calibration(campaign, tables, label_after, command) -> dict:
    out = {"campaign": str(campaign.path), "runs": [r.name for r in campaign.runs],
           "fit_percent_before": round(tables["baseline"].overall, 2), "command": command}
    if label_after:
        out["fit_percent_after"] = round(tables[label_after].overall, 2)
    return out


def held_out_text(model, campaign, table) -> str:
    """Lines on how a saved model fits this campaign, and whether the campaign is held out."""
    cal = model.calibration or {}
    fitted_on = cal.get("campaign")
    here = Path(str(campaign.path)).resolve() if campaign.path else None
    where = ([Path(fitted_on)] + ([Path(model.path).parent / fitted_on] if model.path else [])) if fitted_on else []
    same = bool(fitted_on) and here is not None and any(p.resolve() == here for p in where)
    what = ("NOT held out: the model was fitted on this campaign" if same else
            f"held out: the model was fitted on {fitted_on}" if fitted_on else
            "the model file records no calibration campaign")
    per = ", ".join(f"{k} {v:.1f} %" for k, v in table.per_signal.items())
    own = cal.get("fit_percent_after", cal.get("fit_percent_before"))
    on_own = f" (on its own campaign: {own:.1f} %)" if isinstance(own, (int, float)) else ""
    return (f"model {model.label} validated on {campaign.path} ({what})\n"
            f"{'held-out fit' if fitted_on and not same else 'overall fit'} {table.overall:.1f} %{on_own}; "
            f"per signal: {per}")


def fit_intervals(rep, fitted) -> list[dict]:
    """95 % confidence intervals of every number ``fitted`` (a calibration Fit) fitted, as JSON-ready rows
    {effect, param, value, low, high, unit} (``effect`` "baseline" for beta and K; see
    :func:`ehas_env.diagnosis.fitting.confidence`)."""
    from ehas_env.diagnosis.fitting import _unit, _value_of, confidence

    ci = confidence(rep, fitted) if fitted.free else {}
    rows = []
    for fp in fitted.free:
        if (fp.effect, fp.name) in ci:
            lo, hi = ci[(fp.effect, fp.name)]
            # a side the data do not bound (inf: fitting.interval) is null in JSON, "unbounded" in print
            rows.append({"effect": fp.effect or "baseline", "param": fp.name, "value": float(_value_of(fitted.model, fp)),
                         "low": float(lo) if math.isfinite(lo) else None,
                         "high": float(hi) if math.isfinite(hi) else None, "unit": _unit(fp.effect, fp.name)})
    return rows


def describe_model(model, fitted: bool = True, ci: list | None = None) -> str:
    """Lines naming the model's numbers with units (and their 95 % confidence intervals, ``ci`` from
    :func:`fit_intervals`)."""
    from ehas_env.physics.effects import get_effect

    band = {(r["effect"], r["param"]): (r["low"], r["high"]) for r in (ci or [])}

    def num(effect, k, v, unit, fmt=".4g"):
        s = f"{k} = {v:{fmt}} {unit}"
        if (effect, k) in band:
            lo, hi = band[(effect, k)]
            s += (f" (95 % CI {'unbounded' if lo is None else format(lo, fmt)} to "
                  f"{'unbounded' if hi is None else format(hi, fmt)})")
        return s

    from ehas_env.measurement.model_difference import replaced_slots

    # a baseline number an effect of the model sets itself is not in force: named as replaced, not as a value
    by = {slot: n for n in model.effects for slot in replaced_slots(n)}

    def base(k, v, unit, fmt=".4g"):
        return f"{k} replaced by {by[k]}" if k in by else num("baseline", k, v, unit, fmt)

    how = "fitted" if fitted else "as given"
    lines = [f"model ({how}): baseline {base('beta', model.beta, 'Pa')}, {base('K', model.K, 'LPM/mA', '.5g')}"]
    for n, ps in model.effects.items():
        cls = get_effect(n)
        vals = ", ".join(num(n, k, v, cls.param(k).unit) for k, v in ps.items())
        lines.append(f"  + {n} ({cls.title}): {vals}")
    if ci:
        lines.append("  (95 % confidence intervals: cluster-robust, from the fit's Jacobian; docs/measurement-format.md)")
    return "\n".join(lines)


# --- report ------------------------------------------------------------------------------------


def _md_table(header: list[str], rows: list[list]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        out.append("| " + " | ".join(f"{v:.1f}" if isinstance(v, float) else str(v) for v in r) + " |")
    return "\n".join(out)


def fit_markdown(tables: dict) -> str:
    """Per-signal and per-run fit % tables in markdown (columns: the models)."""
    labels = list(tables)
    first = tables[labels[0]]
    rows = [[s] + [tables[l].per_signal.get(s, float("nan")) for l in labels] for s in first.per_signal]
    rows.append(["**overall**"] + [tables[l].overall for l in labels])
    text = _md_table(["signal"] + labels, rows)
    signals = list(first.per_signal)
    a, b = labels[0], labels[-1]
    rows = []
    for run in first.per_run:
        cells = []
        for s in signals:
            if s not in first.per_run[run]:
                cells.append("")
            elif a == b:
                cells.append(f"{tables[a].per_run[run][s]:.1f}")
            else:
                cells.append(f"{tables[a].per_run[run][s]:.1f} -> {tables[b].per_run[run][s]:.1f}")
        rows.append([run] + cells)
    what = f"fit % per run ({a})" if a == b else f"fit % per run ({a} -> {b})"
    return text + f"\n\n{what}:\n\n" + _md_table(["run"] + signals, rows)


def write_report(out: Path, rep, sims: dict, tables: dict, *, campaign, command: str, after_label=None,
                 after_model=None, fitted=False, diagnosis=None, title="Model vs measurement", ci=None,
                 holdout=()) -> Path:
    """Write report.md and its PNGs into ``out``; return the report's path.

    ``sims``/``tables`` map model labels (first: the baseline) to simulated runs
    and :class:`~ehas_env.measurement.replay.FitTable`; ``diagnosis`` (optional) adds the
    ranking of every effect tried; ``holdout`` names the runs a diagnosis held out for validation (every
    figure that shows one marks it).
    """
    from ehas_env.diagnosis import plots as plots
    from ehas_env.output.files import atomic_write_text
    from ehas_env.measurement.residuals import signatures, where_it_fails

    out.mkdir(parents=True, exist_ok=True)
    base_label = next(iter(sims))
    # the model the baseline is judged against: recalibrated if there is one
    ref_label = next((l for l in sims if "recal" in l), base_label)
    shown = [base_label] + ([after_label] if after_label else [])
    lines = [f"# {title}: `{campaign.path}`", "",
             f"Regenerate: `{command}`", ""]
    lines += ["## 1. The campaign", "",
              _md_table(["run", "kind", "what", "samples", "rate Hz", "interpolated"],
                        [[r.name, r.kind, r.label(), r.n, f"{1 / r.dt:g}", sum(r.interpolated.values())]
                         for r in campaign.runs]), "",
              f"Missing samples interpolated: {campaign.interpolated_total} "
              f"(gaps of at most 5 samples are filled linearly; longer ones are refused).", ""]

    # 2. where the baseline fails
    lines += ["## 2. Where the baseline fails", "",
              "Fit % is the NRMSE fit, 100 (1 - |y - y_model| / |y - mean(y)|); signals whose measured "
              "variation is at their noise level (a regulated supply) are left out of it.", "",
              fit_markdown({base_label: tables[base_label]}), "",
              "Residual signatures (measured - model; `RMS/noise` is the residual RMS over the signal's "
              "estimated noise level, `non-white` the share of autocorrelation lags outside the 99 % band "
              "of white noise):", "", "```", where_it_fails(rep, sims[ref_label], ref_label), "```", ""]
    sig = signatures(rep, sims[ref_label])
    worst = max((s for s in sig.values() if s.kind == "closed_loop"), key=lambda s: s.ratio, default=None)
    worst_run = _worst_run(rep, sims[ref_label])
    figs = []
    if worst_run is not None:
        case = rep.cases[worst_run]
        shown_signals = _worst_signals(case, sims[ref_label][worst_run])
        p = plots.overlay(out / "overlay_before.png", case, {l: sims[l][worst_run] for l in [base_label]},
                          signals=shown_signals, holdout=holdout)
        figs.append(p)
        lines += [f"![overlay before]({p.name})", "",
                  f"*{case.run.name}, the run the baseline fits worst: measured (grey) and the baseline model "
                  "(red, dashed); under each signal its residual in the signal's units; right: zoom on the "
                  "stretch where the baseline fails most (gold on the left).*", ""]
    if worst is not None:
        regs = [name for name, _ in worst.top(3)]
        if regs:
            p = plots.residual_scatter(out / "residual_vs_regressors.png", rep,
                                       {l: sims[l] for l in ([ref_label] + ([after_label] if after_label else []))},
                                       worst.signal, regs, holdout=holdout)
            lines += [f"![residual vs regressors]({p.name})", "",
                      f"*Residual of {worst.signal} against the physical regressors it tracks most "
                      f"({', '.join(regs)}), closed-loop runs pooled.*", ""]
    if any(c.run.kind == "closed_loop" and "load_kN" in c.measured for c in rep.cases):
        p = plots.hysteresis(out / "load_vs_velocity.png", rep, {l: sims[l] for l in shown}, holdout=holdout)
        lines += [f"![load vs velocity]({p.name})", "",
                  "*Load against crank velocity over the steady cycles: friction shows as a step at zero "
                  "velocity, viscous friction as a tilt, extra mass as a wider loop.*", ""]

    # 3. what was tried
    lines += ["## 3. What was tried", ""]
    if diagnosis is not None:
        rows = [[i + 1, e.effect, _params_text(e.effect, e.params), e.fit_percent, round(e.score, 1),
                 "yes" if e.beats_noise else "no", e.evidence] for i, e in enumerate(diagnosis.ranking)]
        lines += [f"Every effect of the library was added to the recalibrated baseline and fitted on the whole "
                  f"campaign (with beta and K); score = reduction of the recalibrated baseline's noise-weighted "
                  f"residual energy in dB, less 0.2 dB per fitted parameter ({diagnosis.elapsed_s:.0f} s, {diagnosis.n_evals} "
                  "campaign replays).", "",
                  _md_table(["rank", "effect", "fitted", "fit %", "score", "beats noise", "evidence"], rows), ""]
    elif after_model is not None:
        lines += [f"The effects requested on the command line: {', '.join(after_model.effects)}"
                  + (" (calibrated on the campaign with beta and K)." if fitted else " (values as given)."),
                  "Run `ehas diagnose` to try every effect of the library.", ""]
    else:
        lines += ["Nothing was added; run `ehas diagnose` to try every effect of the library, then "
                  "`ehas compare DIR --effects NAME --fit`.", ""]

    # 4. what was added, 5. the error drop
    if after_label:
        lines += ["## 4. What was added", "", "```", describe_model(after_model, fitted, ci), "```", ""]
        for name in after_model.effects:
            from ehas_env.physics.effects import get_effect

            cls = get_effect(name)
            lines += [f"**{name}** — {cls.explanation}", "", f"*Its residual signature:* {cls.signature}", ""]
        b, a = tables[base_label].overall, tables[after_label].overall
        lines += ["## 5. The error drop", "",
                  f"Overall fit: **{b:.1f} % -> {a:.1f} %** ({a - b:+.1f} points).", "",
                  fit_markdown({l: tables[l] for l in tables}), ""]
        p = plots.fit_bars(out / "fit_before_after.png", tables)
        lines += [f"![fit before and after]({p.name})", ""]
        if worst_run is not None:
            case = rep.cases[worst_run]
            p = plots.overlay(out / "overlay_after.png", case, {l: sims[l][worst_run] for l in shown},
                              signals=_worst_signals(case, sims[shown[-1]][worst_run]), holdout=holdout)
            lines += [f"![overlay after]({p.name})", "",
                      f"*{case.run.name}: measured (grey), baseline (red, dashed) and the model with the added "
                      "effects (blue); residuals in the signal's units below each; right: zoom on the stretch where "
                      "the model with the added effects fails most in this run.*", ""]
        for i, case in enumerate(rep.cases):
            if case.run.kind == "valve_open_loop":
                p = plots.valve_overlay(out / f"valve_{case.run.name}.png", case, {l: sims[l][i] for l in shown},
                                        holdout=holdout)
                lines += [f"![valve run]({p.name})", ""]
        lines += ["Residual signatures after:", "", "```", where_it_fails(rep, sims[after_label], after_label), "```",
                  ""]
    path = atomic_write_text(out / "report.md", "\n".join(lines) + "\n")
    _readable(out)
    return path


def _readable(folder: Path) -> None:
    """Atomic writes create private files; a report is for reading."""
    import os

    umask = os.umask(0)
    os.umask(umask)
    for f in folder.iterdir():
        if f.is_file():
            os.chmod(f, 0o666 & ~umask)


def _params_text(effect: str, params: dict) -> str:
    if effect == "none":
        return "-"
    from ehas_env.physics.effects import get_effect

    cls = get_effect(effect)
    return ", ".join(f"{k} = {v:.3g} {cls.param(k).unit}" for k, v in params.items())


def _worst_signals(case, sim, k: int = 4) -> list[str]:
    """The run's signals worst first (residual in noise units), at most ``k``: the figures show where the model
    fails most, whatever signal that is."""
    have = [s for s in case.signals if s in case.measured]
    return sorted(have, key=lambda s: float(((case.measured[s] - sim[s]) ** 2).mean()) / case.noise[s] ** 2,
                  reverse=True)[:k]


def _worst_run(rep, sims):
    """Index of the closed-loop run whose residuals are largest in noise units."""
    best, worst = -1.0, None
    for i, (case, sim) in enumerate(zip(rep.cases, sims)):
        if case.run.kind != "closed_loop" or sim is None:
            continue
        e = sum(float(((case.measured[s] - sim[s]) ** 2).mean()) / case.noise[s] ** 2 for s in case.signals)
        if e > best:
            best, worst = e, i
    return worst
