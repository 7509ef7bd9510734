"""ASCII STL generators for walls: a box, the recoater blade and the roller, and the
wall meshes of the repose box and the spreading platform.

Coordinates are in the deck's length unit (SI metres for bedstruct's decks).
Triangles are wound so that normals point out of the solid (or into the box
with ``inward=True``), and each facet's normal is written explicitly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["stl_text", "write_stl", "box_triangles", "BladeGeometry", "cylinder_triangles",
           "RollerGeometry", "read_stl_triangles", "repose_wall_stls"]


def stl_text(triangles, *, name: str = "bedstruct") -> str:
    """ASCII STL text of ``triangles``.

    Parameters
    ----------
    triangles : (M, 3, 3) array_like of float, length
        Vertices of each triangle, counter-clockwise seen from outside.
    name : str
        Solid name.

    Returns
    -------
    str

    Examples
    --------
    >>> print(stl_text([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], name="t"))  # doctest: +NORMALIZE_WHITESPACE
    solid t
     facet normal 0 0 1
      outer loop
       vertex 0 0 0
       vertex 1 0 0
       vertex 0 1 0
      endloop
     endfacet
    endsolid t
    """
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(normals, axis=1)
    if np.any(norm == 0):
        raise ValueError("`triangles` contains a degenerate (zero-area) triangle")
    normals = normals / norm[:, None]
    out = [f"solid {name}"]
    for t, n in zip(tri, normals):
        out.append(" facet normal " + " ".join(f"{v:.10g}" for v in n + 0.0))
        out.append("  outer loop")
        for v in t:
            out.append("   vertex " + " ".join(f"{c:.10g}" for c in v))
        out.append("  endloop")
        out.append(" endfacet")
    out.append(f"endsolid {name}")
    return "\n".join(out)


def write_stl(path, triangles, *, name: str = "bedstruct") -> Path:
    """Write ``triangles`` ((M, 3, 3), length) as an ASCII STL file; returns the path."""
    path = Path(path)
    path.write_text(stl_text(triangles, name=name) + "\n")
    return path


def read_stl_triangles(path) -> np.ndarray:
    """Vertices (M, 3, 3) of an ASCII STL file (normals are ignored)."""
    verts = [list(map(float, line.split()[1:4])) for line in Path(path).read_text().splitlines()
             if line.strip().startswith("vertex")]
    if len(verts) % 3:
        raise ValueError(f"{path}: vertex count {len(verts)} is not a multiple of 3")
    return np.array(verts, dtype=np.float64).reshape(-1, 3, 3)


def _prism(profile_xz, y0: float, y1: float, caps: bool = True) -> np.ndarray:
    """Triangles of a convex x-z polygon (counter-clockwise seen from -y) extruded in y."""
    P = np.asarray(profile_xz, dtype=np.float64)
    k = len(P)
    front = np.column_stack([P[:, 0], np.full(k, y0), P[:, 1]])
    back = np.column_stack([P[:, 0], np.full(k, y1), P[:, 1]])
    tris = []
    # seen from -y with x right and z up, counter-clockwise x-z order gives a +y normal;
    # the y0 cap must face -y, so reverse it there.
    for i in range(1, k - 1 if caps else 1):
        tris.append([front[0], front[i + 1], front[i]])
        tris.append([back[0], back[i], back[i + 1]])
    for i in range(k):
        j = (i + 1) % k
        tris.append([front[i], front[j], back[j]])
        tris.append([front[i], back[j], back[i]])
    tri = np.array(tris)
    # orient every facet outwards (the polygon is convex: compare with the centroid)
    c = np.concatenate([front, back]).mean(axis=0)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.einsum("ij,ij->i", n, tri.mean(axis=1) - c) < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return tri


def box_triangles(lo, hi, *, inward: bool = False) -> np.ndarray:
    """The 12 triangles of an axis-aligned box.

    Parameters
    ----------
    lo, hi : (3,) array_like of float, length
        Opposite corners.
    inward : bool
        Point normals into the box (a container) instead of out of it.

    Returns
    -------
    (12, 3, 3) ndarray of float

    Examples
    --------
    >>> tri = box_triangles([0, 0, 0], [1, 2, 3])
    >>> tri.shape
    (12, 3, 3)
    >>> n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    >>> float(0.5 * np.linalg.norm(n, axis=1).sum())  # surface area 2(2 + 3 + 6)
    22.0
    """
    lo = np.asarray(lo, dtype=np.float64).reshape(3)
    hi = np.asarray(hi, dtype=np.float64).reshape(3)
    if np.any(hi <= lo):
        raise ValueError(f"`hi` must exceed `lo` on every axis; got {lo} and {hi}")
    tri = _prism([[lo[0], lo[2]], [hi[0], lo[2]], [hi[0], hi[2]], [lo[0], hi[2]]], lo[1], hi[1])
    return tri[:, [0, 2, 1]] if inward else tri


@dataclass(frozen=True)
class BladeGeometry:
    """A recoater blade: a slab normal to x, spanning y, moving along +x.

    Parameters
    ----------
    x0 : float, m
        x of the blade's trailing (upstream, -x) face at t = 0.
    z_bottom : float, m
        Height of the lowest point of the blade (the gap above the plate when
        the plate is at z = 0).
    speed : float, m/s
        Constant speed along +x.
    thickness : float, m
        Blade thickness along x (seed: 0.5 mm).
    height : float, m
        Height of the trailing face above ``z_bottom``.
    bevel_deg : float, degrees
        Bevel of the bottom edge (seed: 10): the bottom face rises by
        ``thickness * tan(bevel)`` from the trailing to the leading (+x) face,
        so the leading face is shorter and powder in front of the blade is
        pushed under it. 0 gives a square edge.

    Examples
    --------
    >>> b = BladeGeometry(x0=1e-3, z_bottom=1e-4, speed=0.0254)
    >>> round(b.bevel_rise * 1e6, 2)  # micrometres
    88.16
    >>> b.triangles(0.0, 3e-3).shape
    (12, 3, 3)
    """

    x0: float
    z_bottom: float
    speed: float = 0.0254
    thickness: float = 0.5e-3
    height: float = 2.0e-3
    bevel_deg: float = 10.0

    def __post_init__(self):
        if not (self.thickness > 0 and self.height > 0):
            raise ValueError("`thickness` and `height` must be positive lengths")
        if not (0 <= self.bevel_deg < 90) or self.bevel_rise >= self.height:
            raise ValueError(f"`bevel_deg` must lie in [0, 90) and its rise stay below `height`; "
                             f"got {self.bevel_deg}")

    @property
    def bevel_rise(self) -> float:
        """Height gained by the bottom face across the thickness (m)."""
        return self.thickness * math.tan(math.radians(self.bevel_deg))

    def profile(self) -> np.ndarray:
        """The x-z outline at t = 0, (4, 2), counter-clockwise from the lowest corner."""
        x0, x1 = self.x0, self.x0 + self.thickness
        zb, zt = self.z_bottom, self.z_bottom + self.height
        return np.array([[x0, zb], [x1, zb + self.bevel_rise], [x1, zt], [x0, zt]])

    def triangles(self, y0: float, y1: float, *, caps: bool = True) -> np.ndarray:
        """Triangles of the blade spanning ``y0 <= y <= y1`` (m), normals outward.

        ``caps=False`` leaves out the two end faces (4 triangles): use it when
        the blade spans a periodic y direction, where LIGGGHTS would see the
        end caps as duplicate elements (they coincide modulo the period).
        """
        if y1 <= y0:
            raise ValueError(f"`y1` must exceed `y0`; got {y0} and {y1}")
        return _prism(self.profile(), y0, y1, caps)

    def write_stl(self, path, y0: float, y1: float, *, caps: bool = True) -> Path:
        """Write the blade as an ASCII STL file (for LIGGGHTS ``fix mesh/surface``)."""
        return write_stl(path, self.triangles(y0, y1, caps=caps), name="blade")


def cylinder_triangles(center_xz, radius: float, y0: float, y1: float, *, n_segments: int = 72,
                       n_y: int = 1) -> np.ndarray:
    """Triangles of the lateral surface of a cylinder along y (no end caps), normals outward.

    The polygon is inscribed: the facets lie at most ``radius (1 - cos(pi /
    n_segments))`` inside the true surface (0.1 % of the radius at 72).

    Parameters
    ----------
    center_xz : (2,) array_like of float, length
        Axis position (x, z).
    radius : float, length
    y0, y1 : float, length
        Extent along the axis.
    n_segments : int
        Facets around the circumference.
    n_y : int
        Facets along the axis (keeps the elements' aspect ratio moderate).

    Returns
    -------
    (2 n_segments n_y, 3, 3) ndarray of float

    Examples
    --------
    >>> tri = cylinder_triangles((0.0, 1.0), 0.5, 0.0, 2.0, n_segments=64, n_y=2)
    >>> tri.shape
    (256, 3, 3)
    >>> n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    >>> c = tri.mean(axis=1) - [0.0, 0.0, 1.0]
    >>> bool(np.all(n[:, 0] * c[:, 0] + n[:, 2] * c[:, 2] > 0))  # every normal points outward
    True
    >>> round(float(0.5 * np.linalg.norm(n, axis=1).sum()), 3)  # ~ 2 pi r L = 6.283
    6.281
    """
    if not (radius > 0 and y1 > y0 and n_segments >= 3 and n_y >= 1):
        raise ValueError("`radius` must be positive, `y1` > `y0`, `n_segments` >= 3, `n_y` >= 1")
    cx, cz = (float(v) for v in center_xz)
    th = np.linspace(0.0, 2 * np.pi, int(n_segments) + 1)[:-1]
    ys = np.linspace(y0, y1, int(n_y) + 1)
    tris = []
    for j in range(int(n_y)):
        for i in range(len(th)):
            a, b = th[i], th[(i + 1) % len(th)]
            p = [[cx + radius * math.cos(t), y, cz + radius * math.sin(t)]
                 for t in (a, b) for y in (ys[j], ys[j + 1])]
            # p: (a, y0), (a, y1), (b, y0), (b, y1)
            tris.append([p[0], p[1], p[3]])
            tris.append([p[0], p[3], p[2]])
    tri = np.array(tris, dtype=np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    c = tri.mean(axis=1)
    out = n[:, 0] * (c[:, 0] - cx) + n[:, 2] * (c[:, 2] - cz)
    flip = out < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return tri


@dataclass(frozen=True)
class RollerGeometry:
    """A roller: a cylinder along y translating along +x at ``speed`` and spinning at ``omega``.

    Parameters
    ----------
    x0 : float, m
        x of the axis at t = 0.
    z_bottom : float, m
        Height of the lowest point (the axis is at ``z_bottom + radius``).
    radius : float, m
    speed : float, m/s
    omega : float, rad/s
        Spin about +y (right-hand rule), as :class:`bedstruct.dem.Cylinder`:
        ``omega = -speed / radius`` moves the bottom of the roller forwards
        (counter-rotating).
    n_segments : int
        Facets around the STL cylinder (LIGGGHTS).

    Examples
    --------
    >>> r = RollerGeometry(x0=1e-3, z_bottom=0.0, radius=5e-4, speed=0.1, omega=-200.0)
    >>> r.center_z, round(r.top * 1e3, 3)
    (0.0005, 1.0)
    """

    x0: float
    z_bottom: float
    radius: float
    speed: float
    omega: float = 0.0
    n_segments: int = 72

    def __post_init__(self):
        if not self.radius > 0:
            raise ValueError(f"`radius` must be positive; got {self.radius}")

    @property
    def center_z(self) -> float:
        """z of the axis at t = 0 (m)."""
        return self.z_bottom + self.radius

    @property
    def top(self) -> float:
        """z of the top of the roller (m)."""
        return self.z_bottom + 2 * self.radius

    def triangles(self, y0: float, y1: float) -> np.ndarray:
        """STL facets spanning ``[y0, y1]``, elements no longer than ~4x their width."""
        arc = 2 * math.pi * self.radius / self.n_segments
        n_y = max(1, int(math.ceil((y1 - y0) / (4 * arc))))
        return cylinder_triangles((self.x0, self.center_z), self.radius, y0, y1,
                                  n_segments=self.n_segments, n_y=n_y)


# --------------------------------------------------------------------------- wall meshes
def _rect(x0, x1, y0, y1, z0, z1):
    """Two triangles of an axis-aligned rectangle (one of the extents is zero)."""
    if z0 == z1:
        a, b, c, d = [x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0]
    elif x0 == x1:
        a, b, c, d = [x0, y0, z0], [x0, y1, z0], [x0, y1, z1], [x0, y0, z1]
    else:
        a, b, c, d = [x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]
    return [[a, b, c], [a, c, d]]


def _chamber_meshes(folder, length: float, width: float, z_platform: float,
                    chamber_depth: float) -> dict[str, Path]:
    """Spreading platform ``[0, L] x [0, W]`` at ``z_platform`` and, with a chamber, its front
    wall at ``x = L`` from ``-chamber_depth`` to 0, written as STL files into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    L, W = length, width
    # square-ish strips: LIGGGHTS 3.8 stops with "assertion failed (region_neighbor_list_I.h)"
    # on a platform of two long triangles (here from a 6 mm x 0.6 mm platform on)
    n = max(1, int(math.ceil(L / W - 1e-9)))
    xs = np.linspace(0.0, L, n + 1)
    strips = [t for a, b in zip(xs[:-1], xs[1:]) for t in _rect(a, b, 0.0, W, z_platform, z_platform)]
    meshes = {"platform": write_stl(folder / "platform.stl", strips, name="platform")}
    if chamber_depth > 0:
        meshes["front"] = write_stl(folder / "front.stl",
                                    _rect(L, L, 0.0, W, -chamber_depth, 0.0), name="front")
    return meshes


def repose_wall_stls(geometry, folder) -> dict[str, Path]:
    """Write the LIGGGHTS wall meshes of ``geometry`` into ``folder``.

    Returns
    -------
    dict
        ``plate``, ``sides`` and (with a ledge) ``ledge`` -> STL path.

    Examples
    --------
    >>> import tempfile
    >>> from bedstruct.engines import ReposeGeometry
    >>> g = ReposeGeometry(1e-3, 5e-4, 5e-4, ledge_fraction=0.5, slide=1e-3)
    >>> sorted(repose_wall_stls(g, tempfile.mkdtemp()))
    ['ledge', 'plate', 'sides']
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    L, W, H = geometry.length, geometry.width, geometry.height
    out = {"plate": write_stl(folder / "plate.stl", _rect(0.0, L, 0.0, W, 0.0, 0.0), name="plate")}
    sides = _rect(0.0, 0.0, 0.0, W, 0.0, H) + _rect(L, L, 0.0, W, 0.0, H)
    if not geometry.periodic_width:
        sides += _rect(0.0, L, 0.0, 0.0, 0.0, H) + _rect(0.0, L, W, W, 0.0, H)
    out["sides"] = write_stl(folder / "sides.stl", sides, name="sides")
    if geometry.ledge is not None:
        x0, x1 = geometry.ledge
        out["ledge"] = write_stl(folder / "ledge.stl", _rect(x0, x1, 0.0, W, 0.0, 0.0), name="ledge")
    return out
