"""PSDs and fitting distributions to D10/D50/D90."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import special, stats

import bedstruct
from bedstruct import Frame
from bedstruct.analysis import (particle_size_distribution, percentile_diameter, psd_by_region,
                                psd_from_percentiles, psd_series, psd_table)

Q = np.array([0.1, 0.5, 0.9])


def test_percentiles_match_numpy_for_large_samples():
    rng = np.random.default_rng(0)
    d = rng.lognormal(3.9, 0.4, 200_000)
    np.testing.assert_allclose(percentile_diameter(d, Q), np.quantile(d, Q), rtol=2e-3)
    # volume weighting of a log-normal is log-normal with mu + 3 sigma^2 (Hatch-Choate)
    vol = percentile_diameter(d, Q, weights=d ** 3)
    np.testing.assert_allclose(vol, np.exp(3.9 + 3 * 0.16 + 0.4 * special.ndtri(Q)), rtol=1e-2)


def test_histogram_weightings():
    f = Frame(np.zeros((4, 3)), [1.0, 1.0, 1.0, 2.0], box=[9, 9, 9])
    n = particle_size_distribution(f, weighting="number", bins=[1, 3, 5])
    v = particle_size_distribution(f, bins=[1, 3, 5])
    assert n.fraction.tolist() == [0.75, 0.25] and n.n_particles == 4
    np.testing.assert_allclose(v.fraction, [3 / 11, 8 / 11])
    assert v.cumulative[-1] == pytest.approx(1.0)
    assert v.mean_diameter == pytest.approx((3 * 16 + 256) / (3 * 8 + 64))   # D[4,3]
    assert n.mean_diameter == pytest.approx(2.5)
    with pytest.raises(ValueError, match="weighting"):
        particle_size_distribution(f, weighting="mass")


def test_fit_recovers_known_lognormal():
    mu, sigma = math.log(50.0), 0.45
    # percentiles of the log-normal truncated to [25, 105]
    lo, hi = 25.0, 105.0
    g = stats.norm.cdf((np.log([lo, hi]) - mu) / sigma)
    targets = np.exp(mu + sigma * special.ndtri(g[0] + Q * (g[1] - g[0])))
    fit = bedstruct.psd_from_percentiles(*targets, (lo, hi))
    assert fit.family == "lognormal"
    assert fit.params[0] == pytest.approx(mu, abs=1e-6) and fit.params[1] == pytest.approx(sigma, abs=1e-6)
    assert fit.rms_log_error < 1e-8
    # draws follow the fitted (volume-weighted) distribution
    d = fit.sample_diameters(300_000, seed=1)
    assert d.min() >= lo and d.max() <= hi
    np.testing.assert_allclose(percentile_diameter(d, Q, weights=d ** 3), targets, rtol=1e-2)
    np.testing.assert_allclose(fit.cdf(targets), Q, atol=1e-9)


def test_untruncated_number_conversion():
    mu, sigma = math.log(40.0), 0.3
    targets = np.exp(mu + sigma * special.ndtri(Q))
    fit = psd_from_percentiles(*targets, (1.0, 1e4), family="lognormal")
    d = fit.sample_diameters(200_000, seed=2)
    # number median of a log-normal whose volume median is exp(mu): exp(mu - 3 sigma^2)
    assert np.median(d) == pytest.approx(math.exp(mu - 3 * sigma ** 2), rel=1e-2)
    assert fit.number_cdf(math.exp(mu - 3 * sigma ** 2)) == pytest.approx(0.5, abs=2e-3)
    # number-weighted percentiles sample directly
    nfit = psd_from_percentiles(*targets, (1.0, 1e4), weighting="number")
    dn = nfit.sample_radii(200_000, seed=3) * 2
    np.testing.assert_allclose(np.quantile(dn, Q), targets, rtol=1e-2)


def test_fit_recovers_rosin_rammler():
    lam, k = 55.0, 2.2
    g = 1 - np.exp(-(np.array([5.0, 200.0]) / lam) ** k)          # truncated to [5, 200]
    targets = lam * (-np.log1p(-(g[0] + Q * (g[1] - g[0])))) ** (1 / k)
    fit = psd_from_percentiles(*targets, (5.0, 200.0))
    assert fit.family == "rosin-rammler"
    assert fit.params == pytest.approx((lam, k), rel=1e-6)
    assert fit.alternatives["lognormal"][1] > fit.rms_log_error


def test_seed_powder():
    fit = psd_from_percentiles(29.84, 52.08, 86.11, (25, 105))
    assert fit.rms_log_error < 0.02
    r = fit.sample_radii(50_000, seed=0)
    assert 12.5 <= r.min() and r.max() <= 52.5
    d = 2 * r
    np.testing.assert_allclose(percentile_diameter(d, Q, weights=d ** 3), [29.84, 52.08, 86.11], rtol=0.03)


def test_fit_errors():
    with pytest.raises(ValueError, match="d10 < d50"):
        psd_from_percentiles(50, 40, 80, (10, 100))
    with pytest.raises(ValueError, match="bounds"):
        psd_from_percentiles(30, 50, 90, (35, 100))
    with pytest.raises(ValueError, match="family"):
        psd_from_percentiles(30, 50, 90, (10, 100), family="gamma")


def test_by_region_series_and_table():
    rng = np.random.default_rng(4)
    pos = rng.uniform(0, 10, (500, 3))
    r = np.where(pos[:, 0] < 5, 0.2, 0.4)
    f = Frame(pos, r, box=[10, 10, 10])
    parts = psd_by_region(f, [[0, 0, 0], [5, 0, 0]], [[5, 10, 10], [10, 10, 10]], weighting="number")
    assert [p.d50 for p in parts] == [0.4, 0.8]
    assert sum(p.n_particles for p in parts) == 500
    s = psd_series([f, f], mask=lambda fr: fr.positions[:, 0] < 5)
    assert s[0].d90 == pytest.approx(0.4)
    t = psd_table(parts, labels=["start", "end"])
    assert t["label"].tolist() == ["start", "end"] and t["d50"].tolist() == [0.4, 0.8]
