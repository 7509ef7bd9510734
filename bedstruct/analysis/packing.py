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
           "layer_packing", "bed_bounds", "bed_windows", "sphere_box_volume", "packing_table"]

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


def bed_bounds(frame, *, margin: float = 0.0):
    """The region enclosing all spheres: sphere extents on fixed axes, the box on periodic ones.

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
        if box.is_triclinic:
            raise ValueError("the bounding-box definition is ambiguous for periodic triclinic "
                             "boxes; give explicit windows")
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
