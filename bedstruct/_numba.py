"""The one place that decides how numba kernels are compiled and threaded.

Kernels import ``njit``, ``njit_parallel`` and ``prange`` from here so that
compilation options are uniform: ``cache=True`` (compiled once per machine),
``fastmath`` off by default for reproducible reductions, ``error_model='numpy'``
so that divisions never raise inside hot loops.

numba keys a cached kernel on the file that defines it, not on the files whose
functions it compiles in (the contact pieces of ``dem/_kernels_contact.py`` are
compiled into the pair and integrator kernels). So that a cache is never reused
stale, the compiled kernels go to a folder named by a hash of every bedstruct
source file that uses numba and of the numba version
(``$XDG_CACHE_HOME/bedstruct/numba/<hash>``, :data:`CACHE_DIR`), unless
``NUMBA_CACHE_DIR`` says where.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba
from numba import prange

__all__ = ["njit", "njit_parallel", "prange", "set_num_threads", "get_num_threads",
           "THREADING_LAYER_PRIORITY", "CACHE_DIR", "kernel_source_hash", "source_hash"]

#: Numba threading layers in bedstruct's order of preference. TBB comes last: with the TBB
#: layer a process that ran a parallel kernel from a thread other than the main one can hang
#: at exit in TBB's finalisation (numba issue 10556; seen here as a test run that printed its
#: summary and never exited). A user's ``NUMBA_THREADING_LAYER`` or
#: ``NUMBA_THREADING_LAYER_PRIORITY`` is left as it is.
THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]
if not (os.environ.get("NUMBA_THREADING_LAYER", "default") != "default"
        or "NUMBA_THREADING_LAYER_PRIORITY" in os.environ):
    numba.config.THREADING_LAYER_PRIORITY = list(THREADING_LAYER_PRIORITY)


def source_hash(parts=("",), *, root=None, suffixes=(".py",), keep=None, salt: bytes = b"") -> str:
    """SHA-256 (16 hex digits) of the source files of ``parts`` of the package.

    Each part is a path relative to ``root`` (default: the bedstruct package): a folder
    stands for the files under it whose names end in one of ``suffixes`` (sorted), a file
    for itself. Each file's relative path and bytes are hashed, after ``salt``; ``keep``
    (a function of the bytes) leaves out the files it says no to. It names the numba cache
    folder (:func:`kernel_source_hash`) and the code a workflow run was made by.
    """
    root = Path(__file__).resolve().parent if root is None else Path(root)
    h = hashlib.sha256(salt)
    for part in parts:
        p = root / part
        files = sorted(f for f in p.rglob("*") if f.suffix in suffixes and f.is_file()
                       and "__pycache__" not in f.parts) if p.is_dir() else [p]
        for f in files:
            data = f.read_bytes()
            if keep is None or keep(data):
                h.update(f.relative_to(root).as_posix().encode() + b"\0")
                h.update(data + b"\0")
    return h.hexdigest()[:16]


def kernel_source_hash(root=None) -> str:
    """Hash of the numba version and of every source file under ``root`` that uses numba.

    ``root`` defaults to the bedstruct package.
    """
    return source_hash(root=root, salt=numba.__version__.encode(),
                       keep=lambda data: b"numba" in data or b"njit" in data)


def _cache_dir() -> str | None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "bedstruct" / "numba"
    folder = base / kernel_source_hash()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:  # no writable cache home: numba's own place beside the sources
        return None
    numba.config.CACHE_DIR = str(folder)
    return str(folder)


#: Where compiled kernels are cached (None: numba's ``__pycache__`` beside the sources).
CACHE_DIR = _cache_dir()

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
