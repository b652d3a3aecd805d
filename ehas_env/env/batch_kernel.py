"""Compiled stepping of the tracking environment, one env or a batch in one loop.

Compiled into every generated model (:mod:`ehas_env.physics.codegen`): the part
below ``# >>> compiled`` runs there, beside the model's ``advance``, ``measure``,
``sense`` and ``control_law``; call the entry points of a model
(``plant.model.batch_step``), not of this module.  Importing this module alone
gives the layouts (``C_*``, ``X_*``, ``R_*``).  This module adds what an environment step needs around it -- the reference and
its derivatives, the optional compiled rig controller (residual mode), sensor
noise, observation, reward, termination and the episode's % error -- and steps
one environment (:func:`single_step`) or N of them (:func:`batch_step`) with
the very same code, so a batch reproduces N single environments exactly.

Each environment is two flat float64 rows:

* ``C`` (constants, length ``C_P + N_SLOTS``): the episode's configuration
  (``C_*`` offsets) followed by the plant's parameter vector (the model's ``SLOTS``);
* ``X`` (mutable, length ``X_HIST + history length``): the episode's counters,
  the controller's memory, the plant state (room for :data:`MAX_STATES`) and
  the command ring buffer.

and a scratch block ``W`` of shape :data:`W_SHAPE`.  A batch stacks rows.

Examples
--------
>>> import numpy as np
>>> from ehas_env.env import batch_kernel as bk
>>> from ehas_env.simulation.compiled_model import current_model
>>> bk.N_OBS_BASE, len(bk.RAW_NAMES)
(10, 18)
>>> z = current_model().gauss_noise(12345, 7)
>>> bool(z == current_model().gauss_noise(12345, 7) and np.isfinite(z))
True
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ehas_env.physics.layout import *  # noqa: F401,F403

# >>> compiled

# ---------------------------------------------------------------------------
# layouts
# ---------------------------------------------------------------------------
MAX_COMPONENTS = 4  # sines in a sum-of-sines reference
#: one sine of the reference: kernel.reference_point's vector (SineReference.kernel_vector)
REF_FIELDS = ("amp_deg", "freq_hz", "phase_rad", "ramp_s")
N_REF = len(REF_FIELDS)
MAX_PREVIEW = 8  # reference preview samples in the observation

MAX_STATES = 32  # room for the plant state in X (baseline 11 + effects' own states)
N_GAIN_SLOTS = 16  # control_laws.N_GAINS
N_MEM_SLOTS = 8  # control_laws.N_MEM
# C: constants of one environment (the plant's parameter vector follows, from C_P on)
_C_NAMES = (
    "dt", "nsub", "mode", "act_scale", "u_max", "law",
) + tuple(f"gain{j}" for j in range(N_GAIN_SLOTS)) + (
    "adc", "dac", "gain_err", "noise_std", "seed",
    "amp", "ref_kind", "ncomp",
) + tuple(f"comp{j}_{q}" for j in range(MAX_COMPONENTS) for q in REF_FIELDS) + (
    "nsteps", "win0", "win1",
    "rate_w", "term_w",
    "th_scale", "v_scale", "a_scale", "p_scale", "obs_clip",
    "nprev",
) + tuple(f"prev{j}" for j in range(MAX_PREVIEW)) + tuple(f"s0_{j}" for j in range(MAX_STATES))
C_INDEX = {name: j for j, name in enumerate(_C_NAMES)}
C_P = len(_C_NAMES)  # the plant's parameter vector starts here

# numba reads module-level ints as compile-time constants
C_DT, C_NSUB, C_MODE, C_ACT_SCALE, C_UMAX, C_LAW = (
    C_INDEX[n] for n in ("dt", "nsub", "mode", "act_scale", "u_max", "law"))
C_GAINS = C_INDEX["gain0"]  # the base controller's gains (N_GAIN_SLOTS)
C_ADC, C_DAC, C_GAIN_ERR, C_NOISE_STD, C_SEED = (C_INDEX[n] for n in ("adc", "dac", "gain_err", "noise_std", "seed"))
C_AMP, C_REF_KIND, C_NCOMP, C_COMP = C_INDEX["amp"], C_INDEX["ref_kind"], C_INDEX["ncomp"], C_INDEX["comp0_amp_deg"]
C_NSTEPS, C_WIN0, C_WIN1 = C_INDEX["nsteps"], C_INDEX["win0"], C_INDEX["win1"]
C_RATE_W, C_TERM_W = C_INDEX["rate_w"], C_INDEX["term_w"]
C_TH_SCALE, C_V_SCALE, C_A_SCALE, C_P_SCALE, C_OBS_CLIP = (
    C_INDEX[n] for n in ("th_scale", "v_scale", "a_scale", "p_scale", "obs_clip"))
C_NPREV, C_PREV, C_S0 = C_INDEX["nprev"], C_INDEX["prev0"], C_INDEX["s0_0"]

# reference kinds (C_REF_KIND); a chirp would be kind 1 with its own parameter block
REF_SUM_OF_SINES = 0
# controller modes (C_MODE)
MODE_DIRECT, MODE_RIG, MODE_EXTERNAL = 0, 1, 2

# X: mutable state of one environment
X_K = 0  # step index k (t = k dt)
X_APREV = 1  # previous (clipped) action
X_THS = 2  # sensed theta at t_k, deg (what the controller reads)
X_FLAGS = 3  # status bits of the last step (FLAG_*)
X_SUMW, X_NW, X_MAXW = 4, 5, 6  # e^2 sum, count, max |e| in the metric window
X_SUMA, X_NA, X_MAXA = 7, 8, 9  # the same over every sample so far
X_MEM = 10  # the base controller's memory (N_MEM_SLOTS)
X_S = X_MEM + N_MEM_SLOTS  # the plant state (MAX_STATES)
X_HIST = X_S + MAX_STATES  # command ring buffer (advance's hist) from here on

#: states smaller than this are set to zero after each step (far below any physical
#: scale of the plant: flows ~1e-4 m^3/s, angles ~1 rad, pressures ~1e7 Pa)
TINY = 1.0e-150

#: scratch of one environment: RK4 stages k1..k4, tmp, a state backup, the measured outputs
W_SHAPE = (7, max(MAX_STATES, N_OUT))

FLAG_STROKE_END = 1  # the piston touched a stroke end: terminated
FLAG_NONFINITE = 2  # the state became non-finite: step undone, terminated
FLAG_BAD_ACTION = 4  # non-finite action: nothing was simulated
FLAG_TRUNCATED = 8  # the episode reached its last step

# raw (unscaled) values of the latest sample, engineering units
RAW_NAMES = (
    "t", "theta_deg", "theta_sensed_deg", "omega_deg_s", "omega_sensed_deg_s", "theta_ref_deg", "theta_ref_dot",
    "theta_ref_ddot", "theta_ref_dddot", "error_deg", "p_a_bar", "p_b_bar", "p_s_bar", "flow_lpm", "load_kN",
    "current_mA", "u_controller_mA", "action",
)
N_RAW = len(RAW_NAMES)
(R_T, R_THETA, R_THS, R_OMEGA, R_OMEGA_S, R_REF, R_REFD, R_REFDD, R_REFDDD, R_ERR, R_PA, R_PB, R_PS, R_FLOW,
 R_LOAD, R_CURRENT, R_UCTRL, R_ACTION) = range(N_RAW)

#: observation entries before the preview, and after it
OBS_HEAD = ("error", "theta", "omega", "theta_ref", "theta_ref_dot", "theta_ref_ddot")
OBS_TAIL = ("p_a", "p_b", "prev_action", "u_controller")
N_OBS_BASE = len(OBS_HEAD) + len(OBS_TAIL)

_BAR = 1.0e5
_LPM = 1.0e-3 / 60.0
_RAD2DEG = 180.0 / math.pi


def x_length(hist_len: int) -> int:
    """Length of an environment's mutable row for a command buffer of ``hist_len``."""
    return X_HIST + int(hist_len)


# ---------------------------------------------------------------------------
# small compiled parts
# ---------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _splitmix64(z):
    z = (z + np.uint64(0x9E3779B97F4A7C15))
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True)
def gauss_noise(seed, k):
    """Standard normal draw number ``k`` of the stream ``seed`` (counter-based).

    A pure function of (seed, k): an environment stepped alone or inside a
    batch, in any order, sees the same noise.  Box-Muller on two splitmix64
    draws.
    """
    base = _splitmix64(np.uint64(seed) * np.uint64(0x100000001B3) + np.uint64(k) * np.uint64(2))
    a = _splitmix64(base)
    b = _splitmix64(base + np.uint64(1))
    u1 = (float(a >> np.uint64(11)) + 1.0) * (1.0 / 9007199254740992.0)  # (0, 1]
    u2 = float(b >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@njit(cache=True, inline="always")
def reference(C, t):
    """(theta_ref, its 1st, 2nd, 3rd derivative) at t, deg and deg/s^n.

    A sum of sines, each evaluated by ``reference_point`` (the faded-in
    sine of ``SineReference``), so a single sine is bit for bit the reference of
    ``Plant.simulate_closed_loop``.
    """
    r = 0.0
    rd = 0.0
    rdd = 0.0
    rddd = 0.0
    for j in range(int(C[C_NCOMP])):
        a = C_COMP + N_REF * j
        r0, r1, r2, r3 = reference_point(C[a:a + N_REF], t)
        r += r0
        rd += r1
        rdd += r2
        rddd += r3
    return r, rd, rdd, rddd


@njit(cache=True, inline="always")
def _clip(x, c):
    return min(max(x, -c), c)


@njit(cache=True, inline="always")
def _observe(X, C, W, u_base, current, a, obs, raw):
    """Measure the state at t_k, write obs and raw, update the episode's error sums.

    Returns the tracking error on the physical angle, deg.
    """
    P = C[C_P:]
    s = X[X_S:X_S + N_STATES]
    out = W[6]
    measure(s, P, out)
    k = X[X_K]
    t = k * C[C_DT]
    th = out[O_THETA] * _RAD2DEG
    noise = 0.0
    if C[C_NOISE_STD] > 0.0:
        noise = C[C_NOISE_STD] * gauss_noise(np.int64(C[C_SEED]), np.int64(k))
    th_s = sense(out[O_THETA], C[C_GAIN_ERR], noise, C[C_ADC])
    # the rig has no velocity sensor: the observed rate is the sensed angle's backward difference
    omega_s = (th_s - X[X_THS]) / C[C_DT] if k > 0.0 else 0.0
    X[X_THS] = th_s
    r, rd, rdd, rddd = reference(C, t)
    e_obs = r - th_s
    e = r - th
    omega = out[O_OMEGA] * _RAD2DEG

    amp = C[C_AMP]
    clip = C[C_OBS_CLIP]
    th_sc = C[C_TH_SCALE]
    obs[0] = _clip(e_obs / amp, clip)
    obs[1] = _clip(th_s / th_sc, clip)
    obs[2] = _clip(omega_s / C[C_V_SCALE], clip)
    obs[3] = _clip(r / th_sc, clip)
    obs[4] = _clip(rd / C[C_V_SCALE], clip)
    obs[5] = _clip(rdd / C[C_A_SCALE], clip)
    npv = int(C[C_NPREV])
    for j in range(npv):
        obs[6 + j] = _clip(reference(C, t + C[C_PREV + j])[0] / th_sc, clip)
    o = 6 + npv
    p_sc = C[C_P_SCALE]
    obs[o] = _clip(2.0 * s[4] / p_sc - 1.0, clip)
    obs[o + 1] = _clip(2.0 * s[5] / p_sc - 1.0, clip)
    obs[o + 2] = a
    obs[o + 3] = _clip(u_base / C[C_ACT_SCALE], clip)

    raw[R_T] = t
    raw[R_THETA] = th
    raw[R_THS] = th_s
    raw[R_OMEGA] = omega
    raw[R_OMEGA_S] = omega_s
    raw[R_REF] = r
    raw[R_REFD] = rd
    raw[R_REFDD] = rdd
    raw[R_REFDDD] = rddd
    raw[R_ERR] = e_obs
    raw[R_PA] = s[4] / _BAR
    raw[R_PB] = s[5] / _BAR
    raw[R_PS] = s[6] / _BAR
    raw[R_FLOW] = out[O_FLOW] / _LPM
    raw[R_LOAD] = out[O_FORCE] * 1e-3
    raw[R_CURRENT] = current
    raw[R_UCTRL] = u_base
    raw[R_ACTION] = a

    e2 = e * e
    ae = abs(e)
    X[X_SUMA] += e2
    X[X_NA] += 1.0
    if ae > X[X_MAXA]:
        X[X_MAXA] = ae
    if k >= C[C_WIN0] and k < C[C_WIN1]:
        X[X_SUMW] += e2
        X[X_NW] += 1.0
        if ae > X[X_MAXW]:
            X[X_MAXW] = ae
    return e


@njit(cache=True, inline="always")
def _base_controller(X, C, k, dt):
    """The compiled base controller's command at t_k, mA: its law on the sensed angle of the last measurement."""
    r, rd, rdd, rddd = reference(C, k * dt)
    s = X[X_S:X_S + N_STATES]
    return control_law(np.int64(C[C_LAW]), C[C_GAINS:C_GAINS + N_GAIN_SLOTS], X[X_MEM:X_MEM + N_MEM_SLOTS], k * dt,
                       dt, X[X_THS], r, rd, rdd, rddd, (s[4] - s[5]) * 1e-5, s[6] * 1e-5, C[C_UMAX])


@njit(cache=True, inline="always")
def _reset_core(X, C, W, obs, raw):
    for j in range(X.shape[0]):
        X[j] = 0.0
    for j in range(N_STATES):
        X[X_S + j] = C[C_S0 + j]
    _observe(X, C, W, 0.0, 0.0, 0.0, obs, raw)


@njit(cache=True, inline="always")
def _step_core(X, C, W, action, u_ext, obs, raw):
    """One control period of one environment; returns the reward.

    Status bits go to X[X_FLAGS]; a non-finite action changes nothing.
    """
    if not math.isfinite(action) or not math.isfinite(u_ext):
        X[X_FLAGS] = FLAG_BAD_ACTION
        return 0.0
    flags = 0
    a = min(max(action, -1.0), 1.0)
    dt = C[C_DT]
    k = X[X_K]
    u_max = C[C_UMAX]
    mode = C[C_MODE]
    if mode == MODE_RIG:
        u_base = _base_controller(X, C, k, dt)
    elif mode == MODE_EXTERNAL:
        u_base = min(max(u_ext, -u_max), u_max)
    else:
        u_base = 0.0
    u = min(max(u_base + a * C[C_ACT_SCALE], -u_max), u_max)
    u = quantize(u, C[C_DAC])

    s = X[X_S:X_S + N_STATES]
    hist = X[X_HIST:]
    backup = W[5]
    for j in range(N_STATES):
        backup[j] = s[j]
    ki = np.int64(k)
    hist[ki % hist.shape[0]] = u
    hit = advance(s, C[C_P:], hist, ki, dt, np.int64(C[C_NSUB]), 0.0, W[0], W[1], W[2], W[3], W[4])
    finite = True
    for j in range(N_STATES):
        x = s[j]
        if not math.isfinite(x):
            finite = False
        elif abs(x) < TINY:
            # A decaying state (valve flow after the command returns to zero) would
            # otherwise reach subnormal numbers, which make every operation ~100x slower.
            s[j] = 0.0
    if not finite:
        for j in range(N_STATES):
            s[j] = backup[j]
        flags |= FLAG_NONFINITE
    elif hit:
        flags |= FLAG_STROKE_END
    X[X_K] = k + 1.0
    a_prev = X[X_APREV]
    X[X_APREV] = a
    e = _observe(X, C, W, u_base, u, a, obs, raw)
    e_n = e / C[C_AMP]
    da = a - a_prev
    reward = -(e_n * e_n) - C[C_RATE_W] * da * da
    if flags != 0:
        # ending early must never pay: charge the rest of the episode at the amplitude
        reward -= C[C_TERM_W] * max(C[C_NSTEPS] - (k + 1.0), 0.0)
    if k + 1.0 >= C[C_NSTEPS]:
        flags |= FLAG_TRUNCATED
    X[X_FLAGS] = flags
    return reward


@njit(cache=True, inline="always")
def _row_step(X, C, W, action, active, obs, raw, rewards, terminated, truncated, i):
    """Row i of a batch step: reward and end flags written, returns 1 if the episode ended."""
    rewards[i] = 0.0
    terminated[i] = False
    truncated[i] = False
    if not active:
        return 0
    rewards[i] = _step_core(X, C, W, action, 0.0, obs, raw)
    f = np.int64(X[X_FLAGS])
    if f & (FLAG_STROKE_END | FLAG_NONFINITE):
        terminated[i] = True
        return 1
    if f & FLAG_TRUNCATED:
        truncated[i] = True
        return 1
    return 0


# ---------------------------------------------------------------------------
# entry points
# ---------------------------------------------------------------------------
@njit(cache=True, _nrt=False)
def single_reset(X, C, W, obs, raw):
    """Reset one environment to C's initial state and observe t = 0."""
    _reset_core(X, C, W, obs, raw)


@njit(cache=True, _nrt=False)
def single_step(X, C, W, action, u_ext, obs, raw):
    """One step of one environment: returns the reward, status bits in X[X_FLAGS]."""
    return _step_core(X, C, W, action, u_ext, obs, raw)


@njit(cache=True, _nrt=False)
def batch_reset(X, C, W, mask, obs, raw):
    """Reset the rows i with mask[i] (serial)."""
    for i in range(X.shape[0]):
        if mask[i]:
            _reset_core(X[i], C[i], W[i], obs[i], raw[i])


# Two functions, not one body jitted twice: numba's cache keys a function by its name and
# code, so a serial and a parallel build of the same function would share cache entries.
@njit(cache=True, _nrt=False)
def batch_step_serial(X, C, W, actions, active, obs, raw, rewards, terminated, truncated):
    """One step of every active row, serial loop; returns how many rows ended."""
    n_done = 0
    for i in range(X.shape[0]):
        n_done += _row_step(X[i], C[i], W[i], actions[i], active[i], obs[i], raw[i], rewards, terminated,
                            truncated, i)
    return n_done


@njit(_nrt=False)
def _row_call(X, C, W, actions, active, obs, raw, rewards, terminated, truncated, i):
    # a call, not inlined: the row views are made here, without reference counting,
    # which a parallel loop (always reference counted) would do atomically on shared arrays
    return _row_step(X[i], C[i], W[i], actions[i], active[i], obs[i], raw[i], rewards, terminated, truncated, i)


@njit(cache=True, parallel=True)
def batch_step_parallel(X, C, W, actions, active, obs, raw, rewards, terminated, truncated):
    """One step of every active row, rows spread over the cores; returns how many rows ended."""
    n_done = 0
    for i in prange(X.shape[0]):
        n_done += _row_call(X, C, W, actions, active, obs, raw, rewards, terminated, truncated, i)
    return n_done


def batch_step(X, C, W, actions, active, obs, raw, rewards, terminated, truncated, parallel: bool = False) -> int:
    """Step every active row i of the batch with ``actions[i]`` (see :func:`single_step`).

    Writes ``rewards``, ``terminated`` (stroke end, non-finite state) and
    ``truncated`` (end of the episode) per row, zero for inactive rows, and
    returns how many rows ended.  Rows are independent, so the serial and the
    parallel (numba ``prange``, one thread per core) loops give identical results.
    """
    fn = batch_step_parallel if parallel else batch_step_serial
    return int(fn(X, C, W, actions, active, obs, raw, rewards, terminated, truncated))
