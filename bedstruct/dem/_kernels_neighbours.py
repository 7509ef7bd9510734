"""numba neighbour-list kernels of the DEM engine: cell list, pair list, history remap.

Counting-sort cell list, half-stencil Verlet pair list with an integer
periodic image per pair, orientation-free pair keys and the remap of contact
history onto a new pair list; plus the grid-hash acceptance test of raindrop
insertion.
"""

from __future__ import annotations

import math

import numpy as np

from .._numba import njit, prange

__all__ = ["wrap_and_flag", "cell_indices", "counting_sort", "HALF_STENCIL", "pair_build",
           "pair_keys", "remap_history", "raindrop_accept", "permute_particles",
           "history_source", "carry_history", "compact_chunks"]

_FM = dict(fastmath=True)


@njit  # no fastmath: the finiteness test must stay
def wrap_and_flag(x, images, lo, hi, L, periodic, out):
    """Wrap positions into the box along periodic axes (``images`` counts the wraps) and flag
    in ``out`` the particles outside a fixed face or with a non-finite position.

    Returns ``(n_out, n_nonfinite)``; a flagged particle's row is left as it was.
    """
    n = x.shape[0]
    n_out = 0
    n_bad = 0
    for i in range(n):
        if not (math.isfinite(x[i, 0]) and math.isfinite(x[i, 1]) and math.isfinite(x[i, 2])):
            out[i] = True
            n_out += 1
            n_bad += 1
            continue
        gone = False
        for a in range(3):
            if periodic[a]:
                k = math.floor((x[i, a] - lo[a]) / L[a])
                if k != 0.0:
                    x[i, a] -= k * L[a]
                    images[i, a] += np.int64(k)
            elif x[i, a] < lo[a] or x[i, a] >= hi[a]:
                gone = True
        out[i] = gone
        if gone:
            n_out += 1
    return n_out, n_bad


@njit(**_FM)
def cell_indices(x, lo, cell_len, ncell, out):
    """Linear cell index ``(cz*ny + cy)*nx + cx`` of each particle (clamped to the grid)."""
    n = x.shape[0]
    for i in range(n):
        c0 = int(math.floor((x[i, 0] - lo[0]) / cell_len[0]))
        c1 = int(math.floor((x[i, 1] - lo[1]) / cell_len[1]))
        c2 = int(math.floor((x[i, 2] - lo[2]) / cell_len[2]))
        c0 = min(max(c0, 0), ncell[0] - 1)
        c1 = min(max(c1, 0), ncell[1] - 1)
        c2 = min(max(c2, 0), ncell[2] - 1)
        out[i] = (c2 * ncell[1] + c1) * ncell[0] + c0


@njit
def counting_sort(cells, ncells):
    """Stable counting sort: returns (perm, cell_start) with particles grouped by cell."""
    n = cells.shape[0]
    start = np.zeros(ncells + 1, dtype=np.int64)
    for i in range(n):
        start[cells[i] + 1] += 1
    for c in range(ncells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    perm = np.empty(n, dtype=np.int64)
    for i in range(n):
        c = cells[i]
        perm[fill[c]] = i
        fill[c] += 1
    return perm, start


# the 13 forward neighbour cells of the half stencil
HALF_STENCIL = np.array([(dx, dy, dz) for dz in (-1, 0, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1)
                         if (dz > 0) or (dz == 0 and dy > 0) or (dz == 0 and dy == 0 and dx > 0)],
                        dtype=np.int64)


@njit(parallel=True, **_FM)
def pair_build(x, rad, cells, start, ncell, periodic, L, stencil, skin, bounds, counts, fill,
               pi, pj, psh, chunk_off, chunk_cap, chunk_cnt):
    """Half-stencil pair list with cutoff ``r_i + r_j + skin``.

    ``fill=0``: write per-particle pair counts. ``fill=1`` (``counts`` holding
    exclusive offsets): write the pairs ``(i, j, image of j)``. ``fill=2``:
    one pass, chunk t writing its pairs from ``chunk_off[t]`` with room for
    ``chunk_cap[t]``; ``chunk_cnt[t]`` gets the number written, or -1 when
    the room was too small. Particles must be sorted by cell: the neighbour
    cells of a cell (their particle ranges and periodic images) are looked up
    once for all its particles.
    """
    nt = bounds.shape[0] - 1
    ns = stencil.shape[0]
    nx = ncell[0]
    ny = ncell[1]
    nz = ncell[2]
    for t in prange(nt):
        tpos = chunk_off[t] if fill == 2 else 0
        tend = tpos + chunk_cap[t] if fill == 2 else 0
        over = False
        # the stencil of the current cell as particle ranges [j0, j1) with the image of
        # their cells: neighbour cells whose ranges follow each other (a row along x, same
        # image) make one range; the own cell (j > i) comes last
        sj0 = np.zeros(ns + 1, dtype=np.int64)
        sj1 = np.zeros(ns + 1, dtype=np.int64)
        ssh = np.zeros((ns + 1, 3), dtype=np.int64)
        nr = 0
        cprev = -1
        for i in range(bounds[t], bounds[t + 1]):
            if over:
                break
            c = cells[i]
            if c != cprev:
                cprev = c
                cx = c % nx
                cy = (c // nx) % ny
                cz = c // (nx * ny)
                nr = 0
                for s in range(ns):
                    sx = 0
                    sy = 0
                    sz = 0
                    ox = cx + stencil[s, 0]
                    oy = cy + stencil[s, 1]
                    oz = cz + stencil[s, 2]
                    if ox < 0:
                        if not periodic[0]:
                            continue
                        ox += nx
                        sx = -1
                    elif ox >= nx:
                        if not periodic[0]:
                            continue
                        ox -= nx
                        sx = 1
                    if oy < 0:
                        if not periodic[1]:
                            continue
                        oy += ny
                        sy = -1
                    elif oy >= ny:
                        if not periodic[1]:
                            continue
                        oy -= ny
                        sy = 1
                    if oz < 0:
                        if not periodic[2]:
                            continue
                        oz += nz
                        sz = -1
                    elif oz >= nz:
                        if not periodic[2]:
                            continue
                        oz -= nz
                        sz = 1
                    cc = (oz * ny + oy) * nx + ox
                    j0 = start[cc]
                    j1 = start[cc + 1]
                    if j0 >= j1:
                        continue
                    if (nr > 0 and sj1[nr - 1] == j0 and ssh[nr - 1, 0] == sx
                            and ssh[nr - 1, 1] == sy and ssh[nr - 1, 2] == sz):
                        sj1[nr - 1] = j1
                        continue
                    sj0[nr] = j0
                    sj1[nr] = j1
                    ssh[nr, 0] = sx
                    ssh[nr, 1] = sy
                    ssh[nr, 2] = sz
                    nr += 1
                sj1[nr] = start[c + 1]  # own cell, j > i
                ssh[nr, 0] = 0
                ssh[nr, 1] = 0
                ssh[nr, 2] = 0
            sj0[nr] = i + 1
            xi0 = x[i, 0]
            xi1 = x[i, 1]
            xi2 = x[i, 2]
            ri = rad[i] + skin
            cnt = 0
            pos = counts[i] if fill == 1 else tpos
            for s in range(nr + 1):
                j0 = sj0[s]
                j1 = sj1[s]
                if j0 >= j1:
                    continue
                sx = ssh[s, 0]
                sy = ssh[s, 1]
                sz = ssh[s, 2]
                a0 = xi0 - sx * L[0]
                a1 = xi1 - sy * L[1]
                a2 = xi2 - sz * L[2]
                for j in range(j0, j1):
                    d0 = a0 - x[j, 0]
                    d1 = a1 - x[j, 1]
                    d2 = a2 - x[j, 2]
                    rc = ri + rad[j]
                    if d0 * d0 + d1 * d1 + d2 * d2 < rc * rc:
                        if fill == 2 and pos >= tend:
                            over = True
                            break
                        if fill:
                            pi[pos] = i
                            pj[pos] = j
                            psh[pos, 0] = sx
                            psh[pos, 1] = sy
                            psh[pos, 2] = sz
                            pos += 1
                        cnt += 1
                if over:
                    break
            if fill == 0:
                counts[i] = cnt
            tpos = pos
        if fill == 2:
            chunk_cnt[t] = -1 if over else tpos - chunk_off[t]


@njit(inline="always")
def _pair_key(a, b):
    """Key ``min(a, b) * 2^31 + max(a, b)`` of the pair of ids ``(a, b)`` and its sign (+1
    if ``a < b``)."""
    if a < b:
        return a * 2147483648 + b, 1.0
    return b * 2147483648 + a, -1.0


@njit(parallel=True)
def pair_keys(ids, pi, pj, bounds, keys, sign):
    """Orientation-free key ``min(id) * 2^31 + max(id)`` and sign (+1 if id_i < id_j)."""
    nt = bounds.shape[0] - 1
    for t in prange(nt):
        for k in range(bounds[t], bounds[t + 1]):
            keys[k], sign[k] = _pair_key(ids[pi[k]], ids[pj[k]])


@njit(inline="always")
def _carry(k, idx, new_sign, old_sign, old_ht, old_hr, ht, hr):
    """Pair ``k``'s history from old pair ``idx`` (sign flipped with the orientation), or
    zero where ``idx`` < 0 (a new contact)."""
    if idx >= 0:
        s = new_sign[k] * old_sign[idx]
        for c in range(3):
            ht[k, c] = s * old_ht[idx, c]
            hr[k, c] = s * old_hr[idx, c]
    else:
        for c in range(3):
            ht[k, c] = 0.0
            hr[k, c] = 0.0


@njit(parallel=True)
def remap_history(new_keys, new_sign, old_keys_sorted, old_sign_sorted, old_ht_sorted,
                  old_hr_sorted, bounds, ht, hr):
    """Carry history to the new pair list by binary search of the sorted old keys.

    History vectors flip sign when the pair's (i, j) orientation flips.
    """
    nt = bounds.shape[0] - 1
    m = old_keys_sorted.shape[0]
    for t in prange(nt):
        for k in range(bounds[t], bounds[t + 1]):
            key = new_keys[k]
            idx = np.searchsorted(old_keys_sorted, key)
            if not (idx < m and old_keys_sorted[idx] == key):
                idx = -1
            _carry(k, idx, new_sign, old_sign_sorted, old_ht_sorted, old_hr_sorted, ht, hr)


@njit
def partner_csr(old_keys, n_lo):
    """The old pairs grouped by their lower id (``key >> 31``): ``start`` (n_lo + 1) and
    ``order`` (indices into ``old_keys``), for :func:`remap_history_csr`."""
    start = np.zeros(n_lo + 1, dtype=np.int64)
    for q in range(old_keys.shape[0]):
        start[(old_keys[q] >> 31) + 1] += 1
    for a in range(n_lo):
        start[a + 1] += start[a]
    pos = start[:-1].copy()
    order = np.empty(old_keys.shape[0], dtype=np.int64)
    for q in range(old_keys.shape[0]):
        lo = old_keys[q] >> 31
        order[pos[lo]] = q
        pos[lo] += 1
    return start, order


@njit(parallel=True)
def remap_history_csr(new_keys, new_sign, old_keys, old_sign, start, order, old_ht, old_hr,
                      bounds, ht, hr, slots):
    """Carry history to the new pair list by looking each pair up among its lower-id
    sphere's old partners (:func:`partner_csr`): linear in the pairs, a few comparisons
    each, where :func:`remap_history`'s binary search mispredicts ~log2(m) branches.

    The same values as :func:`remap_history` (history flips sign with the pair's
    orientation); ``slots[k]`` is the old pair carried to pair ``k``, or -1.
    """
    nt = bounds.shape[0] - 1
    n_lo = start.shape[0] - 1
    for t in prange(nt):
        for k in range(bounds[t], bounds[t + 1]):
            key = new_keys[k]
            lo = key >> 31
            idx = -1
            if lo < n_lo:
                for p in range(start[lo], start[lo + 1]):
                    q = order[p]
                    if old_keys[q] == key:
                        idx = q
                        break
            slots[k] = idx
            _carry(k, idx, new_sign, old_sign, old_ht, old_hr, ht, hr)


@njit(inline="always")
def _raindrop_cell(p, lo, cell_len, n, period):
    """Grid cell of coordinate ``p`` along one axis (wrapped where ``period`` > 0)."""
    c = int(math.floor((p - lo) / cell_len))
    if period > 0.0:
        return c % n
    return min(max(c, 0), n - 1)


@njit(inline="always")
def _raindrop_span(c, n, period):
    """``(first, last)`` cell offsets around cell ``c`` of ``n`` to visit along one axis
    (taken modulo ``n`` where ``period`` > 0)."""
    if period > 0.0:
        if n < 3:
            return 0, n - 1
        return c - 1, c + 1
    return max(c - 1, 0), min(c + 1, n - 1)


@njit(inline="always")
def _nearest_image(d, period):
    """Separation ``d`` along one axis, the nearest periodic image where ``period`` > 0."""
    if period > 0.0:
        return d - period * math.floor(d / period + 0.5)
    return d


@njit
def raindrop_accept(cand, crad, ex, erad, lo, cell_len, ncell, period, out_mask):
    """Greedy acceptance of candidate spheres that overlap neither existing spheres nor
    earlier accepted candidates (grid hash, serial; deterministic). Along an axis with
    ``period`` > 0 the grid (``ncell`` cells of ``cell_len`` from ``lo``) covers one period
    and spheres overlap their neighbours' nearest images."""
    nc = ncell[0] * ncell[1] * ncell[2]
    ne = ex.shape[0]
    nn = cand.shape[0]
    head = -np.ones(nc, dtype=np.int64)
    nxt = -np.ones(ne + nn, dtype=np.int64)
    px = np.empty((ne + nn, 3))
    pr = np.empty(ne + nn)
    cnt = 0

    for k in range(ne + nn):
        if k < ne:
            p0 = ex[k, 0]
            p1 = ex[k, 1]
            p2 = ex[k, 2]
            rr = erad[k]
        else:
            p0 = cand[k - ne, 0]
            p1 = cand[k - ne, 1]
            p2 = cand[k - ne, 2]
            rr = crad[k - ne]
        c0 = _raindrop_cell(p0, lo[0], cell_len[0], ncell[0], period[0])
        c1 = _raindrop_cell(p1, lo[1], cell_len[1], ncell[1], period[1])
        c2 = _raindrop_cell(p2, lo[2], cell_len[2], ncell[2], period[2])
        ok = True
        if k >= ne:
            a0, a1 = _raindrop_span(c0, ncell[0], period[0])
            b0, b1 = _raindrop_span(c1, ncell[1], period[1])
            e0, e1 = _raindrop_span(c2, ncell[2], period[2])
            for aa in range(a0, a1 + 1):
                a = aa % ncell[0]
                for bb in range(b0, b1 + 1):
                    b = bb % ncell[1]
                    for cc in range(e0, e1 + 1):
                        c = cc % ncell[2]
                        q = head[(c * ncell[1] + b) * ncell[0] + a]
                        while q >= 0:
                            d0 = _nearest_image(p0 - px[q, 0], period[0])
                            d1 = _nearest_image(p1 - px[q, 1], period[1])
                            d2 = _nearest_image(p2 - px[q, 2], period[2])
                            rs = rr + pr[q]
                            if d0 * d0 + d1 * d1 + d2 * d2 < rs * rs:
                                ok = False
                                break
                            q = nxt[q]
                        if not ok:
                            break
                    if not ok:
                        break
                if not ok:
                    break
            out_mask[k - ne] = ok
        if ok:
            px[cnt, 0] = p0
            px[cnt, 1] = p1
            px[cnt, 2] = p2
            pr[cnt] = rr
            cell = (c2 * ncell[1] + c1) * ncell[0] + c0
            nxt[cnt] = head[cell]
            head[cell] = cnt
            cnt += 1


@njit
def permute_particles(order, x, v, om, f, tq, rad, mass, inv_m, inv_i, ptype, ids, images,
                      wslot, whist):
    """New per-particle arrays holding rows ``order`` of each (the rebuild's sort by cell)."""
    n = order.shape[0]
    ns = wslot.shape[1]
    nh = whist.shape[2]
    x2 = np.empty((n, 3), dtype=x.dtype)
    v2 = np.empty((n, 3), dtype=v.dtype)
    om2 = np.empty((n, 3), dtype=om.dtype)
    f2 = np.empty((n, 3), dtype=f.dtype)
    tq2 = np.empty((n, 3), dtype=tq.dtype)
    rad2 = np.empty(n, dtype=rad.dtype)
    mass2 = np.empty(n, dtype=mass.dtype)
    inv_m2 = np.empty(n, dtype=inv_m.dtype)
    inv_i2 = np.empty(n, dtype=inv_i.dtype)
    ptype2 = np.empty(n, dtype=ptype.dtype)
    ids2 = np.empty(n, dtype=ids.dtype)
    images2 = np.empty((n, 3), dtype=images.dtype)
    wslot2 = np.empty((n, ns), dtype=wslot.dtype)
    whist2 = np.empty((n, ns, nh), dtype=whist.dtype)
    for k in range(n):
        i = order[k]
        for c in range(3):
            x2[k, c] = x[i, c]
            v2[k, c] = v[i, c]
            om2[k, c] = om[i, c]
            f2[k, c] = f[i, c]
            tq2[k, c] = tq[i, c]
            images2[k, c] = images[i, c]
        rad2[k] = rad[i]
        mass2[k] = mass[i]
        inv_m2[k] = inv_m[i]
        inv_i2[k] = inv_i[i]
        ptype2[k] = ptype[i]
        ids2[k] = ids[i]
        for s in range(ns):
            wslot2[k, s] = wslot[i, s]
            for c in range(nh):
                whist2[k, s, c] = whist[i, s, c]
    return x2, v2, om2, f2, tq2, rad2, mass2, inv_m2, inv_i2, ptype2, ids2, images2, wslot2, whist2


@njit
def history_source(ids, pi, pj, ht, hr, hx, sort_by_key):
    """The old pairs that carry history (nonzero tangential, rolling or, where ``hx`` has
    rows, ageing history), for :func:`carry_history`.

    Returns ``(src, keys, sign)``: the pairs' indices in the old list, in index order (or
    sorted by key with ``sort_by_key``), their keys and signs as :func:`pair_keys` gives.
    """
    m = ht.shape[0]
    use_x = hx.shape[0] == m and m > 0
    act = np.empty(m, dtype=np.int64)
    n = 0
    for k in range(m):
        on = (ht[k, 0] != 0.0 or ht[k, 1] != 0.0 or ht[k, 2] != 0.0 or hr[k, 0] != 0.0
              or hr[k, 1] != 0.0 or hr[k, 2] != 0.0)
        if not on and use_x:
            on = hx[k, 0] != 0.0 or hx[k, 1] != 0.0 or hx[k, 2] != 0.0
        if on:
            act[n] = k
            n += 1
    src = act[:n].copy()
    keys = np.empty(n, dtype=np.int64)
    sign = np.empty(n)
    for q in range(n):
        keys[q], sign[q] = _pair_key(ids[pi[src[q]]], ids[pj[src[q]]])
    if sort_by_key and n:
        o = np.argsort(keys, kind="mergesort")
        src = src[o]
        keys = keys[o]
        sign = sign[o]
    return src, keys, sign


@njit
def carry_history(ids, pi, pj, bounds, src, old_keys, old_sign, old_ht, old_hr, old_hx, n_lo,
                  by_partner, ht, hr, hx):
    """Carry the old pairs' history (:func:`history_source`) onto the new pair list
    ``(pi, pj)``: by partner table (:func:`remap_history_csr`) when ``by_partner``, else by
    binary search of the key-sorted old pairs (:func:`remap_history`). ``ht``, ``hr`` (and
    ``hx`` where it has rows: ageing history) are written in full."""
    m = pi.shape[0]
    keys = np.zeros(m, dtype=np.int64)
    sign = np.zeros(m)
    pair_keys(ids, pi, pj, bounds, keys, sign)
    o_ht = np.empty((src.shape[0], 3))
    o_hr = np.empty((src.shape[0], 3))
    for q in range(src.shape[0]):
        for c in range(3):
            o_ht[q, c] = old_ht[src[q], c]
            o_hr[q, c] = old_hr[src[q], c]
    slots = np.empty(m, dtype=np.int64)
    if by_partner:
        start, order = partner_csr(old_keys, n_lo)
        remap_history_csr(keys, sign, old_keys, old_sign, start, order, o_ht, o_hr, bounds,
                          ht, hr, slots)
    else:
        remap_history(keys, sign, old_keys, old_sign, o_ht, o_hr, bounds, ht, hr)
        if hx.shape[0]:
            nq = old_keys.shape[0]
            for k in range(m):
                idx = np.searchsorted(old_keys, keys[k])
                slots[k] = idx if idx < nq and old_keys[idx] == keys[k] else -1
    if hx.shape[0]:
        for k in range(m):
            if slots[k] >= 0:
                q = src[slots[k]]
                for c in range(3):
                    hx[k, c] = old_hx[q, c]


@njit
def compact_chunks(bi, bj, bs, off, cnt):
    """The pairs written by :func:`pair_build` (``fill=2``) chunk by chunk, as one list."""
    m = 0
    for t in range(cnt.shape[0]):
        m += cnt[t]
    pi = np.empty(m, dtype=bi.dtype)
    pj = np.empty(m, dtype=bj.dtype)
    psh = np.empty((m, 3), dtype=bs.dtype)
    k = 0
    for t in range(cnt.shape[0]):
        for p in range(off[t], off[t] + cnt[t]):
            pi[k] = bi[p]
            pj[k] = bj[p]
            for c in range(3):
                psh[k, c] = bs[p, c]
            k += 1
    return pi, pj, psh
