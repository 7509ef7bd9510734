"""Calibrate the SJKR cohesion energy density against a target static angle of repose.

A bracketing search (regula falsi with the Illinois modification) over
replicate repose simulations: the angle is evaluated at the two ends of
``calibrate.cohesion_bracket`` (the bracket widens geometrically until it
contains the target; it stops early when the angle stops rising with
cohesion, as it does once cohesive blocks break off irregularly), then at the
secant crossing, keeping a bracket, until
the mean angle is within ``tolerance_deg`` of the target or ``max_iter``
evaluations were made. The calibrated value and its uncertainty come from a
weighted straight-line fit of angle against cohesion through the points of
the final bracket and the best point (inverse prediction with the delta
method), so the noise of the replicate angles propagates into the answer; the
uncertainty is at least the angle uncertainty divided by the slope of a line
through every evaluated point (two close, noisy points can fake a steep slope).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .._json import to_jsonable, write_json_atomic
from ._rundir import RunLayout, marks_failure
from ._common import typed
from .repose import ReposeResult, run_repose

__all__ = ["CalibrationPoint", "CalibrationResult", "calibrate_cohesion", "inverse_linear"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CalibrationPoint:
    """One point of the angle-cohesion curve: cohesion (J/m^3), mean angle and uncertainty (deg);
    ``note`` says why the angle is NaN (no pile could be measured at this cohesion)."""

    cohesion: float
    angle_deg: float
    angle_std_deg: float
    replicate_angles_deg: tuple
    note: str = ""


@dataclass(frozen=True)
class CalibrationResult:
    """Calibrated SJKR cohesion energy density.

    Attributes
    ----------
    cohesion : float, J/m^3
        Cohesion at which the fitted angle equals the target; when the target
        was not bracketed, the evaluated cohesion closest to it.
    cohesion_std : float, J/m^3
        Its standard uncertainty (from the angle uncertainties of the
        points and the slope of the fit); NaN when not bracketed.
    target_deg : float
    slope_deg_per_unit : float, degrees per J/m^3
        Slope of the local angle-cohesion line.
    converged : bool
        A point within ``tolerance_deg`` of the target was found.
    bracketed : bool
        The target lay between two evaluated angles.
    curve : tuple of CalibrationPoint
        Every evaluated point, sorted by cohesion.
    n_runs : int
        Repose simulations run.
    """

    cohesion: float
    cohesion_std: float
    target_deg: float
    slope_deg_per_unit: float
    converged: bool
    bracketed: bool
    curve: tuple
    n_runs: int

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return to_jsonable(self)


def _miss(p, target):
    return abs(p.angle_deg - target) if math.isfinite(p.angle_deg) else math.inf


def inverse_linear(x, y, sy, target: float) -> tuple[float, float, float]:
    """Weighted straight line ``y = a + b x`` through points; return ``(x*, sigma_x*, b)`` at ``y = target``.

    Parameters
    ----------
    x, y : (n,) array_like
        Abscissae and ordinates (n >= 2).
    sy : (n,) array_like
        Standard uncertainties of ``y`` (non-positive or NaN values are
        replaced by the mean of the valid ones, or 1).
    target : float

    Returns
    -------
    x_star, sigma_x_star, slope : float

    Examples
    --------
    >>> xs, s, b = inverse_linear([0.0, 1.0], [10.0, 20.0], [1.0, 1.0], 15.0)
    >>> round(xs, 6), round(s, 4), b
    (0.5, 0.0707, 10.0)
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    sy = np.asarray(sy, dtype=float).copy()
    good = np.isfinite(sy) & (sy > 0)
    sy[~good] = float(sy[good].mean()) if good.any() else 1.0
    if x.size < 2 or np.ptp(x) == 0:
        raise ValueError("need at least two distinct abscissae")
    xm = x.mean()
    xs = (x - xm)
    w = 1.0 / sy ** 2
    A = np.c_[np.ones_like(xs), xs]
    cov = np.linalg.inv(A.T @ (A * w[:, None]))
    a, b = cov @ (A.T @ (w * y))
    if b == 0:
        return float("nan"), float("nan"), 0.0
    xstar = (target - a) / b
    # delta method: d x*/d a = -1/b, d x*/d b = -(target - a)/b^2
    g = np.array([-1.0 / b, -(target - a) / b ** 2])
    var = float(g @ cov @ g)
    return float(xstar + xm), math.sqrt(max(var, 0.0)), float(b)


def calibrate_cohesion(cfg, *, target_deg: float | None = None, bracket=None,
                       replicates: int | None = None, max_iter: int | None = None,
                       tolerance_deg: float | None = None, out=None,
                       evaluate=None, progress: bool = False,
                       overwrite: bool = False) -> CalibrationResult:
    """Find the cohesion energy density whose repose angle matches ``target_deg``.

    Parameters
    ----------
    cfg : dict or WorkflowConfig
        Configuration (sections ``repose`` and ``calibrate``); a dict is loaded and checked
        once (:func:`~bedstruct.workflows.config.workflow_config`), and every point's repose
        run reads that one configuration.
    target_deg, bracket, replicates, max_iter, tolerance_deg : optional
        Override the ``calibrate`` section (bracket: ``(low, high)`` J/m^3).
    out : path, optional
        Run directory: each evaluation goes into ``k<value>/`` (a repose run folder),
        the points so far into ``points.json`` after each one, the calibration into
        ``results.json``. An earlier calibration of the same configuration and settings
        in ``out`` is resumed: its finished points (and replicates) are reused, so the
        search retraces its steps without simulating them again; one of another
        configuration is refused (ConfigError) unless ``overwrite``.
    evaluate : callable, optional
        ``evaluate(cohesion) -> (angle_deg, angle_std_deg, replicate_angles)``
        replacing the simulation (for tests and other models).
    progress : bool, optional
        Show a progress bar over the evaluated points (stderr).
    overwrite : bool, optional
        Replace an earlier run in ``out``.

    Returns
    -------
    CalibrationResult

    Examples
    --------
    A linear model with angle 20 + 1e-6 k reaches 33 deg at k = 1.3e7:

    >>> cfg = load_config(preset="tiny")
    >>> res = calibrate_cohesion(cfg, target_deg=33.0, bracket=(1e6, 5e6), max_iter=8,
    ...                          evaluate=lambda k: (20 + 1e-6 * k, 0.5, ()))
    >>> round(res.cohesion / 1e7, 3), res.bracketed, res.converged
    (1.3, True, True)
    """
    cfg = typed(cfg)
    cc = cfg.calibrate
    target = float(cc.target_deg if target_deg is None else target_deg)
    lo, hi = (float(v) for v in (cc.cohesion_bracket if bracket is None else bracket))
    if not 0 <= lo < hi:
        raise ConfigError(f"config key `calibrate.cohesion_bracket` must be 0 <= low < high; got {lo}, {hi}")
    nrep = int(cc.replicates if replicates is None else replicates)
    nmax = int(cc.max_iter if max_iter is None else max_iter)
    tol = float(cc.tolerance_deg if tolerance_deg is None else tolerance_deg)
    if nrep < 1:
        raise ConfigError(f"config key `calibrate.replicates` must be >= 1; got {nrep}")
    if not tol > 0:
        raise ConfigError(f"config key `calibrate.tolerance_deg` must be positive; got {tol}")
    layout = None
    if out is not None:
        inputs = {"target_deg": target, "bracket": [lo, hi], "replicates": nrep,
                  "max_iter": nmax, "tolerance_deg": tol, "evaluate": evaluate is not None}
        layout = RunLayout(out, cfg, workflow="calibrate", inputs=inputs, overwrite=overwrite)
    pts: dict[float, CalibrationPoint] = {}
    n_runs = 0
    from ._common import progress_bar
    bar = progress_bar(total=nmax + 2, desc="calibrate", unit="point", progress=progress)

    def ev(k):
        nonlocal n_runs
        if k in pts:
            return pts[k]
        note = ""
        if evaluate is not None:
            a, s, reps = evaluate(k)
        else:
            sub = None if layout is None else layout.path / f"k{k:.4g}"
            r: ReposeResult = run_repose(cfg, cohesion=k, replicates=nrep, out=sub)
            a, s, reps = r.angle_deg, r.angle_std_deg, tuple(x.angle_deg for x in r.replicates)
            n_runs += len(r.replicates)
            if r.unmeasured:
                where = f" ({sub})" if sub is not None else ""
                note = "; ".join(f"{st}: {why}" for st, why in r.unmeasured.items())
                log.warning("calibrate: cohesion %.4g J/m^3%s: %d of %d piles could not be "
                            "measured: %s", k, where, len(r.unmeasured), len(r.replicates), note)
        p = CalibrationPoint(float(k), float(a), float(s), tuple(float(v) for v in reps), note)
        pts[k] = p
        log.info("calibrate: cohesion %.4g -> %.2f +- %.2f deg", k, a, s)
        bar.update(1)
        bar.set_postfix_str(f"k={k:.4g} J/m^3: {a:.2f} deg")
        if layout is not None:  # the curve so far (each point's runs are in k<value>/)
            write_json_atomic(layout.path / "points.json",
                              {"target_deg": target,
                               "points": sorted(pts.values(), key=lambda q: q.cohesion)})
        return p

    with marks_failure(layout):
        return _search(ev, pts, lo, hi, target=target, nmax=nmax, tol=tol, layout=layout,
                       bar=bar, n_runs=lambda: n_runs)


def _no_point_measured(pts, layout) -> ConfigError:
    """The error of a calibration none of whose points gave an angle: each point, its folder
    and why."""
    rows = "; ".join(
        f"k = {p.cohesion:.4g} J/m^3"
        + (f" ({layout.path / f'k{p.cohesion:.4g}'})" if layout is not None else "")
        + f": {p.note or 'no angle'}" for p in sorted(pts.values(), key=lambda q: q.cohesion))
    return ConfigError("calibrate: no pile could be measured at any cohesion of the bracket "
                       f"({rows}). Choose a `calibrate.cohesion_bracket` on the scale of the "
                       "material's Young's modulus: SJKR pull-in scales as k^3 / E^2, so the "
                       "seed's 3.0e7-3.6e7 J/m^3 at 1e7 Pa is about 1e3-1e4 J/m^3 at the "
                       "tiny and small presets' 1e6 Pa (--set \"calibrate.cohesion_bracket=[1e3, 1e4]\")")


def _search(ev, pts, lo, hi, *, target, nmax, tol, layout, bar, n_runs) -> CalibrationResult:
    """The bracketing search of :func:`calibrate_cohesion` over ``ev(cohesion)``."""
    p_lo, p_hi = ev(lo), ev(hi)
    if not any(math.isfinite(p.angle_deg) for p in pts.values()):
        raise _no_point_measured(pts, layout)
    it = 2
    # widen until bracketed (angle assumed to rise with cohesion)
    monotonic = p_hi.angle_deg > p_lo.angle_deg
    while monotonic and it < nmax + 2 and not (p_lo.angle_deg <= target <= p_hi.angle_deg):
        if p_hi.angle_deg < target:
            lo, p_lo = hi, p_hi
            hi = hi * 1.5
            p_hi = ev(hi)
        else:
            hi, p_hi = lo, p_lo
            lo = lo / 1.5
            p_lo = ev(lo)
        it += 1
        # stop widening once the angle no longer rises with cohesion (cohesive blocks
        # break off irregularly; the curve has a maximum)
        monotonic = p_hi.angle_deg > p_lo.angle_deg
    if not monotonic:
        log.warning("calibrate: the angle does not rise with cohesion between %.4g and %.4g "
                    "J/m^3 (%.2f -> %.2f deg)", p_lo.cohesion, p_hi.cohesion, p_lo.angle_deg,
                    p_hi.angle_deg)
    bracketed = p_lo.angle_deg <= target <= p_hi.angle_deg
    side = 0
    best = min(pts.values(), key=lambda p: _miss(p, target))
    while bracketed and it < nmax + 2 and abs(best.angle_deg - target) > tol:
        f_lo, f_hi = p_lo.angle_deg - target, p_hi.angle_deg - target
        if side == -1:
            f_hi *= 0.5
        elif side == 1:
            f_lo *= 0.5
        k = lo - f_lo * (hi - lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
        # keep new points away from the bracket ends: replicate noise would otherwise
        # cluster them and fake a steep slope
        k = float(min(max(k, lo + 0.2 * (hi - lo)), hi - 0.2 * (hi - lo)))
        p = ev(k)
        it += 1
        if p.angle_deg < target:
            lo, p_lo = k, p
            side = 1
        else:
            hi, p_hi = k, p
            side = -1
        best = min(pts.values(), key=lambda q: _miss(q, target))
    if not bracketed:
        # no crossing: report the closest point, without an uncertainty
        res = CalibrationResult(cohesion=float(best.cohesion), cohesion_std=float("nan"),
                                target_deg=target, slope_deg_per_unit=float("nan"),
                                converged=bool(abs(best.angle_deg - target) <= tol), bracketed=False,
                                curve=tuple(sorted(pts.values(), key=lambda p: p.cohesion)),
                                n_runs=n_runs())
        log.warning("calibrate: target %.2f deg not bracketed; closest %.2f deg at %.4g J/m^3",
                    target, best.angle_deg, best.cohesion)
        if layout is not None:
            layout.write_results({"workflow": "calibrate", **res.to_dict()})
        bar.close()
        return res
    use = {p_lo.cohesion: p_lo, p_hi.cohesion: p_hi, best.cohesion: best}
    xs = [p.cohesion for p in use.values()]
    try:
        if len(set(xs)) < 2:
            raise ValueError("one point")
        kstar, sk, slope = inverse_linear(xs, [p.angle_deg for p in use.values()],
                                          [p.angle_std_deg for p in use.values()], target)
    except (ValueError, np.linalg.LinAlgError):
        kstar, sk, slope = best.cohesion, float("nan"), float("nan")
    # noise floor: the angle uncertainty at the crossing divided by the slope of a line
    # through every point (a local slope from two noisy points can be far too steep)
    allp = [p for p in pts.values() if math.isfinite(p.angle_deg)]
    if len({p.cohesion for p in allp}) >= 2:
        try:
            _, _, b_all = inverse_linear([p.cohesion for p in allp], [p.angle_deg for p in allp],
                                         [p.angle_std_deg for p in allp], target)
            s_a = float(np.nanmean([p.angle_std_deg for p in use.values()]))
            if b_all > 0 and math.isfinite(s_a):
                sk = max(sk, s_a / b_all) if math.isfinite(sk) else s_a / b_all
        except (ValueError, np.linalg.LinAlgError):
            pass
    res = CalibrationResult(cohesion=float(kstar), cohesion_std=float(sk), target_deg=target,
                            slope_deg_per_unit=float(slope),
                            converged=bool(abs(best.angle_deg - target) <= tol), bracketed=bracketed,
                            curve=tuple(sorted(pts.values(), key=lambda p: p.cohesion)), n_runs=n_runs())
    if layout is not None:
        layout.write_results({"workflow": "calibrate", **res.to_dict()})
    bar.close()
    return res


from .config import load_config  # noqa: E402  (doctest namespace)
