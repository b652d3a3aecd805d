"""An environment's first step without waiting for a compile: the interpreted build, the fast build behind it.

Truth here is the fast-step (inlined, numba-compiled) build itself: the interpreted build is the same
generated text run by Python, so every trajectory must agree with it bit for bit -- on the baseline, with
effects on, with sensor noise (the counter-based uint64 generator), in residual mode with a compiled law,
at a stroke end and on a non-finite state.  The background compile is checked on a tiny generated module
(seconds, not the environment's tens of seconds of CPU): it starts, writes its markers, the caller switches,
a changed text is never served by the old cache, and a failed compile falls back to compiling in-process.
The environment's whole path from an empty cache (slow: one full compile of its step) is the last test.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from ehas_env.env import batch_kernel as bk
from ehas_env.env.tracking_env import TrackingEnv
from ehas_env.physics import codegen
from ehas_env.physics import compile_behind as cb
from ehas_env.simulation.compiled_model import _Ready, current_model
from ehas_env.simulation.plant import RigController


def _on(env, model):
    """``env`` stepping on ``model`` from now on (a build that is ready)."""
    env._builds = _Ready(model)
    env._model = model
    return env


def _run(model, steps, actions, kwargs, corrupt_at=None):
    env = _on(TrackingEnv(**kwargs), model)
    obs, info = env.reset(seed=5)
    rows = [np.concatenate([obs, env._raw, env._X])]
    for k in range(steps):
        if k == corrupt_at:
            env._C[bk.C_P + model.IDX["beta"]] = np.inf
        obs, r, term, trunc, info = env.step(np.array([actions[k]], np.float32))
        rows.append(np.concatenate([obs, env._raw, env._X, [r, term, trunc]]))
        if term or trunc:
            break
    return np.array(rows, dtype=object if len({len(x) for x in rows}) > 1 else float), info


CASES = {
    "baseline": ({}, 400, None),
    "effects, realistic sensors": ({"effects": {"coulomb_friction": {"Fc": 300.0}, "valve_deadband": {}},
                                    "sensors": "realistic"}, 400, None),
    "residual, compiled law": ({"controller": RigController.book(), "amplitude_deg": 30.0}, 400, None),
    "stroke end": ({"amplitude_deg": 40.0, "freq_hz": 0.5}, 3000, None),
    "non-finite state": ({}, 50, 20),
}


@pytest.mark.parametrize("case", list(CASES))
def test_interpreted_build_steps_bit_for_bit_like_the_fast_build(case):
    kwargs, steps, corrupt = CASES[case]
    rng = np.random.default_rng(11)
    actions = rng.uniform(-1.0, 1.0, steps) if case != "stroke end" else np.ones(steps)
    fast, slow = current_model(), current_model(interpreted=True)
    assert slow.__name__.startswith("ehas_py_") and fast.__name__.startswith("ehas_model_")
    assert not hasattr(slow.single_step, "py_func")  # really not numba
    a, info_a = _run(fast, steps, actions, kwargs, corrupt)
    b, info_b = _run(slow, steps, actions, kwargs, corrupt)
    assert len(a) == len(b) > 1
    for ra, rb in zip(a, b):
        np.testing.assert_array_equal(np.asarray(ra, float), np.asarray(rb, float))
    if case == "stroke end":
        assert info_a["termination"] == info_b["termination"] == "stroke_end"
    if case == "non-finite state":
        assert info_a["termination"] == info_b["termination"] == "non_finite_state"


# parallel=True compiles the prange kernel (about 2 min on 2 cores): slow, as in test_vector_env.py
@pytest.mark.parametrize("parallel", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_interpreted_vector_env_steps_bit_for_bit_like_the_fast_build(parallel):
    from ehas_env.env.vector_env import TrackingVectorEnv

    rng = np.random.default_rng(4)
    actions = rng.uniform(-1.0, 1.0, (300, 3))
    runs = []
    for model in (current_model(), current_model(interpreted=True)):
        env = TrackingVectorEnv(3, parallel=parallel, cycles=0.5, freq_hz=2.0,  # episodes of 250 steps: autoresets
                                randomise={"amplitude_deg": (5.0, 40.0)})
        env._builds = _Ready(model)
        env._model = model
        obs, _ = env.reset(seed=8)
        rows = [np.concatenate([obs.ravel(), np.zeros(9)])]
        for a in actions:
            obs, r, term, trunc, _ = env.step(a)
            rows.append(np.concatenate([obs.ravel(), r, term, trunc]))
        runs.append(np.array(rows))
    assert runs[0].shape == runs[1].shape
    np.testing.assert_array_equal(runs[0], runs[1])


# -- the background compile, on a tiny generated module ------------------------------------------------------------
TINY = textwrap.dedent('''\
    import numpy as np
    from numba import njit


    @njit(cache=True)
    def bump(x, y, n, flag):
        x[0] += y * n if flag else y
        return x[0] * {factor}
    ''')


def _tiny(factor: str):
    """(fast, interpreted) modules of the tiny text; the fast one written beside numba's cache like a model."""
    text = TINY.format(factor=factor)
    name = f"ehas_model_{codegen._digest(text)}"
    fast = codegen._load(name, text, [])
    interp = codegen._load(f"ehas_py_{codegen._digest(text)}", text.replace("from numba import njit\n", "")
                           .replace("@njit(cache=True)\n", ""), [])
    return fast, interp


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("EHAS_CACHE_DIR", str(tmp_path / "models"))
    monkeypatch.delenv("EHAS_QUIET", raising=False)
    return tmp_path / "models"


def test_the_fast_build_compiles_behind_and_the_caller_switches_to_it(cache, capfd):
    fast, interp = _tiny("2.0")
    x = np.zeros(1)
    behind = cb.FastBuildBehind(fast, interp, {"bump": (x, 1.5, 2, True)}, "the test's call")
    assert behind.model is interp and not behind.done
    assert (cache / f"{fast.__name__}.compiling").exists()
    assert "compiles in a background process" in capfd.readouterr().err
    assert behind.model.bump(x, 1.5, 2, True) == 6.0  # the caller works meanwhile
    assert x[0] == 3.0  # the example arguments were copied, never changed
    assert behind.wait(timeout=180) is fast and behind.done
    assert "switched to the fast-step build" in capfd.readouterr().err
    assert cb.is_ready(Path(fast.__file__), ["bump"]) and not (cache / f"{fast.__name__}.compiling").exists()
    assert "compiled bump" in (cache / f"{fast.__name__}.compile.log").read_text()
    assert fast.bump.signatures and not sum(fast.bump.stats.cache_misses.values())  # loaded from the cache, here
    assert not list(cache.glob("*.npz"))  # the arguments file is removed
    # a later caller finds the markers: the fast build at once, no process
    again = cb.FastBuildBehind(fast, interp, {"bump": (x, 1.5, 2, True)}, "the test's call")
    assert again.done and again.model is fast and again._proc is None


def test_a_changed_text_is_never_served_by_the_old_compile(cache):
    old, _ = _tiny("3.0")
    cb.FastBuildBehind(old, old, {"bump": (np.zeros(1), 1.0, 1, False)}, "old").wait(timeout=180)
    new, new_interp = _tiny("4.0")
    assert new.__name__ != old.__name__
    behind = cb.FastBuildBehind(new, new_interp, {"bump": (np.zeros(1), 1.0, 1, False)}, "new")
    assert not behind.done and behind.model is new_interp
    assert behind.wait(timeout=180) is new
    assert new.bump(np.zeros(1), 1.0, 1, False) == 4.0 and old.bump(np.zeros(1), 1.0, 1, False) == 3.0


def test_a_failed_background_compile_falls_back_to_compiling_here(cache, capfd):
    fast, interp = _tiny("6.0")
    # a string array: numba cannot type ``x[0] += y * n`` for it, so the background process fails
    behind = cb.FastBuildBehind(fast, interp, {"bump": (np.zeros(1), np.array(["a"]), 1, True)}, "the test's call")
    behind._proc.wait(timeout=180)
    behind._next = 0.0
    assert behind.poll() is fast and behind.done
    err = capfd.readouterr().err
    assert "background compile stopped with exit status" in err and "compiling the fast-step build here" in err
    assert not cb.is_ready(Path(fast.__file__), ["bump"])


def test_a_second_caller_waits_for_the_running_compile_instead_of_starting_one(cache, capfd):
    fast, interp = _tiny("5.0")
    calls = {"bump": (np.zeros(1), 1.0, 1, True)}
    first = cb.FastBuildBehind(fast, interp, calls, "first")
    second = cb.FastBuildBehind(fast, interp, calls, "second")
    assert first._proc is not None and second._proc is None and second.model is interp
    err = capfd.readouterr().err
    assert err.count("compiles in a background process") == 1  # said once: the second caller adds nothing
    assert "another process" not in err
    assert second.wait(timeout=180) is fast  # it switches on the first one's markers
    first.wait(timeout=180)


# -- the environment from an empty cache ----------------------------------------------------------------------------
FIRST_STEP = textwrap.dedent('''\
    import json, sys, time
    import numpy as np, gymnasium, ehas_env
    env = gymnasium.make("ehas/Tracking-v0").unwrapped
    env.reset(seed=3)
    first = env._model.__name__
    rows = []
    for k in range(200):
        obs, r, *_ = env.step(np.array([0.5 * np.sin(k / 15.0)], np.float32))
        rows.append([r, *obs.tolist()])
        if k == 100 and sys.argv[1] == "wait":
            env._builds.wait(timeout=900)
    print(json.dumps({"first": first, "last": env._model.__name__, "done": env._builds.done, "rows": rows}))
    ''')


def _first_step(cache, mode):
    env = {**os.environ, "EHAS_CACHE_DIR": str(cache)}
    env.pop("EHAS_BUILD", None)
    out = subprocess.run([sys.executable, "-c", FIRST_STEP, mode], capture_output=True, text=True, env=env,
                         timeout=1200)
    assert out.returncode == 0, out.stderr
    import json
    return json.loads(out.stdout.strip().splitlines()[-1]), out.stderr


@pytest.mark.slow  # one full compile of the environment's step (about 30 s of CPU quiet)
def test_environment_starts_interpreted_from_an_empty_cache_switches_and_the_next_process_starts_fast(tmp_path):
    first, err = _first_step(tmp_path / "models", "wait")
    assert first["first"].startswith("ehas_py_") and first["last"].startswith("ehas_model_") and first["done"]
    assert "compiles in a background process" in err and "switched to the fast-step build" in err
    second, err2 = _first_step(tmp_path / "models", "no")
    assert second["first"].startswith("ehas_model_") and "background" not in err2
    # the trajectory does not see the switch at step 100: the same numbers as the fast build all along
    np.testing.assert_array_equal(np.array(first["rows"]), np.array(second["rows"]))


GRID = textwrap.dedent('''\
    import json
    import numpy as np
    from ehas_controllers.batch_sim import Batch, grid
    from ehas_env.simulation.compiled_model import current_model
    from ehas_env.simulation.plant import RigController
    batch = Batch(grid(disc_sets=(1, 3, 5, 7), freqs=(2.0, 3.0, 4.0)), cycles=3.0)
    assert len(batch) >= 32, len(batch)
    first = "quick" if batch.model is current_model(inline=False) else "fast"
    gains = RigController.book().gains_vector()
    m1 = batch.run(gains)
    batch._builds.wait(timeout=1500)
    m2 = batch.run(gains)
    print(json.dumps({"first": first, "last": "fast" if batch.model is current_model() else "other",
                      "m1": m1.tolist(), "m2": m2.tolist()}))
    ''')


@pytest.mark.slow  # a quick and a full fast-step compile of the grid's driver (about 70 s of CPU quiet)
def test_a_benchmark_grid_runs_on_the_quick_build_while_the_fast_one_compiles_with_the_same_metrics(tmp_path):
    env = {**os.environ, "EHAS_CACHE_DIR": str(tmp_path / "models")}
    env.pop("EHAS_BUILD", None)
    out = subprocess.run([sys.executable, "-c", GRID], capture_output=True, text=True, env=env, timeout=1800)
    assert out.returncode == 0, out.stderr
    import json
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["first"] == "quick" and res["last"] == "fast"
    assert "quick-compile build" in out.stderr and "switched to the fast-step build" in out.stderr
    np.testing.assert_array_equal(np.array(res["m1"]), np.array(res["m2"]))
