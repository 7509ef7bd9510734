"""Engine checks: neighbour list vs brute force, periodic contacts, determinism,
checkpoints, removal, settled bed, output, walls, time-step guard."""

import json
import math

import numpy as np
import pytest

from bedstruct import Box, UnsafeTimestepError
from bedstruct.dem import (Blade, ContactModel, Cylinder, Material, Plane, Simulation,
                           TriangleMesh, box_walls, repose_box)
from bedstruct.dem import _kernels as K

E, NU, RHO, R = 1e7, 0.3, 2500.0, 1e-4
MODEL = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5, rolling_friction=0.1,
                     cohesion=2e4)


def _gas(n=300, seed=0, n_threads=2, boundary="pp pp ff"):
    box = Box([0, 0, 0], [2e-3, 2e-3, 3e-3], boundary=boundary)
    sim = Simulation(box, MODEL, walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")],
                     n_threads=n_threads, seed=seed)
    rng = np.random.default_rng(seed)
    sim.insert_raindrop(n, lambda k, g: R * (0.6 + 0.8 * g.random(k)))
    sim.v[:] = rng.normal(0, 0.05, sim.v.shape)
    return sim


def _brute_pairs(sim, cutoff_extra):
    x = sim.x
    d = x[:, None, :] - x[None, :, :]
    L = sim.box.lengths
    for a in range(3):
        if sim.box.periodic[a]:
            d[..., a] -= L[a] * np.round(d[..., a] / L[a])
    r = np.sqrt((d ** 2).sum(-1))
    rc = sim.rad[:, None] + sim.rad[None, :] + cutoff_extra
    i, j = np.nonzero(np.triu(r < rc, 1))
    return {tuple(sorted((int(sim.ids[a]), int(sim.ids[b])))) for a, b in zip(i, j)}


def test_pair_list_matches_brute_force():
    sim = _gas(400)
    sim.run(50)
    sim._rebuild()
    got = [tuple(sorted((int(sim.ids[a]), int(sim.ids[b])))) for a, b in zip(sim.pi, sim.pj)]
    assert len(got) == len(set(got))  # each pair once
    assert set(got) == _brute_pairs(sim, sim.skin)
    # images stored with the pairs give the true (minimum image) distances
    d = sim.x[sim.pi] - sim.x[sim.pj] - sim.psh * sim.box.lengths
    assert np.all(np.sqrt((d ** 2).sum(1)) < sim.rad[sim.pi] + sim.rad[sim.pj] + sim.skin)


def test_periodic_contact_across_boundary():
    box = Box([0, 0, 0], [2e-3, 2e-3, 2e-3], boundary="pp pp ff")
    sim = Simulation(box, MODEL, gravity=(0, 0, 0), n_threads=1)
    sim.add_particles([[0.5 * R, 1e-3, 1e-3], [2e-3 - 1.4 * R, 1e-3, 1e-3]], [R, R])
    con = sim.contacts()
    assert con.n_contacts == 1 and bool(con.periodic[0])
    assert np.allclose(np.abs(con.branch[0]), [1.9 * R, 0, 0], atol=1e-12)
    sim.run(20)
    fr = sim.frame()
    # the sphere near x=0 is pushed towards +x, its image partner towards -x
    assert fr.velocities[0, 0] > 0 and fr.velocities[1, 0] < 0
    sim.run(3000)
    fr = sim.frame()
    assert np.all((fr.positions[:, 0] >= 0) & (fr.positions[:, 0] < 2e-3))


def test_deterministic_for_seed_and_threads():
    def run():
        sim = _gas(250, seed=4, n_threads=2)
        sim.run(400)
        return sim.frame()
    a, b = run(), run()
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.velocities, b.velocities)
    assert np.array_equal(a.omegas, b.omegas)


def test_checkpoint_resume_is_bit_identical(tmp_path):
    ref = _gas(250, seed=5, n_threads=2)
    ref.run(600)
    sim = _gas(250, seed=5, n_threads=2)
    sim.run(300)
    path = sim.save_checkpoint(tmp_path / "ck.npz")
    res = Simulation.from_checkpoint(path)
    res.run(300)
    a, b = ref.frame(), res.frame()
    assert res.step == ref.step and res.time == ref.time
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.velocities, b.velocities)
    assert np.array_equal(a.omegas, b.omegas)
    assert res.rng.random() == ref.rng.random()


def test_particles_leaving_the_domain_are_removed_and_counted():
    box = Box([0, 0, 0], [2e-3, 2e-3, 2e-3], boundary="pp pp ff")
    sim = Simulation(box, MODEL, n_threads=1)
    sim.add_particles([[1e-3, 1e-3, 0.5e-3], [0.5e-3, 0.5e-3, 1.5e-3]], [R, R],
                      velocities=[[0, 0, -1.0], [0, 0, 0]])
    stats = sim.run(time=2e-3)
    assert sim.n_removed == 1 and stats.n_removed == 1
    assert sim.n_particles == 1
    assert sim.frame().ids.tolist() == [2]


def test_small_settled_bed_stays_at_rest():
    box = Box([0, 0, 0], [1.2e-3, 1.2e-3, 3e-3], boundary="pp pp ff")
    model = ContactModel(Material(E, NU, RHO), restitution=0.3, friction=0.5,
                         rolling_friction=0.2)
    sim = Simulation(box, model, walls=[Plane((0, 0, 0), (0, 0, 1))], n_threads=2, seed=1)
    sim.insert_raindrop(120, R, region=((0, 0, 0), (1.2e-3, 1.2e-3, 1.5e-3)))
    sim.run(time=0.09)  # a few spheres wander over the surface for ~0.08 s
    z0 = sim.frame().positions.copy()
    ke0 = sim.kinetic_energy()
    sim.run(time=0.01)
    fr = sim.frame()
    vmax = np.abs(fr.velocities).max()
    assert vmax < 1e-4  # m/s, vs ~0.05 m/s after a free fall over one radius
    assert sim.kinetic_energy() <= max(ke0, 1e-15)  # no energy creeps in
    disp = np.sqrt(((fr.positions - z0) ** 2).sum(1))
    assert np.percentile(disp, 95) < 0.005 * R and disp.max() < 0.2 * R
    # all particles supported: coordination > 0 except possible rattlers
    c = sim.contacts()
    cn = c.per_particle_count() + np.bincount(c.walls.particle, minlength=sim.n_particles)
    assert (cn == 0).mean() < 0.1


def test_run_directory_output(tmp_path):
    sim = _gas(60, seed=2, n_threads=1)
    sim.run(20, dump_every=10, run_dir=tmp_path / "run")
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    assert cfg["units"] == "SI" and cfg["model"]["friction"] == 0.5
    text = (tmp_path / "run" / "dump.liggghts").read_text()
    assert text.count("ITEM: TIMESTEP") == 2
    assert "ITEM: ATOMS id type x y z" in text
    walls = [json.loads(line) for line in (tmp_path / "run" / "walls.jsonl").read_text().splitlines()]
    assert walls[0]["name"] == "floor"
    assert (tmp_path / "run" / "contacts.local").exists()
    try:
        from bedstruct.io import read_dump
    except ImportError:
        return
    from bedstruct.io import read_dump_local
    traj = read_dump(tmp_path / "run" / "dump.liggghts")
    fr = traj[-1]
    assert np.allclose(fr.positions, sim.frame().positions, rtol=1e-9, atol=1e-15)
    cons = read_dump_local(tmp_path / "run" / "contacts.local", frames=list(traj))
    last = cons[sim.step]
    ref = sim.contacts()
    assert last.n_contacts == ref.n_contacts
    key = lambda c: np.lexsort((c.ids_j, c.ids_i))  # noqa: E731
    assert np.allclose(last.force_normal[key(last)], ref.force_normal[key(ref)], rtol=1e-6,
                       atol=1e-15)


def _newton_residual(sim):
    """Rows of the frame whose total force differs from the sum of its contacts' forces and
    gravity (particles touching a wall left out)."""
    fr = sim.frame()
    c = sim.contacts()
    total = np.zeros_like(fr.forces)
    np.add.at(total, c.i, c.force)
    np.add.at(total, c.j, -c.force)
    total += fr.columns["mass"][:, None] * sim.gravity
    walls = np.zeros(len(fr.forces), dtype=bool)
    walls[c.walls.particle] = True
    bad = ~np.isclose(total, fr.forces, rtol=1e-6, atol=1e-12).all(axis=1) & ~walls
    return c.n_contacts, np.flatnonzero(bad)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_contact_forces_are_those_of_the_step(seed):
    # the forces of a step are evaluated at its half-step velocities: the contacts report
    # those (damping at the velocities after the step gave other forces). Without tangential
    # damping, so that a sliding contact's force (mu F_n, its spring rescaled to it) is
    # what evaluating it again gives
    model = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5,
                         tangential_damping=False)
    box = Box([0, 0, 0], [2e-3, 2e-3, 3e-3], boundary="pp pp ff")
    sim = Simulation(box, model, walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")],
                     n_threads=2, seed=seed)
    sim.insert_raindrop(300, lambda k, g: R * (0.6 + 0.8 * g.random(k)),
                        region=((0, 0, 0), (2e-3, 2e-3, 1.5e-3)))
    sim.v[:] = np.random.default_rng(seed).normal(0, 0.2, sim.v.shape)
    sim.run(300)
    n, bad = _newton_residual(sim)
    assert n > 0 and bad.size == 0


def test_frame_and_contacts_are_consistent():
    sim = _gas(200, seed=3, n_threads=2)
    sim.run(300)
    fr = sim.frame()
    c = sim.contacts()
    assert c.n_contacts > 0
    assert np.all(np.diff(fr.ids) > 0)
    assert np.allclose(fr.positions[c.i] + c.branch - fr.positions[c.j],
                       np.round((fr.positions[c.i] + c.branch - fr.positions[c.j]) / 2e-3) * 2e-3,
                       atol=1e-12)
    # Newton: sum of pair forces on i and j plus gravity = total force (off the walls)
    n, bad = _newton_residual(sim)
    assert n == c.n_contacts and bad.size == 0


def test_unsafe_timestep_refused_unless_forced():
    box = Box([0, 0, 0], [2e-3, 2e-3, 2e-3], boundary="ff ff ff")
    sim = Simulation(box, MODEL, dt=1e-5, n_threads=1)
    sim.add_particles([[1e-3, 1e-3, 1e-3]], [R])
    with pytest.raises(UnsafeTimestepError, match="Rayleigh"):
        sim.run(1)
    sim = Simulation(box, MODEL, dt=1e-5, force=True, n_threads=1)
    sim.add_particles([[1e-3, 1e-3, 1e-3]], [R])
    sim.run(1)
    assert sim.dt == 1e-5


def test_wall_geometry_primitives():
    W = np.array([Blade(gap=1e-4, speed=0.1, x0=0.0).row()])
    # directly under the trailing edge: distance = gap - z
    hit, d, n1, n2, n3, u1, *_ = K.wall_geometry(W, 0, -0.25e-3, 0.0, 0.3e-4, 0.0)
    assert hit and d == pytest.approx(0.7e-4) and n3 == pytest.approx(-1.0) and u1 == 0.1
    # after 1 ms the blade moved 0.1 mm
    hit, d, *_ = K.wall_geometry(W, 0, -0.25e-3 + 1e-4, 0.0, 0.3e-4, 1e-3)
    assert d == pytest.approx(0.7e-4)
    # in front of the blade (leading face at +0.25 mm), at mid height
    hit, d, n1, n2, n3, *_ = K.wall_geometry(W, 0, 0.35e-3, 0.0, 1e-3, 0.0)
    assert d == pytest.approx(0.1e-3) and n1 == pytest.approx(1.0)
    # under the bevel: distance to the inclined face
    x = 0.2e-3
    zface = 1e-4 + (x + 0.25e-3) * math.tan(math.radians(10))
    hit, d, *_ = K.wall_geometry(W, 0, x, 0.0, 0.5e-4, 0.0)
    assert d == pytest.approx((zface - 0.5e-4) * math.cos(math.radians(10)), rel=1e-9)
    # roller surface velocity
    cyl = Cylinder(point=(0, 0, 1e-3), axis=(0, 1, 0), radius=5e-4, omega=10.0).row()
    hit, d, n1, n2, n3, u1, u2, u3, *_ = K.wall_geometry(np.array([cyl]), 0, 0, 0, 0.4e-3, 0.0)
    assert d == pytest.approx(1e-4) and n3 == pytest.approx(-1.0)
    assert u1 == pytest.approx(-10.0 * 5e-4)  # omega_y x (0,0,-R) = (-omega R, 0, 0)
    # beyond a finite roller's open end the nearest point is on the rim circle (the sphere
    # had no contact there, and its force vanished as its centre crossed the end plane)
    cyl = Cylinder(point=(0, 0, 0), axis=(0, 1, 0), radius=5e-4, half_length=1e-3).row()
    hit, d, n1, n2, n3, *_ = K.wall_geometry(np.array([cyl]), 0, 0, 1e-3 + 2e-5, 5e-4 + 2e-5, 0.0)
    assert hit and d == pytest.approx(math.hypot(2e-5, 2e-5))
    assert (n1, n2, n3) == pytest.approx((0.0, math.sqrt(0.5), math.sqrt(0.5)))
    hit, d, *_ = K.wall_geometry(np.array([cyl]), 0, 0, -1e-3 - 3e-5, 5e-4 - 4e-5, 0.0)
    assert hit and d == pytest.approx(5e-5)
    hit, d_in, *_ = K.wall_geometry(np.array([cyl]), 0, 0, 1e-3 - 1e-12, 5e-4 + 2e-5, 0.0)
    hit, d_out, *_ = K.wall_geometry(np.array([cyl]), 0, 0, 1e-3 + 1e-12, 5e-4 + 2e-5, 0.0)
    assert d_out == pytest.approx(d_in, rel=1e-9)   # continuous across the end plane
    # triangle mesh: one triangle in the plane z = 0
    tri = np.array([[0, 0, 0, 1, 0, 0, 0, 1, 0]], dtype=float)
    row = TriangleMesh(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)).row()
    row[14], row[15] = 0, 1
    hit, d, n1, n2, n3, *_ = K.mesh_geometry(np.array([row]), 0, tri, 0.2, 0.2, 0.3, 0.0)
    assert d == pytest.approx(0.3) and n3 == pytest.approx(1.0)


def test_blade_spreads_layer_and_sliding_plate():
    box = Box([0, 0, 0], [3e-3, 1e-3, 2e-3], boundary="ff pp ff")
    blade = Blade(gap=2.5e-4, speed=0.2, x0=0.3e-3)
    sim = Simulation(box, MODEL, walls=[Plane((0, 0, 0), (0, 0, 1), name="substrate"), blade],
                     n_threads=1, seed=0)
    sim.insert_raindrop(150, R, region=((0.6e-3, 0, 0), (1.5e-3, 1e-3, 1e-3)))
    sim.run(time=0.01)
    sim.run(time=0.008)
    st = {w.name: w for w in sim.wall_states()}
    assert st["blade"].origin[0] == pytest.approx(0.3e-3 + 0.2 * sim.time)
    fr = sim.frame()
    behind = fr.positions[:, 0] < st["blade"].origin[0] - 0.25e-3
    # particles left behind the blade lie below the gap (plus a radius margin)
    assert behind.sum() > 0
    assert fr.positions[behind, 2].max() < 2.5e-4 + 0.5 * R
    # repose box: the plate slides out and the particles fall
    walls = repose_box((0, 0, 1e-3), (1e-3, 1e-3, 2e-3))
    sim = Simulation(Box([0, 0, 0], [3e-3, 1e-3, 2e-3], boundary="ff ff ff"), MODEL,
                     walls=walls + [Plane((0, 0, 0), (0, 0, 1), name="floor")], n_threads=1, seed=0)
    sim.insert_raindrop(30, R, region=((0, 0, 1e-3), (1e-3, 1e-3, 2e-3)))
    sim.run(time=0.01)
    assert sim.frame().positions[:, 2].min() > 1e-3
    sim.set_wall_motion("plate", velocity=(0.5, 0, 0))
    sim.run(time=0.01)
    assert sim.frame().positions[:, 2].min() < 1e-3


def test_box_walls_contain_particles():
    box = Box([0, 0, 0], [1e-3, 1e-3, 2e-3], boundary="ff ff ff")
    sim = Simulation(box, MODEL, walls=box_walls((0, 0, 0), (1e-3, 1e-3, 2e-3), open_top=False),
                     n_threads=1, seed=0)
    sim.insert_raindrop(40, R)
    sim.v[:] = np.random.default_rng(0).normal(0, 0.1, sim.v.shape)
    sim.run(time=0.005)
    assert sim.n_removed == 0
    p = sim.frame().positions
    assert np.all((p[:, :2] > 0) & (p[:, :2] < 1e-3))


def test_mesh_floor_matches_plane_floor():
    """A sphere bouncing on a two-triangle STL-like floor rebounds as on a plane."""
    model = ContactModel(Material(E, NU, RHO), restitution=0.6, friction=0.3)
    tri = np.array([[[0, 0, 0], [2e-3, 0, 0], [2e-3, 2e-3, 0]],
                    [[0, 0, 0], [2e-3, 2e-3, 0], [0, 2e-3, 0]]], dtype=float)
    out = []
    for wall in (Plane((0, 0, 0), (0, 0, 1)), TriangleMesh(tri)):
        sim = Simulation(Box([0, 0, 0], [2e-3] * 3, boundary="ff ff ff"), model, walls=[wall],
                         gravity=(0, 0, 0), n_threads=1, v_max=0.3)
        sim.add_particles([[0.7e-3, 1.1e-3, 1.01 * R]], [R], velocities=[[0.05, 0, -0.3]])
        sim.run(time=2e-4)
        out.append(sim.v[0].copy())
    assert np.allclose(out[0], out[1], rtol=1e-9, atol=1e-12)
    assert out[0][2] == pytest.approx(0.6 * 0.3, rel=0.02)


def test_roller_drags_particle_at_surface_speed():
    """A sphere pressed on a spinning roller is dragged along the roller surface."""
    model = ContactModel(Material(E, NU, RHO), restitution=0.3, friction=0.5)
    roller = Cylinder(point=(1e-3, 1e-3, 0.0), axis=(0, 1, 0), radius=5e-4, omega=20.0)
    sim = Simulation(Box([0, 0, 0], [2e-3, 2e-3, 2e-3], boundary="ff ff ff"), model,
                     walls=[roller], gravity=(0, 0, -9.81), n_threads=1)
    sim.add_particles([[1e-3, 1e-3, 5e-4 + 0.999 * R]], [R])
    sim.run(time=3e-4)
    # omega = +20 rad/s about +y: the top of the roller moves along (y x z) = +x at 10 mm/s
    assert 0.0 < sim.v[0, 0] < 20.0 * 5e-4
    sim.set_wall_motion("roller", omega=-20.0)
    sim.run(time=6e-4)
    assert sim.v[0, 0] < 0.0
    st = sim.wall_states()[0]
    assert st.n_contacts == 1 and st.force[2] < 0  # the sphere presses down on the roller


def test_wall_load_average_conserves_momentum():
    """A sphere dropped onto a floor: the floor's load averaged over every step equals the
    weight less the sphere's momentum change per time (impulse balance, to the trapezoid
    rule's end terms), whether it bounces or rests; no averaging started -> an error."""
    model = ContactModel(Material(E, NU, RHO), restitution=0.5, friction=0.5)
    sim = Simulation(Box([0, 0, 0], [1e-3, 1e-3, 2e-3], boundary="pp pp ff"), model,
                     walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")], gravity=(0, 0, -9.81),
                     n_threads=1)
    sim.add_particles([[5e-4, 5e-4, 3 * R]], [R])
    with pytest.raises(RuntimeError, match="start_wall_load_average"):
        sim.wall_load_average()
    mass = RHO * 4.0 / 3.0 * math.pi * R ** 3
    for duration in (4e-3, 2e-2):           # bouncing at the end, then at rest
        v0 = sim.v[0].copy()
        sim.start_wall_load_average()
        with pytest.raises(RuntimeError, match="no step"):
            sim.wall_load_average(stop=False)
        t0 = sim.time
        sim.run(time=duration)
        T = sim.time - t0
        load = sim.wall_load_average()["floor"]
        expected_z = -mass * 9.81 - mass * (sim.v[0, 2] - v0[2]) / T
        assert load[2] == pytest.approx(expected_z, rel=2e-3)
        assert abs(load[0]) < 1e-3 * mass * 9.81
    with pytest.raises(RuntimeError, match="start_wall_load_average"):
        sim.wall_load_average()   # the last call stopped the averaging


def test_read_stl_ascii_and_binary(tmp_path):
    from bedstruct.dem import read_stl
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 0, 1], [0, 1, 1]]], float)
    lines = ["solid t"]
    for t in tri:
        lines += ["facet normal 0 0 1", "outer loop"] + [f"vertex {a} {b} {c}" for a, b, c in t] + \
                 ["endloop", "endfacet"]
    (tmp_path / "a.stl").write_text("\n".join(lines + ["endsolid t"]))
    rec = np.zeros(2, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    (tmp_path / "b.stl").write_bytes(b"\0" * 80 + np.uint32(2).tobytes() + rec.tobytes())
    assert np.allclose(read_stl(tmp_path / "a.stl", scale=1e-3), tri * 1e-3)
    assert np.allclose(read_stl(tmp_path / "b.stl"), tri)


def test_progress_bar_runs(capsys):
    sim = _gas(30, seed=1, n_threads=1)
    stats = sim.run(60, progress=True)
    assert stats.n_steps == 60 and "p-steps/s" in capsys.readouterr().err
