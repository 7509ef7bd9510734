"""The lazy trajectory of dump files: one scan for the byte offset of every frame
(text or binary), then one frame parsed per access.

Implementation module of :mod:`bedstruct.io.lammps_dump` (import from there).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..core import Frame, Trajectory
from ..errors import BedstructWarning, DumpFormatError
from ._binary import is_binary, parse_binary_frame, scan_binary
from ._columns import frame_from_raw
from ._source import Source, scan_text, stream_cut
from ._stream import _stream_columns
from ._text import (RawFrame, TruncatedFrame, check_unit_style, normalise_columns,
                    parse_text_frame, tail_truncation, truncated)

__all__ = ["DumpTrajectory", "SkippedFrame", "ON_ERROR"]

#: What a reader does with a malformed frame: raise (default) or skip it with a warning.
ON_ERROR = ("raise", "skip")


@dataclass(frozen=True)
class SkippedFrame:
    """A frame left out of a trajectory because it is malformed or cut off.

    Attributes
    ----------
    path : str
        The file holding the frame.
    timestep : int or None
        Its timestep (None when the timestep itself cannot be read).
    line : int or None
        The 1-based line where the problem was found (text dumps); for
        binary dumps the reader's position, as in
        :class:`~bedstruct.errors.DumpFormatError`.
    reason : str
        What is wrong, as the strict reader's error says it.
    """

    path: str
    timestep: int | None
    line: int | None
    reason: str

    def to_dict(self) -> dict:
        """The record as a JSON-ready dict."""
        return {"path": self.path, "timestep": self.timestep, "line": self.line,
                "reason": self.reason}

    def __str__(self) -> str:
        where = f"{self.path}" + (f", line {self.line}" if self.line is not None else "")
        step = "unknown" if self.timestep is None else self.timestep
        return f"{where}: frame at timestep {step} skipped: {self.reason}"


def check_on_error(on_error) -> str:
    """``on_error`` when it is one of :data:`ON_ERROR`, else a ValueError naming them."""
    if on_error not in ON_ERROR:
        raise ValueError(f"`on_error` must be 'raise' (a malformed frame is an error) or 'skip' "
                         f"(it is left out with a warning); got {on_error!r}")
    return on_error


class _Entry:
    __slots__ = ("file", "kind", "start", "end", "line", "timestep", "count", "at_eof", "state",
                 "index", "units", "units_line", "rows")

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
                 wrap=False, columns=None, on_error="raise"):
        units = check_unit_style(units)
        lenient = check_on_error(on_error) == "skip"
        strict = strict and not lenient
        self._opts = dict(radius=radius, units=units, sort_by_id=sort_by_id, wrap=wrap)
        self._columns = normalise_columns(columns)
        self._files = [_File(p) for p in paths]
        #: The frames left out (:class:`SkippedFrame`), in file order.
        self.skipped: list[SkippedFrame] = []
        entries = []
        for f in self._files:
            found = self._scan(f, strict, lenient)
            _carry_units(found, units)   # a style stated by a frame left out still holds
            if lenient:
                found = self._keep_readable(found)
            entries.extend(found)
        if len(self._files) > 1:
            entries.sort(key=lambda e: e.timestep)  # stable: file order, then file position
        self._entries = entries

    def _skip(self, path, timestep, exc: DumpFormatError, what: str, stacklevel: int) -> None:
        """Record a left-out frame and warn, naming the file, timestep and line."""
        record = SkippedFrame(path=str(path), timestep=timestep, line=exc.line,
                              reason=exc.message)
        self.skipped.append(record)
        step = "unknown" if timestep is None else timestep
        line = "" if exc.line is None else f" (line {exc.line})"
        warnings.warn(f"skipping {what} of {path} (timestep {step}): {exc.message}{line}",
                      BedstructWarning, stacklevel=stacklevel + 1)

    def _keep_readable(self, entries: list) -> list:
        """The entries whose frames read without error; each other one is skipped.

        Every frame is parsed once here, so that the trajectory holds only
        frames that read: the cost of ``on_error="skip"``.
        """
        kept = []
        for e in entries:
            try:
                self._read_entry(e)
            except DumpFormatError as exc:
                self._skip(e.file.path, e.timestep, exc, "a malformed frame", stacklevel=4)
                continue
            kept.append(e)
        for k, e in enumerate(kept):
            e.at_eof = e.at_eof and k == len(kept) - 1
        return kept

    # ----------------------------------------------------------------- scanning
    def _scan(self, f: _File, strict: bool, lenient: bool = False) -> list:
        src = f.source
        head = src.read_range(0, 64)
        src.close()
        if not head.strip():
            return []
        if is_binary(head):
            return self._scan_binary(f, strict)
        scan = scan_text(src, lenient=lenient)
        stream_cut(src, strict, stacklevel=5)
        f.ends_with_newline = scan.ends_with_newline
        if not scan.starts and scan.cut_line is not None:
            exc = truncated("the file ends inside the header of its first frame", path=f.path,
                            line=scan.cut_line)
            if strict:
                raise exc
            self._skip(f.path, None, exc, "the truncated only frame", stacklevel=4)
            return []
        entries = []
        for k, start in enumerate(scan.starts):
            entries.append(_Entry(file=f, kind="text", start=start, end=scan.end(k),
                                  line=scan.lines[k], timestep=scan.timesteps[k],
                                  count=scan.counts[k], at_eof=k == len(scan.starts) - 1,
                                  state=None, index=k, units=scan.units[k],
                                  units_line=scan.units_lines[k], rows=scan.rows(k)))
        if entries:
            self._check_last_text(f, entries, strict, scan.tail)
        return entries

    def _check_last_text(self, f, entries, strict, tail=None):
        """Skip (strict=False) or report a last frame cut off by the end of the file.

        A last line without its newline is always cut off: LAMMPS ends every
        line with one, and a cut number (``0.0025`` as ``0.002``) still parses.
        """
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
            self._skip(f.path, last.timestep, exc, "the truncated last frame", stacklevel=5)
            entries.pop()
            if entries:
                entries[-1].at_eof = False
            return
        except DumpFormatError:
            return  # any other defect is reported when that frame is read
        if raw.partial_tail is not None:
            exc = tail_truncation(raw, buf, last.line)
            if strict:
                raise exc
            self._skip(f.path, None, exc, "a cut-off frame header at the end",
                       stacklevel=5)
            last.end = last.start + raw.tail_offset
            last.at_eof = False
        elif last.timestep is None:
            last.timestep = raw.timestep

    def _scan_binary(self, f, strict):
        scan = scan_binary(f.source)
        if scan.truncated_at is not None:
            if strict or not scan.starts:
                raise DumpFormatError(f"truncated frame: binary snapshot {len(scan.starts) + 1} "
                                      f"is cut off at byte {scan.truncated_at}", path=f.path)
            exc = DumpFormatError(f"truncated frame: binary snapshot {len(scan.starts) + 1} "
                                  f"is cut off at byte {scan.truncated_at}", path=f.path)
            self._skip(f.path, None, exc, "the truncated last snapshot", stacklevel=4)
        return [_Entry(file=f, kind="binary", start=s, end=e, line=None, timestep=t, count=c,
                       at_eof=False, state=st, index=k, units=u, units_line=None, rows=r)
                for k, (s, e, t, c, st, u, r) in enumerate(zip(
                    scan.starts, scan.ends, scan.timesteps, scan.counts, scan.states,
                    scan.units, scan.rows))]

    # ----------------------------------------------------------------- access
    def __len__(self) -> int:
        return len(self._entries)

    def _raw(self, index: int, *, header_only=False) -> RawFrame:
        return self._raw_entry(self._entries[index], header_only=header_only)

    def _raw_entry(self, e: _Entry, *, header_only=False) -> RawFrame:
        buf = e.file.source.read_range(e.start, e.end - e.start)
        if e.kind == "binary":
            raw = parse_binary_frame(buf, path=e.file.path, state=e.state,
                                     columns=self._columns, header_only=header_only)
            return _with_file_units(raw, e)
        raw = parse_text_frame(buf, path=e.file.path, line0=e.line, at_eof=e.at_eof,
                               file_ends_with_newline=e.file.ends_with_newline,
                               header_only=header_only, ncols_override=self._columns)
        del buf  # the frame text is not kept: messages re-read the line they need
        raw._rows = self._row_reader(e, raw.data_line)
        return _with_file_units(raw, e)

    def _row_reader(self, e, data_line):
        def row_text(r):
            buf = e.file.source.read_range(e.start, e.end - e.start)
            pos = _offset_of_line(buf, data_line + r - 1 - e.line)
            end = buf.find(b"\n", pos)
            return buf[pos:len(buf) if end < 0 else end].decode("latin-1").rstrip("\r")
        return row_text

    def _read_frame(self, index: int) -> Frame:
        return self._read_entry(self._entries[index])

    def _read_entry(self, e: _Entry) -> Frame:
        if e.kind == "text":
            frame = self._read_text_fast(e)
            if frame is not None:
                return frame
        raw = self._raw_entry(e)  # general path: exact error messages, rare tokens
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
        return frame_from_raw(_with_file_units(raw, e), frame_index=e.index, planned=planned,
                              **self._opts)

    def check_structure(self) -> None:
        """Check every frame's row count against its header, without parsing values.

        The counts come from the scan (lines between ``ITEM: ATOMS`` and the
        next frame, or the size of a binary snapshot), so this costs nothing
        for a well-formed file; a frame that disagrees is re-read to name the
        exact line.

        Raises
        ------
        DumpFormatError
            For the first frame whose rows do not match its header (or whose
            header is malformed).
        """
        for k, e in enumerate(self._entries):
            if e.rows is not None and e.rows == e.count:
                continue
            if e.kind == "binary":
                self._raw(k)
                continue
            buf = e.file.source.read_range(e.start, e.end - e.start)
            parse_text_frame(buf, path=e.file.path, line0=e.line, at_eof=e.at_eof,
                             file_ends_with_newline=e.file.ends_with_newline,
                             parse_values=False, ncols_override=self._columns)

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

    def __iter__(self):
        """The frames in order, one parsed at a time; the files are closed when the
        iteration ends (exhausted, broken off or failed)."""
        try:
            for k in range(len(self)):
                yield self._read_frame(k)
        finally:
            self.close()

    def close(self) -> None:
        """Close the open files (reading again reopens them).

        A trajectory also closes its files when an iteration over it ends and
        when it is garbage collected.
        """
        for f in self._files:
            f.source.close()

    def __repr__(self) -> str:
        what = self._files[0].path if len(self._files) == 1 else f"{len(self._files)} files"
        return f"DumpTrajectory({what!r}, n_frames={len(self)})"


def _carry_units(entries, units) -> None:
    """Give every frame of one file the unit style stated before it.

    LAMMPS writes ``ITEM: UNITS`` (and the unit string of a binary dump) only
    before the first snapshot, so a style holds until the file states another.
    A style that contradicts ``units=`` is an error naming the line.
    """
    style = line = None
    for e in entries:
        if e.units is not None:
            style, line = e.units, e.units_line
            if units is not None and style != units:
                raise DumpFormatError(f"the file says 'ITEM: UNITS {style}' but units={units!r} "
                                      f"was given", path=e.file.path, line=line)
        e.units, e.units_line = style, line


def _with_file_units(raw: RawFrame, e: _Entry) -> RawFrame:
    if raw.units is None:
        raw.units = e.units
    return raw


def _offset_of_line(buf: bytes, k: int) -> int:
    """Byte offset of the 0-based line ``k`` of ``buf``."""
    pos = 0
    for _ in range(k):
        nxt = buf.find(b"\n", pos)
        if nxt < 0:
            return len(buf)
        pos = nxt + 1
    return pos
