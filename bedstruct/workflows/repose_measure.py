"""What a repose run gives, the same for every engine: one replicate's result
(:class:`ReposeReplicate`), the result over replicates (:class:`ReposeResult`,
:func:`combine_replicates`), the measurement of the pile (:func:`measure_pile`) and
the record of a finished replicate that a resumed run reuses.

The embedded run (:mod:`bedstruct.workflows.repose`) and the external engines'
(:mod:`bedstruct.workflows.external`) both build on it.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ConfigError
from .._json import to_jsonable, write_json_atomic
from ._common import from_plain, typed

__all__ = ["ReposeReplicate", "ReposeResult", "measure_pile", "measure_replicate_pile",
           "combine_replicates", "unmeasured_reason", "repose_result_from_dict"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReposeReplicate:
    """One angle-of-repose simulation.

    Attributes
    ----------
    seed : int
    cohesion : float, J/m^3
    angle_deg, angle_std_deg : float, degrees
        Mean of the fitted flanks and its uncertainty (from the flank fits).
    left_deg, right_deg : float, degrees
        Flank angles (NaN for a flank not fitted).
    n_inserted, n_remaining, n_fallen : int
        Particles inserted (all of them, also any lost while the box fills), left in the
        box, fallen into the reservoir (removed: ``n_inserted = n_remaining + n_fallen +
        n_lost_nonfinite``).
    pile_height : float, m
        Crest height of the pile above the plate.
    wall_time : float, s
    stage : str
        Sub-folder of the run directory (empty when nothing was written).
    n_lost_nonfinite : int
        Particles dropped for non-finite positions (a numerical blow-up; 0 unless the
        engine was told to drop them rather than raise).
    note : str
        Why the pile could not be measured (empty when it was): no pile formed, too few
        particles left, flanks that could not be fitted.
    """

    seed: int
    cohesion: float
    angle_deg: float
    angle_std_deg: float
    left_deg: float
    right_deg: float
    n_inserted: int
    n_remaining: int
    n_fallen: int
    pile_height: float
    wall_time: float
    stage: str = ""
    n_lost_nonfinite: int = 0
    note: str = ""


@dataclass(frozen=True)
class ReposeResult:
    """Static angle of repose over replicate simulations.

    Attributes
    ----------
    angle_deg : float, degrees
        Mean over the replicates whose pile could be measured (and their flanks); NaN
        when none could (:attr:`n_measured` is 0, :attr:`unmeasured` says why).
    angle_std_deg : float, degrees
        Standard uncertainty of that mean: the replicate standard error
        combined with the mean flank-fit uncertainty (root sum of squares).
    spread_deg : float, degrees
        Standard deviation of the replicate angles (NaN for one replicate).
    cohesion : float, J/m^3
    replicates : tuple of ReposeReplicate
    """

    angle_deg: float
    angle_std_deg: float
    spread_deg: float
    cohesion: float
    replicates: tuple = field(default_factory=tuple)

    @property
    def n_measured(self) -> int:
        """Replicates whose pile was measured (the mean is over these)."""
        return sum(1 for r in self.replicates if math.isfinite(r.angle_deg))

    @property
    def unmeasured(self) -> dict:
        """``{stage or "rep<i>": why}`` for each replicate whose pile could not be measured."""
        return {(r.stage or f"rep{i:02d}"): (r.note or "the pile could not be measured")
                for i, r in enumerate(self.replicates) if not math.isfinite(r.angle_deg)}

    def to_dict(self) -> dict:
        """JSON-ready summary (``angle_deg``, ``angle_std_deg``, replicates..., and
        ``n_measured``, ``unmeasured``: how many piles the mean is over, why the others
        could not be measured)."""
        d = to_jsonable(self)
        d["n_measured"] = self.n_measured
        d["unmeasured"] = self.unmeasured
        return d


def _finished_replicate(layout, stage: str, seed: int, cohesion: float):
    """The replicate recorded in ``<stage>/result.json`` of a resumed run, or None."""
    if layout is None or not layout.resumed:
        return None
    p = layout.path / stage / "result.json"
    if not p.is_file():
        return None
    try:
        rep = from_plain(ReposeReplicate, json.loads(p.read_text()))
    except (ValueError, TypeError) as exc:
        log.warning("%s: unreadable (%s); the replicate runs again", p, exc)
        return None
    if rep.seed != int(seed) or rep.cohesion != float(cohesion):
        return None
    return rep


def _record_replicate(layout, stage: str, rep: ReposeReplicate) -> None:
    """Record the finished replicate in ``<stage>/result.json`` (atomically; a resumed run
    reuses it, :func:`_finished_replicate`) and remove its checkpoint."""
    write_json_atomic(layout.path / stage / "result.json", rep, keep_nan=True)
    (layout.path / stage / "progress.npz").unlink(missing_ok=True)


def repose_result_from_dict(d: dict) -> ReposeResult:
    """The :class:`ReposeResult` of ``ReposeResult.to_dict()`` (as read from results.json;
    other keys are ignored)."""
    reps = tuple(from_plain(ReposeReplicate, r) for r in d["replicates"])
    return replace(from_plain(ReposeResult, {**d, "replicates": []}), replicates=reps)


def unmeasured_reason(n_inserted: int, n_remaining: int, n_fallen: int, detail: str = "") -> str:
    """Why a repose replicate's pile could not be measured, from its particle counts.

    Hardly any particle drained (fewer than 2 % of those inserted, or 10): no pile formed,
    the powder did not flow. Otherwise the flanks could not be fitted (``detail``: what
    the fit said).

    Examples
    --------
    >>> unmeasured_reason(797, 796, 1)[:38]
    'no pile formed: 1 of 797 particles dra'
    """
    if n_fallen < max(10, 0.02 * n_inserted):
        return (f"no pile formed: {n_fallen} of {n_inserted} particles drained when the plate "
                "slid out; the powder did not flow (a cohesive block that did not fail, or a "
                "plate that slid too little: lower contact.cohesion or contact.friction, or "
                "raise repose.slide_fraction)")
    what = f": {detail}" if detail else ""
    return (f"the pile's flanks could not be fitted ({n_remaining} particles remain, "
            f"{n_fallen} of {n_inserted} drained){what}")


def measure_replicate_pile(frame, cfg, *, r_max: float, n_inserted: int, n_fallen: int,
                           label: str) -> tuple:
    """:func:`measure_pile` of a replicate's final ``frame``, for every engine: a pile that
    cannot be measured gives NaN angles and a note saying why (:func:`unmeasured_reason`,
    logged as a warning naming ``label``), not an exception.

    Returns
    -------
    tuple
        ``(angle_deg, angle_std_deg, left_deg, right_deg, top, note)``; ``note`` is empty
        when the pile was measured.
    """
    why = []
    try:
        a, s, left, right, top = measure_pile(frame, cfg, r_max=r_max, reasons=why)
        note = ""
    except ConfigError as exc:   # (almost) nothing left in the box
        a = s = left = right = top = float("nan")
        note = str(exc)
    if not math.isfinite(a) and not note:
        note = unmeasured_reason(n_inserted, int(frame.n_particles), n_fallen, "; ".join(why))
    if note:
        log.warning("repose: replicate %s: %s", label, note)
    return a, s, left, right, top, note


def measure_pile(frame, cfg, *, r_max: float, reasons: list | None = None):
    """Angle of the pile left in ``frame`` (SI) by a repose run of ``cfg``.

    The same measurement for every engine and for ``bedstruct report``:
    :func:`bedstruct.analysis.pile_angle` on the spheres above the plate level,
    within the ledge (or the part of the floor left after the slide) plus a
    pad of ``2 r_max`` (both flanks with a ledge, else the flank facing the opening).

    Parameters
    ----------
    frame : Frame
    cfg : dict or WorkflowConfig
    r_max : float, m
        Largest particle radius.
    reasons : list, optional
        Gets why the pile could not be fitted appended (when the angles are NaN because
        the fit failed).

    Returns
    -------
    tuple of float
        ``(angle_deg, angle_std_deg, left_deg, right_deg, top)``; NaN angles
        (with a logged warning) when the pile cannot be fitted.

    Raises
    ------
    ConfigError
        Fewer than 10 spheres remain.
    """
    from ..analysis import pile_angle   # numba kernels: imported when a pile is measured

    rc = typed(cfg).repose
    L, W, _ = (float(v) for v in rc.box)
    ped = float(rc.pedestal_fraction)
    slide = L if ped > 0 else float(rc.slide_fraction) * L
    on_plate = int(np.count_nonzero(frame.positions[:, 2] > -frame.radii))
    if on_plate < 10:
        raise ConfigError(f"repose: only {on_plate} particles remain in the box; no pile to "
                          "measure. The powder drained or was thrown out of the box: with too "
                          "little cohesion or friction it all flows out (raise contact.cohesion "
                          "or contact.friction, or use a ledge: repose.pedestal_fraction); a "
                          "cohesion far too high for the Young's modulus makes the packing "
                          "explode (lower contact.cohesion; the presets' comments give its "
                          "scale)")
    x_lo = (L - ped * L) / 2 if ped > 0 else 0.0
    x_hi = (L + ped * L) / 2 if ped > 0 else L - slide
    pad = 2 * r_max
    bounds = ((x_lo - pad, x_hi + pad), (0.0, W))
    flanks = "both" if ped > 0 else "right"
    try:
        res = pile_angle(frame, axis=0, base=0.0, bounds=bounds, flanks=flanks,
                         shape="wedge").repose
        return (float(res.angle_deg), float(res.angle_std_deg), float(res.left_deg),
                float(res.right_deg), float(res.top))
    except ValueError as exc:
        log.warning("repose: pile could not be measured: %s", exc)
        if reasons is not None:
            reasons.append(str(exc))
        nan = float("nan")
        x = frame.positions[:, 0]
        keep = (frame.positions[:, 2] > -frame.radii) & (x > x_lo - pad) & (x < x_hi + pad)
        top = float(np.max(frame.positions[keep, 2] + frame.radii[keep])) if keep.any() else nan
        return nan, nan, nan, nan, top


def combine_replicates(reps, cohesion: float) -> ReposeResult:
    """Mean angle over replicates with its uncertainty (see :class:`ReposeResult`)."""
    ang = np.array([r.angle_deg for r in reps], dtype=float)
    fit = np.array([r.angle_std_deg for r in reps], dtype=float)
    ok = np.isfinite(ang)
    if not ok.any():
        return ReposeResult(float("nan"), float("nan"), float("nan"), float(cohesion), tuple(reps))
    a = ang[ok]
    mean = float(a.mean())
    spread = float(a.std(ddof=1)) if a.size > 1 else float("nan")
    sem = spread / math.sqrt(a.size) if a.size > 1 else 0.0
    fit_u = float(np.nanmean(fit[ok])) / math.sqrt(a.size) if np.isfinite(fit[ok]).any() else 0.0
    return ReposeResult(mean, float(math.hypot(sem, fit_u)), spread, float(cohesion), tuple(reps))
