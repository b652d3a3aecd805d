"""The effects library: physical additions to the baseline plant, by name.

Each effect lives in one module of this package: a subclass of
:class:`~ehas_env.physics.effects.base.Effect` with its parameters (SI unit, default,
fitting bounds, realistic range), a one-paragraph physical explanation, its
residual signature in words, and ``apply``, which writes its values into the
general plant model's parameter slots (``ehas_env.physics.kernel.SLOTS``).  Subclassing
registers the effect; importing this package imports every module in it, so
adding an effect means adding one file here.  An effect that needs a physical
term the general model does not have yet also adds that term to
``ehas_env.physics.kernel``.

Examples
--------
>>> from ehas_env.physics.effects import REGISTRY, get_effect
>>> get_effect("coulomb_friction").resolve({"Fc": 250})
{'Fc': 250.0}
>>> "transport_delay" in REGISTRY
True
"""
import importlib
import pkgutil

from ehas_env.physics.effects.base import REGISTRY, Effect, Param, get_effect, parse_spec, resolve_effects

for _mod in sorted(m.name for m in pkgutil.iter_modules(__path__)):
    if _mod != "base":
        importlib.import_module(f"{__name__}.{_mod}")

__all__ = ["REGISTRY", "Effect", "Param", "get_effect", "parse_spec", "resolve_effects"]
