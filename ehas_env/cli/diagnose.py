"""``ehas diagnose``: where the baseline fails and which effect of the library explains it.

``ehas diagnose CAMPAIGN_DIR [--json FILE] [--out DIR]`` replays the campaign
with the baseline, prints where it fails (residual signatures per signal), then
adds every effect of the library in turn, fits it (with beta and K), and prints
the ranking with evidence in words; ``"none"`` heads the ranking when nothing
beats noise.  ``--json`` writes the JSON of docs/measurement-format.md; ``--out`` a
report.md with plots.  ``--with NAME[,NAME...]`` starts from a model that
already has those effects (refitted with every candidate), to find the next
one; ``--stack`` repeats the diagnosis, adding the winner each time, until
nothing more beats noise.
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

MAX_STACK = 4


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("campaign", metavar="CAMPAIGN_DIR", help="folder of RUN.csv + RUN.json pairs (docs/measurement-format.md)")
    parser.add_argument("--json", default=None, metavar="FILE", help="write the diagnosis as JSON (docs/measurement-format.md)")
    parser.add_argument("--out", default=None, metavar="DIR", help="folder for report.md and plots")
    parser.add_argument("--with", dest="with_effects", default="", metavar="NAME[,NAME...]",
                        help="effects already added (fitted with each candidate): find the next one")
    parser.add_argument("--stack", action="store_true",
                        help=f"add the winner and diagnose again until nothing beats noise (at most {MAX_STACK})")
    parser.add_argument("--candidates", default="", metavar="NAME[,NAME...]",
                        help="try only these effects (default: every effect of the library)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier --out folder / --json file")
    parser.add_argument("--columns", default="", metavar="NEW=OLD[,NEW=OLD...]",
                        help="map a logger's column names onto the format's, e.g. theta_deg=Angle1,current_mA=I_cmd "
                             "(docs/measurement-format.md)")


def run(args) -> int:
    from ehas_env.measurement.campaign import parse_column_map, read_campaign
    from ehas_env.measurement.diagnosis import diagnose
    from ehas_env.physics.effects import get_effect, parse_spec
    from ehas_env.measurement.replay import ModelSpec, Replayer, format_fit_tables
    from ehas_env.measurement.residuals import where_it_fails

    t0 = time.perf_counter()
    base = parse_spec(args.with_effects) if args.with_effects else {}
    candidates = [c.strip() for c in args.candidates.split(",") if c.strip()] or None
    for c in candidates or []:
        get_effect(c)
    from ehas_env.output.outputs import OutputSet, check_file

    for n, p in base.items():
        get_effect(n).resolve(p)  # bad values refused before any work
    # the output paths, before any work
    if args.json:
        check_file(args.json, "--json", overwrite=args.overwrite)
    outputs = OutputSet(args.out, "--out", overwrite=args.overwrite) if args.out else None
    campaign = read_campaign(args.campaign, columns=parse_column_map(args.columns))
    if not args.quiet:
        from ehas_env.output.progress import status

        status(f"{len(campaign.runs)} runs read; replaying them, then fitting every candidate effect "
               "(about 30-60 s on two cores)", "diagnose")
    rep = Replayer(campaign, model=getattr(args, "model", None))  # --model: diagnose on that rig (docs/model-file.md)
    if rep.model is not None:
        print(f"baseline: model {rep.model.label}")
    print(campaign.summary())
    print()

    steps = []
    while True:
        d = diagnose(campaign, base_effects=base, candidates=candidates, progress=not args.quiet, replayer=rep)
        steps.append(d)
        if len(steps) == 1:
            print(where_it_fails(rep, d.baseline.sims, "baseline" + (" + " + " + ".join(base) if base else "")))
            print()
        print(_ranking_text(d))
        print()
        if not args.stack or d.found == "none" or len(steps) >= MAX_STACK:
            break
        base = {k: dict(v) for k, v in d.top.fit.model.effects.items()}
        print(f"adding {d.found}; diagnosing again on top of {', '.join(base)}")
        print()

    first, last = steps[0], steps[-1]
    final = last.top if last.found != "none" else (steps[-2].top if len(steps) > 1 else None)
    tables = {"baseline": first.baseline.table, "baseline, beta/K recal.": first.null.table}
    if final is not None:
        tables["+ " + " + ".join(final.fit.model.effects)] = final.fit.table
    print(format_fit_tables(tables).split("\n\nfit % per run")[0])
    if final is not None:
        b, a = first.baseline.table.overall, final.fit.table.overall
        print(f"\nadding {', '.join(final.fit.model.effects)}: overall fit {b:.1f} % -> {a:.1f} % ({a - b:+.1f} points)")
        print(f"next: ehas compare {shlex.quote(str(campaign.path))} --effects {','.join(final.fit.model.effects)} "
              "--fit --out DIR --save-model model.json")
    elapsed = time.perf_counter() - t0
    print(f"diagnosed {len(campaign.runs)} runs in {elapsed:.1f} s ({sum(d.n_evals for d in steps)} replays)")

    command = "ehas diagnose " + " ".join(shlex.quote(a) for a in _argv())
    if args.json:
        from ehas_env.output.files import atomic_write_text

        doc = first.to_json()
        doc["campaign"] = str(campaign.path)
        doc["elapsed_s"] = round(elapsed, 1)
        if args.stack:
            doc["stack"] = [d.top.to_json() for d in steps]
        atomic_write_text(args.json, json.dumps(doc, indent=2) + "\n")
        print(f"json: {args.json}")
    if outputs is not None:
        from ehas_env.cli.compare import write_report

        sims = {"baseline": first.baseline.sims, "baseline, beta/K recal.": first.null.sims}
        label = None
        model = None
        if final is not None:
            label = "+ " + " + ".join(final.fit.model.effects)
            sims[label] = final.fit.sims
            model = final.fit.model
        with outputs as tmp:
            path = write_report(tmp, rep, sims, tables, campaign=campaign, command=command, after_label=label,
                                after_model=model, fitted=True, diagnosis=first, title="Diagnosis")
        print(f"report: {Path(args.out) / path.name}")
    return 0


def _argv() -> list[str]:
    argv = sys.argv[1:]
    return argv[1:] if argv and argv[0] == "diagnose" else argv


def _ranking_text(d) -> str:
    from ehas_env.cli.compare import _params_text

    base = f" on top of {', '.join(d.base_effects)}" if d.base_effects else ""
    lines = [f"which effect is missing{base} (recalibrated baseline: fit {d.null.table.overall:.1f} %, residual "
             f"{d.null.cost:.2f}x noise variance)",
             f"{'rank':<5}{'effect':<20}{'score dB':>9}{'fit %':>8}  {'beats noise':<12}fitted"]
    for i, e in enumerate(d.ranking):
        lines.append(f"{i + 1:<5}{e.effect:<20}{e.score:>9.2f}{e.fit_percent:>8.1f}  {'yes' if e.beats_noise else 'no':<12}"
                     f"{_params_text(e.effect, e.params)}")
    lines.append(f"diagnosis: {d.found}")
    lines.append(f"evidence: {d.top.evidence}")
    return "\n".join(lines)


DEMO_HIDDEN = {"coulomb_friction": {"Fc": 420.0}}
DEMO_SEED = 2024


def demo_section(outdir: Path) -> str:
    """``ehas demo``'s last section: a campaign with a hidden effect, diagnosed blind.

    Simulates a campaign with Coulomb friction hidden (Fc = 420 N, beta and K
    perturbed, sensor noise; seed 2024) into ``outdir/campaign``, diagnoses it
    without being told, writes ``outdir/diagnosis/`` (report.md, PNGs,
    diagnosis.json) and ``outdir/model.json`` (the calibrated model), and
    returns a short markdown summary.  About 20-40 s on two cores.
    """
    from ehas_env.measurement.campaign import read_campaign
    from ehas_env.cli.campaign import write_simulated_campaign
    from ehas_env.cli.compare import write_report
    from ehas_env.measurement.diagnosis import diagnose
    from ehas_env.output.files import atomic_write_text
    from ehas_env.measurement.model_file import save_model
    from ehas_env.measurement.replay import Replayer

    outdir = Path(outdir)
    t0 = time.perf_counter()
    camp_dir = outdir / "campaign"
    command = (f"ehas simulate-campaign --effects coulomb_friction:Fc={DEMO_HIDDEN['coulomb_friction']['Fc']:g} "
               f"--seed {DEMO_SEED} --perturb --out {camp_dir}")
    _, truth = write_simulated_campaign(camp_dir, DEMO_HIDDEN, seed=DEMO_SEED, perturb=True, command=command,
                                        overwrite=True)
    campaign = read_campaign(camp_dir)
    rep = Replayer(campaign)
    d = diagnose(campaign, replayer=rep)
    diag_dir = outdir / "diagnosis"
    diag_cmd = f"ehas diagnose {camp_dir} --json {diag_dir / 'diagnosis.json'} --out {diag_dir}"
    diag_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(diag_dir / "diagnosis.json", json.dumps(d.to_json(), indent=2) + "\n")
    tables = {"baseline": d.baseline.table, "baseline, beta/K recal.": d.null.table}
    sims = {"baseline": d.baseline.sims, "baseline, beta/K recal.": d.null.sims}
    label = model = None
    if d.found != "none":
        label = f"+ {d.found}"
        tables[label], sims[label] = d.top.fit.table, d.top.fit.sims
        model = d.top.fit.model
        save_model(outdir / "model.json", model.effects, beta=model.beta, K=model.K,
                   calibration={"campaign": str(camp_dir), "command": diag_cmd,
                                "fit_percent_before": round(d.baseline.table.overall, 2),
                                "fit_percent_after": round(d.top.fit.table.overall, 2)})
    write_report(diag_dir, rep, sims, tables, campaign=campaign, command=diag_cmd, after_label=label,
                 after_model=model, fitted=True, diagnosis=d, title="Diagnosis")
    from ehas_env.cli.compare import _params_text

    hidden = ", ".join(f"{n} ({_params_text(n, p)})" for n, p in truth["effects"].items())
    lines = ["## Model vs measurement: finding a hidden effect", "",
             f"A synthetic campaign ({len(campaign.runs)} runs: 4 closed-loop sine runs across disc sets, amplitudes and "
             f"frequencies, plus a valve chirp; sensor noise; beta and K perturbed) was simulated with **{hidden}** "
             f"hidden, then diagnosed blind: every effect of the library added in turn and fitted.", "",
             f"Regenerate: `{command}` then `{diag_cmd}`", "",
             "| rank | effect | fitted | score dB | fit % |", "|---|---|---|---|---|"]
    for i, e in enumerate(d.ranking[:4]):
        lines.append(f"| {i + 1} | {e.effect} | {_params_text(e.effect, e.params)} | {e.score:.2f} | {e.fit_percent:.1f} |")
    lines += ["", f"Diagnosis: **{d.found}**. Evidence: {d.top.evidence}.", ""]
    if model is not None:
        lines += [f"Adding it: overall fit {d.baseline.table.overall:.1f} % -> {d.top.fit.table.overall:.1f} % "
                  f"(baseline -> calibrated model, saved as `{outdir / 'model.json'}` for `--model`).", ""]
    lines += [f"Report: `{diag_dir / 'report.md'}` ({time.perf_counter() - t0:.0f} s).", ""]
    return "\n".join(lines)
