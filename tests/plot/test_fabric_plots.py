"""Rose diagrams and fabric figures (Agg backend): artists carry the right data."""

from __future__ import annotations

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from matplotlib.figure import Figure  # noqa: E402

import bedstruct  # noqa: E402
from bedstruct import Box, Contacts, Frame  # noqa: E402
from bedstruct.analysis.fabric import (  # noqa: E402
    fabric_density, fabric_tensors, projected_density, region_fabric, sample_directions,
)
from bedstruct.analysis.harmonics import harmonic_expansion, sphere_grid  # noqa: E402
from bedstruct.plot.fabric import (  # noqa: E402
    plot_fabric_difference, plot_fabric_differences, plot_fabric_evolution, plot_harmonic_power,
    plot_rose, plot_rose_2d, plot_rose_grid, rose_mesh,
)

D2_TI = np.diag([2.0, -1.0, -1.0]) * 2.5 / 3      # transversely isotropic about x: a dumbbell


@pytest.fixture(scope="module")
def ti_sample():
    x = sample_directions(20_000, D2=D2_TI, rng=1)
    return x, fabric_tensors(x)


@pytest.fixture(scope="module")
def iso_sample():
    x = sample_directions(20_000, rng=2)
    return x, fabric_tensors(x)


def _render(fig, tmp_path, name):
    path = tmp_path / f"{name}.png"
    fig.savefig(path, dpi=40)
    assert path.stat().st_size > 1000


def test_plot_rose_dumbbell(ti_sample, tmp_path):
    _, t = ti_sample
    fig = plot_rose(t, kind=2, n_theta=21, n_phi=41)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert ax.name == "3d" and ax.get_title() == "rank 2"
    assert len(ax.collections) == 1
    # the surface extends to 4 pi f(x) along x (the dumbbell's long axis) and less along y, z
    fx = 4 * np.pi * fabric_density(t, [1, 0, 0], rank=2)
    fy = 4 * np.pi * fabric_density(t, [0, 1, 0], rank=2)
    assert ax.get_xlim()[1] == pytest.approx(fx, rel=1e-3)
    assert fx > 2.3 and fy < 0.3
    assert len(fig.axes) == 2            # colour bar
    assert bedstruct.plot_rose is plot_rose
    _render(fig, tmp_path, "rose")


def test_rose_cells_lie_on_the_rose_and_are_coloured_by_its_value(ti_sample):
    _, t = ti_sample
    fig = plot_rose(t, kind=4, n_theta=13, n_phi=25)
    (surface,) = fig.axes[0].collections
    _, _, d = sphere_grid(13, 25)
    f = 4 * np.pi * fabric_density(t, d, rank=4)
    on_rose = d * np.abs(f)[..., None]
    corners = surface._faces                   # (cells, 4, 3): the quadrilaterals as drawn
    assert corners.shape == (12 * 24, 4, 3)
    # cell (a, b) has the grid points (a, b), (a, b+1), (a+1, b+1), (a+1, b) as corners
    for k, (da, db) in enumerate([(0, 0), (0, 1), (1, 1), (1, 0)]):
        expected = on_rose[da:da + 12, db:db + 24].reshape(-1, 3)
        np.testing.assert_allclose(corners[:, k], expected, rtol=1e-12, atol=1e-15)
    # coloured by the value at the first corner on viridis over the range of the values (the
    # colours in cell order; get_facecolor gives them sorted by depth for one view)
    from matplotlib import colormaps, colors
    expected = colormaps["viridis"](colors.Normalize(f.min(), f.max())(f[:-1, :-1].ravel()))
    np.testing.assert_allclose(surface._facecolor3d, expected, atol=1e-12)


def test_plot_rose_difference_uses_symmetric_diverging_colours(ti_sample):
    _, t = ti_sample
    fig = plot_rose(t, kind="difference", n_theta=11, n_phi=21)
    cbar_ax = fig.axes[1]
    lo, hi = cbar_ax.get_ylim()
    assert lo == pytest.approx(-hi)
    assert fig.axes[0].get_title() == "rank 4 - rank 2"


def test_plot_rose_accepts_expansions_callables_and_checks_axes(ti_sample):
    x, t = ti_sample
    e = harmonic_expansion(x, 8)
    for kind in (None, 2, 4, "difference"):
        assert isinstance(plot_rose(e, kind=kind, n_theta=7, n_phi=13, colorbar=False), Figure)
    fig = plot_rose(lambda d: np.full(d.shape[:-1], 1 / (4 * np.pi)), n_theta=7, n_phi=13)
    assert fig.axes[0].get_xlim()[1] == pytest.approx(1.0)     # unit sphere
    flat = Figure().add_subplot()
    with pytest.raises(ValueError, match="3-D"):
        plot_rose(t, ax=flat)
    with pytest.raises(TypeError):
        plot_rose("not a distribution")
    with pytest.raises(ValueError, match="kind"):
        plot_rose(t, kind=3)
    # drawing into given axes returns their figure
    fig = Figure()
    ax = fig.add_subplot(projection="3d")
    assert plot_rose(t, ax=ax, n_theta=7, n_phi=13, colorbar=False) is fig


def test_plot_rose_grid_layout(ti_sample, iso_sample):
    fig = plot_rose_grid([iso_sample[1], ti_sample[1]], names=["start", "end"], n_theta=7, n_phi=13)
    titles = [a.get_title() for a in fig.axes if a.name == "3d"]
    assert titles == ["start: rank 2", "start: rank 4", "start: rank 4 - rank 2",
                      "end: rank 2", "end: rank 4", "end: rank 4 - rank 2"]


def test_plot_rose_2d_bars_and_overlay(ti_sample, tmp_path):
    x, t = ti_sample
    fig = plot_rose_2d(x, bins=24)
    assert [a.get_title() for a in fig.axes] == ["xy", "xz", "yz"]
    for ax, (u, v), plane in zip(fig.axes, [(0, 1), (0, 2), (1, 2)], ["xy", "xz", "yz"]):
        heights = np.array([p.get_height() for p in ax.patches])
        ang = np.concatenate([np.arctan2(x[:, v], x[:, u]), np.arctan2(-x[:, v], -x[:, u])]) % (2 * np.pi)
        ref, _ = np.histogram(ang, bins=24, range=(0, 2 * np.pi), density=True)
        np.testing.assert_allclose(heights, ref, rtol=1e-10)
        line = ax.get_lines()[0]
        a, p = line.get_data()
        np.testing.assert_allclose(p, projected_density(t, a, plane=plane), rtol=1e-12)
    # the dumbbell about x: in xy the density peaks at 0 and pi, in yz it is flat
    xy = fig.axes[0].get_lines()[0].get_ydata()
    yz = fig.axes[2].get_lines()[0].get_ydata()
    assert xy.max() / xy.min() > 5 and yz.max() / yz.min() < 1.05
    _render(fig, tmp_path, "rose2d")
    # weights from a Contacts object, no overlay
    c = Contacts(i=[0, 1], j=[1, 2], branch=[[1.0, 0, 0], [0, 1.0, 0]], radii_i=[0.6, 0.6],
                 radii_j=[0.6, 0.6])
    fig = plot_rose_2d(c, weights="contact_area", rank=None, planes=("xy",))
    assert len(fig.axes[0].get_lines()) == 0
    with pytest.raises(ValueError, match="planes"):
        plot_rose_2d(x, planes=("xw",))


def test_plot_fabric_difference_gain_and_loss(ti_sample, iso_sample, tmp_path):
    _, t = ti_sample
    _, t0 = iso_sample
    fig = plot_fabric_difference(t0, t, names=("start", "end"), n_theta=11, n_phi=21)
    assert fig.axes[0].name == "3d" and fig.axes[0].get_title() == "3d: end - start"
    polar = [a for a in fig.axes if a.name == "polar"]
    assert [a.get_title() for a in polar] == ["xy: end - start", "xz: end - start"]
    gain, loss = polar[0].patches[:2]
    assert gain.get_label() == "gain" and loss.get_label() == "loss"
    assert matplotlib.colors.same_color(gain.get_facecolor()[:3], "tab:red")
    # gain along x (angle 0), loss along y (angle pi/2) for a dumbbell about x
    vg = gain.get_xy()
    vl = loss.get_xy()
    r_gain_0 = vg[np.argmin(np.abs(vg[:, 0] - 0.0)), 1]
    r_loss_90 = vl[np.argmin(np.abs(vl[:, 0] - np.pi / 2)), 1]
    dp0 = projected_density(t, 0.0) - projected_density(t0, 0.0)
    dp90 = projected_density(t, np.pi / 2) - projected_density(t0, np.pi / 2)
    assert r_gain_0 == pytest.approx(dp0, rel=1e-9) and dp0 > 0
    assert r_loss_90 == pytest.approx(-dp90, rel=1e-9) and dp90 < 0
    _render(fig, tmp_path, "difference")
    with pytest.raises(TypeError):
        plot_fabric_difference(t0, "x")
    with pytest.raises(ValueError, match="views"):
        plot_fabric_difference(t0, t, views=("top",))


def _bed():
    rng = np.random.default_rng(5)
    n = 400
    pos = rng.uniform([0, 0, 0], [30, 5, 5], size=(n, 3))
    f = Frame(pos, np.full(n, 0.5), box=Box([0, 0, 0], [30, 5, 5], boundary="ff ff ff"))
    i = rng.integers(0, n, 2000)
    j = (i + rng.integers(1, n, 2000)) % n
    br = rng.normal(size=(2000, 3)) * np.where(pos[i, :1] < 10, [3, 1, 1], [1, 1, 1])
    return f, Contacts(i=i, j=j, branch=br, radii_i=np.full(2000, 0.5), radii_j=np.full(2000, 0.5),
                       n_particles=n)


def test_region_figures_and_evolution(tmp_path):
    f, c = _bed()
    r = region_fabric(c, f)
    fig = plot_fabric_differences(r, n_theta=7, n_phi=13)
    titles = [a.get_title() for a in fig.axes if a.name == "3d"]
    assert titles == ["3d: centre - start", "3d: end - start", "3d: end - centre"]
    fig = plot_fabric_evolution(r)
    top, bottom = fig.axes
    x = top.get_lines()[0].get_xdata()
    np.testing.assert_allclose(x, 0.5 * (r.edges[1:] + r.edges[:-1]))
    np.testing.assert_allclose(top.get_lines()[0].get_ydata(), [t.eigenvalues[0] for t in r.tensors])
    np.testing.assert_allclose(bottom.get_lines()[0].get_ydata(), [t.anisotropy for t in r.tensors])
    assert r["start"].anisotropy > r["end"].anisotropy    # the start region was made anisotropic
    assert "along x" in bottom.get_xlabel()
    _render(fig, tmp_path, "evolution")
    r8 = region_fabric(c, f, l_max=8, n_regions=4)
    fig = plot_harmonic_power(r8, degrees=[2, 4])
    line = fig.axes[0].get_lines()[0]
    np.testing.assert_allclose(line.get_xdata(), 0.5 * (r8.edges[1:] + r8.edges[:-1]))
    np.testing.assert_allclose(line.get_ydata(), [e.power[2] / e.power[0] for e in r8.expansions])
    with pytest.raises(ValueError, match="l_max"):
        plot_harmonic_power(r)


def test_plot_harmonic_power(ti_sample, iso_sample):
    e1 = harmonic_expansion(ti_sample[0], 6)
    e0 = harmonic_expansion(iso_sample[0], 6)
    fig = plot_harmonic_power(e1, degrees=[2, 4, 6])
    bars = fig.axes[0].patches
    np.testing.assert_allclose([b.get_height() for b in bars], e1.power[[2, 4, 6]] / e1.power[0])
    fig = plot_harmonic_power([e0, e1], x=[0.0, 1.0], degrees=[2, 4])
    lines = fig.axes[0].get_lines()
    assert [ln.get_label() for ln in lines] == ["l = 2", "l = 4"]
    np.testing.assert_allclose(lines[0].get_ydata(), [e0.power[2] / e0.power[0], e1.power[2] / e1.power[0]])
    with pytest.raises(ValueError):
        plot_harmonic_power([])


def test_rose_mesh_points_lie_on_the_rose(ti_sample):
    pv = pytest.importorskip("pyvista")
    _, t = ti_sample
    mesh = rose_mesh(t, kind=4, n_theta=9, n_phi=17)
    assert isinstance(mesh, pv.PolyData)
    assert mesh.n_points == 9 * 17 and mesh.n_cells == 8 * 16
    _, _, d = sphere_grid(9, 17)
    f = 4 * np.pi * fabric_density(t, d.reshape(-1, 3))
    np.testing.assert_allclose(mesh.point_data["f"], f, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(mesh.points, axis=1), np.abs(f), rtol=1e-6)


def test_plot_rose_2d_leaves_a_plane_with_no_projected_normal_empty(tmp_path):
    import warnings
    normals = np.tile([0.0, 0.0, 1.0], (30, 1))        # every normal perpendicular to xy
    with warnings.catch_warnings():
        warnings.simplefilter("error")                  # no division by a zero total
        fig = plot_rose_2d(normals, bins=12)
        fig.savefig(tmp_path / "rose.png")
    xy, xz, yz = fig.axes
    assert not xy.patches and "no normal" in xy.texts[0].get_text()
    for ax in (xz, yz):
        heights = [p.get_height() for p in ax.patches]
        assert len(heights) == 12 and np.all(np.isfinite(heights))
        # every projection along +-z: all the density in the bins at 90 and 270 degrees
        assert sum(h > 0 for h in heights) == 2
