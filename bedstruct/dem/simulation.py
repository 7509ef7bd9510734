"""The DEM orchestrator: validates input, owns the state arrays, calls the kernels.

A :class:`Simulation` holds particles (structure-of-arrays, SI units), walls,
a :class:`~bedstruct.dem.ContactModel` and the neighbour list. Each step makes
two passes over particles and one over the compacted pair list (see
docs/engine.md); the neighbour list is rebuilt when a particle has moved by
more than half the skin since the last build.
"""

from __future__ import annotations

import json
import logging
import math
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import _numba
from .._atomic import atomic_path
from ..core import Box, Contacts, Frame, WallContacts
from ..errors import ConfigError, UnsafeTimestepError
from . import _kernels as K
from .insertion import raindrop_positions, sample_radii
from .params import ContactModel, Material
from .walls import TriangleMesh

__all__ = ["Simulation", "RunStats", "WallState"]

log = logging.getLogger(__name__)

_WALL_SLOTS = 3
_CHECKPOINT_VERSION = 1


@dataclass(frozen=True)
class RunStats:
    """What one :meth:`Simulation.run` call did.

    Attributes
    ----------
    n_steps : int
    wall_time : float, s
        Time in the stepping loop (excluding the first-call compilation only
        when the kernels were already compiled).
    particle_steps_per_s : float
    n_rebuilds : int
        Neighbour-list rebuilds during the run.
    n_removed : int
        Particles removed for leaving the domain during the run.
    """

    n_steps: int
    wall_time: float
    particle_steps_per_s: float
    n_rebuilds: int
    n_removed: int


@dataclass(frozen=True)
class WallState:
    """Position and load of one wall at the current time.

    ``origin`` (m) is the wall's reference point (plane point, plate or
    prism origin, roller axis point), ``velocity`` (m/s), ``force`` (N) the
    total force the particles exert on the wall, ``n_contacts`` the number
    of particles touching it.
    """

    name: str
    origin: np.ndarray
    velocity: np.ndarray
    force: np.ndarray
    n_contacts: int


def _vec3(name, v):
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"`{name}` must be a finite 3-vector; got {v!r}")
    return a


class Simulation:
    """An embedded DEM simulation of polydisperse spheres (SI units).

    Parameters
    ----------
    box : Box or box-like
        Domain (m). Periodic axes wrap; particles leaving a non-periodic
        face are removed and counted (:attr:`n_removed`). Default boundary
        of a plain ``[lo, hi]`` box is ``pp pp ff``.
    model : ContactModel
        Materials and contact coefficients.
    walls : sequence of walls, optional
        :class:`~bedstruct.dem.Plane`, :class:`~bedstruct.dem.Rectangle`,
        :class:`~bedstruct.dem.Prism` (:func:`~bedstruct.dem.Blade`),
        :class:`~bedstruct.dem.Cylinder`, :class:`~bedstruct.dem.TriangleMesh`.
    gravity : (3,) array_like, m/s^2
        Default ``(0, 0, -9.81)``.
    dt : float, s, optional
        Time step; default ``safety`` times the Rayleigh time of the
        smallest particle present when the first run starts (or
        ``min_radius``).
    safety : float
        Fraction of the Rayleigh time used for the default step (0.15).
    max_rayleigh_fraction : float
        A step above this fraction of the Rayleigh time (0.3), or above a
        tenth of the Hertz impact time at ``v_max``, is refused with
        :class:`~bedstruct.UnsafeTimestepError` unless ``force=True``.
    v_max : float, m/s
        Largest expected impact speed, for the Hertz-time check (1 m/s).
    min_radius : float, m, optional
        Smallest radius to plan the time step and skin for (default: the
        smallest radius present at the first run).
    skin : float, m, optional
        Neighbour-list skin (default 0.15 d_min).
    force : bool
        Accept an unsafe time step (a warning is logged).
    n_threads : int, optional
        Number of threads (and force-buffer chunks); default all of numba's.
        Results are bitwise reproducible for a given seed and n_threads.
        Systems of fewer than ``serial_below`` (5000) particles run the same
        chunks on one thread (identical results, less overhead).
    seed : int, optional
        Seed of the generator used by insertion.

    Examples
    --------
    >>> from bedstruct.dem import Simulation, ContactModel, Material, Plane
    >>> model = ContactModel(Material(1e7, 0.3, 2500.0), restitution=0.9, friction=0.5)
    >>> sim = Simulation(Box([0, 0, 0], [1e-3, 1e-3, 2e-3], boundary="ff ff ff"), model,
    ...                  walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")], n_threads=1)
    >>> sim.add_particles([[5e-4, 5e-4, 1e-4]], [1e-4])
    >>> stats = sim.run(200)
    >>> sim.n_particles, stats.n_steps
    (1, 200)
    """

    def __init__(self, box, model: ContactModel, *, walls=(), gravity=(0.0, 0.0, -9.81),
                 dt: float | None = None, safety: float = 0.15, max_rayleigh_fraction: float = 0.3,
                 v_max: float = 1.0, min_radius: float | None = None, skin: float | None = None,
                 force: bool = False, n_threads: int | None = None, seed=None):
        if not isinstance(model, ContactModel):
            raise TypeError(f"`model` must be a ContactModel; got {type(model).__name__}")
        if isinstance(box, Box):
            self.box = box
        else:
            arr = np.asarray(box, dtype=np.float64)
            self.box = (Box(arr[0], arr[1], boundary="pp pp ff") if arr.shape == (2, 3)
                        else Box.from_box(box))
        if self.box.is_triclinic:
            raise ConfigError("the DEM engine needs an orthogonal box (no tilt)")
        self.model = model
        self.gravity = _vec3("gravity", gravity)
        self._dt_user = dt
        self.safety = float(safety)
        self.max_rayleigh_fraction = float(max_rayleigh_fraction)
        self.v_max = float(v_max)
        self.min_radius = min_radius
        self._skin_user = skin
        self.force = bool(force)
        self.n_threads = int(n_threads or _numba.get_num_threads())
        self.serial_below = 5000
        if self.n_threads < 1:
            raise ConfigError(f"`n_threads` must be >= 1; got {n_threads}")
        self.rng = np.random.default_rng(seed)
        self.seed = seed
        self.time = 0.0
        self.step = 0
        self.n_removed = 0
        self.n_rebuilds = 0
        self.wall_overflow = 0
        self.dt = None
        self.skin = None
        self._ready = False
        self._next_id = 1
        tabs = model.tables()
        self._tabs = tuple(np.ascontiguousarray(a) for a in
                           (tabs.youngs, tabs.shear, tabs.beta, tabs.friction,
                            tabs.rolling_friction, tabs.cohesion))
        Y, G, B = self._tabs[:3]
        self._cap, self._age = model.extension_arrays()
        self._programs = {}
        self._gn_coef = np.ascontiguousarray(-2.0 * math.sqrt(5.0 / 6.0) * B * np.sqrt(2.0 * Y))
        self._gt_ratio = np.ascontiguousarray(np.sqrt(4.0 * G / Y) if model.tangential_damping
                                              else np.zeros_like(Y))
        self._L = np.ascontiguousarray(self.box.lengths, dtype=np.float64)
        self._lo = np.ascontiguousarray(self.box.lo, dtype=np.float64)
        self._hi = np.ascontiguousarray(self.box.hi, dtype=np.float64)
        self._periodic = np.array(self.box.periodic, dtype=np.bool_)
        self._set_walls(list(walls))
        self._alloc_particles(0)
        self._alloc_pairs(0)

    # ------------------------------------------------------------ allocation
    def _set_walls(self, walls):
        names = [w.name for w in walls]
        if len(set(names)) != len(names):
            raise ConfigError(f"wall names must be unique; got {names}")
        self.walls = walls
        self.wall_names = names
        rows = []
        tris = []
        ntri = 0
        for w in walls:
            r = w.row()
            if isinstance(w, TriangleMesh):
                t = np.asarray(w.triangles, dtype=np.float64).reshape(-1, 9)
                r[14] = ntri
                r[15] = ntri + len(t)
                ntri += len(t)
                tris.append(t)
            rows.append(r)
        self._W = np.ascontiguousarray(np.array(rows).reshape(len(rows), K.WALL_NCOL))
        self._tri = np.ascontiguousarray(np.concatenate(tris) if tris else np.zeros((0, 9)))

    def _alloc_particles(self, n):
        z3 = lambda: np.zeros((n, 3))  # noqa: E731
        self.x, self.v, self.om, self.f, self.tq = z3(), z3(), z3(), z3(), z3()
        self.rad = np.zeros(n)
        self.mass = np.zeros(n)
        self.inv_m = np.zeros(n)
        self.inv_i = np.zeros(n)
        self.ptype = np.zeros(n, dtype=np.int32)
        self.ids = np.zeros(n, dtype=np.int64)
        self.images = np.zeros((n, 3), dtype=np.int64)
        self.x_ref = z3()
        self.wslot = -np.ones((n, _WALL_SLOTS), dtype=np.int32)
        self.whist = np.zeros((n, _WALL_SLOTS, 6))

    def _alloc_pairs(self, m):
        self.pi = np.zeros(m, dtype=np.int32)
        self.pj = np.zeros(m, dtype=np.int32)
        self.psh = np.zeros((m, 3), dtype=np.int8)
        self.ht = np.zeros((m, 3))
        self.hr = np.zeros((m, 3))
        self.hx = np.zeros((m if self.model.contact_ageing else 0, 3))  # ageing history

    @property
    def n_particles(self) -> int:
        """Number of particles now in the domain."""
        return int(self.x.shape[0])

    @property
    def n_pairs(self) -> int:
        """Number of pairs in the neighbour list (touching or within the skin)."""
        return int(self.pi.shape[0])

    # -------------------------------------------------------------- particles
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
            Unique positive ids (default: continuing from the largest id).
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
            ``(lo, hi)`` corners; default the whole box. On periodic axes the
            region is kept one largest diameter inside the upper face.
        types : int or (n,) array
        velocity : (3,) array_like, m/s

        Returns
        -------
        int
            Number actually inserted (fewer when the region is full).
        """
        radii = sample_radii(n, psd, rng=self.rng)
        lo, hi = (self._lo.copy(), self._hi.copy()) if region is None else (
            np.array(region[0], dtype=float), np.array(region[1], dtype=float))
        for a in range(3):
            if self._periodic[a] and hi[a] > self._hi[a] - 2 * radii.max():
                hi[a] = self._hi[a] - 2 * radii.max()
        pos, ok = raindrop_positions(lo, hi, radii, existing=self.x, existing_radii=self.rad,
                                     rng=self.rng, max_attempts=max_attempts)
        typ = np.broadcast_to(np.asarray(types), (n,))[ok]
        self.add_particles(pos, radii[ok], types=typ,
                           velocities=np.tile(_vec3("velocity", velocity), (len(pos), 1)))
        if len(pos) < n:
            log.info("raindrop insertion placed %d of %d spheres (region full)", len(pos), n)
        return int(len(pos))

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

    # -------------------------------------------------------------- walls
    def set_wall_motion(self, name: str, *, velocity=None, omega=None) -> None:
        """Change a wall's translation velocity (m/s) or a roller's spin (rad/s) from now on."""
        try:
            w = self.wall_names.index(name)
        except ValueError:
            raise ConfigError(f"no wall named {name!r}; walls: {self.wall_names}") from None
        self._programs.pop(name, None)
        row = self._W[w]
        dt0 = self.time - row[13]
        row[1:4] = row[1:4] + row[10:13] * dt0
        row[13] = self.time
        if velocity is not None:
            row[10:13] = _vec3("velocity", velocity)
        if omega is not None:
            if int(row[0]) != K.WALL_CYLINDER:
                raise ConfigError(f"wall {name!r} is not a Cylinder; only rollers spin")
            row[16] = float(omega)
        if self._ready:
            self._build_wall_list()

    def set_wall_program(self, name: str, *, velocity, ramp_time: float = 0.0,
                         vibration_amplitude: float = 0.0, vibration_frequency: float = 0.0,
                         vibration_direction=(0.0, 0.0, 1.0)) -> None:
        """Prescribe a wall's translation from now on: start-up ramp plus vibration.

        With ``s`` the time since this call, ``tau`` the ramp time, ``A`` the
        amplitude, ``f`` the frequency and **d** the unit vibration direction::

            x(s) = x(0) + v [s - tau (1 - exp(-s/tau))] + A sin(2 pi f s) d
            u(s) = v (1 - exp(-s/tau)) + 2 pi f A cos(2 pi f s) d

        (``tau = 0``: ``x = x(0) + v s``). The wall row is updated every step
        (position and velocity exact at the time the walls are evaluated).
        :meth:`set_wall_motion` on the same wall ends the program.

        Parameters
        ----------
        name : str
            Wall name.
        velocity : (3,) float, m/s
            Steady translation velocity v.
        ramp_time : float, s
            Start-up time constant tau (>= 0).
        vibration_amplitude : float, m
            Vibration amplitude A (>= 0).
        vibration_frequency : float, Hz
            Vibration frequency f (>= 0).
        vibration_direction : (3,) float
            Direction of the vibration (normalised here).
        """
        try:
            w = self.wall_names.index(name)
        except ValueError:
            raise ConfigError(f"no wall named {name!r}; walls: {self.wall_names}") from None
        for key, val in (("ramp_time", ramp_time), ("vibration_amplitude", vibration_amplitude),
                         ("vibration_frequency", vibration_frequency)):
            if not (math.isfinite(float(val)) and float(val) >= 0.0):
                raise ConfigError(f"`{key}` must be a number >= 0; got {val!r}")
        d = _vec3("vibration_direction", vibration_direction)
        nd = float(np.linalg.norm(d))
        if nd == 0.0:
            raise ConfigError("`vibration_direction` must be a non-zero vector")
        row = self._W[w]
        origin = row[1:4] + row[10:13] * (self.time - row[13])
        self._programs[name] = dict(t0=float(self.time), origin=origin.tolist(),
                                    velocity=_vec3("velocity", velocity).tolist(),
                                    ramp_time=float(ramp_time),
                                    amplitude=float(vibration_amplitude),
                                    frequency=float(vibration_frequency),
                                    direction=(d / nd).tolist())
        self._apply_programs(self.time)
        if self._ready:
            self._build_wall_list()

    @staticmethod
    def wall_program_state(program: dict, time: float):
        """Position and velocity of a programmed wall at ``time`` (see :meth:`set_wall_program`)."""
        s = time - program["t0"]
        v = np.asarray(program["velocity"])
        tau = program["ramp_time"]
        if tau > 0.0:
            e = math.exp(-s / tau)
            x = np.asarray(program["origin"]) + v * (s - tau * (1.0 - e))
            u = v * (1.0 - e)
        else:
            x = np.asarray(program["origin"]) + v * s
            u = v.copy()
        amp = program["amplitude"]
        if amp > 0.0:
            om = 2.0 * math.pi * program["frequency"]
            d = np.asarray(program["direction"])
            x = x + amp * math.sin(om * s) * d
            u = u + amp * om * math.cos(om * s) * d
        return x, u

    def _apply_programs(self, time):
        for name, prog in self._programs.items():
            row = self._W[self.wall_names.index(name)]
            x, u = self.wall_program_state(prog, time)
            row[1:4] = x
            row[10:13] = u
            row[13] = time

    def wall_states(self) -> list[WallState]:
        """Position, velocity and particle load of every wall now."""
        out = []
        wb = getattr(self, "_wbuf", None)
        for w, name in enumerate(self.wall_names):
            row = self._W[w]
            origin = row[1:4] + row[10:13] * (self.time - row[13])
            if wb is not None and wb.shape[1] == len(self.wall_names):
                tot = wb[:, w, :].sum(axis=0)
            else:
                tot = np.zeros(6)
            out.append(WallState(name, origin, row[10:13].copy(), tot[:3].copy(), int(tot[4])))
        return out

    # ------------------------------------------------------------- time step
    def rayleigh_time(self) -> float:
        """Rayleigh time (s) of the smallest particle (or ``min_radius``)."""
        return self.model.rayleigh_time(self._rmin())

    def _rmin(self) -> float:
        if self.min_radius is not None:
            return float(self.min_radius)
        if self.n_particles == 0:
            raise ConfigError("no particles: give `min_radius` or add particles before running")
        return float(self.rad.min())

    def _choose_dt(self):
        rmin = self._rmin()
        t_r = self.model.rayleigh_time(rmin)
        t_h = self.model.hertz_time(rmin, self.v_max)
        if self._dt_user is None:
            dt = min(self.safety * t_r, 0.1 * t_h)
        else:
            dt = float(self._dt_user)
            if not dt > 0:
                raise ConfigError(f"`dt` must be positive; got {dt}")
            reasons = []
            if dt > self.max_rayleigh_fraction * t_r:
                reasons.append(f"dt = {dt:.3g} s is {dt / t_r:.0%} of the Rayleigh time "
                               f"{t_r:.3g} s of the smallest sphere (r = {rmin:.3g} m); the limit "
                               f"is {self.max_rayleigh_fraction:.0%}")
            if dt > 0.1 * t_h:
                reasons.append(f"dt = {dt:.3g} s exceeds 10% of the Hertz impact time "
                               f"{t_h:.3g} s at v_max = {self.v_max} m/s (a collision would span "
                               f"fewer than 10 steps)")
            if reasons:
                msg = "unsafe time step: " + "; ".join(reasons) + \
                      ". Use a smaller dt, a softer Young's modulus, or force=True."
                if not self.force:
                    raise UnsafeTimestepError(msg)
                log.warning("%s (accepted because force=True)", msg)
        self.dt = dt
        if self._skin_user is not None:
            self.skin = float(self._skin_user)
        else:
            self.skin = 0.15 * 2.0 * rmin
        self.t_rayleigh = t_r
        self.t_hertz = t_h

    # ------------------------------------------------------- neighbour list
    def _cell_grid(self):
        rmax = float(self.rad.max(initial=0.0))
        cut = 2.0 * rmax + self.skin + self._extra_cutoff()
        nc = np.maximum(1, np.floor(self._L / cut)).astype(np.int64)
        for a in range(3):
            if self._periodic[a] and nc[a] < 3:
                raise ConfigError(f"periodic box length along {'xyz'[a]} ({self._L[a]:.3g} m) must "
                                  f"be at least 3 neighbour cutoffs (3 x {cut:.3g} m)")
            # limit the number of cells for very sparse systems
        while np.prod(nc) > max(8 * self.n_particles, 1000):
            nc = np.maximum(1, nc // 2)
            for a in range(3):
                if self._periodic[a] and nc[a] < 3:
                    nc[a] = 3
        return nc, self._L / nc

    def _extra_cutoff(self) -> float:
        """Neighbour cutoff beyond contact: the largest capillary rupture distance (m)."""
        if not self.model.capillary or self.rad.size == 0:
            return 0.0
        return float(self.model.rupture_distance(0.5 * float(self.rad.max())))

    def _chunks(self, n):
        return np.linspace(0, n, self.n_threads + 1).astype(np.int64)

    def _rebuild(self):
        self.n_rebuilds += 1
        # 1. wrap periodic axes, remove particles outside fixed faces
        for a in range(3):
            if self._periodic[a]:
                k = np.floor((self.x[:, a] - self._lo[a]) / self._L[a]).astype(np.int64)
                if np.any(k):
                    self.x[:, a] -= k * self._L[a]
                    self.images[:, a] += k
        out = np.zeros(self.n_particles, dtype=bool)
        for a in range(3):
            if not self._periodic[a]:
                out |= (self.x[:, a] < self._lo[a]) | (self.x[:, a] >= self._hi[a])
        if not np.all(np.isfinite(self.x)):
            bad = ~np.all(np.isfinite(self.x), axis=1)
            log.warning("%d particles with non-finite positions removed", int(bad.sum()))
            out |= bad
        # keep old list (for history) keyed by ids before permuting
        act = K.active_history(self.ht, self.hr)
        ext = self.model.extension_code
        if ext & 2:
            act = np.union1d(act, np.flatnonzero(np.any(self.hx != 0.0, axis=1)))
        old_keys = np.zeros(act.size, dtype=np.int64)
        old_sign = np.zeros(act.size)
        if act.size:
            kk = np.zeros(self.n_pairs, dtype=np.int64)
            ss = np.zeros(self.n_pairs)
            K.pair_keys(self.ids, self.pi, self.pj, self._chunks(self.n_pairs), kk, ss)
            old_keys = kk[act]
            old_sign = ss[act]
        old_ht = self.ht[act]
        old_hr = self.hr[act]
        old_hx = self.hx[act] if ext & 2 else self.hx
        n_out = int(out.sum())
        if n_out:
            self.n_removed += n_out
            log.info("removed %d particles that left the domain (total %d)", n_out, self.n_removed)
        keep = np.flatnonzero(~out)
        # 2. sort by cell
        nc, cell_len = self._cell_grid()
        cells = np.zeros(keep.size, dtype=np.int64)
        xk = np.ascontiguousarray(self.x[keep])
        K.cell_indices(xk, self._lo, cell_len, nc, cells)
        perm, start = K.counting_sort(cells, int(np.prod(nc)))
        order = keep[perm]
        for name in ("x", "v", "om", "f", "tq", "rad", "mass", "inv_m", "inv_i", "ptype", "ids",
                     "images", "wslot", "whist"):
            setattr(self, name, np.ascontiguousarray(getattr(self, name)[order]))
        cells = np.ascontiguousarray(cells[perm])
        n = self.n_particles
        self.x_ref = self.x.copy()
        # 3. pair list: one pass into per-chunk room sized from the last list,
        #    two passes (count, fill) on the first build or when the room is short
        pb = self._chunks(n)
        T = self.n_threads
        skin_c = self.skin + self._extra_cutoff()
        none_i = np.zeros(0, dtype=np.int64)
        m_prev = getattr(self, "_m_hint", 0)
        done = False
        if m_prev and n:
            share = np.diff(pb).astype(np.float64) / n
            cap = (1.25 * m_prev * share + 64 + 8 * np.diff(pb)).astype(np.int64)
            off = np.zeros(T, dtype=np.int64)
            np.cumsum(cap[:-1], out=off[1:])
            tot = int(cap.sum())
            bi = np.empty(tot, dtype=np.int32)
            bj = np.empty(tot, dtype=np.int32)
            bs = np.empty((tot, 3), dtype=np.int8)
            cnt = np.zeros(T, dtype=np.int64)
            K.pair_build(self.x, self.rad, cells, start, nc, self._periodic, self._L,
                         K.HALF_STENCIL, skin_c, pb, none_i, 2, bi, bj, bs, off, cap, cnt)
            if np.all(cnt >= 0):
                sel = np.concatenate([np.arange(o, o + c) for o, c in zip(off, cnt)])
                self._alloc_pairs(0)
                self.pi, self.pj, self.psh = bi[sel], bj[sel], bs[sel]
                m = sel.size
                self.ht = np.zeros((m, 3))
                self.hr = np.zeros((m, 3))
                self.hx = np.zeros((m if self.model.contact_ageing else 0, 3))  # ageing history
                done = True
        if not done:
            counts = np.zeros(n, dtype=np.int64)
            dummy_i = np.zeros(0, dtype=np.int32)
            dummy_s = np.zeros((0, 3), dtype=np.int8)
            z = np.zeros(T, dtype=np.int64)
            K.pair_build(self.x, self.rad, cells, start, nc, self._periodic, self._L,
                         K.HALF_STENCIL, skin_c, pb, counts, 0, dummy_i, dummy_i, dummy_s,
                         z, z, z)
            offs = np.zeros(n, dtype=np.int64)
            if n:
                np.cumsum(counts[:-1], out=offs[1:])
            m = int(counts.sum())
            self._alloc_pairs(m)
            K.pair_build(self.x, self.rad, cells, start, nc, self._periodic, self._L,
                         K.HALF_STENCIL, skin_c, pb, offs, 1, self.pi, self.pj, self.psh,
                         z, z, z)
        self._m_hint = m
        # 4. history remap by sorted key
        if old_keys.size and m:
            o = np.argsort(old_keys, kind="stable")
            keys = np.zeros(m, dtype=np.int64)
            sign = np.zeros(m)
            qb = self._chunks(m)
            K.pair_keys(self.ids, self.pi, self.pj, qb, keys, sign)
            K.remap_history(keys, sign, np.ascontiguousarray(old_keys[o]),
                            np.ascontiguousarray(old_sign[o]), np.ascontiguousarray(old_ht[o]),
                            np.ascontiguousarray(old_hr[o]), qb, self.ht, self.hr)
            if ext & 2:
                ks = old_keys[o]
                idx = np.minimum(np.searchsorted(ks, keys), ks.size - 1)
                hit = ks[idx] == keys
                self.hx[hit] = old_hx[o][idx[hit]]
        self._alloc_buffers()
        self._build_wall_list()

    def _build_wall_list(self):
        """Candidate walls of each particle (closer than r + skin), built at the
        current time; rebuilt when a wall has moved skin/2 or at pair rebuilds."""
        n = self.n_particles
        self._wstart = np.zeros(n + 1, dtype=np.int64)
        empty = np.zeros(0, dtype=np.int64)
        K.wall_candidates(self.x, self.rad, self._W, self._tri, self.time, self.skin, False,
                          self._wstart, empty, self.wslot, self.whist)
        np.cumsum(self._wstart, out=self._wstart)
        self._wcand = np.zeros(int(self._wstart[-1]), dtype=np.int64)
        K.wall_candidates(self.x, self.rad, self._W, self._tri, self.time, self.skin, True,
                          self._wstart, self._wcand, self.wslot, self.whist)
        self._wall_list_time = self.time
        # fastest wall surface speed (translation plus roller rim speed), m/s
        W = self._W
        sp = np.sqrt((W[:, 10:13] ** 2).sum(axis=1)) if len(W) else np.zeros(0)
        self._wall_speed = float(sp.max(initial=0.0))
        for prog in self._programs.values():
            bound = (float(np.linalg.norm(prog["velocity"]))
                     + 2.0 * math.pi * prog["frequency"] * prog["amplitude"])
            self._wall_speed = max(self._wall_speed, bound)

    def _alloc_buffers(self):
        n = self.n_particles
        T = self.n_threads
        if getattr(self, "_fbuf", None) is None or self._fbuf.shape != (T, n, 3):
            self._fbuf = np.zeros((T, n, 3))
            self._tbuf = np.zeros((T, n, 3))
        nw = self._W.shape[0]
        if getattr(self, "_wbuf", None) is None or self._wbuf.shape != (T, nw, 6):
            self._wbuf = np.zeros((T, nw, 6))
        self._disp = np.zeros(T)
        self._overflow = np.zeros(T, dtype=np.int64)
        self._pbounds = self._chunks(n)
        self._qbounds = self._chunks(self.n_pairs)
        self._fn_out = np.zeros(0)
        self._ft_out = np.zeros((0, 3))
        self._wfn = np.zeros((0, _WALL_SLOTS))
        self._wdel = np.zeros((0, _WALL_SLOTS))
        self._wnrm = np.zeros((0, _WALL_SLOTS, 3))

    # ------------------------------------------------------------- stepping
    def _pair_pass(self, dt, ht, hr, fbuf, tbuf, store, fn_out, ft_out, hx=None):
        Y, G, B, MU, MUR, COH = self._tabs
        m = self.model
        ext = m.extension_code
        if ext == 0 and m.rolling_stiffness_factor == 2.25:
            K.pair_forces(self.x, self.v, self.om, self.rad, self.mass, self.inv_i, self.ptype,
                          self.pi, self.pj, self.psh, self._L, ht, hr, self._qbounds, fbuf, tbuf,
                          Y, G, self._gn_coef, self._gt_ratio, MU, MUR, COH, m.rolling_code,
                          m.limit_force, float(m.rolling_damping), dt, store, fn_out, ft_out)
        else:
            K.pair_forces_ext(self.x, self.v, self.om, self.rad, self.mass, self.inv_i,
                              self.ptype, self.pi, self.pj, self.psh, self._L, ht, hr,
                              self._qbounds, fbuf, tbuf, Y, G, self._gn_coef, self._gt_ratio, MU,
                              MUR, COH, m.rolling_code, m.limit_force, float(m.rolling_damping),
                              dt, store, fn_out, ft_out, ext, self.hx if hx is None else hx,
                              self._cap, self._age)

    def _finish_pass(self, dt, v, om, f, tq, fbuf, tbuf, wslot, whist, store, wfn, wdel, wnrm):
        Y, G, B, MU, MUR, COH = self._tabs
        m = self.model
        K.finish_step(self.x, v, om, f, tq, fbuf, tbuf, self.mass, self.inv_m, self.inv_i,
                      self.rad, self.ptype, self.gravity, self._pbounds, self._W, self._tri,
                      self.time, self._wstart, self._wcand, wslot, whist, self._wbuf, Y, G, B, MU, MUR, COH, m.rolling_code,
                      m.tangential_damping, m.limit_force, float(m.rolling_damping), dt, store,
                      wfn, wdel, wnrm, self._overflow, float(m.rolling_stiffness_factor))

    def _setup(self):
        if self.dt is None:
            self._choose_dt()
        self._rebuild()
        # forces at the current state without advancing (dt = 0 leaves history unchanged)
        self._pair_pass(0.0, self.ht, self.hr, self._fbuf, self._tbuf, False, self._fn_out,
                        self._ft_out)
        self._finish_pass(0.0, self.v, self.om, self.f, self.tq, self._fbuf, self._tbuf,
                          self.wslot, self.whist, False, self._wfn, self._wdel, self._wnrm)
        self._ready = True

    def _one_step(self):
        dt = self.dt
        K.kick_drift(self.x, self.v, self.om, self.f, self.tq, self.inv_m, self.inv_i, self.x_ref,
                     dt, self._pbounds, self._disp)
        if self._disp.max() > (0.5 * self.skin) ** 2:
            self._rebuild()
        elif self._wall_speed * (self.time + dt - self._wall_list_time) > 0.5 * self.skin:
            self.time += dt  # build the wall list at the time the walls are evaluated
            self._build_wall_list()
            self.time -= dt
        self._pair_pass(dt, self.ht, self.hr, self._fbuf, self._tbuf, False, self._fn_out,
                        self._ft_out)
        self.step += 1
        self.time = self.time + dt
        if self._programs:
            self._apply_programs(self.time)
        self._finish_pass(dt, self.v, self.om, self.f, self.tq, self._fbuf, self._tbuf,
                          self.wslot, self.whist, False, self._wfn, self._wdel, self._wnrm)

    def run(self, steps: int | None = None, *, time: float | None = None, progress: bool = False,
            dump_every: int | None = None, run_dir=None, checkpoint_every: int | None = None,
            callback=None) -> RunStats:
        """Advance the simulation.

        Parameters
        ----------
        steps : int, optional
            Number of steps; or give ``time``.
        time : float, s, optional
            Simulated time to advance (rounded up to whole steps).
        progress : bool
            Show a tqdm bar with simulated time and particle-steps per second.
        dump_every : int, optional
            Write a dump frame, a contact dump and the wall state every so
            many steps into ``run_dir`` (also at the end).
        run_dir : RunDirectory or path, optional
            Where output goes (created with the full configuration).
        checkpoint_every : int, optional
            Write ``checkpoint.npz`` into ``run_dir`` every so many steps.
        callback : callable, optional
            ``callback(sim)`` after every step (slow; for tests and control).

        Returns
        -------
        RunStats
        """
        from .output import RunDirectory
        if (steps is None) == (time is None):
            raise ConfigError("give exactly one of `steps` or `time`")
        if not self._ready:
            self._setup()
        nsteps = int(steps) if steps is not None else int(math.ceil(float(time) / self.dt - 1e-9))
        if nsteps < 0:
            raise ConfigError(f"number of steps must be >= 0; got {nsteps}")
        rd = None
        if run_dir is not None:
            rd = run_dir if isinstance(run_dir, RunDirectory) else RunDirectory(run_dir)
            rd.write_config(self)
        elif dump_every or checkpoint_every:
            raise ConfigError("`dump_every` and `checkpoint_every` need a `run_dir`")
        old_threads = _numba.get_num_threads()
        # the work is split into n_threads fixed chunks (so results depend only on
        # n_threads); small systems run those chunks on one thread, where thread
        # wake-up costs more than the work (ENGINE-NOTES point 10)
        actual = 1 if self.n_particles < self.serial_below else self.n_threads
        _numba.set_num_threads(min(actual, _numba_max_threads()))
        bar = None
        if progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=nsteps, unit="step")
        reb0, rem0 = self.n_rebuilds, self.n_removed
        psteps = 0
        t0 = _time.perf_counter()
        try:
            for s in range(nsteps):
                self._one_step()
                psteps += self.n_particles
                if callback is not None:
                    callback(self)
                if rd is not None and dump_every and self.step % dump_every == 0:
                    rd.write_output(self)
                if rd is not None and checkpoint_every and self.step % checkpoint_every == 0:
                    self.save_checkpoint(rd.path / "checkpoint.npz")
                if bar is not None and (s % 50 == 49 or s == nsteps - 1):
                    el = _time.perf_counter() - t0
                    bar.set_postfix_str(f"t={self.time:.4g} s, "
                                        f"{psteps / max(el, 1e-12) / 1e6:.2f} M p-steps/s")
                    bar.update(s + 1 - bar.n)
        finally:
            _numba.set_num_threads(old_threads)
            if bar is not None:
                bar.close()
        wall = _time.perf_counter() - t0
        if rd is not None and dump_every and self.step % dump_every != 0:
            rd.write_output(self)
        self.wall_overflow = int(self._overflow.sum())
        return RunStats(nsteps, wall, psteps / wall if wall > 0 else float("nan"),
                        self.n_rebuilds - reb0, self.n_removed - rem0)

    # ------------------------------------------------------------- output
    def _evaluate(self):
        """Pair and wall forces at the current state without changing it."""
        if not self._ready:
            self._setup()
        m = self.n_pairs
        n = self.n_particles
        T = self.n_threads
        fn = np.zeros(m)
        ft = np.zeros((m, 3))
        fb = np.zeros((T, n, 3))
        tb = np.zeros((T, n, 3))
        self._pair_pass(0.0, self.ht.copy(), self.hr.copy(), fb, tb, True, fn, ft, self.hx.copy())
        wfn = np.zeros((n, _WALL_SLOTS))
        wdel = np.zeros((n, _WALL_SLOTS))
        wnrm = np.zeros((n, _WALL_SLOTS, 3))
        wslot = self.wslot.copy()
        f = np.zeros((n, 3))
        tq = np.zeros((n, 3))
        wb = self._wbuf.copy()
        self._finish_pass(0.0, self.v.copy(), self.om.copy(), f, tq, fb, tb, wslot,
                          self.whist.copy(), True, wfn, wdel, wnrm)
        self._wbuf = wb
        return fn, ft, wslot, wfn, wdel, wnrm, f, tq

    def frame(self) -> Frame:
        """The current state as a :class:`~bedstruct.Frame` (SI, rows sorted by id).

        Carries velocities (m/s), omegas (rad/s), forces (N, total incl.
        gravity), image flags, and the columns ``mass`` (kg) and
        ``torque`` (N m, (N, 3)).
        """
        o = np.argsort(self.ids, kind="stable")
        x = self.x[o].copy()
        img = self.images[o].copy()
        # report positions wrapped into the box on periodic axes
        for a in range(3):
            if self._periodic[a]:
                k = np.floor((x[:, a] - self._lo[a]) / self._L[a]).astype(np.int64)
                x[:, a] -= k * self._L[a]
                img[:, a] += k
        return Frame(x, self.rad[o], box=self.box, timestep=self.step, ids=self.ids[o],
                     types=self.ptype[o] + 1, time=self.time, velocities=self.v[o],
                     omegas=self.om[o], forces=self.f[o], images=img,
                     columns={"mass": self.mass[o], "torque": self.tq[o]})

    def contacts(self) -> Contacts:
        """Touching pairs with their forces, indexed like :meth:`frame` (rows sorted by id).

        ``force_normal`` and ``force_tangential`` are the forces on ``i``
        (N); ``branch`` points from i to j (minimum image); the SJKR area of
        each contact is in ``area`` (m^2); ``walls`` holds the
        particle-wall contacts.
        """
        fn, ft, wslot, wfn, wdel, wnrm, _, _ = self._evaluate()
        o = np.argsort(self.ids, kind="stable")
        inv = np.empty_like(o)
        inv[o] = np.arange(o.size)
        d = self.x[self.pi] - self.x[self.pj] - self.psh * self._L
        r = np.sqrt(np.einsum("ij,ij->i", d, d))
        ri = self.rad[self.pi]
        rj = self.rad[self.pj]
        touch = r < ri + rj
        d, r, ri, rj = d[touch], r[touch], ri[touch], rj[touch]
        en = d / r[:, None]
        i = inv[self.pi[touch]]
        j = inv[self.pj[touch]]
        area = -np.pi / 4 * ((r - ri - rj) * (r + ri - rj) * (r - ri + rj) * (r + ri + rj)) / r ** 2
        wp, ws = np.nonzero(wslot >= 0)
        walls = WallContacts(particle=inv[wp], wall=wslot[wp, ws], normals=wnrm[wp, ws],
                             overlap=wdel[wp, ws], radii=self.rad[wp])
        return Contacts(i=i, j=j, branch=-d, radii_i=ri, radii_j=rj, ids_i=self.ids[self.pi[touch]],
                        ids_j=self.ids[self.pj[touch]], periodic=np.any(self.psh[touch] != 0, axis=1),
                        force_normal=fn[touch, None] * en, force_tangential=ft[touch], area=area,
                        n_particles=self.n_particles, source="bedstruct.dem", walls=walls)

    def kinetic_energy(self) -> float:
        """Translational plus rotational kinetic energy (J)."""
        et = 0.5 * np.sum(self.mass * np.einsum("ij,ij->i", self.v, self.v))
        er = 0.5 * np.sum(np.einsum("ij,ij->i", self.om, self.om) / self.inv_i)
        return float(et + er)

    def memory_bytes(self) -> tuple[int, int]:
        """Bytes held per particle and per pair-list entry (state, buffers, history)."""
        per_p = sum(getattr(self, a).nbytes for a in
                    ("x", "v", "om", "f", "tq", "rad", "mass", "inv_m", "inv_i", "ptype", "ids",
                     "images", "x_ref", "wslot", "whist"))
        per_p += self._fbuf.nbytes + self._tbuf.nbytes + self._wstart.nbytes + self._wcand.nbytes
        per_c = sum(getattr(self, a).nbytes for a in ("pi", "pj", "psh", "ht", "hr", "hx"))
        n = max(self.n_particles, 1)
        m = max(self.n_pairs, 1)
        return int(per_p / n), int(per_c / m)

    def config(self) -> dict:
        """The full configuration as JSON-ready data."""
        return {
            "engine": "bedstruct.dem", "units": "SI",
            "box": {"lo": self.box.lo.tolist(), "hi": self.box.hi.tolist(),
                    "boundary": list(self.box.boundary)},
            "model": self.model.to_dict(),
            "walls": [w.state() for w in self.walls],
            "gravity": self.gravity.tolist(), "dt": self.dt, "skin": self.skin,
            "safety": self.safety, "max_rayleigh_fraction": self.max_rayleigh_fraction,
            "v_max": self.v_max, "force": self.force, "n_threads": self.n_threads,
            "seed": self.seed if isinstance(self.seed, (int, type(None))) else str(self.seed),
            "n_particles": self.n_particles, "step": self.step, "time": self.time,
        }

    # ---------------------------------------------------------- checkpoints
    _STATE = ("x", "v", "om", "f", "tq", "rad", "mass", "inv_m", "inv_i", "ptype", "ids", "images",
              "x_ref", "wslot", "whist", "pi", "pj", "psh", "ht", "hr", "hx", "_W", "_tri",
              "_wstart", "_wcand")

    def save_checkpoint(self, path) -> Path:
        """Write the complete state (incl. contact history and rng) atomically to ``path`` (.npz)."""
        path = Path(path)
        if not self._ready:
            self._setup()
        arrays = {name.lstrip("_"): getattr(self, name) for name in self._STATE}
        meta = dict(version=_CHECKPOINT_VERSION, time=self.time, step=self.step, dt=self.dt,
                    skin=self.skin, n_removed=self.n_removed, n_rebuilds=self.n_rebuilds,
                    next_id=self._next_id, n_threads=self.n_threads, wall_names=self.wall_names,
                    rng=self.rng.bit_generator.state, config=self.config(),
                    t_rayleigh=self.t_rayleigh, t_hertz=self.t_hertz,
                    wall_list_time=self._wall_list_time, wall_speed=self._wall_speed,
                    wall_programs=self._programs)
        arrays["meta"] = np.array(json.dumps(meta, default=_json_default))
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
        return path

    @classmethod
    def from_checkpoint(cls, path, model: ContactModel | None = None, *, walls=None) -> "Simulation":
        """Resume from :meth:`save_checkpoint`; continuing gives the same result bit for bit.

        ``model`` defaults to the model recorded in the checkpoint; ``walls``
        (the wall objects, for the configuration record) default to the
        recorded wall table.
        """
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        meta = json.loads(str(data.pop("meta")))
        cfg = meta["config"]
        if model is None:
            model = _model_from_dict(cfg["model"])
        box = Box(cfg["box"]["lo"], cfg["box"]["hi"], boundary=cfg["box"]["boundary"])
        sim = cls(box, model, walls=(), gravity=cfg["gravity"], dt=meta["dt"], force=True,
                  skin=meta["skin"], n_threads=meta["n_threads"], v_max=cfg["v_max"],
                  safety=cfg["safety"], max_rayleigh_fraction=cfg["max_rayleigh_fraction"])
        sim.walls = list(walls) if walls is not None else []
        sim.wall_names = meta["wall_names"]
        for name in cls._STATE:
            if name == "hx" and "hx" not in data:  # checkpoints written before the extensions
                data["hx"] = np.zeros((data["pi"].shape[0], 3))
            setattr(sim, name, np.ascontiguousarray(data[name.lstrip("_")]))
        sim.dt = meta["dt"]
        sim.skin = meta["skin"]
        sim.t_rayleigh = meta["t_rayleigh"]
        sim.t_hertz = meta["t_hertz"]
        sim.time = meta["time"]
        sim.step = meta["step"]
        sim.n_removed = meta["n_removed"]
        sim.n_rebuilds = meta["n_rebuilds"]
        sim._next_id = meta["next_id"]
        sim.force = cfg["force"]
        sim.rng.bit_generator.state = meta["rng"]
        sim._wall_cfg = cfg["walls"]
        sim._alloc_buffers()
        sim._wall_list_time = meta["wall_list_time"]
        sim._wall_speed = meta["wall_speed"]
        sim._programs = dict(meta.get("wall_programs", {}))
        sim._ready = True
        return sim


def _numba_max_threads() -> int:
    import numba
    return int(numba.config.NUMBA_NUM_THREADS)


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    return str(o)


_EXTENSION_KEYS = ("capillary", "capillary_surface_tension", "capillary_contact_angle",
                   "capillary_film_thickness", "capillary_bridge_volume", "contact_ageing",
                   "ageing_bond_ratio", "ageing_time_constant", "ageing_reference_rest_time",
                   "ageing_break_slip", "rolling_stiffness_factor")


def _model_from_dict(d: dict) -> ContactModel:
    def mat(m):
        return None if m is None else Material(m["youngs_modulus"], m["poisson_ratio"], m["density"],
                                               name=m.get("name", ""))
    kw = {k: d[k] for k in ("restitution", "friction", "rolling_friction", "cohesion",
                            "rolling_model", "rolling_damping", "wall_restitution", "wall_friction",
                            "wall_rolling_friction", "wall_cohesion", "tangential_damping",
                            "limit_force")}
    kw.update({k: d[k] for k in _EXTENSION_KEYS if k in d})
    return ContactModel(tuple(mat(m) for m in d["materials"]), wall_material=mat(d["wall_material"]),
                        **kw)
