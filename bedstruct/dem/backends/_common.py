"""Shared inputs of the external-engine backends: sphere data files
(:func:`write_sphere_data`, :func:`read_data_header`) and the SI contact
parameters that every deck generator takes (:class:`GranularParams`,
:func:`as_granular_params`).

Running decks and parsing logs live in :mod:`bedstruct.dem.backends._engine`;
their names are re-exported here so that ``from ._common import ...`` keeps
working. Everything here is plain Python; no engine is needed to import it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ._engine import (EngineInfo, EngineLog, EngineRunError, RunResult, ThermoRun, parse_log,
                      run_deck)

__all__ = [
    "EngineInfo",
    "EngineRunError",
    "RunResult",
    "ThermoRun",
    "EngineLog",
    "GranularParams",
    "as_granular_params",
    "parse_log",
    "run_deck",
    "write_sphere_data",
    "read_data_header",
]


# --------------------------------------------------------------------------- data files
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
    from ...errors import DumpFormatError

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


# --------------------------------------------------------------------------- parameters
@dataclass(frozen=True)
class GranularParams:
    """The seed's contact model in SI units, as every deck generator takes it.

    One particle type (type 1); the walls use atom type 2 in LIGGGHTS decks so
    that their coefficients can differ. ``wall_*`` values default to the
    particle-particle ones.

    Parameters
    ----------
    youngs_modulus : float, Pa
        Young's modulus E of particles (and walls unless ``wall_youngs_modulus``).
    poisson_ratio : float, dimensionless
    density : float, kg/m^3
    restitution : float, dimensionless
        Normal coefficient of restitution e in (0, 1].
    friction : float, dimensionless
        Coulomb sliding friction mu.
    rolling_friction : float, dimensionless
        Rolling friction mu_r (LIGGGHTS ``epsd2``; 0 disables it).
    cohesion_energy_density : float, J/m^3
        SJKR cohesion energy density k (0 disables cohesion).
    gravity : float, m/s^2
        Magnitude of gravity along -z (0 disables it).
    wall_youngs_modulus, wall_poisson_ratio, wall_restitution, wall_friction,
    wall_rolling_friction, wall_cohesion_energy_density : float or None
        Particle-wall values (None: same as particle-particle).

    Examples
    --------
    >>> p = GranularParams(youngs_modulus=1e7, restitution=0.1)
    >>> p.wall("friction"), p.effective_youngs_modulus()
    (0.4, 5494505.494505495)
    """

    youngs_modulus: float = 1.0e7
    poisson_ratio: float = 0.3
    density: float = 8300.0
    restitution: float = 0.1
    friction: float = 0.4
    rolling_friction: float = 0.05
    cohesion_energy_density: float = 0.0
    gravity: float = 9.81
    wall_youngs_modulus: float | None = None
    wall_poisson_ratio: float | None = None
    wall_restitution: float | None = None
    wall_friction: float | None = None
    wall_rolling_friction: float | None = None
    wall_cohesion_energy_density: float | None = None

    def __post_init__(self):
        def check(name, lo, hi, lo_open=False):
            v = getattr(self, name)
            if v is None:
                return
            ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi
            if not ok:
                br = "(" if lo_open else "["
                raise ValueError(f"`{name}` must lie in {br}{lo}, {hi}]; got {v!r}")
        for name in ("youngs_modulus", "density", "wall_youngs_modulus"):
            check(name, 0.0, math.inf, lo_open=True)
        for name in ("poisson_ratio", "wall_poisson_ratio"):
            check(name, -1.0, 0.4999999)
        for name in ("restitution", "wall_restitution"):
            check(name, 0.0, 1.0, lo_open=True)
        for name in ("friction", "rolling_friction", "cohesion_energy_density", "gravity",
                     "wall_friction", "wall_rolling_friction", "wall_cohesion_energy_density"):
            check(name, 0.0, math.inf)

    def wall(self, name: str) -> float:
        """Particle-wall value of ``name`` (e.g. ``"friction"``), defaulting to the particle one."""
        v = getattr(self, "wall_" + name)
        return getattr(self, name) if v is None else v

    def effective_youngs_modulus(self) -> float:
        """Particle-particle Hertz E* = E / (2 (1 - nu^2)) (Pa)."""
        return self.youngs_modulus / (2.0 * (1.0 - self.poisson_ratio ** 2))


def as_granular_params(model=None, **overrides) -> GranularParams:
    """Normalise contact parameters to :class:`GranularParams`.

    Parameters
    ----------
    model : GranularParams, mapping, bedstruct.dem ContactModel or None
        A mapping uses :class:`GranularParams` field names. An engine
        ``ContactModel`` (one particle type, ``materials``, ``restitution``,
        ``friction``, ``rolling_friction``, ``cohesion``, ``wall_*``) is
        converted; ``gravity`` then comes from ``overrides`` or the default.
    **overrides
        Field values that replace those of ``model``.

    Returns
    -------
    GranularParams

    Raises
    ------
    ValueError
        For an unknown key, or a multi-type ContactModel (the external decks
        support one particle type).
    TypeError
        For an object of another kind.

    Examples
    --------
    >>> as_granular_params({"restitution": 0.5}, friction=0.3).friction
    0.3
    """
    names = {f.name for f in fields(GranularParams)}
    if model is None:
        base: dict[str, Any] = {}
    elif isinstance(model, GranularParams):
        base = {f: getattr(model, f) for f in names}
    elif isinstance(model, Mapping):
        base = dict(model)
    elif hasattr(model, "materials") and hasattr(model, "restitution"):
        mats = model.materials
        mats = tuple(mats) if isinstance(mats, (list, tuple)) else (mats,)
        if len(mats) != 1:
            raise ValueError(f"external decks support one particle type; the model has {len(mats)}")

        def scalar(name, v):
            if v is None:
                return None
            arr = np.asarray(v, dtype=np.float64)
            if arr.size != 1:
                raise ValueError(f"`{name}` must be a single value for one particle type; got {arr.shape}")
            return float(arr.reshape(-1)[0])
        m0 = mats[0]
        base = dict(youngs_modulus=m0.youngs_modulus, poisson_ratio=m0.poisson_ratio,
                    density=m0.density, restitution=scalar("restitution", model.restitution),
                    friction=scalar("friction", model.friction),
                    rolling_friction=scalar("rolling_friction", model.rolling_friction),
                    cohesion_energy_density=scalar("cohesion", model.cohesion),
                    wall_restitution=scalar("wall_restitution", getattr(model, "wall_restitution", None)),
                    wall_friction=scalar("wall_friction", getattr(model, "wall_friction", None)),
                    wall_rolling_friction=scalar("wall_rolling_friction",
                                                 getattr(model, "wall_rolling_friction", None)),
                    wall_cohesion_energy_density=scalar("wall_cohesion",
                                                        getattr(model, "wall_cohesion", None)))
        rm = getattr(model, "rolling_model", "epsd2")
        if rm not in ("epsd2", "none") and base["rolling_friction"]:
            raise ValueError(f"external decks implement rolling_model 'epsd2' only; got {rm!r}")
        if rm == "none":
            base["rolling_friction"] = 0.0
        wm = getattr(model, "wall_material", None)
        if wm is not None:
            base["wall_youngs_modulus"] = wm.youngs_modulus
            base["wall_poisson_ratio"] = wm.poisson_ratio
    else:
        raise TypeError("`model` must be GranularParams, a mapping of its fields or a "
                        f"bedstruct.dem ContactModel; got {type(model).__name__}")
    base.update(overrides)
    unknown = set(base) - names
    if unknown:
        raise ValueError(f"unknown contact parameter(s) {sorted(unknown)}; expected some of "
                         f"{sorted(names)}")
    return GranularParams(**base)
