"""``ehas model diff FILE``: a model file as a difference from the book's rig (issue 36, "one story").

Truth: the values written into the files by ``ehas model new`` (independent of the difference code) and
the book's rig numbers from docs/rig.md (supply 220 bar, beta 1 GPa).
"""
from __future__ import annotations

import pytest

from ehas_env.cli.main import main


def _new(tmp_path, name, *args):
    path = tmp_path / name
    assert main(["model", "new", str(path), *args]) == 0
    return path


def test_book_rig_has_no_difference(tmp_path, capsys):
    path = _new(tmp_path, "book.json")
    capsys.readouterr()
    assert main(["model", "diff", str(path)]) == 0
    assert "nothing: the book's rig as it is" in capsys.readouterr().out


def test_effect_and_rig_field_listed_with_units(tmp_path, capsys):
    path = _new(tmp_path, "m.json", "--supply-bar", "200", "--effects", "viscous_friction:b=3000")
    capsys.readouterr()
    assert main(["model", "diff", str(path)]) == 1
    out = capsys.readouterr().out
    assert "viscous_friction.b" in out and "3000 N s/m" in out
    assert "supply_bar: 220 -> 200 bar" in out


def test_value_an_effect_replaces_is_not_shown_in_force(tmp_path, capsys):
    path = _new(tmp_path, "b.json", "--bulk-modulus-Pa", "9.3e8", "--effects", "bulk_modulus:beta=7.9e8")
    capsys.readouterr()
    assert main(["model", "diff", str(path)]) == 1
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("beta "))
    assert "not in force: replaced by bulk_modulus.beta" in line and "0.93" not in line
    assert "bulk_modulus.beta" in out and "7.9e+08 Pa" in out


@pytest.mark.parametrize("ci, shown", [([{"effect": "viscous_friction", "param": "b", "value": 3000.0, "low": 2800.0,
                                          "high": 3200.0, "unit": "N s/m"}], "[2800, 3200]"),
                                        ([{"effect": "viscous_friction", "param": "b", "value": 3000.0, "low": 2800.0,
                                           "high": None, "unit": "N s/m"}], "[2800, unbounded]")])
def test_intervals_of_the_calibration_are_printed(tmp_path, capsys, ci, shown):
    import json

    path = _new(tmp_path, "c.json", "--effects", "viscous_friction:b=3000")
    doc = json.loads(path.read_text())
    doc["calibration"] = {"ci95": ci}
    path.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["model", "diff", str(path)]) == 1
    assert shown in capsys.readouterr().out
