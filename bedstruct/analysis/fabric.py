"""Fabric tensors of contact normals (Kanatani 1984), ranks 2 and 4, three kinds.

For unit directions :math:`n^{(a)}` with weights :math:`w_a` (1 by default)
the tensors of the *first kind* (moment tensors) are the weighted means

.. math::

    N_{ij} = \\langle n_i n_j \\rangle, \\qquad N_{ijkl} = \\langle n_i n_j n_k n_l \\rangle .

A contact's direction ``n`` and ``-n`` give the same even-rank products, so
these tensors are antipodally symmetric by construction. The *second kind*
(fabric tensors) and the *third kind* (deviatoric tensors) are

.. math::

    F_{ij} = \\tfrac{15}{2}\\left(N_{ij} - \\tfrac15 \\delta_{ij}\\right), \\quad
    F_{ijkl} = \\tfrac{315}{8}\\left(N_{ijkl} - \\tfrac23 \\delta_{(ij}N_{kl)}
               + \\tfrac1{21}\\delta_{(ij}\\delta_{kl)}\\right),

    D_{ij} = \\tfrac{15}{2}\\left(N_{ij} - \\tfrac13 \\delta_{ij}\\right), \\quad
    D_{ijkl} = \\tfrac{315}{8}\\left(N_{ijkl} - \\tfrac67 \\delta_{(ij}N_{kl)}
               + \\tfrac3{35}\\delta_{(ij}\\delta_{kl)}\\right),

with the full symmetrisation
:math:`\\delta_{(ij}N_{kl)} = (\\delta_{ij}N_{kl} + \\delta_{ik}N_{jl} + \\delta_{il}N_{jk}
+ \\delta_{jk}N_{il} + \\delta_{jl}N_{ik} + \\delta_{kl}N_{ij})/6` and
:math:`\\delta_{(ij}\\delta_{kl)} = (\\delta_{ij}\\delta_{kl} + \\delta_{ik}\\delta_{jl}
+ \\delta_{il}\\delta_{jk})/3`. They approximate the direction density
(per unit solid angle, integrating to 1 over the sphere)

.. math::

    f(n) = \\frac{1}{4\\pi}\\left(1 + D_{ij} n_i n_j + D_{ijkl} n_i n_j n_k n_l\\right)
         = \\frac{1}{4\\pi} F_{ijkl} n_i n_j n_k n_l ,

which is the truncation at degree 4 of the density's spherical-harmonic
series (see :mod:`bedstruct.analysis.harmonics` and ``docs/fabric.md`` for
the derivation). All quantities are dimensionless.

References
----------
K. Kanatani, "Distribution of directional data and fabric tensors",
Int. J. Eng. Sci. 22 (1984) 149-164, https://doi.org/10.1016/0020-7225(84)90090-9
"""

# The implementation is split by topic: tensor algebra (_fabric_algebra), tensors of
# directions and the densities they approximate (_fabric_tensors), regions along the bed
# and tables (_fabric_regions), LAMMPS conventions (_fabric_lammps). Import from here.

from ._fabric_algebra import deviatoric_rank4, isotropic_rank4, sym_delta_tensor
from ._fabric_lammps import LammpsFabric, lammps_fabric, lammps_voigt
from ._fabric_regions import RegionFabric, contact_regions, fabric_table, region_fabric
from ._fabric_tensors import (FabricTensors, fabric_density, fabric_tensors, projected_density,
                              sample_directions)

__all__ = [
    "FabricTensors", "fabric_tensors", "fabric_density", "projected_density",
    "sample_directions", "contact_regions", "RegionFabric", "region_fabric",
    "LammpsFabric", "lammps_fabric", "lammps_voigt", "fabric_table",
    "deviatoric_rank4", "sym_delta_tensor", "isotropic_rank4",
]
