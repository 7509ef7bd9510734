"""Reading and writing LAMMPS/LIGGGHTS ``dump custom`` files (text and binary).

:func:`read_dump` scans the file(s) once for the byte offset of every frame and
returns a lazy :class:`DumpTrajectory` that parses frames on demand, one at a
time; :func:`iter_frames` is its generator form. :func:`write_dump` writes
frames in the LIGGGHTS ``dump custom`` layout with round-trip exact numbers.
"""

# The implementation is split by stage: column mapping onto a Frame (_columns), the
# streaming text parser (_stream), the lazy DumpTrajectory (_trajectory) and writing
# (_writer); header and block parsing are in _text, binary dumps in _binary.

from __future__ import annotations

import glob
import logging
import os

import numpy as np

from ._columns import frame_from_raw
from ._trajectory import DumpTrajectory, SkippedFrame
from ._writer import write_dump

__all__ = ["read_dump", "iter_frames", "write_dump", "DumpTrajectory", "SkippedFrame",
           "expand_paths", "frame_from_raw"]

log = logging.getLogger(__name__)

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


def read_dump(path_or_glob, *, radius=None, units=None, strict=True, sort_by_id=True,
              wrap=False, columns=None, on_error="raise") -> DumpTrajectory:
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
        The LAMMPS unit style of the numbers (``"si"``, ``"cgs"``, ``"micro"``,
        ``"nano"``, ``"lj"``, ``"real"``, ``"metal"``, ``"electron"``; any
        case) when the file has no ``ITEM: UNITS``; no number is converted. A
        style a file states holds for all its later frames (LAMMPS writes it
        before the first snapshot only). When neither states it the frames
        have ``units.style = None`` (unknown).
    strict : bool, optional
        With False, a truncated *last* frame of a file (one still being
        written) is skipped with a :class:`~bedstruct.errors.BedstructWarning`;
        by default it is a :class:`~bedstruct.errors.DumpFormatError`. A last
        line without its newline counts as cut off (LAMMPS ends every line
        with one), so a number cut short is never read.
    sort_by_id : bool, optional
        Order each frame's rows by particle id (default True).
    wrap : bool, optional
        Wrap unwrapped coordinates (``xu yu zu``) into the box, with
        ``images`` set to the box shifts removed, so that
        ``frame.unwrapped_positions()`` gives them back; recorded in the
        frame's provenance. Default False: positions are as written.
    columns : str or sequence of str, optional
        Column names to use instead of the header's, as one string
        (``"id type x y z radius"``) or a sequence: needed for old-style text
        dumps (``ITEM: ATOMS`` without names) and binary dumps of the old
        layout, which carry no names.
    on_error : {"raise", "skip"}, optional
        What a malformed frame does. ``"raise"`` (default): reading it raises
        a :class:`~bedstruct.errors.DumpFormatError` naming the file and
        line. ``"skip"``: every frame is parsed once when the files are
        opened, and each one that does not read (a truncated frame, a
        non-numeric value, an atom count that does not match its rows, a
        timestep or count that is not an integer, ...) is left out with a
        :class:`~bedstruct.errors.BedstructWarning` naming the file, the
        timestep and the line; the trajectory's ``skipped`` attribute lists
        them as :class:`SkippedFrame` records. Implies ``strict=False``.
        Defects that leave no frame to find (text before the first frame, an
        unknown unit style) still raise.

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
    ValueError
        For an unknown ``units`` style or empty ``columns``.

    Notes
    -----
    Columns map onto the frame as follows: ``id``, ``type``; positions from
    ``x y z``, else scaled ``xs ys zs`` (converted with the box, triclinic
    included), else unwrapped ``xu yu zu``, else ``xsu ysu zsu``; ``ix iy iz``
    to ``images`` (0 with unwrapped positions, which already include them);
    ``vx vy vz`` to ``velocities``; ``omegax omegay omegaz``
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

    A damaged frame is left out with ``on_error="skip"``:

    >>> import warnings
    >>> text = open(path).read()
    >>> with open(path, "w") as fh:
    ...     _ = fh.write(text.replace("ITEM: TIMESTEP\\n0", "ITEM: TIMESTEP\\n5")
    ...                  + text.replace("1.5", "1.x"))
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     traj = read_dump(path, on_error="skip")
    >>> traj.timesteps.tolist(), [(s.timestep, s.line) for s in traj.skipped]
    ([5], [(0, 22)])

    .. versionadded:: 0.1
    """
    _check_radius(radius)
    return DumpTrajectory(expand_paths(path_or_glob), radius=radius, units=units, strict=strict,
                          sort_by_id=sort_by_id, wrap=wrap, columns=columns, on_error=on_error)


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
                wrap=False, columns=None, on_error="raise"):
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
                     sort_by_id=sort_by_id, wrap=wrap, columns=columns, on_error=on_error)
    try:
        for k in range(len(traj)):
            yield traj._read_frame(k)
    finally:
        traj.close()
