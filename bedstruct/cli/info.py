"""Summarise LIGGGHTS/LAMMPS files: frames, timesteps, N per frame, box, flags, columns.

Accepts dump files (text, .gz, .bz2, binary), globs and data files: dumps of
one kind matched by a glob are summarised as one trajectory, every data file
on its own. Every frame's atom count is checked against its rows; the values
of the first non-empty frame are parsed. Quiet and one block per summary by
default; ``--json`` prints one JSON object per call as the last line. Exit
status 1 when a file cannot be read or holds no frame (an empty file).

With ``--lenient`` every frame of a dump is parsed and the malformed ones
(cut off, non-numeric values, atom counts that do not match their rows) are
left out with a warning naming file, timestep and line, and listed as skipped.
"""

from __future__ import annotations

import sys

NAME = "info"
HELP = "summarise dump and data files (frames, N, box, columns)"


def add_arguments(parser) -> None:
    parser.add_argument("paths", nargs="+", metavar="PATH", help="dump/data files or globs")
    parser.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    parser.add_argument("--radius", type=float, default=None,
                        help="radius to assume when a dump has no radius/diameter column")
    parser.add_argument("--columns", default=None, metavar="NAMES",
                        help="column names for dumps that do not name theirs (old text dumps, "
                             "old binary dumps), e.g. 'id type x y z radius'")
    parser.add_argument("--lenient", action="store_true",
                        help="read damaged dumps: leave malformed frames out (each named with "
                             "file, timestep and line) instead of stopping at the first")


def run(args) -> int:
    from .. import io
    from . import input_warnings_as_lines, print_json

    on_error = "skip" if args.lenient else "raise"
    with input_warnings_as_lines("info"):
        summaries = [s for p in args.paths
                     for s in io.summarise_all(p, radius=args.radius, columns=args.columns,
                                               on_error=on_error)]
    if args.json:
        print_json({"files": summaries})
    else:
        for s in summaries:
            print(io.format_summary(s))
    # a file with nothing in it is not a dump: say so and fail, as for any unreadable file
    empty = [s["path"] for s in summaries if s.get("format") == "empty" or not s.get("n_frames")]
    if empty:
        print(f"bedstruct info: error: {', '.join(map(str, empty))}: no frames (the file is empty)",
              file=sys.stderr)
        return 1
    return 0
