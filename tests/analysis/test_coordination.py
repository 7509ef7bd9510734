"""Coordination numbers, rattler removal, windows and series."""

from __future__ import annotations

import numpy as np
import pytest

import bedstruct
from bedstruct import Contacts, Frame, FrameList
from bedstruct.analysis import (TimeSeries, bed_windows, coordination, coordination_by_window,
                                coordination_series, coordination_table, find_contacts,
                                remove_rattlers)
from lattices import cubic_lattice, fcc_lattice




def chain_contacts(pairs, n):
    pairs = np.asarray(pairs)
    m = len(pairs)
    return Contacts(i=pairs[:, 0], j=pairs[:, 1], branch=np.tile([1.0, 0, 0], (m, 1)),
                    radii_i=np.full(m, 0.5), radii_j=np.full(m, 0.5), n_particles=n)


def test_lattice_values(sc_frame, fcc_frame):
    sc = bedstruct.coordination(sc_frame)
    assert sc.mean == 6.0 and sc.mechanical == 6.0 and sc.n_rattlers == 0
    fcc = coordination(fcc_frame, tolerance=1e-9)
    assert np.all(fcc.per_particle == 12) and fcc.mechanical == 12.0


def test_rattler_removal_is_iterative():
    # a tetrahedron (each has 3) plus a tail 3-4-5: with min 3, the tail peels off one by one
    tet = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    c = chain_contacts(tet + [(3, 4), (4, 5)], 6)
    r = remove_rattlers(c, min_contacts=2)
    assert r.tolist() == [False] * 4 + [True, True]      # 5 has 1 -> removed, then 4 has 1
    res = coordination(Frame(np.zeros((6, 3)), np.ones(6), box=[9, 9, 9]), c, min_contacts=2)
    assert res.per_particle.tolist() == [3, 3, 3, 4, 2, 1]
    assert res.mean == pytest.approx(16 / 6)
    assert res.mean_excluding_rattlers == pytest.approx(13 / 4)
    assert res.mechanical == pytest.approx(3.0)            # 2 * 6 / 4
    assert res.per_particle_mechanical.tolist() == [3, 3, 3, 3, 0, 0]
    # everything goes when the threshold exceeds the tetrahedron's 3
    assert remove_rattlers(c, min_contacts=4).all()
    assert not remove_rattlers(c, min_contacts=0).any()


def test_open_lattice_surface_is_rattler_free_with_walls():
    f = cubic_lattice((3, 3, 3), boundary=("pp", "pp", "ff"))
    plain = coordination(f, min_contacts=6)
    assert plain.n_rattlers == 27                         # top/bottom have 5, cascade removes all
    walls = coordination(f, walls=["zlo", "zhi"], include_walls=True, min_contacts=6)
    assert walls.n_rattlers == 0 and walls.mean == 6.0


def test_by_window_and_table(random_bed):
    res = coordination(random_bed)
    lo, hi = bed_windows(random_bed, 3)
    w = coordination_by_window(random_bed, lo, hi, result=res)
    assert w.n_particles.sum() == random_bed.n_particles
    # the windows partition the particles, so the count-weighted mean is the global mean
    assert np.average(w.mean, weights=w.n_particles) == pytest.approx(res.mean)
    t = coordination_table(res, random_bed)
    assert set(t) == {"id", "cn", "cn_mechanical", "rattler"}
    assert all(len(v) == random_bed.n_particles for v in t.values())


def test_series_and_errors(sc_frame):
    frames = FrameList([sc_frame, fcc_lattice()])
    s = coordination_series(frames, tolerance=1e-9)
    assert s.mean.tolist() == [6.0, 12.0]
    with pytest.raises(ValueError, match="frame has"):
        coordination(sc_frame, find_contacts(fcc_lattice()))
    with pytest.raises(TypeError, match="Contacts"):
        coordination(sc_frame, contacts=[1, 2])
    with pytest.raises(ValueError, match="min_contacts"):
        remove_rattlers(find_contacts(sc_frame), min_contacts=-1)
    empty = coordination(Frame(np.zeros((0, 3)), np.zeros(0), box=[1, 1, 1]))
    assert np.isnan(empty.mean) and empty.n_particles == 0


def test_timeseries_runner(sc_frame):
    frames = FrameList([sc_frame, fcc_lattice(), sc_frame])
    ts = TimeSeries(coordination, tolerance=1e-9)
    with pytest.raises(AttributeError, match="run"):
        ts.results
    res = ts.run(frames, start=1).results
    assert res.frames.tolist() == [1, 2] and res.field("mean").tolist() == [12.0, 6.0]
    table = res.table()
    assert table["mechanical"].tolist() == [12.0, 6.0] and "per_particle" not in table


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5])
def test_peeling_matches_simultaneous_removal(random_bed, k):
    """The O(N+M) queue kernel equals repeated simultaneous removal in NumPy (with walls)."""
    c = find_contacts(random_bed, walls=["zlo"])
    n = random_bed.n_particles
    wall = np.bincount(c.walls.particle, minlength=n)
    active = np.ones(n, dtype=bool)
    while True:
        keep = active[c.i] & active[c.j]
        cnt = (np.bincount(c.i[keep], minlength=n) + np.bincount(c.j[keep], minlength=n)
               + wall * active)
        drop = active & (cnt < k)
        if not drop.any():
            break
        active &= ~drop
    got = remove_rattlers(c, min_contacts=k, include_walls=True)
    assert np.array_equal(got, ~active)
    assert 0 < got.sum() < n or k in (1, 5)


def test_default_threshold_is_two(random_bed):
    res = coordination(random_bed)
    assert res.min_contacts == 2
    assert np.all(res.per_particle_mechanical[~res.rattlers] >= 2)
