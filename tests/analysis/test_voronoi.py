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
