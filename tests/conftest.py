"""Shared test fixtures: where the read-only reference material lives."""
from __future__ import annotations

import csv
import sys
from pathlib import Path

import pytest

# test modules in the layer folders import read_book_csv from here
sys.path.insert(0, str(Path(__file__).parent))

#: effect files loaded by ``effects_path`` where a test asks for them (tests/breaking_plants.py), never imported by
#: collection: an effect registers itself when imported, and a registered effect is compiled into every later model
#: of the run.  (Here, not in a conftest.py of that folder: a second module named ``conftest`` shadows this one for
#: the tests that import ``read_book_csv`` from it.)
collect_ignore = ["breaking_effects"]

#: the book's tables, the tests' independent truth, kept in the repository (tests/data/book/README.md)
BOOK = Path(__file__).resolve().parent / "data" / "book"


def book_path(name: str) -> Path:
    """Path of one of the book's tables in tests/data/book; the test FAILS (never skips) when it is missing.

    The book's data is the tests' independent truth: a test that needs it and cannot
    read it has not passed, so it must not be reported as skipped.
    """
    path = BOOK / name
    if not path.is_file():
        pytest.fail(f"the book's reference data {path} is missing: tests that need it cannot pass without it "
                    f"(the tests' copy of the book's tables, tests/data/book/README.md)", pytrace=False)
    return path


def read_book_csv(name: str) -> list[dict[str, str]]:
    """Rows of one of the book's tables in tests/data/book (independent truth for tests); fails if it is missing."""
    path = book_path(name)
    with path.open() as fh:
        lines = [ln for ln in fh if not ln.startswith("#")]
    return list(csv.DictReader(lines))


@pytest.fixture(scope="session")
def book_loads():
    return read_book_csv("analytic_loads.csv")


@pytest.fixture(scope="module")
def ray_local(request):
    """A local Ray instance with 2 CPUs; the test module's functions are shipped by value."""
    ray = pytest.importorskip("ray")
    ray.cloudpickle.register_pickle_by_value(request.module)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module", autouse=True)
def _registered_effects_and_laws_stay_in_their_module():
    """What a test module registers (user effects, test effects, user controller laws) is unregistered when it ends.

    The compiled model holds every registered effect and law (ehas_env.simulation.compiled_model), so an effect or
    law left registered by one module gave every later environment, benchmark or plant in that worker a model of
    its own, compiled again: seven inlined builds (each 3-5 min on 2 loaded cores) in one default run instead of
    one.  The registries and the loaders' "already loaded" records are restored together, so a later module that
    loads the same file imports and registers it again.  So is ``EHAS_EFFECTS_PATH``, which loading a folder sets
    for worker processes: left set, every later subprocess of the worker (a command run as a user runs it, a
    README block, a Ray or compile-behind worker) loaded the earlier modules' user effects and compiled a model
    of its own with them (in one default run, a hypothesis model with three modules' effects, about 3 min of CPU).
    """
    import os

    from ehas_controllers import base as cbase
    from ehas_env.physics.effects import REGISTRY
    from ehas_env.physics.effects import loading
    from ehas_env.simulation import control_laws

    saved = (dict(REGISTRY), dict(control_laws._LAWS), dict(loading._LOADED), dict(loading.SOURCES),
             dict(cbase.LOADED_FILES))
    user_modules = {n for n in sys.modules if n.startswith(("ehas_user_effects.", "ehas_user_controllers."))}
    effects_path = os.environ.get(loading.ENV_VAR)
    yield
    if effects_path is None:
        os.environ.pop(loading.ENV_VAR, None)
    else:
        os.environ[loading.ENV_VAR] = effects_path
    for live, old in zip((REGISTRY, control_laws._LAWS, loading._LOADED, loading.SOURCES, cbase.LOADED_FILES), saved):
        live.clear()
        live.update(old)
    for n in [n for n in sys.modules if n.startswith(("ehas_user_effects.", "ehas_user_controllers."))]:
        if n not in user_modules:
            del sys.modules[n]
