"""Fabric tensors per slab of a bed along the spreading direction
(:func:`contact_regions`, :func:`region_fabric`) and the table of several
results (:func:`fabric_table`).

Implementation module of :mod:`bedstruct.analysis.fabric` (import from there).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ._fabric_algebra import _readonly
from ._fabric_lammps import lammps_voigt
from ._fabric_tensors import FabricTensors, _resolve_weights, fabric_tensors

__all__ = ["contact_regions", "RegionFabric", "region_fabric", "fabric_table"]

_REGION_NAMES_3 = ("start", "centre", "end")


# --------------------------------------------------------------------------- regions
def _axis_index(axis) -> int:
    if isinstance(axis, str):
        key = axis.lower()
        if key not in ("x", "y", "z"):
            raise ValueError(f"`axis` must be 0, 1, 2 or 'x', 'y', 'z'; got {axis!r}")
        return "xyz".index(key)
    if axis not in (0, 1, 2):
        raise ValueError(f"`axis` must be 0, 1, 2 or 'x', 'y', 'z'; got {axis!r}")
    return int(axis)


def contact_regions(contacts, frame, *, axis=0, n_regions: int = 3, position="midpoint",
                    bounds=None):
    """Split contacts into ``n_regions`` equal slabs along an axis by contact position.

    Parameters
    ----------
    contacts : Contacts
        Contacts of ``frame`` (``i``, ``j``, ``branch``, ``radii_i``, ``radii_j``).
    frame : Frame
        The frame the contacts index (for particle positions and the box).
    axis : {0, 1, 2, "x", "y", "z"}
        The spreading direction. Default x.
    n_regions : int
        Number of equal slabs (default 3: start, centre, end).
    position : {"midpoint", "particle"}
        ``"midpoint"``: the contact point on the branch vector weighted by
        radii, :math:`x_i + b\\, r_i/(r_i + r_j)` (the centre of the overlap
        lens for touching spheres), wrapped into the box on periodic axes;
        ``"particle"``: the centre of particle ``i``.
    bounds : (2,) array_like of float or "box", optional
        Extent (length) divided into slabs. Default: the range of the
        frame's particle centres along ``axis``; ``"box"``: the box
        ``lo``/``hi``. Contacts outside get region -1.

    Returns
    -------
    labels : (M,) ndarray of int
        Region of each contact, 0 (start) to ``n_regions - 1`` (end), or -1.
    edges : (n_regions + 1,) ndarray of float, length
        Slab boundaries.

    Examples
    --------
    >>> import bedstruct
    >>> f = bedstruct.Frame([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [0.5] * 4,
    ...                     box=bedstruct.Box([-1, -1, -1], [4, 1, 1], boundary="ff ff ff"))
    >>> c = bedstruct.Contacts(i=[0, 1, 2], j=[1, 2, 3], branch=[[1, 0, 0]] * 3,
    ...                        radii_i=[0.5] * 3, radii_j=[0.5] * 3, n_particles=4)
    >>> labels, edges = contact_regions(c, f)
    >>> labels.tolist(), edges.tolist()
    ([0, 1, 2], [0.0, 1.0, 2.0, 3.0])
    """
    ax = _axis_index(axis)
    n_regions = int(n_regions)
    if n_regions < 1:
        raise ValueError(f"`n_regions` must be >= 1; got {n_regions}")
    if contacts.n_contacts and max(contacts.i.max(), contacts.j.max()) >= frame.n_particles:
        raise ValueError(f"`contacts` index particles up to {max(contacts.i.max(), contacts.j.max())} "
                         f"but `frame` has N={frame.n_particles}")
    if position == "midpoint":
        t = contacts.radii_i / (contacts.radii_i + contacts.radii_j)
        pts = frame.positions[contacts.i] + contacts.branch * t[:, None]
        if frame.box.periodic[ax] and pts.shape[0]:
            pts = frame.box.wrap(pts)
    elif position == "particle":
        pts = frame.positions[contacts.i]
    else:
        raise ValueError(f"`position` must be 'midpoint' or 'particle'; got {position!r}")
    if bounds is None:
        if frame.n_particles == 0:
            raise ValueError("`frame` has no particles; give `bounds`")
        lo, hi = float(frame.positions[:, ax].min()), float(frame.positions[:, ax].max())
    elif isinstance(bounds, str):
        if bounds != "box":
            raise ValueError(f"`bounds` must be (lo, hi) or 'box'; got {bounds!r}")
        lo, hi = float(frame.box.lo[ax]), float(frame.box.hi[ax])
    else:
        lo, hi = (float(b) for b in bounds)
    if not hi > lo:
        raise ValueError(f"`bounds` must satisfy lo < hi; got ({lo}, {hi})")
    edges = np.linspace(lo, hi, n_regions + 1)
    x = pts[:, ax]
    labels = np.floor((x - lo) / (hi - lo) * n_regions).astype(np.int64)
    labels[x == hi] = n_regions - 1
    labels[(x < lo) | (x > hi)] = -1
    return labels, edges


@dataclass(frozen=True)
class RegionFabric:
    """Fabric tensors of contacts in slabs along the spreading direction.

    Attributes
    ----------
    names : tuple of str
        ``("start", "centre", "end")`` for three regions, else ``"region k"``.
    edges : (n_regions + 1,) ndarray of float, length
        Slab boundaries along ``axis``.
    axis : int
        0, 1 or 2.
    tensors : tuple of FabricTensors or None
        One per region; None where a region has no contact.
    labels : (M,) ndarray of int
        Region of each contact (-1 outside).
    expansions : tuple of HarmonicExpansion or None, or None
        Per-region spherical-harmonic expansions when ``l_max`` was given.

    .. versionadded:: 0.1
    """

    names: tuple
    edges: np.ndarray
    axis: int
    tensors: tuple
    labels: np.ndarray = field(repr=False)
    expansions: tuple | None = field(default=None, repr=False)

    def __getitem__(self, key) -> FabricTensors | None:
        if isinstance(key, str):
            return self.tensors[self.names.index(key)]
        return self.tensors[key]

    def __len__(self) -> int:
        return len(self.tensors)


def region_fabric(contacts, frame, *, axis=0, n_regions: int = 3, weights=None,
                  position="midpoint", bounds=None, l_max: int | None = None) -> RegionFabric:
    """Fabric tensors of each slab (default thirds: start, centre, end) along an axis.

    Parameters
    ----------
    contacts, frame, axis, n_regions, position, bounds
        As for :func:`contact_regions`.
    weights : (M,) array_like or str, optional
        As for :func:`fabric_tensors` (strings select Contacts fields).
    l_max : int, optional
        Also expand each region in spherical harmonics to this degree
        (:func:`~bedstruct.analysis.harmonics.harmonic_expansion`).

    Returns
    -------
    RegionFabric

    Examples
    --------
    >>> import bedstruct
    >>> f = bedstruct.Frame([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [0.5] * 4,
    ...                     box=bedstruct.Box([-1, -1, -1], [4, 1, 1], boundary="ff ff ff"))
    >>> c = bedstruct.Contacts(i=[0, 1, 2], j=[1, 2, 3], branch=[[1, 0, 0]] * 3,
    ...                        radii_i=[0.5] * 3, radii_j=[0.5] * 3, n_particles=4)
    >>> r = region_fabric(c, f)
    >>> r.names, float(r["start"].N2[0, 0])
    (('start', 'centre', 'end'), 1.0)
    """
    labels, edges = contact_regions(contacts, frame, axis=axis, n_regions=n_regions,
                                    position=position, bounds=bounds)
    m = contacts.n_contacts
    w = _resolve_weights(contacts, weights, m)
    normals = contacts.normals
    out = []
    exps = []
    if l_max is not None:
        from .harmonics import harmonic_expansion
    for k in range(int(n_regions)):
        sel = labels == k
        if not np.any(sel) or (w is not None and not w[sel].sum() > 0):
            out.append(None)
            exps.append(None)
            continue
        wk = None if w is None else w[sel]
        out.append(fabric_tensors(normals[sel], wk))
        if l_max is not None:
            exps.append(harmonic_expansion(normals[sel], l_max, wk))
    names = _REGION_NAMES_3 if n_regions == 3 else tuple(f"region {k}" for k in range(n_regions))
    labels.setflags(write=False)
    return RegionFabric(names=names, edges=_readonly(edges), axis=_axis_index(axis),
                        tensors=tuple(out), labels=labels,
                        expansions=None if l_max is None else tuple(exps))


# --------------------------------------------------------------------------- table
_COMP = ("xx", "yy", "zz", "xy", "xz", "yz")


def fabric_table(results: Sequence[FabricTensors | None], *, labels=None) -> dict:
    """Columns (dict of equal-length arrays) summarising several FabricTensors, for pandas.

    Parameters
    ----------
    results : sequence of FabricTensors or None
        E.g. ``region_fabric(...).tensors`` or one per frame. None rows
        (empty regions) become NaN.
    labels : sequence, optional
        A label per row (``label`` column); default the row index.

    Returns
    -------
    dict of str to (K,) ndarray
        ``label``, ``n_contacts``, ``total_weight``, ``N2_xx`` ... ``N2_yz``,
        ``D2_xx`` ... ``D2_yz``, ``lambda1..3`` (eigenvalues of N2,
        descending), ``anisotropy`` and ``anisotropy_rank4``. Zero-length
        typed columns for empty input.

    Examples
    --------
    >>> t = fabric_tensors([[1, 0, 0], [0, 1, 0]])
    >>> tab = fabric_table([t, None], labels=["a", "b"])
    >>> tab["N2_xx"].tolist(), tab["n_contacts"].tolist()
    ([0.5, nan], [2, 0])
    """
    results = list(results)
    k = len(results)
    labels = np.arange(k) if labels is None else np.asarray(list(labels))
    if labels.shape != (k,):
        raise ValueError(f"`labels` must have one entry per result ({k}); got {labels.shape}")
    tab = {"label": labels,
           "n_contacts": np.array([0 if r is None else r.n_contacts for r in results], dtype=np.int64),
           "total_weight": np.array([np.nan if r is None else r.total_weight for r in results],
                                    dtype=np.float64)}
    for name in ("N2", "D2"):
        vals = np.array([np.full(6, np.nan) if r is None else lammps_voigt(getattr(r, name))
                         for r in results], dtype=np.float64).reshape(k, 6)
        for c, comp in enumerate(_COMP):
            tab[f"{name}_{comp}"] = vals[:, c]
    eig = np.array([np.full(3, np.nan) if r is None else r.eigenvalues for r in results],
                   dtype=np.float64).reshape(k, 3)
    for c in range(3):
        tab[f"lambda{c + 1}"] = eig[:, c]
    for name in ("anisotropy", "anisotropy_rank4"):
        tab[name] = np.array([np.nan if r is None else getattr(r, name) for r in results],
                             dtype=np.float64)
    return tab
