"""State output and checkpoints of a :class:`~bedstruct.dem.Simulation`.

The :class:`_StateIO` mixin holds :meth:`frame`, :meth:`contacts` (forces
evaluated at the current state without changing it), energies, memory use,
the configuration record and the bit-exact checkpoint/resume.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Self

import numpy as np

from .._atomic import atomic_path
from .._json import json_default
from ..core import Box, Contacts, Frame, WallContacts
from .params import ContactModel, Material
from ._sim_walls import _WALL_SLOTS

__all__: list[str] = []

_CHECKPOINT_VERSION = 1


class _StateIO:
    """Frames, contacts, energies, configuration and checkpoints (mixed into Simulation)."""

    def _evaluate(self):
        """Pair and wall forces of the last force evaluation, without changing the state.

        After a step the forces were evaluated at the step's half-step velocities (velocity
        Verlet; the second half kick followed): they are evaluated again at those, taken back
        from the current ones, so that they are the forces that moved the particles (the
        total in :meth:`frame`), as LIGGGHTS' ``compute pair/gran/local`` reports them.
        """
        if not self._ready:
            self._setup()
        if self._f_half_step and not self._kicked and self.dt:
            v, om = self.v, self.om
            h = 0.5 * self.dt
            self.v = v - (h * self.inv_m)[:, None] * self.f
            self.om = om - (h * self.inv_i)[:, None] * self.tq
            try:
                return self._evaluate_now()
            finally:
                self.v, self.om = v, om
        return self._evaluate_now()

    def _evaluate_now(self):
        """Pair and wall forces at the current positions and velocities."""
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
        (N) of the last step, those in the total forces of :meth:`frame` (evaluated
        at the step's half-step velocities, as in LIGGGHTS' ``pair/gran/local``; with
        tangential damping, the tangential force of a contact sliding at the Coulomb
        limit is evaluated again from its rescaled spring and carries the damping term
        the limit left out of the step);
        ``branch`` points from i to j (minimum image); the SJKR area of
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

    def save_checkpoint(self, path, *, extra: dict | None = None) -> Path:
        """Write the complete state (incl. contact history and rng) atomically to ``path`` (.npz).

        ``extra`` (JSON-ready data) is stored with it and comes back as
        ``checkpoint_extra`` of :meth:`from_checkpoint`'s simulation (the workflows keep
        the position in their stage script there; ``{"outputs": {"run_dir": ..., "sizes":
        ...}}`` is what :meth:`run` records about its :class:`RunDirectory`).
        """
        path = Path(path)
        if not self._ready:
            self._setup()
        arrays = {name.lstrip("_"): getattr(self, name) for name in self._STATE}
        arrays["wbuf"] = self._wbuf  # the wall loads of the last step (wall_states)
        if self._wload is not None:  # a wall-load average in progress
            arrays["wload"] = self._wload
        meta = dict(version=_CHECKPOINT_VERSION, time=self.time, step=self.step, dt=self.dt,
                    skin=self.skin, n_removed=self.n_removed, n_rebuilds=self.n_rebuilds,
                    wall_overflow=int(self.wall_overflow + self._overflow.sum()),
                    next_id=self._next_id, n_threads=self.n_threads, wall_names=self.wall_names,
                    rng=self.rng.bit_generator.state, config=self.config(),
                    t_rayleigh=self.t_rayleigh, t_hertz=self.t_hertz,
                    wall_list_time=self._wall_list_time, wall_speed=self._wall_speed,
                    wall_programs=self._programs, kicked=bool(getattr(self, "_kicked", False)),
                    forces_half_step=bool(self._f_half_step),
                    pair_bounds=self._qbounds.tolist(), wload_steps=int(self._wload_steps),
                    n_lost_nonfinite=int(self.n_lost_nonfinite), nonfinite=self.nonfinite,
                    extra=extra if extra is not None else {})
        arrays["meta"] = np.array(json.dumps(meta, default=json_default))
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
        return path

    @classmethod
    def from_checkpoint(cls, path, model: ContactModel | None = None, *, walls=None) -> Self:
        """Resume from :meth:`save_checkpoint`; continuing gives the same result bit for bit.

        ``model`` defaults to the model recorded in the checkpoint; ``walls``
        (the wall objects, for the configuration record) default to the
        recorded wall table. The ``extra`` data given to :meth:`save_checkpoint` is
        ``sim.checkpoint_extra``.
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
                  safety=cfg["safety"], max_rayleigh_fraction=cfg["max_rayleigh_fraction"],
                  nonfinite=meta.get("nonfinite", "raise"))
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
        sim.wall_overflow = int(meta.get("wall_overflow", 0))
        sim._next_id = meta["next_id"]
        sim.force = cfg["force"]
        sim.rng.bit_generator.state = meta["rng"]
        sim._wall_cfg = cfg["walls"]
        sim._alloc_buffers()
        if len(meta.get("pair_bounds", ())) == sim.n_threads + 1:
            sim._qbounds = np.array(meta["pair_bounds"], dtype=np.int64)
        sim._balance_finish()
        sim._wall_list_time = meta["wall_list_time"]
        sim._wall_speed = meta["wall_speed"]
        sim._programs = dict(meta.get("wall_programs", {}))
        sim._kicked = bool(meta.get("kicked", False))  # saved after an interrupted run()
        sim._f_half_step = bool(meta.get("forces_half_step", sim.step > 0))
        if sim._kicked:
            # the step under way looks at the displacements since the last build (a rebuild
            # may be due): as the drift computed them, per chunk
            dd = sim._displacement2()
            for t in range(sim.n_threads):
                part = dd[sim._pbounds[t]:sim._pbounds[t + 1]]
                sim._disp[t] = part.max(initial=0.0)
        if "wbuf" in data and data["wbuf"].shape == sim._wbuf.shape:
            sim._wbuf = np.ascontiguousarray(data["wbuf"])
        if "wload" in data:
            sim._wload = np.array(data["wload"])
            sim._wload_steps = int(meta.get("wload_steps", 0))
        sim.n_lost_nonfinite = int(meta.get("n_lost_nonfinite", 0))
        sim.checkpoint_extra = dict(meta.get("extra", {}))
        sim._resume_outputs = sim.checkpoint_extra.get("outputs")
        sim._ready = True
        return sim


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
