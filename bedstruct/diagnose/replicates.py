"""Replicate runs of a simulator and their run-to-run scatter.

A simulator is any callable ``simulator(base, effects, seed) -> Observations``. The
diagnosis runs it at a few replicate seeds per parameter point; the scatter of those
replicates, pooled over the points, is the simulation noise every later step weighs
residuals by, taken at a one-sided upper confidence bound because two to four seeds
per point leave it poorly determined.

.. versionadded:: 0.1
"""

from __future__ import annotations

from typing import Callable, Mapping

import numpy as np
from scipy import stats

from .measurements import Observations
from .where import _nan_mean

__all__ = ["Simulator", "simulate_replicates", "variance_upper_bound", "VARIANCE_BOUND_LEVEL"]

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
