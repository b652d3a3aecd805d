"""``ehas plan-test DIAGNOSIS.json --out PLAN.json``: the runs that decide between explanations a campaign cannot
tell apart.

The design is :mod:`ehas_env.diagnosis.experiment_design`; the alternatives come from
the diagnosis JSON (``ehas diagnose --json``, key ``alternatives``), the
controller, supply and noise levels from the campaign it names.
"""
from __future__ import annotations

import argparse
import json
import time


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("diagnosis", help="the diagnosis JSON that ehas diagnose CAMPAIGN --json wrote")
    parser.add_argument("--out", required=True, metavar="PLAN.json",
                        help="the test plan to write (docs/measurement-format.md, 'The test plan')")
    parser.add_argument("--campaign", default=None, metavar="DIR",
                        help="the campaign folder (default: the one the diagnosis names)")
    parser.add_argument("--model", default=None, metavar="FILE",
                        help="the model file the diagnosis was made on (ehas diagnose --model FILE): the plan is "
                             "simulated on that rig and kept inside its envelope")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing PLAN.json")


def run(args) -> int:
    from pathlib import Path

    from ehas_env.measurement.campaign import read_campaign
    from ehas_env.diagnosis.experiment_design import Envelope, check_plan, plan_test, read_diagnosis, rig_model
    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.outputs import check_file, check_not_input
    from ehas_env.output.progress import status, working

    t0 = time.perf_counter()
    parent = Path(args.out).absolute().parent
    if not parent.is_dir():
        raise FileNotFoundError(f"--out {args.out}: the folder {parent} does not exist; create it or write the plan "
                                "elsewhere")
    check_not_input(args.out, "--out", [args.diagnosis])
    check_file(args.out, "--out", overwrite=args.overwrite)
    doc, explanations = read_diagnosis(args.diagnosis)
    model = rig_model(doc, args.model, args.diagnosis)
    envelope = Envelope.for_model(model)
    folder = Path(args.campaign or doc["campaign"])
    if not folder.is_dir():
        raise FileNotFoundError(f"{args.diagnosis}: its campaign {folder} is not a folder here; give it with "
                                "--campaign DIR")
    campaign = read_campaign(folder)
    if len(explanations) < 2:
        print(f"{args.diagnosis}: the diagnosis lists no alternative the logs cannot tell from "
              f"{explanations[0].name}; nothing to separate: the plan has no runs")
    else:
        print(f"explanations to separate: {explanations[0].name} (reported) vs "
              + ", ".join(e.name for e in explanations[1:]))
    with working("designing the runs: simulating candidate runs inside the rig's envelope with every explanation's "
                 "model", "plan-test"):
        plan = plan_test(doc, explanations, campaign, envelope=envelope, model=model,
                         say=lambda msg: status(msg, "plan-test"))
    out = plan.to_json()
    check_plan(out, envelope, where=str(args.out))
    print(f"{plan.n_candidates} candidate runs simulated inside the envelope of "
          + ("the book's rig" if model is None else f"the rig of {model.label}")
          + (f", {len(plan.left_out)} left out (the rig would not follow them, their cycles would not repeat, or a "
             "chamber pressure would come near the tank or above the supply)"
             if plan.left_out else ""))
    for line in plan.why:
        print("  " + line)
    for s in out["separates"]:
        print(f"separates {s['a']} from {s['b']} by {s['predicted_db']:.1f} dB over the campaign's noise "
              f"(the campaign: within what its logs resolve)")
    if plan.pairs and not plan.runs:
        print("no run inside the envelope separates them by 0.3 dB: these explanations stay apart only outside it")
    atomic_write_text(args.out, json.dumps(out, indent=2) + "\n")
    print(f"plan: {args.out} ({len(out['runs'])} runs, {sum(r['duration_s'] for r in out['runs']):g} s of logging); "
          f"log them into the campaign folder and run ehas diagnose again")
    print(f"planned in {time.perf_counter() - t0:.1f} s")
    return 0
