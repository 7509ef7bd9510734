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
        Uniform-gradient (Voigt) bound ``(1/V) sum G l l^T``.
    fabric : (3, 3) ndarray
        Normal fabric tensor ``N_ij = <n_i n_j>`` of the conducting contacts.
    fabric_eigenvalues : (3,) ndarray
    fabric_eigenvectors : (3, 3) ndarray
    volume : float, m^3
    n_particles, n_contacts, n_fixed : int
        Particles and conducting contacts in the region, and particles held
        in the boundary slabs.
    asymmetry : float
        ``|K - K^T| / |K|`` of the raw tensor (0 with periodic boundaries).
    boundary : str
        Per axis ``"periodic"`` or ``"slabs"``.
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


def conductivity_tensor(network: ThermalNetwork, *, region=None, boundary_width=None,
                        volume=None) -> ConductivityTensor:
    """Effective conductivity tensor of a bed region from imposed gradients.

    For each axis a unit temperature gradient is imposed, ``T = g.x +
    theta`` with ``theta`` periodic along axes where the box is periodic and
    the region spans it, and ``theta = 0`` in slabs of particles at the
    region's faces along the other axes. The steady network equations give
    ``theta``; the mean flux of the region is

    .. math:: \\langle q \\rangle = -\\frac{1}{V} \\sum_c G_c (T_j - T_i)\\, l_c
              = -K g

    with ``l_c`` the branch vector, which yields one column of ``K`` per
    gradient. The normal fabric tensor ``N = <n n>`` of the same contacts is
    returned beside it.

    Parameters
    ----------
    network : ThermalNetwork
    region : ((3,), (3,)) array_like, optional, m
        ``(lo, hi)`` of a box; particles whose centres lie inside take part.
        Default all particles.
    boundary_width : float, optional, m
        Thickness of the held slabs; default the largest particle diameter.
    volume : float, optional, m^3
        Volume for the mean flux; default the region (periodic axes: the
        box length; otherwise the particles' extent, centres +- radii).

    Returns
    -------
    ConductivityTensor

    Notes
    -----
    For a periodic simple cubic lattice of spacing ``s`` with conductance
    ``G`` per contact, ``K = (G / s) I``.

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
    if region is None:
        inside = np.ones(n_all, dtype=bool)
        lo_r = hi_r = None
    else:
        lo_r, hi_r = (np.asarray(v, dtype=np.float64).reshape(3) for v in region)
        if np.any(hi_r <= lo_r):
            raise ValueError(f"`region` must be (lo, hi) with hi > lo (m); got {region!r}")
        inside = np.all((pos >= lo_r) & (pos <= hi_r), axis=1)
    idx = np.flatnonzero(inside)
    if idx.size < 2:
        raise ValueError(f"the region holds {idx.size} particles; need at least 2")
    box_len = net.box_hi - net.box_lo
    through = []
    for ax in range(3):
        spans = region is None or (lo_r[ax] <= net.box_lo[ax] + 1e-12 * box_len[ax]
                                   and hi_r[ax] >= net.box_hi[ax] - 1e-12 * box_len[ax])
        through.append(bool(net.periodic[ax] and spans))
    # contacts inside the region, conducting, not wrapping along a non-through axis
    rowmap = np.full(n_all, -1, dtype=np.int64)
    rowmap[idx] = np.arange(idx.size)
    ci, cj = rowmap[net.i], rowmap[net.j]
    keep = (ci >= 0) & (cj >= 0) & (net.conductance > 0)
    wrap = np.abs(pos[net.j] - pos[net.i] - net.branch)
    for ax in range(3):
        if not through[ax]:
            keep &= wrap[:, ax] <= 1e-9 * max(box_len[ax], 1e-300) + 1e-300
    ci, cj, G, l = ci[keep], cj[keep], net.conductance[keep], net.branch[keep]
    n = idx.size
    p = pos[idx]
    # held slabs
    if boundary_width is None:
        boundary_width = 2.0 * float(np.max(radii[idx]))
    held = np.zeros(n, dtype=bool)
    ext = np.empty(3)
    for ax in range(3):
        if through[ax]:
            ext[ax] = box_len[ax]
            continue
        lo_a = p[:, ax].min() if lo_r is None else lo_r[ax]
        hi_a = p[:, ax].max() if hi_r is None else hi_r[ax]
        held |= (p[:, ax] <= lo_a + boundary_width) | (p[:, ax] >= hi_a - boundary_width)
        ext[ax] = ((hi_r[ax] - lo_r[ax]) if lo_r is not None
                   else float(np.max(p[:, ax] + radii[idx]) - np.min(p[:, ax] - radii[idx])))
    V = float(np.prod(ext)) if volume is None else float(volume)
    if not V > 0:
        raise ValueError(f"`volume` must be positive (m^3); got {V!r}")
    W = sp.coo_matrix((np.concatenate([G, G]), (np.concatenate([ci, cj]), np.concatenate([cj, ci]))),
                      shape=(n, n)).tocsr()
    # gauge: one held node per component without held nodes
    ncomp, comp = connected_components(W, directed=False)
    has_held = np.zeros(ncomp, dtype=bool)
    has_held[comp[held]] = True
    first = np.full(ncomp, -1, dtype=np.int64)
    order = np.arange(n)[::-1]
    first[comp[order]] = order
    pin = first[~has_held]
    fixed = held.copy()
    fixed[pin] = True
    free = np.flatnonzero(~fixed)
    K = np.zeros((3, 3))
    if free.size:
        L = (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()
        Lff = L[free][:, free].tocsc()
        B = np.zeros((n, 3))
        for beta in range(3):
            gl = G * l[:, beta]
            B[:, beta] = np.bincount(ci, gl, minlength=n) - np.bincount(cj, gl, minlength=n)
        if free.size <= _STEADY_DIRECT_MAX:
            from scipy.sparse.linalg import splu
            theta_f = splu(Lff).solve(np.ascontiguousarray(B[free]))
        else:
            Wf = W[free][:, free].tocsr()
            Wf.sort_indices()
            d = np.asarray(L.diagonal())[free]
            wrow = np.asarray(Wf.sum(axis=1)).ravel()
            theta_f = np.zeros((free.size, 3))
            nf = free.size
            bounds = _k.chunk_bounds(nf, 64)
            work = [np.empty(nf) for _ in range(4)]
            tol = 1e-10 * float(np.max(box_len))
            for beta in range(3):
                x = np.zeros(nf)
                it = _k.pcg_solve(Wf.indptr.astype(np.int64), Wf.indices.astype(np.int32),
                                  Wf.data.astype(np.float64), d, wrow,
                                  np.ascontiguousarray(B[free, beta]), x, tol, 20 * nf, bounds,
                                  *work, np.empty(64), np.empty(64), np.zeros(1))
                if it > 20 * nf:
                    raise RuntimeError("conductivity_tensor: CG did not converge")
                theta_f[:, beta] = x
        theta = np.zeros((n, 3))
        theta[free] = theta_f
    else:
        theta = np.zeros((n, 3))
    for beta in range(3):
        dT = l[:, beta] + theta[cj, beta] - theta[ci, beta]
        K[:, beta] = (G * dT) @ l / V
    asym = float(np.linalg.norm(K - K.T) / np.linalg.norm(K)) if np.any(K) else 0.0
    Ks = 0.5 * (K + K.T)
    affine = (l * G[:, None]).T @ l / V
    dist = np.linalg.norm(l, axis=1)
    nrm = l / np.where(dist > 0, dist, 1.0)[:, None]
    fabric = nrm.T @ nrm / max(nrm.shape[0], 1)
    kw, kv = _eig_desc(Ks)
    fw, fv = _eig_desc(fabric)
    return ConductivityTensor(tensor=Ks, eigenvalues=kw, eigenvectors=kv, affine=affine, fabric=fabric,
                              fabric_eigenvalues=fw, fabric_eigenvectors=fv, volume=V,
                              n_particles=int(n), n_contacts=int(G.size), n_fixed=int(held.sum()),
                              asymmetry=asym,
                              boundary=tuple("periodic" if t else "slabs" for t in through))
