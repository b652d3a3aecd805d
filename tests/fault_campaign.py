#!/usr/bin/env python
"""Fault campaign of the ``ehas`` command line and Python API (issue 14).

A standalone script, not a pytest module (it defines no tests and no doctest
examples)::

    python tests/fault_campaign.py --out results/fault_campaign [--overwrite] [--jobs 2]

It runs several hundred cases of bad input, faults, interrupts and
determinism checks against every ``ehas`` subcommand, each as a subprocess
(``python -m ehas_env.cli.main ...``) in its own temporary folder, and classifies
each outcome automatically:

=================  ==============================================================
``refused``        status != 0, one line on stderr (progress lines and warnings
                   excluded) holding "error:" and naming the culprit
``ok``             status 0 where the input is valid (or an unusual but valid
                   one), or a pipe / interrupt / repeated run handled well
``skipped``        not run here (permission cases as root)
``traceback``      "Traceback (most recent call last)" or "internal error" on
                   stderr (API cases: an exception type no user error raises)
``silent``         status 0 for nonsense input (the case expects a refusal)
``unclear``        refused, but the last line does not name the culprit, or
                   holds no "error:", or stderr has several lines
``refused_valid``  a clear refusal of a valid input
``leftover``       refused, but files were written, or hidden temporaries left
``lost``           an earlier output (or a user's own file) changed or vanished
``mixed``          after an interrupted overwrite: files of two runs in one
                   output folder, or temporaries left beside it
``nondeterministic`` the same command twice gave different files
``timeout``        the subprocess ran longer than 120 s
=================  ==============================================================

The cases are generated from the argparse parser (every numeric option gets
NaN, inf, -inf, -1, 0, 1e308, 1e-308, abc, 1,5 and a huge integer; every choice
option an unknown choice), from tables of path options (inputs and outputs),
and from corrupted copies of valid files (controller JSON, model JSON, campaign
folders, training TOML, effect files, agent folders) that the script makes
first with the smallest options the commands allow.
"""
from __future__ import annotations

import argparse
import csv
import datetime as _dt
import hashlib
import io
import json
import math
import os
import platform
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from ehas_env.physics.effects.example_file import spring_effect

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT = 120.0
IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
TRACEBACK_MARKS = ("Traceback (most recent call last)", "internal error")
PIPE_MARKS = ("Traceback", "BrokenPipeError", "Exception ignored")
BUG_CLASSES = ("traceback", "silent", "unclear", "refused_valid", "leftover", "lost", "mixed", "nondeterministic",
               "timeout", "ran_code")
MARKER = "MARKER"  # data that tries to run code writes this file into the case folder
GOOD_CLASSES = ("refused", "ok", "skipped")
TMP_MARK = re.compile(r"ehas-(tmp|old|done)")
RECORD = ".ehas-output.json"  # ehas_env.output.outputs.RECORD: part of a folder output, not a temporary


# -- the case ---------------------------------------------------------------------------------------
@dataclass
class Case:
    """One campaign case (argv after ``ehas``; ``{tmp}``, ``{fx}``, ``{root}`` are filled in at run time)."""

    family: str
    what: str
    argv: list
    expect: str = "refuse"  # refuse | accept | either | interrupt | same | quiet | api
    culprit: tuple = ()
    setup: Callable | None = None
    mode: str = "run"  # run | pipe_sh | pipe_closed | interrupt | twice | api
    protect: tuple = ()  # paths (relative to the case folder) that must stay byte-identical
    opts: dict = field(default_factory=dict)
    skip: str = ""
    forbid: tuple = ()  # words the refusal must not say (a folder "does not exist")
    id: str = ""


@dataclass
class Result:
    case: Case
    outcome: str
    status: object
    seconds: float
    last: str
    notes: str
    command: str


# -- small file helpers --------------------------------------------------------------------------------
def wtext(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


def wbytes(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)


GARBAGE = bytes(range(256)) * 4 + b"\x00\xff\xfe\x89PNG\r\n\x1a\n garbage"


def scaffold(tmp: Path) -> None:
    """Files every case folder holds: a plain file, an empty folder, empty and garbage files."""
    wtext(tmp / "plainfile", "just a file\n")
    (tmp / "afolder").mkdir(exist_ok=True)
    (tmp / "emptydir").mkdir(exist_ok=True)
    for suffix in (".json", ".csv", ".toml", ".py", ".zip"):
        wbytes(tmp / f"empty{suffix}", b"")
        wbytes(tmp / f"garbage{suffix}", GARBAGE)


def snapshot(path: Path) -> dict:
    """{relative path: sha256 (or 'DIR'/'LINK')} of everything under path (hidden files too; no __pycache__)."""
    out = {}
    if path.is_symlink() or path.is_file():
        return {".": _digest(path)}
    if not path.exists():
        return {}
    for p in sorted(path.rglob("*")):
        rel = p.relative_to(path)
        if "__pycache__" in rel.parts:
            continue
        out[str(rel)] = _digest(p)
    return out


def _digest(p: Path) -> str:
    if p.is_symlink():
        return "LINK:" + os.readlink(p)
    if p.is_dir():
        return "DIR"
    try:
        return hashlib.sha256(p.read_bytes()).hexdigest()
    except OSError as exc:
        return f"ERR:{exc.errno}"


def copytree(src: Path, dst: Path) -> None:
    shutil.copytree(src, dst, symlinks=True, dirs_exist_ok=True)


# -- the command --------------------------------------------------------------------------------------
def ehas_cmd() -> list[str]:
    """How to run ehas: ``python -m ehas_env.cli.main`` when it runs as a script, else the console script."""
    try:
        r = subprocess.run([sys.executable, "-m", "ehas_env.cli.main", "--version"], capture_output=True, text=True,
                           timeout=60)
        if r.returncode == 0 and r.stdout.startswith("ehas"):
            return [sys.executable, "-m", "ehas_env.cli.main"]
    except (OSError, subprocess.TimeoutExpired):
        pass
    exe = shutil.which("ehas")
    if exe is None:
        sys.exit("fault_campaign: error: neither `python -m ehas_env.cli.main` nor an `ehas` command runs")
    return [exe]


EHAS: list[str] = []
ENV: dict = {}


def child_env() -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("EHAS_DEBUG", "EHAS_EFFECTS_PATH")}
    env["MPLBACKEND"] = "Agg"
    env["PYTHONUNBUFFERED"] = "1"
    env.setdefault("OMP_NUM_THREADS", "1")
    env["EHAS_PLUGIN_TIMEOUT"] = "10"  # the plug-in import limit (default 30 s): the hang cases end sooner
    return env


def fill(arg, tmp: Path, fx: Path) -> str:
    return str(arg).replace("{tmp}", str(tmp)).replace("{fx}", str(fx)).replace("{root}", str(ROOT))


def shown(argv) -> str:
    """The command line as a user would type it ($CASE: the case's folder, $FX: the fixtures)."""
    return "ehas " + shlex.join(str(a) for a in argv).replace("{tmp}", "$CASE").replace("{fx}", "$FX").replace(
        "{root}/", "").replace("{root}", ".")


# -- stderr analysis ----------------------------------------------------------------------------------
TQDM = re.compile(r"\d+%\|")


def stderr_lines(err: str) -> list[str]:
    return [ln.strip() for ln in re.split(r"[\r\n]+", err) if ln.strip()]


def message_lines(err: str) -> tuple[list[str], int]:
    """(lines that count as messages, number of warning lines) - progress lines and tqdm bars dropped."""
    lines = stderr_lines(err)
    keep, warnings = [], 0
    for i, ln in enumerate(lines):
        last = i == len(lines) - 1
        if TQDM.search(ln) and not last:
            continue
        if ln.startswith("[") and not last:
            continue
        if ": warning:" in ln and not last:
            warnings += 1
            continue
        m = re.match(r"^ehas(?: [\w -]+?)?: (.*)$", ln)  # "ehas CMD: ..." or "ehas: compiling ..." status lines
        if m and not last and not re.match(r"(error|internal error|warning)\b", m.group(1)):
            continue  # a status line ("ehas perf: PPO training throughput ...")
        keep.append(ln)
    return keep, warnings


def has_traceback(err: str) -> bool:
    return any(m in err for m in TRACEBACK_MARKS)


def refusal_quality(err: str, culprit: tuple, forbid: tuple = ()) -> tuple[bool, str]:
    """(clear?, why not) of a refusal's stderr."""
    lines, _ = message_lines(err)
    if not lines:
        return False, "no message on stderr"
    last = lines[-1]
    why = []
    if len(lines) > 1:
        why.append(f"{len(lines)} message lines")
    if "error:" not in last:
        why.append("no 'error:'")
    if culprit and not any(culprit_found(c, last) for c in culprit):
        why.append("culprit " + " / ".join(repr(c) for c in culprit) + " not named")
    for f in forbid:
        if f.lower() in last.lower():
            why.append(f"says {f!r}, which is wrong")
    return not why, "; ".join(why)


def culprit_found(culprit: str, text: str) -> bool:
    """Is the culprit named? An option ``--x-y`` is also named by its own word ``x_y`` / ``x-y`` (``f1 = 600 Hz``)."""
    if culprit.startswith("="):  # exact words only
        return culprit[1:].lower() in text.lower()
    if culprit.lower() in text.lower():
        return True
    if culprit.startswith("--"):
        bare = culprit[2:]
        for name in {bare, bare.replace("-", "_"), bare.replace("-", " ")}:
            if re.search(r"(?<![\w-])" + re.escape(name) + r"(?![\w-])", text, flags=re.I):
                return True
    return False


def last_line(err: str) -> str:
    lines = stderr_lines(err)
    return lines[-1][:200] if lines else ""


def staging_leftovers(tmp: Path) -> list[str]:
    found = []
    for p in tmp.rglob("*"):
        if TMP_MARK.search(p.name):
            found.append(str(p.relative_to(tmp)))
    return found


def diff_snap(before: dict, after: dict) -> str:
    missing = [k for k in before if k not in after]
    changed = [k for k in before if k in after and after[k] != before[k]]
    new = [k for k in after if k not in before]
    parts = []
    if missing:
        parts.append("missing " + ", ".join(missing[:5]) + (" ..." if len(missing) > 5 else ""))
    if changed:
        parts.append("changed " + ", ".join(changed[:5]) + (" ..." if len(changed) > 5 else ""))
    if new:
        parts.append("new " + ", ".join(new[:5]) + (" ..." if len(new) > 5 else ""))
    return "; ".join(parts)


# -- running one case ------------------------------------------------------------------------------------
def run_proc(argv: list[str], cwd: Path, timeout: float = TIMEOUT):
    """(status or 'timeout', stdout, stderr, seconds) of one ehas run."""
    t0 = time.monotonic()
    try:
        r = subprocess.run(EHAS + argv, cwd=cwd, env=ENV, capture_output=True, text=True, errors="replace",
                           timeout=timeout, stdin=subprocess.DEVNULL)
        return r.returncode, r.stdout, r.stderr, time.monotonic() - t0
    except subprocess.TimeoutExpired as exc:
        err = exc.stderr.decode(errors="replace") if isinstance(exc.stderr, bytes) else (exc.stderr or "")
        return "timeout", "", err, time.monotonic() - t0


def run_case(case: Case, scratch: Path, fx: Path) -> Result:
    cmd = shown(case.argv) if case.mode != "api" else "python -c " + shlex.quote(case.argv[0].replace("\n", "; "))
    if case.skip:
        return Result(case, "skipped", "", 0.0, "", case.skip, cmd)
    tmp = scratch / case.id
    tmp.mkdir(parents=True)
    scaffold(tmp)
    try:
        if case.setup is not None:
            case.setup(tmp, fx)
    except Exception as exc:  # noqa: BLE001 - a broken setup is the campaign's bug: say so, go on
        return Result(case, "setup_failed", "", 0.0, "", f"setup: {type(exc).__name__}: {exc}", cmd)
    runner = {"run": _run_plain, "pipe_sh": _run_pipe_sh, "pipe_closed": _run_pipe_closed,
              "interrupt": _run_interrupt, "twice": _run_twice, "api": _run_api,
              "concurrent": _run_concurrent}[case.mode]
    try:
        res = runner(case, tmp, fx, cmd)
    finally:
        if not KEEP:
            shutil.rmtree(tmp, ignore_errors=True)
    return res


def _run_plain(case: Case, tmp: Path, fx: Path, cmd: str) -> Result:
    argv = [fill(a, tmp, fx) for a in case.argv]
    protected = {p: snapshot(tmp / p) for p in case.protect}
    before = snapshot(tmp)
    status, out, err, secs = run_proc(argv, tmp)
    last = last_line(err)
    after = snapshot(tmp)
    notes = []
    lost = []
    for p, snap in protected.items():
        now = snapshot(tmp / p)
        if now != snap:
            lost.append(f"{p}: {diff_snap(snap, now)}")
    staging = staging_leftovers(tmp)
    _, nwarn = message_lines(err)
    if nwarn:
        notes.append(f"{nwarn} warning line(s) before the last line")
    if (tmp / MARKER).exists():
        outcome = "ran_code"
        notes.append("data ran code: the marker file was written")
    elif status == "timeout":
        outcome = "timeout"
    elif has_traceback(err):
        outcome = "traceback"
    elif lost:
        outcome = "lost"
        notes.append("earlier output changed: " + " | ".join(lost))
    elif staging:
        outcome = "leftover"
        notes.append("temporaries left: " + ", ".join(staging[:4]))
    else:
        outcome = classify_status(case, status, err, notes)
        if outcome == "refused" or (outcome == "unclear" and status != 0):
            new = [k for k in after if k not in before and not k.endswith(".pyc")]
            if new:
                if outcome == "refused":
                    outcome = "leftover"
                notes.append("refused but wrote: " + ", ".join(sorted(new)[:5]))
    return Result(case, outcome, status, secs, last, "; ".join(notes), cmd)


def classify_status(case: Case, status, err: str, notes: list) -> str:
    if case.expect == "refuse":
        if status == 0:
            return "silent"
        clear, why = refusal_quality(err, case.culprit, case.forbid)
        if not clear:
            notes.append(why)
        return "refused" if clear else "unclear"
    if status == 0:
        return "ok"
    clear, why = refusal_quality(err, case.culprit)
    if not clear:
        notes.append(why)
        return "unclear"
    if case.expect == "accept":
        notes.append("a valid input was refused")
        return "refused_valid"
    return "refused"


def _run_pipe_sh(case: Case, tmp: Path, fx: Path, cmd: str) -> Result:
    """``ehas ARGS | head -1``: ehas must end quietly when head goes away."""
    argv = [fill(a, tmp, fx) for a in case.argv]
    line = shlex.join(EHAS + argv) + " | head -1 >/dev/null; exit ${PIPESTATUS[0]}"
    t0 = time.monotonic()
    try:
        r = subprocess.run(["bash", "-c", line], cwd=tmp, env=ENV, capture_output=True, text=True, timeout=TIMEOUT,
                           errors="replace")
        status, err = r.returncode, r.stderr
    except subprocess.TimeoutExpired:
        status, err = "timeout", ""
    secs = time.monotonic() - t0
    return _pipe_result(case, status, err, secs, cmd + " | head -1")


def _run_pipe_closed(case: Case, tmp: Path, fx: Path, cmd: str) -> Result:
    """stdout is a pipe whose reader has already gone: the first write fails with EPIPE."""
    argv = [fill(a, tmp, fx) for a in case.argv]
    r_fd, w_fd = os.pipe()
    os.close(r_fd)
    t0 = time.monotonic()
    try:
        p = subprocess.Popen(EHAS + argv, cwd=tmp, env=ENV, stdout=w_fd, stderr=subprocess.PIPE, text=True,
                             errors="replace", stdin=subprocess.DEVNULL)
    finally:
        os.close(w_fd)
    try:
        _, err = p.communicate(timeout=TIMEOUT)
        status = p.returncode
    except subprocess.TimeoutExpired:
        p.kill()
        _, err = p.communicate()
        status = "timeout"
    return _pipe_result(case, status, err, time.monotonic() - t0, cmd + "  (stdout: a pipe nobody reads)")


def _pipe_result(case, status, err, secs, cmd) -> Result:
    notes = []
    if status == "timeout":
        outcome = "timeout"
    elif any(m in err for m in PIPE_MARKS) or has_traceback(err):
        outcome = "traceback"
    elif message_lines(err + "\n[end]")[0][:-1]:  # anything but progress lines
        outcome = "unclear"
        notes.append("stderr not empty")
    elif status not in (0, 141):
        outcome = "unclear"
        notes.append(f"status {status}")
    else:
        outcome = "ok"
    return Result(case, outcome, status, secs, last_line(err), "; ".join(notes), cmd)


def _run_interrupt(case: Case, tmp: Path, fx: Path, cmd: str) -> Result:
    """Start an overwrite of an earlier output, signal it, check the folder holds one whole set."""
    o = case.opts
    argv = [fill(a, tmp, fx) for a in case.argv]
    watch = tmp / o["watch"]  # the output (a folder, or a stem's folder)
    for f in sorted(watch.rglob("*")):  # mark the earlier set: no file of a new run can equal a marked one
        if f.is_file() and not f.is_symlink():
            with open(f, "ab") as fh:
                fh.write(b"\n")
    earlier = snapshot(watch)
    new_names = set(o["new_names"](fx))  # names a complete new set has
    parent = watch.parent
    before_parent = {p.name for p in parent.iterdir()}
    sig = o["signal"]
    t0 = time.monotonic()
    # a shell's background job ignores SIGINT and children inherit that: give the command the default handler,
    # as a terminal's Ctrl-C finds it (run in the background, the campaign otherwise saw SIGINT ignored)
    p = subprocess.Popen(EHAS + argv, cwd=tmp, env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         text=True, errors="replace", stdin=subprocess.DEVNULL,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines: list[str] = []
    first = threading.Event()

    def reader():
        for ln in p.stderr:
            lines.append(ln)
            first.set()
        first.set()

    th = threading.Thread(target=reader, daemon=True)
    th.start()
    trigger = o["trigger"]
    sent_at = None
    deadline = t0 + 60
    if trigger == "staging":  # the new set is being written: a staging file, or a staging folder with a file
        while p.poll() is None and time.monotonic() < deadline:
            if any(TMP_MARK.search(n.name) and (n.is_file() or (n.is_dir() and any(n.iterdir())))
                   for n in _entries(parent, watch)):
                break
            time.sleep(0.002)
    elif trigger.startswith("first+"):
        first.wait(timeout=60)
        time.sleep(float(trigger[6:]))
    elif trigger.startswith("t="):
        time.sleep(float(trigger[2:]))
    elif trigger.startswith("line="):  # as soon as a stderr line holds this text (e.g. the final "writing")
        while p.poll() is None and time.monotonic() < deadline and not any(trigger[5:] in ln for ln in lines):
            time.sleep(0.002)
    notes = []
    if p.poll() is None:
        p.send_signal(sig)
        sent_at = time.monotonic()
    else:
        notes.append("ended before the signal")
    try:
        p.wait(timeout=TIMEOUT)
        status = p.returncode
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()
        status = "timeout"
    th.join(timeout=5)
    err = "".join(lines)
    secs = time.monotonic() - t0
    if sent_at is not None:
        notes.append(f"signal {signal.Signals(sig).name} at {sent_at - t0:.2f} s, exit {time.monotonic() - sent_at:.2f} s later")
    after = snapshot(watch)
    hidden = sorted(n for n in {q.name for q in parent.iterdir()} - before_parent if n.startswith("."))
    # hidden files are temporaries, except a whole-folder output's record of its own files
    hidden += [k for k in after if TMP_MARK.search(k) or (Path(k).name.startswith(".") and Path(k).name != RECORD)]
    top_after = {k for k in after if "/" not in k}
    stale = [k for k in earlier if k in after and after[k] == earlier[k] and earlier[k] != "DIR"]
    if hidden:
        state = "mixed"
        notes.append("temporaries left: " + ", ".join(hidden[:4]))
    elif after == earlier:
        state = "ok"
        notes.append("earlier set intact")
    elif top_after == new_names and not stale:
        state = "ok"
        notes.append("complete new set")
    elif stale and (top_after - set(earlier)):
        state = "mixed"
        notes.append(f"{len(stale)} earlier file(s) beside new ones: " + diff_snap(earlier, after))
    elif stale or not after:
        state = "lost"
        notes.append("earlier set damaged: " + diff_snap(earlier, after))
    else:
        state = "mixed"
        notes.append("neither the earlier set nor a complete new set: " + diff_snap(earlier, after))
    outcome = "timeout" if status == "timeout" else "traceback" if has_traceback(err) else state
    if outcome == "ok" and isinstance(status, int) and status < 0:
        outcome = "unclear"
        notes.append(f"died of signal {-status} without a message (not handled as an interrupt)")
    elif status not in (0, 130, "timeout"):
        notes.append(f"status {status}")
    return Result(case, outcome, status, secs, last_line(err), "; ".join(notes), cmd + f"  (+ {signal.Signals(sig).name} at {trigger})")


def _entries(parent: Path, watch: Path):
    try:
        yield from list(parent.iterdir())
        if watch.is_dir():
            yield from list(watch.iterdir())
    except OSError:
        return


def _run_twice(case: Case, tmp: Path, fx: Path, cmd: str) -> Result:
    """The same command in two fresh folders: the listed files must be the same (times and paths aside)."""
    argv = [fill(a, tmp, fx) for a in case.argv]
    runs = []
    secs = 0.0
    for name in ("a", "b"):
        d = tmp / name
        d.mkdir()
        status, out, err, s = run_proc(argv, d)
        secs += s
        runs.append((d, status, out, err))
        if status != 0:
            outcome = "timeout" if status == "timeout" else ("traceback" if has_traceback(err) else "unclear")
            return Result(case, outcome, status, secs, last_line(err), f"run {name} failed", cmd + "  (twice)")
    diffs = []
    for pattern in case.opts["files"]:
        fa = sorted(p.relative_to(runs[0][0]) for p in runs[0][0].glob(pattern))
        fb = sorted(p.relative_to(runs[1][0]) for p in runs[1][0].glob(pattern))
        if fa != fb:
            diffs.append(f"{pattern}: different files")
            continue
        if not fa:
            diffs.append(f"{pattern}: no file")
        for rel in fa:
            if _normalised(runs[0][0] / rel) != _normalised(runs[1][0] / rel):
                diffs.append(str(rel))
    if case.opts.get("stdout") and _norm_text(runs[0][2]) != _norm_text(runs[1][2]):
        diffs.append("stdout")
    outcome = "nondeterministic" if diffs else "ok"
    return Result(case, outcome, 0, secs, last_line(runs[1][3]), ("differ: " + ", ".join(diffs[:6])) if diffs else "",
                  cmd + "  (twice)")


def _run_concurrent(case: Case, tmp: Path, fx: Path, cmd: str) -> Result:
    """The same command twice at the same moment: one writes the output, the other refuses in one line (or, when
    it came second after the first finished, refuses as 'already exists'); never both status 0, never a mix."""
    argv = [fill(a, tmp, fx) for a in case.argv]
    t0 = time.monotonic()
    procs = [subprocess.Popen(EHAS + argv, cwd=tmp, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, errors="replace", stdin=subprocess.DEVNULL) for _ in range(2)]
    outs = []
    for pr in procs:
        try:
            o, e = pr.communicate(timeout=TIMEOUT)
            outs.append((pr.returncode, o, e))
        except subprocess.TimeoutExpired:
            pr.kill()
            o, e = pr.communicate()
            outs.append(("timeout", o, e))
    secs = time.monotonic() - t0
    notes = []
    if any(st == "timeout" for st, _, _ in outs):
        return Result(case, "timeout", "timeout", secs, "", "", cmd + "  (two at once)")
    if any(has_traceback(e) for _, _, e in outs):
        return Result(case, "traceback", 1, secs, "", "", cmd + "  (two at once)")
    ok = [o for o in outs if o[0] == 0]
    refused = [o for o in outs if o[0] != 0]
    staging = staging_leftovers(tmp)
    if len(ok) == 2:
        return Result(case, "lost", 0, secs, "", "both runs wrote the same output (one replaced the other)",
                      cmd + "  (two at once)")
    if staging:
        return Result(case, "mixed", 1, secs, "", "temporaries left: " + ", ".join(staging[:4]), cmd + "  (two at once)")
    if len(ok) != 1:
        return Result(case, "unclear", refused[0][0], secs, last_line(refused[0][2]), "neither run wrote its output",
                      cmd + "  (two at once)")
    st, _, err = refused[0]
    clear, why = refusal_quality(err, case.culprit)
    if not clear:
        notes.append(why)
    return Result(case, "ok" if clear else "unclear", 0, secs, last_line(err), "; ".join(notes),
                  cmd + "  (two at once)")


VOLATILE = re.compile(r"(time|elapsed|created|date|utc|wall|seconds|_s$|duration_s|per_s|host|pid|python|"
                      r"version|cpu|rss|throughput)", re.I)


def _normalised(p: Path):
    if p.suffix == ".json":
        try:
            return _drop_volatile(json.loads(p.read_text()))
        except ValueError:
            pass
    if p.suffix in (".csv", ".md", ".txt"):
        return _norm_text(p.read_text(errors="replace"))
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _norm_text(s: str) -> str:
    return re.sub(re.escape(str(SCRATCH)) + r"/cases/[^/\s]+/[ab]/", "", s)


def _drop_volatile(obj):
    if isinstance(obj, dict):
        return {k: _drop_volatile(v) for k, v in obj.items() if not VOLATILE.search(k)}
    if isinstance(obj, list):
        return [_drop_volatile(v) for v in obj]
    if isinstance(obj, str):
        return _norm_text(obj)
    return obj


API_PRELUDE = r'''
import json, sys, warnings
warnings.simplefilter("ignore")
ns = {}
try:
    exec(compile(sys.argv[1], "<case>", "exec"), ns)
except BaseException as exc:
    t = type(exc)
    user = isinstance(exc, (ValueError, TypeError, OSError)) or t.__module__.startswith("gymnasium.error")
    print(json.dumps({"raised": t.__module__ + "." + t.__qualname__, "msg": str(exc), "user": user}))
else:
    print(json.dumps({"raised": None, "result": repr(ns.get("result"))[:300]}))
'''



def _run_api(case: Case, tmp: Path, fx: Path, cmd: str) -> Result:
    code = fill(case.argv[0], tmp, fx)
    t0 = time.monotonic()
    try:
        r = subprocess.run([sys.executable, "-c", API_PRELUDE, code], cwd=tmp, env=ENV, capture_output=True,
                           text=True, timeout=TIMEOUT, errors="replace")
        status, out, err = r.returncode, r.stdout, r.stderr
    except subprocess.TimeoutExpired:
        return Result(case, "timeout", "timeout", time.monotonic() - t0, "", "", cmd)
    secs = time.monotonic() - t0
    try:
        rep = json.loads(out.strip().splitlines()[-1])
    except (ValueError, IndexError):
        return Result(case, "traceback", status, secs, last_line(err), "the API case crashed the interpreter", cmd)
    notes = []
    if rep["raised"] is None:
        last = "returned " + rep["result"]
        outcome = "silent" if case.expect == "refuse" else "ok"
        return Result(case, outcome, 0, secs, last[:200], "", cmd)
    msg = rep["msg"]
    last = f"{rep['raised'].split('.')[-1]}: {' '.join(msg.split())}"[:200]
    if not rep.get("user"):  # a user's bad input raises ValueError, TypeError, OSError or a gymnasium error
        notes.append(f"raised {rep['raised']}")
        return Result(case, "traceback", 1, secs, last, "; ".join(notes), cmd)
    why = []
    if "\n" in msg.strip():
        why.append("message of several lines")
    if case.culprit and not any(culprit_found(c, msg) for c in case.culprit):
        why.append("culprit " + " / ".join(repr(c) for c in case.culprit) + " not named")
    if why:
        return Result(case, "unclear", 1, secs, last, "; ".join(why), cmd)
    outcome = "refused" if case.expect != "accept" else "refused_valid"
    return Result(case, outcome, 1, secs, last, "", cmd)


KEEP = False
SCRATCH = Path("/nonexistent")


# ======================================================================================================
# fixtures: valid inputs and earlier outputs, made once with the smallest options
# ======================================================================================================
SMOKE = ROOT / "train" / "configs" / "ppo_smoke.toml"
SIM = ["--cycles", "3"]
BENCH_FAST = ["--no-robustness", "--no-book", "--cycles", "2.1", "--no-progress"]
PERF_FAST = ["--seconds", "0.01", "--repeats", "1", "--sizes", "1", "--training-steps", "0", "--rss-envs", "0"]
TRAIN_FAST = ["--algo", "ppo", "--config", "{fx}/smoke.toml", "--total-steps", "10", "--no-progress",
              "--no-tensorboard"]
DIAG_FAST = ["--no-propose", "--no-stack", "--quiet"]

#: earlier outputs: name -> argv writing it under {tmp}/out (the lost/overwrite/interrupt families copy them)
EARLIER = {
    "simulate": ["simulate", *SIM, "--out", "{tmp}/out/run"],
    "excite": ["excite", "chirp", "--duration", "1", "--out", "{tmp}/out/chirp"],
    "identify": ["identify", "{fx}/excite/chirp.csv", "--out", "{tmp}/out/id", "--json", "{tmp}/out/id.json"],
    "curves": ["curves", "--out", "{tmp}/out/curves"],
    "simulate-campaign": ["simulate-campaign", "--duration", "0.21", "--out", "{tmp}/out/camp"],
    "compare": ["compare", "{fx}/camp", "--out", "{tmp}/out/report", "--save-model", "{tmp}/out/m.json"],
    "diagnose": ["diagnose", "{fx}/camp", *DIAG_FAST, "--out", "{tmp}/out/diag", "--json", "{tmp}/out/diag.json"],
    "bench": ["bench", "{fx}/ctrl/model.json", *BENCH_FAST, "--out", "{tmp}/out/bench"],
    "tune": ["tune", "--method", "model", "--out", "{tmp}/out/tune/model.json", "--no-progress"],
    "perf": ["perf", *PERF_FAST, "--out", "{tmp}/out/perf"],
    "demo": ["demo", "--quick", "--out", "{tmp}/out/demo"],
    "model": ["model", "new", "{tmp}/out/m.json"],
    "train": ["train", *TRAIN_FAST, "--out", "{tmp}/out/train"],
    "export-controller": ["export-controller", "{fx}/ctrl/model.json", "--name", "rig", "--out", "{tmp}/out/c"],
    "export-drive": ["export-drive", "{fx}/learned.json", "--out", "{tmp}/out/drives"],
    "export-fmu": ["export-fmu", "--out", "{tmp}/out/rig.fmu"],  # the library compiled: the whole export
}

#: a learning controller that has learned (export-drive, export-controller): two conditions of the guard long
#: test's harmonic canceller
LEARNED = ROOT / "results" / "long_test_guard" / "learned_harmonic_on_schedule_model_based.json"
LEARNED_AT = ((7, 30.0, 3.0), (1, 10.0, 1.0))


def learned_fixture(path: Path) -> None:
    d = json.loads(LEARNED.read_text())
    d["learned"] = [r for r in d["learned"] if (r["disc_sets"], r["amplitude_deg"], r["freq_hz"]) in LEARNED_AT]
    assert len(d["learned"]) == len(LEARNED_AT), "the learned fixture's conditions are not in " + str(LEARNED)
    wtext(path, json.dumps(d))


def make_fixtures(fx: Path, jobs: int) -> None:
    """Valid inputs (controllers, a campaign, runs, a model, an agent, a config) and earlier outputs."""
    fx.mkdir(parents=True)
    shutil.copy(SMOKE, fx / "smoke.toml")
    agent = ROOT / "results" / "agents" / "ppo"
    jobs_list = [
        (fx, ["tune", "--method", "model", "--out", str(fx / "ctrl/model.json"), "--no-progress"]),
        (fx, ["simulate-campaign", "--duration", "0.21", "--out", str(fx / "camp")]),
        (fx, ["excite", "chirp", "--duration", "1", "--out", str(fx / "excite/chirp")]),
        (fx, ["simulate", *SIM, "--out", str(fx / "sim/run")]),
        (fx, ["model", "new", str(fx / "model.json")]),
    ]
    if not (agent / "policy.safetensors").is_file():
        jobs_list.append((fx, ["train", *[fill(a, fx, fx) for a in TRAIN_FAST], "--out", str(fx / "agent_ppo")]))
    _run_fixture_jobs(jobs_list, jobs)
    learned_fixture(fx / "learned.json")
    if (agent / "policy.safetensors").is_file():
        shutil.copytree(agent, fx / "agent_ppo")
    later = [(fx, ["tune", "--method", "relay", "--out", str(fx / "ctrl/relay.json"), "--no-progress"])]
    for name, argv in EARLIER.items():
        d = fx / "earlier" / name
        d.mkdir(parents=True)
        later.append((d, [fill(a, d, fx) for a in argv]))
    # the complete new sets of the interrupt family (names only)
    d = fx / "newsets"
    d.mkdir()
    later.append((d, ["bench", str(fx / "ctrl/relay.json"), "--cycles", "3", "--no-progress", "--no-book",
                      "--out", str(d / "bench")]))
    _run_fixture_jobs(later, jobs)


def _run_fixture_jobs(jobs_list, jobs: int) -> None:
    def one(item):
        cwd, argv = item
        status, out, err, secs = run_proc(argv, cwd, timeout=300)
        if status != 0:
            raise SystemExit(f"fault_campaign: error: fixture command failed ({status}): ehas {shlex.join(argv)}: "
                             f"{last_line(err)}")
        return secs

    with ThreadPoolExecutor(max_workers=jobs) as ex:
        list(ex.map(one, jobs_list))


def names_of(rel: str):
    return lambda fx: {p.name for p in (fx / rel).iterdir()}


# ======================================================================================================
# case generation
# ======================================================================================================
def walk_parser():
    """(command words, parser) of every (sub)command of ``ehas``."""
    from ehas_env.cli.main import build_parser

    out = []

    def rec(p, words):
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if words:
            out.append((words, p))
        for s in subs:
            for name, sp in s.choices.items():
                rec(sp, words + [name])

    rec(build_parser(), [])
    return out


#: the fastest valid command line of each command (the numeric, choice and path cases start from it)
def base_argv(words: list[str], opt: str = "", group: str = "") -> list[str]:
    cmd = " ".join(words)
    if cmd == "tune":
        if group == "optimiser" or opt in ("--max-evals", "--starts", "--seed", "--objective", "--start"):
            return ["tune", "--method", "optimize", "--disc-sets", "1", "--freq", "1", "--amplitude", "10",
                    "--max-evals", "2", "--out", "{tmp}/o/c.json", "--no-progress"]
        if group == "relay" or opt in ("--relay-mA", "--rule"):
            return ["tune", "--method", "relay", "--out", "{tmp}/o/c.json", "--no-progress"]
        if opt == "--base":
            return ["tune", "--method", "schedule", "--base", "model", "--out", "{tmp}/o/c.json", "--no-progress"]
        return ["tune", "--method", "model", "--out", "{tmp}/o/c.json", "--no-progress"]
    if cmd == "excite":
        kind = {"--f0": "chirp", "--f1": "chirp", "--method": "chirp", "--hold": "prbs", "--order": "prbs",
                "--levels": "prms", "--lines": "multisine"}.get(opt, "chirp")
        return ["excite", kind, "--duration", "1", "--out", "{tmp}/o/x"]
    return {
        "demo": ["demo", "--quick", "--out", "{tmp}/o"],
        "size": ["size"],
        "effects": ["effects"],
        "simulate": ["simulate", *SIM, "--out", "{tmp}/o/run"],
        "perf": ["perf", *PERF_FAST, "--out", "{tmp}/o"],
        "bench": ["bench", "{fx}/ctrl/model.json", *BENCH_FAST, "--out", "{tmp}/o"],
        "identify": ["identify", "{fx}/excite/chirp.csv", "--no-plots", "--out", "{tmp}/o"],
        "curves": ["curves", "--out", "{tmp}/o"],
        "simulate-campaign": ["simulate-campaign", "--duration", "0.21", "--out", "{tmp}/o"],
        "compare": ["compare", "{tmp}/camp"],
        "diagnose": ["diagnose", "{tmp}/camp", *DIAG_FAST],
        "train": ["train", *TRAIN_FAST, "--out", "{tmp}/o"],
        "model show": ["model", "show"],
        "model new": ["model", "new", "{tmp}/o/m.json"],
        "model diff": ["model", "diff", "{fx}/model.json", "{fx}/model.json"],
        "export-controller": ["export-controller", "{fx}/ctrl/model.json", "--out", "{tmp}/o"],
        "export-drive": ["export-drive", "{fx}/learned.json", "--out", "{tmp}/o"],
        "export-fmu": ["export-fmu", "--no-binary", "--out", "{tmp}/o/rig.fmu"],
    }[cmd]


def needs_camp(argv) -> bool:
    return any("{tmp}/camp" in str(a) for a in argv)


def with_camp(tmp: Path, fx: Path) -> None:
    copytree(fx / "camp", tmp / "camp")


def without(argv: list[str], opt: str) -> list[str]:
    """argv without ``opt`` (and its value)."""
    out, skip = [], False
    for a in argv:
        if skip:
            skip = False
            continue
        if a == opt:
            skip = True
            continue
        out.append(a)
    return out


def field_name(opt: str) -> str:
    return opt.lstrip("-").replace("-", "_")


NUMERIC_VALUES = ["nan", "inf", "-inf", "-1", "0", "1e308", "1e-308", "abc", "1,5", "9" * 40]


def numeric_cases() -> list[Case]:
    from ehas_env.ranges import Number

    cases = []
    for words, parser in walk_parser():
        groups = {id(a): g.title for g in parser._action_groups for a in g._group_actions}
        for a in parser._actions:
            if not isinstance(a.type, Number):
                continue
            opt = a.option_strings[0] if a.option_strings else a.dest
            group = groups.get(id(a), "")
            for v in NUMERIC_VALUES:
                try:
                    a.type.range.parse(v, opt)
                    expect = "either"  # inside the declared range: run it; a clear refusal is fine too
                except ValueError:
                    expect = "refuse"
                base = without(base_argv(words, opt, group), opt)
                arg = [f"{opt}={v}"] if v.startswith("-") and not re.match(r"^-\d", v) else [opt, v]
                cases.append(Case("numeric", f"{' '.join(words)} {opt} {v}", base + arg, expect,
                                  (opt, field_name(opt)), setup=with_camp if needs_camp(base) else None))
    return cases


def choice_cases() -> list[Case]:
    cases = []
    for words, parser in walk_parser():
        for a in parser._actions:
            if not a.choices or isinstance(a, argparse._SubParsersAction):
                continue
            opt = a.option_strings[0] if a.option_strings else a.dest
            base = base_argv(words, opt)
            for v in ("bogus", ""):
                if a.option_strings:
                    argv = without(base, opt) + [opt, v]
                    culprit = (opt, v) if v else (opt,)
                else:  # a positional choice (excite KIND): replace it
                    argv = [v if x == base[1] else x for x in base]
                    culprit = (repr(v),) if v else ("kind", "choose from")
                cases.append(Case("choice", f"{' '.join(words)} {opt} {v!r}", argv, "refuse", culprit,
                                  setup=with_camp if needs_camp(argv) else None))
    # subcommands themselves
    for argv, expect, culprit in ((["bogus"], "refuse", ("bogus",)), (["model", "bogus"], "refuse", ("bogus",)),
                                  (["model"], "either", ("ACTION", "show"))):
        cases.append(Case("choice", f"ehas {' '.join(argv)}", argv, expect, culprit))
    return cases


def list_cases() -> list[Case]:
    """Options holding lists, specs and names: gains, effects, sizes, supplies, NAS, polynomials, columns..."""
    S = base_argv(["simulate"])
    C = base_argv(["curves"])
    P = base_argv(["perf"])
    Z = ["size"]
    I = ["identify", "--no-plots", "--out", "{tmp}/o"]
    D = base_argv(["diagnose"])
    K = ["compare", "{tmp}/camp"]
    M = ["model", "new", "{tmp}/o/m.json"]
    SC = ["simulate-campaign", "--duration", "0.21", "--out", "{tmp}/o"]
    rows = [
        # (argv, expect, culprit)
        (S + ["--gains", "Kp=nan"], "refuse", ("Kp",)),
        (S + ["--gains", "Kp=abc"], "refuse", ("Kp",)),
        (S + ["--gains", "Kp=1e308"], "refuse", ("Kp",)),
        (S + ["--gains", "Kq=1"], "refuse", ("Kq",)),
        (S + ["--gains", "Kp="], "refuse", ("Kp",)),
        (S + ["--gains", "Kp"], "refuse", ("Kp",)),
        (S + ["--gains", ","], "refuse", ("--gains",)),
        (S + ["--gains", "Kp=1,Kp=2"], "refuse", ("Kp",)),
        (S + ["--gains", "Kp=1;Ki=2"], "refuse", ("--gains", "Kp")),
        (S + ["--gains", "kp=1"], "refuse", ("kp",)),
        (S + ["--gains", "Kp=0,Ki=0,Kv=0,Ka=0"], "either", ("--gains",)),
        (S + ["--gains", "Kp=-5"], "either", ("Kp",)),
        (S + ["--gains", "Kp=1", "--controller", "{fx}/ctrl/model.json"], "refuse", ("--gains", "--controller")),
        (S + ["--effects", "bogus_effect"], "refuse", ("bogus_effect",)),
        (S + ["--effects", "coulomb_friction:Fc=nan"], "refuse", ("Fc",)),
        (S + ["--effects", "coulomb_friction:Fc=-1"], "refuse", ("Fc",)),
        (S + ["--effects", "coulomb_friction:Fc=1e308"], "refuse", ("Fc",)),
        (S + ["--effects", "coulomb_friction:Fc=abc"], "refuse", ("Fc",)),
        (S + ["--effects", "coulomb_friction:Xx=1"], "refuse", ("Xx",)),
        (S + ["--effects", "coulomb_friction:Fc"], "refuse", ("Fc",)),
        (S + ["--effects", ":"], "refuse", ("--effects", "effects")),
        (S + ["--effects", "Fc=300"], "refuse", ("Fc",)),
        (S + ["--effects", "coulomb_friction,coulomb_friction"], "either", ("coulomb_friction",)),
        (S + ["--effects", "coulomb_friction:Fc=300;viscous_friction"], "accept", ()),
        # '' is refused like any empty option value ("the value is empty"); leaving --effects out is "none"
        (S + ["--effects", ""], "either", ("--effects",)),
        (S + ["--effects", "stribeck_friction:Fc=500,Fs=100"], "refuse", ("Fs", "Fc")),
        (C + ["--supplies", "0"], "refuse", ("--supplies",)),
        (C + ["--supplies", "nan"], "refuse", ("--supplies",)),
        (C + ["--supplies", "400"], "refuse", ("--supplies",)),
        (C + ["--supplies", ""], "refuse", ("--supplies",)),
        (C + ["--supplies", "70,,220"], "refuse", ("--supplies",)),
        (C + ["--supplies", "70"], "accept", ()),
        (C + ["--gains", "Kp=inf"], "refuse", ("Kp",)),
        (C + ["--effects", "bogus_effect"], "refuse", ("bogus_effect",)),
        (P + ["--sizes", "0"], "refuse", ("--sizes",)),
        (P + ["--sizes", "nan"], "refuse", ("--sizes",)),
        (P + ["--sizes", "-1"], "refuse", ("--sizes",)),
        (P + ["--sizes", "1,,2"], "refuse", ("--sizes",)),
        (P + ["--sizes", ""], "refuse", ("--sizes",)),
        (P + ["--sizes", "1e308"], "refuse", ("--sizes",)),
        (P + ["--sizes", "2.5"], "refuse", ("--sizes",)),
        (P + ["--sizes", "1,1"], "either", ("--sizes",)),
        (Z + ["--nas-counts", "1,2,3"], "refuse", ("--nas-counts",)),
        (Z + ["--nas-counts", "a,b,c,d,e"], "refuse", ("--nas-counts",)),
        (Z + ["--nas-counts", "-1,0,0,0,0"], "refuse", ("--nas-counts",)),
        (Z + ["--nas-counts", "nan,0,0,0,0"], "refuse", ("--nas-counts",)),
        (Z + ["--nas-counts", "1e308,0,0,0,0"], "either", ("--nas-counts",)),
        (Z + ["--nas-counts", "0,0,0,0,0"], "accept", ()),
        (Z + ["--nas-class", "13"], "refuse", ("--nas-class",)),
        (Z + ["--nas-class", "abc"], "refuse", ("--nas-class",)),
        (Z + ["--nas-class", "-1"], "refuse", ("--nas-class",)),
        (Z + ["--nas-class", ""], "refuse", ("--nas-class",)),
        (Z + ["--nas-class", "00"], "accept", ()),
        (Z + ["--disc-sets", "3", "--inertia", "1"], "refuse", ("--inertia", "--disc-sets")),
        (Z + ["--table", "nas"], "either", ("--nas",)),
        (I + ["--num", "nan", "--den", "1,2"], "refuse", ("--num",)),
        (I + ["--num", "1", "--den", "0"], "refuse", ("--den",)),
        (I + ["--num", "1", "--den", "1,abc"], "refuse", ("--den",)),
        (I + ["--num", "1"], "refuse", ("--den",)),
        (I + ["--den", "1,2"], "refuse", ("--num",)),
        (I + ["--num", "1,2,3", "--den", "1,2"], "refuse", ("--num", "--den")),
        (I + ["--num", "", "--den", "1,2"], "refuse", ("--num",)),
        (I + ["--num", "1", "--den", "1,-2"], "either", ("--den",)),
        (I + ["--num", "14567.29", "--den", "1,147.83,11449.86"], "accept", ()),
        (I,                                                     "refuse", ("run", "--num")),
        (I + ["{fx}/excite/chirp.csv", "--input", "nonexistent_col"], "refuse", ("nonexistent_col",)),
        (I + ["{fx}/excite/chirp.csv", "--output", "nonexistent_col"], "refuse", ("nonexistent_col",)),
        (I + ["{fx}/excite/chirp.csv", "--output", "current_mA"], "either", ("--output",)),
        (I + ["{fx}/excite/chirp.csv", "--zeros", "3", "--poles", "2"], "refuse", ("--zeros",)),
        (I + ["{fx}/sim/run.csv"], "either", ("flow_lpm", "run.csv")),
        (I + ["{fx}/sim/run.csv", "--output", "theta_deg", "--poles", "3"], "either", ("theta_deg",)),
        (K + ["--columns", "t"], "refuse", ("--columns",)),
        (K + ["--columns", "=x"], "refuse", ("--columns",)),
        (K + ["--columns", "theta_deg=Nope"], "refuse", ("Nope",)),
        (K + ["--columns", "bogus=t"], "refuse", ("bogus",)),
        (K + ["--columns", "t=theta_deg"], "refuse", ("theta_deg", "t")),
        (K + ["--effects", "bogus_effect"], "refuse", ("bogus_effect",)),
        (K + ["--effects", "coulomb_friction:Fc=nan"], "refuse", ("Fc",)),
        (K + ["--fit"], "either", ("--fit", "--effects")),
        (D + ["--with", "bogus_effect"], "refuse", ("bogus_effect",)),
        (D + ["--candidates", "bogus_effect"], "refuse", ("bogus_effect",)),
        (D + ["--candidates", ""], "refuse", ("--candidates",)),
        (D + ["--candidates", ","], "refuse", ("--candidates",)),
        (D + ["--holdout", "bogus_run"], "refuse", ("bogus_run",)),
        (D + ["--holdout", "cl_1set_35deg_3hz,cl_3sets_20deg_1hz,cl_5sets_30deg_2hz,cl_7sets_10deg_3hz,valve_chirp"],
         "refuse", ("--holdout",)),
        (D + ["--holdout", "none"], "accept", ()),
        (D + ["--holdout", ""], "either", ("--holdout",)),
        (D + ["--with", "coulomb_friction", "--candidates", "coulomb_friction"], "either", ("coulomb_friction",)),
        (D + ["--stack", "--no-stack"], "either", ("--stack", "--no-stack")),
        (D + ["--columns", "theta_deg=Nope"], "refuse", ("Nope",)),
        (SC + ["--effects", "bogus_effect"], "refuse", ("bogus_effect",)),
        (SC + ["--effects", "coulomb_friction:Fc=1e9"], "refuse", ("Fc",)),
        (M + ["--effects", "bogus_effect"], "refuse", ("bogus_effect",)),
        (M + ["--name", ""], "either", ("--name",)),
        (M + ["--description", "x" * 3000], "refuse", ("description",)),
        (M + ["--half-stroke-mm", "60"], "refuse", ("half_stroke", "--half-stroke-mm")),
        (M + ["--rated-flow-lpm", "10", "--K-lpm-per-mA", "2"], "refuse", ("--rated-flow-lpm", "--K-lpm-per-mA")),
        (M + ["--crank-radius-mm", "60", "--half-stroke-mm", "42", "--rated-flow-lpm", "40"], "accept", ()),
        (["effects", "bogus_effect"], "refuse", ("bogus_effect",)),
        (["effects", ""], "refuse", ("name", "effect")),
        (["effects", "coulomb_friction"], "accept", ()),
    ]
    cases = []
    for argv, expect, culprit in rows:
        cases.append(Case("lists", " ".join(argv[:1] + argv[-2:]), argv, expect, culprit,
                          setup=with_camp if needs_camp(argv) else None))
    return cases


# -- paths ---------------------------------------------------------------------------------------------
#: input files: (words, option or None for the positional, base argv builder, suffix of the expected file)
def input_file_slots():
    S = base_argv(["simulate"])
    return [
        ("size --model", ["size", "--model", "@"], ".json"),
        ("simulate --model", S + ["--model", "@"], ".json"),
        ("simulate --controller", S + ["--controller", "@"], ".json"),
        ("tune --model", base_argv(["tune"]) + ["--model", "@"], ".json"),
        ("tune --start", base_argv(["tune"], "--start") + ["--start", "@"], ".json"),
        ("bench CONTROLLER_FILE", ["bench", "@", *BENCH_FAST, "--out", "{tmp}/o"], ".json"),
        ("bench --model", base_argv(["bench"]) + ["--model", "@"], ".json"),
        ("identify RUN", ["identify", "@", "--no-plots", "--out", "{tmp}/o"], ".csv"),
        ("curves --model", base_argv(["curves"]) + ["--model", "@"], ".json"),
        ("simulate-campaign --model", base_argv(["simulate-campaign"]) + ["--model", "@"], ".json"),
        ("compare --model", ["compare", "{tmp}/camp", "--model", "@"], ".json"),
        ("diagnose --model", base_argv(["diagnose"]) + ["--model", "@"], ".json"),
        ("train --config", without(base_argv(["train"]), "--config") + ["--config", "@"], ".toml"),
        ("train --model", base_argv(["train"]) + ["--model", "@"], ".json"),
        ("model show FILE", ["model", "show", "@"], ".json"),
        ("model new --from", ["model", "new", "{tmp}/o/m.json", "--from", "@"], ".json"),
        ("model diff A", ["model", "diff", "@", "{fx}/model.json"], ".json"),
        ("model diff B", ["model", "diff", "{fx}/model.json", "@"], ".json"),
        ("export-controller CONTROLLER", ["export-controller", "@", "--out", "{tmp}/o"], ".json"),
        ("export-drive CONTROLLER", ["export-drive", "@", "--out", "{tmp}/o"], ".json"),
        ("export-fmu MODEL", ["export-fmu", "@", "--no-binary", "--out", "{tmp}/o/rig.fmu"], ".json"),
        ("export-fmu --controller", base_argv(["export-fmu"]) + ["--controller", "@"], ".json"),
    ]


def input_dir_slots():
    slots = [
        ("compare CAMPAIGN_DIR", ["compare", "@"], True),
        ("diagnose CAMPAIGN_DIR", ["diagnose", "@", *DIAG_FAST], True),
    ]
    for words in (["simulate"], ["bench"], ["tune"], ["compare"], ["diagnose"], ["simulate-campaign"], ["train"],
                  ["effects"], ["perf"], ["curves"], ["model", "new"]):
        full = words[0] in ("simulate", "effects", "diagnose", "model")  # all variants; the others: two
        slots.append((" ".join(words) + " --effects-path", base_argv(words) + ["--effects-path", "@"],
                      False if full else None))
    return slots


def put(argv, value):
    return [value if a == "@" else a for a in argv]


def path_cases() -> list[Case]:
    cases = []
    for what, argv, suffix in input_file_slots():
        variants = [
            ("under a regular file", "{tmp}/plainfile/x" + suffix, "refuse", ("plainfile",)),
            ("a folder", "{tmp}/afolder", "refuse", ("afolder",)),
            ("missing", "{tmp}/missing" + suffix, "refuse", ("missing" + suffix,)),
            ("empty file", "{tmp}/empty" + suffix, "refuse", ("empty" + suffix,)),
            ("binary garbage", "{tmp}/garbage" + suffix, "refuse", ("garbage" + suffix,)),
            ("empty string", "", "refuse", ("''", "\"\"", "=" + what.split()[-1])),
        ]
        for vname, value, expect, culprit in variants:
            a = put(argv, value)
            cases.append(Case("path-in", f"{what}: {vname}", a, expect, culprit,
                              setup=with_camp if needs_camp(a) else None,
                              forbid=("does not exist", "no such file") if vname == "a folder" else ()))
        a = put(argv, "{tmp}/unreadable" + suffix)
        cases.append(Case("path-in", f"{what}: unreadable", a, "refuse", ("unreadable" + suffix,),
                          skip="as root, permissions are not enforced" if IS_ROOT else "",
                          setup=_unreadable("unreadable" + suffix, camp=needs_camp(a))))
    for what, argv, is_campaign in input_dir_slots():
        variants = [
            ("a regular file", "{tmp}/plainfile", "refuse", ("plainfile",)),
            ("missing", "{tmp}/missingdir", "refuse", ("missingdir",)),
            ("under a regular file", "{tmp}/plainfile/sub", "refuse", ("plainfile",)),
            ("empty folder", "{tmp}/emptydir", "refuse" if is_campaign else "accept", ("emptydir",)),
            ("a non-.py file", "{tmp}/garbage.json", "refuse", ("garbage.json",)),
        ]
        for vname, value, expect, culprit in variants:
            if vname == "a non-.py file" and is_campaign:
                continue
            if is_campaign is None and vname not in ("missing", "a regular file"):
                continue
            a = put(argv, value)
            cases.append(Case("path-in", f"{what}: {vname}", a, expect, culprit,
                              setup=with_camp if needs_camp(a) else None))
    cases += output_path_cases()
    return cases


def _unreadable(name, camp: bool):
    def setup(tmp, fx):
        if camp:  # the command's campaign is there: the unreadable file is the one culprit
            with_camp(tmp, fx)
        wtext(tmp / name, "{}")
        os.chmod(tmp / name, 0)
    return setup


#: output slots: (what, argv with @, kind dir|file|stem, shared: a non-empty folder is fine)
def output_slots():
    return [
        ("demo --out", ["demo", "--quick", "--out", "@"], "dir", False),
        ("perf --out", ["perf", *PERF_FAST, "--out", "@"], "dir", True),
        ("bench --out", ["bench", "{fx}/ctrl/model.json", *BENCH_FAST, "--out", "@"], "dir", True),
        ("identify --out", ["identify", "{fx}/excite/chirp.csv", "--out", "@"], "dir", False),
        ("curves --out", ["curves", "--out", "@"], "dir", False),
        ("simulate-campaign --out", ["simulate-campaign", "--duration", "0.21", "--out", "@"], "dir", False),
        ("compare --out", ["compare", "{tmp}/camp", "--out", "@"], "dir", False),
        ("diagnose --out", ["diagnose", "{tmp}/camp", *DIAG_FAST, "--out", "@"], "dir", False),
        ("train --out", ["train", *TRAIN_FAST, "--out", "@"], "dir", False),
        ("tune --out", ["tune", "--method", "model", "--no-progress", "--out", "@"], "file", False),
        ("tune --bode", ["tune", "--method", "model", "--no-progress", "--out", "{tmp}/o/c.json", "--bode", "@"],
         "file", False),
        ("identify --json", ["identify", "{fx}/excite/chirp.csv", "--no-plots", "--out", "{tmp}/o", "--json", "@"],
         "file", False),
        ("compare --save-model", ["compare", "{tmp}/camp", "--save-model", "@"], "file", False),
        ("diagnose --json", ["diagnose", "{tmp}/camp", *DIAG_FAST, "--json", "@"], "file", False),
        ("diagnose --write-effect", ["diagnose", "{tmp}/camp", "--no-stack", "--quiet", "--write-effect", "@"],
         "file", False),
        ("model new FILE", ["model", "new", "@"], "file", False),
        ("simulate --out", ["simulate", *SIM, "--out", "@"], "stem", False),
        ("excite --out", ["excite", "chirp", "--duration", "1", "--out", "@"], "stem", False),
        # the exports' files are members of a shared folder (other files stay); the FMU is one file
        ("export-controller --out", ["export-controller", "{fx}/ctrl/model.json", "--out", "@"], "dir", True),
        ("export-drive --out", ["export-drive", "{fx}/learned.json", "--out", "@"], "dir", True),
        ("export-fmu --out", ["export-fmu", "--no-binary", "--out", "@"], "file", False),
    ]


def output_path_cases() -> list[Case]:
    cases = []
    for what, argv, kind, shared in output_slots():
        ext = {"tune --bode": ".png", "diagnose --write-effect": ".py", "export-fmu --out": ".fmu"}.get(what, ".json")
        leaf = "x" + (ext if kind == "file" else "")
        v = [("under a regular file", "{tmp}/plainfile/" + leaf, "refuse", ("plainfile",))]
        if kind == "dir":
            v.append(("an existing regular file", "{tmp}/plainfile", "refuse", ("plainfile",)))
            v.append(("a non-empty folder of other files", "{tmp}/busy", "accept" if shared else "refuse",
                      ("busy", "--overwrite")))
        else:
            v.append(("an existing folder", "{tmp}/afolder", "refuse", ("afolder",)))
            existing = "{tmp}/busy/x" + (ext if kind == "file" else "")
            v.append(("an existing output without --overwrite", existing, "refuse", ("--overwrite", "busy")))
        v.append(("a new nested folder with spaces and non-ASCII", "{tmp}/new/dossier é/b/" + leaf, "accept", ()))
        v.append(("empty string", "", "refuse" if kind != "dir" else "either", ("''", "=" + what.split()[-1])))
        if kind == "stem":
            v.append(("a stem with a suffix (run.csv)", "{tmp}/o/run.csv", "either", ("run.csv", "--out")))
        for vname, value, expect, culprit in v:
            a = put(argv, value)

            def setup(tmp, fx, a=a, kind=kind, ext=ext):
                if needs_camp(a):
                    with_camp(tmp, fx)
                wtext(tmp / "busy" / "notes.txt", "my own notes\n")
                if kind == "file":
                    wtext(tmp / "busy" / ("x" + ext), "earlier\n")
                if kind == "stem":
                    wtext(tmp / "busy" / "x.csv", "earlier\n")
                    wtext(tmp / "busy" / "x.json", "{}\n")
            protect = ("busy",) if expect == "refuse" else ("busy/notes.txt",) if shared else ()
            cases.append(Case("path-out", f"{what}: {vname}", a, expect, culprit, setup=setup, protect=protect))
        a = put(argv, "{tmp}/readonly/" + leaf)

        def ro_setup(tmp, fx, a=a):
            if needs_camp(a):
                with_camp(tmp, fx)
            (tmp / "readonly").mkdir()
            os.chmod(tmp / "readonly", 0o555)
        cases.append(Case("path-out", f"{what}: in a read-only folder", a, "refuse", ("readonly",), setup=ro_setup,
                          skip="as root, permissions are not enforced" if IS_ROOT else ""))
    return cases


# -- file formats ---------------------------------------------------------------------------------------
def controller_cases() -> list[Case]:
    def ctrl(fx):
        return json.loads((fx / "ctrl/model.json").read_text())

    def mut(fn):
        def setup(tmp, fx):
            d = ctrl(fx)
            r = fn(d)
            data = r if isinstance(r, (str, bytes)) else json.dumps(r if r is not None else d, allow_nan=True)
            (wbytes if isinstance(data, bytes) else wtext)(tmp / "c.json", data)
        return setup

    def set_(path, value):
        def fn(d):
            cur = d
            for k in path[:-1]:
                cur = cur[k]
            cur[path[-1]] = value
            return d
        return fn

    def del_(path):
        def fn(d):
            cur = d
            for k in path[:-1]:
                cur = cur[k]
            del cur[path[-1]]
            return d
        return fn

    nan, inf = float("nan"), float("inf")
    rows = [
        ("a JSON list", lambda d: [d], ("c.json",)),
        ("a JSON string", lambda d: '"piff"', ("c.json",)),
        ("no format", del_(["format"]), ("format",)),
        ("wrong format", set_(["format"], "ehas-model"), ("format",)),
        ("version 2", set_(["version"], 2), ("version",)),
        ("version '1' (a string)", set_(["version"], "1"), ("version",)),
        ("no version", del_(["version"]), ("version",)),
        ("no type", del_(["type"]), ("type",)),
        ("unknown type", set_(["type"], "pidx"), ("pidx",)),
        ("type null", set_(["type"], None), ("type",)),
        ("no gains", del_(["gains"]), ("gains",)),
        ("gains a list", set_(["gains"], [1, 2]), ("gains",)),
        ("gains empty", set_(["gains"], {}), ("gains", "Kp")),
        ("Kp NaN", set_(["gains", "Kp"], nan), ("Kp",)),
        ("Kp Infinity", set_(["gains", "Kp"], inf), ("Kp",)),
        ("Kp 1e308", set_(["gains", "Kp"], 1e308), ("Kp",)),
        ("Kp a string", set_(["gains", "Kp"], "abc"), ("Kp",)),
        ("Kp '1' (a string)", set_(["gains", "Kp"], "1"), ("Kp",)),
        ("Kp true", set_(["gains", "Kp"], True), ("Kp",)),
        ("Kp null", set_(["gains", "Kp"], None), ("Kp",)),
        ("unknown gain Kq", set_(["gains", "Kq"], 1.0), ("Kq",)),
        ("rate_hz 0", set_(["rate_hz"], 0), ("rate_hz",)),
        ("rate_hz -1000", set_(["rate_hz"], -1000), ("rate_hz",)),
        ("rate_hz NaN", set_(["rate_hz"], nan), ("rate_hz",)),
        ("rate_hz 1e9", set_(["rate_hz"], 1e9), ("rate_hz",)),
        ("i_max 0", set_(["i_max"], 0), ("i_max",)),
        ("i_max -5", set_(["i_max"], -5), ("i_max",)),
        ("i_max NaN", set_(["i_max"], nan), ("i_max",)),
        ("i_max 1e6", set_(["i_max"], 1e6), ("i_max",)),
        ("output_bits 99", set_(["output_bits"], 99), ("output_bits",)),
        ("output_bits -1", set_(["output_bits"], -1), ("output_bits",)),
        ("output_bits 2.5", set_(["output_bits"], 2.5), ("output_bits",)),
        ("kind 'learned'", set_(["kind"], "learned"), ("kind",)),
        ("kind 'bogus'", set_(["kind"], "bogus"), ("kind",)),
        ("dp_hp -1", set_(["gains", "dp_hp"], -1.0), ("dp_hp",)),
        ("truncated JSON", lambda d: json.dumps(d)[:60], ("c.json",)),
        ("trailing comma", lambda d: json.dumps(d)[:-1] + ",}", ("c.json",)),
        ("UTF-16", lambda d: json.dumps(d).encode("utf-16"), ("c.json",)),
    ]
    accept = [
        ("extra unknown top-level keys", set_(["my_note"], "hello")),
        ("no metrics, notes, units", lambda d: {k: v for k, v in d.items() if k not in ("metrics", "notes", "units",
                                                                                        "command")}),
        ("a UTF-8 byte-order mark", lambda d: "\ufeff" + json.dumps(d)),
        ("gains only (Kp, Ki)", set_(["gains"], {"Kp": 1.0, "Ki": 2.0})),
    ]
    cases = []
    bench = ["bench", "{tmp}/c.json", *BENCH_FAST, "--out", "{tmp}/o"]
    sim = ["simulate", *SIM, "--controller", "{tmp}/c.json", "--out", "{tmp}/o/run"]
    export_c = ["export-controller", "{tmp}/c.json", "--out", "{tmp}/o"]
    export_fmu = ["export-fmu", "--controller", "{tmp}/c.json", "--no-binary", "--out", "{tmp}/o/rig.fmu"]
    for i, (what, fn, culprit) in enumerate(rows):
        cases.append(Case("controller-json", f"bench: {what}", bench, "refuse", culprit, setup=mut(fn)))
        if i % 3 == 0:
            cases.append(Case("controller-json", f"simulate --controller: {what}", sim, "refuse", culprit,
                              setup=mut(fn)))
        elif i % 3 == 1:
            cases.append(Case("controller-json", f"export-controller: {what}", export_c, "refuse", culprit,
                              setup=mut(fn)))
        else:
            cases.append(Case("controller-json", f"export-fmu --controller: {what}", export_fmu, "refuse", culprit,
                              setup=mut(fn)))
    cases += learned_cases()
    for what, fn in accept:
        cases.append(Case("controller-json", f"bench: {what}", bench, "either", ("c.json",), setup=mut(fn)))
    # Python controller files and other suffixes
    py_rows = [
        ("c.py with a syntax error", "c.py", "def oops(:\n", ("c.py",)),
        ("c.py importing a missing module", "c.py", "import no_such_module_x\n", ("c.py",)),
        ("c.py raising at import", "c.py", "raise RuntimeError('boom')\n", ("c.py",)),
        ("c.py with no controller", "c.py", "X = 1\n", ("c.py",)),
        ("c.py with CONTROLLER = 3", "c.py", "CONTROLLER = 3\n", ("CONTROLLER",)),
        ("c.txt", "c.txt", "{}", ("c.txt",)),
        ("c (no suffix)", "c", "{}", ("'c'", "/c", "c:")),
    ]
    for what, name, text, culprit in py_rows:
        argv = ["bench", "{tmp}/" + name, *BENCH_FAST, "--out", "{tmp}/o"]
        cases.append(Case("controller-json", f"bench: {what}", argv, "refuse", culprit,
                          setup=lambda tmp, fx, name=name, text=text: wtext(tmp / name, text)))
    return cases


def learned_cases() -> list[Case]:
    """A learning controller's ``learned`` records damaged: export-drive and export-controller (which export them)
    refuse in one line naming the record's field, and write nothing."""
    def mut(fn):
        def setup(tmp, fx):
            d = json.loads((fx / "learned.json").read_text())
            fn(d)
            wtext(tmp / "c.json", json.dumps(d, allow_nan=True))
        return setup

    def rec(key, value):
        def fn(d):
            d["learned"][0][key] = value
        return fn

    def table(values):
        def fn(d):
            d["learned"][0]["feedforward"] = {"table_mA": values}
        return fn

    rows = [
        ("no learned records", lambda d: d.pop("learned"), ("learned",)),
        ("learned an empty list", lambda d: d.update(learned=[]), ("learned",)),
        ("learned a string", lambda d: d.update(learned="7,30,3"), ("learned",)),
        ("learned[0] a number", lambda d: d["learned"].__setitem__(0, 5), ("learned[0]",)),
        ("learned[0] without feedforward", lambda d: d["learned"][0].pop("feedforward"), ("feedforward",)),
        ("learned[0].disc_sets 9", rec("disc_sets", 9), ("disc_sets",)),
        ("learned[0].freq_hz 0", rec("freq_hz", 0), ("freq_hz",)),
        ("learned[0].amplitude_deg NaN", rec("amplitude_deg", float("nan")), ("amplitude_deg",)),
        ("learned[0] table with a NaN", table([0.0] * 15 + [float("nan")]), ("learned[0]", "feedforward")),
        ("learned[0] table of 3 values", table([0.1, 0.2, 0.3]), ("learned[0]", "feedforward")),
        ("learned[0] table of strings", table(["a"] * 16), ("learned[0]", "feedforward")),
        ("a piff file (nothing to export as drives)", lambda d: d.clear() or d.update(
            {"format": "ehas-controller", "version": 1, "type": "piff", "gains": {"Kp": 1.0}}), ("c.json",)),
    ]
    cases = []
    for what, fn, culprit in rows:
        cases.append(Case("controller-json", f"export-drive: {what}", ["export-drive", "{tmp}/c.json", "--out",
                                                                        "{tmp}/o"], "refuse", culprit, setup=mut(fn)))
        if "piff" not in what:
            cases.append(Case("controller-json", f"export-controller: {what}",
                              ["export-controller", "{tmp}/c.json", "--out", "{tmp}/o"], "refuse", culprit,
                              setup=mut(fn)))
    return cases


def model_cases() -> list[Case]:
    base = {"format": "ehas-model", "version": 2, "kind": "plant", "name": "t",
            "rig": {"crank_radius_mm": 50, "piston_area_cm2": 7.658, "half_stroke_mm": 35,
                    "inertia_per_set_kgm2": 0.383, "dead_volume_cm3": 20, "supply_bar": 220,
                    "bulk_modulus_Pa": 1e9},
            "valve": {"model": "grey_box", "K_lpm_per_mA": 1.2723, "wn_rad_s": 107, "zeta": 0.691,
                      "rated_drop_bar": 70, "rated_current_mA": 20},
            "effects": {}, "effects_path": []}
    nan, inf = float("nan"), float("inf")

    def doc(**changes):
        d = json.loads(json.dumps(base))
        for key, value in changes.items():
            sect, _, k = key.partition("__")
            if k:
                if value is DELETE:
                    d[sect].pop(k, None)
                else:
                    d[sect][k] = value
            elif value is DELETE:
                d.pop(sect, None)
            else:
                d[sect] = value
        return d

    rows = [
        ("no format", doc(format=DELETE), ("format",)),
        ("format ehas-controller", doc(format="ehas-controller"), ("format",)),
        ("version 3", doc(version=3), ("version",)),
        ("version '2' (a string)", doc(version="2"), ("version",)),
        ("no version", doc(version=DELETE), ("version",)),
        ("kind motor", doc(kind="motor"), ("kind",)),
        ("unknown top-level key", doc(rigg={}), ("rigg",)),
        ("misspelt rig key crank_radius", doc(rig__crank_radius=60), ("crank_radius",)),
        ("crank_radius_mm -5", doc(rig__crank_radius_mm=-5), ("crank_radius_mm",)),
        ("crank_radius_mm NaN", doc(rig__crank_radius_mm=nan), ("crank_radius_mm",)),
        ("crank_radius_mm Infinity", doc(rig__crank_radius_mm=inf), ("crank_radius_mm",)),
        ("crank_radius_mm 1e308", doc(rig__crank_radius_mm=1e308), ("crank_radius_mm",)),
        ("crank_radius_mm 'abc'", doc(rig__crank_radius_mm="abc"), ("crank_radius_mm",)),
        ("crank_radius_mm '50' (a string)", doc(rig__crank_radius_mm="50"), ("crank_radius_mm",)),
        ("crank_radius_mm null", doc(rig__crank_radius_mm=None), ("crank_radius_mm",)),
        ("crank_radius_mm true", doc(rig__crank_radius_mm=True), ("crank_radius_mm",)),
        ("half_stroke_mm >= crank_radius_mm", doc(rig__half_stroke_mm=50), ("half_stroke_mm",)),
        ("supply_bar 0", doc(rig__supply_bar=0), ("supply_bar",)),
        ("bulk_modulus_Pa 1", doc(rig__bulk_modulus_Pa=1), ("bulk_modulus_Pa",)),
        ("inertia_per_set_kgm2 0", doc(rig__inertia_per_set_kgm2=0), ("inertia_per_set_kgm2",)),
        ("dead_volume_cm3 -1", doc(rig__dead_volume_cm3=-1), ("dead_volume_cm3",)),
        ("rig a list", doc(rig=[1, 2]), ("rig",)),
        ("valve model black_box", doc(valve__model="black_box"), ("black_box",)),
        ("valve zeta 0", doc(valve__zeta=0), ("zeta",)),
        ("valve wn_rad_s NaN", doc(valve__wn_rad_s=nan), ("wn_rad_s",)),
        ("valve K_lpm_per_mA 0", doc(valve__K_lpm_per_mA=0), ("K_lpm_per_mA",)),
        ("valve unknown key", doc(valve__Kq=1), ("Kq",)),
        ("valve white_box unknown key", doc(valve__model="white_box", valve__white_box={"Kxx": 1}), ("Kxx",)),
        ("valve white_box Kt -1", doc(valve__model="white_box", valve__white_box={"Kt": -1}), ("Kt",)),
        ("effects unknown effect", doc(effects={"bogus_effect": {}}), ("bogus_effect",)),
        ("effects Fc out of range", doc(effects={"coulomb_friction": {"Fc": 1e9}}), ("Fc",)),
        ("effects Fc NaN", doc(effects={"coulomb_friction": {"Fc": nan}}), ("Fc",)),
        ("effects unknown parameter", doc(effects={"coulomb_friction": {"Fx": 1}}), ("Fx",)),
        ("effects a list", doc(effects=["coulomb_friction"]), ("effects",)),
        ("effects_path a string", doc(effects_path=5), ("effects_path",)),
        ("description 3000 characters", doc(description="x" * 3000), ("description",)),
        ("name a number", doc(name=5), ("name",)),
        ("version 1 with beta 1", {"format": "ehas-model", "version": 1, "baseline": {"beta_Pa": 1}},
         ("beta_Pa",)),
        ("version 1 with K 50", {"format": "ehas-model", "version": 1, "baseline": {"K_lpm_per_mA": 50}},
         ("K_lpm_per_mA",)),
        ("a JSON list", [base], ("m.json",)),
        ("duplicate key (JSON allows, last wins)", None, ("crank_radius_mm",)),
    ]
    cases = []
    show = ["model", "show", "{tmp}/m.json"]
    sim = ["simulate", *SIM, "--model", "{tmp}/m.json", "--out", "{tmp}/o/run"]

    def setup_for(d):
        def setup(tmp, fx):
            if d is None:
                text = json.dumps(base).replace('"crank_radius_mm": 50', '"crank_radius_mm": 50, "crank_radius_mm": -5')
            else:
                text = json.dumps(d, allow_nan=True)
            wtext(tmp / "m.json", text)
        return setup

    fmu = ["export-fmu", "{tmp}/m.json", "--no-binary", "--out", "{tmp}/o/rig.fmu"]
    for i, (what, d, culprit) in enumerate(rows):
        cases.append(Case("model-json", f"model show: {what}", show, "refuse", culprit, setup=setup_for(d)))
        if i % 4 == 0:
            cases.append(Case("model-json", f"simulate --model: {what}", sim, "refuse", culprit, setup=setup_for(d)))
        if i % 4 == 2:
            cases.append(Case("model-json", f"export-fmu MODEL: {what}", fmu, "refuse", culprit, setup=setup_for(d)))
    cases.append(Case("model-json", "model show: truncated JSON", show, "refuse", ("m.json",),
                      setup=lambda tmp, fx: wtext(tmp / "m.json", json.dumps(base)[:80])))
    acc = [
        ("every key left out but format and version", {"format": "ehas-model", "version": 2}),
        ("units and calibration given", doc(units={"x": "N"}, calibration={"campaign": "c"})),
        ("version 1 file", {"format": "ehas-model", "version": 1, "baseline": {"beta_Pa": 9.6e8, "K_lpm_per_mA": 1.28}}),
        # an older file's effects_path is never loaded (issue 22): a missing folder does not matter, a warning says so
        ("effects_path missing folder (ignored)", doc(effects_path=["no_such_folder"])),
    ]
    for what, d in acc:
        cases.append(Case("model-json", f"simulate --model: {what}", sim, "accept", (), setup=setup_for(d)))
    cases.append(Case("model-json", f"export-fmu MODEL: {acc[0][0]}", fmu, "accept", (), setup=setup_for(acc[0][1])))
    return cases


class _Delete:
    pass


DELETE = _Delete()


# -- campaign folders ------------------------------------------------------------------------------------
RUN = "cl_3sets_20deg_1hz"
VALVE = "valve_chirp"


def _csv_rows(path: Path):
    lines = path.read_text().splitlines()
    return lines[0].split(","), [ln.split(",") for ln in lines[1:]]


def _csv_write(path: Path, header, rows, sep=",", newline="\n"):
    path.write_text(newline.join([sep.join(header)] + [sep.join(r) for r in rows]) + newline)


def camp_edit(fn, run=RUN):
    """setup: copy the campaign to {tmp}/camp, then fn(header, rows, folder) edits run's CSV in place."""
    def setup(tmp, fx):
        with_camp(tmp, fx)
        p = tmp / "camp" / f"{run}.csv"
        header, rows = _csv_rows(p)
        r = fn(header, rows, tmp / "camp")
        if r is False:  # fn rewrote the file itself
            return
        if r is not None:
            header, rows = r
        _csv_write(p, header, rows)
    return setup


def camp_setup(fn):
    def setup(tmp, fx):
        with_camp(tmp, fx)
        fn(tmp / "camp")
    return setup


def side_edit(fn, run=RUN):
    def setup(tmp, fx):
        with_camp(tmp, fx)
        p = tmp / "camp" / f"{run}.json"
        d = json.loads(p.read_text())
        r = fn(d)
        p.write_text(r if isinstance(r, str) else json.dumps(d if r is None else r, allow_nan=True))
    return setup


def col_op(name, fn):
    def edit(header, rows, folder):
        j = header.index(name)
        for k, r in enumerate(rows):
            r[j] = fn(k, r[j])
    return edit


def campaign_cases() -> list[Case]:
    def drop(col):
        def edit(h, rows, folder):
            j = h.index(col)
            return [x for i, x in enumerate(h) if i != j], [[x for i, x in enumerate(r) if i != j] for r in rows]
        return edit

    def cells(col, start, n, value):
        return col_op(col, lambda k, v: value if start <= k < start + n else v)

    def swap_rows(h, rows, folder):
        rows[10], rows[11] = rows[11], rows[10]

    def dup_time(h, rows, folder):
        rows[11][0] = rows[10][0]

    def nonuniform(h, rows, folder):
        rows[50][0] = repr(float(rows[50][0]) + 0.0004)

    def scale(col, f):
        return col_op(col, lambda k, v: repr(float(v) * f) if v not in ("", "nan") else v)

    def every(n):
        def edit(h, rows, folder):
            return h, rows[::n]
        return edit

    def header_only(h, rows, folder):
        return h, []

    def one_row(h, rows, folder):
        return h, rows[:1]

    def short_row(h, rows, folder):
        rows[20] = rows[20][:-2]

    def long_row(h, rows, folder):
        rows[20] = rows[20] + ["1"]

    def dup_col(h, rows, folder):
        j = h.index("theta_deg")
        return h + ["theta_deg"], [r + [r[j]] for r in rows]

    def rename(old, new):
        def edit(h, rows, folder):
            return [new if x == old else x for x in h], rows
        return edit

    def extra_col(h, rows, folder):
        return h + ["oil_temp_C"], [r + ["41.5"] for r in rows]

    def shift_t(off):
        return col_op("t", lambda k, v: repr(float(v) + off))

    def raw(fn):
        """edit the CSV file's text (returns False: do not rewrite the rows)."""
        def edit(h, rows, folder):
            p = folder / f"{RUN}.csv"
            fn(p)
            return False
        return edit

    rows = [
        # (what, setup, expect, culprit)
        ("no theta_deg column", camp_edit(drop("theta_deg")), "refuse", (RUN,)),
        ("no t column", camp_edit(drop("t")), "refuse", (RUN,)),
        ("no current_mA column", camp_edit(drop("current_mA")), "refuse", (RUN,)),
        ("no theta_ref_deg column", camp_edit(drop("theta_ref_deg")), "refuse", (RUN,)),
        ("valve run without flow_lpm", camp_edit(drop("flow_lpm"), VALVE), "refuse", (VALVE,)),
        ("no p_a_bar column (optional)", camp_edit(drop("p_a_bar")), "accept", ()),
        ("3 NaN cells in a row (filled)", camp_edit(cells("theta_deg", 100, 3, "nan")), "accept", ()),
        ("5 empty cells in a row (filled)", camp_edit(cells("theta_deg", 100, 5, "")), "accept", ()),
        ("6 NaN cells in a row", camp_edit(cells("theta_deg", 100, 6, "nan")), "refuse", (RUN,)),
        ("50 NaN cells in a row", camp_edit(cells("current_mA", 100, 50, "nan")), "refuse", (RUN,)),
        ("every theta_deg NaN", camp_edit(cells("theta_deg", 0, 10 ** 9, "nan")), "refuse", (RUN,)),
        ("NaN in t", camp_edit(cells("t", 30, 1, "nan")), "refuse", (RUN,)),
        ("inf cell", camp_edit(cells("theta_deg", 30, 1, "inf")), "refuse", (RUN,)),
        ("-inf cell", camp_edit(cells("current_mA", 30, 1, "-inf")), "refuse", (RUN,)),
        ("1e308 cell in theta_deg", camp_edit(cells("theta_deg", 30, 1, "1e308")), "refuse", (RUN,)),
        ("'abc' cell", camp_edit(cells("theta_deg", 30, 1, "abc")), "refuse", (RUN,)),
        ("non-monotonic time (two rows swapped)", camp_edit(swap_rows), "refuse", (RUN,)),
        ("duplicate time", camp_edit(dup_time), "refuse", (RUN,)),
        ("non-uniform time", camp_edit(nonuniform), "refuse", (RUN,)),
        ("t in ms", camp_edit(scale("t", 1000)), "refuse", (RUN,)),
        ("sampling 1 MHz+ (t / 1e4)", camp_edit(scale("t", 1e-4)), "refuse", (RUN,)),
        ("sampling 50 Hz (every 20th row)", camp_edit(every(20)), "refuse", (RUN,)),
        ("angles in rad", camp_edit(lambda h, r, f: (scale("theta_deg", math.pi / 180)(h, r, f),
                                                      scale("theta_ref_deg", math.pi / 180)(h, r, f))[-1]),
         "refuse", (RUN,)),
        ("current in A", camp_edit(scale("current_mA", 1e-3)), "refuse", (RUN,)),
        ("current x 1000 (uA)", camp_edit(scale("current_mA", 1e3)), "refuse", (RUN,)),
        ("pressure in Pa", camp_edit(scale("p_a_bar", 1e5)), "refuse", (RUN,)),
        ("load_kN in N", camp_edit(scale("load_kN", 1e3)), "refuse", (RUN,)),
        ("valve flow x 100", camp_edit(scale("flow_lpm", 100), VALVE), "refuse", (VALVE,)),
        ("a row with a field missing", camp_edit(short_row), "refuse", (RUN,)),
        ("a row with an extra field", camp_edit(long_row), "refuse", (RUN,)),
        ("header only", camp_edit(header_only), "refuse", (RUN,)),
        ("one data row", camp_edit(one_row), "refuse", (RUN,)),
        ("duplicate column name", camp_edit(dup_col), "refuse", (RUN,)),
        ("column renamed Angle1 (no --columns)", camp_edit(rename("theta_deg", "Angle1")), "refuse", (RUN,)),
        ("column theta_rad instead of theta_deg", camp_edit(rename("theta_deg", "theta_rad")), "refuse", (RUN,)),
        ("empty CSV file", camp_setup(lambda c: (c / f"{RUN}.csv").write_bytes(b"")), "refuse", (RUN,)),
        ("binary garbage CSV", camp_setup(lambda c: (c / f"{RUN}.csv").write_bytes(GARBAGE)), "refuse", (RUN,)),
        ("UTF-16 CSV", camp_setup(lambda c: (c / f"{RUN}.csv").write_bytes(
            (c / f"{RUN}.csv").read_text().encode("utf-16"))), "refuse", (RUN,)),
        ("mixed separators in the header", camp_edit(raw(lambda p: p.write_text(
            p.read_text().replace(",", ";", 2)))), "refuse", (RUN,)),
        ("a comment line first", camp_edit(raw(lambda p: p.write_text("# logger v2\n" + p.read_text()))),
         "either", (RUN,)),
        ("logged reference disagrees with the sidecar", side_edit(lambda d: d["reference"].update(freq_hz=2.0)),
         "refuse", (RUN,)),
        # sidecars
        ("truncated sidecar JSON", side_edit(lambda d: json.dumps(d)[:40]), "refuse", (RUN,)),
        ("empty sidecar", side_edit(lambda d: ""), "refuse", (RUN,)),
        ("sidecar a list", side_edit(lambda d: [d]), "refuse", (RUN,)),
        ("sidecar without kind", side_edit(lambda d: d.pop("kind") and d), "refuse", ("kind",)),
        ("sidecar kind bogus", side_edit(lambda d: d.update(kind="bogus")), "refuse", ("bogus", "kind")),
        ("sidecar disc_sets 9", side_edit(lambda d: d.update(disc_sets=9)), "refuse", ("disc_sets",)),
        ("sidecar disc_sets 2.5", side_edit(lambda d: d.update(disc_sets=2.5)), "refuse", ("disc_sets",)),
        ("sidecar disc_sets '3'", side_edit(lambda d: d.update(disc_sets="3")), "refuse", ("disc_sets",)),
        ("sidecar disc_sets missing", side_edit(lambda d: d.pop("disc_sets") and d), "refuse", ("disc_sets",)),
        ("sidecar supply_bar 0", side_edit(lambda d: d.update(supply_bar=0)), "refuse", ("supply_bar",)),
        ("sidecar supply_bar 500", side_edit(lambda d: d.update(supply_bar=500)), "refuse", ("supply_bar",)),
        ("sidecar supply_bar NaN", side_edit(lambda d: d.update(supply_bar=float("nan"))), "refuse",
         ("supply_bar",)),
        ("sidecar without reference", side_edit(lambda d: d.pop("reference") and d), "refuse", ("reference",)),
        ("sidecar amplitude_deg 50", side_edit(lambda d: d["reference"].update(amplitude_deg=50)), "refuse",
         ("amplitude_deg",)),
        ("sidecar freq_hz 0", side_edit(lambda d: d["reference"].update(freq_hz=0)), "refuse", ("freq_hz",)),
        ("sidecar freq_hz NaN", side_edit(lambda d: d["reference"].update(freq_hz=float("nan"))), "refuse",
         ("freq_hz",)),
        ("sidecar without controller", side_edit(lambda d: d.pop("controller") and d), "refuse", ("controller",)),
        ("sidecar Kp 1e308", side_edit(lambda d: d["controller"].update(Kp=1e308)), "refuse", ("Kp",)),
        ("sidecar Kp 'abc'", side_edit(lambda d: d["controller"].update(Kp="abc")), "refuse", ("Kp",)),
        ("sidecar rate_hz 0", side_edit(lambda d: d["controller"].update(rate_hz=0)), "refuse", ("rate_hz",)),
        ("sidecar ramp_cycles -1", side_edit(lambda d: d["reference"].update(ramp_cycles=-1)), "refuse",
         ("ramp_cycles",)),
        ("valve sidecar kind closed_loop", side_edit(lambda d: d.update(kind="closed_loop"), VALVE), "refuse",
         (VALVE,)),
        ("sidecar with an unknown key", side_edit(lambda d: d.update(operator="jo")), "either", ("operator",)),
        # folder contents
        ("orphan JSON", camp_setup(lambda c: wtext(c / "orphan.json", "{}")), "accept", ()),
        ("CSV without sidecar", camp_setup(lambda c: (c / f"{RUN}.json").unlink()), "either", (RUN,)),
        ("dangling symlink x.csv", camp_setup(lambda c: os.symlink(c / "nowhere.csv", c / "x.csv")), "accept", ()),
        ("symlink loop y.csv", camp_setup(lambda c: os.symlink(c / "y.csv", c / "y.csv")), "accept", ()),
        ("a folder named run.csv", camp_setup(lambda c: (c / "run.csv").mkdir()), "accept", ()),
        ("a folder named run.csv with run.json", camp_setup(lambda c: ((c / "run.csv").mkdir(),
                                                                       wtext(c / "run.json", "{}"))), "either",
         ("run.csv",)),
        ("extra unknown column", camp_edit(extra_col), "accept", ()),
        ("UTF-8 byte-order mark", camp_edit(raw(lambda p: p.write_text("\ufeff" + p.read_text()))), "accept", ()),
        ("CRLF line ends", camp_edit(raw(lambda p: p.write_bytes(p.read_bytes().replace(b"\n", b"\r\n")))),
         "accept", ()),
        ("semicolons and decimal commas", camp_edit(raw(lambda p: p.write_text(
            p.read_text().replace(",", ";").replace(".", ",")))), "accept", ()),
        ("tab separators", camp_edit(raw(lambda p: p.write_text(p.read_text().replace(",", "\t")))), "accept", ()),
        ("no newline at the end", camp_edit(raw(lambda p: p.write_text(p.read_text().rstrip("\n")))), "accept",
         ()),
        ("trailing blank lines", camp_edit(raw(lambda p: p.write_text(p.read_text() + "\n\n\n"))), "accept", ()),
        ("time starting at 100 s", camp_edit(shift_t(100.0)), "either", (RUN,)),
        ("run name with spaces", camp_setup(lambda c: ((c / f"{RUN}.csv").rename(c / "run 1.csv"),
                                                       (c / f"{RUN}.json").rename(c / "run 1.json"))), "accept", ()),
        ("only truth.json and README left", camp_setup(lambda c: [p.unlink() for p in c.glob("*_*.*")
                                                                  if p.name != "truth.json"]), "refuse",
         ("camp",)),
        ("the campaign folder is a symlink", lambda tmp, fx: (with_camp(tmp, fx),
                                                              os.rename(tmp / "camp", tmp / "real"),
                                                              os.symlink(tmp / "real", tmp / "camp")), "accept", ()),
        ("a CSV that is a symlink to another run", camp_setup(lambda c: ((c / f"{RUN}.csv").unlink(),
                                                                         os.symlink(c / "cl_7sets_10deg_3hz.csv",
                                                                                    c / f"{RUN}.csv"))), "refuse",
         (RUN,)),
    ]
    cases = []
    diag_pick = {"no theta_deg column", "6 NaN cells in a row", "non-monotonic time (two rows swapped)",
                 "truncated sidecar JSON", "orphan JSON", "dangling symlink x.csv", "a folder named run.csv",
                 "extra unknown column", "sidecar disc_sets 9", "angles in rad", "binary garbage CSV",
                 "CSV without sidecar", "UTF-16 CSV", "only truth.json and README left", "t in ms",
                 "semicolons and decimal commas", "valve run without flow_lpm", "empty CSV file"}
    for what, setup, expect, culprit in rows:
        cases.append(Case("campaign", f"compare: {what}", ["compare", "{tmp}/camp"], expect, culprit, setup=setup,
                          protect=("camp",) if "symlink" not in what else ()))
        if what in diag_pick:
            cases.append(Case("campaign", f"diagnose: {what}", ["diagnose", "{tmp}/camp", *DIAG_FAST], expect,
                              culprit, setup=setup, protect=("camp",) if "symlink" not in what else ()))
    # --columns on a renamed logger
    cases.append(Case("campaign", "compare: Angle1 mapped with --columns theta_deg=Angle1",
                      ["compare", "{tmp}/camp", "--columns", "theta_deg=Angle1"], "accept", (),
                      setup=camp_edit(rename("theta_deg", "Angle1"))))
    return cases


# -- training configs --------------------------------------------------------------------------------------
def train_cases() -> list[Case]:
    text = SMOKE.read_text()

    def sub(old, new, count=1):
        def setup(tmp, fx):
            assert old in text, old
            wtext(tmp / "cfg.toml", text.replace(old, new, count))
        return setup

    def add(section, line):
        return sub(f"[{section}]\n", f"[{section}]\n{line}\n")

    rows = [
        ("TOML syntax error", sub("n_envs = 4", "n_envs = = 4"), ("cfg.toml",)),
        ("format bogus", sub('format = "ehas-train-config"', 'format = "bogus"'), ("format",)),
        ("no format (optional)", sub('format = "ehas-train-config"\n', ""), ("format",)),
        ("version 99", sub("version = 1", "version = 99"), ("version",)),
        ("version '1'", sub("version = 1", 'version = "1"'), ("version",)),
        ("unknown section [trian]", sub("[train]", "[trian]"), ("trian",)),
        ("unknown [train] key totl_steps", add("train", "totl_steps = 5"), ("totl_steps",)),
        ("algo dqn", sub('algo = "ppo"', 'algo = "dqn"'), ("dqn",)),
        ("algo sac while --algo ppo", sub('algo = "ppo"', 'algo = "sac"'), ("algo",)),
        ("total_steps 0", sub("total_steps = 12_000", "total_steps = 0"), ("total_steps",)),
        ("total_steps nan", sub("total_steps = 12_000", "total_steps = nan"), ("total_steps",)),
        ("total_steps 1e308", sub("total_steps = 12_000", "total_steps = 1e308"), ("total_steps",)),
        ("total_steps 'abc'", sub("total_steps = 12_000", 'total_steps = "abc"'), ("total_steps",)),
        ("total_steps 1.5", sub("total_steps = 12_000", "total_steps = 1.5"), ("total_steps",)),
        ("n_envs 0", sub("n_envs = 4", "n_envs = 0"), ("n_envs",)),
        ("seed -1", sub("seed = 0", "seed = -1"), ("seed",)),
        ("checkpoint_every 0", sub("checkpoint_every = 2_000", "checkpoint_every = 0"), ("checkpoint_every",)),
        ("vecnormalize 'yes'", sub("vecnormalize = true", 'vecnormalize = "yes"'), ("vecnormalize",)),
        ("eval_episodes -1", sub("eval_episodes = 2", "eval_episodes = -1"), ("eval_episodes",)),
        ("log_interval_s 0", sub("log_interval_s = 1e9", "log_interval_s = 0"), ("log_interval_s",)),
        ("vec_env bogus", add("train", 'vec_env = "bogus"'), ("vec_env",)),
        ("max_minutes 0", add("train", "max_minutes = 0"), ("max_minutes",)),
        ("learning_rate 0", sub("learning_rate = 1e-3", "learning_rate = 0"), ("learning_rate",)),
        ("learning_rate nan", sub("learning_rate = 1e-3", "learning_rate = nan"), ("learning_rate",)),
        ("learning_rate 'fast'", sub("learning_rate = 1e-3", 'learning_rate = "fast"'), ("learning_rate",)),
        ("gamma 2", sub("gamma = 0.95", "gamma = 2"), ("gamma",)),
        ("gae_lambda 5", sub("gae_lambda = 0.9", "gae_lambda = 5"), ("gae_lambda",)),
        ("n_steps 0", sub("n_steps = 200", "n_steps = 0"), ("n_steps",)),
        ("batch_size 0", sub("batch_size = 100", "batch_size = 0"), ("batch_size",)),
        ("batch_size 1e9", sub("batch_size = 100", "batch_size = 1_000_000_000"), ("batch_size",)),
        ("n_epochs 0", sub("n_epochs = 5", "n_epochs = 0"), ("n_epochs",)),
        ("unknown hyper-parameter", add("algo", "learning_rat = 0.1"), ("learning_rat",)),
        ("action_noise_std for ppo", add("algo", "action_noise_std = 0.1"), ("action_noise_std",)),
        ("net_arch [0]", sub("net_arch = [32, 32]", "net_arch = [0]"), ("net_arch",)),
        ("net_arch 'big'", sub("net_arch = [32, 32]", 'net_arch = "big"'), ("net_arch",)),
        ("net_arch [1e9]", sub("net_arch = [32, 32]", "net_arch = [1_000_000_000]"), ("net_arch",)),
        ("activation_fn sigmoid", sub('activation_fn = "tanh"', 'activation_fn = "sigmoid"'), ("activation_fn",)),
        ("policy_kwargs a string", sub("[algo.policy_kwargs]\nnet_arch = [32, 32]\nactivation_fn = \"tanh\"",
                                       'policy_kwargs = "x"'), ("policy_kwargs",)),
        ("env id bogus", sub('id = "ehas/Tracking-v0"', 'id = "ehas/Bogus-v0"'), ("Bogus",)),
        ("env residual 'no'", sub("residual = false", 'residual = "no"'), ("residual",)),
        ("action_repeat 0", sub("action_repeat = 10", "action_repeat = 0"), ("action_repeat",)),
        ("action_scale_mA 50", sub("action_scale_mA = 20.0", "action_scale_mA = 50.0"), ("action_scale_mA",)),
        ("reward_scale -1", sub("reward_scale = 1.0", "reward_scale = -1.0"), ("reward_scale",)),
        ("env.kwargs disc_sets 9", sub("disc_sets = 1", "disc_sets = 9"), ("disc_sets",)),
        ("env.kwargs amplitude_deg 50", sub("amplitude_deg = 10.0", "amplitude_deg = 50.0"), ("amplitude_deg",)),
        ("env.kwargs freq_hz 0", sub("freq_hz = 1.0", "freq_hz = 0.0"), ("freq_hz",)),
        ("env.kwargs cycles 0", sub("cycles = 1.0", "cycles = 0.0"), ("cycles",)),
        ("env.kwargs unknown key", add("env.kwargs", "dics_sets = 2"), ("dics_sets",)),
        ("env.kwargs effects bogus", add("env.kwargs", 'effects = "bogus_effect"'), ("bogus_effect",)),
        ("env.kwargs model missing file", add("env.kwargs", 'model = "no_such_model.json"'), ("no_such_model",)),
        ("randomise disc_sets reversed", sub("[env.kwargs]", "[randomise]\ndisc_sets = [7, 1]\n[env.kwargs]"),
         ("disc_sets",)),
        ("randomise unknown effect", sub("[env.kwargs]", "[randomise.effects]\nbogus_effect = \"typical\"\n"
                                                         "[env.kwargs]"), ("bogus_effect",)),
        ("randomise freq_hz [0, 100]", sub("[env.kwargs]", "[randomise]\nfreq_hz = [0.0, 100.0]\n[env.kwargs]"),
         ("freq_hz",)),
        ("a section that is a value", sub("[train]", "train = 5\n[trainx]"), ("train",)),
    ]
    cases = []
    argv = ["train", "--algo", "ppo", "--config", "{tmp}/cfg.toml", "--out", "{tmp}/tr", "--total-steps", "10",
            "--no-progress", "--no-tensorboard"]
    for what, setup, culprit in rows:
        cases.append(Case("train-toml", what, argv, "either" if "(optional)" in what else "refuse", culprit,
                          setup=setup))
    # command-line combinations of train
    T = ["train", *TRAIN_FAST]
    more = [
        ("no --algo and no --sweep", ["train", "--config", "{fx}/smoke.toml", "--out", "{tmp}/tr"], "refuse",
         ("--algo",)),
        ("--sweep with a config without [sweep]", T + ["--sweep", "--out", "{tmp}/tr"], "refuse", ("sweep",)),
        ("--resume on a fresh folder", T + ["--resume", "--out", "{tmp}/tr"], "refuse", ("--resume", "tr")),
        ("--vec-env subproc --n-envs 1", T + ["--vec-env", "subproc", "--n-envs", "1", "--out", "{tmp}/tr"], "either",
         ("--vec-env",)),
        ("--residual with ppo smoke config", T + ["--residual", "--out", "{tmp}/tr"], "either", ("--residual",)),
        ("--model a valid model file", T + ["--model", "{fx}/model.json", "--out", "{tmp}/tr"], "accept", ()),
        ("the bundled sac_smoke with --algo ppo", ["train", "--algo", "ppo", "--config",
                                                   "{root}/train/configs/sac_smoke.toml", "--out", "{tmp}/tr",
                                                   "--total-steps", "10", "--no-progress", "--no-tensorboard"],
         "refuse", ("algo", "sac")),
    ]
    for what, a, expect, culprit in more:
        cases.append(Case("train-toml", what, a, expect, culprit))
    return cases


# -- effect files ------------------------------------------------------------------------------------------
EFFECT_OK = spring_effect()


def effect_cases() -> list[Case]:
    def files(**named):
        def setup(tmp, fx):
            for name, content in named.items():
                name = name.replace("__", ".").replace("_DOT_", ".")
                data = content if isinstance(content, bytes) else content.encode()
                wbytes(tmp / "eff" / name, data)
        return setup

    ok = EFFECT_OK
    rows = [
        # (what, files, argv tail (effects NAME / simulate), expect, culprit)
        ("syntax error", {"spring__py": ok.replace("return -(k * theta)", "return -(k * theta")}, "effects",
         "refuse", ("spring.py",)),
        ("misspelt place crank_torqe", {"spring__py": ok.replace("def crank_torque", "def crank_torqe")}, "effects",
         "refuse", ("crank_torqe",)),
        ("import of a missing module", {"spring__py": "import no_such_module_x\n" + ok}, "effects", "refuse",
         ("spring.py",)),
        ("raises at import", {"spring__py": ok + "\nraise RuntimeError('boom')\n"}, "effects", "refuse",
         ("spring.py",)),
        ("name clashes with a built-in effect", {"spring__py": ok.replace('"fc_spring"', '"coulomb_friction"')},
         "effects", "refuse", ("coulomb_friction",)),
        ("two files with the same effect name", {"a__py": ok, "b__py": ok.replace("FcSpring", "FcSpring2")},
         "effects", "refuse", ("fc_spring",)),
        ("parameter default outside its bounds", {"spring__py": ok.replace("2000.0, (0.0, 1.0e6)",
                                                                           "-5.0, (0.0, 1.0e6)")}, "effects",
         "refuse", ("k", "fc_spring")),
        ("bounds reversed", {"spring__py": ok.replace("(0.0, 1.0e6)", "(1.0e6, 0.0)")}, "effects", "refuse",
         ("k", "fc_spring")),
        ("name with a hyphen", {"spring__py": ok.replace('"fc_spring"', '"fc-spring"')}, "effects", "refuse",
         ("fc-spring",)),
        ("name with a space", {"spring__py": ok.replace('"fc_spring"', '"fc spring"')}, "effects", "refuse",
         ("fc spring",)),
        ("main_param not a parameter", {"spring__py": ok.replace('main_param = "k"', 'main_param = "kk"')},
         "effects", "refuse", ("kk",)),
        ("holds no physics", {"spring__py": ok.split("    @staticmethod")[0]}, "effects", "refuse",
         ("fc_spring",)),
        ("two parameters with one name", {"spring__py": ok.replace(
            'typical=(500.0, 5000.0)),)', 'typical=(500.0, 5000.0)), Param("k", "N", 1.0, (0.0, 2.0), "dup"))')},
         "effects", "refuse", ("k",)),
        ("not UTF-8", {"spring__py": ok.encode("utf-16")}, "effects", "refuse", ("spring.py",)),
        ("params not a tuple", {"spring__py": ok.replace('params = (Param(', 'params = Param(').replace(
            'typical=(500.0, 5000.0)),)', 'typical=(500.0, 5000.0))')}, "effects", "refuse", ("params", "fc_spring")),
        ("an empty .py file (defines no effect)", {"spring__py": ""}, "effects", "refuse", ("spring.py",)),
        ("a broken _private.py (skipped)", {"_private__py": "def oops(:\n"}, "effects", "accept", ()),
        ("a broken .txt beside (skipped)", {"notes__txt": "def oops(:\n"}, "effects", "accept", ()),
        ("a valid effect, listed", {"spring__py": ok}, "effects", "accept", ()),
        ("a valid effect, explained", {"spring__py": ok}, "explain", "accept", ()),
        # these reach the model builder
        ("misspelt argument thetaa", {"spring__py": ok.replace("(theta, k)", "(thetaa, k)").replace(
            "k * theta", "k * thetaa")}, "simulate", "refuse", ("thetaa",)),
        ("uses numpy in its body", {"spring__py": ok.replace("return -(k * theta)",
                                                             "return -(k * np.tanh(theta))")},
         "simulate", "either", ("np", "fc_spring")),
        ("chamber_flows returning one number", {"spring__py": ok.replace(
            "def crank_torque(theta, k):\n        return -(k * theta)",
            "def chamber_flows(theta, k):\n        return -(k * theta)")}, "simulate", "refuse",
         ("chamber_flows", "fc_spring")),
        ("parameter out of bounds on the command line", {"spring__py": ok}, "simulate-bad", "refuse", ("k",)),
    ]
    cases = []
    for what, named, how, expect, culprit in rows:
        if how == "effects":
            argv = ["effects", "--effects-path", "{tmp}/eff"]
        elif how == "explain":
            argv = ["effects", "fc_spring", "--effects-path", "{tmp}/eff"]
        elif how == "simulate":
            argv = ["simulate", *SIM, "--effects-path", "{tmp}/eff", "--effects", "fc_spring", "--out", "{tmp}/o/run"]
        else:
            argv = ["simulate", *SIM, "--effects-path", "{tmp}/eff", "--effects", "fc_spring:k=-5",
                    "--out", "{tmp}/o/run"]
        cases.append(Case("effect-file", what, argv, expect, culprit, setup=files(**named)))
    # the same broken file through other commands (loaded before their work starts)
    broken = {"spring__py": ok.replace("def crank_torque", "def crank_torqe")}
    for words in (["bench"], ["diagnose"], ["train"], ["perf"], ["curves"], ["simulate-campaign"], ["tune"]):
        argv = base_argv(words) + ["--effects-path", "{tmp}/eff"]

        def setup(tmp, fx, argv=argv):
            files(**broken)(tmp, fx)
            if needs_camp(argv):
                with_camp(tmp, fx)
        cases.append(Case("effect-file", f"{words[0]}: misspelt place crank_torqe", argv, "refuse", ("crank_torqe",),
                          setup=setup))
    # --effects-path given a single .py file
    cases.append(Case("effect-file", "--effects-path a .py file with a syntax error",
                      ["effects", "--effects-path", "{tmp}/eff/spring.py"], "refuse", ("spring.py",),
                      setup=files(spring__py="def oops(:\n")))
    cases.append(Case("effect-file", "--effects-path the same folder twice",
                      ["effects", "--effects-path", "{tmp}/eff", "--effects-path", "{tmp}/eff"], "accept", (),
                      setup=files(spring__py=ok)))
    return cases


# -- agent folders -------------------------------------------------------------------------------------------
def agent_cases() -> list[Case]:
    def agent(fn):
        def setup(tmp, fx):
            copytree(fx / "agent_ppo", tmp / "agent")
            fn(tmp / "agent")
        return setup

    def cfg(change):
        def fn(a):
            d = json.loads((a / "config.json").read_text())
            change(d)
            (a / "config.json").write_text(json.dumps(d))
        return fn

    def trunc(name, n=100):
        def fn(a):
            (a / name).write_bytes((a / name).read_bytes()[:n])
        return fn

    def jedit(name, change):
        def fn(a):
            d = json.loads((a / name).read_text())
            change(d)
            (a / name).write_text(json.dumps(d))
        return fn

    def legacy_pickles(a):
        for name in ("policy.json", "policy.safetensors", "obs_norm.json"):
            (a / name).unlink()
        (a / "vecnormalize.pkl").write_bytes(marker_pickle(a.parent / "MARKER"))
        (a / "model.zip").write_bytes(marker_zip(a.parent / "MARKER"))

    rows = [
        ("policy.safetensors removed", lambda a: (a / "policy.safetensors").unlink(), ("policy.safetensors",)),
        ("policy.safetensors truncated", trunc("policy.safetensors", 1000), ("policy.safetensors",)),
        ("policy.safetensors binary garbage", lambda a: (a / "policy.safetensors").write_bytes(GARBAGE),
         ("policy.safetensors",)),
        ("policy.safetensors empty", lambda a: (a / "policy.safetensors").write_bytes(b""), ("policy.safetensors",)),
        ("policy.safetensors a folder", lambda a: ((a / "policy.safetensors").unlink(),
                                                   (a / "policy.safetensors").mkdir()), ("policy.safetensors",)),
        ("policy.json removed (no pickles beside)", lambda a: (a / "policy.json").unlink(), ("agent",)),
        ("policy.json garbage", lambda a: (a / "policy.json").write_bytes(GARBAGE), ("policy.json",)),
        ("policy.json activation os.system", jedit("policy.json", lambda d: d["kwargs"].update(
            activation_fn="os.system")), ("activation_fn",)),
        ("policy.json net_arch [10**9]", jedit("policy.json", lambda d: d["kwargs"].update(net_arch=[10**9])),
         ("net_arch",)),
        ("policy.json version 1.0", jedit("policy.json", lambda d: d.update(version=1.0)), ("version",)),
        ("policy.json a key twice", lambda a: (a / "policy.json").write_text(
            (a / "policy.json").read_text().replace('"version": 1,', '"version": 1, "version": 1,', 1)), ("version",)),
        ("policy.json algo sac (config ppo)", jedit("policy.json", lambda d: d.update(algo="sac")), ("algo",)),
        ("config.json removed", lambda a: (a / "config.json").unlink(), ("config.json",)),
        ("config.json garbage", lambda a: (a / "config.json").write_bytes(GARBAGE), ("config.json",)),
        ("config.json truncated", trunc("config.json", 50), ("config.json",)),
        ("config.json a list", lambda a: (a / "config.json").write_text("[]"), ("config.json",)),
        ("config.json algo dqn", cfg(lambda d: d.update(algo="dqn")), ("dqn", "algo")),
        ("config.json algo sac (policy is ppo)", cfg(lambda d: d.update(algo="sac")), ("algo", "policy.json")),
        ("config.json without algo", cfg(lambda d: d.pop("algo")), ("algo",)),
        ("config.json action_scale_mA 50", cfg(lambda d: d.update(action_scale_mA=50.0)), ("action_scale_mA",)),
        ("config.json action_repeat 0", cfg(lambda d: d.update(action_repeat=0)), ("action_repeat",)),
        ("config.json env_kwargs cycles nan", cfg(lambda d: d["env_kwargs"].update(cycles=float("nan"))),
         ("cycles",)),
        ("obs_norm.json removed", lambda a: (a / "obs_norm.json").unlink(), ("obs_norm.json",)),
        ("obs_norm.json garbage", lambda a: (a / "obs_norm.json").write_bytes(GARBAGE), ("obs_norm.json",)),
        ("obs_norm.json truncated", trunc("obs_norm.json", 40), ("obs_norm.json",)),
        ("obs_norm.json var negative", jedit("obs_norm.json", lambda d: d.update(var=[-1.0] * len(d["var"]))),
         ("var",)),
        ("obs_norm.json mean as strings", jedit("obs_norm.json", lambda d: d.update(mean=[str(v) for v in d["mean"]])),
         ("mean",)),
        ("an empty folder", lambda a: [p.unlink() for p in a.iterdir() if p.is_file()], ("agent",)),
        ("a pickled (legacy) agent that runs code", legacy_pickles, ("--allow-pickle",)),
    ]
    cases = []
    # every damage through simulate --controller (4 s); the model.zip / config.json damages through bench too
    # (bench runs the 63 conditions when it accepts an agent: 20-80 s)
    on_bench = {"policy.safetensors removed", "policy.safetensors truncated", "policy.safetensors binary garbage",
                "config.json garbage", "config.json truncated", "config.json algo dqn", "an empty folder",
                "a pickled (legacy) agent that runs code"}
    for what, fn, culprit in rows:
        if what in on_bench:
            bench = ["bench", "{tmp}/agent", *BENCH_FAST, "--out", "{tmp}/o"]
            cases.append(Case("agent-folder", f"bench: {what}", bench, "refuse", culprit, setup=agent(fn)))
        sim = ["simulate", *SIM, "--controller", "{tmp}/agent", "--out", "{tmp}/o/run"]
        cases.append(Case("agent-folder", f"simulate --controller: {what}", sim, "refuse", culprit,
                          setup=agent(fn)))
    cases.append(Case("agent-folder", "simulate --controller: a valid agent copy",
                      ["simulate", *SIM, "--controller", "{tmp}/agent", "--out", "{tmp}/o/run"], "accept", (),
                      setup=agent(lambda a: None)))
    cases.append(Case("agent-folder", "simulate --controller: valid agent, metrics.json garbage",
                      ["simulate", *SIM, "--controller", "{tmp}/agent", "--out", "{tmp}/o/run"], "either",
                      ("metrics.json",), setup=agent(lambda a: (a / "metrics.json").write_bytes(GARBAGE))))
    return cases


# -- data that tries to run code, plug-ins that misbehave, two runs at once (issue 22) -----------------------------
EVIL = "open(__import__('os').path.join({tmp!r}, 'MARKER'), 'w').write('ran')\n"


def marker_pickle(marker: Path) -> bytes:
    """A pickle that writes ``marker`` when loaded (what a hostile agent file does)."""
    import pickle

    class Payload:
        def __reduce__(self):
            return (Path.write_text, (Path(marker), "ran"))

    return pickle.dumps(Payload())


def marker_zip(marker: Path) -> bytes:
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("data", json.dumps({"policy_class": {":serialized:": marker_pickle(marker).hex()}}))
        z.writestr("pytorch_variables.pth", marker_pickle(marker))
    return buf.getvalue()


def _evil_folder(tmp: Path) -> Path:
    d = tmp / "evil"
    d.mkdir(exist_ok=True)
    wtext(d / "evil_effect.py", EVIL.format(tmp=str(tmp)))
    wtext(d / "evilmod.py", EVIL.format(tmp=str(tmp)))
    return d


def data_code_cases() -> list[Case]:
    """A model file, a run sidecar, a training TOML that each try to run code (write MARKER); no marker may appear."""
    def model(kind):
        def setup(tmp, fx):
            evil = _evil_folder(tmp)
            d = json.loads((fx / "model.json").read_text())
            d["effects_path"] = {"abs": [str(evil)], "rel": ["../" + tmp.name + "/evil"],
                                 "py": [str(evil / "evil_effect.py")], "named": [str(evil)]}[kind]
            if kind == "named":
                d["effects"] = {"evil_effect": {}}
                d["user_effects"] = {"evil_effect": {"file": "evil_effect.py", "sha256": hashlib.sha256(
                    (evil / "evil_effect.py").read_bytes()).hexdigest()}}
            wtext(tmp / "m.json", json.dumps(d))
            if "camp" in kind:
                with_camp(tmp, fx)
        return setup

    cmds = {
        "model show": ["model", "show", "{tmp}/m.json"],
        "model diff": ["model", "diff", "{tmp}/m.json", "{fx}/model.json"],
        "model new --from": ["model", "new", "{tmp}/new.json", "--from", "{tmp}/m.json"],
        "simulate --model": ["simulate", *SIM, "--model", "{tmp}/m.json", "--out", "{tmp}/o/run"],
        "size --model": ["size", "--model", "{tmp}/m.json"],
        "curves --model": ["curves", "--model", "{tmp}/m.json", "--out", "{tmp}/o"],
        "simulate-campaign --model": ["simulate-campaign", "--duration", "0.21", "--model", "{tmp}/m.json",
                                      "--out", "{tmp}/o"],
        "compare --model": ["compare", "{tmp}/camp", "--model", "{tmp}/m.json"],
    }
    cases = []
    for kind in ("abs", "rel", "py", "named"):
        for what, argv in cmds.items():
            if kind in ("rel", "py") and what not in ("model show", "simulate --model"):
                continue
            def setup(tmp, fx, kind=kind, argv=argv):
                model(kind)(tmp, fx)
                if needs_camp(argv):
                    with_camp(tmp, fx)
            if kind == "named":
                cases.append(Case("data-code", f"model file naming an unloaded user effect: {what}", argv, "refuse",
                                  ("evil_effect",), setup=setup))
            else:
                cases.append(Case("data-code", f"model file effects_path ({kind}) to code: {what}", argv, "either",
                                  ("m.json",), setup=setup))
    # a training TOML
    def toml(text):
        def setup(tmp, fx):
            _evil_folder(tmp)
            model("named")(tmp, fx)
            wtext(tmp / "cfg.toml", text.format(tmp=str(tmp)))
        return setup
    train = ["train", "--algo", "ppo", "--config", "{tmp}/cfg.toml", "--total-steps", "10", "--no-progress",
             "--no-tensorboard", "--out", "{tmp}/o"]
    for what, text, culprit in (
            ("[env] id = 'evilmod:Env'", "[train]\nalgo = 'ppo'\n[env]\nid = 'evilmod:Env'\n", ("module",)),
            ("[env] id = 'evil.evilmod:Env'", "[train]\nalgo = 'ppo'\n[env]\nid = 'evil.evilmod:Env'\n", ("module",)),
            ("[env] controller = a .py file", "[train]\nalgo = 'ppo'\n[env]\nresidual = true\ncontroller = '{tmp}/evil/evilmod.py'\n",
             ("--controller-path",)),
            ("with --model naming a user effect", "[train]\nalgo = 'ppo'\n", ("evil_effect",))):
        argv = train + (["--model", "{tmp}/m.json"] if "--model" in what else [])
        cases.append(Case("data-code", f"train TOML {what}", argv, "refuse", culprit, setup=toml(text)))
    # run sidecars naming code
    def sidecar(tmp, fx):
        evil = _evil_folder(tmp)
        with_camp(tmp, fx)
        for side in (tmp / "camp").glob("*.json"):
            if side.name == "truth.json":
                continue
            d = json.loads(side.read_text())
            d["effects_path"] = [str(evil)]
            d["controller"] = {"type": "evil", "file": str(evil / "evilmod.py")}
            side.write_text(json.dumps(d))
    for what, argv in (("compare", ["compare", "{tmp}/camp"]),
                       ("diagnose", ["diagnose", "{tmp}/camp", "--no-propose", "--no-stack", "--candidates",
                                     "coulomb_friction"])):
        cases.append(Case("data-code", f"run sidecars naming code: {what}", argv, "either", ("json", "effects_path",
                                                                                             "controller"),
                          setup=sidecar))
    return cases


def plugin_cases() -> list[Case]:
    """Plug-in files (code by contract) that misbehave: one line naming the file, never a hang or a silent exit."""
    from ehas_env.physics.effects.example_file import spring_effect as eff

    ok = eff()
    ctrl_ok = CONTROLLER_PY

    def files(**named):
        def setup(tmp, fx):
            for name, content in named.items():
                wtext(tmp / "plug" / name.replace("__", "."), content)
        return setup
    sim_eff = ["simulate", *SIM, "--effects-path", "{tmp}/plug", "--effects", "fc_spring", "--out", "{tmp}/o/run"]
    sim_ctl = ["simulate", *SIM, "--controller", "{tmp}/plug/ctl.py", "--out", "{tmp}/o/run"]
    rows = [
        ("effect: sys.exit(0) at import", {"spring__py": "import sys\nsys.exit(0)\n"}, sim_eff, ("spring.py",)),
        ("effect: os._exit(0) at import", {"spring__py": "import os\nos._exit(0)\n"}, sim_eff, ("spring.py",)),
        ("effect: KeyboardInterrupt at import", {"spring__py": "raise KeyboardInterrupt\n"}, sim_eff,
         ("spring.py",)),
        ("effect: endless loop at import", {"spring__py": "while True:\n    pass\n"}, sim_eff, ("spring.py",)),
        ("effect: endless loop in the term the load-time check calls", {"spring__py": ok.replace(
            "return -(k * theta)", "while True:\n            pass")}, sim_eff, ("spring.py",)),
        ("effect: name ''", {"spring__py": ok.replace('name = "fc_spring"', 'name = ""')}, sim_eff,
         ("spring.py",)),
        ("effect: parameter named theta", {"spring__py": ok.replace('Param("k"', 'Param("theta"').replace(
            'main_param = "k"', 'main_param = "theta"').replace("(theta, k)", "(theta)").replace(
            "k * theta", "theta")}, sim_eff, ("theta",)),
        ("effect: smooth = 'yes'", {"spring__py": ok.replace('    main_param = "k"', '    main_param = "k"\n'
                                                            '    smooth = "yes"')}, sim_eff, ("smooth",)),
        ("effect: log_scale = 1", {"spring__py": ok.replace("typical=(500.0, 5000.0))", "typical=(500.0, 5000.0), "
                                                            "log_scale=1)")}, sim_eff, ("log_scale",)),
        ("effect: bounds +-1e308, value 1e300 (NaN at run time)", {"spring__py": ok.replace(
            "(0.0, 1.0e6)", "(-1.0e308, 1.0e308)").replace("typical=(500.0, 5000.0)", "typical=None")},
         sim_eff[:-4] + ["--effects", "fc_spring:k=1e300", "--out", "{tmp}/o/run"], ("NaN",)),
        ("controller: sys.exit(0) at import", {"ctl__py": "import sys\nsys.exit(0)\n"}, sim_ctl, ("ctl.py",)),
        ("controller: os._exit(0) at import", {"ctl__py": "import os\nos._exit(0)\n"}, sim_ctl, ("ctl.py",)),
        ("controller: endless loop at import", {"ctl__py": "while True:\n    pass\n"}, sim_ctl, ("ctl.py",)),
        ("controller: law with a wrong signature", {"ctl__py": ctrl_ok.replace(
            "def law(gains, mem, t, dt, theta, r, rd, rdd, rddd, p_load, p_s, u_max)", "def law(gains, mem, t)")},
         sim_ctl, ("law",)),
        ("controller: law returns NaN", {"ctl__py": ctrl_ok.replace("return min(max(u, -u_max), u_max)",
                                                                    "return float('nan')")}, sim_ctl, ("law",)),
        ("controller: law returns NaN after 0.5 s", {"ctl__py": ctrl_ok.replace(
            "return min(max(u, -u_max), u_max)", "return min(max(u, -u_max), u_max) if t < 0.5 else float('nan')")},
         sim_ctl, ("NaN", "user_pd_ff")),
        ("controller: NaN default gain", {"ctl__py": ctrl_ok.replace("Kp: float = 1.5", "Kp: float = float('nan')")},
         sim_ctl, ("Kp",)),
        ("controller: endless loop in the law", {"ctl__py": ctrl_ok.replace(
            "e = r - theta", "while True:\n            pass")}, sim_ctl, ("ctl.py",)),
    ]
    cases = [Case("plugin", what, argv, "refuse", culprit, setup=files(**named))
             for what, named, argv, culprit in rows]
    cases.append(Case("plugin", "controller: a valid PD + feed-forward file", sim_ctl, "accept", (),
                      setup=files(ctl__py=ctrl_ok)))
    cases.append(Case("plugin", "effect: a valid file", sim_eff, "accept", (), setup=files(spring__py=ok)))
    return cases


def concurrent_cases() -> list[Case]:
    """Two identical commands started together: one writes, the other refuses in one line."""
    rows = [
        ("simulate --out", ["simulate", *SIM, "--out", "{tmp}/o/run"]),
        ("simulate --out (folder exists)", ["simulate", *SIM, "--out", "{tmp}/afolder/run"]),
        ("model new FILE", ["model", "new", "{tmp}/m.json"]),
        ("excite --out", ["excite", "chirp", "--duration", "1", "--out", "{tmp}/o/chirp"]),
        ("simulate-campaign --out", ["simulate-campaign", "--duration", "0.21", "--out", "{tmp}/c"]),
        ("identify --json", ["identify", "{fx}/excite/chirp.csv", "--json", "{tmp}/id.json"]),
        ("export-fmu --out (compiled)", ["export-fmu", "--out", "{tmp}/rig.fmu"]),
        ("export-controller --out", ["export-controller", "{fx}/ctrl/model.json", "--out", "{tmp}/c"]),
        ("export-drive --out", ["export-drive", "{fx}/learned.json", "--out", "{tmp}/d"]),
    ]
    return [Case("concurrent", what, argv, "either", ("another ehas run", "created by another run",
                                                      "already exists"), mode="concurrent") for what, argv in rows]


CONTROLLER_PY = """from dataclasses import dataclass

from ehas_controllers.base import CompiledController


@dataclass
class PDFF(CompiledController):
    type_name = "user_pd_ff"
    name = "PD+FF (user)"
    Kp: float = 1.5          # mA/deg
    Kd: float = 0.01         # mA/(deg/s)
    Kv: float = 1.0 / 56.25  # mA/(deg/s), velocity feed-forward

    @staticmethod
    def law(gains, mem, t, dt, theta, r, rd, rdd, rddd, p_load, p_s, u_max):
        e = r - theta
        de = (e - mem[0]) / dt if mem[1] > 0.0 else 0.0
        mem[0] = e
        mem[1] = 1.0
        u = gains[0] * e + gains[1] * de + gains[2] * rd
        return min(max(u, -u_max), u_max)
"""


# -- pipes -------------------------------------------------------------------------------------------------
def pipe_cases() -> list[Case]:
    cmds = [["effects"], ["effects", "coulomb_friction"], ["size"], ["size", "--format", "csv", "--table", "loads"],
            ["size", "--format", "json", "--table", "flows"], ["model", "show"], ["model", "show", "--json"], ["--help"],
            ["simulate", "--help"], ["model", "diff", "{fx}/model.json", "{fx}/ctrl/../model.json"],
            ["compare", "{tmp}/camp"]]
    cases = []
    for argv in cmds:
        setup = with_camp if needs_camp(argv) else None
        cases.append(Case("pipe", " ".join(argv) + " | head -1", argv, "quiet", (), mode="pipe_sh", setup=setup))
        cases.append(Case("pipe", " ".join(argv) + " > closed pipe", argv, "quiet", (), mode="pipe_closed",
                          setup=setup))
    return cases


# -- earlier work: overwrite refusals, late failures, user's own files ----------------------------------
def earlier_setup(name, extra=None):
    def setup(tmp, fx):
        copytree(fx / "earlier" / name / "out", tmp / "out")
        if extra:
            extra(tmp, fx)
    return setup


def lost_cases() -> list[Case]:
    late = {  # a second run with --overwrite that must fail: argv tail, culprit
        "simulate": [(["--effects", "coulomb_friction:Fc=99999"], ("Fc",)),
                     (["--controller", "{tmp}/missing.json"], ("missing.json",)),
                     (["--model", "{tmp}/garbage.json"], ("garbage.json",))],
        "excite": [(["--f1", "600", "--rate", "1000"], ("--f1",))],
        "identify": [(["--input", "nonexistent_col"], ("nonexistent_col",))],
        "curves": [(["--gains", "Kp=abc"], ("Kp",)), (["--model", "{tmp}/garbage.json"], ("garbage.json",))],
        "simulate-campaign": [(["--effects", "bogus_effect"], ("bogus_effect",)),
                              (["--model", "{tmp}/garbage.json"], ("garbage.json",))],
        "compare": [(["--effects", "bogus_effect"], ("bogus_effect",)),
                    (["--model", "{tmp}/missing.json"], ("missing.json",))],
        "diagnose": [(["--candidates", "bogus_effect"], ("bogus_effect",)),
                     (["--holdout", "bogus_run"], ("bogus_run",))],
        "bench": [(["--model", "{tmp}/missing.json"], ("missing.json",))],
        "tune": [(["--model", "{tmp}/garbage.json"], ("garbage.json",))],
        "perf": [(["--sizes", "0"], ("--sizes",))],
        "demo": [],
        "model": [(["--from", "{tmp}/missing.json"], ("missing.json",)), (["--effects", "bogus_effect"],
                                                                          ("bogus_effect",))],
        "train": [],
        "export-controller": [],  # its one input is the positional: below, a controller that learned nothing
        "export-drive": [(["--condition", "7,30,9"], ("7 sets 30 deg 9 Hz",))],
        "export-fmu": [(["{tmp}/garbage.json"], ("garbage.json",)), (["--controller", "{tmp}/missing.json"],
                                                                     ("missing.json",)),
                       (["--controller", "{fx}/learned.json"], ("--controller",))],
    }
    bad_number = {"simulate": "--cycles", "excite": "--duration", "identify": "--poles", "curves": "--disc-sets",
                  "simulate-campaign": "--duration", "compare": None, "diagnose": "--fit-window",
                  "bench": "--cycles", "tune": "--phase-margin", "perf": "--seconds", "demo": None,
                  "model": "--zeta", "train": "--total-steps", "export-controller": None, "export-drive": None,
                  "export-fmu": "--disc-sets"}
    cases = []
    for name, argv in EARLIER.items():
        argv = list(argv)
        if name in ("compare", "diagnose"):
            argv = [a.replace("{fx}/camp", "{tmp}/camp") for a in argv]

            def extra(tmp, fx):
                with_camp(tmp, fx)
        else:
            extra = None
        has_overwrite = name not in ("train", "demo")
        # 1. the same command again, no --overwrite
        if name != "demo":  # an earlier demo is replaced anyway (by design)
            cases.append(Case("lost", f"{name}: again without --overwrite", argv, "refuse",
                              ("--overwrite", "--resume", "exists"), setup=earlier_setup(name, extra),
                              protect=("out",)))
        # 2. --overwrite with a bad number
        opt = bad_number[name]
        if opt:
            a = without(argv, opt) + [opt, "nan"] + (["--overwrite"] if has_overwrite else [])
            cases.append(Case("lost", f"{name}: --overwrite {opt} nan", a, "refuse", (opt,),
                              setup=earlier_setup(name, extra), protect=("out",)))
        # 3. --overwrite with a bad input found later
        for tail, culprit in late[name]:
            a = argv + tail + (["--overwrite"] if has_overwrite else [])
            cases.append(Case("lost", f"{name}: --overwrite {' '.join(tail)}", a, "refuse", culprit,
                              setup=earlier_setup(name, extra), protect=("out",)))
    # train: resume with a broken config; an agent folder given as --out of a new training
    tr = EARLIER["train"]
    cases.append(Case("lost", "train: --resume with a broken config",
                      without(tr, "--config") + ["--config", "{tmp}/garbage.toml", "--resume"], "refuse",
                      ("garbage.toml",), setup=earlier_setup("train"), protect=("out",)))
    cases.append(Case("lost", "train: --resume --total-steps 5 (fewer than done)",
                      without(tr, "--total-steps") + ["--total-steps", "5", "--resume"], "either",
                      ("--total-steps",), setup=earlier_setup("train"), protect=()))
    # demo: an earlier demo is replaced anyway; a failing demo must keep it
    cases.append(Case("lost", "demo: over an earlier demo, --out under it is a file",
                      ["demo", "--quick", "--out", "{tmp}/out/demo/README.md"], "refuse", ("README.md",),
                      setup=earlier_setup("demo"), protect=("out",)))
    # outputs onto inputs
    cases += [
        Case("lost", "compare CAMP --out CAMP --overwrite (the report onto the campaign)",
             ["compare", "{tmp}/camp", "--out", "{tmp}/camp", "--overwrite"], "refuse", ("--out", "camp"),
             setup=with_camp, protect=("camp",)),
        Case("lost", "diagnose CAMP --out CAMP --overwrite",
             ["diagnose", "{tmp}/camp", *DIAG_FAST, "--out", "{tmp}/camp", "--overwrite"], "refuse",
             ("--out", "camp"), setup=with_camp, protect=("camp",)),
        Case("lost", "diagnose CAMP --json CAMP/cl_3sets_20deg_1hz.json --overwrite (onto a sidecar)",
             ["diagnose", "{tmp}/camp", *DIAG_FAST, "--json", "{tmp}/camp/cl_3sets_20deg_1hz.json", "--overwrite"],
             "refuse", ("--json", "cl_3sets_20deg_1hz.json"), setup=with_camp, protect=("camp",)),
        Case("lost", "compare CAMP --save-model CAMP/cl_3sets_20deg_1hz.json --overwrite (onto a sidecar)",
             ["compare", "{tmp}/camp", "--save-model", "{tmp}/camp/cl_3sets_20deg_1hz.json", "--overwrite"],
             "refuse", ("--save-model", "cl_3sets_20deg_1hz.json"), setup=with_camp, protect=("camp",)),
        Case("lost", "simulate-campaign --out CAMP --overwrite (an earlier campaign replaced on request)",
             ["simulate-campaign", "--duration", "0.21", "--out", "{tmp}/camp", "--overwrite"], "accept", (),
             setup=with_camp),
        Case("lost", "identify RUN --json RUN.csv --overwrite (onto its own input)",
             ["identify", "{tmp}/run/chirp.csv", "--no-plots", "--out", "{tmp}/o", "--json", "{tmp}/run/chirp.csv",
              "--overwrite"], "refuse", ("--json", "chirp.csv"),
             setup=lambda tmp, fx: copytree(fx / "excite", tmp / "run"), protect=("run",)),
        Case("lost", "identify RUN --out FOLDER-OF-RUN --overwrite (plots onto the input's folder)",
             ["identify", "{tmp}/run/chirp.csv", "--out", "{tmp}/run", "--overwrite"], "refuse", ("--out", "run"),
             setup=lambda tmp, fx: copytree(fx / "excite", tmp / "run"), protect=("run",)),
        Case("lost", "bench CTRL --out FOLDER-OF-CTRL --overwrite (the controller file must stay)",
             ["bench", "{tmp}/ctl/model.json", *BENCH_FAST, "--out", "{tmp}/ctl", "--overwrite"], "accept", (),
             setup=lambda tmp, fx: copytree(fx / "ctrl", tmp / "ctl"), protect=("ctl/model.json", "ctl/relay.json")),
        Case("lost", "tune --start C.json --out C.json --overwrite (in place)",
             ["tune", "--method", "optimize", "--disc-sets", "1", "--freq", "1", "--amplitude", "10", "--max-evals",
              "2", "--start", "{tmp}/c.json", "--out", "{tmp}/c.json", "--overwrite", "--no-progress"], "either",
             ("--out",), setup=lambda tmp, fx: shutil.copy(fx / "ctrl/model.json", tmp / "c.json")),
        Case("lost", "model new M --from M --overwrite --zeta 0.5 (in place)",
             ["model", "new", "{tmp}/m.json", "--from", "{tmp}/m.json", "--zeta", "0.5", "--overwrite"], "accept", (),
             setup=lambda tmp, fx: shutil.copy(fx / "model.json", tmp / "m.json")),
        Case("lost", "simulate --out CAMP/RUN --overwrite (a run of a campaign, replaced on request)",
             ["simulate", *SIM, "--out", "{tmp}/camp/cl_3sets_20deg_1hz", "--overwrite"], "either", (),
             setup=with_camp),
    ]
    # the exports: a late refusal keeps the earlier export; a shared folder's other files (the input too) stay
    def unlearned(tmp, fx):
        d = json.loads((fx / "learned.json").read_text())
        d.pop("learned")
        wtext(tmp / "unlearned.json", json.dumps(d))

    def ctl_folder(input_name):
        def setup(tmp, fx):
            wtext(tmp / "ctl" / input_name, (fx / "learned.json").read_text())
            wtext(tmp / "ctl" / "my_notes.json", '{"rig": "B"}\n')
            wtext(tmp / "ctl" / "rig_log.csv", "t,x\n0,1\n")
        return setup
    cases += [
        Case("lost", "export-controller: --overwrite with a controller that learned nothing",
             ["export-controller", "{tmp}/unlearned.json", "--name", "rig", "--out", "{tmp}/out/c", "--overwrite"],
             "refuse", ("learned",), setup=earlier_setup("export-controller", unlearned), protect=("out",)),
        Case("lost", "export-controller CTRL --out FOLDER-OF-CTRL --overwrite (the controller file must stay)",
             ["export-controller", "{tmp}/ctl/model.json", "--out", "{tmp}/ctl", "--overwrite"], "accept", (),
             setup=lambda tmp, fx: copytree(fx / "ctrl", tmp / "ctl"), protect=("ctl/model.json", "ctl/relay.json")),
        Case("lost", "export-drive CTRL --out FOLDER-OF-CTRL --overwrite (the controller, the user's CSV and JSON "
                     "stay)", ["export-drive", "{tmp}/ctl/learned.json", "--out", "{tmp}/ctl", "--overwrite"],
             "accept", (), setup=ctl_folder("learned.json"),
             protect=("ctl/learned.json", "ctl/my_notes.json", "ctl/rig_log.csv")),
        Case("lost", "export-drive DIR/drive.json --out DIR --overwrite (the input named as the drive set's file)",
             ["export-drive", "{tmp}/ctl/drive.json", "--out", "{tmp}/ctl", "--overwrite"], "refuse",
             ("drive.json", "input"), setup=ctl_folder("drive.json"), protect=("ctl",)),
    ]
    # --overwrite must not take a user's own files with it
    own = [
        ("curves", ["curves", "--out", "{tmp}/out", "--overwrite"]),
        ("simulate-campaign", ["simulate-campaign", "--duration", "0.21", "--out", "{tmp}/out", "--overwrite"]),
        ("identify", ["identify", "{fx}/excite/chirp.csv", "--out", "{tmp}/out", "--overwrite"]),
        ("compare", ["compare", "{tmp}/camp", "--out", "{tmp}/out", "--overwrite"]),
        ("diagnose", ["diagnose", "{tmp}/camp", *DIAG_FAST, "--out", "{tmp}/out", "--overwrite"]),
        ("bench", ["bench", "{fx}/ctrl/model.json", *BENCH_FAST, "--out", "{tmp}/out", "--overwrite"]),
        ("perf", ["perf", *PERF_FAST, "--out", "{tmp}/out", "--overwrite"]),
        ("export-controller", ["export-controller", "{fx}/ctrl/model.json", "--out", "{tmp}/out", "--overwrite"]),
        ("export-drive", ["export-drive", "{fx}/learned.json", "--out", "{tmp}/out", "--overwrite"]),
    ]
    # ... nor a file the user added to an earlier output folder afterwards
    added = {"curves": "out/curves", "simulate-campaign": "out/camp", "identify": "out/id", "compare": "out/report",
             "diagnose": "out/diag", "demo": "out/demo"}
    for name, folder in added.items():
        argv = list(EARLIER[name])
        if name in ("compare", "diagnose"):
            argv = [a.replace("{fx}/camp", "{tmp}/camp") for a in argv]
        argv = argv + (["--overwrite"] if name != "demo" else [])

        def extra(tmp, fx, name=name, folder=folder):
            if name in ("compare", "diagnose"):
                with_camp(tmp, fx)
            wtext(tmp / folder / "my_notes.txt", "what I saw on the rig\n")

        cases.append(Case("lost", f"{name} --overwrite over an earlier output holding a file the user added", argv,
                          "either", ("--overwrite", "my_notes.txt"), setup=earlier_setup(name, extra),
                          protect=(f"{folder}/my_notes.txt",)))
    for name, argv in own:
        def setup(tmp, fx, argv=argv):
            if needs_camp(argv):
                with_camp(tmp, fx)
            wtext(tmp / "out" / "my_thesis.tex", "\\section{Results}\n")
            wtext(tmp / "out" / "data" / "rig_log.csv", "t,x\n0,1\n")
        cases.append(Case("lost", f"{name} --overwrite over a folder of the user's own files", argv, "either",
                          ("--overwrite", "out"), setup=setup, protect=("out/my_thesis.tex", "out/data")))
    return cases


# -- interrupted overwrites -------------------------------------------------------------------------------
def interrupt_cases() -> list[Case]:
    cases = []
    bench = ["bench", "{fx}/ctrl/relay.json", "--cycles", "20", "--no-progress", "--no-book", "--out",
             "{tmp}/out/bench", "--overwrite"]
    for sig, trig in ((signal.SIGINT, "first+0"), (signal.SIGINT, "first+2"), (signal.SIGINT, "line=[bench] writing"),
                      (signal.SIGTERM, "first+1"), (signal.SIGTERM, "staging")):
        if True:
            cases.append(Case("interrupt", f"bench --overwrite, {signal.Signals(sig).name} at {trig}", bench,
                              "interrupt", mode="interrupt", setup=earlier_setup("bench"),
                              opts={"watch": "out/bench", "signal": sig, "trigger": trig,
                                    "new_names": names_of("newsets/bench")}))
    camp = ["simulate-campaign", "--duration", "30", "--seed", "1", "--perturb", "--out", "{tmp}/out/camp",
            "--overwrite"]
    camp_names = names_of("camp")
    for sig, trig in ((signal.SIGINT, "t=0.8"), (signal.SIGINT, "t=1.6"), (signal.SIGINT, "staging"),
                      (signal.SIGTERM, "t=1.2"), (signal.SIGTERM, "t=2"), (signal.SIGTERM, "staging")):
        if True:
            cases.append(Case("interrupt", f"simulate-campaign --overwrite, {signal.Signals(sig).name} at {trig}",
                              camp, "interrupt", mode="interrupt",
                              setup=earlier_setup("simulate-campaign"),
                              opts={"watch": "out/camp", "signal": sig, "trigger": trig, "new_names": camp_names}))
    others = [
        ("simulate", ["simulate", "--cycles", "300", "--freq", "1", "--out", "{tmp}/out/run", "--overwrite"], "out",
         lambda fx: {"run.csv", "run.json"}),
        ("curves", ["curves", "--disc-sets", "5", "--out", "{tmp}/out/curves", "--overwrite"], "out/curves",
         names_of("earlier/curves/out/curves")),
        ("demo", ["demo", "--quick", "--out", "{tmp}/out/demo"], "out/demo", names_of("earlier/demo/out/demo")),
        ("compare", ["compare", "{tmp}/camp", "--effects", "coulomb_friction", "--fit", "--out", "{tmp}/out/report",
                     "--overwrite"], "out/report", names_of("earlier/compare/out/report")),
        ("diagnose", ["diagnose", "{tmp}/camp", "--no-propose", "--out", "{tmp}/out/diag", "--overwrite"],
         "out/diag", names_of("earlier/diagnose/out/diag")),
        ("identify", ["identify", "{fx}/excite/chirp.csv", "--poles", "3", "--out", "{tmp}/out/id", "--overwrite"],
         "out/id", names_of("earlier/identify/out/id")),
        ("excite", ["excite", "chirp", "--duration", "600", "--out", "{tmp}/out/chirp", "--overwrite"], "out",
         lambda fx: {"chirp.csv", "chirp.json"}),
        ("export-controller", ["export-controller", "{fx}/ctrl/model.json", "--name", "rig", "--out", "{tmp}/out/c",
                               "--overwrite"], "out/c", names_of("earlier/export-controller/out/c")),
        ("export-drive", ["export-drive", "{fx}/learned.json", "--out", "{tmp}/out/drives", "--overwrite"],
         "out/drives", names_of("earlier/export-drive/out/drives")),
        # compiling the library is most of the run: signals before, during and after gcc
        ("export-fmu", ["export-fmu", "--out", "{tmp}/out/rig.fmu", "--overwrite"], "out", lambda fx: {"rig.fmu"}),
    ]
    last_line_of = {"curves": "line=[curves] 5/5", "demo": "line=2/2 Design point, simulated: done",
                    "compare": "line=writing the report"}
    for name, argv, watch, new_names in others:
        def setup(tmp, fx, name=name, argv=argv):
            earlier_setup(name)(tmp, fx)
            if needs_camp(argv):
                with_camp(tmp, fx)
        triggers = [(signal.SIGINT, "t=1.2"), (signal.SIGTERM, "staging")]
        if name == "export-fmu":  # one file, written at the end: no staging folder to wait for
            triggers = [(signal.SIGINT, "t=0.6"), (signal.SIGINT, "t=1.2"), (signal.SIGTERM, "t=1.8")]
        elif name in ("export-controller", "export-drive"):  # about a second in all: while the new set is written
            triggers = [(signal.SIGINT, "t=0.5"), (signal.SIGINT, "staging"), (signal.SIGTERM, "staging")]
        if name in last_line_of:
            triggers.append((signal.SIGINT, last_line_of[name]))
        for sig, trig in triggers:
            cases.append(Case("interrupt", f"{name} --overwrite, {signal.Signals(sig).name} at {trig}", argv,
                              "interrupt", mode="interrupt", setup=setup,
                              opts={"watch": watch, "signal": sig, "trigger": trig, "new_names": new_names}))
    return cases


# -- determinism --------------------------------------------------------------------------------------------
def determinism_cases() -> list[Case]:
    rows = [
        ("simulate --sensors --seed 5", ["simulate", *SIM, "--sensors", "--seed", "5", "--out", "o/run"],
         ["o/run.csv", "o/run.json"]),
        ("simulate-campaign --perturb --seed 3", ["simulate-campaign", "--duration", "0.5", "--perturb", "--seed",
                                                  "3", "--out", "c"], ["c/*.csv", "c/*.json"]),
        ("excite prbs --seed 2", ["excite", "prbs", "--duration", "2", "--seed", "2", "--out", "e/prbs"],
         ["e/prbs.csv", "e/prbs.json"]),
        ("excite multisine --seed 2", ["excite", "multisine", "--duration", "2", "--seed", "2", "--out", "e/ms"],
         ["e/ms.csv"]),
        ("identify", ["identify", "{fx}/excite/chirp.csv", "--no-plots", "--out", "i", "--json", "i.json"],
         ["i.json"]),
        ("tune --method model", ["tune", "--method", "model", "--no-progress", "--out", "t/model.json"],
         ["t/model.json"]),
        ("tune --method optimize --starts 2", ["tune", "--method", "optimize", "--disc-sets", "1", "--freq", "1",
                                               "--amplitude", "10", "--max-evals", "3", "--starts", "2",
                                               "--no-progress", "--out", "t/opt.json"], ["t/opt.json"]),
        ("bench", ["bench", "{fx}/ctrl/model.json", *BENCH_FAST, "--out", "b"], ["b/benchmark.csv"]),
        ("diagnose --json", ["diagnose", "{fx}/camp", *DIAG_FAST, "--json", "d.json"], ["d.json"]),
        ("compare --effects coulomb_friction --fit --save-model", ["compare", "{fx}/camp", "--effects",
                                                                   "coulomb_friction", "--fit", "--save-model",
                                                                   "m.json"], ["m.json"]),
        ("train --total-steps 200 --seed 1", ["train", *without(TRAIN_FAST, "--total-steps"), "--total-steps", "200",
                                              "--seed", "1", "--out", "tr"], ["tr/metrics.json"]),
        ("export-controller", ["export-controller", "{fx}/ctrl/model.json", "--out", "c"], ["c/*.h", "c/*.c"]),
        ("export-drive", ["export-drive", "{fx}/learned.json", "--out", "d"], ["d/*.csv", "d/*.json"]),
        ("export-fmu (compiled)", ["export-fmu", "--out", "f/rig.fmu"], ["f/rig.fmu"]),
    ]
    cases = [Case("determinism", what, argv, "same", mode="twice", opts={"files": files}) for what, argv, files in rows]
    cases.append(Case("determinism", "size --format json (stdout)", ["size", "--format", "json", "--table", "loads"],
                      "same", mode="twice", opts={"files": [], "stdout": True}))
    # bench with 1 and 2 workers: the same numbers
    cases.append(Case("determinism", "bench --workers 2 vs the table of --workers 1",
                      ["bench", "{fx}/ctrl/model.json", *BENCH_FAST, "--workers", "2", "--out", "b"], "same",
                      mode="twice", opts={"files": ["b/benchmark.csv"]}))
    return cases


# -- the Python API --------------------------------------------------------------------------------------
def api_cases() -> list[Case]:
    P = "from ehas_env.simulation.plant import Plant\n"
    G = "import gymnasium, numpy as np, ehas_env\n"
    N = "import numpy as np\n"
    rows = [
        (P + "result = Plant(disc_sets=0)", "refuse", ("disc_sets",)),
        (P + "result = Plant(disc_sets=float('nan'))", "refuse", ("disc_sets",)),
        (P + "result = Plant(disc_sets=2.5)", "refuse", ("disc_sets",)),
        (P + "result = Plant(disc_sets=True)", "refuse", ("disc_sets",)),
        (P + "result = Plant(disc_sets='3')", "refuse", ("disc_sets",)),
        (P + "result = Plant(3, dt=0)", "refuse", ("dt",)),
        (P + "result = Plant(3, dt=float('nan'))", "refuse", ("dt",)),
        (P + "result = Plant(3, substeps=0)", "refuse", ("substeps",)),
        (P + "result = Plant(3, inertia=-1)", "refuse", ("inertia",)),
        (P + "result = Plant(3, seed=-1)", "refuse", ("seed",)),
        (P + "result = Plant(3, effects={'bogus_effect': {}})", "refuse", ("bogus_effect",)),
        (P + "result = Plant(3, effects={'coulomb_friction': {'Fc': float('nan')}})", "refuse", ("Fc",)),
        (P + "result = Plant(3, effects='coulomb_friction:Fc=300')", "either", ("effects",)),
        (P + "result = Plant(3, effects=5)", "refuse", ("effects",)),
        (P + "result = Plant(3, valve='black_box')", "refuse", ("black_box", "valve")),
        (P + "result = Plant(3, effects_path='/no/such/folder')", "refuse", ("/no/such/folder",)),
        (P + "result = Plant(3, model='{tmp}/missing.json')", "refuse", ("missing.json",)),
        (P + "result = Plant(3, model={'format': 'ehas-model', 'version': 2, 'valve': {'zeta': 0}})", "refuse",
         ("zeta",)),
        (P + "result = Plant(3).simulate_closed_loop(amplitude_deg=float('nan'))", "refuse", ("amplitude",)),
        (P + "result = Plant(3).simulate_closed_loop(amplitude_deg=60)", "refuse", ("amplitude",)),
        (P + "result = Plant(3).simulate_closed_loop(freq_hz=0)", "refuse", ("freq",)),
        (P + "result = Plant(3).simulate_closed_loop(cycles=1e308)", "refuse", ("cycles",)),
        (P + "result = Plant(3).simulate_closed_loop(cycles=-1)", "refuse", ("cycles",)),
        (P + "result = Plant(3).simulate_closed_loop(duration=0)", "refuse", ("duration",)),
        (P + "result = Plant(3).simulate_closed_loop(duration=float('inf'))", "refuse", ("duration",)),
        (P + "result = Plant(3).simulate_closed_loop(theta0_deg=90)", "refuse", ("theta0",)),
        (P + "result = Plant(3).simulate_closed_loop(controller='pid')", "refuse", ("controller",)),
        (P + N + "result = Plant(3).simulate_valve_test(np.full(100, np.nan))", "refuse", ("current",)),
        (P + N + "result = Plant(3).simulate_valve_test(np.array([]))", "refuse", ("current",)),
        (P + N + "result = Plant(3).simulate_valve_test(np.zeros((10, 10)))", "refuse", ("current",)),
        (P + N + "result = Plant(3).simulate_valve_test(np.zeros(100), supply_bar=0)", "refuse", ("supply",)),
        (P + N + "result = Plant(3).simulate_valve_test(np.full(100, 1e308))", "either", ("current",)),
        (P + N + "result = Plant(3).simulate_valve_test('abc')", "refuse", ("current",)),
        (G + "result = gymnasium.make('ehas/Tracking-v0', disc_sets=9)", "refuse", ("disc_sets",)),
        (G + "result = gymnasium.make('ehas/Tracking-v0', amplitude_deg=50)", "refuse", ("amplitude",)),
        (G + "result = gymnasium.make('ehas/Tracking-v0', freq_hz=-1)", "refuse", ("freq",)),
        (G + "result = gymnasium.make('ehas/Tracking-v0', cycles=float('nan'))", "refuse", ("cycles",)),
        (G + "result = gymnasium.make('ehas/Tracking-v0', bogus_kwarg=1)", "refuse", ("bogus_kwarg",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0'); e.reset(seed=0)\n"
             "result = e.step(np.array([np.nan], dtype=np.float32))[0]", "refuse", ("action",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0'); e.reset(seed=0)\n"
             "result = e.step(np.array([np.inf], dtype=np.float32))[0]", "refuse", ("action",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0'); e.reset(seed=0)\nresult = e.step(np.zeros(5))[0]", "refuse",
         ("action",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0'); e.reset(seed=0)\nresult = e.step(float('nan'))[0]", "refuse",
         ("action",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0'); e.reset(seed=0)\nresult = e.step('abc')[0]", "refuse",
         ("action",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0', disable_env_checker=True)\nresult = e.step(np.zeros(1))",
         "refuse", ("reset",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0')\nresult = e.reset(options={'disc_sets': 0})", "refuse",
         ("disc_sets",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0')\nresult = e.reset(options={'bogus': 1})", "refuse",
         ("bogus",)),
        (G + "e = gymnasium.make('ehas/Tracking-v0')\nresult = e.reset(seed=-1)", "refuse", ("seed",)),
        ("from ehas_env.env.vector_env import TrackingVectorEnv\nresult = TrackingVectorEnv(0)", "refuse",
         ("num_envs",)),
        ("import numpy as np\nfrom ehas_env.env.vector_env import TrackingVectorEnv\ne = TrackingVectorEnv(2)\n"
         "e.reset(seed=0)\nresult = e.step(np.zeros((3, 1)))", "refuse", ("action",)),
        ("import numpy as np\nfrom ehas_env.env.vector_env import TrackingVectorEnv\ne = TrackingVectorEnv(2)\n"
         "e.reset(seed=0)\nresult = e.step(np.full((2, 1), np.nan, dtype=np.float32))[0]", "refuse", ("action",)),
        ("from ehas_env.measurement.campaign import read_campaign\nresult = read_campaign('{tmp}/nonexistent')",
         "refuse", ("nonexistent",)),
        ("from ehas_env.measurement.campaign import read_campaign\nresult = read_campaign('{tmp}/plainfile')",
         "refuse", ("plainfile",)),
        ("from ehas_env.measurement.campaign import read_campaign\nresult = read_campaign(None)", "refuse",
         ("None", "path", "folder")),
        ("from ehas_env.measurement.campaign import read_campaign\n"
         "result = read_campaign('{fx}/camp', columns={'theta_deg': 'Nope'})", "refuse", ("Nope",)),
        ("from ehas_controllers.base import load_controller\nresult = load_controller('{tmp}/missing.json')",
         "refuse", ("missing.json",)),
        ("from ehas_controllers.base import controller_from_dict\n"
         "result = controller_from_dict({'type': 'piff', 'gains': {'Kp': float('nan')}})", "refuse", ("Kp",)),
        ("from ehas_controllers.base import controller_from_dict\n"
         "result = controller_from_dict({'type': 'piff', 'gains': {'Kq': 1.0}})", "refuse", ("Kq",)),
        ("from ehas_controllers.base import controller_from_dict\nresult = controller_from_dict([])", "refuse",
         ("list", "object")),
        ("from ehas_controllers.base import controller_from_dict\n"
         "result = controller_from_dict({'type': 'piff', 'gains': {'Kp': 1}, 'rate_hz': 0})", "refuse",
         ("rate_hz",)),
        ("from ehas_env.simulation.model_file import load_model\nresult = load_model('{tmp}/missing.json')",
         "refuse", ("missing.json",)),
        ("from ehas_env.simulation.model_file import parse_model\n"
         "result = parse_model({'format': 'ehas-model', 'version': 2, 'rig': {'crank_radius_mm': -5}}, 'x.json')",
         "refuse", ("crank_radius_mm",)),
        (P + "from ehas_env.simulation.sensors import Sensors\nresult = Plant(3, sensors=Sensors(adc_bits=99))",
         "refuse", ("adc_bits",)),
        (P + "from ehas_env.simulation.sensors import Sensors\nresult = Plant(3, sensors=Sensors(theta_noise_deg=-1))",
         "refuse", ("theta_noise_deg",)),
        (P + "from ehas_env.simulation.sensors import Sensors\n"
             "result = Plant(3, sensors=Sensors(flow_noise_lpm=float('nan')))", "refuse", ("flow_noise_lpm",)),
        (P + "from ehas_env.simulation.sensors import Sensors\n"
             "result = Plant(3, sensors=Sensors(lvdt_gain_error=5))", "refuse", ("lvdt_gain_error",)),
        # the exports' library (controllers/export_c.py, ehas_env/simulation/fmu.py)
        ("from ehas_controllers.export_c import controller_c\nfrom ehas_controllers.ilc import ILC\n"
         "from ehas_controllers.piff import PIFF\nresult = controller_c(ILC(PIFF.book()))", "refuse", ("learned",)),
        ("from ehas_controllers.export_c import controller_c\nresult = controller_c('piff')", "refuse",
         ("str", "C export takes")),
        ("from ehas_env.simulation.fmu import fmu_sources\nresult = fmu_sources(disc_sets=9)", "refuse",
         ("disc_sets",)),
        ("from ehas_env.simulation.fmu import fmu_sources\nresult = fmu_sources('{tmp}/missing.json')", "refuse",
         ("missing.json",)),
        ("from ehas_env.simulation.fmu import write_fmu\nresult = write_fmu('{tmp}/x.fmu', controller=object())",
         "refuse", ("compiled law",)),
    ]
    return [Case("api", code.splitlines()[-1][:90], [code], expect, culprit, mode="api") for code, expect, culprit in rows]


# -- command-line misc -------------------------------------------------------------------------------------
def misc_cases() -> list[Case]:
    S = base_argv(["simulate"])
    rows = [
        (["simulate", "--cylces", "3"], "refuse", ("--cylces",)),
        (["simulate", "--cycles"], "refuse", ("--cycles",)),
        (["simulate", "extra_positional"], "refuse", ("extra_positional",)),
        (S + ["--cycles", "4"], "either", ("--cycles",)),
        (["simulate", "--cyc", "3", "--out", "{tmp}/o/run"], "either", ("--cyc",)),
        (["tune", "--out", "{tmp}/c.json"], "refuse", ("--method",)),
        (["size", "--bogus"], "refuse", ("--bogus",)),
        (["--bogus"], "refuse", ("--bogus",)),
        ([], "accept", ()),
        (["--version"], "accept", ()),
        (S + ["--freq", "3", "--amplitude", "10.5"], "accept", ()),
        (S + ["--amplitude", "44.4"], "either", ("--amplitude",)),
        (S + ["--amplitude", "44.43"], "refuse", ("--amplitude",)),
        (without(S, "--cycles") + ["--freq", "0.01", "--cycles", "10"], "refuse", ("--cycles", "--freq")),
        (without(S, "--cycles") + ["--freq", "50", "--cycles", "3"], "accept", ()),
        (without(S, "--cycles") + ["--cycles", "3.5"], "accept", ()),
        (without(S, "--cycles") + ["--cycles", "0x10"], "refuse", ("--cycles",)),
        (without(S, "--cycles") + ["--cycles", " 3 "], "either", ("--cycles",)),
        (without(S, "--cycles") + ["--cycles", "٣"], "either", ("--cycles",)),
        (without(S, "--cycles") + ["--cycles", "3_0"], "either", ("--cycles",)),
        (S + ["--disc-sets", "7.0"], "accept", ()),
        (S + ["--disc-sets", "3.5"], "refuse", ("--disc-sets",)),
        (S + ["--seed", "4294967295", "--sensors"], "accept", ()),
        (S + ["--seed", "4294967296"], "refuse", ("--seed",)),
        (S + ["--plot"], "accept", ()),
        (S + ["--model", "{fx}/model.json", "--gains", "Kp=1,Ki=2"], "accept", ()),
        (S + ["--effects", "coulomb_friction:Fc=300", "--sensors"], "accept", ()),
        (["excite", "chirp", "--duration", "1", "--f0", "10", "--f1", "5", "--out", "{tmp}/o/x"], "either",
         ("--f0", "--f1")),
        (["excite", "multisine", "--duration", "1", "--f1", "600", "--out", "{tmp}/o/x"], "refuse", ("--f1",)),
        (["excite", "chirp", "--duration", "1", "--f1", "5000", "--out", "{tmp}/o/x"], "refuse", ("--f1",)),
        (["excite", "prbs", "--duration", "1", "--hold", "0.0001", "--out", "{tmp}/o/x"], "refuse", ("--hold",)),
        (["excite", "prbs", "--duration", "1", "--hold", "30", "--out", "{tmp}/o/x"], "refuse", ("--hold",)),
        (["excite", "prbs", "--duration", "100", "--order", "2", "--out", "{tmp}/o/x"], "either", ("--order",)),
        (["excite", "chirp", "--duration", "0.001", "--out", "{tmp}/o/x"], "refuse", ("--duration",)),
        (["excite", "chirp", "--duration", "1", "--offset", "20", "--amplitude", "20", "--out", "{tmp}/o/x"],
         "either", ("--offset", "--amplitude")),
        (["excite", "chirp", "--duration", "1", "--levels", "3", "--out", "{tmp}/o/x"], "either", ("--levels",)),
        (["excite", "multisine", "--duration", "1", "--lines", "100000", "--out", "{tmp}/o/x"], "refuse",
         ("--lines",)),
        (["excite", "chirp", "--duration", "3600", "--rate", "100000", "--out", "{tmp}/o/x"], "refuse",
         ("--duration", "--rate")),
        (["tune", "--method", "model", "--bandwidth", "100", "--out", "{tmp}/o/c.json", "--no-progress"], "either",
         ("--bandwidth",)),
        (["tune", "--method", "model", "--kdp", "0.5", "--out", "{tmp}/o/c.json", "--no-progress"], "either",
         ("--kdp", "--pressure-feedback")),
        (["tune", "--method", "relay", "--max-evals", "5", "--out", "{tmp}/o/c.json", "--no-progress"], "either",
         ("--max-evals",)),
        (["tune", "--method", "model", "--executor", "ray", "--workers", "0", "--out", "{tmp}/o/c.json"], "refuse",
         ("--workers",)),
        (["bench", "{fx}/ctrl/model.json", "{fx}/ctrl/model.json", *BENCH_FAST, "--out", "{tmp}/o"], "either",
         ("model.json",)),
        (["bench", "{fx}/ctrl/model.json", *BENCH_FAST, "--retune", "--out", "{tmp}/o"], "either", ("--retune",)),
        (["bench", "{fx}/ctrl/model.json", *BENCH_FAST, "--model", "{fx}/model.json", "--out", "{tmp}/o"], "accept",
         ()),
        (["identify", "{fx}/excite/chirp.csv", "--no-plots", "--out", "{tmp}/o", "--max-lag", "10000"], "either",
         ("--max-lag",)),
        (["identify", "{fx}/excite/chirp.csv", "--no-plots", "--out", "{tmp}/o", "--poles", "10", "--zeros", "9"],
         "either", ("--poles", "--zeros")),
        (["identify", "{fx}/excite/chirp.csv", "--no-plots", "--out", "{tmp}/o", "--initial-state", "estimate",
          "--intersample", "foh"], "accept", ()),
        (["diagnose", "{tmp}/camp", *DIAG_FAST, "--fit-window", "600"], "either", ("--fit-window",)),
        (["diagnose", "{tmp}/camp", "--no-stack", "--quiet", "--write-effect", "{tmp}/w/my_term.py"], "either",
         ("--write-effect",)),
        (["diagnose", "{tmp}/camp", "--no-stack", "--quiet", "--write-effect", "{tmp}/w/my-term.txt"], "refuse",
         ("--write-effect", "my-term")),
        (["compare", "{tmp}/camp", "--effects", "coulomb_friction", "--fit", "--save-model", "{tmp}/m.json"],
         "accept", ()),
        (["compare", "{tmp}/camp", "--save-model", "{tmp}/m.txt"], "either", ("--save-model", "m.txt")),
        (["size", "--inertia", "1", "--radius", "0.001"], "either", ("--radius", "--inertia")),
        (["size", "--amplitude", "89", "--freq", "1000"], "either", ("--amplitude", "--freq")),
        (["size", "--model", "{fx}/model.json", "--table", "design"], "accept", ()),
        (["model", "show", "{fx}/ctrl/model.json"], "refuse", ("model.json", "format")),
        (["model", "show", "{fx}/camp/cl_3sets_20deg_1hz.json"], "refuse", ("cl_3sets_20deg_1hz.json", "format")),
        (["model", "diff", "{fx}/model.json"], "refuse", ("B", "b")),
        (["model", "new", "{tmp}/m.txt"], "either", ("m.txt",)),
        (["perf", *PERF_FAST, "--out", "{tmp}/o", "--sizes", "1,2"], "accept", ()),
        (["simulate-campaign", "--duration", "0.21", "--out", "{tmp}/o", "--model", "{fx}/model.json",
          "--effects", "coulomb_friction:Fc=300", "--perturb"], "accept", ()),
        (["curves", "--out", "{tmp}/o", "--valve", "white_box", "--supplies", "350"], "accept", ()),
        (["effects", "coulomb_friction", "extra"], "refuse", ("extra",)),
        (["export-controller", "{fx}/ctrl/model.json", "--out", "{tmp}/o", "--name", "///"], "either", ("--name",)),
        (["export-controller", "{fx}/ctrl/model.json", "--out", "{tmp}/o", "--name", "  "], "refuse", ("--name",)),
        (["export-controller", "{fx}/learned.json", "--out", "{tmp}/o", "--name", "rig_harmonic"], "accept", ()),
        (["export-controller", "{fx}/agent_ppo", "--out", "{tmp}/o"], "refuse", ("agent_ppo",)),
        (["export-drive", "{fx}/learned.json", "--condition", "7,30", "--out", "{tmp}/o"], "refuse", ("--condition",)),
        (["export-drive", "{fx}/learned.json", "--condition", "7,30,abc", "--out", "{tmp}/o"], "refuse",
         ("--condition",)),
        (["export-drive", "{fx}/learned.json", "--condition", "9,30,3", "--out", "{tmp}/o"], "refuse",
         ("--condition",)),
        (["export-drive", "{fx}/learned.json", "--condition", "7,30,3", "--condition", "7,30,3", "--out", "{tmp}/o"],
         "either", ("--condition",)),
        (["export-drive", "{fx}/ctrl/model.json", "--out", "{tmp}/o"], "refuse", ("model.json",)),
        (["export-fmu", "{fx}/model.json", "--controller", "{fx}/ctrl/relay.json", "--closed-loop", "--disc-sets",
          "7", "--out", "{tmp}/o/rig.fmu"], "accept", ()),
        (["export-fmu", "--controller", "{fx}/agent_ppo", "--no-binary", "--out", "{tmp}/o/rig.fmu"], "refuse",
         ("--controller", "agent_ppo")),
        (["export-fmu", "--no-binary", "--out", "{tmp}/o/rig"], "refuse", ("--out", ".fmu")),
    ]
    cases = []
    for argv, expect, culprit in rows:
        cases.append(Case("misc", " ".join(argv[:4]) + (" ..." if len(argv) > 4 else ""), argv, expect, culprit,
                          setup=with_camp if needs_camp(argv) else None))
    return cases


FAMILIES = {
    "numeric": numeric_cases, "choice": choice_cases, "lists": list_cases, "paths": path_cases,
    "controller-json": controller_cases, "model-json": model_cases, "campaign": campaign_cases,
    "train-toml": train_cases, "effect-file": effect_cases, "agent-folder": agent_cases, "pipe": pipe_cases,
    "lost": lost_cases, "interrupt": interrupt_cases, "determinism": determinism_cases, "api": api_cases,
    "misc": misc_cases, "data-code": data_code_cases, "plugin": plugin_cases, "concurrent": concurrent_cases,
}


def all_cases(only: set | None) -> list[Case]:
    cases = []
    for fam, fn in FAMILIES.items():
        if only and fam not in only:
            continue
        got = fn()
        prefix = re.sub(r"[^a-z]", "", fam)[:4]
        for i, c in enumerate(got, 1):
            c.id = f"{prefix}{i:03d}"
        cases += got
    return cases


# ======================================================================================================
# the report
# ======================================================================================================
CLASS_ORDER = ["refused", "ok", "skipped", "traceback", "silent", "unclear", "refused_valid", "leftover", "lost",
               "mixed", "nondeterministic", "timeout", "ran_code", "setup_failed"]


def write_report(folder: Path, results: list[Result], argv_used: str, started: _dt.datetime, elapsed: float,
                 jobs: int) -> None:
    folder.mkdir(parents=True)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["id", "family", "case", "command", "expected", "outcome", "status", "seconds", "culprit",
                "last_stderr_line", "notes"])
    for r in results:
        r.last, r.notes = _clean(r.last)[:200], _clean(r.notes)
        w.writerow([r.case.id, r.case.family, r.case.what, r.command, r.case.expect, r.outcome, r.status,
                    f"{r.seconds:.2f}", " | ".join(r.case.culprit), r.last, r.notes])
    (folder / "cases.csv").write_text(buf.getvalue())

    counts: dict[str, int] = {}
    fam: dict[str, dict[str, int]] = {}
    for r in results:
        counts[r.outcome] = counts.get(r.outcome, 0) + 1
        fam.setdefault(r.case.family, {}).setdefault(r.outcome, 0)
        fam[r.case.family][r.outcome] += 1
    classes = [c for c in CLASS_ORDER if any(c in f for f in fam.values())]
    classes += sorted({c for f in fam.values() for c in f} - set(classes))
    bugs = [r for r in results if r.outcome not in GOOD_CLASSES]
    skipped = [r for r in results if r.outcome == "skipped"]
    L = []
    L.append("# Fault campaign of the ehas command line (issue 14)")
    L.append("")
    L.append("Regenerate with (about %d min on %d cores, %d parallel cases):" % (max(1, round(elapsed / 60)),
                                                                                 os.cpu_count() or 1, jobs))
    L.append("")
    L.append(f"    {argv_used}")
    L.append("")
    L.append("As root, file permissions are not enforced and the permission cases are skipped; to run them too, run "
             "as a normal user, e.g. as root: `chmod -R o+rX . && setpriv --reuid=nobody --regid=nogroup "
             "--clear-groups env HOME=/tmp/nobody-home python tests/fault_campaign.py --out /tmp/fc` (a writable "
             "HOME for the compiled-model cache), then copy `/tmp/fc` here.")
    L.append("")
    L.append(f"Run on {started.strftime('%Y-%m-%d %H:%M UTC')} in {elapsed / 60:.1f} min; "
             f"Python {platform.python_version()}, ehas {_ehas_version()}, commit {_git_commit()}; "
             f"{'as root (permission cases skipped)' if IS_ROOT else 'as a normal user'}.")
    L.append("")
    L.append(f"{len(results)} cases: every `ehas` subcommand run as a subprocess (`{' '.join(_short(EHAS))}`) in "
             "its own temporary folder, each with a 120 s timeout. `cases.csv` has one row per case "
             "(`$CASE` is the case's folder, `$FX` the fixtures: a tuned controller, a "
             "`simulate-campaign --duration 0.21` campaign, an `excite chirp --duration 1` run, a model file, "
             "a copy of `results/agents/ppo`, earlier outputs of each command).")
    L.append("")
    L.append("## Counts per outcome class")
    L.append("")
    L.append("| class | cases | meaning |")
    L.append("|---|---:|---|")
    meaning = {
        "refused": "clear refusal: status != 0, one line on stderr with `error:` naming the culprit",
        "ok": "valid (or unusual but valid) input handled; pipe closed quietly; interrupt left one whole set; "
              "repeated run identical",
        "skipped": "not run (permission cases: running as root)",
        "traceback": "`Traceback` or `internal error` on stderr (API: an exception type no user error should raise)",
        "silent": "status 0 for nonsense input",
        "unclear": "refused, but the last line does not name the culprit / has no `error:` / several lines / "
                   "says something wrong (a folder 'does not exist'); interrupts: the process died of the signal "
                   "instead of ending with status 130",
        "refused_valid": "a valid input refused",
        "leftover": "refused but files written, or hidden temporaries left",
        "lost": "earlier output or the user's own files changed or deleted",
        "mixed": "interrupted overwrite left files of two runs (or temporaries) in the output folder",
        "nondeterministic": "the same command twice gave different files",
        "timeout": "ran longer than 120 s",
        "setup_failed": "the campaign could not prepare the case (a bug of this script)",
    }
    for c in classes:
        L.append(f"| `{c}` | {counts.get(c, 0)} | {meaning.get(c, '')} |")
    L.append(f"| **total** | {len(results)} | |")
    L.append("")
    L.append("## Counts per family")
    L.append("")
    L.append("| family | cases | " + " | ".join(f"`{c}`" for c in classes) + " |")
    L.append("|---|---:|" + "---:|" * len(classes))
    for f, d in fam.items():
        L.append(f"| {f} | {sum(d.values())} | " + " | ".join(str(d.get(c, "")) for c in classes) + " |")
    L.append("")
    L.append("Families: `numeric` every numeric option of every command with NaN, inf, -inf (as `--opt=-inf`), "
             "-1, 0, 1e308, 1e-308, abc, 1,5 and a 40-digit integer (values inside the declared range must run or "
             "be refused clearly); `choice` unknown and empty choices; `lists` gains, effect specs, sizes, "
             "supplies, NAS counts, polynomials, column maps, hold-outs, candidates; `path-in` / `path-out` input "
             "and output paths (under a regular file, a folder for a file and back, missing, empty, binary garbage, "
             "new nested folders, spaces and non-ASCII, existing outputs); `controller-json`, `model-json`, "
             "`campaign`, `train-toml`, `effect-file`, `agent-folder` corrupted copies of valid files; `pipe` "
             "`| head -1` and a stdout nobody reads; `lost` earlier outputs under a failing second run, outputs "
             "onto inputs, `--overwrite` over a user's own files; `interrupt` SIGINT/SIGTERM during an overwrite; "
             "`determinism` the same command twice; `api` the Python API's refusals; `misc` the rest.")
    L.append("")
    L.append("Rules of the classifier: stderr lines starting with `[`, tqdm bars, `ehas CMD: ...` status lines "
             "and `warning:` lines before the last line are not counted as message lines (warnings are noted in "
             "the notes column). The culprit is a list of alternatives; the last line must contain one of them "
             "(case-insensitive). A refusal of a case expected to be refused is checked for files it left behind.")
    L.append("")
    L.append(f"## Cases that are not `refused` / `ok` / `skipped` ({len(bugs)})")
    L.append("")
    if not bugs:
        L.append("None.")
    by_class: dict[str, list[Result]] = {}
    for r in bugs:
        by_class.setdefault(r.outcome, []).append(r)
    for c in [c for c in CLASS_ORDER if c in by_class] + sorted(set(by_class) - set(CLASS_ORDER)):
        L.append(f"### `{c}` ({len(by_class[c])})")
        L.append("")
        L.append("| id | family | case | command | status | last stderr line | notes |")
        L.append("|---|---|---|---|---|---|---|")
        for r in by_class[c]:
            L.append(f"| {r.case.id} | {r.case.family} | {_md(r.case.what)} | `{_md(r.command, code=True)}` | "
                     f"{r.status} | {_md(r.last)} | {_md(r.notes)} |")
        L.append("")
    if skipped:
        L.append(f"## Skipped ({len(skipped)})")
        L.append("")
        for r in skipped:
            L.append(f"- {r.case.id} {r.case.what}: {r.notes}")
        L.append("")
    (folder / "README.md").write_text("\n".join(L) + "\n")


def _clean(text: str) -> str:
    """The temporary folders' paths as $CASE (the case's folder) and $FX (the fixtures)."""
    text = re.sub(re.escape(str(SCRATCH)) + r"/cases/[^/\s:]+", "$CASE", str(text))
    return text.replace(str(SCRATCH) + "/fx", "$FX").replace(str(SCRATCH), "$SCRATCH")


def _md(s: str, code: bool = False) -> str:
    s = str(s).replace("|", "\\|").replace("\n", " ")
    if code:
        s = s.replace("`", "'")
    return s[:400]


def _short(cmd):
    return ["python" if c == sys.executable else c for c in cmd]


def _ehas_version() -> str:
    try:
        from ehas_env import __version__
        return __version__
    except Exception:  # noqa: BLE001
        return "?"


def _git_commit() -> str:
    try:
        # safe.directory: run as another user than the checkout's owner (the permission cases), git refuses
        return subprocess.run(["git", "-c", f"safe.directory={ROOT}", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              timeout=10).stdout.strip() or "?"
    except (OSError, subprocess.TimeoutExpired):
        return "?"


# ======================================================================================================
def main(argv=None) -> int:
    global EHAS, ENV, KEEP, SCRATCH
    ap = argparse.ArgumentParser(prog="fault_campaign.py", description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, help="results folder (cases.csv, README.md)")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing non-empty --out")
    ap.add_argument("--jobs", type=int, default=2, help="cases run at the same time (default 2)")
    ap.add_argument("--only", default="", help="comma-separated families (default: all): " + ", ".join(FAMILIES))
    ap.add_argument("--keep", action="store_true", help="keep the case folders (printed at the end)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())) and not args.overwrite:
        print(f"fault_campaign.py: error: --out {out} exists and is not empty; pass --overwrite to replace it",
              file=sys.stderr)
        return 2
    if args.jobs < 1:
        print("fault_campaign.py: error: --jobs must be >= 1", file=sys.stderr)
        return 2
    only = {f.strip() for f in args.only.split(",") if f.strip()} or None
    if only and only - set(FAMILIES):
        print(f"fault_campaign.py: error: --only: unknown families {sorted(only - set(FAMILIES))}", file=sys.stderr)
        return 2
    KEEP = args.keep
    started = _dt.datetime.now(_dt.timezone.utc)
    t0 = time.monotonic()
    ENV = child_env()
    EHAS = ehas_cmd()
    scratch = SCRATCH = Path(tempfile.mkdtemp(prefix="ehas-fault-"))
    fx = scratch / "fx"
    try:
        print(f"[fault-campaign] fixtures in {fx} ...", file=sys.stderr, flush=True)
        make_fixtures(fx, args.jobs)
        fx_before = snapshot(fx)
        cases = all_cases(only)
        print(f"[fault-campaign] {len(cases)} cases (fixtures took {time.monotonic() - t0:.0f} s)", file=sys.stderr,
              flush=True)
        results: dict[str, Result] = {}
        lock = threading.Lock()
        done = [0]

        def one(case: Case) -> Result:
            try:
                r = run_case(case, scratch / "cases", fx)
            except Exception as exc:  # noqa: BLE001 - keep the campaign going, record the failure
                r = Result(case, "setup_failed", "", 0.0, "", f"{type(exc).__name__}: {exc}", shown(case.argv))
            with lock:
                results[case.id] = r
                done[0] += 1
                if r.outcome in BUG_CLASSES or r.outcome == "setup_failed":  # say it at once, not only at the end
                    print(f"[fault-campaign] {case.id} {r.outcome}: {r.command} | {r.last} | {r.notes}"[:600],
                          file=sys.stderr, flush=True)
                if done[0] % 25 == 0 or done[0] == len(cases):
                    tally: dict[str, int] = {}
                    for x in results.values():
                        tally[x.outcome] = tally.get(x.outcome, 0) + 1
                    print(f"[fault-campaign] {done[0]}/{len(cases)} cases, {(time.monotonic() - t0) / 60:.1f} min: "
                          + ", ".join(f"{k} {v}" for k, v in sorted(tally.items())), file=sys.stderr, flush=True)
            return r

        # slow families first, the many quick refusals last (they fill the tail); interrupts run in the pool too
        first = ["agent-folder", "interrupt", "determinism", "effect-file", "train-toml", "lost", "path-out",
                 "campaign", "misc", "lists", "path-in", "controller-json", "api", "model-json", "pipe", "choice",
                 "numeric"]
        order = sorted(cases, key=lambda c: first.index(c.family) if c.family in first else len(first))
        with ThreadPoolExecutor(max_workers=args.jobs) as ex:
            list(ex.map(one, order))
        if snapshot(fx) != fx_before:
            print("[fault-campaign] note: the fixtures changed during the campaign: "
                  + diff_snap(fx_before, snapshot(fx)), file=sys.stderr)
        ordered = [results[c.id] for c in cases]
        elapsed = time.monotonic() - t0
        cmdline = "python tests/fault_campaign.py --out " + shlex.quote(args.out) + (
            " --overwrite" if args.overwrite else "") + (f" --jobs {args.jobs}" if args.jobs != 2 else "") + (
            f" --only {args.only}" if args.only else "")
        stage = out.parent / f".{out.name}.fault-tmp.{os.getpid()}"
        if stage.exists():
            shutil.rmtree(stage)
        out.parent.mkdir(parents=True, exist_ok=True)
        write_report(stage, ordered, cmdline, started, elapsed, args.jobs)
        old = out.parent / f".{out.name}.fault-old.{os.getpid()}"
        if out.exists():
            os.rename(out, old)
        os.rename(stage, out)
        if old.exists():
            shutil.rmtree(old)
        tally: dict[str, int] = {}
        for r in ordered:
            tally[r.outcome] = tally.get(r.outcome, 0) + 1
        print(f"[fault-campaign] {len(ordered)} cases in {elapsed / 60:.1f} min: "
              + ", ".join(f"{k} {v}" for k, v in sorted(tally.items())) + f" -> {out}", file=sys.stderr)
        return 0
    except KeyboardInterrupt:
        print("fault_campaign.py: interrupted; nothing written", file=sys.stderr)
        return 130
    finally:
        if KEEP:
            print(f"[fault-campaign] case folders kept in {scratch}", file=sys.stderr)
        else:
            shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
