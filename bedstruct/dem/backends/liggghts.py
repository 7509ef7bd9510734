"""LIGGGHTS 3.8 backend: locate the Debian ``liggghts`` binary and write the
seed's contact model (hertz + tangential history + SJKR cohesion + EPSD2 rolling
friction) as LIGGGHTS input commands.

The deck generators that users call are in :mod:`bedstruct.dem.backends.decks`
(``bed_deck(..., engine="liggghts")`` and friends); this module holds the
LIGGGHTS dialect.
"""

from __future__ import annotations

import os
import shutil
import subprocess

from ._common import EngineInfo, GranularParams

__all__ = ["find_liggghts", "liggghts_model_commands", "liggghts_wall_model"]

_RUN_AS_ROOT = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}


def _openmpi_launcher() -> str | None:
    for name in ("mpirun.openmpi", "orterun", "mpiexec.openmpi"):
        path = shutil.which(name)
        if path:
            return path
    path = shutil.which("mpirun")
    if path:
        try:
            out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=20,
                                 env={**os.environ, **_RUN_AS_ROOT}).stdout
        except (OSError, subprocess.SubprocessError):
            return None
        if "Open MPI" in out or "OpenRTE" in out:
            return path
    return None


def find_liggghts(executable: str | None = None) -> EngineInfo | None:
    """Locate LIGGGHTS and the OpenMPI launcher it was built against.

    Looks at ``executable``, then ``$BEDSTRUCT_LIGGGHTS``, then ``liggghts`` on
    ``PATH`` (Debian package ``liggghts``, 3.8.0). The Debian binary links
    OpenMPI (``libmpi.so.40``), so the launcher is ``mpirun.openmpi`` (or
    ``orterun``), never an MPICH ``mpirun`` that a virtual environment may put
    first on ``PATH``. When running as root, OpenMPI's run-as-root switches are
    added to the environment, and ``--oversubscribe`` to the launcher flags.

    Parameters
    ----------
    executable : str, optional
        Explicit path or name of the LIGGGHTS binary.

    Returns
    -------
    EngineInfo or None
        None when no binary is found.

    Examples
    --------
    >>> info = find_liggghts()
    >>> info is None or info.name == "liggghts"
    True
    """
    exe = executable or os.environ.get("BEDSTRUCT_LIGGGHTS") or "liggghts"
    path = shutil.which(exe)
    if path is None:
        return None
    env = {"OMPI_MCA_btl_vader_single_copy_mechanism": "none"}
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        env.update(_RUN_AS_ROOT)
    return EngineInfo("liggghts", path, _openmpi_launcher(), ("--oversubscribe",), env)


def _fmt(x: float) -> str:
    return f"{float(x):.10g}"


def liggghts_wall_model(params: GranularParams) -> str:
    """The ``model ...`` words shared by ``pair_style gran`` and ``fix wall/gran``.

    Cohesion (``sjkr``) and rolling friction (``epsd2``) are included only when
    their coefficients are non-zero for particles or walls.

    Examples
    --------
    >>> liggghts_wall_model(GranularParams(cohesion_energy_density=3.2e7))
    'model hertz tangential history cohesion sjkr rolling_friction epsd2'
    >>> liggghts_wall_model(GranularParams(rolling_friction=0.0))
    'model hertz tangential history'
    """
    words = "model hertz tangential history"
    if params.cohesion_energy_density > 0 or params.wall("cohesion_energy_density") > 0:
        words += " cohesion sjkr"
    if params.rolling_friction > 0 or params.wall("rolling_friction") > 0:
        words += " rolling_friction epsd2"
    return words


def liggghts_model_commands(params: GranularParams, *, n_types: int = 2) -> tuple[list[str], int]:
    """Material fixes and ``pair_style gran`` lines for ``n_types`` atom types.

    Particles are type 1; walls use type 2 when ``n_types >= 2`` (their own
    coefficients), else type 1 (then the wall values must equal the particle
    values).

    Returns
    -------
    lines : list of str
    wall_type : int

    Raises
    ------
    ValueError
        If walls need their own coefficients but the box has one atom type.

    Examples
    --------
    >>> lines, wt = liggghts_model_commands(GranularParams(youngs_modulus=1e8), n_types=2)
    >>> lines[0]
    'fix m1 all property/global youngsModulus peratomtype 100000000 100000000'
    >>> wt
    2
    """
    p = params
    if n_types >= 2:
        wt = 2
    else:
        wt = 1
        for name in ("youngs_modulus", "poisson_ratio", "restitution", "friction",
                     "rolling_friction", "cohesion_energy_density"):
            if p.wall(name) != getattr(p, name):
                raise ValueError(f"wall {name} differs from the particle value but the data file "
                                 "declares 1 atom type; write it with n_types=2 so that walls "
                                 "get atom type 2")

    def per_type(name):
        vals = [p.wall(name) if t == wt else getattr(p, name) for t in range(1, n_types + 1)]
        return " ".join(_fmt(v) for v in vals)

    def per_pair(name):
        vals = []
        for i in range(1, n_types + 1):
            for j in range(1, n_types + 1):
                wall = (i == wt) != (j == wt)
                vals.append(p.wall(name) if wall else getattr(p, name))
        return f"{n_types} " + " ".join(_fmt(v) for v in vals)

    lines = [
        f"fix m1 all property/global youngsModulus peratomtype {per_type('youngs_modulus')}",
        f"fix m2 all property/global poissonsRatio peratomtype {per_type('poisson_ratio')}",
        f"fix m3 all property/global coefficientRestitution peratomtypepair {per_pair('restitution')}",
        f"fix m4 all property/global coefficientFriction peratomtypepair {per_pair('friction')}",
    ]
    model = liggghts_wall_model(p)
    if "epsd2" in model:
        lines.append("fix m5 all property/global coefficientRollingFriction peratomtypepair "
                     f"{per_pair('rolling_friction')}")
    if "sjkr" in model:
        lines.append("fix m6 all property/global cohesionEnergyDensity peratomtypepair "
                     f"{per_pair('cohesion_energy_density')}")
    lines += [f"pair_style gran {model}", "pair_coeff * *"]
    return lines, wt
