"""Runs off centre: ``reference.offset_deg`` (the sine's mean angle) in every log format, replay, compare, diagnose.

Truth: the reference is ``offset + A sin(2 pi f t)`` once faded in, so over whole
steady cycles the logged ``theta_ref_deg`` averages the offset and swings
``offset +- A`` (analytic); the rig's own model with the hidden effect replays
every run down to the sensor noise (a replay that ignored the offset would miss
the mean angle by ``offset`` degrees: thousands of noise variances); the files
are written with the loggers' own libraries (``format_writers``), not with ehas.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from format_writers import as_logged, write_campaign_as

from ehas_env.cli.main import main
from ehas_env.measurement.campaign import CampaignError, read_campaign, validate_meta
from ehas_env.measurement.replay import ModelSpec, Replayer
from ehas_env.measurement.synthetic import simulate_campaign
from ehas_env.simulation.reference import SineReference

PLAN = ((3, 15.0, 2.0, -20.0), (5, 12.0, 1.5, 25.0))
HIDDEN = {"coulomb_friction": {"Fc": 300.0}}
LABELS = ["csv", "mat5", "mat73", "tdms", "hdf5", "parquet"]


@pytest.fixture(scope="module")
def runs():
    runs, _ = simulate_campaign(HIDDEN, seed=5, duration=2.0, plan=PLAN)
    return as_logged(runs)


@pytest.fixture(scope="module")
def folders(runs, tmp_path_factory):
    root = tmp_path_factory.mktemp("offset")
    return {label: write_campaign_as(root / label, runs, label) for label in LABELS}


def test_the_sidecar_carries_the_mean_angle_and_the_log_follows_it(runs):
    for (name, cols, meta), (_, amp, freq, off) in zip(runs, PLAN):
        assert meta["reference"]["offset_deg"] == off and "off" in name
        t = cols["t"]
        steady = t >= 1.0 / freq  # after the one-period fade-in
        whole = steady & (t < 1.0 / freq + math.floor((t[-1] - 1.0 / freq) * freq + 0.01) / freq)
        assert whole.sum() > 400
        ref = cols["theta_ref_deg"][whole]
        assert abs(ref.mean() - off) < 0.01
        assert abs(ref.max() - (off + amp)) < 0.01 and abs(ref.min() - (off - amp)) < 0.01
        assert abs(cols["theta_deg"][whole].mean() - off) < 0.5  # the rig follows it there


@pytest.mark.parametrize("label", LABELS)
def test_every_format_reads_and_replays_the_offset_run(folders, label):
    camp = read_campaign(folders[label])
    offsets = {r.name: r.meta["reference"].get("offset_deg") for r in camp.runs if r.kind == "closed_loop"}
    assert sorted(offsets.values()) == sorted(p[3] for p in PLAN)
    rep = Replayer(camp)
    sims = rep.simulate(ModelSpec(effects=HIDDEN))
    assert rep.log_cost(sims) < 1.5  # the truth replays every run down to the noise
    table = rep.fit_table(sims)
    assert table.overall > 90.0
    if label != "csv":  # and gives what the CSV gives
        csv = Replayer(read_campaign(folders["csv"]))
        assert csv.fit_table(csv.simulate(ModelSpec(effects=HIDDEN))).overall == table.overall


def test_a_replay_that_drops_the_offset_misses_by_far(folders, tmp_path):
    """The check above can fail: the same logs with the sidecar's offset set to 0 are refused (the logged reference
    is not the sidecar's), and the replay of a centred reference misses the mean angle."""
    camp = read_campaign(folders["csv"])
    run = next(r for r in camp.runs if r.kind == "closed_loop")
    side = json.loads((folders["csv"] / f"{run.name}.json").read_text())
    side["reference"].pop("offset_deg")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / f"{run.name}.csv").write_text((folders["csv"] / f"{run.name}.csv").read_text())
    (bad / f"{run.name}.json").write_text(json.dumps(side))
    with pytest.raises(CampaignError, match="theta_ref_deg .* offset_deg 0"):
        read_campaign(bad)
    off = run.meta["reference"]["offset_deg"]
    run.meta["reference"] = {**run.meta["reference"], "offset_deg": 0.0}
    rep = Replayer(camp)
    sims = rep.simulate(ModelSpec(effects=HIDDEN))
    k = camp.runs.index(run)
    late = run.t - run.t[0] > 1.0
    miss = run.columns["theta_deg"][late] - sims[k]["theta_deg"][late]
    assert abs(miss.mean() - off) < 1.0
    assert rep.log_cost(sims) > 10.0


def test_ehas_compare_reads_an_offset_campaign(folders, capsys):
    assert main(["compare", str(folders["tdms"]), "--effects", "coulomb_friction:Fc=300"]) == 0
    assert "overall fit:" in capsys.readouterr().out


@pytest.mark.slow
def test_ehas_diagnose_finds_the_effect_of_an_offset_campaign(folders, tmp_path):
    """About 50 s on two cores (a whole diagnosis); the replay of offset runs it rests on is tested above."""
    out = tmp_path / "d.json"
    assert main(["diagnose", str(folders["parquet"]), "--json", str(out), "--quiet", "--no-propose"]) == 0
    doc = json.loads(out.read_text())
    assert doc["ranking"][0]["effect"] in ("coulomb_friction", "stribeck_friction")
    assert doc["verdict"] == "explained"


@pytest.mark.slow
@pytest.mark.parametrize("label", [x for x in LABELS if x != "csv"])
def test_diagnose_json_is_the_same_in_every_format(folders, label, tmp_path):
    """About 10 s per campaign once compiled."""
    def diagnosis(folder):
        out = tmp_path / f"{folder.name}.json"
        assert main(["diagnose", str(folder), "--json", str(out), "--quiet", "--no-propose"]) == 0
        doc = json.loads(out.read_text())
        doc.pop("campaign"), doc.pop("elapsed_s"), doc.pop("next", None)  # these name the folder or the time
        return doc

    assert diagnosis(folders[label]) == diagnosis(folders["csv"])


META = {"kind": "closed_loop", "disc_sets": 3, "supply_bar": 220,
        "controller": {"Kp": 1, "Ki": 2, "Kv": 0.0178, "Ka": 0.0002, "rate_hz": 1000}}


@pytest.mark.parametrize("ref, bad", [
    ({"amplitude_deg": 30, "freq_hz": 1, "offset_deg": 15}, "15"),
    ({"amplitude_deg": 30, "freq_hz": 1, "offset_deg": -14.5}, "-14.5"),
    ({"amplitude_deg": 20, "freq_hz": 1, "offset_deg": "10"}, "'10'"),
    ({"amplitude_deg": 20, "freq_hz": 1, "offset_deg": float("nan")}, "nan"),
])
def test_an_offset_beyond_the_stroke_end_is_refused_in_one_line(ref, bad):
    with pytest.raises(CampaignError) as exc:
        validate_meta({**META, "reference": ref}, where="camp/run.json")
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("camp/run.json, reference: key 'offset_deg' = " + bad)
    assert "44.43" in msg


def test_an_offset_inside_the_stroke_is_kept_and_a_missing_one_is_centred():
    ok = validate_meta({**META, "reference": {"amplitude_deg": 30, "freq_hz": 1, "offset_deg": -14.4}})
    assert ok["reference"]["offset_deg"] == -14.4
    assert "offset_deg" not in validate_meta({**META, "reference": {"amplitude_deg": 30, "freq_hz": 1}})["reference"]
    with pytest.raises(ValueError, match="offset_deg .* 44.43"):
        SineReference(30.0, 1.0, offset_deg=20.0)
