"""Run a workflow on the embedded DEM engine or LIGGGHTS/LAMMPS and write a run directory.

  bedstruct run repose --preset tiny --out runs/repose --json
  bedstruct run spread my.toml --set spread.tool=roller --out runs/roller
  bedstruct run spread --preset small --engine liggghts --np 2 --out runs/lig

Running the same command again resumes a killed run. A repose or spread run also
writes OUT/summary.html: its numbers and pictures of the bed (the first pile, the
last layer). `bedstruct run WORKFLOW --help-config` lists the workflow's
configuration keys; details in docs/workflows.md.

With --json, stdout holds one JSON object (the results, ``out``, the ``files``
written and whether the run was ``resumed``) and the human lines go to stderr.
Options that do not fit together exit with status 2, a bad configuration or a
failed run with status 1.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from ..workflows.schema import config_reference

NAME = "run"
HELP = "run a workflow (repose, spread, calibrate) on the embedded DEM engine or LIGGGHTS/LAMMPS"

_WORKFLOWS = {
    "repose": ("angle of repose: a box filled by raindrop insertion, the bottom plate slides out, "
               "the pile's flanks are measured", ("repose",)),
    "spread": ("multi-layer spreading with a blade (rake), plate or roller; per layer bed height, "
               "packing per region, dynamic angle, coordination", ("spread",)),
    "calibrate": ("SJKR cohesion energy density that reproduces calibrate.target_deg (bracketing "
                  "search over repose runs)", ("repose", "calibrate")),
}
_COMMON_SECTIONS = ("", "material", "contact", "psd", "time")
_LATE_SECTIONS = ("external", "output")


_SET_EXAMPLES = {"repose": "repose.drain_time=0.1", "spread": "spread.speed=0.05",
                 "calibrate": "calibrate.target_deg=35"}


class _PrintConfigReference(argparse.Action):
    """``--help-config``: print the workflow's configuration keys and exit."""

    def __init__(self, option_strings, dest, sections=(), **kwargs):
        self.sections = sections
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        import os
        try:
            print("configuration keys ([section] key, default and unit, meaning, allowed "
                  "values):\n")
            print(config_reference(self.sections), flush=True)
        except BrokenPipeError:   # `| head`: the reader has what it wanted
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        parser.exit(0)


def _workflow_arguments(parser, name: str, sections) -> None:
    parser.add_argument("config", nargs="?", default=None, metavar="CONFIG",
                        help="TOML configuration file (optional with --preset)")
    parser.add_argument("--preset", default=None, metavar="NAME",
                        help="base preset: tiny, small or seed")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help=f"override a key, e.g. {_SET_EXAMPLES[name]} (repeatable)")
    parser.add_argument("--out", required=True, metavar="DIR", help="run directory")
    parser.add_argument("--engine", default=None, choices=["embedded", "liggghts", "lammps"],
                        metavar="NAME", help="embedded (default), liggghts or lammps")
    parser.add_argument("--np", type=int, default=None, metavar="N",
                        help="MPI ranks for liggghts/lammps")
    parser.add_argument("--exe", default=None, metavar="PATH",
                        help="engine binary for liggghts/lammps")
    parser.add_argument("--write-only", action="store_true",
                        help=("liggghts/lammps: write the deck, do not run it"
                              if name != "calibrate" else argparse.SUPPRESS))
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object on stdout (nothing else)")
    parser.add_argument("--progress", action="store_true", default=None,
                        help="progress bar (default: when stderr is a terminal)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a run of another configuration in --out")
    if name != "calibrate":
        parser.add_argument("--no-3d", dest="view_3d", action="store_false",
                            help="leave the 3-D picture out of summary.html")
    parser.add_argument("--help-config", action=_PrintConfigReference,
                        sections=_COMMON_SECTIONS + sections + _LATE_SECTIONS,
                        help="print the configuration keys and exit")


def add_arguments(parser) -> None:
    sub = parser.add_subparsers(dest="workflow", metavar="WORKFLOW", required=True)
    for name, (what, sections) in _WORKFLOWS.items():
        p = sub.add_parser(
            name, help=what.split(":")[0].split(";")[0], description=what[0].upper() + what[1:] + ".",
            epilog=f"configuration keys: `bedstruct run {name} --help-config`; "
                   "details in docs/workflows.md",
            formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("--traceback", action="store_true", default=argparse.SUPPRESS,
                       help="show the full Python traceback on errors")
        _workflow_arguments(p, name, sections)


def _summary(workflow, res) -> dict:
    if workflow == "repose":
        d = res.to_dict()
        return {"workflow": "repose", "angle_deg": d["angle_deg"], "angle_std_deg": d["angle_std_deg"],
                "spread_deg": d["spread_deg"], "cohesion": d["cohesion"],
                "n_measured": d["n_measured"], "unmeasured": d["unmeasured"],
                "replicates": d["replicates"]}
    if workflow == "calibrate":
        return {"workflow": "calibrate", **res.to_dict()}
    d = res.to_dict()
    return {"workflow": "spread", "tool": d["tool"], "speed": d["speed"], "regions": d["regions"],
            "bed_height_m": d["bed_height_m"],
            "bed_top_m": [layer["bed_top_m"] for layer in d["layers"]],
            "packing_fraction": d["packing_fraction"],
            "mean_dynamic_angle_deg": d["mean_dynamic_angle_deg"],
            "coordination": [layer["coordination"] for layer in d["layers"]],
            "nominal_height_m": [layer["nominal_height"] for layer in d["layers"]],
            "german_a": d["german_a"], "german_b": d["german_b"],
            "german_determined": d.get("german_determined"), "layers": d["layers"]}


def _run_status(out) -> str | None:
    """The status in ``out/run.json`` ("running", "complete"), or None without one."""
    from pathlib import Path
    try:
        return str(json.loads((Path(out) / "run.json").read_text()).get("status"))
    except (OSError, ValueError, AttributeError):
        return None


def _flag_overrides(args) -> list:
    """The ``(flag as typed, KEY=VALUE, value)`` of --engine, --np, --exe and --write-only,
    which are configuration overrides."""
    pairs = []
    if args.engine is not None:
        pairs.append((f"--engine {args.engine}", f'engine="{args.engine}"', args.engine))
    if getattr(args, "np", None) is not None:
        pairs.append((f"--np {args.np}", f"external.np={int(args.np)}", int(args.np)))
    if getattr(args, "exe", None):
        pairs.append((f"--exe {args.exe}", f"external.exe={json.dumps(str(args.exe))}",
                      str(args.exe)))
    if getattr(args, "write_only", False):
        pairs.append(("--write-only", "external.write_only=true", True))
    return pairs


def _by_flag(message: str, pairs) -> str:
    """``message`` with the configuration key a flag stands for named as that flag."""
    for flag, assignment, value in pairs:
        key = assignment.split("=", 1)[0]
        message = message.replace(f"--set {assignment}: config key `{key}` ", f"{flag}: ")
        message = message.replace(f"--set {assignment}", flag)
        message = message.replace(f"`{key}` = {value!r}", flag)
    return message


def _files_written(out, decks=()) -> dict:
    """The paths of the run directory's files that exist: results, summary page, run
    record, configuration, and the decks of a write-only run."""
    from pathlib import Path
    names = {"results": "results.json", "summary": "summary.html", "run": "run.json",
             "config": "config.toml"}
    files = {k: str(Path(out) / v) for k, v in names.items() if (Path(out) / v).is_file()}
    if decks:
        files["decks"] = [str(d) for d in decks]
    return files


def run(args) -> int:
    from ..errors import ConfigError
    from ..workflows import calibrate_cohesion, load_config, run_repose, run_spread, typed_config
    from . import UsageError, print_json

    if args.config is None and args.preset is None:
        raise UsageError("give a CONFIG file or --preset NAME (tiny, small, seed)")
    if args.workflow == "calibrate" and args.write_only:
        raise UsageError("--write-only writes LIGGGHTS/LAMMPS decks of the repose or spread "
                         "workflow, not of calibrate")
    flags = _flag_overrides(args)
    try:
        cfg = load_config(args.config, preset=args.preset,
                          overrides=[*args.overrides, *(a for _, a, _ in flags)],
                          workflow=args.workflow)
    except ConfigError as exc:
        if _by_flag(str(exc), flags) == str(exc):
            raise
        raise ConfigError(_by_flag(str(exc), flags)) from None
    if cfg["external"]["write_only"] and (cfg["engine"] == "embedded" or args.workflow == "calibrate"):
        if getattr(args, "write_only", False):
            raise UsageError("--write-only writes LIGGGHTS/LAMMPS decks: use it with "
                             "`run repose|spread --engine liggghts|lammps`")
        raise ConfigError("config key `external.write_only` = true writes LIGGGHTS/LAMMPS decks "
                          "of the repose or spread workflow: it needs engine = \"liggghts\" or "
                          "\"lammps\"")
    func = {"repose": run_repose, "spread": run_spread, "calibrate": calibrate_cohesion}[args.workflow]
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    overwrite = bool(getattr(args, "overwrite", False))
    before = _run_status(args.out) if not overwrite else None
    try:
        res = func(typed_config(cfg), out=args.out, progress=progress, overwrite=overwrite)
    except ConfigError as exc:
        if _by_flag(str(exc), flags) == str(exc):
            raise
        raise ConfigError(_by_flag(str(exc), flags)) from None
    human = sys.stderr if args.json else sys.stdout
    resumed = before is not None and not cfg["external"]["write_only"]
    if resumed:
        print(f"resumed the {'finished' if before == 'complete' else 'unfinished'} run in "
              f"{args.out} (finished stages reused)", file=sys.stderr)
    if getattr(res, "decks", None) is not None and not hasattr(res, "angle_deg"):  # write-only
        for cmd in res.commands:
            print(f"deck written; run it with: {cmd}", file=human)
        print(f"results: {args.out}/results.json", file=sys.stderr)
        if args.json:
            print_json({"workflow": args.workflow, "engine": res.engine, **res.to_dict(),
                        "out": str(args.out), "resumed": False,
                        "files": _files_written(args.out, res.decks)})
        return 0
    summary = _summary(args.workflow, res)
    if cfg["engine"] != "embedded":
        summary["engine"] = cfg["engine"]
    rc = 0
    if args.workflow == "repose":
        rc = _print_repose(res, human)
    elif args.workflow == "calibrate":
        print(f"calibrated cohesion: {res.cohesion:.4g} +- {res.cohesion_std:.2g} J/m^3 for "
              f"{res.target_deg:.1f} deg (bracketed: {res.bracketed}, converged: {res.converged})",
              file=human)
        for p in res.curve:
            print(f"  k = {p.cohesion:.4g} J/m^3: {p.angle_deg:.2f} +- {p.angle_std_deg:.2f} deg",
                  file=human)
    else:
        for layer in res.layers:
            angle = layer.mean_dynamic_angle_deg
            angle_txt = (f"{angle:.1f} deg" if math.isfinite(angle) else
                         "not measurable (no heap with a free toe on the platform; a longer "
                         "spread.plate_length helps, see docs/workflows.md)")
            print(f"layer {layer.index}: bed {layer.bed_height_m * 1e6:.0f} um (nominal "
                  f"{layer.nominal_height * 1e6:.0f} um), packing "
                  f"{', '.join(f'{v:.3f}' for v in layer.packing_fraction)}, dynamic angle "
                  f"{angle_txt}", file=human)
    print(f"results: {args.out}/results.json", file=sys.stderr)
    if args.workflow in ("repose", "spread"):
        _write_summary_page(args)
    if args.json:
        print_json({**summary, "out": str(args.out), "resumed": resumed,
                    "files": _files_written(args.out)})
    return rc


def _print_repose(res, stream=None) -> int:
    """Print the angle of repose of ``res`` (on ``stream``, stdout by default) and why piles
    could not be measured (stderr); 1 when no pile could be measured, else 0."""
    stream = sys.stdout if stream is None else stream
    n, m = len(res.replicates), res.n_measured
    why = "; ".join(f"{stage}: {reason}" for stage, reason in res.unmeasured.items())
    if m == 0:
        print(f"angle of repose: not measurable ({'no pile' if n == 1 else f'none of {n} piles'}"
              f" could be measured; cohesion {res.cohesion:.4g} J/m^3)", file=stream)
        print(f"bedstruct run: error: no pile could be measured: {why}", file=sys.stderr)
        return 1
    if m == n:
        what = ("one pile; +- is the flank-fit uncertainty, not a scatter between piles"
                if n == 1 else f"mean of {n} piles; +- its standard uncertainty, scatter "
                f"between piles {res.spread_deg:.2f} deg")
    else:
        what = (f"mean of {m} of {n} piles ({n - m} could not be measured: {why}); "
                + ("+- is the flank-fit uncertainty of the one pile measured" if m == 1 else
                   f"+- its standard uncertainty, scatter between piles {res.spread_deg:.2f} deg"))
    print(f"angle of repose: {res.angle_deg:.2f} +- {res.angle_std_deg:.2f} deg ({what}; "
          f"cohesion {res.cohesion:.4g} J/m^3)", file=stream)
    if m < n:
        print(f"bedstruct run: warning: {n - m} of {n} piles could not be measured: {why}",
              file=sys.stderr)
    return 0


def _write_summary_page(args) -> None:
    """OUT/summary.html, and where it is; a page that cannot be written is a warning (the
    run itself succeeded)."""
    from ..report.run_summary import write_run_summary
    try:
        path = write_run_summary(args.out, view_3d=getattr(args, "view_3d", True))
    except Exception as exc:   # the results are written: the page is a convenience
        print(f"bedstruct run: warning: no summary page ({type(exc).__name__}: {exc})",
              file=sys.stderr)
        return
    print(f"summary: {path}", file=sys.stderr)
