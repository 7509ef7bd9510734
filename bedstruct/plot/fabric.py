"""Rose diagrams of contact-normal fabric: 3-D roses, planar roses, differences, evolution.

Every function builds on :class:`matplotlib.figure.Figure` (never pyplot),
never shows or saves, and returns the ``Figure`` it drew on (when axes are
given, their figure). Roses are drawn as the closed surface
:math:`r(n) = 4\\pi |f(n)|` (``relative=True``, so an isotropic sample is the
unit sphere) coloured by the signed value :math:`4\\pi f(n)`, with
:math:`f` from :func:`~bedstruct.analysis.fabric.fabric_density` (tensors)
or :func:`~bedstruct.analysis.harmonics.harmonic_density` (expansions).
"""

# Split by figure family: roses of one fabric (_fabric_roses) and comparisons between
# regions or frames (_fabric_compare). Import from here.

from ._fabric_compare import (plot_fabric_difference, plot_fabric_differences,
                              plot_fabric_evolution, plot_harmonic_power)
from ._fabric_roses import plot_rose, plot_rose_2d, plot_rose_grid, rose_mesh

__all__ = [
    "plot_rose", "plot_rose_grid", "plot_rose_2d", "plot_fabric_difference",
    "plot_fabric_differences", "plot_fabric_evolution", "plot_harmonic_power", "rose_mesh",
]
