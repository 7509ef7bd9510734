"""Workflow configuration: TOML files, presets, defaults and ``key=value`` overrides.

A configuration is a nested mapping of sections (``material``, ``contact``,
``psd``, ``repose``, ``spread``, ``calibrate``, ``external``, ``effects``, ``output``) to scalar or list
values, all in SI units. :func:`load_config` starts from :data:`DEFAULTS`,
applies a preset (``tiny``, ``small``, ``seed``; files in
``bedstruct/workflows/presets``), then a user TOML file, then ``--set``
overrides. Every key is type checked against the defaults; an unknown key or
a value of the wrong type raises :class:`~bedstruct.errors.ConfigError`
naming the key.
"""

from __future__ import annotations

import copy
import difflib
import math
import tomllib
from pathlib import Path

from ..errors import ConfigError

__all__ = ["DEFAULTS", "PRESETS", "load_config", "apply_override", "preset_path", "config_to_toml",
           "available_presets", "validate_config"]

#: Largest ``time.safety``: the engine refuses a step above this fraction of the Rayleigh
#: time (``Simulation(max_rayleigh_fraction=0.3)``, LIGGGHTS' check/timestep/gran advice).
MAX_SAFETY = 0.3

#: Default configuration (SI units). Presets and user files override it.
DEFAULTS: dict = {
    "preset": "",
    "description": "",
    "engine": "embedded",
    "seed": 1,
    "n_threads": 1,
    "material": {
        "youngs_modulus": 1e7,      # Pa (softened; CoCr is ~2.1e11)
        "poisson_ratio": 0.3,
        "density": 8300.0,          # kg/m^3, CoCr
    },
    "contact": {
        "restitution": 0.1,
        "friction": 0.4,
        "rolling_friction": 0.05,
        "cohesion": 0.0,            # SJKR energy density k, J/m^3
        "rolling_model": "epsd2",
        "wall_friction": -1.0,      # < 0: same as particle-particle
        "wall_cohesion": -1.0,      # < 0: same as particle-particle
    },
    "psd": {                        # volume-weighted diameters (laser diffraction), m
        "d10": 29.84e-6,
        "d50": 52.08e-6,
        "d90": 86.11e-6,
        "d_min": 28e-6,
        "d_max": 100e-6,
        "scale": 1.0,               # coarse-graining factor applied to every diameter
    },
    "time": {
        "safety": 0.15,             # fraction of the Rayleigh time, (0, 0.3]
        "v_max": 1.0,               # m/s (> 0), largest impact speed: dt <= Hertz time / 10
    },
    "repose": {
        "box": [6e-3, 3e-3, 1.8e-3],    # L x W x H, m
        "periodic_width": False,        # y periodic instead of side walls
        "n_particles": 105000,          # 0: from fill_fraction at packing 0.6
        "fill_fraction": 0.5,           # raindrop region height / box height
        "pedestal_fraction": 0.0,       # fixed central ledge (fraction of L); 0: plate slides partly
        "slide_fraction": 0.5,          # how far the plate slides out (fraction of L)
        "plate_speed": 0.05,            # m/s, plate slides towards -x
        "fill_time": 0.02,              # s, settling after insertion
        "drain_time": 0.05,             # s, after the plate has moved
        "rest_time": 0.0,               # s, rest before the plate moves (contacts age, with
                                        #    effects.contact_ageing; a static pile is otherwise unchanged)
        "reservoir_depth": 10e-3,       # m below the plate; particles leaving it are removed
        "replicates": 3,
        "n_frames": 5,                  # frames written per replicate
    },
    "spread": {
        "tool": "blade",                # blade (= rake) | plate | roller
        "plate_length": 18.9e-3,        # m, build platform along x
        "chamber": True,                # front wall up to the tool level (platform in a chamber)
        "width": 3e-3,                  # m, periodic along y
        "gaps": [508e-6, 508e-6, 102e-6, 127e-6],
        "speed": 0.0254,                # m/s
        "pile_particles": 100000,
        "pile_length": 3e-3,            # m, footprint of the pile along x
        "pile_time": 0.02,              # s, settling of the pile when generated
        "lower_speed": 0.02,            # m/s, platform lowering between layers
        "settle_time": 0.005,           # s, after each layer
        "return_speed": 0.5,            # m/s, tool return above the bed
        "blade_thickness": 0.5e-3,
        "bevel_deg": 10.0,
        "blade_height": 2e-3,
        "roller_radius": 0.5e-3,
        "roller_omega_factor": -1.0,    # spin about +y = factor * speed / radius:
                                        # -1 counter-rotating, 1 rolling, 0 none
        "stop_margin": 0.5e-3,          # m, the tool stops this far beyond the platform end
        "n_frames": 10,                 # frames per layer (dynamic angle, dumps)
        "regions": 3,
    },
    "calibrate": {
        "target_deg": 33.0,
        "cohesion_bracket": [3.0e7, 3.6e7],
        "replicates": 2,
        "max_iter": 4,
        "tolerance_deg": 1.0,
    },
    "external": {                   # --engine liggghts|lammps (bedstruct.workflows.external)
        "np": 1,                    # MPI ranks
        "exe": "",                  # engine binary ("": the one found on this machine)
        "write_only": False,        # write decks and inputs, do not run
        "cohesion_model": "dmt",    # LAMMPS stand-in for SJKR: dmt | jkr | none (drop cohesion)
        "timeout": 0.0,             # s per engine run (0: none)
    },
    "effects": {                    # diagnosis extensions (bedstruct.diagnose catalogue
                                    # engine_map names); the defaults are the base model
        "capillary": False,         # Willett liquid bridges between particles
        "capillary_surface_tension": 0.072,     # N/m
        "capillary_contact_angle": 0.3490658503988659,  # rad (20 deg)
        "capillary_film_thickness": 0.0,        # m; bridge volume 2 pi R*^2 t
        "contact_ageing": False,    # bonds at resting contacts
        "ageing_bond_ratio": 0.0,   # bond / SJKR force after the reference rest time
        "ageing_time_constant": 10.0,           # s
        "ageing_reference_rest_time": 60.0,     # s
        "ageing_break_slip": 1e-6,  # m of tangential slip that breaks a bond
        "rolling_model": "epsd",    # rolling model carrying shape_rolling_friction (if > 0)
        "shape_rolling_friction": 0.0,          # added to contact.rolling_friction
        "rolling_stiffness_factor": 2.25,       # epsd k_r = f k_n mu_r^2 R*^2
        "fines_mass_fraction": 0.0, # mass fraction of fines below psd.d_min
        "fines_median_diameter": 20e-6,         # m, volume-weighted median of the fines
        "fines_sigma_ln": 0.25,
        "fines_min_diameter": 8e-6, # m
        "wall_friction_excess": 0.0,            # wall friction = particle friction + excess
        "blade_ramp_time": 0.0,     # s, tool speed v (1 - exp(-t/tau))
        "blade_vibration_amplitude": 0.0,       # m, vertical tool vibration
        "blade_vibration_frequency": 0.0,       # Hz
    },
    "output": {
        "frames": True,
        "contacts": True,
        "compress": True,
        "checkpoint": False,        # keep an engine checkpoint of every finished stage
        "checkpoint_every": 20000,  # steps between resume checkpoints inside a stage (0: only
                                    # at stage ends: spreading layers)
    },
}

#: Names of the bundled presets.
PRESETS = ("tiny", "small", "seed")

_PRESET_DIR = Path(__file__).with_name("presets")


def available_presets() -> list[str]:
    """Names of the presets shipped in ``bedstruct/workflows/presets``.

    Examples
    --------
    >>> available_presets()
    ['seed', 'small', 'tiny']
    """
    return sorted(p.stem for p in _PRESET_DIR.glob("*.toml"))


def preset_path(name: str) -> Path:
    """Path of the preset file ``name`` (``tiny``, ``small``, ``seed``)."""
    p = _PRESET_DIR / f"{name}.toml"
    if not p.is_file():
        raise ConfigError(f"unknown preset {name!r}; available: {', '.join(available_presets())}")
    return p


def _read_toml(path) -> dict:
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None


def _type_name(v) -> str:
    if isinstance(v, bool):
        return "bool"
    if isinstance(v, int):
        return "int"
    if isinstance(v, float):
        return "float"
    if isinstance(v, str):
        return "str"
    if isinstance(v, list):
        return "list"
    if isinstance(v, dict):
        return "table"
    return type(v).__name__


def _check_value(key: str, default, value):
    """Return ``value`` converted to the type of ``default`` or raise ConfigError naming ``key``."""
    if isinstance(default, bool):
        if isinstance(value, bool):
            return value
    elif isinstance(default, int):
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        if isinstance(value, float) and value.is_integer():
            return int(value)
    elif isinstance(default, float):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            v = float(value)
            if not math.isfinite(v):
                raise ConfigError(f"config key `{key}` must be a finite number; got {value!r}")
            return v
    elif isinstance(default, str):
        if isinstance(value, str):
            return value
    elif isinstance(default, list):
        if isinstance(value, (list, tuple)) and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
            return [float(x) for x in value]
        raise ConfigError(f"config key `{key}` must be a list of numbers; got {value!r}")
    raise ConfigError(f"config key `{key}` must be of type {_type_name(default)}; "
                      f"got {_type_name(value)} {value!r}")


def _merge(base: dict, new: dict, prefix: str = "") -> None:
    for k, v in new.items():
        key = f"{prefix}{k}"
        if k not in base:
            close = difflib.get_close_matches(k, list(base), n=3)
            hint = f" (did you mean {', '.join(close)}?)" if close else ""
            raise ConfigError(f"unknown config key `{key}`{hint}")
        if isinstance(base[k], dict):
            if not isinstance(v, dict):
                raise ConfigError(f"config key `{key}` must be a table (section); got {v!r}")
            _merge(base[k], v, prefix=f"{key}.")
        else:
            base[k] = _check_value(key, base[k], v)


def _parse_value(text: str):
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # a bare string


def apply_override(config: dict, assignment: str) -> dict:
    """Apply one ``section.key=value`` override (value in TOML syntax) in place.

    Parameters
    ----------
    config : dict
        A configuration from :func:`load_config`.
    assignment : str
        ``"spread.speed=0.05"``, ``"spread.gaps=[1e-4, 2e-4]"``,
        ``"spread.tool=roller"`` (bare words are strings).

    Returns
    -------
    dict
        ``config``, modified.

    Raises
    ------
    ConfigError
        Unknown key, or a value of the wrong type (the message names the key).

    Examples
    --------
    >>> cfg = load_config(preset="tiny")
    >>> apply_override(cfg, "spread.speed=0.1")["spread"]["speed"]
    0.1
    >>> apply_override(cfg, "spread.speed=fast")
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: config key `spread.speed` must be of type float; got str 'fast'
    """
    if "=" not in assignment:
        raise ConfigError(f"override must look like section.key=value; got {assignment!r}")
    key, text = assignment.split("=", 1)
    key = key.strip()
    parts = key.split(".")
    node = {}
    leaf = node
    for p in parts[:-1]:
        leaf[p] = {}
        leaf = leaf[p]
    leaf[parts[-1]] = _parse_value(text.strip())
    _merge(config, node)
    return config


def load_config(source=None, *, preset: str | None = None, overrides=()) -> dict:
    """Build a complete workflow configuration.

    Parameters
    ----------
    source : path or dict, optional
        A TOML file (or an already-parsed mapping). It may name a base
        preset with a top-level ``preset = "small"``.
    preset : str, optional
        Base preset (``tiny``, ``small``, ``seed``); overrides the file's
        ``preset`` key.
    overrides : sequence of str
        ``section.key=value`` assignments applied last (see
        :func:`apply_override`).

    Returns
    -------
    dict
        Defaults, then the preset, then the file, then the overrides, all
        type checked. SI units.

    Raises
    ------
    ConfigError
        Unknown preset or key, wrong value type, unreadable TOML.

    Examples
    --------
    >>> cfg = load_config(preset="tiny", overrides=["contact.cohesion=2e4"])
    >>> cfg["preset"], cfg["contact"]["cohesion"]
    ('tiny', 20000.0)
    >>> load_config(preset="tiny", overrides=["spread.sped=1"])
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: unknown config key `spread.sped` (did you mean speed?)
    """
    cfg = copy.deepcopy(DEFAULTS)
    user = {}
    if source is not None:
        user = copy.deepcopy(dict(source)) if isinstance(source, dict) else _read_toml(source)
    name = preset or user.get("preset") or None
    if name:
        if not isinstance(name, str):
            raise ConfigError(f"config key `preset` must be a string; got {name!r}")
        _merge(cfg, _read_toml(preset_path(name)))
        cfg["preset"] = name
    _merge(cfg, user)
    if name:
        cfg["preset"] = name
    for a in overrides or ():
        apply_override(cfg, a)
    _validate(cfg)
    return cfg


def validate_config(cfg: dict) -> None:
    """Check the values of a configuration (types are checked by :func:`load_config`).

    Called by :func:`load_config` and again by the workflows before any simulation (a
    configuration may be changed after loading).

    Raises
    ------
    ConfigError
        Naming the first key whose value is out of range, and the range.

    Examples
    --------
    >>> cfg = load_config(preset="tiny")
    >>> cfg["spread"]["gaps"] = []
    >>> validate_config(cfg)
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: config key `spread.gaps` must list at least one layer gap (m); got []
    """
    _validate(cfg)


def _validate(cfg: dict) -> None:
    def get(key):
        node = cfg
        for part in key.split("."):
            node = node[part]
        return node

    def positive(key):
        v = get(key)
        vals = v if isinstance(v, list) else [v]
        if not all(x > 0 for x in vals):
            raise ConfigError(f"config key `{key}` must be positive; got {v!r}")

    def at_least(key, low, what=""):
        v = get(key)
        if not v >= low:
            raise ConfigError(f"config key `{key}` must be >= {low}{what}; got {v!r}")

    for key in ("material.youngs_modulus", "material.density", "psd.d10", "psd.d50", "psd.d90",
                "psd.d_min", "psd.d_max", "psd.scale", "repose.box",
                "repose.plate_speed", "repose.replicates", "repose.fill_time",
                "repose.reservoir_depth", "spread.plate_length", "spread.width",
                "spread.gaps", "spread.speed", "spread.pile_particles", "spread.pile_length",
                "spread.pile_time", "spread.lower_speed", "spread.return_speed",
                "spread.settle_time", "spread.blade_thickness", "spread.blade_height",
                "spread.roller_radius", "calibrate.replicates", "calibrate.cohesion_bracket",
                "calibrate.tolerance_deg"):
        positive(key)
    at_least("n_threads", 1, " (threads)")
    at_least("seed", 0)
    at_least("repose.drain_time", 0.0, " s")
    at_least("repose.n_frames", 0)
    at_least("spread.n_frames", 1, " (frames recorded per layer)")
    at_least("spread.regions", 1, " (regions along the platform)")
    at_least("spread.stop_margin", 0.0, " m (how far beyond the platform end the tool stops)")
    at_least("calibrate.max_iter", 0)
    if "checkpoint_every" in cfg["output"]:  # a configuration built before the key existed
        at_least("output.checkpoint_every", 0, " steps (0: checkpoints at stage ends only)")
    if not cfg["spread"]["gaps"]:
        raise ConfigError("config key `spread.gaps` must list at least one layer gap (m); got []")
    if not 0 <= cfg["spread"]["bevel_deg"] < 90:
        raise ConfigError("config key `spread.bevel_deg` must lie in [0, 90) degrees; "
                          f"got {cfg['spread']['bevel_deg']!r}")
    t = cfg["time"]
    if not 0 < t["safety"] <= MAX_SAFETY:
        raise ConfigError(f"config key `time.safety` must lie in (0, {MAX_SAFETY}]: the time "
                          "step is this fraction of the Rayleigh time of the smallest sphere, "
                          f"and above {MAX_SAFETY} the contacts are not resolved (the run blows "
                          f"up); got {t['safety']!r}")
    if not t["v_max"] > 0:
        raise ConfigError("config key `time.v_max` must be a positive speed (m/s): the largest "
                          "expected impact speed, which bounds the time step by the Hertz "
                          f"contact time; got {t['v_max']!r}")
    r = cfg["repose"]
    if not 0 < r["slide_fraction"] <= 1:
        raise ConfigError(f"config key `repose.slide_fraction` must lie in (0, 1]; "
                          f"got {r['slide_fraction']!r}")
    if not 0 <= r["pedestal_fraction"] < 1:
        raise ConfigError(f"config key `repose.pedestal_fraction` must lie in [0, 1); "
                          f"got {r['pedestal_fraction']!r}")
    p = cfg["psd"]
    if not p["d_min"] < p["d10"] < p["d50"] < p["d90"] < p["d_max"]:
        raise ConfigError("config keys `psd.d_min < psd.d10 < psd.d50 < psd.d90 < psd.d_max` must "
                          f"increase; got {p['d_min']}, {p['d10']}, {p['d50']}, {p['d90']}, {p['d_max']}")
    if len(cfg["repose"]["box"]) != 3:
        raise ConfigError(f"config key `repose.box` must be [L, W, H]; got {cfg['repose']['box']!r}")
    rest = cfg["repose"]["rest_time"]
    if not (math.isfinite(rest) and rest >= 0):
        raise ConfigError(f"config key `repose.rest_time` must be >= 0 s; got {rest!r}")
    if not 0 < cfg["repose"]["fill_fraction"] <= 1:
        raise ConfigError("config key `repose.fill_fraction` must lie in (0, 1]")
    if cfg["spread"]["tool"] not in ("blade", "rake", "plate", "roller"):
        raise ConfigError(f"config key `spread.tool` must be blade, rake, plate or roller; "
                          f"got {cfg['spread']['tool']!r}")
    if cfg["engine"] not in ("embedded", "liggghts", "lammps"):
        raise ConfigError(f"config key `engine` must be embedded, liggghts or lammps; "
                          f"got {cfg['engine']!r}")
    ext = cfg["external"]
    if ext["np"] < 1:
        raise ConfigError(f"config key `external.np` must be >= 1; got {ext['np']}")
    if ext["cohesion_model"] not in ("dmt", "jkr", "none"):
        raise ConfigError("config key `external.cohesion_model` must be dmt, jkr or none; "
                          f"got {ext['cohesion_model']!r}")
    at_least("external.timeout", 0.0, " s (0: none)")
    _validate_effects(cfg["effects"])
    b = cfg["calibrate"]["cohesion_bracket"]
    if len(b) != 2 or not b[0] < b[1]:
        raise ConfigError(f"config key `calibrate.cohesion_bracket` must be [low, high] with "
                          f"low < high; got {b!r}")


def _validate_effects(fx: dict) -> None:
    for key in ("capillary_surface_tension", "capillary_film_thickness", "ageing_bond_ratio",
                "ageing_break_slip", "shape_rolling_friction", "fines_mass_fraction",
                "blade_ramp_time", "blade_vibration_amplitude", "blade_vibration_frequency"):
        if fx[key] < 0:
            raise ConfigError(f"config key `effects.{key}` must be >= 0; got {fx[key]!r}")
    for key in ("ageing_time_constant", "ageing_reference_rest_time", "rolling_stiffness_factor",
                "fines_median_diameter", "fines_sigma_ln", "fines_min_diameter"):
        if not fx[key] > 0:
            raise ConfigError(f"config key `effects.{key}` must be positive; got {fx[key]!r}")
    if not 0 <= fx["capillary_contact_angle"] < 0.5 * math.pi:
        raise ConfigError("config key `effects.capillary_contact_angle` must lie in [0, pi/2) rad; "
                          f"got {fx['capillary_contact_angle']!r}")
    if fx["fines_mass_fraction"] >= 1:
        raise ConfigError("config key `effects.fines_mass_fraction` must lie in [0, 1); "
                          f"got {fx['fines_mass_fraction']!r}")
    if fx["capillary"] and fx["capillary_film_thickness"] <= 0:
        raise ConfigError("config key `effects.capillary_film_thickness` must be positive when "
                          "`effects.capillary` is true")
    if fx["rolling_model"] not in ("epsd", "epsd2", "cdt"):
        raise ConfigError("config key `effects.rolling_model` must be epsd, epsd2 or cdt; "
                          f"got {fx['rolling_model']!r}")


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else "nan"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise ConfigError(f"cannot write {type(v).__name__} to TOML")


def config_to_toml(cfg: dict) -> str:
    """TOML text of a configuration (round-trips through :func:`load_config`).

    Examples
    --------
    >>> cfg = load_config(preset="tiny")
    >>> load_config(tomllib.loads(config_to_toml(cfg))) == cfg
    True
    """
    top = [f"{k} = {_toml_value(v)}" for k, v in cfg.items() if not isinstance(v, dict)]
    out = ["# bedstruct workflow configuration (SI units)"] + top
    for k, v in cfg.items():
        if isinstance(v, dict):
            out.append(f"\n[{k}]")
            out += [f"{kk} = {_toml_value(vv)}" for kk, vv in v.items()]
    return "\n".join(out) + "\n"
