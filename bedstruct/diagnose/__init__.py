"""Sim-to-real gap diagnosis: where the simulation misses the data, which unmodelled
effect explains it, how far adding it closes the gap, and what to measure next.

The diagnosis talks to simulations only through the simulator interface
``simulator(base, effects, seed) -> Observations``: the embedded DEM engine
(:mod:`bedstruct.diagnose.engine_simulator`, ``kind = "engine"``) or, for tests and
examples, the analytic :class:`SurrogateSimulator` (labelled ``"surrogate"``).

The modules, by concept: measurements (``measurements``, ``measurement_io``,
``measurement_parse``, ``measurement_values``, ``observables``, ``observables_image``,
``observables_registry``, ``trial_counts``); simulators (``surrogate``, ``engine_simulator``,
``engine_cache``, ``engine_runs``, ``process_pool``, ``replicates``, ``config``, ``parameters``,
``catalogue``); the model and its fit (``effect_response``, ``fingerprints``,
``fingerprint_runs``, ``identifiability``, ``noise_correlation``, ``where``, ``attribution``,
``profile_interval``, ``separation``, ``confirm``, ``diagnosis``, ``diagnosis_result``); the run
library and its emulator (``run_design``, ``run_library``, ``emulator``, ``emulator_fit``,
``amortised``); another engine's baseline (``bridge``); the answer, report and figures
(``answer``, ``report``, ``figures``). Imports point from the later groups to the earlier
ones. The validation of the method (synthetic and LIGGGHTS twins, the blind protocol) is the
subpackage :mod:`bedstruct.diagnose.validation`, which uses the method and is not used by it.
"""

from __future__ import annotations

from .amortised import AmortisedDiagnosis, diagnose_with_library
from .answer import answer, compact_answer
from .attribution import Attribution, EffectEstimate, ModelFit, attribute, fit_model
from .bridge import EngineBridge, engine_bridge
from .catalogue import (CATALOGUE, Effect, catalogue, effect, engine_hooks, halsey_film_thickness,
                        kelvin_radius)
from .config import SimConfig, load_sim_config, make_simulator
from .confirm import Shrink, gap_size
from .diagnosis import candidate_design, diagnose, diagnosis_design
from .diagnosis_result import Diagnosis, NextMeasurement, identification
from .effect_response import Fingerprint
from .emulator import EmulatedSimulator, Emulator
from .emulator_fit import fit_emulator
from .fingerprint_runs import compute_fingerprints
from .fingerprints import FingerprintSet
from .identifiability import nuisance_projector
from .measurement_io import load_measurements, measurement_from_dict, write_measurements
from .measurements import (KINDS, ROLES, Conditions, Measurement, MeasurementSet, Observations,
                           Setup)
from .observables import psd_percentiles, psd_percentiles_from_cumulative, windowed_mean
from .observables_registry import (ObservableKind, observable_kind, observable_kinds, observe,
                                   register_observable, unregister_observable)
from .observables_image import (AngleFit, angle_from_image, angle_from_particles,
                                fit_surface_angle, read_image, render_side_view, surface_profile)
from .parameters import PARAMETER_BOUNDS, parameter_bounds
from .replicates import Simulator, simulate_replicates
from .run_design import design_spec
from .run_library import RunLibrary, StaleLibraryError, build_library, load_library
from .report import diagnosis_report
from .separation import nearest_imitations, not_told_apart, separation
from .surrogate import BASE_PARAMETERS, SurrogateSimulator
from .where import GapGroup, Residuals, WhereResult, standardised_residuals, where, where_table
from .validation.blind import BenchmarkResult, pool_benchmarks, run_benchmark
from .validation.blind_twins import OUT_OF_CATALOGUE
from .validation.design import engine_twin_design, twin_design
from .validation.liggghts import LIGGGHTS_PRESETS, validate_liggghts
from .validation.records import METHOD_VERSION
from .validation.report import validation_report
from .validation.scores import GOALS, ValidationResult, capped_summary, capped_twins, score_twins
from .validation.validate import ENGINE_PRESETS, PRESETS, validate

__all__ = [
    # measurements and observation operators
    "KINDS", "ROLES", "Conditions", "Setup", "Measurement", "MeasurementSet", "Observations",
    "load_measurements", "write_measurements", "measurement_from_dict",
    "windowed_mean", "psd_percentiles", "psd_percentiles_from_cumulative", "render_side_view",
    "surface_profile", "AngleFit", "fit_surface_angle", "angle_from_image", "angle_from_particles",
    "read_image", "observe", "ObservableKind", "observable_kinds", "observable_kind",
    "register_observable", "unregister_observable",
    # catalogue, parameters and simulators
    "CATALOGUE", "Effect", "catalogue", "effect", "engine_hooks", "halsey_film_thickness",
    "kelvin_radius", "PARAMETER_BOUNDS", "parameter_bounds",
    "BASE_PARAMETERS", "SurrogateSimulator", "SimConfig", "load_sim_config", "make_simulator",
    # statistics
    "standardised_residuals", "Residuals", "GapGroup", "WhereResult", "where", "where_table",
    "Simulator", "simulate_replicates", "Fingerprint", "FingerprintSet", "compute_fingerprints",
    "nuisance_projector", "ModelFit", "EffectEstimate", "Attribution", "fit_model", "attribute",
    # orchestration and the answer
    "candidate_design", "identification", "diagnosis_design", "gap_size", "Shrink",
    "NextMeasurement", "Diagnosis", "diagnose", "answer", "compact_answer",
    "diagnosis_report", "validation_report",
    # run library and emulator
    "design_spec", "build_library", "load_library", "RunLibrary", "StaleLibraryError",
    "fit_emulator", "Emulator", "EmulatedSimulator", "diagnose_with_library",
    "AmortisedDiagnosis",
    # another engine's baseline
    "EngineBridge", "engine_bridge",
    # validation
    "PRESETS", "ENGINE_PRESETS", "GOALS", "METHOD_VERSION", "ValidationResult", "score_twins",
    "capped_twins", "capped_summary", "separation", "nearest_imitations", "not_told_apart",
    "twin_design", "engine_twin_design", "validate", "LIGGGHTS_PRESETS", "validate_liggghts",
    "run_benchmark", "BenchmarkResult", "pool_benchmarks", "OUT_OF_CATALOGUE",
]
