"""Learned controllers: stable-baselines3 training (installed as ``ehas_train``)."""
