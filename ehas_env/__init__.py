"""ehas: electro-hydraulic actuation systems toolkit.

The package ``ehas_env`` holds the physics (plant, effects, sensors), the
gymnasium environment, identification and diagnosis.  The repository folders
``controllers/`` and ``train/`` are installed as ``ehas_controllers`` and
``ehas_train`` so that no clash-prone top-level names are installed.
"""

__version__ = "0.1.0"


def register_envs() -> None:
    """Register ``ehas/Tracking-v0`` with gymnasium (single and vector entry points).

    The TimeLimit is a safety cap: episodes end by themselves (truncated) after
    ``cycles`` reference periods, 3000 steps by default; see ehas_env.env.tracking_env.
    """
    import gymnasium

    if "ehas/Tracking-v0" not in gymnasium.registry:
        gymnasium.register(
            id="ehas/Tracking-v0",
            entry_point="ehas_env.env.tracking_env:TrackingEnv",
            vector_entry_point="ehas_env.env.vector_env:TrackingVectorEnv",
            max_episode_steps=60_000,
        )


class _RegisterWhenGymnasiumLoads:
    """Import hook: registers the environments right after gymnasium is imported.

    Importing gymnasium here would pull numpy into every ``ehas`` command (the
    CLI stays light); with the hook, ``import ehas_env`` before or after
    ``import gymnasium`` both make ``gymnasium.make("ehas/Tracking-v0")`` work.
    """

    busy = False

    def find_spec(self, name, path=None, target=None):
        if name != "gymnasium" or self.busy:
            return None
        import importlib.util
        import sys

        self.busy = True  # the normal finders locate gymnasium
        try:
            spec = importlib.util.find_spec(name)
        finally:
            self.busy = False
        if spec is not None and spec.loader is not None and hasattr(spec.loader, "exec_module"):
            load = spec.loader.exec_module

            def exec_module(module, _load=load):
                _load(module)
                if self in sys.meta_path:
                    sys.meta_path.remove(self)
                register_envs()

            spec.loader.exec_module = exec_module
        return spec


def _register_envs() -> None:
    import sys

    if "gymnasium" in sys.modules:
        register_envs()
    elif not any(isinstance(f, _RegisterWhenGymnasiumLoads) for f in sys.meta_path):
        sys.meta_path.insert(0, _RegisterWhenGymnasiumLoads())


_register_envs()
