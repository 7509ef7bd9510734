"""One effect's response: the change of every design component with the effect's magnitude.

:class:`Fingerprint` holds the simulated magnitudes and nodes, interpolates the response
between them (a straight line through the origin when the two fingerprint magnitudes agree
with linearity, else a monotone cubic) and the standard error of that interpolation. The set
of fingerprints, with the base runs and the recalibration sensitivities, is
:class:`~bedstruct.diagnose.fingerprints.FingerprintSet`.

.. versionadded:: 0.1
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .catalogue import Effect

__all__ = ["Fingerprint"]


def _interp_se(a: float, knots, se) -> np.ndarray:
    """Rows ``se`` at sorted magnitudes ``knots`` (0 first) interpolated linearly at ``a`` >= 0,
    proportional to ``a`` beyond the last."""
    if a >= knots[-1]:
        return se[-1] * (a / knots[-1])
    j = int(np.searchsorted(knots, a, side="right")) - 1
    w = (a - knots[j]) / (knots[j + 1] - knots[j])
    return (1.0 - w) * se[j] + w * se[j + 1]


@dataclass(frozen=True)
class Fingerprint:
    """The response of all design components to one effect.

    Attributes
    ----------
    effect : Effect
    magnitudes : (2,) ndarray
        The simulated magnitudes ``(m1, m2)``.
    delta : (2, n) ndarray
        Mean change against the base runs (same seeds), canonical units.
    delta_se : (2, n) ndarray
        Standard error of ``delta`` from the replicate scatter of the paired differences.
    nodes : (k,) ndarray
        Magnitudes with a simulated response, 0 included (refinement adds nodes).
    responses : (k, n) ndarray
        Mean change at each node.
    linear : bool
        True when the response is linear within its estimation noise; the
        prediction is then the least-squares line through the origin, otherwise
        a monotone piecewise-cubic (PCHIP) interpolation of the nodes, extended
        linearly beyond them.
    signal : float
        Whitened, nuisance-projected norm on the calibration components at ``m2``
        (``sqrt`` of the chi-square the effect at the prior top would add).
    noise : float
        Expected norm of the fingerprint's own estimation noise (same metric).
    signal_se : float
        Standard error of ``signal``: the estimation noise along the signal's own
        direction (at most ``noise``).
    identifiable : bool
        ``signal**2 > threshold + noise**2``: detectable at the prior top with the
        calibration observables.
    confounded_with : tuple of str
        Effects whose projected fingerprints are nearly parallel (|cos| > 0.98).
    identify_with : tuple of str
        Non-calibration observables (held-out or candidate) where the effect
        shows most, by whitened change at ``m2`` (changes above 2 sigma and above
        twice their own estimation noise; empty: the catalogue's suggestions apply).
    run_var : (2, n) ndarray or None
        Variance of one run at ``m1`` and ``m2``: the point's own replicate variance
        where its scatter was set aside from the pooled one
        (:func:`~bedstruct.diagnose.replicates.homogeneous_variance`), else the pooled
        estimate.
    delta_n : (2, n) ndarray of int or None
        Paired runs behind each component of ``delta`` (a run that could not observe a
        component leaves it out).
    single_run_share : float
        Share of ``signal**2`` carried by calibration components that the prior top
        observed in fewer than two runs: their response, and the scatter it is judged
        against, rest on one run (:meth:`FingerprintSet.marginal`).
    scatter_nodes : tuple of (float, (n,) ndarray)
        Variance of one run at magnitudes simulated after the fingerprint (refinement
        nodes, reruns, a twin's sizing node; :meth:`FingerprintSet.node_run_var`), which
        :meth:`FingerprintSet.run_sd` interpolates with :attr:`run_var`.
    se_nodes : tuple of (float, (n,) ndarray)
        Standard error of the response at those nodes where their runs scattered beyond
        the pooled estimate (NaN elsewhere: the interpolated :attr:`delta_se` holds there),
        which :meth:`predict_se` interpolates with :attr:`delta_se`.
    """

    effect: Effect
    magnitudes: np.ndarray
    delta: np.ndarray
    delta_se: np.ndarray
    nodes: np.ndarray
    responses: np.ndarray
    linear: bool
    signal: float = 0.0
    noise: float = 0.0
    identifiable: bool = True
    confounded_with: tuple[str, ...] = ()
    identify_with: tuple[str, ...] = ()
    run_var: np.ndarray | None = None
    signal_se: float = 0.0
    delta_n: np.ndarray | None = None
    single_run_share: float = 0.0
    scatter_nodes: tuple = ()
    se_nodes: tuple = ()

    def __post_init__(self):
        order = np.argsort(self.nodes)
        nodes = np.asarray(self.nodes, float)[order]
        resp = np.asarray(self.responses, float)[order]
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "responses", resp)
        nz = nodes != 0
        slope = (nodes[nz] @ resp[nz]) / float(nodes[nz] @ nodes[nz]) if nz.any() else resp[0] * 0
        object.__setattr__(self, "_slope", slope)
        if not self.linear:
            from scipy.interpolate import PchipInterpolator
            f = PchipInterpolator(nodes, resp, axis=0, extrapolate=False)
            object.__setattr__(self, "_f", f)
            object.__setattr__(self, "_df", f.derivative())

    @property
    def name(self) -> str:
        return self.effect.name

    @property
    def slope(self) -> np.ndarray:
        """Least-squares response per unit magnitude (line through the origin)."""
        return self._slope

    def predict(self, a: float) -> np.ndarray:
        """Predicted change of every component at magnitude ``a``."""
        a = float(a)
        if self.linear:
            return self._slope * a
        lo, hi = self.nodes[0], self.nodes[-1]
        if a < lo:
            return self._f(lo) + self._df(lo) * (a - lo)
        if a > hi:
            return self._f(hi) + self._df(hi) * (a - hi)
        return self._f(a)

    def predict_se(self, a: float) -> np.ndarray:
        """Standard error of :meth:`predict` at ``a``, from the replicate scatter.

        ``delta_se`` interpolated linearly over the simulated magnitudes (0 at no effect),
        proportional to ``a`` beyond them. A node simulated later whose runs scattered
        beyond the pooled estimate (:attr:`se_nodes`: heaps that stand or fall there) joins
        the interpolation with its own standard error on those components, replacing a
        fingerprint point at the same magnitude; elsewhere such nodes, and the fitted line,
        take the interpolated value (an approximation: their runs scattered like the rest).

        Examples
        --------
        >>> from bedstruct.diagnose import catalogue
        >>> f = Fingerprint(catalogue(["wall_friction"])[0], np.array([0.2, 0.4]),
        ...                 np.array([[1.0, 2.0], [2.0, 4.0]]), np.array([[0.1, 0.1], [0.2, 0.2]]),
        ...                 np.array([0.0, 0.2, 0.4]), np.array([[0, 0], [1.0, 2.0], [2.0, 4.0]]),
        ...                 linear=True)
        >>> f.predict_se(0.3)
        array([0.15, 0.15])
        >>> g = f.with_node(0.3, [1.5, 3.0], se=[2.0, np.nan])   # wild on the first only
        >>> g.predict_se(0.3), g.predict_se(0.35)
        (array([2.  , 0.15]), array([1.1  , 0.175]))
        """
        m = np.r_[0.0, self.magnitudes]
        se = np.vstack([np.zeros_like(self.delta_se[0]), self.delta_se])
        a = abs(float(a))
        out = _interp_se(a, m, se)
        if not self.se_nodes:
            return out
        own = np.vstack([s for _, s in self.se_nodes])
        for i in np.flatnonzero(np.isfinite(own).any(axis=0)):
            knots = np.r_[m, [b for (b, _), ok in zip(self.se_nodes, np.isfinite(own[:, i])) if ok]]
            vals = np.r_[se[:, i], own[np.isfinite(own[:, i]), i]]
            # a later node at a fingerprint magnitude replaces that point's estimate
            knots, first = np.unique(np.abs(knots[::-1]), return_index=True)
            out[i] = _interp_se(a, knots, vals[::-1][first][:, None])[0]
        return out

    def derivative(self, a: float) -> np.ndarray:
        """d(prediction)/d(magnitude) at ``a``."""
        a = float(a)
        if self.linear:
            return self._slope
        return self._df(min(max(a, self.nodes[0]), self.nodes[-1]))

    def with_node(self, a: float, response, run_var=None, se=None) -> "Fingerprint":
        """A copy with a simulated response at magnitude ``a`` added (non-linear interpolation).

        Components not observed at ``a`` (NaN) keep the current interpolation there.
        ``run_var``, the variance of one run at ``a`` (:meth:`FingerprintSet.node_run_var`),
        is added to :attr:`scatter_nodes`; ``se``, the response's own standard error where
        its runs scattered beyond the pooled estimate (:meth:`FingerprintSet.node_scatter`,
        NaN elsewhere), to :attr:`se_nodes`.
        """
        from dataclasses import replace
        response = np.array(response, dtype=float)
        gap = ~np.isfinite(response)
        response[gap] = self.predict(a)[gap]
        nodes = np.append(self.nodes, float(a))
        resp = np.vstack([self.responses, response[None]])
        scatter = self.scatter_nodes if run_var is None else \
            self.scatter_nodes + ((float(a), np.asarray(run_var, float)),)
        own_se = self.se_nodes if se is None or not np.isfinite(se).any() else \
            self.se_nodes + ((float(a), np.asarray(se, float)),)
        return replace(self, nodes=nodes, responses=resp, linear=False, scatter_nodes=scatter,
                       se_nodes=own_se)

    def nonlinearity(self) -> float:
        """Relative deviation at ``m1`` from the straight line through 0 and ``m2`` (0 if linear)."""
        m1, m2 = self.magnitudes
        line = self.delta[1] * (m1 / m2)
        den = np.linalg.norm(line)
        return float(np.linalg.norm(self.delta[0] - line) / den) if den > 0 else 0.0
