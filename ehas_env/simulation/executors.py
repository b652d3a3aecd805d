"""Where work runs: local processes (default) or a Ray cluster.

One small abstraction used by ``ehas bench``, ``ehas tune --method optimize``
and ``ehas train --sweep``: an executor maps a picklable function over a list
of tasks and returns the results **in task order**, so the driver (the only
process that writes files) gets the same numbers wherever the work ran, as long
as every task carries its own seed.  A task whose worker dies is retried up to
``retries`` times; after that the run stops with an error naming the task,
never with a silently shorter result set.

Examples
--------
>>> ex = make_executor("local", workers=1)
>>> ex.map(abs, [-1, 2, -3])
[1, 2, 3]
"""
from __future__ import annotations

import concurrent.futures as cf
import inspect
import os
from dataclasses import dataclass
from typing import Callable, Sequence


#: seconds between redraws of the progress bar while no task ends (a task can run for minutes)
REFRESH_S = 5.0


class TaskFailed(RuntimeError):
    """A task failed on every attempt (or raised an error in its own code)."""


def _progress(total: int, desc: str, enabled: bool):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, disable=not enabled or total <= 1, leave=False)


@dataclass
class LocalExecutor:
    """Runs tasks in this process (``workers=1``) or in a pool of local processes.

    Parameters
    ----------
    workers : int
        Processes to use; 1 runs serially in the calling process (no pickling).
    retries : int
        Attempts after the first for a task whose worker process died.
    """

    workers: int = 1
    retries: int = 2
    progress: bool = True
    name: str = "local"

    def map(self, fn: Callable, tasks: Sequence, desc: str = "tasks") -> list:
        tasks = list(tasks)
        results: dict[int, object] = {}
        with _progress(len(tasks), desc, self.progress) as bar:
            if self.workers <= 1:
                for i, task in enumerate(tasks):
                    results[i] = _call(fn, task, i)
                    bar.update()
            else:
                pending = list(range(len(tasks)))
                while pending:
                    broken = self._round(fn, tasks, pending, self.workers, results, bar)
                    if len(broken) == len(pending):
                        # no progress: run each survivor alone to find the task that kills its worker
                        for i in broken:
                            self._isolated(fn, tasks, i, results, bar)
                        broken = []
                    pending = broken
        return [results[i] for i in range(len(tasks))]

    @staticmethod
    def _round(fn, tasks, indices, workers, results, bar) -> list[int]:
        """Run ``indices`` in one pool; return those lost to a dead worker."""
        broken = []
        with cf.ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(_call, fn, tasks[i], i): i for i in indices}
            pending = set(futures)
            while pending:
                # wake every few seconds to redraw the bar (its elapsed time): never silent while a long task runs
                done, pending = cf.wait(pending, timeout=REFRESH_S, return_when=cf.FIRST_COMPLETED)
                bar.refresh()
                for fut in done:
                    i = futures[fut]
                    try:
                        results[i] = fut.result()
                        bar.update()
                    except cf.process.BrokenProcessPool:
                        broken.append(i)
        return sorted(broken)

    def _isolated(self, fn, tasks, i, results, bar) -> None:
        for _ in range(self.retries + 1):
            if not self._round(fn, tasks, [i], 1, results, bar):
                return
        raise TaskFailed(f"task {i} ({_label(tasks[i])}): its worker process died {self.retries + 1} times "
                         f"when run alone; giving up (retries={self.retries})")


def _call(fn, task, i):
    """Run one task; its own exception becomes TaskFailed naming the task (no retry)."""
    try:
        return fn(task)
    except Exception as exc:
        raise TaskFailed(f"task {i} ({_label(task)}) raised {type(exc).__name__}: {exc}") from exc


@dataclass
class RayExecutor:
    """Runs tasks as Ray tasks on a cluster (``address``) or a local Ray instance.

    Parameters
    ----------
    address : str or None
        ``"auto"`` joins the running cluster (``ray start --head`` / a Ray job),
        an explicit ``"ray://host:10001"`` or ``"host:6379"`` joins that one, and
        None starts a local Ray instance with ``num_cpus``.
    num_cpus : int or None
        CPUs of the local instance (ignored when joining a cluster).
    retries : int
        Ray's own re-execution of a task whose worker died (``max_retries``).
    """

    address: str | None = None
    num_cpus: int | None = None
    retries: int = 2
    progress: bool = True
    name: str = "ray"

    def _init(self):
        try:
            import ray
        except ModuleNotFoundError:
            raise ValueError("--executor ray needs Ray: pip install 'ehas[ray]' (or pip install 'ray[tune]')") from None
        if not ray.is_initialized():
            kwargs = {"ignore_reinit_error": True, "include_dashboard": False, "log_to_driver": False}
            if self.address:
                ray.init(address=self.address, **kwargs)
            else:
                ray.init(num_cpus=self.num_cpus or os.cpu_count(), **kwargs)
        return ray

    def map(self, fn: Callable, tasks: Sequence, desc: str = "tasks") -> list:
        ray = self._init()
        tasks = list(tasks)
        opts = dict(max_retries=self.retries, retry_exceptions=False)
        if inspect.isfunction(fn):
            remote = ray.remote(**opts)(fn)
            refs = [remote.remote(t) for t in tasks]
        else:  # ray.remote takes only functions: partials and callable objects go through a trampoline
            remote = ray.remote(**opts)(_apply)
            fn_ref = ray.put(fn)
            refs = [remote.remote(fn_ref, t) for t in tasks]
        index = {ref: i for i, ref in enumerate(refs)}
        results: dict[int, object] = {}
        remaining = list(refs)
        with _progress(len(tasks), desc, self.progress) as bar:
            while remaining:
                done, remaining = ray.wait(remaining, num_returns=1, timeout=REFRESH_S)
                bar.refresh()  # its elapsed time, every few seconds while a long task runs
                for ref in done:
                    i = index[ref]
                    try:
                        results[i] = ray.get(ref)
                    except ray.exceptions.RayTaskError as exc:
                        raise TaskFailed(f"task {i} ({_label(tasks[i])}) raised: {exc.cause!r}") from exc
                    except (ray.exceptions.WorkerCrashedError, ray.exceptions.NodeDiedError) as exc:
                        raise TaskFailed(f"task {i} ({_label(tasks[i])}): its worker died {self.retries + 1} times; "
                                         "giving up") from exc
                    bar.update()
        return [results[i] for i in range(len(tasks))]


def make_executor(kind: str = "local", *, workers: int | None = None, address: str | None = None,
                  retries: int = 2, progress: bool = True):
    """Executor by name: ``"local"`` (processes) or ``"ray"``."""
    if kind == "local":
        return LocalExecutor(workers=workers if workers is not None else 1, retries=retries, progress=progress)
    if kind == "ray":
        return RayExecutor(address=address, num_cpus=workers, retries=retries, progress=progress)
    raise ValueError(f"--executor must be 'local' or 'ray', got {kind!r}")


def add_executor_arguments(parser) -> None:
    """The command-line options every sweeping command shares."""
    parser.add_argument("--executor", choices=("local", "ray"), default="local",
                        help="where the work runs: local processes (default) or a Ray cluster")
    from ehas_env.ranges import option

    parser.add_argument("--workers", type=option("--workers", "workers"), default=None,
                        help="local: worker processes (default 1 = in-process); ray: CPUs of a local Ray instance")
    parser.add_argument("--address", default=None,
                        help="Ray cluster address ('auto' joins a running cluster; default: start a local instance)")


def executor_from_args(args):
    """The executor :func:`add_executor_arguments`' options ask for (``--no-progress`` is honoured)."""
    return make_executor(getattr(args, "executor", "local"), workers=getattr(args, "workers", None),
                         address=getattr(args, "address", None), progress=not getattr(args, "no_progress", False))


def _apply(fn, task):
    return fn(task)


def _label(task) -> str:
    text = repr(task)
    return text if len(text) <= 80 else text[:77] + "..."
