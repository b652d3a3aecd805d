"""Closing the loop on the independent generator: diagnose, plan the runs that decide, log them, diagnose again.

For each case a campaign is simulated by the independent generator
(``tests/independent_rig``: it shares no code with ehas) with one hidden effect
whose signature another explanation shares in a standard campaign (one supply,
centred runs).  Then, with ehas's own commands as a user runs them:

1. ``ehas diagnose CAMP --json first.json``: is the truth among the explanations listed (the one reported, or
   an alternative the logs cannot tell from it)?
2. ``ehas plan-test first.json --out plan.json``: the runs that separate them;
3. the plan's runs are simulated by the generator with the truth and added to the campaign folder;
4. ``ehas diagnose CAMP --json second.json``: does it name the truth now?  And the separation each planned run
   realised (``per_run_db`` of the pair in the second diagnosis) against what the plan predicted.

Run from the repository's root::

    python -m tests.measurement.plan_loop [--work DIR] [--cases NAME,...]

Each case's result is kept in ``results/test_plans/cases/NAME.json`` as it
finishes (a rerun skips finished cases: ``--redo`` redoes them); the table is
``results/test_plans/README.md``.  Hours of CPU on two cores: the generator
integrates every run with an adaptive solver.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "results" / "test_plans"

#: name -> (place of the model, generator effect, its values, the ehas names that are the truth)
CASES = {
    "air": ("fluid", "entrained_air", {"eps": 10.0}, ("hyp_entrained_air",)),
    "mount": ("mechanics", "load_compliance", {"k": 25000.0}, ("hyp_load_compliance",)),
    "coulomb": ("mechanics (friction)", "coulomb_friction", {"Fc": 600.0}, ("coulomb_friction",)),
    "coil_lag": ("valve", "current_lag", {"T": 6.0}, ("hyp_coil_lag",)),
    "lvdt_zero": ("sensors", "lvdt_offset", {"x0": 1.0}, ("hyp_position_offset",)),
    "orifice_leak": ("leakage", "turbulent_leakage", {"q100": 1.2}, ("hyp_turbulent_leakage",)),
    "crank_zero": ("mechanics (kinematics)", "crank_offset", {"phi0": 10.0}, ("hyp_crank_offset",)),
    "laminar_leak": ("leakage", "internal_leakage", {"C_leak": 5e-12}, ("internal_leakage",)),
    "underlap": ("valve", "valve_underlap", {"u0": 0.7}, ("hyp_valve_underlap",)),
    "air_mild": ("fluid", "entrained_air", {"eps": 3.0}, ("hyp_entrained_air",)),
    "mount_stiff": ("mechanics", "load_compliance", {"k": 80000.0}, ("hyp_load_compliance",)),
    "coil_lag_short": ("valve (command path)", "current_lag", {"T": 2.0}, ("hyp_coil_lag",)),
    # smaller magnitudes of the same places: where a standard campaign still sees the effect but not which
    "coulomb_small": ("mechanics (friction)", "coulomb_friction", {"Fc": 250.0}, ("coulomb_friction",)),
    "crank_zero_small": ("mechanics (kinematics)", "crank_offset", {"phi0": 4.0}, ("hyp_crank_offset",)),
    "lvdt_zero_mid": ("sensors", "lvdt_offset", {"x0": 0.6}, ("hyp_position_offset",)),
    "air_mid": ("fluid", "entrained_air", {"eps": 6.0}, ("hyp_entrained_air",)),
    "laminar_leak_small": ("leakage", "internal_leakage", {"C_leak": 2e-12}, ("internal_leakage",)),
    "orifice_leak_small": ("leakage", "turbulent_leakage", {"q100": 0.4}, ("hyp_turbulent_leakage",)),
    "underlap_small": ("valve", "valve_underlap", {"u0": 0.3}, ("hyp_valve_underlap",)),
    "coulomb_rig_b": ("mechanics (friction)", "coulomb_friction", {"Fc": 600.0}, ("coulomb_friction",)),
    # the compliant mount of issue 34's example, stiffer: where the standard campaign may no longer tell it from oil
    "mount_150": ("mechanics (mount)", "load_compliance", {"k": 150000.0}, ("hyp_load_compliance",)),
    "mount_250": ("mechanics (mount)", "load_compliance", {"k": 250000.0}, ("hyp_load_compliance",)),
    # a lag of the position sensor (an augmentation, ehas_env/physics/augment.py, declared mistaken for a transport
    # delay); the standard campaign's valve chirp shows the command path, the loop's own logs alone do not
    "lvdt_lag": ("sensors (dynamics)", "lvdt_lag", {"T": 2.0}, ("aug_lag_position_sensor",)),
    "lvdt_lag_loop_only": ("sensors (dynamics)", "lvdt_lag", {"T": 2.0}, ("aug_lag_position_sensor",)),
    # a load's weight vs a spring on the crank; a drag growing with the square of the speed vs a viscous one
    "unbalance": ("mechanics (load)", "crank_unbalance", {"G": 25.0}, ("hyp_crank_unbalance",)),
    "disc_drag": ("mechanics (load drag)", "disc_drag", {"c": 1.0}, ("hyp_quadratic_drag",)),
    "unbalance_small": ("mechanics (load)", "crank_unbalance", {"G": 12.0}, ("hyp_crank_unbalance",)),
    "lvdt_lag_mild": ("sensors (dynamics)", "lvdt_lag", {"T": 0.5}, ("aug_lag_position_sensor",)),
    "disc_drag_small": ("mechanics (load drag)", "disc_drag", {"c": 0.15}, ("hyp_quadratic_drag",)),
    "orifice_leak_tiny": ("leakage", "turbulent_leakage", {"q100": 0.2}, ("hyp_turbulent_leakage",)),
    "lugre": ("mechanics (friction dynamics)", "lugre_friction", {"Fc": 150.0}, ("hyp_lugre_friction",)),
    "disc_drag_tiny": ("mechanics (load drag)", "disc_drag", {"c": 0.06}, ("hyp_quadratic_drag",)),
    "disc_drag_faint": ("mechanics (load drag)", "disc_drag", {"c": 0.04}, ("hyp_quadratic_drag",)),
    "mount_100": ("mechanics (mount)", "load_compliance", {"k": 100000.0}, ("hyp_load_compliance",)),
    "lvdt_lag_faint": ("sensors (dynamics)", "lvdt_lag", {"T": 0.25}, ("aug_lag_position_sensor",)),
    "underlap_loop_only": ("valve", "valve_underlap", {"u0": 0.3}, ("hyp_valve_underlap",)),
    "coil_lag_faint": ("valve (command path)", "current_lag", {"T": 1.0}, ("hyp_coil_lag",)),
    "air_8": ("fluid", "entrained_air", {"eps": 8.0}, ("hyp_entrained_air",)),
}
#: cases on another rig than the book's (tests/independent_rig/rigs/NAME.json): diagnosed and planned with --model
RIGS = {"coulomb_rig_b": "rig_b"}
#: cases whose campaign is not the standard one (options of tests.independent_rig.campaign.simulate), and in words
CAMPAIGNS = {name: ({"valve": False}, "the closed-loop runs only, no valve bench run")
             for name in ("lvdt_lag_loop_only", "underlap_loop_only")}


def _listed(doc: dict) -> list[str]:
    """The explanations a diagnosis lists: the reported model's effects and the alternatives within."""
    return list(doc["reported_model"]["effects"]) + [a["name"] for a in doc.get("alternatives", [])]


def _ehas(argv: list[str]) -> int:
    from ehas_env.cli.main import main

    return main(argv)


def add_plan_runs(camp: Path, plan: dict, effects: dict, seed: int) -> list[str]:
    """Simulate the plan's runs with the generator and the truth, and write them into the campaign folder."""
    from tests.independent_rig.campaign import COLUMNS, _fmt, rig_named
    from tests.independent_rig.effects import to_si
    from tests.independent_rig.sensors import Chain
    from tests.independent_rig.simulate import DT, chirp, closed_loop, valve_bench

    truth = json.loads((camp / "truth.json").read_text())
    base, _ = rig_named(truth.get("rig", "book"))
    rig = base.with_(beta=truth["beta_Pa"], K=truth["K_lpm_per_mA"] * 1e-3 / 60.0)
    chain = Chain()
    rng = np.random.default_rng(seed + 1000)
    eff = to_si(effects)
    names = []
    for r in plan["runs"]:
        if r["kind"] == "closed_loop":
            ref = r["reference"]
            gains = {**base.controller_gains(), **{k: r["controller"][k] for k in ("Kp", "Ki", "Kv", "Ka")}}
            cols, _, meta = closed_loop(rig.with_(supply=r["supply_bar"] * 1e5), r["disc_sets"], ref["amplitude_deg"],
                                        ref["freq_hz"], r["duration_s"], eff, chain, rng, gains=gains,
                                        offset_deg=ref.get("offset_deg", 0.0))
        else:
            ex = r["excitation"]
            n = int(round(r["duration_s"] / DT))
            cmd = np.array([chain.dac(c) for c in chirp(n, ex["f0_hz"], ex["f1_hz"], ex["amplitude_mA"])])
            cols, meta = valve_bench(rig, cmd, r["supply_bar"], eff, chain, rng)
        meta["notes"] = "planned run (ehas plan-test), simulated by the independent generator"
        names_ = [c for c in COLUMNS if c in cols]
        data = np.column_stack([np.asarray(cols[c], float) for c in names_])
        lines = [",".join(names_)] + [",".join(_fmt(v) for v in row) for row in data]
        (camp / f"{r['name']}.csv").write_text("\n".join(lines) + "\n")
        (camp / f"{r['name']}.json").write_text(json.dumps({"format": "ehas-run", "version": 1, **meta}, indent=1))
        names.append(r["name"])
    return names


def realised(second: dict, a: str, b: str, runs: list[str]) -> float | None:
    """The separation of a and b the planned runs realised in the second diagnosis: ``10 log10`` of the mean over the
    runs of ``J_other / J_reported`` (the measure the plan predicts), None when the pair is not compared there.
    Negative when the alternative of the second diagnosis fits them better than its reported explanation; the plan
    predicts the size of the separation, not its sign, so the table compares ``|realised|`` with the prediction."""
    for e in second.get("alternatives", []) + second.get("ruled_out", []):
        if {e["name"], e["in_place_of"]} == {a, b}:
            vals = [e["per_run_db"][r] for r in runs if r in e.get("per_run_db", {})]
            if vals:
                return 10.0 * math.log10(float(np.mean([10.0 ** (v / 10.0) for v in vals])))
    return None


def run_case(name: str, work: Path, seed: int, redo_first: bool = False) -> dict:
    from tests.independent_rig.campaign import simulate, write

    from tests.independent_rig.acceptance import rig_model

    place, gen_effect, values, truth_names = CASES[name]
    rig = RIGS.get(name, "book")
    mopt = ["--model", str(rig_model(rig))] if rig != "book" else []
    folder = work / name
    folder.mkdir(parents=True, exist_ok=True)
    camp = folder / "camp"
    t0 = time.time()
    if not (camp / "truth.json").exists():
        runs, truth = simulate({gen_effect: values}, seed=seed, rig=rig, **CAMPAIGNS.get(name, ({}, ""))[0],
                               progress=lambda s: print(f"  [{name}] {s}", flush=True))
        write(camp, runs, truth, overwrite=True)
    first, second, plan_path = folder / "first.json", folder / "second.json", folder / "plan.json"
    for p in (second, plan_path) + ((first,) if redo_first else ()):
        p.unlink(missing_ok=True)
    for p in camp.glob("plan_*"):
        p.unlink()
    if not first.exists():  # the first diagnosis is kept between reruns (it does not depend on the plan)
        assert _ehas(["diagnose", str(camp), "--json", str(first), "--quiet"] + mopt) == 0
    d1 = json.loads(first.read_text())
    listed1 = _listed(d1)
    assert _ehas(["plan-test", str(first), "--out", str(plan_path)] + mopt) == 0
    plan = json.loads(plan_path.read_text())
    if plan["runs"]:
        add_plan_runs(camp, plan, {gen_effect: values}, seed)
        assert _ehas(["diagnose", str(camp), "--json", str(second), "--quiet"] + mopt) == 0
    return {**record(name, folder), "rig": rig, "elapsed_s": round(time.time() - t0, 1), "seed": seed,
            "campaign": CAMPAIGNS.get(name, ({}, "standard"))[1], "commit": commit()}


def commit(path: Path | None = None) -> str:
    """The commit the tree runs on (``+uncommitted`` when its package or tests differ from it); with ``path``, the
    commit that last recorded that file (``recorded in HASH``: the code it ran on is that commit's or older).

    Parameters
    ----------
    path : Path, optional
        A file of the repository.

    Returns
    -------
    str
        ``unknown`` outside a git work tree.
    """
    import subprocess

    def git(*args):
        return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout.strip()

    try:
        if path is not None:
            h = git("log", "-1", "--format=%h", "--", str(path.relative_to(ROOT)))
            return f"recorded in {h}" if h else "unknown"
        dirty = git("status", "--porcelain", "--", "ehas_env", "tests")
        return git("rev-parse", "--short", "HEAD") + ("+uncommitted" if dirty else "")
    except (OSError, ValueError, subprocess.CalledProcessError):
        return "unknown"


def record(name: str, folder: Path) -> dict:
    """A case's record from its diagnoses and plan in ``folder`` (first.json, plan.json, second.json)."""
    from ehas_env.diagnosis.alternatives import prefers

    place, gen_effect, values, truth_names = CASES[name]
    d1 = json.loads((folder / "first.json").read_text())
    listed1 = _listed(d1)
    plan = json.loads((folder / "plan.json").read_text())
    added = [r["name"] for r in plan["runs"]]
    d2 = json.loads((folder / "second.json").read_text()) if added else None
    pairs = []
    for s in plan["separates"]:
        pairs.append({"a": s["a"], "b": s["b"], "predicted_db": s["predicted_db"],
                      "realised_db": None if d2 is None else realised(d2, s["a"], s["b"], added)})
    named2 = list(d2["reported_model"]["effects"]) if d2 else []
    left2 = [a["name"] for a in d2.get("alternatives", [])] if d2 else []
    preferred2 = [a["name"] for a in d2.get("alternatives", [])
                  if prefers(a["score_difference_db"], a["resolvable_db"], a.get("per_run_db") or {})] if d2 else []
    return {"case": name, "place": place, "truth": {gen_effect: values}, "truth_is": list(truth_names),
            "first": {"reported": list(d1["reported_model"]["effects"]), "verdict": d1["verdict"],
                      "alternatives": [a["name"] for a in d1.get("alternatives", [])],
                      "ruled_out": [a["name"] for a in d1.get("ruled_out", [])]},
            "truth_listed_first": any(t in listed1 for t in truth_names),
            "plan": [r["name"] for r in plan["runs"]], "pairs": pairs,
            "second": None if d2 is None else {"reported": named2, "verdict": d2["verdict"],
                                                "alternatives": left2, "preferred": preferred2},
            "truth_named_second": (any(t in named2 for t in truth_names) and not any(t in left2 for t in truth_names)
                                   and not left2) if d2 else None,
            "truth_preferred_second": any(t in preferred2 for t in truth_names) and not any(
                t in preferred2 for t in left2 if t not in truth_names) if d2 else None}


def table(results: list[dict]) -> str:
    lines = ["# Closing the loop: diagnose, plan the runs that decide, diagnose again", "",
             "Regenerate with (from the repository's root; hours of CPU on two cores):", "",
             "    python -m tests.measurement.plan_loop", "",
             "Each case: a campaign of the independent generator (tests/independent_rig, no shared code) with one "
             "hidden effect; `ehas diagnose --json`, `ehas plan-test`, the plan's runs simulated by the generator "
             "with the truth and added, `ehas diagnose` again (tests/measurement/plan_loop.py; "
             "docs/measurement-format.md, 'The test plan'). A case is run once and kept (`--redo` reruns it): "
             "`commit` is the code it ran on (`+uncommitted`: with changes not yet committed; `recorded in H`: a case "
             "of an earlier run, made at commit H or before it).", "",
             "| case | place | truth | first: reported | first: alternatives (within) | first: ruled out | "
             "truth listed | planned runs | predicted dB | realised dB | second: reported | truth named | commit |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        pred = ", ".join(f"{p['predicted_db']:.1f}" for p in r["pairs"]) or "-"
        real = ", ".join("-" if p["realised_db"] is None else f"{p['realised_db']:.1f}" for p in r["pairs"]) or "-"
        truth = ", ".join(f"{n} {v}" for n, v in r["truth"].items())
        sec = r["second"]
        place = r["place"] if r.get("rig", "book") == "book" else f"{r['place']} ({r['rig']})"
        if r.get("campaign", "standard") != "standard":
            place += f" (campaign: {r['campaign']})"
        lines.append(f"| {r['case']} | {place} | {truth} | {', '.join(r['first']['reported']) or 'none'} | "
                     f"{', '.join(r['first']['alternatives']) or 'none'} | {', '.join(r['first']['ruled_out']) or 'none'} | "
                     f"{'yes' if r['truth_listed_first'] else 'no'} "
                     f"| {', '.join(r['plan']) or 'none'} | {pred} | {real} | "
                     f"{', '.join(sec['reported']) or 'none' if sec else '-'} | "
                     f"{_named(r)} | {r.get('commit', 'unknown')} |")
    n = len(results)
    if n:
        listed = sum(r["truth_listed_first"] for r in results)
        planned = [r for r in results if r["plan"]]
        named = sum(_named(r) == "yes" for r in planned)
        decided = [r["case"] for r in results if not r["plan"]]
        agree = [abs(p["predicted_db"] - abs(p["realised_db"])) <= 3.0 for r in results for p in r["pairs"]
                 if p["realised_db"] is not None]
        amb = [r for r in results if r["first"]["alternatives"]]
        amb_named = sum(_named(r) == "yes" for r in amb if r["plan"])
        amb_agree = [abs(p["predicted_db"] - abs(p["realised_db"])) <= 3.0 for r in amb for p in r["pairs"]
                     if p["realised_db"] is not None]
        pairs = sorted({" vs ".join(sorted(_pair(r))) for r in amb})
        lines += ["", f"Genuinely ambiguous (the first diagnosis lists an alternative these logs cannot tell from the "
                      f"reported one): {len(amb)} of {n} cases, {len(pairs)} distinct pairs or triples "
                      f"({'; '.join(pairs) or 'none'}), places: "
                      f"{', '.join(sorted({r['place'] for r in amb})) or 'none'}. Of these: truth listed "
                      f"{sum(r['truth_listed_first'] for r in amb)} of {len(amb)}; the second diagnosis names the "
                      f"truth (reported, no alternative left within) in {amb_named} of {len(amb)}; predicted and "
                      f"realised separation within 3 dB: {sum(amb_agree)} of {len(amb_agree)} pairs. The truth not reported "
                      f"but preferred by the data in the second diagnosis' words (an alternative fitting better than "
                      f"the reported one by more than the logs resolve): "
                      f"{sum(bool(r.get('truth_preferred_second')) and _named(r) != 'yes' for r in amb)}."]
        lines += ["", f"Truth among the listed explanations in the first diagnosis: {listed} of {n}. Cases with a "
                      f"plan: {len(planned)}; the second diagnosis names the truth (reported, no alternative left "
                      f"within) in {named} of them. Predicted and realised separation within 3 dB: {sum(agree)} of "
                      f"{len(agree)} pairs."
                      + (f" Decided by the first diagnosis already (no alternative within, nothing to plan): "
                         f"{', '.join(decided)}." if decided else "")]
    lines += ["", "Notes on the runs (by hand): NOTES.md. Spurious alternatives on the acceptance campaigns: "
                  "spurious.md. `ehas plan-test`'s time: plan_test_time.md."]
    return "\n".join(lines) + "\n"


def _pair(r: dict) -> frozenset:
    """The explanations a first diagnosis could not tell apart: its alternatives within and the reported effects they
    stand for (those they are rivals of; all reported ones when none is)."""
    from ehas_env.diagnosis.alternatives import rivals_of

    alts = set(r["first"]["alternatives"])
    rep = [e for e in r["first"]["reported"] if any(a in rivals_of(e) or e in rivals_of(a) for a in alts)]
    return frozenset(alts | set(rep or r["first"]["reported"]))


def _named(r: dict) -> str:
    """The second diagnosis' answer: the truth reported and nothing left within, reported with alternatives left,
    or not reported."""
    if r["second"] is None:
        return "no plan needed"
    if not r["truth_named_second"]:
        if r.get("truth_preferred_second"):
            return (f"preferred by the data ({', '.join(r['second']['preferred'])} better than the reported "
                    f"{', '.join(r['second']['reported'])}), not reported")
        return "no"
    left = r["second"]["alternatives"]
    return "yes" if not left else f"reported, but {', '.join(left)} still within"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="close the loop of ehas plan-test on the independent generator")
    ap.add_argument("--work", default="/tmp/ehas_test_plans", help="folder for the campaigns and diagnoses")
    ap.add_argument("--cases", default=",".join(CASES), help="cases to run, comma-separated: " + ", ".join(CASES))
    ap.add_argument("--redo", action="store_true", help="redo cases already finished (the campaign and the first "
                    "diagnosis are kept in --work: only the plan and the second diagnosis are redone)")
    ap.add_argument("--redo-first", action="store_true", help="with --redo: the first diagnosis too")
    ap.add_argument("--rescore", action="store_true", help="rebuild finished cases' records from their diagnoses and "
                    "plans in --work (nothing simulated or diagnosed)")
    a = ap.parse_args(argv)
    work = Path(a.work)
    (OUT / "cases").mkdir(parents=True, exist_ok=True)
    names = [c.strip() for c in a.cases.split(",") if c.strip()]
    bad = [c for c in names if c not in CASES]
    if bad:
        print(f"plan_loop: error: unknown case {bad[0]!r}; cases: {', '.join(CASES)}", file=sys.stderr)
        return 2
    from ehas_env.output.files import atomic_write_text

    for k, name in enumerate(names):
        path = OUT / "cases" / f"{name}.json"
        if a.rescore:
            if path.exists() and (work / name / "plan.json").exists():
                old = json.loads(path.read_text())
                atomic_write_text(path, json.dumps({**record(name, work / name), **{
                    k: old[k] for k in ("rig", "elapsed_s", "seed", "campaign", "commit") if k in old}}, indent=1)
                                  + "\n")
            continue
        if path.exists() and not a.redo:
            print(f"[plan_loop] {name}: done before ({path})", flush=True)
            continue
        print(f"[plan_loop] {name}: simulating, diagnosing, planning, diagnosing again", flush=True)
        res = run_case(name, work, seed=100 + list(CASES).index(name), redo_first=a.redo_first)
        atomic_write_text(path, json.dumps(res, indent=1) + "\n")
        print(f"[plan_loop] {name}: {json.dumps(res)}", flush=True)
    results = [json.loads((OUT / "cases" / f"{n}.json").read_text()) for n in CASES
               if (OUT / "cases" / f"{n}.json").exists()]
    for r in results:  # cases recorded before the commit was kept in their record
        r.setdefault("commit", commit(OUT / "cases" / f"{r['case']}.json"))
    atomic_write_text(OUT / "README.md", table(results))
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
