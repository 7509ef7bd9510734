"""Observation operators: one per observable kind, applied identically to simulation and real data.

Simulation output reaches the diagnosis only through these functions. The same
operator turns a simulated heap (rendered to a side-view image by
:func:`render_side_view`) and a camera image of the real heap into an angle
(:func:`angle_from_image`); the same windowed mean turns a simulated and a
measured angle time series into per-window values (:func:`windowed_mean`); the
same volume-weighted percentiles turn simulated radii and a measured size
distribution into d10/d50/d90 (:func:`psd_percentiles`,
:func:`psd_percentiles_from_cumulative`).

:func:`observe` dispatches on the kind with a documented dict of arrays, which is
the contract a simulation workflow fills in.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Mapping

import numpy as np

__all__ = ["windowed_mean", "psd_percentiles", "psd_percentiles_from_cumulative",
           "render_side_view", "surface_profile", "AngleFit", "fit_surface_angle",
           "fit_image_angle", "angle_from_image", "angle_from_particles", "read_image", "bed_height",
           "packing_fraction_in_region", "roughness", "tool_force_ratio", "observe"]


def _batch_means_se(block_stat, n: int, n_blocks: int = 10) -> float:
    """Standard error of a statistic of a uniformly sampled, autocorrelated record (batch means).

    The samples ``0 .. n-1`` are cut into ``n_blocks`` consecutive blocks and
    ``block_stat(indices)`` is evaluated on each; the standard error is the scatter
    of the blocks' values over ``sqrt(n_blocks)``. Blocks much longer than the
    correlation time are independent; shorter ones are not, and their scatter
    understates the error: it is multiplied by ``sqrt((1 + r1) / (1 - r1))``, with
    ``r1`` the lag-1 correlation of consecutive blocks' values (clipped to
    ``[0, 0.9]``), the first-order correction of correlated batches.

    Returns NaN with fewer than ``2 n_blocks`` samples (too few to form blocks).
    Shared by :func:`windowed_mean` and :func:`tool_force_ratio`.
    """
    n_blocks = int(n_blocks)
    if n_blocks < 2:
        raise ValueError(f"`n_blocks` must be >= 2; got {n_blocks}")
    if n < 2 * n_blocks:
        return float("nan")
    r = np.array([float(block_stat(b)) for b in np.array_split(np.arange(n), n_blocks)])
    se = float(r.std(ddof=1) / math.sqrt(n_blocks))
    d = r - r.mean()
    ss = float(np.sum(d * d))
    r1 = float(np.sum(d[:-1] * d[1:]) / ss) if ss > 0 else 0.0
    r1 = min(max(r1, 0.0), 0.9)
    return se * math.sqrt((1.0 + r1) / (1.0 - r1))


def windowed_mean(times, values, windows, *, n_blocks: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error of a time series in each time window.

    Parameters
    ----------
    times : (T,) array_like of float
        Sample times (stroke fractions, dimensionless, or any consistent unit).
    values : (T,) array_like of float
        The series (e.g. dynamic angle, deg), sampled at a uniform rate.
    windows : (n, 2) array_like of float
        ``[t0, t1)`` windows in the unit of ``times`` (the last window includes ``t1``).
    n_blocks : int
        Blocks of the batch-means standard error.

    Returns
    -------
    mean, sem : (n,) ndarray
        Window means and their standard errors. A measured series is
        autocorrelated (a heap's angle drifts over many frames), so ``std/sqrt(k)``
        of its ``k`` samples would understate the error by the square root of the
        correlation time in samples; the standard error is taken from batch means
        instead (``n_blocks`` consecutive blocks, corrected for the correlation of
        neighbouring blocks; the same estimator as :func:`tool_force_ratio`). A
        window of fewer than ``2 n_blocks`` samples gets their standard deviation
        (no credit for averaging: their correlation cannot be estimated), and 0
        for a single sample.

    Raises
    ------
    ValueError
        If shapes disagree or a window holds no sample.

    Examples
    --------
    >>> m, s = windowed_mean([0, 0.05, 0.5, 0.9], [40, 38, 27, 28], [[0, 0.1], [0.1, 1]])
    >>> m
    array([39. , 27.5])
    """
    t = np.asarray(times, dtype=float).ravel()
    v = np.asarray(values, dtype=float).ravel()
    w = np.atleast_2d(np.asarray(windows, dtype=float))
    if t.shape != v.shape:
        raise ValueError(f"`times` and `values` must have the same length; got {t.shape} and {v.shape}")
    if w.shape[1] != 2:
        raise ValueError(f"`windows` must have shape (n, 2); got {w.shape}")
    mean = np.empty(len(w))
    sem = np.empty(len(w))
    for i, (t0, t1) in enumerate(w):
        sel = (t >= t0) & ((t < t1) | ((i == len(w) - 1) & (t <= t1))) & np.isfinite(v)
        vals = v[sel]
        k = len(vals)
        if k == 0:
            raise ValueError(f"window [{t0:g}, {t1:g}] holds no sample")
        mean[i] = vals.mean()
        if k >= 2 * n_blocks:
            sem[i] = _batch_means_se(lambda b: vals[b].mean(), k, n_blocks)
        else:
            sem[i] = vals.std(ddof=1) if k > 1 else 0.0
    return mean, sem


def psd_percentiles(diameters, percentiles=(10, 50, 90), *, weights="volume") -> np.ndarray:
    """Volume-weighted (laser-diffraction-like) percentiles of particle diameters.

    Parameters
    ----------
    diameters : (N,) array_like of float, length
        Particle diameters.
    percentiles : sequence of float
        Percentiles in (0, 100).
    weights : {"volume", "number"}
        ``"volume"`` weights each particle by d^3 as laser diffraction does.

    Returns
    -------
    (k,) ndarray of float, length
        Diameters below which the given percentage of volume (or number) lies
        (linear interpolation of the cumulative distribution).

    Examples
    --------
    >>> psd_percentiles([1.0, 1.0, 2.0], [50], weights="number")
    array([1.])
    """
    d = np.sort(np.asarray(diameters, dtype=float).ravel())
    if d.size == 0 or np.any(~np.isfinite(d)) or np.any(d <= 0):
        raise ValueError("`diameters` must be a non-empty array of positive finite lengths")
    if weights not in ("volume", "number"):
        raise ValueError(f"`weights` must be 'volume' or 'number'; got {weights!r}")
    w = d ** 3 if weights == "volume" else np.ones_like(d)
    cum = 100.0 * (np.cumsum(w) - 0.5 * w) / w.sum()
    return np.interp(np.asarray(percentiles, dtype=float), cum, d)


def psd_percentiles_from_cumulative(sizes, cumulative, percentiles=(10, 50, 90)) -> np.ndarray:
    """Percentiles from a measured cumulative size distribution (sizes vs % passing).

    Parameters
    ----------
    sizes : (k,) array_like of float, length
        Size classes (increasing).
    cumulative : (k,) array_like of float
        Cumulative volume percentage finer than each size (0..100, non-decreasing).
    percentiles : sequence of float

    Examples
    --------
    >>> psd_percentiles_from_cumulative([10, 20, 40], [0, 50, 100], [50, 75])
    array([20., 30.])
    """
    s = np.asarray(sizes, dtype=float).ravel()
    c = np.asarray(cumulative, dtype=float).ravel()
    if s.shape != c.shape or s.size < 2:
        raise ValueError("`sizes` and `cumulative` must be equal-length arrays of at least 2 values")
    if np.any(np.diff(s) <= 0) or np.any(np.diff(c) < 0):
        raise ValueError("`sizes` must increase and `cumulative` must not decrease")
    return np.interp(np.asarray(percentiles, dtype=float), c, s)


def render_side_view(positions, radii, *, pixel_size, axis=1, extent=None,
                     background=0.0, foreground=1.0) -> np.ndarray:
    """Project spheres onto a side plane as discs: the simulated camera image.

    Parameters
    ----------
    positions : (N, 3) array_like of float, length
    radii : (N,) array_like of float, length
    pixel_size : float, length
        Edge of one pixel in the units of ``positions``.
    axis : int
        Viewing axis (projected away); default 1 (view along y, image in x-z).
    extent : (xmin, xmax, zmin, zmax), optional
        Image window in the plane; default the bounding box of the discs.
    background, foreground : float
        Grey levels of empty and powder pixels.

    Returns
    -------
    (rows, cols) ndarray of float
        Row 0 is the top of the image (highest z), column 0 the smallest x.

    Examples
    --------
    >>> img = render_side_view([[0.5, 0.0, 0.5]], [0.5], pixel_size=0.1, extent=(0, 1, 0, 1))
    >>> img.shape, int(img.sum())
    ((10, 10), 80)
    """
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    r = np.asarray(radii, dtype=float).ravel()
    if len(r) != len(p):
        raise ValueError(f"`radii` must have shape (N,) matching `positions` (N={len(p)}); got {r.shape}")
    if not pixel_size > 0:
        raise ValueError(f"`pixel_size` must be > 0; got {pixel_size!r}")
    keep = [a for a in range(3) if a != axis]
    xy = p[:, keep]
    if extent is None:
        extent = (float((xy[:, 0] - r).min()), float((xy[:, 0] + r).max()),
                  float((xy[:, 1] - r).min()), float((xy[:, 1] + r).max()))
    x0, x1, z0, z1 = extent
    ncol = max(int(math.ceil((x1 - x0) / pixel_size)), 1)
    nrow = max(int(math.ceil((z1 - z0) / pixel_size)), 1)
    img = np.full((nrow, ncol), float(background))
    xc = x0 + (np.arange(ncol) + 0.5) * pixel_size
    zc = z1 - (np.arange(nrow) + 0.5) * pixel_size
    for (cx, cz), rad in zip(xy, r):
        c0 = max(int((cx - rad - x0) / pixel_size), 0)
        c1 = min(int((cx + rad - x0) / pixel_size) + 1, ncol)
        r0 = max(int((z1 - (cz + rad)) / pixel_size), 0)
        r1 = min(int((z1 - (cz - rad)) / pixel_size) + 1, nrow)
        if c0 >= c1 or r0 >= r1:
            continue
        dx = xc[c0:c1][None, :] - cx
        dz = zc[r0:r1][:, None] - cz
        inside = dx * dx + dz * dz <= rad * rad
        img[r0:r1, c0:c1][inside] = foreground
    return img


def read_image(path) -> np.ndarray:
    """Read an image file as a float greyscale array (scikit-image)."""
    from skimage import io
    from skimage.color import rgb2gray
    img = io.imread(str(path))
    if img.ndim == 3:
        img = rgb2gray(img[..., :3])
    return np.asarray(img, dtype=float)


#: Polarities of :func:`surface_profile` / :func:`angle_from_image`.
POWDER = ("bright", "dark", "auto")


def _powder_polarity(bright) -> str:
    """Which Otsu class is the powder: the one that fills the bottom of a side view."""
    q = max(1, bright.shape[0] // 4)
    fb, ft = float(bright[-q:].mean()), float(bright[:q].mean())
    if fb - ft >= 0.25:
        return "bright"
    if ft - fb >= 0.25:
        return "dark"
    raise ValueError(f"cannot tell the powder from the background (bright pixels: {fb:.0%} of the "
                     f"bottom quarter of the image, {ft:.0%} of the top quarter; the powder should "
                     f"fill the bottom): give powder='bright' or 'dark'")


def _segment(image, powder, min_object):
    """Otsu segmentation: the powder mask and the polarity used."""
    from skimage.filters import threshold_otsu
    from skimage.morphology import remove_small_objects

    img = np.asarray(image, dtype=float)
    if img.ndim != 2:
        raise ValueError(f"`image` must be a 2-D greyscale array; got shape {img.shape}")
    if powder not in POWDER:
        raise ValueError(f"`powder` must be one of {POWDER}; got {powder!r}")
    if not np.all(np.isfinite(img)):
        raise ValueError("`image` holds non-finite pixels")
    if np.ptp(img) == 0:
        raise ValueError("`image` is uniform; nothing to segment")
    t = threshold_otsu(img)
    if powder == "auto":
        powder = _powder_polarity(img > t)
    mask = img > t if powder == "bright" else img < t
    if min_object > 1:
        mask = remove_small_objects(mask, max_size=min_object - 1) if _has_max_size() else \
            remove_small_objects(mask, min_size=min_object)
    return mask, powder


def _profile(mask, pixel_size):
    nrow, ncol = mask.shape
    has = mask.any(axis=0)
    top = np.argmax(mask, axis=0)
    height = np.where(has, (nrow - top) * pixel_size, np.nan)
    x = (np.arange(ncol) + 0.5) * pixel_size
    return x, height


def surface_profile(image, *, pixel_size, powder="bright", min_object=16) -> tuple[np.ndarray, np.ndarray]:
    """Free-surface height per image column after Otsu segmentation.

    Parameters
    ----------
    image : (rows, cols) array_like
        Greyscale side view, row 0 at the top.
    pixel_size : float, length
    powder : {"bright", "dark", "auto"}
        Whether the powder is brighter or darker than the background; ``"auto"``
        takes the class that fills the bottom of the image (an error when neither
        clearly does).
    min_object : int
        Foreground objects smaller than this many pixels are removed (dust, noise).

    Returns
    -------
    x, height : (cols,) ndarray of float, length
        Column centres and the height of the topmost powder pixel above the
        image bottom (NaN where a column holds no powder).
    """
    mask, _ = _segment(image, powder, min_object)
    return _profile(mask, pixel_size)


def _has_max_size() -> bool:
    import inspect
    from skimage.morphology import remove_small_objects
    return "max_size" in inspect.signature(remove_small_objects).parameters


@dataclass(frozen=True)
class AngleFit:
    """A robust line fit of a free surface.

    Attributes
    ----------
    angle : float
        Inclination of the surface, deg (positive, 0..90): the mean over the
        fitted flanks.
    slope : float
        dz/dx of the fitted line of the first fitted flank (left, then right;
        the sign tells which way it falls).
    intercept : float, length
        Of the same line.
    n_points, n_inliers : int
        Surface points fitted and those within the inlier distance of their
        flank's line (all flanks together).
    flanks : tuple of str
        The flanks fitted (``"left"``: left of the crest, rising to the right;
        ``"right"``: right of the crest, falling to the right).
    flank_angles : tuple of float
        Their angles, deg.
    powder : str or None
        Polarity used when the fit comes from an image (:func:`fit_image_angle`).
    """

    angle: float
    slope: float
    intercept: float
    n_points: int
    n_inliers: int
    flanks: tuple = ()
    flank_angles: tuple = ()
    powder: str | None = None


def _fit_line(xs, hs, method, thr, seed):
    """Slope, intercept and inlier count of one flank's points."""
    if method == "theil-sen":
        from scipy.stats import theilslopes
        slope, intercept, _, _ = theilslopes(hs, xs)
        dist = np.abs(hs - (slope * xs + intercept)) / math.sqrt(1.0 + slope * slope)
        return float(slope), float(intercept), int(np.sum(dist <= thr))
    from skimage.measure import LineModelND, ransac
    data = np.column_stack([xs, hs])
    _, inliers = ransac(data, LineModelND, min_samples=2, residual_threshold=thr,
                        max_trials=200, rng=np.random.default_rng(seed))
    if inliers is None or inliers.sum() < 3:
        inliers = np.ones(len(xs), dtype=bool)
    slope, intercept = np.polyfit(xs[inliers], hs[inliers], 1)
    return float(slope), float(intercept), int(inliers.sum())


def fit_surface_angle(x, height, *, band=(0.15, 0.85), method="ransac", flanks="both",
                      residual_threshold=None, seed=0, min_points=5) -> AngleFit:
    """Robust line fit of the inclined part of a free-surface profile, flank by flank.

    From the crest (the highest point) each flank is followed outwards until the
    profile drops below the band; its points inside the band are fitted on their
    own, and the angle is the mean over the flanks found (as
    :func:`bedstruct.analysis.angle_of_repose` does for simulated piles). A
    one-sided heap (flat top against a wall, the pile in front of a blade) has
    one flank; a cone has two, and a single straight line through both would
    read ~0 deg.

    Parameters
    ----------
    x, height : (k,) array_like of float, length
        Profile (NaN heights are ignored).
    band : (float, float)
        Only points between these fractions of the profile's height range are
        fitted, which drops the flat top and the toe of the heap.
    method : {"ransac", "theil-sen"}
        RANSAC (scikit-image, then least squares on the inliers) or Theil-Sen (scipy).
    flanks : {"both", "left", "right"}
        Which flanks to fit (``"both"``: every flank found).
    residual_threshold : float, optional
        Inlier distance (RANSAC's, and the one ``n_inliers`` counts); default
        2 % of the height range.
    seed : int
        Seed of the RANSAC sampler.
    min_points : int
        A flank needs at least this many points in the band, descending through
        at least half of it (a flat top is no flank).

    Returns
    -------
    AngleFit

    Raises
    ------
    ValueError
        If the profile is flat or no flank is found.

    Examples
    --------
    >>> x = np.linspace(0, 1, 50)
    >>> fit_surface_angle(x, 1 - x * np.tan(np.radians(30))).angle  # doctest: +ELLIPSIS
    30.0...
    >>> cone = 1 - np.abs(x - 0.5) * np.tan(np.radians(30))
    >>> f = fit_surface_angle(x, cone, method="theil-sen")
    >>> f.flanks, [round(a, 1) for a in f.flank_angles]
    (('left', 'right'), [30.0, 30.0])
    """
    if method not in ("ransac", "theil-sen"):
        raise ValueError(f"`method` must be 'ransac' or 'theil-sen'; got {method!r}")
    if flanks not in ("both", "left", "right"):
        raise ValueError(f"`flanks` must be 'both', 'left' or 'right'; got {flanks!r}")
    x = np.asarray(x, dtype=float).ravel()
    h = np.asarray(height, dtype=float).ravel()
    ok = np.isfinite(h) & np.isfinite(x)
    x, h = x[ok], h[ok]
    order = np.argsort(x, kind="stable")
    x, h = x[order], h[order]
    if len(x) < 3:
        raise ValueError("too few surface points to fit an angle (need >= 3)")
    lo, hi = float(np.min(h)), float(np.max(h))
    if not hi > lo:
        raise ValueError("the surface profile is flat: no inclined surface to fit")
    q = (h - lo) / (hi - lo)
    thr = residual_threshold if residual_threshold is not None else 0.02 * (hi - lo)
    peak = int(np.argmax(h))
    names, angles, lines, n_pts, n_in = [], [], [], 0, 0
    for name, step in (("left", -1), ("right", 1)):
        if flanks not in ("both", name):
            continue
        idx, k = [], peak
        while 0 <= k < len(x):
            if q[k] < band[0]:
                break
            if q[k] <= band[1]:
                idx.append(k)
            k += step
        if len(idx) < max(int(min_points), 3) or np.ptp(q[idx]) < 0.5 * (band[1] - band[0]):
            continue
        idx = np.sort(np.asarray(idx))
        slope, icpt, inl = _fit_line(x[idx], h[idx], method, thr, seed)
        names.append(name)
        angles.append(float(np.degrees(np.arctan(abs(slope)))))
        lines.append((slope, icpt))
        n_pts += len(idx)
        n_in += inl
    if not names:
        which = "flank" if flanks == "both" else f"{flanks} flank"
        raise ValueError(f"no inclined {which} found: the profile does not descend from its crest "
                         f"through the band {band[0]:g}-{band[1]:g} of its height range in "
                         f">= {min_points} points")
    return AngleFit(float(np.mean(angles)), float(lines[0][0]), float(lines[0][1]), n_pts, n_in,
                    tuple(names), tuple(angles))


def fit_image_angle(image, *, pixel_size=1.0, powder="bright", band=(0.15, 0.85), method="ransac",
                    flanks="both", seed=0, min_object=16, min_inlier_fraction=0.5,
                    min_height_pixels=10) -> AngleFit:
    """Angle of a powder heap or pile from a side-view image, with quality checks.

    Otsu segmentation, topmost powder pixel per column as the free surface, and
    a robust line fit of each flank's inclined part (:func:`fit_surface_angle`).
    The image must look like a side view of a heap, otherwise the angle would be
    a number read from noise: the powder fills the bottom of the image (in the
    lowest 5 % of the rows in >= 25 % of the columns), stays clear of its top edge
    (<= 5 % of the columns), is solid under its surface (>= 80 % of the pixels),
    its surface rises >= ``min_height_pixels`` above the toe, and
    >= ``min_inlier_fraction`` of the fitted points lie on the fitted lines. An
    upside-down or rotated image, the wrong polarity or pure noise fail these.

    Parameters
    ----------
    image : (rows, cols) array_like
        Greyscale side view (row 0 at the top).
    pixel_size : float, length
        Only the ratio of scales matters for the angle; square pixels assumed.
    powder : {"bright", "dark", "auto"}
        See :func:`surface_profile`.
    band, method, flanks, seed
        See :func:`fit_surface_angle`.

    Returns
    -------
    AngleFit
        With ``powder`` the polarity used.

    Raises
    ------
    ValueError
        Saying which check failed.
    """
    mask, pol = _segment(image, powder, min_object)
    nrow, ncol = mask.shape
    if not mask.any():
        raise ValueError(f"no {pol} powder found in the image")
    nb = max(1, int(round(0.05 * nrow)))
    bottom = float(mask[-nb:].any(axis=0).mean())
    if bottom < 0.25:
        raise ValueError(f"the {pol} powder does not rest on the bottom of the image (it reaches the "
                         f"lowest 5 % of the rows in {bottom:.0%} of the columns; >= 25 % expected): "
                         f"is the image upside down or rotated, or the powder's polarity wrong?")
    top = float(mask[0].mean())
    if top > 0.05:
        raise ValueError(f"the {pol} powder reaches the top edge of the image in {top:.0%} of the "
                         f"columns (<= 5 % expected): the heap is cut off, the image is rotated, or "
                         f"a wall, the blade or uneven lighting is segmented as powder (crop the "
                         f"image to the heap)")
    has = mask.any(axis=0)
    under = float(np.sum(nrow - np.argmax(mask, axis=0)[has]))
    solid = float(mask.sum()) / under
    if solid < 0.8:
        raise ValueError(f"the {pol} powder is not solid under its surface ({solid:.0%} of the pixels "
                         f"under the surface are powder; >= 80 % expected): the image is too noisy, "
                         f"or not a side view of a heap")
    x, h = _profile(mask, pixel_size)
    rise = (np.nanmax(h) - np.nanmin(h)) / pixel_size
    if rise < min_height_pixels:
        raise ValueError(f"the free surface rises only {rise:.0f} pixels above its lowest point "
                         f"(>= {min_height_pixels} expected): no heap to read an angle from")
    fit = fit_surface_angle(x, h, band=band, method=method, flanks=flanks, seed=seed)
    frac = fit.n_inliers / max(fit.n_points, 1)
    if frac < min_inlier_fraction:
        raise ValueError(f"the free surface is not straight: {frac:.0%} of its {fit.n_points} "
                         f"points lie on the fitted line(s) ({min_inlier_fraction:.0%} expected)")
    return replace(fit, powder=pol)


def angle_from_image(image, *, pixel_size=1.0, powder="bright", band=(0.15, 0.85),
                     method="ransac", flanks="both", seed=0) -> float:
    """Angle of a powder heap or pile from a side-view image.

    Otsu segmentation, topmost powder pixel per column as the free surface, and
    a robust line fit of the inclined part of each flank, with the quality
    checks of :func:`fit_image_angle` (which raises ``ValueError`` on an image
    that is not a side view of a heap).

    Parameters
    ----------
    image : (rows, cols) array_like
        Greyscale side view (row 0 at the top).
    pixel_size : float, length
        Only the ratio of scales matters for the angle; square pixels assumed.
    powder : {"bright", "dark", "auto"}
        See :func:`surface_profile`.
    flanks : {"both", "left", "right"}
        See :func:`fit_surface_angle`: a two-flanked pile reads the mean of its flanks.

    Returns
    -------
    float
        Angle, deg.

    Examples
    --------
    >>> rows, cols = np.mgrid[0:100, 0:200]
    >>> img = (rows > 20 + 0.5 * cols).astype(float)   # surface falling at slope 0.5
    >>> round(angle_from_image(img), 1)
    26.6
    """
    return fit_image_angle(image, pixel_size=pixel_size, powder=powder, band=band, method=method,
                           flanks=flanks, seed=seed).angle


def angle_from_particles(positions, radii, *, pixel_size=None, axis=1, **kwargs) -> float:
    """Angle of a simulated heap: rendered side view, then :func:`angle_from_image`.

    The pixel size defaults to a third of the smallest radius.
    """
    r = np.asarray(radii, dtype=float)
    px = float(pixel_size) if pixel_size is not None else float(r.min()) / 3.0
    img = render_side_view(positions, radii, pixel_size=px, axis=axis)
    return angle_from_image(img, pixel_size=px, **kwargs)


def _top_surface(positions, radii, *, bin_size, x_range=None):
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    r = np.asarray(radii, dtype=float).ravel()
    x = p[:, 0]
    lo, hi = (x.min(), x.max()) if x_range is None else x_range
    nb = max(int((hi - lo) / bin_size), 1)
    idx = np.clip(((x - lo) / (hi - lo) * nb).astype(int), 0, nb - 1)
    top = np.full(nb, -np.inf)
    np.maximum.at(top, idx, p[:, 2] + r)
    top[~np.isfinite(top)] = np.nan
    return top


def bed_height(positions, radii, *, plate_z=0.0, bin_size=None, x_range=None) -> float:
    """Mean height of the top surface above the plate (length, frame units).

    The top surface is the highest sphere top in each x bin (bin default: the
    largest diameter), the same operator a profilometer line scan gives.
    """
    r = np.asarray(radii, dtype=float)
    top = _top_surface(positions, radii, bin_size=bin_size or 2 * float(r.max()), x_range=x_range)
    return float(np.nanmean(top) - plate_z)


def roughness(heights) -> float:
    """Rq roughness of a surface profile after removing its best-fit line (length).

    Examples
    --------
    >>> round(roughness([0.0, 1.0, 0.0, 1.0]), 3)
    0.447
    """
    h = np.asarray(heights, dtype=float).ravel()
    h = h[np.isfinite(h)]
    if len(h) < 3:
        raise ValueError("`heights` needs at least 3 finite values")
    x = np.arange(len(h))
    resid = h - np.polyval(np.polyfit(x, h, 1), x)
    return float(np.sqrt(np.mean(resid ** 2)))


def packing_fraction_in_region(positions, radii, lo, hi) -> float:
    """Solid fraction in an axis-aligned region, counting spheres by their centres.

    Spheres whose centre lies in ``[lo, hi)`` contribute their whole volume; the
    error is of order (mean radius / region size), so regions should be many
    diameters wide.

    Examples
    --------
    >>> round(packing_fraction_in_region([[0.5, 0.5, 0.5]], [0.5], [0, 0, 0], [1, 1, 1]), 4)
    0.5236
    """
    p = np.asarray(positions, dtype=float).reshape(-1, 3)
    r = np.asarray(radii, dtype=float).ravel()
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    inside = np.all((p >= lo) & (p < hi), axis=1)
    return float((4.0 / 3.0) * np.pi * np.sum(r[inside] ** 3) / np.prod(hi - lo))


def tool_force_ratio(force_x, force_z, *, n_blocks: int = 10) -> tuple[float, float]:
    """Vertical over horizontal load on the recoater over a stroke, and its standard error.

    The ratio of the time means ``mean(F_z) / mean(F_x)`` of a load-cell record
    sampled at a uniform rate over the stroke (force of the powder on the tool, x
    along the stroke: the push gives ``F_x < 0``, powder dragged down the tool's
    face ``F_z < 0``; any force unit). The engine's time-averaged tool load
    (:attr:`bedstruct.workflows.spread_measure.LayerResult.tool_force`) is the
    same ratio of means. The load is autocorrelated, so the standard error comes
    from ``n_blocks`` consecutive blocks (batch means): the scatter of the
    blocks' ratios over ``sqrt(n_blocks)``, corrected for the correlation of
    neighbouring blocks (the estimator of :func:`windowed_mean`).

    Parameters
    ----------
    force_x, force_z : (n,) array_like of float
    n_blocks : int

    Returns
    -------
    ratio, standard_error : float
        NaN standard error with fewer than ``2 n_blocks`` samples.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 400)
    >>> fx = -1.0 - 0.1 * np.sin(40 * t)
    >>> fz = 0.2 * fx
    >>> ratio, se = tool_force_ratio(fx, fz)
    >>> round(ratio, 6), se < 1e-9
    (0.2, True)
    """
    fx = np.asarray(force_x, float).reshape(-1)
    fz = np.asarray(force_z, float).reshape(-1)
    if fx.shape != fz.shape or fx.size == 0:
        raise ValueError("tool_force_ratio: `force_x` and `force_z` need the same, non-zero "
                         f"length; got {fx.size} and {fz.size}")
    if not (np.all(np.isfinite(fx)) and np.all(np.isfinite(fz))):
        raise ValueError("tool_force_ratio: forces must be finite")
    mx = float(fx.mean())
    if mx == 0.0:
        raise ValueError("tool_force_ratio: the mean horizontal load is zero (no push recorded)")
    ratio = float(fz.mean()) / mx
    return ratio, _batch_means_se(lambda b: fz[b].mean() / fx[b].mean(), fx.size, n_blocks)


def observe(kind: str, data: Mapping[str, Any], *, windows=None, percentiles=None) -> np.ndarray:
    """Apply the observation operator of ``kind`` to a dict of arrays.

    This is the contract between a simulation workflow (or a real-data reader)
    and the diagnosis. Keys per kind:

    ``static_angle``
        ``image`` (+ ``pixel_size``) or ``positions`` + ``radii``.
    ``dynamic_angle_series``
        ``times`` (stroke fractions) and ``angles`` (deg) or ``images`` (+ ``pixel_size``);
        needs ``windows``.
    ``bed_height``
        ``positions`` + ``radii`` (+ ``plate_z``) or ``surface_heights``.
    ``packing_fraction``
        ``positions`` + ``radii`` + ``region_lo`` + ``region_hi``.
    ``psd``
        ``diameters`` or ``sizes`` + ``cumulative``; needs ``percentiles``.
    ``roughness``
        ``surface_heights``.
    ``coordination``
        ``coordination`` (per-particle contact counts).
    ``tool_force_ratio``
        ``force_x`` + ``force_z`` (a load-cell record over the stroke; see
        :func:`tool_force_ratio`).

    A :class:`bedstruct.Frame` (or any object with ``positions`` and ``radii``)
    may be passed instead of a dict for the particle-based kinds.

    Returns
    -------
    (n,) ndarray
        Component values in the kind's canonical unit (see :data:`KINDS`).

    Examples
    --------
    >>> observe("coordination", {"coordination": [3, 4, 5]})
    array([4.])
    """
    if not isinstance(data, Mapping):
        if hasattr(data, "positions") and hasattr(data, "radii"):
            data = {"positions": np.asarray(data.positions), "radii": np.asarray(data.radii)}
        else:
            raise TypeError(f"`data` must be a dict of arrays or a Frame; got {type(data).__name__}")
    if kind == "static_angle":
        if "image" in data:
            return np.array([angle_from_image(data["image"], pixel_size=data.get("pixel_size", 1.0))])
        return np.array([angle_from_particles(data["positions"], data["radii"])])
    if kind == "dynamic_angle_series":
        if windows is None:
            raise ValueError("dynamic_angle_series needs `windows`")
        if "images" in data:
            angles = [angle_from_image(im, pixel_size=data.get("pixel_size", 1.0)) for im in data["images"]]
        else:
            angles = data["angles"]
        return windowed_mean(data["times"], angles, windows)[0]
    if kind == "bed_height":
        if "surface_heights" in data:
            return np.array([float(np.nanmean(data["surface_heights"]))])
        return np.array([bed_height(data["positions"], data["radii"], plate_z=data.get("plate_z", 0.0))])
    if kind == "packing_fraction":
        return np.array([packing_fraction_in_region(data["positions"], data["radii"],
                                                    data["region_lo"], data["region_hi"])])
    if kind == "psd":
        if percentiles is None:
            raise ValueError("psd needs `percentiles`")
        if "diameters" in data:
            return psd_percentiles(data["diameters"], percentiles)
        return psd_percentiles_from_cumulative(data["sizes"], data["cumulative"], percentiles)
    if kind == "roughness":
        return np.array([roughness(data["surface_heights"])])
    if kind == "coordination":
        return np.array([float(np.mean(data["coordination"]))])
    if kind == "tool_force_ratio":
        return np.array([tool_force_ratio(data["force_x"], data["force_z"])[0]])
    raise ValueError(f"unknown observable kind {kind!r}")
