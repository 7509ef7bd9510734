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

Two passes compute the same contact law
(:data:`~bedstruct.dem._kernels_contact.pair_contact`, written once). The blocked pass
(the engine's default without capillary bridges and ageing) gathers the touching pairs
of a block into a small contiguous scratch, runs the contact law over it in a loop that
LLVM vectorises, and scatters forces, torques and history back in pair order. The
single loop computes each pair where it finds it and carries the extensions. Both
round every operation as written (no reassociation, no fused multiply-adds) and add
forces to each particle in pair-list order, so without extensions their results are
equal bit for bit, and a change of the loops around the law leaves its bits as they
are. The blocked pass is in :mod:`bedstruct.dem._kernels_pairs_blocked`; the
per-type-pair table ``TAB`` (:func:`~bedstruct.dem._kernels_contact.pair_table`) and the
clearing of a pair apart are in :mod:`bedstruct.dem._kernels_contact`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, types
from numba.extending import overload

from .._numba import njit, prange
from ._kernels_contact import (ROLL_CDT, ROLL_EPSD, ROLL_EPSD2, ROLL_NONE, STRICT, _open_pair,
                               ageing_bond, capillary_force, law_rows, pair_contact,
                               sjkr_area_pair)
from ._kernels_pairs_blocked import BLOCKED_BY_ROLLING

__all__ = ["pair_forces", "pair_pass_call", "run_pair_pass", "PAIR_PASSES"]

_FM = dict(fastmath=True)
_BLOCK = 64  # pairs per block of the two-pass loop

@njit(**STRICT)
def _pair_chunk(t, P, PL, L, hist, bounds, fbuf, tbuf, TAB, rolling, limit, eta_r, dt, store,
                fn_out, ft_out, cap, age, kr_fac):
    """Chunk ``t`` of :func:`pair_forces`, compiled for a constant rolling model and
    for the extensions passed (``cap``, ``age``, ``kr_fac`` not None)."""
    literally(rolling)  # one specialisation per model: the others' code is not in the loop
    x, v, om, rad, mass, inv_i, ptype = P
    # positions, velocities and spins read as flat views (row i at 3 i): fewer live strides
    xf = x.reshape(-1)
    vf = v.reshape(-1)
    of = om.reshape(-1)
    pi, pj, psh = PL
    ht, hr = hist
    Y, G, B, GTR, MU, MUR, COH, krf = law_rows(TAB, kr_fac)
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
            dx = xf[3 * i] - xf[3 * j] - psh[k, 0] * L[0]
            dy = xf[3 * i + 1] - xf[3 * j + 1] - psh[k, 1] * L[1]
            dz = xf[3 * i + 2] - xf[3 * j + 2] - psh[k, 2] * L[2]
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
            ti = np.uint32(ptype[i])
            tj = np.uint32(ptype[j])
            k_coh = COH[ti, tj]
            f_bridge = 0.0
            if cap is not None:
                f_bridge = capillary_force(0.0, ri * rj / rs, cap)
            f_bond = 0.0
            if age is not None:
                if age[0][k, 2] == 0.0 and age[1][0] != 0.0:
                    f_bond = ageing_bond(k_coh, sjkr_area_pair(math.sqrt(r2), ri, rj),
                                         age[0][k, 0], age[1])
            s01 = ht[k, 0]
            s02 = ht[k, 1]
            s03 = ht[k, 2]
            h01 = 0.0
            h02 = 0.0
            h03 = 0.0
            mur = 0.0
            if rolling != ROLL_NONE:
                h01 = hr[k, 0]
                h02 = hr[k, 1]
                h03 = hr[k, 2]
                mur = MUR[ti, tj]
            inv_ii = 0.0
            inv_ij = 0.0
            if rolling == ROLL_EPSD:
                inv_ii = inv_i[i]
                inv_ij = inv_i[j]
            (fn, f1, f2, f3, s1, s2, s3, h1, h2, h3, ti1, ti2, ti3, tj1, tj2, tj3, e1, e2, e3,
             vt1, vt2, vt3) = pair_contact(
                dx, dy, dz, r2, ri, rj, mass[i], mass[j],
                (vf[3 * i] - vf[3 * j], vf[3 * i + 1] - vf[3 * j + 1],
                 vf[3 * i + 2] - vf[3 * j + 2]),
                (of[3 * i], of[3 * i + 1], of[3 * i + 2]),
                (of[3 * j], of[3 * j + 1], of[3 * j + 2]),
                Y[ti, tj], G[ti, tj], B[ti, tj], GTR[ti, tj], MU[ti, tj], mur, k_coh, f_bridge,
                f_bond, (s01, s02, s03), (h01, h02, h03), inv_ii, inv_ij, rolling, limit, eta_r,
                dt, krf)
            ht[k, 0] = s1
            ht[k, 1] = s2
            ht[k, 2] = s3
            if rolling != ROLL_NONE:
                hr[k, 0] = h1
                hr[k, 1] = h2
                hr[k, 2] = h3
            if age is not None:
                hx = age[0]
                if hx[k, 2] == 0.0:
                    # the spring this step would reach without the Coulomb cap, and what the cap
                    # cut off it: sliding, not elastic shear (an elastic tangential displacement
                    # is recovered; only sliding breaks the bond)
                    u1 = s01 + vt1 * dt
                    u2 = s02 + vt2 * dt
                    u3 = s03 + vt3 * dt
                    un = u1 * e1 + u2 * e2 + u3 * e3
                    trial = math.sqrt((u1 - un * e1) ** 2 + (u2 - un * e2) ** 2
                                      + (u3 - un * e3) ** 2)
                    hx[k, 0] += dt
                    hx[k, 1] += max(trial - math.sqrt(s1 * s1 + s2 * s2 + s3 * s3), 0.0)
                    if hx[k, 1] > age[1][3]:
                        hx[k, 2] = 1.0
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
# the other models' code is gone from the hot loop (~10 % faster than a runtime switch).
# Written out per model: one wrapper taking the model through `literally` gives the same
# code but was still compiling after 15 CPU-minutes in a fresh process; these four compile
# in about one minute.
_BY_ROLLING = (_pair_forces_0, _pair_forces_1, _pair_forces_2, _pair_forces_3)


def pair_forces(P, PL, L, hist, bounds, fbuf, tbuf, TAB, rolling, limit, eta_r, dt, store,
                fn_out, ft_out, cap=None, age=None, kr_fac=None, blocked=False):
    """Contact forces of the pair list into per-chunk buffers (history updated in place).

    Parameters
    ----------
    P : tuple
        Particles ``(x, v, om, rad, mass, inv_i, ptype)``; ``x``, ``v`` and ``om`` are
        C-contiguous (N, 3) arrays (the passes read them as flat views).
    PL : tuple
        Pair list ``(pi, pj, psh)`` (psh: integer periodic image of j).
    L : (3,) box lengths; hist : ``(ht, hr)`` tangential and rolling history (M, 3).
    bounds : (T+1,) chunk bounds over the pairs; fbuf, tbuf : (T, N, 3) per-chunk buffers.
    TAB : (7, T+1, T+1) per-type-pair constants
        (:func:`~bedstruct.dem._kernels_contact.pair_table`).
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
    pass (``_BLOCK_B`` pairs, its scratch held in the L1 cache) then gathers the
    touching pairs' data, computes the block's contacts in one vectorised loop
    and adds the forces afterwards, in the same pair order.
    Forces are added to each particle in the order of the pair list in both.
    """
    variant, args = pair_pass_call(P, PL, L, hist, bounds, fbuf, tbuf, TAB, rolling, limit,
                                   eta_r, dt, store, fn_out, ft_out, cap, age, kr_fac, blocked)
    PAIR_PASSES[variant](*args)


#: The compiled pair passes: the blocked pass of each rolling model (``ROLL_*`` code), then
#: the single loop of each.
PAIR_PASSES = BLOCKED_BY_ROLLING + _BY_ROLLING


def pair_pass_call(P, PL, L, hist, bounds, fbuf, tbuf, TAB, rolling, limit, eta_r, dt, store,
                   fn_out, ft_out, cap=None, age=None, kr_fac=None, blocked=False):
    """Which pass :func:`pair_forces` runs for these arguments (its index in
    :data:`PAIR_PASSES`) and the pass's arguments: ``PAIR_PASSES[variant](*args)`` is that
    call, and :func:`run_pair_pass` makes it from compiled code."""
    if blocked and cap is None and age is None:
        return rolling, (P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit, eta_r, dt, store, fn_out,
                         ft_out, kr_fac)
    return len(BLOCKED_BY_ROLLING) + rolling, (P, PL, L, hist, bounds, fbuf, tbuf, TAB, limit,
                                               eta_r, dt, store, fn_out, ft_out, cap, age, kr_fac)


def run_pair_pass(variant, args):
    """``PAIR_PASSES[variant](*args)`` in compiled code, with ``variant`` a compile-time
    constant (so that a caller compiled per variant can be cached)."""
    PAIR_PASSES[variant](*args)


@overload(run_pair_pass)
def _run_pair_pass(variant, args):
    if not isinstance(variant, types.IntegerLiteral):
        return None
    kernel = PAIR_PASSES[variant.literal_value]

    def impl(variant, args):
        kernel(*args)
    return impl
