"""The compiled model of every effect and controller law registered now.

:mod:`ehas_env.physics.codegen` builds a model from the effects and laws it is
given; this module gives it the registered ones (the library's and the user's
effects, :mod:`ehas_env.simulation.control_laws`) and picks the build.

Examples
--------
>>> from ehas_env.simulation.compiled_model import current_model
>>> m = current_model(inline=False)
>>> m.STATE_NAMES[:3], "coulomb_friction.Fc" in m.IDX
(('theta', 'omega', 'qc'), True)
"""
from __future__ import annotations

import os

from ehas_env.physics.codegen import build_model
from ehas_env.simulation.control_laws import all_laws


def current_model(inline: bool = True, hypotheses: bool = False, interpreted: bool = False):
    """The model of every effect and controller law registered now (built-in and user-loaded).

    Parameters
    ----------
    inline : bool
        True (the environments' and the batched kernel's build): every model function is inlined into the
        drivers, the fastest step and a long compile.  False (the :class:`~ehas_env.simulation.plant.Plant`'s
        build: replay of logs, fits, single runs): each function is compiled once and called, several times
        faster to compile for a slower step (``results/compile.md`` has both figures).
    hypotheses : bool
        Also hold the diagnosis' structural hypotheses (effects of kind ``"hypothesis"``).  They are left out
        otherwise: every model a command compiles pays for every effect it holds, and only a diagnosis that
        reaches them (or a plant that names one) uses them.
    interpreted : bool
        The inlined build's text run as plain Python (no compile, the same numbers, a slow step; ``inline``
        and ``EHAS_BUILD`` do not apply): what an environment steps on while its fast build compiles.

    Returns
    -------
    module
        The generated model module.
    """
    if interpreted:
        return build_model(_effects(hypotheses), laws=all_laws(), interpreted=True)
    forced = forced_build()
    if forced:
        inline = forced == "inline"
    return build_model(_effects(hypotheses), laws=all_laws(), inline=inline)


def forced_build() -> str:
    """The build ``$EHAS_BUILD`` forces on everything (benchmarks of the builds).

    Returns
    -------
    str
        "inline", "quick" or "" (unset: each caller picks its build).

    Raises
    ------
    ValueError
        If ``EHAS_BUILD`` holds anything else.
    """
    forced = os.environ.get("EHAS_BUILD", "")
    if forced not in ("", "inline", "quick"):
        raise ValueError(f"EHAS_BUILD must be 'inline' or 'quick' (or unset), got {forced!r}")
    return forced


def _effects(hypotheses: bool) -> list:
    from ehas_env.physics.effects import REGISTRY

    return [c for c in REGISTRY.values() if hypotheses or c.kind != "hypothesis"]


class _Ready:
    """A build that is in use from the start (the :class:`FastBuildBehind` interface: ``model``, ``done``)."""

    done = True

    def __init__(self, model):
        self.model = self.fast = model

    def poll(self):
        return self.model

    def wait(self, timeout=None):
        return self.model


def fast_model_behind(calls, what: str, estimate: str = "inline", meanwhile: str = "interpreted"):
    """The fast-step build of :func:`current_model`, compiled behind a quicker build on its first use.

    When the inlined build's entry points ``calls`` are already in numba's cache (or ``EHAS_BUILD`` forces a
    build, or ``EHAS_COMPILE_BEHIND=0``), that build is used at once; otherwise the caller starts on the
    ``meanwhile`` build (same numbers) while a background process compiles the inlined one
    (:class:`ehas_env.physics.compile_behind.FastBuildBehind`).

    Parameters
    ----------
    calls : dict
        ``{entry point: example arguments}`` the caller runs (see ``FastBuildBehind``).
    what : str
        What runs on it, for the messages.
    estimate : str
        Which measured compile time (``ehas_env.physics.codegen.COMPILE_CPU_S``) the message's estimate scales.
    meanwhile : {"interpreted", "quick"}
        The build run until the fast one is ready: the interpreted build (no compile; an environment's
        step) or the quick build (compiled in seconds, a step a few times slower; a benchmark grid).

    Returns
    -------
    FastBuildBehind or object with the same ``model``, ``done``, ``poll()`` and ``wait()``
        Call ``poll()`` (cheap) before each use while ``done`` is False; ``model`` is the build to call.
    """
    fast = current_model()
    if forced_build() or os.environ.get("EHAS_COMPILE_BEHIND", "") == "0":
        return _Ready(fast)
    from ehas_env.physics.compile_behind import FastBuildBehind

    if meanwhile == "quick":
        return FastBuildBehind(fast, current_model(inline=False), calls, what, estimate,
                               "quick-compile build (same numbers, compiled in seconds, a slower step)")
    return FastBuildBehind(fast, current_model(interpreted=True), calls, what, estimate)


def names_hypothesis(names) -> bool:
    """True when one of the effect ``names`` is a structural hypothesis (its model is the one with them)."""
    from ehas_env.physics.effects import REGISTRY

    return any(n in REGISTRY and REGISTRY[n].kind == "hypothesis" for n in names)
