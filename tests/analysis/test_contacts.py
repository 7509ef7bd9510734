"""Contact detection: brute-force reference, lattices, invariances, walls, dumped contacts."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from bedstruct import Box, Contacts, Frame
from bedstruct.analysis import Wall, compare_contacts, coordination, find_contacts
from lattices import cubic_lattice, fcc_lattice




FLAG_SETS = list(itertools.product(["pp", "ff"], repeat=3))


def brute_force(frame, tol, max_image=3):
    """O(N^2) reference over explicit image shifts: sorted (i, j, branch) rows."""
    box = frame.box
    pos = box.wrap(frame.positions)
    r = frame.radii
    n = len(pos)
    ii, jj = np.triu_indices(n, k=0)
    rows = []
    ranges = [range(-max_image, max_image + 1) if p else range(1) for p in box.periodic]
    for s in itertools.product(*ranges):
        d = pos[jj] + box.matrix @ np.array(s, float) - pos[ii]
        cut = r[ii] + r[jj] + tol
        ok = np.einsum("ij,ij->i", d, d) <= cut * cut
        positive = next((v > 0 for v in s if v != 0), False)
        if not positive:
            ok &= ii != jj
        rows += [(a, b, *np.round(v, 9)) for a, b, v in zip(ii[ok], jj[ok], d[ok])]
    return sorted(rows)


def rows(c):
    return sorted((a, b, *np.round(v, 9)) for a, b, v in zip(c.i, c.j, c.branch))


def random_frame(box, n, rng, rmin=0.2, rmax=0.9, spill=0.3):
    s = rng.uniform(0, 1, (n, 3))
    pos = box.cartesian(s)
    fixed = ~np.array(box.periodic)
    pos[:, fixed] += rng.normal(0, spill, (n, fixed.sum()))   # fixed axes: some outside the box
    return Frame(pos, rng.uniform(rmin, rmax, n), box=box)


@pytest.mark.parametrize("flags", FLAG_SETS, ids=[" ".join(f) for f in FLAG_SETS])
@pytest.mark.parametrize("tilt", [(0, 0, 0), (1.0, -0.7, 0.5)], ids=["ortho", "triclinic"])
def test_matches_brute_force(flags, tilt):
    rng = np.random.default_rng([FLAG_SETS.index(flags), int(tilt[0] != 0)])
    box = Box([0, -1, 2], [6, 4, 7], tilt=tilt, boundary=flags)
    frame = random_frame(box, 150, rng)
    c = find_contacts(frame, tolerance=0.05)
    assert rows(c) == brute_force(frame, 0.05)
    assert c.n_contacts > 100
    # periodic flag: only pairs found through an image
    assert not c.periodic.any() if flags == ("ff",) * 3 else c.periodic.any()


@pytest.mark.parametrize("length", [0.9, 1.7, 2.5, 3.3])
def test_boxes_narrower_than_three_cells(length):
    """Widths below 3 cutoffs (and below 1 cutoff) still give every image contact."""
    rng = np.random.default_rng(3)
    box = Box([0, 0, 0], [length, 1.2 * length, 4], tilt=[0.3, 0, 0], boundary="pp pp ff")
    frame = random_frame(box, 12, rng)
    c = find_contacts(frame)
    assert rows(c) == brute_force(frame, 0.0, max_image=5)


def test_flat_box_and_particles_outside_fixed_box():
    """A box of zero height (2-D data) and spheres far outside a fixed box."""
    rng = np.random.default_rng(8)
    flat = Box([0, 0, 0], [8, 8, 0], boundary="pp pp ff")
    f = Frame(np.c_[rng.uniform(0, 8, (200, 2)), np.zeros(200)], rng.uniform(0.2, 0.5, 200), box=flat)
    assert rows(find_contacts(f)) == brute_force(f, 0.0)
    tiny = Box([0, 0, 0], [1, 1, 1], boundary="ff ff ff")
    g = Frame(rng.uniform(-5, 5, (200, 3)), rng.uniform(0.2, 0.8, 200), box=tiny)
    assert rows(find_contacts(g)) == brute_force(g, 0.0)


def test_serial_equals_parallel(random_bed):
    a = find_contacts(random_bed, parallel=False)
    b = find_contacts(random_bed)
    assert rows(a) == rows(b)


@pytest.mark.parametrize("n", [(1, 1, 1), (2, 2, 2), (4, 3, 5)])
@pytest.mark.parametrize("flags", ["pp pp pp", "pp ff pp", "ff ff ff"])
def test_lattices(n, flags):
    sc = cubic_lattice(n, boundary=flags.split())
    fcc = fcc_lattice(n, boundary=flags.split())
    csc = find_contacts(sc)
    cfcc = find_contacts(fcc, tolerance=1e-9)
    if flags == "pp pp pp":
        assert np.all(csc.per_particle_count() == 6)
        assert np.all(cfcc.per_particle_count() == 12)
    else:
        # surfaces lose contacts; the interior keeps the bulk value
        assert csc.per_particle_count().max() <= 6 and cfcc.per_particle_count().max() <= 12
    assert np.allclose(csc.distance, 1.0) and np.allclose(cfcc.distance, 2 * fcc.radii[0])
    assert np.allclose(np.linalg.norm(cfcc.normals, axis=1), 1.0)
    assert np.allclose(csc.overlap, 0.0, atol=1e-12)


def test_sc_open_box_counts():
    """4x4x4 simple cubic with fixed walls: 3 * 4 * 4 * 3 = 144 bonds."""
    c = find_contacts(cubic_lattice((4, 4, 4), boundary=("ff",) * 3))
    assert c.n_contacts == 144


def test_rotation_and_translation_invariance():
    rng = np.random.default_rng(11)
    box = Box([-20, -20, -20], [20, 20, 20], boundary="ff ff ff")
    pos = rng.uniform(-4, 4, (300, 3))
    r = rng.uniform(0.3, 0.7, 300)
    base = find_contacts(Frame(pos, r, box=box))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rot = find_contacts(Frame(pos @ q.T + [1.3, -2.1, 0.7], r, box=box))
    assert np.array_equal(base.i, rot.i) and np.array_equal(base.j, rot.j)
    np.testing.assert_allclose(rot.overlap, base.overlap, atol=1e-12)
    np.testing.assert_allclose(rot.normals, base.normals @ q.T, atol=1e-12)
    # periodic translation: same pairs and overlaps after shifting everything
    pbox = Box([0, 0, 0], [9, 9, 9])
    f = Frame(rng.uniform(0, 9, (300, 3)), r, box=pbox)
    g = Frame(pbox.wrap(f.positions + [4.4, -7.3, 2.2]), r, box=pbox)
    a, b = find_contacts(f), find_contacts(g)
    assert np.array_equal(a.i, b.i) and np.array_equal(a.j, b.j)
    np.testing.assert_allclose(a.branch, b.branch, atol=1e-12)


def test_lens_area_and_fields():
    f = Frame([[0, 0, 0], [1.5, 0, 0], [5, 5, 5]], [1.0, 1.0, 0.5], box=([-3] * 3, [8] * 3),
              ids=[10, 20, 30])
    c = find_contacts(f)
    assert c.n_contacts == 1 and c.ids_i.tolist() == [10] and c.ids_j.tolist() == [20]
    a = math.sqrt(1 - 0.75 ** 2)
    np.testing.assert_allclose(c.contact_radius, [a])
    np.testing.assert_allclose(c.area, [math.pi * a * a])
    np.testing.assert_allclose(c.contact_area, c.lens_area)
    assert c.source == "geometric" and c.n_particles == 3


def test_walls():
    rng = np.random.default_rng(5)
    box = Box([0, 0, 0], [5, 5, 5], boundary="pp pp ff")
    f = Frame(rng.uniform(0, 5, (200, 3)), rng.uniform(0.1, 0.4, 200), box=box)
    c = find_contacts(f, walls=["zlo", Wall.plate(2.5), ([0, 0, 5], [0, 0, -1])])
    w = c.walls
    for k, (z0, sign) in enumerate([(0.0, 1), (2.5, 1), (5.0, -1)]):
        dist = sign * (f.positions[:, 2] - z0)
        expect = np.flatnonzero(dist <= f.radii)
        assert np.array_equal(np.sort(w.particle[w.wall == k]), expect)
        np.testing.assert_allclose(w.overlap[w.wall == k], f.radii[expect] - dist[expect])
        np.testing.assert_allclose(w.normals[w.wall == k], [[0, 0, -sign]] * expect.size)
    # wall contacts stay apart from pairs
    assert rows(c) == rows(find_contacts(f))
    cn = coordination(f, c, include_walls=True, min_contacts=0)
    assert cn.per_particle.sum() == 2 * c.n_contacts + w.n_contacts


def test_triclinic_face_wall():
    box = Box([0, 0, 0], [4, 4, 4], tilt=[0, 2.0, 0], boundary="ff pp pp")
    # the xlo face is tilted: x = 0.5 z; a sphere at z = 2 touches it at x = 1 + r
    f = Frame([[1.4, 1, 2], [3, 1, 2]], [0.45, 0.45], box=box)
    w = find_contacts(f, walls=["xlo"]).walls
    assert w.particle.tolist() == [0]
    np.testing.assert_allclose(w.overlap, [0.45 - 0.4 / math.sqrt(1.25)])


def test_errors_and_empty():
    f = Frame(np.zeros((0, 3)), np.zeros(0), box=[1, 1, 1])
    c = find_contacts(f, walls=["zlo"])
    assert c.n_contacts == 0 and c.walls.n_contacts == 0
    g = Frame([[0, 0, 0]], [1.0], box=[4, 4, 4])
    with pytest.raises(ValueError, match="tolerance"):
        find_contacts(g, tolerance=float("nan"))
    with pytest.raises(ValueError, match="cutoff"):
        find_contacts(g, tolerance=-3.0)
    with pytest.raises(ValueError, match="wall names"):
        find_contacts(g, walls=["bottom"])
    with pytest.raises(TypeError, match="wall"):
        find_contacts(g, walls=[3.0])


# ----------------------------------------------------------- dumped contacts
def relaxed_bed(n=700, seed=2):
    """A dense random polydisperse bed in a pp pp ff box, relaxed by overlap removal."""
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(seed)
    L = np.array([12.0, 12.0, 30.0])
    r = rng.uniform(0.35, 0.75, n)
    pos = rng.uniform([0, 0, 0], [L[0], L[1], 9.0], (n, 3))
    big = np.array([L[0], L[1], 1e6])            # z effectively non-periodic
    for _ in range(60):
        pos[:, 2] = np.maximum(pos[:, 2] - 0.02, r)  # settle on the plate z = 0
        pos[:, :2] %= L[:2]
        tree = cKDTree(pos + [0, 0, 1e5], boxsize=big)
        pairs = tree.query_pairs(2 * r.max(), output_type="ndarray")
        d = pos[pairs[:, 1]] - pos[pairs[:, 0]]
        d[:, :2] -= L[:2] * np.round(d[:, :2] / L[:2])
        dist = np.linalg.norm(d, axis=1)
        ov = r[pairs[:, 0]] + r[pairs[:, 1]] - dist
        hit = ov > 0.01 * (r[pairs[:, 0]] + r[pairs[:, 1]])   # leave DEM-like small overlaps
        push = 0.5 * (ov[hit] - 0.005)[:, None] * d[hit] / dist[hit, None]
        np.add.at(pos, pairs[hit, 0], -push)
        np.add.at(pos, pairs[hit, 1], push)
        pos[:, 2] = np.maximum(pos[:, 2], r)
    pos[:, :2] %= L[:2]
    box = Box([0, 0, 0], L, boundary="pp pp ff")
    return Frame(pos, r, box=box, ids=rng.permutation(n) + 1, timestep=5000)


def write_liggghts_local(path, frame):
    """A LIGGGHTS compute pair/gran/local file (pos id periodic), built with scipy."""
    from scipy.spatial import cKDTree
    L = frame.box.lengths
    pos = frame.positions
    tree = cKDTree(pos + [0, 0, 1e5], boxsize=[L[0], L[1], 1e6])
    pairs = tree.query_pairs(2 * frame.radii.max(), output_type="ndarray")
    d = pos[pairs[:, 1]] - pos[pairs[:, 0]]
    img = np.zeros_like(d)
    img[:, :2] = -L[:2] * np.round(d[:, :2] / L[:2])
    d += img
    touch = np.linalg.norm(d, axis=1) < frame.radii[pairs[:, 0]] + frame.radii[pairs[:, 1]]
    pairs, img = pairs[touch], img[touch]
    lines = ["ITEM: TIMESTEP", str(frame.timestep), "ITEM: NUMBER OF ENTRIES", str(len(pairs)),
             "ITEM: BOX BOUNDS pp pp ff"]
    lines += [f"{lo:.16e} {hi:.16e}" for lo, hi in zip(frame.box.lo, frame.box.hi)]
    lines.append("ITEM: ENTRIES c_pgl[1] c_pgl[2] c_pgl[3] c_pgl[4] c_pgl[5] c_pgl[6] "
                 "c_pgl[7] c_pgl[8] c_pgl[9] ")
    for (a, b), sh in zip(pairs, img):
        x1, x2 = pos[a], pos[b] + sh          # LIGGGHTS writes the ghost (image) position
        per = int(np.any(sh != 0))
        lines.append(" ".join(f"{v:g}" for v in (*x1, *x2)) + f" {frame.ids[a]} {frame.ids[b]} {per} ")
    path.write_text("\n".join(lines) + "\n")
    return len(pairs)


def parse_local(path, frame):
    """Parse the file above into Contacts by hand (cross-check of the io reader)."""
    text = path.read_text().splitlines()
    k = next(i for i, ln in enumerate(text) if ln.startswith("ITEM: ENTRIES"))
    data = np.loadtxt(text[k + 1:], ndmin=2)
    ids1, ids2 = data[:, 6].astype(np.int64), data[:, 7].astype(np.int64)
    row = np.empty(frame.ids.max() + 1, dtype=np.int64)
    row[frame.ids] = np.arange(frame.n_particles)
    i, j = row[ids1], row[ids2]
    return Contacts(i=i, j=j, branch=data[:, 3:6] - data[:, 0:3], radii_i=frame.radii[i],
                    radii_j=frame.radii[j], ids_i=ids1, ids_j=ids2, periodic=data[:, 8] > 0,
                    n_particles=frame.n_particles, source=str(path))


@pytest.mark.slow   # the default run's cross-check is test_liggghts_written_bed_agrees
def test_geometric_agrees_with_dumped_contacts(tmp_path):
    from bedstruct import read_dump_local
    frame = relaxed_bed()
    path = tmp_path / "contacts.local"
    m = write_liggghts_local(path, frame)
    dumped = read_dump_local(path, keywords=["pos", "id"], frames=frame)[frame.timestep]
    by_hand = parse_local(path, frame)
    assert compare_contacts(dumped, by_hand).identical
    assert m > 1000 and dumped.periodic.any() and dumped.n_contacts == m
    # strict '<' in the file: use the touching subset of the geometric contacts
    geo = find_contacts(frame).touching()
    match = compare_contacts(geo, dumped)
    assert match.identical, (match.only_a[:5], match.only_b[:5])
    assert match.n_common == m
    assert match.max_normal_difference < 1e-4           # positions written with %g
    # the same analyses accept either source
    a = coordination(frame, geo)
    b = coordination(frame, dumped)
    assert np.array_equal(a.per_particle, b.per_particle)
    assert a.mean == pytest.approx(b.mean) and 3.0 < a.mean < 8.0
    assert np.allclose(np.sort(geo.overlap), np.sort(dumped.overlap), atol=1e-4)
    # periodic flags agree pair by pair
    key = lambda c: dict(zip(zip(np.minimum(c.ids_i, c.ids_j).tolist(),
                                 np.maximum(c.ids_i, c.ids_j).tolist()), c.periodic.tolist()))
    assert key(geo) == key(dumped)


def test_real_liggghts_frame(realdata):
    """A bed written by LIGGGHTS (1800 spheres settling in a shrink-wrapped box)."""
    from bedstruct import read_dump
    path = realdata / "CFDEMproject+LIGGGHTS-PUBLIC" / "contactModels_v3.2.0" / "dump20000.newModels"
    frame = read_dump(path)[-1]
    c = find_contacts(frame)
    assert rows(c) == brute_force(frame, 0.0)
    assert c.n_contacts > 0 and not c.periodic.any()
    assert np.all(c.overlap < 0.2 * frame.radii.max())   # DEM overlaps are small
    res = coordination(frame, c)
    assert res.mean == pytest.approx(2 * c.n_contacts / frame.n_particles)


from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=25, deadline=None)
@given(st.lists(st.sampled_from(["pp", "ff"]), min_size=3, max_size=3),
       st.lists(st.floats(-0.45, 0.45), min_size=3, max_size=3),
       st.lists(st.floats(1.0, 6.0), min_size=3, max_size=3),
       st.integers(1, 60), st.integers(0, 2**31 - 1), st.floats(0.0, 0.3))
def test_random_boxes_match_brute_force(flags, tilt_frac, lengths, n, seed, tol):
    """Random orthogonal/triclinic boxes (LAMMPS tilt limits), sizes and tolerances."""
    lx, ly, lz = lengths
    tilt = [tilt_frac[0] * lx, tilt_frac[1] * lx, tilt_frac[2] * ly]
    box = Box([0, 0, 0], lengths, tilt=tilt, boundary=flags)
    rng = np.random.default_rng(seed)
    frame = random_frame(box, n, rng, rmin=0.1, rmax=0.7)
    assert rows(find_contacts(frame, tolerance=tol)) == brute_force(frame, tol, max_image=8)


@pytest.mark.parametrize("n", [20_000, pytest.param(400_000, marks=pytest.mark.slow)])
def test_against_scipy_kdtree_at_scale(n):
    """An independent neighbour search (scipy cKDTree, periodic x and y) on a larger bed."""
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(n)
    L = np.array([40.0, 30.0, 1e3]) * (n / 20_000) ** (1 / 3)
    box = Box([0, 0, 0], [L[0], L[1], 12.0], boundary="pp pp ff")
    pos = rng.uniform([0, 0, 0], [L[0], L[1], 12.0], (n, 3))
    r = rng.uniform(0.25, 0.6, n)
    c = find_contacts(Frame(pos, r, box=box))
    tree = cKDTree(pos + [0, 0, L[2] / 4], boxsize=[L[0], L[1], L[2]])
    pairs = tree.query_pairs(2 * r.max(), output_type="ndarray")
    d = pos[pairs[:, 1]] - pos[pairs[:, 0]]
    d[:, :2] -= L[:2] * np.round(d[:, :2] / L[:2])
    ok = np.einsum("ij,ij->i", d, d) <= (r[pairs[:, 0]] + r[pairs[:, 1]]) ** 2
    ref = np.sort(pairs[ok, 0] * n + pairs[ok, 1])
    got = np.sort(np.minimum(c.i, c.j) * n + np.maximum(c.i, c.j))
    assert got.size > n and np.array_equal(got, ref)


def test_many_partners_overflow_path():
    """A big sphere touched by hundreds of small ones (more than the per-row buffer)."""
    rng = np.random.default_rng(12)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    pos = np.vstack([[10.0, 10.0, 10.0], 10.0 + u * 5.25])
    r = np.r_[5.0, rng.uniform(0.2, 0.35, 400)]
    f = Frame(pos, r, box=Box([0, 0, 0], [20, 20, 20], boundary="pp pp ff"))
    c = find_contacts(f)
    assert rows(c) == brute_force(f, 0.0)
    assert c.per_particle_count()[0] > 100


def test_liggghts_written_bed_agrees(tmp_path):
    """LIGGGHTS itself writes the bed and its pair/gran/local contacts; find_contacts agrees.

    The relaxed bed (scaled to 14-30 um radii, SI) is run for 10 tiny steps by
    LIGGGHTS 3.8, which dumps atoms and ``compute pair/gran/local pos id force
    contactArea delta`` at full precision; both are read back with bedstruct's
    readers.
    """
    from bedstruct import read_dump, read_dump_local
    from bedstruct.engines import bed_deck, find_liggghts, run_deck, write_sphere_data
    if find_liggghts() is None:
        pytest.skip("LIGGGHTS is not installed (run .ci/install-engines.sh)")
    bed = relaxed_bed(n=500, seed=4)
    scale = 4e-5
    data = write_sphere_data(tmp_path / "bed.data", bed.positions * scale, bed.radii * scale,
                             box_lo=bed.box.lo * scale, box_hi=bed.box.hi * scale, n_types=2)
    deck = bed_deck(data, engine="liggghts", steps=10, dt=1e-9, dump="bed.dump", dump_every=10,
                    contacts="contacts.dump", contacts_every=10)
    fmt_atoms = " ".join(["%d", "%d"] + ["%.17g"] * 13)
    fmt_local = " ".join(["%.17g"] * 14)                # LIGGGHTS stores local ids as doubles
    deck = deck.replace("run 10\n", f'dump_modify dmp format "{fmt_atoms}"\n'
                                    f'dump_modify dloc format "{fmt_local}"\nrun 10\n')
    (tmp_path / "bed.in").write_text(deck)
    run_deck(tmp_path / "bed.in", cwd=tmp_path)
    traj = read_dump(tmp_path / "bed.dump")
    frame = traj[-1]
    dumped = read_dump_local(tmp_path / "contacts.dump", frames=list(traj),
                             keywords=["pos", "id", "force", "contactArea", "delta"])[frame.timestep]
    geo = find_contacts(frame)
    assert frame.n_particles == 500 and dumped.n_contacts > 500 and dumped.periodic.any()
    match = compare_contacts(geo, dumped)
    assert match.identical, (match.only_a[:5], match.only_b[:5])
    assert match.max_normal_difference < 1e-12

    def by_pair(c):
        return np.argsort(np.minimum(c.ids_i, c.ids_j) * 10**6 + np.maximum(c.ids_i, c.ids_j))
    g, d = by_pair(geo), by_pair(dumped)
    # LIGGGHTS' overlap and contact area are the geometric overlap and lens area
    np.testing.assert_allclose(geo.overlap[g], dumped.columns["delta"][d], atol=1e-12 * scale)
    np.testing.assert_allclose(geo.area[g], dumped.area[d], rtol=1e-9)
    np.testing.assert_array_equal(geo.periodic[g], dumped.periodic[d])
    a, b = coordination(frame, geo, min_contacts=2), coordination(frame, dumped, min_contacts=2)
    assert np.array_equal(a.per_particle, b.per_particle) and np.array_equal(a.rattlers, b.rattlers)
    assert a.mechanical == b.mechanical and a.n_rattlers < frame.n_particles
