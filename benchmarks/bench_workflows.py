"""Benchmark: the workflows (angle of repose, multi-layer spreading) of a preset on every engine.

Runs one repose replicate and the spreading workflow of the preset (default
``small``; ``--preset tiny`` for a quick check) on the embedded engine, and
times the same workflows on LIGGGHTS and LAMMPS when installed (``nan`` otherwise),
through the decks the workflows generate. Run::

    python benchmarks/bench_workflows.py [--preset small] [--layers N] [--threads 1]
    python benchmarks/bench_workflows.py --seed-steps 200     # the seed preset: extrapolate

``--seed-steps N`` times N steps (after 20 untimed ones) of the ``seed`` preset's
repose box as inserted (105,000 spheres) on each engine, one thread / one rank, and
extrapolates to its whole repose replicate and to one spreading layer of its
18.9 mm plate (``RESULT preset=seed seed_particles=... dt=... repose_steps=...
spread_steps_per_layer=... embedded_s_per_step=... embedded_repose_h=...
embedded_spread_h_per_layer=... liggghts_... lammps_... ratio_liggghts=...
ratio_lammps=...``; the ratios are the embedded engine's seconds per step over the
external engine's ``Loop time`` per step). The inserted state is
loose (few contacts): a lower bound on the cost of a settled bed
(docs/validation.md, "The seed preset: time per run").

``--diagnosis-call`` times one engine call of the diagnosis (``bedstruct diagnose
validate --simulator engine``): the validation twin design on the preset's scale model,
its reposes and three spreading runs sharing one pile, embedded engine only: the
diagnosis's extensions have no LIGGGHTS/LAMMPS deck, so this mode times **no external
engine and has no ratio**; it says so in its RESULT line (``RESULT preset=...
diagnosis_call_s=... workflow_runs=... rebuilds=... steps=... ratio_liggghts=nan
ratio_lammps=nan external=none``).

Otherwise ends with ``RESULT preset=... engine=embedded repose_s=... repose_particles=...
spread_s=... spread_layers=... spread_steps=... spread_final_particles=... liggghts_repose_s=...
liggghts_spread_s=... lammps_repose_s=... lammps_spread_s=... ratio_repose_liggghts=...
ratio_spread_liggghts=... ratio_repose_lammps=... ratio_spread_lammps=...``, the ratios
being the embedded engine's wall time over the external engine's for the same workflow
(below 1: the embedded engine is faster; nan where an engine is not installed or not run).
Both sides time the whole workflow call (the external side includes writing the deck,
starting the engine and reading its dumps back).
Timings include numba compilation on the first call unless the cache is warm;
on a shared machine they are indicative only.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time


def _ratio(a, b) -> str:
    """``a / b`` to 3 digits, or nan when either is missing or not a positive number."""
    try:
        a, b = float(a), float(b)
    except (TypeError, ValueError):
        return "nan"
    return f"{a / b:.3g}" if b > 0 and not (math.isnan(a) or math.isnan(b)) else "nan"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="small")
    p.add_argument("--layers", type=int, default=None, help="spread only the first N layers")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--skip-spread", action="store_true")
    p.add_argument("--seed-steps", type=int, default=0,
                   help="time N steps of the seed preset's repose box per engine and extrapolate")
    p.add_argument("--diagnosis-call", action="store_true",
                   help="time one engine call of the diagnosis at the preset's scale model")
    args = p.parse_args(argv)
    if args.seed_steps > 0:
        return seed_timing(args.seed_steps)
    if args.diagnosis_call:
        return diagnosis_call_timing(args.preset, args.threads)

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
    from bedstruct.engines import find_lammps, find_liggghts
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
    for eng in ("liggghts", "lammps"):  # embedded wall time over the external engine's
        out[f"ratio_repose_{eng}"] = _ratio(out.get("repose_s"), out.get(f"{eng}_repose_s"))
        out[f"ratio_spread_{eng}"] = _ratio(out.get("spread_s"), out.get(f"{eng}_spread_s"))
    print("RESULT " + " ".join(f"{k}={v}" for k, v in out.items()))
    return 0


def diagnosis_call_timing(preset: str, threads: int) -> int:
    """Time one uncached engine call of the diagnosis (base parameters, seed 1)."""
    from bedstruct.dem import Simulation
    from bedstruct.diagnose.validation.design import engine_scale_model, engine_twin_design
    from bedstruct.diagnose.engine_simulator import diagnosis_simulator

    sim = diagnosis_simulator(engine_twin_design(),
                              {"preset": engine_scale_model(preset), "n_threads": threads})
    counts = {"rebuilds": 0, "steps": 0}
    run = Simulation.run

    def counted(self, *a, **k):   # count the engine's steps and rebuilds of every run
        stats = run(self, *a, **k)
        counts["rebuilds"] += stats.n_rebuilds
        counts["steps"] += stats.n_steps
        return stats

    Simulation.run = counted
    try:
        t0 = time.perf_counter()
        sim({"cohesion_energy_density": 3.6e7}, {}, 1)
        wall = time.perf_counter() - t0
    finally:
        Simulation.run = run
    print("# no external engine timed: the diagnosis's extensions have no LIGGGHTS/LAMMPS deck, "
          "so this mode has no ratio")
    print(f"RESULT preset={preset} engine=embedded threads={threads} "
          f"diagnosis_call_s={wall:.1f} workflow_runs={sim.n_runs} "
          f"rebuilds={counts['rebuilds']} steps={counts['steps']} "
          f"ratio_liggghts=nan ratio_lammps=nan external=none")
    return 0


def seed_timing(steps: int) -> int:
    """Time ``steps`` steps of the seed preset's repose box on each engine; extrapolate."""
    import re
    from pathlib import Path

    from bedstruct.core import Box
    from bedstruct.dem import Plane, Simulation
    from bedstruct.engines import find_lammps, find_liggghts, run_deck
    from bedstruct.workflows import load_config
    from bedstruct.workflows._common import contact_model
    from bedstruct.workflows.external import repose_inputs, run_repose_external

    cfg = load_config(preset="seed", overrides=["n_threads=1"])
    inp = repose_inputs(cfg, seed=1)
    dt = inp["dt"]
    rc, sc = cfg["repose"], cfg["spread"]
    n_repose = (rc["fill_time"] + rc["box"][0] / rc["plate_speed"] + rc["drain_time"]) / dt
    n_layer = ((sc["plate_length"] + sc["stop_margin"]) / sc["speed"]
               + 2 * sc["settle_time"] + sum(sc["gaps"]) / len(sc["gaps"]) / sc["lower_speed"]) / dt
    out = {"preset": "seed", "seed_particles": len(inp["radii"]), "dt": f"{dt:.4g}",
           "repose_steps": int(n_repose), "spread_steps_per_layer": int(n_layer)}
    per_step = {}
    box = Box(inp["box_lo"], inp["box_hi"], boundary=("ff", "ff", "ff"))
    sim = Simulation(box, contact_model(cfg), walls=[Plane((0, 0, 0), (0, 0, 1), name="plate")],
                     safety=cfg["time"]["safety"], v_max=cfg["time"]["v_max"],
                     min_radius=float(inp["radii"].min()), n_threads=1, seed=1)
    sim.add_particles(inp["positions"], inp["radii"])
    sim.run(steps=20)
    t0 = time.perf_counter()
    sim.run(steps=steps)
    per_step["embedded"] = (time.perf_counter() - t0) / steps
    found = {"liggghts": find_liggghts(), "lammps": find_lammps()}
    for eng in ("liggghts", "lammps"):
        if found[eng] is None:
            continue
        over = [f"engine={eng}", "external.write_only=true", "repose.replicates=1"]
        if eng == "lammps":
            over.append("external.cohesion_model=none")    # LAMMPS has no SJKR
        with tempfile.TemporaryDirectory() as tmp:
            res = run_repose_external(load_config(preset="seed", overrides=over), out=tmp)
            deck = Path(res.decks[0])
            text = deck.read_text()
            first = re.search(r"^run \d+$", text, flags=re.M).start()
            body = re.sub(r"^dump .*$", "", text[:first], flags=re.M)
            (deck.parent / "in.time").write_text(body + f"run 20\nrun {steps}\n")
            log = run_deck(deck.parent / "in.time", np=1, cwd=deck.parent).log
            per_step[eng] = log.last.loop_time / steps
    for eng, sps in per_step.items():
        out[f"{eng}_s_per_step"] = f"{sps:.4g}"
        out[f"{eng}_repose_h"] = round(sps * n_repose / 3600, 2)
        out[f"{eng}_spread_h_per_layer"] = round(sps * n_layer / 3600, 2)
    for eng in ("liggghts", "lammps"):  # embedded s/step over the external engine's
        out[f"ratio_{eng}"] = _ratio(per_step["embedded"], per_step.get(eng))
    print("RESULT " + " ".join(f"{k}={v}" for k, v in out.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
