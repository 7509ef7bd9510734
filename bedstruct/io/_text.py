"""Parsing one frame of a text LAMMPS/LIGGGHTS dump (``dump custom`` or ``dump local``).

The header is read line by line (a handful of lines); the data block is parsed
in one vectorised pass by :func:`bedstruct.io._kernels.parse_rows`. Only when
that pass reports a problem is the offending line read again with plain Python
to say exactly what is wrong and where.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import DumpFormatError
from ._kernels import parse_rows

__all__ = ["RawFrame", "TruncatedFrame", "parse_text_frame", "parse_block", "line_bounds",
           "many_slow_rows", "general_block"]

_KNOWN_ITEMS = ("TIMESTEP", "NUMBER OF ATOMS", "NUMBER OF ENTRIES", "BOX BOUNDS", "ATOMS",
                "ENTRIES", "UNITS", "TIME")
_FLAGS = set("pfsm")


class TruncatedFrame(DumpFormatError):
    """A frame that ends early at the end of the file (being written, or cut off)."""


@dataclass
class RawFrame:
    """A frame as written: header values and the (n, ncols) float64 data block."""

    path: str
    timestep: int
    n: int
    bounds: np.ndarray
    tilt: np.ndarray | None
    boundary: tuple
    kind: str
    names: list
    data: np.ndarray | None
    units: str | None = None
    time: float | None = None
    data_line: int = 0              # 1-based line number of the first data row
    header_line: int = 0            # 1-based line number of the ITEM: ATOMS/ENTRIES line
    notes: list = field(default_factory=list)
    partial_tail: int | None = None  # line of a cut-off frame header after this frame
    body_offset: int = 0             # byte offset of the data block in the frame text
    _rows: object = None             # callable r -> text of data row r (for messages)

    def row_text(self, r: int) -> str | None:
        return None if self._rows is None else self._rows(r)


def _decode(b: bytes) -> str:
    return b.decode("latin-1").rstrip("\r\n")


def _floats(text: bytes, count: int, path, line, what: str):
    parts = text.split()
    if len(parts) != count:
        raise DumpFormatError(f"expected {count} numbers for {what}, found {len(parts)}",
                              path=path, line=line, text=_decode(text))
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise DumpFormatError(f"expected {count} numbers for {what}", path=path, line=line,
                              text=_decode(text)) from None
    return vals


def _integer(text: bytes, path, line, what: str) -> int:
    s = text.strip()
    try:
        return int(s)
    except ValueError:
        pass
    try:
        v = float(s)
        if np.isfinite(v) and v.is_integer():
            return int(v)
    except ValueError:
        pass
    raise DumpFormatError(f"expected an integer for {what}", path=path, line=line,
                          text=_decode(text))


def _parse_boundary(tokens, path, line, text):
    if len(tokens) == 0:
        return ("pp", "pp", "pp"), True
    if len(tokens) != 3 or any(len(t) not in (1, 2) or not set(t) <= _FLAGS for t in tokens):
        raise DumpFormatError("expected three boundary flags such as 'pp pp ff' after "
                              "'ITEM: BOX BOUNDS [xy xz yz]'", path=path, line=line, text=text)
    out = []
    for t in tokens:
        t = t if len(t) == 2 else t + t
        if "p" in t and t != "pp":
            raise DumpFormatError("a periodic boundary flag must be 'pp'", path=path, line=line,
                                  text=text)
        out.append(t)
    return tuple(out), False


def parse_text_frame(buf: bytes, *, path: str, line0: int = 0, at_eof: bool = True,
                     file_ends_with_newline: bool = True, parse_values: bool = True,
                     header_only: bool = False, ncols_override=None) -> RawFrame:
    """Parse one frame whose text starts at ``buf[0]`` (0-based line ``line0``).

    ``at_eof`` says that ``buf`` runs to the end of the file, so that missing
    data means a truncated frame (:class:`TruncatedFrame`) rather than a count
    mismatch. With ``parse_values=False`` everything but the numbers is checked.
    """
    p = 0
    ln = line0          # 0-based index of the line starting at p
    size = len(buf)
    timestep = n = None
    bounds = tilt = boundary = None
    units = time = None
    notes = []
    kind = names = None
    header_line = 0

    def line_at(pos):
        e = buf.find(b"\n", pos)
        if e < 0:
            return buf[pos:], size
        return buf[pos:e], e + 1

    def need(pos, what, lnum):
        if pos >= size:
            cls = TruncatedFrame if at_eof else DumpFormatError
            raise cls(f"truncated frame: the file ends inside the header (expected {what})",
                      path=path, line=lnum)

    while True:
        need(p, "'ITEM: ATOMS ...'", ln + 1)
        text, q = line_at(p)
        stripped = text.strip()
        if not stripped:
            p, ln = q, ln + 1
            continue
        if not stripped.startswith(b"ITEM:"):
            raise DumpFormatError("expected an 'ITEM: ...' header line", path=path, line=ln + 1,
                                  text=_decode(text))
        item = stripped[5:].strip()
        item_s = item.decode("latin-1")
        item_line = ln + 1
        p, ln = q, ln + 1
        if item_s == "TIMESTEP":
            need(p, "the timestep", ln + 1)
            val, p = line_at(p)
            timestep = _integer(val, path, ln + 1, "TIMESTEP")
            ln += 1
        elif item_s in ("NUMBER OF ATOMS", "NUMBER OF ENTRIES"):
            need(p, "the number of atoms", ln + 1)
            val, p = line_at(p)
            n = _integer(val, path, ln + 1, item_s)
            if n < 0:
                raise DumpFormatError(f"{item_s} must not be negative", path=path, line=ln + 1,
                                      text=_decode(val))
            ln += 1
        elif item_s == "UNITS":
            need(p, "the unit style", ln + 1)
            val, p = line_at(p)
            units = val.strip().decode("latin-1").lower() or None
            ln += 1
        elif item_s == "TIME":
            need(p, "the time", ln + 1)
            val, p = line_at(p)
            time = _floats(val, 1, path, ln + 1, "TIME")[0]
            ln += 1
        elif item_s.startswith("BOX BOUNDS"):
            tokens = item_s.split()[2:]
            tri = tokens[:3] == ["xy", "xz", "yz"]
            if tri:
                tokens = tokens[3:]
            boundary, bare = _parse_boundary(tokens, path, item_line, _decode(text))
            if bare:
                notes.append("bare 'ITEM: BOX BOUNDS' without flags: assumed periodic 'pp pp pp'")
            rows = []
            for _ in range(3):
                need(p, "three box bound lines", ln + 1)
                val, p = line_at(p)
                rows.append(_floats(val, 3 if tri else 2, path, ln + 1,
                                    "a triclinic box line 'lo hi tilt'" if tri else "a box line 'lo hi'"))
                ln += 1
            rows = np.array(rows, dtype=np.float64)
            bounds = rows[:, :2].copy()
            tilt = rows[:, 2].copy() if tri else None
        elif item_s.split(" ")[0] in ("ATOMS", "ENTRIES"):
            kind = item_s.split(" ")[0]
            names = item_s.split()[1:]
            header_line = item_line
            if ncols_override is not None:
                names = list(ncols_override)
            break
        else:
            if at_eof and q >= size and not buf.endswith(b"\n") and any(
                    k.startswith(item_s) for k in _KNOWN_ITEMS):
                raise TruncatedFrame("truncated frame: the file ends inside a header line",
                                     path=path, line=item_line, text=_decode(text))
            raise DumpFormatError(
                "unknown header item; expected one of " + ", ".join(f"'ITEM: {k}'" for k in _KNOWN_ITEMS),
                path=path, line=item_line, text=_decode(text))
    missing = [w for w, v in (("ITEM: TIMESTEP", timestep), ("ITEM: NUMBER OF ATOMS", n),
                              ("ITEM: BOX BOUNDS", bounds)) if v is None]
    if missing:
        raise DumpFormatError("frame header lacks " + ", ".join(missing) + f" before 'ITEM: {kind}'",
                              path=path, line=header_line)
    if not names:
        raise DumpFormatError(f"'ITEM: {kind}' names no columns (old dump style); pass columns=",
                              path=path, line=header_line)
    if len(set(names)) != len(names):
        dup = sorted({c for c in names if names.count(c) > 1})
        raise DumpFormatError(f"duplicate column names {dup}", path=path, line=header_line)
    raw = RawFrame(path=path, timestep=timestep, n=n, bounds=bounds, tilt=tilt, boundary=boundary,
                   kind=kind, names=names, data=None, units=units, time=time,
                   data_line=ln + 1, header_line=header_line, notes=notes, body_offset=p)
    if header_only:
        return raw
    raw.data, raw.partial_tail, raw._rows = parse_block(
        buf, p, n, len(names), path=path, data_line=ln + 1, at_eof=at_eof,
        file_ends_with_newline=file_ends_with_newline, parse_values=parse_values,
        what=f"({' '.join(names)})")
    return raw


def _is_space(c: int) -> bool:
    return c <= 32


def line_bounds(buf: bytes, p: int):
    """The data block ``buf[p:]`` without trailing blank space, as a uint8 array, with
    the start and end offsets of its lines (relative to ``p``) and its end in ``buf``."""
    end = len(buf)
    while end > p and _is_space(buf[end - 1]):
        end -= 1
    body = np.frombuffer(buf, dtype=np.uint8)[p:end]
    if body.size:
        step = 1 << 22  # newline search in 4 MiB pieces: no frame-sized temporary
        nl = np.concatenate([np.flatnonzero(body[k:k + step] == 10) + k
                             for k in range(0, body.size, step)])
        ends = np.empty(nl.size + 1, dtype=np.int64)
        ends[:-1] = nl
        ends[-1] = body.size
        starts = np.empty_like(ends)
        starts[0] = 0
        starts[1:] = nl + 1
    else:
        starts = ends = np.zeros(0, dtype=np.int64)
    return body, starts, ends, end


def many_slow_rows(n_slow: int, n: int) -> bool:
    """Whether ``n_slow`` of ``n`` rows needing the general parser is enough to
    parse the whole block with :func:`general_block` rather than row by row."""
    return n_slow > max(64, n // 20)


def general_block(text: bytes, n: int, ncols: int):
    """The (n, ncols) values of ``text`` by NumPy's general number parser.

    Returns None when the block does not hold exactly ``n * ncols`` numbers.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flat = np.fromstring(bytes(text), dtype=np.float64, sep=" ")
    return flat.reshape(n, ncols) if flat.size == n * ncols else None


def parse_block(buf: bytes, p: int, n: int, ncols: int, *, path: str, data_line: int,
                at_eof: bool, file_ends_with_newline: bool = True, parse_values: bool = True,
                what: str = ""):
    """Parse ``n`` lines of ``ncols`` numbers from ``buf[p:]``.

    Returns ``(data, partial_tail, row_text)`` where ``partial_tail`` is the line
    number of a cut-off frame header found after the data at the end of the file
    (else None).
    """
    body, starts, ends, end = line_bounds(buf, p)
    m = starts.size

    def row_text(r):
        return buf[p + starts[r]:p + ends[r]].decode("latin-1").rstrip("\r")

    partial_tail = None
    if m > n:
        extra = row_text(n).strip()
        if at_eof and extra.startswith("ITEM:"):
            partial_tail = data_line + n
            starts, ends = starts[:n], ends[:n]
            m = n
        else:
            raise DumpFormatError(f"atom count mismatch: the header says {n} rows but more "
                                  f"follow", path=path, line=data_line + n, text=extra)
    if m < n:
        if at_eof:
            raise TruncatedFrame(f"truncated frame: the header says {n} rows but the file ends "
                                 f"after {m}", path=path, line=data_line + m)
        raise DumpFormatError(f"atom count mismatch: the header says {n} rows but only {m} "
                              f"follow before the next frame", path=path, line=data_line + m)
    last_cut = at_eof and not file_ends_with_newline and partial_tail is None
    if not parse_values:
        if m and last_cut and len(row_text(m - 1).split()) != ncols:
            raise TruncatedFrame(f"truncated frame: the last row has "
                                 f"{len(row_text(m - 1).split())} of {ncols} values",
                                 path=path, line=data_line + m - 1, text=row_text(m - 1))
        return None, partial_tail, row_text
    out = np.empty((n, ncols), dtype=np.float64)
    if n == 0:
        return out, partial_tail, row_text
    status = np.empty(n, dtype=np.int8)
    parse_rows(body, starts, ends, ncols, out.reshape(-1), np.arange(ncols, dtype=np.int64),
               np.full(ncols, ncols, dtype=np.int64), np.arange(n, dtype=np.int64), status)
    bad = np.flatnonzero(status == 1)
    if bad.size:
        r = int(bad[0])
        text = row_text(r)
        k = len(text.split())
        cls = TruncatedFrame if (last_cut and r == n - 1 and k < ncols) else DumpFormatError
        if cls is TruncatedFrame:
            msg = f"truncated frame: the last row has {k} of {ncols} values {what}"
        else:
            msg = f"wrong number of values on a line: found {k}, expected {ncols} {what}"
        raise cls(msg, path=path, line=data_line + r, text=text)
    slow = np.flatnonzero(status == 2)
    if many_slow_rows(slow.size, n):
        block = general_block(buf[p:end], n, ncols)
        if block is not None:
            return block, partial_tail, row_text
    for r in slow:
        r = int(r)
        text = row_text(r)
        for c, tok in enumerate(text.split()):
            try:
                out[r, c] = float(tok)
            except ValueError:
                raise DumpFormatError(f"non-numeric value in column {c + 1} {what}; expected a "
                                      f"number", path=path, line=data_line + r,
                                      text=text) from None
    return out, partial_tail, row_text
