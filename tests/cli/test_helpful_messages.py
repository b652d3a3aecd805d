"""Messages that help (issue 36): did-you-mean for commands, options and effect names; a `next:` after compare.

Each case is what a new user typed; before the fix the line named no alternative (`--ouf`), or listed all
31 effects for a typo.
"""
from __future__ import annotations

import pytest

from ehas_env.cli.main import main


def error_line(capsys, argv) -> str:
    rc = main(argv)
    out, err = capsys.readouterr()
    assert rc == 2, (rc, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # one line, no traceback
    return lines[0]


def test_a_mistyped_option_gets_the_closest_option(capsys):
    line = error_line(capsys, ["diagnose", "camp", "--ouf"])
    assert line.startswith("ehas diagnose: error: unrecognized argument: --ouf")
    assert "did you mean '--out'?" in line


def test_a_mistyped_option_with_a_value_and_a_second_one(capsys):
    line = error_line(capsys, ["diagnose", "camp", "--candidats=x", "--jsn", "d.json"])
    assert "--candidats=x (did you mean '--candidates'" in line  # the closest first
    assert "--jsn (did you mean '--json'?)" in line


def test_an_option_with_nothing_close_gets_no_guess(capsys):
    line = error_line(capsys, ["simulate", "--no-such-option"])
    assert "unrecognized argument: --no-such-option" in line and "did you mean" not in line


def test_a_mistyped_command_gets_the_closest_command(capsys):
    line = error_line(capsys, ["diagnos"])
    assert "invalid choice: 'diagnos'; did you mean 'diagnose'?" in line


def test_a_mistyped_choice_gets_the_closest_choice(capsys):
    line = error_line(capsys, ["tune", "--method", "optimise"])
    assert "did you mean 'optimize'?" in line


@pytest.mark.parametrize("typo, expected", [
    ("frictoin", "coulomb_friction"),          # a word of the name
    ("coulomb_fricton", "coulomb_friction"),   # the whole name
    ("leakge", "internal_leakage"),
])
def test_a_mistyped_effect_gets_one_to_three_names_not_all(capsys, typo, expected):
    from ehas_env.physics.effects import REGISTRY

    line = error_line(capsys, ["effects", typo])
    assert f"unknown effect '{typo}'; did you mean" in line and f"'{expected}'" in line
    named = [n for n in REGISTRY if f"'{n}'" in line]
    assert 1 <= len(named) <= 3, named  # was: the list of all 31
    assert "known effects:" not in line


def test_an_effect_name_with_nothing_close_still_lists_them_all(capsys):
    line = error_line(capsys, ["effects", "xyz"])
    from ehas_env.physics.effects import REGISTRY

    assert "known effects: " in line and "backlash, bulk_modulus" in line
    assert all(n in line for n in REGISTRY)  # every one, the generic augmentations (aug_*) too


@pytest.mark.parametrize("argv, expected", [
    (["compare", "camp"], "ehas diagnose camp"),
    (["compare", "camp", "--columns", "theta_deg=Angle"], "ehas diagnose camp --columns theta_deg=Angle"),
    (["compare", "camp", "--effects", "coulomb_friction"],
     "ehas compare camp --effects coulomb_friction --fit --save-model camp-calibrated/model.json"),
    (["compare", "camp", "--effects", "coulomb_friction", "--fit", "--model", "rig.json"],
     "ehas compare camp --model rig.json --effects coulomb_friction --fit --save-model camp-calibrated/model.json"),
    (["compare", "camp", "--effects", "coulomb_friction", "--fit", "--save-model", "m.json"],
     "ehas tune --method model --model m.json"),
])
def test_compare_names_the_next_step(argv, expected):
    from ehas_env.cli.compare import next_step
    from ehas_env.cli.main import build_parser

    args = build_parser("compare").parse_args(argv)
    assert next_step(args, args.campaign) == expected


def test_compare_prints_its_next_step(tmp_path, capsys):
    import json

    from ehas_env.measurement.campaign import write_campaign
    from ehas_env.measurement.synthetic import simulate_campaign

    runs, _ = simulate_campaign({}, seed=5, duration=0.6, plan=((2, 12.0, 2.0),))
    camp = write_campaign(tmp_path / "camp", runs)
    assert main(["compare", str(camp), "--json", str(tmp_path / "c.json")]) == 0
    out = capsys.readouterr().out
    assert f"next: ehas diagnose {camp}\n" in out
    assert json.loads((tmp_path / "c.json").read_text())["next"] == f"ehas diagnose {camp}"


def test_identify_prints_every_number_with_its_unit(tmp_path, capsys):
    """K was printed without unit; the poles, the intervals and the offsets too."""
    import re

    run = tmp_path / "chirp"
    assert main(["excite", "chirp", "--f0", "0.5", "--f1", "40", "--amplitude", "15", "--duration", "4",
                 "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["identify", str(run) + ".csv", "--poles", "2", "--zeros", "0", "--offsets", "output",
                 "--out", str(tmp_path / "ident")]) == 0
    out = capsys.readouterr().out
    assert re.search(r"\n  K = 1\.27\d* LPM/mA, wn = 10\d\.\d+ rad/s", out), out
    assert re.search(r"\n  poles: .* rad/s\n", out)
    assert re.search(r"\n\s+K = [\d.]+ \+- [\de.+-]+ LPM/mA \(", out)
    assert re.search(r"\n\s+wn = [\d.]+ \+- [\de.+-]+ rad/s \(", out)
    assert re.search(r"\n\s+a1 = [\d.]+ \+- [\de.+-]+ 1/s \(", out)
    assert re.search(r"\n\s+a0 = [\d.]+ \+- [\de.+-]+ 1/s\^2 \(", out)
    assert re.search(r"\n\s+b0 = [\d.]+ \+- [\de.+-]+ LPM/\(mA s\^2\) \(", out)
    assert re.search(r"\n\s+output_offset = [-\de.+]+ \+- [\de.+-]+ LPM \(", out)


@pytest.mark.parametrize("name, unit", [("flow_lpm", "LPM"), ("current_mA", "mA"), ("p_a_bar", "bar"),
                                        ("theta_deg", "deg"), ("y1", "y1")])
def test_the_unit_of_a_signal_is_the_end_of_its_name(name, unit):
    from ehas_env.identification.fit import signal_unit

    assert signal_unit(name) == unit


def test_the_errors_page_quotes_the_mistyped_effect_message_as_the_tool_prints_it(capsys):
    """docs/errors.md shows the message of a mistyped effect word for word: the count of effects in it is the
    registry's, not a number typed once (it said 31 while the tool listed 39)."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "errors.md").read_text()
    shown = next(line.strip() for line in doc.splitlines() if "unknown effect 'frictoin'" in line)
    assert main(["effects", "frictoin"]) == 2
    printed = capsys.readouterr().err.strip()
    assert printed == shown


def test_the_stacking_table_keeps_a_generated_blocks_name_apart_from_its_verdict():
    """A block generated from kind and place (aug_beyond_chamber_a, 20 characters) ran into its "kept" column."""
    from types import SimpleNamespace as NS

    from ehas_env.cli.diagnose import _stack_text

    res = NS(steps=[NS(effect="external_leakage", kept=False, reason="stands in"),
                    NS(effect="aug_beyond_chamber_a", kept=True, reason="a term above 45 bar")],
             model=NS(effects={"aug_beyond_chamber_a": {}}))
    lines = _stack_text(res).splitlines()
    assert lines[2].split() == ["aug_beyond_chamber_a", "kept", "a", "term", "above", "45", "bar"]
    assert lines[1].index("not kept") == lines[2].index("kept")
