"""Particle size distributions (PSD): measured from frames and fitted to percentiles.

Sizes are reported as **diameters** in the frame's length unit. Number
weighting counts particles; volume weighting (what laser diffraction reports)
weights each particle by ``d^3``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.frame import Frame, _as_frame

__all__ = ["PSDResult", "particle_size_distribution", "percentile_diameter", "psd_by_region",
           "psd_series", "PSDFit", "psd_from_percentiles", "psd_table"]

_WEIGHTINGS = ("number", "volume")


def _check_weighting(weighting):
    if weighting not in _WEIGHTINGS:
        raise ValueError(f"`weighting` must be 'number' or 'volume'; got {weighting!r}")


def _diameters(data) -> np.ndarray:
    if isinstance(data, Frame) or hasattr(data, "radii"):
        r = np.asarray(data.radii, dtype=np.float64)
    else:
        r = np.asarray(data, dtype=np.float64).reshape(-1)
    if r.size and not (np.all(np.isfinite(r)) and np.all(r > 0)):
        raise ValueError("radii must be positive and finite")
    return 2.0 * r


def percentile_diameter(diameters, q, *, weights=None) -> np.ndarray:
    """Diameters below which a fraction ``q`` of the (weighted) particles lie.

    Parameters
    ----------
    diameters : (N,) array_like of float, length
    q : float or array_like of float
        Fractions in [0, 1] (0.5 for D50).
    weights : (N,) array_like of float, optional
        Weights (``d**3`` for volume weighting); default equal.

    Returns
    -------
    float or ndarray, length

    Notes
    -----
    The empirical CDF is evaluated at the sorted diameters with midpoint
    plotting positions, :math:`F_k = (\\sum_{m \\le k} w_m - w_k/2)/\\sum w`,
    and interpolated linearly; below the first (above the last) position
    the smallest (largest) diameter is returned.

    Examples
    --------
    >>> float(percentile_diameter([1, 2, 3, 4], 0.5))
    2.5
    >>> float(percentile_diameter([1, 2, 3, 4], 0.5, weights=[1, 1, 1, 5]))
    3.5
    """
    d = np.asarray(diameters, dtype=np.float64).reshape(-1)
    if d.size == 0:
        return np.full(np.shape(q), np.nan) if np.ndim(q) else float("nan")
    w = np.ones_like(d) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != d.shape:
        raise ValueError(f"`weights` must match `diameters` ({d.shape}); got {w.shape}")
    order = np.argsort(d, kind="stable")
    d, w = d[order], w[order]
    c = np.cumsum(w)
    f = (c - 0.5 * w) / c[-1]
    out = np.interp(np.asarray(q, dtype=np.float64), f, d)
    return float(out) if np.ndim(out) == 0 else out


@dataclass(frozen=True)
class PSDResult:
    """A measured particle size distribution.

    Attributes
    ----------
    edges : (B + 1,) ndarray of float, length
        Bin edges (diameters).
    fraction : (B,) ndarray of float
        Weighted fraction per bin (sums to 1).
    density : (B,) ndarray of float, 1/length
        ``fraction / bin width``.
    cumulative : (B,) ndarray of float
        Weighted fraction below each upper edge.
    d10, d50, d90 : float, length
        Percentile diameters (see :func:`percentile_diameter`).
    mean_diameter : float, length
        Weighted mean diameter (number: arithmetic mean; volume: the
        De Brouckere mean D[4,3]).
    weighting : str
        ``"number"`` or ``"volume"``.
    n_particles : int
    diameters : (N,) ndarray of float, length
        The sorted diameters (for distances between PSDs).
    """

    edges: np.ndarray
    fraction: np.ndarray
    density: np.ndarray
    cumulative: np.ndarray
    d10: float
    d50: float
    d90: float
    mean_diameter: float
    weighting: str
    n_particles: int
    diameters: np.ndarray = field(repr=False)

    @property
    def centres(self) -> np.ndarray:
        """Bin centres (length)."""
        return 0.5 * (self.edges[1:] + self.edges[:-1])

    @property
    def weights(self) -> np.ndarray:
        """Per-particle weights matching ``diameters`` (1 or d^3)."""
        return np.ones_like(self.diameters) if self.weighting == "number" else self.diameters ** 3

    @property
    def span(self) -> float:
        """Relative width ``(D90 - D10) / D50``."""
        return (self.d90 - self.d10) / self.d50


def particle_size_distribution(data, *, weighting: str = "volume", bins=40,
                               range=None, log_bins: bool = False) -> PSDResult:
    """Number- or volume-weighted PSD of a frame (or of an array of radii).

    Parameters
    ----------
    data : Frame or (N,) array_like of float
        A frame, or the particle **radii** (length).
    weighting : {"volume", "number"}, optional
        Default ``"volume"`` (comparable with laser diffraction).
    bins : int or (B + 1,) array_like, optional
        Number of bins or the bin edges (diameters).
    range : (2,) array_like, optional
        Diameter range of the bins (default min to max diameter).
    log_bins : bool, optional
        Logarithmically spaced bins.

    Returns
    -------
    PSDResult

    .. versionadded:: 0.1

    Examples
    --------
    >>> r = np.array([1.0, 1.0, 1.0, 2.0])
    >>> p = particle_size_distribution(r, weighting="number", bins=[1, 3, 5])
    >>> p.fraction.tolist(), p.d50
    ([0.75, 0.25], 2.0)
    >>> particle_size_distribution(r, bins=[1, 3, 5]).fraction.tolist()   # by volume
    [0.2727272727272727, 0.7272727272727273]
    """
    _check_weighting(weighting)
    d = np.sort(_diameters(data))
    w = np.ones_like(d) if weighting == "number" else d ** 3
    if np.ndim(bins) == 0:
        if d.size == 0:
            lo, hi = (0.0, 1.0) if range is None else range
        else:
            lo, hi = (d[0], d[-1]) if range is None else range
        if hi <= lo:
            hi = lo * 1.001 + 1e-300 if lo > 0 else 1.0
        edges = (np.geomspace(lo, hi, int(bins) + 1) if log_bins
                 else np.linspace(lo, hi, int(bins) + 1))
    else:
        edges = np.asarray(bins, dtype=np.float64)
    hist, _ = np.histogram(d, bins=edges, weights=w)
    tot = hist.sum()
    frac = hist / tot if tot > 0 else np.full(hist.shape, np.nan)
    dv = percentile_diameter(d, [0.1, 0.5, 0.9], weights=w) if d.size else np.full(3, np.nan)
    mean = float(np.sum(w * d) / np.sum(w)) if d.size else float("nan")
    return PSDResult(edges=edges, fraction=frac, density=frac / np.diff(edges),
                     cumulative=np.cumsum(frac), d10=float(dv[0]), d50=float(dv[1]), d90=float(dv[2]),
                     mean_diameter=mean, weighting=weighting, n_particles=int(d.size), diameters=d)


def psd_by_region(frame, lower, upper, **kwargs) -> list[PSDResult]:
    """PSD of the particles whose centres lie in each window.

    Parameters
    ----------
    frame : Frame
    lower, upper : (K, 3) array_like of float, length
        Window corners (e.g. from :func:`bedstruct.analysis.bed_windows`).
    **kwargs
        Passed to :func:`particle_size_distribution` (use fixed ``bins``
        edges to compare regions).

    Returns
    -------
    list of PSDResult

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[1, 1, 1], [3, 1, 1]], [0.5, 0.8], box=[4, 2, 2])
    >>> [p.d50 for p in psd_by_region(f, [[0, 0, 0], [2, 0, 0]], [[2, 2, 2], [4, 2, 2]])]
    [1.0, 1.6]
    """
    frame = _as_frame(frame)
    lo = np.atleast_2d(np.asarray(lower, dtype=np.float64))
    hi = np.atleast_2d(np.asarray(upper, dtype=np.float64))
    if lo.shape != hi.shape or lo.shape[1:] != (3,):
        raise ValueError(f"`lower` and `upper` must both have shape (K, 3); got {lo.shape}, {hi.shape}")
    pos = frame.box.wrap(frame.positions)
    out = []
    for k in np.arange(lo.shape[0]):
        inside = np.all((pos >= lo[k]) & (pos < hi[k]), axis=1)
        out.append(particle_size_distribution(frame.radii[inside], **kwargs))
    return out


def psd_series(frames, *, mask=None, **kwargs) -> list[PSDResult]:
    """PSD of every frame (optionally of the particles selected by ``mask(frame)``).

    Examples
    --------
    >>> from bedstruct import Frame
    >>> fs = [Frame([[0, 0, 0]], [r], box=[2, 2, 2]) for r in (0.5, 0.6)]
    >>> [p.d50 for p in psd_series(fs)]
    [1.0, 1.2]
    """
    out = []
    for f in frames:
        r = f.radii if mask is None else f.radii[np.asarray(mask(f), dtype=bool)]
        out.append(particle_size_distribution(r, **kwargs))
    return out


def psd_table(results, labels=None) -> dict[str, np.ndarray]:
    """One row per PSD: label, n_particles, d10, d50, d90, mean_diameter.

    Examples
    --------
    >>> sorted(psd_table([]))
    ['d10', 'd50', 'd90', 'label', 'mean_diameter', 'n_particles']
    """
    results = list(results)
    labels = [str(k) for k in np.arange(len(results))] if labels is None else [str(x) for x in labels]
    return {"label": np.asarray(labels, dtype=str),
            "n_particles": np.asarray([r.n_particles for r in results], dtype=np.int64),
            "d10": np.asarray([r.d10 for r in results], dtype=np.float64),
            "d50": np.asarray([r.d50 for r in results], dtype=np.float64),
            "d90": np.asarray([r.d90 for r in results], dtype=np.float64),
            "mean_diameter": np.asarray([r.mean_diameter for r in results], dtype=np.float64)}


# ----------------------------------------------------------------- fitting
_Q = np.array([0.1, 0.5, 0.9])


def _base_cdf(family, p, d):
    from scipy import special
    d = np.asarray(d, dtype=np.float64)
    if family == "lognormal":
        mu, sigma = p
        with np.errstate(divide="ignore"):
            return special.ndtr((np.log(d) - mu) / sigma)
    lam, k = p
    return -np.expm1(-(np.clip(d, 0, None) / lam) ** k)


def _base_ppf(family, p, q):
    from scipy import special
    q = np.asarray(q, dtype=np.float64)
    if family == "lognormal":
        mu, sigma = p
        return np.exp(mu + sigma * special.ndtri(q))
    lam, k = p
    return lam * (-np.log1p(-q)) ** (1.0 / k)


def _base_pdf(family, p, d):
    d = np.asarray(d, dtype=np.float64)
    if family == "lognormal":
        mu, sigma = p
        z = (np.log(d) - mu) / sigma
        return np.exp(-0.5 * z * z) / (d * sigma * math.sqrt(2 * math.pi))
    lam, k = p
    x = d / lam
    return k / lam * x ** (k - 1) * np.exp(-x ** k)


@dataclass(frozen=True)
class PSDFit:
    """A size distribution fitted to measured percentiles, truncated to bounds.

    Attributes
    ----------
    family : str
        ``"lognormal"`` (parameters ``mu, sigma`` of ``ln d``) or
        ``"rosin-rammler"`` (parameters ``d63, n``: ``F = 1 - exp(-(d/d63)^n)``).
    params : tuple of 2 float
        Parameters of the chosen family (diameters in the input unit).
    bounds : tuple of 2 float
        Truncation range of diameters.
    weighting : str
        Basis of the percentiles and of :meth:`cdf` (``"volume"`` for laser
        diffraction, or ``"number"``).
    targets : (3,) ndarray
        Measured D10, D50, D90.
    fitted : (3,) ndarray
        D10, D50, D90 of the fitted truncated distribution.
    rms_log_error : float
        RMS of ``ln(fitted / targets)`` of the chosen family.
    alternatives : dict
        ``{family: (params, rms_log_error)}`` of every family tried.
    """

    family: str
    params: tuple
    bounds: tuple
    weighting: str
    targets: np.ndarray
    fitted: np.ndarray
    rms_log_error: float
    alternatives: dict

    def _mass(self):
        lo, hi = self.bounds
        g = _base_cdf(self.family, self.params, np.array([lo, hi]))
        return float(g[0]), float(g[1] - g[0])

    def cdf(self, d) -> np.ndarray:
        """Truncated CDF in the fit's weighting at diameters ``d``."""
        g0, m = self._mass()
        d = np.clip(np.asarray(d, dtype=np.float64), *self.bounds)
        return (_base_cdf(self.family, self.params, d) - g0) / m

    def ppf(self, q) -> np.ndarray:
        """Diameters at fractions ``q`` of the truncated distribution (fit's weighting)."""
        g0, m = self._mass()
        return _base_ppf(self.family, self.params, g0 + np.asarray(q, dtype=np.float64) * m)

    def pdf(self, d) -> np.ndarray:
        """Truncated density (1/length) in the fit's weighting."""
        _, m = self._mass()
        d = np.asarray(d, dtype=np.float64)
        inside = (d >= self.bounds[0]) & (d <= self.bounds[1])
        return np.where(inside, _base_pdf(self.family, self.params, np.clip(d, *self.bounds)) / m, 0.0)

    def number_cdf(self, d, *, n_grid: int = 4001) -> np.ndarray:
        """Number-weighted CDF at diameters ``d`` (converted from volume weighting if needed)."""
        if self.weighting == "number":
            return self.cdf(d)
        grid, c = self._number_grid(n_grid)
        return np.interp(np.asarray(d, dtype=np.float64), grid, c)

    def _number_grid(self, n_grid):
        lo, hi = self.bounds
        grid = np.geomspace(lo, hi, int(n_grid))
        q0 = self.pdf(grid) / grid ** 3          # number density ~ volume density / d^3
        seg = 0.5 * (q0[1:] + q0[:-1]) * np.diff(grid)
        c = np.concatenate([[0.0], np.cumsum(seg)])
        return grid, c / c[-1]

    def sample_diameters(self, n: int, *, seed=None, n_grid: int = 20001) -> np.ndarray:
        """Draw ``n`` particle diameters (number-weighted draws, so that the
        sample's ``weighting``-weighted PSD follows the fit)."""
        rng = np.random.default_rng(seed)
        u = rng.random(int(n))
        if self.weighting == "number":
            return self.ppf(u)
        grid, c = self._number_grid(n_grid)
        # inverse CDF by interpolation in log-diameter (density is smooth there)
        return np.exp(np.interp(u, c, np.log(grid)))

    def sample_radii(self, n: int, *, seed=None) -> np.ndarray:
        """Draw ``n`` particle radii (half of :meth:`sample_diameters`), length.

        Examples
        --------
        >>> fit = psd_from_percentiles(29.84, 52.08, 86.11, (25, 105))
        >>> r = fit.sample_radii(1000, seed=1)
        >>> bool(r.min() >= 12.5 and r.max() <= 52.5)
        True
        """
        return 0.5 * self.sample_diameters(n, seed=seed)


def _fit_family(family, targets, bounds):
    from scipy import optimize
    lo, hi = bounds
    z = np.log(targets)
    if family == "lognormal":
        from scipy import special
        x = special.ndtri(_Q)
        slope, icpt = np.polyfit(x, z, 1)
        p0 = np.array([icpt, max(slope, 1e-3)])
    else:
        x = np.log(-np.log1p(-_Q))          # ln(-ln(1-F)) = k ln d - k ln lam
        k, c = np.polyfit(z, x, 1)
        k = max(k, 0.1)
        p0 = np.array([math.exp(-c / k), k])

    def model(p):
        if p[1] <= 0 or (family != "lognormal" and p[0] <= 0):
            return np.full(3, 1e3)
        g = _base_cdf(family, p, np.array([lo, hi]))
        m = g[1] - g[0]
        if not m > 1e-12:
            return np.full(3, 1e3)
        d = _base_ppf(family, p, g[0] + _Q * m)
        return np.log(d) - z

    sol = optimize.least_squares(model, p0, xtol=1e-14, ftol=1e-14)
    res = model(sol.x)
    return tuple(float(v) for v in sol.x), float(np.sqrt(np.mean(res ** 2)))


def psd_from_percentiles(d10: float, d50: float, d90: float, bounds, *, weighting: str = "volume",
                         family: str = "auto") -> PSDFit:
    """Fit a log-normal and a Rosin-Rammler distribution to D10/D50/D90 and keep the better.

    Parameters
    ----------
    d10, d50, d90 : float, length
        Measured percentile diameters (any unit; results use the same).
    bounds : (2,) array_like of float, length
        Smallest and largest diameter; the distributions are truncated to it
        and fitted *as truncated* distributions.
    weighting : {"volume", "number"}, optional
        Basis of the percentiles: ``"volume"`` (default, laser diffraction)
        or ``"number"``.
    family : {"auto", "lognormal", "rosin-rammler"}, optional
        ``"auto"`` keeps the family with the smaller RMS log error.

    Returns
    -------
    PSDFit
        With :meth:`PSDFit.sample_radii` to draw particle radii.

    Raises
    ------
    ValueError
        If the percentiles are not increasing, or lie outside ``bounds``.

    Notes
    -----
    Log-normal: :math:`F(d) = \\Phi((\\ln d - \\mu)/\\sigma)`; Rosin-Rammler:
    :math:`F(d) = 1 - \\exp(-(d/d_{63})^n)`. Truncated to
    :math:`[d_{lo}, d_{hi}]`: :math:`F_t = (F(d) - F(d_{lo}))/(F(d_{hi}) - F(d_{lo}))`.
    Parameters minimise :math:`\\sum_p (\\ln F_t^{-1}(p) - \\ln D_p)^2` over
    p = 0.1, 0.5, 0.9 (Levenberg-Marquardt from the closed-form untruncated
    fit). Number-weighted draws from volume-weighted percentiles use the
    number density :math:`q_0(d) \\propto q_3(d)/d^3`.

    .. versionadded:: 0.1

    Examples
    --------
    >>> fit = psd_from_percentiles(29.84, 52.08, 86.11, (25, 105))   # the seed's CoCr powder
    >>> fit.family, round(fit.rms_log_error, 4)
    ('rosin-rammler', 0.0062)
    >>> fit.fitted.round(1).tolist()
    [30.1, 51.8, 86.5]
    """
    targets = np.array([d10, d50, d90], dtype=np.float64)
    _check_weighting(weighting)
    lo, hi = (float(b) for b in bounds)
    if not (np.all(np.isfinite(targets)) and targets[0] < targets[1] < targets[2] and targets[0] > 0):
        raise ValueError(f"percentiles must satisfy 0 < d10 < d50 < d90; got {targets.tolist()}")
    if not (0 < lo < targets[0] and targets[2] < hi):
        raise ValueError(f"`bounds` must enclose the percentiles with 0 < lower < d10 and d90 < upper; "
                         f"got bounds=({lo}, {hi}) for {targets.tolist()}")
    families = ("lognormal", "rosin-rammler") if family == "auto" else (family,)
    for fam in families:
        if fam not in ("lognormal", "rosin-rammler"):
            raise ValueError(f"`family` must be 'auto', 'lognormal' or 'rosin-rammler'; got {fam!r}")
    alts = {fam: _fit_family(fam, targets, (lo, hi)) for fam in families}
    best = min(alts, key=lambda k: alts[k][1])
    params, rms = alts[best]
    g = _base_cdf(best, params, np.array([lo, hi]))
    fitted = _base_ppf(best, params, g[0] + _Q * (g[1] - g[0]))
    return PSDFit(family=best, params=params, bounds=(lo, hi), weighting=weighting, targets=targets,
                  fitted=fitted, rms_log_error=rms, alternatives=alts)
