"""numba pair-force kernel of the DEM engine.

One ``prange`` pass over the compacted pair list: Hertz + damping, SJKR,
Mindlin history and rolling resistance, with the diagnosis extensions
(capillary bridges, contact ageing, an EPSD rolling stiffness factor other
than 2.25) compiled in only when they are on. The contact arithmetic comes
from the inline functions of :mod:`bedstruct.dem._kernels_contact`.

Work is split into ``T`` contiguous chunks (``bounds``, length T+1); forces go
to per-chunk buffers ``fbuf[t]`` that the integrator reduces in a fixed order,
so results are deterministic for a given number of chunks and free of races.
Positions of the periodic image of j are ``x_j + s L`` with the integer image
``s`` stored per pair.

Compile-time selection: the rolling model is a literal (one compiled kernel
per model, the others' code is not in the loop); each extension is an
argument that is either its parameters or ``None``, and numba compiles the
``None`` case without the extension's code (a type, so the choice costs no
dispatch time per call).

Two passes compute the same contact law. The blocked pass (the engine's
default without capillary bridges and ageing) gathers the touching pairs of
a block into a small contiguous scratch, runs the contact law over it in a
loop that LLVM vectorises, and scatters forces, torques and history back in
pair order. The single loop computes each pair where it finds it; it carries
the extensions and is the pass whose rounding the reference trajectories
record. Their results differ in the last bits only: the single loop's
fast-math lets LLVM reassociate and fuse multiply-adds, the blocked loop
rounds every operation as written (so a pair's force does not depend on its
place in a block).
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally

from .._numba import njit, prange
from ._kernels_contact import (EPSD_STIFFNESS_FACTOR, ROLL_CDT, ROLL_EPSD, ROLL_EPSD2, ROLL_NONE,
                               ageing_bond, capillary_force, hertz_stiffness, normal_force,
                               pair_damping, rolling_torque, shear_torques, sjkr_area_pair,
                               tangential_history, tangential_velocity)

__all__ = ["pair_forces", "pair_table", "TAB_YOUNGS", "TAB_SHEAR", "TAB_DAMPING",
           "TAB_DAMPING_RATIO", "TAB_FRICTION", "TAB_ROLLING_FRICTION", "TAB_COHESION"]

_FM = dict(fastmath=True)
_BLOCK = 64  # pairs per block of the two-pass loop

#: Rows of the per-type-pair table ``TAB`` (see :func:`pair_table`).
TAB_YOUNGS, TAB_SHEAR, TAB_DAMPING, TAB_DAMPING_RATIO, TAB_FRICTION, TAB_ROLLING_FRICTION, \
    TAB_COHESION = range(7)


def pair_table(youngs, shear, beta, friction, rolling_friction, cohesion, tangential_damping):
    """The per-type-pair constants of the pair kernel as one ``(7, T+1, T+1)`` array.

    Rows: ``Y*``, ``G*``, ``B = -2 sqrt(5/6) beta sqrt(2 Y*)``,
    ``GTR = sqrt(4 G*/Y*)`` (0 without tangential damping), ``mu``, ``mu_r`` and
    the SJKR cohesion energy density, so that ``gamma_n = B sqrt(sqrt(R* delta) m*)``
    and ``gamma_t = GTR gamma_n`` equal :func:`hertz_coefficients`.
    """
    gn_coef = -2.0 * math.sqrt(5.0 / 6.0) * beta * np.sqrt(2.0 * youngs)
    gt_ratio = np.sqrt(4.0 * shear / youngs) if tangential_damping else np.zeros_like(youngs)
    return np.ascontiguousarray(np.stack([youngs, shear, gn_coef, gt_ratio, friction,
                                          rolling_friction, cohesion]), dtype=np.float64)


@njit(inline="always", **_FM)
def _open_pair(k, ht, hr, store, fn_out, ft_out):
    """A pair apart: its history is cleared (written only when set) and no force stored."""
    if ht[k, 0] != 0.0 or ht[k, 1] != 0.0 or ht[k, 2] != 0.0:
        ht[k, 0] = 0.0
        ht[k, 1] = 0.0
        ht[k, 2] = 0.0
    if hr[k, 0] != 0.0 or hr[k, 1] != 0.0 or hr[k, 2] != 0.0:
        hr[k, 0] = 0.0
        hr[k, 1] = 0.0
        hr[k, 2] = 0.0
    if store:
        ft_out[k, 0] = 0.0
        ft_out[k, 1] = 0.0
        ft_out[k, 2] = 0.0


@njit(**_FM)
def _pair_chunk(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, rolling, limit, eta_r, dt, store,
                fn_out, ft_out, cap, age, kr_fac):
    """Chunk ``t`` of :func:`pair_forces`, compiled for a constant rolling model and
    for the extensions passed (``cap``, ``age``, ``kr_fac`` not None)."""
    literally(rolling)  # one specialisation per model: the others' code is not in the loop
    x, v, om, rad, mass, inv_i, ptype = P
    pi, pj, psh = PL
    ht, hr = hist
    Y = TAB[TAB_YOUNGS]
    G = TAB[TAB_SHEAR]
    B = TAB[TAB_DAMPING]
    GTR = TAB[TAB_DAMPING_RATIO]
    MU = TAB[TAB_FRICTION]
    MUR = TAB[TAB_ROLLING_FRICTION]
    COH = TAB[TAB_COHESION]
    if kr_fac is None:
        krf = EPSD_STIFFNESS_FACTOR
    else:
        krf = kr_fac
    # scratch of one block: active pairs (tk, with their separation) and the others (tn)
    tk = np.empty(_BLOCK, dtype=np.int64)
    tn = np.empty(_BLOCK, dtype=np.int64)
    sep = np.empty((_BLOCK, 4))
    fb = fbuf[t]  # this chunk's force and torque buffers
    tb = tbuf[t]
    for b0 in range(bounds[t], bounds[t + 1], _BLOCK):
        b1 = min(b0 + _BLOCK, bounds[t + 1])
        # pass 1: separations and the split active / not, without a data-dependent
        # branch (the overlap test is a coin flip for ~30 % of the list). Active are
        # the touching pairs, and every pair when liquid bridges act across gaps.
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
            if cap is None:
                touch = r2 < rs * rs
            else:
                touch = True
            nb += 1 if touch else 0
            nn += 0 if touch else 1
        # pairs not touching lose their history
        for q in range(nn):
            k = tn[q]
            _open_pair(k, ht, hr, store, fn_out, ft_out)
            if store:
                fn_out[k] = 0.0
            if age is not None:
                age[0][k, 0] = 0.0
                age[0][k, 1] = 0.0
                age[0][k, 2] = 0.0
        # pass 2: contact forces of the active pairs
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
            if cap is not None:
                if r2 >= rs * rs:  # a pair apart, held by a liquid bridge up to its rupture
                    if age is not None:
                        age[0][k, 0] = 0.0
                        age[0][k, 1] = 0.0
                        age[0][k, 2] = 0.0
                    r = math.sqrt(r2)
                    fcap = capillary_force(r - rs, ri * rj / rs, cap)
                    if fcap != 0.0:
                        # attractive: pulls i towards j along -n
                        c = -fcap / r
                        fb[i, 0] += c * dx
                        fb[i, 1] += c * dy
                        fb[i, 2] += c * dz
                        fb[j, 0] -= c * dx
                        fb[j, 1] -= c * dy
                        fb[j, 2] -= c * dz
                    _open_pair(k, ht, hr, store, fn_out, ft_out)
                    if store:
                        fn_out[k] = -fcap
                    continue
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
            sq = math.sqrt(reff * delta)
            kn, kt = hertz_stiffness(sq, Y[ti, tj], G[ti, tj])
            gn, gt = pair_damping(sq, meff, B[ti, tj], GTR[ti, tj])
            vr1 = v[i, 0] - v[j, 0]
            vr2 = v[i, 1] - v[j, 1]
            vr3 = v[i, 2] - v[j, 2]
            vn = vr1 * e1 + vr2 * e2 + vr3 * e3
            fn = normal_force(kn, delta, gn, vn, limit)
            # Coulomb and rolling limits use Hertz + damping only: LIGGGHTS' default
            # (`tangential_reduce off`) adds cohesion to the force, not to the caps.
            fn_cap = fn
            k_coh = COH[ti, tj]
            if k_coh != 0.0:
                fn -= k_coh * sjkr_area_pair(r, ri, rj)
            if cap is not None:
                fn -= capillary_force(0.0, reff, cap)
            if age is not None:
                if age[0][k, 2] == 0.0 and age[1][0] != 0.0:
                    fn -= ageing_bond(k_coh, sjkr_area_pair(r, ri, rj), age[0][k, 0], age[1])
            cri = ri - 0.5 * delta
            crj = rj - 0.5 * delta
            vt1, vt2, vt3 = tangential_velocity(vr1, vr2, vr3, vn, e1, e2, e3,
                                                cri * om[i, 0] + crj * om[j, 0],
                                                cri * om[i, 1] + crj * om[j, 1],
                                                cri * om[i, 2] + crj * om[j, 2])
            if age is not None:
                # the spring the step would reach without the Coulomb cap (as tangential_history)
                u1 = ht[k, 0] + vt1 * dt
                u2 = ht[k, 1] + vt2 * dt
                u3 = ht[k, 2] + vt3 * dt
                un = u1 * e1 + u2 * e2 + u3 * e3
                trial = math.sqrt((u1 - un * e1) ** 2 + (u2 - un * e2) ** 2 + (u3 - un * e3) ** 2)
            s1, s2, s3, f1, f2, f3 = tangential_history(ht[k, 0], ht[k, 1], ht[k, 2], vt1, vt2, vt3,
                                                        e1, e2, e3, kt, gt, MU[ti, tj], fn_cap,
                                                        dt)
            ht[k, 0] = s1
            ht[k, 1] = s2
            ht[k, 2] = s3
            if age is not None:
                hx = age[0]
                if hx[k, 2] == 0.0:
                    hx[k, 0] += dt
                    # sliding, not elastic shear: what the Coulomb cap cut off the spring (an
                    # elastic tangential displacement is recovered; only sliding breaks the bond)
                    hx[k, 1] += max(trial - math.sqrt(s1 * s1 + s2 * s2 + s3 * s3), 0.0)
                    if hx[k, 1] > age[1][3]:
                        hx[k, 2] = 1.0
            ti1, ti2, ti3, tj1, tj2, tj3 = shear_torques(e1, e2, e3, f1, f2, f3, cri, crj)
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
                        reff, fn_cap, mur, dt, ieff, eta_r, krf)
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

# The blocked contact loop rounds every operation as written (fast-math without
# reassociation or contraction into fused multiply-adds): its vectorised body and its scalar
# remainder then give a pair the same bits whichever lane or position it has in a block.
_STRICT = dict(fastmath={"nnan", "ninf", "nsz"})
# the history spring, the rolling torque and the SJKR lens inlined into that loop (the same
# functions, compiled inline), so that the loop has no calls and LLVM can vectorise it
_tangential_history = njit(inline="always", **_STRICT)(tangential_history.py_func)
_rolling_torque = njit(inline="always", **_STRICT)(rolling_torque.py_func)
_sjkr_area_pair = njit(inline="always", **_STRICT)(sjkr_area_pair.py_func)


@njit(**_STRICT)
def _pair_chunk_blocked(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, rolling, limit, eta_r, dt,
                        store, fn_out, ft_out, kr_fac):
    """Chunk ``t`` of :func:`pair_forces` in gather-compute-scatter blocks (no capillary
    bridges, no ageing): per block, the touching pairs' data are gathered into one
    contiguous scratch (``S[row * _BLOCK_B + q]``) while the block is split (a pair apart
    is overwritten by the next), the contact law runs over the scratch in a loop without
    calls or indirect addresses (vectorised by LLVM), and the forces, torques and history
    are scattered back in pair order."""
    literally(rolling)
    x, v, om, rad, mass, inv_i, ptype = P
    pi, pj, psh = PL
    ht, hr = hist
    Y = TAB[TAB_YOUNGS]
    G = TAB[TAB_SHEAR]
    B = TAB[TAB_DAMPING]
    GTR = TAB[TAB_DAMPING_RATIO]
    MU = TAB[TAB_FRICTION]
    MUR = TAB[TAB_ROLLING_FRICTION]
    COH = TAB[TAB_COHESION]
    if kr_fac is None:
        krf = EPSD_STIFFNESS_FACTOR
    else:
        krf = kr_fac
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
            i = pi[k]
            j = pj[k]
            dx = x[i, 0] - x[j, 0] - psh[k, 0] * L[0]
            dy = x[i, 1] - x[j, 1] - psh[k, 1] * L[1]
            dz = x[i, 2] - x[j, 2] - psh[k, 2] * L[2]
            r2 = dx * dx + dy * dy + dz * dz
            rs = rad[i] + rad[j]
            S[_DX * _BLOCK_B + nb] = dx
            S[_DY * _BLOCK_B + nb] = dy
            S[_DZ * _BLOCK_B + nb] = dz
            S[_R2 * _BLOCK_B + nb] = r2
            ti = np.uint32(ptype[i])
            tj = np.uint32(ptype[j])
            S[_RI * _BLOCK_B + nb] = rad[i]
            S[_RJ * _BLOCK_B + nb] = rad[j]
            S[_MI * _BLOCK_B + nb] = mass[i]
            S[_MJ * _BLOCK_B + nb] = mass[j]
            S[_VR1 * _BLOCK_B + nb] = v[i, 0] - v[j, 0]
            S[_VR2 * _BLOCK_B + nb] = v[i, 1] - v[j, 1]
            S[_VR3 * _BLOCK_B + nb] = v[i, 2] - v[j, 2]
            S[_OI1 * _BLOCK_B + nb] = om[i, 0]
            S[_OI2 * _BLOCK_B + nb] = om[i, 1]
            S[_OI3 * _BLOCK_B + nb] = om[i, 2]
            S[_OJ1 * _BLOCK_B + nb] = om[j, 0]
            S[_OJ2 * _BLOCK_B + nb] = om[j, 1]
            S[_OJ3 * _BLOCK_B + nb] = om[j, 2]
            S[_Y * _BLOCK_B + nb] = Y[ti, tj]
            S[_G * _BLOCK_B + nb] = G[ti, tj]
            S[_B * _BLOCK_B + nb] = B[ti, tj]
            S[_GTR * _BLOCK_B + nb] = GTR[ti, tj]
            S[_MU * _BLOCK_B + nb] = MU[ti, tj]
            S[_COH * _BLOCK_B + nb] = COH[ti, tj]
            S[_S1 * _BLOCK_B + nb] = ht[k, 0]
            S[_S2 * _BLOCK_B + nb] = ht[k, 1]
            S[_S3 * _BLOCK_B + nb] = ht[k, 2]
            if rolling != ROLL_NONE:
                S[_MUR * _BLOCK_B + nb] = MUR[ti, tj]
                S[_H1 * _BLOCK_B + nb] = hr[k, 0]
                S[_H2 * _BLOCK_B + nb] = hr[k, 1]
                S[_H3 * _BLOCK_B + nb] = hr[k, 2]
            if rolling == ROLL_EPSD:
                S[_II * _BLOCK_B + nb] = inv_i[i]
                S[_IJ * _BLOCK_B + nb] = inv_i[j]
            tk[nb] = k
            tn[nn] = k
            touch = r2 < rs * rs
            nb += 1 if touch else 0
            nn += 0 if touch else 1
        for q in range(nn):
            k = tn[q]
            _open_pair(k, ht, hr, store, fn_out, ft_out)
            if store:
                fn_out[k] = 0.0
        # the contact law over the block (the arithmetic of _pair_chunk, pair by pair)
        for q in range(nb):
            dx = S[_DX * _BLOCK_B + q]
            dy = S[_DY * _BLOCK_B + q]
            dz = S[_DZ * _BLOCK_B + q]
            r2 = S[_R2 * _BLOCK_B + q]
            ri = S[_RI * _BLOCK_B + q]
            rj = S[_RJ * _BLOCK_B + q]
            rs = ri + rj
            r = math.sqrt(r2)
            rinv = 1.0 / r
            e1 = dx * rinv
            e2 = dy * rinv
            e3 = dz * rinv
            delta = rs - r
            reff = ri * rj / rs
            mi = S[_MI * _BLOCK_B + q]
            mj = S[_MJ * _BLOCK_B + q]
            meff = mi * mj / (mi + mj)
            sq = math.sqrt(reff * delta)
            kn, kt = hertz_stiffness(sq, S[_Y * _BLOCK_B + q], S[_G * _BLOCK_B + q])
            gn, gt = pair_damping(sq, meff, S[_B * _BLOCK_B + q], S[_GTR * _BLOCK_B + q])
            vr1 = S[_VR1 * _BLOCK_B + q]
            vr2 = S[_VR2 * _BLOCK_B + q]
            vr3 = S[_VR3 * _BLOCK_B + q]
            vn = vr1 * e1 + vr2 * e2 + vr3 * e3
            fn = normal_force(kn, delta, gn, vn, limit)
            fn_cap = fn
            k_coh = S[_COH * _BLOCK_B + q]
            if k_coh != 0.0:
                fn -= k_coh * _sjkr_area_pair(r, ri, rj)
            cri = ri - 0.5 * delta
            crj = rj - 0.5 * delta
            oi1 = S[_OI1 * _BLOCK_B + q]
            oi2 = S[_OI2 * _BLOCK_B + q]
            oi3 = S[_OI3 * _BLOCK_B + q]
            oj1 = S[_OJ1 * _BLOCK_B + q]
            oj2 = S[_OJ2 * _BLOCK_B + q]
            oj3 = S[_OJ3 * _BLOCK_B + q]
            vt1, vt2, vt3 = tangential_velocity(vr1, vr2, vr3, vn, e1, e2, e3,
                                                cri * oi1 + crj * oj1,
                                                cri * oi2 + crj * oj2,
                                                cri * oi3 + crj * oj3)
            s1, s2, s3, f1, f2, f3 = _tangential_history(
                S[_S1 * _BLOCK_B + q], S[_S2 * _BLOCK_B + q], S[_S3 * _BLOCK_B + q], vt1, vt2, vt3,
                e1, e2, e3, kt, gt, S[_MU * _BLOCK_B + q], fn_cap, dt)
            S[_S1 * _BLOCK_B + q] = s1
            S[_S2 * _BLOCK_B + q] = s2
            S[_S3 * _BLOCK_B + q] = s3
            ti1, ti2, ti3, tj1, tj2, tj3 = shear_torques(e1, e2, e3, f1, f2, f3, cri, crj)
            if rolling != ROLL_NONE:
                mur = S[_MUR * _BLOCK_B + q]
                if mur > 0.0:
                    ieff = 0.0
                    if rolling == ROLL_EPSD:
                        ii = 1.0 / S[_II * _BLOCK_B + q] + mi * ri * ri
                        ij = 1.0 / S[_IJ * _BLOCK_B + q] + mj * rj * rj
                        ieff = ii * ij / (ii + ij)
                    h1, h2, h3, m1, m2, m3 = _rolling_torque(
                        rolling,
                        S[_H1 * _BLOCK_B + q], S[_H2 * _BLOCK_B + q], S[_H3 * _BLOCK_B + q],
                        oi1 - oj1, oi2 - oj2, oi3 - oj3, e1, e2, e3, kn, kt, delta,
                        reff, fn_cap, mur, dt, ieff, eta_r, krf)
                    S[_H1 * _BLOCK_B + q] = h1
                    S[_H2 * _BLOCK_B + q] = h2
                    S[_H3 * _BLOCK_B + q] = h3
                    ti1 -= m1
                    ti2 -= m2
                    ti3 -= m3
                    tj1 += m1
                    tj2 += m2
                    tj3 += m3
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
def _pair_forces_0(P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store, fn_out,
                   ft_out, cap, age, kr_fac):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, ROLL_NONE, limit, eta_r, dt,
                    store, fn_out, ft_out, cap, age, kr_fac)


@njit(parallel=True, **_FM)
def _pair_forces_1(P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store, fn_out,
                   ft_out, cap, age, kr_fac):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, ROLL_CDT, limit, eta_r, dt,
                    store, fn_out, ft_out, cap, age, kr_fac)


@njit(parallel=True, **_FM)
def _pair_forces_2(P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store, fn_out,
                   ft_out, cap, age, kr_fac):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, ROLL_EPSD, limit, eta_r, dt,
                    store, fn_out, ft_out, cap, age, kr_fac)


@njit(parallel=True, **_FM)
def _pair_forces_3(P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store, fn_out,
                   ft_out, cap, age, kr_fac):
    for t in prange(bounds.shape[0] - 1):
        _pair_chunk(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, ROLL_EPSD2, limit, eta_r, dt,
                    store, fn_out, ft_out, cap, age, kr_fac)


# one compiled kernel per rolling model: the model is a compile-time constant there, so
# the other models' code is gone from the hot loop (~10 % faster than a runtime switch)
_BY_ROLLING = (_pair_forces_0, _pair_forces_1, _pair_forces_2, _pair_forces_3)


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


_BLOCKED_BY_ROLLING = (_pair_forces_blocked_0, _pair_forces_blocked_1, _pair_forces_blocked_2,
                       _pair_forces_blocked_3)


def pair_forces(P, PL, L, hist, bounds, fbuf, tbuf, TAB, rolling, limit, eta_r, dt, store,
                fn_out, ft_out, cap=None, age=None, kr_fac=None, blocked=False):
    """Contact forces of the pair list into per-chunk buffers (history updated in place).

    Parameters
    ----------
    P : tuple
        Particles ``(x, v, om, rad, mass, inv_i, ptype)``.
    PL : tuple
        Pair list ``(pi, pj, psh)`` (psh: integer periodic image of j).
    L : (3,) box lengths; hist : ``(ht, hr)`` tangential and rolling history (M, 3).
    bounds : (T+1,) chunk bounds over the pairs; fbuf, tbuf : (T, N, 3) per-chunk buffers.
    TAB : (7, T+1, T+1) per-type-pair constants (:func:`pair_table`).
    rolling : int
        Rolling model code (``ROLL_*``); a compile-time constant.
    limit, eta_r, dt, store, fn_out, ft_out
        Clip of the normal force at 0, EPSD rolling damping ratio, time step (s),
        whether to write the pair normal force and tangential force.
    cap : (4,) array or None
        Capillary bridges on: ``(gamma cos theta, theta, film thickness, fixed
        volume or -1)`` (:func:`capillary_force`).
    age : tuple ``(hx, AGE)`` or None
        Contact ageing on: ``hx[k] = (contact age, accumulated sliding, broken)``
        and ``AGE = (bond ratio, tau, 1/ln(1 + t_ref/tau), break slip)``.
    kr_fac : float or None
        EPSD rolling stiffness factor; None compiles the standard 2.25 in.
    blocked : bool
        Use the blocked (gather-compute-scatter) pass where it applies, that is
        without ``cap`` and ``age``; False runs the single loop.

    Notes
    -----
    Both passes process the list in blocks: a short first pass computes
    separations and splits the block into touching and other pairs without
    branching on the overlap test. The single loop then computes each touching
    pair and adds its forces at once (``_BLOCK`` pairs a block); the blocked
    pass (``_BLOCK_B`` pairs, its scratch held in the L1 cache) gathers the
    pairs' data in that first pass, computes the block's contacts in one
    vectorised loop and adds the forces afterwards, in the same pair order.
    Forces are added to each particle in the order of the pair list in both.
    """
    if blocked and cap is None and age is None:
        _BLOCKED_BY_ROLLING[rolling](P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt,
                                     store, fn_out, ft_out, kr_fac)
        return
    _BY_ROLLING[rolling](P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store, fn_out,
                         ft_out, cap, age, kr_fac)
