"""Classical controllers and tuners (installed as ``ehas_controllers``)."""
