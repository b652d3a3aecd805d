"""Fits of independent candidates run side by side on threads (issue 44, point 2).

A screen is a short least-squares fit: one replay of the campaign a step (the secant Jacobian), then its own
linear algebra.  One replay spreads the campaign's runs over the replay threads
(:meth:`~ehas_env.measurement.replay.Replayer.simulate_many`), but a campaign of four runs of 3 s and a short valve
chirp keeps two cores busy for about 0.65 of its time, and between replays the fit's own work runs on one.  Two
screens at once fill those gaps: their replays share the replay threads, whose compiled runs release the GIL.

Each candidate's fit depends on its own inputs alone (the replays are deterministic, the linear algebra runs on one
BLAS thread: :func:`~ehas_env.diagnosis.fitting.one_blas_thread`), so the results are the candidates' results one
after the other, in their order; only the progress lines may interleave.  A Ctrl-C sets
:data:`~ehas_env.measurement.replay.STOP`: every thread ends at its next replay and the interrupt goes on.
"""
from __future__ import annotations

import contextvars
import signal
import threading

from ehas_env.measurement.replay import STOP, own_rests

#: candidates fitted at once: two keep the replay threads of two cores busy while one of them does its own step
SCREEN_WORKERS = 2


def side_by_side(fn, items, workers: int | None = None) -> list:
    """``[fn(x) for x in items]``, the calls run on ``workers`` threads at once (default :data:`SCREEN_WORKERS`).

    Parameters
    ----------
    fn : callable
        One candidate's work; it must not depend on another call's (each reads only its own argument and shared
        state it does not change).
    items : iterable
        The arguments, in order.
    workers : int, optional
        Threads; 1 runs the calls one after the other in this thread.

    Returns
    -------
    list
        The results in the order of ``items``.  The first call (in that order) that raised re-raises here, once
        the others have ended.

    Examples
    --------
    >>> side_by_side(lambda x: x * x, [1, 2, 3])
    [1, 4, 9]
    """
    items = list(items)
    n = min(SCREEN_WORKERS if workers is None else int(workers), len(items))
    # each call in the caller's context, its kept replays its own (own_rests): what it replays and counts never
    # depends on which call came first, on one thread or on many
    contexts = [contextvars.copy_context() for _ in items]

    def call(k):
        with own_rests():
            return fn(items[k])

    if n <= 1:
        return [contexts[k].run(call, k) for k in range(len(items))]
    results, errors, lock, order = [None] * len(items), {}, threading.Lock(), iter(range(len(items)))

    def worker():
        while not STOP.is_set():
            with lock:
                k = next(order, None)
            if k is None:
                return
            try:
                results[k] = contexts[k].run(call, k)
            except BaseException as e:  # noqa: BLE001 -- re-raised in the calling thread
                errors[k] = e

    threads = [threading.Thread(target=worker, name=f"ehas-screen-{j}", daemon=True) for j in range(n)]
    # a Ctrl-C while the threads start would leave one running that nothing waits for: held until they have
    held = []
    main = threading.current_thread() is threading.main_thread()
    before = signal.signal(signal.SIGINT, lambda *_: held.append(1)) if main else None
    try:
        for t in threads:
            t.start()
    finally:
        if main:
            signal.signal(signal.SIGINT, before)
    try:
        if held:
            raise KeyboardInterrupt
        for t in threads:
            while t.is_alive():
                t.join(0.1)  # a timed join lets a Ctrl-C through
    except KeyboardInterrupt:
        STOP.set()  # the calls not begun never do; each one running ends at its next replay (ReplaysStopped)
        for t in threads:
            t.join()
        raise
    finally:
        STOP.clear()
    if errors:
        raise errors[min(errors)]
    return results
