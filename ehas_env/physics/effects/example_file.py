"""The text of a user's effect file, a torsion spring centring the crank (docs/effects-and-controllers.md).

The tests of user effects, of effect declarations, of the model cache and the fault campaign start from it (and
edit it); the compile benchmark (``python -m ehas_env.cli.compile_bench``) times it as "a new user effect".
"""
from __future__ import annotations


def spring_effect(name: str = "fc_spring", cls: str = "FcSpring") -> str:
    """The file's text; ``name`` and ``cls`` tell copies apart (an effect name registers once)."""
    return f'''"""A torsion spring centring the crank."""
from ehas_env.physics.effects import Effect, Param


class {cls}(Effect):
    name = "{name}"
    title = "torsion spring on the crank"
    params = (Param("k", "N m/rad", 2000.0, (0.0, 1.0e6), "spring rate", typical=(500.0, 5000.0)),)
    main_param = "k"
    explanation = "A spring pulls the crank back to 0 deg with a torque -k theta."
    signature = "load residual in phase with position"

    @staticmethod
    def crank_torque(theta, k):
        return -(k * theta)
'''
