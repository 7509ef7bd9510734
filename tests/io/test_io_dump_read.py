"""read_dump / iter_frames: column mapping, boxes, compression, series, laziness."""

from __future__ import annotations

import bz2
import gzip
import tracemalloc

import numpy as np
import pytest

import bedstruct
from bedstruct import Box, Frame, read_dump, iter_frames, write_dump
from bedstruct.errors import DumpFormatError

from _iohelpers import _dump_text_fixture, good_rows, write  # noqa: F401 (fixtures)


def test_basic_mapping_sorted_by_id(write, dump_text, good_rows):
    p = write("a.dump", dump_text(good_rows, step=42, flags="pp ff mm"))
    traj = read_dump(p)
    assert len(traj) == 1 and traj.timesteps.tolist() == [42]
    f = traj[0]
    assert f.ids.tolist() == [1, 2, 3]
    assert f.types.tolist() == [2, 1, 1]
    assert f.positions.tolist() == [[4, 5, 6], [1, 2, 3], [7.5, 8.5, 9.5]]
    assert f.radii.tolist() == [0.25, 0.5, 0.5]
    assert f.box.boundary == ("pp", "ff", "mm") and f.box.periodic == (True, False, False)
    assert f.positions.dtype == np.float64
    assert f.units.style is None  # not stated anywhere
    assert f.provenance.source == str(p)
    unsorted = read_dump(p, sort_by_id=False)[0]
    assert unsorted.ids.tolist() == [2, 1, 3]


def test_all_vector_columns(write, dump_text):
    cols = "id type x y z ix iy iz vx vy vz fx fy fz omegax omegay omegaz diameter c_x[1] c_x[2] f_t"
    row = "1 1 1 2 3 -1 0 2 0.1 0.2 0.3 4 5 6 7 8 9 0.5 11 12 13"
    f = read_dump(write("v.dump", dump_text([row], cols=cols)))[0]
    assert f.images.tolist() == [[-1, 0, 2]]
    assert f.velocities.tolist() == [[0.1, 0.2, 0.3]]
    assert f.forces.tolist() == [[4, 5, 6]]
    assert f.omegas.tolist() == [[7, 8, 9]]
    assert f.radii.tolist() == [0.25]  # diameter halved
    assert any("diameter" in n for n in f.provenance.notes)
    assert sorted(f.columns) == ["c_x[1]", "c_x[2]", "f_t"]
    assert f.columns["c_x[2]"].tolist() == [12.0]


def test_missing_id_and_type_are_synthesised(write, dump_text):
    p = write("n.dump", dump_text(["1 2 3 0.5", "4 5 6 0.5"], cols="x y z radius"))
    f = read_dump(p)[0]
    assert f.ids.tolist() == [1, 2] and f.types.tolist() == [1, 1]
    notes = " ".join(f.provenance.notes)
    assert "ids 1..N synthesised" in notes and "types set to 1" in notes


def test_missing_radius_needs_radius_argument(write, dump_text):
    p = write("r.dump", dump_text(["1 1 1 2 3"], cols="id type x y z"))
    with pytest.raises(DumpFormatError, match="radius") as err:
        read_dump(p)[0]
    assert err.value.line == 9
    with pytest.raises(ValueError, match="`radius` must be positive"):
        read_dump(p, radius=-0.3)
    f = read_dump(p, radius=0.3)[0]
    assert f.radii.tolist() == [0.3]
    assert any("given by the caller" in n for n in f.provenance.notes)


def test_scaled_coordinates_triclinic(write):
    # triclinic box lo=0, hi=(10, 8, 6), tilt xy=2, xz=-1, yz=0.5; bounding box as LAMMPS writes it
    box = Box([0, 0, 0], [10, 8, 6], [2.0, -1.0, 0.5])
    b = box.lammps_bounds()
    text = ("ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS xy xz yz pp pp pp\n"
            f"{b[0, 0]} {b[0, 1]} 2.0\n{b[1, 0]} {b[1, 1]} -1.0\n{b[2, 0]} {b[2, 1]} 0.5\n"
            "ITEM: ATOMS id type xs ys zs radius\n1 1 0.5 0.25 0.5 0.1\n")
    f = read_dump(write("tri.dump", text))[0]
    assert f.box.tilt.tolist() == [2.0, -1.0, 0.5]
    np.testing.assert_allclose(f.box.lo, [0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(f.box.hi, [10, 8, 6], atol=1e-12)
    # x = lo + s0*a + s1*b + s2*c with a=(10,0,0), b=(2,8,0), c=(-1,0.5,6)
    np.testing.assert_allclose(f.positions[0], [5 + 0.5 - 0.5, 2 + 0.25, 3.0])


def test_unwrapped_coordinates_kept_or_wrapped(write):
    text = ("ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS pp pp ff\n0 10\n0 10\n"
            "0 10\nITEM: ATOMS id xu yu zu radius\n1 12.5 -1.0 11.0 0.5\n")
    p = write("u.dump", text)
    f = read_dump(p)[0]
    assert f.positions.tolist() == [[12.5, -1.0, 11.0]]
    assert any("unwrapped" in n for n in f.provenance.notes)
    g = read_dump(p, wrap=True)[0]
    assert g.positions.tolist() == [[2.5, 9.0, 11.0]]  # z is not periodic
    assert any("wrapped into the box" in n for n in g.provenance.notes)


def test_bare_box_bounds_units_time_trailing_space(write):
    text = ("ITEM: UNITS\ncgs\nITEM: TIME\n0.25\nITEM: TIMESTEP\n7\nITEM: NUMBER OF ATOMS\n1\n"
            "ITEM: BOX BOUNDS\n0 1\n0 1\n0 1\nITEM: ATOMS id type x y z radius   \n"
            "1 1 0.5 0.5 0.5 0.1   \n   \n"
            "ITEM: UNITS\ncgs\nITEM: TIME\n0.5\nITEM: TIMESTEP\n8\nITEM: NUMBER OF ATOMS\n0\n"
            "ITEM: BOX BOUNDS\n0 1\n0 1\n0 1\nITEM: ATOMS id type x y z radius\n")
    traj = read_dump(write("units.dump", text))
    assert traj.timesteps.tolist() == [7, 8]
    f, g = traj
    assert f.units.style == "cgs" and f.time == 0.25 and g.time == 0.5
    assert f.box.boundary == ("pp", "pp", "pp")
    assert any("assumed periodic" in n for n in f.provenance.notes)
    assert g.n_particles == 0 and g.positions.shape == (0, 3)
    with pytest.raises(DumpFormatError, match="ITEM: UNITS cgs"):
        read_dump(write("units2.dump", text), units="si")[0]
    h = read_dump(write("units3.dump", text.replace("ITEM: UNITS\ncgs\n", "")), units="micro")[0]
    assert h.units.style == "micro"


@pytest.mark.parametrize("opener,ext", [(gzip.open, ".gz"), (bz2.open, ".bz2")])
def test_compressed(tmp_path, dump_text, good_rows, opener, ext):
    text = dump_text(good_rows, step=1) + dump_text(good_rows[:2], step=2)
    p = tmp_path / f"c.dump{ext}"
    with opener(p, "wb") as fh:
        fh.write(text.encode())
    traj = read_dump(p)
    assert traj.timesteps.tolist() == [1, 2]
    assert traj[1].n_particles == 2 and traj[0].n_particles == 3
    # random access backwards after forwards reopens the stream
    assert traj[0].positions.tolist() == traj[0].positions.tolist()
    # compression detected from the magic bytes without the extension
    q = tmp_path / "noext"
    q.write_bytes(p.read_bytes())
    assert read_dump(q)[1].ids.tolist() == [1, 2]


def test_zstd(tmp_path, dump_text, good_rows):
    zstd = pytest.importorskip("zstandard")
    p = tmp_path / "c.dump.zst"
    p.write_bytes(zstd.ZstdCompressor().compress(dump_text(good_rows).encode()))
    assert read_dump(p)[0].ids.tolist() == [1, 2, 3]


def test_glob_series_sorted_by_timestep(tmp_path, dump_text, good_rows):
    for step in (1000, 200, 30):
        (tmp_path / f"dump{step}.liggghts").write_text(dump_text(good_rows, step=step))
    traj = read_dump(str(tmp_path / "dump*.liggghts"))
    assert traj.timesteps.tolist() == [30, 200, 1000]
    assert [f.timestep for f in traj] == [30, 200, 1000]
    assert [f.timestep for f in iter_frames(str(tmp_path / "dump*.liggghts"))] == [30, 200, 1000]
    with pytest.raises(FileNotFoundError):
        read_dump(str(tmp_path / "nothing*.dump"))


def test_random_access_slices_and_context_manager(tmp_path, dump_text, good_rows):
    p = tmp_path / "m.dump"
    p.write_text("".join(dump_text(good_rows, step=s) for s in range(0, 50, 10)))
    with read_dump(p) as traj:
        assert len(traj) == 5
        assert traj[-1].timestep == 40 and traj[2].timestep == 20 and traj[0].timestep == 0
        assert [f.timestep for f in traj[1:4]] == [10, 20, 30]
        assert traj.n_particles.tolist() == [3] * 5
        with pytest.raises(IndexError):
            traj[5]
    assert "n_frames=5" in repr(traj)


def test_iteration_holds_one_frame(tmp_path):
    """Iterating a 20-frame file never holds more than about one frame in memory."""
    rng = np.random.default_rng(0)
    n = 5000
    frame = Frame(rng.uniform(0, 10, (n, 3)).round(5), np.full(n, 0.1), box=[10, 10, 10],
                  velocities=rng.normal(size=(n, 3)).round(6))
    p = tmp_path / "big.dump"
    write_dump(p, (Frame(frame.positions, frame.radii, box=frame.box, timestep=k,
                         velocities=frame.velocities) for k in range(20)))
    frame_bytes = n * 11 * 8
    traj = read_dump(p)
    traj[0]  # compile kernels and warm up outside the measurement
    tracemalloc.start()
    count = 0
    for f in traj:
        count += f.n_particles
        del f
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert count == 20 * n
    assert peak < 6 * frame_bytes, (peak, frame_bytes)   # the file holds 20 frames


def test_dump_local_file_refused_by_read_dump(realdata):
    p = realdata / "ashriva16+granular-force-chains/LAMMPS/examples/dump.neigh"
    with pytest.raises(DumpFormatError, match="read_dump_local"):
        read_dump(p)[0]


def test_top_level_names():
    for name in ("read_dump", "iter_frames", "read_dump_local", "read_data", "write_dump",
                 "write_data", "write_dump_local", "save_hdf5", "load_hdf5", "to_universe",
                 "from_universe", "to_pyvista"):
        assert getattr(bedstruct, name) is getattr(bedstruct.io, name)
        assert name in bedstruct.io.__all__


@pytest.mark.parametrize("chunk,slow_rows", [(37, 0), (1000, 3), (1000, 400), (1 << 21, 0)])
def test_fast_path_equals_general_path(tmp_path, monkeypatch, chunk, slow_rows):
    """The streaming one-pass parser and the general parser give identical frames,
    wherever the pieces end and however many tokens need the general number parser."""
    from bedstruct.io import _stream, lammps_dump
    from bedstruct.io._text import parse_text_frame
    from bedstruct.io.lammps_dump import frame_from_raw
    monkeypatch.setattr(_stream, "_STREAM_CHUNK", chunk)
    rng = np.random.default_rng(3)
    n = 500
    cols = "id type x y z xu yu zu ix iy iz vx vy vz omegax omegay omegaz fx fy fz radius c_a f_b[2]"
    data = np.column_stack([rng.permutation(n) + 1, rng.integers(1, 4, n),
                            rng.uniform(0, 10, (n, 6)).round(6), rng.integers(-2, 3, (n, 3)),
                            rng.normal(size=(n, 9)).round(7), rng.uniform(0.1, 0.3, n).round(4),
                            rng.normal(size=(n, 2)).round(3)])
    data[:slow_rows, -1] = rng.normal(size=slow_rows)        # 17-digit round-trip reprs
    data[:slow_rows:2, -2] = np.nan
    lines = [" ".join(("%d" if k in (0, 1, 8, 9, 10) else "%r") % v for k, v in enumerate(row))
             for row in data.tolist()]
    text = ("ITEM: TIMESTEP\n3\nITEM: NUMBER OF ATOMS\n%d\nITEM: BOX BOUNDS pp pp ff\n0 10\n0 10\n"
            "0 10\nITEM: ATOMS %s\n" % (n, cols)) + "\n".join(lines) + "\n"
    p = tmp_path / "both.dump"
    p.write_text(text)
    def general_path_used(*args, **kwargs):
        raise AssertionError("the streaming parser fell back to the general path")

    monkeypatch.setattr(lammps_dump.DumpTrajectory, "_raw", general_path_used)
    for sort in (True, False):
        fast = read_dump(p, sort_by_id=sort)[0]
        general = frame_from_raw(parse_text_frame(text.encode(), path=str(p)), sort_by_id=sort)
        for name in ("positions", "radii", "ids", "types", "velocities", "omegas", "forces",
                     "images"):
            np.testing.assert_array_equal(getattr(fast, name), getattr(general, name), name)
        assert fast.columns.keys() == general.columns.keys() == {"xu", "yu", "zu", "c_a", "f_b[2]"}
        for name in fast.columns:
            np.testing.assert_array_equal(fast.columns[name], general.columns[name])
        if slow_rows:
            order = np.argsort(data[:, 0]) if sort else np.arange(n)
            np.testing.assert_array_equal(fast.columns["f_b[2]"], data[order, -1])
            assert fast.columns[name].flags.c_contiguous
        assert fast.positions.flags.c_contiguous and fast.velocities.flags.c_contiguous
    assert fast.ids.tolist() == data[:, 0].astype(int).tolist()  # file order when not sorting


def test_crlf_line_endings_and_tabs(write, dump_text, good_rows):
    text = dump_text([r.replace(" ", "\t") for r in good_rows], step=5)
    p = write("crlf.dump", text.replace("\n", "\r\n").encode())
    f = read_dump(p)[0]
    assert f.timestep == 5 and f.ids.tolist() == [1, 2, 3]
    assert f.positions.tolist() == [[4, 5, 6], [1, 2, 3], [7.5, 8.5, 9.5]]


@pytest.mark.parametrize("hide_isal", [True, False])
def test_gzip_with_and_without_isal(tmp_path, monkeypatch, dump_text, good_rows, hide_isal):
    import sys
    if hide_isal:
        monkeypatch.setitem(sys.modules, "isal", None)  # import fails: standard gzip is used
    else:
        pytest.importorskip("isal")
    p = tmp_path / "s.dump.gz"
    with gzip.open(p, "wb") as fh:
        fh.write("".join(dump_text(good_rows, step=s) for s in (5, 6, 7)).encode())
    traj = read_dump(p)
    assert [f.timestep for f in traj] == [5, 6, 7]
    assert traj[0].positions.tolist() == traj[2].positions.tolist()


def test_units_stated_once_apply_to_every_frame_of_the_file(write, dump_text, good_rows):
    """LAMMPS writes ITEM: UNITS before the first snapshot only (dump_modify units yes)."""
    text = ("ITEM: UNITS\nsi\nITEM: TIME\n0\n" + dump_text(good_rows, step=0)
            + "ITEM: TIME\n0.001\n" + dump_text(good_rows, step=100) + dump_text(good_rows, step=200))
    p = write("units.dump", text)
    traj = read_dump(p)
    assert [f.units.style for f in traj] == ["si", "si", "si"]
    assert traj.header(2).units == "si"
    for k in (0, 2):  # the conflict is found whichever frame is read
        with pytest.raises(DumpFormatError, match="ITEM: UNITS si") as info:
            read_dump(p, units="cgs")[k]
        assert info.value.line == 2
    assert read_dump(p, units="SI")[2].units.style == "si"
    # a run appended in another unit style restates it: it applies from there on
    more = write("more.dump", text + "ITEM: UNITS\ncgs\n" + dump_text(good_rows, step=300))
    assert [f.units.style for f in read_dump(more)] == ["si", "si", "si", "cgs"]
    # the unit of one file is not carried into the next file of a glob
    other = write("units.dump.b", dump_text(good_rows, step=400))
    traj = read_dump([p, other])
    assert [f.units.style for f in traj] == ["si", "si", "si", None]


def test_binary_units_stated_in_the_first_snapshot_only(tmp_path):
    from bedstruct.io._binary import write_binary_dump
    data = np.array([[1, 1, 0.5, 0.5, 0.5, 0.1]])
    snap = dict(timestep=0, bounds=np.array([[0, 1.0]] * 3), tilt=None, boundary=("pp",) * 3,
                names="id type x y z radius".split(), data=data, units="cgs")
    path = tmp_path / "u.bin"
    write_binary_dump(path, [snap, dict(snap, timestep=10, units=None),
                             dict(snap, timestep=20, units=None)])
    assert [f.units.style for f in read_dump(path)] == ["cgs", "cgs", "cgs"]
    with pytest.raises(DumpFormatError, match="cgs"):
        read_dump(path, units="si")[2]


def _triclinic_unwrapped(write, cols, arrays, name):
    lo = np.array([1.0, 2.0, 3.0])
    box = Box(lo, lo + [10.0, 8.0, 6.0], [2.0, -1.0, 1.5], boundary="pp pp ff")
    b = box.lammps_bounds()
    head = ("ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n5\nITEM: BOX BOUNDS xy xz yz pp pp ff\n"
            + "".join(f"{float(b[k, 0])!r} {float(b[k, 1])!r} {float(box.tilt[k])!r}\n"
                      for k in range(3))
            + f"ITEM: ATOMS id type {cols} radius\n")
    rows = [f"{i + 1} 1 " + " ".join(repr(float(v)) if a.dtype.kind == "f" else str(int(v))
                                     for a in arrays for v in a[i]) + " 0.1\n"
            for i in range(5)]
    return write(name, head + "".join(rows)), box


def test_unwrapped_coordinates_with_image_flags_are_not_shifted_twice(tmp_path, write):
    rng = np.random.default_rng(0)
    s = rng.uniform(0.05, 0.95, (5, 3))
    img = rng.integers(-2, 3, (5, 3))
    img[:, 2] = 0                                  # z is not periodic
    lo = np.array([1.0, 2.0, 3.0])
    m = Box(lo, lo + [10.0, 8.0, 6.0], [2.0, -1.0, 1.5]).matrix
    xu = lo + (s + img) @ m.T
    p, box = _triclinic_unwrapped(write, "xu yu zu ix iy iz", [xu, img], "uimg.dump")
    f = read_dump(p)[0]
    assert np.array_equal(f.positions, xu)               # as written, default wrap=False
    assert np.array_equal(f.unwrapped_positions(), xu)   # images not added a second time
    assert f.images.tolist() == [[0, 0, 0]] * 5
    assert any("ix iy iz" in n for n in f.provenance.notes)
    g = read_dump(p, wrap=True)[0]
    assert box.contains(g.positions).all()
    assert g.images.tolist() == img.tolist()
    np.testing.assert_allclose(g.unwrapped_positions(), xu, rtol=0, atol=1e-12)
    assert any("ix iy iz" in n for n in g.provenance.notes)
    for frame in (f, g):   # round trip: the same frame, bit for bit
        out = tmp_path / "rt.dump"
        write_dump(out, frame)
        back = read_dump(out)[0]
        assert np.array_equal(back.positions, frame.positions)
        assert np.array_equal(back.images, frame.images)
        np.testing.assert_allclose(back.unwrapped_positions(), frame.unwrapped_positions(),
                                   rtol=0, atol=1e-12)  # the box may differ in the last bit


def test_wrapping_unwrapped_coordinates_records_the_images(write):
    text = ("ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS pp pp ff\n0 10\n0 10\n"
            "0 10\nITEM: ATOMS id xu yu zu radius\n1 32.5 -1.0 11.0 0.5\n")
    g = read_dump(write("u.dump", text), wrap=True)[0]
    assert g.positions.tolist() == [[2.5, 9.0, 11.0]] and g.images.tolist() == [[3, -1, 0]]
    assert g.unwrapped_positions().tolist() == [[32.5, -1.0, 11.0]]


def test_columns_given_as_one_string(write, dump_text, good_rows):
    p = write("a.dump", dump_text(good_rows))
    f = read_dump(p, columns="id type x y z radius")[0]
    assert f.ids.tolist() == [1, 2, 3] and f.radii.tolist() == [0.25, 0.5, 0.5]
    old = write("old.dump", dump_text(good_rows, cols=""))
    with pytest.raises(DumpFormatError, match="columns="):
        read_dump(old)[0]
    g = read_dump(old, columns="id type x y z radius")[0]
    assert g.positions.tolist() == f.positions.tolist()
    with pytest.raises(ValueError, match="columns"):
        read_dump(p, columns="")


@pytest.mark.parametrize("bad", ["mm", "foo", 5, ""])
def test_units_argument_is_checked(write, dump_text, good_rows, bad):
    p = write("a.dump", dump_text(good_rows))
    with pytest.raises(ValueError, match="si, cgs, micro, nano, lj, real, metal, electron"):
        read_dump(p, units=bad)


def test_units_argument_accepts_the_lammps_styles(write, dump_text, good_rows):
    p = write("a.dump", dump_text(good_rows))
    for style in ("si", "cgs", "micro", "nano", "lj", "real", "metal", "electron", "CGS"):
        assert read_dump(p, units=style)[0].units.style == style.lower()
    assert read_dump(p, units=None)[0].units.style is None
    bad = write("b.dump", "ITEM: UNITS\nfurlong\n" + dump_text(good_rows))
    with pytest.raises(DumpFormatError, match="furlong") as info:
        read_dump(bad)[0]
    assert info.value.line == 2


@pytest.mark.parametrize("ids", [[1, 2, 3, 4, 5], [11, 12, 13, 14, 15], [2, 5, 7, 9, 40],
                                 [3, 1, 5, 2, 4]], ids=["dense", "offset", "sparse", "unsorted"])
def test_dump_local_joins_contacts_by_particle_id(tmp_path, ids):
    """Contacts name particles by id; i and j are their rows in the atom frame, whether the
    ids are a run of consecutive numbers (found by offset) or not (found by search)."""
    from bedstruct import read_dump_local
    pos = np.array([[0.1, 0.1, 0.1], [0.3, 0.1, 0.1], [0.5, 0.1, 0.1], [0.7, 0.1, 0.1],
                    [0.9, 0.1, 0.1]])
    frame = Frame(pos, np.full(5, 0.1), box=[1, 1, 1], ids=ids, timestep=7)
    pairs = [(0, 1), (4, 0), (2, 3), (3, 4)]  # rows of `frame` as given
    lines = [f"{ids[a]} {ids[b]} 0" for a, b in pairs]
    path = tmp_path / "pairs.local"
    path.write_text("ITEM: TIMESTEP\n7\nITEM: NUMBER OF ENTRIES\n4\nITEM: BOX BOUNDS pp pp pp\n"
                    "0 1\n0 1\n0 1\nITEM: ENTRIES id1 id2 periodic\n" + "\n".join(lines) + "\n")
    c = read_dump_local(path, frames=frame)[7]
    assert frame.positions[c.i].tolist() == pos[[a for a, _ in pairs]].tolist()
    assert frame.positions[c.j].tolist() == pos[[b for _, b in pairs]].tolist()
    assert c.ids_i.tolist() == [ids[a] for a, _ in pairs]
    assert c.ids_j.tolist() == [ids[b] for _, b in pairs]
    # branch from i to j by the minimum image (box length 1)
    dx = [((pos[b, 0] - pos[a, 0] + 0.5) % 1.0) - 0.5 for a, b in pairs]
    assert c.branch[:, 0] == pytest.approx(dx)
    for bad in (max(ids) + 1, min(ids) - 1, 0):
        if bad in ids:
            continue
        path.write_text(path.read_text().replace(lines[2], f"{ids[2]} {bad} 0"))
        with pytest.raises(DumpFormatError, match=rf"particle id {bad} \(id2\)") as e:
            read_dump_local(path, frames=frame)
        assert e.value.line == 12
        path.write_text(path.read_text().replace(f"{ids[2]} {bad} 0", lines[2]))


def test_gzip_source_reads_the_plain_bytes_at_any_offset(tmp_path):
    """Ranges of a multi-member gzip stream, read into buffers or as bytes, forwards and
    backwards (reopening the stream), are the bytes of the plain text."""
    from bedstruct.io._source import Source
    rng = np.random.default_rng(3)
    plain = b"".join(rng.integers(0, 10, 400_000).astype(str).astype("S1"))
    path = tmp_path / "members.gz"
    with open(path, "wb") as fh:  # three members and zero padding, as frame-by-frame writes
        for part in (plain[:100_000], plain[100_000:100_001], plain[100_001:]):
            fh.write(gzip.compress(part) + b"\0" * 3)
    src = Source(path)
    buf = bytearray(150_000)
    for start, size in [(0, 10), (5, 150_000), (99_990, 30), (300_000, 150_000),
                        (1000, 1), (399_999, 10), (400_000, 10), (50_000, 120_000)]:
        want = plain[start:start + size]
        assert src.read_range(start, size) == want
        got = src.read_into(start, memoryview(buf)[:size])
        assert bytes(buf[:got]) == want, (start, size)
    src.close()


def test_gzip_source_resumes_backward_reads_from_saved_points(tmp_path, monkeypatch):
    """A range read again after later ones (a frame read a second time) decodes from the
    point saved where it was first read, not from the start of the file, and gives the
    same bytes, across member boundaries and after pickling."""
    import pickle

    from bedstruct.io._source import Source, _GzipMembers
    monkeypatch.setattr(_GzipMembers, "_RAW", 4096)  # many small decoding steps
    calls = []
    decode = _GzipMembers._decode_more
    monkeypatch.setattr(_GzipMembers, "_decode_more", lambda self: calls.append(1) or decode(self))
    rng = np.random.default_rng(4)
    plain = b"".join(rng.integers(0, 10, 400_000).astype(str).astype("S1"))
    path = tmp_path / "members.gz"
    with open(path, "wb") as fh:
        for part in (plain[:100_000], plain[100_000:100_001], plain[100_001:]):
            fh.write(gzip.compress(part) + b"\0" * 3)
    src = Source(path)
    starts = [5, 100_000, 100_001, 250_000, 350_000]
    for s in starts:
        assert src.read_range(s, 20_000) == plain[s:s + 20_000]
    calls.clear()
    assert src.read_range(0, 100) == plain[:100]
    from_start = len(calls)  # a reopened stream decodes from the start
    buf = bytearray(20_000)
    for s in [350_000, 250_000, 100_001, 100_000, 250_000, 5]:
        calls.clear()
        assert src.read_range(s, 20_000) == plain[s:s + 20_000], s
        assert len(calls) <= from_start + 4, s  # not the 100-350 kB before s again
        assert src.read_into(s + 7, buf) == 20_000 and bytes(buf) == plain[s + 7:s + 20_007]
    calls.clear()
    src.read_range(350_000, 10)
    assert 0 < len(calls) < 8  # 350 kB from the start would take about 35 steps
    copy = pickle.loads(pickle.dumps(src))
    assert copy.read_range(250_000, 50) == plain[250_000:250_050]
    src.close()
    copy.close()


@pytest.mark.parametrize("name", ["closing.dump", "closing.dump.gz", "closing.dump.bz2"])
def test_lazy_trajectories_close_their_files(tmp_path, name):
    """No file is left open (no ResourceWarning): a trajectory read from and dropped, an
    iteration run to the end or broken off, and read_dump_local."""
    import gc
    import warnings
    from bedstruct import read, read_dump_local
    frames = [Frame([[0.5, 0.5, 0.5], [1.4, 0.5, 0.5]], [0.5, 0.5], box=[2, 1, 1], timestep=t)
              for t in (0, 10)]
    path = tmp_path / name
    write_dump(path, frames)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResourceWarning)
        # a ResourceWarning in a finaliser is reported through sys.unraisablehook
        with pytest.MonkeyPatch.context() as mp:
            caught = []
            mp.setattr("sys.unraisablehook", caught.append)
            assert read(path)[-1].timestep == 10
            traj = read(path)
            assert [f.timestep for f in traj] == [0, 10]
            assert all(f.source._fh is None for f in traj._files)
            it = iter(traj)
            next(it)
            it.close()
            assert all(f.source._fh is None for f in traj._files)
            traj[0]
            del traj, it
            gc.collect()
        assert not caught, [str(c.exc_value) for c in caught]
