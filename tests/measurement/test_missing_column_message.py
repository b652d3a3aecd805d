"""A renamed column (issue 36): the error names the columns found and the --columns that maps them.

Before the fix a run whose logger wrote ``Angle1`` for ``theta_deg`` got "required column 'theta_deg' is
missing; a closed_loop run needs t, current_mA, theta_deg, theta_ref_deg": neither the column the file has
nor the option that fixes it.
"""
from __future__ import annotations

import pytest

from ehas_env.measurement.campaign import CampaignError, read_campaign, validate_run, write_campaign
from ehas_env.measurement.synthetic import simulate_campaign

CL = "cl_2sets_12deg_2hz"


@pytest.fixture(scope="module")
def runs():
    runs, _ = simulate_campaign({}, seed=5, duration=0.6, plan=((2, 12.0, 2.0),))
    return runs


def rename(path, old, new):
    lines = path.read_text().splitlines()
    lines[0] = ",".join(new if c == old else c for c in lines[0].split(","))
    path.write_text("\n".join(lines) + "\n")


def test_a_renamed_column_is_named_with_the_mapping_that_reads_it(tmp_path, runs):
    camp = write_campaign(tmp_path / "camp", runs)
    rename(camp / f"{CL}.csv", "theta_deg", "Angle1")
    with pytest.raises(CampaignError) as exc:
        read_campaign(camp)
    text = str(exc.value)
    assert text.startswith(f"{camp / CL}.csv: required column 'theta_deg' is missing; a closed_loop run needs "
                           "t, current_mA, theta_deg, theta_ref_deg; the file's columns: t, current_mA, ")
    assert "Angle1" in text.split("the file's columns:")[1]
    assert "--columns theta_deg=NAME" in text  # 'Angle1' is not close to 'theta_deg': the general form
    # the mapping the message shows reads the campaign
    assert read_campaign(camp, columns={"theta_deg": "Angle1"}).runs[0].columns["theta_deg"].size > 0


def test_a_column_close_to_the_missing_one_is_offered_as_the_mapping(tmp_path, runs):
    camp = write_campaign(tmp_path / "camp", runs)
    rename(camp / f"{CL}.csv", "theta_deg", "Theta_Deg")
    with pytest.raises(CampaignError, match=r"--columns theta_deg=Theta_Deg reads 'Theta_Deg' as 'theta_deg' \(deg\)"):
        read_campaign(camp)


def test_a_run_built_in_memory_names_its_columns(runs):
    name, cols, meta = next(r for r in runs if r[0] == CL)
    cols = {k: v for k, v in cols.items() if k != "current_mA"}
    with pytest.raises(CampaignError, match=r"required column 'current_mA' is missing; .*the run's columns: t, "
                                            r"theta_deg"):
        validate_run(name, cols, meta)
