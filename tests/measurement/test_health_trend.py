"""A health trend over campaigns (ehas_env.diagnosis.health; ``ehas diagnose CAMP1 CAMP2 ...``, issue 33).

The statistics on tables with known truth, and the command line end to end on two short campaigns of the
package's simulator recorded "weeks apart": Coulomb friction 300 N, then 600 N.
"""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ehas_env.diagnosis.health import trend, trend_text


def _row(effect, param, v, half, unit="N"):
    return {"effect": effect, "param": param, "value": v, "low": v - half, "high": v + half, "unit": unit}


def test_changed_unchanged_and_only_in_some():
    t = trend([("jan", [_row("coulomb_friction", "Fc", 300.0, 10.0), _row("baseline", "K", 1.27, 0.01, "LPM/mA")]),
               ("feb", [_row("coulomb_friction", "Fc", 420.0, 10.0), _row("baseline", "K", 1.28, 0.01, "LPM/mA")]),
               ("mar", [_row("coulomb_friction", "Fc", 600.0, 15.0), _row("baseline", "K", 1.27, 0.01, "LPM/mA"),
                        _row("valve_null_bias", "i_bias", 0.4, 0.05, "mA")])])
    (c,) = t["changed"]
    assert (c["parameter"], c["direction"], c["ratio_first_last"], c["from"], c["to"]) == \
        ("coulomb_friction.Fc", "rises", 2.0, "jan", "mar")
    assert t["unchanged"] == ["baseline.K"]  # 1 % apart: within the model-error floor
    assert t["only_in"] == {"valve_null_bias.i_bias": ["mar"]}
    text = trend_text(t)
    assert "changed: coulomb_friction.Fc rises 2x from jan to mar" in text
    assert "valve_null_bias.i_bias only in mar" in text


def test_values_within_their_intervals_are_unchanged():
    t = trend([("a", [_row("viscous_friction", "b", 4000.0, 600.0)]), ("b", [_row("viscous_friction", "b", 4400.0, 600.0)])])
    assert t["changed"] == [] and t["unchanged"] == ["viscous_friction.b"]


@pytest.mark.slow  # two diagnoses in a new process: about 40 s on two cores
def test_diagnose_several_campaigns_gives_the_trend(tmp_path):
    from ehas_env.measurement.synthetic import write_simulated_campaign

    plan = ((3, 20.0, 1.0), (7, 10.0, 3.0))
    camps = []
    for k, fc in enumerate((300.0, 600.0)):
        d = tmp_path / f"week{1 + 4 * k}"
        write_simulated_campaign(d, {"coulomb_friction": {"Fc": fc}}, seed=40 + k, duration=1.5, plan=plan, valve=False)
        camps.append(str(d))
    out = tmp_path / "trend.json"
    r = subprocess.run([sys.executable, "-m", "ehas_env.cli.main", "diagnose", *camps, "--candidates",
                        "coulomb_friction", "--no-hypotheses", "--no-propose", "--holdout", "none", "--quiet",
                        "--json", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "health trend" in r.stdout and "=== campaign 2 of 2" in r.stdout
    doc = json.loads(out.read_text())
    assert len(doc["campaigns"]) == 2
    ch = {c["parameter"]: c for c in doc["trend"]["changed"]}
    assert ch["coulomb_friction.Fc"]["direction"] == "rises"
    assert ch["coulomb_friction.Fc"]["ratio_first_last"] == pytest.approx(2.0, rel=0.15)
