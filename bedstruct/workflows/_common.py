"""Shared pieces of the workflows: model from config, size distribution, tool motion.

The run folders live in :mod:`bedstruct.workflows._rundir`, resuming in
:mod:`bedstruct.workflows._resume`; JSON conversion in :mod:`bedstruct._json`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import fields

import numpy as np

from ..errors import ConfigError

log = logging.getLogger(__name__)

__all__ = ["contact_model", "psd_sampler", "check_engine", "tool_motion", "from_plain",
           "frame_fingerprint", "german_fit_values", "progress_bar", "CONTACT_KEYWORDS"]

#: LIGGGHTS ``compute pair/gran/local`` keywords of the contact dumps written by the workflows.
CONTACT_KEYWORDS = ("pos", "id", "force", "force_normal", "force_tangential", "contactArea")


def progress_bar(iterable=None, *, progress: bool, **kwargs):
    """A tqdm progress bar when ``progress`` (the notebook one in Jupyter), else a silent one.

    The silent one is plain tqdm: tqdm's notebook front end is imported only for a
    bar that is shown, as it warns where ipywidgets is missing.
    """
    if progress:
        from tqdm.auto import tqdm
    else:
        from tqdm import tqdm
    return tqdm(iterable, disable=not progress, **kwargs)


def check_engine(cfg: dict) -> None:
    """Raise ConfigError when an embedded-engine step is handed another engine's config."""
    eng = cfg.get("engine", "embedded")
    if eng != "embedded":
        raise ConfigError(f"engine {eng!r}: this step runs the embedded engine only; run "
                          "LIGGGHTS/LAMMPS through run_repose, run_spread or calibrate_cohesion "
                          "(bedstruct.workflows), which hand the config to bedstruct.workflows.external")


def contact_model(cfg: dict, *, cohesion: float | None = None):
    """The :class:`~bedstruct.dem.ContactModel` of a configuration (SI)."""
    from ..dem import ContactModel, Material
    m, c = cfg["material"], cfg["contact"]
    mat = Material(m["youngs_modulus"], m["poisson_ratio"], m["density"])
    k = float(c["cohesion"] if cohesion is None else cohesion)
    if k < 0:
        raise ConfigError(f"config key `contact.cohesion` must be >= 0; got {k}")
    kw = {}
    if c["wall_friction"] >= 0:
        kw["wall_friction"] = c["wall_friction"]
    if c["wall_cohesion"] >= 0:
        kw["wall_cohesion"] = c["wall_cohesion"]
    rolling_friction, rolling_model = c["rolling_friction"], c["rolling_model"]
    fx = cfg.get("effects")
    if fx:  # diagnosis extensions; every one off at its default (the base model)
        if fx["wall_friction_excess"] != 0.0:
            mu_w = c["wall_friction"] if c["wall_friction"] >= 0 else c["friction"]
            kw["wall_friction"] = max(0.0, mu_w + fx["wall_friction_excess"])
        if fx["shape_rolling_friction"] > 0.0:
            rolling_model = fx["rolling_model"]
            rolling_friction = rolling_friction + fx["shape_rolling_friction"]
            kw["rolling_stiffness_factor"] = fx["rolling_stiffness_factor"]
        if fx["capillary"]:
            kw.update(capillary=True, capillary_surface_tension=fx["capillary_surface_tension"],
                      capillary_contact_angle=fx["capillary_contact_angle"],
                      capillary_film_thickness=fx["capillary_film_thickness"])
        if fx["contact_ageing"] and fx["ageing_bond_ratio"] > 0.0:
            kw.update(contact_ageing=True, ageing_bond_ratio=fx["ageing_bond_ratio"],
                      ageing_time_constant=fx["ageing_time_constant"],
                      ageing_reference_rest_time=fx["ageing_reference_rest_time"],
                      ageing_break_slip=fx["ageing_break_slip"])
    return ContactModel(mat, restitution=c["restitution"], friction=c["friction"],
                        rolling_friction=rolling_friction, cohesion=k,
                        rolling_model=rolling_model, **kw)


def tool_motion(sim, cfg: dict, name: str, velocity, **kw) -> None:
    """Start the spreading tool: constant velocity, or the start-up ramp and vibration of
    ``effects.blade_ramp_time`` / ``blade_vibration_*`` when set
    (:meth:`~bedstruct.dem.Simulation.set_wall_program`, vibration along z)."""
    fx = cfg.get("effects") or {}
    tau = float(fx.get("blade_ramp_time", 0.0))
    amp = float(fx.get("blade_vibration_amplitude", 0.0))
    freq = float(fx.get("blade_vibration_frequency", 0.0))
    if tau > 0.0 or (amp > 0.0 and freq > 0.0):
        if kw:
            sim.set_wall_motion(name, **kw)
        sim.set_wall_program(name, velocity=velocity, ramp_time=tau,
                             vibration_amplitude=amp if freq > 0.0 else 0.0,
                             vibration_frequency=freq)
    else:
        sim.set_wall_motion(name, velocity=velocity, **kw)


def psd_sampler(cfg: dict):
    """A callable ``(n, rng) -> radii`` (m) drawing from the fitted, scaled size distribution.

    The volume-weighted D10/D50/D90 are fitted with
    :func:`bedstruct.analysis.psd_from_percentiles` (truncated to
    ``[d_min, d_max]``) and every drawn diameter is multiplied by
    ``psd.scale``.
    """
    from ..analysis import psd_from_percentiles
    p = cfg["psd"]
    fit = psd_from_percentiles(p["d10"], p["d50"], p["d90"], (p["d_min"], p["d_max"]),
                               weighting="volume")
    scale = float(p["scale"])

    fx = cfg.get("effects") or {}
    phi = float(fx.get("fines_mass_fraction", 0.0))

    def draw(n, rng):
        return scale * fit.sample_radii(int(n), seed=rng)
    draw.r_min = 0.5 * scale * p["d_min"]
    draw.r_max = 0.5 * scale * p["d_max"]
    draw.fit = fit
    if phi <= 0.0:
        return draw
    return _with_fines(draw, phi, fx, d_cut=p["d_min"], scale=scale)


def _fines_diameters(n, rng, fx, d_cut):
    """Number-weighted draw of the fines: log-normal with volume-weighted median
    ``fines_median_diameter`` (number median ``d50_v exp(-3 sigma^2)``), truncated to
    ``[fines_min_diameter, d_cut]`` by inverse-CDF sampling (m, unscaled)."""
    from scipy.special import ndtr, ndtri
    s = float(fx["fines_sigma_ln"])
    mu = math.log(float(fx["fines_median_diameter"])) - 3.0 * s * s
    lo = ndtr((math.log(float(fx["fines_min_diameter"])) - mu) / s)
    hi = ndtr((math.log(float(d_cut)) - mu) / s)
    if not hi > lo:
        raise ConfigError("config keys `effects.fines_*`: the fines distribution has no mass "
                          f"between fines_min_diameter and psd.d_min ({d_cut})")
    u = lo + (hi - lo) * rng.random(int(n))
    return np.exp(mu + s * ndtri(u))


def _with_fines(base, phi, fx, *, d_cut, scale):
    """Mix a fines population carrying mass fraction ``phi`` into the sampler ``base``."""
    if float(fx["fines_min_diameter"]) >= d_cut:
        raise ConfigError("config key `effects.fines_min_diameter` must lie below `psd.d_min`")
    ref = np.random.default_rng(12345)
    v_c = float(np.mean((2.0 * base(20000, ref) / scale) ** 3))
    v_f = float(np.mean(_fines_diameters(20000, ref, fx, d_cut) ** 3))
    p_f = (phi / v_f) / (phi / v_f + (1.0 - phi) / v_c)   # number fraction of fines

    def draw(n, rng):
        n = int(n)
        k = int(rng.binomial(n, p_f))
        r = np.concatenate([base(n - k, rng), 0.5 * scale * _fines_diameters(k, rng, fx, d_cut)])
        rng.shuffle(r)
        return r
    draw.r_min = 0.5 * scale * float(fx["fines_min_diameter"])
    draw.r_max = base.r_max
    draw.fit = base.fit
    draw.fines_number_fraction = p_f
    return draw


def from_plain(cls, data: dict):
    """Rebuild the dataclass ``cls`` from :func:`bedstruct._json.plain` data (keys that are not fields are
    ignored; lists become tuples, ``None`` in a float field NaN)."""
    out = {}
    for f in fields(cls):
        if f.name not in data:
            continue
        v = data[f.name]
        if f.type in ("float",) and v is None:
            v = float("nan")
        elif isinstance(v, list):
            v = tuple(float("nan") if x is None else tuple(x) if isinstance(x, list) else x
                      for x in v)
        out[f.name] = v
    return cls(**out)


def frame_fingerprint(frame) -> str:
    """A short hash of a frame's particles (ids, types, positions, radii, velocities)."""
    import hashlib
    h = hashlib.sha256()
    for a in (frame.ids, frame.types, frame.positions, frame.radii, frame.velocities,
              frame.omegas):
        if a is not None:
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def german_fit_values(fractions, coordinations) -> tuple[float, float, float]:
    """``(a, b, r_squared)`` of German's law over the finite points; NaN with fewer than 3."""
    from ..analysis import fit_german_law
    f_arr, c_arr = np.asarray(fractions, dtype=float), np.asarray(coordinations, dtype=float)
    good = np.isfinite(f_arr) & np.isfinite(c_arr) & (f_arr > 0)
    if good.sum() >= 3:
        try:
            g = fit_german_law(f_arr[good], c_arr[good])
            return float(g.a), float(g.b), float(g.r_squared)
        except (ValueError, np.linalg.LinAlgError) as exc:
            log.warning("German's-law fit failed: %s", exc)
    nan = float("nan")
    return nan, nan, nan
