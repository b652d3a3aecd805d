"""The diagnosis page is a page a person reads (issue 42, point 4).

Read back with the standard library's ``html.parser`` (not with the code that writes it):

* no table cell is a JSON list or object or a Python repr: nested per-run parameters are a table of their own,
  one row per run, one column per parameter;
* every column of numbers states its unit in its heading (or the table has a ``unit`` column);
* the run held out for validation is named on the page and in every per-run table;
* every command on the page runs as written from the folder the user ran from (``Regenerate`` is run);

and, with matplotlib's renderer, every title, axis label and legend of each figure lies inside the figure and
each figure that shows the held-out run says so.  A slow test renders the page in headless Chromium (Debian's
``chromium`` package) and checks the screenshot is not blank.
"""
from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
HELD = "cl_5sets_30deg_2hz"
HELD_WORDS = "held out for validation"


# -- reading the page back ---------------------------------------------------------------------------------------
class Page(HTMLParser):
    """Tables (header cells, rows of cells), command elements' text, every element's attributes, all text."""

    def __init__(self):
        super().__init__()
        self.tables: list[dict] = []
        self.commands: list[str] = []
        self.attrs: list[tuple[str, dict]] = []
        self.text: list[str] = []
        self._cell = None
        self._command = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.attrs.append((tag, a))
        if tag == "table":
            self.tables.append({"header": [], "rows": []})
        elif tag == "tr" and self.tables:
            self.tables[-1]["rows"].append([])
        elif tag in ("td", "th"):
            self._cell = [tag, ""]
        elif tag == "code" and "command" in (a.get("class") or "").split():
            self._command = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            kind, text = self._cell
            t = self.tables[-1]
            if kind == "th":
                t["header"].append(text.strip())
                if t["rows"] and not t["rows"][-1]:
                    t["rows"].pop()  # the header row is no data row
            else:
                t["rows"][-1].append(text.strip())
            self._cell = None
        elif tag == "code" and self._command is not None:
            self.commands.append(self._command)
            self._command = None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell[1] += data
        if self._command is not None:
            self._command += data


def parse(path: Path) -> Page:
    p = Page()
    p.feed(Path(path).read_text(encoding="utf-8"))
    p.close()
    for t in p.tables:
        t["rows"] = [r for r in t["rows"] if r]
    return p


def is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def looks_like_a_repr(text: str) -> bool:
    """A JSON list/object, a Python list/dict/tuple repr, a bare Python constant or a numpy repr."""
    t = text.strip()
    if not t:
        return False
    try:
        if isinstance(json.loads(t), (list, dict)):
            return True
    except ValueError:
        pass
    return bool(re.fullmatch(r"[\[{(].*[\]})]", t, re.S) or re.search(r"\{'|': |\barray\(|\bnp\.\w", t)
                or t in ("True", "False", "None", "nan", "{}", "[]"))


UNIT_RE = re.compile(r"\[[^\]]+\]|%")


def check_page(page: Page, held: list[str]) -> None:
    """The page's tables hold values with units; the held-out runs are named on it and in per-run tables."""
    assert page.tables, "the page has no table"
    for t in page.tables:
        header, rows = t["header"], t["rows"]
        for r in rows:
            assert len(r) == len(header), (header, r)
            for h, cell in zip(header, r):
                assert not looks_like_a_repr(cell), f"column {h!r}: {cell[:120]!r}"
        has_unit_column = "unit" in header
        for k, h in enumerate(header):
            cells = [r[k] for r in rows if r[k]]
            if cells and all(is_number(c) for c in cells):
                assert has_unit_column or UNIT_RE.search(h), f"numeric column {h!r} states no unit: {header}"
        if header and header[0] == "run":  # a per-run table: each run's role
            assert "role" in header, header
            role = {r[0]: r[header.index("role")] for r in rows}
            for name in held:
                if name in role:
                    assert role[name] == HELD_WORDS, (name, role)
            assert all(v != HELD_WORDS for k, v in role.items() if k not in held), role
    named = [a for tag, a in page.attrs if a.get("id") == "held-out"]
    assert len(named) == 1, "the page does not say which runs are held out for validation"
    assert named[0]["data-runs"].split(",") == (held or [""])
    text = " ".join(page.text)
    for name in held:
        assert f"{HELD_WORDS}: {name}" in text


# -- a small diagnosis folder ------------------------------------------------------------------------------------
def diagnosis_doc() -> dict:
    """A diagnosis JSON of every section the page shows, in the shape ``ehas diagnose --json`` writes
    (docs/measurement-format.md)."""
    runs = ["cl_1set_35deg_3hz", "cl_3sets_20deg_1hz", HELD, "cl_7sets_10deg_3hz"]

    def p(v, lo, hi):
        return {"value": v, "low": lo, "high": hi, "at_range_end": False}

    return {
        "verdict": "explained", "residual_x_noise": 1.06, "residual_x_sensor_noise": 1.2,
        "grade": {"verdict": "explained", "residual_x_noise": 1.06,
                  "thresholds": {"explained": 2.0, "unexplained": 4.0, "block_explained": 4.0,
                                 "block_unexplained": 9.0}},
        "ranking": [{"effect": "coulomb_friction", "params": {"Fc": 299.8}, "fit_percent": 97.73, "score": 7.32,
                     "evidence": "Fc = 300 N; removes 82 % of the residual energy"},
                    {"effect": "stribeck_friction", "params": {"Fc": 299.8, "Fs": 299.8, "vs": 0.0089},
                     "fit_percent": 97.7, "score": 6.9, "evidence": "as well"}],
        "model": {"effects": {"coulomb_friction": {"Fc": 299.8}}, "beta": 9.929e8, "K": 1.284,
                  "ci95": [{"effect": "coulomb_friction", "param": "Fc", "value": 299.8, "low": 298.6, "high": 301.0,
                            "unit": "N"},
                           {"effect": "baseline", "param": "beta", "value": 9.929e8, "low": 9.82e8, "high": 1.004e9,
                            "unit": "Pa"}]},
        "stack": [{"effect": "coulomb_friction", "kept": True, "reason": "sane, lowers the residual",
                   "params": {"Fc": 299.8}, "residual_x_noise_fit": 1.214, "residual_x_noise_validation": 1.75,
                   "fit_percent_validation": 98.8}],
        "validation": {"holdout": [HELD], "fit_window_s": 3.0, "fit_runs": [r for r in runs if r != HELD] + ["valve"],
                       "residual_x_noise_validation": 1.75, "holdout_fit_percent_baseline": 93.2,
                       "holdout_fit_percent_model": 98.8},
        "alternatives": [{"name": "hyp_pressure_friction", "in_place_of": "coulomb_friction",
                          "title": "seal friction proportional to the chamber pressures",
                          "words": "1.36 N per bar of P_A + P_B", "params": {"mu_p": 1.361},
                          "units": {"mu_p": "N/bar"}, "ci95": {"mu_p": [1.356, 1.367]}, "score_difference_db": 0.01,
                          "resolvable_db": 0.3, "within": True, "preferred": False,
                          "model": {"effects": {"hyp_pressure_friction": {"mu_p": 1.361}}, "beta": 9.9e8, "K": 1.28},
                          "reason": "nearly constant at one supply pressure",
                          "per_run_db": {**{r: 0.01 for r in runs}, "valve": 0.0}}],
        "ruled_out": [{"name": "viscous_friction", "in_place_of": "coulomb_friction", "title": "viscous friction",
                       "params": {"b": 250.0}, "units": {"b": "N s/m"}, "ci95": {"b": [240.0, 260.0]},
                       "score_difference_db": 4.1, "resolvable_db": 0.3, "within": False,
                       "per_run_db": {r: 4.0 for r in runs}}],
        "per_run": {"order": "file order",
                    "units": {"coulomb_friction.Fc": "N", "baseline.beta": "Pa", "baseline.K": "LPM/mA"},
                    "runs": [{"run": r, "recorded": None,
                              "params": {"coulomb_friction.Fc": p(300.0 + k, 298.0 + k, 302.0 + k),
                                         "baseline.beta": p(1.0e9, 0.98e9, 1.02e9),
                                         "baseline.K": p(1.284, 1.283, 1.285)}} for k, r in enumerate(runs)]},
        "drift": [], "disturbances": [],
        "campaign": "camp",
        "next": "ehas compare camp --effects coulomb_friction:Fc=299.8 --fit --out compare --json compare.json "
                "--save-model model.json",
    }


def _verdict_png(folder: Path, held=(HELD,)) -> Path:
    from ehas_env.diagnosis.plots import verdict_bars
    from ehas_env.measurement.verdict import Block, grade

    blocks = [Block(r, s, x, 1.0, 500, True) for r, x in (("cl_1set_35deg_3hz", 1.1), (HELD, 1.4))
              for s in ("theta_deg", "p_a_bar")]
    return verdict_bars(folder / "verdict.png", blocks, grade(blocks), holdout=held)


def make_folder(tmp_path: Path, doc: dict, name: str = "diag out") -> Path:
    """A diagnose --out folder: diagnosis.json, a figure, a report.md that shows it; and the campaign folder the
    next step names."""
    folder = tmp_path / name
    folder.mkdir()
    (folder / "diagnosis.json").write_text(json.dumps(doc, indent=2))
    _verdict_png(folder)
    (folder / "report.md").write_text("# Diagnosis\n\n![verdict](verdict.png)\n")
    (tmp_path / "camp").mkdir(exist_ok=True)
    return folder


def ehas_on_path(tmp_path: Path) -> dict:
    """An environment whose ``ehas`` is this checkout's command line (a shim), whatever is installed."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(exist_ok=True)
    shim = bin_dir / "ehas"
    shim.write_text(f"#!/bin/sh\nexec {shlex.quote(sys.executable)} -m ehas_env.cli.main \"$@\"\n")
    shim.chmod(0o755)
    return {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
            "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}


def run_as_written(command: str, cwd: Path, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(command, shell=True, cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


# -- the tests ---------------------------------------------------------------------------------------------------
def test_the_page_is_tables_of_values_with_units_and_names_the_held_out_run(tmp_path):
    from ehas_env.cli.report import build_page

    doc = diagnosis_doc()
    folder = make_folder(tmp_path, doc)
    page = parse(build_page(doc, folder, command="ehas report x --overwrite").write(tmp_path / "p.html"))
    check_page(page, [HELD])
    headers = [t["header"] for t in page.tables]
    # the per-run parameters: one row per run, one column per parameter with its unit (beta as the model shows it)
    # (one table per effect: coulomb_friction, then the baseline's beta and K)
    per_run = next(t for t in page.tables if "Fc [N]" in t["header"])
    assert [r[0] for r in per_run["rows"]] == [r["run"] for r in doc["per_run"]["runs"]]
    h = per_run["header"]
    assert h == ["run", "role", "Fc [N]", "Fc, 95 % interval [N]"]
    row = {r[0]: r for r in per_run["rows"]}
    assert float(row[HELD][h.index("Fc [N]")]) == 302.0
    assert row[HELD][h.index("Fc, 95 % interval [N]")] == "300 to 304"
    assert row[HELD][h.index("role")] == HELD_WORDS
    assert row["cl_1set_35deg_3hz"][h.index("role")] == "fitted"
    base = next(t for t in page.tables if "beta [GPa]" in t["header"])
    assert "K [LPM/mA]" in base["header"]
    assert float(base["rows"][2][base["header"].index("beta [GPa]")]) == 1.0  # 1.0e9 Pa, shown in GPa
    # the alternatives' per-run score differences: a table too, the held-out run marked
    assert ["run", "role", "hyp_pressure_friction [dB]"] in headers
    # every command is shown once, as written
    assert page.commands == ["ehas report x --overwrite", doc["next"]]


@pytest.mark.parametrize("source", ["results/demo/diagnosis/diagnosis.json", "results/report_page/diagnosis.json"])
def test_the_page_of_a_real_diagnosis_json_passes_the_same_checks(tmp_path, source):
    from ehas_env.cli.report import build_page, held_out

    doc = json.loads((ROOT / source).read_text())
    page = parse(build_page(doc, tmp_path, command="ehas report x --overwrite").write(tmp_path / "p.html"))
    held = held_out(doc)
    assert held, "the campaign of 5 runs has a run held out for validation"
    check_page(page, held)


def test_an_older_per_run_shape_and_a_comparison_are_read_as_tables(tmp_path):
    from ehas_env.cli.report import build_page

    doc = diagnosis_doc()
    doc["per_run"] = {"cl_a": {"coulomb_friction.Fc": [300.0, 296.0, 304.0]}, HELD: {"coulomb_friction.Fc": 301.0}}
    page = parse(build_page(doc, tmp_path, command="").write(tmp_path / "p.html"))
    check_page(page, [HELD])
    t = next(t for t in page.tables if "Fc [N]" in t["header"])  # the unit from the library
    assert t["rows"][0][t["header"].index("Fc, 95 % interval [N]")] == "296 to 304"
    comparison = {"campaign": "camp", "residual_x_noise": 1.1, "verdict": "explained",
                  "before": {"model": "baseline", "residual_x_noise": 5.2, "verdict": "unexplained", "fit_percent": 76.0},
                  "after": {"model": "+ coulomb_friction", "residual_x_noise": 1.1, "verdict": "explained",
                            "fit_percent": 97.7, "thresholds": {"explained": 2.0}},
                  "fitted": [{"effect": "coulomb_friction", "param": "Fc", "value": 299.8, "ci95": [298.6, 301.0],
                              "unit": "N"}],
                  "next": "ehas tune --method model --model model.json"}
    page = parse(build_page(comparison, tmp_path, command="").write(tmp_path / "c.html"))
    check_page(page, [])
    assert ["model", "residual [x what does not repeat]", "verdict", "fit [%]"] in [t["header"] for t in page.tables]


def test_the_old_page_fails_these_checks():
    """The checks can fail: a page with the per-run parameters poured into one cell as JSON, a number column
    without a unit, or no held-out run named is refused."""
    for html in ("<table><tr><th>run</th><th>role</th><th>value</th></tr><tr><td>a</td><td>fitted</td>"
                 "<td>[{&quot;run&quot;: &quot;a&quot;}]</td></tr></table><p id='held-out' data-runs=''>x</p>",
                 "<table><tr><th>effect</th><th>fitted</th></tr><tr><td>c</td><td>{'Fc': 3.0}</td></tr></table>"
                 "<p id='held-out' data-runs=''>x</p>",
                 "<table><tr><th>effect</th><th>score</th></tr><tr><td>c</td><td>7.3</td></tr></table>"
                 "<p id='held-out' data-runs=''>x</p>",
                 "<table><tr><th>effect</th><th>score [dB]</th></tr><tr><td>c</td><td>7.3</td></tr></table>"):
        p = Page()
        p.feed(html)
        with pytest.raises(AssertionError):
            check_page(p, [])


def test_every_command_on_the_page_runs_as_written_from_the_users_folder(tmp_path):
    """``ehas report "diag out/"`` from the user's folder: the page's Regenerate line, run as written from there,
    rewrites the page (it failed before: no --overwrite); the next step parses with ehas's own parser and names
    the campaign folder that exists there."""
    from ehas_env.cli.main import build_parser

    doc = diagnosis_doc()
    folder = make_folder(tmp_path, doc)
    env = ehas_on_path(tmp_path)
    r = run_as_written("ehas report 'diag out/'", tmp_path, env)
    assert r.returncode == 0, r.stderr
    page = parse(folder / "report.html")
    check_page(page, [HELD])
    regenerate, nxt = page.commands
    assert shlex.split(regenerate)[:3] == ["ehas", "report", "diag out/"]
    (folder / "report.html").write_text("stale")
    r = run_as_written(regenerate, tmp_path, env)
    assert r.returncode == 0, (regenerate, r.stderr)
    assert parse(folder / "report.html").commands == [regenerate, nxt]  # the same page, written again
    # run from another folder, the same line fails: the page says where to run it from
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    assert run_as_written(regenerate, elsewhere, env).returncode != 0
    assert "run from the folder" in " ".join(page.text)
    words = shlex.split(nxt)
    assert words[0] == "ehas"
    args = build_parser(words[1]).parse_args(words[1:])
    assert (tmp_path / args.campaign).is_dir()
    # with --json and --out, the regenerate line keeps them
    r = run_as_written("ehas report 'diag out/' --json 'diag out/diagnosis.json' --out page.html", tmp_path, env)
    assert r.returncode == 0, r.stderr
    again = parse(tmp_path / "page.html").commands[0]
    assert run_as_written(again, tmp_path, env).returncode == 0, again


def test_report_command_quotes_the_folder_as_given():
    from ehas_env.cli.report import report_command

    assert shlex.split(report_command("runs/my diag/")) == ["ehas", "report", "runs/my diag/", "--overwrite"]
    assert shlex.split(report_command("d", "d/x.json", "p.html")) == ["ehas", "report", "d", "--json", "d/x.json",
                                                                       "--out", "p.html", "--overwrite"]


# -- the figures -------------------------------------------------------------------------------------------------
def _fake_runs(n_closed: int = 1):
    """Closed-loop runs and a valve run in memory, with measured and simulated signals (no simulator)."""
    from ehas_env.measurement.campaign import Run

    dt, cases, sims = 1e-3, [], []
    t = np.arange(0.0, 1.5, dt)
    rng = np.random.default_rng(0)
    names = [HELD, "cl_1set_35deg_3hz_with_a_long_name", "cl_7sets_10deg_3hz"][:n_closed]
    for k, name in enumerate(names):
        w = 2 * np.pi * 2.0
        theta = 20 * np.sin(w * t)
        sim = {"theta_deg": theta, "omega_deg_s": 20 * w * np.cos(w * t), "current_mA": 3 * np.cos(w * t),
               "flow_lpm": 10 * np.cos(w * t), "p_a_bar": 110 + 30 * np.sin(w * t),
               "p_b_bar": 110 - 30 * np.sin(w * t), "load_kN": 4.0 * np.sin(w * t), "p_s_bar": 210 + 0 * t}
        meas = {s: v + 0.02 * np.abs(v).max() * rng.standard_normal(t.size) + 0.3 * np.sign(sim["omega_deg_s"])
                for s, v in sim.items() if s != "omega_deg_s"}
        meta = {"kind": "closed_loop", "supply_bar": 210.0, "disc_sets": 3 + 2 * k,
                "reference": {"amplitude_deg": 20.0, "freq_hz": 2.0, "phase_rad": 0.0, "ramp_cycles": 1.0}}
        run = Run(name, None, meta, t, dt, {"p_s_bar": meas["p_s_bar"]})
        cases.append(SimpleNamespace(run=run, measured=meas, noise={s: 0.02 * np.abs(v).max() + 1e-3
                                                                   for s, v in sim.items()},
                                     signals=tuple(s for s in sim if s != "omega_deg_s")))
        sims.append(sim)
    flow = 10 * np.sin(2 * np.pi * (1 + 10 * t) * t)
    valve = Run("valve_chirp", None, {"kind": "valve_open_loop", "supply_bar": 70.0}, t, dt, {"current_mA": flow / 2})
    cases.append(SimpleNamespace(run=valve, measured={"flow_lpm": flow + 0.05 * rng.standard_normal(t.size)},
                                 noise={"flow_lpm": 0.05}, signals=("flow_lpm",)))
    sims.append({"flow_lpm": flow})
    return SimpleNamespace(cases=cases), sims


def _texts_outside(fig) -> list[str]:
    """The titles, axis labels, tick labels and legends of ``fig`` that extend beyond the figure (pixels),
    measured by matplotlib's renderer."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    box = fig.bbox
    out = []

    def outside(bb):
        return bb.x0 < box.x0 - 1 or bb.y0 < box.y0 - 1 or bb.x1 > box.x1 + 1 or bb.y1 > box.y1 + 1

    texts = [t for t in (getattr(fig, "_suptitle", None),) if t is not None and t.get_text()]
    for ax in fig.axes:
        texts += [t for t in (ax.title, ax.xaxis.label, ax.yaxis.label) if t.get_text()]
        for lg in [ax.get_legend()]:
            if lg is not None and outside(lg.get_window_extent(r)):
                out.append(f"legend of {ax.get_title()!r}")
        if outside(ax.get_tightbbox(r)):
            out.append(f"axes {ax.get_title()!r} with its tick labels")
    for lg in fig.legends:
        if outside(lg.get_window_extent(r)):
            out.append("figure legend")
    out += [repr(t.get_text()) for t in texts if outside(t.get_window_extent(r))]
    return out


@pytest.fixture
def saved_figures(monkeypatch):
    """Every figure saved, checked as it is saved: (texts outside the figure, every text of the figure)."""
    from matplotlib.figure import Figure
    from matplotlib.text import Text

    seen = []
    save = Figure.savefig

    def checked(fig, *a, **k):
        if isinstance(k.get("dpi"), (int, float)):
            fig.set_dpi(k["dpi"])  # measured at the resolution it is saved at (a font's width does not scale)
        seen.append((_texts_outside(fig), " | ".join(t.get_text() for t in fig.findobj(Text))))
        return save(fig, *a, **k)

    monkeypatch.setattr(Figure, "savefig", checked)
    return seen


def test_every_figure_title_and_label_lies_inside_the_figure_and_names_the_held_out_run(tmp_path, saved_figures):
    """Long run names and model labels, two closed-loop runs (the load-velocity figure is narrow: its long
    title was cut at both sides); the held-out run is marked in every figure that shows it.  Measured at the
    resolution each figure is saved at."""
    from ehas_env.diagnosis import plots as plots
    from ehas_env.output.plots import plot_run

    rep, sims = _fake_runs(2)
    label = "+ coulomb_friction + hyp_pressure_friction + aug_hose_ab"
    models = {"baseline, beta/K recal.": sims, label: sims}
    held = (HELD,)
    closed = rep.cases[0]
    plots.overlay(tmp_path / "o.png", closed, {k: v[0] for k, v in models.items()}, holdout=held)
    plots.residual_scatter(tmp_path / "s.png", rep, models, "load_kN", ["sign(velocity)", "velocity", "position"],
                           holdout=held)
    plots.hysteresis(tmp_path / "h.png", rep, models, holdout=held)
    tables = {k: SimpleNamespace(per_signal={"theta_deg": 99.0, "p_a_bar": 60.0, "load_kN": 55.0}, overall=71.0)
              for k in models}
    plots.fit_bars(tmp_path / "f.png", tables)
    plots.valve_overlay(tmp_path / "v.png", rep.cases[-1], {k: v[-1] for k, v in models.items()}, holdout=held)
    _verdict_png(tmp_path)
    res = SimpleNamespace(t=closed.run.t, theta_deg=closed.measured["theta_deg"],
                          theta_ref_deg=sims[0]["theta_deg"], current_mA=closed.measured["current_mA"],
                          p_a_bar=closed.measured["p_a_bar"], p_b_bar=closed.measured["p_b_bar"],
                          p_s_bar=closed.measured["p_s_bar"], load_kN=closed.measured["load_kN"])
    plot_run(res, tmp_path / "r.png", title="a long title of a simulated run " * 6)
    assert len(saved_figures) == 7
    for outside, _ in saved_figures:
        assert not outside, outside
    shows_held = [text for _, text in saved_figures if HELD in text]
    assert len(shows_held) == 4  # overlay, residual scatter, load vs velocity, verdict
    for text in shows_held:
        assert HELD_WORDS in text, text[:300]
    # the valve run is no held-out run: its figure does not say so
    assert HELD_WORDS not in saved_figures[4][1]


# -- the page in a real browser ----------------------------------------------------------------------------------
@pytest.mark.slow
def test_the_page_renders_in_headless_chromium(tmp_path):
    """Renders the page of a small diagnosis folder (its JSON, a verdict, an overlay and a load-velocity figure)
    with headless Chromium and checks the screenshot: produced, the window's size, not blank (run with ``-m slow``; needs
    Debian's ``chromium`` package: ``apt-get install -y chromium``)."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("no chromium on PATH (apt-get install -y chromium); the page is not rendered")
    from PIL import Image

    from ehas_env.cli.report import build_page

    from ehas_env.diagnosis import plots as plots

    doc = diagnosis_doc()
    folder = make_folder(tmp_path, doc, "diag")
    rep, sims = _fake_runs(3)
    models = {"baseline": sims, "+ coulomb_friction": sims}
    plots.overlay(folder / "overlay_after.png", rep.cases[0], {k: v[0] for k, v in models.items()}, holdout=(HELD,))
    plots.hysteresis(folder / "load_vs_velocity.png", rep, models, holdout=(HELD,))
    (folder / "report.md").write_text("![overlay after](overlay_after.png)\n![load vs velocity](load_vs_velocity.png)\n"
                                      "![verdict](verdict.png)\n")
    page = build_page(doc, folder, command="ehas report diag --overwrite").write(folder / "report.html")
    png = tmp_path / "page.png"
    r = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", f"--screenshot={png}",
                        "--window-size=1400,3000", "--hide-scrollbars", page.resolve().as_uri()],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and png.is_file(), r.stderr[-2000:]
    im = np.asarray(Image.open(png).convert("L"), dtype=float)
    assert im.shape == (3000, 1400)
    ink = im < 200
    assert ink.mean() > 0.01, "the screenshot is blank"
    # text and tables from top to bottom, not one block: ink in most bands of 300 px
    assert sum(ink[k:k + 300].mean() > 0.002 for k in range(0, 3000, 300)) >= 8
