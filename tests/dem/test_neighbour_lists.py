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
