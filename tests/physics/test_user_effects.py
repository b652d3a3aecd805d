"""An effect written outside the package, in one file, used everywhere with no edit of ehas."""
from __future__ import annotations

import math

import numpy as np
import pytest
from ehas_env.physics.effects.example_file import spring_effect

SPRING = spring_effect("torsion_spring", "TorsionSpring")


@pytest.fixture(scope="module")
def spring_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("my_effects")
    (d / "my_spring.py").write_text(SPRING)
    return d


def test_plant_uses_a_user_effect_file(spring_dir):
    from ehas_env.simulation.plant import Plant

    k = 2000.0
    plant = Plant(disc_sets=1, effects={"torsion_spring": {"k": k}}, effects_path=spring_dir)
    assert "torsion_spring" in plant.model.EFFECTS
    # the compiled rate equals the spring's own term at an arbitrary state
    s = plant.initial_state(10.0)
    ds, ds0 = np.zeros(plant.model.N_STATES), np.zeros(plant.model.N_STATES)
    plant.model.derivatives(s, 0.0, plant.param_vector, ds)
    bare = Plant(disc_sets=1)
    bare.model.derivatives(s, 0.0, bare.param_vector, ds0)
    assert ds[1] - ds0[1] == pytest.approx(-k * math.radians(10.0) / plant.rig.inertia, rel=1e-12)
    # and a closed-loop run needs more load to hold the same path (the spring pushes back)
    run = plant.simulate_closed_loop(amplitude_deg=20, freq_hz=1, cycles=3)
    ref = bare.simulate_closed_loop(amplitude_deg=20, freq_hz=1, cycles=3)
    assert np.abs(run.load_kN).max() > np.abs(ref.load_kN).max()


def test_linearisation_shows_the_spring(spring_dir):
    from ehas_env.physics.linearise import linearise
    from ehas_env.simulation.plant import Plant

    k = 5.0e4
    plant = Plant(disc_sets=2, effects={"torsion_spring": {"k": k}}, effects_path=spring_dir)
    lin = linearise(plant)
    th, om = lin.states.index("theta"), lin.states.index("omega")
    inertia = plant.rig.inertia
    # pure spring-inertia: the mechanical block alone (pressures held) rings at sqrt(k / I)
    assert math.sqrt(-lin.A[om, th]) == pytest.approx(math.sqrt(k / inertia), rel=1e-6)
    # the hydraulic mode moves as the stiffness sum says: w^2 = (K_h + k) / I, with the oil's
    # torsional stiffness K_h = beta A^2 r^2 (1/V_A + 1/V_B) at mid-stroke, written out here
    rig = plant.rig
    v0 = rig.area * rig.half_stroke + rig.dead_volume
    k_h = rig.beta * rig.area ** 2 * rig.radius ** 2 * 2.0 / v0
    bare = linearise(Plant(disc_sets=2))
    assert bare.hydraulic_wn_hz() * 2 * math.pi == pytest.approx(math.sqrt(k_h / inertia), rel=1e-5)
    assert lin.hydraulic_wn_hz() * 2 * math.pi == pytest.approx(math.sqrt((k_h + k) / inertia), rel=1e-5)


def _spring_moves_the_crank_less(spring_dir):
    import gymnasium

    import ehas_env  # noqa: F401

    env = gymnasium.make("ehas/Tracking-v0", effects={"torsion_spring": {"k": 3000.0}}, effects_path=str(spring_dir),
                         controller=None)
    env.reset(seed=0)
    infos = [env.step(np.array([0.2], np.float32))[4] for _ in range(300)]
    env2 = gymnasium.make("ehas/Tracking-v0", controller=None)
    env2.reset(seed=0)
    infos2 = [env2.step(np.array([0.2], np.float32))[4] for _ in range(300)]
    # the same current moves the spring-loaded crank less far
    assert abs(infos[-1]["theta_deg"]) < abs(infos2[-1]["theta_deg"])


@pytest.mark.slow  # compiles the environment's inlined build with the user's effect: 352 s on 2 loaded cores
def test_environment_uses_a_user_effect(spring_dir):
    _spring_moves_the_crank_less(spring_dir)


def test_environment_uses_a_user_effect_on_the_quick_build(spring_dir, monkeypatch):
    """The same check on the quick-compile build (EHAS_BUILD=quick, seconds to compile): the default run's."""
    monkeypatch.setenv("EHAS_BUILD", "quick")
    _spring_moves_the_crank_less(spring_dir)


def test_simulate_and_effects_commands_take_effects_path(spring_dir, tmp_path, capsys):
    from ehas_env.cli.main import main

    assert main(["effects", "torsion_spring", "--effects-path", str(spring_dir)]) == 0
    assert "torsion spring on the crank" in capsys.readouterr().out
    out = tmp_path / "run"
    assert main(["simulate", "--effects-path", str(spring_dir), "--effects", "torsion_spring:k=3000",
                 "--cycles", "3", "--out", str(out)]) == 0
    import json

    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["effects"] == {"torsion_spring": {"k": 3000.0}}


def test_a_broken_effect_file_is_one_clear_error(tmp_path, capsys):
    from ehas_env.cli.main import main

    (tmp_path / "bad.py").write_text("import nonexistent_module_xyz\n")
    assert main(["effects", "--effects-path", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "bad.py" in err and "nonexistent_module_xyz" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("body, message", [
    ('    @staticmethod\n    def piston_forse(v, k):\n        return -k * v\n',
     "static method 'piston_forse' is not a place where physics enters"),
    ("    pass\n", "holds no physics: write at least one static method named after a place"),
])
def test_an_effect_that_would_do_nothing_is_refused(tmp_path, capsys, body, message):
    """A misspelt place, or no place at all, would leave the model unchanged without a word."""
    from ehas_env.cli.main import main

    (tmp_path / "typo.py").write_text(
        "from ehas_env.physics.effects.base import Effect, Param\n\n\nclass Typo(Effect):\n"
        "    name = 'typo_effect'\n    params = (Param('k', 'N s/m', 1.0, (0.0, 10.0), 'a damping'),)\n" + body)
    assert main(["effects", "--effects-path", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "typo.py" in err and message in err, err


# slow: the benchmark compiles the fast-step build of a new effect set (about 2.5 min on 2 cores); the quick
# build takes the same file in test_plant_uses_a_user_effect_file and the environment test below
@pytest.mark.slow
def test_bench_and_diagnose_take_the_effect_from_its_folder(spring_dir, tmp_path, capsys):
    """bench puts the user's effect in its robustness table; diagnose finds it hidden in a campaign."""
    import json

    from ehas_env.cli.main import main

    ctrl = tmp_path / "book.json"
    from ehas_controllers.piff import PIFF

    PIFF.book().save(ctrl)
    assert main(["bench", str(ctrl), "--effects-path", str(spring_dir), "--out", str(tmp_path / "bench")]) == 0
    rows = (tmp_path / "bench" / "benchmark_robustness.csv").read_text()
    assert "torsion_spring" in rows
    capsys.readouterr()
    camp = tmp_path / "camp"
    k = 3000.0
    assert main(["simulate-campaign", "--effects-path", str(spring_dir), "--effects", f"torsion_spring:k={k}",
                 "--seed", "3", "--out", str(camp)]) == 0
    out = tmp_path / "diag.json"
    assert main(["diagnose", str(camp), "--effects-path", str(spring_dir), "--candidates", "torsion_spring",
                 "--no-stack", "--no-propose", "--quiet", "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    top = res["ranking"][0]
    assert top["effect"] == "torsion_spring"
    assert top["params"]["k"] == pytest.approx(k, rel=0.1)


def test_an_effect_folder_named_in_the_environment_is_checked_once_not_recursively(tmp_path):
    """With EHAS_EFFECTS_PATH naming a folder whose file was never checked, loading it finishes: the import check's
    child process does not load that folder again (it used to spawn a child per level until the time limit)."""
    import os
    import subprocess
    import sys

    from ehas_env.physics.effects.example_file import spring_effect

    folder = tmp_path / "fx"
    folder.mkdir()
    (folder / "spring.py").write_text(spring_effect("env_path_spring", "EnvPathSpring"))
    env = {**os.environ, "EHAS_EFFECTS_PATH": str(folder), "EHAS_CACHE_DIR": str(tmp_path / "cache"),
           "EHAS_PLUGIN_TIMEOUT": "60"}
    proc = subprocess.run([sys.executable, "-c", "from ehas_env.physics.effects import REGISTRY\n"
                           "print('env_path_spring' in REGISTRY)"], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-400:]
    assert proc.stdout.strip() == "True"
    # exactly one check ran (its mark), not a chain of them
    assert len(list((tmp_path / "cache" / "plugins_ok").iterdir())) == 1
