"""Observation operators: one per observable kind, applied identically to simulation and real data.

Simulation output reaches the diagnosis only through these functions. The same
operator turns a simulated heap (rendered to a side-view image by
:func:`render_side_view`) and a camera image of the real heap into an angle
(:func:`angle_from_image`); the same windowed mean turns a simulated and a
measured angle time series into per-window values (:func:`windowed_mean`); the
same volume-weighted percentiles turn simulated radii and a measured size
distribution into d10/d50/d90 (:func:`psd_percentiles`,
:func:`psd_percentiles_from_cumulative`).

The image-based angle operator (:func:`render_side_view`, :func:`surface_profile`,
:func:`fit_surface_angle`, :func:`fit_image_angle`, :func:`angle_from_image`,
:func:`angle_from_particles`, :class:`AngleFit`, :func:`read_image`) lives in
:mod:`bedstruct.diagnose.observables_image`.

:func:`observe` dispatches on the kind with a documented dict of arrays, which is
the contract a simulation workflow fills in.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from . import observables_image as _image
from .observables_image import angle_from_image, angle_from_particles

__all__ = ["windowed_mean", "psd_percentiles", "psd_percentiles_from_cumulative", "bed_height",
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


#: Polarities of :func:`surface_profile` / :func:`angle_from_image` (defined in
#: :mod:`bedstruct.diagnose.observables_image`).
POWDER = _image.POWDER


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
