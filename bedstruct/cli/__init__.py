"""The ``bedstruct`` command line: a thin layer over the library.

Each subcommand is a module in this package defining ``NAME``, ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``; heavy imports happen
inside ``run``. Known errors (bad input, bad configuration) print one line
and exit with status 1, options that do not fit together (:class:`UsageError`)
with status 2 like argparse's own; ``--traceback`` shows the full trace.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import pkgutil
import sys
import warnings

from .._version import __version__
from .._json import json_default
from ..errors import BedstructError, BedstructWarning

__all__ = ["main", "print_json", "UsageError"]

EXIT_OK, EXIT_ERROR, EXIT_USAGE = 0, 1, 2


class UsageError(BedstructError):
    """Options missing or not fitting together, found after parsing: exit status 2."""


def _subcommand_modules():
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(mod, "NAME") and hasattr(mod, "run"):
            yield mod


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="bedstruct",
        description="Quantify powder beds from LIGGGHTS/LAMMPS particle data.")
    parser.add_argument("--version", action="version", version=f"bedstruct {__version__}")
    parser.add_argument("--traceback", action="store_true",
                        help="show the full Python traceback on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in _subcommand_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=(mod.__doc__ or mod.HELP),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("--traceback", action="store_true", default=argparse.SUPPRESS,
                       help="show the full Python traceback on errors")
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


@contextlib.contextmanager
def input_warnings_as_lines(prog: str):
    """Within the block, bedstruct's warnings (about the input) are written as one
    ``bedstruct PROG: warning: ...`` line each, without Python's source-line echo; other
    warnings keep Python's format. The format is replaced, not ``showwarning``, so that
    warnings a caller records (``warnings.catch_warnings(record=True)``) stay as they are."""
    fallback = warnings.formatwarning

    def format_warning(message, category, filename, lineno, line=None):
        if not issubclass(category, BedstructWarning):
            return fallback(message, category, filename, lineno, line)
        return f"bedstruct {prog}: warning: " + " ".join(str(message).split()) + "\n"
    warnings.formatwarning = format_warning
    try:
        yield
    finally:
        warnings.formatwarning = fallback


def print_json(obj) -> None:
    """Print ``obj`` as one line of JSON (the last line scripts parse)."""
    print(json.dumps(obj, separators=(",", ":"), sort_keys=False, default=json_default))


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt:
        print("bedstruct: interrupted", file=sys.stderr)
        return 130
    except UsageError as exc:
        if getattr(args, "traceback", False):
            raise
        print(f"bedstruct {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except (BedstructError, OSError, ValueError,
            ImportError) as exc:  # ImportError: an optional dependency, named in the message
        if getattr(args, "traceback", False):
            raise
        print(f"bedstruct {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR


def entry_point() -> None:  # pragma: no cover - console script
    sys.exit(main())
