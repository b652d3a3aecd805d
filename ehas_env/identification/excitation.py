"""Excitation signals for identifying a servo valve: chirp, PRBS, PRMS, multisine.

Every generator returns an :class:`Excitation`: sample times and a current
sequence in mA, one value per sample period, meant to be held (zero-order hold)
until the next sample, as the rig's controller output is.  Random signals take a
``seed``: the same seed gives the identical sequence.

The book identified its valve from a chirp 0.5-2 Hz at +-20 mA and from a
pseudo-random multilevel signal (PRMS) at +-20 mA (chapter 5).  Which of them
excites the valve's dynamics is the subject of :mod:`ehas_env.identification.book_valve`.

Examples
--------
>>> sig = chirp(duration=10.0, f0=0.5, f1=2.0, amplitude=20.0)
>>> sig.current_mA.size, float(abs(sig.current_mA).max()) <= 20.0
(10000, True)
>>> a = prms(duration=2.0, amplitude=20.0, hold=0.02, levels=5, seed=3)
>>> b = prms(duration=2.0, amplitude=20.0, hold=0.02, levels=5, seed=3)
>>> bool((a.current_mA == b.current_mA).all()), sorted(set(a.current_mA.tolist()))
(True, [-20.0, -10.0, 0.0, 10.0, 20.0])
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: feedback taps (1-based register positions) of maximum-length LFSRs, orders 2..20
#: (x^n + x^k + 1 or the four-tap forms of the standard tables)
MLS_TAPS = {
    2: (2, 1), 3: (3, 2), 4: (4, 3), 5: (5, 3), 6: (6, 5), 7: (7, 6), 8: (8, 6, 5, 4), 9: (9, 5),
    10: (10, 7), 11: (11, 9), 12: (12, 11, 10, 4), 13: (13, 12, 11, 8), 14: (14, 13, 12, 2),
    15: (15, 14), 16: (16, 15, 13, 4), 17: (17, 14), 18: (18, 11), 19: (19, 18, 17, 14), 20: (20, 17),
}
KINDS = ("chirp", "prbs", "prms", "multisine")


@dataclass
class Excitation:
    """A sampled current command.

    Attributes
    ----------
    t : ndarray
        Sample times, s (0, dt, 2 dt, ...).
    current_mA : ndarray
        Command current, mA, held from t_k to t_k+1.
    kind : str
        ``chirp``, ``prbs``, ``prms`` or ``multisine``.
    params : dict
        The generator's arguments (JSON-ready), for the run file's sidecar.
    """

    t: np.ndarray
    current_mA: np.ndarray
    kind: str
    params: dict = field(default_factory=dict)

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0]) if self.t.size > 1 else float("nan")

    def describe(self) -> str:
        args = ", ".join(f"{k}={v}" for k, v in self.params.items())
        return f"{self.kind}({args})"


def _samples(duration: float, rate_hz: float) -> int:
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be a positive sample rate in Hz, got {rate_hz!r}")
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive number of seconds, got {duration!r}")
    n = int(round(duration * rate_hz))
    if n < 2:
        raise ValueError(f"duration {duration:g} s at {rate_hz:g} Hz gives {n} sample(s); need at least 2")
    return n


def _check_amplitude(amplitude: float, offset: float = 0.0) -> None:
    if not (math.isfinite(amplitude) and amplitude > 0):
        raise ValueError(f"amplitude must be a positive current in mA, got {amplitude!r}")
    if not math.isfinite(offset):
        raise ValueError(f"offset must be a finite current in mA, got {offset!r}")


def _check_band(f0: float, f1: float, rate_hz: float) -> None:
    if not (math.isfinite(f0) and math.isfinite(f1) and 0 < f0 < f1):
        raise ValueError(f"frequencies must satisfy 0 < f0 < f1 (Hz), got f0={f0!r}, f1={f1!r}")
    if f1 >= rate_hz / 2:
        raise ValueError(f"f1 = {f1:g} Hz must lie below the Nyquist frequency {rate_hz / 2:g} Hz")


def _hold_samples(hold: float, rate_hz: float) -> int:
    if not (math.isfinite(hold) and hold > 0):
        raise ValueError(f"hold must be a positive clock period in s, got {hold!r}")
    m = int(round(hold * rate_hz))
    if m < 1 or abs(m - hold * rate_hz) > 1e-6 * max(1.0, hold * rate_hz):
        raise ValueError(f"hold = {hold:g} s must be a whole number (>= 1) of sample periods 1/{rate_hz:g} s")
    return m


def chirp(duration: float = 10.0, rate_hz: float = 1000.0, *, f0: float = 0.5, f1: float = 2.0,
          amplitude: float = 20.0, method: str = "linear", offset: float = 0.0) -> Excitation:
    """Swept sine ``offset + amplitude sin(phi(t))`` from ``f0`` to ``f1`` over ``duration``.

    ``method="linear"``: f(t) = f0 + (f1 - f0) t / T;
    ``method="log"``: f(t) = f0 (f1 / f0)^(t / T) (equal time per decade).
    The signal starts at zero with zero phase, so a valve at rest is not kicked.

    Examples
    --------
    >>> s = chirp(duration=4.0, f0=1.0, f1=3.0, amplitude=10.0)
    >>> bool(np.allclose(s.current_mA, 10.0 * np.sin(2 * np.pi * (s.t + 0.25 * s.t**2))))  # f = 1 + 0.5 t Hz
    True
    """
    n = _samples(duration, rate_hz)
    _check_band(f0, f1, rate_hz)
    _check_amplitude(amplitude, offset)
    t = np.arange(n) / rate_hz
    T = float(duration)
    if method in ("linear", "lin"):
        phase = 2.0 * np.pi * (f0 * t + 0.5 * (f1 - f0) * t * t / T)
        method = "linear"
    elif method in ("log", "logarithmic"):
        k = math.log(f1 / f0)
        phase = 2.0 * np.pi * f0 * T / k * (np.exp(k * t / T) - 1.0)
        method = "log"
    else:
        raise ValueError(f"chirp method must be 'linear' or 'log', got {method!r}")
    u = offset + amplitude * np.sin(phase)
    return Excitation(t, u, "chirp", {"f0_hz": f0, "f1_hz": f1, "amplitude_mA": amplitude, "method": method,
                                      "offset_mA": offset, "duration_s": duration, "rate_hz": rate_hz})


def mls(order: int, seed: int = 1) -> np.ndarray:
    """One period (2^order - 1 chips) of a maximum-length binary sequence, values 0/1.

    The Fibonacci shift register starts from a non-zero state derived from
    ``seed`` (a different seed gives a cyclic shift of the same sequence).

    Examples
    --------
    >>> s = mls(4)
    >>> s.size, int(s.sum())   # 2^(n-1) ones, 2^(n-1) - 1 zeros
    (15, 8)
    """
    if order not in MLS_TAPS:
        raise ValueError(f"PRBS order must be an integer in {min(MLS_TAPS)}..{max(MLS_TAPS)}, got {order!r}")
    period = 2**order - 1
    state = (int(seed) % period) + 1  # any non-zero register state
    reg = [(state >> j) & 1 for j in range(order)]
    taps = [tp - 1 for tp in MLS_TAPS[order]]
    out = np.empty(period, dtype=np.int8)
    for k in range(period):
        out[k] = reg[-1]
        fb = 0
        for tp in taps:
            fb ^= reg[tp]
        reg = [fb] + reg[:-1]
    return out


def prbs(duration: float = 10.0, rate_hz: float = 1000.0, *, amplitude: float = 20.0, hold: float = 0.01,
         order: int | None = None, seed: int = 0, offset: float = 0.0) -> Excitation:
    """Pseudo-random binary sequence: +-amplitude, switching only on a clock of period ``hold``.

    The chips come from a maximum-length shift register of ``order`` (default:
    the smallest whose period covers the run, capped at 20), so one period is
    balanced and its autocorrelation is two-valued.  Its power is flat up to
    about 0.44 / hold Hz; choose ``hold`` near a third of the valve's time
    constant to put the power where the valve responds.

    Examples
    --------
    >>> p = prbs(duration=1.0, amplitude=5.0, hold=0.002, order=7)
    >>> sorted(set(p.current_mA.tolist())), p.params["period_chips"]
    ([-5.0, 5.0], 127)
    """
    n = _samples(duration, rate_hz)
    _check_amplitude(amplitude, offset)
    m = _hold_samples(hold, rate_hz)
    chips = _chips(n, m, hold, duration, 3)  # a period of the shortest register (order 2)
    if order is None:
        order = min(max(int(math.ceil(math.log2(chips + 1))), 2), max(MLS_TAPS))
    seq = mls(order, seed)
    bits = np.resize(seq, chips)
    u = offset + amplitude * (2.0 * np.repeat(bits, m)[:n] - 1.0)
    t = np.arange(n) / rate_hz
    return Excitation(t, u, "prbs", {"amplitude_mA": amplitude, "hold_s": hold, "order": order,
                                     "period_chips": 2**order - 1, "seed": seed, "offset_mA": offset,
                                     "duration_s": duration, "rate_hz": rate_hz})


def prms(duration: float = 10.0, rate_hz: float = 1000.0, *, amplitude: float = 20.0, hold: float = 0.01,
         levels: int = 5, seed: int = 0, offset: float = 0.0) -> Excitation:
    """Pseudo-random multilevel signal: a seeded random level every ``hold`` seconds.

    The levels are ``levels`` equally spaced values over [-amplitude, +amplitude]
    (``levels`` >= 2), drawn independently and uniformly at each clock tick and
    held until the next.  Unlike a PRBS it also visits intermediate levels,
    which reveals gain non-linearity; like a PRBS its power is flat up to about
    0.44 / hold Hz, so a short ``hold`` spends most of the power above a slow
    valve's bandwidth.

    Examples
    --------
    >>> p = prms(duration=1.0, amplitude=20.0, hold=0.05, levels=3, seed=1)
    >>> bool(np.all(p.current_mA.reshape(-1, 50) == p.current_mA.reshape(-1, 50)[:, :1]))  # held 50 samples
    True
    """
    n = _samples(duration, rate_hz)
    _check_amplitude(amplitude, offset)
    m = _hold_samples(hold, rate_hz)
    if not (isinstance(levels, (int, np.integer)) and levels >= 2):
        raise ValueError(f"levels must be an integer >= 2, got {levels!r}")
    rng = np.random.default_rng(seed)
    grid = np.linspace(-amplitude, amplitude, int(levels))
    chips = _chips(n, m, hold, duration, 2)
    u = offset + np.repeat(grid[rng.integers(0, levels, chips)], m)[:n]
    t = np.arange(n) / rate_hz
    return Excitation(t, u, "prms", {"amplitude_mA": amplitude, "hold_s": hold, "levels": int(levels), "seed": seed,
                                     "offset_mA": offset, "duration_s": duration, "rate_hz": rate_hz})


def _chips(n: int, m: int, hold: float, duration: float, least: int) -> int:
    """Clock periods in the run; a signal of fewer than ``least`` is a constant or a step, not an excitation."""
    chips = -(-n // m)
    if chips < least:
        raise ValueError(f"hold = {hold:g} s leaves {chips} clock period(s) in a {duration:g} s run; give hold "
                         f"<= duration / {least} = {duration / least:g} s")
    return chips


def multisine(duration: float = 10.0, rate_hz: float = 1000.0, *, f0: float = 0.5, f1: float = 40.0,
              amplitude: float = 20.0, lines: int = 40, phases: str = "low_crest", seed: int = 0,
              offset: float = 0.0) -> Excitation:
    """Sum of equal-amplitude sines on a grid of ``lines`` frequencies from f0 to f1, peak = amplitude.

    The frequencies are whole multiples of 1/duration, log-spaced (duplicates
    merged), so the signal is periodic over the run and its power sits on
    exactly those lines.  Phases: ``"schroeder"`` (Schroeder 1970; low crest
    factor for consecutive harmonics, not for log-spaced lines),
    ``"low_crest"`` (default: Schroeder's, then clipped and restored on the
    lines until the crest factor stops falling, after Van der Ouderaa et al.
    1988) or ``"random"`` (from ``seed``).  The crest factor (peak / rms) is
    in ``params``: a lower one gives more power, hence signal-to-noise, for the
    same peak current.

    Examples
    --------
    >>> m = multisine(duration=2.0, f0=1.0, f1=20.0, amplitude=10.0, lines=5)
    >>> round(float(abs(m.current_mA).max()), 9), m.params["freqs_hz"]
    (10.0, [1.0, 2.0, 4.5, 9.5, 20.0])
    """
    n = _samples(duration, rate_hz)
    _check_band(f0, f1, rate_hz)
    _check_amplitude(amplitude, offset)
    if not (isinstance(lines, (int, np.integer)) and lines >= 1):
        raise ValueError(f"lines must be a positive integer, got {lines!r}")
    df = rate_hz / n  # the DFT grid of the run: the lines are whole periods of it
    room = max(0, min(math.floor(f1 / df + 1e-9), (n - 1) // 2) - max(math.ceil(f0 / df - 1e-9), 1) + 1)
    if lines > room:
        # more lines than the grid holds between f0 and f1 would be merged away without a word
        raise ValueError(f"lines = {lines}: only {room} frequency lines of the 1/duration = {df:g} Hz grid lie "
                         f"between f0 = {f0:g} Hz and f1 = {f1:g} Hz; give lines <= {room} or a longer duration")
    k = np.unique(np.round(np.geomspace(f0, f1, int(lines)) / df).astype(int))
    k = k[(k >= 1) & (k < n // 2)]
    if k.size == 0:
        raise ValueError(f"no frequency line between f0 = {f0:g} Hz and f1 = {f1:g} Hz on the 1/duration = {df:g} Hz grid")
    freqs = k * df
    j = np.arange(1, k.size + 1)
    if phases in ("schroeder", "low_crest"):
        ph = -np.pi * j * (j - 1) / k.size
    elif phases == "random":
        ph = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, k.size)
    else:
        raise ValueError(f"phases must be 'low_crest', 'schroeder' or 'random', got {phases!r}")
    spec = np.zeros(n // 2 + 1, dtype=complex)
    spec[k] = np.exp(1j * ph)
    x = np.fft.irfft(spec, n)
    if phases == "low_crest":
        best = x
        for _ in range(200):
            peak = np.abs(x).max()
            clipped = np.clip(x, -0.6 * peak, 0.6 * peak)
            spec = np.zeros_like(spec)
            spec[k] = np.exp(1j * np.angle(np.fft.rfft(clipped)[k]))
            x = np.fft.irfft(spec, n)
            if _crest(x) < _crest(best) - 1e-6:
                best = x
        x = best
    t = np.arange(n) / rate_hz
    u = offset + amplitude * x / np.max(np.abs(x))
    return Excitation(t, u, "multisine", {"f0_hz": f0, "f1_hz": f1, "amplitude_mA": amplitude, "lines": int(k.size),
                                          "freqs_hz": [round(float(f), 9) for f in freqs], "phases": phases,
                                          "crest_factor": _crest(x), "seed": seed, "offset_mA": offset,
                                          "duration_s": duration, "rate_hz": rate_hz})


def _crest(x: np.ndarray) -> float:
    return float(np.abs(x).max() / np.sqrt(np.mean(x * x)))


def make(kind: str, **kwargs) -> Excitation:
    """Build a signal by name: ``make("chirp", f0=0.5, f1=2)`` (see the generators for arguments).

    Examples
    --------
    >>> make("prbs", duration=0.5, hold=0.005, amplitude=1.0).kind
    'prbs'
    """
    gens = {"chirp": chirp, "prbs": prbs, "prms": prms, "multisine": multisine}
    if kind not in gens:
        raise ValueError(f"unknown excitation '{kind}'; expected one of {', '.join(KINDS)}")
    return gens[kind](**kwargs)
