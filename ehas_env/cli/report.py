"""``ehas report FOLDER``: one HTML page of a diagnosis or comparison, to open in a browser, offline.

``ehas report FOLDER [--json FILE] [--out FILE.html]`` reads the diagnosis JSON
(``ehas diagnose --json``; by default ``FOLDER/diagnosis.json``, which
``ehas diagnose --out FOLDER`` writes there too) or a comparison JSON
(``ehas compare --json``), and the figures of FOLDER (``--out`` of
``diagnose`` or ``compare``, in the order its report.md shows them), and
writes one self-contained page (default ``FOLDER/report.html``): the verdict
with its noise figure, the runs held out for validation, the model as a
difference from the book's rig, the alternatives and per-run parameters when
the JSON has them, the figures (embedded), and the next step.  No script,
nothing from the network (:mod:`ehas_env.output.html`).  ``ehas diagnose --out
DIR --html`` writes the same page into DIR.

The page is read by a person: every table holds values (nested records become
tables of their own: one row per run, one column per parameter), each number's
unit in its column's heading; the runs held out for validation are named on it
and in every per-run table; its commands (``Regenerate``: :func:`report_command`,
and the next step) run as written from the folder the user ran from.
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
    page = build_page(doc, folder, command=report_command(args.folder, args.json, args.out))
    page.write(out)
    print(f"report: {out} ({len(page.parts)} parts, {sum(map(len, page.parts)) // 1024} kB; opens offline)")
    return 0


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
    """The PNGs of ``folder`` in the order its report.md shows them, each with the italic line under it there (else
    its alt text), then any other."""
    shown = []
    md = folder / "report.md"
    if md.is_file():
        for alt, name, words in re.findall(r"!\[([^\]]*)\]\(([^)\s]+\.png)\)(?:\s*\n\s*\n\*([^*\n]+)\*)?",
                                           md.read_text(encoding="utf-8")):
            p = folder / name
            if p.is_file() and p not in [q for q, _ in shown]:
                shown.append((p, words or alt))
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


def report_command(folder, json_file=None, out=None) -> str:
    """The ``ehas report`` command that rewrites a page, runnable as printed from the folder it was run in.

    The page already exists when a reader sees the command, so it carries ``--overwrite`` (without it ``ehas
    report`` refuses to replace the page).

    Parameters
    ----------
    folder : str or Path
        FOLDER as the user gave it (relative to where they ran the command).
    json_file, out : str or Path, optional
        ``--json FILE`` and ``--out FILE.html`` as the user gave them.

    Returns
    -------
    str
        One shell command line.

    Examples
    --------
    >>> report_command("runs/diag nosis/")
    "ehas report 'runs/diag nosis/' --overwrite"
    """
    words = ["ehas", "report", str(folder)]
    if json_file is not None:
        words += ["--json", str(json_file)]
    if out is not None:
        words += ["--out", str(out)]
    return " ".join(shlex.quote(w) for w in words + ["--overwrite"])


def _num(v, digits: int = 4) -> str:
    """A number as a table shows it (``digits`` significant digits); ``""`` for None or what is no number."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return ""
    return f"{0.0 if v == 0 else v:.{digits}g}"  # no "-0"


def _interval(low, high) -> str:
    """A 95 % interval as words, ``1.2 to 1.4`` (a side the data do not bound: ``unbounded``)."""
    return " to ".join("unbounded" if v is None else _num(v) for v in (low, high))


def _param_unit(name: str) -> str:
    """The unit of ``effect.param`` (a library effect's parameter); ``""`` when it is no registered effect's."""
    from ehas_env.physics.effects import get_effect

    effect, _, param = name.partition(".")
    try:
        return get_effect(effect).param(param).unit
    except Exception:  # a hypothesis or term the library does not register: no unit known
        return ""


def _shown(name: str, unit: str) -> tuple[str, float]:
    """The unit a parameter is shown in and the factor from its JSON unit (``baseline.beta``: Pa -> GPa, as the
    model's difference from the book's rig shows it)."""
    from ehas_env.measurement.model_difference import BASELINE

    for slot, _, shown, scale in BASELINE:
        if name in (slot, f"baseline.{slot}"):
            return shown, scale
    return unit, 1.0


def _values_text(params: dict, units: dict | None = None, ci95: dict | None = None) -> str:
    """Fitted values as words, ``Fc = 419.4 N (95 %: 418.4 to 420.5)``, one parameter after another."""
    out = []
    for k, v in (params or {}).items():
        unit = (units or {}).get(k, "")
        text = f"{k} = {_num(v)}" + (f" {unit}" if unit not in ("", "-") else "")
        ci = (ci95 or {}).get(k)
        if isinstance(ci, (list, tuple)) and len(ci) == 2:
            text += f" (95 %: {_interval(*ci)})"
        out.append(text)
    return "; ".join(out)


def held_out(doc: dict) -> list[str]:
    """The runs a diagnosis held out for validation (``validation.holdout``); ``[]`` when none or not a diagnosis.

    Parameters
    ----------
    doc : dict
        A diagnosis or comparison JSON.

    Returns
    -------
    list of str
    """
    v = doc.get("validation")
    runs = v.get("holdout") if isinstance(v, dict) else None
    return [str(r) for r in runs] if isinstance(runs, list) else []


def _role(run: str, held: list[str]) -> str:
    from ehas_env.diagnosis.plots import HELD_OUT

    return HELD_OUT if run in held else "fitted"


def _per_run_records(per_run) -> tuple[str, dict, list[dict]]:
    """The JSON's ``per_run`` as (order, units, runs), each run ``{run, recorded, params: {name: {value, low,
    high, at_range_end}}}``; an older shape (``{run: {name: value or [value, low, high]}}``) read the same way."""
    if isinstance(per_run, dict) and isinstance(per_run.get("runs"), list):
        order, units, runs = per_run.get("order") or "", dict(per_run.get("units") or {}), per_run["runs"]
    elif isinstance(per_run, dict):
        order, units = "", {}
        runs = [{"run": k, "params": v} for k, v in per_run.items() if isinstance(v, dict)]
    else:
        return "", {}, []
    out = []
    for r in runs:
        if not isinstance(r, dict):
            continue
        params = {}
        for name, p in (r.get("params") or {}).items():
            if isinstance(p, dict):
                params[name] = p
            elif isinstance(p, (list, tuple)) and len(p) == 3:
                params[name] = {"value": p[0], "low": p[1], "high": p[2]}
            else:
                params[name] = {"value": p}
            units.setdefault(name, _param_unit(name))
        out.append({"run": str(r.get("run", "")), "recorded": r.get("recorded"), "params": params})
    return order, units, out


def _per_run_table(page, per_run, held: list[str], final: dict | None = None) -> None:
    """Parameters fitted on each run alone, one table per effect (``baseline`` for beta and K): one row per run
    (its role: fitted or held out for validation), one column per parameter with its unit and one with its
    95 % interval.  ``final``: the final model's effects (an effect not in it is marked "judged, not kept")."""
    order, units, runs = _per_run_records(per_run)
    if not runs:
        return
    names = []
    for r in runs:
        names += [n for n in r["params"] if n not in names]
    groups: dict[str, list[str]] = {}
    for n in names:
        groups.setdefault(n.partition(".")[0] if "." in n else "baseline", []).append(n)
    recorded = any(r.get("recorded") not in (None, "") for r in runs)
    page.paragraph("The final model's parameters (and those of the best effects judged but not kept) refitted on "
                   "each closed-loop run alone" + (f", runs in {order}" if order else "") + ":")
    for effect, group in groups.items():
        if final is not None:
            kept = effect == "baseline" or effect in final
            page.subheading(f"{effect} ({'final model' if kept else 'judged, not kept'})")
        else:
            page.subheading(effect)
        shown = {n: _shown(n, units.get(n, "")) for n in group}
        header = ["run", "role"] + (["recorded"] if recorded else [])
        for n in group:
            short, unit = n.partition(".")[2] or n, shown[n][0]
            header += [f"{short} [{unit}]" if unit else short,
                       f"{short}, 95 % interval [{unit}]" if unit else f"{short}, 95 % interval"]
        rows = []
        for r in runs:
            row = [r["run"], _role(r["run"], held)] + ([str(r.get("recorded") or "")] if recorded else [])
            for n in group:
                p, scale = r["params"].get(n) or {}, shown[n][1]
                v = p.get("value")
                row.append(_num(v * scale) if isinstance(v, (int, float)) else "")
                lo, hi = (p.get(k) for k in ("low", "high"))
                text = (_interval(*(None if x is None else x * scale for x in (lo, hi)))
                        if "low" in p or "high" in p else "")
                row.append(text + (" (at its fit range's end)" if p.get("at_range_end") else ""))
            rows.append(row)
        page.table(header, rows, marked=[r["run"] in held for r in runs])


def _alternatives(page, alts: list, held: list[str], title: str, intro: str) -> None:
    """Alternatives (or those ruled out): one row each with its fitted values in words, the score difference in
    dB; what each says and why it looks alike; the per-run score differences as their own table."""
    alts = [a for a in alts if isinstance(a, dict)]
    if not alts:
        return
    page.heading(title)
    page.paragraph(intro)
    page.table(["alternative", "in place of", "fitted values", "score difference [dB]", "resolvable [dB]",
                "preferred by the data"],
               [[a.get("name"), a.get("in_place_of"), _values_text(a.get("params"), a.get("units"), a.get("ci95")),
                 _num(a.get("score_difference_db"), 3), _num(a.get("resolvable_db"), 3),
                 "yes" if a.get("preferred") else "no"] for a in alts])
    for a in alts:
        words = ". ".join(str(a[k]) for k in ("title", "words") if a.get(k))
        if a.get("reason"):
            words += f". Why it looks alike: {a['reason']}"
        if words:
            page.paragraph(f"{a.get('name')}: {words}")
    per_run = [a for a in alts if isinstance(a.get("per_run_db"), dict)]
    if per_run:
        runs = []
        for a in per_run:
            runs += [r for r in a["per_run_db"] if r not in runs]
        page.paragraph("Score difference per run, 10 log10 of the alternative's residual energy over the reported "
                       "model's (positive: the reported model fits that run better):")
        page.table(["run", "role"] + [f"{a.get('name')} [dB]" for a in per_run],
                   [[r, _role(r, held)] + [_num(a["per_run_db"].get(r), 3) for a in per_run] for r in runs],
                   marked=[r in held for r in runs])


def _validation(page, doc: dict, held: list[str]) -> None:
    """Which runs were fitted and which held out for validation, and how the model does on the held-out ones."""
    from ehas_env.diagnosis.plots import HELD_OUT

    page.heading("Validation: the runs held out")
    v = doc.get("validation") if isinstance(doc.get("validation"), dict) else None
    if v is None:
        page.paragraph(f"{HELD_OUT}: none (a comparison fits and judges every run of the campaign)",
                       id="held-out", data={"runs": ""})
        return
    if not held:
        page.paragraph(f"{HELD_OUT}: none (fewer than 4 runs, or --holdout none)", id="held-out", data={"runs": ""})
    else:
        page.paragraph(f"{HELD_OUT}: {', '.join(held)} (not fitted; the model kept must lower the residual on it)",
                       id="held-out", data={"runs": ",".join(held)})
    fitted = [str(r) for r in v.get("fit_runs") or []]
    runs = fitted + [r for r in held if r not in fitted]
    window = v.get("fit_window_s")
    if runs:
        page.table(["run", "role"], [[r, _role(r, held)] for r in runs], marked=[r in held for r in runs])
    if isinstance(window, (int, float)):
        page.paragraph(f"Closed-loop runs fitted over their first {window:g} s; the rest of each run is validation "
                       "data too.")
    cols = [("holdout_fit_percent_baseline", "fit of the held-out runs, baseline [%]"),
            ("holdout_fit_percent_model", "fit of the held-out runs, final model [%]"),
            ("residual_x_noise_validation", "final model's residual on the validation data [x sensor-noise variance]")]
    cols = [(k, h) for k, h in cols if isinstance(v.get(k), (int, float))]
    if cols:
        page.table([h for _, h in cols], [[_num(v[k]) for k, _ in cols]])


def _verdict(page, doc: dict) -> None:
    """The verdict with its noise figure, the thresholds, the unexplained rest in words; a comparison's models."""
    from ehas_env.measurement.verdict import FIGURE_KEY, figure_text

    page.heading("Verdict")
    x = float(doc[FIGURE_KEY])
    page.paragraph(f"{doc['verdict']}: residual {figure_text(x)} (the noise figure: the model's residual against what "
                   "does not repeat from cycle to cycle; docs/measurement-format.md)",
                   id="verdict-figure", cls="figure", data={"value": repr(x), "verdict": doc["verdict"]})
    g = doc.get("grade") or (doc.get("after") or {})
    t = g.get("thresholds") if isinstance(g, dict) else None
    if isinstance(t, dict) and all(isinstance(t.get(k), (int, float)) for k in
                                   ("explained", "block_explained", "unexplained", "block_unexplained")):
        page.paragraph(f"explained up to {t['explained']:g}x overall (and {t['block_explained']:g}x in every run and "
                       f"signal); unexplained above {t['unexplained']:g}x (or {t['block_unexplained']:g}x in one)")
    if isinstance(doc.get("unexplained"), dict) and doc["unexplained"].get("text"):
        page.paragraph(doc["unexplained"]["text"])
    if "before" in doc and "after" in doc:
        sides = [s for s in (doc["before"], doc.get("recalibrated"), doc["after"]) if isinstance(s, dict)]
        page.table(["model", "residual [x what does not repeat]", "verdict", "fit [%]"],
                   [[s.get("model"), _num(s.get(FIGURE_KEY), 3), s.get("verdict"), _num(s.get("fit_percent"))]
                    for s in sides])


def _model(page, doc: dict) -> None:
    """The final model as its difference from the book's rig; a structural hypothesis or missing state kept."""
    from ehas_env.measurement.model_difference import model_difference

    model = _model_of(doc)
    if model is not None:
        rows = model.get("difference") or model_difference(model)
        page.heading("The model: what differs from the book's rig")
        if rows:
            def bound(r, side):
                v = r.get(side)
                return "unbounded" if v is None and r.get("fitted", r.get("low") is not None) else _num(v)

            page.table(["quantity", "what it is", "book", "value", "95 % low", "95 % high", "unit", "note"],
                       [[r.get("quantity"), r.get("words", ""), "off" if r.get("book") is None else _num(r["book"]),
                         _num(r.get("value")), bound(r, "low"), bound(r, "high"), r.get("unit"), r.get("note")]
                        for r in rows])
        else:
            page.paragraph("nothing: the book's rig as it is")
    hyp = doc.get("hypothesis")
    if isinstance(hyp, dict):
        page.heading("Structural hypothesis kept")
        page.paragraph(". ".join(str(hyp[k]) for k in ("title", "words") if hyp.get(k)) + ". Fitted: "
                       + _values_text(hyp.get("params"), hyp.get("units"), hyp.get("ci95")))
    states = doc.get("states") if isinstance(doc.get("states"), list) else [doc.get("state")]
    states = [st for st in states if isinstance(st, dict) and st.get("words")]
    if states:
        page.heading("Missing state kept" if len(states) == 1 else "Missing states kept")
        for st in states:
            page.paragraph(f"{st.get('kept', '')}: {st['words']}")


def _search(page, doc: dict) -> None:
    """What the search tried: the first round's ranking and the stacking, numbers with units in the headings."""
    if isinstance(doc.get("ranking"), list) and doc["ranking"]:
        page.heading("Effects tried (first round, ranked best first)")
        ranking = [e for e in doc["ranking"] if isinstance(e, dict)]
        page.table(["effect", "fitted", "score [dB]", "fit [%]", "evidence"],
                   [[e.get("effect"),
                     _values_text(e.get("params"), {k: _param_unit(f"{e.get('effect')}.{k}") for k in e.get("params") or {}}),
                     _num(e.get("score"), 3), _num(e.get("fit_percent")), e.get("evidence")] for e in ranking])
    if isinstance(doc.get("stack"), list) and doc["stack"]:
        page.heading("Stacking: which effects were kept, and why")
        page.table(["effect", "kept", "reason", "residual, fit data [x sensor-noise variance]",
                    "residual, validation data [x sensor-noise variance]",
                    "fit of the held-out runs [%]"],
                   [[s.get("effect"), "yes" if s.get("kept") else "no", s.get("reason"),
                     _num(s.get("residual_x_noise_fit")), _num(s.get("residual_x_noise_validation")),
                     _num(s.get("fit_percent_validation"))] for s in doc["stack"] if isinstance(s, dict)])


def build_page(doc: dict, folder, command: str = ""):
    """The HTML page of a diagnosis or comparison JSON and its figures.

    Every table holds values, a number's unit in its column's heading (or in a ``unit`` column); the run held
    out for validation is named near the top and in every per-run table; every command on the page runs as
    written from the folder the user ran the diagnosis (or ``ehas report``) from.

    Parameters
    ----------
    doc : dict
        The JSON (``ehas diagnose --json`` or ``ehas compare --json``); keys other than ``verdict`` and
        ``residual_x_noise`` are read when present and of the expected shape.
    folder : str or Path
        The folder whose PNGs are embedded.
    command : str
        The command that rewrites the page (:func:`report_command`; printed on it).

    Returns
    -------
    ehas_env.output.html.Page
    """
    from ehas_env.output.html import Page

    folder = Path(folder)
    kind = "Diagnosis" if "ranking" in doc or "stack" in doc else "Comparison"
    held = held_out(doc)
    page = Page(f"{kind}: {doc.get('campaign', folder)}")
    if command:
        page.command(command, intro="Regenerate this page (run from the folder the "
                                    f"{kind.lower()} was run in):")
    _verdict(page, doc)
    _validation(page, doc, held)
    _model(page, doc)
    _alternatives(page, doc.get("alternatives") or [], held,
                  "Alternatives: other models that explain the data about as well",
                  "These logs cannot tell these explanations from the reported one (their score difference is "
                  "within what the logs resolve); ehas plan-test designs the runs that decide.")
    _alternatives(page, doc.get("ruled_out") or [], held, "Ruled out: explanations these logs tell apart",
                  "Fitted in place of the reported explanation and worse by more than the logs resolve.")
    if doc.get("per_run"):
        page.heading("Per-run parameters")
        model_effects = (doc.get("model") or {}).get("effects") if isinstance(doc.get("model"), dict) else None
        _per_run_table(page, doc["per_run"], held, model_effects if isinstance(model_effects, dict) else None)
    for key, title in (("drift", "Drift between runs"), ("disturbances", "Disturbances in the residual")):
        texts = [d["text"] for d in doc.get(key) or [] if isinstance(d, dict) and d.get("text")]
        if texts:
            page.heading(title)
            for text in texts:
                page.paragraph(text)
    _search(page, doc)
    figs = _figures(folder)
    if figs:
        page.heading("Figures")
        if held:
            page.paragraph(f"{'Runs' if len(held) > 1 else 'Run'} {', '.join(held)}: held out for validation, "
                           "so marked in every figure that shows it.")
        for p, caption in figs:
            page.figure(p, caption)
    page.heading("Next step")
    nxt = next_step(doc)
    if nxt.startswith("ehas "):
        page.command(nxt, intro="Run from the same folder:")
    else:
        page.paragraph(nxt)
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
    return ("save the calibrated model with ehas compare CAMPAIGN --effects ... --fit --save-model FILE, then run "
            "the controllers on it with ehas bench results/controllers/*.json --model FILE")
