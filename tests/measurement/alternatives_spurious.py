"""No spurious alternatives: on campaigns where one explanation is clearly right, does the diagnosis list another
that its own data in fact separate?

Issue 34 asks that at most 5 % of the acceptance campaigns (tests/independent_rig/cases.py: clean, library-only,
out-of-library) list an alternative (``alternatives`` of ``ehas diagnose --json``: one the logs cannot tell from
the reported explanation) that the data separate by more than 3 dB.  For each campaign this module simulates it
with the independent generator (no shared code with ehas), diagnoses it as the acceptance does (``--model`` on the
rigs with a model file), and for every alternative listed checks the two figures the diagnosis itself records on
all the campaign's runs: ``score_difference_db`` (the whole campaign) and the largest ``per_run_db`` (one run).
An alternative is *spurious* when either exceeds 3 dB: the data separate it, yet it is listed as not told apart.

Run from the repository's root (tens of minutes on two cores; resumable)::

    python -m tests.measurement.alternatives_spurious [--cases ID,...] [--work DIR]

The table covers every case finished so far (``--cases`` adds cases to it).

Each case's record is kept in ``results/test_plans/spurious/ID.json``; the table is
``results/test_plans/spurious.md``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "results" / "test_plans"
SEPARATED_DB = 3.0  # issue 34: an alternative the data separate by more than this is spurious

#: a representative part of the acceptance set: every rig, every library effect, out-of-library effects of each
#: place whose rivals the diagnosis fits (tests/independent_rig/cases.py ids)
DEFAULT = ("clean_book_s0", "clean_book_s1", "clean_rig_b_s0", "clean_rig_c_s0",
           "lib_coulomb_friction_0", "lib_viscous_friction_0", "lib_transport_delay_0", "lib_valve_null_bias_0",
           "lib_internal_leakage_0", "ool_lugre_friction_strong", "ool_disc_drag_strong",
           "ool_return_pressure_strong", "clean_book_s2", "clean_book_s3", "ool_load_compliance_strong",
           "ool_crank_offset_strong", "ool_current_lag_strong", "ool_turbulent_leakage_strong",
           "ool_valve_underlap_strong", "ool_entrained_air_strong", "ool_single_rod_strong",
           "ool_supply_line_loss_strong", "ool_crank_unbalance_strong")


def spurious(doc: dict, limit_db: float = SEPARATED_DB) -> list[dict]:
    """The alternatives a diagnosis lists although its own data separate them by more than ``limit_db``.

    Parameters
    ----------
    doc : dict
        A diagnosis JSON (``ehas diagnose --json``).
    limit_db : float
        dB.

    Returns
    -------
    list of dict
        Per spurious alternative: ``name``, ``in_place_of``, ``score_difference_db``, ``max_run_db``, ``run``.
    """
    out = []
    for a in doc.get("alternatives", []):
        runs = a.get("per_run_db") or {}
        worst = max(runs, key=runs.get) if runs else None
        top = runs[worst] if worst else float("-inf")
        if a["score_difference_db"] > limit_db or top > limit_db:
            out.append({"name": a["name"], "in_place_of": a["in_place_of"],
                        "score_difference_db": a["score_difference_db"], "max_run_db": top, "run": worst})
    return out


def run_case(case: dict, work: Path) -> dict:
    """Generate (or reuse) and diagnose one acceptance case; its record."""
    from tests.independent_rig import campaign as gen
    from tests.independent_rig.acceptance import rig_model
    from ehas_env.cli.main import main as ehas

    wdir = work / case["id"]
    camp = wdir / "campaign"
    t0 = time.time()
    if not (camp / "truth.json").exists():
        runs, truth = gen.simulate(case["effects"], seed=case["seed"], rig=case["rig"], duration=case["duration"])
        gen.write(camp, runs, truth, overwrite=True)
    model = rig_model(case["rig"])
    diag = wdir / "diag.json"
    argv = ["diagnose", str(camp), "--json", str(diag), "--quiet", "--overwrite"] + (
        ["--model", str(model)] if model else [])
    code = ehas(argv)
    rec = {"id": case["id"], "group": case["group"], "rig": case["rig"], "effects": case["effects"],
           "seed": case["seed"], "command": "ehas " + " ".join(argv), "exit": code}
    if code != 0 or not diag.exists():
        return rec
    doc = json.loads(diag.read_text())
    rec.update({"reported": list(doc["reported_model"]["effects"]), "verdict": doc["verdict"],
                "alternatives": [{k: a[k] for k in ("name", "in_place_of", "score_difference_db", "resolvable_db")}
                                 | {"max_run_db": max((a.get("per_run_db") or {"-": float("nan")}).values())}
                                 for a in doc.get("alternatives", [])],
                "ruled_out": [a["name"] for a in doc.get("ruled_out", [])],
                "spurious": spurious(doc), "elapsed_s": round(time.time() - t0, 1)})
    return rec


def table(recs: list[dict]) -> str:
    lines = ["# No spurious alternatives on campaigns one explanation clearly explains", "",
             "Regenerate with (from the repository's root; tens of minutes on two cores):", "",
             "    python -m tests.measurement.alternatives_spurious", "",
             "Campaigns of the acceptance set (tests/independent_rig/cases.py), simulated by the independent "
             "generator and diagnosed (`ehas diagnose --json`, `--model` on rig_b and rig_c). An alternative listed "
             f"(not told apart from the reported explanation) is spurious when the campaign's own data separate them "
             f"by more than {SEPARATED_DB:g} dB: its `score_difference_db` over all runs, or its largest "
             "`per_run_db` on one run (tests/measurement/alternatives_spurious.py).", "",
             "| case | truth | rig | reported | alternatives listed (score diff / largest run, dB) | ruled out | "
             "spurious |", "|---|---|---|---|---|---|---|"]
    for r in recs:
        if "verdict" not in r:
            lines.append(f"| {r['id']} | {r['effects'] or 'none'} | {r['rig']} | diagnose exited {r['exit']} | | | |")
            continue
        alts = ", ".join(f"{a['name']} for {a['in_place_of']} ({a['score_difference_db']:+.2f} / "
                         f"{a['max_run_db']:+.2f})" for a in r["alternatives"]) or "none"
        truth = ", ".join(f"{n} {v}" for n, v in r["effects"].items()) or "none"
        lines.append(f"| {r['id']} | {truth} | {r['rig']} | {', '.join(r['reported']) or 'none'} | {alts} | "
                     f"{', '.join(r['ruled_out']) or 'none'} | {'yes' if r['spurious'] else 'no'} |")
    done = [r for r in recs if "verdict" in r]
    if done:
        n_sp = sum(bool(r["spurious"]) for r in done)
        n_alt = sum(bool(r["alternatives"]) for r in done)
        lines += ["", f"Campaigns: {len(done)}; listing any alternative: {n_alt}; listing a spurious one (separated "
                      f"by > {SEPARATED_DB:g} dB): {n_sp} ({100.0 * n_sp / len(done):.0f} %; issue 34: at most 5 %)."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    from tests.independent_rig.cases import all_cases

    ap = argparse.ArgumentParser(description="spurious alternatives on the acceptance campaigns")
    ap.add_argument("--cases", default=",".join(DEFAULT), help="acceptance case ids, comma-separated")
    ap.add_argument("--work", default="/tmp/ehas_spurious", help="folder for the campaigns and diagnoses")
    ap.add_argument("--redo", action="store_true", help="rediagnose cases already finished")
    a = ap.parse_args(argv)
    known = {c["id"]: c for c in all_cases()}
    ids = [c.strip() for c in a.cases.split(",") if c.strip()]
    bad = [c for c in ids if c not in known]
    if bad:
        print(f"alternatives_spurious: error: unknown case {bad[0]!r} (ids of tests/independent_rig/cases.py)",
              file=sys.stderr)
        return 2
    from ehas_env.output.files import atomic_write_text

    (OUT / "spurious").mkdir(parents=True, exist_ok=True)
    for cid in ids:
        path = OUT / "spurious" / f"{cid}.json"
        if path.exists() and not a.redo:
            continue
        print(f"[spurious] {cid}: simulating and diagnosing", flush=True)
        rec = run_case(known[cid], Path(a.work))
        atomic_write_text(path, json.dumps(rec, indent=1) + "\n")
        print(f"[spurious] {cid}: {json.dumps(rec)}", flush=True)
    order = [c["id"] for c in all_cases()]  # every case finished so far, in the acceptance set's order
    recs = [json.loads((OUT / "spurious" / f"{c}.json").read_text()) for c in order
            if (OUT / "spurious" / f"{c}.json").exists()]
    atomic_write_text(OUT / "spurious.md", table(recs))
    print(table(recs))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
