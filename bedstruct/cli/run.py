"""Run a workflow on the embedded DEM engine or LIGGGHTS/LAMMPS and write a run directory.

  bedstruct run repose --preset tiny --out runs/repose --json
  bedstruct run spread my.toml --set spread.tool=roller --out runs/roller
  bedstruct run spread --preset small --engine liggghts --np 2 --out runs/lig

Running the same command again resumes a killed run. A repose or spread run also
writes OUT/summary.html: its numbers and pictures of the bed (the first pile, the
last layer). `bedstruct run WORKFLOW --help` lists the workflow's configuration
keys; details in docs/workflows.md.
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


def _workflow_arguments(parser) -> None:
    parser.add_argument("config", nargs="?", default=None, metavar="CONFIG",
                        help="TOML configuration file (optional with --preset)")
    parser.add_argument("--preset", default=None, help="base preset: tiny, small or seed")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a configuration key, e.g. spread.speed=0.05 (repeatable)")
    parser.add_argument("--out", required=True, metavar="DIR", help="run directory")
    parser.add_argument("--engine", default=None, choices=["embedded", "liggghts", "lammps"],
                        help="DEM engine (default: the configuration's, embedded)")
    parser.add_argument("--np", type=int, default=None, metavar="N",
                        help="MPI ranks for liggghts/lammps (external.np)")
    parser.add_argument("--exe", default=None, metavar="PATH",
                        help="engine binary for liggghts/lammps (external.exe)")
    parser.add_argument("--write-only", action="store_true",
                        help="liggghts/lammps: write the deck and inputs, do not run")
    parser.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    parser.add_argument("--progress", action="store_true", default=None,
                        help="show a progress bar (default: when stderr is a terminal)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier run of another configuration in --out")
    parser.add_argument("--no-3d", dest="view_3d", action="store_false",
                        help="repose, spread: leave the 3-D picture out of summary.html")


def add_arguments(parser) -> None:
    sub = parser.add_subparsers(dest="workflow", metavar="WORKFLOW", required=True)
    for name, (what, sections) in _WORKFLOWS.items():
        p = sub.add_parser(
            name, help=what.split(":")[0].split(";")[0], description=what[0].upper() + what[1:] + ".",
            epilog="configuration keys ([section] key, default and unit, meaning, allowed values):\n\n"
                   + config_reference(_COMMON_SECTIONS + sections + _LATE_SECTIONS),
            formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("--traceback", action="store_true", default=argparse.SUPPRESS,
                       help="show the full Python traceback on errors")
        _workflow_arguments(p)


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


def run(args) -> int:
    from ..errors import ConfigError
    from ..workflows import calibrate_cohesion, load_config, run_repose, run_spread, typed_config
    from . import print_json

    if args.config is None and args.preset is None:
        raise ConfigError("give a CONFIG file or --preset NAME (tiny, small, seed)")
    overrides = list(args.overrides)
    if args.engine is not None:
        overrides.append(f'engine="{args.engine}"')
    if getattr(args, "np", None) is not None:
        overrides.append(f"external.np={int(args.np)}")
    if getattr(args, "exe", None):
        overrides.append(f"external.exe={json.dumps(str(args.exe))}")
    if getattr(args, "write_only", False):
        overrides.append("external.write_only=true")
    cfg = load_config(args.config, preset=args.preset, overrides=overrides)
    if cfg["external"]["write_only"] and (cfg["engine"] == "embedded" or args.workflow == "calibrate"):
        raise ConfigError("--write-only writes LIGGGHTS/LAMMPS decks of the repose or spread "
                          "workflow: use it with `run repose|spread --engine liggghts|lammps`")
    func = {"repose": run_repose, "spread": run_spread, "calibrate": calibrate_cohesion}[args.workflow]
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    overwrite = bool(getattr(args, "overwrite", False))
    before = _run_status(args.out) if not overwrite else None
    res = func(typed_config(cfg), out=args.out, progress=progress, overwrite=overwrite)
    if before is not None and not cfg["external"]["write_only"]:
        print(f"resumed the {'finished' if before == 'complete' else 'unfinished'} run in "
              f"{args.out} (finished stages reused)", file=sys.stderr)
    if getattr(res, "decks", None) is not None and not hasattr(res, "angle_deg"):  # write-only
        for cmd in res.commands:
            print(f"deck written; run it with: {cmd}")
        print(f"results: {args.out}/results.json", file=sys.stderr)
        if args.json:
            print_json({"workflow": args.workflow, "engine": res.engine, **res.to_dict()})
        return 0
    summary = _summary(args.workflow, res)
    if cfg["engine"] != "embedded":
        summary["engine"] = cfg["engine"]
    rc = 0
    if args.workflow == "repose":
        rc = _print_repose(res)
    elif args.workflow == "calibrate":
        print(f"calibrated cohesion: {res.cohesion:.4g} +- {res.cohesion_std:.2g} J/m^3 for "
              f"{res.target_deg:.1f} deg (bracketed: {res.bracketed}, converged: {res.converged})")
        for p in res.curve:
            print(f"  k = {p.cohesion:.4g} J/m^3: {p.angle_deg:.2f} +- {p.angle_std_deg:.2f} deg")
    else:
        for layer in res.layers:
            angle = layer.mean_dynamic_angle_deg
            angle_txt = (f"{angle:.1f} deg" if math.isfinite(angle) else
                         "not measurable (no heap with a free toe on the platform; a longer "
                         "spread.plate_length helps, see docs/workflows.md)")
            print(f"layer {layer.index}: bed {layer.bed_height_m * 1e6:.0f} um (nominal "
                  f"{layer.nominal_height * 1e6:.0f} um), packing "
                  f"{', '.join(f'{v:.3f}' for v in layer.packing_fraction)}, dynamic angle "
                  f"{angle_txt}")
    print(f"results: {args.out}/results.json", file=sys.stderr)
    if args.workflow in ("repose", "spread"):
        _write_summary_page(args)
    if args.json:
        print_json(summary)
    return rc


def _print_repose(res) -> int:
    """Print the angle of repose of ``res`` (stdout) and why piles could not be measured
    (stderr); 1 when no pile could be measured, else 0."""
    n, m = len(res.replicates), res.n_measured
    why = "; ".join(f"{stage}: {reason}" for stage, reason in res.unmeasured.items())
    if m == 0:
        print(f"angle of repose: not measurable ({'no pile' if n == 1 else f'none of {n} piles'}"
              f" could be measured; cohesion {res.cohesion:.4g} J/m^3)")
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
          f"cohesion {res.cohesion:.4g} J/m^3)")
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
