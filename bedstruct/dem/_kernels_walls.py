"""numba wall geometry of the DEM engine: analytic walls, triangle meshes, candidate lists.

A wall is one row of the table ``W`` (``WALL_NCOL`` columns, written by
:mod:`bedstruct.dem.walls`); mesh walls point into a triangle table ``tri``.
:func:`wall_geometry` and :func:`mesh_geometry` return the closest-approach
data used by the integrator's wall pass (:func:`~bedstruct.dem._kernels_step.finish_step`).
"""

from __future__ import annotations

import math

import numpy as np

from .._numba import njit, prange

__all__ = ["wall_geometry", "closest_on_triangle", "mesh_geometry", "any_wall_geometry",
           "wall_candidates", "candidate_lists",
           "WALL_PLANE", "WALL_RECT", "WALL_PRISM", "WALL_CYLINDER", "WALL_MESH", "WALL_NCOL"]

WALL_PLANE = 0
WALL_RECT = 1
WALL_PRISM = 2
WALL_CYLINDER = 3
WALL_MESH = 4
WALL_NCOL = 34

_FM = dict(fastmath=True)


@njit(inline="always", **_FM)
def wall_geometry(W, w, px, py, pz, time):
    """Closest-approach data of wall ``w`` for a sphere centre p.

    Returns ``(hit, dist, n1, n2, n3, u1, u2, u3, om1, om2, om3)``: signed
    distance from the wall surface to p, unit normal from the wall to p,
    velocity of the wall surface at the contact point and wall angular
    velocity. ``hit`` is False where the geometry gives no direction (a centre on a
    cylinder's axis or rim). Beyond a cylinder's end the nearest point is on its rim.
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
        he = W[w, 14]
        if se > he or se < -he:
            # beyond an end (open, no cap): the nearest point is on the rim circle
            de = se - he if se > he else se + he
            dr = rho - rad
            d = math.sqrt(dr * dr + de * de)
            if d == 0.0:
                return False, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
            return (True, d, (dr * e1 + de * nx) / d, (dr * e2 + de * ny) / d,
                    (dr * e3 + de * nz) / d, s1, s2, s3, om * nx, om * ny, om * nz)
        return True, rho - rad, e1, e2, e3, s1, s2, s3, om * nx, om * ny, om * nz
    return False, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


@njit(inline="always", **_FM)
def _edge_dots(px, py, pz, qx, qy, qz, abx, aby, abz, acx, acy, acz):
    """``(ab . (p - q), ac . (p - q))`` for a vertex q of triangle abc."""
    rx = px - qx
    ry = py - qy
    rz = pz - qz
    return abx * rx + aby * ry + abz * rz, acx * rx + acy * ry + acz * rz


@njit(**_FM)
def closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point of triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5)."""
    abx = bx - ax
    aby = by - ay
    abz = bz - az
    acx = cx - ax
    acy = cy - ay
    acz = cz - az
    d1, d2 = _edge_dots(px, py, pz, ax, ay, az, abx, aby, abz, acx, acy, acz)
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az
    d3, d4 = _edge_dots(px, py, pz, bx, by, bz, abx, aby, abz, acx, acy, acz)
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz
    d5, d6 = _edge_dots(px, py, pz, cx, cy, cz, abx, aby, abz, acx, acy, acz)
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


@njit(inline="always", **_FM)
def any_wall_geometry(W, w, tri, px, py, pz, time):
    """:func:`mesh_geometry` for a mesh wall, :func:`wall_geometry` for the others."""
    # unpacked in each branch (one merge of scalars, as the callers had it written out:
    # the same machine code as returning either call's tuple would not be)
    if int(W[w, 0]) == WALL_MESH:
        hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3 = mesh_geometry(W, w, tri, px, py, pz, time)
    else:
        hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3 = wall_geometry(W, w, px, py, pz, time)
    return hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3


@njit
def prism_boxes(W):
    """Bounding box ``(u_min, u_max, v_min, v_max)`` of each prism wall's polygon in its
    own frame (rows of other walls are zero)."""
    box = np.zeros((W.shape[0], 4))
    for w in range(W.shape[0]):
        if int(W[w, 0]) == WALL_PRISM:
            box[w, 0] = box[w, 1] = W[w, 18]
            box[w, 2] = box[w, 3] = W[w, 19]
            for k in range(1, int(W[w, 17])):
                box[w, 0] = min(box[w, 0], W[w, 18 + 2 * k])
                box[w, 1] = max(box[w, 1], W[w, 18 + 2 * k])
                box[w, 2] = min(box[w, 2], W[w, 19 + 2 * k])
                box[w, 3] = max(box[w, 3], W[w, 19 + 2 * k])
    return box


@njit(inline="always", **_FM)
def _outside_prism_box(W, w, box, px, py, pz, time, reach):
    """True when p lies farther than ``reach`` outside prism w's bounding box (its polygon's
    box in the prism's frame, and its half length along the axis): the prism is then
    farther than ``reach`` from p."""
    dt0 = time - W[w, 13]
    rx = px - (W[w, 1] + W[w, 10] * dt0)
    ry = py - (W[w, 2] + W[w, 11] * dt0)
    rz = pz - (W[w, 3] + W[w, 12] * dt0)
    nx = W[w, 4]
    ny = W[w, 5]
    nz = W[w, 6]
    ux = W[w, 7]
    uy = W[w, 8]
    uz = W[w, 9]
    pu = rx * ux + ry * uy + rz * uz
    pv = rx * (uy * nz - uz * ny) + ry * (uz * nx - ux * nz) + rz * (ux * ny - uy * nx)
    se = rx * nx + ry * ny + rz * nz
    return (pu < box[w, 0] - reach or pu > box[w, 1] + reach or pv < box[w, 2] - reach
            or pv > box[w, 3] + reach or abs(se) > W[w, 14] + reach)


@njit(parallel=True, **_FM)
def wall_candidates(x, rad, W, tri, time, skin, bounds, near, wslot, whist):
    """Particle-wall candidates: ``near[i, w]`` is True when wall w is closer than ``r + skin``.

    One parallel pass over particle chunks (``bounds``); history slots of walls
    that are no longer candidates are freed. The orchestration compacts
    ``near`` into a CSR list (walls of a particle in increasing order). A prism (the
    blade) is measured only where the sphere is near its bounding box (within
    ``r + skin`` and a relative margin of 1e-6 that keeps rounding out of the answer).
    """
    nw = W.shape[0]
    ns = wslot.shape[1]
    nt = bounds.shape[0] - 1
    box = prism_boxes(W)
    for t in prange(nt):
        for i in range(bounds[t], bounds[t + 1]):
            for w in range(nw):
                if int(W[w, 0]) == WALL_PRISM and _outside_prism_box(
                        W, w, box, x[i, 0], x[i, 1], x[i, 2], time,
                        (rad[i] + skin) * (1.0 + 1e-6)):
                    ok = False
                else:
                    hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3 = any_wall_geometry(
                        W, w, tri, x[i, 0], x[i, 1], x[i, 2], time)
                    ok = hit and dist < rad[i] + skin and dist > -rad[i] - skin
                near[i, w] = ok
                if not ok:
                    for sl in range(ns):
                        if wslot[i, sl] == w:
                            wslot[i, sl] = -1
                            for c in range(6):
                                whist[i, sl, c] = 0.0


@njit
def candidate_lists(near):
    """CSR form of ``near``: ``start`` (n + 1) and the candidate walls of particle i in
    ``cand[start[i]:start[i + 1]]``, in increasing order."""
    n, nw = near.shape
    start = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        c = 0
        for w in range(nw):
            if near[i, w]:
                c += 1
        start[i + 1] = start[i] + c
    cand = np.empty(start[n], dtype=np.int64)
    k = 0
    for i in range(n):
        for w in range(nw):
            if near[i, w]:
                cand[k] = w
                k += 1
    return start, cand
