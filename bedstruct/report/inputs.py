"""Load dumps (and contact files) for a report and run it end to end."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from ..core import Contacts, Frame, FrameList
from ..io import read, read_dump_local
from ..io.data_file import BOUNDARY_NOT_RECORDED
from .build import build_report
from .options import ReportOptions, select_frames
from ._model import Report
from ._render import write_report

__all__ = ["load_report_inputs", "report_on_files"]


def load_report_inputs(paths: Sequence[str], *, contacts: str | None = None,
                       contact_keywords: Sequence[str] | None = None, frames: str = "-1",
                       radius: float | None = None, units: str | None = None,
                       on_error: str = "raise", contact_columns=None,
                       boundary: str | Sequence[str] | None = None
                       ) -> tuple[list[Frame], list[int], Contacts | None, dict]:
    """Read the frames selected from dump files and the matching contacts.

    Parameters
    ----------
    paths : sequence of str
        Dump files or globs (text, gz, bz2, binary), LAMMPS data files or
        bedstruct HDF5 archives, recognised from their content
        (:func:`bedstruct.io.read`); their frames are concatenated in order.
    contacts : str, optional
        A ``dump local`` contact file; contacts of the last selected frame
        are joined by particle id (geometric contacts are used otherwise).
        A frame whose particle ids repeat is refused: contacts could not be
        joined to it.
    contact_keywords : sequence of str, optional
        The ``compute pair/gran/local`` keywords of the contact file.
    contact_columns : dict or sequence, optional
        For other contact layouts (LAMMPS ``property/local``): what each
        column holds, as ``columns=`` of :func:`bedstruct.io.read_dump_local`.
    frames : str
        Frame selection (see :func:`select_frames`), counted over the frames
        that read.
    radius, units : optional
        As for :func:`bedstruct.io.read`.
    boundary : str or sequence of 3 str, optional
        Boundary flags of data files, which do not record them (default
        ``"pp pp pp"``, see :func:`bedstruct.io.read_data`); the boundary of
        every data file read is listed in the inputs under ``boundary``,
        saying whether it was given or assumed.
    on_error : {"raise", "skip"}
        ``"skip"`` leaves malformed dump frames out (see
        :func:`bedstruct.io.read_dump`); they are listed in the inputs under
        ``skipped_frames`` (file, timestep, line, reason).

    Returns
    -------
    frames, indices, contacts, inputs
        The selected frames, their indices, the contacts of the last one
        (or None) and a description of the inputs for the report.
    """
    trajectories = [read(p, radius=radius, units=units, on_error=on_error, boundary=boundary)
                    for p in paths]
    skipped = [s.to_dict() for t in trajectories for s in getattr(t, "skipped", ())]
    sizes = [len(t) for t in trajectories]
    total = sum(sizes)
    if total == 0:
        raise ValueError(f"{', '.join(str(p) for p in paths)}: no frames to report on")
    idx = select_frames(total, frames)
    selected = []
    for k in idx:
        t = 0
        while k >= sizes[t]:
            k -= sizes[t]
            t += 1
        selected.append(trajectories[t][k])
    contact_obj = None
    if contacts is not None:
        by_step = read_dump_local(contacts, keywords=contact_keywords, columns=contact_columns,
                                  frames=selected[-1])
        last = selected[-1].timestep
        if last not in by_step:
            raise ValueError(f"{contacts}: no contact frame at timestep {last} "
                             f"(has {sorted(by_step)[:10]})")
        contact_obj = by_step[last]
    inputs = {"paths": [str(p) for p in paths], "frames_in_input": total,
              "frames_selected": idx, "contacts": str(contacts) if contacts else "geometric detection",
              "units_given": units, "radius_given": radius}
    flags = _data_file_boundaries(trajectories, boundary)
    if flags:
        inputs["boundary"] = flags
    if on_error == "skip":
        inputs["skipped_frames"] = skipped
    return selected, idx, contact_obj, inputs


def _data_file_boundaries(trajectories, boundary) -> str | None:
    """What boundary the data files among the inputs were read with (they do not record
    it): ``"pp pp ff (given)"`` or ``"pp pp pp (assumed: ...)"``; None without data files."""
    seen = []
    for t in trajectories:
        if not isinstance(t, FrameList):   # data files are read into a FrameList
            continue
        for frame in t:
            if any(BOUNDARY_NOT_RECORDED in n for n in frame.provenance.notes):
                flags = " ".join(frame.box.boundary)
                if flags not in seen:
                    seen.append(flags)
    if not seen:
        return None
    if boundary is not None:
        return f"{', '.join(seen)} (given for the data file: it does not record it)"
    return (f"{', '.join(seen)} (assumed for the data file, which does not record it; "
            f"give --boundary, e.g. 'pp pp ff' for a bed under open space)")


def report_on_files(paths: Sequence[str], out_dir, *, contacts: str | None = None,
                    contact_keywords: Sequence[str] | None = None, options: ReportOptions | None = None,
                    radius: float | None = None, units: str | None = None, progress: bool = False,
                    on_error: str = "raise", contact_columns=None,
                    boundary: str | Sequence[str] | None = None) -> tuple[Report, Path, Path]:
    """Read inputs, build the report and write ``report.html`` and ``report.json``.

    ``on_error="skip"`` reads damaged dumps, leaving malformed frames out;
    the report lists them; ``contact_columns`` and ``boundary`` are as for
    :func:`load_report_inputs`. Returns the
    report and the two paths written. An ``out_dir`` that is a file is an error
    before anything is read.
    """
    if Path(out_dir).exists() and not Path(out_dir).is_dir():
        raise NotADirectoryError(f"the output folder {out_dir} is a file")
    options = options or ReportOptions()
    frames, idx, contact_obj, inputs = load_report_inputs(
        paths, contacts=contacts, contact_keywords=contact_keywords, frames=options.frames,
        radius=radius, units=units, on_error=on_error, contact_columns=contact_columns,
        boundary=boundary)
    report = build_report(frames, contacts=contact_obj, options=options, frame_indices=idx,
                          inputs=inputs, progress=progress)
    html_path, json_path = write_report(report, out_dir)
    return report, html_path, json_path
