"""``ehas diagnose``: where the model fails, which effects of the library explain it, and what is still missing.

``ehas diagnose CAMPAIGN_DIR [--json FILE] [--out DIR]`` replays the campaign
with the baseline, prints where it fails (residual signatures per signal), then
adds every effect of the library in turn, fits it (with beta and K), ranks them
with evidence in words, and stacks: the best effect is kept when it is
physically sane and lowers the residual of validation data (runs held out of
the fit, ``--holdout``, and the fitted runs beyond their fit windows), then the
next is sought on top of it, until no candidate passes (``--no-stack``: one
round), the same effect refitted on two separate groups of runs must agree
within its 95 % intervals.  When the library leaves the campaign not explained,
the structural hypotheses (``hyp_*``: chamber B's area, the return pressure, the
valve's gain per direction) are tried the same way.  The verdict is graded from
the data (the residual against what does not repeat from cycle to cycle:
*explained*, *small structured residual*, *unexplained*); then it shows what the
remaining residual follows and, when not explained, proposes the missing term
(``--write-effect DIR/NAME.py`` writes the kept hypothesis, else the proposed
term, as an effect file for ``ehas compare CAMPAIGN --effects-path DIR
--effects NAME --fit --json FILE``).
``--json`` writes the JSON of docs/measurement-format.md; ``--out`` a report.md
with plots.  ``--with NAME[,NAME...]`` starts from a model that already has
those effects.  Candidates are the library's effects and the effects of the
``--effects-path`` folders (``--candidates`` narrows or widens that: names,
``library``, ``all``).
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path

from ehas_env.ranges import number, split_list



def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("campaign", metavar="CAMPAIGN_DIR", nargs="+",
                        help="folder of RUN.csv + RUN.json pairs (docs/measurement-format.md); several folders, in "
                             "the order recorded: each diagnosed, then a health trend (the parameters per campaign "
                             "with their intervals, and which changed)")
    parser.add_argument("--json", default=None, metavar="FILE", help="write the diagnosis as JSON (docs/measurement-format.md)")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="folder for report.md, its plots and diagnosis.json (the JSON of --json)")
    parser.add_argument("--html", action="store_true",
                        help="also write DIR/report.html (needs --out): one self-contained page to open offline, "
                             "as ehas report DIR writes it")
    parser.add_argument("--with", dest="with_effects", default=None, metavar="NAME[,NAME...]",
                        help="effects already added (fitted with each candidate): find the next one")
    parser.add_argument("--stack", action="store_true",
                        help="stack effects (the default): keep the best while it is sane and lowers the "
                             "validation residual, then look again")
    parser.add_argument("--no-stack", action="store_true", help="one round: rank the candidates, keep at most one")
    parser.add_argument("--candidates", default=None, metavar="NAME[,NAME...]",
                        help="try only these effects; 'library' = every effect of ehas's library, 'all' = those "
                             "and every other registered effect (default: the library and the effects of "
                             "--effects-path)")
    parser.add_argument("--holdout", default=None, metavar="RUN[,RUN...]",
                        help="runs kept out of the fit for validation ('none': none); default with >= 4 runs: "
                             "one closed-loop run per 4 runs, the most central one")
    parser.add_argument("--fit-window", type=number("--fit-window", "s", 0.5, 600.0), default=None, metavar="S",
                        help="seconds of each closed-loop run the fit uses (default 3; the rest validates)")
    parser.add_argument("--write-effect", default=None, metavar="DIR/NAME.py",
                        help="when the campaign is unexplained, write the proposed term as an effect file NAME")
    parser.add_argument("--no-propose", action="store_true", help="do not look for a missing term")
    parser.add_argument("--no-hypotheses", action="store_true",
                        help="do not try the structural hypotheses (hyp_*: chamber B's area, return pressure, valve "
                             "gain per direction) when the library leaves the campaign not explained")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier --out folder / --json file / --write-effect file")
    parser.add_argument("--save-model", default=None, metavar="FILE",
                        help="write the final model as a model file (docs/model-file.md): ehas compare CAMPAIGN "
                             "--model FILE prints the same noise figure as this diagnosis (--out DIR writes "
                             "DIR/model.json too)")
    from ehas_env.simulation.executors import add_executor_arguments

    add_executor_arguments(parser)  # several campaigns (a fleet of rigs): each diagnosis one task, here or on Ray
    parser.add_argument("--checkpoint", default=None, metavar="DIR",
                        help="several campaigns: keep each finished diagnosis in DIR and skip it when the same "
                             "command runs again (resume after Ctrl-C or a lost node)")
    parser.add_argument("--columns", default=None, metavar="NEW=OLD[,NEW=OLD...]",
                        help="map a logger's column names onto the format's, e.g. theta_deg=Angle1,current_mA=I_cmd "
                             "(docs/measurement-format.md)")


def run(args) -> int:
    camps = args.campaign if isinstance(args.campaign, (list, tuple)) else [args.campaign]
    if len(camps) > 1:
        return run_trend(args, list(camps))
    args.campaign = camps[0]
    return run_one(args)


def run_trend(args, camps: list) -> int:
    """``ehas diagnose CAMP1 CAMP2 ...``: each campaign diagnosed as alone (its JSON kept), then the health trend
    (:func:`ehas_env.diagnosis.health.trend`); ``--json`` writes {"campaigns": [each diagnosis JSON], "trend"}."""
    import copy

    from ehas_env.diagnosis.health import trend, trend_text
    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.outputs import check_file, check_not_input

    for flag, v in (("--out", args.out), ("--write-effect", args.write_effect)):
        if v:
            raise ValueError(f"{flag}: one campaign at a time (several campaign folders give a health trend; "
                             f"diagnose a campaign alone for {flag})")
    if len(set(map(str, camps))) < len(camps):
        raise ValueError("CAMPAIGN_DIR: a folder is named twice; name each campaign once, in the order recorded")
    if args.json:
        check_not_input(args.json, "--json", camps)
        check_file(args.json, "--json", overwrite=args.overwrite)
    from ehas_env.measurement.campaign import parse_column_map, read_campaign

    for c in camps:  # every folder read (and refused, one line) before any work
        read_campaign(c, columns=parse_column_map(args.columns))
    docs = fleet_docs(args, camps)
    t = trend([(str(c), d["model"]["ci95"]) for c, d in zip(camps, docs)])
    print(trend_text(t))
    if args.json:
        atomic_write_text(args.json, json.dumps({"campaigns": docs, "trend": t}, indent=2) + "\n")
        print(f"json: {args.json}")
    return 0


#: the options of one campaign's diagnosis that a fleet task carries (the rest are the fleet's own)
FLEET_OPTIONS = ("with_effects", "stack", "no_stack", "candidates", "holdout", "fit_window", "no_propose",
                 "no_hypotheses", "columns", "model", "effects_path")


def fleet_task(task: dict) -> dict:
    """One campaign of a fleet diagnosed as alone (a task of :mod:`ehas_env.simulation.executors`: picklable, it
    runs in this process, a local worker or a Ray worker): its console text and its diagnosis JSON.

    Parameters
    ----------
    task : dict
        ``campaign`` (the folder), ``options`` (the diagnose options of :data:`FLEET_OPTIONS`).

    Returns
    -------
    dict
        ``campaign``, ``console`` (what ``ehas diagnose CAMPAIGN`` prints), ``doc`` (its ``--json``).
    """
    import contextlib
    import io

    opts = argparse.Namespace(**task["options"], campaign=task["campaign"], json=None, out=None, html=False,
                              write_effect=None, save_model=None, quiet=True, overwrite=False)
    if opts.effects_path:  # a worker of another process loads the user's effect files as the driver did
        from ehas_env.physics.effects import load_effects_path

        load_effects_path(opts.effects_path)
    sink: list = []
    opts.doc_sink = sink
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        run_one(opts)
    return {"campaign": str(task["campaign"]), "console": out.getvalue(), "doc": sink[0]}


def fleet_docs(args, camps: list) -> list[dict]:
    """Every campaign of a fleet diagnosed as alone, on the executor the options name (``--executor local
    --workers N``, ``--executor ray [--address A]``), in the order given, each one's console text printed in that
    order; with ``--checkpoint DIR`` each finished diagnosis is kept in DIR and a rerun of the same command skips
    it.  The JSON of each is the one ``ehas diagnose CAMPAIGN --json`` writes, wherever it ran.

    Parameters
    ----------
    args : argparse.Namespace
        The diagnose options.
    camps : list
        The campaign folders, in the order recorded.

    Returns
    -------
    list of dict
        Each campaign's diagnosis JSON.
    """
    from ehas_env.output.files import atomic_write_text
    from ehas_env.simulation.executors import executor_from_args

    options = {k: getattr(args, k, None) for k in FLEET_OPTIONS}
    tasks = [{"campaign": str(c), "options": options} for c in camps]
    done: dict[int, dict] = {}
    ck = Path(args.checkpoint) if getattr(args, "checkpoint", None) else None
    if ck is not None:
        if ck.exists() and not ck.is_dir():
            raise ValueError(f"--checkpoint {ck}: is a file, not a folder; give a folder (made when missing)")
        ck.mkdir(parents=True, exist_ok=True)
        for k, task in enumerate(tasks):
            f = ck / f"{k:03d}.json"
            if f.is_file():
                try:
                    rec = json.loads(f.read_text())
                    kept = rec["result"] if rec.get("task") == task else None  # same campaign, same options
                except (ValueError, KeyError, TypeError, AttributeError):
                    print(f"{f}: not a checkpoint this command wrote; diagnosing that campaign again")
                    kept = None
                if kept is not None:
                    done[k] = kept
    todo = [k for k in range(len(tasks)) if k not in done]
    if done:
        print(f"{len(done)} of {len(tasks)} campaigns kept from {ck}; diagnosing {len(todo)}")

    def keep(k, result):
        done[k] = result
        if ck is not None:
            atomic_write_text(ck / f"{k:03d}.json", json.dumps({"task": tasks[k], "result": result}) + "\n")

    executor = executor_from_args(args)
    if getattr(executor, "workers", 2) == 1 and executor.name == "local":
        # in this process, one after the other: each printed (with its progress) as it runs, kept as it ends
        import contextlib
        import io

        for k, c in enumerate(camps):
            print(f"=== campaign {k + 1} of {len(camps)}: {c} ===")
            if k in done:
                print(done[k]["console"])
                continue
            sub = argparse.Namespace(**{**vars(args), "campaign": c, "json": None, "doc_sink": []})
            text = io.StringIO()
            with contextlib.redirect_stdout(_Tee(sys.stdout, text)):
                run_one(sub)
            keep(k, {"campaign": str(c), "console": text.getvalue(), "doc": sub.doc_sink[0]})
            print()
        return [done[k]["doc"] for k in range(len(camps))]
    if todo:
        where = (f"{executor.workers} local processes" if executor.name == "local" else
                 f"the Ray cluster at {args.address}" if getattr(args, "address", None) else "a local Ray instance")
        print(f"diagnosing {len(todo)} campaigns on {where}")
        for k, result in zip(todo, executor.map(fleet_task, [tasks[k] for k in todo], desc="campaigns")):
            keep(k, result)
    for k, c in enumerate(camps):
        print(f"=== campaign {k + 1} of {len(camps)}: {c} ===")
        print(done[k]["console"])
    return [done[k]["doc"] for k in range(len(camps))]


class _Tee:
    """Writes to two streams (a fleet's console shown as it runs and kept for its checkpoint)."""

    def __init__(self, *streams):
        self.streams = streams

    def write(self, text):
        for st in self.streams:
            st.write(text)
        return len(text)

    def flush(self):
        for st in self.streams:
            st.flush()


def run_one(args) -> int:
    from ehas_env.measurement.campaign import parse_column_map, read_campaign
    from ehas_env.diagnosis.candidates import FIT_WINDOW_S, resolve_candidates
    from ehas_env.diagnosis.pipeline import diagnose_open
    from ehas_env.physics.effects import get_effect, parse_spec
    from ehas_env.measurement.replay import format_fit_tables
    from ehas_env.measurement.residuals import follows_text, where_it_fails
    from ehas_env.measurement.verdict import envelope_text, figure_text
    from ehas_env.output.outputs import OutputSet, check_file, check_not_input

    t0 = time.perf_counter()
    base = parse_spec(args.with_effects) if args.with_effects else {}
    spec = None if args.candidates is None else split_list(args.candidates, "--candidates",
                                                              "effect names (or library, all)")
    candidates = resolve_candidates(spec, getattr(args, "effects_path", None))
    # bad values refused before any work; a parameter not given starts from its default
    base = {n: get_effect(n).resolve(p) for n, p in base.items()}
    both = [c for c in (spec or []) if c in base]
    if both:
        raise ValueError(f"--candidates: {both[0]} is already in --with (candidates are tried on top of the "
                         f"--with effects); name effects not in --with: {', '.join(base)}")
    window = FIT_WINDOW_S if args.fit_window is None else args.fit_window
    if not 0.5 <= window <= 600:
        raise ValueError(f"--fit-window {window:g}: give 0.5 to 600 s")
    holdout = None
    if args.holdout is not None:
        holdout = [] if args.holdout.strip().lower() == "none" else split_list(args.holdout, "--holdout", "run names (or none)")
    # the output paths, before any work
    if args.json:
        check_not_input(args.json, "--json", [args.campaign])
        check_file(args.json, "--json", overwrite=args.overwrite)
    if getattr(args, "save_model", None):
        check_not_input(args.save_model, "--save-model", [args.campaign])
        check_file(args.save_model, "--save-model", overwrite=args.overwrite)
        if Path(args.save_model).suffix != ".json":
            raise ValueError(f"--save-model {args.save_model}: give a .json file (a model file, docs/model-file.md)")
    if args.out:
        check_not_input(args.out, "--out", [args.campaign])
    elif getattr(args, "html", False):
        raise ValueError("--html writes DIR/report.html: give --out DIR as well")
    if args.write_effect:
        check_not_input(args.write_effect, "--write-effect", [args.campaign])
        we = Path(args.write_effect)
        if we.suffix != ".py" or not we.stem.isidentifier():
            raise ValueError(f"--write-effect {we}: give DIR/NAME.py with NAME a Python identifier (it names the effect)")
        from ehas_env.physics.effects import REGISTRY

        if we.stem in REGISTRY:  # the written file would register a second effect of that name and fail to load
            raise ValueError(f"--write-effect {we}: '{we.stem}' is already an effect's name; choose a new NAME")
        check_file(args.write_effect, "--write-effect", overwrite=args.overwrite)
    outputs = OutputSet(args.out, "--out", overwrite=args.overwrite) if args.out else None
    campaign = read_campaign(args.campaign, columns=parse_column_map(args.columns))
    closed = [r.name for r in campaign.runs if r.meta.get("kind") == "closed_loop"]
    if holdout and closed and set(closed) <= set(holdout) and len(closed) < len(campaign.runs):
        raise ValueError(f"--holdout {args.holdout}: holds out every closed-loop run ({', '.join(closed)}); the fit "
                         "would see valve runs only and could not place effects on the load; hold out fewer")
    say = (lambda msg: None)
    if not args.quiet:
        from ehas_env.output.progress import status

        status(f"{len(campaign.runs)} runs read; compiling or loading the model, then timing a replay of the "
               "campaign to say how long the diagnosis will take", "diagnose")
        say = (lambda msg: status(msg, "diagnose"))
    model = None
    if getattr(args, "model", None):  # diagnose on that rig, its effects on (docs/model-file.md)
        from ehas_env.simulation.model_file import load_model

        model = load_model(args.model)
        print(f"baseline: model {model.label}")
    print(campaign.summary())
    if not args.candidates and candidates:
        from ehas_env.diagnosis.candidates import library_effects

        print(f"candidates: the library and, from --effects-path, "
              f"{', '.join(c for c in candidates if c not in library_effects())}")
    print()
    res = diagnose_open(campaign, candidates=candidates, base_effects=base, holdout=holdout,
                        stack=not args.no_stack, propose=not args.no_propose,
                        hypotheses=not getattr(args, "no_hypotheses", False), window_s=window,
                        progress=not args.quiet, log=say, model=model)
    first = res.first
    print(where_it_fails(res.full, res.baseline_all, "baseline" + (" + " + " + ".join(base) if base else "")))
    print()
    for d in res.rounds:
        print(_ranking_text(d, res.train))
        print()
    print(_stack_text(res))
    print()
    tables = {"baseline": res.full.fit_table(res.baseline_all), "final model": res.full.fit_table(res.sims_all)}
    print(format_fit_tables(tables).split("\n\nfit % per run")[0].replace(
        "fit % (NRMSE) per signal, mean over runs", "fit % (NRMSE) per signal, baseline vs final model, mean over runs", 1))
    print()
    print(_model_text(res))
    print()
    print(_validation_text(res))
    print()
    print(follows_text(res.follows, "final model"))
    print()
    print(f"verdict: {res.verdict}, residual {figure_text(res.residual_x_noise)}")
    envelope = envelope_text(res.grade)  # the runs judged on their cycle envelope (None: none)
    if envelope:
        print(envelope)
    if res.unexplained is not None:
        print(res.unexplained["text"])
    else:
        print(f"the final model explains the campaign: its residual is {figure_text(res.residual_x_noise)} from "
              f"cycle to cycle (sensor noise, disturbances; explained up to {res.grade['thresholds']['explained']:g}x)")
    if res.alternatives:  # what these logs cannot tell apart (ehas_env.diagnosis.alternatives)
        from ehas_env.diagnosis.alternatives import alternatives_text

        print(alternatives_text(res.alternatives, res.model.effects))
    for line in _findings_lines(res):  # per-run drift, disturbances, fits on a bound (issue 33)
        print(line)
    written = next_line = None
    for name in res.states:  # generic augmentations kept (the states stage's, or one fitted in place of an effect)
        print(f"missing state kept: {name} ({get_effect(name).in_words(res.model.effects[name])})")
    hyp = res.hypothesis
    if hyp is not None:
        h = res.hypothesis_json()
        print()
        print(f"structural hypothesis kept: {h['effect']} ({h['words']})")
        for other in [n for n in res.model.effects if n != hyp and get_effect(n).kind == "hypothesis"]:
            print(f"  kept with it: {other} ({get_effect(other).in_words(res.model.effects[other])})")
    if hyp is not None and res.proposal is None:  # (with a term proposed on top, the term's file is written)
        if args.write_effect:
            from ehas_env.diagnosis.hypothesis_file import write_hypothesis

            written = write_hypothesis(args.write_effect, hyp, res.model.effects[hyp], origin=str(campaign.path),
                                       ci={k: tuple(v) for k, v in h["ci95"].items()}, words=h["words"],
                                       before=h.get("residual_x_noise_before"), after=res.residual_x_noise)
            name = Path(args.write_effect).stem
            print(f"effect file: {args.write_effect}")
            next_line = next_command(args, campaign.path, [n for n in res.model.effects if n != hyp] + [name],
                                     extra_path=Path(args.write_effect).parent, measured_inputs=res.measured_inputs,
                                     values=res.model.effects)
            print("next: " + next_line)
    elif res.proposal is not None:
        p = res.proposal
        print()
        print("proposed missing term:")
        print("  " + p.equation().replace("\n", "\n  "))
        v = p.validation
        print(f"  residual {v['residual_x_noise_all_before']:.3g}x -> {v['residual_x_noise_all_after']:.3g}x noise, "
              f"fit {v['fit_percent_all_before']:.1f} % -> {v['fit_percent_all_after']:.1f} % (all data)")
        for n in p.named:  # the term's shape in physical words (ehas_env.diagnosis.naming)
            print(f"  named: {n['words']} ({n['kind']}, at {n['place'].replace('_', ' ')}; keeps "
                  f"{100 * n['keeps_share']:.0f} % of the flexible term's gain)")
        if not p.named and (p.naming or {}).get("text"):
            print(f"  named: nothing ({p.naming['text']})")
        if args.write_effect:
            from ehas_env.diagnosis.proposal import write_effect

            written = write_effect(args.write_effect, p, origin=str(campaign.path))
            name = Path(args.write_effect).stem
            print(f"effect file: {args.write_effect}")
            next_line = next_command(args, campaign.path, list(res.model.effects) + [name],
                                     extra_path=Path(args.write_effect).parent, measured_inputs=res.measured_inputs,
                                     values=res.model.effects)
            print("next: " + next_line)
    elif args.write_effect:
        print("no effect file written: " + ("the campaign is explained" if res.unexplained is None else
                                            "no term of the dictionary lowers the residual"))
    if next_line is None and (res.model.effects or res.measured_inputs):  # the final model (a kept hypothesis is
        # a registered effect; a logged quantity kept as a measured input is given as one)
        next_line = next_command(args, campaign.path, list(res.model.effects), measured_inputs=res.measured_inputs,
                                 values=res.model.effects)
        print("next: " + next_line)
    elapsed = time.perf_counter() - t0
    print(f"diagnosed {len(campaign.runs)} runs in {elapsed:.1f} s ({res.n_evals} replays)")

    command = "ehas diagnose " + " ".join(shlex.quote(a) for a in _argv())
    from ehas_env.output.files import atomic_write_text

    doc = diagnosis_doc(res, campaign.path, elapsed, effect_file=args.write_effect if written else None)
    if next_line:
        doc["next"] = next_line
    if getattr(args, "doc_sink", None) is not None:  # several campaigns: the health trend collects each JSON
        args.doc_sink.append(doc)
    if args.json:
        atomic_write_text(args.json, json.dumps(doc, indent=2) + "\n")
        print(f"json: {args.json}")
    if getattr(args, "save_model", None):
        save_final_model(args.save_model, res, campaign.path, command, model)
        print(f"model file: {args.save_model} (ehas compare {shlex.quote(str(campaign.path))} --model "
              f"{shlex.quote(str(args.save_model))} gives the same {figure_text(res.residual_x_noise)})")
    if outputs is not None:
        from ehas_env.cli.compare import write_report

        sims = {"baseline": res.baseline_all}
        tabs = {"baseline": tables["baseline"]}
        label = after = None  # the report's model with the effects (``model`` stays the rig diagnosed on)
        if res.model.effects:
            label = "+ " + " + ".join(res.model.effects)
            sims[label], tabs[label] = res.sims_all, tables["final model"]
            after = res.model
        with outputs as tmp:
            path = write_report(tmp, res.full, sims, tabs, campaign=campaign, command=command, after_label=label,
                                after_model=after, fitted=True, diagnosis=first, title="Diagnosis",
                                holdout=res.holdout)
            extra = ["## 6. Stacking, confidence and validation", "", "```", _stack_text(res), "",
                     _model_text(res), "", _validation_text(res), "```", "",
                     "## 7. Verdict and what is left", "",
                     f"**{res.verdict}**: residual {figure_text(res.residual_x_noise)} from cycle to cycle.", "",
                     *([envelope + ".", ""] if envelope else []),
                     "![verdict](verdict.png)", "",
                     res.unexplained["text"] if res.unexplained else "", "",
                     "```", follows_text(res.follows, "final model"), "```", ""]
            if _findings_lines(res):
                extra += ["```", *_findings_lines(res), "```", ""]
            if res.alternatives:
                from ehas_env.diagnosis.alternatives import alternatives_text

                extra += ["### What these logs cannot tell apart", "",
                          alternatives_text(res.alternatives, res.model.effects).replace("\n", "\n\n"), ""]
            if res.proposal is not None:
                extra += ["## 8. The missing term, proposed", "", "```", res.proposal.equation(), "```", "",
                          f"Fit on all data {res.proposal.validation['fit_percent_all_before']:.1f} % -> "
                          f"{res.proposal.validation['fit_percent_all_after']:.1f} %; residual "
                          f"{res.proposal.validation['residual_x_noise_all_before']:.3g}x -> "
                          f"{res.proposal.validation['residual_x_noise_all_after']:.3g}x noise.", ""]
            from ehas_env.diagnosis.candidates import COST_SIGNALS
            from ehas_env.diagnosis.plots import verdict_bars
            from ehas_env.measurement.verdict import blocks_of

            verdict_bars(tmp / "verdict.png", blocks_of(res.full, res.sims_all, COST_SIGNALS), res.grade,
                         holdout=res.holdout)
            with open(path, "a") as fh:
                fh.write("\n".join(extra) + "\n")
            atomic_write_text(tmp / "diagnosis.json", json.dumps(doc, indent=2) + "\n")
            save_final_model(tmp / "model.json", res, campaign.path, command, model)
            if getattr(args, "html", False):
                from ehas_env.cli.report import build_page, report_command

                build_page(doc, tmp, command=report_command(args.out)).write(tmp / "report.html")
        print(f"report: {Path(args.out) / path.name}" + (f", {Path(args.out) / 'report.html'}" if args.html else ""))
    return 0


def save_final_model(path, res, campaign_path, command: str, base=None) -> Path:
    """The diagnosis' final model as a model file (docs/model-file.md): its effects with their fitted values, beta
    and K as the rig runs them, the noise figure it was graded on and where (``calibration``).  ``ehas compare
    CAMPAIGN --model FILE`` replays exactly this model and prints the same figure.

    Parameters
    ----------
    path : str or Path
        The file to write.
    res : OpenDiagnosis
        The diagnosis.
    campaign_path : str or Path
        The campaign diagnosed.
    command : str
        The diagnose command (provenance).
    base : PlantModel, optional
        The rig diagnosed on (``--model``; default the book's).

    Returns
    -------
    Path
    """
    from ehas_env.simulation.model_file import save_model

    rig = res.full.absolute(res.model)
    cal = {"campaign": str(campaign_path), "verdict": res.verdict, "residual_x_noise": res.residual_x_noise,
           "fit_percent_after": round(res.full.fit_table(res.sims_all).overall, 2),
           "measured_inputs": list(res.measured_inputs)}
    return save_model(path, {n: dict(p) for n, p in res.model.effects.items()}, beta=rig.beta, K=rig.K,
                      base=base, calibration=cal, command=command)


def diagnosis_doc(res, campaign_path, elapsed_s: float, effect_file=None) -> dict:
    """The one JSON shape of a diagnosis (``ehas diagnose --json`` and ``ehas demo``; docs/measurement-format.md).

    Parameters
    ----------
    res : OpenDiagnosis
        The result of :func:`ehas_env.diagnosis.pipeline.diagnose_open`.
    campaign_path : str or Path
        The campaign diagnosed.
    elapsed_s : float
        Wall time of the diagnosis, compile included, s.
    effect_file : str, optional
        The effect file written for the proposal (``--write-effect``).

    Returns
    -------
    dict
        :meth:`OpenDiagnosis.to_json` with ``model.difference`` (the model as a difference from the book's rig),
        ``campaign``, ``effect_file``, ``next`` (the next command, when the model has effects and no file was
        written) and ``elapsed_s``.
    """
    from ehas_env.measurement.model_difference import model_difference

    doc = res.to_json()
    doc["model"]["difference"] = model_difference(doc["model"])
    doc["campaign"] = str(campaign_path)
    if effect_file is not None and doc.get("hypothesis"):
        doc["hypothesis"]["effect_file"] = str(effect_file)
        doc["effect_file"] = str(effect_file)
    elif effect_file is not None and doc.get("unexplained") and doc["unexplained"].get("proposal"):
        doc["unexplained"]["proposal"]["effect_file"] = str(effect_file)
        doc["effect_file"] = str(effect_file)
    if doc["model"]["effects"] and effect_file is None:
        # the comparison that saves the calibrated model (run() replaces it with the one it prints, which keeps
        # the command line's --effects-path, --model and --columns)
        doc["next"] = next_command(argparse.Namespace(), campaign_path, list(doc["model"]["effects"]),
                                   values=doc["model"]["effects"])
    doc["elapsed_s"] = round(elapsed_s, 1)
    return doc


def next_command(args, campaign_path, effects: list[str], extra_path=None, measured_inputs=(), values=None) -> str:
    """The ``ehas compare`` command that adds ``effects`` to the campaign, runnable as printed: it keeps every
    ``--effects-path`` given, the written effect file's folder, ``--model`` and ``--columns``, and always saves
    the calibrated model (``--save-model model.json``, the file ``ehas tune``/``bench --model`` take).

    Parameters
    ----------
    args : argparse.Namespace
        The diagnose command's arguments (``effects_path``, ``model``, ``columns`` are kept).
    campaign_path : str or Path
        The campaign diagnosed.
    effects : list of str
        The effects of the final model (and the written effect's name).
    extra_path : str or Path, optional
        The folder of a written effect file, added to ``--effects-path``.
    measured_inputs : sequence of str
        Logged quantities the diagnosis took as measured inputs (``--measured-input``).
    values : dict, optional
        {effect: {param: value}} (the parameters' units): the diagnosis' fitted values, given as
        ``NAME:param=value`` so that ``--fit`` starts where the diagnosis ended (a fit from the typical middle
        may stop in another valley) and reproduces its final model.

    Returns
    -------
    str
        One shell command line.
    """
    q = shlex.quote
    parts = ["ehas compare", q(str(campaign_path))]
    paths = [str(p) for p in (getattr(args, "effects_path", None) or [])]
    if extra_path is not None and str(extra_path) not in paths:
        paths.append(str(extra_path))
    parts += [f"--effects-path {q(p)}" for p in paths]
    if getattr(args, "model", None):
        parts.append(f"--model {q(str(args.model))}")
    if getattr(args, "columns", None):
        parts.append(f"--columns {q(args.columns)}")
    if measured_inputs:
        parts.append(f"--measured-input {q(','.join(measured_inputs))}")
    # the calibrated model file is what a user tunes and benchmarks on (--model): always offered
    if effects:
        vals = values or {}
        spec = [n + (":" + ",".join(f"{k}={v:.6g}" for k, v in vals[n].items()) if vals.get(n) else "")
                for n in effects]
        parts.append(f"--effects {q(','.join(spec))}")
    if effects or measured_inputs:
        parts.append("--fit")
    from ehas_env.cli.compare import next_folder

    d = Path(next_folder(campaign_path))  # beside the campaign, named after it (not the current folder)
    parts += [f"--out {q(str(d / 'compare'))}", f"--json {q(str(d / 'compare.json'))}",
              f"--save-model {q(str(d / 'model.json'))}"]
    return " ".join(parts)


def _findings_lines(res) -> list[str]:
    """Parameters that differ between runs, disturbances, and fitted parameters on a bound, in words."""
    from ehas_env.diagnosis.disturbances import disturbance_lines
    from ehas_env.diagnosis.drift import drift_lines
    from ehas_env.diagnosis.honesty import at_bound_lines, at_bounds

    return (drift_lines(res.drift, res.per_run) + disturbance_lines(res.disturbances)
            + at_bound_lines(at_bounds(res.fit_train, res.model.effects, baseline=True)))


def _stack_text(res) -> str:
    lines = ["stacking (an effect is kept when it is physically sane and lowers the residual of the validation data)"]
    if not res.steps:
        lines.append("  no candidate beat noise")
    width = max([20] + [len(s.effect) + 2 for s in res.steps])  # a generated block's name is longer than 18
    for s in res.steps:
        lines.append(f"  {s.effect:<{width}}{'kept' if s.kept else 'not kept':<10}{s.reason}")
    lines.append("final model: the baseline" + "".join(f" + {n}" for n in res.model.effects)
                 + ("" if res.model.effects else " (no effect kept)"))
    return "\n".join(lines)


def _model_text(res) -> str:
    """The final model, once: what differs from the book's rig, engineering units, 95 % intervals."""
    from ehas_env.measurement.model_difference import difference_text, model_difference

    return difference_text(model_difference(res.to_json()["model"]))


def _validation_text(res) -> str:
    """Held-out runs: fit % and the noise figure of the final model on them alone."""
    from ehas_env.diagnosis.candidates import COST_SIGNALS
    from ehas_env.measurement.verdict import figure_text, noise_figure

    v = res.validation
    lines = [f"validation: fitted on {', '.join(v['fit_runs'])} (first {v['fit_window_s']:g} s of closed-loop runs)"]
    if v["holdout"]:
        held = set(v["holdout"])
        sims = [s if c.run.name in held else None for c, s in zip(res.full.cases, res.sims_all)]
        lines.append(f"  held out: {', '.join(v['holdout'])}; fit % baseline {v['holdout_fit_percent_baseline']:.1f} -> "
                     f"model {v['holdout_fit_percent_model']:.1f}; final model's residual on them "
                     f"{figure_text(noise_figure(res.full, sims, COST_SIGNALS))}")
    else:
        lines.append("  no run held out (fewer than 4 runs, or --holdout none)")
    return "\n".join(lines)


def _argv() -> list[str]:
    argv = sys.argv[1:]
    return argv[1:] if argv and argv[0] == "diagnose" else argv


def _ranking_text(d, rep) -> str:
    """One round's ranking; the recalibrated baseline's residual as the noise figure on the fit data ``rep``."""
    from ehas_env.cli.compare import _params_text
    from ehas_env.diagnosis.candidates import COST_SIGNALS
    from ehas_env.measurement.verdict import figure_text, noise_figure

    base = f" on top of {', '.join(d.base_effects)}" if d.base_effects else ""
    lines = [f"which effect is missing{base} (recalibrated baseline{base.replace(' on top of', ' +')}: fit "
             f"{d.null.table.overall:.1f} %, residual {figure_text(noise_figure(rep, d.null.sims, COST_SIGNALS))} "
             "on the fit data)",
             f"{'rank':<5}{'effect':<20}{'score dB':>9}{'fit %':>8}  {'beats noise':<12}fitted"]
    for i, e in enumerate(d.ranking):
        lines.append(f"{i + 1:<5}{e.effect:<20}{e.score:>9.2f}{e.fit_percent:>8.1f}  {'yes' if e.beats_noise else 'no':<12}"
                     f"{_params_text(e.effect, e.params)}")
    lines.append(f"best of this round: {d.found} (whether it is kept: the stacking below; the final model after it)")
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
    from ehas_env.measurement.synthetic import write_simulated_campaign
    from ehas_env.cli.compare import write_report
    from ehas_env.diagnosis.pipeline import diagnose_open
    from ehas_env.output.files import atomic_write_text
    from ehas_env.simulation.model_file import save_model

    outdir = Path(outdir)
    t0 = time.perf_counter()
    camp_dir = outdir / "campaign"
    command = (f"ehas simulate-campaign --effects coulomb_friction:Fc={DEMO_HIDDEN['coulomb_friction']['Fc']:g} "
               f"--seed {DEMO_SEED} --perturb --out {camp_dir}")
    _, truth = write_simulated_campaign(camp_dir, DEMO_HIDDEN, seed=DEMO_SEED, perturb=True, command=command,
                                        overwrite=True)
    campaign = read_campaign(camp_dir)
    t1 = time.perf_counter()
    res = diagnose_open(campaign, stack=False, propose=False)
    d, rep = res.first, res.train
    diag_dir = outdir / "diagnosis"
    diag_cmd = f"ehas diagnose {camp_dir} --no-stack --no-propose --json {diag_dir / 'diagnosis.json'} --out {diag_dir}"
    diag_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(diag_dir / "diagnosis.json",
                      json.dumps(diagnosis_doc(res, camp_dir, time.perf_counter() - t1), indent=2) + "\n")
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
    from ehas_env.diagnosis.candidates import COST_SIGNALS
    from ehas_env.diagnosis.plots import verdict_bars
    from ehas_env.measurement.verdict import blocks_of, figure_text

    verdict_bars(diag_dir / "verdict.png", blocks_of(res.full, res.sims_all, COST_SIGNALS), res.grade)
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
    lines += ["", f"Diagnosis: **{d.found}**. Evidence: {d.top.evidence}.", "",
              f"Verdict: **{res.verdict}**, residual {figure_text(res.residual_x_noise)} from cycle to cycle "
              f"(`diagnosis/verdict.png`: per run and signal).", ""]
    if model is not None:
        lines += [f"Adding it: overall fit {d.baseline.table.overall:.1f} % -> {d.top.fit.table.overall:.1f} % "
                  f"(baseline -> calibrated model, saved as `{outdir / 'model.json'}` for `--model`).", ""]
    lines += [f"Report: `{diag_dir / 'report.md'}` ({time.perf_counter() - t0:.0f} s).", ""]
    return "\n".join(lines)
