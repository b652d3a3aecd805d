"""The acceptance set: which campaigns the harness generates and diagnoses.

Groups:

* ``clean``: no effect; the book rig and the two other geometries (rigs/), several seeds;
* ``library``: one library effect re-implemented here (coulomb, viscous, delay, null bias, internal leakage);
* ``ool``: each out-of-library effect at its two magnitudes (the mild one on another rig geometry
  for a third of them);
* ``pairs``: two out-of-library effects together, and one beside a library effect;
* ``timing``: a 5-run campaign (4 closed-loop runs + the valve chirp) with 3 s and with 30 s runs.

and, apart (:func:`unlisted_cases`, not in :func:`all_cases`, so that results/diagnosis_open_world stays as
it is), the group ``unlisted`` of issue 33: each class of :data:`.effects.UNLISTED` at its two magnitudes
(the mild one on another rig geometry for a third of them), two unlisted classes together, and one beside
a library effect.
"""
from __future__ import annotations

from .effects import LIBRARY, OUT_OF_LIBRARY, UNLISTED

PAIRS = (("return_pressure", "lugre_friction"), ("valve_direction_gain", "crank_unbalance"),
         ("single_rod", "disc_drag"), ("current_lag", "turbulent_leakage"), ("entrained_air", "lvdt_offset"),
         ("load_compliance", "valve_underlap"), ("crank_offset", "supply_line_loss"))
LIB_PAIR = ("crank_unbalance", "coulomb_friction")
TIMING_EFFECT = {"crank_unbalance": {"G": 80.0}}
#: unlisted classes together: places apart (a sensor and a torque, a line and a force, a boundary and the command
#: path, the metering and a force)
UNLISTED_PAIRS = (("lvdt_lag", "bearing_friction"), ("hose_line", "bore_wear_friction"),
                  ("supply_ripple", "current_slew"), ("land_flow_forces", "end_cushion"))
#: an unlisted class beside a library effect (the library effect at its mild magnitude)
UNLISTED_LIB_PAIRS = (("bearing_friction", "coulomb_friction"), ("hose_line", "internal_leakage"))


def _case(cid, group, effects, seed, rig="book", duration=3.0):
    return {"id": cid, "group": group, "effects": effects, "seed": seed, "rig": rig, "duration": duration}


def all_cases(quick: bool = False, timing_repeats: int = 3) -> list[dict]:
    """Every case of the acceptance set, in the order run (``quick``: a small, representative part).

    Returns
    -------
    list of dict
        ``id``, ``group``, ``effects`` ({name: {param: value}}), ``seed``, ``rig``, ``duration`` (s per run).
    """
    cases = []
    clean_seeds = {"book": range(8), "rig_b": range(4), "rig_c": range(4)}
    if quick:
        clean_seeds = {"book": range(2), "rig_b": range(1), "rig_c": range(1)}
    for rig, seeds in clean_seeds.items():
        for s in seeds:
            cases.append(_case(f"clean_{rig}_s{s}", "clean", {}, 100 + s, rig))
    lib_rigs = {"coulomb_friction": "book", "viscous_friction": "book", "transport_delay": "rig_b",
                "valve_null_bias": "book", "internal_leakage": "rig_c"}
    for i, (name, spec) in enumerate(LIBRARY.items()):
        levels = (0, 1) if name == "coulomb_friction" else (0,)
        for lv in levels:
            if quick and lv:
                continue
            cases.append(_case(f"lib_{name}_{lv}", "library", {name: spec.values(lv)}, 200 + 10 * i + lv,
                               lib_rigs[name]))
    for i, (name, spec) in enumerate(OUT_OF_LIBRARY.items()):
        for lv in (0, 1):
            rig = "book"
            if lv == 0 and i % 3 == 1:
                rig = "rig_b"
            elif lv == 0 and i % 3 == 2:
                rig = "rig_c"
            if quick and (lv == 0 or i % 4):
                continue
            cases.append(_case(f"ool_{name}_{'mild' if lv == 0 else 'strong'}", "ool", {name: spec.values(lv)},
                               300 + 10 * i + lv, rig))
    if not quick:
        for j, (a, b) in enumerate(PAIRS):
            eff = {a: OUT_OF_LIBRARY[a].values(0), b: OUT_OF_LIBRARY[b].values(0)}
            cases.append(_case(f"pair_{a}+{b}", "pairs", eff, 500 + j))
        a, b = LIB_PAIR
        cases.append(_case(f"pair_{a}+{b}", "pairs",
                           {a: OUT_OF_LIBRARY[a].values(0), b: LIBRARY[b].values(0)}, 550))
    for dur in (3.0, 30.0):
        for k in range(timing_repeats if not quick else 1):
            cases.append(_case(f"timing_{dur:g}s_{k}", "timing", TIMING_EFFECT, 600 + k, "book", dur))
    return cases


def unlisted_cases() -> list[dict]:
    """The group ``unlisted`` (issue 33, item 7), in the order run.

    Returns
    -------
    list of dict
        As :func:`all_cases`: ``id``, ``group`` ("unlisted"), ``effects``, ``seed``, ``rig``, ``duration``.
    """
    cases = []
    for i, (name, spec) in enumerate(UNLISTED.items()):
        for lv in (0, 1):
            rig = "book"
            if lv == 0 and i % 3 == 1:
                rig = "rig_b"
            elif lv == 0 and i % 3 == 2:
                rig = "rig_c"
            cases.append(_case(f"unl_{name}_{'mild' if lv == 0 else 'strong'}", "unlisted", {name: spec.values(lv)},
                               700 + 10 * i + lv, rig))
    for j, (a, b) in enumerate(UNLISTED_PAIRS):
        cases.append(_case(f"unl_pair_{a}+{b}", "unlisted",
                           {a: UNLISTED[a].values(0), b: UNLISTED[b].values(0)}, 800 + j))
    for j, (a, b) in enumerate(UNLISTED_LIB_PAIRS):
        cases.append(_case(f"unl_pair_{a}+{b}", "unlisted",
                           {a: UNLISTED[a].values(0), b: LIBRARY[b].values(0)}, 850 + j))
    return cases
