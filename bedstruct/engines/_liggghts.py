"""The LIGGGHTS 3.8 dialect (:class:`LiggghtsDialect`): the Debian ``liggghts`` binary
under OpenMPI (:func:`find_liggghts`), the seed's contact model as ``pair_style gran
model hertz tangential history`` with SJKR cohesion and EPSD2 rolling friction
(:func:`liggghts_model_commands`), and walls as STL meshes (``fix mesh/surface``)
moved by ``fix move/mesh``. The diagnosis' effects it realises are stated in
:data:`LIGGGHTS_REALISATIONS`; liquid bridges are its own model (:class:`LiquidBridges`).
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BedstructWarning, ConfigError
from ._dialect import Dialect, Realisation, effects_on, option, path_word
from ._launch import EngineInfo
from ._params import coefficient
from ._registry import register
from ._stl import RollerGeometry, _chamber_meshes, repose_wall_stls, write_stl

__all__ = ["LiggghtsDialect", "LiquidBridges", "LIGGGHTS_REALISATIONS", "find_liggghts",
           "check_easo_bridges", "EASO_MIN_BRIDGE_VOLUME", "easo_bridge_volume",
           "liggghts_model_commands", "liggghts_wall_model"]

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


def liggghts_wall_model(model) -> str:
    """The ``model ...`` words shared by ``pair_style gran`` and ``fix wall/gran``.

    ``model`` is a one-type :class:`~bedstruct.dem.ContactModel`. Cohesion (``sjkr``)
    and rolling friction (``model.rolling_model``) are included only when their
    coefficients are non-zero for particles or walls.

    Examples
    --------
    >>> from bedstruct.dem import seed_contact_model
    >>> liggghts_wall_model(seed_contact_model(cohesion=3.2e7))
    'model hertz tangential history cohesion sjkr rolling_friction epsd2'
    >>> liggghts_wall_model(seed_contact_model(rolling_friction=0.0))
    'model hertz tangential history'
    >>> liggghts_wall_model(seed_contact_model(rolling_model="cdt"))
    'model hertz tangential history rolling_friction cdt'
    """
    words = "model hertz tangential history"
    if max(coefficient(model, "cohesion"), coefficient(model, "cohesion", wall=True)) > 0:
        words += " cohesion sjkr"
    if max(coefficient(model, "rolling_friction"),
           coefficient(model, "rolling_friction", wall=True)) > 0:
        words += f" rolling_friction {model.rolling_model}"
    return words


def liggghts_model_commands(model, *, n_types: int = 2) -> tuple[list[str], int]:
    """Material fixes and ``pair_style gran`` lines of a one-type
    :class:`~bedstruct.dem.ContactModel` for ``n_types`` atom types.

    Particles are type 1; walls use type 2 when ``n_types >= 2`` (their own
    coefficients: ``wall_material`` and the ``wall_*`` values), else type 1 (then
    the wall values must equal the particle values).

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
    >>> from bedstruct.dem import seed_contact_model
    >>> lines, wt = liggghts_model_commands(seed_contact_model(youngs_modulus=1e8), n_types=2)
    >>> lines[0]
    'fix m1 all property/global youngsModulus peratomtype 100000000 100000000'
    >>> wt
    2
    """
    def value(name, wall=False):
        return coefficient(model, name, wall=wall)

    if n_types >= 2:
        wt = 2
    else:
        wt = 1
        for name in ("youngs_modulus", "poisson_ratio", "restitution", "friction",
                     "rolling_friction", "cohesion"):
            if value(name, wall=True) != value(name):
                raise ValueError(f"wall {name} differs from the particle value but the data file "
                                 "declares 1 atom type; write it with n_types=2 so that walls "
                                 "get atom type 2")

    def per_type(name):
        vals = [value(name, wall=t == wt) for t in range(1, n_types + 1)]
        return " ".join(_fmt(v) for v in vals)

    def per_pair(name):
        vals = []
        for i in range(1, n_types + 1):
            for j in range(1, n_types + 1):
                vals.append(value(name, wall=(i == wt) != (j == wt)))
        return f"{n_types} " + " ".join(_fmt(v) for v in vals)

    lines = [
        f"fix m1 all property/global youngsModulus peratomtype {per_type('youngs_modulus')}",
        f"fix m2 all property/global poissonsRatio peratomtype {per_type('poisson_ratio')}",
        f"fix m3 all property/global coefficientRestitution peratomtypepair {per_pair('restitution')}",
        f"fix m4 all property/global coefficientFriction peratomtypepair {per_pair('friction')}",
    ]
    words = liggghts_wall_model(model)
    if "rolling_friction" in words:
        lines.append("fix m5 all property/global coefficientRollingFriction peratomtypepair "
                     f"{per_pair('rolling_friction')}")
    if "sjkr" in words:
        lines.append("fix m6 all property/global cohesionEnergyDensity peratomtypepair "
                     f"{per_pair('cohesion')}")
    if "rolling_friction epsd " in words + " ":
        # LIGGGHTS' EPSD carries a rolling dashpot; the same damping ratio at every pair
        lines.append("fix m7 all property/global coefficientRollingViscousDamping peratomtypepair "
                     f"{n_types} " + " ".join([_fmt(model.rolling_damping)] * n_types ** 2))
    lines += [f"pair_style gran {words}", "pair_coeff * *"]
    return lines, wt


#: Smallest bridge LIGGGHTS 3.8's ``easo/capillary/viscous`` acts on, m^3 (SI decks): it
#: skips a pair whose bridge volume ``V`` has ``1000 V < 1e-14`` (a fixed cut-off in its
#: source), giving neither capillary nor viscous force, while the model has taken the place
#: of the particles' SJKR cohesion.
EASO_MIN_BRIDGE_VOLUME = 1e-17


def easo_bridge_volume(r_i, r_j, liquid_volume_fraction: float):
    """Bridge volume (m^3) of LIGGGHTS 3.8's easo model between spheres of radii ``r_i``, ``r_j``.

    Each particle gives ``V_p (1 - sqrt(1 - r_o^2 / (r_i + r_j)^2)) / 2`` of its liquid
    ``V_p = (4/3) pi r^3 liquid_volume_fraction`` (``r_o`` the other radius); between equal
    spheres the bridge is ``(1 - sqrt(3)/2) V_p``.

    Examples
    --------
    >>> from bedstruct.engines import easo_bridge_volume
    >>> v = easo_bridge_volume(1.0, 1.0, 1.0)
    >>> round(float(v) / (4 / 3 * math.pi), 4)   # 1 - sqrt(3)/2 of one particle's volume
    0.134
    """
    r_i, r_j = np.asarray(r_i, float), np.asarray(r_j, float)
    rs = r_i + r_j
    vi = 4.0 / 3.0 * np.pi * r_i ** 3 * liquid_volume_fraction
    vj = 4.0 / 3.0 * np.pi * r_j ** 3 * liquid_volume_fraction
    return (0.5 * vi * (1 - np.sqrt(1 - r_j ** 2 / rs ** 2))
            + 0.5 * vj * (1 - np.sqrt(1 - r_i ** 2 / rs ** 2)))


def check_easo_bridges(film_thickness: float, reference_radius: float) -> None:
    """Refuse a liquid film whose bridges LIGGGHTS' easo model would skip.

    A film ``t`` on spheres of ``reference_radius`` ``r`` is the liquid volume fraction
    ``3 t / r``; the bridge between two such spheres must hold at least
    :data:`EASO_MIN_BRIDGE_VOLUME`, else LIGGGHTS computes no bridge force at all and the
    particles, whose SJKR cohesion the bridges replace, run without cohesion.

    Raises
    ------
    bedstruct.errors.ConfigError
        With the film's bridge volume, the cut-off and the thinnest film LIGGGHTS acts on.

    Examples
    --------
    >>> from bedstruct.engines import check_easo_bridges
    >>> check_easo_bridges(2e-8, 26e-6)          # 0.23 % liquid: bridges of 2.3e-17 m^3
    >>> check_easo_bridges(1.5e-14, 26e-6)       # a humidity film: far below the cut-off
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: engine 'liggghts' cannot realise these liquid bridges: ...
    """
    t, r = float(film_thickness), float(reference_radius)
    c = 3.0 * t / r
    v = float(easo_bridge_volume(r, r, c))
    if v >= EASO_MIN_BRIDGE_VOLUME:
        return
    t_min = t * EASO_MIN_BRIDGE_VOLUME / v if v > 0 else float("inf")
    raise ConfigError(
        f"engine 'liggghts' cannot realise these liquid bridges: its easo/capillary/viscous "
        f"skips a bridge holding less than {EASO_MIN_BRIDGE_VOLUME:.0e} m^3 of liquid (a fixed "
        f"cut-off) and then exerts no force at all, while the particles' SJKR cohesion is "
        f"replaced by the bridges; a film of {t:.3g} m on spheres of radius {r:.3g} m (liquid "
        f"volume fraction {c:.3g}) gives bridges of {v:.3g} m^3. LIGGGHTS acts on films of at "
        f"least {t_min:.3g} m on these spheres (volume fraction {3 * t_min / r:.3g}); run "
        f"thinner films, such as humidity's adsorbed layers, with --engine embedded (Willett "
        f"bridges)")


@dataclass(frozen=True)
class LiquidBridges:
    """Liquid bridges between particles: LIGGGHTS' ``cohesion easo/capillary/viscous`` (SI).

    LIGGGHTS 3.8 allows one cohesion model, so the bridges replace the particles'
    SJKR cohesion in ``pair_style gran`` (its coefficients stay declared); the walls
    keep their model. The bridge law is LIGGGHTS' own (Easo), not the embedded
    engine's Willett bridges (``contact.capillary``).

    Parameters
    ----------
    surface_tension : float, N/m
    liquid_volume_fraction : float
        ``surfaceLiquidContentInitial``: liquid volume per particle volume.
    contact_angle : float, rad
        Written per atom type in degrees (LIGGGHTS 3.8 reads degrees).
    fluid_viscosity : float, Pa s
    min_separation_ratio, max_separation_ratio : float
        ``minSeparationDistanceRatio`` and ``maxSeparationDistanceRatio``.

    Examples
    --------
    >>> LiquidBridges(0.072, 1e-3).lines(2)[3]
    'fix twc4 all property/global contactAngle peratomtype 20 20'
    """

    surface_tension: float
    liquid_volume_fraction: float
    contact_angle: float = math.radians(20.0)
    fluid_viscosity: float = 1e-3
    min_separation_ratio: float = 1.01
    max_separation_ratio: float = 1.1

    def __post_init__(self):
        if not (self.surface_tension > 0 and self.liquid_volume_fraction > 0):
            raise ValueError("liquid bridges: `surface_tension` and `liquid_volume_fraction` "
                             "must be > 0")

    @classmethod
    def from_film(cls, *, surface_tension: float, contact_angle: float, film_thickness: float,
                  reference_radius: float, **kwargs) -> "LiquidBridges":
        """The bridges of a liquid film ``film_thickness`` on spheres of ``reference_radius``.

        A film ``t`` on a sphere of radius ``r`` holds ``4 pi r^2 t`` of liquid, the
        volume fraction ``3 t / r`` (LIGGGHTS' one ``surfaceLiquidContentInitial`` for
        every particle: the fraction of spheres of ``reference_radius``). LIGGGHTS 3.8
        uses ``theta_i theta_j / 2`` (rad) as the angle between equal types, so each type
        gets ``sqrt(2 contact_angle)`` and the angle LIGGGHTS applies is ``contact_angle``.
        Other keywords are those of the class (viscosity, separation ratios).

        Raises
        ------
        bedstruct.errors.ConfigError
            A film too thin for LIGGGHTS' bridges (:func:`check_easo_bridges`).

        Examples
        --------
        >>> b = LiquidBridges.from_film(surface_tension=0.072, contact_angle=0.02,
        ...                             film_thickness=1e-7, reference_radius=30e-6)
        >>> round(b.liquid_volume_fraction * 1e2, 10), round(0.5 * b.contact_angle ** 2, 12)
        (1.0, 0.02)
        """
        if not (film_thickness > 0 and reference_radius > 0):
            raise ValueError("liquid bridges: `film_thickness` and `reference_radius` must be > 0; "
                             f"got {film_thickness!r}, {reference_radius!r}")
        if not 0.0 <= contact_angle < 0.5 * math.pi:
            raise ValueError(f"liquid bridges: `contact_angle` must lie in [0, pi/2) rad; got "
                             f"{contact_angle!r}")
        check_easo_bridges(film_thickness, reference_radius)
        return cls(float(surface_tension), 3.0 * float(film_thickness) / float(reference_radius),
                   contact_angle=math.sqrt(2.0 * float(contact_angle)), **kwargs)

    def lines(self, n_types: int) -> list[str]:
        """The ``property/global`` lines of the model for ``n_types`` atom types."""
        return [
            "fix twc1 all property/global surfaceLiquidContentInitial scalar "
            f"{_fmt(self.liquid_volume_fraction)}",
            f"fix twc2 all property/global surfaceTension scalar {_fmt(self.surface_tension)}",
            f"fix twc3 all property/global fluidViscosity scalar {_fmt(self.fluid_viscosity)}",
            "fix twc4 all property/global contactAngle peratomtype "
            + " ".join([_fmt(math.degrees(self.contact_angle))] * n_types),
            "fix twc5 all property/global minSeparationDistanceRatio scalar "
            f"{_fmt(self.min_separation_ratio)}",
            "fix twc6 all property/global maxSeparationDistanceRatio scalar "
            f"{_fmt(self.max_separation_ratio)}",
        ]

    def pair_model(self, model: str) -> str:
        """``model`` words (:func:`liggghts_wall_model`) with the bridges as the cohesion."""
        if " cohesion sjkr" in model:
            return model.replace(" cohesion sjkr", " cohesion easo/capillary/viscous")
        return model.replace("tangential history",
                             "tangential history cohesion easo/capillary/viscous", 1)


def _mesh_walls(meshes: dict, model, wt: int, *, back_plane: bool = False, loaded=(),
                wall_fix: str = "wmesh") -> list[str]:
    """One ``fix mesh/surface`` per mesh (name -> STL path), all in one ``fix wall/gran``
    (LIGGGHTS allows one mesh wall/gran fix); with ``back_plane`` also the primitive plane
    ``x = 0``. Meshes named in ``loaded`` are ``mesh/surface/stress``: their fix's global
    vector holds the total force (and torque) of the particles on them."""
    wm = liggghts_wall_model(model)
    lines = [f"fix {name} all mesh/surface{'/stress' if name in loaded else ''} file "
             f"{path_word(path)} type {wt} curvature_tolerant yes"
             for name, path in meshes.items()]
    lines.append(f"fix {wall_fix} all wall/gran {wm} mesh n_meshes {len(meshes)} meshes "
                 + " ".join(meshes))
    if back_plane:
        lines.append(f"fix wback all wall/gran {wm} primitive type {wt} xplane 0.0")
    return lines


#: How LIGGGHTS 3.8 realises each catalogue effect (:attr:`LiggghtsDialect.realisations`).
LIGGGHTS_REALISATIONS = {
    "capillary_bridges": Realisation(
        "LIGGGHTS' own liquid bridges, pair_style gran cohesion easo/capillary/viscous "
        "(Soulie's law, LiquidBridges.from_film): surface tension and contact angle from "
        "`contact.capillary_*`, liquid volume fraction 3 t / r from the film thickness t on a sphere of "
        "the PSD's median radius r = psd.scale psd.d50 / 2; they replace the particles' SJKR "
        "cohesion (one cohesion model per pair style) and walls get none. LIGGGHTS skips a "
        "bridge holding less than 1e-17 m^3 of liquid (no force at all): films too thin for "
        "that at the median radius, such as the catalogue's humidity films, are refused"),
    "contact_ageing": Realisation(refused=(
        "LIGGGHTS has no contact model whose bond grows with each contact's rest time; "
        "run it with --engine embedded")),
    "non_sphericity": Realisation(
        "rolling friction `contact.rolling_friction` (mu_r + mu_r,shape) at particle and wall "
        "contacts in the rolling model `contact.rolling_model`: epsd (Ai et al. 2011; stiffness "
        "2.25 k_n mu_r^2 R*^2, coefficientRollingViscousDamping 0.3, the embedded damping "
        "ratio; another `contact.rolling_stiffness_factor` is refused), epsd2 or cdt"),
    "missing_fines": Realisation("fines inserted with the particles (the PSD's data file)"),
    "wall_friction": Realisation("particle-wall coefficientFriction contact.wall_friction "
                                 "(atom type 2)"),
    "blade_startup": Realisation(refused=(
        "the decks move the tool at constant velocity (fix move/mesh linear); the start-up "
        "ramp and vibration are a wall program of the embedded engine: run them with "
        "--engine embedded")),
}

#: LIGGGHTS' EPSD rolling stiffness prefactor (k_r = 2.25 k_n mu_r^2 R*^2), fixed in the code.
_LIGGGHTS_EPSD_STIFFNESS = 2.25


@register
@dataclass(frozen=True)
class LiggghtsDialect(Dialect):
    """LIGGGHTS 3.8: walls are STL meshes in one ``fix wall/gran`` (``fix move/mesh`` moves
    them), the particle-wall coefficients those of atom type 2.

    Parameters
    ----------
    liquid_bridges : LiquidBridges, optional
        Liquid bridges between particles (``cohesion easo/capillary/viscous``).

    Examples
    --------
    >>> d = LiggghtsDialect()
    >>> d.moving_run("mvplate", "plate", "-0.5 0 0", 10)
    ['fix mvplate all move/mesh mesh plate linear -0.5 0 0', 'run 10', 'unfix mvplate']
    """

    name = "liggghts"
    executable_name = "liggghts"
    atom_style = "granular"
    comm_vel = "communicate single vel yes"
    # compute pair/gran/local pos id force contactArea delta
    contact_dump_columns = "x1 y1 z1 x2 y2 z2 id1 id2 periodic fx fy fz contact_area overlap"
    tool_load = ("f_tool", "")
    realisations = LIGGGHTS_REALISATIONS

    liquid_bridges: LiquidBridges | None = None

    def find(self, executable=None):
        return find_liggghts(executable)

    def check_effect_options(self, cfg, *, spreading=False):
        d50 = option(cfg, "psd.d50")
        if "capillary_bridges" in effects_on(cfg) and d50 is not None:
            t = float(option(cfg, "contact.capillary_film_thickness", 0.0))
            scale = float(option(cfg, "psd.scale", 1.0))
            r_ref = 0.5 * scale * float(d50)
            check_easo_bridges(t, r_ref)
            d_min = option(cfg, "psd.d_min")
            r_min = 0.5 * scale * float(d_min if d_min is not None else d50)
            if float(easo_bridge_volume(r_min, r_min, 3.0 * t / r_ref)) < EASO_MIN_BRIDGE_VOLUME:
                warnings.warn(
                    f"engine 'liggghts': bridges between the smallest spheres (diameter "
                    f"{scale * float(d_min):.3g} m) hold less than {EASO_MIN_BRIDGE_VOLUME:.0e} "
                    f"m^3 of liquid: LIGGGHTS' easo model gives them neither a bridge force nor "
                    f"cohesion", BedstructWarning, stacklevel=2)
        f = float(option(cfg, "contact.rolling_stiffness_factor", _LIGGGHTS_EPSD_STIFFNESS))
        if (option(cfg, "contact.rolling_model") == "epsd"
                and float(option(cfg, "contact.rolling_friction", 0.0)) > 0.0
                and f != _LIGGGHTS_EPSD_STIFFNESS):
            raise ConfigError(
                f"engine 'liggghts' cannot realise contact.rolling_stiffness_factor = {f!r} (the "
                "EPSD rolling friction carrying the effect 'non_sphericity'): LIGGGHTS' EPSD"
                " stiffness is 2.25 k_n mu_r^2 R*^2; set it to 2.25 or run with --engine embedded")

    def check_model_options(self, model):
        """Refuse liquid bridges without their LIGGGHTS model (:class:`LiquidBridges`) and an
        EPSD rolling stiffness other than LIGGGHTS' own."""
        if model.capillary and self.liquid_bridges is None:
            raise ConfigError(
                "engine 'liggghts' writes the ContactModel's `capillary` bridges as its own model "
                "(LiquidBridges): give the dialect `liquid_bridges` (LiquidBridges.from_film, or "
                "Dialect.with_effects of a workflow configuration)")
        f = model.rolling_stiffness_factor
        if (model.rolling_model == "epsd" and f != _LIGGGHTS_EPSD_STIFFNESS
                and max(coefficient(model, "rolling_friction"),
                        coefficient(model, "rolling_friction", wall=True)) > 0.0):
            raise ConfigError(
                f"engine 'liggghts' cannot realise `rolling_stiffness_factor` = {f!r}: LIGGGHTS' "
                "EPSD stiffness is 2.25 k_n mu_r^2 R*^2; set it to 2.25 or run with --engine "
                "embedded")

    def with_effects(self, cfg, *, reference_radius=None, spreading=False):
        self.check_effects(cfg, spreading=spreading)
        if "capillary_bridges" not in effects_on(cfg):
            return self
        if reference_radius is None:
            raise ValueError("LIGGGHTS liquid bridges need `reference_radius` (m): the radius "
                             "whose liquid volume fraction the film thickness sets")
        c = cfg["contact"]
        bridges = LiquidBridges.from_film(
            surface_tension=float(c["capillary_surface_tension"]),
            contact_angle=float(c["capillary_contact_angle"]),
            film_thickness=float(c["capillary_film_thickness"]),
            reference_radius=float(reference_radius))
        return self.with_options(liquid_bridges=bridges)

    def effect_notes(self):
        if self.liquid_bridges is None:
            return []
        return ["liquid bridges are LIGGGHTS' easo/capillary/viscous (Soulie), not the embedded "
                "engine's Willett bridges; they replace the particles' SJKR cohesion; walls get "
                "no bridges; one liquid fraction for every particle (set at the PSD's median "
                "radius)"]

    def model_lines(self, model, *, n_types, soft=False):
        lines, wt = liggghts_model_commands(model, n_types=n_types)
        if self.liquid_bridges is not None:
            *props, pair_style, pair_coeff = lines
            pair_style = "pair_style gran " + self.liquid_bridges.pair_model(
                pair_style[len("pair_style gran "):])
            lines = [*props, *self.liquid_bridges.lines(n_types), pair_style, pair_coeff]
        if soft and min(coefficient(model, "youngs_modulus"),
                        coefficient(model, "youngs_modulus", wall=True)) < 5e6:
            # LIGGGHTS refuses E < 5e6 Pa in SI units unless told (softened moduli are deliberate)
            lines = ["soft_particles yes", *lines]
        return lines, wt

    def plane_wall(self, model, wall_type, *, zlo):
        return [f"fix wbottom all wall/gran {liggghts_wall_model(model)} primitive type "
                f"{wall_type} zplane {zlo:.10g}"]

    def moving_blade(self, model, wall_type, blade, *, stl_path):
        if stl_path is None:
            raise ValueError("LIGGGHTS needs the blade as an STL file: pass `stl_path` "
                             "(write it with blade.write_stl(...))")
        return [*_mesh_walls({"blade": stl_path}, model, wall_type, wall_fix="wblade"),
                f"fix mvblade all move/mesh mesh blade linear {blade.speed:.10g} 0 0"]

    def contact_computes(self, *, tangential=False):
        return ["compute cpl all pair/gran/local pos id force contactArea delta"]

    def contact_columns(self, *, tangential=False):
        return " ".join(f"c_cpl[{i}]" for i in range(1, 15))

    def moving_run(self, fix, mesh, velocity, steps, *, rotate=None):
        lines = [f"fix {fix} all move/mesh mesh {mesh} linear {velocity}"]
        if rotate is None:
            return lines + [f"run {steps}", f"unfix {fix}"]
        # superposed on the translation: the rotation axis moves with the mesh
        rot = f"rot{mesh}"
        return lines + [f"fix {rot} all move/mesh mesh {mesh} rotate {rotate}",
                        f"run {steps}", f"unfix {rot}", f"unfix {fix}"]

    def processors_grid(self, np, *, span=None):
        """LIGGGHTS 3.8 has no load balancing (no ``balance``, no ``fix balance``: both are
        unknown commands), so its slabs are the box's equal parts. Where the powder covers
        only ``span`` of the box along x (the repose box, which reaches past ``-L`` for the
        plate), the box is split along x once on an even number of ranks, at the middle of
        the powder (:meth:`box_lines` centres the box on it), and the halves along y (two
        ranks: ``* 1 1``, which runs on any number); on an odd number along y only (the
        powder fills the width). Otherwise (``span`` None, one rank) x slabs."""
        if np <= 2 or span is None:
            return "* 1 1"
        return "2 * 1" if np % 2 == 0 else "1 * 1"

    def box_lines(self, np, *, box, span):
        """On an even number of ranks, ``change_box`` widens the box along x to be symmetric
        about the middle of the powder ``span``, so that the cut between the two x slabs
        halves it (the box only grows: the meshes must stay inside it). None without
        ``span``."""
        if np % 2 or span is None:
            return []
        lo, hi = box
        mid = 0.5 * (span[0] + span[1])
        half = max(mid - lo, hi - mid)
        new_lo, new_hi = min(lo, mid - half), max(hi, mid + half)
        if (new_lo, new_hi) == (lo, hi):
            return []
        return [f"change_box all x final {new_lo!r} {new_hi!r} units box"]

    def repose_walls(self, geometry, schedule, model, wall_type, *, stl_folder):
        if stl_folder is None:
            raise ValueError("LIGGGHTS needs the walls as STL files: pass `stl_folder`")
        return _mesh_walls(repose_wall_stls(geometry, stl_folder), model, wall_type)

    def spread_walls(self, plan, model, wall_type, *, stl_folder):
        if stl_folder is None:
            raise ValueError("LIGGGHTS needs the walls as STL files: pass `stl_folder`")
        tool, W = plan.tool, plan.width
        meshes = _chamber_meshes(stl_folder, plan.plate_length, W, -float(plan.gaps[0]),
                                 plan.chamber_depth)
        folder = Path(stl_folder)
        if isinstance(tool, RollerGeometry):
            meshes["tool"] = write_stl(folder / "tool.stl", tool.triangles(0.0, W), name="roller")
        else:
            meshes["tool"] = tool.write_stl(folder / "tool.stl", 0.0, W, caps=False)
        lines = _mesh_walls(meshes, model, wall_type, back_plane=True, loaded=("tool",))
        if plan.side_walls:  # primitive planes, as the back wall
            wm = liggghts_wall_model(model)
            lines += [f"fix wylo all wall/gran {wm} primitive type {wall_type} yplane 0.0",
                      f"fix wyhi all wall/gran {wm} primitive type {wall_type} yplane {W:.10g}"]
        return lines
