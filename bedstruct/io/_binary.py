"""LAMMPS binary dumps (``dump custom ... file.bin``), old and new header layouts.

Layout per snapshot (native byte order, LAMMPS built with the default
``LAMMPS_SMALLBIG``: 8-byte step and atom counts, 4-byte ints):

* newer files (LAMMPS >= 2021) start a snapshot with the negative length of a
  magic string (``DUMPCUSTOM``), the string, an endian flag and a revision
  number, then the real timestep; older files start with the timestep;
* atom count, triclinic flag, six boundary codes (p=0, f=1, s=2, m=3), the
  bounds ``xlo xhi ylo yhi zlo zhi`` (the bounding box for triclinic boxes)
  and ``xy xz yz`` when triclinic, values per atom;
* revision 2 and later: the unit style (length-prefixed, may be empty), a
  one-byte flag followed by the time when set, and the column names
  (length-prefixed, space-separated);
* the number of chunks, then per chunk its number of doubles and the doubles.

Once a file has declared revision 2, every later snapshot carries the units
and columns block too, as LAMMPS's ``tools/binary2txt`` reads it; LAMMPS
writes the unit style in the first snapshot only (an empty string after it).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from ..core import Box
from ..errors import DumpFormatError
from ._source import Source, _open_stream
from ._text import RawFrame, TruncatedFrame, check_unit_style

__all__ = ["is_binary", "scan_binary", "parse_binary_frame", "write_binary_dump", "BinaryScan"]

_BOUND_CODES = "pfsm"


def is_binary(first_bytes: bytes) -> bool:
    """True when the start of a (decompressed) file is not a text dump."""
    head = first_bytes.lstrip()
    if head.startswith(b"ITEM:") or len(first_bytes) < 8:
        return False
    # text files (data files, text dumps) are printable ASCII and whitespace
    return any(b < 9 or 13 < b < 32 or b > 126 for b in first_bytes[:64])


@dataclass
class BinaryScan:
    path: str
    starts: list = field(default_factory=list)
    ends: list = field(default_factory=list)
    timesteps: list = field(default_factory=list)
    counts: list = field(default_factory=list)
    states: list = field(default_factory=list)   # (revision, has_magic) in force at each frame
    units: list = field(default_factory=list)    # unit style written in the snapshot, or None
    rows: list = field(default_factory=list)     # rows the chunks hold (None: not whole rows)
    truncated_at: int | None = None              # byte offset of a cut-off last snapshot
    size: int = 0


class _Stream:
    def __init__(self, fh):
        self.fh = fh
        self.pos = 0

    def read(self, k):
        data = self.fh.read(k)
        self.pos += len(data)
        return data

    def skip(self, k):
        while k > 0:
            got = self.fh.read(min(k, 1 << 24))
            if not got:
                return False
            k -= len(got)
            self.pos += len(got)
        return True


def _header(read, path, state):
    """Read one snapshot header with ``read(k) -> bytes``; returns a dict or None at EOF.

    ``state`` is a mutable dict holding the revision seen so far.
    """
    raw = read(8)
    if not raw:
        return None
    if len(raw) < 8:
        raise EOFError
    (step,) = struct.unpack("=q", raw)
    if step < 0:
        mlen = -step
        if mlen > 1024:
            raise DumpFormatError("not a LAMMPS binary dump (bad magic length)", path=path, line=1)
        magic = read(mlen)
        if len(magic) < mlen:
            raise EOFError
        endian, revision = struct.unpack("=ii", _exact(read, 8))
        if endian != 1:
            raise DumpFormatError("binary dump written on a machine of the other byte order "
                                  "(endian flag mismatch); convert it with LAMMPS binary2txt",
                                  path=path)
        state["magic"] = magic.decode("latin-1")
        state["revision"] = revision
        (step,) = struct.unpack("=q", _exact(read, 8))
    (natoms,) = struct.unpack("=q", _exact(read, 8))
    (tri,) = struct.unpack("=i", _exact(read, 4))
    codes = struct.unpack("=6i", _exact(read, 24))
    bounds = struct.unpack("=6d", _exact(read, 48))
    tilt = struct.unpack("=3d", _exact(read, 24)) if tri else None
    (size_one,) = struct.unpack("=i", _exact(read, 4))
    units = time = None
    names = None
    if state.get("magic") is not None and state.get("revision", 1) > 1:
        (ulen,) = struct.unpack("=i", _exact(read, 4))
        if ulen > 0:
            units = _exact(read, ulen).decode("latin-1")
        (flag,) = struct.unpack("=b", _exact(read, 1))
        if flag:
            (time,) = struct.unpack("=d", _exact(read, 8))
        (clen,) = struct.unpack("=i", _exact(read, 4))
        names = _exact(read, clen).decode("latin-1").split() if clen > 0 else []
    (nchunk,) = struct.unpack("=i", _exact(read, 4))
    if natoms < 0 or size_one < 0 or nchunk < 0 or any(c not in (0, 1, 2, 3) for c in codes):
        raise DumpFormatError("not a LAMMPS binary dump (implausible header values)", path=path)
    boundary = tuple(_BOUND_CODES[codes[2 * k]] + _BOUND_CODES[codes[2 * k + 1]] for k in range(3))
    return dict(timestep=step, n=natoms, tilt=tilt, boundary=boundary,
                bounds=np.array(bounds).reshape(3, 2), size_one=size_one, units=units, time=time,
                names=names, nchunk=nchunk)


def _exact(read, k):
    data = read(k)
    if len(data) < k:
        raise EOFError
    return data


def scan_binary(source: Source) -> BinaryScan:
    """Find the byte range of every snapshot of a binary dump."""
    scan = BinaryScan(path=source.path)
    stream = _Stream(_open_stream(source.path, source.compression))
    state: dict = {}
    try:
        while True:
            start = stream.pos
            st_before = dict(state)
            try:
                h = _header(stream.read, source.path, state)
                if h is None:
                    break
                values = 0
                for _ in range(h["nchunk"]):
                    (k,) = struct.unpack("=i", _exact(stream.read, 4))
                    if k < 0 or not stream.skip(8 * k):
                        raise EOFError
                    values += k
            except EOFError:
                scan.truncated_at = start
                break
            scan.starts.append(start)
            scan.ends.append(stream.pos)
            scan.timesteps.append(int(h["timestep"]))
            scan.counts.append(int(h["n"]))
            scan.states.append(st_before)
            scan.units.append(check_unit_style(h["units"] or None, path=source.path))
            size = h["size_one"]
            scan.rows.append(values // size if size and values % size == 0 else None)
    finally:
        stream.fh.close()
    scan.size = stream.pos
    return scan


def parse_binary_frame(buf: bytes, *, path: str, state: dict, columns=None,
                       header_only: bool = False) -> RawFrame:
    """Parse one snapshot from its bytes (``state``: revision in force before it)."""
    pos = [0]

    def read(k):
        data = buf[pos[0]:pos[0] + k]
        pos[0] += len(data)
        return data

    state = dict(state)
    try:
        h = _header(read, path, state)
    except EOFError:
        raise TruncatedFrame("truncated binary snapshot header", path=path) from None
    names = h["names"]
    if columns is not None:
        names = list(columns.split() if isinstance(columns, str) else columns)
    units = check_unit_style(h["units"] or None, path=path)
    if not names:
        raise DumpFormatError("this binary dump (old header layout) has no column names; pass "
                              "columns='id type x y z ...' as in the dump command", path=path)
    if len(names) != h["size_one"]:
        raise DumpFormatError(f"binary dump has {h['size_one']} values per atom but "
                              f"{len(names)} column names were given/found: {names}", path=path)
    try:
        Box.from_lammps_bounds(h["bounds"], h["tilt"], h["boundary"])
    except ValueError as exc:
        raise DumpFormatError(f"binary snapshot of timestep {h['timestep']}: invalid box: {exc}",
                              path=path) from None
    raw = RawFrame(path=path, timestep=int(h["timestep"]), n=int(h["n"]), bounds=h["bounds"],
                   tilt=None if h["tilt"] is None else np.array(h["tilt"]), boundary=h["boundary"],
                   kind="ATOMS", names=names, data=None, units=units, time=h["time"])
    if header_only:
        return raw
    parts = []
    for c in range(h["nchunk"]):
        (k,) = struct.unpack("=i", _exact(read, 4))
        chunk = read(8 * k)
        if len(chunk) < 8 * k:
            raise TruncatedFrame(f"truncated binary snapshot (chunk {c + 1} of {h['nchunk']})",
                                 path=path)
        parts.append(np.frombuffer(chunk, dtype=np.float64))
    flat = np.concatenate(parts) if parts else np.zeros(0)
    if flat.size != raw.n * h["size_one"]:
        raise DumpFormatError(f"atom count mismatch: header says {raw.n} atoms x "
                              f"{h['size_one']} values but the chunks hold {flat.size} values",
                              path=path)
    raw.data = flat.reshape(raw.n, h["size_one"]).copy()
    return raw


def write_binary_dump(path, snapshots, *, revision: int = 2, nchunks: int = 2) -> None:
    """Write a LAMMPS binary dump (private helper, for tests).

    ``snapshots`` is a sequence of dicts with ``timestep``, ``bounds`` (3, 2),
    ``tilt`` (3,) or None, ``boundary`` (3 two-letter flags), ``names`` and
    ``data`` (n, k); optional ``units`` and ``time`` (revision 2 only).
    ``revision=1`` writes the old layout (no magic string, no column names).
    """
    with open(path, "wb") as fh:
        for snap in snapshots:
            data = np.ascontiguousarray(snap["data"], dtype=np.float64)
            n, k = data.shape
            if revision >= 2:
                magic = b"DUMPCUSTOM"
                fh.write(struct.pack("=q", -len(magic)))
                fh.write(magic)
                fh.write(struct.pack("=ii", 1, revision))
            fh.write(struct.pack("=q", int(snap["timestep"])))
            fh.write(struct.pack("=q", n))
            tilt = snap.get("tilt")
            fh.write(struct.pack("=i", 0 if tilt is None else 1))
            codes = [_BOUND_CODES.index(c) for flag in snap["boundary"] for c in flag]
            fh.write(struct.pack("=6i", *codes))
            fh.write(struct.pack("=6d", *np.asarray(snap["bounds"], dtype=float).reshape(6)))
            if tilt is not None:
                fh.write(struct.pack("=3d", *tilt))
            fh.write(struct.pack("=i", k))
            if revision >= 2:
                units = (snap.get("units") or "").encode()
                fh.write(struct.pack("=i", len(units)))
                fh.write(units)
                time = snap.get("time")
                fh.write(struct.pack("=b", 0 if time is None else 1))
                if time is not None:
                    fh.write(struct.pack("=d", float(time)))
                cols = " ".join(snap["names"]).encode()
                fh.write(struct.pack("=i", len(cols)))
                fh.write(cols)
            pieces = [p.reshape(-1) for p in np.array_split(data, nchunks) if p.size] if n else []
            fh.write(struct.pack("=i", len(pieces)))
            for piece in pieces:
                fh.write(struct.pack("=i", piece.size))
                fh.write(piece.tobytes())
