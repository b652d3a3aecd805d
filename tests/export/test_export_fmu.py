"""ehas export-fmu: the FMI 2.0 co-simulation FMU passes FMPy's validation and, simulated by FMPy, gives Plant's
numbers (within 1e-9 of each channel's largest value; measured: identical to the last bit) over benchmark runs --
open loop with a sine current (through the stroke ends) and closed loop with the pi_ff law -- for the book rig
and for a model file with two effects and a recalibrated crank."""
from __future__ import annotations

import shutil
import zipfile

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402

from ehas_controllers.piff import PIFF  # noqa: E402
from ehas_env.simulation.fmu import write_fmu  # noqa: E402
from ehas_env.cli.main import main  # noqa: E402
from ehas_env.simulation.plant import Plant  # noqa: E402

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None,
                                reason="no C compiler on this machine")
DT = 1e-3
CHANNELS = {"theta_deg": "theta_deg", "omega_deg_s": "omega_deg_s", "theta_crank_deg": "theta_crank_deg",
            "flow_lpm": "flow_lpm", "p_a_bar": "p_a_bar", "p_b_bar": "p_b_bar", "p_s_bar": "p_s_bar",
            "load_kN": "load_kN"}


@pytest.fixture(scope="module")
def two_effects(tmp_path_factory):
    path = tmp_path_factory.mktemp("model") / "two_effects.json"
    assert main(["model", "new", str(path), "--effects", "coulomb_friction:Fc=400,internal_leakage:C_leak=3e-12",
                 "--crank-radius-mm", "55", "--name", "two effects"]) == 0
    return str(path)


def agree(fmu_result, sim, channels, n):
    for out, field in channels.items():
        a, b = fmu_result[out][:n], getattr(sim, field)[:n]
        scale = np.max(np.abs(b))
        assert scale > 0.0, out
        err = np.max(np.abs(a - b)) / scale
        assert err <= 1e-9, f"{out}: largest difference {err:.3g} of the channel's largest value"


@pytest.mark.parametrize("which", ["book", "two_effects"])
def test_open_loop_sine_current(tmp_path, which, request):
    model = None if which == "book" else request.getfixturevalue("two_effects")
    fmu = tmp_path / "rig.fmu"
    write_fmu(fmu, model, disc_sets=3)
    assert validate_fmu(str(fmu)) == []
    names = zipfile.ZipFile(fmu).namelist()
    assert {"modelDescription.xml", "sources/ehas_rig.c", "binaries/linux64/ehas_rig.so"} <= set(names)
    n = 3000
    t = np.arange(n) * DT
    cmd = 4.0 * np.sin(2 * np.pi * 1.0 * t) + 0.5  # drifts into a stroke end: the stops are in the run
    sig = np.array(list(zip(t, cmd)), dtype=[("time", float), ("current_mA", float)])
    # the FMU exported for 3 disc sets, run with 5 (its parameter)
    res = fmpy.simulate_fmu(str(fmu), start_time=0.0, stop_time=(n - 1) * DT, step_size=DT, output_interval=DT,
                            input=sig, start_values={"disc_sets": 5}, output=list(CHANNELS))
    sim = (Plant(disc_sets=5, model=model) if model else Plant(disc_sets=5)).simulate(cmd)
    assert len(res) == n
    assert sim.hit_stroke_end
    agree(res, sim, CHANNELS, n)


@pytest.mark.parametrize("which", ["book", "two_effects"])
def test_closed_loop_with_the_pi_ff_law(tmp_path, which, request):
    model = None if which == "book" else request.getfixturevalue("two_effects")
    ctrl = PIFF(Kp=1.5, Ki=3.0, Kv=0.0178, Ka=0.00023, Kdp=0.01, dp_hp=20.0, output_bits=12)
    fmu = tmp_path / "rig.fmu"
    write_fmu(fmu, model, controller=ctrl, disc_sets=5, closed_loop=True)
    assert validate_fmu(str(fmu)) == []
    n = 4000
    res = fmpy.simulate_fmu(str(fmu), start_time=0.0, stop_time=(n - 1) * DT, step_size=DT, output_interval=DT,
                            start_values={"amplitude_deg": 25.0, "freq_hz": 2.0},
                            output=[*CHANNELS, "current_cmd_mA", "theta_ref_deg"])
    sim = (Plant(disc_sets=5, model=model) if model else Plant(disc_sets=5)).simulate_closed_loop(
        ctrl, amplitude_deg=25.0, freq_hz=2.0, cycles=8)
    assert sim.tracking_errors()["rms_error_pct"] < 5.0  # a real tracking run, not a resting plant
    agree(res, sim, {**CHANNELS, "current_cmd_mA": "current_mA", "theta_ref_deg": "theta_ref_deg"}, n)


def test_a_step_that_is_not_whole_control_periods_is_refused(tmp_path):
    fmu = tmp_path / "rig.fmu"
    write_fmu(fmu)
    with pytest.raises(Exception, match="fmi2DoStep"):
        fmpy.simulate_fmu(str(fmu), stop_time=0.01, step_size=0.0015, output_interval=0.0015)


def test_cli_writes_and_refuses_an_existing_file(tmp_path, capsys):
    out = tmp_path / "rig.fmu"
    assert main(["export-fmu", "--out", str(out), "--no-binary"]) == 0
    names = zipfile.ZipFile(out).namelist()
    assert "sources/ehas_rig.c" in names and not any(n.startswith("binaries/") for n in names)
    assert main(["export-fmu", "--out", str(out)]) != 0
    assert "--overwrite" in capsys.readouterr().err
