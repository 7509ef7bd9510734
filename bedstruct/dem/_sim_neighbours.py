"""Neighbour lists of a :class:`~bedstruct.dem.Simulation`: rebuild, sort, history remap.

The :class:`_NeighbourList` mixin owns the displacement-triggered rebuild:
wrap periodic axes and remove particles that left the domain, sort the
particles by cell (an internal permutation: ids travel with the rows, and
:meth:`~bedstruct.dem.Simulation.frame` reports rows sorted by id), build the
half-stencil pair list, carry contact history over by pair key, and build the
particle-wall candidate list.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ..errors import BedstructError, ConfigError
from . import _kernels as K
from ._sim_walls import _WALL_SLOTS

__all__ = ["NumericalInstabilityError"]

log = logging.getLogger("bedstruct.dem.simulation")


class NumericalInstabilityError(BedstructError, RuntimeError):
    """Particles got non-finite positions: the simulation blew up (see the message).

    Raised by :class:`~bedstruct.dem.Simulation` (``nonfinite="raise"``, the default) as
    soon as a non-finite position is found; such particles are counted in
    ``Simulation.n_lost_nonfinite``, never in ``n_removed``.
    """


class _NeighbourList:
    """Cell grid, pair-list rebuild, wall candidates and per-chunk buffers (mixed into Simulation)."""

    def _cell_grid(self):
        rmax = float(self.rad.max(initial=0.0))
        key = (rmax, self.n_particles, self.skin, self._extra_cutoff(), self._L.tobytes())
        memo = self.__dict__.get("_grid_memo")
        if memo is not None and memo[0] == key:
            return memo[1]
        grid = self._cell_grid_for(rmax)
        self._grid_memo = (key, grid)
        return grid

    def _cell_grid_for(self, rmax):
        cut = 2.0 * rmax + self.skin + self._extra_cutoff()
        nc = np.maximum(1, np.floor(self._L / cut)).astype(np.int64)
        for a in range(3):
            if self._periodic[a] and nc[a] < 3:
                raise ConfigError(f"periodic box length along {'xyz'[a]} ({self._L[a]:.3g} m) must "
                                  f"be at least 3 neighbour cutoffs (3 x {cut:.3g} m)")
        # a sparse system in a large box: coarsen the axis with the most cells until the
        # grid has at most max(32 n, 32768) cells (the cell sort and its offsets scale
        # with the number of cells, the pair search with the particles per cell)
        cap = max(32 * self.n_particles, 32768)
        while np.prod(nc) > cap:
            free = [a for a in range(3) if nc[a] > (3 if self._periodic[a] else 1)]
            if not free:
                break
            a = max(free, key=lambda k: nc[k])
            nc[a] = max(3 if self._periodic[a] else 1, nc[a] // 2)
        return nc, self._L / nc

    def _extra_cutoff(self) -> float:
        """Neighbour cutoff beyond contact: the largest capillary rupture distance (m)."""
        if not self.model.capillary or self.rad.size == 0:
            return 0.0
        return float(self.model.rupture_distance(0.5 * float(self.rad.max())))

    def _chunks(self, n):
        # bounds of T equal chunks of n items; called several times per rebuild, so memoised
        # (a copy: callers rebalance theirs in place)
        memo = self.__dict__.setdefault("_chunk_memo", {})
        key = (int(n), self.n_threads)
        bounds = memo.get(key)
        if bounds is None:
            if len(memo) > 256:
                memo.clear()
            # np.linspace(0, n, T + 1).astype(np.int64), without its overhead: t * (n / T)
            # rounded as it rounds, truncated
            T = self.n_threads
            bounds = memo[key] = np.array([int(t * (n / T)) for t in range(T)] + [int(n)],
                                          dtype=np.int64)
        return bounds.copy()

    def _rebuild(self):
        self.n_rebuilds += 1
        # 1. wrap periodic axes, remove particles outside fixed faces or not finite
        out = np.zeros(self.n_particles, dtype=bool)
        n_out, n_bad = K.wrap_and_flag(self.x, self.images, self._lo, self._hi, self._L,
                                       self._periodic, out)
        self._rebuild_due = False
        if n_bad:
            self._lost_nonfinite(int(n_bad))
            n_out -= n_bad   # a blow-up is not particles leaving the domain
        if n_out:
            self.n_removed += n_out
            log.info("removed %d particles that left the domain (total %d)", n_out, self.n_removed)
        nc, cell_len = self._cell_grid()  # of the particles before any is dropped
        if n_out or n_bad:
            self._drop_particles(np.flatnonzero(~out))
        # 2. sort by cell, pair list, history carried onto it by pair key, wall lists. The
        #    remap looks each new pair up among its lower-id sphere's old partners (ids dense
        #    enough for a table by id), else by binary search in the sorted keys
        n = self.n_particles
        n_lo = int(self.ids.max(initial=-1)) + 1
        parts, pairs, hist, walls = K.rebuild_sorted(
            (self.x, self.v, self.om, self.f, self.tq, self.rad, self.mass, self.inv_m,
             self.inv_i, self.ptype, self.ids, self.images, self.wslot, self.whist),
            (self._lo, nc, cell_len), self._L, self._periodic, (self.pi, self.pj, self.psh),
            (self.ht, self.hr, self.hx), bool(self.model.contact_ageing),
            n_lo <= 8 * n + 1024, n_lo, self.skin + self._extra_cutoff(), self._chunks(n),
            getattr(self, "_m_hint", 0), (self._W, self._tri, float(self.time), self.skin))
        (self.x, self.v, self.om, self.f, self.tq, self.rad, self.mass, self.inv_m, self.inv_i,
         self.ptype, self.ids, self.images, self.wslot, self.whist, self.x_ref) = parts
        self.pi, self.pj, self.psh = pairs
        self.ht, self.hr, self.hx = hist
        self._m_hint = self.n_pairs
        self._alloc_buffers()
        self._balance_pairs()
        self._build_wall_list(walls)

    def _drop_particles(self, keep):
        """Keep particles ``keep`` only (in that order), and the pairs between them."""
        new = np.full(self.n_particles, -1, dtype=np.int64)
        new[keep] = np.arange(keep.shape[0])
        (self.x, self.v, self.om, self.f, self.tq, self.rad, self.mass, self.inv_m, self.inv_i,
         self.ptype, self.ids, self.images, self.wslot, self.whist) = K.permute_particles(
            keep, self.x, self.v, self.om, self.f, self.tq, self.rad, self.mass, self.inv_m,
            self.inv_i, self.ptype, self.ids, self.images, self.wslot, self.whist)
        both = (new[self.pi] >= 0) & (new[self.pj] >= 0)
        self.pi = new[self.pi[both]].astype(np.int32)
        self.pj = new[self.pj[both]].astype(np.int32)
        self.psh = np.ascontiguousarray(self.psh[both])
        self.ht = np.ascontiguousarray(self.ht[both])
        self.hr = np.ascontiguousarray(self.hr[both])
        if self.hx.shape[0]:
            self.hx = np.ascontiguousarray(self.hx[both])

    def _lost_nonfinite(self, n_bad: int) -> None:
        """``n_bad`` particles have non-finite positions: count them apart from the
        removals and raise :class:`NumericalInstabilityError` (``nonfinite="raise"``) or
        warn loudly and let the rebuild drop them (``nonfinite="drop"``)."""
        self.n_lost_nonfinite += n_bad
        t_r = getattr(self, "t_rayleigh", None)
        why = (f"{n_bad} particle(s) got non-finite positions at step {self.step} "
               f"(t = {self.time:.6g} s): the simulation blew up")
        hint = (f"; dt = {self.dt:.3g} s" + (f" = {self.dt / t_r:.0%} of the Rayleigh time "
                                             f"{t_r:.3g} s" if t_r else "")
                + ". Use a smaller time step (safety, or time.safety in a workflow), check the "
                  "contact parameters and wall motions")
        if self.nonfinite == "raise":
            raise NumericalInstabilityError(why + hint + "; Simulation(nonfinite='drop') drops "
                                            "such particles and goes on")
        log.warning("%s%s; dropped (%d so far, counted in n_lost_nonfinite, not n_removed)",
                    why, hint, self.n_lost_nonfinite)
        if not getattr(self, "_warned_nonfinite", False):
            import warnings
            from ..errors import BedstructWarning
            warnings.warn(why + "; the particles are dropped (Simulation.n_lost_nonfinite)",
                          BedstructWarning, stacklevel=4)
            self._warned_nonfinite = True

    def _displacement2(self):
        """Squared displacement of each particle since the last pair-list build, summed as
        the integrator's displacement test sums it."""
        d = self.x - self.x_ref
        return d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]

    def _build_wall_list(self, lists=None):
        """Candidate walls of each particle, built at the current time; rebuilt when a
        wall has moved skin/2 or at pair rebuilds (``lists``: the rebuild's).

        Until the next wall-list build each wall moves at most skin/2, and until the next
        rebuild each particle stays within skin/2 of where it was at the last pair-list
        build: one that has moved by d since then may still move by d + skin/2 from here.
        The candidates are therefore the walls closer than r + skin plus the largest such
        d (none at a rebuild, where the lists come from ``lists``)."""
        if lists is None:
            moved = math.sqrt(float(self._displacement2().max(initial=0.0)))
            lists = K.wall_lists(self.x, self.rad, self._W, self._tri, self.time,
                                 self.skin + moved, self._chunks(self.n_particles),
                                 self.wslot, self.whist)
        self._wstart, self._wcand = lists
        self._balance_finish()
        self._wall_list_time = self.time
        # fastest wall translation (a roller's spin does not move its surface), m/s
        W = self._W
        sp = np.sqrt((W[:, 10:13] ** 2).sum(axis=1)) if len(W) else np.zeros(0)
        self._wall_speed = float(sp.max(initial=0.0))
        for prog in self._programs.values():
            bound = (float(np.linalg.norm(prog["velocity"]))
                     + 2.0 * math.pi * prog["frequency"] * prog["amplitude"])
            self._wall_speed = max(self._wall_speed, bound)

    def _balance_pairs(self):
        """Pair-pass chunks of equal estimated work at this build: a touching pair
        costs 1, a pair within the skin 0.15 (it leaves after the overlap test).
        Fixed until the next build (and saved in checkpoints): results depend on it."""
        m = self.n_pairs
        self._qbounds = self._chunks(m)
        if self.n_threads > 1 and m:
            d = self.x[self.pi] - self.x[self.pj] - self.psh * self._L
            rs = self.rad[self.pi] + self.rad[self.pj]
            cost = np.cumsum(np.where(np.einsum("ij,ij->i", d, d) < rs * rs, 1.0, 0.15))
            tgt = cost[-1] * np.arange(1, self.n_threads) / self.n_threads
            self._qbounds[1:-1] = np.searchsorted(cost, tgt, side="left") + 1
            self._qbounds = np.maximum.accumulate(np.minimum(self._qbounds, m))

    def _balance_finish(self):
        """Chunks of the integrator's second pass with equal estimated work: a
        particle costs 1 and each of its candidate walls 8 (measured ratio ~10)."""
        n = self.n_particles
        self._fbounds = self._chunks(n)
        if self.n_threads > 1 and n and self._wstart.shape[0] == n + 1:
            cost = np.cumsum(1.0 + 8.0 * np.diff(self._wstart))
            tgt = cost[-1] * np.arange(1, self.n_threads) / self.n_threads
            self._fbounds[1:-1] = np.searchsorted(cost, tgt, side="left") + 1
            self._fbounds = np.maximum.accumulate(np.minimum(self._fbounds, n))

    def _alloc_buffers(self):
        n = self.n_particles
        T = self.n_threads
        if getattr(self, "_fbuf", None) is None or self._fbuf.shape != (T, n, 3):
            self._fbuf = np.zeros((T, n, 3))
            self._tbuf = np.zeros((T, n, 3))
        nw = self._W.shape[0]
        if getattr(self, "_wbuf", None) is None or self._wbuf.shape != (T, nw, 6):
            self._wbuf = np.zeros((T, nw, 6))
        if getattr(self, "_overflow", None) is not None:  # wall-slot overflows since the last build
            self.wall_overflow += int(self._overflow.sum())
        if getattr(self, "_disp", None) is None or self._disp.shape[0] != T:
            self._disp = np.zeros(T)
            self._overflow = np.zeros(T, dtype=np.int64)
        else:  # displacements and wall-slot overflows count from this build (the overflows
            # are added up in `wall_overflow`)
            self._disp.fill(0.0)
            self._overflow.fill(0)
        self._pbounds = self._chunks(n)
        self._fbounds = self._pbounds
        self._qbounds = self._chunks(self.n_pairs)
        if getattr(self, "_fn_out", None) is None:  # no outputs: empty, never written
            self._fn_out = np.zeros(0)
            self._ft_out = np.zeros((0, 3))
            self._wfn = np.zeros((0, _WALL_SLOTS))
            self._wdel = np.zeros((0, _WALL_SLOTS))
            self._wnrm = np.zeros((0, _WALL_SLOTS, 3))
