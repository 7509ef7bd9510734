"""The DEM orchestrator: validates input, owns the state arrays, calls the kernels.

A :class:`Simulation` holds particles (structure-of-arrays, SI units), walls,
a :class:`~bedstruct.dem.ContactModel` and the neighbour list. Each step makes
two passes over particles and one over the compacted pair list (see
docs/engine.md); the neighbour list is rebuilt when a particle has moved by
more than half the skin since the last build.
"""

from __future__ import annotations

import logging
import math
import os
import time as _time
from dataclasses import dataclass

import numpy as np

from .. import _numba
from ..core import Box
from ..errors import ConfigError
from . import _kernels as K
from ._sim_io import _StateIO
from ._sim_particles import _Particles
from ._sim_timestep import _TimeStep
from ._sim_neighbours import NumericalInstabilityError, _NeighbourList
from ._sim_walls import _WALL_SLOTS, WallState, _WallControl, _vec3
from .params import ContactModel
from .walls import TriangleMesh

__all__ = ["Simulation", "RunStats", "WallState", "NumericalInstabilityError"]

#: Steps between the checks for non-finite positions inside :meth:`Simulation.run`.
_FINITE_CHECK_EVERY = 64
#: No wall-load sum (the step loop's empty table).
_NO_WLOAD = np.zeros((0, 3))

log = logging.getLogger(__name__)


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
    n_lost_nonfinite : int
        Particles dropped for non-finite positions during the run (only with
        ``nonfinite="drop"``; the default raises).
    """

    n_steps: int
    wall_time: float
    particle_steps_per_s: float
    n_rebuilds: int
    n_removed: int
    n_lost_nonfinite: int = 0

class Simulation(_Particles, _WallControl, _NeighbourList, _StateIO, _TimeStep):
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
        Fraction of the Rayleigh time used for the default step (0.15); it must
        lie in ``(0, max_rayleigh_fraction]`` (a larger one raises
        :class:`~bedstruct.UnsafeTimestepError` unless ``force=True``).
    max_rayleigh_fraction : float
        A step above this fraction of the Rayleigh time (0.3), or above a
        tenth of the Hertz impact time at ``v_max``, is refused with
        :class:`~bedstruct.UnsafeTimestepError` unless ``force=True``.
    v_max : float, m/s
        Largest expected impact speed, for the Hertz-time check (1 m/s; > 0). A wall
        moving faster is checked at its own speed at each run start.
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
        chunks on one thread (identical results, less overhead). So does a
        run that starts while other processes keep the cores busy (with
        ``yield_when_busy``, the default): threads that wait for each other
        on a loaded machine run slower than one thread alone.
    seed : int, optional
        Seed of the generator used by insertion.
    nonfinite : {"raise", "drop"}
        What a particle with a non-finite position (a blow-up) does: raise
        :class:`NumericalInstabilityError` (default), or be dropped with a
        warning. Either way it is counted in :attr:`n_lost_nonfinite`, not in
        :attr:`n_removed`.

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
                 force: bool = False, n_threads: int | None = None, seed=None,
                 nonfinite: str = "raise"):
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
        self._check_time_settings()
        if nonfinite not in ("raise", "drop"):
            raise ConfigError(f"`nonfinite` must be 'raise' or 'drop'; got {nonfinite!r}")
        self.nonfinite = nonfinite
        self.n_lost_nonfinite = 0
        self._rebuild_due = False
        self.checkpoint_extra = {}     # what from_checkpoint read besides the state
        self._resume_outputs = None
        self._ready = False
        self.n_threads = n_threads or _numba.get_num_threads()
        self.serial_below = 5000
        self.yield_when_busy = True
        # True: the pair pass in gather-compute-scatter blocks where no extension is on
        # (vectorised contact law, the single loop's bits; docs/engine.md)
        self.blocked_pairs = True
        # True: run() makes the steps between two looks at the state in one numba loop
        # (the same kernel calls as _one_step, bit for bit; docs/engine.md)
        self.fused_loop = True
        self.rng = np.random.default_rng(seed)
        self.seed = seed
        self.time = 0.0
        self.step = 0
        self.n_removed = 0
        self.n_rebuilds = 0
        self.wall_overflow = 0
        self.dt = None
        self.skin = None
        self._kicked = False  # True between fused steps inside run() only
        self._f_half_step = False  # self.f from a step (at its half-step velocities)
        self._next_id = 1
        tabs = model.tables()
        self._tabs = tuple(np.ascontiguousarray(a) for a in
                           (tabs.youngs, tabs.shear, tabs.beta, tabs.friction,
                            tabs.rolling_friction, tabs.cohesion))
        self._pair_tab = K.pair_table(*self._tabs, model.tangential_damping)
        self._wall_tab = np.ascontiguousarray(np.stack(self._tabs))
        self._cap, self._age = model.extension_arrays()
        # the EPSD stiffness factor is compiled in unless it differs from the standard one
        self._kr_fac = (float(model.rolling_stiffness_factor)
                        if model.rolling_model == "epsd"
                        and model.rolling_stiffness_factor != K.EPSD_STIFFNESS_FACTOR else None)
        self._programs = {}
        self._wload = None    # (n_walls, 3) running sum of wall loads, or None (not averaging)
        self._wload_steps = 0
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
    def n_threads(self) -> int:
        """Number of chunks the work is split into, one per thread (results depend on it).

        Setting it on a simulation that has run re-chunks the work at once (a neighbour
        rebuild), so that every per-chunk buffer matches."""
        return self._n_threads

    @n_threads.setter
    def n_threads(self, value: int) -> None:
        value = int(value)
        if value < 1:
            raise ConfigError(f"`n_threads` must be >= 1; got {value}")
        changed = value != getattr(self, "_n_threads", None)
        self._n_threads = value
        if changed and self._ready:
            self._rebuild()

    @property
    def n_pairs(self) -> int:
        """Number of pairs in the neighbour list (touching or within the skin)."""
        return int(self.pi.shape[0])

    # ------------------------------------------------------------- stepping
    def _pair_call(self, dt, ht, hr, fbuf, tbuf, store, fn_out, ft_out, hx=None):
        """The pair pass as ``(variant, args)``: ``K.PAIR_PASSES[variant](*args)`` runs it."""
        m = self.model
        # an extension that is off is passed as None and compiled out of the kernel
        return K.pair_pass_call(
            (self.x, self.v, self.om, self.rad, self.mass, self.inv_i, self.ptype),
            (self.pi, self.pj, self.psh), self._L, (ht, hr), self._qbounds, fbuf, tbuf,
            self._pair_tab, m.rolling_code, m.limit_force, float(m.rolling_damping), dt, store,
            fn_out, ft_out, self._cap if m.capillary else None,
            (self.hx if hx is None else hx, self._age) if m.contact_ageing else None,
            self._kr_fac, blocked=self.blocked_pairs)

    def _pair_pass(self, dt, ht, hr, fbuf, tbuf, store, fn_out, ft_out, hx=None):
        variant, args = self._pair_call(dt, ht, hr, fbuf, tbuf, store, fn_out, ft_out, hx)
        K.PAIR_PASSES[variant](*args)

    def _finish_pass(self, dt, v, om, f, tq, fbuf, tbuf, wslot, whist, store, wfn, wdel, wnrm,
                     kick_next=False):
        m = self.model
        K.finish_step((self.x, v, om, f, tq, self.mass, self.inv_m, self.inv_i, self.rad,
                       self.ptype), fbuf, tbuf, self.gravity, self._fbounds,
                      (self._W, self._tri, self.time, self._wstart, self._wcand, wslot, whist,
                       self._wbuf), self._wall_tab, m.rolling_code, m.tangential_damping,
                      m.limit_force, float(m.rolling_damping), dt, store, (wfn, wdel, wnrm),
                      self._overflow, kick_next, self.x_ref, self._disp,
                      float(m.rolling_stiffness_factor))

    def _setup(self):
        if self.dt is None:
            self._choose_dt()
        self._check_dt_present()
        self._rebuild()
        # forces at the current state without advancing (dt = 0 leaves history unchanged)
        self._pair_pass(0.0, self.ht, self.hr, self._fbuf, self._tbuf, False, self._fn_out,
                        self._ft_out)
        self._finish_pass(0.0, self.v, self.om, self.f, self.tq, self._fbuf, self._tbuf,
                          self.wslot, self.whist, False, self._wfn, self._wdel, self._wnrm)
        self._f_half_step = False
        self._ready = True

    def _one_step(self, kick_next: bool = False):
        """One velocity-Verlet step. With ``kick_next`` the step ends with the next
        step's half kick and drift already done (fused into the integrator's second
        pass; the state is then mid-step until the next call, which skips them)."""
        dt = self.dt
        if not self._kicked:
            K.kick_drift(self.x, self.v, self.om, self.f, self.tq, self.inv_m, self.inv_i,
                         self.x_ref, dt, self._pbounds, self._disp)
        self._kicked = False
        if self._rebuild_due or self._disp.max() > (0.5 * self.skin) ** 2:
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
                          self.wslot, self.whist, False, self._wfn, self._wdel, self._wnrm,
                          kick_next)
        self._kicked = kick_next
        self._f_half_step = True

    def _run_fused(self, nmax: int, fuse_last: bool) -> int:
        """Up to ``nmax`` steps of :meth:`_one_step` in the numba step loop
        (:func:`~bedstruct.dem._kernels_run.run_steps`), the last fused with the next
        step's first pass when ``fuse_last``; returns the number done. It stops early,
        with the next step's drift done, where that step needs a rebuild or a new wall
        list (:meth:`_one_step` then makes it)."""
        m = self.model
        dt = self.dt
        variant, args = self._pair_call(dt, self.ht, self.hr, self._fbuf, self._tbuf, False,
                                       self._fn_out, self._ft_out)
        prog = self._program_table()
        wload = self._wload if self._wload is not None else _NO_WLOAD
        done, time, kicked = K.run_steps(
            nmax, fuse_last,
            (self._kicked, self.time, dt, (0.5 * self.skin) ** 2, 0.5 * self.skin,
             self._wall_speed, self._wall_list_time),
            (self.x, self.v, self.om, self.f, self.tq, self.inv_m, self.inv_i, self._pbounds),
            variant, args,
            ((self.x, self.v, self.om, self.f, self.tq, self.mass, self.inv_m, self.inv_i,
              self.rad, self.ptype), self._fbuf, self._tbuf, self.gravity, self._fbounds,
             (self._W, self._tri, self._wstart, self._wcand, self.wslot, self.whist, self._wbuf),
             self._wall_tab, m.rolling_code, m.tangential_damping, m.limit_force,
             float(m.rolling_damping), (self._wfn, self._wdel, self._wnrm), self._overflow,
             self.x_ref, self._disp, float(m.rolling_stiffness_factor)), prog, wload)
        self.step += done
        self.time = time
        self._kicked = kicked
        if done:
            self._f_half_step = True
        if self._wload is not None:
            self._wload_steps += done
        return done

    def age_contacts(self, seconds: float) -> int:
        """Let the packing rest for ``seconds`` without simulating the rest.

        With contact ageing (``ContactModel(contact_ageing=True)``) every touching
        contact whose bond has not broken grows older by ``seconds``; its bond then
        holds ``r F_sjkr ln(1 + t_w/tau) / ln(1 + t_ref/tau)`` at the new rest
        time ``t_w``. For a packing at rest this is what simulating the rest would
        give (nothing slides, so no bond breaks and no contact opens or closes)
        at no cost, where a rest of minutes would take ~1e8 time steps. Positions,
        velocities and the clock are unchanged; without contact ageing nothing is.

        Parameters
        ----------
        seconds : float, s
            Rest time, >= 0.

        Returns
        -------
        int
            Number of contacts aged.

        Examples
        --------
        >>> from bedstruct import Box
        >>> from bedstruct.dem import ContactModel, Material, Simulation
        >>> model = ContactModel(Material(1e7, 0.3, 2500.0), cohesion=1e5, contact_ageing=True,
        ...                      ageing_bond_ratio=1.0)
        >>> sim = Simulation(Box([0, 0, 0], [2e-3] * 3), model, gravity=(0, 0, 0), n_threads=1)
        >>> sim.add_particles([[0.9e-3, 1e-3, 1e-3], [1.0999e-3, 1e-3, 1e-3]], [1e-4, 1e-4])
        >>> sim.age_contacts(600.0)
        1
        >>> float(sim.hx[0, 0])
        600.0
        """
        t = float(seconds)
        if not (math.isfinite(t) and t >= 0.0):
            raise ConfigError(f"age_contacts: rest time must be finite and >= 0; got {seconds!r}")
        if not self._ready:
            self._setup()
        if not self.model.contact_ageing or self.n_pairs == 0 or t == 0.0:
            return 0
        d = self.x[self.pi] - self.x[self.pj] - self.psh * self._L
        rs = self.rad[self.pi] + self.rad[self.pj]
        touching = (np.einsum("ij,ij->i", d, d) < rs * rs) & (self.hx[:, 2] == 0.0)
        self.hx[touching, 0] += t
        return int(touching.sum())

    def steps_for(self, time: float) -> int:
        """Number of steps :meth:`run` makes for ``time`` seconds (rounded up to whole steps).

        Sets the time step up first (as the first :meth:`run` does) when it is not yet chosen.
        """
        if not self._ready:
            self._setup()
        return int(math.ceil(float(time) / self.dt - 1e-9))

    def _check_finite(self) -> None:
        """Non-finite positions (a blow-up) are handled at once (:meth:`_lost_nonfinite`):
        the displacement test that triggers rebuilds never sees NaN."""
        if np.isfinite(self.x).all():
            return
        if self.nonfinite == "raise":
            self._lost_nonfinite(int((~np.isfinite(self.x).all(axis=1)).sum()))
        self._rebuild_due = True  # the next step's rebuild drops them

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
            Where output goes (created with the full configuration). The first
            run of a simulation resumed from ``run_dir``'s checkpoint
            (:meth:`from_checkpoint`) cuts that folder's dumps back to what they
            held when the checkpoint was written, so a resumed run's output
            equals an uninterrupted one's.
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
        self._check_wall_speed()
        nsteps = int(steps) if steps is not None else self.steps_for(time)
        if nsteps < 0:
            raise ConfigError(f"number of steps must be >= 0; got {nsteps}")
        rd = None
        if run_dir is not None:
            rd = run_dir if isinstance(run_dir, RunDirectory) else RunDirectory(run_dir)
            resumed = getattr(self, "_resume_outputs", None)
            if resumed is not None:  # first run after from_checkpoint: drop output past it
                self._resume_outputs = None
                if resumed.get("run_dir") == str(rd.path.resolve()):
                    rd.truncate(resumed.get("sizes", {}))
            rd.write_config(self)
        elif dump_every or checkpoint_every:
            raise ConfigError("`dump_every` and `checkpoint_every` need a `run_dir`")
        old_threads = _numba.get_num_threads()
        # the work is split into n_threads fixed chunks (so results depend only on
        # n_threads); small systems run those chunks on one thread, where thread
        # wake-up costs more than the work (ENGINE-NOTES point 10)
        actual = 1 if self.n_particles < self.serial_below else self.n_threads
        actual = min(actual, _numba_max_threads())
        if actual > 1 and self.yield_when_busy and _cores_busy(actual):
            log.info("other processes keep the cores busy: this run's %d chunks run on one "
                     "thread", self.n_threads)
            actual = 1
        _numba.set_num_threads(actual)
        bar = None
        if progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=nsteps, unit="step")
        reb0, rem0, bad0 = self.n_rebuilds, self.n_removed, self.n_lost_nonfinite
        psteps = 0
        dump = dump_every if rd is not None and dump_every else 0
        ckpt = checkpoint_every if rd is not None and checkpoint_every else 0

        def looked_at(step_no: int) -> bool:
            # a step after which the state is written out
            return bool((dump and step_no % dump == 0) or (ckpt and step_no % ckpt == 0))

        t0 = _time.perf_counter()
        try:
            s = 0
            while s < nsteps:
                if (self.fused_loop and callback is None and not self._rebuild_due
                        and (self._wload is None or self._wbuf.shape[1] == len(self.wall_names))):
                    # the steps up to the next look at the state, in the numba loop
                    end = min(nsteps, s + _FINITE_CHECK_EVERY - s % _FINITE_CHECK_EVERY)
                    if bar is not None:
                        end = min(end, s + 50 - s % 50)
                    for every in (dump, ckpt):
                        if every:
                            end = min(end, s + every - self.step % every)
                    fuse_last = end < nsteps and not looked_at(self.step + end - s)
                    n_now = self.n_particles
                    done = self._run_fused(end - s, fuse_last)
                    psteps += done * n_now
                    s += done
                    if s == end:
                        self._check_finite_after(s - 1, nsteps)
                        self._after_step(s - 1, nsteps, psteps, t0, rd, dump, ckpt, bar)
                        continue
                # one step from Python (a rebuild or a new wall list is due, a callback
                # looks, or fused_loop is off), its last pass fused with the next step's
                # first unless the state is looked at in between (the last step,
                # callbacks, dumps, checkpoints)
                fuse = s + 1 < nsteps and callback is None and not looked_at(self.step + 1)
                self._one_step(fuse)
                self._check_finite_after(s, nsteps)
                psteps += self.n_particles
                if self._wload is not None:
                    self._accumulate_wall_loads()
                if callback is not None:
                    callback(self)
                self._after_step(s, nsteps, psteps, t0, rd, dump, ckpt, bar)
                s += 1
        finally:
            _numba.set_num_threads(old_threads)
            if self._kicked:
                log.warning("run() interrupted between fused steps: positions and velocities "
                            "include the next step's half kick and drift; the next run() (or a "
                            "checkpoint saved now) continues exactly")
            if bar is not None:
                bar.close()
        wall = _time.perf_counter() - t0
        if rd is not None and dump_every and self.step % dump_every != 0:
            rd.write_output(self)
        self.wall_overflow += int(self._overflow.sum())
        self._overflow.fill(0)
        return RunStats(nsteps, wall, psteps / wall if wall > 0 else float("nan"),
                        self.n_rebuilds - reb0, self.n_removed - rem0,
                        self.n_lost_nonfinite - bad0)

    def _check_finite_after(self, s, nsteps):
        if s % _FINITE_CHECK_EVERY == _FINITE_CHECK_EVERY - 1 or s + 1 == nsteps:
            self._check_finite()

    def _after_step(self, s, nsteps, psteps, t0, rd, dump, ckpt, bar):
        """What :meth:`run` does after its step ``s`` (and the finiteness check): outputs,
        checkpoints and the progress bar."""
        if dump and self.step % dump == 0:
            rd.write_output(self)
        if ckpt and self.step % ckpt == 0:
            self.save_checkpoint(rd.path / "checkpoint.npz", extra={"outputs": {
                "run_dir": str(rd.path.resolve()), "sizes": rd.output_sizes()}})
        if bar is not None and (s % 50 == 49 or s == nsteps - 1):
            el = _time.perf_counter() - t0
            bar.set_postfix_str(f"t={self.time:.4g} s, "
                                f"{psteps / max(el, 1e-12) / 1e6:.2f} M p-steps/s")
            bar.update(s + 1 - bar.n)


#: this process's wall time, CPU time and the others' load at the last look (_cores_busy)
_LOAD_PROBE = [None, None, 0.0]


def _cores_busy(threads: int) -> bool:
    """Whether other processes leave fewer than ``threads`` cores to this one.

    The 1-minute load average less this process's own use (its CPU time over the
    wall time since the previous look, one thread at the first) estimates what the
    others run; the cores are busy when that exceeds ``cores - threads + 0.5``. The
    load is looked at most every half second (the estimate is kept in between);
    False where the load average is unknown.
    """
    try:
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
        wall, cpu = _time.perf_counter(), _time.process_time()
        w0, c0, others = _LOAD_PROBE
        if w0 is None or wall - w0 >= 0.5:
            own = 1.0 if w0 is None else (cpu - c0) / (wall - w0)
            others = os.getloadavg()[0] - own
            _LOAD_PROBE[:] = [wall, cpu, others]
    except (AttributeError, OSError):
        return False
    return others > (cores or 1) - threads + 0.5


def _numba_max_threads() -> int:
    import numba
    return int(numba.config.NUMBA_NUM_THREADS)
