"""What a diagnosis replays the campaign for: its replays counted by what asked for them (issue 44, point 1).

Forward sensitivities (or an adjoint) replace the difference Jacobian's columns -- one replay per fitted number --
by one simulation that carries the derivatives.  How much of a diagnosis that could save is the share of its replays
that are such columns.  This benchmark counts them: every replay of one diagnosis, attributed to the part of the
search that asked for it (a number scanned over its grid, a scan's zoom, a least-squares step, a difference column
of a fit's Jacobian, a confidence interval's, the linearised screens, the start's estimate).  Counts, not times:
they do not depend on the machine's load.

    python -m tests.measurement.replay_origins --out results/replay_origins [--case current_slew --variant rest]

The campaigns are the independent generator's start-condition cases (``tests/independent_rig/start_conditions.py``),
written to ``--work`` (default: a folder under the system's temporary directory).
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: the parts of the search a replay is attributed to: the innermost of these function names on its call stack
ORIGINS = (
    ("confidence", "a confidence interval's difference Jacobian (fitting.confidence)"),
    ("jacobian", "a fit's difference Jacobian, one column per fitted number (fitting.Objective.jacobian)"),
    ("_zoomed", "a scan's zoom between its best point's neighbours (fitting._zoomed)"),
    ("_scanned", "a number scanned over its grid (fitting._scanned)"),
    ("least_squares", "a least-squares step (the trial point of scipy's least_squares)"),
    ("linear_share", "a balance block's linearised screen (states.linear_share)"),
    ("estimate", "the start's estimate of the time (diagnosis.estimate)"),
)


def origin(names: list[str]) -> str:
    """The origin of a replay whose call stack holds the function ``names`` (outermost first)."""
    for key, _ in ORIGINS:
        if key in names:
            return key
    return "other"


def count(campaign: Path, model: Path | None) -> dict:
    """Diagnose ``campaign`` in this process, counting every replay (one model of a ``simulate_many`` call) by
    :func:`origin`; returns {total, by_origin {origin: count}, verdict, residual_x_noise, elapsed_s}."""
    from ehas_env.cli.main import main
    from ehas_env.measurement import replay as R

    counts: collections.Counter = collections.Counter()
    whole = R.Replayer._simulate_whole

    def counted(self, models, runs):
        counts[origin([f.name for f in traceback.extract_stack()])] += len(models)
        return whole(self, models, runs)

    out = Path(tempfile.mkdtemp()) / "diag.json"
    R.Replayer._simulate_whole = counted
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            main(["diagnose", str(campaign), "--json", str(out), "--quiet"] + (["--model", str(model)] if model else []))
    finally:
        R.Replayer._simulate_whole = whole
    d = json.loads(out.read_text())
    return {"total": sum(counts.values()), "by_origin": dict(counts.most_common()), "verdict": d.get("verdict"),
            "residual_x_noise": d.get("residual_x_noise"), "elapsed_s": d.get("elapsed_s")}


def _commit() -> str:
    return subprocess.run(["git", "log", "-1", "--format=%h", "--", "ehas_env"], capture_output=True, text=True,
                          cwd=ROOT).stdout.strip()


def write(out: Path, rec: dict, command: str) -> None:
    """``results.json`` and ``README.md`` of ``rec`` in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(rec, indent=1) + "\n")
    words = dict(ORIGINS)
    total = rec["total"]
    rows = [f"| {words.get(k, 'anything else')} | {n} | {100.0 * n / total:.1f} % |"
            for k, n in sorted(rec["by_origin"].items(), key=lambda kv: -kv[1])]
    jac = sum(rec["by_origin"].get(k, 0) for k in ("jacobian", "confidence"))
    text = f"""# What a diagnosis replays the campaign for (issue 44, point 1)

Regenerate: `{command}` (package at commit {rec['commit']}; counts, not times: they do not depend on the load).

Campaign: the independent generator's start-condition case `{rec['case']}`, variant `{rec['variant']}` (5 runs of 3 s,
`tests/independent_rig/start_conditions.py`). Diagnosis: {rec['verdict']}, {rec['residual_x_noise']}x what does not
repeat, {total} replays.

| what asked for the replay | replays | share |
|---|---:|---:|
{chr(10).join(rows)}

Forward sensitivities (or an adjoint) would replace the difference Jacobians' columns: {jac} of {total} replays
({100.0 * jac / total:.0f} %). Even free, they would leave {100.0 * (total - jac) / total:.0f} % of the replays: the
scans of each candidate's main number and their zooms, and the least-squares steps, are where a diagnosis spends its
replays.
"""
    (out / "README.md").write_text(text)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/replay_origins")
    ap.add_argument("--work", default=str(Path(tempfile.gettempdir()) / "ehas_replay_origins"))
    ap.add_argument("--case", default="current_slew")
    ap.add_argument("--variant", default="rest")
    a = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from tests.independent_rig import acceptance as acc
    from tests.independent_rig import start_conditions as sc

    case = next((c for c in sc.cases() if c["id"] == a.case), None)
    if case is None:
        raise SystemExit(f"replay_origins: --case {a.case}: no such start-condition case")
    camp = Path(a.work) / a.case / a.variant
    print(f"[origins] writing {a.case} ({a.variant}) to {camp}", flush=True)
    sc._generate(case, a.variant, camp)
    print("[origins] diagnosing it, every replay counted (a few minutes on 2 cores)", flush=True)
    rec = {"case": a.case, "variant": a.variant, "commit": _commit(), **count(camp, acc.rig_model(case["rig"]))}
    command = (f"python -m tests.measurement.replay_origins --out {a.out}"
               + (f" --case {a.case} --variant {a.variant}" if (a.case, a.variant) != ("current_slew", "rest") else ""))
    write(Path(a.out), rec, command)
    print(f"[origins] {rec['total']} replays: " + ", ".join(f"{k} {v}" for k, v in rec["by_origin"].items()))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    raise SystemExit(main())
