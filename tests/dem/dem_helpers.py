"""Builders shared by the engine tests (a uniquely named module: several conftest.py
files would shadow each other under ``from conftest import``)."""

from bedstruct import Box


def closed_box(size=2e-3):
    return Box([0, 0, 0], [size] * 3, boundary="ff ff ff")


def two_sphere_sim(model, *, R=1e-4, v0=0.5, gap=0.01, dt=None, **kw):
    from bedstruct.dem import Simulation
    sim = Simulation(closed_box(), model, gravity=(0, 0, 0), n_threads=1, dt=dt, v_max=max(v0, 0.1), **kw)
    c = 1e-3
    sim.add_particles([[c - (1 + gap) * R, c, c], [c + (1 + gap) * R, c, c]], [R, R],
                      velocities=[[v0, 0, 0], [-v0, 0, 0]])
    return sim
