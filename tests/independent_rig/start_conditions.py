"""The verdict on campaigns as rigs record them (issue 42, point 3 and the first acceptance point).

For every hidden class of the independent generator (:data:`.effects.ALL`: out of library, library, the check
and the unlisted classes) at its strong magnitude, and a clean campaign on each of the three rigs, the same
campaign (same seed, rig, effects and noise draws) is generated in :data:`VARIANTS`:

* ``fade``: every closed-loop run faded in over one period (ehas's own plan; the reference);
* ``rest``: from rest without a fade-in, the sidecars leaving ``ramp_cycles`` out (the format's default 0);
* ``rest_bump``: ``rest`` with a knock on the 1-set run's crank at mid-run (:func:`bump_of`);
* ``mid``: without a fade-in, the reference starting at A sin(60 deg) with the rig at rest there;
* ``rest_cut``: ``rest`` with the 1-set 3 Hz run's log ending 0.15 s early (its last cycle incomplete).

(a) The verdict figure of the book model on each: ``ehas compare CAMP --json F`` (no fit), ``after.residual_x_noise``
and ``after.verdict``, with its per-block numbers; the acceptance: every variant's figure within
:data:`AGREE` of the ``fade`` one.

(b) The full diagnosis of the ``rest`` variant (``ehas diagnose CAMP --json F``): verdict, figure, what it added
to the book model (:func:`.judge.worded_items`), and whether a campaign whose hidden effect rises
:data:`VISIBLE_DB` or more above the noise on a key signal (:func:`effect_db`) is called explained with nothing
added (must be 0), and clean campaigns called unexplained (must be 0).

(c) The full diagnosis of each of :data:`DIAGNOSED` (``fade``, ``rest``, ``rest_bump``) at one commit: the final
figure of each within :data:`AGREE` of the ``fade`` one's, the same verdict words (the acceptance's agreement, on
what the diagnosis reports; ``--part c``).

Checkpoints: each finished case is ``OUT/cases/ID.json`` (part a, and part b once run); a rerun skips what is
there (Ctrl-C and rerun resumes).  Campaigns go to ``--work``.

    python -m tests.independent_rig.start_conditions --out results/verdict_start_conditions
        [--part a|b|ab|c] [--only ID[,ID]] [--limit N] [--jobs N] [--work DIR] [--readme-only] [--redo]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import tempfile
import time
from pathlib import Path

import numpy as np

from . import acceptance as acc
from . import campaign as gen
from .effects import ALL
from .judge import LIBRARY_KIND, judge_place_kind, kept_effects, worded_items
from .rig import BAR
from .sensors import Chain

COMMAND = "python -m tests.independent_rig.start_conditions --out results/verdict_start_conditions"
#: the acceptance: a variant's verdict figure within this share of the faded-in campaign's
AGREE = 0.10
#: a hidden effect "rises above the noise" on a key signal from this many dB (its own contribution's energy over
#: a whole run, in the sensor's noise variance)
VISIBLE_DB = 10.0
#: the bump: on this run, at mid-run, this long, its peak torque this share of the rig's stall torque A Ps r
BUMP_RUN = gen.run_name(1, 35.0, 3.0)
BUMP_WIDTH_S = 0.03
BUMP_STALL_SHARE = 0.02
#: the run cut short and by how much (its last cycle incomplete: 0.45 of a 3 Hz period)
CUT_RUN = gen.run_name(1, 35.0, 3.0)
CUT_SHORT_S = 0.15
#: the phase of the mid-stroke start, rad: the reference starts at A sin(60 deg) = 0.87 A, moving
MID_PHASE_RAD = math.radians(60.0)
#: the variants and their options of :func:`.campaign.simulate` (the bump filled in per rig by :func:`options`)
VARIANTS = ("fade", "rest", "rest_bump", "mid", "rest_cut")
#: the key signals of the effect's measure (the logged transducers; current_mA is the controller's own output)
KEY_SIGNALS = ("theta_deg", "p_a_bar", "p_b_bar", "flow_lpm", "load_kN")
GUESS_A_S = 150.0  # a case's first guess of time for part a, s (6 generations, 5 compares)
GUESS_B_S = 480.0  # and for part b (one diagnosis)


def cases() -> list[dict]:
    """Every hidden class at its strong magnitude on the book rig, then a clean campaign on each rig.

    Returns
    -------
    list of dict
        ``id``, ``effects`` ({name: {param: value}}), ``seed``, ``rig``, ``duration`` (s per run).
    """
    out = [{"id": name, "effects": {name: spec.values(1)}, "seed": 900 + i, "rig": "book", "duration": 3.0}
           for i, (name, spec) in enumerate(ALL.items())]
    out += [{"id": f"clean_{rig}", "effects": {}, "seed": 990 + j, "rig": rig, "duration": 3.0}
            for j, rig in enumerate(("book", "rig_b", "rig_c"))]
    return out


def bump_of(rig: str, duration: float) -> dict:
    """The knock of the ``rest_bump`` variant: a half-sine torque pulse of :data:`BUMP_WIDTH_S` at mid-run on
    :data:`BUMP_RUN`, its peak :data:`BUMP_STALL_SHARE` of the rig's stall torque A Ps r (book rig: 16.8 N m,
    about 10x the sensor noise at its peak on the angle and the pressures: clearly visible, and a knock, not a
    change of the rig)."""
    r, _ = gen.rig_named(rig)
    stall = r.area * r.supply * r.radius
    return {"run": BUMP_RUN, "t_s": round(duration / 2.0, 3), "width_s": BUMP_WIDTH_S,
            "torque_Nm": round(BUMP_STALL_SHARE * stall, 2)}


def options(variant: str, rig: str, duration: float) -> dict:
    """The options of :func:`.campaign.simulate` that make ``variant``.

    Every variant, ``fade`` included, holds the chamber pressures within [0, Ps] inside the integration
    (``exact_bounds``): the starts from rest drive chambers to 0 bar and Ps for about 20 ms, where the generator's
    default (the bounds applied only between its pieces, up to 1 ms apart) is 30-60 bar off the converged
    solution of the documented model (docs/independent-generator.md, "Start conditions")."""
    rest = {"ramp_cycles": 0, "state_ramp": False}
    v = {"fade": {}, "rest": rest, "rest_bump": {**rest, "bump": bump_of(rig, duration)},
         "mid": {"ramp_cycles": 0, "phase_rad": MID_PHASE_RAD, "rest": "start"},
         "rest_cut": {**rest, "cut": {"run": CUT_RUN, "short_s": CUT_SHORT_S}}}[variant]
    return {**v, "exact_bounds": True}


def noise_sigma(signal: str, rig, chain: Chain) -> float:
    """The generator's own noise level of a logged signal (white noise and its converter's step), in its unit."""
    q = 2.0 ** -chain.adc_bits if chain.adc_bits else 0.0
    if signal == "theta_deg":  # position noise and ADC over 2h, seen as an angle at mid-stroke
        return math.degrees(math.hypot(chain.lvdt_noise_m, 2.0 * rig.half_stroke * q / math.sqrt(12.0)) / rig.radius)
    p = math.hypot(chain.pressure_noise_bar, 400.0 * q / math.sqrt(12.0))
    if signal in ("p_a_bar", "p_b_bar"):
        return p
    if signal == "load_kN":  # A (p_a - p_b), two independent transducers
        return rig.area * math.sqrt(2.0) * p * BAR * 1e-3
    if signal == "flow_lpm":
        return math.hypot(chain.flow_noise_lpm, 80.0 * q / math.sqrt(12.0))
    raise KeyError(signal)


def effect_db(with_runs: list, without_runs: list, rig: str, chain: Chain | None = None) -> dict:
    """The hidden effect's own contribution on each run and key signal, dB above the sensor noise.

    The campaign with the effect minus the same campaign without it (same seed, so the same noise draws): its
    mean-square energy over the whole run, in the signal's noise variance (:func:`noise_sigma`), in dB.

    Parameters
    ----------
    with_runs, without_runs : list of (name, columns, sidecar)
        :func:`.campaign.simulate`'s runs, with and without the effect.
    rig : str
        The rig's name (its geometry sets the angle's and the load's noise).
    chain : Chain, optional
        The measurement chain (default: the generator's).

    Returns
    -------
    dict
        ``best_db``, ``best`` ({run, signal}), ``per`` ({run: {signal: dB}}).
    """
    chain = chain or Chain()
    r, _ = gen.rig_named(rig)
    per, best = {}, (-math.inf, None)
    for (name, a, _), (name0, b, _) in zip(with_runs, without_runs):
        assert name == name0, (name, name0)
        for s in KEY_SIGNALS:
            if s not in a or s not in b:
                continue
            d = (np.asarray(a[s], float) - np.asarray(b[s], float)) / noise_sigma(s, r, chain)
            e = float(np.mean(d * d))
            db = 10.0 * math.log10(e) if e > 0 else -math.inf
            per.setdefault(name, {})[s] = round(db, 2) if math.isfinite(db) else None
            if db > best[0]:
                best = (db, {"run": name, "signal": s})
    return {"best_db": round(best[0], 2) if math.isfinite(best[0]) else None, "best": best[1], "per": per}


def _generate(case: dict, variant: str, camp: Path, effects=None) -> tuple:
    """Write ``case``'s campaign in ``variant`` to ``camp`` (kept when its truth.json is this one's); returns
    (runs or None when reused, seconds)."""
    eff = case["effects"] if effects is None else effects
    opts = options(variant, case["rig"], case["duration"])
    key = {"effects": eff, "seed": case["seed"], "rig": case["rig"], "duration_s": case["duration"],
           "variant": variant, "start": json.loads(json.dumps(opts)), "generator_version": gen.VERSION}
    if (camp / "truth.json").exists():
        t = json.loads((camp / "truth.json").read_text())
        if {k: t.get(k) for k in key} == key:
            return None, 0.0
    t0 = time.time()
    runs, truth = gen.simulate(eff, seed=case["seed"], rig=case["rig"], duration=case["duration"], **opts)
    truth["variant"] = variant
    truth["start"] = opts  # the options as given (simulate records the ones that differ from the plan)
    gen.write(camp, runs, truth, overwrite=True)
    return runs, time.time() - t0


def _read_runs(camp: Path) -> list:
    """A written campaign's runs back as (name, columns, sidecar), in the plan's order (the valve chirp last)."""
    truth = json.loads((camp / "truth.json").read_text())
    names = [gen.run_name(*p) for p in truth["plan"]] + ["valve_chirp"]
    out = []
    for n in names:
        p = camp / f"{n}.csv"
        if not p.exists():
            continue
        head = p.read_text().splitlines()[0].split(",")
        data = np.loadtxt(p, delimiter=",", skiprows=1, ndmin=2)
        out.append((n, {c: data[:, k] for k, c in enumerate(head)}, json.loads((camp / f"{n}.json").read_text())))
    return out


#: the models each variant is judged with: the rig's model file as it is (the book's numbers), and the same at the
#: campaign's own beta and K (what a perfect recalibration reaches: truth.json's beta_Pa and K_lpm_per_mA)
MODELS = ("book", "true_bk")


def true_bk_model(camp: Path, rig: str, path: Path) -> Path:
    """Write the rig's model file (docs/model-file.md) with the campaign's own beta and K (its truth.json) to
    ``path``; returns it."""
    truth = json.loads((camp / "truth.json").read_text())
    src = acc.rig_model(rig)
    doc = (json.loads(Path(src).read_text()) if src else
           {"format": "ehas-model", "version": 2, "kind": "plant", "name": "book rig", "rig": {},
            "valve": {"model": "grey_box"}})
    doc["name"] = f"{doc.get('name', rig)} at the campaign's beta and K"
    doc["rig"]["bulk_modulus_Pa"] = truth["beta_Pa"]
    doc["valve"]["K_lpm_per_mA"] = truth["K_lpm_per_mA"]
    doc.pop("provenance", None)
    path.write_text(json.dumps(doc, indent=1) + "\n")
    return path


def compare(camp: Path, rig: str, wdir: Path, tag: str, model: Path | None = None) -> dict:
    """A model's verdict on ``camp``: ``ehas compare CAMP --json F [--model FILE]`` (no fit; default: the rig's
    model file, the book's numbers)."""
    out = wdir / f"compare_{tag}.json"
    model = model or acc.rig_model(rig)
    cmd = [acc.ehas_exe(), "compare", str(camp), "--json", str(out), "--overwrite"] + (
        ["--model", str(model)] if model else [])
    code, stdout, stderr, wall = acc._run(cmd, log=wdir / f"compare_{tag}.log")
    if code != 0 or not out.exists():
        return {"error": f"compare exited {code}: {(stderr or stdout).strip().splitlines()[-1:]}",
                "command": shlex.join(cmd)}
    after = json.loads(out.read_text())["after"]
    return {"residual_x_noise": after["residual_x_noise"], "verdict": after["verdict"], "worst": after.get("worst"),
            "residual_x_sensor_noise": after.get("residual_x_sensor_noise"), "blocks": after.get("blocks") or [],
            "command": shlex.join(cmd), "wall_s": round(wall, 1)}


def part_a(case: dict, work: Path) -> dict:
    """Generate every variant (and, with an effect, the ``rest`` campaign without it), measure each's figure."""
    t0 = time.time()
    wdir = work / case["id"]
    wdir.mkdir(parents=True, exist_ok=True)
    rec = {"variants": {}, "true_bk": {}, "gen_s": {}}
    for v in VARIANTS:
        camp = wdir / v
        _, s = _generate(case, v, camp)
        rec["gen_s"][v] = round(s, 1)
        rec["variants"][v] = {**compare(camp, case["rig"], wdir, v),
                              "options": {k: (round(x, 6) if isinstance(x, float) else x)
                                          for k, x in options(v, case["rig"], case["duration"]).items()}}
        rec["true_bk"][v] = compare(camp, case["rig"], wdir, f"{v}_true_bk",
                                    true_bk_model(camp, case["rig"], wdir / f"model_true_bk_{v}.json"))
    for key in ("variants", "true_bk"):
        side = rec[key]
        base = side["fade"].get("residual_x_noise")
        for v in VARIANTS:
            x = side[v].get("residual_x_noise")
            side[v]["ratio_to_fade"] = round(x / base, 4) if x is not None and base else None
        tag = "" if key == "variants" else "_true_bk"
        rec["agree" + tag] = all(side[v]["ratio_to_fade"] is not None and abs(side[v]["ratio_to_fade"] - 1.0)
                                 <= AGREE for v in VARIANTS)
        rec["agree_bump" + tag] = all(side[v]["ratio_to_fade"] is not None and
                                      abs(side[v]["ratio_to_fade"] - 1.0) <= AGREE for v in ("rest", "rest_bump"))
    if case["effects"]:
        clean = wdir / "rest_without_effect"
        _generate(case, "rest", clean, effects={})
        rec["effect"] = effect_db(_read_runs(wdir / "rest"), _read_runs(clean), case["rig"])
    else:
        rec["effect"] = {"best_db": None, "best": None, "per": {}}
    rec["a_s"] = round(time.time() - t0, 1)
    return rec


def part_b(case: dict, work: Path, out: Path, variant: str = "rest") -> dict:
    """The full diagnosis of the ``variant`` campaign (part b: ``rest``)."""
    t0 = time.time()
    wdir = work / case["id"]
    camp = wdir / variant
    _generate(case, variant, camp)
    diag_json = wdir / f"diag_{variant}.json"
    if diag_json.exists():
        diag_json.unlink()
    model = acc.rig_model(case["rig"])
    cmd = [acc.ehas_exe(), "diagnose", str(camp), "--json", str(diag_json), "--quiet", "--overwrite"] + (
        ["--model", str(model)] if model else [])
    code, stdout, stderr, wall = acc._run(cmd, log=wdir / f"diagnose_{variant}.log")
    rec = {"command": shlex.join(cmd), "wall_s": round(wall, 1)}
    if code != 0 or not diag_json.exists():
        rec["error"] = f"diagnose exited {code}: {(stderr or stdout).strip().splitlines()[-1:]}"
        return rec
    diag = json.loads(diag_json.read_text())
    (out / "diag").mkdir(exist_ok=True)
    name = case["id"] if variant == "rest" else f"{case['id']}.{variant}"
    (out / "diag" / f"{name}.json").write_text(json.dumps(diag, indent=1) + "\n")
    items = worded_items(diag)
    rec.update({"verdict": diag.get("verdict"), "residual_x_noise": diag.get("residual_x_noise"),
                "kept": kept_effects(diag), "named": [i["label"] for i in items],
                "added_nothing": not items and not kept_effects(diag),
                # what the logs cannot part from what was kept: the alternatives stage's, and the blocks within
                # reach of each state kept (the states stage's ``within``)
                "alternatives": [a.get("effect") or a.get("name") or a.get("label")
                                 for a in diag.get("alternatives") or [] if isinstance(a, dict)]
                + [w.get("effect") for st in diag.get("states") or [] if isinstance(st, dict)
                   for w in st.get("within") or [] if isinstance(w, dict)],
                "elapsed_s": diag.get("elapsed_s"), "b_s": round(time.time() - t0, 1),
                "generator_version": json.loads((camp / "truth.json").read_text()).get("generator_version", 1)})
    return rec


#: part c: the variants whose diagnoses are compared (the acceptance's: with a fade-in, without, with a bump)
DIAGNOSED = ("fade", "rest", "rest_bump")


def part_c(case: dict, work: Path, out: Path) -> dict:
    """The full diagnosis of each of :data:`DIAGNOSED` at one commit, and whether their figures agree: each
    variant's diagnosed figure within :data:`AGREE` of the ``fade`` one's, and the same verdict words."""
    rec = {v: part_b(case, work, out, v) for v in DIAGNOSED}
    base = rec["fade"].get("residual_x_noise")
    for v in DIAGNOSED:
        x = rec[v].get("residual_x_noise")
        rec[v]["ratio_to_fade"] = round(x / base, 4) if x is not None and base else None
    rec["agree"] = all(rec[v]["ratio_to_fade"] is not None and abs(rec[v]["ratio_to_fade"] - 1.0) <= AGREE
                       for v in DIAGNOSED)
    rec["same_verdict"] = len({rec[v].get("verdict") for v in DIAGNOSED}) == 1
    return rec


def _side(recs: list[dict], key: str) -> dict:
    """Part a's figures of one model (``variants``: the book's; ``true_bk``: at the campaign's beta and K)."""
    a = [r for r in recs if key in (r.get("a") or {})]
    tag = "" if key == "variants" else "_true_bk"

    def ratio(r, v):
        return r["a"][key][v].get("ratio_to_fade")

    worst = {v: max((abs(ratio(r, v) - 1.0) for r in a if ratio(r, v) is not None), default=None)
             for v in VARIANTS[1:]}
    near = [r for r in a if (r["a"][key]["fade"].get("residual_x_noise") or 1e9) <= NEAR_X]
    return {"cases": len(a),
            "near_cases": [r["id"] for r in near],
            "near_agree_all_variants": sum(1 for r in near if r["a"]["agree" + tag]),
            "near_disagree": {v: [r["id"] for r in near if ratio(r, v) is None or abs(ratio(r, v) - 1.0) > AGREE]
                              for v in VARIANTS[1:]},
            "rose": {v: sum(1 for r in a if (ratio(r, v) or 1.0) > 1.0 + AGREE) for v in VARIANTS[1:]},
            "fell": {v: sum(1 for r in a if (ratio(r, v) or 1.0) < 1.0 - AGREE) for v in VARIANTS[1:]},
            "agree_all_variants": sum(1 for r in a if r["a"]["agree" + tag]),
            "agree_fade_rest_bump": sum(1 for r in a if r["a"]["agree_bump" + tag]),
            "disagree": {v: [r["id"] for r in a if ratio(r, v) is None or abs(ratio(r, v) - 1.0) > AGREE]
                         for v in VARIANTS[1:]},
            "largest_relative_difference": {v: (round(x, 4) if x is not None else None) for v, x in worst.items()},
            "verdict_changed": {v: [r["id"] for r in a if r["a"][key][v].get("verdict")
                                    != r["a"][key]["fade"].get("verdict")] for v in VARIANTS[1:]},
            "clean_unexplained": {v: [r["id"] for r in a if not r["effects"]
                                      and r["a"][key][v].get("verdict") == "unexplained"] for v in VARIANTS},
            "floor_far_above_residual": {v: [r["id"] for r in a if floor_above(r["a"][key][v].get("blocks") or [])]
                                         for v in VARIANTS},
            "floor_10x_noise": {v: [r["id"] for r in a if floor_big(r["a"][key][v].get("blocks") or [])]
                                for v in VARIANTS}}


#: a floor this many times the sensor noise's variance counts a deterministic response: the generator's campaigns
#: hold nothing that does not repeat but white sensor noise and its converters (and the knock of ``rest_bump``,
#: about 3x on its run), so a larger floor is the rig's own response that changes from cycle to cycle (a start's
#: settling, a subharmonic) -- what the issue says a floor must never count
FLOOR_BIG = 10.0


def floor_big(blocks: list[dict]) -> list[dict]:
    """The blocks whose floor is above :data:`FLOOR_BIG` sensor-noise variances."""
    return [b for b in blocks if (b.get("floor_x_sensor_noise") or 0.0) > FLOOR_BIG]


#: campaigns whose faded-in figure is at most this (the verdict's "unexplained" threshold, 1 + UNEXPLAINED_X of
#: ehas_env/measurement/verdict.py) are the ones a 10 % change can move across a verdict
NEAR_X = 4.0


#: a block whose residual is below this share of its floor has a floor "far above the residual it judges" (issue 42,
#: point 1: a residual cannot be far below the noise it contains)
FLOOR_ABOVE = 2.0 / 3.0


def floor_above(blocks: list[dict]) -> list[dict]:
    """The blocks whose floor is far above their residual (residual_x_noise below :data:`FLOOR_ABOVE`)."""
    return [b for b in blocks if b.get("residual_x_noise") is not None and b["residual_x_noise"] < FLOOR_ABOVE]


def changed_blocks(fade: list[dict], other: list[dict], k: int = 3) -> list[tuple]:
    """The ``k`` blocks whose figure (each counted at least 1, as the overall figure counts it) moved most between
    two variants: (fade block, other block), largest |log| change first."""
    by = {(b["run"], b["signal"]): b for b in fade}
    pairs = [(by[(b["run"], b["signal"])], b) for b in other if (b["run"], b["signal"]) in by]
    pairs.sort(key=lambda fb: -abs(math.log(max(fb[1]["residual_x_noise"], 1.0))
                                   - math.log(max(fb[0]["residual_x_noise"], 1.0))))
    return pairs[:k]


def stand_in(rec: dict, variant: str, diag: dict | None) -> dict | None:
    """A campaign called explained by something other than its hidden effect's kind: does the diagnosis list the
    truth's kind among the alternatives the logs cannot part from what it kept (the issue's "a stand-in that
    explains one lists the truth's kind among its alternatives")?  None when the diagnosis is not explained, the
    campaign is clean, or what it named is of the truth's kind (:func:`.judge.judge_place_kind`).

    Returns
    -------
    dict or None
        ``named`` (the labels), ``missed`` (the hidden effects no named item is of the kind of), ``listed`` (bool:
        every missed one's kind among the alternatives' kinds), ``alternatives``.
    """
    if not diag or not rec["effects"] or diag.get("verdict") != "explained":
        return None
    j = judge_place_kind(rec["effects"], worded_items(diag))
    missed = [n for n, v in j["per_effect"].items() if not v["right_kind"]]
    if not missed:
        return None
    alts = (rec.get("c") or {}).get(variant, {}).get("alternatives") or (rec.get("b") or {}).get("alternatives") or []
    kinds = set().union(*(LIBRARY_KIND.get(a, set()) for a in alts if a)) if alts else set()
    return {"named": [it["label"] for it in j["items"]], "missed": missed, "alternatives": alts,
            "listed": all(set(ALL[n].accepted_kinds) & kinds for n in missed)}


def _diag(out: Path | None, cid: str, variant: str) -> dict | None:
    """A case's stored diagnosis of one variant (``OUT/diag``), None when absent."""
    if out is None:
        return None
    p = out / "diag" / (f"{cid}.json" if variant == "rest" else f"{cid}.{variant}.json")
    return json.loads(p.read_text()) if p.exists() else None


def recommended_figure(diag: dict | None):
    """The figure of the model a diagnosis recommends: with the term it proposes, where it proposes one, that model's
    all-data residual (``unexplained.proposal.validation.residual_x_noise_all_after``, the refit in the full model
    its ``next:`` reproduces; the drawn set's judge counts the same model as the final one), else its own
    ``residual_x_noise``; None without a diagnosis.

    >>> recommended_figure({"residual_x_noise": 6.2, "unexplained": {"proposal": {"validation":
    ...     {"residual_x_noise_all_after": 1.01}}}})
    1.01
    >>> recommended_figure({"residual_x_noise": 1.02, "unexplained": None})
    1.02
    """
    if not isinstance(diag, dict):
        return None
    un = diag.get("unexplained")
    prop = un.get("proposal") if isinstance(un, dict) else None
    after = ((prop or {}).get("validation") or {}).get("residual_x_noise_all_after") if isinstance(prop, dict) else None
    return after if isinstance(after, (int, float)) else diag.get("residual_x_noise")


def _agree_recommended(r: dict, out: Path | None) -> bool | None:
    """Whether the recommended models' figures (:func:`recommended_figure`) of part c's variants agree within
    :data:`AGREE` of the ``fade`` one's; None when a stored diagnosis is missing."""
    figs = {v: recommended_figure(_diag(out, r["id"], v)) for v in DIAGNOSED}
    if any(x is None for x in figs.values()) or not figs["fade"]:
        return None
    return all(abs(figs[v] / figs["fade"] - 1.0) <= AGREE for v in DIAGNOSED)


def summarise(recs: list[dict], out: Path | None = None) -> dict:
    """The figures against the issue's acceptance over the cases here (``out``: the folder whose ``diag/`` holds
    the stored diagnoses the stand-in judgement reads, :func:`stand_in`)."""
    b = [r for r in recs if "b" in r and "error" not in r["b"]]
    visible = [r for r in b if r["effects"] and (((r.get("a") or {}).get("effect") or {}).get("best_db") or -1e9)
               >= VISIBLE_DB]
    s = {"cases": len(recs), "book": _side(recs, "variants"), "true_bk": _side(recs, "true_bk"),
         "part_b": len(b), "part_b_errors": sum(1 for r in recs if "b" in r and "error" in r["b"]),
         "visible_effects_diagnosed": len(visible),
         "visible_explained_nothing_added": [r["id"] for r in visible
                                             if r["b"]["verdict"] == "explained" and r["b"]["added_nothing"]],
         "clean_diagnosed": sum(1 for r in b if not r["effects"]),
         "clean_unexplained": [r["id"] for r in b if not r["effects"] and r["b"]["verdict"] == "unexplained"]}
    c = [r for r in recs if "c" in r and all("error" not in r["c"][v] for v in DIAGNOSED)]
    s["part_c"] = {"cases": len(c), "agree": sum(1 for r in c if r["c"]["agree"]),
                   "same_verdict": sum(1 for r in c if r["c"]["same_verdict"]),
                   "beyond": [r["id"] for r in c if not r["c"]["agree"]],
                   # the same with the model each recommends (its proposed term in, where it proposes one)
                   "agree_recommended": sum(1 for r in c if _agree_recommended(r, out)),
                   "beyond_recommended": [r["id"] for r in c if _agree_recommended(r, out) is False],
                   "verdict_changed": [r["id"] for r in c if not r["c"]["same_verdict"]],
                   "visible_explained_nothing_added": sorted(
                       f"{r['id']} ({v})" for r in c for v in DIAGNOSED
                       if r["effects"] and (((r.get("a") or {}).get("effect") or {}).get("best_db") or -1e9)
                       >= VISIBLE_DB and r["c"][v].get("verdict") == "explained" and r["c"][v].get("added_nothing")),
                   "clean_unexplained": sorted(f"{r['id']} ({v})" for r in c for v in DIAGNOSED
                                               if not r["effects"] and r["c"][v].get("verdict") == "unexplained"),
                   "commits": sorted({r["c"].get("ehas_commit") for r in c if r["c"].get("ehas_commit")}),
                   "stand_ins": {f"{r['id']} ({v})": si for r in c for v in DIAGNOSED
                                 if (si := stand_in(r, v, _diag(out, r["id"], v))) is not None},
                   # campaigns of the generator's current version (stroke ends met at their instant) in all three
                   "current_generator": [r["id"] for r in c if all(r["c"][v].get("generator_version", 1)
                                                                   == gen.VERSION for v in DIAGNOSED)]}
    s["meets"] = {"agree_within_10pct_book": bool(s["book"]["cases"])
                  and s["book"]["agree_all_variants"] == s["book"]["cases"],
                  "agree_within_10pct_true_bk": bool(s["true_bk"]["cases"])
                  and s["true_bk"]["agree_all_variants"] == s["true_bk"]["cases"],
                  "visible_explained_nothing_added_0": not s["visible_explained_nothing_added"],
                  "clean_unexplained_0": not s["clean_unexplained"]}
    return s


def _f(x, nd=3):
    return "-" if x is None else (("yes" if x else "no") if isinstance(x, bool) else
                                  f"{x:.{nd}g}" if isinstance(x, (int, float)) else str(x))


def readme(recs: list[dict], summ: dict, command: str) -> str:
    """The README of OUT: what, how judged, the summary, every case."""
    full = cases()
    have = {r["id"] for r in recs}
    nb = sum(1 for r in recs if "b" in r)
    L = ["# The verdict on campaigns as rigs record them (issue 42, point 3)", "",
         f"Regenerate (resumable; finished cases in `cases/` are kept): `{command}` (part a and b; "
         "`--part a` for the figures alone; `--part c` for the diagnoses of `fade`, `rest` and `rest_bump`).", "",
         "## What", "",
         "Campaigns of the independent generator (`tests/independent_rig/`, plain NumPy/SciPy sharing no code with "
         "the package; `docs/independent-generator.md`, \"Start conditions\"): every hidden class of the generator "
         f"({len(ALL)}: out of library, library, the backlash check and the unlisted classes) at its strong "
         "magnitude on the book rig, and a clean campaign on each of the three rigs (4 closed-loop sine runs and "
         "the valve chirp, 3 s each). Each campaign is generated in five variants, the same seed (the same noise "
         "draws, beta and K) otherwise:", "",
         "| variant | what the rig did |", "|---|---|",
         "| `fade` | every closed-loop run faded in over one period (ehas's own plan; the reference) |",
         "| `rest` | started from rest without a fade-in; the sidecars leave `ramp_cycles` out (the format's "
         "default 0) |",
         f"| `rest_bump` | `rest`, and a knock on `{BUMP_RUN}`'s crank at mid-run: a half-sine torque pulse of "
         f"{BUMP_WIDTH_S * 1e3:g} ms, its peak {100 * BUMP_STALL_SHARE:g} % of the rig's stall torque A Ps r (book: "
         f"{bump_of('book', 3.0)['torque_Nm']:g} N m, about 10x the sensor noise at its peak on the angle and the "
         "pressures) |",
         f"| `mid` | without a fade-in, the reference starting mid-stroke at A sin({math.degrees(MID_PHASE_RAD):g} deg), "
         "moving, with the rig at rest there (the operator jogged it there); `ramp_cycles` 0 stated |",
         f"| `rest_cut` | `rest`, with `{CUT_RUN}`'s log ending {CUT_SHORT_S:g} s early (its last cycle "
         "incomplete) |", "",
         "## How it is judged", "",
         "* (a) The verdict figure of the book model (the rig's model file, no fit) on each variant: `ehas compare "
         "CAMP --json F`, `after.residual_x_noise` and `after.verdict`. The acceptance: every variant's figure "
         f"within {100 * AGREE:g} % of the `fade` one.",
         "* (b) The full diagnosis of the `rest` variant (the start-from-rest campaign of the issue): `ehas diagnose "
         "CAMP --json F`; its verdict, figure and what it added to the book model (kept library effects, hypotheses, "
         "states, named terms, disturbances: `judge.worded_items`). The acceptance: 0 campaigns whose hidden effect "
         f"rises >= {VISIBLE_DB:g} dB above the noise on a key signal called explained with nothing added; 0 clean "
         "campaigns called unexplained.",
         "* The effect's own measure (the generator's terms, `start_conditions.effect_db`): the `rest` campaign with "
         "the effect minus the same campaign without it (same seed, same noise draws), its mean-square energy over "
         "each whole run in the signal's sensor-noise variance (the generator's chain: 9 um LVDT, 0.25 bar, 0.06 "
         "LPM, their 16-bit converters; the load as A (p_a - p_b)), in dB; the best run and key signal (angle, "
         "pressures, flow, load) counts.", "",
         f"Cases here: {len(have)} of {len(full)} in part a, {nb} in part b"
         + (f"; not yet run (a): {', '.join(c['id'] for c in full if c['id'] not in have)}"
            if len(have) < len(full) else "") + ". " + _commits(recs), "",
         "## Summary against the issue's thresholds", ""]
    for key, words in (("book", "the rig's model file as it is (the book's beta and K)"),
                       ("true_bk", "the rig's model at the campaign's own beta and K (a perfect recalibration)")):
        m = summ[key]
        L += [f"(a), {words}:", "",
              f"* Figure within {100 * AGREE:g} % of the faded-in campaign's in every variant: "
              f"{m['agree_all_variants']}/{m['cases']}; in `rest` and `rest_bump` (the acceptance's two): "
              f"{m['agree_fade_rest_bump']}/{m['cases']}.",
              f"* Of the {len(m['near_cases'])} campaigns whose `fade` figure is at most {NEAR_X:g} (where 10 % can "
              f"move a verdict): within 10 % in every variant {m['near_agree_all_variants']}; beyond: " + "; ".join(
                  f"`{v}`: {', '.join(ids) or 'none'}" for v, ids in m["near_disagree"].items()) + ".",
              "* Figures that rose (more evidence in the start) / fell by more than 10 %: " + ", ".join(
                  f"`{v}` {m['rose'][v]}/{m['fell'][v]}" for v in VARIANTS[1:]) + ".",
              "* Largest relative difference from `fade`: " + ", ".join(
                  f"`{v}` {_pct(x)}" for v, x in m["largest_relative_difference"].items()) + ".",
              "* Campaigns beyond 10 %: " + "; ".join(f"`{v}`: {', '.join(ids) or 'none'}"
                                                     for v, ids in m["disagree"].items()) + ".",
              "* Verdict words that changed from `fade`: " + "; ".join(
                  f"`{v}`: {', '.join(ids) or 'none'}" for v, ids in m["verdict_changed"].items()) + ".",
              "* Clean campaigns `compare` calls unexplained: " + "; ".join(
                  f"`{v}`: {len(ids)}" for v, ids in m["clean_unexplained"].items()) + ".",
              f"* Campaigns with a block whose floor is far above its residual (residual below "
              f"{FLOOR_ABOVE:.2f} floors; the block then counts as 1): " + "; ".join(
                  f"`{v}`: {len(ids)}" for v, ids in m["floor_far_above_residual"].items()) + ".",
              f"* Campaigns with a block whose floor is above {FLOOR_BIG:g}x the sensor noise's variance (in this "
              "generator nothing but the sensor chain and the knock fails to repeat: such a floor counts the rig's own "
              "response): " + "; ".join(f"`{v}`: {len(ids)}" for v, ids in m["floor_10x_noise"].items()) + ".", ""]
    L += [f"(b) Diagnosed (`rest`): {summ['part_b']} ({summ['part_b_errors']} failed to run); with the hidden "
          f"effect >= {VISIBLE_DB:g} dB above the noise: {summ['visible_effects_diagnosed']}; of those called "
          f"explained with nothing added to the book model: {len(summ['visible_explained_nothing_added'])} "
          f"({', '.join(summ['visible_explained_nothing_added']) or 'none'}; threshold 0). Clean campaigns "
          f"diagnosed: {summ['clean_diagnosed']}; called unexplained: {len(summ['clean_unexplained'])} "
          "(threshold 0).", ""]
    pc = summ.get("part_c") or {}
    if pc.get("cases"):
        L += [f"(c) Diagnosed with a fade-in, from rest and from rest with the knock (`fade`, `rest`, `rest_bump`, "
              f"at {', '.join(pc['commits'])}; `--part c`): {pc['cases']} campaigns. The final figure of `rest` and "
              f"`rest_bump` within {100 * AGREE:g} % of `fade`'s: {pc['agree']}/{pc['cases']} (beyond: "
              f"{', '.join(pc['beyond']) or 'none'}); the figure of the model each recommends (with the term it "
              f"proposes, where it proposes one: `unexplained.proposal.validation.residual_x_noise_all_after`, the "
              f"model its `next:` reproduces and the drawn set's judge counts as final) within {100 * AGREE:g} %: "
              f"{pc.get('agree_recommended', '?')}/{pc['cases']} (beyond: "
              f"{', '.join(pc.get('beyond_recommended') or []) or 'none'}); the same verdict words in all three: "
              f"{pc['same_verdict']}/{pc['cases']} (changed: {', '.join(pc['verdict_changed']) or 'none'}). Visible "
              f"effects called explained with nothing added: {', '.join(pc['visible_explained_nothing_added']) or 'none'}"
              f"; clean campaigns called unexplained: {', '.join(pc['clean_unexplained']) or 'none'}. Generated by the "
              f"generator's version {gen.VERSION} (a stroke end met at its instant) in all three: "
              f"{len(pc.get('current_generator') or [])}/{pc['cases']}; the others (marked v1) by version 1, whose "
              "piston stopped at the next piece's boundary, up to 1 ms after the impact: the starts from rest that "
              "overshoot into a stroke end carry that error in their `rest` figures "
              "(docs/independent-generator.md, \"Start conditions\").", ""]
        si = pc.get("stand_ins") or {}
        L += [f"Called explained by a stand-in (what was named is not of the hidden effect's kind, "
              f"`start_conditions.stand_in`): {len(si)} diagnoses; the truth's kind listed among the alternatives the "
              f"logs cannot part from it: {sum(1 for x in si.values() if x['listed'])}/{len(si)}"
              + ("" if not si else " (" + "; ".join(
                  f"{k}: {', '.join(x['named'])} for {', '.join(x['missed'])}, "
                  + ("listed" if x["listed"] else "not listed: " + (", ".join(x["alternatives"]) or "no alternatives"))
                  for k, x in si.items()) + ")") + ".", "",
              "| case | fade: verdict, figure | rest | rest_bump | within 10 % | added (fade / rest / rest_bump) |",
              "|---|---|---|---|---|---|"]
        for r in recs:
            cc = r.get("c")
            if not cc:
                continue
            cell = {v: (f"{(cc.get(v) or {}).get('verdict', (cc.get(v) or {}).get('error'))} "
                        f"{_f((cc.get(v) or {}).get('residual_x_noise'))}"
                        + (f" ({_f(cc[v].get('ratio_to_fade'))})" if v != "fade" and cc[v].get("ratio_to_fade") else ""))
                    for v in DIAGNOSED}
            added = " / ".join(", ".join((cc.get(v) or {}).get("named") or (cc.get(v) or {}).get("kept") or ["-"])
                               for v in DIAGNOSED)
            v1 = "" if r["id"] in (pc.get("current_generator") or []) else " (v1)"
            L.append(f"| {r['id']}{v1} | {cell['fade']} | {cell['rest']} | {cell['rest_bump']} | {_f(cc.get('agree'))} "
                     f"| {added} |")
        L.append("")
    L += ["## Every campaign", "",
          "Each cell: `residual_x_noise` (x what does not repeat) of the book model / of the model at the "
          "campaign's beta and K, each with its verdict (e explained, s small structured residual, u unexplained) "
          "and, beside `fade`, its ratio to the `fade` figure. Effect dB: the hidden effect's own contribution on "
          "its best run and key signal.", "",
          "| case | rig | hidden | effect dB (where) | fade | rest | rest_bump | mid | rest_cut | within 10 % "
          "(book, true) | diagnosis of rest: verdict, figure | added to the book model | s (a, b) |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        hidden = "; ".join(f"{n}: " + ", ".join(f"{k}={v:g} {_unit(n, k)}" for k, v in p.items())
                           for n, p in r["effects"].items()) or "none"
        a = r.get("a") or {}
        e = a.get("effect") or {}
        where = f" ({e['best']['run']} {e['best']['signal']})" if e.get("best") else ""
        cells = []
        for v in VARIANTS:
            parts = []
            for key in ("variants", "true_bk"):
                x = (a.get(key) or {}).get(v) or {}
                parts.append("error" if "error" in x else
                             f"{_f(x.get('residual_x_noise'))} {(x.get('verdict') or '?')[0]}"
                             + (f" ({x['ratio_to_fade']:.2f})" if v != "fade" and x.get("ratio_to_fade") else ""))
            cells.append(" / ".join(parts))
        b = r.get("b") or {}
        diag = ("-" if not b else f"error: {b['error']}" if "error" in b else
                f"{b['verdict']} {_f(b['residual_x_noise'])}")
        added = "-" if not b or "error" in b else ("nothing" if b["added_nothing"] else
                                                   ", ".join(b["named"] or b["kept"]).replace("|", "/"))
        L.append(f"| {r['id']} | {r['rig']} | {hidden} | {_f(e.get('best_db'))}{where} | " + " | ".join(cells)
                 + f" | {_f(a.get('agree'))}, {_f(a.get('agree_true_bk'))} | {diag} | {added} "
                 f"| {_f(a.get('a_s'), 4)}, {_f(b.get('b_s'), 4)} |")
    L += [""] + findings(recs)
    L += ["", "## Where a variant's figure moved (book model, beyond 10 %)", "",
          "The three blocks whose figure (counted at least 1) moved most from `fade`: residual_x_noise, the floor "
          "in sensor-noise variances and the stretch that set it (s; `-`: the sensor noise).", "",
          "| case | variant | run | signal | fade: x (floor, stretch) | variant: x (floor, stretch) |",
          "|---|---|---|---|---|---|"]
    for r in recs:
        side = (r.get("a") or {}).get("variants") or {}
        for v in VARIANTS[1:]:
            x = side.get(v) or {}
            if x.get("ratio_to_fade") is None or abs(x["ratio_to_fade"] - 1.0) <= AGREE:
                continue
            for f, o in changed_blocks(side["fade"].get("blocks") or [], x.get("blocks") or []):
                L.append(f"| {r['id']} | {v} | {o['run']} | {o['signal']} | {_blk(f)} | {_blk(o)} |")
    L += ["", "Per-block numbers (`after.blocks` of each compare: run, signal, residual_x_noise, "
          "floor_x_sensor_noise, floor_from_s, floor_to_s) are in `cases/ID.json`, `a.variants.VARIANT.blocks` "
          "(book model) and `a.true_bk.VARIANT.blocks`.", ""]
    return "\n".join(L) + "\n"


def _block(rec: dict, side: str, variant: str, run: str, signal: str) -> dict | None:
    for b in (((rec.get("a") or {}).get(side) or {}).get(variant) or {}).get("blocks") or []:
        if b["run"] == run and b["signal"] == signal:
            return b
    return None


def findings(recs: list[dict]) -> list[str]:
    """What the figures show, with the numbers of the cases here (the causes of the differences)."""
    a = [r for r in recs if "a" in r]
    L = ["## What the differences come from", ""]
    clean = [r for r in a if not r["effects"]]
    if clean:
        L.append("* **The start stretch shows beta and K.** Clean campaigns, book model / model at the campaign's own "
                 "beta and K, `fade` -> `rest`: " + "; ".join(
                     f"{r['id']} {_f(r['a']['variants']['fade'].get('residual_x_noise'))} -> "
                     f"{_f(r['a']['variants']['rest'].get('residual_x_noise'))} / "
                     f"{_f(r['a']['true_bk']['fade'].get('residual_x_noise'))} -> "
                     f"{_f(r['a']['true_bk']['rest'].get('residual_x_noise'))}" for r in clean)
                 + ". A start from rest without a fade-in drives chambers to 0 bar and Ps (book rig, 5 sets, "
                 "+-30 deg at 2 Hz: A at 0 bar from 74 to 95 ms, B at Ps from 71 to 165 ms), where the response "
                 "hangs on beta: the rig's beta a few % off the model file's is a residual of tens of noise "
                 "variances there, none with a fade-in. The fit (`ehas diagnose`, part b) recalibrates beta and K.")
    b = _block(next((r for r in clean if r["id"] == "clean_book"), {}), "true_bk", "rest", gen.run_name(5, 30.0, 2.0),
               "p_a_bar")
    L.append("* **The reference model's own step at the bounds.** Even at the campaign's beta and K the clean "
             "book campaign from rest keeps a residual on the run that reaches the bounds"
             + (f" (cl_5sets_30deg_2hz p_a_bar {b['residual_x_noise']:.3g} floors)" if b else "")
             + ": ehas's reference model at its 10 RK4 sub-steps per period is 4.4 bar (A), 7.2 bar (B) and 0.14 "
             "deg off its own converged solution (160 sub-steps) there, 20-30x the pressure noise, and the "
             "generator with `exact_bounds` is within 0.24 and 0.39 bar of that converged solution "
             "(`test_exact_bounds_meet_the_reference_model_where_a_start_from_rest_reaches_them`; "
             "docs/independent-generator.md). This is ehas_env's integrator (a projection after each 0.1 ms step "
             "onto [0, Ps]), not the verdict.")
    big = [(r["id"], b) for r in a for b in floor_big((r["a"]["true_bk"].get("rest") or {}).get("blocks") or [])]
    if big:
        worst = sorted(big, key=lambda ib: -ib[1]["floor_x_sensor_noise"])[:6]
        L.append(f"* **The floor counts the rig's own response.** In `rest` (model at the campaign's beta and K) "
                 f"{len(big)} blocks of {len({i for i, _ in big})} campaigns have a floor above {FLOOR_BIG:g}x the "
                 "sensor noise, in `fade` " + str(sum(len(floor_big((r["a"]["true_bk"].get("fade") or {})
                                                                      .get("blocks") or [])) for r in a))
                 + " blocks; the largest: " + "; ".join(
                     f"{i} {bl['run']} {bl['signal']} floor {bl['floor_x_sensor_noise']:.4g} ({bl['floor_from_s']:g}-"
                     f"{bl['floor_to_s']:g} s), residual {bl['residual_x_noise']:.3g} floors" for i, bl in worst)
                 + ". Nothing in these campaigns fails to repeat but white sensor noise: such a floor is a "
                 "deterministic response the model misses and that changes from cycle to cycle, which the "
                 "cycle-to-cycle change counts as floor, so the block counts about 1. Two kinds seen at "
                 "191828e (book model, `rest`): a settling the start excites that lasts beyond the one settling "
                 "cycle (`current_lag` T = 6 ms, cl_5sets_30deg_2hz: the residual per cycle 369747, 255855, "
                 "153551, 102063, 60439, 41994 noise variances, the correlation of each cycle with the next "
                 "+0.86 to -0.85; floor 139860 from 0.5 s, block 1.17 floors; with the fade-in the same run is "
                 "49 floors on a floor of 47), and a subharmonic (`single_rod` alpha 0.75, cl_7sets_10deg_3hz: "
                 "each cycle correlates -0.84 with the next, the measured cycle means alternate 0.19/-0.20 deg and "
                 "103/89 bar; floor 100379 (theta) to 169803 (p_a) sensor-noise variances, the residual 0.45-0.54 "
                 "of it). At 191828e the floor was max(change, noise), never capped by the residual; since "
                 "2026-11-29 it is at most the residual's own mean square over the stretch that sets it "
                 "(ehas_env/measurement/verdict.py, `residual_floor`), and since 2026-11-30 a subharmonic is "
                 "judged, not floor (the floor from the change over two periods where it is 4x below the change "
                 "over one). A "
                 "settling that keeps its shape while it "
                 "falls cycle after cycle to the run's end has had no floor since 2026-11-29 (the sensor noise "
                 "is its floor: `verdict._still_settling`); of the book-model figures of part (a) it moved only "
                 "load_compliance's without a fade-in (`rest` 46.7 -> 81.7); a settling that changes its "
                 "shape from cycle to cycle is still counted (up to the residual's mean square). Since 2026-11-30 a closed-loop run whose loop "
                 "does not repeat at all (its position reading changes by more than 5 % of its swing from one "
                 "cycle to the next, `verdict.REPEAT_SHARE`: an instability, an "
                 "oscillation of its own) is never floor: capped where the model's loop repeats, judged on its "
                 "cycle envelope where the model's does not either (`verdict.loop_repeats`, "
                 "`verdict.envelope_block`; docs/measurement-format.md, \"The verdict\"). Part (a) cases that "
                 "ran before that rule (their commits above) keep the floor they had.")
    knocked = []
    for r in a:
        x0 = _block(r, "true_bk", "rest", BUMP_RUN, "theta_deg")
        x1 = _block(r, "true_bk", "rest_bump", BUMP_RUN, "theta_deg")
        if x0 and x1:
            knocked.append((r["id"], x0, x1))
    if knocked:
        ratios = sorted(k[2]["floor_x_sensor_noise"] / k[1]["floor_x_sensor_noise"] for k in knocked)
        worst = max(knocked, key=lambda k: k[1]["residual_x_noise"] / max(k[2]["residual_x_noise"], 1e-9))
        L.append(f"* **A knock raises its run's floor for the whole run.** The {BUMP_WIDTH_S * 1e3:g} ms knock on "
                 f"{BUMP_RUN} raises that run's angle floor by a median factor {ratios[len(ratios) // 2]:.3g} (range "
                 f"{ratios[0]:.3g}-{ratios[-1]:.3g}) over {len(knocked)} campaigns: its cycle-to-cycle change "
                 "counts it twice over the shorter floor stretch (from one period on), against once in the residual "
                 "over the whole run, and it is spread over the run's 3 s. A structured residual elsewhere in the "
                 f"run is then divided by it: {worst[0]}: {worst[1]['residual_x_noise']:.3g} -> "
                 f"{worst[2]['residual_x_noise']:.3g} floors (floor {worst[1]['floor_x_sensor_noise']:.4g} -> "
                 f"{worst[2]['floor_x_sensor_noise']:.4g}).")
    slow = gen.run_name(3, 20.0, 1.0)
    L.append(f"* **Which runs have their own floor.** {slow} (1 Hz, 3 s) faded in has one cycle after the fade-in "
             "and the settling cycle: fewer than 2, so the sensor noise is its floor; from rest it has two (1-3 s), "
             "its own floor.")
    for side, words in (("variants", "book model"), ("true_bk", "model at the campaign's beta and K")):
        rel = [(abs(r["a"][side]["rest_cut"]["residual_x_noise"] / r["a"][side]["rest"]["residual_x_noise"] - 1.0),
                r["id"]) for r in a if r["a"][side]["rest_cut"].get("residual_x_noise")
               and r["a"][side]["rest"].get("residual_x_noise")]
        if rel:
            m = max(rel)
            L.append(f"* **A run cut short** (`rest_cut` against `rest`, which differ only in {CUT_RUN}'s last "
                     f"{CUT_SHORT_S:g} s), {words}: within 10 % in {sum(1 for x, _ in rel if x <= AGREE)}/{len(rel)}; "
                     f"largest difference {100 * m[0]:.1f} % ({m[1]}).")
    return L


def _blk(b: dict) -> str:
    stretch = "-" if b.get("floor_from_s") is None else f"{b['floor_from_s']:g}-{b['floor_to_s']:g}"
    return f"{b['residual_x_noise']:.3g} ({b['floor_x_sensor_noise']:.4g}, {stretch})"


def _commits(recs: list[dict]) -> str:
    cs = sorted({r.get("ehas_commit") for r in recs if r.get("ehas_commit")} |
                {(r.get("b") or {}).get("ehas_commit") for r in recs if (r.get("b") or {}).get("ehas_commit")})
    text = f"The cases ran at commit{'s' if len(cs) > 1 else ''} {', '.join(cs) or '?'} of this repository"
    if len(cs) > 1:  # other work was committed meanwhile: say whether what makes the figures changed between them
        import subprocess

        same = all(subprocess.run(["git", "-C", str(acc.ROOT), "diff", "--quiet", cs[0], c, "--", *FIGURE_CODE],
                                  capture_output=True).returncode == 0 for c in cs[1:])
        what = ", ".join(c for c in FIGURE_CODE if not c.startswith(":")) + " (c_source.py, the exports' C, aside)"
        text += f"; {what} are the same at all of them" if same else f"; {what} differ between them"
    return text + "."


#: the code that makes the figures and the diagnosis (the README says whether it changed between the cases' commits)
FIGURE_CODE = ("ehas_env/measurement/verdict.py", "ehas_env/measurement/replay.py",
               "ehas_env/diagnosis/candidates.py", "ehas_env/diagnosis/fitting.py", "ehas_env/diagnosis/keeping.py",
               "ehas_env/physics",
               ":(exclude)ehas_env/physics/c_source.py")


def _pct(x):
    return "-" if x is None else f"{100 * x:.1f} %"


def _unit(name: str, param: str) -> str:
    return next((p.unit for p in ALL[name].params if p.name == param), "")


def _atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="the verdict on campaigns as rigs record them (issue 42, point 3)")
    ap.add_argument("--out", default="results/verdict_start_conditions")
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "ehas_start_conditions"),
                    help="campaigns and compare/diagnosis files (large; not committed)")
    ap.add_argument("--part", choices=("a", "b", "ab", "c"), default="ab",
                    help="a: the figures of every variant; b: the diagnosis of the rest variant; c: the diagnoses "
                         "of the fade, rest and rest_bump variants at one commit, compared")
    ap.add_argument("--only", default="", help="case ids, comma-separated")
    ap.add_argument("--limit", type=int, default=0, help="run at most this many new cases")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once")
    ap.add_argument("--readme-only", action="store_true", help="rewrite README.md and results.json from cases/")
    ap.add_argument("--redo", action="store_true", help="rerun the parts already checkpointed")
    a = ap.parse_args(argv)
    out, work = Path(a.out), Path(a.work)
    (out / "cases").mkdir(parents=True, exist_ok=True)
    selected = cases()
    if a.only:
        only = set(a.only.split(","))
        unknown = only - {c["id"] for c in selected}
        if unknown:
            raise SystemExit(f"--only: unknown case id(s) {', '.join(sorted(unknown))}; known: "
                             f"{', '.join(c['id'] for c in selected)}")
        selected = [c for c in selected if c["id"] in only]

    def stored(cid):
        p = out / "cases" / f"{cid}.json"
        return json.loads(p.read_text()) if p.exists() else None

    todo = []
    if not a.readme_only:
        for c in selected:
            rec = stored(c["id"]) or {}
            need = [p for p in a.part if a.redo or p not in rec]
            if need:
                todo.append((c, need))
    if a.limit:
        todo = todo[:a.limit]
    guess = sum((GUESS_A_S if "a" in n else 0) + (GUESS_B_S if "b" in n else 0)
                + (len(DIAGNOSED) * GUESS_B_S if "c" in n else 0) for _, n in todo)
    print(f"[start] {len(selected)} cases selected, {len(todo)} to run; about {guess / 60 / max(1, a.jobs):.0f} min "
          f"(first guess {GUESS_A_S:.0f} s part a, {GUESS_B_S:.0f} s part b)", flush=True)

    def one(item):
        c, need = item
        for part in need:
            commit = acc._commit()  # the code the part starts with (a commit made while it runs is not its)
            if part == "a":
                new = {"a": part_a(c, work), "ehas_commit": commit}
            elif part == "c":
                new = {"c": {**part_c(c, work, out), "ehas_commit": commit}}
                # part (c)'s `rest` diagnosis is part (b)'s (the same campaign and command; it wrote diag/ID.json)
                new["b"] = {**new["c"]["rest"], "ehas_commit": commit}
            else:
                new = {"b": {**part_b(c, work, out), "ehas_commit": commit}}
            # the record as stored now (another process may have written its other part meanwhile), with this part
            rec = {**(stored(c["id"]) or dict(c)), **new}
            tmp = out / "cases" / f".{c['id']}.{os.getpid()}.json.tmp"
            tmp.write_text(json.dumps(rec, indent=1) + "\n")
            os.replace(tmp, out / "cases" / f"{c['id']}.json")
        return rec

    try:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max(1, a.jobs)) as pool:
            for k, ((c, need), rec) in enumerate(zip(todo, pool.map(one, todo)), 1):
                v = (rec.get("a") or {}).get("variants") or {}
                tv = (rec.get("a") or {}).get("true_bk") or {}
                figs = ", ".join(f"{n} {_f(x.get('residual_x_noise'))}/{_f((tv.get(n) or {}).get('residual_x_noise'))}"
                                 for n, x in v.items())
                b = rec.get("b") or {}
                cc = rec.get("c") or {}
                if cc:
                    figs += "; diagnosed " + ", ".join(f"{v} {(cc.get(v) or {}).get('verdict')} "
                                                       f"{_f((cc.get(v) or {}).get('residual_x_noise'))}"
                                                       for v in DIAGNOSED)
                print(f"[start] {k}/{len(todo)} {c['id']} ({'+'.join(need)}): {figs}; effect "
                      f"{_f((rec.get('a') or {}).get('effect', {}).get('best_db'))} dB"
                      + (f"; diagnosis {b.get('verdict', b.get('error'))} {_f(b.get('residual_x_noise'))}, added "
                         f"{b.get('named') or b.get('kept') or 'nothing'}" if b else ""), flush=True)
    except KeyboardInterrupt:
        print("[start] interrupted: finished cases are kept; rerun the same command to resume", flush=True)
    order = {c["id"]: i for i, c in enumerate(cases())}
    recs = sorted((json.loads(p.read_text()) for p in (out / "cases").glob("*.json")),
                  key=lambda r: order.get(r["id"], 1e9))
    summ = summarise(recs, out)
    command = COMMAND if str(a.out) == "results/verdict_start_conditions" else \
        f"python -m tests.independent_rig.start_conditions --out {a.out}"
    slim = [{k: v for k, v in r.items() if k != "a"} | {"a": {
        **{k: v for k, v in r["a"].items() if k not in ("variants", "true_bk")},
        **{side: {n: {k: x for k, x in v.items() if k != "blocks"} for n, v in r["a"][side].items()}
           for side in ("variants", "true_bk")}}}
        if "a" in r else r for r in recs]
    _atomic(out / "results.json", json.dumps({"command": command, "agree": AGREE, "visible_db": VISIBLE_DB,
                                              "variants": list(VARIANTS), "summary": summ, "cases": slim},
                                             indent=1) + "\n")
    _atomic(out / "README.md", readme(recs, summ, command))
    print(f"[start] wrote {out / 'README.md'} and results.json ({len(recs)} cases)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
