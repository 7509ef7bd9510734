"""Reading and writing LAMMPS/LIGGGHTS ``dump custom`` files (text and binary).

:func:`read_dump` scans the file(s) once for the byte offset of every frame and
returns a lazy :class:`DumpTrajectory` that parses frames on demand, one at a
time; :func:`iter_frames` is its generator form. :func:`write_dump` writes
frames in the LIGGGHTS ``dump custom`` layout with round-trip exact numbers.
"""

from __future__ import annotations

import glob
import logging
import os
import warnings

import numpy as np

from ..core import Box, Frame, Provenance, Trajectory, Units
from ..errors import BedstructWarning, DumpFormatError
from ._binary import is_binary, parse_binary_frame, scan_binary
from ._source import Source, scan_text
from ._kernels import gather_rows
from ._text import RawFrame, TruncatedFrame, parse_text_frame

__all__ = ["read_dump", "iter_frames", "write_dump", "DumpTrajectory", "expand_paths",
           "frame_from_raw"]

log = logging.getLogger(__name__)

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
_GLOB_CHARS = set("*?[")


def expand_paths(path_or_glob) -> list[str]:
    """Expand a path, a glob pattern or a list of them into existing file names.

    Raises
    ------
    FileNotFoundError
        If nothing matches.
    """
    items = [path_or_glob] if isinstance(path_or_glob, (str, os.PathLike)) else list(path_or_glob)
    out = []
    for item in items:
        item = os.fspath(item)
        if os.path.exists(item):
            out.append(item)
        elif _GLOB_CHARS & set(item):
            matches = sorted(glob.glob(item))
            if not matches:
                raise FileNotFoundError(f"no files match {item!r}")
            out.extend(matches)
        else:
            raise FileNotFoundError(f"no such file: {item}")
    if not out:
        raise FileNotFoundError(f"no files given: {path_or_glob!r}")
    return out


# --------------------------------------------------------------------------- mapping
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
    if slow.size > max(64, k // 20):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            vals = np.fromstring(bytes(piece[:end]), dtype=np.float64, sep=" ")
        if vals.size != k * ncols:
            return -1
        vals = vals.reshape(k, ncols)
        for c in range(ncols):
            flat[base[c] + rows * stride[c]] = vals[:, c]
    else:
        for r in slow.tolist():
            tokens = piece[starts[r]:ends[r]].split()
            try:
                values = [float(t) for t in tokens]
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
        notes.append("no 'id' column: ids 1..N synthesised in file order")
    if planned is None:
        cols = _Columns(data, order)

    def row_of(r):  # row index in the file of sorted row r
        return int(r if order is None else order[r])

    # positions
    positions = None
    for triple, scaled, unwrapped in _POSITION_SETS:
        have = [c in idx for c in triple]
        if all(have):
            positions = cols.take([idx[c] for c in triple])
            used.update(triple)
            if scaled:
                positions = box.cartesian(positions)
                notes.append(f"positions converted from scaled coordinates {' '.join(triple)}")
            if unwrapped:
                if wrap:
                    positions = box.wrap(positions)
                    notes.append(f"unwrapped coordinates {' '.join(triple)} wrapped into the box "
                                 f"(wrap=True)")
                else:
                    notes.append(f"positions are unwrapped coordinates {' '.join(triple)} "
                                 f"(not wrapped into the box)")
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

    if "type" in idx:
        types = _check_int(cols.take([idx["type"]]), raw, "type", order)
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
        raise DumpFormatError("no 'radius' or 'diameter' column; pass radius= to read_dump",
                              path=raw.path, line=raw.header_line, text=" ".join(names))
    good = np.isfinite(radii) & (radii > 0)
    if not good.all():
        r = int(np.flatnonzero(~good)[0])
        what = rname if rname else "radius="
        raise DumpFormatError(f"{what} must be positive and finite; row {row_of(r) + 1} gives "
                              f"radius {float(radii[r])!r}", path=raw.path,
                              line=raw.data_line + row_of(r) if rname else None,
                              text=raw.row_text(row_of(r)) if rname else None)

    kw = {}
    if all(c in idx for c in ("ix", "iy", "iz")):
        img = cols.take([idx[c] for c in ("ix", "iy", "iz")]).reshape(n, 3)
        kw["images"] = _check_int(img, raw, "ix iy iz", order)
        used.update(("ix", "iy", "iz"))
    for attr, options in _VECTORS:
        for triple in options:
            if all(c in idx for c in triple):
                kw[attr] = cols.take([idx[c] for c in triple]).reshape(n, 3)
                used.update(triple)
                break
    columns = {name: cols.take([k]) for k, name in enumerate(names) if name not in used}

    style = raw.units
    if units is not None:
        if style is not None and style != str(units).lower():
            raise DumpFormatError(f"the file says 'ITEM: UNITS {style}' but units={units!r} "
                                  f"was given", path=raw.path)
        style = str(units).lower()
    frame = Frame(positions, radii, box=box, timestep=raw.timestep, ids=ids, types=types,
                  time=raw.time, columns=columns, units=Units(style),
                  provenance=Provenance(source=raw.path, frame_index=frame_index,
                                        notes=tuple(notes)), **kw)
    if sort_by_id:
        frame = frame.sorted_by_id()  # no-op unless ids repeat
    return frame


# --------------------------------------------------------------------------- trajectory
class _Entry:
    __slots__ = ("file", "kind", "start", "end", "line", "timestep", "count", "at_eof", "state",
                 "index")

    def __init__(self, **kw):
        for k, v in kw.items():
            setattr(self, k, v)


class _File:
    def __init__(self, path):
        self.source = Source(path)
        self.path = self.source.path
        self.ends_with_newline = True


class DumpTrajectory(Trajectory):
    """A lazily read sequence of frames from LAMMPS/LIGGGHTS dump files.

    Created by :func:`read_dump`. The files are scanned once for the byte
    offsets of the frames; each access parses one frame. Supports ``len()``,
    indexing, slicing, iteration, :attr:`timesteps`, :attr:`n_particles`,
    ``close()`` and use as a context manager.
    """

    def __init__(self, paths, *, radius=None, units=None, strict=True, sort_by_id=True,
                 wrap=False, columns=None):
        self._opts = dict(radius=radius, units=units, sort_by_id=sort_by_id, wrap=wrap)
        self._columns = columns
        self._files = [_File(p) for p in paths]
        entries = []
        for f in self._files:
            entries.extend(self._scan(f, strict))
        if len(self._files) > 1:
            entries.sort(key=lambda e: e.timestep)  # stable: file order, then file position
        self._entries = entries

    # ----------------------------------------------------------------- scanning
    def _scan(self, f: _File, strict: bool) -> list:
        src = f.source
        head = src.read_range(0, 64)
        src.close()
        if not head.strip():
            return []
        if is_binary(head):
            return self._scan_binary(f, strict)
        scan = scan_text(src)
        f.ends_with_newline = scan.ends_with_newline
        entries = []
        for k, start in enumerate(scan.starts):
            entries.append(_Entry(file=f, kind="text", start=start, end=scan.end(k),
                                  line=scan.lines[k], timestep=scan.timesteps[k],
                                  count=scan.counts[k], at_eof=k == len(scan.starts) - 1,
                                  state=None, index=k))
        if entries:
            self._check_last_text(f, entries, strict, scan.tail)
        return entries

    def _check_last_text(self, f, entries, strict, tail=None):
        last = entries[-1]
        if tail is not None:
            buf = tail
        else:
            buf = f.source.read_range(last.start, last.end - last.start)
            f.source.close()
        try:
            raw = parse_text_frame(buf, path=f.path, line0=last.line, at_eof=True,
                                   file_ends_with_newline=f.ends_with_newline,
                                   parse_values=False, ncols_override=self._columns)
        except TruncatedFrame as exc:
            if strict:
                raise
            warnings.warn(f"skipping the truncated last frame of {f.path} "
                          f"(timestep {last.timestep}): {exc.message}", BedstructWarning,
                          stacklevel=4)
            entries.pop()
            if entries:
                entries[-1].at_eof = False
            return
        except DumpFormatError:
            return  # any other defect is reported when that frame is read
        if raw.partial_tail is not None:
            if strict:
                raise DumpFormatError("truncated frame: a frame header is cut off at the end of "
                                      "the file", path=f.path, line=raw.partial_tail)
            warnings.warn(f"ignoring a cut-off frame header at the end of {f.path} "
                          f"(line {raw.partial_tail})", BedstructWarning, stacklevel=4)
            cut = buf.find(b"ITEM:", _offset_of_line(buf, raw.partial_tail - last.line - 1))
            last.end = last.start + cut
            last.at_eof = False
        elif last.timestep is None:
            last.timestep = raw.timestep

    def _scan_binary(self, f, strict):
        scan = scan_binary(f.source)
        if scan.truncated_at is not None:
            if strict or not scan.starts:
                raise DumpFormatError(f"truncated frame: binary snapshot {len(scan.starts) + 1} "
                                      f"is cut off at byte {scan.truncated_at}", path=f.path)
            warnings.warn(f"skipping the truncated last snapshot of {f.path} (byte "
                          f"{scan.truncated_at})", BedstructWarning, stacklevel=4)
        return [_Entry(file=f, kind="binary", start=s, end=e, line=None, timestep=t, count=c,
                       at_eof=False, state=st, index=k)
                for k, (s, e, t, c, st) in enumerate(zip(scan.starts, scan.ends, scan.timesteps,
                                                        scan.counts, scan.states))]

    # ----------------------------------------------------------------- access
    def __len__(self) -> int:
        return len(self._entries)

    def _raw(self, index: int, *, header_only=False) -> RawFrame:
        e = self._entries[index]
        buf = e.file.source.read_range(e.start, e.end - e.start)
        if e.kind == "binary":
            return parse_binary_frame(buf, path=e.file.path, state=e.state,
                                      columns=self._columns, header_only=header_only)
        raw = parse_text_frame(buf, path=e.file.path, line0=e.line, at_eof=e.at_eof,
                               file_ends_with_newline=e.file.ends_with_newline,
                               header_only=header_only, ncols_override=self._columns)
        del buf  # the frame text is not kept: messages re-read the line they need
        raw._rows = self._row_reader(e, raw.data_line)
        return raw

    def _row_reader(self, e, data_line):
        def row_text(r):
            buf = e.file.source.read_range(e.start, e.end - e.start)
            pos = _offset_of_line(buf, data_line + r - 1 - e.line)
            end = buf.find(b"\n", pos)
            return buf[pos:len(buf) if end < 0 else end].decode("latin-1").rstrip("\r")
        return row_text

    def _read_frame(self, index: int) -> Frame:
        e = self._entries[index]
        if e.kind == "text":
            frame = self._read_text_fast(e)
            if frame is not None:
                return frame
        raw = self._raw(index)  # general path: exact error messages, rare tokens
        if raw.kind != "ATOMS":
            raise DumpFormatError("this is a 'dump local' file (ITEM: ENTRIES); read it with "
                                  "read_dump_local", path=raw.path, line=raw.header_line)
        return frame_from_raw(raw, frame_index=e.index, **self._opts)

    def _read_text_fast(self, e):
        """A clean text frame read in pieces straight into its arrays, else None."""
        total = e.end - e.start
        head = e.file.source.read_range(e.start, min(total, 1 << 16))
        try:
            raw = parse_text_frame(head, path=e.file.path, line0=e.line,
                                   at_eof=e.at_eof and len(head) == total,
                                   file_ends_with_newline=e.file.ends_with_newline,
                                   header_only=True, ncols_override=self._columns)
        except DumpFormatError:
            return None
        if raw.kind != "ATOMS" or raw.n == 0:
            return None
        first = head[raw.body_offset:]
        del head
        planned = _stream_columns(e.file.source, e.start + raw.body_offset + len(first), e.end,
                                  first, raw, self._opts["sort_by_id"])
        if planned is None:
            return None
        planned.sort()
        raw._rows = self._row_reader(e, raw.data_line)
        return frame_from_raw(raw, frame_index=e.index, planned=planned, **self._opts)

    def header(self, index: int) -> RawFrame:
        """The parsed header of frame ``index`` (box, columns, units) without its data."""
        n = len(self)
        k = index + n if index < 0 else index
        if not 0 <= k < n:
            raise IndexError(f"frame index {index} out of range for {n} frames")
        return self._raw(k, header_only=True)

    @property
    def timesteps(self) -> np.ndarray:
        """Timestep of every frame (int64), from the scan (no frame is parsed)."""
        return np.array([e.timestep for e in self._entries], dtype=np.int64)

    @property
    def n_particles(self) -> np.ndarray:
        """Number of particles of every frame (int64), from the headers."""
        return np.array([-1 if e.count is None else e.count for e in self._entries],
                        dtype=np.int64)

    @property
    def paths(self) -> list[str]:
        """The files read, in the order given."""
        return [f.path for f in self._files]

    def close(self) -> None:
        """Close the open files (reading again reopens them)."""
        for f in self._files:
            f.source.close()

    def __repr__(self) -> str:
        what = self._files[0].path if len(self._files) == 1 else f"{len(self._files)} files"
        return f"DumpTrajectory({what!r}, n_frames={len(self)})"


def _offset_of_line(buf: bytes, k: int) -> int:
    """Byte offset of the 0-based line ``k`` of ``buf``."""
    pos = 0
    for _ in range(k):
        nxt = buf.find(b"\n", pos)
        if nxt < 0:
            return len(buf)
        pos = nxt + 1
    return pos


def read_dump(path_or_glob, *, radius=None, units=None, strict=True, sort_by_id=True,
              wrap=False, columns=None) -> DumpTrajectory:
    """Open LAMMPS/LIGGGHTS dump file(s) as a lazily read trajectory.

    Text ``dump custom`` files (plain, ``.gz``, ``.bz2``, ``.zst`` when the
    ``zstandard`` package is installed) and binary dumps (old and new header
    layouts) are recognised from their content.

    Parameters
    ----------
    path_or_glob : str, path-like or sequence of them
        A file, a glob pattern (``"post/dump*.liggghts"``) or a list. Frames
        of several files are ordered by timestep.
    radius : float, optional
        Radius (length) to give every particle when the dump has neither a
        ``radius`` nor a ``diameter`` column; otherwise such a dump is an error.
    units : str, optional
        The unit style of the numbers (``"si"``, ``"cgs"``, ``"micro"``...),
        when the file has no ``ITEM: UNITS``; no number is converted. When
        neither states it the frames have ``units.style = None`` (unknown).
    strict : bool, optional
        With False, a truncated *last* frame of a file (one still being
        written) is skipped with a :class:`~bedstruct.errors.BedstructWarning`;
        by default it is a :class:`~bedstruct.errors.DumpFormatError`.
    sort_by_id : bool, optional
        Order each frame's rows by particle id (default True).
    wrap : bool, optional
        Wrap unwrapped coordinates (``xu yu zu``) into the box; recorded in the
        frame's provenance. Default False: positions are as written.
    columns : str or sequence of str, optional
        Column names to use instead of the header's (needed for binary dumps
        of the old layout, which carry no names).

    Returns
    -------
    DumpTrajectory
        A lazy :class:`~bedstruct.core.Trajectory` of :class:`~bedstruct.core.Frame`.

    Raises
    ------
    DumpFormatError
        For malformed input, naming the file, the 1-based line and what was
        expected: truncated frames, non-numeric values, a wrong number of
        values on a line, atom count mismatches, non-positive or NaN radii,
        NaN/inf positions, unknown header items.
    FileNotFoundError
        If no file matches.

    Notes
    -----
    Columns map onto the frame as follows: ``id``, ``type``; positions from
    ``x y z``, else scaled ``xs ys zs`` (converted with the box, triclinic
    included), else unwrapped ``xu yu zu``, else ``xsu ysu zsu``; ``ix iy iz``
    to ``images``; ``vx vy vz`` to ``velocities``; ``omegax omegay omegaz``
    to ``omegas``; ``fx fy fz`` to ``forces``; ``radius``, or ``diameter``
    halved. Every other column is kept in ``frame.columns`` under its dump name
    (``c_x[1]``, ``f_temp``, ...). A missing ``id`` column gives ids 1..N, a
    missing ``type`` column types 1; both are noted in ``frame.provenance``.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, read_dump, write_dump
    >>> path = os.path.join(tempfile.mkdtemp(), "dump.liggghts")
    >>> write_dump(path, Frame([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], [0.5, 0.5], box=[2, 1, 1]))
    >>> with read_dump(path) as traj:
    ...     frame = traj[0]
    >>> len(traj), frame.n_particles, frame.positions[1].tolist()
    (1, 2, [1.5, 0.5, 0.5])

    .. versionadded:: 0.1
    """
    _check_radius(radius)
    return DumpTrajectory(expand_paths(path_or_glob), radius=radius, units=units, strict=strict,
                          sort_by_id=sort_by_id, wrap=wrap, columns=columns)


def _check_radius(radius):
    if radius is None:
        return
    try:
        r = float(radius)
    except (TypeError, ValueError):
        raise TypeError(f"`radius` must be a number (length); got {radius!r}") from None
    if not (np.isfinite(r) and r > 0):
        raise ValueError(f"`radius` must be positive and finite (length); got {radius!r}")


def iter_frames(path_or_glob, *, radius=None, units=None, strict=True, sort_by_id=True,
                wrap=False, columns=None):
    """Yield the frames of dump file(s) one at a time (generator form of :func:`read_dump`).

    Only one frame is held at a time; the file is closed when the generator
    finishes or is closed.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, iter_frames, write_dump
    >>> path = os.path.join(tempfile.mkdtemp(), "dump.gz")
    >>> write_dump(path, [Frame([[0.5, 0.5, 0.5]], [0.5], box=[1, 1, 1], timestep=t)
    ...                   for t in (0, 100)])
    >>> [f.timestep for f in iter_frames(path)]
    [0, 100]
    """
    traj = read_dump(path_or_glob, radius=radius, units=units, strict=strict,
                     sort_by_id=sort_by_id, wrap=wrap, columns=columns)
    try:
        for k in range(len(traj)):
            yield traj._read_frame(k)
    finally:
        traj.close()


# --------------------------------------------------------------------------- writing
def _open_write(path, append=False):
    path = os.fspath(path)
    mode = "ab" if append else "wb"
    low = path.lower()
    if low.endswith((".gz", ".gzip")):
        import gzip
        return gzip.open(path, mode, compresslevel=6)
    if low.endswith(".bz2"):
        import bz2
        return bz2.open(path, mode)
    if low.endswith((".zst", ".zstd")):
        import zstandard
        return zstandard.open(path, mode)
    return open(path, mode)


def _frame_table(frame: Frame, columns=None):
    """(names, list of 1-D arrays, int flags) for the dump columns of a frame."""
    table = {"id": frame.ids, "type": frame.types}
    for k, c in enumerate("xyz"):
        table[c] = frame.positions[:, k]
    if frame.images is not None:
        for k, c in enumerate(("ix", "iy", "iz")):
            table[c] = frame.images[:, k]
    for attr, names in (("velocities", ("vx", "vy", "vz")), ("forces", ("fx", "fy", "fz")),
                        ("omegas", ("omegax", "omegay", "omegaz"))):
        arr = getattr(frame, attr)
        if arr is not None:
            for k, c in enumerate(names):
                table[c] = arr[:, k]
    table["radius"] = frame.radii
    for name, arr in frame.columns.items():
        if arr.ndim == 1:
            table[name] = arr
        else:
            flat = arr.reshape(arr.shape[0], -1)
            for k in range(flat.shape[1]):
                table[f"{name}[{k + 1}]"] = flat[:, k]
    if columns is not None:
        columns = list(columns.split() if isinstance(columns, str) else columns)
        missing = [c for c in columns if c not in table]
        if missing:
            raise ValueError(f"`columns` names {missing} that this frame does not have; "
                             f"available: {list(table)}")
        table = {c: table[c] for c in columns}
    for name in table:
        if not name or any(ch.isspace() for ch in name):
            raise ValueError(f"column name {name!r} cannot be written to a dump header")
    names = list(table)
    arrays = [np.asarray(table[c]) for c in names]
    return names, arrays


def _format_rows(arrays, n) -> bytes:
    if n == 0:
        return b""
    fmts = []
    cols = []
    for a in arrays:
        if a.dtype.kind in "iub":
            fmts.append("%d")
            cols.append(a.astype(np.int64).tolist())
        else:
            fmts.append("%r")
            cols.append(a.astype(np.float64).tolist())
    fmt = " ".join(fmts)
    lines = [fmt % row for row in zip(*cols)]
    return ("\n".join(lines) + "\n").encode("ascii")


def _box_header(box: Box) -> str:
    flags = " ".join(box.boundary)
    b = box.lammps_bounds()
    if box.is_triclinic:
        rows = [f"{float(b[k, 0])!r} {float(b[k, 1])!r} {float(box.tilt[k])!r}" for k in range(3)]
        return f"ITEM: BOX BOUNDS xy xz yz {flags}\n" + "\n".join(rows) + "\n"
    rows = [f"{float(b[k, 0])!r} {float(b[k, 1])!r}" for k in range(3)]
    return f"ITEM: BOX BOUNDS {flags}\n" + "\n".join(rows) + "\n"


def write_dump(path, frames_or_frame, *, columns=None, append=False, units_item=False,
               time_item=False) -> None:
    """Write frames as a LIGGGHTS/LAMMPS text ``dump custom`` file.

    Floats are written with Python's shortest round-trip representation, so
    :func:`read_dump` gives back identical float64 values. The file is
    compressed by extension (``.gz``, ``.bz2``, ``.zst``).

    Parameters
    ----------
    path : path-like
        Output file.
    frames_or_frame : Frame or iterable of Frame
        What to write, in order.
    columns : str or sequence of str, optional
        Dump column names to write, in order (default: ``id type x y z``,
        ``ix iy iz`` and ``vx vy vz fx fy fz omegax omegay omegaz`` where
        present, ``radius``, then every extra column; (N, k) columns are
        written as ``name[1] .. name[k]``).
    append : bool, optional
        Append to an existing file instead of replacing it.
    units_item, time_item : bool, optional
        Also write ``ITEM: UNITS`` / ``ITEM: TIME`` before each frame (LAMMPS
        ``dump_modify units yes`` / ``time yes``). Off by default because
        LIGGGHTS and some readers do not know these items.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, write_dump
    >>> path = os.path.join(tempfile.mkdtemp(), "dump.liggghts")
    >>> write_dump(path, Frame([[0.1, 0.2, 0.3]], [0.05], box=[1, 1, 1], timestep=5))
    >>> print(open(path).read().strip())  # doctest: +NORMALIZE_WHITESPACE
    ITEM: TIMESTEP
    5
    ITEM: NUMBER OF ATOMS
    1
    ITEM: BOX BOUNDS pp pp pp
    0.0 1.0
    0.0 1.0
    0.0 1.0
    ITEM: ATOMS id type x y z radius
    1 1 0.1 0.2 0.3 0.05
    """
    frames = [frames_or_frame] if isinstance(frames_or_frame, Frame) else frames_or_frame
    with _open_write(path, append) as fh:
        for frame in frames:
            if not isinstance(frame, Frame):
                raise TypeError(f"expected Frame objects; got {type(frame).__name__}")
            names, arrays = _frame_table(frame, columns)
            head = []
            if units_item and frame.units.style:
                head.append(f"ITEM: UNITS\n{frame.units.style}\n")
            if time_item and frame.time is not None:
                head.append(f"ITEM: TIME\n{float(frame.time)!r}\n")
            head.append(f"ITEM: TIMESTEP\n{frame.timestep}\n")
            head.append(f"ITEM: NUMBER OF ATOMS\n{frame.n_particles}\n")
            head.append(_box_header(frame.box))
            head.append("ITEM: ATOMS " + " ".join(names) + "\n")
            fh.write("".join(head).encode("ascii"))
            fh.write(_format_rows(arrays, frame.n_particles))
