"""Diagnose the gap between a simulation and measurements, or validate the diagnosis.

  bedstruct diagnose --sim CONFIG --real MEASUREMENTS --out DIR [--library DIR]
      Where the simulation misses the data, which effect explains it, what to measure next.
  bedstruct diagnose validate [--preset mini|tiny|small] [--simulator surrogate|engine|liggghts]
      Score the diagnosis on synthetic twins (options: bedstruct diagnose validate --help).
  bedstruct diagnose benchmark --out DIR | --score DIR [DIR ...] | --rediagnose DIR [TWIN ...]
      Run, score or replay the blind benchmark (options: bedstruct diagnose benchmark --help).

Details of every option and of the files: docs/diagnose.md.
"""

from __future__ import annotations

import argparse

NAME = "diagnose"
HELP = "sim-to-real gap diagnosis (where, which effect, how far, what next) and its validation"

#: The help of each mode: its description and its one line in ``bedstruct diagnose --help``.
_MODES = {
    "validate": ("score the diagnosis on synthetic twins",
                 "Score the diagnosis on synthetic twins whose cause is known.\n\n"
                 "Details of every option: docs/diagnose-validation.md."),
    "benchmark": ("run, score or replay the blind benchmark",
                  "Run the blind benchmark into --out DIR, score sealed benchmark folders\n"
                  "(--score) or diagnose their twins again (--rediagnose).\n\n"
                  "Details of every option: docs/diagnose-validation.md (Blind benchmark)."),
}


def _whole(text: str, minimum: int) -> int:
    """``text`` as a whole number of at least ``minimum``, else an argparse type error."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a whole number >= {minimum}; got {text!r}") from None
    if n < minimum:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}; got {text!r}")
    return n


def _rounds(text: str) -> int:
    """A number of rounds or seeds: a whole number >= 0."""
    return _whole(text, 0)


def _seed(text: str) -> int:
    """A random seed: a whole number >= 0."""
    return _whole(text, 0)


def _count(text: str) -> int:
    """A number of processes, ranks or repeats: a whole number >= 1."""
    return _whole(text, 1)


def _twins(text: str) -> int:
    """A number of benchmark twins: a whole number >= 4."""
    return _whole(text, 4)


def _shard(text: str) -> tuple[int, int]:
    try:
        k, n = (int(x) for x in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected K/N with integers, e.g. 0/2; got {text!r}") from None
    if not (n >= 1 and 0 <= k < n):
        raise argparse.ArgumentTypeError(f"expected 0 <= K < N; got {text!r}")
    return k, n


#: Every option: flags, argparse keywords and its help in each mode that uses it (one help
#: shared by several modes: ``dict.fromkeys(modes, help)``). Each mode's help lists only its
#: own options; every parser accepts them all, and a mode's run refuses those that do not
#: apply to it (with the reason).
_OPTIONS = [
    (("--sim",), dict(metavar="CONFIG"),
     {"diagnose": "simulation config TOML, or 'surrogate'",
      "validate": "--simulator engine or liggghts: config of the engine",
      "benchmark": "diagnosing simulator: 'surrogate' (default) or a simulation config TOML"}),
    (("--real",), dict(metavar="MEASUREMENTS"), {"diagnose": "measurement TOML file"}),
    (("--out",), dict(metavar="DIR"),
     {"diagnose": "output folder (HTML report and JSON)",
      "validate": "write the validation report and validation.json here",
      "benchmark": "benchmark folder (resumed if it holds this benchmark; another is refused)"}),
    (("--library",), dict(metavar="DIR"),
     {"diagnose": "answer on the emulator of a run library in DIR",
      "benchmark": "diagnose on the emulator of the diagnosing config's run library in DIR"}),
    (("--workers",), dict(type=_count, default=None, metavar="N"),
     dict.fromkeys(("diagnose", "benchmark"), "--library: local processes for the library's runs")),
    (("--scheduler",), dict(metavar="ADDRESS"),
     dict.fromkeys(("diagnose", "benchmark"), "--library: Dask scheduler for the library's runs")),
    (("--preset",), dict(choices=["mini", "tiny", "small"], default=None),
     {"validate": "validation size (default tiny)",
      "benchmark": "workflow preset of a DEM twins engine (default tiny)"}),
    (("--simulator",), dict(choices=["surrogate", "engine", "liggghts"], default=None),
     {"validate": "simulator of the twins (default surrogate)"}),
    (("--twins-engine",), dict(choices=["surrogate", "embedded", "liggghts", "lammps"],
                               default=None),
     {"benchmark": "what makes the twins' data (default surrogate)"}),
    (("--n",), dict(type=_twins, default=None),
     {"benchmark": "number of twins (>= 4; default 40)"}),
    (("--draw",), dict(choices=["detectable", "prior"], default=None),
     {"benchmark": "effect magnitudes the diagnosing model detects (default), or the whole prior"}),
    (("--seed",), dict(type=_seed, default=None),
     {"diagnose": "replicate seed (>= 0; default: the config's)",
      "validate": "seed of the validation (>= 0; default 0)",
      "benchmark": "seed of the draw (>= 0; default 0)"}),
    (("--twin-seed",), dict(type=_seed, default=None),
     {"validate": "seed of the twins only (>= 0)"}),
    (("--campaign",), dict(choices=["seed", "full"], default=None),
     {"validate": "--simulator engine: the twins' measurement design (default seed)"}),
    (("--cache",), dict(metavar="DIR"),
     dict.fromkeys(("diagnose", "validate"), "engine: folder caching every run")),
    (("--jobs",), dict(type=_count, default=None, metavar="N"),
     dict.fromkeys(("diagnose", "validate"), "engine: run engine calls in N processes")),
    (("--np",), dict(type=_count, default=None, metavar="N"),
     {"diagnose": "engine: MPI ranks of each LIGGGHTS or LAMMPS run"}),
    (("--records",), dict(metavar="FILE"),
     {"validate": "record each twin here and resume from it"}),
    (("--records-only",), dict(action="store_true", default=None),
     {"validate": "score the recorded twins, run none"}),
    (("--shard",), dict(metavar="K/N", type=_shard),
     {"validate": "run only twins i with i %% N == K"}),
    (("--twin-jobs",), dict(type=_count, default=None, metavar="N"),
     {"validate": "run the twins in N processes"}),
    (("--twin-repeats",), dict(type=_count, default=None, metavar="R"),
     {"validate": "repeated experiments per twin (default 1)"}),
    (("--refine",), dict(type=_rounds, default=None, metavar="N"),
     dict.fromkeys(("diagnose", "validate"),
                   "rounds simulating the leading effects at their fits")),
    (("--top-up",), dict(type=_rounds, default=None, metavar="N"),
     dict.fromkeys(("diagnose", "validate"), "seeds added where identifiability is marginal")),
    # replaces a diagnosis setting (recorded in the benchmark); for tests, so left out of --help
    (("--diagnose-setting",), dict(action="append", default=None, metavar="KEY=VALUE"), {}),
    (("--score",), dict(nargs="+", metavar="DIR", default=None),
     {"benchmark": "score sealed benchmark folders (together when several); run nothing"}),
    (("--rediagnose",), dict(nargs="+", metavar=("DIR", "TWIN"), default=None),
     {"benchmark": "diagnose a sealed folder's twins again and compare; run nothing"}),
    (("--json",), dict(action="store_true"),
     {"diagnose": "print the answer as one line of JSON instead of in words",
      "validate": "print the scores as one line of JSON instead of the table",
      "benchmark": "print the summary as one JSON line last"}),
    (("--progress",), dict(action="store_true"),
     dict.fromkeys(("diagnose", "validate"), "show progress bars")),
]


def _add_options(parser, mode: str, *, defaults: bool) -> None:
    """Every option on ``parser``, the help shown for those of ``mode`` only.

    Without ``defaults`` (a mode's subparser) an option not given leaves the value that
    ``bedstruct diagnose`` parsed before the mode's name, or its default, as it is.
    """
    for flags, kw, helps in _OPTIONS:
        kw = dict(kw, help=helps.get(mode, argparse.SUPPRESS))
        if not defaults:
            kw["default"] = argparse.SUPPRESS
        parser.add_argument(*flags, **kw)


class _OptionalModeFormatter(argparse.RawDescriptionHelpFormatter):
    """Help formatter whose usage line shows an optional mode as optional: ``[MODE ...]``."""

    def _format_args(self, action, default_metavar):
        text = super()._format_args(action, default_metavar)
        if action.nargs == argparse.PARSER and not action.required:
            return f"[{text}]"
        return text


def add_arguments(parser) -> None:
    """The options of ``bedstruct diagnose`` and its modes ``validate`` and ``benchmark``.

    Each mode is a subparser whose help lists its own options; an option given before
    the mode's name reaches the mode as well. The mode is optional (without one: the
    diagnosis), and the usage line says so.
    """
    parser.formatter_class = _OptionalModeFormatter
    _add_options(parser, "diagnose", defaults=True)
    sub = parser.add_subparsers(dest="action", metavar="MODE", required=False,
                                help="without one: the diagnosis")
    for mode, (line, description) in _MODES.items():
        p = sub.add_parser(mode, help=line, description=description,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("--traceback", action="store_true", default=argparse.SUPPRESS,
                       help="show the full Python traceback on errors")
        _add_options(p, mode, defaults=False)


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
    caveat = None if amortised is None else amortised.caveat
    if args.json:
        extra = {} if amortised is None else {
            "emulator_trusted": amortised.trusted,
            "emulator_loo_rmse_sigma": _short(amortised.loo_rmse_sigma),
            "emulator_loo_within_2sigma": _short(amortised.loo_within_2sigma),
            "emulator_confirm_rmse_sigma": _short(amortised.check.rmse_sigma),
            "emulator_confirm_within_2sigma": _short(amortised.check.within_2sigma),
            "library_runs": amortised.library_runs}
        print_json(to_jsonable(dict(compact_answer(diag, caveat), simulator=diag.simulator,
                               report=str(html), **extra)))
    else:
        for line in answer_lines(diag, caveat=caveat):
            print(line)
        if amortised is not None:
            print(amortised.emulator_line())
            print(amortised.summary_line())
        print(f"Report: {html} (statistics in its appendix; full answer in "
              f"{args.out}/diagnosis.json)")
    return 0
