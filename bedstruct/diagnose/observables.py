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

Quantities of a frame (bed height, packing fraction, roughness, coordination,
segregation, the pile's angle) are defined once, in :mod:`bedstruct.analysis`;
the observable kinds that use them, and :func:`observe`, which dispatches on the
kind, are in :mod:`bedstruct.diagnose.observables_registry`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from . import observables_image as _image

__all__ = ["windowed_mean", "psd_percentiles", "psd_percentiles_from_cumulative",
           "tool_force_ratio"]


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
        for a single sample; NaN for a window whose samples are all NaN (missing data).

    Raises
    ------
    ValueError
        If shapes disagree or a window holds no sample time.

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
        inside = (t >= t0) & ((t < t1) | ((i == len(w) - 1) & (t <= t1)))
        if not inside.any():
            raise ValueError(f"window [{t0:g}, {t1:g}] holds no sample")
        vals = v[inside & np.isfinite(v)]
        k = len(vals)
        if k == 0:   # samples without a value (e.g. no heap to measure): missing data
            mean[i] = sem[i] = np.nan
            continue
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
        Diameters below which the given percentage of volume (or number) lies:
        :func:`bedstruct.analysis.percentile_diameter` (midpoint plotting
        positions, linear interpolation), the definition the report uses.

    Examples
    --------
    >>> psd_percentiles([1.0, 1.0, 2.0], [50], weights="number")
    array([1.])
    """
    from ..analysis import percentile_diameter
    d = np.asarray(diameters, dtype=float).ravel()
    if d.size == 0 or np.any(~np.isfinite(d)) or np.any(d <= 0):
        raise ValueError("`diameters` must be a non-empty array of positive finite lengths")
    if weights not in ("volume", "number"):
        raise ValueError(f"`weights` must be 'volume' or 'number'; got {weights!r}")
    q = np.asarray(percentiles, dtype=float) / 100.0
    return np.atleast_1d(percentile_diameter(d, q, weights=d ** 3 if weights == "volume" else None))


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
