"""numba pair-force kernel of the DEM engine (the base contact model).

One ``prange`` pass over the compacted pair list: Hertz + damping, SJKR,
Mindlin history and rolling resistance. Work is split into ``T`` contiguous
chunks (``bounds``, length T+1); forces go to per-chunk buffers ``fbuf[t]``
that the integrator reduces in a fixed order, so results are deterministic
for a given number of chunks and free of races. The diagnosis extensions
(capillary bridges, contact ageing) live in :mod:`bedstruct.dem._kernels_ext`.

Positions of the periodic image of j are ``x_j + s L`` with the integer
image ``s`` stored per pair.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally

from .._numba import njit, prange
from ._kernels_contact import (ROLL_CDT, ROLL_EPSD, ROLL_EPSD2, ROLL_NONE, rolling_torque,
                               sjkr_area_pair, tangential_history)

__all__ = ["pair_forces"]

_FM = dict(fastmath=True)
_BLOCK = 64  # pairs per block of the two-pass loop


@njit(**_FM)
def _pair_chunk(t, x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf, tbuf,
                Y, G, B, GTR, MU, MUR, COH, rolling, limit, eta_r, dt, store, fn_out, ft_out):
    """Chunk ``t`` of :func:`pair_forces`, compiled for a constant rolling model."""
    literally(rolling)  # one specialisation per model: the others' code is not in the loop
    # scratch of one block: touching pairs (tk, with their separation) and the others (tn)
    tk = np.empty(_BLOCK, dtype=np.int64)
    tn = np.empty(_BLOCK, dtype=np.int64)
    sep = np.empty((_BLOCK, 4))
    fb = fbuf[t]  # this chunk's force and torque buffers
    tb = tbuf[t]
    for b0 in range(bounds[t], bounds[t + 1], _BLOCK):
        b1 = min(b0 + _BLOCK, bounds[t + 1])
        # pass 1: separations and the split touching / not touching, without a
        # data-dependent branch (the overlap test is a coin flip for ~30 % of the list)
        nb = 0
        nn = 0
        for k in range(b0, b1):
            i = pi[k]
            j = pj[k]
            dx = x[i, 0] - x[j, 0] - psh[k, 0] * L[0]
            dy = x[i, 1] - x[j, 1] - psh[k, 1] * L[1]
            dz = x[i, 2] - x[j, 2] - psh[k, 2] * L[2]
            r2 = dx * dx + dy * dy + dz * dz
            rs = rad[i] + rad[j]
            sep[nb, 0] = dx
            sep[nb, 1] = dy
            sep[nb, 2] = dz
            sep[nb, 3] = r2
            tk[nb] = k
            tn[nn] = k
            touch = r2 < rs * rs
            nb += 1 if touch else 0
            nn += 0 if touch else 1
        # pairs not touching lose their history
        for q in range(nn):
            k = tn[q]
            if ht[k, 0] != 0.0 or ht[k, 1] != 0.0 or ht[k, 2] != 0.0:
                ht[k, 0] = 0.0
                ht[k, 1] = 0.0
                ht[k, 2] = 0.0
            if hr[k, 0] != 0.0 or hr[k, 1] != 0.0 or hr[k, 2] != 0.0:
                hr[k, 0] = 0.0
                hr[k, 1] = 0.0
                hr[k, 2] = 0.0
            if store:
                fn_out[k] = 0.0
                ft_out[k, 0] = 0.0
                ft_out[k, 1] = 0.0
                ft_out[k, 2] = 0.0
        # pass 2: contact forces of the touching pairs
        for q in range(nb):
            # unsigned indices: no negative-index wraparound in the address arithmetic
            k = np.uint64(tk[q])
            i = np.uint32(pi[k])
            j = np.uint32(pj[k])
            dx = sep[q, 0]
            dy = sep[q, 1]
            dz = sep[q, 2]
            r2 = sep[q, 3]
            ri = rad[i]
            rj = rad[j]
            rs = ri + rj
            r = math.sqrt(r2)
            rinv = 1.0 / r
            e1 = dx * rinv
            e2 = dy * rinv
            e3 = dz * rinv
            delta = rs - r
            ti = np.uint32(ptype[i])
            tj = np.uint32(ptype[j])
            reff = ri * rj / rs
            mi = mass[i]
            mj = mass[j]
            meff = mi * mj / (mi + mj)
            # hertz_coefficients with one square root less: B holds
            # -2 sqrt(5/6) beta sqrt(2 Y*) and GTR sqrt(4 G*/Y*) (0: no tangential damping)
            sq = math.sqrt(reff * delta)
            kn = 4.0 / 3.0 * Y[ti, tj] * sq
            kt = 8.0 * G[ti, tj] * sq
            gn = B[ti, tj] * math.sqrt(sq * meff)
            gt = gn * GTR[ti, tj]
            vr1 = v[i, 0] - v[j, 0]
            vr2 = v[i, 1] - v[j, 1]
            vr3 = v[i, 2] - v[j, 2]
            vn = vr1 * e1 + vr2 * e2 + vr3 * e3
            fn = kn * delta - gn * vn
            if limit and fn < 0.0:
                fn = 0.0
            # Coulomb and rolling limits use Hertz + damping only: LIGGGHTS' default
            # (`tangential_reduce off`) adds cohesion to the force, not to the caps.
            fn_cap = fn
            k_coh = COH[ti, tj]
            if k_coh != 0.0:
                fn -= k_coh * sjkr_area_pair(r, ri, rj)
            cri = ri - 0.5 * delta
            crj = rj - 0.5 * delta
            w1 = cri * om[i, 0] + crj * om[j, 0]
            w2 = cri * om[i, 1] + crj * om[j, 1]
            w3 = cri * om[i, 2] + crj * om[j, 2]
            vt1 = vr1 - vn * e1 - (w2 * e3 - w3 * e2)
            vt2 = vr2 - vn * e2 - (w3 * e1 - w1 * e3)
            vt3 = vr3 - vn * e3 - (w1 * e2 - w2 * e1)
            s1, s2, s3, f1, f2, f3 = tangential_history(ht[k, 0], ht[k, 1], ht[k, 2], vt1, vt2, vt3,
                                                        e1, e2, e3, kt, gt, MU[ti, tj], fn_cap, dt)
            ht[k, 0] = s1
            ht[k, 1] = s2
            ht[k, 2] = s3
            # torque of Ft about each centre: -cr (en x Ft)
            c1 = e2 * f3 - e3 * f2
            c2 = e3 * f1 - e1 * f3
            c3 = e1 * f2 - e2 * f1
            ti1 = -cri * c1
            ti2 = -cri * c2
            ti3 = -cri * c3
            tj1 = -crj * c1
            tj2 = -crj * c2
            tj3 = -crj * c3
            if rolling != ROLL_NONE:
                mur = MUR[ti, tj]
                if mur > 0.0:
                    ieff = 0.0
                    if rolling == ROLL_EPSD:
                        ii = 1.0 / inv_i[i] + mi * ri * ri
                        ij = 1.0 / inv_i[j] + mj * rj * rj
                        ieff = ii * ij / (ii + ij)
                    h1, h2, h3, m1, m2, m3 = rolling_torque(
                        rolling, hr[k, 0], hr[k, 1], hr[k, 2], om[i, 0] - om[j, 0],
                        om[i, 1] - om[j, 1], om[i, 2] - om[j, 2], e1, e2, e3, kn, kt, delta,
                        reff, fn_cap, mur, dt, ieff, eta_r)
                    hr[k, 0] = h1
                    hr[k, 1] = h2
                    hr[k, 2] = h3
                    ti1 -= m1
                    ti2 -= m2
                    ti3 -= m3
                    tj1 += m1
                    tj2 += m2
                    tj3 += m3
            fx = fn * e1 + f1
            fy = fn * e2 + f2
            fz = fn * e3 + f3
            fb[i, 0] += fx
            fb[i, 1] += fy
            fb[i, 2] += fz
            fb[j, 0] -= fx
            fb[j, 1] -= fy
            fb[j, 2] -= fz
            tb[i, 0] += ti1
            tb[i, 1] += ti2
            tb[i, 2] += ti3
            tb[j, 0] += tj1
            tb[j, 1] += tj2
            tb[j, 2] += tj3
            if store:
                fn_out[k] = fn
                ft_out[k, 0] = f1
                ft_out[k, 1] = f2
                ft_out[k, 2] = f3


@njit(parallel=True, **_FM)
def _pair_forces_0(x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf, tbuf,
                   Y, G, B, GTR, MU, MUR, COH, limit, eta_r, dt, store, fn_out, ft_out):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk(t, x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf,
                    tbuf, Y, G, B, GTR, MU, MUR, COH, ROLL_NONE, limit, eta_r, dt, store, fn_out, ft_out)


@njit(parallel=True, **_FM)
def _pair_forces_1(x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf, tbuf,
                   Y, G, B, GTR, MU, MUR, COH, limit, eta_r, dt, store, fn_out, ft_out):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk(t, x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf,
                    tbuf, Y, G, B, GTR, MU, MUR, COH, ROLL_CDT, limit, eta_r, dt, store, fn_out, ft_out)


@njit(parallel=True, **_FM)
def _pair_forces_2(x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf, tbuf,
                   Y, G, B, GTR, MU, MUR, COH, limit, eta_r, dt, store, fn_out, ft_out):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk(t, x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf,
                    tbuf, Y, G, B, GTR, MU, MUR, COH, ROLL_EPSD, limit, eta_r, dt, store, fn_out, ft_out)


@njit(parallel=True, **_FM)
def _pair_forces_3(x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf, tbuf,
                   Y, G, B, GTR, MU, MUR, COH, limit, eta_r, dt, store, fn_out, ft_out):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk(t, x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf,
                    tbuf, Y, G, B, GTR, MU, MUR, COH, ROLL_EPSD2, limit, eta_r, dt, store, fn_out, ft_out)


# one compiled kernel per rolling model: the model is a compile-time constant there, so
# the other models' code is gone from the hot loop (~10 % faster than a runtime switch)
_BY_ROLLING = (_pair_forces_0, _pair_forces_1, _pair_forces_2, _pair_forces_3)


def pair_forces(x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf, tbuf,
                Y, G, B, GTR, MU, MUR, COH, rolling, limit, eta_r, dt, store, fn_out, ft_out):
    """Contact forces of the pair list into per-chunk buffers (history updated in place).

    ``B = -2 sqrt(5/6) beta sqrt(2 Y*)`` and ``GTR = sqrt(4 G*/Y*)`` (0 without
    tangential damping) per type pair, so that ``gamma_n = B sqrt(sqrt(R* delta) m*)``
    and ``gamma_t = GTR gamma_n`` equal :func:`hertz_coefficients`.

    The list is processed in blocks of ``_BLOCK`` pairs: a short first pass
    computes separations and splits the block into touching and other pairs
    without branching on the overlap test; the second pass computes the
    contacts. Per pair the arithmetic, and the order in which forces are
    added, are those of a single loop over the list (bit for bit).
    """
    _BY_ROLLING[rolling](x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf,
                         tbuf, Y, G, B, GTR, MU, MUR, COH, limit, eta_r, dt, store, fn_out, ft_out)
