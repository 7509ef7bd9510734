"""Mapping the columns of a parsed dump frame onto a :class:`~bedstruct.core.Frame`:
ids and row order, positions (plain, scaled, unwrapped), radii, images, vectors
and the extra columns, with exact messages for bad values.

Implementation module of :mod:`bedstruct.io.lammps_dump` (import from there).
"""

from __future__ import annotations

import warnings

import numpy as np

from ..core import Box, Frame, Provenance, Units
from ..errors import BedstructWarning, DumpFormatError
from ._order_kernels import gather_rows
from ._text import RawFrame, check_unit_style

__all__ = ["frame_from_raw", "SYNTHESISED_IDS_NOTE"]

#: The provenance note of a frame read from a dump without an ``id`` column: its ids are
#: row numbers, not the particle ids of the simulation.
SYNTHESISED_IDS_NOTE = "no 'id' column: ids 1..N synthesised in file order"

_POSITION_SETS = (
    (("x", "y", "z"), False, False),
    (("xs", "ys", "zs"), True, False),
    (("xu", "yu", "zu"), False, True),
    (("xsu", "ysu", "zsu"), True, True),
)
_VECTORS = (
    ("velocities", (("vx", "vy", "vz"),)),
    ("omegas", (("omegax", "omegay", "omegaz"), ("wx", "wy", "wz"))),
    ("forces", (("fx", "fy", "fz"),)),
)


def _check_int(col: np.ndarray, raw: RawFrame, name: str, order) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        ints = col.astype(np.int64)
    bad = np.flatnonzero(ints != col)
    if bad.size:
        width = col.shape[1] if col.ndim == 2 else 1
        k = int(bad[0] // width)
        r = int(k if order is None else order[k])
        raise DumpFormatError(f"column {name!r} must hold integers; row {r + 1} has "
                              f"{float(col.reshape(-1)[bad[0]])!r}", path=raw.path,
                              line=raw.data_line + r, text=raw.row_text(r))
    return ints


def _check_range(values: np.ndarray, limit: int, raw: RawFrame, name: str, order, why: str):
    """Integers read as float64 must stay below ``limit`` in magnitude."""
    bad = np.flatnonzero(np.abs(values) >= limit)
    if bad.size:
        r = int(bad[0] if order is None else order[bad[0]])
        raise DumpFormatError(f"column {name!r}: row {r + 1} has {int(values[bad[0]])}; {why}",
                              path=raw.path, line=raw.data_line + r, text=raw.row_text(r))


def _warn_repeated_ids(ids: np.ndarray, order, raw: RawFrame) -> None:
    """Warn when an id appears twice (LAMMPS ids are unique unless ``atom_modify id no``).

    ``ids`` are in id order when ``order`` is given or they already increase.
    """
    if ids.size < 2 or np.all(ids[1:] > ids[:-1]):
        return
    if order is None:  # file order (sort_by_id=False)
        order = np.argsort(ids, kind="stable")
        ids = ids[order]
    same = np.flatnonzero(ids[1:] == ids[:-1])
    if not same.size:
        return
    k = int(same[0])
    first, second = int(order[k]), int(order[k + 1])
    warnings.warn(f"{raw.path}, line {raw.data_line + second}: particle id {int(ids[k])} appears "
                  f"more than once in the frame of timestep {raw.timestep} (also on line "
                  f"{raw.data_line + first})", BedstructWarning, stacklevel=4)


def _id_order(ids: np.ndarray):
    """Row order that sorts ``ids`` (None when already strictly increasing)."""
    n = ids.size
    if n < 2 or np.all(ids[1:] > ids[:-1]):
        return None
    lo, hi = int(ids.min()), int(ids.max())
    if hi - lo + 1 == n:  # a permutation of consecutive ids: O(N) scatter
        order = np.full(n, -1, dtype=np.int64)
        order[ids - lo] = np.arange(n, dtype=np.int64)
        if not (order < 0).any():
            return order
    return np.argsort(ids, kind="stable").astype(np.int64)


class _Columns:
    """Gathers (reordered) columns of a parsed block into contiguous arrays."""

    def __init__(self, data: np.ndarray, order):
        self.data = data
        n = data.shape[0]
        self.order = np.arange(n, dtype=np.int64) if order is None else order
        self.sorted = order is not None

    def take(self, ks) -> np.ndarray:
        ks = np.asarray(ks, dtype=np.int64)
        if not self.sorted:
            if ks.size == 1:
                return np.ascontiguousarray(self.data[:, ks[0]])
            return np.ascontiguousarray(self.data[:, ks])
        out = np.empty((self.data.shape[0], ks.size), dtype=np.float64)
        gather_rows(self.data, self.order, ks, out)
        return out[:, 0] if ks.size == 1 else out


def _unwrapped(positions, images, box: Box, wrap: bool, triple: str, notes: list):
    """Positions and images from unwrapped coordinates, such that
    ``positions + images @ box.matrix.T`` is the unwrapped position.

    Unwrapped coordinates already include the image shifts, so the dump's
    ``ix iy iz`` must not be added again: kept as written (default), the
    images are 0; wrapped into the box, the images are the box shifts the wrap
    removed (not the dump's flags, which LAMMPS updates only on reneighbouring).
    """
    had = " (the dump's ix iy iz are not applied again)" if images is not None else ""
    if not wrap:
        notes.append(f"positions are unwrapped coordinates {triple} (not wrapped into the box)")
        if images is not None:
            notes.append(f"images set to 0: positions {triple} already include the dump's "
                         f"ix iy iz, so unwrapped_positions() are the positions")
            images = np.zeros_like(images)
        return positions, images
    wrapped = box.wrap(positions)
    images = box.image_shift(positions - wrapped)
    notes.append(f"unwrapped coordinates {triple} wrapped into the box (wrap=True); images are "
                 f"the box shifts removed{had}")
    return wrapped, images


def frame_from_raw(raw: RawFrame, *, radius=None, units=None, wrap=False, sort_by_id=True,
                   frame_index=None, planned=None) -> Frame:
    """Map the columns of a parsed dump frame onto a :class:`Frame`.

    See :func:`read_dump` for the column mapping.
    """
    names = raw.names
    idx = {name: k for k, name in enumerate(names)}
    used = set()
    notes = list(raw.notes)
    n = raw.n
    data = raw.data
    box = Box.from_lammps_bounds(raw.bounds, raw.tilt, raw.boundary)

    # ids first: they decide the row order
    order = None
    if planned is not None:
        order = planned.order
        cols = planned
    if "id" in idx:
        if planned is not None:
            ids = planned.ids
        else:
            raw_ids = _check_int(data[:, idx["id"]], raw, "id", None)
            if sort_by_id:
                order = _id_order(raw_ids)
            ids = raw_ids if order is None else raw_ids[order]
        used.add("id")
    else:
        ids = np.arange(1, n + 1, dtype=np.int64)
        notes.append(SYNTHESISED_IDS_NOTE)
    if planned is None:
        cols = _Columns(data, order)

    def row_of(r):  # row index in the file of sorted row r
        return int(r if order is None else order[r])

    # ids beyond 2**53 collapse onto their neighbours in float64
    _check_range(ids, 2 ** 53, raw, "id", order, "ids of 2**53 or more cannot be read exactly")

    # positions
    positions = None
    unwrapped_set = None
    for triple, scaled, unwrapped in _POSITION_SETS:
        have = [c in idx for c in triple]
        if all(have):
            positions = cols.take([idx[c] for c in triple])
            used.update(triple)
            if scaled:
                positions = box.cartesian(positions)
                notes.append(f"positions converted from scaled coordinates {' '.join(triple)}")
            if unwrapped:
                unwrapped_set = " ".join(triple)
            break
        if any(have):
            raise DumpFormatError(f"incomplete position columns: found "
                                  f"{[c for c in triple if c in idx]}, expected all of {list(triple)}",
                                  path=raw.path, line=raw.header_line)
    if positions is None:
        raise DumpFormatError("no position columns; expected x y z, xs ys zs, xu yu zu or "
                              "xsu ysu zsu", path=raw.path, line=raw.header_line,
                              text=" ".join(names))
    positions = np.ascontiguousarray(positions).reshape(n, 3)
    finite = np.isfinite(positions).all(axis=1)
    if not finite.all():
        r = int(np.flatnonzero(~finite)[0])
        raise DumpFormatError(f"position of row {row_of(r) + 1} is not finite "
                              f"({positions[r].tolist()})", path=raw.path,
                              line=raw.data_line + row_of(r), text=raw.row_text(row_of(r)))

    images = None
    if all(c in idx for c in ("ix", "iy", "iz")):
        img = cols.take([idx[c] for c in ("ix", "iy", "iz")]).reshape(n, 3)
        images = _check_int(img, raw, "ix iy iz", order)
        used.update(("ix", "iy", "iz"))
    if unwrapped_set is not None:
        positions, images = _unwrapped(positions, images, box, wrap, unwrapped_set, notes)

    if "type" in idx:
        types = _check_int(cols.take([idx["type"]]), raw, "type", order)
        _check_range(types, 2 ** 31, raw, "type", order, "types must fit a 32-bit integer")
        used.add("type")
    else:
        types = np.ones(n, dtype=np.int32)
        notes.append("no 'type' column: all types set to 1")

    # radii
    if "radius" in idx:
        radii = cols.take([idx["radius"]])
        used.add("radius")
        rname = "radius"
    elif "diameter" in idx:
        radii = cols.take([idx["diameter"]]) / 2.0
        used.add("diameter")
        rname = "diameter"
        notes.append("radii are the 'diameter' column halved")
    elif radius is not None:
        radii = np.full(n, float(radius))
        rname = None
        notes.append(f"no radius/diameter column: radius {float(radius)!r} given by the caller")
    else:
        raise DumpFormatError("no 'radius' or 'diameter' column; pass radius= to read_dump "
                              "(--radius on the command line)",
                              path=raw.path, line=raw.header_line, text=" ".join(names))
    good = np.isfinite(radii) & (radii > 0)
    if not good.all():
        r = int(np.flatnonzero(~good)[0])
        what = rname if rname else "radius="
        raise DumpFormatError(f"{what} must be positive and finite; row {row_of(r) + 1} gives "
                              f"radius {float(radii[r])!r}", path=raw.path,
                              line=raw.data_line + row_of(r) if rname else None,
                              text=raw.row_text(row_of(r)) if rname else None)

    kw = {} if images is None else {"images": images}
    for attr, options in _VECTORS:
        for triple in options:
            if all(c in idx for c in triple):
                kw[attr] = cols.take([idx[c] for c in triple]).reshape(n, 3)
                used.update(triple)
                break
    columns = {name: cols.take([k]) for k, name in enumerate(names) if name not in used}

    style = raw.units
    units = check_unit_style(units)
    if units is not None:
        if style is not None and style != units:
            raise DumpFormatError(f"the file says 'ITEM: UNITS {style}' but units={units!r} "
                                  f"was given", path=raw.path)
        style = units
    _warn_repeated_ids(ids, order, raw)
    frame = Frame(positions, radii, box=box, timestep=raw.timestep, ids=ids, types=types,
                  time=raw.time, columns=columns, units=Units(style),
                  provenance=Provenance(source=raw.path, frame_index=frame_index,
                                        notes=tuple(notes)), **kw)
    if sort_by_id:
        frame = frame.sorted_by_id()  # no-op unless ids repeat
    return frame
