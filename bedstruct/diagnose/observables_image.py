"""The image-based angle operator: side views of heaps and the angle of their free surface.

One operator reads the angle of a powder heap from a side view, whether the view
is a camera image of the real heap or a simulated heap rendered as discs on the
side plane (:func:`render_side_view`, :func:`angle_from_particles`): Otsu
segmentation and the free-surface height per column (:func:`surface_profile`),
a robust line fit of each flank of the profile (:func:`fit_surface_angle`,
giving an :class:`AngleFit`), and the same with quality checks that refuse an
image that is not a side view of a heap (:func:`fit_image_angle`,
:func:`angle_from_image`); :func:`read_image` reads an image file as greyscale.
:func:`~bedstruct.diagnose.observables.observe` applies them to the angle kinds.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["render_side_view", "read_image", "POWDER", "surface_profile", "AngleFit",
           "fit_surface_angle", "fit_image_angle", "angle_from_image", "angle_from_particles"]


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
