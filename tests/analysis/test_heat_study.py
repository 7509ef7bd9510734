"""Tests of bedstruct.analysis.heat_study (seed section 2.4.2 on bed regions).

Lattices with known answers: a cubic lattice gives round zones and mirror-equal
start and end regions; a lattice compressed along x gives a zone elongated along
x with the continuum roundness sqrt(D_y / D_x); tiling a periodic strip equals
building the wide lattice; scaling every conductance only rescales time.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bedstruct.analysis.heat import COCR, ThermalMaterial, thermal_network
from bedstruct.analysis.heat_study import heat_regions, heat_regions_table, planar_axes, tile_network
from bedstruct.core import Box, Contacts, Frame, Units


def lattice(n, spacing, radius, boundary="ff ff ff"):
    """Simple-cubic lattice, per-axis spacing, six-neighbour contacts by index (micrometres)."""
    n = np.asarray(n)
    s = np.broadcast_to(np.asarray(spacing, dtype=float), (3,))
    grid = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    box = Box([0, 0, 0], n * s, boundary=boundary)
    index = np.arange(len(grid)).reshape(tuple(n))
    ii, jj, br = [], [], []
    for ax in range(3):
        sh = np.zeros(3, dtype=int)
        sh[ax] = 1
        nb = grid + sh
        ok = nb[:, ax] < n[ax]
        if box.periodic[ax]:
            nb[:, ax] %= n[ax]
            ok[:] = True
        src = np.flatnonzero(ok)
        ii.append(src)
        jj.append(index[tuple(nb[src].T)])
        br.append(np.tile(sh * s, (len(src), 1)))
    i, j, b = np.concatenate(ii), np.concatenate(jj), np.concatenate(br)
    r = np.full(len(grid), float(radius))
    f = Frame((grid + 0.5) * s, r, box=box, units=Units("micro"))
    return f, Contacts(i, j, b, r[i], r[j], n_particles=len(r))


def test_cubic_lattice_regions_are_round_and_start_mirrors_end():
    f, c = lattice((39, 13, 4), 20.0, 10.5)
    # a one-particle source (centred over a site) cooled far: the continuum limit
    res = heat_regions(f, c, source_diameter=25e-6, cell=2.5e-6, stop_fraction=0.01,
                       threshold_fraction=0.3, atol=0.5)
    assert res.names == ("start", "centre", "end")
    assert res.tiles == (1, 1, 1)
    assert res.roundness.shape == (3, 1)
    assert [len(n[0]) for n in res.source_nodes] == [1, 1, 1]
    assert np.all(res.roundness > 0.93)
    # start and end are mirror images of each other in x
    assert res.peak_temperature[0, 0] == pytest.approx(res.peak_temperature[2, 0], rel=1e-6)
    assert res.roundness[0, 0] == pytest.approx(res.roundness[2, 0], abs=1e-3)
    # the common end time is the median crossing; the hottest particle there sits at the stop level
    T0, Ts = res.initial_temperature, res.source_temperature
    assert res.time == pytest.approx(np.median(res.crossing_times))
    k = int(np.argmin(np.abs(res.crossing_times[:, 0] - res.time)))
    assert res.peak_temperature[k, 0] == pytest.approx(T0 + 0.01 * (Ts - T0), abs=1.0)
    assert np.all(res.peak_temperature > T0) and np.all(res.peak_temperature < Ts)
    # the outline is halfway between ambient and the hottest visible cell
    top = np.array([np.nanmax(m[0].values) for m in res.maps])
    np.testing.assert_allclose(res.thresholds[:, 0], T0 + 0.3 * (top - T0))
    # a regular block: isotropic in-plane conductivity and fabric (the windows' x faces, from
    # the spheres' extent, lie r - s/2 off the lattice planes: 1e-3 in the lateral volume)
    np.testing.assert_allclose(res.conductivity_roundness, 1.0, atol=1e-3)
    # contacts cut by a window face count with their inside fraction, while the 13 rows along
    # the free y surfaces have 12 bonds each (and 12.5 along x in the start and end windows,
    # which have one free x surface): the fabric sees the missing surface contacts
    np.testing.assert_allclose(res.fabric_ratio, [12 / 12.5, 12 / 13, 12 / 12.5], rtol=2e-3)
    t = heat_regions_table(res)
    assert set(len(v) for v in t.values()) == {3}
    np.testing.assert_allclose(t["peak_temperature_C"], res.peak_temperature[:, 0] - 273.15)
    np.testing.assert_allclose(t["roundness_std"], 0.0)


def test_isotropic_strip_regions_have_round_conductivity():
    # windows cut along x of a strip periodic in y: the cut contacts count with their inside
    # fraction, so the isotropic lattice gives K roundness 1 (not Kxx/Kyy = 1 - s/W)
    f, c = lattice((42, 10, 4), 20.0, 10.5, boundary="ff pp ff")
    res = heat_regions(f, c, source_diameter=45e-6, atol=0.5)
    assert [k.boundary[:2] for k in res.conductivity] == [("surface/window", "periodic"),
                                                          ("window", "periodic"),
                                                          ("window/surface", "periodic")]
    np.testing.assert_allclose(res.conductivity_roundness, 1.0, atol=2e-3)
    G = thermal_network(f, c).conductance      # the lattice's one contact conductance
    np.testing.assert_allclose(G, G[0], rtol=1e-12)
    G = float(G[0])
    for k in res.conductivity:
        assert k.tensor[0, 0] == pytest.approx(G / 20e-6, rel=1e-9)
        assert k.affine[0, 0] == pytest.approx(G / 20e-6, rel=1e-9)


def test_compressed_lattice_zone_is_elongated_along_the_compression():
    s = np.array([18.5, 20.0, 20.0])
    r = 10.5
    a = np.sqrt(r ** 2 - (s / 2) ** 2)
    ratio = (a[0] / a[1]) * (s[0] / s[1]) ** 2          # D_x / D_y of the continuum
    f, c = lattice((33, 31, 4), s, r)
    res = heat_regions(f, c, n_regions=1, source_diameter=25e-6, cell=2.5e-6, stop_fraction=0.01,
                       threshold_fraction=0.3, atol=0.5)
    assert res.names == ("bed",)
    # K_aa = G_a s_a / (s_b s_c) of the infinite lattice, also for the finite block
    assert res.conductivity_roundness[0] == pytest.approx(1 / math.sqrt(ratio), rel=1e-9)
    assert res.conductivity_orientation_deg[0] == pytest.approx(0.0, abs=1e-6)
    assert abs(res.orientation_deg[0, 0]) < 5.0
    assert res.roundness[0, 0] == pytest.approx(1 / math.sqrt(ratio), abs=0.03)
    assert res.roundness[0, 0] < 0.93


def test_scaling_every_conductance_only_rescales_time():
    f, c = lattice((15, 15, 3), 20.0, 10.5)
    kw = dict(n_regions=1, source_diameter=45e-6, cell=2.5e-6, atol=0.05)
    a = heat_regions(f, c, **kw)
    fast = ThermalMaterial(COCR.density, COCR.specific_heat, 4 * COCR.conductivity)
    b = heat_regions(f, c, materials=fast, **kw)
    assert b.time == pytest.approx(a.time / 4, rel=1e-3)
    np.testing.assert_allclose(b.peak_temperature, a.peak_temperature, atol=0.5)
    np.testing.assert_allclose(b.roundness, a.roundness, atol=0.01)


def test_tiling_a_periodic_strip_equals_the_wide_lattice():
    strip, cs = lattice((6, 4, 3), 20.0, 10.5, boundary="ff pp ff")
    wide, cw = lattice((6, 12, 3), 20.0, 10.5, boundary="ff pp ff")
    t = tile_network(thermal_network(strip, cs), (1, 3, 1))
    w = thermal_network(wide, cw)
    assert t.n_particles == w.n_particles and t.n_contacts == w.n_contacts
    np.testing.assert_allclose(t.box_hi, w.box_hi)

    def edges(net):
        key = np.round(net.positions * 1e7).astype(np.int64)
        pi, pj = key[net.i], key[net.j]
        a = np.where((pi < pj).all(axis=1)[:, None] | (pi < pj)[:, :1], pi, pj)  # order-free pair
        b = np.where((a == pi).all(axis=1)[:, None], pj, pi)
        return sorted(map(tuple, np.hstack([a, b, np.round(net.conductance * 1e12)[:, None].astype(np.int64)])))

    assert sorted(map(tuple, np.round(t.positions * 1e7).astype(np.int64))) == \
        sorted(map(tuple, np.round(w.positions * 1e7).astype(np.int64)))
    assert edges(t) == edges(w)
    with pytest.raises(ValueError, match="not periodic"):
        tile_network(t, (2, 1, 1))


def test_narrow_periodic_strip_is_tiled_automatically():
    f, c = lattice((30, 4, 3), 20.0, 10.5, boundary="ff pp ff")   # 80 um wide
    res = heat_regions(f, c, n_regions=1, source_diameter=45e-6, cell=5e-6, n_sources=2, atol=0.5)
    assert res.tiles == (1, 4, 1)                                   # >= 6 x 45 um = 270 um
    assert res.roundness.shape == (1, 2) and res.source_centers.shape == (1, 2, 3)
    # the two sources sit half a period apart across the strip
    assert abs(res.source_centers[0, 1, 1] - res.source_centers[0, 0, 1]) == pytest.approx(40e-6)


def test_planar_axes_and_bad_input():
    ang, r = planar_axes([[1.0, 0, 0], [0, 4.0, 0], [0, 0, 1]])
    assert ang == pytest.approx(90.0) and r == pytest.approx(0.5)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    ang, r = planar_axes(R @ np.diag([9.0, 1.0, 1.0]) @ R.T)
    assert ang == pytest.approx(30.0) and r == pytest.approx(1 / 3)
    f, c = lattice((9, 9, 2), 20.0, 10.5)
    with pytest.raises(ValueError, match="stop_fraction"):
        heat_regions(f, c, stop_fraction=1.5)
    with pytest.raises(ValueError, match="axis"):
        heat_regions(f, c, axis=2)
    with pytest.raises(ValueError, match="names"):
        heat_regions(f, c, names=["a"])
    with pytest.raises(ValueError, match="initial_temperature"):
        heat_regions(f, c, initial_temperature=2000.0)
