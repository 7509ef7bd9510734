"""Where is the gap: standardised residuals per observable, condition and time window.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from .noise_correlation import correlation_among, quadratic_form
from .measurements import MeasurementSet

__all__ = ["standardised_residuals", "Residuals", "GapGroup", "WhereResult", "where", "where_table"]


def standardised_residuals(real, sigma_meas, sim_samples, *, sim_var=None):
    """Residuals of real data against the simulation mean, in units of their combined noise.

    Parameters
    ----------
    real : (n,) array_like of float
        Measured values.
    sigma_meas : (n,) array_like of float
        Measurement standard deviations (same units), > 0.
    sim_samples : (R, n) array_like of float
        Replicate simulations (different seeds) at the same parameters.
    sim_var : (n,) array_like of float, optional
        Replicate variance of one simulation run; default the sample variance of
        ``sim_samples`` (needs R >= 2). Pass a pooled estimate when available.

    Returns
    -------
    z : (n,) ndarray
        Standardised residuals (dimensionless).
    sigma : (n,) ndarray
        Combined standard deviation of ``real - mean(sim)``.
    sim_mean : (n,) ndarray

    Notes
    -----
    .. math:: z_i = \\frac{y_i - \\bar s_i}{\\sqrt{\\sigma_{m,i}^2 + s_i^2/R}}

    Examples
    --------
    >>> z, sig, mu = standardised_residuals([10.0], [0.3], [[9.0], [9.8], [9.2]])
    >>> mu, np.round(sig, 3), np.round(z, 2)
    (array([9.33333333]), array([0.384]), array([1.73]))
    """
    y = np.asarray(real, dtype=float).ravel()
    sm = np.asarray(sigma_meas, dtype=float).ravel()
    s = np.atleast_2d(np.asarray(sim_samples, dtype=float))
    if s.shape[1] != y.size or sm.shape != y.shape:
        raise ValueError(f"`real` ({y.size}), `sigma_meas` ({sm.size}) and `sim_samples` columns "
                         f"({s.shape[1]}) must have the same length")
    # a replicate that could not observe a component (NaN) is missing data: each component
    # is averaged over its own finite replicates; with none, its z is NaN
    R = np.sum(np.isfinite(s), axis=0)
    if sim_var is None:
        if s.shape[0] < 2:
            raise ValueError("need >= 2 replicate simulations to estimate the simulation noise "
                             "(or pass `sim_var`)")
        sim_var = _nan_var(s)
    sim_var = np.asarray(sim_var, dtype=float).ravel()
    mu = _nan_mean(s)
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = np.where(R > 0, np.sqrt(sm ** 2 + sim_var / np.maximum(R, 1)), np.nan)
    seen = R > 0
    if np.any(~(sigma[seen] > 0)):
        raise ValueError("combined noise is zero or invalid for some components; state measurement "
                         "uncertainties > 0")
    return (y - mu) / sigma, sigma, mu


def _nan_mean(samples) -> np.ndarray:
    """Column means over finite entries (NaN where a column has none), without warnings."""
    s = np.asarray(samples, dtype=float)
    ok = np.isfinite(s)
    n = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.where(ok, s, 0.0).sum(axis=0) / n, np.nan)


def _nan_var(samples) -> np.ndarray:
    """Column variances (ddof 1) over finite entries (NaN with fewer than two)."""
    s = np.asarray(samples, dtype=float)
    ok = np.isfinite(s)
    n = ok.sum(axis=0)
    d = np.where(ok, s - _nan_mean(s), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 1, (d * d).sum(axis=0) / (n - 1), np.nan)


@dataclass(frozen=True)
class Residuals:
    """Per-component residuals with their metadata (all arrays of length n)."""

    names: np.ndarray
    labels: np.ndarray
    kinds: np.ndarray
    roles: np.ndarray
    conditions: np.ndarray
    units: np.ndarray
    real: np.ndarray
    sim_mean: np.ndarray
    sigma_meas: np.ndarray
    sigma_sim: np.ndarray
    sigma: np.ndarray
    z: np.ndarray

    @property
    def n(self) -> int:
        return len(self.z)


@dataclass(frozen=True)
class GapGroup:
    """Aggregate of residuals over a group of components."""

    group: str
    key: str
    n: int
    chi2: float
    rms_z: float
    max_z: float
    p_value: float


@dataclass(frozen=True)
class WhereResult:
    """Where the simulation and the data disagree.

    Attributes
    ----------
    residuals : Residuals
    order : (n,) ndarray of int
        Component indices ranked by ``|z|``, largest first.
    groups : tuple of GapGroup
        Aggregates by observable, by kind and time window, and by role, ranked by chi2/n.
    chi2, dof, p_value : float
        Global chi-square test of "no gap" (all components).
    max_abs_z, p_max : float
        Largest ``|z|`` and its Sidak-corrected p-value.
    significant : bool
        Whether either test rejects "no gap" at ``alpha`` (split between the two).
    summary : tuple of str
        Sentences such as ``"dynamic angle, first 10 % of stroke: +6.1 sigma"``.
    """

    residuals: Residuals
    order: np.ndarray
    groups: tuple[GapGroup, ...]
    chi2: float
    dof: int
    p_value: float
    max_abs_z: float
    p_max: float
    significant: bool
    alpha: float
    summary: tuple[str, ...]

    def ranked(self, n: int | None = None) -> list[dict]:
        """The ranked table as a list of dicts (largest ``|z|`` first)."""
        r = self.residuals
        rows = []
        for i in self.order[:n]:
            rows.append({"observable": str(r.names[i]), "component": str(r.labels[i]),
                         "kind": str(r.kinds[i]), "role": str(r.roles[i]),
                         "conditions": str(r.conditions[i]), "unit": str(r.units[i]),
                         "real": float(r.real[i]), "simulated": float(r.sim_mean[i]),
                         "residual": float(r.real[i] - r.sim_mean[i]), "sigma": float(r.sigma[i]),
                         "z": float(r.z[i])})
        return rows


def _component_meta(ms: MeasurementSet):
    cond, units = [], []
    for m in ms:
        cond += [m.conditions.label()] * m.n_components
        units += [m.unit] * m.n_components
    return np.asarray(cond, dtype=str), np.asarray(units, dtype=str)


def _window_key(label: str) -> str:
    return label if label.startswith("t=") else ""


def where(measurements: MeasurementSet, sim_samples, *, sim_var=None, alpha: float = 0.05,
          correlation=None) -> WhereResult:
    """Rank where the simulation misses the measurements.

    Parameters
    ----------
    measurements : MeasurementSet
        Real data (calibrate and validate observables; candidates are ignored).
    sim_samples : (R, n) array_like
        Replicate simulations of the same components, in file order.
    sim_var : (n,) array_like, optional
        Pooled replicate variance of one run (see :func:`standardised_residuals`).
    alpha : float
        Significance level of the "no gap" tests.
    correlation : (n, n) array_like, optional
        Correlation of the components' noise
        (:func:`~bedstruct.diagnose.noise_correlation.correlation_matrix`): the chi-squares
        of the groups and of the whole are then ``z^T R^{-1} z``, so that a deviation read
        twice from one run counts about once; the ranking stays on each component's own z.

    Returns
    -------
    WhereResult
    """
    ms = measurements.select(("calibrate", "validate"))
    s = np.atleast_2d(np.asarray(sim_samples, dtype=float))
    y, sm = ms.values(), ms.uncertainty()
    z, sigma, mu = standardised_residuals(y, sm, s, sim_var=sim_var)
    var1 = np.asarray(sim_var, float) if sim_var is not None else _nan_var(s)
    cond, units = _component_meta(ms)
    res = Residuals(ms.component_names(), ms.component_labels(), ms.kinds(), ms.roles(), cond, units,
                    y, mu, sm, np.sqrt(var1), sigma, z)
    order = np.argsort(-np.abs(z), kind="stable")

    groups = []

    def add(group, key, idx):
        zz = z[idx]
        chi2 = (float(np.sum(zz ** 2)) if correlation is None
                else quadratic_form(zz, correlation_among(correlation, idx))[0])
        j = int(np.argmax(np.abs(zz)))
        groups.append(GapGroup(group, key, len(idx), chi2, math.sqrt(chi2 / len(idx)), float(zz[j]),
                               float(stats.chi2.sf(chi2, len(idx)))))

    for name in dict.fromkeys(res.names):
        add("observable", str(name), np.flatnonzero(res.names == name))
    kw = np.asarray([f"{k} {_window_key(lab)}".strip() for k, lab in zip(res.kinds, res.labels)])
    for key in dict.fromkeys(kw):
        add("kind/window", str(key), np.flatnonzero(kw == key))
    for role in dict.fromkeys(res.roles):
        add("role", str(role), np.flatnonzero(res.roles == role))
    groups.sort(key=lambda g: -g.chi2 / g.n)

    n = len(z)
    chi2 = float(np.sum(z ** 2)) if correlation is None else quadratic_form(z, correlation)[0]
    p = float(stats.chi2.sf(chi2, n))
    mx = float(np.max(np.abs(z))) if n else 0.0
    p1 = 2.0 * stats.norm.sf(mx)
    p_max = float(-np.expm1(n * np.log1p(-min(p1, 1 - 1e-16))))
    significant = bool(min(p, p_max) < alpha / 2)
    summary = []
    for g in groups:
        if g.group != "observable":
            continue
        i = np.flatnonzero(res.names == g.key)
        k = i[np.argmax(np.abs(z[i]))]
        summary.append(f"{g.key} [{res.labels[k]}; {res.conditions[k]}]: {z[k]:+.1f} sigma"
                       + ("" if abs(z[k]) > 2 else " (within noise)"))
    return WhereResult(res, order, tuple(groups), chi2, n, p, mx, p_max, significant, alpha, tuple(summary))


def where_table(result: WhereResult) -> dict[str, np.ndarray]:
    """The ranked residual table as equal-length columns (for pandas)."""
    rows = result.ranked()
    cols = ["observable", "component", "kind", "role", "conditions", "unit", "real", "simulated",
            "residual", "sigma", "z"]
    out = {}
    for c in cols:
        vals = [r[c] for r in rows]
        out[c] = np.asarray(vals, dtype=float if c in ("real", "simulated", "residual", "sigma", "z")
                            else str)
    return out
