"""A fitted emulator of a run library, and a simulator that runs on it.

An :class:`Emulator` (made by :func:`~bedstruct.diagnose.emulator_fit.fit_emulator`)
holds one Gaussian process per observable component and a noise model. It predicts the
mean of a run, its own uncertainty and the run-to-run scatter at a point of the design
box (:meth:`Emulator.predict`, a :class:`Prediction`), draws seeded emulated runs
(:meth:`Emulator.sample`), and checks itself against runs of the real simulator
(:meth:`Emulator.check`, an :class:`EmulatorCheck`).

:class:`EmulatedSimulator` has the simulator interface ``sim(base, effects, seed) ->
Observations``: the emulator mean plus a seeded draw of its noise, so the diagnosis
runs on it unchanged. It refuses inputs outside the library's design box by name.

.. versionadded:: 0.1
"""

from __future__ import annotations

import json
import math
import warnings
import zlib
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import ConfigError
from .measurements import Observations
from .run_library import RunLibrary

__all__ = ["Emulator", "Prediction", "EmulatorCheck", "EmulatedSimulator"]


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


class Emulator:
    """A fitted emulator of a run library.

    Made by :func:`~bedstruct.diagnose.emulator_fit.fit_emulator`.

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
    loo : ~bedstruct.diagnose.emulator_fit.LeaveOneOut
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

    def by_observable(self, vec) -> dict[str, np.ndarray]:
        """A vector over every component (as :meth:`predict` gives) split by observable."""
        out, i = {}, 0
        for n in self.names:
            k = self.n_components[n]
            out[n] = np.asarray(vec[i:i + k], float)
            i += k
        return out

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


class EmulatedSimulator:
    """A simulator that answers from an emulator: ``sim(base, effects, seed) -> Observations``.

    Parameters
    ----------
    emulator : Emulator
        From :func:`~bedstruct.diagnose.emulator_fit.fit_emulator`.
    name : str, optional
        Label (default ``"emulator[<library's simulator>]"``).

    Notes
    -----
    A call returns the emulator mean plus a seeded draw of its noise model
    (:meth:`Emulator.sample`), ``source="emulator"``; a point outside the library's
    design box is refused (:class:`~bedstruct.errors.ConfigError` naming the parameter).

    Examples
    --------
    See :func:`~bedstruct.diagnose.emulator_fit.fit_emulator` for ``emu``; then
    ``sim = EmulatedSimulator(emu)`` and
    ``diagnose(measurements, sim, base=...)`` as with any simulator.
    """

    def __init__(self, emulator: Emulator, *, name: str | None = None):
        self.emulator = emulator
        self.name = name or f"emulator[{emulator.source or 'simulator'}]"

    @property
    def names(self) -> tuple[str, ...]:
        return self.emulator.names

    def parameter_box(self) -> dict[str, tuple[float, float]]:
        """The library's design range of each varied base parameter: the emulator's
        domain, within which a diagnosis keeps its recalibration (:func:`diagnose`)."""
        emu = self.emulator
        return {k: (float(emu.lower[i]), float(emu.upper[i])) for i, k in enumerate(emu.varied)}

    def __call__(self, base: Mapping[str, float], effects: Mapping[str, float], seed: int) -> Observations:
        return Observations(self.emulator.by_observable(self.emulator.sample(base, effects, seed)),
                            source="emulator")
