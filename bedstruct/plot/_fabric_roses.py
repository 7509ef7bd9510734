"""Rose diagrams of one fabric: 3-D roses (alone, in a grid, as a pyvista mesh)
and planar roses of projected normals, with the helpers that the comparison
figures share.

Implementation module of :mod:`bedstruct.plot.fabric` (import from there).
"""

from __future__ import annotations

import math

import numpy as np

from ..analysis._fabric_tensors import _PLANES
from ..analysis.fabric import (FabricTensors, RegionFabric, fabric_tensors, fabric_density,
                               projected_density)
from ..analysis.harmonics import HarmonicExpansion, harmonic_density, sphere_grid
from ._mpl import figure_class

__all__ = ["plot_rose", "plot_rose_grid", "plot_rose_2d", "rose_mesh"]

_KIND_TITLES = {2: "rank 2", 4: "rank 4", "difference": "rank 4 - rank 2"}


def _normalise_kind(kind):
    if kind in (None, 4, "4", "rank4"):
        return 4
    if kind in (2, "2", "rank2"):
        return 2
    if kind in ("difference", "diff"):
        return "difference"
    raise ValueError(f"`kind` must be 2, 4 or 'difference'; got {kind!r}")


def _density_function(source, kind):
    """A function directions (..., 3) -> f (...) in 1/sr for tensors, expansions or callables."""
    if isinstance(source, FabricTensors):
        k = _normalise_kind(kind)
        return lambda d: fabric_density(source, d, rank=k)
    if isinstance(source, HarmonicExpansion):
        if kind is None:
            return lambda d: harmonic_density(source, d)
        if kind in ("difference", "diff"):
            return lambda d: harmonic_density(source, d, l_max=4) - harmonic_density(source, d, l_max=2)
        if isinstance(kind, (int, np.integer)) and kind >= 0:
            return lambda d: harmonic_density(source, d, l_max=int(kind))
        raise ValueError(f"`kind` for an expansion must be None, a degree or 'difference'; got {kind!r}")
    if callable(source):
        return source
    raise TypeError(f"expected FabricTensors, HarmonicExpansion or a callable; "
                    f"got {type(source).__name__}")


def _rose_values(source, kind, n_theta, n_phi, relative):
    _, _, dirs = sphere_grid(n_theta, n_phi)
    f = np.asarray(_density_function(source, kind)(dirs), dtype=np.float64)
    val = f * (4.0 * math.pi) if relative else f
    return dirs, val


def _diverging(kind, values, cmap, norm):
    from matplotlib import colors
    signed = kind in ("difference", "diff") or float(np.min(values)) < 0
    if cmap is None:
        cmap = "RdBu_r" if signed else "viridis"
    if norm is None:
        if signed:
            vmax = float(np.max(np.abs(values))) or 1.0
            norm = colors.Normalize(-vmax, vmax)
        else:
            lo, hi = float(np.min(values)), float(np.max(values))
            norm = colors.Normalize(lo, hi if hi > lo else lo + 1e-12)
    import matplotlib
    return matplotlib.colormaps[cmap] if isinstance(cmap, str) else cmap, norm


def _draw_rose(ax, dirs, values, cmap, norm):
    """The surface r = |values| over the latitude-longitude grid ``dirs``, one quadrilateral
    per grid cell coloured by the value at its first corner, as one collection."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    r = np.abs(values)
    xyz = dirs * r[..., None]
    quads = np.stack([xyz[:-1, :-1], xyz[:-1, 1:], xyz[1:, 1:], xyz[1:, :-1]], axis=2).reshape(-1, 4, 3)
    colours = cmap(norm(values[:-1, :-1])).reshape(-1, 4)
    ax.add_collection3d(Poly3DCollection(quads, facecolors=colours, edgecolors=colours, linewidth=0,
                                         antialiased=False, shade=False), autolim=False)
    lim = float(r.max()) or 1.0
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_zlim(-lim, lim)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")


def plot_rose(source, *, kind=None, ax=None, n_theta: int = 41, n_phi: int = 81, relative=True,
              cmap=None, norm=None, colorbar=True, title=None):
    """3-D rose diagram: the closed surface :math:`r(n) = |f(n)|` coloured by :math:`f(n)`.

    Parameters
    ----------
    source : FabricTensors, HarmonicExpansion or callable
        The distribution. A callable maps directions (..., 3) to densities.
    kind : {None, 4, 2, "difference"} or int
        For tensors: the rank-4 (default) or rank-2 approximation, or their
        difference :math:`D_{ijkl}n_in_jn_kn_l / (4\\pi)` (seed figure 22c).
        For expansions: the truncation degree (default all degrees) or
        ``"difference"`` (degree 4 minus degree 2).
    ax : mpl_toolkits.mplot3d.Axes3D, optional
        Axes to draw on (3-D projection); default a new Figure.
    n_theta, n_phi : int
        Resolution of the latitude-longitude grid.
    relative : bool
        Plot :math:`4\\pi f` (1 for an isotropic sample; default) instead of
        :math:`f` in 1/sr.
    cmap, norm : optional
        Colour map and normalisation; default viridis, or a symmetric
        RdBu_r when values change sign (difference).
    colorbar : bool
        Add a colour bar.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from bedstruct.analysis.fabric import fabric_tensors
    >>> fig = plot_rose(fabric_tensors([[1, 0, 0], [0, 1, 0], [0, 0, 1]]), n_theta=9, n_phi=17)
    >>> len(fig.axes)   # the rose and its colour bar
    2
    """
    Figure = figure_class(three_d=True)
    from matplotlib.cm import ScalarMappable
    if ax is None:
        fig = Figure(figsize=(5.5, 5))
        ax = fig.add_subplot(projection="3d")
    else:
        if getattr(ax, "name", "") != "3d":
            raise ValueError("`ax` must be a 3-D axes (add_subplot(projection='3d'))")
        fig = ax.figure
    dirs, values = _rose_values(source, kind, n_theta, n_phi, relative)
    cm, nm = _diverging(kind, values, cmap, norm)
    _draw_rose(ax, dirs, values, cm, nm)
    if title is None and isinstance(source, FabricTensors):
        title = _KIND_TITLES[_normalise_kind(kind)]
    if title:
        ax.set_title(title)
    if colorbar:
        sm = ScalarMappable(norm=nm, cmap=cm)
        sm.set_array(values)
        fig.colorbar(sm, ax=ax, shrink=0.6, pad=0.1,
                     label=r"$4\pi f(n)$" if relative else r"$f(n)$ [1/sr]")
    return fig


def plot_rose_grid(results, *, names=None, kinds=(2, 4, "difference"), n_theta: int = 31,
                   n_phi: int = 61, relative=True, share_colors=True):
    """Grid of 3-D roses: one row per result, one column per kind (seed figure 22).

    Parameters
    ----------
    results : RegionFabric or sequence of FabricTensors
        E.g. the start, centre and end regions.
    names : sequence of str, optional
        Row names (default the regions' names or "0", "1", ...).
    kinds : sequence
        Columns, each as ``kind`` of :func:`plot_rose`.
    n_theta, n_phi, relative
        As for :func:`plot_rose`.
    share_colors : bool
        One colour scale per column (default), so rows compare directly.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from bedstruct.analysis.fabric import fabric_tensors
    >>> t = fabric_tensors([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> fig = plot_rose_grid([t, t], n_theta=7, n_phi=13)
    >>> len([a for a in fig.axes if a.name == "3d"])
    6
    """
    Figure = figure_class(three_d=True)
    names, items = _named_results(results, names)
    kinds = list(kinds)
    norms = [None] * len(kinds)
    if share_colors:
        for c, kind in enumerate(kinds):
            vals = [_rose_values(t, kind, n_theta, n_phi, relative)[1] for t in items if t is not None]
            if vals:
                _, norms[c] = _diverging(kind, np.concatenate([v.ravel() for v in vals]), None, None)
    fig = Figure(figsize=(3.6 * len(kinds), 3.4 * len(items)))
    fig.subplots_adjust(hspace=0.3, wspace=0.3)
    for r, (name, t) in enumerate(zip(names, items)):
        for c, kind in enumerate(kinds):
            ax = fig.add_subplot(len(items), len(kinds), r * len(kinds) + c + 1, projection="3d")
            if t is None:
                ax.set_title(f"{name}: no contacts")
                continue
            plot_rose(t, kind=kind, ax=ax, n_theta=n_theta, n_phi=n_phi, relative=relative,
                      norm=norms[c], colorbar=True,
                      title=f"{name}: {_KIND_TITLES[_normalise_kind(kind)]}")
    return fig


def _named_results(results, names):
    if isinstance(results, RegionFabric):
        items = list(results.tensors)
        default = list(results.names)
    elif isinstance(results, (FabricTensors, HarmonicExpansion)):
        items = [results]
        default = ["0"]
    else:
        items = list(results)
        default = [str(k) for k in range(len(items))]
    names = default if names is None else [str(n) for n in names]
    if len(names) != len(items):
        raise ValueError(f"`names` must have one entry per result ({len(items)}); got {len(names)}")
    return names, items


def _projected_angles(normals, plane, weights):
    u, v, _ = _PLANES[plane]
    nu, nv = normals[:, u], normals[:, v]
    keep = (nu * nu + nv * nv) > 0
    alpha = np.arctan2(nv[keep], nu[keep])
    alpha = np.concatenate([alpha, alpha + math.pi]) % (2.0 * math.pi)   # n and -n
    w = None if weights is None else np.concatenate([weights[keep], weights[keep]])
    return alpha, w


def plot_rose_2d(normals, *, weights=None, tensors=None, planes=("xy", "xz", "yz"), bins: int = 36,
                 rank=4, axes=None, color="C0", line_color="C3"):
    """Planar roses: polar histograms of normals projected on coordinate planes.

    The histogram is the density of the projected angle :math:`\\alpha`
    (1/radian, both ``n`` and ``-n`` counted); the tensor approximation's
    density of the same angle,
    :func:`~bedstruct.analysis.fabric.projected_density`, is overlaid as a
    line, so the two agree for a sample well described by its tensors. A
    plane on which no normal projects (every one perpendicular to it) gets
    an empty panel that says so.

    Parameters
    ----------
    normals : (M, 3) array_like of float, or Contacts
        Contact normals.
    weights : (M,) array_like or str, optional
        As for :func:`~bedstruct.analysis.fabric.fabric_tensors`.
    tensors : FabricTensors, optional
        Tensor approximation to overlay; default computed from the normals
        (None and ``rank=None`` draws no line).
    planes : sequence of {"xy", "xz", "yz"}
        One polar panel each; angles measured from the first named axis.
    bins : int
        Angular bins over the full circle.
    rank : {4, 2, None}
        Approximation overlaid.
    axes : sequence of polar Axes, optional
        One per plane; default a new Figure with a row of panels.
    color, line_color : colours
        Bars and overlay line.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = plot_rose_2d([[1, 0, 0], [1, 1, 0], [0, 0, 1]], bins=8)
    >>> [a.get_title() for a in fig.axes]
    ['xy', 'xz', 'yz']
    """
    from ..analysis._fabric_tensors import _as_directions, _resolve_weights
    Figure = figure_class(three_d=True)
    arr = _as_directions(normals)
    w = _resolve_weights(normals, weights, arr.shape[0])
    norm = np.sqrt(np.einsum("ij,ij->i", arr, arr))
    ok = norm > 0
    arr = arr[ok] / norm[ok, None]
    w = None if w is None else w[ok]
    if tensors is None and rank is not None:
        tensors = fabric_tensors(arr, w)
    planes = list(planes)
    for p in planes:
        if p not in _PLANES:
            raise ValueError(f"`planes` entries must be among {sorted(_PLANES)}; got {p!r}")
    if axes is None:
        fig = Figure(figsize=(4.2 * len(planes), 4))
        fig.subplots_adjust(wspace=0.35)
        axes = [fig.add_subplot(1, len(planes), k + 1, projection="polar") for k in range(len(planes))]
    else:
        axes = list(axes)
        if len(axes) != len(planes):
            raise ValueError(f"`axes` must hold one polar axes per plane ({len(planes)}); got {len(axes)}")
        fig = axes[0].figure
    edges = np.linspace(0.0, 2.0 * math.pi, int(bins) + 1)
    grid = np.linspace(0.0, 2.0 * math.pi, 361)
    for ax, plane in zip(axes, planes):
        alpha, ww = _projected_angles(arr, plane, w)
        total = float(alpha.size if ww is None else np.sum(ww))
        ax.set_title(plane)
        ax.set_yticklabels([])
        if not total > 0:      # every normal perpendicular to the plane: nothing to draw
            ax.text(0.5, 0.5, "no normal projects\non this plane", transform=ax.transAxes,
                    ha="center", va="center")
            continue
        hist, _ = np.histogram(alpha, bins=edges, weights=ww, density=True)
        ax.bar(0.5 * (edges[1:] + edges[:-1]), hist, width=np.diff(edges), color=color, alpha=0.55,
               edgecolor="white", linewidth=0.5, label="projected normals")
        if tensors is not None and rank is not None:
            p = projected_density(tensors, grid, plane=plane, rank=rank)
            ax.plot(grid, p, color=line_color, linewidth=1.8, label=f"rank-{rank} tensor")
    return fig


def rose_mesh(source, *, kind=None, n_theta: int = 61, n_phi: int = 121, relative=True):
    """The 3-D rose as a :class:`pyvista.PolyData` for interactive or VTK use.

    Points lie at :math:`r(n) = |4\\pi f(n)|` (or :math:`|f|` with
    ``relative=False``) along a latitude-longitude grid; point data ``"f"``
    holds the signed value for colouring (``mesh.plot(scalars="f")``) and
    ``mesh.save("rose.vtp")`` writes it for ParaView.

    Parameters
    ----------
    source, kind, n_theta, n_phi, relative
        As for :func:`plot_rose`.

    Returns
    -------
    pyvista.PolyData
        Quadrilateral faces, ``n_theta * n_phi`` points.

    Examples
    --------
    >>> from bedstruct.analysis.fabric import fabric_tensors
    >>> mesh = rose_mesh(fabric_tensors([[1, 0, 0], [0, 1, 0], [0, 0, 1]]), n_theta=5, n_phi=9)
    >>> mesh.n_points, mesh.n_cells
    (45, 32)
    """
    try:
        import pyvista as pv
    except ImportError as exc:  # pragma: no cover
        raise ImportError("rose_mesh needs pyvista: pip install pyvista") from exc
    dirs, val = _rose_values(source, kind, n_theta, n_phi, relative)
    pts = (dirs * np.abs(val)[..., None]).reshape(-1, 3)
    idx = np.arange(n_theta * n_phi).reshape(n_theta, n_phi)
    quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=-1).reshape(-1, 4)
    faces = np.hstack([np.full((quads.shape[0], 1), 4), quads]).ravel()
    mesh = pv.PolyData(pts, faces)
    mesh.point_data["f"] = val.reshape(-1)
    return mesh
