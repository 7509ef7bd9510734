"""bedstruct's readers against OVITO's (``ovito.io.import_file``), an independent implementation.

Both read the same files: the third-party LIGGGHTS/LAMMPS files in ../shared/realdata and
dumps bedstruct writes itself (text, gz, binary of both header layouts, triclinic, scaled
``xs ys zs``, unwrapped ``xu yu zu`` with image flags, several frames). Compared: frame
count, timesteps, ids, types, positions, radii, velocities, forces, angular velocities,
image flags, extra columns, the cell matrix and origin, and the periodic flags.

Tolerances (measured with OVITO 3.17.2; set by what OVITO stores and how it parses):

* OVITO keeps positions, velocities, forces and extra columns as float64, but its number
  parser is not always correctly rounded: with 16-17 significant digits (Python's ``repr``,
  which ``write_dump`` and the engine write) 10-30 % of the values come out 1 or 2 ulp away
  from ``float(text)`` (2 ulp only below about 1e-5; at most 1.35 machine epsilons relative,
  over 300,000 random values from 1e-30 to 1e30), and so do a few short numbers with large
  exponents (``1.21169e-27`` in ashriva16's dump). Float64 values therefore agree to
  **2 ulp** (``OVITO_ULPS``), and every file is also
  checked value by value against Python's ``float`` of its text (or against the array
  written): bedstruct's values are the correctly rounded ones, bit for bit. LIGGGHTS' ``%g``
  numbers in the usual range (6 digits, exponent within +-22) agree exactly (checked on a
  ``%g`` file bedstruct writes).
* OVITO stores radii as **float32**, parsed straight from the text: they agree with
  bedstruct's float64 radii cast to float32 exactly for ``%g`` text and binary files, and to
  1 float32 ulp for 17-digit text (OVITO's float32 parse is not correctly rounded either).
* Scaled coordinates are converted to Cartesian by both (in a different order of operations):
  agree to 4 ulp of the box size. Triclinic cells are rebuilt by both from the bounding box
  written in the dump: same bound.
* OVITO keeps rows in file order; bedstruct sorts them by id (``sort_by_id=False`` keeps file
  order, checked too). A file without ids gets ids 1..N in file order from bedstruct.
* OVITO takes the positions of a binary dump of the old layout (no column names) whose
  coordinates all lie in [0, 1] for scaled coordinates; the binary test keeps coordinates
  in a box that is not the unit cube, where both readers take them as Cartesian.

The module skips when OVITO is not installed (``pip install -e .[bench]``) and the real-data
tests skip when ../shared/realdata is absent.
"""

from __future__ import annotations

import gzip
import shutil
import warnings

import numpy as np
import pytest

ovito_io = pytest.importorskip("ovito.io", reason="OVITO is not installed "
                               "(pip install -e .[bench], or pip install 'ovito>=3.10')")

from bedstruct import Box, Frame, read_data, read_dump, write_dump  # noqa: E402
from bedstruct.errors import DumpFormatError  # noqa: E402
from bedstruct.io._binary import write_binary_dump  # noqa: E402

LIGGGHTS = "CFDEMproject+LIGGGHTS-PUBLIC/contactModels_v3.2.0"
PARSCALE = "CFDEMproject+LIGGGHTS-PUBLIC/ParScale_fluidizedBedTempParScale"
PYGRAN = "anabiman+pygran"
ASHRIVA = "ashriva16+granular-force-chains/LAMMPS/examples"
LEXI = "lexiarlen+LIGGGHTS_SEAICE/lexi_tests"
GRAN = "lammps+lammps/examples/granular"

EPS = np.finfo(np.float64).eps
OVITO_ULPS = 2  # OVITO's parse of 17-digit (and some large-exponent) numbers, see above
VECTORS = (("velocities", "Velocity"), ("forces", "Force"), ("omegas", "Angular Velocity"))


# ----------------------------------------------------------------------------- helpers
def ovito_pipeline(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ovito_io.import_file(str(path), **kw)


def ovito_frames(path, **kw):
    """All frames of a file (or wildcard pattern) as OVITO DataCollections."""
    pipe = ovito_pipeline(path, **kw)
    return [pipe.compute(k) for k in range(pipe.source.num_frames)]


def prop(data, name):
    """An OVITO particle property as a NumPy array (None when absent)."""
    return np.asarray(data.particles[name]).copy() if name in data.particles.keys() else None


def assert_ulp(a, b, ulps, what):
    """``|a - b| <= ulps`` units in the last place of ``b`` (0: bit-identical)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape, what
    if ulps == 0:
        np.testing.assert_array_equal(a, b, err_msg=what)
        return
    tol = ulps * np.spacing(np.abs(b))
    bad = np.abs(a - b) > tol
    assert not bad.any(), (f"{what}: {int(bad.sum())} values differ by more than {ulps} ulp, "
                           f"e.g. {a[bad][:3].tolist()} vs {b[bad][:3].tolist()}")


def assert_box(frame, data, *, ulps=0):
    """Cell matrix (columns are the cell vectors), origin and periodic flags."""
    cell = np.asarray(data.cell[...], dtype=np.float64)
    scale = float(np.abs(cell).max()) if cell.size else 1.0
    if ulps == 0:
        np.testing.assert_array_equal(cell[:, :3], frame.box.matrix, err_msg="cell matrix")
        np.testing.assert_array_equal(cell[:, 3], frame.box.lo, err_msg="cell origin")
    else:
        np.testing.assert_allclose(cell[:, :3], frame.box.matrix, rtol=0,
                                   atol=ulps * EPS * scale, err_msg="cell matrix")
        np.testing.assert_allclose(cell[:, 3], frame.box.lo, rtol=0, atol=ulps * EPS * scale,
                                   err_msg="cell origin")
    assert tuple(bool(p) for p in data.cell.pbc) == tuple(frame.box.periodic)


def assert_same(frame, data, *, ulps=0, pos_atol=None, file_order=False, check_images=True,
                timestep=True):
    """One bedstruct frame against one OVITO frame.

    OVITO rows are put in id order unless ``file_order`` (a file without ids, or
    ``sort_by_id=False``). ``ulps`` bounds float64 values; ``pos_atol`` replaces it for
    positions (scaled coordinates).
    """
    n = data.particles.count
    assert frame.n_particles == n
    if timestep:
        assert frame.timestep == data.attributes["Timestep"]
    ids = prop(data, "Particle Identifier")
    order = np.arange(n)
    if ids is None:
        np.testing.assert_array_equal(frame.ids, np.arange(1, n + 1))  # synthesised
    else:
        if not file_order:
            order = np.argsort(ids, kind="stable")
        np.testing.assert_array_equal(frame.ids, ids[order])
    types = prop(data, "Particle Type")
    if types is None:
        np.testing.assert_array_equal(frame.types, 1)  # bedstruct's default
    else:
        np.testing.assert_array_equal(frame.types, types[order])
    pos = prop(data, "Position")[order]
    if pos_atol is None:
        assert_ulp(frame.positions, pos, ulps, "positions")
    else:
        np.testing.assert_allclose(frame.positions, pos, rtol=0, atol=pos_atol,
                                   err_msg="positions")
    radius = prop(data, "Radius")
    assert radius.dtype == np.float32  # OVITO's storage: compare in float32
    mine = frame.radii.astype(np.float32)
    if ulps:  # 1 float32 ulp: OVITO parses 17-digit radii straight to float32
        np.testing.assert_array_max_ulp(mine, radius[order], maxulp=ulps)
    else:
        np.testing.assert_array_equal(mine, radius[order], err_msg="radii (float32)")
    for attr, name in VECTORS:
        ref = prop(data, name)
        mine = getattr(frame, attr)
        assert (ref is None) == (mine is None), attr
        if ref is not None:
            assert_ulp(mine, ref[order], ulps, attr)
    img = prop(data, "Periodic Image")
    if check_images:
        assert (img is None) == (frame.images is None)
        if img is not None:
            np.testing.assert_array_equal(frame.images, img[order])
    return order


def python_table(path, header_line=9):
    """The data block of a one-frame dump parsed with Python's ``float``, per column name,
    in file order (the referee where OVITO and bedstruct differ by an ulp)."""
    lines = open(path).read().splitlines()
    names = lines[header_line - 1].split()[2:]
    rows = [[float(v) for v in ln.split()] for ln in lines[header_line:] if ln.strip()]
    table = np.array(rows, dtype=np.float64).reshape(len(rows), len(names))
    return {name: table[:, k] for k, name in enumerate(names)}


def frame_table(frame):
    """A bedstruct frame's values under their dump column names."""
    out = {"id": frame.ids, "type": frame.types, "radius": frame.radii}
    for k, c in enumerate("xyz"):
        out[c] = frame.positions[:, k]
    for attr, names in (("velocities", ("vx", "vy", "vz")), ("forces", ("fx", "fy", "fz")),
                        ("omegas", ("omegax", "omegay", "omegaz")),
                        ("images", ("ix", "iy", "iz"))):
        arr = getattr(frame, attr)
        if arr is not None:
            out.update({c: arr[:, k] for k, c in enumerate(names)})
    out.update(frame.columns)
    return out


def assert_matches_text(path, **kw):
    """bedstruct's file-order frame equals Python's ``float`` of every token, bit for bit."""
    frame = read_dump(path, sort_by_id=False, **kw)[0]
    ref = python_table(path)
    mine = frame_table(frame)
    for name, values in ref.items():
        np.testing.assert_array_equal(np.asarray(mine[name], dtype=np.float64), values,
                                      err_msg=f"column {name} of {path}")


# ----------------------------------------------------------------------------- real data
def test_liggghts_series_by_wildcard(realdata):
    """Four LIGGGHTS files (the first with 0 atoms, ``mm`` bounds, ``ix iy iz``, a trailing
    space after the column names), opened as one trajectory by both."""
    pattern = str(realdata / LIGGGHTS / "dump*.newModels")
    traj = read_dump(pattern)
    frames = ovito_frames(pattern)
    assert len(traj) == len(frames) == 4
    assert traj.timesteps.tolist() == [d.attributes["Timestep"] for d in frames]
    for frame, data in zip(traj, frames):
        assert_same(frame, data)  # %g numbers: bit for bit
        assert_box(frame, data)
    assert frames[0].particles.count == 0 and frames[1].particles.count == 1800
    for path in traj.paths[1:]:
        assert_matches_text(path)


@pytest.mark.parametrize("rel", [
    f"{PYGRAN}/PyDEM/GUI/dump.50000",                                      # x y z radius only
    f"{PYGRAN}/examples/scripts/Particle-Analysis/Advanced/traj.dump",      # ids out of order
    f"{ASHRIVA}/visualize.du",                                             # compute columns
    f"{LEXI}/bond_tension/post/dump1024.liggghts",
])
def test_third_party_dump(realdata, rel):
    path = realdata / rel
    traj = read_dump(path)
    frames = ovito_frames(path)
    assert len(traj) == len(frames) == 1
    frame, data = traj[0], frames[0]
    no_ids = "Particle Identifier" not in data.particles.keys()
    # OVITO misrounds a few tokens (1.21169e-27 in visualize.du) by 1 ulp; bedstruct's
    # values are Python's float of every token (assert_matches_text)
    order = assert_same(frame, data, ulps=OVITO_ULPS, file_order=no_ids)
    assert_box(frame, data)
    # every extra column (c_c1, c_3[1], ...) is kept by both under its dump name
    for name, values in frame.columns.items():
        assert_ulp(values, prop(data, name)[order], OVITO_ULPS, name)
    unsorted = read_dump(path, sort_by_id=False)[0]
    assert_same(unsorted, data, ulps=OVITO_ULPS, file_order=True)
    assert_matches_text(path)


def test_pygran_malformed_second_frame(realdata):
    """pygran's test/traj.dump declares 2253 atoms in its second frame but holds more rows:
    OVITO keeps only the first (empty) frame, bedstruct lists both and names line 2272,
    the line OVITO reports too."""
    path = realdata / PYGRAN / "test/traj.dump"
    traj = read_dump(path)
    frames = ovito_frames(path)
    assert len(frames) == 1 and frames[0].particles.count == 0
    assert_same(traj[0], frames[0])
    assert_box(traj[0], frames[0])
    with pytest.raises(DumpFormatError) as info:
        traj[1]
    assert info.value.line == 2272


@pytest.mark.parametrize("rel, style", [
    (f"{GRAN}/3ps.dat", None), (f"{GRAN}/data.particles", None),
    (f"{GRAN}/spheres12.data", "sphere"), (f"{GRAN}/spheres200.data", "sphere"),
    (f"{PARSCALE}/particleFew.data", "sphere"),
])
def test_third_party_data_file(realdata, rel, style):
    """LAMMPS data files (``atom_style sphere``). OVITO needs ``atom_style`` where the file
    has no ``Atoms # sphere`` comment; it cannot read LIGGGHTS' ``hybrid granular bond/gran``
    file (lexiarlen's test.data), which is not compared."""
    path = realdata / rel
    frame = read_data(path)
    kw = {} if style is None else {"atom_style": style}
    (data,) = ovito_frames(path, **kw)
    # data files store no boundary flags: OVITO assumes periodic, as bedstruct's default.
    # 3ps.dat has 17-digit coordinates (OVITO misrounds 2.7937481665024794e-05 by 1 ulp)
    assert_same(frame, data, ulps=OVITO_ULPS, timestep=False)
    assert_box(frame, data)
    by_id = np.argsort(prop(data, "Particle Identifier"))
    np.testing.assert_array_equal(frame.columns["density"], prop(data, "Density")[by_id])


# ----------------------------------------------------------------------------- bedstruct's dumps
def random_frames(n=300, frames=3, *, tilt=None, boundary="pp fs pp", seed=0):
    """Frames with permuted ids, all vectors and image flags, in a box off the origin."""
    rng = np.random.default_rng(seed)
    box = Box([-1.5, 0.25, 0.5], [2.0, 1.0, 3.0], tilt if tilt is not None else np.zeros(3),
              boundary)
    out = []
    for k in range(frames):
        images = rng.integers(-2, 3, (n, 3)) * np.array(box.periodic)  # 0 on fixed axes
        out.append(Frame(box.cartesian(rng.uniform(0, 1, (n, 3))), rng.uniform(0.01, 0.02, n),
                         box=box, timestep=1000 * k + 7, ids=rng.permutation(n) + 1,
                         types=rng.integers(1, 4, n), velocities=rng.normal(0, 0.1, (n, 3)),
                         forces=rng.normal(0, 1e-6, (n, 3)), omegas=rng.normal(0, 10, (n, 3)),
                         images=images))
    return out


def check_written(path, written, *, ulps=OVITO_ULPS):
    """bedstruct gives back exactly what was written; OVITO agrees to ``ulps``."""
    traj = read_dump(path)
    frames = ovito_frames(path)
    assert len(traj) == len(frames) == len(written)
    assert traj.timesteps.tolist() == [d.attributes["Timestep"] for d in frames] \
        == [f.timestep for f in written]
    for frame, data, orig in zip(traj, frames, written):
        orig = orig.sorted_by_id()
        np.testing.assert_array_equal(frame.positions, orig.positions)  # the correct value
        assert_same(frame, data, ulps=ulps)
        assert_box(frame, data, ulps=0 if not frame.box.is_triclinic else 4)
    return traj, frames


@pytest.mark.parametrize("suffix", ["", ".gz"])
def test_written_text_and_gz_multi_frame(tmp_path, suffix):
    written = random_frames()
    path = tmp_path / f"dump.liggghts{suffix}"
    write_dump(path, written)  # up to 17 significant digits: OVITO within 2 ulp
    check_written(path, written)
    if suffix == "":  # the same file compressed by another tool reads the same
        with open(path, "rb") as src, gzip.open(tmp_path / "copy.gz", "wb") as dst:
            shutil.copyfileobj(src, dst)
        check_written(tmp_path / "copy.gz", written)


def test_written_six_digits_agree_exactly(tmp_path):
    """LIGGGHTS writes ``%g`` (6 digits): OVITO and bedstruct agree bit for bit."""
    written = random_frames(frames=2, seed=3)
    rounded = []
    for f in written:  # round every float to 6 significant digits, as %g does
        g = lambda a: np.array([float(f"{v:g}") for v in a.ravel()]).reshape(a.shape)  # noqa: E731
        rounded.append(Frame(g(f.positions), g(f.radii), box=f.box, timestep=f.timestep,
                             ids=f.ids, types=f.types, velocities=g(f.velocities),
                             forces=g(f.forces), omegas=g(f.omegas), images=f.images))
    path = tmp_path / "dump6"
    write_dump(path, rounded)
    check_written(path, rounded, ulps=0)


def test_written_triclinic(tmp_path):
    written = random_frames(frames=2, tilt=(0.5, -0.25, 0.125), boundary="pp pp ff", seed=1)
    path = tmp_path / "tri.dump"
    write_dump(path, written)
    traj, frames = check_written(path, written)  # the cell matrices carry the tilt
    assert traj[0].box.is_triclinic and np.asarray(frames[0].cell[...])[0, 1] == 0.5  # xy


@pytest.mark.parametrize("tilt", [None, (0.5, -0.25, 0.125)])
def test_written_scaled_coordinates(tmp_path, tilt):
    (f,) = random_frames(frames=1, tilt=tilt, seed=2)
    s = f.box.fractional(f.positions)
    g = Frame(f.positions, f.radii, box=f.box, timestep=f.timestep, ids=f.ids, types=f.types,
              columns={"xs": s[:, 0], "ys": s[:, 1], "zs": s[:, 2]})
    path = tmp_path / "scaled.dump"
    write_dump(path, g, columns="id type xs ys zs radius")
    frame = read_dump(path)[0]
    (data,) = ovito_frames(path)
    atol = 4 * EPS * float(np.abs(f.box.matrix).sum(axis=1).max() + np.abs(f.box.lo).max())
    assert_same(frame, data, ulps=OVITO_ULPS, pos_atol=atol)  # ulps: radii (17 digits)
    assert_box(frame, data, ulps=0 if tilt is None else 4)


def test_written_unwrapped_with_image_flags(tmp_path):
    """``xu yu zu`` plus ``ix iy iz``: both take the unwrapped coordinates as positions.
    OVITO keeps the dump's image flags; bedstruct sets images to 0 (the flags are already in
    ``xu``) unless ``wrap=True``, which wraps into the box and gives back the same points."""
    (f,) = random_frames(frames=1, boundary="pp pp ff", seed=4)
    unw = f.unwrapped_positions()
    g = Frame(f.positions, f.radii, box=f.box, timestep=f.timestep, ids=f.ids, types=f.types,
              images=f.images, columns={"xu": unw[:, 0], "yu": unw[:, 1], "zu": unw[:, 2]})
    path = tmp_path / "unwrapped.dump"
    write_dump(path, g, columns="id type xu yu zu ix iy iz radius")
    (data,) = ovito_frames(path)
    frame = read_dump(path)[0]
    order = assert_same(frame, data, ulps=OVITO_ULPS, check_images=False)
    np.testing.assert_array_equal(frame.positions, unw[np.argsort(f.ids)])  # as written
    np.testing.assert_array_equal(frame.images, 0)
    np.testing.assert_array_equal(prop(data, "Periodic Image")[order], f.images[np.argsort(f.ids)])
    wrapped = read_dump(path, wrap=True)[0]
    assert f.box.contains(wrapped.positions).all()
    scale = float(np.abs(unw).max())
    np.testing.assert_allclose(wrapped.unwrapped_positions(), prop(data, "Position")[order],
                               rtol=0, atol=8 * EPS * scale)


@pytest.mark.parametrize("revision", [1, 2])
def test_written_binary(tmp_path, revision):
    """LAMMPS binary dumps: revision 2 names its columns, revision 1 does not (both readers
    are then told the columns). The second snapshot is triclinic."""
    rng = np.random.default_rng(10 + revision)
    names = ["id", "type", "x", "y", "z", "vx", "vy", "vz", "radius"]
    ovito_names = ["Particle Identifier", "Particle Type", "Position.X", "Position.Y",
                   "Position.Z", "Velocity.X", "Velocity.Y", "Velocity.Z", "Radius"]
    snaps = []
    for step, tilt in ((100, None), (200, (0.5, 0.0, -0.25))):
        n = 40
        data = np.column_stack([rng.permutation(n) + 1, rng.integers(1, 3, n),
                                rng.uniform([-1, 0, 0], [2, 1, 3], (n, 3)),
                                rng.normal(size=(n, 3)), rng.uniform(0.01, 0.05, n)])
        snaps.append(dict(timestep=step, bounds=np.array([[-1.0, 2.0], [0.0, 1.0], [0.0, 3.0]]),
                          tilt=tilt, boundary=("pp", "fs", "pp"), names=names, data=data))
    path = tmp_path / f"rev{revision}.bin"
    write_binary_dump(path, snaps, revision=revision)
    traj = read_dump(path, **({"columns": names} if revision == 1 else {}))
    frames = ovito_frames(path, **({"columns": ovito_names} if revision == 1 else {}))
    assert len(traj) == len(frames) == 2
    for frame, data, snap in zip(traj, frames, snaps):
        assert_same(frame, data)  # binary: the same doubles, bit for bit
        assert_box(frame, data, ulps=0 if snap["tilt"] is None else 4)
        ref = snap["data"][np.argsort(snap["data"][:, 0])]
        np.testing.assert_array_equal(frame.positions, ref[:, 2:5])
