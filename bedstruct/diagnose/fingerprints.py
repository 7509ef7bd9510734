"""Fingerprints: how every observable changes per effect, net of what recalibration absorbs.

For each effect the simulator is run at two magnitudes (half and full top of the
prior) with the same replicate seeds as the base runs; the mean change per
component gives a quadratic response through the origin: a straight line when the
two magnitudes agree with linearity within noise, else a monotone interpolation
(refined by further runs at fitted magnitudes during the attribution). The sensitivities of the observables to the recalibrated base
parameters (e.g. the cohesion energy density) span the *nuisance* directions: a
gap along them is closed by recalibrating, not by an effect. Identifiability is
judged on the calibration observables, whitened by the combined noise, after
projecting those directions out. The runs and the set built from them are in
:mod:`bedstruct.diagnose.fingerprint_runs` (:func:`~bedstruct.diagnose.fingerprint_runs.compute_fingerprints`),
identifiability in :mod:`bedstruct.diagnose.identifiability`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import ConfigError
from .effect_response import Fingerprint
from .identifiability import assess_fingerprints
from .measurements import MeasurementSet
from .parameters import parameter_bounds
from .where import _nan_mean

__all__ = ["FingerprintSet", "selection_threshold"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FingerprintSet:
    """Everything the diagnosis simulates once for a design: base runs, nuisance, fingerprints.

    Attributes
    ----------
    design : MeasurementSet
        Measured plus candidate observables, in row order.
    names : tuple of str
        Observable names present in the simulator output (row order source).
    rows_calibrate, rows_validate, rows_candidate : (n,) ndarray of bool
        Component masks by role.
    base : dict
        Base parameters.
    seeds : tuple of int
        Replicate seeds of the base runs: the first :attr:`n_replicates` are shared by
        every parameter point, the rest (:attr:`top_up_seeds`) were added for the
        effects in :attr:`topped_up` only.
    base_samples : (R, n) ndarray
        Replicates at the base parameters, one row per seed of :attr:`seeds`.
    sim_var : (n,) ndarray
        Replicate variance of one run, pooled over the parameter points that scatter like
        the base point (all of them unless Bartlett's test sets one aside,
        :func:`~bedstruct.diagnose.replicates.homogeneous_variance`), at its one-sided
        84 % upper confidence bound (:func:`variance_upper_bound`): with two or three seeds
        per point the pooled estimate rests on few degrees of freedom, and an
        underestimated scatter would turn noise into a gap.
    sigma_meas : (n,) ndarray
        Measurement (or stated candidate) standard deviations.
    nuisance : tuple of str
        Recalibrated base parameters.
    sensitivities : (n, p) ndarray
        d(observable)/d(parameter), per unit of each parameter.
    fingerprints : tuple of Fingerprint
    threshold : float
        Chi-square increase an effect needs to be selected (Bonferroni over effects).
    topped_up : tuple of str
        Effects whose identifiability was marginal with the shared seeds
        (:meth:`marginal`) and that were run again with :attr:`top_up_seeds`, as was the
        base.
    top_up_seeds : tuple of int
        The seeds added for them.
    bounds : dict of str to (float, float)
        Narrower bounds of recalibrated parameters than their physical ones (the
        configuration's ``[recalibrate] bounds``; see :meth:`shift_bounds`).
    """

    design: MeasurementSet
    names: tuple[str, ...]
    rows_calibrate: np.ndarray
    rows_validate: np.ndarray
    rows_candidate: np.ndarray
    base: dict
    seeds: tuple[int, ...]
    base_samples: np.ndarray
    sim_var: np.ndarray
    sigma_meas: np.ndarray
    nuisance: tuple[str, ...]
    sensitivities: np.ndarray
    fingerprints: tuple[Fingerprint, ...]
    threshold: float
    alpha: float = 0.05
    simulator_name: str = ""
    n_runs: int = 0
    meta: dict = field(default_factory=dict)
    sim_dof: np.ndarray | None = None
    topped_up: tuple[str, ...] = ()
    top_up_seeds: tuple[int, ...] = ()
    bounds: dict = field(default_factory=dict)

    @property
    def n_replicates(self) -> int:
        """Replicate seeds shared by every parameter point."""
        return self.base_samples.shape[0] - len(self.top_up_seeds)

    def marginal(self, width: float = 2.0, single_run: float = 0.5) -> tuple[str, ...]:
        """Effects whose identifiability is undecided by their own estimation noise.

        An effect is identifiable when ``signal**2 > threshold + noise**2``; it is
        marginal when its signal lies within ``width`` standard errors
        (:attr:`Fingerprint.signal_se`) of that bound, so that other replicate seeds
        could well have judged it the other way; or when more than ``single_run`` of
        its signal lies on components that the prior top observed in only one run
        (:attr:`Fingerprint.single_run_share`): there the standard error assumes the
        base's scatter, which the point that lost a run has not shown it keeps (an
        ageing pile that stands as a block in one run and reads 59 deg in the other).

        Examples
        --------
        >>> from dataclasses import replace
        >>> from bedstruct.diagnose import Effect
        >>> effect = Effect(name="e", title="e", magnitude="m", unit="1", prior=(0.0, 1.0),
        ...                 physics="", signature="", sources=(), engine_map=())
        >>> fp = Fingerprint(effect, np.array([1.0, 2.0]), np.zeros((2, 1)), np.zeros((2, 1)),
        ...                  np.array([0.0, 1.0, 2.0]), np.zeros((3, 1)), True,
        ...                  signal=4.1, noise=2.6, signal_se=0.8)
        >>> fps = FingerprintSet(*[None] * 12, (fp,), threshold=9.55)
        >>> fps.marginal()  # 4.1 against a bound of 4.04, known to +-0.8
        ('e',)
        >>> replace(fps, fingerprints=(replace(fp, signal=6.0),)).marginal()
        ()
        >>> replace(fps, fingerprints=(replace(fp, signal=6.0, single_run_share=0.8),)).marginal()
        ('e',)
        """
        out = []
        for f in self.fingerprints:
            bound = float(np.sqrt(self.threshold + f.noise ** 2))
            if abs(f.signal - bound) < width * f.signal_se or f.single_run_share > single_run:
                out.append(f.name)
        return tuple(out)

    @property
    def sigma(self) -> np.ndarray:
        """Combined noise of ``real - mean(base runs)`` per component.

        The mean is over the base replicates that observed the component.
        """
        n = np.maximum(np.sum(np.isfinite(self.base_samples), axis=0), 1)
        return np.sqrt(self.sigma_meas ** 2 + self.sim_var / n)

    def run_sd(self, effect: str | None = None, magnitude: float = 0.0) -> np.ndarray:
        """Standard deviation of one run, per component, at the base or with ``effect`` at
        ``magnitude``.

        The pooled estimate (not its upper bound) at the base; with an effect whose
        fingerprint points scattered differently (:attr:`Fingerprint.run_var`), the
        variance interpolated linearly in the magnitude between the base and those
        points (held beyond them); nodes simulated later
        (:attr:`Fingerprint.scatter_nodes`) join the table, replacing a fingerprint point
        at the same magnitude.
        """
        var = self._pooled_run_var()
        if effect is None or not magnitude:
            return np.sqrt(var)
        fp = self[effect]
        if fp.run_var is None and not fp.scatter_nodes:
            return np.sqrt(var)
        run_var = np.vstack([var, var]) if fp.run_var is None else fp.run_var
        nodes = np.r_[0.0, fp.magnitudes, [a for a, _ in fp.scatter_nodes]]
        table = np.vstack([var, run_var] + [v[None] for _, v in fp.scatter_nodes])
        # a later node at a fingerprint magnitude replaces that point's estimate
        nodes, first = np.unique(nodes[::-1], return_index=True)
        table = table[::-1][first]
        return np.sqrt(np.array([np.interp(float(magnitude), nodes, table[:, i])
                                 for i in range(table.shape[1])]))

    def _pooled_run_var(self) -> np.ndarray:
        from .replicates import variance_upper_bound as bound
        return self.sim_var if self.sim_dof is None else self.sim_var / bound(self.sim_dof)

    def node_run_var(self, samples, alpha: float = 0.01, rows=None) -> np.ndarray:
        """Variance of one run at a parameter point simulated after the fingerprints.

        Per component, the point's own replicate variance where it exceeds the pooled
        run variance significantly (one-sided F-test at ``alpha`` per component), else the
        pooled estimate: a magnitude at which heaps stand or fall scatters unlike the base,
        and runs there must be judged in that scatter. No correction for the number of
        components: a scatter understated makes a true model's rerun fail and a twin's file
        claim less noise than its runs have, one overstated only costs power (with four
        seeds a Bonferroni level missed a six-fold variance at tiny).

        Parameters
        ----------
        samples : (R, n) array_like
            The point's replicates (NaN where a run did not observe a component).
        alpha : float
            Level of each component's test.
        rows : (n,) bool array, optional
            The components that ``samples`` holds (default all); the others keep the
            pooled estimate.

        Returns
        -------
        (n,) ndarray

        Examples
        --------
        >>> from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue,
        ...                                 compute_fingerprints, diagnosis_design, twin_design)
        >>> effects = catalogue(["wall_friction"])
        >>> design = diagnosis_design(twin_design(), effects)
        >>> fps = compute_fingerprints(SurrogateSimulator(design), design, BASE_PARAMETERS,
        ...                            effects, replicates=3)
        >>> sd = fps.run_sd()                       # the pooled scatter of one run
        >>> rng = np.random.default_rng(0)
        >>> wild = fps.base_mean + 30.0 * sd * rng.standard_normal((4, sd.size))
        >>> bool(np.all(fps.node_run_var(wild) > sd ** 2))
        True
        >>> tame = fps.base_mean + sd * rng.standard_normal((4, sd.size))
        >>> bool(np.allclose(fps.node_run_var(tame), sd ** 2))
        True
        """
        own, pooled, wider, _ = self._node_test(samples, alpha, rows)
        return np.where(wider, own, pooled)

    def node_scatter(self, samples, alpha: float = 0.01, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """One run's variance at a node simulated after the fingerprints, and its response's
        standard error where those runs scattered beyond the pooled estimate.

        The variance is :meth:`node_run_var`'s. The standard error, on the components whose
        scatter exceeded the pooled one, is ``sqrt(own / runs + pooled / base runs)`` (the
        node's mean against the base runs' mean; the pairing by seed is ignored, which only
        overstates it, and the node's own scatter dominates there); NaN elsewhere, where
        :meth:`Fingerprint.predict_se` interpolates the fingerprint's own.

        Parameters
        ----------
        samples, alpha, rows
            As in :meth:`node_run_var`.

        Returns
        -------
        run_var, se : (n,) ndarray

        Examples
        --------
        >>> from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue,
        ...                                 compute_fingerprints, diagnosis_design, twin_design)
        >>> effects = catalogue(["wall_friction"])
        >>> design = diagnosis_design(twin_design(), effects)
        >>> fps = compute_fingerprints(SurrogateSimulator(design), design, BASE_PARAMETERS,
        ...                            effects, replicates=3)
        >>> sd = fps.run_sd()
        >>> rng = np.random.default_rng(0)
        >>> wild = fps.base_mean + sd * rng.standard_normal((4, sd.size))
        >>> wild[:, 0] += 30.0 * sd[0] * rng.standard_normal(4)      # one component only
        >>> run_var, se = fps.node_scatter(wild)
        >>> bool(run_var[0] > 25.0 * sd[0] ** 2), bool(np.isnan(se[1:]).all())
        (True, True)
        >>> bool(np.isclose(se[0], np.sqrt(run_var[0] / 4 + sd[0] ** 2 / 3)))  # 4 runs, 3 base
        True
        """
        own, pooled, wider, n_own = self._node_test(samples, alpha, rows)
        n_base = np.maximum(np.sum(np.isfinite(self.base_samples), axis=0), 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            se = np.sqrt(own / np.maximum(n_own, 1) + pooled / n_base)
        return np.where(wider, own, pooled), np.where(wider, se, np.nan)

    def _node_test(self, samples, alpha, rows):
        """Own and pooled variance per component, whether the own one is wider (one-sided
        F-test at ``alpha``) and the runs behind it."""
        from scipy import stats

        from .where import _nan_var
        pooled = self._pooled_run_var()
        if rows is not None:
            s = np.full((len(samples), pooled.size), np.nan)
            s[:, np.asarray(rows, bool)] = samples
        else:
            s = np.atleast_2d(np.asarray(samples, float))
        own = _nan_var(s)
        n_own = np.sum(np.isfinite(s), axis=0)
        dof_own = n_own - 1
        dof_pool = np.full(pooled.shape, np.inf) if self.sim_dof is None else \
            np.asarray(self.sim_dof, float)
        ok = (dof_own >= 1) & np.isfinite(own) & (pooled > 0)
        p = np.ones(pooled.shape)
        with np.errstate(invalid="ignore", divide="ignore"):
            p[ok] = stats.f.sf(own[ok] / pooled[ok], dof_own[ok], dof_pool[ok])
        return own, pooled, ok & (p < alpha), n_own

    def sensitivity_step(self, name: str) -> float:
        """The finite-difference step of a nuisance parameter's sensitivity (its units;
        5 % of the base where the fingerprints do not state it)."""
        steps = self.meta.get("sensitivity_steps") or {}
        if name in steps:
            return float(steps[name])
        return 0.05 * abs(self.base[name]) if self.base[name] != 0 else 0.05

    def parameter_bounds(self) -> dict[str, tuple[float, float]]:
        """Bounds of each recalibrated parameter (its units): physical, narrowed by
        :attr:`bounds` (:func:`~bedstruct.diagnose.parameters.parameter_bounds`)."""
        return parameter_bounds(self.nuisance, self.bounds)

    def shift_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the recalibration shifts: the parameters' bounds less
        their base values, in the order of :attr:`nuisance`."""
        b = self.parameter_bounds()
        lo = np.array([b[n][0] - float(self.base[n]) for n in self.nuisance], dtype=float)
        hi = np.array([b[n][1] - float(self.base[n]) for n in self.nuisance], dtype=float)
        return lo, hi

    @property
    def base_mean(self) -> np.ndarray:
        """Mean of the base replicates per component (over those that observed it)."""
        return _nan_mean(self.base_samples)

    def restrict(self, names: Sequence[str]) -> "FingerprintSet":
        """The same set on the observables ``names`` only (row order kept).

        Identifiability is re-assessed on the remaining calibration observables.

        Examples
        --------
        A linear toy simulator: two calibration observables and a held-out one.

        >>> from bedstruct.diagnose import (Effect, MeasurementSet, Observations, compute_fingerprints,
        ...                                 measurement_from_dict)
        >>> design = MeasurementSet(tuple(measurement_from_dict(dict(
        ...     name=n, kind="static_angle", value=0.0, uncertainty=1.0, role=r))
        ...     for n, r in [("a", "calibrate"), ("b", "calibrate"), ("c", "validate")]))
        >>> effect = Effect(name="e", title="e", magnitude="m", unit="1", prior=(0.0, 1.0),
        ...                 physics="", signature="", sources=(), engine_map=())
        >>> def simulator(base, effects, seed):
        ...     m, noise = effects.get("e", 0.0), 0.1 * np.random.default_rng(seed).standard_normal(3)
        ...     return Observations({"a": base["k"] + 30 * m + noise[0],
        ...                          "b": -base["k"] + 40 * m + noise[1], "c": m + noise[2]})
        >>> fps = compute_fingerprints(simulator, design, {"k": 1.0}, [effect], nuisance=("k",),
        ...                            replicates=2)
        >>> fps.restrict(["b", "c"]).names
        ('b', 'c')
        >>> fps["e"].identifiable, fps.restrict(["b", "c"])["e"].identifiable
        (True, False)
        """
        from dataclasses import replace
        wanted = set(names)
        unknown = wanted - set(self.names)
        if unknown:
            raise KeyError(f"observable {sorted(unknown)[0]!r} is not in the fingerprint set")
        keep_names = [n for n in self.names if n in wanted]
        keep = np.isin(self.design.component_names(), keep_names)
        design = self.design.__class__(tuple(self.design[n] for n in keep_names), self.design.title,
                                       self.design.source, self.design.path, self.design.notes)
        if not (design.roles() == "calibrate").any():
            raise ConfigError("no calibration observable left in the fingerprint set")
        fps = tuple(replace(f, delta=f.delta[:, keep], delta_se=f.delta_se[:, keep],
                            responses=f.responses[:, keep],
                            run_var=None if f.run_var is None else f.run_var[:, keep],
                            scatter_nodes=tuple((a, v[keep]) for a, v in f.scatter_nodes),
                            se_nodes=tuple((a, v[keep]) for a, v in f.se_nodes),
                            delta_n=None if f.delta_n is None else f.delta_n[:, keep])
                    for f in self.fingerprints)
        roles = design.roles()
        out = replace(self, design=design, names=tuple(keep_names),
                      rows_calibrate=roles == "calibrate", rows_validate=roles == "validate",
                      rows_candidate=roles == "candidate", base_samples=self.base_samples[:, keep],
                      sim_var=self.sim_var[keep], sigma_meas=self.sigma_meas[keep],
                      sim_dof=None if self.sim_dof is None else self.sim_dof[keep],
                      sensitivities=self.sensitivities[keep], fingerprints=fps,
                      meta=dict(self.meta, uneven_scatter={
                          k: v for k, v in self.meta.get("uneven_scatter", {}).items()
                          if k.split(" ")[0] in wanted},
                          correlated_scatter=[
                              c for c in self.meta.get("correlated_scatter", [])
                              if all(k.split(" ")[0] in wanted for k in c["components"])]))
        return assess_fingerprints(out)

    def __getitem__(self, name: str) -> Fingerprint:
        for f in self.fingerprints:
            if f.name == name:
                return f
        raise KeyError(name)

    @property
    def effect_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fingerprints)

    def subset(self, names: Sequence[str]) -> "FingerprintSet":
        """The same set restricted to the effects ``names`` (order kept)."""
        from dataclasses import replace
        keep = tuple(f for f in self.fingerprints if f.name in set(names))
        return replace(self, fingerprints=keep)

    def table(self) -> list[dict]:
        """One row per effect: signal (with its standard error), noise, identifiability,
        the seeds behind it and what would identify it."""
        return [{"effect": f.name, "signal_sigma": f.signal, "signal_se_sigma": f.signal_se,
                 "noise_sigma": f.noise, "identifiable": f.identifiable,
                 "single_run_share": f.single_run_share,
                 "seeds": len(self.seeds) if f.name in self.topped_up else self.n_replicates, "nonlinearity": f.nonlinearity(),
                 "confounded_with": list(f.confounded_with),
                 "identify_with": list(f.identify_with)} for f in self.fingerprints]


def selection_threshold(alpha: float, n_effects: int) -> float:
    """Chi-square decrease a single effect needs to be selected: the chi-square(1)
    quantile at ``alpha`` shared (Bonferroni) over the ``n_effects`` candidates.

    Examples
    --------
    >>> round(selection_threshold(0.05, 1), 3)
    3.841
    """
    from scipy import stats
    return float(stats.chi2.isf(alpha / max(int(n_effects), 1), 1))


def _design_sigma(design: MeasurementSet, names) -> np.ndarray:
    return np.concatenate([design[n].uncertainty for n in names])
