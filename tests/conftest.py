"""Shared fixtures: tiny lattices with exactly known answers."""

from __future__ import annotations

import os
import pathlib

import numpy as np
import pytest

import bedstruct
from bedstruct import Box, Frame
from lattices import cubic_lattice, fcc_lattice  # noqa: F401  (re-exported for fixtures)

ROOT = pathlib.Path(__file__).resolve().parents[1]
REALDATA = pathlib.Path(os.environ.get("BEDSTRUCT_REALDATA", ROOT.parent / "shared" / "realdata"))


@pytest.fixture
def realdata() -> pathlib.Path:
    """The folder of third-party LIGGGHTS/LAMMPS files (skips when absent)."""
    if not REALDATA.is_dir():
        pytest.skip(f"third-party files not found at {REALDATA} (set BEDSTRUCT_REALDATA)")
    return REALDATA


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
