"""Magnitude intervals from the profile of the chi-square.

The normal approximation reads the local slope of the interpolated response at the fitted
magnitude; the profile refits the recalibration (and a partner effect) over the whole
prior and carries the interpolated responses' noise as an added variance.
"""

from __future__ import annotations

import numpy as np
import pytest

from bedstruct.diagnose import compute_fingerprints, diagnosis_report
from bedstruct.diagnose.attribution import attribute, fit_model
from bedstruct.diagnose.profile_interval import profile_interval
from diagnose_helpers import ToySimulator, toy_design, toy_effect
from test_diagnose_local_scatter import RESP, SENS, N, wild_node_fit

LINEAR = {"A": np.r_[3, -2, 1, 4, -1, 2, -3, 1, 0, 0, 0, 0] * 1.0,
          "B": np.r_[3, -1, 2, 3, -1, 2, -2, 2, -1, 0, 0, 0] * 1.0}   # much like A


def _linear_fps(seed=0):
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects=LINEAR, noise_sd=0.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A"), toy_effect("B")],
                               nuisance=("k",), replicates=2, alpha=0.01, seed=seed)
    return fps


def test_on_a_linear_noiseless_response_the_profile_is_the_normal_interval():
    """With exact linear responses the chi-square is quadratic in the magnitude, so the
    profile's interval is the optimum +- 1.96 standard errors."""
    fps = _linear_fps()
    rng = np.random.default_rng(2)
    for r in range(5):
        y = 0.4 * LINEAR["A"] + 0.3 * SENS["k"] + rng.standard_normal(N)
        fit = fit_model(y, fps, ["A"])
        prof = profile_interval(y, fps, ["A"], "A", float(fit.magnitudes[0]))
        assert not np.any(fps["A"].predict_se(0.5))
        lo, hi = fit.intervals[0]
        if 0.0 < lo and hi < 1.0:
            np.testing.assert_allclose(prof.interval, (lo, hi), atol=2e-3 * (hi - lo))
        # the profile's lowest point is the least-squares magnitude
        assert prof.magnitudes[np.argmin(prof.chi2)] == pytest.approx(fit.magnitudes[0],
                                                                      abs=1.0 / 160)
        assert prof.chi2.min() == pytest.approx(fit.chi2, rel=1e-6, abs=1e-9)


def test_a_partner_effect_refitted_at_each_magnitude_widens_the_interval():
    fps = _linear_fps()
    y = 0.5 * LINEAR["A"] + 0.5 * LINEAR["B"] + 0.2 * np.random.default_rng(4).standard_normal(N)
    pair = fit_model(y, fps, ["A", "B"])
    prof = profile_interval(y, fps, ["A", "B"], "A", float(pair.magnitudes[0]))
    lo, hi = pair.intervals[0]
    # the pair's normal interval already carries the correlation with B: the profile agrees
    np.testing.assert_allclose(prof.interval, (lo, hi), atol=0.02 * (hi - lo))
    # and holding B at its fitted magnitude narrows it
    y_fixed = y - fps["B"].predict(float(pair.magnitudes[1]))
    alone = profile_interval(y_fixed, fps, ["A"], "A", float(pair.magnitudes[0]))
    assert np.diff(alone.interval)[0] < 0.9 * np.diff(prof.interval)[0]


def test_the_profile_covers_where_a_wild_node_pulls_the_estimate():
    """A refinement node where runs scatter by ~30 on one component: the normal interval
    covers the truth in about half the draws (its linearisation does not carry the pull of
    the wild component on the estimate); the profile covers it far more often."""
    hits_normal, hits_profile = [], []
    for r in range(40):
        residual, own, fit = wild_node_fit(r)
        lo, hi = fit.intervals[0]
        hits_normal.append(lo <= 0.25 <= hi)
        plo, phi = profile_interval(residual, own, ["A"], "A", float(fit.magnitudes[0])).interval
        hits_profile.append(plo <= 0.25 <= phi)
    # 40 draws: normal 0.55, profile 0.95
    assert np.mean(hits_profile) >= 0.85
    assert np.mean(hits_normal) <= 0.7


def test_the_profile_holds_both_branches_of_a_response_that_turns_over():
    """y = F (m - m^2): the same response at m and 1 - m. The normal interval holds the
    branch the optimiser landed on; the profile holds both."""
    design = toy_design(N, n_validate=3)
    resp = RESP["A"] / 4.0
    sim = ToySimulator(design, sens=SENS, effects={"A": resp}, curvature={"A": -resp},
                       noise_sd=0.3)
    hits_normal, hits_profile, inner = [], [], []
    for r in range(30):
        fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                                   replicates=3, alpha=0.01, seed=100 * r)
        y = resp * (0.3 - 0.09) + np.random.default_rng(r).normal(0.0, 0.3, N)
        fit = fit_model(y - fps.base_mean, fps, ["A"])
        lo, hi = fit.intervals[0]
        hits_normal.append(lo <= 0.3 <= hi)
        prof = profile_interval(y - fps.base_mean, fps, ["A"], "A", float(fit.magnitudes[0]))
        hits_profile.append(prof.interval[0] <= 0.3 <= prof.interval[1])
        inner.append((prof.interval[0] > 0.05, prof.interval[1] < 0.95))
    # 30 draws: normal 0.57, profile 1.0; the profile still leaves out no effect (m = 0)
    # and its mirror (m = 1) in 70 % and 77 % of them
    assert np.mean(hits_profile) >= 0.9 and np.mean(hits_normal) <= 0.75
    assert np.all(np.mean(inner, axis=0) >= 0.5)


def test_attribute_reports_the_profile_for_the_chosen_model_only():
    fps = _linear_fps()
    y = 0.6 * LINEAR["A"] + 0.3 * SENS["k"] + 0.3 * np.random.default_rng(9).standard_normal(N)
    att = attribute(y, fps)
    assert att.verdict == "attributed" and att.best.effects == ("A",)
    assert att.best.interval_kind == "profile"
    prof = profile_interval(y, fps, ["A"], "A", att.selected[0].magnitude)
    assert att.selected[0].interval == prof.interval
    # the ranking's entry of the chosen single is the same fit
    assert [e for e in att.ranking if e.effect == "A"][0].interval == prof.interval
    assert {m.interval_kind for m in att.models if m is not att.best} == {"normal"}
    assert att.best.as_dict()["interval_kind"] == "profile"


def test_bad_arguments_are_named():
    fps = _linear_fps()
    with pytest.raises(ValueError, match="'C' must be one of"):
        profile_interval(np.zeros(N), fps, ["A"], "C", 0.1)
    gap = np.zeros(N)
    gap[2] = np.nan
    with pytest.raises(ValueError, match="not finite on fitted rows o2"):
        profile_interval(gap, fps, ["A"], "A", 0.1)
    with pytest.raises(ValueError, match="fitted magnitude of 'A' is nan"):
        profile_interval(np.zeros(N), fps, ["A"], "A", float("nan"))


def test_the_report_draws_the_profile_the_interval_was_read_from():
    from bedstruct.diagnose import Observations, diagnose
    from bedstruct.diagnose.figures import plot_magnitude_profile
    design = toy_design(N, n_validate=3, sigma=0.3)
    sim = ToySimulator(design, sens=SENS, effects=LINEAR, noise_sd=0.3)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A"), toy_effect("B")],
                               nuisance=("k",), replicates=3, alpha=0.01)
    y = 0.6 * LINEAR["A"] + 0.3 * np.random.default_rng(2).standard_normal(N)
    real = design.with_values(Observations({f"o{i}": [v] for i, v in enumerate(y)}))
    d = diagnose(real, sim, base={"k": 1.0}, effects=[toy_effect("A"), toy_effect("B")],
                 fingerprints=fps, refine=0, confirm_rounds=0)
    assert d.verdict == "attributed"
    top = d.attribution.selected[0]
    assert d.to_json()["which"][0]["interval_kind"] == "profile"
    fig, ax = plot_magnitude_profile(d)
    band = ax.patches[0]   # a Rectangle (matplotlib >= 3.9) or a Polygon
    edges = ((band.get_x(), band.get_x() + band.get_width()) if hasattr(band, "get_width")
             else (band.get_xy()[:, 0].min(), band.get_xy()[:, 0].max()))
    np.testing.assert_allclose(edges, top.interval)
    # the curve is at or below the threshold exactly inside the band
    x, c = ax.lines[0].get_data()
    inside = (x >= top.interval[0]) & (x <= top.interval[1])
    assert np.all(c[~inside] > 3.84 - 1e-9) and np.all(c[inside] <= 3.84 + 0.5)
    rep = diagnosis_report(d)
    assert any("profile of chi-square" in caption for sec in rep.sections
               for caption, _ in sec.figures)


def test_a_gap_along_the_recalibration_does_not_move_the_profile():
    """The recalibration is refitted at every magnitude: adding any shift of the nuisance
    parameters to the data leaves the profile (and so the interval) unchanged."""
    design = toy_design(N, n_validate=3)
    sim = ToySimulator(design, sens=SENS, effects=RESP, noise_sd=1.0)
    fps = compute_fingerprints(sim, design, {"k": 1.0}, [toy_effect("A")], nuisance=("k",),
                               replicates=3, alpha=0.01, seed=3)
    y = 0.3 * RESP["A"] + np.random.default_rng(3).standard_normal(N) - fps.base_mean
    prof = profile_interval(y, fps, ["A"], "A", 0.3)
    shifted = profile_interval(y + fps.sensitivities @ np.array([0.7]), fps, ["A"], "A", 0.3)
    np.testing.assert_allclose(shifted.chi2, prof.chi2, rtol=1e-8, atol=1e-8)
    assert shifted.interval == pytest.approx(prof.interval)
    # a gap along the effect does move it
    moved = profile_interval(y + 0.2 * fps["A"].predict(1.0), fps, ["A"], "A", 0.5)
    assert moved.magnitudes[moved.chi2.argmin()] > prof.magnitudes[prof.chi2.argmin()] + 0.1
