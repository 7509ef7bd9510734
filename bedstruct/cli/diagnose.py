"""Diagnose the gap between a simulation and measurements, or validate the diagnosis.

  bedstruct diagnose --sim CONFIG --real MEASUREMENTS --out DIR [--library LIB]
      Where the simulation misses the data, which effect explains it, how far the gap
      shrinks, what to measure next (with --library: on a run library's emulator).
  bedstruct diagnose validate --preset mini|tiny|small [--simulator surrogate|engine|liggghts]
  bedstruct diagnose benchmark --twins-engine surrogate|embedded|liggghts|lammps --n N --out DIR
  bedstruct diagnose benchmark --score DIR [DIR ...] | --rediagnose DIR [TWIN ...]

Details of every option and of the files: docs/diagnose.md.
"""

from __future__ import annotations

NAME = "diagnose"
HELP = "sim-to-real gap diagnosis (where, which effect, how far, what next) and its validation"


def add_arguments(parser) -> None:
    parser.add_argument("action", nargs="?", choices=["validate", "benchmark"], default=None,
                        help="'validate': score the diagnosis on synthetic twins; 'benchmark': "
                             "the blind protocol")
    parser.add_argument("--sim", metavar="CONFIG", help="simulation config TOML, or 'surrogate'")
    parser.add_argument("--real", metavar="MEASUREMENTS", help="measurement TOML file")
    parser.add_argument("--out", metavar="DIR", help="output folder (HTML report and JSON)")
    parser.add_argument("--preset", choices=["mini", "tiny", "small"], default=None,
                        help="validation size (default tiny)")
    parser.add_argument("--simulator", choices=["surrogate", "engine", "liggghts"],
                        default=None,
                        help="validate: simulator of the twins (default surrogate)")
    parser.add_argument("--cache", metavar="DIR",
                        help="engine: folder caching every run (overrides [engine] cache)")
    parser.add_argument("--seed", type=int, default=None, help="override the replicate seed")
    parser.add_argument("--twin-seed", type=int, default=None,
                        help="validate: seed of the twins only")
    parser.add_argument("--campaign", choices=["seed", "full"], default=None,
                        help="validate --simulator engine: the twins' measurement design")
    parser.add_argument("--jobs", type=int, default=None, metavar="N",
                        help="engine: run engine calls in N processes")
    parser.add_argument("--np", type=int, default=None, metavar="N",
                        help="engine: MPI ranks of each LIGGGHTS or LAMMPS run")
    parser.add_argument("--records", metavar="FILE",
                        help="validate: record each twin here and resume from it")
    parser.add_argument("--records-only", action="store_true", default=None,
                        help="validate: score the recorded twins, run none")
    parser.add_argument("--shard", metavar="K/N", type=_shard,
                        help="validate: run only twins i with i %% N == K")
    parser.add_argument("--twin-jobs", type=int, default=None, metavar="N",
                        help="validate: run the twins in N processes")
    parser.add_argument("--twin-repeats", type=int, default=None, metavar="R",
                        help="validate: repeated experiments per twin (default 1)")
    parser.add_argument("--refine", type=_rounds, default=None, metavar="N",
                        help="rounds simulating the leading effects at their fits (default: config)")
    parser.add_argument("--top-up", type=_rounds, default=None, metavar="N",
                        help="seeds added where an effect's identifiability is marginal")
    parser.add_argument("--library", metavar="DIR",
                        help="answer on the emulator of a run library in DIR (built once), "
                             "confirmed by one rerun of the simulator")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="--library: local processes for the library's runs")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="--library: Dask distributed scheduler for the library's runs")
    parser.add_argument("--twins-engine", choices=["surrogate", "embedded", "liggghts", "lammps"],
                        default=None, help="benchmark: what makes the twins' data (default surrogate)")
    parser.add_argument("--n", type=int, default=None,
                        help="benchmark: number of twins (>= 4; default 40)")
    parser.add_argument("--draw", choices=["detectable", "prior"], default=None,
                        help="benchmark: effect magnitudes the diagnosing model detects "
                             "(default), or over the whole prior")
    parser.add_argument("--diagnose-setting", action="append", default=None, metavar="KEY=VALUE",
                        help="benchmark: replace a diagnosis setting (tests only; recorded)")
    parser.add_argument("--score", nargs="+", metavar="DIR", default=None,
                        help="benchmark: score sealed benchmark folders (together when several); "
                             "run nothing")
    parser.add_argument("--rediagnose", nargs="+", metavar=("DIR", "TWIN"), default=None,
                        help="benchmark: rediagnose a sealed folder's twins, compare answers")
    parser.add_argument("--json", action="store_true", help="print the answer as one JSON line last")
    parser.add_argument("--progress", action="store_true", help="show progress bars")


def _shard(text: str) -> tuple[int, int]:
    import argparse
    try:
        k, n = (int(x) for x in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected K/N with integers, e.g. 0/2; got {text!r}") from None
    if not (n >= 1 and 0 <= k < n):
        raise argparse.ArgumentTypeError(f"expected 0 <= K < N; got {text!r}")
    return k, n


def _rounds(text: str) -> int:
    import argparse
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0; got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0; got {text!r}")
    return n


def _short(v):
    """A finite number to three significant digits (no float noise), else None."""
    import math
    return float(f"{v:.3g}") if v is not None and math.isfinite(v) else None


def _write_json(path, obj) -> None:
    import json
    from pathlib import Path

    from .._json import to_jsonable
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(to_jsonable(obj), indent=1, allow_nan=False), encoding="utf-8")


#: Options of ``diagnose validate`` alone, with their defaults there.
_VALIDATE_ONLY = {"preset": "tiny", "simulator": "surrogate", "twin_seed": None,
                  "campaign": "seed", "records": None, "shard": None, "twin_repeats": 1,
                  "records_only": False, "twin_jobs": 1}


#: Options of ``bedstruct diagnose benchmark`` alone (None when not given).
_BENCHMARK_ONLY = ("twins_engine", "n", "draw", "diagnose_setting", "score", "rediagnose")


def _misplaced(args, names) -> list[str]:
    return ["--" + n.replace("_", "-") for n in names if getattr(args, n) is not None]


def _run_validate(args) -> int:
    from ..diagnose import validate, validation_report
    from .._json import to_jsonable
    from ..report._render import write_report
    from . import UsageError, print_json

    if args.real:
        raise UsageError("--real is for a diagnosis; validate makes its own measurement files")
    if args.library or args.workers is not None or args.scheduler or args.np is not None:
        raise UsageError("--library/--workers/--scheduler/--np are for a diagnosis, not validate")
    for name, default in _VALIDATE_ONLY.items():
        if getattr(args, name) is None:
            setattr(args, name, default)
    engine = None
    if args.simulator in ("engine", "liggghts"):
        from ..diagnose.validation.design import engine_scale_model
        engine = {"preset": engine_scale_model(args.preset)}
        if args.sim:
            from ..diagnose import load_sim_config
            engine = dict(load_sim_config(args.sim).engine) or engine
        if args.cache:
            engine["cache"] = args.cache
        if args.jobs is not None:
            engine["jobs"] = args.jobs
    elif args.sim or args.cache or args.jobs is not None:
        raise UsageError("--sim/--cache/--jobs with validate need --simulator engine or liggghts")
    result = validate(args.preset, seed=args.seed or 0, progress=args.progress,
                      simulator=args.simulator, engine=engine, twin_seed=args.twin_seed,
                      campaign=args.campaign, records=args.records, shard=args.shard,
                      twin_repeats=args.twin_repeats, records_only=args.records_only,
                      refine=args.refine, top_up=args.top_up, twin_jobs=args.twin_jobs)
    out = result.to_json()
    if args.out:
        write_report(validation_report(result), args.out)
        _write_json(f"{args.out}/validation.json", out)
    if args.json:
        compact = {k: v for k, v in out.items() if k != "twins"}
        print_json(to_jsonable(compact))
    else:
        failed = result.settings.get("failed") or []
        not_run = result.settings.get("not_run") or []
        print(f"validation ({result.preset}, simulator = {result.simulator}; twins: {len(result.twins)}"
              + (f", failed: {len(failed)}" if failed else "")
              + (f", not run: {len(not_run)}" if not_run else "") + ")")
        for k, g in result.goals.items():
            over = (f"  (over {g['n_twins']} twins with a held-out gap; "
                    f"{g['n_no_heldout_gap']} without)" if g.get("n_no_heldout_gap") else "")
            print(f"  {k:30s} {g['value']:.3f}   goal {g['goal']:8s} "
                  f"{'met' if g['met'] else 'NOT MET'}{over}")
        print(f"  {'null_gap_flagged':30s} {result.null_gap_flagged:.3f}")
        print(f"  {'median_gap_shrink_rms':30s} {result.median_gap_shrink_rms:.3f}")
        print(f"  {'magnitude_coverage':30s} {result.magnitude_coverage:.3f}")
        ident = result.identifiable
        if ident.get("not_identifiable"):
            print(f"  identifiable effects only (not: {', '.join(ident['not_identifiable'])}): "
                  f"top1 {ident['top1_accuracy']:.3f}, "
                  f"out-of-catalogue unexplained {ident['out_of_catalogue_unexplained']:.3f}")
        det = result.detected
        if det.get("n_effect_twins_undetected"):
            print(f"  twins with a significant gap only ({det['n_effect_twins_undetected']} effect "
                  f"twin(s) without): top1 {det['top1_accuracy']:.3f}, "
                  f"out-of-catalogue unexplained {det['out_of_catalogue_unexplained']:.3f}")
        from ..diagnose.validation.scores import capped_summary
        capped = capped_summary(result.twins, sigma=" sigma")
        if capped:
            print(f"  effect twins held at the prior top below the drawn gap: {capped}")
        for name, why in (result.settings.get("unobservable") or {}).items():
            print(f"  missing data: {name} dropped ({why})")
    return 0


def run(args) -> int:
    if args.action == "validate":
        return _run_validate(args)
    if args.action == "benchmark":
        from ..diagnose.validation.blind import run_benchmark_command
        return run_benchmark_command(args)
    import dataclasses

    from . import UsageError

    missing = [f"--{k}" for k in ("sim", "real", "out") if not getattr(args, k)]
    if missing:
        raise UsageError(f"missing {', '.join(missing)} (usage: bedstruct diagnose --sim CONFIG "
                         f"--real MEASUREMENTS --out DIR)")
    misplaced = _misplaced(args, _VALIDATE_ONLY)
    if misplaced:
        raise UsageError(f"{', '.join(misplaced)} appl{'ies' if len(misplaced) == 1 else 'y'} "
                         "to 'bedstruct diagnose validate' only")
    misplaced = _misplaced(args, _BENCHMARK_ONLY)
    if misplaced:
        raise UsageError(f"{', '.join(misplaced)} appl{'ies' if len(misplaced) == 1 else 'y'} "
                         "to 'bedstruct diagnose benchmark' only")
    from ..diagnose import (diagnose, diagnosis_design, diagnosis_report, load_measurements,
                            load_sim_config, make_simulator)
    from ..diagnose.answer import answer_lines, compact_answer
    from .._json import to_jsonable
    from ..report._render import write_report
    from . import print_json

    cfg = load_sim_config(args.sim)
    given = [f"--{n}" for n in ("jobs", "cache", "np") if getattr(args, n) not in (None, "")]
    if given and cfg.kind != "engine":
        raise UsageError(f"{', '.join(given)} need{'s' if len(given) == 1 else ''} a simulation "
                         f"config with kind = \"engine\"")
    if args.np is not None:
        cfg = dataclasses.replace(cfg, engine=dict(cfg.engine, np=args.np))
    if args.jobs is not None:
        cfg = dataclasses.replace(cfg, engine=dict(cfg.engine, jobs=args.jobs))
    if args.cache:
        cfg = dataclasses.replace(cfg, engine=dict(cfg.engine, cache=args.cache))
    if args.refine is not None:  # recorded in the output's sim_config
        cfg = dataclasses.replace(cfg, refine=args.refine)
    if args.top_up is not None:
        cfg = dataclasses.replace(cfg, top_up=args.top_up)
    ms = load_measurements(args.real)
    design = diagnosis_design(ms, cfg.effects)
    sim = make_simulator(cfg, design)
    settings = cfg.diagnose_settings(seed=args.seed)
    amortised = None
    if args.library:
        from ..diagnose.amortised import diagnose_with_library
        amortised = diagnose_with_library(
            ms, sim, base=cfg.base, library=args.library, workers=args.workers or 1,
            scheduler=args.scheduler, progress=args.progress, **cfg.library_settings(),
            bridge=cfg.bridge or None, engine=cfg.engine, **settings)
        diag = amortised.diagnosis
    elif args.workers is not None or args.scheduler:
        raise UsageError("--workers/--scheduler build a run library: give --library DIR")
    else:
        if cfg.bridge:
            from ..diagnose.bridge import engine_bridge
            settings["bridge"] = engine_bridge(ms, sim, base=cfg.base, bridge=cfg.bridge,
                                               engine=cfg.engine, effects=cfg.effects,
                                               progress=args.progress)
        diag = diagnose(ms, sim, base=cfg.base, effects=cfg.effects, nuisance=cfg.nuisance,
                        progress=args.progress, **settings)
    out = diag.to_json()
    out["sim_config"] = cfg.as_dict()
    if amortised is not None:
        out["emulator"] = amortised.to_json()
    html, js = write_report(diagnosis_report(diag, amortised=amortised), args.out)
    _write_json(f"{args.out}/diagnosis.json", out)
    if args.json:
        extra = {} if amortised is None else {
            "emulator_confirm_rmse_sigma": _short(amortised.check.rmse_sigma),
            "emulator_confirm_within_2sigma": _short(amortised.check.within_2sigma),
            "library_runs": amortised.library_runs}
        print_json(to_jsonable(dict(compact_answer(diag), simulator=diag.simulator,
                               report=str(html), **extra)))
    else:
        for line in answer_lines(diag):
            print(line)
        if amortised is not None:
            print(amortised.summary_line())
        print(f"Report: {html} (statistics in its appendix; full answer in "
              f"{args.out}/diagnosis.json)")
    return 0
