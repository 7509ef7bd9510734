"""The engine's neighbour lists hold every contact between their builds."""

import numpy as np

from bedstruct import Box
from bedstruct.dem import ContactModel, Material, Plane, Simulation

E, NU, RHO = 1e7, 0.3, 2500.0
R = 40e-6


def test_a_moving_wall_list_built_between_rebuilds_keeps_every_contact():
    # A sphere 1.2 skins from a wall moves 0.45 skin away while the wall advances 0.55 skin
    # (the wall lists are rebuilt on their own when the wall has moved half a skin), then
    # comes back 0.9 skin while the wall advances 0.44 skin more. Neither the pair list nor
    # the wall lists are due by then, yet the two overlap by 0.24 skin: the lists built
    # mid-way must count the sphere's displacement since the pair list's build.
    model = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.3)
    box = Box([-1e-3] * 3, [1e-3] * 3, boundary="ff ff ff")
    sim = Simulation(box, model, walls=[Plane((0, 0, 0), (1, 0, 0), name="wall")],
                     gravity=(0.0, 0.0, 0.0), n_threads=1)
    skin = 0.15 * 2 * R
    sim.add_particles([[R + 1.2 * skin, 0.0, 0.0]], [R])
    sim.run(1)
    assert sim.skin == skin
    n = 100
    T = n * sim.dt
    sim.set_wall_motion("wall", velocity=(0.55 * skin / T, 0.0, 0.0))
    sim.v[:] = (0.45 * skin / T, 0.0, 0.0)
    sim.run(n)
    u2 = 0.9 * skin / T
    sim.v[:] = (-u2, 0.0, 0.0)
    sim.set_wall_motion("wall", velocity=(0.44 * skin / T, 0.0, 0.0))
    rebuilds = sim.n_rebuilds
    sim.run(n)
    assert sim.n_rebuilds == rebuilds  # no pair rebuild in the second stretch
    wall_x = sim.wall_states()[0].origin[0]
    np.testing.assert_allclose(wall_x, 0.99 * skin, rtol=1e-9)
    # without the contact the sphere would end at R + 0.75 skin, 0.24 skin inside the wall
    assert 0.75 * skin - wall_x < -0.2 * skin
    assert sim.v[0, 0] > -0.9 * u2  # the wall has pushed the sphere back
    assert sim.x[0, 0] - R - wall_x > -0.1 * skin


def _pile_in_a_tall_box(height, n=400):
    model = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.3)
    box = Box([0, 0, 0], [4e-3, 0.6e-3, height], boundary="ff pp ff")
    sim = Simulation(box, model, walls=[Plane((0, 0, 0), (0, 0, 1))], n_threads=1, seed=3)
    sim.insert_raindrop(n, R, region=((0, 0, 0), (4e-3, 0.6e-3, 0.25e-3)))
    return sim


def test_a_dense_pile_in_a_tall_box_keeps_cells_of_one_cutoff():
    # 400 spheres at the bottom of a box 108 cutoffs tall: the grid of one cutoff per cell
    # has 43 x 6 x 108 = 27,864 cells, 70 per sphere; a limit of 8 cells per sphere, every
    # axis halved, made cells of 4 cutoffs along x and z: 16 times the candidates per cell
    sim = _pile_in_a_tall_box(10e-3)
    sim.run(1)
    nc, cell = sim._cell_grid()
    cut = 2 * R + 0.15 * 2 * R
    assert sim.skin == 0.15 * 2 * R
    np.testing.assert_array_equal(nc, np.floor(sim._L / cut).astype(int))
    assert np.all(cell >= cut)
    # a box too large for cells of one cutoff: the grid is capped at max(32 n, 32768) cells,
    # coarsened along the axis with the most cells, never below 3 cells along a periodic axis
    sim = _pile_in_a_tall_box(2.0)
    sim.run(1)
    nc, cell = sim._cell_grid()
    assert 16384 < nc.prod() <= 32768 and tuple(nc[:2]) == (43, 6)
    assert np.all(cell >= cut)


def test_the_pair_list_holds_every_pair_within_the_cutoff_on_any_grid():
    # the same pile on cells of one cutoff (tall box) and on coarsened cells (taller box):
    # the same pairs, each within r_i + r_j + skin
    lists = []
    for height in (10e-3, 2.0):
        sim = _pile_in_a_tall_box(height)
        sim.run(1)
        d = sim.x[sim.pi] - sim.x[sim.pj] - sim.psh * sim._L
        dist = np.sqrt((d * d).sum(axis=1))
        assert np.all(dist < sim.rad[sim.pi] + sim.rad[sim.pj] + sim.skin)
        ids = np.sort(np.column_stack([sim.ids[sim.pi], sim.ids[sim.pj]]), axis=1)
        lists.append({tuple(p) for p in ids})
        x, rad, cut = sim.x, sim.rad, sim.skin
        n = len(x)
        # every pair within the cutoff (brute force, periodic along y) is listed
        dx = x[:, None, :] - x[None, :, :]
        dx[..., 1] -= sim._L[1] * np.round(dx[..., 1] / sim._L[1])
        within = np.sqrt((dx ** 2).sum(-1)) < rad[:, None] + rad[None, :] + cut
        iu = np.triu_indices(n, 1)
        want = {tuple(sorted((int(sim.ids[i]), int(sim.ids[j]))))
                for i, j in zip(*iu) if within[i, j]}
        assert want == lists[-1]
    assert lists[0] == lists[1] and len(lists[0]) > 200
