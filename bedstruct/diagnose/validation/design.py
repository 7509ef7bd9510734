"""The measurement designs of validation twins: what a twin's file measures.

:func:`twin_design` is the surrogate's full experimental campaign; :func:`engine_twin_design`
the seed's design on the DEM engine, with the catalogue's candidate measurements added for
``campaign="full"``; :func:`engine_scale_model` names the engine preset a validation preset
runs on. Used by :func:`~bedstruct.diagnose.validation.validate.validate`.

.. versionadded:: 0.1
"""

from __future__ import annotations

from dataclasses import replace

from ...errors import ConfigError
from ..catalogue import catalogue as _catalogue
from ..measurements import MeasurementSet
from ..measurement_io import measurement_from_dict
from ..surrogate import SPEED_X1

__all__ = ["twin_design", "engine_twin_design", "engine_scale_model"]


def engine_scale_model(preset: str) -> str:
    """The engine preset (scale model) a validation preset runs on by default.

    Examples
    --------
    >>> [engine_scale_model(p) for p in ("mini", "tiny", "small")]
    ['tiny', 'tiny', 'small']
    """
    return "small" if preset == "small" else "tiny"


def twin_design() -> MeasurementSet:
    """The observables of a validation twin: what a full experimental campaign would give.

    Static angle in the narrow (3 mm, as simulated) and a wide (30 mm, as in the seed
    experiment) box; dynamic angle in three stroke windows at x1, x2, x5 speed; bed
    height per layer; packing fraction per region; PSD before and after
    spreading; roughness per speed. Roles split every kind of observable between
    calibration and held-out validation (x2 speed, layers 2 and 4, ...).
    Uncertainties are stated per observable (one standard deviation).
    """
    w = [[0.0, 0.05], [0.05, 0.3], [0.3, 1.0]]
    specs = [dict(name="static_angle", kind="static_angle", uncertainty=0.5, role="calibrate",
                  conditions=dict(box_width=3e-3)),
             dict(name="static_angle_wide_box", kind="static_angle", uncertainty=0.5,
                  role="calibrate", conditions=dict(box_width=30e-3))]
    for f, role in ((1, "calibrate"), (5, "calibrate"), (2, "validate")):
        specs.append(dict(name=f"dynamic_angle_x{f}", kind="dynamic_angle_series", windows=w,
                          uncertainty=[1.0, 0.7, 0.6], role=role,
                          conditions=dict(speed=f * SPEED_X1, layer=3)))
    for layer, role in ((1, "calibrate"), (2, "validate"), (3, "calibrate"), (4, "validate")):
        specs.append(dict(name=f"bed_height_layer{layer}", kind="bed_height", uncertainty=10e-6,
                          unit="m", role=role, conditions=dict(layer=layer, speed=SPEED_X1)))
    for f, region, role in ((1, "start", "calibrate"), (1, "end", "calibrate"),
                            (1, "center", "validate"), (5, "start", "validate")):
        specs.append(dict(name=f"packing_fraction_x{f}_{region}", kind="packing_fraction",
                          uncertainty=0.005, role=role,
                          conditions=dict(speed=f * SPEED_X1, layer=1, region=region)))
    specs.append(dict(name="psd_before", kind="psd", percentiles=[10, 50, 90], unit="m",
                      uncertainty=[0.6e-6, 1.0e-6, 1.7e-6], role="calibrate",
                      conditions=dict(stage="before")))
    specs.append(dict(name="psd_after_x1", kind="psd", percentiles=[10, 50, 90], unit="m",
                      uncertainty=[0.6e-6, 1.0e-6, 1.7e-6], role="validate",
                      conditions=dict(stage="after", speed=SPEED_X1, layer=1, region="start")))
    for f, role in ((1, "calibrate"), (5, "calibrate"), (2, "validate")):
        specs.append(dict(name=f"roughness_x{f}", kind="roughness", uncertainty=1.5e-6, unit="m",
                          role=role, conditions=dict(speed=f * SPEED_X1, layer=1)))
    ms = []
    for s in specs:
        d = dict(s)
        d["value"] = [0.0] * (3 if s["kind"] in ("dynamic_angle_series", "psd") else 1)
        ms.append(measurement_from_dict(d))
    return MeasurementSet(tuple(ms), title="validation twin design",
                          source="bedstruct.diagnose.validation.validate.twin_design")


def engine_twin_design(campaign: str = "seed") -> MeasurementSet:
    """The observables of an engine validation twin (``validate(simulator="engine")``).

    With ``campaign="full"`` the twins also measure every candidate measurement of
    the catalogue (the avalanche angle after rest, the dry-powder static angle, the
    packing at the start of an x5 stroke, ...; role ``calibrate``): the campaign the
    diagnosis' "what to measure next" asks for. Every engine call simulates them
    anyway, so the full campaign costs no extra runs.

    The seed's measurement design (``data/measurements/seed.toml``: static angle in the
    30 mm box, dynamic angle at x1 (first 10 % and rest of the stroke), x2 (held
    out) and x5, bed height after layers 1 and 2 (2 held out), PSD before spreading)
    with the same kinds, conditions and roles, so that engine runs cached for twins
    serve the seed case too; plus the static angle in a narrow box with side walls
    (3 mm, the seed simulation's box: wall friction), the packing fraction of layer 1
    at the start and end (calibration) and centre (held out), the roughness of layer
    1 (held out) and the PSD after spreading (held out). The engine maps layers
    beyond its preset's to the last one (``tiny``: 2 layers).
    """
    x1, x2, x5 = SPEED_X1, 2 * SPEED_X1, 5 * SPEED_X1
    specs = [dict(name="static_angle", kind="static_angle", uncertainty=1.0, role="calibrate",
                  conditions=dict(box_width=0.030)),
             dict(name="static_angle_narrow_box", kind="static_angle", uncertainty=1.0,
                  role="calibrate", conditions=dict(box_width=3e-3)),
             dict(name="dynamic_angle_x1_early", kind="dynamic_angle_series", uncertainty=4.0,
                  role="calibrate", conditions=dict(speed=x1, layer=3, time_window=[0.0, 0.1]))]
    for name, v, role in (("x1", x1, "calibrate"), ("x2", x2, "validate"), ("x5", x5, "calibrate")):
        specs.append(dict(name=f"dynamic_angle_{name}_steady", kind="dynamic_angle_series",
                          uncertainty=1.0, role=role,
                          conditions=dict(speed=v, layer=3, time_window=[0.1, 1.0])))
    for layer, role in ((1, "calibrate"), (2, "validate")):
        specs.append(dict(name=f"bed_height_layer{layer}", kind="bed_height", uncertainty=10e-6,
                          unit="m", role=role, conditions=dict(layer=layer, speed=x1)))
    specs.append(dict(name="psd_before", kind="psd", percentiles=[10, 50, 90], unit="m",
                      uncertainty=[0.6e-6, 1.0e-6, 1.7e-6], role="calibrate",
                      conditions=dict(stage="before")))
    for region, role in (("start", "calibrate"), ("end", "calibrate"), ("center", "validate")):
        specs.append(dict(name=f"packing_fraction_x1_{region}", kind="packing_fraction",
                          uncertainty=0.005, role=role,
                          conditions=dict(speed=x1, layer=1, region=region)))
    specs.append(dict(name="roughness_x1", kind="roughness", uncertainty=1.5e-6, unit="m",
                      role="validate", conditions=dict(speed=x1, layer=1)))
    specs.append(dict(name="psd_after_x1", kind="psd", percentiles=[10, 50, 90], unit="m",
                      uncertainty=[0.6e-6, 1.0e-6, 1.7e-6], role="validate",
                      conditions=dict(stage="after", speed=x1, layer=1, region="start")))
    if campaign not in ("seed", "full"):
        raise ConfigError(f"campaign: expected 'seed' or 'full'; got {campaign!r}")
    ms = []
    for s in specs:
        d = dict(s)
        d["value"] = [0.0] * (3 if s["kind"] == "psd" else 1)
        ms.append(measurement_from_dict(d))
    seed_design = MeasurementSet(tuple(ms), title="engine validation twin design",
                                 source="bedstruct.diagnose.validation.validate.engine_twin_design")
    if campaign == "seed":
        return seed_design
    from ..diagnosis import candidate_design
    extra = tuple(replace(m, role="calibrate")
                  for m in candidate_design(_catalogue(), seed_design))
    return MeasurementSet(seed_design.measurements + extra,
                          title="engine validation twin design (full campaign)",
                          source="bedstruct.diagnose.validation.validate.engine_twin_design")
