"""Which catalogue effects a measurement design tells apart.

Identifiability (:func:`bedstruct.diagnose.fingerprints.assess_fingerprints`) asks whether
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

from .fingerprints import FingerprintSet, nuisance_projector

__all__ = ["nearest_imitations", "separation"]

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
    cal = fps.rows_calibrate
    sigma = fps.sigma[cal]
    P = nuisance_projector(fps.sensitivities[cal] / sigma[:, None])

    def projected(fp, a):
        return P @ (np.asarray(fp.predict(a), float)[cal] / sigma)

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


def nearest_imitations(fps: FingerprintSet) -> list[dict]:
    """Per effect, the row of :func:`separation` for the other effect that imitates it best.

    Examples
    --------
    >>> from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue,
    ...                                 compute_fingerprints, diagnosis_design, twin_design)
    >>> effects = catalogue()
    >>> design = diagnosis_design(twin_design(), effects)
    >>> fps = compute_fingerprints(SurrogateSimulator(design), design, BASE_PARAMETERS, effects,
    ...                            replicates=2)
    >>> [(r["effect"], r["other"]) for r in nearest_imitations(fps)][:2]
    [('contact_ageing', 'non_sphericity'), ('capillary_bridges', 'non_sphericity')]
    """
    best: dict[str, dict] = {}
    for row in separation(fps):
        if row["effect"] not in best or row["unique_fraction"] < best[row["effect"]]["unique_fraction"]:
            best[row["effect"]] = row
    return list(best.values())
