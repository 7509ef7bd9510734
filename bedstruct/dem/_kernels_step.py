"""numba integrator passes of the DEM engine (velocity Verlet, two passes per step).

:func:`kick_drift` (first half kick, drift, displacement since the last
neighbour build) and :func:`finish_step` (reduction of the per-chunk pair
forces, gravity, wall contacts, second half kick).
"""

from __future__ import annotations

from .._numba import njit, prange
from ._kernels_contact import wall_contact
from ._kernels_walls import any_wall_geometry

__all__ = ["kick_drift", "finish_step"]

# fastmath without reassociation or fused multiply-add: finish_step's fused half kick
# must round exactly as kick_drift's (v + a f twice, with a f rounded, not v + 2 a f)
_FM = dict(fastmath={"nnan", "ninf", "nsz", "arcp", "afn"})


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


@njit(parallel=True, **_FM)
def finish_step(P, fbuf, tbuf, gravity, bounds, WS, WTAB, rolling, tdamp, limit, eta_r, dt,
                store, wout, overflow, kick_next, x_ref, disp_out, kr_fac):
    """Reduce per-chunk forces, add gravity and wall forces, second half kick.

    ``P = (x, v, om, f, tq, mass, inv_m, inv_i, rad, ptype)`` are the particles;
    ``WS = (W, tri, time, wstart, wcand, wslot, whist, wbuf)`` the walls and their
    contacts; ``WTAB`` the ``(6, T+1, T+1)`` table of ``Y*``, ``G*``, ``beta``,
    ``mu``, ``mu_r`` and the SJKR energy density (row/column T: the walls);
    ``wout = (wfn, wdelta, wnorm)`` the wall-contact outputs written with ``store``.
    Only the walls listed for particle i in ``wcand[wstart[i]:wstart[i+1]]``
    (see :func:`wall_candidates`) are evaluated.
    With ``kick_next`` the pass goes on with the next step's :func:`kick_drift`
    (the same arithmetic, one pass over the particles less per step): the
    caller must then skip that kick_drift call.
    Wall contacts keep their tangential/rolling history in per-particle slots
    ``wslot[i, s]`` (wall index or -1) and ``whist[i, s, 0:6]``. The reaction
    on each wall is summed per chunk into ``wbuf[t, w, 0:6]`` (force, torque
    about the wall origin is not needed: 3:6 hold the sum of normal force
    magnitudes and contact counts).
    """
    x, v, om, f, tq, mass, inv_m, inv_i, rad, ptype = P
    W, tri, time, wstart, wcand, wslot, whist, wbuf = WS
    wfn_out, wdelta_out, wnorm_out = wout
    Y = WTAB[0]
    G = WTAB[1]
    B = WTAB[2]
    MU = WTAB[3]
    MUR = WTAB[4]
    COH = WTAB[5]
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
                hit, dist, n1, n2, n3, u1, u2, u3, o1, o2, o3 = any_wall_geometry(
                    W, w, tri, x[i, 0], x[i, 1], x[i, 2], time)
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
                    dist, (n1, n2, n3), (u1, u2, u3), (o1, o2, o3), (ri, mass[i], inv_i[i]),
                    (v[i, 0], v[i, 1], v[i, 2]), (om[i, 0], om[i, 1], om[i, 2]),
                    (Y[ti, wt], G[ti, wt], B[ti, wt], MU[ti, wt], MUR[ti, wt], COH[ti, wt]),
                    rolling, tdamp, limit, eta_r, dt, (h1, h2, h3), (q1, q2, q3), kr_fac)
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
        m2 = 0.0
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
            if not kick_next:  # f and tq are read by kick_drift and outputs only
                f[i, 0] = fx
                f[i, 1] = fy
                f[i, 2] = fz
                tq[i, 0] = tx
                tq[i, 1] = ty
                tq[i, 2] = tz
            # in locals, each array read and written once (no reloads through possible aliases)
            a = h * inv_m[i]
            ab = h * inv_i[i]
            v0 = v[i, 0] + a * fx
            v1 = v[i, 1] + a * fy
            v2 = v[i, 2] + a * fz
            o0 = om[i, 0] + ab * tx
            o1 = om[i, 1] + ab * ty
            o2 = om[i, 2] + ab * tz
            if kick_next:  # next step's half kick and drift, as kick_drift
                v0 += a * fx
                v1 += a * fy
                v2 += a * fz
                o0 += ab * tx
                o1 += ab * ty
                o2 += ab * tz
                p0 = x[i, 0] + dt * v0
                p1 = x[i, 1] + dt * v1
                p2 = x[i, 2] + dt * v2
                x[i, 0] = p0
                x[i, 1] = p1
                x[i, 2] = p2
                d0 = p0 - x_ref[i, 0]
                d1 = p1 - x_ref[i, 1]
                d2 = p2 - x_ref[i, 2]
                dd = d0 * d0 + d1 * d1 + d2 * d2
                if dd > m2:
                    m2 = dd
            v[i, 0] = v0
            v[i, 1] = v1
            v[i, 2] = v2
            om[i, 0] = o0
            om[i, 1] = o1
            om[i, 2] = o2
        if kick_next:
            disp_out[t] = m2
