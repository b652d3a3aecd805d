"""The output layer: check output paths before any work, replace a command's output set as a whole.

Every writing command does two things through this module:

1. **Before any work** it checks where it will write (:func:`check_folder`,
   :func:`check_file`, :class:`OutputSet` at construction): a file where a
   folder is expected, a path under a file, a read-only folder, an earlier
   output that would be replaced without ``--overwrite``.  Each problem is one
   :class:`OutputError` (a ``ValueError``: the CLI prints it as one line,
   status 2) naming the option, the path and what is allowed.

2. **While working** it writes into a temporary folder beside the output
   (:class:`OutputSet`) and swaps it in at the end: the previous output is
   renamed away, the new one renamed in, the previous one deleted.  A run that
   fails, is interrupted (Ctrl-C) or killed leaves the previous complete set
   (or nothing); the next run removes what a killed run left behind (and puts
   back a previous set a kill caught halfway through the swap).

Two shapes of output set:

* a **folder** that belongs to the command (``ehas compare --out DIR``): the
  folder is the set and is swapped whole.  It carries a record of the files
  the command wrote (:data:`RECORD`); ``--overwrite`` replaces a folder only
  when every file in it is on that record, so a user's own files (a folder of
  notes given as ``--out`` by mistake, a file added to an output since) are
  never deleted;
* **members** of a shared folder (``ehas simulate --out results/simulate/run``
  writes ``run.csv`` + ``run.json``; ``ehas bench --out results`` writes
  ``benchmark*`` and ``heatmap_*.png``): the set is the files matching the
  command's patterns; old members are moved aside together, the new ones moved
  in, the sidecar/summary last.

Examples
--------
>>> import tempfile, pathlib
>>> work = tempfile.TemporaryDirectory()
>>> root = pathlib.Path(work.name)
>>> with OutputSet(root / "report", option="--out") as tmp:
...     _ = (tmp / "report.md").write_text("# new\\n")
>>> sorted(p.name for p in root.iterdir())
['report']
>>> OutputSet(root / "report", option="--out")
Traceback (most recent call last):
...
ehas_env.output.outputs.OutputError: --out ... already exists and is not empty; pass --overwrite to replace it
>>> work.cleanup()
"""
from __future__ import annotations

import contextlib
import errno
import fnmatch
import os
import re
import shutil
import signal
import threading
from pathlib import Path

TMP = "ehas-tmp"  # a run's output being written
OLD = "ehas-old"  # the previous output, moved aside during the swap
DONE = "ehas-done"  # the previous output after a complete swap, being deleted
#: the record of a folder set's files, written last into the folder (see :func:`foreign_files`)
RECORD = ".ehas-output.json"
_STALE = re.compile(r"^\.(?P<name>.*)\.(?P<what>ehas-tmp|ehas-old|ehas-done)\.(?P<pid>\d+)$")
_ATOMIC_TMP = re.compile(r"^\..+\.(?P<pid>\d+)\.[A-Za-z0-9_]+\.tmp$")  # ehas_env.output.files temporaries


class OutputError(ValueError):
    """An output path that cannot be used; the message names the option, the path and what is allowed."""


# -- checks before work --------------------------------------------------------------------------------
def _label(option: str | None, path: Path) -> str:
    return f"{option} {path}" if option else str(path)


def check_parent(path, option: str | None = None) -> Path:
    """The nearest existing folder above ``path``; OutputError if it is a file or not writable."""
    path = Path(path)
    p = path.absolute().parent
    while not (p.exists() or p.is_symlink()):
        p = p.parent
    if p.is_symlink() and not p.exists():
        raise OutputError(f"{_label(option, path)}: {p} is a dangling symbolic link")
    if not p.is_dir():
        raise OutputError(f"{_label(option, path)}: {p} is a file, not a folder; give a path in a folder")
    probe_writable(p, _label(option, path))
    return p


def _check_parent_shown(path: Path, shown: str) -> None:
    try:
        check_parent(path, None)
    except OutputError as exc:
        raise OutputError(f"{shown}: " + str(exc).split(": ", 1)[-1]) from None


def probe_writable(folder: Path, label: str) -> None:
    """OutputError unless a file can be made in ``folder`` (a real probe: permissions, read-only disks, /proc)."""
    probe = Path(folder) / f".ehas-probe.{os.getpid()}"
    try:
        os.mkdir(probe)
    except FileExistsError:
        pass
    except OSError as exc:
        raise OutputError(f"{label}: cannot write in {folder} ({exc.strerror or exc}); "
                          "give a path in a writable folder") from None
    try:
        os.rmdir(probe)
    except OSError:
        pass


def check_folder(path, option: str | None = "--out", *, overwrite: bool = False) -> Path:
    """Check that ``path`` can become this command's output folder (before any work).

    Allowed: a new path in a writable folder, an empty folder, or (with
    ``overwrite``) a folder of an earlier output, which is then replaced whole.
    """
    path = Path(path)
    if path.is_symlink() and not path.exists():
        raise OutputError(f"{_label(option, path)} is a dangling symbolic link; give a folder")
    if path.exists() and not path.is_dir():
        raise OutputError(f"{_label(option, path)} is a file; expected a folder (new, empty, or an earlier "
                          "output with --overwrite)")
    check_parent(path, option)
    if path.is_dir():
        try:
            entries = [e for e in os.listdir(path)]
        except PermissionError:
            raise OutputError(f"{_label(option, path)}: cannot read the folder (permission denied)") from None
        if entries and not overwrite:
            raise OutputError(f"{_label(option, path)} already exists and is not empty; pass --overwrite to "
                              "replace it")
        if entries:
            foreign = foreign_files(path)
            if foreign:
                shown = ", ".join(str(f) for f in foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
                raise OutputError(f"{_label(option, path)} holds files no ehas run wrote there ({shown}); "
                                  "--overwrite replaces only an ehas output folder: move them out or give a new folder")
            probe_writable(path, _label(option, path))
    return path


def foreign_files(folder) -> list[Path]:
    """The files in ``folder`` (relative paths) that are on no ehas output record.

    The records read are the folder's own, those of the folders above it (a
    folder inside an ehas output, such as ``ehas demo``'s campaign, which its
    README regenerates with ``ehas simulate-campaign --overwrite``, is that
    output's) and those of the folders inside it (that campaign, regenerated,
    carries its own record).
    A folder on no record (the user's own folder, or an output of an ehas
    version before the record) has no file on it.  Leftovers of killed runs
    and empty folders do not count.

    >>> import tempfile, pathlib
    >>> work = tempfile.TemporaryDirectory()
    >>> root = pathlib.Path(work.name)
    >>> with OutputSet(root / "report", option="--out") as tmp:
    ...     _ = (tmp / "report.md").write_text("# new\\n")
    >>> foreign_files(root / "report")
    []
    >>> _ = (root / "report" / "my_notes.txt").write_text("mine")
    >>> foreign_files(root / "report")
    [PosixPath('my_notes.txt')]
    >>> work.cleanup()
    """
    folder = Path(folder)
    known: set[str] = set()
    for owner in (folder.absolute(), *folder.absolute().parents):
        below = folder.absolute().relative_to(owner).as_posix()
        for name in _recorded(owner):
            if below == ".":
                known.add(name)
            elif name.startswith(below + "/"):
                known.add(name[len(below) + 1:])
    files = sorted(_files(folder))
    for f in files:  # outputs written inside it since (the demo's campaign regenerated) carry their own records
        if f.name == RECORD and f.parent != folder:
            below = f.parent.relative_to(folder).as_posix()
            known.update(f"{below}/{name}" for name in _recorded(f.parent))
    out = []
    for f in files:
        rel = f.relative_to(folder)
        if rel.name == RECORD or (len(rel.parts) == 1 and (_STALE.match(rel.name) or _ATOMIC_TMP.match(rel.name))):
            continue
        if rel.as_posix() not in known:
            out.append(rel)
    return out


def _recorded(folder: Path) -> list[str]:
    """The files on ``folder``'s record (none when it has no record, or a damaged one)."""
    from ehas_env.output.files import read_json

    try:
        if not (folder / RECORD).is_file():
            return []
        record = read_json(folder / RECORD, "an ehas output record")
        files = record["files"] if record.get("format") == "ehas-output-set" else []
        return [f for f in files if isinstance(f, str)]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):  # damaged: nothing is on it
        return []


def _files(folder: Path):
    for root, dirs, names in os.walk(folder, followlinks=False):
        for n in names + [d for d in dirs if os.path.islink(os.path.join(root, d))]:
            yield Path(root) / n


def write_record(folder) -> None:
    """Write ``folder``'s record of its files (:data:`RECORD`): they are this ehas output's own."""
    import json

    folder = Path(folder)
    files = sorted(f.relative_to(folder).as_posix() for f in _files(folder))
    files = [f for f in files if f != RECORD]
    text = json.dumps({"format": "ehas-output-set", "version": 1,
                       "about": "the files an ehas command wrote here; --overwrite replaces the folder only if "
                                "it holds no other file",
                       "files": files}, indent=1) + "\n"
    (folder / RECORD).write_text(text, encoding="utf-8")


def check_not_input(path, option: str | None, inputs) -> None:
    """Refuse an output ``path`` that is one of the command's ``inputs``, holds one, or lies in an input folder's
    files: even with ``--overwrite``, a command never writes over what it reads.

    >>> check_not_input("camp", "--out", ["camp"])
    Traceback (most recent call last):
    ...
    ehas_env.output.outputs.OutputError: --out camp is this command's input camp; write the output elsewhere
    """
    out = Path(path).absolute().resolve()
    for item in inputs:
        if item is None or str(item) == "":
            continue
        src = Path(item).absolute().resolve()
        if out == src:
            raise OutputError(f"{_label(option, Path(path))} is this command's input {item}; write the output "
                              "elsewhere")
        if src.is_relative_to(out):
            raise OutputError(f"{_label(option, Path(path))} holds this command's input {item}; replacing it would "
                              "delete the input: write the output elsewhere")
        if src.is_dir() and out.is_relative_to(src) and out.suffix.lower() in (".csv", ".json"):
            raise OutputError(f"{_label(option, Path(path))} lies among the run files of the input {item}; write "
                              "the output elsewhere")


def check_file(path, option: str | None = None, *, overwrite: bool = False, suffix: str | None = None) -> Path:
    """Check that the file ``path`` can be written (before any work).

    Refused: a folder, a path under a file, an unwritable folder, and an
    existing file without ``overwrite``.
    """
    path = Path(path)
    if str(path).endswith(os.sep) or path.is_dir():
        raise OutputError(f"{_label(option, path)} is a folder; expected a file name")
    if suffix and path.suffix.lower() != suffix:
        raise OutputError(f"{_label(option, path)}: expected a {suffix} file name")
    check_parent(path, option)
    if (path.exists() or path.is_symlink()) and not overwrite:
        raise OutputError(f"{_label(option, path)} already exists; pass --overwrite to replace it")
    lock(path, option)
    # written later through files.atomic_write_*: exclusively (without overwrite) and, inside a command, only
    # when the command succeeds (files.begin / files.finish)
    from ehas_env.output import files

    files.CLAIMED[os.path.abspath(path)] = (option, overwrite)
    return path


# -- one writer per output -------------------------------------------------------------------------------
LOCK = "ehas-lock"
_HELD: dict[str, int] = {}


def _lock_path(path: Path) -> Path:
    path = Path(os.path.abspath(path))
    return path.parent / f".{path.name}.{LOCK}"


def lock(path, option: str | None = None, lock_file: Path | None = None) -> Path:
    """Claim the output ``path`` for this process: a second run writing the same output refuses in one line.

    The claim is a file ``.NAME.ehas-lock`` beside the output, created exclusively (``O_EXCL``) and holding
    the pid; a claim of a process that is gone is taken over.  Released by :func:`unlock` (an
    :class:`OutputSet` at its end, every claim at the process's exit).
    """
    lk = lock_file or _lock_path(path)
    key = str(lk)
    if _HELD.get(key) == os.getpid():
        return lk
    for _ in range(3):
        try:
            fd = os.open(lk, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            try:
                pid = int(lk.read_text().strip() or 0)
            except (OSError, ValueError):
                pid = 0
            if pid and pid != os.getpid() and _alive(pid):
                raise OutputError(f"{_label(option, Path(path))}: another ehas run (pid {pid}) is writing this "
                                  f"output now; wait for it to finish (or remove {lk} if no ehas runs)") from None
            try:
                lk.unlink()  # a finished or killed run's claim
            except FileNotFoundError:
                pass
            continue
        except OSError:
            return lk  # the folder is checked elsewhere (check_parent); no claim file where none can be made
        with os.fdopen(fd, "w") as fh:
            fh.write(f"{os.getpid()}\n")
        _HELD[key] = os.getpid()
        return lk
    raise OutputError(f"{_label(option, Path(path))}: cannot claim this output ({lk} keeps reappearing)")


def unlock(lk) -> None:
    """Release a claim of :func:`lock` held by this process."""
    key = str(lk)
    if _HELD.get(key) == os.getpid():
        del _HELD[key]
        try:
            if Path(key).read_text().strip() == str(os.getpid()):
                os.unlink(key)
        except OSError:
            pass


def unlock_all() -> None:
    """Release every claim of this process (at the end of a command and at exit)."""
    for key in [k for k, pid in _HELD.items() if pid == os.getpid()]:
        unlock(key)


import atexit  # noqa: E402

from ehas_env.output import files as _transaction  # noqa: E402  (the command transaction of output.files)

atexit.register(unlock_all)
_transaction.AT_FINISH.append(unlock_all)  # a command's end releases its claims (files.finish)


# -- stale leftovers -------------------------------------------------------------------------------------
def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process
    except OSError:
        return False
    return True


def _rm(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        try:
            path.unlink()
        except FileNotFoundError:
            pass


def clean_stale(folder) -> list[Path]:
    """Remove what killed ehas runs left in ``folder``; put back a previous output caught mid-swap.

    Returns the entries removed.  Entries of live processes (a concurrent run)
    are left alone.
    """
    folder = Path(folder)
    removed: list[Path] = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in sorted(names):
        m = _STALE.match(name)
        if m and not _alive(int(m.group("pid"))):
            entry = folder / name
            if m.group("what") == OLD:
                _restore(folder, m.group("name"), entry)
            if entry.exists() or entry.is_symlink():
                _rm(entry)
                removed.append(entry)
            continue
        m = _ATOMIC_TMP.match(name)
        if m and not _alive(int(m.group("pid"))):
            _rm(folder / name)
            removed.append(folder / name)
            continue
        if name.endswith(f".{LOCK}"):  # the claim of a run that is gone
            try:
                pid = int((folder / name).read_text().strip() or 0)
            except (OSError, ValueError):
                continue
            if pid and not _alive(pid):
                _rm(folder / name)
                removed.append(folder / name)
    return removed


def _restore(folder: Path, name: str, old: Path) -> None:
    """A kill between moving the previous output aside and finishing the swap: put the previous set back."""
    if name.startswith("members-"):
        # member set: once the previous members are all aside (".complete"), what matches in the
        # folder is the interrupted run's partial set: remove it; then the previous set goes back
        if (old / ".complete").exists():
            patterns = (old / ".patterns").read_text().split("\n") if (old / ".patterns").is_file() else []
            for p in _matches(folder, patterns):
                _rm(p)
        for f in old.iterdir():
            if f.name not in (".patterns", ".complete"):
                os.replace(f, folder / f.name)
    else:  # folder set: the final folder is missing only if the kill came between the two renames
        final = folder / name
        if not final.exists():
            os.replace(old, final)


def _matches(folder: Path, patterns) -> list[Path]:
    try:
        names = os.listdir(folder)
    except OSError:
        return []
    return [folder / n for n in sorted(names)
            if not n.startswith(".") and any(fnmatch.fnmatchcase(n, p) for p in patterns if p)]


# -- the output set --------------------------------------------------------------------------------------
class OutputSet:
    """Write a command's outputs into a temporary folder and swap them in as one set.

    Parameters
    ----------
    path : path
        The output folder.
    option : str
        The option that named it (for messages), e.g. ``"--out"``.
    overwrite : bool
        Replace an earlier output; without it an existing non-empty folder (or
        existing members) is refused before any work.
    members : sequence of str, optional
        Glob patterns of the files this command owns in a shared folder; the
        folder's other files are left alone.  Without it the folder is the set.
    last : sequence of str
        Patterns of members moved in last (the sidecar that makes a run complete).
    check : bool
        Check the path now (default); construct early, before the work.

    Use as a context manager: ``with OutputSet(out, option="--out") as tmp:``
    write into ``tmp``; on a normal exit the set is swapped in, on an exception
    (and Ctrl-C) ``tmp`` is removed and the previous output stays whole.
    """

    def __init__(self, path, option: str | None = "--out", *, overwrite: bool = False, members=None,
                 last=(), check: bool = True, shown=None):
        self.path = Path(path)
        self.shown = Path(shown) if shown is not None else self.path  # the path named in messages
        self.option = option
        self.overwrite = overwrite
        self.members = tuple(members) if members else None
        self.last = tuple(last)
        self.tmp: Path | None = None
        self._created_folder = False
        self._lock = None
        if check:
            self.check()

    # checks
    def check(self) -> None:
        self._check()
        # one writer per output set: a second run started meanwhile refuses here, before any work
        self._lock = lock(self.shown, self.option, _lock_path(self.path) if self.members is None else
                          Path(os.path.abspath(self.path)) / f".members-{_tag(self.members)}.{LOCK}")

    def _check(self) -> None:
        if self.members is None:
            check_folder(self.path, self.option, overwrite=self.overwrite)
            clean_stale(self.path.absolute().parent)
            return
        folder = self.path
        shown = _label(self.option, self.shown)
        if folder.exists() and not folder.is_dir():
            raise OutputError(f"{shown}: {folder} is a file, not a folder")
        if folder.is_dir():
            probe_writable(folder, shown)
            clean_stale(folder)
            existing = _matches(folder, self.members)
            if existing and not self.overwrite:
                raise OutputError(f"{_label(self.option, existing[0])} already exists; pass --overwrite to replace "
                                  "the earlier output")
        else:
            check_parent(folder / "x", None if self.shown != self.path else self.option) if self.shown == self.path \
                else _check_parent_shown(folder / "x", shown)

    def existing(self) -> list[Path]:
        """The files of an earlier output this set would replace."""
        if self.members is None:
            return [self.path] if self.path.is_dir() and any(self.path.iterdir()) else []
        return _matches(self.path, self.members) if self.path.is_dir() else []

    # context manager
    def __enter__(self) -> Path:
        try:
            return self._enter()
        except OSError as exc:
            self.abort()
            raise self._named(exc) from None

    def _enter(self) -> Path:
        pid = os.getpid()
        if self.members is None:
            parent = self.path.absolute().parent
            parent.mkdir(parents=True, exist_ok=True)
            self.tmp = parent / f".{self.path.name}.{TMP}.{pid}"
        else:
            if not self.path.exists():
                self._created_folder = True
            self.path.mkdir(parents=True, exist_ok=True)
            self.tmp = self.path.absolute() / f".members-{_tag(self.members)}.{TMP}.{pid}"
        _rm(self.tmp)
        self.tmp.mkdir()
        return self.tmp

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            try:
                self.commit()
            except OSError as err:
                self.abort()
                raise self._named(err) from None
            except BaseException:  # Ctrl-C just before the swap: the temporary goes too
                self.abort()
                raise
            return False
        self.abort()
        if isinstance(exc, OSError):
            raise self._named(exc) from None
        return False

    def abort(self) -> None:
        """Remove the temporary folder (the previous output stays as it was)."""
        if self._lock is not None:
            unlock(self._lock)
        if self.tmp is not None:
            _rm(self.tmp)
        if self._created_folder:
            try:
                self.path.rmdir()  # only if empty
            except OSError:
                pass

    def commit(self) -> None:
        """Swap the temporary folder in (see the class docstring); a Ctrl-C or SIGTERM waits until it is done."""
        with _signals_held():
            self._commit()
        if self._lock is not None:
            unlock(self._lock)

    def _commit(self) -> None:
        tmp, pid = self.tmp, os.getpid()
        if self.members is None:
            write_record(tmp)
            final = self.path.absolute()
            old = final.parent / f".{final.name}.{OLD}.{pid}"
            if not self.overwrite and final.is_dir() and any(final.iterdir()):
                raise _created_meanwhile(self.option, self.shown)
            if final.exists():
                os.replace(final, old)
            os.replace(tmp, final)
            if old.exists():
                done = final.parent / f".{final.name}.{DONE}.{pid}"
                os.replace(old, done)
                _rm(done)
            self.tmp = None
            return
        folder = self.path.absolute()
        tag = _tag(self.members)
        if not self.overwrite and _matches(folder, self.members):
            raise _created_meanwhile(self.option, _matches(folder, self.members)[0])
        old = folder / f".members-{tag}.{OLD}.{pid}"
        _rm(old)
        old.mkdir()
        (old / ".patterns").write_text("\n".join(self.members))
        for f in _matches(folder, self.members):
            os.replace(f, old / f.name)
        (old / ".complete").write_text("")
        new = sorted(tmp.iterdir(), key=lambda p: (any(fnmatch.fnmatchcase(p.name, x) for x in self.last), p.name))
        for f in new:
            target = folder / f.name
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            os.replace(f, target)
        done = folder / f".members-{tag}.{DONE}.{pid}"
        os.replace(old, done)
        _rm(done)
        _rm(tmp)
        self.tmp = None

    def _named(self, err: OSError) -> OSError:
        """The OSError with the temporary path replaced by the output path it stands for."""
        name = err.filename
        if isinstance(name, (str, os.PathLike)) and self.tmp is not None:
            s = str(name)
            t = str(self.tmp)
            if s.startswith(t):
                final = self.path if self.members is None else self.path
                name = str(final) + s[len(t):]
        if name is None:
            name = str(self.path)
        e = OSError(err.errno or errno.EIO, err.strerror or str(err), str(name))
        return e


def _created_meanwhile(option, path) -> ValueError:
    from ehas_env.output.files import OutputExists

    return OutputExists(f"{_label(option, Path(path))} was created by another run meanwhile; nothing was replaced "
                        "(pass --overwrite to replace it)")


@contextlib.contextmanager
def _signals_held():
    """SIGINT and SIGTERM wait until the block ends (a swap is never cut in half), then act as they would have.

    Only in the main thread (where Python runs signal handlers); an ignored signal stays ignored.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list = []
    previous: dict = {}

    def hold(signum, frame):
        held.append((signum, frame))

    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            handler = signal.getsignal(sig)
            if handler is None or handler == signal.SIG_IGN:
                continue
            previous[sig] = signal.signal(sig, hold)
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if held:
            signum, frame = held[0]
            handler = previous[signum]
            if callable(handler):
                handler(signum, frame)  # Python's default raises KeyboardInterrupt here, after the swap
            else:
                signal.raise_signal(signum)  # SIG_DFL: what the signal would have done


def _tag(patterns) -> str:
    text = "-".join(patterns)
    return re.sub(r"[^A-Za-z0-9_-]+", "_", text)[:60] or "set"


def stem_set(stem, option: str = "--out", *, overwrite: bool = False, suffixes=(".csv", ".json", ".png"),
             last=(".json",)) -> OutputSet:
    """The output set of a run file ``STEM.csv`` + ``STEM.json`` (+ ``STEM.png``): members of STEM's folder.

    The sidecar ``.json`` goes in last: a run is complete once it is there.
    """
    stem = Path(stem)
    if stem.suffix in (".csv", ".json"):
        stem = stem.with_suffix("")
    if stem.name in ("", ".", ".."):
        raise OutputError(f"{option} {stem}: expected an output stem (a file name without suffix), got a folder")
    if stem.is_dir():
        raise OutputError(f"{option} {stem} is a folder; expected an output stem, e.g. {stem / 'run'} "
                          "(writes run.csv, run.json)")
    # the names the run writer gives (ehas_env.measurement.runfile.write_run: stem.with_suffix)
    names = {s: stem.with_suffix(s).name for s in suffixes}
    return OutputSet(stem.parent, option, overwrite=overwrite, members=[_glob_escape(n) for n in names.values()],
                     last=[_glob_escape(names[s]) for s in last if s in names], shown=stem)


def _glob_escape(name: str) -> str:
    return re.sub(r"([*?\[])", r"[\1]", name)
