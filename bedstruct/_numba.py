"""The one place that decides how numba kernels are compiled and threaded.

Kernels import ``njit``, ``njit_parallel`` and ``prange`` from here so that
compilation options are uniform: ``cache=True`` (compiled once per machine),
``fastmath`` off by default for reproducible reductions, ``error_model='numpy'``
so that divisions never raise inside hot loops.
"""

from __future__ import annotations

import os

import numba
from numba import prange

__all__ = ["njit", "njit_parallel", "prange", "set_num_threads", "get_num_threads",
           "THREADING_LAYER_PRIORITY"]

#: Numba threading layers in bedstruct's order of preference. TBB comes last: with the TBB
#: layer a process that ran a parallel kernel from a thread other than the main one can hang
#: at exit in TBB's finalisation (numba issue 10556; seen here as a test run that printed its
#: summary and never exited). A user's ``NUMBA_THREADING_LAYER`` or
#: ``NUMBA_THREADING_LAYER_PRIORITY`` is left as it is.
THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]
if not (os.environ.get("NUMBA_THREADING_LAYER", "default") != "default"
        or "NUMBA_THREADING_LAYER_PRIORITY" in os.environ):
    numba.config.THREADING_LAYER_PRIORITY = list(THREADING_LAYER_PRIORITY)

_BASE = dict(cache=True, error_model="numpy", boundscheck=False, nogil=True)


def njit(*args, **kwargs):
    """``numba.njit`` with bedstruct's defaults (cached, numpy error model)."""
    opts = dict(_BASE)
    opts.update(kwargs)
    if args and callable(args[0]):
        return numba.njit(**opts)(args[0])
    return numba.njit(*args, **opts)


def njit_parallel(*args, **kwargs):
    """Like :func:`njit` with ``parallel=True`` (use ``prange`` inside)."""
    kwargs.setdefault("parallel", True)
    return njit(*args, **kwargs)


def set_num_threads(n: int) -> None:
    """Set the number of threads numba's parallel kernels use."""
    numba.set_num_threads(int(n))


def get_num_threads() -> int:
    """Number of threads numba's parallel kernels use now."""
    return int(numba.get_num_threads())
