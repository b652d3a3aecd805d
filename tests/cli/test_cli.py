"""The ``ehas`` command line: bad input gives one clear line and exit code 2;
``ehas simulate`` writes a run in the measurement format."""
from __future__ import annotations

import json

import numpy as np
import pytest

from ehas_env.cli.main import main


@pytest.mark.parametrize("argv, words", [
    (["simulate", "--disc-sets", "9"], "--disc-sets must be an integer in [1, 7] disc sets, got '9'"),
    (["simulate", "--amplitude", "44.5"], "--amplitude must be a number in (0, 44.43) deg"),
    (["simulate", "--effects", "magic"], "unknown effect 'magic'"),
    (["simulate", "--effects", "coulomb_friction:Fx=3"], "no parameter 'Fx'"),
    (["simulate", "--gains", "Kq=1"], "unknown gain 'Kq'"),
    (["simulate", "--freq", "nan"], "--freq must be a number in (0, 50] Hz, got 'nan'"),
])
def test_bad_arguments_one_clear_line(argv, words, capsys, tmp_path):
    try:
        rc = main([*argv, "--out", str(tmp_path / "x")])
    except SystemExit as exc:  # refused by the option's type, while parsing
        rc = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and err[0].startswith(f"ehas {argv[0]}: error:")
    assert words in err[0]
    assert not list(tmp_path.iterdir())  # nothing written


def test_simulate_writes_measurement_format(tmp_path, capsys):
    stem = tmp_path / "run"
    assert main(["simulate", "--disc-sets", "2", "--amplitude", "10", "--freq", "2", "--cycles", "3",
                 "--sensors", "--seed", "4", "--out", str(stem)]) == 0
    header = (tmp_path / "run.csv").read_text().splitlines()[0].split(",")
    assert {"t", "current_mA", "theta_deg", "theta_ref_deg", "flow_lpm", "p_a_bar", "p_b_bar", "p_s_bar",
            "load_kN"} == set(header)
    data = np.loadtxt(tmp_path / "run.csv", delimiter=",", skiprows=1)
    assert data.shape == (1500, len(header))
    assert np.allclose(np.diff(data[:, header.index("t")]), 1e-3)
    meta = json.loads((tmp_path / "run.json").read_text())
    assert meta["kind"] == "closed_loop" and meta["disc_sets"] == 2
    assert meta["reference"]["amplitude_deg"] == 10 and meta["reference"]["freq_hz"] == 2
    assert {"Kp", "Ki", "Kv", "Ka", "rate_hz"} <= set(meta["controller"])
    # logged current is on the 12-bit DAC grid
    lsb = 40.0 / 4096
    cur = data[:, header.index("current_mA")]
    assert np.allclose(cur / lsb, np.round(cur / lsb), atol=1e-6)
    assert "rms % position error" in capsys.readouterr().out
