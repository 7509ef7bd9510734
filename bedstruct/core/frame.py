"""One snapshot of spheres in a box: the data model every reader produces."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Mapping

import numpy as np

from .box import Box

__all__ = ["Frame", "Units", "Provenance", "UNIT_STYLES"]

# LAMMPS unit styles relevant to granular work: the SI factor of each quantity.
UNIT_STYLES: dict[str, dict[str, float]] = {
    "si": dict(length=1.0, time=1.0, mass=1.0, velocity=1.0, force=1.0, density=1.0),
    "cgs": dict(length=1e-2, time=1.0, mass=1e-3, velocity=1e-2, force=1e-5, density=1e3),
    "micro": dict(length=1e-6, time=1e-6, mass=1e-15, velocity=1.0, force=1e-9, density=1e3),
    # LAMMPS nano: attogram (1e-21 kg), nm, ns; force ag nm/ns^2, density ag/nm^3
    "nano": dict(length=1e-9, time=1e-9, mass=1e-21, velocity=1.0, force=1e-12, density=1e6),
    # LAMMPS real and metal: g/mol, Angstrom, fs or ps; kcal/mol/A or eV/A; g/cm^3
    "real": dict(length=1e-10, time=1e-15, mass=1e-3 / 6.02214076e23, velocity=1e5,
                 force=4184.0 / 6.02214076e23 / 1e-10, density=1e3),
    "metal": dict(length=1e-10, time=1e-12, mass=1e-3 / 6.02214076e23, velocity=1e2,
                  force=1.602176634e-19 / 1e-10, density=1e3),
    # LAMMPS electron: amu, Bohr, fs; velocity Bohr per atomic time unit (1.03275e-15 s),
    # force Hartree/Bohr; the style defines no density
    "electron": dict(length=5.29177210903e-11, time=1e-15, mass=1e-3 / 6.02214076e23,
                     velocity=5.29177210903e-11 / 1.03275e-15,
                     force=4.3597447222071e-18 / 5.29177210903e-11),
}
_LENGTH_NAMES = {"si": "m", "cgs": "cm", "micro": "um", "nano": "nm", "real": "Å", "metal": "Å",
                 "electron": "Bohr"}
_VELOCITY_NAMES = {"si": "m/s", "cgs": "cm/s", "micro": "um/us", "nano": "nm/ns", "real": "Å/fs",
                   "metal": "Å/ps", "electron": "Bohr/atu"}


@dataclass(frozen=True)
class Units:
    """Unit system of a frame's numbers.

    Parameters
    ----------
    style : str or None
        A LAMMPS unit style (``"si"``, ``"cgs"``, ``"micro"``, ``"nano"``, ``"real"``,
        ``"metal"``, ``"electron"``, ``"lj"``) or None when unknown. Default ``"si"``.
    conversions : tuple of str
        A record of every conversion already applied to the data.

    Examples
    --------
    >>> Units("cgs").length_unit, Units("cgs").to_si("length")
    ('cm', 0.01)
    """

    style: str | None = "si"
    conversions: tuple[str, ...] = ()

    def __post_init__(self):
        if self.style is not None:
            object.__setattr__(self, "style", str(self.style).lower())

    @property
    def length_unit(self) -> str:
        """Name of the length unit (``"m"``, ``"cm"``, ..., or ``"unknown"``)."""
        return _LENGTH_NAMES.get(self.style or "", "lj units" if self.style == "lj" else "unknown")

    @property
    def velocity_unit(self) -> str:
        """Name of the velocity unit (``"m/s"``, ``"um/us"``, ``"Å/ps"``, ..., or ``"unknown"``)."""
        return _VELOCITY_NAMES.get(self.style or "", "lj units" if self.style == "lj" else "unknown")

    def to_si(self, quantity: str) -> float:
        """Factor converting ``quantity`` in this style to SI.

        Raises
        ------
        ValueError
            If the style is unknown or has no SI meaning (``lj``).
        """
        if self.style not in UNIT_STYLES:
            raise ValueError(f"units {self.style!r} have no known SI conversion; "
                             f"state the unit system with units='si'|'cgs'|'micro'|'nano'|"
                             f"'real'|'metal'|'electron'")
        if quantity not in UNIT_STYLES["si"]:
            raise ValueError(f"unknown quantity {quantity!r}; one of "
                             f"{sorted(UNIT_STYLES['si'])}")
        try:
            return UNIT_STYLES[self.style][quantity]
        except KeyError:
            raise ValueError(f"LAMMPS units {self.style!r} define no {quantity}") from None


@dataclass(frozen=True)
class Provenance:
    """Where a frame came from: source file, frame index in it, and notes.

    ``notes`` records anything the reader had to assume (synthesised ids,
    default types, a converted diameter column, unit conversions).
    """

    source: str | None = None
    frame_index: int | None = None
    notes: tuple[str, ...] = ()

    def with_note(self, note: str) -> "Provenance":
        """A copy with one more note."""
        return replace(self, notes=self.notes + (note,))


def _as_vectors(name: str, value, n: int, dtype=np.float64) -> np.ndarray | None:
    if value is None:
        return None
    arr = np.ascontiguousarray(value, dtype=dtype)
    if arr.shape != (n, 3):
        raise ValueError(f"`{name}` must have shape (N, 3) matching `positions` (N={n}); "
                         f"got {arr.shape}")
    return arr


@dataclass(eq=False)
class Frame:
    """A snapshot of N spheres in a box.

    Parameters
    ----------
    positions : (N, 3) array_like of float, length
        Sphere centres (float64).
    radii : (N,) array_like of float, length
        Sphere radii, all positive and finite.
    box : Box or box-like
        The simulation box (see :meth:`Box.from_box`).
    timestep : int, optional
        The simulation step number. Default 0.
    ids : (N,) array_like of int, optional
        Particle ids; default ``1..N``.
    types : (N,) array_like of int, optional
        Particle types; default all 1.
    time : float, optional
        Simulated time (time units), when known.
    velocities, omegas, forces : (N, 3) array_like of float, optional
        Velocities (length/time), angular velocities (1/time) and forces.
    images : (N, 3) array_like of int, optional
        Periodic image flags ``ix iy iz``: ``positions + images @ box.matrix.T``
        is the unwrapped position (0 when the positions are already unwrapped).
    columns : mapping of str to (N,) or (N, k) arrays, optional
        Every other per-atom column under its dump name (``mass``,
        ``density``, ``c_cn``, ``f_temp[1]`` ...).
    units : Units, optional
        Unit system of the numbers (default SI).
    provenance : Provenance, optional
        Source file, frame index and notes.

    Examples
    --------
    >>> f = Frame([[0, 0, 0], [1, 0, 0]], [0.5, 0.5], box=[2, 2, 2])
    >>> f.n_particles, f.ids.tolist(), f.types.tolist()
    (2, [1, 2], [1, 1])
    >>> round(f.particle_volume, 6)
    1.047198
    """

    positions: np.ndarray
    radii: np.ndarray
    box: Box
    timestep: int = 0
    ids: np.ndarray | None = None
    types: np.ndarray | None = None
    time: float | None = None
    velocities: np.ndarray | None = None
    omegas: np.ndarray | None = None
    forces: np.ndarray | None = None
    images: np.ndarray | None = None
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    units: Units = field(default_factory=Units)
    provenance: Provenance = field(default_factory=Provenance)

    def __post_init__(self):
        pos = np.ascontiguousarray(self.positions, dtype=np.float64)
        if pos.ndim == 1 and pos.size == 0:
            pos = pos.reshape(0, 3)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise ValueError(f"`positions` must have shape (N, 3); got {pos.shape}")
        n = pos.shape[0]
        radii = np.asarray(self.radii, dtype=np.float64)
        if radii.ndim == 0:
            radii = np.full(n, float(radii))
        radii = np.ascontiguousarray(radii)
        if radii.shape != (n,):
            raise ValueError(f"`radii` must have shape (N,) matching `positions` (N={n}); "
                             f"got {radii.shape}")
        if n and not np.all(np.isfinite(pos)):
            bad = int(np.flatnonzero(~np.all(np.isfinite(pos), axis=1))[0])
            raise ValueError(f"`positions` must be finite; row {bad} is {pos[bad].tolist()}")
        if n and not (np.all(np.isfinite(radii)) and np.all(radii > 0)):
            bad = int(np.flatnonzero(~(np.isfinite(radii) & (radii > 0)))[0])
            raise ValueError(f"`radii` must be positive and finite; row {bad} is {radii[bad]}")
        self.positions = pos
        self.radii = radii
        self.box = Box.from_box(self.box)
        self.timestep = int(self.timestep)
        if self.ids is None:
            self.ids = np.arange(1, n + 1, dtype=np.int64)
        else:
            self.ids = np.ascontiguousarray(self.ids, dtype=np.int64)
            if self.ids.shape != (n,):
                raise ValueError(f"`ids` must have shape (N,) (N={n}); got {self.ids.shape}")
        if self.types is None:
            self.types = np.ones(n, dtype=np.int32)
        else:
            self.types = np.ascontiguousarray(self.types, dtype=np.int32)
            if self.types.shape != (n,):
                raise ValueError(f"`types` must have shape (N,) (N={n}); got {self.types.shape}")
        self.velocities = _as_vectors("velocities", self.velocities, n)
        self.omegas = _as_vectors("omegas", self.omegas, n)
        self.forces = _as_vectors("forces", self.forces, n)
        self.images = _as_vectors("images", self.images, n, dtype=np.int64)
        cols = {}
        for name, value in dict(self.columns).items():
            arr = np.asarray(value)
            if arr.shape[:1] != (n,):
                raise ValueError(f"column {name!r} must have N={n} rows; got shape {arr.shape}")
            cols[str(name)] = arr
        self.columns = cols
        if self.time is not None:
            self.time = float(self.time)
        if not isinstance(self.units, Units):
            self.units = Units(self.units)
        if not isinstance(self.provenance, Provenance):
            self.provenance = Provenance(source=str(self.provenance))

    # ------------------------------------------------------------- derived
    @property
    def n_particles(self) -> int:
        """Number of particles N."""
        return int(self.positions.shape[0])

    def __len__(self) -> int:
        return self.n_particles

    @property
    def diameters(self) -> np.ndarray:
        """Sphere diameters (length)."""
        return 2.0 * self.radii

    @property
    def volumes(self) -> np.ndarray:
        """Sphere volumes (length^3)."""
        return (4.0 / 3.0) * math.pi * self.radii ** 3

    @property
    def particle_volume(self) -> float:
        """Total volume of all spheres (length^3)."""
        return float(self.volumes.sum())

    def unwrapped_positions(self) -> np.ndarray:
        """Positions with image flags applied (requires ``images``)."""
        if self.images is None:
            raise ValueError("this frame has no image flags (ix iy iz); cannot unwrap")
        return self.positions + self.images @ self.box.matrix.T

    def __repr__(self) -> str:
        return (f"Frame(timestep={self.timestep}, n_particles={self.n_particles}, box={self.box!r}, "
                f"units={self.units.style!r})")

    # ------------------------------------------------------------- copies
    def copy(self) -> "Frame":
        """A deep copy (all arrays copied)."""
        def c(a):
            return None if a is None else a.copy()
        return replace(self, positions=self.positions.copy(), radii=self.radii.copy(),
                       ids=self.ids.copy(), types=self.types.copy(), velocities=c(self.velocities),
                       omegas=c(self.omegas), forces=c(self.forces), images=c(self.images),
                       columns={k: v.copy() for k, v in self.columns.items()})

    def select(self, mask_or_index) -> "Frame":
        """A new frame with only the selected particles (mask or indices)."""
        idx = np.asarray(mask_or_index)
        if idx.dtype == bool:
            if idx.shape != (self.n_particles,):
                raise ValueError(f"mask must have shape ({self.n_particles},); got {idx.shape}")
            idx = np.flatnonzero(idx)

        def s(a):
            return None if a is None else a[idx]
        return replace(self, positions=self.positions[idx], radii=self.radii[idx],
                       ids=self.ids[idx], types=self.types[idx], velocities=s(self.velocities),
                       omegas=s(self.omegas), forces=s(self.forces), images=s(self.images),
                       columns={k: v[idx] for k, v in self.columns.items()})

    def sorted_by_id(self) -> "Frame":
        """This frame with rows ordered by ascending id (self if already sorted)."""
        if self.n_particles < 2 or np.all(self.ids[1:] > self.ids[:-1]):
            return self
        return self.select(np.argsort(self.ids, kind="stable"))

    def with_units(self, style: str) -> "Frame":
        """Record the unit system without converting any number."""
        return replace(self, units=Units(style, self.units.conversions))

    def to_si(self) -> "Frame":
        """A copy converted to SI, with the conversion recorded in ``units``.

        Positions, radii, box, time, velocities, forces, and the ``mass`` and
        ``density`` columns are converted; angular velocities scale with
        1/time. Other columns are kept as they are and listed in the record.
        """
        u = self.units
        if u.style == "si":
            return self
        L, T = u.to_si("length"), u.to_si("time")
        V, F, M, D = u.to_si("velocity"), u.to_si("force"), u.to_si("mass"), u.to_si("density")
        box = Box(self.box.lo * L, self.box.hi * L, self.box.tilt * L, self.box.boundary)
        cols = dict(self.columns)
        kept = []
        for name in list(cols):
            if name == "mass":
                cols[name] = cols[name] * M
            elif name == "density":
                cols[name] = cols[name] * D
            else:
                kept.append(name)
        note = f"converted {u.style} -> si (length x{L:g}, time x{T:g})"
        if kept:
            note += "; columns left unconverted: " + ", ".join(kept)
        return replace(
            self, positions=self.positions * L, radii=self.radii * L, box=box,
            time=None if self.time is None else self.time * T,
            velocities=None if self.velocities is None else self.velocities * V,
            omegas=None if self.omegas is None else self.omegas / T,
            forces=None if self.forces is None else self.forces * F,
            columns=cols, units=Units("si", u.conversions + (note,)))


def _as_frame(obj: Any) -> Frame:
    """Normalise frame-like input: a Frame, ``(box, positions, radii)``, or an object
    with ``positions``, ``radii`` and ``box`` attributes."""
    if isinstance(obj, Frame):
        return obj
    if isinstance(obj, tuple) and len(obj) == 3:
        box, positions, radii = obj
        return Frame(positions, radii, box=box)
    if all(hasattr(obj, a) for a in ("positions", "radii", "box")):
        return Frame(obj.positions, obj.radii, box=obj.box)
    raise TypeError(f"expected a Frame or (box, positions, radii); got {type(obj).__name__}")


def columns_table(frame: Frame) -> Mapping[str, np.ndarray]:
    """All per-particle data of a frame as named 1-D columns (dump naming)."""
    out: dict[str, np.ndarray] = {"id": frame.ids, "type": frame.types}
    for k, name in enumerate("xyz"):
        out[name] = frame.positions[:, k]
    out["radius"] = frame.radii
    for attr, names in (("velocities", ("vx", "vy", "vz")), ("omegas", ("omegax", "omegay", "omegaz")),
                        ("forces", ("fx", "fy", "fz")), ("images", ("ix", "iy", "iz"))):
        arr = getattr(frame, attr)
        if arr is not None:
            for k, name in enumerate(names):
                out[name] = arr[:, k]
    for name, arr in frame.columns.items():
        if arr.ndim == 1:
            out[name] = arr
        else:
            for k in range(arr.shape[1]):
                out[f"{name}[{k + 1}]"] = arr[:, k]
    return out
