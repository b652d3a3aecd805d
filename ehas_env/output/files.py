"""Reading and writing the files ehas uses, with one-line errors that name the file.

Reading: :func:`read_text` is the one door through which every reader of a file
from elsewhere (controller and model JSON, run CSVs and their sidecars, training
TOML configs, agent folders' ``config.json``, checkpoint state) gets its text, and
:func:`read_json` parses JSON through it.  A path that is not a readable UTF-8 text
file is refused with one line naming the file and what it should be::

    c.json: not a UTF-8 text file (byte 0x80 at offset 128); expected a controller JSON file (docs/errors.md)
    cfg: is a folder; expected a training config (TOML file)
    run.csv: UTF-16 text; save it as UTF-8 (expected a run CSV file)

======================  ===================================================
the path                error
======================  ===================================================
empty                   ValueError ``the path is empty; expected ...``
missing                 FileNotFoundError ``PATH: does not exist; expected ...``
a folder                ValueError ``PATH: is a folder; expected ...``
a device or a socket    ValueError ``PATH: not a regular file; expected ...``
unreadable              ValueError ``PATH: cannot be read (permission denied); ...``
larger than max_bytes   ValueError ``PATH: N bytes, more than the M ...``
UTF-16 (byte-order      ValueError ``PATH: UTF-16 text; save it as UTF-8 ...``
mark)
not UTF-8, or a NUL     ValueError ``PATH: not a UTF-8 text file (...); expected ...``
byte (binary data)
not JSON                ValueError ``PATH: not valid JSON at line L column C: ...``
(:func:`read_json`)
======================  ===================================================

A UTF-8 byte-order mark (as spreadsheet exports and some editors write) is
dropped.  The command line prints a ValueError or FileNotFoundError as
``ehas CMD: error: <message>`` with exit status 2.  Named pipes (``<(...)``) are
read like files.

Writing: :func:`atomic_write_bytes` / :func:`atomic_write_text` write through a
temporary file and an atomic rename, so a reader never sees a half-written file.

Examples
--------
>>> import tempfile, pathlib
>>> work = tempfile.TemporaryDirectory()
>>> p = pathlib.Path(work.name) / "x.json"
>>> _ = p.write_bytes(b'{"a": 1}\\x80')
>>> read_json(p, "a test JSON file")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
ValueError: ...x.json: not a UTF-8 text file (byte 0x80 at offset 8); expected a test JSON file
>>> work.cleanup()
"""
from __future__ import annotations

import errno
import json
import os
import stat
import tempfile
from pathlib import Path


def read_text(path, what: str, *, max_bytes: int | None = None) -> str:
    """The text of the UTF-8 file ``path``, or one clear error naming it and ``what`` it should be.

    Parameters
    ----------
    path : path
        The file to read.
    what : str
        What the file should be, with its article, e.g. ``"a controller JSON file (written by ehas tune)"``;
        every error ends with ``expected <what>``.
    max_bytes : int, optional
        Refuse a larger file before reading it.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Anything else that makes it not a readable UTF-8 text file (see the module docstring).
    """
    if path is None or str(path) == "":
        raise ValueError(f"the path is empty; expected {what}")
    path = Path(path)
    try:
        st = path.stat()
    except OSError as exc:
        raise _unreadable(path, exc, what) from None
    if stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{path}: is a folder; expected {what}")
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISFIFO(st.st_mode)):
        raise ValueError(f"{path}: not a regular file; expected {what}")
    if max_bytes is not None and st.st_size > max_bytes:
        raise ValueError(f"{path}: {st.st_size:,} bytes, more than the {max_bytes:,} bytes allowed for {what}")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise _unreadable(path, exc, what) from None
    if max_bytes is not None and len(raw) > max_bytes:  # a pipe has no size before it is read
        raise ValueError(f"{path}: {len(raw):,} bytes, more than the {max_bytes:,} bytes allowed for {what}")
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise ValueError(f"{path}: UTF-16 text, not a UTF-8 text file; save it as UTF-8 (expected {what})")
    bom = 3 if raw.startswith(b"\xef\xbb\xbf") else 0  # a UTF-8 byte-order mark is dropped
    try:
        text = raw[bom:].decode("utf-8")
    except UnicodeDecodeError as exc:
        at = bom + exc.start
        raise ValueError(f"{path}: not a UTF-8 text file (byte 0x{raw[at]:02x} at offset {at}); "
                         f"expected {what}") from None
    if "\0" in text:
        at = raw.index(b"\0")
        raise ValueError(f"{path}: not a UTF-8 text file (a NUL byte at offset {at}: binary data); expected {what}")
    return text


def _unreadable(path: Path, exc: OSError, what: str) -> Exception:
    """The one-line error for a file that could not be opened or read (see the module docstring)."""
    if isinstance(exc, FileNotFoundError):
        return FileNotFoundError(f"{path}: does not exist; expected {what}")
    if isinstance(exc, NotADirectoryError):
        return FileNotFoundError(f"{path}: does not exist (a part of the path is a file); expected {what}")
    if isinstance(exc, IsADirectoryError):
        return ValueError(f"{path}: is a folder; expected {what}")
    if isinstance(exc, PermissionError):
        return ValueError(f"{path}: cannot be read (permission denied); expected {what}")
    return ValueError(f"{path}: cannot be read ({exc.strerror or exc}); expected {what}")


class DuplicateKey(ValueError):
    """A JSON object names one key twice (json keeps the last silently; ehas refuses)."""


def _no_duplicates(pairs):
    out = {}
    for k, v in pairs:
        if k in out:
            raise DuplicateKey(k)
        out[k] = v
    return out


def loads_strict(text: str):
    """``json.loads`` refusing a key named twice in one object (:class:`DuplicateKey`)."""
    return json.loads(text, object_pairs_hook=_no_duplicates)


def read_json(path, what: str, *, max_bytes: int | None = None):
    """The parsed JSON of the file ``path`` (:func:`read_text`; invalid JSON or a key named twice in one object is one
    line naming the file)."""
    text = read_text(path, what, max_bytes=max_bytes)
    try:
        return json.loads(text, object_pairs_hook=_no_duplicates)
    except DuplicateKey as exc:
        raise ValueError(f"{path}: key {exc.args[0]!r} appears twice in one object; a key may appear once "
                         f"(expected {what})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}; "
                         f"expected {what}") from None
    except RecursionError:
        raise ValueError(f"{path}: JSON nested too deeply; expected {what}") from None


def _umask() -> int:
    """The process's umask (read from /proc where there is one: setting it to learn it races with threads)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file and an atomic rename."""
    path = Path(path)
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # the pid in the name lets the next run remove what a killed one left (outputs.clean_stale)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp", dir=path.parent)
        # mkstemp makes the file private (0600); an output gets the mode any new file gets (0644 under the
        # usual umask 022), so colleagues and a results server can read it
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        claim = CLAIMED.get(os.path.abspath(path))
        if claim is not None and PENDING is not None:
            PENDING.append((tmp, path, claim))  # a command's output: placed when the command succeeds
            return path
        place(tmp, path, overwrite=True if claim is None else claim[1], option=None if claim is None else claim[0])
    except BaseException as exc:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError) and (exc.filename is None or str(exc.filename) == str(tmp)):
            # name the file the user asked for, not the temporary one
            raise type(exc)(exc.errno, exc.strerror or str(exc), str(path)) from None
        raise
    return path


#: called when a command's transaction ends (:func:`finish`): the claims' owner (ehas_env.output.outputs) registers
#: its release here, so this lower module needs no import of it
AT_FINISH: list = []

#: outputs a command checked before its work (``outputs.check_file``): absolute path -> (option, overwrite)
CLAIMED: dict[str, tuple] = {}
#: while a command runs (``begin``): written claimed outputs waiting for its success, (temporary, path, claim)
PENDING: list | None = None


class OutputExists(ValueError):
    """An output created meanwhile by another run (exclusive creation refused); one line naming it."""


def place(tmp, path, *, overwrite: bool, option: str | None = None) -> None:
    """Move the finished temporary ``tmp`` to ``path``: replacing it with ``overwrite``, else only if ``path``
    does not exist at that instant (a hard link is exclusive: two runs cannot both create ``path``)."""
    if overwrite:
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path)
    except FileExistsError:
        os.unlink(tmp)
        label = f"{option} {path}" if option else str(path)
        raise OutputExists(f"{label} was created by another run meanwhile; nothing was replaced "
                           "(pass --overwrite to replace it)") from None
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EXDEV, errno.EMLINK):
            raise
        if os.path.lexists(path):  # a file system without hard links: checked, then renamed
            os.unlink(tmp)
            raise OutputExists(f"{path} was created by another run meanwhile; nothing was replaced") from None
        os.replace(tmp, path)
        return
    os.unlink(tmp)


_DEPTH = [0]


def begin() -> None:
    """Start a command's transaction: claimed outputs written from now wait for :func:`finish` (a command run
    inside another, as ``ehas demo`` runs some, joins the outer one)."""
    global PENDING
    _DEPTH[0] += 1
    if _DEPTH[0] == 1:
        PENDING = []


def finish(ok: bool) -> None:
    """End the transaction: place the waiting outputs (``ok``) or remove them (a failed command leaves none)."""
    global PENDING
    _DEPTH[0] = max(0, _DEPTH[0] - 1)
    if _DEPTH[0]:
        return
    pending, PENDING = PENDING or [], None
    try:
        if ok:
            for k, (tmp, path, claim) in enumerate(pending):
                try:
                    place(tmp, path, overwrite=claim[1], option=claim[0])
                except BaseException:
                    for t, _, _ in pending[k + 1:]:
                        _unlink_quiet(t)
                    raise
        else:
            for tmp, _, _ in pending:
                _unlink_quiet(tmp)
    finally:
        CLAIMED.clear()
        for release in AT_FINISH:
            release()


def _unlink_quiet(p) -> None:
    try:
        os.unlink(p)
    except OSError:
        pass


def atomic_write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) atomically, see :func:`atomic_write_bytes`."""
    return atomic_write_bytes(path, text.encode("utf-8"))
