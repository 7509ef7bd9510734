"""Twins of a validation run side by side, one process per twin.

A twin at the ``small`` engine preset is a chain of a dozen or more engine calls, each
depending on the last (its sizing node, its repeated experiments, the refinement node, the
reruns), from a quarter of an hour to hours on one core. ``jobs`` in the ``[engine]`` table
spreads the calls of one batch (the replicate seeds of one point: three) over processes;
``twin_jobs`` spreads whole twins, so that N cores stay busy: each worker runs one twin
(:func:`~bedstruct.diagnose.validate.validate` with ``shard=(i, n_twins)``, the twin's
magnitude and truth runs those of the whole plan) and takes the next when it finishes.

The fingerprints are computed once, before the twins, in the calling process (its calls
spread by ``jobs``); the workers read them back from the engine cache, which ``twin_jobs``
therefore requires on the engine. Each worker appends its twin's records to a file of its
own; they are merged into ``records`` as each twin finishes, so an interrupted run resumes
from there as a serial one does.

.. versionadded:: 0.1
"""

from __future__ import annotations

import json
import logging
import multiprocessing
import os
import tempfile
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

log = logging.getLogger(__name__)

__all__ = ["run_twins_in_processes"]


def _one_twin(kwargs: dict, index: int, n_twins: int, part: str) -> tuple[int, str]:
    """Worker: run twin ``index`` alone (records appended to ``part``)."""
    from .validate import validate
    kw = dict(kwargs)
    engine = kw.get("engine")
    if engine:
        # one twin per process already: its calls run in it, one after the other
        kw["engine"] = dict(engine, jobs=1)
    validate(**kw, shard=(index, n_twins), records=part, progress=False)
    return index, part


def run_twins_in_processes(kwargs: dict, twins: list[int], n_twins: int, records, jobs: int, *,
                           progress: bool = False) -> int:
    """Run the plan's twins ``twins`` in ``jobs`` worker processes; their records into ``records``.

    Parameters
    ----------
    kwargs : dict
        The arguments of :func:`~bedstruct.diagnose.validate.validate` that define the
        validation (preset, seeds, statistics settings, simulator and engine table), without
        ``shard``, ``records``, ``records_only``, ``twin_jobs`` and ``progress``.
    twins : list of int
        Indices of the twins to run (the plan's, not yet recorded).
    n_twins : int
        Length of the whole plan.
    records : path
        JSON-lines file the finished twins' records are appended to.
    jobs : int
        Worker processes.
    progress : bool
        A bar over the finished twins.

    Returns
    -------
    int
        The number of twins run.
    """
    if not twins:
        return 0
    records = Path(records)
    workers = max(1, min(int(jobs), len(twins)))
    ctx = multiprocessing.get_context("spawn")
    from ..workflows.diagnosis_pool import _exit_with_parent
    with tempfile.TemporaryDirectory(prefix="bedstruct-twin-records-",
                                     dir=records.parent) as tmp:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                   initializer=_exit_with_parent, initargs=(os.getpid(),))
        futures = []
        try:
            futures = [pool.submit(_one_twin, kwargs, i, n_twins, str(Path(tmp) / f"twin{i}.jsonl"))
                       for i in twins]
            done = as_completed(futures)
            if progress:
                from tqdm import tqdm
                done = tqdm(done, total=len(futures), desc=f"twins ({workers} processes)")
            for f in done:
                i, part = f.result()   # the first failed twin stops the run, with its error
                _append(Path(part), records)
        except BaseException:
            # A failed twin or Ctrl-C: the queued twins are dropped and the running ones
            # stopped (a twin runs for hours; the engine calls it finished are in the cache,
            # so running it again costs only the call it was in). Twins that finished keep
            # their records.
            procs = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in procs:
                proc.terminate()
            for proc in procs:
                proc.join(timeout=30)
            for f in futures:
                if f.done() and not f.cancelled() and f.exception() is None:
                    _append(Path(f.result()[1]), records)
            raise
        pool.shutdown(wait=True)
    return len(twins)


def _append(part: Path, records: Path) -> None:
    """Append a finished twin's records (whole lines) to ``records`` once."""
    if not part.exists():
        return
    lines = [ln for ln in part.read_text(encoding="utf-8").splitlines() if ln.strip()]
    for ln in lines:
        json.loads(ln)  # a worker writes whole records; anything else is a bug, not data
    if lines:
        with open(records, "a", encoding="utf-8") as fh:
            fh.write("".join(ln + "\n" for ln in lines))
    part.unlink()
