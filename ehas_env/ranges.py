"""One place where numbers from users get their type, unit and allowed range.

Every numeric command-line option is declared with :func:`number` (an argparse
``type=``), and the readers of files from elsewhere (training configs,
controller and model JSON) call :func:`check_number` / :func:`check_field`,
so the command line, the files and the Python API refuse the same things with
the same words::

    --cycles must be a number in (0, 10000] reference cycles, got '1e308'
    runs/x.toml: [algo] gamma must be a number in (0, 1], got 2

The ranges are physical or practical limits: the rig's own (1..7 disc sets,
amplitudes inside the stroke ends at 44.43 deg, +-20 mA at the servo amplifier)
and upper bounds that keep a run's memory and time sane (a simulation of more
than :data:`MAX_SIM_SECONDS` s, a signal of more than :data:`MAX_SAMPLES`
samples).  ``docs/errors.md`` lists them for users.

This module imports nothing heavy: building the parser stays cheap.

Examples
--------
>>> cycles = number("--cycles", "reference cycles", 0, 1e4, lo_open=True)
>>> cycles("3")
3.0
>>> cycles("1e308")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: --cycles must be a number in (0, 10000] reference cycles, got '1e308'
>>> check_field("disc_sets", 9, "cfg.toml: [env.kwargs] disc_sets")
Traceback (most recent call last):
...
ValueError: cfg.toml: [env.kwargs] disc_sets must be an integer in [1, 7] disc sets, got 9
"""
from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

#: longest simulated run, s (600 s at 1 kHz = 600 000 samples of ~10 signals: tens of MB)
MAX_SIM_SECONDS = 600.0
#: longest excitation signal, samples (10 million doubles = 80 MB per signal)
MAX_SAMPLES = 10_000_000
#: the stroke ends of the 50 mm crank, deg (asin(35 mm / 50 mm); ehas_env.physics.rig THETA_STROKE_END)
STROKE_END_DEG = 44.43
#: the servo amplifier's clip, mA
SERVO_LIMIT_MA = 20.0
SEED_MAX = 2**32 - 1


@dataclass(frozen=True)
class Range:
    """An allowed numeric range with its unit.

    ``integer`` values must be whole numbers (``3`` or ``3.0``, not ``3.5``, not
    ``true``); ``lo_open`` / ``hi_open`` exclude the bound itself.  Every range
    has finite bounds: an absurd number is refused, not allocated.
    """

    lo: float
    hi: float
    unit: str = ""
    integer: bool = False
    lo_open: bool = False
    hi_open: bool = False

    def describe(self) -> str:
        """``an integer in [1, 7] disc sets`` / ``a number in (0, 20] Hz``."""
        what = "an integer" if self.integer else "a number"
        left = "(" if self.lo_open else "["
        right = ")" if self.hi_open else "]"
        text = f"{what} in {left}{_g(self.lo)}, {_g(self.hi)}{right}"
        return f"{text} {self.unit}" if self.unit else text

    def check(self, value, where: str):
        """``value`` as int/float if it is in the range; ValueError ``WHERE must be ..., got VALUE`` otherwise.

        Accepts Python numbers (and numpy scalars); strings are refused here
        (a config's ``freq_hz = "1"`` is an error, not a number).
        """
        if isinstance(value, bool) or not _is_number(value):
            raise ValueError(f"{where} must be {self.describe()}, got {value!r}")
        v = float(value)
        if not math.isfinite(v) or not self._inside(v) or (self.integer and not v.is_integer()):
            raise ValueError(f"{where} must be {self.describe()}, got {value!r}")
        return int(v) if self.integer else v

    def parse(self, text: str, where: str):
        """A command-line string checked against the range (ValueError naming ``where``)."""
        try:
            v = float(text.strip())
        except (ValueError, AttributeError):
            raise ValueError(f"{where} must be {self.describe()}, got {text!r}") from None
        if not math.isfinite(v) or not self._inside(v) or (self.integer and not v.is_integer()):
            raise ValueError(f"{where} must be {self.describe()}, got {text!r}")
        return int(v) if self.integer else v

    def _inside(self, v: float) -> bool:
        lo_ok = v > self.lo if self.lo_open else v >= self.lo
        hi_ok = v < self.hi if self.hi_open else v <= self.hi
        return lo_ok and hi_ok


class Number:
    """An argparse ``type=``: parses the option's text and checks its :class:`Range`.

    The error names the option, the allowed range with its unit and the value
    given; :class:`ehas_env.cli.main.Parser` prints it as one line.
    """

    def __init__(self, name: str, rng: Range):
        self.name = name
        self.range = rng
        self.__name__ = f"number in {rng.describe()}"  # argparse shows a type's __name__ in some messages

    def __call__(self, text: str):
        try:
            return self.range.parse(text, self.name)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    def __repr__(self) -> str:
        return f"number({self.name!r}, {self.range.describe()!r})"


def number(name: str, unit: str = "", lo: float = 0.0, hi: float = 1.0, *, integer: bool = False,
           lo_open: bool = False, hi_open: bool = False) -> Number:
    """argparse ``type=`` for the option ``name``: a finite number (``integer``: whole) in [lo, hi].

    >>> number("--disc-sets", "disc sets", 1, 7, integer=True)("7")
    7
    """
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise ValueError(f"number({name!r}): bounds must be finite with lo <= hi, got [{lo}, {hi}]")
    return Number(name, Range(float(lo), float(hi), unit, integer, lo_open, hi_open))


def option(name: str, field: str) -> Number:
    """argparse ``type=`` for option ``name`` with the shared range of :data:`FIELDS` ``field``.

    >>> option("--freq", "freq_hz")("3")
    3.0
    """
    return Number(name, FIELDS[field])


def check_number(value, where: str, unit: str = "", lo: float = 0.0, hi: float = 1.0, *, integer: bool = False,
                 lo_open: bool = False, hi_open: bool = False):
    """The plain-function form of :func:`number`, for file readers and the Python API.

    >>> check_number(2, "x.toml: [algo] gamma", "", 0, 1, lo_open=True)
    Traceback (most recent call last):
    ...
    ValueError: x.toml: [algo] gamma must be a number in (0, 1], got 2
    """
    return Range(float(lo), float(hi), unit, integer, lo_open, hi_open).check(value, where)


def check_field(field: str, value, where: str | None = None):
    """Check ``value`` against the shared range of :data:`FIELDS` ``field`` (``where`` names it in errors)."""
    return FIELDS[field].check(value, where or field)


# -- the shared ranges -------------------------------------------------------------------------------
#: quantities that appear on the command line, in config files and in the Python API under one name
FIELDS: dict[str, Range] = {
    "disc_sets": Range(1, 7, "disc sets", integer=True),
    "amplitude_deg": Range(0, STROKE_END_DEG, "deg", lo_open=True, hi_open=True),
    "freq_hz": Range(0, 50, "Hz", lo_open=True),
    "cycles": Range(0, 10_000, "reference cycles", lo_open=True),
    "duration_s": Range(0, MAX_SIM_SECONDS, "s", lo_open=True),
    "theta0_deg": Range(-40, 40, "deg"),
    "seed": Range(0, SEED_MAX, "", integer=True),
    "current_mA": Range(0, SERVO_LIMIT_MA, "mA", lo_open=True),
    # a relay test's amplitude (ehas tune --method relay): at least one step of the rig's 12-bit output over
    # +-20 mA (40 mA / 4096 = 0.0098 mA); a smaller relay is rounded to 0 mA there and does not move the valve
    "relay_mA": Range(0.01, SERVO_LIMIT_MA, "mA"),
    "offset_mA": Range(-SERVO_LIMIT_MA, SERVO_LIMIT_MA, "mA"),
    "supply_bar": Range(0, 350, "bar", lo_open=True),
    "workers": Range(1, 1024, "workers", integer=True),
    # a controller gain (mA per deg, deg/s, ...): finite and far beyond any useful loop gain, so the
    # loop's arithmetic stays finite (1e308 overflows)
    "gain": Range(-1e6, 1e6, ""),
    "rate_hz": Range(1, 1e6, "Hz"),
    # the Python API's plant (ehas_env.simulation.plant.Plant): a load inertia up to a crank held still
    # (1e9 kg m^2 clamps it in the tests); a period from the fastest controller rate (1 MHz) to the
    # slowest logging rate a campaign may have (100 Hz)
    "inertia_kgm2": Range(1e-6, 1e12, "kg m^2"),
    "dt": Range(1e-6, 0.01, "s"),
    "substeps": Range(1, 1000, "RK4 sub-steps per period", integer=True),
    # its measurement chain (ehas_env.simulation.sensors.Sensors); flow noise as ehas excite --flow-noise
    "theta_noise_deg": Range(0, 10, "deg"),
    "pressure_noise_bar": Range(0, 100, "bar"),
    "flow_noise_lpm": Range(0, 25, "LPM"),
    "adc_bits": Range(0, 32, "bits", integer=True),
    "dac_bits": Range(0, 32, "bits", integer=True),
    "lvdt_gain_error": Range(-0.5, 0.5, ""),
    # training ([train], [algo], [env])
    "total_steps": Range(1, 1e10, "steps", integer=True),
    "n_envs": Range(1, 65_536, "environments", integer=True),
    "checkpoint_every": Range(1, 1e10, "steps", integer=True),
    "eval_episodes": Range(0, 100_000, "episodes", integer=True),
    "torch_threads": Range(1, 1024, "threads", integer=True),
    "validate_every": Range(0, 1e10, "steps", integer=True),
    "validate_conditions": Range(1, 100_000, "conditions", integer=True),
    "clip_obs": Range(0, 1e6, "", lo_open=True),
    "log_interval_s": Range(0, 1e10, "s", lo_open=True),  # 1e9: never (the smoke configs)
    "max_minutes": Range(0, 525_600, "min", lo_open=True),  # a year
    "learning_rate": Range(0, 1, "", lo_open=True),
    "gamma": Range(0, 1, "", lo_open=True),
    "tau": Range(0, 1, "", lo_open=True),
    "action_noise_std": Range(0, 10, "", lo_open=True),
    # stable-baselines3's numeric hyper-parameters ([algo]): their meaningful ranges (a batch larger than
    # the rollout, or zero epochs, trains nothing; gae_lambda > 1 makes the advantages diverge)
    "gae_lambda": Range(0, 1, ""),
    "n_steps": Range(1, 10_000_000, "steps per environment per rollout", integer=True),
    "batch_size": Range(1, 10_000_000, "samples", integer=True),
    "n_epochs": Range(1, 10_000, "epochs", integer=True),
    "clip_range": Range(0, 10, "", lo_open=True),
    "clip_range_vf": Range(0, 1e6, "", lo_open=True),
    "ent_coef": Range(0, 100, ""),
    "vf_coef": Range(0, 100, ""),
    "max_grad_norm": Range(0, 1e6, "", lo_open=True),
    "target_kl": Range(0, 100, "", lo_open=True),
    "buffer_size": Range(1, 100_000_000, "transitions", integer=True),
    "learning_starts": Range(0, 1e10, "steps", integer=True),
    "gradient_steps": Range(-1, 1_000_000, "gradient steps (-1: as many as environment steps)", integer=True),
    "policy_delay": Range(1, 10_000, "updates", integer=True),
    "target_policy_noise": Range(0, 10, ""),
    "target_noise_clip": Range(0, 10, ""),
    "stats_window_size": Range(1, 1_000_000, "episodes", integer=True),
    "action_repeat": Range(1, 10_000, "control periods", integer=True),
    "action_scale_mA": Range(0, SERVO_LIMIT_MA, "mA", lo_open=True),
    "reward_scale": Range(0, 1e9, "", lo_open=True),
    "action_penalty": Range(0, 1e9, ""),
}

#: numeric keyword arguments of the environment (``[env.kwargs]`` of a training config)
ENV_KWARGS = {"disc_sets": "disc_sets", "amplitude_deg": "amplitude_deg", "freq_hz": "freq_hz",
              "cycles": "cycles", "theta0_deg": "theta0_deg"}


def check_run_length(seconds, dt: float = 1e-3, where: str = "run") -> float:
    """Refuse simulations longer than :data:`MAX_SIM_SECONDS` (the memory a run's signals take grows with it).

    ``Plant.simulate_closed_loop`` and ``Plant.simulate_valve_test`` should call
    this on their duration (``cycles / freq_hz`` or ``duration``) before allocating.

    >>> check_run_length(1e308 / 1.0, where="--cycles 1e308 at --freq 1")
    Traceback (most recent call last):
    ...
    ValueError: --cycles 1e308 at --freq 1 lasts 1e+308 s; at most 600 s can be simulated in one run
    """
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and 0 < seconds <= MAX_SIM_SECONDS):
        raise ValueError(f"{where} lasts {_g(seconds)} s; at most {_g(MAX_SIM_SECONDS)} s can be simulated in one run")
    n = seconds / dt
    if n > MAX_SAMPLES:
        raise ValueError(f"{where} is {_g(n)} samples; at most {MAX_SAMPLES:,} samples per run")
    return float(seconds)


def check_samples(n, where: str) -> int:
    """Refuse signals of more than :data:`MAX_SAMPLES` samples (or fewer than 2)."""
    if not (isinstance(n, (int, float)) and math.isfinite(n) and 2 <= n <= MAX_SAMPLES):
        raise ValueError(f"{where} gives {_g(n)} samples; allowed 2 to {MAX_SAMPLES:,}")
    return int(n)


def split_list(text: str, where: str, what: str, *, max_items: int = 1000, unique: bool = True) -> list[str]:
    """The items of a comma-separated option value, stripped; every list option splits with this.

    Refused: no item at all, an empty item (``70,,220``: a typo, not "skip"),
    more than ``max_items`` items and (``unique``) an item given twice.

    >>> split_list(" 70, 140 ,210", "--supplies", "pressures in bar")
    ['70', '140', '210']
    >>> split_list("70,,210", "--supplies", "pressures in bar")
    Traceback (most recent call last):
    ...
    ValueError: --supplies: empty item in '70,,210'; give comma-separated pressures in bar
    >>> split_list("a,b,a", "--candidates", "effect names")
    Traceback (most recent call last):
    ...
    ValueError: --candidates: 'a' is given twice in 'a,b,a'
    """
    items = [part.strip() for part in str(text).split(",")]
    if not any(items):
        raise ValueError(f"{where}: expected comma-separated {what}, got {text!r}")
    if "" in items:
        raise ValueError(f"{where}: empty item in {text!r}; give comma-separated {what}")
    if len(items) > max_items:
        raise ValueError(f"{where}: at most {max_items} {what}, got {len(items)}")
    if unique:
        dup = next((i for k, i in enumerate(items) if i in items[:k]), None)
        if dup is not None:
            raise ValueError(f"{where}: {dup!r} is given twice in {text!r}")
    return items


def numeric_actions(parser: argparse.ArgumentParser):
    """(option string, action) of every option of ``parser`` typed with :class:`Number` (tests walk these)."""
    for action in parser._actions:
        if isinstance(action.type, Number):
            yield (action.option_strings[0] if action.option_strings else action.dest), action


def _is_number(value) -> bool:
    if isinstance(value, (int, float)):
        return True
    try:  # numpy scalars
        import numbers

        return isinstance(value, numbers.Real)
    except Exception:  # pragma: no cover
        return False


def _g(v) -> str:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return repr(v)
    if v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return f"{v:g}"
