"""The embedded DEM engine: Hertz-Mindlin spheres with SJKR cohesion and rolling resistance.

Build a :class:`Simulation` from a box, a :class:`ContactModel` and walls, add
particles (:meth:`Simulation.add_particles`, :meth:`Simulation.insert_raindrop`,
:meth:`Simulation.insert_frame`), :meth:`Simulation.run`, and read the state as
a :class:`bedstruct.Frame` (:meth:`Simulation.frame`) and
:class:`bedstruct.Contacts` (:meth:`Simulation.contacts`). SI units throughout;
see docs/engine.md for the equations.
"""

from .insertion import raindrop_positions, sample_radii
from .output import RunDirectory
from .params import (ContactModel, Material, effective_shear_modulus, effective_youngs_modulus,
                     hertz_time, rayleigh_time, restitution_beta, seed_contact_model)
from .simulation import NumericalInstabilityError, RunStats, Simulation, WallState
from .walls import (Blade, Cylinder, Plane, Prism, Rectangle, TriangleMesh, box_walls, read_stl,
                    repose_box)

__all__ = ["Simulation", "RunStats", "WallState", "NumericalInstabilityError", "ContactModel", "Material",
           "seed_contact_model", "RunDirectory",
           "Plane", "Rectangle", "Prism", "Blade", "Cylinder", "TriangleMesh", "box_walls",
           "repose_box", "read_stl", "sample_radii", "raindrop_positions", "rayleigh_time",
           "hertz_time", "effective_youngs_modulus", "effective_shear_modulus",
           "restitution_beta"]
