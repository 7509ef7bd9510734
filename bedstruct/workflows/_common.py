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
from .schema import psd_table

log = logging.getLogger(__name__)

__all__ = ["contact_model", "psd_sampler", "mean_sphere_volume", "insert_carrying",
           "tabulated_psd_sampler", "side_walls",
           "width_bounds", "check_engine", "tool_motion", "from_plain", "frame_fingerprint",
           "german_fit_values", "progress_bar", "CONTACT_KEYWORDS"]

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


def typed(cfg):
    """``cfg`` as a :class:`~bedstruct.workflows.WorkflowConfig`
    (:func:`~bedstruct.workflows.config.workflow_config`: a mapping is loaded and checked,
    a WorkflowConfig is taken as it is)."""
    from .config import workflow_config
    return workflow_config(cfg)


def check_engine(cfg) -> None:
    """Raise ConfigError when an embedded-engine step is handed another engine's config."""
    eng = typed(cfg).engine
    if eng != "embedded":
        raise ConfigError(f"engine {eng!r}: this step runs the embedded engine only; run "
                          "LIGGGHTS/LAMMPS through run_repose, run_spread or calibrate_cohesion "
                          "(bedstruct.workflows), which hand the config to bedstruct.workflows.external")


#: ``contact`` options that are not :class:`~bedstruct.dem.ContactModel` fields of the same
#: name and meaning (every other one is passed to it as it is).
_CONTACT_OWN = ("cohesion", "wall_friction", "wall_cohesion", "ageing")


def contact_model(cfg, *, cohesion: float | None = None):
    """The :class:`~bedstruct.dem.ContactModel` of a configuration (SI).

    Every ``contact`` option named like a field of the contact model is that field
    (coefficients, the rolling model, liquid bridges, the ageing law's parameters); a
    negative ``wall_friction`` / ``wall_cohesion`` is the particle value, and contact
    ageing is on when ``ageing`` is set with a positive ``ageing_bond_ratio``.
    """
    from ..dem import ContactModel, Material
    cfg = typed(cfg)
    m, c = cfg.material, cfg.contact
    mat = Material(m.youngs_modulus, m.poisson_ratio, m.density)
    k = float(c.cohesion if cohesion is None else cohesion)
    if k < 0:
        raise ConfigError(f"config key `contact.cohesion` must be >= 0; got {k}")
    fields_of_model = {f.name for f in fields(ContactModel)}
    kw = {f.name: getattr(c, f.name) for f in fields(c)
          if f.name in fields_of_model and f.name not in _CONTACT_OWN}
    if c.wall_friction >= 0:
        kw["wall_friction"] = c.wall_friction
    if c.wall_cohesion >= 0:
        kw["wall_cohesion"] = c.wall_cohesion
    kw["contact_ageing"] = bool(c.ageing) and c.ageing_bond_ratio > 0.0
    return ContactModel(mat, cohesion=k, **kw)


def tool_motion(sim, cfg, name: str, velocity, **kw) -> None:
    """Start the spreading tool: constant velocity, or the start-up ramp and vibration of
    ``spread.ramp_time`` / ``spread.vibration_*`` when set
    (:meth:`~bedstruct.dem.Simulation.set_wall_program`, vibration along z)."""
    sp = typed(cfg).spread
    tau = float(sp.ramp_time)
    amp = float(sp.vibration_amplitude)
    freq = float(sp.vibration_frequency)
    if tau > 0.0 or (amp > 0.0 and freq > 0.0):
        if kw:
            sim.set_wall_motion(name, **kw)
        sim.set_wall_program(name, velocity=velocity, ramp_time=tau,
                             vibration_amplitude=amp if freq > 0.0 else 0.0,
                             vibration_frequency=freq)
    else:
        sim.set_wall_motion(name, velocity=velocity, **kw)


def width_bounds(width: float, *, walls: bool, margin: float) -> tuple[float, float, str]:
    """``(ylo, yhi, boundary)`` of a workflow's simulation box across y.

    Periodic over ``[0, width]`` without side walls; with them (:func:`side_walls`) the
    box reaches ``margin`` beyond each wall and y is not periodic.

    Examples
    --------
    >>> width_bounds(3e-3, walls=False, margin=1e-4)
    (0.0, 0.003, 'pp')
    >>> width_bounds(3e-3, walls=True, margin=1e-4)
    (-0.0001, 0.0031, 'ff')
    """
    if walls:
        return -float(margin), float(width) + float(margin), "ff"
    return 0.0, float(width), "pp"


def side_walls(width: float, *, x_range, z_range, prefix: str = "box") -> list:
    """The side walls at y = 0 and y = ``width`` over ``x_range`` x ``z_range``.

    Fixed plates (:class:`~bedstruct.dem.Rectangle`, the ``y`` pair of
    :func:`~bedstruct.dem.box_walls`) named ``{prefix}_ylo`` and ``{prefix}_yhi``: the
    particle-wall contacts of the contact model's wall parameters. The repose box
    (``repose.periodic_width = false``) and the spreading run (``spread.side_walls``)
    are bounded across y by them.

    Examples
    --------
    >>> [(w.name, float(w.center[1])) for w in side_walls(3e-3, x_range=(0, 1e-2), z_range=(0, 2e-3))]
    [('box_ylo', 0.0), ('box_yhi', 0.003)]
    """
    from ..dem import box_walls
    lo = (float(x_range[0]), 0.0, float(z_range[0]))
    hi = (float(x_range[1]), float(width), float(z_range[1]))
    return box_walls(lo, hi, open_top=True, sides=("y",), prefix=prefix)[1:]


def tabulated_psd_sampler(diameters, volume_fractions, *, scale: float = 1.0):
    """A callable ``(n, rng) -> radii`` (m) drawing by number from a tabulated volume CDF.

    Parameters
    ----------
    diameters : (M,) array_like of float, m
        Increasing diameters, M >= 3.
    volume_fractions : (M,) array_like of float
        Cumulative volume fraction undersize at each diameter (laser diffraction's
        table), not decreasing, in [0, 1].
    scale : float
        Coarse-graining factor multiplying every drawn diameter.

    Returns
    -------
    callable
        With attributes ``r_min``, ``r_max`` (the table's range times ``scale``, halved)
        and ``number_fractions`` (the number fraction in each interval of the table).

    Notes
    -----
    The volume CDF is interpolated linearly in :math:`\\ln d` between the points and
    truncated to the table's range (renormalised from its first to its last value):
    in interval :math:`i` the volume density per :math:`\\ln d` is the constant
    :math:`c_i = \\Delta F_i / \\Delta \\ln d_i`. A particle's volume is
    :math:`\\propto d^3`, so the number density per :math:`\\ln d` is
    :math:`c_i d^{-3}`, exactly: interval :math:`i` holds the number weight
    :math:`w_i = c_i (d_i^{-3} - d_{i+1}^{-3}) / 3`, and inside it
    :math:`d^{-3}` is uniform between :math:`d_i^{-3}` and :math:`d_{i+1}^{-3}`.
    An interval is drawn by :math:`w_i`, then :math:`d` by inverting that.

    Examples
    --------
    >>> import numpy as np
    >>> draw = tabulated_psd_sampler([20e-6, 40e-6, 80e-6], [0.0, 0.5, 1.0])
    >>> r = draw(100000, np.random.default_rng(0))
    >>> bool(r.min() >= 10e-6 and r.max() <= 40e-6)
    True
    >>> d = 2 * r        # half the volume lies below 40 um
    >>> round(float(np.sum(d[d < 40e-6] ** 3) / np.sum(d ** 3)), 2)
    0.5
    """
    d = np.asarray(diameters, dtype=np.float64)
    f = np.asarray(volume_fractions, dtype=np.float64)
    psd_table({"diameters": d, "volume_fractions": f})   # the checks, named by key
    lnd = np.log(d)
    c = np.diff(f) / np.diff(lnd)                    # volume fraction per ln d, per interval
    inv3 = d ** -3.0
    w = c * (inv3[:-1] - inv3[1:]) / 3.0             # number weight per interval
    p_num = w / w.sum()
    cum = np.cumsum(p_num)
    cum[-1] = 1.0
    scale = float(scale)

    def draw(n, rng):
        n = int(n)
        i = np.minimum(np.searchsorted(cum, rng.random(n), side="right"), len(w) - 1)
        u = rng.random(n)
        x = inv3[i] - u * (inv3[i] - inv3[i + 1])  # d^-3, uniform within the interval
        return 0.5 * scale * np.clip(x ** (-1.0 / 3.0), d[i], d[i + 1])
    draw.r_min = 0.5 * scale * float(d[0])
    draw.r_max = 0.5 * scale * float(d[-1])
    draw.number_fractions = p_num
    draw.fit = None
    return draw


def mean_sphere_volume(draw, n_draws: int = 20_000) -> float:
    """Mean sphere volume of a size distribution ``draw`` (:func:`psd_sampler`), m^3, over
    ``n_draws`` radii of a fixed generator (the same number for the same distribution)."""
    r = draw(int(n_draws), np.random.default_rng(0))
    return float(np.mean(4.0 / 3.0 * np.pi * r ** 3))


def insert_carrying(sim, need: int, carried, draw, region) -> list:
    """Raindrop-insert ``need`` spheres into ``region``, the radii carried over first.

    The radii are ``carried`` (those an earlier insertion found no room for) and, for the
    rest of ``need``, fresh draws of ``draw`` from the simulation's generator. Returns the
    radii not placed (floats), to carry to the next insertion: a volume filled in several
    insertions then holds the distribution drawn, where dropping the spheres that found no
    room (and drawing anew) keeps the small ones, which fit more often.
    """
    from ..dem import sample_radii
    need = max(int(need), 0)
    radii = np.asarray([float(r) for r in carried][:need], dtype=np.float64)
    if need > radii.shape[0]:
        radii = np.concatenate([radii, sample_radii(need - radii.shape[0], draw, rng=sim.rng)])
    placed = sim.insert_radii(radii, region=region)
    return [float(r) for r in radii[~placed]]


def psd_sampler(cfg):
    """A callable ``(n, rng) -> radii`` (m) drawing from the configured, scaled size distribution.

    With a tabulated distribution (``psd.diameters`` and ``psd.volume_fractions``,
    :func:`tabulated_psd_sampler`) the radii are drawn from it, truncated to its
    range; otherwise the volume-weighted D10/D50/D90 are fitted with
    :func:`bedstruct.analysis.psd_from_percentiles` (truncated to
    ``[d_min, d_max]``). Every drawn diameter is multiplied by ``psd.scale``;
    ``psd.fines_mass_fraction`` adds fines below the smallest diameter.
    """
    p = typed(cfg).psd
    scale = float(p.scale)
    phi = float(p.fines_mass_fraction)
    table = psd_table({"diameters": p.diameters, "volume_fractions": p.volume_fractions})
    if table is not None:
        draw = tabulated_psd_sampler(*table, scale=scale)
        d_cut = float(table[0][0])
    else:
        from ..analysis import psd_from_percentiles
        fit = psd_from_percentiles(p.d10, p.d50, p.d90, (p.d_min, p.d_max), weighting="volume")

        def draw(n, rng):
            return scale * fit.sample_radii(int(n), seed=rng)
        draw.r_min = 0.5 * scale * p.d_min
        draw.r_max = 0.5 * scale * p.d_max
        draw.fit = fit
        d_cut = p.d_min
    if phi <= 0.0:
        return draw
    return _with_fines(draw, phi, p, d_cut=d_cut, scale=scale)


def _fines_diameters(n, rng, p, d_cut):
    """Number-weighted draw of the fines: log-normal with volume-weighted median
    ``fines_median_diameter`` (number median ``d50_v exp(-3 sigma^2)``), truncated to
    ``[fines_min_diameter, d_cut]`` by inverse-CDF sampling (m, unscaled)."""
    from scipy.special import ndtr, ndtri
    s = float(p.fines_sigma_ln)
    mu = math.log(float(p.fines_median_diameter)) - 3.0 * s * s
    lo = ndtr((math.log(float(p.fines_min_diameter)) - mu) / s)
    hi = ndtr((math.log(float(d_cut)) - mu) / s)
    if not hi > lo:
        raise ConfigError("config keys `psd.fines_*`: the fines distribution has no mass "
                          f"between psd.fines_min_diameter and the smallest diameter ({d_cut})")
    u = lo + (hi - lo) * rng.random(int(n))
    return np.exp(mu + s * ndtri(u))


def _with_fines(base, phi, p, *, d_cut, scale):
    """Mix a fines population carrying mass fraction ``phi`` into the sampler ``base``
    (fines below ``d_cut``: ``psd.d_min``, or the tabulated distribution's smallest diameter)."""
    if float(p.fines_min_diameter) >= d_cut:
        raise ConfigError("config key `psd.fines_min_diameter` must lie below the smallest "
                          f"diameter of the size distribution (`psd.d_min`, or the first of "
                          f"`psd.diameters`): {d_cut!r} m")
    ref = np.random.default_rng(12345)
    v_c = float(np.mean((2.0 * base(20000, ref) / scale) ** 3))
    v_f = float(np.mean(_fines_diameters(20000, ref, p, d_cut) ** 3))
    p_f = (phi / v_f) / (phi / v_f + (1.0 - phi) / v_c)   # number fraction of fines

    def draw(n, rng):
        n = int(n)
        k = int(rng.binomial(n, p_f))
        r = np.concatenate([base(n - k, rng), 0.5 * scale * _fines_diameters(k, rng, p, d_cut)])
        rng.shuffle(r)
        return r
    draw.r_min = 0.5 * scale * float(p.fines_min_diameter)
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


def german_fit_values(fractions, coordinations) -> tuple[float, float, float, bool | None]:
    """``(a, b, r_squared, determined)`` of German's law over the finite points (``determined``:
    :attr:`~bedstruct.analysis.GermanFit.determined`); NaN and None with fewer than 3."""
    from ..analysis import fit_german_law
    f_arr, c_arr = np.asarray(fractions, dtype=float), np.asarray(coordinations, dtype=float)
    good = np.isfinite(f_arr) & np.isfinite(c_arr) & (f_arr > 0)
    if good.sum() >= 3:
        try:
            g = fit_german_law(f_arr[good], c_arr[good])
            return float(g.a), float(g.b), float(g.r_squared), bool(g.determined)
        except (ValueError, np.linalg.LinAlgError) as exc:
            log.warning("German's-law fit failed: %s", exc)
    nan = float("nan")
    return nan, nan, nan, None
