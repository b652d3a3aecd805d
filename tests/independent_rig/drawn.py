"""Acceptance of ``ehas diagnose`` on the drawn set: hidden physics drawn from a grammar (issue 43, point 5).

For each case of :func:`.grammar.drawn_cases` (blocks of hidden physics drawn as (place, kind, magnitude) with the
fixed :data:`.grammar.SEED`): generate the campaign, diagnose it and compare the written effect file as
:func:`.acceptance.run_case` does, measure the recalibrated baseline as :mod:`.unlisted` does, and judge
(:func:`.judge.judge_blocks`): the right place and the right block kind named in physical words, the residual
closed, a recommended term too weak to be written, a kept hypothesis that worsens the all-data residual
(:func:`.judge.honesty`).  Writes ``OUT/results.json`` and ``OUT/README.md`` with the summary against issue 43's
thresholds.

Checkpoints: each finished case is ``OUT/cases/ID.json``; a rerun skips those (Ctrl-C and rerun resumes).

    python -m tests.independent_rig.drawn --out results/diagnosis_drawn [--only ID[,ID]] [--limit N]
        [--work DIR] [--list] [--readme-only] [--redo] [--seed N --singles N --pairs N]

``--seed`` draws another set (held out: drawn after everything the published set tuned, judged the same way); its
cases are drawn with ``--singles`` and ``--pairs`` (default the published set's counts) and go to their own
``--out``.
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from . import acceptance as acc
from . import unlisted
from .grammar import (DB_HIGH, DB_LOW, KINDS, N_PAIRS, N_SINGLES, PLACES, SEED, Screen, counts, describe,
                      drawn_cases)
from .judge import alternatives_hold, block_items, honesty, judge_blocks
from .unlisted import _atomic, _f, _pct, baseline_residual

#: issue 43's thresholds (point 5): right place and kind, closed, weak terms, models worse than the book's
THRESHOLDS = {"right_place_kind_share": 0.70, "closed_share": 0.80, "weak_terms": 0, "worsening_hypotheses": 0,
              "closed_x_noise": 2.0, "closed_below_baseline": 0.20, "weak_term_share": 0.10}
#: a case's first guess of time, s (generation, diagnosis, compare of the effect file, baseline compare)
GUESS_S = 300.0
DEFAULT_OUT = "results/diagnosis_drawn"
COMMAND = f"python -m tests.independent_rig.drawn --out {DEFAULT_OUT}"


def run(case: dict, work: Path, out: Path, caps: dict, cold_cache: bool = False) -> dict:
    """One case: :func:`.acceptance.run_case` (which generates the case's blocks), the baseline, the judgement
    (``cold_cache``: the diagnosis on an empty model cache of its own, compiles included, as issue 44 times it)."""
    t0 = time.time()
    rec = acc.run_case(case, work, out, caps, cold_cache=cold_cache, resolution=False, warm_again=False)
    if "error" in rec:
        return rec
    wdir = work / case["id"]
    model = acc.rig_model(case["rig"])
    diag = json.loads((out / "diag" / f"{case['id']}.json").read_text())
    base = acc._num((diag.get("validation") or {}).get("residual_x_noise_recalibrated_baseline"))
    if base is None:
        base = baseline_residual(wdir / "campaign", ["--model", str(model)] if model else [], wdir)
    final = acc._num(rec.get("residual_after"))
    if final is None:
        final = acc._num(diag.get("residual_x_noise"))
    rec["place_kind"] = _judged(case["blocks"], diag)
    rec["honesty"] = honesty(diag, base, final)
    rec["unexplained_text"] = ((diag.get("unexplained") or {}).get("no_term")
                               or (diag.get("unexplained") or {}).get("text"))
    rec["steps"]["total_s"] = round(time.time() - t0, 1)
    return rec


def _judged(blocks: list[dict], diag: dict) -> dict:
    """:func:`.judge.judge_blocks` of the diagnosis, with ``alternatives``: whether each block missed is among what
    the logs cannot part from what was named (:func:`.judge.alternatives_hold`)."""
    j = judge_blocks(blocks, block_items(diag))
    return {**j, "alternatives": alternatives_hold(blocks, diag, j["per_block"])}


def rejudge(rec: dict, out: Path) -> dict:
    """The record judged again from its stored diagnosis by the judge as it is now (:func:`.unlisted.rejudge`)."""
    return unlisted.rejudge(rec, out, lambda r, diag: _judged(r["blocks"], diag))


def summarise(recs: list[dict]) -> dict:
    """Figures against :data:`THRESHOLDS` over the cases that ran (:func:`.unlisted.summarise`), and the right
    share per kind and per place."""
    s = unlisted.summarise(recs, THRESHOLDS, per="per_block")
    ok = [r for r in recs if "error" not in r and "place_kind" in r]
    s["by_kind"], s["by_place"] = _by(ok, "kind"), _by(ok, "place")
    # the explained cases that named a stand-in: is each block missed among the alternatives the logs cannot part?
    stand = [r for r in ok if r.get("verdict") == "explained" and r["place_kind"].get("alternatives")]
    s["explained_by_stand_in"] = len(stand)
    s["stand_in_lists_truth"] = sum(1 for r in stand
                                    if all(v["listed"] for v in r["place_kind"]["alternatives"].values()))
    return s


def _by(recs: list[dict], key: str) -> dict:
    """{kind or place: [blocks named right (place and kind), blocks]} over the blocks of ``recs``."""
    out = {}
    for r in recs:
        for b in r["blocks"]:
            v = r["place_kind"]["per_block"][f"{b['kind']}@{b['place']}"]
            n = out.setdefault(b[key], [0, 0])
            n[0] += bool(v["right_kind"] and v["right_place"])
            n[1] += 1
    return out


#: what changed after the held-out draw (seed 20261129) was looked at, case by case: each a case it is no longer
#: blind for, and the figure under the rule or code before, so its README never shows a tuned figure as a blind one
HELD_OUT_SEEN = (
    ("d06", "a hose's line pressure starts at its chamber's pressure on any rig (bbefaf2), found on d06: the campaign "
            "3.32x -> 2.14x what does not repeat at the truth's hose"),
    ("d13", "a pure delay at the flow meter's reading (87af049), built after d13 (a delay there) was named a lag"),
    ("d15", "the judge counts valve_dynamics as a gain as well as a lag (its flow gain K multiplies the coil current: "
            "the logs cannot tell a gain there from one at the coil), changed after d15 (a gain at the coil current, "
            "named valve_dynamics) was judged wrong: under the rule before, right place and kind 15/18"),
)


def readme(recs: list[dict], summ: dict, command: str, seed: int = SEED, full: list | None = None) -> str:
    """The README of ``OUT``: what was run, the summary against the thresholds, every case, the draw."""
    full = drawn_cases() if full is None else full  # the whole draw (a held-out one: its own cases)
    have = {r["id"] for r in recs}
    n_ok = summ["campaigns"] - summ["errors"]
    L = ["# Diagnosis of hidden physics drawn from a grammar (issue 43, point 5)", "",
         f"Regenerate (resumable; finished cases in `cases/` are kept): `{command}`", "",
         "Campaigns of the independent generator (`tests/independent_rig/`, plain NumPy/SciPy sharing no code with "
         "the package; `docs/independent-generator.md`, \"The drawn set\") whose hidden physics is drawn from a "
         "grammar (`tests/independent_rig/grammar.py`): a place of the generator's model (a signal or a balance), a "
         "kind that fits it (static: offset, gain, dead zone, saturation, piecewise-linear, cubic; dynamic: lag, "
         "rate limit, delay, play, a compliance with a mass, a line volume behind a resistance) and a magnitude "
         f"(log-uniform in the kind's range, scaled by the place's size on the rig), "
         + (f"with the seed {SEED} published before anything was tuned" if seed == SEED else
            f"with the seed {seed}: a held-out draw, made after what the published set (seed {SEED}) tuned")
         + f"; a block whose own effect is below {DB_LOW:g} dB or above {DB_HIGH:g} dB over "
         "the sensor noise on its best key signal was redrawn at another magnitude.  Each campaign is diagnosed "
         "(`ehas diagnose CAMP --json --write-effect`), the written effect file compared as the diagnosis prints "
         "it, and the recalibrated baseline measured (the model with no effect, beta and K fitted).", "",
         f"Cases here: {len(have)} of {len(full)}"
         + (f"; not yet run: {', '.join(c['id'] for c in full if c['id'] not in have)}" if len(have) < len(full)
            else "") + ".  Figures are over the cases here only; " + acc.commits_of(recs), "",
         *((["Not blind on every case: changed after this draw was looked at (`drawn.HELD_OUT_SEEN`):", ""]
            + [f"* {cid}: {what}." for cid, what in HELD_OUT_SEEN] + [""]) if seed != SEED else []),
         "## Summary against issue 43's thresholds", "",
         f"* Right place and right kind named in physical words: {summ['right_place_kind']}/{n_ok} "
         f"({_pct(summ['right_place_kind_share'])}; threshold >= 70 %); the right kind among any named item, bare "
         f"proposal constants included: {summ['right_kind_any_form']}.",
         f"* Residual closed (final <= 2x noise and >= 20 % below the recalibrated baseline): {summ['closed']}/{n_ok} "
         f"({_pct(summ['closed_share'])}; threshold >= 80 %)"
         + (f"; {summ['closed_unknown']} without a baseline figure" if summ["closed_unknown"] else "") + ".",
         f"* Recommended terms whose refit removes < 10 % of the excess over noise: {summ['weak_terms']} "
         "(threshold 0).",
         f"* Recommended models worse than the book model (a kept hypothesis that leaves the all-data residual above "
         f"the bare library model's): {summ['worsening_hypotheses']} (threshold 0).",
         f"* Explained with a block missed (a stand-in named): {summ['explained_by_stand_in']}; the missed blocks' "
         f"kind at their place among the alternatives the logs cannot part from what was named (issue 42): "
         f"{summ['stand_in_lists_truth']}/{summ['explained_by_stand_in']} (`judge.alternatives_hold`).",
         f"* Cases that failed to run: {summ['errors']}.", "",
         "How it is judged (`tests/independent_rig/judge.py`, `judge_blocks`, `honesty`): every item the diagnosis "
         "names in words (kept library effects, hypotheses and states, the proposal's `named` forms; bare proposal "
         "terms count as constants) gets the block kinds its law stands for (`LIBRARY_BLOCK`, `NAMED_FORM_BLOCK`, "
         "else its words) and the grammar's places it names (its diagnosis place, narrowed by side words; the "
         "readings, which the diagnosis has no place for, by words); a block is found when one worded item has an "
         "accepted kind at its place; nothing worded may be of a kind no block has.", "",
         "| kind | right / blocks |  | place | right / blocks |", "|---|---|---|---|---|"]
    kinds, places = list(summ["by_kind"].items()), list(summ["by_place"].items())
    for i in range(max(len(kinds), len(places))):
        k = f"{kinds[i][0]} | {kinds[i][1][0]}/{kinds[i][1][1]}" if i < len(kinds) else " | "
        p = f"{places[i][0]} | {places[i][1][0]}/{places[i][1][1]}" if i < len(places) else " | "
        L.append(f"| {k} | | {p} |")
    L += ["", "## Every campaign", "",
          "| case | rig | hidden (words; its own effect) | verdict | baseline x noise | final x noise | closed | "
          "named (block kinds @ places) | right place+kind | weak term | worsening hyp. | s |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        hidden = "; ".join(f"{b['words']} ({s['best_db']:.0f} dB)" for b, s in zip(r["blocks"], r["screen"]))
        if "error" in r or "place_kind" not in r:
            L.append(f"| {r['id']} | {r['rig']} | {hidden} | error: {r.get('error', 'not judged')} | | | | | | | | |")
            continue
        h, j = r["honesty"], r["place_kind"]
        named = "; ".join(f"{it['label']} ({'/'.join(it['block_kinds']) or '?'} @ "
                          f"{'/'.join(it['grammar_places']) or '?'}{'' if it['words'] else ', constant'})"
                          for it in j["items"]) or "-"
        L.append(f"| {r['id']} | {r['rig']} | {hidden} | {r.get('verdict')} | {_f(h['baseline'])} | {_f(h['final'])} "
                 f"| {_f(h['closed'])} | {named.replace('|', '/')} | {_f(j['right'])} | {_f(h['weak_term'])} "
                 f"| {_f(h['worsening_hypothesis'])} | {_f(r['steps'].get('total_s'), 4)} |")
    c = counts(full)
    L += ["", "## The draw", "", f"{len(full)} cases ({sum(len(x['blocks']) == 1 for x in full)} single, "
          f"{sum(len(x['blocks']) == 2 for x in full)} pairs); blocks per kind: "
          + ", ".join(f"{k} {n}" for k, n in c["kinds"].items()) + "; per place: "
          + ", ".join(f"{p} {n}" for p, n in c["places"].items()) + ".", "",
          "| kind | fits | source |", "|---|---|---|"]
    for k in KINDS.values():
        L.append(f"| `{k.name}` | {', '.join(p.name for p in PLACES.values() if k.fits(p))} | {k.source} |")
    return "\n".join(L) + "\n"


def list_cases(cases: list[dict], seed: int = SEED) -> str:
    """The drawn list as ``--list`` prints it: one line per case, then the counts per kind and per place."""
    c = counts(cases)
    return "\n".join([f"# drawn set: seed {seed}, {len(cases)} cases "
                      f"({sum(len(x['blocks']) == 1 for x in cases)} single, "
                      f"{sum(len(x['blocks']) == 2 for x in cases)} pairs)"]
                     + [describe(x) for x in cases]
                     + ["# blocks per kind: " + ", ".join(f"{k} {n}" for k, n in c["kinds"].items()),
                        "# blocks per place: " + ", ".join(f"{p} {n}" for p, n in c["places"].items())]) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="acceptance of ehas diagnose on hidden physics drawn from a grammar")
    ap.add_argument("--out", default=DEFAULT_OUT)
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "ehas_drawn"),
                    help="campaigns and diagnosis files (large; not committed)")
    ap.add_argument("--only", default="", help="case ids, comma-separated")
    ap.add_argument("--limit", type=int, default=0, help="run at most this many new cases")
    ap.add_argument("--list", action="store_true", help="print the drawn cases and exit (runs nothing)")
    ap.add_argument("--readme-only", action="store_true",
                    help="rewrite README.md and results.json from cases/ (each case judged again from diag/)")
    ap.add_argument("--redo", action="store_true", help="rerun cases already checkpointed")
    ap.add_argument("--cold-cache", action="store_true",
                    help="diagnose each case on an empty model cache of its own (its time includes every compile)")
    ap.add_argument("--seed", type=int, default=SEED,
                    help=f"the draw's seed (default {SEED}, the published set; another seed draws a held-out set)")
    ap.add_argument("--singles", type=int, default=N_SINGLES, help="single campaigns drawn")
    ap.add_argument("--pairs", type=int, default=N_PAIRS, help="campaigns of two blocks drawn")
    a = ap.parse_args(argv)
    if a.seed < 0:
        raise SystemExit(f"--seed: a whole number >= 0, got {a.seed}")
    if a.singles < 0 or a.pairs < 0 or a.singles + a.pairs == 0:
        raise SystemExit("--singles, --pairs: counts >= 0, at least one case in all")
    held_out = (a.seed, a.singles, a.pairs) != (SEED, N_SINGLES, N_PAIRS)
    if held_out and str(a.out) == DEFAULT_OUT:
        raise SystemExit(f"--out: a draw other than the published one (seed {SEED}, {N_SINGLES} singles, {N_PAIRS} "
                         f"pairs) goes to a folder of its own, not {DEFAULT_OUT}")
    # a held-out draw measures its blocks in memory: the published set's cache file stays as it is
    cases = drawn_cases(a.seed, Screen(None) if held_out else None, a.singles, a.pairs)
    drawn = list(cases)
    if a.list:
        print(list_cases(cases, a.seed), end="")
        return 0
    out, work = Path(a.out), Path(a.work)
    (out / "cases").mkdir(parents=True, exist_ok=True)
    (out / "diag").mkdir(exist_ok=True)
    order = {c["id"]: i for i, c in enumerate(cases)}
    if a.only:
        only = set(a.only.split(","))
        unknown = only - set(order)
        if unknown:
            raise SystemExit(f"--only: unknown case id(s) {', '.join(sorted(unknown))}; known: {', '.join(order)}")
        cases = [c for c in cases if c["id"] in only]
    done = {p.stem for p in (out / "cases").glob("*.json")}
    todo = [] if a.readme_only else [c for c in cases if a.redo or c["id"] not in done]
    if a.limit:
        todo = todo[:a.limit]
    caps = acc.capabilities() if todo else {}
    print(f"[drawn] {len(cases)} cases selected, {len(todo)} to run; about {len(todo) * GUESS_S / 60:.0f} min "
          f"(first guess {GUESS_S:.0f} s a case, until measured)", flush=True)
    times: list = []
    try:
        for k, c in enumerate(todo, 1):
            print(f"[drawn] {k}/{len(todo)} {c['id']} (rig {c['rig']}): {'; '.join(b['words'] for b in c['blocks'])}",
                  flush=True)
            rec = run(c, work, out, caps, cold_cache=a.cold_cache)
            rec["ehas_commit"] = acc._commit()
            _atomic(out / "cases" / f"{c['id']}.json", json.dumps(rec, indent=1) + "\n")
            times.append(rec["steps"].get("total_s") or GUESS_S)
            h, j = rec.get("honesty") or {}, rec.get("place_kind") or {}
            print(f"[drawn]   {rec.get('verdict', rec.get('error'))}; baseline {_f(h.get('baseline'))} -> final "
                  f"{_f(h.get('final'))}; right place+kind {_f(j.get('right'))}; about "
                  f"{(len(todo) - k) * sum(times) / len(times) / 60:.0f} min left", flush=True)
    except KeyboardInterrupt:
        print("[drawn] interrupted: finished cases are kept; rerun the same command to resume", flush=True)
    recs = sorted((rejudge(json.loads(p.read_text()), out) for p in (out / "cases").glob("*.json")),
                  key=lambda r: order.get(r["id"], 1e9))
    summ = summarise(recs)
    command = COMMAND if str(a.out) == DEFAULT_OUT else f"python -m tests.independent_rig.drawn --out {a.out}"
    if held_out:
        command += f" --seed {a.seed} --singles {a.singles} --pairs {a.pairs}"
    _atomic(out / "results.json", json.dumps({"command": command, "seed": a.seed, "thresholds": THRESHOLDS,
                                              "summary": summ, "cases": recs}, indent=1) + "\n")
    _atomic(out / "README.md", readme(recs, summ, command, a.seed, drawn))
    print(f"[drawn] wrote {out / 'README.md'} and results.json ({len(recs)} cases)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
