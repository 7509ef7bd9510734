"""The workflow configuration, defined once: sections as frozen dataclasses.

Each section (``material``, ``contact``, ``psd``, ``time``, ``repose``, ``spread``,
``calibrate``, ``external``, ``output``) is a frozen dataclass whose fields carry
their default, unit, meaning and bounds in the field metadata. The diagnosis'
effects are ordinary options of the section whose physics they change (liquid
bridges, contact ageing and the EPSD rolling stiffness in ``contact``, a fines tail
in ``psd``, the tool's start-up and vibration in ``spread``); every default is the
base model.
From this one definition come the defaults of :func:`~bedstruct.workflows.load_config`
(:data:`~bedstruct.workflows.DEFAULTS`), the range checks and their messages, the
configuration reference of ``bedstruct run WORKFLOW --help-config`` and of the docs
(:func:`config_reference`), and typed, read-only access to a loaded configuration
(:func:`typed_config`; :func:`config_dict` gives its dict back). :func:`psd_table` checks a
tabulated size distribution.
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields

import numpy as np

from ..errors import ConfigError

__all__ = ["WorkflowConfig", "MaterialSection", "ContactSection", "PSDSection", "TimeSection",
           "ReposeSection", "SpreadSection", "CalibrateSection", "ExternalSection",
           "OutputSection", "typed_config", "config_dict", "defaults_dict", "check_bounds",
           "config_reference", "psd_table", "SECTIONS"]

#: Largest volume fraction a tabulated size distribution (``psd.volume_fractions``) may
#: leave out below its first diameter or above its last (a measured table cut off in its
#: tails); the draws are renormalised to the table's range. More is refused.
PSD_END_MAX_MISSING = 0.1

#: Largest ``time.safety``: the engine refuses a step above this fraction of the Rayleigh
#: time (``Simulation(max_rayleigh_fraction=0.3)``, LIGGGHTS' check/timestep/gran advice).
MAX_SAFETY = 0.3


def key(default, unit: str = "", doc: str = "", *, gt=None, ge=None, lt=None, le=None,
        choices: tuple | None = None):
    """A configuration field: its default, unit, one-line meaning and bounds.

    ``gt``/``ge``/``lt``/``le`` bound a number (every element of a list);
    ``choices`` lists the allowed strings.
    """
    meta = {"unit": unit, "doc": doc, "gt": gt, "ge": ge, "lt": lt, "le": le, "choices": choices}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class MaterialSection:
    """Particle material."""

    youngs_modulus: float = key(1e7, "Pa", "Young's modulus (softened; CoCr is about 2.1e11)", gt=0)
    poisson_ratio: float = key(0.3, "", "Poisson's ratio (isotropic solids: -1 to 0.5)", gt=-1, lt=0.5)
    density: float = key(8300.0, "kg/m^3", "particle density (CoCr)", gt=0)


@dataclass(frozen=True)
class ContactSection:
    """Contact model between particles (and walls)."""

    restitution: float = key(0.1, "", "normal coefficient of restitution", gt=0, le=1)
    friction: float = key(0.4, "", "sliding friction coefficient", ge=0)
    rolling_friction: float = key(0.05, "", "rolling friction coefficient", ge=0)
    cohesion: float = key(0.0, "J/m^3", "SJKR cohesion energy density", ge=0)
    rolling_model: str = key("epsd2", "", "rolling resistance model", choices=("epsd", "epsd2", "cdt"))
    wall_friction: float = key(-1.0, "", "particle-wall friction; negative: the particle value")
    wall_cohesion: float = key(-1.0, "J/m^3", "particle-wall cohesion; negative: the particle value")
    rolling_stiffness_factor: float = key(2.25, "", "epsd rolling stiffness k_r = f k_n mu_r^2 R*^2",
                                          gt=0)
    capillary: bool = key(False, "", "Willett liquid bridges between particles")
    capillary_surface_tension: float = key(0.072, "N/m", "liquid surface tension", ge=0)
    capillary_contact_angle: float = key(0.3490658503988659, "rad", "liquid contact angle", ge=0,
                                         lt=0.5 * math.pi)
    capillary_film_thickness: float = key(0.0, "m", "liquid film; bridge volume 2 pi R*^2 t", ge=0)
    ageing: bool = key(False, "", "bonds grow at resting contacts")
    ageing_bond_ratio: float = key(0.0, "", "bond / SJKR force after the reference rest time", ge=0)
    ageing_time_constant: float = key(10.0, "s", "bond growth time constant", gt=0)
    ageing_reference_rest_time: float = key(60.0, "s", "rest time of ageing_bond_ratio", gt=0)
    ageing_break_slip: float = key(1e-6, "m", "tangential slip that breaks a bond", ge=0)


@dataclass(frozen=True)
class PSDSection:
    """Volume-weighted particle size distribution: laser diffraction percentiles, or its table."""

    d10: float = key(29.84e-6, "m", "D10 diameter", gt=0)
    d50: float = key(52.08e-6, "m", "D50 diameter", gt=0)
    d90: float = key(86.11e-6, "m", "D90 diameter", gt=0)
    d_min: float = key(28e-6, "m", "smallest diameter (truncation)", gt=0)
    d_max: float = key(100e-6, "m", "largest diameter (truncation)", gt=0)
    scale: float = key(1.0, "", "coarse-graining factor applied to every diameter", gt=0)
    diameters: tuple = key((), "m", "tabulated distribution: increasing diameters (at least 3; "
                           "replaces d10-d_max)", gt=0)
    volume_fractions: tuple = key((), "", "tabulated distribution: cumulative volume fraction "
                                  "undersize at each diameter", ge=0, le=1)
    fines_mass_fraction: float = key(0.0, "", "mass fraction of fines below the smallest diameter",
                                     ge=0, lt=1)
    fines_median_diameter: float = key(20e-6, "m", "volume-weighted median diameter of the fines", gt=0)
    fines_sigma_ln: float = key(0.25, "", "log-normal width of the fines", gt=0)
    fines_min_diameter: float = key(8e-6, "m", "smallest fine", gt=0)


@dataclass(frozen=True)
class TimeSection:
    """Time step."""

    safety: float = key(0.15, "", "time step as a fraction of the Rayleigh time", gt=0, le=MAX_SAFETY)
    v_max: float = key(1.0, "m/s", "largest impact speed: the step is at most a tenth of the Hertz time",
                       gt=0)


@dataclass(frozen=True)
class ReposeSection:
    """Angle-of-repose test: a box filled by raindrop insertion, a sliding bottom plate."""

    box: tuple = key((6e-3, 3e-3, 1.8e-3), "m", "box length, width and height", gt=0)
    periodic_width: bool = key(False, "", "periodic along y instead of side walls")
    n_particles: int = key(105000, "", "particles; 0: from fill_fraction at packing 0.6", ge=0)
    fill_fraction: float = key(0.5, "", "raindrop region height / box height", gt=0, le=1)
    pedestal_fraction: float = key(0.0, "", "fixed central ledge (fraction of the length)", ge=0, lt=1)
    slide_fraction: float = key(0.5, "", "how far the plate slides out (fraction of the length)",
                                gt=0, le=1)
    plate_speed: float = key(0.05, "m/s", "plate speed towards -x", gt=0)
    fill_time: float = key(0.02, "s", "settling after insertion", gt=0)
    drain_time: float = key(0.05, "s", "time after the plate has moved", ge=0)
    rest_time: float = key(0.0, "s", "rest before the plate moves (contacts age with contact.ageing)",
                           ge=0)
    reservoir_depth: float = key(10e-3, "m", "depth below the plate; particles leaving it are removed",
                                 gt=0)
    replicates: int = key(3, "", "independent piles", gt=0)
    n_frames: int = key(5, "", "frames written per replicate", ge=0)


@dataclass(frozen=True)
class SpreadSection:
    """Multi-layer spreading with a blade (rake), plate or roller."""

    tool: str = key("blade", "", "spreading tool (rake = blade)", choices=("blade", "rake", "plate", "roller"))
    plate_length: float = key(18.9e-3, "m", "build platform length along x", gt=0)
    chamber: bool = key(True, "", "front wall up to the tool level (platform in a chamber)")
    width: float = key(3e-3, "m", "width: the period along y, or the distance between the side walls",
                       gt=0)
    side_walls: bool = key(False, "", "plane walls at y = 0 and y = width instead of a periodic strip")
    gaps: tuple = key((508e-6, 508e-6, 102e-6, 127e-6), "m", "gap between tool and bed, one per layer",
                      gt=0)
    speed: float = key(0.0254, "m/s", "tool speed", gt=0)
    pile_particles: int = key(100000, "", "particles per pile", gt=0)
    pile_length: float = key(3e-3, "m", "footprint of the pile along x", gt=0)
    pile_time: float = key(0.02, "s", "settling of a generated pile", gt=0)
    lower_speed: float = key(0.02, "m/s", "platform lowering speed between layers", gt=0)
    settle_time: float = key(0.005, "s", "settling after each layer", gt=0)
    return_speed: float = key(0.5, "m/s", "tool return speed above the bed", gt=0)
    blade_thickness: float = key(0.5e-3, "m", "blade thickness", gt=0)
    bevel_deg: float = key(10.0, "deg", "blade bevel angle", ge=0, lt=90)
    blade_height: float = key(2e-3, "m", "blade height", gt=0)
    roller_radius: float = key(0.5e-3, "m", "roller radius", gt=0)
    roller_omega_factor: float = key(-1.0, "", "roller spin = factor * speed / radius: -1 counter-rotating, "
                                     "1 rolling, 0 none")
    stop_margin: float = key(0.5e-3, "m", "the tool stops this far beyond the platform end", ge=0)
    ramp_time: float = key(0.0, "s", "tool start-up: speed v (1 - exp(-t/tau))", ge=0)
    vibration_amplitude: float = key(0.0, "m", "vertical tool vibration amplitude", ge=0)
    vibration_frequency: float = key(0.0, "Hz", "vertical tool vibration frequency", ge=0)
    n_frames: int = key(10, "", "frames per layer (dynamic angle, dumps)", ge=1)
    regions: int = key(3, "", "regions along the platform", ge=1)


@dataclass(frozen=True)
class CalibrateSection:
    """Calibration of the cohesion energy density against an angle of repose."""

    target_deg: float = key(33.0, "deg", "angle of repose to reproduce", gt=0, lt=90)
    cohesion_bracket: tuple = key((3.0e7, 3.6e7), "J/m^3", "[low, high] cohesion search bracket", gt=0)
    replicates: int = key(2, "", "repose replicates per point", gt=0)
    max_iter: int = key(4, "", "largest number of search steps", ge=0)
    tolerance_deg: float = key(1.0, "deg", "stop within this angle of the target", gt=0, lt=90)


@dataclass(frozen=True)
class ExternalSection:
    """LIGGGHTS and LAMMPS runs (``engine = "liggghts"`` or ``"lammps"``)."""

    np: int = key(1, "", "MPI ranks", ge=1)
    exe: str = key("", "", "engine binary (empty: the one found on this machine)")
    write_only: bool = key(False, "", "write decks and inputs, do not run")
    cohesion_model: str = key("dmt", "", "LAMMPS stand-in for SJKR (none drops cohesion)",
                              choices=("dmt", "jkr", "none"))
    timeout: float = key(0.0, "s", "limit per engine run (0: none)", ge=0)


@dataclass(frozen=True)
class OutputSection:
    """What a run writes."""

    frames: bool = key(True, "", "write particle dumps")
    contacts: bool = key(True, "", "write contact dumps")
    compress: bool = key(True, "", "gzip the dumps")
    checkpoint: bool = key(False, "", "keep an engine checkpoint of every finished stage")
    checkpoint_every: int = key(20000, "steps", "steps between resume checkpoints inside a stage "
                                "(0: at stage ends only)", ge=0)


@dataclass(frozen=True)
class WorkflowConfig:
    """A complete workflow configuration (SI units), read-only."""

    preset: str = key("", "", "base preset: tiny, small or seed")
    description: str = key("", "", "free text")
    engine: str = key("embedded", "", "DEM engine", choices=("embedded", "liggghts", "lammps"))
    seed: int = key(1, "", "random seed", ge=0)
    n_threads: int = key(1, "", "threads of the embedded engine", ge=1)
    material: MaterialSection = field(default_factory=MaterialSection)
    contact: ContactSection = field(default_factory=ContactSection)
    psd: PSDSection = field(default_factory=PSDSection)
    time: TimeSection = field(default_factory=TimeSection)
    repose: ReposeSection = field(default_factory=ReposeSection)
    spread: SpreadSection = field(default_factory=SpreadSection)
    calibrate: CalibrateSection = field(default_factory=CalibrateSection)
    external: ExternalSection = field(default_factory=ExternalSection)
    output: OutputSection = field(default_factory=OutputSection)


#: Section name -> its dataclass, in configuration order.
SECTIONS = {f.name: f.default_factory for f in fields(WorkflowConfig) if f.default is MISSING}


def _plain_default(value):
    return list(value) if isinstance(value, tuple) else value


def defaults_dict() -> dict:
    """The default configuration as the nested dict :func:`load_config` starts from.

    Examples
    --------
    >>> from bedstruct.workflows.schema import defaults_dict
    >>> d = defaults_dict()
    >>> d["contact"]["friction"], d["spread"]["gaps"][:2]
    (0.4, [0.000508, 0.000508])
    """
    out = {}
    for f in fields(WorkflowConfig):
        if f.name in SECTIONS:
            out[f.name] = {g.name: _plain_default(g.default) for g in fields(SECTIONS[f.name])}
        else:
            out[f.name] = f.default
    return out


def typed_config(cfg: dict) -> WorkflowConfig:
    """A loaded configuration as a frozen :class:`WorkflowConfig` (lists become tuples).

    Examples
    --------
    >>> from bedstruct.workflows import load_config
    >>> from bedstruct.workflows.schema import typed_config
    >>> c = typed_config(load_config(preset="tiny"))
    >>> c.spread.tool, c.psd.scale
    ('blade', 2.0)
    """
    top = {}
    for f in fields(WorkflowConfig):
        if f.name not in cfg:
            continue
        v = cfg[f.name]
        if f.name in SECTIONS:
            v = SECTIONS[f.name](**{k: tuple(x) if isinstance(x, list) else x for k, x in v.items()})
        top[f.name] = v
    return WorkflowConfig(**top)


def config_dict(cfg: WorkflowConfig) -> dict:
    """A :class:`WorkflowConfig` as the nested dict :func:`load_config` returns (tuples become
    lists): what the run folder's ``config.toml`` and the engines' effect checks read.

    The inverse of :func:`typed_config`.

    Examples
    --------
    >>> from bedstruct.workflows import load_config
    >>> from bedstruct.workflows.schema import config_dict, typed_config
    >>> cfg = load_config(preset="tiny")
    >>> config_dict(typed_config(cfg)) == cfg
    True
    """
    if not isinstance(cfg, WorkflowConfig):
        raise TypeError(f"config_dict: expected a WorkflowConfig; got {type(cfg).__name__}")
    out = {}
    for f in fields(WorkflowConfig):
        v = getattr(cfg, f.name)
        if f.name in SECTIONS:
            v = {g.name: _plain_default(getattr(v, g.name)) for g in fields(SECTIONS[f.name])}
        out[f.name] = v
    return out


def psd_table(p: dict):
    """The tabulated size distribution of a ``psd`` section, checked: ``(diameters, F)``
    arrays (m, cumulative volume fraction undersize), or None when none is given.

    Raises
    ------
    ConfigError
        Naming ``psd.diameters`` or ``psd.volume_fractions`` and what is expected.

    Examples
    --------
    >>> from bedstruct.workflows.schema import psd_table
    >>> psd_table({"diameters": [], "volume_fractions": []}) is None
    True
    >>> psd_table({"diameters": [2e-5, 4e-5], "volume_fractions": [0.0, 1.0]})
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: config key `psd.diameters` must list at least 3 diameters (m) of the tabulated distribution; got 2
    """
    d_raw, f_raw = p.get("diameters"), p.get("volume_fractions")
    d_raw = () if d_raw is None else d_raw
    f_raw = () if f_raw is None else f_raw
    if not len(d_raw) and not len(f_raw):
        return None
    d = np.asarray(d_raw, dtype=np.float64)
    f = np.asarray(f_raw, dtype=np.float64)
    if d.ndim != 1 or d.size < 3:
        raise ConfigError("config key `psd.diameters` must list at least 3 diameters (m) of the "
                          f"tabulated distribution; got {d.size}")
    if not (np.all(np.isfinite(d)) and d[0] > 0 and np.all(np.diff(d) > 0)):
        raise ConfigError("config key `psd.diameters` must hold positive diameters (m) in "
                          f"increasing order; got {[float(x) for x in d_raw]!r}")
    if f.shape != d.shape:
        raise ConfigError("config key `psd.volume_fractions` must give one cumulative volume "
                          f"fraction per diameter of `psd.diameters` ({d.size}); got {f.size}")
    if not (np.all(np.isfinite(f)) and np.all((f >= 0) & (f <= 1))
            and np.all(np.diff(f) >= 0) and f[-1] > f[0]):
        raise ConfigError("config key `psd.volume_fractions` must hold the cumulative volume "
                          "fraction undersize at each diameter: within [0, 1], not decreasing, "
                          f"the last above the first; got {[float(x) for x in f_raw]!r}")
    below, above = float(f[0]), 1.0 - float(f[-1])
    if below > PSD_END_MAX_MISSING or above > PSD_END_MAX_MISSING:
        raise ConfigError("config key `psd.volume_fractions` must cover the distribution: "
                          f"{below:.3g} of the volume lies below the first of `psd.diameters` "
                          f"and {above:.3g} above the last (at most {PSD_END_MAX_MISSING:g} "
                          "each; the draws are renormalised to the table's range, so the "
                          "missing volume would shift every percentile). Give the cumulative "
                          "fraction undersize (0 to 1) and the diameters where it reaches 0 "
                          f"and 1; got {[float(x) for x in f_raw]!r}")
    return d, f


def _bound_text(meta) -> str:
    if meta["choices"]:
        return "one of " + ", ".join(meta["choices"])
    lo = ("> " + f"{meta['gt']:g}") if meta["gt"] is not None else (
        (">= " + f"{meta['ge']:g}") if meta["ge"] is not None else None)
    hi = ("< " + f"{meta['lt']:g}") if meta["lt"] is not None else (
        ("<= " + f"{meta['le']:g}") if meta["le"] is not None else None)
    parts = [p for p in (lo, hi) if p]
    return " and ".join(parts)


def _in_bounds(x, meta) -> bool:
    return ((meta["gt"] is None or x > meta["gt"]) and (meta["ge"] is None or x >= meta["ge"])
            and (meta["lt"] is None or x < meta["lt"]) and (meta["le"] is None or x <= meta["le"]))


def check_bounds(cfg: dict) -> None:
    """Check every value of ``cfg`` against the bounds and choices of its field.

    Raises
    ------
    ConfigError
        Naming the first key out of bounds, its bounds with the unit, and the value.

    Examples
    --------
    >>> from bedstruct.workflows import load_config
    >>> from bedstruct.workflows.schema import check_bounds
    >>> cfg = load_config(preset="tiny")
    >>> cfg["contact"]["friction"] = -0.1
    >>> check_bounds(cfg)
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: config key `contact.friction` must be >= 0 (sliding friction coefficient); got -0.1
    """
    def check(name, f, value):
        meta = f.metadata
        if meta["choices"]:
            if value not in meta["choices"]:
                raise ConfigError(f"config key `{name}` must be {_bound_text(meta)}; got {value!r}")
            return
        if not any(meta[b] is not None for b in ("gt", "ge", "lt", "le")):
            return
        values = value if isinstance(value, (list, tuple)) else [value]
        if not all(_in_bounds(x, meta) for x in values):
            unit = f" {meta['unit']}" if meta["unit"] else ""
            what = "positive" if meta["gt"] == 0 and meta["lt"] is None and meta["le"] is None \
                else _bound_text(meta) + unit
            raise ConfigError(f"config key `{name}` must be {what} ({meta['doc']}); got {value!r}")

    for f in fields(WorkflowConfig):
        if f.name not in cfg:
            continue
        if f.name in SECTIONS:
            for g in fields(SECTIONS[f.name]):
                if g.name in cfg[f.name]:
                    check(f"{f.name}.{g.name}", g, cfg[f.name][g.name])
        else:
            check(f.name, f, cfg[f.name])


def _default_text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "[" + ", ".join(f"{x:g}" for x in value) + "]"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def config_reference(sections=None, *, markdown: bool = False) -> str:
    """The configuration keys with their defaults, units, meaning and bounds.

    Parameters
    ----------
    sections : sequence of str, optional
        Section names (``"spread"``, ...; ``""`` for the top-level keys); all by default.
    markdown : bool, optional
        A Markdown table per section (the docs' reference) instead of plain text
        (``bedstruct run WORKFLOW --help-config``).

    Examples
    --------
    >>> from bedstruct.workflows.schema import config_reference
    >>> print(config_reference(["time"]))
    [time] Time step.
      safety                      0.15             time step as a fraction of the Rayleigh time (> 0 and <= 0.3)
      v_max                       1 m/s            largest impact speed: the step is at most a tenth of the Hertz time (> 0)
    """
    wanted = list(SECTIONS) if sections is None else list(sections)
    out = []
    for name in wanted:
        if name == "":
            rows = [f for f in fields(WorkflowConfig) if f.name not in SECTIONS]
            title = "top-level keys"
        else:
            cls = SECTIONS[name]
            rows = list(fields(cls))
            title = f"[{name}] {cls.__doc__.strip()}"
        if markdown:
            out.append(f"### `{name or 'top level'}`\n")
            if name:
                out.append(SECTIONS[name].__doc__.strip() + "\n")
            out.append("| key | default | unit | meaning | allowed |")
            out.append("|---|---|---|---|---|")
            for f in rows:
                m = f.metadata
                out.append(f"| `{f.name}` | `{_default_text(f.default)}` | {m['unit']} | "
                           f"{m['doc']} | {_bound_text(m)} |")
            out.append("")
        else:
            out.append(title)
            for f in rows:
                m = f.metadata
                bounds = _bound_text(m)
                value = f"{_default_text(f.default)} {m['unit']}".rstrip()
                line = f"  {f.name:<27} {value:<16} {m['doc']}" + (f" ({bounds})" if bounds else "")
                out.append(line.rstrip())
    return "\n".join(out).rstrip() + "\n" if markdown else "\n".join(out)

