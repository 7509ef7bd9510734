"""Packing fractions: exact sphere-cuboid volumes, lattices, windows, periodic images."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

import bedstruct
from bedstruct import Box, Frame
from bedstruct.analysis import (bed_bounds, bed_windows, layer_packing, packing_along,
                                packing_fraction, packing_grid,
                                packing_sliding, packing_table, sphere_box_volume)
from bedstruct.analysis._packing_kernels import _disc_rect
from lattices import cubic_lattice, fcc_lattice




BALL = 4.0 / 3.0 * math.pi


def test_special_cases():
    v = sphere_box_volume([[0, 0, 0]] * 5, [1.0] * 5,
                          [-1, -1, -1], [1, 1, 1]) / BALL
    assert np.allclose(v, 1.0, rtol=1e-14)
    c = np.array([[0, 0, 1.0], [0, 1, 1], [1, 1, 1], [0, 0, 0.5], [0, 0, 1.5]])
    v = sphere_box_volume(c, np.ones(5), [-1, -1, -1], [1, 1, 1])
    h1, h2 = 1.5, 0.5                                       # caps of height h: pi h^2 (3r - h) / 3
    expect = [BALL / 2, BALL / 4, BALL / 8, math.pi * h1 ** 2 * (3 - h1) / 3,
              math.pi * h2 ** 2 * (3 - h2) / 3]
    np.testing.assert_allclose(v, expect, rtol=1e-13)
    # a sphere bigger than the box contains it
    assert sphere_box_volume([[0.1, 0.2, 0.3]], [5.0], [-1, -1, -1], [1, 1, 1])[0] == pytest.approx(8.0, rel=1e-13)


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")
def test_disc_rectangle_area_against_quadrature():
    rng = np.random.default_rng(0)
    for _ in range(40):
        x0, x1 = np.sort(rng.uniform(-1.4, 1.4, 2))
        y0, y1 = np.sort(rng.uniform(-1.4, 1.4, 2))

        def chord(x):
            h = math.sqrt(max(1 - x * x, 0.0))
            return max(0.0, min(y1, h) - max(y0, -h))
        a, b = max(x0, -1), min(x1, 1)
        if b <= a:
            assert _disc_rect(x0, x1, y0, y1, 1.0) == 0.0
            continue
        # split at the kinks and smooth the square-root ends so quad is exact to ~1e-15
        kinks = sorted(p for y in (y0, y1) if abs(y) < 1
                       for p in (-math.sqrt(1 - y * y), math.sqrt(1 - y * y)) if a < p < b)
        edges = [a, *kinks, b]
        ref = 0.0
        for s, t in zip(edges[:-1], edges[1:]):
            ref += integrate.quad(lambda u: chord(s + (t - s) * (3 * u * u - 2 * u ** 3))
                                  * 6 * u * (1 - u) * (t - s), 0, 1, epsabs=1e-15, epsrel=1e-14, limit=200)[0]
        assert _disc_rect(x0, x1, y0, y1, 1.0) == pytest.approx(ref, abs=1e-12)


def test_volume_independent_of_integration_axis():
    """Permuting axes changes the integration axis and all breakpoints: results agree to 1e-11."""
    rng = np.random.default_rng(1)
    c = rng.uniform(-1, 1, (400, 3))
    r = rng.uniform(0.3, 1.2, 400)
    lo = np.array([-0.7, -0.2, -0.5])
    hi = np.array([0.4, 0.9, 0.3])
    base = sphere_box_volume(c, r, lo, hi)
    for perm in ([1, 2, 0], [2, 0, 1], [1, 0, 2]):
        other = sphere_box_volume(c[:, perm], r, lo[perm], hi[perm])
        np.testing.assert_allclose(other, base, atol=1e-11 * BALL * r.max() ** 3)
    assert (base > 0).sum() > 300


def test_volume_against_monte_carlo():
    rng = np.random.default_rng(2)
    for _ in range(6):
        c = rng.uniform(-0.5, 0.5, 3)
        r = rng.uniform(0.5, 1.0)
        lo = rng.uniform(-1.0, 0.0, 3)
        hi = lo + rng.uniform(0.4, 1.2, 3)
        n = 1_000_000
        p = c + rng.uniform(-r, r, (n, 3))
        inside = (np.sum((p - c) ** 2, axis=1) <= r * r) & np.all((p >= lo) & (p <= hi), axis=1)
        frac = inside.mean()
        mc = frac * (2 * r) ** 3
        se = math.sqrt(frac * (1 - frac) / n) * (2 * r) ** 3
        exact = sphere_box_volume([c], [r], lo, hi)[0]
        assert abs(exact - mc) < 5 * se + 1e-12


def test_lattices():
    sc = cubic_lattice((4, 4, 4))
    assert bedstruct.packing_fraction(sc).fraction == pytest.approx(math.pi / 6, rel=1e-14)
    # any window spanning whole periods, anywhere (periodic images fill it in)
    for shift in (0.0, 0.37, 3.9):
        lo = np.array([0.1, 0.2, 0.3]) + shift
        res = packing_fraction(sc, (lo, lo + [2, 3, 4]))
        assert res.fraction == pytest.approx(math.pi / 6, rel=1e-12)
    fcc = fcc_lattice((3, 3, 3))
    assert packing_fraction(fcc).fraction == pytest.approx(math.pi / (3 * math.sqrt(2)), rel=1e-12)
    a = fcc.box.lengths[0] / 3
    res = packing_fraction(fcc, ([0.3, 0.1, 0.2], [0.3 + 2 * a, 0.1 + a, 0.2 + 3 * a]))
    assert res.fraction == pytest.approx(0.74048, abs=1e-5)
    # fixed box: sphere extents are exactly the box
    open_sc = cubic_lattice((3, 4, 5), boundary=("ff",) * 3)
    r = packing_fraction(open_sc)
    assert r.fraction == pytest.approx(math.pi / 6) and r.definition == "bounding-box"
    assert float(r) == r.fraction and f"{r:.4f}" == "0.5236"


def test_periodic_images_counted_once():
    box = Box([0, 0, 0], [4, 4, 4], boundary="pp pp ff")
    f = Frame([[0.2, 3.9, 2.0]], [0.5], box=box)            # crosses x and y boundaries
    whole = packing_fraction(f, ([0, 0, 0], [4, 4, 4]))
    assert whole.solid_volume == pytest.approx(BALL * 0.125, rel=1e-13)
    # the quarter of the sphere beyond x = 0 sits at the far side, inside x in [3.5, 4]
    far = packing_fraction(f, ([3.5, 0, 0], [4, 4, 4]))
    near = packing_fraction(f, ([0, 0, 0], [3.5, 4, 4]))
    h = 0.3
    assert far.solid_volume == pytest.approx(math.pi * h * h * (1.5 - h) / 3, rel=1e-12)
    assert far.solid_volume + near.solid_volume == pytest.approx(whole.solid_volume, rel=1e-12)


def test_triclinic_periodic_window_equals_explicit_images():
    rng = np.random.default_rng(4)
    box = Box([0, 0, 0], [5, 4, 6], tilt=[1.0, -0.8, 0.6], boundary="pp pp pp")
    f = Frame(box.cartesian(rng.uniform(0, 1, (60, 3))), rng.uniform(0.3, 0.9, 60), box=box)
    lo, hi = np.array([0.5, 0.7, 1.0]), np.array([3.5, 3.0, 4.5])
    got = packing_fraction(f, (lo, hi)).solid_volume
    shifts = np.array([[a, b, c] for a in (-2, -1, 0, 1, 2) for b in (-2, -1, 0, 1, 2)
                       for c in (-2, -1, 0, 1, 2)], float) @ box.matrix.T
    pos = box.wrap(f.positions)
    allpos = (pos[None] + shifts[:, None]).reshape(-1, 3)
    ref = sphere_box_volume(allpos, np.tile(f.radii, len(shifts)), lo, hi).sum()
    assert got == pytest.approx(ref, rel=1e-12)


def test_windows_partition_and_agree(random_bed):
    total = random_bed.particle_volume
    prof = packing_along(random_bed, 3)
    assert prof.solid_volume.sum() == pytest.approx(total, rel=1e-12)
    lo, hi = bed_bounds(random_bed)
    assert prof.window_volume.sum() == pytest.approx(np.prod(hi - lo))
    assert np.average(prof.fractions, weights=prof.window_volume) == pytest.approx(
        packing_fraction(random_bed).fraction, rel=1e-12)
    # sliding windows with step == width are the same windows
    third = (hi[0] - lo[0]) / 3
    slide = packing_sliding(random_bed, third, step=third)
    np.testing.assert_allclose(slide.fractions, prof.fractions, rtol=1e-12)
    # each window alone gives the same number
    for k in range(3):
        one = packing_fraction(random_bed, (prof.lower[k], prof.upper[k]))
        assert one.fraction == pytest.approx(prof.fractions[k], rel=1e-12)
    grid = packing_grid(random_bed, (3, 2, 4))
    cell = np.prod([np.diff(e)[0] for e in grid.edges])
    assert (grid.fractions * cell).sum() == pytest.approx(total, rel=1e-12)
    # every cell where it belongs: the window kernel on that cell's bounds agrees
    for idx in np.ndindex(grid.fractions.shape):
        cell_lo = [grid.edges[a][idx[a]] for a in range(3)]
        cell_hi = [grid.edges[a][idx[a] + 1] for a in range(3)]
        one = packing_fraction(random_bed, (cell_lo, cell_hi))
        assert grid.fractions[idx] == pytest.approx(one.fraction, rel=1e-10, abs=1e-12)
    t = packing_table(prof)
    assert len(t["fraction"]) == 3 and set(t) >= {"x_lo", "z_hi"}


def test_translation_invariance_periodic():
    rng = np.random.default_rng(6)
    box = Box([0, 0, 0], [6, 6, 6])
    f = Frame(rng.uniform(0, 6, (200, 3)), rng.uniform(0.2, 0.6, 200), box=box)
    lo, hi = np.array([1.0, 0.5, 2.0]), np.array([4.0, 5.0, 3.5])
    a = packing_fraction(f, (lo, hi)).fraction
    t = np.array([2.3, -4.1, 0.7])
    g = Frame(box.wrap(f.positions + t), f.radii, box=box)
    assert packing_fraction(g, (lo + t, hi + t)).fraction == pytest.approx(a, rel=1e-12)


def test_layer_slab():
    sc = cubic_lattice((4, 4, 4), boundary=("pp", "pp", "ff"))
    assert layer_packing(sc, 0.0, 2.0).fraction == pytest.approx(math.pi / 6, rel=1e-12)
    # half a layer of spheres: the lower halves of the first row fill pi/6 as well
    assert layer_packing(sc, 0.0, 0.5).fraction == pytest.approx(math.pi / 6, rel=1e-12)
    lo, hi = bed_windows(sc, 4)
    assert np.allclose(np.diff(lo[:, 0]), 1.0)


def test_errors(sc_frame):
    with pytest.raises(ValueError, match="wider than the periodic box"):
        packing_fraction(sc_frame, ([0, 0, 0], [5, 1, 1]))
    with pytest.raises(ValueError, match="exceed"):
        packing_fraction(sc_frame, ([0, 0, 0], [0, 1, 1]))
    with pytest.raises(TypeError, match="pair"):
        packing_fraction(sc_frame, 3.0)
    with pytest.raises(ValueError, match="exceeds"):
        packing_sliding(sc_frame, 10.0)


from hypothesis import given, settings, strategies as st  # noqa: E402

coord = st.floats(-1.5, 1.5, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(coord, min_size=3, max_size=3), st.floats(0.2, 1.5), st.lists(coord, min_size=3, max_size=3),
       st.lists(st.floats(0.05, 2.0), min_size=3, max_size=3), st.integers(0, 2), st.floats(0.01, 0.99))
def test_volume_is_additive(c, r, lo, size, axis, frac):
    """Splitting a cuboid in two along any axis splits the sphere's volume exactly."""
    lo = np.array(lo)
    hi = lo + np.array(size)
    cut = lo[axis] + frac * (hi[axis] - lo[axis])
    hi1 = hi.copy()
    hi1[axis] = cut
    lo2 = lo.copy()
    lo2[axis] = cut
    whole = sphere_box_volume([c], [r], lo, hi)[0]
    parts = sphere_box_volume([c], [r], lo, hi1)[0] + sphere_box_volume([c], [r], lo2, hi)[0]
    assert parts == pytest.approx(whole, abs=1e-11 * r ** 3)
    assert -1e-15 <= whole <= min(BALL * r ** 3, np.prod(size)) * (1 + 1e-12)
