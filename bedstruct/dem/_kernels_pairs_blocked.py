"""numba pair-force kernel of the DEM engine: the blocked (gather-compute-scatter) pass.

The engine's default pass without capillary bridges and ageing
(:func:`bedstruct.dem._kernels_pairs.pair_forces` with ``blocked=True``). Per block of
the pair list it gathers the touching pairs' data into a small contiguous scratch
that stays in the L1 cache, runs the contact law over the scratch in a loop without
calls or indirect addresses that LLVM vectorises, and scatters forces, torques and
history back in pair order. The contact law is the single loop's
(:data:`~bedstruct.dem._kernels_contact.pair_contact`), rounded as written, so a pair's
force does not depend on its place in a block and the results equal the single loop's
(:mod:`bedstruct.dem._kernels_pairs`) bit for bit.

One compiled kernel per rolling model (:data:`BLOCKED_BY_ROLLING`, indexed by the
``ROLL_*`` code), with the EPSD stiffness factor compiled in or passed.
"""

from __future__ import annotations

import numpy as np
from numba import literally

from .._numba import njit, prange
from ._kernels_contact import (ROLL_CDT, ROLL_EPSD, ROLL_EPSD2, ROLL_NONE, STRICT, _open_pair,
                               law_rows, pair_contact)

__all__ = ["BLOCKED_BY_ROLLING"]

_FM = dict(fastmath=True)


#: Pairs per block of the blocked pass: its scratch (45 rows of 32 doubles, 11.5 kB) stays in
#: the L1 cache (256 pairs, 92 kB, ran slower than the single loop).
_BLOCK_B = 32
# rows of the scratch of one block in the blocked pass (row r holds pairs r*_BLOCK_B + q):
# what the gather reads (geometry, radii, masses, velocities, type-pair constants, history)
_DX, _DY, _DZ, _R2, _RI, _RJ, _MI, _MJ, _VR1, _VR2, _VR3, _OI1, _OI2, _OI3, _OJ1, _OJ2, _OJ3, \
    _Y, _G, _B, _GTR, _MU, _MUR, _COH, _S1, _S2, _S3, _H1, _H2, _H3, _II, _IJ = range(32)
# and what the contact law writes for the scatter (force on i, torques, history, outputs)
_FX, _FY, _FZ, _TI1, _TI2, _TI3, _TJ1, _TJ2, _TJ3, _FN, _F1, _F2, _F3 = range(32, 45)
_NROW = 45
# unsigned index constants: with unsigned indices numba emits no wrap-around of negative
# indices, which costs the gather about as many instructions as its loads and stores
_U1 = np.uint64(1)
_U2 = np.uint64(2)
_U3 = np.uint64(3)

@njit(**STRICT)
def _pair_chunk_blocked(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, rolling, limit, eta_r, dt,
                        store, fn_out, ft_out, kr_fac):
    """Chunk ``t`` of :func:`pair_forces` in gather-compute-scatter blocks (no capillary
    bridges, no ageing): per block, the pairs' separations are computed and the block split
    into touching pairs and pairs apart (a pair apart is overwritten by the next), the
    touching pairs' data are gathered into one contiguous scratch
    (``S[row * _BLOCK_B + q]``), the contact law runs over the scratch in a loop without
    calls or indirect addresses (vectorised by LLVM), and the forces, torques and history
    are scattered back in pair order."""
    literally(rolling)
    x, v, om, rad, mass, inv_i, ptype = P
    # positions, velocities and spins read as flat views (row i at 3 i): fewer live strides
    xf = x.reshape(-1)
    vf = v.reshape(-1)
    of = om.reshape(-1)
    pi, pj, psh = PL
    ht, hr = hist
    Y, G, B, GTR, MU, MUR, COH, krf = law_rows(TAB, kr_fac)
    tk = np.empty(_BLOCK_B, dtype=np.int64)
    tn = np.empty(_BLOCK_B, dtype=np.int64)
    S = np.empty(_NROW * _BLOCK_B)
    fb = fbuf[t]
    tb = tbuf[t]
    for b0 in range(bounds[t], bounds[t + 1], _BLOCK_B):
        b1 = min(b0 + _BLOCK_B, bounds[t + 1])
        # separations and the split touching / not, without a data-dependent branch
        nb = 0
        nn = 0
        for k in range(b0, b1):
            ku = np.uint64(k)
            i = np.uint64(pi[ku])
            j = np.uint64(pj[ku])
            i3 = _U3 * i
            j3 = _U3 * j
            dx = xf[i3] - xf[j3] - psh[ku, 0] * L[0]
            dy = xf[i3 + _U1] - xf[j3 + _U1] - psh[ku, 1] * L[1]
            dz = xf[i3 + _U2] - xf[j3 + _U2] - psh[ku, 2] * L[2]
            r2 = dx * dx + dy * dy + dz * dz
            ri = rad[i]
            rj = rad[j]
            rs = ri + rj
            S[_DX * _BLOCK_B + nb] = dx
            S[_DY * _BLOCK_B + nb] = dy
            S[_DZ * _BLOCK_B + nb] = dz
            S[_R2 * _BLOCK_B + nb] = r2
            S[_RI * _BLOCK_B + nb] = ri
            S[_RJ * _BLOCK_B + nb] = rj
            tk[nb] = k
            tn[nn] = k
            touch = r2 < rs * rs
            nb += 1 if touch else 0
            nn += 0 if touch else 1
        # the touching pairs' other data, contact by contact
        for q in range(nb):
            k = np.uint64(tk[q])
            i = np.uint64(pi[k])
            j = np.uint64(pj[k])
            i3 = _U3 * i
            j3 = _U3 * j
            ti = np.uint32(ptype[i])
            tj = np.uint32(ptype[j])
            S[_MI * _BLOCK_B + q] = mass[i]
            S[_MJ * _BLOCK_B + q] = mass[j]
            S[_VR1 * _BLOCK_B + q] = vf[i3] - vf[j3]
            S[_VR2 * _BLOCK_B + q] = vf[i3 + _U1] - vf[j3 + _U1]
            S[_VR3 * _BLOCK_B + q] = vf[i3 + _U2] - vf[j3 + _U2]
            S[_OI1 * _BLOCK_B + q] = of[i3]
            S[_OI2 * _BLOCK_B + q] = of[i3 + _U1]
            S[_OI3 * _BLOCK_B + q] = of[i3 + _U2]
            S[_OJ1 * _BLOCK_B + q] = of[j3]
            S[_OJ2 * _BLOCK_B + q] = of[j3 + _U1]
            S[_OJ3 * _BLOCK_B + q] = of[j3 + _U2]
            S[_Y * _BLOCK_B + q] = Y[ti, tj]
            S[_G * _BLOCK_B + q] = G[ti, tj]
            S[_B * _BLOCK_B + q] = B[ti, tj]
            S[_GTR * _BLOCK_B + q] = GTR[ti, tj]
            S[_MU * _BLOCK_B + q] = MU[ti, tj]
            S[_COH * _BLOCK_B + q] = COH[ti, tj]
            S[_S1 * _BLOCK_B + q] = ht[k, 0]
            S[_S2 * _BLOCK_B + q] = ht[k, 1]
            S[_S3 * _BLOCK_B + q] = ht[k, 2]
            if rolling != ROLL_NONE:
                S[_MUR * _BLOCK_B + q] = MUR[ti, tj]
                S[_H1 * _BLOCK_B + q] = hr[k, 0]
                S[_H2 * _BLOCK_B + q] = hr[k, 1]
                S[_H3 * _BLOCK_B + q] = hr[k, 2]
            if rolling == ROLL_EPSD:
                S[_II * _BLOCK_B + q] = inv_i[i]
                S[_IJ * _BLOCK_B + q] = inv_i[j]
        for q in range(nn):
            k = np.uint64(tn[q])
            _open_pair(k, ht, hr, store, fn_out, ft_out)
            if store:
                fn_out[k] = 0.0
        # the contact law over the block
        for q in range(nb):
            mur = 0.0
            h1 = 0.0
            h2 = 0.0
            h3 = 0.0
            if rolling != ROLL_NONE:
                mur = S[_MUR * _BLOCK_B + q]
                h1 = S[_H1 * _BLOCK_B + q]
                h2 = S[_H2 * _BLOCK_B + q]
                h3 = S[_H3 * _BLOCK_B + q]
            inv_ii = 0.0
            inv_ij = 0.0
            if rolling == ROLL_EPSD:
                inv_ii = S[_II * _BLOCK_B + q]
                inv_ij = S[_IJ * _BLOCK_B + q]
            (fn, f1, f2, f3, s1, s2, s3, h1, h2, h3, ti1, ti2, ti3, tj1, tj2, tj3, e1, e2, e3,
             _, _, _) = pair_contact(
                S[_DX * _BLOCK_B + q], S[_DY * _BLOCK_B + q], S[_DZ * _BLOCK_B + q],
                S[_R2 * _BLOCK_B + q], S[_RI * _BLOCK_B + q], S[_RJ * _BLOCK_B + q],
                S[_MI * _BLOCK_B + q], S[_MJ * _BLOCK_B + q],
                (S[_VR1 * _BLOCK_B + q], S[_VR2 * _BLOCK_B + q], S[_VR3 * _BLOCK_B + q]),
                (S[_OI1 * _BLOCK_B + q], S[_OI2 * _BLOCK_B + q], S[_OI3 * _BLOCK_B + q]),
                (S[_OJ1 * _BLOCK_B + q], S[_OJ2 * _BLOCK_B + q], S[_OJ3 * _BLOCK_B + q]),
                S[_Y * _BLOCK_B + q], S[_G * _BLOCK_B + q], S[_B * _BLOCK_B + q],
                S[_GTR * _BLOCK_B + q], S[_MU * _BLOCK_B + q], mur, S[_COH * _BLOCK_B + q],
                0.0, 0.0, (S[_S1 * _BLOCK_B + q], S[_S2 * _BLOCK_B + q], S[_S3 * _BLOCK_B + q]),
                (h1, h2, h3), inv_ii, inv_ij, rolling, limit, eta_r, dt, krf)
            S[_S1 * _BLOCK_B + q] = s1
            S[_S2 * _BLOCK_B + q] = s2
            S[_S3 * _BLOCK_B + q] = s3
            if rolling != ROLL_NONE:
                S[_H1 * _BLOCK_B + q] = h1
                S[_H2 * _BLOCK_B + q] = h2
                S[_H3 * _BLOCK_B + q] = h3
            S[_FX * _BLOCK_B + q] = fn * e1 + f1
            S[_FY * _BLOCK_B + q] = fn * e2 + f2
            S[_FZ * _BLOCK_B + q] = fn * e3 + f3
            S[_TI1 * _BLOCK_B + q] = ti1
            S[_TI2 * _BLOCK_B + q] = ti2
            S[_TI3 * _BLOCK_B + q] = ti3
            S[_TJ1 * _BLOCK_B + q] = tj1
            S[_TJ2 * _BLOCK_B + q] = tj2
            S[_TJ3 * _BLOCK_B + q] = tj3
            S[_FN * _BLOCK_B + q] = fn
            S[_F1 * _BLOCK_B + q] = f1
            S[_F2 * _BLOCK_B + q] = f2
            S[_F3 * _BLOCK_B + q] = f3
        # scatter, in pair order (the order of the additions of the single loop)
        for q in range(nb):
            k = np.uint64(tk[q])
            i = np.uint32(pi[k])
            j = np.uint32(pj[k])
            fx = S[_FX * _BLOCK_B + q]
            fy = S[_FY * _BLOCK_B + q]
            fz = S[_FZ * _BLOCK_B + q]
            fb[i, 0] += fx
            fb[i, 1] += fy
            fb[i, 2] += fz
            fb[j, 0] -= fx
            fb[j, 1] -= fy
            fb[j, 2] -= fz
            tb[i, 0] += S[_TI1 * _BLOCK_B + q]
            tb[i, 1] += S[_TI2 * _BLOCK_B + q]
            tb[i, 2] += S[_TI3 * _BLOCK_B + q]
            tb[j, 0] += S[_TJ1 * _BLOCK_B + q]
            tb[j, 1] += S[_TJ2 * _BLOCK_B + q]
            tb[j, 2] += S[_TJ3 * _BLOCK_B + q]
            ht[k, 0] = S[_S1 * _BLOCK_B + q]
            ht[k, 1] = S[_S2 * _BLOCK_B + q]
            ht[k, 2] = S[_S3 * _BLOCK_B + q]
            if rolling != ROLL_NONE:
                hr[k, 0] = S[_H1 * _BLOCK_B + q]
                hr[k, 1] = S[_H2 * _BLOCK_B + q]
                hr[k, 2] = S[_H3 * _BLOCK_B + q]
            if store:
                fn_out[k] = S[_FN * _BLOCK_B + q]
                ft_out[k, 0] = S[_F1 * _BLOCK_B + q]
                ft_out[k, 1] = S[_F2 * _BLOCK_B + q]
                ft_out[k, 2] = S[_F3 * _BLOCK_B + q]


@njit(parallel=True, **_FM)
def _pair_forces_blocked_0(P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store,
                           fn_out, ft_out, kr_fac):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk_blocked(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, ROLL_NONE, limit, eta_r,
                            dt, store, fn_out, ft_out, kr_fac)


@njit(parallel=True, **_FM)
def _pair_forces_blocked_1(P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store,
                           fn_out, ft_out, kr_fac):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk_blocked(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, ROLL_CDT, limit, eta_r,
                            dt, store, fn_out, ft_out, kr_fac)


@njit(parallel=True, **_FM)
def _pair_forces_blocked_2(P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store,
                           fn_out, ft_out, kr_fac):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk_blocked(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, ROLL_EPSD, limit, eta_r,
                            dt, store, fn_out, ft_out, kr_fac)


@njit(parallel=True, **_FM)
def _pair_forces_blocked_3(P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store,
                           fn_out, ft_out, kr_fac):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk_blocked(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, ROLL_EPSD2, limit, eta_r,
                            dt, store, fn_out, ft_out, kr_fac)


#: The blocked pass of each rolling model, indexed by its ``ROLL_*`` code.
BLOCKED_BY_ROLLING = (_pair_forces_blocked_0, _pair_forces_blocked_1, _pair_forces_blocked_2,
                      _pair_forces_blocked_3)
