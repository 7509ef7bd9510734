"""How a validation's synthetic twins are made and sized.

A twin's measurement file is the mean of repeated simulator runs at a withheld effect
and magnitude, plus reading noise, stating the noise a lab would
(:func:`_twin_measurements`); its magnitude is set so that the effect's gap on the
calibration observables, after recalibration, is a drawn number of sigma in that noise
(:func:`_magnitude_for_snr`), on the response simulated at that magnitude
(:func:`_size_twin`). Split from :mod:`bedstruct.diagnose.validation.validate`, which runs
the plan and scores it.

.. versionadded:: 0.1
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..measurements import MeasurementSet, Observations
from ..measurement_io import load_measurements, write_measurements

log = logging.getLogger("bedstruct.diagnose.validation.validate")


def _repeat_seed(seed: int, k: int) -> int:
    """Seed of the ``k``-th repeated experiment of a twin (the first is the twin's own)."""
    return int(seed) + 7919 * int(k)


def _twin_measurements(design, sim, base_true, effects, seed, folder: Path, idx: int,
                       intrinsic, repeats: int = 1) -> MeasurementSet:
    # Each 'real' experiment carries the run-to-run scatter of the process (the simulator's
    # replicate noise) plus reading noise; the file states the mean of the repeated
    # experiments with its standard error (both noises over the number of repeats that
    # observed it), as a lab that repeats a test reports it.
    calls = [(dict(base_true), dict(effects), _repeat_seed(seed, k)) for k in range(repeats)]
    prefetch = getattr(sim, "prefetch", None)
    if prefetch is not None:  # a parallel simulator runs the repeated experiments side by side
        prefetch(calls)
    runs = [sim(*c) for c in calls]
    rng = np.random.default_rng([seed, 99])
    noisy, stated, seen_in = {}, {}, {}
    for m in design:
        vals = np.array([r[m.name] + m.uncertainty * rng.standard_normal(m.n_components)
                         for r in runs])
        seen = np.isfinite(vals).sum(axis=0)
        seen_in[m.name] = seen
        with np.errstate(invalid="ignore"):
            noisy[m.name] = np.where(seen > 0, np.nansum(vals, axis=0) / np.maximum(seen, 1), np.nan)
        stated[m.name] = np.sqrt((m.uncertainty ** 2 + intrinsic[m.name] ** 2) / np.maximum(seen, 1))
    twin = design.with_values(Observations(noisy, source="twin"),
                              uncertainty=Observations(stated), provenance="synthetic twin")
    # the file states its trials and those that gave no reading (e.g. no heap to fit, or
    # a heap that stood as a block): a reading in no trial is an outcome, not a value
    twin = replace(twin, measurements=tuple(
        replace(m, trials=int(repeats), not_measured=int(repeats) - seen_in[m.name])
        for m in twin.measurements))
    seen = tuple(m for m in twin.measurements if np.all(np.isfinite(m.values)))
    tried = tuple(m for m in twin.measurements if m.measured_in_no_trial)
    # a component read in no repeat beside components read in some: left out, as before
    lost = [m.name for m in twin.measurements
            if not np.all(np.isfinite(m.values)) and not m.measured_in_no_trial]
    if lost:
        log.info("twin %d: not observable in its run, left out of its file: %s", idx, lost)
    notes = [f"not observable in the twin's run: {', '.join(lost)}"] if lost else []
    if tried:
        notes.append(f"no reading in any of its {int(repeats)} repeat(s), stated as such: "
                     f"{', '.join(m.name for m in tried)}")
    twin = MeasurementSet(seen, title=f"twin {idx}", source="synthetic twin (withheld truth)",
                          notes="; ".join(notes), unmeasured=tried)
    path = write_measurements(twin, folder / f"twin_{idx:03d}.toml")
    # the file round trip checks the format; plausible ranges are for measured numbers
    return load_measurements(path, check_range=False)


def _twin_plan(effect_names, cfg: dict, *, in_turn: bool) -> list[tuple[str, str | None]]:
    """The twins to run, as ``(kind, effect)``.

    ``in_turn`` (engine twins, few and slow): the null twins first, then the effects in
    turn, so that a partial run, or any shard of it, covers every effect.
    """
    plan = [("effect", e) for e in effect_names for _ in range(cfg["per_effect"])]
    plan += [("null", None)] * cfg["null"]
    plan += [("out_of_catalogue", e) for e in effect_names for _ in range(cfg["out_of_catalogue"])]
    if in_turn:
        rank = {e: j for j, e in enumerate(effect_names)}
        turn, keyed = {}, []
        for k in plan:
            keyed.append(((k[0] != "null", turn.get(k, 0), rank.get(k[1], -1)), k))
            turn[k] = turn.get(k, 0) + 1
        plan = [k for _, k in sorted(keyed, key=lambda t: t[0])]
    return plan


def _twin_sigma(fps, intrinsic, repeats: int = 1) -> np.ndarray:
    """Per component, the noise of ``twin - mean(base runs)`` as the twin's diagnosis sees it.

    The twin's stated uncertainty (reading noise and one run's scatter, over the number of
    repeated experiments) combined with the base runs' mean, i.e.
    :attr:`FingerprintSet.sigma` with the twin's file in place of the design's uncertainties.
    """
    comp = fps.design.component_names()
    sd = np.zeros(len(comp))
    for name in fps.names:
        sd[comp == name] = np.asarray(intrinsic[name], dtype=float)
    n = np.maximum(np.sum(np.isfinite(fps.base_samples), axis=0), 1)
    return np.sqrt((fps.sigma_meas ** 2 + sd ** 2) / repeats + fps.sim_var / n)


def _projected_gap(fps, name: str, sigma=None, *, debias: bool = False):
    """``gap(a)``: the recalibration-projected gap of effect ``name`` at magnitude ``a``, in sigma.

    The norm, on the calibration observables, of the effect's change with the part
    recalibration absorbs projected out, in the noise ``sigma`` (per component, default
    :attr:`FingerprintSet.sigma`; a twin's is :func:`_twin_sigma`; a callable ``sigma(a)``
    gives the noise at each magnitude, as for a twin whose scatter depends on it).

    The fingerprint's predicted change carries its own estimation noise, which adds
    ``sum_i P_ii (se_i / sigma_i)**2`` to the expected squared norm (``se`` from
    :meth:`Fingerprint.predict_se`). With ``debias`` that is subtracted, so the gap is an
    unbiased estimate of the true effect's squared gap (its square root; 0 where the noise
    exceeds it); without it, the fingerprint's prediction as it is. Twins are sized
    without it and record both (``twin_gap_sigma``, ``twin_gap_debiased_sigma``): the
    debiased estimate is skewed, its median below the true gap (and zero where noise
    dominates), so twins sized on it carry more than drawn in a noisy fingerprint, where
    those sized on the prediction carry less; a validation errs on the weak side.
    """
    from ..identifiability import nuisance_projector
    from ..noise_correlation import correlation_matrix, inverse_cholesky, whiten
    cal = fps.rows_calibrate
    fp = fps[name]
    # in the metric the fit uses (components read from one run share their noise)
    R = correlation_matrix(fps, cal)
    W = None if R is None else inverse_cholesky(R)

    def gap(a):
        s = sigma(a) if callable(sigma) else (fps.sigma if sigma is None else sigma)
        sig = np.asarray(s, dtype=float)[cal]
        P = nuisance_projector(whiten(W, fps.sensitivities[cal] / sig[:, None]))
        g2 = float(np.sum((P @ whiten(W, fp.predict(a)[cal] / sig)) ** 2))
        if debias:
            d = fp.predict_se(a)[cal] / sig
            g2 -= float(np.diag(P) @ d ** 2 if W is None
                        else np.trace(P @ W @ (R * np.outer(d, d)) @ W.T))
        return math.sqrt(max(g2, 0.0))
    return gap


def _magnitude_for_snr(fps, name: str, snr: float, sigma=None, *, debias: bool = False) -> float:
    """Smallest magnitude whose recalibration-projected gap on the calibration observables is ``snr`` sigma.

    ``sigma`` and ``debias`` as in :func:`_projected_gap`. The first crossing on a grid
    over the prior range, refined by bisection; a response need not grow monotonically
    (ageing's gap falls again towards its prior top). When no magnitude in the prior
    range reaches ``snr``, the one with the largest gap (the twin is capped there).
    """
    norm = _projected_gap(fps, name, sigma, debias=debias)
    top = fps[name].effect.prior[1]
    grid = np.linspace(0.0, top, 65)
    gaps = np.array([norm(a) for a in grid])
    above = np.nonzero(gaps >= snr)[0]
    if not above.size:
        return float(grid[int(np.argmax(gaps))])
    lo, hi = grid[above[0] - 1], grid[above[0]]
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if norm(mid) < snr else (lo, mid)
    return 0.5 * (lo + hi)


def _size_twin(sim, fps, name: str, snr: float, sigma) -> tuple[float, object, dict]:
    """A twin's magnitude, sized on its effect's response simulated at that magnitude.

    The magnitude first solved on the fingerprint (:func:`_magnitude_for_snr`, with the
    response interpolated between its nodes) is simulated on the fingerprint's seeds
    (:func:`~bedstruct.diagnose.fingerprint_runs.simulate_node`), that response added as
    a node, and the magnitude solved once more: a twin carries the gap drawn for it even
    where the response is far from straight between the nodes. ``sigma(fps, a)`` gives the
    twin's noise at magnitude ``a``.

    Returns the magnitude, the fingerprint set with the node (for sizing the twin only:
    the diagnosis never sees it) and the record's fields on the node.
    """
    from dataclasses import replace

    from ..fingerprint_runs import simulate_node
    first = _magnitude_for_snr(fps, name, snr, lambda a: sigma(fps, a))
    # a long wait at the engine presets: say what it is for
    log.info("twin sizing: %s simulated at %.4g on %d seeds", name, first, len(fps.seeds))
    node = simulate_node(sim, fps, name, first)
    if node is None:
        return first, fps, {"twin_node_magnitude": None, "twin_node_gap_sigma": None}
    own = replace(fps, fingerprints=tuple(node if f.name == name else f for f in fps.fingerprints))
    gap_at_node = _projected_gap(own, name, lambda a: sigma(own, a))(first)
    magnitude = _magnitude_for_snr(own, name, snr, lambda a: sigma(own, a))
    return magnitude, own, {"twin_node_magnitude": first, "twin_node_gap_sigma": gap_at_node}


def _intrinsic_sd(fps, effect: str | None = None, magnitude: float | None = None) -> Observations:
    """Per-observable standard deviation of one simulator run at a twin's parameter point.

    The replicate scatter itself, not the upper confidence bound the diagnosis puts on it
    (:attr:`FingerprintSet.sim_var`): a twin's run scatters like any run at its point, and
    its file states that scatter as the standard deviation of repeated experiments would
    (:meth:`FingerprintSet.run_sd`; the base point's without an effect).
    """
    comp = fps.design.component_names()
    sd = fps.run_sd(effect, float(magnitude or 0.0))
    return Observations({n: sd[comp == n] for n in fps.names})
