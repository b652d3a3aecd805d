"""Model files (docs/model-file.md): read (v1 and v2), validated field by field with one-line
errors naming the file and the field, written and compared; the book's rig is the default."""
from __future__ import annotations

import json

import numpy as np
import pytest

from ehas_env.cli.main import main
from ehas_env.simulation.model_file import (FIELDS, PlantModel, diff_models, load_model, model_doc, parse_model,
                                             save_model, write_model)
from ehas_env.physics.effects.example_file import spring_effect
from ehas_env.physics.rig import RigParams
from ehas_env.simulation.plant import Plant, RigController

RIG_B = dict(crank_radius_mm=60, half_stroke_mm=42, piston_area_cm2=9.0, inertia_per_set_kgm2=0.5,
             K_lpm_per_mA=2.0, wn_rad_s=150, zeta=0.6)


def test_the_default_model_is_the_books_rig_exactly():
    m = PlantModel()
    assert m.is_book and m.rig == RigParams()
    for n in (1, 4, 7):
        np.testing.assert_array_equal(Plant(n, model=m).param_vector, Plant(n).param_vector)
    assert m.controller() == RigController.book()
    # every field's default is the book's value, in the file's unit
    assert {f.key: f.default for f in FIELDS}["crank_radius_mm"] == pytest.approx(50.0)
    assert {f.key: f.default for f in FIELDS}["piston_area_cm2"] == pytest.approx(7.658)


def test_version_2_round_trip_and_plant(tmp_path):
    m = PlantModel.from_values("rig B", effects={"coulomb_friction": {"Fc": 250}}, **RIG_B)
    path = write_model(tmp_path / "b.json", m)
    doc = json.loads(path.read_text())
    assert (doc["format"], doc["version"], doc["kind"]) == ("ehas-model", 2, "plant")
    assert doc["rig"]["crank_radius_mm"] == 60 and doc["valve"]["K_lpm_per_mA"] == 2
    assert doc["units"] == {"coulomb_friction.Fc": "N"}
    back = load_model(path)
    assert diff_models(m, back) == [] and back.path == str(path)
    p = Plant(4, model=path)
    assert p.rig.radius == pytest.approx(0.06) and p.rig.area == pytest.approx(9e-4)
    assert p.rig.inertia == pytest.approx(2.0) and p.rig.K == 2.0 and p.rig.wn == 150
    assert p.effects == {"coulomb_friction": {"Fc": 250.0}}
    # effects given with the model add to its own; inertia/rig given override
    p2 = Plant(2, model=back, effects={"viscous_friction": {"b": 1000}}, inertia=3.0)
    assert set(p2.effects) == {"coulomb_friction", "viscous_friction"} and p2.rig.inertia == 3.0


def test_version_1_files_still_read(tmp_path):
    f = tmp_path / "old.json"
    f.write_text(json.dumps({"format": "ehas-model", "version": 1, "baseline": {"beta_Pa": 9.6e8, "K_lpm_per_mA": 1.281},
                             "effects": {"coulomb_friction": {"Fc": 412.0}}, "calibration": {"campaign": "x"}}))
    m = load_model(f)
    assert m.rig.beta == 9.6e8 and m.rig.K == 1.281 and m.rig.radius == 0.05
    assert m["effects"] == {"coulomb_friction": {"Fc": 412.0}} and m["rig"] is m.rig  # the older dict form
    assert m.calibration == {"campaign": "x"}


@pytest.mark.parametrize("change, words", [
    ({"rig": {"crank_radius_mm": -5}}, "rig.crank_radius_mm must be a number in [1, 2000] mm, got -5"),
    ({"rig": {"piston_area_cm2": "9"}}, "rig.piston_area_cm2 must be a number"),
    ({"rig": {"supply_bar": 1e9}}, "rig.supply_bar must be a number in (0, 350] bar"),
    ({"rig": {"inertia_per_set_kgm2": 0}}, "rig.inertia_per_set_kgm2"),
    ({"rig": {"bulk_modulus_Pa": 1e12}}, "rig.bulk_modulus_Pa"),
    ({"rig": {"half_stroke_mm": 60}}, "rig.half_stroke_mm (60 mm) must be shorter than rig.crank_radius_mm"),
    ({"rig": {"crank_radius_m": 0.06}}, "rig.crank_radius_m is not a model-file field"),
    ({"valve": {"zeta": float("nan")}}, "valve.zeta"),
    ({"valve": {"model": "magic"}}, "valve.model must be one of grey_box, white_box"),
    ({"valve": {"white_box": {"Kt": -1}}}, "valve.white_box.Kt"),
    ({"valve": {"rated_current_mA": 0}}, "valve.rated_current_mA"),
    ({"effects": {"magic": {}}}, "effects"),
    ({"effects_path": "nowhere"}, "effects_path must be a list of texts"),
    ({"user_effects": {"spring": {"file": "s.py"}}}, "user_effects.spring must be"),
    ({"user_effects": {"spring": {"file": "../s.py", "sha256": "0" * 64}}}, "user_effects.spring must be"),
    ({"effects": {"spring": {}}, "user_effects": {"spring": {"file": "s.py", "sha256": "0" * 64}}},
     "effect 'spring' is a user effect (file s.py"),
    ({"user_effects": {"coulomb_friction": {"file": "c.py", "sha256": "0" * 64}}},
     "user_effects.coulomb_friction names an effect that effects does not switch on"),
    ({"version": 2.0}, "'version' = 2.0"),
    ({"version": True}, "'version' = True"),
    ({"effects": {"coulomb_friction": {"Fc": "300"}}}, "parameter 'Fc' must be a number"),
    ({"calibration": {"fit_percent_after": "98"}}, "calibration.fit_percent_after must be a number"),
    ({"calibration": {"nested": float("nan")}}, "calibration.nested must be"),
    ({"provenance": {"x": float("inf")}}, "provenance.x must be"),
    ({"kind": "pump"}, "kind = 'pump'"),
    ({"version": 3}, "'version' = 3"),
    ({"extra": 1}, "extra is not a model-file field"),
])
def test_every_field_is_checked_with_one_line_naming_file_and_field(change, words, tmp_path, capsys):
    doc = model_doc(PlantModel())
    for k, v in change.items():
        doc[k] = {**doc[k], **v} if isinstance(v, dict) and isinstance(doc.get(k), dict) and k != "effects" else v
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(ValueError) as exc:
        load_model(f)
    msg = str(exc.value)
    assert str(f) in msg and words in msg and "\n" not in msg
    # and the same words on the command line, one line, status 2
    assert main(["simulate", "--model", str(f), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "bad.json" in err[0]


def test_a_model_file_names_its_user_effects_and_never_loads_their_code(tmp_path):
    folder = tmp_path / "rig"
    (folder / "my_effects").mkdir(parents=True)
    spring = folder / "my_effects" / "torsion_spring_mf.py"
    spring.write_text(spring_effect("torsion_spring_mf", "TorsionSpringMF"))  # the example user effect file
    import hashlib

    digest = hashlib.sha256(spring.read_bytes()).hexdigest()
    doc = model_doc(PlantModel())
    doc["effects_path"] = ["my_effects"]  # an older file's folder: read, never imported
    doc["effects"] = {"torsion_spring_mf": {"k": 25.0}}
    f = folder / "m.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="effect 'torsion_spring_mf' is a user effect that is not loaded; give the "
                                         "folder holding its file with --effects-path"):
        load_model(f)
    from ehas_env.physics.effects import load_effects_path

    load_effects_path(folder / "my_effects")  # what --effects-path DIR does
    m = load_model(f)
    assert m.effects == {"torsion_spring_mf": {"k": 25.0}}
    out = model_doc(m)
    assert "effects_path" not in out
    assert out["user_effects"] == {"torsion_spring_mf": {"file": "torsion_spring_mf.py", "sha256": digest}}
    # a model saved with a different file text refuses the loaded one, naming both hashes
    out["user_effects"]["torsion_spring_mf"]["sha256"] = "f" * 64
    f.write_text(json.dumps(out))
    with pytest.raises(ValueError, match=f"sha256 {digest[:12]}.*is not the file the model was saved with"):
        load_model(f)


def test_save_model_keeps_the_base_rig_and_records_provenance(tmp_path):
    base = PlantModel.from_values("rig B", **RIG_B)
    path = save_model(tmp_path / "fit.json", {"coulomb_friction": {"Fc": 300}}, beta=9.5e8, base=base,
                      calibration={"campaign": "A"}, command="ehas compare A --fit")
    m = load_model(path)
    assert m.rig.radius == pytest.approx(0.06) and m.rig.beta == 9.5e8 and m.rig.K == 2.0
    assert m.provenance["command"] == "ehas compare A --fit" and "ehas_version" in m.provenance
    assert m.name == "rig B" and m.calibration == {"campaign": "A"}


def test_cli_model_new_show_diff(tmp_path, capsys):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(["model", "new", str(a)]) == 0
    assert main(["model", "new", str(b), "--from", str(a), "--name", "rig B", "--crank-radius-mm", "60",
                 "--rated-flow-lpm", "40", "--effects", "coulomb_friction:Fc=300"]) == 0
    capsys.readouterr()
    assert load_model(b).rig.K == pytest.approx(2.0)
    assert main(["model", "show", str(b)]) == 0
    out = capsys.readouterr().out
    assert "crank_radius_mm        60" in out and "(book 50)" in out and "coulomb_friction(Fc=300)" in out
    assert main(["model", "diff", str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert "rig.crank_radius_mm: 50 -> 60 mm (+20.00 %)" in out and "effects.coulomb_friction: added Fc=300" in out
    assert main(["model", "diff", str(a), str(a)]) == 0
    assert main(["model", "new", str(a)]) == 2  # exists: --overwrite
    assert "--overwrite" in capsys.readouterr().err
    assert main(["model", "new", str(tmp_path / "c.json"), "--half-stroke-mm", "70"]) == 2
    assert "rig.half_stroke_mm" in capsys.readouterr().err


def test_env_and_vector_env_take_the_model(tmp_path):
    import gymnasium

    import ehas_env  # noqa: F401
    from ehas_env.env import batch_kernel as bk
    from ehas_env.env.vector_env import TrackingVectorEnv

    path = write_model(tmp_path / "b.json", PlantModel.from_values("rig B", **RIG_B))
    env = gymnasium.make("ehas/Tracking-v0", model=str(path), disc_sets=4)
    env.reset(seed=0)
    np.testing.assert_allclose(env.unwrapped._C[bk.C_P:], Plant(4, model=path).param_vector)
    vec = TrackingVectorEnv(2, model=load_model(path), disc_sets=2)
    vec.reset(seed=0)
    assert vec._C[0, bk.C_P] == pytest.approx(2 * 0.5)  # slot 0: inertia, 0.5 kg m^2 per set
    vec.close()
    env.close()


def test_bench_names_duplicate_controllers_by_content():
    from ehas_controllers.base import controller_from_dict
    from ehas_controllers.benchmark import _unique_names
    from ehas_controllers.piff import PIFF

    a = PIFF.book()
    d = a.to_dict()
    d["gains"]["Kp"] = 1.5
    names = _unique_names([a, PIFF.book(), controller_from_dict(d)])
    assert len(set(names)) == 3 and not any(n.endswith("(2)") for n in names)
    assert names[2] == "book (Kp 1.5)" and "same as" in names[1]


def test_a_pickled_agent_loads_only_behind_allow_pickle(tmp_path, monkeypatch):
    import warnings

    pytest.importorskip("stable_baselines3")
    from ehas_train.agent import PickleWarning, load_agent, trust_agent

    monkeypatch.setenv("EHAS_TRUSTED_AGENTS", str(tmp_path / "trusted.json"))
    folder = tmp_path / "agent"
    folder.mkdir()
    from stable_baselines3 import PPO

    import gymnasium

    import ehas_env  # noqa: F401
    PPO("MlpPolicy", gymnasium.make("ehas/Tracking-v0"), n_steps=64, batch_size=32, device="cpu").save(folder / "model.zip")
    zipped = folder / "model.zip"  # a bare zip (a folder without config.json is refused)
    with pytest.raises(ValueError, match="unpickling can run any code.*--allow-pickle"):
        load_agent(zipped)
    with pytest.warns(PickleWarning):
        load_agent(zipped, allow_pickle=True)
    trust_agent(zipped)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PickleWarning)
        load_agent(zipped, allow_pickle=True)  # trusted: quiet
    zipped.write_bytes(zipped.read_bytes() + b"\0")  # changed: warns again
    with pytest.warns(PickleWarning):
        load_agent(zipped, allow_pickle=True)


def test_parse_model_from_a_dict_and_errors_name_the_source():
    m = parse_model({"format": "ehas-model", "version": 2, "rig": {"crank_radius_mm": 55}}, "<dict>")
    assert m.rig.radius == pytest.approx(0.055) and m.rig.area == RigParams().area
    with pytest.raises(ValueError, match="<dict>: rig.crank_radius_mm"):
        parse_model({"format": "ehas-model", "version": 2, "rig": {"crank_radius_mm": 0}}, "<dict>")
