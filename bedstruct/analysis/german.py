"""Coordination number versus packing fraction: German's law and its fitted form."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["german_cn", "GermanFit", "fit_german_law"]


def german_cn(f, *, a: float = 1.0, b: float = 1.0) -> np.ndarray:
    """German's coordination number ``CN = 2a + 11 b f^2`` (``a = b = 1``: the original law).

    Parameters
    ----------
    f : array_like of float
        Packing fraction (dimensionless).
    a, b : float, optional
        Coefficients of the fitted form (1 for the original law).

    Returns
    -------
    ndarray of float
        Coordination number (dimensionless).

    Notes
    -----
    .. math:: CN_S = 2 + 11 f^2, \\qquad CN_m = 2a + 11 b f^2

    The first is German's semi-empirical law [1]_; the second the seed
    report's fitted form (eq. 8, a = 1.925, b = 0.04545).

    References
    ----------
    .. [1] R. M. German, "Coordination number changes during powder
       densification", Powder Technology 253 (2014) 368-376,
       doi:10.1016/j.powtec.2013.12.006.

    Examples
    --------
    >>> float(german_cn(0.5))
    4.75
    >>> round(float(german_cn(0.6, a=1.925, b=0.04545)), 4)
    4.03
    """
    f = np.asarray(f, dtype=np.float64)
    return 2.0 * a + 11.0 * b * f * f


@dataclass(frozen=True)
class GermanFit:
    """Least-squares fit of ``CN = 2a + 11 b f^2``.

    Attributes
    ----------
    a, b : float
        Fitted coefficients (dimensionless).
    a_ci, b_ci : tuple of 2 float
        Confidence intervals at ``confidence`` (Student t, n - 2 degrees of
        freedom); NaN with fewer than 3 points.
    covariance : (2, 2) ndarray
        Covariance of (a, b).
    f, cn : (n,) ndarray of float
        The data.
    residuals : (n,) ndarray of float
        ``cn - (2a + 11 b f^2)``.
    unfitted_residuals : (n,) ndarray of float
        ``cn - (2 + 11 f^2)``.
    unfitted_deviation : float
        Mean absolute difference between the original law and the measured
        CN, ``mean |CN_S(f) - cn|`` (the seed report's "deviated by 0.46").
    fitted_deviation : float
        The same for the fitted law.
    r_squared : float
        Coefficient of determination of the fit (NaN when cn is constant).
    confidence : float
        Confidence level of the intervals.
    """

    a: float
    b: float
    a_ci: tuple
    b_ci: tuple
    covariance: np.ndarray
    f: np.ndarray
    cn: np.ndarray
    residuals: np.ndarray
    unfitted_residuals: np.ndarray
    unfitted_deviation: float
    fitted_deviation: float
    r_squared: float
    confidence: float

    @property
    def n_points(self) -> int:
        """Number of (f, cn) points."""
        return int(self.f.shape[0])

    def predict(self, f) -> np.ndarray:
        """Fitted CN at packing fractions ``f``."""
        return german_cn(f, a=self.a, b=self.b)


def fit_german_law(f, cn, *, confidence: float = 0.95, weights=None) -> GermanFit:
    """Fit ``CN = 2a + 11 b f^2`` to packing fractions and coordination numbers.

    Parameters
    ----------
    f : (n,) array_like of float
        Packing fractions of windows, frames or runs (dimensionless).
    cn : (n,) array_like of float
        Mean coordination numbers of the same windows, frames or runs.
    confidence : float, optional
        Level of the confidence intervals (default 0.95).
    weights : (n,) array_like of float, optional
        Weights of the points (e.g. particle counts); default equal.

    Returns
    -------
    GermanFit

    Raises
    ------
    ValueError
        If shapes differ, values are not finite, fewer than 2 points are
        given, or all ``f`` are equal (a and b then cannot be separated).

    Notes
    -----
    Ordinary (or weighted) linear least squares on the design matrix
    ``[2, 11 f^2]``; intervals are ``estimate +- t_{(1+c)/2, n-2} * se``.

    .. versionadded:: 0.1

    Examples
    --------
    >>> f = np.array([0.50, 0.55, 0.60, 0.62])
    >>> fit = fit_german_law(f, 2 * 1.925 + 11 * 0.04545 * f ** 2)
    >>> round(fit.a, 4), round(fit.b, 5)
    (1.925, 0.04545)
    >>> round(fit.unfitted_deviation, 3)    # mean |2 + 11 f^2 - cn|
    1.554
    """
    from scipy import stats

    f = np.asarray(f, dtype=np.float64).reshape(-1)
    cn = np.asarray(cn, dtype=np.float64).reshape(-1)
    if f.shape != cn.shape:
        raise ValueError(f"`f` and `cn` must have the same length; got {f.shape[0]} and {cn.shape[0]}")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(cn))):
        raise ValueError("`f` and `cn` must be finite (drop empty windows first)")
    n = f.shape[0]
    if n < 2:
        raise ValueError(f"fitting two coefficients needs at least 2 points; got {n}")
    if np.ptp(f) == 0:
        raise ValueError("all packing fractions are equal; a and b cannot be separated")
    if not 0 < confidence < 1:
        raise ValueError(f"`confidence` must lie in (0, 1); got {confidence}")
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != (n,) or np.any(w < 0) or not np.any(w > 0):
        raise ValueError("`weights` must be n non-negative numbers, not all zero")
    X = np.stack([np.full(n, 2.0), 11.0 * f * f], axis=1)
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(X * sw[:, None], cn * sw, rcond=None)
    a, b = (float(c) for c in coef)
    pred = X @ coef
    res = cn - pred
    dof = n - 2
    nan2 = (float("nan"), float("nan"))
    if dof > 0:
        s2 = float(np.sum(w * res ** 2) / dof)   # weights are relative: scale from residuals
        cov = s2 * np.linalg.inv((X * w[:, None]).T @ X)
        t = float(stats.t.ppf(0.5 + confidence / 2, dof))
        se = np.sqrt(np.diag(cov))
        a_ci = (a - t * se[0], a + t * se[0])
        b_ci = (b - t * se[1], b + t * se[1])
    else:
        cov = np.full((2, 2), np.nan)
        a_ci = b_ci = nan2
    ss_tot = float(np.sum(w * (cn - np.average(cn, weights=w)) ** 2))
    r2 = 1.0 - float(np.sum(w * res ** 2)) / ss_tot if ss_tot > 0 else float("nan")
    unfit = cn - german_cn(f)
    return GermanFit(a=a, b=b, a_ci=a_ci, b_ci=b_ci, covariance=cov, f=f, cn=cn, residuals=res,
                     unfitted_residuals=unfit, unfitted_deviation=float(np.mean(np.abs(unfit))),
                     fitted_deviation=float(np.mean(np.abs(res))), r_squared=r2,
                     confidence=float(confidence))
