"""Parsing one frame of a text LAMMPS/LIGGGHTS dump (``dump custom`` or ``dump local``).

The header is read line by line (a handful of lines); the data block is parsed
in one vectorised pass by :func:`bedstruct.io._kernels.parse_rows`. Only when
that pass reports a problem is the offending line read again with plain Python
to say exactly what is wrong and where.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..core import Box
from ..errors import BedstructWarning, DumpFormatError
from ._kernels import parse_rows

__all__ = ["RawFrame", "TruncatedFrame", "parse_text_frame", "parse_block", "line_bounds",
           "many_slow_rows", "general_block", "parse_lines_threaded", "parse_token", "truncated",
           "starts_frame",
           "tail_truncation", "skip_or_raise",
           "check_unit_style", "LAMMPS_UNIT_STYLES", "normalise_columns"]

_KNOWN_ITEMS = ("TIMESTEP", "NUMBER OF ATOMS", "NUMBER OF ENTRIES", "BOX BOUNDS", "ATOMS",
                "ENTRIES", "UNITS", "TIME")
_FLAGS = set("pfsm")
#: The items a frame may start with (LAMMPS writes UNITS and TIME before TIMESTEP).
_FRAME_STARTS = (b"ITEM: TIMESTEP", b"ITEM: UNITS", b"ITEM: TIME")

#: The unit styles of the LAMMPS ``units`` command.
LAMMPS_UNIT_STYLES = ("si", "cgs", "micro", "nano", "lj", "real", "metal", "electron")

# Characters of the numbers C's printf writes (decimal, nan, inf, infinity). Anything else
# (Python's '1_000', hex floats, Fortran 'D' exponents, 'nan(1)') is refused rather than read
# by whichever parser happens to accept it.
_NOT_NUMBER = re.compile(r"[^0-9eE.+\-naifNAIFtyTY]")
_NUMBER_TEXT = b"0123456789eE.+-naifNAIFtyTY \t\r\n\v\f"


class TruncatedFrame(DumpFormatError):
    """A frame that ends early at the end of the file (being written, or cut off)."""


def truncated(detail: str, *, path, line: int, text=None) -> TruncatedFrame:
    """The error for a file that ends inside a frame, at 1-based ``line``."""
    return TruncatedFrame(f"truncated frame: the file looks truncated at line {line}: {detail}",
                          path=path, line=line, text=text)


def tail_truncation(raw: "RawFrame", buf: bytes, line0: int) -> TruncatedFrame:
    """The error for the frame header cut off after the last complete frame
    (``raw.partial_tail``) of a file; ``buf`` runs from line ``line0`` to its end."""
    return truncated(f"the frame header that starts at line {raw.partial_tail} is cut off",
                     path=raw.path, line=line0 + buf.count(b"\n") + 1)


def skip_or_raise(exc: TruncatedFrame, strict: bool, what: str, stacklevel: int = 3) -> None:
    """strict: raise ``exc``; else warn that ``what`` (the cut-off part) is skipped."""
    if strict:
        raise exc
    warnings.warn(f"{what}: {exc.message}", BedstructWarning, stacklevel=stacklevel + 1)


def starts_frame(line: bytes) -> bool:
    """Whether ``line`` (possibly cut off) can begin a frame: a prefix of, or one of,
    ``ITEM: TIMESTEP``, ``ITEM: UNITS``, ``ITEM: TIME``."""
    s = line.strip()
    return bool(s) and any(k.startswith(s) or s == k for k in _FRAME_STARTS)


def parse_token(tok) -> float:
    """The value of one number token, as C's ``strtod`` reads what ``printf`` writes.

    Raises
    ------
    ValueError
        For anything else, including tokens Python's ``float`` alone accepts
        (``1_000``).
    """
    s = tok.decode("latin-1") if isinstance(tok, (bytes, bytearray)) else str(tok)
    if _NOT_NUMBER.search(s):
        raise ValueError(f"not a number: {s!r}")
    return float(s)


def check_unit_style(units, *, path=None, line=None, text=None):
    """``units`` lower-cased when it is a LAMMPS unit style (or None).

    Raises
    ------
    ValueError
        For anything else (a :class:`DumpFormatError` naming ``path`` and
        ``line`` when they are given: the style was read from a file).
    """
    if units is None:
        return None
    style = units.lower() if isinstance(units, str) else None
    if style in LAMMPS_UNIT_STYLES:
        return style
    msg = (f"unknown unit style {units!r}; expected one of {', '.join(LAMMPS_UNIT_STYLES)} "
           f"(the LAMMPS 'units' styles)")
    if path is not None:
        raise DumpFormatError(msg, path=path, line=line, text=text)
    raise ValueError(f"`units`: {msg}, or None when not known")


def normalise_columns(columns):
    """``columns=`` as a list of names: a string is split on whitespace.

    Raises
    ------
    ValueError
        If no name is given or a name is not a string.
    """
    if columns is None:
        return None
    names = columns.split() if isinstance(columns, str) else list(columns)
    if not names or not all(isinstance(c, str) and c and not any(ch.isspace() for ch in c)
                            for c in names):
        raise ValueError(f"`columns` must name the dump columns, as 'id type x y z radius' or "
                         f"a list of names; got {columns!r}")
    return names


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
    tail_offset: int | None = None   # its byte offset in the frame text
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


def _box_line(text: bytes, tri: bool, path, line):
    what = "a triclinic box line 'lo hi tilt'" if tri else "a box line 'lo hi'"
    vals = _floats(text, 3 if tri else 2, path, line, what)
    if not all(np.isfinite(vals)):
        raise DumpFormatError(f"box bounds must be finite; expected {what}", path=path,
                              line=line, text=_decode(text))
    if vals[1] < vals[0]:
        raise DumpFormatError(f"box 'hi' {vals[1]!r} is below 'lo' {vals[0]!r}", path=path,
                              line=line, text=_decode(text))
    return vals


def _check_box(bounds, tilt, boundary, path, line, text):
    """The box the header describes must exist (a triclinic bounding box narrower than
    its tilt gives hi < lo once converted back)."""
    try:
        Box.from_lammps_bounds(bounds, tilt, boundary)
    except ValueError as exc:
        raise DumpFormatError(f"invalid box: {exc}", path=path, line=line, text=text) from None


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
    mismatch; a cut-off frame header after the data is then reported in
    ``partial_tail``. ``file_ends_with_newline=False`` (with ``at_eof``) means
    the last line is cut off. With ``parse_values=False`` everything but the
    numbers is checked.
    """
    if at_eof and not file_ends_with_newline:
        return _parse_cut_frame(buf, path=path, line0=line0, parse_values=parse_values,
                                header_only=header_only, ncols_override=ncols_override)
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
            if at_eof:
                raise truncated(f"the file ends inside a frame header (expected {what})",
                                path=path, line=lnum)
            raise DumpFormatError(f"the frame header is incomplete before the next "
                                  f"'ITEM: TIMESTEP' (expected {what})", path=path, line=lnum)

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
            units = val.strip().decode("latin-1") or None
            units = check_unit_style(units, path=path, line=ln + 1, text=_decode(val))
            ln += 1
        elif item_s == "TIME":
            need(p, "the time", ln + 1)
            val, p = line_at(p)
            time = _floats(val, 1, path, ln + 1, "TIME")[0]
            ln += 1
        elif item_s.startswith("BOX BOUNDS"):
            tokens = item_s.split()[2:]
            if tokens[:2] == ["abc", "origin"]:
                raise DumpFormatError("the general triclinic box of newer LAMMPS ('BOX BOUNDS "
                                      "abc origin') is not supported yet; dump with the "
                                      "restricted triclinic box ('xy xz yz')", path=path,
                                      line=item_line, text=_decode(text))
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
                rows.append(_box_line(val, tri, path, ln + 1))
                ln += 1
            rows = np.array(rows, dtype=np.float64)
            bounds = rows[:, :2].copy()
            tilt = rows[:, 2].copy() if tri else None
            _check_box(bounds, tilt, boundary, path, item_line, _decode(text))
        elif item_s.split(" ")[0] in ("ATOMS", "ENTRIES"):
            kind = item_s.split(" ")[0]
            names = item_s.split()[1:]
            header_line = item_line
            if ncols_override is not None:
                names = normalise_columns(ncols_override)
            break
        else:
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
    raw.data, tail, raw._rows = parse_block(buf, p, n, len(names), path=path,
                                            data_line=ln + 1, at_eof=at_eof,
                                            parse_values=parse_values, names=names)
    if tail is not None:
        raw.partial_tail, raw.tail_offset = tail
        _check_tail(buf, raw.tail_offset, raw.partial_tail, path)
    return raw


def _parse_cut_frame(buf: bytes, *, path: str, line0: int, **kw) -> RawFrame:
    """The last frame of a file whose last line has no newline.

    LAMMPS ends every line with a newline, so that line was cut off, possibly
    inside a number (``0.0025`` read as ``0.002``): it is never parsed. Either
    the frame is incomplete without it (:class:`TruncatedFrame`), or the frame
    is complete and the cut line begins the next frame's header
    (``partial_tail``), or it is a surplus row (a count mismatch).
    """
    k = buf.rfind(b"\n") + 1
    cut = buf[k:]
    cut_line = line0 + buf.count(b"\n", 0, k) + 1
    try:
        raw = parse_text_frame(buf[:k], path=path, line0=line0, at_eof=True, **kw)
    except TruncatedFrame:
        raise truncated("its last line ends without a newline (LAMMPS ends every line with "
                        "one), so it is cut off", path=path, line=cut_line,
                        text=_decode(cut)) from None
    if kw.get("header_only") or raw.partial_tail is not None:
        return raw
    if not starts_frame(cut):
        raise DumpFormatError(f"atom count mismatch: the header says {raw.n} rows but more "
                              f"follow", path=path, line=cut_line, text=_decode(cut))
    raw.partial_tail, raw.tail_offset = cut_line, k
    return raw


def _check_tail(buf: bytes, offset: int, line: int, path: str) -> None:
    """Lines after the last complete frame of a file must be the start of a frame header
    cut off by the end of the file; anything else is reported where it goes wrong."""
    try:
        parse_text_frame(buf[offset:], path=path, line0=line - 1, at_eof=True,
                         header_only=True)
    except TruncatedFrame:
        return
    # a complete header the scan did not take for a frame: it lacks ITEM: TIMESTEP
    raise DumpFormatError("expected 'ITEM: TIMESTEP' to start a new frame", path=path,
                          line=line, text=_decode(buf[offset:buf.find(b"\n", offset)]))


def _is_space(c: int) -> bool:
    return c <= 32


def line_bounds(buf: bytes, p: int):
    """The data block ``buf[p:]`` without trailing blank space, as a uint8 array, with
    the start and end offsets of its lines (relative to ``p``) and its end in ``buf``."""
    end = len(buf)
    while end > p and _is_space(buf[end - 1]):
        end -= 1
    body = np.frombuffer(buf, dtype=np.uint8)[p:end]
    body.flags.writeable = False   # the kernels' one signature, whatever holds the text
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

    Returns None when the block does not hold exactly ``n * ncols`` numbers or
    holds any token that is not a number (the caller then reads row by row to
    say which).
    """
    if bytes(text).translate(None, _NUMBER_TEXT):  # anything left is not a number character
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            flat = np.fromstring(bytes(text), dtype=np.float64, sep=" ")
        except ValueError:  # numpy >= 2 raises on a bad token; older versions stop there
            return None
    return flat.reshape(n, ncols) if flat.size == n * ncols else None


def parse_lines_threaded(arr, start: int, stop: int, ncols: int, out, base, stride, *,
                         threads: int) -> bool:
    """Parse the lines of ``arr[start:stop]`` as rows 0, 1, ... with
    :func:`~bedstruct.io._kernels.parse_lines`, cut at line starts into ``threads``
    spans parsed at once (each on its own thread).

    ``arr`` is a uint8 array whose text ends without blank lines; ``out`` holds as
    many rows as it has lines. Returns True when every line was read exactly; False
    leaves the rows in an unknown state (parse them with :func:`parse_rows` then).
    """
    from ._kernels import count_lines, parse_lines

    size = stop - start
    threads = max(1, min(threads, size >> 16))  # below 64 KiB a span is not worth a thread
    if threads == 1:
        return parse_lines(arr, start, stop, ncols, out, base, stride, 0) == \
            count_lines(arr, start, stop)
    cuts = [start]
    for k in range(1, threads):
        x = start + size * k // threads
        nl = np.flatnonzero(arr[x:min(stop, x + (1 << 16))] == 10)
        cuts.append(max(cuts[-1], x + int(nl[0]) + 1) if nl.size else cuts[-1])
    cuts.append(stop)
    rows = [0]
    for a, b in zip(cuts[:-1], cuts[1:]):
        rows.append(rows[-1] + count_lines(arr, a, b))
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(threads) as pool:
        done = list(pool.map(lambda k: parse_lines(arr, cuts[k], cuts[k + 1], ncols, out, base,
                                                   stride, rows[k]), range(threads)))
    return done == rows[1:]


def parse_block(buf: bytes, p: int, n: int, ncols: int, *, path: str, data_line: int,
                at_eof: bool, parse_values: bool = True, names=None):
    """Parse ``n`` lines of ``ncols`` numbers from ``buf[p:]``.

    Returns ``(data, tail, row_text)`` where ``tail`` is ``(line, offset)`` of a
    cut-off frame header found after the data at the end of the file (else
    None).
    """
    from .._numba import get_num_threads
    from ._kernels import count_lines

    end = len(buf)
    while end > p and _is_space(buf[end - 1]):
        end -= 1
    arr = np.frombuffer(buf, dtype=np.uint8)
    arr.flags.writeable = False   # the kernels' one signature, whatever holds the text
    m = count_lines(arr, p, end)
    names = [f"column {c + 1}" for c in range(ncols)] if names is None else list(names)
    what = f"({' '.join(names)})"
    bounds = []  # line starts and ends, found only when needed

    def lines():
        if not bounds:
            bounds.extend(line_bounds(buf, p)[1:3])
        return bounds

    def row_text(r):
        starts, ends = lines()
        return buf[p + starts[r]:p + ends[r]].decode("latin-1").rstrip("\r")

    tail = None
    stop = end
    if m > n:
        extra = row_text(n)
        if at_eof and starts_frame(extra.encode("latin-1")):
            starts, ends = lines()
            tail = (data_line + n, p + int(starts[n]))
            stop = p + int(ends[n - 1]) if n else p
            m = n
        else:
            raise DumpFormatError(f"atom count mismatch: the header says {n} rows but more "
                                  f"follow", path=path, line=data_line + n, text=extra.strip())
    if m < n:
        if at_eof:
            raise truncated(f"the header says {n} rows but the file ends after {m}",
                            path=path, line=data_line + m)
        raise DumpFormatError(f"atom count mismatch: the header says {n} rows but only {m} "
                              f"follow before the next frame", path=path, line=data_line + m)
    if not parse_values:
        return None, tail, row_text
    out = np.empty((n, ncols), dtype=np.float64)
    if n == 0:
        return out, tail, row_text
    if parse_lines_threaded(arr, p, stop, ncols, out.reshape(-1), np.arange(ncols, dtype=np.int64),
                            np.full(ncols, ncols, dtype=np.int64), threads=get_num_threads()):
        return out, tail, row_text
    starts, ends = lines()
    body = arr[p:end]
    status = np.empty(n, dtype=np.int8)
    parse_rows(body, starts[:n], ends[:n], ncols, out.reshape(-1),
               np.arange(ncols, dtype=np.int64), np.full(ncols, ncols, dtype=np.int64),
               np.arange(n, dtype=np.int64), status)
    bad = np.flatnonzero(status == 1)
    if bad.size:
        r = int(bad[0])
        text = row_text(r)
        raise DumpFormatError(f"wrong number of values on a line: found {len(text.split())}, "
                              f"expected {ncols} {what}", path=path, line=data_line + r,
                              text=text)
    slow = np.flatnonzero(status == 2)
    if many_slow_rows(slow.size, n):
        block = general_block(buf[p:end], n, ncols)
        if block is not None:
            return block, tail, row_text
    for r in slow:
        r = int(r)
        text = row_text(r)
        for c, tok in enumerate(text.split()):
            try:
                out[r, c] = parse_token(tok)
            except ValueError:
                raise DumpFormatError(f"non-numeric value {tok!r} in column {c + 1} "
                                      f"'{names[c]}' of {what}; expected a number", path=path,
                                      line=data_line + r, text=text) from None
    return out, tail, row_text
