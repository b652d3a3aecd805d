"""Compiled stepping of the tracking environment, one env or a batch in one loop.

The physics is :mod:`ehas_env.physics.kernel` (``advance`` and ``measure``), unchanged.
This module adds what an environment step needs around it -- the reference and
its derivatives, the optional compiled rig controller (residual mode), sensor
noise, observation, reward, termination and the episode's % error -- and steps
one environment (:func:`single_step`) or N of them (:func:`batch_step`) with
the very same code, so a batch reproduces N single environments exactly.

Each environment is two flat float64 rows:

* ``C`` (constants, length :data:`N_CONST`): the plant's parameter vector
  (``kernel.SLOTS``) followed by the episode's configuration (``C_*`` offsets);
* ``X`` (mutable, length ``X_HIST + history length``): the plant state, the
  controller's memory, the episode's counters and the command ring buffer.

and a scratch block ``W`` of shape :data:`W_SHAPE`.  A batch stacks rows.

Why the kernel functions are compiled again here
------------------------------------------------
Every array passed between numba functions is reference counted (atomic
increments on each call).  ``advance`` calls ``derivatives`` 40 times per 1 ms
step, and the counting costs more than the arithmetic (about 3.4 us against
1 us per step).  This module compiles the kernel's own functions a second time
with reference counting off (``_nrt=False``: they never allocate, and the views
they receive never outlive the call) and inlined into one body, which gives
bit-identical results at a quarter of the cost.  The tests compare both builds.

The compiled functions are cached on disk; the cache key includes a hash of
``kernel.py`` (a closure variable, see :func:`_build`) so a change of the
physics invalidates it -- numba alone would not notice a change in another file.

Examples
--------
>>> import numpy as np
>>> from ehas_env.env import batch_kernel as bk
>>> bk.N_OBS_BASE, len(bk.RAW_NAMES)
(10, 18)
>>> z = bk.gauss_noise(12345, 7)
>>> bool(z == bk.gauss_noise(12345, 7) and np.isfinite(z))
True
"""
from __future__ import annotations

import hashlib
import math
import types
from pathlib import Path

import numpy as np
from numba import njit, prange

from ehas_env.physics import kernel as K

# ---------------------------------------------------------------------------
# layouts
# ---------------------------------------------------------------------------
MAX_COMPONENTS = 4  # sines in a sum-of-sines reference
#: one sine of the reference: kernel.reference_point's vector (SineReference.kernel_vector)
REF_FIELDS = ("amp_deg", "freq_hz", "phase_rad", "ramp_s")
N_REF = len(REF_FIELDS)
MAX_PREVIEW = 8  # reference preview samples in the observation

# C: constants of one environment (after the plant's parameter vector)
_C_NAMES = (
    "dt", "nsub", "mode", "act_scale", "u_max",
    "kp", "ki", "kv", "ka", "kj", "kdp", "whp",
    "adc", "dac", "gain_err", "noise_std", "seed",
    "amp", "ref_kind", "ncomp",
) + tuple(f"comp{j}_{q}" for j in range(MAX_COMPONENTS) for q in REF_FIELDS) + (
    "nsteps", "win0", "win1",
    "rate_w", "term_w",
    "th_scale", "v_scale", "a_scale", "p_scale", "obs_clip",
    "nprev",
) + tuple(f"prev{j}" for j in range(MAX_PREVIEW)) + tuple(f"s0_{j}" for j in range(K.N_STATES))
C_INDEX = {name: K.N_SLOTS + j for j, name in enumerate(_C_NAMES)}
N_CONST = K.N_SLOTS + len(_C_NAMES)

# numba reads module-level ints as compile-time constants
C_DT, C_NSUB, C_MODE, C_ACT_SCALE, C_UMAX = (C_INDEX[n] for n in ("dt", "nsub", "mode", "act_scale", "u_max"))
C_KP = C_INDEX["kp"]  # 7 gains follow: kp ki kv ka kj kdp whp
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
X_K = K.N_STATES  # step index k (t = k dt)
X_INTEG = X_K + 1  # controller integral of the error, deg s
X_DPLP = X_K + 2  # controller's low-passed load pressure, bar
X_APREV = X_K + 3  # previous (clipped) action
X_THS = X_K + 4  # sensed theta at t_k, deg (what the controller reads)
X_FLAGS = X_K + 5  # status bits of the last step (FLAG_*)
X_SUMW, X_NW, X_MAXW = X_K + 6, X_K + 7, X_K + 8  # e^2 sum, count, max |e| in the metric window
X_SUMA, X_NA, X_MAXA = X_K + 9, X_K + 10, X_K + 11  # the same over every sample so far
X_HIST = X_K + 12  # command ring buffer (kernel.advance's hist) from here on

#: states smaller than this are set to zero after each step (far below any physical
#: scale of the plant: flows ~1e-4 m^3/s, angles ~1 rad, pressures ~1e7 Pa)
TINY = 1.0e-150

#: scratch of one environment: RK4 stages k1..k4, tmp, a state backup, the measured outputs
W_SHAPE = (7, max(K.N_STATES, K.N_OUT))

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


def kernel_fingerprint() -> int:
    """63-bit hash of ``kernel.py``'s source: part of the compiled cache's key."""
    src = Path(K.__file__).read_bytes()
    return int.from_bytes(hashlib.sha256(src).digest()[:8], "little") >> 1


# ---------------------------------------------------------------------------
# the kernel's functions, compiled without reference counting
# ---------------------------------------------------------------------------
#: kernel functions inlined into their callers: one straight compiled body is ~25 % faster
#: (``advance`` itself stays a function, compiled once for every entry point)
_INLINED = ("rk4_substep", "derivatives", "land_flows", "friction_force", "project", "valve_current", "delayed_command",
            "reference_point", "measure", "quantize")


def _rejit_kernel() -> dict:
    """The kernel module's numba functions compiled again with ``_nrt=False``.

    Same Python source (``py_func``), same globals except that calls between
    kernel functions go to the new builds.  Compilation is lazy: only what a
    step uses is ever compiled, and never on a warm cache.
    """
    g = dict(vars(K))
    built = {}
    for name, obj in vars(K).items():
        py = getattr(obj, "py_func", None)
        if py is None or getattr(py, "__module__", None) != K.__name__:
            continue
        opts = {k: v for k, v in obj.targetoptions.items() if k in ("inline", "boundscheck", "fastmath", "error_model")}
        if name in _INLINED:
            opts["inline"] = "always"
        fn = types.FunctionType(py.__code__, g, py.__name__, py.__defaults__, py.__closure__)
        fn.__doc__ = py.__doc__
        built[name] = njit(_nrt=False, **opts)(fn)
    g.update(built)
    return built


_NB = _rejit_kernel()
advance = _NB["advance"]
measure = _NB["measure"]
quantize = _NB["quantize"]
reference_point = _NB["reference_point"]


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

    A sum of sines, each evaluated by ``kernel.reference_point`` (the faded-in
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
    P = C[:K.N_SLOTS]
    s = X[:K.N_STATES]
    out = W[6]
    measure(s, P, out)
    k = X[X_K]
    t = k * C[C_DT]
    th = out[K.O_THETA] * _RAD2DEG
    th_s = th * (1.0 + C[C_GAIN_ERR])
    if C[C_NOISE_STD] > 0.0:
        th_s += C[C_NOISE_STD] * gauss_noise(np.int64(C[C_SEED]), np.int64(k))
    th_s = quantize(th_s, C[C_ADC])
    # the rig has no velocity sensor: the observed rate is the sensed angle's backward difference
    omega_s = (th_s - X[X_THS]) / C[C_DT] if k > 0.0 else 0.0
    X[X_THS] = th_s
    r, rd, rdd, rddd = reference(C, t)
    e_obs = r - th_s
    e = r - th
    omega = out[K.O_OMEGA] * _RAD2DEG

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
    raw[R_FLOW] = out[K.O_FLOW] / _LPM
    raw[R_LOAD] = out[K.O_FORCE] * 1e-3
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
def _rig_controller(X, C, k, dt):
    """The rig's PI + feed-forward law of ``kernel.run_rig_controller`` at t_k, mA.

    Same statements in the same order (anti-windup included), reading the
    sensed angle stored at the last measurement.
    """
    kp, ki, kv, ka = C[C_KP], C[C_KP + 1], C[C_KP + 2], C[C_KP + 3]
    kj, kdp, whp = C[C_KP + 4], C[C_KP + 5], C[C_KP + 6]
    u_max = C[C_UMAX]
    r, rd, rdd, rddd = reference(C, k * dt)
    e = r - X[X_THS]
    dp = (X[4] - X[5]) * 1e-5
    if whp > 0.0:
        X[X_DPLP] += dt * whp * (dp - X[X_DPLP])
        dp_fb = dp - X[X_DPLP]
    else:
        dp_fb = dp
    integ = X[X_INTEG]
    u_ff = kv * rd + ka * rdd + kj * rddd - kdp * dp_fb
    u = kp * e + ki * (integ + e * dt) + u_ff
    if (u < u_max and u > -u_max) or (u >= u_max and e < 0.0) or (u <= -u_max and e > 0.0):
        integ += e * dt
    X[X_INTEG] = integ
    u = kp * e + ki * integ + u_ff
    return min(max(u, -u_max), u_max)


@njit(cache=True, inline="always")
def _reset_core(X, C, W, obs, raw):
    for j in range(X.shape[0]):
        X[j] = 0.0
    for j in range(K.N_STATES):
        X[j] = C[C_S0 + j]
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
        u_base = _rig_controller(X, C, k, dt)
    elif mode == MODE_EXTERNAL:
        u_base = min(max(u_ext, -u_max), u_max)
    else:
        u_base = 0.0
    u = min(max(u_base + a * C[C_ACT_SCALE], -u_max), u_max)
    u = quantize(u, C[C_DAC])

    s = X[:K.N_STATES]
    hist = X[X_HIST:]
    backup = W[5]
    for j in range(K.N_STATES):
        backup[j] = s[j]
    ki = np.int64(k)
    hist[ki % hist.shape[0]] = u
    hit = advance(s, C[:K.N_SLOTS], hist, ki, dt, np.int64(C[C_NSUB]), 0.0, W[0], W[1], W[2], W[3], W[4])
    finite = True
    for j in range(K.N_STATES):
        x = s[j]
        if not math.isfinite(x):
            finite = False
        elif abs(x) < TINY:
            # A decaying state (valve flow after the command returns to zero) would
            # otherwise reach subnormal numbers, which make every operation ~100x slower.
            s[j] = 0.0
    if not finite:
        for j in range(K.N_STATES):
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
# entry points (built with the kernel's fingerprint as a closure variable)
# ---------------------------------------------------------------------------
def _build(fingerprint: int):
    """Compile the entry points; ``fingerprint`` keys the on-disk cache to kernel.py."""

    @njit(cache=True, _nrt=False)
    def single_reset(X, C, W, obs, raw):
        """Reset one environment to C's initial state and observe t = 0."""
        if fingerprint < 0:  # never: keeps kernel.py's hash in the cache key
            return
        _reset_core(X, C, W, obs, raw)

    @njit(cache=True, _nrt=False)
    def single_step(X, C, W, action, u_ext, obs, raw):
        """One step of one environment: returns the reward, status bits in X[X_FLAGS]."""
        if fingerprint < 0:
            return 0.0
        return _step_core(X, C, W, action, u_ext, obs, raw)

    @njit(cache=True, _nrt=False)
    def batch_reset(X, C, W, mask, obs, raw):
        """Reset the rows i with mask[i] (serial)."""
        if fingerprint < 0:
            return
        for i in range(X.shape[0]):
            if mask[i]:
                _reset_core(X[i], C[i], W[i], obs[i], raw[i])

    # Two functions, not one body jitted twice: numba's cache keys a function by its name and
    # code, so a serial and a parallel build of the same function would share cache entries.
    @njit(cache=True, _nrt=False)
    def batch_step_serial(X, C, W, actions, active, obs, raw, rewards, terminated, truncated):
        """One step of every active row, serial loop; returns how many rows ended."""
        if fingerprint < 0:
            return 0
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
        if fingerprint < 0:
            return 0
        n_done = 0
        for i in prange(X.shape[0]):
            n_done += _row_call(X, C, W, actions, active, obs, raw, rewards, terminated, truncated, i)
        return n_done

    return single_reset, single_step, batch_reset, batch_step_serial, batch_step_parallel


FINGERPRINT = kernel_fingerprint()
single_reset, single_step, batch_reset, batch_step_serial, batch_step_parallel = _build(FINGERPRINT)


def batch_step(X, C, W, actions, active, obs, raw, rewards, terminated, truncated, parallel: bool = False) -> int:
    """Step every active row i of the batch with ``actions[i]`` (see :func:`single_step`).

    Writes ``rewards``, ``terminated`` (stroke end, non-finite state) and
    ``truncated`` (end of the episode) per row, zero for inactive rows, and
    returns how many rows ended.  Rows are independent, so the serial and the
    parallel (numba ``prange``, one thread per core) loops give identical results.
    """
    fn = batch_step_parallel if parallel else batch_step_serial
    return int(fn(X, C, W, actions, active, obs, raw, rewards, terminated, truncated))
