"""Issue 22: data is data.  A model file, a run sidecar, a training TOML and an agent folder that each try to
run code (write a marker file) are read by every command that reads them: no marker, one clear line, a
non-zero status where the input cannot be used.  And the other direction: a model saved with a user effect
reopens with the same --effects-path, and refuses in one line without it.
"""
from __future__ import annotations

import hashlib
import json
import pickle
import shutil
from pathlib import Path

import pytest

from ehas_env.cli import main as cli

from ehas_env.physics.effects.example_file import spring_effect

ROOT = Path(__file__).resolve().parents[2]

SPRING = spring_effect("torsion_spring_dd", "TorsionSpringDD")  # the example user effect file


class _Payload:
    """Unpickling this writes the marker (what a hostile pickle does)."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (Path.write_text, (Path(self.marker), "ran"))


@pytest.fixture
def hostile(tmp_path):
    """A marker path and a folder of code that writes it when imported."""
    marker = tmp_path / "MARKER"
    code = tmp_path / "evil"
    code.mkdir()
    body = f"open({str(marker)!r}, 'w').write('ran')\n"
    (code / "evil_effect.py").write_text(body)
    (code / "evilmod.py").write_text(body)
    return marker, code


def run(argv, capsys):
    try:
        rc = cli.main([str(a) for a in argv])
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    return rc, [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("[") and ": warning: " not in ln]


def _model(path, **extra):
    from ehas_env.simulation.model_file import PlantModel, model_doc

    doc = model_doc(PlantModel())
    doc.update(extra)
    path.write_text(json.dumps(doc))
    return path


def test_a_model_file_never_imports_the_code_it_names(hostile, tmp_path, capsys):
    marker, code = hostile
    quiet = _model(tmp_path / "quiet.json", effects_path=[str(code), "../" + code.name,
                                                         str(code / "evil_effect.py")])
    named = _model(tmp_path / "named.json", effects={"evil_effect": {}}, effects_path=[str(code)],
                   user_effects={"evil_effect": {"file": "evil_effect.py",
                                                 "sha256": hashlib.sha256((code / "evil_effect.py").read_bytes())
                                                 .hexdigest()}})
    for model in (quiet, named):
        cases = [["model", "show", model], ["model", "diff", model, model],
                 ["model", "new", tmp_path / f"new_{model.stem}.json", "--from", model],
                 ["size", "--model", model], ["simulate", "--model", model, "--out", tmp_path / "o" / model.stem]]
        for argv in cases:
            rc, err = run(argv, capsys)
            assert not marker.exists(), argv
            if model is named:  # the effect's code is not loaded: refused in one line naming it
                assert rc == 2 and len(err) == 1, (argv, err)
                assert "effect 'evil_effect' is a user effect (file evil_effect.py" in err[0], err
                assert "--effects-path" in err[0]
            else:
                assert rc in (0, 1), (argv, err)  # usable: the folder is ignored
    from ehas_env.simulation.plant import Plant

    Plant(disc_sets=2, model=quiet)
    with pytest.raises(ValueError, match="is a user effect"):
        Plant(disc_sets=2, model=named)
    import gymnasium

    import ehas_env  # noqa: F401
    with pytest.raises(ValueError, match="is a user effect"):
        gymnasium.make("ehas/Tracking-v0", model=str(named))
    toml = tmp_path / "cfg.toml"
    toml.write_text(f"[train]\nalgo = 'ppo'\n[env]\nmodel = {json.dumps(str(named))}\n")
    from ehas_train.config import load_config

    try:
        load_config(toml)
    except ValueError:
        pass
    assert not marker.exists()


def test_a_training_config_never_imports_a_module(hostile, tmp_path, capsys, monkeypatch):
    marker, code = hostile
    monkeypatch.syspath_prepend(str(code))
    monkeypatch.chdir(code)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[train]\nalgo = 'ppo'\n[env]\nid = 'evilmod:Env'\n")
    rc, err = run(["train", "--algo", "ppo", "--config", cfg, "--out", tmp_path / "t", "--no-progress", "--no-tensorboard"], capsys)
    assert rc == 2 and len(err) == 1 and "names a module to import" in err[0], err
    cfg.write_text(f"[train]\nalgo = 'ppo'\n[env]\nresidual = true\ncontroller = {json.dumps(str(code / 'evilmod.py'))}\n")
    rc, err = run(["train", "--algo", "ppo", "--config", cfg, "--out", tmp_path / "t", "--no-progress", "--no-tensorboard"], capsys)
    assert rc == 2 and len(err) == 1 and "never imports code" in err[0] and "--controller-path" in err[0], err
    assert not marker.exists()
    assert not (tmp_path / "t").exists()


def test_a_run_sidecar_never_imports_code(hostile, tmp_path, capsys):
    marker, code = hostile
    camp = tmp_path / "camp"
    rc, _ = run(["simulate-campaign", "--out", camp, "--duration", "0.21"], capsys)
    assert rc == 0
    for side in (p for p in camp.glob("*.json") if p.name != "truth.json"):
        meta = json.loads(side.read_text())
        meta["effects_path"] = [str(code)]
        meta["effects"] = {"evil_effect": {}}
        meta["controller"] = {"type": "evil_effect", "file": str(code / "evil_effect.py")}
        side.write_text(json.dumps(meta))
    for argv in (["compare", camp, "--out", tmp_path / "c"], ["diagnose", camp, "--json", tmp_path / "d.json"]):
        rc, err = run(argv, capsys)
        assert not marker.exists(), argv
        if rc != 0:
            assert len(err) == 1 and "Traceback" not in err[0], err
    assert not (tmp_path / "d.json").exists() or rc == 0


def _hostile_agent(tmp_path, marker):
    folder = tmp_path / "agent"
    shutil.copytree(ROOT / "results" / "agents" / "ppo", folder)
    for name in ("policy.json", "policy.safetensors", "obs_norm.json"):
        (folder / name).unlink()
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    import zipfile

    with zipfile.ZipFile(folder / "model.zip", "w") as z:
        z.writestr("data", json.dumps({"policy_class": {":serialized:": pickle.dumps(_Payload(marker)).hex()}}))
        z.writestr("pytorch_variables.pth", pickle.dumps(_Payload(marker)))
    return folder


def test_an_agent_folder_never_unpickles(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from ehas_train.agent import load_agent

    marker = tmp_path / "MARKER"
    folder = _hostile_agent(tmp_path, marker)
    with pytest.raises(ValueError, match="unpickling can run any code, so ehas does not load it"):
        load_agent(folder)
    for argv in (["bench", folder, "--out", tmp_path / "b", "--no-robustness", "--no-book"],
                 ["simulate", "--controller", folder, "--out", tmp_path / "s" / "run"]):
        rc, err = run(argv, capsys)
        assert rc == 2 and len(err) == 1, (argv, err)
        assert "pickled stable-baselines3 agent" in err[0] and "--allow-pickle" in err[0], err
    # a policy.json that names code instead of an activation is refused by name
    ok = tmp_path / "ok"
    shutil.copytree(ROOT / "results" / "agents" / "ppo", ok)
    doc = json.loads((ok / "policy.json").read_text())
    doc["kwargs"]["activation_fn"] = "os.system"
    (ok / "policy.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"kwargs.activation_fn = 'os.system'; allowed: Tanh"):
        load_agent(ok)
    assert not marker.exists()


def test_the_shipped_agents_load_without_unpickling(monkeypatch):
    pytest.importorskip("stable_baselines3")
    from ehas_train.agent import load_agent

    def refuse(*a, **k):
        raise AssertionError("unpickled")

    monkeypatch.setattr(pickle, "load", refuse)
    monkeypatch.setattr(pickle, "loads", refuse)
    import torch

    monkeypatch.setattr(torch, "load", refuse)
    for folder in sorted((ROOT / "results" / "agents").iterdir()):
        if folder.is_dir():
            assert not (folder / "model.zip").exists() and not (folder / "vecnormalize.pkl").exists(), folder
            agent = load_agent(folder)
            assert agent.kind == "learned"


def test_a_model_saved_with_a_user_effect_reopens_with_the_same_effects_path(tmp_path, capsys):
    eff = tmp_path / "my_effects"
    eff.mkdir()
    (eff / "torsion_spring_dd.py").write_text(SPRING)
    model = tmp_path / "m.json"
    rc, err = run(["model", "new", model, "--effects-path", eff, "--effects", "torsion_spring_dd:k=300"], capsys)
    assert rc == 0, err
    doc = json.loads(model.read_text())
    assert doc["user_effects"] == {"torsion_spring_dd": {
        "file": "torsion_spring_dd.py", "sha256": hashlib.sha256(SPRING.encode()).hexdigest()}}
    assert "effects_path" not in doc
    # reopens with --effects-path on every command that reads it (this process has loaded it by now; a fresh
    # process without --effects-path refuses, see the subprocess check below)
    for argv in (["model", "show", model, "--effects-path", eff],
                 ["simulate", "--model", model, "--effects-path", eff, "--out", tmp_path / "s" / "run"]):
        rc, err = run(argv, capsys)
        assert rc == 0, (argv, err)
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "ehas_env.cli.main", "model", "show", str(model)],
                          capture_output=True, text=True, cwd=tmp_path,
                          env={k: v for k, v in __import__("os").environ.items() if k != "EHAS_EFFECTS_PATH"})
    err = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2 and len(err) == 1, proc.stderr
    assert "effect 'torsion_spring_dd' is a user effect (file torsion_spring_dd.py" in err[0]
    assert "--effects-path DIR" in err[0]
