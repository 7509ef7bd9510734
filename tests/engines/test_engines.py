"""External engines (LIGGGHTS 3.8, LAMMPS) as independent references.

Engine runs skip when the engine is not installed (install both with
``bash .ci/install-engines.sh``). Sizes are tiny: the whole file runs in well
under a minute on a loaded 2-core machine.
"""

from __future__ import annotations

import math
from contextlib import nullcontext
from dataclasses import replace

import numpy as np
import pytest

from bedstruct.errors import BedstructWarning

from bedstruct.dem import ContactModel, Material, seed_contact_model
from bedstruct.engines import (BladeGeometry, EngineRunError, bed_deck, box_triangles,
                               find_lammps, find_liggghts, hertz_contact_time, impact_deck,
                               impact_result, lammps_granular_coeffs, liggghts_model_commands,
                               moving_wall_deck, parse_log,
                               read_data_header, read_stl_triangles, run_deck, write_sphere_data,
                               write_stl)

ENGINES = {"liggghts": find_liggghts, "lammps": find_lammps}


def _engine_param(name):
    return pytest.param(name, marks=pytest.mark.skipif(
        ENGINES[name]() is None,
        reason=f"{name} is not installed (run .ci/install-engines.sh)"))


both_engines = pytest.mark.parametrize("engine", [_engine_param("liggghts"), _engine_param("lammps")])


# --------------------------------------------------------------------------- log parsing
LIGGGHTS_LOG = """\
LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown)
atom_style granular
WARNING: 
\tThe contact model you specified is not located in any whitelist.
Setting up run at Sat Nov 21 10:36:27 2026

Memory usage per processor = 4.58844 Mbytes
    Step           Time           dist            vx1 
       0              0       4.08e-05            0.5 
       1  6.5590114e-09  4.0793441e-05            0.5 
WARNING: Particle insertion: Less insertions than requested (../fix_insert.cpp:782)
       2  1.3118023e-08  4.0786882e-05      0.4999999 
Loop time of 0.00288291 on 1 procs for 2 steps with 2 atoms, finish time Sat Nov 21 10:36:27 2026


Pair  time (%) = 0.000711144 (24.6676)
Nlocal:    2 ave 2 max 2 min
Total # of neighbors = 1
Ave neighs/atom = 0.5
Neighbor list builds = 1
Setting up run at Sat Nov 21 10:36:28 2026
    Step           Time           dist            vx1 
       2  1.3118023e-08  4.0786882e-05      0.4999999 
      12  1.3118023e-07  4.07e-05               -0.25 
Loop time of 0.5 on 2 procs for 10 steps with 2 atoms, finish time Sat Nov 21 10:36:28 2026
"""

LAMMPS_LOG = """\
LAMMPS (22 Jul 2025 - Update 4)
  using 1 OpenMP thread(s) per MPI task
Per MPI rank memory allocation (min/avg/max) = 18.45 | 18.45 | 18.45 Mbytes
   Step          Time          v_dist          v_v1          KinEng    
         0   0              4.2e-05        0.5            6.9533917e-11
       500   5e-07          4.15e-05       0.5            6.9533917e-11
Loop time of 0.00293777 on 1 procs for 500 steps with 2 atoms

0.0% CPU use with 1 MPI tasks x 1 OpenMP threads
Nlocal:              2 ave           2 max           2 min
Histogram: 1 0 0 0 0 0 0 0 0 0
Total # of neighbors = 1
Ave neighs/atom = 0.5
Neighbor list builds = 1
ERROR: Lost atoms: original 2 current 1 (src/src/thermo.cpp:497)
"""


def test_parse_liggghts_log():
    lg = parse_log(LIGGGHTS_LOG)
    assert lg.engine == "liggghts" and "3.8.0" in lg.version
    assert len(lg.runs) == 2
    first, second = lg.runs
    assert first.columns == ("Step", "Time", "dist", "vx1")
    assert first.data.shape == (3, 4)  # the WARNING inside the table is skipped
    assert (first.loop_time, first.n_procs, first.n_steps, first.n_atoms) == (0.00288291, 1, 2, 2)
    assert first.neighbors_per_atom == 0.5 and first.atoms_per_proc == (2.0, 2.0, 2.0)
    assert second.n_procs == 2 and second.loop_time == 0.5 and second.atoms_per_proc is None
    # LIGGGHTS drops the v_ prefix; both spellings work
    assert lg.column("v_vx1").tolist() == [0.5, 0.5, 0.4999999, 0.4999999, -0.25]
    assert len(lg.warnings) == 2 and not lg.errors


def test_parse_lammps_log():
    lg = parse_log(LAMMPS_LOG)
    assert lg.engine == "lammps"
    assert lg.last.column("KinEng").shape == (2,)
    assert lg.last.n_steps == 500 and lg.last.neighbors_per_atom == 0.5
    assert lg.last.atoms_per_proc == (2.0, 2.0, 2.0)
    assert lg.errors == ("ERROR: Lost atoms: original 2 current 1 (src/src/thermo.cpp:497)",)
    with pytest.raises(KeyError, match="columns are"):
        lg.last.column("PotEng")


def test_parse_log_from_file(tmp_path):
    p = tmp_path / "log.lammps"
    p.write_text(LAMMPS_LOG)
    assert parse_log(p).last.n_atoms == 2


def test_parse_log_crashed_run_keeps_rows():
    text = "LAMMPS (x)\nStep KinEng\n0 1.0\n10 2.0\nERROR: boom\n"
    lg = parse_log(text)
    assert lg.last.loop_time is None and lg.last.data.shape == (2, 2)


# --------------------------------------------------------------------------- parameters
def test_the_seed_contact_model():
    m = seed_contact_model()
    assert m.n_types == 1 and m.materials[0] == Material(1e7, 0.3, 8300.0, name="CoCr (soft)")
    assert (m.restitution, m.friction, m.rolling_friction, m.cohesion, m.rolling_model) == (
        0.1, 0.4, 0.05, 0.0, "epsd2")
    assert seed_contact_model(density=4000.0, friction=0.6).materials[0].density == 4000.0
    with pytest.raises(Exception, match="`youngs_modulus`, `poisson_ratio` and `density`"):
        seed_contact_model(materials=Material(1e7, 0.3))


def test_a_contact_model_is_written_per_atom_type_with_the_walls_own():
    # particles type 1, walls type 2: wall values where exactly one of the pair is a wall
    cm = ContactModel(Material(2e7, 0.25, 7000.0), restitution=0.3, friction=0.5,
                      rolling_friction=0.1, cohesion=1e4, wall_friction=0.7,
                      wall_material=Material(3e8, 0.2))
    lines, wt = liggghts_model_commands(cm, n_types=2)
    assert wt == 2 and lines[:6] == [
        "fix m1 all property/global youngsModulus peratomtype 20000000 300000000",
        "fix m2 all property/global poissonsRatio peratomtype 0.25 0.2",
        "fix m3 all property/global coefficientRestitution peratomtypepair 2 0.3 0.3 0.3 0.3",
        "fix m4 all property/global coefficientFriction peratomtypepair 2 0.5 0.7 0.7 0.5",
        "fix m5 all property/global coefficientRollingFriction peratomtypepair 2 0.1 0.1 0.1 0.1",
        "fix m6 all property/global cohesionEnergyDensity peratomtypepair 2 10000 10000 10000 10000"]
    with pytest.raises(ValueError, match="wall youngs_modulus differs"):
        liggghts_model_commands(cm, n_types=1)
    # LAMMPS: one (E, nu) per contact, E chosen so that its E* is the pair's
    # 1 / ((1 - nu1^2)/E1 + (1 - nu2^2)/E2), written with nu1
    words = lammps_granular_coeffs(replace(cm, cohesion=0.0), wall=True).split()
    estar = 1 / ((1 - 0.25 ** 2) / 2e7 + (1 - 0.2 ** 2) / 3e8)
    assert float(words[1]) == pytest.approx(2 * (1 - 0.25 ** 2) * estar, rel=1e-9)
    assert words[2:4] == ["0.3", "0.25"] and words[10] == "0.7"


def test_lammps_refuses_sjkr_without_mapping():
    p = seed_contact_model(cohesion=3.2e7)
    with pytest.raises(ValueError, match="no SJKR"):
        lammps_granular_coeffs(p)
    words = lammps_granular_coeffs(p, cohesion_model="dmt")
    assert words.startswith("dmt ") and "damping viscoelastic" in words


def test_lammps_dmt_gamma_matches_sjkr_force_at_reference_overlap():
    # DMT pull-in 4 pi gamma R* must equal SJKR k * pi * a_geo^2 (a_geo^2 = 2 R* delta)
    k, r = 3.2e7, 26e-6
    p = seed_contact_model(cohesion=k, rolling_friction=0.0)
    gamma = float(lammps_granular_coeffs(p, cohesion_model="dmt").split()[4])
    rstar = r / 2
    delta = 1e-3 * rstar
    assert 4 * math.pi * gamma * rstar == pytest.approx(k * math.pi * 2 * rstar * delta, rel=1e-9)


# --------------------------------------------------------------------------- STL
def _signed_volume(tri):
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def test_box_stl_roundtrip_and_volume(tmp_path):
    tri = box_triangles([0, 0, 0], [1e-3, 2e-3, 3e-3])
    path = write_stl(tmp_path / "box.stl", tri, name="box")
    back = read_stl_triangles(path)
    np.testing.assert_allclose(back, tri, rtol=1e-9)
    assert _signed_volume(back) == pytest.approx(6e-9, rel=1e-9)  # outward normals: +V
    assert _signed_volume(box_triangles([0, 0, 0], [1, 2, 3], inward=True)) == pytest.approx(-6.0)


def test_blade_geometry_volume_and_bevel():
    b = BladeGeometry(x0=1e-3, z_bottom=1e-4, thickness=0.5e-3, height=2e-3, bevel_deg=10)
    tri = b.triangles(0.0, 3e-3)
    rise = 0.5e-3 * math.tan(math.radians(10))
    area = 0.5e-3 * 2e-3 - 0.5 * 0.5e-3 * rise  # rectangle minus the bevelled corner
    assert _signed_volume(tri) == pytest.approx(area * 3e-3, rel=1e-9)
    # the lowest point is the trailing bottom edge, the leading face starts `rise` higher
    assert tri[..., 2].min() == pytest.approx(1e-4)
    lead = np.isclose(tri[..., 0], 1.5e-3, rtol=0, atol=1e-12)
    assert tri[..., 2][lead].min() == pytest.approx(1e-4 + rise)
    assert b.triangles(0.0, 3e-3, caps=False).shape == (8, 3, 3)


# --------------------------------------------------------------------------- engines
def test_hertz_contact_time_formula():
    p = seed_contact_model(youngs_modulus=1e8)
    t = hertz_contact_time(2e-5, 2e-5, p, speed=1.0)
    m = 4 / 3 * math.pi * (2e-5) ** 3 * 8300
    estar = 1e8 / (2 * (1 - 0.09))
    assert t == pytest.approx(2.868 * ((m / 2) ** 2 / (1e-5 * estar ** 2 * 1.0)) ** 0.2)


def _impact(engine, tmp_path, **kw):
    p = seed_contact_model(youngs_modulus=1e8, **kw)
    deck = tmp_path / f"impact_{engine}.in"
    deck.write_text(impact_deck(p, engine=engine, radius=20e-6, speed=1.0))
    return impact_result(run_deck(deck).log, 20e-6), p


@both_engines
@pytest.mark.parametrize("e", [0.1, 0.5])
def test_impact_restitution(engine, e, tmp_path):
    res, _ = _impact(engine, tmp_path, restitution=e)
    assert res.restitution == pytest.approx(e, rel=0.02)


@both_engines
def test_impact_hertz_contact_time(engine, tmp_path):
    res, p = _impact(engine, tmp_path, restitution=1.0)
    assert res.restitution == pytest.approx(1.0, abs=1e-4)
    t = hertz_contact_time(20e-6, 20e-6, p, speed=1.0)
    assert res.contact_time == pytest.approx(t, rel=0.02)
    # Hertz maximum overlap (15 m* v^2 / (16 E* sqrt(R*)))^(2/5)
    m = 4 / 3 * math.pi * (20e-6) ** 3 * 8300.0 / 2
    estar = 1e8 / (2 * (1 - 0.3 ** 2))
    dmax = (15 * m * 1.0 / (16 * estar * math.sqrt(10e-6))) ** 0.4
    assert res.max_overlap == pytest.approx(dmax, rel=0.01)


@both_engines
def test_wall_impact_restitution_and_contact_time(engine, tmp_path):
    # a sphere on a stiffer plane: E* mixes particle and wall moduli, m* = m, R* = r
    r = 20e-6
    p = seed_contact_model(youngs_modulus=1e8, wall_material=Material(3e8, 0.3), restitution=0.9,
                           wall_restitution=1.0)
    deck = tmp_path / "wall.in"
    deck.write_text(impact_deck(p, engine=engine, radius=r, speed=1.0, target="wall"))
    res = impact_result(run_deck(deck).log, r, 0.0)
    assert res.restitution == pytest.approx(1.0, abs=1e-4)
    estar = 1 / ((1 - 0.09) / 1e8 + (1 - 0.09) / 3e8)
    m = 4 / 3 * math.pi * r ** 3 * 8300.0
    assert res.contact_time == pytest.approx(2.868 * (m ** 2 / (r * estar ** 2)) ** 0.2, rel=0.02)
    deck.write_text(impact_deck(seed_contact_model(wall_restitution=0.3), engine=engine,
                                target="wall"))
    assert impact_result(run_deck(deck).log, 20e-6, 0.0).restitution == pytest.approx(0.3, rel=0.02)


R = 50e-6


def _columns_bed(tmp_path):
    """3 x 3 columns of 3 touching spheres standing on the plate (18 contacts)."""
    g = np.arange(3)
    ii, jj, kk = np.meshgrid(g, g, g, indexing="ij")
    pos = np.column_stack([(ii.ravel() + 0.5) * 2.5 * R, (jj.ravel() + 0.5) * 2.5 * R,
                           R + kk.ravel() * 2 * R * (1 - 1e-6)])
    return write_sphere_data(tmp_path / "columns.data", pos, np.full(27, R),
                             box_lo=[0, 0, 0], box_hi=[7.5 * R, 7.5 * R, 10 * R], n_types=2)


def _contact_pairs(engine, path):
    lines = path.read_text().splitlines()
    start = max(i for i, line in enumerate(lines) if line.startswith("ITEM: ENTRIES"))
    rows = np.array([[float(v) for v in line.split()] for line in lines[start + 1:] if line.strip()])
    if engine == "liggghts":  # x1 y1 z1 x2 y2 z2 id1 id2 periodic fx fy fz area delta
        ids, force = rows[:, 6:8], rows[:, 9:12]
    else:  # id1 id2 dist fx fy fz: every pair within the cutoff, keep touching ones
        rows = rows[rows[:, 2] < 2 * R]
        ids, force = rows[:, 0:2], rows[:, 3:6]
    return {tuple(sorted(map(int, p))) for p in ids}, force


@both_engines
def test_bed_deck_runs_and_dumps_are_readable(engine, tmp_path):
    data = _columns_bed(tmp_path)
    steps, dt = 20, 1e-8
    p = seed_contact_model(youngs_modulus=1e8, restitution=0.5)
    deck = tmp_path / "bed.in"
    deck.write_text(bed_deck(data, p, engine=engine, steps=steps, dt=dt, thermo_every=10,
                             dump="bed.dump", dump_every=steps, contacts="contacts.dump",
                             contacts_every=steps, write_data="final.data"))
    res = run_deck(deck)
    assert res.log.last.n_atoms == 27 and res.log.last.n_steps == steps
    assert read_data_header(tmp_path / "final.data")["atoms"] == 27
    pairs, force = _contact_pairs(engine, tmp_path / "contacts.dump")
    # column neighbours k, k+1 in every column: ids differ by 1 within a column of 3
    expected = {(c * 3 + k + 1, c * 3 + k + 2) for c in range(9) for k in range(2)}
    assert pairs == expected
    assert np.all(np.abs(force[:, :2]) < 1e-6 * np.abs(force[:, 2]).max())  # vertical forces only
    # per-particle dump: bedstruct's reader when available, else the raw columns
    try:
        from bedstruct.io import read_dump
    except ImportError:
        read_dump = None
    if read_dump is not None:
        frame = read_dump(tmp_path / "bed.dump")[-1]
        assert frame.n_particles == 27
        np.testing.assert_allclose(frame.radii, R)
        vz = frame.velocities[:, 2]
    else:
        rows = np.loadtxt(tmp_path / "bed.dump", skiprows=9)
        assert rows.shape == (27, 15)
        np.testing.assert_allclose(rows[:, 14], R)
        vz = rows[:, 7]
    # the top spheres carry nobody: over 20 tiny steps they fall freely, vz = -g t (tiny overlap)
    assert np.all(vz <= 0)
    assert vz.min() == pytest.approx(-9.81 * steps * dt, rel=0.05)


@both_engines
def test_rolling_resistance_decelerates_a_rolling_sphere(engine, tmp_path):
    # full mobilisation: torque mu_r R m g on a sphere rolling without slip on the plate,
    # (I + m R^2) dw/dt = -mu_r R m g  ->  dv/dt = -5 mu_r g / 7 (EPSD2 in LIGGGHTS, SDS in LAMMPS)
    v0, mur = 0.01, 0.2
    data = write_sphere_data(tmp_path / "one.data", [[2 * R, 2 * R, R * (1 - 1e-5)]], [R],
                             box_lo=[0, 0, 0], box_hi=[4 * R, 4 * R, 4 * R], n_types=2,
                             velocities=[[v0, 0, 0]], omegas=[[0, v0 / R, 0]])
    p = seed_contact_model(youngs_modulus=1e8, restitution=0.5, friction=0.5, rolling_friction=mur)
    deck = tmp_path / "roll.in"
    deck.write_text(bed_deck(data, p, engine=engine, steps=8000, dt=1e-7, thermo_every=500,
                             thermo_variables={"vx1": "vx[1]"}))
    log = run_deck(deck).log
    t, vx = log.column("Step") * 1e-7, log.column("v_vx1")
    slope = np.polyfit(t[4:], vx[4:], 1)[0]
    assert slope == pytest.approx(-5 * mur * 9.81 / 7, rel=0.01)


@pytest.mark.skipif(find_lammps() is None, reason="lammps is not installed")
def test_lammps_fabric_of_vertical_columns(tmp_path):
    # every contact is vertical: phi = diag(0, 0, 1); LAMMPS prints (15/2)(phi - I/3)
    data = _columns_bed(tmp_path)
    deck = tmp_path / "fab.in"
    deck.write_text(bed_deck(data, seed_contact_model(youngs_modulus=1e8), engine="lammps", steps=5,
                             dt=1e-8, thermo_every=5, fabric=True))
    run = run_deck(deck).log.last
    contact = [run.column(f"c_fab[{i}]")[-1] for i in range(1, 7)]
    np.testing.assert_allclose(contact, [-2.5, -2.5, 5.0, 0, 0, 0], atol=1e-9)
    with pytest.raises(ValueError, match="fabric"):
        bed_deck(data, engine="liggghts", steps=5, dt=1e-8, fabric=True)


@both_engines
def test_two_ranks_match_one_rank(engine, tmp_path):
    info = ENGINES[engine]()
    if info.mpirun is None:
        pytest.skip(f"no MPI launcher for {engine}")
    data = _columns_bed(tmp_path)
    finals = []
    for np_ in (1, 2):
        deck = tmp_path / f"bed{np_}.in"
        deck.write_text(bed_deck(data, seed_contact_model(youngs_modulus=1e8), engine=engine,
                                 steps=50, dt=1e-8, thermo_every=50))
        res = run_deck(deck, np=np_)
        assert res.log.last.n_procs == np_
        finals.append(res.log.last.column("KinEng")[-1])
    assert finals[1] == pytest.approx(finals[0], rel=1e-6)


@both_engines
def test_moving_blade_pushes_particles(engine, tmp_path):
    data = _columns_bed(tmp_path)
    blade = BladeGeometry(x0=0.0, z_bottom=0.5 * R, speed=0.5, thickness=0.2 * R, height=8 * R,
                          bevel_deg=10)
    stl = blade.write_stl(tmp_path / "blade.stl", 0.0, 7.5 * R, caps=False)
    deck = tmp_path / "blade.in"
    ctx = pytest.warns(BedstructWarning, match="unbevelled") if engine == "lammps" else nullcontext()
    with ctx:
        text = moving_wall_deck(data, seed_contact_model(youngs_modulus=1e8), engine=engine,
                                blade=blade, stl_path=stl, steps=300, dt=1e-7, thermo_every=300)
    deck.write_text(text)
    res = run_deck(deck)
    # the blade's leading face (x = 0.2 R) reaches the first column (surface at 0.25 R) after
    # 5e-6 s and shoves it at 0.5 m/s; without the blade the bed would be at rest
    m = 4 / 3 * math.pi * R ** 3 * 8300
    assert res.log.last.column("KinEng")[-1] > 0.05 * 0.5 * m * 0.5 ** 2


def _single_sphere_blade(engine, tmp_path, blade, position, *, restitution=0.5, steps=200):
    r = 20e-6
    data = write_sphere_data(tmp_path / "one.data", [position], [r], box_lo=[-1e-4, 0, 0],
                             box_hi=[7e-4, 2e-4, 2e-3], n_types=2)
    stl = blade.write_stl(tmp_path / "blade.stl", 0.0, 2e-4, caps=False)
    deck = tmp_path / "one_blade.in"
    deck.write_text(moving_wall_deck(
        data, seed_contact_model(youngs_modulus=1e8, restitution=restitution), gravity=0.0,
        engine=engine, blade=blade, stl_path=stl, steps=steps, dt=1e-8, thermo_every=steps,
        thermo_variables={"vx1": "vx[1]", "vz1": "vz[1]"}))
    log = run_deck(deck).log
    return log.column("v_vx1")[-1], log.column("v_vz1")[-1]


@both_engines
def test_static_bevel_pushes_along_its_normal(engine, tmp_path):
    # bevel 10 deg, bottom edge at z = 100 um: above x = 400 um the bevel face is at 170.5 um
    r, tan10 = 20e-6, math.tan(math.radians(10))
    blade = BladeGeometry(x0=0.0, z_bottom=100e-6, speed=0.0, thickness=500e-6, height=1e-3,
                          bevel_deg=10)
    face = 100e-6 + 400e-6 * tan10
    vx, vz = _single_sphere_blade(engine, tmp_path, blade, [400e-6, 1e-4, face - r - 2e-6])
    assert vx == 0 and vz == 0  # 2 um below the bevel: untouched
    vx, vz = _single_sphere_blade(engine, tmp_path, blade, [400e-6, 1e-4, face - r + 2e-6])
    assert vz < 0 and vx / -vz == pytest.approx(tan10, rel=1e-3)  # pushed along the bevel normal


@both_engines
def test_moving_flat_blade_rebound(engine, tmp_path):
    # an infinitely heavy wall at speed V hitting a sphere at rest sends it off at (1 + e) V
    blade = BladeGeometry(x0=0.0, z_bottom=100e-6, speed=0.1, thickness=100e-6, height=1e-3,
                          bevel_deg=0)
    vx, vz = _single_sphere_blade(engine, tmp_path, blade, [100e-6 + 21e-6, 1e-4, 5e-4],
                                  restitution=0.5, steps=3000)
    assert vx == pytest.approx(1.5 * 0.1, rel=0.01) and vz == 0


@both_engines
def test_run_deck_error_carries_log_tail(engine, tmp_path):
    deck = tmp_path / "bad.in"
    deck.write_text(f"# bedstruct deck for {engine}\nunits si\nthis_is_not_a_command 1 2 3\n")
    with pytest.raises(EngineRunError, match="this_is_not_a_command|Unknown command|Invalid"):
        run_deck(deck)


@both_engines
def test_benchmark_external_uses_timed_run(engine, tmp_path):
    from bedstruct.engines import benchmark_external
    data = _columns_bed(tmp_path)
    res = benchmark_external(data, engine=engine, np=1, steps=60, dt=1e-8, warmup_steps=10,
                             model=seed_contact_model(youngs_modulus=1e8), workdir=tmp_path)
    assert res["n_atoms"] == 27 and res["steps"] == 60 and res["np"] == 1
    assert res["particle_steps_per_s"] == pytest.approx(27 * 60 / res["loop_time_s"])
    assert res["loop_time_s"] < res["wall_time_s"]  # start-up and the warm-up are excluded
    log = parse_log(tmp_path / f"bench_{engine}.log")
    assert [r.n_steps for r in log.runs] == [10, 60]


@both_engines
def test_pour_bed_writes_settling_bed(engine, tmp_path):
    from bedstruct.engines import pour_bed
    out = pour_bed(tmp_path / "bed.data", n_particles=40, engine=engine, width=(0.3e-3, 0.3e-3),
                   steps=400, workdir=tmp_path)
    head = read_data_header(out)
    assert head["atoms"] == 40 and head["atom types"] == 2
    assert np.all(np.asarray(head["hi"][:2]) == pytest.approx(0.3e-3))


def test_cached_bed_returns_existing_file(tmp_path):
    from bedstruct.engines import cached_bed
    existing = write_sphere_data(tmp_path / "bed10_seed3.data", [[0, 0, 1e-4]] * 1, [5e-5],
                                 box_lo=[-1e-4, -1e-4, 0], box_hi=[1e-4, 1e-4, 1e-3])
    assert cached_bed(10, cache_dir=tmp_path, rng=3) == existing


# --------------------------------------------------------------------------- multi-layer decks
def test_cylinder_triangles_are_inscribed_and_outward():
    from bedstruct.engines import cylinder_triangles
    tri = cylinder_triangles((1.0, 2.0), 0.5, 0.0, 3.0, n_segments=48, n_y=3)
    v = tri.reshape(-1, 3)
    assert np.allclose(np.hypot(v[:, 0] - 1.0, v[:, 2] - 2.0), 0.5)      # vertices on the circle
    assert v[:, 1].min() == 0.0 and v[:, 1].max() == 3.0
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    c = tri.mean(axis=1)
    assert np.all(n[:, 0] * (c[:, 0] - 1.0) + n[:, 2] * (c[:, 2] - 2.0) > 0)
    # lateral area of the inscribed 48-gon prism: 48 * chord * length
    chord = 2 * 0.5 * math.sin(math.pi / 48)
    assert 0.5 * np.linalg.norm(n, axis=1).sum() == pytest.approx(48 * chord * 3.0, rel=1e-12)


def test_spread_plan_steps_align_with_frames():
    from bedstruct.engines import RollerGeometry, SpreadLayersPlan
    tool = RollerGeometry(x0=6e-4, z_bottom=0.0, radius=5e-4, speed=0.1, omega=-200.0)
    plan = SpreadLayersPlan(3e-3, 6e-4, (4e-4, 3e-4, 2e-4), tool, ((1, 10), (11, 20), (21, 30)),
                            (0.0, 2e-3, 3e-3), (1e-3, 2e-3), 1e-6, x_end=3.9e-3, n_frames=5,
                            settle_time=2e-4, lower_speed=0.05)
    assert len(plan.layers) == 3
    for ls in plan.layers:
        assert ls.spread % plan.every == 0 and ls.end % plan.every == 0
        assert ls.start < ls.spread < ls.stop < ls.end
        # the tool covers x0 -> x_end in the spreading steps (to one step)
        assert (ls.stop - ls.spread) * 1e-6 * 0.1 == pytest.approx(3.3e-3, abs=1e-7)
    # layer 2 starts after layer 1 ends and the tool returned; lowering takes gap / lower_speed
    assert plan.layers[1].start > plan.layers[0].end
    assert plan.layers[1].spread - plan.layers[1].start >= 3e-4 / 0.05 / 1e-6
    with pytest.raises(ValueError, match="one entry per layer"):
        SpreadLayersPlan(3e-3, 6e-4, (4e-4,), tool, ((1, 10), (11, 20)), (0.0, 1.0), (0, 1), 1e-6)


@both_engines
def test_roller_spin_drags_a_sphere_on_top(tmp_path, engine):
    """A sphere resting on top of the roller is dragged along the roller's surface velocity,
    omega e_y x (R e_z) = omega R e_x: +x for omega > 0, -x for omega < 0 (the embedded
    engine's convention); without spin it barely moves (the roller translates by 5 um in 2 ms).
    Friction limits the drag to ~mu g t^2 / 2 ~ 10 um in 2 ms."""
    from bedstruct.engines import (RollerGeometry, SpreadLayersPlan, read_stl_triangles,
                                        spread_layers_deck)
    from bedstruct.io import read_dump
    R, r, W = 5e-4, 5e-5, 4e-4
    p = seed_contact_model(youngs_modulus=1e7, restitution=0.3, friction=0.5, rolling_friction=0.0,
                           density=8000.0)
    dt = 2e-7
    x = {}
    for omega in (-100.0, 0.0, 100.0):
        d = tmp_path / f"w{omega:+.0f}"
        (d / "layer01").mkdir(parents=True)
        tool = RollerGeometry(x0=1e-3, z_bottom=0.0, radius=R, speed=0.0025, omega=omega)
        data = write_sphere_data(d / "s.data", [[1e-3, 0.5 * W, 2 * R + r - 2e-7]], [r],
                                 box_lo=[0.0, 0.0, -1e-3], box_hi=[3e-3, W, 3e-3],
                                 density=p.materials[0].density, n_types=2)
        plan = SpreadLayersPlan(2e-3, W, (2e-4,), tool, ((1, 1),), (0.0,), (2e-3, 2.5e-3), dt,
                                speed=0.0025, x_end=1e-3 + 5e-6, settle_time=2e-5, n_frames=2)
        deck = d / "in.deck"
        deck.write_text(spread_layers_deck(data, p, engine=engine, plan=plan, stl_folder=d,
                                           contacts=False))
        run_deck(deck, np=1, cwd=d)
        if engine == "liggghts":  # the STL roller is the 72-gon of radius R about the axis
            v = read_stl_triangles(d / "tool.stl").reshape(-1, 3)
            assert np.allclose(np.hypot(v[:, 0] - 1e-3, v[:, 2] - R), R)
        traj = read_dump(d / "layer01" / "frames.dump", units="si")
        x[omega] = float(traj[len(traj) - 1].positions[0, 0]) - 1e-3
    assert x[100.0] > x[0.0] + 4e-6, x
    assert x[-100.0] < x[0.0] - 4e-6, x
    assert abs(x[0.0]) < 6e-6, x


def _landing_plan(intervals, dt=1e-6):
    from bedstruct.engines import SpreadLayersPlan
    blade = BladeGeometry(x0=0.0, z_bottom=0.0, speed=0.1, height=1e-3)
    return SpreadLayersPlan(3e-3, 2e-3, (2e-4, 2e-4), blade, ((1, 1), (2, 2)), (0.0, 5e-3),
                            (5e-4, 1.5e-3), dt, x_end=3.5e-3, n_frames=4, settle_time=5e-3,
                            landing_intervals=intervals, landing_margin=5e-5)


def test_spread_deck_waits_for_flying_powder_only_when_asked(tmp_path):
    """The landing loop is written before layer 2 only, and only with ``landing_intervals``;
    LAMMPS' walls move on the planned step (the run's step less the steps waited)."""
    from bedstruct.engines import spread_layers_deck
    data = write_sphere_data(tmp_path / "a.data", [[1e-3, 2e-4, -1.5e-4], [1e-3, 2e-4, 5e-3]],
                             [5e-5, 5e-5], box_lo=[-1e-3, 0, -1e-3], box_hi=[5e-3, 4e-4, 1e-2],
                             n_types=2)
    for engine in ("liggghts", "lammps"):
        deck = spread_layers_deck(data, engine=engine, plan=_landing_plan(20), stl_folder=tmp_path)
        assert deck.count("label landing") == 1 and "label landing02" in deck
        assert 'if "${fly02} > 0" then "run 5000"' in deck
        assert deck.count("BEDSTRUCT_OFFSET layer=") == 2
        quiet = spread_layers_deck(data, engine=engine, plan=_landing_plan(0), stl_folder=tmp_path)
        assert "label landing" not in quiet and "inflight" not in quiet
    ramps = [ln for ln in deck.splitlines() if ln.startswith(("variable bx", "variable bz",
                                                               "variable pz"))]
    assert len(ramps) == 3 and all("(step-v_off)" in ln for ln in ramps)
    assert not any("step" in ln.replace("(step-v_off)", "") for ln in ramps)
    with pytest.raises(ValueError, match="must not be negative"):
        _landing_plan(-1)


def test_landing_offsets_shift_the_plan(tmp_path):
    from bedstruct.engines import landing_offsets
    plan = _landing_plan(20)
    log = tmp_path / "log"
    log.write_text("Step Atoms\nBEDSTRUCT_OFFSET layer=1 steps=0\n"
                   'print "BEDSTRUCT_OFFSET layer=2 steps=${off}"\n'
                   "BEDSTRUCT_OFFSET layer=2 steps=15000\n")
    off = landing_offsets(log, 2)
    assert off == (0, 15000)
    a, b = plan.shifted(off)
    assert a == plan.layers[0]
    assert b.start == plan.layers[1].start                       # the wait comes after it
    assert (b.spread, b.stop, b.end) == tuple(getattr(plan.layers[1], f) + 15000
                                              for f in ("spread", "stop", "end"))
    with pytest.raises(ValueError, match=r"log: .*layer\(s\) \[3\]"):
        landing_offsets(log, 3)
    with pytest.raises(ValueError, match="non-decreasing"):
        plan.shifted((15000, 0))
    # the stroke-averaged tool loads of the same log: NaN where a layer printed none
    from bedstruct.engines import tool_loads
    with open(log, "a") as fh:
        fh.write('print "BEDSTRUCT_TOOL_FORCE layer=1 fx=${tfx01} fy=${tfy01} fz=${tfz01}"\n'
                 "BEDSTRUCT_TOOL_FORCE layer=1 fx=-1.5e-05 fy=2e-08 fz=3.25e-06\n")
    (a1, b1) = tool_loads(log, 2)
    assert a1 == (-1.5e-05, 2e-08, 3.25e-06) and all(np.isnan(b1))


@both_engines
def test_spread_deck_waits_for_a_thrown_sphere_to_land(tmp_path, engine):
    """A sphere thrown up at 0.4 m/s in layer 1 is still in the air when layer 2 begins
    (its flight takes 2 v / g = 82 ms); the deck waits in 5 ms intervals until it has landed
    before the next pile (one large sphere) is placed. The tool of layer 2 starts after the
    wait: the large sphere lies ahead of the blade's front face at every frame, by the
    schedule shifted by the logged offset, and the blade pushes it (LAMMPS moves its walls
    by the planned step, so this fails if the offset were ignored there)."""
    from bedstruct.engines import landing_offsets, spread_layers_deck
    from bedstruct.io import read_dump
    p = seed_contact_model(youngs_modulus=1e7, restitution=0.3, friction=0.5, rolling_friction=0.0,
                           density=8000.0)
    for k in (1, 2):
        (tmp_path / f"layer{k:02d}").mkdir()
    r_big = 4.5e-4   # on the platform its centre is above the blade's lowest point
    # the pile of layer 2 is written relative to its base, parked 5 mm up
    data = write_sphere_data(tmp_path / "a.data", [[1e-3, 1e-3, -1.5e-4],
                                                   [1.1e-3, 1e-3, 5e-3 + r_big]],
                             [5e-5, r_big], box_lo=[-1e-3, 0, -1e-3], box_hi=[6e-3, 2e-3, 1.5e-2],
                             density=p.materials[0].density, velocities=[[0, 0, 0.4], [0, 0, 0]], n_types=2)
    plan = _landing_plan(20)
    deck = tmp_path / "in.deck"
    deck.write_text(spread_layers_deck(data, p, engine=engine, plan=plan, stl_folder=tmp_path,
                                       contacts=False))
    run_deck(deck, np=1, cwd=tmp_path, log_path="in.log")
    off = landing_offsets(tmp_path / "in.log", 2)
    n = plan._steps(plan.settle_time)
    assert off[0] == 0 and off[1] % n == 0
    # checked at about 57 ms (layer 1, lowering and settling), landed at about 82 ms
    assert 3 * n <= off[1] <= 20 * n, off
    ls = plan.shifted(off)[1]
    traj = read_dump(tmp_path / "layer02" / "frames.dump", units="si")
    steps = [int(traj[i].timestep) for i in range(len(traj))]
    assert steps[0] == ls.spread and ls.end in steps
    front0 = plan.tool.x0 + plan.tool.thickness
    pushed = False
    for i, step in enumerate(steps):
        fr = traj[i]
        big = fr.positions[np.asarray(fr.ids) == 2]
        if len(big) == 0:    # pushed over the platform's end and out of the box
            continue
        big = big[0]
        front = front0 + plan.speed * plan.dt * min(max(step - ls.spread, 0), ls.stop - ls.spread)
        assert big[0] - r_big > front - 5e-6, (step, big[0] - r_big, front)
        pushed |= big[0] - r_big < front + 2e-5 and step > ls.spread
    assert pushed
