"""Every third-party file in ../shared/realdata parses, checked against its raw text."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from bedstruct import read_data, read_dump, read_dump_local
from bedstruct.errors import DumpFormatError

LIGGGHTS = "CFDEMproject+LIGGGHTS-PUBLIC/contactModels_v3.2.0"
PYGRAN = "anabiman+pygran"
ASHRIVA = "ashriva16+granular-force-chains/LAMMPS/examples"
LEXI = "lexiarlen+LIGGGHTS_SEAICE/lexi_tests"
GRAN = "lammps+lammps/examples/granular"


def raw_rows(path, header_line):
    """Data rows after the 1-based ``header_line`` (ITEM: ATOMS), split with plain Python."""
    lines = open(path).read().splitlines()
    return lines[header_line - 1].split()[2:], [ln.split() for ln in lines[header_line:] if ln.strip()]


def check_against_text(frame, path, header_line, *, id_col="id"):
    names, rows = raw_rows(path, header_line)
    assert len(rows) == frame.n_particles
    col = {n: k for k, n in enumerate(names)}
    for row in (rows[0], rows[len(rows) // 2], rows[-1]):
        if id_col in col:
            r = int(np.flatnonzero(frame.ids == int(row[col[id_col]]))[0])
        else:
            r = rows.index(row)
        for k, axis in enumerate("xyz"):
            assert frame.positions[r, k] == float(row[col[axis]])
        rad = float(row[col["radius"]]) if "radius" in col else float(row[col["diameter"]]) / 2
        assert frame.radii[r] == rad
        if "vx" in col:
            assert frame.velocities[r].tolist() == [float(row[col[c]]) for c in ("vx", "vy", "vz")]
        if "omegax" in col:
            assert frame.omegas[r].tolist() == [float(row[col[c]]) for c in
                                                ("omegax", "omegay", "omegaz")]
        if "fx" in col:
            assert frame.forces[r].tolist() == [float(row[col[c]]) for c in ("fx", "fy", "fz")]


def test_liggghts_contact_models_series(realdata):
    traj = read_dump(str(realdata / LIGGGHTS / "dump*.newModels"))
    assert traj.timesteps.tolist() == [0, 800, 8000, 20000]
    assert traj.n_particles.tolist() == [0, 1800, 1800, 1800]
    empty = traj[0]
    assert empty.n_particles == 0 and empty.box.boundary == ("mm", "mm", "mm")
    for k, step in ((1, 800), (3, 20000)):
        f = traj[k]
        assert f.timestep == step and f.ids.tolist() == list(range(1, 1801))
        np.testing.assert_array_equal(f.radii, 0.0025)
        assert f.images is not None and not f.columns
        np.testing.assert_array_equal(f.box.lo, [-0.05, -0.05, 0.0])
        check_against_text(f, realdata / LIGGGHTS / f"dump{step}.newModels", 9)


def test_liggghts_dump_matches_mdanalysis(realdata):
    mda = pytest.importorskip("MDAnalysis")
    path = realdata / LIGGGHTS / "dump20000.newModels"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        u = mda.Universe(str(path), topology_format="LAMMPSDUMP", format="LAMMPSDUMP")
    f = read_dump(path)[0]
    assert np.array_equal(u.atoms.ids, f.ids)  # MDAnalysis sorts by id as well
    # MDAnalysis stores float32 and moves the box origin to 0 (x - xlo); bedstruct keeps
    # float64 and never shifts the origin
    assert u.atoms.positions.dtype == np.float32
    np.testing.assert_allclose(u.atoms.positions, f.positions - f.box.lo, rtol=0, atol=1e-7)
    np.testing.assert_allclose(u.atoms.velocities, f.velocities, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(u.dimensions[:3], f.box.lengths, rtol=1e-6)


def test_pygran_positions_only_dump(realdata):
    path = realdata / PYGRAN / "PyDEM/GUI/dump.50000"
    f = read_dump(path)[0]
    assert f.n_particles == 4485 and f.ids.tolist() == list(range(1, 4486))
    assert f.box.boundary == ("ff", "ff", "ff")
    check_against_text(f, path, 9)


def test_pygran_two_frames_first_empty(realdata):
    path = realdata / PYGRAN / "examples/scripts/Particle-Analysis/Advanced/traj.dump"
    f = read_dump(path)[0]
    assert f.n_particles == 100 and f.box.boundary == ("pp", "pp", "ff")
    np.testing.assert_array_equal(f.radii, 25e-6)
    check_against_text(f, path, 9)


def test_pygran_test_dump_is_malformed(realdata):
    """pygran's test/traj.dump declares 2253 atoms in its second frame but holds 2737 rows
    (id 1 twice). bedstruct reads the first (empty) frame and names the first surplus row,
    line 2272 -- the line OVITO 3.17 also rejects; MDAnalysis misreads the file instead."""
    path = realdata / PYGRAN / "test/traj.dump"
    traj = read_dump(path)
    assert traj.timesteps.tolist() == [0, 1000] and traj.n_particles.tolist() == [0, 2253]
    assert traj[0].n_particles == 0 and traj[0].types.size == 0
    with pytest.raises(DumpFormatError, match="count mismatch") as info:
        traj[1]
    assert info.value.line == 2272
    assert open(path).read().splitlines()[2271].startswith("607 ")


def test_ashriva_2d_disc_dump_with_compute_columns(realdata):
    path = realdata / ASHRIVA / "visualize.du"
    f = read_dump(path)[0]
    assert f.n_particles == 3000
    assert sorted(f.columns) == ["c_3[1]", "c_3[2]", "c_3[3]", "c_3[4]", "c_3[5]", "c_3[6]",
                                 "c_c1", "c_c2"]
    check_against_text(f, path, 9)
    names, rows = raw_rows(path, 9)
    r = int(np.flatnonzero(f.ids == int(rows[7][0]))[0])
    assert f.columns["c_3[4]"][r] == float(rows[7][names.index("c_3[4]")])
    assert f.box.lo[0] == -7.0514196525667646e-14


def test_lexiarlen_dump_and_empty_local(realdata):
    path = realdata / LEXI / "bond_tension/post/dump1024.liggghts"
    f = read_dump(path)[0]
    assert f.timestep == 1024 and f.radii.tolist() == [50.0, 50.0]
    assert f.positions.tolist() == [[99.1903, 100, 100], [200.81, 100, 100]]
    assert f.velocities[:, 0].tolist() == [-0.5, 0.5]
    local = read_dump_local(realdata / LEXI / "bond_tension/post/bfc1024.bond",
                            columns=["id1", "id2"] + [None] * 14, frames=f)
    c = local[1024]
    assert c.n_contacts == 0 and c.branch.shape == (0, 3) and c.n_particles == 2


def test_ashriva_dump_local_joined(realdata):
    frame = read_dump(realdata / ASHRIVA / "visualize.du")[0]
    cmap = {"c_1[1]": "id1", "c_1[2]": "id2", "c_2[1]": "dist", "c_2[2]": "eng",
            "c_2[3]": "fx", "c_2[4]": "fy", "c_2[5]": "fz"}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # dumped distances agree with the frame's geometry
        contacts = read_dump_local(realdata / ASHRIVA / "dump.neigh", columns=cmap,
                                   frames=frame)[0]
    assert contacts.n_contacts == 9000 and contacts.n_particles == 3000
    lines = open(realdata / ASHRIVA / "dump.neigh").read().splitlines()
    first = lines[9].split()
    assert contacts.ids_i[0] == int(first[1]) and contacts.ids_j[0] == int(first[2])
    # positions carry 6 significant digits (%g): |x| < 60 gives distances to about 1e-4
    np.testing.assert_allclose(contacts.distance, contacts.columns["dist"], rtol=0, atol=2e-4)
    # the force on i from the dump is split along the branch: fn + ft = f, fn || branch
    f = np.array([[float(v) for v in ln.split()[5:8]] for ln in lines[9:]])
    np.testing.assert_allclose(contacts.force, f, rtol=1e-12, atol=1e-30)
    np.testing.assert_allclose(np.cross(contacts.force_normal, contacts.normals), 0, atol=1e-20)
    # contacts across the periodic boundary are kept and flagged (ids 1 and 1550)
    k = int(np.flatnonzero((contacts.ids_i == 1) & (contacts.ids_j == 1550))[0])
    assert contacts.periodic[k] and contacts.distance[k] < 1.2
    assert contacts.periodic.sum() > 0


def test_lammps_granular_data_files(realdata):
    f = read_data(realdata / GRAN / "3ps.dat")
    assert f.n_particles == 3 and f.ids.tolist() == [1, 2, 3]
    assert f.radii.tolist() == [0.00025, 0.005, 0.005]
    assert f.positions[0].tolist() == [0.005, 2.7937481665024794e-05, 0.0016005372526493155]
    assert f.images.tolist() == [[0, 0, 0]] * 3
    assert f.velocities.tolist() == [[0, 0, 0]] * 3 and f.omegas is not None
    np.testing.assert_allclose(f.columns["mass"][1], 2500 * 4 / 3 * np.pi * 0.005 ** 3)
    g = read_data(realdata / GRAN / "data.particles")
    assert g.velocities[:, 2].tolist() == [1.0, -1.0]
    s = read_data(realdata / GRAN / "spheres12.data")
    assert s.n_particles == 12 and s.images is None
    assert s.radii[1] == 0.6 and s.positions[11].tolist() == [0.8968590780, -0.2350366437,
                                                               -0.2006719701]
    assert any("assumed 'sphere'" in n for n in s.provenance.notes)
    big = read_data(realdata / GRAN / "spheres200.data")
    assert big.n_particles == 200 and big.box.hi.tolist() == [0.005, 0.005, 0.02]
    assert big.columns["density"].tolist() == [1560.0] * 200


def test_parscale_data_file_with_tabs_and_unsorted_ids(realdata):
    f = read_data(realdata / "CFDEMproject+LIGGGHTS-PUBLIC/ParScale_fluidizedBedTempParScale/"
                  "particleFew.data")
    assert f.ids.tolist() == list(range(1, 11))
    # id 7 is the second row in the file: 7 1 2e-3 2500 0.0040 0.005 0.0495
    r = int(np.flatnonzero(f.ids == 7)[0])
    assert f.positions[r].tolist() == [0.004, 0.005, 0.0495] and f.radii[r] == 1e-3
    assert f.velocities[r].tolist() == [0, 0, 1]                  # velocities joined by id
    assert f.velocities[int(np.flatnonzero(f.ids == 4)[0])].tolist() == [0, 0, -1]
    assert f.box.hi.tolist() == [0.02, 0.01, 0.10]


def test_lexiarlen_hybrid_granular_bond_gran(realdata):
    path = realdata / LEXI / "dynamic_forcing/test/test.data"
    f = read_data(path)
    assert f.n_particles == 2612
    lines = open(path).read().splitlines()
    row = lines[20].split()  # first Atoms row: id type x y z diameter density ix iy iz
    assert f.positions[0].tolist() == [float(v) for v in row[2:5]]
    assert f.radii[0] == float(row[5]) / 2 and f.columns["density"][0] == 910.0
    assert f.images.tolist()[0] == [0, 0, 0]
    vrow = lines[2635].split()
    assert f.velocities[0].tolist() == [float(v) for v in vrow[1:4]]
    assert f.omegas[0].tolist() == [float(v) for v in vrow[4:7]]
    assert any("bond/gran" in n for n in f.provenance.notes)
    assert f.columns["type_mass"][0] == 0.0
