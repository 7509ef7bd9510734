"""Scores of a twin validation: the result type, the goals and the twin records.

:func:`score_twins` turns twin records (one per diagnosed twin, as
:func:`bedstruct.diagnose.validate` writes them, also to a JSON-lines file while it runs)
into the issue's scores; :class:`ValidationResult` holds them with the twins and settings.

.. versionadded:: 0.1
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import ConfigError

__all__ = ["GOALS", "ValidationResult", "capped_summary", "capped_twins", "score_twins"]

log = logging.getLogger("bedstruct.diagnose.validation.validate")

#: Goals of the issue at the small preset.
GOALS = {"top1_accuracy": (">=", 0.90), "null_false_attribution": ("<=", 0.05),
         "out_of_catalogue_unexplained": (">=", 0.80), "median_gap_shrink": (">=", 0.70)}
#: Level of the test for a held-out gap before: the median shrink is taken over the effect
#: twins whose held-out observables show a gap beyond noise (``p_gap_heldout_before`` below
#: it), since the shrink of a gap within noise is noise.
SHRINK_ALPHA = 0.05


@dataclass(frozen=True)
class ValidationResult:
    """Scores of the diagnosis on synthetic twins.

    Attributes
    ----------
    preset, simulator : str
    top1_accuracy : float
        Fraction of in-catalogue twins whose true effect is attributed first.
    null_false_attribution : float
        Fraction of null twins where any effect was attributed.
    null_gap_flagged : float
        Fraction of null twins where the "where" test flagged a significant gap.
    out_of_catalogue_unexplained : float
        Fraction of out-of-catalogue twins answered "unexplained".
    median_gap_shrink : float
        Median over in-catalogue twins of the held-out excess-gap shrink, over those whose
        held-out gap before is beyond noise (chi-square at :data:`SHRINK_ALPHA`; their
        number and that of the others are in ``goals["median_gap_shrink"]``).
    median_gap_shrink_rms : float
        The same with the RMS gap (noise floor included; stricter).
    confusion : dict
        ``{"labels": [...], "rows": [...], "matrix": [[...]]}``: true label by row,
        predicted top label by column (``none``, ``unexplained`` included).
    magnitudes : list of dict
        Per correctly attributed twin: true and fitted magnitude, interval, covered.
    twins : list of dict
        One record per twin.
    goals : dict
        Each goal with its value and whether it is met.
    identifiable : dict
        Scores over the twins whose true effect the fingerprints found identifiable
        (``effects``, ``top1_accuracy``, ``out_of_catalogue_unexplained`` and the twin
        counts); empty when identifiability was not given. A twin of an effect that these
        observables cannot see at any magnitude of its prior tests the identifiability
        report, not the attribution.
    detected : dict
        Scores over the twins whose gap the "where" test found significant
        (``top1_accuracy``, ``out_of_catalogue_unexplained``, the twin counts and
        ``n_effect_twins_undetected``). A twin sized on a fingerprint's interpolated response
        can carry less than requested (a response that is not straight between the
        simulated magnitudes, the fingerprint's own noise); one without a significant gap
        cannot be attributed by any method and tests how the twins are made.
    """

    preset: str
    simulator: str
    top1_accuracy: float
    null_false_attribution: float
    null_gap_flagged: float
    out_of_catalogue_unexplained: float
    median_gap_shrink: float
    median_gap_shrink_rms: float
    magnitude_coverage: float
    magnitude_median_relative_error: float
    confusion: dict
    magnitudes: list
    twins: list
    goals: dict
    seconds: float
    settings: dict = field(default_factory=dict)
    identifiable: dict = field(default_factory=dict)
    detected: dict = field(default_factory=dict)

    @classmethod
    def from_scores(cls, preset: str, simulator: str, scores: dict, twins, seconds: float,
                    settings: dict) -> "ValidationResult":
        """The result of twins scored by :func:`score_twins` (``scores``)."""
        keys = ("top1_accuracy", "null_false_attribution", "null_gap_flagged",
                "out_of_catalogue_unexplained", "median_gap_shrink", "median_gap_shrink_rms",
                "magnitude_coverage", "magnitude_median_relative_error", "confusion",
                "magnitudes")
        return cls(preset, simulator, *(scores[k] for k in keys), list(twins), scores["goals"],
                   seconds, settings, scores["identifiable"], scores.get("detected", {}))

    def to_json(self) -> dict:
        return {"schema": "bedstruct.diagnose.validate/1", "preset": self.preset,
                "simulator": self.simulator,
                "top1_accuracy": self.top1_accuracy,
                "null_false_attribution": self.null_false_attribution,
                "null_gap_flagged": self.null_gap_flagged,
                "out_of_catalogue_unexplained": self.out_of_catalogue_unexplained,
                "median_gap_shrink": self.median_gap_shrink,
                "median_gap_shrink_rms": self.median_gap_shrink_rms,
                "magnitude_coverage": self.magnitude_coverage,
                "magnitude_median_relative_error": self.magnitude_median_relative_error,
                "confusion": self.confusion, "magnitudes": self.magnitudes, "goals": self.goals,
                "identifiable": self.identifiable, "detected": self.detected,
                "n_twins": len(self.twins), "twins": self.twins, "seconds": self.seconds,
                "settings": self.settings}


def capped_twins(twins) -> list[dict]:
    """Effect twins whose magnitude the prior top held below the gap drawn for them.

    Examples
    --------
    >>> capped_twins([{"type": "effect", "true_effect": "a", "requested_gap_sigma": 7.0,
    ...                "twin_gap_sigma": 4.4},
    ...               {"type": "effect", "true_effect": "b", "requested_gap_sigma": 6.0,
    ...                "twin_gap_sigma": 6.0}, {"type": "null", "true_effect": None}])
    [{'type': 'effect', 'true_effect': 'a', 'requested_gap_sigma': 7.0, 'twin_gap_sigma': 4.4}]
    """
    return [t for t in twins if t["type"] == "effect" and t.get("twin_gap_sigma") is not None
            and t["twin_gap_sigma"] < (1 - 1e-6) * t["requested_gap_sigma"]]


def capped_summary(twins, sigma: str = "σ") -> str:
    """:func:`capped_twins` per effect, in words ("" if none).

    Examples
    --------
    >>> capped_summary([{"type": "effect", "true_effect": "a", "requested_gap_sigma": 7.0,
    ...                  "twin_gap_sigma": 4.4}] * 2 + [{"type": "effect", "true_effect": "b",
    ...                  "requested_gap_sigma": 9.0, "twin_gap_sigma": 1.61}], sigma=" sigma")
    'a (2 twins, 4.4 sigma), b (1 twin, 1.6 sigma)'
    """
    by = {}
    for t in capped_twins(twins):
        by.setdefault(t["true_effect"], []).append(t["twin_gap_sigma"])
    parts = []
    for e, g in by.items():
        lo, hi = f"{min(g):.1f}", f"{max(g):.1f}"
        parts.append(f"{e} ({len(g)} twin{'s' if len(g) > 1 else ''}, "
                     f"{lo if lo == hi else lo + '–' + hi}{sigma})")
    return ", ".join(parts)


def score_twins(twins, effect_names, *, removed_rows: bool = True,
                identifiable=None) -> dict:
    """Scores of a list of twin records (as in ``ValidationResult.twins``).

    Also used on a partial run: ``validate(..., records=PATH)`` appends each twin's
    record to a JSON-lines file as it completes.

    Parameters
    ----------
    twins : list of dict
        Twin records.
    effect_names : sequence of str
        The catalogue, in the confusion matrix's order.
    removed_rows : bool
        Add the "(removed)" rows of out-of-catalogue twins to the confusion matrix.
    identifiable : mapping of str to bool, optional
        Per effect, whether the fingerprints found it identifiable
        (:attr:`Fingerprint.identifiable`); adds the ``identifiable`` scores, over the
        twins of identifiable effects only.

    Returns
    -------
    dict
        ``top1_accuracy``, ``null_false_attribution``, ``null_gap_flagged``,
        ``out_of_catalogue_unexplained``, ``median_gap_shrink`` (and ``_rms``),
        ``magnitude_coverage``, ``magnitude_median_relative_error``, ``confusion``,
        ``magnitudes``, ``goals``, ``identifiable`` (``{}`` without `identifiable`),
        ``detected`` (the twins whose gap "where" found significant; ``{}`` without effect
        twins).

    Examples
    --------
    >>> twins = [
    ...     {"type": "effect", "true_effect": "a", "true_magnitude": 0.5, "predicted": "a",
    ...      "verdict": "attributed", "gap_significant": True, "shrink": 0.9, "shrink_rms": 0.8,
    ...      "fitted_magnitude": 0.45, "interval": [0.3, 0.6]},
    ...     {"type": "null", "true_effect": None, "true_magnitude": None, "predicted": "none",
    ...      "verdict": "none", "gap_significant": False, "shrink": None, "shrink_rms": None}]
    >>> s = score_twins(twins, ["a"], removed_rows=False)
    >>> s["top1_accuracy"], s["null_false_attribution"], s["magnitude_coverage"]
    (1.0, 0.0, 1.0)
    >>> s["confusion"]["matrix"]
    [[1, 0, 0], [0, 1, 0]]

    An effect the observables cannot see is scored apart:

    >>> twins.append({"type": "effect", "true_effect": "b", "true_magnitude": 0.4,
    ...               "predicted": "none", "verdict": "none", "gap_significant": False,
    ...               "shrink": None, "shrink_rms": None})
    >>> s = score_twins(twins, ["a", "b"], removed_rows=False,
    ...                 identifiable={"a": True, "b": False})
    >>> s["top1_accuracy"], s["identifiable"]["top1_accuracy"], s["identifiable"]["not_identifiable"]
    (0.5, 1.0, ['b'])

    So is a twin that carries no significant gap:

    >>> s["detected"]["top1_accuracy"], s["detected"]["n_effect_twins_undetected"]
    (1.0, 1)
    """
    eff_tw = [t for t in twins if t["type"] == "effect"]
    null_tw = [t for t in twins if t["type"] == "null"]
    ooc_tw = [t for t in twins if t["type"] == "out_of_catalogue"]

    def frac(items, pred):
        return float(np.mean([bool(pred(t)) for t in items])) if items else float("nan")

    def top1_hit(t):
        return t["verdict"] == "attributed" and t["predicted"].split("+")[0] == t["true_effect"]

    def ooc_hit(t):
        return t["verdict"] == "unexplained"

    top1 = frac(eff_tw, top1_hit)
    null_false = frac(null_tw, lambda t: t["verdict"] == "attributed")
    null_flag = frac(null_tw, lambda t: t["gap_significant"])
    ooc = frac(ooc_tw, ooc_hit)
    def finite(x):  # NaN is null in records read back from JSON
        return isinstance(x, (int, float)) and x == x

    def heldout_gap(t):  # a shrink of noise measures nothing (records before the test: kept)
        p = t.get("p_gap_heldout_before")
        return not finite(p) or p < SHRINK_ALPHA

    shrink_tw = [t for t in eff_tw if heldout_gap(t)]
    shr = [t["shrink"] for t in shrink_tw if finite(t["shrink"])]
    shr_rms = [t["shrink_rms"] for t in shrink_tw if finite(t["shrink_rms"])]
    med = float(np.median(shr)) if shr else float("nan")
    med_rms = float(np.median(shr_rms)) if shr_rms else float("nan")

    rows = list(effect_names) + ["null"] + ([f"{e} (removed)" for e in effect_names]
                                            if removed_rows else [])
    cols = list(effect_names) + ["none", "unexplained"]
    mat = np.zeros((len(rows), len(cols)), dtype=int)
    for t in twins:
        r = (t["true_effect"] if t["type"] == "effect" else "null" if t["type"] == "null"
             else f"{t['true_effect']} (removed)")
        c = t["predicted"].split("+")[0]
        mat[rows.index(r), cols.index(c)] += 1
    confusion = {"rows": rows, "columns": cols, "matrix": mat.tolist()}

    mags = []
    for t in eff_tw:
        # a twin made by another code's model of the effect (a LIGGGHTS capillary twin) may
        # have no true magnitude in the catalogue's terms: its attribution counts, not its size
        if (t["verdict"] == "attributed" and t["predicted"].split("+")[0] == t["true_effect"]
                and t.get("true_magnitude") is not None):
            lo, hi = t["interval"]
            mags.append({"effect": t["true_effect"], "true": t["true_magnitude"],
                         "fitted": t["fitted_magnitude"], "interval": [lo, hi],
                         "covered": bool(lo <= t["true_magnitude"] <= hi)})
    coverage = float(np.mean([m["covered"] for m in mags])) if mags else float("nan")
    rel = [abs(m["fitted"] - m["true"]) / abs(m["true"]) for m in mags if m["true"]]
    med_rel = float(np.median(rel)) if rel else float("nan")
    values = {"top1_accuracy": top1, "null_false_attribution": null_false,
              "out_of_catalogue_unexplained": ooc, "median_gap_shrink": med}
    goals = {}
    for k, (op, target) in GOALS.items():
        v = values[k]
        ok = (v >= target) if op == ">=" else (v <= target)
        goals[k] = {"value": v, "goal": f"{op} {target}", "met": bool(ok) if v == v else False}
    goals["median_gap_shrink"].update(n_twins=len(shr),
                                      n_no_heldout_gap=len(eff_tw) - len(shrink_tw))
    ident = {}
    if identifiable is not None:
        seen = [e for e in effect_names if identifiable.get(e, False)]
        eff_i = [t for t in eff_tw if t["true_effect"] in seen]
        ooc_i = [t for t in ooc_tw if t["true_effect"] in seen]
        ident = {"effects": seen, "not_identifiable": [e for e in effect_names if e not in seen],
                 "top1_accuracy": frac(eff_i, top1_hit), "n_effect_twins": len(eff_i),
                 "out_of_catalogue_unexplained": frac(ooc_i, ooc_hit), "n_out_of_catalogue_twins": len(ooc_i)}
    detected = {}
    if eff_tw:
        eff_d = [t for t in eff_tw if t.get("gap_significant")]
        ooc_d = [t for t in ooc_tw if t.get("gap_significant")]
        detected = {"top1_accuracy": frac(eff_d, top1_hit), "n_effect_twins": len(eff_d),
                    "n_effect_twins_undetected": len(eff_tw) - len(eff_d),
                    "out_of_catalogue_unexplained": frac(ooc_d, ooc_hit),
                    "n_out_of_catalogue_twins": len(ooc_d)}
    return {"top1_accuracy": top1, "null_false_attribution": null_false, "null_gap_flagged": null_flag,
            "out_of_catalogue_unexplained": ooc, "median_gap_shrink": med,
            "median_gap_shrink_rms": med_rms, "magnitude_coverage": coverage,
            "magnitude_median_relative_error": med_rel, "confusion": confusion, "magnitudes": mags,
            "goals": goals, "identifiable": ident, "detected": detected}
