"""Opening (possibly compressed) files and scanning them for frame offsets.

A :class:`Source` reads byte ranges of the *decompressed* stream of one file;
compressed streams are read forwards and reopened when a caller seeks
backwards. A gzip stream resumes from the decompressor's state saved where an
earlier range began (a frame's start) rather than from the start of the file.
:func:`scan_text` finds the byte offset, line number, timestep and
particle count of every frame of a text dump in one pass over the file.
"""

from __future__ import annotations

import bz2
import gzip
import os
import zlib
from dataclasses import dataclass, field

from ..errors import DumpFormatError

__all__ = ["Source", "compression_of", "scan_text", "TextScan", "stream_cut"]

_CHUNK = 1 << 23  # 8 MiB
_EXT = {".gz": "gz", ".gzip": "gz", ".bz2": "bz2", ".zst": "zst", ".zstd": "zst"}
_MAGIC = ((b"\x1f\x8b", "gz"), (b"BZh", "bz2"), (b"\x28\xb5\x2f\xfd", "zst"))


def _decompress_errors():
    errors = [EOFError, OSError, gzip.BadGzipFile, zlib.error]
    try:
        from isal import isal_zlib
        errors.append(isal_zlib.error)
    except ImportError:
        pass
    try:
        import zstandard
        errors.append(zstandard.ZstdError)
    except ImportError:
        pass
    return tuple(errors)


def compression_of(path) -> str | None:
    """``"gz"``, ``"bz2"``, ``"zst"`` or None, from the extension or the magic bytes."""
    ext = os.path.splitext(str(path))[1].lower()
    if ext in _EXT:
        return _EXT[ext]
    with open(path, "rb") as fh:
        head = fh.read(4)
    for magic, kind in _MAGIC:
        if head.startswith(magic):
            return kind
    return None


class _GzipMembers:
    """Forward reader of the (possibly multi-member) gzip stream of a file that stops, rather
    than fails, where the compressed data end early.

    A dump written frame by frame as gzip members and killed during a write ends inside its
    last member; :class:`gzip.GzipFile` then raises and nothing of the file can be read.
    Here everything decoded up to the cut is returned and ``truncated_at`` says where the
    compressed data stopped (None for a complete stream); corrupt data still raise.
    """

    _RAW = 1 << 20

    def __init__(self, path):
        self._raw = open(path, "rb")
        self._inflate = _gzip_inflater()
        self._member = None          # decompressor of the member being read
        self._pending = b""          # decoded bytes, returned from offset _off on
        self._off = 0
        self._read_raw = 0           # compressed bytes consumed
        self._decoded = 0            # decoded bytes before _pending
        self._mark = None            # resume point at the start of _pending (see resume_point)
        self._done = False
        self.truncated_at = None

    def resume_point(self):
        """Where decoding can resume to return the bytes from the start of ``_pending`` on:
        (decoded offset, compressed offset, copy of the member's decompressor or None at a
        member boundary), or None when the decompressor cannot be copied."""
        return self._mark

    def resume(self, point) -> int:
        """Continue decoding from a :meth:`resume_point` of a reader of the same file: the
        decoded offset it returns from."""
        decoded, raw, member = point
        self._raw.seek(raw)
        self._read_raw = raw
        self._member = None if member is None else member.copy()
        self._pending, self._off, self._decoded = b"", 0, decoded
        self._mark = point
        self._done = False
        self.truncated_at = None
        return decoded

    def _decode_more(self) -> None:
        """Decode the next piece of compressed data (``_pending`` is all returned)."""
        self._decoded += len(self._pending)
        try:
            member = None if self._member is None else self._member.copy()
            self._mark = (self._decoded, self._read_raw, member)
        except (AttributeError, ValueError):  # a decompressor without copy()
            self._mark = None
        data = self._raw.read(self._RAW)
        if not data:
            if self._member is not None and not self._member.eof:
                self.truncated_at = self._read_raw  # inside a member: the file was cut
            self._done = True
            return
        self._read_raw += len(data)
        out = []
        while data:
            if self._member is None:
                data = data.lstrip(b"\0")   # zero padding between members is allowed
                if not data:
                    break
                self._member = self._inflate()
            out.append(self._member.decompress(data))
            if self._member.eof:
                data = self._member.unused_data
                self._member = None
            else:
                data = b""
        self._pending = out[0] if len(out) == 1 else b"".join(out)
        self._off = 0

    def readinto(self, view) -> int:
        """Fill ``view`` with the next decoded bytes: the number written (fewer at the end).
        Decoded data are copied once, into ``view``."""
        view = memoryview(view).cast("B")
        got = 0
        while got < len(view):
            left = len(self._pending) - self._off
            if left <= 0:
                if self._done:
                    break
                self._decode_more()
                continue
            k = min(left, len(view) - got)
            view[got:got + k] = memoryview(self._pending)[self._off:self._off + k]
            self._off += k
            got += k
        return got

    def read(self, size: int = -1) -> bytes:
        size = (1 << 62) if size is None or size < 0 else size
        parts = []
        while size > 0:
            left = len(self._pending) - self._off
            if left <= 0:
                if self._done:
                    break
                self._decode_more()
                continue
            k = min(left, size)
            whole = k == len(self._pending)
            parts.append(self._pending if whole else self._pending[self._off:self._off + k])
            self._off += k
            size -= k
        return parts[0] if len(parts) == 1 else b"".join(parts)

    def close(self) -> None:
        self._raw.close()

    def __del__(self):  # a Source left open by a caller closes with it, as GzipFile did
        raw = getattr(self, "_raw", None)
        if raw is not None:
            raw.close()


def _gzip_inflater():
    """A factory of gzip-member decompressors: ISA-L's (about three times faster) when the
    optional 'isal' is installed, else zlib's."""
    try:
        from isal import isal_zlib
        return lambda: isal_zlib.decompressobj(wbits=31)
    except (ImportError, AttributeError):
        return lambda: zlib.decompressobj(wbits=31)


def _open_stream(path, compression):
    if compression is None:
        return open(path, "rb")
    if compression == "gz":
        return _GzipMembers(path)
    if compression == "bz2":
        return bz2.BZ2File(path, "rb")
    if compression == "zst":
        try:
            import zstandard
        except ImportError:
            raise ImportError(f"{path}: reading .zst files needs the 'zstandard' package "
                              "(pip install zstandard)") from None
        raw = open(path, "rb")
        return zstandard.ZstdDecompressor().stream_reader(raw, read_across_frames=True,
                                                         closefd=True)
    raise ValueError(f"unknown compression {compression!r}")


class Source:
    """Random access to the decompressed bytes of one file.

    Parameters
    ----------
    path : path-like
        The file (plain, ``.gz``, ``.bz2`` or ``.zst``).
    """

    def __init__(self, path):
        self.path = os.fspath(path)
        if not os.path.exists(self.path):
            raise FileNotFoundError(f"no such file: {self.path}")
        if os.path.isdir(self.path):
            raise IsADirectoryError(f"is a directory, not a dump file: {self.path}")
        self.compression = compression_of(self.path)
        self._fh = None
        self._pos = 0
        self._resume_points = {}  # decoded offset -> resume point of a gzip stream
        #: Byte of the compressed file at which its data end early (a gz file cut while
        #: being written), once a read has reached that end; None otherwise.
        self.stream_truncated_at = None

    def _reopen(self):
        self.close()
        self._fh = _open_stream(self.path, self.compression)
        self._pos = 0

    def read_range(self, start: int, length: int) -> bytes:
        """``length`` bytes of the decompressed stream from ``start`` (fewer at the end)."""
        if self.compression is None:
            return self._read_range(start, length)
        try:
            return self._read_range(start, length)
        except _decompress_errors() as exc:
            self.close()
            raise DumpFormatError(f"cannot decompress ({self.compression}): {exc}",
                                  path=self.path) from None

    def read_into(self, start: int, view) -> int:
        """Fill the writable buffer ``view`` with the decompressed stream from ``start``:
        the number of bytes read (fewer at the end). Plain files are read straight into
        ``view``, without an intermediate copy."""
        view = memoryview(view).cast("B")
        if self.compression is not None:
            try:
                self._skip_to(start)
            except _decompress_errors() as exc:
                self.close()
                raise DumpFormatError(f"cannot decompress ({self.compression}): {exc}",
                                      path=self.path) from None
            if not hasattr(self._fh, "readinto"):
                data = self.read_range(start, len(view))
                view[:len(data)] = data
                return len(data)
        elif self._fh is None:
            self._reopen()
        if self.compression is None:
            self._fh.seek(start)
        got = 0
        try:
            while got < len(view):
                k = self._fh.readinto(view[got:])
                if not k:
                    break
                got += k
        except _decompress_errors() as exc:
            if self.compression is None:
                raise
            self.close()
            raise DumpFormatError(f"cannot decompress ({self.compression}): {exc}",
                                  path=self.path) from None
        self._pos = start + got
        return got

    def _read_range(self, start: int, length: int) -> bytes:
        if self._fh is None:
            self._reopen()
        if self.compression is None:
            self._fh.seek(start)
            data = self._fh.read(length)
            self._pos = start + len(data)
            return data
        self._skip_to(start)
        self._keep_resume_point()
        data = self._read_exact(length)
        self._pos += len(data)
        return data

    #: Resume points kept per gzip file (each holds a decompressor's state, about 40 KB).
    MAX_RESUME_POINTS = 256

    def _keep_resume_point(self) -> None:
        """Keep the gzip stream's resume point at or before the current offset (the start
        of a range read with :meth:`read_range`, such as a frame's header)."""
        point = getattr(self._fh, "resume_point", lambda: None)()
        if point is not None and point[0] > 0 and len(self._resume_points) < \
                self.MAX_RESUME_POINTS:
            self._resume_points.setdefault(point[0], point)

    def _skip_to(self, start: int) -> None:
        """Move a compressed stream to ``start``: reopened when it is past it, and resumed
        from the last resume point up to ``start`` when one lies ahead of it."""
        if self._fh is None or start < self._pos:
            self._reopen()
        best = max((k for k in self._resume_points if self._pos < k <= start), default=None)
        if best is not None:
            self._pos = self._fh.resume(self._resume_points[best])
        skip = start - self._pos
        while skip > 0:
            got = self._fh.read(min(skip, _CHUNK))
            if not got:
                break
            skip -= len(got)
            self._pos += len(got)

    def _read_exact(self, length):
        parts = []
        while length > 0:
            got = self._fh.read(min(length, 1 << 26))
            if not got:
                break
            parts.append(got)
            length -= len(got)
        return parts[0] if len(parts) == 1 else b"".join(parts)

    def chunks(self, size: int | None = None):
        """Iterate over the whole decompressed stream in chunks (restarts the stream)."""
        size = _CHUNK if size is None else size
        self._reopen()
        try:
            while True:
                try:
                    got = self._fh.read(size)
                except _decompress_errors() as exc:
                    raise DumpFormatError(f"cannot decompress ({self.compression}): {exc}",
                                          path=self.path) from None
                if not got:
                    return
                self._pos += len(got)
                yield got
        finally:
            self.close()

    def close(self):
        if self._fh is not None:
            cut = getattr(self._fh, "truncated_at", None)
            if cut is not None:
                self.stream_truncated_at = cut
            self._fh.close()
            self._fh = None
            self._pos = 0

    def __del__(self):  # the open stream closes with its Source (no ResourceWarning)
        fh = getattr(self, "_fh", None)
        if fh is not None:
            fh.close()

    def __getstate__(self):  # picklable: reopen lazily in the other process
        state = dict(self.__dict__)
        state["_fh"] = None
        state["_pos"] = 0
        state["_resume_points"] = {}  # decompressor states do not pickle
        return state


@dataclass
class TextScan:
    """Where the frames of one text dump start (decompressed byte offsets)."""

    path: str
    starts: list = field(default_factory=list)      # byte offset of the frame's first ITEM line
    lines: list = field(default_factory=list)       # 0-based line index of that line
    timesteps: list = field(default_factory=list)   # int or None
    counts: list = field(default_factory=list)      # NUMBER OF ATOMS / ENTRIES, or None
    units: list = field(default_factory=list)       # unit style stated before the frame, or None
    units_lines: list = field(default_factory=list)  # 1-based line of that style, or None
    body_lines: list = field(default_factory=list)  # 0-based line of ITEM: ATOMS/ENTRIES, or None
    size: int = 0
    n_lines: int = 0                                # lines in the file (a cut last line counts)
    ends_with_newline: bool = True
    first_bytes: bytes = b""
    tail: bytes | None = None   # text of the last frame
    cut_line: int | None = None  # the file ends inside the header of its first frame (1-based)

    def end(self, k: int) -> int:
        return self.starts[k + 1] if k + 1 < len(self.starts) else self.size

    def rows(self, k: int) -> int | None:
        """Lines between frame ``k``'s ``ITEM: ATOMS`` line and the next frame (its
        data rows plus any blank lines), or None when it has no such line."""
        if self.body_lines[k] is None:
            return None
        end = self.lines[k + 1] if k + 1 < len(self.starts) else self.n_lines
        return end - self.body_lines[k] - 1


def _int_value(raw: bytes, path, line):
    try:
        return int(raw.strip())
    except ValueError:
        pass
    try:  # some writers print large step numbers as floats (1e+06)
        v = float(raw.strip())
        if v.is_integer():
            return int(v)
    except ValueError:
        pass
    raise DumpFormatError("expected an integer", path=path, line=line,
                          text=raw.decode("latin-1").strip())


def _line_text(buf: bytes, j: int) -> str:
    """The whole line of ``buf`` around offset ``j``."""
    a = buf.rfind(b"\n", 0, j) + 1
    b = buf.find(b"\n", j)
    return buf[a:len(buf) if b < 0 else b].decode("latin-1").strip()


def _before_first_frame(source, buf, j, line):
    return DumpFormatError("expected a LAMMPS dump: its first frame must start with "
                           "'ITEM: TIMESTEP' (or 'ITEM: UNITS' / 'ITEM: TIME' before it) at the "
                           "start of a line, with nothing but blank lines before it",
                           path=source.path, line=line, text=_line_text(buf, j))


def scan_text(source: Source, *, lenient: bool = False) -> TextScan:
    """Find every frame of a text dump (``ITEM: TIMESTEP``, with any preceding
    ``ITEM: UNITS``/``ITEM: TIME`` items) in one pass.

    Also records, per frame, the unit style stated before it and the line of
    its ``ITEM: ATOMS``/``ENTRIES`` item, so that row counts can be checked
    without parsing.

    With ``lenient``, a timestep or atom count value that is not an integer
    is left as None (the frame parser then names it) instead of raising.

    Raises
    ------
    DumpFormatError
        If anything but blank lines comes before the first frame, or a unit
        style or a timestep / atom count value is not valid.
    """
    from ._text import check_unit_style, starts_frame

    scan = TextScan(path=source.path)
    tail_parts: list = []  # text of the last frame (checked for truncation without reading
    tail_from = None       # it again) from absolute offset tail_from
    carry = b""
    base = 0          # absolute offset of buf[0]
    nl_base = 0       # newlines before base
    pending = None    # (start, line) of an UNITS/TIME item waiting for its TIMESTEP
    pending_units = (None, None)  # (style, line) stated by a pending UNITS item
    want = None       # value line still to read: ("ts"|"n"|"units", frame index)
    last_byte = b"\n"
    chunks = source.chunks()
    eof = False
    while not eof:
        try:
            chunk = next(chunks)
        except StopIteration:
            chunk = b""
            eof = True
        if not scan.first_bytes and chunk:
            scan.first_bytes = chunk[:64]
        buf = carry + chunk if carry else chunk
        if chunk:
            last_byte = chunk[-1:]
        p = 0
        counted_to = 0
        nl_count = nl_base
        n = len(buf)
        while True:
            if want is not None:
                e = buf.find(b"\n", p)
                cut = e < 0   # the last line of a file without a final newline
                if cut:
                    if not eof:
                        break
                    e = n
                nl_count += buf.count(b"\n", counted_to, p)
                counted_to = p
                kind, k = want
                raw = buf[p:e]
                if raw.strip():
                    try:
                        if kind == "units":
                            text = raw.decode("latin-1").strip()
                            pending_units = (check_unit_style(text, path=source.path,
                                                              line=nl_count + 1, text=text),
                                             nl_count + 1)
                        else:
                            value = _int_value(raw, source.path, nl_count + 1)
                            (scan.timesteps if kind == "ts" else scan.counts)[k] = value
                    except DumpFormatError:
                        # a cut-off value is a truncated frame, reported later; with lenient a
                        # bad value is left to the frame parser, which names it
                        if not (cut or (lenient and kind != "units")):
                            raise
                elif not (eof and e >= n):  # an empty value line before the end of the file
                    what = {"ts": "the timestep", "n": "the number of atoms",
                            "units": "the unit style"}[kind]
                    raise DumpFormatError(f"expected {what} on this line", path=source.path,
                                          line=nl_count + 1, text="")
                want = None
                p = min(e + 1, n)
                continue
            begun = bool(scan.starts) or pending is not None
            i = buf.find(b"ITEM:", p)
            if not begun:  # before the first frame: only blank lines
                stop = i if i >= 0 else n
                if i < 0 and not eof:
                    stop = buf.rfind(b"\n", p, n) + 1 or p
                j = p + len(buf[p:stop]) - len(buf[p:stop].lstrip())
                if j < stop:
                    line = nl_count + buf.count(b"\n", counted_to, j) + 1
                    if eof and buf.find(b"\n", j) < 0 and starts_frame(buf[j:]):
                        scan.cut_line = line  # e.g. 'ITE': the file ends in its first line
                        p = n
                        break
                    raise _before_first_frame(source, buf, j, line)
            if i < 0:
                if eof:
                    p = n
                else:  # commit whole lines; a partial "ITEM:" line starts after the last newline
                    nlpos = buf.rfind(b"\n", p, n)
                    if nlpos >= 0:
                        p = nlpos + 1
                break
            if i > 0 and buf[i - 1] != 10:
                p = i + 5
                continue
            e = buf.find(b"\n", i)
            if e < 0 and not eof:
                p = i
                break
            cut = e < 0
            if cut:
                e = n
            nl_count += buf.count(b"\n", counted_to, i)
            counted_to = i
            name = buf[i + 5:e].strip()
            absolute = base + i
            if name == b"TIMESTEP":
                start, line = pending if pending is not None else (absolute, nl_count)
                pending = None
                scan.starts.append(start)
                scan.lines.append(line)
                scan.timesteps.append(None)
                scan.counts.append(None)
                scan.units.append(pending_units[0])
                scan.units_lines.append(pending_units[1])
                scan.body_lines.append(None)
                pending_units = (None, None)
                want = ("ts", len(scan.starts) - 1)
            elif name in (b"UNITS", b"TIME"):
                if pending is None:
                    pending = (absolute, nl_count)
                if name == b"UNITS":
                    want = ("units", None)
            elif not begun:
                if cut and starts_frame(buf[i:e]):
                    scan.cut_line = nl_count + 1  # e.g. 'ITEM: T' is all the file holds
                else:
                    raise _before_first_frame(source, buf, i, nl_count + 1)
            elif name.startswith(b"NUMBER OF"):
                # a second count in one frame (a frame without its TIMESTEP) is left to the
                # row count check and the frame parser, which name the line
                if scan.starts and scan.counts[-1] is None:
                    want = ("n", len(scan.starts) - 1)
            elif name.startswith(b"ATOMS") or name.startswith(b"ENTRIES"):
                if scan.starts and scan.body_lines[-1] is None:
                    scan.body_lines[-1] = nl_count
            p = min(e + 1, n)
        nl_count += buf.count(b"\n", counted_to, p)
        # keep the text from the last frame's start (or the first frame's pending items)
        keep_from = scan.starts[-1] if scan.starts else (pending[0] if pending else None)
        if keep_from is None:
            tail_parts, tail_from = [], None
        elif keep_from >= base:
            tail_parts, tail_from = [buf[keep_from - base:p]], keep_from
        else:
            if keep_from != tail_from:  # a frame whose pending items came in an earlier chunk
                tail_parts = [b"".join(tail_parts)[keep_from - tail_from:]]
                tail_from = keep_from
            tail_parts.append(buf[:p])
        carry = buf[p:]
        base += p
        nl_base = nl_count
        if eof:
            break
    if scan.starts:
        scan.tail = b"".join(tail_parts + [carry])
    scan.size = base + len(carry)
    scan.ends_with_newline = last_byte == b"\n"
    scan.n_lines = nl_base + (0 if scan.ends_with_newline or not scan.size else 1)
    if not scan.starts and pending is not None and scan.cut_line is None:
        scan.cut_line = scan.n_lines + (1 if scan.ends_with_newline else 0)
    return scan


def stream_cut(source: Source, strict: bool, stacklevel: int = 2) -> None:
    """After a full pass over ``source``: a compressed stream that ends early is an error
    (strict) or a warning; the frames before the cut are then read as usual, the one it
    cuts through being a truncated last frame."""
    cut = source.stream_truncated_at
    if cut is None:
        return
    msg = (f"cannot decompress ({source.compression}): the compressed data end inside a member "
           f"at the end of the file ({cut} bytes): the file was cut, e.g. while being written")
    if strict:
        raise DumpFormatError(msg + "; read with strict=False for the frames before the cut",
                              path=source.path)
    import warnings

    from ..errors import BedstructWarning
    warnings.warn(f"{source.path}: {msg}; reading the frames before the cut", BedstructWarning,
                  stacklevel=stacklevel + 1)
