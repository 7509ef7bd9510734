"""numba neighbour rebuild of the DEM engine in one call.

:func:`rebuild_in_place` makes the whole neighbour rebuild of
:meth:`~bedstruct.dem.Simulation.run` when no particle has left the domain: the
periodic wrap, the particles sorted by cell, the pair list, the contact history carried
onto it and the wall candidate lists, with the kernels of
:mod:`~bedstruct.dem._kernels_neighbours` and :mod:`~bedstruct.dem._kernels_walls`
called in the orchestrator's order with the same arguments (the same lists, bit for bit).
Where a particle has left (or has a non-finite position) it hands back before changing
anything but the wrap, and the orchestrator removes the particles and rebuilds itself.
:func:`wall_lists` is the wall candidate lists alone.
"""

from __future__ import annotations

import numpy as np

from .._numba import njit
from ._kernels_neighbours import (HALF_STENCIL, carry_history, cell_indices, compact_chunks,
                                  counting_sort, history_source, pair_build, permute_particles)
from ._kernels_walls import candidate_lists, wall_candidates

__all__ = ["rebuild_sorted", "wall_lists", "pair_list"]


@njit
def wall_lists(x, rad, W, tri, time, skin, bounds, wslot, whist):
    """Candidate walls of each particle as a CSR list ``(start, cand)``
    (:func:`~bedstruct.dem._kernels_walls.wall_candidates`, then
    :func:`~bedstruct.dem._kernels_walls.candidate_lists`)."""
    near = np.zeros((x.shape[0], W.shape[0]), dtype=np.bool_)
    wall_candidates(x, rad, W, tri, time, skin, bounds, near, wslot, whist)
    return candidate_lists(near)


@njit
def pair_list(x, rad, cells, start, nc, periodic, L, cutoff, bounds, m_hint):
    """The half-stencil pair list ``(pi, pj, psh)`` of particles sorted by cell
    (:func:`~bedstruct.dem._kernels_neighbours.pair_build`): one pass into per-chunk room
    sized from ``m_hint`` pairs (the last list), or, on a first build (``m_hint`` 0) or
    where the room was short, a counting pass and a filling pass."""
    n = x.shape[0]
    nt = bounds.shape[0] - 1
    none_i = np.zeros(0, dtype=np.int64)
    if m_hint > 0 and n > 0:
        cap = np.empty(nt, dtype=np.int64)
        off = np.zeros(nt, dtype=np.int64)
        for t in range(nt):
            size = bounds[t + 1] - bounds[t]
            cap[t] = np.int64(1.25 * m_hint * (size / n) + 64 + 8 * size)
            if t:
                off[t] = off[t - 1] + cap[t - 1]
        tot = off[nt - 1] + cap[nt - 1]
        bi = np.empty(tot, dtype=np.int32)
        bj = np.empty(tot, dtype=np.int32)
        bs = np.empty((tot, 3), dtype=np.int8)
        cnt = np.zeros(nt, dtype=np.int64)
        pair_build(x, rad, cells, start, nc, periodic, L, HALF_STENCIL, cutoff, bounds, none_i,
                   2, bi, bj, bs, off, cap, cnt)
        if cnt.min() >= 0:
            return compact_chunks(bi, bj, bs, off, cnt)
    counts = np.zeros(n, dtype=np.int64)
    dummy_i = np.zeros(0, dtype=np.int32)
    dummy_s = np.zeros((0, 3), dtype=np.int8)
    z = np.zeros(nt, dtype=np.int64)
    pair_build(x, rad, cells, start, nc, periodic, L, HALF_STENCIL, cutoff, bounds, counts, 0,
               dummy_i, dummy_i, dummy_s, z, z, z)
    offs = np.zeros(n, dtype=np.int64)
    for i in range(1, n):
        offs[i] = offs[i - 1] + counts[i - 1]
    m = offs[n - 1] + counts[n - 1] if n else 0
    pi = np.zeros(m, dtype=np.int32)
    pj = np.zeros(m, dtype=np.int32)
    psh = np.zeros((m, 3), dtype=np.int8)
    pair_build(x, rad, cells, start, nc, periodic, L, HALF_STENCIL, cutoff, bounds, offs, 1, pi,
               pj, psh, z, z, z)
    return pi, pj, psh


@njit
def rebuild_sorted(P, grid, L, periodic, PL, hist, ageing, by_partner, n_lo, cutoff, bounds,
                   m_hint, WL):
    """The neighbour rebuild of particles that are all inside the domain (wrapped).

    ``P = (x, v, om, f, tq, rad, mass, inv_m, inv_i, ptype, ids, images, wslot, whist)``
    are the particles, ``grid = (lo, ncell, cell_len)`` the cell grid, ``L`` and
    ``periodic`` the box, ``PL = (pi, pj, psh)`` and ``hist = (ht, hr, hx)`` the old pair
    list and its history, ``ageing`` whether the new list has ageing history, ``by_partner``
    and ``n_lo`` how the history is looked up
    (:func:`~bedstruct.dem._kernels_neighbours.carry_history`), ``cutoff`` the skin plus
    any extra cutoff, ``bounds`` the particle chunks, ``m_hint`` the last list's length
    (:func:`pair_list`) and ``WL = (W, tri, time, skin)`` the walls.

    Returns the particle arrays sorted by cell (as ``P``, then ``x_ref``, a copy of the
    positions), the new pair list ``(pi, pj, psh)``, its history ``(ht, hr, hx)`` and the
    wall lists ``(wstart, wcand)``.
    """
    x, v, om, f, tq, rad, mass, inv_m, inv_i, ptype, ids, images, wslot, whist = P
    lo, nc, cell_len = grid
    pi, pj, psh = PL
    ht, hr, hx = hist
    W, tri, time, skin = WL
    n = x.shape[0]
    src, old_keys, old_sign = history_source(ids, pi, pj, ht, hr, hx, not by_partner)
    cells = np.empty(n, dtype=np.int64)
    cell_indices(x, lo, cell_len, nc, cells)
    perm, start = counting_sort(cells, nc[0] * nc[1] * nc[2])
    (x2, v2, om2, f2, tq2, rad2, mass2, inv_m2, inv_i2, ptype2, ids2, images2, wslot2,
     whist2) = permute_particles(perm, x, v, om, f, tq, rad, mass, inv_m, inv_i, ptype, ids,
                                 images, wslot, whist)
    cells = cells[perm]
    x_ref = x2.copy()
    pi2, pj2, psh2 = pair_list(x2, rad2, cells, start, nc, periodic, L, cutoff, bounds, m_hint)
    m = pi2.shape[0]
    ht2 = np.zeros((m, 3))
    hr2 = np.zeros((m, 3))
    hx2 = np.zeros((m if ageing else 0, 3))
    if old_keys.size and m:
        # the history of each new pair is independent of the others: any chunks will do
        nt = bounds.shape[0] - 1
        pb = np.empty(nt + 1, dtype=np.int64)
        for t in range(nt + 1):
            pb[t] = (m * t) // nt
        carry_history(ids2, pi2, pj2, pb, src, old_keys, old_sign, ht, hr, hx, n_lo,
                      by_partner, ht2, hr2, hx2)
    wstart, wcand = wall_lists(x2, rad2, W, tri, time, skin, bounds, wslot2, whist2)
    return ((x2, v2, om2, f2, tq2, rad2, mass2, inv_m2, inv_i2, ptype2, ids2, images2, wslot2,
             whist2, x_ref), (pi2, pj2, psh2), (ht2, hr2, hx2), (wstart, wcand))
