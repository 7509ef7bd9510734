"""Analyses of frames and contacts: packing, coordination, PSD, surface,
angle of repose, fabric tensors, spherical harmonics and heat conduction.

Each module keeps its own ``__all__``; this package re-exports them all.
"""

from .._lazy import collect as _collect

__all__ = _collect(__name__, [
    "contacts", "coordination", "packing", "german", "psd", "segregation", "surface", "repose",
    "fabric", "harmonics", "heat", "heat_study", "timeseries", "bed_state", "rdf", "voronoi",
], globals())
