"""Proof on synthetic twins whose effect is withheld from the diagnosis.

Each twin's "real" data come from one simulator run with an effect at a
magnitude the diagnosis is not told (and a slightly different cohesion), plus
measurement noise drawn from the stated uncertainties; the twin is written as a
measurement TOML file and read back, so the diagnosis sees only that file.
Three kinds of twins: in-catalogue (the true effect must rank first), null (no
effect: nothing may be attributed) and out-of-catalogue (the true effect is
removed from the catalogue: the answer must be "unexplained").

Validation runs on the analytic
:class:`~bedstruct.diagnose.surrogate.SurrogateSimulator` (``simulator =
"surrogate"``, the default: seconds) or on the embedded DEM engine
(``simulator = "engine"``, :func:`bedstruct.diagnose.engine_simulator.diagnosis_simulator`, on
:func:`engine_twin_design` with :data:`ENGINE_PRESETS`: minutes to hours), or on
twins made by LIGGGHTS and diagnosed on the engine (``simulator = "liggghts"``,
:mod:`bedstruct.diagnose.validation.liggghts`), and every result says which.

.. versionadded:: 0.1
"""

from __future__ import annotations

import logging
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ...errors import ConfigError
from ..catalogue import catalogue as _catalogue
from ..diagnosis import diagnose, diagnosis_design
from ..fingerprint_runs import compute_fingerprints
from ..measurements import MeasurementSet
from ..separation import not_told_apart
from ..surrogate import BASE_PARAMETERS, SurrogateSimulator
from .twins import (_intrinsic_sd, _projected_gap, _size_twin, _twin_measurements,
                    _twin_plan, _twin_sigma)
from .parallel import run_twins_in_processes
from .design import engine_scale_model, engine_twin_design, twin_design
from .records import METHOD_VERSION, records_done, twin_record
from .scores import ValidationResult, score_twins

__all__ = ["PRESETS", "ENGINE_PRESETS", "validate"]

log = logging.getLogger(__name__)

#: Twin counts and replicate seeds per preset.
PRESETS = {
    "tiny": dict(per_effect=2, null=4, out_of_catalogue=2, replicates=3),
    "small": dict(per_effect=10, null=60, out_of_catalogue=3, replicates=4),
}
#: Twin counts and replicate seeds per preset on the DEM engine (``simulator="engine"``):
#: one engine call costs ~10-60 s on one core, so the engine presets are much smaller.
#: ``top_up``: seeds added for the base and the effects whose identifiability is marginal
#: after ``replicates`` (:func:`compute_fingerprints`).
ENGINE_PRESETS = {
    "mini": dict(per_effect=0, null=1, out_of_catalogue=0, replicates=2, effects=("wall_friction",)),
    # top_up=2: on two seeds wall friction's identifiability and contact ageing's (its signal
    # on one run) were both judged wrongly at tiny; on four both come out as the twins show.
    "tiny": dict(per_effect=1, null=1, out_of_catalogue=0, replicates=2, top_up=2,
                 effects=("wall_friction", "capillary_bridges", "contact_ageing", "blade_startup")),
    "small": dict(per_effect=2, null=4, out_of_catalogue=0, replicates=3, top_up=3,
                  effects=("wall_friction", "capillary_bridges", "contact_ageing", "blade_startup",
                           "non_sphericity")),
}


def _fingerprint_settings(fps) -> dict:
    """A validation's settings that come from its fingerprints (``None`` when scored from records)."""
    if fps is None:
        return {"top_up": None, "unobservable": None, "missing_runs": None,
                "uneven_scatter": None, "scored_from_records": True}
    return {"top_up": {"seeds": list(fps.top_up_seeds), "effects": {
                name: dict(fps.meta["top_up"][name], signal_after=fps[name].signal,
                           signal_se_after=fps[name].signal_se,
                           identifiable_after=fps[name].identifiable)
                for name in fps.topped_up}},
            "unobservable": dict(fps.meta.get("unobservable", {})),
            "missing_runs": dict(fps.meta.get("missing_runs", {})),
            "uneven_scatter": dict(fps.meta.get("uneven_scatter", {}))}


def validate(preset: str = "tiny", *, seed: int = 0, alpha: float = 0.05, select_alpha: float = 0.01,
             gof_alpha: float = 0.01, snr_range: tuple[float, float] = (5.0, 10.0),
             simulator: str = "surrogate", engine: dict | None = None, refine: int | None = None,
             twin_seed: int | None = None, records=None, campaign: str = "seed",
             shard: tuple[int, int] | None = None, twin_repeats: int = 1,
             records_only: bool = False, top_up: int | None = None, twin_jobs: int = 1,
             progress: bool = False,
             on_status: Callable[[str], None] | None = None) -> ValidationResult:
    """Run the twin validation on the surrogate simulator or the DEM engine.

    Parameters
    ----------
    preset : {"tiny", "small"} (engine also "mini")
        Number of twins and replicate seeds (see :data:`PRESETS`, :data:`ENGINE_PRESETS`).
    seed : int
        Seed of twin magnitudes, noise and replicate runs.
    snr_range : (float, float)
        Each effect twin's magnitude is set so that its gap on the calibration
        observables, after recalibration, is ``U(*snr_range)`` sigma: twins test
        discrimination at a stated detectability, not the arbitrary width of a
        prior range. Weaker gaps are the identifiability report's business.
    simulator : {"surrogate", "engine", "liggghts"}
        ``"engine"`` runs :func:`bedstruct.diagnose.engine_simulator.diagnosis_simulator` on
        :func:`engine_twin_design`. Each in-catalogue engine twin is diagnosed a
        second time with its effect removed from the catalogue (the
        out-of-catalogue twin), which reuses its runs. ``"liggghts"`` makes the twins
        with LIGGGHTS and diagnoses them on the engine
        (:func:`~bedstruct.diagnose.validation.liggghts.validate_liggghts`; preset
        ``tiny``; with ``engine["cache"]`` the twins are kept in its ``liggghts-twins/``).
    engine : dict, optional
        The ``[engine]`` table (default: the scale model of the same name,
        ``{"preset": "small"}`` for ``small``, else ``{"preset": "tiny"}``); give ``cache`` to
        keep every run on disk (reruns and other diagnoses of the same design reuse it).
    refine : int, optional
        Refinement rounds of each diagnosis (default 2 on the surrogate, 1 on the engine).
    twin_seed : int, optional
        Seed of the twins only (magnitudes, truth runs, noise; default ``seed``): a
        further batch of twins on the same (cached) fingerprints.
    records : path, optional
        JSON-lines file to which each twin's record is appended as it completes
        (score a partial run with :func:`score_twins`). Records already in the file
        from a run of the same validation (preset, simulator, campaign, seeds, statistics
        settings) are
        taken as done, not rerun: an interrupted validation resumes, and shards
        merged into one file (``cat``) are scored by running once more on it.
    shard : (int, int), optional
        ``(k, n)``: run only the twins whose index ``i`` has ``i % n == k`` (magnitudes
        and truth runs stay those of the whole plan), to split one validation over
        ``n`` processes or machines that share the engine cache.
    campaign : {"seed", "full"}
        Engine twins: the seed's measurement design (default) or the full campaign
        that adds the catalogue's candidate measurements (:func:`engine_twin_design`).
        The surrogate's :func:`twin_design` is a full campaign already.
    records_only : bool
        Score the twins already in ``records`` and run none (the table of a partial or
        sharded run; the others are listed in ``settings["not_run"]``). Records state
        their fingerprints' identifiability, so they are scored without a simulator;
        only records written before they did (no ``fingerprint_identifiable``) need the
        fingerprints computed, from the engine's cache that holds them.
    top_up : int, optional
        Fingerprint seeds added for the base and every effect whose identifiability is
        marginal after the preset's replicates (default: the preset's ``top_up``, 0 where
        it names none; see :data:`ENGINE_PRESETS`).
    twin_repeats : int
        Repeated experiments per twin (default 1): its file states their mean and standard
        error, as a lab that repeats each test reports it. Twins are sized in that noise,
        so an effect that its prior caps below the drawn gap in one experiment can reach
        it in several; each repeat is one more simulator call per twin.
    twin_jobs : int
        Run the twins in this many processes, one twin each at a time
        (:func:`~bedstruct.diagnose.validation.parallel.run_twins_in_processes`; default 1:
        in this process). The fingerprints are computed first, here; on the engine the
        workers read them back from ``engine["cache"]``, which is then required. Records
        go to ``records`` as each twin finishes (a temporary file without it). Not with
        ``shard`` or ``records_only``.
    progress : bool
        Progress bars (fingerprint calls, twins; the running twin and its engine calls so far
        beside the twins' bar).
    on_status : callable, optional
        Called with a one-line status of the running twin as it changes (``"twin 3
        (capillary_bridges): 5 engine calls, 17 min"``), for callers that show progress their
        own way (the worker processes of ``twin_jobs`` report through it).

    Returns
    -------
    ValidationResult
    """
    if simulator == "liggghts":
        # twins from another code: their own plan and preset table, same records and scores
        from .liggghts import validate_liggghts
        if (campaign != "seed" or shard is not None or twin_repeats != 1 or twin_seed is not None
                or records_only or top_up is not None or int(twin_jobs) != 1):
            raise ConfigError("simulator='liggghts': campaign, shard, twin_repeats, twin_seed, "
                              "records_only, top_up and twin_jobs are for the engine's twins; "
                              "LIGGGHTS twins follow liggghts_twin_plan")
        workdir = Path(engine["cache"]) / "liggghts-twins" if engine and engine.get("cache") else None
        return validate_liggghts(preset, seed=seed, engine=engine, workdir=workdir, records=records,
                                 alpha=alpha, select_alpha=select_alpha, gof_alpha=gof_alpha,
                                 refine=1 if refine is None else refine, progress=progress)
    if simulator not in ("surrogate", "engine"):
        raise ConfigError(f"simulator: expected 'surrogate', 'engine' or 'liggghts'; got {simulator!r}")
    table = PRESETS if simulator == "surrogate" else ENGINE_PRESETS
    if preset not in table:
        raise ConfigError(f"preset: expected one of {sorted(table)} for the {simulator}; got {preset!r}")
    cfg = table[preset]
    if campaign not in ("seed", "full"):
        raise ConfigError(f"campaign: expected 'seed' or 'full'; got {campaign!r}")
    if simulator == "surrogate" and campaign != "seed":
        raise ConfigError("campaign: the surrogate's twin design is a full campaign already; "
                          "campaign='full' is for simulator='engine'")
    if shard is not None:
        k_shard, n_shard = (int(x) for x in shard)
        if not (n_shard >= 1 and 0 <= k_shard < n_shard):
            raise ConfigError(f"shard: expected (k, n) with 0 <= k < n; got {tuple(shard)!r}")
    if int(twin_repeats) != twin_repeats or twin_repeats < 1:
        raise ConfigError(f"twin_repeats: expected a whole number >= 1; got {twin_repeats!r}")
    twin_repeats = int(twin_repeats)
    if records_only and records is None:
        raise ConfigError("records_only: give the records file whose twins to score")
    if top_up is None:
        top_up = int(cfg.get("top_up", 0))
    elif int(top_up) != top_up or top_up < 0:
        raise ConfigError(f"top_up: expected a whole number >= 0; got {top_up!r}")
    top_up = int(top_up)
    if refine is None:
        # one round on the engine: each costs a call per fingerprint seed for every diagnosis
        # with a leading effect, and one rescued a small capillary twin without making any
        # twin wrong (docs/diagnose-validation.md)
        refine = 2 if simulator == "surrogate" else 1
    t0 = time.perf_counter()
    effects = _catalogue(cfg.get("effects"))
    tseed = int(seed if twin_seed is None else twin_seed)
    # everything that changes a twin's record: records of another validation are not reused
    signature = {"preset": preset, "simulator": simulator, "campaign": campaign, "seed": int(seed),
                 "twin_seed": tseed, "alpha": alpha, "select_alpha": select_alpha,
                 "gof_alpha": gof_alpha, "refine": int(refine),
                 "snr_range": [float(x) for x in snr_range], "method_version": METHOD_VERSION,
                 "twin_repeats": twin_repeats, "top_up": top_up}
    if int(twin_jobs) != twin_jobs or twin_jobs < 1:
        raise ConfigError(f"twin_jobs: expected a whole number >= 1; got {twin_jobs!r}")
    twin_jobs = int(twin_jobs)
    if twin_jobs > 1:
        if shard is not None or records_only:
            raise ConfigError("twin_jobs: runs the whole plan's twins in processes; not with "
                              "shard or records_only")
        if simulator == "engine" and not (engine or {}).get("cache"):
            raise ConfigError("twin_jobs: the twin processes read the fingerprints back from the "
                              "engine cache; give [engine] cache (CLI: --cache DIR)")
        if records is None:
            tmp_records = tempfile.TemporaryDirectory(prefix="bedstruct-validate-")
            records = Path(tmp_records.name) / "records.jsonl"
    done = records_done(records, signature)
    # records that state their fingerprints' identifiability are scored without a simulator
    offline = records_only and all("fingerprint_identifiable" in r for r in done.values())
    base = dict(BASE_PARAMETERS)
    sim = fps = None
    if simulator == "surrogate":
        measured = twin_design()
        design = diagnosis_design(measured, effects)
        sim = SurrogateSimulator(design)
    elif not offline:
        from ..engine_simulator import diagnosis_simulator
        measured = engine_twin_design(campaign)
        # with the whole catalogue's candidate measurements (one humid repose more per call),
        # so that a diagnosis of any measurement file of this design finds every run cached
        design = diagnosis_design(measured, _catalogue())
        sim = diagnosis_simulator(design, dict(engine or {"preset": engine_scale_model(preset)}))
    if not offline:
        fps = compute_fingerprints(sim, design, base, effects, replicates=cfg["replicates"],
                                   seed=seed, top_up=top_up, alpha=select_alpha,
                                   simulator_name=simulator, progress=progress)
        identifiable = {f.name: bool(f.identifiable) for f in fps.fingerprints}
        intrinsic = sim.noise_sd() if simulator == "surrogate" else _intrinsic_sd(fps)
        # twins are sized in the noise their own diagnosis sees (their files state one run's
        # scatter on top of the reading noise), not in the design's reading noise alone
        twin_sigma = _twin_sigma(fps, intrinsic, twin_repeats)
        if fps.meta.get("unobservable"):  # the simulator cannot give them: no twin measures them
            measured = MeasurementSet(tuple(m for m in measured if m.name in fps.names),
                                      measured.title, measured.source, measured.path,
                                      measured.notes)
    else:
        identifiable = {}
        for r in done.values():
            identifiable.update(r["fingerprint_identifiable"])
    rng = np.random.default_rng([tseed, 2024])
    reuse_ooc = simulator == "engine"
    plan = _twin_plan([e.name for e in effects], cfg, in_turn=reuse_ooc)
    n_in_processes, n_resumed = 0, len(done)
    if twin_jobs > 1:
        kinds_of = lambda kind: [kind] + (["out_of_catalogue"]  # noqa: E731
                                          if reuse_ooc and kind == "effect" else [])
        todo = [i for i, (kind, _) in enumerate(plan)
                if any((i, k) not in done for k in kinds_of(kind))]
        n_in_processes = run_twins_in_processes(
            validate, dict(preset=preset, seed=seed, alpha=alpha, select_alpha=select_alpha,
                 gof_alpha=gof_alpha, snr_range=tuple(snr_range), simulator=simulator,
                 engine=engine, refine=refine, twin_seed=tseed, campaign=campaign,
                 twin_repeats=twin_repeats, top_up=top_up),
            todo, len(plan), records, twin_jobs, progress=progress)
        # every twin is recorded now: the loop below scores them
        done = records_done(records, signature)

    twins, failed, not_run = [], [], []
    iterator = enumerate(plan)
    if progress:
        from tqdm import tqdm
        iterator = tqdm(list(iterator), desc="twins")

    def run_one(i, kind, name, real, truth):
        cat = tuple(x for x in effects if not (kind == "out_of_catalogue" and x.name == name))
        diag = diagnose(real, sim, base=base, effects=cat, replicates=cfg["replicates"], seed=seed,
                        alpha=alpha, select_alpha=select_alpha, gof_alpha=gof_alpha,
                        fingerprints=fps, refine=refine, simulator_name=simulator)
        twins.append(twin_record(diag, i, kind, signature, truth, records=records,
                                 identifiable=identifiable))

    with tempfile.TemporaryDirectory(prefix="bedstruct-twins-") as tmp:
        folder = Path(tmp)
        for i, (kind, name) in iterator:
            base_true = dict(base)
            base_true["cohesion_energy_density"] *= 1.0 + rng.uniform(-0.02, 0.02)
            snr = float(rng.uniform(*snr_range)) if name is not None else None
            twin_run_seed = tseed * 100003 + 5000 + i
            if shard is not None and i % n_shard != k_shard:
                continue  # another shard's twin (its draws above keep the plan's)
            kinds = [kind] + (["out_of_catalogue"] if reuse_ooc and kind == "effect" else [])
            todo = [k for k in kinds if (i, k) not in done]
            twins.extend(done[(i, k)] for k in kinds if (i, k) in done)
            if not todo:
                continue
            if records_only:
                not_run.extend({"twin": i, "type": k, "true_effect": name} for k in todo)
                continue
            if progress or on_status is not None:
                # a twin takes hours at the engine presets: say which one runs
                label = f"twin {i} ({name or 'null'})"

                def announce(text, bar=iterator if progress else None):
                    if bar is not None:
                        bar.set_postfix_str(text, refresh=True)
                    if on_status is not None:
                        on_status(text)
                announce(label)
                if hasattr(sim, "on_call"):  # and how many engine calls it has run so far
                    sim.on_call = lambda s, label=label, c0=sim.n_calls, t0=time.perf_counter(), \
                        announce=announce: announce(
                            f"{label}: {s.n_calls - c0} engine call{'' if s.n_calls - c0 == 1 else 's'}, "
                            f"{(time.perf_counter() - t0) / 60:.0f} min")
            truth = {"true_effect": name, "true_magnitude": None,
                     "true_cohesion": base_true["cohesion_energy_density"]}
            try:
                effects_true, magnitude, own_fps = {}, None, fps
                if name is not None:
                    # in the noise the twin's file will state, at the twin's own magnitude
                    def noise(f, a, e=name):
                        return twin_sigma if simulator == "surrogate" else \
                            _twin_sigma(f, _intrinsic_sd(f, e, a), twin_repeats)
                    magnitude, own_fps, node = _size_twin(sim, fps, name, snr, noise)
                    effects_true = {name: magnitude}
                    # below the draw when the prior top is weaker: such a twin is scored as
                    # drawn, and its record says how strong it could be
                    own_sigma = lambda a: noise(own_fps, a)  # noqa: E731
                    truth.update(true_magnitude=magnitude, requested_gap_sigma=snr,
                                 twin_gap_sigma=_projected_gap(own_fps, name, own_sigma)(magnitude),
                                 twin_gap_debiased_sigma=_projected_gap(
                                     own_fps, name, own_sigma, debias=True)(magnitude),
                                 **node)
                # one run's scatter at the twin's point, its sizing node's where those runs
                # scattered unlike the base (the replicate scatter an experimenter would state)
                own = intrinsic if simulator == "surrogate" else \
                    _intrinsic_sd(own_fps, name, magnitude)
                real = _twin_measurements(measured, sim, base_true, effects_true, twin_run_seed,
                                          folder, i, own, twin_repeats)
                for k in todo:
                    run_one(i, k, name, real, truth)
            except (ValueError, np.linalg.LinAlgError) as exc:
                if simulator == "surrogate":
                    raise
                # an engine run without a measurable observable: recorded, not scored
                log.warning("twin %d (%s %s) failed: %s", i, kind, name, exc)
                failed.append({"twin": i, "type": kind, **truth, "error": str(exc)[:500]})

    sc = score_twins(twins, [e.name for e in effects],
                     removed_rows=bool(cfg["out_of_catalogue"] or reuse_ooc),
                     identifiable=identifiable or None)
    settings = {"replicates": cfg["replicates"], "per_effect": cfg["per_effect"], "null": cfg["null"],
                "out_of_catalogue_per_effect": cfg["out_of_catalogue"] or (
                    "each effect twin, its effect removed" if reuse_ooc else 0),
                "effects": [e.name for e in effects], "refine": refine,
                **_fingerprint_settings(fps),
                "failed": failed, "not_run": not_run,
                "simulator_runs": getattr(sim, "n_runs", None),
                "cached_calls": getattr(sim, "n_cached", None),
                "engine": dict(getattr(sim, "base_cfg", {}) and {
                    "preset": sim.preset, "overrides": sim.overrides,
                    "cache": str(sim.cache) if sim.cache else None}),
                "alpha": alpha,
                "shard": list(shard) if shard is not None else None,
                "resumed_twins": n_resumed,
                "twin_jobs": twin_jobs, "twins_run_in_processes": n_in_processes,
                "select_alpha": select_alpha,
                "gof_alpha": gof_alpha, "seed": seed, "twin_seed": tseed,
                "twin_magnitudes": f"gap of U{tuple(snr_range)} sigma on calibration observables "
                                   "after recalibration, in the twin's own noise (reading noise, "
                                   "one run's scatter, the base runs' mean); capped at the prior top",
                "twin_cohesion": "base x (1 + U(-0.02, 0.02))",
                "twin_repeats": twin_repeats,
                "design": "twin_design()" if simulator == "surrogate" else
                          f"engine_twin_design({campaign!r})",
                "note": ("runs on the analytic surrogate simulator, not the DEM engine"
                         if simulator == "surrogate" else
                         "runs on the embedded DEM engine (scale-model preset)")}
    return ValidationResult.from_scores(preset, simulator, sc, twins, time.perf_counter() - t0,
                                        settings)
