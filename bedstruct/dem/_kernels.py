"""numba kernels of the DEM engine, one import point for the orchestration.

The kernels live in focused modules, re-exported here:

* :mod:`~bedstruct.dem._kernels_contact`: the contact physics, each piece written
  once as an inline function (Hertz, damping, Mindlin history, SJKR, rolling
  resistance, capillary bridges, ageing bonds), the particle-wall contact and the
  per-type-pair table of the pair kernels;
* :mod:`~bedstruct.dem._kernels_walls`: wall geometry and candidate lists;
* :mod:`~bedstruct.dem._kernels_pairs`: the pair-force kernel (extensions
  compiled in only when on) and its single-loop pass;
* :mod:`~bedstruct.dem._kernels_pairs_blocked`: its blocked (vectorised) pass;
* :mod:`~bedstruct.dem._kernels_step`: the integrator passes;
* :mod:`~bedstruct.dem._kernels_run`: the step loop that runs them between looks at the state;
* :mod:`~bedstruct.dem._kernels_neighbours`: cell list, pair list, history remap;
* :mod:`~bedstruct.dem._kernels_rebuild`: the neighbour rebuild made of them, in one call.

All kernels are pure functions of contiguous arrays and scalars (SI units) and
write into preallocated outputs. Parallel kernels split their work into
``T`` contiguous chunks (``bounds`` arrays of length T+1) and run one chunk per
``prange`` iteration; forces go to per-chunk buffers ``fbuf[t]`` that the
integrator reduces in a fixed order, so results are deterministic for a
given number of chunks and free of races.

Conventions (as LIGGGHTS): for a pair (i, j), ``en = (x_i - x_j) / r`` points
from j to i; ``Fn > 0`` is repulsive; the force on i is ``Fn en + Ft``.
Positions of the periodic image of j are ``x_j + s L`` with the integer
image ``s`` stored per pair.
"""

from __future__ import annotations

from ._kernels_contact import (EPSD_STIFFNESS_FACTOR, ROLL_CDT, ROLL_EPSD, ROLL_EPSD2,  # noqa: F401
                               ROLL_NONE, SQRT_5_6, ageing_bond, capillary_force,
                               hertz_coefficients, hertz_stiffness, normal_force, pair_damping,
                               pair_table, rolling_torque, shear_torques, sjkr_area_pair,
                               sjkr_area_wall, tangential_history, tangential_velocity,
                               wall_contact)
from ._kernels_neighbours import (HALF_STENCIL, carry_history,  # noqa: F401
                                  cell_indices, compact_chunks, counting_sort, history_source,
                                  pair_build, pair_keys, partner_csr, permute_particles,
                                  raindrop_accept, remap_history, remap_history_csr,
                                  wrap_and_flag)
from ._kernels_rebuild import pair_list, rebuild_sorted, wall_lists  # noqa: F401
from ._kernels_pairs import PAIR_PASSES, pair_forces, pair_pass_call  # noqa: F401
from ._kernels_run import (PROGRAM_NCOL, add_wall_loads, apply_wall_programs,  # noqa: F401
                           run_steps)
from ._kernels_step import finish_step, kick_drift  # noqa: F401
from ._kernels_walls import (WALL_CYLINDER, WALL_MESH, WALL_NCOL, WALL_PLANE,  # noqa: F401
                             WALL_PRISM, WALL_RECT, closest_on_triangle, mesh_geometry,
                             candidate_lists, wall_candidates, wall_geometry)

__all__: list[str] = []
