"""Shared test fixtures: where the read-only reference material lives."""
from __future__ import annotations

import csv
import sys
from pathlib import Path

import pytest

# test modules in the layer folders import read_book_csv from here
sys.path.insert(0, str(Path(__file__).parent))

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
