"""Twins of a validation run side by side, one process per twin.

A twin at the ``small`` engine preset is a chain of a dozen or more engine calls, each
depending on the last (its sizing node, its repeated experiments, the refinement node, the
reruns), from a quarter of an hour to hours on one core. ``jobs`` in the ``[engine]`` table
spreads the calls of one batch (the replicate seeds of one point: three) over processes;
``twin_jobs`` spreads whole twins, so that N cores stay busy: each worker runs one twin
(:func:`~bedstruct.diagnose.validation.validate.validate` with ``shard=(i, n_twins)``, the twin's
magnitude and truth runs those of the whole plan) and takes the next when it finishes.

The fingerprints are computed once, before the twins, in the calling process (its calls
spread by ``jobs``); the workers read them back from the engine cache, which ``twin_jobs``
therefore requires on the engine. Each worker appends its twin's records to a file of its
own, started with what ``records`` already holds of that twin (a twin cut short between
its two diagnoses resumes with the second); they are merged into ``records`` as each twin
finishes, so an interrupted run resumes from there as a serial one does.

.. versionadded:: 0.1
"""

from __future__ import annotations

import json
import logging
import multiprocessing
import os
import tempfile
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, as_completed, wait
from pathlib import Path
from typing import Callable

from ..process_pool import _exit_with_parent

log = logging.getLogger(__name__)

__all__ = ["run_twins_in_processes"]

#: a worker's status line of its twin sits beside the twin's records file, with this suffix
_STATUS = ".status"
#: seconds between looks at the running twins' status lines (with a progress bar)
_POLL_S = 10.0


def _one_twin(validate: Callable, kwargs: dict, index: int, n_twins: int,
              part: str) -> tuple[int, str]:
    """Worker: run twin ``index`` alone with ``validate`` (records appended to ``part``, its
    status line written to ``part`` + ``.status`` as it changes)."""
    kw = dict(kwargs)
    engine = kw.get("engine")
    if engine:
        # one twin per process already: its calls run in it, one after the other
        kw["engine"] = dict(engine, jobs=1)
    status = Path(part + _STATUS)

    def report(text: str) -> None:
        tmp = status.with_name(status.name + f".{os.getpid()}")
        try:
            tmp.write_text(text, encoding="utf-8")
            os.replace(tmp, status)   # the parent never reads half a line
        except OSError as exc:   # a status line is not worth an hours-long twin
            log.debug("twin %d: status line not written: %s", index, exc)
    validate(**kw, shard=(index, n_twins), records=part, progress=False, on_status=report)
    return index, part


def run_twins_in_processes(validate: Callable, kwargs: dict, twins: list[int], n_twins: int,
                           records, jobs: int, *, progress: bool = False) -> int:
    """Run the plan's twins ``twins`` in ``jobs`` worker processes; their records into ``records``.

    Parameters
    ----------
    validate : callable
        :func:`~bedstruct.diagnose.validation.validate.validate` (passed in: a module-level function, so
        that the workers unpickle it by name), called with ``kwargs`` and ``shard=(i, n)``.
    kwargs : dict
        The arguments of :func:`~bedstruct.diagnose.validation.validate.validate` that define the
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
        A bar over the finished twins, with the running twins' status beside it (each
        worker's twin and the engine calls it has run so far).

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
    with tempfile.TemporaryDirectory(prefix="bedstruct-twin-records-",
                                     dir=records.parent) as tmp:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                   initializer=_exit_with_parent, initargs=(os.getpid(),))
        futures = []
        try:
            paths = {i: str(Path(tmp) / f"twin{i}.jsonl") for i in twins}
            _seed_parts(paths, records)
            parts = {pool.submit(_one_twin, validate, kwargs, i, n_twins, p): p for i, p in paths.items()}
            futures = list(parts)
            if progress:
                _wait_with_bar(parts, workers, records)
            else:
                for f in as_completed(futures):
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


def _wait_with_bar(parts: dict, workers: int, records: Path) -> None:
    """Merge finished twins' records as they come (``parts``: future -> its records file),
    with a bar over the twins whose postfix shows what each running twin has done so far
    (its worker's status line)."""
    from tqdm import tqdm
    pending = set(parts)
    with tqdm(total=len(parts), desc=f"twins ({workers} processes)") as bar:
        while pending:
            finished, pending = wait(pending, timeout=_POLL_S, return_when=FIRST_COMPLETED)
            for f in finished:
                i, part = f.result()   # the first failed twin stops the run, with its error
                _append(Path(part), records)
                bar.update(1)
            lines = (_read_status(parts[f]) for f in pending if f.running())
            bar.set_postfix_str(" | ".join(x for x in lines if x), refresh=True)


def _read_status(part: str) -> str:
    """The running twin's status line ('' before its worker wrote one)."""
    try:
        return Path(part + _STATUS).read_text(encoding="utf-8").strip()
    except OSError:
        return ""


def _seed_parts(paths: dict, records: Path) -> None:
    """Start each twin's records file (``paths``: twin index -> file) with the lines
    ``records`` holds of that twin, so that its worker resumes it (an engine effect twin
    whose attribution finished before an interruption runs only its withheld diagnosis)."""
    if not records.exists():
        return
    seeded = {i: [] for i in paths}
    for ln in records.read_text(encoding="utf-8").splitlines():
        try:
            rec = json.loads(ln)
        except ValueError:
            continue   # the resume reads the records first and names a damaged line
        i = rec.get("twin") if isinstance(rec, dict) else None
        if isinstance(i, int) and i in seeded:
            seeded[i].append(ln + "\n")
    for i, lines in seeded.items():
        if lines:
            Path(paths[i]).write_text("".join(lines), encoding="utf-8")


def _append(part: Path, records: Path) -> None:
    """Append a finished twin's records (whole lines) to ``records`` once: lines it
    already holds (those its file was started with) are not written again."""
    if not part.exists():
        return
    lines = [ln for ln in part.read_text(encoding="utf-8").splitlines() if ln.strip()]
    for ln in lines:
        json.loads(ln)  # a worker writes whole records; anything else is a bug, not data
    if lines and records.exists():
        have = set(records.read_text(encoding="utf-8").splitlines())
        lines = [ln for ln in lines if ln not in have]
    if lines:
        with open(records, "a", encoding="utf-8") as fh:
            fh.write("".join(ln + "\n" for ln in lines))
    part.unlink()
    part.with_name(part.name + _STATUS).unlink(missing_ok=True)
