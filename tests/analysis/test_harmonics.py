"""Real spherical harmonics: SciPy reference, orthonormality, invariance, exact tensor link."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import sph_harm_y

import bedstruct
from bedstruct.analysis import _fabric_kernels as K
from bedstruct.analysis.fabric import fabric_density, fabric_tensors, sample_directions
from bedstruct.analysis.harmonics import (
    HarmonicExpansion, _sphere_quadrature, fabric_from_harmonics, harmonic_density,
    harmonic_expansion, harmonics_from_fabric, real_spherical_harmonics, sphere_grid,
)

from _directions import random_rotation, unit


def scipy_real_ylm(l_max, d):
    """Independent reference built from SciPy's complex harmonics."""
    d = unit(d)
    th = np.arccos(np.clip(d[:, 2], -1, 1))
    ph = np.arctan2(d[:, 1], d[:, 0])
    out = np.zeros((len(d), (l_max + 1) ** 2))
    for l in range(l_max + 1):
        for m in range(-l, l + 1):
            if m > 0:
                v = np.sqrt(2) * (-1) ** m * sph_harm_y(l, m, th, ph).real
            elif m < 0:
                v = np.sqrt(2) * (-1) ** m * sph_harm_y(l, -m, th, ph).imag
            else:
                v = sph_harm_y(l, 0, th, ph).real
            out[:, l * l + l + m] = v
    return out


def test_real_harmonics_match_scipy():
    rng = np.random.default_rng(0)
    d = np.vstack([unit(rng.normal(size=(100, 3))), [[0, 0, 1], [0, 0, -1], [1, 0, 0]]])
    np.testing.assert_allclose(real_spherical_harmonics(d, 12), scipy_real_ylm(12, d), atol=1e-13)
    # high degree: the normalised recurrence stays accurate
    np.testing.assert_allclose(real_spherical_harmonics(d[:10], 40), scipy_real_ylm(40, d[:10]),
                               atol=1e-11)


def test_cartesian_forms_of_low_degrees():
    rng = np.random.default_rng(1)
    d = unit(rng.normal(size=(20, 3)))
    x, y, z = d.T
    y_ = real_spherical_harmonics(d, 2)
    c1 = np.sqrt(3 / (4 * np.pi))
    np.testing.assert_allclose(y_[:, 1:4], c1 * np.stack([y, z, x], 1), atol=1e-14)
    np.testing.assert_allclose(y_[:, 4], 0.5 * np.sqrt(15 / np.pi) * x * y, atol=1e-14)
    np.testing.assert_allclose(y_[:, 8], 0.25 * np.sqrt(15 / np.pi) * (x * x - y * y), atol=1e-14)


def test_orthonormal_on_the_sphere():
    q, w = _sphere_quadrature(2 * 10)
    y = real_spherical_harmonics(q, 10)
    np.testing.assert_allclose((y * w[:, None]).T @ y, np.eye(121), atol=1e-12)


def test_kernel_py_func_matches_compiled():
    rng = np.random.default_rng(2)
    d = unit(rng.normal(size=(30, 3)))
    a, b, f = K.recurrence_tables(6)
    o1 = np.zeros((2, 49))
    o2 = np.zeros((2, 49))
    K.harmonic_sums(d, np.empty(0), False, 6, False, a, b, f, 2, o1)
    K.harmonic_sums.py_func(d, np.empty(0), False, 6, False, a, b, f, 2, o2)
    np.testing.assert_allclose(o1, o2, atol=1e-13)


def test_coefficients_are_weighted_sample_means():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(500, 3)) * [2, 1, 0.5]
    w = rng.random(500)
    ref = w @ scipy_real_ylm(6, x) / w.sum()
    e = harmonic_expansion(x, 6, w, antipodal=False)
    np.testing.assert_allclose(e.coefficients, ref, atol=1e-14)
    assert e.coefficient(3, -2) == pytest.approx(ref[9 + 3 - 2], abs=1e-14)
    assert e.power[0] == pytest.approx(1 / (4 * np.pi))
    np.testing.assert_allclose(e.power, [np.sum(ref[l * l:(l + 1) ** 2] ** 2) for l in range(7)],
                               atol=1e-15)
    assert e.n_samples == 500 and e.total_weight == pytest.approx(w.sum())
    assert bedstruct.harmonic_expansion is harmonic_expansion


def test_antipodal_zeroes_odd_degrees_and_equals_symmetrised_data():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(300, 3)) + [1, 0, 0]
    a = harmonic_expansion(x, 7)
    sym = harmonic_expansion(np.vstack([x, -x]), 7, antipodal=False)
    np.testing.assert_allclose(a.coefficients, sym.coefficients, atol=1e-14)
    for l in (1, 3, 5, 7):
        assert np.all(a.degree(l) == 0.0) and a.power[l] == 0.0
    directed = harmonic_expansion(x, 7, antipodal=False)
    assert directed.power[1] > 0.01
    np.testing.assert_allclose(directed.degree(2), a.degree(2), atol=1e-14)


def test_power_is_rotation_invariant():
    rng = np.random.default_rng(5)
    x = sample_directions(3000, D2=np.diag([0.6, 0.2, -0.8]), rng=rng) + 0.3   # directed, skewed
    w = rng.random(len(x))
    for antipodal in (True, False):
        e = harmonic_expansion(x, 8, w, antipodal=antipodal)
        for _ in range(3):
            r = random_rotation(rng)
            er = harmonic_expansion(x @ r.T, 8, w, antipodal=antipodal)
            np.testing.assert_allclose(er.power, e.power, rtol=1e-11, atol=1e-16)
            assert not np.allclose(er.coefficients, e.coefficients)


def test_truncations_equal_tensor_approximations_exactly():
    rng = np.random.default_rng(6)
    x = sample_directions(5000, D2=np.diag([1.5, -0.5, -1.0]), rng=rng)
    w = rng.random(len(x))
    t = fabric_tensors(x, w)
    e = harmonic_expansion(x, 8, w)
    _, _, g = sphere_grid(25, 49)
    np.testing.assert_allclose(harmonic_density(e, g, l_max=2), fabric_density(t, g, rank=2), atol=1e-14)
    np.testing.assert_allclose(harmonic_density(e, g, l_max=4), fabric_density(t, g, rank=4), atol=1e-14)
    np.testing.assert_allclose(e.truncated(4).density(g), t.density(g), atol=1e-14)
    # and the l = 6, 8 terms are what the rank-4 tensors miss
    assert np.abs(harmonic_density(e, g) - fabric_density(t, g)).max() > 1e-4


def test_conversions_in_both_directions():
    rng = np.random.default_rng(7)
    x = rng.normal(size=(2000, 3)) * [1.5, 1, 0.6]
    t = fabric_tensors(x)
    e = harmonic_expansion(x, 8)
    back = fabric_from_harmonics(e)
    for name in ("N2", "N4", "F2", "F4", "D2", "D4"):
        np.testing.assert_allclose(getattr(back, name), getattr(t, name), atol=1e-13, err_msg=name)
    assert back.n_contacts == t.n_contacts
    h4 = harmonics_from_fabric(t, l_max=8)
    np.testing.assert_allclose(h4.coefficients, e.truncated(4).coefficients.tolist() + [0] * 56,
                               atol=1e-14)
    h2 = harmonics_from_fabric(t, l_max=4, rank=2)
    np.testing.assert_allclose(h2.coefficients[:9], e.coefficients[:9], atol=1e-14)
    assert np.all(h2.coefficients[9:] == 0)
    # from an l = 2 expansion only the rank-2 part survives
    t2 = fabric_from_harmonics(e.truncated(2))
    np.testing.assert_allclose(t2.D2, t.D2, atol=1e-13)
    np.testing.assert_allclose(t2.D4, 0, atol=1e-12)


def test_density_integrates_to_one():
    rng = np.random.default_rng(8)
    e = harmonic_expansion(rng.normal(size=(100, 3)), 6, antipodal=False)
    q, w = _sphere_quadrature(8)
    assert np.sum(w * harmonic_density(e, q)) == pytest.approx(1.0, abs=1e-13)


def test_input_validation():
    with pytest.raises(ValueError, match="l_max"):
        harmonic_expansion(np.eye(3), -1)
    with pytest.raises(ValueError, match="l_max"):
        harmonic_expansion(np.eye(3), True)
    with pytest.raises(ValueError, match="usable"):
        harmonic_expansion(np.zeros((2, 3)), 2)
    with pytest.raises(ValueError, match="length"):
        HarmonicExpansion.from_coefficients(np.ones(5))
    e = harmonic_expansion(np.eye(3), 2)
    with pytest.raises(ValueError):
        e.coefficient(3, 0)
    with pytest.raises(ValueError):
        e.truncated(4)
    with pytest.raises(ValueError, match="row 1"):
        real_spherical_harmonics([[1, 0, 0], [0, 0, 0]], 2)
    with pytest.raises(ValueError, match="c_00"):
        fabric_from_harmonics(HarmonicExpansion.from_coefficients(np.zeros(9)))


@pytest.mark.slow
def test_sampled_power_converges_to_analytic():
    """Large sample from f = (1 + D2 nn)/4pi: P_2 -> (2/15)(1/4pi) D:D, higher powers -> 0."""
    d2 = np.diag([2.0, -1.0, -1.0]) * 0.8
    x = sample_directions(1_000_000, D2=d2, rng=9)
    e = harmonic_expansion(x, 8)
    assert e.power[2] == pytest.approx(2 / 15 / (4 * np.pi) * np.sum(d2 * d2), rel=0.02)
    assert e.power[4] < 1e-5 and e.power[6] < 1e-5
