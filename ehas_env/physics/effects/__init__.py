"""The effects library: physical additions to the baseline plant, by name.

Each effect lives in one module of this package: a subclass of
:class:`~ehas_env.physics.effects.base.Effect` with its parameters (SI unit, default,
fitting bounds, realistic range), a one-paragraph physical explanation, its
residual signature in words, and its physics: static methods named after the
places of the model where it acts (``PLACES``: piston force, crank torque,
chamber flows, valve current, moving mass, supply rate, rod joint, own states),
which :mod:`ehas_env.physics.codegen` compiles into the model.  Subclassing
registers the effect; importing this package imports every module in it, so
adding an effect means adding one file here -- or, from outside the package,
one file in a folder named by ``--effects-path`` (:mod:`.loading`).

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
    if _mod not in ("base", "loading"):
        importlib.import_module(f"{__name__}.{_mod}")

# the generic state augmentations (one class per kind, a subclass per place): outside this package, tried by the
# diagnosis' state stage only (ehas_env.diagnosis.states); and the static terms at the balances (one class per kind,
# applied at every balance place)
importlib.import_module("ehas_env.physics.augment")
importlib.import_module("ehas_env.physics.balance_blocks")

from ehas_env.physics.effects.loading import load_effects_path, load_external_effects  # noqa: E402

load_external_effects()

__all__ = ["REGISTRY", "Effect", "Param", "get_effect", "load_effects_path", "parse_spec", "resolve_effects"]
