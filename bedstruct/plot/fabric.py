"""Rose diagrams of contact-normal fabric: 3-D roses, planar roses, differences, evolution.

Every function builds on :class:`matplotlib.figure.Figure` (never pyplot),
never shows or saves, and returns the ``Figure`` it drew on (when axes are
given, their figure). Roses are drawn as the closed surface
:math:`r(n) = 4\\pi |f(n)|` (``relative=True``, so an isotropic sample is the
unit sphere) coloured by the signed value :math:`4\\pi f(n)`, with
:math:`f` from :func:`~bedstruct.analysis.fabric.fabric_density` (tensors)
or :func:`~bedstruct.analysis.harmonics.harmonic_density` (expansions).
"""

from __future__ import annotations

import math
from itertools import combinations
from typing import Sequence

import numpy as np

from ..analysis._fabric_tensors import _PLANES
from ..analysis.fabric import (FabricTensors, RegionFabric, fabric_tensors, fabric_density,
                               projected_density)
from ..analysis.harmonics import HarmonicExpansion, harmonic_density, sphere_grid

__all__ = [
    "plot_rose", "plot_rose_grid", "plot_rose_2d", "plot_fabric_difference",
    "plot_fabric_differences", "plot_fabric_evolution", "plot_harmonic_power", "rose_mesh",
]

_KIND_TITLES = {2: "rank 2", 4: "rank 4", "difference": "rank 4 - rank 2"}


def _mpl():
    try:
        import matplotlib  # noqa: F401
        from matplotlib.figure import Figure
        import mpl_toolkits.mplot3d  # noqa: F401  (registers the 3-D projection)
    except ImportError as exc:  # pragma: no cover
        raise ImportError("plotting needs matplotlib: pip install matplotlib") from exc
    return Figure


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
    r = np.abs(values)
    xyz = dirs * r[..., None]
    ax.plot_surface(xyz[..., 0], xyz[..., 1], xyz[..., 2], facecolors=cmap(norm(values)),
                    rstride=1, cstride=1, linewidth=0, antialiased=False, shade=False)
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
    Figure = _mpl()
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
    Figure = _mpl()
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
    line, so the two agree for a sample well described by its tensors.

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
    Figure = _mpl()
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
        hist, _ = np.histogram(alpha, bins=edges, weights=ww, density=True)
        ax.bar(0.5 * (edges[1:] + edges[:-1]), hist, width=np.diff(edges), color=color, alpha=0.55,
               edgecolor="white", linewidth=0.5, label="projected normals")
        if tensors is not None and rank is not None:
            p = projected_density(tensors, grid, plane=plane, rank=rank)
            ax.plot(grid, p, color=line_color, linewidth=1.8, label=f"rank-{rank} tensor")
        ax.set_title(plane)
        ax.set_yticklabels([])
    return fig


def _as_pair(first, second):
    for t in (first, second):
        if not isinstance(t, FabricTensors):
            raise TypeError(f"expected FabricTensors; got {type(t).__name__}")


def plot_fabric_difference(first, second, *, rank=4, views=("3d", "xy", "xz"), names=None,
                           axes=None, n_theta: int = 41, n_phi: int = 81, relative=True,
                           colorbar=True):
    """Change of contact-normal density from ``first`` to ``second`` (seed figures 23-24).

    Shows :math:`\\Delta f = f_{second} - f_{first}`: red where the second
    state has more contacts in a direction (gain), blue where it has fewer
    (loss). The 3-D view is the surface :math:`r = 4\\pi|\\Delta f|` coloured
    by the signed change; planar views (``"xy"``, ``"xz"``, ``"yz"``) show
    the change of the projected-angle density
    (:func:`~bedstruct.analysis.fabric.projected_density`), gain and loss
    lobes filled in red and blue.

    Parameters
    ----------
    first, second : FabricTensors
        E.g. two regions (start and centre) or two frames.
    rank : {4, 2}
        Tensor approximation used.
    views : sequence of {"3d", "xy", "xz", "yz"}
    names : (str, str), optional
        Names for the title, default ``("first", "second")``.
    axes : sequence of Axes, optional
        One per view (3-D axes for "3d", polar for planes).
    n_theta, n_phi, relative, colorbar
        As for :func:`plot_rose`.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from bedstruct.analysis.fabric import fabric_tensors
    >>> a = fabric_tensors([[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> b = fabric_tensors([[1, 0, 0], [1, 0.1, 0], [0, 0, 1]])
    >>> fig = plot_fabric_difference(a, b, n_theta=9, n_phi=17)
    >>> fig.axes[0].get_title()
    '3d: second - first'
    """
    _as_pair(first, second)
    Figure = _mpl()
    from matplotlib.cm import ScalarMappable
    from matplotlib import colors
    rank = _normalise_kind(rank)
    if rank == "difference":
        raise ValueError("`rank` must be 2 or 4")
    names = ("first", "second") if names is None else tuple(names)
    label = f"{names[1]} - {names[0]}"
    views = list(views)
    if axes is None:
        fig = Figure(figsize=(4.2 * len(views), 4))
        axes = [fig.add_subplot(1, len(views), k + 1,
                                projection="3d" if v == "3d" else "polar")
                for k, v in enumerate(views)]
    else:
        axes = list(axes)
        if len(axes) != len(views):
            raise ValueError(f"`axes` must hold one axes per view ({len(views)}); got {len(axes)}")
        fig = axes[0].figure
    scale = 4.0 * math.pi if relative else 1.0
    grid = np.linspace(0.0, 2.0 * math.pi, 361)
    for ax, view in zip(axes, views):
        if view == "3d":
            _, _, dirs = sphere_grid(n_theta, n_phi)
            val = scale * (fabric_density(second, dirs, rank=rank) - fabric_density(first, dirs, rank=rank))
            vmax = float(np.max(np.abs(val))) or 1.0
            import matplotlib
            cm = matplotlib.colormaps["RdBu_r"]
            nm = colors.Normalize(-vmax, vmax)
            _draw_rose(ax, dirs, val, cm, nm)
            if colorbar:
                sm = ScalarMappable(norm=nm, cmap=cm)
                sm.set_array(val)
                fig.colorbar(sm, ax=ax, shrink=0.6, pad=0.1,
                             label=r"$4\pi\,\Delta f$" if relative else r"$\Delta f$ [1/sr]")
        elif view in _PLANES:
            dp = (projected_density(second, grid, plane=view, rank=rank)
                  - projected_density(first, grid, plane=view, rank=rank))
            ax.fill(grid, np.clip(dp, 0, None), color="tab:red", alpha=0.7, label="gain")
            ax.fill(grid, np.clip(-dp, 0, None), color="tab:blue", alpha=0.7, label="loss")
            ax.set_yticklabels([])
        else:
            raise ValueError(f"`views` entries must be '3d', 'xy', 'xz' or 'yz'; got {view!r}")
        ax.set_title(f"{view}: {label}")
    return fig


def plot_fabric_differences(results, *, names=None, pairs=None, rank=4, views=("3d", "xy", "xz"),
                            n_theta: int = 31, n_phi: int = 61, relative=True):
    """Differences between every pair of regions or frames, one row per pair.

    With a :class:`~bedstruct.analysis.fabric.RegionFabric` of three
    regions the rows are start-centre, start-end and centre-end, each
    showing ``second - first`` (seed figures 23-24).

    Parameters
    ----------
    results : RegionFabric or sequence of FabricTensors
    names : sequence of str, optional
    pairs : sequence of (int, int), optional
        Index pairs ``(first, second)``; default all ``i < j``.
    rank, views, n_theta, n_phi, relative
        As for :func:`plot_fabric_difference`.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from bedstruct.analysis.fabric import fabric_tensors
    >>> t = [fabric_tensors(d) for d in ([[1, 0, 0]], [[0, 1, 0]], [[0, 0, 1]])]
    >>> fig = plot_fabric_differences(t, names=["start", "centre", "end"], n_theta=7, n_phi=13)
    >>> [a.get_title() for a in fig.axes if a.name == "polar"][:2]
    ['xy: centre - start', 'xz: centre - start']
    """
    Figure = _mpl()
    names, items = _named_results(results, names)
    pairs = list(combinations(range(len(items)), 2)) if pairs is None else [tuple(p) for p in pairs]
    views = list(views)
    fig = Figure(figsize=(4.2 * len(views), 3.8 * max(1, len(pairs))))
    fig.subplots_adjust(hspace=0.4, wspace=0.3)
    for r, (i, j) in enumerate(pairs):
        axes = [fig.add_subplot(len(pairs), len(views), r * len(views) + k + 1,
                                projection="3d" if v == "3d" else "polar")
                for k, v in enumerate(views)]
        if items[i] is None or items[j] is None:
            axes[0].set_title(f"{names[j]} - {names[i]}: no contacts")
            continue
        plot_fabric_difference(items[i], items[j], rank=rank, views=views, names=(names[i], names[j]),
                               axes=axes, n_theta=n_theta, n_phi=n_phi, relative=relative)
    return fig


def plot_fabric_evolution(results, *, x=None, xlabel=None, axes=None):
    """Eigenvalues of ``N2`` and anisotropies along the bed or over frames.

    Parameters
    ----------
    results : RegionFabric or sequence of FabricTensors (None allowed)
        One entry per region or frame.
    x : (K,) array_like, optional
        Abscissa; default the region centres (RegionFabric) or 0..K-1.
    xlabel : str, optional
    axes : (Axes, Axes), optional
        Top: eigenvalues :math:`\\lambda_1 \\ge \\lambda_2 \\ge \\lambda_3`; bottom:
        anisotropy :math:`\\sqrt{3/2\\,D_{ij}D_{ij}}` and
        :math:`\\|D_{ijkl}\\|`.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from bedstruct.analysis.fabric import fabric_tensors
    >>> t = [fabric_tensors(d) for d in ([[1, 0, 0], [0, 1, 0]], [[1, 0, 0]])]
    >>> fig = plot_fabric_evolution(t)
    >>> len(fig.axes[0].get_lines()), len(fig.axes[1].get_lines())  # + the 1/3 guide line
    (4, 2)
    """
    Figure = _mpl()
    if isinstance(results, RegionFabric):
        items = list(results.tensors)
        if x is None:
            x = 0.5 * (results.edges[1:] + results.edges[:-1])
            xlabel = xlabel or f"position along {'xyz'[results.axis]}"
    else:
        items = list(results)
    x = np.arange(len(items)) if x is None else np.asarray(x, dtype=np.float64)
    if x.shape != (len(items),):
        raise ValueError(f"`x` must have one value per result ({len(items)}); got {x.shape}")
    if axes is None:
        fig = Figure(figsize=(6, 5.5))
        axes = fig.subplots(2, 1, sharex=True)
    else:
        axes = list(axes)
        fig = axes[0].figure
    eig = np.array([np.full(3, np.nan) if t is None else t.eigenvalues for t in items]).reshape(-1, 3)
    for k in range(3):
        axes[0].plot(x, eig[:, k], marker="o", label=rf"$\lambda_{k + 1}(N_{{ij}})$")
    axes[0].axhline(1.0 / 3.0, color="0.6", linestyle=":", linewidth=1)
    axes[0].set_ylabel("eigenvalue")
    axes[0].legend(fontsize="small")
    a2 = np.array([np.nan if t is None else t.anisotropy for t in items])
    a4 = np.array([np.nan if t is None else t.anisotropy_rank4 for t in items])
    axes[1].plot(x, a2, marker="o", label=r"$\sqrt{3/2\,D_{ij}D_{ij}}$")
    axes[1].plot(x, a4, marker="s", label=r"$\|D_{ijkl}\|$")
    axes[1].set_ylabel("anisotropy")
    axes[1].legend(fontsize="small")
    axes[1].set_xlabel(xlabel or "region / frame")
    return fig


def plot_harmonic_power(expansions, *, x=None, degrees=None, relative=True, xlabel=None, ax=None):
    """Rotation-invariant harmonic power per degree, for one or several expansions.

    One expansion: bars of :math:`P_l` against :math:`l`. Several (regions
    or frames): one line per degree against ``x``.

    Parameters
    ----------
    expansions : HarmonicExpansion, sequence of them, or RegionFabric
        A RegionFabric must carry expansions (``region_fabric(..., l_max=...)``);
        its slab centres are the abscissa.
    x : (K,) array_like, optional
        Abscissa for several expansions (default 0..K-1).
    degrees : sequence of int, optional
        Degrees to show (default every non-zero degree with power, l >= 1).
    relative : bool
        Plot :math:`P_l / P_0` (default) instead of :math:`P_l`.
    xlabel : str, optional
    ax : Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from bedstruct.analysis.harmonics import harmonic_expansion
    >>> e = harmonic_expansion([[1, 0, 0], [0, 1, 0], [0, 0, 1]], 6)
    >>> fig = plot_harmonic_power([e, e, e])
    >>> len(fig.axes[0].get_lines())   # l = 4 and l = 6 (l = 2 is zero for cubic data)
    2
    """
    Figure = _mpl()
    if isinstance(expansions, RegionFabric):
        if expansions.expansions is None:
            raise ValueError("this RegionFabric has no expansions; call region_fabric(..., l_max=8)")
        if x is None:
            x = 0.5 * (expansions.edges[1:] + expansions.edges[:-1])
            xlabel = xlabel or f"position along {'xyz'[expansions.axis]}"
        keep = [k for k, e in enumerate(expansions.expansions) if e is not None]
        x = np.asarray(x, dtype=np.float64)[keep]
        expansions = [expansions.expansions[k] for k in keep]
    single = isinstance(expansions, HarmonicExpansion)
    items = [expansions] if single else list(expansions)
    if not items:
        raise ValueError("`expansions` is empty")
    if ax is None:
        fig = Figure(figsize=(6, 4))
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    l_max = min(e.l_max for e in items)
    p = np.array([e.power[:l_max + 1] for e in items])
    if relative:
        p = p / p[:, :1]
    if degrees is None:
        degrees = [l for l in range(1, l_max + 1) if np.any(p[:, l] > 1e-14 * p[:, 0].max())]
    label = r"$P_l / P_0$" if relative else r"$P_l$"
    if single:
        ax.bar(degrees, p[0, degrees], color="C0")
        ax.set_xlabel("degree l")
        ax.set_xticks(list(degrees))
    else:
        x = np.arange(len(items)) if x is None else np.asarray(x, dtype=np.float64)
        if x.shape != (len(items),):
            raise ValueError(f"`x` must have one value per expansion ({len(items)}); got {x.shape}")
        for l in degrees:
            ax.plot(x, p[:, l], marker="o", label=f"l = {l}")
        ax.legend(fontsize="small")
        ax.set_xlabel(xlabel or "region / frame")
    ax.set_ylabel(label)
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
