"""The import graph: layers point one way, nothing imports the command line, no import circles.

Every module of ``ehas_env``, ``ehas_controllers`` (controllers/) and ``ehas_train`` (train/) is read as text
(AST, function-level imports included: an import run later is still a dependency) and its imports of the
project's own modules are checked against the layer map below, lowest first:

====================  ======================================================================
layer                 modules
====================  ======================================================================
0  utilities          ``ehas_env.ranges`` (option ranges, list parsing), ``ehas_env.output`` (files, plots, progress),
                      ``ehas_env.plugin_import`` (importing a user's code file with a time limit)
1  physics            ``ehas_env.physics`` (baseline, effects, codegen, linearisation)
2  simulation         ``ehas_env.simulation`` (plant, loops, sensors, control laws, model files)
3  measurement ...    ``ehas_env.measurement``, ``ehas_env.identification``, ``ehas_env.env``, ``ehas_env.book``
4  diagnosis          ``ehas_env.diagnosis`` (the diagnosis' stages, searches, fits and honesty rules)
5  controllers/train  ``ehas_controllers``, ``ehas_train``
6  command line       ``ehas_env.cli`` and the command modules of the upper packages (``*_cli``)
====================  ======================================================================

A module may import its own layer and those below it.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"ehas_env": ROOT / "ehas_env", "ehas_controllers": ROOT / "controllers", "ehas_train": ROOT / "train"}
LAYERS = (
    (0, ("ehas_env.ranges", "ehas_env.output", "ehas_env.plugin_import")),
    (1, ("ehas_env.physics",)),
    (2, ("ehas_env.simulation",)),
    (3, ("ehas_env.measurement", "ehas_env.identification", "ehas_env.env", "ehas_env.book")),
    (4, ("ehas_env.diagnosis",)),
    (5, ("ehas_controllers", "ehas_train")),
    (6, ("ehas_env.cli",)),
)
CLI = 6

#: imports from a higher layer still to be removed, each with why it is still there (an entry found no more fails
#: the test, so the list can only shrink)
KNOWN_UPWARD: set[tuple[str, str]] = set()


def layer(module: str) -> int | None:
    """The layer of ``module`` (None for a package's own ``__init__`` at the top, which only re-exports)."""
    if module.rsplit(".", 1)[-1].endswith("_cli"):
        return CLI
    for number, prefixes in LAYERS:
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return number
    return None


def modules() -> dict[str, Path]:
    out = {}
    for pkg, folder in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            rel = path.relative_to(folder).with_suffix("")
            parts = [pkg, *rel.parts]
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = path
    return out


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The project's modules ``name`` imports (relative imports resolved; ``from pkg import mod`` counts mod)."""
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    here = name if is_pkg else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here.split(".")
                base = base[:len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in known else mod for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in known:  # a name inside a module: the module
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {name: imports(name, path, known) for name, path in mods.items()}


def test_every_module_has_a_layer():
    missing = [m for m in modules() if layer(m) is None and m not in PACKAGES]
    assert not missing, f"modules outside the layer map: {missing}"


def test_nothing_outside_the_command_line_imports_it():
    bad = sorted(f"{a} -> {b}" for a, deps in graph().items() for b in deps
                 if layer(b) == CLI and layer(a) != CLI)
    assert not bad, "imports of the command line from below:\n" + "\n".join(bad)


def test_layers_point_one_way():
    bad = []
    for a, deps in graph().items():
        la = layer(a)
        for b in deps:
            lb = layer(b)
            if la is not None and lb is not None and lb > la and (a, b) not in KNOWN_UPWARD:
                bad.append(f"{a} (layer {la}) -> {b} (layer {lb})")
    assert not bad, "imports from a higher layer:\n" + "\n".join(sorted(bad))
    gone = sorted(f"{a} -> {b}" for a, b in KNOWN_UPWARD if b not in graph().get(a, ()))
    assert not gone, "fixed: delete from KNOWN_UPWARD:\n" + "\n".join(gone)


def _cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
            if w not in g:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    import sys

    old = sys.getrecursionlimit()
    sys.setrecursionlimit(max(old, 10_000))
    try:
        for v in g:
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(old)
    return out


def test_no_import_circles():
    # a package's __init__ re-exporting its modules is no circle: its modules importing the package mean its parts
    g = {a: {b for b in deps if b not in PACKAGES and not (modules()[b].name == "__init__.py" and a.startswith(b + "."))
             and (a, b) not in KNOWN_UPWARD}
         for a, deps in graph().items()}
    circles = _cycles(g)
    assert not circles, "import circles:\n" + "\n".join(" <-> ".join(c) for c in circles)


def test_the_checker_sees_a_circle_and_an_upward_import():
    """The rules fail on a graph built to break them (so a pass above means something)."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert layer("ehas_env.physics.codegen") < layer("ehas_env.env.batch_kernel")
    assert layer("ehas_controllers.tune_cli") == CLI
