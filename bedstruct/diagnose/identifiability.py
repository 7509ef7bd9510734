"""Identifiability: what the calibration observables can see of each effect's fingerprint.

For a :class:`~bedstruct.diagnose.fingerprints.FingerprintSet`, each effect's response at
the top of its prior is whitened, the part recalibrating the base parameters would absorb
is projected out (:func:`nuisance_projector`), and what is left is compared with the
selection threshold and the fingerprint's own estimation noise
(:func:`assess_fingerprints`); effects whose projected responses are nearly parallel are
reported as confounded, and a non-identifiable effect is given the measurements where it
shows most.

.. versionadded:: 0.1
"""

from __future__ import annotations

import warnings

import numpy as np

from .measurements import MeasurementSet
from .where import _nan_var

__all__ = ["nuisance_projector", "assess_fingerprints"]


def nuisance_projector(sensitivities_w) -> np.ndarray:
    """Orthogonal projector removing the span of whitened nuisance sensitivities.

    Parameters
    ----------
    sensitivities_w : (n, p) array_like
        Whitened sensitivities (columns); p may be 0.

    Returns
    -------
    (n, n) ndarray
        ``I - S (S^T S)^+ S^T``.

    Examples
    --------
    >>> P = nuisance_projector([[1.0], [0.0]])
    >>> P @ np.array([3.0, 4.0])
    array([0., 4.])
    """
    S = np.asarray(sensitivities_w, dtype=float)
    n = S.shape[0]
    if S.ndim != 2 or S.shape[1] == 0:
        return np.eye(n)
    Q, r, _ = np.linalg.svd(S, full_matrices=False)
    keep = r > 1e-12 * max(r.max(), 1e-300)
    Q = Q[:, keep]
    return np.eye(n) - Q @ Q.T


def _uneven_scatter(groups, points, design: MeasurementSet, p, aside) -> dict:
    """Components with points set aside from the pooled scatter, with the Bartlett p-value
    over all points, the per-point standard deviations and the points set aside."""
    sd = np.sqrt(np.array([_nan_var(g) for g in groups]))
    names, labels = design.component_names(), design.component_labels()
    single = {m.name: m.n_components == 1 for m in design}
    out = {}
    for i in np.flatnonzero(aside.any(axis=0)):
        key = str(names[i]) if single[str(names[i])] else f"{names[i]} {labels[i]}"
        col = sd[:, i]
        ok = np.isfinite(col)
        lo, hi = int(np.argmin(np.where(ok, col, np.inf))), int(np.argmax(np.where(ok, col, -np.inf)))
        out[key] = {"p_value": float(p[i]), "sd_base": float(col[0]),
                    "sd_min": float(col[lo]), "smallest_at": points[lo],
                    "sd_max": float(col[hi]), "largest_at": points[hi],
                    "set_aside": [points[k] for k in np.flatnonzero(aside[:, i])]}
    return out


def _correlated_scatter(groups, seeds, design: MeasurementSet, *, r_min: float = 0.9,
                        min_dof: int = 10) -> list[dict]:
    """Pairs of measured components whose run-to-run deviations move together.

    Each run's value less its parameter point's mean and its seed's mean (over the points
    run on that seed), so that what a seed shares across points (the same initial pile) is
    not taken for two readings of one run; a pair is listed when the correlation of these
    residuals reaches ``r_min`` over at least ``min_dof`` degrees of freedom
    (``(points - 1) (seeds - 1)`` over the runs that observed both). Such components are read
    from one run (the avalanche angle after rest is the static angle's heap when nothing
    ages) or one sample (PSD percentiles); the diagnosis treats them as independent and
    counts a common deviation about twice.

    Parameters
    ----------
    groups : sequence of (R_k, n) array_like
        Replicates of each parameter point.
    seeds : sequence of sequence of int
        The seed of each replicate, per point.
    design : MeasurementSet
        The ``n`` components' observables (candidates are skipped).

    Examples
    --------
    >>> from bedstruct.diagnose import MeasurementSet, measurement_from_dict
    >>> design = MeasurementSet(tuple(measurement_from_dict(dict(
    ...     name=n, kind="static_angle", value=0.0, uncertainty=1.0, role="calibrate"))
    ...     for n in ("a", "b", "c")))
    >>> rng = np.random.default_rng(0)
    >>> shared = rng.normal(size=(4, 3))        # what each seed gives every point
    >>> groups = []
    >>> for _ in range(6):
    ...     x = shared + rng.normal(size=(4, 3))
    ...     x[:, 1] = x[:, 0] + 0.01 * rng.normal(size=4)   # b read from a's run
    ...     groups.append(x)
    >>> [(p["components"], p["dof"]) for p in _correlated_scatter(groups, [range(4)] * 6, design)]
    [(['a', 'b'], 15)]
    """
    from .noise_correlation import component_keys
    keys = component_keys(design)   # the names the statistics look the pairs up by
    measured = np.flatnonzero(design.roles() != "candidate")
    seed_ids = sorted({int(s) for ss in seeds for s in ss})
    col = {s: c for c, s in enumerate(seed_ids)}
    n = len(keys)
    table = np.full((len(groups), len(seed_ids), n), np.nan)   # point x seed x component
    for k, (g, ss) in enumerate(zip(groups, seeds)):
        g = np.atleast_2d(np.asarray(g, float))
        for row, s in zip(g, ss):
            table[k, col[int(s)]] = row
    out = []
    for a_i, i in enumerate(measured):
        for j in measured[a_i + 1:]:
            both = np.isfinite(table[:, :, i]) & np.isfinite(table[:, :, j])
            # points and seeds with at least two runs observing both
            rows = both.sum(axis=1) >= 2
            cols = both.sum(axis=0) >= 2
            m = both & rows[:, None] & cols[None, :]
            n_p, n_s = int(rows.sum()), int(cols.sum())
            dof = int(m.sum()) - n_p - n_s + 1
            if dof < min_dof:
                continue
            res, flat = [], False
            for c in (i, j):
                x = np.where(m, table[:, :, c], np.nan)
                r = x - np.nanmean(x)
                total = float(np.nansum(r * r))
                for _ in range(10):  # two-way means by alternating (missing cells allowed)
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore", RuntimeWarning)  # all-missing rows
                        r = r - np.nan_to_num(np.nanmean(r, axis=1, keepdims=True))
                        r = r - np.nan_to_num(np.nanmean(r, axis=0, keepdims=True))
                res.append(r[m])
                # a component the seed alone decides (the PSD drawn before spreading) leaves
                # rounding noise, whose correlation means nothing
                flat |= float(res[-1] @ res[-1]) <= 1e-9 * total
            den = float(np.sqrt((res[0] @ res[0]) * (res[1] @ res[1])))
            if flat or den <= 0:
                continue
            r = float(res[0] @ res[1]) / den
            if abs(r) >= r_min:
                out.append({"components": [keys[i], keys[j]], "r": r, "dof": dof})
    return out


def assess_fingerprints(fps: FingerprintSet) -> FingerprintSet:
    """Identifiability, confounding and identifying measurements of every fingerprint.

    Judged on the calibration components of ``fps``, whitened by its combined noise,
    after projecting out the nuisance sensitivities; recomputed whenever the rows of
    the set change (:meth:`FingerprintSet.restrict`).
    """
    from dataclasses import replace
    from .noise_correlation import correlation_matrix, inverse_cholesky, whiten
    cal = fps.rows_calibrate
    sigma = fps.sigma
    # components read from one run: judged in the metric of the fit (generalised least squares)
    R = correlation_matrix(fps, cal)
    W = None if R is None else inverse_cholesky(R)
    P = nuisance_projector(whiten(W, fps.sensitivities[cal] / sigma[cal, None]))
    projected = [P @ whiten(W, f.delta[1][cal] / sigma[cal]) for f in fps.fingerprints]
    noncal = ~cal
    comp_names = fps.design.component_names()
    out = []
    for k, fp in enumerate(fps.fingerprints):
        D, SE = fp.delta, fp.delta_se
        f = projected[k]
        # signal and its estimation noise in the noise of a comparison with the fingerprint:
        # the experiment's and the fingerprint's own (a component whose response at the prior
        # top is known to no better than its scatter there carries no more than that)
        sig_c = np.sqrt(sigma[cal] ** 2 + SE[1][cal] ** 2)
        P_c = nuisance_projector(whiten(W, fps.sensitivities[cal] / sig_c[:, None]))
        f_c = P_c @ whiten(W, D[1][cal] / sig_c)
        signal = float(np.linalg.norm(f_c))
        d = SE[1][cal] / sig_c
        # the estimation noise's covariance in the whitened metric (its runs share the
        # components' correlation)
        C = None if W is None else W @ (R * np.outer(d, d)) @ W.T
        noise = float(np.sqrt(np.sum(d ** 2) if C is None else np.trace(C)))
        # the estimation noise along the signal's own direction: how far the signal
        # itself is known (the projector leaves that direction unchanged)
        u = f_c / signal if signal > 0 else f_c
        signal_se = float(np.sqrt(np.sum((u * d) ** 2) if C is None else u @ C @ u))
        single = 0.0
        if fp.delta_n is not None and signal > 0:
            one = fp.delta_n[1][cal] < 2
            single = float(np.sum(f_c[one] ** 2) / signal ** 2)
        identifiable = signal ** 2 > fps.threshold + noise ** 2
        conf = []
        for j, other in enumerate(projected):
            if j == k:
                continue
            den = np.linalg.norm(f) * np.linalg.norm(other)
            if den > 0 and abs(f @ other) / den > 0.98:
                conf.append(fps.fingerprints[j].name)
        ident = []
        if noncal.any():
            # what is left on the other rows once the base parameters are recalibrated on the
            # calibration rows, beyond 2 sigma and twice its own estimation noise (a noisy
            # fingerprint must not name a measurement by chance)
            J = fps.sensitivities
            beta = np.linalg.lstsq(whiten(W, J[cal] / sigma[cal, None]),
                                   whiten(W, D[1][cal] / sigma[cal]), rcond=None)[0]
            left = np.abs(D[1][noncal] - J[noncal] @ beta)
            w = left / sigma[noncal]
            real = left > 2.0 * SE[1][noncal]
            for i in np.argsort(-w):
                nm = str(comp_names[noncal][i])
                if w[i] > 2.0 and real[i] and nm not in ident:
                    ident.append(nm)
                if len(ident) == 3:
                    break
        out.append(replace(fp, signal=signal, noise=noise, signal_se=signal_se,
                           single_run_share=single,
                           identifiable=bool(identifiable),
                           confounded_with=tuple(conf), identify_with=tuple(ident)))
    return replace(fps, fingerprints=tuple(out))
