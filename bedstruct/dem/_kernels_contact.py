"""numba contact laws of the DEM engine (scalars in, scalars out; SI units).

Hertz normal stiffness and damping, the Mindlin tangential spring with
history and Coulomb cap, SJKR lens areas, rolling resistance (CDT, EPSD,
EPSD2) and the complete particle-wall contact built from them. The pair
kernels (:mod:`bedstruct.dem._kernels_pairs`) inline the same arithmetic.

Conventions (as LIGGGHTS): ``en`` points from the partner (j or the wall)
to i; ``Fn > 0`` is repulsive; the force on i is ``Fn en + Ft``.
"""

from __future__ import annotations

import math

from .._numba import njit

__all__ = ["hertz_coefficients", "sjkr_area_pair", "sjkr_area_wall", "tangential_history",
           "rolling_torque", "wall_contact", "ROLL_NONE", "ROLL_CDT", "ROLL_EPSD", "ROLL_EPSD2",
           "SQRT_5_6"]

SQRT_5_6 = math.sqrt(5.0 / 6.0)

ROLL_NONE = 0
ROLL_CDT = 1
ROLL_EPSD = 2
ROLL_EPSD2 = 3

_FM = dict(fastmath=True)


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
