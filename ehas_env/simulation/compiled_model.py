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


def current_model(inline: bool = True, hypotheses: bool = False):
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

    Returns
    -------
    module
        The generated model module.
    """
    from ehas_env.physics.effects import REGISTRY

    forced = os.environ.get("EHAS_BUILD", "")  # "inline" / "quick": one build for everything (benchmarks of the builds)
    if forced not in ("", "inline", "quick"):
        raise ValueError(f"EHAS_BUILD must be 'inline' or 'quick' (or unset), got {forced!r}")
    if forced:
        inline = forced == "inline"
    effects = [c for c in REGISTRY.values() if hypotheses or c.kind != "hypothesis"]
    return build_model(effects, laws=all_laws(), inline=inline)


def names_hypothesis(names) -> bool:
    """True when one of the effect ``names`` is a structural hypothesis (its model is the one with them)."""
    from ehas_env.physics.effects import REGISTRY

    return any(n in REGISTRY and REGISTRY[n].kind == "hypothesis" for n in names)
