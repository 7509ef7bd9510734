"""Fingerprints: how every observable changes per effect, net of what recalibration absorbs.

For each effect the simulator is run at two magnitudes (half and full top of the
prior) with the same replicate seeds as the base runs; the mean change per
component gives a quadratic response through the origin: a straight line when the
two magnitudes agree with linearity within noise, else a monotone interpolation
(refined by further runs at fitted magnitudes during the attribution). The sensitivities of the observables to the recalibrated base
parameters (e.g. the cohesion energy density) span the *nuisance* directions: a
gap along them is closed by recalibrating, not by an effect. Identifiability is
judged on the calibration observables, whitened by the combined noise, after
projecting those directions out.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy import stats

from ..errors import ConfigError
from .catalogue import Effect
from .measurements import MeasurementSet, Observations

__all__ = ["Simulator", "simulate_replicates", "Fingerprint", "FingerprintSet",
           "compute_fingerprints", "nuisance_projector"]

#: The simulator interface: ``simulator(base, effects, seed) -> Observations``.
Simulator = Callable[[Mapping[str, float], Mapping[str, float], int], Observations]


def simulate_replicates(simulator: Simulator, base, effects, seeds, names) -> np.ndarray:
    """Run ``simulator`` once per seed and stack the components of ``names``.

    Returns
    -------
    (R, n) ndarray
    """
    rows = []
    for sd in seeds:
        obs = simulator(dict(base), dict(effects), int(sd))
        if not isinstance(obs, Observations):
            raise TypeError(f"the simulator must return an Observations object; got {type(obs).__name__}")
        rows.append(obs.vector(names))
    return np.asarray(rows)


def nuisance_projector(sensitivities_w) -> np.ndarray:
    """Orthogonal projector removing the span of whitened nuisance sensitivities.

    Parameters
    ----------
    sensitivities_w : (n, p) array_like
        Whitened sensitivities (columns); p may be 0.

    Returns
    -------
    (n, n) ndarray
        ``I - S (S^T S)^+ S^T``.

    Examples
    --------
    >>> P = nuisance_projector([[1.0], [0.0]])
    >>> P @ np.array([3.0, 4.0])
    array([0., 4.])
    """
    S = np.asarray(sensitivities_w, dtype=float)
    n = S.shape[0]
    if S.ndim != 2 or S.shape[1] == 0:
        return np.eye(n)
    Q, r, _ = np.linalg.svd(S, full_matrices=False)
    keep = r > 1e-12 * max(r.max(), 1e-300)
    Q = Q[:, keep]
    return np.eye(n) - Q @ Q.T


@dataclass(frozen=True)
class Fingerprint:
    """The response of all design components to one effect.

    Attributes
    ----------
    effect : Effect
    magnitudes : (2,) ndarray
        The simulated magnitudes ``(m1, m2)``.
    delta : (2, n) ndarray
        Mean change against the base runs (same seeds), canonical units.
    delta_se : (2, n) ndarray
        Standard error of ``delta`` from the replicate scatter of the paired differences.
    nodes : (k,) ndarray
        Magnitudes with a simulated response, 0 included (refinement adds nodes).
    responses : (k, n) ndarray
        Mean change at each node.
    linear : bool
        True when the response is linear within its estimation noise; the
        prediction is then the least-squares line through the origin, otherwise
        a monotone piecewise-cubic (PCHIP) interpolation of the nodes, extended
        linearly beyond them.
    signal : float
        Whitened, nuisance-projected norm on the calibration components at ``m2``
        (``sqrt`` of the chi-square the effect at the prior top would add).
    noise : float
        Expected norm of the fingerprint's own estimation noise (same metric).
    identifiable : bool
        ``signal**2 > threshold + noise**2``: detectable at the prior top with the
        calibration observables.
    confounded_with : tuple of str
        Effects whose projected fingerprints are nearly parallel (|cos| > 0.98).
    identify_with : tuple of str
        Non-calibration observables (held-out or candidate) where the effect
        shows most, by whitened change at ``m2`` (changes above 2 sigma and above
        twice their own estimation noise; empty: the catalogue's suggestions apply).
    """

    effect: Effect
    magnitudes: np.ndarray
    delta: np.ndarray
    delta_se: np.ndarray
    nodes: np.ndarray
    responses: np.ndarray
    linear: bool
    signal: float = 0.0
    noise: float = 0.0
    identifiable: bool = True
    confounded_with: tuple[str, ...] = ()
    identify_with: tuple[str, ...] = ()

    def __post_init__(self):
        order = np.argsort(self.nodes)
        nodes = np.asarray(self.nodes, float)[order]
        resp = np.asarray(self.responses, float)[order]
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "responses", resp)
        nz = nodes != 0
        slope = (nodes[nz] @ resp[nz]) / float(nodes[nz] @ nodes[nz]) if nz.any() else resp[0] * 0
        object.__setattr__(self, "_slope", slope)
        if not self.linear:
            from scipy.interpolate import PchipInterpolator
            f = PchipInterpolator(nodes, resp, axis=0, extrapolate=False)
            object.__setattr__(self, "_f", f)
            object.__setattr__(self, "_df", f.derivative())

    @property
    def name(self) -> str:
        return self.effect.name

    @property
    def slope(self) -> np.ndarray:
        """Least-squares response per unit magnitude (line through the origin)."""
        return self._slope

    def predict(self, a: float) -> np.ndarray:
        """Predicted change of every component at magnitude ``a``."""
        a = float(a)
        if self.linear:
            return self._slope * a
        lo, hi = self.nodes[0], self.nodes[-1]
        if a < lo:
            return self._f(lo) + self._df(lo) * (a - lo)
        if a > hi:
            return self._f(hi) + self._df(hi) * (a - hi)
        return self._f(a)

    def derivative(self, a: float) -> np.ndarray:
        """d(prediction)/d(magnitude) at ``a``."""
        a = float(a)
        if self.linear:
            return self._slope
        return self._df(min(max(a, self.nodes[0]), self.nodes[-1]))

    def with_node(self, a: float, response) -> "Fingerprint":
        """A copy with a simulated response at magnitude ``a`` added (non-linear interpolation)."""
        from dataclasses import replace
        nodes = np.append(self.nodes, float(a))
        resp = np.vstack([self.responses, np.asarray(response, float)[None]])
        return replace(self, nodes=nodes, responses=resp, linear=False)

    def nonlinearity(self) -> float:
        """Relative deviation at ``m1`` from the straight line through 0 and ``m2`` (0 if linear)."""
        m1, m2 = self.magnitudes
        line = self.delta[1] * (m1 / m2)
        den = np.linalg.norm(line)
        return float(np.linalg.norm(self.delta[0] - line) / den) if den > 0 else 0.0


@dataclass(frozen=True)
class FingerprintSet:
    """Everything the diagnosis simulates once for a design: base runs, nuisance, fingerprints.

    Attributes
    ----------
    design : MeasurementSet
        Measured plus candidate observables, in row order.
    names : tuple of str
        Observable names present in the simulator output (row order source).
    rows_calibrate, rows_validate, rows_candidate : (n,) ndarray of bool
        Component masks by role.
    base : dict
        Base parameters.
    seeds : tuple of int
        Replicate seeds shared by all runs.
    base_samples : (R, n) ndarray
        Replicates at the base parameters.
    sim_var : (n,) ndarray
        Pooled replicate variance of one run (over all parameter points).
    sigma_meas : (n,) ndarray
        Measurement (or stated candidate) standard deviations.
    nuisance : tuple of str
        Recalibrated base parameters.
    sensitivities : (n, p) ndarray
        d(observable)/d(parameter), per unit of each parameter.
    fingerprints : tuple of Fingerprint
    threshold : float
        Chi-square increase an effect needs to be selected (Bonferroni over effects).
    """

    design: MeasurementSet
    names: tuple[str, ...]
    rows_calibrate: np.ndarray
    rows_validate: np.ndarray
    rows_candidate: np.ndarray
    base: dict
    seeds: tuple[int, ...]
    base_samples: np.ndarray
    sim_var: np.ndarray
    sigma_meas: np.ndarray
    nuisance: tuple[str, ...]
    sensitivities: np.ndarray
    fingerprints: tuple[Fingerprint, ...]
    threshold: float
    alpha: float = 0.05
    simulator_name: str = ""
    n_runs: int = 0
    meta: dict = field(default_factory=dict)

    @property
    def n_replicates(self) -> int:
        return self.base_samples.shape[0]

    @property
    def sigma(self) -> np.ndarray:
        """Combined noise of ``real - mean(base runs)`` per component."""
        return np.sqrt(self.sigma_meas ** 2 + self.sim_var / self.n_replicates)

    def __getitem__(self, name: str) -> Fingerprint:
        for f in self.fingerprints:
            if f.name == name:
                return f
        raise KeyError(name)

    @property
    def effect_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fingerprints)

    def subset(self, names: Sequence[str]) -> "FingerprintSet":
        """The same set restricted to the effects ``names`` (order kept)."""
        from dataclasses import replace
        keep = tuple(f for f in self.fingerprints if f.name in set(names))
        return replace(self, fingerprints=keep)

    def table(self) -> list[dict]:
        """One row per effect: signal, noise, identifiability and what would identify it."""
        return [{"effect": f.name, "signal_sigma": f.signal, "noise_sigma": f.noise,
                 "identifiable": f.identifiable, "nonlinearity": f.nonlinearity(),
                 "confounded_with": list(f.confounded_with),
                 "identify_with": list(f.identify_with)} for f in self.fingerprints]


def _design_sigma(design: MeasurementSet, names) -> np.ndarray:
    return np.concatenate([design[n].uncertainty for n in names])


def compute_fingerprints(simulator: Simulator, design: MeasurementSet, base: Mapping[str, float],
                         effects: Sequence[Effect], *, nuisance: Sequence[str] = ("cohesion_energy_density",),
                         rel_step: float = 0.05, replicates: int = 4, seed: int = 0,
                         alpha: float = 0.05, simulator_name: str = "",
                         progress: bool = False) -> FingerprintSet:
    """Simulate base, nuisance and effect runs and build the fingerprints.

    Parameters
    ----------
    simulator : callable
        ``simulator(base, effects, seed) -> Observations`` covering ``design``.
    design : MeasurementSet
        Observables (calibrate/validate/candidate). Measured observables missing
        from the simulator output raise ConfigError; candidates it cannot produce
        are dropped.
    base : mapping
        Base parameters (SI).
    effects : sequence of Effect
        The catalogue to fingerprint.
    nuisance : sequence of str
        Base parameters that recalibration may change.
    rel_step : float
        Relative finite-difference step of the nuisance sensitivities.
    replicates : int
        Seeds per parameter point (>= 2).
    seed : int
        First replicate seed; seeds are ``seed, seed+1, ...``.
    alpha : float
        Family-wise level; the selection threshold is the chi-square(1) quantile
        at ``alpha / n_effects``.

    Returns
    -------
    FingerprintSet
    """
    if replicates < 2:
        raise ConfigError(f"replicates: need >= 2 replicate seeds; got {replicates}")
    base = dict(base)
    for p in nuisance:
        if p not in base:
            raise ConfigError(f"recalibrate: parameter {p!r} is not among the base parameters "
                              f"{sorted(base)}")
    seeds = tuple(int(seed) + i for i in range(replicates))
    probe = simulator(dict(base), {}, seeds[0])
    names = []
    for m in design:
        if m.name in probe:
            if len(probe[m.name]) != m.n_components:
                raise ConfigError(f"observable {m.name!r}: simulator gives {len(probe[m.name])} "
                                  f"components, the design {m.n_components}")
            names.append(m.name)
        elif m.role != "candidate":
            raise ConfigError(f"observable {m.name!r}: the simulator does not produce it "
                              f"(it produces {sorted(probe.names)})")
    design = design.__class__(tuple(design[n] for n in names), design.title, design.source,
                              design.path, design.notes)
    roles = design.roles()
    rows_cal, rows_val, rows_cand = roles == "calibrate", roles == "validate", roles == "candidate"
    if not rows_cal.any():
        raise ConfigError("measurements: no observable has role 'calibrate'; the attribution is "
                          "fitted on calibration observables only")
    sigma_meas = _design_sigma(design, names)

    def run(params, eff):
        return simulate_replicates(simulator, params, eff, seeds, names)

    progress_bar = None
    if progress:
        from tqdm import tqdm
        progress_bar = tqdm(total=1 + len(nuisance) + 2 * len(effects), desc="fingerprints")
    n_runs = 0
    base_s = run(base, {})
    n_runs += replicates
    resid_sq = [base_s - base_s.mean(axis=0)]
    if progress_bar:
        progress_bar.update()

    sens = np.zeros((base_s.shape[1], len(nuisance)))
    for j, p in enumerate(nuisance):
        h = rel_step * abs(base[p]) if base[p] != 0 else rel_step
        plus = dict(base)
        plus[p] = base[p] + h
        sp = run(plus, {})
        n_runs += replicates
        resid_sq.append(sp - sp.mean(axis=0))
        sens[:, j] = (sp - base_s).mean(axis=0) / h
        if progress_bar:
            progress_bar.update()

    raw = []
    for e in effects:
        m1, m2 = e.reference_magnitudes
        deltas, ses = [], []
        for m in (m1, m2):
            se = run(base, {e.name: m})
            n_runs += replicates
            resid_sq.append(se - se.mean(axis=0))
            d = se - base_s
            deltas.append(d.mean(axis=0))
            ses.append(d.std(axis=0, ddof=1) / math.sqrt(replicates))
            if progress_bar:
                progress_bar.update()
        D, SE = np.asarray(deltas), np.asarray(ses)
        # Keep the quadratic term only where the two magnitudes disagree with a linear
        # response beyond the fingerprints' own estimation noise (else it fits noise).
        dev = D[1] / m2 - D[0] / m1
        se_dev = np.sqrt((SE[1] / m2) ** 2 + (SE[0] / m1) ** 2)
        ok = se_dev > 0
        if ok.any():
            curv_chi2 = float(np.sum((dev[ok] / se_dev[ok]) ** 2))
            curved = curv_chi2 > stats.chi2.isf(0.01, int(ok.sum())) or (~ok & (dev != 0)).any()
        else:
            curved = bool(np.any(dev != 0))
        raw.append((e, np.array([m1, m2]), D, SE, bool(curved)))
    if progress_bar:
        progress_bar.close()

    pooled = np.concatenate(resid_sq, axis=0)
    dof = sum(r.shape[0] - 1 for r in resid_sq)
    sim_var = np.sum(pooled ** 2, axis=0) / dof

    sigma = np.sqrt(sigma_meas ** 2 + sim_var / replicates)
    cal = rows_cal
    Sw = sens[cal] / sigma[cal, None]
    P = nuisance_projector(Sw)
    n_eff = max(len(effects), 1)
    threshold = float(stats.chi2.isf(alpha / n_eff, 1))
    projected = []
    for e, mags, D, SE, curved in raw:
        projected.append(P @ (D[1][cal] / sigma[cal]))

    fps = []
    noncal = ~cal
    comp_names = design.component_names()
    for k, (e, mags, D, SE, curved) in enumerate(raw):
        f = projected[k]
        signal = float(np.linalg.norm(f))
        noise = float(np.sqrt(np.sum((SE[1][cal] / sigma[cal]) ** 2)))
        identifiable = signal ** 2 > threshold + noise ** 2
        conf = []
        for j, other in enumerate(projected):
            if j == k:
                continue
            den = np.linalg.norm(f) * np.linalg.norm(other)
            if den > 0 and abs(f @ other) / den > 0.98:
                conf.append(raw[j][0].name)
        ident = []
        if noncal.any():
            # a change of more than 2 sigma that is also beyond twice its own estimation
            # noise (a noisy fingerprint must not name a measurement by chance)
            w = np.abs(D[1][noncal]) / sigma[noncal]
            real = np.abs(D[1][noncal]) > 2.0 * SE[1][noncal]
            order = np.argsort(-w)
            seen = []
            for i in order:
                nm = str(comp_names[noncal][i])
                if w[i] > 2.0 and real[i] and nm not in seen:
                    seen.append(nm)
                if len(seen) == 3:
                    break
            ident = seen
        nodes = np.array([0.0, mags[0], mags[1]])
        resp = np.vstack([np.zeros(D.shape[1]), D])
        fps.append(Fingerprint(e, mags, D, SE, nodes, resp, not curved, signal, noise,
                               bool(identifiable), tuple(conf), tuple(ident)))
    return FingerprintSet(design, tuple(names), rows_cal, rows_val, rows_cand, base, seeds, base_s,
                          sim_var, sigma_meas, tuple(nuisance), sens, tuple(fps), threshold, alpha,
                          simulator_name, n_runs)
