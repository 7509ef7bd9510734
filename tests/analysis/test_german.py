"""German's law: fit against an independent regression, interval coverage, deviation."""

from __future__ import annotations

import numpy as np
import pytest

import bedstruct
from bedstruct.analysis import (coordination_by_window, fit_german_law, german_cn,
                                packing_along)


def test_exact_recovery_of_seed_coefficients():
    f = np.linspace(0.45, 0.65, 9)
    cn = german_cn(f, a=1.925, b=0.04545)
    fit = bedstruct.fit_german_law(f, cn)
    assert fit.a == pytest.approx(1.925, abs=1e-12) and fit.b == pytest.approx(0.04545, abs=1e-12)
    assert np.allclose(fit.residuals, 0, atol=1e-12) and fit.r_squared == pytest.approx(1.0)
    assert fit.a_ci[0] <= fit.a <= fit.a_ci[1]
    np.testing.assert_allclose(fit.predict(f), cn)


def test_matches_polyfit():
    rng = np.random.default_rng(1)
    f = rng.uniform(0.4, 0.65, 30)
    cn = 2 * 1.8 + 11 * 0.2 * f ** 2 + rng.normal(0, 0.1, 30)
    slope, icpt = np.polyfit(f ** 2, cn, 1)
    fit = fit_german_law(f, cn)
    assert fit.a == pytest.approx(icpt / 2, rel=1e-10) and fit.b == pytest.approx(slope / 11, rel=1e-10)
    # standard errors agree with the classical formula for simple regression
    x = f ** 2
    s2 = np.sum((cn - icpt - slope * x) ** 2) / 28
    se_slope = np.sqrt(s2 / np.sum((x - x.mean()) ** 2))
    assert np.sqrt(fit.covariance[1, 1]) == pytest.approx(se_slope / 11, rel=1e-8)


def test_interval_coverage():
    rng = np.random.default_rng(2)
    f = np.linspace(0.45, 0.65, 8)
    hits = 0
    trials = 400
    for _ in range(trials):
        cn = german_cn(f, a=1.9, b=0.3) + rng.normal(0, 0.05, f.size)
        fit = fit_german_law(f, cn, confidence=0.9)
        hits += fit.b_ci[0] <= 0.3 <= fit.b_ci[1]
    assert 0.86 < hits / trials < 0.94


def test_unfitted_deviation_definition():
    f = np.array([0.5, 0.55, 0.6])
    cn = german_cn(f) - np.array([0.40, 0.46, 0.52])
    fit = fit_german_law(f, cn)
    assert fit.unfitted_deviation == pytest.approx(0.46)      # mean |CN_S - cn|
    np.testing.assert_allclose(fit.unfitted_residuals, [-0.40, -0.46, -0.52])
    assert fit.fitted_deviation < fit.unfitted_deviation / 100


def test_two_points_and_errors():
    fit = fit_german_law([0.5, 0.6], [4.0, 4.2])
    assert np.isnan(fit.a_ci[0]) and fit.n_points == 2
    with pytest.raises(ValueError, match="at least 2"):
        fit_german_law([0.5], [4.0])
    with pytest.raises(ValueError, match="equal"):
        fit_german_law([0.5, 0.5, 0.5], [4.0, 4.1, 4.2])
    with pytest.raises(ValueError, match="same length"):
        fit_german_law([0.5, 0.6], [4.0])
    with pytest.raises(ValueError, match="finite"):
        fit_german_law([0.5, np.nan], [4.0, 4.1])


def test_windows_pipeline(random_bed):
    prof = packing_along(random_bed, 4)
    cn = coordination_by_window(random_bed, prof.lower, prof.upper)
    fit = fit_german_law(prof.fractions, cn.mean, weights=cn.n_particles)
    assert np.isfinite(fit.a) and fit.n_points == 4


def test_integer_weights_equal_repeated_points():
    rng = np.random.default_rng(3)
    f = rng.uniform(0.45, 0.65, 7)
    cn = german_cn(f, a=1.9, b=0.05) + rng.normal(0, 0.2, 7)
    k = np.array([1, 3, 2, 5, 1, 4, 2])
    weighted = fit_german_law(f, cn, weights=k)
    repeated = fit_german_law(np.repeat(f, k), np.repeat(cn, k))
    assert weighted.a == pytest.approx(repeated.a, rel=1e-12)
    assert weighted.b == pytest.approx(repeated.b, rel=1e-12)
    # and it is the weighted straight line cn = 2a + 11b f^2 (numpy weights multiply residuals)
    slope, intercept = np.polyfit(f ** 2, cn, 1, w=np.sqrt(k))
    assert weighted.a == pytest.approx(intercept / 2, rel=1e-10)
    assert weighted.b == pytest.approx(slope / 11, rel=1e-10)
    unweighted = fit_german_law(f, cn)
    assert abs(unweighted.a - weighted.a) > 1e-3     # the weights matter for these points


def test_plot_on_given_axes():
    from matplotlib.figure import Figure
    from bedstruct.plot import plot_german
    f = np.array([0.5, 0.55, 0.6, 0.62])
    fit = fit_german_law(f, german_cn(f, a=1.925, b=0.04545) + [0.01, -0.02, 0.0, 0.01])
    fig = Figure()
    ax, rax = fig.subplots(2, 1)
    assert plot_german(fit, ax=ax, residual_ax=rax) is ax
    assert len(ax.lines) == 3 and len(rax.lines) == 3            # zero line + two residual sets
    np.testing.assert_allclose(rax.lines[1].get_ydata(), fit.residuals)
    assert "a = 1.9" in ax.get_legend().get_texts()[2].get_text()


def _stepped_bed():
    """SC spheres (r = 0.51, spacing 1), 4 layers deep, thinning to 1 layer along x: CN and f vary."""
    from bedstruct import Box, Frame
    g = np.stack(np.meshgrid(*[np.arange(k) + 0.5 for k in (24, 4, 4)], indexing="ij"), -1).reshape(-1, 3)
    layers = 4 - (g[:, 0] // 6)                      # 4, 3, 2, 1 layers in x quarters
    keep = g[:, 2] < layers
    return Frame(g[keep], np.full(keep.sum(), 0.51), box=Box([0, 0, 0], [24, 4, 4], boundary="pp pp ff"))


def test_german_law_along_fits_the_windows_it_states():
    from bedstruct.analysis import (GERMAN_WINDOWS, coordination, coordination_by_window, german_law_along,
                                    packing_along)
    bed = _stepped_bed()
    g = german_law_along(bed)
    assert g.n_windows == GERMAN_WINDOWS == 12 and g.n_used == 12 and g.axis == 0
    assert g.definition.startswith("12 of 12 equal windows along x")
    # the same fit by hand from the documented pieces
    cn = coordination(bed)
    prof = packing_along(bed, 12)
    by_hand = fit_german_law(prof.fractions, coordination_by_window(bed, prof.lower, prof.upper, result=cn).mean)
    assert (g.fit.a, g.fit.b) == (by_hand.a, by_hand.b)
    # the windows away from a step (x in 2-4, 8-10, 14-16, 20-22) hold k = 4, 3, 2, 1 layers:
    # 8 k spheres of r = 0.51 in 2 x 4 x 4.02, and CN 4 in-plane + 2 (k - 1) / k vertical
    for w, k in zip((1, 4, 7, 10), (4, 3, 2, 1)):
        assert g.n_particles[w] == 8 * k
        assert g.fractions[w] == pytest.approx(8 * k * 4 / 3 * np.pi * 0.51 ** 3 / (2 * 4 * 4.02), rel=1e-3)
        assert g.cn[w] == pytest.approx(4 + 2 * (k - 1) / k, abs=1e-12)


def test_german_law_along_leaves_out_sparse_windows_and_needs_three():
    from bedstruct.analysis import german_law_along
    bed = _stepped_bed()
    few = german_law_along(bed, min_particles=20)       # windows of k layers hold 8 k particles
    assert few.n_used == 6 and few.used[:6].all() and not few.used[6:].any()
    assert few.fit.n_points == 6
    assert german_law_along(bed, min_particles=40).fit is None     # only 4-layer windows: too few
    with pytest.raises(ValueError, match="`n_windows` must be at least 3"):
        german_law_along(bed, n_windows=2)
    with pytest.raises(ValueError, match="`axis`"):
        german_law_along(bed, axis=5)


def test_determined_when_cn_rises_with_packing_over_the_points():
    rng = np.random.default_rng(5)
    f = np.linspace(0.40, 0.65, 12)
    fit = fit_german_law(f, german_cn(f, a=1.2, b=0.5) + rng.normal(0, 0.05, f.size))
    assert fit.b_ci[0] > 0 and fit.a_ci[1] > 0
    assert fit.determined and fit.undetermined_reason is None


def test_not_determined_when_cn_does_not_depend_on_packing():
    # a flat coordination number with noise over a narrow packing range: b's interval spans 0
    rng = np.random.default_rng(6)
    f = np.linspace(0.600, 0.604, 12)
    fit = fit_german_law(f, 6.0 + rng.normal(0, 0.1, f.size))
    assert fit.b_ci[0] < 0 < fit.b_ci[1]
    assert not fit.determined
    assert "interval of b includes 0" in fit.undetermined_reason
    assert "f = 0.600-0.604" in fit.undetermined_reason


def test_not_determined_when_the_law_extrapolates_to_negative_coordination():
    # a steep rise over a narrow range: b is well away from 0, but 2a (CN at f -> 0) is < 0
    rng = np.random.default_rng(7)
    f = np.linspace(0.60, 0.62, 10)
    fit = fit_german_law(f, german_cn(f, a=-5.0, b=4.0) + rng.normal(0, 0.001, f.size))
    assert fit.b_ci[0] > 0 and fit.a_ci[1] < 0
    assert not fit.determined and "interval of a lies below 0" in fit.undetermined_reason
    # two points leave no interval, so nothing is determined
    two = fit_german_law([0.5, 0.6], [4.0, 4.2])
    assert not two.determined and "no interval" in two.undetermined_reason


def test_lattice_slab_windows_do_not_determine_a_and_b():
    from bedstruct.analysis import german_law_along
    rng = np.random.default_rng(0)
    d, n, nz = 1.0, 8, 3
    a = d * np.sqrt(2.0)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) * a
    cells = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)
    pos = (cells[:, None, :] * a + basis[None]).reshape(-1, 3) + 0.5 * d + rng.normal(0, 0.002, (len(cells) * 4, 3))
    frame = bedstruct.Frame(pos, np.full(len(pos), 0.5005 * d),
                            box=bedstruct.Box([0, 0, 0], [n * a, n * a, nz * a + 2], boundary="pp pp ff"))
    g = german_law_along(frame, check_state=False)
    assert g.n_used == 12 and np.ptp(g.fractions[g.used]) < 0.01
    assert not g.fit.determined


def test_workflow_summary_carries_whether_a_and_b_are_determined():
    from bedstruct.workflows._common import german_fit_values
    rng = np.random.default_rng(5)
    f = np.linspace(0.40, 0.65, 12)
    a, b, r2, determined = german_fit_values(f, german_cn(f, a=1.2, b=0.5) + rng.normal(0, 0.05, f.size))
    assert determined is True and a == pytest.approx(1.2, abs=0.2)
    flat = german_fit_values(np.linspace(0.6, 0.604, 12), 6.0 + rng.normal(0, 0.1, 12))
    assert flat[3] is False
    assert german_fit_values([0.5, 0.6], [4.0, 4.1])[3] is None
