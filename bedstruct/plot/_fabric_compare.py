"""Comparing fabric between regions or frames: density differences (3-D and
planar), the evolution of eigenvalues and anisotropies, and harmonic power.

Implementation module of :mod:`bedstruct.plot.fabric` (import from there).
"""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np

from ..analysis._fabric_tensors import _PLANES
from ..analysis.fabric import FabricTensors, RegionFabric, fabric_density, projected_density
from ..analysis.harmonics import HarmonicExpansion, sphere_grid
from ._fabric_roses import _draw_rose, _named_results, _normalise_kind
from ._mpl import figure_class

__all__ = ["plot_fabric_difference", "plot_fabric_differences", "plot_fabric_evolution",
           "plot_harmonic_power"]


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
    Figure = figure_class(three_d=True)
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
    Figure = figure_class(three_d=True)
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
    Figure = figure_class(three_d=True)
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


def plot_harmonic_power(expansions, *, x=None, degrees=None, relative=True, xlabel=None, labels=None,
                        ax=None):
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
    labels : sequence of str, optional
        Tick labels of the expansions (e.g. ``["start", "centre", "end"]``),
        one per expansion, placed at ``x``.
    ax : Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from bedstruct.analysis.harmonics import harmonic_expansion
    >>> e = harmonic_expansion([[1, 0, 0], [0, 1, 0], [0, 0, 1]], 6)
    >>> fig = plot_harmonic_power([e, e, e], labels=["start", "centre", "end"])
    >>> len(fig.axes[0].get_lines())   # l = 4 and l = 6 (l = 2 is zero for cubic data)
    2
    >>> [t.get_text() for t in fig.axes[0].get_xticklabels()]
    ['start', 'centre', 'end']
    """
    Figure = figure_class(three_d=True)
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
        if labels is not None:
            labels = [str(v) for v in labels]
            if len(labels) != len(items):
                raise ValueError(f"`labels` must have one entry per expansion ({len(items)}); got {len(labels)}")
            ax.set_xticks(list(x), labels)
        ax.legend(fontsize="small")
        ax.set_xlabel(xlabel or "region / frame")
    ax.set_ylabel(label)
    return fig
