"""Readers and writers: LAMMPS/LIGGGHTS dumps, dump local, data files, HDF5, interop.

Examples
--------
>>> import bedstruct.io
>>> "read_dump" in bedstruct.io.__all__
True
"""

from .data_file import read_data, write_data
from .dump_local import (PAIR_GRAN_LOCAL_DEFAULT, PAIR_GRAN_LOCAL_ORDER, liggghts_local_columns,
                         read_dump_local, write_dump_local)
from .formats import FORMATS, detect_format, read
from .hdf5 import HDF5Contents, load_hdf5, save_hdf5
from .interop import from_universe, to_pyvista, to_universe
from .lammps_dump import DumpTrajectory, SkippedFrame, iter_frames, read_dump, write_dump
from .summary import format_summary, summarise, summarise_all

__all__ = ["read", "detect_format", "FORMATS", "read_dump", "iter_frames", "read_dump_local", "read_data", "write_dump",
           "write_data", "write_dump_local", "save_hdf5", "load_hdf5", "to_universe",
           "from_universe", "to_pyvista", "summarise", "summarise_all", "format_summary",
           "DumpTrajectory", "SkippedFrame",
           "HDF5Contents", "liggghts_local_columns", "PAIR_GRAN_LOCAL_ORDER",
           "PAIR_GRAN_LOCAL_DEFAULT"]
