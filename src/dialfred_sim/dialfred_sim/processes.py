"""Worker processes that never outlive the process that started them (no ROS).

A pool's workers are daemonic, but that only ends them when their parent exits normally: a parent
killed with SIGTERM or SIGKILL (a `kill PID` of a long render or evaluation) leaves them running, still
writing into the run's files while a resumed run writes there too. Every pool here starts its workers
with `watch_parent`: a thread that ends the worker once its parent is gone.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Optional

PARENT_POLL_S = 0.25


def watch_parent(poll_s: float = PARENT_POLL_S, grace_s: float = 0.0) -> None:
    """In a worker: end this process (exit status 143, as SIGTERM) within `poll_s` seconds of its parent's
    death (the worker is then re-parented, so its parent id changes), or `grace_s` seconds after it: time
    to end in its own way first (a node told by SIGTERM)."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll_s)
        time.sleep(grace_s)
        os._exit(143)

    threading.Thread(target=watch, name='watch-parent', daemon=True).start()


def _start_worker(initializer: Optional[Callable], initargs: tuple) -> None:
    watch_parent()
    if initializer is not None:
        initializer(*initargs)


def worker_pool(workers: int, initializer: Optional[Callable] = None, initargs: tuple = (),
                maxtasksperchild: Optional[int] = None):
    """A `multiprocessing` Pool of `workers` spawned processes (fresh interpreters: no state forked from
    this one) that end when this process dies."""
    return multiprocessing.get_context('spawn').Pool(workers, initializer=_start_worker,
                                                     initargs=(initializer, initargs),
                                                     maxtasksperchild=maxtasksperchild)


def worker_executor(workers: int, initializer: Optional[Callable] = None, initargs: tuple = ()) -> ProcessPoolExecutor:
    """The same as a `concurrent.futures` executor."""
    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context('spawn'), initializer=_start_worker,
                               initargs=(initializer, initargs))
