"""The compiled model is keyed by its text: an edited effect file gives a new model, an unchanged one is reused,
and what an edit does not touch (the library's baseline) is not compiled again.

Counted, not timed: each case runs in a fresh process (numba's on-disk cache is what carries over between
runs) and reports the generated model's module name and numba's own cache statistics of ``derivatives``
(``cache_misses``: compiled here; ``cache_hits``: loaded from an earlier run's compile).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

from ehas_env.physics.effects.example_file import spring_effect

PROBE = textwrap.dedent("""
    import json, sys
    import numpy as np
    from ehas_env.physics.effects import load_effects_path
    from ehas_env.simulation.plant import Plant
    load_effects_path([sys.argv[1]])
    plant = Plant(disc_sets=3, effects={"cache_probe_spring": {"k": 1000.0}})
    m = plant.model
    s = plant.initial_state().copy()
    s[0] = 0.1
    ds = np.zeros(m.N_STATES)
    m.derivatives(s, 0.0, plant.param_vector, ds)
    st = m.derivatives.stats
    lib = m.land_flows.stats  # a library function: its own module in the quick build, whatever the effects
    print(json.dumps({"module": m.__name__, "misses": sum(st.cache_misses.values()),
                      "hits": sum(st.cache_hits.values()), "alpha": ds[1],
                      "lib_module": m.land_flows.py_func.__module__,
                      "lib_misses": sum(lib.cache_misses.values()), "lib_hits": sum(lib.cache_hits.values())}))
""")


def _effect(rate_scale: str) -> str:
    """The example spring effect with its torque scaled by ``rate_scale`` (an edit of the law's text)."""
    text = spring_effect("cache_probe_spring", "CacheProbeSpring")
    assert "return -(k * theta)" in text
    return text.replace("return -(k * theta)", f"return -({rate_scale} * k * theta)")


def _run(tmp_path, folder, quiet: bool = True) -> dict:
    env = {**os.environ, "EHAS_CACHE_DIR": str(tmp_path / "models"), "EHAS_QUIET_COMPILE": "1" if quiet else "0"}
    out = subprocess.run([sys.executable, "-c", PROBE, str(folder)], capture_output=True, text=True, env=env,
                         check=True)
    return {**json.loads(out.stdout.strip().splitlines()[-1]), "stderr": out.stderr}


def test_edited_effect_file_gives_a_new_model_and_an_unchanged_one_is_not_recompiled(tmp_path):
    fx = tmp_path / "fx"
    fx.mkdir()
    (fx / "spring.py").write_text(_effect("1.0"))
    first = _run(tmp_path, fx, quiet=False)
    # the first compile was announced and its time kept, in seconds and per kilobyte of the text it compiled: every
    # generated file here is this model's (a fresh cache)
    from ehas_env.physics import codegen

    assert "ehas: compiling the simulator" in first["stderr"]
    record = json.loads((tmp_path / "models" / codegen.COMPILE_RECORD).read_text())
    kb = sum(p.stat().st_size for p in (tmp_path / "models").glob("*.py")) / 1000.0
    (seconds,), (rate,) = record["quick"], record["quick" + codegen.PER_KB]
    assert rate * kb == pytest.approx(seconds, rel=1e-3)
    again = _run(tmp_path, fx)
    assert first["misses"] >= 1 and first["hits"] == 0  # compiled in the first process
    assert again["module"] == first["module"]  # the same text: the same generated model ...
    assert again["misses"] == 0 and again["hits"] >= 1  # ... loaded from the cache, not compiled again
    assert again["alpha"] == first["alpha"]

    (fx / "spring.py").write_text(_effect("2.0"))  # the user edits the law: twice the torque
    edited = _run(tmp_path, fx)
    assert edited["module"] != first["module"]  # a new model text, hence a new compiled model
    assert edited["misses"] >= 1 and edited["hits"] == 0
    # ... while what did not change is not compiled again: the library (baseline) loads from the cache
    assert first["lib_misses"] >= 1 and first["lib_hits"] == 0
    assert edited["lib_module"] == first["lib_module"] != edited["module"]
    assert edited["lib_misses"] == 0 and edited["lib_hits"] >= 1
    # no stale code: the edited law runs (the spring's share of the crank's acceleration doubles)
    assert edited["alpha"] != first["alpha"]


@pytest.mark.slow  # compiles the inlined build too (about a minute on a quiet core)
def test_both_builds_give_the_same_numbers():
    """The quick-compile and the inlined build run the same arithmetic: bit for bit the same run."""
    import numpy as np

    from ehas_env.simulation.compiled_model import current_model
    from ehas_env.simulation.plant import Plant, RigController

    plant = Plant(disc_sets=5)
    quick = plant.simulate_closed_loop(RigController.book(), amplitude_deg=20, freq_hz=2, cycles=3)
    plant._model = current_model(inline=True)
    fast = plant.simulate_closed_loop(RigController.book(), amplitude_deg=20, freq_hz=2, cycles=3)
    assert plant.model is not Plant(disc_sets=5).model
    np.testing.assert_array_equal(quick.theta_deg, fast.theta_deg)
    np.testing.assert_array_equal(quick.current_mA, fast.current_mA)


def test_the_compile_estimate_learns_this_machines_compile_times(tmp_path, monkeypatch):
    """The message a first compile prints estimates its time from the machine's own record of its last compiles of
    that build (their median), else from the table measured once (COMPILE_CPU_S); the record keeps the last 5, a
    model's compile that goes on in another function replaces its figure, and a record that cannot be read is the
    table again (a state effect's model took 37 CPU s where the table says 9)."""
    from ehas_env.physics import codegen

    monkeypatch.setenv("EHAS_CACHE_DIR", str(tmp_path))
    build = "quick, library cached"
    assert codegen.quiet_compile_s(build) == codegen.COMPILE_CPU_S[build]
    for s in (30.0, 10.0, 20.0):
        codegen.record_compile_s(build, s)
    assert codegen.quiet_compile_s(build) == 20.0
    codegen.record_compile_s(build, 40.0, new=False)  # the last compile went on: 20 -> 40
    assert codegen.quiet_compile_s(build) == 30.0  # 30, 10, 40
    for s in (50.0, 60.0, 70.0):
        codegen.record_compile_s(build, s)
    doc = json.loads((tmp_path / codegen.COMPILE_RECORD).read_text())
    assert doc[build] == [10.0, 40.0, 50.0, 60.0, 70.0]  # the last COMPILE_KEPT = 5
    assert codegen.quiet_compile_s(build) == 50.0
    assert codegen.compile_estimate_s(build) == pytest.approx(codegen.quiet_compile_s(build) * codegen.load_scale())
    assert codegen.quiet_compile_s("quick") == codegen.COMPILE_CPU_S["quick"]  # another build: its own record
    (tmp_path / codegen.COMPILE_RECORD).write_text("not json")
    assert codegen.quiet_compile_s(build) == codegen.COMPILE_CPU_S[build]
    codegen.record_compile_s(build, 12.0)  # a broken record is started again
    assert codegen.quiet_compile_s(build) == 12.0
    # a compile of known size: the size times the rate per kilobyte, the table's until this machine has its own
    assert codegen.quiet_compile_s(build, kb=200.0) == pytest.approx(200.0 * codegen.COMPILE_CPU_S_PER_KB[build])
    for r in (0.2, 0.05, 0.1):
        codegen.record_compile_s(build + codegen.PER_KB, r)
    assert codegen.quiet_compile_s(build, kb=200.0) == pytest.approx(20.0)
    assert codegen.quiet_compile_s(build) == 12.0  # the seconds' record is its own
    assert codegen.quiet_compile_s("inline", kb=200.0) == codegen.COMPILE_CPU_S["inline"]  # no rate: its seconds


PART_PROBE = textwrap.dedent("""
    import numpy as np
    from ehas_env.simulation.plant import Plant
    m = Plant(disc_sets=3).model
    m.reference_series(np.array([10.0, 1.0, 0.0, 0.5]), np.linspace(0.0, 1.0, 5))  # a part: the reference alone
    print("part done", flush=True)
    s = Plant(disc_sets=3).initial_state().copy()
    m.derivatives(s, 0.0, Plant(disc_sets=3).param_vector, np.zeros(m.N_STATES))  # the whole right-hand side
""")


def test_a_part_of_a_new_model_compiles_unannounced_and_unrecorded_the_whole_model_announced(tmp_path):
    """A diagnosis' replays run on the C drivers, so numba compiles only small parts of its models (a reference
    series, a sensor chain read in Python): a compile whose first function is not the right-hand side or one
    that calls it (codegen.WHOLE_MODEL) is neither announced with the whole model's estimate nor recorded as one
    (it was: "about 23 s" for a compile of 0.3 s, and a per-kilobyte rate 20 times too small kept for the next
    estimate); the whole model's compile after it still is."""
    from ehas_env.physics import codegen

    env = {**os.environ, "EHAS_CACHE_DIR": str(tmp_path / "models"), "EHAS_QUIET_COMPILE": "0"}
    out = subprocess.run([sys.executable, "-c", PART_PROBE], capture_output=True, text=True, env=env, check=True)
    assert "part done" in out.stdout
    said = [ln for ln in out.stderr.splitlines() if ln.startswith("ehas: compiling the simulator")]
    assert len(said) == 1 and "(quick build, derivatives;" in said[0], out.stderr
    record = json.loads((tmp_path / "models" / codegen.COMPILE_RECORD).read_text())
    assert len(record["quick"]) == 1  # the whole model's compile, once
