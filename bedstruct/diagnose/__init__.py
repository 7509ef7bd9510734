"""Sim-to-real gap diagnosis: where the simulation misses the data, which unmodelled
effect explains it, how far adding it closes the gap, and what to measure next.

The diagnosis talks to simulations only through the simulator interface
``simulator(base, effects, seed) -> Observations``; until the DEM workflows
exist, :class:`SurrogateSimulator` (analytic, labelled ``"surrogate"``) stands in.
"""

from __future__ import annotations

from .attribution import Attribution, EffectEstimate, ModelFit, attribute, fit_model
from .catalogue import (CATALOGUE, Effect, catalogue, effect, engine_hooks, halsey_film_thickness,
                        kelvin_radius)
from .config import SimConfig, load_sim_config, make_simulator
from .diagnosis_result import Diagnosis, NextMeasurement, identification
from .confirm import Shrink, gap_size
from .diagnosis import candidate_design, diagnose, diagnosis_design
from .effect_response import Fingerprint
from .fingerprints import FingerprintSet
from .fingerprint_runs import compute_fingerprints
from .identifiability import nuisance_projector
from .measurements import KINDS, ROLES, Conditions, Measurement, MeasurementSet, Observations
from .measurement_io import load_measurements, measurement_from_dict, write_measurements
from .observables_image import (
    AngleFit, angle_from_image, angle_from_particles, fit_surface_angle, read_image,
    render_side_view, surface_profile)
from .observables import (
    bed_height, observe, packing_fraction_in_region, psd_percentiles,
    psd_percentiles_from_cumulative, roughness, windowed_mean)
from .replicates import Simulator, simulate_replicates
from .report import diagnosis_report, validation_report
from .separation import nearest_imitations, not_told_apart, separation
from .surrogate import BASE_PARAMETERS, SurrogateSimulator
from .validate import ENGINE_PRESETS, PRESETS, validate
from .validation_design import engine_twin_design, twin_design
from .validate_liggghts import LIGGGHTS_PRESETS, validate_liggghts
from .validation_scores import GOALS, ValidationResult, capped_summary, capped_twins, score_twins
from .where import GapGroup, Residuals, WhereResult, standardised_residuals, where, where_table

__all__ = [
    # measurements and observation operators
    "KINDS", "ROLES", "Conditions", "Measurement", "MeasurementSet", "Observations",
    "load_measurements", "write_measurements", "measurement_from_dict",
    "windowed_mean", "psd_percentiles", "psd_percentiles_from_cumulative", "render_side_view",
    "surface_profile", "AngleFit", "fit_surface_angle", "angle_from_image", "angle_from_particles",
    "read_image", "bed_height", "packing_fraction_in_region", "roughness", "observe",
    # catalogue and simulators
    "CATALOGUE", "Effect", "catalogue", "effect", "engine_hooks", "halsey_film_thickness",
    "kelvin_radius",
    "BASE_PARAMETERS", "SurrogateSimulator", "SimConfig", "load_sim_config", "make_simulator",
    # statistics
    "standardised_residuals", "Residuals", "GapGroup", "WhereResult", "where", "where_table",
    "Simulator", "simulate_replicates", "Fingerprint", "FingerprintSet", "compute_fingerprints",
    "nuisance_projector", "ModelFit", "EffectEstimate", "Attribution", "fit_model", "attribute",
    # orchestration
    "candidate_design", "identification", "diagnosis_design", "gap_size", "Shrink",
    "NextMeasurement", "Diagnosis", "diagnose", "PRESETS", "ENGINE_PRESETS", "GOALS",
    "ValidationResult", "score_twins", "capped_twins", "capped_summary", "separation", "nearest_imitations", "not_told_apart", "twin_design", "engine_twin_design", "validate",
    "LIGGGHTS_PRESETS", "validate_liggghts",
    "diagnosis_report", "validation_report",
]
