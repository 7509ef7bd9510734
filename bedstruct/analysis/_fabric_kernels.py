"""Numba kernels for fabric tensors and real spherical harmonics.

Pure functions of contiguous float64 arrays; they write into preallocated
``out`` arrays and never validate (the orchestrators in ``fabric.py`` and
``harmonics.py`` do). Every kernel has a NumPy reference in the tests.
"""

from __future__ import annotations

import math

import numpy as np

from .._numba import njit, njit_parallel, prange

__all__ = []

# Exponents (px, py, pz) of the 15 distinct degree-4 monomials n_x^px n_y^py n_z^pz.
MONO4 = np.array([
    (4, 0, 0), (0, 4, 0), (0, 0, 4), (3, 1, 0), (3, 0, 1), (1, 3, 0), (0, 3, 1), (1, 0, 3),
    (0, 1, 3), (2, 2, 0), (2, 0, 2), (0, 2, 2), (2, 1, 1), (1, 2, 1), (1, 1, 2),
], dtype=np.int64)
# Pairs (i, j) of the 6 distinct degree-2 monomials, in LAMMPS/Voigt order xx yy zz xy xz yz.
MONO2 = np.array([(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)], dtype=np.int64)

# Layout of one row of the moment-sum output.
N_MOMENT_COLUMNS = 2 + 6 + 15   # [sum w, n_bad, 6 second moments, 15 fourth moments]


@njit
def moment_sums(normals, weights, use_weights, n_chunks, out):
    """Weighted sums of n n and n n n n over unit directions, by chunk.

    One thread: a few dozen flops per direction, memory-bound, where threads
    would cost more to compile than they save. The chunks fix the order of the
    sums, so the result does not depend on the number of threads.

    ``normals`` (M, 3) need not be unit vectors: each row is normalised.
    Rows of zero length or with non-finite entries are skipped and counted
    in column 1. ``out`` has shape (n_chunks, N_MOMENT_COLUMNS).
    """
    m = normals.shape[0]
    for c in range(n_chunks):
        start = (m * c) // n_chunks
        stop = (m * (c + 1)) // n_chunks
        sw = 0.0
        bad = 0.0
        s2 = np.zeros(6)
        s4 = np.zeros(15)
        px = np.empty(5)
        py = np.empty(5)
        pz = np.empty(5)
        for a in range(start, stop):
            x = normals[a, 0]
            y = normals[a, 1]
            z = normals[a, 2]
            r2 = x * x + y * y + z * z
            if not (r2 > 0.0 and r2 < np.inf):
                bad += 1.0
                continue
            inv = 1.0 / math.sqrt(r2)
            x *= inv
            y *= inv
            z *= inv
            w = weights[a] if use_weights else 1.0
            sw += w
            xx = x * x
            yy = y * y
            zz = z * z
            s2[0] += w * xx
            s2[1] += w * yy
            s2[2] += w * zz
            s2[3] += w * x * y
            s2[4] += w * x * z
            s2[5] += w * y * z
            px[0] = 1.0
            py[0] = 1.0
            pz[0] = 1.0
            for p in range(1, 5):
                px[p] = px[p - 1] * x
                py[p] = py[p - 1] * y
                pz[p] = pz[p - 1] * z
            for k in range(15):
                s4[k] += w * px[MONO4[k, 0]] * py[MONO4[k, 1]] * pz[MONO4[k, 2]]
        out[c, 0] = sw
        out[c, 1] = bad
        for k in range(6):
            out[c, 2 + k] = s2[k]
        for k in range(15):
            out[c, 8 + k] = s4[k]


@njit
def ylm_row(x, y, z, l_max, a, b, fmm, ylm):
    """Real orthonormal spherical harmonics Y_lm(n) for l <= l_max at a unit vector.

    ``ylm[l*l + l + m]`` receives Y_lm. Uses the fully normalised Legendre
    recurrence on the polynomial part P_l^m(z) / sin^m(theta) and
    (x + i y)^m = sin^m(theta) e^{i m phi}, so no trigonometric call is made.
    ``a``, ``b`` are the recurrence tables and ``fmm[m]`` the diagonal factors
    built by :func:`recurrence_tables`.
    """
    sqrt2 = 1.4142135623730951
    cm = 1.0
    sm = 0.0
    pmm = 0.28209479177387814  # 1 / sqrt(4 pi)
    for m in range(l_max + 1):
        if m > 0:
            c_new = x * cm - y * sm
            sm = x * sm + y * cm
            cm = c_new
            pmm *= fmm[m]
        p2 = 0.0
        p1 = pmm
        for l in range(m, l_max + 1):
            if l == m:
                p = pmm
            elif l == m + 1:
                p = z * math.sqrt(2.0 * m + 3.0) * pmm
            else:
                p = a[l, m] * (z * p1 - b[l, m] * p2)
            if l > m:
                p2 = p1
                p1 = p
            base = l * l + l
            if m == 0:
                ylm[base] = p
            else:
                ylm[base + m] = sqrt2 * p * cm
                ylm[base - m] = sqrt2 * p * sm


@njit
def ylm_accumulate(x, y, z, w, l_max, even_only, a, b, fmm, acc):
    """``acc[l*l + l + m] += w * Y_lm(n)`` (same recurrence as :func:`ylm_row`, fused)."""
    sqrt2w = 1.4142135623730951 * w
    cm = 1.0
    sm = 0.0
    pmm = 0.28209479177387814
    for m in range(l_max + 1):
        if m > 0:
            c_new = x * cm - y * sm
            sm = x * sm + y * cm
            cm = c_new
            pmm *= fmm[m]
        wc = sqrt2w * cm
        ws = sqrt2w * sm
        p2 = 0.0
        p1 = pmm
        for l in range(m, l_max + 1):
            if l == m:
                p = pmm
            elif l == m + 1:
                p = z * math.sqrt(2.0 * m + 3.0) * pmm
                p2 = p1
                p1 = p
            else:
                p = a[l, m] * (z * p1 - b[l, m] * p2)
                p2 = p1
                p1 = p
            if even_only and (l & 1) == 1:
                continue
            base = l * l + l
            if m == 0:
                acc[base] += w * p
            else:
                acc[base + m] += wc * p
                acc[base - m] += ws * p


@njit_parallel
def harmonic_sums(normals, weights, use_weights, l_max, even_only, a, b, fmm, n_chunks, out):
    """Weighted sums of Y_lm(n) over directions, by chunk; ``out`` (n_chunks, (l_max+1)^2).

    Rows of zero length or with non-finite entries are skipped. With
    ``even_only`` the odd degrees are left at zero.
    """
    m_rows = normals.shape[0]
    k_tot = (l_max + 1) * (l_max + 1)
    for c in prange(n_chunks):
        start = (m_rows * c) // n_chunks
        stop = (m_rows * (c + 1)) // n_chunks
        acc = np.zeros(k_tot)
        for r in range(start, stop):
            x = normals[r, 0]
            y = normals[r, 1]
            z = normals[r, 2]
            r2 = x * x + y * y + z * z
            if not (r2 > 0.0 and r2 < np.inf):
                continue
            inv = 1.0 / math.sqrt(r2)
            w = weights[r] if use_weights else 1.0
            ylm_accumulate(x * inv, y * inv, z * inv, w, l_max, even_only, a, b, fmm, acc)
        for k in range(k_tot):
            out[c, k] = acc[k]


@njit_parallel
def harmonic_matrix(directions, l_max, a, b, fmm, out):
    """Y_lm at each direction: ``out[r, l*l + l + m]`` (directions are normalised)."""
    for r in prange(directions.shape[0]):
        x = directions[r, 0]
        y = directions[r, 1]
        z = directions[r, 2]
        r2 = x * x + y * y + z * z
        inv = 1.0 / math.sqrt(r2) if r2 > 0.0 else 0.0
        ylm_row(x * inv, y * inv, z * inv, l_max, a, b, fmm, out[r])


def recurrence_tables(l_max: int):
    """Coefficient tables (a, b, fmm) for :func:`ylm_row` up to degree ``l_max``."""
    n = l_max + 1
    a = np.zeros((n, n))
    b = np.zeros((n, n))
    for l in range(2, n):
        for m in range(0, l - 1):
            a[l, m] = math.sqrt((4.0 * l * l - 1.0) / (l * l - m * m))
            b[l, m] = math.sqrt(((l - 1.0) ** 2 - m * m) / (4.0 * (l - 1.0) ** 2 - 1.0))
    fmm = np.ones(n)
    for m in range(1, n):
        fmm[m] = math.sqrt((2.0 * m + 1.0) / (2.0 * m))
    return a, b, fmm
