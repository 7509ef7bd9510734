"""Fabric tensors: brute-force references, Kanatani identities, sampling, invariances."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import bedstruct
from bedstruct import Box, Contacts, Frame
from bedstruct.analysis import _fabric_kernels as K
from bedstruct.analysis.fabric import (
    contact_regions, deviatoric_rank4, fabric_density, fabric_table, fabric_tensors,
    isotropic_rank4, lammps_fabric, lammps_voigt, projected_density, region_fabric,
    sample_directions, sym_delta_tensor,
)
from bedstruct.analysis.harmonics import _sphere_quadrature

from _directions import random_rotation, unit

DELTA = np.eye(3)


def icosahedron():
    """The 12 vertices of an icosahedron: a spherical 5-design (moments up to 5 are isotropic)."""
    g = (1 + 5 ** 0.5) / 2
    v = []
    for a, b in itertools.product((-1, 1), repeat=2):
        v += [(0, a, b * g), (a, b * g, 0), (b * g, 0, a)]
    return unit(v)


def brute_moments(n, w=None):
    u = unit(n)
    w = np.ones(len(u)) if w is None else np.asarray(w, float)
    n2 = np.einsum("a,ai,aj->ij", w, u, u) / w.sum()
    n4 = np.einsum("a,ai,aj,ak,al->ijkl", w, u, u, u, u) / w.sum()
    return n2, n4


def sym_brute(a2, b2):
    """(1/24) sum over all permutations of the four indices of a_ij b_kl."""
    t = np.einsum("ij,kl->ijkl", a2, b2)
    return sum(np.transpose(t, p) for p in itertools.permutations(range(4))) / 24.0


# --------------------------------------------------------------------------- kernels
def test_moments_match_brute_force_weighted_and_unnormalised():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(3000, 3)) * rng.uniform(0.1, 5, size=(3000, 1))
    w = rng.random(3000)
    t = fabric_tensors(x, w)
    n2, n4 = brute_moments(x, w)
    np.testing.assert_allclose(t.N2, n2, atol=1e-14)
    np.testing.assert_allclose(t.N4, n4, atol=1e-14)
    assert t.n_contacts == 3000 and t.total_weight == pytest.approx(w.sum())


def test_moment_kernel_py_func_matches_compiled():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(50, 3))
    w = rng.random(50)
    a = np.zeros((3, K.N_MOMENT_COLUMNS))
    b = np.zeros((3, K.N_MOMENT_COLUMNS))
    K.moment_sums(x, w, True, 3, a)
    K.moment_sums.py_func(x, w, True, 3, b)
    np.testing.assert_allclose(a, b, rtol=1e-13)


def test_zero_rows_are_skipped_and_all_zero_raises():
    x = np.array([[1.0, 0, 0], [0, 0, 0], [0, 2.0, 0]])
    t = fabric_tensors(x)
    assert t.n_contacts == 2
    np.testing.assert_allclose(t.N2, np.diag([0.5, 0.5, 0]), atol=1e-15)
    with pytest.raises(ValueError, match="no usable direction"):
        fabric_tensors(np.zeros((3, 3)))


@pytest.mark.parametrize("bad, match", [
    (np.zeros((4, 2)), "shape"),
])
def test_bad_shapes(bad, match):
    with pytest.raises(ValueError, match=match):
        fabric_tensors(bad)


def test_bad_weights():
    x = np.eye(3)
    with pytest.raises(ValueError, match="non-negative"):
        fabric_tensors(x, [1, -1, 1])
    with pytest.raises(ValueError, match=r"shape \(M,\)"):
        fabric_tensors(x, [1, 1])
    with pytest.raises(ValueError, match="sum to zero"):
        fabric_tensors(x, [0, 0, 0])
    with pytest.raises(ValueError, match="finite"):
        fabric_tensors(x, [1, np.nan, 1])
    with pytest.raises(TypeError, match="Contacts"):
        fabric_tensors(x, "force_normal")


# --------------------------------------------------------------------------- Kanatani algebra
def test_symmetrisations_equal_full_permutation_average():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(3, 3))
    a = a + a.T
    np.testing.assert_allclose(sym_delta_tensor(a), sym_brute(DELTA, a), atol=1e-14)
    np.testing.assert_allclose(isotropic_rank4(), sym_brute(DELTA, DELTA), atol=1e-15)


def test_third_kind_is_traceless_and_seed_unsymmetrised_form_is_not():
    rng = np.random.default_rng(4)
    t = fabric_tensors(rng.normal(size=(500, 3)) * [3, 1, 0.5])
    assert abs(np.trace(t.D2)) < 1e-13
    for pair in itertools.combinations(range(4), 2):
        tr = np.trace(t.D4, axis1=pair[0], axis2=pair[1])
        assert np.abs(tr).max() < 1e-12, pair
    # the seed's printed form, delta_ij N_kl without symmetrisation, is not traceless
    seed = 315 / 8 * (t.N4 - 6 / 7 * np.einsum("ij,kl->ijkl", DELTA, t.N2)
                      + 3 / 35 * np.einsum("ij,kl->ijkl", DELTA, DELTA))
    assert np.abs(np.einsum("ikkl->il", seed)).max() > 0.1
    # full symmetry of every rank-4 tensor
    for p in itertools.permutations(range(4)):
        np.testing.assert_allclose(np.transpose(t.D4, p), t.D4, atol=1e-13)
        np.testing.assert_allclose(np.transpose(t.F4, p), t.F4, atol=1e-13)
    np.testing.assert_allclose(t.D4, 315 / 8 * deviatoric_rank4(t.N4), atol=1e-12)


def test_isotropic_design_gives_identity_like_F_and_zero_D():
    t = fabric_tensors(icosahedron())   # exact isotropic moments up to rank 5
    np.testing.assert_allclose(t.N2, DELTA / 3, atol=1e-15)
    np.testing.assert_allclose(t.N4, isotropic_rank4() / 5, atol=1e-15)
    np.testing.assert_allclose(t.F2, DELTA, atol=1e-14)
    np.testing.assert_allclose(t.F4, isotropic_rank4(), atol=1e-13)
    np.testing.assert_allclose(t.D2, 0, atol=1e-14)
    np.testing.assert_allclose(t.D4, 0, atol=1e-13)
    assert t.anisotropy < 1e-13 and t.anisotropy_rank4 < 1e-12


def test_second_kind_reproduces_density_on_the_sphere():
    """F_ij n n / 4pi = f2 and F_ijkl nnnn / 4pi = f4 exactly (Kanatani 1984, second kind)."""
    rng = np.random.default_rng(5)
    t = fabric_tensors(rng.normal(size=(400, 3)) * [2, 1, 1])
    d = unit(rng.normal(size=(200, 3)))
    f2 = np.einsum("ni,nj,ij->n", d, d, t.F2) / (4 * np.pi)
    f4 = np.einsum("ni,nj,nk,nl,ijkl->n", d, d, d, d, t.F4) / (4 * np.pi)
    np.testing.assert_allclose(fabric_density(t, d, rank=2), f2, atol=1e-14)
    np.testing.assert_allclose(fabric_density(t, d, rank=4), f4, atol=1e-13)
    np.testing.assert_allclose(fabric_density(t, d, rank="difference"),
                               fabric_density(t, d, rank=4) - fabric_density(t, d, rank=2), atol=1e-14)


def test_density_integrates_to_one_and_is_the_L2_projection():
    """For data x, the approximation f4 matches every sample moment of degree <= 4."""
    rng = np.random.default_rng(6)
    x = unit(rng.normal(size=(300, 3)) * [3, 1, 0.3])
    w = rng.random(300)
    t = fabric_tensors(x, w)
    q, qw = _sphere_quadrature(12)
    f4 = fabric_density(t, q, rank=4)
    f2 = fabric_density(t, q, rank=2)
    assert np.sum(qw * f4) == pytest.approx(1.0, abs=1e-13)
    assert np.sum(qw * f2) == pytest.approx(1.0, abs=1e-13)
    assert np.sum(qw * fabric_density(t, q, rank="difference")) == pytest.approx(0.0, abs=1e-13)
    b = rng.normal(size=(3, 3, 3, 3))
    c = rng.normal(size=(3, 3))

    def p(n):   # an arbitrary even polynomial of degree 4
        return (np.einsum("ni,nj,nk,nl,ijkl->n", n, n, n, n, b)
                + np.einsum("ni,nj,ij->n", n, n, c) + 0.7)
    sample_mean = np.sum(w * p(x)) / w.sum()
    assert np.sum(qw * f4 * p(q)) == pytest.approx(sample_mean, abs=1e-12)

    def p2(n):
        return np.einsum("ni,nj,ij->n", n, n, c) + 0.7
    assert np.sum(qw * f2 * p2(q)) == pytest.approx(np.sum(w * p2(x)) / w.sum(), abs=1e-12)


def test_projected_density_normalised_and_matches_histogram():
    rng = np.random.default_rng(7)
    d2 = np.diag([2.0, -1.0, -1.0]) * 0.8
    x = sample_directions(40_000, D2=d2, rng=rng)
    t = fabric_tensors(x)
    a = np.linspace(0, 2 * np.pi, 2001)
    for plane, (u, v) in {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}.items():
        p = projected_density(t, a, plane=plane)
        assert np.trapezoid(p, a) == pytest.approx(1.0, abs=1e-10)
        ang = np.concatenate([np.arctan2(x[:, v], x[:, u]), np.arctan2(-x[:, v], -x[:, u])]) % (2 * np.pi)
        hist, edges = np.histogram(ang, bins=24, range=(0, 2 * np.pi), density=True)
        centres = 0.5 * (edges[1:] + edges[:-1])
        expect = projected_density(t, centres, plane=plane)
        assert np.abs(hist - expect).max() < 0.1 * expect.max()


# --------------------------------------------------------------------------- sampling from known f
def _d_samples(x):
    """Per-sample contributions whose mean is D2 and D4 (so the standard error is exact)."""
    u = unit(x)
    d2 = 7.5 * (np.einsum("ai,aj->aij", u, u) - DELTA / 3)
    n4 = np.einsum("ai,aj,ak,al->aijkl", u, u, u, u)
    n2 = np.einsum("ai,aj->aij", u, u)
    s = (np.einsum("ij,akl->aijkl", DELTA, n2) + np.einsum("ik,ajl->aijkl", DELTA, n2)
         + np.einsum("il,ajk->aijkl", DELTA, n2) + np.einsum("jk,ail->aijkl", DELTA, n2)
         + np.einsum("jl,aik->aijkl", DELTA, n2) + np.einsum("kl,aij->aijkl", DELTA, n2)) / 6
    d4 = 315 / 8 * (n4 - 6 / 7 * s + 3 / 35 * isotropic_rank4())
    return d2, d4


def _cubic_d4(c):
    e = np.zeros((3, 3, 3, 3))
    for a in range(3):
        e[a, a, a, a] = 1.0
    return c * deviatoric_rank4(e)


@pytest.mark.parametrize("name, D2, D4", [
    ("isotropic", np.zeros((3, 3)), np.zeros((3, 3, 3, 3))),
    ("transversely isotropic", np.diag([2.0, -1.0, -1.0]) * 2.5 / 3, np.zeros((3, 3, 3, 3))),
    ("rank-4 cubic", np.zeros((3, 3)), _cubic_d4(2.0)),
    ("rank 2 + 4", np.diag([-0.3, -0.3, 0.6]), _cubic_d4(1.0)),
])
def test_samples_from_known_density_recover_D_within_sampling_error(name, D2, D4):
    x = sample_directions(40_000, D2=D2, D4=D4, rng=11)
    t = fabric_tensors(x)
    d2s, d4s = _d_samples(x)
    np.testing.assert_allclose(d2s.mean(0), t.D2, atol=1e-12)
    np.testing.assert_allclose(d4s.mean(0), t.D4, atol=1e-10)
    se2 = d2s.std(0) / np.sqrt(len(x)) + 1e-12
    se4 = d4s.std(0) / np.sqrt(len(x)) + 1e-12
    assert np.max(np.abs(t.D2 - D2) / se2) < 5, name
    assert np.max(np.abs(t.D4 - D4) / se4) < 5, name


def test_sample_directions_rejects_non_distributions():
    with pytest.raises(ValueError, match="negative"):
        sample_directions(10, D2=np.diag([4.0, -2.0, -2.0]), rng=0)
    with pytest.raises(ValueError, match="traceless"):
        sample_directions(10, D2=np.eye(3), rng=0)


# --------------------------------------------------------------------------- invariances
def test_rotating_the_sample_rotates_the_tensors_exactly():
    rng = np.random.default_rng(12)
    x = sample_directions(2000, D2=np.diag([1.0, -0.2, -0.8]), rng=rng)
    w = rng.random(len(x))
    t = fabric_tensors(x, w)
    for _ in range(3):
        r = random_rotation(rng)
        tr = fabric_tensors(x @ r.T, w)
        rt = t.rotated(r)
        for name in ("N2", "N4", "F2", "F4", "D2", "D4"):
            np.testing.assert_allclose(getattr(tr, name), getattr(rt, name), atol=1e-13, err_msg=name)
        np.testing.assert_allclose(tr.eigenvalues, t.eigenvalues, atol=1e-13)
        assert tr.anisotropy == pytest.approx(t.anisotropy, abs=1e-12)
        assert tr.anisotropy_rank4 == pytest.approx(t.anisotropy_rank4, abs=1e-11)
        # eigenvectors rotate (up to sign)
        dots = np.abs(np.einsum("ik,ik->k", tr.eigenvectors, r @ t.eigenvectors))
        np.testing.assert_allclose(dots, 1.0, atol=1e-9)


def test_antipodal_symmetry_and_uniform_weights():
    rng = np.random.default_rng(13)
    x = rng.normal(size=(500, 3))
    flip = np.where(rng.random(500) < 0.5, -1.0, 1.0)[:, None]
    a, b = fabric_tensors(x), fabric_tensors(x * flip)
    c = fabric_tensors(x, np.full(500, 3.7))
    for name in ("N2", "N4", "D2", "D4"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), atol=1e-14)
        np.testing.assert_allclose(getattr(c, name), getattr(a, name), atol=1e-14)
    # integer weights = repeated rows
    k = rng.integers(1, 4, size=500)
    np.testing.assert_allclose(fabric_tensors(x, k).N4, fabric_tensors(np.repeat(x, k, axis=0)).N4,
                               atol=1e-14)


def test_eigen_decomposition_and_anisotropy_values():
    t = fabric_tensors([[1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    np.testing.assert_allclose(t.eigenvalues, [0.5, 0.25, 0.25])
    np.testing.assert_allclose(np.abs(t.eigenvectors[:, 0]), [1, 0, 0])
    # D = a (3 e e - I)/3 with e = x  => anisotropy a
    a = 7.5 * (0.5 - 1 / 3) * 3 / 2
    assert t.anisotropy == pytest.approx(a)
    assert t.eigenvalues.sum() == pytest.approx(1.0)
    with pytest.raises(AttributeError):
        t.n_contacts = 3      # frozen
    with pytest.raises(ValueError):
        t.N2[0, 0] = 1.0      # read-only arrays


# --------------------------------------------------------------------------- Contacts and weights
def _contacts_with_forces():
    rng = np.random.default_rng(14)
    m = 200
    branch = unit(rng.normal(size=(m, 3))) * rng.uniform(0.9, 1.0, size=(m, 1))
    fn = -branch * rng.uniform(0, 5, size=(m, 1))
    return Contacts(i=np.arange(m), j=np.arange(m) + m, branch=branch, radii_i=np.full(m, 0.5),
                    radii_j=np.full(m, 0.5), force_normal=fn, n_particles=2 * m)


def test_contacts_input_and_named_weights():
    c = _contacts_with_forces()
    t = fabric_tensors(c)
    np.testing.assert_allclose(t.N4, brute_moments(c.normals)[1], atol=1e-14)
    fmag = np.linalg.norm(c.force_normal, axis=1)
    np.testing.assert_allclose(fabric_tensors(c, "force_normal").N2, brute_moments(c.branch, fmag)[0],
                               atol=1e-14)
    np.testing.assert_allclose(fabric_tensors(c, "contact_area").N2,
                               brute_moments(c.branch, c.contact_area)[0], atol=1e-14)
    np.testing.assert_allclose(fabric_tensors(c, "branch_length").N2,
                               brute_moments(c.branch, c.distance)[0], atol=1e-14)
    nof = Contacts(i=[0], j=[1], branch=[[1.0, 0, 0]], radii_i=[0.6], radii_j=[0.6])
    with pytest.raises(ValueError, match="force_normal"):
        fabric_tensors(nof, "force_normal")
    with pytest.raises(ValueError, match="unknown `weights`"):
        fabric_tensors(nof, "mass")
    assert bedstruct.fabric_tensors is fabric_tensors


# --------------------------------------------------------------------------- regions
def _line_frame(boundary="ff ff ff"):
    pos = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [4, 0, 0], [5, 0, 0]])
    f = Frame(pos, [0.5] * 6, box=Box([-0.5, -1, -1], [5.5, 1, 1], boundary=boundary))
    c = Contacts(i=[0, 1, 2, 3, 4], j=[1, 2, 3, 4, 5], branch=[[1.0, 0, 0]] * 4 + [[0.6, 0.8, 0]],
                 radii_i=[0.5] * 5, radii_j=[0.5] * 5, n_particles=6)
    return f, c


def test_contact_regions_midpoint_particle_and_bounds():
    f, c = _line_frame()
    lab, edges = contact_regions(c, f)          # extent 0..5, midpoints 0.5, 1.5, ... 4.3
    np.testing.assert_allclose(edges, np.linspace(0, 5, 4))
    assert lab.tolist() == [0, 0, 1, 2, 2]
    lab, _ = contact_regions(c, f, position="particle")   # x_i = 0..4
    assert lab.tolist() == [0, 0, 1, 1, 2]
    lab, edges = contact_regions(c, f, bounds="box", n_regions=2)
    np.testing.assert_allclose(edges, [-0.5, 2.5, 5.5])
    assert lab.tolist() == [0, 0, 1, 1, 1]      # 2.5 lies on the edge: upper slab
    lab, _ = contact_regions(c, f, bounds=(1.0, 3.0), n_regions=2, axis="x")
    assert lab.tolist() == [-1, 0, 1, -1, -1]
    # unequal radii shift the contact point towards the smaller sphere
    c2 = Contacts(i=[0], j=[1], branch=[[1.0, 0, 0]], radii_i=[0.9], radii_j=[0.1], n_particles=6)
    lab, _ = contact_regions(c2, f, bounds=(0.0, 1.0), n_regions=4)
    assert lab.tolist() == [3]   # point at x = 0.9 (the plain midpoint 0.5 would give 2)
    with pytest.raises(ValueError, match="axis"):
        contact_regions(c, f, axis=3)
    with pytest.raises(ValueError, match="position"):
        contact_regions(c, f, position="lens")


def test_contact_regions_wraps_periodic_midpoints():
    f, _ = _line_frame(boundary="pp ff ff")
    # contact across the periodic x boundary: 5 -> 0 via minimum image (+1 in x)
    c = Contacts(i=[5], j=[0], branch=[[1.0, 0, 0]], radii_i=[0.3], radii_j=[0.7], n_particles=6)
    lab, _ = contact_regions(c, f, bounds="box")   # contact point 5.3: inside, last region
    assert lab.tolist() == [2]
    c = Contacts(i=[5], j=[0], branch=[[1.0, 0, 0]], radii_i=[0.7], radii_j=[0.3], n_particles=6)
    lab, _ = contact_regions(c, f, bounds="box")   # 5.7 wraps to -0.3: first region
    assert lab.tolist() == [0]


def test_region_fabric_equals_fabric_of_selection():
    rng = np.random.default_rng(15)
    n = 300
    pos = rng.uniform([0, 0, 0], [30, 5, 5], size=(n, 3))
    f = Frame(pos, np.full(n, 0.5), box=Box([0, 0, 0], [30, 5, 5], boundary="ff ff ff"))
    i = rng.integers(0, n, 900)
    j = (i + rng.integers(1, n, 900)) % n
    br = rng.normal(size=(900, 3))
    w = rng.random(900)
    c = Contacts(i=i, j=j, branch=br, radii_i=np.full(900, 0.5), radii_j=np.full(900, 0.5), n_particles=n)
    r = region_fabric(c, f, weights=w)
    assert r.names == ("start", "centre", "end") and len(r) == 3
    for k, name in enumerate(r.names):
        sel = r.labels == k
        ref = fabric_tensors(c.select(sel), w[sel])
        np.testing.assert_allclose(r[name].N4, ref.N4, atol=1e-14)
        assert r[k].n_contacts == sel.sum()
    r5 = region_fabric(c, f, n_regions=5, axis=1, l_max=4)
    assert r5.names[0] == "region 0" and r5.axis == 1
    from bedstruct.analysis.harmonics import fabric_from_harmonics
    for t, e in zip(r5.tensors, r5.expansions):
        np.testing.assert_allclose(fabric_from_harmonics(e).D4, t.D4, atol=1e-12)
    assert r.expansions is None
    tab = fabric_table(r.tensors, labels=r.names)
    assert set(len(v) for v in tab.values()) == {3}
    assert tab["label"].tolist() == ["start", "centre", "end"]


def test_fabric_table_empty_is_typed():
    tab = fabric_table([])
    assert all(len(v) == 0 for v in tab.values())
    assert tab["n_contacts"].dtype == np.int64 and tab["N2_xx"].dtype == np.float64


# --------------------------------------------------------------------------- LAMMPS
def _lammps_reference(pairs_del, branch_len=None, fn=None, ft=None):
    """Literal transcription of LAMMPS compute_fabric.cpp (GRANULAR) for one processor."""
    nc = len(pairs_del)
    phi = [0.0] * 6
    for dx, dy, dz in pairs_del:
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        nx, ny, nz = dx / r, dy / r, dz / r
        for k, v in enumerate((nx * nx, ny * ny, nz * nz, nx * ny, nx * nz, ny * nz)):
            phi[k] += v
    phi = [p / nc for p in phi]
    tr = (phi[0] + phi[1] + phi[2]) / 3
    ac = [7.5 * (phi[k] - (tr if k < 3 else 0.0)) for k in range(6)]
    out = {"contact": ac}
    xs = {"branch": [0.0] * 6, "fn": [0.0] * 6, "ft": [0.0] * 6}
    for a, (dx, dy, dz) in enumerate(pairs_del):
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        nx, ny, nz = dx / r, dy / r, dz / r
        denom = (1 + ac[0] * nx * nx + ac[1] * ny * ny + ac[2] * nz * nz
                 + 2 * ac[3] * nx * ny + 2 * ac[4] * nx * nz + 2 * ac[5] * ny * nz)
        pref = 1 / nc / denom
        prods = (nx * nx, ny * ny, nz * nz, nx * ny, nx * nz, ny * nz)
        for key, val in (("branch", branch_len), ("fn", fn), ("ft", ft)):
            if val is not None:
                for k in range(6):
                    xs[key][k] += pref * prods[k] * val[a]

    def dev(x, scale_tr3):
        t3 = (x[0] + x[1] + x[2]) / 3
        return [scale_tr3 * (x[k] - (t3 if k < 3 else 0.0)) for k in range(6)]
    tb = (xs["branch"][0] + xs["branch"][1] + xs["branch"][2]) / 3
    tn = (xs["fn"][0] + xs["fn"][1] + xs["fn"][2]) / 3
    out["branch"] = dev(xs["branch"], 15 / (6 * tb)) if branch_len is not None else None
    out["fn"] = dev(xs["fn"], 15 / (6 * tn)) if fn is not None else None
    out["ft"] = dev(xs["ft"], 15 / (9 * tn)) if ft is not None else None
    return out


def test_lammps_contact_tensor_is_our_D2_and_other_tensors_follow_the_source():
    rng = np.random.default_rng(16)
    m = 60
    delv = rng.normal(size=(m, 3)) * [1.5, 1.0, 0.7]      # LAMMPS uses x_i - x_j
    lengths = np.linalg.norm(delv, axis=1)
    fn = rng.uniform(0.1, 3, m)
    ft = rng.uniform(0.0, 1, m)
    ref = _lammps_reference(delv, lengths, fn, ft)
    ours = lammps_fabric(-delv, branch_lengths=lengths, force_normal=fn, force_tangential=ft)
    t = fabric_tensors(delv)
    np.testing.assert_allclose(ours.contact, lammps_voigt(t.D2), atol=1e-14)
    np.testing.assert_allclose(ours.contact, ref["contact"], atol=1e-14)
    np.testing.assert_allclose(ours.branch, ref["branch"], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(ours.force_normal, ref["fn"], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(ours.force_tangential, ref["ft"], rtol=1e-12, atol=1e-14)
    assert ours.n_contacts == m
    # from a Contacts object: branch lengths and forces default to its fields
    c = Contacts(i=np.arange(m), j=np.arange(m) + m, branch=-delv, radii_i=np.full(m, 2.0),
                 radii_j=np.full(m, 2.0), force_normal=unit(delv) * fn[:, None])
    oc = lammps_fabric(c)
    np.testing.assert_allclose(oc.branch, ref["branch"], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(oc.force_normal, ref["fn"], rtol=1e-12, atol=1e-14)
    assert oc.force_tangential is None
    with pytest.raises(ValueError, match="force_normal"):
        lammps_fabric(delv, force_tangential=ft)


def test_lattice_neighbour_shells_analytic_values():
    """SC (6 neighbours) and FCC (12): D2 = 0, D4_xxxx = 21/4 and -21/16 (hand-derived)."""
    sc = np.vstack([np.eye(3), -np.eye(3)])
    fcc = np.array([(a, b, 0) for a in (-1, 1) for b in (-1, 1)]
                   + [(a, 0, b) for a in (-1, 1) for b in (-1, 1)]
                   + [(0, a, b) for a in (-1, 1) for b in (-1, 1)], dtype=float)
    for dirs, d4xxxx, d4xxyy in ((sc, 21 / 4, -21 / 8), (fcc, -21 / 16, 21 / 32)):
        t = fabric_tensors(dirs)
        np.testing.assert_allclose(t.D2, 0, atol=1e-14)
        assert t.D4[0, 0, 0, 0] == pytest.approx(d4xxxx, abs=1e-13)
        assert t.D4[0, 0, 1, 1] == pytest.approx(d4xxyy, abs=1e-13)
        assert t.D4[2, 2, 2, 2] == pytest.approx(d4xxxx, abs=1e-13)


def test_the_anisotropy_of_isotropic_samples_is_their_stated_noise():
    # M isotropic normals: E[a^2] = 225/(4M), E[a4^2] = 2835/(8M), E[P2/P0] = 5/M, E[P4/P0] = 9/M
    from bedstruct.analysis import fabric_tensors, harmonic_expansion
    rng = np.random.default_rng(7)
    M, reps = 200, 400
    a2, a42, p2, p4 = [], [], [], []
    for _ in range(reps):
        n = rng.normal(size=(M, 3))
        n /= np.linalg.norm(n, axis=1)[:, None]
        t = fabric_tensors(n)
        e = harmonic_expansion(n, 4)
        a2.append(t.anisotropy ** 2)
        a42.append(t.anisotropy_rank4 ** 2)
        p2.append(e.power[2] / e.power[0])
        p4.append(e.power[4] / e.power[0])
    assert np.sqrt(np.mean(a2)) == pytest.approx(t.anisotropy_noise, rel=0.06)
    assert np.sqrt(np.mean(a42)) == pytest.approx(t.anisotropy_rank4_noise, rel=0.06)
    assert np.mean(p2) * M == pytest.approx(5.0, rel=0.1)
    assert np.mean(p4) * M == pytest.approx(9.0, rel=0.1)
    # the identities behind them hold for any sample
    assert t.anisotropy ** 2 == pytest.approx(45 / 4 * p2[-1], rel=1e-9)
    assert t.anisotropy_rank4 ** 2 == pytest.approx(315 / 8 * p4[-1], rel=1e-9)
