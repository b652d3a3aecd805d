"""ehas: electro-hydraulic actuation systems toolkit.

The package ``ehas_env`` holds the physics (plant, effects, sensors), the
gymnasium environment, identification and diagnosis.  The repository folders
``controllers/`` and ``train/`` are installed as ``ehas_controllers`` and
``ehas_train`` so that no clash-prone top-level names are installed.
"""

__version__ = "0.1.0"
