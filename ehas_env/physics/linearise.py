"""One linearisation: the compiled model's own right-hand side, differentiated numerically.

Every effect a plant carries -- built-in or a user's file -- is in the
linearisation, because it is the same ``derivatives`` the simulators run.
Non-smooth effects (``Effect.smooth = False``: dry friction's tanh sign, a
deadband, play in a joint) have no small-signal term at rest; they are switched
off here unless asked for (``keep_nonsmooth=True``, which differentiates the
smoothed sign function as it is, a very stiff term).

Examples
--------
>>> from ehas_env.simulation.plant import Plant
>>> from ehas_env.physics.linearise import linearise
>>> lin = linearise(Plant(disc_sets=3))
>>> lin.states
('theta', 'omega', 'qc', 'qc_dot', 'pa', 'pb')
>>> round(lin.hydraulic_wn_hz(), 1)    # the oil column against 3 disc sets
37.2
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ehas_env.physics.effects import REGISTRY


@dataclass
class Linearisation:
    """A, B, C, D of the plant at an operating point, with state names (SI; input mA; outputs deg, bar)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: tuple
    outputs: tuple = ("theta_deg", "p_load_bar")

    def state_space(self):
        """The python-control ``StateSpace`` (input: valve command mA; outputs: theta deg, load pressure bar)."""
        import control

        return control.ss(self.A, self.B, self.C, self.D, inputs=["current_mA"], outputs=list(self.outputs),
                          states=list(self.states))

    def tf(self, output: str = "theta_deg"):
        """Transfer function from the command (mA) to ``output``."""
        import control

        k = self.outputs.index(output)
        return control.ss2tf(self.A, self.B, self.C[k:k + 1], self.D[k:k + 1])

    def hydraulic_wn_hz(self) -> float:
        """Undamped frequency of the crank-oil mode: eigenvalues of the (theta, omega, pa, pb) block, Hz."""
        idx = [self.states.index(n) for n in ("theta", "omega", "pa", "pb")]
        ev = np.linalg.eigvals(self.A[np.ix_(idx, idx)])
        return float(np.max(np.abs(ev))) / (2.0 * math.pi)


def operating_state(plant, theta_deg: float = 0.0, load_bar: float = 0.0, flow_lpm: float = 0.0) -> np.ndarray:
    """At rest at ``theta_deg`` with P_A - P_B = ``load_bar`` around Ps/2, valve no-load flow ``flow_lpm``.

    With equal piston areas that is the operating point.  When the chambers' areas differ (a
    single-rod actuator, ``hyp_rod_area``, a user effect), Ps/2 in both chambers pushes the piston:
    the pressures are trimmed instead to the piston force ``A load_bar`` and to the share of the
    valve flow the two areas take (:func:`_trim_pressures`).
    """
    s = plant.initial_state(theta_deg)
    ps = plant.rig.supply
    s[4], s[5] = 0.5 * (ps + load_bar * 1e5), 0.5 * (ps - load_bar * 1e5)
    s[2] = flow_lpm * 1e-3 / 60.0
    _trim_pressures(plant, s, load_bar * 1e5)
    return s


def _trim_pressures(plant, s: np.ndarray, load: float) -> None:
    """Set (pa, pb) of ``s`` for a plant whose B-side piston area is ``r`` times the A side's (r != 1).

    ``r`` is read from the model's own right-hand side (how the piston's acceleration changes with
    each chamber pressure).  The pressures then satisfy ``pa - r pb = load`` (Pa: the piston force
    over the A-side area) and keep both chambers steady with the piston moving at the speed of the
    valve's flow into A: at a no-load flow of zero, in the limit of a small flow (the pressures a
    critically lapped valve settles at; for equal areas both give Ps/2 +- load/2).
    """
    m = plant.model
    P = plant.param_vector
    names = list(m.STATE_NAMES)
    i_cur = m.valve_current(0.0, P)
    ds = np.zeros(m.N_STATES)

    def rates(x):
        m.derivatives(x, i_cur, P, ds)
        return ds.copy()

    ia, ib = names.index("pa"), names.index("pb")
    push = names.index("vp") if "vp" in names and _two_body(m, plant) else names.index("omega")
    h = 1e-3 * plant.rig.supply
    sp, sm = s.copy(), s.copy()
    sp[ia] += h
    sm[ib] += h
    base = rates(s)[push]
    da, db = rates(sp)[push] - base, rates(sm)[push] - base
    if da == 0.0 or not math.isfinite(da / db) or abs(-db / da - 1.0) < 1e-9:
        return  # equal areas (or no piston force): Ps/2 +- load/2 is the operating point
    r = -db / da
    rig = plant.rig
    x = s.copy()
    if x[2] == 0.0:
        x[2] = 1e-6  # m^3/s (0.06 LPM): a small flow, for the pressures' limit only
    lever = rig.radius * math.cos(x[0])

    def steady(pb):
        # the chambers' rates with pa = load + r pb and the piston at the speed of the flow into A
        x[ia], x[ib] = load + r * pb, pb
        q_a = m.lands(x, x[2], x[ia], x[ib], x[names.index("ps")], P)[0]
        x[names.index("omega")] = q_a / (rig.area * lever)
        if push != names.index("omega"):
            x[push] = lever * x[names.index("omega")]
        return rates(x)[ib]

    lo, hi = max(0.0, -load / r) + 1e-9 * rig.supply, min(rig.supply, (rig.supply - load) / r) - 1e-9 * rig.supply
    f_lo, f_hi = steady(lo), steady(hi)
    if not (lo < hi and f_lo * f_hi < 0.0):
        raise ValueError(f"no operating point with P_A - {r:.3g} P_B = {load / 1e5:g} bar within the supply "
                         f"({rig.supply / 1e5:g} bar): the piston areas' ratio and the load do not fit this rig")
    for _ in range(100):  # bisection: the B chamber's rate is monotonic in its pressure
        mid = 0.5 * (lo + hi)
        f_mid = steady(mid)
        if (f_mid < 0.0) == (f_lo < 0.0):
            lo, f_lo = mid, f_mid
        else:
            hi = mid
        if hi - lo < 1e-9 * rig.supply:
            break
    pb = 0.5 * (lo + hi)
    s[ia], s[ib] = load + r * pb, pb


def jacobian(plant, s0: np.ndarray, current_mA: float = 0.0, *, keep_nonsmooth: bool = False,
             rel_step: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """(df/ds, df/di) of the model's right-hand side at (s0, current), central differences, SI per mA."""
    m = plant.model
    P = plant.param_vector
    if not keep_nonsmooth:
        for name in m.EFFECTS:
            if not getattr(REGISTRY[name], "smooth", True):
                P[m.IDX[f"{name}.on"]] = 0.0
    n = m.N_STATES
    ds_p, ds_m = np.zeros(n), np.zeros(n)
    scale = np.abs(s0) + np.array([_state_scale(name) for name in m.STATE_NAMES])
    A = np.zeros((n, n))
    for j in range(n):
        h = rel_step * scale[j]
        sp, sm = s0.copy(), s0.copy()
        sp[j] += h
        sm[j] -= h
        m.derivatives(sp, m.valve_current(current_mA, P), P, ds_p)
        m.derivatives(sm, m.valve_current(current_mA, P), P, ds_m)
        A[:, j] = (ds_p - ds_m) / (2 * h)
    h = rel_step * 20.0
    m.derivatives(s0.copy(), m.valve_current(current_mA + h, P), P, ds_p)
    m.derivatives(s0.copy(), m.valve_current(current_mA - h, P), P, ds_m)
    return A, (ds_p - ds_m) / (2 * h)


def _state_scale(name: str) -> float:
    """A typical size of each state, for the difference step."""
    return {"theta": 0.1, "omega": 1.0, "qc": 1e-4, "qc_dot": 1e-2, "pa": 1e6, "pb": 1e6, "ps": 1e6, "xp": 1e-3,
            "vp": 1e-2, "theta_a": 1e-3, "omega_a": 1.0}.get(name, 1.0)


def linearise(plant, *, theta_deg: float = 0.0, load_bar: float = 0.0, current_mA: float = 0.0,
              flow_lpm: float = 0.0, keep_nonsmooth: bool = False) -> Linearisation:
    """Linearisation of ``plant`` (any effects) at rest at ``theta_deg`` with ``load_bar`` across the piston.

    States that do not move at this point (the supply without a supply effect, the
    piston states of a rigid rod, the valve states of the other valve model) are dropped.

    Parameters
    ----------
    plant : ehas_env.simulation.plant.Plant
        The plant, with its effects.
    theta_deg, load_bar, current_mA, flow_lpm : float
        Operating point: crank angle (deg), P_A - P_B (bar), valve command (mA), valve
        no-load flow (LPM; its orifice slopes give the flow-pressure coefficient K_c).
    keep_nonsmooth : bool
        Differentiate non-smooth effects as they are (default: switched off).

    Returns
    -------
    Linearisation
        A, B, C, D with state names; ``.state_space()`` gives python-control's object.
    """
    m = plant.model
    s0 = operating_state(plant, theta_deg, load_bar, flow_lpm)
    if flow_lpm:
        # a valve passing flow is an operating point only with the piston moving at the speed that flow
        # gives (chamber pressures steady): otherwise d(P')/d(x) would carry the filling of a locked chamber
        q_a = m.lands(s0, s0[2], s0[4], s0[5], s0[6], plant.param_vector)[0]
        s0[1] = q_a / (plant.rig.area * plant.rig.radius * math.cos(s0[0]))
        s0[8] = plant.rig.radius * math.cos(s0[0]) * s0[1]
    A, b = jacobian(plant, s0, current_mA, keep_nonsmooth=keep_nonsmooth)
    # a state whose rate is identically zero at this point is a constant here (the supply without a supply
    # effect, the other valve model's states): it is dropped, its value held
    keep = [j for j in range(m.N_STATES) if np.any(A[j, :] != 0.0) or m.STATE_NAMES[j] in ("theta", "omega")]
    keep = [j for j in keep if m.STATE_NAMES[j] not in ("xp", "vp") or _two_body(m, plant)]
    A = A[np.ix_(keep, keep)]
    B = b[keep].reshape(-1, 1)
    names = tuple(m.STATE_NAMES[j] for j in keep)
    C = np.zeros((2, len(keep)))
    C[0, names.index("theta")] = math.degrees(1.0)
    C[1, names.index("pa")] = 1e-5
    C[1, names.index("pb")] = -1e-5
    return Linearisation(A, B, C, np.zeros((2, 1)), names)


def _two_body(m, plant) -> bool:
    return bool(m.two_body(plant.param_vector))
