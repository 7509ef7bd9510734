"""Coordination numbers: per particle, per window and per frame, with rattler removal."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.contacts import Contacts
from ..core.frame import _as_frame
from . import _contact_kernels as _k
from .contacts import find_contacts

__all__ = ["CoordinationResult", "coordination", "remove_rattlers", "WindowCoordination",
           "coordination_by_window", "CoordinationSeries", "coordination_series",
           "coordination_table"]


@dataclass(frozen=True)
class CoordinationResult:
    """Coordination numbers of one frame.

    Attributes
    ----------
    per_particle : (N,) ndarray of int
        Contacts of each particle (pairs, plus wall contacts when counted).
    mean : float
        Mean of ``per_particle`` over all particles (NaN when N = 0).
    rattlers : (N,) ndarray of bool
        Particles removed by iterative rattler removal.
    mean_excluding_rattlers : float
        Mean of ``per_particle`` over non-rattlers (contacts with rattlers
        still counted).
    mechanical : float
        Mechanical coordination number ``Z_m = 2 M' / N'`` (plus wall contacts
        of non-rattlers over ``N'`` when walls are counted), where ``M'``
        counts contacts between non-rattlers and ``N'`` the non-rattlers.
    per_particle_mechanical : (N,) ndarray of int
        Contacts of each particle among non-rattlers (0 for rattlers).
    min_contacts : int
        Threshold used for rattler removal.
    n_rattlers : int
        Number of rattlers.
    """

    per_particle: np.ndarray
    mean: float
    rattlers: np.ndarray
    mean_excluding_rattlers: float
    mechanical: float
    per_particle_mechanical: np.ndarray
    min_contacts: int
    n_rattlers: int

    @property
    def n_particles(self) -> int:
        """Number of particles N."""
        return int(self.per_particle.shape[0])

    @property
    def rattler_fraction(self) -> float:
        """Fraction of particles that are rattlers."""
        return self.n_rattlers / self.n_particles if self.n_particles else float("nan")


def _counts(contacts: Contacts, n: int, include_walls: bool, active=None) -> np.ndarray:
    i, j = contacts.i, contacts.j
    if active is not None:
        keep = active[i] & active[j]
        i, j = i[keep], j[keep]
    c = np.bincount(i, minlength=n) + np.bincount(j, minlength=n)
    if include_walls and contacts.walls is not None and contacts.walls.n_contacts:
        p = contacts.walls.particle
        if active is not None:
            p = p[active[p]]
        c = c + np.bincount(p, minlength=n)
    return c.astype(np.int64)


def remove_rattlers(contacts: Contacts, *, min_contacts: int = 2, include_walls: bool = False,
                    n_particles: int | None = None) -> np.ndarray:
    """Iteratively flag particles with fewer than ``min_contacts`` contacts.

    Removing a rattler removes its contacts, which may turn neighbours into
    rattlers; the result is the fixed point (the k-core of the contact
    network with k = ``min_contacts``), found by queue-based peeling in
    O(N + M).

    Parameters
    ----------
    contacts : Contacts
        Contacts of the frame.
    min_contacts : int, optional
        A particle needs at least this many contacts with non-rattlers to
        stay. Default 2: a particle with 0 or 1 contacts carries no stable
        load in a frictional bed (Thornton's mechanical coordination number
        excludes them); use 4 (``d + 1``) for the frictionless jamming
        convention.
    include_walls : bool, optional
        Count particle-wall contacts (``contacts.walls``) towards the minimum.
    n_particles : int, optional
        Number of particles (default ``contacts.n_particles``).

    Returns
    -------
    (N,) ndarray of bool
        True for rattlers.

    Examples
    --------
    >>> from bedstruct import Contacts
    >>> c = Contacts(i=[0, 0, 1, 2], j=[1, 2, 2, 3], branch=[[1, 0, 0]] * 4,
    ...              radii_i=[0.5] * 4, radii_j=[0.5] * 4, n_particles=4)
    >>> remove_rattlers(c, min_contacts=2).tolist()   # 3 hangs on one contact
    [False, False, False, True]
    """
    n = contacts.n_particles if n_particles is None else int(n_particles)
    if int(min_contacts) < 0:
        raise ValueError(f"`min_contacts` must be >= 0; got {min_contacts}")
    fixed = np.zeros(n, dtype=np.int64)
    if include_walls and contacts.walls is not None and contacts.walls.n_contacts:
        fixed += np.bincount(contacts.walls.particle, minlength=n)
    removed = np.empty(n, dtype=np.bool_)
    _k.peel_rattlers(contacts.i, contacts.j, fixed, int(min_contacts), removed)
    return removed


def coordination(frame, contacts: Contacts | None = None, *, tolerance: float = 0.0,
                 walls=None, include_walls: bool = False, min_contacts: int = 2
                 ) -> CoordinationResult:
    """Coordination number of every particle, its mean, and the mechanical CN.

    Parameters
    ----------
    frame : Frame or (box, positions, radii)
        The spheres.
    contacts : Contacts, optional
        Precomputed contacts (geometric or read from a ``dump local`` file).
        Default ``find_contacts(frame, tolerance, walls)``.
    tolerance : float, length, optional
        Passed to :func:`find_contacts` when ``contacts`` is None.
    walls : sequence, optional
        Walls passed to :func:`find_contacts` when ``contacts`` is None.
    include_walls : bool, optional
        Count particle-wall contacts in the coordination numbers (default
        False: particle-particle only, as the seed report).
    min_contacts : int, optional
        Threshold of the iterative rattler removal (see
        :func:`remove_rattlers`). Default 2.

    Returns
    -------
    CoordinationResult

    Notes
    -----
    Mean coordination :math:`Z = 2M/N` for :math:`M` pair contacts and
    :math:`N` particles. After iterative removal of rattlers (particles with
    fewer than ``min_contacts`` contacts), the mechanical coordination number
    is :math:`Z_m = 2M'/N'` over the remaining particles. The default
    threshold follows Thornton's mechanical coordination number [1]_, which
    leaves out particles with 0 or 1 contacts (here the removal is iterated
    to a fixed point); frictionless jamming studies use ``d + 1 = 4`` [2]_.

    References
    ----------
    .. [1] C. Thornton, "Numerical simulations of deviatoric shear deformation
       of granular media", Geotechnique 50 (2000) 43-53,
       doi:10.1680/geot.2000.50.1.43.
    .. [2] C. S. O'Hern, L. E. Silbert, A. J. Liu, S. R. Nagel, "Jamming at zero
       temperature and zero applied stress", Phys. Rev. E 68, 011306 (2003),
       doi:10.1103/PhysRevE.68.011306.

    .. versionadded:: 0.1

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> sc = Frame(g + 0.5, np.full(27, 0.5), box=[3, 3, 3])   # simple cubic, periodic
    >>> res = coordination(sc)
    >>> res.mean, res.mechanical, res.n_rattlers
    (6.0, 6.0, 0)
    """
    frame = _as_frame(frame)
    n = frame.n_particles
    if contacts is None:
        contacts = find_contacts(frame, tolerance, walls)
    elif not isinstance(contacts, Contacts):
        raise TypeError(f"`contacts` must be a Contacts object; got {type(contacts).__name__}")
    if contacts.n_particles != n:
        raise ValueError(f"`contacts` were found for {contacts.n_particles} particles but the "
                         f"frame has {n}")
    per = _counts(contacts, n, include_walls)
    ratt = remove_rattlers(contacts, min_contacts=min_contacts, include_walls=include_walls,
                           n_particles=n)
    mech = _counts(contacts, n, include_walls, ~ratt)
    keep = ~ratt
    nan = float("nan")
    return CoordinationResult(
        per_particle=per, mean=float(per.mean()) if n else nan, rattlers=ratt,
        mean_excluding_rattlers=float(per[keep].mean()) if keep.any() else nan,
        mechanical=float(mech[keep].mean()) if keep.any() else nan,
        per_particle_mechanical=mech, min_contacts=int(min_contacts), n_rattlers=int(ratt.sum()))


@dataclass(frozen=True)
class WindowCoordination:
    """Mean coordination number of the particles whose centres lie in each window.

    Attributes
    ----------
    mean : (K,) ndarray of float
        Mean CN per window (NaN for empty windows).
    mechanical : (K,) ndarray of float
        Mean CN among non-rattlers, counting only contacts between non-rattlers.
    n_particles : (K,) ndarray of int
        Particles per window.
    lower, upper : (K, 3) ndarray of float, length
        Window corners.
    """

    mean: np.ndarray
    mechanical: np.ndarray
    n_particles: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


def coordination_by_window(frame, lower, upper, *, contacts: Contacts | None = None,
                           result: CoordinationResult | None = None, **kwargs
                           ) -> WindowCoordination:
    """Mean coordination number per axis-aligned window (by particle centre).

    Parameters
    ----------
    frame : Frame
        The spheres (centres are wrapped into the box along periodic axes).
    lower, upper : (K, 3) or (3,) array_like of float, length
        Window corners, e.g. from :func:`bedstruct.analysis.bed_windows`.
    contacts : Contacts, optional
        Precomputed contacts.
    result : CoordinationResult, optional
        Precomputed per-particle coordination (skips recomputation).
    **kwargs
        Passed to :func:`coordination`.

    Returns
    -------
    WindowCoordination

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(4)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> sc = Frame(g + 0.5, np.full(64, 0.5), box=[4, 4, 4])
    >>> w = coordination_by_window(sc, [[0, 0, 0], [2, 0, 0]], [[2, 4, 4], [4, 4, 4]])
    >>> w.mean.tolist(), w.n_particles.tolist()
    ([6.0, 6.0], [32, 32])
    """
    frame = _as_frame(frame)
    lo = np.atleast_2d(np.asarray(lower, dtype=np.float64))
    hi = np.atleast_2d(np.asarray(upper, dtype=np.float64))
    if lo.shape != hi.shape or lo.shape[1:] != (3,):
        raise ValueError(f"`lower` and `upper` must both have shape (K, 3); got {lo.shape}, {hi.shape}")
    if result is None:
        result = coordination(frame, contacts, **kwargs)
    pos = frame.box.wrap(frame.positions)
    k = lo.shape[0]
    mean = np.full(k, np.nan)
    mech = np.full(k, np.nan)
    count = np.zeros(k, dtype=np.int64)
    for w in range(k):
        inside = np.all((pos >= lo[w]) & (pos < hi[w]), axis=1)
        count[w] = int(inside.sum())
        if count[w]:
            mean[w] = result.per_particle[inside].mean()
            sel = inside & ~result.rattlers
            if sel.any():
                mech[w] = result.per_particle_mechanical[sel].mean()
    return WindowCoordination(mean, mech, count, lo, hi)


@dataclass(frozen=True)
class CoordinationSeries:
    """Mean coordination per frame.

    Attributes
    ----------
    timesteps : (F,) ndarray of int
    mean, mechanical : (F,) ndarray of float
    n_rattlers : (F,) ndarray of int
    """

    timesteps: np.ndarray
    mean: np.ndarray
    mechanical: np.ndarray
    n_rattlers: np.ndarray


def coordination_series(frames, **kwargs) -> CoordinationSeries:
    """Mean and mechanical coordination number of every frame of a trajectory.

    Parameters
    ----------
    frames : iterable of Frame
        A :class:`~bedstruct.Trajectory` or any sequence of frames.
    **kwargs
        Passed to :func:`coordination` (``tolerance``, ``walls``, ...).

    Returns
    -------
    CoordinationSeries

    Examples
    --------
    >>> from bedstruct import Frame
    >>> fs = [Frame([[0, 0, 0], [d, 0, 0]], [0.5, 0.5], box=([-2] * 3, [3] * 3),
    ...             timestep=t) for t, d in enumerate((0.9, 1.1))]
    >>> s = coordination_series(fs, min_contacts=1)
    >>> s.timesteps.tolist(), s.mean.tolist()
    ([0, 1], [1.0, 0.0])
    """
    ts, mean, mech, nr = [], [], [], []
    for f in frames:
        r = coordination(f, **kwargs)
        ts.append(f.timestep)
        mean.append(r.mean)
        mech.append(r.mechanical)
        nr.append(r.n_rattlers)
    return CoordinationSeries(np.asarray(ts, dtype=np.int64), np.asarray(mean, dtype=np.float64),
                              np.asarray(mech, dtype=np.float64), np.asarray(nr, dtype=np.int64))


def coordination_table(result: CoordinationResult, frame=None) -> dict[str, np.ndarray]:
    """Per-particle columns (``id`` when a frame is given, ``cn``, ``cn_mechanical``, ``rattler``).

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[0, 0, 0], [0.9, 0, 0]], [0.5, 0.5], box=([-2] * 3, [3] * 3))
    >>> coordination_table(coordination(f), f)["cn"].tolist()
    [1, 1]
    """
    out = {}
    if frame is not None:
        out["id"] = _as_frame(frame).ids
    out["cn"] = result.per_particle
    out["cn_mechanical"] = result.per_particle_mechanical
    out["rattler"] = result.rattlers
    return out
