"""One entry point for particle files: the reader is chosen from the content.

:func:`detect_format` looks at a file's first bytes (after decompression) and
says what it holds; :func:`read` hands the file to the matching reader and
returns its frames as a :class:`~bedstruct.core.Trajectory`. The suffix decides
only where the content does not (an empty or unreadable head).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from ..core import FrameList, Trajectory
from ..errors import DumpFormatError
from ._source import _decompress_errors, _open_stream, compression_of
from ._trajectory import check_on_error
from .data_file import read_data
from .hdf5 import HDF5_MAGIC, load_hdf5
from .lammps_dump import expand_paths, read_dump

__all__ = ["FORMATS", "detect_format", "read"]

#: What :func:`detect_format` can answer, with the reader each one goes to.
FORMATS = {
    "dump": "bedstruct.io.read_dump (text dump custom/atom, plain or compressed)",
    "dump-binary": "bedstruct.io.read_dump (LAMMPS binary dump)",
    "dump-local": "bedstruct.io.read_dump_local (contacts, not particles)",
    "data": "bedstruct.io.read_data (LAMMPS/LIGGGHTS data file)",
    "hdf5": "bedstruct.io.load_hdf5 (bedstruct HDF5 archive)",
}

_HEAD = 1 << 14
_DATA_HEADER = re.compile(rb"^\s*[-+0-9.eE]+\s+[-+0-9.eE]+\s+[xyz]lo\s+[xyz]hi\b|^\s*\d+\s+atoms\s*$",
                          re.MULTILINE)


def _head(path) -> bytes:
    with open(path, "rb") as fh:
        raw = fh.read(len(HDF5_MAGIC))
    if raw == HDF5_MAGIC:
        return raw
    stream = _open_stream(path, compression_of(path))
    try:
        return stream.read(_HEAD)
    except _decompress_errors() as exc:
        raise DumpFormatError(f"{path}: cannot read the start of the file ({exc})") from exc
    finally:
        stream.close()


def _by_suffix(path) -> str | None:
    name = Path(str(path)).name.lower()
    for ext in (".gz", ".gzip", ".bz2", ".zst", ".zstd"):
        if name.endswith(ext):
            name = name[: -len(ext)]
    if name.endswith((".h5", ".hdf5")):
        return "hdf5"
    if name.endswith((".data", ".lmp")) or name.startswith("data."):
        return "data"
    if name.endswith((".bin", ".binary")):
        return "dump-binary"
    return None


def detect_format(path) -> str:
    """Say what a particle or contact file holds, from its content.

    Parameters
    ----------
    path : str or path-like
        The file (plain, ``.gz``, ``.bz2`` or ``.zst``).

    Returns
    -------
    str
        One of the keys of :data:`FORMATS`: ``"dump"``, ``"dump-binary"``,
        ``"dump-local"``, ``"data"`` or ``"hdf5"``.

    Raises
    ------
    FileNotFoundError
        When the file does not exist.
    IsADirectoryError
        When the path is a directory.
    DumpFormatError
        When the path is not a regular file (``/dev/null``, a pipe), or when
        neither the content nor the suffix says what the file is (for
        example an empty file), naming the file and what was found.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from bedstruct.io import detect_format
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "bed.dump"
    >>> _ = p.write_text("ITEM: TIMESTEP\\n0\\nITEM: NUMBER OF ATOMS\\n0\\n")
    >>> detect_format(p)
    'dump'
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    if os.path.isdir(path):
        raise IsADirectoryError(f"{path}: a directory, not a particle file")
    if not os.path.isfile(path):
        raise DumpFormatError(f"{path}: not a regular file (a device, pipe or socket); "
                              f"bedstruct reads dump, data and HDF5 files")
    head = _head(path)
    if head.startswith(HDF5_MAGIC):
        return "hdf5"
    text = head.lstrip()
    if text.startswith(b"ITEM:"):
        if b"ITEM: NUMBER OF ENTRIES" in head or b"ITEM: ENTRIES" in head:
            return "dump-local"
        return "dump"
    if b"\0" in head[:512]:
        return "dump-binary"
    if _DATA_HEADER.search(head):
        return "data"
    guess = _by_suffix(path)
    if guess is not None and head.strip():
        return guess
    what = "an empty file" if not head.strip() else f"a file starting {head[:40]!r}"
    raise DumpFormatError(f"{path}: not a dump, data, contact or HDF5 file that bedstruct "
                          f"reads ({what})")


def read(path_or_glob, *, radius=None, units=None, on_error="raise", boundary=None,
         **kwargs) -> Trajectory:
    """Read the frames of a particle file, whatever its format.

    Dumps (text or binary, plain or compressed, a glob or a list of files),
    data files and bedstruct HDF5 archives are recognised from their content
    (:func:`detect_format`) and read by :func:`read_dump`, :func:`read_data` or
    :func:`load_hdf5`. A contact (``dump local``) file is refused: its rows are
    contacts, read with :func:`read_dump_local` against the frames they belong to.

    Parameters
    ----------
    path_or_glob : str, path-like or sequence of them
        One file, a glob pattern or a list of files of one format.
    radius, units : optional
        As for :func:`read_dump` (a dump without radii; the unit style when the
        file states none). ``units`` also applies to data files.
    on_error : {"raise", "skip"}, optional
        For dumps, as for :func:`read_dump`: ``"skip"`` leaves malformed
        frames out with a warning and lists them in the trajectory's
        ``skipped``. A malformed data or HDF5 file (one frame, or an archive
        written whole) raises either way.
    boundary : str or sequence of 3 str, optional
        Boundary flags of data files, which do not record them (``"pp pp
        ff"``; default ``"pp pp pp"``, see :func:`read_data`). Dumps and
        HDF5 archives state their own, so giving it for them is an error.
    **kwargs
        Further options of the chosen reader (e.g. ``strict``, ``columns`` for
        dumps, ``atom_style`` for data files).

    Returns
    -------
    Trajectory
        The frames: lazily read for dumps, in memory for data and HDF5 files.

    Raises
    ------
    DumpFormatError
        For a contact file, a list of files of different formats, or a file
        that is none of the formats above.

    Examples
    --------
    >>> import bedstruct.io
    >>> traj = bedstruct.io.read("data/samples/spread/bed.dump.gz")
    >>> traj[-1].n_particles > 0
    True
    """
    check_on_error(on_error)
    paths = expand_paths(path_or_glob)
    kinds = {p: detect_format(p) for p in paths}
    found = set(kinds.values())
    if "dump-local" in found:
        bad = next(p for p, k in kinds.items() if k == "dump-local")
        raise DumpFormatError(f"{bad}: a `dump local` contact file, not particles; read it with "
                              "bedstruct.io.read_dump_local (in the CLI: --contacts)")
    if found <= {"dump", "dump-binary"}:
        if boundary is not None:
            raise ValueError(f"boundary= (--boundary on the command line) is for data files, "
                             f"which do not record it; the dump {paths[0]} states its own "
                             f"(ITEM: BOX BOUNDS)")
        return read_dump(paths if len(paths) > 1 else paths[0], radius=radius, units=units,
                         on_error=on_error, **kwargs)
    if len(found) > 1:
        raise DumpFormatError("files of different formats in one read: " + ", ".join(
            f"{p} ({k})" for p, k in kinds.items()))
    (kind,) = found
    if boundary is not None and kind != "data":
        raise ValueError(f"boundary= (--boundary on the command line) is for data files, "
                         f"which do not record it; {paths[0]} ({kind}) states its own")
    if kind == "data":
        return FrameList([read_data(p, radius=radius, units=units, boundary=boundary, **kwargs)
                          for p in paths])
    frames = []
    for p in paths:
        frames.extend(load_hdf5(p).frames)
    return FrameList(frames)
