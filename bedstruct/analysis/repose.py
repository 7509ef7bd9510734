"""Angle of repose: static (a pile's flanks) and dynamic (the heap in front of a blade).

The free surface is extracted as a height profile along one horizontal axis
from the top-surface height map (:func:`bedstruct.analysis.surface_height_map`);
the steady part of each flank (between fractions of the pile height, excluding
the toe and the crest) is fitted with a robust Theil-Sen line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.frame import _as_frame
from .surface import height_profile, surface_height_map

__all__ = ["FlankFit", "ReposeResult", "angle_of_repose", "PileAngle", "pile_angle", "dynamic_angle_of_repose",
           "heap_front_angle", "ReposeSeries", "dynamic_repose_series", "free_surface_profile"]


@dataclass(frozen=True)
class FlankFit:
    """Robust line fitted to one flank of a pile.

    Attributes
    ----------
    slope, intercept : float
        ``h = intercept + slope * x`` (dimensionless, length).
    angle_deg, angle_std_deg : float
        ``atan(|slope|)`` and its standard uncertainty (degrees), from the
        Theil-Sen 95 % slope interval divided by 2 x 1.96.
    x, h : (m,) ndarray of float, length
        The profile points used.
    """

    slope: float
    intercept: float
    angle_deg: float
    angle_std_deg: float
    x: np.ndarray
    h: np.ndarray

    @property
    def n_points(self) -> int:
        """Number of profile points fitted."""
        return int(self.x.shape[0])


@dataclass(frozen=True)
class ReposeResult:
    """Angle of repose of a pile or heap.

    Attributes
    ----------
    angle_deg : float
        Mean of the fitted flank angles (degrees).
    angle_std_deg : float
        Standard uncertainty of that mean from the flank fits (degrees).
    left_deg, right_deg : float
        Angle of the flank at lower / higher coordinate (NaN if not fitted).
    left_std_deg, right_std_deg : float
    left, right : FlankFit or None
    profile_x, profile_h : (n,) ndarray of float, length
        The free-surface profile.
    base, top : float, length
        Heights taken as the toe level and the crest of the pile.

    Notes
    -----
    ``angle_std_deg`` is the fit uncertainty of one pile's mean angle, not
    a scatter between piles: a spread needs replicates. How much the two
    flanks of this pile differ is :attr:`flank_difference_deg`.
    """

    angle_deg: float
    angle_std_deg: float
    left_deg: float
    right_deg: float
    left_std_deg: float
    right_std_deg: float
    left: FlankFit | None
    right: FlankFit | None
    profile_x: np.ndarray
    profile_h: np.ndarray
    base: float
    top: float

    @property
    def flank_difference_deg(self) -> float:
        """``|left_deg - right_deg|`` (degrees; NaN unless both flanks were fitted)."""
        return abs(self.left_deg - self.right_deg)


def free_surface_profile(frame, *, axis: int = 0, vertical: int = 2, spacing: float | None = None,
                         statistic: str = "max", bounds=None):
    """Free-surface height profile along ``axis`` (length).

    ``statistic="max"`` gives the silhouette seen from the side (what a
    camera or the disk of a repose tester sees; right for cones and wedges);
    ``"median"`` is more robust for a wedge that is uniform across the width.

    Returns
    -------
    x, h : (n,) ndarray of float, length

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[0.5, 0.5, 0.5], [1.5, 0.5, 1.5]], [0.5, 0.5], box=([0, 0, 0], [2, 1, 3]))
    >>> free_surface_profile(f, spacing=0.5)[1].round(3).tolist()
    [0.854, 0.854, 1.854, 1.854]
    """
    frame = _as_frame(frame)
    lat = [a for a in range(3) if a != vertical]
    if axis not in lat:
        raise ValueError(f"`axis` ({axis}) must be a horizontal axis, not the vertical ({vertical})")
    s = surface_height_map(frame, spacing=spacing, vertical=vertical, bounds=bounds)
    return height_profile(s, axis=lat.index(axis), statistic=statistic)


def _fit_flank(x, h, peak, step, q, lo, hi, min_points):
    """Walk from the peak by ``step`` (-1 left, +1 right) to the toe and fit the band."""
    from scipy import stats
    n = x.shape[0]
    k = peak
    idx = []
    while 0 <= k < n:
        if np.isfinite(q[k]):
            if q[k] < lo:
                break
            if q[k] <= hi:
                idx.append(k)
        k += step
    if len(idx) < min_points:
        return None
    idx = np.sort(np.asarray(idx))
    # a flank descends through the band; points that stay at one level are a flat top (a
    # cohesive block whose crest is one bump higher), whose fit would read ~0 deg
    if np.ptp(q[idx]) < 0.5 * (hi - lo):
        return None
    xs, hs = x[idx], h[idx]
    slope, icpt, s_lo, s_hi = stats.theilslopes(hs, xs, alpha=0.95)
    std = (s_hi - s_lo) / (2 * 1.959964)
    ang = math.degrees(math.atan(abs(slope)))
    ang_std = math.degrees(std / (1 + slope * slope))
    return FlankFit(float(slope), float(icpt), ang, ang_std, xs, hs)


def _combine(left, right, x, h, base, top) -> ReposeResult:
    fl = [f for f in (left, right) if f is not None]
    nan = float("nan")
    if fl:
        ang = float(np.mean([f.angle_deg for f in fl]))
        std = float(np.sqrt(np.sum([f.angle_std_deg ** 2 for f in fl])) / len(fl))
    else:
        ang = std = nan
    return ReposeResult(
        angle_deg=ang, angle_std_deg=std,
        left_deg=left.angle_deg if left else nan, right_deg=right.angle_deg if right else nan,
        left_std_deg=left.angle_std_deg if left else nan,
        right_std_deg=right.angle_std_deg if right else nan,
        left=left, right=right, profile_x=x, profile_h=h, base=float(base), top=float(top))


def _check_range(fit_range):
    lo, hi = (float(v) for v in fit_range)
    if not 0.0 <= lo < hi <= 1.0:
        raise ValueError(f"`fit_range` must satisfy 0 <= low < high <= 1; got {fit_range!r}")
    return lo, hi


def angle_of_repose(frame, *, axis: int = 0, vertical: int = 2, spacing: float | None = None,
                    statistic: str = "max", fit_range=(0.2, 0.8), base: float | None = None,
                    flanks: str = "both", bounds=None, min_points: int = 5) -> ReposeResult:
    """Static angle of repose of a pile from particle positions.

    Parameters
    ----------
    frame : Frame
        The settled pile.
    axis : int, optional
        Horizontal axis along which the flanks descend (default 0, x).
    vertical : int, optional
        Vertical axis (default 2).
    spacing : float, length, optional
        Grid spacing of the height map (default half the median radius).
    statistic : {"max", "median", "mean"}, optional
        Reduction of the height map across the other horizontal axis (see
        :func:`free_surface_profile`).
    fit_range : (2,) tuple of float, optional
        Fractions of the pile height ``(h - base)/(top - base)`` that bound
        the steady part of each flank (default 0.2 to 0.8: the toe and the
        rounded crest are left out).
    base : float, length, optional
        Toe level (default the lowest point of the profile).
    flanks : {"both", "left", "right"}, optional
        Which flanks to fit.
    bounds : optional
        Lateral bounds of the height map (see :func:`surface_height_map`).
    min_points : int, optional
        Minimum number of profile points in a flank's band (default 5).

    Returns
    -------
    ReposeResult

    Notes
    -----
    From the crest each flank is followed outwards until the profile drops
    below the lower fraction; a flank whose points do not descend through at
    least half of the band is not fitted (a flat-topped block has no angle of
    repose: NaN, not ~0 deg); the points inside the band are fitted by the
    Theil-Sen estimator [1]_ (median of pairwise slopes), insensitive to the
    single-particle bumps of the surface. The angle is
    :math:`\\theta = \\arctan|s|`.

    References
    ----------
    .. [1] P. K. Sen, "Estimates of the regression coefficient based on
       Kendall's tau", J. Am. Stat. Assoc. 63 (1968) 1379-1389,
       doi:10.1080/01621459.1968.10480934.

    .. versionadded:: 0.1

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> x = np.arange(0.25, 40, 0.5)                   # a row of spheres on a 30 deg wedge
    >>> z = np.clip(10 - np.tan(np.radians(30)) * abs(x - 20), 0, None)
    >>> f = Frame(np.c_[x, np.zeros_like(x), z], np.full(x.size, 0.25), box=([0, -1, -1], [40, 1, 12]))
    >>> res = angle_of_repose(f, spacing=0.1)
    >>> round(res.left_deg, 1), round(res.right_deg, 1)
    (30.0, 30.0)
    """
    frame = _as_frame(frame)
    lo, hi = _check_range(fit_range)
    if flanks not in ("both", "left", "right"):
        raise ValueError(f"`flanks` must be 'both', 'left' or 'right'; got {flanks!r}")
    x, h = free_surface_profile(frame, axis=axis, vertical=vertical, spacing=spacing,
                                statistic=statistic, bounds=bounds)
    b = float(np.nanmin(h)) if base is None else float(base)
    top = float(np.nanmax(h))
    if not top > b:
        raise ValueError("the profile is flat (no pile above the base)")
    q = (h - b) / (top - b)
    peak = int(np.nanargmax(h))
    left = _fit_flank(x, h, peak, -1, q, lo, hi, min_points) if flanks in ("both", "left") else None
    right = _fit_flank(x, h, peak, 1, q, lo, hi, min_points) if flanks in ("both", "right") else None
    return _combine(left, right, x, h, b, top)


@dataclass(frozen=True)
class PileAngle:
    """The angle of repose of a pile, and which particles and base it was measured on.

    Attributes
    ----------
    repose : ReposeResult
        The fit: ``angle_deg`` (mean of the flanks), ``angle_std_deg`` (its
        fit uncertainty, 1 sigma), ``left_deg``, ``right_deg``,
        ``flank_difference_deg``, the profile.
    base : float, length
        Plate level the pile stands on.
    base_found : bool
        True when ``base`` was found from the pile, False when given.
    n_particles : int
        Particles the profile was taken from.
    n_left_out : int
        Particles left out (other clusters, below the plate, outside ``bounds``).
    shape : {"wedge", "cone"}
        How the free surface was taken: the median height across the other
        horizontal axis (a wedge) or the silhouette, the highest point across
        it (a cone).
    """

    repose: ReposeResult
    base: float
    base_found: bool
    n_particles: int
    n_left_out: int
    shape: str = "wedge"

    @property
    def angle_deg(self) -> float:
        """Mean angle of the fitted flanks (degrees)."""
        return self.repose.angle_deg

    @property
    def angle_std_deg(self) -> float:
        """Fit uncertainty (1 sigma) of :attr:`angle_deg` (degrees); not a scatter between piles."""
        return self.repose.angle_std_deg


def pile_angle(frame, *, axis: int = 0, base: float | None = None, bounds=None,
               flanks: str = "both", shape: str = "auto") -> PileAngle:
    """Static angle of repose of a settled pile: the one measurement of a pile.

    ``bedstruct report`` uses it, and a repose run measures its piles the
    same way (plate level and ledge given from its configuration).

    Parameters
    ----------
    frame : Frame
        The settled pile (length unit of the dump).
    axis : int, optional
        Horizontal axis along which the flanks descend (default 0, x).
    base : float, length, optional
        Plate level (height of the plate the pile stands on). Default: found
        as the 5th percentile of the particle bottoms ``z - r`` of the
        largest cluster of touching particles (the layer resting on the
        plate); clumps still falling, in other clusters, are left out.
    bounds : ((lo0, hi0), (lo1, hi1)), optional
        Lateral extent (x, y) of the pile (e.g. a ledge plus a pad):
        particles centred outside it along ``axis`` are left out, and the
        height map spans it (:func:`bedstruct.analysis.surface_height_map`).
        Default: the pile's particle centres plus the largest radius, and
        the box across ``axis`` when that direction is periodic.
    flanks : {"both", "left", "right"}, optional
        Flanks to fit (one for a wedge against a wall).
    shape : {"auto", "wedge", "cone"}, optional
        ``"wedge"``: a pile uniform across the other horizontal axis (a
        slot between side walls, a periodic box); its free surface is the
        median height across that axis. ``"cone"``: a heap that falls off in
        every direction; its free surface is the silhouette, the highest
        point across (what a side camera sees; the median across a cone lies
        below its flank line and gives an angle ~5 deg too low). ``"auto"``
        (default): a wedge when the other axis is periodic; otherwise a cone
        when the silhouette across the other axis has flanks at least half
        as steep as along ``axis``, else a wedge.

    Returns
    -------
    PileAngle

    Raises
    ------
    ValueError
        Fewer than 10 particles stand on the plate, or no pile (a flat profile).

    Notes
    -----
    Particles centred above ``base - r`` form the pile; its free surface is
    the median height (a wedge) or the highest point (a cone) across the
    other horizontal axis of the top-surface map on a grid of half the
    median radius, and each flank is fitted between 20 % and 80 % of the
    pile height (:func:`angle_of_repose`, ``statistic="median"`` or
    ``"max"``). The ``±`` of one pile is the fit uncertainty of
    the mean of its flanks; a scatter between piles needs replicates.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> g = np.stack(np.meshgrid(np.arange(80) * 0.5 + 0.25, [0.25], np.arange(24) * 0.5 + 0.25,
    ...                          indexing="ij"), -1).reshape(-1, 3)
    >>> heap = g[g[:, 2] <= 12 - np.tan(np.radians(30)) * abs(g[:, 0] - 20)]
    >>> p = pile_angle(Frame(heap, np.full(len(heap), 0.26), box=([0, 0, 0], [40, 0.5, 14])))
    >>> round(p.angle_deg), round(p.base, 2), p.base_found
    (30, 0.0, True)
    """
    from .surface import largest_cluster

    frame = _as_frame(frame)
    if axis not in (0, 1):
        raise ValueError(f"`axis` must be a horizontal axis, 0 or 1; got {axis!r}")
    if shape not in ("auto", "wedge", "cone"):
        raise ValueError(f"`shape` must be 'auto', 'wedge' or 'cone'; got {shape!r}")
    n0 = frame.n_particles
    pile = frame
    found = base is None
    if found:
        if n0 == 0:
            raise ValueError("the frame has no particles: no pile to measure")
        cluster = largest_cluster(frame)
        if cluster.sum() >= 0.5 * n0:
            pile = frame.select(cluster)
        base = float(np.percentile(pile.positions[:, 2] - pile.radii, 5))
    pile = pile.select(pile.positions[:, 2] > float(base) - pile.radii)
    if bounds is not None:
        lo, hi = (float(v) for v in bounds[axis])
        along = pile.positions[:, axis]
        pile = pile.select((along > lo) & (along < hi))
    if pile.n_particles < 10:
        raise ValueError(f"only {pile.n_particles} particles stand on the plate at {base:.6g}: no pile to measure")
    if bounds is None:
        # the pile's own extent (not the box's empty ends); across it, the box when periodic
        pad = float(pile.radii.max())
        ext = []
        for a in (0, 1):
            c = pile.positions[:, a]
            if a != axis and pile.box.periodic[a]:
                ext.append((float(pile.box.lo[a]), float(pile.box.hi[a])))
            else:
                ext.append((float(c.min()) - pad, float(c.max()) + pad))
        bounds = tuple(ext)
    spacing = 0.5 * float(np.median(pile.radii))
    res = None
    if shape == "auto":
        shape, silhouette = (("wedge", None) if pile.box.periodic[1 - axis] else
                             _pile_shape(pile, axis, float(base), bounds, spacing))
        if shape == "cone" and flanks == "both":
            res = silhouette            # the fit below, already made to judge the shape
    if res is None:
        res = angle_of_repose(pile, axis=axis, base=float(base), flanks=flanks, bounds=bounds,
                              statistic="median" if shape == "wedge" else "max", spacing=spacing)
    return PileAngle(res, float(base), found, pile.n_particles, n0 - pile.n_particles, shape)


def _pile_shape(pile, axis: int, base: float, bounds, spacing: float):
    """``("cone", fit)`` when the pile's silhouette across the other horizontal axis has flanks
    at least half as steep as its silhouette along ``axis``, else ``("wedge", None)``; ``fit``
    is the silhouette's :func:`angle_of_repose` along ``axis`` (both flanks)."""
    fits = []
    for a in (axis, 1 - axis):
        try:
            fits.append(angle_of_repose(pile, axis=a, base=base, bounds=bounds, statistic="max",
                                        spacing=spacing))
        except ValueError:      # a flat profile: no flank that way
            return "wedge", None
    along, across = (r.angle_deg for r in fits)
    if np.isfinite(along) and np.isfinite(across) and across >= 0.5 * along:
        return "cone", fits[0]
    return "wedge", None


def dynamic_angle_of_repose(frame, blade_position: float, *, direction: int = 1, axis: int = 0,
                            vertical: int = 2, bed_level: float | None = None,
                            max_distance: float | None = None, spacing: float | None = None,
                            statistic: str = "max", fit_range=(0.2, 0.8), min_points: int = 5
                            ) -> ReposeResult:
    """Dynamic angle of the heap pushed by a moving blade, relative to the bed.

    Parameters
    ----------
    frame : Frame
        A frame during spreading.
    blade_position : float, length
        Coordinate of the blade's front face along ``axis``.
    direction : {1, -1}, optional
        Direction of travel; the heap lies on this side of the blade.
    axis, vertical : int, optional
        Spreading and vertical axes (default x, z).
    bed_level : float, length, optional
        Height of the bed surface ahead of the heap; default the 10th
        percentile of the profile ahead of the blade.
    max_distance : float, length, optional
        Only this far ahead of the blade (default: to the last particle).
    spacing, statistic, fit_range, min_points
        As :func:`angle_of_repose`.

    Returns
    -------
    ReposeResult
        ``angle_deg`` is the angle of the heap's front flank (the flank on the
        side of travel, reported as ``right`` for ``direction=1`` and ``left``
        for ``-1``).

    .. versionadded:: 0.1

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> x = np.arange(5.25, 30, 0.5)            # heap ahead of a blade at x = 5, 35 deg
    >>> z = 1 + np.clip(8 - np.tan(np.radians(35)) * (x - 5), 0, None)
    >>> f = Frame(np.c_[x, np.zeros_like(x), z], np.full(x.size, 0.25), box=([0, -1, 0], [40, 1, 12]))
    >>> round(dynamic_angle_of_repose(f, 5.0, spacing=0.1).angle_deg, 1)
    35.0
    """
    frame = _as_frame(frame)
    lo, hi = _check_range(fit_range)
    if direction not in (1, -1):
        raise ValueError(f"`direction` must be 1 or -1; got {direction!r}")
    rel = (frame.positions[:, axis] - float(blade_position)) * direction
    sel = rel > 0
    if max_distance is not None:
        sel &= rel < float(max_distance)
    if not sel.any():
        raise ValueError("no particles ahead of the blade")
    sub = frame.select(sel)
    x, h = free_surface_profile(sub, axis=axis, vertical=vertical, spacing=spacing, statistic=statistic)
    ahead = (x - float(blade_position)) * direction > 0
    x, h = x[ahead], h[ahead]
    b = float(np.nanpercentile(h, 10)) if bed_level is None else float(bed_level)
    top = float(np.nanmax(h))
    if not top > b:
        raise ValueError("no heap above the bed level ahead of the blade")
    q = (h - b) / (top - b)
    peak = int(np.nanargmax(h))
    front = _fit_flank(x, h, peak, direction, q, lo, hi, min_points)
    left, right = (None, front) if direction == 1 else (front, None)
    return _combine(left, right, x, h, b, top)


@dataclass(frozen=True)
class ReposeSeries:
    """Dynamic angle of repose per frame.

    Attributes
    ----------
    timesteps : (F,) ndarray of int
    blade_positions : (F,) ndarray of float, length
    angle_deg, angle_std_deg : (F,) ndarray of float
        NaN where no heap could be fitted.
    """

    timesteps: np.ndarray
    blade_positions: np.ndarray
    angle_deg: np.ndarray
    angle_std_deg: np.ndarray


def heap_front_angle(frame, blade_position: float, *, platform_end: float, platform_z: float,
                     tool_bottom: float, r_max: float | None = None,
                     fit_range=(0.2, 0.8)) -> float:
    """Front-flank angle of the heap ahead of a spreading tool, NaN where there is no heap.

    The heap is the powder ahead of the tool's front face on the platform (spreading along
    +x, z up). Its free surface (side silhouette, the highest sphere top per half median
    radius) is fitted from the crest forwards between ``fit_range`` of the heap height,
    measured from the **toe**: the lowest point of the surface ahead of the crest (the
    bed or bare platform the heap runs onto), as the angle the heap makes with the bed.

    NaN, rather than a number that is not a heap's angle, when:

    - the heap is lower than two median diameters;
    - its toe is not on the platform (the heap reached the front wall or the platform's
      end: no free toe, and the band between crest and cut is not a flank);
    - its toe is not below the tool's lowest point (the pile is still an inserted block
      with a vertical front, whose profile ends a radius below its top edge);
    - the fitted line descends through less than half of the fitted band (the flat top
      of a block ending in a cliff).

    Parameters
    ----------
    frame : Frame
        One frame of the stroke.
    blade_position : float, length
        x of the tool's front face.
    platform_end : float, length
        x where the platform ends (it starts behind the tool).
    platform_z : float, length
        Height of the platform surface (spheres below it by more than ``r_max`` are
        ignored: the powder that fell off).
    tool_bottom : float, length
        Height of the tool's lowest point (the bed surface lies below it).
    r_max : float, length, optional
        Largest sphere radius (default: the frame's).
    fit_range : (float, float)
        Fractions of the heap height between which the flank is fitted.

    Returns
    -------
    float, deg

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> from bedstruct.analysis import heap_front_angle
    >>> x = np.arange(5.25, 30, 0.5)
    >>> z = np.clip(8 - np.tan(np.radians(35)) * (x - 5), 0, None) - 1.0
    >>> f = Frame(np.c_[x, np.zeros_like(x), z], np.full(x.size, 0.25), box=([0, -1, -2], [40, 1, 12]))
    >>> round(heap_front_angle(f, 5.0, platform_end=40.0, platform_z=-1.25, tool_bottom=0.0), 1)
    35.0
    >>> cut = heap_front_angle(f, 5.0, platform_end=15.0, platform_z=-1.25, tool_bottom=0.0)
    >>> block = heap_front_angle(f, 5.0, platform_end=40.0, platform_z=-1.25, tool_bottom=-2.0)
    >>> bool(np.isnan(cut)), bool(np.isnan(block))   # toe cut off; toe above the tool's edge
    (True, True)
    """
    frame = _as_frame(frame)
    p = frame.positions
    r_max = float(np.max(frame.radii)) if r_max is None else float(r_max)
    front = float(blade_position)
    sub = frame.select((p[:, 0] < platform_end) & (p[:, 0] > front) & (p[:, 2] > platform_z - r_max))
    if sub.n_particles == 0:
        return float("nan")
    rmed = float(np.median(frame.radii))
    spacing = 0.5 * rmed
    try:
        x, h = free_surface_profile(sub, axis=0, vertical=2, spacing=spacing, statistic="max")
        ahead = x > front
        x, h = x[ahead], h[ahead]
        peak = int(np.nanargmax(h))
        i_toe = peak + int(np.nanargmin(h[peak:]))   # lowest point ahead of the crest
        r = dynamic_angle_of_repose(sub, front, direction=1, axis=0, vertical=2,
                                    bed_level=float(h[i_toe]), spacing=spacing, statistic="max",
                                    fit_range=fit_range)
    except ValueError:
        return float("nan")
    if not r.top - r.base > 4 * rmed or r.right is None:
        return float("nan")
    if not x[i_toe] < platform_end - 2 * r_max:
        return float("nan")
    if not h[i_toe] < tool_bottom:
        return float("nan")
    fit = r.right
    drop = abs(fit.slope) * float(fit.x.max() - fit.x.min())
    if drop < 0.5 * (fit_range[1] - fit_range[0]) * (r.top - r.base):
        return float("nan")
    return float(r.angle_deg)


def dynamic_repose_series(frames, blade_positions, **kwargs) -> ReposeSeries:
    """Dynamic angle of repose of every frame, as a time series.

    Parameters
    ----------
    frames : iterable of Frame
    blade_positions : (F,) array_like of float or callable
        Blade front per frame, or ``f(frame) -> float``.
    **kwargs
        Passed to :func:`dynamic_angle_of_repose`.

    Returns
    -------
    ReposeSeries

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> x = np.arange(5.25, 30, 0.5)
    >>> z = 1 + np.clip(8 - np.tan(np.radians(35)) * (x - 5), 0, None)
    >>> f = Frame(np.c_[x, np.zeros_like(x), z], np.full(x.size, 0.25), box=([0, -1, 0], [40, 1, 12]))
    >>> s = dynamic_repose_series([f, f], [5.0, 5.0], spacing=0.1)
    >>> s.angle_deg.round(1).tolist()
    [35.0, 35.0]
    """
    ts, bp, ang, std = [], [], [], []
    frames = list(frames) if not hasattr(frames, "__len__") else frames
    for k, f in enumerate(frames):
        b = float(blade_positions(f)) if callable(blade_positions) else float(blade_positions[k])
        try:
            r = dynamic_angle_of_repose(f, b, **kwargs)
            a, s = r.angle_deg, r.angle_std_deg
        except ValueError:
            a = s = float("nan")
        ts.append(f.timestep)
        bp.append(b)
        ang.append(a)
        std.append(s)
    return ReposeSeries(np.asarray(ts, dtype=np.int64), np.asarray(bp, dtype=np.float64),
                        np.asarray(ang, dtype=np.float64), np.asarray(std, dtype=np.float64))
