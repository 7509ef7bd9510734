"""Radius-aware contact detection between spheres, and between spheres and plane walls.

Two spheres are in contact when their centre distance is at most
``r_i + r_j + tolerance``. Detection uses a cell list in fractional (box)
coordinates, so it is exact for any mix of periodic and fixed axes and for
triclinic boxes; all arithmetic is float64.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..core.contacts import Contacts, WallContacts
from ..core.frame import _as_frame
from . import _contact_kernels as _k
from .dimension import flat_axis

__all__ = ["find_contacts", "Wall", "ContactMatch", "compare_contacts"]

log = logging.getLogger(__name__)

_FACES = {"xlo": (0, 0), "xhi": (0, 1), "ylo": (1, 0), "yhi": (1, 1), "zlo": (2, 0), "zhi": (2, 1)}


@dataclass(frozen=True)
class Wall:
    """An infinite plane wall.

    Parameters
    ----------
    point : (3,) array_like of float, length
        Any point on the plane.
    normal : (3,) array_like of float
        Direction pointing from the wall into the region of the particles
        (normalised on construction).
    name : str, optional
        Label used in reports.

    Examples
    --------
    >>> w = Wall.plate(0.5)
    >>> w.point.tolist(), w.normal.tolist()
    ([0.0, 0.0, 0.5], [0.0, 0.0, 1.0])
    """

    point: np.ndarray
    normal: np.ndarray
    name: str = ""

    def __post_init__(self):
        p = np.asarray(self.point, dtype=np.float64).reshape(-1)
        n = np.asarray(self.normal, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or n.shape != (3,):
            raise ValueError(f"wall `point` and `normal` must have shape (3,); got {p.shape}, {n.shape}")
        norm = float(np.linalg.norm(n))
        if not np.isfinite(norm) or norm == 0.0:
            raise ValueError(f"wall `normal` must be a finite non-zero vector; got {n.tolist()}")
        object.__setattr__(self, "point", p)
        object.__setattr__(self, "normal", n / norm)

    @classmethod
    def plate(cls, z0: float, *, axis: int = 2) -> "Wall":
        """A horizontal build plate at ``z = z0`` with particles above it."""
        p = np.zeros(3)
        p[axis] = float(z0)
        n = np.zeros(3)
        n[axis] = 1.0
        return cls(p, n, name=f"plate {'xyz'[axis]}={float(z0):g}")

    def signed_distance(self, positions) -> np.ndarray:
        """Distance of points from the plane, positive on the particle side (length)."""
        return (np.asarray(positions, dtype=np.float64) - self.point) @ self.normal


def _as_walls(walls, box) -> list[Wall]:
    if walls is None:
        return []
    if isinstance(walls, (str, Wall)):
        walls = [walls]
    out = []
    for w in walls:
        if isinstance(w, Wall):
            out.append(w)
        elif isinstance(w, str):
            if w not in _FACES:
                raise ValueError(f"wall names must be one of {sorted(_FACES)}; got {w!r}")
            axis, side = _FACES[w]
            m = box.matrix
            recip = np.linalg.inv(m)[axis]  # normal of the face spanned by the other edges
            point = box.lo + (m[:, axis] if side else 0.0)
            out.append(Wall(point, recip if side == 0 else -recip, name=w))
        elif isinstance(w, (tuple, list)) and len(w) == 2:
            out.append(Wall(w[0], w[1]))
        else:
            raise TypeError("each wall must be a Wall, a box face name such as 'zlo', or a "
                            f"(point, normal) pair; got {w!r}")
    return out


def _perpendicular_widths(box) -> np.ndarray:
    """Distances between opposite box faces (length), matching ``_prepare``'s scaling."""
    if not box.is_triclinic:
        return np.where(box.lengths > 0, box.lengths, 1.0)
    m = box.matrix
    a, b, c = m[:, 0], m[:, 1], m[:, 2]
    vol = abs(float(np.dot(a, np.cross(b, c))))
    out = np.empty(3)
    for k, (u, v) in enumerate(((b, c), (c, a), (a, b))):
        area = float(np.linalg.norm(np.cross(u, v)))
        out[k] = vol / area if area > 0 else 0.0
    return out


def _prepare(frame):
    """Positions wrapped into the box along periodic axes, and fractional coordinates.

    Orthogonal boxes: particles already inside keep their coordinates exactly;
    only those outside along a periodic axis are moved by whole periods.
    """
    box = frame.box
    per = np.array(box.periodic)
    if box.is_triclinic:
        pos = box.wrap(frame.positions) if per.any() else frame.positions
        s = box.fractional(pos)
        for k in np.flatnonzero(per):
            col = s[:, k]
            col -= np.floor(col)
            col[col >= 1.0] = 0.0
        return pos, s
    lengths = np.where(box.lengths > 0, box.lengths, 1.0)
    pos = frame.positions
    s = (pos - box.lo) / lengths
    for k in np.flatnonzero(per):
        col = s[:, k]
        bad = np.flatnonzero((col < 0.0) | (col >= 1.0))
        if bad.size:
            if pos is frame.positions:
                pos = pos.copy()
            v = col[bad] - np.floor(col[bad])
            v[v >= 1.0] = 0.0
            col[bad] = v
            pos[bad, k] = box.lo[k] + v * box.lengths[k]
    return pos, s


def _cell_list(s, periodic, widths, cutoff, n, subdivide=1):
    """Cells per axis, stencil reach, integer cell of each particle."""
    ncell = np.ones(3, dtype=np.int64)
    origin = np.zeros(3)
    span = np.ones(3)
    for k in range(3):
        if not periodic[k]:
            lo_k, hi_k = (float(s[:, k].min()), float(s[:, k].max())) if n else (0.0, 0.0)
            origin[k] = lo_k
            span[k] = hi_k - lo_k
        extent = span[k] * widths[k]
        if cutoff > 0 and extent > 0:
            ncell[k] = max(1, int(math.floor(subdivide * extent / (cutoff * (1.0 + 1e-9)))))
    limit = max(2 * n, 64)
    while np.prod(ncell) > limit:
        k = int(np.argmax(ncell))
        ncell[k] = max(1, ncell[k] // 2)
    reach = np.ones(3, dtype=np.int64)
    for k in range(3):
        extent = span[k] * widths[k]
        if periodic[k]:
            if widths[k] <= 0:
                raise ValueError(f"periodic axis {'xyz'[k]} has zero width")
            reach[k] = int(math.floor(ncell[k] * cutoff / widths[k])) + 1
        else:
            r = int(math.floor(ncell[k] * cutoff / extent)) + 1 if extent > 0 else 1
            reach[k] = min(r, ncell[k] - 1)
    safe_span = np.where(span > 0, span, 1.0)
    cell = np.floor((s - origin) / safe_span * ncell).astype(np.int64)
    np.clip(cell, 0, ncell - 1, out=cell)
    return ncell, reach, cell


def find_contacts(frame, tolerance: float = 0.0, walls=None, *, parallel: bool = True) -> Contacts:
    """Find all sphere-sphere (and optionally sphere-wall) contacts of a frame.

    Parameters
    ----------
    frame : Frame or (box, positions, radii)
        The spheres; positions in any length unit (results use the same).
    tolerance : float, length, optional
        Extra gap still counted as contact: a pair is in contact when
        ``|x_j - x_i| <= r_i + r_j + tolerance``. Default 0 (touching or
        overlapping). Use a small positive value (e.g. ``1e-9 * d``) for
        lattices of exactly touching spheres written with rounding.
    walls : sequence, optional
        Plane walls, each a :class:`Wall`, a box face name (``"zlo"``,
        ``"xhi"`` ...) or a ``(point, normal)`` pair with the normal pointing
        towards the particles. Particle-wall contacts (signed distance to the
        plane at most ``r + tolerance``) go to ``contacts.walls``.
    parallel : bool, optional
        Use numba's threads (default True).

    Returns
    -------
    Contacts
        One row per contact, sorted by ``(i, j)``, ``i < j`` (``i == j`` only for a sphere touching
        its own periodic image in a box narrower than two diameters). In a 2-D
        run (:func:`~bedstruct.analysis.flat_axis`) the particles are discs in
        the plane: images across the flat axis are not contacts. The
        ``branch`` vector points from ``i`` to the (image of) ``j``; ``area``
        holds the lens area ``pi a^2`` (0 for non-touching near contacts);
        ``periodic`` marks pairs found through a periodic image after
        wrapping the positions into the box.

    Raises
    ------
    ValueError
        If ``tolerance`` is not finite or leaves a non-positive cutoff.

    Notes
    -----
    The cell list lives in fractional coordinates with at least
    ``2 r_max + tolerance`` between opposite faces of a cell, so neighbours lie
    in adjacent cells for orthogonal and triclinic boxes alike. Along a
    periodic axis a neighbour cell outside the box is wrapped and the image
    shift applied; boxes narrower than the cutoff use a wider stencil, so every
    image within reach is found. Lens radius of two overlapping spheres at
    distance :math:`d`:

    .. math:: a^2 = r_i^2 - \\left(\\frac{d^2 + r_i^2 - r_j^2}{2d}\\right)^2 .

    .. versionadded:: 0.1

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[0.5, 1, 1], [1.4, 1, 1], [3.6, 1, 1]], [0.5] * 3,
    ...           box=([0, 0, 0], [4, 2, 2]))          # periodic along x
    >>> c = find_contacts(f)
    >>> c.i.tolist(), c.j.tolist(), c.periodic.tolist()
    ([0, 0], [1, 2], [False, True])
    >>> c.normals.round(3).tolist()
    [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]
    >>> c.overlap.round(6).tolist()
    [0.1, 0.1]
    """
    frame = _as_frame(frame)
    tol = float(tolerance)
    if not math.isfinite(tol):
        raise ValueError(f"`tolerance` must be finite; got {tolerance!r}")
    box = frame.box
    n = frame.n_particles
    radii = frame.radii
    wall_list = _as_walls(walls, box)
    periodic = np.array(box.periodic)
    if n == 0:
        empty = np.zeros(0, dtype=np.int64)
        wc = _wall_contacts(np.zeros((0, 3)), radii, wall_list, tol) if wall_list else None
        return Contacts(i=empty, j=empty, branch=np.zeros((0, 3)), radii_i=np.zeros(0),
                        radii_j=np.zeros(0), ids_i=empty, ids_j=empty, area=np.zeros(0),
                        n_particles=0, walls=wc)
    cutoff = 2.0 * float(radii.max()) + tol
    if cutoff <= 0:
        raise ValueError(f"`tolerance` ({tol}) leaves no positive cutoff (2 r_max + tolerance)")
    flat = flat_axis(frame)
    pos, s = _prepare(frame)
    widths = _perpendicular_widths(box)
    ncell, reach, cell = _cell_list(s, periodic, widths, cutoff, n)
    lin = (cell[:, 0] * ncell[1] + cell[:, 1]) * ncell[2] + cell[:, 2]
    order = np.argsort(lin, kind="stable")
    n_cells = int(np.prod(ncell))
    cell_start = np.zeros(n_cells + 1, dtype=np.int64)
    np.cumsum(np.bincount(lin, minlength=n_cells), out=cell_start[1:])
    spos = np.ascontiguousarray(pos[order])
    srad = np.ascontiguousarray(radii[order])
    scell = np.ascontiguousarray(cell[order])
    per_i = periodic.astype(np.int64)
    matrix = np.ascontiguousarray(box.matrix)
    sdtype = np.int8 if int(reach.max()) < 100 else np.int64
    jdtype = np.int32 if n < 2**31 - 1 else np.int64
    args = (spos, srad, scell, cell_start, ncell, per_i, reach, matrix, tol)
    from .._numba import get_num_threads, set_num_threads
    threads = get_num_threads()
    if not parallel:
        set_num_threads(1)
    try:
        i, j, shift = _scan(args, order, jdtype, sdtype)
        if flat is not None and periodic[flat]:
            # a disc of a 2-D run does not touch its images across the plane
            keep = shift[:, flat] == 0
            i, j, shift = i[keep], j[keep], shift[keep]
        rows = np.argsort(i * np.int64(n) + j, kind="stable")
        i, j, shift = i[rows], j[rows], np.ascontiguousarray(shift[rows])
        branch = np.empty((i.size, 3), dtype=np.float64)
        area = np.empty(i.size, dtype=np.float64)
        _k.pair_geometry(i, j, shift, np.ascontiguousarray(pos), radii, matrix, branch, area)
    finally:
        if not parallel:
            set_num_threads(threads)
    crosses = np.any(shift != 0, axis=1)
    m = i.size
    ri = radii[i]
    rj = radii[j]
    wc = _wall_contacts(pos, radii, wall_list, tol) if wall_list else None
    log.debug("find_contacts: %d particles, %d contacts, cells %s, reach %s", n, m, ncell, reach)
    return Contacts(i=i, j=j, branch=branch, radii_i=ri, radii_j=rj, ids_i=frame.ids[i],
                    ids_j=frame.ids[j], periodic=crosses, area=area, n_particles=n,
                    source="geometric", walls=wc)


def _scan(args, order, jdtype, sdtype, cap=12):
    """Pair scan with a fixed per-particle capacity (overflowing rows are rescanned).

    Returns original-index pairs ``i <= j`` and their integer image shifts.
    """
    n = order.shape[0]
    rows = np.arange(n, dtype=np.int64)
    out_j = np.empty((n, cap), dtype=jdtype)
    out_s = np.empty((n, cap, 3), dtype=sdtype)
    counts = np.empty(n, dtype=np.int64)
    _k.scan_pairs(rows, *args, cap, out_j, out_s, counts)
    over = np.flatnonzero(counts > cap)
    take = np.minimum(counts, cap)
    take[over] = 0
    parts = [(rows, take, out_j, out_s)]
    if over.size:
        cap2 = int(counts[over].max())
        oj = np.empty((over.size, cap2), dtype=jdtype)
        osh = np.empty((over.size, cap2, 3), dtype=sdtype)
        oc = np.empty(over.size, dtype=np.int64)
        _k.scan_pairs(over, *args, cap2, oj, osh, oc)
        parts.append((over, oc, oj, osh))
    m = int(sum(int(p[1].sum()) for p in parts))
    i = np.empty(m, dtype=np.int64)
    j = np.empty(m, dtype=np.int64)
    shift = np.empty((m, 3), dtype=np.int64)
    base = 0
    for r, t, oj, osh in parts:
        offsets = np.zeros(r.size, dtype=np.int64)
        np.cumsum(t[:-1], out=offsets[1:])
        offsets += base
        _k.compact_pairs(r, t, offsets, oj, osh, order, i, j, shift)
        base += int(t.sum())
    return i, j, shift


def _wall_contacts(pos, radii, walls, tol) -> WallContacts:
    parts, widx, normals, overlaps = [], [], [], []
    for k, w in enumerate(walls):
        dist = w.signed_distance(pos)
        hit = np.flatnonzero(dist <= radii + tol)
        parts.append(hit)
        widx.append(np.full(hit.size, k, dtype=np.int64))
        normals.append(np.broadcast_to(-w.normal, (hit.size, 3)))
        overlaps.append(radii[hit] - dist[hit])
    particle = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
    return WallContacts(particle=particle, wall=np.concatenate(widx) if widx else particle,
                        normals=np.concatenate(normals) if normals else np.zeros((0, 3)),
                        overlap=np.concatenate(overlaps) if overlaps else np.zeros(0),
                        radii=radii[particle])


@dataclass(frozen=True)
class ContactMatch:
    """How two contact lists of the same frame agree (matched by particle ids).

    Attributes
    ----------
    n_common : int
        Pairs present in both lists.
    only_a, only_b : (K, 2) ndarray of int
        Id pairs (smaller id first) present in only one list.
    max_normal_difference : float
        Largest ``|n_a - n_b|`` over common pairs (dimensionless), with the
        normals oriented from the smaller to the larger id.
    """

    n_common: int
    only_a: np.ndarray
    only_b: np.ndarray
    max_normal_difference: float

    @property
    def identical(self) -> bool:
        """True when both lists hold the same pairs."""
        return self.only_a.shape[0] == 0 and self.only_b.shape[0] == 0


def _keyed(c: Contacts):
    if c.ids_i is None or c.ids_j is None:
        raise ValueError("contacts to compare must carry particle ids (`ids_i`, `ids_j`)")
    lo = np.minimum(c.ids_i, c.ids_j)
    hi = np.maximum(c.ids_i, c.ids_j)
    sign = np.where(c.ids_i <= c.ids_j, 1.0, -1.0)
    return lo, hi, c.normals * sign[:, None]


def compare_contacts(a: Contacts, b: Contacts) -> ContactMatch:
    """Compare two contact lists of one frame (e.g. geometric vs dumped).

    Pairs are matched by their particle ids regardless of order.

    Parameters
    ----------
    a, b : Contacts
        Contact lists with ``ids_i``/``ids_j``.

    Returns
    -------
    ContactMatch

    Examples
    --------
    >>> from bedstruct import Frame
    >>> f = Frame([[0, 0, 0], [0.9, 0, 0], [1.8, 0, 0]], [0.5] * 3, box=([-1] * 3, [3] * 3))
    >>> m = compare_contacts(find_contacts(f), find_contacts(f.select([0, 1])))
    >>> m.n_common, m.only_a.tolist()
    (1, [[2, 3]])
    """
    la, ha, na = _keyed(a)
    lb, hb, nb = _keyed(b)
    big = int(max(ha.max(initial=0), hb.max(initial=0))) + 1
    ka = la * big + ha
    kb = lb * big + hb
    common, ia, ib = np.intersect1d(ka, kb, assume_unique=False, return_indices=True)
    diff = float(np.max(np.linalg.norm(na[ia] - nb[ib], axis=1), initial=0.0))
    only_a = np.setdiff1d(ka, kb)
    only_b = np.setdiff1d(kb, ka)

    def pairs(k):
        return np.stack([k // big, k % big], axis=1).astype(np.int64)
    return ContactMatch(int(common.size), pairs(only_a), pairs(only_b), diff)
