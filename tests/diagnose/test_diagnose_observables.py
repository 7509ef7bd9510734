"""Observation operators against known answers."""

from __future__ import annotations

import numpy as np
import pytest


from bedstruct.diagnose import (angle_from_image, angle_from_particles, fit_surface_angle,
                                observe, psd_percentiles, psd_percentiles_from_cumulative,
                                render_side_view, surface_profile, windowed_mean)
from diagnose_helpers import cubic_positions, heap_particles


@pytest.mark.parametrize("angle", [22.0, 27.3, 33.0, 38.3, 45.0])
@pytest.mark.parametrize("method", ["ransac", "theil-sen"])
def test_angle_from_rendered_heap_within_one_degree(angle, method):
    pos, rad = heap_particles(angle, seed=int(angle * 10))
    img = render_side_view(pos, rad, pixel_size=5e-6)
    assert abs(angle_from_image(img, pixel_size=5e-6, method=method) - angle) < 1.0


def test_angle_from_noisy_blurred_dark_powder_image():
    from scipy.ndimage import gaussian_filter
    pos, rad = heap_particles(33.0, seed=3)
    img = render_side_view(pos, rad, pixel_size=5e-6, background=0.8, foreground=0.25)
    rng = np.random.default_rng(0)
    img = gaussian_filter(img, 1.5) + 0.08 * rng.standard_normal(img.shape)
    assert abs(angle_from_image(img, pixel_size=5e-6, powder="dark") - 33.0) < 1.0


def test_angle_is_mirror_and_scale_invariant():
    pos, rad = heap_particles(30.0, seed=5)
    img = render_side_view(pos, rad, pixel_size=5e-6)
    a = angle_from_image(img, pixel_size=5e-6)
    assert angle_from_image(img[:, ::-1], pixel_size=5e-6) == pytest.approx(a, abs=0.3)
    # pixel size cancels: same image, other scale
    assert angle_from_image(img, pixel_size=1.0) == pytest.approx(a, abs=1e-9)
    assert angle_from_particles(pos, rad) == pytest.approx(30.0, abs=1.0)


def test_surface_profile_of_step():
    img = np.zeros((10, 4))
    img[6:, :2] = 1.0
    img[3:, 2:] = 1.0
    x, h = surface_profile(img, pixel_size=0.5, min_object=1)
    np.testing.assert_allclose(h, [2.0, 2.0, 3.5, 3.5])
    np.testing.assert_allclose(x, [0.25, 0.75, 1.25, 1.75])


def test_fit_surface_angle_rejects_outliers():
    x = np.linspace(0, 1, 200)
    h = 1.0 - np.tan(np.radians(35)) * x
    h[::17] += 0.3   # spikes (dust on the surface)
    assert fit_surface_angle(x, h, band=(0, 1)).angle == pytest.approx(35.0, abs=0.2)
    with pytest.raises(ValueError, match="method"):
        fit_surface_angle(x, h, method="ols")


def test_uniform_image_is_an_error():
    with pytest.raises(ValueError, match="uniform"):
        surface_profile(np.ones((5, 5)), pixel_size=1.0)


def test_windowed_mean_and_errors():
    t = np.linspace(0, 1, 101)
    v = np.where(t < 0.1, 35.0, 27.0) + 0 * t
    m, s = windowed_mean(t, v, [[0, 0.1], [0.1, 1.0]])
    np.testing.assert_allclose(m, [35.0, 27.0])
    np.testing.assert_allclose(s, [0.0, 0.0])
    with pytest.raises(ValueError, match="holds no sample"):
        windowed_mean([0.5], [1.0], [[0, 0.1]])


def test_psd_percentiles_volume_weighting():
    # 1000 particles of 10 um and 1 of 100 um: by volume half the mass is in the big one
    d = np.r_[np.full(1000, 10e-6), 100e-6]
    assert psd_percentiles(d, [50], weights="number")[0] == pytest.approx(10e-6)
    assert psd_percentiles(d, [90])[0] > 50e-6
    # sampling a log-normal volume distribution: percentiles match the analytic ones
    rng = np.random.default_rng(1)
    mu, sig = np.log(50e-6), 0.3
    # number-weighted log-normal with mu - 3 sig^2 is volume-weighted log-normal with mu
    dn = np.exp(rng.normal(mu - 3 * sig ** 2, sig, 400_000))
    from scipy.stats import norm
    expect = np.exp(mu + sig * norm.ppf([0.1, 0.5, 0.9]))
    np.testing.assert_allclose(psd_percentiles(dn, [10, 50, 90]), expect, rtol=0.01)


def test_psd_from_cumulative():
    np.testing.assert_allclose(psd_percentiles_from_cumulative([10, 20, 40], [0, 50, 100], [25, 50]),
                               [15.0, 20.0])
    with pytest.raises(ValueError):
        psd_percentiles_from_cumulative([10, 5], [0, 100])


def test_packing_fraction_and_bed_height_of_lattice():
    # a simple cubic lattice: packing pi/6 in the region it fills; seen from above, the
    # spheres' caps cover pi/4 of the plane (the columns between them reach the plate)
    pos = cubic_positions(6)
    rad = np.full(len(pos), 0.5)
    data = {"positions": pos, "radii": rad}
    phi = observe("packing_fraction", dict(data, region_lo=[0, 0, 0], region_hi=[6, 6, 6]))
    assert phi[0] == pytest.approx(np.pi / 6, rel=1e-9)
    # bed height: top layer centres at 5.5, caps of mean height r (2/3) over their discs
    h = observe("bed_height", dict(data, plate_z=0.0, bounds=((0, 6), (0, 6)), spacing=0.005))[0]
    assert h == pytest.approx(np.pi / 4 * (5.5 + 1.0 / 3.0), rel=2e-3)


def test_roughness_is_the_sa_of_the_height_map():
    x = np.linspace(0, 20 * np.pi, 20001)
    h = 0.3 * np.sin(x)
    # Sa of a sine over whole periods: mean |a sin| = 2 a / pi
    assert observe("roughness", {"surface_heights": h})[0] == pytest.approx(0.6 / np.pi, rel=1e-3)


def test_observe_dispatch_matches_direct_operators():
    t = np.linspace(0, 1, 50)
    a = 27 + 5 * np.exp(-t / 0.03)
    w = np.array([[0, 0.1], [0.1, 1]])
    np.testing.assert_allclose(observe("dynamic_angle_series", {"times": t, "angles": a}, windows=w),
                               windowed_mean(t, a, w)[0])
    d = np.array([20e-6, 40e-6, 60e-6])
    np.testing.assert_allclose(observe("psd", {"diameters": d}, percentiles=[50]), psd_percentiles(d, [50]))
    assert observe("coordination", {"coordination": [4, 6]})[0] == 5.0
    with pytest.raises(ValueError, match="unknown observable kind"):
        observe("temperature", {})


def test_observe_accepts_a_frame():
    from bedstruct import Frame
    from bedstruct.analysis import bed_height
    pos = cubic_positions(4)
    f = Frame(pos, np.full(len(pos), 0.5), box=[4, 4, 4])
    assert observe("bed_height", f)[0] == pytest.approx(bed_height(f, 0.0))
    with pytest.raises(TypeError, match="Frame"):
        observe("bed_height", 3.0)


def _side_view(left_deg, right_deg, nr=300, nc=600):
    """Binary side view of a pile with its crest at the centre and two flanks of given angles."""
    r, c = np.mgrid[0:nr, 0:nc].astype(float)
    t = np.where(c < nc / 2, np.tan(np.radians(left_deg)), np.tan(np.radians(right_deg)))
    return (r >= np.minimum(0.15 * nr + np.abs(c - nc / 2) * t, 0.9 * nr)).astype(float)


@pytest.mark.parametrize("method", ["ransac", "theil-sen"])
def test_two_flanked_pile_is_fitted_flank_by_flank(method):
    img = _side_view(25.0, 35.0)
    assert angle_from_image(img, method=method) == pytest.approx(30.0, abs=0.3)   # the mean
    assert angle_from_image(img, method=method, flanks="left") == pytest.approx(25.0, abs=0.3)
    assert angle_from_image(img, method=method, flanks="right") == pytest.approx(35.0, abs=0.3)
    fit = fit_surface_angle(*surface_profile(img, pixel_size=1.0), method=method)
    assert fit.flanks == ("left", "right")
    np.testing.assert_allclose(fit.flank_angles, [25.0, 35.0], atol=0.3)


def test_image_polarity_auto_and_quality_checks():
    img = _side_view(30.0, 30.0)
    dark = 0.8 - 0.6 * img
    assert angle_from_image(dark, powder="auto") == pytest.approx(30.0, abs=0.3)
    assert angle_from_image(dark, powder="dark") == pytest.approx(30.0, abs=0.3)
    with pytest.raises(ValueError, match="bottom of the image"):
        angle_from_image(dark)                        # bright powder assumed: none at the bottom
    with pytest.raises(ValueError, match="bottom of the image"):
        angle_from_image(img[::-1])                   # upside down
    with pytest.raises(ValueError, match="top edge"):
        angle_from_image(np.rot90(_side_view(30.0, 30.0)[:, :300]))   # rotated by 90 deg
    with pytest.raises(ValueError):
        angle_from_image(np.random.default_rng(0).random((300, 600)))  # noise
    with pytest.raises(ValueError, match="cannot tell the powder"):
        angle_from_image(np.random.default_rng(0).random((300, 600)), powder="auto")
    with pytest.raises(ValueError, match="rises only"):
        angle_from_image(np.r_[np.zeros((200, 300)), np.ones((100, 300))])   # a flat bed


@pytest.mark.parametrize("phi", [0.0, 0.9, 0.99])
def test_windowed_mean_standard_error_of_autocorrelated_series(phi):
    """The stated standard error of a window mean matches the spread of window means over
    repeated AR(1) series (std/sqrt(k) was ~15x too small at phi = 0.99)."""
    from scipy.signal import lfilter
    rng = np.random.default_rng(11)
    n, reps = 2000, 300
    e = rng.normal(0, np.sqrt(1 - phi ** 2), (reps, n))
    e[:, 0] = rng.normal(0, 1, reps)
    x = lfilter([1], [1, -phi], e, axis=1)
    t = np.linspace(0, 1, n)
    res = np.array([windowed_mean(t, xi, [[0.1, 1.0]]) for xi in x])[:, :, 0]
    ratio = np.sqrt(np.mean(res[:, 1] ** 2)) / res[:, 0].std()
    assert 0.75 < ratio < 1.3, ratio
