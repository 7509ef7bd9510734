"""Packing fraction (packing density): the seed's bounding-box definition and exact
windowed fractions from sphere-cuboid intersection volumes.

All lengths are in the frame's own unit; fractions are dimensionless.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.frame import _as_frame
from . import _packing_kernels as _k
from .contacts import _prepare

__all__ = ["PackingResult", "PackingProfile", "PackingGrid", "packing_fraction",
           "packing_fractions", "packing_along", "packing_sliding", "packing_grid",
           "layer_packing", "bed_bounds", "bed_windows", "sphere_box_volume", "packing_table",
           "disc_rectangle_area", "area_fraction", "area_fractions"]

_N_NODES = 16


def _gauss(n=_N_NODES):
    x, w = np.polynomial.legendre.leggauss(n)
    return np.ascontiguousarray((x + 1.0) / 2.0), np.ascontiguousarray(w / 2.0)


@dataclass(frozen=True)
class PackingResult:
    """Packing fraction of one region.

    Attributes
    ----------
    fraction : float
        Solid volume over region volume (dimensionless).
    solid_volume : float
        Volume of sphere material inside the region (length^3).
    region_volume : float
        Volume of the region (length^3).
    lower, upper : (3,) ndarray of float, length
        Corners of the region.
    definition : str
        ``"bounding-box"`` (the seed's: all particle volume over the box
        enclosing all particles) or ``"window"`` (exact intersection volumes).

    Examples
    --------
    >>> r = PackingResult(0.5, 1.0, 2.0, np.zeros(3), np.ones(3), "window")
    >>> float(r), f"{r:.2f}"
    (0.5, '0.50')
    """

    fraction: float
    solid_volume: float
    region_volume: float
    lower: np.ndarray
    upper: np.ndarray
    definition: str

    def __float__(self) -> float:
        return float(self.fraction)

    def __format__(self, spec: str) -> str:
        return format(self.fraction, spec)


@dataclass(frozen=True)
class PackingProfile:
    """Packing fractions of a set of windows.

    Attributes
    ----------
    fractions : (K,) ndarray of float
    solid_volume, window_volume : (K,) ndarray of float, length^3
    lower, upper : (K, 3) ndarray of float, length
    """

    fractions: np.ndarray
    solid_volume: np.ndarray
    window_volume: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @property
    def centres(self) -> np.ndarray:
        """Window centres (K, 3), length."""
        return 0.5 * (self.lower + self.upper)

    def __len__(self) -> int:
        return int(self.fractions.shape[0])


@dataclass(frozen=True)
class PackingGrid:
    """Packing fractions on a 3-D grid of cuboid cells.

    Attributes
    ----------
    fractions : (nx, ny, nz) ndarray of float
    edges : tuple of 3 ndarrays
        Cell edges along x, y, z (length).
    """

    fractions: np.ndarray
    edges: tuple

    @property
    def centres(self) -> tuple:
        """Cell-centre coordinates along each axis."""
        return tuple(0.5 * (e[1:] + e[:-1]) for e in self.edges)


def _image_shifts(box, lo, hi, rmax) -> np.ndarray:
    """Periodic image translations that may bring a wrapped sphere into [lo, hi]."""
    per = np.array(box.periodic)
    if not per.any():
        return np.zeros((1, 3))
    elo = np.asarray(lo, dtype=np.float64) - rmax
    ehi = np.asarray(hi, dtype=np.float64) + rmax
    corners = np.array([[(elo, ehi)[a][0], (elo, ehi)[b][1], (elo, ehi)[c][2]]
                        for a in (0, 1) for b in (0, 1) for c in (0, 1)])
    s = box.fractional(corners)
    ranges = []
    for k in range(3):
        if per[k]:
            ranges.append(np.arange(math.ceil(s[:, k].min() - 1.0), math.floor(s[:, k].max()) + 1))
        else:
            ranges.append(np.array([0]))
    grid = np.stack(np.meshgrid(*ranges, indexing="ij"), -1).reshape(-1, 3).astype(np.float64)
    return np.ascontiguousarray(grid @ box.matrix.T)


def _rect_volumes(frame, ex, ey, ez, *, nodes=_N_NODES) -> np.ndarray:
    ex, ey, ez = (np.ascontiguousarray(e, dtype=np.float64) for e in (ex, ey, ez))
    out = np.zeros((ex.size - 1, ey.size - 1, ez.size - 1))
    if frame.n_particles == 0:
        return out
    pos = _prepare(frame)[0]
    lo = np.array([ex[0], ey[0], ez[0]])
    hi = np.array([ex[-1], ey[-1], ez[-1]])
    shifts = _image_shifts(frame.box, lo, hi, float(frame.radii.max()))
    x, w = _gauss(nodes)
    _k.grid_volumes(np.ascontiguousarray(pos), frame.radii, shifts, ex, ey, ez, x, w, out)
    return out


def _check_corners(lower, upper):
    lo = np.atleast_2d(np.asarray(lower, dtype=np.float64))
    hi = np.atleast_2d(np.asarray(upper, dtype=np.float64))
    if lo.shape != hi.shape or lo.ndim != 2 or lo.shape[1] != 3:
        raise ValueError(f"window corners must have shape (3,) or (K, 3); got {lo.shape} and {hi.shape}")
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError("window corners must be finite")
    if np.any(hi <= lo):
        raise ValueError(f"window `upper` must exceed `lower` on every axis; got lower={lo.tolist()}, "
                         f"upper={hi.tolist()}")
    return lo, hi


def _check_periodic_width(box, lo, hi):
    if box.is_triclinic:
        return
    for k in np.flatnonzero(box.periodic):
        if np.any(hi[:, k] - lo[:, k] > box.lengths[k] * (1 + 1e-12)):
            raise ValueError(f"a window is wider than the periodic box along {'xyz'[k]} "
                             f"({box.lengths[k]}); space would be counted twice")


def sphere_box_volume(centres, radii, lower, upper) -> np.ndarray:
    """Exact volume of each sphere inside one axis-aligned cuboid.

    Parameters
    ----------
    centres : (N, 3) array_like of float, length
    radii : (N,) array_like of float, length
    lower, upper : (3,) array_like of float, length
        Cuboid corners.

    Returns
    -------
    (N,) ndarray of float, length^3

    Notes
    -----
    The volume is :math:`\\int A(t)\\,dt` of the closed-form area :math:`A`
    of the disc of radius :math:`\\sqrt{r^2 - t^2}` inside the cross-section
    rectangle, integrated over the polar angle :math:`t = r \\sin\\theta`, split
    where the disc meets an edge or corner, by Gauss-Legendre after a
    smoothing substitution with adaptive bisection (error below
    :math:`10^{-12} r^3`; see ``_packing_kernels``). Spheres cut by one plane
    pair use the exact cap formula.

    .. versionadded:: 0.1

    Examples
    --------
    >>> v = sphere_box_volume([[0, 0, 0], [0, 0, 1], [1, 1, 1]], [1, 1, 1], [-1, -1, -1], [1, 1, 1])
    >>> (v / (4 / 3 * np.pi)).round(12).tolist()   # whole, half, one octant
    [1.0, 0.5, 0.125]
    """
    c = np.ascontiguousarray(centres, dtype=np.float64).reshape(-1, 3)
    r = np.ascontiguousarray(radii, dtype=np.float64).reshape(-1)
    if r.shape[0] != c.shape[0]:
        raise ValueError(f"`radii` must have shape (N,) matching `centres` (N={c.shape[0]}); got {r.shape}")
    lo, hi = _check_corners(lower, upper)
    x, w = _gauss()
    out = np.empty(c.shape[0])
    _k.sphere_box_volumes(c, r, lo[0], hi[0], x, w, out)
    return out


def _tilts_within_periodic(box) -> bool:
    """Whether every tilt couples two periodic axes (as LAMMPS requires of the second one).

    The box bounds along the periodic axes then span one period of the lattice the tilted
    edges generate, so an axis-aligned region over them holds every particle once.
    """
    per = box.periodic
    return all(t == 0 or (per[a] and per[b])
               for t, (a, b) in zip(np.asarray(box.tilt, dtype=float), ((0, 1), (0, 2), (1, 2))))


def bed_bounds(frame, *, margin: float = 0.0):
    """The region enclosing all spheres: sphere extents on fixed axes, the box on periodic ones.

    A triclinic box whose tilts couple periodic axes only (``xy`` with x and
    y periodic, and so on) is bounded by its untilted bounds along the
    periodic axes: they span one period of the tilted lattice.

    Parameters
    ----------
    frame : Frame
    margin : float, length, optional
        Added on both sides of the non-periodic extents.

    Returns
    -------
    lower, upper : (3,) ndarray of float, length

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[1, 1, 1], [3, 2, 2]], [0.5, 0.5], box=([0, 0, 0], [4, 4, 4]), )
    >>> lo, hi = bed_bounds(f)
    >>> lo.tolist(), hi.tolist()     # all periodic: the box
    ([0.0, 0.0, 0.0], [4.0, 4.0, 4.0])
    """
    frame = _as_frame(frame)
    box = frame.box
    if frame.n_particles == 0:
        raise ValueError("the frame has no particles; no bed to bound")
    pos = frame.positions
    lo = (pos - frame.radii[:, None]).min(axis=0) - margin
    hi = (pos + frame.radii[:, None]).max(axis=0) + margin
    per = np.array(box.periodic)
    if per.any():
        if box.is_triclinic and not _tilts_within_periodic(box):
            raise ValueError("the bounding-box definition is ambiguous for a triclinic box tilted "
                             "along a bounded axis; give explicit windows")
        lo[per] = box.lo[per]
        hi[per] = box.hi[per]
    return lo, hi


def packing_fraction(frame, window=None, *, exact_bounding_box: bool = False) -> PackingResult:
    """Packing fraction of a frame, in the seed's definition or inside a window.

    Parameters
    ----------
    frame : Frame or (box, positions, radii)
    window : pair of (3,) array_like, optional
        ``(lower, upper)`` corners of an axis-aligned window (length). Spheres
        count with the exact volume they have inside it; along periodic axes
        their images count too. None (default) uses the seed report's
        definition: total particle volume over the volume of the box
        enclosing all particles (sphere extents on fixed axes, the box
        length on periodic axes; see :func:`bed_bounds`).
    exact_bounding_box : bool, optional
        With ``window=None``, integrate exactly over the bounding box instead
        of summing whole sphere volumes (identical except for spheres that
        straddle a periodic boundary in a box shorter than a diameter).

    Returns
    -------
    PackingResult
        Behaves like a float (``float(res)``, ``f"{res:.3f}"``).

    Notes
    -----
    .. math:: \\phi = \\frac{\\sum_i V(B_i \\cap W)}{|W|}

    where :math:`B_i` is ball :math:`i` and :math:`W` the window.

    .. versionadded:: 0.1

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(4)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> sc = Frame(g + 0.5, np.full(64, 0.5), box=[4, 4, 4])
    >>> round(packing_fraction(sc).fraction, 6), round(np.pi / 6, 6)
    (0.523599, 0.523599)
    >>> round(float(packing_fraction(sc, ([0.3, 0.2, 0.1], [2.3, 3.2, 2.1]))), 6)  # whole periods
    0.523599
    """
    frame = _as_frame(frame)
    if window is None:
        lo, hi = bed_bounds(frame)
        vol = float(np.prod(hi - lo))
        if exact_bounding_box:
            solid = float(_rect_volumes(frame, *[np.array([lo[k], hi[k]]) for k in range(3)]).sum())
        else:
            solid = frame.particle_volume
        return PackingResult(solid / vol, solid, vol, lo, hi, "bounding-box")
    try:
        lower, upper = window
    except (TypeError, ValueError):
        raise TypeError("`window` must be a (lower, upper) pair of corner arrays") from None
    lo, hi = _check_corners(lower, upper)
    _check_periodic_width(frame.box, lo, hi)
    solid = float(_rect_volumes(frame, *[np.array([lo[0, k], hi[0, k]]) for k in range(3)]).sum())
    vol = float(np.prod(hi[0] - lo[0]))
    return PackingResult(solid / vol, solid, vol, lo[0], hi[0], "window")


def packing_fractions(frame, lower, upper) -> PackingProfile:
    """Exact packing fractions of K axis-aligned (possibly overlapping) windows.

    The windows' edges form a rectilinear grid; volumes are computed once per
    grid cell and summed per window.

    Parameters
    ----------
    frame : Frame
    lower, upper : (K, 3) array_like of float, length

    Returns
    -------
    PackingProfile

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[1, 1, 1]], [1.0], box=([0, 0, 0], [4, 2, 2]), )
    >>> p = packing_fractions(f, [[0, 0, 0], [1, 0, 0]], [[1, 2, 2], [3, 2, 2]])
    >>> (p.solid_volume / (4 / 3 * np.pi)).round(12).tolist()
    [0.5, 0.5]
    """
    frame = _as_frame(frame)
    lo, hi = _check_corners(lower, upper)
    _check_periodic_width(frame.box, lo, hi)
    edges = [np.unique(np.concatenate([lo[:, k], hi[:, k]])) for k in range(3)]
    cells = _rect_volumes(frame, *edges)
    csum = np.zeros(tuple(s + 1 for s in cells.shape))
    csum[1:, 1:, 1:] = cells.cumsum(0).cumsum(1).cumsum(2)
    a = [np.searchsorted(edges[k], lo[:, k]) for k in range(3)]
    b = [np.searchsorted(edges[k], hi[:, k]) for k in range(3)]
    solid = (csum[b[0], b[1], b[2]] - csum[a[0], b[1], b[2]] - csum[b[0], a[1], b[2]]
             - csum[b[0], b[1], a[2]] + csum[a[0], a[1], b[2]] + csum[a[0], b[1], a[2]]
             + csum[b[0], a[1], a[2]] - csum[a[0], a[1], a[2]])
    vol = np.prod(hi - lo, axis=1)
    return PackingProfile(solid / vol, solid, vol, lo, hi)


def bed_windows(frame, n_windows: int = 3, *, axis: int = 0, bounds=None):
    """Split the bed region into ``n_windows`` equal windows along one axis.

    Parameters
    ----------
    frame : Frame
    n_windows : int, optional
        Default 3 (the seed's start, centre and end regions).
    axis : int, optional
        The spreading direction (default 0, x).
    bounds : pair of (3,) array_like, optional
        Region to split; default :func:`bed_bounds`.

    Returns
    -------
    lower, upper : (K, 3) ndarray of float, length

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[1, 1, 1], [5, 1, 1]], [1.0, 1.0], box=([0, 0, 0], [6, 2, 2]), )
    >>> lo, hi = bed_windows(f)
    >>> lo[:, 0].tolist(), hi[:, 0].tolist()
    ([0.0, 2.0, 4.0], [2.0, 4.0, 6.0])
    """
    frame = _as_frame(frame)
    if int(n_windows) < 1:
        raise ValueError(f"`n_windows` must be >= 1; got {n_windows}")
    lo, hi = bed_bounds(frame) if bounds is None else (np.asarray(bounds[0], float), np.asarray(bounds[1], float))
    e = np.linspace(lo[axis], hi[axis], int(n_windows) + 1)
    lower = np.tile(lo, (int(n_windows), 1))
    upper = np.tile(hi, (int(n_windows), 1))
    lower[:, axis] = e[:-1]
    upper[:, axis] = e[1:]
    return lower, upper


def packing_along(frame, n_windows: int = 3, *, axis: int = 0, bounds=None) -> PackingProfile:
    """Packing fraction in ``n_windows`` equal windows along the bed (start, centre, end).

    Parameters are those of :func:`bed_windows`.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(6)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> sc = Frame(g + 0.5, np.full(216, 0.5), box=[6, 6, 6])
    >>> (packing_along(sc).fractions / (np.pi / 6)).round(12).tolist()
    [1.0, 1.0, 1.0]
    """
    lo, hi = bed_windows(frame, n_windows, axis=axis, bounds=bounds)
    return packing_fractions(frame, lo, hi)


def packing_sliding(frame, width: float, *, step: float | None = None, axis: int = 0,
                    bounds=None) -> PackingProfile:
    """Packing fraction in sliding windows of ``width`` moved by ``step`` along one axis.

    Parameters
    ----------
    frame : Frame
    width : float, length
        Window width along ``axis``.
    step : float, length, optional
        Distance between successive windows (default ``width / 2``).
    axis : int, optional
        Direction of travel (default 0).
    bounds : pair of (3,) array_like, optional
        Region (default :func:`bed_bounds`); windows start at its lower edge
        and stop before passing its upper edge.

    Returns
    -------
    PackingProfile

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(6)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> sc = Frame(g + 0.5, np.full(216, 0.5), box=[6, 6, 6])
    >>> p = packing_sliding(sc, 2.5, step=0.5)
    >>> len(p), bool(np.allclose(p.fractions, np.pi / 6, atol=0.02))
    (8, True)
    """
    frame = _as_frame(frame)
    lo, hi = bed_bounds(frame) if bounds is None else (np.asarray(bounds[0], float), np.asarray(bounds[1], float))
    width = float(width)
    step = width / 2 if step is None else float(step)
    if not (width > 0 and step > 0):
        raise ValueError(f"`width` and `step` must be positive; got {width}, {step}")
    span = hi[axis] - lo[axis]
    if width > span:
        raise ValueError(f"`width` ({width}) exceeds the region length along axis {axis} ({span})")
    n = int(math.floor((span - width) / step * (1 + 1e-12))) + 1
    starts = lo[axis] + step * np.arange(n)
    lower = np.tile(lo, (n, 1))
    upper = np.tile(hi, (n, 1))
    lower[:, axis] = starts
    upper[:, axis] = starts + width
    return packing_fractions(frame, lower, upper)


def packing_grid(frame, shape, *, bounds=None) -> PackingGrid:
    """Packing fraction on a regular 3-D grid of cells covering the region.

    Parameters
    ----------
    frame : Frame
    shape : tuple of 3 int
        Cells along x, y, z.
    bounds : pair of (3,) array_like, optional
        Region (default :func:`bed_bounds`).

    Returns
    -------
    PackingGrid

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(4)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> sc = Frame(g + 0.5, np.full(64, 0.5), box=[4, 4, 4])
    >>> grid = packing_grid(sc, (2, 2, 2))
    >>> bool(np.allclose(grid.fractions, np.pi / 6))
    True
    """
    frame = _as_frame(frame)
    shape = tuple(int(s) for s in shape)
    if len(shape) != 3 or min(shape) < 1:
        raise ValueError(f"`shape` must be 3 positive integers; got {shape}")
    lo, hi = bed_bounds(frame) if bounds is None else (np.asarray(bounds[0], float), np.asarray(bounds[1], float))
    edges = tuple(np.linspace(lo[k], hi[k], shape[k] + 1) for k in range(3))
    vol = _rect_volumes(frame, *edges)
    cell = np.einsum("i,j,k->ijk", *[np.diff(e) for e in edges])
    return PackingGrid(vol / cell, edges)


def layer_packing(frame, base: float, height: float, *, axis: int = 2, bounds=None) -> PackingResult:
    """Packing fraction of the slab between the plate (``base``) and ``base + height``.

    Parameters
    ----------
    frame : Frame
    base : float, length
        Height of the build plate (or previous layer).
    height : float, length
        Slab thickness, e.g. the layer thickness.
    axis : int, optional
        Vertical axis (default 2).
    bounds : pair of (3,) array_like, optional
        Lateral extent (default :func:`bed_bounds`).

    Returns
    -------
    PackingResult

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(4)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> sc = Frame(g + 0.5, np.full(64, 0.5), box=([0, 0, 0], [4, 4, 4]))
    >>> round(layer_packing(sc, 0.0, 2.0).fraction / (np.pi / 6), 12)
    1.0
    """
    frame = _as_frame(frame)
    lo, hi = bed_bounds(frame) if bounds is None else (np.asarray(bounds[0], float).copy(), np.asarray(bounds[1], float).copy())
    lo = lo.copy()
    hi = hi.copy()
    lo[axis] = float(base)
    hi[axis] = float(base) + float(height)
    return packing_fraction(frame, (lo, hi))


def packing_table(profile: PackingProfile) -> dict[str, np.ndarray]:
    """Columns of a :class:`PackingProfile` for ``pandas.DataFrame``.

    Examples
    --------
    >>> p = PackingProfile(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    >>> sorted(packing_table(p))
    ['fraction', 'solid_volume', 'window_volume', 'x_hi', 'x_lo', 'y_hi', 'y_lo', 'z_hi', 'z_lo']
    """
    out = {"fraction": profile.fractions, "solid_volume": profile.solid_volume,
           "window_volume": profile.window_volume}
    for k, a in enumerate("xyz"):
        out[f"{a}_lo"] = profile.lower[:, k]
        out[f"{a}_hi"] = profile.upper[:, k]
    return out


# ---------------------------------------------------------------- 2-D runs (discs)
def _disc_quadrant_area(a, b, r):
    """Area of the disc of radius ``r`` at the origin with ``x < a`` and ``y < b`` (closed form).

    With ``x = r sin t`` the chord at ``x`` is ``2 r cos t`` long; the part below ``y = b`` has
    the antiderivatives below on the arcs where ``r cos t`` exceeds ``|b|`` or not.
    """
    ta = np.arcsin(np.clip(a / r, -1.0, 1.0))
    tb = np.arccos(np.clip(np.abs(b) / r, 0.0, 1.0))

    def chord_below(t):       # integral of (b + r cos t) r cos t dt
        return b * r * np.sin(t) + r * r * (0.5 * t + 0.25 * np.sin(2.0 * t))

    def whole_chord(t):       # integral of 2 r^2 cos^2 t dt
        return r * r * (t + 0.5 * np.sin(2.0 * t))

    def part(g, t0, t1):
        return np.where(t1 > t0, g(np.maximum(t1, t0)) - g(t0), 0.0)

    area = part(chord_below, -tb, np.minimum(ta, tb))
    outer = part(whole_chord, -0.5 * np.pi, np.minimum(ta, -tb)) + part(whole_chord, tb, ta)
    return area + np.where(b >= 0, outer, 0.0)


def disc_rectangle_area(centres, radii, lower, upper) -> np.ndarray:
    """Exact area of each disc inside one axis-aligned rectangle.

    Parameters
    ----------
    centres : (N, 2) array_like of float, length
        Disc centres in the plane.
    radii : (N,) array_like of float, length
    lower, upper : (2,) array_like of float, length
        Rectangle corners.

    Returns
    -------
    (N,) ndarray of float, length^2

    Notes
    -----
    Inclusion-exclusion over the rectangle's corners of the closed-form
    area of a disc below and left of a corner.

    Examples
    --------
    >>> a = disc_rectangle_area([[0, 0], [0, 1], [1, 1]], [1, 1, 1], [-1, -1], [1, 1])
    >>> (a / np.pi).round(12).tolist()       # whole, half, one quarter
    [1.0, 0.5, 0.25]
    """
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    r = np.asarray(radii, dtype=np.float64).reshape(-1)
    if r.shape[0] != c.shape[0]:
        raise ValueError(f"`radii` must have shape (N,) matching `centres` (N={c.shape[0]}); got {r.shape}")
    lo = np.asarray(lower, dtype=np.float64).reshape(2)
    hi = np.asarray(upper, dtype=np.float64).reshape(2)
    if np.any(hi <= lo):
        raise ValueError(f"rectangle `upper` must exceed `lower`; got {lo.tolist()}, {hi.tolist()}")
    x0, x1 = lo[0] - c[:, 0], hi[0] - c[:, 0]
    y0, y1 = lo[1] - c[:, 1], hi[1] - c[:, 1]
    f = _disc_quadrant_area
    out = f(x1, y1, r) - f(x0, y1, r) - f(x1, y0, r) + f(x0, y0, r)
    return np.clip(out, 0.0, np.pi * r * r)


def _plane_axes(frame):
    """(flat axis, the two in-plane axes) of a 2-D run; refuses a 3-D frame or a tilted box."""
    from .dimension import flat_axis
    k = flat_axis(frame)
    if k is None:
        raise ValueError("the frame is not a 2-D run (no axis along which every centre lies in one "
                         "plane, periodic or thinner than a diameter); use packing_fraction")
    if frame.box.is_triclinic:
        raise ValueError("area fractions are computed for orthogonal boxes only; this box is tilted")
    u, v = [a for a in range(3) if a != k]
    return k, u, v


def _disc_areas(frame, lower, upper, u, v) -> np.ndarray:
    """Disc area (with periodic images in the plane) inside each rectangle, (K,)."""
    box = frame.box
    pos = _prepare(frame)[0][:, [u, v]]
    r = frame.radii
    rmax = float(r.max())
    out = np.zeros(lower.shape[0])
    for w in range(lower.shape[0]):
        lo, hi = lower[w, [u, v]], upper[w, [u, v]]
        ranges = []
        for q, a in enumerate((u, v)):
            if box.periodic[a]:
                L = float(box.lengths[a])
                ranges.append(np.arange(math.ceil((lo[q] - rmax - box.hi[a]) / L),
                                        math.floor((hi[q] + rmax - box.lo[a]) / L) + 1) * L)
            else:
                ranges.append(np.zeros(1))
        for du in ranges[0]:
            for dv in ranges[1]:
                c = pos + [du, dv]
                near = np.all((c + r[:, None] > lo) & (c - r[:, None] < hi), axis=1)   # the rest add 0
                if near.any():
                    out[w] += float(disc_rectangle_area(c[near], r[near], lo, hi).sum())
    return out


def area_fraction(frame, window=None) -> PackingResult:
    """Area fraction of a 2-D run: disc area over the area of a rectangle in its plane.

    Parameters
    ----------
    frame : Frame
        A 2-D run (see :func:`bedstruct.analysis.flat_axis`): the particles
        are discs of their radius in the plane.
    window : pair of (3,) array_like, optional
        ``(lower, upper)`` corners of an axis-aligned window (length); the
        coordinate along the flat axis is ignored. Discs count with the
        exact area they have inside it, with their periodic images in the
        plane. None (default): total disc area over the rectangle enclosing
        all discs (disc extents along bounded axes, the box along periodic
        ones; as :func:`bed_bounds` in the plane).

    Returns
    -------
    PackingResult
        ``solid_volume`` and ``region_volume`` hold areas (length^2);
        ``definition`` is ``"bounding-box area"`` or ``"window area"``.

    Raises
    ------
    ValueError
        If the frame is not a 2-D run, has no particles, or its box is tilted.

    Notes
    -----
    .. math:: \\phi_{2D} = \\frac{\\sum_i A(D_i \\cap W)}{|W|}

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Box, Frame
    >>> g = np.stack(np.meshgrid(np.arange(4), np.arange(4), [0.0], indexing="ij"), -1).reshape(-1, 3)
    >>> square = Frame(g + [0.5, 0.5, 0], np.full(16, 0.5), box=Box([0, 0, -0.25], [4, 4, 0.25]))
    >>> round(area_fraction(square).fraction / (np.pi / 4), 12)     # touching discs on a square lattice
    1.0
    """
    frame = _as_frame(frame)
    if frame.n_particles == 0:
        raise ValueError("the frame has no particles")
    k, u, v = _plane_axes(frame)
    if window is None:
        lo, hi = bed_bounds(frame)
        lo[k], hi[k] = frame.box.lo[k], frame.box.hi[k]
        area = float((hi[u] - lo[u]) * (hi[v] - lo[v]))
        solid = float(np.sum(np.pi * frame.radii ** 2))
        return PackingResult(solid / area, solid, area, lo, hi, "bounding-box area")
    try:
        lower, upper = window
    except (TypeError, ValueError):
        raise TypeError("`window` must be a (lower, upper) pair of corner arrays") from None
    prof = area_fractions(frame, np.atleast_2d(lower), np.atleast_2d(upper))
    return PackingResult(float(prof.fractions[0]), float(prof.solid_volume[0]), float(prof.window_volume[0]),
                         prof.lower[0], prof.upper[0], "window area")


def area_fractions(frame, lower, upper) -> PackingProfile:
    """Exact area fractions of K axis-aligned windows in the plane of a 2-D run.

    Parameters
    ----------
    frame : Frame
        A 2-D run (see :func:`bedstruct.analysis.flat_axis`).
    lower, upper : (K, 3) array_like of float, length
        Window corners; the coordinate along the flat axis is ignored.

    Returns
    -------
    PackingProfile
        ``solid_volume`` and ``window_volume`` hold areas (length^2).

    Raises
    ------
    ValueError
        As :func:`area_fraction`, or if a window is wider than the periodic
        box in the plane.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Box, Frame
    >>> g = np.stack(np.meshgrid(np.arange(6), np.arange(4), [0.0], indexing="ij"), -1).reshape(-1, 3)
    >>> square = Frame(g + [0.5, 0.5, 0], np.full(24, 0.5), box=Box([0, 0, -0.25], [6, 4, 0.25]))
    >>> lo, hi = bed_windows(square, 3)
    >>> (area_fractions(square, lo, hi).fractions / (np.pi / 4)).round(12).tolist()
    [1.0, 1.0, 1.0]
    """
    frame = _as_frame(frame)
    if frame.n_particles == 0:
        raise ValueError("the frame has no particles")
    k, u, v = _plane_axes(frame)
    lo = np.atleast_2d(np.asarray(lower, dtype=np.float64)).copy()
    hi = np.atleast_2d(np.asarray(upper, dtype=np.float64)).copy()
    lo[:, k], hi[:, k] = 0.0, 1.0             # the flat axis does not enter
    lo, hi = _check_corners(lo, hi)
    for a in (u, v):
        if frame.box.periodic[a] and np.any(hi[:, a] - lo[:, a] > frame.box.lengths[a] * (1 + 1e-12)):
            raise ValueError(f"a window is wider than the periodic box along {'xyz'[a]} "
                             f"({frame.box.lengths[a]}); area would be counted twice")
    solid = _disc_areas(frame, lo, hi, u, v)
    area = (hi[:, u] - lo[:, u]) * (hi[:, v] - lo[:, v])
    lo[:, k], hi[:, k] = frame.box.lo[k], frame.box.hi[k]
    return PackingProfile(solid / area, solid, area, lo, hi)
