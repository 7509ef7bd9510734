"""numba kernels of the DEM engine: contact laws, walls, cell list, pair list, integrator.

All kernels are pure functions of contiguous arrays and scalars (SI units) and
write into preallocated outputs. Parallel kernels split their work into
``T`` contiguous chunks (``bounds`` arrays of length T+1) and run one chunk per
``prange`` iteration; forces go to per-chunk buffers ``fbuf[t]`` that the
integrator reduces in a fixed order, so results are deterministic for a
given number of chunks and free of races.

Conventions (as LIGGGHTS): for a pair (i, j), ``en = (x_i - x_j) / r`` points
from j to i; ``Fn > 0`` is repulsive; the force on i is ``Fn en + Ft``.
Positions of the periodic image of j are ``x_j + s L`` with the integer
image ``s`` stored per pair.
"""

from __future__ import annotations

import math

import numpy as np

from .._numba import njit, prange

__all__: list[str] = []

SQRT_5_6 = math.sqrt(5.0 / 6.0)

ROLL_NONE = 0
ROLL_CDT = 1
ROLL_EPSD = 2
ROLL_EPSD2 = 3

WALL_PLANE = 0
WALL_RECT = 1
WALL_PRISM = 2
WALL_CYLINDER = 3
WALL_MESH = 4
WALL_NCOL = 34

_FM = dict(fastmath=True)


# ----------------------------------------------------------------- contact laws
@njit(**_FM)
def hertz_coefficients(delta, reff, meff, ystar, gstar, beta):
    """LIGGGHTS Hertz: returns (kn, kt, gamma_n, gamma_t) for overlap ``delta``."""
    sq = math.sqrt(reff * delta)
    sn = 2.0 * ystar * sq
    st = 8.0 * gstar * sq
    kn = 4.0 / 3.0 * ystar * sq
    gn = -2.0 * SQRT_5_6 * beta * math.sqrt(sn * meff)
    gt = -2.0 * SQRT_5_6 * beta * math.sqrt(st * meff)
    return kn, st, gn, gt


@njit(**_FM)
def sjkr_area_pair(r, ri, rj):
    """Area of the overlap lens of two spheres at centre distance r (SJKR)."""
    return -math.pi / 4.0 * ((r - ri - rj) * (r + ri - rj) * (r - ri + rj) * (r + ri + rj)) / (r * r)


@njit(**_FM)
def sjkr_area_wall(dist, ri):
    """Area of the circle cut from a sphere by a plane at distance ``dist``."""
    a = (ri * ri - dist * dist) * math.pi
    return a if a > 0.0 else 0.0


@njit(**_FM)
def tangential_history(s1, s2, s3, vt1, vt2, vt3, e1, e2, e3, kt, gt, mu, fn, dt):
    """Mindlin spring with history and Coulomb cap (LIGGGHTS ``tangential history``).

    Returns the updated history (s1, s2, s3) and the tangential force on i.
    """
    s1 += vt1 * dt
    s2 += vt2 * dt
    s3 += vt3 * dt
    rsh = s1 * e1 + s2 * e2 + s3 * e3
    s1 -= rsh * e1
    s2 -= rsh * e2
    s3 -= rsh * e3
    shrmag = math.sqrt(s1 * s1 + s2 * s2 + s3 * s3)
    f1 = -kt * s1
    f2 = -kt * s2
    f3 = -kt * s3
    fshear = kt * shrmag
    ffric = mu * abs(fn)
    if fshear > ffric:
        if shrmag != 0.0:
            ratio = ffric / fshear
            f1 *= ratio
            f2 *= ratio
            f3 *= ratio
            s1 = -f1 / kt
            s2 = -f2 / kt
            s3 = -f3 / kt
        else:
            f1 = 0.0
            f2 = 0.0
            f3 = 0.0
    else:
        f1 -= gt * vt1
        f2 -= gt * vt2
        f3 -= gt * vt3
    return s1, s2, s3, f1, f2, f3


@njit(**_FM)
def rolling_torque(model, h1, h2, h3, w1, w2, w3, e1, e2, e3, kn, kt, delta, reff, fn, mur,
                   dt, inertia_eff, eta_r, kr_fac=2.25):
    """Rolling-resistance torque ``M`` (subtracted from i, added to j) and new history.

    ``w`` is the relative angular velocity omega_i - omega_j; only its part
    normal to ``en`` (rolling, no torsion) acts. Models: 1 = CDT
    ``M = mu_r kn delta R* w_t/|w_t|``; 3 = EPSD2 spring ``k_r = k_t R*^2``
    capped at ``mu_r |Fn| R*``; 2 = EPSD with ``k_r = kr_fac kn mu_r^2 R*^2`` (2.25) and
    a dashpot ``C_r = 2 eta_r sqrt(I_r k_r)`` off at full mobilisation.
    """
    wn = w1 * e1 + w2 * e2 + w3 * e3
    wt1 = w1 - wn * e1
    wt2 = w2 - wn * e2
    wt3 = w3 - wn * e3
    if model == ROLL_CDT:
        wmag = math.sqrt(wt1 * wt1 + wt2 * wt2 + wt3 * wt3)
        if wmag > 0.0:
            c = mur * kn * delta * reff / wmag
            return 0.0, 0.0, 0.0, c * wt1, c * wt2, c * wt3
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if model == ROLL_EPSD2:
        kr = kt * reff * reff
    else:
        kr = kr_fac * kn * mur * mur * reff * reff
    m1 = h1 + kr * dt * wt1
    m2 = h2 + kr * dt * wt2
    m3 = h3 + kr * dt * wt3
    mag = math.sqrt(m1 * m1 + m2 * m2 + m3 * m3)
    mmax = abs(fn) * reff * mur
    full = False
    if mag > mmax:
        fac = mmax / mag
        m1 *= fac
        m2 *= fac
        m3 *= fac
        full = True
    h1 = m1
    h2 = m2
    h3 = m3
    if model == ROLL_EPSD and not full:
        cr = 2.0 * eta_r * math.sqrt(inertia_eff * kr)
        m1 += cr * wt1
        m2 += cr * wt2
        m3 += cr * wt3
    return h1, h2, h3, m1, m2, m3


# ---------------------------------------------------------------------- walls
@njit(inline="always", **_FM)
def wall_geometry(W, w, px, py, pz, time):
    """Closest-approach data of wall ``w`` for a sphere centre p.

    Returns ``(hit, dist, n1, n2, n3, u1, u2, u3, om1, om2, om3)``: signed
    distance from the wall surface to p, unit normal from the wall to p,
    velocity of the wall surface at the contact point and wall angular
    velocity. ``hit`` is False when the wall cannot touch the sphere
    (behind a plane, beyond a cylinder end).
    """
    kind = int(W[w, 0])
    dt0 = time - W[w, 13]
    ox = W[w, 1] + W[w, 10] * dt0
    oy = W[w, 2] + W[w, 11] * dt0
    oz = W[w, 3] + W[w, 12] * dt0
    u1 = W[w, 10]
    u2 = W[w, 11]
    u3 = W[w, 12]
    rx = px - ox
    ry = py - oy
    rz = pz - oz
    nx = W[w, 4]
    ny = W[w, 5]
    nz = W[w, 6]
    if kind == WALL_PLANE:
        d = rx * nx + ry * ny + rz * nz
        return True, d, nx, ny, nz, u1, u2, u3, 0.0, 0.0, 0.0
    if kind == WALL_RECT:
        ax = W[w, 7]
        ay = W[w, 8]
        az = W[w, 9]
        bx = ny * az - nz * ay
        by = nz * ax - nx * az
        bz = nx * ay - ny * ax
        s1 = rx * ax + ry * ay + rz * az
        s2 = rx * bx + ry * by + rz * bz
        h1 = W[w, 14]
        h2 = W[w, 15]
        c1 = min(max(s1, -h1), h1)
        c2 = min(max(s2, -h2), h2)
        vx = rx - c1 * ax - c2 * bx
        vy = ry - c1 * ay - c2 * by
        vz = rz - c1 * az - c2 * bz
        d = math.sqrt(vx * vx + vy * vy + vz * vz)
        if d > 0.0:
            return True, d, vx / d, vy / d, vz / d, u1, u2, u3, 0.0, 0.0, 0.0
        return True, 0.0, nx, ny, nz, u1, u2, u3, 0.0, 0.0, 0.0
    if kind == WALL_PRISM:
        # extrusion axis e = (nx, ny, nz); in-plane u = W[7:10]; v = u x e
        ux = W[w, 7]
        uy = W[w, 8]
        uz = W[w, 9]
        vx_ = uy * nz - uz * ny
        vy_ = uz * nx - ux * nz
        vz_ = ux * ny - uy * nx
        se = rx * nx + ry * ny + rz * nz
        he = W[w, 14]
        ce = min(max(se, -he), he)
        pu = rx * ux + ry * uy + rz * uz
        pv = rx * vx_ + ry * vy_ + rz * vz_
        nv = int(W[w, 17])
        inside = True
        best = 1e300
        qu = 0.0
        qv = 0.0
        maxsep = -1e300
        mu_ = 0.0
        mv_ = 0.0
        for k in range(nv):
            au = W[w, 18 + 2 * k]
            av = W[w, 19 + 2 * k]
            k2 = (k + 1) % nv
            bu = W[w, 18 + 2 * k2]
            bv = W[w, 19 + 2 * k2]
            eu = bu - au
            ev = bv - av
            elen = math.sqrt(eu * eu + ev * ev)
            # outward normal of a CCW polygon edge
            onu = ev / elen
            onv = -eu / elen
            sep = (pu - au) * onu + (pv - av) * onv
            if sep > 0.0:
                inside = False
            if sep > maxsep:
                maxsep = sep
                mu_ = onu
                mv_ = onv
            t = ((pu - au) * eu + (pv - av) * ev) / (elen * elen)
            t = min(max(t, 0.0), 1.0)
            cu = au + t * eu
            cv = av + t * ev
            dd = (pu - cu) * (pu - cu) + (pv - cv) * (pv - cv)
            if dd < best:
                best = dd
                qu = cu
                qv = cv
        if inside:
            if se > he or se < -he:
                d = abs(se - ce)
                s = 1.0 if se > ce else -1.0
                return True, d, s * nx, s * ny, s * nz, u1, u2, u3, 0.0, 0.0, 0.0
            d = maxsep  # negative: penetration depth through the nearest face
            return (True, d, mu_ * ux + mv_ * vx_, mu_ * uy + mv_ * vy_, mu_ * uz + mv_ * vz_,
                    u1, u2, u3, 0.0, 0.0, 0.0)
        du = pu - qu
        dv = pv - qv
        de = se - ce
        gx = du * ux + dv * vx_ + de * nx
        gy = du * uy + dv * vy_ + de * ny
        gz = du * uz + dv * vz_ + de * nz
        d = math.sqrt(gx * gx + gy * gy + gz * gz)
        return True, d, gx / d, gy / d, gz / d, u1, u2, u3, 0.0, 0.0, 0.0
    if kind == WALL_CYLINDER:
        se = rx * nx + ry * ny + rz * nz
        if abs(se) > W[w, 14]:
            return False, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        qx = rx - se * nx
        qy = ry - se * ny
        qz = rz - se * nz
        rho = math.sqrt(qx * qx + qy * qy + qz * qz)
        if rho == 0.0:
            return False, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        rad = W[w, 15]
        e1 = qx / rho
        e2 = qy / rho
        e3 = qz / rho
        om = W[w, 16]
        # surface velocity: u + Omega e_axis x (R e_r)
        s1 = u1 + om * rad * (ny * e3 - nz * e2)
        s2 = u2 + om * rad * (nz * e1 - nx * e3)
        s3 = u3 + om * rad * (nx * e2 - ny * e1)
        return True, rho - rad, e1, e2, e3, s1, s2, s3, om * nx, om * ny, om * nz
    return False, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


@njit(**_FM)
def closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point of triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5)."""
    abx = bx - ax
    aby = by - ay
    abz = bz - az
    acx = cx - ax
    acy = cy - ay
    acz = cz - az
    apx = px - ax
    apy = py - ay
    apz = pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az
    bpx = px - bx
    bpy = py - by
    bpz = pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz
    cpx = px - cx
    cpy = py - cy
    cpz = pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz)
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w


@njit(inline="always", **_FM)
def mesh_geometry(W, w, tri, px, py, pz, time):
    """Closest triangle of a mesh wall (rows ``W[w,14]..W[w,15]`` of ``tri``)."""
    dt0 = time - W[w, 13]
    ox = W[w, 1] + W[w, 10] * dt0
    oy = W[w, 2] + W[w, 11] * dt0
    oz = W[w, 3] + W[w, 12] * dt0
    lx = px - ox
    ly = py - oy
    lz = pz - oz
    best = 1e300
    gx = 0.0
    gy = 0.0
    gz = 1.0
    for k in range(int(W[w, 14]), int(W[w, 15])):
        qx, qy, qz = closest_on_triangle(lx, ly, lz, tri[k, 0], tri[k, 1], tri[k, 2],
                                         tri[k, 3], tri[k, 4], tri[k, 5],
                                         tri[k, 6], tri[k, 7], tri[k, 8])
        dx = lx - qx
        dy = ly - qy
        dz = lz - qz
        dd = dx * dx + dy * dy + dz * dz
        if dd < best:
            best = dd
            gx = dx
            gy = dy
            gz = dz
    d = math.sqrt(best)
    if d == 0.0:
        return False, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return True, d, gx / d, gy / d, gz / d, W[w, 10], W[w, 11], W[w, 12], 0.0, 0.0, 0.0


# ------------------------------------------------------------ integrator passes
@njit(parallel=True, **_FM)
def kick_drift(x, v, om, f, tq, inv_m, inv_i, x_ref, dt, bounds, disp_out):
    """First half kick, drift, and per-chunk max squared displacement since the last build."""
    h = 0.5 * dt
    nt = bounds.shape[0] - 1
    for t in prange(nt):
        m2 = 0.0
        for i in range(bounds[t], bounds[t + 1]):
            a = h * inv_m[i]
            b = h * inv_i[i]
            for k in range(3):
                v[i, k] += a * f[i, k]
                om[i, k] += b * tq[i, k]
                x[i, k] += dt * v[i, k]
            d0 = x[i, 0] - x_ref[i, 0]
            d1 = x[i, 1] - x_ref[i, 1]
            d2 = x[i, 2] - x_ref[i, 2]
            dd = d0 * d0 + d1 * d1 + d2 * d2
            if dd > m2:
                m2 = dd
        disp_out[t] = m2


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
def pair_forces(x, v, om, rad, mass, inv_i, ptype, pi, pj, psh, L, ht, hr, bounds, fbuf, tbuf,
                Y, G, B, GTR, MU, MUR, COH, rolling, limit, eta_r, dt, store, fn_out, ft_out):
    """Contact forces of the pair list into per-chunk buffers (history updated in place).

    ``B = -2 sqrt(5/6) beta sqrt(2 Y*)`` and ``GTR = sqrt(4 G*/Y*)`` (0 without
    tangential damping) per type pair, so that ``gamma_n = B sqrt(sqrt(R* delta) m*)``
    and ``gamma_t = GTR gamma_n`` equal :func:`hertz_coefficients`.
    """
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
    ageing); ``hx[k] = (contact age, accumulated slip, broken)`` is the ageing
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
            s1, s2, s3, f1, f2, f3 = tangential_history(ht[k, 0], ht[k, 1], ht[k, 2], vt1, vt2, vt3,
                                                        e1, e2, e3, kt, gt, MU[ti, tj], fn_cap, dt)
            ht[k, 0] = s1
            ht[k, 1] = s2
            ht[k, 2] = s3
            if age_on and hx[k, 2] == 0.0:
                hx[k, 0] += dt
                hx[k, 1] += math.sqrt(vt1 * vt1 + vt2 * vt2 + vt3 * vt3) * dt
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


@njit(**_FM)
def wall_contact(dist, n1, n2, n3, u1, u2, u3, o1, o2, o3, ri, mi, inv_ii, v1, v2, v3, w1, w2, w3,
                 ystar, gstar, beta, mu, mur, kc, rolling, tdamp, limit, eta_r, dt,
                 h1, h2, h3, r1, r2, r3, kr_fac=2.25):
    """One particle-wall contact (scalars only): force and torque on the particle,
    normal force, overlap and the updated tangential (h) and rolling (r) history."""
    delta = ri - dist
    kn, kt, gn, gt = hertz_coefficients(delta, ri, mi, ystar, gstar, beta)
    if not tdamp:
        gt = 0.0
    vr1 = v1 - u1
    vr2 = v2 - u2
    vr3 = v3 - u3
    vn = vr1 * n1 + vr2 * n2 + vr3 * n3
    fn = kn * delta - gn * vn
    if limit and fn < 0.0:
        fn = 0.0
    # Coulomb and rolling limits use Hertz + damping only: LIGGGHTS' default
    # (`tangential_reduce off`) adds cohesion to the force, not to the caps.
    fn_cap = fn
    if kc != 0.0:
        fn -= kc * sjkr_area_wall(dist, ri)
    cr = ri - 0.5 * delta
    c1 = cr * w1
    c2 = cr * w2
    c3 = cr * w3
    vt1 = vr1 - vn * n1 - (c2 * n3 - c3 * n2)
    vt2 = vr2 - vn * n2 - (c3 * n1 - c1 * n3)
    vt3 = vr3 - vn * n3 - (c1 * n2 - c2 * n1)
    h1, h2, h3, f1, f2, f3 = tangential_history(h1, h2, h3, vt1, vt2, vt3, n1, n2, n3, kt, gt,
                                                mu, fn_cap, dt)
    t1 = -cr * (n2 * f3 - n3 * f2)
    t2 = -cr * (n3 * f1 - n1 * f3)
    t3 = -cr * (n1 * f2 - n2 * f1)
    if rolling != ROLL_NONE and mur > 0.0:
        ieff = 1.0 / inv_ii + mi * ri * ri
        r1, r2, r3, m1, m2, m3 = rolling_torque(rolling, r1, r2, r3, w1 - o1, w2 - o2, w3 - o3,
                                                n1, n2, n3, kn, kt, delta, ri, fn_cap, mur, dt, ieff,
                                                eta_r, kr_fac)
        t1 -= m1
        t2 -= m2
        t3 -= m3
    return (fn * n1 + f1, fn * n2 + f2, fn * n3 + f3, t1, t2, t3, fn, delta,
            h1, h2, h3, r1, r2, r3)


@njit(parallel=True, **_FM)
def finish_step(x, v, om, f, tq, fbuf, tbuf, mass, inv_m, inv_i, rad, ptype, gravity, bounds,
                W, tri, time, wstart, wcand, wslot, whist, wbuf, Y, G, B, MU, MUR, COH, rolling, tdamp, limit,
                eta_r, dt, store, wfn_out, wdelta_out, wnorm_out, overflow, kr_fac=2.25):
    """Reduce per-chunk forces, add gravity and wall forces, second half kick.

    Only the walls listed for particle i in ``wcand[wstart[i]:wstart[i+1]]``
    (see :func:`wall_candidates`) are evaluated.
    Wall contacts keep their tangential/rolling history in per-particle slots
    ``wslot[i, s]`` (wall index or -1) and ``whist[i, s, 0:6]``. The reaction
    on each wall is summed per chunk into ``wbuf[t, w, 0:6]`` (force, torque
    about the wall origin is not needed: 3:6 hold the sum of normal force
    magnitudes and contact counts).
    """
    nt = bounds.shape[0] - 1
    nb = fbuf.shape[0]
    nw = W.shape[0]
    ns = wslot.shape[1]
    h = 0.5 * dt
    wt = Y.shape[0] - 1
    for t in prange(nt):
        for w in range(nw):
            for c in range(6):
                wbuf[t, w, c] = 0.0
        # wall contacts of the chunk's particles (added to this chunk's buffer)
        for i in range(bounds[t], bounds[t + 1]):
            if not store and wstart[i] == wstart[i + 1]:
                continue
            if store:
                for s in range(ns):
                    wfn_out[i, s] = 0.0
                    wdelta_out[i, s] = 0.0
            ri = rad[i]
            for cw in range(wstart[i], wstart[i + 1]):
                w = wcand[cw]
                if int(W[w, 0]) == WALL_MESH:
                    hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3 = mesh_geometry(
                        W, w, tri, x[i, 0], x[i, 1], x[i, 2], time)
                else:
                    hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3 = wall_geometry(
                        W, w, x[i, 0], x[i, 1], x[i, 2], time)
                slot = -1
                for s in range(ns):
                    if wslot[i, s] == w:
                        slot = s
                touching = hit and dist < ri and dist > -ri
                if not touching:
                    if slot >= 0:
                        wslot[i, slot] = -1
                        for c in range(6):
                            whist[i, slot, c] = 0.0
                    continue
                if slot < 0:
                    for s in range(ns):
                        if wslot[i, s] < 0:
                            slot = s
                            break
                    if slot >= 0:
                        wslot[i, slot] = w
                        for c in range(6):
                            whist[i, slot, c] = 0.0
                    else:
                        overflow[t] += 1
                ti = ptype[i]
                if slot >= 0:
                    h1 = whist[i, slot, 0]
                    h2 = whist[i, slot, 1]
                    h3 = whist[i, slot, 2]
                    q1 = whist[i, slot, 3]
                    q2 = whist[i, slot, 4]
                    q3 = whist[i, slot, 5]
                else:
                    h1 = 0.0
                    h2 = 0.0
                    h3 = 0.0
                    q1 = 0.0
                    q2 = 0.0
                    q3 = 0.0
                (gx, gy, gz, g1, g2, g3, fnw, delta, h1, h2, h3, q1, q2, q3) = wall_contact(
                    dist, n1, n2, n3, u1, u2, u3, o1, o2, o3, ri, mass[i], inv_i[i],
                    v[i, 0], v[i, 1], v[i, 2], om[i, 0], om[i, 1], om[i, 2],
                    Y[ti, wt], G[ti, wt], B[ti, wt], MU[ti, wt], MUR[ti, wt], COH[ti, wt],
                    rolling, tdamp, limit, eta_r, dt, h1, h2, h3, q1, q2, q3, kr_fac)
                if slot >= 0:
                    whist[i, slot, 0] = h1
                    whist[i, slot, 1] = h2
                    whist[i, slot, 2] = h3
                    whist[i, slot, 3] = q1
                    whist[i, slot, 4] = q2
                    whist[i, slot, 5] = q3
                fbuf[t, i, 0] += gx
                fbuf[t, i, 1] += gy
                fbuf[t, i, 2] += gz
                tbuf[t, i, 0] += g1
                tbuf[t, i, 1] += g2
                tbuf[t, i, 2] += g3
                wbuf[t, w, 0] -= gx
                wbuf[t, w, 1] -= gy
                wbuf[t, w, 2] -= gz
                wbuf[t, w, 3] += fnw
                wbuf[t, w, 4] += 1.0
                if store and slot >= 0:
                    wfn_out[i, slot] = fnw
                    wdelta_out[i, slot] = delta
                    wnorm_out[i, slot, 0] = -n1
                    wnorm_out[i, slot, 1] = -n2
                    wnorm_out[i, slot, 2] = -n3
        # reduction, gravity and half kick (a simple, vectorisable loop)
        for i in range(bounds[t], bounds[t + 1]):
            fx = gravity[0] * mass[i]
            fy = gravity[1] * mass[i]
            fz = gravity[2] * mass[i]
            tx = 0.0
            ty = 0.0
            tz = 0.0
            for b in range(nb):
                fx += fbuf[b, i, 0]
                fy += fbuf[b, i, 1]
                fz += fbuf[b, i, 2]
                tx += tbuf[b, i, 0]
                ty += tbuf[b, i, 1]
                tz += tbuf[b, i, 2]
                fbuf[b, i, 0] = 0.0
                fbuf[b, i, 1] = 0.0
                fbuf[b, i, 2] = 0.0
                tbuf[b, i, 0] = 0.0
                tbuf[b, i, 1] = 0.0
                tbuf[b, i, 2] = 0.0
            f[i, 0] = fx
            f[i, 1] = fy
            f[i, 2] = fz
            tq[i, 0] = tx
            tq[i, 1] = ty
            tq[i, 2] = tz
            a = h * inv_m[i]
            ab = h * inv_i[i]
            v[i, 0] += a * fx
            v[i, 1] += a * fy
            v[i, 2] += a * fz
            om[i, 0] += ab * tx
            om[i, 1] += ab * ty
            om[i, 2] += ab * tz


@njit(**_FM)
def wall_candidates(x, rad, W, tri, time, skin, fill, wstart, wcand, wslot, whist):
    """Particle-wall candidate list (CSR): walls closer than ``r + skin``.

    With ``fill=False`` writes per-particle counts to ``wstart[i+1]``; with
    ``fill=True`` (``wstart`` then holding offsets) writes the wall indices and
    frees history slots of walls that are no longer candidates.
    """
    n = x.shape[0]
    nw = W.shape[0]
    ns = wslot.shape[1]
    for i in range(n):
        pos = wstart[i]
        cnt = 0
        for w in range(nw):
            if int(W[w, 0]) == WALL_MESH:
                hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3 = mesh_geometry(
                    W, w, tri, x[i, 0], x[i, 1], x[i, 2], time)
            else:
                hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3 = wall_geometry(
                    W, w, x[i, 0], x[i, 1], x[i, 2], time)
            near = hit and dist < rad[i] + skin and dist > -rad[i] - skin
            if near:
                if fill:
                    wcand[pos] = w
                    pos += 1
                cnt += 1
            elif fill:
                for sl in range(ns):
                    if wslot[i, sl] == w:
                        wslot[i, sl] = -1
                        for c in range(6):
                            whist[i, sl, c] = 0.0
        if not fill:
            wstart[i + 1] = cnt


# --------------------------------------------------------------- neighbour lists
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
    the room was too small. Particles must be sorted by cell.
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
        for i in range(bounds[t], bounds[t + 1]):
            if over:
                break
            c = cells[i]
            cx = c % nx
            cy = (c // nx) % ny
            cz = c // (nx * ny)
            xi0 = x[i, 0]
            xi1 = x[i, 1]
            xi2 = x[i, 2]
            ri = rad[i] + skin
            cnt = 0
            pos = counts[i] if fill == 1 else tpos
            for s in range(ns + 1):
                sx = 0
                sy = 0
                sz = 0
                if s == ns:  # own cell, j > i
                    j0 = i + 1
                    j1 = start[c + 1]
                else:
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


@njit(parallel=True)
def pair_keys(ids, pi, pj, bounds, keys, sign):
    """Orientation-free key ``min(id) * 2^31 + max(id)`` and sign (+1 if id_i < id_j)."""
    nt = bounds.shape[0] - 1
    for t in prange(nt):
        for k in range(bounds[t], bounds[t + 1]):
            a = ids[pi[k]]
            b = ids[pj[k]]
            if a < b:
                keys[k] = a * 2147483648 + b
                sign[k] = 1.0
            else:
                keys[k] = b * 2147483648 + a
                sign[k] = -1.0


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
            if idx < m and old_keys_sorted[idx] == key:
                s = new_sign[k] * old_sign_sorted[idx]
                for c in range(3):
                    ht[k, c] = s * old_ht_sorted[idx, c]
                    hr[k, c] = s * old_hr_sorted[idx, c]
            else:
                for c in range(3):
                    ht[k, c] = 0.0
                    hr[k, c] = 0.0


@njit
def active_history(ht, hr):
    """Indices of pairs with nonzero history."""
    m = ht.shape[0]
    n = 0
    for k in range(m):
        if (ht[k, 0] != 0.0 or ht[k, 1] != 0.0 or ht[k, 2] != 0.0 or hr[k, 0] != 0.0
                or hr[k, 1] != 0.0 or hr[k, 2] != 0.0):
            n += 1
    out = np.empty(n, dtype=np.int64)
    n = 0
    for k in range(m):
        if (ht[k, 0] != 0.0 or ht[k, 1] != 0.0 or ht[k, 2] != 0.0 or hr[k, 0] != 0.0
                or hr[k, 1] != 0.0 or hr[k, 2] != 0.0):
            out[n] = k
            n += 1
    return out


@njit
def raindrop_accept(cand, crad, ex, erad, lo, cell_len, ncell, out_mask):
    """Greedy acceptance of candidate spheres that overlap neither existing spheres nor
    earlier accepted candidates (grid hash, serial; deterministic)."""
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
        c0 = min(max(int(math.floor((p0 - lo[0]) / cell_len[0])), 0), ncell[0] - 1)
        c1 = min(max(int(math.floor((p1 - lo[1]) / cell_len[1])), 0), ncell[1] - 1)
        c2 = min(max(int(math.floor((p2 - lo[2]) / cell_len[2])), 0), ncell[2] - 1)
        ok = True
        if k >= ne:
            for a in range(max(c0 - 1, 0), min(c0 + 2, ncell[0])):
                for b in range(max(c1 - 1, 0), min(c1 + 2, ncell[1])):
                    for c in range(max(c2 - 1, 0), min(c2 + 2, ncell[2])):
                        q = head[(c * ncell[1] + b) * ncell[0] + a]
                        while q >= 0:
                            d0 = p0 - px[q, 0]
                            d1 = p1 - px[q, 1]
                            d2 = p2 - px[q, 2]
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
