"""Numba kernels for radius-aware contact detection with a cell list.

Kernels are pure functions of contiguous arrays: the orchestrator in
``contacts.py`` validates input, builds the cell list (particles sorted by
cell) and calls them. Cells live in fractional (box) coordinates so the same
code serves orthogonal and triclinic boxes; along a periodic axis a neighbour
cell index outside ``[0, n)`` is wrapped and the matching image shift (an
integer multiple of the box vector) is applied to the partner's position.

Each pair is visited once through a half stencil: unwrapped cell offsets
``o`` that are lexicographically positive, plus ``o = 0`` with ``j > i``. Every
distinct unwrapped neighbour cell is a distinct (cell, image) combination, so
a pair that touches through two different images (possible only when a
periodic width is below twice the cutoff) is reported once per image, and a
particle touching its own image is reported once (``i == j``, positive shift).
"""

from __future__ import annotations

import math

import numpy as np

from .._numba import njit, njit_parallel, prange

__all__ = ["scan_pairs", "compact_pairs", "pair_geometry", "peel_rattlers"]


@njit(inline="always")
def _neighbour_cell(c, n, periodic):
    """Cell index ``c`` on an axis of ``n`` cells: (wrapped index, image shift, inside).

    Along a periodic axis ``c`` wraps into ``[0, n)`` and the shift counts the
    box lengths crossed; along a closed axis a cell outside is not inside.
    """
    s = 0
    if periodic:
        s = c // n
        c -= s * n
        return c, s, True
    return c, s, c >= 0 and c < n


@njit_parallel
def scan_pairs(rows, pos, radii, cell_xyz, cell_start, ncell, periodic, reach, matrix, tol,
               cap, out_j, out_shift, counts):
    """Find the partners of the (cell-sorted) particles ``rows``.

    For ``rows[r] = i`` writes up to ``cap`` partners into ``out_j[r, :]`` and
    their image shifts (integers per axis) into ``out_shift[r, :, :]``, and the
    total number found into ``counts[r]`` (which may exceed ``cap``: the
    caller then rescans those rows with a larger ``cap``).

    ``pos`` (N, 3) are cell-sorted Cartesian positions wrapped along periodic
    axes, ``cell_xyz`` (N, 3) the integer cells, ``cell_start`` the CSR start of
    each linear cell, ``ncell`` cells per axis, ``periodic`` flags (as int),
    ``reach`` the stencil half-width per axis, ``matrix`` the box matrix with
    the edge vectors as columns and ``tol`` the contact tolerance.
    """
    for r in prange(rows.shape[0]):
        i = rows[r]
        c = 0
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        ri = radii[i]
        for ox in range(-reach[0], reach[0] + 1):
            if ox < 0:
                continue
            cx, sx, inside = _neighbour_cell(cell_xyz[i, 0] + ox, ncell[0], periodic[0])
            if not inside:
                continue
            for oy in range(-reach[1], reach[1] + 1):
                if ox == 0 and oy < 0:
                    continue
                cy, sy, inside = _neighbour_cell(cell_xyz[i, 1] + oy, ncell[1], periodic[1])
                if not inside:
                    continue
                for oz in range(-reach[2], reach[2] + 1):
                    if ox == 0 and oy == 0 and oz < 0:
                        continue
                    cz, sz, inside = _neighbour_cell(cell_xyz[i, 2] + oz, ncell[2],
                                                     periodic[2])
                    if not inside:
                        continue
                    shx = matrix[0, 0] * sx + matrix[0, 1] * sy + matrix[0, 2] * sz
                    shy = matrix[1, 0] * sx + matrix[1, 1] * sy + matrix[1, 2] * sz
                    shz = matrix[2, 0] * sx + matrix[2, 1] * sy + matrix[2, 2] * sz
                    lin = (cx * ncell[1] + cy) * ncell[2] + cz
                    start = cell_start[lin]
                    if ox == 0 and oy == 0 and oz == 0:
                        start = i + 1          # own cell, no image: only j > i
                    for j in range(start, cell_start[lin + 1]):
                        dx = pos[j, 0] + shx - xi
                        dy = pos[j, 1] + shy - yi
                        dz = pos[j, 2] + shz - zi
                        cut = ri + radii[j] + tol
                        if dx * dx + dy * dy + dz * dz <= cut * cut:
                            if c < cap:
                                out_j[r, c] = j
                                out_shift[r, c, 0] = sx
                                out_shift[r, c, 1] = sy
                                out_shift[r, c, 2] = sz
                            c += 1
        counts[r] = c


@njit
def compact_pairs(rows, take, offsets, out_j, out_shift, order, i_out, j_out, s_out):
    """Gather the scan buffers into flat arrays in original row indices.

    Row ``r`` contributes ``take[r]`` pairs at ``offsets[r]``; indices are mapped
    through ``order`` (cell-sorted -> original) and each pair is oriented so
    that ``i <= j`` (the image shift changes sign when swapped). One thread: a
    memory-bound gather, where threads would cost more to compile than they save.
    """
    for r in range(rows.shape[0]):
        base = offsets[r]
        a = order[rows[r]]
        for c in range(take[r]):
            b = order[out_j[r, c]]
            sx = out_shift[r, c, 0]
            sy = out_shift[r, c, 1]
            sz = out_shift[r, c, 2]
            k = base + c
            if a <= b:
                i_out[k] = a
                j_out[k] = b
                s_out[k, 0] = sx
                s_out[k, 1] = sy
                s_out[k, 2] = sz
            else:
                i_out[k] = b
                j_out[k] = a
                s_out[k, 0] = -sx
                s_out[k, 1] = -sy
                s_out[k, 2] = -sz


@njit
def pair_geometry(i, j, shift, pos, radii, matrix, out_branch, out_area):
    """Branch vectors ``pos[j] + matrix @ shift - pos[i]`` and lens areas ``pi a^2``
    (one thread: a few flops per contact)."""
    for k in range(i.shape[0]):
        a = i[k]
        b = j[k]
        sx = shift[k, 0]
        sy = shift[k, 1]
        sz = shift[k, 2]
        d2 = 0.0
        for d in range(3):
            v = (pos[b, d] + matrix[d, 0] * sx + matrix[d, 1] * sy + matrix[d, 2] * sz
                 - pos[a, d])
            out_branch[k, d] = v
            d2 += v * v
        dist = math.sqrt(d2)
        r1 = radii[a]
        r2 = radii[b]
        if dist >= r1 + r2:
            rad2 = 0.0
        elif dist <= abs(r1 - r2):
            rad2 = min(r1, r2) ** 2
        else:
            x = (d2 + r1 * r1 - r2 * r2) / (2.0 * dist)
            rad2 = max(r1 * r1 - x * x, 0.0)
        out_area[k] = math.pi * rad2


@njit
def peel_rattlers(i, j, fixed, min_contacts, removed):
    """Iteratively remove particles with fewer than ``min_contacts`` contacts.

    ``fixed`` (N,) holds contacts that never disappear (walls); ``removed``
    (N,) bool is written. Queue-based peeling (O(N + M)); the result is the
    same fixed point as repeated simultaneous removal (the k-core).
    """
    n = fixed.shape[0]
    m = i.shape[0]
    deg = fixed.copy()
    start = np.zeros(n + 1, dtype=np.int64)
    for k in range(m):
        start[i[k] + 1] += 1
        start[j[k] + 1] += 1
    for p in range(n):
        start[p + 1] += start[p]
    fill = start[:-1].copy()
    nbr = np.empty(2 * m, dtype=np.int64)
    for k in range(m):
        nbr[fill[i[k]]] = j[k]
        fill[i[k]] += 1
        nbr[fill[j[k]]] = i[k]
        fill[j[k]] += 1
    for p in range(n):
        deg[p] += start[p + 1] - start[p]
    queue = np.empty(n, dtype=np.int64)
    queued = np.zeros(n, dtype=np.bool_)
    head = 0
    tail = 0
    for p in range(n):
        removed[p] = False
        if deg[p] < min_contacts:
            queue[tail] = p
            tail += 1
            queued[p] = True
    while head < tail:
        p = queue[head]
        head += 1
        removed[p] = True
        for e in range(start[p], start[p + 1]):
            q = nbr[e]
            if removed[q]:
                continue
            deg[q] -= 1
            if deg[q] < min_contacts and not queued[q]:
                queue[tail] = q
                tail += 1
                queued[q] = True
