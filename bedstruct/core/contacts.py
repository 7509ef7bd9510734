"""Contacts between spheres (and between spheres and walls) of one frame."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["Contacts", "WallContacts", "lens_radius"]


def lens_radius(r1, r2, distance) -> np.ndarray:
    """Radius of the circle in which two overlapping spheres intersect.

    For spheres of radii ``r1`` and ``r2`` at centre distance ``d`` the
    plane of intersection lies at ``x = (d^2 + r1^2 - r2^2) / (2 d)`` from
    centre 1 and the circle has radius ``a = sqrt(r1^2 - x^2)``. Pairs that
    do not overlap get 0; a sphere inside the other gets the smaller radius.

    Parameters
    ----------
    r1, r2 : array_like of float, length
        Radii.
    distance : array_like of float, length
        Centre distances.

    Returns
    -------
    ndarray of float, length

    Examples
    --------
    >>> float(lens_radius(1.0, 1.0, 1.0))  # sqrt(1 - 0.25)
    0.8660254037844386
    >>> float(lens_radius(1.0, 1.0, 2.5))
    0.0
    """
    r1 = np.asarray(r1, dtype=np.float64)
    r2 = np.asarray(r2, dtype=np.float64)
    d = np.asarray(distance, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (d * d + r1 * r1 - r2 * r2) / (2.0 * d)
        a2 = r1 * r1 - x * x
    a = np.sqrt(np.clip(a2, 0.0, None))
    a = np.where(d >= r1 + r2, 0.0, a)
    a = np.where(d <= np.abs(r1 - r2), np.minimum(r1, r2), a)
    return a


def _col(name, value, m, shape_tail=(), dtype=np.float64):
    if value is None:
        return None
    arr = np.ascontiguousarray(value, dtype=dtype)
    if arr.shape != (m,) + shape_tail:
        raise ValueError(f"`{name}` must have shape {(m,) + shape_tail} (M={m} contacts); "
                         f"got {arr.shape}")
    return arr


@dataclass(eq=False)
class Contacts:
    """Particle-particle contacts of one frame, one row per contact.

    Each unordered pair appears once. ``normals`` and ``branch`` point from
    particle ``i`` to particle ``j`` along the minimum-image displacement, so
    contacts across periodic boundaries are kept (``periodic`` marks them).

    Parameters
    ----------
    i, j : (M,) array_like of int
        Row indices into the frame's arrays.
    branch : (M,) array_like of float, length
        Vectors from the centre of ``i`` to the centre of ``j`` (minimum image).
    radii_i, radii_j : (M,) array_like of float, length
        Radii of the two spheres (for overlap and lens geometry).
    ids_i, ids_j : (M,) array_like of int, optional
        Particle ids of the two spheres.
    periodic : (M,) array_like of bool, optional
        True where the contact crosses a periodic boundary.
    force_normal, force_tangential : (M, 3) array_like of float, optional
        Contact force on ``i`` split into normal and tangential parts (when
        known, e.g. from a ``dump local`` file).
    area : (M,) array_like of float, optional
        Contact area (length^2) as dumped by the simulator; when absent it
        is the area of the overlap lens, ``pi a^2``.
    n_particles : int, optional
        Number of particles of the frame (so per-particle counts include
        particles without contacts).
    columns : dict, optional
        Any other per-contact values by name.
    source : str, optional
        ``"geometric"`` or the contact file name.
    walls : WallContacts, optional
        Particle-wall contacts found beside the pairs (kept apart from them).

    Examples
    --------
    >>> c = Contacts(i=[0], j=[1], branch=[[1.5, 0, 0]], radii_i=[1.0], radii_j=[1.0],
    ...              n_particles=2)
    >>> c.n_contacts, c.normals.tolist(), c.overlap.tolist()
    (1, [[1.0, 0.0, 0.0]], [0.5])
    >>> round(float(c.contact_radius[0]), 6)
    0.661438
    """

    i: np.ndarray
    j: np.ndarray
    branch: np.ndarray
    radii_i: np.ndarray
    radii_j: np.ndarray
    ids_i: np.ndarray | None = None
    ids_j: np.ndarray | None = None
    periodic: np.ndarray | None = None
    force_normal: np.ndarray | None = None
    force_tangential: np.ndarray | None = None
    area: np.ndarray | None = None
    n_particles: int | None = None
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = "geometric"
    walls: "WallContacts | None" = None

    def __post_init__(self):
        self.i = np.ascontiguousarray(self.i, dtype=np.int64).reshape(-1)
        m = self.i.shape[0]
        self.j = _col("j", self.j, m, dtype=np.int64)
        branch = np.asarray(self.branch, dtype=np.float64)
        if m == 0:
            branch = branch.reshape(0, 3)
        self.branch = _col("branch", branch, m, (3,))
        self.radii_i = _col("radii_i", self.radii_i, m)
        self.radii_j = _col("radii_j", self.radii_j, m)
        self.ids_i = _col("ids_i", self.ids_i, m, dtype=np.int64)
        self.ids_j = _col("ids_j", self.ids_j, m, dtype=np.int64)
        self.periodic = (np.zeros(m, dtype=bool) if self.periodic is None
                         else _col("periodic", self.periodic, m, dtype=bool))
        for name in ("force_normal", "force_tangential"):
            val = getattr(self, name)
            if val is not None and m == 0:
                val = np.asarray(val, dtype=np.float64).reshape(0, 3)
            setattr(self, name, _col(name, val, m, (3,)))
        self.area = _col("area", self.area, m)
        if self.n_particles is None:
            self.n_particles = int(max(self.i.max(initial=-1), self.j.max(initial=-1)) + 1)
        self.n_particles = int(self.n_particles)
        if m and (self.i.min() < 0 or self.j.min() < 0 or max(self.i.max(), self.j.max()) >= self.n_particles):
            raise ValueError(f"contact indices must lie in [0, {self.n_particles}); got "
                             f"i in [{self.i.min()}, {self.i.max()}], j in [{self.j.min()}, {self.j.max()}]")
        self.columns = {str(k): np.asarray(v) for k, v in dict(self.columns).items()}
        for k, v in self.columns.items():
            if v.shape[:1] != (m,):
                raise ValueError(f"contact column {k!r} must have M={m} rows; got {v.shape}")

    # ------------------------------------------------------------ geometry
    @property
    def n_contacts(self) -> int:
        """Number of contacts M."""
        return int(self.i.shape[0])

    def __len__(self) -> int:
        return self.n_contacts

    @property
    def distance(self) -> np.ndarray:
        """Centre distances |branch| (length)."""
        return np.sqrt(np.einsum("ij,ij->i", self.branch, self.branch))

    @property
    def normals(self) -> np.ndarray:
        """Unit normals from ``i`` to ``j`` (dimensionless), shape (M, 3)."""
        d = self.distance
        with np.errstate(invalid="ignore", divide="ignore"):
            n = self.branch / d[:, None]
        return np.nan_to_num(n, nan=0.0)

    @property
    def overlap(self) -> np.ndarray:
        """``r_i + r_j - d`` (length); negative for near (non-touching) pairs."""
        return self.radii_i + self.radii_j - self.distance

    @property
    def contact_radius(self) -> np.ndarray:
        """Radius of the overlap lens (length); 0 for non-touching pairs."""
        return lens_radius(self.radii_i, self.radii_j, self.distance)

    @property
    def lens_area(self) -> np.ndarray:
        """Area of the overlap lens, ``pi a^2`` (length^2)."""
        return math.pi * self.contact_radius ** 2

    @property
    def contact_area(self) -> np.ndarray:
        """Dumped contact area where available, else the lens area (length^2)."""
        return self.area if self.area is not None else self.lens_area

    @property
    def force(self) -> np.ndarray | None:
        """Total contact force on ``i`` (normal + tangential), when known."""
        if self.force_normal is None and self.force_tangential is None:
            return None
        fn = self.force_normal if self.force_normal is not None else 0.0
        ft = self.force_tangential if self.force_tangential is not None else 0.0
        return fn + ft

    # ------------------------------------------------------------- selection
    def select(self, mask_or_index) -> "Contacts":
        """A new :class:`Contacts` with only the selected rows."""
        idx = np.asarray(mask_or_index)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)

        def s(a):
            return None if a is None else a[idx]
        return replace(self, i=self.i[idx], j=self.j[idx], branch=self.branch[idx],
                       radii_i=self.radii_i[idx], radii_j=self.radii_j[idx],
                       ids_i=s(self.ids_i), ids_j=s(self.ids_j), periodic=self.periodic[idx],
                       force_normal=s(self.force_normal), force_tangential=s(self.force_tangential),
                       area=s(self.area), columns={k: v[idx] for k, v in self.columns.items()})

    def touching(self) -> "Contacts":
        """Only the rows with positive overlap."""
        return self.select(self.overlap > 0.0)

    def per_particle_count(self) -> np.ndarray:
        """Number of contacts of each particle, shape (n_particles,)."""
        return (np.bincount(self.i, minlength=self.n_particles)
                + np.bincount(self.j, minlength=self.n_particles)).astype(np.int64)

    def __repr__(self) -> str:
        return (f"Contacts(n_contacts={self.n_contacts}, n_particles={self.n_particles}, "
                f"source={self.source!r})")


@dataclass(eq=False)
class WallContacts:
    """Contacts between particles and plane walls, kept apart from pairs.

    Parameters
    ----------
    particle : (M,) array_like of int
        Row index of the particle in the frame.
    wall : (M,) array_like of int
        Index of the wall in the list of walls given to the detector.
    normals : (M, 3) array_like of float
        Unit vectors from the particle centre towards the wall.
    overlap : (M,) array_like of float, length
        ``r - distance to the wall`` (negative for near contacts).
    radii : (M,) array_like of float, length
        Particle radii.
    """

    particle: np.ndarray
    wall: np.ndarray
    normals: np.ndarray
    overlap: np.ndarray
    radii: np.ndarray

    def __post_init__(self):
        self.particle = np.ascontiguousarray(self.particle, dtype=np.int64).reshape(-1)
        m = self.particle.shape[0]
        self.wall = _col("wall", self.wall, m, dtype=np.int64)
        nrm = np.asarray(self.normals, dtype=np.float64)
        self.normals = _col("normals", nrm.reshape(0, 3) if m == 0 else nrm, m, (3,))
        self.overlap = _col("overlap", self.overlap, m)
        self.radii = _col("radii", self.radii, m)

    @property
    def n_contacts(self) -> int:
        """Number of particle-wall contacts."""
        return int(self.particle.shape[0])

    @property
    def contact_radius(self) -> np.ndarray:
        """Radius of the sphere-plane intersection circle (length)."""
        h = np.clip(self.overlap, 0.0, None)
        return np.sqrt(np.clip(2.0 * self.radii * h - h * h, 0.0, None))

    @property
    def area(self) -> np.ndarray:
        """Area of the sphere-plane intersection circle (length^2)."""
        return math.pi * self.contact_radius ** 2
