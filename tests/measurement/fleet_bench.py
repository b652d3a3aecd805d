"""Benchmark of a fleet diagnosis (issue 44, point 4): 16 campaigns one by one against a 2-node local Ray cluster.

A fleet: 16 campaigns of the package's synthetic rig (4 closed-loop runs + the valve chirp, ``--duration`` s per
run), a Coulomb friction rising from campaign to campaign (a rig wearing over months).  Each is diagnosed

* one by one: ``ehas diagnose C01 ... C16 --json serial.json`` (this process, one campaign after the other);
* on a 2-node Ray cluster started here (two nodes of one CPU each, both on this machine):
  ``ehas diagnose C01 ... C16 --json ray.json --executor ray --address ADDR``;

and the two JSON files are compared without their wall times.  Writes ``OUT/results.json`` and ``OUT/README.md``
(times, their ratio, the machine's load before and after, the commit).

    python -m tests.measurement.fleet_bench --out results/fleet [--campaigns 16] [--duration 3] [--quick]

``--quick``: each diagnosis restricted to one candidate, without hypotheses or proposal (a check of the mechanics).
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
QUICK = ["--candidates", "coulomb_friction", "--no-hypotheses", "--no-propose"]


def timeless(obj):
    """A diagnosis JSON without its wall times (the one thing that differs between where a diagnosis ran)."""
    if isinstance(obj, dict):
        return {k: timeless(v) for k, v in obj.items() if k != "elapsed_s"}
    if isinstance(obj, list):
        return [timeless(v) for v in obj]
    return obj


def make_fleet(folder: Path, n: int, duration: float) -> list[str]:
    """``n`` campaigns whose Coulomb friction rises from 200 to 500 N, one seed each."""
    from ehas_env.measurement.campaign import write_campaign
    from ehas_env.measurement.synthetic import simulate_campaign

    out = []
    for k in range(n):
        fc = 200.0 + 300.0 * k / max(n - 1, 1)
        runs, _ = simulate_campaign({"coulomb_friction": {"Fc": fc}}, seed=9000 + k, perturb=True, duration=duration)
        out.append(str(write_campaign(folder / f"C{k + 1:02d}", runs)))
    return out


def _ehas(args: list, log: Path) -> float:
    t0 = time.perf_counter()
    p = subprocess.run([str(Path(sys.executable).parent / "ehas"), *args], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    log.write_text("$ ehas " + " ".join(args) + "\n" + p.stdout + "\n--- stderr\n" + p.stderr)
    if p.returncode != 0:
        raise SystemExit(f"fleet_bench: ehas {' '.join(args[:3])} ... exited {p.returncode}; see {log}")
    return wall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="results/fleet")
    ap.add_argument("--campaigns", type=int, default=16)
    ap.add_argument("--duration", type=float, default=3.0)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="ehas_fleet_"))
    camps = make_fleet(work, a.campaigns, a.duration)
    opts = ["--quiet"] + (QUICK if a.quick else [])
    load0 = os.getloadavg()
    print(f"[fleet] {len(camps)} campaigns in {work}; one by one ...", flush=True)
    t_serial = _ehas(["diagnose", *camps, *opts, "--json", str(work / "serial.json")], work / "serial.log")
    print(f"[fleet] one by one: {t_serial:.1f} s; on a 2-node Ray cluster ...", flush=True)
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    try:
        cluster.add_node(num_cpus=1)
        t_ray = _ehas(["diagnose", *camps, *opts, "--json", str(work / "ray.json"), "--executor", "ray",
                       "--address", cluster.address], work / "ray.log")
    finally:
        cluster.shutdown()
    load1 = os.getloadavg()
    same = timeless(json.loads((work / "serial.json").read_text())) == timeless(json.loads((work / "ray.json").read_text()))
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT).stdout.strip()
    cmd = "python -m tests.measurement.fleet_bench --out " + a.out + (" --quick" if a.quick else "") + \
        (f" --campaigns {a.campaigns}" if a.campaigns != 16 else "") + (f" --duration {a.duration:g}" if a.duration != 3.0 else "")
    res = {"campaigns": len(camps), "duration_s": a.duration, "quick": a.quick, "serial_s": round(t_serial, 1),
           "ray_2_nodes_s": round(t_ray, 1), "ratio": round(t_ray / t_serial, 3), "same_json": same,
           "load_before": [round(x, 2) for x in load0], "load_after": [round(x, 2) for x in load1],
           "commit": commit, "command": cmd}
    (out / "results.json").write_text(json.dumps(res, indent=2) + "\n")
    (out / "README.md").write_text(
        "# A fleet of rigs diagnosed one by one and on a 2-node Ray cluster (issue 44)\n\n"
        f"Regenerate: `{cmd}` (at commit {commit}).\n\n"
        f"{len(camps)} campaigns of the package's synthetic rig (4 closed-loop runs of {a.duration:g} s + the valve "
        "chirp each; Coulomb friction rising 200 -> 500 N over the fleet)"
        + (", each diagnosis restricted to one candidate without hypotheses or proposal" if a.quick else "")
        + ".\n\n| | wall s |\n|---|---:|\n"
        f"| one by one (`ehas diagnose C01 ... --json`) | {t_serial:.1f} |\n"
        f"| 2-node local Ray cluster, 1 CPU a node (`--executor ray --address ...`) | {t_ray:.1f} |\n"
        f"| ratio | {t_ray / t_serial:.2f} |\n\n"
        f"Same JSON (wall times left out): **{'yes' if same else 'NO'}**. Machine load (1, 5, 15 min) before "
        f"{', '.join(f'{x:.1f}' for x in load0)}, after {', '.join(f'{x:.1f}' for x in load1)} on 2 cores.\n")
    print(json.dumps(res), flush=True)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
