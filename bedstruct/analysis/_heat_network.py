"""The thermal network: particles are capacities, contacts are conductances."""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass, field
from functools import cached_property
from typing import Mapping

import numpy as np

from ..core import Contacts, Frame, UNIT_STYLES
from ..core.frame import _as_frame
from ..errors import BedstructWarning

__all__ = ["ThermalMaterial", "COCR", "GasGap", "ThermalNetwork", "thermal_network"]

log = logging.getLogger(__name__)

_LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "micron": 1e-6,
                 "nm": 1e-9}


@dataclass(frozen=True)
class ThermalMaterial:
    """Thermal properties of a particle material (SI).

    Parameters
    ----------
    density : float, kg/m^3
    specific_heat : float, J/(kg K)
    conductivity : float, W/(m K)
    name : str, optional

    Notes
    -----
    .. versionadded:: 0.1

    Examples
    --------
    >>> m = ThermalMaterial(8300.0, 450.0, 13.0, name="CoCr")
    >>> m.volumetric_heat_capacity  # J/(m^3 K)
    3735000.0
    """

    density: float
    specific_heat: float
    conductivity: float
    name: str = ""

    def __post_init__(self):
        for attr in ("density", "specific_heat", "conductivity"):
            v = float(getattr(self, attr))
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"ThermalMaterial `{attr}` must be positive and finite; "
                                 f"got {v!r}")
            object.__setattr__(self, attr, v)

    @property
    def volumetric_heat_capacity(self) -> float:
        """``rho * c`` in J/(m^3 K)."""
        return self.density * self.specific_heat


#: Co-28Cr-6Mo (ASTM F75) near room temperature: 8300 kg/m^3, 450 J/(kg K),
#: 13 W/(m K). Sources in docs/heat.md (ASTM F75 data sheets; MakeItFrom
#: R30075 lists 8.4 g/cm^3, 450 J/(kg K), 13 W/(m K)).
COCR = ThermalMaterial(8300.0, 450.0, 13.0, name="CoCr (ASTM F75, ~300 K)")


@dataclass(frozen=True)
class GasGap:
    """Conduction through the gas between near or touching spheres (optional).

    The gas lens between two spheres of radii ``r_i`` and ``r_j`` with the
    surface gap ``h0 = max(d - r_i - r_j, 0)`` is integrated in parallel
    plates out to the radius ``rho_c = lens_fraction * min(r_i, r_j)``, with
    the parabolic gap ``h(rho) = h0 + rho^2 / (2 R*)``,
    ``R* = r_i r_j / (r_i + r_j)``, and a Knudsen temperature-jump distance
    ``delta = 2 (2 - alpha)/alpha * 2 gamma / ((gamma + 1) Pr) * lambda``
    added to the gap (Smoluchowski jump):

    .. math:: G_g = 2 \\pi k_g R^* \\ln\\left(1 + \\frac{\\rho_c^2}{2 R^* (h_0 + \\delta)}\\right)

    Parameters
    ----------
    conductivity : float, W/(m K)
        Gas conductivity; default argon at 300 K (0.0177).
    mean_free_path : float, m
        Molecular mean free path; default argon at 1 atm, 300 K (6.8e-8).
    accommodation : float
        Thermal accommodation coefficient (0, 1]; default 0.9.
    gamma, prandtl : float
        Heat-capacity ratio (5/3) and Prandtl number (0.67) of the gas.
    lens_fraction : float
        Outer radius of the gas lens in units of the smaller radius (0.5).
    max_gap : float or None, m
        Pairs with a surface gap above this get no gas term (default: every
        pair in the contacts given; for the plate, gaps below 0.1 r).

    Notes
    -----
    .. versionadded:: 0.1

    Examples
    --------
    >>> g = GasGap()
    >>> round(g.jump_distance * 1e9)  # nm
    310
    """

    conductivity: float = 0.0177
    mean_free_path: float = 6.8e-8
    accommodation: float = 0.9
    gamma: float = 5.0 / 3.0
    prandtl: float = 0.67
    lens_fraction: float = 0.5
    max_gap: float | None = None

    def __post_init__(self):
        if not (self.conductivity > 0 and self.mean_free_path >= 0 and 0 < self.accommodation <= 1
                and self.lens_fraction > 0):
            raise ValueError(f"invalid GasGap parameters: {self!r}")

    @property
    def jump_distance(self) -> float:
        """Knudsen temperature-jump distance ``delta`` (m), added to the gap."""
        a, g = self.accommodation, self.gamma
        return 2.0 * (2.0 - a) / a * 2.0 * g / ((g + 1.0) * self.prandtl) * self.mean_free_path

    def conductance(self, r_i, r_j, gap) -> np.ndarray:
        """Gas conductance (W/K) of pairs with radii and surface gaps in metres."""
        r_i = np.asarray(r_i, dtype=np.float64)
        r_j = np.asarray(r_j, dtype=np.float64)
        h0 = np.clip(np.asarray(gap, dtype=np.float64), 0.0, None)
        with np.errstate(invalid="ignore"):
            rstar = np.where(np.isinf(r_j), r_i, r_i * r_j / (r_i + r_j))
        rho_c = self.lens_fraction * np.minimum(r_i, r_j)
        g = 2.0 * math.pi * self.conductivity * rstar * np.log1p(
            rho_c ** 2 / (2.0 * rstar * (h0 + self.jump_distance + 1e-300)))
        if self.max_gap is not None:
            g = np.where(h0 <= self.max_gap, g, 0.0)
        return g


@dataclass(frozen=True, eq=False)
class ThermalNetwork:
    """Particles as heat capacities joined by contact conductances (SI).

    Built by :func:`thermal_network`; read by :func:`conduct_heat` and
    :func:`conductivity_tensor`.

    Attributes
    ----------
    capacity : (N,) ndarray, J/K
        ``rho c V`` of every particle.
    i, j : (M,) ndarray of int
        Particle rows joined by each conductance.
    conductance : (M,) ndarray, W/K
        Total conductance (solid contact plus gas term).
    gas_conductance : (M,) ndarray, W/K
        The gas part of ``conductance`` (zeros without a gas model).
    branch : (M, 3) ndarray, m
        Minimum-image vectors from ``i`` to ``j``.
    positions : (N, 3) ndarray, m
    radii : (N,) ndarray, m
    plate_conductance : (N,) ndarray, W/K
        Conductance of each particle to the plate (used when the plate has a
        fixed temperature).
    plate_z : float, m
        Height of the plate.
    box_lo, box_hi : (3,) ndarray, m
        The frame's box.
    periodic : tuple of 3 bool
        Periodic axes of the box.
    length_scale : float, m per frame length unit
        The conversion applied at the boundary.
    units : str
        Record of the conversion.
    """

    capacity: np.ndarray
    i: np.ndarray
    j: np.ndarray
    conductance: np.ndarray
    gas_conductance: np.ndarray
    branch: np.ndarray
    positions: np.ndarray
    radii: np.ndarray
    plate_conductance: np.ndarray
    plate_z: float
    box_lo: np.ndarray
    box_hi: np.ndarray
    periodic: tuple
    length_scale: float
    units: str
    types: np.ndarray = field(default=None)

    @property
    def n_particles(self) -> int:
        """Number of nodes N."""
        return int(self.capacity.shape[0])

    @property
    def n_contacts(self) -> int:
        """Number of conductances M (zero conductances included)."""
        return int(self.i.shape[0])

    @cached_property
    def weights(self):
        """Symmetric CSR matrix ``W`` with ``W[i, j] = G_ij`` (W/K)."""
        import scipy.sparse as sp
        n = self.n_particles
        keep = self.conductance > 0
        i, j, g = self.i[keep], self.j[keep], self.conductance[keep]
        w = sp.coo_matrix((np.concatenate([g, g]), (np.concatenate([i, j]), np.concatenate([j, i]))),
                          shape=(n, n)).tocsr()
        w.sum_duplicates()
        w.sort_indices()
        return w

    @cached_property
    def weight_sums(self) -> np.ndarray:
        """Row sums of ``W`` (W/K): the total conductance of each particle."""
        return np.asarray(self.weights.sum(axis=1)).ravel()

    def __repr__(self) -> str:
        return (f"ThermalNetwork(n_particles={self.n_particles}, n_contacts={self.n_contacts}, "
                f"length_scale={self.length_scale:g} m)")


def _length_scale(frame: Frame, length_unit) -> tuple[float, str]:
    style = frame.units.style
    known = style in UNIT_STYLES
    if length_unit is None:
        if not known:
            raise ValueError(
                f"the frame's unit system is {style!r}, which has no known SI length; state it with "
                f"length_unit= (metres per frame length unit, or 'm', 'mm', 'um', 'si', 'cgs', "
                f"'micro', 'nano')")
        scale = UNIT_STYLES[style]["length"]
        return scale, f"length: frame units {style!r} -> m (x{scale:g})"
    if isinstance(length_unit, str):
        key = length_unit.strip().lower()
        if key in UNIT_STYLES:
            scale = UNIT_STYLES[key]["length"]
        elif key in _LENGTH_UNITS:
            scale = _LENGTH_UNITS[key]
        else:
            raise ValueError(f"`length_unit` must be a length name {sorted(_LENGTH_UNITS)}, a "
                             f"unit style {sorted(UNIT_STYLES)} or metres per unit; got "
                             f"{length_unit!r}")
    else:
        scale = float(length_unit)
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"`length_unit` must be positive metres per frame unit; got {length_unit!r}")
    if known and not math.isclose(scale, UNIT_STYLES[style]["length"], rel_tol=1e-12):
        warnings.warn(
            f"length_unit={length_unit!r} ({scale:g} m) overrides the frame's units {style!r} "
            f"({UNIT_STYLES[style]['length']:g} m)", BedstructWarning, stacklevel=3)
    return scale, f"length: stated length_unit={length_unit!r} -> m (x{scale:g})"


def _materials_per_particle(types: np.ndarray, materials) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if materials is None:
        materials = COCR
    if isinstance(materials, ThermalMaterial):
        n = types.shape[0]
        return (np.full(n, materials.density), np.full(n, materials.specific_heat),
                np.full(n, materials.conductivity))
    if not isinstance(materials, Mapping):
        raise TypeError(f"`materials` must be a ThermalMaterial or a mapping type -> "
                        f"ThermalMaterial; got {type(materials).__name__}")
    uniq = np.unique(types)
    missing = [int(t) for t in uniq if int(t) not in materials]
    if missing:
        raise ValueError(f"`materials` has no entry for particle types {missing}; given types "
                         f"{sorted(int(k) for k in materials)}")
    rho = np.empty(types.shape[0])
    cp = np.empty(types.shape[0])
    k = np.empty(types.shape[0])
    for t in uniq:
        m = materials[int(t)]
        if not isinstance(m, ThermalMaterial):
            raise TypeError(f"`materials[{int(t)}]` must be a ThermalMaterial; got {type(m).__name__}")
        sel = types == t
        rho[sel], cp[sel], k[sel] = m.density, m.specific_heat, m.conductivity
    return rho, cp, k


def thermal_network(frame, contacts: Contacts | None = None, *, materials=None, length_unit=None,
                    gas: GasGap | None = None, contact_area: str = "auto", plate_z=None,
                    plate_material: ThermalMaterial | None = None) -> ThermalNetwork:
    """Build the thermal network of a frame from its contacts (converted to SI).

    Every particle is a node of heat capacity ``C = rho c V``; every contact
    is a conductance. Touching spheres conduct through their contact circle
    of radius ``a`` (Batchelor & O'Brien 1977; the contact model of Gusarov
    et al. 2003 for powder beds):

    .. math:: G = 2 k_s a \\quad\\text{(same material)},\\qquad
              G = \\frac{4 a}{1/k_i + 1/k_j}\\quad\\text{(different materials)}

    plus, optionally, a gas term for near and touching pairs
    (:class:`GasGap`).

    Parameters
    ----------
    frame : Frame or frame-like
        Positions and radii (frame length unit).
    contacts : Contacts, optional
        Contacts of ``frame`` (frame length unit). When omitted they are
        found with ``bedstruct.analysis.contacts.find_contacts(frame)``.
    materials : ThermalMaterial or mapping of int to ThermalMaterial, optional
        Properties per particle type; default :data:`COCR` for all.
    length_unit : float or str, optional
        Metres per frame length unit (or ``"um"``, ``"mm"``, ``"micro"``,
        ...). Required when the frame's unit system is unknown; overrides a
        known one with a warning.
    gas : GasGap, optional
        Add gas conduction across near and touching pairs.
    contact_area : {"auto", "lens", "dumped"}
        Source of the contact radius: the lens of the overlapping spheres
        (``"lens"``), the area dumped by the simulator,
        ``a = sqrt(area / pi)`` (``"dumped"``, frame length^2), or the dumped
        area where present, else the lens (``"auto"``).
    plate_z : float, optional
        Height of the build plate (frame length unit); default the box's
        lower z bound. Particles overlapping it get a contact conductance
        ``2 k a`` to the plate (harmonic mean of the two conductivities).
    plate_material : ThermalMaterial, optional
        Plate material; default that of each particle.

    Returns
    -------
    ThermalNetwork

    Raises
    ------
    ValueError
        Unknown units without ``length_unit``, contacts that do not match the
        frame, missing materials.

    Notes
    -----
    Pairs that only touch (zero overlap) have ``a = 0`` and conduct only
    through the gas term.

    References
    ----------
    .. [1] G. K. Batchelor and R. W. O'Brien, Thermal or electrical conduction
       through a granular material, Proc. R. Soc. Lond. A 355 (1977) 313-333,
       doi:10.1098/rspa.1977.0100
    .. [2] A. V. Gusarov, T. Laoui, L. Froyen, V. I. Titov, Contact thermal
       conductivity of a powder bed in selective laser sintering, Int. J. Heat
       Mass Transf. 46 (2003) 1103-1109, doi:10.1016/S0017-9310(02)00370-8

    .. versionadded:: 0.1

    Examples
    --------
    Two CoCr spheres of radius 10 um overlapping so that the contact radius
    is 2 um: ``G = 2 * 13 * 2e-6 = 5.2e-5`` W/K.

    >>> import numpy as np
    >>> from bedstruct.core import Frame, Contacts, Units
    >>> d = 2 * np.sqrt(10.0**2 - 2.0**2)
    >>> f = Frame([[0, 0, 0], [d, 0, 0]], [10.0, 10.0], box=[100, 100, 100], units=Units("micro"))
    >>> c = Contacts(i=[0], j=[1], branch=[[d, 0, 0]], radii_i=[10.0], radii_j=[10.0])
    >>> net = thermal_network(f, c)
    >>> net.conductance
    array([5.2e-05])
    >>> float(net.capacity[0])  # rho c 4/3 pi r^3, J/K
    1.5645...e-08
    >>> net.units
    "length: frame units 'micro' -> m (x1e-06)"
    """
    frame = _as_frame(frame)
    scale, note = _length_scale(frame, length_unit)
    n = frame.n_particles
    if contacts is None:
        try:
            from .contacts import find_contacts
        except ImportError:
            raise ValueError("`contacts` were not given and bedstruct.analysis.contacts."
                             "find_contacts is not available; pass Contacts explicitly") from None
        contacts = find_contacts(frame)
    if not isinstance(contacts, Contacts):
        raise TypeError(f"`contacts` must be a bedstruct Contacts; got {type(contacts).__name__}")
    if contacts.n_particles != n:
        raise ValueError(f"`contacts` belong to a frame of {contacts.n_particles} particles; "
                         f"the frame has N={n}")
    if contact_area not in ("auto", "lens", "dumped"):
        raise ValueError(f"`contact_area` must be 'auto', 'lens' or 'dumped'; got {contact_area!r}")
    rho, cp, k = _materials_per_particle(frame.types, materials)
    radii = frame.radii * scale
    capacity = rho * cp * (4.0 / 3.0) * math.pi * radii ** 3

    keep = contacts.i != contacts.j
    if not np.all(keep):
        contacts = contacts.select(keep)
    ci, cj = contacts.i, contacts.j
    if contact_area == "dumped" and contacts.area is None:
        raise ValueError("contact_area='dumped' needs contacts with an `area` column "
                         "(e.g. from a dump local file); these have none")
    if contact_area != "lens" and contacts.area is not None:
        a = np.sqrt(np.clip(contacts.area, 0.0, None) / math.pi) * scale
    else:
        a = contacts.contact_radius * scale
    k_pair = 2.0 * k[ci] * k[cj] / (k[ci] + k[cj])
    g_solid = 2.0 * k_pair * a
    branch = contacts.branch * scale
    if gas is not None:
        gap = -contacts.overlap * scale
        g_gas = gas.conductance(contacts.radii_i * scale, contacts.radii_j * scale, gap)
    else:
        g_gas = np.zeros(ci.shape[0])
    # plate
    z_plate = (frame.box.lo[2] if plate_z is None else float(plate_z)) * scale
    pos = frame.positions * scale
    h = radii - (pos[:, 2] - z_plate)                 # overlap with the plate plane
    hp = np.clip(h, 0.0, None)
    a_plate = np.sqrt(np.clip(2.0 * radii * hp - hp * hp, 0.0, None))
    k_plate = k if plate_material is None else np.full(n, plate_material.conductivity)
    g_plate = 2.0 * (2.0 * k * k_plate / (k + k_plate)) * a_plate
    if gas is not None:
        gap_p = -h
        gp = gas.conductance(radii, np.full(n, np.inf), gap_p)
        limit = gas.max_gap if gas.max_gap is not None else 0.1 * radii
        g_plate = g_plate + np.where(gap_p <= limit, gp, 0.0)
    ro = lambda v: (v.setflags(write=False), v)[1]  # noqa: E731
    net = ThermalNetwork(
        capacity=ro(capacity), i=ro(ci.copy()), j=ro(cj.copy()), conductance=ro(g_solid + g_gas),
        gas_conductance=ro(g_gas), branch=ro(branch), positions=ro(pos), radii=ro(radii),
        plate_conductance=ro(g_plate), plate_z=float(z_plate), box_lo=ro(frame.box.lo * scale),
        box_hi=ro(frame.box.hi * scale), periodic=tuple(frame.box.periodic), length_scale=scale,
        units=note, types=ro(frame.types.copy()))
    log.debug("thermal network: %d nodes, %d conductances (%s)", n, ci.shape[0], note)
    return net
