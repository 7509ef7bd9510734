"""Benchmark: the workflows (angle of repose, multi-layer spreading) of a preset on every engine.

Runs one repose replicate and the spreading workflow of the preset (default
``small``; ``--preset tiny`` for a quick check) on the embedded engine, and
times the same workflows on LIGGGHTS and LAMMPS when installed (``nan`` otherwise),
through the decks the workflows generate. Run::

    python benchmarks/bench_workflows.py [--preset small] [--layers N] [--threads 1]

Ends with ``RESULT preset=... engine=embedded repose_s=... repose_particles=...
spread_s=... spread_layers=... spread_steps=... spread_final_particles=... liggghts_repose_s=...
liggghts_spread_s=... lammps_repose_s=... lammps_spread_s=...``.
Timings include numba compilation on the first call unless the cache is warm;
on a shared machine they are indicative only.
"""

from __future__ import annotations

import argparse
import tempfile
import time


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="small")
    p.add_argument("--layers", type=int, default=None, help="spread only the first N layers")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--skip-spread", action="store_true")
    args = p.parse_args(argv)

    from bedstruct.errors import ConfigError
    from bedstruct.workflows import load_config, run_repose, run_spread

    over = [f"n_threads={args.threads}", "repose.replicates=1"]
    cfg = load_config(preset=args.preset, overrides=over)
    if args.layers:
        gaps = cfg["spread"]["gaps"][:args.layers]
        cfg["spread"]["gaps"] = gaps
    out = {"preset": args.preset, "engine": "embedded", "threads": args.threads}
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        rep = run_repose(cfg, out=f"{tmp}/repose")
        out["repose_s"] = round(time.perf_counter() - t0, 2)
        out["repose_particles"] = rep.replicates[0].n_inserted
        out["repose_angle_deg"] = round(rep.angle_deg, 2)
        if not args.skip_spread:
            t0 = time.perf_counter()
            spr = run_spread(cfg, out=f"{tmp}/spread")
            wall = time.perf_counter() - t0
            out["spread_s"] = round(wall, 2)
            out["spread_layers"] = len(spr.layers)
            out["spread_steps"] = spr.extra["steps"]
            out["spread_final_particles"] = spr.extra["n_particles_final"]
    from bedstruct.dem.backends import find_lammps, find_liggghts
    found = {"liggghts": find_liggghts(), "lammps": find_lammps()}
    for eng in ("liggghts", "lammps"):
        if found[eng] is None:
            out[f"{eng}_repose_s"] = "nan"
            continue
        ecfg = load_config(preset=args.preset, overrides=over + [f'engine="{eng}"'])
        if args.layers:
            ecfg["spread"]["gaps"] = ecfg["spread"]["gaps"][:args.layers]
        with tempfile.TemporaryDirectory() as tmp:
            try:
                t0 = time.perf_counter()
                rep = run_repose(ecfg, out=f"{tmp}/repose")
                out[f"{eng}_repose_s"] = round(time.perf_counter() - t0, 2)
                out[f"{eng}_repose_angle_deg"] = round(rep.angle_deg, 2)
                if not args.skip_spread:
                    t0 = time.perf_counter()
                    run_spread(ecfg, out=f"{tmp}/spread")
                    out[f"{eng}_spread_s"] = round(time.perf_counter() - t0, 2)
            except ConfigError as exc:   # e.g. an option the engine does not support
                out[f"{eng}_status"] = f'"{exc}"'.replace(" ", "_")[:60]
    print("RESULT " + " ".join(f"{k}={v}" for k, v in out.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
