"""Numba kernels that put the rows of a parsed dump block in id order.

A dump lists its atoms in whatever order the engine's processors wrote them;
a :class:`~bedstruct.Frame` holds them sorted by id. These kernels read the id
column as integers (:func:`integer_column`), find the sorting order in one
counting pass when the ids are a run of consecutive integers
(:func:`consecutive_order`), and apply an order to a block of rows, in place
(:func:`permute_rows`) or while selecting columns (:func:`gather_rows`).
The numbers themselves are parsed by :mod:`bedstruct.io._kernels`.
"""

from __future__ import annotations

import numpy as np

from .._numba import njit, njit_parallel, prange

__all__ = ["integer_column", "consecutive_order", "permute_rows", "gather_rows"]

_U1 = np.uint64(1)


@njit
def integer_column(flat, b, st, ints):
    """``ints[r] = flat[b + r * st]`` as int64 for a column of whole numbers.

    Returns ``(exact, increasing, lo, hi)``: whether every value is a whole number
    below 2**63 in magnitude (else ``ints`` is incomplete), whether they strictly
    increase, and their least and greatest value.

    Examples
    --------
    >>> import numpy as np
    >>> ints = np.empty(3, dtype=np.int64)
    >>> integer_column(np.array([3.0, 0.5, 1.0, 0.5, 2.0, 0.5]), 0, 2, ints)
    (True, False, 1, 3)
    >>> ints.tolist()
    [3, 1, 2]
    """
    n = ints.shape[0]
    increasing = True
    lo = hi = 0
    for r in range(n):
        x = flat[b + r * st]
        if not abs(x) < 9.2e18:
            return False, False, 0, 0
        v = np.int64(x)
        if float(v) != x:
            return False, False, 0, 0
        ints[r] = v
        if r == 0:
            lo = hi = v
        else:
            if v <= ints[r - 1]:
                increasing = False
            lo = min(lo, v)
            hi = max(hi, v)
    return True, increasing, lo, hi


@njit
def consecutive_order(ids, lo, order):
    """``order[ids[r] - lo] = r`` for ids that are a permutation of ``lo, lo + 1, ...``
    (``max(ids) - lo + 1 == len(ids)``): the row order that sorts them. Returns False
    when an id repeats (some position is then left unset).

    Examples
    --------
    >>> import numpy as np
    >>> order = np.empty(3, dtype=np.int64)
    >>> consecutive_order(np.array([12, 10, 11]), 10, order), order.tolist()
    (True, [1, 2, 0])
    """
    n = ids.shape[0]
    for k in range(n):
        order[k] = -1
    for r in range(n):
        order[ids[r] - lo] = r
    for k in range(n):
        if order[k] < 0:
            return False
    return True


@njit
def permute_rows(flat, b, w, order, tmp):
    """Reorder the (n, w) row-major block ``flat[b:b + n * w]`` in place so that its row
    ``r`` becomes its former row ``order[r]``; ``tmp`` holds at least ``n * w`` values.

    Examples
    --------
    >>> import numpy as np
    >>> flat = np.array([9.0, 1, 2, 3, 4, 5, 6])
    >>> permute_rows(flat, 1, 2, np.array([2, 0, 1]), np.empty(6))
    >>> flat.tolist()
    [9.0, 5.0, 6.0, 1.0, 2.0, 3.0, 4.0]
    """
    n = order.shape[0]
    if w == 3:
        for r in range(n):
            src = np.uint64(b + order[r] * 3)
            dst = np.uint64(r * 3)
            tmp[dst] = flat[src]
            tmp[dst + _U1] = flat[src + _U1]
            tmp[dst + np.uint64(2)] = flat[src + np.uint64(2)]
    else:
        for r in range(n):
            src = b + order[r] * w
            for c in range(w):
                tmp[np.uint64(r * w + c)] = flat[np.uint64(src + c)]
    for i in range(n * w):
        flat[np.uint64(b + i)] = tmp[np.uint64(i)]


@njit_parallel
def gather_rows(data, order, cols, out):
    """``out[r, k] = data[order[r], cols[k]]`` (row reordering and column selection at once)."""
    m = cols.shape[0]
    for r in prange(order.shape[0]):
        src = order[r]
        for k in range(m):
            out[r, k] = data[src, cols[k]]
