"""Writers and readers round-trip exactly (hypothesis over frames, boxes and flags)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bedstruct import (Box, Contacts, Frame, load_hdf5, read_data, read_dump, read_dump_local,
                       save_hdf5, write_data, write_dump, write_dump_local)
from bedstruct.io._binary import write_binary_dump

FLAGS = st.sampled_from(["pp", "ff", "ss", "mm", "fs", "sm", "fm"])
SETTINGS = settings(max_examples=15, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


@st.composite
def frames(draw, *, max_n=12, extras=True):
    seed = draw(st.integers(0, 2 ** 32 - 1))
    rng = np.random.default_rng(seed)
    n = draw(st.integers(0, max_n))
    lo = rng.uniform(-5, 5, 3) * draw(st.sampled_from([1.0, 1e-4, 1e3]))
    lengths = rng.uniform(0.5, 10, 3) * abs(lo).max().clip(1e-3, None)
    tri = draw(st.booleans())
    tilt = rng.uniform(-0.4, 0.4, 3) * lengths[[0, 0, 1]] if tri else np.zeros(3)
    flags = tuple(draw(FLAGS) for _ in range(3))
    box = Box(lo, lo + lengths, tilt, flags)
    pos = box.cartesian(rng.uniform(0, 1, (n, 3)))
    radii = rng.uniform(0.01, 1.0, n) * lengths.min() / 4
    kw = {}
    if extras and draw(st.booleans()):
        kw["velocities"] = rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-20, 20)
        kw["omegas"] = rng.normal(size=(n, 3))
    if extras and draw(st.booleans()):
        kw["forces"] = rng.normal(size=(n, 3)) * 1e-9
        kw["images"] = rng.integers(-3, 4, (n, 3))
    cols = {"c_cn": rng.integers(0, 12, n).astype(float), "f_q[2]": rng.normal(size=n)} \
        if extras and draw(st.booleans()) else {}
    ids = rng.permutation(np.arange(1, 3 * n + 2))[:n]
    return Frame(pos, radii, box=box, timestep=int(rng.integers(0, 10 ** 9)), ids=ids,
                 types=rng.integers(1, 4, n), columns=cols, **kw)


def assert_same_frame(a: Frame, b: Frame, *, exact_box=None):
    a = a.sorted_by_id()
    assert b.timestep == a.timestep
    np.testing.assert_array_equal(b.ids, a.ids)
    np.testing.assert_array_equal(b.types, a.types)
    np.testing.assert_array_equal(b.positions, a.positions)      # bit-identical float64
    np.testing.assert_array_equal(b.radii, a.radii)
    for name in ("velocities", "omegas", "forces", "images"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(y, x)
    assert b.box.boundary == a.box.boundary
    if exact_box or (exact_box is None and not a.box.is_triclinic):
        assert b.box == a.box
    else:
        # triclinic bounds are written as the LAMMPS bounding box: lo + m - m may round
        np.testing.assert_array_equal(b.box.tilt, a.box.tilt)
        np.testing.assert_allclose(b.box.lo, a.box.lo, rtol=1e-15, atol=1e-15 * abs(a.box.hi).max())
        np.testing.assert_allclose(b.box.hi, a.box.hi, rtol=1e-15, atol=1e-15 * abs(a.box.hi).max())


@SETTINGS
@given(frame=frames(), ext=st.sampled_from(["dump", "dump.gz"]))
def test_write_dump_read_dump(tmp_path, frame, ext):
    path = tmp_path / f"rt.{ext}"
    write_dump(path, [frame, frame])
    traj = read_dump(path)
    assert len(traj) == 2
    for back in traj:
        assert_same_frame(frame, back)
        for name, col in frame.columns.items():
            np.testing.assert_array_equal(back.columns[name], col[np.argsort(frame.ids)])


@SETTINGS
@given(frame=frames(extras=False))
def test_write_data_read_data(tmp_path, frame):
    rng = np.random.default_rng(frame.n_particles)
    dens = rng.uniform(1000, 9000, frame.n_particles)
    vel = rng.normal(size=(frame.n_particles, 3))
    frame = Frame(frame.positions, frame.radii, box=frame.box, ids=frame.ids, types=frame.types,
                  velocities=vel, omegas=vel * 2, images=rng.integers(-2, 3, (frame.n_particles, 3)))
    path = tmp_path / "data.rt"
    write_data(path, frame, density=dens)
    back = read_data(path, boundary=frame.box.boundary)
    if frame.n_particles == 0:  # no rows: nothing says whether images/omegas were there
        assert back.n_particles == 0 and back.box == frame.box
        return
    assert_same_frame(Frame(frame.positions, frame.radii, box=frame.box, ids=frame.ids,
                            types=frame.types, velocities=vel, omegas=vel * 2,
                            images=frame.images, timestep=0), back, exact_box=True)
    np.testing.assert_array_equal(back.columns["density"], dens[np.argsort(frame.ids)])


@SETTINGS
@given(frame=frames())
def test_hdf5_round_trip(tmp_path, frame):
    frame = frame.with_units("micro")
    path = tmp_path / "rt.h5"
    save_hdf5(path, [frame], results={"phi": 0.61, "curve": np.linspace(0, 1, 100),
                                      "meta": {"name": "bed", "n": 3}})
    stored = load_hdf5(path)
    back = stored.frames[0]
    assert_same_frame(frame, back.sorted_by_id(), exact_box=True)
    assert back.units == frame.units and back.provenance == frame.provenance
    assert back.columns.keys() == frame.columns.keys()
    assert stored.results["phi"] == 0.61 and stored.results["meta"] == {"name": "bed", "n": 3}
    np.testing.assert_array_equal(stored.results["curve"], np.linspace(0, 1, 100))
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".tmp")]  # temp file gone


def test_hdf5_contacts_provenance_time_and_version(tmp_path, sc_frame):
    import bedstruct
    f = sc_frame.copy()
    f.time = 1.5
    f.provenance = f.provenance.with_note("converted cgs -> si")
    c = _lattice_contacts(f)
    save_hdf5(tmp_path / "c.h5", [f, f], contacts=[c, None])
    stored = load_hdf5(tmp_path / "c.h5")
    assert stored.bedstruct_version == bedstruct.__version__
    assert stored.frames[1].time == 1.5 and stored.frames[0].provenance.notes == f.provenance.notes
    assert stored.contacts[1] is None
    back = stored.contacts[0]
    for name in ("i", "j", "branch", "radii_i", "periodic", "force_normal"):
        np.testing.assert_array_equal(getattr(back, name), getattr(c, name))
    assert back.n_particles == c.n_particles

    # extra per-contact columns come back by name, in order (also for frames, above)
    c.columns = {"c_id": np.arange(c.n_contacts) * 3, "f_torque": np.ones((c.n_contacts, 3))}
    save_hdf5(tmp_path / "cols.h5", [f], contacts=[c])
    back = load_hdf5(tmp_path / "cols.h5").contacts[0]
    assert list(back.columns) == ["c_id", "f_torque"]
    for name in c.columns:
        np.testing.assert_array_equal(back.columns[name], c.columns[name])
    with pytest.raises(ValueError, match="align"):
        save_hdf5(tmp_path / "bad.h5", [f], contacts=[c, c])
    assert not (tmp_path / "bad.h5").exists()
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def _cubic(n, boundary) -> Frame:
    """Simple cubic lattice of touching unit-diameter spheres filling the box exactly."""
    grid = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    return Frame(grid + 0.5, np.full(len(grid), 0.5), box=Box([0, 0, 0], n, boundary=boundary))


def _lattice_contacts(frame: Frame) -> Contacts:
    """All pairs closer than 1.01 * (ri + rj), brute force, with synthetic forces."""
    d = frame.positions[None] - frame.positions[:, None]
    d = frame.box.minimum_image(d.reshape(-1, 3)).reshape(d.shape)
    dist = np.linalg.norm(d, axis=2)
    rs = frame.radii[:, None] + frame.radii[None]
    i, j = np.nonzero(np.triu(dist < 1.01 * rs, 1))
    br = d[i, j]
    n = br / np.linalg.norm(br, axis=1)[:, None]
    fn = -n * np.arange(1, len(i) + 1)[:, None]
    ft = np.cross(n, [0.3, 0.1, 0.7]) * 0.01
    periodic = np.any(frame.positions[j] - frame.positions[i] != br, axis=1)
    return Contacts(i=i, j=j, branch=br, radii_i=frame.radii[i], radii_j=frame.radii[j],
                    ids_i=frame.ids[i], ids_j=frame.ids[j], periodic=periodic, force_normal=fn,
                    force_tangential=ft, n_particles=frame.n_particles)


@pytest.mark.parametrize("boundary", ["pp pp pp", "pp ff pp", "ff ff ff"])
def test_dump_local_round_trip(tmp_path, boundary):
    frame = _cubic((3, 4, 3), boundary)
    c = _lattice_contacts(frame)
    assert c.n_contacts > 0 and c.periodic.any() == (boundary != "ff ff ff")
    path = tmp_path / "local.dump"
    kw = write_dump_local(path, frame, c)
    assert kw == ("pos", "id", "force", "force_normal", "force_tangential", "contactArea")
    back = read_dump_local(path, keywords=list(kw), frames=frame)[frame.timestep]
    for name in ("i", "j", "branch", "ids_i", "ids_j", "periodic", "force_normal",
                 "force_tangential", "radii_i"):
        np.testing.assert_array_equal(getattr(back, name), getattr(c, name), err_msg=name)
    np.testing.assert_array_equal(back.area, c.contact_area)
    np.testing.assert_array_equal(back.columns["x1"], frame.positions[c.i, 0])
    # keywords in any order describe the same fixed layout
    again = read_dump_local(path, keywords=list(reversed(kw)), frames=[frame])[frame.timestep]
    np.testing.assert_array_equal(again.force_normal, c.force_normal)
    # the columns are named by meaning, so no keywords are needed for these files
    plain = read_dump_local(path, frames=frame)[frame.timestep]
    np.testing.assert_array_equal(plain.force_tangential, c.force_tangential)
    np.testing.assert_array_equal(plain.area, c.contact_area)
    # LIGGGHTS-style names need the keywords, and two frames append to one file
    lig = tmp_path / "lig.dump"
    write_dump_local(lig, frame, c, compute_id="pgl")
    f2 = Frame(frame.positions, frame.radii, box=frame.box, timestep=50)
    write_dump_local(lig, f2, c, compute_id="pgl", append=True)
    assert "c_pgl[19]" in lig.read_text().splitlines()[8]
    both = read_dump_local(lig, keywords=kw, frames=[frame, f2])
    assert list(both) == [0, 50]
    np.testing.assert_array_equal(both[50].branch, c.branch)


def test_dump_local_total_force_is_split_along_the_branch(tmp_path, sc_frame):
    c = _lattice_contacts(sc_frame)
    c = Contacts(i=c.i, j=c.j, branch=c.branch, radii_i=c.radii_i, radii_j=c.radii_j,
                 force_normal=c.force_normal, force_tangential=c.force_tangential,
                 n_particles=c.n_particles)
    path = tmp_path / "f.dump"
    write_dump_local(path, sc_frame, c)
    # read only the total force (columns 10-12), as if only 'pos id force' had been dumped
    cmap = [None] * 6 + ["id1", "id2", "periodic", "fx", "fy", "fz"] + [f"u{k}" for k in range(7)]
    back = read_dump_local(path, columns=cmap, frames=sc_frame)[0]
    assert "u0" in back.columns and "force" not in back.columns
    np.testing.assert_allclose(back.force_normal, c.force_normal, atol=1e-12)
    np.testing.assert_allclose(back.force_tangential, c.force_tangential, atol=1e-12)


def test_dump_local_empty_and_missing_frame(tmp_path, sc_frame):
    empty = Contacts(i=[], j=[], branch=np.zeros((0, 3)), radii_i=[], radii_j=[],
                     n_particles=sc_frame.n_particles)
    path = tmp_path / "e.dump"
    kw = write_dump_local(path, sc_frame, empty)
    assert kw == ("pos", "id", "contactArea")
    back = read_dump_local(path, keywords=kw, frames=sc_frame)[0]
    assert back.n_contacts == 0 and back.n_particles == sc_frame.n_particles
    other = Frame(sc_frame.positions, sc_frame.radii, box=sc_frame.box, timestep=5)
    with pytest.raises(ValueError, match="no atom frame at timestep 0"):
        read_dump_local(path, keywords=kw, frames=other)
    with pytest.raises(ValueError, match="frames="):
        read_dump_local(path, keywords=kw)


def test_dump_local_bad_keywords_and_ids(tmp_path, sc_frame):
    from bedstruct.errors import DumpFormatError
    c = _lattice_contacts(sc_frame)
    path = tmp_path / "k.dump"
    write_dump_local(path, sc_frame, c)
    with pytest.raises(DumpFormatError, match="give 12 columns but the file has 19"):
        read_dump_local(path, keywords=["pos", "id", "force"], frames=sc_frame)
    write_dump_local(tmp_path / "k2.dump", sc_frame, c, compute_id="x")
    with pytest.raises(DumpFormatError, match="keywords="):
        read_dump_local(tmp_path / "k2.dump", frames=sc_frame)
    fewer = sc_frame.select(np.arange(10))
    with pytest.raises(DumpFormatError, match="not in the atom frame") as info:
        read_dump_local(path, keywords=["pos", "id", "force", "force_normal",
                                        "force_tangential", "contactArea"], frames=fewer)
    assert info.value.line >= 10


@pytest.mark.parametrize("revision", [1, 2])
def test_binary_dump_both_revisions(tmp_path, revision):
    rng = np.random.default_rng(revision)
    names = ["id", "type", "x", "y", "z", "vx", "vy", "vz", "radius"]
    snaps = []
    for step, tri in ((100, False), (200, True)):
        n = 7 if step == 100 else 0 if revision == 1 else 5
        data = np.column_stack([rng.permutation(n) + 1, np.ones(n), rng.uniform(0, 1, (n, 3)),
                                rng.normal(size=(n, 3)), np.full(n, 0.05)])
        snaps.append(dict(timestep=step, bounds=np.array([[-1.0, 2.0], [0.0, 1.0], [0.0, 3.0]]),
                          tilt=(0.5, 0.0, -0.25) if tri else None, boundary=("pp", "fs", "pp"),
                          names=names, data=data, units="si" if revision == 2 else None,
                          time=0.125 * step if revision == 2 else None))
    path = tmp_path / f"rev{revision}.bin"
    write_binary_dump(path, snaps, revision=revision)
    kw = {"columns": " ".join(names)} if revision == 1 else {}
    traj = read_dump(path, **kw)
    assert traj.timesteps.tolist() == [100, 200]
    for snap, frame in zip(snaps, traj):
        data = snap["data"][np.argsort(snap["data"][:, 0])]
        np.testing.assert_array_equal(frame.positions, data[:, 2:5])
        np.testing.assert_array_equal(frame.velocities, data[:, 5:8])
        assert frame.box.boundary == ("pp", "fs", "pp")
        if revision == 2:
            assert frame.units.style == "si" and frame.time == 0.125 * snap["timestep"]
    assert traj[1].box.tilt.tolist() == [0.5, 0.0, -0.25]
    if revision == 1:
        from bedstruct.errors import DumpFormatError
        with pytest.raises(DumpFormatError, match="columns="):
            read_dump(path)[0]


def test_binary_truncated_and_gz(tmp_path):
    import gzip
    from bedstruct.errors import BedstructWarning, DumpFormatError
    data = np.array([[1, 1, 0.1, 0.2, 0.3, 0.05], [2, 1, 0.4, 0.5, 0.6, 0.05]])
    snap = dict(timestep=1, bounds=np.array([[0, 1.0]] * 3), tilt=None, boundary=("pp",) * 3,
                names="id type x y z radius".split(), data=data)
    path = tmp_path / "t.bin"
    write_binary_dump(path, [snap, dict(snap, timestep=2)])
    raw = path.read_bytes()
    (tmp_path / "cut.bin").write_bytes(raw[:-20])
    with pytest.raises(DumpFormatError, match="truncated"):
        read_dump(tmp_path / "cut.bin")
    with pytest.warns(BedstructWarning):
        assert read_dump(tmp_path / "cut.bin", strict=False).timesteps.tolist() == [1]
    with gzip.open(tmp_path / "t.bin.gz", "wb") as fh:
        fh.write(raw)
    assert read_dump(tmp_path / "t.bin.gz")[1].positions.tolist() == data[:, 2:5].tolist()


def test_write_dump_columns_and_units_items(tmp_path, random_bed):
    f = random_bed.with_units("cgs")
    f.time = 0.75
    path = tmp_path / "u.dump"
    write_dump(path, f, columns="id type x y z radius", units_item=True, time_item=True)
    text = path.read_text()
    assert text.startswith("ITEM: UNITS\ncgs\nITEM: TIME\n0.75\nITEM: TIMESTEP\n100\n")
    back = read_dump(path)[0]
    assert back.units.style == "cgs" and back.time == 0.75 and back.velocities is None
    with pytest.raises(ValueError, match="does not have"):
        write_dump(path, f, columns="id x y z vx")


def test_mdanalysis_round_trip(random_bed):
    pytest.importorskip("MDAnalysis")
    from bedstruct import from_universe, to_universe
    f = random_bed
    u = to_universe(f)
    assert u.atoms.n_atoms == f.n_particles
    np.testing.assert_allclose(u.atoms.positions, f.positions, rtol=1e-6)
    np.testing.assert_array_equal(u.atoms.radii, f.radii)
    back = from_universe(u)
    assert back.box == f.box and back.timestep == f.timestep
    np.testing.assert_allclose(back.positions, f.positions, rtol=1e-6)  # float32 inside
    np.testing.assert_array_equal(back.ids, f.ids)
    tri = Frame(f.positions, f.radii, box=Box([0, 0, 0], [10, 8, 6], [1.0, 0.5, -0.5]))
    u2 = to_universe(tri)
    u2.trajectory.ts.data.pop("bedstruct_box")
    b2 = from_universe(u2)
    np.testing.assert_allclose(b2.box.matrix, tri.box.matrix, atol=1e-5)
    with pytest.raises(ValueError, match="radius="):
        import MDAnalysis as mda
        from_universe(mda.Universe.empty(2, trajectory=True))


def test_pyvista_points_and_contact_lines(sc_frame):
    pytest.importorskip("pyvista")
    from bedstruct import to_pyvista
    f = Frame(sc_frame.positions, sc_frame.radii, box=sc_frame.box,
              velocities=np.ones((sc_frame.n_particles, 3)),
              columns={"c_cn": np.arange(sc_frame.n_particles)})
    mesh = to_pyvista(f)
    assert mesh.n_points == f.n_particles
    np.testing.assert_array_equal(mesh.points, f.positions)
    assert {"radius", "id", "type", "velocities", "c_cn"} <= set(mesh.point_data.keys())
    c = _lattice_contacts(f)
    blocks = to_pyvista(f, c)
    lines = blocks["contacts"]
    assert lines.n_cells == c.n_contacts and lines.n_points == 2 * c.n_contacts
    # each line runs from particle i along the minimum-image branch (length 1 on this lattice)
    seg = lines.points[1::2] - lines.points[0::2]
    np.testing.assert_allclose(np.linalg.norm(seg, axis=1), 1.0)
    assert lines.cell_data["periodic"].sum() == c.periodic.sum() > 0
