"""Status lines and progress bars on stderr, so that no long command is silent.

Every command that can take more than about 2 s says what it is doing on stderr
as soon as it starts (stdout stays for results, so ``ehas ... > file`` keeps a
clean file), and then either advances a progress bar (:func:`bar`, tqdm) or,
for a step of unknown length, repeats its status line with the time elapsed
(:func:`working`).  ``EHAS_QUIET=1`` in the environment silences both.

Examples
--------
>>> with working("fitting", "compare", interval=60):
...     pass
>>> [x for x in bar(range(3), desc="runs", disable=True)]
[0, 1, 2]
"""
from __future__ import annotations

import os
import sys
import threading
import time
from contextlib import contextmanager


def quiet() -> bool:
    """True when ``EHAS_QUIET`` is set to anything but ``""``/``0``."""
    return os.environ.get("EHAS_QUIET", "") not in ("", "0")


def status(message: str, prefix: str = "ehas") -> None:
    """One line on stderr, flushed at once: ``[prefix] message``."""
    if quiet():
        return
    try:
        sys.stderr.write(f"[{prefix}] {message}\n")  # one write: lines from threads side by side never run together
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):  # stderr closed: nobody to tell
        pass


@contextmanager
def working(what: str, prefix: str = "ehas", interval: float = 10.0):
    """Say ``what ...`` now, repeat it with the elapsed time every ``interval`` s, and say when it is done.

    For steps whose length is not known in advance (a fit, compiling the
    simulator); use :func:`bar` where the steps can be counted.
    """
    t0 = time.perf_counter()
    status(f"{what} ...", prefix)
    done = threading.Event()

    def beat():
        while not done.wait(interval):
            status(f"{what} ... {time.perf_counter() - t0:.0f} s", prefix)

    thread = threading.Thread(target=beat, name=f"ehas-status-{prefix}", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join(timeout=1.0)
    status(f"{what}: done in {time.perf_counter() - t0:.1f} s", prefix)


def bar(iterable=None, *, total=None, desc: str = "", unit: str = "it", disable: bool = False, leave: bool = False):
    """A tqdm progress bar on stderr (disabled by ``disable`` or ``EHAS_QUIET``)."""
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, disable=disable or quiet(), leave=leave,
                file=sys.stderr, mininterval=0.5, dynamic_ncols=True)
