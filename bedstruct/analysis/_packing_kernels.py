"""Numba kernels: exact volume of the intersection of spheres with cuboids.

The volume of a ball of radius ``r`` inside a cuboid is integrated over one
clipped axis ``t`` of the exact area of the disc of radius
``rho(t) = sqrt(r^2 - t^2)`` inside the rectangle spanned by the other two
axes. The area has a closed form (below). The integral is taken over the polar
angle, ``t = r sin(theta)``, ``rho = r cos(theta)``, which removes the
square-root branch points of ``rho`` at the poles; the integrand's remaining
kinks (``rho`` equal to the distance from the centre to an edge line or a
corner) split the range, and each piece is integrated with Gauss-Legendre
nodes after the substitution ``theta = a + (b - a)(3u^2 - 2u^3)`` (smooth at
both ends), refined by adaptive bisection until the halves agree with the
whole to 1e-13 r^3. Tested against adaptive quadrature, Monte Carlo,
additivity under splitting and permutation of the integration axis.
"""

from __future__ import annotations

import math

import numpy as np

from .._numba import njit

__all__ = ["sphere_box_volume_one", "sphere_box_volumes", "grid_volumes", "cap_height_map"]

_BIG = 1e300


@njit
def _hprim(x, rho):
    """Integral of sqrt(rho^2 - X^2) from -rho to x, for x in [-rho, rho]."""
    if x <= -rho:
        return 0.0
    if x >= rho:
        return 0.5 * math.pi * rho * rho
    h = math.sqrt(max(rho * rho - x * x, 0.0))
    return 0.5 * (x * h + rho * rho * math.asin(x / rho)) + 0.25 * math.pi * rho * rho


@njit
def _quadrant(x, y, rho):
    """Area of the disc of radius rho at the origin with X <= x and Y <= y."""
    if x <= -rho or y <= -rho:
        return 0.0
    xc = min(x, rho)
    if y >= rho:
        return 2.0 * _hprim(xc, rho)
    w = math.sqrt(max(rho * rho - y * y, 0.0))
    if y >= 0.0:
        # lengths: h(X) + min(y, h(X)) for X in [-rho, xc]
        area = _hprim(xc, rho)
        a = min(xc, -w)
        area += _hprim(a, rho)
        lo = max(-w, -rho)
        hi = min(xc, w)
        if hi > lo:
            area += y * (hi - lo)
        if xc > w:
            area += _hprim(xc, rho) - _hprim(w, rho)
        return area
    # y < 0: length h(X) + y where |X| < w
    hi = min(xc, w)
    if hi <= -w:
        return 0.0
    return _hprim(hi, rho) - _hprim(-w, rho) + y * (hi + w)


@njit
def _disc_rect(x0, x1, y0, y1, rho):
    """Area of the disc of radius rho at the origin inside [x0, x1] x [y0, y1]."""
    if rho <= 0.0 or x1 <= x0 or y1 <= y0:
        return 0.0
    return (_quadrant(x1, y1, rho) - _quadrant(x0, y1, rho)
            - _quadrant(x1, y0, rho) + _quadrant(x0, y0, rho))


@njit
def _insert_sorted(buf, n, v):
    k = n
    while k > 0 and buf[k - 1] > v:
        buf[k] = buf[k - 1]
        k -= 1
    buf[k] = v
    return n + 1


@njit
def sphere_box_volume_one(cx, cy, cz, r, x0, x1, y0, y1, z0, z1, nodes, weights):
    """Exact volume of the ball (centre, r) inside the cuboid [x0,x1]x[y0,y1]x[z0,z1]."""
    lo0 = x0 - cx
    hi0 = x1 - cx
    lo1 = y0 - cy
    hi1 = y1 - cy
    lo2 = z0 - cz
    hi2 = z1 - cz
    if hi0 <= -r or lo0 >= r or hi1 <= -r or lo1 >= r or hi2 <= -r or lo2 >= r:
        return 0.0
    if hi0 <= lo0 or hi1 <= lo1 or hi2 <= lo2:
        return 0.0
    c0 = lo0 > -r or hi0 < r
    c1 = lo1 > -r or hi1 < r
    c2 = lo2 > -r or hi2 < r
    nclip = int(c0) + int(c1) + int(c2)
    if nclip == 0:
        return 4.0 / 3.0 * math.pi * r * r * r
    # integration axis t: a clipped axis; (u, v): the other two
    if c2:
        ta, tb, ua, ub, va, vb = lo2, hi2, lo0, hi0, lo1, hi1
    elif c0:
        ta, tb, ua, ub, va, vb = lo0, hi0, lo1, hi1, lo2, hi2
    else:
        ta, tb, ua, ub, va, vb = lo1, hi1, lo0, hi0, lo2, hi2
    ta = max(ta, -r)
    tb = min(tb, r)
    if nclip == 1:
        # only t clipped: integral of pi (r^2 - t^2)
        return math.pi * (r * r * (tb - ta) - (tb * tb * tb - ta * ta * ta) / 3.0)
    ua = max(ua, -r)
    ub = min(ub, r)
    va = max(va, -r)
    vb = min(vb, r)
    # breakpoints: rho(t) equal to edge distances and corner distances
    # breakpoints in the polar angle theta (t = r sin theta, rho = r cos theta):
    # rho equal to an edge or corner distance d <=> theta = +-acos(d / r)
    bp = np.empty(22)
    nb = 0
    tha = math.asin(max(-1.0, min(1.0, ta / r)))
    thb = math.asin(max(-1.0, min(1.0, tb / r)))
    nb = _insert_sorted(bp, nb, tha)
    nb = _insert_sorted(bp, nb, thb)
    cu = ua > -r or ub < r
    cv = va > -r or vb < r
    for k in range(4):
        if k == 0:
            d = abs(ua) if cu and ua > -r else -1.0
        elif k == 1:
            d = abs(ub) if cu and ub < r else -1.0
        elif k == 2:
            d = abs(va) if cv and va > -r else -1.0
        else:
            d = abs(vb) if cv and vb < r else -1.0
        if 0.0 <= d < r:
            th = math.acos(d / r)
            if tha < th < thb:
                nb = _insert_sorted(bp, nb, th)
            if tha < -th < thb:
                nb = _insert_sorted(bp, nb, -th)
    if cu and cv:
        for p in range(2):
            uu = ua if p == 0 else ub
            for q in range(2):
                vv = va if q == 0 else vb
                dc = math.sqrt(uu * uu + vv * vv)
                if dc < r:
                    th = math.acos(dc / r)
                    if tha < th < thb:
                        nb = _insert_sorted(bp, nb, th)
                    if tha < -th < thb:
                        nb = _insert_sorted(bp, nb, -th)
    total = 0.0
    scale = r * r * r
    stack = np.empty((64, 2))
    for s in range(nb - 1):
        if bp[s + 1] <= bp[s]:
            continue
        # adaptive bisection: accept a piece when its two halves agree with it
        top = 0
        stack[0, 0] = bp[s]
        stack[0, 1] = bp[s + 1]
        top = 1
        while top > 0:
            top -= 1
            a = stack[top, 0]
            b = stack[top, 1]
            m = 0.5 * (a + b)
            whole = _piece(a, b, r, ua, ub, va, vb, nodes, weights)
            left = _piece(a, m, r, ua, ub, va, vb, nodes, weights)
            right = _piece(m, b, r, ua, ub, va, vb, nodes, weights)
            if abs(left + right - whole) <= 1e-13 * scale or top >= 62 or b - a < 1e-12:
                total += left + right
            else:
                stack[top, 0] = a
                stack[top, 1] = m
                stack[top + 1, 0] = m
                stack[top + 1, 1] = b
                top += 2
    return total


@njit
def _piece(a, b, r, ua, ub, va, vb, nodes, weights):
    """Gauss-Legendre integral over theta in [a, b] of A(r cos theta) r cos theta, with the
    end-smoothing substitution theta = a + (b - a)(3u^2 - 2u^3)."""
    h = b - a
    acc = 0.0
    for q in range(nodes.shape[0]):
        u = nodes[q]
        th = a + h * (3.0 * u * u - 2.0 * u * u * u)
        jac = 6.0 * u * (1.0 - u)
        rho = r * math.cos(th)
        if rho <= 0.0:
            continue
        acc += weights[q] * jac * rho * _disc_rect(ua, ub, va, vb, rho)
    return acc * h


@njit
def sphere_box_volumes(centres, radii, lower, upper, nodes, weights, out):
    """``out[i]`` = volume of sphere ``i`` inside the one cuboid (lower, upper)."""
    for i in range(centres.shape[0]):
        out[i] = sphere_box_volume_one(centres[i, 0], centres[i, 1], centres[i, 2], radii[i],
                                       lower[0], upper[0], lower[1], upper[1], lower[2], upper[2],
                                       nodes, weights)


@njit
def _first_cell(edges, x):
    """Index of the cell of a sorted edge array that contains x (clipped)."""
    n = edges.shape[0] - 1
    k = np.searchsorted(edges, x, side="right") - 1
    if k < 0:
        return 0
    if k > n - 1:
        return n - 1
    return k


@njit
def grid_volumes(centres, radii, shifts, ex, ey, ez, nodes, weights, out):
    """Add to ``out[a, b, c]`` the volume of every sphere image inside each grid cell.

    The grid is rectilinear with sorted cell edges ``ex``, ``ey``, ``ez``;
    ``shifts`` (S, 3) are the periodic image translations to try (include
    zero). Serial scatter: each sphere touches only the cells it overlaps.
    """
    gx0 = ex[0]
    gx1 = ex[ex.shape[0] - 1]
    gy0 = ey[0]
    gy1 = ey[ey.shape[0] - 1]
    gz0 = ez[0]
    gz1 = ez[ez.shape[0] - 1]
    full_c = 4.0 / 3.0 * math.pi
    for i in range(centres.shape[0]):
        r = radii[i]
        for s in range(shifts.shape[0]):
            cx = centres[i, 0] + shifts[s, 0]
            cy = centres[i, 1] + shifts[s, 1]
            cz = centres[i, 2] + shifts[s, 2]
            if cx + r <= gx0 or cx - r >= gx1 or cy + r <= gy0 or cy - r >= gy1 \
                    or cz + r <= gz0 or cz - r >= gz1:
                continue
            a0 = _first_cell(ex, cx - r)
            a1 = _first_cell(ex, cx + r)
            b0 = _first_cell(ey, cy - r)
            b1 = _first_cell(ey, cy + r)
            c0 = _first_cell(ez, cz - r)
            c1 = _first_cell(ez, cz + r)
            if a0 == a1 and b0 == b1 and c0 == c1 and cx - r >= ex[a0] and cx + r <= ex[a0 + 1] \
                    and cy - r >= ey[b0] and cy + r <= ey[b0 + 1] \
                    and cz - r >= ez[c0] and cz + r <= ez[c0 + 1]:
                out[a0, b0, c0] += full_c * r * r * r
                continue
            for a in range(a0, a1 + 1):
                for b in range(b0, b1 + 1):
                    for c in range(c0, c1 + 1):
                        out[a, b, c] += sphere_box_volume_one(
                            cx, cy, cz, r, ex[a], ex[a + 1], ey[b], ey[b + 1], ez[c], ez[c + 1],
                            nodes, weights)


@njit(inline="always")
def _node_index(k, n, periodic):
    """Node index ``k`` on a lateral axis of ``n`` nodes: (wrapped index, inside).

    Along a periodic axis ``k`` wraps into ``[0, n)``; along a closed axis a
    node outside is not inside.
    """
    if periodic:
        return k % n, True
    return k, k >= 0 and k < n


@njit
def cap_height_map(pos, radii, probe, x0, y0, dx, dy, per_x, per_y, ax, ay, az, out):
    """Highest point of every sphere (grown by ``probe``) above each grid node.

    Node ``(k, l)`` sits at ``(x0 + (k + 1/2) dx, y0 + (l + 1/2) dy)``; along a
    periodic lateral axis node indices wrap. ``out`` (nx, ny) must be
    initialised (e.g. to -inf); it receives ``max_i z_i + sqrt((r_i + p)^2 -
    rho^2) - p``, the height of the lowest point of a probe sphere of radius
    ``p`` lowered onto the spheres (``p = 0``: the highest cap).
    """
    nx = out.shape[0]
    ny = out.shape[1]
    for i in range(pos.shape[0]):
        rr = radii[i] + probe
        cx = pos[i, ax]
        cy = pos[i, ay]
        cz = pos[i, az]
        k0 = int(math.ceil((cx - rr - x0) / dx - 0.5))
        k1 = int(math.floor((cx + rr - x0) / dx - 0.5))
        l0 = int(math.ceil((cy - rr - y0) / dy - 0.5))
        l1 = int(math.floor((cy + rr - y0) / dy - 0.5))
        for k in range(k0, k1 + 1):
            kk, inside = _node_index(k, nx, per_x)
            if not inside:
                continue
            ddx = x0 + (k + 0.5) * dx - cx
            for m in range(l0, l1 + 1):
                mm, inside = _node_index(m, ny, per_y)
                if not inside:
                    continue
                ddy = y0 + (m + 0.5) * dy - cy
                d2 = ddx * ddx + ddy * ddy
                if d2 < rr * rr:
                    h = cz + math.sqrt(rr * rr - d2) - probe
                    if h > out[kk, mm]:
                        out[kk, mm] = h
