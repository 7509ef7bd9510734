"""Figures of scalar bed metrics: German's law, PSDs and segregation, packing and
coordination along the bed, height maps, and angles of repose.

Every function takes ``ax=None``; it draws on the given Axes and returns it, or
creates a :class:`matplotlib.figure.Figure` (never pyplot) and returns
``(fig, ax)``. Nothing is shown or saved.
"""

from __future__ import annotations

import numpy as np

from ._mpl import figure_class

__all__ = ["plot_german", "plot_psd", "plot_psd_along_bed", "plot_packing_profile",
           "plot_coordination", "plot_height_map", "plot_repose", "plot_repose_series", "plot_rdf",
           "plot_local_packing"]


def _figure(ax, nrows=1, **kw):
    Figure = figure_class()
    if ax is not None:
        return None, ax
    fig = Figure(figsize=kw.pop("figsize", (6.0, 4.0 if nrows == 1 else 6.0)), layout="constrained")
    if nrows == 1:
        return fig, fig.add_subplot(1, 1, 1)
    axes = fig.subplots(nrows, 1, sharex=True, gridspec_kw=kw.pop("gridspec_kw", None))
    return fig, axes


def _ret(fig, ax):
    return ax if fig is None else (fig, ax)


def plot_german(fit, *, ax=None, residual_ax=None, label: str = "data"):
    """Measured CN against packing fraction with German's law and the fitted law, plus residuals.

    Parameters
    ----------
    fit : GermanFit
        From :func:`bedstruct.analysis.fit_german_law`.
    ax : Axes, optional
        Where to draw data and laws. When None a figure with two panels
        (laws above, residuals below) is created.
    residual_ax : Axes, optional
        Where to draw the residuals when ``ax`` is given.
    label : str, optional
        Legend label of the data points.

    Returns
    -------
    Axes or (Figure, (Axes, Axes))

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.analysis import fit_german_law
    >>> fit = fit_german_law([0.5, 0.55, 0.6], [3.98, 4.0, 4.03])
    >>> fig, (top, bottom) = plot_german(fit)
    >>> len(top.lines)
    3
    """
    from ..analysis.german import german_cn
    created = ax is None
    if created:
        fig, (ax, residual_ax) = _figure(None, nrows=2, gridspec_kw={"height_ratios": [3, 1]})
    f = np.asarray(fit.f)
    grid = np.linspace(f.min() - 0.02, f.max() + 0.02, 200)
    ax.plot(f, fit.cn, "o", label=label)
    ax.plot(grid, german_cn(grid), "--",
            label=f"$CN_S = 2 + 11 f^2$ (mean |dev| {fit.unfitted_deviation:.2f})")
    ax.plot(grid, fit.predict(grid), "-",
            label=f"$CN_m = 2a + 11 b f^2$, a = {fit.a:.3f}, b = {fit.b:.4f}"
                  + ("" if fit.determined else " (a, b not separately determined)"))
    ax.set_ylabel("coordination number")
    ax.legend(fontsize="small")
    if residual_ax is not None:
        residual_ax.axhline(0.0, color="0.5", lw=0.8)
        residual_ax.plot(f, fit.residuals, "o", label="fitted law")
        residual_ax.plot(f, fit.unfitted_residuals, "x", label="German's law")
        residual_ax.set_xlabel("packing fraction f")
        residual_ax.set_ylabel("residual")
        residual_ax.legend(fontsize="small")
    else:
        ax.set_xlabel("packing fraction f")
    return (fig, (ax, residual_ax)) if created else ax


def plot_psd(results, *, labels=None, ax=None, cumulative: bool = False, unit: str = "",
             scale: float = 1.0):
    """Overlay particle size distributions (e.g. before and after spreading).

    Parameters
    ----------
    results : PSDResult or sequence of PSDResult
    labels : sequence of str, optional
    ax : Axes, optional
    cumulative : bool, optional
        Plot the cumulative fraction instead of the density.
    unit : str, optional
        Length unit for the axis label (after ``scale``).
    scale : float, optional
        Factor applied to the diameters (e.g. 1e6 to plot metres in um).

    Returns
    -------
    Axes or (Figure, Axes)

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.analysis import particle_size_distribution
    >>> p = particle_size_distribution(np.array([1.0, 1.5, 2.0]), bins=4)
    >>> fig, ax = plot_psd([p, p], labels=["before", "after"])
    >>> len(ax.lines)
    2
    """
    if hasattr(results, "edges"):
        results = [results]
    results = list(results)
    labels = [None] * len(results) if labels is None else list(labels)
    fig, ax = _figure(ax)
    for r, lab in zip(results, labels):
        if cumulative:
            ax.plot(r.edges[1:] * scale, r.cumulative, drawstyle="steps-post", label=lab)
        else:
            ax.plot(r.centres * scale, r.fraction * 100, marker="o", ms=3, label=lab)
    w = results[0].weighting if results else "volume"
    ax.set_xlabel(f"diameter{f' ({unit})' if unit else ''}")
    ax.set_ylabel(f"cumulative {w} fraction" if cumulative else f"{w} fraction per bin (%)")
    if any(lab is not None for lab in labels):
        ax.legend(fontsize="small")
    return _ret(fig, ax)


def plot_psd_along_bed(seg, *, ax=None, unit: str = ""):
    """PSDs of the windows along the deposited bed, with heap and initial pile.

    Parameters
    ----------
    seg : SegregationResult
        From :func:`bedstruct.analysis.segregation`.

    Returns
    -------
    Axes or (Figure, Axes)

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> from bedstruct.analysis import segregation
    >>> rng = np.random.default_rng(0)
    >>> f = Frame(rng.uniform(0, 10, (300, 3)), rng.uniform(0.2, 0.3, 300), box=[10, 10, 10])
    >>> fig, ax = plot_psd_along_bed(segregation(f, 8.0, initial=f))
    >>> len(ax.lines)
    5
    """
    results = [*seg.along_bed, seg.heap] + ([seg.initial] if seg.initial is not None else [])
    n = len(seg.along_bed)
    names = {3: ["start", "centre", "end"]}.get(n, [f"window {k + 1}" for k in range(n)])
    labels = [f"bed {nm} (D50 {p.d50:.3g})" for nm, p in zip(names, seg.along_bed)]
    labels.append(f"heap (D50 {seg.heap.d50:.3g})")
    if seg.initial is not None:
        labels.append(f"initial pile (D50 {seg.initial.d50:.3g})")
    return plot_psd(results, labels=labels, ax=ax, unit=unit)


def plot_packing_profile(profile, *, axis: int = 0, coordination=None, ax=None, unit: str = "",
                         scale: float = 1.0):
    """Packing fraction of windows against their position (optionally CN on a twin axis).

    Parameters
    ----------
    profile : PackingProfile
    axis : int, optional
        Coordinate of the window centres on the x axis of the plot.
    coordination : WindowCoordination, optional
        Mean CN of the same windows, drawn on a secondary y axis.
    unit : str, optional
        Length unit of the x axis label (after ``scale``).
    scale : float, optional
        Factor applied to positions (e.g. 1e3 to plot metres in mm).

    Returns
    -------
    Axes or (Figure, Axes)

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> from bedstruct.analysis import packing_along, coordination_by_window
    >>> f = Frame(np.random.default_rng(0).uniform(0, 6, (100, 3)), np.full(100, 0.4), box=[6, 6, 6])
    >>> p = packing_along(f)
    >>> fig, ax = plot_packing_profile(p, coordination=coordination_by_window(f, p.lower, p.upper))
    >>> len(ax.lines)
    1
    """
    fig, ax = _figure(ax)
    x = profile.centres[:, axis] * scale
    ax.plot(x, profile.fractions, "o-", color="C0", label="packing fraction")
    ax.set_xlabel(f"{'xyz'[axis]}{f' ({unit})' if unit else ''}")
    ax.set_ylabel("packing fraction", color="C0")
    if coordination is not None:
        tw = ax.twinx()
        tw.plot(x, coordination.mean, "s--", color="C3", label="mean CN")
        tw.set_ylabel("coordination number", color="C3")
    return _ret(fig, ax)


def plot_coordination(result, *, ax=None, mechanical: bool = False):
    """Histogram of per-particle coordination numbers with the mean marked.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> from bedstruct.analysis import coordination
    >>> g = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> fig, ax = plot_coordination(coordination(Frame(g + 0.5, np.full(27, 0.5), box=[3, 3, 3])))
    >>> len(ax.patches) > 0
    True
    """
    fig, ax = _figure(ax)
    vals = result.per_particle_mechanical[~result.rattlers] if mechanical else result.per_particle
    top = int(vals.max()) if vals.size else 1
    ax.hist(vals, bins=np.arange(-0.5, top + 1.5), rwidth=0.85)
    mean = result.mechanical if mechanical else result.mean
    ax.axvline(mean, color="C3", label=f"mean {mean:.2f}")
    ax.set_xlabel("mechanical coordination number" if mechanical else "coordination number")
    ax.set_ylabel("particles")
    ax.legend(fontsize="small")
    return _ret(fig, ax)


def plot_height_map(surface, *, ax=None, cmap: str = "viridis", unit: str = "", scale: float = 1.0,
                    axes: str = "xy"):
    """Top-surface height map with axes, units, true aspect and its roughness in the title.

    Parameters
    ----------
    surface : SurfaceResult
        From :func:`bedstruct.analysis.surface_height_map`.
    ax : Axes, optional
    cmap : str, optional
    unit : str, optional
        Length unit of the axes, colour bar and roughness (after ``scale``).
    scale : float, optional
        Factor applied to every length (e.g. 1e3 to plot metres in mm).
    axes : str, optional
        Names of the map's two horizontal axes (default ``"xy"``).

    Returns
    -------
    Axes or (Figure, Axes)

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> from bedstruct.analysis import surface_height_map
    >>> f = Frame(np.random.default_rng(0).uniform(0, 6, (100, 3)), np.full(100, 0.4), box=[6, 6, 6])
    >>> fig, ax = plot_height_map(surface_height_map(f, spacing=0.2), unit="mm")
    >>> len(ax.images), ax.get_xlabel(), ax.get_ylabel(), ax.get_aspect()
    (1, 'x (mm)', 'y (mm)', 1.0)
    """
    xs, ys = np.asarray(surface.x) * scale, np.asarray(surface.y) * scale
    dx = xs[1] - xs[0] if xs.size > 1 else scale
    dy = ys[1] - ys[0] if ys.size > 1 else scale
    ext = [xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2]
    if ax is None:
        # a long narrow strip gets a wide, low figure; the colour bar goes below it
        ratio = (ext[3] - ext[2]) / max(ext[1] - ext[0], 1e-300)
        fig, ax = _figure(None, figsize=(8.0, float(np.clip(8.0 * ratio + 1.6, 2.4, 7.0))))
    else:
        fig = None
    im = ax.imshow(surface.heights.T * scale, origin="lower", extent=ext, cmap=cmap, aspect="equal")
    u = f" ({unit})" if unit else ""
    wide = (ext[1] - ext[0]) > 2.5 * (ext[3] - ext[2])
    cb = (fig or ax.figure).colorbar(im, ax=ax, orientation="horizontal" if wide else "vertical",
                                     fraction=0.08 if wide else 0.15, aspect=40 if wide else 20)
    cb.set_label(f"top-surface height{u}")
    ax.set_xlabel(f"{axes[0]}{u}")
    ax.set_ylabel(f"{axes[1]}{u}")
    r = surface.roughness
    ax.set_title(f"Sa {r.sa * scale:.3g}  Sq {r.sq * scale:.3g}  Sz {r.sz * scale:.3g}{f' {unit}' if unit else ''}"
                 f"  Ssk {r.ssk:.2f}  uncovered {100 * surface.uncovered_fraction:.1f}%", fontsize="small")
    return _ret(fig, ax)


def plot_repose(result, *, ax=None, unit: str = "", scale: float = 1.0):
    """Free-surface profile with the fitted flank lines and their angles.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> from bedstruct.analysis import angle_of_repose
    >>> x = np.arange(0.25, 40, 0.5)
    >>> z = np.clip(10 - np.tan(np.radians(30)) * abs(x - 20), 0, None)
    >>> f = Frame(np.c_[x, 0 * x, z], np.full(x.size, 0.25), box=([0, -1, -1], [40, 1, 12]))
    >>> fig, ax = plot_repose(angle_of_repose(f, spacing=0.1))
    >>> len(ax.lines)
    3
    """
    fig, ax = _figure(ax)
    ax.plot(result.profile_x * scale, result.profile_h * scale, "-", color="0.4", lw=1, label="free surface")
    for name, fl in (("left", result.left), ("right", result.right)):
        if fl is None:
            continue
        xs = np.array([fl.x.min(), fl.x.max()])
        ax.plot(xs * scale, (fl.intercept + fl.slope * xs) * scale, "-", lw=2.5,
                label=f"{name}: {fl.angle_deg:.1f}° (fit ± {fl.angle_std_deg:.1f}°)")
    ax.set_xlabel(f"position{f' ({unit})' if unit else ''}")
    ax.set_ylabel(f"height{f' ({unit})' if unit else ''}")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize="small")
    return _ret(fig, ax)


def plot_repose_series(series, *, time=None, ax=None, label: str = "simulation"):
    """Dynamic angle of repose against time (or timestep), with its uncertainty band.

    Parameters
    ----------
    series : ReposeSeries
    time : (F,) array_like, optional
        Abscissa (default the timesteps).

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.analysis import ReposeSeries
    >>> s = ReposeSeries(np.arange(3), np.zeros(3), np.array([27.0, 28.0, 27.5]), np.full(3, 0.3))
    >>> fig, ax = plot_repose_series(s)
    >>> len(ax.lines)
    1
    """
    fig, ax = _figure(ax)
    t = series.timesteps if time is None else np.asarray(time)
    ax.plot(t, series.angle_deg, "-o", ms=3, label=label)
    ax.fill_between(t, series.angle_deg - series.angle_std_deg,
                    series.angle_deg + series.angle_std_deg, alpha=0.3)
    ax.set_xlabel("timestep" if time is None else "time")
    ax.set_ylabel("dynamic angle of repose (°)")
    ax.legend(fontsize="small")
    return _ret(fig, ax)


def plot_rdf(result, *, diameter: float | None = None, ax=None, unit: str = "", scale: float = 1.0):
    """Radial distribution function g(r), against r or against r over a diameter.

    Parameters
    ----------
    result : RDFResult
        From :func:`bedstruct.analysis.radial_distribution`.
    diameter : float, length, optional
        Plot against ``r / diameter`` (e.g. the median diameter).
    ax : Axes, optional
    unit : str, optional
        Length unit of the x axis when ``diameter`` is not given (after ``scale``).
    scale : float, optional
        Factor applied to r when ``diameter`` is not given.

    Returns
    -------
    Axes or (Figure, Axes)

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Frame
    >>> from bedstruct.analysis import radial_distribution
    >>> f = Frame(np.random.default_rng(0).uniform(0, 6, (300, 3)), np.full(300, 0.2), box=[6, 6, 6])
    >>> fig, ax = plot_rdf(radial_distribution(f, cutoff=2.0, n_bins=20), diameter=0.4)
    >>> ax.get_xlabel(), len(ax.lines)
    ('r / d', 2)
    """
    fig, ax = _figure(ax)
    x = result.r / diameter if diameter else result.r * scale
    ax.plot(x, result.g, "-", color="C0", lw=1.5, label="g(r)")
    ax.axhline(1.0, color="0.6", lw=0.8, ls="--")
    ax.set_xlabel("r / d" if diameter else f"r{f' ({unit})' if unit else ''}")
    ax.set_ylabel("g(r)")
    ax.set_xlim(0, float(x[-1] + (x[1] - x[0]) / 2) if len(x) > 1 else None)
    return _ret(fig, ax)


def plot_local_packing(result, positions, *, axis: int = 0, unit: str = "", scale: float = 1.0,
                       n_windows: int = 24):
    """Histogram of local packing fractions and their map along the bed.

    Parameters
    ----------
    result : LocalPacking
        From :func:`bedstruct.analysis.local_packing`.
    positions : (N, 3) array_like of float, length
        Particle positions (rows as in ``result``).
    axis : int, optional
        Direction along the bed (default 0).
    unit : str, optional
        Length unit of the map's x axis (after ``scale``).
    scale : float, optional
        Factor applied to positions.
    n_windows : int, optional
        Windows of the packing-fraction line along the bed (default 24).

    Returns
    -------
    matplotlib.figure.Figure
        Left: histogram (cells inside, cells at a wall or the free surface).
        Right: each particle's fraction against its position, and the
        fraction of each window (particle volume over cell volume).

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.analysis import LocalPacking
    >>> lp = LocalPacking(np.full(4, 0.5), np.ones(4), np.array([0, 0, 0, 1], bool), np.zeros(3), np.ones(3))
    >>> fig = plot_local_packing(lp, np.random.default_rng(0).uniform(0, 1, (4, 3)))
    >>> len(fig.axes)
    2
    """
    Figure = figure_class()
    fig = Figure(figsize=(10.0, 3.8), layout="constrained")
    ax_h, ax_m = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 2]})
    frac, wall = np.asarray(result.fractions), np.asarray(result.at_wall, dtype=bool)
    bins = np.linspace(0.0, max(0.8, float(np.nanmax(frac)) if frac.size else 0.8), 41)
    ax_h.hist([frac[~wall], frac[wall]], bins=bins, stacked=True, color=["C0", "0.7"],
              label=["inside", "at a wall / surface"])
    ax_h.set_xlabel("local packing fraction")
    ax_h.set_ylabel("particles")
    ax_h.legend(fontsize="small")
    x = np.asarray(positions, dtype=np.float64)[:, axis] * scale
    ax_m.scatter(x[~wall], frac[~wall], s=3, color="C0", alpha=0.4, lw=0)
    ax_m.scatter(x[wall], frac[wall], s=3, color="0.7", alpha=0.4, lw=0)
    if x.size:
        edges = np.linspace(x.min(), x.max(), n_windows + 1)
        k = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_windows - 1)
        vol = np.asarray(result.cell_volumes)
        mean = np.array([np.sum(frac[k == b] * vol[k == b]) / np.sum(vol[k == b]) if np.any(k == b) else np.nan
                         for b in range(n_windows)])
        ax_m.plot(0.5 * (edges[1:] + edges[:-1]), mean, "-", color="C3", lw=2, label="window (all cells)")
        ax_m.legend(fontsize="small")
    ax_m.set_xlabel(f"{'xyz'[axis]}{f' ({unit})' if unit else ''}")
    ax_m.set_ylabel("local packing fraction")
    return fig
