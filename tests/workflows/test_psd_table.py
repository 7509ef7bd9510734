"""A tabulated size distribution (``psd.diameters``, ``psd.volume_fractions``) drawn by number."""

import numpy as np
import pytest
from scipy.special import ndtr

from bedstruct.analysis import percentile_diameter
from bedstruct.errors import ConfigError
from bedstruct.workflows import load_config
from bedstruct.workflows._common import psd_sampler, tabulated_psd_sampler

D = np.geomspace(15e-6, 120e-6, 25)


def _table_percentiles(d, F, q):
    """The table's volume-weighted percentiles: its CDF, renormalised over the table's range,
    inverted log-linearly (independent of the sampler's number weighting)."""
    G = (F - F[0]) / (F[-1] - F[0])
    return np.exp(np.interp(q, G, np.log(d)))


def _cfg(d, F, *more):
    return load_config(preset="tiny", overrides=[
        "psd.diameters=[" + ", ".join(repr(float(x)) for x in d) + "]",
        "psd.volume_fractions=[" + ", ".join(repr(float(x)) for x in F) + "]", *more])


def test_draws_reproduce_the_table_s_volume_percentiles():
    # a log-normal table cut off on both sides (F from 0.01 to 0.995): truncated to its range
    F = ndtr((np.log(D) - np.log(45e-6)) / 0.35)
    cfg = _cfg(D, F)
    draw = psd_sampler(cfg)
    scale = cfg["psd"]["scale"]
    d = 2.0 * draw(200_000, np.random.default_rng(1)) / scale
    got = percentile_diameter(d, [0.1, 0.5, 0.9], weights=d ** 3)
    want = _table_percentiles(D, F, [0.1, 0.5, 0.9])
    np.testing.assert_allclose(got, want, rtol=0.01)
    assert draw.r_min == pytest.approx(0.5 * scale * D[0])
    assert draw.r_max == pytest.approx(0.5 * scale * D[-1])
    assert d.min() >= D[0] * (1 - 1e-12) and d.max() <= D[-1] * (1 + 1e-12)
    # the whole volume CDF, not only three points, at every diameter of the table
    order = np.argsort(d)
    cum = np.cumsum(d[order] ** 3) / np.sum(d ** 3)
    G = (F - F[0]) / (F[-1] - F[0])
    assert np.max(np.abs(np.interp(D, d[order], cum) - G)) < 0.01


def test_number_weighting_is_exact_for_a_power_law():
    """Volume uniform in ln d between 20 and 40 um: the number density per ln d is
    proportional to d^-3, so the number fraction below the geometric middle (28.28 um) is
    (1 - 2^-1.5) / (1 - 2^-3) = 1 / (1 + 2^-1.5)."""
    draw = tabulated_psd_sampler([20e-6, 30e-6, 40e-6], [0.0, np.log(1.5) / np.log(2), 1.0])
    d = 2.0 * draw(400_000, np.random.default_rng(3))
    mid = np.sqrt(20e-6 * 40e-6)
    assert np.mean(d < mid) == pytest.approx(1.0 / (1.0 + 2 ** -1.5), abs=0.003)


def test_a_bimodal_table_gives_two_modes():
    F = 0.5 * ndtr((np.log(D) - np.log(22e-6)) / 0.15) + 0.5 * ndtr((np.log(D) - np.log(80e-6)) / 0.12)
    d = 2.0 * tabulated_psd_sampler(D, F)(200_000, np.random.default_rng(2))
    h, e = np.histogram(np.log(d), bins=np.log(D), weights=d ** 3)
    dens = np.pad(h / np.diff(e), 1)
    peaks = [i - 1 for i in range(1, len(dens) - 1)
             if dens[i] > dens[i - 1] and dens[i] >= dens[i + 1] and dens[i] > 0.1 * dens.max()]
    centres = np.sqrt(D[:-1] * D[1:])[peaks]
    assert len(peaks) == 2
    np.testing.assert_allclose(centres, [22e-6, 80e-6], rtol=0.12)
    # equal volumes in both modes
    assert np.sum(d[d < 45e-6] ** 3) / np.sum(d ** 3) == pytest.approx(0.5, abs=0.01)


def test_fines_mix_into_a_tabulated_distribution():
    F = ndtr((np.log(D) - np.log(45e-6)) / 0.35)
    cfg = _cfg(D, F, "psd.fines_mass_fraction=0.1", "psd.fines_median_diameter=10e-6",
               "psd.fines_min_diameter=5e-6")
    draw = psd_sampler(cfg)
    d = 2.0 * draw(200_000, np.random.default_rng(4)) / cfg["psd"]["scale"]
    assert draw.r_min == pytest.approx(0.5 * cfg["psd"]["scale"] * 5e-6)
    # the fines are those below the table's smallest diameter, with their mass fraction
    assert np.sum(d[d < D[0]] ** 3) / np.sum(d ** 3) == pytest.approx(0.1, abs=0.01)
    # fines above the table's smallest diameter: refused when the configuration loads
    with pytest.raises(ConfigError, match=r"fines_min_diameter.*smallest diameter of the "
                                          r"powder, `psd\.diameters`"):
        _cfg(D, F, "psd.fines_mass_fraction=0.1", "psd.fines_min_diameter=20e-6")


def test_without_a_table_the_percentile_fit_draws_as_before():
    cfg = load_config(preset="tiny")
    assert cfg["psd"]["diameters"] == [] and cfg["psd"]["volume_fractions"] == []
    draw = psd_sampler(cfg)
    assert draw.fit is not None and draw.r_min == pytest.approx(0.5 * 2.0 * cfg["psd"]["d_min"])


@pytest.mark.parametrize("d, F, match", [
    ([20e-6, 40e-6], [0.0, 1.0], r"`psd\.diameters` must list at least 3"),
    ([20e-6, 40e-6, 30e-6], [0.0, 0.5, 1.0], r"`psd\.diameters` must hold positive .*increasing"),
    ([20e-6, 30e-6, 40e-6], [0.0, 1.0], r"`psd\.volume_fractions` must give one .* \(3\); got 2"),
    ([20e-6, 30e-6, 40e-6], [0.0, 0.6, 0.5], r"`psd\.volume_fractions` must hold the cumulative"),
    ([20e-6, 30e-6, 40e-6], [0.0, 0.5, 1.2], r"`psd\.volume_fractions` must hold the cumulative"),
    ([20e-6, 30e-6, 40e-6], [0.3, 0.3, 0.3], r"`psd\.volume_fractions` must hold the cumulative"),
    ([], [0.0, 0.5, 1.0], r"`psd\.diameters` must list at least 3"),
])
def test_a_bad_table_is_refused_naming_the_key(d, F, match):
    with pytest.raises(ConfigError, match=match):
        load_config(preset="tiny", overrides=[f"psd.diameters={d!r}", f"psd.volume_fractions={F!r}"])
    with pytest.raises(ConfigError, match=match):
        tabulated_psd_sampler(d, F)
