"""Numba kernels of the heat-conduction model (see :mod:`bedstruct.analysis.heat`).

Pure functions of contiguous arrays; no validation (the orchestrator does it).
Reductions are summed per fixed chunk of rows and the chunks are then added
in order, so results do not depend on the number of threads.
"""

from __future__ import annotations

import math

import numpy as np

from .._numba import njit, njit_parallel, prange

__all__: list[str] = []


@njit
def chunk_bounds(n, n_chunks):
    """Row ranges ``[bounds[c], bounds[c+1])`` splitting ``n`` rows in ``n_chunks``."""
    out = np.empty(n_chunks + 1, dtype=np.int64)
    for c in range(n_chunks + 1):
        out[c] = (n * c) // n_chunks
    return out


@njit(inline="always")
def _a_row(indptr, indices, data, diag, v, i):
    """Row ``i`` of ``A v`` with ``A = diag(diag) - W`` (``W`` in CSR)."""
    acc = diag[i] * v[i]
    for k in range(indptr[i], indptr[i + 1]):
        acc -= data[k] * v[indices[k]]
    return acc


@njit(inline="always")
def _set_residual(i, ri, r, z, diag):
    """Store residual ``r_i`` and preconditioned ``z_i = r_i / diag_i``; returns ``z_i``."""
    r[i] = ri
    zi = ri / diag[i]
    z[i] = zi
    return zi


@njit(inline="always")
def _sum_and_max(partial, partial_max, nc):
    """Chunk partials added in order, and the largest chunk maximum."""
    s = 0.0
    m = 0.0
    for c in range(nc):
        s += partial[c]
        if partial_max[c] > m:
            m = partial_max[c]
    return s, m


@njit_parallel
def pcg_solve(indptr, indices, data, diag, wrow, b, x, tol, maxiter, bounds, r, z, p, q, partial,
              partial_max, out):
    """Jacobi-preconditioned CG for ``A x = b`` with ``A = diag(diag) - W``.

    ``W`` is the symmetric, non-negative CSR matrix ``(indptr, indices,
    data)``; ``A`` must be symmetric positive definite. ``x`` holds the first
    guess on entry and the solution on exit. Iterates until the largest
    preconditioned residual ``max |r_i / diag_i|`` is at most ``tol`` (the
    units of ``x``). ``wrow`` holds the row sums of ``W``; on exit
    ``out[0]`` is the exact sum of the true residual, ``sum(b - A x) =
    sum(b) - sum((diag - wrow) x)`` (``W`` is symmetric), computed without
    another product. Returns the number of iterations (``maxiter + 1`` if
    not converged).
    """
    nc = bounds.shape[0] - 1
    # r = b - A x ; z = r / d ; p = z ; rz = r.z
    for c in prange(nc):
        s = 0.0
        m = 0.0
        for i in range(bounds[c], bounds[c + 1]):
            ri = b[i] - _a_row(indptr, indices, data, diag, x, i)
            zi = _set_residual(i, ri, r, z, diag)
            p[i] = zi
            s += ri * zi
            a = abs(zi)
            if a > m:
                m = a
        partial[c] = s
        partial_max[c] = m
    rz, zmax = _sum_and_max(partial, partial_max, nc)
    it = 0
    while zmax > tol:
        if it >= maxiter:
            it = maxiter + 1
            break
        it += 1
        # q = A p ; pq = p.q
        for c in prange(nc):
            s = 0.0
            for i in range(bounds[c], bounds[c + 1]):
                acc = _a_row(indptr, indices, data, diag, p, i)
                q[i] = acc
                s += p[i] * acc
            partial[c] = s
        pq = 0.0
        for c in range(nc):
            pq += partial[c]
        if pq <= 0.0:
            break
        alpha = rz / pq
        for c in prange(nc):
            s = 0.0
            m = 0.0
            for i in range(bounds[c], bounds[c + 1]):
                x[i] += alpha * p[i]
                ri = r[i] - alpha * q[i]
                zi = _set_residual(i, ri, r, z, diag)
                s += ri * zi
                a = abs(zi)
                if a > m:
                    m = a
            partial[c] = s
            partial_max[c] = m
        rz_new, zmax = _sum_and_max(partial, partial_max, nc)
        beta = rz_new / rz
        rz = rz_new
        for c in prange(nc):
            for i in range(bounds[c], bounds[c + 1]):
                p[i] = z[i] + beta * p[i]
    # sum of the true residual: sum_i b_i - sum_i (diag_i - wrow_i) x_i
    for c in prange(nc):
        s = 0.0
        for i in range(bounds[c], bounds[c + 1]):
            s += b[i] - (diag[i] - wrow[i]) * x[i]
        partial[c] = s
    tot = 0.0
    for c in range(nc):
        tot += partial[c]
    out[0] = tot
    return it


@njit_parallel
def be_system(C, d, x_old, inv_h, rhs_const, bounds, diag, rhs):
    """Backward-Euler system: ``diag = C/h + d`` and ``rhs = C/h x_old + rhs_const``."""
    nc = bounds.shape[0] - 1
    for c in prange(nc):
        for i in range(bounds[c], bounds[c + 1]):
            ch = C[i] * inv_h
            diag[i] = ch + d[i]
            rhs[i] = ch * x_old[i] + rhs_const[i]


@njit
def rasterize_top(x, y, ztop_centre, radii, values, x0, y0, cell, nx, ny, mode, out, height,
                  owner):
    """Top view of spheres on a grid of square cells.

    For every cell centre covered by the disc of a sphere, ``mode == 0``
    keeps the value of the sphere whose surface is highest there (what a
    camera above the bed sees) and ``mode == 1`` keeps the largest value of
    all spheres covering the cell. ``out`` (ny, nx) must be NaN-filled,
    ``height`` -inf-filled and ``owner`` -1-filled on entry.
    """
    n = x.shape[0]
    for p in range(n):
        r = radii[p]
        i0 = int(math.floor((x[p] - r - x0) / cell - 0.5))
        i1 = int(math.ceil((x[p] + r - x0) / cell - 0.5))
        j0 = int(math.floor((y[p] - r - y0) / cell - 0.5))
        j1 = int(math.ceil((y[p] + r - y0) / cell - 0.5))
        if i0 < 0:
            i0 = 0
        if j0 < 0:
            j0 = 0
        if i1 > nx - 1:
            i1 = nx - 1
        if j1 > ny - 1:
            j1 = ny - 1
        for j in range(j0, j1 + 1):
            cy = y0 + (j + 0.5) * cell
            dy = cy - y[p]
            for i in range(i0, i1 + 1):
                cx = x0 + (i + 0.5) * cell
                dx = cx - x[p]
                d2 = dx * dx + dy * dy
                if d2 > r * r:
                    continue
                h = ztop_centre[p] + math.sqrt(r * r - d2)
                if mode == 0:
                    if h > height[j, i]:
                        height[j, i] = h
                        out[j, i] = values[p]
                        owner[j, i] = p
                else:
                    if owner[j, i] < 0 or values[p] > out[j, i]:
                        out[j, i] = values[p]
                        owner[j, i] = p
                    if h > height[j, i]:
                        height[j, i] = h
    return out
