"""Run a workflow on the embedded DEM engine (or LIGGGHTS/LAMMPS) and write a run directory.

Workflows:
  repose     angle of repose: box filled by raindrop insertion, bottom plate
             slides out, the remaining pile is measured (both flanks,
             replicates); JSON: angle_deg, angle_std_deg, replicates.
  spread     multi-layer spreading with a blade (rake), plate or roller; per
             layer: bed_height_m, packing_fraction per region,
             mean_dynamic_angle_deg, coordination, fabric, segregation.
  calibrate  SJKR cohesion energy density reproducing calibrate.target_deg
             (bracketing search over replicate repose runs).

Configuration: a TOML file and/or --preset tiny|small|seed, then
--set section.key=value overrides (TOML values; bare words are strings),
e.g. --set spread.speed=0.0508 --set "spread.gaps=[5e-4, 5e-4]".

Engines: --engine embedded (default), or liggghts / lammps (same particles,
walls, contact model and time step; --np N MPI ranks, --exe PATH for your
own binary, --write-only to write the deck and inputs into the run directory
without running). On liggghts/lammps, repose runs in full and spread runs
all layers in one engine run (later piles wait parked and are moved in
before their layer, so contact histories carry over; blade, plate or
roller; --write-only writes that one deck); calibrate runs its repose
points on the chosen engine.

Run folders: a run writes run.json (status "running", then "complete"),
config.toml and, last, results.json into --out, and checkpoints as it goes
(output.checkpoint_every steps; every spreading layer, repose replicate and
calibration point). Running the same command again resumes a killed run
from its latest checkpoint (finished stages are reused, a finished run
gives its results back); a folder holding a run of another configuration
is refused unless --overwrite replaces it. On liggghts/lammps a resumed run
reuses finished repose replicates, the spreading pile and a finished
spreading engine run; an engine run that was killed runs again from its start.

Examples:
  bedstruct run repose --preset tiny --out runs/repose --json
  bedstruct run repose --preset tiny --engine liggghts --np 2 --out runs/repose-lig
  bedstruct run spread --preset small --set spread.tool=roller --out runs/roller
"""

from __future__ import annotations

import json
import math
import sys

NAME = "run"
HELP = "run a workflow (repose, spread, calibrate) on the embedded DEM engine or LIGGGHTS/LAMMPS"


def add_arguments(parser) -> None:
    parser.add_argument("workflow", choices=["repose", "spread", "calibrate"], help="workflow to run")
    parser.add_argument("config", nargs="?", default=None, metavar="CONFIG",
                        help="TOML configuration file (optional with --preset)")
    parser.add_argument("--preset", default=None, help="base preset: tiny, small or seed")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a configuration key (repeatable)")
    parser.add_argument("--out", required=True, metavar="DIR", help="run directory")
    parser.add_argument("--engine", default=None, choices=["embedded", "liggghts", "lammps"],
                        help="DEM engine (liggghts/lammps: repose, spread with blade/plate)")
    parser.add_argument("--np", type=int, default=None, metavar="N",
                        help="MPI ranks for liggghts/lammps (external.np)")
    parser.add_argument("--exe", default=None, metavar="PATH",
                        help="engine binary for liggghts/lammps (external.exe)")
    parser.add_argument("--write-only", action="store_true",
                        help="liggghts/lammps: write the deck and inputs, do not run (repose, spread)")
    parser.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    parser.add_argument("--progress", action="store_true", default=None,
                        help="show a progress bar (default: when stderr is a terminal)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an earlier run in --out (default: resume a run of the "
                             "same configuration, refuse one of another)")


def _summary(workflow, res) -> dict:
    if workflow == "repose":
        d = res.to_dict()
        return {"workflow": "repose", "angle_deg": d["angle_deg"], "angle_std_deg": d["angle_std_deg"],
                "spread_deg": d["spread_deg"], "cohesion": d["cohesion"],
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
            "german_a": d["german_a"], "german_b": d["german_b"], "layers": d["layers"]}


def _run_status(out) -> str | None:
    """The status in ``out/run.json`` ("running", "complete"), or None without one."""
    from pathlib import Path
    try:
        return str(json.loads((Path(out) / "run.json").read_text()).get("status"))
    except (OSError, ValueError, AttributeError):
        return None


def run(args) -> int:
    from ..errors import ConfigError
    from ..workflows import calibrate_cohesion, load_config, run_repose, run_spread
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
    res = func(cfg, out=args.out, progress=progress, overwrite=overwrite)
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
    if args.workflow == "repose":
        print(f"angle of repose: {res.angle_deg:.2f} +- {res.angle_std_deg:.2f} deg "
              f"({len(res.replicates)} replicate(s), cohesion {res.cohesion:.4g} J/m^3)")
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
    if args.json:
        print_json(summary)
    return 0
