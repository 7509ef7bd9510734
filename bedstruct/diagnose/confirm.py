"""How far: rerun the attributed model, confirm it, and measure the gap it closes.

The attribution predicts an extended model by interpolating each effect's fingerprint
between the magnitudes it was simulated at. :func:`confirm_attribution` simulates the
chosen model at its fitted magnitudes (fresh seeds) and asks the calibration and the
held-out observables whether that simulation agrees with the data. Where the rerun
contradicts the fit on the calibration observables, one of the fit's two predictions was
wrong, and the one that can be re-simulated is: a recalibration shift beyond its
finite-difference step (the base is simulated at that shift, on the base runs' seeds), or,
for a single effect, the interpolation between the fingerprint's magnitudes (the rerun is
itself a simulation at the fitted magnitude and becomes a node). The model is refitted and
simulated again: a Gauss-Newton step with the simulator in the loop, paid for only when the
fit was wrong. :class:`Shrink` holds the gap on the held-out observables before and after.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .attribution import Attribution, attribute
from .fingerprints import FingerprintSet
from .replicates import Simulator, simulate_replicates
from .noise_correlation import correlation_among, correlation_matrix, quadratic_form
from .where import _nan_mean, standardised_residuals

__all__ = ["gap_size", "shrink_interval", "Shrink", "Confirmation", "confirm_attribution", "p_fit_z",
           "component_gaps"]

#: Seeds of the k-th rerun are ``seed + RERUN_SEED_STRIDE * (k + 1) + i``: fresh for every
#: rerun, so a refit through one rerun is checked on runs it has not seen.
RERUN_SEED_STRIDE = 1000


def gap_size(z, correlation=None) -> tuple[float, float]:
    """RMS of standardised residuals and the *excess* gap beyond noise.

    Parameters
    ----------
    z : (n,) array_like
        Standardised residuals (NaN: not observed, left out).
    correlation : (n, n) array_like, optional
        Correlation of their noise (:func:`~bedstruct.diagnose.noise_correlation.correlation_matrix`);
        the mean square is then ``z^T R^{-1} z / n``, so that a deviation read twice from
        one run counts about once.

    Returns
    -------
    rms, excess : float
        ``sqrt(mean z^2)`` and ``sqrt(max(mean z^2 - 1, 0))``; the excess is 0
        when the residuals are as large as the noise explains.

    Examples
    --------
    >>> gap_size([3.0, 1.0, 1.0, 1.0])
    (1.7320508075688772, 1.4142135623730951)
    """
    z = np.asarray(z, dtype=float)
    if correlation is None:
        z = z[np.isfinite(z)]  # a component no rerun could observe carries no evidence
        if z.size == 0:
            return float("nan"), float("nan")
        ms = float(np.mean(z * z))
    else:
        q, n = quadratic_form(z, correlation)
        if n == 0:
            return float("nan"), float("nan")
        ms = q / n
    return math.sqrt(ms), math.sqrt(max(ms - 1.0, 0.0))


def shrink_interval(z_before, z_after, correlation=None, *, level: float = 0.9,
                    n_draws: int = 2000, seed: int = 0) -> tuple[float, float]:
    """Interval of the held-out gap's shrink ``1 - excess after / excess before``.

    A parametric bootstrap: each component's true deviation before and after is taken as
    its standardised residual scaled to the excess gap (so that the draws' mean excess is
    the observed one), a noise of unit variance (correlated as ``correlation``) is added,
    the same draw before and after (the measured values are the same), and the shrink is
    computed again. The interval holds the central ``level`` of the draws.

    Parameters
    ----------
    z_before, z_after : (n,) array_like
        Standardised residuals of the held-out components before and after (NaN: left out).
    correlation : (n, n) array_like, optional
        Correlation of their noise.
    level : float
        Coverage of the interval.
    n_draws : int
        Bootstrap draws.
    seed : int
        Seed of the draws (the interval is reproducible).

    Returns
    -------
    (float, float)
        Lower and upper end (dimensionless fraction; NaN when there is no gap before).

    Examples
    --------
    >>> lo, hi = shrink_interval([4.0, -3.0, 5.0], [0.5, -0.2, 1.0])
    >>> 0.5 < lo < 1.0 and hi == 1.0
    True
    >>> shrink_interval([0.5, -0.3], [0.1, 0.2])
    (nan, nan)
    """
    zb, za = np.asarray(z_before, float), np.asarray(z_after, float)
    ok = np.isfinite(zb) & np.isfinite(za)
    zb, za = zb[ok], za[ok]
    R = None if correlation is None else np.asarray(correlation, float)[np.ix_(ok, ok)]
    rms_b, exc_b = gap_size(zb, R)
    rms_a, exc_a = gap_size(za, R)
    if not (zb.size and exc_b > 0):
        return float("nan"), float("nan")
    mu_b = zb * (exc_b / rms_b)
    mu_a = za * (exc_a / rms_a) if rms_a > 0 else np.zeros_like(za)
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((n_draws, zb.size))
    if R is not None:
        noise = noise @ np.linalg.cholesky(R).T
    fracs = []
    for e in noise:
        b = gap_size(mu_b + e, R)[1]
        if b > 0:
            fracs.append(1.0 - gap_size(mu_a + e, R)[1] / b)
    if not fracs:
        return float("nan"), float("nan")
    q = (1.0 - level) / 2.0
    lo, hi = np.quantile(fracs, [q, 1.0 - q])
    return float(lo), float(hi)


@dataclass(frozen=True)
class Shrink:
    """Gap on the held-out observables before and after adding the attributed effect.

    ``before``: the base model; ``recalibrated``: the base with the nuisance
    parameters refitted on calibration observables only; ``after``: recalibrated
    plus the attributed effect(s) at their fitted magnitudes (calibration-only fit).
    Gaps are RMS standardised residuals; ``*_excess`` is the part beyond noise.
    ``fraction`` = 1 - after_excess / before_excess (NaN without a gap), and
    ``fraction_interval`` its 90 % interval (:func:`shrink_interval`).
    ``p_rerun_calibration`` / ``p_rerun_heldout``: goodness of fit (chi-square and
    largest-|z|, Bonferroni) of the rerun of the attributed model to the calibration and
    to the held-out observables (NaN without an attribution): the checks that confirm it.
    ``refits``: earlier reruns whose calibration check failed and after which the model was
    refitted (model, magnitudes, their p-values, seeds, and what was re-simulated:
    ``recalibration`` or ``node``), oldest first. ``p_before``: chi-square p-value of the
    held-out gap before (``n_heldout`` components, the observed ones): at or above a test's
    level there is no held-out gap beyond noise, and ``fraction`` measures noise.
    ``rerun_worst``: the components on which the final rerun (of the attributed model, or of
    the recalibrated base) departs most from the data, largest ``|z|`` first (observable,
    component label, role, ``z``): where a failed check comes from.
    ``p_rerun_trials``: the file's trials without a reading against the final model's runs
    (:func:`~bedstruct.diagnose.trial_counts.trial_check`; 1 when nothing could be tested,
    NaN when the file states no trials); ``trial_rows``: its observables, smallest p first.
    ``components``: measured against simulated per measured component, before and after
    (:func:`component_gaps`).
    """

    model: str
    magnitudes: dict
    nuisance: dict
    before: float
    recalibrated: float
    after: float
    before_excess: float
    recalibrated_excess: float
    after_excess: float
    fraction: float
    fraction_rms: float
    per_observable: tuple[dict, ...]
    n_heldout: int
    p_rerun_calibration: float = float("nan")
    p_rerun_heldout: float = float("nan")
    refits: tuple[dict, ...] = ()
    p_before: float = float("nan")
    rerun_worst: tuple[dict, ...] = ()
    p_rerun_trials: float = float("nan")
    trial_rows: tuple[dict, ...] = ()
    fraction_interval: tuple[float, float] = (float("nan"), float("nan"))
    components: tuple[dict, ...] = ()

    def as_dict(self) -> dict:
        return {"model": self.model, "magnitudes": self.magnitudes, "nuisance": self.nuisance,
                "before": self.before, "recalibrated": self.recalibrated, "after": self.after,
                "before_excess": self.before_excess, "recalibrated_excess": self.recalibrated_excess,
                "after_excess": self.after_excess, "fraction": self.fraction,
                "fraction_interval": list(self.fraction_interval),
                "fraction_rms": self.fraction_rms, "n_heldout": self.n_heldout,
                "p_rerun_calibration": self.p_rerun_calibration,
                "p_rerun_heldout": self.p_rerun_heldout, "refits": list(self.refits),
                "p_before": self.p_before,
                "p_rerun_trials": self.p_rerun_trials, "trial_rows": list(self.trial_rows),
                "per_observable": list(self.per_observable),
                "rerun_worst": list(self.rerun_worst), "components": list(self.components)}


def _mean_and_sd(samples, run_var) -> tuple[np.ndarray, np.ndarray]:
    """Mean of replicate runs per component and its standard deviation (run scatter / sqrt R)."""
    s = np.atleast_2d(np.asarray(samples, float))
    n = np.sum(np.isfinite(s), axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, np.nansum(np.where(np.isfinite(s), s, 0.0), axis=0) / np.maximum(n, 1),
                        np.nan)
        sd = np.where(n > 0, np.sqrt(np.asarray(run_var, float) / np.maximum(n, 1)), np.nan)
    return mean, sd


def component_gaps(residuals, sigma_meas, before, after=None, *, run_var) -> tuple[dict, ...]:
    """Measured against simulated per component, before and after adding the effect.

    Parameters
    ----------
    residuals : Residuals
        The measured components (:attr:`~bedstruct.diagnose.where.WhereResult.residuals`):
        names, labels, kinds, roles, units, measured values and the base model's mean.
    sigma_meas : (n,) array_like
        Measurement uncertainty per component (its unit).
    before : (R, n) array_like
        Runs of the recalibrated base model.
    after : (R, n) array_like, optional
        Runs of the recalibrated model with the effect(s) added (None: none was rerun).
    run_var : (n,) array_like
        Run-to-run variance of one run per component (pooled).

    Returns
    -------
    tuple of dict
        One per component, in row order: ``observable``, ``component``, ``kind``, ``role``,
        ``unit``, ``measured``, ``sigma`` (measurement), ``base`` (mean of the base runs),
        ``before`` and ``before_sd`` (mean of the recalibrated runs and its standard
        deviation from run scatter), ``after`` and ``after_sd`` (NaN without ``after``);
        values in the component's SI unit.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.diagnose import MeasurementSet, measurement_from_dict, where
    >>> m = measurement_from_dict({"name": "aor", "kind": "static_angle", "value": 33.0,
    ...                            "uncertainty": 0.5})
    >>> w = where(MeasurementSet((m,)), np.array([[30.0], [30.4]]))
    >>> row, = component_gaps(w.residuals, [0.5], [[31.0], [31.2]], [[32.9], [33.1]],
    ...                       run_var=[0.04])
    >>> row["before"], row["after"], round(row["after_sd"], 3)
    (31.1, 33.0, 0.141)
    """
    r = residuals
    b_mean, b_sd = _mean_and_sd(before, run_var)
    if after is None:
        a_mean = a_sd = np.full(len(b_mean), np.nan)
    else:
        a_mean, a_sd = _mean_and_sd(after, run_var)
    sm = np.asarray(sigma_meas, float)
    return tuple({"observable": str(r.names[i]), "component": str(r.labels[i]),
                  "kind": str(r.kinds[i]), "role": str(r.roles[i]), "unit": str(r.units[i]),
                  "measured": float(r.real[i]), "sigma": float(sm[i]),
                  "base": float(r.sim_mean[i]),
                  "before": float(b_mean[i]), "before_sd": float(b_sd[i]),
                  "after": float(a_mean[i]), "after_sd": float(a_sd[i])}
                 for i in range(len(sm)))




def params_after(base, nuisance_names, shifts):
    """Base parameters with the nuisance shifts of a fit added."""
    p = dict(base)
    for name, b in zip(nuisance_names, shifts):
        p[name] = p[name] + float(b)
    return p




def p_fit_z(z, correlation=None) -> float:
    """Combined (chi-square and largest-|z|, Bonferroni) p-value of standardised residuals.

    Components that are not finite (no rerun observed them) carry no evidence. With the
    noise's ``correlation`` (as in :func:`gap_size`) the chi-square is ``z^T R^{-1} z``;
    the largest-|z| test stays on the marginal residuals (Sidak is conservative under
    positive correlation).

    Examples
    --------
    >>> round(p_fit_z([0.0, 0.0, 0.0]), 3)
    1.0
    >>> p_fit_z([6.0, 0.0, 0.0]) < 1e-6
    True
    """
    from scipy import stats
    q, n = quadratic_form(z, correlation)
    z = np.asarray(z, dtype=float)
    z = z[np.isfinite(z)]  # components no rerun observed
    if n == 0:
        return 1.0
    p_chi = float(stats.chi2.sf(q, n))
    p1 = min(2.0 * stats.norm.sf(float(np.max(np.abs(z)))), 1.0 - 1e-16)
    p_max = float(-np.expm1(n * np.log1p(-p1)))
    return min(1.0, 2.0 * min(p_chi, p_max))




def _or_zero(values, j: int) -> float:
    """``values[j]``, or 0 where a fit does not state it (a fit without run noise)."""
    return float(values[j]) if len(values) > j and np.isfinite(values[j]) else 0.0


@dataclass(frozen=True)
class Confirmation:
    """What :func:`confirm_attribution` found.

    Attributes
    ----------
    attribution : Attribution
        The attribution after any refit through a rerun (its verdict is not yet
        changed by the checks; :func:`~bedstruct.diagnose.diagnose` does that).
    fingerprints : FingerprintSet
        The fingerprints with the reruns used as nodes.
    samples : (R, m) ndarray or None
        The last rerun of the attributed model (measured components), None when the
        final attribution attributes nothing.
    z_after, z_check : (m,) ndarray or None
        Standardised residuals of the data against that rerun; ``z_check``, which the
        checks test, adds the variance the fit's uncertainty puts on the prediction: on
        the calibration observables only the part from the runs' noise
        (:attr:`~bedstruct.diagnose.attribution.ModelFit.stderr_runs`), on the held-out
        ones all of it.
    p_calibration, p_heldout : float
        Goodness of fit of that rerun to the calibration and the held-out observables
        (NaN without an attribution or without such observables).
    refits : tuple of dict
        Reruns that failed the calibration check, oldest first, each with what was then
        re-simulated: ``"recalibration"`` (the base at the fitted shifts) or ``"node"``
        (the rerun itself, as the effect's fingerprint node).
    n_runs : int
        Simulator runs made.
    extra_samples : (R, q) ndarray or None
        The last rerun's components of ``extra_names`` (observables the checks do not
        fit, such as those a file read in no trial; the trial check counts their runs
        without a reading).
    rerun_seeds : tuple of int
        The seeds of the last rerun.
    """

    attribution: Attribution
    fingerprints: FingerprintSet
    samples: np.ndarray | None
    z_after: np.ndarray | None
    z_check: np.ndarray | None
    p_calibration: float
    p_heldout: float
    refits: tuple[dict, ...]
    n_runs: int
    extra_samples: np.ndarray | None = None
    rerun_seeds: tuple[int, ...] = ()


def _bridge_variance(simulator, mags, names, design) -> np.ndarray:
    """Variance of an engine bridge's effect correction at magnitudes ``mags`` over the
    components of ``names`` (zero without a bridge with probes,
    :meth:`~bedstruct.diagnose.bridge.EngineBridge.correction`)."""
    n_comp = [design[n].n_components for n in names]
    bridge = getattr(simulator, "bridge", None)
    if bridge is None or not mags:
        return np.zeros(int(sum(n_comp)))
    _, sd = bridge.correction(mags)
    return np.concatenate([np.asarray(sd[n], float) ** 2 if n in sd else np.zeros(k)
                           for n, k in zip(names, n_comp)])


def confirm_attribution(att: Attribution, fps: FingerprintSet, residual, simulator: Simulator, *,
                        y, sigma_meas, names, seed: int = 0, rounds: int = 2,
                        alpha: float = 0.01, max_effects: int = 2,
                        progress=None, extra_names=()) -> Confirmation:
    """Rerun the attributed model at its fitted magnitudes and check it against the data.

    Parameters
    ----------
    att : Attribution
        The attribution to confirm (nothing is run unless its verdict is ``"attributed"``).
    fps : FingerprintSet
        The fingerprints it was fitted with; the measured rows are ``~fps.rows_candidate``.
    residual : (n,) ndarray
        Data minus base mean on every fingerprint row (NaN on candidate rows).
    simulator : callable
        ``simulator(base, effects, seed) -> Observations``.
    y, sigma_meas : (m,) ndarray
        Measured values and their uncertainties, measured rows in order.
    names : sequence of str
        Measured observable names in row order.
    seed : int
        The diagnosis' first seed; the k-th rerun uses
        ``seed + RERUN_SEED_STRIDE * (k + 1) + i``.
    rounds : int
        Largest number of refits through a rerun (0: rerun once and report).
    alpha, max_effects : float, int
        Selection level and largest combination, as for :func:`attribute`.
    progress : tqdm-like, optional
        Its ``update(n)`` is called after every ``n`` simulator runs.
    extra_names : sequence of str
        Further observables the reruns are to give (:attr:`Confirmation.extra_samples`).

    Returns
    -------
    Confirmation

    Notes
    -----
    A refit happens only when the rerun fails the calibration check. Two predictions of
    the fit may have been wrong. When the fitted recalibration shift of a nuisance
    parameter exceeds its finite-difference step, its linear sensitivities were
    extrapolated: the base is simulated at that shift on the base runs' seeds and each
    sensitivity becomes the least-squares line through the origin and both paired points
    (the refit). Otherwise, for a *single* effect, the interpolated fingerprint
    was wrong at the fitted magnitude, and the rerun, corrected to the base nuisance with
    the linear sensitivities the fit uses, is the effect's response there: it becomes a
    node. A pair's rerun cannot be split between its two effects, and a rerun that fails
    only on the held-out observables says nothing the calibration fit could use; both end
    the loop. So does a fitted magnitude within 5 % of the top simulated magnitude from an
    existing node: the rerun there was the check.
    """
    rows_meas = ~fps.rows_candidate
    y = np.asarray(y, float)
    sigma_meas = np.asarray(sigma_meas, float)
    cal = fps.rows_calibrate[rows_meas]
    held = fps.rows_validate[rows_meas]
    var_meas = fps.sim_var[rows_meas]
    corr = correlation_matrix(fps, rows_meas)   # components read from one run

    def z_of(samples, extra_var=None, run_var=None):
        s = sigma_meas if extra_var is None else np.sqrt(sigma_meas ** 2 + extra_var)
        v = var_meas if run_var is None else np.maximum(var_meas, run_var)
        return standardised_residuals(y, s, samples, sim_var=v)[0]

    refits, n_runs, secants = [], 0, {}
    measured_names = set(names)
    extra_names = [n for n in extra_names if n not in measured_names]
    n_cols = int(np.sum(rows_meas))
    extra = None
    seeds: list[int] = []
    samples = z_after = z_check = None
    p_cal = p_held = float("nan")
    for k in range(max(int(rounds), 0) + 1):
        samples = z_after = z_check = None
        p_cal = p_held = float("nan")
        if att.verdict != "attributed":
            break
        model = att.best
        seeds = [int(seed) + RERUN_SEED_STRIDE * (k + 1) + i for i in range(fps.n_replicates)]
        mags = {e: float(a) for e, a in zip(model.effects, model.magnitudes)}
        params = params_after(fps.base, fps.nuisance, model.nuisance)
        samples = simulate_replicates(simulator, params, mags, seeds, list(names) + extra_names)
        samples, extra = samples[:, :n_cols], samples[:, n_cols:]
        n_runs += len(seeds)
        if progress is not None:
            progress.update(len(seeds))
        # the rerun's mean scatters as runs do at the model's magnitudes: more than the
        # pooled scatter where the fingerprint's later nodes or this rerun showed it
        local = np.max([fps.run_sd(e, a) ** 2 for e, a in mags.items()], axis=0) \
            if mags else fps.sim_var
        local = np.maximum(local, fps.node_run_var(samples, rows=rows_meas))[rows_meas]
        z_after = z_of(samples, run_var=local)
        # Both checks add the variance that the uncertainty of the fitted magnitudes and
        # shifts puts on the prediction. On the held-out observables it is the fit's whole
        # uncertainty. On the calibration observables the data's own noise cancels from it
        # (the values were fitted to these data), but the noise of the runs the fit read
        # them through does not: without it a true model with a noisy prediction would
        # fail the check more often than its level.
        pred_var = np.zeros(len(fps.sigma))
        runs_var = np.zeros(len(fps.sigma))
        for j, (e, a_e) in enumerate(zip(model.effects, model.magnitudes)):
            slope = fps[e].derivative(float(a_e))
            pred_var += (slope * model.stderr[j]) ** 2
            runs_var += (slope * _or_zero(model.stderr_runs, j)) ** 2
        for j, se_b in enumerate(model.nuisance_stderr):
            pred_var += (fps.sensitivities[:, j] * se_b) ** 2
            runs_var += (fps.sensitivities[:, j] * _or_zero(model.nuisance_stderr_runs, j)) ** 2
        # an engine bridge's correction of the effects' responses is uncertain as a whole
        # (one probe for every run), not run by run
        bridge_var = _bridge_variance(simulator, mags, names, fps.design)
        z_check = np.where(cal, z_of(samples, runs_var[rows_meas] + bridge_var, run_var=local),
                           z_of(samples, pred_var[rows_meas] + bridge_var, run_var=local))
        p_cal = p_fit_z(z_check[cal], correlation_among(corr, cal)) if cal.any() else float("nan")
        p_held = p_fit_z(z_check[held], correlation_among(corr, held)) if held.any() else float("nan")
        if not p_cal < att.gof_alpha or k == rounds:
            break
        record = {"model": model.label, "magnitudes": mags, "p_fit": float(model.p_fit),
                  "p_rerun_calibration": p_cal, "p_rerun_heldout": p_held, "seeds": list(seeds)}
        # The recalibration first: a shift beyond the finite-difference step extrapolates the
        # linear sensitivities, and their error would otherwise pass into an effect's node.
        far = [j for j, name in enumerate(fps.nuisance)
               if name not in secants and abs(model.nuisance[j]) > fps.sensitivity_step(name)]
        if far:
            sens = fps.sensitivities.copy()
            for j in far:
                name, shift = fps.nuisance[j], float(model.nuisance[j])
                h = fps.sensitivity_step(name)
                point = dict(fps.base, **{name: fps.base[name] + shift})
                # on the base runs' seeds, paired like the finite difference itself
                s_b = simulate_replicates(simulator, point, {}, fps.seeds, fps.names)
                n_runs += len(fps.seeds)
                if progress is not None:
                    progress.update(len(fps.seeds))
                d_shift = _nan_mean(s_b - fps.base_samples)
                d_step = sens[:, j] * h
                ok = np.isfinite(d_shift)
                # least-squares line through the origin and both paired points
                sens[ok, j] = (h * d_step[ok] + shift * d_shift[ok]) / (h * h + shift * shift)
                secants[name] = shift
            moved = (sens - fps.sensitivities) @ np.asarray(model.nuisance, float)
            fps = replace(fps, sensitivities=sens)
            # Only an error the noise could not hide explains the failed rerun; a linear
            # response re-simulated is the same, and the effect's node is tried next.
            if np.nanmax(np.abs(moved[fps.rows_calibrate]) / fps.sigma[fps.rows_calibrate]) > 0.5:
                record["recalibration"] = {fps.nuisance[j]: float(model.nuisance[j]) for j in far}
                refits.append(record)
                att = attribute(residual, fps, alpha=alpha, gof_alpha=att.gof_alpha,
                                max_effects=max_effects)
                continue
        if len(model.effects) != 1:
            break
        effect, a = model.effects[0], float(model.magnitudes[0])
        fp = fps[effect]
        if np.min(np.abs(fp.nodes - a)) < 0.05 * abs(fp.magnitudes[1]):
            break
        shift = fps.sensitivities[rows_meas] @ np.asarray(model.nuisance, float) \
            if len(model.nuisance) else 0.0
        response = np.full(len(fps.sigma), np.nan)  # unmeasured: the interpolation stays
        response[rows_meas] = _nan_mean(samples) - fps.base_mean[rows_meas] - shift
        record["node"] = {effect: a}
        refits.append(record)
        run_var, se = fps.node_scatter(samples, rows=rows_meas)
        fps = replace(fps, fingerprints=tuple(f.with_node(a, response, run_var=run_var, se=se)
                                              if f.name == effect else f for f in fps.fingerprints))
        att = attribute(residual, fps, alpha=alpha, gof_alpha=att.gof_alpha, max_effects=max_effects)
    return Confirmation(att, fps, samples, z_after, z_check, p_cal, p_held, tuple(refits), n_runs,
                        extra if samples is not None and extra_names else None,
                        tuple(seeds) if samples is not None else ())
