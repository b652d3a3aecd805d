"""A diagnosis' larger model compiles behind the library's rounds (issue 44: a diagnosis on an empty model cache).

A replay of a structural hypothesis or a block runs on the model of every registered effect and hypothesis, whose
first compile takes tens of seconds.  ``Replayer.compile_behind`` starts it in a background process on the other core
while the diagnosis replays the registered effects; a replay on it waits for that process and loads what it
compiled.  Truth: the same replay compiled in this process (bit for bit), and the argument packing's round trip.
"""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.physics import codegen
from ehas_env.physics.compile_behind import _pack_args, _unpack_args


def test_a_left_out_argument_goes_to_the_background_process_as_left_out():
    calls = [("closed_loop", (np.zeros(3), 2, 0.5, None)), ("closed_loop", (np.ones(2), 1, 0.25, np.ones(4)))]
    back = _unpack_args(np.load(_saved(_pack_args(calls)), allow_pickle=False))
    assert [e for e, _ in back] == ["closed_loop", "closed_loop"]
    first, second = back[0][1], back[1][1]
    assert first[3] is None and isinstance(second[3], np.ndarray)
    assert np.array_equal(first[0], np.zeros(3)) and first[1] == 2 and first[2] == 0.5


def _saved(arrays: dict):
    import io

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    buf.seek(0)
    return buf


def test_what_the_background_takes_off_the_compile_watcher_it_gives_back(monkeypatch):
    import types

    Model = types.ModuleType("ehas_model_test")  # a generated model of three files this process wrote, not compiled

    monkeypatch.setattr(codegen, "_FRESH", {"ehas_lib_test": ("quick", "ehas_model_test"),
                                            "ehas_fx_test": ("quick", "ehas_model_test"),
                                            "ehas_model_test": ("quick", "ehas_model_test"),
                                            "ehas_model_other": ("quick", "ehas_model_other")})
    taken = codegen.take_fresh(Model)
    assert taken[0] == "quick" and sorted(taken[2]) == ["ehas_fx_test", "ehas_lib_test", "ehas_model_test"]
    assert list(codegen._FRESH) == ["ehas_model_other"]  # another model's stay
    assert codegen.take_fresh(Model) is None  # nothing left to take
    codegen.put_fresh(Model, taken)
    assert codegen._FRESH["ehas_fx_test"] == ("quick", "ehas_model_test") and len(codegen._FRESH) == 4


@pytest.mark.slow
def test_a_replay_on_the_model_compiled_behind_is_the_one_compiled_here(tmp_path, monkeypatch):
    """Two empty model caches: in one the larger model compiles behind, in the other here; a replay of a
    structural hypothesis gives the same numbers bit for bit (about a minute: two compiles of the larger model)."""
    import subprocess
    import sys

    script = (
        "import sys, numpy as np\n"
        "from ehas_env.measurement.campaign import Campaign, validate_run\n"
        "from ehas_env.measurement.replay import Replayer, ModelSpec\n"
        "from ehas_env.measurement.synthetic import simulate_campaign\n"
        "runs, _ = simulate_campaign({'coulomb_friction': {'Fc': 400.0}}, seed=5, perturb=True, duration=1.0,\n"
        "                            plan=((3, 20.0, 1.0), (5, 25.0, 2.0)))\n"
        "rep = Replayer(Campaign(None, [validate_run(*r) for r in runs]), hypotheses=True)\n"
        "rep.simulate(ModelSpec())\n"
        "print('behind', rep.compile_behind(), flush=True)\n"
        "sims = rep.simulate(ModelSpec(effects={'hyp_coil_lag': {'T': 2.0}}))\n"
        "np.save(sys.argv[1], np.concatenate([v for s in sims if s is not None for k, v in sorted(s.items())]))\n")
    out = {}
    for way in ("behind", "here"):
        # (numba's drivers: the C compiler's build of them leaves nothing to compile behind)
        env = {**__import__("os").environ, "EHAS_CACHE_DIR": str(tmp_path / way), "EHAS_DRIVERS": "numba",
               "EHAS_COMPILE_BEHIND": "1" if way == "behind" else "0"}
        r = subprocess.run([sys.executable, "-c", script, str(tmp_path / f"{way}.npy")], env=env,
                           capture_output=True, text=True, timeout=900)
        assert r.returncode == 0, r.stderr[-2000:]
        assert f"behind {way == 'behind'}" in r.stdout
        if way == "behind":
            assert "switched to the model with the structural hypotheses and blocks" in r.stderr
        out[way] = np.load(tmp_path / f"{way}.npy")
    assert np.array_equal(out["behind"], out["here"])
