"""The user-facing API is documented the numpydoc way: every parameter in ``Parameters``, a ``Returns`` section
where a value comes back (issue 23).

The API is what the README and docs/ tell users to call: the plant and its controller, the environments, model
files, campaigns and their diagnosis, the controllers, effects.  For each function, class and public method
defined in it: a docstring; a ``Parameters`` section naming every argument (``self``/``cls`` and a bare ``*``
excepted; a class documents its constructor's arguments under ``Parameters`` or, for a dataclass, ``Attributes``);
a ``Returns`` (or ``Yields``) section when the body returns a value.  Properties need a docstring only.
"""
from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import re
import textwrap

import pytest

API = (
    "ehas_env.simulation.plant:Plant",
    "ehas_env.simulation.plant:SimResult",
    "ehas_env.simulation.rig_controller:RigController",
    "ehas_env.simulation.model_file:load_model",
    "ehas_env.simulation.model_file:save_model",
    "ehas_env.simulation.model_file:PlantModel",
    "ehas_env.env.tracking_env:TrackingEnv",
    "ehas_env.env.vector_env:TrackingVectorEnv",
    "ehas_env.measurement.campaign:read_campaign",
    "ehas_env.diagnosis.pipeline:diagnose_open",
    "ehas_env.measurement.runfile:write_result",
    "ehas_env.measurement.runfile:write_run",
    "ehas_env.physics.effects.base:Effect",
    "ehas_env.physics.effects.base:Param",
    "ehas_controllers.base:Controller",
    "ehas_controllers.base:load_controller",
    "ehas_controllers.piff:PIFF",
    "ehas_controllers.piff:GainSchedule",
)

_SECTION = re.compile(r"^\s*(Parameters|Returns|Yields|Attributes|Other Parameters|Raises|Examples|Notes|See Also)"
                      r"\s*\n\s*-{3,}\s*$", re.M)


def sections(doc: str) -> dict[str, str]:
    """Numpydoc section title -> its text."""
    doc = inspect.cleandoc(doc or "")
    marks = list(_SECTION.finditer(doc))
    return {m.group(1): doc[m.end():marks[k + 1].start() if k + 1 < len(marks) else len(doc)]
            for k, m in enumerate(marks)}


def documented_names(text: str) -> set[str]:
    """Names a Parameters/Attributes section documents (``a, b : type`` lines at the section's indent)."""
    names = set()
    for line in textwrap.dedent(text.strip("\n")).splitlines():
        if line and not line[0].isspace():
            head = line.split(" : ")[0] if " : " in line else line.strip()
            for part in head.split(","):
                names.add(part.strip().lstrip("*"))
    return names


def returns_value(fn) -> bool:
    """The function's own body has ``return <value>`` (nested functions and classes not counted)."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    except (OSError, TypeError, SyntaxError):
        return False
    top = tree.body[0]

    def walk(node):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
                continue
            if isinstance(child, ast.Return) and child.value is not None and not (
                    isinstance(child.value, ast.Constant) and child.value.value is None):
                return True
            if walk(child):
                return True
        return False

    return walk(top)


def problems_of_function(fn, who: str, params=None) -> list[str]:
    doc = inspect.getdoc(fn) if not isinstance(fn, type) else fn.__doc__
    if not doc or not doc.strip():
        return [f"{who}: no docstring"]
    secs = sections(doc)
    out = []
    if params is None:
        try:
            sig = inspect.signature(fn)
        except (TypeError, ValueError):
            return out
        params = [p.name for p in sig.parameters.values() if p.name not in ("self", "cls")]
    if params:
        have = documented_names(secs.get("Parameters", "")) | documented_names(secs.get("Attributes", "")) | \
            documented_names(secs.get("Other Parameters", ""))
        missing = [p for p in params if p not in have]
        if "Parameters" not in secs and "Attributes" not in secs:
            out.append(f"{who}: no Parameters section (arguments {', '.join(params)})")
        elif missing:
            out.append(f"{who}: Parameters lacks {', '.join(missing)}")
    if not isinstance(fn, type) and returns_value(fn) and not ({"Returns", "Yields"} & set(secs)):
        out.append(f"{who}: returns a value but has no Returns section")
    return out


def problems_of_class(cls, who: str) -> list[str]:
    if dataclasses.is_dataclass(cls):
        params = [f.name for f in dataclasses.fields(cls) if f.init and not f.name.startswith("_")]
    else:
        init = cls.__dict__.get("__init__")
        params = None if init is None else [p.name for p in inspect.signature(init).parameters.values()
                                            if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    out = problems_of_function(cls, who, params=params or [])
    for name, member in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(member, property):
            if not (member.__doc__ or "").strip():
                out.append(f"{who}.{name}: property without a docstring")
            continue
        fn = member.__func__ if isinstance(member, (classmethod, staticmethod)) else member
        if inspect.isfunction(fn):
            out += problems_of_function(fn, f"{who}.{name}")
    return out


def problems(target: str) -> list[str]:
    module, name = target.split(":")
    obj = getattr(importlib.import_module(module), name)
    return problems_of_class(obj, target) if isinstance(obj, type) else problems_of_function(obj, target)


@pytest.mark.parametrize("target", API)
def test_user_facing_api_has_numpydoc_parameters_and_returns(target):
    found = problems(target)
    assert not found, "\n".join(found)


def test_the_checker_fails_on_definitions_built_to_break_it():
    def no_doc(a):
        return a

    def missing_param(a, b):
        """Add.

        Parameters
        ----------
        a : float
            One.

        Returns
        -------
        float
        """
        return a + b

    def no_returns(a):
        """Twice.

        Parameters
        ----------
        a : float
            A number.
        """
        return 2 * a

    def fine(a, b=1, *, c=2):
        """Sum.

        Parameters
        ----------
        a, b : float
            Numbers.
        c : float
            Another.

        Returns
        -------
        float
        """
        def inner():
            return 1
        return a + b + c + inner()

    @dataclasses.dataclass
    class Undocumented:
        """A dataclass whose field x is not documented.

        Attributes
        ----------
        y : float
            Y.
        """

        x: float = 0.0
        y: float = 0.0

        def value(self, k):
            """Undocumented argument and return."""
            return self.x * k

    assert problems_of_function(no_doc, "f") == ["f: no docstring"]
    assert problems_of_function(missing_param, "f") == ["f: Parameters lacks b"]
    assert problems_of_function(no_returns, "f") == ["f: returns a value but has no Returns section"]
    assert problems_of_function(fine, "f") == []
    assert problems_of_class(Undocumented, "C") == [
        "C: Parameters lacks x", "C.value: no Parameters section (arguments k)",
        "C.value: returns a value but has no Returns section"]
