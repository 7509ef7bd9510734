"""Magnitude intervals from the profile of the chi-square.

The normal approximation at the optimum (``ModelFit.intervals``) reads the local slope of
the interpolated response as information about the magnitude. Where the response is flat
within its own noise over a wide range (the static angle of repose with capillary bridges
between relative humidities of 0.075 and 0.8) or bends between nodes, that slope says little,
and in the ``small`` engine validation the interval missed the true magnitude in 3 of 8
attributed twins. Here the chi-square is profiled instead: at each magnitude on a grid over
the prior the recalibration shifts (and a partner effect's magnitude, on its own grid) are
refitted, and the interval holds the magnitudes whose chi-square is within
``chi2_1(level)`` of the lowest.

The responses are means of a few runs, so each point carries the noise of its
interpolated prediction (:meth:`Fingerprint.predict_se`) as an added variance, correlated
between components read from one run like the data's (the effective-variance chi-square).
That variance grows with the magnitude, so the profile's lowest point can move off the
least-squares magnitude; the interval always holds the fitted magnitude.

.. versionadded:: 0.1
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from .fingerprints import FingerprintSet
from .noise_correlation import correlation_matrix

__all__ = ["ProfileInterval", "profile_interval"]

_GRID = 161          # magnitudes profiled over the prior (one effect)
_GRID_PAIR = 81      # ... and with a partner effect, whose magnitude is refitted at each
_PARTNER_GRID = 33   # of them on its own grid


@dataclass(frozen=True)
class ProfileInterval:
    """Profile of the chi-square over one effect's magnitude.

    Attributes
    ----------
    effect : str
    magnitudes, chi2 : (m,) ndarray
        The grid over the prior and the profiled (effective-variance) chi-square on it.
    interval : tuple of float
        Magnitudes whose chi-square is within ``threshold`` of the lowest, with the fitted
        magnitude (edges interpolated between grid points, clipped to the prior).
    threshold : float
        ``chi2_1`` quantile at the interval's level.
    """

    effect: str
    magnitudes: np.ndarray
    chi2: np.ndarray
    interval: tuple[float, float]
    threshold: float


def _chi2_batch(u0, S, R, preds, pred_se):
    """Effective-variance chi-square at many magnitude points, recalibration refitted.

    ``u0`` (n,) whitened-by-sigma residual, ``S`` (n, p) sensitivities, ``R`` (n, n)
    correlation, ``preds``/``pred_se`` (m, n) summed predictions and their standard error.
    """
    u = u0[None, :] - preds
    C = R[None] * (1.0 + pred_se[:, :, None] * pred_se[:, None, :])
    L = np.linalg.cholesky(C)
    uw = np.linalg.solve(L, u[..., None])[..., 0]
    chi2 = np.einsum("mi,mi->m", uw, uw)
    if S.shape[1]:
        Sw = np.linalg.solve(L, np.broadcast_to(S, (len(u),) + S.shape))
        # the recalibration's least-squares share, by its projection
        q, _ = np.linalg.qr(Sw)
        proj = np.einsum("mij,mi->mj", q, uw)
        chi2 = chi2 - np.einsum("mj,mj->m", proj, proj)
    return np.clip(chi2, 0.0, None)


def profile_interval(residual, fps: FingerprintSet, effects, effect: str, fitted: float, *,
                     rows=None, level: float = 0.95) -> ProfileInterval:
    """Interval of one effect's magnitude from the profiled chi-square.

    Parameters
    ----------
    residual : (n,) array_like
        ``real - mean(base runs)`` on all design rows.
    fps : FingerprintSet
    effects : sequence of str
        The model's effects (one or two); ``effect`` is one of them.
    effect : str
    fitted : float
        The model's least-squares magnitude of ``effect`` (always inside the interval).
    rows : (n,) bool array, optional
        Rows fitted; default the calibration rows.
    level : float

    Returns
    -------
    ProfileInterval

    Examples
    --------
    >>> from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue,
    ...                                 compute_fingerprints, diagnosis_design, twin_design)
    >>> effects = catalogue(["wall_friction"])
    >>> design = diagnosis_design(twin_design(), effects)
    >>> sim = SurrogateSimulator(design)
    >>> fps = compute_fingerprints(sim, design, BASE_PARAMETERS, effects, replicates=2)
    >>> residual = fps["wall_friction"].predict(0.25)     # the response at 0.25, no noise
    >>> prof = profile_interval(residual, fps, ["wall_friction"], "wall_friction", 0.25)
    >>> bool(prof.interval[0] < 0.25 < prof.interval[1])
    True
    >>> float(prof.magnitudes[prof.chi2.argmin()])        # the profile is lowest there
    0.25
    """
    rows = fps.rows_calibrate if rows is None else np.asarray(rows, bool)
    effects = list(effects)
    if effect not in effects or len(effects) > 2:
        raise ValueError(f"profile_interval: {effect!r} must be one of one or two effects, "
                         f"got {effects}")
    if not np.isfinite(float(fitted)):
        raise ValueError(f"profile_interval: the fitted magnitude of {effect!r} is {fitted}")
    sig = fps.sigma[rows]
    n = int(rows.sum())
    R = correlation_matrix(fps, rows)
    R = np.eye(n) if R is None else R
    u0 = np.asarray(residual, dtype=float)[rows] / sig
    bad = ~np.isfinite(u0)
    if bad.any():
        names = np.asarray(fps.design.component_names())[rows][bad]
        raise ValueError(f"profile_interval: the residual is not finite on fitted rows "
                         f"{', '.join(map(str, names[:5]))}{' ...' if bad.sum() > 5 else ''}: "
                         "leave unobserved components out of rows")
    S = fps.sensitivities[rows] / sig[:, None]
    f = fps[effect]
    lo, hi = (float(v) for v in f.effect.prior)
    size = _GRID if len(effects) == 1 else _GRID_PAIR
    grid = np.unique(np.r_[np.linspace(lo, hi, size), np.clip(float(fitted), lo, hi),
                           f.nodes[(f.nodes >= lo) & (f.nodes <= hi)]])

    def table(fp, mags):
        pred = np.array([fp.predict(a)[rows] for a in mags]) / sig
        # predict_se is piecewise linear in |a| between the simulated magnitudes: evaluated
        # there and interpolated (it is the slow part of the table)
        knots = np.r_[0.0, fp.magnitudes, [b for b, _ in fp.se_nodes]]
        knots = np.unique(np.r_[mags[0], mags[-1], knots, -knots])
        knots = knots[(knots >= mags[0]) & (knots <= mags[-1])]
        at = np.array([fp.predict_se(a)[rows] for a in knots])
        se = np.column_stack([np.interp(mags, knots, at[:, i]) for i in range(at.shape[1])])
        return pred, np.nan_to_num(se / sig)

    pred, se = table(f, grid)
    if len(effects) == 1:
        chi2 = _chi2_batch(u0, S, R, pred, se)
    else:
        g = fps[effects[1 - effects.index(effect)]]
        glo, ghi = (float(v) for v in g.effect.prior)
        partner = np.linspace(glo, ghi, _PARTNER_GRID)
        gpred, gse = table(g, partner)
        m, mp = len(grid), len(partner)
        both = _chi2_batch(u0, S, R,
                           (pred[:, None, :] + gpred[None, :, :]).reshape(m * mp, n),
                           np.sqrt(se[:, None, :] ** 2 + gse[None, :, :] ** 2).reshape(m * mp, n))
        chi2 = both.reshape(m, mp).min(axis=1)
    q = float(stats.chi2.ppf(level, 1))
    inside = chi2 <= chi2.min() + q
    idx = np.flatnonzero(inside)
    i0, i1 = idx[0], idx[-1]

    def edge(i, j):
        """Where the chi-square crosses the threshold between grid points i (in) and j (out)."""
        c_in, c_out, level_ = chi2[i], chi2[j], chi2.min() + q
        t = (level_ - c_in) / (c_out - c_in) if c_out != c_in else 0.0
        return float(grid[i] + np.clip(t, 0.0, 1.0) * (grid[j] - grid[i]))

    a_lo = float(grid[0]) if i0 == 0 else edge(i0, i0 - 1)
    a_hi = float(grid[-1]) if i1 == len(grid) - 1 else edge(i1, i1 + 1)
    fitted = float(np.clip(fitted, lo, hi))
    return ProfileInterval(effect, grid, chi2, (min(a_lo, fitted), max(a_hi, fitted)), q)
