"""Writing frames as LIGGGHTS/LAMMPS text ``dump custom`` files (:func:`write_dump`),
and the text helpers that ``dump local`` writing shares.

Implementation module of :mod:`bedstruct.io.lammps_dump` (import from there).
"""

from __future__ import annotations

import contextlib
import os

import numpy as np

from .._atomic import atomic_path
from ..core import Box, Frame

__all__ = ["write_dump"]


def _compressed_writer(path, target, mode):
    """A binary writer of ``path``, compressed as the name ``target`` says."""
    low = target.lower()
    if low.endswith((".gz", ".gzip")):
        import gzip
        return gzip.open(path, mode, compresslevel=6)
    if low.endswith(".bz2"):
        import bz2
        return bz2.open(path, mode)
    if low.endswith((".zst", ".zstd")):
        try:
            import zstandard
        except ImportError:
            raise ImportError(f"{target}: writing .zst files needs the 'zstandard' package "
                              "(pip install zstandard)") from None
        return zstandard.open(path, mode)
    return open(path, mode)


@contextlib.contextmanager
def _open_write(path, append=False):
    """A binary writer of ``path`` (compressed by its extension) that never leaves a
    half-written file when the writing stops on an exception.

    A new file is written beside ``path`` and moved into place when the ``with`` block
    ends without an error, so an existing file is kept until then. When appending, an
    error cuts the file back to the size it had before.
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        raise IsADirectoryError(f"{path}: a directory; give the path of the file to write")
    if not append and os.path.exists(path) and not os.path.isfile(path):
        with _compressed_writer(path, path, "wb") as fh:  # a pipe or device: write through
            yield fh
        return
    if not append:
        with atomic_path(path, suffix=".tmp") as tmp:
            with _compressed_writer(tmp, path, "wb") as fh:
                yield fh
        return
    size = os.path.getsize(path) if os.path.exists(path) else None
    try:
        with _compressed_writer(path, path, "ab") as fh:
            yield fh
    except BaseException:
        if size is None:
            with contextlib.suppress(OSError):
                os.unlink(path)
        else:
            with open(path, "r+b") as raw:
                raw.truncate(size)
        raise


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
        if arr.dtype.kind not in "biuf":
            raise ValueError(f"column {name!r} holds {arr.dtype} values; a dump holds numbers "
                             f"only (leave it out with `columns=`)")
        if arr.ndim == 1:
            parts = {name: arr}
        else:
            flat = arr.reshape(arr.shape[0], -1)
            parts = {f"{name}[{k + 1}]": flat[:, k] for k in range(flat.shape[1])}
        for key, values in parts.items():
            if key in table:
                raise ValueError(f"column {name!r} would be written as {key!r}, which this "
                                 f"frame already writes (from its ids, types, positions, "
                                 f"vectors or radii); rename the column")
            table[key] = values
    if columns is not None:
        columns = list(columns.split() if isinstance(columns, str) else columns)
        missing = [c for c in columns if c not in table]
        if missing:
            raise ValueError(f"`columns` names {missing} that this frame does not have; "
                             f"available: {list(table)}")
        table = {c: table[c] for c in columns}
    for name in table:
        if not name or not name.isascii() or not name.isprintable() or any(
                ch.isspace() for ch in name):
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
            cols.append(a.astype(np.uint64 if a.dtype.kind == "u" else np.int64).tolist())
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

        A new file is written beside ``path`` and moved into place when
        complete, so an error (or interruption) while writing leaves the
        previous file untouched; when appending, an error cuts the file back
        to its previous size.
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
    if isinstance(frames, (str, bytes)) or not hasattr(frames, "__iter__"):
        raise TypeError(f"expected a Frame or an iterable of Frame objects; got "
                        f"{type(frames_or_frame).__name__}")
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
