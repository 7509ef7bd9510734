"""The engine's run-directory dumps go through bedstruct.io's writers: exact round trip."""

import numpy as np

from bedstruct import Box
from bedstruct.dem import ContactModel, Material, Plane, Simulation
from bedstruct.io import read_dump, read_dump_local

R = 1e-4
MODEL = ContactModel(Material(1e7, 0.3, 2500.0), restitution=0.5, friction=0.5,
                     rolling_friction=0.1, cohesion=2e4)


def test_run_directory_dump_round_trips_bit_exactly(tmp_path):
    box = Box([0, 0, 0], [2e-3, 2e-3, 3e-3], boundary="pp pp ff")
    sim = Simulation(box, MODEL, walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")],
                     n_threads=1, seed=5)
    sim.insert_raindrop(80, lambda k, g: R * (0.6 + 0.8 * g.random(k)),
                        region=((0, 0, 0), (2e-3, 2e-3, 1e-3)))
    sim.run(3000, dump_every=1500, run_dir=tmp_path / "run")
    traj = read_dump(tmp_path / "run" / "dump.liggghts")
    assert len(traj) == 2 and traj[-1].timestep == sim.step
    got, ref = traj[-1], sim.frame()
    # floats are written shortest-round-trip: every value comes back bit for bit
    for name in ("positions", "velocities", "omegas", "forces", "radii", "ids", "types", "images"):
        assert np.array_equal(getattr(got, name), getattr(ref, name)), name
    assert np.array_equal(got.columns["mass"], ref.columns["mass"])
    # (N, 3) columns are written as name[1..3] and read back as three columns
    for k in range(3):
        assert np.array_equal(got.columns[f"torque[{k + 1}]"], ref.columns["torque"][:, k])
    cons = read_dump_local(tmp_path / "run" / "contacts.local", frames=list(traj))
    c, cref = cons[sim.step], sim.contacts()
    assert c.n_contacts == cref.n_contacts > 0
    key = lambda x: np.lexsort((x.ids_j, x.ids_i))  # noqa: E731
    assert np.array_equal(c.ids_i[key(c)], cref.ids_i[key(cref)])
