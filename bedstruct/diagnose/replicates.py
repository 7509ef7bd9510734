"""Replicate runs of a simulator and their run-to-run scatter.

A simulator is any callable ``simulator(base, effects, seed) -> Observations``. The
diagnosis runs it at a few replicate seeds per parameter point; the scatter of those
replicates, pooled over the points that scatter like the base point, is the simulation
noise every later step weighs residuals by, taken at a one-sided upper confidence bound
because two to four seeds per point leave it poorly determined.

.. versionadded:: 0.1
"""

from __future__ import annotations

from typing import Callable, Mapping

import numpy as np
from scipy import stats

from .measurements import Observations
from .where import _nan_mean, _nan_var

__all__ = ["Simulator", "simulate_replicates", "variance_upper_bound", "VARIANCE_BOUND_LEVEL",
           "scatter_homogeneity", "homogeneous_variance"]

#: The simulator interface: ``simulator(base, effects, seed) -> Observations``.
Simulator = Callable[[Mapping[str, float], Mapping[str, float], int], Observations]


def simulate_replicates(simulator: Simulator, base, effects, seeds, names) -> np.ndarray:
    """Run ``simulator`` once per seed and stack the components of ``names``.

    Returns
    -------
    (R, n) ndarray
    """
    prefetch = getattr(simulator, "prefetch", None)
    if prefetch is not None:  # a simulator that can run a batch in parallel
        prefetch([(dict(base), dict(effects), int(sd)) for sd in seeds])
    rows = []
    for sd in seeds:
        obs = simulator(dict(base), dict(effects), int(sd))
        if not isinstance(obs, Observations):
            raise TypeError(f"the simulator must return an Observations object; got {type(obs).__name__}")
        rows.append(obs.vector(names))
    return np.asarray(rows)


#: One-sided confidence level of the run-to-run variance used by the diagnosis.
VARIANCE_BOUND_LEVEL = 0.84


def variance_upper_bound(dof) -> np.ndarray:
    """Factor from a pooled variance estimate to its one-sided upper confidence bound.

    ``dof / chi2.ppf(1 - VARIANCE_BOUND_LEVEL, dof)``: 2.2 at 6 degrees of freedom,
    1.34 at 30, tending to 1; NaN without a degree of freedom.

    Examples
    --------
    >>> np.round(variance_upper_bound([6, 30, 1000]), 2)
    array([2.19, 1.34, 1.05])
    """
    nu = np.asarray(dof, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(nu > 0, nu / stats.chi2.ppf(1.0 - VARIANCE_BOUND_LEVEL, np.maximum(nu, 1)),
                        np.nan)


def _pooled_variance(groups):
    """Run-to-run variance pooled over parameter points (finite replicates of each) and its
    degrees of freedom per component."""
    ss, dof = 0.0, 0
    for g in groups:
        g = np.asarray(g, float)
        d = g - _nan_mean(g)
        ss = ss + np.where(np.isfinite(d), d * d, 0.0).sum(axis=0)
        dof = dof + np.maximum(np.isfinite(g).sum(axis=0) - 1, 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(dof > 0, ss / np.maximum(dof, 1), np.nan), np.asarray(dof)


def scatter_homogeneity(groups) -> tuple[np.ndarray, np.ndarray]:
    """Bartlett's test that every parameter point scatters alike, per component.

    The diagnosis pools one run-to-run variance over its parameter points; this says
    where the replicates contradict that.

    Parameters
    ----------
    groups : sequence of (R_k, n) array_like
        Replicates of each parameter point; NaN where a run did not observe a component.

    Returns
    -------
    p_value : (n,) ndarray
        Bartlett p-value over the points with at least two finite replicates; NaN where
        fewer than two points can be compared or a point shows no scatter at all
        (identical replicates: nothing to weigh).
    sd : (k, n) ndarray
        Replicate standard deviation of each point (NaN with fewer than two replicates).

    Notes
    -----
    With two or three seeds per point a variance has one or two degrees of freedom, and
    the test needs a large spread of the standard deviations to reject: at two seeds,
    per-point standard deviations of 0.004 and 0.07 are still consistent with one scatter.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> same = [rng.normal(0.0, 1.0, (4, 1)) for _ in range(6)]
    >>> grows = [rng.normal(0.0, 10.0 ** k, (4, 1)) for k in range(-2, 4)]
    >>> bool(scatter_homogeneity(same)[0][0] > 0.01), bool(scatter_homogeneity(grows)[0][0] < 1e-6)
    (True, True)
    """
    groups = [np.atleast_2d(np.asarray(g, dtype=float)) for g in groups]
    n = groups[0].shape[1] if groups else 0
    sd = np.full((len(groups), n), np.nan)
    p = np.full(n, np.nan)
    if not groups:
        return p, sd
    for k, g in enumerate(groups):
        sd[k] = np.sqrt(_nan_var(g))
    for i in range(n):
        cols = [g[:, i][np.isfinite(g[:, i])] for g in groups]
        cols = [c for c in cols if c.size >= 2]
        if len(cols) < 2 or any(np.ptp(c) == 0.0 for c in cols):
            continue
        p[i] = stats.bartlett(*cols).pvalue
    return p, sd


def homogeneous_variance(groups, *, alpha: float = 0.01):
    """Run-to-run variance pooled over the parameter points that scatter like the first one.

    Per component, Bartlett's test (:func:`scatter_homogeneity`) is applied to the points;
    while it rejects at ``alpha`` over the number of components tested (Bonferroni), the
    point with the largest scatter is set aside (never the first, the base point) and the
    test repeated on the rest. The variance pooled over the points kept is the scatter of
    the base point's neighbourhood; a point set aside keeps its own.

    Parameters
    ----------
    groups : sequence of (R_k, n) array_like
        Replicates of each parameter point, the base point first; NaN where a run did not
        observe a component.
    alpha : float
        Family-wise level of the tests.

    Returns
    -------
    variance, dof : (n,) ndarray
        Pooled variance of one run over the points kept, and its degrees of freedom.
    set_aside : (k, n) ndarray of bool
        The points set aside per component.
    p_value : (n,) ndarray
        Bartlett p-value over all points (NaN where untestable).

    Examples
    --------
    Six points scatter alike; a seventh, one hundred times as much:

    >>> rng = np.random.default_rng(3)
    >>> groups = [rng.normal(0.0, 1.0, (3, 1)) for _ in range(6)] + [rng.normal(0.0, 100.0, (3, 1))]
    >>> var, dof, aside, p = homogeneous_variance(groups)
    >>> aside[:, 0].tolist(), int(dof[0]), bool(var[0] < 5.0)
    ([False, False, False, False, False, False, True], 12, True)
    """
    groups = [np.atleast_2d(np.asarray(g, dtype=float)) for g in groups]
    p_all, sd = scatter_homogeneity(groups)
    n = p_all.size
    aside = np.zeros((len(groups), n), dtype=bool)
    level = alpha / max(int(np.isfinite(p_all).sum()), 1)
    for i in np.flatnonzero(np.isfinite(p_all) & (p_all < level)):
        while True:
            kept = [k for k in range(len(groups)) if not aside[k, i]]
            p, _ = scatter_homogeneity([groups[k][:, i:i + 1] for k in kept])
            if not (np.isfinite(p[0]) and p[0] < level):
                break
            noisiest = max((k for k in kept[1:] if np.isfinite(sd[k, i])), key=lambda k: sd[k, i],
                           default=None)
            if noisiest is None:
                break
            aside[noisiest, i] = True
    masked = [np.where(aside[k][None, :], np.nan, g) for k, g in enumerate(groups)]
    var, dof = _pooled_variance(masked)
    return var, dof, aside, p_all
