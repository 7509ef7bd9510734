"""Workflows on the embedded DEM engine: angle of repose, cohesion calibration, multi-layer spreading.

Each workflow takes a configuration from :func:`load_config` (defaults, a
preset ``tiny``/``small``/``seed``, a TOML file and ``key=value``
overrides), runs the embedded engine (:mod:`bedstruct.dem`), writes a run
directory (:class:`RunLayout`) and returns a frozen result dataclass. See
docs/workflows.md.
"""

from .config import (DEFAULTS, PRESETS, apply_override, available_presets, config_to_toml,
                     load_config, preset_path, workflow_config)
from .._json import write_json_atomic
from ._common import CONTACT_KEYWORDS
from ._rundir import RunLayout
from .schema import WorkflowConfig, config_dict, config_reference, typed_config
from .calibrate import CalibrationPoint, CalibrationResult, calibrate_cohesion, inverse_linear
from .repose import ReposeReplicate, ReposeResult, repose_replicate, run_repose
from .spread import LayerResult, SpreadResult, generate_pile, pile_key, run_spread

__all__ = ["WorkflowConfig", "typed_config", "workflow_config", "config_dict", "config_reference",
           "DEFAULTS", "PRESETS", "load_config", "apply_override", "available_presets",
           "config_to_toml", "preset_path", "RunLayout", "write_json_atomic", "CONTACT_KEYWORDS",
           "ReposeReplicate", "ReposeResult", "run_repose", "repose_replicate",
           "CalibrationPoint", "CalibrationResult", "calibrate_cohesion", "inverse_linear",
           "LayerResult", "SpreadResult", "run_spread", "generate_pile", "pile_key"]
