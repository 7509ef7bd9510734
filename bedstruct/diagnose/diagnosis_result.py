"""What a diagnosis found: the :class:`Diagnosis` result, its JSON answer and data notes.

:func:`~bedstruct.diagnose.diagnosis.diagnose` makes it; this module holds the result types
and the text they give (which measurements would identify an effect, notes on the data).

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .attribution import Attribution
from .confirm import Shrink
from .fingerprints import FingerprintSet
from .measurements import MeasurementSet
from .noise_correlation import effective_correlation
from .parameters import PARAMETER_UNITS
from .separation import nearest_imitations, not_told_apart, separation
from .where import WhereResult

__all__ = ["SCHEMA", "Diagnosis", "NextMeasurement", "identification", "uneven_scatter_note"]

SCHEMA = "bedstruct.diagnose/1"


def identification(fps, name: str) -> dict:
    """Which measurements would identify effect ``name``, and on what evidence.

    ``identify_with`` lists the observables its simulated fingerprint moves beyond 2 sigma
    outside the calibration set (:func:`~bedstruct.diagnose.identifiability.assess_fingerprints`).
    When there are none, the catalogue's own suggestions are split into those the
    fingerprint runs did measure (``checked``: they do not identify it in these
    simulations, so they are not suggested) and those it could not (``unchecked``: not in
    the design, or not observable; suggested, unverified).

    Returns
    -------
    dict
        ``effect``, ``identify_with``, ``evidence`` (``"simulated"``, ``"catalogue"`` or
        ``"none"``), ``checked``, ``unchecked`` and a one-sentence ``note``.
    """
    f = fps[name]
    if f.identify_with:
        return {"effect": name, "identify_with": list(f.identify_with), "evidence": "simulated",
                "checked": [], "unchecked": [],
                "note": "moves these observables beyond 2 sigma in the fingerprint runs"}
    suggested = [d["name"] for d in f.effect.identify_with]
    simulated = set(fps.names)
    checked = [n for n in suggested if n in simulated]
    unchecked = [n for n in suggested if n not in simulated]
    if unchecked:
        note = ("the catalogue suggests " + ", ".join(unchecked) + " (not verified: the fingerprint "
                "runs did not measure or could not observe it)")
        if checked:
            note += "; " + ", ".join(checked) + " did not move beyond 2 sigma in the runs"
        return {"effect": name, "identify_with": unchecked, "evidence": "catalogue",
                "checked": checked, "unchecked": unchecked, "note": note}
    return {"effect": name, "identify_with": [], "evidence": "none", "checked": checked,
            "unchecked": [],
            "note": ("no measurement in the design identifies it: "
                     + (", ".join(checked) + ", suggested by the catalogue, did not move beyond "
                        "2 sigma in the fingerprint runs either" if checked else
                        "the catalogue suggests none") + "; a new kind of measurement is needed")}


@dataclass(frozen=True)
class NextMeasurement:
    """A measurement ranked by how well it separates the top two candidate models."""

    observable: str
    kind: str
    conditions: str
    role: str
    separation: float
    separates: tuple[str, str]
    measured: bool

    def as_dict(self) -> dict:
        return {"observable": self.observable, "kind": self.kind, "conditions": self.conditions,
                "role": self.role, "separation_sigma": self.separation,
                "separates": list(self.separates), "already_measured": self.measured}


@dataclass(frozen=True)
class Diagnosis:
    """Everything :func:`diagnose` found; ``to_json()`` gives the compact answer."""

    measurements: MeasurementSet
    fingerprints: FingerprintSet
    where: WhereResult
    attribution: Attribution
    shrink: Shrink
    next: tuple[NextMeasurement, ...]
    simulator: str
    settings: dict = field(default_factory=dict)

    @property
    def verdict(self) -> str:
        return self.attribution.verdict

    @property
    def residual(self) -> np.ndarray:
        """Measured minus base-mean on every fingerprint row (NaN on candidate rows)."""
        return _residual(self.measurements, self.fingerprints)

    def to_json(self) -> dict:
        """The compact JSON answer: where, which, how much, confidence, what next.

        ``settings.data_notes`` holds every note of :meth:`data_notes` (unit conversions,
        observables measured but not used, runs that missed an observable, uneven or
        correlated scatter, trials without a reading).
        """
        att = self.attribution
        confidence = (att.selected[0].confidence if att.selected else
                      (att.null.weight if att.verdict == "none" else None))
        pairs = separation(self.fingerprints)
        return {
            "schema": SCHEMA, "simulator": self.simulator,
            "measurements": self.measurements.path or self.measurements.title,
            "verdict": att.verdict, "partial": bool(att.partial), "reason": att.reason,
            "gap_significant": self.where.significant,
            "gap_chi2": {"chi2": self.where.chi2, "dof": self.where.dof, "p_value": self.where.p_value,
                         "max_abs_z": self.where.max_abs_z, "p_max": self.where.p_max},
            "where": self.where.ranked(), "where_summary": list(self.where.summary),
            "which": att.which(),
            "confidence": confidence,
            "candidates": [e.as_dict() for e in att.ranking],
            "models": [dict(m.as_dict(), label=m.label) for m in att.models[:12]],
            "shrink": self.shrink.as_dict(),
            "recalibration": self.recalibration(),
            "next": [n.as_dict() for n in self.next],
            "identifiability": self.fingerprints.table(),
            "separation": nearest_imitations(pairs),
            "not_told_apart_from": not_told_apart(att, self.fingerprints, rows=pairs),
            "not_identifiable": [identification(self.fingerprints, f.name)
                                 for f in self.fingerprints.fingerprints if not f.identifiable],
            "not_measured": self.trials_without_reading(),
            "settings": dict(self.settings, data_notes=self.data_notes()),
        }

    def recalibration(self) -> dict[str, dict]:
        """The recalibrated parameters of the answer's model, each within its bounds.

        Per parameter: ``base`` and fitted ``value`` (its SI unit, ``unit``), ``shift``,
        ``bounds`` (``None`` for an open end) and ``at_bound`` (the fit ended on a bound:
        the data would take the parameter past a physical or configured limit).
        """
        fps = self.fingerprints
        limits = fps.parameter_bounds()
        out = {}
        for name in fps.nuisance:
            base = float(fps.base[name])
            shift = float(self.shrink.nuisance.get(name, 0.0))
            value = base + shift
            lo, hi = limits[name]
            tol = 1e-6 * max(abs(base), abs(value), 1e-300)
            at = bool((math.isfinite(lo) and value <= lo + tol)
                      or (math.isfinite(hi) and value >= hi - tol))
            out[name] = {"base": base, "shift": shift, "value": value,
                         "unit": PARAMETER_UNITS.get(name, ""),
                         "bounds": [lo if math.isfinite(lo) else None,
                                    hi if math.isfinite(hi) else None],
                         "at_bound": at}
        return out

    def trials_without_reading(self) -> list[dict]:
        """The observables whose file states trials that gave no reading.

        One row per such observable: ``observable``, ``role``, ``trials``, ``not_measured``
        (per component), ``in_no_trial`` (no reading at all: it has no value to fit),
        ``simulated`` (the fingerprints' simulator gives it), ``fingerprint_runs`` and
        ``fingerprint_runs_without_reading`` (the simulation's runs behind the
        fingerprints, and those in which it could not read the observable either). The
        final model is tested on these counts (:attr:`Shrink.p_rerun_trials`).
        """
        pts = self.fingerprints.meta.get("unread_runs", {})
        out = []
        for m in self.measurements.measurements + tuple(self.measurements.unmeasured):
            if m.trials is None or m.not_measured is None or not np.any(m.not_measured):
                continue
            mine = pts.get(m.name, [])
            out.append({"observable": m.name, "role": m.role, "trials": int(m.trials),
                        "not_measured": [int(k) for k in m.not_measured],
                        "in_no_trial": m.measured_in_no_trial,
                        "simulated": bool(mine),
                        "fingerprint_runs": int(sum(p["runs"] for p in mine)),
                        "fingerprint_runs_without_reading": int(sum(p["unread"] for p in mine))})
        return out

    def data_notes(self) -> list[str]:
        """Notes on the data, one sentence each.

        What the simulations or the file could not observe, scatter that differs between
        parameter points, and what was done to the file's numbers when it was read (unit
        conversions, uncertainties from replicates). Empty when there is nothing to say.
        """
        missing = self.settings.get("missing_runs") or {}
        out = [f"{n}: not observed in {k} fingerprint run(s); averaged over the runs that did"
               for n, k in missing.items()]
        out += [uneven_scatter_note(n, u) for n, u in (self.settings.get("uneven_scatter") or {}).items()]
        out += [f"{w['effect']} at {w['magnitude']:.3g} (simulated after the fingerprints): "
                f"{w['component']} scatters from run to run with standard deviation "
                f"{w['sd']:.3g} against {w['sd_pooled']:.3g} pooled; runs there are judged in "
                f"their own scatter, and more seeds at that magnitude would sharpen the answer"
                for w in self.settings.get("node_scatter") or []]
        out += [f"{c['components'][0]} and {c['components'][1]}: their run-to-run deviations "
                f"move together (r = {c['r']:.2f} over {c['dof']} degrees of freedom), as when "
                f"one run or one sample gives both; the statistics take them together "
                f"(generalised least squares at r = "
                f"{effective_correlation(c['r'], c['dof']):.2f}, the lower end of its 95 % "
                f"interval), so that a common deviation counts about once"
                for c in self.settings.get("correlated_scatter") or []]
        for t in self.trials_without_reading():
            if not t["simulated"]:
                out.append(f"{t['observable']}: no reading in {max(t['not_measured'])} of its "
                           f"{t['trials']} trials; the simulation does not give this "
                           f"observable, so those trials are not tested")
                continue
            sim = (f"the simulation could not read it in {t['fingerprint_runs_without_reading']} "
                   f"of its {t['fingerprint_runs']} fingerprint runs")
            if t["in_no_trial"]:
                out.append(f"{t['observable']}: no reading in any of its {t['trials']} trial(s); "
                           f"it has no value to fit ({sim}), and the answer's model must give "
                           f"such trials as often (a test that gives no reading, such as a "
                           f"heap that stands as a block, is an outcome)")
            else:
                k = max(t["not_measured"])
                out.append(f"{t['observable']}: no reading in {k} of its {t['trials']} trials; "
                           f"the value is the mean of the others ({sim}), and the answer's "
                           f"model must give such trials as often")
        # a conversion that many observables share (a file of 20 layers with speeds in cm/s)
        # is said once, with the observables it applies to
        shared: dict[str, list[str]] = {}
        for m in self.measurements:
            for c in m.conversions:
                shared.setdefault(c, []).append(m.name)
        out += [f"{', '.join(names)}: {c}" if len(names) <= 3 else
                f"{names[0]}, {names[1]} and {len(names) - 2} more observables: {c}"
                for c, names in shared.items()]
        out += [f"set-up: {c}" for c in self.measurements.setup.conversions]
        return out + list(self.settings.get("data_notes") or [])


def uneven_scatter_note(component: str, u: dict) -> str:
    """One sentence on a component whose run-to-run scatter differs between parameter points."""
    return (f"{component}: the run-to-run scatter differs between parameter points (Bartlett "
            f"p = {u['p_value']:.2g}; standard deviation {u['sd_min']:.3g} at {u['smallest_at']} "
            f"to {u['sd_max']:.3g} at {u['largest_at']}, {u['sd_base']:.3g} at the base); "
            f"pooled without {', '.join(u.get('set_aside', []))}, which keep their own")


def _residual(measurements: MeasurementSet, fps: FingerprintSet) -> np.ndarray:
    """Measured minus base mean on the fingerprint rows (NaN on candidate rows)."""
    names = [n for n in fps.names if fps.design[n].role != "candidate"]
    out = np.full(len(fps.sigma), np.nan)
    rows = ~fps.rows_candidate
    out[rows] = np.concatenate([measurements[n].values for n in names]) - fps.base_mean[rows]
    return out
