"""External DEM engines as independent references: LIGGGHTS 3.8 and LAMMPS, one
dialect object each.

A dialect (:class:`LiggghtsDialect`, :class:`LammpsDialect`; :func:`dialect` by
name) spells bedstruct's scenarios in its engine's commands, finds its binary
(:meth:`Dialect.find`), runs decks (:meth:`Dialect.run`, :func:`run_deck` on N MPI
ranks) and reads their logs (:func:`parse_log`). The deck writers take the embedded
engine's contact model (a one-type :class:`~bedstruct.dem.ContactModel`, SI; by default
the seed's, :func:`~bedstruct.dem.seed_contact_model`) and scenario descriptions for
every engine: a bed (:func:`bed_deck`, :func:`moving_wall_deck`), a head-on impact
(:func:`impact_deck`), the angle-of-repose box (:func:`repose_deck`) and
multi-layer spreading (:func:`spread_layers_deck`). What an engine cannot realise is
refused by name (:class:`~bedstruct.errors.ConfigError`). Install both engines with
``.ci/install-engines.sh``; docs/backends.md explains the parameter mapping.

Examples
--------
>>> from bedstruct.dem import seed_contact_model
>>> from bedstruct.engines import impact_deck
>>> deck = impact_deck(seed_contact_model(youngs_modulus=1e8, restitution=0.5), engine="lammps")
>>> deck.splitlines()[0]
'# bedstruct deck for lammps: head-on impact on a sphere'
"""

from ._bed import (ImpactResult, bed_deck, hertz_contact_time, impact_deck, impact_result,
                   moving_wall_deck)
from ._bench import benchmark_external, cached_bed, loose_lattice, pour_bed
from ._datafile import data_file_radii, read_data_header, write_sphere_data
from ._dialect import DUMP_COLUMNS, EFFECT_KEYS, EMBEDDED_REALISATIONS, Dialect, Realisation, effects_on
from ._lammps import (LAMMPS_REALISATIONS, REFERENCE_OVERLAP, REFERENCE_RADIUS, LammpsDialect,
                      find_lammps, lammps_granular_coeffs)
from ._launch import EngineInfo, EngineRunError, RunResult, run_deck
from ._liggghts import (EASO_MIN_BRIDGE_VOLUME, LIGGGHTS_REALISATIONS, LiggghtsDialect,
                        LiquidBridges, check_easo_bridges, easo_bridge_volume, find_liggghts,
                        liggghts_model_commands)
from ._logs import EngineLog, ThermoRun, landing_offsets, parse_log, run_finished, tool_loads
from ._realisations import effect_realisations
from ._registry import ENGINE_NAMES, dialect
from ._repose import repose_deck
from ._scenarios import LayerSteps, ReposeGeometry, ReposeSchedule, SpreadLayersPlan, tool_top
from ._spread import spread_layers_deck
from ._stl import (BladeGeometry, RollerGeometry, box_triangles, cylinder_triangles,
                   read_stl_triangles, repose_wall_stls, stl_text, write_stl)

__all__ = [
    # dialects
    "Dialect", "LiggghtsDialect", "LammpsDialect", "LiquidBridges", "dialect", "ENGINE_NAMES",
    "check_easo_bridges", "easo_bridge_volume", "EASO_MIN_BRIDGE_VOLUME",
    "find_liggghts", "find_lammps", "liggghts_model_commands", "lammps_granular_coeffs",
    "REFERENCE_RADIUS", "REFERENCE_OVERLAP",
    # the diagnosis' effects on each engine
    "Realisation", "EFFECT_KEYS", "EMBEDDED_REALISATIONS", "LIGGGHTS_REALISATIONS",
    "LAMMPS_REALISATIONS", "effect_realisations", "effects_on",
    # running and logs
    "EngineInfo", "EngineRunError", "RunResult", "run_deck",
    "EngineLog", "ThermoRun", "parse_log", "landing_offsets", "run_finished", "tool_loads",
    # inputs
    "write_sphere_data", "read_data_header", "data_file_radii",
    "BladeGeometry", "RollerGeometry", "box_triangles", "cylinder_triangles",
    "read_stl_triangles", "repose_wall_stls", "stl_text", "write_stl",
    "ReposeGeometry", "ReposeSchedule", "LayerSteps", "SpreadLayersPlan", "tool_top",
    # decks
    "DUMP_COLUMNS", "bed_deck", "moving_wall_deck", "impact_deck", "ImpactResult",
    "impact_result", "hertz_contact_time", "repose_deck", "spread_layers_deck",
    # benchmarks
    "benchmark_external", "cached_bed", "loose_lattice", "pour_bed",
]
