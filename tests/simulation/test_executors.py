"""Executors: same results in task order wherever the work runs; dead workers are
retried or reported, never dropped."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from ehas_env.simulation.executors import LocalExecutor, TaskFailed, make_executor


def seeded_work(task):
    seed, n = task
    return float(np.random.default_rng(seed).normal(size=n).sum())


def die_once(task):
    """Kill the worker process the first time a task runs (a marker file remembers)."""
    marker, value = task
    if not os.path.exists(marker):
        Path(marker).write_text("died")
        os._exit(17)
    return value * 2


def always_die(task):
    os._exit(3)


def raises(task):
    raise ValueError(f"bad task {task}")


TASKS = [(s, 100) for s in range(6)]


def test_local_serial_and_pool_agree():
    serial = LocalExecutor(workers=1, progress=False).map(seeded_work, TASKS)
    pooled = LocalExecutor(workers=2, progress=False).map(seeded_work, TASKS)
    assert serial == pooled == [seeded_work(t) for t in TASKS]


def test_local_worker_death_is_retried(tmp_path):
    tasks = [(str(tmp_path / f"m{i}"), i) for i in range(4)]
    assert LocalExecutor(workers=2, progress=False).map(die_once, tasks) == [0, 2, 4, 6]


def test_local_worker_that_always_dies_is_reported():
    with pytest.raises(TaskFailed, match="died 2 times when run alone"):
        LocalExecutor(workers=2, retries=1, progress=False).map(always_die, [1, 2])


def test_task_error_names_the_task():
    with pytest.raises(TaskFailed, match="task 0 .*bad task 7"):
        LocalExecutor(workers=1, progress=False).map(raises, [7])
    with pytest.raises(TaskFailed, match="bad task 7"):
        LocalExecutor(workers=2, progress=False).map(raises, [7])


def test_unknown_executor():
    with pytest.raises(ValueError, match="--executor must be 'local' or 'ray'"):
        make_executor("dask")


def test_ray_gives_the_local_results(ray_local):
    assert make_executor("ray", progress=False).map(seeded_work, TASKS) == [seeded_work(t) for t in TASKS]


def test_ray_retries_a_dead_worker(ray_local, tmp_path):
    tasks = [(str(tmp_path / f"r{i}"), i) for i in range(3)]
    assert make_executor("ray", progress=False).map(die_once, tasks) == [0, 2, 4]


def test_ray_reports_a_worker_that_always_dies(ray_local):
    with pytest.raises(TaskFailed, match="worker died"):
        make_executor("ray", retries=1, progress=False).map(always_die, [1])
