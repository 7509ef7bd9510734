"""Coordination number versus packing fraction: German's law and its fitted form."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["german_cn", "GermanFit", "fit_german_law", "GermanAlongBed", "german_law_along",
           "apart_from_bed", "GERMAN_WINDOWS", "GERMAN_MIN_PARTICLES"]

#: Default number of equal windows along the bed for German's-law fits.
GERMAN_WINDOWS = 12
#: Windows with fewer particles (by centre) are left out of the fit.
GERMAN_MIN_PARTICLES = 5


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
    determined : bool
        Whether ``a`` and ``b`` are separately determined (property;
        :attr:`undetermined_reason` says why not).
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

    @property
    def undetermined_reason(self) -> str | None:
        """Why the data do not determine ``a`` and ``b`` separately, or None when they do.

        ``a`` and ``b`` are determined when the fit has intervals (at least 3 points), the
        interval of ``b`` excludes 0 (the coordination number depends detectably on the
        packing fraction over the points' range) and the interval of ``a`` does not lie
        below 0 (``2a`` is the law's coordination at ``f -> 0``: a negative one is an
        extrapolation beyond a packing range too narrow to reach it). Otherwise ``a`` and
        ``b`` trade off along the data and their values describe the points' mean
        coordination only; ``unfitted_deviation`` (the original law's error) keeps its
        meaning either way.
        """
        lo, hi = float(self.f.min()), float(self.f.max())
        span = f"f = {lo:.3f}-{hi:.3f}"
        if not np.all(np.isfinite(self.a_ci + self.b_ci)):
            return f"{self.n_points} points leave no interval for a and b"
        level = f"{self.confidence:.0%}"
        if self.b_ci[0] <= 0.0 <= self.b_ci[1]:
            return (f"the coordination number shows no detectable dependence on the packing "
                    f"fraction over {span} (the {level} interval of b includes 0): a and b are not "
                    f"separately determined")
        if self.a_ci[1] < 0.0:
            return (f"the fitted law gives a negative coordination number at low packing "
                    f"(the {level} interval of a lies below 0): the range {span} is too narrow "
                    f"to extrapolate to f = 0, so a and b are not separately determined")
        return None

    @property
    def determined(self) -> bool:
        """Whether the data determine ``a`` and ``b`` separately (see
        :attr:`undetermined_reason`)."""
        return self.undetermined_reason is None


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
        se = [float(v) for v in np.sqrt(np.clip(np.diag(cov), 0.0, None))]  # exact fit: -0
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


_AXIS_NAMES = "xyz"


@dataclass(frozen=True)
class GermanAlongBed:
    """German's law fitted over windows along a bed, and the windows it used.

    Attributes
    ----------
    fit : GermanFit or None
        The fit over the windows used (None with fewer than 3 of them).
    n_windows : int
        Equal windows the bed region was split into along ``axis``.
    axis : int
        Direction along the bed (0, 1, 2).
    min_particles : int
        Windows with fewer particles (by centre) were left out.
    lower, upper : (n_windows, 3) ndarray of float, length
        Window corners.
    fractions : (n_windows,) ndarray of float
        Exact sphere-cuboid packing fraction of each window.
    cn : (n_windows,) ndarray of float
        Mean coordination number of the particles centred in each window
        (all their contacts counted; NaN when empty).
    n_particles : (n_windows,) ndarray of int
        Particles centred in each window.
    used : (n_windows,) ndarray of bool
        Windows that entered the fit.
    n_apart : int
        Particles apart from the bed (:func:`apart_from_bed`), left out of the bed region.
    """

    fit: GermanFit | None
    n_windows: int
    axis: int
    min_particles: int
    lower: np.ndarray
    upper: np.ndarray
    fractions: np.ndarray
    cn: np.ndarray
    n_particles: np.ndarray
    used: np.ndarray
    n_apart: int = 0

    @property
    def n_used(self) -> int:
        """Number of windows in the fit."""
        return int(np.count_nonzero(self.used))

    @property
    def definition(self) -> str:
        """One sentence saying which points were fitted."""
        apart = (f"; {self.n_apart} particle{'s' if self.n_apart != 1 else ''} apart from the "
                 f"bed left out" if self.n_apart else "")
        return (f"{self.n_used} of {self.n_windows} equal windows along {_AXIS_NAMES[self.axis]} "
                f"over the bed region (windows with at least {self.min_particles} particles"
                f"{apart}): exact sphere-cuboid packing fraction and mean coordination of the "
                f"particles centred there")


def apart_from_bed(frame, network) -> np.ndarray:
    """Particles apart from the bed: beyond the contact network's extent, by more than two
    of the largest diameters, along a bounded axis (one thrown up or left far from it).

    Parameters
    ----------
    frame : Frame
    network : (N,) array_like of bool
        The particles of the contact network (not rattlers).

    Returns
    -------
    (N,) ndarray of bool
        None when the frame has no network.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Box, Frame
    >>> pos = [[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [1.0, 0.5, 9.0]]
    >>> f = Frame(pos, [0.5, 0.5, 0.5], box=Box([0, 0, 0], [2, 1, 10], boundary="pp pp ff"))
    >>> apart_from_bed(f, [True, True, False]).tolist()
    [False, False, True]
    """
    pos = np.asarray(frame.positions, dtype=float)
    rad = np.asarray(frame.radii, dtype=float)
    net = np.asarray(network, dtype=bool)
    out = np.zeros(len(rad), dtype=bool)
    if not net.any():
        return out
    lo = (pos[net] - rad[net, None]).min(axis=0)
    hi = (pos[net] + rad[net, None]).max(axis=0)
    gap = 4.0 * float(rad.max())
    for a in range(3):
        if not frame.box.periodic[a]:
            out |= (pos[:, a] - rad > hi[a] + gap) | (pos[:, a] + rad < lo[a] - gap)
    return out


def german_law_along(frame, contacts=None, *, n_windows: int = GERMAN_WINDOWS, axis: int = 0,
                     min_particles: int = GERMAN_MIN_PARTICLES, coordination_result=None,
                     confidence: float = 0.95, check_state: bool = True) -> GermanAlongBed:
    """Fit German's law to the packing and coordination of windows along a bed.

    The one definition of a bed's German fit: the bed region
    (:func:`bedstruct.analysis.bed_windows`; particles apart from the bed,
    :func:`apart_from_bed`, are left out of it) is split into ``n_windows``
    equal windows along ``axis``; each gives its exact sphere-cuboid packing
    fraction (:func:`bedstruct.analysis.packing_along`) and the mean
    coordination number of the particles centred in it
    (:func:`bedstruct.analysis.coordination_by_window`); windows with at
    least ``min_particles`` particles are fitted by :func:`fit_german_law`.
    ``bedstruct report`` uses it with the defaults.

    Parameters
    ----------
    frame : Frame
    contacts : Contacts, optional
        Contacts of the frame (detected geometrically when omitted and no
        ``coordination_result`` is given).
    n_windows : int, optional
        Windows along the bed (default :data:`GERMAN_WINDOWS`, 12).
    axis : int, optional
        Direction along the bed (default 0, x).
    min_particles : int, optional
        Smallest particle count of a window in the fit (default 5).
    coordination_result : CoordinationResult, optional
        Per-particle coordination already computed for ``frame``.
    confidence : float, optional
        Level of the fit's confidence intervals (default 0.95).
    check_state : bool, optional
        Refuse a frame for which German's law is not meaningful, as
        :func:`bedstruct.analysis.bed_state` judges it (a moving bed, a
        dilute flow, a 2-D run, fewer than 10 particles), as ``bedstruct
        report`` does (default True). False fits whatever the frame shows.

    Returns
    -------
    GermanAlongBed
        ``fit`` is None when fewer than 3 windows qualify or their packing
        fractions are all equal.

    Raises
    ------
    ValueError
        If ``n_windows`` < 3, ``axis`` is not 0, 1 or 2, or ``min_particles``
        < 1; with ``check_state``, if German's law is not meaningful for the
        frame (the message says why).

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Box, Frame
    >>> g = np.stack(np.meshgrid(*[np.arange(k) + 0.5 for k in (24, 4, 4)], indexing="ij"), -1)
    >>> pos = g.reshape(-1, 3)
    >>> keep = (pos[:, 0] < 12) | (pos[:, 2] < 3)       # the second half is one layer thinner
    >>> bed = Frame(pos[keep], np.full(keep.sum(), 0.51), box=Box([0, 0, 0], [24, 4, 4], boundary="pp pp ff"))
    >>> g = german_law_along(bed, n_windows=6)
    >>> g.n_used, g.definition.split(":")[0]
    (6, '6 of 6 equal windows along x over the bed region (windows with at least 5 particles)')
    """
    from .coordination import coordination, coordination_by_window
    from .packing import bed_bounds, packing_along

    if int(n_windows) < 3:
        raise ValueError(f"`n_windows` must be at least 3 for a two-coefficient fit; got {n_windows}")
    if axis not in (0, 1, 2):
        raise ValueError(f"`axis` must be 0, 1 or 2; got {axis!r}")
    if int(min_particles) < 1:
        raise ValueError(f"`min_particles` must be at least 1; got {min_particles}")
    if check_state:
        from .bed_state import bed_state
        from .contacts import find_contacts
        if contacts is None:
            contacts = find_contacts(frame)
        min_contacts = coordination_result.min_contacts if coordination_result is not None else 2
        state = bed_state(frame, contacts, min_contacts=min_contacts, axis=axis)
        if not state.meaningful("german"):
            raise ValueError(f"German's law is not meaningful for this frame ({state.label}): "
                             f"{state.not_meaningful['german']}; pass check_state=False to fit anyway")
    if coordination_result is None:
        coordination_result = coordination(frame, contacts)
    apart = apart_from_bed(frame, ~np.asarray(coordination_result.rattlers, dtype=bool))
    bounds = bed_bounds(frame.select(~apart)) if apart.any() else None
    prof = packing_along(frame, int(n_windows), axis=axis, bounds=bounds)
    wins = coordination_by_window(frame, prof.lower, prof.upper, result=coordination_result)
    f = np.asarray(prof.fractions, dtype=np.float64)
    cn = np.asarray(wins.mean, dtype=np.float64)
    n = np.asarray(wins.n_particles, dtype=np.int64)
    used = (n >= int(min_particles)) & np.isfinite(f) & np.isfinite(cn)
    fit = None
    if used.sum() >= 3 and np.ptp(f[used]) > 0:
        fit = fit_german_law(f[used], cn[used], confidence=confidence)
    return GermanAlongBed(fit=fit, n_windows=int(n_windows), axis=int(axis), min_particles=int(min_particles),
                          lower=np.asarray(prof.lower), upper=np.asarray(prof.upper), fractions=f, cn=cn,
                          n_particles=n, used=used, n_apart=int(apart.sum()))
