"""numba step loop of the DEM engine: many velocity-Verlet steps in one call.

:func:`run_steps` makes the steps of :meth:`~bedstruct.dem.Simulation.run` between two
looks at the state (a neighbour rebuild, a new wall candidate list, a finiteness check,
an output) without returning to Python: per step the same kernel calls with the same
arguments as the orchestrator's own step (:func:`~bedstruct.dem._kernels_step.kick_drift`
unless fused, the pair pass, the wall programs, :func:`~bedstruct.dem._kernels_step.finish_step`
and the running sum of wall loads), so the results are bit for bit the same. It hands back
as soon as a rebuild or a new wall list is due, with that step's drift done.

The pair pass comes as its index in :data:`~bedstruct.dem._kernels_pairs.PAIR_PASSES` (the
variant the contact model selects), a compile-time constant, and its arguments: the loop is
compiled, and cached, once per variant.
"""

from __future__ import annotations

import math

from .._numba import njit
from ._kernels_pairs import run_pair_pass
from ._kernels_step import finish_step, kick_drift

__all__ = ["run_steps", "apply_wall_programs", "add_wall_loads", "PROGRAM_NCOL"]

#: Columns of the wall-program table: wall, t0, origin (3), velocity (3), ramp time,
#: amplitude, frequency, direction (3) (see ``Simulation.set_wall_program``).
PROGRAM_NCOL = 14


@njit
def apply_wall_programs(PROG, W, time):
    """Position and velocity of each programmed wall at ``time`` written into its row of
    ``W`` (and ``time`` as the row's reference time).

    With ``s`` the time since the program's start, ``tau`` the ramp time, ``A`` the
    amplitude, ``f`` the frequency and **d** the unit vibration direction (see
    ``Simulation.set_wall_program``)::

        x(s) = x(0) + v [s - tau (1 - exp(-s/tau))] + A sin(2 pi f s) d
        u(s) = v (1 - exp(-s/tau)) + 2 pi f A cos(2 pi f s) d

    (``tau = 0``: ``x = x(0) + v s``, ``u = v``).
    """
    for p in range(PROG.shape[0]):
        w = int(PROG[p, 0])
        s = time - PROG[p, 1]
        tau = PROG[p, 8]
        e = 0.0
        ramp = 0.0
        if tau > 0.0:
            e = math.exp(-s / tau)
            ramp = s - tau * (1.0 - e)
        amp = PROG[p, 9]
        sn = 0.0
        cs = 0.0
        om = 0.0
        if amp > 0.0:
            om = 2.0 * math.pi * PROG[p, 10]
            sn = amp * math.sin(om * s)
            cs = amp * om * math.cos(om * s)
        for k in range(3):
            vk = PROG[p, 5 + k]
            if tau > 0.0:
                xk = PROG[p, 2 + k] + vk * ramp
                uk = vk * (1.0 - e)
            else:
                xk = PROG[p, 2 + k] + vk * s
                uk = vk
            if amp > 0.0:
                xk = xk + sn * PROG[p, 11 + k]
                uk = uk + cs * PROG[p, 11 + k]
            W[w, 1 + k] = xk
            W[w, 10 + k] = uk
        W[w, 13] = time


@njit
def add_wall_loads(wbuf, wload):
    """Add this step's force of the particles on each wall (the sum of the per-chunk
    buffers ``wbuf[:, w, :3]``, in chunk order) to ``wload``."""
    for w in range(wload.shape[0]):
        for c in range(3):
            acc = wbuf[0, w, c]
            for b in range(1, wbuf.shape[0]):
                acc += wbuf[b, w, c]
            wload[w, c] += acc


@njit(inline="always")
def _run_steps(pair_pass, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    kicked, time, dt, thr2, half_skin, wall_speed, wall_list_time = clock
    x, v, om, f, tq, inv_m, inv_i, pbounds = KD
    (FP, fbuf, tbuf, gravity, fbounds, WG, WTAB, rolling, tdamp, limit, eta_r, wout, overflow,
     x_ref, disp, kr_fac) = FIN
    W, tri, wstart, wcand, wslot, whist, wbuf = WG
    done = 0
    while done < nmax:
        if not kicked:
            kick_drift(x, v, om, f, tq, inv_m, inv_i, x_ref, dt, pbounds, disp)
        if disp.max() > thr2 or wall_speed * (time + dt - wall_list_time) > half_skin:
            return done, time, True
        run_pair_pass(pair_pass, PA)  # pair_pass is a constant where inlined
        time = time + dt
        if PROG.shape[0]:
            apply_wall_programs(PROG, W, time)
        kick_next = done + 1 < nmax or fuse_last
        finish_step(FP, fbuf, tbuf, gravity, fbounds, (W, tri, time, wstart, wcand, wslot, whist,
                                                        wbuf), WTAB, rolling, tdamp, limit, eta_r,
                    dt, False, wout, overflow, kick_next, x_ref, disp, kr_fac)
        kicked = kick_next
        if wload.shape[0]:
            add_wall_loads(wbuf, wload)
        done += 1
    return done, time, kicked


# one compiled (and cached) loop per pair pass of PAIR_PASSES, the pass a constant in each
@njit
def _run_steps_0(nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    return _run_steps(0, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)


@njit
def _run_steps_1(nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    return _run_steps(1, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)


@njit
def _run_steps_2(nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    return _run_steps(2, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)


@njit
def _run_steps_3(nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    return _run_steps(3, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)


@njit
def _run_steps_4(nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    return _run_steps(4, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)


@njit
def _run_steps_5(nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    return _run_steps(5, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)


@njit
def _run_steps_6(nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    return _run_steps(6, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)


@njit
def _run_steps_7(nmax, fuse_last, clock, KD, PA, FIN, PROG, wload):
    return _run_steps(7, nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)


_BY_PASS = (_run_steps_0, _run_steps_1, _run_steps_2, _run_steps_3, _run_steps_4, _run_steps_5,
            _run_steps_6, _run_steps_7)


def run_steps(nmax, fuse_last, clock, KD, pair_pass, PA, FIN, PROG, wload):
    """Up to ``nmax`` steps; returns ``(steps done, time, kicked)``.

    ``clock = (kicked, time, dt, thr2, half_skin, wall_speed, wall_list_time)``;
    ``KD = (x, v, om, f, tq, inv_m, inv_i, pbounds)`` are :func:`kick_drift`'s arrays;
    ``PAIR_PASSES[pair_pass](*PA)`` is the pair pass; ``FIN = (FP, fbuf, tbuf, gravity,
    fbounds, WG, WTAB, rolling, tdamp, limit, eta_r, wout, overflow, x_ref, disp, kr_fac)``
    are :func:`finish_step`'s arguments with ``WG = (W, tri, wstart, wcand, wslot, whist,
    wbuf)`` (the time is the loop's); ``PROG`` the wall programs (``PROGRAM_NCOL`` columns,
    none: 0 rows); ``wload`` the running sum of wall loads (0 rows: not summed).
    Every step but the last is fused with the next one's half kick and drift; the last
    is with ``fuse_last``. Fewer steps are done when a rebuild (largest squared
    displacement above ``thr2``) or a new wall list (walls moved more than
    ``half_skin``) is due: the next step's drift is then done (``kicked`` True).
    """
    return _BY_PASS[pair_pass](nmax, fuse_last, clock, KD, PA, FIN, PROG, wload)
