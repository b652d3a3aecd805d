"""Registry of compiled controller laws: each controller file registers its one law here.

A compiled law is a plain function that numba can compile, with the signature::

    law(gains, mem, t, dt, theta, r, rd, rdd, rddd, p_load, p_s, u_max) -> current mA

``gains`` (up to :data:`N_GAINS` numbers, the controller's own meaning), ``mem``
(:data:`N_MEM` numbers of memory, zero at the start of a run, the law updates
them in place), t (s), dt (s), the sensed angle theta (deg), the reference
r and its first three derivatives (deg, deg/s^k), load pressure and supply
pressure (bar), the output limit u_max (mA).  It returns the command before
the DAC, clipped to +-u_max.  The law's source is copied into the compiled
model (:mod:`ehas_env.physics.codegen`), so it may use ``math`` and nothing
else from outside its body.

Examples
--------
>>> from ehas_env.simulation.control_laws import law_id
>>> law_id("pi_ff")
0
"""
from __future__ import annotations

from ehas_env.simulation.pi_ff_law import pi_ff_law

N_GAINS = 16
N_MEM = 8
_LAWS: dict[str, object] = {}


def register_law(name: str, fn) -> None:
    """Register ``fn`` as the compiled law ``name`` (re-registering the same name replaces it)."""
    if not callable(fn):
        raise ValueError(f"control law '{name}' must be a function")
    check_law(name, fn)
    _LAWS[name] = fn


#: a compiled law's arguments, in order (ehas_env.simulation.pi_ff_law is the example)
LAW_ARGS = ("gains", "mem", "t", "dt", "theta", "r", "rd", "rdd", "rddd", "p_load", "p_s", "u_max")


def check_law(name: str, fn) -> None:
    """A law's signature (12 plain arguments, :data:`LAW_ARGS`) and one call, as plain Python, with realistic
    values returning one finite number: a wrong law fails here in one line, not deep inside numba."""
    import inspect
    import math
    import numbers

    import numpy as np

    who = f"control law '{name}' ({getattr(fn, '__qualname__', fn)})"
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        raise ValueError(f"{who}: not a Python function") from None
    ps = list(sig.parameters.values())
    if len(ps) != len(LAW_ARGS) or any(p.kind not in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in ps):
        raise ValueError(f"{who}: takes ({', '.join(sig.parameters)}); a law takes exactly {len(LAW_ARGS)} plain "
                         f"arguments ({', '.join(LAW_ARGS)})")
    gains = np.zeros(N_GAINS)
    gains[:3] = (0.3, 0.1, 0.05)
    try:
        out = fn(gains, np.zeros(N_MEM), 0.1, 1e-3, 1.0, 2.0, 10.0, 0.0, 0.0, 5.0, 220.0, 20.0)
    except Exception as exc:  # a user's law: one line naming it
        raise ValueError(f"{who}: a call with realistic values raised {type(exc).__name__}: "
                         f"{' '.join(str(exc).split())[:200]}") from None
    if isinstance(out, bool) or not isinstance(out, (numbers.Real, np.floating)) or not math.isfinite(float(out)):
        raise ValueError(f"{who}: returned {out!r:.60} for realistic values; a law returns one finite current, mA")


def all_laws() -> list:
    """(name, function) of every registered law, built-in first, in registration order."""
    return list(_LAWS.items())


def law_id(name: str) -> int:
    """Index of law ``name`` in the current model (ValueError naming the known laws otherwise)."""
    names = [n for n, _ in all_laws()]
    if name not in names:
        raise ValueError(f"unknown compiled control law '{name}'; known: {', '.join(names)}")
    return names.index(name)


def compiled_form(controller, disc_sets: int | None = None):
    """The object that carries ``controller``'s compiled law on ``disc_sets`` (with ``law_id()`` and
    ``gains_vector()``), or None when the controller has only a Python ``act``.

    Gain schedules pick their entry (``for_plant``); ``rig_gains`` (the rig's PI + feed-forward
    form of PIFF and schedules) is followed.
    """
    sub = controller.for_plant(disc_sets) if disc_sets is not None and hasattr(controller, "for_plant") else controller
    if callable(getattr(sub, "law_id", None)) and callable(getattr(sub, "gains_vector", None)):
        return sub
    rg = getattr(sub, "rig_gains", None)
    rc = rg(disc_sets) if callable(rg) else None
    if rc is not None and callable(getattr(rc, "law_id", None)):
        return rc
    return None


# the built-in law, registered first (law number 0): the book's PI + feed-forward
register_law("pi_ff", pi_ff_law)
