"""The simulation box: bounds, triclinic tilts and per-axis boundary flags."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Box"]

_VALID_FLAGS = frozenset("pfsm")


def _normalise_boundary(boundary) -> tuple[str, str, str]:
    if isinstance(boundary, str):
        boundary = boundary.split()
    boundary = tuple(str(b) for b in boundary)
    if len(boundary) != 3:
        raise ValueError(f"`boundary` needs one entry per axis (3); got {boundary!r}")
    out = []
    for axis, b in zip("xyz", boundary):
        if len(b) == 1:
            b = b + b
        if len(b) != 2 or any(c not in _VALID_FLAGS for c in b):
            raise ValueError(
                f"boundary flag for {axis} must be one or two of 'p', 'f', 's', 'm' "
                f"(LAMMPS style); got {b!r}")
        if ("p" in b) and b != "pp":
            raise ValueError(f"boundary flag for {axis}: periodic must apply to both sides "
                             f"('pp'); got {b!r}")
        out.append(b)
    return tuple(out)  # type: ignore[return-value]


@dataclass(frozen=True, eq=False)
class Box:
    """An orthogonal or triclinic simulation box with LAMMPS boundary flags.

    The box follows the LAMMPS convention: the edge vectors are
    ``a = (lx, 0, 0)``, ``b = (xy, ly, 0)`` and ``c = (xz, yz, lz)`` with
    ``l = hi - lo``, and a point is ``lo + s0 a + s1 b + s2 c`` for fractional
    coordinates ``s`` in [0, 1).

    Parameters
    ----------
    lo, hi : (3,) array_like of float, length
        Lower and upper bounds of the (untilted) box.
    tilt : (3,) array_like of float, length, optional
        Tilt factors ``(xy, xz, yz)``; zeros for an orthogonal box.
    boundary : sequence of 3 str, optional
        LAMMPS boundary flags per axis, one or two letters of ``p`` (periodic),
        ``f`` (fixed), ``s`` (shrink-wrapped), ``m`` (shrink-wrapped with a
        minimum), as ``("pp", "pp", "ff")`` or ``"pp pp ff"``. Default
        all periodic, as LAMMPS.

    Attributes
    ----------
    periodic : tuple of 3 bool
        Whether each axis is periodic.

    Examples
    --------
    >>> box = Box([0, 0, 0], [10, 10, 5], boundary="pp pp ff")
    >>> box.periodic
    (True, True, False)
    >>> box.volume
    500.0
    >>> box.minimum_image([[9.0, 1.0, 4.0]])
    array([[-1.,  1.,  4.]])
    >>> box.wrap([[11.0, -1.0, 7.0]])
    array([[1., 9., 7.]])
    """

    lo: np.ndarray
    hi: np.ndarray
    tilt: np.ndarray = field(default_factory=lambda: np.zeros(3))
    boundary: tuple[str, str, str] = ("pp", "pp", "pp")

    def __post_init__(self):
        lo = np.array(self.lo, dtype=np.float64).reshape(-1)
        hi = np.array(self.hi, dtype=np.float64).reshape(-1)
        tilt = np.array(self.tilt, dtype=np.float64).reshape(-1)
        if lo.shape != (3,) or hi.shape != (3,):
            raise ValueError(f"`lo` and `hi` must have shape (3,); got {lo.shape} and {hi.shape}")
        if tilt.shape != (3,):
            raise ValueError(f"`tilt` must have shape (3,) as (xy, xz, yz); got {tilt.shape}")
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(np.isfinite(tilt))):
            raise ValueError(f"box bounds must be finite; got lo={lo}, hi={hi}, tilt={tilt}")
        if np.any(hi < lo):
            raise ValueError(f"box `hi` must not be below `lo`; got lo={lo}, hi={hi}")
        for a in (lo, hi, tilt):
            a.setflags(write=False)
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)
        object.__setattr__(self, "tilt", tilt)
        object.__setattr__(self, "boundary", _normalise_boundary(self.boundary))

    # ------------------------------------------------------------------ basics
    @property
    def periodic(self) -> tuple[bool, bool, bool]:
        """Per-axis periodicity derived from the boundary flags."""
        return tuple(b == "pp" for b in self.boundary)  # type: ignore[return-value]

    @property
    def lengths(self) -> np.ndarray:
        """Edge lengths ``hi - lo`` (length)."""
        return self.hi - self.lo

    @property
    def is_triclinic(self) -> bool:
        """True when any tilt factor is non-zero."""
        return bool(np.any(self.tilt != 0.0))

    @property
    def matrix(self) -> np.ndarray:
        """(3, 3) matrix whose columns are the edge vectors a, b, c."""
        lx, ly, lz = self.lengths
        xy, xz, yz = self.tilt
        return np.array([[lx, xy, xz], [0.0, ly, yz], [0.0, 0.0, lz]])

    @property
    def volume(self) -> float:
        """Box volume (length^3); tilts do not change it."""
        return float(np.prod(self.lengths))

    def __eq__(self, other) -> bool:
        if not isinstance(other, Box):
            return NotImplemented
        return (np.array_equal(self.lo, other.lo) and np.array_equal(self.hi, other.hi)
                and np.array_equal(self.tilt, other.tilt) and self.boundary == other.boundary)

    def __repr__(self) -> str:
        s = f"Box(lo={self.lo.tolist()}, hi={self.hi.tolist()}"
        if self.is_triclinic:
            s += f", tilt={self.tilt.tolist()}"
        return s + f", boundary={' '.join(self.boundary)!r})"

    # ------------------------------------------------------------ constructors
    @classmethod
    def from_box(cls, obj: Any, *, boundary=None) -> "Box":
        """Build a box from box-like input.

        Accepts a :class:`Box`; a ``(lo, hi)`` pair; a (3,) array of lengths
        (box from the origin); a (6,) array ``xlo xhi ylo yhi zlo zhi``; or
        an object with ``lo`` and ``hi`` attributes.

        Examples
        --------
        >>> Box.from_box([2.0, 3.0, 4.0]).hi
        array([2., 3., 4.])
        """
        if isinstance(obj, Box):
            return obj if boundary is None else cls(obj.lo, obj.hi, obj.tilt, boundary)
        kw = {} if boundary is None else {"boundary": boundary}
        if hasattr(obj, "lo") and hasattr(obj, "hi"):
            return cls(obj.lo, obj.hi, getattr(obj, "tilt", np.zeros(3)),
                       boundary if boundary is not None else getattr(obj, "boundary", ("pp",) * 3))
        if isinstance(obj, tuple) and len(obj) == 2:
            return cls(obj[0], obj[1], **kw)
        try:
            arr = np.asarray(obj, dtype=np.float64)
        except (TypeError, ValueError):
            raise TypeError(f"cannot make a Box from {obj!r}") from None
        if arr.shape == (3,):
            return cls(np.zeros(3), arr, **kw)
        if arr.shape in ((6,), (3, 2)):
            arr = arr.reshape(3, 2)
            return cls(arr[:, 0], arr[:, 1], **kw)
        raise TypeError(f"cannot make a Box from {type(obj).__name__} with shape {arr.shape}")

    @classmethod
    def from_lammps_bounds(cls, bounds, tilt=None, boundary=("pp", "pp", "pp")) -> "Box":
        """Box from the bounds written in a LAMMPS dump header.

        For triclinic boxes LAMMPS writes the *bounding* box
        (``xlo_bound xhi_bound xy`` ...); this converts it back to the true
        ``lo``/``hi`` as the LAMMPS manual (Howto triclinic) describes.

        Parameters
        ----------
        bounds : (3, 2) array_like
            ``[[xlo, xhi], [ylo, yhi], [zlo, zhi]]`` as written.
        tilt : (3,) array_like, optional
            ``(xy, xz, yz)``; when given, ``bounds`` are the bounding box.
        boundary : sequence of 3 str
            The boundary flags of the header.

        Examples
        --------
        >>> b = Box.from_lammps_bounds([[-1, 10], [0, 10], [0, 10]], tilt=[-1, 0, 0])
        >>> b.lo, b.hi
        (array([0., 0., 0.]), array([10., 10., 10.]))
        """
        b = np.asarray(bounds, dtype=np.float64).reshape(3, 2)
        if tilt is None:
            return cls(b[:, 0], b[:, 1], np.zeros(3), boundary)
        xy, xz, yz = (float(t) for t in tilt)
        lo = b[:, 0].copy()
        hi = b[:, 1].copy()
        lo[0] -= min(0.0, xy, xz, xy + xz)
        hi[0] -= max(0.0, xy, xz, xy + xz)
        lo[1] -= min(0.0, yz)
        hi[1] -= max(0.0, yz)
        return cls(lo, hi, np.array([xy, xz, yz]), boundary)

    def lammps_bounds(self) -> np.ndarray:
        """(3, 2) bounds as LAMMPS writes them (bounding box for triclinic)."""
        xy, xz, yz = self.tilt
        b = np.stack([self.lo, self.hi], axis=1).copy()
        if self.is_triclinic:
            b[0, 0] += min(0.0, xy, xz, xy + xz)
            b[0, 1] += max(0.0, xy, xz, xy + xz)
            b[1, 0] += min(0.0, yz)
            b[1, 1] += max(0.0, yz)
        return b

    def replace(self, **changes) -> "Box":
        """A copy with some fields replaced (``lo``, ``hi``, ``tilt``, ``boundary``)."""
        kw = dict(lo=self.lo, hi=self.hi, tilt=self.tilt, boundary=self.boundary)
        kw.update(changes)
        return Box(**kw)

    # -------------------------------------------------------------- geometry
    def fractional(self, positions) -> np.ndarray:
        """Fractional coordinates ``s`` with ``x = lo + matrix @ s``."""
        x = np.asarray(positions, dtype=np.float64)
        d = x - self.lo
        if not self.is_triclinic:
            return d / self.lengths
        return np.linalg.solve(self.matrix, d.reshape(-1, 3).T).T.reshape(x.shape)

    def cartesian(self, fractional) -> np.ndarray:
        """Cartesian positions from fractional coordinates."""
        s = np.asarray(fractional, dtype=np.float64)
        if not self.is_triclinic:
            return self.lo + s * self.lengths
        return self.lo + s @ self.matrix.T

    def wrap(self, positions) -> np.ndarray:
        """Map positions into the box along periodic axes (others untouched).

        Returns a new float64 array of the same shape.
        """
        x = np.array(positions, dtype=np.float64, copy=True)
        per = np.array(self.periodic)
        if not per.any() or x.size == 0:
            return x
        if not self.is_triclinic:
            lo, length = self.lo[per], self.lengths[per]
            wrapped = lo + np.mod(x[..., per] - lo, length)
            # np.mod can return exactly `length` for tiny negative inputs
            x[..., per] = np.where(wrapped >= lo + length, lo, wrapped)
            return x
        s = self.fractional(x)
        s[..., per] -= np.floor(s[..., per])
        s[..., per] = np.where(s[..., per] >= 1.0, 0.0, s[..., per])
        return self.cartesian(s)

    def minimum_image(self, displacements) -> np.ndarray:
        """Minimum-image convention applied to displacement vectors.

        Periodic axes are reduced to the nearest image (for triclinic boxes
        in fractional coordinates, exact for displacements shorter than half
        the smallest periodic width, which LAMMPS guarantees by limiting
        tilts); non-periodic axes are left as they are.
        """
        d = np.array(displacements, dtype=np.float64, copy=True)
        per = np.array(self.periodic)
        if not per.any() or d.size == 0:
            return d
        if not self.is_triclinic:
            length = self.lengths[per]
            d[..., per] -= length * np.round(d[..., per] / length)
            return d
        s = np.linalg.solve(self.matrix, d.reshape(-1, 3).T).T
        s[:, per] -= np.round(s[:, per])
        return (s @ self.matrix.T).reshape(d.shape)

    def image_shift(self, displacements) -> np.ndarray:
        """Integer image counts that :meth:`minimum_image` subtracts, shape (..., 3)."""
        d = np.asarray(displacements, dtype=np.float64)
        per = np.array(self.periodic)
        s = self.fractional(d + self.lo) if self.is_triclinic else d / self.lengths
        n = np.where(per, np.round(s), 0.0)
        return n.astype(np.int64)

    def contains(self, positions) -> np.ndarray:
        """Boolean mask of positions inside the box (periodic axes always inside)."""
        s = self.fractional(positions)
        per = np.array(self.periodic)
        inside = (s >= 0.0) & (s <= 1.0)
        inside[..., per] = True
        return np.all(inside, axis=-1)
