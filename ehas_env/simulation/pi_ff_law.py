"""The book's PI + feed-forward control law, written once.

The rig's RMC70-like controller (1 kHz, zero-order hold) and its model-inversion
and load-pressure-feedback variants are one law::

    i = Kp e + Ki int(e) + Kv r' + Ka r'' + Kj r''' - Kdp dP_L,      e = theta_ref - theta

:func:`pi_ff_law` is compiled into the model as the law ``"pi_ff"``
(:mod:`ehas_env.simulation.control_laws` registers it) and called as plain
Python by :meth:`ehas_controllers.piff.PIFF.act`; its gains and their units are
:class:`ehas_env.simulation.rig_controller.RigController`'s.  This module imports
nothing of the project: the law's body is copied into the compiled model.
"""
from __future__ import annotations

#: gain name -> unit (the order of the gains vector)
GAIN_UNITS = {
    "Kp": "mA/deg",
    "Ki": "mA/(deg s)",
    "Kv": "mA/(deg/s)",
    "Ka": "mA/(deg/s^2)",
    "Kj": "mA/(deg/s^3)",
    "Kdp": "mA/bar",
    "dp_hp": "rad/s",
}
GAIN_NAMES = tuple(GAIN_UNITS)


def pi_ff_law(gains, mem, t, dt, theta, r, rd, rdd, rddd, p_load, p_s, u_max):
    """PI + feed-forward + load-pressure feedback, mA, clipped to +-u_max (compiled law "pi_ff").

    gains = (Kp, Ki, Kv, Ka, Kj, Kdp, dp_hp) in the units of GAIN_UNITS;
    mem = [integral of e (deg s), low-passed load pressure (bar), ...].  The
    integral stops while the output is clamped and the error would drive it
    further (anti-windup).
    """
    kp, ki, kv, ka, kj, kdp, whp = gains[0], gains[1], gains[2], gains[3], gains[4], gains[5], gains[6]
    e = r - theta
    if whp > 0.0:
        # first-order high-pass: feed back only the pressure's changes
        mem[1] += dt * whp * (p_load - mem[1])
        dp_fb = p_load - mem[1]
    else:
        dp_fb = p_load
    u_ff = kv * rd + ka * rdd + kj * rddd - kdp * dp_fb
    u = kp * e + ki * (mem[0] + e * dt) + u_ff
    if (u < u_max and u > -u_max) or (u >= u_max and e < 0.0) or (u <= -u_max and e > 0.0):
        mem[0] += e * dt
    u = kp * e + ki * mem[0] + u_ff
    return min(max(u, -u_max), u_max)
