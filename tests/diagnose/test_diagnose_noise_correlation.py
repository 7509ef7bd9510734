"""Components read from one run: generalised least squares instead of counting twice.

The x5 dynamic angle's early and steady windows at the tiny engine preset come from one short
stroke and move together from run to run (r = 0.95). Treated as independent, one deviation
of that run is counted twice: a null twin's gap test rejects too often and an effect that
moves both readings looks twice as certain as it is.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from bedstruct.diagnose import Observations, compute_fingerprints, where
from bedstruct.diagnose.attribution import fit_model
from bedstruct.diagnose.confirm import gap_size, p_fit_z
from bedstruct.diagnose.noise_correlation import (conservative_correlation, correlation_matrix,
                                                  quadratic_form)
from diagnose_helpers import ToySimulator, toy_design, toy_effect

N = 12                                   # o0..o8 calibrate, o9..o11 held out
PAIRS = [(0, 1), (2, 3), (4, 5), (6, 7)]  # each pair is read from one run
SENS = {"k": np.linspace(1.0, 2.0, N)}
RESP = {"A": np.r_[5, 5, -4, 3, 4, -4, 0, 0, 2, 3, -3, 0] * 1.0}


def _pair_noise(rng_or_seed, n=N):
    """Unit noise in which each pair of PAIRS shares one deviation (plus a 5 % own part)."""
    rng = np.random.default_rng(rng_or_seed)
    e = rng.standard_normal(n)
    for i, j in PAIRS:
        e[j] = (e[i] + 0.05 * e[j]) / np.sqrt(1.0 + 0.05 ** 2)
    return e


class _PairedReadings(ToySimulator):
    def __call__(self, base, effects, seed):
        obs = super().__call__(base, effects, seed)
        names = [m.name for m in self.design]
        y = obs.vector(names)
        m = float(effects.get("A", 0.0))
        y = y + _pair_noise([int(seed), 5, int(round(1e6 * m))])
        return Observations({n: [v] for n, v in zip(names, y)}, source="toy")


@pytest.fixture(scope="module")
def setup():
    design = toy_design(N, n_validate=3)
    sim = _PairedReadings(design, sens=SENS, effects=RESP, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=6, alpha=0.01)
    return design, sim, fps


def test_the_pairs_are_found_and_enter_at_their_lower_confidence_bound(setup):
    _, _, fps = setup
    pairs = fps.meta["correlated_scatter"]
    assert sorted(tuple(p["components"]) for p in pairs) == [
        (f"o{i}", f"o{j}") for i, j in PAIRS]
    R = correlation_matrix(fps)
    for p, (i, j) in zip(sorted(pairs, key=lambda p: p["components"]), PAIRS):
        # at the lower end of its interval, and at most 0.95 (smallest eigenvalue 0.05)
        assert R[i, j] == pytest.approx(min(conservative_correlation(p["r"], p["dof"]), 0.95))
        assert 0.9 < R[i, j] < p["r"]
    off = R - np.diag(np.diag(R))
    off[[i for i, _ in PAIRS], [j for _, j in PAIRS]] = 0.0
    off[[j for _, j in PAIRS], [i for i, _ in PAIRS]] = 0.0
    assert np.all(off == 0.0)
    # a pair with one component left out of the rows leaves nothing correlated
    assert correlation_matrix(fps, rows=np.r_[0, 2, 4, 6, 8]) is None


def test_the_fit_is_generalised_least_squares(setup):
    """fit_model against the normal equations with the full noise covariance."""
    _, _, fps = setup
    cal = fps.rows_calibrate
    rng = np.random.default_rng(3)
    residual = 0.4 * RESP["A"] + 0.3 * SENS["k"] + rng.normal(0.0, 1.0, N)
    fit = fit_model(residual, fps, ("A",))
    sig = fps.sigma[cal]
    cov = correlation_matrix(fps, cal) * np.outer(sig, sig)
    X = np.column_stack([fps["A"].predict(1.0)[cal], fps.sensitivities[cal]])
    assert np.allclose(fps["A"].predict(0.37)[cal], 0.37 * X[:, 0])   # a linear response
    ci = np.linalg.inv(cov)
    beta = np.linalg.solve(X.T @ ci @ X, X.T @ ci @ residual[cal])
    res = residual[cal] - X @ beta
    assert fit.magnitudes[0] == pytest.approx(beta[0], rel=1e-6)
    assert fit.nuisance[0] == pytest.approx(beta[1], rel=1e-6)
    assert fit.chi2 == pytest.approx(float(res @ ci @ res), rel=1e-6)
    # and it is not the fit that ignores the pairs
    fps0 = type(fps)(**{**fps.__dict__, "meta": dict(fps.meta, correlated_scatter=[])})
    assert abs(fit_model(residual, fps0, ("A",)).chi2 - fit.chi2) > 0.05 * fit.chi2


def test_null_data_are_rejected_at_the_nominal_rate(setup):
    """Null experiments whose paired readings share their deviations: in the generalised
    metric the gap tests reject at about their level; counting each shared deviation twice
    rejects far more often."""
    design, _, fps = setup
    meas = ~fps.rows_candidate
    corr = correlation_matrix(fps, meas)
    # a simulation known exactly (no noise of its own): the measurement's noise alone
    base = np.zeros((4, N))
    zero = np.zeros(N)
    draws = 300
    z = np.array([_pair_noise([k, 11]) for k in range(draws)])
    real = [design.with_values(Observations({f"o{i}": [v] for i, v in enumerate(y)})) for y in z]
    rate_gls = np.mean([where(r, base, sim_var=zero, correlation=corr).significant for r in real])
    rate_diag = np.mean([where(r, base, sim_var=zero).significant for r in real])
    fit_gls = np.mean([p_fit_z(y, corr) < 0.05 for y in z])
    fit_diag = np.mean([p_fit_z(y) < 0.05 for y in z])
    # both tests at alpha / 2 (where) or Bonferroni-combined (p_fit_z): at most alpha
    assert rate_gls <= 0.06 and fit_gls <= 0.06
    assert rate_diag > 2.0 * rate_gls and fit_diag > 2.0 * fit_gls
    # each pair's shared deviation counts about once (1.05 times at the 0.95 cap; the true
    # correlation here is 0.999), not twice
    q = np.array([quadratic_form(y, corr)[0] for y in z])
    assert np.mean(q) == pytest.approx(N - len(PAIRS), rel=0.08)
    assert np.mean([quadratic_form(y)[0] for y in z]) == pytest.approx(N, rel=0.08)


def test_quadratic_forms_reduce_to_the_plain_ones_without_correlation():
    z = np.array([1.5, -0.5, np.nan, 2.0])
    assert quadratic_form(z) == (pytest.approx(6.5), 3)
    assert quadratic_form(z, np.eye(4)) == (pytest.approx(6.5), 3)
    assert gap_size(z, np.eye(4)) == pytest.approx(gap_size(z))
    assert p_fit_z(z, np.eye(4)) == pytest.approx(p_fit_z(z))
    # a pair read twice from one deviation counts once as its correlation tends to 1
    R = np.eye(4)
    R[0, 1] = R[1, 0] = 0.999
    q, n = quadratic_form([2.0, 2.0, np.nan, 0.0], R)
    assert q == pytest.approx(4.0, rel=1e-3) and n == 3
    assert stats.chi2.sf(q, n) > stats.chi2.sf(8.0, n)


def test_identifiability_and_twin_sizing_use_the_fit_metric(setup):
    """The effect moves o0 and o1 alike (less evidence than two independent readings) and
    o2/o3, o4/o5 in opposite directions (more: noise moves them together, so their
    difference is measured more precisely than either). Identifiability and the twins'
    sizing see what the fit sees."""
    from dataclasses import replace

    from bedstruct.diagnose.identifiability import assess_fingerprints
    from bedstruct.diagnose.validation.twins import _projected_gap
    _, _, fps = setup
    fps0 = assess_fingerprints(replace(fps, meta=dict(fps.meta, correlated_scatter=[])))
    g, g0 = _projected_gap(fps, "A")(1.0), _projected_gap(fps0, "A")(1.0)
    assert g > 2.0 * g0 and fps["A"].signal > 2.0 * fps0["A"].signal
    # the twin's gap is the fit's: a residual equal to the effect's change at magnitude 1
    # gives the null model (recalibration alone) a chi-square of the squared gap
    residual = fps["A"].predict(1.0)
    assert fit_model(residual, fps, ()).chi2 == pytest.approx(g ** 2, rel=1e-6)
    assert fit_model(residual, fps0, ()).chi2 == pytest.approx(g0 ** 2, rel=1e-6)
    # and on the alike pair alone the evidence is about halved
    alike = np.zeros(N)
    alike[[0, 1]] = RESP["A"][[0, 1]]
    rows = fps.rows_calibrate
    sig = fps.sigma[rows]
    R = correlation_matrix(fps, rows)
    z = alike[rows] / sig
    r = R[0, 1]
    q_gls = quadratic_form(z, R)[0]
    assert q_gls == pytest.approx((z[0] ** 2 - 2 * r * z[0] * z[1] + z[1] ** 2) / (1 - r * r))
    assert q_gls < 0.6 * quadratic_form(z)[0]
