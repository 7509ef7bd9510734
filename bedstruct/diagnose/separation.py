"""Which catalogue effects a measurement design tells apart.

Identifiability (:func:`bedstruct.diagnose.identifiability.assess_fingerprints`) asks whether
an effect's gap stands out of the noise; attribution also needs it to stand out of the
*other* effects' fingerprints. Two effects whose fingerprints point in similar directions
(for example contact ageing and non-sphericity, which both steepen a static angle) are told
apart only once the gap is large enough that the best imitation by the other effect leaves
a residual beyond the selection threshold. :func:`separation` gives, for every pair, how much
of an effect's fingerprint the other cannot imitate, and the gap from which on the two are
told apart.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math

import numpy as np

from .fingerprints import FingerprintSet
from .identifiability import nuisance_projector

__all__ = ["nearest_imitations", "not_told_apart", "separation"]

_GRID = 81  # magnitudes along the imitating effect's prior


def separation(fps: FingerprintSet) -> list[dict]:
    """How well the calibration observables tell each pair of effects apart.

    For effect A at the top of its prior and every other effect B, the whitened,
    recalibration-projected change of the calibration observables of A is compared with
    the closest change that B produces at any magnitude within its prior (a fine grid).

    Parameters
    ----------
    fps : FingerprintSet
        Fingerprints (identifiability already assessed).

    Returns
    -------
    list of dict
        One row per ordered pair (A, B), A's rows sorted by ``unique_fraction``:
        ``effect`` (A), ``other`` (B), ``signal_sigma`` (A's projected norm at its prior
        top), ``residual_sigma`` (distance from A to B's closest imitation, sigma),
        ``unique_fraction`` (the ratio of the two: 1 for orthogonal fingerprints, 0 for an
        imitation that is perfect), ``gap_to_separate_sigma`` (the gap of A at which B's
        best imitation is worse by the selection threshold, ``sqrt(threshold) /
        unique_fraction``, assuming the shape at the prior top; ``inf`` when B imitates A
        perfectly) and ``separable`` (whether A reaches that gap within its prior).

    Examples
    --------
    >>> from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue,
    ...                                 compute_fingerprints, diagnosis_design, twin_design)
    >>> effects = catalogue()
    >>> design = diagnosis_design(twin_design(), effects)
    >>> fps = compute_fingerprints(SurrogateSimulator(design), design, BASE_PARAMETERS, effects,
    ...                            replicates=2)
    >>> rows = separation(fps)
    >>> hardest = min(rows, key=lambda r: r["unique_fraction"])
    >>> hardest["effect"], hardest["other"], round(hardest["unique_fraction"], 2)
    ('non_sphericity', 'capillary_bridges', 0.82)
    >>> all(r["separable"] for r in rows)
    True
    """
    from .noise_correlation import decorrelator, whiten
    cal = fps.rows_calibrate
    sigma = fps.sigma[cal]
    W = decorrelator(fps, cal)   # the fit's metric (components read from one run)
    P = nuisance_projector(whiten(W, fps.sensitivities[cal] / sigma[:, None]))

    def projected(fp, a):
        return P @ whiten(W, np.asarray(fp.predict(a), float)[cal] / sigma)

    curves = {}
    for fp in fps.fingerprints:
        lo, hi = fp.effect.prior
        grid = np.linspace(min(0.0, lo), hi, _GRID)
        curves[fp.name] = np.array([projected(fp, a) for a in grid])
    level = math.sqrt(max(float(fps.threshold), 0.0))
    rows = []
    for fa in fps.fingerprints:
        top = projected(fa, fa.effect.prior[1])
        signal = float(np.linalg.norm(top))
        mine = []
        for fb in fps.fingerprints:
            if fb.name == fa.name:
                continue
            residual = float(np.min(np.linalg.norm(curves[fb.name] - top, axis=1)))
            unique = residual / signal if signal > 0 else float("nan")
            need = level / unique if unique > 0 else float("inf")
            mine.append({"effect": fa.name, "other": fb.name, "signal_sigma": signal,
                         "residual_sigma": residual, "unique_fraction": unique,
                         "gap_to_separate_sigma": need, "separable": bool(signal >= need)})
        rows += sorted(mine, key=lambda r: r["unique_fraction"])
    return rows


def nearest_imitations(fps_or_rows) -> list[dict]:
    """Per effect, the row of :func:`separation` for the other effect that imitates it best.

    Parameters
    ----------
    fps_or_rows : FingerprintSet or list of dict
        Fingerprints, or the rows :func:`separation` already gave for them.

    Returns
    -------
    list of dict
        One row of :func:`separation` per effect, in the rows' order of effects.

    Examples
    --------
    >>> rows = [{"effect": "a", "other": "b", "unique_fraction": 0.55},
    ...         {"effect": "a", "other": "c", "unique_fraction": 0.97},
    ...         {"effect": "b", "other": "a", "unique_fraction": 0.58}]
    >>> [(r["effect"], r["other"]) for r in nearest_imitations(rows)]
    [('a', 'b'), ('b', 'a')]
    """
    rows = separation(fps_or_rows) if isinstance(fps_or_rows, FingerprintSet) else fps_or_rows
    best: dict[str, dict] = {}
    for row in rows:
        if row["effect"] not in best or row["unique_fraction"] < best[row["effect"]]["unique_fraction"]:
            best[row["effect"]] = row
    return list(best.values())


def not_told_apart(attribution, fps: FingerprintSet, *, rows=None) -> list[dict]:
    """Other effects that the first attributed effect is not told apart from by the data.

    An effect B counts when it alone would also be selected (its chi-square decrease
    passes the selection threshold) and the attributed effect A lowers the chi-square by
    less than that threshold more than B does: the data favour A over B by less than the
    selection asks of any effect over the null, so the answer could as well be B.

    Parameters
    ----------
    attribution : Attribution
    fps : FingerprintSet
        The fingerprints the attribution used.
    rows : list of dict, optional
        :func:`separation` of ``fps``, when already computed.

    Returns
    -------
    list of dict
        ``effect`` (B), ``delta_chi2`` (B's), ``preference`` (A's chi-square decrease
        minus B's), ``unique_fraction`` and ``gap_to_separate_sigma`` (of A against B, from
        :func:`separation`: the gap from which on this design tells the two apart) and
        ``gap_sigma`` (A's, ``sqrt`` of its chi-square decrease); empty without an
        attribution.
    """
    if attribution.verdict != "attributed" or not attribution.selected:
        return []
    top = attribution.selected[0]
    level = float(attribution.threshold)
    by_pair = {(r["effect"], r["other"]): r for r in (separation(fps) if rows is None else rows)}
    out = []
    for other in attribution.ranking:
        r = by_pair.get((top.effect, other.effect))
        if r is None or other.delta_chi2 <= level:
            continue
        preference = float(top.delta_chi2 - other.delta_chi2)
        if preference < level:
            out.append({"effect": other.effect, "delta_chi2": float(other.delta_chi2),
                        "preference": preference, "unique_fraction": r["unique_fraction"],
                        "gap_sigma": math.sqrt(max(float(top.delta_chi2), 0.0)),
                        "gap_to_separate_sigma": r["gap_to_separate_sigma"]})
    return out
