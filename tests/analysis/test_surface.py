"""Top-surface height maps, roughness and layer heights."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bedstruct import Box, Frame
from bedstruct.analysis import (bed_height, height_profile, layer_heights, surface_height_map,
                                surface_roughness)
from lattices import cubic_lattice




def brute_heights(frame, xs, ys, probe=0.0):
    box = frame.box
    out = np.full((xs.size, ys.size), -np.inf)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    for p, r in zip(box.wrap(frame.positions), frame.radii):
        for sx in (-1, 0, 1):
            for sy in (-1, 0, 1):
                if (sx and not box.periodic[0]) or (sy and not box.periodic[1]):
                    continue
                c = p + [sx * box.lengths[0], sy * box.lengths[1], 0]
                d2 = (X - c[0]) ** 2 + (Y - c[1]) ** 2
                R = r + probe
                h = np.where(d2 < R * R, c[2] + np.sqrt(np.clip(R * R - d2, 0, None)) - probe, -np.inf)
                out = np.maximum(out, h)
    return out


@pytest.mark.parametrize("probe", [0.0, 0.3])
def test_height_map_matches_brute_force(probe, random_bed):
    s = surface_height_map(random_bed, spacing=0.2, probe_radius=probe)
    ref = brute_heights(random_bed, s.x, s.y, probe)
    assert np.array_equal(np.isfinite(ref), s.covered)
    np.testing.assert_allclose(s.heights[s.covered], ref[s.covered], rtol=1e-13)


def test_probe_bridges_gaps():
    box = Box([0, 0, 0], [4, 2, 4], boundary="ff pp ff")
    f = Frame([[1.0, 1.0, 1.0], [3.0, 1.0, 1.0]], [0.9, 0.9], box=box)
    x, h0 = height_profile(surface_height_map(f, spacing=0.01, bounds=((0, 4), (0, 2))), statistic="max")
    x, h1 = height_profile(surface_height_map(f, spacing=0.01, bounds=((0, 4), (0, 2)), probe_radius=1.0),
                           statistic="max")
    mid = np.argmin(np.abs(x - 2.0))
    assert np.isnan(h0[mid])                               # gap between the spheres (0.2 wide)
    # probe of radius 1 resting on both: centre at 1 + sqrt(1.9^2 - 1), bottom 1 below
    assert h1[mid] == pytest.approx(1 + math.sqrt(1.9 ** 2 - 1) - 1, abs=5e-3)   # node 0.005 off
    assert np.all(h1[np.isfinite(h0)] >= h0[np.isfinite(h0)] - 1e-12)   # a probe cannot sink in


def test_roughness_definitions():
    z = np.array([[0.0, 1.0, 2.0, 5.0]])
    r = surface_roughness(z)
    # deviations -2, -1, 0, 3: Sa = 6/4, Sq^2 = 14/4, Ssk = (27 - 9)/4 / 3.5^1.5, Sku = 98/4 / 3.5^2
    assert r.mean_height == 2.0 and r.sz == 5.0
    assert r.sa == pytest.approx(1.5, rel=1e-12)
    assert r.sq == pytest.approx(math.sqrt(3.5), rel=1e-12)
    assert r.ssk == pytest.approx(4.5 / 3.5 ** 1.5, rel=1e-12)
    assert r.sku == pytest.approx(2.0, rel=1e-12)
    assert surface_roughness(-z).ssk == pytest.approx(-r.ssk)
    assert surface_roughness(-z).sku == pytest.approx(r.sku)
    # two levels: Sku = 1 (the least possible); Gaussian heights: Ssk 0, Sku 3
    assert surface_roughness([[0.0, 1.0] * 8]).sku == pytest.approx(1.0, rel=1e-12)
    gauss = surface_roughness(np.random.default_rng(1).normal(0.0, 2.0, 400000))
    assert gauss.sq == pytest.approx(2.0, rel=0.01)
    assert gauss.sa == pytest.approx(2.0 * math.sqrt(2 / math.pi), rel=0.01)
    assert gauss.ssk == pytest.approx(0.0, abs=0.02) and gauss.sku == pytest.approx(3.0, abs=0.05)
    assert np.isnan(surface_roughness([np.nan]).sa)


def test_flat_lattice_and_layers():
    sc = cubic_lattice((4, 4, 3), boundary=("pp", "pp", "ff"))
    s = surface_height_map(sc, spacing=0.01, base=0.0)
    assert s.uncovered_fraction == pytest.approx(1 - math.pi / 4, abs=0.002)   # rasterised discs
    assert s.heights.max() == pytest.approx(2.5 + math.sqrt(0.25 - 2 * 0.005 ** 2), abs=1e-12)
    # mean over a unit cell: 2.5 (pi/4) + (2/3) pi 0.5^3 + 0 (bare nodes at base)
    assert s.mean_height == pytest.approx(2.5 * math.pi / 4 + 2 / 3 * math.pi / 8, abs=0.005)
    with_gaps = surface_height_map(sc, spacing=0.01)
    assert np.nanmax(with_gaps.heights) == s.heights.max() and np.isnan(with_gaps.heights).any()
    hs = layer_heights([cubic_lattice((4, 4, k), boundary=("pp", "pp", "ff")) for k in (1, 2, 3)],
                       0.0, spacing=0.01)
    np.testing.assert_allclose(np.diff(hs), math.pi / 4, atol=0.003)   # one row of caps per layer
    assert bed_height(sc, 0.0, spacing=0.01) == pytest.approx(s.mean_height)


def test_periodic_wrap_and_translation_invariance():
    rng = np.random.default_rng(1)
    box = Box([0, 0, 0], [6, 5, 9], boundary="pp pp ff")
    f = Frame(rng.uniform([0, 0, 0], [6, 5, 3], (150, 3)), rng.uniform(0.3, 0.6, 150), box=box)
    a = surface_height_map(f, spacing=0.25)
    # shift by whole grid steps: the map rolls
    g = Frame(box.wrap(f.positions + [1.5, 0.75, 0.2]), f.radii, box=box)
    b = surface_height_map(g, spacing=0.25)
    np.testing.assert_allclose(np.roll(a.heights, (6, 3), axis=(0, 1)) + 0.2, b.heights, atol=1e-12)
    assert a.roughness.sq == pytest.approx(b.roughness.sq, rel=1e-12)


def test_errors():
    f = Frame([[0, 0, 0]], [1.0], box=[3, 3, 3])
    with pytest.raises(ValueError, match="spacing"):
        surface_height_map(f, spacing=0.0)
    with pytest.raises(ValueError, match="probe"):
        surface_height_map(f, probe_radius=-1.0)
    with pytest.raises(ValueError, match="no particles"):
        surface_height_map(Frame(np.zeros((0, 3)), np.zeros(0), box=[1, 1, 1]))


# --------------------------------------------------------------- grounded_particles

def _bed_with_flyers(seed=0):
    """A cubic lattice bed on z = 0, two particles in flight above it (one alone, one a touching
    pair) and one resting on the bed but written past the periodic x face."""
    bed = cubic_lattice((6, 4, 3), 1.0)                   # spheres of radius 0.5 on z = 0
    extra = np.array([[2.5, 1.5, 6.0],                    # alone, 3 diameters above the bed
                      [4.0, 2.5, 7.0], [4.98, 2.5, 7.0],  # a touching pair in flight
                      [6.49, 0.5, 3.45]])                 # on (0.5, 0.5, 2.5) through x = 6 = 0
    pos = np.concatenate([bed.positions, extra])
    return Frame(pos, np.full(len(pos), 0.5), box=Box([0, 0, -1], [6, 4, 10],
                                                      boundary=("pp", "pp", "ff")))


def test_grounded_particles_leaves_out_particles_in_flight():
    from bedstruct.analysis import grounded_particles
    fr = _bed_with_flyers()
    g = grounded_particles(fr, 0.0)
    n_bed = 6 * 4 * 3
    assert g[:n_bed].all()
    assert not g[n_bed:n_bed + 3].any()          # the lone flyer and the flying pair
    assert g[n_bed + 3]                           # rests on the bed across the periodic face
    # a flyer that lands (touches the top layer) joins the bed
    pos = fr.positions.copy()
    pos[n_bed, 2] = 3.0
    assert grounded_particles(Frame(pos, fr.radii, box=fr.box), 0.0)[n_bed]


def test_grounded_particles_is_invariant_under_periodic_shift_and_order():
    from bedstruct.analysis import grounded_particles
    fr = _bed_with_flyers()
    g = grounded_particles(fr, 0.0)
    shifted = fr.positions + [2.3, -1.7, 0.0]    # along the periodic axes only
    assert np.array_equal(grounded_particles(Frame(shifted, fr.radii, box=fr.box), 0.0), g)
    perm = np.random.default_rng(0).permutation(fr.n_particles)
    gp = grounded_particles(Frame(fr.positions[perm], fr.radii[perm], box=fr.box), 0.0)
    assert np.array_equal(gp, g[perm])


def test_grounded_particles_base_and_errors():
    from bedstruct.analysis import grounded_particles
    fr = _bed_with_flyers()
    # a base below the bed's lowest point by more than the tolerance grounds nothing
    assert not grounded_particles(fr, -1.0).any()
    assert grounded_particles(fr.select(np.zeros(fr.n_particles, bool)), 0.0).shape == (0,)
    with pytest.raises(ValueError, match="tolerance"):
        grounded_particles(fr, 0.0, tolerance=-1.0)
    with pytest.raises(ValueError, match="vertical"):
        grounded_particles(fr, 0.0, vertical=3)
