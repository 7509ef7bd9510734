"""Summaries of dump, dump local and data files (``bedstruct info``)."""

from __future__ import annotations

import numpy as np

from ._binary import is_binary
from ._source import Source
from .data_file import read_data
from .lammps_dump import expand_paths, read_dump

__all__ = ["summarise", "format_summary"]


def _box_dict(box) -> dict:
    return {"lo": box.lo.tolist(), "hi": box.hi.tolist(), "tilt": box.tilt.tolist(),
            "boundary": list(box.boundary), "periodic": list(box.periodic)}


def _kind(path) -> tuple[str, str | None]:
    src = Source(path)
    try:
        head = src.read_range(0, 256)
    finally:
        src.close()
    comp = src.compression
    if head.lstrip().startswith(b"ITEM:"):
        return "text", comp
    if is_binary(head):
        return "binary", comp
    return "data", comp


def summarise(path, radius=None) -> dict:
    """Summarise a dump, dump local or data file (or a glob of dumps).

    Reads the frame headers, and the first non-empty frame in full to check
    it and collect the reader's notes.

    Parameters
    ----------
    path : str or path-like
        A file or glob pattern.
    radius : float, optional
        Radius assumed when a dump has no radius/diameter column.

    Returns
    -------
    dict
        JSON-serialisable: ``path``, ``files``, ``format``, ``n_frames``,
        ``timesteps``, ``n_particles`` (per frame; contact rows for dump
        local files), ``box`` (``lo``, ``hi``, ``tilt``, ``boundary``,
        ``periodic`` of the first frame), ``columns``, ``units`` and
        ``notes``.

    Raises
    ------
    DumpFormatError
        If the file is malformed.

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
    paths = expand_paths(path)
    kind, comp = _kind(paths[0])
    summary = {"path": str(path), "files": paths}
    if kind == "data":
        frame = read_data(paths[0])
        summary.update(format="lammps-data", n_frames=1, timesteps=[None],
                       n_particles=[frame.n_particles], box=_box_dict(frame.box),
                       columns=["id", "type", "radius", "x", "y", "z"]
                       + (["ix", "iy", "iz"] if frame.images is not None else [])
                       + (["vx", "vy", "vz"] if frame.velocities is not None else [])
                       + (["omegax", "omegay", "omegaz"] if frame.omegas is not None else [])
                       + list(frame.columns),
                       units=frame.units.style, notes=list(frame.provenance.notes))
        return summary
    with read_dump(paths, radius=radius) as traj:
        n = len(traj)
        fmt = "lammps-dump-text" if kind == "text" else "lammps-dump-binary"
        summary.update(format=fmt + (f" ({comp})" if comp else ""), n_frames=n,
                       timesteps=traj.timesteps.tolist(), n_particles=traj.n_particles.tolist(),
                       box=None, columns=[], units=None, notes=[])
        if n == 0:
            summary["notes"].append("no frames")
            return summary
        head = traj.header(0)
        from ..core import Box
        box = Box.from_lammps_bounds(head.bounds, head.tilt, head.boundary)
        summary.update(box=_box_dict(box), columns=list(head.names), units=head.units,
                       notes=list(head.notes))
        if head.kind == "ENTRIES":
            summary["format"] = "lammps-dump-local" + (f" ({comp})" if comp else "")
            summary["notes"].append("n_particles counts contact rows (ITEM: NUMBER OF ENTRIES)")
            return summary
        if radius is None and not {"radius", "diameter"} & set(head.names):
            summary["notes"].append("no radius/diameter column: pass --radius (radius=) to "
                                    "read the frames")
            return summary
        counts = np.asarray(summary["n_particles"])
        k = int(np.argmax(counts > 0)) if np.any(counts > 0) else 0
        frame = traj[k]
        summary["notes"] = list(dict.fromkeys(summary["notes"] + list(frame.provenance.notes)))
    return summary


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
    return "\n".join(lines)
