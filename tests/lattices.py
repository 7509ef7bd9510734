"""Lattices with exactly known answers, shared by the tests.

Import with ``from lattices import cubic_lattice, fcc_lattice`` (tests/ is on the path;
a uniquely named module, because several conftest.py files would shadow each other).
"""

import numpy as np

from bedstruct import Box, Frame


def cubic_lattice(n=(4, 4, 4), spacing=1.0, radius=0.5, boundary=("pp", "pp", "pp")) -> Frame:
    """Simple cubic lattice of touching spheres filling a periodic box exactly."""
    n = np.asarray(n)
    grid = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    pos = (grid + 0.5) * spacing
    box = Box([0, 0, 0], n * spacing, boundary=boundary)
    return Frame(pos, np.full(len(pos), radius), box=box)


def fcc_lattice(n=(3, 3, 3), a=np.sqrt(2.0), boundary=("pp", "pp", "pp")) -> Frame:
    """FCC lattice of touching unit-diameter spheres (a = sqrt(2) d)."""
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    n = np.asarray(n)
    grid = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    pos = ((grid[:, None, :] + basis[None]) * a).reshape(-1, 3) + 0.25 * a
    box = Box([0, 0, 0], n * a, boundary=boundary)
    return Frame(pos, np.full(len(pos), a / (2 * np.sqrt(2.0))), box=box)
