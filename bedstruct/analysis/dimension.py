"""Whether a frame is a 2-D run: discs in a plane rather than spheres in space.

A LAMMPS ``dimension 2`` run keeps every particle at one z in a periodic z
box of any thickness. Read as 3-D, each sphere touches its own image across
a z box thinner than a diameter, and volumes are taken over a slab that has
no physical meaning. :func:`flat_axis` recognises such a frame so that the
analyses can treat its particles as discs.
"""

from __future__ import annotations

import numpy as np

from ..core.frame import _as_frame

__all__ = ["flat_axis", "AXIS_NAMES"]

#: Names of the three axes.
AXIS_NAMES = "xyz"

# centres closer together along an axis than this fraction of the largest diameter share a plane
_FLAT_TOLERANCE = 1e-9
# fewer particles than this lie in a plane by chance (a line, a pair)
_MIN_FLAT_PARTICLES = 3


def flat_axis(frame) -> int | None:
    """The axis a 2-D run lies flat along, or None for a 3-D frame.

    Parameters
    ----------
    frame : Frame or (box, positions, radii)

    Returns
    -------
    int or None
        0, 1 or 2 when every particle centre has the same coordinate along
        that axis (within 1e-9 of the largest diameter) and the axis is
        periodic (a LAMMPS 2-D run: z periodic, every particle at one z) or
        the box along it is thinner than the largest diameter; z is
        preferred when several axes qualify. None otherwise, and for frames
        of fewer than 3 particles, whose centres always share a plane.

    Notes
    -----
    A single layer of spheres in a periodic box one diameter thick (a 3-D
    crystal one cell high) also shares one coordinate along a periodic axis;
    it is read as 2-D, as LAMMPS would run it.

    Examples
    --------
    >>> import numpy as np
    >>> from bedstruct import Box, Frame
    >>> g = np.stack(np.meshgrid(np.arange(4), np.arange(4), [0.0], indexing="ij"), -1).reshape(-1, 3)
    >>> discs = Frame(g + [0.5, 0.5, 0], np.full(16, 0.5), box=Box([0, 0, -0.25], [4, 4, 0.25]))
    >>> flat_axis(discs)
    2
    >>> flat_axis(Frame(g + [0.5, 0.5, 1.5], np.full(16, 0.5), box=Box([0, 0, 0], [4, 4, 3], boundary="pp pp ff")))
    """
    frame = _as_frame(frame)
    if frame.n_particles < _MIN_FLAT_PARTICLES:
        return None
    pos = frame.positions
    d_max = 2.0 * float(frame.radii.max())
    box = frame.box
    widths = np.abs(np.diag(box.matrix))
    for k in (2, 0, 1):
        if float(np.ptp(pos[:, k])) > _FLAT_TOLERANCE * d_max:
            continue
        if box.periodic[k] or widths[k] < d_max:
            return k
    return None
