import numpy as np
import pytest

from bedstruct import Box, Frame
from lattices import cubic_lattice, fcc_lattice

pytest.importorskip("pyvoro2", reason="optional extra bedstruct[voronoi] (pyvoro2) not installed")

from bedstruct.analysis import local_packing, packing_along  # noqa: E402


def test_simple_cubic_lattice_is_pi_over_6_per_particle():
    lp = local_packing(cubic_lattice((5, 5, 5)))
    np.testing.assert_allclose(lp.fractions, np.pi / 6, rtol=1e-12)
    assert not lp.at_wall.any()


def test_fcc_lattice_is_0_7405_per_particle():
    lp = local_packing(fcc_lattice((4, 4, 4)))
    np.testing.assert_allclose(lp.fractions, np.pi / (3 * np.sqrt(2)), rtol=1e-12)
    assert lp.fractions[0] == pytest.approx(0.7405, abs=5e-5)


def test_radical_faces_are_the_tangent_planes_of_unequal_spheres():
    # touching spheres of radii 1 and 0.5 alternating along x in a periodic 1 x 1 column:
    # radical cells are slabs 2 and 1 long; plain Voronoi would give 1.5 each
    x = np.array([1.0, 2.5, 4.0, 5.5])
    f = Frame(np.c_[x, np.full(4, 0.5), np.full(4, 0.5)], [1.0, 0.5, 1.0, 0.5], box=Box([0, 0, 0], [6, 1, 1]))
    lp = local_packing(f)
    np.testing.assert_allclose(lp.cell_volumes, [2.0, 1.0, 2.0, 1.0], rtol=1e-12)


def test_cells_tile_the_region_with_walls_along_bounded_axes():
    rng = np.random.default_rng(5)
    pos = rng.uniform([0, 0, 0.2], [4, 3, 2.8], (200, 3))
    f = Frame(pos, rng.uniform(0.05, 0.15, 200), box=Box([0, 0, 0], [4, 3, 3], boundary="pp pp ff"))
    lp = local_packing(f, region=((0, 4), (0, 3), (0, 3)))
    assert lp.cell_volumes.sum() == pytest.approx(36.0, rel=1e-9)
    # particles nearest the bottom and top walls have cells closed by them; none in the middle
    z = pos[:, 2]
    assert lp.at_wall[np.argmin(z)] and lp.at_wall[np.argmax(z)]
    assert not lp.at_wall[(z > 1.2) & (z < 1.8)].any()
    with pytest.raises(ValueError, match="outside `region`"):
        local_packing(f, region=((0, 4), (0, 3), (1, 3)))


def test_mean_over_a_window_equals_the_windowed_packing_of_the_bundled_bed():
    from pathlib import Path
    import bedstruct
    sample = Path(__file__).parents[2] / "data" / "samples" / "spread" / "bed.dump.gz"
    bed = bedstruct.read_dump(sample, units="si")[-1]
    lp = local_packing(bed)
    prof = packing_along(bed, 3)
    x = bed.positions[:, 0]
    for k in range(3):
        inside = (x >= prof.lower[k, 0]) & (x < prof.upper[k, 0])
        # the cells of the particles centred in a window tile it up to its ragged ends
        assert lp.mean(inside) == pytest.approx(prof.fractions[k], abs=0.005)
    assert 0.55 < lp.mean() < 0.62            # away from the walls and the free surface


def _jittered_bed(scale, offset=0.0):
    """A jittered, polydisperse FCC bed under open space (pp pp ff), lengths times ``scale``."""
    f = fcc_lattice((4, 4, 3), boundary=("pp", "pp", "ff"))
    rng = np.random.default_rng(3)
    pos = f.positions + rng.normal(scale=0.03, size=f.positions.shape)
    radii = f.radii * rng.uniform(0.8, 1.0, f.n_particles)
    lo, hi = np.asarray(f.box.lo), np.asarray(f.box.hi)
    return Frame((pos + offset) * scale, radii * scale,
                 box=Box((lo + offset) * scale, (hi + offset) * scale, boundary=f.box.boundary))


@pytest.mark.parametrize("scale, offset", [(1e-5, 0.0), (1e-4, 0.0), (1.0, 1e5)])
def test_cells_do_not_depend_on_the_length_unit(scale, offset):
    # 10 um and 100 um spheres in metres, and a bed far from the origin, tessellate as the
    # same bed in units of its diameter does: voro++'s absolute tolerances do not see the unit
    ref = local_packing(_jittered_bed(1.0))
    lp = local_packing(_jittered_bed(scale, offset))
    np.testing.assert_allclose(lp.fractions, ref.fractions, rtol=1e-9)
    np.testing.assert_array_equal(lp.at_wall, ref.at_wall)
    np.testing.assert_allclose(lp.cell_volumes, ref.cell_volumes * scale ** 3, rtol=1e-9)
    # all cells together tile the bed's bounding box: their mean is its packing fraction
    from bedstruct.analysis import packing_fraction
    frame = _jittered_bed(scale, offset)
    assert lp.mean(np.ones(lp.n_particles, bool)) == pytest.approx(packing_fraction(frame).fraction, rel=1e-9)


def test_coincident_centres_are_named():
    f = cubic_lattice((3, 3, 3))
    pos = np.vstack([f.positions, f.positions[4]])
    with pytest.raises(ValueError, match=r"rows 4 and 27\): coincident particles"):
        local_packing(Frame(pos, np.full(len(pos), 0.5), box=f.box))
