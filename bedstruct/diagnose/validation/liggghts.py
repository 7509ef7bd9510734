"""Validation on twins made with LIGGGHTS: another code's numerics are part of the gap.

:func:`validate_liggghts` is :func:`bedstruct.diagnose.validate` with the "real" data
made by LIGGGHTS 3.8 (:func:`~bedstruct.diagnose.validation.liggghts_twins.make_liggghts_twin`)
and the diagnosis run on the embedded engine's fingerprints. Each twin's effect is a set
of configuration option values that the LIGGGHTS dialect writes with LIGGGHTS' own models
(:data:`bedstruct.engines.LIGGGHTS_REALISATIONS`), not the catalogue's:

=================  ===========================================  =================================
twin               option values (LIGGGHTS' model)               true catalogue effect (magnitude)
=================  ===========================================  =================================
null               none                                          none
rolling friction   ``contact.rolling_friction`` base + 0.20,     ``non_sphericity`` (0.20)
                   ``contact.rolling_model`` epsd2 (EPSD2,
                   particles and walls)
liquid bridges     ``contact.capillary``, surface tension        ``capillary_bridges`` (no
                   1e-3 N/m, film 8.67 nm (liquid fraction       relative humidity in that model)
                   5e-4 at 52 um), angle 0.061 rad (``cohesion
                   easo/capillary/viscous`` in place of SJKR)
wall friction      ``contact.wall_friction`` base friction       ``wall_friction`` (0.30)
                   + 0.30 (particle-wall ``coefficientFriction``)
=================  ===========================================  =================================

The base is the diagnosis' base parameters (:data:`~bedstruct.diagnose.surrogate.BASE_PARAMETERS`).

Each effect twin is diagnosed twice, with its effect in the catalogue and removed
(the out-of-catalogue twin), on the same file; the scores are those of
:func:`~bedstruct.diagnose.score_twins`. A LIGGGHTS twin costs one LIGGGHTS run per
repetition (about a minute each at ``tiny`` on one core); the fingerprints cost the
engine calls of :func:`~bedstruct.diagnose.compute_fingerprints`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import json
import logging
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import ConfigError
from ..catalogue import catalogue as _catalogue
from ..diagnosis import diagnose, diagnosis_design
from .liggghts_twins import effects_label, liggghts_twin_design, make_liggghts_twin
from .liggghts_law import easo_effective_contact_angle
from ..fingerprint_runs import compute_fingerprints
from ..measurement_io import load_measurements
from ..surrogate import BASE_PARAMETERS
from .records import METHOD_VERSION, method_version_of, records_done, twin_record
from .scores import ValidationResult, score_twins

__all__ = ["LIGGGHTS_PRESETS", "LiggghtsTwinSpec", "liggghts_twin_plan", "validate_liggghts"]

log = logging.getLogger(__name__)

#: Per preset: replicate seeds of the engine's fingerprints, repetitions of each LIGGGHTS
#: experiment, and the catalogue (the effects LIGGGHTS twins are made of; the others would
#: only be out-of-catalogue candidates).
LIGGGHTS_PRESETS = {
    "tiny": dict(replicates=3, repetitions=3,
                 effects=("capillary_bridges", "non_sphericity", "wall_friction")),
}

#: The liquid-bridge twin: gamma 1e-3 N/m, a film giving the liquid volume fraction 5e-4 on
#: the tiny preset's median sphere (radius 52 um; fraction 3 t / r), and the angle LIGGGHTS
#: applies to two types of 20 degrees each (theta_i theta_j / 2).
_BRIDGES = {"contact.capillary": True, "contact.capillary_surface_tension": 1e-3,
            "contact.capillary_film_thickness": 5e-4 * 52e-6 / 3.0,
            "contact.capillary_contact_angle": easo_effective_contact_angle(0.3490658503988659,
                                                                            0.3490658503988659)}



@dataclass(frozen=True)
class LiggghtsTwinSpec:
    """One LIGGGHTS twin of the plan: its option values and the truth they stand for.

    Attributes
    ----------
    kind : {"null", "effect"}
    effects : dict
        The twin's option values (``"section.option"``: what the LIGGGHTS runs'
        configuration sets, after the base parameters).
    true_effect : str or None
        The catalogue effect the change is (``None`` for the null twin).
    true_magnitude : float or None
        Its magnitude in the catalogue's terms, where the LIGGGHTS model has one.
    """

    kind: str
    effects: dict
    true_effect: str | None = None
    true_magnitude: float | None = None

    @property
    def label(self) -> str:
        """Short description of :attr:`effects`."""
        return effects_label(self.effects)


def liggghts_twin_plan(base=None) -> list[LiggghtsTwinSpec]:
    """The LIGGGHTS twins of a validation (see the module docstring) on the base
    parameters ``base`` (default :data:`~bedstruct.diagnose.surrogate.BASE_PARAMETERS`).

    Examples
    --------
    >>> plan = liggghts_twin_plan({"friction": 0.5, "rolling_friction": 0.1})
    >>> [(t.kind, t.true_effect, t.true_magnitude) for t in plan]
    ... # doctest: +NORMALIZE_WHITESPACE
    [('null', None, None), ('effect', 'non_sphericity', 0.2),
     ('effect', 'capillary_bridges', None), ('effect', 'wall_friction', 0.3)]
    >>> plan[1].effects["contact.rolling_friction"], plan[3].effects
    (0.3, {'contact.wall_friction': 0.8})
    """
    base = BASE_PARAMETERS if base is None else base
    return [LiggghtsTwinSpec("null", {}),
            LiggghtsTwinSpec("effect", {"contact.rolling_friction":
                                        round(float(base["rolling_friction"]) + 0.20, 12),
                                        "contact.rolling_model": "epsd2"},
                             "non_sphericity", 0.20),
            LiggghtsTwinSpec("effect", dict(_BRIDGES), "capillary_bridges", None),
            LiggghtsTwinSpec("effect", {"contact.wall_friction":
                                        round(float(base["friction"]) + 0.30, 12)},
                             "wall_friction", 0.30)]


def _refuse_rewritten_twin(folder: Path) -> None:
    """Raise ConfigError for a twin folder whose ``truth.json`` states a deck-rewriting
    ``effect`` record (a LIGGGHTS twin made before the effects were configuration values)."""
    truth = folder / "truth.json"
    try:
        have = json.loads(truth.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return
    if isinstance(have, dict) and "effect" in have and "effects" not in have:
        eff = have["effect"]
        raise ConfigError(
            f"{folder}: this LIGGGHTS twin states its effect as a deck rewriting "
            f"(truth.json 'effect' = {eff.get('kind', eff) if isinstance(eff, dict) else eff!r}), "
            "which bedstruct no longer makes; its runs are not reused. Remove the folder (or "
            "give another workdir / --cache) to make the twin again from its option values")


def _twin_folder_matches(folder: Path, want: dict) -> bool:
    """Whether ``folder`` holds a finished twin made with the settings ``want``."""
    truth, toml = folder / "truth.json", folder / "twin.toml"
    if not (truth.is_file() and toml.is_file()):
        return False
    try:
        have = json.loads(truth.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return False
    have = dict(have, method_version=method_version_of(have))
    return all(have.get(k) == v for k, v in want.items())


def _made_entry(i: int, spec: LiggghtsTwinSpec, folder: Path, *, keep: bool) -> dict:
    """What ``settings["twins_made"]`` says of a finished twin (from its ``truth.json``)."""
    doc = json.loads((folder / "truth.json").read_text(encoding="utf-8"))
    return {"twin": i, "liggghts_effect": spec.label,
            "folder": str(folder) if keep else None, "seeds_used": doc.get("seeds_used"),
            "liggghts_seconds": doc.get("seconds")}


def validate_liggghts(preset: str = "tiny", *, seed: int = 0, engine: dict | None = None,
                      workdir=None, records=None, alpha: float = 0.05,
                      select_alpha: float = 0.01, gof_alpha: float = 0.01, refine: int = 1,
                      progress: bool = False) -> ValidationResult:
    """Validate the diagnosis on twins whose "real" data come from LIGGGHTS.

    Parameters
    ----------
    preset : {"tiny"}
        Scale model of both engines and the sizes of :data:`LIGGGHTS_PRESETS`.
    seed : int
        Seed of the fingerprints' replicate runs; the LIGGGHTS repetitions run on seeds
        ``1000 + 10 seed + k`` and each twin's reading noise on ``10 + 100 seed + i``.
    engine : dict, optional
        The embedded engine's ``[engine]`` table (default ``{"preset": preset}``); its
        ``overrides`` are applied to the LIGGGHTS runs too, and ``cache`` keeps its runs.
    workdir : path, optional
        Folder of the twins (``twin<i>/`` with ``twin.toml``, ``truth.json`` and the
        LIGGGHTS runs). A twin already there, made with the same settings, is reused,
        so an interrupted validation resumes. Default: a temporary folder, removed
        afterwards.
    records : path, optional
        JSON-lines file of twin records, as in :func:`~bedstruct.diagnose.validate`.
    alpha, select_alpha, gof_alpha, refine
        As in :func:`~bedstruct.diagnose.diagnose`.
    progress : bool
        Progress bars.

    Returns
    -------
    ValidationResult
        With ``simulator = "liggghts"``; ``settings["twins_made"]`` lists each twin's
        folder, seeds used and LIGGGHTS wall time.

    Raises
    ------
    ConfigError
        Unknown preset, no ``liggghts`` executable on the PATH, or a twin folder in
        ``workdir`` made by deck rewriting (its ``truth.json`` states an ``effect``
        record, not option values): remove it to make the twin again.

    Examples
    --------
    About an hour on one core at ``tiny`` (24 engine calls for the fingerprints, 12
    LIGGGHTS runs, the reruns); with a cache a second call reuses every run:

    >>> from bedstruct.diagnose.validation import liggghts as validate_liggghts
    >>> res = validate_liggghts("tiny", engine={"preset": "tiny", "cache": "runs"},
    ...                         workdir="runs/liggghts-twins")   # doctest: +SKIP
    >>> res.confusion["rows"][:4]                                # doctest: +SKIP
    ['capillary_bridges', 'non_sphericity', 'wall_friction', 'null']
    """
    if preset not in LIGGGHTS_PRESETS:
        raise ConfigError(f"preset: expected one of {sorted(LIGGGHTS_PRESETS)} for LIGGGHTS twins "
                          f"(a LIGGGHTS twin at 'small' is hours per repetition); got {preset!r}")
    if shutil.which("liggghts") is None:
        raise ConfigError("LIGGGHTS twins need the liggghts executable on the PATH "
                          "(Debian/Ubuntu: apt-get install liggghts)")
    base = dict(BASE_PARAMETERS)
    plan = liggghts_twin_plan(base)
    if workdir is not None:   # before any run: twins this version cannot reuse are refused
        for i in range(len(plan)):
            _refuse_rewritten_twin(Path(workdir) / f"twin{i}")
    from ..engine_simulator import diagnosis_simulator
    cfg = LIGGGHTS_PRESETS[preset]
    t0 = time.perf_counter()
    effects = _catalogue(cfg["effects"])
    measured = liggghts_twin_design()
    design = diagnosis_design(measured, effects)
    engine = dict(engine or {"preset": preset})
    engine.setdefault("preset", preset)
    if engine["preset"] != preset:
        # both codes must run the same scale model, or their difference is not numerics
        raise ConfigError(f"[engine] preset {engine['preset']!r}: LIGGGHTS twins at {preset!r} "
                          f"need the engine's fingerprints at the same scale model")
    sim = diagnosis_simulator(design, engine)
    overrides = [str(s) for s in engine.get("overrides", [])]
    fps = compute_fingerprints(sim, design, base, effects, replicates=cfg["replicates"], seed=seed,
                               alpha=select_alpha, simulator_name="engine", progress=progress)
    signature = {"preset": preset, "simulator": "liggghts", "seed": int(seed), "alpha": alpha,
                 "select_alpha": select_alpha, "gof_alpha": gof_alpha, "refine": int(refine),
                 "method_version": METHOD_VERSION}
    done = records_done(records, signature)
    seeds = tuple(1000 + 10 * int(seed) + k for k in range(cfg["repetitions"]))
    twins, failed, made = [], [], []
    tmp = None
    if workdir is None:
        # about an hour and a half of runs that an interruption would lose
        log.warning("LIGGGHTS twins are made in a temporary folder and removed afterwards; "
                    "give workdir (CLI: --cache DIR) to keep and reuse them")
        tmp = tempfile.TemporaryDirectory(prefix="bedstruct-liggghts-twins-")
        root = Path(tmp.name)
    else:
        root = Path(workdir)
    steps = list(enumerate(plan))
    if progress:
        from tqdm import tqdm
        steps = tqdm(steps, desc="LIGGGHTS twins")
    from ..engine_cache import _DECK_REVISION
    try:
        for i, spec in steps:
            truth = {"true_effect": spec.true_effect, "true_magnitude": spec.true_magnitude,
                     "true_cohesion": base["cohesion_energy_density"],
                     "liggghts_effect": spec.label}
            kinds = [spec.kind] + (["out_of_catalogue"] if spec.kind == "effect" else [])
            twins.extend(done[(i, k)] for k in kinds if (i, k) in done)
            todo = [k for k in kinds if (i, k) not in done]
            folder = root / f"twin{i}"
            noise_seed = 10 + 100 * int(seed) + i
            want = {"effects": spec.effects, "base": base, "seeds": list(seeds),
                    "noise_seed": noise_seed, "preset": preset, "overrides": overrides,
                    "deck_revision": _DECK_REVISION, "method_version": METHOD_VERSION}
            if not todo:  # every diagnosis resumed from the records: list the twin, if kept
                if _twin_folder_matches(folder, want):
                    made.append(_made_entry(i, spec, folder, keep=tmp is None))
                continue
            try:
                if not _twin_folder_matches(folder, want):
                    made_twin = make_liggghts_twin(measured, spec.effects, base=base, out=folder,
                                                   seeds=seeds, noise_seed=noise_seed,
                                                   preset=preset, overrides=overrides,
                                                   replace_failed=2)
                    # the settings a later run checks before reusing this twin
                    doc = json.loads(made_twin.truth_path.read_text(encoding="utf-8"))
                    doc.update(deck_revision=_DECK_REVISION, method_version=METHOD_VERSION)
                    made_twin.truth_path.write_text(json.dumps(doc, indent=1), encoding="utf-8")
                made.append(_made_entry(i, spec, folder, keep=tmp is None))
                # a twin's numbers need not lie in a kind's plausible range (an empty
                # region reads a packing fraction near 0)
                real = load_measurements(folder / "twin.toml", check_range=False)
                for kind in todo:
                    cat = tuple(e for e in effects
                                if not (kind == "out_of_catalogue" and e.name == spec.true_effect))
                    diag = diagnose(real, sim, base=base, effects=cat,
                                    replicates=cfg["replicates"], seed=seed, alpha=alpha,
                                    select_alpha=select_alpha, gof_alpha=gof_alpha,
                                    fingerprints=fps, refine=refine, simulator_name="engine")
                    twins.append(twin_record(diag, i, kind, signature, truth, records=records))
            except (ValueError, np.linalg.LinAlgError, RuntimeError) as exc:
                # a LIGGGHTS run that cannot be observed, or an engine rerun without a
                # measurable observable: recorded, not scored
                log.warning("LIGGGHTS twin %d (%s) failed: %s", i, spec.label, exc)
                failed.append({"twin": i, "type": spec.kind, **truth, "error": str(exc)[:500]})
    finally:
        if tmp is not None:
            tmp.cleanup()
    names = [e.name for e in effects]
    sc = score_twins(twins, names, removed_rows=True,
                     identifiable={f.name: bool(f.identifiable) for f in fps.fingerprints})
    settings = {"replicates": cfg["replicates"], "repetitions": cfg["repetitions"],
                "liggghts_seeds": list(seeds), "effects": names, "refine": refine,
                "twins_made": made, "failed": failed,
                "unobservable": dict(fps.meta.get("unobservable", {})),
                "missing_runs": dict(fps.meta.get("missing_runs", {})),
                "uneven_scatter": dict(fps.meta.get("uneven_scatter", {})),
                "simulator_runs": sim.n_runs, "cached_calls": sim.n_cached,
                "engine": {"preset": sim.preset, "overrides": sim.overrides,
                           "cache": str(sim.cache) if sim.cache else None},
                "resumed_twins": len(done), "alpha": alpha, "select_alpha": select_alpha,
                "gof_alpha": gof_alpha, "seed": seed,
                "twin_magnitudes": "fixed (liggghts_twin_plan): rolling friction +0.20, wall "
                                   "friction +0.30, liquid bridges gamma 1e-3 N/m, liquid 5e-4 "
                                   "at 52 um",
                "twin_cohesion": "the base's (the LIGGGHTS numerics are the cohesion's gap)",
                "design": "liggghts_twin_design()",
                "note": "twins made with LIGGGHTS 3.8 (one MPI rank); fingerprints on the "
                        "embedded DEM engine (scale-model preset)"}
    return ValidationResult.from_scores(preset, "liggghts", sc, twins, time.perf_counter() - t0,
                                        settings)
