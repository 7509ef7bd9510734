"""Figures of the analyses. Every function returns matplotlib ``Figure``/``Axes`` objects and
never shows or saves them (the caller decides). The diagnosis draws its own figures
(:mod:`bedstruct.diagnose.figures`)."""

from __future__ import annotations

from .metrics import (
    plot_german, plot_psd, plot_psd_along_bed, plot_packing_profile, plot_coordination,
    plot_height_map, plot_repose, plot_repose_series, plot_rdf, plot_local_packing,
)
from .fabric import (
    plot_rose, plot_rose_grid, plot_rose_2d, plot_fabric_difference, plot_fabric_differences,
    plot_fabric_evolution, plot_harmonic_power, rose_mesh,
)
from .heat import (
    plot_temperature_map, plot_temperature_history,
)

__all__ = [
    "plot_german", "plot_psd", "plot_psd_along_bed", "plot_packing_profile",
    "plot_coordination", "plot_height_map", "plot_repose", "plot_repose_series", "plot_rdf",
    "plot_local_packing", "plot_rose", "plot_rose_grid", "plot_rose_2d",
    "plot_fabric_difference", "plot_fabric_differences", "plot_fabric_evolution",
    "plot_harmonic_power", "rose_mesh", "plot_temperature_map", "plot_temperature_history",
]
