"""The one integrator: fixed-step RK4 over the model's right-hand side, the command delay, the stroke ends.

Compiled into every generated model (:mod:`ehas_env.physics.codegen`): the part
below the ``# >>> compiled`` line runs there (the one above it, from ``# >>> compiled,
the same for every model``, calls nothing of the assembled model and goes to the
quick build's library module), beside the model's ``derivatives``,
``valve_current``, ``coil_current``, ``project`` parts and ``measure``; this file is not imported
on its own.  ``advance`` is compiled without reference counting (it never
allocates, and the views it gets never outlive the call): with every model
function inlined into it, one control period is one straight compiled body.

The valve bench (``run_valve_test``) steps the same integrator with the valve's
rates only (ports joined through the flow meter, no load pressure).
"""
import math

import numpy as np
from numba import njit

from ehas_env.physics.layout import *  # noqa: F401,F403  (for readers: the names below come from the model)

# >>> compiled, the same for every model
@njit(cache=True, inline="always")
def rk4_work(s):
    """Scratch arrays of one RK4 step (k1, k2, k3, k4, tmp) for a state like s."""
    return np.empty_like(s), np.empty_like(s), np.empty_like(s), np.empty_like(s), np.empty_like(s)


@njit(cache=True, inline="always")
def delayed_command(hist, k, j, nsub, dt, tau, i_initial):
    """Command applied at sub-step j of period k with transport delay tau.

    ``hist[m % len(hist)]`` holds the command issued at step m (zero-order hold).
    """
    if tau <= 0.0:
        return hist[k % hist.shape[0]]
    t = (k + j / nsub) * dt - tau
    m = int(math.floor(t / dt + 1e-9))
    if m < 0:
        return i_initial
    return hist[m % hist.shape[0]]


# >>> compiled
@njit(cache=True, inline="always")
def crank_end(theta, P):
    """The stroke end the one-body crank's angle ``theta`` (rad) is at or past: ``(1.0, its angle)`` for the upper,
    ``(-1.0, its angle)`` for the lower, ``(0.0, 0.0)`` for neither (the piston r sin(theta) - piston_offset at
    +-half stroke).  One test for :func:`project` (which stops the crank there) and :func:`held_at_bounds` (which
    holds it there inside a step)."""
    r = P[I_RADIUS]
    x_off = P[I_XOFF]
    hi = min((P[I_HALF_STROKE] + x_off) / r, 1.0)
    lo = max((x_off - P[I_HALF_STROKE]) / r, -1.0)
    # asin(y) >= y for y >= 0 (<= y for y <= 0): only past y can the crank reach that end (saves the asin)
    if theta >= (hi if hi >= 0.0 else -2.0):
        th_end = math.asin(hi)
        if theta >= th_end:
            return 1.0, th_end
    elif theta <= (lo if lo <= 0.0 else 2.0):
        th_end = math.asin(lo)
        if theta <= th_end:
            return -1.0, th_end
    return 0.0, 0.0


@njit(cache=True, inline="always")
def project(s, P):
    """Hard limits after a step: spool end stops, pressure range, stroke ends.

    Returns True when the piston sits at a stroke end.
    """
    spool_stops(s, P)
    # the chambers are held below the supply's setting P[I_SUPPLY], not below the supply state s[6]: a supply that
    # falls (a pump's ripple, a droop) does not take oil out of a chamber above it -- the chamber discharges
    # through its land by the orifice law; with a constant supply the two are the same number
    ps_cap = P[I_SUPPLY]
    if s[6] > ps_cap:
        s[6] = ps_cap
    if s[6] < 0.0:
        s[6] = 0.0
    for j in (4, 5):
        if s[j] < 0.0:
            s[j] = 0.0
        elif s[j] > ps_cap:
            s[j] = ps_cap
    r = P[I_RADIUS]
    hit = False
    if two_body(P):
        if abs(s[7]) >= P[I_HALF_STROKE]:
            hit = True
            s[7] = math.copysign(P[I_HALF_STROKE], s[7])
            if s[8] * s[7] > 0.0:
                s[8] = 0.0
    else:
        side, th_end = crank_end(s[0], P)
        if side != 0.0:
            hit = True
            s[0] = th_end
            if s[1] * side > 0.0:
                s[1] = 0.0
        s[7] = r * math.sin(s[0]) - P[I_XOFF]
        s[8] = r * math.cos(s[0]) * s[1]
    return hit


@njit(cache=True, inline="always")
def held_at_bounds(s, P, ds):
    """What ``project`` holds after a step, held inside it too (in place): a chamber at its bound (0 or the
    supply's setting) has no rate outward, and a piston at a stroke end, not moving inward and pushed outward, neither
    moves nor accelerates (the stop's reaction).  Clipped only after each step, the stages of the step inside it
    run past the bound: a first-order error in the step (a start from rest that empties a chamber rang 0.18 deg
    rms off the converged run at 10 sub-steps of 0.1 ms; an impact at a stroke end left the pressures 17 bar
    off at its instant)."""
    for j in (4, 5):
        if (s[j] <= 0.0 and ds[j] < 0.0) or (s[j] >= P[I_SUPPLY] and ds[j] > 0.0):
            ds[j] = 0.0
    lim = P[I_HALF_STROKE]
    if two_body(P):
        if abs(s[7]) >= lim:
            out = 1.0 if s[7] > 0.0 else -1.0
            if s[8] * out >= 0.0 and ds[8] * out > 0.0:
                ds[7] = 0.0
                ds[8] = 0.0
        return
    side, th_end = crank_end(s[0], P)
    if side != 0.0 and s[1] * side >= 0.0 and ds[1] * side > 0.0:
        ds[0] = 0.0
        ds[1] = 0.0


@njit(cache=True, inline="always")
def measure(s, P, out):
    """Write the physical outputs of state s into out[0:8] (SI, noise-free; the angle as the LVDT reads it)."""
    r = P[I_RADIUS]
    th = math.asin(min(max(s[7] / r, -1.0), 1.0))
    out[O_THETA] = math.asin(min(max(position_reading(s[7], P, s) / r, -1.0), 1.0))
    out[O_OMEGA] = s[8] / (r * math.cos(th))
    # the meter in line A sits at the valve's port: the land's flow at the port's pressures; every sensed output
    # through its reading place (ehas_env.physics.layout.SENSED)
    out[O_FLOW] = flow_a_reading(metered_flow(s, P), P, s)
    out[O_PA] = pa_reading(s[4], P, s)
    out[O_PB] = pb_reading(s[5], P, s)
    out[O_PS] = ps_reading(s[6], P, s)
    out[O_FORCE] = force_reading(P[I_AREA] * (s[4] - s[5]), P, s)
    out[O_CRANK] = s[0]


@njit(cache=True, inline="always")
def rates(s, i_valve, P, ds, bench_supply):
    """The model's rates; with bench_supply >= 0 only the valve's, on the flow bench at that supply (Pa)."""
    if bench_supply < 0.0:
        derivatives(s, i_valve, P, ds)
        held_at_bounds(s, P, ds)
    else:
        for j in range(ds.shape[0]):
            ds[j] = 0.0
        valve_rates(s, coil_current(s, i_valve, P, ds), bench_supply, 0.0, P, ds)
        if bench_meter_on(P):  # the meter's own states follow the flow it meters
            q = bench_flow(s, s[2], bench_supply, math.sqrt(max(bench_supply, 0.0) / P[I_DROP]), P)
            bench_reading_rates(s, q, P, ds)


@njit(cache=True, inline="always")
def rk4_substep(s, i_valve, P, h, k1, k2, k3, k4, tmp, bench_supply, have_k1):
    """One classical RK4 step of length h (s updated in place); with ``have_k1`` true, k1 already holds the rates
    at s (the period's first, evaluated to decide its refinement) and is not evaluated again.

    The four stages share one call of :func:`rates`: numba inlines a function once per call site, and the model's
    right-hand side inlined four times over was most of the inlined build's compile.  Each stage's rates land in
    k4 and are kept in k1..k3; the stage states are the same sums as the textbook's, so the numbers are too.
    """
    # the states moved: the baseline's and those of the effects on (P's ``moved.*`` slots, mark_effects_on); the
    # others have rates 0 and would add 0 (a model of every hypothesis has 52 states, a replay moves 11-15 of them)
    listed = P[I_MOVED] > 0.0
    n = int(P[I_MOVED]) if listed else N_STATES
    for a in range(n):
        j = int(P[I_MOVED + 1 + a]) if listed else a
        tmp[j] = s[j]
    for st in range(4):
        if st == 0 and have_k1:
            for a in range(n):
                j = int(P[I_MOVED + 1 + a]) if listed else a
                k4[j] = k1[j]
        else:
            rates(tmp, i_valve, P, k4, bench_supply)
        if st < 3:
            c = h if st == 2 else 0.5 * h
            for a in range(n):
                j = int(P[I_MOVED + 1 + a]) if listed else a
                tmp[j] = s[j] + c * k4[j]
                if st == 0:
                    k1[j] = k4[j]
                elif st == 1:
                    k2[j] = k4[j]
                else:
                    k3[j] = k4[j]
    for a in range(n):
        j = int(P[I_MOVED + 1 + a]) if listed else a
        s[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


#: a sub-step in which a chamber pressure would reach its bound (0 or the supply) is cut into this many:
#: the pressure range's clip inside a step is where a fixed step loses most (a start from rest that empties a
#: chamber was 4-7 bar off with 10 sub-steps; the same run with the clipped steps refined is within the noise;
#: with the rates held at the bound too, :func:`held_at_bounds`, 0.0019 deg rms unrefined, 0.0001 refined)
REFINE = 8


@njit(cache=True, inline="always")
def near_bound(s, k1, h, P):
    """Whether a chamber pressure, moving at the rates k1 for two steps h, would pass its bound (0 or the
    supply's setting P[I_SUPPLY]): the sub-step that follows is refined."""
    for j in (4, 5):
        step = 2.0 * h * k1[j]
        if s[j] + step < 0.0 or s[j] + step > P[I_SUPPLY]:
            return True
    return False


#: ... and so is one with the piston within this share of the half stroke of an end: there a chamber's volume is
#: its dead volume alone and its pressure moves fastest (an impact from rest emptied chamber B from 147 bar to 0 in
#: 2 ms, 17 bar off at 10 sub-steps, 0.5 bar at 40 and at 160)
END_SHARE = 0.02


@njit(cache=True, inline="always")
def near_stroke_end(s, P):
    """Whether the piston is within :data:`END_SHARE` of the half stroke of an end (``s[7]``: its position, kept
    by ``project`` for the one-body crank too)."""
    return abs(s[7]) >= (1.0 - END_SHARE) * P[I_HALF_STROKE]


@njit(cache=True, _nrt=False)
def advance(s, P, hist, k, dt, nsub, i_initial, k1, k2, k3, k4, tmp):
    """Integrate one control period [k dt, (k+1) dt] with nsub RK4 sub-steps; a sub-step in which a chamber
    pressure would reach its bound (the rates of the sub-step before, the period's first from the state itself,
    decide) or that starts with the piston near a stroke end is taken as :data:`REFINE` steps.

    Returns True if a stroke end was touched during the period.
    """
    h = dt / nsub
    tau = P[I_TAU]
    hit = False
    for j in range(nsub):
        i_cmd = delayed_command(hist, k, j, nsub, dt, tau, i_initial)
        i_v = valve_current(i_cmd, P)
        if j == 0:
            rates(s, i_v, P, k1, -1.0)
        m = REFINE if near_bound(s, k1, h, P) or near_stroke_end(s, P) else 1
        for q in range(m):
            # the period's first rates are those of its first step: kept, not evaluated twice
            rk4_substep(s, i_v, P, h / m, k1, k2, k3, k4, tmp, -1.0, j == 0 and q == 0)
            if project(s, P):
                hit = True
    return hit


@njit(cache=True)
def run_open_loop(s, P, cmd, dt, nsub, hist, out):
    """Simulate from a command current sequence (mA, zero-order hold at dt).

    Row k of ``out`` holds the outputs at t_k and the command issued then.
    """
    k1, k2, k3, k4, tmp = rk4_work(s)
    hist[:] = 0.0
    for k in range(cmd.shape[0]):
        measure(s, P, out[k])
        out[k, O_CURRENT] = cmd[k]
        hist[k % hist.shape[0]] = cmd[k]
        hit = advance(s, P, hist, k, dt, nsub, 0.0, k1, k2, k3, k4, tmp)
        out[k, O_STROKE] = 1.0 if hit else 0.0


@njit(cache=True)
def bench_flow(s, qc, supply, scale, P):
    """The bench meter's flow with the control ports joined through it, m^3/s: q_c sqrt(supply / rated drop)
    for the critically lapped lands; with valve-side effects on, the flow at the ports' pressure where what
    enters through A leaves through B (bisection).  ``s``: the bench's state (a supply or return line's volume
    keeps its rest there: the bench has its own regulated supply and return, only the valve's states move)."""
    if P[I_EFFECTS_ON] == 0.0:
        return qc * scale
    ea, eb = valve_side_flows(s, qc, 0.5 * supply, 0.5 * supply, supply, P)
    if ea == 0.0 and eb == 0.0 and not lands_changed(P):  # nothing acts at the lands: their exact figure
        return qc * scale
    lo, hi = 0.0, supply
    qa = 0.0
    for _ in range(60):
        pm = 0.5 * (lo + hi)
        la, lb, _ = lands(s, qc, pm, pm, supply, P)
        ea, eb = valve_side_flows(s, qc, pm, pm, supply, P)
        qa = la + ea
        if qa + lb + eb > 0.0:  # more enters the ports than leaves: their pressure is higher
            lo = pm
        else:
            hi = pm
    return qa


# nogil: replays of a campaign run side by side in Python threads (ehas_env.measurement.replay)
@njit(cache=True, nogil=True)
def run_valve_test(P, cmd, dt, nsub, supply, hist, out, supply_log=None):
    """Valve alone, control ports joined through the flow meter (rated test).

    Two lands in series share the supply drop, so the metered flow is
    q_c * sqrt(supply / rated_drop), as the meter in line A reads it (its reading's effects, and their states,
    act on the bench too).  out[k] = (flow m^3/s, q_c m^3/s, valve current mA).
    ``supply_log`` (Pa, one per sample; left out: the constant ``supply``) is a measured
    supply pressure: sample k and the step after it run at supply_log[k].
    """
    s = np.zeros(N_STATES)
    k1, k2, k3, k4, tmp = rk4_work(s)
    h = dt / nsub
    tau = P[I_TAU]
    scale = math.sqrt(max(supply, 0.0) / P[I_DROP])
    hist[:] = 0.0
    for k in range(cmd.shape[0]):
        if supply_log is not None:
            supply = supply_log[k]
            scale = math.sqrt(max(supply, 0.0) / P[I_DROP])
        # the flow meter's reading of it (the ports are joined through the meter: its own blocks act here too)
        out[k, 0] = flow_a_reading(bench_flow(s, s[2], supply, scale, P), P, s)
        out[k, 1] = s[2]
        hist[k % hist.shape[0]] = cmd[k]
        for j in range(nsub):
            i_v = valve_current(delayed_command(hist, k, j, nsub, dt, tau, 0.0), P)
            if j == 0:
                out[k, 2] = i_v
            rk4_substep(s, i_v, P, h, k1, k2, k3, k4, tmp, supply, False)
            spool_stops(s, P)
