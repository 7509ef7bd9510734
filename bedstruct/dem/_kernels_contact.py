"""numba contact laws of the DEM engine (scalars in, scalars out; SI units).

Each piece of contact physics is written once here as a small jitted function:
Hertz stiffness and damping, the normal force, SJKR lens areas, the relative
tangential velocity, the Mindlin tangential spring with history and Coulomb
cap, the torques of the tangential force, rolling resistance (CDT, EPSD,
EPSD2), the Willett capillary bridge and the ageing bond. They are composed
once into a pair contact (:func:`pair_contact_law`), which both pair passes
(:mod:`bedstruct.dem._kernels_pairs`, :mod:`bedstruct.dem._kernels_pairs_blocked`) compute,
and into the particle-wall contact (:func:`wall_contact`); the pair passes read
their per-type-pair constants from one table (:func:`pair_table`). Each can be tested in pure Python
through ``.py_func``.

Two kinds: the one-line pieces are inlined into the caller by numba
(``inline="always"``); the ones with branches (:func:`tangential_history`,
:func:`rolling_torque`, :func:`hertz_coefficients`, the SJKR areas,
:func:`capillary_force`) are compiled as functions of their own, which the
particle-wall contact calls. The pair passes inline every piece instead
(:data:`PAIR_PIECES`), rounded as written (:data:`STRICT`): their loop has no calls,
and a pair's bits do not depend on the loop around the law.

Conventions (as LIGGGHTS): ``en`` points from the partner (j or the wall)
to i; ``Fn > 0`` is repulsive; the force on i is ``Fn en + Ft``.
"""

from __future__ import annotations

import math
import types

import numpy as np

from .._numba import njit

__all__ = ["hertz_stiffness", "hertz_coefficients", "pair_damping", "normal_force",
           "sjkr_area_pair", "sjkr_area_wall", "tangential_velocity", "tangential_history",
           "shear_torques", "rolling_torque", "capillary_force", "ageing_bond",
           "wall_contact", "pair_contact", "pair_contact_law", "PAIR_PIECES", "STRICT",
           "ROLL_NONE", "ROLL_CDT", "ROLL_EPSD", "ROLL_EPSD2", "SQRT_5_6",
           "EPSD_STIFFNESS_FACTOR", "pair_table", "law_rows", "TAB_YOUNGS", "TAB_SHEAR",
           "TAB_DAMPING", "TAB_DAMPING_RATIO", "TAB_FRICTION", "TAB_ROLLING_FRICTION", "TAB_COHESION"]

SQRT_5_6 = math.sqrt(5.0 / 6.0)

ROLL_NONE = 0
ROLL_CDT = 1
ROLL_EPSD = 2
ROLL_EPSD2 = 3

#: Prefactor of the EPSD rolling stiffness ``k_r = f k_n mu_r^2 R*^2`` (Ai et al. 2011).
EPSD_STIFFNESS_FACTOR = 2.25

_FM = dict(fastmath=True)
_INLINE = dict(inline="always", fastmath=True)


@njit(**_INLINE)
def hertz_stiffness(sq, ystar, gstar):
    """Hertz normal and Mindlin tangential stiffness ``(k_n, k_t)`` from ``sq = sqrt(R* delta)``."""
    return 4.0 / 3.0 * ystar * sq, 8.0 * gstar * sq


@njit(**_INLINE)
def pair_damping(sq, meff, bcoef, gtr):
    """Normal and tangential damping ``(gamma_n, gamma_t)`` from per-type-pair constants.

    ``bcoef = -2 sqrt(5/6) beta sqrt(2 Y*)`` and ``gtr = sqrt(4 G*/Y*)`` (0
    without tangential damping): the damping of :func:`hertz_coefficients`
    with one square root less.
    """
    gn = bcoef * math.sqrt(sq * meff)
    return gn, gn * gtr


@njit(**_INLINE)
def normal_force(kn, delta, gn, vn, limit):
    """Hertz + damping normal force (> 0 repulsive), clipped at 0 with ``limit``."""
    fn = kn * delta - gn * vn
    if limit and fn < 0.0:
        fn = 0.0
    return fn


@njit(**_FM)
def hertz_coefficients(delta, reff, meff, ystar, gstar, beta):
    """LIGGGHTS Hertz: returns (kn, kt, gamma_n, gamma_t) for overlap ``delta``.

    The damping is computed from the restitution's ``beta`` directly (the
    particle-wall contact); :func:`pair_damping` gives the same quantity from
    precomputed per-type-pair constants.
    """
    sq = math.sqrt(reff * delta)
    sn = 2.0 * ystar * sq
    kn, st = hertz_stiffness(sq, ystar, gstar)
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


@njit(**_INLINE)
def tangential_velocity(vr1, vr2, vr3, vn, e1, e2, e3, w1, w2, w3):
    """Tangential relative velocity at the contact: ``v_r - v_n en - w x en``.

    ``w`` is the lever-weighted angular velocity (``cr_i om_i + cr_j om_j`` for
    a pair, ``cr om`` for a wall).
    """
    vt1 = vr1 - vn * e1 - (w2 * e3 - w3 * e2)
    vt2 = vr2 - vn * e2 - (w3 * e1 - w1 * e3)
    vt3 = vr3 - vn * e3 - (w1 * e2 - w2 * e1)
    return vt1, vt2, vt3


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


@njit(**_INLINE)
def shear_torques(e1, e2, e3, f1, f2, f3, cri, crj):
    """Torques of the tangential force about the two centres: ``-cr (en x Ft)`` each."""
    c1 = e2 * f3 - e3 * f2
    c2 = e3 * f1 - e1 * f3
    c3 = e1 * f2 - e2 * f1
    return -cri * c1, -cri * c2, -cri * c3, -crj * c1, -crj * c2, -crj * c3


@njit(**_FM)
def rolling_torque(model, h1, h2, h3, w1, w2, w3, e1, e2, e3, kn, kt, delta, reff, fn, mur,
                   dt, inertia_eff, eta_r, kr_fac=EPSD_STIFFNESS_FACTOR):
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
def capillary_force(gap, reff, CAP):
    """Willett et al. (2000) liquid-bridge force (N, attractive, >= 0) at separation ``gap``.

    ``R = 2 R*`` (the sphere radius for equal spheres, Derjaguin mean radius
    otherwise), bridge volume ``V = 2 pi R*^2 t`` (or the fixed ``CAP[3]``),
    ``F = 2 pi R gamma cos(theta) / (1 + 2.1 S + 10 S^2)`` with
    ``S = (gap/2) sqrt(R/V)``; zero beyond the rupture distance
    ``s_c = (1 + theta/2) V^(1/3)``; at contact (gap <= 0) ``2 pi R gamma cos(theta)``.
    ``CAP = (gamma cos theta, theta, film thickness, fixed volume or -1)``.
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


@njit(**_INLINE)
def ageing_bond(k_coh, area, age, AGE):
    """Bond of a resting contact of age ``age`` (N, attractive, >= 0).

    ``r F_sjkr ln(1 + t_w/tau) / ln(1 + t_ref/tau)`` with ``F_sjkr = k_coh area`` and
    ``AGE = (bond ratio r, tau, 1/ln(1 + t_ref/tau), break slip, ...)``.
    """
    return AGE[0] * k_coh * area * math.log1p(age / AGE[1]) * AGE[2]


@njit(**_FM)
def wall_contact(dist, n, u, o, sphere, vel, omega, law, rolling, tdamp, limit, eta_r, dt, h, r,
                 kr_fac=EPSD_STIFFNESS_FACTOR):
    """One particle-wall contact: force and torque on the particle, normal force, overlap
    and the updated tangential (h) and rolling (r) history, as a flat tuple of scalars.

    ``n``: unit normal from the wall to the sphere; ``u``, ``o``: the wall's velocity and
    angular velocity at the contact; ``sphere = (radius, mass, 1 / moment of inertia)``;
    ``vel``, ``omega``: the sphere's velocity and angular velocity; ``law = (Y*, G*, beta,
    mu, mu_r, cohesion energy density)`` of the wall-sphere type pair; ``h``, ``r``: the
    tangential and rolling history (all 3-vectors as tuples).
    """
    n1, n2, n3 = n
    u1, u2, u3 = u
    o1, o2, o3 = o
    ri, mi, inv_ii = sphere
    v1, v2, v3 = vel
    w1, w2, w3 = omega
    ystar, gstar, beta, mu, mur, kc = law
    h1, h2, h3 = h
    r1, r2, r3 = r
    delta = ri - dist
    kn, kt, gn, gt = hertz_coefficients(delta, ri, mi, ystar, gstar, beta)
    if not tdamp:
        gt = 0.0
    vr1 = v1 - u1
    vr2 = v2 - u2
    vr3 = v3 - u3
    vn = vr1 * n1 + vr2 * n2 + vr3 * n3
    fn = normal_force(kn, delta, gn, vn, limit)
    # Coulomb and rolling limits use Hertz + damping only: LIGGGHTS' default
    # (`tangential_reduce off`) adds cohesion to the force, not to the caps.
    fn_cap = fn
    if kc != 0.0:
        fn -= kc * sjkr_area_wall(dist, ri)
    cr = ri - 0.5 * delta
    vt1, vt2, vt3 = tangential_velocity(vr1, vr2, vr3, vn, n1, n2, n3, cr * w1, cr * w2, cr * w3)
    h1, h2, h3, f1, f2, f3 = tangential_history(h1, h2, h3, vt1, vt2, vt3, n1, n2, n3, kt, gt,
                                                mu, fn_cap, dt)
    t1, t2, t3, _, _, _ = shear_torques(n1, n2, n3, f1, f2, f3, cr, 0.0)
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


# --- one pair contact: the pieces composed -----------------------------------------------------

def pair_contact_law(**pieces):
    """The pair contact law as a Python function to jit, composed of this module's pieces
    or of those given by name (``tangential_history=...``).

    Both pair passes compute a contact with it as :data:`pair_contact`, its pieces
    inlined and rounded as written; with the pieces' ``py_func`` it runs in the
    interpreter (the test that the compiled passes round as written). The law is written
    once (one code object); only the functions its names resolve to differ.

    The returned ``law(dx, dy, dz, r2, ri, rj, mi, mj, vr, oi, oj, ystar, gstar, bcoef, gtr,
    mu, mur, k_coh, f_bridge, f_bond, s, h, inv_ii, inv_ij, rolling, limit, eta_r, dt,
    kr_fac)`` takes a touching pair's separation ``(dx, dy, dz) = x_i - x_j`` and
    ``r2 = |d|^2``, radii, masses, relative velocity ``vr = v_i - v_j`` and angular
    velocities ``oi``, ``oj`` (3-tuples), the type pair's constants
    (:func:`pair_table`), the attractive forces the extensions add to SJKR cohesion
    (``f_bridge`` a liquid bridge, ``f_bond`` an ageing bond; 0 when off), the
    tangential spring ``s`` and rolling torque ``h`` so far (3-tuples), the inverse moments
    of inertia (EPSD only) and the rolling model (a compile-time constant); fewer than 31
    arguments, so that numba can inline its calls. It returns
    ``(fn, f1, f2, f3, s1, s2, s3, h1, h2, h3, ti1, ti2, ti3, tj1, tj2, tj3, e1, e2, e3,
    vt1, vt2, vt3)``: the normal force (> 0 repulsive, cohesion and extensions
    included), the tangential force on i, the new spring and rolling torque (``h``
    unchanged without rolling resistance), the torques on i and j, the unit normal
    from j to i and the tangential velocity (which contact ageing needs).

    Coulomb and rolling limits use Hertz + damping only: LIGGGHTS' default
    (``tangential_reduce off``) adds cohesion to the force, not to the caps.
    """
    return types.FunctionType(_pair_contact.__code__, {**globals(), **pieces}, "pair_contact")


def _pair_contact(dx, dy, dz, r2, ri, rj, mi, mj, vr, oi, oj, ystar, gstar, bcoef, gtr, mu, mur,
                  k_coh, f_bridge, f_bond, s, h, inv_ii, inv_ij, rolling, limit, eta_r, dt, kr_fac):
    vr1, vr2, vr3 = vr
    oi1, oi2, oi3 = oi
    oj1, oj2, oj3 = oj
    s1, s2, s3 = s
    h1, h2, h3 = h
    rs = ri + rj
    r = math.sqrt(r2)
    rinv = 1.0 / r
    e1 = dx * rinv
    e2 = dy * rinv
    e3 = dz * rinv
    delta = rs - r
    reff = ri * rj / rs
    meff = mi * mj / (mi + mj)
    sq = math.sqrt(reff * delta)
    kn, kt = hertz_stiffness(sq, ystar, gstar)
    gn, gt = pair_damping(sq, meff, bcoef, gtr)
    vn = vr1 * e1 + vr2 * e2 + vr3 * e3
    fn = normal_force(kn, delta, gn, vn, limit)
    fn_cap = fn
    if k_coh != 0.0:
        fn -= k_coh * sjkr_area_pair(r, ri, rj)
    fn -= f_bridge
    fn -= f_bond
    cri = ri - 0.5 * delta
    crj = rj - 0.5 * delta
    vt1, vt2, vt3 = tangential_velocity(vr1, vr2, vr3, vn, e1, e2, e3,
                                        cri * oi1 + crj * oj1,
                                        cri * oi2 + crj * oj2,
                                        cri * oi3 + crj * oj3)
    s1, s2, s3, f1, f2, f3 = tangential_history(s1, s2, s3, vt1, vt2, vt3, e1, e2, e3, kt, gt,
                                                mu, fn_cap, dt)
    ti1, ti2, ti3, tj1, tj2, tj3 = shear_torques(e1, e2, e3, f1, f2, f3, cri, crj)
    if rolling != ROLL_NONE:
        if mur > 0.0:
            ieff = 0.0
            if rolling == ROLL_EPSD:
                ii = 1.0 / inv_ii + mi * ri * ri
                ij = 1.0 / inv_ij + mj * rj * rj
                ieff = ii * ij / (ii + ij)
            h1, h2, h3, m1, m2, m3 = rolling_torque(
                rolling, h1, h2, h3, oi1 - oj1, oi2 - oj2, oi3 - oj3, e1, e2, e3, kn, kt,
                delta, reff, fn_cap, mur, dt, ieff, eta_r, kr_fac)
            ti1 -= m1
            ti2 -= m2
            ti3 -= m3
            tj1 += m1
            tj2 += m2
            tj3 += m3
    return (fn, f1, f2, f3, s1, s2, s3, h1, h2, h3, ti1, ti2, ti3, tj1, tj2, tj3, e1, e2, e3,
            vt1, vt2, vt3)


#: Fast-math without reassociation or contraction into fused multiply-adds: every operation
#: rounded as written, so that a result does not depend on where the compiler puts it.
STRICT = dict(fastmath={"nnan", "ninf", "nsz"})

#: The pieces of the pair contact law as the pair passes compile them: inlined (their loop has
#: no calls, and LLVM vectorises the blocked pass's) and rounded as written.
PAIR_PIECES = {f.__name__: njit(inline="always", **STRICT)(f.py_func) for f in (
    hertz_stiffness, pair_damping, normal_force, sjkr_area_pair, tangential_velocity,
    tangential_history, shear_torques, rolling_torque)}

#: One pair contact (:func:`pair_contact_law` of :data:`PAIR_PIECES`), inlined into both pair
#: passes: a contact's bits do not depend on the pass, its place in a block or the loop around it.
pair_contact = njit(inline="always", **STRICT)(pair_contact_law(**PAIR_PIECES))


# --- the pair kernels' per-type-pair constants, and a pair apart ------------------------------

#: Rows of the per-type-pair table ``TAB`` (see :func:`pair_table`).
TAB_YOUNGS, TAB_SHEAR, TAB_DAMPING, TAB_DAMPING_RATIO, TAB_FRICTION, TAB_ROLLING_FRICTION, \
    TAB_COHESION = range(7)


@njit(inline="always")
def law_rows(TAB, kr_fac):
    """The pair law's per-type-pair tables as views of ``TAB`` (``Y*``, ``G*``, ``B``, ``GTR``,
    ``mu``, ``mu_r``, cohesion; see :func:`pair_table`) and the rolling stiffness factor:
    ``kr_fac``, or EPSD's :data:`EPSD_STIFFNESS_FACTOR` when it is None."""
    if kr_fac is None:
        krf = EPSD_STIFFNESS_FACTOR
    else:
        krf = kr_fac
    return (TAB[TAB_YOUNGS], TAB[TAB_SHEAR], TAB[TAB_DAMPING], TAB[TAB_DAMPING_RATIO],
            TAB[TAB_FRICTION], TAB[TAB_ROLLING_FRICTION], TAB[TAB_COHESION], krf)


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
def _clear_row(h, k):
    """Row ``k`` of a history array set to zero where it is not zero (a zero keeps its
    sign), written back either way, without a branch on its values."""
    a0 = h[k, 0]
    a1 = h[k, 1]
    a2 = h[k, 2]
    clear = a0 != 0.0 or a1 != 0.0 or a2 != 0.0
    h[k, 0] = 0.0 if clear else a0
    h[k, 1] = 0.0 if clear else a1
    h[k, 2] = 0.0 if clear else a2


@njit(inline="always", **_FM)
def _open_pair(k, ht, hr, store, fn_out, ft_out):
    """A pair apart: its tangential and rolling history cleared (:func:`_clear_row`) and no
    force stored."""
    _clear_row(ht, k)
    _clear_row(hr, k)
    if store:
        ft_out[k, 0] = 0.0
        ft_out[k, 1] = 0.0
        ft_out[k, 2] = 0.0
