"""Summarise LIGGGHTS/LAMMPS files: frames, timesteps, N per frame, box, flags, columns.

Accepts dump files (text, .gz, .bz2, binary), globs and data files. Quiet and
one block per file by default; ``--json`` prints one JSON object per call as
the last line.
"""

from __future__ import annotations

NAME = "info"
HELP = "summarise dump and data files (frames, N, box, columns)"


def add_arguments(parser) -> None:
    parser.add_argument("paths", nargs="+", metavar="PATH", help="dump/data files or globs")
    parser.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    parser.add_argument("--radius", type=float, default=None,
                        help="radius to assume when a dump has no radius/diameter column")


def run(args) -> int:
    from .. import io
    from . import print_json

    summaries = [io.summarise(p, radius=args.radius) for p in args.paths]
    if args.json:
        print_json({"files": summaries})
        return 0
    for s in summaries:
        print(io.format_summary(s))
    return 0
