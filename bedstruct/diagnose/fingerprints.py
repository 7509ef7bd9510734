"""Fingerprints: how every observable changes per effect, net of what recalibration absorbs.

For each effect the simulator is run at two magnitudes (half and full top of the
prior) with the same replicate seeds as the base runs; the mean change per
component gives a quadratic response through the origin: a straight line when the
two magnitudes agree with linearity within noise, else a monotone interpolation
(refined by further runs at fitted magnitudes during the attribution). The sensitivities of the observables to the recalibrated base
parameters (e.g. the cohesion energy density) span the *nuisance* directions: a
gap along them is closed by recalibrating, not by an effect. Identifiability is
judged on the calibration observables, whitened by the combined noise, after
projecting those directions out.

.. versionadded:: 0.1
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
from scipy import stats

from ..errors import ConfigError
from .catalogue import Effect
# identifiability's two public functions live there and are re-exported here
from .identifiability import _uneven_scatter, assess_fingerprints, nuisance_projector  # noqa: F401
from .measurements import MeasurementSet
from .replicates import (Simulator, homogeneous_variance, simulate_replicates,
                         variance_upper_bound)
from .where import _nan_mean, _nan_var

__all__ = ["Fingerprint", "FingerprintSet", "compute_fingerprints", "assess_fingerprints",
           "nuisance_projector"]

log = logging.getLogger(__name__)

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

    def derivative(self, a: float) -> np.ndarray:
        """d(prediction)/d(magnitude) at ``a``."""
        a = float(a)
        if self.linear:
            return self._slope
        return self._df(min(max(a, self.nodes[0]), self.nodes[-1]))

    def with_node(self, a: float, response) -> "Fingerprint":
        """A copy with a simulated response at magnitude ``a`` added (non-linear interpolation).

        Components not observed at ``a`` (NaN) keep the current interpolation there.
        """
        from dataclasses import replace
        response = np.array(response, dtype=float)
        gap = ~np.isfinite(response)
        response[gap] = self.predict(a)[gap]
        nodes = np.append(self.nodes, float(a))
        resp = np.vstack([self.responses, response[None]])
        return replace(self, nodes=nodes, responses=resp, linear=False)

    def nonlinearity(self) -> float:
        """Relative deviation at ``m1`` from the straight line through 0 and ``m2`` (0 if linear)."""
        m1, m2 = self.magnitudes
        line = self.delta[1] * (m1 / m2)
        den = np.linalg.norm(line)
        return float(np.linalg.norm(self.delta[0] - line) / den) if den > 0 else 0.0


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
        Replicate seeds shared by all runs.
    base_samples : (R, n) ndarray
        Replicates at the base parameters.
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

    @property
    def n_replicates(self) -> int:
        return self.base_samples.shape[0]

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
        points (held beyond them).
        """
        from .replicates import variance_upper_bound as bound
        var = self.sim_var if self.sim_dof is None else self.sim_var / bound(self.sim_dof)
        if effect is None or not magnitude:
            return np.sqrt(var)
        fp = self[effect]
        if fp.run_var is None:
            return np.sqrt(var)
        nodes = np.r_[0.0, fp.magnitudes]
        order = np.argsort(nodes)
        table = np.vstack([var, fp.run_var])[order]
        return np.sqrt(np.array([np.interp(float(magnitude), nodes[order], table[:, i])
                                 for i in range(table.shape[1])]))

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

        >>> from bedstruct.diagnose import Effect, MeasurementSet, Observations, measurement_from_dict
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
                            run_var=None if f.run_var is None else f.run_var[:, keep])
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
                          if k.split(" ")[0] in wanted}))
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
        """One row per effect: signal, noise, identifiability and what would identify it."""
        return [{"effect": f.name, "signal_sigma": f.signal, "noise_sigma": f.noise,
                 "identifiable": f.identifiable, "nonlinearity": f.nonlinearity(),
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


def compute_fingerprints(simulator: Simulator, design: MeasurementSet, base: Mapping[str, float],
                         effects: Sequence[Effect], *, nuisance: Sequence[str] = ("cohesion_energy_density",),
                         rel_step: float = 0.05, replicates: int = 4, seed: int = 0,
                         alpha: float = 0.05, simulator_name: str = "",
                         progress: bool = False) -> FingerprintSet:
    """Simulate base, nuisance and effect runs and build the fingerprints.

    Parameters
    ----------
    simulator : callable
        ``simulator(base, effects, seed) -> Observations`` covering ``design``.
    design : MeasurementSet
        Observables (calibrate/validate/candidate). Measured observables missing
        from the simulator output raise ConfigError; candidates it cannot produce
        are dropped.
    base : mapping
        Base parameters (SI).
    effects : sequence of Effect
        The catalogue to fingerprint.
    nuisance : sequence of str
        Base parameters that recalibration may change.
    rel_step : float
        Relative finite-difference step of the nuisance sensitivities.
    replicates : int
        Seeds per parameter point (>= 2).
    seed : int
        First replicate seed; seeds are ``seed, seed+1, ...``.
    alpha : float
        Family-wise level; the selection threshold is the chi-square(1) quantile
        at ``alpha / n_effects``.

    Returns
    -------
    FingerprintSet
    """
    if replicates < 2:
        raise ConfigError(f"replicates: need >= 2 replicate seeds; got {replicates}")
    base = dict(base)
    for p in nuisance:
        if p not in base:
            raise ConfigError(f"recalibrate: parameter {p!r} is not among the base parameters "
                              f"{sorted(base)}")
    seeds = tuple(int(seed) + i for i in range(replicates))

    def step(p):  # the nuisance parameter's finite-difference point and step
        h = rel_step * abs(base[p]) if base[p] != 0 else rel_step
        return dict(base, **{p: base[p] + h}), h

    if hasattr(simulator, "prefetch"):
        # every point's replicates at once (parallel simulators), the probe below among them:
        # run on its own first, it would keep all but one process waiting (the engine checks
        # its design's kinds when it is made)
        points = [(dict(base), {})] + [(step(p)[0], {}) for p in nuisance]
        points += [(dict(base), {e.name: m}) for e in effects for m in e.reference_magnitudes]
        simulator.prefetch([(b, e, s) for b, e in points for s in seeds], progress=progress)
    probe = simulator(dict(base), {}, seeds[0])
    names = []
    for m in design:
        if m.name in probe:
            if len(probe[m.name]) != m.n_components:
                raise ConfigError(f"observable {m.name!r}: simulator gives {len(probe[m.name])} "
                                  f"components, the design {m.n_components}")
            names.append(m.name)
        elif m.role != "candidate":
            raise ConfigError(f"observable {m.name!r}: the simulator does not produce it "
                              f"(it produces {sorted(probe.names)})")
    design = design.__class__(tuple(design[n] for n in names), design.title, design.source,
                              design.path, design.notes)
    if not (design.roles() == "calibrate").any():
        raise ConfigError("measurements: no observable has role 'calibrate'; the attribution is "
                          "fitted on calibration observables only")

    def run(params, eff):
        return simulate_replicates(simulator, params, eff, seeds, names)

    progress_bar = None
    if progress:
        from tqdm import tqdm
        progress_bar = tqdm(total=1 + len(nuisance) + 2 * len(effects), desc="fingerprints")
    groups = []   # replicate samples of every parameter point (pooled run-to-run scatter)
    point_names = []   # what each group is, for the notes
    base_s = run(base, {})
    groups.append(base_s)
    point_names.append("base")
    if progress_bar:
        progress_bar.update()
    sens = np.zeros((base_s.shape[1], len(nuisance)))
    steps = {}
    for j, p in enumerate(nuisance):
        plus, h = step(p)
        sp = run(plus, {})
        groups.append(sp)
        point_names.append(f"{p} {plus[p]:.4g}")
        sens[:, j] = _nan_mean(sp - base_s) / h
        steps[p] = float(h)
        if progress_bar:
            progress_bar.update()
    paired = []
    for e in effects:
        for m in e.reference_magnitudes:
            se = run(base, {e.name: m})
            groups.append(se)
            point_names.append(f"{e.name} {m:g}")
            paired.append(se - base_s)
            if progress_bar:
                progress_bar.update()
    if progress_bar:
        progress_bar.close()
    n_runs = replicates * len(groups)
    # one scatter pooled over the points that scatter like the base: a point far from it
    # (e.g. a cohesive block that stands or falls) keeps its own
    sim_var_estimate, sim_dof, aside, p_scatter = homogeneous_variance(groups, alpha=0.01)
    sim_var = sim_var_estimate * variance_upper_bound(sim_dof)
    first_effect = 1 + len(nuisance)
    own = [np.where(aside[g], _nan_var(groups[g]), sim_var_estimate) for g in range(len(groups))]
    run_var_all = [np.vstack(own[first_effect + 2 * k:first_effect + 2 * k + 2])
                   for k in range(len(effects))]

    # Missing data: a run that could not observe a component (e.g. no heap to fit) gives
    # NaN there. Means and paired differences use the finite replicates; an observable
    # that some parameter point never observed has no fingerprint and is dropped.
    D_all = np.array([_nan_mean(d) for d in paired]).reshape(len(paired), -1)
    n_pairs = np.array([np.isfinite(d).sum(axis=0) for d in paired]).reshape(len(paired), -1)
    sd_pairs = np.array([np.sqrt(_nan_var(d)) for d in paired]).reshape(len(paired), -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        # one finite pair: its scatter from the pooled run variance (two runs differ)
        SE_all = np.where(n_pairs >= 2, sd_pairs / np.sqrt(np.maximum(n_pairs, 1)),
                          np.sqrt(2.0 * sim_var / np.maximum(n_pairs, 1)))
    # an effect strong enough to remove what is observed (e.g. no heap left at the prior
    # top) leaves one magnitude unobserved: its response is the other's, scaled linearly
    comp = design.component_names()
    extrapolated = {}
    for k, e in enumerate(effects):
        mags = np.asarray(e.reference_magnitudes, float)
        for a, b in ((0, 1), (1, 0)):
            lost = ~np.isfinite(D_all[2 * k + a]) & np.isfinite(D_all[2 * k + b])
            if lost.any():
                r = mags[a] / mags[b]
                D_all[2 * k + a, lost] = D_all[2 * k + b, lost] * r
                SE_all[2 * k + a, lost] = SE_all[2 * k + b, lost] * abs(r)
                extrapolated.setdefault(e.name, []).extend(
                    f"{comp[i]} at {mags[a]:g} (from {mags[b]:g})" for i in np.flatnonzero(lost))
    usable = np.isfinite(sim_var) & (np.isfinite(base_s).sum(axis=0) > 0) \
        & np.all(np.isfinite(sens), axis=1) & np.all(np.isfinite(D_all), axis=0) \
        & np.all(np.isfinite(SE_all), axis=0)
    stacked = np.concatenate(groups, axis=0)
    missing, unobservable = {}, {}
    for n in names:
        i = comp == n
        k = int(np.sum(~np.all(np.isfinite(stacked[:, i]), axis=1)))
        if k:
            missing[n] = k
        if not usable[i].all():
            unobservable[n] = (f"not observed in {k} of {n_runs} fingerprint runs (too few to "
                               f"estimate its response to every parameter)")
    if unobservable:
        log.warning("fingerprints: observable(s) %s dropped: the simulator could not observe "
                    "them often enough", sorted(unobservable))
    keep_names = [n for n in names if n not in unobservable]
    keep = np.isin(comp, keep_names)
    design = design.__class__(tuple(design[n] for n in keep_names), design.title, design.source,
                              design.path, design.notes)
    roles = design.roles()
    rows_cal, rows_val, rows_cand = roles == "calibrate", roles == "validate", roles == "candidate"
    if not rows_cal.any():
        raise ConfigError(f"the simulator could not observe any calibration observable often "
                          f"enough to fingerprint it ({unobservable})")
    base_s, sim_var, sens, sim_dof = base_s[:, keep], sim_var[keep], sens[keep], sim_dof[keep]
    uneven = _uneven_scatter([g[:, keep] for g in groups], point_names, design,
                             p_scatter[keep], aside[:, keep])
    if uneven:
        log.warning("fingerprints: the run-to-run scatter differs between parameter points "
                    "for %s; points that scatter unlike the base keep their own",
                    sorted(uneven))
    D_all, SE_all = D_all[:, keep], SE_all[:, keep]

    fps = []
    for k, e in enumerate(effects):
        m1, m2 = e.reference_magnitudes
        D, SE = D_all[2 * k:2 * k + 2], SE_all[2 * k:2 * k + 2]
        # Keep the quadratic term only where the two magnitudes disagree with a linear
        # response beyond the fingerprints' own estimation noise (else it fits noise).
        dev = D[1] / m2 - D[0] / m1
        se_dev = np.sqrt((SE[1] / m2) ** 2 + (SE[0] / m1) ** 2)
        ok = se_dev > 0
        if ok.any():
            curv_chi2 = float(np.sum((dev[ok] / se_dev[ok]) ** 2))
            curved = curv_chi2 > stats.chi2.isf(0.01, int(ok.sum())) or (~ok & (dev != 0)).any()
        else:
            curved = bool(np.any(dev != 0))
        nodes = np.array([0.0, m1, m2])
        resp = np.vstack([np.zeros(D.shape[1]), D])
        fps.append(Fingerprint(e, np.array([m1, m2]), D, SE, nodes, resp, not curved,
                               run_var=run_var_all[k][:, keep]))
    threshold = selection_threshold(alpha, len(effects))
    out = FingerprintSet(design, tuple(keep_names), rows_cal, rows_val, rows_cand, base, seeds,
                         base_s, sim_var, _design_sigma(design, keep_names), tuple(nuisance), sens,
                         tuple(fps), threshold, alpha, simulator_name, n_runs,
                         {"missing_runs": missing, "unobservable": unobservable,
                          "extrapolated": extrapolated, "uneven_scatter": uneven,
                          "sensitivity_steps": steps}, sim_dof)
    return assess_fingerprints(out)
