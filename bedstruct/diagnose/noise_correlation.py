"""Correlated run-to-run noise: generalised least squares for components read from one run.

Some measured components come from the same run or the same sample (the early and steady
windows of one dynamic angle at a speed where the stroke is short, the percentiles of one
PSD); their run-to-run deviations move together.
:func:`~bedstruct.diagnose.identifiability._correlated_scatter` lists such pairs from the
fingerprint runs (``FingerprintSet.meta["correlated_scatter"]``). Treating them as
independent counts a common deviation about twice: a noise excursion looks like a gap, and
an effect that moves both looks twice as certain as it is.

The statistics instead whiten by the noise's correlation: with ``R`` the correlation matrix
of the listed pairs (identity elsewhere) and ``R = L L^T``, residuals already divided by
their standard deviations are multiplied by ``L^{-1}``; chi-squares, fits and gap sizes are
then taken in that metric. Each listed correlation enters at the lower bound of its 95 %
confidence interval (Fisher's z over the pair's degrees of freedom), and at most 0.95
(:func:`effective_correlation`): a correlation taken
too high would overweight the *difference* of the two readings, which the runs determine
less well, and turn noise there into a gap; one taken lower only keeps part of the double
count. Where no pair is listed nothing changes (:func:`decorrelator` returns ``None`` and
the callers keep their plain division).

The measurement's own noise is taken to share the correlation: a twin's readings come from
runs just as the simulation's do, and a real experiment reads the two windows of one
dynamic angle from one stroke.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math

import numpy as np
from scipy import linalg

__all__ = ["component_keys", "conservative_correlation", "correlation_among", "correlation_matrix",
           "effective_correlation",
           "decorrelator", "inverse_cholesky", "quadratic_form", "whiten"]

#: Lower end of a two-sided 95 % interval: z - 1.96 se.
_Z95 = 1.959963984540054
#: Largest correlation used (the smallest eigenvalue of a lone pair's matrix is 1 - this).
_R_MAX = 0.95


def component_keys(design) -> list[str]:
    """Names of a design's components as the correlated-scatter notes give them.

    A single-component observable by its name, a component of a multi-component one by its
    name and label (``"psd_before d50"``).
    """
    names, labels = design.component_names(), design.component_labels()
    single = {m.name: m.n_components == 1 for m in design}
    return [str(n) if single[str(n)] else f"{n} {lab}" for n, lab in zip(names, labels)]


def conservative_correlation(r: float, dof: int) -> float:
    """The lower end of a correlation's 95 % confidence interval, towards zero.

    Fisher's z with standard error ``1 / sqrt(dof - 2)`` (``dof`` degrees of freedom of the
    residuals the correlation was computed from); 0 when the interval holds zero.

    Examples
    --------
    >>> round(conservative_correlation(0.95, 15), 3)
    0.859
    >>> round(conservative_correlation(-0.95, 15), 3)
    -0.859
    >>> conservative_correlation(0.3, 5)
    0.0
    """
    r = float(np.clip(r, -0.999999, 0.999999))
    se = 1.0 / math.sqrt(max(int(dof) - 2, 1))
    z = max(abs(math.atanh(r)) - _Z95 * se, 0.0)
    return math.copysign(math.tanh(z), r)


def effective_correlation(r: float, dof: int) -> float:
    """The correlation a listed pair enters the statistics with: the lower end of its 95 %
    interval (:func:`conservative_correlation`), kept within ±0.95.

    Examples
    --------
    >>> effective_correlation(0.999, 40)
    0.95
    >>> round(effective_correlation(0.93, 76), 3)
    0.892
    """
    return float(np.clip(conservative_correlation(r, dof), -_R_MAX, _R_MAX))


def correlation_matrix(fps, rows=None) -> np.ndarray | None:
    """Correlation of the noise among ``rows`` of ``fps`` (``None``: independent).

    Parameters
    ----------
    fps : FingerprintSet
        Its ``meta["correlated_scatter"]`` lists the correlated pairs (``components``,
        ``r``, ``dof``).
    rows : (n,) bool array or index array, optional
        Design components to keep, in order (default all).

    Returns
    -------
    (m, m) ndarray or None
        Identity except at the listed pairs (their :func:`effective_correlation`);
        ``None`` when no listed pair has both components among ``rows``. Each
        correlation is kept within ±0.95: two readings that agree to rounding would
        otherwise give their difference, which is noise of another kind, an unbounded
        weight (with 0.95 a deviation read twice counts 1.05 times). Chains of pairs
        that would take the smallest eigenvalue below 0.05 (or make the matrix
        indefinite) are pulled towards the identity just enough to keep it there.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from bedstruct.diagnose import MeasurementSet, measurement_from_dict
    >>> design = MeasurementSet(tuple(measurement_from_dict(dict(
    ...     name=n, kind="static_angle", value=0.0, uncertainty=1.0, role="calibrate"))
    ...     for n in ("a", "b", "c")))
    >>> fps = SimpleNamespace(design=design, meta={"correlated_scatter": [
    ...     {"components": ["a", "b"], "r": 0.95, "dof": 15}]})
    >>> correlation_matrix(fps).round(3)
    array([[1.   , 0.859, 0.   ],
           [0.859, 1.   , 0.   ],
           [0.   , 0.   , 1.   ]])
    >>> correlation_matrix(fps, rows=np.array([True, False, True])) is None
    True
    """
    pairs = (getattr(fps, "meta", None) or {}).get("correlated_scatter") or []
    if not pairs:
        return None
    keys = component_keys(fps.design)
    idx = np.arange(len(keys)) if rows is None else np.asarray(rows)
    if idx.dtype == bool:
        idx = np.flatnonzero(idx)
    pos = {keys[i]: k for k, i in enumerate(idx)}
    R = np.eye(len(idx))
    any_pair = False
    for p in pairs:
        a, b = p["components"]
        if a in pos and b in pos:
            r = effective_correlation(float(p["r"]), int(p.get("dof", 0)))
            if r != 0.0:
                R[pos[a], pos[b]] = R[pos[b], pos[a]] = r
                any_pair = True
    if not any_pair:
        return None
    lam = float(np.linalg.eigvalsh(R).min())
    if lam < 1.0 - _R_MAX - 1e-12:
        # a chain of pairs: shrink the off-diagonal part to the same smallest eigenvalue
        t = _R_MAX / (1.0 - lam)
        R = t * R + (1.0 - t) * np.eye(len(R))
    return R


def decorrelator(fps, rows=None) -> np.ndarray | None:
    """``L^{-1}`` for the noise correlation ``R = L L^T`` on ``rows`` (``None``: independent).

    Multiply residuals already divided by their standard deviations by it to whiten them.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from bedstruct.diagnose import MeasurementSet, measurement_from_dict
    >>> design = MeasurementSet(tuple(measurement_from_dict(dict(
    ...     name=n, kind="static_angle", value=0.0, uncertainty=1.0, role="calibrate"))
    ...     for n in ("a", "b")))
    >>> fps = SimpleNamespace(design=design, meta={"correlated_scatter": [
    ...     {"components": ["a", "b"], "r": 0.95, "dof": 15}]})
    >>> W = decorrelator(fps)
    >>> z = W @ np.array([2.0, 2.0])        # one common deviation read twice
    >>> round(float(z @ z), 2)               # counted once (4.0), not twice (8.0)
    4.3
    """
    R = correlation_matrix(fps, rows)
    return None if R is None else inverse_cholesky(R)


def inverse_cholesky(R) -> np.ndarray:
    """``L^{-1}`` with ``R = L L^T`` (``L`` lower triangular): ``L^{-1} R L^{-T} = I``.

    Examples
    --------
    >>> R = np.array([[1.0, 0.5], [0.5, 1.0]])
    >>> W = inverse_cholesky(R)
    >>> np.allclose(W @ R @ W.T, np.eye(2))
    True
    """
    L = np.linalg.cholesky(np.asarray(R, dtype=float))
    return linalg.solve_triangular(L, np.eye(len(L)), lower=True)


def whiten(W, x):
    """``W @ x`` for a vector or a matrix of columns; ``x`` itself when ``W`` is ``None``."""
    return x if W is None else W @ x


def correlation_among(correlation, rows):
    """The correlation among ``rows`` (a boolean mask or indices); ``None`` stays ``None``.

    Examples
    --------
    >>> R = np.array([[1.0, 0.5, 0.0], [0.5, 1.0, 0.0], [0.0, 0.0, 1.0]])
    >>> correlation_among(R, np.array([True, True, False]))
    array([[1. , 0.5],
           [0.5, 1. ]])
    >>> correlation_among(None, [0, 1]) is None
    True
    """
    if correlation is None:
        return None
    rows = np.asarray(rows)
    return np.asarray(correlation, dtype=float)[np.ix_(rows, rows)]


def quadratic_form(z, correlation=None) -> tuple[float, int]:
    """``z^T R^{-1} z`` over the finite entries of ``z``, and their number.

    ``correlation`` is ``R`` for all entries of ``z`` (``None``: the identity, ``z @ z``);
    a component no run observed (NaN) carries no evidence and drops out with its row and
    column.

    Examples
    --------
    >>> quadratic_form([2.0, 2.0, np.nan])
    (8.0, 2)
    >>> R = np.array([[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 1.0]])
    >>> q, n = quadratic_form([2.0, 2.0, np.nan], R)
    >>> round(q, 3), n
    (4.211, 2)
    """
    z = np.asarray(z, dtype=float)
    ok = np.isfinite(z)
    z = z[ok]
    if correlation is None or z.size == 0:
        return float(z @ z), int(z.size)
    w = inverse_cholesky(np.asarray(correlation, dtype=float)[np.ix_(ok, ok)]) @ z
    return float(w @ w), int(z.size)
