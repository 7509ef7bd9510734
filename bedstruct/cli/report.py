"""Write a self-contained HTML report and a JSON file of every number for dumps.

At the top, pictures of the bed coloured by particle size: a 3-D view
(rendered off screen with pyvista, the ``interop`` extra; the report says why
when it cannot be drawn) and a side view. Sections: data summary, packing
fraction along the bed, coordination and German's law, size distribution and
segregation, surface roughness, fabric tensors with rose diagrams, harmonic
spectrum, angle of repose (when a pile is present) and, with --heat,
heat-affected-zone roundness. A section that fails
is reported as failed; the rest still renders. Prints where it wrote the
report and what the input is (settled bed, pile, moving bed, dilute flow).
Exit status 0 when the report was written (even with failed sections), 1 on
bad input. With ``--lenient``, malformed frames of damaged dumps are left out
with a warning naming file, timestep and line; the report lists them.
"""

from __future__ import annotations

import sys

NAME = "report"
HELP = "write report.html and report.json for dumps"


def add_arguments(parser) -> None:
    parser.add_argument("paths", nargs="+", metavar="PATH", help="dump files, globs or data files")
    parser.add_argument("--out", default="bedstruct-report", metavar="DIR",
                        help="output folder (default: bedstruct-report)")
    parser.add_argument("--contacts", metavar="LOCALDUMP", help="LIGGGHTS/LAMMPS dump local contact file")
    parser.add_argument("--contact-keywords", metavar="KW", default=None,
                        help="pair/gran/local keywords of the contact file, e.g. 'pos id force contactArea'")
    parser.add_argument("--regions", type=int, default=3, help="regions along the bed (default 3)")
    parser.add_argument("--axis", default="x", choices=["x", "y", "z"], help="spreading direction")
    parser.add_argument("--frames", default="-1", metavar="SEL",
                        help="frames: -1 (last, default), all, an index or start:stop:step")
    parser.add_argument("--radius", type=float, default=None, help="radius when the dump has none")
    parser.add_argument("--units", default=None,
                        choices=["si", "cgs", "micro", "nano", "lj", "real", "metal", "electron"],
                        help="LAMMPS unit style of the dump when it does not say")
    parser.add_argument("--repose-base", type=float, default=None, metavar="Z",
                        help="height of the plate a pile stands on (length unit of the dump)")
    parser.add_argument("--german-windows", type=int, default=None, metavar="N",
                        help="windows along the bed for the German's-law fit (default 12, the library's "
                             "analysis.german_law_along)")
    parser.add_argument("--no-3d", dest="view_3d", action="store_false",
                        help="leave out the 3-D picture of the bed (the side view is always drawn)")
    parser.add_argument("--heat", action="store_true", help="add the heat-conduction section")
    parser.add_argument("--heat-length-unit", type=float, default=None, metavar="M",
                        help="metres per dump length unit (heat needs SI when the unit is unknown)")
    parser.add_argument("--heat-stop-fraction", type=float, default=0.25, metavar="F",
                        help="end the heat runs when the hottest particle has cooled to this fraction "
                             "of the pulse excess (default 0.25)")
    parser.add_argument("--lenient", action="store_true",
                        help="read damaged dumps: leave malformed frames out (each named with "
                             "file, timestep and line, and listed in the report)")
    parser.add_argument("--json", action="store_true", help="print the JSON summary as the last line")
    parser.add_argument("--progress", action="store_true", default=None,
                        help="show a progress bar (default: when stderr is a terminal)")


def run(args) -> int:
    from ..report import ReportOptions, report_on_files
    from . import UsageError, print_json

    try:
        options = ReportOptions(regions=args.regions, axis=args.axis, frames=args.frames,
                                heat=args.heat, heat_length_unit=args.heat_length_unit,
                                heat_stop_fraction=args.heat_stop_fraction,
                                repose_base=args.repose_base, view_3d=args.view_3d,
                                **({} if args.german_windows is None else {"german_windows": args.german_windows}))
    except ValueError as exc:   # an option's value out of range: a usage error, like argparse's
        raise UsageError(str(exc)) from None
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    kw = args.contact_keywords.split() if args.contact_keywords else None
    report, html_path, json_path = report_on_files(
        args.paths, args.out, contacts=args.contacts, contact_keywords=kw, options=options,
        radius=args.radius, units=args.units, progress=progress,
        on_error="skip" if args.lenient else "raise")
    state = report.state or {}
    kind = f" (input: {state['kind']}" + (f"; not meaningful for it: {', '.join(state['not_meaningful'])}"
                                        if state.get("not_meaningful") else "") + ")" if state else ""
    print(f"bedstruct report: wrote {html_path} and {json_path}{kind}")
    skipped = report.inputs.get("skipped_frames") or []
    if skipped:   # each one was also warned about as it was read
        print(f"bedstruct report: warning: {len(skipped)} malformed frame(s) left out "
              f"(listed in {html_path})", file=sys.stderr)
    if args.json:
        summary = report.summary()
        summary.update(html=str(html_path), json=str(json_path))
        print_json(summary)
    elif report.failed:
        print(f"bedstruct report: warning: section(s) failed: {', '.join(report.failed)} "
              f"(see {html_path})", file=sys.stderr)
    heat = report.section("heat") if args.heat else None
    if heat is not None and heat.status == "skipped":
        # asked for by name, so its absence is news even with --json
        print(f"bedstruct report: warning: --heat skipped: {heat.text}", file=sys.stderr)
    return 0
