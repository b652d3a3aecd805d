"""The scans a diagnosis makes, and what a coarse grid first would cut (issue 44, point 3: a cheap proxy first).

A screen scans its candidate's main number over a grid and fits it further only where the grid's best beats the
model it screens on (:func:`ehas_env.diagnosis.fitting.fit`); the coarse grid (:func:`~ehas_env.diagnosis.fitting.
coarse_scan`) is replayed first and a candidate whose best there stays above that model's cost by more than
``COARSE_SLACK`` is not scanned further.  This survey diagnoses campaigns of the independent generator's drawn set
in this process with the coarse cut off (every grid scanned whole, as before it), records every scan against a
model to beat (``fitting.SCAN_WATCHERS``: the grid's costs, the model's, where the fit ended), and judges rules of
the coarse grid on them: the replays of the scans each would save, and the candidates the whole grid sends on to a
fit that it would cut (``cut``; ``mattered``: of those, the ones whose fit ended 0.3 dB below the model, what a
candidate must remove to count).

    python -m tests.measurement.coarse_scan_survey --out results/coarse_scan [--cases d00_saturation@return,...]
    python -m tests.measurement.coarse_scan_survey --out results/coarse_scan --records FILE.jsonl[.gz] ...

Records are kept per campaign in ``--work`` (resumable); ``--records`` judges recorded scans only.
"""
from __future__ import annotations

import argparse
import gzip
import json
import math
import os
import tempfile
import time
from pathlib import Path

from ehas_env.diagnosis.fitting import MIN_SCORE as MIN_SCORE_DB  # what a candidate must remove to count, dB
from ehas_env.diagnosis.fitting import SKIP_MARGIN, asks_fine_grid, coarse_scan

COMMAND = "python -m tests.measurement.coarse_scan_survey --out results/coarse_scan"
#: the drawn campaigns surveyed by default (those the rule was set on, and the set's other singles are one option)
CASES = ("d01_volume@supply", "d05_rate_limit@load_reading", "d06_compliance@crank_torque",
         "d09_dead_zone@crank_torque", "d10_delay@pressure_reading_b", "d11_piecewise_linear@piston_force",
         "d13_lag@coil_current", "d14_compliance@piston_force", "d17_offset@return",
         "d19_saturation@flow_reading", "d23_volume@chamber_b", "d25_lag@pressure_reading_b",
         "d27_play@pressure_reading_b", "p0_compliance@piston_force+dead_zone@chamber_a",
         "p2_offset@land_a+delay@position_reading", "p6_lag@land_b+offset@chamber_b",
         "p7_rate_limit@coil_current+smooth@pressure_reading_a")
#: what the committed records are
RECORDS_NOTE = ("The records in `results/coarse_scan/scans_bad8e6b.jsonl.gz` are the scans of the drawn runner's "
                "diagnoses (`python -m tests.independent_rig.drawn --only ID`, the CLI's `ehas diagnose`) at commit "
                "bad8e6b, before the coarse grid, taken by a logger in `fitting.fit` that recorded what "
                "`fitting.SCAN_WATCHERS` now gets; each campaign's later checks (`compare --fit`) are among them. "
                "Without `--records` the survey diagnoses the campaigns again in this process.")
#: the rules judged: (points over the grid, spread over each sign's values apart, slack)
RULES = tuple((k, signed, slack) for k in (3, 4) for signed in (False, True) for slack in (0.03, 0.1, 0.2, 0.3))


def coarse_indices(rec: dict, k: int, signed: bool) -> list[int]:
    """The indices into ``rec``'s values of a coarse grid of ``k`` points (each sign's apart when ``signed``) and
    the values the data point at: the package's rule (:func:`ehas_env.diagnosis.fitting.coarse_scan`) with its
    variants."""
    return coarse_scan(rec["values"], rec["grid"], rec["extra"], points=k, each_sign=signed)


def judge(recs: list[dict], k: int, signed: bool, slack: float) -> dict:
    """One rule on the recorded scans: replays saved of all scanned, candidates cut that the whole grid sent on,
    those among them that mattered (listed)."""
    saved = total = cut = 0
    mattered = []
    for r in recs:
        if asks_fine_grid(r["effect"]):  # asks for its finer grid (backlash): scanned whole
            total += len(r["costs"])
            continue
        c, null = r["costs"], r["null"]
        idx = coarse_indices(r, k, signed)
        total += len(c)
        if min(c[j] for j in idx) >= null * (1.0 - SKIP_MARGIN) * (1.0 + slack):
            saved += len(c) - len(idx)
            if min(c) < null * (1.0 - SKIP_MARGIN):
                cut += 1
                if r["final"] < null * 10.0 ** (-MIN_SCORE_DB / 10.0):
                    mattered.append({"effect": r["effect"], "grid_best": round(min(c) / null, 4),
                                     "final": round(r["final"] / null, 4)})
    return {"points": k, "each_sign": signed, "slack": slack, "replays_saved": saved, "replays_scanned": total,
            "share_saved": round(saved / total, 3) if total else None, "cut": cut, "mattered": mattered}


def margins(recs: list[dict], k: int = 3, signed: bool = True, n: int = 8) -> list[dict]:
    """The scans the whole grid sent on whose coarse best came closest above the model (the rule's margin)."""
    rows = []
    for r in recs:
        c, null = r["costs"], r["null"]
        if asks_fine_grid(r["effect"]) or min(c) >= null * (1.0 - SKIP_MARGIN):
            continue
        coarse = min(c[j] for j in coarse_indices(r, k, signed)) / null
        rows.append({"effect": r["effect"], "coarse_best": round(coarse, 4), "grid_best": round(min(c) / null, 4),
                     "final": round(r["final"] / null, 4)})
    return sorted(rows, key=lambda x: -x["coarse_best"])[:n]


def survey(cid: str, work: Path) -> Path:
    """Diagnose drawn case ``cid`` in this process, every grid scanned whole; its scans' records to a file."""
    from tests.independent_rig import acceptance as acc
    from tests.independent_rig import grammar

    from ehas_env.diagnosis import fitting
    from ehas_env.diagnosis.pipeline import diagnose_open
    from ehas_env.measurement.campaign import read_campaign

    case = {c["id"]: c for c in grammar.drawn_cases()}[cid]
    camp = work / cid / "campaign"
    acc.generate_campaign(case, camp)
    path = work / cid / "scans.jsonl"
    part = path.with_suffix(".part")
    out = part.open("w")
    slack, fitting.COARSE_SLACK = fitting.COARSE_SLACK, math.inf
    fitting.SCAN_WATCHERS.append(lambda rec: out.write(json.dumps({"case": cid, **rec}) + "\n"))
    try:
        model = acc.rig_model(case["rig"])
        diagnose_open(read_campaign(camp), model=str(model) if model else None,
                      log=lambda msg: print(f"[scans]   {msg}", flush=True))
    finally:
        fitting.SCAN_WATCHERS.clear()
        fitting.COARSE_SLACK = slack
        out.close()
    os.replace(part, path)  # a campaign's records whole or not at all
    return path


#: the fields a scan's record must hold to be judged
RECORD_FIELDS = ("effect", "values", "grid", "extra", "costs", "null", "final")


def read_records(paths) -> list[dict]:
    """The scans' records of the ``.jsonl`` (or ``.jsonl.gz``) files ``paths``, those with a model to beat.

    Raises
    ------
    ValueError
        A file that cannot be read, a line that is no JSON object with :data:`RECORD_FIELDS` (one line, naming
        the file and line).
    """
    recs = []
    for p in paths:
        opener = gzip.open if str(p).endswith(".gz") else open
        try:
            with opener(p, "rt") as f:
                for n, line in enumerate(f, 1):
                    if not line.strip():
                        continue
                    try:
                        rec = json.loads(line)
                    except ValueError as exc:
                        raise ValueError(f"--records: {p}, line {n}: not JSON ({exc})") from None
                    if not isinstance(rec, dict) or any(k not in rec for k in RECORD_FIELDS):
                        raise ValueError(f"--records: {p}, line {n}: a scan's record needs the fields "
                                         f"{', '.join(RECORD_FIELDS)}")
                    if not isinstance(rec["costs"], list) or not isinstance(rec["values"], list) or \
                            len(rec["costs"]) != len(rec["values"]) or not rec["costs"]:
                        raise ValueError(f"--records: {p}, line {n}: 'costs' and 'values' must be lists of one "
                                         "length, not empty")
                    recs.append(rec)
        except (OSError, EOFError) as exc:
            raise ValueError(f"--records: {p}: cannot be read ({exc.strerror or exc})") from None
    return [r for r in recs if r.get("null") is not None]


def readme(res: dict, command: str) -> str:
    L = ["# A screen's scan, a coarse grid first (issue 44, point 3)", "",
         f"Regenerate: `{command}`", "",
         f"Scans recorded: {res['scans']} against a model to beat, on {len(res['cases'])} campaigns of the drawn set; "
         f"{res['went_on']} of them the whole grid sent on to a fit ({res['mattered']} whose fit ended 0.3 dB or more "
         "below the model). Replays: those of the scans (a screen's fit after its scan is the same either way).", "",
         "| points | each sign apart | slack | scans' replays saved | cut that the grid sent on | of them mattered |",
         "|---:|---|---:|---:|---:|---|"]
    for j in res["rules"]:
        L.append(f"| {j['points']} | {'yes' if j['each_sign'] else 'no'} | {j['slack']:g} | "
                 f"{j['replays_saved']} of {j['replays_scanned']} ({100 * j['share_saved']:.0f} %) | {j['cut']} | "
                 + (f"{len(j['mattered'])}: " + ", ".join(f"{m['effect']} (grid {m['grid_best']}, fit {m['final']})"
                                                          for m in j["mattered"][:3])
                    + (", ..." if len(j["mattered"]) > 3 else "") if j["mattered"] else "none") + " |")
    L += ["", "The package's rule: 3 points, each sign apart, slack 0.2 (`ehas_env.diagnosis.fitting.COARSE_POINTS`, "
          "`COARSE_SLACK`). The candidates the grid sent on whose coarse best came closest above the model (costs "
          "over the model's):", "", "| effect | coarse best | grid best | fit |", "|---|---:|---:|---:|"]
    L += [f"| {m['effect']} | {m['coarse_best']} | {m['grid_best']} | {m['final']} |" for m in res["margins"]]
    L += ["", f"Campaigns: {', '.join(res['cases'])}."]
    if res.get("records"):
        L += ["", RECORDS_NOTE]
    return "\n".join(L)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="the scans of a diagnosis, and what a coarse grid first would cut")
    ap.add_argument("--out", required=True)
    ap.add_argument("--cases", default=",".join(CASES), help="drawn case ids, comma-separated")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "ehas_coarse_scan"),
                    help="campaigns and the scans' records (resumable)")
    ap.add_argument("--records", nargs="*", default=None, help="judge these recorded scans (.jsonl[.gz]) only")
    a = ap.parse_args(argv)
    out, work = Path(a.out), Path(a.work)
    if a.records is None:
        from tests.independent_rig import grammar

        known = {c["id"] for c in grammar.drawn_cases()}
        unknown = [c for c in a.cases.split(",") if c and c not in known]
        if unknown:
            raise SystemExit(f"--cases: unknown drawn case id(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    try:
        recs = read_records([Path(p) for p in a.records]) if a.records is not None else None
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    out.mkdir(parents=True, exist_ok=True)
    if a.records is not None:
        paths, command = [Path(p) for p in a.records], f"{COMMAND} --records {' '.join(a.records)}"
    else:
        paths = []
        ids = [c for c in a.cases.split(",") if c]
        for n, cid in enumerate(ids, 1):
            done = work / cid / "scans.jsonl"
            if not done.exists():
                print(f"[scans] {n}/{len(ids)} {cid}: generating and diagnosing, every grid whole "
                      "(1-10 min)", flush=True)
                t0 = time.time()
                survey(cid, work)
                print(f"[scans]   {time.time() - t0:.0f} s", flush=True)
            paths.append(done)
        command = COMMAND if a.cases == ",".join(CASES) else f"{COMMAND} --cases {a.cases}"
    if recs is None:
        recs = read_records(paths)
    res = {"records": [str(p) for p in paths] if a.records is not None else None, "scans": len(recs), "cases": sorted({r.get("case", "?") for r in recs}),
           "went_on": sum(1 for r in recs if min(r["costs"]) < r["null"] * (1.0 - SKIP_MARGIN)),
           "mattered": sum(1 for r in recs if r["final"] < r["null"] * 10.0 ** (-MIN_SCORE_DB / 10.0)),
           "rules": [judge(recs, *rule) for rule in RULES], "margins": margins(recs), "command": command}
    (out / "results.json").write_text(json.dumps(res, indent=1) + "\n")
    (out / "README.md").write_text(readme(res, command) + "\n")
    print(f"[scans] wrote {out / 'README.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
