"""ehas export-controller --format c: each controller type's C, compiled with the system's C compiler into a
shared library and driven through ctypes, commands the same currents as the Python law over a 30-cycle
closed-loop run on the Python plant (the plant's loop calls the C law every period)."""
from __future__ import annotations

import ctypes
import shutil
import subprocess

import numpy as np
import pytest

from ehas_controllers.drive import DriveController, export_drives
from ehas_controllers.export_c import controller_c
from ehas_controllers.harmonic import HarmonicCanceller
from ehas_controllers.ilc import ILC
from ehas_controllers.piff import PIFF, GainSchedule
from ehas_env.simulation.plant import Plant

CC = shutil.which("gcc") or shutil.which("cc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler on this machine")


def build(ctrl, tmp_path, name=None):
    cname, header, source = controller_c(ctrl, name)
    (tmp_path / f"{cname}.h").write_text(header)
    (tmp_path / f"{cname}.c").write_text(source)
    lib = tmp_path / f"lib{cname}.so"
    # -Werror: the generated C compiles clean under -Wall; strict C99, no fused multiply-add
    subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-Werror", "-ffp-contract=off", "-shared", "-fPIC",
                    str(tmp_path / f"{cname}.c"), "-o", str(lib), "-lm"], check=True, capture_output=True, text=True)
    return cname, ctypes.CDLL(str(lib))


class CLaw:
    """The exported C controller as a Python controller object: Plant's closed loop calls act() every period."""

    def __init__(self, cname, lib, disc_sets):
        self.lib, self.disc_sets = lib, disc_sets
        self.init = getattr(lib, f"{cname}_init")
        self.init.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_double]
        self.step = getattr(lib, f"{cname}_step")
        self.step.argtypes = [ctypes.c_void_p] + [ctypes.c_double] * 9
        self.step.restype = ctypes.c_double
        size = getattr(lib, f"{cname}_state_size")
        size.restype = ctypes.c_long
        self.state = ctypes.create_string_buffer(size())
        self.started = False

    def reset(self):
        self.started = False

    def act(self, m):
        if not self.started:
            assert self.init(self.state, self.disc_sets, m["amplitude_deg"], m["freq_hz"]) == 0
            self.started = True
        return self.step(self.state, m["t"], m["theta_deg"], m["theta_ref_deg"], m["theta_ref_dot"],
                         m["theta_ref_ddot"], m["theta_ref_dddot"], m["p_a_bar"], m["p_b_bar"], m["p_s_bar"])


class PythonAct:
    """A controller run through its Python ``act`` (a PIFF would otherwise run its law compiled into the model)."""

    def __init__(self, ctrl):
        self.ctrl = ctrl

    def reset(self):
        self.ctrl.reset()

    def act(self, m):
        return self.ctrl.act(m)


def same_commands(plant, python_ctrl, c_ctrl, amplitude, freq, cycles=30):
    ref = plant.simulate_closed_loop(PythonAct(python_ctrl), amplitude_deg=amplitude, freq_hz=freq, cycles=cycles)
    run = plant.simulate_closed_loop(c_ctrl, amplitude_deg=amplitude, freq_hz=freq, cycles=cycles)
    u_py, u_c = ref.current_mA, run.current_mA
    assert u_py.size == int(round(cycles / freq / plant.dt))
    scale = np.max(np.abs(u_py))
    assert scale > 1.0  # the run commands currents (a law stuck at 0 would pass trivially)
    err = np.max(np.abs(u_c - u_py)) / scale
    assert err <= 1e-9, f"largest command difference {err:.3g} of the largest command"
    return u_py, err


def test_piff_with_pressure_feedback_and_dac(tmp_path):
    # every term of the law: jerk feed-forward, high-passed pressure feedback, anti-windup (a small i_max clamps)
    ctrl = PIFF(Kp=1.5, Ki=3.0, Kv=0.0178, Ka=0.00023, Kj=1e-7, Kdp=0.01, dp_hp=20.0, i_max=8.0, output_bits=12,
                name="rig piff")
    cname, lib = build(ctrl, tmp_path)
    assert cname == "rig_piff"
    plant = Plant(disc_sets=3)
    u, _ = same_commands(plant, ctrl.for_plant(3), CLaw(cname, lib, 3), 25.0, 3.0)
    assert np.max(np.abs(u)) == pytest.approx(8.0, abs=ctrl.dac_lsb)  # the clamp was reached: the anti-windup branch ran
    steps = np.unique(np.round(u / ctrl.dac_lsb, 6))
    assert np.allclose(steps, np.round(steps))  # every command on the 12-bit DAC's grid


def test_gain_schedule_picks_the_disc_sets_row(tmp_path):
    sched = GainSchedule({1: PIFF(Kp=0.8, Ki=1.5), 5: PIFF(Kp=2.0, Ki=3.0, Kv=0.02)}, name="p")
    # a one-letter name: its prefix p_ / P_ must not clash with the generated code's own names
    cname, lib = build(sched, tmp_path)
    law = CLaw(cname, lib, 4)
    assert law.init(law.state, 9, 10.0, 1.0) == -1  # no row for 9 disc sets
    same_commands(Plant(disc_sets=4), sched.for_plant(4), law, 20.0, 3.0)  # 4 sets: interpolated gains


def _learned(ctrl, disc_sets, amplitude, freq, cycles):
    sub = ctrl.for_plant(disc_sets)
    Plant(disc_sets=disc_sets).simulate_closed_loop(sub, amplitude_deg=amplitude, freq_hz=freq, cycles=cycles)
    assert ctrl.learned_state(), "the run learned nothing"
    return ctrl


@pytest.mark.parametrize("kind", ["ilc", "harmonic"])
def test_learning_controller_plays_its_learned_table(tmp_path, kind):
    base = PIFF.book()
    ctrl = ILC(base, gain=0.5) if kind == "ilc" else HarmonicCanceller(base, harmonics=5, gain=0.5)
    _learned(ctrl, 2, 20.0, 3.0, 8)
    table = ctrl.feedforward_table("2 sets 20 deg 3 Hz")
    assert np.max(np.abs(table)) > 0.01  # it learned a feed-forward worth playing
    cname, lib = build(ctrl, tmp_path, name=f"{kind}_rig")
    law = CLaw(cname, lib, 2)
    assert law.init(law.state, 2, 20.0, 2.0) == -1  # no table learned at 2 Hz
    # the Python twin of the playback: the drive files of the same learned state, replayed by DriveController
    written = export_drives(ctrl, tmp_path / "drive")
    drive = DriveController([str(p) for p in written[:-1]]).for_plant(2)
    u, _ = same_commands(Plant(disc_sets=2), drive, law, 20.0, 3.0)
    # and the table matters: without it (the base loop alone) the commands differ
    alone = Plant(disc_sets=2).simulate_closed_loop(PythonAct(base.for_plant(2)), amplitude_deg=20.0, freq_hz=3.0,
                                                    cycles=30)
    assert np.max(np.abs(alone.current_mA - u)) > 0.01


def test_drive_file_controller(tmp_path):
    ctrl = _learned(ILC(PIFF.book(), gain=0.5), 1, 15.0, 3.0, 6)
    written = export_drives(ctrl, tmp_path / "drive")
    drive = DriveController([str(p) for p in written[:-1]])
    cname, lib = build(drive, tmp_path)
    same_commands(Plant(disc_sets=1), drive.for_plant(1), CLaw(cname, lib, 1), 15.0, 3.0)


def test_a_learned_agent_and_an_unlearned_ilc_are_refused_in_one_line():
    class Agent:
        kind, name = "learned", "sac"

    with pytest.raises(ValueError, match="learned agent's network is not exported"):
        controller_c(Agent())
    with pytest.raises(ValueError, match="learned nothing yet"):
        controller_c(ILC(PIFF.book()))
