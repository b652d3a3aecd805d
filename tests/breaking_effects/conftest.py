"""The effect files here are loaded by ``effects_path`` where a test asks for them (tests/breaking_plants.py), never
imported by collection: an effect registers itself when imported, and a registered effect is compiled into every
later model of the run."""
collect_ignore = ["slip_coupling.py"]
