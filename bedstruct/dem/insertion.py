"""Particle insertion: raindrop insertion in a region, saved piles, PSD sampling (SI units)."""

from __future__ import annotations

import importlib
import math
from typing import Callable

import numpy as np

from ..errors import ConfigError
from . import _kernels as K

__all__ = ["sample_radii", "raindrop_positions"]


def sample_radii(n: int, psd, *, rng=None) -> np.ndarray:
    """Draw ``n`` particle radii (m) from a size distribution.

    Parameters
    ----------
    n : int
        Number of radii.
    psd : float, array_like, callable, PSDFit or mapping
        A single radius; an array of radii to resample from; a callable
        ``psd(n, rng) -> radii``; a fitted distribution with
        ``sample_radii(n, seed=)`` (:func:`bedstruct.analysis.psd_from_percentiles`);
        or a mapping of diameter percentiles ``{10: d10, 50: d50, 90: d90}``
        (m, optional ``"bounds": (d_min, d_max)``, default ``(d10/3, 3 d90)``),
        fitted with :func:`bedstruct.analysis.psd_from_percentiles`. Other
        percentile sets are interpolated log-linearly in probit space. Percentiles
        are volume-based in both cases; radii are drawn by number.
    rng : int or numpy Generator, optional

    Returns
    -------
    (n,) ndarray of float, m

    Examples
    --------
    >>> r = sample_radii(1000, {10: 20e-6, 50: 30e-6, 90: 45e-6}, rng=0)
    >>> bool(np.all((2 * r >= 20e-6 / 3) & (2 * r <= 3 * 45e-6)))
    True
    >>> round(float(np.median(2 * r)) * 1e6)  # number median < volume median d50
    23
    >>> sample_radii(2, 1e-5).tolist()
    [1e-05, 1e-05]
    """
    rng = np.random.default_rng(rng)
    n = int(n)
    if hasattr(psd, "sample_radii"):  # a fitted PSD (bedstruct.analysis.PSDFit)
        out = np.asarray(psd.sample_radii(n, seed=rng), dtype=np.float64)
    elif callable(psd):
        out = np.asarray(psd(n, rng), dtype=np.float64)
    elif isinstance(psd, dict):
        out = _from_percentiles(n, psd, rng)
    else:
        arr = np.asarray(psd, dtype=np.float64)
        out = np.full(n, float(arr)) if arr.ndim == 0 else rng.choice(arr.reshape(-1), size=n)
    if out.shape != (n,) or not np.all(np.isfinite(out) & (out > 0)):
        raise ConfigError(f"the size distribution must give {n} positive finite radii; "
                          f"got shape {out.shape}")
    return out


def _from_percentiles(n, pct: dict, rng) -> np.ndarray:
    pct = dict(pct)
    bounds = pct.pop("bounds", None)
    try:
        func = getattr(importlib.import_module("bedstruct.analysis.psd"), "psd_from_percentiles")
    except (ImportError, AttributeError):  # pragma: no cover - analysis always present
        func = None
    keys = {float(k) for k in pct}
    if func is not None and keys == {10.0, 50.0, 90.0}:
        d = {float(k): float(v) for k, v in pct.items()}
        if bounds is None:
            bounds = (d[10.0] / 3.0, d[90.0] * 3.0)
        return np.asarray(func(d[10.0], d[50.0], d[90.0], bounds).sample_radii(n, seed=rng),
                          dtype=np.float64)
    q = np.array(sorted(float(k) for k in pct), dtype=np.float64)
    d = np.array([float(pct[k]) for k in sorted(pct, key=float)], dtype=np.float64)
    if q.size < 2 or np.any(np.diff(d) <= 0) or q[0] <= 0 or q[-1] >= 100 or d[0] <= 0:
        raise ConfigError(f"percentiles must be >= 2 increasing diameters at levels in (0, 100); "
                          f"got {pct!r}")
    d_min, d_max = (d[0] / 3.0, d[-1] * 3.0) if bounds is None else map(float, bounds)
    if not 0 < d_min < d[0] or not d_max > d[-1]:
        raise ConfigError(f"bounds must bracket the percentiles' diameters: 0 < d_min < {d[0]:g} "
                          f"and d_max > {d[-1]:g}; got {bounds!r}")
    # The percentiles are volume-based (laser diffraction), as in the {10, 50, 90} case: the
    # volume distribution is log-linear in the probit of the level between them (extended
    # with the end slopes, truncated to the bounds); particles are drawn by number,
    # q0(d) ~ q3(d) / d^3.
    from scipy.special import ndtr, ndtri
    z = ndtri(q / 100.0)
    logd_knots = np.log(d)
    slope_lo = (z[1] - z[0]) / (logd_knots[1] - logd_knots[0])
    slope_hi = (z[-1] - z[-2]) / (logd_knots[-1] - logd_knots[-2])
    grid = np.linspace(np.log(d_min), np.log(d_max), 4097)
    zg = np.interp(grid, logd_knots, z)
    zg = np.where(grid < logd_knots[0], z[0] + slope_lo * (grid - logd_knots[0]), zg)
    zg = np.where(grid > logd_knots[-1], z[-1] + slope_hi * (grid - logd_knots[-1]), zg)
    volume_mass = np.diff(ndtr(zg))
    mid = 0.5 * (grid[1:] + grid[:-1])
    number_cdf = np.concatenate([[0.0], np.cumsum(volume_mass * np.exp(-3.0 * mid))])
    number_cdf /= number_cdf[-1]
    return 0.5 * np.exp(np.interp(rng.random(n), number_cdf, grid))


def raindrop_positions(lo, hi, radii, *, existing=None, existing_radii=None, rng=None,
                       max_attempts: int = 50, period=None) -> tuple[np.ndarray, np.ndarray]:
    """Random non-overlapping positions for spheres in the region ``[lo, hi]``.

    Spheres lie wholly inside the region, overlap neither each other nor
    the ``existing`` spheres. Candidates are drawn in batches and accepted
    greedily in order, so the result is deterministic for a seed. Along a
    periodic axis (``period``) whose whole period the region spans, centres
    are drawn over the period ``[lo, lo + period)`` and spheres must not
    overlap across it (nearest images).

    Parameters
    ----------
    lo, hi : (3,) array_like, m
        Region corners.
    radii : (n,) array_like, m
        Radii to place, in order of preference.
    existing, existing_radii : (M, 3) and (M,) arrays, optional
        Spheres already present.
    rng : int or Generator, optional
    max_attempts : int
        Candidate rounds before giving up on the rest.
    period : (3,) array_like, m, optional
        Length of the period along each periodic axis, 0 along the others
        (default: no periodic axis).

    Returns
    -------
    positions : (k, 3) ndarray, m
    placed : (n,) ndarray of bool
        Which of ``radii`` were placed (``k = placed.sum()``).

    Examples
    --------
    >>> pos, ok = raindrop_positions((0, 0, 0), (1e-3, 1e-3, 1e-3), np.full(20, 50e-6), rng=1)
    >>> pos.shape, bool(ok.all())
    ((20, 3), True)

    Periodic along y, the region spanning the period: centres anywhere in it

    >>> pos, ok = raindrop_positions((0, 0, 0), (2e-3, 0.3e-3, 2e-3), np.full(200, 50e-6),
    ...                              rng=1, period=(0, 0.3e-3, 0))
    >>> bool(pos[:, 1].max() > 0.3e-3 - 50e-6)
    True
    """
    rng = np.random.default_rng(rng)
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    radii = np.ascontiguousarray(radii, dtype=np.float64).reshape(-1)
    if np.any(hi <= lo):
        raise ConfigError(f"insertion region must have hi > lo; got lo={lo.tolist()}, hi={hi.tolist()}")
    ex = np.zeros((0, 3)) if existing is None else np.ascontiguousarray(existing, dtype=np.float64)
    er = np.zeros(0) if existing_radii is None else np.ascontiguousarray(existing_radii, dtype=np.float64)
    per = np.zeros(3) if period is None else np.asarray(period, dtype=np.float64).reshape(3)
    if np.any(~np.isfinite(per)) or np.any(per < 0):
        raise ConfigError(f"`period` must be lengths >= 0 (0: not periodic); got {per.tolist()}")
    # a periodic axis the region spans whole: centres anywhere in one period
    whole = (per > 0) & (hi - lo >= per * (1 - 1e-12))
    per = np.where(whole, per, 0.0)
    rmax = float(max(radii.max(initial=0.0), er.max(initial=0.0)))
    if np.any((hi - lo <= 2 * radii.max(initial=0.0)) & ~whole):
        raise ConfigError("insertion region is smaller than the largest sphere")
    cell = max(2 * rmax, 1e-12)
    glo = np.where(whole, lo, lo - 2 * rmax)
    ghi = np.where(whole, lo + per, hi + 2 * rmax)
    ncell = np.maximum(1, np.minimum(np.floor((ghi - glo) / cell), 200)).astype(np.int64)
    cell_len = (ghi - glo) / ncell
    keep = (np.all((ex >= glo) & (ex <= ghi) | whole, axis=1) if len(ex)
            else np.zeros(0, bool))
    ex = np.ascontiguousarray(ex[keep])
    er = np.ascontiguousarray(er[keep])
    placed = np.zeros(radii.size, dtype=bool)
    out = np.zeros((radii.size, 3))
    for _ in range(max_attempts):
        todo = np.flatnonzero(~placed)
        if todo.size == 0:
            break
        r = radii[todo]
        u = rng.random((todo.size, 3))
        cand = np.where(whole, lo + u * per, lo + r[:, None] + u * (hi - lo - 2 * r[:, None]))
        mask = np.zeros(todo.size, dtype=np.bool_)
        K.raindrop_accept(np.ascontiguousarray(cand), np.ascontiguousarray(r), ex, er, glo, cell_len,
                          ncell, per, mask)
        acc = todo[mask]
        out[acc] = cand[mask]
        placed[acc] = True
        ex = np.concatenate([ex, cand[mask]])
        er = np.concatenate([er, r[mask]])
    return out[placed], placed


def _psd_callable(psd) -> Callable:  # pragma: no cover - convenience
    return lambda n, rng: sample_radii(n, psd, rng=rng)


_ = math
