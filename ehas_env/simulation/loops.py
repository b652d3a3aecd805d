"""The compiled drivers around the plant: reference, sensing, control law dispatch, the one closed loop.

Compiled into every generated model (:mod:`ehas_env.physics.codegen`); the part
below ``# >>> compiled`` runs there (the part above it, from ``# >>> compiled, the
same for every model``, calls nothing of the assembled model: the quick build
compiles it once into its library module).  :func:`closed_loop` is the one closed-loop
driver (sense -> law -> DAC -> advance -> metrics) of ``Plant``, the benchmark
and the replay of logged runs; the environment's step uses the same
:func:`sense` and :func:`control_law`.

Sums written by :func:`closed_loop` (in the order of ``METRICS``): sum of e^2 and
max |e| of e = theta_ref - theta (the LVDT's angle, deg) over the window
[k0, k1) -- :func:`ehas_env.simulation.metrics.percent_errors` turns them into
the % error --, largest |command|, share of periods at the output limit,
largest |P_A - P_B| (bar), stroke end touched (1/0).
"""
import math

import numpy as np
from numba import njit

from ehas_env.physics.layout import *  # noqa: F401,F403  (for readers: the names below come from the model)

# >>> compiled, the same for every model
@njit(cache=True, inline="always")
def reference_point(ref, t):
    """theta_ref and its first three derivatives (deg, deg/s^k) at t.

    ref = (amplitude deg, f Hz, phase rad[, ramp s[, offset deg]]): the sine
    offset + amplitude sin(2 pi f t + phase) about a mean angle ``offset``.  With a
    ramp time T > 0 the whole command (mean angle and sine) fades in with the
    smoothstep 10x^3 - 15x^4 + 6x^5, x = t/T, so the command starts at rest at
    0: a rig operator never steps a heavy inertia to full sine velocity, or to
    the mean angle, at t = 0.
    """
    amp, w, ph = ref[0], 2.0 * math.pi * ref[1], ref[2]
    T = ref[3] if ref.shape[0] > 3 else 0.0
    off = ref[4] if ref.shape[0] > 4 else 0.0
    s, s1, s2, s3 = 1.0, 0.0, 0.0, 0.0
    if T > 0.0 and t < T:
        x = max(t, 0.0) / T
        s = x * x * x * (10.0 + x * (-15.0 + 6.0 * x))
        s1 = 30.0 * x * x * (1.0 - x) * (1.0 - x) / T
        s2 = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / (T * T)
        s3 = (60.0 - 360.0 * x + 360.0 * x * x) / (T * T * T)
    sn, cs = math.sin(w * t + ph), math.cos(w * t + ph)
    r = amp * s * sn + off * s
    rd = amp * (s1 * sn + s * w * cs) + off * s1
    rdd = amp * (s2 * sn + 2.0 * s1 * w * cs - s * w * w * sn) + off * s2
    rddd = amp * (s3 * sn + 3.0 * s2 * w * cs - 3.0 * s1 * w * w * sn - s * w * w * w * cs) + off * s3
    return r, rd, rdd, rddd


@njit(cache=True, inline="always")
def reference_series(ref, t):
    """:func:`reference_point` at every time of the array t, shape (4, len(t)): one call for a whole log."""
    out = np.empty((4, t.shape[0]))
    for k in range(t.shape[0]):
        r, rd, rdd, rddd = reference_point(ref, t[k])
        out[0, k] = r
        out[1, k] = rd
        out[2, k] = rdd
        out[3, k] = rddd
    return out


@njit(cache=True, inline="always")
def quantize(x, lsb):
    """x rounded to a multiple of lsb (no rounding for lsb <= 0): an ADC or DAC."""
    if lsb <= 0.0:
        return x
    return lsb * math.floor(x / lsb + 0.5)


@njit(cache=True, inline="always")
def sense(theta_rad, gain_err, noise, adc):
    """The controller's reading of the LVDT angle, deg: gain error, noise, ADC."""
    return quantize(math.degrees(theta_rad) * (1.0 + gain_err) + noise, adc)


# >>> compiled
METRICS = ("rms_error_pct", "peak_error_pct", "max_current_mA", "saturation_frac", "peak_delta_p_bar",
           "hit_stroke_end")
REF_SINE, REF_STEP = 0, 1


# nogil: replays of a campaign run side by side in Python threads (ehas_env.measurement.replay)
@njit(cache=True, nogil=True)
def closed_loop(s, P, law, gains, ref, kind, dt, nsub, hist, noise, sensor, k0, k1, metrics, out, supply=None):
    """One closed-loop run of ``len(noise)`` periods with the compiled law number ``law``.

    ref: (amplitude deg, f Hz, phase rad, ramp s[, offset deg]) for kind REF_SINE, or
    (step deg, -, step time s, -) for REF_STEP; sensor = (theta ADC lsb deg,
    DAC lsb mA, LVDT gain error, output limit mA).  Writes ``metrics`` (see
    METRICS; error window [k0, k1)) and, when ``out`` has rows, the outputs of
    every period (layout ``OUT_NAMES``).  ``supply`` (Pa, one per period; left out:
    the model's own) is a measured supply pressure: period k runs at supply[k] (the
    supply state set to it), the chambers held below its highest value, the supply's
    setting (ehas_env.diagnosis.measured_inputs; P itself is not changed).
    """
    if supply is not None:
        P = P.copy()
        P[I_SUPPLY] = np.max(supply)
    k1v, k2v, k3v, k4v, tmp = rk4_work(s)
    row = np.zeros(N_OUT)
    adc, dac, gain_err, u_max = sensor[0], sensor[1], sensor[2], sensor[3]
    mem = np.zeros(8)
    hist[:] = 0.0
    se2 = 0.0
    emax = 0.0
    umax_seen = 0.0
    nsat = 0
    dpmax = 0.0
    hit_any = False
    keep = out.shape[0] > 0
    n = noise.shape[0]
    for k in range(n):
        if supply is not None:
            s[6] = supply[k]
        measure(s, P, row)
        t = k * dt
        if kind == REF_SINE:
            r, rd, rdd, rddd = reference_point(ref, t)
        else:
            r = ref[0] if t >= ref[2] else 0.0
            rd, rdd, rddd = 0.0, 0.0, 0.0
        th = sense(row[O_THETA], gain_err, noise[k], adc)
        dp = (s[4] - s[5]) * 1e-5
        u = quantize(control_law(law, gains, mem, t, dt, th, r, rd, rdd, rddd, dp, s[6] * 1e-5, u_max), dac)
        # metrics: tracking on the true (LVDT) angle, as ehas_env.simulation.metrics does
        if k >= k0 and k < k1:
            et = r - math.degrees(row[O_THETA])
            se2 += et * et
            if abs(et) > emax:
                emax = abs(et)
        if abs(u) > umax_seen:
            umax_seen = abs(u)
        if abs(u) >= u_max * (1.0 - 1e-9):
            nsat += 1
        if abs(dp) > dpmax:
            dpmax = abs(dp)
        hist[k % hist.shape[0]] = u
        hit = advance(s, P, hist, k, dt, nsub, 0.0, k1v, k2v, k3v, k4v, tmp)
        if hit:
            hit_any = True
        if keep:
            for j in range(N_OUT):
                out[k, j] = row[j]
            out[k, O_SENSED] = th
            out[k, O_CURRENT] = u
            out[k, O_STROKE] = 1.0 if hit else 0.0
    metrics[0] = se2
    metrics[1] = emax
    metrics[2] = umax_seen
    metrics[3] = nsat / max(n, 1)
    metrics[4] = dpmax
    metrics[5] = 1.0 if hit_any else 0.0


@njit(cache=True)
def closed_loop_batch(S0, P, laws, G, R, kinds, dt, nsub, hist_len, noise, lengths, sensor, win, metrics, out):
    """closed_loop for each row c (serial): plant P[c] from S0[c], law laws[c] with gains G[c]."""
    hist = np.zeros(hist_len)
    for c in range(S0.shape[0]):
        s = S0[c].copy()
        o = out[c, :lengths[c]] if out.shape[1] > 0 else out[c]
        closed_loop(s, P[c], laws[c], G[c], R[c], kinds[c], dt, nsub, hist, noise[c, :lengths[c]], sensor[c],
                    win[c, 0], win[c, 1], metrics[c], o)


@njit(cache=True)
def required_load(P, s0, theta, omega, alpha, out):
    """A (P_A - P_B) (N) that moves the crank along (theta, omega, alpha): the right-hand side inverted.

    The crank's acceleration is affine in the load pressure, so two evaluations per
    point (load 0 and 1 bar) give it, whatever effects act on the piston or crank.
    """
    s = s0.copy()
    ds = np.zeros(s.shape[0])
    r, ps = P[I_RADIUS], s0[6]
    for k in range(theta.shape[0]):
        s[0], s[1] = theta[k], omega[k]
        s[7] = r * math.sin(theta[k]) - P[I_XOFF]
        s[8] = r * math.cos(theta[k]) * omega[k]
        s[4], s[5] = 0.5 * ps, 0.5 * ps
        derivatives(s, 0.0, P, ds)
        a0 = ds[1]
        s[4], s[5] = 0.5 * (ps + 1e5), 0.5 * (ps - 1e5)
        derivatives(s, 0.0, P, ds)
        out[k] = P[I_AREA] * 1e5 * (alpha[k] - a0) / (ds[1] - a0)


@njit(cache=True)
def run_relay(s, P, d, hyst, bias, dt, nsub, hist, theta_out, u_out):
    """Relay experiment (Astrom-Hagglund) on the plant: u = bias +- d switching on e = -theta.

    The set point is 0 deg; the relay starts at +d and switches when the error
    crosses +-hyst deg.  theta_out (deg) and u_out (mA) receive the run.
    """
    k1, k2, k3, k4, tmp = rk4_work(s)
    row = np.zeros(N_OUT)
    hist[:] = 0.0
    state = 1.0
    for k in range(theta_out.shape[0]):
        measure(s, P, row)
        th = math.degrees(row[O_THETA])
        e = -th
        if e > hyst:
            state = 1.0
        elif e < -hyst:
            state = -1.0
        u = bias + state * d
        theta_out[k] = th
        u_out[k] = u
        hist[k % hist.shape[0]] = u
        advance(s, P, hist, k, dt, nsub, 0.0, k1, k2, k3, k4, tmp)
