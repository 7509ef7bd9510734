import numpy as np
import pytest

from bedstruct import Box, Frame
from bedstruct.analysis import radial_distribution
from lattices import fcc_lattice


@pytest.mark.parametrize("boundary", ["pp pp pp", "pp pp ff", "ff ff ff"])
def test_ideal_gas_is_one_at_every_distance_with_and_without_walls(boundary):
    # without the set-covariance correction g(2) would be about 0.75 (pp pp ff) and 0.5 (ff ff ff)
    rng = np.random.default_rng(7)
    gs = []
    for _ in range(4):
        pos = rng.uniform(0, [10, 6, 4], (1500, 3))
        f = Frame(pos, np.full(1500, 0.01), box=Box([0, 0, 0], [10, 6, 4], boundary=boundary))
        gs.append(radial_distribution(f, cutoff=2.0, n_bins=10).g)
    g = np.mean(gs, axis=0)
    assert np.all(np.abs(g[2:] - 1) < 0.03), g     # bins from r = 0.4 hold > 1000 pairs each
    assert abs(np.mean(g[2:]) - 1) < 0.01


def test_pair_counts_match_brute_force_with_minimum_image():
    rng = np.random.default_rng(3)
    pos = rng.uniform(0, [5, 4, 3], (300, 3))
    f = Frame(pos, np.full(300, 0.1), box=Box([0, 0, 0], [5, 4, 3], boundary="pp ff pp"))
    res = radial_distribution(f, cutoff=1.4, n_bins=7)
    d = pos[:, None] - pos[None]
    L = np.array([5.0, 0.0, 3.0])
    d -= L * np.round(d / np.array([5.0, 1.0, 3.0]))
    r = np.sqrt((d ** 2).sum(-1))[np.triu_indices(300, 1)]
    np.testing.assert_array_equal(res.n_pairs, np.histogram(r, bins=np.linspace(0, 1.4, 8))[0])


def test_fcc_shells_sit_at_d_sqrt2_d_and_sqrt3_d():
    fcc = fcc_lattice((5, 5, 5))                     # unit diameter, 500 spheres, periodic
    res = radial_distribution(fcc, cutoff=1.8, n_bins=120)      # bins of 0.015: no shell on an edge
    peaks = res.r[res.n_pairs > 0]
    # every pair sits on a shell: 12 at d, 6 at sqrt(2) d, 24 at sqrt(3) d per sphere
    for shell, count in ((1.0, 12), (np.sqrt(2), 6), (np.sqrt(3), 24)):
        near = np.abs(res.r - shell) < 0.0076
        assert res.n_pairs[near].sum() == 500 * count / 2
    assert np.all(np.min(np.abs(peaks[:, None] - [1.0, np.sqrt(2), np.sqrt(3)]), axis=1) < 0.0076)
    assert res.first_peak[0] == pytest.approx(1.0, abs=0.0076)


def test_errors_name_the_parameter():
    f = Frame([[1, 1, 1], [2, 1, 1]], [0.5, 0.5], box=Box([0, 0, 0], [4, 4, 4]))
    with pytest.raises(ValueError, match="at most half the periodic box length"):
        radial_distribution(f, cutoff=3.0)
    with pytest.raises(ValueError, match="at least 2 particles"):
        radial_distribution(Frame([[1, 1, 1]], [0.5], box=[4, 4, 4]))
    with pytest.raises(ValueError, match="`n_bins`"):
        radial_distribution(f, n_bins=0)
    with pytest.raises(ValueError, match="tilted"):
        radial_distribution(Frame([[1, 1, 1], [2, 1, 1]], [0.5, 0.5],
                                  box=Box([0, 0, 0], [4, 4, 4], tilt=[0.5, 0, 0])))
