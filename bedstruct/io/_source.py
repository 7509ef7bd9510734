"""Opening (possibly compressed) files and scanning them for frame offsets.

A :class:`Source` reads byte ranges of the *decompressed* stream of one file;
compressed streams are read forwards and reopened when a caller seeks
backwards. :func:`scan_text` finds the byte offset, line number, timestep and
particle count of every frame of a text dump in one pass over the file.
"""

from __future__ import annotations

import bz2
import gzip
import os
import zlib
from dataclasses import dataclass, field

from ..errors import DumpFormatError

__all__ = ["Source", "compression_of", "scan_text", "TextScan"]

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


def _open_stream(path, compression):
    if compression is None:
        return open(path, "rb")
    if compression == "gz":
        try:  # ISA-L inflates about three times faster when the optional 'isal' is installed
            from isal import igzip
        except ImportError:
            return gzip.GzipFile(path, "rb")
        return igzip.IGzipFile(path, "rb")
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

    def _read_range(self, start: int, length: int) -> bytes:
        if self._fh is None:
            self._reopen()
        if self.compression is None:
            self._fh.seek(start)
            data = self._fh.read(length)
            self._pos = start + len(data)
            return data
        if start < self._pos:
            self._reopen()
        skip = start - self._pos
        while skip > 0:
            got = self._fh.read(min(skip, _CHUNK))
            if not got:
                break
            skip -= len(got)
            self._pos += len(got)
        data = self._read_exact(length)
        self._pos += len(data)
        return data

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
            self._fh.close()
            self._fh = None
            self._pos = 0

    def __getstate__(self):  # picklable: reopen lazily in the other process
        state = dict(self.__dict__)
        state["_fh"] = None
        state["_pos"] = 0
        return state


@dataclass
class TextScan:
    """Where the frames of one text dump start (decompressed byte offsets)."""

    path: str
    starts: list = field(default_factory=list)      # byte offset of the frame's first ITEM line
    lines: list = field(default_factory=list)       # 0-based line index of that line
    timesteps: list = field(default_factory=list)   # int or None
    counts: list = field(default_factory=list)      # NUMBER OF ATOMS / ENTRIES, or None
    size: int = 0
    ends_with_newline: bool = True
    first_bytes: bytes = b""
    tail: bytes | None = None   # text of the last frame

    def end(self, k: int) -> int:
        return self.starts[k + 1] if k + 1 < len(self.starts) else self.size


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


def scan_text(source: Source) -> TextScan:
    """Find every frame of a text dump (``ITEM: TIMESTEP``, with any preceding
    ``ITEM: UNITS``/``ITEM: TIME`` items) in one pass.

    Raises
    ------
    DumpFormatError
        If the file does not start with an ``ITEM:`` line.
    """
    scan = TextScan(path=source.path)
    keep_tail = True  # the last frame is checked for truncation without reading it again
    tail_parts: list = []
    carry = b""
    base = 0          # absolute offset of buf[0]
    nl_base = 0       # newlines before base
    pending = None    # (start, line) of an UNITS/TIME item waiting for its TIMESTEP
    want = None       # value line still to read: ("ts"|"n", frame index)
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
                if e < 0:
                    if not eof:
                        break
                    e = n
                nl_count += buf.count(b"\n", counted_to, p)
                counted_to = p
                kind, k = want
                raw = buf[p:e]
                if raw.strip():
                    value = _int_value(raw, source.path, nl_count + 1)
                    (scan.timesteps if kind == "ts" else scan.counts)[k] = value
                elif not (eof and e >= n):  # an empty value line before the end of the file
                    what = "the timestep" if kind == "ts" else "the number of atoms"
                    raise DumpFormatError(f"expected {what} on this line", path=source.path,
                                          line=nl_count + 1, text="")
                want = None
                p = min(e + 1, n)
                continue
            i = buf.find(b"ITEM:", p)
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
            if e < 0:
                e = n
            nl_count += buf.count(b"\n", counted_to, i)
            counted_to = i
            name = buf[i + 5:e].strip()
            absolute = base + i
            if name.startswith(b"TIMESTEP"):
                start, line = pending if pending is not None else (absolute, nl_count)
                pending = None
                scan.starts.append(start)
                scan.lines.append(line)
                scan.timesteps.append(None)
                scan.counts.append(None)
                want = ("ts", len(scan.starts) - 1)
            elif name.startswith(b"UNITS") or (name.startswith(b"TIME") and not name.startswith(b"TIMESTEP")):
                if pending is None:
                    pending = (absolute, nl_count)
            elif name.startswith(b"NUMBER OF"):
                if scan.starts:
                    want = ("n", len(scan.starts) - 1)
            p = min(e + 1, n)
        nl_count += buf.count(b"\n", counted_to, p)
        if keep_tail and scan.starts:
            last = scan.starts[-1]
            if last >= base:
                tail_parts = [buf[last - base:p]]
            else:
                tail_parts.append(buf[:p])
        carry = buf[p:]
        base += p
        nl_base = nl_count
        if eof:
            break
    if keep_tail and scan.starts:
        tail_parts.append(carry)
        scan.tail = b"".join(tail_parts)
    scan.size = base + len(carry)
    scan.ends_with_newline = last_byte == b"\n"
    head = scan.first_bytes.lstrip()
    if scan.size and not head.startswith(b"ITEM:"):
        raise DumpFormatError("expected a LAMMPS dump starting with 'ITEM: TIMESTEP'",
                              path=source.path, line=1,
                              text=head[:40].decode("latin-1").split("\n")[0])
    return scan
