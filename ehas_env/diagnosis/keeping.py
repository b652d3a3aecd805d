"""Only real effects are kept: a fitted effect must say the same on separate groups of runs.

An effect that stands in for something the model lacks fits whatever number
lowers the residual of the runs it is given; a real one fits the same number
on any of them.  So before an effect is kept, its parameters are refitted on
two separate groups of the fitted runs (:func:`run_groups`), each with its
cluster-robust 95 % interval, and the effect is kept only when every
parameter's two estimates agree within their intervals (:func:`agree`).

Examples
--------
>>> agree({"b": [(4000.0, (3800.0, 4200.0)), (4100.0, (3900.0, 4300.0))]})[0]
True
>>> ok, why = agree({"Fc": [(100.0, (90.0, 110.0)), (300.0, (280.0, 320.0))]})
>>> ok, why.split(":")[0]
(False, 'Fc')
>>> agree({"r_s": [(4.0, (1.25, 4.0), True), (1.34, (1.05, 1.64))]})[0]   # one ran to its range's end
True
>>> gain = {"gain": [(-0.004, (-0.019, 0.012)), (-0.082, (-0.154, -0.010))]}  # %, typical +-3 %
>>> agree(gain)[0], agree(gain, {"gain": 0.3})[0]
(False, True)
"""
from __future__ import annotations

import math

#: two estimates agree when their difference is within this many combined 95 % half-widths
AGREE_WITHIN = 1.0
#: least half-width of an interval, relative to the estimate: the cluster-robust interval of a few seconds of
#: data holds the noise, not the model's own small structural errors elsewhere (a real single-rod area ratio,
#: fitted on two groups of runs of a simulator, came out 0.2955 and 0.2999 with intervals of +-0.0001); a
#: stand-in's estimates part by far more (a factor, not per cent)
MODEL_ERROR_FLOOR = 0.1


def least_half_width(param) -> float:
    """The least half-width of a parameter's estimate that is not relative to the estimate itself: for a parameter
    whose typical values straddle zero (an offset, a gain error, a bend), :data:`MODEL_ERROR_FLOOR` of the largest
    typical magnitude; 0 for the others.

    A floor relative to the estimate vanishes where the estimate does: a real LVDT's bend of 3 % fitted with a
    gain error that is truly 0 gave -0.004 % [-0.019, 0.012] and -0.082 % [-0.154, -0.010] on two groups of runs,
    apart by 0.08 % of the scale in a parameter whose typical values span +-3 %, and the true hypothesis was called
    a stand-in.  Near zero a parameter's model error is a share of its own scale, not of its estimate.

    Parameters
    ----------
    param : Param
        The effect's parameter (its ``typical`` range, or its ``bounds`` when it has none).

    Returns
    -------
    float
        In the parameter's unit.

    Examples
    --------
    >>> from ehas_env.physics.effects import get_effect
    >>> least_half_width(get_effect("hyp_position_shape").param("gain"))
    0.30000000000000004
    >>> least_half_width(get_effect("coulomb_friction").param("Fc"))
    0.0
    """
    lo, hi = param.typical or param.bounds
    return MODEL_ERROR_FLOOR * max(abs(lo), abs(hi)) if lo < 0.0 < hi else 0.0


def agree(estimates: dict[str, list[tuple]], least: dict[str, float] | None = None) -> tuple[bool, str]:
    """Whether each parameter's estimates from separate groups of runs agree within their 95 % intervals.

    Two estimates a, b with half-widths ha, hb agree when |a - b| <= AGREE_WITHIN * sqrt(ha^2 + hb^2)
    (the 95 % interval of the difference of independent estimates); a half-width is at least
    :data:`MODEL_ERROR_FLOOR` of its estimate, and at least ``least[name]`` (:func:`least_half_width`: a parameter
    whose typical values straddle zero).  An estimate that ran to the end of its fitted range
    (flagged by a third element True) is no point estimate: its interval is cut at that end and one-sided,
    so it agrees with another estimate when their intervals (each at least the floor and ``least`` wide on either
    side of its estimate) overlap.

    Parameters
    ----------
    estimates : dict
        {parameter: [(value, (low, high)) or (value, (low, high), at_range_end), ...]}, one entry per group
        of runs.
    least : dict, optional
        {parameter: least half-width in its unit}.

    Returns
    -------
    (bool, str)
        True and "" when every pair agrees; otherwise False and the first disagreement in words.
    """
    for name, ests in estimates.items():
        h0 = (least or {}).get(name, 0.0)
        for i in range(len(ests)):
            for j in range(i + 1, len(ests)):
                (a, (alo, ahi)), (b, (blo, bhi)) = ests[i][:2], ests[j][:2]
                pinned = any(len(e) > 2 and e[2] for e in (ests[i], ests[j]))
                ha = max(0.5 * (ahi - alo), MODEL_ERROR_FLOOR * abs(a), h0)
                hb = max(0.5 * (bhi - blo), MODEL_ERROR_FLOOR * abs(b), h0)
                if not all(map(math.isfinite, (a, b, ha, hb, alo, ahi, blo, bhi))):
                    return False, f"{name}: an estimate or its interval is not finite"
                if pinned:
                    fa, fb = max(MODEL_ERROR_FLOOR * abs(a), h0), max(MODEL_ERROR_FLOOR * abs(b), h0)
                    if max(min(alo, a - fa), min(blo, b - fb)) <= min(max(ahi, a + fa), max(bhi, b + fb)):
                        continue
                    return False, (f"{name}: {a:.4g} [{alo:.4g}, {ahi:.4g}] on one group of runs and {b:.4g} "
                                   f"[{blo:.4g}, {bhi:.4g}] on another (one at the end of its range) do not "
                                   "overlap")
                if abs(a - b) > AGREE_WITHIN * math.hypot(ha, hb):
                    return False, (f"{name}: {a:.4g} [{alo:.4g}, {ahi:.4g}] on one group of runs and {b:.4g} "
                                   f"[{blo:.4g}, {bhi:.4g}] on another do not agree within their 95 % intervals")
    return True, ""


def run_groups(names: list[str], kinds: list[str]) -> list[list[int]] | None:
    """Two groups of runs (indices) to refit an effect on: closed-loop runs alternate between them,
    the valve runs (and the windows cut from one run, ``NAME@...``) follow their run.  None when fewer than
    two closed-loop runs are fitted.

    Parameters
    ----------
    names : list of str
        Names of the fitted runs (windows of one run are named ``RUN@START``).
    kinds : list of str
        Their kinds (``closed_loop``, ``valve_open_loop``).

    Returns
    -------
    list of two lists of indices, or None

    Examples
    --------
    >>> run_groups(["a", "b", "c", "v@0.1s", "v@0.9s"], ["closed_loop"] * 3 + ["valve_open_loop"] * 2)
    [[0, 2, 3, 4], [1]]
    """
    cl = [i for i, k in enumerate(kinds) if k == "closed_loop"]
    if len(cl) < 2:
        return None
    groups: list[list[int]] = [[], []]
    base = {}
    for j, i in enumerate(cl):
        groups[j % 2].append(i)
    valve_runs = []
    for i, (n, k) in enumerate(zip(names, kinds)):
        if k != "closed_loop":
            root = n.split("@")[0]
            if root not in base:
                base[root] = len(valve_runs) % 2
                valve_runs.append(root)
            groups[base[root]].append(i)
    return [sorted(g) for g in groups]
