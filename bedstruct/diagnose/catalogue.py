"""Catalogue of unmodelled effects: switchable engine extensions with one magnitude each.

Every effect names the physics it adds, the magnitude parameter that switches it
on (magnitude 0 is the base model), the prior range of that magnitude, sources,
the expected signature, and the measurements that would identify it. The mapping
from magnitude to workflow configuration options is kept as *data* (``engine_map``):
each effect sets ordinary options of the section where its physics lives
(``contact.capillary``, ``contact.rolling_friction``, ``psd.fines_mass_fraction``,
``spread.ramp_time`` ...), which the embedded engine and the external engines' dialects
realise or refuse by name.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

from ..errors import ConfigError

__all__ = ["Effect", "CATALOGUE", "catalogue", "effect", "halsey_film_thickness",
           "kelvin_radius", "engine_hooks", "CAPILLARY_ASPERITY"]


@dataclass(frozen=True)
class Effect:
    """One unmodelled effect with a single magnitude parameter.

    Parameters
    ----------
    name : str
        Identifier used in magnitudes dicts, JSON and the CLI.
    title : str
        Human-readable name.
    magnitude : str
        Name of the magnitude parameter.
    unit : str
        Unit of the magnitude (SI; ``"1"`` for dimensionless).
    prior : tuple of float
        Prior range ``(lo, hi)`` of the magnitude; 0 (off) lies inside it.
    physics : str
        What the extension adds to the contact model, in words and formulas.
    signature : str
        Expected fingerprint on the observables.
    sources : tuple of str
        Literature (with DOI) behind the physics and the prior range.
    engine_map : tuple of (str, str, float, float)
        ``(option, rule, a, b)`` rows mapping the magnitude ``m`` to workflow
        configuration options (dotted names, ``"contact.rolling_friction"``): rule
        ``"linear"`` gives ``a * m + b``, ``"const"`` gives ``a``, ``"switch"`` gives
        ``m != 0``, ``"offset"`` gives ``max(0, base + a * m)`` with ``base`` the value
        of option ``b`` in the configuration being diagnosed (a change of a contact
        coefficient relative to the base model), ``"halsey"`` gives ``a`` times
        the water film thickness (m) at relative humidity ``m`` (see
        :func:`halsey_film_thickness`), ``"kelvin"`` gives
        ``a * (1 + 2 r_K(m) / b)`` with the Kelvin radius ``r_K`` (see
        :func:`kelvin_radius`); the last two give 0 at ``m = 0``.
    identify_with : tuple of dict
        Measurements (``name``, ``kind``, ``conditions``, ``uncertainty``,
        ``unit``) that would identify the effect when the current observables
        cannot; used as candidate measurements by the diagnosis.
    signed : bool
        Whether negative magnitudes are physical.

    Examples
    --------
    >>> e = effect("capillary_bridges")
    >>> e.magnitude, e.unit, e.prior
    ('relative_humidity', '1', (0.0, 0.8))
    >>> sorted(e.engine_parameters(0.0))[:2]
    ['contact.capillary', 'contact.capillary_contact_angle']
    >>> effect("wall_friction").engine_parameters(0.2, {"contact": {"friction": 0.5}})
    {'contact.wall_friction': 0.7}
    """

    name: str
    title: str
    magnitude: str
    unit: str
    prior: tuple[float, float]
    physics: str
    signature: str
    sources: tuple[str, ...]
    engine_map: tuple[tuple[str, str, float, float], ...]
    identify_with: tuple[Mapping[str, Any], ...] = field(default=())
    signed: bool = False

    @property
    def reference_magnitudes(self) -> tuple[float, float]:
        """The two magnitudes at which fingerprints are simulated: half and full prior top."""
        hi = self.prior[1]
        return (0.5 * hi, hi)

    def engine_parameters(self, magnitude: float,
                          base: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The configuration options that switch this effect on at ``magnitude``.

        Parameters
        ----------
        magnitude : float
            The effect magnitude in :attr:`unit`.
        base : mapping, optional
            The workflow configuration being diagnosed (sections of options), which the
            ``"offset"`` rules read their base value from; needed only by those.

        Returns
        -------
        dict
            ``{"section.option": value}`` in SI units.

        Raises
        ------
        ValueError
            If ``magnitude`` is not finite, or an ``"offset"`` rule has no ``base``
            configuration holding its option.
        """
        m = float(magnitude)
        if not math.isfinite(m):
            raise ValueError(f"magnitude of {self.name!r} must be finite; got {magnitude!r}")
        out: dict[str, Any] = {}
        for key, rule, a, b in self.engine_map:
            if rule == "offset":
                out[key] = max(0.0, _option(base, b, self.name) + a * m)
            elif rule == "linear":
                out[key] = a * m + b
            elif rule == "const":
                out[key] = a
            elif rule == "switch":
                out[key] = m != 0.0
            elif rule == "halsey":
                out[key] = a * halsey_film_thickness(m) if m > 0 else 0.0
            elif rule == "kelvin":
                out[key] = a * (1.0 + 2.0 * kelvin_radius(m) / b) if m > 0 else 0.0
            else:  # pragma: no cover - catalogue data error
                raise ValueError(f"unknown engine_map rule {rule!r} in {self.name!r}")
        return out

    @property
    def realisations(self) -> dict:
        """Per engine (``embedded``, ``liggghts``, ``lammps``), how it realises this effect
        (a :class:`bedstruct.engines.Realisation`: ``how``, or ``refused`` and why).

        Examples
        --------
        >>> effect("contact_ageing").realisations["lammps"].realised
        False
        """
        from ..engines import effect_realisations
        return effect_realisations()[self.name]

    def to_json(self) -> dict:
        return {"name": self.name, "title": self.title, "magnitude": self.magnitude,
                "unit": self.unit, "prior": list(self.prior), "physics": self.physics,
                "signature": self.signature, "sources": list(self.sources),
                "engine_parameters_at_prior_top": engine_hooks()[self.name],
                "engines": {eng: {"realised": r.realised, "how": r.how, "refused": r.refused}
                            for eng, r in self.realisations.items()},
                "identify_with": [dict(d) for d in self.identify_with]}


def _option(cfg, dotted: str, name: str) -> float:
    """The value of option ``section.key`` in the configuration ``cfg``."""
    section, _, key = dotted.partition(".")
    try:
        return float(cfg[section][key])
    except (TypeError, KeyError):
        raise ValueError(f"effect {name!r}: its offset from `{dotted}` needs the configuration "
                         "being diagnosed (base=), holding that option") from None


def halsey_film_thickness(relative_humidity: float, *, monolayer: float = 0.354e-9) -> float:
    """Adsorbed water film thickness at a relative humidity (Halsey equation).

    Parameters
    ----------
    relative_humidity : float
        Relative humidity, dimensionless, in (0, 1).
    monolayer : float, optional
        Thickness of one water monolayer, length (m). Default 0.354 nm.

    Returns
    -------
    float
        Film thickness, length (m).

    Notes
    -----
    .. math:: t = t_m \\left(\\frac{5}{\\ln(1/\\mathrm{RH})}\\right)^{1/3}

    References
    ----------
    Halsey, G. (1948). J. Chem. Phys. 16, 931. doi:10.1063/1.1746689

    Examples
    --------
    >>> round(halsey_film_thickness(0.5) * 1e9, 3)
    0.684
    """
    rh = float(relative_humidity)
    if not 0.0 < rh < 1.0:
        raise ValueError(f"`relative_humidity` must lie in (0, 1); got {relative_humidity!r}")
    return monolayer * (5.0 / math.log(1.0 / rh)) ** (1.0 / 3.0)


def kelvin_radius(relative_humidity: float, *, molar_volume: float = 1.8e-5,
                  surface_tension: float = 0.072, temperature: float = 293.15) -> float:
    """Kelvin radius of water menisci at a relative humidity.

    Parameters
    ----------
    relative_humidity : float
        Relative humidity, dimensionless, in (0, 1).
    molar_volume : float, optional
        Molar volume of the liquid, m^3/mol (water 1.8e-5).
    surface_tension : float, optional
        N/m (water 0.072).
    temperature : float, optional
        K.

    Returns
    -------
    float
        ``r_K = gamma V_m / (R T ln(1/RH))``, length (m): gaps narrower than about
        ``2 r_K cos(theta)`` fill by capillary condensation.

    References
    ----------
    Butt, H.-J., Kappl, M. (2009). Normal capillary forces. Adv. Colloid Interface Sci.
    146, 48-60. doi:10.1016/j.cis.2008.10.002

    Examples
    --------
    >>> round(kelvin_radius(0.5) * 1e9, 2)
    0.77
    """
    rh = float(relative_humidity)
    if not 0.0 < rh < 1.0:
        raise ValueError(f"`relative_humidity` must lie in (0, 1); got {relative_humidity!r}")
    return surface_tension * molar_volume / (8.314462618 * temperature * math.log(1.0 / rh))


#: Asperity model of the capillary bridges (see the ``capillary_bridges`` entry):
#: asperity radius ``r_a`` (m), roughness height scale ``h_r`` (m), contact angle (rad),
#: the reference effective radius ``R*_ref`` (m; D50/4 of the seed powder, equal
#: spheres) at which the engine's Willett form gives the asperity force.
CAPILLARY_ASPERITY = {"asperity_radius": 0.05e-6, "roughness_height": 1.0e-9,
                      "contact_angle": math.radians(20.0), "reference_radius": 52.08e-6 / 4,
                      "surface_tension": 0.072}


def _capillary_map():
    c = CAPILLARY_ASPERITY
    ratio = c["asperity_radius"] / (2.0 * c["reference_radius"])
    return (("contact.capillary", "switch", 0, 0),
            ("contact.capillary_surface_tension", "kelvin", c["surface_tension"] * ratio,
             c["roughness_height"] / math.cos(c["contact_angle"])),
            ("contact.capillary_contact_angle", "const", c["contact_angle"], 0),
            ("contact.capillary_film_thickness", "halsey",
             (c["asperity_radius"] / c["reference_radius"]) ** 2, 0))


def _m(name, kind, uncertainty, unit, **conditions):
    return {"name": name, "kind": kind, "uncertainty": uncertainty, "unit": unit,
            "conditions": conditions}


CATALOGUE: tuple[Effect, ...] = (
    Effect(
        name="contact_ageing",
        title="Humidity-driven contact ageing",
        magnitude="bond_strength_ratio",
        unit="1",
        prior=(0.0, 2.0),
        physics=(
            "Contacts at rest grow a bond (capillary condensation in asperity gaps) whose strength "
            "rises logarithmically with rest time t_w, F_b = r * F_coh * ln(1 + t_w/tau)/ln(1 + t_ref/tau) "
            "(tau = 10 s, t_ref = 60 s, F_coh the SJKR cohesion force of the contact), and breaks for "
            "good once the contact slides more than a critical tangential displacement. The magnitude r "
            "is the aged bond strength relative to the SJKR cohesion after the reference rest time."),
        signature=("Transient: the powder that rested before the stroke resists; the dynamic angle "
                   "spikes in the first ~10 % of the stroke and relaxes to the unaged value; static "
                   "angle of a freshly poured heap barely changes; avalanche angle after rest rises "
                   "logarithmically with rest time."),
        sources=(
            "Bocquet, L., Charlaix, E., Ciliberto, S., Crassous, J. (1998). Moisture-induced ageing in "
            "granular media and the kinetics of capillary condensation. Nature 396, 735-737. "
            "doi:10.1038/25492",
            "Restagno, F., Gayvallet, H., Bocquet, L., Charlaix, E. (1999). Humidity effects and aging "
            "behavior in granular media. arXiv:cond-mat/9908142",
            "Frye, K.M., Marone, C. (2002). Effect of humidity on granular friction at room "
            "temperature. J. Geophys. Res. 107, 2309. doi:10.1029/2001JB000654",
        ),
        engine_map=(("contact.ageing", "switch", 0, 0),
                    ("contact.ageing_bond_ratio", "linear", 1.0, 0.0),
                    ("contact.ageing_time_constant", "const", 10.0, 0),
                    ("contact.ageing_reference_rest_time", "const", 60.0, 0),
                    ("contact.ageing_break_slip", "const", 1e-6, 0)),
        identify_with=(_m("avalanche_angle_rest600", "static_angle", 0.5, "deg", rest_time=600.0,
                          box_width=0.03),
                       _m("dynamic_angle_x5_early", "dynamic_angle_series", 1.0, "deg",
                          speed=0.127, layer=3, time_window=[0.0, 0.1])),
    ),
    Effect(
        name="capillary_bridges",
        title="Capillary liquid bridges (Willett)",
        magnitude="relative_humidity",
        unit="1",
        prior=(0.0, 0.8),
        physics=(
            "Pendular water bridges at asperity contacts. Real gas-atomised particles touch at "
            "nanoscale asperities, so a bridge forms around an asperity of radius r_a, not around "
            "the whole sphere: at RH below ~0.8 the Kelvin radius r_K (0.2-2.4 nm) is far below the "
            "roughness, and the full-sphere pull-off 2 pi R gamma cos(theta) (~2000 particle weights "
            "for 52 um CoCr) does not develop: only a few asperities bridge (van Zwol et al. 2007, "
            "2008, on metal and oxide surfaces with 1-15 nm roughness; Butt & Kappl 2009), and "
            "bridges persist down to a few % RH. Model: "
            "pull-off F = 2 pi r_a gamma cos(theta) n(RH), n = 1 + 2 r_K(RH) cos(theta) / h_r the "
            "number of asperity gaps filled by condensation (r_a = 0.05 um, h_r = 1 nm; Bond "
            "number F / weight ~ 6 at RH 0.3 and ~ 19 at RH 0.8 for a 52 um sphere). The engine's "
            "Willett closed form with R = 2 R*, F = 2 pi R gamma' cos(theta) / (1 + 2.1 S + 10 S^2), "
            "S = (s/2) sqrt(R/V), carries it through the effective surface tension gamma' = gamma "
            "r_a n(RH) / (2 R*_ref) (R*_ref = D50/4), and the bridge volume V = 2 pi R*^2 t' of an "
            "asperity bridge through t' = t_Halsey(RH) (r_a / R*_ref)^2; rupture at s_c = "
            "(1 + theta/2) V^(1/3) (Lian et al. 1993); bridges re-form on contact. Our model, not "
            "a fit to CoCr data: the asperity radius and roughness scale are order-of-magnitude "
            "choices. Magnitude: ambient relative humidity."),
        signature=("Persistent extra cohesion that, unlike SJKR cohesion, acts across gaps up to "
                   "s_c and barely weakens with rake speed: static and dynamic angles rise at all "
                   "speeds; bridges across gaps hold loose agglomerates, so the packing fraction "
                   "of spread layers drops markedly; roughness rises; segregation weakens. Part "
                   "of it is absorbed by recalibrating the cohesion energy density."),
        sources=(
            "Willett, C.D., Adams, M.J., Johnson, S.A., Seville, J.P.K. (2000). Capillary bridges "
            "between two spherical bodies. Langmuir 16, 9396-9405. doi:10.1021/la000657y",
            "Lian, G., Thornton, C., Adams, M.J. (1993). A theoretical study of the liquid bridge "
            "forces between two rigid spherical bodies. J. Colloid Interface Sci. 161, 138-147. "
            "doi:10.1006/jcis.1993.1452",
            "Halsey, G. (1948). Physical adsorption on non-uniform surfaces. J. Chem. Phys. 16, 931. "
            "doi:10.1063/1.1746689",
            "Mitarai, N., Nori, F. (2006). Wet granular materials. Adv. Phys. 55, 1-45. "
            "doi:10.1080/00018730600626065",
            "van Zwol, P.J., Palasantzas, G., De Hosson, J.Th.M. (2007). Influence of random "
            "roughness on the adhesion between metal surfaces due to capillary condensation. "
            "Appl. Phys. Lett. 91, 101905. doi:10.1063/1.2768919",
            "van Zwol, P.J., Palasantzas, G., De Hosson, J.Th.M. (2008). Influence of roughness on "
            "capillary forces between hydrophilic surfaces. Phys. Rev. E 78, 031606. "
            "doi:10.1103/PhysRevE.78.031606",
            "Butt, H.-J., Kappl, M. (2009). Normal capillary forces. Adv. Colloid Interface Sci. "
            "146, 48-60. doi:10.1016/j.cis.2008.10.002",
        ),
        engine_map=_capillary_map(),
        identify_with=(_m("static_angle_dry", "static_angle", 0.5, "deg", relative_humidity=0.05,
                          box_width=0.03),
                       _m("packing_fraction_x1_center", "packing_fraction", 0.005, "1",
                          speed=0.0254, layer=1, region="center")),
    ),
    Effect(
        name="non_sphericity",
        title="Particle non-sphericity via rolling resistance",
        magnitude="extra_rolling_friction",
        unit="1",
        prior=(0.0, 0.3),
        physics=(
            "Shape is represented by an elastic-plastic spring-dashpot (EPSD) rolling resistance "
            "torque, limited by M_r = mu_r,shape R* F_n, on top of the base constant-torque model; "
            "the magnitude is the extra rolling friction coefficient mu_r,shape that mimics the "
            "interlocking of non-spherical gas-atomised particles (satellites, ellipticity)."),
        signature=("Static angles rise in any box; dynamic angles rise, increasingly with rake "
                   "speed (rolling dominates in fast flow, interlocking under shear); packing "
                   "fraction and coordination fall; roughness rises. Distinct from cohesion, whose "
                   "effect on the dynamic angle weakens with speed."),
        sources=(
            "Ai, J., Chen, J.-F., Rotter, J.M., Ooi, J.Y. (2011). Assessment of rolling resistance "
            "models in discrete element simulations. Powder Technol. 206, 269-282. "
            "doi:10.1016/j.powtec.2010.09.030",
            "Wensrich, C.M., Katterfeld, A. (2012). Rolling friction as a technique for modelling "
            "particle shape in DEM. Powder Technol. 217, 409-417. doi:10.1016/j.powtec.2011.10.057",
        ),
        engine_map=(("contact.rolling_model", "const", "epsd", 0),
                    ("contact.rolling_friction", "offset", 1.0, "contact.rolling_friction"),
                    ("contact.rolling_stiffness_factor", "const", 2.25, 0)),
        identify_with=(_m("packing_fraction_x1_center", "packing_fraction", 0.005, "1",
                          speed=0.0254, layer=1, region="center"),
                       _m("coordination_x1_center", "coordination", 0.2, "1",
                          speed=0.0254, layer=1, region="center")),
    ),
    Effect(
        name="missing_fines",
        title="Fines missing from the simulated PSD",
        magnitude="fines_mass_fraction",
        unit="1",
        prior=(0.0, 0.12),
        physics=(
            "The simulated PSD is cut at 14 um radius (28 um diameter); the extension inserts the "
            "measured tail below the cut-off as a log-normal fines population (median 20 um "
            "diameter, sigma_ln 0.25) carrying the given mass fraction of the powder, with the "
            "same contact law (their higher granular Bond number makes them more cohesive); the "
            "spreading pile keeps the base powder's solid volume (more, smaller spheres)."),
        signature=("PSD before spreading: d10 falls strongly, d50 a little; packing fraction rises "
                   "(fines fill voids), coordination rises; angles rise slightly; after spreading "
                   "fines percolate, so the spread layer is finer than the pile."),
        sources=(
            "Meier, C., Weissbach, R., Weinberg, J., Wall, W.A., Hart, A.J. (2019). Critical "
            "influences of particle size and adhesion on the powder layer uniformity in metal "
            "additive manufacturing. J. Mater. Process. Technol. 266, 484-501. "
            "doi:10.1016/j.jmatprotec.2018.10.037",
            "Seed report: measured PSD 25-105 um with D10 = 29.84 um vs simulated radii 14-50 um.",
        ),
        engine_map=(("psd.fines_mass_fraction", "linear", 1.0, 0.0),
                    ("psd.fines_median_diameter", "const", 20e-6, 0),
                    ("psd.fines_sigma_ln", "const", 0.25, 0),
                    ("psd.fines_min_diameter", "const", 8e-6, 0)),
        identify_with=(_m("psd_before", "psd", 0.6e-6, "m", stage="before"),),
    ),
    Effect(
        name="wall_friction",
        title="Wall and blade friction differing from particle-particle friction",
        magnitude="wall_friction_excess",
        unit="1",
        prior=(-0.2, 0.4),
        signed=True,
        physics=(
            "Particle-wall (blade, plate and side walls) sliding friction mu_w = mu + d_mu instead "
            "of the particle-particle value mu; rolling friction against walls unchanged. Magnitude: "
            "d_mu (negative for polished walls)."),
        signature=("Side walls of the narrow simulated repose box hold the heap: the static angle "
                   "rises in a narrow box but hardly in a wide one (spheres roll along the walls, "
                   "so the rise is small); blade friction acts in a thin boundary layer, so the "
                   "free-surface dynamic angle changes little, but the vertical load on the blade "
                   "over the horizontal one (a two-axis load cell on the recoater) follows d_mu, "
                   "in a direction set by the blade's bevel and the particle size: on the tiny "
                   "scale model 0.17 on a powder bed, +0.03 at +0.4 and -0.05 at -0.2 (powder "
                   "dragged down the face); on the small one -0.16, -0.5 at +0.4 (powder "
                   "wedged under the bevel pushes the blade up), run scatter 0.006 at the base; "
                   "plate friction thickens the first layer and steepens the packing gradient "
                   "along the plate."),
        sources=(
            "Zhou, Y.C., Xu, B.H., Yu, A.B., Zulli, P. (2002). An experimental and numerical study of "
            "the angle of repose of coarse spheres. Powder Technol. 125, 45-54. "
            "doi:10.1016/S0032-5910(01)00520-4",
            "Haeri, S. (2017). Optimisation of blade type spreaders for powder bed preparation in "
            "additive manufacturing using DEM simulations. Powder Technol. 321, 94-104. "
            "doi:10.1016/j.powtec.2017.08.011",
        ),
        engine_map=(("contact.wall_friction", "offset", 1.0, "contact.friction"),),
        identify_with=(_m("static_angle_narrow_box", "static_angle", 0.5, "deg", box_width=0.003),
                       _m("static_angle_wide_box", "static_angle", 0.5, "deg", box_width=0.03),
                       _m("tool_force_ratio_x1_layer2", "tool_force_ratio", 0.005, "1",
                          speed=0.0254, layer=2)),
    ),
    Effect(
        name="blade_startup",
        title="Blade start-up acceleration and vibration",
        magnitude="ramp_time",
        unit="s",
        prior=(0.0, 0.25),
        physics=(
            "The stage does not start at full speed: v(t) = v (1 - exp(-t/tau)) with ramp time tau "
            "(the magnitude), plus a sinusoidal blade vibration of fixed amplitude and frequency "
            "(held at the values below, measured from a stage accelerometer when available)."),
        signature=("Early-stroke dynamic angle is *lower* than steady (the pile sees a slower "
                   "blade), most at the highest speed where the angle depends steeply on speed and "
                   "the stroke is shortest; the start region of the bed is packed differently."),
        sources=(
            "Nan, W., Pasha, M., Ghadiri, M. (2018). Jamming during particle spreading in additive "
            "manufacturing. Powder Technol. 338, 253-262. doi:10.1016/j.powtec.2018.07.030",
            "Haeri, S. (2017). Powder Technol. 321, 94-104. doi:10.1016/j.powtec.2017.08.011",
        ),
        engine_map=(("spread.ramp_time", "linear", 1.0, 0.0),
                    ("spread.vibration_amplitude", "const", 2e-6, 0),
                    ("spread.vibration_frequency", "const", 120.0, 0)),
        identify_with=(_m("dynamic_angle_x5_early", "dynamic_angle_series", 1.0, "deg",
                          speed=0.127, layer=3, time_window=[0.0, 0.1]),
                       _m("packing_fraction_x5_start", "packing_fraction", 0.005, "1",
                          speed=0.127, layer=1, region="start")),
    ),
)


def catalogue(names=None, *, exclude=()) -> tuple[Effect, ...]:
    """The catalogue, optionally restricted to ``names`` and without ``exclude``.

    Parameters
    ----------
    names : iterable of str, optional
        Effects to keep (default: all).
    exclude : iterable of str, optional
        Effects to drop (used by the out-of-catalogue validation twins).

    Raises
    ------
    ConfigError
        If a name is not in the catalogue.

    Examples
    --------
    >>> [e.name for e in catalogue(exclude=["blade_startup"])][-1]
    'wall_friction'
    """
    known = {e.name: e for e in CATALOGUE}
    for n in list(names or []) + list(exclude):
        if n not in known:
            raise ConfigError(f"catalogue: unknown effect {n!r}; known: {sorted(known)}")
    keep = list(names) if names is not None else [e.name for e in CATALOGUE]
    return tuple(known[n] for n in keep if n not in set(exclude))


def effect(name: str) -> Effect:
    """The catalogue entry called ``name`` (ConfigError if unknown)."""
    return catalogue([name])[0]


def engine_hooks(base: Mapping[str, Any] | None = None) -> dict[str, dict[str, Any]]:
    """The configuration options every effect sets at the top of its prior (the wiring
    contract), on the configuration ``base`` (default: the workflow defaults).

    Examples
    --------
    >>> engine_hooks()["wall_friction"]      # contact.friction 0.4 + 0.4
    {'contact.wall_friction': 0.8}
    """
    if base is None:
        from ..workflows.config import DEFAULTS as base
    return {e.name: e.engine_parameters(e.prior[1], base) for e in CATALOGUE}
