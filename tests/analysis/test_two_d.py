"""2-D runs (discs in a plane), tilted boxes and too few particles, against known geometry."""

import warnings

import numpy as np
import pytest

from bedstruct import Box, Frame


def _square_discs(n=(8, 6), radius=0.5, thickness=0.56, velocities=None):
    """Touching discs on a square lattice at z = 0, in a periodic z box thinner than a diameter
    (a LAMMPS 2-D run)."""
    g = np.stack(np.meshgrid(np.arange(n[0]), np.arange(n[1]), [0.0], indexing="ij"), -1).reshape(-1, 3)
    pos = (g + [0.5, 0.5, 0.0]) * [2 * radius, 2 * radius, 1.0]
    box = Box([0, 0, -thickness / 2], [n[0] * 2 * radius, n[1] * 2 * radius, thickness / 2])
    return Frame(pos, np.full(len(pos), radius), box=box, velocities=velocities)


def _hexagonal_discs(nx=8, ny=6, d=1.0, gap=0.0):
    """Discs on a triangular lattice of spacing d + gap in a periodic box (rows of nx, ny even)."""
    a = d + gap
    rows = []
    for j in range(ny):
        for i in range(nx):
            rows.append([(i + 0.5 * (j % 2) + 0.25) * a, (j + 0.5) * a * np.sqrt(3) / 2, 0.0])
    box = Box([0, 0, -0.25 * d], [nx * a, ny * a * np.sqrt(3) / 2, 0.25 * d])
    return Frame(np.array(rows), np.full(nx * ny, d / 2), box=box)


def test_flat_axis_recognises_a_2d_run_and_not_a_3d_bed():
    from bedstruct.analysis import flat_axis
    from lattices import cubic_lattice
    assert flat_axis(_square_discs()) == 2
    assert flat_axis(_hexagonal_discs()) == 2
    assert flat_axis(cubic_lattice((4, 4, 4))) is None
    # one layer of spheres on a plate under a bounded z: a monolayer in 3-D
    assert flat_axis(cubic_lattice((4, 4, 1), boundary=("pp", "pp", "ff"))) is None


def test_find_contacts_counts_no_disc_touching_its_image_across_the_plane():
    from bedstruct.analysis import coordination, find_contacts
    sq = _square_discs()
    c = find_contacts(sq, tolerance=1e-9)
    assert not np.any(c.i == c.j)
    assert np.all(c.branch[:, 2] == 0)
    # touching discs on a square lattice: 4 neighbours each, in the plane
    np.testing.assert_array_equal(coordination(sq, c).per_particle, 4)
    hexa = _hexagonal_discs()
    np.testing.assert_array_equal(coordination(hexa, find_contacts(hexa, tolerance=1e-9)).per_particle, 6)
    # discs further apart than a diameter (the LAMMPS 2-D LJ example): no contact at all
    assert find_contacts(_hexagonal_discs(gap=0.1225)).n_contacts == 0


def test_area_fraction_of_disc_lattices_is_the_geometric_one():
    from bedstruct.analysis import area_fraction, area_fractions, bed_windows, disc_rectangle_area
    sq = _square_discs()
    assert area_fraction(sq).fraction == pytest.approx(np.pi / 4, rel=1e-12)
    hexa = _hexagonal_discs()
    assert area_fraction(hexa).fraction == pytest.approx(np.pi / (2 * np.sqrt(3)), rel=1e-12)
    # windows cut discs anywhere, periodic images included: the lattice value in whole periods
    lo, hi = bed_windows(sq, 4, axis=0)
    lo[:, 0] += 0.3
    hi[:, 0] += 0.3
    np.testing.assert_allclose(area_fractions(sq, lo, hi).fractions, np.pi / 4, rtol=1e-12)
    # a disc cut by the rectangle through its centre and by a corner
    np.testing.assert_allclose(disc_rectangle_area([[0, 0], [1, 1], [0, 0.5]], [1, 1, 1], [-1, -1], [1, 1]),
                               [np.pi, np.pi / 4, np.pi - (np.pi / 3 - np.sqrt(3) / 4)], rtol=1e-12)
    with pytest.raises(ValueError, match="not a 2-D run"):
        from lattices import cubic_lattice
        area_fraction(cubic_lattice())


def test_disc_rectangle_area_matches_a_fine_grid():
    from bedstruct.analysis import disc_rectangle_area
    rng = np.random.default_rng(3)
    x = (np.arange(2000) + 0.5) / 2000 * 4 - 2
    gx, gy = np.meshgrid(x, x, indexing="ij")
    for _ in range(4):
        c, r = rng.uniform(-0.5, 0.5, 2), rng.uniform(0.4, 1.2)
        lo = rng.uniform(-1.5, 0, 2)
        hi = lo + rng.uniform(0.3, 1.8, 2)
        inside = ((gx - c[0]) ** 2 + (gy - c[1]) ** 2 <= r * r) & (gx >= lo[0]) & (gx <= hi[0]) \
            & (gy >= lo[1]) & (gy <= hi[1])
        assert disc_rectangle_area([c], [r], lo, hi)[0] == pytest.approx(inside.sum() * (4 / 2000) ** 2,
                                                                          abs=2e-3)


def test_bed_state_of_a_2d_run_uses_the_area_fraction_and_refuses_3d_analyses():
    from bedstruct.analysis import bed_state
    st = bed_state(_square_discs(), contacts=None)
    assert st.dimension == 2 and st.flat_axis == 2
    assert st.packing_fraction == pytest.approx(np.pi / 4, rel=1e-12)
    assert st.kind == "settled bed" and st.mean_coordination == 4.0    # touching discs, in the plane
    st = bed_state(_hexagonal_discs(gap=-0.01))    # overlapping by 1 %: a held 2-D bed
    assert st.kind in ("settled bed", "pile") and st.mean_coordination == pytest.approx(6.0)
    assert "2-D run" in st.reason and st.label.startswith("a 2-D ")
    for key in ("german", "rdf", "voronoi", "surface", "fabric", "harmonics", "repose", "heat"):
        assert "2-D run" in st.not_meaningful[key]
    assert st.meaningful("coordination") and st.meaningful("packing") and st.meaningful("psd")


def test_bed_state_of_a_2d_heap_finds_a_pile_by_its_in_plane_height():
    # a triangular heap of discs in the x-y plane (flat along z): its height is along y, so
    # its top surface peaks; heights along z (all at one z) would show a flat top
    from bedstruct.analysis import bed_state
    a, nx = 0.99, 30
    rows = [[(i + 0.5 * j + 0.5) * a, (j + 0.5) * a * np.sqrt(3) / 2, 0.0] for j in range(nx) for i in range(nx - j)]
    heap = Frame(np.array(rows), np.full(len(rows), 0.5),
                 box=Box([0, 0, -0.28], [nx * a + 2, 27 * a, 0.28], boundary="ff ff pp"))
    st = bed_state(heap)
    assert st.flat_axis == 2 and st.kind == "pile" and st.peak > 0.3
    assert bed_state(_hexagonal_discs(gap=-0.01)).peak == pytest.approx(0.0, abs=1e-12)   # flat top


def test_bed_state_judges_a_tilted_box_as_its_orthogonal_copy():
    from bedstruct.analysis import bed_state
    rng = np.random.default_rng(0)
    pos = rng.uniform([0.5, 0.5, 0.5], [9.5, 9.5, 29.5], (60, 3))
    ortho = Frame(pos, np.full(60, 0.5), box=Box([0, 0, 0], [10, 10, 30], boundary="pp pp ff"))
    tilted = Frame(pos, np.full(60, 0.5), box=Box([0, 0, 0], [10, 10, 30], tilt=[0.01, 0, 0], boundary="pp pp ff"))
    a, b = bed_state(ortho), bed_state(tilted)
    assert a.kind == b.kind == "dilute flow"
    assert a.not_meaningful == b.not_meaningful
    assert b.packing_fraction == pytest.approx(a.packing_fraction, rel=1e-12)


def test_bed_state_marks_a_handful_of_particles_and_an_empty_frame():
    from bedstruct.analysis import bed_state
    from bedstruct.analysis.bed_state import MIN_PARTICLES
    two = Frame([[1, 1, 1], [2, 1, 1]], [0.5, 0.5], box=Box([0, 0, 0], [3, 2, 2], boundary="ff ff ff"))
    st = bed_state(two)
    for key in ("packing", "rdf", "voronoi", "german"):
        assert f"fewer than {MIN_PARTICLES}" in st.not_meaningful[key]
    empty = bed_state(Frame(np.zeros((0, 3)), np.zeros(0), box=[2, 2, 2]))
    assert empty.label == "an empty frame"
    assert {"packing", "psd", "rdf", "voronoi", "coordination"} <= set(empty.not_meaningful)


def test_radial_distribution_wraps_a_coordinate_a_rounding_error_below_the_box():
    from bedstruct.analysis import radial_distribution
    rng = np.random.default_rng(1)
    pos = rng.uniform(0, 10, (50, 3))
    pos[0, 0] = -1e-16                  # np.mod gives exactly 10.0
    res = radial_distribution(Frame(pos, np.full(50, 0.3), box=[10, 10, 10]), cutoff=2.0, n_bins=10)
    assert res.n_pairs.sum() > 0


def test_first_peak_is_none_when_no_pair_lies_within_the_cutoff():
    from bedstruct.analysis import radial_distribution
    f = Frame([[0.1, 0.5, 0.5], [9.9, 1.5, 1.5]], [0.05, 0.05], box=Box([0, 0, 0], [10, 2, 2], boundary="ff ff ff"))
    res = radial_distribution(f)
    assert np.all(res.n_pairs == 0) and res.first_peak is None


def test_german_law_along_refuses_a_falling_cloud():
    from bedstruct.analysis import german_law_along
    rng = np.random.default_rng(2)
    g = np.stack(np.meshgrid(*[np.arange(k) for k in (24, 4, 4)], indexing="ij"), -1).reshape(-1, 3) * 3.0 + 1.0
    cloud = Frame(g + rng.normal(0, 0.1, g.shape), np.full(len(g), 0.5),
                  box=Box([0, 0, 0], [72, 12, 12], boundary="pp pp ff"))
    with pytest.raises(ValueError, match="not meaningful for this frame \\(a dilute flow\\)"):
        german_law_along(cloud)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert german_law_along(cloud, check_state=False).n_windows == 12     # asked for: fitted


def test_german_law_along_refuses_a_2d_run():
    from bedstruct.analysis import german_law_along
    with pytest.raises(ValueError, match="2-D"):
        german_law_along(_hexagonal_discs(nx=24, gap=-0.01))
