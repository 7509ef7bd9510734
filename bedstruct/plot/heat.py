"""Figures of heat conduction: top-view temperature maps and temperature histories."""

from __future__ import annotations

import math

import numpy as np

from ._mpl import figure_class

__all__ = ["plot_temperature_map", "plot_temperature_history"]

_KELVIN = 273.15


def plot_temperature_map(tmap, *, ax=None, haz=None, vmin=None, vmax=None, cmap="inferno",
                         celsius=True, colorbar=True, length_scale=1e-6):
    """Top-view temperature map with the heat-affected-zone ellipse (seed figure 26).

    Parameters
    ----------
    tmap : TemperatureMap
        From :func:`bedstruct.analysis.heat.temperature_map`.
    ax : matplotlib Axes, optional
        Draw here; otherwise a new ``Figure`` is made.
    haz : HAZShape, optional
        Draw its equivalent ellipse (same area centroid, axes, orientation).
    vmin, vmax : float, optional
        Colour limits in the displayed unit (C or K); the seed used 250 and
        360 C.
    cmap : str
    celsius : bool
        Show degrees Celsius (default) rather than kelvin.
    colorbar : bool
    length_scale : float, m
        Unit of the axes (default micrometres).

    Returns
    -------
    Axes, or (Figure, Axes) when ``ax`` is None.

    .. versionadded:: 0.1

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.analysis.heat import TemperatureMap
    >>> m = TemperatureMap(np.full((4, 5), 400.0), np.arange(5) * 1e-6, np.arange(4) * 1e-6, 1e-6,
    ...                    np.array([0, 5e-6, 0, 4e-6]), "top")
    >>> fig, ax = plot_temperature_map(m)
    >>> ax.get_xlabel()
    'x (um)'
    """
    Figure = figure_class()
    from matplotlib.patches import Ellipse
    created = ax is None
    if created:
        fig = Figure(figsize=(5, 4.2))
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    shift = _KELVIN if celsius else 0.0
    unit = "C" if celsius else "K"
    lname = {1e-6: "um", 1e-3: "mm", 1.0: "m"}.get(length_scale, f"x{length_scale:g} m")
    ext = np.asarray(tmap.extent) / length_scale
    im = ax.imshow(tmap.values - shift, origin="lower", extent=tuple(ext), cmap=cmap, vmin=vmin,
                   vmax=vmax, interpolation="nearest")
    if haz is not None and haz.area > 0:
        c = np.asarray(haz.centroid) / length_scale
        ax.add_patch(Ellipse(tuple(c), haz.major_axis / length_scale, haz.minor_axis / length_scale,
                             angle=math.degrees(haz.orientation), fill=False, color="cyan", lw=1.5,
                             label=f"HAZ {haz.threshold - shift:.0f} {unit}, R = {haz.roundness:.3f}"))
        ax.legend(loc="upper right", fontsize="small")
    ax.set_xlabel(f"x ({lname})")
    ax.set_ylabel(f"y ({lname})")
    ax.set_aspect("equal")
    if colorbar:
        fig.colorbar(im, ax=ax, label=f"temperature ({unit})")
    return (fig, ax) if created else ax


def plot_temperature_history(result, *, ax=None, particles=None, celsius=True, time_scale=1e-3):
    """Hottest-particle temperature over time, and optionally chosen particles.

    Parameters
    ----------
    result : HeatResult
    ax : matplotlib Axes, optional
    particles : sequence of int, optional
        Row indices of particles to draw as well.
    celsius : bool
    time_scale : float, s
        Unit of the time axis (default ms).

    Returns
    -------
    Axes, or (Figure, Axes) when ``ax`` is None.
    """
    Figure = figure_class()
    created = ax is None
    if created:
        fig = Figure(figsize=(5, 3.5))
        ax = fig.add_subplot()
    shift = _KELVIN if celsius else 0.0
    t = np.asarray(result.times) / time_scale
    ax.plot(t, result.max_temperature - shift, "k-", lw=2, label="hottest particle")
    if particles is not None:
        for p in np.atleast_1d(particles):
            ax.plot(t, result.temperatures[:, int(p)] - shift, lw=1, label=f"particle {int(p)}")
    tname = {1e-3: "ms", 1e-6: "us", 1.0: "s"}.get(time_scale, f"x{time_scale:g} s")
    ax.set_xlabel(f"time ({tname})")
    ax.set_ylabel(f"temperature ({'C' if celsius else 'K'})")
    ax.legend(fontsize="small")
    return (fig, ax) if created else ax
