"""A campaign of the independent rig, written in the measurement format (docs/measurement-format.md).

A campaign is the one a test engineer runs (the plan of ``ehas simulate-campaign``,
read from ehas_env/measurement/synthetic.py, not imported): four closed-loop
sine runs over disc sets, amplitudes and frequencies, and a valve chirp
(0.5 -> 30 Hz log sweep, 8 mA, on the 70 bar flow bench).  Each run is
``RUN.csv`` + ``RUN.json``; ``truth.json`` (which campaign readers skip: a
``.json`` without its ``.csv``) records what was simulated.

Start conditions as rigs record them (options of :func:`simulate`, the defaults
being ehas's own plan): runs that start from rest without a fade-in
(``ramp_cycles=0``, the sidecar stating it or leaving the key out), a reference
that starts mid-stroke (``phase_rad``, the rig at rest at 0 or where the reference
starts), a mid-run bump on one run's crank (``bump``) and a run cut short
(``cut``: the last cycle incomplete).  docs/independent-generator.md, "Start
conditions".

Run as a script to write one::

    python -m tests.independent_rig.campaign OUT --effects return_pressure:p_t=10 --seed 3 [--rig rig_b]
        [--ramp-cycles 0 [--omit-ramp]] [--phase-deg 90 --rest start]
        [--bump cl_1set_35deg_3hz,1.5,0.03,20] [--cut cl_1set_35deg_3hz,0.15] [--exact-bounds]
        [--case ID]   (the blocks of a drawn case, tests/independent_rig/grammar.py)
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .effects import ALL, to_si
from .rig import Rig, book_rig, read_rig
from .sensors import Chain
from .simulate import DT, Bump, chirp, closed_loop, valve_bench

#: the generator's version in truth.json (``generator_version``): 2 meets a stroke end at its instant with
#: ``exact_bounds`` (an event of its integrator); 1 (and a truth.json without the field) stopped the piston at the
#: next piece's boundary, up to 1 ms late -- the same campaigns otherwise, bit for bit
VERSION = 2
PLAN = ((3, 20.0, 1.0), (5, 30.0, 2.0), (1, 35.0, 3.0), (7, 10.0, 3.0))  # (disc sets, amplitude deg, Hz)
DURATION = 3.0  # s per run
CHIRP = (0.5, 30.0, 8.0)  # Hz, Hz, mA
BENCH_SUPPLY_BAR = 70.0  # the valve's rated test (docs/rig.md)
#: rig geometries beside the book's, as model files (docs/model-file.md)
RIGS_DIR = Path(__file__).parent / "rigs"
#: beta and K as a real rig differs from its nominal numbers: +-5 % and +-1 % (the package's own
#: recalibration ranges are +-7 % and +-3 %)
BETA_SPREAD, K_SPREAD = 0.05, 0.01
COLUMNS = ("t", "current_mA", "theta_deg", "theta_ref_deg", "flow_lpm", "p_a_bar", "p_b_bar", "p_s_bar", "load_kN")


def rig_named(name: str) -> tuple:
    """(Rig, model file path or None) for ``book`` or a file stem of :data:`RIGS_DIR`."""
    if name in ("book", "", None):
        return book_rig(), None
    path = RIGS_DIR / f"{name}.json"
    return read_rig(path), path


def run_name(sets: int, amp: float, freq: float) -> str:
    s = "1set" if sets == 1 else f"{sets}sets"
    return f"cl_{s}_{amp:g}deg_{freq:g}hz".replace(".", "p")


#: start time of a scheduled campaign's first run, and the time between runs (written as the sidecars' ``recorded``)
SCHEDULE_START = "2026-11-27T08:00:00"
SCHEDULE_STEP_MIN = 40.0


def simulate(effects: dict | None = None, *, seed: int = 0, rig: str = "book", duration: float = DURATION,
             plan=PLAN, perturb: bool = True, valve: bool = True, chain: Chain | None = None, progress=None,
             schedule: dict | None = None, ramp_cycles: float = 1, state_ramp: bool = True, phase_rad: float = 0.0,
             rest: str = "zero", bump: dict | None = None, cut: dict | None = None, exact_bounds: bool = False,
             blocks: list | None = None):
    """Simulate a campaign in memory.

    Parameters
    ----------
    effects : dict
        Hidden effects ``{name: {param: value in its unit}}`` (:mod:`.effects`).
    seed : int
        Seeds the noise and the perturbation of beta and K.
    rig : str
        ``book`` or a model file stem in ``rigs/``.
    duration : float
        Seconds per run.
    plan : sequence of (disc_sets, amplitude_deg, freq_hz)
        The closed-loop runs.
    perturb : bool
        Draw beta within +-5 % and K within +-1 % of the rig's numbers.
    valve : bool
        Add the valve chirp.
    chain : Chain, optional
        Measurement chain.
    progress : callable, optional
        ``progress(text)`` after each run.
    schedule : dict, optional
        Parameters that change from run to run (drift), one value per closed-loop run in recording order:
        ``{"effects": {name: {param: [values in its unit]}}, "beta": [factors], "K": [factors]}`` (factors of
        the rig's beta and K, after the perturbation).  The valve chirp, recorded last, takes the last run's.
        With a schedule, each sidecar records its start time (``recorded``, ISO 8601; the runs
        :data:`SCHEDULE_STEP_MIN` minutes apart).
    ramp_cycles : float
        Every closed-loop run's fade-in, reference periods (0: the run starts from rest without one).
    state_ramp : bool
        The sidecars state ``ramp_cycles`` (False: the key is left out, which the format reads as 0; only with
        ``ramp_cycles`` 0).
    phase_rad : float
        The reference sine's phase, rad: without a fade-in every run's reference starts at A sin(phase), away
        from mid-stroke.
    rest : str
        Where each closed-loop run's rig rests at t = 0: ``"zero"`` (mid-stroke) or ``"start"`` (where the
        reference starts).
    bump : dict, optional
        A mid-run knock on one run's crank: ``{"run": run name, "t_s": s, "width_s": s, "torque_Nm": N m}``
        (:class:`.simulate.Bump`).
    cut : dict, optional
        One run cut short: ``{"run": run name, "short_s": s}``, its log ending ``short_s`` before the planned
        duration (the same samples up to there; the last cycle incomplete).
    exact_bounds : bool
        Chamber pressures held within [0, Ps] inside the integration too, not only between its pieces
        (:class:`.physics.RigModel`; for runs that drive a chamber to 0 bar or Ps, such as starts from rest
        without a fade-in).
    blocks : list of dict, optional
        Drawn blocks of hidden physics, ``{"place", "kind", "params" (SI)[, "words"]}`` (:mod:`.grammar`), in
        every run; truth.json records them under ``blocks``.

    Returns
    -------
    runs : list of (name, columns, sidecar)
    truth : dict
    """
    base, path = rig_named(rig)
    names = [run_name(*p) for p in plan]
    for what, opt in (("bump", bump), ("cut", cut)):
        if opt is not None and opt.get("run") not in names:
            raise ValueError(f"{what}: run {opt.get('run')!r} is not a closed-loop run of the plan; one of "
                             f"{', '.join(names)}")
    if cut is not None and not 0.0 < float(cut["short_s"]) < duration:
        raise ValueError(f"cut: short_s must be in (0, {duration:g}) s, got {cut['short_s']!r}")
    knock = (Bump(float(bump["t_s"]), float(bump["width_s"]), float(bump["torque_Nm"])) if bump is not None
             else None)
    if knock is not None and (knock.k0 + knock.periods) * DT > duration + 1e-9:
        raise ValueError(f"bump: t_s + width_s = {(knock.k0 + knock.periods) * DT:g} s is beyond the run's "
                         f"{duration:g} s")
    chain = chain or Chain()
    drawn = None
    if blocks is not None:
        from .grammar import block_from_dict  # the grammar imports this module: read here, when it is asked for

        drawn = [block_from_dict(b) for b in blocks]
    rng = np.random.default_rng(seed)
    fb = 1.0 + (rng.uniform(-BETA_SPREAD, BETA_SPREAD) if perturb else 0.0)
    fk = 1.0 + (rng.uniform(-K_SPREAD, K_SPREAD) if perturb else 0.0)
    actual: Rig = base.with_(beta=base.beta * fb, K=base.K * fk)
    eff_si = to_si(effects or {})
    runs = []
    nominal = actual
    for k, (sets, amp, freq) in enumerate(plan):
        t0 = time.time()
        actual, eff_si = _scheduled(nominal, effects, schedule, k)
        # the controller's gains are the nominal rig's (the engineer tuned on the model file), not the actual's
        name = run_name(sets, amp, freq)
        cols, _, meta = closed_loop(actual, int(sets), float(amp), float(freq), duration, eff_si, chain, rng,
                                    gains=base.controller_gains(), ramp_cycles=ramp_cycles, phase_rad=phase_rad,
                                    rest=rest, bump=knock if bump is not None and bump["run"] == name else None,
                                    state_ramp=state_ramp, exact_bounds=exact_bounds, blocks=drawn)
        meta["notes"] = f"independent generator (tests/independent_rig), seed {seed}"
        if cut is not None and cut["run"] == name:
            keep = int(round((duration - float(cut["short_s"])) / DT))
            cols = {k: np.asarray(v)[:keep] for k, v in cols.items()}
        if schedule:
            meta["recorded"] = _recorded(k)
        runs.append((name, cols, meta))
        if progress:
            progress(f"{runs[-1][0]} {time.time() - t0:.1f} s")
    if valve:
        n = int(round(duration / DT))
        cmd = np.array([chain.dac(c) for c in chirp(n, *CHIRP)])
        if schedule:
            actual, eff_si = _scheduled(nominal, effects, schedule, len(plan) - 1)
        cols, meta = valve_bench(actual, cmd, BENCH_SUPPLY_BAR, eff_si, chain, rng, blocks=drawn)
        meta["notes"] = f"valve chirp {CHIRP[0]:g}-{CHIRP[1]:g} Hz, {CHIRP[2]:g} mA, flow bench (seed {seed})"
        if schedule:
            meta["recorded"] = _recorded(len(plan))
        runs.append(("valve_chirp", cols, meta))
        actual = nominal
    truth = {"generator": "tests/independent_rig", "generator_version": VERSION, "effects": effects or {},
             "kinds": {n: ALL[n].kind for n in (effects or {})},
             "rig": rig, "model_file": str(path.name) if path else None,
             "beta_Pa": actual.beta, "K_lpm_per_mA": actual.K / (1e-3 / 60), "seed": seed, "perturb": perturb,
             "duration_s": duration, "plan": [list(p) for p in plan], "chain": chain.to_dict()}
    # the gains the runs were given, for the controller's carry-over check
    truth["controller"] = base.controller_gains()
    if schedule:
        truth["schedule"] = schedule
    if drawn is not None:
        truth["blocks"] = [b.to_dict() for b in drawn]
    start = {k: v for k, v in (("ramp_cycles", ramp_cycles), ("state_ramp", state_ramp), ("phase_rad", phase_rad),
                               ("rest", rest), ("exact_bounds", exact_bounds))
             if v != {"ramp_cycles": 1, "state_ramp": True, "phase_rad": 0.0, "rest": "zero",
                      "exact_bounds": False}[k]}
    if bump is not None:
        start["bump"] = {"run": bump["run"], **knock.to_dict()}
    if cut is not None:
        start["cut"] = {"run": cut["run"], "short_s": float(cut["short_s"])}
    if start:  # recorded only when the runs do not start as ehas plans them (older campaigns stay as they were)
        truth["start"] = start
    return runs, truth


def _scheduled(rig: Rig, effects: dict | None, schedule: dict | None, k: int) -> tuple:
    """The rig and the effects (SI) of closed-loop run ``k`` under ``schedule`` (see :func:`simulate`)."""
    eff = {n: dict(p) for n, p in (effects or {}).items()}
    if not schedule:
        return rig, to_si(eff)
    for name, params in (schedule.get("effects") or {}).items():
        for pname, values in params.items():
            eff.setdefault(name, {})[pname] = float(values[k])
    fb = float(schedule["beta"][k]) if "beta" in schedule else 1.0
    fk = float(schedule["K"][k]) if "K" in schedule else 1.0
    return rig.with_(beta=rig.beta * fb, K=rig.K * fk), to_si(eff)


def _recorded(k: int) -> str:
    from datetime import datetime, timedelta

    return (datetime.fromisoformat(SCHEDULE_START) + timedelta(minutes=SCHEDULE_STEP_MIN * k)).isoformat()


def _fmt(x: float) -> str:
    return f"{x:.9g}"


def write(out, runs, truth, *, overwrite: bool = False) -> Path:
    """Write the campaign folder (whole or nothing: a temporary folder renamed at the end)."""
    out = Path(out)
    if out.exists():
        if not overwrite:
            raise FileExistsError(f"{out} exists")
        import shutil
        shutil.rmtree(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    umask = os.umask(0)
    os.umask(umask)
    tmp.chmod(0o777 & ~umask)  # mkdtemp makes it private; a campaign folder gets the mode any folder gets
    for name, cols, meta in runs:
        names = [c for c in COLUMNS if c in cols]
        data = np.column_stack([np.asarray(cols[c], float) for c in names])
        lines = [",".join(names)] + [",".join(_fmt(v) for v in row) for row in data]
        (tmp / f"{name}.csv").write_text("\n".join(lines) + "\n")
        (tmp / f"{name}.json").write_text(json.dumps({"format": "ehas-run", "version": 1, **meta}, indent=1) + "\n")
    (tmp / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    os.replace(tmp, out)
    return out


def parse_effects(text: str) -> dict:
    """``name:p=v,q=w;other`` or ``name`` (its mild magnitude) -> {name: {p: v}}."""
    out = {}
    for part in filter(None, (text or "").split(";")):
        name, _, rest = part.partition(":")
        name = name.strip()
        if name not in ALL:
            raise SystemExit(f"unknown effect {name!r}; known: {', '.join(ALL)}")
        out[name] = ({k: float(v) for k, v in (kv.split("=") for kv in rest.split(","))} if rest
                     else ALL[name].values(0))
    return out


def _fields(text: str, n: int, option: str) -> list:
    """``RUN,x,y,...`` -> [RUN, float, ...] (n fields), or ValueError naming the option."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != n:
        raise ValueError(f"{option}: expected {n} comma-separated fields, got {text!r}")
    try:
        return [parts[0]] + [float(p) for p in parts[1:]]
    except ValueError:
        raise ValueError(f"{option}: the fields after the run name must be numbers, got {text!r}") from None


def _whole(x: float):
    """x as an int when it is whole (the sidecar writes 1, as ehas's plan does, not 1.0)."""
    return int(x) if float(x).is_integer() else float(x)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="write a campaign of the independent rig")
    ap.add_argument("out")
    ap.add_argument("--effects", default="", help="name:p=v,...;name2 (';' between effects)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rig", default="book", help="book or a stem of tests/independent_rig/rigs")
    ap.add_argument("--duration", type=float, default=DURATION)
    ap.add_argument("--no-perturb", action="store_true")
    ap.add_argument("--overwrite", action="store_true")
    ap.add_argument("--ramp-cycles", type=float, default=1.0,
                    help="fade-in of every closed-loop run, reference periods (0: start from rest without one)")
    ap.add_argument("--omit-ramp", action="store_true",
                    help="leave ramp_cycles out of the sidecars (the format's default 0; with --ramp-cycles 0)")
    ap.add_argument("--phase-deg", type=float, default=0.0, help="the reference sine's phase, deg")
    ap.add_argument("--rest", choices=("zero", "start"), default="zero",
                    help="where the rig rests at t = 0: mid-stroke or where the reference starts")
    ap.add_argument("--bump", default="", help="RUN,T_S,WIDTH_S,TORQUE_NM: a torque pulse on that run's crank")
    ap.add_argument("--cut", default="", help="RUN,SHORT_S: that run's log ends SHORT_S s early")
    ap.add_argument("--exact-bounds", action="store_true",
                    help="hold the chamber pressures within [0, Ps] inside the integration too (runs that reach them)")
    ap.add_argument("--case", default="", help="add the blocks of this drawn case (python -m "
                                               "tests.independent_rig.drawn --list); give its --seed and --rig too")
    a = ap.parse_args(argv)
    blocks = None
    if a.case:
        from .grammar import case_named

        blocks = case_named(a.case)["blocks"]
    try:
        bump = dict(zip(("run", "t_s", "width_s", "torque_Nm"), _fields(a.bump, 4, "--bump"))) if a.bump else None
        cut = dict(zip(("run", "short_s"), _fields(a.cut, 2, "--cut"))) if a.cut else None
        runs, truth = simulate(parse_effects(a.effects), seed=a.seed, rig=a.rig, duration=a.duration,
                               perturb=not a.no_perturb, progress=lambda s: print("  " + s, flush=True),
                               ramp_cycles=_whole(a.ramp_cycles), state_ramp=not a.omit_ramp,
                               phase_rad=math.radians(a.phase_deg), rest=a.rest, bump=bump, cut=cut,
                               exact_bounds=a.exact_bounds, blocks=blocks)
    except ValueError as e:
        raise SystemExit(f"campaign: {e}") from None
    truth["command"] = "python -m tests.independent_rig.campaign " + " ".join(sys.argv[1:] if argv is None else argv)
    print(f"wrote {write(a.out, runs, truth, overwrite=a.overwrite)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
