"""External DEM engines as independent references: LIGGGHTS 3.8 and LAMMPS.

Locate the engines (:func:`find_liggghts`, :func:`find_lammps`), write decks
that take bedstruct's SI contact parameters (:func:`bed_deck`,
:func:`impact_deck`, :func:`moving_wall_deck`; the workflows' :func:`repose_deck`
and :func:`spread_layers_deck`), run them on N MPI ranks
(:func:`run_deck`), parse their logs (:func:`parse_log`) and time them
(:func:`benchmark_external`). Install both engines with ``.ci/install-engines.sh``;
docs/backends.md explains the parameter mapping.

Examples
--------
>>> from bedstruct.dem.backends import GranularParams, impact_deck
>>> deck = impact_deck(GranularParams(youngs_modulus=1e8, restitution=0.5), engine="lammps")
>>> deck.splitlines()[0]
'# bedstruct deck for lammps: head-on impact on a sphere'
"""

from ._common import (EngineInfo, EngineLog, EngineRunError, GranularParams, RunResult, ThermoRun,
                      as_granular_params, parse_log, read_data_header, run_deck, write_sphere_data)
from .bench import benchmark_external, cached_bed, loose_lattice, pour_bed
from .decks import (DUMP_COLUMNS, ImpactResult, bed_deck, data_file_radii, hertz_contact_time,
                    impact_deck, impact_result, moving_wall_deck)
from .lammps import find_lammps, lammps_granular_coeffs
from .liggghts import find_liggghts, liggghts_model_commands
from .spread_decks import LayerSteps, SpreadLayersPlan, spread_layers_deck
from .spread_logs import landing_offsets, run_finished, tool_loads
from .stl import (BladeGeometry, RollerGeometry, box_triangles, cylinder_triangles,
                  read_stl_triangles, stl_text, write_stl)
from .workflow_decks import (ReposeGeometry, ReposeSchedule, SpreadGeometry, SpreadSchedule,
                             repose_deck, repose_wall_stls, spread_deck)

__all__ = [
    "EngineInfo", "EngineLog", "EngineRunError", "GranularParams", "RunResult", "ThermoRun",
    "as_granular_params", "parse_log", "read_data_header", "run_deck", "write_sphere_data",
    "benchmark_external", "cached_bed", "loose_lattice", "pour_bed",
    "DUMP_COLUMNS", "ImpactResult", "bed_deck", "data_file_radii", "hertz_contact_time",
    "impact_deck", "impact_result", "moving_wall_deck",
    "find_lammps", "lammps_granular_coeffs", "find_liggghts", "liggghts_model_commands",
    "BladeGeometry", "box_triangles", "read_stl_triangles", "stl_text", "write_stl",
    "ReposeGeometry", "ReposeSchedule", "repose_deck", "repose_wall_stls", "SpreadGeometry",
    "SpreadSchedule", "spread_deck",
    "LayerSteps", "RollerGeometry", "SpreadLayersPlan", "cylinder_triangles", "landing_offsets",
    "run_finished", "spread_layers_deck", "tool_loads",
]
