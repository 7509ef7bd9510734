"""Material and contact-model parameters of the DEM engine (SI units).

Parameters are frozen dataclasses; :meth:`ContactModel.tables` turns them into
the small per-type-pair constant tables the kernels read. Particle types are
numbered 1..T as in LIGGGHTS; the walls form one extra type (index T in the
0-based tables).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import ConfigError

__all__ = ["Material", "ContactModel", "ModelTables", "seed_contact_model", "rayleigh_time", "hertz_time",
           "effective_youngs_modulus", "effective_shear_modulus", "restitution_beta",
           "ROLLING_MODELS"]

#: Rolling-resistance models and their kernel codes.
ROLLING_MODELS = {"none": 0, "cdt": 1, "epsd": 2, "epsd2": 3}


@dataclass(frozen=True)
class Material:
    """Elastic material of one particle type (or of the walls).

    Parameters
    ----------
    youngs_modulus : float, Pa
        Young's modulus E (often softened in DEM; see docs/engine.md).
    poisson_ratio : float, dimensionless
        Poisson ratio, in (-1, 0.5).
    density : float, kg/m^3
        Mass density (unused for walls).
    name : str, optional
        A label recorded in the run configuration.

    Examples
    --------
    >>> m = Material(1e7, 0.3, 8300.0, name="CoCr (soft)")
    >>> round(m.shear_modulus, 1)
    3846153.8
    """

    youngs_modulus: float
    poisson_ratio: float
    density: float = 8300.0
    name: str = ""

    def __post_init__(self):
        if not (math.isfinite(self.youngs_modulus) and self.youngs_modulus > 0):
            raise ConfigError(f"`youngs_modulus` must be a positive number of Pa; "
                              f"got {self.youngs_modulus!r}")
        if not (-1.0 < self.poisson_ratio < 0.5):
            raise ConfigError(f"`poisson_ratio` must lie in (-1, 0.5); got {self.poisson_ratio!r}")
        if not (math.isfinite(self.density) and self.density > 0):
            raise ConfigError(f"`density` must be a positive number of kg/m^3; got {self.density!r}")

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)) (Pa)."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


def effective_youngs_modulus(m1: Material, m2: Material) -> float:
    """Hertz effective modulus ``Y* = 1 / ((1-nu1^2)/E1 + (1-nu2^2)/E2)`` (Pa).

    Examples
    --------
    >>> m = Material(1e7, 0.3)
    >>> round(effective_youngs_modulus(m, m))
    5494505
    """
    return 1.0 / ((1 - m1.poisson_ratio ** 2) / m1.youngs_modulus
                  + (1 - m2.poisson_ratio ** 2) / m2.youngs_modulus)


def effective_shear_modulus(m1: Material, m2: Material) -> float:
    """Mindlin effective shear modulus ``G* = 1/(2(2-nu1)(1+nu1)/E1 + 2(2-nu2)(1+nu2)/E2)`` (Pa)."""
    return 1.0 / (2 * (2 - m1.poisson_ratio) * (1 + m1.poisson_ratio) / m1.youngs_modulus
                  + 2 * (2 - m2.poisson_ratio) * (1 + m2.poisson_ratio) / m2.youngs_modulus)


def restitution_beta(e: float) -> float:
    """``beta = ln(e) / sqrt(ln(e)^2 + pi^2)`` (dimensionless, <= 0); e = 0 gives -1.

    Examples
    --------
    >>> round(restitution_beta(0.5), 6)
    -0.215454
    >>> restitution_beta(1.0)
    0.0
    """
    if e <= 0.0:
        return -1.0
    le = math.log(e)
    return le / math.sqrt(le * le + math.pi ** 2)


def rayleigh_time(radius: float, material: Material) -> float:
    """Rayleigh time ``pi r sqrt(rho/G) / (0.1631 nu + 0.8766)`` (s), as in LIGGGHTS.

    Examples
    --------
    >>> t = rayleigh_time(14e-6, Material(1e7, 0.3, 8300.0))
    >>> round(t * 1e6, 3)  # microseconds
    2.208
    """
    nu = material.poisson_ratio
    return (math.pi * radius * math.sqrt(material.density / material.shear_modulus)
            / (0.1631 * nu + 0.8766))


def hertz_time(radius: float, material: Material, v_max: float) -> float:
    """Duration of a head-on Hertz impact of two equal spheres at speed ``v_max`` (s).

    ``t = 2.868 (m*^2 / (R* Y*^2 v))^(1/5)`` with ``m* = m/2`` and ``R* = r/2``.
    """
    m = 4.0 / 3.0 * math.pi * radius ** 3 * material.density
    ystar = effective_youngs_modulus(material, material)
    return 2.868 * ((0.5 * m) ** 2 / (0.5 * radius * ystar ** 2 * v_max)) ** 0.2


def _pair_table(name: str, value, n: int, *, lo=0.0, hi=math.inf) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full((n, n), float(arr))
    if arr.shape != (n, n):
        raise ConfigError(f"`{name}` must be a number or a ({n}, {n}) per-type-pair table; "
                          f"got shape {arr.shape}")
    if not np.allclose(arr, arr.T):
        raise ConfigError(f"`{name}` per-type-pair table must be symmetric")
    if not (np.all(np.isfinite(arr)) and np.all(arr >= lo) and np.all(arr <= hi)):
        raise ConfigError(f"`{name}` must lie in [{lo}, {hi}]; got {arr.tolist()}")
    return arr


def _wall_row(name: str, value, default: np.ndarray, n: int, *, lo=0.0, hi=math.inf) -> np.ndarray:
    if value is None:
        return np.diag(default).copy()
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ConfigError(f"`{name}` must be a number or one value per particle type ({n},); "
                          f"got shape {arr.shape}")
    if not (np.all(np.isfinite(arr)) and np.all(arr >= lo) and np.all(arr <= hi)):
        raise ConfigError(f"`{name}` must lie in [{lo}, {hi}]; got {arr.tolist()}")
    return arr


@dataclass(frozen=True)
class ModelTables:
    """Per-type-pair constants read by the kernels, shape (T+1, T+1) each.

    Index ``T`` is the wall type. ``youngs`` = Y*, ``shear`` = G*, ``beta``
    from the coefficient of restitution ``restitution`` = e, ``friction`` = mu,
    ``rolling_friction`` = mu_r, ``cohesion`` = k (J/m^3).
    """

    youngs: np.ndarray
    shear: np.ndarray
    beta: np.ndarray
    friction: np.ndarray
    rolling_friction: np.ndarray
    cohesion: np.ndarray
    restitution: np.ndarray


@dataclass(frozen=True)
class ContactModel:
    """Hertz-Mindlin contact model with SJKR cohesion and rolling resistance.

    The formulas are those of LIGGGHTS ``pair_style granular model hertz
    tangential history cohesion sjkr rolling_friction epsd2`` (see
    docs/engine.md). Scalars apply to every pair of particle types; give a
    symmetric (T, T) array for per-type-pair values. Particle-wall contacts
    use the ``wall_*`` values (one per particle type, default: the
    particle-particle diagonal).

    Parameters
    ----------
    materials : Material or sequence of Material
        One material per particle type (types 1..T).
    restitution : float or (T, T) array, dimensionless
        Coefficient of normal restitution e in [0, 1].
    friction : float or (T, T) array, dimensionless
        Coulomb (static) friction coefficient mu.
    rolling_friction : float or (T, T) array, dimensionless
        Rolling friction coefficient mu_r (0 disables rolling resistance).
    cohesion : float or (T, T) array, J/m^3
        SJKR cohesion energy density k (0 disables cohesion).
    rolling_model : {"epsd2", "cdt", "epsd", "none"}
        Rolling-resistance law. Default ``"epsd2"``.
    rolling_damping : float, dimensionless
        Viscous damping ratio eta_r of the ``"epsd"`` model only.
    wall_material : Material, optional
        Material of every wall (default: the material of type 1).
    wall_restitution, wall_friction, wall_rolling_friction, wall_cohesion : float or (T,) array
        Particle-wall coefficients per particle type.
    tangential_damping : bool
        Include the tangential dashpot (LIGGGHTS default on).
    limit_force : bool
        Clip the Hertz + damping normal force at 0 (LIGGGHTS ``limitForce``,
        default off).
    capillary : bool
        Switch on pendular liquid bridges between particles (Willett et al.
        2000 closed form; docs/engine.md, "Extensions for the diagnosis").
        Default off.
    capillary_surface_tension : float, N/m
        Liquid surface tension gamma (water: 0.072).
    capillary_contact_angle : float, rad
        Liquid-solid contact angle theta, in [0, pi/2).
    capillary_film_thickness : float, m
        Adsorbed film thickness t; bridge volume ``V = 2 pi R*^2 t``.
    capillary_bridge_volume : float, m^3, optional
        A fixed bridge volume for every pair instead of the film rule.
    contact_ageing : bool
        Switch on humidity-driven contact ageing bonds. Default off.
    ageing_bond_ratio : float, dimensionless
        Bond strength relative to the SJKR cohesion force after the reference
        rest time.
    ageing_time_constant, ageing_reference_rest_time : float, s
        tau and t_ref of the logarithmic ageing law.
    ageing_break_slip : float, m
        Accumulated sliding beyond which the bond breaks for good (until the
        contact opens): the tangential displacement the Coulomb limit cuts off
        the Mindlin spring, not its elastic (recoverable) shear.
    rolling_stiffness_factor : float, dimensionless
        Prefactor of the ``"epsd"`` rolling stiffness ``k_r = f k_n mu_r^2 R*^2``
        (Ai et al. 2011 use 2.25).

    Examples
    --------
    >>> model = ContactModel(Material(1e7, 0.3, 8300.0), restitution=0.5, friction=0.5,
    ...                      rolling_friction=0.1, cohesion=1e4)
    >>> model.n_types
    1
    >>> t = model.tables()
    >>> t.youngs.shape, round(float(t.beta[0, 0]), 4)
    ((2, 2), -0.2155)
    """

    materials: tuple[Material, ...] | Material
    restitution: object = 0.5
    friction: object = 0.5
    rolling_friction: object = 0.0
    cohesion: object = 0.0
    rolling_model: str = "epsd2"
    rolling_damping: float = 0.3
    wall_material: Material | None = None
    wall_restitution: object = None
    wall_friction: object = None
    wall_rolling_friction: object = None
    wall_cohesion: object = None
    tangential_damping: bool = True
    limit_force: bool = False
    capillary: bool = False
    capillary_surface_tension: float = 0.072
    capillary_contact_angle: float = 0.3490658503988659
    capillary_film_thickness: float = 0.0
    capillary_bridge_volume: float | None = None
    contact_ageing: bool = False
    ageing_bond_ratio: float = 0.0
    ageing_time_constant: float = 10.0
    ageing_reference_rest_time: float = 60.0
    ageing_break_slip: float = 1e-6
    rolling_stiffness_factor: float = 2.25
    _tables: ModelTables | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        mats = self.materials
        if isinstance(mats, Material):
            mats = (mats,)
        mats = tuple(mats)
        if not mats or not all(isinstance(m, Material) for m in mats):
            raise ConfigError("`materials` must be a Material or a non-empty sequence of Material "
                              "(one per particle type)")
        object.__setattr__(self, "materials", mats)
        if self.rolling_model not in ROLLING_MODELS:
            raise ConfigError(f"`rolling_model` must be one of {sorted(ROLLING_MODELS)}; "
                              f"got {self.rolling_model!r}")
        self._check_extensions()
        object.__setattr__(self, "_tables", self._build_tables())

    def _check_extensions(self):
        def num(name, lo=0.0, hi=math.inf, strict=False):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise ConfigError(f"`{name}` must be a number; got {v!r}")
            v = float(v)
            if not (math.isfinite(v) and (v > lo if strict else v >= lo) and v <= hi):
                raise ConfigError(f"`{name}` must lie in {'(' if strict else '['}{lo}, {hi}]; "
                                  f"got {v!r}")
            object.__setattr__(self, name, v)
        for b in ("capillary", "contact_ageing"):
            if not isinstance(getattr(self, b), (bool, np.bool_)):
                raise ConfigError(f"`{b}` must be true or false; got {getattr(self, b)!r}")
            object.__setattr__(self, b, bool(getattr(self, b)))
        num("capillary_surface_tension")
        num("capillary_contact_angle", hi=0.5 * math.pi - 1e-9)
        num("capillary_film_thickness")
        if self.capillary_bridge_volume is not None:
            num("capillary_bridge_volume", strict=True)
        num("ageing_bond_ratio")
        num("ageing_time_constant", strict=True)
        num("ageing_reference_rest_time", strict=True)
        num("ageing_break_slip")
        num("rolling_stiffness_factor", strict=True)
        if self.capillary and self.capillary_bridge_volume is None \
                and self.capillary_film_thickness <= 0.0:
            raise ConfigError("`capillary` needs `capillary_film_thickness` > 0 or a "
                              "`capillary_bridge_volume`")

    @property
    def extension_code(self) -> int:
        """Kernel flags of the switched-on extensions (1 capillary, 2 ageing)."""
        return (1 if self.capillary else 0) | (2 if self.contact_ageing else 0)

    def bridge_volume(self, reff):
        """Liquid bridge volume of a pair with reduced radius ``reff`` (m^3).

        ``V = 2 pi R*^2 t`` from the film thickness t, or the fixed
        ``capillary_bridge_volume``.
        """
        if self.capillary_bridge_volume is not None:
            return float(self.capillary_bridge_volume) + 0.0 * np.asarray(reff)
        return 2.0 * math.pi * np.asarray(reff) ** 2 * self.capillary_film_thickness

    def rupture_distance(self, reff):
        """Willett/Lian rupture distance ``s_c = (1 + theta/2) V^(1/3)`` (m)."""
        return (1.0 + 0.5 * self.capillary_contact_angle) * np.cbrt(self.bridge_volume(reff))

    def extension_arrays(self):
        """(capillary, ageing) parameter arrays read by the pair kernel."""
        cap = np.array([self.capillary_surface_tension * math.cos(self.capillary_contact_angle),
                        self.capillary_contact_angle, self.capillary_film_thickness,
                        -1.0 if self.capillary_bridge_volume is None
                        else float(self.capillary_bridge_volume)])
        age = np.array([self.ageing_bond_ratio, self.ageing_time_constant,
                        1.0 / math.log1p(self.ageing_reference_rest_time / self.ageing_time_constant),
                        self.ageing_break_slip, self.rolling_stiffness_factor])
        return cap, age

    @property
    def n_types(self) -> int:
        """Number of particle types T."""
        return len(self.materials)

    @property
    def rolling_code(self) -> int:
        """Kernel code of the rolling model (0 none, 1 cdt, 2 epsd, 3 epsd2)."""
        return ROLLING_MODELS[self.rolling_model]

    def _build_tables(self) -> ModelTables:
        n = self.n_types
        wall = self.wall_material or self.materials[0]
        mats = list(self.materials) + [wall]
        rest = _pair_table("restitution", self.restitution, n, hi=1.0)
        mu = _pair_table("friction", self.friction, n)
        mur = _pair_table("rolling_friction", self.rolling_friction, n)
        coh = _pair_table("cohesion", self.cohesion, n)
        w_rest = _wall_row("wall_restitution", self.wall_restitution, rest, n, hi=1.0)
        w_mu = _wall_row("wall_friction", self.wall_friction, mu, n)
        w_mur = _wall_row("wall_rolling_friction", self.wall_rolling_friction, mur, n)
        w_coh = _wall_row("wall_cohesion", self.wall_cohesion, coh, n)

        def full(pp, pw):
            out = np.zeros((n + 1, n + 1))
            out[:n, :n] = pp
            out[:n, n] = pw
            out[n, :n] = pw
            return out

        Y = np.array([[effective_youngs_modulus(a, b) for b in mats] for a in mats])
        G = np.array([[effective_shear_modulus(a, b) for b in mats] for a in mats])
        e_full = full(rest, w_rest)
        beta = np.vectorize(restitution_beta)(e_full)
        return ModelTables(youngs=Y, shear=G, beta=beta, friction=full(mu, w_mu),
                           rolling_friction=full(mur, w_mur), cohesion=full(coh, w_coh),
                           restitution=e_full)

    def tables(self) -> ModelTables:
        """The per-type-pair constant tables (computed once)."""
        return self._tables

    def rayleigh_time(self, min_radius: float) -> float:
        """Smallest Rayleigh time over particle types at radius ``min_radius`` (s)."""
        return min(rayleigh_time(min_radius, m) for m in self.materials)

    def hertz_time(self, min_radius: float, v_max: float) -> float:
        """Shortest head-on Hertz impact time over types at ``min_radius`` and ``v_max`` (s)."""
        return min(hertz_time(min_radius, m, v_max) for m in self.materials)

    def to_dict(self) -> dict:
        """A JSON-ready description (recorded in run directories)."""
        def conv(v):
            if isinstance(v, Material):
                return dict(youngs_modulus=v.youngs_modulus, poisson_ratio=v.poisson_ratio,
                            density=v.density, name=v.name)
            if isinstance(v, np.ndarray):
                return v.tolist()
            return v
        out = {}
        for k in ("restitution", "friction", "rolling_friction", "cohesion", "rolling_model",
                  "rolling_damping", "wall_restitution", "wall_friction", "wall_rolling_friction",
                  "wall_cohesion", "tangential_damping", "limit_force", "capillary",
                  "capillary_surface_tension", "capillary_contact_angle",
                  "capillary_film_thickness", "capillary_bridge_volume", "contact_ageing",
                  "ageing_bond_ratio", "ageing_time_constant", "ageing_reference_rest_time",
                  "ageing_break_slip", "rolling_stiffness_factor"):
            out[k] = conv(np.asarray(getattr(self, k)) if isinstance(getattr(self, k), (list, tuple))
                          else getattr(self, k))
        out["materials"] = [conv(m) for m in self.materials]
        out["wall_material"] = conv(self.wall_material) if self.wall_material else None
        out["units"] = "SI"
        return out


def seed_contact_model(*, youngs_modulus: float = 1.0e7, poisson_ratio: float = 0.3,
                       density: float = 8300.0, **fields) -> ContactModel:
    """The seed's contact model: soft CoCr spheres, Hertz-Mindlin with EPSD2 rolling friction.

    One particle type of ``Material(youngs_modulus, poisson_ratio, density)``; the seed's
    coefficients are restitution 0.1, friction 0.4, rolling friction 0.05 (``epsd2``)
    and no cohesion. Every other :class:`ContactModel` field (``cohesion``,
    ``wall_friction``, ``wall_material`` ...) is given by keyword and replaces the
    seed's value. The external engines' decks take this model by default.

    Parameters
    ----------
    youngs_modulus : float, Pa
        Young's modulus of the (softened) particles.
    poisson_ratio : float, dimensionless
    density : float, kg/m^3
    **fields
        :class:`ContactModel` fields.

    Returns
    -------
    ContactModel

    Examples
    --------
    >>> m = seed_contact_model(cohesion=4.2e4)
    >>> m.materials[0].youngs_modulus, m.restitution, m.friction, m.rolling_friction, m.cohesion
    (10000000.0, 0.1, 0.4, 0.05, 42000.0)
    >>> seed_contact_model(youngs_modulus=1e8, wall_friction=0.6).tables().friction[0].tolist()
    [0.4, 0.6]
    """
    if "materials" in fields:
        raise ConfigError("seed_contact_model takes the particles' material as `youngs_modulus`, "
                          "`poisson_ratio` and `density`, not `materials`")
    seed = dict(restitution=0.1, friction=0.4, rolling_friction=0.05, cohesion=0.0,
                rolling_model="epsd2")
    return ContactModel(Material(youngs_modulus, poisson_ratio, density, name="CoCr (soft)"),
                        **{**seed, **fields})


def _as_sequence(x) -> Sequence:
    return x if isinstance(x, (list, tuple)) else [x]
