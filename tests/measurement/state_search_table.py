"""The state stage on campaigns simulated with each generic augmentation, and on a clean one; the compile cost of
the augmentations.  Writes ``results/state_search/README.md``.

Each campaign is the package's synthetic 5-run campaign (``ehas_env.measurement.synthetic``: the same model, so
this is a consistency table, not an independent one) with one augmentation hidden; the final model the stage
starts from is the baseline's best (``fit_null``); the stage tries every augmentation
(``ehas_env.physics.augment.augmentations``).  The compile cost is the CPU time to compile and run the quick build
with the structural hypotheses (what the diagnosis' replays run) in an empty model cache, with and without the
augmentations registered, each in a fresh process.

Run from the repository's root::

    python -m tests.measurement.state_search_table [--skip-compile]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "results" / "state_search" / "README.md"
COMMAND = "python -m tests.measurement.state_search_table"
CASES = [
    ("aug_lag_coil", {"T": 6.0}, 3304),
    ("aug_lag_position_sensor", {"T": 8.0}, 3301),
    ("aug_link_rod_crank", {"k_link": 3.0e6, "m_link": 20.0}, 3302),
    ("aug_link_mount", {"k_link": 5.0e6, "m_link": 30.0}, 3305),
    ("aug_hose_a", {"V_line": 200.0, "R_line": 2.0}, 3306),
    ("aug_hose_b", {"V_line": 300.0, "R_line": 1.0}, 3307),
    (None, None, 3303),
]


def compile_cpu(with_augmentations: bool) -> dict:
    """CPU and wall seconds of a first Plant(hypotheses=True) closed- and open-loop run in an empty model cache,
    in this process (call it in a fresh one)."""
    t0, c0 = time.monotonic(), time.process_time()
    from ehas_env.physics import augment
    from ehas_env.physics.effects import REGISTRY

    if not with_augmentations:
        for n in augment.augmentations():
            if n in REGISTRY and issubclass(REGISTRY[n], augment.Augmentation):
                del REGISTRY[n]
    import numpy as np

    from ehas_env.simulation.plant import Plant

    p = Plant(disc_sets=2, hypotheses=True)
    p.simulate_closed_loop(amplitude_deg=10, freq_hz=1, cycles=1)
    p.simulate(np.zeros(100))
    return {"effects": len(REGISTRY), "cpu_s": round(time.process_time() - c0, 1),
            "wall_s": round(time.monotonic() - t0, 1), "load": round(os.getloadavg()[0], 1)}


def _compile_in_fresh_process(with_augmentations: bool) -> dict:
    env = dict(os.environ, EHAS_CACHE_DIR=tempfile.mkdtemp(prefix="ehas-state-compile-"), EHAS_QUIET_COMPILE="1")
    env["NUMBA_CACHE_DIR"] = env["EHAS_CACHE_DIR"]
    code = (f"import json; from tests.measurement.state_search_table import compile_cpu; "
            f"print(json.dumps(compile_cpu({with_augmentations})))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_case(effect, params, seed) -> dict:
    from ehas_env.measurement.campaign import Campaign, validate_run
    from ehas_env.diagnosis.candidates import FIT_WINDOW_S, fit_null
    from ehas_env.diagnosis.search import data_stage
    from ehas_env.diagnosis.states import state_stage
    from ehas_env.measurement.synthetic import simulate_campaign

    runs, _ = simulate_campaign({effect: params} if effect else None, seed=seed, duration=3.5)
    camp = Campaign(None, [validate_run(n, c, m) for n, c, m in runs])
    s = data_stage(camp, window_s=FIT_WINDOW_S, hypotheses=True)
    null = fit_null(s.rep)
    t0 = time.monotonic()
    _, rec = state_stage(s.rep, s.full, null, s.parts, lambda m: print(m, file=sys.stderr, flush=True))
    return {"truth": effect, "params_true": params, "seed": seed, "stage_s": round(time.monotonic() - t0, 1), **rec}


def table(rows: list, comp: dict | None) -> str:
    lines = ["# The state stage (issue 33, item 2)", "",
             f"Regenerate: `{COMMAND}` (from the repository's root; about 10 min on 2 cores).", "",
             "Synthetic 5-run campaigns (the package's own model: a consistency table) with one generic "
             "augmentation hidden; the stage starts from the baseline's best fit and tries every augmentation "
             "(`ehas_env/diagnosis/states.py`, `state_stage`).", "",
             "| hidden | kept | fitted (95 %) | residual all data before -> after (x noise) | validation before -> "
             "after | stage s | in words |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        truth = "none" if r["truth"] is None else f"{r['truth']} {r['params_true']}"
        fitted = ("" if not r["params"] else
                  ", ".join(f"{k} = {v:g} [{r['ci95'][k][0]:g}, {r['ci95'][k][1]:g}]" for k, v in r["params"].items()))
        after = r["residual_x_noise_all_after"]
        vafter = r["residual_x_noise_validation_after"]
        lines.append(f"| {truth} | {r['kept'] or 'none'} | {fitted} | {r['residual_x_noise_all_before']} -> "
                     f"{'-' if after is None else after} | {r['residual_x_noise_validation_before']} -> "
                     f"{'-' if vafter is None else vafter} | {r['stage_s']} | {r['words'] or r['skipped']} |")
    if comp:
        w, wo = comp["with"], comp["without"]
        lines += ["", "## Compile cost", "",
                  "First closed- and open-loop run of `Plant(hypotheses=True)` (the quick build the diagnosis' "
                  "replays run) in an empty model cache, each in a fresh process:", "",
                  "| | effects | CPU s | wall s | load |", "|---|---|---|---|---|",
                  f"| without the augmentations | {wo['effects']} | {wo['cpu_s']} | {wo['wall_s']} | {wo['load']} |",
                  f"| with the augmentations | {w['effects']} | {w['cpu_s']} | {w['wall_s']} | {w['load']} |"]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-compile", action="store_true",
                    help="do not measure the compile cost again (the table keeps the figures measured before)")
    args = ap.parse_args(argv)
    from ehas_env.output.files import atomic_write_text

    rows = []
    for effect, params, seed in CASES:
        print(f"state_search_table: campaign with {effect or 'nothing'} hidden ...", file=sys.stderr, flush=True)
        rows.append(run_case(effect, params, seed))
    comp = None
    if args.skip_compile and OUT.with_name("rows.json").exists():  # the compile figures measured before, kept
        comp = json.loads(OUT.with_name("rows.json").read_text()).get("compile")
    if not args.skip_compile:
        print("state_search_table: compile cost, two fresh processes ...", file=sys.stderr, flush=True)
        comp = {"without": _compile_in_fresh_process(False), "with": _compile_in_fresh_process(True)}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(OUT, table(rows, comp))
    atomic_write_text(OUT.with_name("rows.json"), json.dumps({"rows": rows, "compile": comp}, indent=1) + "\n")
    print(f"state_search_table: wrote {OUT.relative_to(ROOT)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
