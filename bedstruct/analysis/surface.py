"""Top surface of a powder bed: height maps, areal roughness, profiles and layer heights.

Heights and roughness values are in the frame's length unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.frame import _as_frame
from . import _packing_kernels as _k

__all__ = ["SurfaceResult", "Roughness", "surface_roughness", "surface_height_map",
           "height_profile", "bed_height", "layer_heights", "grounded_particles",
           "largest_cluster"]


@dataclass(frozen=True)
class Roughness:
    """Areal roughness parameters (ISO 25178-2) of a height map (length, except skewness/kurtosis).

    Attributes
    ----------
    sa : float
        Arithmetic mean height ``mean |z - zbar|``.
    sq : float
        Root mean square height ``sqrt(mean (z - zbar)^2)``.
    sz : float
        Maximum height ``max z - min z`` (highest peak plus deepest pit).
    ssk : float
        Skewness ``mean (z - zbar)^3 / sq^3`` (dimensionless).
    sku : float
        Kurtosis ``mean (z - zbar)^4 / sq^4`` (dimensionless).
    mean_height : float
        ``zbar``.
    """

    sa: float
    sq: float
    sz: float
    ssk: float
    sku: float
    mean_height: float


def surface_roughness(heights) -> Roughness:
    """ISO 25178-2 areal parameters Sa, Sq, Sz, Ssk, Sku of a height map (NaNs ignored).

    Examples
    --------
    >>> r = surface_roughness([[0.0, 2.0], [0.0, 2.0]])
    >>> r.sa, r.sq, r.sz, r.ssk
    (1.0, 1.0, 2.0, 0.0)
    """
    z = np.asarray(heights, dtype=np.float64).reshape(-1)
    z = z[np.isfinite(z)]
    if z.size == 0:
        nan = float("nan")
        return Roughness(nan, nan, nan, nan, nan, nan)
    zbar = float(z.mean())
    dev = z - zbar
    sq = float(np.sqrt(np.mean(dev ** 2)))
    with np.errstate(invalid="ignore", divide="ignore"):
        ssk = float(np.mean(dev ** 3) / sq ** 3) if sq > 0 else 0.0
        sku = float(np.mean(dev ** 4) / sq ** 4) if sq > 0 else float("nan")
    return Roughness(float(np.mean(np.abs(dev))), sq, float(z.max() - z.min()), ssk, sku, zbar)


@dataclass(frozen=True)
class SurfaceResult:
    """Top-surface height map and its statistics.

    Attributes
    ----------
    heights : (nx, ny) ndarray of float, length
        Surface height at each node (NaN where no particle lies above the
        node and no ``base`` was given; ``base`` there otherwise).
    x, y : (nx,), (ny,) ndarray of float, length
        Node coordinates along the two lateral axes.
    covered : (nx, ny) ndarray of bool
        Nodes with a particle above them.
    roughness : Roughness
        Areal parameters of ``heights``.
    uncovered_fraction : float
        Fraction of nodes with no particle above them (bare plate).
    probe_radius : float, length
        0 for the highest-cap surface.
    base : float or None, length
        Plate height used for uncovered nodes.
    """

    heights: np.ndarray
    x: np.ndarray
    y: np.ndarray
    covered: np.ndarray
    roughness: Roughness
    uncovered_fraction: float
    probe_radius: float
    base: float | None

    @property
    def sa(self) -> float:
        """Arithmetic mean height deviation (length)."""
        return self.roughness.sa

    @property
    def sq(self) -> float:
        """RMS height deviation (length)."""
        return self.roughness.sq

    @property
    def sz(self) -> float:
        """Maximum height (length)."""
        return self.roughness.sz

    @property
    def ssk(self) -> float:
        """Skewness (dimensionless)."""
        return self.roughness.ssk

    @property
    def mean_height(self) -> float:
        """Mean surface height (length)."""
        return self.roughness.mean_height


def _lateral_grid(frame, axis, spacing, bounds):
    box = frame.box
    if bounds is not None:
        lo, hi = float(bounds[0]), float(bounds[1])
        per = False
    elif box.periodic[axis] and not box.is_triclinic:
        lo, hi = float(box.lo[axis]), float(box.hi[axis])
        per = True
    else:
        c = frame.positions[:, axis]
        lo, hi = float((c - frame.radii).min()), float((c + frame.radii).max())
        per = False
    length = hi - lo
    if not length > 0:
        raise ValueError(f"lateral extent along axis {axis} is empty ({lo} to {hi})")
    n = max(1, int(round(length / spacing)) if per else int(math.ceil(length / spacing - 1e-9)))
    return lo, length / n, n, per


def surface_height_map(frame, *, spacing: float | None = None, probe_radius: float = 0.0,
                       bounds=None, base: float | None = None, vertical: int = 2
                       ) -> SurfaceResult:
    """Height map of the top surface: highest sphere cap (or probe sphere) over a grid.

    Parameters
    ----------
    frame : Frame
    spacing : float, length, optional
        Grid spacing; default half the median radius.
    probe_radius : float, length, optional
        Radius of a probe sphere lowered vertically onto the bed; the height
        is that of its lowest point, which bridges gaps narrower than the
        probe. Default 0: the highest particle cap above each node.
    bounds : ((lo0, hi0), (lo1, hi1)), optional
        Lateral extents of the grid along the two horizontal axes; default
        the box along periodic axes and the sphere extents otherwise.
    base : float, length, optional
        Plate height: nodes with no particle above them take this height
        (otherwise NaN and left out of the roughness).
    vertical : int, optional
        Vertical axis (default 2, z).

    Returns
    -------
    SurfaceResult

    Notes
    -----
    Height at node :math:`(x, y)`:
    :math:`h = \\max_i \\left[z_i + \\sqrt{(r_i + p)^2 - \\rho_i^2}\\right] - p`,
    over spheres whose grown footprint covers the node (:math:`\\rho_i` the
    lateral distance). Roughness follows ISO 25178-2.

    .. versionadded:: 0.1

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[0.5, 0.5, 0.5], [1.5, 0.5, 1.0]], [0.5, 0.5], box=([0, 0, 0], [2, 1, 3]))
    >>> s = surface_height_map(f, spacing=0.5)
    >>> s.heights.round(3).tolist()
    [[0.854, 0.854], [0.854, 0.854], [1.354, 1.354], [1.354, 1.354]]
    >>> round(s.sa, 3), round(s.sz, 3), s.uncovered_fraction
    (0.25, 0.5, 0.0)
    """
    frame = _as_frame(frame)
    if frame.n_particles == 0:
        raise ValueError("the frame has no particles; no surface to map")
    if vertical not in (0, 1, 2):
        raise ValueError(f"`vertical` must be 0, 1 or 2; got {vertical!r}")
    lat = [a for a in range(3) if a != vertical]
    spacing = 0.5 * float(np.median(frame.radii)) if spacing is None else float(spacing)
    if not spacing > 0:
        raise ValueError(f"`spacing` must be positive; got {spacing}")
    p = float(probe_radius)
    if p < 0:
        raise ValueError(f"`probe_radius` must be >= 0; got {p}")
    bx = by = None
    if bounds is not None:
        bx, by = bounds
    x0, dx, nx, px = _lateral_grid(frame, lat[0], spacing, bx)
    y0, dy, ny, py = _lateral_grid(frame, lat[1], spacing, by)
    pos = frame.box.wrap(frame.positions) if any(frame.box.periodic) else frame.positions
    out = np.full((nx, ny), -np.inf)
    _k.cap_height_map(np.ascontiguousarray(pos), frame.radii, p, x0, y0, dx, dy, px, py,
                      lat[0], lat[1], vertical, out)
    covered = np.isfinite(out)
    if base is not None:
        heights = np.where(covered, out, float(base))
    else:
        heights = np.where(covered, out, np.nan)
    xs = x0 + (np.arange(nx) + 0.5) * dx
    ys = y0 + (np.arange(ny) + 0.5) * dy
    return SurfaceResult(heights=heights, x=xs, y=ys, covered=covered,
                         roughness=surface_roughness(heights),
                         uncovered_fraction=float(1.0 - covered.mean()), probe_radius=p,
                         base=None if base is None else float(base))


def height_profile(surface: SurfaceResult, *, axis: int = 0, statistic: str = "mean"):
    """Height profile along one lateral axis of a height map.

    Parameters
    ----------
    surface : SurfaceResult
    axis : {0, 1}, optional
        0: along the first lateral axis (x, the spreading direction when
        vertical is z), reducing over the second; 1: the reverse.
    statistic : {"mean", "median", "max", "min"}, optional
        Reduction across the other axis (NaNs ignored).

    Returns
    -------
    coords, heights : (n,) ndarray of float, length

    Examples
    --------
    >>> s = SurfaceResult(np.array([[1.0, 3.0], [2.0, 2.0]]), np.array([0.0, 1.0]),
    ...                   np.array([0.0, 1.0]), np.ones((2, 2), bool), surface_roughness([0]), 0.0, 0.0, None)
    >>> height_profile(s)[1].tolist(), height_profile(s, statistic="max")[1].tolist()
    ([2.0, 2.0], [3.0, 2.0])
    """
    funcs = {"mean": np.nanmean, "median": np.nanmedian, "max": np.nanmax, "min": np.nanmin}
    if statistic not in funcs:
        raise ValueError(f"`statistic` must be one of {sorted(funcs)}; got {statistic!r}")
    if axis not in (0, 1):
        raise ValueError(f"`axis` must be 0 or 1; got {axis!r}")
    h = surface.heights
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # all-NaN columns -> NaN
        prof = funcs[statistic](h, axis=1 - axis)
    return (surface.x if axis == 0 else surface.y), prof


def bed_height(frame, base: float, **kwargs) -> float:
    """Mean height of the top surface above the plate (length).

    Uncovered nodes count with height ``base`` (zero thickness).

    Parameters
    ----------
    frame : Frame
    base : float, length
        Plate height.
    **kwargs
        Passed to :func:`surface_height_map` (``spacing``, ``bounds``,
        ``probe_radius``).

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[0.5, 0.5, 0.5]], [0.5], box=([0, 0, 0], [1, 1, 2]))
    >>> round(bed_height(f, 0.0, spacing=0.01), 2)   # (pi/4) 0.5 + (2/3) pi 0.5^3 = 0.6545
    0.65
    """
    s = surface_height_map(frame, base=base, **kwargs)
    return float(np.mean(s.heights) - float(base))


def layer_heights(frames, base: float, **kwargs) -> np.ndarray:
    """Bed height above ``base`` of each frame (e.g. one frame after each layer), length.

    Examples
    --------
    >>> from bedstruct import Frame
    >>> fs = [Frame([[0.5, 0.5, z]], [0.5], box=([0, 0, 0], [1, 1, 3])) for z in (0.5, 1.5)]
    >>> layer_heights(fs, 0.0, spacing=0.01).round(2).tolist()
    [0.65, 1.44]
    """
    return np.array([bed_height(f, base, **kwargs) for f in frames], dtype=np.float64)


def grounded_particles(frame, base: float, *, vertical: int = 2, tolerance: float | None = None
                       ) -> np.ndarray:
    """Particles that rest on the base through a chain of touching particles.

    A particle is grounded when it touches the plane ``z = base`` (its lowest
    point at most ``tolerance`` above it) or touches a grounded particle
    (centre distance at most ``r_i + r_j + tolerance``). Particles thrown up
    by a fast blade, or falling, are not; the spreading workflow waits for
    them to land before it reinserts its pile. In a heap sheared fast enough
    to dilate, neighbours can lie further apart than the tolerance, so parts
    of a flowing heap may count as not grounded: a static test.

    Parameters
    ----------
    frame : Frame
    base : float, length
        Height of the plate (along ``vertical``) the powder rests on.
    vertical : int, optional
        Vertical axis (default z).
    tolerance : float, length, optional
        Gap still counted as touching (default 5 % of the median diameter,
        so that particles written with rounding or just separating still
        count).

    Returns
    -------
    (N,) ndarray of bool

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[0.5, 0.5, 0.5], [0.5, 0.5, 1.5], [0.5, 0.5, 4.0]], [0.5, 0.5, 0.5],
    ...           box=([0, 0, 0], [1, 1, 6]))
    >>> grounded_particles(f, 0.0).tolist()   # a column of two, one particle in flight
    [True, True, False]
    """
    frame = _as_frame(frame)
    n = frame.n_particles
    if vertical not in (0, 1, 2):
        raise ValueError(f"`vertical` must be 0, 1 or 2; got {vertical!r}")
    if n == 0:
        return np.zeros(0, dtype=bool)
    label, tol = _touching_clusters(frame, tolerance)
    on_base = frame.positions[:, vertical] - frame.radii <= float(base) + tol
    return np.isin(label, np.unique(label[on_base]))


def largest_cluster(frame, *, tolerance: float | None = None) -> np.ndarray:
    """The particles of the largest cluster of touching particles.

    A pile's particles touch one another; clumps falling off a ledge or
    thrown ahead of a blade form other, smaller clusters. Measuring a pile on
    its largest cluster keeps them from setting its base.

    Parameters
    ----------
    frame : Frame
    tolerance : float, length, optional
        Gap still counted as touching (default 5 % of the median diameter).

    Returns
    -------
    (N,) ndarray of bool

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[0.5, 0.5, 0.5], [0.5, 0.5, 1.5], [0.5, 0.5, 2.5], [0.5, 0.5, 4.0]],
    ...           [0.5] * 4, box=([0, 0, 0], [1, 1, 6]))
    >>> largest_cluster(f).tolist()
    [True, True, True, False]
    """
    frame = _as_frame(frame)
    if frame.n_particles == 0:
        return np.zeros(0, dtype=bool)
    label, _ = _touching_clusters(frame, tolerance)
    return label == np.argmax(np.bincount(label))


def _touching_clusters(frame, tolerance) -> tuple[np.ndarray, float]:
    """Cluster label of every particle (touching within the tolerance) and the tolerance."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from .contacts import find_contacts
    n = frame.n_particles
    tol = 0.1 * float(np.median(frame.radii)) if tolerance is None else float(tolerance)
    if not (math.isfinite(tol) and tol >= 0):
        raise ValueError(f"`tolerance` must be finite and >= 0; got {tolerance!r}")
    c = find_contacts(frame, tolerance=tol, parallel=False)
    graph = coo_matrix((np.ones(len(c.i)), (c.i, c.j)), shape=(n, n))
    return connected_components(graph, directed=False)[1], tol
