"""Heat conduction through the contact network: physics against physics.

Analytic answers (two spheres, chains, lattices), exact matrix exponentials,
energy conservation, brute-force references for the kernels, and the
anisotropy of stretched lattices (conductivity tensor and HAZ shape).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bedstruct.core import Box, Contacts, Frame, Units
from bedstruct.errors import BedstructWarning
from bedstruct.analysis import _heat_kernels as hk
from bedstruct.analysis.heat import (COCR, GasGap, HemisphereSource, ThermalMaterial, TemperatureMap,
                                     conduct_heat, conductivity_tensor, haz_shape, source_nodes,
                                     temperature_map, thermal_network)

K_S = COCR.conductivity


# ----------------------------------------------------------------- helpers
def brute_contacts(frame: Frame, tolerance: float = 0.0) -> Contacts:
    """O(N^2) minimum-image pair search (reference for small frames)."""
    pos = frame.positions
    d = frame.box.minimum_image(pos[None, :, :] - pos[:, None, :])
    dist = np.linalg.norm(d, axis=-1)
    rsum = frame.radii[:, None] + frame.radii[None, :]
    i, j = np.nonzero(np.triu(dist <= rsum + tolerance, 1))
    return Contacts(i, j, d[i, j], frame.radii[i], frame.radii[j], n_particles=frame.n_particles)


def lattice(n, spacing, radius, *, boundary="ff ff ff", rotate_deg=0.0, units="micro"):
    """Simple-cubic lattice with per-axis spacing; contacts by index (6 neighbours).

    With ``rotate_deg`` the lattice is turned about z (non-periodic boxes only).
    """
    n = np.asarray(n)
    s = np.broadcast_to(np.asarray(spacing, dtype=float), (3,))
    grid = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    pos = (grid + 0.5) * s
    box = Box([0, 0, 0], n * s, boundary=boundary)
    per = box.periodic
    index = np.arange(len(grid)).reshape(tuple(n))
    ii, jj, br = [], [], []
    for ax in range(3):
        shift = np.zeros(3, dtype=int)
        shift[ax] = 1
        nb = grid + shift
        ok = nb[:, ax] < n[ax]
        if per[ax] and n[ax] > 2:
            nb[:, ax] %= n[ax]
            ok = np.ones(len(grid), dtype=bool)
        src = np.flatnonzero(ok)
        ii.append(src)
        jj.append(index[tuple(nb[src].T)])
        br.append(np.tile(shift * s, (len(src), 1)))
    i, j, b = np.concatenate(ii), np.concatenate(jj), np.concatenate(br).astype(float)
    if rotate_deg:
        c, sn = math.cos(math.radians(rotate_deg)), math.sin(math.radians(rotate_deg))
        R = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1.0]])
        centre = pos.mean(axis=0)
        pos = (pos - centre) @ R.T + centre
        b = b @ R.T
        big = np.abs(pos - centre).max() * 2 + 10 * s.max()
        box = Box(centre - big, centre + big, boundary=boundary)
        box = Box([box.lo[0], box.lo[1], 0.0], [box.hi[0], box.hi[1], n[2] * s[2]], boundary=boundary)
    r = np.full(len(pos), float(radius))
    frame = Frame(pos, r, box=box, units=Units(units))
    contacts = Contacts(i, j, b, r[i], r[j], n_particles=len(pos))
    return frame, contacts


def two_spheres(overlap_radius=2.0, r=10.0):
    d = 2 * math.sqrt(r * r - overlap_radius ** 2)
    f = Frame([[0, 0, 0], [d, 0, 0]], [r, r], box=[100, 100, 100], units=Units("micro"))
    c = Contacts([0], [1], [[d, 0, 0]], [r], [r])
    return f, c


def chain(n, r=10.0, a=2.0):
    d = 2 * math.sqrt(r * r - a * a)
    x = np.arange(n) * d
    f = Frame(np.c_[x, np.zeros(n), np.zeros(n)], np.full(n, r), box=[n * d + 10, 50, 50],
              units=Units("micro"))
    c = Contacts(np.arange(n - 1), np.arange(1, n), np.tile([d, 0, 0], (n - 1, 1)),
                 np.full(n - 1, r), np.full(n - 1, r))
    return f, c


def random_bed(n=300, seed=3, box=(12, 12, 8)):
    rng = np.random.default_rng(seed)
    b = Box([0, 0, 0], box, boundary="pp pp ff")
    pos = rng.uniform([0, 0, 0.6], [box[0], box[1], box[2]], size=(n, 3))
    radii = rng.uniform(0.5, 0.9, size=n)
    f = Frame(pos, radii, box=b, units=Units("micro"))
    return f, brute_contacts(f)


# ----------------------------------------------------------- network model
def test_contact_conductance_is_2ka_and_capacity_rhocv():
    f, c = two_spheres(2.0, 10.0)
    net = thermal_network(f, c)
    assert net.conductance[0] == pytest.approx(2 * K_S * 2e-6, rel=1e-12)
    assert net.capacity[0] == pytest.approx(8300 * 450 * 4 / 3 * math.pi * 1e-15, rel=1e-12)
    assert net.length_scale == 1e-6 and "micro" in net.units


def test_dissimilar_materials_use_series_constriction():
    f, c = two_spheres(2.0)
    f = Frame(f.positions, f.radii, box=f.box, types=[1, 2], units=Units("micro"))
    m1, m2 = ThermalMaterial(8000, 500, 10.0), ThermalMaterial(8000, 500, 40.0)
    net = thermal_network(f, c, materials={1: m1, 2: m2})
    # 1/G = 1/(4 k1 a) + 1/(4 k2 a)
    assert net.conductance[0] == pytest.approx(1 / (1 / (4 * 10 * 2e-6) + 1 / (4 * 40 * 2e-6)))
    with pytest.raises(ValueError, match="no entry for particle types \\[2\\]"):
        thermal_network(f, c, materials={1: m1})


def test_units_converted_at_the_boundary_and_recorded():
    f, c = two_spheres(2.0)
    net_um = thermal_network(f, c)
    f_cm = Frame(f.positions * 1e-4, f.radii * 1e-4, box=Box([0] * 3, [1e-2] * 3), units=Units("cgs"))
    c_cm = Contacts([0], [1], c.branch * 1e-4, [1e-3], [1e-3])
    net_cm = thermal_network(f_cm, c_cm)
    assert net_cm.conductance[0] == pytest.approx(net_um.conductance[0], rel=1e-12)
    assert net_cm.capacity[0] == pytest.approx(net_um.capacity[0], rel=1e-12)
    assert "cgs" in net_cm.units
    unknown = f.with_units(None)
    with pytest.raises(ValueError, match="length_unit"):
        thermal_network(unknown, c)
    net = thermal_network(unknown, c, length_unit="um")
    assert net.conductance[0] == pytest.approx(net_um.conductance[0]) and "um" in net.units
    with pytest.warns(BedstructWarning, match="overrides"):
        thermal_network(f, c, length_unit=1e-3)
    with pytest.raises(ValueError, match="length_unit"):
        thermal_network(unknown, c, length_unit="furlong")


def test_dumped_area_is_used_for_the_contact_radius():
    f, c = two_spheres(2.0)
    c2 = Contacts([0], [1], c.branch, [10.0], [10.0], area=[math.pi * 3.0 ** 2])
    assert thermal_network(f, c2).conductance[0] == pytest.approx(2 * K_S * 3e-6)
    assert thermal_network(f, c2, contact_area="lens").conductance[0] == pytest.approx(2 * K_S * 2e-6)
    with pytest.raises(ValueError, match="area"):
        thermal_network(f, c, contact_area="dumped")


def test_gas_gap_conductance_matches_numerical_integral():
    gas = GasGap()
    r1, r2, h0 = 12e-6, 8e-6, 0.4e-6
    rstar = r1 * r2 / (r1 + r2)
    rho_c = gas.lens_fraction * min(r1, r2)
    # exact sphere surfaces would differ; the model integrates the parabolic gap
    ref, _ = scipy.integrate.quad(
        lambda rho: 2 * math.pi * rho * gas.conductivity
        / (h0 + gas.jump_distance + rho ** 2 / (2 * rstar)), 0, rho_c)
    assert gas.conductance(r1, r2, h0) == pytest.approx(ref, rel=1e-8)
    # decreasing with the gap, zero beyond max_gap
    g = gas.conductance([r1] * 3, [r2] * 3, [0.0, 1e-6, 5e-6])
    assert g[0] > g[1] > g[2] > 0
    assert GasGap(max_gap=2e-6).conductance(r1, r2, 5e-6) == 0.0
    # near (non-touching) pairs conduct through the gas only
    f = Frame([[0, 0, 0], [20.5, 0, 0]], [10.0, 10.0], box=[100] * 3, units=Units("micro"))
    c = Contacts([0], [1], [[20.5, 0, 0]], [10.0], [10.0])
    assert thermal_network(f, c).conductance[0] == 0.0
    net = thermal_network(f, c, gas=gas)
    assert net.conductance[0] == pytest.approx(gas.conductance(10e-6, 10e-6, 0.5e-6))


# ------------------------------------------------------------ transients
def test_two_spheres_relax_exponentially():
    f, c = two_spheres(2.0)
    net = thermal_network(f, c)
    G, C = net.conductance[0], net.capacity[0]
    tau = C / (2 * G)
    times = np.linspace(0, 3 * tau, 7)
    res = conduct_heat(net, t_end=3 * tau, times=times, initial_temperature=[500.0, 300.0], atol=1e-4)
    dT = res.temperatures[:, 0] - res.temperatures[:, 1]
    np.testing.assert_allclose(dT, 200 * np.exp(-times / tau), atol=5e-4)
    np.testing.assert_allclose(res.temperatures.mean(axis=1), 400.0, atol=1e-10)
    # first-order monotone variant converges too, and never overshoots
    res1 = conduct_heat(net, t_end=3 * tau, initial_temperature=[500.0, 300.0], atol=1e-3,
                        extrapolate=False)
    d1 = res1.final_temperature[0] - res1.final_temperature[1]
    assert d1 == pytest.approx(200 * math.exp(-3), abs=0.15)   # first order: error ~ sqrt(atol)
    assert res1.peak_temperature[0] == 500.0 and res1.peak_temperature[1] <= 400.0


def test_chain_matches_matrix_exponential():
    n = 8
    f, c = chain(n)
    net = thermal_network(f, c)
    T0 = np.linspace(900.0, 300.0, n) ** 1.1 / 2.0
    L = (sp.diags(net.weight_sums) - net.weights).toarray()
    Minv = np.diag(1 / net.capacity)
    tau = net.capacity[0] / net.conductance[0]
    times = np.array([0.0, 0.3, 1.0, 4.0, 10.0]) * tau
    res = conduct_heat(net, t_end=times[-1], times=times, initial_temperature=T0, atol=1e-4)
    for t, T in zip(times, res.temperatures):
        ref = scipy.linalg.expm(-Minv @ L * t) @ T0
        np.testing.assert_allclose(T, ref, atol=2e-3)
    assert res.energy.relative_error < 1e-10


def test_chain_between_fixed_temperatures_reaches_linear_profile():
    n = 10
    f, c = chain(n)
    net = thermal_network(f, c)
    fixed = np.full(n, np.nan)
    fixed[0], fixed[-1] = 800.0, 300.0
    tau = net.capacity[0] / net.conductance[0]
    res = conduct_heat(net, t_end=400 * tau, fixed_temperature=fixed, initial_temperature=300.0)
    np.testing.assert_allclose(res.final_temperature, np.linspace(800, 300, n), atol=1e-3)
    # steady state: the heat in at the hot end went out at the cold end
    # (boundary energy equals the stored energy: imbalance is zero)
    assert abs(res.energy.imbalance).max() < 1e-10 * abs(res.energy.stored).max()


def test_energy_conserved_with_insulated_boundaries_direct_and_cg():
    f, c = random_bed()
    net = thermal_network(f, c)
    rng = np.random.default_rng(0)
    T0 = rng.uniform(300, 1500, f.n_particles)
    tau = np.median(net.capacity / np.maximum(net.weight_sums, 1e-300))
    out = {}
    for solver, cg_tol in (("direct", None), ("cg", 1.0)):   # a very loose CG tolerance
        res = conduct_heat(net, t_end=20 * tau, initial_temperature=T0, solver=solver, cg_tol=cg_tol)
        E0 = net.capacity @ T0
        E1 = net.capacity @ res.final_temperature
        assert abs(E1 - E0) / E0 < 1e-12
        assert res.energy.relative_error < 1e-10
        assert res.solver == solver
        out[solver] = res
    assert out["cg"].n_iterations > 0
    # and the two solvers agree (to the looseness of the CG tolerance)
    assert np.abs(out["cg"].final_temperature - out["direct"].final_temperature).max() < 20.0


def test_cg_matches_direct_at_tight_tolerance():
    f, c = random_bed(seed=5)
    net = thermal_network(f, c)
    src = HemisphereSource((6e-6, 6e-6), diameter=5e-6)
    tau = np.median(net.capacity / np.maximum(net.weight_sums, 1e-300))
    kw = dict(t_end=30 * tau, source=src, atol=0.5, dt_initial=tau)
    rd = conduct_heat(net, solver="direct", **kw)
    rc = conduct_heat(net, solver="cg", cg_tol=1e-8, **kw)
    assert rc.n_steps == rd.n_steps
    np.testing.assert_allclose(rc.final_temperature, rd.final_temperature, atol=1e-5)


def test_held_source_and_plate_energy_balance():
    f, c = random_bed(seed=11)
    # let the lowest particles overlap the plate at z = 0
    pos = f.positions.copy()
    low = pos[:, 2] < 1.5
    pos[low, 2] = f.radii[low] * 0.9
    f = Frame(pos, f.radii, box=f.box, units=f.units)
    c = brute_contacts(f)
    net = thermal_network(f, c)
    assert np.count_nonzero(net.plate_conductance) == np.count_nonzero(low)
    src = HemisphereSource((6e-6, 6e-6), diameter=6e-6, temperature=1573.15, duration=5e-5)
    res = conduct_heat(net, t_end=4e-4, source=src, plate_temperature=293.15,
                       initial_temperature=293.15)
    e = res.energy
    assert e.relative_error < 1e-10
    assert e.source[-1] > e.source[0] > 0          # the held source kept feeding heat
    assert e.boundary[-1] < 0                      # the cold plate took heat out
    assert np.all(res.final_temperature >= 293.15 - 1e-6)
    nodes, _ = source_nodes(net, src)
    np.testing.assert_allclose(res.peak_temperature[nodes], 1573.15)


def test_constant_power_source_stores_power_times_time():
    f, c = random_bed(seed=2)
    net = thermal_network(f, c)
    src = HemisphereSource((6e-6, 6e-6), diameter=6e-6, power=1e-3, duration=1e-4)
    res = conduct_heat(net, t_end=3e-4, source=src, times=[1e-4, 3e-4])
    np.testing.assert_allclose(res.energy.stored, [1e-7, 1e-7], rtol=1e-10)
    np.testing.assert_allclose(res.energy.source, [1e-7, 1e-7], rtol=1e-10)


def test_source_nodes_hemisphere_on_the_surface():
    f, c = lattice((5, 5, 3), 20.0, 10.5)
    net = thermal_network(f, c)
    nodes, centre = source_nodes(net, HemisphereSource((50e-6, 50e-6), diameter=50e-6))
    # the surface is the top of the upper layer: z = 2.5 * 20 + 10.5 um
    assert centre[2] == pytest.approx(60.5e-6)
    d = np.linalg.norm(net.positions - centre, axis=1)
    np.testing.assert_array_equal(nodes, np.flatnonzero(d <= 25e-6))
    assert len(nodes) == 5    # the top-centre particle and its four neighbours
    with pytest.raises(ValueError, match="no particle"):
        source_nodes(net, HemisphereSource((1.0, 1.0)))


def test_pulse_source_seed_setup_runs_and_cools():
    f, c = lattice((9, 9, 3), 20.0, 10.5)
    net = thermal_network(f, c)
    src = HemisphereSource((90e-6, 90e-6), diameter=50e-6)   # pulse at 1300 C
    res = conduct_heat(net, t_end=5e-3, source=src)
    assert res.max_temperature[0] == pytest.approx(1573.15)
    assert np.all(np.diff(res.max_temperature) <= 1e-9)    # the hottest particle only cools
    assert res.energy.relative_error < 1e-10
    assert res.energy.source[0] == pytest.approx(
        net.capacity[res.source_nodes].sum() * (1573.15 - 293.15))


def test_bad_inputs_raise_clear_errors():
    f, c = two_spheres()
    net = thermal_network(f, c)
    with pytest.raises(ValueError, match="t_end"):
        conduct_heat(net, t_end=0)
    with pytest.raises(ValueError, match="initial_temperature"):
        conduct_heat(net, t_end=1, initial_temperature=[300.0])
    with pytest.raises(TypeError, match="ThermalNetwork"):
        conduct_heat(f, t_end=1)
    with pytest.raises(ValueError, match="center"):
        HemisphereSource((1.0,))
    with pytest.raises(ValueError, match="times"):
        conduct_heat(net, t_end=1, times=[2.0])
    lifted = Frame(f.positions + [0, 0, 50.0], f.radii, box=f.box, units=f.units)
    with pytest.warns(BedstructWarning, match="no particle touches the plate"):
        conduct_heat(thermal_network(lifted, c), t_end=1e-4, plate_temperature=300.0)


# --------------------------------------------------------------- kernels
def test_pcg_kernel_against_scipy_solve():
    rng = np.random.default_rng(1)
    n = 300
    W = sp.random(n, n, density=0.03, random_state=2, data_rvs=lambda k: rng.uniform(0.1, 1, k))
    W = (W + W.T).tocsr()
    W.setdiag(0)
    W.eliminate_zeros()
    W.sort_indices()
    d = np.asarray(W.sum(axis=1)).ravel() + rng.uniform(0.01, 0.1, n)
    b = rng.normal(size=n)
    A = sp.diags(d) - W
    ref = spla.spsolve(A.tocsc(), b)
    wrow = np.asarray(W.sum(axis=1)).ravel()
    for idx_dtype in (np.int32,):   # the dtype the solver uses
        x = np.zeros(n)
        work = [np.empty(n) for _ in range(4)]
        out = np.zeros(1)
        it = hk.pcg_solve(W.indptr.astype(np.int64), W.indices.astype(idx_dtype), W.data, d, wrow, b,
                          x, 1e-12, 5000, hk.chunk_bounds(n, 64), *work, np.empty(64), np.empty(64),
                          out)
        assert 0 < it <= 5000
        np.testing.assert_allclose(x, ref, atol=1e-9)
        assert out[0] == pytest.approx((b - A @ x).sum(), abs=1e-12)   # exact residual sum
    # a loose tolerance stops early, and the residual sum is still exact
    x = np.zeros(n)
    it = hk.pcg_solve(W.indptr.astype(np.int64), W.indices.astype(np.int32), W.data, d, wrow, b, x,
                      1e-1, 5000, hk.chunk_bounds(n, 64), *work, np.empty(64), np.empty(64), out)
    assert it < 20 and np.abs(x - ref).max() > 1e-6
    assert out[0] == pytest.approx((b - A @ x).sum(), abs=1e-12)


def test_rasterize_top_against_numpy_reference():
    rng = np.random.default_rng(4)
    n = 60
    x, y, z = rng.uniform(0, 10, n), rng.uniform(0, 8, n), rng.uniform(0, 3, n)
    r = rng.uniform(0.4, 1.2, n)
    v = rng.uniform(300, 900, n)
    cell, nx, ny = 0.25, 40, 32
    xc = (np.arange(nx) + 0.5) * cell
    yc = (np.arange(ny) + 0.5) * cell
    gx, gy = np.meshgrid(xc, yc)
    d2 = (gx[..., None] - x) ** 2 + (gy[..., None] - y) ** 2
    cover = d2 <= r ** 2
    h = np.where(cover, z + np.sqrt(np.clip(r ** 2 - d2, 0, None)), -np.inf)
    ref_top = np.where(cover.any(-1), v[np.argmax(h, axis=-1)], np.nan)
    ref_max = np.where(cover.any(-1), np.max(np.where(cover, v, -np.inf), axis=-1), np.nan)
    for mode, ref in ((0, ref_top), (1, ref_max)):
        out = np.full((ny, nx), np.nan)
        hk.rasterize_top(x, y, z, r, v, 0.0, 0.0, cell, nx, ny, mode, out, np.full((ny, nx), -np.inf),
                         np.full((ny, nx), -1, dtype=np.int64))
        np.testing.assert_array_equal(out, ref)


# -------------------------------------------------- conductivity tensor
def test_simple_cubic_lattice_conductivity_is_isotropic_g_over_s():
    f, c = lattice((4, 4, 4), 20.0, 10.5, boundary="pp pp pp")
    net = thermal_network(f, c)
    k = conductivity_tensor(net)
    G = 2 * K_S * math.sqrt(10.5 ** 2 - 10.0 ** 2) * 1e-6
    np.testing.assert_allclose(k.tensor, G / 20e-6 * np.eye(3), rtol=1e-10, atol=1e-12)
    # the temperature field of a perfect lattice is exactly affine: the bound is attained
    np.testing.assert_allclose(k.affine, G / 20e-6 * np.eye(3), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(k.fabric, np.eye(3) / 3, atol=1e-12)
    assert k.boundary == ("periodic",) * 3 and k.asymmetry < 1e-10
    assert k.anisotropy == pytest.approx(0.0, abs=1e-10)


def test_stretched_lattice_gives_predicted_anisotropy():
    s = np.array([19.0, 20.0, 21.0])
    r = 10.8
    f, c = lattice((4, 4, 4), s, r, boundary="pp pp pp")
    net = thermal_network(f, c)
    k = conductivity_tensor(net)
    a = np.sqrt(r ** 2 - (s / 2) ** 2) * 1e-6
    G = 2 * K_S * a
    sm = s * 1e-6
    expected = G * sm ** 2 / np.prod(sm)            # K_aa = G_a s_a / (s_b s_c)
    np.testing.assert_allclose(np.diag(k.tensor), expected, rtol=1e-10)
    np.testing.assert_allclose(k.affine, np.diag(expected), rtol=1e-10, atol=1e-10 * expected.min())
    np.testing.assert_allclose(k.eigenvalues, np.sort(expected)[::-1], rtol=1e-10)
    assert abs(k.eigenvectors[0, 0]) == pytest.approx(1.0)   # principal direction x
    # the contact directions alone are isotropic: the fabric cannot see this anisotropy
    np.testing.assert_allclose(k.fabric, np.eye(3) / 3, atol=1e-12)


def test_missing_contacts_along_z_show_in_tensor_and_fabric():
    f, c = lattice((4, 4, 4), [20.0, 20.0, 22.0], 10.5, boundary="pp pp pp")
    c = c.select(c.overlap > 0)     # the z neighbours do not touch
    net = thermal_network(f, c)
    k = conductivity_tensor(net)
    assert k.tensor[2, 2] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(k.fabric, np.diag([0.5, 0.5, 0.0]), atol=1e-12)


def test_window_in_rotated_block_finds_principal_direction():
    # a window inside a block rotated 30 deg: crossing contacts on window faces keep the
    # lattice's uniform gradient, so the tensor is the rotated bulk tensor
    s = np.array([18.5, 20.0, 20.0])
    r = 10.5
    f, c = lattice((40, 40, 4), s, r, rotate_deg=30.0)
    net = thermal_network(f, c)
    centre = f.positions.mean(axis=0)
    lo = np.array([centre[0] - 150, centre[1] - 150, -1.0]) * 1e-6
    hi = np.array([centre[0] + 150, centre[1] + 150, 100.0]) * 1e-6
    k = conductivity_tensor(net, region=(lo, hi))
    assert k.boundary == ("window", "window", "surface")
    a = np.sqrt(np.clip(r ** 2 - (s / 2) ** 2, 0, None)) * 1e-6
    kx, ky, kz = 2 * K_S * a * (s * 1e-6) ** 2 / np.prod(s * 1e-6)
    t = math.radians(30.0)
    R = np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])
    expected = R @ np.diag([kx, ky, kz]) @ R.T
    # the window's faces are not lattice planes: the branch length inside differs from
    # density x volume at the 1e-2 level
    np.testing.assert_allclose(k.tensor, expected, rtol=1e-2, atol=1e-2 * kx)
    v = k.eigenvectors[:, 0]
    assert math.degrees(math.atan2(v[1], v[0])) % 180 == pytest.approx(30.0, abs=0.5)


def test_random_bed_tensor_is_below_the_affine_bound():
    f, c = random_bed(n=400, seed=8, box=(10, 10, 8))
    net = thermal_network(f, c)
    k = conductivity_tensor(net)
    assert k.boundary == ("periodic", "periodic", "surface")
    # in-plane (insulated top and bottom, nothing held) the affine estimate is sum G l (x) l / V
    affine = np.einsum("m,ma,mb->ab", net.conductance, net.branch, net.branch) / k.volume
    np.testing.assert_allclose(k.affine[:2, :2], affine[:2, :2], rtol=1e-12)
    # relaxing the temperatures can only lower the dissipation: K <= affine (Loewner order)
    assert np.linalg.eigvalsh(k.affine - k.tensor).min() > -1e-9 * k.affine.max()
    assert np.all(k.eigenvalues > 0)


def fcc(cells, a=20.0, radius_factor=0.51, boundary="pp pp pp"):
    """Face-centred cubic lattice of ``cells`` cubic cells of side ``a`` (um); nearest distance a/sqrt(2)."""
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) + 0.25
    g = np.stack(np.meshgrid(*[np.arange(cells)] * 3, indexing="ij"), -1).reshape(-1, 1, 3)
    pos = ((g + basis[None]).reshape(-1, 3)) * a
    s = a / math.sqrt(2)
    f = Frame(pos, np.full(len(pos), radius_factor * s), box=Box([0, 0, 0], [cells * a] * 3, boundary=boundary),
              units=Units("micro"))
    return f, brute_contacts(f), s


def insulated_solve(net, held=None):
    """Independent reference: sparse Laplacian, unit gradients, theta = 0 on ``held`` (else one pin).

    Returns the flux sums ``sum_c G (T_j - T_i) l_c`` (one column per gradient) and the
    temperatures ``T = g.x + theta`` of each solve.
    """
    n, i, j, G, l = net.n_particles, net.i, net.j, net.conductance, net.branch
    W = sp.coo_matrix((np.r_[G, G], (np.r_[i, j], np.r_[j, i])), shape=(n, n)).tocsr()
    L = (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()
    F, T = np.zeros((3, 3)), np.zeros((3, n))
    for b in range(3):
        fixed = np.zeros(n, dtype=bool)
        if held is not None and held[b] is not None:
            fixed[held[b]] = True
        else:
            fixed[0] = True
        free = np.flatnonzero(~fixed)
        rhs = np.bincount(i, G * l[:, b], minlength=n) - np.bincount(j, G * l[:, b], minlength=n)
        th = np.zeros(n)
        th[free] = spla.spsolve(L[free][:, free].tocsc(), rhs[free])
        F[:, b] = (G * (l[:, b] + th[j] - th[i])) @ l
        T[b] = net.positions[:, b] + th
    return F, T


@pytest.mark.parametrize("boundary", ["ff ff ff", "pp pp ff", "pp ff pp", "ff pp ff", "ff ff pp"])
def test_simple_cubic_lattice_is_g_over_s_with_free_surfaces(boundary):
    # free surfaces: the held slabs apply only to the gradient normal to them, and the
    # thickness reaches one contact radius (s/2) beyond the outer centres: exact K = G/s I
    f, c = lattice((6, 5, 4), 20.0, 10.5, boundary=boundary)
    net = thermal_network(f, c)
    G = net.conductance[0]
    k = conductivity_tensor(net)
    np.testing.assert_allclose(k.tensor, G / 20e-6 * np.eye(3), rtol=1e-10, atol=1e-10 * G / 20e-6)
    np.testing.assert_allclose(k.affine, G / 20e-6 * np.eye(3), rtol=1e-10, atol=1e-10 * G / 20e-6)
    assert k.volume == pytest.approx(120 * 100 * 80 * 1e-18, rel=1e-12)
    assert k.boundary == tuple("periodic" if b == "pp" else "surface" for b in boundary.split())


@pytest.mark.parametrize("window", [
    ((140, 0, 0), (420, 200, 120)),          # x window of 14 cells, y periodic spanned, z bed
    ((0, 0, 0), (280, 200, 120)),            # starts at the bed's free x surface
    ((100, 40, 0), (500, 160, 120)),         # also cuts the periodic y axis
    ((100, 40, 20), (500, 160, 100)),        # and z: every face a window face
])
def test_simple_cubic_lattice_windows_of_whole_cells_give_g_over_s(window):
    # contacts cut by a window face count with the part of their branch inside; across faces
    # normal to the gradient the outside end is held at the affine temperature
    f, c = lattice((42, 10, 6), 20.0, 10.5, boundary="ff pp ff")
    net = thermal_network(f, c)
    G = net.conductance[0]
    lo, hi = (np.asarray(v, dtype=float) * 1e-6 for v in window)
    k = conductivity_tensor(net, region=(lo, hi))
    np.testing.assert_allclose(k.tensor, G / 20e-6 * np.eye(3), rtol=1e-9, atol=1e-9 * G / 20e-6)
    assert k.volume == pytest.approx(np.prod(hi - lo), rel=1e-9)
    assert k.boundary[0] in ("window", "surface/window")


def test_bed_windows_of_an_isotropic_lattice_show_no_anisotropy():
    # three x-windows of a strip periodic in y (as heat_regions cuts them): round in-plane K
    from bedstruct.analysis import bed_windows
    from bedstruct.analysis.heat_study import planar_axes
    f, c = lattice((42, 10, 6), 20.0, 10.5, boundary="ff pp ff")
    net = thermal_network(f, c)
    G = net.conductance[0]
    lo, hi = bed_windows(f, 3, axis=0)
    for a, b in zip(lo * 1e-6, hi * 1e-6):
        k = conductivity_tensor(net, region=(a, b))
        assert k.tensor[0, 0] == pytest.approx(G / 20e-6, rel=1e-9)
        # the windows' faces are s/40 off the lattice planes: lateral volume error < 3e-3
        np.testing.assert_allclose(np.diag(k.tensor), G / 20e-6, rtol=3e-3)
        assert planar_axes(k.tensor)[1] == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("window", [None, ((20, 20, 0), (60, 60, 80)), ((0, 10, 10), (80, 70, 70))])
def test_fcc_lattice_is_2_sqrt2_g_over_s(window):
    f, c, s = fcc(4)
    net = thermal_network(f, c)
    assert net.n_contacts == 6 * f.n_particles
    G = net.conductance[0]
    region = None if window is None else tuple(np.asarray(v, dtype=float) * 1e-6 for v in window)
    k = conductivity_tensor(net, region=region)
    expected = 2 * math.sqrt(2) * G / (s * 1e-6)
    np.testing.assert_allclose(k.tensor, expected * np.eye(3), rtol=1e-9, atol=1e-9 * expected)
    np.testing.assert_allclose(k.fabric, np.eye(3) / 3, atol=1e-12)


def test_thin_bed_with_insulated_faces_matches_an_independent_solve():
    # 4 layers periodic in x and y, lognormal contact conductances: in-plane K of the free slab
    # (insulated top and bottom), not the affine bound that holding the z faces would give
    from dataclasses import replace
    rng = np.random.default_rng(0)
    f, c = lattice((10, 10, 4), 20.0, 10.5, boundary="pp pp ff")
    net = thermal_network(f, c)
    net = replace(net, conductance=net.conductance[0] * rng.lognormal(0.0, 1.0, net.n_contacts))
    k = conductivity_tensor(net)
    V = 200e-6 * 200e-6 * 80e-6                   # 4 layers of 20 um
    assert k.volume == pytest.approx(V, rel=1e-12)
    assert k.boundary == ("periodic", "periodic", "surface")
    F, _ = insulated_solve(net)
    np.testing.assert_allclose(k.tensor[:2, :2], 0.5 * (F + F.T)[:2, :2] / V, rtol=1e-8)
    assert k.tensor[0, 0] / k.affine[0, 0] < 0.75            # far below the affine bound
    # K_zz: the outer layers are held (slabs thinner than a quarter of the bed); the heat
    # through a plane between the held layers, per area and unit gradient
    z = f.positions[:, 2]
    F, T = insulated_solve(net, held=[None, None, (z < 20) | (z > 60)])
    up = (np.abs(z[net.i] - 30.0) < 1.0) & (net.branch[:, 2] > 0)      # layer 2 -> layer 3
    Q = np.sum(net.conductance[up] * (T[2, net.j[up]] - T[2, net.i[up]]))
    assert k.tensor[2, 2] == pytest.approx(Q / (200e-6 * 200e-6), rel=1e-8)


def test_conductivity_tensor_does_not_depend_on_the_length_unit():
    f, c = random_bed(n=300, seed=5, box=(10, 10, 8))
    lo, hi = np.array([2.0, 0, 0]), np.array([8.0, 10, 8])
    k_um = conductivity_tensor(thermal_network(f, c), region=(lo * 1e-6, hi * 1e-6))
    f_si = Frame(f.positions * 1e-6, f.radii * 1e-6, box=Box([0, 0, 0], np.array([10, 10, 8]) * 1e-6,
                                                           boundary="pp pp ff"), units=Units("si"))
    c_si = brute_contacts(f_si)
    np.testing.assert_array_equal(c_si.i, c.i)
    k_si = conductivity_tensor(thermal_network(f_si, c_si), region=(lo * 1e-6, hi * 1e-6))
    np.testing.assert_allclose(k_si.tensor, k_um.tensor, rtol=1e-9, atol=1e-12 * np.abs(k_um.tensor).max())
    assert k_si.volume == pytest.approx(k_um.volume, rel=1e-12)
    assert k_um.boundary == ("window", "periodic", "surface")


# --------------------------------------------------------- HAZ and maps
def _haz(spacing, radius, rotate=0.0, n=(31, 31, 4), t_end=2.5e-3):
    f, c = lattice(n, spacing, radius, rotate_deg=rotate)
    net = thermal_network(f, c)
    cx, cy = net.positions[:, 0].mean(), net.positions[:, 1].mean()
    src = HemisphereSource((cx, cy), diameter=45e-6)
    res = conduct_heat(net, t_end=t_end, source=src, atol=0.5)
    m = temperature_map(res, cell=2.5e-6)
    top = np.nanmax(m.values)
    shape = haz_shape(m, 293.15 + 0.3 * (top - 293.15))
    return res, m, shape


def test_haz_on_cubic_lattice_is_round():
    res, m, shape = _haz(20.0, 10.5)
    assert shape.roundness > 0.95
    assert shape.major_axis / shape.minor_axis < 1.05
    np.testing.assert_allclose(shape.centroid, res.source_center[:2], atol=3e-6)
    assert shape.area > 50 * (20e-6) ** 2 / 4  # spread well beyond the source


def test_haz_on_compressed_lattice_is_elongated_along_the_compression():
    # closer along x: larger contacts and shorter bonds; continuum diffusivity ratio
    # D_x / D_y = (a_x / a_y) (s_x / s_y)^2, so R -> sqrt(D_y / D_x) for an ellipse
    s = np.array([19.0, 20.0, 20.0])
    r = 10.5
    a = np.sqrt(r ** 2 - (s / 2) ** 2)
    ratio = (a[0] / a[1]) * (s[0] / s[1]) ** 2
    _, _, shape = _haz(s, r)
    assert abs(shape.orientation_deg) < 3.0
    assert shape.roundness == pytest.approx(1 / math.sqrt(ratio), abs=0.04)
    assert shape.roundness < 0.93
    # turning the lattice turns the zone with it
    _, _, turned = _haz(s, r, rotate=30.0)
    assert turned.orientation_deg == pytest.approx(30.0, abs=4.0)
    assert turned.roundness == pytest.approx(shape.roundness, abs=0.04)


def test_haz_shape_of_synthetic_ellipse():
    yy, xx = np.mgrid[0:200, 0:200] + 0.5
    t = math.radians(-40.0)
    u = (xx - 100) * math.cos(t) + (yy - 100) * math.sin(t)
    v = -(xx - 100) * math.sin(t) + (yy - 100) * math.cos(t)
    vals = np.where((u / 60) ** 2 + (v / 30) ** 2 <= 1, 600.0, 300.0)
    m = TemperatureMap(vals, xx[0] * 1e-6, yy[:, 0] * 1e-6, 1e-6, np.array([0, 200, 0, 200]) * 1e-6,
                       "top", source_center=np.array([100e-6, 100e-6]))
    s = haz_shape(m, 500.0)
    assert s.orientation_deg == pytest.approx(-40.0, abs=0.5)
    assert s.major_axis == pytest.approx(120e-6, rel=0.01)
    assert s.minor_axis == pytest.approx(60e-6, rel=0.02)
    assert s.area == pytest.approx(math.pi * 60e-6 * 30e-6, rel=0.01)
    assert s.roundness == pytest.approx(0.5, abs=0.01)
    empty = haz_shape(m, 1e4)
    assert empty.area == 0 and math.isnan(empty.roundness)


def test_temperature_map_modes_and_errors():
    f, c = lattice((6, 6, 2), 20.0, 10.5)
    net = thermal_network(f, c)
    T = 300.0 + net.positions[:, 2] * 1e6      # hotter on top; bottom layer 310 K
    top = temperature_map(net, temperature=T, cell=5e-6)
    hot = temperature_map(net, temperature=-T + 1000, cell=5e-6, method="max")
    assert np.nanmax(top.values) == pytest.approx(330.0) and np.nanmin(top.values) == pytest.approx(330.0)
    assert np.nanmin(hot.values) == pytest.approx(690.0)     # the lower particle is hotter
    lin = temperature_map(net, temperature=T, cell=5e-6, method="linear")
    assert np.nanmax(np.abs(lin.values - 330.0)) < 1e-9
    with pytest.raises(ValueError, match="temperature"):
        temperature_map(net)
    with pytest.raises(ValueError, match="method"):
        temperature_map(net, temperature=T, method="mean")


# -------------------------------------------------------------- plots
def test_plots_build_figures():
    import matplotlib
    matplotlib.use("Agg")
    from bedstruct.plot.heat import plot_temperature_history, plot_temperature_map
    res, m, shape = _haz(20.0, 10.5, n=(11, 11, 2), t_end=5e-4)
    fig, ax = plot_temperature_map(m, haz=shape)
    assert len(ax.images) == 1 and len(ax.patches) == 1
    fig2, ax2 = plot_temperature_history(res, particles=[0, 1])
    assert len(ax2.lines) == 3
    from matplotlib.figure import Figure
    ax3 = Figure().add_subplot()
    assert plot_temperature_map(m, ax=ax3, celsius=False) is ax3


# ------------------------------------------------------------ slow checks
@pytest.mark.slow
def test_large_random_network_cg_conserves_energy():
    rng = np.random.default_rng(9)
    n = 40 ** 3
    f, c = lattice((40, 40, 40), 20.0, 10.5)
    pos = f.positions + rng.normal(scale=0.1, size=f.positions.shape)
    f = Frame(pos, f.radii, box=f.box, units=f.units)
    c = Contacts(c.i, c.j, pos[c.j] - pos[c.i], c.radii_i, c.radii_j, n_particles=n)
    net = thermal_network(f, c)
    src = HemisphereSource((400e-6, 400e-6), diameter=100e-6)
    res = conduct_heat(net, t_end=5e-3, source=src, solver="cg", times=[5e-3])
    assert res.energy.relative_error < 1e-10
    # self-convergence: ten times tighter tolerance changes the field by about the tolerance
    fine = conduct_heat(net, t_end=5e-3, source=src, solver="cg", times=[5e-3], atol=0.1 * 1.28)
    assert fine.n_steps > res.n_steps
    assert np.abs(fine.final_temperature - res.final_temperature).max() < 2 * 1.28


def test_default_contacts_from_find_contacts_match_brute_force():
    pytest.importorskip("bedstruct.analysis.contacts")
    f, c = random_bed(n=200, seed=12)
    net_default = thermal_network(f)                # finds the contacts itself
    net_ref = thermal_network(f, c)
    key = lambda net: sorted(zip(np.minimum(net.i, net.j), np.maximum(net.i, net.j),  # noqa: E731
                                 np.round(net.conductance, 18)))
    got = [k for k in key(net_default) if k[2] > 0]
    ref = [k for k in key(net_ref) if k[2] > 0]
    assert len(got) == len(ref) > 50
    np.testing.assert_allclose([g[2] for g in got], [r[2] for r in ref], rtol=1e-9)


def test_haz_table_columns():
    yy, xx = np.mgrid[0:50, 0:50]
    vals = np.where((xx - 25) ** 2 + (yy - 25) ** 2 <= 100, 500.0, 300.0)
    m = TemperatureMap(vals, np.arange(50) + 0.5, np.arange(50) + 0.5, 1.0, np.array([0, 50, 0, 50.0]),
                       "top")
    from bedstruct.analysis.heat import haz_table
    t = haz_table([haz_shape(m, 400.0), haz_shape(m, 1e4)], labels=["a", "b"])
    assert {len(v) for v in t.values()} == {2}
    assert t["label"].tolist() == ["a", "b"] and t["roundness"][0] > 0.95 and np.isnan(t["roundness"][1])
    with pytest.raises(ValueError, match="labels"):
        haz_table([haz_shape(m, 400.0)], labels=[])


def test_conductivity_tensor_cg_path_matches_lu(monkeypatch):
    from bedstruct.analysis import _heat_maps
    f, c = random_bed(n=400, seed=8, box=(10, 10, 8))
    net = thermal_network(f, c)
    ref = conductivity_tensor(net)
    monkeypatch.setattr(_heat_maps, "_STEADY_DIRECT_MAX", 0)
    k = conductivity_tensor(net)
    np.testing.assert_allclose(k.tensor, ref.tensor, rtol=1e-7, atol=1e-9 * np.abs(ref.tensor).max())


def test_sphere_on_fixed_temperature_plate_relaxes_exponentially():
    r, h = 10.0, 0.2                                  # um; overlap with the plate plane z = 0
    f = Frame([[50.0, 50.0, r - h]], [r], box=[100, 100, 100], units=Units("micro"))
    net = thermal_network(f, Contacts([], [], np.zeros((0, 3)), [], [], n_particles=1))
    a = math.sqrt(2 * r * h - h * h) * 1e-6
    assert net.plate_conductance[0] == pytest.approx(2 * K_S * a, rel=1e-12)
    tau = net.capacity[0] / net.plate_conductance[0]
    times = np.array([0.0, 0.5, 1.0, 2.0]) * tau
    res = conduct_heat(net, t_end=2 * tau, times=times, initial_temperature=800.0,
                       plate_temperature=300.0, atol=1e-3)
    np.testing.assert_allclose(res.temperatures[:, 0], 300 + 500 * np.exp(-times / tau), atol=5e-3)
    # all the heat that left went into the plate
    np.testing.assert_allclose(res.energy.boundary, res.energy.stored, rtol=1e-12, atol=1e-20)
