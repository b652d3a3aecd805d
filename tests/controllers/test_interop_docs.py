"""docs/linear-models.md runs as written: its python blocks, in order, print what the page shows."""
from __future__ import annotations

import contextlib
import io
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "linear-models.md"

pytest.importorskip("control")
pytest.importorskip("matplotlib")


def blocks(text: str) -> list[tuple[str, str | None]]:
    """(python code, the plain block right after it or None), in page order."""
    fences = re.findall(r"```(\w*)\n(.*?)```", text, flags=re.S)
    out = []
    for k, (lang, body) in enumerate(fences):
        if lang == "python":
            nxt = fences[k + 1] if k + 1 < len(fences) else None
            out.append((body, nxt[1] if nxt is not None and nxt[0] == "" else None))
    return out


def test_the_page_is_linked_from_the_docs_index():
    assert "(linear-models.md)" in (ROOT / "docs" / "README.md").read_text()


def test_linear_models_doc_runs_and_prints_what_it_shows(monkeypatch):
    monkeypatch.chdir(ROOT)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    code = blocks(DOC.read_text(encoding="utf-8"))
    assert len(code) >= 5, "the page lost its examples"
    ns: dict = {"__name__": "linear_models_doc"}
    for k, (body, expected) in enumerate(code, 1):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            exec(compile(body, f"{DOC.name} block {k}", "exec"), ns)
        printed = [line.strip() for line in buf.getvalue().splitlines()]
        for line in (expected or "").strip().splitlines():
            assert line.strip() in printed, (f"block {k} of {DOC.name} should print {line.strip()!r}; "
                                             f"it printed {printed}")
    assert os.path.getsize(ns["png"]) > 10_000  # the Bode plot was drawn
