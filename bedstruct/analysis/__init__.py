"""Analyses of frames and contacts: packing, coordination, PSD, surface,
angle of repose, fabric tensors, spherical harmonics, heat conduction, the state of
the input (bed, pile, flow), g(r) and Voronoi local packing.

Examples
--------
>>> import bedstruct.analysis
>>> "packing_fraction" in bedstruct.analysis.__all__
True
"""

from __future__ import annotations

from .contacts import (
    find_contacts, Wall, ContactMatch, compare_contacts,
)
from .coordination import (
    CoordinationResult, coordination, remove_rattlers, WindowCoordination,
    coordination_by_window, CoordinationSeries, coordination_series, coordination_table,
)
from .packing import (
    PackingResult, PackingProfile, PackingGrid, packing_fraction, packing_fractions,
    packing_along, packing_sliding, packing_grid, layer_packing, bed_bounds, bed_windows,
    sphere_box_volume, packing_table, disc_rectangle_area, area_fraction, area_fractions,
)
from .dimension import (
    flat_axis,
)
from .german import (
    german_cn, GermanFit, fit_german_law, GermanAlongBed, german_law_along, apart_from_bed,
    GERMAN_WINDOWS, GERMAN_MIN_PARTICLES,
)
from .psd import (
    PSDResult, particle_size_distribution, percentile_diameter, psd_by_region, psd_series,
    PSDFit, psd_from_percentiles, psd_table,
)
from .segregation import (
    PSDComparison, compare_psd, wasserstein_psd, segregation_index, SegregationResult,
    segregation, heap_mask,
)
from .surface import (
    SurfaceResult, Roughness, surface_roughness, surface_height_map, height_profile,
    bed_height, layer_heights, grounded_particles, largest_cluster,
)
from .repose import (
    FlankFit, ReposeResult, angle_of_repose, PileAngle, pile_angle, dynamic_angle_of_repose,
    heap_front_angle,
    ReposeSeries, dynamic_repose_series, free_surface_profile,
)
from .fabric import (
    FabricTensors, fabric_tensors, fabric_density, projected_density, sample_directions,
    contact_regions, RegionFabric, region_fabric, LammpsFabric, lammps_fabric, lammps_voigt,
    fabric_table, deviatoric_rank4, sym_delta_tensor, isotropic_rank4,
)
from .harmonics import (
    HarmonicExpansion, harmonic_expansion, real_spherical_harmonics, harmonic_density,
    sphere_grid, harmonics_from_fabric, fabric_from_harmonics,
)
from .heat import (
    ThermalMaterial, COCR, GasGap, ThermalNetwork, thermal_network, HemisphereSource,
    source_nodes, EnergyRecord, HeatResult, conduct_heat, TemperatureMap, temperature_map,
    HAZShape, haz_shape, haz_table, ConductivityTensor, conductivity_tensor,
)
from .heat_study import (
    HeatRegionsResult, heat_regions, heat_regions_table, tile_network, planar_axes,
)
from .timeseries import (
    TimeSeries, TimeSeriesResults,
)
from .bed_state import (
    BedState, bed_state, BED_KINDS,
)
from .rdf import (
    RDFResult, radial_distribution,
)
from .voronoi import (
    LocalPacking, local_packing,
)

__all__ = [
    "find_contacts", "Wall", "ContactMatch", "compare_contacts", "CoordinationResult",
    "coordination", "remove_rattlers", "WindowCoordination", "coordination_by_window",
    "CoordinationSeries", "coordination_series", "coordination_table", "PackingResult",
    "PackingProfile", "PackingGrid", "packing_fraction", "packing_fractions", "packing_along",
    "packing_sliding", "packing_grid", "layer_packing", "bed_bounds", "bed_windows",
    "sphere_box_volume", "packing_table", "disc_rectangle_area", "area_fraction", "area_fractions",
    "flat_axis", "german_cn", "GermanFit", "fit_german_law",
    "GermanAlongBed", "german_law_along", "apart_from_bed", "GERMAN_WINDOWS", "GERMAN_MIN_PARTICLES",
    "PSDResult", "particle_size_distribution", "percentile_diameter", "psd_by_region",
    "psd_series", "PSDFit", "psd_from_percentiles", "psd_table", "PSDComparison",
    "compare_psd", "wasserstein_psd", "segregation_index", "SegregationResult", "segregation",
    "heap_mask", "SurfaceResult", "Roughness", "surface_roughness", "surface_height_map",
    "height_profile", "bed_height", "layer_heights", "grounded_particles", "largest_cluster",
    "FlankFit", "ReposeResult", "angle_of_repose", "PileAngle", "pile_angle",
    "dynamic_angle_of_repose", "heap_front_angle", "ReposeSeries", "dynamic_repose_series", "free_surface_profile",
    "FabricTensors", "fabric_tensors", "fabric_density", "projected_density",
    "sample_directions", "contact_regions", "RegionFabric", "region_fabric", "LammpsFabric",
    "lammps_fabric", "lammps_voigt", "fabric_table", "deviatoric_rank4", "sym_delta_tensor",
    "isotropic_rank4", "HarmonicExpansion", "harmonic_expansion", "real_spherical_harmonics",
    "harmonic_density", "sphere_grid", "harmonics_from_fabric", "fabric_from_harmonics",
    "ThermalMaterial", "COCR", "GasGap", "ThermalNetwork", "thermal_network",
    "HemisphereSource", "source_nodes", "EnergyRecord", "HeatResult", "conduct_heat",
    "TemperatureMap", "temperature_map", "HAZShape", "haz_shape", "haz_table",
    "ConductivityTensor", "conductivity_tensor", "HeatRegionsResult", "heat_regions",
    "heat_regions_table", "tile_network", "planar_axes", "TimeSeries", "TimeSeriesResults",
    "BedState", "bed_state", "BED_KINDS", "RDFResult", "radial_distribution", "LocalPacking",
    "local_packing",
]
