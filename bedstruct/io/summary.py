"""Summaries of dump, dump local and data files (``bedstruct info``)."""

from __future__ import annotations

import os
import re

import numpy as np

from ..errors import DumpFormatError
from ._binary import is_binary
from ._source import Source
from ._trajectory import check_on_error
from .data_file import read_data
from .hdf5 import HDF5_MAGIC
from .lammps_dump import expand_paths, read_dump

__all__ = ["summarise", "summarise_all", "format_summary"]

_HEAD = 4096
_DATA_ATOMS = re.compile(rb"(?m)^[ \t]*\d+[ \t]+atoms[ \t]*(#.*)?\r?$")
_ITEM_LINE = re.compile(rb"(?m)^ITEM:")


def _box_dict(box) -> dict:
    return {"lo": box.lo.tolist(), "hi": box.hi.tolist(), "tilt": box.tilt.tolist(),
            "boundary": list(box.boundary), "periodic": list(box.periodic)}


def _kind(path) -> tuple[str, str | None]:
    """``("text" | "binary" | "data" | "empty", compression)`` from the first bytes.

    Raises
    ------
    DumpFormatError
        If the file is neither a dump nor a data file.
    """
    src = Source(path)
    try:
        head = src.read_range(0, _HEAD)
    finally:
        src.close()
    comp = src.compression
    if head.startswith(HDF5_MAGIC):
        raise DumpFormatError("an HDF5 file, not a LAMMPS/LIGGGHTS dump or data file: load it "
                              "with bedstruct.io.load_hdf5 or bedstruct.io.read", path=str(path))
    if not head.strip() and len(head) < _HEAD:
        return "empty", comp
    if head.lstrip().startswith(b"ITEM:"):
        return "text", comp
    if _DATA_ATOMS.search(head):
        return "data", comp
    if is_binary(head):
        return "binary", comp
    if _ITEM_LINE.search(head):
        return "text", comp  # the dump reader names what comes before its first frame
    first = next((ln for ln in head.splitlines() if ln.strip()), b"")
    line = head[:head.find(first)].count(b"\n") + 1
    raise DumpFormatError("not a recognisable LAMMPS/LIGGGHTS file: a dump starts with "
                          "'ITEM: TIMESTEP', a data file has an 'N atoms' line in its header",
                          path=str(path), line=line, text=first.decode("latin-1").strip())


def _groups(path_or_glob) -> list:
    """The files of ``path_or_glob`` as (label, kind, compression, files) groups: dumps of
    one kind together (one trajectory), every data or empty file on its own."""
    files = expand_paths(path_or_glob)
    groups: dict = {}
    for f in files:
        kind, comp = _kind(f)
        key = (kind, comp) if kind in ("text", "binary") else (kind, comp, f)
        groups.setdefault(key, []).append(f)
    single = len(groups) == 1
    label = (str(path_or_glob) if isinstance(path_or_glob, (str, os.PathLike))
             else ", ".join(map(str, path_or_glob)))
    return [(label if single else (fs[0] if len(fs) == 1 else f"{label} ({key[0]} dumps)"),
             key[0], key[1], fs) for key, fs in groups.items()]


def summarise_all(path_or_glob, radius=None, columns=None, on_error="raise") -> list[dict]:
    """Summarise every file of a path or glob: one summary per data file, one per
    set of dumps of the same kind (read as one trajectory).

    Parameters
    ----------
    path_or_glob : str, path-like or sequence of them
        Files or glob patterns.
    radius : float, optional
        Radius assumed when a dump has no radius/diameter column.
    columns : str or sequence of str, optional
        Column names for dumps that do not name theirs (old text dumps,
        old-layout binary dumps).
    on_error : {"raise", "skip"}, optional
        As for :func:`summarise`.

    Returns
    -------
    list of dict
        :func:`summarise` results.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, write_data
    >>> from bedstruct.io import summarise_all
    >>> folder = tempfile.mkdtemp()
    >>> for k in (1, 2):
    ...     write_data(os.path.join(folder, f"d{k}.data"),
    ...                Frame([[0.5, 0.5, 0.5]] * k, [0.1] * k, box=[1, 1, 1]), density=1.0)
    >>> [s["n_particles"] for s in summarise_all(os.path.join(folder, "*.data"))]
    [[1], [2]]
    """
    check_on_error(on_error)
    return [_summarise_group(label, kind, comp, files, radius, columns, on_error)
            for label, kind, comp, files in _groups(path_or_glob)]


def summarise(path, radius=None, columns=None, on_error="raise") -> dict:
    """Summarise a dump, dump local or data file (or a glob of dumps).

    Reads the frame headers, checks every frame's atom count against its
    rows (from the scan of the file, so almost free), and parses the first
    non-empty frame in full to check its values and collect the reader's
    notes; the notes say so.

    Parameters
    ----------
    path : str or path-like
        A file or glob pattern.
    radius : float, optional
        Radius assumed when a dump has no radius/diameter column.
    columns : str or sequence of str, optional
        Column names for dumps that do not name theirs (old text dumps,
        old-layout binary dumps).
    on_error : {"raise", "skip"}, optional
        ``"skip"`` reads dumps with :func:`read_dump`'s ``on_error="skip"``:
        every frame is parsed, the malformed ones are left out and listed in
        ``skipped``. Default ``"raise"``: the first malformed frame is an
        error.

    Returns
    -------
    dict
        JSON-serialisable: ``path``, ``files``, ``format``, ``n_frames``,
        ``timesteps``, ``n_particles`` (per frame; contact rows for dump
        local files), ``box`` (``lo``, ``hi``, ``tilt``, ``boundary``,
        ``periodic`` of the first frame), ``columns``, ``units``, ``notes``
        and ``skipped`` (the frames left out: ``path``, ``timestep``,
        ``line``, ``reason``; empty unless ``on_error="skip"``).

    Raises
    ------
    DumpFormatError
        If the file is malformed or not a dump or data file.
    ValueError
        If ``path`` matches files that cannot be summarised together (several
        data files, or dumps of different kinds): use :func:`summarise_all`.

    Examples
    --------
    >>> import os, tempfile
    >>> from bedstruct import Frame, write_dump
    >>> from bedstruct.io import summarise
    >>> path = os.path.join(tempfile.mkdtemp(), "dump.liggghts")
    >>> write_dump(path, Frame([[0.5, 0.5, 0.5]], [0.5], box=[1, 1, 1], timestep=7))
    >>> s = summarise(path)
    >>> s["format"], s["n_frames"], s["timesteps"], s["n_particles"]
    ('lammps-dump-text', 1, [7], [1])
    """
    groups = _groups(path)
    if len(groups) > 1:
        raise ValueError(f"{path}: {len(groups)} kinds of file (or several data files) cannot "
                         f"be summarised as one; use summarise_all")
    label, kind, comp, files = groups[0]
    return _summarise_group(label, kind, comp, files, radius, columns, check_on_error(on_error))


def _summarise_group(label, kind, comp, files, radius, columns, on_error="raise") -> dict:
    summary = {"path": str(label), "files": [str(f) for f in files], "skipped": []}
    if kind == "empty":
        summary.update(format="empty", n_frames=0, timesteps=[], n_particles=[], box=None,
                       columns=[], units=None, notes=["the file is empty (nothing but blank "
                                                      "lines)"])
        return summary
    if kind == "data":
        frame = read_data(files[0])
        summary.update(format="lammps-data", n_frames=1, timesteps=[None],
                       n_particles=[frame.n_particles], box=_box_dict(frame.box),
                       columns=["id", "type", "radius", "x", "y", "z"]
                       + (["ix", "iy", "iz"] if frame.images is not None else [])
                       + (["vx", "vy", "vz"] if frame.velocities is not None else [])
                       + (["omegax", "omegay", "omegaz"] if frame.omegas is not None else [])
                       + list(frame.columns),
                       units=frame.units.style, notes=list(frame.provenance.notes))
        return summary
    with read_dump(files, radius=radius, columns=columns, on_error=on_error) as traj:
        summary["skipped"] = [s.to_dict() for s in traj.skipped]
        _summarise_dump(traj, kind, comp, summary, radius, on_error == "skip")
    return summary


def _summarise_dump(traj, kind, comp, summary, radius, all_parsed=False) -> None:
    n = len(traj)
    fmt = "lammps-dump-text" if kind == "text" else "lammps-dump-binary"
    summary.update(format=fmt + (f" ({comp})" if comp else ""), n_frames=n,
                   timesteps=traj.timesteps.tolist(), n_particles=traj.n_particles.tolist(),
                   box=None, columns=[], units=None, notes=[])
    if n == 0:
        summary["notes"].append("no frames")
        return
    head = traj.header(0)
    from ..core import Box
    box = Box.from_lammps_bounds(head.bounds, head.tilt, head.boundary)
    summary.update(box=_box_dict(box), columns=list(head.names), units=head.units,
                   notes=list(head.notes))
    traj.check_structure()
    checked = (f"atom counts checked against the row counts of all {n} frames" if n > 1
               else "atom count checked against the row count of the frame")
    if head.kind == "ENTRIES":
        summary["format"] = "lammps-dump-local" + (f" ({comp})" if comp else "")
        summary["notes"] += ["n_particles counts contact rows (ITEM: NUMBER OF ENTRIES)",
                             f"{checked}; values not parsed"]
        return
    if radius is None and not {"radius", "diameter"} & set(head.names):
        summary["notes"] += ["no radius/diameter column: pass --radius (radius=) to read the "
                             "frames", f"{checked}; values not parsed"]
        return
    counts = np.asarray(summary["n_particles"])
    k = int(np.argmax(counts > 0)) if np.any(counts > 0) else 0
    frame = traj[k]
    summary["notes"] = list(dict.fromkeys(summary["notes"] + list(frame.provenance.notes)))
    if all_parsed:
        summary["notes"].append(f"values parsed and checked in all {n} frames kept"
                                + (f"; {len(traj.skipped)} malformed frame(s) left out"
                                   if traj.skipped else ""))
    else:
        summary["notes"].append(f"{checked}; values parsed and checked in frame {k} only "
                                f"(timestep {frame.timestep})")


def format_summary(summary: dict) -> str:
    """Human-readable text of a :func:`summarise` result (one block).

    Examples
    --------
    >>> s = {"path": "dump.x", "format": "lammps-dump-text", "files": ["dump.x"],
    ...      "n_frames": 2, "timesteps": [0, 100], "n_particles": [10, 12],
    ...      "box": {"lo": [0, 0, 0], "hi": [1, 1, 1], "tilt": [0, 0, 0],
    ...              "boundary": ["pp", "pp", "ff"], "periodic": [True, True, False]},
    ...      "columns": ["id", "x", "y", "z", "radius"], "units": None, "notes": []}
    >>> print(format_summary(s))
    dump.x: lammps-dump-text
      frames: 2 (timesteps 0 .. 100)
      particles per frame: 10 .. 12 (first 10, last 12)
      box: lo 0 0 0, hi 1 1 1, boundary pp pp ff
      columns: id x y z radius
      units: not stated
    """
    s = summary
    lines = [f"{s['path']}: {s['format']}"]
    if len(s.get("files", [])) > 1:
        lines.append(f"  files: {len(s['files'])}")
    steps = [t for t in s["timesteps"] if t is not None]
    span = f" (timesteps {steps[0]} .. {steps[-1]})" if steps else ""
    lines.append(f"  frames: {s['n_frames']}{span}")
    counts = s["n_particles"]
    if counts:
        what = "rows" if "local" in s["format"] else "particles"
        if min(counts) == max(counts):
            lines.append(f"  {what} per frame: {counts[0]}")
        else:
            lines.append(f"  {what} per frame: {min(counts)} .. {max(counts)} "
                         f"(first {counts[0]}, last {counts[-1]})")
    box = s.get("box")
    if box:
        lines.append("  box: lo " + " ".join(f"{v:g}" for v in box["lo"]) + ", hi "
                     + " ".join(f"{v:g}" for v in box["hi"])
                     + (", tilt " + " ".join(f"{v:g}" for v in box["tilt"])
                        if any(box["tilt"]) else "")
                     + f", boundary {' '.join(box['boundary'])}")
    if s.get("columns"):
        lines.append("  columns: " + " ".join(s["columns"]))
    lines.append(f"  units: {s.get('units') or 'not stated'}")
    for note in s.get("notes", []):
        lines.append(f"  note: {note}")
    for k in s.get("skipped", []):
        where = k["path"] + (f", line {k['line']}" if k.get("line") is not None else "")
        step = "unknown" if k.get("timestep") is None else k["timestep"]
        lines.append(f"  skipped: frame at timestep {step} ({where}): {k['reason']}")
    return "\n".join(lines)
