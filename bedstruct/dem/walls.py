"""Walls of the DEM engine: analytic primitives with prescribed motion (SI units).

Every wall is a small dataclass that knows its geometry at the reference time
and a constant translation velocity (a roller also spins). The simulation
turns walls into rows of one float table read by the kernels; wall motion can
be changed between runs with :meth:`Simulation.set_wall_motion
<bedstruct.dem.Simulation.set_wall_motion>`. All walls share the wall
material and the ``wall_*`` coefficients of the :class:`ContactModel`.

Walls do not have periodic images: place them away from periodic faces or
span the periodic direction (infinite planes, prisms and cylinders).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from . import _kernels as K

__all__ = ["Plane", "Rectangle", "Prism", "Blade", "Cylinder", "TriangleMesh", "box_walls",
           "repose_box", "read_stl"]

_BIG = 1e30


def _unit(name, v) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,):
        raise ConfigError(f"`{name}` must be a 3-vector; got shape {a.shape}")
    n = float(np.linalg.norm(a))
    if not n > 0:
        raise ConfigError(f"`{name}` must be a non-zero vector; got {a.tolist()}")
    return a / n


def _vec(name, v) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"`{name}` must be a finite 3-vector; got {v!r}")
    return a


class _Wall:
    name: str
    velocity: tuple

    def _row(self) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def row(self) -> np.ndarray:
        """The kernel row of this wall at time 0 (reference time 0)."""
        r = self._row()
        r[10:13] = _vec("velocity", self.velocity)
        r[13] = 0.0
        return r

    def state(self) -> dict:
        """JSON-ready description."""
        out = {"kind": type(self).__name__}
        for k, v in self.__dict__.items():
            if isinstance(v, np.ndarray):
                v = v.tolist()
            elif isinstance(v, tuple):
                v = [float(a) if np.isscalar(a) else a for a in v]
            out[k] = v
        return out


@dataclass
class Plane(_Wall):
    """Infinite one-sided plane through ``point`` with unit ``normal`` pointing to the particles.

    Parameters
    ----------
    point : (3,) array_like, m
    normal : (3,) array_like
        Direction towards the particle side (normalised).
    velocity : (3,) array_like, m/s
        Constant translation velocity.
    name : str

    Examples
    --------
    >>> Plane((0, 0, 0), (0, 0, 1), name="floor").row()[:7].tolist()
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    """

    point: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)
    velocity: tuple = (0.0, 0.0, 0.0)
    name: str = "plane"

    def _row(self):
        r = np.zeros(K.WALL_NCOL)
        r[0] = K.WALL_PLANE
        r[1:4] = _vec("point", self.point)
        r[4:7] = _unit("normal", self.normal)
        return r


@dataclass
class Rectangle(_Wall):
    """Finite thin plate (two-sided): centre, normal, in-plane axis and half sizes.

    ``axis`` is projected into the plane; the second in-plane axis is
    ``normal x axis``. Edges and corners are handled exactly (closest point).
    """

    center: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)
    axis: tuple = (1.0, 0.0, 0.0)
    half_sizes: tuple = (1.0, 1.0)
    velocity: tuple = (0.0, 0.0, 0.0)
    name: str = "rectangle"

    def _row(self):
        n = _unit("normal", self.normal)
        a = _vec("axis", self.axis)
        a = _unit("axis (projected into the plane)", a - np.dot(a, n) * n)
        h = np.asarray(self.half_sizes, dtype=np.float64)
        if h.shape != (2,) or not np.all(h > 0):
            raise ConfigError(f"`half_sizes` must be two positive lengths; got {self.half_sizes!r}")
        r = np.zeros(K.WALL_NCOL)
        r[0] = K.WALL_RECT
        r[1:4] = _vec("center", self.center)
        r[4:7] = n
        r[7:10] = a
        r[14:16] = h
        return r


@dataclass
class Prism(_Wall):
    """A convex polygon extruded along ``axis`` (half length ``half_length``, inf allowed).

    ``polygon`` lists up to 8 vertices ``(u, v)`` counter-clockwise in the
    plane spanned by ``u_axis`` and ``v = u_axis x axis``, relative to
    ``origin``.
    """

    origin: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 1.0, 0.0)
    u_axis: tuple = (1.0, 0.0, 0.0)
    polygon: tuple = ((0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0))
    half_length: float = math.inf
    velocity: tuple = (0.0, 0.0, 0.0)
    name: str = "prism"

    def _row(self):
        e = _unit("axis", self.axis)
        u = _vec("u_axis", self.u_axis)
        u = _unit("u_axis (projected normal to axis)", u - np.dot(u, e) * e)
        poly = np.asarray(self.polygon, dtype=np.float64)
        if poly.ndim != 2 or poly.shape[1] != 2 or not 3 <= poly.shape[0] <= 8:
            raise ConfigError(f"`polygon` must be 3 to 8 (u, v) vertices; got shape {poly.shape}")
        area = 0.5 * np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
        if area <= 0:
            raise ConfigError("`polygon` vertices must be counter-clockwise (positive area)")
        r = np.zeros(K.WALL_NCOL)
        r[0] = K.WALL_PRISM
        r[1:4] = _vec("origin", self.origin)
        r[4:7] = e
        r[7:10] = u
        r[14] = min(float(self.half_length), _BIG)
        r[17] = poly.shape[0]
        r[18:18 + 2 * poly.shape[0]] = poly.reshape(-1)
        return r


def Blade(*, gap: float, speed: float, x0: float, surface_z: float = 0.0,
          thickness: float = 0.5e-3, bevel_deg: float = 10.0, height: float = 5e-3,
          y_center: float = 0.0, width: float = math.inf, name: str = "blade") -> Prism:
    """The recoater blade: a 0.5 mm plate with a bevelled bottom edge moving along +x.

    The blade's lowest edge is at ``surface_z + gap`` on its trailing face;
    its bottom face rises at ``bevel_deg`` towards the leading face (the
    bevel faces the powder it pushes), so the leading bottom corner is
    ``thickness * tan(bevel)`` higher. The blade spans ``width`` along y
    (default infinite, for a y-periodic bed).

    Parameters
    ----------
    gap : float, m
        Height of the lowest edge above ``surface_z``.
    speed : float, m/s
        Blade speed along +x (negative moves along -x, the bevel then faces -x).
    x0 : float, m
        x of the blade mid-plane at time 0.

    Examples
    --------
    >>> b = Blade(gap=100e-6, speed=0.05, x0=0.0)
    >>> [round(v * 1e3, 4) for v in b.polygon[1]]  # leading bottom corner (mm)
    [0.25, 0.0882]
    """
    if not gap > 0 or not thickness > 0 or not height > thickness:
        raise ConfigError(f"blade needs gap > 0, thickness > 0 and height > thickness; got "
                          f"gap={gap}, thickness={thickness}, height={height}")
    t = thickness
    b = t * math.tan(math.radians(bevel_deg))
    s = 1.0 if speed >= 0 else -1.0
    if s > 0:
        poly = ((-t / 2, 0.0), (t / 2, b), (t / 2, height), (-t / 2, height))
    else:
        poly = ((-t / 2, b), (t / 2, 0.0), (t / 2, height), (-t / 2, height))
    return Prism(origin=(x0, y_center, surface_z + gap), axis=(0, 1, 0), u_axis=(1, 0, 0),
                 polygon=poly, half_length=width / 2, velocity=(speed, 0.0, 0.0), name=name)


@dataclass
class Cylinder(_Wall):
    """A roller: outer surface of a cylinder spinning at ``omega`` (rad/s) about ``axis``.

    Ends are open (no caps): a sphere beyond an end touches the rim circle. The roller may
    also translate with ``velocity``.
    """

    point: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 1.0, 0.0)
    radius: float = 1e-3
    half_length: float = math.inf
    omega: float = 0.0
    velocity: tuple = (0.0, 0.0, 0.0)
    name: str = "roller"

    def _row(self):
        if not self.radius > 0:
            raise ConfigError(f"`radius` must be positive; got {self.radius}")
        r = np.zeros(K.WALL_NCOL)
        r[0] = K.WALL_CYLINDER
        r[1:4] = _vec("point", self.point)
        r[4:7] = _unit("axis", self.axis)
        r[14] = min(float(self.half_length), _BIG)
        r[15] = float(self.radius)
        r[16] = float(self.omega)
        return r


@dataclass
class TriangleMesh(_Wall):
    """A triangle mesh wall (for example from an STL file), translating rigidly.

    The contact is with the closest triangle only (adequate for convex
    features and smooth meshes; a particle touching two triangles at a
    concave crease feels the nearer). Cost grows with the number of
    triangles; keep meshes small.
    """

    triangles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    velocity: tuple = (0.0, 0.0, 0.0)
    name: str = "mesh"

    def _row(self):
        tri = np.asarray(self.triangles, dtype=np.float64)
        if tri.ndim != 3 or tri.shape[1:] != (3, 3) or tri.shape[0] == 0:
            raise ConfigError(f"`triangles` must have shape (M, 3, 3) with M > 0; got {tri.shape}")
        r = np.zeros(K.WALL_NCOL)
        r[0] = K.WALL_MESH
        return r

    def state(self) -> dict:
        return {"kind": "TriangleMesh", "name": self.name, "n_triangles": int(len(self.triangles)),
                "velocity": list(map(float, self.velocity))}


def read_stl(path, *, scale: float = 1.0) -> np.ndarray:
    """Triangles (M, 3, 3) from an ASCII or binary STL file, multiplied by ``scale``."""
    with open(path, "rb") as fh:
        data = fh.read()
    if data[:5].lower() == b"solid" and b"facet" in data[:1000]:
        verts = [list(map(float, line.split()[1:4])) for line in data.decode(errors="replace").splitlines()
                 if line.strip().startswith("vertex")]
        tri = np.asarray(verts, dtype=np.float64).reshape(-1, 3, 3)
    else:
        n = int(np.frombuffer(data[80:84], dtype="<u4")[0])
        rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
        tri = np.frombuffer(data[84:84 + n * 50], dtype=rec)["v"].astype(np.float64)
    return tri * scale


def box_walls(lo, hi, *, open_top: bool = True, sides=("x", "y"), prefix: str = "box"):
    """Plates bounding the box ``[lo, hi]`` from inside: floor, sides, optional lid.

    ``sides`` selects the side pairs (``"x"``, ``"y"``); leave out a periodic
    axis. Returns a list of :class:`Rectangle` named ``{prefix}_zlo``, ...
    """
    lo = _vec("lo", lo)
    hi = _vec("hi", hi)
    c = 0.5 * (lo + hi)
    h = 0.5 * (hi - lo)
    walls = [Rectangle(center=(c[0], c[1], lo[2]), normal=(0, 0, 1), axis=(1, 0, 0),
                       half_sizes=(h[0], h[1]), name=f"{prefix}_zlo")]
    if not open_top:
        walls.append(Rectangle(center=(c[0], c[1], hi[2]), normal=(0, 0, -1), axis=(1, 0, 0),
                               half_sizes=(h[0], h[1]), name=f"{prefix}_zhi"))
    if "x" in sides:
        for x, nm in ((lo[0], "xlo"), (hi[0], "xhi")):
            walls.append(Rectangle(center=(x, c[1], c[2]), normal=(1, 0, 0), axis=(0, 1, 0),
                                   half_sizes=(h[1], h[2]), name=f"{prefix}_{nm}"))
    if "y" in sides:
        for y, nm in ((lo[1], "ylo"), (hi[1], "yhi")):
            walls.append(Rectangle(center=(c[0], y, c[2]), normal=(0, 1, 0), axis=(1, 0, 0),
                                   half_sizes=(h[0], h[2]), name=f"{prefix}_{nm}"))
    return walls


def repose_box(lo, hi, *, plate_name: str = "plate"):
    """Angle-of-repose box: four side plates and a bottom plate that can slide out.

    The bottom plate (named ``plate_name``) is as large as the box floor;
    start it moving with ``sim.set_wall_motion("plate", velocity=(v, 0, 0))``
    once the pile has settled. The side plates stop at the floor.
    """
    walls = box_walls(lo, hi, open_top=True, prefix="box")
    walls[0].name = plate_name
    return walls
