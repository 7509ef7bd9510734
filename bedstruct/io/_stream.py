"""The one-pass streaming parser of a clean text frame: the data block is read in
small pieces and parsed straight into the final arrays (positions and vectors
as (N, 3) blocks), then sorted by id. Anything irregular returns None and the
reader takes the general path of :mod:`bedstruct.io._text`, which reports
problems precisely.

Implementation module of :mod:`bedstruct.io.lammps_dump` (import from there).
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ._columns import _POSITION_SETS, _VECTORS
from ._text import RawFrame, general_block, many_slow_rows, parse_token

__all__: list[str] = []


class _Planned:
    """Columns parsed straight into their final arrays (see :func:`_stream_columns`)."""

    def __init__(self, flat, slots, n, order, ids, idcol=None):
        self.flat = flat
        self.slots = slots      # column -> (base, stride); triples -> base
        self.n = n
        self.order = order
        self.ids = ids          # sorted ids, int64 (None without an id column)
        self.idcol = idcol
        self.in_order = order is None

    def sort(self):
        """Reorder every slot by ``order`` (rows were parsed in file order); the id
        column is written from the sorted ids rather than permuted."""
        if self.in_order:
            return
        from ._order_kernels import permute_rows
        n = self.n
        blocks = [(v, 3) if isinstance(key, tuple) else (v[0], 1)
                  for key, v in self.slots.items()
                  if isinstance(key, tuple) or (v[1] == 1 and key != self.idcol)]
        if self.idcol is not None and self.slots[self.idcol][1] == 1:
            b = self.slots[self.idcol][0]
            self.flat[b:b + n] = self.ids
        if not blocks:
            self.in_order = True
            return
        tmp = np.empty(max(w for _, w in blocks) * n, dtype=np.float64)  # one block's size
        for b, w in blocks:
            permute_rows(self.flat, b, w, self.order, tmp)
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
    arr.flags.writeable = False   # the kernels' one signature: read-only text (as _text passes)
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


class _Pieces:
    """The lines of a data block read in pieces into a few reused buffers, each piece
    parsed by one worker thread while the next is read (``threads == 1``: in turn).

    A piece is parsed by :func:`~bedstruct.io._kernels.parse_lines`; one it refuses
    is read again row by row (:func:`_parse_piece`), which takes rare tokens to the
    general number parser. The result is ``None`` when anything is irregular.
    """

    def __init__(self, n, ncols, flat, base, stride, threads):
        self.n, self.ncols, self.flat, self.base, self.stride = n, ncols, flat, base, stride
        self.threads = threads
        self.pool = ThreadPoolExecutor(threads) if threads > 1 else None
        self.jobs = deque()   # (result or future, buffer, stop, final, first row, rows)
        self.free = []        # buffers of finished pieces
        self.row = 0          # rows handed out so far
        self.failed = False

    def buffer(self, size):
        buf = self.free.pop() if self.free else None
        return buf if buf is not None and len(buf) >= size else bytearray(size)

    def submit(self, buf, stop: int, final: bool) -> bool:
        """Parse ``buf[:stop]``; False when its lines would pass the frame's rows."""
        from ._kernels import count_lines, parse_lines

        end = stop
        if final:
            while end > 0 and buf[end - 1] <= 32:
                end -= 1
        arr = np.frombuffer(buf, dtype=np.uint8)
        arr.flags.writeable = False   # the kernels' one signature: read-only text (as _text passes)
        k = count_lines(arr, 0, end)
        if self.row + k > self.n:
            return False
        args = (arr, 0, end, self.ncols, self.flat, self.base, self.stride, self.row)
        job = parse_lines(*args) if self.pool is None else self.pool.submit(parse_lines, *args)
        self.jobs.append((job, buf, stop, final, self.row, k))
        self.row += k
        while len(self.jobs) > self.threads:
            self._finish()
        return not self.failed

    def _finish(self):
        job, buf, stop, final, row0, k = self.jobs.popleft()
        got = job if self.pool is None else job.result()
        if got != row0 + k and not self.failed:
            redo = _parse_piece(bytes(buf[:stop]), final, row0, self.n, self.ncols, self.flat,
                                self.base, self.stride)
            self.failed = redo != k
        self.free.append(buf)

    def close(self) -> bool:
        """Wait for every piece: True when all were read exactly."""
        while self.jobs:
            self._finish()
        if self.pool is not None:
            self.pool.shutdown(wait=True)
        self.free.clear()
        return not self.failed


def _stream_columns(source, pos: int, end: int, first: bytes, raw: RawFrame, sort_by_id: bool):
    """Parse a frame's data block into final arrays, reading it in small pieces.

    ``first`` holds the start of the block (read with the header) and ``pos`` is
    the stream offset right after it. Pieces are parsed on numba's number of
    threads (:func:`bedstruct._numba.set_num_threads`) while the next is read
    or decompressed. Returns a :class:`_Planned` provider, or None when anything
    is irregular (wrong counts, bad tokens, non-integer ids); the caller then
    takes the general path, which reports problems precisely.
    """
    from .._numba import get_num_threads
    from ._order_kernels import consecutive_order, integer_column

    n, names = raw.n, raw.names
    ncols = len(names)
    base, stride, slots, size = _plan(names, n)
    flat = np.empty(size, dtype=np.float64)
    pieces = _Pieces(n, ncols, flat, base, stride, max(1, get_num_threads()))
    carry = first
    try:
        while True:
            buf = pieces.buffer(max(_STREAM_CHUNK, 2 * len(carry)))
            fill = len(carry)
            buf[:fill] = carry
            while True:
                final = pos >= end
                if final:
                    cut = fill
                    break
                if fill == len(buf):  # a line longer than the buffer
                    grown = bytearray(2 * len(buf))
                    grown[:fill] = buf
                    buf = grown
                got = source.read_into(pos, memoryview(buf)[fill:fill + min(len(buf) - fill,
                                                                             end - pos)])
                if not got:
                    return None
                pos += got
                fill += got
                if pos >= end:
                    cut = fill
                    final = True
                    break
                cut = buf.rfind(b"\n", 0, fill) + 1
                if cut:
                    break
            carry = bytes(buf[cut:fill])
            if not pieces.submit(buf, cut, final):
                return None
            if final:
                break
    finally:
        exact = pieces.close()
        buf = carry = None  # the text is parsed: free it before the ids are sorted
    row = pieces.row
    if not exact:
        return None
    if row != n:
        return None
    order = None
    ids = None
    if "id" in names:
        b, st = slots[names.index("id")]
        ids = np.empty(n, dtype=np.int64)
        exact, increasing, lo, hi = integer_column(flat, b, st, ids)
        if not exact:
            return None
        if sort_by_id and not increasing:
            order = np.empty(n, dtype=np.int64)
            if not (hi - lo + 1 == n and consecutive_order(ids, lo, order)):
                order = np.argsort(ids, kind="stable").astype(np.int64)
            ids = ids[order]
    return _Planned(flat, slots, n, order, ids, names.index("id") if ids is not None else None)
