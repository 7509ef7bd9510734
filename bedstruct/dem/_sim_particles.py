"""Adding spheres to a :class:`~bedstruct.dem.Simulation`: arrays, raindrop insertion, saved piles.

A mixin of :class:`~bedstruct.dem.Simulation` (like ``_sim_walls`` and
``_sim_neighbours``): it validates new particles, derives their mass and inertia from
the contact model's materials and appends them to the structure-of-arrays state.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ..core import Frame
from ._sim_walls import _WALL_SLOTS, _vec3
from .insertion import raindrop_positions, sample_radii

log = logging.getLogger("bedstruct.dem.simulation")

#: Ids stay below 2^31: the neighbour list keys a pair's history by ``min(id) 2^31 + max(id)``.
_ID_LIMIT = 2 ** 31


class _Particles:
    """Particle insertion of :class:`~bedstruct.dem.Simulation`."""

    def add_particles(self, positions, radii, *, types=None, velocities=None, omegas=None,
                      ids=None) -> None:
        """Add spheres.

        Parameters
        ----------
        positions : (n, 3) array_like, m
        radii : (n,) array_like or float, m
        types : (n,) array_like of int, optional
            Particle types 1..T of the contact model (default 1).
        velocities, omegas : (n, 3) array_like, optional
            m/s and rad/s (default 0).
        ids : (n,) array_like of int, optional
            Unique positive ids below 2^31 (default: continuing from the largest id).
        """
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        n = pos.shape[0]
        rad = np.asarray(radii, dtype=np.float64)
        rad = np.full(n, float(rad)) if rad.ndim == 0 else rad.reshape(-1)
        if rad.shape != (n,) or not np.all(np.isfinite(rad) & (rad > 0)):
            raise ValueError(f"`radii` must be {n} positive finite values matching `positions`; "
                             f"got shape {rad.shape}")
        if not np.all(np.isfinite(pos)):
            raise ValueError("`positions` must be finite")
        typ = np.ones(n, dtype=np.int64) if types is None else np.asarray(types).reshape(-1).astype(np.int64)
        if typ.shape != (n,) or typ.min(initial=1) < 1 or typ.max(initial=1) > self.model.n_types:
            raise ValueError(f"`types` must be {n} integers in 1..{self.model.n_types} "
                             f"(the contact model's types); got {np.unique(typ).tolist()}")
        vel = np.zeros((n, 3)) if velocities is None else np.asarray(velocities, np.float64).reshape(n, 3)
        omg = np.zeros((n, 3)) if omegas is None else np.asarray(omegas, np.float64).reshape(n, 3)
        if ids is None:
            new_ids = np.arange(self._next_id, self._next_id + n, dtype=np.int64)
        else:
            new_ids = np.asarray(ids, dtype=np.int64).reshape(-1)
            if new_ids.shape != (n,) or new_ids.min(initial=1) < 1:
                raise ValueError("`ids` must be n positive integers")
        if new_ids.max(initial=0) >= _ID_LIMIT:
            raise ValueError(f"particle ids must be below 2^31 = {_ID_LIMIT} (contact histories "
                             f"are keyed by pairs of ids); got {int(new_ids.max())}: renumber the "
                             "particles (e.g. `insert_frame(..., keep_ids=False)`)")
        allids = np.concatenate([self.ids, new_ids])
        if np.unique(allids).size != allids.size:
            raise ValueError("particle ids must be unique (an added id already exists)")
        self._next_id = int(allids.max(initial=0)) + 1
        dens = np.array([m.density for m in self.model.materials])[typ - 1]
        mass = 4.0 / 3.0 * math.pi * rad ** 3 * dens
        inertia = 0.4 * mass * rad ** 2
        cat = np.concatenate
        self.x = np.ascontiguousarray(cat([self.x, pos]))
        self.v = np.ascontiguousarray(cat([self.v, vel]))
        self.om = np.ascontiguousarray(cat([self.om, omg]))
        self.f = np.ascontiguousarray(cat([self.f, np.zeros((n, 3))]))
        self.tq = np.ascontiguousarray(cat([self.tq, np.zeros((n, 3))]))
        self.rad = cat([self.rad, rad])
        self.mass = cat([self.mass, mass])
        self.inv_m = cat([self.inv_m, 1.0 / mass])
        self.inv_i = cat([self.inv_i, 1.0 / inertia])
        self.ptype = cat([self.ptype, (typ - 1).astype(np.int32)])
        self.ids = allids
        self.images = cat([self.images, np.zeros((n, 3), dtype=np.int64)])
        self.x_ref = np.ascontiguousarray(cat([self.x_ref, pos]))
        self.wslot = cat([self.wslot, -np.ones((n, _WALL_SLOTS), dtype=np.int32)])
        self.whist = cat([self.whist, np.zeros((n, _WALL_SLOTS, 6))])
        self._ready = False

    def insert_raindrop(self, n: int, psd, *, region=None, types=1, velocity=(0.0, 0.0, 0.0),
                        max_attempts: int = 50) -> int:
        """Raindrop insertion: place up to ``n`` non-overlapping spheres in a region.

        Parameters
        ----------
        n : int
            Number of spheres wanted.
        psd : radius, array, callable or percentile mapping
            Size distribution (see :func:`~bedstruct.dem.sample_radii`), m.
        region : ((3,), (3,)), m, optional
            ``(lo, hi)`` corners; default the whole box. Along a periodic axis
            that it spans whole, centres are drawn over the whole period and
            spheres do not overlap across it.
        types : int or (n,) array
        velocity : (3,) array_like, m/s

        Returns
        -------
        int
            Number actually inserted (fewer when the region is full).

        Notes
        -----
        The radii that do not fit are dropped; large spheres fit less often than small
        ones, so the spheres placed in a region that fills up are finer than ``psd``.
        To fill a volume in several insertions with the distribution intact, draw the
        radii once and carry those not placed to the next insertion with
        :meth:`insert_radii`.
        """
        radii = sample_radii(n, psd, rng=self.rng)
        return int(np.count_nonzero(self.insert_radii(radii, region=region, types=types,
                                                      velocity=velocity,
                                                      max_attempts=max_attempts)))

    def insert_radii(self, radii, *, region=None, types=1, velocity=(0.0, 0.0, 0.0),
                     max_attempts: int = 50) -> np.ndarray:
        """Raindrop insertion of given radii, in order: which of them were placed.

        Parameters
        ----------
        radii : (n,) array_like of float, m
            Radii to place, in order of preference.
        region : ((3,), (3,)), m, optional
            As :meth:`insert_raindrop`.
        types : int or (n,) array
        velocity : (3,) array_like, m/s

        Returns
        -------
        (n,) ndarray of bool
            Which of ``radii`` were inserted (all but those that found no room).
        """
        radii = np.asarray(radii, dtype=np.float64).reshape(-1)
        n = radii.shape[0]
        if n and not (np.all(np.isfinite(radii)) and radii.min() > 0):
            raise ValueError("`radii` must be positive and finite")
        lo, hi = (self._lo.copy(), self._hi.copy()) if region is None else (
            np.array(region[0], dtype=float), np.array(region[1], dtype=float))
        period = np.where(self._periodic, self._L, 0.0)
        pos, ok = raindrop_positions(lo, hi, radii, existing=self.x, existing_radii=self.rad,
                                     rng=self.rng, max_attempts=max_attempts, period=period)
        typ = np.broadcast_to(np.asarray(types), (n,))[ok]
        self.add_particles(pos, radii[ok], types=typ,
                           velocities=np.tile(_vec3("velocity", velocity), (len(pos), 1)))
        if len(pos) < n:
            log.info("raindrop insertion placed %d of %d spheres (region full)", len(pos), n)
        return np.asarray(ok, dtype=bool)

    def insert_frame(self, frame: Frame, *, offset=(0.0, 0.0, 0.0), keep_ids: bool = False,
                     types=None) -> None:
        """Insert the spheres of a saved pile (a :class:`~bedstruct.Frame` in SI units).

        Velocities and angular velocities of the frame are kept when present.
        New ids are assigned unless ``keep_ids``.
        """
        frame = frame.to_si()
        pos = frame.positions + _vec3("offset", offset)
        typ = frame.types if types is None else types
        self.add_particles(pos, frame.radii, types=typ, velocities=frame.velocities,
                           omegas=frame.omegas, ids=frame.ids if keep_ids else None)
