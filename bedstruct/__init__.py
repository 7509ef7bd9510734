"""bedstruct: quantify powder beds from DEM particle data.

Readers for LIGGGHTS/LAMMPS files produce :class:`Frame` objects (spheres in a
:class:`Box`) and :class:`Contacts`; analyses consume them; an embedded DEM
engine writes them. Heavy subpackages are imported on first use.

Examples
--------
>>> import bedstruct
>>> frame = bedstruct.Frame([[0, 0, 0], [1, 0, 0]], [0.5, 0.5], box=[2, 2, 2])
>>> frame.n_particles
2
"""

from __future__ import annotations

import importlib

from ._json import to_jsonable
from ._version import __version__
from .core import Box, Contacts, Frame, FrameList, Provenance, Trajectory, Units, WallContacts
from .errors import ConfigError, DumpFormatError, UnsafeTimestepError

# Public names that live in subpackages, imported lazily so that `import bedstruct`
# stays fast (numba, scipy, matplotlib load only when needed).
_LAZY = {
    # io
    "read": "bedstruct.io", "read_dump": "bedstruct.io", "iter_frames": "bedstruct.io",
    "read_dump_local": "bedstruct.io", "read_data": "bedstruct.io",
    "write_dump": "bedstruct.io", "write_data": "bedstruct.io", "write_dump_local": "bedstruct.io",
    "save_hdf5": "bedstruct.io", "load_hdf5": "bedstruct.io",
    "to_universe": "bedstruct.io", "from_universe": "bedstruct.io", "to_pyvista": "bedstruct.io",
    # analysis
    "find_contacts": "bedstruct.analysis", "coordination": "bedstruct.analysis",
    "packing_fraction": "bedstruct.analysis", "fit_german_law": "bedstruct.analysis",
    "psd_from_percentiles": "bedstruct.analysis", "angle_of_repose": "bedstruct.analysis",
    "fabric_tensors": "bedstruct.analysis", "harmonic_expansion": "bedstruct.analysis",
    "packing_along": "bedstruct.analysis", "surface_height_map": "bedstruct.analysis",
    "segregation": "bedstruct.analysis", "dynamic_angle_of_repose": "bedstruct.analysis",
    "particle_size_distribution": "bedstruct.analysis", "region_fabric": "bedstruct.analysis",
    "conduct_heat": "bedstruct.analysis", "thermal_network": "bedstruct.analysis",
    "temperature_map": "bedstruct.analysis", "haz_shape": "bedstruct.analysis",
    "conductivity_tensor": "bedstruct.analysis",
    # engine
    "Simulation": "bedstruct.dem", "ContactModel": "bedstruct.dem", "Material": "bedstruct.dem",
    # workflows
    "load_config": "bedstruct.workflows", "run_repose": "bedstruct.workflows",
    "run_spread": "bedstruct.workflows", "calibrate_cohesion": "bedstruct.workflows",
    # report
    "build_report": "bedstruct.report", "report_on_files": "bedstruct.report",
    # plots
    "plot_rose": "bedstruct.plot", "plot_temperature_map": "bedstruct.plot",
}

__all__ = ["__version__", "Box", "Frame", "FrameList", "Trajectory", "Units", "Provenance",
           "Contacts", "WallContacts", "DumpFormatError", "ConfigError", "UnsafeTimestepError",
           "to_jsonable",
           *_LAZY]


# Subpackages, importable as attributes after a plain ``import bedstruct``.
_SUBPACKAGES = ("io", "analysis", "plot", "dem", "engines", "workflows", "report", "diagnose")


def __getattr__(name: str):
    if name in _SUBPACKAGES:
        value = importlib.import_module(f"bedstruct.{name}")
    else:
        module = _LAZY.get(name)
        if module is None:
            raise AttributeError(f"module 'bedstruct' has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | set(_SUBPACKAGES))
