"""Workflow configuration: TOML files, presets, defaults and ``key=value`` overrides.

A configuration is a nested mapping of sections (``material``, ``contact``,
``psd``, ``time``, ``repose``, ``spread``, ``calibrate``, ``external``, ``output``) to scalar or list
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
import logging
import math
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path

from ..errors import ConfigError
from .schema import (MAX_SAFETY, WorkflowConfig, check_bounds, config_dict, defaults_dict, psd_table,
                     typed_config)

__all__ = ["DEFAULTS", "PRESETS", "load_config", "apply_override", "preset_path", "config_to_toml",
           "available_presets", "validate_config", "workflow_config", "check_run_geometry"]

#: Default configuration (SI units), from the section dataclasses of
#: :mod:`bedstruct.workflows.schema`. Presets and user files override it.
DEFAULTS: dict = defaults_dict()

#: Where each key of the ``[effects]`` section lives: the section is refused (by
#: :func:`load_config`), naming these options, and nothing is translated.
_MOVED_EFFECT_KEYS = {
    "capillary": "contact.capillary",
    "capillary_surface_tension": "contact.capillary_surface_tension",
    "capillary_contact_angle": "contact.capillary_contact_angle",
    "capillary_film_thickness": "contact.capillary_film_thickness",
    "contact_ageing": "contact.ageing",
    "ageing_bond_ratio": "contact.ageing_bond_ratio",
    "ageing_time_constant": "contact.ageing_time_constant",
    "ageing_reference_rest_time": "contact.ageing_reference_rest_time",
    "ageing_break_slip": "contact.ageing_break_slip",
    "rolling_model": "contact.rolling_model",
    "shape_rolling_friction": "contact.rolling_friction (the whole coefficient, shape included)",
    "rolling_stiffness_factor": "contact.rolling_stiffness_factor",
    "fines_mass_fraction": "psd.fines_mass_fraction",
    "fines_median_diameter": "psd.fines_median_diameter",
    "fines_sigma_ln": "psd.fines_sigma_ln",
    "fines_min_diameter": "psd.fines_min_diameter",
    "wall_friction_excess": "contact.wall_friction (the particle-wall friction itself, "
                            "not its excess over contact.friction)",
    "blade_ramp_time": "spread.ramp_time",
    "blade_vibration_amplitude": "spread.vibration_amplitude",
    "blade_vibration_frequency": "spread.vibration_frequency",
}

log = logging.getLogger(__name__)

#: A tabulated size distribution that leaves out more than this volume fraction at an end
#: (and at most ``schema.PSD_END_MAX_MISSING``) is loaded with a logged warning.
_PSD_CUT_QUIET = 1e-3

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
        raise ConfigError(f"{path}: not valid TOML: {exc} (values are plain numbers in SI "
                          f"units, e.g. speed = 0.05)") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a UTF-8 text file (byte {exc.object[exc.start]:#x} at "
                          f"position {exc.start}); a configuration is TOML text") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a folder; expected a configuration file (TOML)") from None
    except FileNotFoundError:
        raise ConfigError(f"configuration file not found: {path}") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot be read: {exc.strerror}") from None


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


def _refuse_effects_section(new: dict) -> None:
    """Refuse an ``[effects]`` section, naming the option of each of its keys."""
    if "effects" not in new:
        return
    fx = new["effects"]
    keys = list(fx) if isinstance(fx, dict) and fx else list(_MOVED_EFFECT_KEYS)
    rows = "; ".join(f"effects.{k} -> {_MOVED_EFFECT_KEYS.get(k, 'no such option')}" for k in keys)
    raise ConfigError("config section `effects` does not exist: the effects are options of the "
                      f"section where their physics lives; set them there ({rows})")


def _merge(base: dict, new: dict, prefix: str = "") -> None:
    if not prefix:
        _refuse_effects_section(new)
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
        Unknown key, a value of the wrong type (the message names the key), or the key
        ``preset`` (a preset is chosen with ``load_config(preset=...)``, ``--preset``).

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
    if key == "preset":
        raise ConfigError("the preset cannot be set by an override (it would only change the "
                          "label, not the values): choose it with --preset NAME, or with "
                          '`preset = "NAME"` in the configuration file')
    parts = key.split(".")
    node = {}
    leaf = node
    for p in parts[:-1]:
        leaf[p] = {}
        leaf = leaf[p]
    leaf[parts[-1]] = _parse_value(text.strip())
    _merge(config, node)
    return config


def load_config(source=None, *, preset: str | None = None, overrides=(),
                workflow: str | None = None) -> dict:
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
    workflow : {"repose", "calibrate", "spread"}, optional
        The workflow the configuration is for: its lengths are checked against the
        particle sizes (a repose run is not refused over ``spread.gaps``). Default: every
        workflow's. A run checks its own sections again before it writes anything
        (:func:`check_run_geometry`).

    Returns
    -------
    dict
        Defaults, then the preset, then the file, then the overrides, all
        type checked. SI units.

    Raises
    ------
    ConfigError
        Unknown preset or key, wrong value type, a value out of range or inconsistent
        with another (a layer gap thinner than the smallest particle, a box narrower
        than a few particles...), unreadable TOML. The message names the key and
        where its value came from: the file, ``preset NAME (path)`` or ``--set KEY=VALUE``.

    Examples
    --------
    >>> cfg = load_config(preset="tiny", overrides=["contact.cohesion=2e4"])
    >>> cfg["preset"], cfg["contact"]["cohesion"]
    ('tiny', 20000.0)
    >>> load_config(preset="tiny", overrides=["spread.sped=1"])
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: --set spread.sped=1: unknown config key `spread.sped` (did you mean speed?)
    """
    cfg = copy.deepcopy(DEFAULTS)
    user = {}
    user_label = None
    if source is not None:
        if isinstance(source, dict):
            user = copy.deepcopy(dict(source))
        else:
            user = _read_toml(source)
            user_label = str(source)
    origin: dict[str, str] = {}
    name = preset or user.get("preset") or None
    if name:
        if not isinstance(name, str):
            raise ConfigError(_sourced(f"config key `preset` must be a string; got {name!r}",
                                       user_label))
        path = preset_path(name)
        _merge_from(cfg, _read_toml(path), f"preset {name} ({path})", origin)
        cfg["preset"] = name
    _merge_from(cfg, user, user_label, origin)
    if name:
        cfg["preset"] = name
    for a in overrides or ():
        label = f"--set {a}"
        try:
            apply_override(cfg, a)
        except ConfigError as exc:
            raise ConfigError(_sourced(str(exc), label)) from None
        origin[str(a).split("=", 1)[0].strip()] = label
    if workflow is not None and workflow not in _GEOMETRY:
        raise ConfigError(f"unknown workflow {workflow!r}; one of {', '.join(_GEOMETRY)}")
    try:
        _validate(cfg, workflow)
    except ConfigError as exc:
        raise ConfigError(_sourced(str(exc), *_origins(str(exc), origin))) from None
    return cfg


def _sourced(message: str, *labels) -> str:
    """``message`` prefixed with where its values came from (a file, a preset, ``--set``)."""
    labels = [lb for lb in dict.fromkeys(labels) if lb]
    return f"{'; '.join(labels)}: {message}" if labels else message


def _leaf_keys(tree: dict, prefix: str = ""):
    for k, v in tree.items():
        if isinstance(v, dict):
            yield from _leaf_keys(v, f"{prefix}{k}.")
        else:
            yield f"{prefix}{k}"


def _merge_from(cfg: dict, new: dict, label, origin: dict) -> None:
    """Merge ``new`` into ``cfg``; a refused key is named with ``label``, and ``origin``
    records ``label`` as the source of every key of ``new``."""
    try:
        _merge(cfg, new)
    except ConfigError as exc:
        raise ConfigError(_sourced(str(exc), label)) from None
    if label:
        for k in _leaf_keys(new):
            origin[k] = label


_KEY_NAME = re.compile(r"\b([a-z_]+\.[a-z_0-9]+)\b")


def _origins(message: str, origin: dict) -> list:
    """The sources (``origin``) of the keys a message names, in the order it names them."""
    return [origin[k] for k in _KEY_NAME.findall(message) if k in origin]


def validate_config(cfg: dict) -> None:
    """Check the values of a configuration dict (types are checked by :func:`load_config`).

    :func:`load_config` calls it; a dict changed after loading can be checked again
    with it. The workflows load a dict given to them once, with :func:`workflow_config`.

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


def workflow_config(cfg) -> WorkflowConfig:
    """The :class:`~bedstruct.workflows.WorkflowConfig` a workflow runs: ``cfg`` itself when it
    is one, else the mapping loaded once (:func:`load_config`: defaults, its preset, its
    keys, every type and value checked) and made read-only (:func:`typed_config`).

    A :class:`WorkflowConfig` (made with :func:`typed_config` of a loaded configuration,
    changed with :func:`dataclasses.replace`) has each value checked against its field's
    bounds and choices again, so a replaced value out of range is refused too.

    Raises
    ------
    ConfigError
        Naming the first key of a mapping that is unknown, of the wrong type or out of range.
    TypeError
        ``cfg`` is neither a mapping nor a WorkflowConfig.

    Examples
    --------
    >>> cfg = load_config(preset="tiny")
    >>> workflow_config(cfg).contact.friction == cfg["contact"]["friction"]
    True
    >>> workflow_config({"preset": "tiny", "contact": {"friction": -0.1}})
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: config key `contact.friction` must be >= 0 (sliding friction coefficient); got -0.1
    >>> import dataclasses
    >>> wc = workflow_config(cfg)
    >>> workflow_config(dataclasses.replace(wc, contact=dataclasses.replace(wc.contact, restitution=1.5)))
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: config key `contact.restitution` must be > 0 and <= 1 (normal coefficient of restitution); got 1.5
    """
    if isinstance(cfg, WorkflowConfig):
        check_bounds(config_dict(cfg))
        return cfg
    if isinstance(cfg, Mapping):
        return typed_config(load_config(dict(cfg)))
    raise TypeError(f"a workflow configuration must be a mapping (load_config) or a "
                    f"WorkflowConfig; got {type(cfg).__name__}")


def _validate(cfg: dict, workflow: str | None = None) -> None:
    if not cfg["spread"]["gaps"]:
        raise ConfigError("config key `spread.gaps` must list at least one layer gap (m); got []")
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
    p = cfg["psd"]
    table = psd_table(p)
    if table is not None:
        below, above = float(table[1][0]), 1.0 - float(table[1][-1])
        if max(below, above) > _PSD_CUT_QUIET:
            log.warning("config key `psd.volume_fractions`: the table leaves out %.3g of the "
                        "volume below its first diameter and %.3g above its last; the draws "
                        "are renormalised to the table's range", below, above)
    if not p["d_min"] < p["d10"] < p["d50"] < p["d90"] < p["d_max"]:
        raise ConfigError("config keys `psd.d_min < psd.d10 < psd.d50 < psd.d90 < psd.d_max` must "
                          f"increase; got {p['d_min']}, {p['d10']}, {p['d50']}, {p['d90']}, {p['d_max']}")
    if len(cfg["repose"]["box"]) != 3:
        raise ConfigError(f"config key `repose.box` must be [L, W, H]; got {cfg['repose']['box']!r}")
    check_bounds(cfg)
    _validate_options(cfg["contact"])
    b = cfg["calibrate"]["cohesion_bracket"]
    if len(b) != 2 or not b[0] < b[1]:
        raise ConfigError(f"config key `calibrate.cohesion_bracket` must be [low, high] with "
                          f"low < high; got {b!r}")
    _validate_fines(cfg["psd"])
    _validate_wall_sentinels(cfg["contact"])
    for part in (_GEOMETRY[workflow] if workflow else ("spread", "repose")):
        _validate_geometry(cfg, part)


def _diameter_range(p: dict) -> tuple[float, float]:
    """Smallest and largest particle diameter (m, scaled) of a checked ``psd`` section
    (the tabulated distribution's ends, else ``d_min`` and ``d_max``; fines aside)."""
    table = psd_table(p)
    lo, hi = (float(table[0][0]), float(table[0][-1])) if table is not None else (
        float(p["d_min"]), float(p["d_max"]))
    return lo * float(p["scale"]), hi * float(p["scale"])


#: The sections whose lengths each workflow uses.
_GEOMETRY = {"repose": ("repose",), "calibrate": ("repose",), "spread": ("spread",)}


def _validate_fines(p: dict) -> None:
    """Fines below the smallest diameter of the powder they are added to."""
    if float(p["fines_mass_fraction"]) <= 0.0:
        return
    table = psd_table(p)
    d_cut = float(table[0][0]) if table is not None else float(p["d_min"])
    key = "`psd.diameters`" if table is not None else "`psd.d_min`"
    if not float(p["fines_min_diameter"]) < d_cut:
        raise ConfigError(f"config key `psd.fines_min_diameter` ({p['fines_min_diameter']!r} m) "
                          f"must lie below the smallest diameter of the powder, {key} "
                          f"({d_cut!r} m): the fines are the sizes below it")


def _validate_wall_sentinels(c: dict) -> None:
    """``contact.wall_friction`` / ``wall_cohesion``: -1 means the particle value; any
    other negative number is a typing slip, not a setting."""
    for k in ("wall_friction", "wall_cohesion"):
        v = float(c[k])
        if v < 0 and v != -1.0:
            raise ConfigError(f"config key `contact.{k}` must be >= 0, or -1 for the particle "
                              f"value; got {c[k]!r}")


def _validate_geometry(cfg: dict, part: str) -> None:
    """Cross-key checks of the lengths of section ``part`` (``"spread"`` or ``"repose"``)
    against the particle sizes and each other (m)."""
    d_lo, d_hi = _diameter_range(cfg["psd"])
    psd_keys = ("`psd.diameters` x `psd.scale`" if psd_table(cfg["psd"]) is not None
                else "`psd.d_min`/`psd.d_max` x `psd.scale`")
    sizes = f"particles of {d_lo * 1e6:.4g}-{d_hi * 1e6:.4g} um ({psd_keys})"
    # at load: room for two of the largest particles across (a run checks the neighbour
    # cells of its own box before it writes anything: check_run_geometry)
    min_width = 2.0 * d_hi
    if part == "spread":
        _spread_geometry(cfg["spread"], d_lo, d_hi, sizes, min_width)
    else:
        _repose_geometry(cfg["repose"], d_hi, sizes, min_width)


def _spread_geometry(sp: dict, d_lo: float, d_hi: float, sizes: str, min_width: float) -> None:
    gaps = [float(g) for g in sp["gaps"]]
    thin = [g for g in gaps if g < d_lo]
    if thin:
        raise ConfigError(f"config key `spread.gaps` holds a layer gap thinner than the smallest "
                          f"particle: {thin[0] * 1e6:.4g} um against {sizes}; every gap must be "
                          "at least the smallest diameter (check the units: metres)")
    if float(sp["width"]) < min_width:
        raise ConfigError(f"config key `spread.width` ({sp['width']!r} m) is too narrow for "
                          f"{sizes}: it must be at least {min_width:.4g} m (2 largest diameters; "
                          "check the units: metres)")
    for name in ("plate_length", "pile_length"):
        if float(sp[name]) < 3.0 * d_hi:
            raise ConfigError(f"config key `spread.{name}` ({sp[name]!r} m) must be at least 3 "
                              f"largest particle diameters for {sizes} (check the units: metres)")
    if float(sp["pile_length"]) > float(sp["plate_length"]):
        raise ConfigError(f"config key `spread.pile_length` ({sp['pile_length']!r} m) is longer "
                          f"than the platform, `spread.plate_length` ({sp['plate_length']!r} m): "
                          "the pile would be inserted over the front wall and fall into the "
                          "overflow")
    if sp["tool"] in ("blade", "rake", "plate") and \
            not float(sp["blade_height"]) > float(sp["blade_thickness"]):
        raise ConfigError(f"config key `spread.blade_height` ({sp['blade_height']!r} m) must "
                          f"exceed `spread.blade_thickness` ({sp['blade_thickness']!r} m)")


def _repose_geometry(rp: dict, d_hi: float, sizes: str, min_width: float) -> None:
    L, W, H = (float(v) for v in rp["box"])
    if W < min_width:
        raise ConfigError(f"config key `repose.box` width {W!r} m is too narrow for {sizes}: it "
                          f"must be at least {min_width:.4g} m (2 largest diameters; check the "
                          "units: metres)")
    if min(L, H) < 3.0 * d_hi:
        raise ConfigError(f"config key `repose.box` ({rp['box']!r} m) must be at least 3 "
                          f"largest particle diameters long and high for {sizes} (check the "
                          "units: metres)")
    if float(rp["pedestal_fraction"]) == 0.0 and float(rp["slide_fraction"]) * L < d_hi:
        raise ConfigError(f"config key `repose.slide_fraction` ({rp['slide_fraction']!r}) slides "
                          f"the plate {float(rp['slide_fraction']) * L * 1e6:.4g} um, less than "
                          f"the largest particle ({d_hi * 1e6:.4g} um): no powder can drain and "
                          "no pile forms; slide it further or use a ledge "
                          "(`repose.pedestal_fraction`)")


def check_run_geometry(cfg, workflow: str) -> None:
    """Check that the periodic width of a ``workflow`` run (``"spread"``, ``"repose"``) holds
    the engine's neighbour cells: 3 cells of the largest diameter plus the neighbour skin
    (0.15 of the smallest) across it. The workflows call it before they write anything.

    Raises
    ------
    ConfigError
        Naming ``spread.width`` or ``repose.box`` and the least width.
    """
    c = cfg if isinstance(cfg, dict) else config_dict(cfg)
    if workflow in ("spread", "repose"):
        _validate_geometry(c, workflow)
    d_lo, d_hi = _diameter_range(c["psd"])
    need = 3.0 * (d_hi + 0.15 * d_lo)
    if workflow == "spread" and not c["spread"]["side_walls"]:
        key, width = "spread.width", float(c["spread"]["width"])
    elif workflow == "repose" and c["repose"]["periodic_width"]:
        key, width = "repose.box", float(c["repose"]["box"][1])
    else:
        return
    if width < need:
        raise ConfigError(f"config key `{key}`: the periodic width {width!r} m must hold 3 "
                          f"neighbour cells of the largest particle ({d_hi * 1e6:.4g} um) and "
                          f"the skin: at least {need:.4g} m (or use side walls)")


def _validate_options(c: dict) -> None:
    if c["capillary"] and c["capillary_film_thickness"] <= 0:
        raise ConfigError("config key `contact.capillary_film_thickness` must be positive when "
                          "`contact.capillary` is true")


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
