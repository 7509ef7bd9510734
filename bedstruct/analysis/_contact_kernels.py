"""Numba kernels for radius-aware contact detection with a cell list.

Kernels are pure functions of contiguous arrays: the orchestrator in
``contacts.py`` validates input, builds the cell list (particles sorted by
cell) and calls them. Cells live in fractional (box) coordinates so the same
code serves orthogonal and triclinic boxes; along a periodic axis a neighbour
cell index outside ``[0, n)`` is wrapped and the matching image shift (an
integer multiple of the box vector) is applied to the partner's position.

Every distinct (unwrapped neighbour cell) is visited once, so a pair that
touches through two different images (possible only when a periodic width is
below twice the cutoff) is reported once per image, and a particle touching
its own image is reported with ``i == j`` and a lexicographically positive
shift.
"""

from __future__ import annotations

import numpy as np

from .._numba import njit, njit_parallel, prange

__all__ = ["count_pairs", "fill_pairs"]


@njit
def _positive_shift(sx, sy, sz):
    if sx != 0:
        return sx > 0
    if sy != 0:
        return sy > 0
    return sz > 0


@njit_parallel
def count_pairs(pos, radii, cell_xyz, cell_start, ncell, periodic, reach, matrix, tol, counts):
    """Count partners ``j >= i`` of each (cell-sorted) particle ``i``.

    Parameters are the cell-sorted Cartesian positions ``pos`` (N, 3) wrapped
    into the box along periodic axes, ``radii`` (N,), the integer cell of each
    particle ``cell_xyz`` (N, 3), the CSR start of each linear cell
    ``cell_start`` (n_cells + 1,), cells per axis ``ncell`` (3,), periodic
    flags (3,) as int, the stencil half-width ``reach`` (3,), the box matrix
    (columns are the edge vectors) and the distance tolerance. Writes
    ``counts`` (N,).
    """
    n = pos.shape[0]
    for i in prange(n):
        c = 0
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        ri = radii[i]
        for ox in range(-reach[0], reach[0] + 1):
            cx = cell_xyz[i, 0] + ox
            sx = 0
            if periodic[0]:
                sx = cx // ncell[0]
                cx -= sx * ncell[0]
            elif cx < 0 or cx >= ncell[0]:
                continue
            for oy in range(-reach[1], reach[1] + 1):
                cy = cell_xyz[i, 1] + oy
                sy = 0
                if periodic[1]:
                    sy = cy // ncell[1]
                    cy -= sy * ncell[1]
                elif cy < 0 or cy >= ncell[1]:
                    continue
                for oz in range(-reach[2], reach[2] + 1):
                    cz = cell_xyz[i, 2] + oz
                    sz = 0
                    if periodic[2]:
                        sz = cz // ncell[2]
                        cz -= sz * ncell[2]
                    elif cz < 0 or cz >= ncell[2]:
                        continue
                    shx = matrix[0, 0] * sx + matrix[0, 1] * sy + matrix[0, 2] * sz
                    shy = matrix[1, 0] * sx + matrix[1, 1] * sy + matrix[1, 2] * sz
                    shz = matrix[2, 0] * sx + matrix[2, 1] * sy + matrix[2, 2] * sz
                    lin = (cx * ncell[1] + cy) * ncell[2] + cz
                    for j in range(cell_start[lin], cell_start[lin + 1]):
                        if j < i:
                            continue
                        if j == i and not _positive_shift(sx, sy, sz):
                            continue
                        dx = pos[j, 0] + shx - xi
                        dy = pos[j, 1] + shy - yi
                        dz = pos[j, 2] + shz - zi
                        cut = ri + radii[j] + tol
                        if dx * dx + dy * dy + dz * dz <= cut * cut:
                            c += 1
        counts[i] = c


@njit_parallel
def fill_pairs(pos, radii, cell_xyz, cell_start, ncell, periodic, reach, matrix, tol, offsets,
               out_i, out_j, out_branch, out_periodic):
    """Second pass of :func:`count_pairs`: write the pairs at ``offsets[i]``.

    ``out_i``/``out_j`` are cell-sorted indices, ``out_branch`` the vector from
    ``i`` to the image of ``j``, ``out_periodic`` whether an image shift was used.
    """
    n = pos.shape[0]
    for i in prange(n):
        k = offsets[i]
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2]
        ri = radii[i]
        for ox in range(-reach[0], reach[0] + 1):
            cx = cell_xyz[i, 0] + ox
            sx = 0
            if periodic[0]:
                sx = cx // ncell[0]
                cx -= sx * ncell[0]
            elif cx < 0 or cx >= ncell[0]:
                continue
            for oy in range(-reach[1], reach[1] + 1):
                cy = cell_xyz[i, 1] + oy
                sy = 0
                if periodic[1]:
                    sy = cy // ncell[1]
                    cy -= sy * ncell[1]
                elif cy < 0 or cy >= ncell[1]:
                    continue
                for oz in range(-reach[2], reach[2] + 1):
                    cz = cell_xyz[i, 2] + oz
                    sz = 0
                    if periodic[2]:
                        sz = cz // ncell[2]
                        cz -= sz * ncell[2]
                    elif cz < 0 or cz >= ncell[2]:
                        continue
                    shx = matrix[0, 0] * sx + matrix[0, 1] * sy + matrix[0, 2] * sz
                    shy = matrix[1, 0] * sx + matrix[1, 1] * sy + matrix[1, 2] * sz
                    shz = matrix[2, 0] * sx + matrix[2, 1] * sy + matrix[2, 2] * sz
                    lin = (cx * ncell[1] + cy) * ncell[2] + cz
                    for j in range(cell_start[lin], cell_start[lin + 1]):
                        if j < i:
                            continue
                        if j == i and not _positive_shift(sx, sy, sz):
                            continue
                        dx = pos[j, 0] + shx - xi
                        dy = pos[j, 1] + shy - yi
                        dz = pos[j, 2] + shz - zi
                        cut = ri + radii[j] + tol
                        if dx * dx + dy * dy + dz * dz <= cut * cut:
                            out_i[k] = i
                            out_j[k] = j
                            out_branch[k, 0] = dx
                            out_branch[k, 1] = dy
                            out_branch[k, 2] = dz
                            out_periodic[k] = (sx != 0) or (sy != 0) or (sz != 0)
                            k += 1
