"""Which effect: fingerprint regression, model comparison and the 'unexplained' verdict.

The residual on the calibration observables, whitened by the combined noise (and by the
correlation of components read from one run, :mod:`bedstruct.diagnose.noise_correlation`), is
fitted by models ``r = sum_e delta_e(a_e) + S beta``: a subset of effects with
magnitudes ``a_e`` inside their prior ranges (bounded non-linear least squares on
the fingerprint responses) plus recalibration shifts ``beta`` of the nuisance
parameters within their physical bounds (:mod:`bedstruct.diagnose.parameters`); a value
that ends on a bound is listed in :attr:`ModelFit.at_bound`. The chosen model is the best subset of its size (lowest BIC),
the size chosen by significance: a single effect when it lowers the chi-square by
more than its Bonferroni threshold, a pair when it lowers every single's by more
than the next threshold. It must then fit within noise (combined chi-square and
largest-residual goodness-of-fit p-value >= ``gof_alpha``), otherwise the verdict is
``"unexplained"``. All single effects and pairs are fitted for the model-comparison
table (chi-square, p-value, AIC, BIC, BIC weight).

.. versionadded:: 0.1
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, stats

from .fingerprints import FingerprintSet, selection_threshold
from .noise_correlation import correlation_matrix, inverse_cholesky, whiten
from .profile_interval import profile_interval

__all__ = ["ModelFit", "EffectEstimate", "Attribution", "fit_model", "attribute"]

_Z95 = 1.959963984540054


@dataclass(frozen=True)
class ModelFit:
    """Fit of one candidate model (a set of effects plus recalibration).

    Attributes
    ----------
    effects : tuple of str
    magnitudes, stderr : (k,) ndarray
        Fitted magnitudes (effect units) and their standard errors.
    intervals : (k, 2) ndarray
        95 % confidence intervals: the normal approximation at the optimum, or for the
        chosen model of :func:`attribute` the profile of the chi-square
        (:func:`~bedstruct.diagnose.profile_interval.profile_interval`); see
        ``interval_kind``.
    nuisance : (p,) ndarray
        Recalibration shifts of the nuisance parameters (their units).
    nuisance_stderr : (p,) ndarray
        Their standard errors.
    stderr_runs, nuisance_stderr_runs : (k,), (p,) ndarray
        The part of those standard errors that comes from the noise of the runs the fit
        reads the data through (the base mean, the interpolated responses, the
        finite-difference points), not from the data's: a rerun at the fitted values departs
        from the data it was fitted to by that part (empty: not known).
    chi2 : float
        Whitened residual sum of squares on the fitted rows.
    dof : int
        Fitted rows less free parameters; a magnitude held at a bound of its prior is
        fixed there and counts neither here nor in the leverage of ``max_resid``.
    p_value : float
        Goodness of fit, ``P(chi2_dof > chi2)``.
    aic, bic : float
    max_resid, p_max : float
        Largest leverage-corrected residual (in sigma) and its Sidak p-value: a
        test against misfit concentrated in a few components.
    p_fit : float
        Combined goodness of fit, ``min(1, 2 min(p_value, p_max))`` (Bonferroni
        over the two tests); a model explains the gap when ``p_fit >= gof_alpha``.
    weight : float
        BIC weight among all fitted models.
    interval_kind : str
        ``"normal"`` or ``"profile"``: how ``intervals`` were made.
    at_bound : tuple of str
        Effects and recalibrated parameters whose fitted value sits on a bound (an effect's
        prior, a parameter's physical or configured bound): the data would take it further.
    """

    effects: tuple[str, ...]
    magnitudes: np.ndarray
    stderr: np.ndarray
    intervals: np.ndarray
    nuisance: np.ndarray
    chi2: float
    dof: int
    p_value: float
    aic: float
    bic: float
    nuisance_stderr: np.ndarray = field(default_factory=lambda: np.zeros(0))
    max_resid: float = float("nan")
    p_max: float = float("nan")
    p_fit: float = float("nan")
    weight: float = float("nan")
    stderr_runs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nuisance_stderr_runs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    interval_kind: str = "normal"
    at_bound: tuple[str, ...] = ()

    @property
    def label(self) -> str:
        return " + ".join(self.effects) if self.effects else "none (recalibration only)"

    def magnitude(self, name: str) -> float:
        return float(self.magnitudes[self.effects.index(name)])

    def as_dict(self) -> dict:
        return {"effects": list(self.effects), "magnitudes": self.magnitudes.tolist(),
                "intervals": self.intervals.tolist(), "interval_kind": self.interval_kind,
                "nuisance": self.nuisance.tolist(),
                "chi2": self.chi2, "dof": self.dof, "p_value": self.p_value,
                "max_resid": self.max_resid, "p_max": self.p_max, "p_fit": self.p_fit,
                "aic": self.aic, "bic": self.bic, "weight": self.weight,
                "at_bound": list(self.at_bound)}


@dataclass(frozen=True)
class EffectEstimate:
    """One effect's fitted magnitude, interval and evidence.

    ``interval_kind`` is that of the model it was read from (:attr:`ModelFit.interval_kind`):
    ``"profile"`` for the chosen model's effects, ``"normal"`` for the other candidates.
    """

    effect: str
    unit: str
    magnitude: float
    interval: tuple[float, float]
    scale: float
    scale_interval: tuple[float, float]
    delta_chi2: float
    p_value: float
    confidence: float
    identifiable: bool
    interval_kind: str = "normal"

    def as_dict(self) -> dict:
        return {"effect": self.effect, "magnitude": self.magnitude, "interval": list(self.interval),
                "interval_kind": self.interval_kind,
                "unit": self.unit, "scale": self.scale, "scale_interval": list(self.scale_interval),
                "delta_chi2": self.delta_chi2, "p_value": self.p_value,
                "confidence": self.confidence, "identifiable": self.identifiable}


@dataclass(frozen=True)
class Attribution:
    """Result of the attribution.

    Attributes
    ----------
    verdict : str
        ``"attributed"``, ``"unexplained"`` or ``"none"`` (no gap to explain).
    selected : tuple of EffectEstimate
        Effects of the chosen model, strongest first (empty unless attributed).
    ranking : tuple of EffectEstimate
        Every effect fitted alone, ranked by chi-square reduction.
    models : tuple of ModelFit
        Null, singles and pairs, ranked by BIC.
    null, best : ModelFit
        The recalibration-only model and the chosen model.
    threshold : float
        Chi-square reduction needed to select an effect.
    gof_alpha : float
        Minimum goodness-of-fit p-value of an acceptable model.
    reason : str
        One sentence explaining the verdict.
    partial : bool
        An attribution that explains most but not all of the gap: its rerun agrees with the
        calibration observables, and closes more than the diagnosis' ``partial_shrink`` of
        the held-out gap, but leaves the held-out observables inconsistent (see
        :func:`~bedstruct.diagnose.diagnose`).
    """

    verdict: str
    selected: tuple[EffectEstimate, ...]
    ranking: tuple[EffectEstimate, ...]
    models: tuple[ModelFit, ...]
    null: ModelFit
    best: ModelFit
    threshold: float
    gof_alpha: float
    reason: str
    partial: bool = False

    def which(self):
        """The ``which`` JSON field: selected effects, ``"unexplained"`` or ``[]``."""
        if self.verdict == "unexplained":
            return "unexplained"
        return [e.as_dict() for e in self.selected]


def _gram_pinv(J) -> np.ndarray:
    """``(J^T J)^+`` computed on unit-norm columns.

    The columns are on different scales (a magnitude of order 0.1 against a cohesion in
    J/m^3: 1e8 apart), and a pseudo-inverse of the raw Gram matrix cuts the small singular
    values relative to the largest, silently dropping the recalibration direction: its
    standard error came out ~1e-11 J/m^3 and the magnitudes' ignored their correlation with
    it. Scaling the columns first keeps what is determined and drops only true degeneracy.

    Examples
    --------
    >>> J = np.column_stack([[50.0, -20.0, 10.0], [1e-6, 2e-6, -1e-6]])
    >>> np.allclose(_gram_pinv(J), np.linalg.inv(J.T @ J))
    True
    """
    J = np.asarray(J, dtype=float)
    norm = np.linalg.norm(J, axis=0)
    d = np.where(norm > 0, 1.0 / np.where(norm > 0, norm, 1.0), 0.0)
    Js = J * d
    return d[:, None] * np.linalg.pinv(Js.T @ Js) * d[None, :]


def fit_model(residual, fps: FingerprintSet, effects, *, rows=None) -> ModelFit:
    """Fit ``residual`` on the given effects plus recalibration (bounded least squares).

    Parameters
    ----------
    residual : (n,) array_like
        ``real - mean(base runs)`` on all design rows (NaN allowed outside ``rows``).
    fps : FingerprintSet
    effects : sequence of str
    rows : (n,) bool array, optional
        Rows to fit; default the calibration rows.

    Returns
    -------
    ModelFit (``weight`` NaN; set by :func:`attribute`)
    """
    rows = fps.rows_calibrate if rows is None else rows
    sig = fps.sigma[rows]
    # components read from one run share their noise: generalised least squares
    R = correlation_matrix(fps, rows)
    W = None if R is None else inverse_cholesky(R)
    r = whiten(W, np.asarray(residual, dtype=float)[rows] / sig)
    S = whiten(W, fps.sensitivities[rows] / sig[:, None])
    fs = [fps[e] for e in effects]
    k, p = len(fs), S.shape[1]
    lo = np.array([f.effect.prior[0] for f in fs])
    hi = np.array([f.effect.prior[1] for f in fs])
    n = len(r)

    def fun(x):
        a, b = x[:k], x[k:]
        out = r - S @ b
        for f, ai in zip(fs, a):
            out = out - whiten(W, f.predict(ai)[rows] / sig)
        return out

    def jac(x):
        a = x[:k]
        Ja = (whiten(W, np.column_stack([-f.derivative(ai)[rows] / sig for f, ai in zip(fs, a)]))
              if k else np.zeros((n, 0)))
        return np.hstack([Ja, -S])

    # the recalibrated parameters stay within their physical bounds (a cohesion never
    # negative, a restitution never above one): the shifts are bounded like the magnitudes
    nlo, nhi = fps.shift_bounds() if p else (np.zeros(0), np.zeros(0))
    blo, bhi = np.concatenate([lo, nlo]), np.concatenate([hi, nhi])
    if k == 0:
        x, active = _bounded_linear(S, r, nlo, nhi) if p else (np.zeros(0), np.zeros(0, bool))
    else:
        def solve(bounds_lo, bounds_hi):
            best = None
            starts = [np.clip(np.zeros(k), lo, hi), 0.5 * (lo + hi), hi * 0.9 + lo * 0.1]
            for a0 in starts:
                x0 = np.clip(np.concatenate([a0, np.zeros(p)]), bounds_lo, bounds_hi)
                sol = optimize.least_squares(fun, x0, jac=jac, bounds=(bounds_lo, bounds_hi),
                                             method="trf", x_scale="jac")
                if best is None or sol.cost < best.cost:
                    best = sol
            return best
        # the shifts' bounds enter only where the fit would cross them (an inactive bound
        # changes no optimum, and the solver's path is then the unbounded one)
        best = solve(np.concatenate([lo, np.full(p, -np.inf)]),
                     np.concatenate([hi, np.full(p, np.inf)]))
        if np.any(best.x[k:] < nlo) or np.any(best.x[k:] > nhi):
            best = solve(blo, bhi)
        x = best.x
        active = best.active_mask != 0
    res = fun(x)
    chi2 = float(res @ res)
    J = jac(x)
    try:
        cov = _gram_pinv(J)
        G = cov @ J.T

        def through_fit(d_noise):
            """Variance a noise of (whitened) sd ``d_noise`` per row puts on the parameters."""
            if W is None:
                return np.einsum("ij,j,ij->i", G, d_noise ** 2, G)
            GW = G @ W   # the runs share the components' correlation too
            return np.einsum("ij,jk,ik->i", GW, R * np.outer(d_noise, d_noise), GW)

        var_x = np.clip(np.diag(cov), 0, None)
        # the interpolated response is itself an estimate from a few runs: its noise at
        # the fitted magnitudes (Fingerprint.predict_se) passes into the parameters
        # through the same normal equations (a steep response between two noisy nodes
        # otherwise gives an interval of a few thousandths)
        d_pred = [np.nan_to_num(f.predict_se(float(ai))[rows] / sig) for f, ai in zip(fs, x[:k])]
        for d in d_pred:
            var_x = var_x + through_fit(d)
        # the runs' share alone: the prediction at the fitted values is
        # (1 - k - sum beta) B + sum_e N_e + sum_j beta_j P_j in the means of the base (B),
        # the effects' nodes (N_e, at most one node's scatter where interpolated) and the
        # finite-difference points (P_j, beta_j = shift / step), each over the base seeds
        # and taken as independent, in one run's pooled scatter (not its upper bound)
        n_base = np.maximum(np.sum(np.isfinite(fps.base_samples), axis=0), 1)[rows]
        beta = np.array([float(bj) / fps.sensitivity_step(name)
                         for bj, name in zip(x[k:], fps.nuisance)])
        pooled = fps.run_sd()[rows] ** 2
        runs = ((1.0 - k - beta.sum()) ** 2 + np.sum(beta ** 2)) * pooled
        for f, ai in zip(fs, x[:k]):
            runs = runs + fps.run_sd(f.name, float(ai))[rows] ** 2
        var_runs = through_fit(np.nan_to_num(np.sqrt(runs / n_base) / sig))
        se = np.sqrt(var_x)
        se_runs = np.sqrt(np.clip(var_runs, 0, None))
    except np.linalg.LinAlgError:  # pragma: no cover
        se = se_runs = np.full(len(x), np.inf)
    a, b = x[:k], x[k:]
    sea = se[:k]
    # within the prior: a magnitude at its bound (or near it) has no support beyond it
    intervals = (np.column_stack([np.maximum(a - _Z95 * sea, lo), np.minimum(a + _Z95 * sea, hi)])
                 if k else np.zeros((0, 2)))
    # A magnitude or shift held at its bound is fixed there, not fitted: it neither uses a
    # degree of freedom nor lends leverage (the slope of a response at its last node can be
    # steep, and counting it would inflate the studentised residuals of the rows it drives).
    free = ~active
    dof = n - int(free.sum())
    pval = float(stats.chi2.sf(chi2, dof)) if dof > 0 else float("nan")
    # Concentrated misfit: largest studentised residual (leverage-corrected), Sidak over rows.
    if dof > 0:
        Jf = J[:, free]
        H = Jf @ _gram_pinv(Jf) @ Jf.T if Jf.shape[1] else np.zeros((n, n))
        lev = np.clip(1.0 - np.diag(H), 1e-12, None)
        tmax = float(np.max(np.abs(res) / np.sqrt(lev)))
        p1 = min(2.0 * stats.norm.sf(tmax), 1.0 - 1e-16)
        pmax = float(-np.expm1(n * np.log1p(-p1)))
        pfit = min(1.0, 2.0 * min(pval, pmax))
    else:
        tmax, pmax, pfit = float("nan"), float("nan"), float("nan")
    # the information criteria still count a magnitude held at its bound: the data put it
    # there, and counting it keeps a pinned model from winning the comparison for free
    npar = k + p
    at_bound = tuple(name for name, on in zip((*effects, *fps.nuisance), active) if on)
    return ModelFit(tuple(effects), a, sea, intervals, b, chi2, dof, pval,
                    chi2 + 2 * npar, chi2 + npar * math.log(max(n, 1)), nuisance_stderr=se[k:],
                    max_resid=tmax,
                    p_max=pmax, p_fit=pfit, stderr_runs=se_runs[:k],
                    nuisance_stderr_runs=se_runs[k:], at_bound=at_bound)


def _bounded_linear(S, r, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """``argmin |r - S b|`` with ``lo <= b <= hi``, and which ``b`` sit on a bound.

    The columns are scaled to unit norm first (a cohesion in J/m^3 against a friction).

    Examples
    --------
    >>> S = np.array([[1.0], [1.0]])
    >>> _bounded_linear(S, np.array([-3.0, -1.0]), np.array([-1.0]), np.array([np.inf]))
    (array([-1.]), array([ True]))
    """
    x = np.linalg.lstsq(S, r, rcond=None)[0]
    if np.all((x >= lo) & (x <= hi)):
        return x, np.zeros(len(x), bool)
    norm = np.linalg.norm(S, axis=0)
    d = np.where(norm > 0, 1.0 / np.where(norm > 0, norm, 1.0), 1.0)
    sol = optimize.lsq_linear(S * d, r, bounds=(lo / d, hi / d), method="bvls")
    return sol.x * d, sol.active_mask != 0


def attribute(residual, fps: FingerprintSet, *, alpha: float | None = None, gof_alpha: float = 0.01,
              max_effects: int = 2, rows=None) -> Attribution:
    """Attribute the calibration residual to catalogue effects, or say 'unexplained'.

    Parameters
    ----------
    residual : (n,) array_like
        ``real - mean(base runs)`` on the design rows.
    fps : FingerprintSet
    alpha : float, optional
        Family-wise level of the effect selection (default ``fps.alpha``).
    gof_alpha : float
        A model whose goodness-of-fit p-value is below this does not explain the gap.
    max_effects : int
        Largest combination considered (1 or 2).

    Returns
    -------
    Attribution
    """
    alpha = fps.alpha if alpha is None else alpha
    names = fps.effect_names
    threshold = selection_threshold(alpha, len(names))
    null = fit_model(residual, fps, (), rows=rows)
    singles = {e: fit_model(residual, fps, (e,), rows=rows) for e in names}
    pairs = {}
    if max_effects >= 2:
        for a, b in itertools.combinations(names, 2):
            pairs[(a, b)] = fit_model(residual, fps, (a, b), rows=rows)
    allm = [null, *singles.values(), *pairs.values()]
    bics = np.array([m.bic for m in allm])
    w = np.exp(-0.5 * (bics - bics.min()))
    w /= w.sum()
    allm = [ModelFit(**{**m.__dict__, "weight": float(wi)}) for m, wi in zip(allm, w)]
    null = allm[0]
    singles = {e: allm[1 + i] for i, e in enumerate(names)}
    pairs = {key: allm[1 + len(names) + i] for i, key in enumerate(pairs)}
    conf = {e: float(sum(m.weight for m in allm if e in m.effects)) for e in names}

    def estimate(e, fit):
        f = fps[e]
        i = fit.effects.index(e)
        mag = float(fit.magnitudes[i])
        lo, hi = (float(v) for v in fit.intervals[i])
        mref = f.magnitudes[1]
        dchi = null.chi2 - singles[e].chi2
        return EffectEstimate(e, f.effect.unit, mag, (lo, hi), mag / mref, (lo / mref, hi / mref),
                              float(dchi), float(stats.chi2.sf(max(dchi, 0.0), 1)), conf[e],
                              f.identifiable, fit.interval_kind)

    # best subset of each size, the size chosen by significance: of the singles that lower
    # the null's chi2 by more than chi2_1 at alpha / n_effects the best (lowest BIC; BIC
    # differs from chi2 within a size only where a magnitude held at a prior bound frees a
    # degree of freedom); of the pairs that lower every single's chi2 by more than chi2_1 at
    # alpha / (n_effects - 1) the best (each of its effects is then significant in it).
    # Forward selection tried only the pairs holding the best single: with capillary
    # bridges withheld from a small engine twin it named non-sphericity + ageing (BIC
    # weight 0.08) beside ageing + blade start-up (0.86), which fits better by chi2 4.9.
    current = null
    significant = [m for m in singles.values() if null.chi2 - m.chi2 > threshold]
    if max_effects >= 1 and significant:
        current = min(significant, key=lambda m: (m.bic, m.chi2))
        thr_pair = selection_threshold(alpha, len(names) - 1)
        lowest_single = min(m.chi2 for m in singles.values())
        significant = [m for m in pairs.values() if lowest_single - m.chi2 > thr_pair]
        if significant:
            current = min(significant, key=lambda m: (m.bic, m.chi2))
    chosen: tuple[str, ...] = current.effects
    chosen_fit = current
    gof_ok = (not math.isnan(current.p_fit)) and current.p_fit >= gof_alpha
    # an effect whose fingerprint is within its own estimation noise can absorb any gap of
    # similar shape (e.g. the numerics of another code): naming it would be confidently wrong
    weak = [e for e in chosen if not fps[e].identifiable]
    if chosen and gof_ok and not weak:
        # the magnitudes of a chosen model that fits (and is named) get intervals
        # from the profile of the chi-square (the other models keep the normal approximation: a
        # profile costs ~15 ms for one effect and ~0.1 s each with a partner)
        prof = [profile_interval(residual, fps, chosen, e, float(a), rows=rows).interval
                for e, a in zip(chosen, current.magnitudes)]
        current = ModelFit(**{**current.__dict__, "intervals": np.array(prof, dtype=float),
                              "interval_kind": "profile"})
        allm = [current if m is chosen_fit else m for m in allm]
        singles = {e: current if m is chosen_fit else m for e, m in singles.items()}
    ranking = tuple(sorted((estimate(e, singles[e]) for e in names), key=lambda x: -x.delta_chi2))

    models = tuple(sorted(allm, key=lambda m: m.bic))
    if chosen and gof_ok and weak:
        verdict = "unexplained"
        sel = ()
        reason = (f"best candidate {current.label} fits (chi2 {current.chi2:.1f} on {current.dof} "
                  f"dof) but {', '.join(weak)} is not identifiable with these observables (its "
                  "fingerprint is within its own noise), so the gap is not attributed to it; "
                  "see the measurements that would identify it")
    elif chosen and gof_ok:
        verdict = "attributed"
        sel = tuple(sorted((estimate(e, current) for e in chosen), key=lambda x: -x.delta_chi2))
        reason = (f"{current.label} lowers chi2 from {null.chi2:.1f} to {current.chi2:.1f} "
                  f"(dof {current.dof}, goodness-of-fit p = {current.p_fit:.3g})")
    elif chosen:
        verdict = "unexplained"
        sel = ()
        reason = (f"best candidate {current.label} leaves chi2 = {current.chi2:.1f} on {current.dof} "
                  f"dof, largest residual {current.max_resid:.1f} sigma (p = {current.p_fit:.2g} < "
                  f"{gof_alpha}): no catalogue effect fits within noise")
    elif null.p_fit >= gof_alpha or math.isnan(null.p_fit):
        verdict = "none"
        sel = ()
        reason = (f"recalibration alone fits the calibration observables (chi2 = {null.chi2:.1f}, "
                  f"dof {null.dof}, p = {null.p_fit:.3g}) and no effect is significant")
    else:
        verdict = "unexplained"
        sel = ()
        reason = (f"gap on calibration observables (chi2 = {null.chi2:.1f}, dof {null.dof}, "
                  f"p = {null.p_fit:.2g}) but no effect lowers it significantly")
    pinned = (current if chosen else null).at_bound
    if pinned:
        # a value on its bound is where the data would go past a physical limit: say so
        reason += (f"; the fit ends on a bound of {', '.join(pinned)} (the data would take "
                   f"{'it' if len(pinned) == 1 else 'them'} past it)")
    return Attribution(verdict, sel, ranking, models, null, current, threshold, gof_alpha, reason)
