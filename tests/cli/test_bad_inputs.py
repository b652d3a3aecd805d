"""Issue 14: every bad input is one clear line (culprit + what is allowed), status != 0, no traceback;
nothing written before the checks; interrupted runs leave the previous complete output; Ctrl-C is 130.

The numeric options are walked from the parser itself, so a new option is covered (and an option
declared with a bare ``type=int``/``float`` fails :func:`test_every_numeric_option_has_a_range`).
"""
from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ehas_env.cli import main as cli
from ehas_env.ranges import Number, numeric_actions

# the arguments each command needs before its options are even looked at
REQUIRED = {
    "excite": ["chirp"],
    "tune": ["--method", "model"],
    "simulate-campaign": ["--out", "unused_campaign"],
    "compare": ["no_such_campaign"],
    "diagnose": ["no_such_campaign"],
    "train": ["--out", "unused_train"],
}


def _subparsers():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return sub.choices


SUBPARSERS = _subparsers()
NUMERIC = [(cmd, opt) for cmd, p in SUBPARSERS.items() for opt, _ in numeric_actions(p)]
BAD_NUMBERS = ["nan", "inf", "-inf", "1e308", "-1e308", "abc", ""]


def run_cli(argv, capsys):
    """(status, stdout, stderr lines) of ``ehas ARGV``, argparse's exits included."""
    try:
        rc = cli.main(list(argv))
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    return rc, out, [ln for ln in err.splitlines() if ln.strip()]


def assert_one_line(rc, err, command, *words):
    assert rc not in (0, None), err
    assert len(err) == 1, err
    assert err[0].startswith(f"ehas {command}:") or err[0].startswith("ehas:"), err
    assert "Traceback" not in err[0]
    for w in words:
        assert w in err[0], (w, err[0])


# -- numbers -----------------------------------------------------------------------------------------------
def test_every_numeric_option_has_a_range():
    """No command declares a number without ehas_env.ranges (type, unit, range in one place)."""
    bare = [(cmd, a.option_strings) for cmd, p in SUBPARSERS.items() for a in p._actions
            if a.type in (int, float)]
    assert not bare, f"numeric options without a range (use ehas_env.ranges.number): {bare}"
    assert len(NUMERIC) >= 40


@pytest.mark.parametrize("value", BAD_NUMBERS)
@pytest.mark.parametrize("command, opt", NUMERIC)
def test_bad_number_is_one_clear_line(command, opt, value, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, out, err = run_cli([command, *REQUIRED.get(command, []), f"{opt}={value}"], capsys)
    assert rc == 2
    assert_one_line(rc, err, command, opt)
    assert "must be" in err[0] and "got" in err[0]  # what is allowed, and what was given
    assert not list(tmp_path.iterdir())  # nothing written


@pytest.mark.parametrize("command, opt", NUMERIC)
def test_each_range_is_finite_and_names_its_bounds(command, opt):
    action = dict(numeric_actions(SUBPARSERS[command]))[opt]
    r = action.type.range
    assert r.lo > -1e12 and r.hi < 1e12 + 1, (command, opt, r)
    if action.default is not None:  # the default itself is allowed
        r.check(action.default, opt)


@pytest.mark.parametrize("argv, words", [
    (["simulate", "--cycles", "1e308"], "--cycles"),
    (["simulate", "--cycles", "4", "--freq", "0.001"], "at most 600 s"),
    (["simulate", "--gains", "Kp=1e308"], "--gains Kp"),
    (["simulate", "--gains", "Kp=nan"], "--gains Kp"),
    (["simulate", "--disc-sets", "3.5"], "--disc-sets"),
    (["excite", "prms", "--levels", "1e12"], "--levels"),
    (["excite", "chirp", "--duration", "3600", "--rate", "100000"], "samples"),
    (["size", "--area", "1e308"], "--area"),
    (["tune", "--method", "model", "--gain-margin", "-1"], "--gain-margin"),
    (["tune", "--method", "model", "--bandwidth", "-1"], "--bandwidth"),
    (["tune", "--method", "model", "--pi-lag", "-1"], "--pi-lag"),
    (["bench", "--workers", "0"], "--workers"),
    (["bench", "--workers", "-1"], "--workers"),
    (["identify", "--num", "1", "--den", "0"], "--den"),
    (["identify", "--num", "1", "--den", "1,inf"], "--den"),
    (["identify", "run.csv", "--poles", "2", "--zeros", "2"], "--zeros"),
    (["curves", "--supplies", "70,1e308"], "--supplies"),
    (["perf", "--sizes", "1,1e12"], "--sizes"),
    (["train", "--algo", "sac", "--max-minutes", "-1", "--out", "t"], "--max-minutes"),
    (["train", "--algo", "sac", "--max-minutes", "nan", "--out", "t"], "--max-minutes"),
    (["nope"], "invalid choice"),
    (["simulate", "--no-such-option"], "unrecognized"),
    # lists: an empty item is a typo, not "skip"; a name given twice is refused (split_list)
    (["simulate", "--gains", ","], "--gains: expected comma-separated"),
    (["simulate", "--gains", "Kp=1,Kp=2"], "--gains: Kp is given twice"),
    (["simulate", "--gains", "Kp"], "'Kp' is not NAME=VALUE"),
    (["curves", "--supplies", "70,,220"], "--supplies: empty item"),
    (["perf", "--sizes", "1,,2"], "--sizes: empty item"),
    (["identify", "--num", "1,,2", "--den", "1,2"], "--num: empty item"),
    (["diagnose", "no_such_campaign", "--candidates", ","], "--candidates: expected comma-separated"),
    (["diagnose", "no_such_campaign", "--candidates", "coulomb_friction,coulomb_friction"], "given twice"),
    (["diagnose", "no_such_campaign", "--candidates", ""], "--candidates: the value is empty"),
    (["diagnose", "no_such_campaign", "--holdout", "a,,b"], "--holdout: empty item"),
    (["compare", "no_such_campaign", "--columns", "theta_deg=a,,t=b"], "--columns: empty item"),
    (["simulate", "--effects", "coulomb_friction,,viscous_friction"], "effects spec: empty item"),
    (["model", "show", ""], "FILE: the path is empty"),
    (["model", "new", "m.json", "--from", ""], "--from: the path is empty"),
    (["model", "diff", "a.json", ""], "B: the path is empty"),
    (["excite", "prbs", "--duration", "1", "--hold", "30"], "hold = 30 s leaves 1 clock period"),
    (["excite", "multisine", "--duration", "1", "--lines", "100000"], "only 40 frequency lines"),
])
def test_examples_of_the_issue(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, _, err = run_cli(argv, capsys)
    assert_one_line(rc, err, argv[0], words)
    assert not [p for p in tmp_path.iterdir()]


# -- output paths ---------------------------------------------------------------------------------------------
#: command -> argv writing into OUT (cheap commands; the checks come before any work)
WRITERS = {
    "simulate": ["simulate", "--out", "{out}/run"],
    "excite": ["excite", "chirp", "--out", "{out}/sig"],
    "simulate-campaign": ["simulate-campaign", "--out", "{out}"],
    "curves": ["curves", "--out", "{out}"],
    "compare": ["compare", "no_such_campaign", "--out", "{out}"],
    "diagnose": ["diagnose", "no_such_campaign", "--out", "{out}"],
    "identify": ["identify", "no_such_run.csv", "--out", "{out}"],
    "tune": ["tune", "--method", "model", "--out", "{out}/c.json"],
    "bench": ["bench", "--out", "{out}"],
    "perf": ["perf", "--out", "{out}"],
    "demo": ["demo", "--out", "{out}"],
    "train": ["train", "--algo", "ppo", "--config", "CONFIG", "--out", "{out}"],
}


def _argv(command, out, tmp_path):
    argv = [a.replace("{out}", str(out)) for a in WRITERS[command]]
    if "CONFIG" in argv:
        from ehas_train.config import bundled_config

        argv[argv.index("CONFIG")] = str(bundled_config("ppo_smoke"))
    return argv


@pytest.mark.parametrize("command", sorted(WRITERS))
def test_output_under_a_file_is_refused_first(command, capsys, tmp_path):
    (tmp_path / "afile").write_text("keep me")
    rc, _, err = run_cli(_argv(command, tmp_path / "afile" / "sub", tmp_path), capsys)
    assert_one_line(rc, err, command, "afile")
    assert (tmp_path / "afile").read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.parametrize("command", sorted(WRITERS))
def test_unwritable_output_folder_is_refused_first(command, capsys, tmp_path, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    real_mkdir = os.mkdir

    def mkdir(path, *a, **k):  # a read-only folder, also when the tests run as root
        if str(path).startswith(str(ro)):
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return real_mkdir(path, *a, **k)

    monkeypatch.setattr(os, "mkdir", mkdir)
    rc, _, err = run_cli(_argv(command, ro / "out", tmp_path), capsys)
    assert_one_line(rc, err, command, str(ro))
    assert "Permission denied" in err[0] or "permission denied" in err[0]
    assert list(ro.iterdir()) == []


@pytest.mark.parametrize("command", ["simulate-campaign", "curves", "compare", "diagnose", "identify", "demo", "train"])
def test_existing_file_where_a_folder_is_expected(command, capsys, tmp_path):
    f = tmp_path / "out"
    f.write_text("keep me")
    rc, _, err = run_cli(_argv(command, f, tmp_path), capsys)
    assert_one_line(rc, err, command, str(f))
    assert f.read_text() == "keep me"


@pytest.mark.parametrize("command", ["simulate-campaign", "curves", "compare", "diagnose", "identify", "train"])
def test_earlier_output_needs_overwrite(command, capsys, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "earlier.txt").write_text("earlier run")
    rc, _, err = run_cli(_argv(command, out, tmp_path), capsys)
    assert_one_line(rc, err, command, str(out))
    assert "--overwrite" in err[0] or "--resume" in err[0]
    assert (out / "earlier.txt").read_text() == "earlier run"


@pytest.mark.parametrize("command, existing", [("simulate", "run.csv"), ("excite", "sig.json"), ("tune", "c.json"),
                                               ("bench", "benchmark.md"), ("perf", "perf.json")])
def test_earlier_member_of_a_shared_folder_needs_overwrite(command, existing, capsys, tmp_path):
    (tmp_path / existing).write_text("earlier")
    rc, _, err = run_cli(_argv(command, tmp_path, tmp_path), capsys)
    assert_one_line(rc, err, command, existing, "--overwrite")
    assert (tmp_path / existing).read_text() == "earlier"


@pytest.mark.parametrize("argv, culprit", [
    (["diagnose", "c", "--json", "{tmp}"], "--json"),
    (["identify", "--num", "1", "--den", "1,1", "--json", "{tmp}"], "--json"),
    (["compare", "c", "--save-model", "{tmp}"], "--save-model"),
    (["tune", "--method", "model", "--out", "{tmp}/x.txt"], ".json"),
    (["tune", "--method", "model", "--out", "{tmp}/c.json", "--bode", "{tmp}"], "--bode"),
])
def test_folder_where_a_file_is_expected(argv, culprit, capsys, tmp_path):
    rc, _, err = run_cli([a.replace("{tmp}", str(tmp_path)) for a in argv], capsys)
    assert_one_line(rc, err, argv[0], culprit)


def test_a_missing_campaign_is_named(capsys, tmp_path):
    rc, _, err = run_cli(["compare", str(tmp_path / "nope")], capsys)
    assert_one_line(rc, err, "compare", "nope")


# -- files from elsewhere ----------------------------------------------------------------------------------
def _controller(**over):
    d = {"format": "ehas-controller", "version": 1, "type": "piff", "name": "c",
         "gains": {"Kp": 1.0, "Ki": 2.0, "Kv": 0.0178, "Ka": 0.0002}}
    d.update(over)
    return {k: v for k, v in d.items() if v is not None}


@pytest.mark.parametrize("doc, words", [
    (_controller(format=None), "no 'format'"),
    (_controller(format="ehas-model"), "'format'"),
    (_controller(version=None), "'version'"),
    (_controller(version=2), "'version' = 2"),
    (_controller(type=None), "no 'type'"),
    (_controller(type="rocket"), "rocket"),
    ([1, 2], "JSON object"),
    ("{broken", "not valid JSON"),
])
def test_controller_file_is_checked(doc, words, capsys, tmp_path):
    f = tmp_path / "ctrl.json"
    f.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    rc, _, err = run_cli(["bench", str(f), "--out", str(tmp_path / "b"), "--no-progress"], capsys)
    assert_one_line(rc, err, "bench", "ctrl.json", words)
    assert rc == 2 and not (tmp_path / "b").exists()


@pytest.mark.parametrize("doc, words", [
    ({"format": "ehas-controller", "version": 1}, "not an ehas model file"),
    ({"format": "ehas-model", "version": 7}, "'version'"),
    ({"format": "ehas-model", "version": 1, "baseline": {"beta_Pa": 1e308}}, "beta_Pa"),
    ({"format": "ehas-model", "version": 1, "effects": {"stribeck_friction": {"Fc": 300, "Fs": 100}}}, "Fs"),
])
def test_model_file_is_checked(doc, words, capsys, tmp_path):
    f = tmp_path / "model.json"
    f.write_text(json.dumps(doc))
    rc, _, err = run_cli(["bench", "--model", str(f), "--out", str(tmp_path / "b")], capsys)
    assert_one_line(rc, err, "bench", "model.json", words)


def test_stribeck_breakaway_below_sliding_is_refused(capsys, tmp_path):
    from ehas_env.physics.effects import resolve_effects

    with pytest.raises(ValueError, match=r"Fs = 100 N must be at least the sliding force Fc = 200 N"):
        resolve_effects({"stribeck_friction": {"Fc": 200, "Fs": 100}})
    resolve_effects({"stribeck_friction": {"Fc": 200, "Fs": 200}})  # equal: Coulomb friction
    rc, _, err = run_cli(["simulate-campaign", "--effects", "stribeck_friction:Fc=200,Fs=100",
                          "--out", str(tmp_path / "c")], capsys)
    assert_one_line(rc, err, "simulate-campaign", "Fs")
    assert not (tmp_path / "c").exists()


TOML = '[train]\nalgo = "ppo"\ntotal_steps = 100\nn_envs = 1\n'


@pytest.mark.parametrize("extra, words", [
    ('[env.kwargs]\nfreq_hz = "1"\n', "[env.kwargs] freq_hz"),
    ("[env.kwargs]\ndisc_sets = 9\n", "[env.kwargs] disc_sets"),
    ("[env.kwargs]\ncycles = 1e308\n", "[env.kwargs] cycles"),
    ("[env.kwargs]\namplitude_deg = nan\n", "[env.kwargs] amplitude_deg"),
    ("[algo]\ngamma = 2\n", "[algo] gamma"),
    ("[algo]\nlearning_rate = inf\n", "[algo] learning_rate"),
    ("[algo]\nn_steps = nan\n", "[algo] n_steps"),
    ("[algo]\ngae_lambda = 5\n", "[algo] gae_lambda must be a number in [0, 1]"),
    ("[algo]\nn_epochs = 0\n", "[algo] n_epochs must be an integer in [1, 10000]"),
    ("[algo]\nbatch_size = 1e9\n", "[algo] batch_size must be an integer"),
    ("[algo]\nn_steps = 16\nbatch_size = 64\n", "batch_size 64 is larger than the rollout (n_steps 16 x n_envs 1"),
    ("[randomise]\ndisc_sets = 9\n", "[randomise] disc_sets"),
    ("[randomise]\nfreq_hz = [1.0, 1e308]\n", "[randomise] freq_hz"),
    ('[randomise.effects]\nstribeck_friction = "typical"\n', "stribeck_friction"),
    ("[env]\naction_scale_mA = 30.0\n", "[env] action_scale_mA"),
    ("[env]\naction_repeat = 0\n", "[env] action_repeat"),
])
def test_training_config_is_validated_before_the_folder(extra, words, capsys, tmp_path):
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(TOML + extra)
    out = tmp_path / "run"
    rc, _, err = run_cli(["train", "--algo", "ppo", "--config", str(cfg), "--out", str(out), "--no-progress"], capsys)
    assert_one_line(rc, err, "train", "cfg.toml", words)
    assert not out.exists()  # a failed start leaves nothing behind


@pytest.mark.parametrize("key, value", [("total_steps", "1e308"), ("total_steps", "0"), ("seed", "-1"),
                                        ("n_envs", "0"), ("n_envs", "1.5"), ("clip_obs", "inf"),
                                        ("eval_episodes", '"3"'), ("log_interval_s", "-1")])
def test_training_config_train_section_ranges(key, value, tmp_path):
    from ehas_train.config import parse_config
    import tomllib

    raw = tomllib.loads(f'[train]\nalgo = "sac"\n{key} = {value}\n')
    with pytest.raises(ValueError, match=rf"x.toml: \[train\] {key} must be (an integer|a number) in"):
        parse_config(raw, source="x.toml")


# -- interrupts, pipes, unexpected errors -----------------------------------------------------------------
def _fake_run(exc):
    def run(args):
        print("some output")
        raise exc
    return run


def test_ctrl_c_is_one_line_and_130(capsys, monkeypatch):
    import ehas_env.cli.effects as mod

    monkeypatch.setattr(mod, "run", _fake_run(KeyboardInterrupt()))
    rc, _, err = run_cli(["effects"], capsys)
    assert rc == 130 and err == ["ehas effects: interrupted"]


def test_unexpected_error_is_one_line_with_a_hint(capsys, monkeypatch):
    import ehas_env.cli.effects as mod

    monkeypatch.setattr(mod, "run", _fake_run(ZeroDivisionError("division by zero")))
    monkeypatch.delenv("EHAS_DEBUG", raising=False)
    rc, _, err = run_cli(["effects"], capsys)
    assert rc == 1 and len(err) == 1 and "ZeroDivisionError" in err[0] and "EHAS_DEBUG=1" in err[0]
    monkeypatch.setenv("EHAS_DEBUG", "1")
    rc, _, err = run_cli(["effects"], capsys)
    assert rc == 1 and any("Traceback" in ln for ln in err)


def test_os_error_names_the_path(capsys, monkeypatch, tmp_path):
    import ehas_env.cli.effects as mod

    target = tmp_path / "full" / "x.csv"

    def run(args):
        from ehas_env.output.files import atomic_write_text

        def fsync(fd):
            raise OSError(errno.ENOSPC, "No space left on device")

        monkeypatch.setattr("ehas_env.output.files.os.fsync", fsync)
        atomic_write_text(target, "data")

    monkeypatch.setattr(mod, "run", run)
    rc, _, err = run_cli(["effects"], capsys)
    assert rc == 1 and err == [f"ehas effects: error: {target}: No space left on device"]
    assert [p.name for p in target.parent.iterdir()] == []  # no stray temporary file


def test_broken_pipe_is_quiet():
    """``ehas size | head -1``: the reader goes away; no traceback, no message."""
    proc = subprocess.run(f"{sys.executable} -m ehas_env.cli.main size | head -1", shell=True, capture_output=True,
                          text=True, timeout=120)
    assert proc.stdout.count("\n") == 1
    assert proc.stderr == ""


def test_broken_pipe_in_a_command(capsys, monkeypatch):
    import ehas_env.cli.effects as mod

    monkeypatch.setattr(mod, "run", _fake_run(BrokenPipeError(errno.EPIPE, "Broken pipe")))
    monkeypatch.setattr(os, "dup2", lambda *a: None)  # keep pytest's stdout
    rc, _, err = run_cli(["effects"], capsys)
    assert rc == 141 and err == []


@pytest.mark.parametrize("argv, culprit", [
    (["simulate", "--model", "", "--out", "{tmp}/x"], "--model: the value is empty"),
    (["effects", ""], "name: the value is empty"),
    (["bench", ""], "CONTROLLER_FILE: the value is empty"),
    (["simulate", "--model", "{tmp}", "--out", "{tmp}/x"], "is a folder; expected a model JSON file"),
])
def test_an_empty_value_or_a_folder_for_a_file_is_refused(tmp_path, capsys, argv, culprit):
    """'' was read as "not given" (or as the current folder); a folder given as a model file "did not exist"."""
    from ehas_env.cli.main import main as ehas_main

    assert ehas_main([a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and culprit in err, err
    assert not (tmp_path / "x").exists()
