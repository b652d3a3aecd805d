"""The long-test benchmark: N cycles from rest per condition, the steady state a learning controller reaches.

Beside the 4-cycle benchmark (:mod:`.benchmark`, unchanged), ``ehas bench --long-test [N]``
runs every controller (classical, learning, learned) for N reference cycles (default 30)
on each condition of the grid and reports, per condition, the figures of
:func:`ehas_env.simulation.long_test.long_test_metrics`: the steady-state rms % error
(last five cycles), the cycles to settle, the worst cycle during learning.  A learning
controller (one with a fixed-gain ``base`` loop: :mod:`.ilc`, :mod:`.harmonic`) is also
held to its base loop: its worst learning cycle is **flagged** where it exceeds the base
loop's worst cycle on the same condition by more than 50 %.

Each run is one ``Plant.simulate_closed_loop``: compiled controllers in the compiled
loop, the others (learning controllers, learned agents) through ``act`` in Python.

Outputs (:func:`run_long_test`, into ``OUT/long_test/``): ``long_test.csv`` (one row per
controller and condition, with the per-cycle rms), ``long_test.md`` (summary, per-condition
tables, the regenerating command) and ``heatmap_long_<controller>.png``.

A learning controller's **guard** (:mod:`.learning`) is reported beside it: per run the number of
guard events and the state it ended in (``learning``, ``stopped``, ``halved``, ``base``), and per
controller the runs where the guard acted and the runs that **ended worse than the base loop**
(:func:`worse_than_base`).  :func:`guard_long_test` runs learning controllers on a list of plants
(the book's, plants built to break them, the sensor layer over several noise seeds) and writes
``guard_long_test.csv`` / ``.md`` / ``.json`` with the median and worst seed.
"""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import math

import numpy as np

from ehas_env.simulation.long_test import DEFAULT_CYCLES, STEADY_CYCLES, long_test_metrics

from .batch_sim import Condition, grid
from .benchmark import AMPLITUDES, DISC_SETS, FREQS, _merge_effects, _slug, _unique_names, heatmap

#: a learning transient is flagged above this multiple of the fixed-gain loop's worst cycle
TRANSIENT_LIMIT = 1.5
LONG_FILES = ("long_test.csv", "long_test.md", "long_test.json", "long_test_robustness.csv", "heatmap_long_*.png")
#: the robustness grid of the long test (a third of the 63 conditions: the corners and middle of the load range)
ROBUST_DISC_SETS = (1, 4, 7)
ROBUST_AMPLITUDES = (10.0, 30.0)
#: a run is divergent when its steady error exceeds this multiple of the best five cycles it reached before
DIVERGENCE_RATIO = 2.0
DIVERGENCE_FLOOR_PCT = 0.05
#: a learning run ends worse than its base loop when its steady rms exceeds the base loop's by this fraction
#: plus the base loop's own wander (the standard deviation of its last five cycles' rms): a periodic orbit
#: reached again after a fall-back matches the base loop's own run far below a per cent; a base loop that
#: oscillates without repeating (a valve gain twice the design's) wanders by per cents from cycle to cycle
WORSE_TOLERANCE = 0.01
CSV_COLUMNS = ("controller", "kind", "disc_sets", "freq_hz", "amplitude_deg", "steady_rms_pct", "steady_peak_pct",
               "settle_cycles", "worst_cycle_pct", "worst_cycle", "base_worst_cycle_pct", "transient_flag",
               "hit_stroke_end", "max_current_mA", "guard_events", "guard_state", "cycle_rms_pct")


def run_condition(controller, cond: Condition, *, cycles: int = DEFAULT_CYCLES, plant_kwargs: dict | None = None) -> dict:
    """One long test: ``controller`` on ``cond`` for ``cycles`` reference periods from rest.

    Parameters
    ----------
    controller : Controller
        Any controller (``for_plant`` picks a schedule's entry and prepares a learning controller).
    cond : Condition
        Disc sets, frequency (Hz), amplitude (deg) and effects of the plant.
    cycles : int
        Reference periods of the run (at least 7).
    plant_kwargs : dict, optional
        Further ``Plant`` arguments (``model``, ``sensors``, ``effects`` merged with the condition's).

    Returns
    -------
    dict
        The condition and :func:`~ehas_env.simulation.long_test.long_test_metrics`, plus
        ``hit_stroke_end`` and ``max_current_mA`` (mA) over the run.
    """
    from ehas_env.simulation.plant import Plant

    kw = _merge_effects(plant_kwargs, cond.effects_dict)
    kw.setdefault("seed", 0)  # the sensor noise of every condition seeded, as in the 4-cycle benchmark
    sub = controller.for_plant(cond.disc_sets) if hasattr(controller, "for_plant") else controller
    plant = Plant(disc_sets=cond.disc_sets, **kw)
    # two samples past N periods, so that the run holds N whole cycles (the metric's cycles end at t0 + N T)
    res = plant.simulate_closed_loop(sub, amplitude_deg=cond.amplitude_deg, freq_hz=cond.freq_hz,
                                     duration=cycles / cond.freq_hz + 2 * plant.dt)
    row = {"disc_sets": cond.disc_sets, "freq_hz": cond.freq_hz, "amplitude_deg": cond.amplitude_deg,
           "effects": cond.effects_dict}
    row.update(long_test_metrics(res.t, res.theta_ref_deg, res.theta_deg, cond.amplitude_deg, cond.freq_hz))
    row["hit_stroke_end"] = res.hit_stroke_end
    row["max_current_mA"] = float(np.abs(res.current_mA).max())
    row.update(guard_fields(sub))
    return row


def guard_fields(sub) -> dict:
    """A learning controller's guard after a run: ``guard_events`` (count), ``guard_state``, ``guard_log``.

    Parameters
    ----------
    sub : Controller
        The copy that ran (:meth:`~.learning.CycleLearner.for_plant`); a controller without a guard gives {}.

    Returns
    -------
    dict
        The three fields, or {}.
    """
    log = getattr(sub, "guard_log", None)
    if log is None:
        return {}
    return {"guard_events": len(log), "guard_state": sub.guard_state, "guard_log": list(log)}


def worse_than_base(row, base_row) -> bool:
    """A learning run that ended worse than its fixed-gain base loop on the same plant and condition.

    Parameters
    ----------
    row, base_row : dict
        The learning controller's and the base loop's rows (``steady_rms_pct``, %).

    Returns
    -------
    bool
        ``steady > (1 + WORSE_TOLERANCE) x the base loop's steady + std(the base loop's last five cycles' rms)``.
    """
    return bool(row["steady_rms_pct"] > worse_limit(base_row))


def worse_limit(base_row) -> float:
    """The steady rms % above which a learning run ended worse than the base loop of ``base_row``."""
    wander = float(np.std(np.asarray(base_row["cycle_rms_pct"], dtype=float)[-STEADY_CYCLES:]))
    return (1.0 + WORSE_TOLERANCE) * base_row["steady_rms_pct"] + wander


def evaluate_long(controller, conditions, *, cycles: int = DEFAULT_CYCLES, plant_kwargs: dict | None = None,
                  progress: bool = True, desc: str | None = None) -> list[dict]:
    """:func:`run_condition` on each condition, with a progress bar naming the controller.

    Parameters
    ----------
    controller : Controller
        The controller.
    conditions : iterable of Condition
        The conditions.
    cycles : int
        Reference periods per run.
    plant_kwargs : dict, optional
        Further ``Plant`` arguments.
    progress : bool
        Show the progress bar.
    desc : str, optional
        The bar's label (default: the controller's name).

    Returns
    -------
    list of dict
        One row per condition (:func:`run_condition`).
    """
    from ehas_env.output.progress import bar

    rows = []
    for c in bar(list(conditions), desc=desc or f"long test {getattr(controller, 'name', 'controller')}",
                 unit="run", disable=not progress):
        rows.append(run_condition(controller, c, cycles=cycles, plant_kwargs=plant_kwargs))
    return rows


def spread_variants(model=None) -> list[tuple[str, dict]]:
    """The plants a learning controller designed on the book's model must stay convergent on.

    +-30 % on the bulk modulus (``bulk_modulus`` beta, 1 GPa), on the valve's flow gain
    (``valve_dynamics`` K, 1.2723 LPM/mA) and on seal friction (``coulomb_friction`` Fc and
    ``viscous_friction`` b, each around the middle of its ``typical`` range - the book's plant has
    none, so +-30 % of a typical rig's); with a calibrated ``model``, also the ends of its 95 % intervals
    (:func:`interval_variants`).

    Parameters
    ----------
    model : ehas_env.simulation.model_file.PlantModel, optional
        The calibrated model the runs are on (``--model``).

    Returns
    -------
    list of (str, dict)
        ``(label, effects)`` per plant.
    """
    from ehas_env.physics.effects import REGISTRY

    def mid(effect, param):
        p = next(q for q in REGISTRY[effect].params if q.name == param)
        return 0.5 * (p.typical[0] + p.typical[1]) if p.typical else p.default

    out = []
    for f in (0.7, 1.3):
        out.append((f"beta x{f:g}", {"bulk_modulus": {"beta": 1.0e9 * f}}))
        out.append((f"K x{f:g}", {"valve_dynamics": {"K": 1.2723 * f}}))
        out.append((f"friction x{f:g}", {"coulomb_friction": {"Fc": mid("coulomb_friction", "Fc") * f},
                                         "viscous_friction": {"b": mid("viscous_friction", "b") * f}}))
    return out + interval_variants(model)


def interval_variants(model) -> list[tuple[str, dict]]:
    """Plants at the ends of a calibrated model's 95 % intervals, one fitted number at a time.

    A model file written by ``ehas compare --fit --save-model`` records each fitted number's interval in
    ``calibration.ci95`` (rows ``{effect, param, value, low, high, unit}``; ``effect`` "baseline" for the
    bulk modulus beta and the valve gain K).  Each end becomes one plant: the model with that number moved
    there (beta and K through the effects that set them, ``bulk_modulus`` and ``valve_dynamics`` with the
    model's own wn and zeta).  A side the data do not bound (null) gives no plant.

    Parameters
    ----------
    model : ehas_env.simulation.model_file.PlantModel or None
        The calibrated model the learning runs on (``--model``); None or a model without intervals gives none.

    Returns
    -------
    list of (str, dict)
        ``(label, effects)`` per plant, the effects given on top of the model's (same name: these win).
    """
    rows = ((getattr(model, "calibration", None) or {}).get("ci95") or []) if model is not None else []
    out = []
    for r in rows:
        effect, param = r.get("effect"), r.get("param")
        for side in ("low", "high"):
            v = r.get(side)
            if v is None or not math.isfinite(float(v)):
                continue
            if effect == "baseline" and param == "beta":
                eff = {"bulk_modulus": {"beta": float(v)}}
            elif effect == "baseline" and param == "K":
                eff = {"valve_dynamics": {"K": float(v), "wn": model.rig.wn, "zeta": model.rig.zeta}}
            elif effect in model.effects:
                eff = {effect: {**model.effects[effect], param: float(v)}}
            else:
                continue
            out.append((f"{param} at its 95 % {side} end ({float(v):.4g} {r.get('unit', '')})".replace(" )", ")"), eff))
    return out


def divergent(row, base_row=None) -> bool:
    """A long run that did not converge: its steady error grew back above twice the best it reached before.

    "The best it reached before" is the smallest rms over :data:`STEADY_CYCLES` consecutive cycles
    (cycles 2 .. N - 5), so that a lucky cycle in sensor noise does not count as convergence.

    Parameters
    ----------
    row : dict
        A :func:`run_condition` row.
    base_row : dict, optional
        The fixed-gain base loop's row on the same plant: learning that ends worse than the loop
        it runs on is divergent too.

    Returns
    -------
    bool
        True for a divergent run (a steady error below :data:`DIVERGENCE_FLOOR_PCT` never is).
    """
    per = np.asarray(row["cycle_rms_pct"], dtype=float)
    steady = row["steady_rms_pct"]
    if steady < DIVERGENCE_FLOOR_PCT:
        return False
    k = STEADY_CYCLES
    windows = [np.sqrt(np.mean(per[j:j + k] ** 2)) for j in range(1, per.size - 2 * k + 1)]
    grew = bool(windows) and steady > DIVERGENCE_RATIO * min(windows)
    worse = base_row is not None and steady > base_row["steady_rms_pct"]
    return bool(grew or worse)


def run_robustness(controllers, names, *, cycles: int, plant_kwargs: dict | None, progress: bool) -> list[dict]:
    """Learning controllers on the spread plants (:func:`spread_variants`), over the robustness grid.

    Parameters
    ----------
    controllers : list of Controller
        The learning controllers (each with a fixed-gain ``base``).
    names : list of str
        Their names in the tables.
    cycles : int
        Reference periods per run.
    plant_kwargs : dict, optional
        Further ``Plant`` arguments.
    progress : bool
        Progress bars.

    Returns
    -------
    list of dict
        Per controller and plant: ``controller``, ``plant``, ``effects``, ``conditions``,
        ``mean_steady_rms_pct``, ``worst_steady_rms_pct``, ``base_mean_steady_rms_pct``, ``divergent``.
    """
    conds = grid(ROBUST_DISC_SETS, FREQS, ROBUST_AMPLITUDES)
    out = []
    for label, effects in spread_variants((plant_kwargs or {}).get("model")):
        kw = _merge_effects(plant_kwargs, effects)
        for ctrl, name in zip(controllers, names):
            rows = evaluate_long(ctrl, conds, cycles=cycles, plant_kwargs=kw, progress=progress,
                                 desc=f"robustness {label}: {name}")
            base = evaluate_long(ctrl.base, conds, cycles=cycles, plant_kwargs=kw, progress=progress,
                                 desc=f"robustness {label}: {ctrl.base.name}")
            out.append({"controller": name, "plant": label, "effects": effects, "conditions": len(rows),
                        "mean_steady_rms_pct": float(np.mean([r["steady_rms_pct"] for r in rows])),
                        "worst_steady_rms_pct": float(max(r["steady_rms_pct"] for r in rows)),
                        "base_mean_steady_rms_pct": float(np.mean([b["steady_rms_pct"] for b in base])),
                        "divergent": int(sum(divergent(r, b) for r, b in zip(rows, base)))})
    return out


def summarise(rows) -> dict:
    """Mean/worst steady rms %, settle cycles, flags and stroke hits of a controller's rows.

    Parameters
    ----------
    rows : list of dict
        :func:`run_condition` rows (``transient_flag`` where the base loop's worst is known).

    Returns
    -------
    dict
        ``mean_steady_rms_pct``, ``worst_steady_rms_pct`` (%), ``mean_settle_cycles``,
        ``max_settle_cycles``, ``worst_cycle_pct`` (%), ``transient_flags``, ``divergent``, ``stroke_end_hits``.
    """
    steady = np.array([r["steady_rms_pct"] for r in rows])
    settle = np.array([r["settle_cycles"] for r in rows])
    return {"conditions": len(rows), "mean_steady_rms_pct": float(steady.mean()),
            "worst_steady_rms_pct": float(steady.max()), "mean_settle_cycles": float(settle.mean()),
            "max_settle_cycles": int(settle.max()), "worst_cycle_pct": float(max(r["worst_cycle_pct"] for r in rows)),
            "transient_flags": int(sum(bool(r.get("transient_flag")) for r in rows)),
            "divergent": int(sum(bool(r.get("divergent")) for r in rows)),
            "stroke_end_hits": int(sum(bool(r["hit_stroke_end"]) for r in rows)),
            "guarded_runs": int(sum(bool(r.get("guard_events")) for r in rows)),
            "fallbacks_to_base": int(sum(r.get("guard_state") == "base" for r in rows)),
            "worse_than_base": int(sum(bool(r.get("worse_than_base")) for r in rows))}


def run_long_test(controllers, out_dir, *, cycles: int = DEFAULT_CYCLES, plant_kwargs: dict | None = None,
                  command: str = "ehas bench --long-test", progress: bool = True, disc_sets=DISC_SETS,
                  plant_label: str = "book rig", robustness: bool = False) -> dict:
    """The long test of ``controllers`` on the grid; writes ``long_test.csv``, ``.md``, ``.json`` and heat maps.

    Parameters
    ----------
    controllers : list of Controller
        The controllers (any kind).
    out_dir : str or path
        Folder to write into (the caller's output set).
    cycles : int
        Reference periods per run (default 30).
    plant_kwargs : dict, optional
        Further ``Plant`` arguments (model file, sensors).
    command : str
        The regenerating command, written into every file.
    progress : bool
        Progress bars.
    disc_sets : sequence of int
        Narrow the grid (tests); default 1..7 (63 conditions).
    plant_label : str
        Words naming the plant in the files.
    robustness : bool
        Also run the learning controllers on the spread plants (:func:`run_robustness`) and
        write ``long_test_robustness.csv``.

    Returns
    -------
    dict
        ``summary`` (controller name -> :func:`summarise`) and ``rows`` (name -> rows).
    """
    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.progress import status

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    controllers = list(controllers)
    names = _unique_names(controllers)
    conds = grid(tuple(disc_sets), FREQS, AMPLITUDES)
    status(f"long test: {len(controllers)} controller(s) x {len(conds)} conditions x {cycles} cycles", "bench")
    results, base_rows = {}, {}
    for ctrl, name in zip(controllers, names):
        results[name] = evaluate_long(ctrl, conds, cycles=cycles, plant_kwargs=plant_kwargs, progress=progress)
        base = getattr(ctrl, "base", None)
        if base is not None:  # a learning controller: its fixed-gain loop on the same conditions
            key = json.dumps(base.to_dict(), sort_keys=True, default=str)
            if key not in base_rows:
                base_rows[key] = evaluate_long(base, conds, cycles=cycles, plant_kwargs=plant_kwargs,
                                               progress=progress, desc=f"long test {base.name} (fixed-gain base)")
            for r, b in zip(results[name], base_rows[key]):
                r["base_worst_cycle_pct"] = b["worst_cycle_pct"]
                r["transient_flag"] = r["worst_cycle_pct"] > TRANSIENT_LIMIT * b["worst_cycle_pct"]
                r["base_steady_rms_pct"] = b["steady_rms_pct"]
                r["worse_than_base"] = worse_than_base(r, b)
    for name in names:
        for r in results[name]:
            r["divergent"] = divergent(r)
    summary = {name: {"kind": getattr(c, "kind", "?"), **summarise(results[name])}
               for c, name in zip(controllers, names)}
    robust = []
    learning = [(c, n) for c, n in zip(controllers, names) if getattr(c, "base", None) is not None]
    if robustness and learning:
        robust = run_robustness([c for c, _ in learning], [n for _, n in learning], cycles=cycles,
                                plant_kwargs=plant_kwargs, progress=progress)
        atomic_write_text(out / "long_test_robustness.csv", _robust_csv(robust, command, cycles))
    status(f"writing {out}: long_test.csv, long_test.md, long_test.json, {len(names)} heatmap(s)", "bench")
    atomic_write_text(out / "long_test.csv", _csv(controllers, names, results, command, cycles))
    pngs = {name: heatmap(results[name], out / f"heatmap_long_{_slug(name)}.png",
                          title=f"'{name}', {plant_label}: steady-state rms % error (long test)", command=command,
                          key="steady_rms_pct",
                          xlabel=f"reference: frequency, amplitude (sine, {cycles} periods, last {STEADY_CYCLES})")
            for name in names}
    atomic_write_text(out / "long_test.json", json.dumps({"command": command, "cycles": cycles, "plant": plant_label,
                                                          "summary": summary}, indent=2) + "\n")
    atomic_write_text(out / "long_test.md", _markdown(names, results, summary, pngs, command, cycles, plant_label,
                                                      tuple(disc_sets), robust))
    return {"summary": summary, "rows": results, "robustness": robust}


def _robust_csv(robust, command, cycles) -> str:
    buf = io.StringIO()
    buf.write(f"# long-test robustness ({cycles} cycles; disc sets {ROBUST_DISC_SETS} x {FREQS} Hz x "
              f"{ROBUST_AMPLITUDES} deg), regenerate with: {command}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["controller", "plant", "effects", "conditions", "mean_steady_rms_pct", "worst_steady_rms_pct",
                "base_mean_steady_rms_pct", "divergent_runs"])
    for r in robust:
        eff = ";".join(f"{e}:" + ",".join(f"{k}={v:.4g}" for k, v in p.items()) for e, p in r["effects"].items())
        w.writerow([r["controller"], r["plant"], eff, r["conditions"], f"{r['mean_steady_rms_pct']:.5g}",
                    f"{r['worst_steady_rms_pct']:.5g}", f"{r['base_mean_steady_rms_pct']:.5g}", r["divergent"]])
    return buf.getvalue()


def _csv(controllers, names, results, command, cycles) -> str:
    buf = io.StringIO()
    buf.write(f"# long-test benchmark ({cycles} cycles from rest per condition), regenerate with: {command}\n")
    buf.write(f"# steady_rms_pct / steady_peak_pct: 100 RMS / max(theta_ref - theta) / amplitude over the last "
              f"{STEADY_CYCLES} cycles; settle_cycles: first cycle from which every cycle's rms stays within 10 % of "
              "it; worst_cycle_pct: largest per-cycle rms over cycles 2..N; transient_flag: worst_cycle_pct > 1.5 x "
              "the fixed-gain base loop's; cycle_rms_pct: per-cycle rms %, cycles 1..N separated by ';'\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for ctrl, name in zip(controllers, names):
        for r in results[name]:
            base = r.get("base_worst_cycle_pct")
            w.writerow([name, getattr(ctrl, "kind", "?"), r["disc_sets"], f"{r['freq_hz']:g}", f"{r['amplitude_deg']:g}",
                        f"{r['steady_rms_pct']:.6g}", f"{r['steady_peak_pct']:.6g}", r["settle_cycles"],
                        f"{r['worst_cycle_pct']:.6g}", r["worst_cycle"], "" if base is None else f"{base:.6g}",
                        int(bool(r.get("transient_flag"))), int(bool(r["hit_stroke_end"])),
                        f"{r['max_current_mA']:.4g}", r.get("guard_events", ""), r.get("guard_state", ""),
                        ";".join(f"{x:.4g}" for x in r["cycle_rms_pct"])])
    return buf.getvalue()


def _table(rows, key, fmt, disc_sets) -> list[str]:
    cols = [(f, a) for f in FREQS for a in AMPLITUDES]
    lines = ["| disc sets | " + " | ".join(f"{f:g} Hz {a:g}°" for f, a in cols) + " |", "|---|" + "---:|" * len(cols)]
    by = {(r["disc_sets"], r["freq_hz"], r["amplitude_deg"]): r for r in rows}
    for n in disc_sets:
        cells = []
        for f, a in cols:
            r = by[(n, f, a)]
            cells.append(fmt(r[key]) + (" **!**" if r.get("transient_flag") else "")
                         + (" **STROKE**" if r["hit_stroke_end"] else ""))
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return lines


def _markdown(names, results, summary, pngs, command, cycles, plant_label, disc_sets, robust=()) -> str:
    n = len(next(iter(results.values()))) if results else 0
    lines = [f"# Long-test benchmark: {plant_label}", "", f"Regenerate with `{command}`.", "",
             f"Protocol: each of {n} conditions (disc sets {', '.join(map(str, disc_sets))} × {{1, 2, 3}} Hz × "
             f"{{10, 20, 30}}°) runs **{cycles} reference cycles from rest** (amplitude faded in over the first). "
             f"Metric (`ehas_env.simulation.long_test`, the % error of docs/metric.md over other windows): "
             f"**steady rms %** = 100 · RMS(θ_ref − θ)/θ_amp over the last {STEADY_CYCLES} cycles; **settle** = the "
             "first cycle from which every cycle's rms stays within 10 % of the steady figure (2: settled once the "
             f"warm-up is over; {cycles + 1}: not settled); **worst cycle** = the largest per-cycle rms over cycles "
             f"2..{cycles}, flagged **!** for a learning controller where it exceeds its fixed-gain base loop's worst "
             "cycle by more than 50 %. The 4-cycle benchmark (`benchmark.md`) is unchanged beside it.", "",
             "## Summary", "",
             "| controller | kind | mean steady rms % | worst steady rms % | mean settle cycle | max settle cycle | "
             "worst cycle % | flagged transients | divergent runs | stroke-end hits | guard events: runs / fallbacks "
             "to base | ended worse than base |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name in names:
        s = summary[name]
        learning = any("guard_state" in r for r in results[name])
        guard = f"{s['guarded_runs']} / {s['fallbacks_to_base']}" if learning else "-"
        worse = str(s["worse_than_base"]) if learning else "-"
        lines.append(f"| {name} | {s['kind']} | {s['mean_steady_rms_pct']:.4f} | {s['worst_steady_rms_pct']:.4f} | "
                     f"{s['mean_settle_cycles']:.1f} | {s['max_settle_cycles']} | {s['worst_cycle_pct']:.3g} | "
                     f"{s['transient_flags']} | {s['divergent']} | {s['stroke_end_hits']} | {guard} | {worse} |")
    lines += ["", f"A run is **divergent** when its steady error (last {STEADY_CYCLES} cycles) exceeds "
              f"{DIVERGENCE_RATIO:g} × the best {STEADY_CYCLES} consecutive cycles it reached before (and "
              f"{DIVERGENCE_FLOOR_PCT:g} %): an error that grows back, from a learning that does not converge or a "
              "loop that oscillates. **Guard events**: runs where the learning controller's guard acted "
              "(docs/learning-control.md) / runs it ended on the base loop alone; **ended worse than base**: steady "
              f"rms above {1 + WORSE_TOLERANCE:g} × its fixed-gain base loop's on the same condition plus that loop's "
              f"own wander (the standard deviation of its last {STEADY_CYCLES} cycles' rms)."]
    if robust:
        lines += ["", "## Robustness: designed on the book's model, run on other plants", "",
                  f"Each learning controller on {len({r['plant'] for r in robust})} plants, ±30 % on β, K and friction, "
                  f"{robust[0]['conditions']} conditions each (disc sets {', '.join(map(str, ROBUST_DISC_SETS))} × "
                  f"{{1, 2, 3}} Hz × {{{', '.join(f'{a:g}' for a in ROBUST_AMPLITUDES)}}}°), {cycles} cycles. A run is "
                  "divergent as above, or when it ends worse than its fixed-gain base loop on the same plant. "
                  "Full numbers: `long_test_robustness.csv`.", "",
                  "| controller | plant | mean steady rms % | worst steady rms % | base loop's mean steady rms % | "
                  "divergent runs |", "|---|---|---:|---:|---:|---:|"]
        for r in robust:
            lines.append(f"| {r['controller']} | {r['plant']} | {r['mean_steady_rms_pct']:.4f} | "
                         f"{r['worst_steady_rms_pct']:.4f} | {r['base_mean_steady_rms_pct']:.4f} | {r['divergent']} |")
    for name in names:
        lines += ["", f"## {name}", "", "Steady-state rms % error:", ""]
        lines += _table(results[name], "steady_rms_pct", lambda x: f"{x:.4f}", disc_sets)
        lines += ["", "Cycles to settle:", ""]
        lines += _table(results[name], "settle_cycles", str, disc_sets)
        lines += ["", "Worst cycle during learning, rms %:", ""]
        lines += _table(results[name], "worst_cycle_pct", lambda x: f"{x:.3g}", disc_sets)
        lines += ["", f"![steady-state heat map]({Path(pngs[name]).name})"]
    return "\n".join(lines) + "\n"


GUARD_FILES = ("guard_long_test.csv", "guard_long_test.md", "guard_long_test.json", "learned_*.json")


def plant_runner(kwargs_of):
    """A :func:`guard_long_test` plant from ``Plant`` arguments: ``kwargs_of(disc_sets, seed) -> dict``.

    Parameters
    ----------
    kwargs_of : callable
        ``(disc_sets, seed) -> Plant keyword arguments`` (effects, sensors, inertia, seed, ...).

    Returns
    -------
    callable
        ``(controller, cond, cycles, seed) -> row`` (:func:`run_condition`).
    """
    def run(controller, cond, cycles, seed):
        return run_condition(controller, cond, cycles=cycles, plant_kwargs=kwargs_of(cond.disc_sets, seed))

    return run


def guard_long_test(controllers, plants, out_dir, *, conditions=None, cycles: int = DEFAULT_CYCLES,
                    command: str = "", progress: bool = True, save_learned: str | None = None) -> dict:
    """Learning controllers and their base loops on several plants (and noise seeds): do they end worse?

    Parameters
    ----------
    controllers : list of CycleLearner
        Learning controllers (each with a fixed-gain ``base``).
    plants : list of dict
        ``name``, ``what`` (words), ``run`` (``(controller, cond, cycles, seed) -> row`` with the long-test
        figures, e.g. :func:`plant_runner`) and ``seeds`` (list of int: the noise seeds it is run with).
    out_dir : str or path
        Folder for ``guard_long_test.csv``, ``.md``, ``.json`` (and ``learned_<controller>.json``).
    conditions : list of Condition, optional
        Default: the 63 conditions.
    cycles : int
        Reference cycles per run.
    command : str
        The regenerating command, written into the files.
    progress : bool
        Progress bars.
    save_learned : str, optional
        A plant's name: after its first seed, each controller is saved with what it learned there
        (``learned_<controller>.json``, the input of ``ehas export-drive``).

    Returns
    -------
    dict
        ``summary``: one dict per controller and plant (``controller``, ``plant``, ``seeds``,
        ``seed_means`` (% per seed), ``median_seed_mean_pct``, ``worst_seed_mean_pct``, ``worst_run_pct``,
        ``base_mean_pct`` (median over seeds), ``runs``, ``worse_than_base``, ``worse_on_base_alone`` (of
        those, the runs that ended with the learned signal dropped: the base loop alone, in another of its
        own oscillations than its own run's), ``gated_runs`` (the repeatability gate closed: nothing learned, the
        base loop alone), ``dropped_runs`` (the per-harmonic guard took harmonics out of learning),
        ``guarded_runs`` (the guard acted while or after learning), ``fallbacks_to_base``);
        ``rows``: every run.
    """
    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.progress import bar

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    controllers = list(controllers)
    names = _unique_names(controllers)
    conds = list(conditions) if conditions is not None else grid(DISC_SETS, FREQS, AMPLITUDES)
    rows, summary, base_cache = [], [], {}
    for plant in plants:
        for ctrl, name in zip(controllers, names):
            per_seed = []
            for seed in plant["seeds"]:
                if hasattr(ctrl, "_memory"):
                    ctrl._memory.clear()  # what it learned: this plant and seed only
                mine, base = [], []
                for c in bar(conds, desc=f"{plant['name']} seed {seed}: {name}", unit="run", disable=not progress):
                    r = plant["run"](ctrl, c, cycles, seed)
                    key = (plant["name"], seed, json.dumps(ctrl.base.to_dict(), sort_keys=True, default=str), c)
                    if key not in base_cache:  # the base loop once per plant, seed and condition
                        base_cache[key] = plant["run"](ctrl.base, c, cycles, seed)
                    b = base_cache[key]
                    r = {k: v for k, v in r.items() if k != "controller"}
                    r.update(controller=name, plant=plant["name"], seed=seed, disc_sets=c.disc_sets, freq_hz=c.freq_hz,
                             amplitude_deg=c.amplitude_deg, base_steady_rms_pct=b["steady_rms_pct"],
                             worse_than_base=worse_than_base(r, b))
                    mine.append(r)
                    base.append(b)
                rows += mine
                per_seed.append((mine, base))
                if save_learned == plant["name"] and seed == plant["seeds"][0] and hasattr(ctrl, "learned_state"):
                    ctrl.save(out / f"learned_{_slug(name)}.json", command=command,
                              notes={"learned_on": f"{plant['name']}: {plant['what']}, noise seed {seed}, "
                                                   f"{cycles} cycles per condition"})
            means = [float(np.mean([r["steady_rms_pct"] for r in m])) for m, _ in per_seed]
            all_rows = [r for m, _ in per_seed for r in m]
            summary.append({
                "controller": name, "plant": plant["name"], "what": plant["what"], "seeds": list(plant["seeds"]),
                "seed_means": means, "median_seed_mean_pct": float(np.median(means)),
                "worst_seed_mean_pct": float(max(means)),
                "worst_run_pct": float(max(r["steady_rms_pct"] for r in all_rows)),
                "base_mean_pct": float(np.median([np.mean([x["steady_rms_pct"] for x in b]) for _, b in per_seed])),
                "runs": len(all_rows), "worse_than_base": int(sum(r["worse_than_base"] for r in all_rows)),
                "worse_on_base_alone": int(sum(r["worse_than_base"] and r.get("guard_state") in ("base", "gated")
                                               for r in all_rows)),
                "gated_runs": int(sum(r.get("guard_state") == "gated" for r in all_rows)),
                "guarded_runs": int(sum(any(e["event"] != "gate" for e in r.get("guard_log", ())) for r in all_rows)),
                "dropped_runs": int(sum(any(e["event"] == "drop" for e in r.get("guard_log", ())) for r in all_rows)),
                "fallbacks_to_base": int(sum(r.get("guard_state") == "base" for r in all_rows))})
    atomic_write_text(out / "guard_long_test.csv", _guard_csv(rows, command, cycles))
    atomic_write_text(out / "guard_long_test.json", json.dumps({"command": command, "cycles": cycles,
                                                                "conditions": len(conds), "summary": summary},
                                                               indent=2) + "\n")
    atomic_write_text(out / "guard_long_test.md", _guard_markdown(summary, plants, command, cycles, len(conds)))
    return {"summary": summary, "rows": rows}


def _guard_csv(rows, command, cycles) -> str:
    buf = io.StringIO()
    buf.write(f"# guard long test ({cycles} cycles from rest per run), regenerate with: {command}\n")
    buf.write("# steady_rms_pct: 100 RMS(theta_ref - theta)/amplitude over the last 5 cycles (the true angle); "
              "base_steady_rms_pct: the fixed-gain base loop's on the same plant, condition and seed; "
              f"worse_than_base: steady > {1 + WORSE_TOLERANCE:g} x base + the std of the base loop's last "
              f"{STEADY_CYCLES} cycles' rms; guard_events: cycle:event of the guard "
              "(gate: the base loop's cycles did not repeat, nothing learned; stop: learning stopped and the best "
              "cycle's feed-forward restored; halve; base: feed-forward dropped; drop[k,...]: harmonics k of the "
              "cycle taken out of learning by the per-harmonic guard)\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["controller", "plant", "seed", "disc_sets", "freq_hz", "amplitude_deg", "steady_rms_pct",
                "base_steady_rms_pct", "worse_than_base", "guard_state", "guard_events", "cycle_rms_pct"])
    for r in rows:
        ev = []  # cycle:event, a cycle's drops as one: 4:drop[2,5,7] (the harmonics taken out of learning)
        for e in r.get("guard_log", []):
            if e["event"] == "drop" and ev and ev[-1][:2] == (e["cycle"], "drop"):
                ev[-1][2].append(e["harmonic"])
            else:
                ev.append((e["cycle"], e["event"], [e["harmonic"]] if e["event"] == "drop" else None))
        ev = ";".join(f"{c}:{name}" + (f"[{','.join(map(str, ks))}]" if ks is not None else "") for c, name, ks in ev)
        w.writerow([r["controller"], r["plant"], r["seed"], r["disc_sets"], f"{r['freq_hz']:g}",
                    f"{r['amplitude_deg']:g}", f"{r['steady_rms_pct']:.6g}", f"{r['base_steady_rms_pct']:.6g}",
                    int(r["worse_than_base"]), r.get("guard_state", ""), ev,
                    ";".join(f"{x:.4g}" for x in r["cycle_rms_pct"])])
    return buf.getvalue()


def _guard_markdown(summary, plants, command, cycles, n_conds) -> str:
    lines = ["# Guard long test: learning controllers on the book's model and on plants built to break them", "",
             f"Regenerate with `{command}`.", "",
             f"Each learning controller and its fixed-gain base loop run {n_conds} conditions × {cycles} reference "
             "cycles from rest on each plant (noise seeds as listed). Steady rms % = 100 · RMS(θ_ref − θ)/θ_amp over "
             f"the last {STEADY_CYCLES} cycles, on the true angle (docs/metric.md). A run **ended worse than its base "
             f"loop** when its steady rms exceeds {1 + WORSE_TOLERANCE:g} × the base loop's on the same plant, "
             f"condition and seed plus the base loop's own wander (the standard deviation of its last {STEADY_CYCLES} "
             "cycles' rms: 0 for a loop that repeats, per cents where it oscillates without repeating). "
             "**Gate closed**: runs where the base loop's cycles did not repeat before the first update (the "
             "repeatability gate), so nothing was learned: the base loop alone. "
             "**Harmonics dropped**: runs where the per-harmonic guard took harmonics that diverged out of "
             "learning (the others learned on). "
             "**Guard**: runs where the guard acted (took harmonics out, stopped learning and restored the best "
             "cycle's feed-forward, halved it, or dropped it) / runs that ended on the base loop alone "
             "(docs/learning-control.md). With several seeds, the mean over the conditions is taken per seed and "
             "the median and worst seed are given. A run that ended worse *on the base loop alone* had its learned "
             "signal dropped by the guard: it ran the base loop's law exactly, in another of that loop's own "
             "oscillations than the base loop's own run (a loop that has more than one, like the base loop on a "
             "valve with twice the design's gain).", "",
             "| plant | what |", "|---|---|"]
    lines += [f"| {p['name']} | {p['what']} (seeds {', '.join(map(str, p['seeds']))}) |" for p in plants]
    lines += ["", "| controller | plant | seeds | mean steady rms %: median seed | worst seed | worst run % | "
              "base loop's mean % | runs | ended worse than base (on the base loop alone) | gate closed | "
              "harmonics dropped | guard acted / fell back to base |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for s in summary:
        lines.append(f"| {s['controller']} | {s['plant']} | {len(s['seeds'])} | {s['median_seed_mean_pct']:.4f} | "
                     f"{s['worst_seed_mean_pct']:.4f} | {s['worst_run_pct']:.4f} | {s['base_mean_pct']:.4f} | "
                     f"{s['runs']} | {s['worse_than_base']} ({s['worse_on_base_alone']}) | {s['gated_runs']} | "
                     f"{s.get('dropped_runs', 0)} | {s['guarded_runs']} / "
                     f"{s['fallbacks_to_base']} |")
    total = sum(s["worse_than_base"] for s in summary)
    alone = sum(s["worse_on_base_alone"] for s in summary)
    lines += ["", f"Runs that ended worse than their base loop, all plants and controllers: **{total}** of "
              f"{sum(s['runs'] for s in summary)}; with learned feed-forward still on: **{total - alone}**.", ""]
    return "\n".join(lines)
