"""Automatic tuners of the PI + feed-forward controller.

1. :func:`tune_model_based` - from the linearised plant (:mod:`.linear_model`):
   feed-forward gains from the inverse plant, load-pressure feedback chosen for
   the best-damped hydraulic mode, PI from a phase-margin (and optional
   bandwidth) target; reports the margins and can save a Bode plot.
2. :func:`tune_optimize` - minimises the simulated rms % error over chosen
   conditions (mean or worst case) with the batched simulator
   (:mod:`.batch_sim`); it never returns gains worse than its start.
3. :func:`tune_relay` - Astrom-Hagglund relay experiment run in simulation on
   the nonlinear plant -> ultimate gain Ku and period Tu -> PI by a classic rule.
4. :func:`tune_schedule` - any of the above per disc set -> a :class:`GainSchedule`.

Every tuner returns a :class:`TuneResult`: the controller, a report dict of the
figures it based its choice on, and readable lines for the terminal.

Examples
--------
>>> from ehas_controllers.tuners import tune_model_based
>>> res = tune_model_based(disc_sets=3)
>>> round(res.report["phase_margin_deg"])
50
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .batch_sim import Batch, grid
from ehas_env.simulation.linear_model import LinearPlant, operating_flow_lpm
from .piff import GAIN_NAMES, GAIN_UNITS, GainSchedule, PIFF

PRESSURE_FEEDBACK = ("none", "static", "dynamic")
PI_RULES = {
    # name: (Kp / Ku, Ti / Tu), Astrom & Hagglund, "PID controllers" (1995)
    "zn": (0.45, 1.0 / 1.2),  # Ziegler-Nichols
    "tl": (1.0 / 3.2, 2.2),  # Tyreus-Luyben: more gain margin, slower integral
}


@dataclass
class TuneResult:
    """What a tuner produced: ``controller``, the figures in ``report``, printable ``lines``."""

    controller: object
    report: dict = field(default_factory=dict)
    lines: list = field(default_factory=list)

    def text(self) -> str:
        return "\n".join(self.lines)


# -- 1. model-based -------------------------------------------------------------
def feedforward_from_model(lp: LinearPlant, Kdp: float = 0.0, dp_hp: float = 0.0,
                           band_hz: tuple[float, float] = (0.5, 4.0)) -> tuple[float, float, float]:
    """(Kv, Ka, Kj) that best invert the plant over ``band_hz``.

    Least squares of ``Kv s + Ka s^2 + Kj s^3`` against ``1/G(s)`` on s = j w over the
    band (relative error), ``G`` the linear plant seen by the controller's output
    (valve lag, chamber compliance, sample-and-hold delay, pressure feedback).  Below
    the valve's and the hydraulic mode's frequencies this equals the Taylor series of
    1/G (:meth:`LinearPlant.inverse_series`); with a high-passed pressure feedback it
    stays accurate in the band where the series would not.

    Examples
    --------
    >>> kv, ka, kj = feedforward_from_model(LinearPlant(disc_sets=3))
    >>> round(1 / kv, 1)       # deg/s per mA: the book's 1/Kv = 56.25
    56.3
    """
    g = lp.tf(Kdp, dp_hp)
    w = 2 * math.pi * np.linspace(band_hz[0], band_hz[1], 64)
    target = 1.0 / g(1j * w)
    s = 1j * w
    basis = np.stack([s, s**2, s**3], axis=1)
    wt = 1.0 / np.abs(target)
    a = np.vstack([(basis * wt[:, None]).real, (basis * wt[:, None]).imag])
    b = np.concatenate([(target * wt).real, (target * wt).imag])
    # scale the columns: the three gains differ by orders of magnitude
    scale = np.abs(a).max(axis=0)
    c, *_ = np.linalg.lstsq(a / scale, b, rcond=None)
    kv, ka, kj = c / scale
    return float(kv), float(ka), float(kj)


def best_pressure_feedback(lp: LinearPlant, dp_hp: float = 0.0, *, min_damping: float = 0.05,
                           kdp_range=(1e-3, 0.1), n: int = 24, **pi_targets) -> tuple[float, dict]:
    """(Kdp mA/bar, PI design) giving the highest crossover that meets the PI targets.

    Scans Kdp (0 and ``n`` values over ``kdp_range``) on the plant ``lp`` (at its
    operating flow), keeping only values whose closed pressure loop has every
    oscillatory pole damped by at least ``min_damping``.  On this rig the valve
    (17 Hz) is slower than the hydraulic mode (24-64 Hz): through the valve's lag the
    pressure feedback *removes* damping from the hydraulic mode at low flow, so it is
    worth only what it adds to the position loop's gain margin - which this scan measures.
    """
    best = None
    for kdp in np.r_[0.0, np.geomspace(kdp_range[0], kdp_range[1], n)]:
        if kdp and _least_damping(lp, float(kdp), dp_hp) < min_damping:
            continue
        try:
            pi = design_pi(lp.tf(float(kdp), dp_hp), **pi_targets)
        except ValueError:
            continue
        if best is None or pi["crossover_hz"] > best[1]["crossover_hz"] * (1 + 1e-6):
            best = (float(kdp), pi)
    if best is None:
        raise ValueError("no pressure-feedback gain meets the PI targets on this plant")
    return best


def _least_damping(lp: LinearPlant, kdp: float, dp_hp: float) -> float:
    poles = lp.open_loop_poles(kdp, dp_hp)
    if np.any(poles.real > 1e-9 * np.abs(poles).max()):
        return -1.0
    osc = poles[np.abs(poles.imag) > 1e-6 * np.abs(poles).max()]
    if osc.size == 0:
        return 1.0
    return float(np.min(-osc.real / np.abs(osc)))


def design_pi(g, *, phase_margin_deg: float = 50.0, bandwidth_hz: float | None = None, pi_lag_deg: float = 3.0,
              min_gain_margin_db: float = 6.0) -> dict:
    """PI gains for the loop ``C(s) G(s)``, C = Kp (1 + wi / s), from a phase-margin target.

    Without ``bandwidth_hz`` the crossover is the frequency where the plant's phase
    is ``-180 + PM + pi_lag`` (the PI zero costs ``pi_lag`` degrees there), lowered
    until the gain margin is at least ``min_gain_margin_db``.  With ``bandwidth_hz``
    the crossover is fixed and the PI zero is placed to meet the phase margin
    (ValueError if the plant alone has less phase there than the target needs).
    Returns Kp (mA/deg), Ki (mA/(deg s)) and the margins python-control finds on the
    designed loop.
    """
    import control

    if not 5.0 <= phase_margin_deg <= 85.0:
        raise ValueError(f"phase margin must be in [5, 85] deg, got {phase_margin_deg!r}")
    w = np.geomspace(0.5, 2000.0, 6000)
    ph = np.degrees(np.unwrap(np.angle(g(1j * w))))
    mag = np.abs(g(1j * w))

    def pi_at(wc, lag_deg):
        k = np.interp(math.log(wc), np.log(w), mag)
        lag = math.radians(lag_deg)
        return math.cos(lag) / k, wc * math.tan(lag)

    if bandwidth_hz is not None:
        wc = 2 * math.pi * bandwidth_hz
        phase_g = float(np.interp(math.log(wc), np.log(w), ph))
        lag = phase_g + 180.0 - phase_margin_deg
        if lag < 0.0:
            raise ValueError(
                f"a PI cannot reach a {phase_margin_deg:g} deg phase margin at {bandwidth_hz:g} Hz: the plant's own "
                f"phase there is {phase_g:.1f} deg; lower the bandwidth or the phase margin")
        lag = min(lag, 60.0)
        kp, wi = pi_at(wc, lag)
    else:
        target = -180.0 + phase_margin_deg + pi_lag_deg
        idx = np.flatnonzero(ph <= target)
        if idx.size == 0:
            raise ValueError("the plant's phase never falls to the target; the model looks wrong")
        wc = float(w[idx[0]])
        kp, wi = pi_at(wc, pi_lag_deg)
        for _ in range(200):
            gm, _pm, *_ = control.stability_margins(control.tf([kp, kp * wi], [1.0, 0.0]) * g)
            if not np.isfinite(gm) or 20 * math.log10(gm) >= min_gain_margin_db:
                break
            wc *= 0.97
            ph_wc = float(np.interp(math.log(wc), np.log(w), ph))
            kp, wi = pi_at(wc, max(0.0, min(60.0, ph_wc + 180.0 - phase_margin_deg)))
    L = control.tf([kp, kp * wi], [1.0, 0.0]) * g
    gm, pm, _sm, wpc, wgc, _ = control.stability_margins(L)
    return {"Kp": float(kp), "Ki": float(kp * wi), "crossover_hz": float(wgc) / (2 * math.pi),
            "phase_margin_deg": float(pm), "gain_margin_db": float(20 * math.log10(gm)) if np.isfinite(gm) else math.inf,
            "phase_crossover_hz": float(wpc) / (2 * math.pi), "loop": L}


def tune_model_based(disc_sets: int = 3, *, phase_margin_deg: float = 50.0, bandwidth_hz: float | None = None,
                     pi_lag_deg: float = 3.0, min_gain_margin_db: float = 6.0, pressure_feedback: str = "none",
                     Kdp: float | None = None, dp_hp: float = 10.0, amplitude_deg: float = 20.0, freq_hz: float = 2.0,
                     ff_band_hz: tuple[float, float] = (0.5, 4.0), min_damping: float = 0.05, plant=None,
                     bode_path=None, bode_note: str = "") -> TuneResult:
    """Model-based design on the linearised plant of ``disc_sets`` sets.

    The plant is linearised at the mean valve flow of the ``amplitude_deg`` /
    ``freq_hz`` sine.  Steps: (1) PI from the phase margin (and optional bandwidth)
    target with at least ``min_gain_margin_db`` of gain margin (:func:`design_pi`),
    together with (``pressure_feedback`` "static", or "dynamic" high-passed at
    ``dp_hp`` rad/s) the load-pressure feedback ``Kdp`` that allows the highest
    crossover while the pressure loop keeps ``min_damping`` (:func:`best_pressure_feedback`;
    a given ``Kdp`` is used as is; "none" skips it); (2) Kv, Ka, Kj inverting the
    plant with its pressure feedback and sample-and-hold over ``ff_band_hz``
    (:func:`feedforward_from_model`), at the same operating flow: the orifice law's
    flow loss ``Kc |q_c| P_L`` does not change sign with the flow, so its mean acts as
    a linear leak that the acceleration feed-forward must make up for.  ``plant`` (an ``ehas_env.simulation.plant.Plant``) replaces the baseline rig.
    """
    if pressure_feedback not in PRESSURE_FEEDBACK:
        raise ValueError(f"pressure_feedback must be one of {', '.join(PRESSURE_FEEDBACK)}, got {pressure_feedback!r}")
    if plant is None:
        from ehas_env.simulation.plant import Plant

        plant = Plant(disc_sets=disc_sets)
    disc_sets = plant.rig.disc_sets
    hp = dp_hp if pressure_feedback == "dynamic" else 0.0
    lp_null = LinearPlant(plant)
    flow = operating_flow_lpm(amplitude_deg, freq_hz, plant.rig)
    lp_op = LinearPlant(plant, flow_lpm=flow)
    zeta0 = _least_damping(lp_op, 0.0, 0.0)
    targets = {"phase_margin_deg": phase_margin_deg, "bandwidth_hz": bandwidth_hz, "pi_lag_deg": pi_lag_deg,
               "min_gain_margin_db": min_gain_margin_db}
    if pressure_feedback == "none":
        kdp = 0.0
        pi = design_pi(lp_op.tf(), **targets)
    elif Kdp is None:
        kdp, pi = best_pressure_feedback(lp_op, hp, min_damping=min_damping, **targets)
    else:
        kdp = float(Kdp)
        pi = design_pi(lp_op.tf(kdp, hp), **targets)
    zeta = _least_damping(lp_op, kdp, hp)
    kv, ka, kj = feedforward_from_model(lp_op, kdp, hp, ff_band_hz)
    ctrl = PIFF(Kp=pi["Kp"], Ki=pi["Ki"], Kv=kv, Ka=ka, Kj=kj, Kdp=kdp, dp_hp=hp if kdp else 0.0,
                name=f"model-based {disc_sets} sets")
    report = {k: v for k, v in pi.items() if k != "loop"}
    report.update({
        "disc_sets": disc_sets, "operating_flow_lpm": flow, "operating_point": f"{amplitude_deg:g} deg, {freq_hz:g} Hz",
        "hydraulic_wn_hz": lp_null.hydraulic_wn / (2 * math.pi), "hydraulic_damping": zeta0,
        "hydraulic_damping_with_dp": zeta, "velocity_gain_deg_s_per_mA": lp_null.velocity_gain,
        "Ku_linear_mA_per_deg": lp_op.ultimate(kdp, hp)[0],
    })
    lines = [
        f"model-based tuning, {disc_sets} disc sets (linearised at {amplitude_deg:g} deg / {freq_hz:g} Hz: "
        f"mean valve flow {flow:.2f} LPM)",
        f"  hydraulic mode {report['hydraulic_wn_hz']:.1f} Hz, damping ratio {zeta0:.3f} at the operating flow"
        + (f" -> {zeta:.3f} with Kdp {kdp:.4g} mA/bar" if kdp else ""),
        f"  loop: crossover {report['crossover_hz']:.2f} Hz, phase margin {report['phase_margin_deg']:.1f} deg "
        f"(target {phase_margin_deg:g}), gain margin {report['gain_margin_db']:.1f} dB at {report['phase_crossover_hz']:.1f} Hz",
    ]
    if bode_path is not None:
        report["bode_png"] = str(save_bode(pi["loop"], lp_op.tf(kdp, hp), bode_path,
                                           title=f"{getattr(getattr(plant, 'plant_model', None), 'label', 'book rig')}, "
                                                 f"{disc_sets} disc sets: model-based PI (Kp {pi['Kp']:.3g} mA/deg, "
                                                 f"Ki {pi['Ki']:.3g} mA/(deg s))\nlinearised at {amplitude_deg:g} deg / "
                                                 f"{freq_hz:g} Hz ({flow:.1f} LPM mean flow), ZOH delay; loop broken "
                                                 f"at the position error" + (f", Kdp {kdp:.3g} mA/bar closed inside G"
                                                                              if kdp else ""),
                                           note=bode_note))
        lines.append(f"  Bode plot: {report['bode_png']}")
    return TuneResult(ctrl, report, lines)


def save_bode(loop, plant_tf, path, title: str = "", note: str = ""):
    """Bode plot of the plant, the loop and the closed loop, margins marked (PNG).

    ``note`` (the command that regenerates it) goes in a corner and in the PNG's metadata.
    """
    import control
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ehas_env.output.files import atomic_write_bytes
    import io

    w = np.geomspace(1.0, 3000.0, 800)
    f = w / (2 * math.pi)
    gm, pm, _sm, wpc, wgc, _ = control.stability_margins(loop)
    cl = control.feedback(loop, 1)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.5, 6.5), sharex=True)
    for sys, label in ((plant_tf, "plant G (deg/mA)"), (loop, "loop L = C G"), (cl, "closed loop T")):
        r = sys(1j * w)
        ax1.semilogx(f, 20 * np.log10(np.abs(r)), label=label)
        ax2.semilogx(f, np.degrees(np.unwrap(np.angle(r))), label=label)
    ax1.axhline(0, color="k", lw=0.5)
    ax2.axhline(-180, color="k", lw=0.5)
    ax1.axvline(wgc / (2 * math.pi), color="g", ls=":", label=f"crossover {wgc / (2 * math.pi):.2f} Hz, PM {pm:.1f} deg")
    if np.isfinite(gm):
        ax1.axvline(wpc / (2 * math.pi), color="r", ls=":", label=f"GM {20 * math.log10(gm):.1f} dB")
    ax2.set_title(f"phase margin {pm:.1f} deg", fontsize=9)
    ax1.set_ylabel("magnitude, dB")
    ax2.set_ylabel("phase, deg")
    ax2.set_xlabel("frequency, Hz")
    ax1.legend(fontsize=7)
    ax1.set_ylim(-80, 60)
    ax2.set_ylim(-450, 0)
    if title:
        ax1.set_title(title, fontsize=9)
    fig.tight_layout()
    if note:
        fig.text(0.005, 0.003, note, fontsize=6, color="0.4")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": "ehas", "Description": note or title})
    plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())


# -- 2. optimiser ------------------------------------------------------------------
#: scale of each gain when its start value is zero (typical magnitudes on this rig)
GAIN_SCALES = {"Kp": 1.0, "Ki": 2.0, "Kv": 0.0178, "Ka": 2.4e-4, "Kj": 2.0e-6, "Kdp": 0.01, "dp_hp": 10.0}
SCALE_VECTOR = np.array([GAIN_SCALES[k] for k in GAIN_NAMES])
#: added to a condition's rms % error when the piston touches a stroke end
STROKE_PENALTY = 100.0


def objective_values(metrics: np.ndarray) -> np.ndarray:
    """Per-condition cost: rms % error, plus :data:`STROKE_PENALTY` if a stroke end was hit."""
    return metrics[:, 0] + STROKE_PENALTY * (metrics[:, 5] > 0.5)


def tune_optimize(start: PIFF | None = None, conditions=None, *, objective: str = "mean", params=None,
                  max_evals: int = 300, cycles: float = 5.0, plant_kwargs: dict | None = None,
                  progress: bool = True) -> TuneResult:
    """Minimise the simulated rms % error over ``conditions`` by Nelder-Mead.

    Parameters
    ----------
    start : PIFF
        Starting gains (default: the model-based design for the conditions' first disc set).
    conditions : list of Condition
        Where to evaluate (default: the 9 frequency x amplitude conditions of 3 sets).
    objective : {"mean", "worst"}
        Mean or maximum over the conditions of the rms % error (+ a stroke-end penalty).
    params : sequence of str
        Gains to vary (default: Kp, Ki, Kv, Ka, Kj, and Kdp, dp_hp where the start uses them).
        The simplex steps by a quarter of each gain's start value (or of a typical
        magnitude, :data:`GAIN_SCALES`, for gains starting at zero).
    max_evals : int
        Objective evaluations (each one batched run of all conditions).

    The best point seen is returned, so the result is never worse than ``start``.
    """
    from scipy.optimize import minimize
    from tqdm import tqdm

    if objective not in ("mean", "worst"):
        raise ValueError(f"objective must be 'mean' or 'worst', got {objective!r}")
    conditions = list(conditions) if conditions is not None else grid(disc_sets=[3])
    if start is None:
        start = tune_model_based(conditions[0].disc_sets).controller
    if params is None:
        params = ["Kp", "Ki", "Kv", "Ka", "Kj"] + (["Kdp"] if start.Kdp else []) + (["dp_hp"] if start.dp_hp else [])
    bad = [p for p in params if p not in GAIN_NAMES]
    if bad:
        raise ValueError(f"unknown gain(s) to optimise: {', '.join(bad)}; choose from {', '.join(GAIN_NAMES)}")
    batch = Batch(conditions, cycles=cycles, plant_kwargs=plant_kwargs)
    base = np.array([getattr(start, k) for k in GAIN_NAMES], dtype=float)
    idx = [GAIN_NAMES.index(p) for p in params]
    scale = np.array([abs(base[i]) if base[i] != 0 else GAIN_SCALES[GAIN_NAMES[i]] for i in idx])
    agg = np.mean if objective == "mean" else np.max
    best = {"J": math.inf, "g": base.copy(), "n": 0}
    bar = tqdm(total=max_evals, desc=f"optimise ({len(conditions)} conditions)", disable=not progress, leave=False)

    def gains_of(x):
        # x = 1 is the start; a step of 1 in x moves a gain by its scale (its start value, or a typical
        # magnitude for gains starting at zero)
        g = base.copy()
        g[idx] = base[idx] + (x - 1.0) * scale
        return g

    def cost(x):
        g = gains_of(x)
        neg = np.minimum(g, 0.0)
        g = np.maximum(g, 0.0)  # negative gains are not a controller the rig would run
        m = batch.run(g, i_max=start.i_max, dac_lsb=start.dac_lsb)
        J = float(agg(objective_values(m))) + 1e3 * float(np.sum((neg / SCALE_VECTOR) ** 2))
        best["n"] += 1
        bar.update(1)
        if J < best["J"]:
            best["J"], best["g"], best["x"] = J, g, np.array(x, dtype=float)
            bar.set_postfix(J=f"{J:.4g}")
        return J

    x0 = np.ones(len(idx))
    j_start = cost(x0)
    best["x"] = x0
    step = 0.25
    while best["n"] < max_evals:
        # Nelder-Mead, restarted from the best point with a fresh (smaller) simplex while the budget
        # lasts: a collapsed simplex on this bumpy objective often stalls short of the minimum
        j_before = best["J"]
        xb = best["x"]
        simplex = np.vstack([xb] + [xb + step * np.eye(len(idx))[k] for k in range(len(idx))])
        minimize(cost, xb, method="Nelder-Mead",
                 options={"maxfev": max_evals - best["n"], "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-4})
        if best["J"] > j_before - 1e-4 * max(abs(j_before), 1e-9) and step <= 0.05:
            break
        step = max(step / 2, 0.05)
    bar.close()
    g = best["g"]
    ctrl = PIFF(**dict(zip(GAIN_NAMES, g)), i_max=start.i_max, output_bits=start.output_bits, rate_hz=start.rate_hz,
                name="optimised")
    report = {"objective": objective, "objective_start": j_start, "objective_best": best["J"], "evaluations": best["n"],
              "conditions": len(conditions), "params": list(params), "start": start.gains()}
    lines = [f"optimiser ({objective} rms % error over {len(conditions)} conditions, {best['n']} evaluations): "
             f"{j_start:.4g} % at the start -> {best['J']:.4g} %"]
    return TuneResult(ctrl, report, lines)


def optimize_task(task) -> TuneResult:
    """One optimisation, run by an executor: ``task = (start, conditions, tune_optimize kwargs)``.

    Module-level and self-contained (the start gains fix the run: Nelder-Mead and
    the simulations are deterministic) so it gives the same result in any process.
    """
    start, conditions, kwargs = task
    return tune_optimize(start, conditions, **{**kwargs, "progress": False})


#: spread of the multi-start perturbation: each varied gain is multiplied by exp(N(0, sigma)) (assumed: about
#: +-30 %, wide enough to reach another basin of the bumpy objective, narrow enough to stay stable)
START_SPREAD = 0.3


def perturbed_starts(start: PIFF, starts: int, seed: int = 0) -> list[PIFF]:
    """``start`` and ``starts - 1`` seeded perturbations of its non-zero gains.

    Examples
    --------
    >>> s = perturbed_starts(PIFF.book(), 3, seed=1)
    >>> len(s), s[0] == PIFF.book(), s[1] == perturbed_starts(PIFF.book(), 2, seed=1)[1]
    (3, True, True)
    """
    import dataclasses

    if starts < 1:
        raise ValueError(f"starts must be >= 1, got {starts!r}")
    rng = np.random.default_rng(seed)
    out = [start]
    for _ in range(starts - 1):
        factors = np.exp(rng.normal(0.0, START_SPREAD, size=len(GAIN_NAMES)))
        out.append(dataclasses.replace(start, **{k: getattr(start, k) * f for k, f in zip(GAIN_NAMES, factors)
                                                 if k != "dp_hp" and getattr(start, k)}))
    return out


def tune_optimize_multistart(start: PIFF, conditions, *, starts: int = 1, seed: int = 0, executor=None,
                             **kwargs) -> TuneResult:
    """:func:`tune_optimize` from ``start`` and ``starts - 1`` perturbed starts; the best result wins.

    The optimisations are independent tasks for ``executor`` (:mod:`ehas_env.simulation.executors`;
    default: one after the other in this process), so a cluster runs them side by side
    with the same outcome.  Ties go to the earlier start.
    """
    from ehas_env.simulation.executors import LocalExecutor

    executor = executor or LocalExecutor(workers=1, progress=False)
    conditions = list(conditions) if conditions is not None else grid(disc_sets=[3])
    cands = perturbed_starts(start, starts, seed)
    results = executor.map(optimize_task, [(c, conditions, kwargs) for c in cands], desc="optimiser starts")
    if len(results) == 1:
        return results[0]
    js = [r.report["objective_best"] for r in results]
    k = int(np.argmin(js))
    best = results[k]
    best.report = {**best.report, "starts": starts, "start_seed": seed, "best_start": k,
                   "objective_best_per_start": js}
    best.lines = best.lines + [f"best of {starts} starts (seed {seed}): start {k}; per start " +
                               ", ".join(f"{j:.4g}" for j in js)]
    return best


# -- 3. relay --------------------------------------------------------------------
def relay_experiment(plant=None, *, disc_sets: int = 3, relay_mA: float = 1.0, hysteresis_deg: float = 0.0,
                     duration_s: float = 4.0) -> dict:
    """Astrom-Hagglund relay test on the nonlinear plant (simulated as on the rig).

    The controller output toggles between +-``relay_mA`` as the position error
    crosses +-``hysteresis_deg`` (set point 0 deg); the loop settles into a limit
    cycle whose fundamental amplitude ``a`` (deg) and period ``Tu`` give the ultimate
    gain ``Ku = 4 d / (pi a)`` (describing function; ``sqrt(a^2 - eps^2)`` with
    hysteresis).  The first third of the run is discarded as the transient.
    """
    from ehas_env.physics import layout as K
    from ehas_env.simulation.plant import TAU_MAX, Plant

    from ehas_env.ranges import check_field

    relay_mA = check_field("relay_mA", relay_mA, "relay_mA (the relay amplitude)")
    if not (math.isfinite(hysteresis_deg) and hysteresis_deg >= 0):
        raise ValueError(f"hysteresis must be >= 0 deg, got {hysteresis_deg!r}")
    plant = plant or Plant(disc_sets=disc_sets)
    n = int(round(duration_s / plant.dt))
    theta, u = np.zeros(n), np.zeros(n)
    plant.model.run_relay(plant.initial_state(), plant.param_vector, relay_mA, hysteresis_deg, 0.0, plant.dt, plant.substeps,
              np.zeros(K.history_length(TAU_MAX, plant.dt)), theta, u)
    rises = np.flatnonzero(np.diff(u) > 0) + 1
    rises = rises[len(rises) // 3:]
    if rises.size < 4:
        raise ValueError(f"relay experiment: no sustained oscillation in {duration_s:g} s with relay_mA = "
                         f"{relay_mA:g} mA (--relay-mA) and hysteresis {hysteresis_deg:g} deg; raise the relay "
                         "amplitude or lengthen the run")
    tu = (rises[-1] - rises[0]) / (rises.size - 1) * plant.dt
    seg = slice(rises[0], rises[-1])
    t = np.arange(n)[seg] * plant.dt
    a1 = 2.0 * abs(np.mean(theta[seg] * np.exp(-2j * math.pi * t / tu)))
    a_eff = math.sqrt(max(a1**2 - hysteresis_deg**2, 1e-300))
    ku = 4.0 * relay_mA / (math.pi * a_eff)
    return {"Ku": ku, "Tu": tu, "wu": 2 * math.pi / tu, "amplitude_deg": a1,
            "peak_to_peak_deg": float(theta[seg].max() - theta[seg].min()), "relay_mA": relay_mA,
            "hysteresis_deg": hysteresis_deg, "disc_sets": plant.rig.disc_sets, "theta_deg": theta, "current_mA": u,
            "dt": plant.dt}


def tune_relay(disc_sets: int = 3, *, rule: str = "tl", relay_mA: float = 1.0, hysteresis_deg: float = 0.0,
               amplitude_deg: float = 20.0, freq_hz: float = 2.0, ff_band_hz: tuple[float, float] = (0.5, 4.0),
               plant=None) -> TuneResult:
    """PI from a relay experiment (``rule``: "zn" Ziegler-Nichols or "tl" Tyreus-Luyben).

    The feed-forward gains (Kv, Ka, Kj) come from the plant model's inverse at the
    mean valve flow of the ``amplitude_deg`` / ``freq_hz`` sine, as in
    :func:`tune_model_based` without pressure feedback: a relay test measures only
    the loop's critical point.
    """
    if rule not in PI_RULES:
        raise ValueError(f"rule must be one of {', '.join(PI_RULES)}, got {rule!r}")
    if plant is None:
        from ehas_env.simulation.plant import Plant

        plant = Plant(disc_sets=disc_sets)
    rel = relay_experiment(plant, relay_mA=relay_mA, hysteresis_deg=hysteresis_deg)
    kr, tr = PI_RULES[rule]
    kp = kr * rel["Ku"]
    ki = kp / (tr * rel["Tu"])
    lp = LinearPlant(plant, flow_lpm=operating_flow_lpm(amplitude_deg, freq_hz, plant.rig))
    kv, ka, kj = feedforward_from_model(lp, 0.0, 0.0, ff_band_hz)
    n = plant.rig.disc_sets
    ctrl = PIFF(Kp=kp, Ki=ki, Kv=kv, Ka=ka, Kj=kj, name=f"relay {rule} {n} sets")
    report = {k: v for k, v in rel.items() if k not in ("theta_deg", "current_mA", "dt")}
    report["rule"] = rule
    lines = [f"relay experiment, {n} disc sets: relay +-{relay_mA:g} mA -> limit cycle {rel['amplitude_deg']:.3f} deg "
             f"(fundamental), period Tu = {rel['Tu'] * 1e3:.1f} ms",
             f"  ultimate gain Ku = {rel['Ku']:.3f} mA/deg; {rule.upper()} rule: Kp = {kr:.3g} Ku, Ti = {tr:.3g} Tu"]
    return TuneResult(ctrl, report, lines)


# -- 4. gain schedule ----------------------------------------------------------------
METHODS = ("model", "optimize", "relay")


def tune_schedule(method: str = "optimize", disc_sets=range(1, 8), *, freqs=(1.0, 2.0, 3.0),
                  amplitudes=(10.0, 20.0, 30.0), plants: dict | None = None, plant_kwargs: dict | None = None,
                  start_kwargs: dict | None = None, progress: bool = True, executor=None, **kwargs) -> TuneResult:
    """Tune with ``method`` at each disc set and schedule the gains on the inertia.

    ``plants`` (disc sets -> Plant) replaces the baseline rig for "model" and "relay";
    ``plant_kwargs`` are the optimiser's Plant arguments.  For "optimize" each disc
    set's optimiser starts from that set's model-based design (``start_kwargs`` go
    to :func:`tune_model_based`) and minimises over that set's ``freqs`` x
    ``amplitudes``; the sets are independent tasks for ``executor``
    (:mod:`ehas_env.simulation.executors`, default: in this process).  Other ``kwargs`` go to the tuner.
    """
    from ehas_env.simulation.plant import Plant

    if method not in METHODS:
        raise ValueError(f"schedule method must be one of {', '.join(METHODS)}, got {method!r}")
    disc_sets = list(disc_sets)
    entries, reports, lines = {}, {}, [f"gain schedule ({method}) over disc sets {disc_sets}"]
    optimised = {}
    if method == "optimize":
        # the disc sets' optimisations are independent: one executor task each (same results anywhere)
        from ehas_env.simulation.executors import LocalExecutor

        ex = executor or LocalExecutor(workers=1, progress=progress)
        tasks = []
        for n in disc_sets:
            plant = (plants or {}).get(n) or Plant(disc_sets=n, **(plant_kwargs or {}))
            start = tune_model_based(plant=plant, **(start_kwargs or {})).controller
            tasks.append((start, grid(disc_sets=[n], freqs=freqs, amplitudes=amplitudes),
                          {"plant_kwargs": plant_kwargs, **kwargs}))
        optimised = dict(zip(disc_sets, ex.map(optimize_task, tasks, desc="schedule (disc sets)")))
    for n in disc_sets:
        if method == "model":
            plant = (plants or {}).get(n) or Plant(disc_sets=n, **(plant_kwargs or {}))
            res = tune_model_based(plant=plant, **kwargs)
        elif method == "relay":
            plant = (plants or {}).get(n) or Plant(disc_sets=n, **(plant_kwargs or {}))
            res = tune_relay(plant=plant, **kwargs)
        else:
            res = optimised[n]
        entries[n] = res.controller
        reports[n] = res.report
        lines += [f"  {n} sets: " + res.lines[0]] + ["  " + ln for ln in res.lines[1:]]
    sched = GainSchedule(entries, name=f"schedule-{method}", basis=f"{method} per disc set")
    return TuneResult(sched, {"method": method, "per_disc_set": reports}, lines)


def describe_gains(ctrl) -> list[str]:
    """Lines 'Kp = 1.234 mA/deg' for a PIFF (or each entry of a schedule)."""
    if isinstance(ctrl, GainSchedule):
        out = []
        for n, c in ctrl.entries.items():
            out.append(f"{n} disc sets: " + ", ".join(f"{k} {getattr(c, k):.4g} {GAIN_UNITS[k]}" for k in GAIN_NAMES))
        return out
    return [f"{k:>5} = {getattr(ctrl, k):.6g} {GAIN_UNITS[k]}" for k in GAIN_NAMES]
