"""Fitting the emulator of a run library: one Gaussian process per component, a noise model.

:func:`fit_emulator` fits one Gaussian process per observable component of a
:class:`~bedstruct.diagnose.run_library.RunLibrary`: inputs are the varied base
parameters and the effect magnitudes, normalised to the design box (each in [0, 1]);
outputs are standardised (zero mean, unit variance over the runs). The kernel is

.. math:: k(u, u') = c\\,\\mathrm{Matern}_{5/2}(u, u'; \\ell_1, \\dots, \\ell_d)
          + \\sigma_n^2\\,\\delta_{uu'}

with one length scale per input (anisotropic: an observable that ignores an effect
gets a long length scale along it) and a white-noise term whose fitted level
:math:`\\sigma_n^2` is the run-to-run scatter of that component; every replicate run is
a training row, so the scatter is fitted, not assumed. The correlation of runs sharing
a seed (common random numbers) and of the components within a run are estimated from
the replicates' deviations from their point means, and the emulated noise reproduces
both.

Why scikit-learn: its :class:`~sklearn.gaussian_process.GaussianProcessRegressor` is
a well-kept, BSD-licensed part of the scientific Python stack with anisotropic
(ARD) Matern kernels and a :class:`~sklearn.gaussian_process.kernels.WhiteKernel`
whose level is a fitted hyperparameter; a library holds 10^2-10^3 runs, within reach
of an exact GP, so the approximate GPs of GPyTorch or GPflow (and their torch or
TensorFlow dependency) buy nothing here, and the exact kernel matrix gives the
leave-one-out residuals in closed form.

Quality is reported as **leave-one-out error in units of the predictive sigma**
(:class:`LeaveOneOut`): every design point is left out in turn (all its replicate
runs at once, so the check is of the interpolation, not of a replicate's twin), its
runs predicted from the others with the fitted hyperparameters (closed form,
Rasmussen & Williams 2006, Sec. 5.4.2), and each residual divided by the predictive
standard deviation of one run (emulator uncertainty plus run scatter). A calibrated
emulator has ``loo_rmse_sigma`` near 1 and about 95 % of the residuals within 2 sigma.

The fitted :class:`~bedstruct.diagnose.emulator.Emulator` and the simulator that runs
on it live in :mod:`bedstruct.diagnose.emulator`.

References
----------
Rasmussen, C.E., Williams, C.K.I. (2006). Gaussian Processes for Machine Learning.
MIT Press. ISBN 026218253X.

.. versionadded:: 0.1
"""

from __future__ import annotations

import hashlib
import json
import logging
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from .._json import write_json_atomic
from ..errors import ConfigError
from .emulator import Emulator, _Component
from .run_library import RunLibrary

__all__ = ["LeaveOneOut", "fit_emulator"]

log = logging.getLogger(__name__)

_EMULATOR_FILE = "emulator.json"
_FIT_VERSION = 2


@dataclass(frozen=True)
class LeaveOneOut:
    """Leave-one-point-out error of an emulator, in units of its predictive sigma.

    Attributes
    ----------
    loo_rmse_sigma : float
        Root mean square of the standardised residuals over every run and component
        (1 for a calibrated emulator).
    loo_within_2sigma : float
        Fraction of the residuals within 2 predictive sigma (0.95 for a calibrated one).
    rmse_sigma : (n,) ndarray
        The same root mean square per component (NaN where not fitted).
    z : (N, n) ndarray
        Standardised residual of each run (row) and component (NaN where the run gave
        no value or the component was not fitted).
    """

    loo_rmse_sigma: float
    loo_within_2sigma: float
    rmse_sigma: np.ndarray
    z: np.ndarray


def _kernel(d: int, nu: float):
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel
    return (ConstantKernel(1.0, (1e-3, 1e3))
            * Matern(length_scale=np.ones(d), length_scale_bounds=(1e-2, 1e2), nu=nu)
            + WhiteKernel(0.05, (1e-8, 1e1)))


def _runs_hash(lib: RunLibrary) -> str:
    doc = [lib.key, lib.point_index.tolist(), lib.seeds.tolist()]
    return hashlib.sha256(json.dumps(doc).encode()).hexdigest()[:20]


def _loo_blocks(gp, u, y, groups):
    """Leave-one-group-out standardised residuals of a fitted GP (closed form)."""
    K = gp.kernel_(u) + gp.alpha * np.eye(len(u))
    c = linalg.cho_factor(K, lower=True)
    kinv = linalg.cho_solve(c, np.eye(len(u)))
    a = kinv @ y
    z = np.full(len(u), np.nan)
    for g in np.unique(groups):
        b = np.flatnonzero(groups == g)
        kbb = kinv[np.ix_(b, b)]
        r = linalg.solve(kbb, a[b], assume_a="pos")
        cov = linalg.inv(kbb)
        z[b] = r / np.sqrt(np.maximum(np.diag(cov), 1e-300))
    return z


def _replicate_deviations(lib: RunLibrary, scale: np.ndarray):
    """Deviations of each run from its point's replicate mean (standardised), by point."""
    out = []
    for p in np.unique(lib.point_index):
        rows = np.flatnonzero(lib.point_index == p)
        if len(rows) < 2:
            continue
        y = lib.outputs[rows] / scale
        ok = np.isfinite(y)
        n_ok = ok.sum(axis=0)
        # an observable with no reading in any replicate of the point has no mean (nan)
        mean = np.where(n_ok > 0, np.where(ok, y, 0.0).sum(axis=0) / np.maximum(n_ok, 1), np.nan)
        out.append((lib.seeds[rows], y - mean))
    return out


def _seed_correlation(devs, replicates: int) -> float:
    """Correlation of two runs at different points sharing a seed (common random numbers)."""
    by_seed: dict[int, list] = {}
    ss, npts = 0.0, 0
    for seeds, d in devs:
        if len(seeds) != replicates:
            continue
        npts += 1
        d = np.where(np.isfinite(d), d, 0.0)
        ss += float(np.sum(d * d))
        for s, row in zip(seeds, d):
            by_seed.setdefault(int(s), []).append(row)
    if npts < 2 or ss <= 0:
        return 0.0
    num = sum(float(np.sum(np.sum(rows, axis=0) ** 2) - np.sum(np.asarray(rows) ** 2))
              for rows in by_seed.values())
    return float(np.clip(num / ((npts - 1) * ss), 0.0, 0.99))


def _within_run_correlation(devs, n: int) -> np.ndarray:
    """Correlation of the components within a run, from the replicate deviations.

    Components that a tenth or more of the runs could not observe are left uncorrelated;
    runs missing any of the others are left out.
    """
    if not devs:
        return np.eye(n)
    d = np.vstack([x for _, x in devs])
    dof_pts = len(devs)
    cols = np.flatnonzero(np.mean(np.isfinite(d), axis=0) >= 0.9)
    corr = np.eye(n)
    if cols.size < 2:
        return corr
    keep = np.all(np.isfinite(d[:, cols]), axis=1)
    d = d[np.ix_(keep, cols)]
    dof = len(d) - dof_pts
    if dof < cols.size + 2:
        return corr
    cov = d.T @ d / dof
    sd = np.sqrt(np.diag(cov))
    ok = sd > 0
    sub = np.eye(cols.size)
    sub[np.ix_(ok, ok)] = cov[np.ix_(ok, ok)] / np.outer(sd[ok], sd[ok])
    corr[np.ix_(cols, cols)] = sub
    w, v = np.linalg.eigh(corr)
    corr = (v * np.maximum(w, 1e-6)) @ v.T
    s = np.sqrt(np.diag(corr))
    return corr / np.outer(s, s)


def fit_emulator(library: RunLibrary, *, nu: float = 2.5, restarts: int = 0,
                 reuse: bool = True, progress: bool = False, max_fit_runs: int = 240) -> Emulator:
    """Fit the emulator of a run library (one GP per observable component).

    Parameters
    ----------
    library : RunLibrary
        From :func:`~bedstruct.diagnose.run_library.build_library` or
        :func:`~bedstruct.diagnose.run_library.load_library`.
    nu : float
        Smoothness of the Matern kernel (1.5, 2.5; ``inf`` is the squared exponential).
    restarts : int
        Further starts of the hyperparameter optimiser per component.
    reuse : bool
        Reuse the hyperparameters stored in the library folder by an earlier fit of the
        same runs with the same settings (``emulator.json``: the same ``nu`` and
        ``max_fit_runs``, and at least as many ``restarts``; then only the kernel matrices
        are factorised), and store them after a fit.
    progress : bool
        Progress bar over the components.
    max_fit_runs : int
        The hyperparameters are optimised on the runs of a seeded random subset of whole
        design points, at most this many runs (the optimiser factorises the kernel matrix
        at every step); the GP is then conditioned on every run.

    Returns
    -------
    Emulator
        With :attr:`Emulator.loo`, the leave-one-point-out error in units of the
        predictive sigma.

    Raises
    ------
    ImportError
        scikit-learn is not installed.

    Examples
    --------
    >>> import tempfile
    >>> from bedstruct.diagnose import BASE_PARAMETERS, SurrogateSimulator
    >>> from bedstruct.diagnose import measurement_from_dict, MeasurementSet
    >>> from bedstruct.diagnose import build_library, design_spec
    >>> m = measurement_from_dict({"name": "aor", "kind": "static_angle", "role": "calibrate",
    ...                            "uncertainty": 0.5, "value": 33.0})
    >>> sim = SurrogateSimulator(MeasurementSet((m,)))
    >>> spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=8, n_per_effect=8)
    >>> emu = fit_emulator(build_library(sim, spec, tempfile.mkdtemp(), progress=False))
    >>> 0.5 < emu.loo.loo_rmse_sigma < 2.0
    True
    >>> float(emu.predict({}, {}).noise_sd[0])  # the surrogate's static-angle scatter: 0.35 deg
    0.3...
    """
    from threadpoolctl import threadpool_limits
    # the kernel matrices are small (10^2-10^3): one BLAS thread is fastest, and threads
    # contend badly on a shared machine (a Cholesky of 375 runs took 0.6 s on two)
    with threadpool_limits(1):
        return _fit_emulator(library, nu=nu, restarts=restarts, reuse=reuse, progress=progress,
                             max_fit_runs=max_fit_runs)


def _hyper_subset(points: np.ndarray, max_runs: int) -> np.ndarray:
    """Runs of a seeded random subset of whole design points, at most ``max_runs`` of them."""
    if len(points) <= max_runs:
        return np.arange(len(points))
    order = np.random.default_rng(0).permutation(np.unique(points))
    keep, n = [], 0
    for p in order:
        k = int(np.sum(points == p))
        if n + k > max_runs:
            continue
        keep.append(p)
        n += k
    return np.flatnonzero(np.isin(points, keep))


def _fit_emulator(library: RunLibrary, *, nu: float = 2.5, restarts: int = 0,
                  reuse: bool = True, progress: bool = False,
                  max_fit_runs: int = 240) -> Emulator:
    try:
        from sklearn.gaussian_process import GaussianProcessRegressor
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError("the run-library emulator needs scikit-learn (pip install scikit-learn)") \
            from exc
    lib = library
    if lib.n_runs == 0:
        raise ConfigError(f"run library {lib.path}: no runs to fit")
    lo, hi = lib.spec.box
    u_all = (lib.inputs - lo) / (hi - lo)
    d = u_all.shape[1]
    stored = {}
    cache = lib.path / _EMULATOR_FILE
    rh = _runs_hash(lib)
    if reuse and cache.is_file():
        try:
            doc = json.loads(cache.read_text())
            if (doc.get("runs") == rh and doc.get("nu") == nu and doc.get("version") == _FIT_VERSION
                    and doc.get("max_fit_runs") == max_fit_runs
                    and int(doc.get("restarts", 0)) >= int(restarts)):
                stored = {int(k): np.asarray(v, float) for k, v in doc["theta"].items()}
        except (OSError, ValueError, KeyError):
            stored = {}
    n = lib.outputs.shape[1]
    comps, zs, thetas = [], np.full_like(lib.outputs, np.nan), {}
    scale_all = np.ones(n)
    it = range(n)
    if progress:
        from tqdm import tqdm
        it = tqdm(it, desc="emulator", unit="component")
    for j in it:
        y = lib.outputs[:, j]
        ok = np.isfinite(y)
        mu = float(np.mean(y[ok])) if ok.any() else float("nan")
        sc = float(np.std(y[ok])) if ok.sum() > 1 else 0.0
        if sc == 0.0 or len(np.unique(lib.point_index[ok])) < 3:
            if ok.any() and sc == 0.0:
                comps.append(_Component(None, mu, 1.0, 0.0))
            else:
                log.warning("emulator: component %d has too few runs with a value; predicted "
                            "as NaN", j)
                comps.append(_Component(None, float("nan"), 1.0, 0.0))
            continue
        scale_all[j] = sc
        u, ys = u_all[ok], (y[ok] - mu) / sc
        kern = _kernel(d, nu)
        theta = stored.get(j)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # hyperparameters at their bounds: noted by LOO
            if theta is None or len(theta) != len(kern.theta):
                sub = _hyper_subset(lib.point_index[ok], max_fit_runs)
                opt = GaussianProcessRegressor(kern, alpha=1e-10,
                                               n_restarts_optimizer=int(restarts), random_state=0)
                opt.fit(u[sub], ys[sub])
                theta = opt.kernel_.theta
            gp = GaussianProcessRegressor(kern.clone_with_theta(theta), optimizer=None, alpha=1e-10)
            gp.fit(u, ys)
        thetas[j] = gp.kernel_.theta.tolist()
        noise_var = float(gp.kernel_.k2.noise_level)
        comps.append(_Component(gp, mu, sc, noise_var))
        zs[np.flatnonzero(ok), j] = _loo_blocks(gp, u, ys, lib.point_index[ok])
    finite = zs[np.isfinite(zs)]
    with np.errstate(invalid="ignore"):
        per = np.sqrt(np.nanmean(zs ** 2, axis=0)) if len(zs) else np.zeros(n)
    loo = LeaveOneOut(float(np.sqrt(np.mean(finite ** 2))) if finite.size else float("nan"),
                      float(np.mean(np.abs(finite) <= 2.0)) if finite.size else float("nan"),
                      per, zs)
    devs = _replicate_deviations(lib, scale_all)
    emu = Emulator(lib, comps, loo, _seed_correlation(devs, lib.spec.replicates),
                   _within_run_correlation(devs, n))
    if reuse and thetas and set(thetas) != set(stored):
        try:
            write_json_atomic(cache, {"version": _FIT_VERSION, "key": lib.key, "runs": rh, "nu": nu,
                                      "max_fit_runs": max_fit_runs, "restarts": int(restarts),
                                      "theta": {str(k): v for k, v in thetas.items()}})
        except OSError:   # a read-only library is still usable
            log.info("emulator: could not store hyperparameters in %s", cache)
    return emu
