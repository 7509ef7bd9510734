"""bedstruct's numba kernels: no TBB threading layer (a process could hang at exit), no stale cache."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

SCRIPT = """
import threading
import numpy as np
import numba
from bedstruct._numba import njit_parallel, prange

@njit_parallel(cache=False)
def total(a):
    s = 0.0
    for i in prange(a.size):
        s += a[i]
    return s

def worker():
    assert total(np.ones(100_000)) == 100_000.0

# a parallel kernel run from a thread other than the main one: with the TBB layer the
# process could hang at exit (numba issue 10556)
t = threading.Thread(target=worker)
t.start()
t.join()
print(numba.threading_layer())
"""


def _run(env_extra):
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_THREADING_LAYER")}
    env.update(env_extra, NUMBA_NUM_THREADS="2")
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                         timeout=300, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.split()[-1]


def test_parallel_kernels_do_not_use_tbb_and_the_process_exits():
    assert _run({}) in ("omp", "workqueue")


def test_a_users_threading_layer_choice_is_kept():
    assert _run({"NUMBA_THREADING_LAYER_PRIORITY": "workqueue omp tbb"}) == "workqueue"


def test_the_kernel_cache_is_keyed_by_every_kernel_source(tmp_path):
    # numba keys a kernel on its own file only; bedstruct's cache folder changes with any
    # file that uses numba (a contact piece compiled into another file's kernel), not others
    from bedstruct import _numba

    (tmp_path / "contact.py").write_text("from numba import njit\n@njit\ndef f(x):\n    return x\n")
    (tmp_path / "pairs.py").write_text("from .._numba import njit\n")
    (tmp_path / "docs.py").write_text("X = 1\n")
    first = _numba.kernel_source_hash(tmp_path)
    (tmp_path / "docs.py").write_text("X = 2\n")
    assert _numba.kernel_source_hash(tmp_path) == first
    (tmp_path / "contact.py").write_text("from numba import njit\n@njit\ndef f(x):\n    return 2 * x\n")
    assert _numba.kernel_source_hash(tmp_path) != first
    if not os.environ.get("NUMBA_CACHE_DIR") and _numba.CACHE_DIR is not None:
        assert pathlib.Path(_numba.CACHE_DIR).name == _numba.kernel_source_hash()
