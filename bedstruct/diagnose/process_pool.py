"""Engine-simulator calls in worker processes (``[engine] jobs = N``).

A diagnosis or its validation asks for many independent engine calls at once: every
parameter point times every replicate seed of the fingerprints, the replicate reruns
of "how far". :meth:`EngineSimulator.prefetch <bedstruct.diagnose.engine_simulator.EngineSimulator.prefetch>`
hands the calls it has not got to :func:`run_calls`, which runs them ``jobs`` at a time,
one engine call per process (each single-threaded engine run then has a core to itself),
and returns their observations; with a cache each worker also stores its call there, so
an interrupted batch keeps every finished call.

Workers are started with ``spawn`` (a forked copy of a process whose numba threading
layer is running may deadlock); they load the compiled kernels from numba's cache. A
worker whose parent is gone (killed, not interrupted) stops within seconds instead of
finishing an engine run nobody will read.

.. versionadded:: 0.1
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Callable, Sequence

__all__ = ["run_calls"]


def _exit_with_parent(parent: int, interval: float = 2.0) -> None:
    """Worker initializer: exit when the parent process ``parent`` is gone."""
    import os
    import threading
    import time

    def watch():
        while True:
            time.sleep(interval)
            if os.getppid() != parent:
                os._exit(1)
    threading.Thread(target=watch, name="bedstruct-parent-watch", daemon=True).start()


def _init_worker(parent: int, ignore_interrupt: bool = False) -> None:
    """Worker initializer: exit with the parent process ``parent``
    (:func:`_exit_with_parent`) and, with ``ignore_interrupt``, ignore Ctrl-C (SIGINT),
    which a terminal sends to every process of the group: the parent then decides
    whether the runs in flight finish."""
    _exit_with_parent(parent)
    if ignore_interrupt:
        import signal
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_calls(worker: Callable, calls: Sequence[tuple], jobs: int, *, progress: bool = False):
    """Run ``worker(*args)`` for each ``args`` of ``calls`` in ``jobs`` worker processes.

    Parameters
    ----------
    worker : callable
        A module-level function (it is pickled into the ``spawn``-ed processes), e.g.
        :func:`bedstruct.diagnose.engine_simulator.engine_call`.
    calls : sequence of tuple
        The arguments of each call.
    jobs : int
        Number of worker processes (at most one per call).
    progress : bool
        Show a progress bar over the finished calls (stderr).

    Returns
    -------
    list
        The worker's result of each call, in order.
    """
    if not calls:
        return []
    ctx = multiprocessing.get_context("spawn")
    workers = max(1, min(int(jobs), len(calls)))
    import os
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                               initializer=_exit_with_parent, initargs=(os.getpid(),))
    try:
        futures = [pool.submit(worker, *args) for args in calls]
        done = as_completed(futures)
        if progress:
            from tqdm import tqdm
            done = tqdm(done, total=len(futures), desc=f"engine calls ({workers} processes)")
        for f in done:
            f.result()  # the first failed call stops the batch, with its error
        results = [f.result() for f in futures]
    except BaseException:
        # a failure or Ctrl-C: the queued calls are dropped instead of run to the end (hours);
        # the calls already running finish and, with a cache, are kept
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return results
