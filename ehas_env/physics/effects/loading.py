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
import importlib.util
import os
import sys
from pathlib import Path

ENV_VAR = "EHAS_EFFECTS_PATH"
_LOADED: dict[str, str] = {}


def _files(path: Path) -> list[Path]:
    if path.is_file():
        if path.suffix != ".py":
            raise ValueError(f"effects path {path}: an effect file must be a .py file")
        return [path]
    if not path.is_dir():
        raise ValueError(f"effects path {path} does not exist (expected a folder of effect .py files)")
    return sorted(p for p in path.glob("*.py") if not p.name.startswith("_"))


def load_effect_file(path) -> None:
    """Import one effect file (its Effect subclasses register themselves); a file is loaded once."""
    path = Path(path).resolve()
    text = path.read_bytes()
    key = str(path)
    digest = hashlib.sha256(text).hexdigest()[:12]
    if _LOADED.get(key) == digest:
        return
    name = f"ehas_user_effects.{path.stem}_{digest}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # a user's file: one line naming it, whatever went wrong inside
        sys.modules.pop(name, None)
        raise ValueError(f"effect file {path}: {type(exc).__name__}: {exc}") from None
    _LOADED[key] = digest


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
    """Effects named by ``EHAS_EFFECTS_PATH`` and the ``ehas.effects`` entry points (at package import)."""
    for p in [p for p in os.environ.get(ENV_VAR, "").split(os.pathsep) if p]:
        for f in _files(Path(p)):
            load_effect_file(f)
    from importlib.metadata import entry_points

    for ep in entry_points(group="ehas.effects"):
        try:
            ep.load()
        except Exception as exc:
            raise ValueError(f"entry point '{ep.name}' of group ehas.effects ({ep.value}): "
                             f"{type(exc).__name__}: {exc}") from None
