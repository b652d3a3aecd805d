"""The record ehas keeps of the files it wrote into a folder (``.ehas-output.json``, written by
``ehas simulate-campaign``) is not a run: reading the campaign passes over it without a note, while any other
stray file is still named (issue 36: every line a user reads should mean something)."""
import shutil
from pathlib import Path

from ehas_env.measurement.campaign import read_campaign
from ehas_env.output.outputs import RECORD

ROOT = Path(__file__).resolve().parents[2]


def test_the_output_record_is_not_reported_as_a_skipped_file(tmp_path):
    camp = tmp_path / "campaign"
    shutil.copytree(ROOT / "results" / "demo" / "campaign", camp)
    (camp / RECORD).write_text('{"format": "ehas-output-set", "version": 1, "files": []}\n')
    (camp / "notes.json").write_text("{}\n")
    warnings = read_campaign(camp).warnings
    assert not any(RECORD in w for w in warnings)
    assert any("notes.json" in w for w in warnings)  # a stray sidecar is still named
