"""Issue 14 for the Python API of the plant: every bad input is one clear line.

Each refusal is a ValueError of one line that names the culprit (the argument,
the effect and its parameter, the controller) and says what is allowed; nothing
escapes as a TypeError, AttributeError, IndexError, OverflowError or numpy
error, and nothing absurd (NaN, a string, a bool, 1e300) is taken silently.
The ranges are those of ``ehas_env.ranges.FIELDS``.  The first refusals
(disc_sets 0/8, inertia -1, an unknown effect or parameter, Fc -3, amplitude
44.5, a NaN current, a controller at 500 Hz) are in ``test_plant.py``.
"""
from __future__ import annotations

import numpy as np
import pytest
from refusals import refused  # tests/ is on sys.path (conftest.py)

from ehas_env.ranges import MAX_SAMPLES
from ehas_env.simulation.plant import Plant, RigController
from ehas_env.simulation.reference import SineReference
from ehas_env.simulation.sensors import Sensors

NAN, INF = float("nan"), float("inf")




@pytest.fixture(scope="module")
def plant():
    return Plant()


class Silent:
    """A Python controller whose act() returns ``value``."""

    def __init__(self, value):
        self.value = value

    def act(self, measurement):
        return self.value


# --- the constructor -----------------------------------------------------------------------------

DISC = "an integer in [1, 7] disc sets"
INERTIA = "a number in [1e-06, 1000000000000] kg m^2"
DT = "a number in [1e-06, 0.01] s"
SUBSTEPS = "an integer in [1, 1000] RK4 sub-steps per period"
SEED = "an integer in [0, 4294967295]"


@pytest.mark.parametrize("kwargs, patterns", [
    ({"disc_sets": 9}, ["disc_sets must be", DISC, "got 9"]),
    ({"disc_sets": 2.5}, ["disc_sets must be", DISC]),
    ({"disc_sets": "3"}, ["disc_sets must be", DISC, "got '3'"]),  # was a TypeError
    ({"disc_sets": None}, ["disc_sets must be", DISC, "got None"]),  # was a TypeError
    ({"disc_sets": NAN}, ["disc_sets must be", DISC]),
    ({"disc_sets": True}, ["disc_sets must be", DISC, "got True"]),
    ({"inertia": NAN}, ["inertia must be", INERTIA]),
    ({"inertia": INF}, ["inertia must be", INERTIA]),
    ({"inertia": "1"}, ["inertia must be", INERTIA, "got '1'"]),
    ({"inertia": True}, ["inertia must be", INERTIA, "got True"]),  # was taken as 1 kg m^2
    ({"inertia": 1e300}, ["inertia must be", INERTIA]),  # was taken
    ({"inertia": 1e-300}, ["inertia must be", INERTIA]),  # was taken
    ({"dt": 0}, ["dt must be", DT]),
    ({"dt": NAN}, ["dt must be", DT]),
    ({"dt": 1.0}, ["dt must be", DT]),
    ({"dt": "1e-3"}, ["dt must be", DT]),
    ({"dt": 1e-300}, ["dt must be", DT]),  # was taken: a 5e298-sample command history at the first run
    ({"substeps": 0}, ["substeps must be", SUBSTEPS]),
    ({"substeps": 2.5}, ["substeps must be", SUBSTEPS]),
    ({"substeps": True}, ["substeps must be", SUBSTEPS, "got True"]),  # was taken as 1
    ({"substeps": 10**9}, ["substeps must be", SUBSTEPS]),  # was taken: hours per second simulated
    ({"seed": -1}, ["seed must be", SEED, "got -1"]),  # was numpy's ValueError at the first run
    ({"seed": 1.5}, ["seed must be", SEED]),  # was numpy's TypeError at the first run
    ({"seed": "x"}, ["seed must be", SEED]),
    ({"seed": True}, ["seed must be", SEED]),
    ({"seed": 2**70}, ["seed must be", SEED]),
    ({"valve": None}, ["valve must be one of grey_box, white_box", "got None"]),
    ({"white_box": 3}, ["white_box must be a WhiteBoxValve", "int"]),
    ({"rig": 3}, ["rig must be a RigParams", "got 3"]),  # was an AttributeError
    ({"rig": {}}, ["rig must be a RigParams", "got {}"]),  # was the book's rig, silently
    ({"sensors": 3}, ["sensors must be a Sensors", "got 3"]),  # was taken, failed later
    ({"sensors": "ideal"}, ["sensors must be a Sensors", "got 'ideal'"]),
    ({"sensors": Sensors(theta_noise_deg=-1.0)}, ["sensors: theta_noise_deg must be", "[0, 10] deg"]),  # was no noise
    ({"sensors": Sensors(theta_noise_deg=NAN)}, ["sensors: theta_noise_deg must be", "got nan"]),  # was NaN logs
    ({"sensors": Sensors(pressure_noise_bar=INF)}, ["sensors: pressure_noise_bar must be", "[0, 100] bar"]),
    ({"sensors": Sensors(flow_noise_lpm=-0.1)}, ["sensors: flow_noise_lpm must be", "[0, 25] LPM"]),
    ({"sensors": Sensors(adc_bits=-3)}, ["sensors: adc_bits must be", "an integer in [0, 32] bits"]),
    ({"sensors": Sensors(adc_bits=2000)}, ["sensors: adc_bits must be", "got 2000"]),  # was an OverflowError
    ({"sensors": Sensors(dac_bits=12.5)}, ["sensors: dac_bits must be", "an integer in [0, 32] bits"]),
    ({"sensors": Sensors(lvdt_gain_error=3.0)}, ["sensors: lvdt_gain_error must be", "[-0.5, 0.5]"]),
    ({"effects_path": 5}, ["effects_path must be a folder or file", "got 5"]),  # was a TypeError
    ({"model": 5}, ["model must be a PlantModel", "int"]),
    ({"model": {}}, ["<model dict>", "not an ehas model file"]),
])
def test_bad_constructor_argument(kwargs, patterns):
    refused(lambda: Plant(**kwargs), *patterns)


def test_a_missing_model_file_is_named():
    refused(lambda: Plant(model="/nonexistent/m.json"), "/nonexistent/m.json", "does not exist",
            exc=FileNotFoundError)


def test_missing_effects_path_is_named(tmp_path):
    refused(lambda: Plant(effects_path=tmp_path / "nope"), "nope", "does not exist")


def _known() -> str:
    """How a refusal's list of known effects starts: every registered effect, sorted (the generated blocks of
    physics/augment.py first, their names starting with aug_)."""
    from ehas_env.physics.effects import REGISTRY

    first = sorted(REGISTRY)[:2]
    assert all(n.startswith("aug_") for n in first)
    return "known effects: " + ", ".join(first)


KNOWN = _known()


@pytest.mark.parametrize("effects, patterns", [
    (5, ["effects must be a dict {name: {param: value}}, a list of effect names or a spec", "got 5"]),
    ({"coulomb_friction": 5}, ["effects: the parameters of 'coulomb_friction' must be a dict", "got 5"]),
    ({"coulomb_friction": [300]}, ["the parameters of 'coulomb_friction' must be a dict", "got [300]"]),
    ({"coulomb_friction": {"Fc": NAN}}, ["effect 'coulomb_friction'", "'Fc'", "[0, 3000] N"]),
    ({"coulomb_friction": {"Fc": INF}}, ["'Fc'", "[0, 3000] N"]),
    ({"coulomb_friction": {"Fc": 1e6}}, ["'Fc'", "[0, 3000] N"]),
    ({"coulomb_friction": {"Fc": "300"}}, ["effect 'coulomb_friction': parameter 'Fc' must be a number in [0, 3000] N",
                                           "got '300'"]),  # was taken as 300
    ({"coulomb_friction": {"Fc": True}}, ["parameter 'Fc' must be a number in [0, 3000] N", "got True"]),  # was 1 N
    ({"coulomb_friction": {"Fc": None}}, ["parameter 'Fc' must be a number", "got None"]),
    ({"coulomb_friction": {"Fk": "x"}}, ["effect 'coulomb_friction' has no parameter 'Fk'", "Fc"]),
    ({1: {}}, ["unknown effect '1'", KNOWN]),
    ([5], ["effects: a list holds effect names (text)", "got 5", KNOWN]),
    ([{"coulomb_friction": {}}], ["a list holds effect names", "coulomb_friction"]),  # was a TypeError
    ("nope", ["unknown effect 'nope'", KNOWN]),
    ("coulomb_friction:Fc=x", ["coulomb_friction:Fc", "must be a number", "'x'"]),
    ({"stribeck_friction": {"Fc": 200, "Fs": 100}}, ["Fs = 100 N must be at least the sliding force Fc = 200 N"]),
])
def test_bad_effects(effects, patterns):
    refused(lambda: Plant(effects=effects), *patterns)


def test_good_values_in_other_clothes_are_taken():
    """numpy numbers, whole floats, a tuple or iterator of names: the same plant as plain Python values."""
    base = Plant(disc_sets=3, effects={"coulomb_friction": {"Fc": 300}}, seed=4)
    other = Plant(disc_sets=np.int64(3), effects={"coulomb_friction": {"Fc": np.float64(300)}}, seed=np.int64(4),
                  dt=np.float64(1e-3), substeps=np.int64(10), inertia=np.float64(base.rig.inertia))
    assert other.rig == base.rig and other.effects == base.effects and other.seed == 4
    assert np.array_equal(other.param_vector, base.param_vector)
    assert Plant(disc_sets=3.0).rig.disc_sets == 3
    assert Plant(effects=iter(["viscous_friction"])).effects == Plant(effects=("viscous_friction",)).effects
    assert Plant(inertia=1e9).rig.inertia == 1e9  # a crank held still (test_plant's clamped piston)


# --- a closed-loop run ---------------------------------------------------------------------------

AMP = "amplitude_deg must be a number in (0, 44.43) deg"
FREQ = "freq_hz must be a number in (0, 50] Hz"
CYCLES = "cycles must be a number in (0, 10000] reference cycles"
DURATION = "duration must be a number in (0, 600] s"
THETA0 = "theta0_deg must be a number in [-40, 40] deg"


@pytest.mark.parametrize("kwargs, patterns", [
    ({"amplitude_deg": 0}, [AMP, "got 0"]),
    ({"amplitude_deg": NAN}, [AMP]),
    ({"amplitude_deg": "20"}, [AMP, "got '20'"]),
    ({"amplitude_deg": True}, [AMP, "got True"]),  # was a 1 deg run
    ({"freq_hz": 0}, [FREQ]),
    ({"freq_hz": INF}, [FREQ]),
    ({"freq_hz": 60}, [FREQ, "got 60"]),  # was taken (a 60 Hz sine sampled at 1 kHz)
    ({"freq_hz": 1e6}, [FREQ]),  # was an IndexError (a run of 0 samples)
    ({"freq_hz": "1"}, [FREQ, "got '1'"]),  # was a TypeError
    ({"freq_hz": None}, [FREQ, "got None"]),  # was a TypeError
    ({"freq_hz": 1e-300}, ["cycles 3 at freq_hz 1e-300 lasts 3e+300 s", "at most 600 s"]),
    ({"cycles": 0}, [CYCLES]),
    ({"cycles": NAN}, [CYCLES]),
    ({"cycles": 1e308}, [CYCLES]),
    ({"cycles": "3"}, [CYCLES, "got '3'"]),  # was a TypeError
    ({"cycles": None}, [CYCLES, "got None"]),  # was a TypeError
    ({"cycles": True}, [CYCLES, "got True"]),  # was one cycle
    ({"cycles": 1e-9}, ["cycles 1e-09 at freq_hz 1", "gives 0 samples", "allowed 2 to"]),  # was an IndexError
    ({"cycles": 10_000, "freq_hz": 10}, ["cycles 10000 at freq_hz 10 lasts 1000 s", "at most 600 s"]),
    ({"duration": 0}, [DURATION]),
    ({"duration": INF}, [DURATION]),
    ({"duration": 1e9}, [DURATION]),
    ({"duration": "1"}, [DURATION, "got '1'"]),  # was a TypeError
    ({"duration": True}, [DURATION, "got True"]),  # was a 1 s run
    ({"duration": 1e-6}, ["duration 1e-06 s", "at dt = 0.001 s", "gives 0 samples"]),  # was an IndexError
    ({"theta0_deg": NAN}, [THETA0, "got nan"]),  # was a run of NaN
    ({"theta0_deg": 90}, [THETA0]),  # was taken: the piston 15 mm beyond its stroke end
    ({"theta0_deg": INF}, [THETA0]),  # was "math domain error"
    ({"theta0_deg": "0"}, [THETA0, "got '0'"]),  # was a TypeError
    ({"reference": 5}, ["reference must be a SineReference", "got 5"]),  # was an AttributeError
    ({"reference": SineReference}, ["reference must be a SineReference", "SineReference"]),
])
def test_bad_closed_loop_argument(plant, kwargs, patterns):
    refused(lambda: plant.simulate_closed_loop(**kwargs), *patterns)


@pytest.mark.parametrize("controller, patterns", [
    (5, ["controller must be a RigController or an object with act(measurement)", "got 5"]),  # AttributeError
    ("book", ["controller must be a RigController", "got 'book'"]),
    ({"Kp": 1.0}, ["controller must be a RigController", "{'Kp': 1.0}"]),
    (RigController, ["controller must be a controller object, got the class RigController",
                     "RigController(...)"]),  # was a TypeError
    (Silent(None), ["controller Silent: act() returned None at t = 0 s", "a current in mA"]),  # was a TypeError
    (Silent("x"), ["controller Silent: act() returned 'x'", "a current in mA"]),  # was float()'s ValueError
    (Silent(np.zeros(2000)), ["controller Silent: act() returned array([0., 0., 0.,", "...", "a current in mA"]),
    (Silent(NAN), ["controller Silent returned a non-finite current nan at t = 0 s"]),
])
def test_bad_controller(plant, controller, patterns):
    refused(lambda: plant.simulate_closed_loop(controller, cycles=1), *patterns)


@pytest.mark.parametrize("field, value, patterns", [
    ("Kp", NAN, ["RigController: Kp must be a number in [-1000000, 1000000]"]),
    ("Ka", 1e300, ["RigController: Ka must be", "[-1000000, 1000000]"]),
    ("rate_hz", 0, ["RigController: rate_hz must be a number in [1, 1000000] Hz", "got 0"]),
    ("rate_hz", 1e300, ["RigController: rate_hz must be", "[1, 1000000] Hz"]),  # was taken
    ("rate_hz", "1000", ["RigController: rate_hz must be", "got '1000'"]),  # was a TypeError
    ("rate_hz", None, ["RigController: rate_hz must be", "got None"]),  # was a TypeError
    ("rate_hz", True, ["RigController: rate_hz must be", "got True"]),  # was taken as 1 Hz
])
def test_bad_rig_controller(field, value, patterns):
    refused(lambda: RigController(**{field: value}), *patterns)


# --- open loop and the valve bench ---------------------------------------------------------------

CURRENT = "current_mA must be a 1-D sequence of currents in mA, one per sample period"


@pytest.mark.parametrize("current, patterns", [
    (np.zeros((10, 3)), [CURRENT, "shape (10, 3)"]),  # was flattened into 30 samples
    (5.0, [CURRENT, "the single number 5.0"]),  # was a one-sample run
    ("abc", [CURRENT, "got 'abc'"]),  # was float()'s ValueError
    (["1", "2"], [CURRENT, "an array of text"]),  # was taken as numbers
    (None, [CURRENT, "got None"]),  # was "a non-finite value at sample 0"
    (object(), [CURRENT, "<object object"]),  # was a TypeError
    (np.array([1 + 1j]), [CURRENT, "complex numbers"]),  # imaginary part was dropped with a warning
    (np.array([True, False]), [CURRENT, "booleans"]),  # was taken as 1, 0 mA
    ([[1.0, 2.0], [3.0]], [CURRENT, "a ragged list"]),  # was numpy's ValueError
    (np.array([]), ["current_mA is empty"]),
    (np.array([0.0, INF]), ["current_mA holds a non-finite value (inf) at sample 1"]),
])
@pytest.mark.parametrize("method", ["simulate", "simulate_valve_test"])
def test_bad_current(plant, method, current, patterns):
    refused(lambda: getattr(plant, method)(current), *patterns)


def test_too_long_a_current_is_refused_before_it_is_simulated(plant):
    refused(lambda: plant.simulate(np.zeros(MAX_SAMPLES + 1)), "current_mA holds 10,000,001 samples",
            "at most 10,000,000")


def test_a_column_vector_of_currents_is_one_signal(plant):
    a = plant.simulate(np.full(50, 3.0))
    b = plant.simulate(np.full((50, 1), 3.0))
    assert np.array_equal(a.theta_deg, b.theta_deg)


@pytest.mark.parametrize("theta0, patterns", [
    (NAN, [THETA0, "got nan"]),  # was a NaN run
    (90, [THETA0]),
    ("0", [THETA0]),  # was a TypeError
])
def test_bad_open_loop_start(plant, theta0, patterns):
    refused(lambda: plant.simulate(np.zeros(10), theta0_deg=theta0), *patterns)


@pytest.mark.parametrize("theta", [NAN, INF, 1e308, "0"])
def test_bad_initial_state(plant, theta):
    refused(lambda: plant.initial_state(theta), "theta_deg must be a number in [-90, 90] deg")


@pytest.mark.parametrize("supply, patterns", [
    (0, ["supply_bar must be a number in (0, 350] bar", "got 0"]),
    (NAN, ["supply_bar must be", "(0, 350] bar"]),
    (1e300, ["supply_bar must be", "(0, 350] bar"]),  # was taken
    ("70", ["supply_bar must be", "got '70'"]),  # was a TypeError
    (None, ["supply_bar must be", "got None"]),  # was a TypeError
])
def test_bad_valve_bench_supply(plant, supply, patterns):
    refused(lambda: plant.simulate_valve_test(np.zeros(10), supply_bar=supply), *patterns)
