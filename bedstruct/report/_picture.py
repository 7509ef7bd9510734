"""Pictures of the bed for the top of the report: a side view (matplotlib, always
drawn) and a 3-D view rendered off screen with PyVista when it can render here.

The 3-D view is rendered in a child process: a graphics stack that cannot work
without a display may abort the process that tries, and the report must survive
that. The child renders through VTK's off-screen fallbacks (EGL, OSMesa) and,
where there is no display but an ``Xvfb`` binary, through a virtual one.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass

import numpy as np

from ..core import Frame
from ._model import figure_uri, png_uri

__all__: list[str] = []

#: Seconds the 3-D render may take before it is given up (with a note).
RENDER_TIMEOUT = 180.0

_AXES = "xyz"


@dataclass(frozen=True)
class SizeScale:
    """Particle diameters to show: ``values`` in ``unit`` (µm or mm when the unit system is known)."""

    values: np.ndarray
    unit: str


def diameters_shown(frame: Frame) -> SizeScale:
    """The particle diameters in µm (largest below 1 mm) or mm, as the report's tables show
    lengths, or in the dump's length unit when it is unknown."""
    from ._render import _display_unit
    d = 2.0 * np.asarray(frame.radii, dtype=float)
    try:
        to_m = frame.units.to_si("length")
    except ValueError:
        return SizeScale(d, "length unit of the dump")
    factor, unit = _display_unit([float(d.max()) * to_m if d.size else 0.0], "m")
    return SizeScale(d * to_m * factor, unit)


def _view_axes(axis: int, flat: int | None = None) -> tuple[int, int, int]:
    """(horizontal, vertical, depth) axes of the side view: along the bed, height, across.

    A 2-D run flat along ``flat`` is seen across its plane.
    """
    if flat is not None and flat != axis:
        return axis, 3 - axis - flat, flat
    vertical = 2 if axis != 2 else 0
    depth = 3 - axis - vertical
    return axis, vertical, depth


def side_view(frame: Frame, *, axis: int = 0, scale: float = 1.0, unit: str = ""):
    """The bed seen from the side: every sphere as a disc of its true size, nearest on top,
    coloured by diameter.

    Parameters
    ----------
    frame : Frame
        The particles.
    axis : int
        The spreading direction (0, 1, 2): horizontal in the picture; height (z,
        or x when the bed spreads along z) is vertical, the view looks across; a
        2-D run (:func:`bedstruct.analysis.flat_axis`) is seen across its plane.
    scale, unit : optional
        Factor and name of the length unit of the picture's axes.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.collections import EllipseCollection

    from ..analysis import flat_axis
    from ..plot._mpl import figure_class
    h, v, depth = _view_axes(axis, flat_axis(frame))
    pos = np.asarray(frame.positions, dtype=float) * scale
    r = np.asarray(frame.radii, dtype=float) * scale
    sizes = diameters_shown(frame)
    order = np.argsort(-pos[:, depth], kind="stable")   # far ones first, near ones drawn last
    Figure = figure_class()
    span = np.ptp(pos[:, h]) + 2 * r.max() if len(r) else 1.0
    height = np.ptp(pos[:, v]) + 2 * r.max() if len(r) else 1.0
    aspect = float(np.clip(height / max(span, 1e-300), 0.15, 1.5))
    fig = Figure(figsize=(9.0, max(2.2, 9.0 * aspect) + 0.8), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    discs = EllipseCollection(2 * r[order], 2 * r[order], np.zeros(len(r)), units="xy",
                              offsets=pos[order][:, [h, v]], offset_transform=ax.transData,
                              cmap="viridis", edgecolors="k", linewidths=0.15)
    discs.set_array(sizes.values[order])
    ax.add_collection(discs)
    if len(r):
        pad = r.max()
        ax.set_xlim(pos[:, h].min() - pad, pos[:, h].max() + pad)
        ax.set_ylim(pos[:, v].min() - pad, pos[:, v].max() + pad)
    ax.set_aspect("equal")
    suffix = f" ({unit})" if unit else ""
    ax.set_xlabel(f"{_AXES[h]}{suffix}")
    ax.set_ylabel(f"{_AXES[v]}{suffix}")
    fig.colorbar(discs, ax=ax, label=f"particle diameter ({sizes.unit})", shrink=0.9)
    return fig


_CHILD = r"""
import sys
import numpy as np
import pyvista as pv
from vtkmodules.vtkCommonCore import vtkLogger

vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)  # the X-to-EGL fallback is not news
pv.OFF_SCREEN = True
src, out, xvfb = sys.argv[1], sys.argv[2], sys.argv[3] == "1"
if xvfb:
    pv.start_xvfb()
data = np.load(src)
pts = pv.PolyData(data["positions"])
pts.point_data["radius"] = data["radii"]
pts.point_data["size"] = data["sizes"]
res = 12 if pts.n_points <= 20000 else 6
spheres = pts.glyph(scale="radius", orient=False,
                    geom=pv.Sphere(radius=1.0, theta_resolution=res, phi_resolution=res))
plotter = pv.Plotter(off_screen=True, window_size=(1000, 640))
plotter.set_background("white")
plotter.add_mesh(spheres, scalars="size", cmap="viridis", smooth_shading=True,
                 scalar_bar_args={"title": str(data["label"]), "color": "black", "fmt": "%.0f",
                                  "vertical": True, "position_x": 0.88, "position_y": 0.15})
plotter.view_isometric()
plotter.camera.zoom(1.25)
plotter.screenshot(out)
plotter.close()
"""


def render_3d(frame: Frame, *, scale: float = 1.0, timeout: float = RENDER_TIMEOUT
              ) -> tuple[bytes | None, str]:
    """A PNG of the bed in 3-D (spheres of their true size coloured by diameter), or
    ``(None, why)`` when PyVista cannot render here.

    Returns ``(png, note)``; the note says how it was drawn or why it was not.
    """
    if importlib.util.find_spec("pyvista") is None:
        return None, ("3-D view not drawn: it needs pyvista "
                      "(pip install 'bedstruct[interop]')")
    if frame.n_particles == 0:
        return None, "3-D view not drawn: the frame has no particles"
    sizes = diameters_shown(frame)
    with tempfile.TemporaryDirectory(prefix="bedstruct-view-") as tmp:
        src, out = os.path.join(tmp, "bed.npz"), os.path.join(tmp, "bed.png")
        np.savez(src, positions=np.ascontiguousarray(frame.positions, dtype=float) * scale,
                 radii=np.asarray(frame.radii, dtype=float) * scale, sizes=sizes.values,
                 label=np.array(f"diameter ({sizes.unit})"))
        attempts = [False]
        if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") \
                and shutil.which("Xvfb"):
            attempts.append(True)   # VTK without EGL/OSMesa needs a (virtual) display
        why = ""
        for xvfb in attempts:
            try:
                done = subprocess.run([sys.executable, "-c", _CHILD, src, out, "1" if xvfb else "0"],
                                      capture_output=True, text=True, timeout=timeout)
            except subprocess.TimeoutExpired:
                why = f"the off-screen render took longer than {timeout:.0f} s"
                continue
            if done.returncode == 0 and os.path.isfile(out) and os.path.getsize(out) > 0:
                with open(out, "rb") as fh:
                    return fh.read(), ("3-D view rendered off screen with PyVista"
                                       + (" on a virtual display (Xvfb)" if xvfb else ""))
            last = [ln for ln in (done.stderr or "").splitlines() if ln.strip()]
            why = (f"the off-screen render failed ({last[-1].strip()[:200]})" if last
                   else f"the off-screen render failed (exit status {done.returncode})")
    headless = sys.platform.startswith("linux") and not os.environ.get("DISPLAY")
    hint = "; no display, and no Xvfb to provide one" if headless and len(attempts) == 1 else ""
    return None, f"3-D view not drawn: {why}{hint}"


def bed_pictures(frame: Frame, *, axis: int = 0, view_3d: bool = True
                 ) -> tuple[list[tuple[str, str]], str]:
    """The pictures of a bed for the top of a page: ``([(caption, PNG data URI)], note)``.

    The 3-D view (when ``view_3d`` and PyVista renders here) comes first, then the
    side view, which is always drawn; the note says how they were drawn or why
    one is missing. A picture that fails is left out with the reason in the note,
    never taking the page down.
    """
    from ._render import _display_unit
    pictures, notes = [], []
    size_unit = diameters_shown(frame).unit
    if view_3d:
        try:
            png, note = render_3d(frame)
        except Exception as exc:   # the picture must not take the page down
            png, note = None, f"3-D view not drawn ({type(exc).__name__}: {exc})"
        notes.append(note)
        if png is not None:
            pictures.append((f"The bed in 3-D, coloured by particle diameter ({size_unit})",
                             png_uri(png)))
    else:
        notes.append("3-D view not drawn (turned off)")
    try:
        unit = frame.units.length_unit
        if unit == "unknown":
            factor, unit = 1.0, "length unit of the dump"
        else:
            extent = np.ptp(frame.positions, axis=0) if frame.n_particles else [0.0]
            factor, unit = _display_unit(list(np.ravel(extent)), unit)
        fig = side_view(frame, axis=axis, scale=factor, unit=unit)
        pictures.append((f"Side view of the bed along {_AXES[axis]} (every particle, nearest in "
                         f"front), coloured by particle diameter ({size_unit})", figure_uri(fig)))
    except Exception as exc:
        notes.append(f"side view not drawn ({type(exc).__name__}: {exc})")
    return pictures, "; ".join(notes) + "."
