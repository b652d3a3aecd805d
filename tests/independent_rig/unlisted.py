"""Acceptance of ``ehas diagnose`` on classes of hidden physics no one listed (issue 33, item 7).

For each case of :func:`.cases.unlisted_cases` (each class of :data:`.effects.UNLISTED` at two magnitudes, and
pairs): generate the campaign, diagnose it and compare the written effect file as
:func:`.acceptance.run_case` does, then measure the recalibrated baseline (the model with no effect, beta and K
fitted: ``ehas compare CAMP --effects viscous_friction --fit --json``, its ``recalibrated`` side) and judge
(:mod:`.judge`): right place and right kind named in physical words (:func:`.judge.judge_place_kind`), the
residual closed, a recommended term too weak to be written, a kept hypothesis that worsens the all-data residual
(:func:`.judge.honesty`).  Writes ``OUT/results.json`` and ``OUT/README.md`` with the summary against the issue's
thresholds.

Checkpoints: each finished case is ``OUT/cases/ID.json``; a rerun skips those (Ctrl-C and rerun resumes).

    python -m tests.independent_rig.unlisted --out results/diagnosis_unlisted [--only ID[,ID]] [--limit N]
        [--work DIR] [--readme-only] [--redo]
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from . import acceptance as acc
from .cases import unlisted_cases
from .effects import ALL, UNLISTED
from .judge import honesty, judge_place_kind, worded_items

#: the issue's thresholds (issue 33, "Acceptance", first point)
THRESHOLDS = {"right_place_kind_share": 0.75, "closed_share": 0.80, "weak_terms": 0, "worsening_hypotheses": 0,
              "closed_x_noise": 2.0, "closed_below_baseline": 0.20, "weak_term_share": 0.10}
#: a case's first guess of time, s (generation, diagnosis, compare of the effect file, baseline compare)
GUESS_S = 240.0
COMMAND = "python -m tests.independent_rig.unlisted --out results/diagnosis_unlisted"


def baseline_residual(camp: Path, mopt: list, wdir: Path):
    """Residual x noise of the recalibrated baseline (no effect; beta and K fitted), or None when compare fails."""
    out = wdir / "baseline.json"
    cmd = [acc.ehas_exe(), "compare", str(camp), "--effects", "viscous_friction", "--fit", "--json", str(out),
           "--overwrite"] + mopt
    code, _, _, _ = acc._run(cmd, log=wdir / "baseline.log")
    if code != 0 or not out.exists():
        return None
    return (json.loads(out.read_text()).get("recalibrated") or {}).get("residual_x_noise")


def run(case: dict, work: Path, out: Path, caps: dict) -> dict:
    """One case: :func:`.acceptance.run_case` (without its oracle), the baseline, and the judgement."""
    t0 = time.time()
    rec = acc.run_case(case, work, out, caps, resolution=False)
    if "error" in rec:
        return rec
    wdir = work / case["id"]
    model = acc.rig_model(case["rig"])
    diag = json.loads((out / "diag" / f"{case['id']}.json").read_text())
    # the diagnosis states where its search started (the recalibrated baseline on all data); older ones do not
    base = acc._num((diag.get("validation") or {}).get("residual_x_noise_recalibrated_baseline"))
    if base is None:
        base = baseline_residual(wdir / "campaign", ["--model", str(model)] if model else [], wdir)
    final = acc._num(rec.get("residual_after"))
    if final is None:
        final = acc._num(diag.get("residual_x_noise"))
    rec["place_kind"] = judge_place_kind(case["effects"], worded_items(diag))
    rec["honesty"] = honesty(diag, base, final)
    rec["disturbances"] = [{k: d.get(k) for k in ("frequency_hz", "amplitude", "unit", "signal", "boundary")}
                           for d in diag.get("disturbances") or []]
    rec["unexplained_text"] = ((diag.get("unexplained") or {}).get("no_term")
                               or (diag.get("unexplained") or {}).get("text"))
    rec["steps"]["total_s"] = round(time.time() - t0, 1)
    return rec


def rejudge(rec: dict, out: Path, place_kind=None) -> dict:
    """The record judged again from its stored diagnosis (``OUT/diag/ID.json``) by the judge as it is now (its maps
    grow with the package's forms); the measured residuals are kept.  ``place_kind(rec, diag)`` judges the place and
    kind (default :func:`.judge.judge_place_kind` of the record's hidden effects)."""
    path = out / "diag" / f"{rec['id']}.json"
    if "place_kind" not in rec or not path.exists():
        return rec
    diag = json.loads(path.read_text())
    h = rec.get("honesty") or {}
    judged = (place_kind(rec, diag) if place_kind is not None
              else judge_place_kind(rec["effects"], worded_items(diag)))
    return {**rec, "place_kind": judged, "honesty": honesty(diag, h.get("baseline"), h.get("final"))}


def summarise(recs: list[dict], thresholds: dict = THRESHOLDS, per: str = "per_effect") -> dict:
    """Figures against ``thresholds`` (default :data:`THRESHOLDS`) over the cases that ran; ``per`` names the
    judgement's per-item table (``per_effect``, the drawn set's ``per_block``)."""
    ok = [r for r in recs if "error" not in r and "place_kind" in r]
    n = len(ok)
    right = sum(1 for r in ok if r["place_kind"]["right"])
    closed = sum(1 for r in ok if r["honesty"]["closed"])
    s = {"campaigns": len(recs), "errors": len(recs) - n, "right_place_kind": right,
         "right_place_kind_share": right / n if n else None,
         "right_kind_any_form": sum(1 for r in ok if all(v["right_kind_any_form"]
                                                         for v in r["place_kind"][per].values())),
         "closed": closed, "closed_share": closed / n if n else None,
         "closed_unknown": sum(1 for r in ok if r["honesty"]["closed"] is None),
         "weak_terms": sum(1 for r in ok if r["honesty"]["weak_term"]),
         "worsening_hypotheses": sum(1 for r in ok if r["honesty"]["worsening_hypothesis"])}
    s["meets"] = {"right_place_kind": n > 0 and s["right_place_kind_share"] >= thresholds["right_place_kind_share"],
                  "closed": n > 0 and s["closed_share"] >= thresholds["closed_share"],
                  "weak_terms": s["weak_terms"] <= thresholds["weak_terms"],
                  "worsening_hypotheses": s["worsening_hypotheses"] <= thresholds["worsening_hypotheses"]}
    return s


def _f(x, nd=3):
    return "-" if x is None else (("yes" if x else "no") if isinstance(x, bool) else
                                  f"{x:.{nd}g}" if isinstance(x, (int, float)) else str(x))


def readme(recs: list[dict], summ: dict, command: str) -> str:
    """The README of ``OUT``: what was run, the summary against the thresholds, every case."""
    full = unlisted_cases()
    have = {r["id"] for r in recs}
    L = ["# Diagnosis of hidden physics no one listed (issue 33, item 7)", "",
         f"Regenerate (resumable; finished cases in `cases/` are kept): `{command}`", "",
         "Campaigns of the independent generator (`tests/independent_rig/`, plain NumPy/SciPy sharing no code with "
         "the package; `docs/independent-generator.md`) with classes of hidden physics that no library effect, no "
         "structural hypothesis (`ehas_env/physics/effects/hyp_*.py`) and no out-of-library effect of the generator "
         "describes (`tests/independent_rig/effects.py`, `UNLISTED`), each at two magnitudes, and pairs.  Each is "
         "diagnosed (`ehas diagnose CAMP --json --write-effect`), the written effect file compared as the diagnosis "
         "prints it, and the recalibrated baseline measured (`ehas compare CAMP --effects viscous_friction --fit "
         "--json`, its `recalibrated` side: no effect, beta and K fitted).  The final residual is the model the "
         "diagnosis' printed `next:` reproduces (`ehas compare` of the effect file it wrote, else its own final "
         "model); a proposed term's own all-data figure, when the written file is a kept hypothesis instead, is "
         "the column beside it.", "",
         f"Cases here: {len(have)} of {len(full)}"
         + (f"; not yet run: {', '.join(c['id'] for c in full if c['id'] not in have)}" if len(have) < len(full)
            else "") + ".  Figures are over the cases here only; " + acc.commits_of(recs), "",
         "## Summary against the issue's thresholds", "",
         f"* Right place and right kind named in physical words: {summ['right_place_kind']}/"
         f"{summ['campaigns'] - summ['errors']} ({_pct(summ['right_place_kind_share'])}; threshold >= 75 %); "
         f"the right kind among any named item, bare proposal constants included: {summ['right_kind_any_form']}.",
         f"* Residual closed (final <= 2x noise and >= 20 % below the baseline): {summ['closed']}/"
         f"{summ['campaigns'] - summ['errors']} ({_pct(summ['closed_share'])}; threshold >= 80 %)"
         + (f"; {summ['closed_unknown']} without a baseline figure" if summ["closed_unknown"] else "") + ".",
         f"* Recommended terms whose refit removes < 10 % of the excess over noise: {summ['weak_terms']} "
         f"(threshold 0).",
         f"* Kept hypotheses that make the all-data residual worse than the bare library model's: "
         f"{summ['worsening_hypotheses']} (threshold 0).",
         f"* Cases that failed to run: {summ['errors']}.", "",
         "How it is judged (`tests/independent_rig/judge.py`, `judge_place_kind`, `honesty`): every item the "
         "diagnosis names (kept library effects, hypotheses and states, the proposal's `named` forms, a disturbance the "
         "logged supply carries; bare proposal terms count as constants, not words) gets the kinds its law stands "
         "for (judged by the form and place, not by the package's own kind string) and the places where it acts; "
         "a hidden class is found when one worded item has an accepted kind at an accepted place "
         "(`effects.py`: `accept`, `places`, with the reason); nothing worded may be of a kind no hidden effect "
         "has.", "",
         "## Every campaign", "",
         "| case | rig | hidden | verdict | baseline x noise | final x noise | proposal, its own figure | closed | "
         "named (kinds @ places) | right place+kind | weak term | worsening hyp. | s |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        hidden = "; ".join(f"{n}: " + ", ".join(f"{k}={v:g} {_unit(n, k)}" for k, v in p.items())
                           for n, p in r["effects"].items())
        if "error" in r or "place_kind" not in r:
            L.append(f"| {r['id']} | {r['rig']} | {hidden} | error: {r.get('error', 'not judged')} "
                     "| | | | | | | | | |")
            continue
        h, j = r["honesty"], r["place_kind"]
        named = "; ".join(f"{it['label']} ({'/'.join(it['kinds'])} @ {'/'.join(it['places']) or '?'}"
                          f"{'' if it['words'] else ', constant'})" for it in j["items"]) or "-"
        own = acc._num((r.get("proposal") or {}).get("residual_after_diag"))
        L.append(f"| {r['id']} | {r['rig']} | {hidden} | {r.get('verdict')} | {_f(h['baseline'])} | {_f(h['final'])} "
                 f"| {_f(own)} | {_f(h['closed'])} | {named.replace('|', '/')} | {_f(j['right'])} | {_f(h['weak_term'])} "
                 f"| {_f(h['worsening_hypothesis'])} | {_f(r['steps'].get('total_s'), 4)} |")
    L += ["", "## The classes", "", "| class | kind | places | law | magnitudes | source |",
          "|---|---|---|---|---|---|"]
    for n, e in UNLISTED.items():
        p = e.params[0]
        L.append(f"| `{n}` | {e.kind} (accepted: {', '.join(e.accepted_kinds)}) | {', '.join(e.places)} | "
                 f"{e.doc} | {p.name} {p.magnitudes[0]:g}, {p.magnitudes[1]:g} {p.unit} | {e.source} |")
    return "\n".join(L) + "\n"


def _pct(x):
    return "-" if x is None else f"{100 * x:.0f} %"


def _unit(name: str, param: str) -> str:
    return next((p.unit for p in ALL[name].params if p.name == param), "")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="acceptance of ehas diagnose on classes of hidden physics no one listed")
    ap.add_argument("--out", default="results/diagnosis_unlisted")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "ehas_unlisted"),
                    help="campaigns and diagnosis files (large; not committed)")
    ap.add_argument("--only", default="", help="case ids, comma-separated")
    ap.add_argument("--limit", type=int, default=0, help="run at most this many new cases")
    ap.add_argument("--readme-only", action="store_true",
                    help="rewrite README.md and results.json from cases/ (each case judged again from diag/)")
    ap.add_argument("--redo", action="store_true", help="rerun cases already checkpointed")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once (each diagnosis uses about one core)")
    a = ap.parse_args(argv)
    out, work = Path(a.out), Path(a.work)
    (out / "cases").mkdir(parents=True, exist_ok=True)
    (out / "diag").mkdir(exist_ok=True)
    cases = unlisted_cases()
    if a.only:
        only = set(a.only.split(","))
        unknown = only - {c["id"] for c in cases}
        if unknown:
            raise SystemExit(f"--only: unknown case id(s) {', '.join(sorted(unknown))}; known: "
                             f"{', '.join(c['id'] for c in cases)}")
        cases = [c for c in cases if c["id"] in only]
    done = {p.stem for p in (out / "cases").glob("*.json")}
    todo = [] if a.readme_only else [c for c in cases if a.redo or c["id"] not in done]
    if a.limit:
        todo = todo[:a.limit]
    caps = acc.capabilities() if todo else {}
    print(f"[unlisted] {len(cases)} cases selected, {len(todo)} to run; about {len(todo) * GUESS_S / 60:.0f} min "
          f"(first guess {GUESS_S:.0f} s a case, until measured)", flush=True)
    times: list = []

    def one(c):
        rec = run(c, work, out, caps)
        rec["ehas_commit"] = acc._commit()
        tmp = out / "cases" / f".{c['id']}.json.tmp"
        tmp.write_text(json.dumps(rec, indent=1) + "\n")
        os.replace(tmp, out / "cases" / f"{c['id']}.json")
        return rec

    try:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max(1, a.jobs)) as pool:  # each case runs its commands as subprocesses
            for c in todo:
                print(f"[unlisted] queued {c['id']} (rig {c['rig']})", flush=True)
            for k, (c, rec) in enumerate(zip(todo, pool.map(one, todo)), 1):
                times.append(rec["steps"].get("total_s") or GUESS_S)
                h, j = rec.get("honesty") or {}, rec.get("place_kind") or {}
                print(f"[unlisted] {k}/{len(todo)} {c['id']}: {rec.get('verdict', rec.get('error'))}; baseline "
                      f"{_f(h.get('baseline'))} -> final {_f(h.get('final'))}; right place+kind {_f(j.get('right'))}; "
                      f"about {(len(todo) - k) * sum(times) / len(times) / max(1, a.jobs) / 60:.0f} min left",
                      flush=True)
    except KeyboardInterrupt:
        print("[unlisted] interrupted: finished cases are kept; rerun the same command to resume", flush=True)
    order = {c["id"]: i for i, c in enumerate(unlisted_cases())}
    recs = sorted((rejudge(json.loads(p.read_text()), out) for p in (out / "cases").glob("*.json")),
                  key=lambda r: order.get(r["id"], 1e9))
    summ = summarise(recs)
    command = COMMAND if str(a.out) == "results/diagnosis_unlisted" else f"python -m tests.independent_rig.unlisted " \
                                                                         f"--out {a.out}"
    _atomic(out / "results.json", json.dumps({"command": command, "thresholds": THRESHOLDS, "summary": summ,
                                               "cases": recs}, indent=1) + "\n")
    _atomic(out / "README.md", readme(recs, summ, command))
    print(f"[unlisted] wrote {out / 'README.md'} and results.json ({len(recs)} cases)", flush=True)
    return 0


def _atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


if __name__ == "__main__":
    raise SystemExit(main())
