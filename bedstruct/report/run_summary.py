"""A short HTML page of a workflow run: its headline numbers and pictures of the bed."""

from __future__ import annotations

import glob
import json
import os
from pathlib import Path

from .._version import __version__
from ..io import read
from ._model import Report, Section, Table
from ._picture import bed_pictures
from ._render import _atomic_write, render_html

__all__ = ["write_run_summary"]

#: Where a run folder keeps the bed a summary pictures (newest last), by workflow.
_BED_FILES = {"repose": ("rep*/pile.dump.gz", "rep*/pile.dump"),
              "spread": ("layer*/bed.dump.gz", "layer*/bed.dump")}


def _final_bed(out: Path, workflow: str) -> str | None:
    found = sorted(p for pattern in _BED_FILES.get(workflow, ()) for p in glob.glob(str(out / pattern)))
    if not found:
        return None
    return found[0] if workflow == "repose" else found[-1]   # the first pile, the last layer


def _repose_section(res: dict, s: Section) -> None:
    n = len(res.get("replicates") or [])
    s.add_number("angle_deg", res.get("angle_deg"), "deg",
                 "static angle of repose: mean over the piles of their mean flank angle",
                 "docs/workflows.md")
    s.add_number("angle_std_deg", res.get("angle_std_deg"), "deg",
                 "fit uncertainty of the one pile's angle" if n == 1 else
                 "standard uncertainty of the mean over the piles")
    s.add_number("spread_deg", res.get("spread_deg"), "deg",
                 "standard deviation between the piles (none with one pile)")
    s.add_number("cohesion", res.get("cohesion"), "J/m^3", "SJKR cohesion energy density")
    rows = [[r.get("stage"), r.get("seed"), r.get("angle_deg"), r.get("angle_std_deg"),
             r.get("left_deg"), r.get("right_deg"), r.get("n_remaining"), r.get("pile_height")]
            for r in res.get("replicates") or []]
    s.tables.append(Table(["pile", "seed", "angle", "+-", "left flank", "right flank",
                           "particles", "height"], rows, caption="every pile",
                          units=["", "1", "deg", "deg", "deg", "deg", "1", "m"]))


def _spread_section(res: dict, s: Section) -> None:
    layers = res.get("layers") or []
    s.add_number("tool", res.get("tool"), "-", "spreading tool")
    s.add_number("speed", res.get("speed"), "m/s", "spreading speed")
    regions = list(res.get("regions") or [])
    names = regions or [f"region {k + 1}" for k in range(len((layers or [{}])[0].get(
        "packing_fraction") or []))]
    rows = []
    for layer in layers:
        packing = list(layer.get("packing_fraction") or [])
        rows.append([layer.get("index"), layer.get("nominal_height"), layer.get("bed_height_m"),
                     layer.get("roughness_sa_m"), *packing, layer.get("mean_dynamic_angle_deg"),
                     layer.get("n_bed")])
    s.tables.append(Table(["layer", "nominal height", "bed height", "roughness Sa",
                           *[f"packing {n}" for n in names], "dynamic angle", "particles"],
                          rows, caption="every layer (bed height: mean top surface above the "
                                        "platform; packing between the platform and the tool)",
                          units=["1", "m", "m", "m", *["1"] * len(names), "deg", "1"]))


def write_run_summary(out_dir, *, results: dict | None = None, view_3d: bool = True) -> Path:
    """Write ``summary.html`` into a run folder: the run's numbers and pictures of its bed.

    Parameters
    ----------
    out_dir : str or path-like
        The folder of a ``repose`` or ``spread`` run (with ``results.json``).
    results : dict, optional
        The run's results (the contents of ``results.json``, read when omitted).
    view_3d : bool
        Draw the 3-D picture (needs pyvista and an off-screen renderer; the
        page says why when it is not drawn). The side view is always drawn.

    Returns
    -------
    pathlib.Path
        The page written.

    Raises
    ------
    FileNotFoundError
        Without ``results`` when the folder has no ``results.json``.
    ValueError
        For results of a workflow other than ``repose`` or ``spread``.

    Examples
    --------
    >>> import tempfile
    >>> from bedstruct.report import write_run_summary
    >>> results = {"workflow": "repose", "angle_deg": 31.0, "angle_std_deg": 1.0,
    ...            "spread_deg": None, "cohesion": 3000.0, "replicates": []}
    >>> page = write_run_summary(tempfile.mkdtemp(), results=results)
    >>> page.name, "31" in page.read_text()
    ('summary.html', True)
    """
    out = Path(out_dir)
    if results is None:
        results = json.loads((out / "results.json").read_text())
    workflow = results.get("workflow")
    if workflow not in _BED_FILES:
        raise ValueError(f"a run summary is written for 'repose' and 'spread' runs; got "
                         f"workflow {workflow!r}")
    bed = _final_bed(out, workflow)
    inputs = {"run folder": str(out), "numbers": str(out / "results.json"),
              "configuration": str(out / "config.toml"),
              "bed pictured": os.path.relpath(bed, out) if bed else "none found"}
    report = Report(title=f"bedstruct run {workflow}", inputs=inputs, settings={},
                    version=__version__)
    section = Section("results", "Results")
    (_repose_section if workflow == "repose" else _spread_section)(results, section)
    if bed:
        contacts = bed.replace("pile.dump", "pile_contacts.dump").replace("bed.dump",
                                                                          "bed_contacts.dump")
        section.text = ("Every number is in results.json. The full analysis of the bed "
                        f"pictured: bedstruct report {bed}"
                        + (f" --contacts {contacts}" if os.path.isfile(contacts) else "")
                        + f" --out {out / 'report'}")
        traj = read(bed)
        try:
            frame = traj[-1]
        finally:
            traj.close()
        report.pictures, report.picture_note = bed_pictures(frame, view_3d=view_3d)
    else:
        report.picture_note = "No bed dump found in the run folder: nothing to picture."
    report.sections.append(section)
    path = out / "summary.html"
    _atomic_write(path, render_html(report))
    return path
