"""numba pair-force kernel with the diagnosis extensions (capillary bridges, contact ageing).

A separate kernel, so that the base model (:mod:`bedstruct.dem._kernels_pairs`)
compiles and runs exactly as without the extensions.
"""

from __future__ import annotations

import math

from .._numba import njit, prange
from ._kernels_contact import ROLL_EPSD, ROLL_NONE, rolling_torque, sjkr_area_pair, tangential_history

__all__ = ["capillary_force", "pair_forces_ext"]

_FM = dict(fastmath=True)


@njit(**_FM)
def capillary_force(gap, reff, CAP):
    """Willett et al. (2000) liquid-bridge force (N, attractive, >= 0) at separation ``gap``.

    ``R = 2 R*`` (the sphere radius for equal spheres, Derjaguin mean radius
    otherwise), bridge volume ``V = 2 pi R*^2 t`` (or the fixed ``CAP[3]``),
    ``F = 2 pi R gamma cos(theta) / (1 + 2.1 S + 10 S^2)`` with
    ``S = (gap/2) sqrt(R/V)``; zero beyond the rupture distance
    ``s_c = (1 + theta/2) V^(1/3)``; at contact (gap <= 0) ``2 pi R gamma cos(theta)``.
    """
    vol = CAP[3]
    if vol < 0.0:
        vol = 2.0 * math.pi * reff * reff * CAP[2]
    if vol <= 0.0:
        return 0.0
    if gap > (1.0 + 0.5 * CAP[1]) * vol ** (1.0 / 3.0):
        return 0.0
    rw = 2.0 * reff
    f0 = 2.0 * math.pi * rw * CAP[0]
    if gap <= 0.0:
        return f0
    sh = 0.5 * gap * math.sqrt(rw / vol)
    return f0 / (1.0 + 2.1 * sh + 10.0 * sh * sh)


@njit(parallel=True, **_FM)
def pair_forces_ext(x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf, tbuf,
                Y, G, B, GTR, MU, MUR, COH, rolling, limit, eta_r, dt, store, fn_out, ft_out,
                ext, hx, CAP, AGE):
    """:func:`pair_forces` with the diagnosis extensions (a separate kernel, so that the
    base model compiles exactly as before).

    ``B = -2 sqrt(5/6) beta sqrt(2 Y*)`` and ``GTR = sqrt(4 G*/Y*)`` (0 without
    tangential damping) per type pair, so that ``gamma_n = B sqrt(sqrt(R* delta) m*)``
    and ``gamma_t = GTR gamma_n`` equal :func:`hertz_coefficients`.

    ``ext`` flags the diagnosis extensions (1 capillary bridges, 2 contact
    ageing); ``hx[k] = (contact age, accumulated sliding, broken)`` is the ageing
    history, ``CAP = (gamma cos theta, theta, film thickness, fixed volume or
    -1)`` and ``AGE = (bond ratio, tau, 1/ln(1 + t_ref/tau), break slip,
    epsd rolling stiffness factor)``. With ``ext = 0`` the arithmetic is the
    base model's.
    """
    cap_on = (ext & 1) != 0
    age_on = (ext & 2) != 0
    kr_fac = AGE[4]
    nt = bounds.shape[0] - 1
    for t in prange(nt):
        for k in range(bounds[t], bounds[t + 1]):
            i = pi[k]
            j = pj[k]
            dx = x[i, 0] - x[j, 0] - psh[k, 0] * L[0]
            dy = x[i, 1] - x[j, 1] - psh[k, 1] * L[1]
            dz = x[i, 2] - x[j, 2] - psh[k, 2] * L[2]
            r2 = dx * dx + dy * dy + dz * dz
            ri = rad[i]
            rj = rad[j]
            rs = ri + rj
            if r2 >= rs * rs:
                if age_on:
                    hx[k, 0] = 0.0
                    hx[k, 1] = 0.0
                    hx[k, 2] = 0.0
                if cap_on:
                    r = math.sqrt(r2)
                    fcap = capillary_force(r - rs, ri * rj / rs, CAP)
                    if fcap != 0.0:
                        # attractive: pulls i towards j along -n
                        c = -fcap / r
                        fbuf[t, i, 0] += c * dx
                        fbuf[t, i, 1] += c * dy
                        fbuf[t, i, 2] += c * dz
                        fbuf[t, j, 0] -= c * dx
                        fbuf[t, j, 1] -= c * dy
                        fbuf[t, j, 2] -= c * dz
                    if store:
                        fn_out[k] = -fcap
                if ht[k, 0] != 0.0 or ht[k, 1] != 0.0 or ht[k, 2] != 0.0:
                    ht[k, 0] = 0.0
                    ht[k, 1] = 0.0
                    ht[k, 2] = 0.0
                if hr[k, 0] != 0.0 or hr[k, 1] != 0.0 or hr[k, 2] != 0.0:
                    hr[k, 0] = 0.0
                    hr[k, 1] = 0.0
                    hr[k, 2] = 0.0
                if store:
                    if not cap_on:
                        fn_out[k] = 0.0
                    ft_out[k, 0] = 0.0
                    ft_out[k, 1] = 0.0
                    ft_out[k, 2] = 0.0
                continue
            r = math.sqrt(r2)
            rinv = 1.0 / r
            e1 = dx * rinv
            e2 = dy * rinv
            e3 = dz * rinv
            delta = rs - r
            ti = ptype[i]
            tj = ptype[j]
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
            if cap_on:
                fn -= capillary_force(0.0, reff, CAP)
            if age_on and hx[k, 2] == 0.0 and AGE[0] != 0.0:
                # bond of the resting contact: r F_sjkr ln(1 + t_w/tau) / ln(1 + t_ref/tau)
                fn -= (AGE[0] * k_coh * sjkr_area_pair(r, ri, rj)
                       * math.log1p(hx[k, 0] / AGE[1]) * AGE[2])
            cri = ri - 0.5 * delta
            crj = rj - 0.5 * delta
            w1 = cri * om[i, 0] + crj * om[j, 0]
            w2 = cri * om[i, 1] + crj * om[j, 1]
            w3 = cri * om[i, 2] + crj * om[j, 2]
            vt1 = vr1 - vn * e1 - (w2 * e3 - w3 * e2)
            vt2 = vr2 - vn * e2 - (w3 * e1 - w1 * e3)
            vt3 = vr3 - vn * e3 - (w1 * e2 - w2 * e1)
            trial = 0.0
            if age_on:
                # the spring the step would reach without the Coulomb cap (as tangential_history)
                u1 = ht[k, 0] + vt1 * dt
                u2 = ht[k, 1] + vt2 * dt
                u3 = ht[k, 2] + vt3 * dt
                un = u1 * e1 + u2 * e2 + u3 * e3
                trial = math.sqrt((u1 - un * e1) ** 2 + (u2 - un * e2) ** 2 + (u3 - un * e3) ** 2)
            s1, s2, s3, f1, f2, f3 = tangential_history(ht[k, 0], ht[k, 1], ht[k, 2], vt1, vt2, vt3,
                                                        e1, e2, e3, kt, gt, MU[ti, tj], fn_cap, dt)
            ht[k, 0] = s1
            ht[k, 1] = s2
            ht[k, 2] = s3
            if age_on and hx[k, 2] == 0.0:
                hx[k, 0] += dt
                # sliding, not elastic shear: what the Coulomb cap cut off the spring (an elastic
                # tangential displacement is recovered; only sliding breaks the aged bond)
                hx[k, 1] += max(trial - math.sqrt(s1 * s1 + s2 * s2 + s3 * s3), 0.0)
                if hx[k, 1] > AGE[3]:
                    hx[k, 2] = 1.0
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
                        reff, fn_cap, mur, dt, ieff, eta_r, kr_fac)
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
            fbuf[t, i, 0] += fx
            fbuf[t, i, 1] += fy
            fbuf[t, i, 2] += fz
            fbuf[t, j, 0] -= fx
            fbuf[t, j, 1] -= fy
            fbuf[t, j, 2] -= fz
            tbuf[t, i, 0] += ti1
            tbuf[t, i, 1] += ti2
            tbuf[t, i, 2] += ti3
            tbuf[t, j, 0] += tj1
            tbuf[t, j, 1] += tj2
            tbuf[t, j, 2] += tj3
            if store:
                fn_out[k] = fn
                ft_out[k, 0] = f1
                ft_out[k, 1] = f2
                ft_out[k, 2] = f3
