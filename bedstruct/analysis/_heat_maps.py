"""Top-view temperature maps, heat-affected-zone shape and effective conductivity."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import _heat_kernels as _k
from ._heat_network import ThermalNetwork
from ._heat_solver import HeatResult

_STEADY_DIRECT_MAX = 200_000   # conductivity_tensor: sparse LU up to this many free nodes, else CG

__all__ = ["TemperatureMap", "temperature_map", "HAZShape", "haz_shape", "haz_table",
           "ConductivityTensor", "conductivity_tensor"]


@dataclass(frozen=True, eq=False)
class TemperatureMap:
    """Particle temperatures seen from above, on a grid of square cells.

    Attributes
    ----------
    values : (ny, nx) ndarray, K
        Temperature per cell (NaN where no particle covers the cell); row
        ``k`` is ``y[k]``, column ``l`` is ``x[l]``.
    x, y : ndarray, m
        Cell centres.
    cell : float, m
        Cell edge.
    extent : (4,) ndarray, m
        ``(xmin, xmax, ymin, ymax)`` of the grid (for ``imshow``).
    method : str
        ``"top"``, ``"max"`` or ``"linear"``.
    source_center : (2,) ndarray or None, m
        Horizontal centre of the heat source, when known.
    time : float or None, s
        Time of the temperatures, when known (NaN for the peak map).
    """

    values: np.ndarray
    x: np.ndarray
    y: np.ndarray
    cell: float
    extent: np.ndarray
    method: str
    source_center: np.ndarray | None = None
    time: float | None = None


def temperature_map(result, *, which="final", temperature=None, cell=None, extent=None,
                    method: str = "top") -> TemperatureMap:
    """Rasterise particle temperatures into a top-view map (seed figure 26).

    Parameters
    ----------
    result : HeatResult or ThermalNetwork
        The run (or a network, with ``temperature`` given).
    which : {"final", "peak"} or int
        Which temperatures of a :class:`HeatResult`: at the end, the peak of
        every particle, or the recorded time with that index.
    temperature : (N,) array_like, optional, K
        Temperatures to map instead.
    cell : float, optional, m
        Cell edge; default a quarter of the median radius.
    extent : (4,) array_like, optional, m
        ``(xmin, xmax, ymin, ymax)``; default the particles' footprint.
    method : {"top", "max", "linear"}
        ``"top"``: temperature of the particle whose surface is highest over
        the cell (what a camera above the bed sees); ``"max"``: hottest
        particle in the column under the cell; ``"linear"``: linear
        interpolation (scipy ``griddata``) between the centres of the
        particles visible from the top.

    Returns
    -------
    TemperatureMap

    .. versionadded:: 0.1

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.core import Frame, Contacts, Units
    >>> from bedstruct.analysis.heat import thermal_network
    >>> f = Frame([[1, 1, 1], [3, 1, 1], [3, 1, 2]], [1.0, 1.0, 1.0], box=[4, 2, 4])
    >>> net = thermal_network(f, Contacts([], [], np.zeros((0, 3)), [], [], n_particles=3))
    >>> m = temperature_map(net, temperature=[300.0, 310.0, 320.0], cell=1.0)
    >>> m.values
    array([[300., 300., 320., 320.],
           [300., 300., 320., 320.]])
    >>> m.x.tolist()  # the particle at (3, 1, 2) hides the one below it
    [0.5, 1.5, 2.5, 3.5]
    """
    src_c = None
    time = None
    if isinstance(result, HeatResult):
        net = result.network
        if result.source_center is not None:
            src_c = np.asarray(result.source_center[:2], dtype=np.float64)
        if temperature is None:
            if isinstance(which, str) and which == "final":
                temperature, time = result.final_temperature, result.t_end
            elif isinstance(which, str) and which == "peak":
                temperature, time = result.peak_temperature, float("nan")
            elif isinstance(which, (int, np.integer)):
                temperature, time = result.temperatures[which], float(result.times[which])
            else:
                raise ValueError(f"`which` must be 'final', 'peak' or a time index; got {which!r}")
    elif isinstance(result, ThermalNetwork):
        net = result
        if temperature is None:
            raise ValueError("a ThermalNetwork needs `temperature=` (N,) to map")
    else:
        raise TypeError(f"`result` must be a HeatResult or ThermalNetwork; got {type(result).__name__}")
    vals = np.ascontiguousarray(temperature, dtype=np.float64)
    n = net.n_particles
    if vals.shape != (n,):
        raise ValueError(f"`temperature` must have shape (N,) (N={n}); got {vals.shape}")
    if method not in ("top", "max", "linear"):
        raise ValueError(f"`method` must be 'top', 'max' or 'linear'; got {method!r}")
    pos, r = net.positions, net.radii
    if n == 0:
        raise ValueError("cannot map an empty network")
    if cell is None:
        cell = 0.25 * float(np.median(r))
    cell = float(cell)
    if not cell > 0:
        raise ValueError(f"`cell` must be positive (m); got {cell!r}")
    if extent is None:
        extent = (float(np.min(pos[:, 0] - r)), float(np.max(pos[:, 0] + r)),
                  float(np.min(pos[:, 1] - r)), float(np.max(pos[:, 1] + r)))
    ext = np.asarray(extent, dtype=np.float64).reshape(-1)
    if ext.shape != (4,) or not (ext[1] > ext[0] and ext[3] > ext[2]):
        raise ValueError(f"`extent` must be (xmin, xmax, ymin, ymax) with max > min; got {extent!r}")
    nx = max(1, int(math.ceil((ext[1] - ext[0]) / cell - 1e-9)))
    ny = max(1, int(math.ceil((ext[3] - ext[2]) / cell - 1e-9)))
    if nx * ny > 50_000_000:
        raise ValueError(f"a {nx} x {ny} grid is too large; choose a larger `cell`")
    ext = np.array([ext[0], ext[0] + nx * cell, ext[2], ext[2] + ny * cell])
    out = np.full((ny, nx), np.nan)
    height = np.full((ny, nx), -np.inf)
    owner = np.full((ny, nx), -1, dtype=np.int64)
    mode = 1 if method == "max" else 0
    _k.rasterize_top(np.ascontiguousarray(pos[:, 0]), np.ascontiguousarray(pos[:, 1]),
                     np.ascontiguousarray(pos[:, 2]), np.ascontiguousarray(r), vals, ext[0], ext[2],
                     cell, nx, ny, mode, out, height, owner)
    xc = ext[0] + (np.arange(nx) + 0.5) * cell
    yc = ext[2] + (np.arange(ny) + 0.5) * cell
    if method == "linear":
        from scipy.interpolate import griddata
        vis = np.unique(owner[owner >= 0])
        if vis.size >= 3:
            gx, gy = np.meshgrid(xc, yc)
            out = griddata(pos[vis, :2], vals[vis], (gx, gy), method="linear")
    return TemperatureMap(values=out, x=xc, y=yc, cell=cell, extent=ext, method=method,
                          source_center=src_c, time=time)


@dataclass(frozen=True, eq=False)
class HAZShape:
    """Shape of the heat-affected zone: cells at or above a threshold.

    Attributes
    ----------
    threshold : float, K
    area : float, m^2
    major_axis, minor_axis : float, m
        Full axis lengths of the ellipse with the same second moments
        (scikit-image ``regionprops``).
    orientation : float, rad
        Angle of the major axis from +x towards +y, in (-pi/2, pi/2].
    roundness : float
        ``R = 4 A / (pi L_major^2)`` (1 for a disc).
    centroid : (2,) ndarray, m
    n_cells : int
    mask : (ny, nx) ndarray of bool
        The zone on the map's grid.
    """

    threshold: float
    area: float
    major_axis: float
    minor_axis: float
    orientation: float
    roundness: float
    centroid: np.ndarray
    n_cells: int
    mask: np.ndarray

    @property
    def orientation_deg(self) -> float:
        """``orientation`` in degrees."""
        return math.degrees(self.orientation)


def haz_shape(tmap: TemperatureMap, threshold: float, *, center=None) -> HAZShape:
    """Heat-affected-zone shape of a temperature map at a threshold.

    The zone is the connected set of cells (8-connectivity) at or above
    ``threshold`` that contains ``center`` (default the source centre of the
    map, else its hottest cell); if ``center`` falls outside every zone the
    nearest zone is taken. Holes inside the zone (cells between particle
    discs that no particle covers, or cooler pockets) are filled, so the area
    is the area inside the outline, as measured from an outline in ImageJ in
    the seed report. Its area, axes and orientation come from
    ``skimage.measure.regionprops``.

    Parameters
    ----------
    tmap : TemperatureMap
    threshold : float, K
    center : (2,) array_like, optional, m

    Returns
    -------
    HAZShape
        All-zero area and NaN shape values when no cell reaches the threshold.

    Notes
    -----
    .. math:: R = \\frac{4 A}{\\pi L_{major}^2}

    as in the seed report (eq. 9, there written without the square).

    .. versionadded:: 0.1

    Examples
    --------
    A disc of radius 20 cells has roundness close to 1:

    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:60, 0:60]
    >>> vals = np.where((xx - 30) ** 2 + (yy - 30) ** 2 <= 400, 500.0, 300.0)
    >>> m = TemperatureMap(vals, np.arange(60) + 0.5, np.arange(60) + 0.5, 1.0,
    ...                    np.array([0, 60, 0, 60.0]), "top")
    >>> s = haz_shape(m, 400.0)
    >>> round(s.roundness, 2), s.n_cells
    (1.0, 1257)
    """
    from skimage.measure import label, regionprops
    if not isinstance(tmap, TemperatureMap):
        raise TypeError(f"`tmap` must be a TemperatureMap; got {type(tmap).__name__}")
    threshold = float(threshold)
    vals = tmap.values
    with np.errstate(invalid="ignore"):
        hot = np.nan_to_num(vals, nan=-np.inf) >= threshold
    empty = HAZShape(threshold, 0.0, float("nan"), float("nan"), float("nan"), float("nan"),
                     np.full(2, np.nan), 0, np.zeros_like(hot))
    if not hot.any():
        return empty
    lab = label(hot, connectivity=2)
    if center is None:
        center = tmap.source_center
    if center is None:
        row, col = np.unravel_index(np.nanargmax(vals), vals.shape)
    else:
        c = np.asarray(center, dtype=np.float64).reshape(-1)[:2]
        col = int(np.clip(np.floor((c[0] - tmap.extent[0]) / tmap.cell), 0, vals.shape[1] - 1))
        row = int(np.clip(np.floor((c[1] - tmap.extent[2]) / tmap.cell), 0, vals.shape[0] - 1))
    k = lab[row, col]
    if k == 0:
        rr, cc = np.nonzero(lab)
        near = np.argmin((rr - row) ** 2 + (cc - col) ** 2)
        k = lab[rr[near], cc[near]]
    # the outline counts (as in ImageJ): fill the gaps between particle discs inside it
    from scipy.ndimage import binary_fill_holes
    mask = binary_fill_holes(lab == k)
    props = regionprops(mask.astype(np.uint8))[0]
    cell = tmap.cell
    area = float(props.area) * cell * cell
    major = float(props.axis_major_length) * cell
    minor = float(props.axis_minor_length) * cell
    # skimage: angle between the row axis (y here) and the major axis; convert to angle from +x
    phi = math.pi / 2 - float(props.orientation)
    phi = (phi + math.pi / 2) % math.pi - math.pi / 2
    if phi <= -math.pi / 2:
        phi += math.pi
    r0, c0 = props.centroid
    centroid = np.array([tmap.extent[0] + (c0 + 0.5) * cell, tmap.extent[2] + (r0 + 0.5) * cell])
    roundness = 4.0 * area / (math.pi * major * major) if major > 0 else float("nan")
    return HAZShape(threshold, area, major, minor, phi, roundness, centroid, int(props.area), mask)


def haz_table(shapes, labels=None) -> dict:
    """Heat-affected-zone shapes as equal-length columns (for pandas).

    Parameters
    ----------
    shapes : sequence of HAZShape
    labels : sequence of str, optional
        One label per shape (e.g. ``"start"``, ``"center"``, ``"end"``).

    Returns
    -------
    dict of str to ndarray
        ``label``, ``threshold`` (K), ``area`` (m^2), ``major_axis``,
        ``minor_axis`` (m), ``orientation_deg`` (degrees), ``roundness``;
        zero-length, correctly typed columns for no shapes.

    .. versionadded:: 0.1

    Examples
    --------
    >>> haz_table([])["roundness"]
    array([], dtype=float64)
    """
    shapes = list(shapes)
    if labels is None:
        labels = [str(k) for k in range(len(shapes))]
    labels = [str(v) for v in labels]
    if len(labels) != len(shapes):
        raise ValueError(f"`labels` must have one entry per shape ({len(shapes)}); got {len(labels)}")
    f = lambda name: np.array([getattr(s, name) for s in shapes], dtype=np.float64)  # noqa: E731
    return {"label": np.array(labels, dtype=str), "threshold": f("threshold"), "area": f("area"),
            "major_axis": f("major_axis"), "minor_axis": f("minor_axis"),
            "orientation_deg": np.degrees(f("orientation")), "roundness": f("roundness")}


@dataclass(frozen=True, eq=False)
class ConductivityTensor:
    """Effective conductivity of a bed region and the fabric of its contacts.

    Attributes
    ----------
    tensor : (3, 3) ndarray, W/(m K)
        Symmetrised effective conductivity ``K`` (``q = -K grad T``).
    eigenvalues : (3,) ndarray, W/(m K)
        Principal conductivities, largest first.
    eigenvectors : (3, 3) ndarray
        Principal directions as columns, in the order of ``eigenvalues``.
    affine : (3, 3) ndarray, W/(m K)
        Uniform-gradient (Voigt) estimate: ``K`` with ``theta = 0``, that is
        ``(1/V_beta) sum w G l l_beta`` per column with the weights and
        volumes of ``tensor`` (symmetric part); ``(1/V) sum G l l^T`` for a
        region with no faces.
    fabric : (3, 3) ndarray
        Normal fabric tensor ``N_ij = <n_i n_j>`` of the conducting contacts
        (weighted by ``w``).
    fabric_eigenvalues : (3,) ndarray
    fabric_eigenvectors : (3, 3) ndarray
    volume : float, m^3
        Volume of the region: box length along periodic axes it spans,
        window faces, and one contact radius beyond the outermost conducting
        centres at free surfaces.
    n_particles, n_contacts, n_fixed : int
        Particles in the region; conducting contacts with at least part of
        their branch inside; distinct particles held at the affine
        temperature for at least one gradient (slab particles at free
        surfaces normal to the gradient, and outside neighbours across
        window faces normal to it).
    asymmetry : float
        ``|K - K^T| / |K|`` of the raw tensor (0 with periodic boundaries).
    boundary : tuple of str
        Per axis ``"periodic"``, ``"window"`` (faces crossed by contacts),
        ``"surface"`` (faces crossed by none), or ``"window/surface"`` /
        ``"surface/window"`` (lower/upper face) when the two differ.
    """

    tensor: np.ndarray
    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    affine: np.ndarray
    fabric: np.ndarray
    fabric_eigenvalues: np.ndarray
    fabric_eigenvectors: np.ndarray
    volume: float
    n_particles: int
    n_contacts: int
    n_fixed: int
    asymmetry: float
    boundary: tuple

    @property
    def anisotropy(self) -> float:
        """``(k_max - k_min) / mean(k)`` of the principal conductivities."""
        m = float(np.mean(self.eigenvalues))
        return float((self.eigenvalues[0] - self.eigenvalues[-1]) / m) if m > 0 else float("nan")


def _eig_desc(t):
    w, v = np.linalg.eigh(t)
    o = np.argsort(w)[::-1]
    return w[o], v[:, o]


def _segment_fraction(start, vec, t_end, lo, hi):
    """Length fraction of ``start + t vec``, ``t in [0, t_end]``, with the coordinate in ``[lo, hi]``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (lo - start) / vec
        tb = (hi - start) / vec
    t0 = np.where(vec != 0, np.minimum(ta, tb), np.where((start >= lo) & (start <= hi), -np.inf, np.inf))
    t1 = np.where(vec != 0, np.maximum(ta, tb), np.where((start >= lo) & (start <= hi), np.inf, -np.inf))
    return np.clip(np.minimum(t1, t_end) - np.maximum(t0, 0.0), 0.0, None)


def conductivity_tensor(network: ThermalNetwork, *, region=None, boundary_width=None,
                        volume=None) -> ConductivityTensor:
    """Effective conductivity tensor of a bed region under mixed boundary conditions.

    For each axis ``beta`` a unit temperature gradient ``g = e_beta`` is
    imposed, ``T = g.x + theta``, and the steady network equations give
    ``theta`` with mixed boundary conditions:

    - *periodic* along axes where the box is periodic and the region spans
      it;
    - *held* (``theta = 0``) on the two faces normal to ``beta``;
    - *insulated* on the other (lateral) faces.

    Each non-periodic face of the region is either a *window* face, crossed
    by contacts to particles outside the region, or a *surface* face, crossed
    by none (a free surface of the bed, or a window face beyond the bed):

    - A window face normal to ``beta`` is held by its outside neighbours: a
      contact from an inside particle to one outside joins it to a node at
      the affine temperature ``g.x`` of the outside end.
    - A surface face normal to ``beta`` is held in a slab: the particles whose
      centres lie within ``boundary_width`` of the outermost centre have
      ``theta = 0``, and the held plane is the slab's inner face.
    - A lateral surface face is insulated: nothing crosses it.
    - A lateral window face is insulated for the fluctuation, without
      cutting its contacts: the outside end of a crossing contact follows
      the inside end (``theta_out = theta_in``, the discrete
      ``d theta / dn = 0``), so the contact carries the affine flux
      ``G g.l`` of its branch. A lattice is then neither truncated nor
      constrained at the face, and a homogeneous medium of any orientation
      keeps its uniform gradient. A connected cluster with no held node (a
      gradient along a periodic axis) must have zero net heat in steady
      state; the mean of its crossing fluxes is subtracted.

    The mean flux over the sample is

    .. math:: \\langle q \\rangle = -\\frac{1}{V_\\beta}
              \\sum_c w_c\\, G_c (T_{out} - T_{in})\\, l_c = -K g

    with ``l_c`` the branch vector and ``w_c`` the fraction of the branch
    inside the sample: 1 for contacts inside, the part up to the face for
    contacts that cross a window face, and only the part between the held
    planes along ``beta``. With this weighting the sum equals the heat
    through the held planes times their distance (discrete divergence
    theorem), so ``K_{beta beta}`` is the flux density through the sample
    per unit gradient. ``V_beta`` is the product of:

    - along periodic axes spanned by the region: the box length;
    - along ``beta`` when not periodic: the distance between the held planes
      (window faces, or the inner faces of the slabs);
    - along the other non-periodic axes: from face to face, where a window
      face is the region's face and a surface face lies one *contact radius*
      beyond the outermost conducting centre: the distance from a
      particle's centre to its contact planes, averaged over its contacts
      with weights ``|n_a|`` (``n`` the contact normal). It is the radius
      for touching spheres, close to it for a random bed, and ``s_a/2`` on a
      lattice of spacing ``s_a``, so overlapping spheres are not counted
      twice.

    One column of ``K`` follows per gradient; the raw tensor need not be
    symmetric with held faces, and its symmetric part is returned. The
    affine estimate is the same average with ``theta = 0``. The
    normal fabric tensor ``N = <n n>`` of the same contacts (weighted by
    ``w``) is returned beside it.

    Parameters
    ----------
    network : ThermalNetwork
    region : ((3,), (3,)) array_like, optional, m
        ``(lo, hi)`` of a box; particles whose centres lie inside take part.
        Default all particles (every non-periodic face is then a surface
        face).
    boundary_width : float, optional, m
        Thickness of the held slabs at surface faces normal to the gradient;
        default the largest particle diameter. It is reduced to a quarter of
        the span between the two faces' outermost centres (or window faces)
        when larger, so that a thin bed keeps a sample between the slabs.
    volume : float, optional, m^3
        If given, used as ``V_beta`` for every column and for the affine
        bound instead of the volumes above.

    Returns
    -------
    ConductivityTensor
        ``volume`` is the volume of the region (the lateral rule on every
        non-periodic axis); ``n_fixed`` counts the distinct particles held
        for at least one gradient (slab particles and outside neighbours
        across window faces); ``boundary`` names each axis ``"periodic"``,
        ``"window"``, ``"surface"``, or ``"window/surface"`` and
        ``"surface/window"`` (lower/upper face) when the faces differ.

    Notes
    -----
    The contacts are counted by the part of their branch inside the sample,
    so a simple cubic lattice of spacing ``s`` with conductance ``G`` per
    contact gives ``K = (G / s) I`` in a periodic box, in a box with free
    surfaces, and in any window whose faces lie between lattice planes; a
    face-centred cubic lattice with nearest-neighbour distance ``s`` gives
    ``2 sqrt(2) G / s I``. A thin bed with insulated top and bottom is not
    pinned to the affine field: ``K`` relaxes as in the free slab.

    .. versionadded:: 0.1

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct.core import Box, Frame, Contacts, Units
    >>> from bedstruct.analysis.heat import thermal_network
    >>> g = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3)
    >>> f = Frame(g + 0.5, np.full(27, 0.55), box=Box([0, 0, 0], [3, 3, 3]), units=Units("micro"))
    >>> d = f.box.minimum_image(f.positions[None] - f.positions[:, None])
    >>> i, j = np.nonzero(np.triu(np.linalg.norm(d, axis=-1) < 1.1, 1))
    >>> c = Contacts(i, j, d[i, j], f.radii[i], f.radii[j])
    >>> net = thermal_network(f, c)
    >>> k = conductivity_tensor(net)
    >>> G, s = net.conductance[0], 1e-6
    >>> np.allclose(k.tensor, G / s * np.eye(3)), np.allclose(k.fabric, np.eye(3) / 3)
    (True, True)
    """
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    if not isinstance(network, ThermalNetwork):
        raise TypeError(f"`network` must be a ThermalNetwork; got {type(network).__name__}")
    net = network
    pos, radii = net.positions, net.radii
    n_all = net.n_particles
    box_len = net.box_hi - net.box_lo
    if region is None:
        inside = np.ones(n_all, dtype=bool)
        lo_w, hi_w = np.full(3, -np.inf), np.full(3, np.inf)
    else:
        lo_w, hi_w = (np.asarray(v, dtype=np.float64).reshape(3) for v in region)
        if np.any(hi_w <= lo_w):
            raise ValueError(f"`region` must be (lo, hi) with hi > lo (m); got {region!r}")
        inside = np.all((pos >= lo_w) & (pos <= hi_w), axis=1)
    idx = np.flatnonzero(inside)
    if idx.size < 2:
        raise ValueError(f"the region holds {idx.size} particles; need at least 2")
    through = []
    for ax in range(3):
        spans = region is None or (lo_w[ax] <= net.box_lo[ax] + 1e-12 * box_len[ax]
                                   and hi_w[ax] >= net.box_hi[ax] - 1e-12 * box_len[ax])
        through.append(bool(net.periodic[ax] and spans))
    bounded = [ax for ax in range(3) if not through[ax]]
    n = idx.size
    p = pos[idx]
    rowmap = np.full(n_all, -1, dtype=np.int64)
    rowmap[idx] = np.arange(n)

    # conducting contacts with at least one end inside
    sel = (net.conductance > 0) & ((rowmap[net.i] >= 0) | (rowmap[net.j] >= 0))
    cid = np.flatnonzero(sel)
    ri, rj = rowmap[net.i[cid]], rowmap[net.j[cid]]
    Gc, lc = net.conductance[cid], net.branch[cid]
    dist = np.linalg.norm(lc, axis=1)
    rad_i, rad_j = radii[net.i[cid]], radii[net.j[cid]]
    with np.errstate(divide="ignore", invalid="ignore"):
        h_i = np.where(dist > 0, (dist ** 2 + rad_i ** 2 - rad_j ** 2) / (2.0 * dist), 0.0)
    h_i = np.clip(h_i, 0.0, dist)                 # centre of i to the contact plane
    h_j = dist - h_i

    def _exit(start, vec):
        """Parameter, axis and side (1: upper) where ``start + t vec`` leaves the region."""
        t = np.full((len(start), 3), np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            for ax in bounded:
                v = vec[:, ax]
                t[:, ax] = np.where(v > 0, (hi_w[ax] - start[:, ax]) / v,
                                    np.where(v < 0, (lo_w[ax] - start[:, ax]) / v, np.inf))
        a = np.argmin(t, axis=1)
        te = t[np.arange(len(start)), a]
        side = (vec[np.arange(len(start)), a] > 0).astype(np.int64)
        return te, a, side

    t_i, ax_i, sd_i = _exit(pos[net.i[cid]], lc)
    t_j, ax_j, sd_j = _exit(pos[net.j[cid]], -lc)
    tol = 1.0 - 1e-12
    internal = (ri >= 0) & (rj >= 0) & (t_i >= tol)
    x_i = (ri >= 0) & ~internal & (t_i < tol)       # crossing edges from the i end
    x_j = (rj >= 0) & ~internal & (t_j < tol)       # ... from the j end
    # internal contacts (rows a -> b, branch l)
    ia, ib, Gi, li = ri[internal], rj[internal], Gc[internal], lc[internal]
    # crossing edges: inside node, outward branch, exit fraction, face
    e_node = np.concatenate([ri[x_i], rj[x_j]])
    e_vec = np.concatenate([lc[x_i], -lc[x_j]])
    e_G = np.concatenate([Gc[x_i], Gc[x_j]])
    e_t = np.concatenate([t_i[x_i], t_j[x_j]])
    e_ax = np.concatenate([ax_i[x_i], ax_j[x_j]])
    e_side = np.concatenate([sd_i[x_i], sd_j[x_j]])
    e_out = np.concatenate([net.j[cid][x_i], net.i[cid][x_j]])
    n_contacts = int(np.count_nonzero(internal | x_i | x_j))

    # contact radius of each conducting particle along each axis: the distance from its centre
    # to its contact planes, averaged over its contacts with weights |n_a|
    na = np.abs(lc) / np.where(dist > 0, dist, 1.0)[:, None]
    ends = [(ia, h_i[internal], na[internal]), (ib, h_j[internal], na[internal]),
            (ri[x_i], h_i[x_i], na[x_i]), (rj[x_j], h_j[x_j], na[x_j])]
    hsum, hw = np.zeros((n, 3)), np.zeros((n, 3))
    for node, h, w in ends:
        for ax in range(3):
            hsum[:, ax] += np.bincount(node, h * w[:, ax], minlength=n)
            hw[:, ax] += np.bincount(node, w[:, ax], minlength=n)
    n_ends = np.bincount(np.concatenate([e[0] for e in ends]), minlength=n)
    cond = n_ends > 0
    if cond.any():
        hmean = np.zeros(n)
        for node, h, _ in ends:
            hmean += np.bincount(node, h, minlength=n)
        hmean[cond] /= n_ends[cond]
        rho = np.where(hw > 0, hsum / np.where(hw > 0, hw, 1.0), hmean[:, None])[cond]
        pc = p[cond]
    else:
        pc, rho = p, np.repeat(radii[idx][:, None], 3, axis=1)

    # faces: "window" if a crossing edge leaves through it, else "surface"
    window = np.zeros((3, 2), dtype=bool)
    for ax in bounded:
        for s in (0, 1):
            window[ax, s] = bool(np.any((e_ax == ax) & (e_side == s)))
    L_mat = box_len.astype(np.float64).copy()
    c_lo, c_hi = pc.min(axis=0), pc.max(axis=0)
    for ax in bounded:
        lo_f = lo_w[ax] if window[ax, 0] else float(np.min(pc[:, ax] - rho[:, ax]))
        hi_f = hi_w[ax] if window[ax, 1] else float(np.max(pc[:, ax] + rho[:, ax]))
        L_mat[ax] = hi_f - lo_f
    V_mat = float(np.prod(L_mat)) if volume is None else float(volume)
    if not V_mat > 0:
        raise ValueError(f"`volume` must be positive (m^3); got {V_mat!r}")
    if boundary_width is None:
        boundary_width = 2.0 * float(np.max(radii[idx]))

    W = sp.coo_matrix((np.concatenate([Gi, Gi]), (np.concatenate([ia, ib]), np.concatenate([ib, ia]))),
                      shape=(n, n)).tocsr()
    wsum = np.asarray(W.sum(axis=1)).ravel()
    ncomp, comp = connected_components(W, directed=False)
    order = np.arange(n)[::-1]
    first = np.full(ncomp, -1, dtype=np.int64)
    first[comp[order]] = order

    K = np.zeros((3, 3))
    Kaff = np.zeros((3, 3))
    held_any = np.zeros(n, dtype=bool)
    held_out = []
    for beta in range(3):
        held = np.zeros(n, dtype=bool)
        P_lo, P_hi = -np.inf, np.inf
        if not through[beta]:
            ref_lo = lo_w[beta] if window[beta, 0] else c_lo[beta]
            ref_hi = hi_w[beta] if window[beta, 1] else c_hi[beta]
            w = min(float(boundary_width), 0.25 * float(ref_hi - ref_lo))
            P_lo = ref_lo if window[beta, 0] else ref_lo + w
            P_hi = ref_hi if window[beta, 1] else ref_hi - w
            if not window[beta, 0]:
                held |= p[:, beta] <= P_lo
            if not window[beta, 1]:
                held |= p[:, beta] >= P_hi
        dirich = e_ax == beta
        if through[beta]:
            dirich[:] = False
        neum = ~dirich
        held_any |= held
        held_out.append(e_out[dirich])
        anchored = np.zeros(ncomp, dtype=bool)
        anchored[comp[held]] = True
        anchored[comp[e_node[dirich]]] = True
        # lateral window faces: theta_out = theta_in; a cluster with no held node must have
        # zero net heat in steady state, so its mean crossing flux is subtracted
        gl_e = e_G * e_vec[:, beta]
        mu = np.zeros(e_G.size)
        sub = neum & ~anchored[comp[e_node]]
        if np.any(sub):
            cs = comp[e_node[sub]]
            mu[sub] = -(np.bincount(cs, gl_e[sub], minlength=ncomp)[cs]
                        / np.bincount(cs, e_G[sub], minlength=ncomp)[cs])
        gl = Gi * li[:, beta]
        B = (np.bincount(ia, gl, minlength=n) - np.bincount(ib, gl, minlength=n)
             + np.bincount(e_node, gl_e + e_G * mu * neum, minlength=n))
        dg = wsum + np.bincount(e_node[dirich], e_G[dirich], minlength=n)
        # gauge: one pinned node per cluster without held nodes or held edges
        fixed = held.copy()
        fixed[first[~anchored]] = True
        free = np.flatnonzero(~fixed)
        theta = np.zeros(n)
        if free.size:
            Wf = W[free][:, free].tocsr()
            if free.size <= _STEADY_DIRECT_MAX:
                from scipy.sparse.linalg import splu
                A = (sp.diags(dg[free]) - Wf).tocsc()
                theta[free] = splu(A).solve(np.ascontiguousarray(B[free]))
            else:
                Wf.sort_indices()
                wrow = np.asarray(Wf.sum(axis=1)).ravel()
                nf = free.size
                bounds = _k.chunk_bounds(nf, 64)
                work = [np.empty(nf) for _ in range(4)]
                x = np.zeros(nf)
                it = _k.pcg_solve(Wf.indptr.astype(np.int64), Wf.indices.astype(np.int32),
                                  Wf.data.astype(np.float64), np.ascontiguousarray(dg[free]), wrow,
                                  np.ascontiguousarray(B[free]), x, 1e-10 * float(np.max(L_mat)),
                                  20 * nf, bounds, *work, np.empty(64), np.empty(64), np.zeros(1))
                if it > 20 * nf:
                    raise RuntimeError("conductivity_tensor: CG did not converge")
                theta[free] = x
        # weighted flux: internal contacts, then crossing edges
        dT_i = li[:, beta] + theta[ib] - theta[ia]
        dT_e = np.where(dirich, e_vec[:, beta] - theta[e_node], e_vec[:, beta] + mu)
        if through[beta]:
            w_i, w_e = np.ones(Gi.size), e_t
        else:
            w_i = _segment_fraction(p[ia, beta], li[:, beta], 1.0, P_lo, P_hi)
            w_e = _segment_fraction(p[e_node, beta], e_vec[:, beta], e_t, P_lo, P_hi)
        V_b = V_mat
        if volume is None and not through[beta]:
            V_b = V_mat / L_mat[beta] * (P_hi - P_lo)
        K[:, beta] = ((w_i * Gi * dT_i) @ li + (w_e * e_G * dT_e) @ e_vec) / V_b
        Kaff[:, beta] = ((w_i * Gi * li[:, beta]) @ li + (w_e * e_G * e_vec[:, beta]) @ e_vec) / V_b
    asym = float(np.linalg.norm(K - K.T) / np.linalg.norm(K)) if np.any(K) else 0.0
    Ks = 0.5 * (K + K.T)
    affine = 0.5 * (Kaff + Kaff.T)
    wl = np.concatenate([np.ones(Gi.size), e_t])
    lall = np.concatenate([li, e_vec])
    d_all = np.linalg.norm(lall, axis=1)
    nrm = lall / np.where(d_all > 0, d_all, 1.0)[:, None]
    fabric = (nrm * wl[:, None]).T @ nrm / max(float(wl.sum()), 1e-300)
    kw, kv = _eig_desc(Ks)
    fw, fv = _eig_desc(fabric)
    n_fixed = int(held_any.sum()) + int(np.unique(np.concatenate(held_out)).size)
    names = []
    for ax in range(3):
        if through[ax]:
            names.append("periodic")
        else:
            lo_n, hi_n = ("window" if window[ax, s] else "surface" for s in (0, 1))
            names.append(lo_n if lo_n == hi_n else f"{lo_n}/{hi_n}")
    return ConductivityTensor(tensor=Ks, eigenvalues=kw, eigenvectors=kv, affine=affine, fabric=fabric,
                              fabric_eigenvalues=fw, fabric_eigenvectors=fv, volume=V_mat,
                              n_particles=int(n), n_contacts=n_contacts, n_fixed=n_fixed,
                              asymmetry=asym, boundary=tuple(names))
