"""The independent generator shares no code with the package, and what it writes reads as a campaign."""
from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

from independent_rig import campaign as gen
from independent_rig.effects import LIBRARY, OUT_OF_LIBRARY, to_si
from independent_rig.judge import FORM_KIND, LIBRARY_KIND, judge

HERE = Path(__file__).parent
PACKAGE_ROOTS = {"ehas_env", "ehas_controllers", "ehas_train", "controllers", "train", "ehas"}


def _imported_roots(path: Path) -> set:
    roots = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            roots |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
        elif isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) in (
                "import_module", "__import__") and node.args and isinstance(node.args[0], ast.Constant):
            roots.add(str(node.args[0].value).split(".")[0])
    return roots


def test_the_generator_imports_nothing_of_the_package():
    """Every module of the generator (its tests aside, which may read its output with ehas) imports only the
    standard library, numpy and scipy: another engine, written from the docs."""
    modules = [p for p in HERE.glob("*.py") if not p.name.startswith("test_")]
    assert len(modules) >= 8
    allowed_third_party = {"numpy", "scipy"}
    import sys
    for p in modules:
        roots = _imported_roots(p)
        assert not roots & PACKAGE_ROOTS, f"{p.name} imports {sorted(roots & PACKAGE_ROOTS)}"
        foreign = {r for r in roots if r not in sys.stdlib_module_names and r not in allowed_third_party}
        assert not foreign, f"{p.name} imports {sorted(foreign)}"


def test_the_out_of_library_effects_are_not_in_the_library():
    """At least 12 effects, none named like an effect of ehas's library, each of a known kind, two magnitudes."""
    from ehas_env.physics.effects import REGISTRY

    assert len(OUT_OF_LIBRARY) >= 12
    assert not set(OUT_OF_LIBRARY) & set(REGISTRY)
    assert set(LIBRARY) <= set(REGISTRY)
    # every effect of ehas's library has a kind (user effects other tests registered in this process aside)
    library = {n for n, c in REGISTRY.items() if c.__module__.startswith("ehas_env.physics.effects.")}
    assert set(LIBRARY_KIND) >= library - {"loading"}
    for spec in OUT_OF_LIBRARY.values():
        assert spec.values(0) != spec.values(1)
        assert spec.kind in spec.accepted_kinds
    # the library re-implementations use the library's own parameter names
    for name, spec in LIBRARY.items():
        assert {p.name for p in spec.params} <= {p.name for p in REGISTRY[name].params}


def test_judge_maps_every_proposal_form():
    """Every form the proposal can name (ehas's dictionary) has a kind; a right and a wrong naming."""
    from ehas_env.measurement.proposal import FORMS

    assert {k.replace("proposal_", "") for k in FORMS} == set(FORM_KIND)
    right = judge({"crank_unbalance": {"G": 25}}, [{"label": "crank_torque.c_th", "kinds": ["load"]}])
    wrong = judge({"crank_unbalance": {"G": 25}}, [{"label": "piston_force.c_pb", "kinds": ["geometry/area"]}])
    assert right["right_kind"] and not wrong["right_kind"] and wrong["wrong"] == ["piston_force.c_pb"]
    assert judge({}, [])["right_kind"] and not judge({}, [{"label": "x", "kinds": ["load"]}])["right_kind"]


@pytest.mark.parametrize("rig", ["book", "rig_b"])
def test_a_written_campaign_reads_as_a_campaign(tmp_path, rig):
    """read_campaign reads the folder unchanged: the runs, their kinds and sidecars; truth.json skipped."""
    from ehas_env.measurement.campaign import read_campaign

    runs, truth = gen.simulate({"return_pressure": {"p_t": 10.0}}, seed=4, rig=rig, duration=0.4)
    out = gen.write(tmp_path / "camp", runs, truth)
    camp = read_campaign(out)
    names = [r.name for r in camp.runs]
    assert names == sorted(n for n, _, _ in runs)
    by = {r.name: r for r in camp.runs}
    base, _ = gen.rig_named(rig)
    for name, cols, meta in runs:
        r = by[name]
        assert r.meta["kind"] == meta["kind"]
        np.testing.assert_allclose(r.columns["current_mA"], cols["current_mA"], rtol=1e-8, atol=1e-12)
        if meta["kind"] == "closed_loop":
            assert r.meta["disc_sets"] == meta["disc_sets"]
            assert r.meta["controller"]["Kv"] == pytest.approx(base.controller_gains()["Kv"])
    assert any("truth.json" in w for w in camp.warnings)
    assert json.loads((out / "truth.json").read_text())["effects"] == {"return_pressure": {"p_t": 10.0}}


def test_effects_reach_the_logs():
    """Every out-of-library effect at its strong magnitude changes what the rig logs (no dead switch)."""
    base, _ = gen.simulate({}, seed=1, duration=0.6, plan=((1, 35.0, 3.0),), valve=True)
    for name, spec in OUT_OF_LIBRARY.items():
        runs, _ = gen.simulate({name: spec.values(1)}, seed=1, duration=0.6, plan=((1, 35.0, 3.0),), valve=True)
        moved = max(float(np.max(np.abs(np.asarray(c[k]) - np.asarray(b[k]))))
                    for (_, c, _), (_, b, _) in zip(runs, base) for k in c if k != "t")
        assert moved > 0.05, name
    assert to_si({"return_pressure": {"p_t": 10.0}}) == {"return_pressure": {"p_t": 1.0e6}}
