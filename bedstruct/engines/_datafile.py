"""Sphere data files as the decks read them: :func:`write_sphere_data` (atom types
declared beyond those the spheres use, so that walls get their own type),
:func:`read_data_header` (counts and box) and :func:`data_file_radii`.

The atoms of a data file are read by :func:`bedstruct.io.read_data`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DumpFormatError

__all__ = ["write_sphere_data", "read_data_header", "data_file_radii"]


def write_sphere_data(path, positions, radii, *, box_lo, box_hi, density=8300.0, types=None,
                      velocities=None, omegas=None, n_types: int | None = None,
                      title: str = "bedstruct"):
    """Write a LAMMPS/LIGGGHTS data file for ``atom_style sphere`` / ``granular``.

    Atom lines are ``id type diameter density x y z`` (the same for both
    engines). Units are whatever the deck uses; bedstruct's decks use SI.

    Parameters
    ----------
    path : str or os.PathLike
        Output file.
    positions : (N, 3) array_like of float, length
    radii : (N,) array_like of float, length
    box_lo, box_hi : (3,) array_like of float, length
        Box bounds.
    density : float or (N,) array_like, mass/length^3
        Particle density.
    types : (N,) array_like of int, optional
        Atom types (default all 1).
    velocities : (N, 3) array_like of float, optional
        Initial velocities (length/time).
    omegas : (N, 3) array_like of float, optional
        Initial angular velocities (rad/time); 0 when only ``velocities`` is given.
    n_types : int, optional
        Number of atom types declared in the header (default ``max(types)``).
        Give one more than the particle types when walls have their own type.
    title : str
        First line of the file.

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import tempfile, os
    >>> d = tempfile.mkdtemp()
    >>> p = write_sphere_data(os.path.join(d, "two.data"), [[0, 0, 1], [0, 0, 3]], [1, 1],
    ...                       box_lo=[-2, -2, 0], box_hi=[2, 2, 4], n_types=2)
    >>> read_data_header(p)["atoms"], read_data_header(p)["atom types"]
    (2, 2)
    """
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    rad = np.asarray(radii, dtype=np.float64).reshape(-1)
    n = len(pos)
    if rad.shape != (n,):
        raise ValueError(f"`radii` must have shape (N,) matching `positions` (N={n}); got {rad.shape}")
    if np.any(~np.isfinite(rad)) or np.any(rad <= 0):
        raise ValueError("`radii` must be positive and finite")
    typ = np.ones(n, dtype=np.int64) if types is None else np.asarray(types, dtype=np.int64)
    if typ.shape != (n,) or (n and typ.min() < 1):
        raise ValueError(f"`types` must be (N,) integers >= 1 (N={n}); got shape {typ.shape}")
    rho = np.broadcast_to(np.asarray(density, dtype=np.float64), (n,))
    lo = np.asarray(box_lo, dtype=np.float64).reshape(3)
    hi = np.asarray(box_hi, dtype=np.float64).reshape(3)
    if np.any(hi <= lo):
        raise ValueError(f"`box_hi` must exceed `box_lo` on every axis; got {lo} and {hi}")
    nt = int(n_types if n_types is not None else (typ.max() if n else 1))
    if n and nt < typ.max():
        raise ValueError(f"`n_types`={nt} is smaller than the largest type {typ.max()}")
    path = Path(path)
    with open(path, "w") as fh:
        fh.write(f"{title}\n\n{n} atoms\n{nt} atom types\n\n")
        for k, ax in enumerate("xyz"):
            fh.write(f"{lo[k]:.17g} {hi[k]:.17g} {ax}lo {ax}hi\n")
        fh.write("\nAtoms\n\n")
        table = np.column_stack([np.arange(1, n + 1), typ, 2 * rad, rho, pos])
        np.savetxt(fh, table, fmt=["%d", "%d", "%.17g", "%.17g", "%.17g", "%.17g", "%.17g"])
        if velocities is not None or omegas is not None:
            vel = (np.zeros((n, 3)) if velocities is None
                   else np.asarray(velocities, dtype=np.float64).reshape(n, 3))
            om = (np.zeros((n, 3)) if omegas is None
                  else np.asarray(omegas, dtype=np.float64).reshape(n, 3))
            fh.write("\nVelocities\n\n")
            np.savetxt(fh, np.column_stack([np.arange(1, n + 1), vel, om]),
                       fmt=["%d"] + ["%.17g"] * 6)
    return path


_HEADER_KEYS = ("atoms", "atom types", "bonds", "ellipsoids")


def read_data_header(path) -> dict:
    """Read the header of a LAMMPS/LIGGGHTS data file.

    Returns
    -------
    dict
        ``atoms`` (int), ``atom types`` (int), ``lo`` and ``hi`` ((3,) float
        arrays of box bounds, length), ``tilt`` ((3,) xy xz yz or None).

    Raises
    ------
    bedstruct.errors.DumpFormatError
        If the counts or box bounds are missing.
    """
    out: dict[str, Any] = {"lo": np.full(3, np.nan), "hi": np.full(3, np.nan), "tilt": None}
    with open(path, errors="replace") as fh:
        fh.readline()
        for lineno, raw in enumerate(fh, start=2):
            line = raw.split("#")[0].strip()
            if not line:
                continue
            toks = line.split()
            if toks[0][0].isalpha():  # first section keyword ends the header
                break
            for key in _HEADER_KEYS:
                if line.endswith(key) and len(toks) == len(key.split()) + 1:
                    out[key] = int(toks[0])
            for k, ax in enumerate("xyz"):
                if line.endswith(f"{ax}lo {ax}hi"):
                    out["lo"][k], out["hi"][k] = float(toks[0]), float(toks[1])
            if line.endswith("xy xz yz"):
                out["tilt"] = np.array([float(t) for t in toks[:3]])
    if "atoms" not in out or "atom types" not in out or np.any(np.isnan(out["lo"])):
        raise DumpFormatError("data file header lacks 'N atoms', 'N atom types' or box bounds",
                              path=str(path))
    return out


def data_file_radii(path) -> np.ndarray:
    """Radii (length) of the ``Atoms`` section of a sphere/granular data file, in file order.

    Read by :func:`bedstruct.io.read_data` (the ``diameter`` column of ``id type
    diameter density x y z ...``).

    Examples
    --------
    >>> import tempfile, os
    >>> p = write_sphere_data(os.path.join(tempfile.mkdtemp(), "a.data"), [[0, 0, 1]], [0.5],
    ...                       box_lo=[-1, -1, 0], box_hi=[1, 1, 2])
    >>> data_file_radii(p).tolist()
    [0.5]
    """
    # bedstruct.io compiles numba kernels on import (seconds): imported when a deck is written,
    # so that importing the engines (and the workflows above them) stays quick
    from ..io import read_data
    return np.asarray(read_data(path).radii, dtype=np.float64)
