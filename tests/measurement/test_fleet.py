"""A fleet of rigs (issue 44, point 4): ``ehas diagnose CAMP1 CAMP2 ...`` diagnoses each campaign as alone, in this
process, in local worker processes or on a Ray cluster, with the same JSON wherever it ran; ``--checkpoint DIR``
keeps each finished diagnosis and a rerun of the same command skips it."""
from __future__ import annotations

import json

import pytest

from ehas_env.cli.main import main
from ehas_env.measurement.campaign import write_campaign
from ehas_env.measurement.synthetic import simulate_campaign
from tests.measurement.fleet_bench import QUICK as _QUICK_OPTIONS, timeless as _timeless

#: a quick diagnosis: one candidate, no hypotheses, no proposal (the fleet's mechanics, not the search, are tested)
QUICK = ["--quiet", *_QUICK_OPTIONS]


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fleet")
    camps = []
    for k, fc in enumerate((250.0, 500.0)):
        runs, _ = simulate_campaign({"coulomb_friction": {"Fc": fc}}, seed=70 + k, duration=1.0,
                                    plan=((3, 20.0, 2.0), (5, 25.0, 3.0)))
        camps.append(str(write_campaign(tmp / f"rig{k}", runs)))
    assert main(["diagnose", *camps, *QUICK, "--json", str(tmp / "serial.json"), "--checkpoint",
                 str(tmp / "ck")]) == 0
    return tmp, camps, json.loads((tmp / "serial.json").read_text())


def test_a_rerun_resumes_from_the_checkpoints(fleet, capsys):
    tmp, camps, serial = fleet
    assert sorted(p.name for p in (tmp / "ck").iterdir()) == ["000.json", "001.json"]
    capsys.readouterr()
    assert main(["diagnose", *camps, *QUICK, "--json", str(tmp / "again.json"), "--checkpoint", str(tmp / "ck")]) == 0
    out = capsys.readouterr().out
    assert "2 of 2 campaigns kept from" in out and "diagnosed" in out  # each campaign's console shown again
    assert json.loads((tmp / "again.json").read_text()) == serial  # nothing rerun: the very same numbers
    # the trend over the fleet names the friction that rose from one rig to the next
    assert any(d["parameter"] == "coulomb_friction.Fc" for d in serial["trend"]["changed"])
    # another option is another task: not taken from the checkpoint
    capsys.readouterr()
    assert main(["diagnose", *camps, *QUICK[:-1], "--json", str(tmp / "other.json"), "--checkpoint",
                 str(tmp / "ck")]) == 0
    assert "kept from" not in capsys.readouterr().out


@pytest.mark.slow  # two worker processes each compile the model
def test_local_workers_give_the_serial_json(fleet):
    tmp, camps, serial = fleet
    assert main(["diagnose", *camps, *QUICK, "--json", str(tmp / "local2.json"), "--executor", "local",
                 "--workers", "2"]) == 0
    assert _timeless(json.loads((tmp / "local2.json").read_text())) == _timeless(serial)


@pytest.mark.slow  # a 2-node Ray cluster on this machine, each node one CPU
def test_a_two_node_ray_cluster_gives_the_serial_json(fleet):
    cluster_utils = pytest.importorskip("ray.cluster_utils")
    tmp, camps, serial = fleet
    cluster = cluster_utils.Cluster(initialize_head=True,
                                    head_node_args={"num_cpus": 1})
    try:
        cluster.add_node(num_cpus=1)
        assert main(["diagnose", *camps, *QUICK, "--json", str(tmp / "ray.json"), "--executor", "ray",
                     "--address", cluster.address]) == 0
    finally:
        import ray

        ray.shutdown()
        cluster.shutdown()
    assert _timeless(json.loads((tmp / "ray.json").read_text())) == _timeless(serial)


def test_a_checkpoint_that_is_a_file_or_not_ours_is_said_in_one_line(fleet, tmp_path, capsys):
    _, camps, _ = fleet
    (tmp_path / "ck").write_text("x")
    assert main(["diagnose", *camps, *QUICK, "--checkpoint", str(tmp_path / "ck")]) == 2
    err = capsys.readouterr().err
    assert "--checkpoint" in err and "is a file, not a folder" in err and (tmp_path / "ck").read_text() == "x"
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "000.json").write_text("{broken")
    (bad / "001.json").write_text("[1, 2]")
    assert main(["diagnose", *camps, *QUICK, "--checkpoint", str(bad)]) == 0
    out = capsys.readouterr().out
    assert out.count("not a checkpoint this command wrote; diagnosing that campaign again") == 2
    assert all(set(json.loads(f.read_text())) == {"task", "result"} for f in bad.iterdir())  # rewritten whole
