"""The fingerprint runs: which simulations a catalogue needs, and the set built from them.

:func:`compute_fingerprints` simulates the base point, one finite-difference point per
recalibrated base parameter and every effect at its two reference magnitudes, all on the
same replicate seeds, and builds the :class:`~bedstruct.diagnose.fingerprints.FingerprintSet`
from the paired differences. With ``top_up`` it then runs the base and the effects whose
identifiability is still undecided by their own estimation noise
(:meth:`FingerprintSet.marginal`) on further seeds, and builds the set again: simulation
time goes where the judgement is close. The set's type is
:class:`~bedstruct.diagnose.fingerprints.FingerprintSet`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import logging
from typing import Mapping, Sequence

import numpy as np
from scipy import stats

from ..errors import ConfigError
from .catalogue import Effect
from .effect_response import Fingerprint
from .fingerprints import FingerprintSet, _design_sigma, selection_threshold
from .identifiability import _correlated_scatter, _uneven_scatter, assess_fingerprints
from .measurements import MeasurementSet
from .replicates import (Simulator, homogeneous_variance, simulate_replicates,
                         variance_upper_bound)
from .where import _nan_mean, _nan_var

__all__ = ["compute_fingerprints", "simulate_node"]

log = logging.getLogger(__name__)


def compute_fingerprints(simulator: Simulator, design: MeasurementSet, base: Mapping[str, float],
                         effects: Sequence[Effect], *, nuisance: Sequence[str] = ("cohesion_energy_density",),
                         rel_step: float = 0.05, replicates: int = 4, seed: int = 0,
                         top_up: int = 0, alpha: float = 0.05, simulator_name: str = "",
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
    top_up : int
        Further seeds for the effects whose identifiability is marginal after the
        shared seeds (:meth:`FingerprintSet.marginal`): the base and both magnitudes of
        each such effect are run on them, and the set is built again (one round;
        0, the default, adds none). The set records them in ``topped_up`` and
        ``top_up_seeds``.
    alpha : float
        Family-wise level; the selection threshold is the chi-square(1) quantile
        at ``alpha / n_effects``.

    Returns
    -------
    FingerprintSet

    Examples
    --------
    A toy simulator whose effect is close to the selection threshold on two seeds, so
    that the base and the effect are run on four more:

    >>> from bedstruct.diagnose import Effect, MeasurementSet, Observations, measurement_from_dict
    >>> design = MeasurementSet(tuple(measurement_from_dict(dict(
    ...     name=n, kind="static_angle", value=0.0, uncertainty=1.0, role="calibrate"))
    ...     for n in ("a", "b")))
    >>> effect = Effect(name="e", title="e", magnitude="m", unit="1", prior=(0.0, 1.0),
    ...                 physics="", signature="", sources=(), engine_map=())
    >>> def simulator(base, effects, seed):
    ...     m = effects.get("e", 0.0)
    ...     noise = np.random.default_rng([seed, int(100 * m)]).standard_normal(2)
    ...     return Observations({"a": base["k"] + 2.5 * m + noise[0], "b": base["k"] + noise[1]})
    >>> fps = compute_fingerprints(simulator, design, {"k": 1.0}, [effect], nuisance=(),
    ...                            replicates=2, top_up=4)
    >>> fps.topped_up, fps.top_up_seeds, fps.n_replicates, len(fps.seeds)
    (('e',), (2, 3, 4, 5), 2, 6)
    """
    if replicates < 2:
        raise ConfigError(f"replicates: need >= 2 replicate seeds; got {replicates}")
    if int(top_up) != top_up or top_up < 0:
        raise ConfigError(f"top_up: expected a whole number >= 0; got {top_up!r}")
    base = dict(base)
    for p in nuisance:
        if p not in base:
            raise ConfigError(f"recalibrate: parameter {p!r} is not among the base parameters "
                              f"{sorted(base)}")
    seeds = tuple(int(seed) + i for i in range(replicates))

    def step(p):  # the nuisance parameter's finite-difference point and step
        h = rel_step * abs(base[p]) if base[p] != 0 else rel_step
        return dict(base, **{p: base[p] + h}), h

    # every parameter point: the base, the nuisance steps, each effect at both magnitudes
    points = [("base", dict(base), {})]
    points += [(f"{p} {step(p)[0][p]:.4g}", step(p)[0], {}) for p in nuisance]
    points += [(f"{e.name} {m:g}", dict(base), {e.name: m})
               for e in effects for m in e.reference_magnitudes]
    if hasattr(simulator, "prefetch"):
        # every point's replicates at once (parallel simulators), the probe below among them:
        # run on its own first, it would keep all but one process waiting (the engine checks
        # its design's kinds when it is made)
        simulator.prefetch([(b, e, s) for _, b, e in points for s in seeds], progress=progress)
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

    def run_points(selected, run_seeds, desc):
        bar = None
        if progress:
            from tqdm import tqdm
            bar = tqdm(total=len(selected), desc=desc)
        out = []
        for _, params, eff in selected:
            out.append(simulate_replicates(simulator, params, eff, run_seeds, names))
            if bar:
                bar.update()
        if bar:
            bar.close()
        return out

    samples = run_points(points, seeds, "fingerprints")
    point_seeds = [seeds] * len(points)
    steps = {p: float(step(p)[1]) for p in nuisance}
    build = dict(design=design, names=names, base=base, nuisance=tuple(nuisance), steps=steps,
                 effects=tuple(effects), alpha=alpha, simulator_name=simulator_name)
    fps = _fingerprint_set(point_names=[n for n, _, _ in points], samples=samples,
                           point_seeds=point_seeds, **build)
    marginal = fps.marginal() if top_up else ()
    if not marginal:
        return fps
    extra = tuple(seeds[-1] + 1 + i for i in range(int(top_up)))
    judged = {f.name: (f.signal, f.signal_se, f.identifiable) for f in fps.fingerprints}
    again = [0] + [k for k, (_, _, eff) in enumerate(points) if set(eff) & set(marginal)]
    if hasattr(simulator, "prefetch"):
        simulator.prefetch([(points[k][1], points[k][2], s) for k in again for s in extra],
                           progress=progress)
    more = run_points([points[k] for k in again], extra, "fingerprint top-up")
    for k, s in zip(again, more):
        samples[k] = np.vstack([samples[k], s])
        point_seeds[k] = seeds + extra
    fps = _fingerprint_set(point_names=[n for n, _, _ in points], samples=samples,
                           point_seeds=point_seeds, **build)
    from dataclasses import replace
    for name in marginal:
        f = fps[name]
        s0, se0, id0 = judged[name]
        log.info("fingerprints: %s was marginal on %d seeds (signal %.2f +- %.2f, identifiable "
                 "%s); on %d: %.2f +- %.2f, identifiable %s", name, len(seeds), s0, se0, id0,
                 len(seeds) + len(extra), f.signal, f.signal_se, f.identifiable)
    meta = dict(fps.meta, top_up={name: {"signal": judged[name][0],
                                         "signal_se": judged[name][1],
                                         "identifiable": judged[name][2]} for name in marginal})
    return replace(fps, topped_up=tuple(marginal), top_up_seeds=extra, meta=meta)


def simulate_node(simulator: Simulator, fps: FingerprintSet, effect: str,
                  magnitude: float) -> Fingerprint | None:
    """The fingerprint of ``effect`` with its response simulated at ``magnitude`` added as a node.

    The effect runs on the set's replicate seeds and is paired with the base runs of the
    same seeds, as the fingerprint's own points are. ``None`` when no run is needed: at
    magnitude 0, or when one of the fingerprint's nodes already lies closer to
    ``magnitude`` than 5 % of the effect's upper reference magnitude. Costs
    ``len(fps.seeds)`` simulator calls otherwise.

    Examples
    --------
    >>> from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue,
    ...                                 compute_fingerprints, diagnosis_design, twin_design)
    >>> effects = catalogue(["wall_friction"])
    >>> design = diagnosis_design(twin_design(), effects)
    >>> sim = SurrogateSimulator(design)
    >>> fps = compute_fingerprints(sim, design, BASE_PARAMETERS, effects, replicates=2)
    >>> fp = simulate_node(sim, fps, "wall_friction", 0.3)
    >>> 0.3 in fp.nodes, simulate_node(sim, fps, "wall_friction", 0.0) is None
    (True, True)
    """
    fp = fps[effect]
    a = float(magnitude)
    if a == 0.0 or np.min(np.abs(fp.nodes - a)) < 0.05 * abs(fp.magnitudes[1]):
        return None
    runs = simulate_replicates(simulator, fps.base, {effect: a}, fps.seeds, fps.names)
    # its runs' own scatter where it exceeds the pooled one (heaps that stand or fall)
    run_var, se = fps.node_scatter(runs)
    return fp.with_node(a, _nan_mean(runs - fps.base_samples), run_var=run_var, se=se)


def _fingerprint_set(*, design, names, base, nuisance, steps, effects, alpha, simulator_name,
                     point_names, samples, point_seeds) -> FingerprintSet:
    """The fingerprint set from every point's replicate samples (base first, then the
    nuisance steps, then each effect at its two magnitudes), each point paired with the
    base runs of the same seeds."""
    base_seeds = point_seeds[0]
    base_s = samples[0]
    row = {s: i for i, s in enumerate(base_seeds)}

    def paired(k):  # the point's runs minus the base runs of the same seeds
        return samples[k] - base_s[[row[s] for s in point_seeds[k]]]

    n_nuis = len(nuisance)
    first_effect = 1 + n_nuis
    sens = np.zeros((base_s.shape[1], n_nuis))
    for j, p in enumerate(nuisance):
        sens[:, j] = _nan_mean(paired(1 + j)) / steps[p]
    diffs = [paired(k) for k in range(first_effect, len(samples))]
    groups = list(samples)
    n_runs = int(sum(len(s) for s in point_seeds))
    # one scatter pooled over the points that scatter like the base: a point far from it
    # (e.g. a cohesive block that stands or falls) keeps its own
    sim_var_estimate, sim_dof, aside, p_scatter = homogeneous_variance(groups, alpha=0.01)
    sim_var = sim_var_estimate * variance_upper_bound(sim_dof)
    own = [np.where(aside[g], _nan_var(groups[g]), sim_var_estimate) for g in range(len(groups))]
    run_var_all = [np.vstack(own[first_effect + 2 * k:first_effect + 2 * k + 2])
                   for k in range(len(effects))]

    # Missing data: a run that could not observe a component (e.g. no heap to fit) gives
    # NaN there. Means and paired differences use the finite replicates; an observable
    # that some parameter point never observed has no fingerprint and is dropped.
    D_all = np.array([_nan_mean(d) for d in diffs]).reshape(len(diffs), -1)
    n_pairs = np.array([np.isfinite(d).sum(axis=0) for d in diffs]).reshape(len(diffs), -1)
    sd_pairs = np.array([np.sqrt(_nan_var(d)) for d in diffs]).reshape(len(diffs), -1)
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
                n_pairs[2 * k + a, lost] = n_pairs[2 * k + b, lost]
                extrapolated.setdefault(e.name, []).extend(
                    f"{comp[i]} at {mags[a]:g} (from {mags[b]:g})" for i in np.flatnonzero(lost))
    usable = np.isfinite(sim_var) & (np.isfinite(base_s).sum(axis=0) > 0) \
        & np.all(np.isfinite(sens), axis=1) & np.all(np.isfinite(D_all), axis=0) \
        & np.all(np.isfinite(SE_all), axis=0)
    # runs without a reading, per observable and point (the trial check weighs a file's
    # trials without one against them; see trial_counts)
    point_effects = [{}] * first_effect + [{e.name: float(m)} for e in effects
                                           for m in e.reference_magnitudes]
    unread_runs = {}
    for n in names:
        i = comp == n
        unread_runs[n] = [{"effects": dict(point_effects[g]),
                           "unread": int(np.sum(~np.all(np.isfinite(groups[g][:, i]), axis=1))),
                           "runs": int(groups[g].shape[0])} for g in range(len(groups))]
    missing, unobservable = {}, {}
    for n in names:
        i = comp == n
        k = sum(p["unread"] for p in unread_runs[n])
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
    # an observable the file tried but read in no trial has no uncertainty: it is simulated
    # for the trial check only, and neither calibrates nor validates
    stated = np.isfinite(_design_sigma(design, keep_names))
    rows_cal, rows_val = (roles == "calibrate") & stated, (roles == "validate") & stated
    rows_cand = roles == "candidate"
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
    D_all, SE_all, n_pairs = D_all[:, keep], SE_all[:, keep], n_pairs[:, keep]

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
                               run_var=run_var_all[k][:, keep],
                               delta_n=n_pairs[2 * k:2 * k + 2].copy()))
    threshold = selection_threshold(alpha, len(effects))
    out = FingerprintSet(design, tuple(keep_names), rows_cal, rows_val, rows_cand, base,
                         tuple(base_seeds), base_s, sim_var, _design_sigma(design, keep_names),
                         tuple(nuisance), sens, tuple(fps), threshold, alpha, simulator_name,
                         n_runs,
                         {"missing_runs": missing, "unobservable": unobservable,
                          "unread_runs": unread_runs,
                          "extrapolated": extrapolated, "uneven_scatter": uneven,
                          "correlated_scatter": _correlated_scatter(
                              [g[:, keep] for g in groups], point_seeds, design),
                          "sensitivity_steps": steps}, sim_dof)
    return assess_fingerprints(out)
