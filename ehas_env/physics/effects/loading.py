"""Effects from outside the package: effect files in a folder, or the ``ehas.effects`` entry-point group.

A user writes ``my_spring.py`` (one :class:`~ehas_env.physics.effects.base.Effect`
subclass, see docs/effects-and-controllers.md) into a folder and names the folder
with ``--effects-path DIR`` on any command, ``effects_path=`` of ``Plant`` and the
environments, or the environment variable ``EHAS_EFFECTS_PATH`` (folders
separated by ``os.pathsep``; subprocesses inherit it).  Installed packages can
register effect modules under the entry-point group ``ehas.effects``.
Importing a file registers its effects; the next model built includes them.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

ENV_VAR = "EHAS_EFFECTS_PATH"
TRUST_ENV = "EHAS_TRUSTED_EFFECTS"
_LOADED: dict[str, str] = {}
#: user effect name -> (file, SHA-256 of its text)
SOURCES: dict[str, tuple[str, str]] = {}


def _files(path: Path) -> list[Path]:
    if path.is_file():
        if path.suffix != ".py":
            raise ValueError(f"effects path {path}: an effect file must be a .py file")
        return [path]
    if not path.is_dir():
        raise ValueError(f"effects path {path} does not exist (expected a folder of effect .py files)")
    try:  # not Path.glob: it lists a folder it cannot read as empty
        names = os.listdir(path)
    except OSError as exc:
        raise ValueError(f"effects path {path}: the folder cannot be read ({exc.strerror or exc}); its effect "
                         "files would be missing") from None
    return sorted(path / n for n in names if n.endswith(".py") and not n.startswith("_") and (path / n).is_file())


def load_effect_file(path) -> None:
    """Import one effect file (its Effect subclasses register themselves); a file is loaded once.

    The import runs with a time limit and fails in one line naming the file
    (:func:`ehas_env.plugin_import.import_file`); each effect it registers remembers
    the file and the SHA-256 of its text (:data:`SOURCES`), which a saved model file records.
    """
    from ehas_env.plugin_import import import_file
    from ehas_env.physics.effects.base import REGISTRY

    path = Path(path).resolve()
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"effect file {path}: cannot be read ({exc.strerror or exc})") from None
    key = str(path)
    digest = hashlib.sha256(text).hexdigest()
    if _LOADED.get(key) == digest[:12]:
        return
    name = f"ehas_user_effects.{path.stem}_{digest[:12]}"
    # the check's child process must not load EHAS_EFFECTS_PATH itself: each of those files would be checked
    # in a child of its own, which loads them again, ... until the time limit
    import_file(path, name, "effect",
                setup=f"import os\nos.environ.pop({ENV_VAR!r}, None)\nimport ehas_env.physics.effects")
    mine = [cls for cls in list(REGISTRY.values()) if cls.__module__ == name]
    if not mine:
        sys.modules.pop(name, None)
        raise ValueError(f"effect file {path}: defines no effect (a subclass of Effect with a name = '...' of "
                         "letters, digits and _; docs/effects-and-controllers.md)")
    for cls in mine:
        SOURCES[cls.name] = (str(path), digest)
    _LOADED[key] = digest[:12]


def effect_source(name: str):
    """``(file, sha256 of its text)`` of a user effect loaded from a file; None for the library's own."""
    return SOURCES.get(name)


def trusted_folders() -> list[Path]:
    """Folders of the user's trust list (``EHAS_TRUSTED_EFFECTS`` or ``~/.config/ehas/trusted_effects.json``).

    The file is a JSON object ``{"format": "ehas-trusted-effects", "version": 1, "folders": ["/abs/dir", ...]}``
    the user writes; a model file's user effect loads from one of these folders only when a file there has
    exactly the SHA-256 the model file records.
    """
    import json

    named = os.environ.get(TRUST_ENV, "")
    f = Path(named or Path.home() / ".config" / "ehas" / "trusted_effects.json")
    if not f.is_file():
        if named:  # the user named a trust list: one that is not there is not an empty one
            raise ValueError(f"{TRUST_ENV} names {f}, which {'is a folder' if f.is_dir() else 'does not exist'}; "
                             "expected the trust list JSON file (docs/model-file.md), or unset the variable")
        return []
    try:
        doc = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"trust list {f}: not readable JSON ({exc})") from None
    if not (isinstance(doc, dict) and doc.get("format") == "ehas-trusted-effects" and doc.get("version") == 1
            and isinstance(doc.get("folders"), list) and all(isinstance(p, str) and Path(p).is_absolute()
                                                             for p in doc["folders"])):
        raise ValueError(f'trust list {f}: expected {{"format": "ehas-trusted-effects", "version": 1, "folders": '
                         '["/absolute/folder", ...]}} (docs/model-file.md)')
    missing = [p for p in doc["folders"] if not Path(p).is_dir()]
    if missing:
        raise ValueError(f"trust list {f}: folder {missing[0]} does not exist (or is not a folder); correct or remove "
                         "it (docs/model-file.md)")
    return [Path(p) for p in doc["folders"]]


def load_trusted(sha256: str) -> bool:
    """Load the effect file of the trust list whose text has this SHA-256; False when none has."""
    for folder in trusted_folders():
        for f in _files(folder):
            try:
                if hashlib.sha256(f.read_bytes()).hexdigest() == sha256:
                    load_effect_file(f)
                    return True
            except OSError:
                continue
    return False


def load_effects_path(paths) -> None:
    """Load every effect file of ``paths`` (a folder, a file, or a list of them) and remember them in
    ``EHAS_EFFECTS_PATH`` so that worker processes load them too."""
    if paths is None:
        return
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    for p in paths:
        for f in _files(Path(p)):
            load_effect_file(f)
    known = [p for p in os.environ.get(ENV_VAR, "").split(os.pathsep) if p]
    for p in paths:
        s = str(Path(p).resolve())
        if s not in known:
            known.append(s)
    os.environ[ENV_VAR] = os.pathsep.join(known)


def load_external_effects() -> None:
    """Effects named by ``EHAS_EFFECTS_PATH`` and the ``ehas.effects`` entry points (at package import).

    A trust list named by ``EHAS_TRUSTED_EFFECTS`` is checked here too (it exists, it is a trust list, its
    folders exist): a variable naming a missing path is one error line, not a silently empty list.
    """
    if os.environ.get(TRUST_ENV):
        trusted_folders()
    for p in [p for p in os.environ.get(ENV_VAR, "").split(os.pathsep) if p]:
        try:
            files = _files(Path(p))
        except ValueError as exc:  # name the variable: the user may not remember setting it
            raise ValueError(f"{ENV_VAR}: {exc}") from None
        for f in files:
            load_effect_file(f)
    from importlib.metadata import entry_points

    for ep in entry_points(group="ehas.effects"):
        try:
            ep.load()
        except Exception as exc:
            raise ValueError(f"entry point '{ep.name}' of group ehas.effects ({ep.value}): "
                             f"{type(exc).__name__}: {exc}") from None
