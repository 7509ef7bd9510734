"""The sim-to-real gap diagnosis: where, which, how far, and what to measure next.

:func:`diagnose` talks to simulations only through the simulator interface
``simulator(base, effects, seed) -> Observations`` (see
:data:`bedstruct.diagnose.fingerprints.Simulator`).

.. versionadded:: 0.1
"""

from __future__ import annotations

from dataclasses import replace
from typing import Mapping, Sequence

import numpy as np
from scipy import stats

from ..errors import ConfigError
from .attribution import Attribution, attribute
from .catalogue import Effect, catalogue as _catalogue
from .fingerprints import FingerprintSet, selection_threshold
from .identifiability import assess_fingerprints
from .fingerprint_runs import compute_fingerprints
from .fingerprint_runs import simulate_node
from .replicates import Simulator, simulate_replicates
from .parameters import parameter_bounds
from .measurements import MeasurementSet
from .measurement_io import measurement_from_dict
from .separation import not_told_apart
from .where import standardised_residuals, where
from .confirm import (RERUN_SEED_STRIDE, Shrink, component_gaps, confirm_attribution, gap_size,
                      shrink_interval,
                      p_fit_z as _p_fit_z, params_after as _params_after)
from .trial_counts import TrialCheck, file_trials, trial_check, unread_counts
from .noise_correlation import correlation_among, correlation_matrix, quadratic_form
from .diagnosis_result import Diagnosis, NextMeasurement, _residual

__all__ = ["candidate_design", "diagnosis_design", "diagnose"]


def candidate_design(effects: Sequence[Effect], existing: MeasurementSet | None = None) -> MeasurementSet:
    """Design-only observables that would identify the effects (their ``identify_with`` lists).

    Candidates whose name, or whose kind and conditions, already exist in
    ``existing`` are left out.
    """
    seen = set(existing.names) if existing is not None else set()
    same = {(m.kind, repr(sorted(m.conditions.as_dict().items()))) for m in (existing or ())}
    out = []
    for e in effects:
        for spec in e.identify_with:
            key = (spec["kind"], repr(sorted(dict(spec["conditions"], **(
                {"time_window": list(spec["conditions"]["time_window"])}
                if "time_window" in spec["conditions"] else {})).items())))
            if spec["name"] in seen or key in same:
                continue
            seen.add(spec["name"])
            same.add(key)
            d = {"name": spec["name"], "kind": spec["kind"], "role": "candidate",
                 "uncertainty": spec["uncertainty"], "unit": spec["unit"],
                 "conditions": dict(spec["conditions"]),
                 "note": f"candidate measurement suggested by the catalogue entry {e.name!r}"}
            if spec["kind"] == "dynamic_angle_series":
                d["windows"] = [list(spec["conditions"]["time_window"])]
            if spec["kind"] == "psd":
                d["percentiles"] = [10, 50, 90]
            out.append(measurement_from_dict(d))
    return MeasurementSet(tuple(out), title="candidate measurements")


def diagnosis_design(measurements: MeasurementSet, effects: Sequence[Effect]) -> MeasurementSet:
    """The observables a diagnosis simulates.

    The measured observables (calibrate, validate), then those the file tried but read in
    none of their trials (the simulator must give them for the trial check,
    :mod:`~bedstruct.diagnose.trial_counts`), then candidate measurements of what is in
    neither.
    """
    measured = measurements.select(("calibrate", "validate"))
    tried = tuple(m for m in measurements.unmeasured if m.role in ("calibrate", "validate"))
    design = replace(measured, measurements=measured.measurements + tried, unmeasured=())
    return design.merged(candidate_design(effects, design))


def _measured_vectors(measurements: MeasurementSet, fps: FingerprintSet):
    """Align the measurements with the fingerprint rows.

    Returns the fingerprint set restricted to what both have (an observable of the
    design that the measurement file lacks is left out; one the simulator could not
    observe, listed in ``fps.meta["unobservable"]``, is skipped with a note), the
    measured-row mask, the measured names, values, uncertainties and the notes.
    """
    notes = []
    unobservable = dict(fps.meta.get("unobservable", {}))
    design_meas = [n for n in fps.names if fps.design[n].role != "candidate"]
    absent = [n for n in design_meas if n not in measurements]
    for n in design_meas:
        if n in measurements and measurements[n].role != fps.design[n].role:
            raise ConfigError(f"observable {n!r}: role {measurements[n].role!r} differs from the "
                              f"fingerprint design ({fps.design[n].role!r})")
    extra = set(measurements.select(("calibrate", "validate")).names) - set(fps.names)
    unknown = sorted(extra - set(unobservable))
    if unknown:
        raise ConfigError(f"measurements: observable {unknown[0]!r} is not in the fingerprint design")
    for n in sorted(extra):
        notes.append(f"{n}: measured but not used: {unobservable[n]}")
    if absent:
        fps = fps.restrict([n for n in fps.names if n not in set(absent)])
        # those read in no trial have a note of their own (Diagnosis.data_notes)
        tried = {m.name for m in measurements.unmeasured}
        untried = [n for n in absent if n not in tried]
        if untried:
            notes.append(f"not measured, left out of the fingerprints: {', '.join(untried)}")
    names = [n for n in fps.names if fps.design[n].role != "candidate"]
    rows = ~fps.rows_candidate
    y = np.concatenate([measurements[n].values for n in names])
    sm = np.concatenate([measurements[n].uncertainty for n in names])
    return fps, rows, names, y, sm, tuple(notes)


def _within_simulator_domain(simulator, nuisance, bounds) -> dict:
    """``bounds`` of the recalibrated parameters narrowed to the simulator's domain.

    A simulator with a ``parameter_box()`` (an emulator: its run library's design range)
    answers only inside it, so the recalibration is fitted inside it too; a fit that ends
    on the box's edge says so, as on any bound.
    """
    out = dict(bounds or {})
    box = getattr(simulator, "parameter_box", None)
    if box is None:
        return out
    physical = parameter_bounds(nuisance, out)
    for k, (lo, hi) in box().items():
        if k in physical:
            plo, phi = physical[k]
            out[k] = (max(plo, lo), min(phi, hi))
    return out


def _refused_recalibration(exc: ConfigError, fps, params, names) -> ConfigError:
    """The simulator's refusal of a recalibrated point, saying it is one (not the base).

    ``params`` are the recalibrated parameters (None: a refit of the effects' models).
    """
    if params is None:
        where = "a refitted model (recalibrated parameters with effects)"
    else:
        limits = fps.parameter_bounds()
        parts = []
        for n in fps.nuisance:
            v = float(params[n])
            lo, hi = limits.get(n, (-np.inf, np.inf))
            edge = " (at its bound)" if v <= lo or v >= hi else ""
            parts.append(f"{n} {v:.6g}{edge}, base {float(fps.base[n]):.6g}")
        where = f"the recalibrated parameters ({'; '.join(parts)})"
    return ConfigError(f"the simulator refused {where}, fitted to the calibration observables "
                       f"{', '.join(names)}: {exc}")


def diagnose(measurements: MeasurementSet, simulator: Simulator, *, base: Mapping[str, float],
             effects: Sequence[Effect] | None = None,
             nuisance: Sequence[str] = ("cohesion_energy_density",), replicates: int = 4,
             top_up: int = 0, seed: int = 0, alpha: float = 0.05, select_alpha: float = 0.01,
             gof_alpha: float = 0.01, heldout_alpha: float = 0.1, max_effects: int = 2,
             fingerprints: FingerprintSet | None = None, simulator_name: str | None = None,
             refine: int = 2, confirm_rounds: int = 2, bounds=None, bridge=None,
             partial_shrink: float = 0.5, progress: bool = False) -> Diagnosis:
    """Diagnose the gap between a simulator and a measurement set.

    Parameters
    ----------
    measurements : MeasurementSet
        Real data (see :func:`load_measurements`).
    simulator : callable
        ``simulator(base, effects, seed) -> Observations`` producing every
        measured observable (and, where it can, the candidate measurements of
        :func:`diagnosis_design`).
    base : mapping
        Base parameters of the calibrated model (SI).
    effects : sequence of Effect, optional
        Catalogue to consider (default: all of :data:`CATALOGUE`).
    nuisance : sequence of str
        Base parameters that recalibration may change (projected out of the fingerprints).
    bounds : mapping of str to (float, float), optional
        Narrower bounds of the recalibrated parameters than their physical ones
        (:func:`~bedstruct.diagnose.parameters.parameter_bounds`); the recalibration is
        fitted within them, and a fit that ends on one says so.
    replicates : int
        Replicate seeds per parameter point.
    top_up : int
        Further seeds for the base and the effects whose identifiability is marginal
        after ``replicates`` seeds (see :func:`compute_fingerprints`).
    seed : int
        First seed (>= 0).
    alpha : float
        Level of the "is there a gap" tests (where).
    select_alpha : float
        Family-wise level of the effect selection (Bonferroni over effects): the
        expected false-attribution rate when there is no effect.
    gof_alpha : float
        Goodness-of-fit level below which the best model does not explain the gap (the
        fit, and the rerun's check on the calibration observables).
    heldout_alpha : float
        Level of the rerun's check on the held-out observables, which no fit has seen: an
        answer (an effect, or recalibration alone) whose rerun departs from them at this
        level is not confirmed, unless it is a partial explanation (``partial_shrink``). A
        true model fails it at this rate; a change outside the catalogue that a catalogue
        effect mimics on the calibration observables is caught by it.
    max_effects : int
        Largest combination of effects (1 or 2).
    fingerprints : FingerprintSet, optional
        Reuse fingerprints computed for the same design (the validation does).
    simulator_name : str, optional
        Label stored in the output (default the simulator's ``name`` attribute).
    refine : int
        Refinement rounds: the leading effects are simulated at their fitted
        magnitudes and the fingerprints re-interpolated through those runs.
    confirm_rounds : int
        Largest number of refits after the rerun that checks an attribution contradicts the
        fit on the calibration observables: the recalibration beyond its finite-difference
        step is re-simulated, or a single effect's rerun becomes a fingerprint node; the
        model is refitted and rerun (see :func:`~bedstruct.diagnose.confirm.confirm_attribution`).
    bridge : EngineBridge, optional
        The offset of the user's engine from ``simulator`` at the base point
        (:func:`~bedstruct.diagnose.bridge.engine_bridge`): the measurements are diagnosed
        as their gap from that engine's baseline (:meth:`EngineBridge.apply`), and the
        result says so in its data notes and ``settings["bridge"]``. A bridge with effect
        probes also corrects ``simulator``'s response to each probed effect by the
        engine's (:meth:`EngineBridge.simulator`).
    partial_shrink : float
        An attribution whose rerun agrees with the calibration observables but not with the
        held-out ones is kept as a *partial* explanation (``attribution.partial``) when the
        lower end of the held-out shrink's 90 % interval exceeds this fraction: the effect
        closes more than this share of the held-out gap (one-sided 95 %) but leaves a
        remainder beyond noise. Below it the attribution is not confirmed (``unexplained``).
        ``1`` turns partial explanations off.

    Returns
    -------
    Diagnosis

    Raises
    ------
    ConfigError
        Before anything is simulated, when ``effects`` is empty, when the file has no
        calibration observable or none of them gave a reading, or when ``seed`` is not a
        whole number >= 0.
    """
    effects = tuple(_catalogue() if effects is None else effects)
    source = measurements.path or measurements.title or "measurements"
    if not effects:
        raise ConfigError("effects: expected at least one catalogue effect to diagnose with; "
                          "got none")
    if not any(m.role == "calibrate" for m in measurements) and \
            not any(m.role == "calibrate" for m in measurements.unmeasured):
        raise ConfigError(f"{source}: no observable has role 'calibrate' (the default role); "
                          f"the recalibration and the effects are fitted on calibration "
                          f"observables only, so at least one is needed")
    if isinstance(seed, bool) or not isinstance(seed, (int, float, np.integer, np.floating)) \
            or not (np.isfinite(seed) and seed == int(seed) and seed >= 0):
        raise ConfigError(f"seed: expected an integer >= 0; got {seed!r}")
    if not any(m.role == "calibrate" for m in measurements) and \
            any(m.role == "calibrate" for m in measurements.unmeasured):
        raise ConfigError(
            f"{source}: no calibration "
            f"observable gave a reading in any of its trials "
            f"({', '.join(m.name for m in measurements.unmeasured)}); there is nothing to fit "
            f"the recalibration and the effects to")
    name = simulator_name or getattr(simulator, "name", type(simulator).__name__)
    if bridge is not None:
        measurements = bridge.apply(measurements)
        simulator = bridge.simulator(simulator)
    bounds = _within_simulator_domain(simulator, nuisance, bounds)
    if fingerprints is None:
        design = diagnosis_design(measurements, effects)
        fps = compute_fingerprints(simulator, design, base, effects, nuisance=nuisance,
                                   replicates=replicates, top_up=top_up, seed=seed,
                                   alpha=select_alpha,
                                   simulator_name=name, progress=progress)
    else:
        missing = [e.name for e in effects if e.name not in fingerprints.effect_names]
        if missing:
            raise ConfigError(f"fingerprints: no fingerprint for effect {missing[0]!r}")
        fps = fingerprints.subset([e.name for e in effects])
        fps = replace(fps, alpha=select_alpha)
    fps, rows_meas, names, y, sm, data_notes = _measured_vectors(measurements, fps)
    if bridge is not None:
        data_notes = (bridge.note(),) + tuple(data_notes)
    # the file's trials without a reading (trial_counts), and the observables the reruns must
    # give for them that the fit does not use (read in no trial)
    trials = file_trials(measurements)
    unread_pts = fps.meta.get("unread_runs", {})
    trial_names = [n for n in trials if n not in names and n in unread_pts]
    n_comp = {m.name: m.n_components
              for m in tuple(measurements.measurements) + tuple(measurements.unmeasured)}
    sigma_meas = fps.sigma_meas.copy()
    sigma_meas[rows_meas] = sm
    # identifiability in this file's noise and for this catalogue, as fingerprints computed
    # for the file would have it (reused ones were assessed in their design's noise)
    fps = assess_fingerprints(replace(fps, sigma_meas=sigma_meas,
                                      threshold=selection_threshold(select_alpha, len(effects)),
                                      bounds=dict(bounds or {})))

    base_meas = fps.base_samples[:, rows_meas]
    # the measured observables in the fingerprints' row order (a file may list them otherwise)
    measured = replace(measurements, measurements=tuple(measurements[n] for n in names))
    corr = correlation_matrix(fps, rows_meas)   # components read from one run
    wh = where(measured, base_meas,
               sim_var=fps.sim_var[rows_meas], alpha=alpha, correlation=corr)
    residual = _residual(measurements, fps)
    att = attribute(residual, fps, alpha=select_alpha, gof_alpha=gof_alpha, max_effects=max_effects)
    bar = None  # the runs after the fingerprints: their number depends on what the fits find
    if progress:
        from tqdm import tqdm
        bar = tqdm(desc="reruns", unit="run")
    # Refinement (Gauss-Newton with the simulator in the loop): simulate the leading
    # effects at their fitted magnitudes, add those responses as fingerprint nodes, refit.
    n_refine_runs = 0
    for _ in range(max(int(refine), 0)):
        if att.best.effects:
            lead = list(zip(att.best.effects, att.best.magnitudes))
        elif att.ranking and att.ranking[0].delta_chi2 > 0.5 * att.threshold:
            top = att.ranking[0]
            lead = [(top.effect, top.magnitude)]
        else:
            break
        new = {}
        for e, a in lead:
            node = simulate_node(simulator, fps, e, a)
            if node is None:
                continue
            n_refine_runs += len(fps.seeds)
            if bar is not None:
                bar.update(len(fps.seeds))
            new[e] = node
        if not new:
            break
        fps = replace(fps, fingerprints=tuple(new.get(f.name, f) for f in fps.fingerprints))
        att = attribute(residual, fps, alpha=select_alpha, gof_alpha=gof_alpha, max_effects=max_effects)

    # ---- how far: rerun at recalibrated base (+ effects), compare held-out gaps
    rerun_seeds = [int(seed) + RERUN_SEED_STRIDE + i for i in range(fps.n_replicates)]
    held_meas = fps.rows_validate[rows_meas]
    z_before = wh.residuals.z
    recal_shift = att.null.nuisance   # what the recalibrated rerun simulates
    p_recal = _params_after(fps.base, fps.nuisance, recal_shift)
    try:
        s_recal = simulate_replicates(simulator, p_recal, {}, rerun_seeds,
                                      list(names) + trial_names)
    except ConfigError as exc:
        raise _refused_recalibration(exc, fps, p_recal, names) from None
    n_meas_cols = int(np.sum(rows_meas))
    s_recal, s_recal_extra = s_recal[:, :n_meas_cols], s_recal[:, n_meas_cols:]
    if bar is not None:
        bar.update(len(rerun_seeds))
    z_recal, _, _ = standardised_residuals(y, sm, s_recal, sim_var=fps.sim_var[rows_meas])
    try:
        conf = confirm_attribution(att, fps, residual, simulator, y=y, sigma_meas=sm,
                                   names=names, seed=seed, rounds=confirm_rounds,
                                   alpha=select_alpha, max_effects=max_effects, progress=bar,
                                   extra_names=trial_names)
    except ConfigError as exc:
        raise _refused_recalibration(exc, fps, None, names) from None
    att, fps = conf.attribution, conf.fingerprints
    if conf.samples is not None:
        chk, n_trial_runs = _trial_check(
            simulator, trials, unread_pts, n_comp, names, trial_names, conf.samples,
            conf.extra_samples, _params_after(fps.base, fps.nuisance, att.best.nuisance),
            {e: float(a) for e, a in zip(att.best.effects, att.best.magnitudes)},
            conf.rerun_seeds)
    else:
        chk, n_trial_runs = _trial_check(simulator, trials, unread_pts, n_comp, names,
                                         trial_names, s_recal, s_recal_extra, p_recal, {},
                                         rerun_seeds)
    if bar is not None:
        bar.update(n_trial_runs)
        bar.close()
    if conf.samples is not None:
        model = att.best
        z_after = conf.z_after
        mags = {e: float(a) for e, a in zip(model.effects, model.magnitudes)}
        label = model.label
        nuis = {k: float(v) for k, v in zip(fps.nuisance, model.nuisance)}
    else:
        # a refit with re-simulated sensitivities may move the null's shift; report the
        # one whose rerun the gaps come from
        mags, z_after, label = {}, z_recal, att.null.label
        nuis = {k: float(v) for k, v in zip(fps.nuisance, recal_shift)}
    per_obs = []
    comp_names = np.asarray([n for n in names for _ in range(measurements[n].n_components)])
    for n in dict.fromkeys(comp_names[held_meas]):
        i = (comp_names == n) & held_meas
        c = correlation_among(corr, i)
        b, r_, a = gap_size(z_before[i], c), gap_size(z_recal[i], c), gap_size(z_after[i], c)
        per_obs.append({"observable": str(n), "before": b[0], "recalibrated": r_[0], "after": a[0],
                        "before_excess": b[1], "after_excess": a[1]})
    c = correlation_among(corr, held_meas)
    b, r_, a = (gap_size(z_before[held_meas], c), gap_size(z_recal[held_meas], c),
                gap_size(z_after[held_meas], c))
    frac = 1.0 - a[1] / b[1] if b[1] > 0 else float("nan")
    frac_interval = shrink_interval(z_before[held_meas], z_after[held_meas], c, seed=seed)
    frac_rms = 1.0 - a[0] / b[0] if b[0] > 0 else float("nan")
    p_cal, p_held = conf.p_calibration, conf.p_heldout
    q, n_held = quadratic_form(z_before[held_meas], c)
    p_before = float(stats.chi2.sf(q, n_held)) if n_held else float("nan")
    comp_labels = [measurements[n].labels[j] for n in names for j in range(measurements[n].n_components)]
    # where the checks see the rerun depart, in the noise each check tests
    z_worst = conf.z_check if conf.samples is not None else z_after
    worst = _worst_components(z_worst, comp_names, comp_labels, held_meas)
    p_trials = chk.p_value if trials else float("nan")
    gaps = component_gaps(wh.residuals, sm, s_recal, conf.samples, run_var=fps.sim_var[rows_meas])
    shrink = Shrink(label, mags, nuis, b[0], r_[0], a[0], b[1], r_[1], a[1], frac, frac_rms,
                    tuple(per_obs), int(held_meas.sum()), p_cal, p_held, conf.refits, p_before,
                    worst, p_trials, chk.rows, frac_interval, gaps)
    trials_failed = bool(trials) and chk.p_value < gof_alpha
    refit_note = "; ".join(_refit_text(r) for r in conf.refits)
    if refit_note:
        refit_note += ("; refitted" + (f" and rerun at {_magnitudes_text(mags)}"
                                       if att.verdict == "attributed" else ""))
        att = replace(att, reason=refit_note + "; " + att.reason)

    # Verdict checks on the reruns (the held-out observables never enter a fit): a
    # significant gap that the calibration observables cannot attribute, or an attribution
    # whose rerun the calibration or the held-out observables contradict, is 'unexplained'.
    verdict_note = ""
    if att.verdict == "none" and wh.significant:
        # Recalibration alone may close a significant gap (e.g. a cohesion calibrated
        # elsewhere): then the rerun at the recalibrated base must agree with every measured
        # observable, the held-out ones included, else nothing explains the gap.
        p_recal = _p_fit_z(z_recal, corr)
        p_recal_held = _p_fit_z(z_recal[held_meas], c) if held_meas.any() else float("nan")
        if held_meas.any() and p_recal >= gof_alpha and p_recal_held >= heldout_alpha \
                and not trials_failed:
            att = replace(att, reason=(
                f"recalibration alone closes the gap: the rerun at the recalibrated "
                f"{', '.join(fps.nuisance)} agrees with all measured observables (p = {p_recal:.2g}) "
                f"and with the held-out ones (p = {p_recal_held:.2g}); no effect is needed. "
                + att.reason))
        else:
            verdict_note = ("the gap is significant (where) but the calibration observables neither "
                            "show it beyond recalibration nor attribute it"
                            + (f", and the rerun at the recalibrated base leaves the measured "
                               f"observables inconsistent (p = {p_recal:.2g}; the held-out ones "
                               f"p = {p_recal_held:.2g})"
                               if held_meas.any() and not trials_failed else "")
                            + (f", and the recalibrated base does not give the trials without a "
                               f"reading ({chk.text()})" if trials_failed else "")
                            + "; " + att.reason)
    elif att.verdict == "none" and trials_failed:
        verdict_note = (f"the trials without a reading depart from the recalibrated base's runs "
                        f"({chk.text()}): a gap that no catalogue effect was fitted to; "
                        + att.reason)
    elif att.verdict == "attributed":
        failed = []
        if p_cal < gof_alpha:
            failed.append(f"the calibration observables (p = {p_cal:.2g} < {gof_alpha:g}"
                          f"{_worst_text(worst, 'calibrate')}; "
                          f"the fit interpolated between simulated magnitudes said "
                          f"p = {att.best.p_fit:.2g})")
        if p_held < heldout_alpha:
            failed.append(f"the held-out observables (p = {p_held:.2g} < {heldout_alpha:g}"
                          f"{_worst_text(worst, 'validate')})")
        if trials_failed:
            failed.append(f"the trials without a reading ({chk.text()})")
        lo_shrink = float(frac_interval[0])
        held_out_only = bool(failed) and p_cal >= gof_alpha and not trials_failed
        if held_out_only and np.isfinite(lo_shrink) and lo_shrink > partial_shrink:
            # the effect closes most of the held-out gap: named, with the remainder said
            att = replace(att, partial=True, reason=(
                (refit_note + "; " if refit_note else "")
                + f"{att.best.label} fits the calibration observables and closes "
                f"{100 * frac:.0f} % of the held-out gap (90 % interval {100 * lo_shrink:.0f}-"
                f"{100 * float(frac_interval[1]):.0f} %), but the rerun at its fitted magnitude "
                f"leaves the held-out observables inconsistent (p = {p_held:.2g}"
                f"{_worst_text(worst, 'validate')}): a partial explanation, something else "
                "remains"))
        elif failed:
            verdict_note = ((refit_note + "; " if refit_note else "")
                            + f"{att.best.label} fits the calibration observables but the rerun at "
                            f"its fitted magnitude leaves {' and '.join(failed)} inconsistent: "
                            f"not confirmed")
    if verdict_note:
        att = replace(att, verdict="unexplained", selected=(), reason=verdict_note)
    close = not_told_apart(att, fps)
    if close:
        att = replace(att, reason=att.reason + "; not told apart from " + ", ".join(
            f"{c['effect']} (which lowers chi2 by only {c['preference']:.1f} less; these "
            f"observables tell the two apart from a gap of {c['gap_to_separate_sigma']:.1f} "
            f"sigma, this one is {c['gap_sigma']:.1f})" for c in close)
            + ": see what to measure next")

    nxt = _next_measurements(att, fps)
    settings = {"replicates": fps.n_replicates, "top_up": {
                    "effects": list(fps.topped_up), "seeds": list(fps.top_up_seeds)},
                "seed": seed, "alpha": alpha,
                "select_alpha": select_alpha, "gof_alpha": gof_alpha,
                "heldout_alpha": heldout_alpha,
                "max_effects": max_effects, "nuisance": list(fps.nuisance),
                "base": dict(fps.base), "effects": [e.name for e in effects],
                "refine": refine, "confirm_rounds": confirm_rounds,
                "data_notes": list(data_notes),
                "bridge": None if bridge is None else bridge.as_dict(),
                "missing_runs": dict(fps.meta.get("missing_runs", {})),
                "uneven_scatter": dict(fps.meta.get("uneven_scatter", {})),
                "node_scatter": _node_scatter(fps),
                "correlated_scatter": list(fps.meta.get("correlated_scatter", [])),
                "simulator_runs": (0 if fingerprints is not None else fps.n_runs) + n_refine_runs
                + len(rerun_seeds) + conf.n_runs}
    return Diagnosis(measurements, fps, wh, att, shrink, nxt, name, settings)


def _trial_check(simulator, trials, unread_pts, n_comp, names, trial_names, samples, extra,
                 params, mags, seeds) -> tuple[TrialCheck, int]:
    """The file's trials without a reading against the final model's runs.

    The runs are the last rerun (``samples`` on ``names``, ``extra`` on ``trial_names``);
    where the file holds an observable read in no trial, ``2 x len(seeds)`` further seeds
    at the same parameters are run for the trials' observables (a model is then judged on
    an outcome its fit never saw, and three runs cannot contradict three trials at the
    fit's level). Returns the check and the further runs made.
    """
    if not trials:
        return TrialCheck(), 0
    cols = list(names) + list(trial_names)
    both = np.hstack([samples, extra]) if extra is not None and extra.size else samples
    counts = unread_counts(both, cols, n_comp)
    tried = [n for n in trials if n in counts]
    n_more = 0
    if any(trials[n][0] >= trials[n][1] for n in tried) and seeds:
        more_seeds = [int(max(seeds)) + 1 + i for i in range(2 * len(seeds))]
        more = simulate_replicates(simulator, params, mags, more_seeds, tried)
        n_more = len(more_seeds)
        for n, (k, r) in unread_counts(more, tried, n_comp).items():
            counts[n] = (counts[n][0] + k, counts[n][1] + r)
    return trial_check(trials, unread_pts, mags, counts), n_more


def _node_scatter(fps: FingerprintSet) -> list[dict]:
    """Components on which a node simulated after the fingerprints scattered unlike the base."""
    pooled = fps.run_sd()
    comp = fps.design.component_names()
    labels = fps.design.component_labels()
    out = []
    for f in fps.fingerprints:
        for a, var in f.scatter_nodes:
            sd = np.sqrt(var)
            for i in np.flatnonzero(np.isfinite(sd) & (sd > pooled * (1.0 + 1e-9))):
                out.append({"effect": f.name, "magnitude": float(a),
                            "component": f"{comp[i]} [{labels[i]}]", "sd": float(sd[i]),
                            "sd_pooled": float(pooled[i])})
    return out


def _refit_text(refit: dict) -> str:
    """One clause on a rerun that contradicted the fit, and what was re-simulated."""
    head = (f"the rerun of {refit['model']} at {_magnitudes_text(refit['magnitudes'])} contradicted "
            f"the fit on the calibration observables (p = {refit['p_rerun_calibration']:.2g}; "
            f"the fit had said p = {refit['p_fit']:.2g})")
    if "recalibration" in refit:
        shifts = ", ".join(f"{k} {v:+.3g}" for k, v in refit["recalibration"].items())
        return (f"{head}: its recalibration ({shifts}) extrapolated the finite-difference "
                f"sensitivities, so the base was simulated at that shift")
    return f"{head}, so the rerun became a fingerprint node"


def _worst_components(z, comp_names, comp_labels, held, n: int = 3) -> tuple[dict, ...]:
    """The ``n`` calibration and the ``n`` held-out components of largest ``|z|``."""
    z = np.asarray(z, float)
    out = []
    for role, mask in (("calibrate", ~held), ("validate", held)):
        idx = np.flatnonzero(mask & np.isfinite(z))
        for i in idx[np.argsort(-np.abs(z[idx]), kind="stable")][:n]:
            out.append({"observable": str(comp_names[i]), "component": str(comp_labels[i]),
                        "role": role, "z": float(z[i])})
    return tuple(out)


def _worst_text(worst, role: str) -> str:
    """", largest OBS [label] +z sigma, ..." for the components of one role beyond 2 sigma."""
    items = [f"{w['observable']} [{w['component']}] {w['z']:+.1f} sigma" for w in worst
             if w["role"] == role and abs(w["z"]) > 2.0]
    return (", largest " + ", ".join(items)) if items else ""


def _magnitudes_text(mags: Mapping[str, float]) -> str:
    return ", ".join(f"{e} = {a:.3g}" for e, a in mags.items())


def _predict(model, fps: FingerprintSet) -> np.ndarray:
    out = fps.sensitivities @ model.nuisance if len(model.nuisance) else np.zeros(len(fps.sigma))
    for e, a in zip(model.effects, model.magnitudes):
        out = out + fps[e].predict(float(a))
    return out


def _next_measurements(att: Attribution, fps: FingerprintSet, n: int = 5) -> tuple[NextMeasurement, ...]:
    models = list(att.models)
    first = att.best if att.verdict == "attributed" else models[0]
    second = next((m for m in models if set(m.effects) != set(first.effects)), None)
    if second is None:
        return ()
    rows = ~fps.rows_calibrate
    if not rows.any():
        return ()
    sep = np.abs(_predict(first, fps) - _predict(second, fps)) / fps.sigma
    comp = fps.design.component_names()
    out = []
    for name in dict.fromkeys(comp[rows]):
        i = (comp == name) & rows
        m = fps.design[name]
        out.append(NextMeasurement(str(name), m.kind, m.conditions.label(), m.role,
                                   float(np.sqrt(np.sum(sep[i] ** 2))), (first.label, second.label),
                                   m.role != "candidate"))
    out.sort(key=lambda x: -x.separation)
    return tuple(out[:n])
