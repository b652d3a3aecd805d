"""``ehas report FOLDER``: one HTML page of a diagnosis or comparison, to open in a browser, offline.

``ehas report FOLDER [--json FILE] [--out FILE.html]`` reads the diagnosis JSON
(``ehas diagnose --json``; by default ``FOLDER/diagnosis.json``, which
``ehas diagnose --out FOLDER`` writes there too) or a comparison JSON
(``ehas compare --json``), and the figures of FOLDER (``--out`` of
``diagnose`` or ``compare``, in the order its report.md shows them), and
writes one self-contained page (default ``FOLDER/report.html``): the verdict
with its noise figure, the model as a difference from the book's rig,
the alternatives and per-run parameters when the JSON has them, the figures
(embedded), and the next step.  No script, nothing from the network
(:mod:`ehas_env.output.html`).  ``ehas diagnose --out DIR --html`` writes the
same page into DIR.
"""
from __future__ import annotations

import argparse
import json
import re
import shlex
from pathlib import Path

#: where ``ehas report`` looks for the JSON in FOLDER, in this order
JSON_NAMES = ("diagnosis.json", "compare.json", "comparison.json")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folder", metavar="FOLDER", help="the --out folder of ehas diagnose or ehas compare")
    parser.add_argument("--json", default=None, metavar="FILE",
                        help=f"the diagnosis or comparison JSON (default: {', '.join(JSON_NAMES)} in FOLDER)")
    parser.add_argument("--out", default=None, metavar="FILE.html", help="the page to write (default FOLDER/report.html)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing page")


def run(args) -> int:
    from ehas_env.output.outputs import check_file

    folder = Path(args.folder)
    if not folder.is_dir():
        raise ValueError(f"FOLDER {folder}: not a folder; give the --out folder of ehas diagnose or ehas compare")
    src = Path(args.json) if args.json else next((folder / n for n in JSON_NAMES if (folder / n).is_file()), None)
    if src is None:
        raise ValueError(f"FOLDER {folder}: holds none of {', '.join(JSON_NAMES)}; give the JSON with --json FILE "
                         "(ehas diagnose --json / ehas compare --json)")
    out = Path(args.out) if args.out else folder / "report.html"
    check_file(out, "--out", overwrite=args.overwrite, suffix=".html")
    doc = read_doc(src)
    command = "ehas report " + " ".join(shlex.quote(a) for a in _argv())
    page = build_page(doc, folder, command=command)
    page.write(out)
    print(f"report: {out} ({len(page.parts)} parts, {sum(map(len, page.parts)) // 1024} kB; opens offline)")
    return 0


def _argv() -> list[str]:
    import sys

    argv = sys.argv[1:]
    return argv[1:] if argv and argv[0] == "report" else argv


def read_doc(path) -> dict:
    """A diagnosis or comparison JSON, checked for the key every page needs.

    Parameters
    ----------
    path : str or Path
        The JSON file.

    Returns
    -------
    dict
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"--json {path}: cannot be read ({e.__class__.__name__})") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"--json {path}: not JSON (line {e.lineno}: {e.msg})") from None
    if not isinstance(doc, dict) or "verdict" not in doc or "residual_x_noise" not in doc:
        raise ValueError(f"--json {path}: not a diagnosis or comparison JSON (no 'verdict' and 'residual_x_noise'; "
                         "docs/measurement-format.md)")
    return doc


def _figures(folder: Path) -> list[tuple[Path, str]]:
    """The PNGs of ``folder`` in the order its report.md shows them (with their alt text), then any other."""
    shown = []
    md = folder / "report.md"
    if md.is_file():
        for alt, name in re.findall(r"!\[([^\]]*)\]\(([^)\s]+\.png)\)", md.read_text(encoding="utf-8")):
            p = folder / name
            if p.is_file() and p not in [q for q, _ in shown]:
                shown.append((p, alt))
    rest = [(p, p.stem.replace("_", " ")) for p in sorted(folder.glob("*.png")) if p not in [q for q, _ in shown]]
    return shown + rest


def _model_of(doc: dict) -> dict | None:
    """The final model in the diagnosis JSON's ``model`` shape (a comparison's ``fitted`` list turned into it)."""
    if isinstance(doc.get("model"), dict):
        return doc["model"]
    if "fitted" not in doc:
        return None
    effects, base, ci = {}, {}, []
    for r in doc["fitted"]:
        if r["effect"] == "baseline":
            base[r["param"]] = r["value"]
        else:
            effects.setdefault(r["effect"], {})[r["param"]] = r["value"]
        lo, hi = (r.get("ci95") or [None, None])
        if lo is not None:
            ci.append({"effect": r["effect"], "param": r["param"], "value": r["value"], "low": lo, "high": hi,
                       "unit": r.get("unit", "")})
    return {"effects": effects, **base, "ci95": ci}


def _cell(v) -> str:
    if isinstance(v, float):
        return f"{v:.5g}"
    if isinstance(v, (dict, list)):
        return json.dumps(v, separators=(", ", ": "))
    return "" if v is None else str(v)


def _records(page, items) -> None:
    """A list of flat-ish records (``alternatives``, ``per_run``) as one table, columns in first-seen order."""
    if isinstance(items, dict):
        items = [{"run": k, **(v if isinstance(v, dict) else {"value": v})} for k, v in items.items()]
    items = [i for i in items if isinstance(i, dict)]
    cols = []
    for i in items:
        cols += [k for k in i if k not in cols]
    page.table(cols, [[_cell(i.get(c)) for c in cols] for i in items])


def build_page(doc: dict, folder, command: str = ""):
    """The HTML page of a diagnosis or comparison JSON and its figures.

    Parameters
    ----------
    doc : dict
        The JSON (``ehas diagnose --json`` or ``ehas compare --json``).
    folder : str or Path
        The folder whose PNGs are embedded.
    command : str
        The command that writes the page (printed on it).

    Returns
    -------
    ehas_env.output.html.Page
    """
    from ehas_env.measurement.model_difference import interval_text, model_difference
    from ehas_env.measurement.verdict import FIGURE_KEY, figure_text
    from ehas_env.output.html import Page

    folder = Path(folder)
    kind = "Diagnosis" if "ranking" in doc or "stack" in doc else "Comparison"
    page = Page(f"{kind}: {doc.get('campaign', folder)}")
    if command:
        page.paragraph(f"Regenerate: {command}")
    page.heading("Verdict")
    x = float(doc[FIGURE_KEY])
    page.paragraph(f"{doc['verdict']}: residual {figure_text(x)} (the noise figure: the model's residual against what "
                   "does not repeat from cycle to cycle; docs/measurement-format.md)",
                   id="verdict-figure", cls="figure", data={"value": repr(x), "verdict": doc["verdict"]})
    g = doc.get("grade") or (doc.get("after") or {})
    if isinstance(g.get("thresholds"), dict):
        t = g["thresholds"]
        page.paragraph(f"explained up to {t['explained']:g}x overall (and {t['block_explained']:g}x in every run and "
                       f"signal); unexplained above {t['unexplained']:g}x (or {t['block_unexplained']:g}x in one)")
    if isinstance(doc.get("unexplained"), dict) and doc["unexplained"].get("text"):
        page.paragraph(doc["unexplained"]["text"])
    if "before" in doc and "after" in doc:
        page.table(["model", "residual", "verdict", "fit %"],
                   [[s.get("model"), figure_text(s[FIGURE_KEY]), s.get("verdict"), s.get("fit_percent")]
                    for s in (doc["before"], doc.get("recalibrated"), doc["after"]) if s])

    model = _model_of(doc)
    if model is not None:
        rows = model.get("difference") or model_difference(model)
        page.heading("The model: what differs from the book's rig")
        if rows:
            page.table(["quantity", "book", "value", "95 % interval", "unit", "note"],
                       [[r["quantity"], "off" if r["book"] is None else f"{r['book']:.5g}",
                         "" if r["value"] is None else f"{r['value']:.5g}",
                         interval_text(r), r["unit"], r["note"]]
                        for r in rows])
        else:
            page.paragraph("nothing: the book's rig as it is")
    if doc.get("alternatives"):
        page.heading("Alternatives: other models that explain the data about as well")
        _records(page, doc["alternatives"])
    if doc.get("per_run"):
        page.heading("Per-run parameters")
        _records(page, doc["per_run"])
    if doc.get("ranking"):
        page.heading("Effects tried (first round, ranked)")
        page.table(["rank", "effect", "fitted", "score dB", "fit %", "evidence"],
                   [[i + 1, e.get("effect"), _cell(e.get("params")), e.get("score"), e.get("fit_percent"),
                     e.get("evidence")] for i, e in enumerate(doc["ranking"])])
    if doc.get("stack"):
        page.heading("Stacking: which effects were kept, and why")
        page.table(["effect", "kept", "reason"], [[s.get("effect"), "yes" if s.get("kept") else "no", s.get("reason")]
                                                 for s in doc["stack"]])
    figs = _figures(folder)
    if figs:
        page.heading("Figures")
        for p, caption in figs:
            page.figure(p, caption)
    page.heading("Next step")
    page.pre(next_step(doc))
    return page


def next_step(doc: dict) -> str:
    """The command a user runs next: the JSON's ``next``, else what the JSON implies.

    Parameters
    ----------
    doc : dict
        A diagnosis or comparison JSON.

    Returns
    -------
    str
    """
    if doc.get("next"):  # a diagnosis JSON states its own (ehas_env.cli.diagnose.diagnosis_doc)
        return doc["next"]
    if "ranking" in doc or "stack" in doc:
        if doc.get("effect_file"):
            return f"add the effect file {doc['effect_file']} with ehas compare --effects-path (see the console's next:)"
        return "nothing to add: the book's rig explains the campaign as it is"
    return ("ehas bench results/controllers/*.json --model model.json --out bench   # with the model saved by "
            "ehas compare ... --save-model model.json")
