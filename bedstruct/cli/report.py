"""Write a self-contained HTML report and a JSON file of every number for dumps.

Prints where it wrote them and what the input is (settled bed, pile, moving bed, dilute
flow); warnings about the input go to stderr. Exit status 0 when the report was written
(even with failed sections), 1 on bad input. The sections and checks: docs/report.md.
"""

from __future__ import annotations

import argparse
import math
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
    parser.add_argument("--contact-columns", metavar="MAP", default=None, type=_contact_columns,
                        help="columns of another contact layout as COLUMN=MEANING pairs, e.g. "
                             "'c_1[1]=id1 c_1[2]=id2 c_2[3]=fx' (meanings: docs/formats.md)")
    parser.add_argument("--regions", type=int, default=3, help="regions along the bed (default 3)")
    parser.add_argument("--axis", default="x", choices=["x", "y", "z"], help="spreading direction")
    parser.add_argument("--frames", default="-1", metavar="SEL",
                        help="frames: -1 (last, default), all, an index or start:stop:step")
    parser.add_argument("--radius", type=_positive, default=None, metavar="R",
                        help="radius when the dump has none (length unit of the dump)")
    parser.add_argument("--boundary", type=_boundary, default=None, metavar="FLAGS",
                        help="boundary flags of a data file, e.g. 'pp pp ff' (default 'pp pp pp')")
    parser.add_argument("--units", default=None,
                        choices=["si", "cgs", "micro", "nano", "lj", "real", "metal", "electron"],
                        help="LAMMPS unit style of the dump when it does not say")
    parser.add_argument("--repose-base", type=_finite, default=None, metavar="Z",
                        help="height of the plate a pile stands on (length unit of the dump)")
    parser.add_argument("--german-windows", type=int, default=None, metavar="N",
                        help="windows along the bed for the German's-law fit (default 12)")
    parser.add_argument("--no-3d", dest="view_3d", action="store_false",
                        help="leave out the 3-D picture of the bed")
    parser.add_argument("--heat", action="store_true", help="add the heat-conduction section")
    parser.add_argument("--heat-length-unit", type=_positive, default=None, metavar="M",
                        help="metres per length unit of the dump, for --heat")
    parser.add_argument("--heat-stop-fraction", type=_fraction, default=0.25, metavar="F",
                        help="end the heat runs at this fraction of the pulse excess (default 0.25)")
    parser.add_argument("--lenient", action="store_true",
                        help="leave malformed frames of damaged dumps out (named in the report)")
    parser.add_argument("--json", action="store_true", help="print the JSON summary as the last line")
    parser.add_argument("--progress", action="store_true", default=None,
                        help="show a progress bar (default: when stderr is a terminal)")


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number; got {text!r}") from None


def _finite(text: str) -> float:
    """A finite number (argparse type)."""
    value = _number(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number; got {text!r}")
    return value


def _positive(text: str) -> float:
    """A positive finite number (argparse type)."""
    value = _finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number; got {text!r}")
    return value


def _fraction(text: str) -> float:
    """A number strictly between 0 and 1 (argparse type)."""
    value = _finite(text)
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a fraction between 0 and 1 (both "
                                         f"excluded); got {text!r}")
    return value


def _boundary(text: str) -> str:
    """LAMMPS boundary flags for the three axes, as ``"pp pp ff"`` (argparse type)."""
    from ..core import Box

    try:
        return " ".join(Box([0, 0, 0], [1, 1, 1], boundary=text).boundary)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{exc} (e.g. 'pp pp ff')") from None


def _contact_columns(text: str):
    """``COLUMN=MEANING`` pairs (a dict), or one meaning per column with ``-`` keeping the
    header name (a list), separated by spaces or commas (argparse type)."""
    words = text.replace(",", " ").split()
    if not words:
        raise argparse.ArgumentTypeError("expected COLUMN=MEANING pairs, e.g. 'c_1[1]=id1 "
                                         "c_1[2]=id2'")
    pairs = [w.partition("=") for w in words]
    if all(sep for _, sep, _ in pairs):
        bad = [w for w, (col, _, meaning) in zip(words, pairs) if not col or not meaning]
        if bad:
            raise argparse.ArgumentTypeError(f"expected COLUMN=MEANING; got {bad[0]!r}")
        cols = [col for col, _, _ in pairs]
        twice = sorted({c for c in cols if cols.count(c) > 1})
        if twice:
            raise argparse.ArgumentTypeError(f"column {twice[0]!r} given twice")
        return {col: meaning for col, _, meaning in pairs}
    if any(sep for _, sep, _ in pairs):
        raise argparse.ArgumentTypeError("give either COLUMN=MEANING pairs or one meaning per "
                                         "column, not both")
    return [None if w == "-" else w for w in words]


def run(args) -> int:
    from ..report import ReportOptions, report_on_files
    from . import UsageError, input_warnings_as_lines, print_json

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
    if args.contact_columns is not None and kw is not None:
        raise UsageError("give --contact-keywords (LIGGGHTS pair/gran/local) or --contact-columns "
                         "(other layouts), not both")
    with input_warnings_as_lines("report"):
        report, html_path, json_path = report_on_files(
            args.paths, args.out, contacts=args.contacts, contact_keywords=kw, options=options,
            radius=args.radius, units=args.units, progress=progress,
            on_error="skip" if args.lenient else "raise", contact_columns=args.contact_columns,
            boundary=args.boundary)
    state = report.state or {}
    kind = f" (input: {state['kind']}" + (f"; not meaningful for it: {', '.join(state['not_meaningful'])}"
                                        if state.get("not_meaningful") else "") + ")" if state else ""
    print(f"bedstruct report: wrote {html_path} and {json_path}{kind}")
    if args.boundary is None and report.inputs.get("boundary"):
        flags = report.inputs["boundary"].split(" (")[0]
        print(f"bedstruct report: note: boundary {flags!r} assumed for the data file, which "
              f"does not record it (give --boundary, e.g. 'pp pp ff' for a bed under open space)",
              file=sys.stderr)
    for text in report.inputs.get("warnings") or []:
        print(f"bedstruct report: warning: {text}", file=sys.stderr)
    units = report.inputs.get("units")
    if args.units is None and isinstance(units, str) and units.startswith("units not stated"):
        print(f"bedstruct report: warning: {units}", file=sys.stderr)
    if report.inputs.get("frame_described"):
        print(f"bedstruct report: note: {report.inputs['frame_described']}", file=sys.stderr)
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
