"""Trials without a reading, weighed: does a model give them as often as the data do?

A test can fail to give a reading: an aged pile that stands as a block after rest leaves no
flank to fit, a fast stroke no heap. Such a trial is an outcome of the powder, and a model
that never produces it where the experiment mostly does is contradicted by it, whatever its
fit to the readings that were made. The trial check tests the trials a measurement file states
(``trials``, ``not_measured``; see :mod:`bedstruct.diagnose.measurement_io`) against the
simulation's runs of the chosen model, observable by observable:

* the model's runs: the rerun at its fitted parameters (and, where the file holds an
  observable read in no trial, further seeds there), pooled with the fingerprint runs of the
  same model on one side of the fitted magnitude: the base-like points (the base and the
  recalibration steps) and the effect's points below it, or the effect's points above it.
  Where the rate of a run without a reading changes monotonically with the magnitude, either
  way, one of the two pools has a rate at least the model's and the other at most, so the
  larger of the two p-values is a conservative test (:func:`model_pools`);
* per observable, Fisher's exact test (two-sided) of the file's trials against each pool,
  the larger p-value kept (:func:`observable_p`);
* over observables, Sidak's correction for the observables where a trial or a run gave no
  reading (Tarone's device: an observable read in every trial and every run cannot reach any
  level, conditional on its margins, and is left out of the count).

The fingerprint runs' counts are recorded when the fingerprints are made
(``FingerprintSet.meta["unread_runs"]``); refinement nodes are not counted.

.. versionadded:: 0.1
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from scipy import stats

__all__ = ["TrialCheck", "file_trials", "model_pools", "observable_p", "trial_check",
           "unread_counts"]


def file_trials(measurements) -> dict[str, tuple[int, int]]:
    """``{observable: (trials without a reading, trials)}`` for every observable of the file
    that states its trials (read ones and those read in no trial alike)."""
    out = {}
    for m in tuple(measurements.measurements) + tuple(getattr(measurements, "unmeasured", ())):
        if m.trials is not None and m.not_measured is not None and m.role != "candidate":
            out[m.name] = (int(np.max(m.not_measured)), int(m.trials))
    return out


def unread_counts(samples, names, n_components: Mapping[str, int]) -> dict[str, tuple[int, int]]:
    """``{observable: (runs without a reading, runs)}`` of stacked run vectors ``samples``
    ``(R, n)`` whose columns are the components of ``names`` in order
    (``n_components[name]`` each).

    Examples
    --------
    >>> unread_counts([[1.0, np.nan, 2.0], [1.0, 3.0, np.nan]], ["a", "b"], {"a": 1, "b": 2})
    {'a': (0, 2), 'b': (2, 2)}
    """
    samples = np.atleast_2d(np.asarray(samples, float))
    out, j = {}, 0
    for n in names:
        k = int(n_components[n])
        cols = samples[:, j:j + k]
        out[n] = (int(np.sum(~np.all(np.isfinite(cols), axis=1))), int(samples.shape[0]))
        j += k
    return out


def model_pools(points, magnitudes: Mapping[str, float], rerun: tuple[int, int]) -> list[tuple[int, int]]:
    """The pools of runs that stand for a model on one observable.

    Parameters
    ----------
    points : sequence of dict
        The fingerprint points' counts on the observable: ``effects`` (``{}`` for the base
        and the recalibration steps, else ``{effect: magnitude}``), ``unread``, ``runs``.
    magnitudes : mapping
        The model's fitted magnitudes (empty: recalibration alone).
    rerun : (int, int)
        Runs without a reading, and runs, at the model itself.

    Returns
    -------
    list of (int, int)
        ``(unread, runs)`` per pool: one for recalibration alone (the base-like points and
        the rerun) or for a pair of effects (the rerun alone: its rate cannot be read off
        either effect's points); two for one effect at ``a``: the base-like points with the
        effect's points at magnitudes up to ``a``, and the effect's points from ``a`` up,
        each with the rerun.

    Examples
    --------
    >>> pts = [{"effects": {}, "unread": 0, "runs": 6}, {"effects": {"e": 1.0}, "unread": 0, "runs": 3},
    ...        {"effects": {"e": 2.0}, "unread": 1, "runs": 3}]
    >>> model_pools(pts, {"e": 1.7}, (2, 3))
    [(2, 12), (3, 6)]
    >>> model_pools(pts, {}, (0, 3))
    [(0, 9)]
    """
    k_r, n_r = (int(v) for v in rerun)
    base = [(p["unread"], p["runs"]) for p in points if not p["effects"]]
    if not magnitudes:
        return [(k_r + sum(k for k, _ in base), n_r + sum(n for _, n in base))]
    if len(magnitudes) > 1:
        return [(k_r, n_r)]
    (effect, a), = magnitudes.items()
    mine = [(abs(float(p["effects"][effect])), p["unread"], p["runs"]) for p in points
            if set(p["effects"]) == {effect}]
    a = abs(float(a))
    below = base + [(k, n) for m, k, n in mine if m <= a]
    above = [(k, n) for m, k, n in mine if m >= a]
    return [(k_r + sum(k for k, _ in pool), n_r + sum(n for _, n in pool)) for pool in (below, above)]


def observable_p(data: tuple[int, int], pools) -> float:
    """The larger of the two-sided Fisher exact p-values of the file's trials
    ``(unread, trials)`` against each pool ``(unread, runs)`` (1 where a table is degenerate).

    Examples
    --------
    Three trials without a reading, against 15 runs that all gave one:

    >>> round(observable_p((3, 3), [(0, 15)]), 5)
    0.00123
    """
    k, r = (int(v) for v in data)
    ps = []
    for ks, ns in pools:
        if ns <= 0 or (k + ks == 0) or (k + ks == r + ns):
            ps.append(1.0)
            continue
        ps.append(float(stats.fisher_exact([[k, r - k], [ks, ns - ks]], alternative="two-sided")[1]))
    return max(ps) if ps else 1.0


@dataclass(frozen=True)
class TrialCheck:
    """What :func:`trial_check` found.

    Attributes
    ----------
    p_value : float
        Sidak-corrected smallest per-observable p-value (1 when nothing was tested).
    n_tested : int
        Observables in the correction: a trial or a run without a reading.
    rows : tuple of dict
        Per observable tested: ``observable``, ``unread`` and ``trials`` (the file's),
        ``pools`` (``[unread, runs]`` of the model's runs), ``p``; smallest ``p`` first.
    """

    p_value: float = 1.0
    n_tested: int = 0
    rows: tuple[dict, ...] = field(default_factory=tuple)

    @property
    def worst(self) -> dict | None:
        return self.rows[0] if self.rows else None

    def text(self) -> str:
        """One line on the worst observable, e.g. for a verdict's reason."""
        w = self.worst
        if w is None:
            return ""
        pools = " or ".join(f"{k} of {n}" for k, n in w["pools"])
        return (f"{w['observable']} gave no reading in {w['unread']} of {w['trials']} trials and "
                f"in {pools} of the model's runs (p = {w['p']:.2g}; {self.p_value:.2g} over the "
                f"{self.n_tested} observable(s) with a trial or a run without a reading)")


def trial_check(trials: Mapping[str, tuple[int, int]], points: Mapping[str, list],
                magnitudes: Mapping[str, float],
                rerun: Mapping[str, tuple[int, int]]) -> TrialCheck:
    """Test the file's trials without a reading against a model's runs.

    Parameters
    ----------
    trials : mapping
        :func:`file_trials` of the measurement file.
    points : mapping
        Per observable, the fingerprint points' counts (``FingerprintSet.meta["unread_runs"]``).
    magnitudes : mapping
        The model's fitted magnitudes (empty: recalibration alone).
    rerun : mapping
        Per observable, ``(unread, runs)`` of the runs at the model itself.

    Returns
    -------
    TrialCheck
        Observables the simulation has no runs of are skipped.

    Examples
    --------
    >>> pts = {"o": [{"effects": {}, "unread": 0, "runs": 6},
    ...              {"effects": {"e": 1.0}, "unread": 0, "runs": 3}]}
    >>> chk = trial_check({"o": (3, 3)}, pts, {"e": 0.5}, {"o": (0, 9)})
    >>> chk.n_tested, round(chk.p_value, 4)
    (1, 0.0022)
    >>> trial_check({"o": (0, 3)}, pts, {"e": 0.5}, {"o": (0, 9)}).p_value
    1.0
    """
    rows = []
    for name, data in trials.items():
        if name not in rerun:
            continue
        pools = model_pools(points.get(name, []), magnitudes, rerun[name])
        if data[0] == 0 and all(k == 0 for k, _ in pools):
            continue   # read in every trial and every run: no level is reachable
        rows.append({"observable": name, "unread": int(data[0]), "trials": int(data[1]),
                     "pools": [[int(k), int(n)] for k, n in pools],
                     "p": observable_p(data, pools)})
    if not rows:
        return TrialCheck()
    rows.sort(key=lambda r: r["p"])
    m = len(rows)
    p = float(1.0 - (1.0 - rows[0]["p"]) ** m)
    return TrialCheck(p_value=min(1.0, max(p, 0.0)), n_tested=m, rows=tuple(rows))
