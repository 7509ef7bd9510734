"""Shared fixtures: tiny lattices with exactly known answers."""

from __future__ import annotations

import os
import pathlib

import numpy as np
import pytest

import bedstruct
from bedstruct import Box, Frame

ROOT = pathlib.Path(__file__).resolve().parents[1]
REALDATA = pathlib.Path(os.environ.get("BEDSTRUCT_REALDATA", ROOT.parent / "shared" / "realdata"))


@pytest.fixture
def realdata() -> pathlib.Path:
    """The folder of third-party LIGGGHTS/LAMMPS files (skips when absent)."""
    if not REALDATA.is_dir():
        pytest.skip(f"third-party files not found at {REALDATA} (set BEDSTRUCT_REALDATA)")
    return REALDATA


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


@pytest.fixture
def sc_frame() -> Frame:
    return cubic_lattice()


@pytest.fixture
def fcc_frame() -> Frame:
    return fcc_lattice()


@pytest.fixture
def random_bed() -> Frame:
    """A random polydisperse frame in a `pp pp ff` box (overlaps allowed)."""
    rng = np.random.default_rng(7)
    n = 400
    box = Box([0, 0, 0], [10, 8, 6], boundary="pp pp ff")
    pos = rng.uniform([0, 0, 0], [10, 8, 6], size=(n, 3))
    radii = rng.uniform(0.3, 0.8, size=n)
    return Frame(pos, radii, box=box, timestep=100)
