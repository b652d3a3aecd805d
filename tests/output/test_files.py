"""The checked file reader (ehas_env.output.files.read_text / read_json) and every reader that uses it (issue 14).

A file that is not UTF-8 text (binary data, UTF-16), a folder given for a file, a missing file: one line
naming the file and what it should be, status 2 through the command line, no traceback.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ehas_env.cli.main import main
from ehas_env.output.files import read_json, read_text
from refusals import refused  # tests/ is on sys.path (conftest.py)

ROOT = Path(__file__).resolve().parents[2]
BINARY = bytes(range(128)).replace(b"\0", b" ") + b"\x80\x81\xfe" + bytes(range(200, 256))  # a 0x80 at offset 128


def test_utf8_text_is_read_and_a_byte_order_mark_dropped(tmp_path):
    f = tmp_path / "x.json"
    f.write_bytes(b"\xef\xbb\xbf" + '{"a": "\u00e9"}'.encode())
    assert read_text(f, "a test file") == '{"a": "\u00e9"}'
    assert read_json(f, "a test file") == {"a": "\u00e9"}


@pytest.mark.parametrize("content, words", [
    (BINARY, ["not a UTF-8 text file (byte 0x80 at offset 128)", "expected a test file"]),
    ('{"a": 1}'.encode("utf-16"), ["UTF-16 text", "save it as UTF-8", "a test file"]),
    (b'{"a": 1}\0\0\0', ["not a UTF-8 text file (a NUL byte at offset 8: binary data)"]),
])
def test_not_utf8_text_names_the_file(tmp_path, content, words):
    f = tmp_path / "x.json"
    f.write_bytes(content)
    refused(lambda: read_text(f, "a test file"), str(f), *words)


def test_paths_that_are_not_a_file(tmp_path, monkeypatch):
    refused(lambda: read_text(tmp_path, "a test file"), str(tmp_path), "is a folder; expected a test file")
    refused(lambda: read_text(tmp_path / "nope.json", "a test file"), "nope.json", "does not exist",
            exc=FileNotFoundError)
    refused(lambda: read_text(tmp_path / "nope.json" / "x", "a test file"), "does not exist", exc=FileNotFoundError)
    refused(lambda: read_text("", "a test file"), "the path is empty; expected a test file")
    refused(lambda: read_text("/dev/null", "a test file"), "/dev/null: not a regular file")
    big = tmp_path / "big.txt"
    big.write_text("x" * 100)
    refused(lambda: read_text(big, "a test file", max_bytes=10), "big.txt: 100 bytes, more than the 10")
    f = tmp_path / "locked.json"
    f.write_text("{}")
    real = Path.read_bytes

    def read_bytes(self):
        if self.name == f.name:
            raise PermissionError(13, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", read_bytes)
    refused(lambda: read_text(f, "a test file"), "locked.json: cannot be read (permission denied)")


def test_invalid_json_names_line_and_column(tmp_path):
    f = tmp_path / "x.json"
    f.write_text('{\n "a": }')
    refused(lambda: read_json(f, "a test file"), "x.json: not valid JSON at line 2 column 7", "a test file")


def test_a_named_pipe_is_read(tmp_path):
    fifo = tmp_path / "p"
    os.mkfifo(fifo)
    pid = os.fork()
    if pid == 0:  # the writer
        try:
            with open(fifo, "w") as fh:
                fh.write('{"a": 1}')
        finally:
            os._exit(0)
    try:
        assert read_json(fifo, "a test file") == {"a": 1}
    finally:
        os.waitpid(pid, 0)


# -- every reader through the command line -------------------------------------------------------------------
def _agent(tmp):
    folder = tmp / "agent"
    shutil.copytree(ROOT / "results" / "agents" / "ppo", folder)
    (folder / "config.json").write_bytes(BINARY)
    return folder


def _campaign(tmp):
    camp = tmp / "camp"
    camp.mkdir()
    (camp / "r1.csv").write_bytes(BINARY)
    (camp / "r1.json").write_text("{}")
    return camp


# (argv with {f}: the file, what to set it up as, the file the error names)
READERS = {
    "simulate --controller": (["simulate", "--cycles", "3", "--controller", "{f}", "--out", "{tmp}/o/run"], "c.json"),
    "bench": (["bench", "{f}", "--no-robustness", "--no-book", "--no-progress", "--out", "{tmp}/o"], "c.json"),
    "tune --start": (["tune", "--method", "optimize", "--max-evals", "2", "--no-progress", "--out", "{tmp}/o/c.json",
                      "--start", "{f}"], "c.json"),
    "identify": (["identify", "{f}", "--no-plots", "--out", "{tmp}/o"], "run.csv"),
    "train --config": (["train", "--algo", "ppo", "--total-steps", "10", "--no-progress", "--no-tensorboard",
                        "--out", "{tmp}/o", "--config", "{f}"], "cfg.toml"),
    "train --config --resume": (["train", "--algo", "ppo", "--total-steps", "10", "--no-progress",
                                 "--no-tensorboard", "--out", "{tmp}/o", "--config", "{f}", "--resume"], "cfg.toml"),
    "--model": (["simulate", "--cycles", "3", "--model", "{f}", "--out", "{tmp}/o/run"], "m.json"),
    "compare (a run CSV)": (["compare", "{f}", "--out", "{tmp}/o"], "camp"),
    "agent config.json": (["simulate", "--cycles", "3", "--controller", "{f}", "--out", "{tmp}/o/run"], "agent"),
}


@pytest.mark.parametrize("reader", list(READERS))
def test_every_reader_refuses_a_binary_file_naming_it(reader, tmp_path, capsys):
    argv, name = READERS[reader]
    if name == "agent":
        f, named = _agent(tmp_path), "agent/config.json"
    elif name == "camp":
        f, named = _campaign(tmp_path), "r1.csv"
    else:
        f = named = tmp_path / name
        f.write_bytes(BINARY)
    rc = main([a.replace("{f}", str(f)).replace("{tmp}", str(tmp_path)) for a in argv])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(err) == 1 and err[0].startswith(f"ehas {argv[0]}: error: "), err
    assert str(named) in err[0] and "not a UTF-8 text file (byte 0x80 at offset 128); expected" in err[0], err
    assert not (tmp_path / "o").exists()


def test_train_config_folder_is_called_a_folder(tmp_path, capsys):
    rc = main(["train", "--algo", "ppo", "--config", str(tmp_path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert f"{tmp_path}: is a folder; expected a training config (a TOML file" in err[0], err
    assert "does not exist" not in err[0]


def test_cli_subprocess_utf16_controller_file(tmp_path):
    """The whole command line in its own process: status 2, one stderr line naming the file, no traceback."""
    f = tmp_path / "c.json"
    doc = json.loads((ROOT / "results" / "controllers" / "model.json").read_text())
    f.write_bytes(json.dumps(doc).encode("utf-16"))
    proc = subprocess.run([sys.executable, "-m", "ehas_env.cli.main", "bench", str(f), "--no-robustness",
                           "--no-book", "--no-progress", "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith(f"ehas bench: error: {f}: UTF-16 text"), proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "o").exists()


def test_written_files_get_the_mode_of_any_new_file(tmp_path):
    """An output is as readable as a file the user makes by hand (umask), not private as mkstemp makes it."""
    import os

    from ehas_env.output.files import atomic_write_text

    old = os.umask(0o022)
    try:
        out = atomic_write_text(tmp_path / "a.json", "{}")
        assert (out.stat().st_mode & 0o777) == 0o644
        os.umask(0o077)
        out = atomic_write_text(tmp_path / "b.json", "{}")
        assert (out.stat().st_mode & 0o777) == 0o600
    finally:
        os.umask(old)
