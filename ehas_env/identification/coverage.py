"""How often the 95 % intervals of ``ehas identify`` contain the truth: a Monte-Carlo check.

The truth is the book's chirp model of the servo valve,
``Q/i = 14567.29 / (s^2 + 147.83 s + 11449.86)`` LPM/mA (K = 1.272 LPM/mA,
wn = 107.0 rad/s, zeta = 0.691), simulated by python-control (an exact
zero-order-hold discretisation, independent of the estimator's own simulator)
for a logarithmic chirp, plus measurement noise from numpy's generator of a
given seed.  For every seed the model is fitted with
:func:`ehas_env.identification.fit.tfest` and the intervals of
:mod:`ehas_env.identification.uncertainty` are checked against the truth.

Cases:

* ``white``: white Gaussian noise (the covariance's own assumption);
* ``coloured``: AR(1) noise (pole 0.9), intervals from the coloured formula
  (``auto`` picks it) and, for comparison, from the white formula;
* ``delay+offsets``: a 3 ms input delay and a 0.4 LPM output offset, both
  estimated (white noise).

Run ``python -m ehas_env.identification.coverage --seeds 200 --out results/identification/coverage.md``
(about a minute on one core).
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

#: the book's chirp model (ehas_env/book/data/valve_identification.csv), LPM/mA
NUM = [14567.29]
DEN = [1.0, 147.83, 11449.86]
DT = 1e-3


def truth() -> dict:
    """K, wn, zeta and the coefficients of the true valve model."""
    from ehas_env.identification.fit import second_order_parameters

    return {**second_order_parameters(NUM, DEN), "a1": DEN[1], "a0": DEN[2], "b0": NUM[0]}


def chirp_input(duration: float = 5.0):
    """A 0.5-40 Hz logarithmic chirp of +-10 mA at 1 kHz (times, current)."""
    from ehas_env.identification.excitation import chirp

    sig = chirp(duration=duration, f0=0.5, f1=40.0, amplitude=10.0, method="log")
    return sig.t, sig.current_mA


def true_output(t, u, delay_s: float = 0.0, upsample: int = 10) -> np.ndarray:
    """The noise-free flow, simulated by python-control (a delay: on a grid ``upsample`` times finer)."""
    import control

    G = control.tf(NUM, DEN)
    if not delay_s:
        return control.forced_response(control.sample_system(G, DT, "zoh"), t, u).outputs
    h = DT / upsample
    shift = int(round(delay_s / h))
    uf = np.r_[np.zeros(shift), np.repeat(u, upsample)][: u.size * upsample]
    tf = np.arange(uf.size) * h
    return control.forced_response(control.sample_system(G, h, "zoh"), tf, uf).outputs[::upsample]


def ar1_noise(rng, n: int, std: float, pole: float = 0.9) -> np.ndarray:
    """AR(1) noise of standard deviation ``std``."""
    w = rng.normal(size=n) * std * math.sqrt(1.0 - pole**2)
    e = np.empty(n)
    acc = rng.normal() * std
    for k in range(n):
        acc = pole * acc + w[k]
        e[k] = acc
    return e


def run_case(case: str, seeds, noise: float = 0.3, duration: float = 5.0) -> dict:
    """Coverage counts of one case over ``seeds``.

    Parameters
    ----------
    case : {"white", "coloured", "delay+offsets"}
        The noise and the estimated extras (module docstring).
    seeds : iterable of int
        Seeds of the noise.
    noise : float
        Noise standard deviation, LPM.
    duration : float
        Chirp length, s.

    Returns
    -------
    dict
        ``{"case", "seeds", "inside": {method: {name: count}}, "width": {name: mean relative half-width}}``;
        method is the covariance formula (``auto`` and, for ``coloured``, also ``white``).
    """
    from ehas_env.identification.fit import tfest
    from ehas_env.identification.uncertainty import covariance

    if case not in ("white", "coloured", "delay+offsets"):
        raise ValueError(f"case must be white, coloured or delay+offsets, got {case!r}")
    t, u = chirp_input(duration)
    tru = truth()
    delay_s, y_off = (0.003, 0.4) if case == "delay+offsets" else (0.0, 0.0)
    y_true = true_output(t, u, delay_s) + y_off
    if case == "delay+offsets":
        tru.update(delay_s=delay_s, output_offset=y_off)
    methods = ["auto", "white"] if case == "coloured" else ["auto"]
    inside = {m: {k: 0 for k in tru} for m in methods}
    width = {k: 0.0 for k in tru}
    seeds = list(seeds)
    for seed in seeds:
        rng = np.random.default_rng(seed)
        e = ar1_noise(rng, u.size, noise) if case == "coloured" else noise * rng.normal(size=u.size)
        kw = dict(delay="estimate", offsets="estimate") if case == "delay+offsets" else {}
        est = tfest(t, u, y_true + e, 2, 0, **kw)
        for m in methods:
            ci = covariance(est, coloured=m).ci95
            for k, v in tru.items():
                lo, hi = ci[k]
                inside[m][k] += int(lo <= v <= hi)
                if m == "auto":
                    width[k] += 0.5 * (hi - lo) / abs(v) / len(seeds)
    return {"case": case, "seeds": len(seeds), "noise": noise, "inside": inside, "width": width}


def report(results: list, command: str, elapsed: float) -> str:
    """The markdown of ``results/identification/coverage.md``."""
    lines = ["# Coverage of the 95 % intervals of `ehas identify`", "",
             f"Regenerate: `{command}` ({elapsed:.0f} s here).", "",
             "Truth: the book's valve model 14567.29 / (s^2 + 147.83 s + 11449.86) LPM/mA (K = 1.2723 LPM/mA, "
             "wn = 107.0 rad/s, zeta = 0.691), simulated by python-control for a 0.5-40 Hz log chirp of +-10 mA, "
             "5 s at 1 kHz, plus noise of the seed; fitted with 2 poles, 0 zeros (`tfest`), intervals from "
             "`ehas_env.identification.uncertainty` (delta method at the optimum).", "",
             "A calibrated 95 % interval contains the truth in 95 % of the seeds; with S seeds the binomial "
             "standard deviation of that share is sqrt(0.95 * 0.05 / S) (1.5 % for 200 seeds).", ""]
    for res in results:
        S = res["seeds"]
        names = list(res["inside"]["auto"])
        lines += [f"## {res['case']} ({S} seeds, noise {res['noise']} LPM"
                  + (", AR(1) pole 0.9" if res["case"] == "coloured" else "") + ")", "",
                  "| covariance | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
        for m, counts in res["inside"].items():
            label = {"auto": "as `ehas identify` (auto)", "white": "white formula (for comparison)"}[m]
            lines.append(f"| {label} | " + " | ".join(f"{100 * counts[k] / S:.1f} %" for k in names) + " |")
        lines.append("| mean half-width (relative) | " + " | ".join(f"{100 * res['width'][k]:.2g} %"
                                                                     for k in names) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    from ehas_env.output.files import atomic_write_text
    from ehas_env.ranges import number

    p = argparse.ArgumentParser(prog="python -m ehas_env.identification.coverage", description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=number("--seeds", "seeds", 1, 10_000, integer=True), default=200,
                   help="seeds of the white case, 1..10000 (default 200; the others use a quarter, at least 1)")
    p.add_argument("--out", default="results/identification/coverage.md", help="markdown file to write")
    args = p.parse_args(argv)
    out = Path(args.out)
    if out.suffix != ".md" or out.is_dir():
        p.error(f"--out must be a .md file, got {args.out!r}")
    t0 = time.perf_counter()
    S = args.seeds
    results = [run_case("white", range(S)), run_case("coloured", range(max(1, S // 4))),
               run_case("delay+offsets", range(max(1, S // 4)))]
    cmd = f"python -m ehas_env.identification.coverage --seeds {S} --out {args.out}"
    text = report(results, cmd, time.perf_counter() - t0)
    atomic_write_text(out, text)
    print(text)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
