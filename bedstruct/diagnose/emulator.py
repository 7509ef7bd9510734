"""An emulator with a noise model over a run library, and a simulator that runs on it.

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

:class:`EmulatedSimulator` has the simulator interface ``sim(base, effects, seed) ->
Observations``: the emulator mean plus a seeded draw of its noise, so the diagnosis
runs on it unchanged. It refuses inputs outside the library's design box by name.

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
import math
import warnings
import zlib
from dataclasses import dataclass
from typing import Mapping

import numpy as np
from scipy import linalg

from .._json import write_json_atomic
from ..errors import ConfigError
from .measurements import Observations
from .run_library import RunLibrary

__all__ = ["Emulator", "LeaveOneOut", "Prediction", "EmulatorCheck", "fit_emulator",
           "EmulatedSimulator"]

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


@dataclass(frozen=True)
class Prediction:
    """Emulator prediction at one parameter point (physical units of each component).

    Attributes
    ----------
    mean : (n,) ndarray
        Predicted mean of a run.
    sd : (n,) ndarray
        Standard deviation of that mean (the emulator's own uncertainty).
    noise_sd : (n,) ndarray
        Run-to-run standard deviation (the fitted white noise).
    """

    mean: np.ndarray
    sd: np.ndarray
    noise_sd: np.ndarray

    @property
    def total_sd(self) -> np.ndarray:
        """Predictive standard deviation of one run: ``sqrt(sd**2 + noise_sd**2)``."""
        return np.sqrt(self.sd ** 2 + self.noise_sd ** 2)


@dataclass(frozen=True)
class EmulatorCheck:
    """How well the emulator predicted runs of the real simulator at one point.

    The emulator predicts each component before the runs are made; each run's value is
    then compared with that prediction, and so is the mean of the runs, whose predictive
    standard deviation is ``sqrt(sd**2 + noise_sd**2 / R)`` over ``R`` runs.

    Attributes
    ----------
    z : (R, n) ndarray
        ``(run - mean) / total_sd`` per run and component.
    rmse_sigma : float
        Root mean square of ``z_mean`` over the components (about 1 when the emulator
        predicted the runs; NaN when no component was observed).
    within_2sigma : float
        Fraction of the components with ``|z_mean| <= 2`` (about 0.95 when calibrated).
    mean_z : (n,) ndarray
        Mean of ``z`` over the runs.
    predicted : (n,) ndarray
        The emulator's predicted mean of the runs (each component's unit).
    predicted_sd : (n,) ndarray
        Its predictive standard deviation for the mean of the runs that gave a value.
    observed : (n,) ndarray
        Mean of the runs (NaN where no run gave a value).
    z_mean : (n,) ndarray
        ``(observed - predicted) / predicted_sd``: the standardised error per component.
    n_runs : int
        Runs compared.
    """

    z: np.ndarray
    rmse_sigma: float
    within_2sigma: float
    mean_z: np.ndarray
    predicted: np.ndarray = None
    predicted_sd: np.ndarray = None
    observed: np.ndarray = None
    z_mean: np.ndarray = None
    n_runs: int = 0


def _kernel(d: int, nu: float):
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel
    return (ConstantKernel(1.0, (1e-3, 1e3))
            * Matern(length_scale=np.ones(d), length_scale_bounds=(1e-2, 1e2), nu=nu)
            + WhiteKernel(0.05, (1e-8, 1e1)))


def _runs_hash(lib: RunLibrary) -> str:
    doc = [lib.key, lib.point_index.tolist(), lib.seeds.tolist()]
    return hashlib.sha256(json.dumps(doc).encode()).hexdigest()[:20]


class _Component:
    """One component's GP (or a constant where the library cannot fit one)."""

    def __init__(self, gp, mu, scale, noise_var):
        self.gp, self.mu, self.scale, self.noise_var = gp, mu, scale, noise_var

    def predict(self, u: np.ndarray):
        """Mean, latent sd and noise sd (physical units) at normalised inputs ``u`` (k, d)."""
        if self.gp is None:
            k = len(u)
            return (np.full(k, self.mu), np.zeros(k), np.full(k, math.sqrt(self.noise_var)) * self.scale)
        m, s = self.gp.predict(u, return_std=True)
        latent = np.sqrt(np.maximum(s ** 2 - self.noise_var, 0.0))
        return self.mu + self.scale * m, self.scale * latent, np.full(len(u), self.scale * math.sqrt(self.noise_var))


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
        out.append((lib.seeds[rows], y - np.nanmean(y, axis=0)))
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


class Emulator:
    """A fitted emulator of a run library (made by :func:`fit_emulator`).

    Attributes
    ----------
    input_names : tuple of str
        Varied base parameters, then effect magnitudes.
    lower, upper : (d,) ndarray
        Corners of the design box (SI / catalogue units).
    fixed : dict
        Base parameters the design did not vary, at their values.
    names : tuple of str
        Observable names (component order).
    n_components : dict of str to int
    loo : LeaveOneOut
        Leave-one-point-out error in units of the predictive sigma.
    seed_correlation : float
        Estimated correlation of runs sharing a seed at different points.
    noise_correlation : (n, n) ndarray
        Estimated correlation of the components within one run.
    key : str
        The library key.
    n_runs : int
        Runs fitted.
    """

    def __init__(self, lib: RunLibrary, comps, loo, seed_corr, noise_corr):
        spec = lib.spec
        self.input_names = spec.input_names
        self.varied = spec.varied
        self.effect_names = tuple(spec.effects)
        self.lower, self.upper = spec.box
        self.fixed = {k: v for k, v in spec.base.items() if k not in spec.ranges}
        self.base = dict(spec.base)
        self.names = lib.names
        self.n_components = dict(lib.n_components)
        self.key = lib.key
        self.source = lib.source
        self.n_runs = lib.n_runs
        self._comps = comps
        self.loo = loo
        self.seed_correlation = seed_corr
        self.noise_correlation = noise_corr
        self._chol = np.linalg.cholesky(noise_corr)
        self._memo: dict[str, Prediction] = {}

    # ------------------------------------------------------------------ inputs
    def check_inputs(self, base: Mapping[str, float], effects: Mapping[str, float]) -> dict:
        """The full base of a call (defaults filled in), refusing points outside the box.

        Raises
        ------
        ConfigError
            A parameter or effect the library does not know, a varied parameter or an
            effect magnitude outside the design box, a fixed parameter at another value.
        """
        unknown = set(base) - set(self.base)
        if unknown:
            raise ConfigError(f"base: parameter {sorted(unknown)[0]!r} is not in the run library "
                              f"(it knows {sorted(self.base)})")
        b = dict(self.base)
        b.update({k: float(v) for k, v in base.items()})
        for k, v in self.fixed.items():
            if not math.isclose(b[k], v, rel_tol=1e-9, abs_tol=1e-12):
                raise ConfigError(f"base: {k} = {b[k]:.6g} differs from the run library's value "
                                  f"{v:.6g} (its design does not vary {k}); rebuild the library "
                                  f"with {k} in `vary`")
        for name, val, i in [(k, b[k], j) for j, k in enumerate(self.varied)] + \
                [(e, float(effects.get(e, 0.0)), len(self.varied) + j)
                 for j, e in enumerate(self.effect_names)]:
            lo, hi = self.lower[i], self.upper[i]
            tol = 1e-9 * (hi - lo)
            if not (lo - tol <= val <= hi + tol):
                what = "base" if i < len(self.varied) else "effects"
                raise ConfigError(f"{what}: {name} = {val:.6g} lies outside the run library's design "
                                  f"box [{lo:.6g}, {hi:.6g}]; the emulator does not extrapolate "
                                  f"(widen the design and rebuild the library)")
        extra = set(effects) - set(self.effect_names)
        if extra and any(float(effects[e]) != 0.0 for e in extra):
            raise ConfigError(f"effects: effect {sorted(extra)[0]!r} is not in the run library "
                              f"(it holds {list(self.effect_names)})")
        return b

    def _u(self, b, effects) -> np.ndarray:
        x = [b[k] for k in self.varied] + [float(effects.get(e, 0.0)) for e in self.effect_names]
        return (np.asarray(x, float) - self.lower) / (self.upper - self.lower)

    # ------------------------------------------------------------------ prediction
    def predict(self, base: Mapping[str, float], effects: Mapping[str, float]) -> Prediction:
        """Predicted mean, its uncertainty and the run scatter at one point.

        Several effects on at once are composed additively around the base point,
        ``f(b, e1 + e2) = f(b, e1) + f(b, e2) - f(b, 0)`` (the library holds one effect
        at a time; the diagnosis' fit makes the same assumption, and the confirming
        rerun of the real simulator tests it).

        Parameters
        ----------
        base : mapping of str to float
            Base parameters (SI; missing ones take the library's base values).
        effects : mapping of str to float
            Effect magnitudes (catalogue units).

        Returns
        -------
        Prediction
        """
        b = self.check_inputs(base, effects)
        on = {e: float(a) for e, a in effects.items() if float(a) != 0.0}
        key = json.dumps([b, on], sort_keys=True)
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        if len(on) <= 1:
            pts = [self._u(b, on)]
        else:
            pts = [self._u(b, {})] + [self._u(b, {e: a}) for e, a in on.items()]
        u = np.asarray(pts)
        mean, sd, noise = [], [], []
        for c in self._comps:
            m, s, nz = c.predict(u)
            if len(on) <= 1:
                mean.append(m[0])
                sd.append(s[0])
            else:
                mean.append(m[0] + np.sum(m[1:] - m[0]))
                sd.append(math.sqrt(float(np.sum(s[1:] ** 2) + (len(on) - 1) ** 2 * s[0] ** 2)))
            noise.append(nz[0])
        out = Prediction(np.asarray(mean), np.asarray(sd), np.asarray(noise))
        if len(self._memo) < 100_000:
            self._memo[key] = out
        return out

    def sample(self, base, effects, seed: int) -> np.ndarray:
        """One emulated run: the mean plus a seeded draw of the run-to-run noise.

        The draw is partly common to every point of one seed (correlation
        :attr:`seed_correlation`, as replicate runs sharing a seed are) and correlated
        between components as :attr:`noise_correlation` says.
        """
        p = self.predict(base, effects)
        n = len(p.mean)
        common = np.random.default_rng([int(seed), 0x5EED]).standard_normal(n)
        b = self.check_inputs(base, effects)
        tag = zlib.crc32(json.dumps([b, {e: float(a) for e, a in effects.items()
                                         if float(a) != 0.0}], sort_keys=True).encode())
        own = np.random.default_rng([int(seed), tag, 7]).standard_normal(n)
        c = self.seed_correlation
        xi = math.sqrt(c) * common + math.sqrt(1.0 - c) * own
        return p.mean + p.noise_sd * (self._chol @ xi)

    def check(self, runs, base: Mapping[str, float], effects: Mapping[str, float]) -> EmulatorCheck:
        """How well the emulator predicts runs of the real simulator at one point.

        Parameters
        ----------
        runs : sequence of Observations or (R, n) array_like
            Real-simulator runs at ``base``, ``effects`` (e.g. the diagnosis' confirming
            rerun).
        base, effects : mapping
            The point.

        Returns
        -------
        EmulatorCheck
        """
        p = self.predict(base, effects)   # the prediction, made before the runs are read
        rows = [r.vector(self.names) if isinstance(r, Observations) else np.asarray(r, float)
                for r in runs]
        y = np.atleast_2d(np.asarray(rows, float))
        if y.shape[1] != len(p.mean):
            raise ValueError(f"check: runs have {y.shape[1]} components; the emulator predicts "
                             f"{len(p.mean)} ({', '.join(self.names)})")
        ok = np.isfinite(y)
        n = ok.sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            z = (y - p.mean) / p.total_sd
            observed = np.where(n > 0, np.where(ok, y, 0.0).sum(axis=0) / np.maximum(n, 1), np.nan)
            pred_sd = np.sqrt(p.sd ** 2 + p.noise_sd ** 2 / np.maximum(n, 1))
            z_mean = (observed - p.mean) / pred_sd
        f = z_mean[np.isfinite(z_mean)]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # a component no run observed
            mean_z = np.nanmean(z, axis=0) if len(z) else np.zeros(0)
        return EmulatorCheck(z, float(np.sqrt(np.mean(f ** 2))) if f.size else float("nan"),
                             float(np.mean(np.abs(f) <= 2.0)) if f.size else float("nan"),
                             mean_z, p.mean, pred_sd, observed, z_mean, int(len(y)))


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
        same runs (``emulator.json``; then only the kernel matrices are factorised), and
        store them after a fit.
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
                    and doc.get("max_fit_runs") == max_fit_runs):
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
                                      "max_fit_runs": max_fit_runs,
                                      "theta": {str(k): v for k, v in thetas.items()}})
        except OSError:   # a read-only library is still usable
            log.info("emulator: could not store hyperparameters in %s", cache)
    return emu


class EmulatedSimulator:
    """A simulator that answers from an emulator: ``sim(base, effects, seed) -> Observations``.

    Parameters
    ----------
    emulator : Emulator
        From :func:`fit_emulator`.
    name : str, optional
        Label (default ``"emulator[<library's simulator>]"``).

    Notes
    -----
    A call returns the emulator mean plus a seeded draw of its noise model
    (:meth:`Emulator.sample`), ``source="emulator"``; a point outside the library's
    design box is refused (:class:`~bedstruct.errors.ConfigError` naming the parameter).

    Examples
    --------
    See :func:`fit_emulator` for ``emu``; then ``sim = EmulatedSimulator(emu)`` and
    ``diagnose(measurements, sim, base=...)`` as with any simulator.
    """

    def __init__(self, emulator: Emulator, *, name: str | None = None):
        self.emulator = emulator
        self.name = name or f"emulator[{emulator.source or 'simulator'}]"

    @property
    def names(self) -> tuple[str, ...]:
        return self.emulator.names

    def __call__(self, base: Mapping[str, float], effects: Mapping[str, float], seed: int) -> Observations:
        y = self.emulator.sample(base, effects, seed)
        out, i = {}, 0
        for n in self.emulator.names:
            k = self.emulator.n_components[n]
            out[n] = y[i:i + k]
            i += k
        return Observations(out, source="emulator")
