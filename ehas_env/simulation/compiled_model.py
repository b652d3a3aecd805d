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


def current_model(inline: bool = True):
    """The model of every effect and controller law registered now (built-in and user-loaded).

    Parameters
    ----------
    inline : bool
        True (the environments' and the batched kernel's build): every model function is inlined into the
        drivers, the fastest step and a long compile.  False (the :class:`~ehas_env.simulation.plant.Plant`'s
        build: replay of logs, fits, single runs): each function is compiled once and called, several times
        faster to compile for a slower step (``results/compile.md`` has both figures).

    Returns
    -------
    module
        The generated model module.
    """
    forced = os.environ.get("EHAS_BUILD", "")  # "inline" / "quick": one build for everything (benchmarks of the builds)
    if forced not in ("", "inline", "quick"):
        raise ValueError(f"EHAS_BUILD must be 'inline' or 'quick' (or unset), got {forced!r}")
    if forced:
        inline = forced == "inline"
    return build_model(laws=all_laws(), inline=inline)
