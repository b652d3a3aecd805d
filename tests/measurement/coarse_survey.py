"""How far a replay at fewer integrator sub-steps is from the full one (issue 44, point 3: less work per replay).

A fit steered by such replays (its scan's grid and its Jacobians at :data:`COARSE_SUBSTEPS`, trusted where a full
replay agrees within :data:`COARSE_TOL` of the noise) was built and measured at commit b48808b: drawn d00 took
114.2 s with 3881 replays (2446 coarse) against 119.5 s with 2826 full ones at the next commit, the same model to 8
digits -- the checks and the longer least-squares paths ate the saving, and it was taken out.  This survey keeps
the figures that decided it.

On campaigns of the independent generator's drawn set (``tests/independent_rig/grammar.py``, generated here):

(a) the baseline model replayed at 2-5 and 20 sub-steps a control period against the full 10: the largest RMS
    difference of any run and signal in its noise, and the time a replay of the campaign takes (side by side on
    the cores, batches of 10 models);
(b) every registered effect at both ends of each parameter's fit range (the others at their fit's start): the
    relative change of the campaign's cost at :data:`COARSE_SUBSTEPS` and whether a guard (every run and signal
    within :data:`COARSE_TOL` of the noise) would trust the coarse replay there.

    python -m tests.measurement.coarse_survey --out results/coarse_replays [--cases d00_saturation@return,...]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

COMMAND = "python -m tests.measurement.coarse_survey --out results/coarse_replays"
CASES = ("d00_saturation@return", "d14_compliance@piston_force")
SUBSTEPS = (2, 3, 4, 5, 20)
#: the coarse replay surveyed in (b), and the guard's tolerance: RMS difference in noise units in every run and signal
COARSE_SUBSTEPS = 4
COARSE_TOL = 0.01


def _campaign(cid: str, work: Path):
    from tests.independent_rig import acceptance as acc
    from tests.independent_rig import campaign as gen
    from tests.independent_rig import grammar

    case = {c["id"]: c for c in grammar.drawn_cases()}[cid]
    camp = work / cid
    runs, truth = gen.simulate(case["effects"], seed=case["seed"], rig=case["rig"], duration=case["duration"],
                               **({"blocks": case["blocks"]} if case.get("blocks") else {}))
    gen.write(camp, runs, truth, overwrite=True)
    return camp, acc.rig_model(case["rig"]), case["rig"]


def _cost(rep, sims) -> float:
    b = rep.cost_blocks(sims)
    n = sum(x.size for x in b)
    return float(np.exp(sum(x.size * np.log(max(float(np.dot(x, x)) / x.size, 1e-300)) for x in b) / n))


def _worst(rep, a, b) -> float:
    """The largest RMS difference of any run and signal between two replays, in that signal's noise."""
    return max(math.sqrt(float(np.dot(x - y, x - y)) / max(x.size, 1))
               for x, y in zip(rep.cost_blocks(a), rep.cost_blocks(b)))


def survey(cid: str, work: Path) -> dict:
    import ehas_env.diagnosis.pipeline  # noqa: F401  (registers the hypotheses and the generated blocks)
    from ehas_env.diagnosis import fitting
    from ehas_env.measurement.campaign import read_campaign
    from ehas_env.measurement.replay import ModelSpec, Replayer
    from ehas_env.physics.effects.base import REGISTRY, get_effect

    camp, model, rig = _campaign(cid, work)
    campaign = read_campaign(camp)
    full = Replayer(campaign, model=model, hypotheses=True)
    base = [ModelSpec(effects={"coulomb_friction": {"Fc": 100.0 + k}}) for k in range(10)]
    full.simulate_many(base[:1])  # compiled (or loaded) before timing

    def timed(rep):
        t = time.perf_counter()
        sims = rep.simulate_many(base)
        return sims[0], (time.perf_counter() - t) / len(base)

    ref, t_full = timed(full)
    steps = []
    for n in SUBSTEPS:
        sims, t = timed(Replayer(campaign, substeps=n, model=model, hypotheses=True))
        steps.append({"substeps": n, "worst_x_noise": round(_worst(full, sims, ref), 5),
                      "replay_ms": round(1e3 * t, 2), "time_share": round(t / t_full, 3)})
    coarse = Replayer(campaign, substeps=COARSE_SUBSTEPS, model=model, hypotheses=True)
    rows = []
    for name in sorted(REGISTRY):
        try:
            fps = [fitting.fit_range(name, p.name) for p in get_effect(name).params]
        except Exception:  # noqa: BLE001 -- an effect without a fit range is not fitted
            continue
        for fp in fps:
            for end in ("lo", "hi"):
                values = {f.name: fitting.start_value(f) for f in fps}
                values[fp.name] = getattr(fp, end)
                m = ModelSpec(effects={name: values})
                try:
                    a, b = full.simulate(m), coarse.simulate(m)
                    ca, cb = _cost(full, a), _cost(full, b)
                    worst = _worst(full, a, b)
                except Exception as e:  # noqa: BLE001 -- a model the effect refuses (Stribeck's Fs < Fc)
                    rows.append({"effect": name, "param": fp.name, "end": end, "error": str(e)[:120]})
                    continue
                rows.append({"effect": name, "param": fp.name, "end": end, "cost": round(ca, 4),
                             "cost_change": None if not math.isfinite(cb) else round(abs(cb - ca) / ca, 6),
                             "worst_x_noise": None if not math.isfinite(worst) else round(worst, 5),
                             "trusted": bool(math.isfinite(worst) and math.isfinite(cb)
                                             and worst <= COARSE_TOL)})
    return {"case": cid, "rig": rig, "full_substeps": full.substeps, "full_replay_ms": round(1e3 * t_full, 2),
            "substeps": steps, "coarse_substeps": COARSE_SUBSTEPS, "coarse_tol": COARSE_TOL,
            "effects": rows}


def _num(v) -> str:
    return "diverged" if v is None else f"{v:.3g}"


def readme(recs: list[dict], command: str) -> str:
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    load = [round(x, 2) for x in os.getloadavg()]
    L = ["# Replays at fewer integrator sub-steps (issue 44, point 3)", "",
         f"Regenerate: `{command}` (at commit {commit}; load (1, 5, 15 min) at the end {load} on "
         f"{os.cpu_count()} cores). A fit steered by coarse replays where a full one agrees was built on these figures "
         "and measured at commit b48808b: drawn d00 (quiet, 2 cores) took 114.2 s with 3881 replays, 2446 of them "
         "coarse, against 119.5 s with 2826 full ones without it, the same model to 8 digits -- the checks and the "
         "longer least-squares paths ate the saving (`ehas diagnose` at b48808b and at the commit after it). It was "
         "taken out.", ""]
    for r in recs:
        L += [f"## {r['case']} ({r['rig']})", "",
              f"(a) The baseline model at fewer sub-steps than {r['full_substeps']} (a replay of the campaign: "
              f"{r['full_replay_ms']} ms at {r['full_substeps']}):", "",
              "| sub-steps | largest RMS difference, x noise | ms a replay | share of the full replay's time |",
              "|---:|---:|---:|---:|"]
        L += [f"| {s['substeps']} | {s['worst_x_noise']:.5f} | {s['replay_ms']} | {s['time_share']} |"
              for s in r["substeps"]]
        rows = [x for x in r["effects"] if "error" not in x]
        bad = sorted((x for x in rows if not x["trusted"]), key=lambda x: -(x["worst_x_noise"] or math.inf))
        L += ["", f"(b) Every effect at both ends of each parameter's fit range, at {r['coarse_substeps']} sub-steps: "
              f"{len(rows)} models, {len(rows) - len(bad)} within the guard's {r['coarse_tol']} of the noise "
              f"(the largest cost change among those: "
              f"{max((x['cost_change'] for x in rows if x['trusted']), default=0):.2g} of the cost); the "
              f"{len(bad)} it refuses (most far from any fit, where both replays are far off and differ by hundreds "
              "of noise units while the cost moves by a few %):", "",
              "| effect | parameter | end | cost, x noise^2 | cost change | largest RMS difference, x noise |",
              "|---|---|---|---:|---:|---:|"]
        L += [f"| {x['effect']} | {x['param']} | {x['end']} | {x['cost']:.4g} | {_num(x['cost_change'])} | "
              f"{_num(x['worst_x_noise'])} |" for x in bad]
        L.append("")
    return "\n".join(L)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="replays at fewer integrator sub-steps against the full ones")
    ap.add_argument("--out", required=True)
    ap.add_argument("--cases", default=",".join(CASES), help="drawn case ids, comma-separated")
    ap.add_argument("--work", default=None, help="where the campaigns are generated (default: a temporary folder)")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    work = Path(a.work) if a.work else Path(tempfile.mkdtemp(prefix="ehas_coarse_"))
    recs = []
    for cid in [c for c in a.cases.split(",") if c]:
        print(f"[coarse] {cid}: generating, replaying every effect at both ends of its range (about 1-2 min)",
              flush=True)
        recs.append(survey(cid, work))
    command = COMMAND if a.cases == ",".join(CASES) else f"{COMMAND} --cases {a.cases}"
    (out / "results.json").write_text(json.dumps(recs, indent=1) + "\n")
    (out / "README.md").write_text(readme(recs, command) + "\n")
    print(f"[coarse] wrote {out / 'README.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
