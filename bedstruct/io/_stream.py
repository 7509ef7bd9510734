"""The one-pass streaming parser of a clean text frame: the data block is read in
small pieces and parsed straight into the final arrays (positions and vectors
as (N, 3) blocks), then sorted by id. Anything irregular returns None and the
reader takes the general path of :mod:`bedstruct.io._text`, which reports
problems precisely.

Implementation module of :mod:`bedstruct.io.lammps_dump` (import from there).
"""

from __future__ import annotations

import numpy as np

from ._columns import _POSITION_SETS, _VECTORS, _id_order
from ._text import RawFrame, general_block, many_slow_rows, parse_token

__all__: list[str] = []


class _Planned:
    """Columns parsed straight into their final arrays (see :func:`_stream_columns`)."""

    def __init__(self, flat, slots, n, order, ids):
        self.flat = flat
        self.slots = slots      # column -> (base, stride); triples -> base
        self.n = n
        self.order = order
        self.ids = ids
        self.in_order = order is None

    def sort(self):
        """Reorder every slot by ``order`` (rows were parsed in file order)."""
        if self.in_order:
            return
        n = self.n
        for key, v in self.slots.items():
            if isinstance(key, tuple):
                b, w = v, 3
            elif v[1] == 1:
                b, w = v[0], 1
            else:
                continue
            block = self.flat[b:b + w * n].reshape(n, w)
            np.copyto(block, np.take(block, self.order, axis=0))  # one block-sized temporary
        self.in_order = True

    def take(self, ks) -> np.ndarray:
        ks = tuple(int(k) for k in ks)
        n = self.n
        if len(ks) == 3 and ks in self.slots:
            b = self.slots[ks]
            return self.flat[b:b + 3 * n].reshape(n, 3)
        if len(ks) == 1:
            b, stride = self.slots[ks[0]]
            return np.ascontiguousarray(self.flat[b:b + stride * n:stride])
        return np.stack([self.take([k]) for k in ks], axis=1)


def _triples(names):
    """Column triples that the reader maps to (N, 3) arrays, when all present."""
    idx = {name: k for k, name in enumerate(names)}
    groups = [t for t, _, _ in _POSITION_SETS] + [("ix", "iy", "iz")]
    groups += [t for _, options in _VECTORS for t in options]
    return [tuple(idx[c] for c in t) for t in groups if all(c in idx for c in t)]


_STREAM_CHUNK = 1 << 21  # 2 MiB of text per parse call keeps the peak memory low


def _plan(names, n):
    """Flat layout of the output arrays: (base, stride) per column, (N, 3) triples."""
    ncols = len(names)
    base = np.empty(ncols, dtype=np.int64)
    stride = np.empty(ncols, dtype=np.int64)
    slots = {}
    pos = 0
    seen = set()
    for t in _triples(names):
        if seen & set(t):
            continue
        seen.update(t)
        slots[t] = pos
        for off, k in enumerate(t):
            base[k], stride[k] = pos + off, 3
            slots[k] = (pos + off, 3)
        pos += 3 * n
    for k in range(ncols):
        if k not in seen:
            base[k], stride[k] = pos, 1
            slots[k] = (pos, 1)
            pos += n
    return base, stride, slots, pos


def _parse_piece(piece: bytes, final: bool, row0: int, n: int, ncols: int, flat, base,
                 stride) -> int:
    """Parse the whole lines of ``piece`` as rows ``row0...`` into ``flat``.

    Returns the number of rows, or -1 when anything is irregular.
    """
    from ._kernels import parse_rows

    end = len(piece)
    if final:
        while end > 0 and piece[end - 1] <= 32:
            end -= 1
    arr = np.frombuffer(piece, dtype=np.uint8)[:end]
    if arr.size == 0:
        return 0
    nl = np.flatnonzero(arr == 10)
    if final:
        ends = np.append(nl, arr.size).astype(np.int64)
    else:
        ends = nl.astype(np.int64)
    starts = np.empty_like(ends)
    starts[0] = 0
    starts[1:] = ends[:-1] + 1
    k = starts.size
    if row0 + k > n:
        return -1
    status = np.empty(k, dtype=np.int8)
    rows = np.arange(row0, row0 + k, dtype=np.int64)
    parse_rows(arr, starts, ends, ncols, flat, base, stride, rows, status)
    if (status == 1).any():
        return -1
    slow = np.flatnonzero(status == 2)
    if many_slow_rows(slow.size, k):
        vals = general_block(piece[:end], k, ncols)
        if vals is None:
            return -1
        for c in range(ncols):
            flat[base[c] + rows * stride[c]] = vals[:, c]
    else:
        for r in slow.tolist():
            tokens = piece[starts[r]:ends[r]].split()
            try:
                values = [parse_token(t) for t in tokens]
            except ValueError:
                return -1
            if len(values) != ncols:
                return -1
            flat[base + (row0 + r) * stride] = values
    return k


def _stream_columns(source, pos: int, end: int, first: bytes, raw: RawFrame, sort_by_id: bool):
    """Parse a frame's data block into final arrays, reading it in small pieces.

    ``first`` holds the start of the block (read with the header) and ``pos`` is
    the stream offset right after it. Returns a :class:`_Planned` provider, or
    None when anything is irregular (wrong counts, bad tokens, non-integer ids);
    the caller then takes the general path, which reports problems precisely.
    """
    n, names = raw.n, raw.names
    ncols = len(names)
    base, stride, slots, size = _plan(names, n)
    flat = np.empty(size, dtype=np.float64)
    row = 0
    carry = first
    while True:
        final = pos >= end
        if not final:
            chunk = source.read_range(pos, min(_STREAM_CHUNK, end - pos))
            if not chunk:
                return None
            pos += len(chunk)
            carry = carry + chunk if carry else chunk
            del chunk
            final = pos >= end
        if final:
            piece, carry = carry, b""
        else:
            cut = carry.rfind(b"\n") + 1
            if cut == 0:
                continue
            piece, carry = carry[:cut], carry[cut:]
        k = _parse_piece(piece, final, row, n, ncols, flat, base, stride)
        if k < 0:
            return None
        row += k
        if final:
            break
    if row != n:
        return None
    order = None
    ids = None
    if "id" in names:
        b, st = slots[names.index("id")]
        idf = flat[b:b + st * n:st]
        with np.errstate(invalid="ignore"):
            ids = idf.astype(np.int64)
        if not np.array_equal(ids, idf):
            return None
        if sort_by_id:
            order = _id_order(ids)
            if order is not None:
                ids = ids[order]
    return _Planned(flat, slots, n, order, ids)
