"""The engine behind ``bedstruct diagnose`` (``[simulator] kind = "engine"``).

:func:`diagnosis_simulator` turns a diagnosis design (a
:class:`~bedstruct.diagnose.MeasurementSet`) and the ``[engine]`` table of a
simulation configuration into the simulator callable the diagnosis expects,
``sim(base, effects, seed) -> Observations``. Each call runs the repose and
spreading workflows of the embedded DEM engine with the base contact parameters
and the catalogue effects switched on at their magnitudes (the configuration
options of the catalogue's ``engine_map``, e.g. ``contact.capillary`` or
``contact.rolling_friction``), then applies the observation operators of
:mod:`bedstruct.diagnose.observables` to the runs.

Scaled presets (``tiny``, ``small``) are scale models: the base cohesion energy
density of the diagnosis (calibrated for the seed's stiff, fine powder) is
multiplied by ``cohesion_scale`` (default: the preset's cohesion / 3.6e7), rake
speeds are the preset's spreading speed times the ratio of the observable's speed
to the seed's x1 speed (0.0254 m/s), layers beyond the preset's are mapped to
its last layer, and lengths come out in the scale model's units. Effect
parameters are mapped to the scale model too (:meth:`EngineSimulator.scale_effects`:
ageing and blade start-up times by the ratio of the stroke times, fines
diameters relative to the preset's cut-off, capillary bridges at the same Bond
number). Numbers from such runs test the wiring and the method on real contact
physics; they are not predictions for the seed powder.

With ``cache = DIR`` in the ``[engine]`` table every call's observations are
stored on disk and reused by a later call of the same configuration and code
(:mod:`bedstruct.diagnose.engine_cache`).

.. versionadded:: 0.1
"""

from __future__ import annotations

import copy
import json
import logging
import math
import tempfile
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..engines import ENGINE_NAMES, dialect
from ..errors import ConfigError
from ..workflows.config import DEFAULTS, load_config
from .catalogue import effect
from .engine_cache import call_key, code_versions, read_entry, write_entry
from .engine_runs import CallRuns, _region_index
from .measurements import Observations
from .observables_registry import observable_kind
from .process_pool import run_calls

__all__ = ["diagnosis_simulator", "EngineSimulator", "effects_config", "with_options",
           "engine_realises", "engine_refusal",
           "setup_config", "PRESET_OVERRIDES"]

log = logging.getLogger(__name__)

_SPEED_X1 = 0.0254          # m/s, the seed's x1 rake speed
_K_SEED = 3.6e7             # J/m^3, the diagnosis' base cohesion energy density
_E_COCR = 2.1e11            # Pa, CoCr's Young's modulus (the seed's calibration)
_STROKE_SEED = 18.9e-3 / _SPEED_X1   # s, the seed's x1 stroke over its 18.9 mm platform
_ENGINE_KEYS = {"preset", "config", "engine", "np", "overrides", "cohesion_scale", "speed_scale",
                "ageing_time_scale", "blade_time_scale", "capillary_scale", "fines_scale",
                "wide_box", "n_threads", "seed", "workdir", "cache", "jobs", "pile_dose"}
_ENGINES = ("embedded", "liggghts", "lammps")
#: Workflow overrides applied to a preset before the user's (the scale model of the
#: diagnosis): the tiny preset's 800-particle pile is used up within the first third of
#: the stroke, leaving most frames without a heap whose angle can be measured; and the
#: dynamic angle is read only from heaps with a free toe on the platform (not pushed
#: against the chamber's front wall), which the tiny preset's 2 mm platform never has
#: at 0.2 m/s and above (4 mm: x1 only), so the platform is 6 mm long.
#: Frame and contact dumps are not written (only the final states the operators read).
#: The small preset gets the same 6 mm platform (on its 4 mm one the x1 and x2 heaps reach
#: the front wall), a 2600-particle pile (enough powder for a heap in layer 3 after two
#: 400 um layers) and only the three layers the observables read (a quarter less time).
PRESET_OVERRIDES = {"tiny": ("spread.pile_particles=1000", "spread.pile_length=0.9e-3",
                             "spread.plate_length=6e-3",
                             "spread.n_frames=16", "output.frames=false", "output.contacts=false",
                             "output.compress=false"),
                    "small": ("spread.pile_particles=2600", "spread.pile_length=1.5e-3",
                              "spread.plate_length=6e-3", "spread.gaps=[400e-6,400e-6,200e-6]",
                              "spread.n_frames=16", "output.frames=false", "output.contacts=false",
                              "output.compress=false")}


def effects_config(effects: Mapping[str, float], base: Mapping[str, Any] | None = None, *,
                   ageing_time_scale: float = 1.0) -> dict:
    """The configuration options of catalogue effects at their magnitudes.

    Effects at magnitude 0 (or absent) are left out, so the base model is
    reproduced exactly. An effect that changes a contact coefficient relative to the
    base model (rolling friction from shape, wall friction from its excess over the
    particle friction) gives the coefficient's whole value, from its value in
    ``base``. Times of the ageing law are divided by ``ageing_time_scale`` (to fit
    rest times into short simulations).

    Parameters
    ----------
    effects : mapping of str to float
        Catalogue names to magnitudes.
    base : mapping, optional
        The workflow configuration the effects apply to (needed by the effects that
        offset one of its options: ``non_sphericity``, ``wall_friction``).
    ageing_time_scale : float
        Divisor of ``contact.ageing_time_constant`` and ``contact.ageing_reference_rest_time``.

    Returns
    -------
    dict
        ``{"section.option": value}`` (:func:`with_options` sets them).

    Examples
    --------
    >>> effects_config({"capillary_bridges": 0.0})
    {}
    >>> cfg = load_config(preset="tiny", overrides=["contact.friction=0.5"])
    >>> fx = effects_config({"wall_friction": 0.2, "blade_startup": 0.05}, cfg)
    >>> fx["contact.wall_friction"], fx["spread.ramp_time"], fx["spread.vibration_frequency"]
    (0.7, 0.05, 120.0)
    """
    out: dict[str, Any] = {}
    for name, m in effects.items():
        if float(m) == 0.0:
            continue
        for key, val in effect(name).engine_parameters(float(m), base).items():
            if isinstance(val, (bool, np.bool_)):
                out[key] = bool(val)
            elif isinstance(val, str):
                out[key] = val
            else:
                out[key] = float(val)
    if ageing_time_scale != 1.0:
        for key in ("contact.ageing_time_constant", "contact.ageing_reference_rest_time"):
            if key in out:
                out[key] = out[key] / float(ageing_time_scale)
    return out


def with_options(cfg: Mapping[str, Any], options: Mapping[str, Any]) -> dict:
    """A copy of the workflow configuration ``cfg`` with ``{"section.option": value}`` set.

    Raises
    ------
    ConfigError
        Naming an option that is not in the configuration.

    Examples
    --------
    >>> cfg = with_options(load_config(preset="tiny"), {"psd.fines_mass_fraction": 0.05})
    >>> cfg["psd"]["fines_mass_fraction"]
    0.05
    """
    out = copy.deepcopy(dict(cfg))
    for dotted, value in options.items():
        section, _, key = dotted.partition(".")
        if not isinstance(out.get(section), dict) or key not in out[section]:
            raise ConfigError(f"unknown config key `{dotted}`")
        out[section][key] = value
    return out


def engine_refusal(effect, engine: str, cfg: Mapping[str, Any] | None = None) -> str:
    """Why ``engine`` cannot realise catalogue ``effect`` (an :class:`Effect`) at the top of
    its prior; empty when it can.

    The engine's stated realisation (:attr:`Effect.realisations`) comes first, then its
    dialect's check (:meth:`bedstruct.engines.Dialect.check_effects`, spreading) of the
    run configuration ``cfg`` with the effect on (by default the workflow defaults with
    the effect at the top of its prior): e.g. LIGGGHTS' liquid bridges below its volume
    cut-off. The embedded engine realises every effect.

    Examples
    --------
    >>> from bedstruct.diagnose import effect
    >>> from bedstruct.diagnose.engine_simulator import engine_refusal
    >>> engine_refusal(effect("non_sphericity"), "liggghts")
    ''
    >>> "rest time" in engine_refusal(effect("contact_ageing"), "lammps")
    True
    """
    if engine not in ENGINE_NAMES:
        if engine != "embedded":
            raise ConfigError(f"engine: expected 'embedded' or one of {', '.join(ENGINE_NAMES)}; "
                              f"got {engine!r}")
        return ""
    r = effect.realisations[engine]
    if not r.realised:
        return r.refused
    if cfg is None:
        cfg = with_options(DEFAULTS, effects_config({effect.name: effect.prior[1]}, DEFAULTS))
    try:
        dialect(engine).check_effects(cfg, spreading=True)
    except ConfigError as exc:
        return str(exc)
    return ""


def engine_realises(effect, engine: str) -> bool:
    """Whether ``engine`` realises catalogue ``effect`` (an :class:`Effect`) with the
    workflow defaults: :func:`engine_refusal` has no reason.

    Examples
    --------
    >>> from bedstruct.diagnose import effect
    >>> from bedstruct.diagnose.engine_simulator import engine_realises
    >>> engine_realises(effect("contact_ageing"), "liggghts")
    False
    >>> engine_realises(effect("capillary_bridges"), "liggghts")   # films far below its cut-off
    False
    >>> engine_realises(effect("non_sphericity"), "liggghts")
    True
    """
    return not engine_refusal(effect, engine)


def setup_config(cfg: Mapping[str, Any], setup, design=(), *, speed_scale: float = 1.0) -> dict:
    """The workflow configuration ``cfg`` with the experiment's set-up applied.

    The conditions of a measurement file's ``[conditions]`` table
    (:class:`~bedstruct.diagnose.measurements.Setup`, SI) map onto the workflow
    configuration (:mod:`bedstruct.workflows.schema`):

    ==================  ====================================================================
    condition           configuration
    ==================  ====================================================================
    ``psd``             ``psd.d10``, ``d50``, ``d90``, ``d_min``, ``d_max``; from a file also
                        the whole distribution, ``psd.diameters`` and
                        ``psd.volume_fractions`` (cumulative at the size classes' edges),
                        which the radii are drawn from (the preset's coarse-graining
                        ``psd.scale`` still multiplies every diameter)
    ``layer_thickness`` ``spread.gaps`` (one per layer; ``layers`` is their number)
    ``blade_speed``     ``spread.speed`` = blade speed x ``speed_scale`` (the scale
                        model's speed; 1 on the ``seed`` preset)
    ``platform_length`` ``spread.plate_length``
    ``platform_width``  ``spread.width`` (without side walls a strip periodic across the
                        stroke)
    ``side_walls``      ``spread.side_walls`` (plane walls at y = 0 and y = ``spread.width``)
                        and the repose box: ``repose.periodic_width = not side_walls``
    ``wall_distance``   the distance between the side walls: ``spread.width`` and the
                        repose box's width ``repose.box[1]``
    ==================  ====================================================================

    Parameters
    ----------
    cfg : mapping
        A complete workflow configuration (:func:`bedstruct.workflows.load_config`).
    setup : Setup
    design : iterable of Measurement
        The observables to simulate (not used by the mapping; kept for the simulators'
        common signature).
    speed_scale : float
        Simulated speed per real speed.

    Returns
    -------
    dict
        The validated configuration.

    Raises
    ------
    ConfigError
        A condition the engine cannot honour, naming the file, the key and what is
        expected: a ``wall_distance`` narrower than ``platform_width`` (the walls bound
        the platform), or a set-up that gives an invalid configuration.

    Examples
    --------
    >>> from bedstruct.diagnose.measurements import Setup
    >>> from bedstruct.workflows.config import load_config
    >>> s = Setup(layer_thickness=(100e-6, 100e-6, 50e-6), blade_speed=0.05, platform_length=10e-3)
    >>> c = setup_config(load_config(preset="seed"), s)
    >>> c["spread"]["gaps"], c["spread"]["speed"], c["spread"]["plate_length"]
    ([0.0001, 0.0001, 5e-05], 0.05, 0.01)
    """
    out = copy.deepcopy(dict(cfg))
    sp, rp = out["spread"], out["repose"]
    if setup.psd is not None:
        out["psd"].update(zip(("d10", "d50", "d90", "d_min", "d_max"), (float(x) for x in setup.psd)))
        table = getattr(setup, "psd_table", None)
        out["psd"]["diameters"] = [] if table is None else [float(x) for x in table[0]]
        out["psd"]["volume_fractions"] = [] if table is None else [float(x) for x in table[1]]
    if setup.layer_thickness is not None:
        sp["gaps"] = [float(x) for x in setup.layer_thickness]
    if setup.blade_speed is not None:
        sp["speed"] = float(setup.blade_speed) * float(speed_scale)
        out["time"]["v_max"] = max(float(out["time"]["v_max"]), 1.5 * sp["speed"])
    if setup.platform_length is not None:
        sp["plate_length"] = float(setup.platform_length)
    if setup.platform_width is not None:
        sp["width"] = float(setup.platform_width)
    if setup.side_walls is not None:
        sp["side_walls"] = bool(setup.side_walls)
        rp["periodic_width"] = not setup.side_walls
        if setup.side_walls and setup.wall_distance is not None:
            w = float(setup.wall_distance)
            if setup.platform_width is not None and float(setup.platform_width) > w * (1 + 1e-9):
                raise ConfigError(f"{setup.where('wall_distance')}: the side walls bound the "
                                  f"platform, so their distance ({w * 1e3:.4g} mm) must be at "
                                  f"least platform_width ({setup.platform_width * 1e3:.4g} mm); "
                                  f"expected wall_distance >= platform_width")
            sp["width"] = w
            box = list(rp["box"])
            box[1] = w
            rp["box"] = box
    try:
        return load_config(out)
    except ConfigError as exc:
        raise ConfigError(f"{setup.path or 'measurement set'}: key 'conditions': the set-up "
                          f"{list(setup.given())} gives an invalid engine configuration: "
                          f"{exc}") from None


class EngineSimulator:
    """Simulator of a diagnosis design on the embedded DEM engine (see the module docstring).

    Parameters
    ----------
    design : MeasurementSet
        Observables to produce (kinds and conditions are used).
    config : mapping
        The ``[engine]`` table: ``preset`` (default ``"tiny"``), or ``config``
        (the path of the user's own workflow configuration, a ``bedstruct run``
        TOML file: their material, contact model and machine, simulated as it
        stands, at full scale: every scale below defaults to 1), ``engine``
        (``"embedded"``, ``"liggghts"`` or ``"lammps"``; default the
        configuration's), ``np`` (MPI ranks of each LIGGGHTS or LAMMPS run),
        ``overrides`` (list of ``section.key=value``), ``cohesion_scale`` (default:
        ``seed``: (E / 2.1e11 Pa)^(2/3), the SJKR pull-in force of CoCr's modulus kept at
        the preset's softened one; ``tiny`` and ``small``: the preset's
        ``contact.cohesion`` / 3.6e7, their own calibration of the seed's value),
        ``speed_scale`` (default: preset speed / 0.0254), ``ageing_time_scale``
        (default 1000, 1 for ``seed``), ``blade_time_scale`` (default: the preset's
        stroke time over the seed's, 1 for ``seed``), ``capillary_scale`` (factor on
        the bridge force; default ``psd.scale**2``, the same Bond number at
        coarse-grained sizes), ``fines_scale`` (default: ``psd.d_min`` / 28 um,
        1 for ``seed``), ``wide_box`` (m; a
        ``box_width`` below it is simulated with side walls, default 0.01),
        ``n_threads``, ``seed`` (offset added to the replicate seed),
        ``workdir`` (folder for run directories; default a temporary one),
        ``jobs`` (worker processes for batches of calls, :meth:`prefetch`; default 1),
        ``cache`` (folder of the observation cache; default none), ``pile_dose``
        (``"volume"``, the default: a call whose effects change the size distribution
        spreads a pile of the base configuration's expected solid volume,
        :meth:`same_dose`; ``"count"``: every pile holds ``spread.pile_particles``
        spheres).

    Notes
    -----
    Call as ``sim(base, effects, seed) -> Observations`` (``source="engine"``).
    ``base`` keys: ``cohesion_energy_density`` (J/m^3, scaled by
    ``cohesion_scale``), ``friction``, ``rolling_friction``, ``restitution``.
    """

    name = "engine"

    def __init__(self, design, config: Mapping[str, Any] | None = None):
        cfg = dict(config or {})
        unknown = set(cfg) - _ENGINE_KEYS
        if unknown:
            raise ConfigError(f"[engine]: key {sorted(unknown)[0]!r}: unknown "
                              f"(known: {sorted(_ENGINE_KEYS)})")
        self.design = design
        # the user's own workflow configuration (their material, contact model, machine) is
        # the model as it stands, at full scale; a preset gets the diagnosis' scale model
        self.config_file = str(cfg["config"]) if cfg.get("config") else None
        user_overrides = [str(s) for s in cfg.get("overrides", [])]
        if self.config_file is not None:
            self.preset = str(cfg["preset"]) if "preset" in cfg else None
            self.overrides = user_overrides
            self.base_cfg = load_config(Path(self.config_file).expanduser(),
                                        preset=self.preset, overrides=self.overrides)
        else:
            self.preset = str(cfg.get("preset", "tiny"))
            self.overrides = list(PRESET_OVERRIDES.get(self.preset, ())) + user_overrides
            self.base_cfg = load_config(preset=self.preset, overrides=self.overrides)
        if "engine" in cfg:
            if cfg["engine"] not in _ENGINES:
                raise ConfigError(f"[engine]: key 'engine': expected one of {', '.join(_ENGINES)}; "
                                  f"got {cfg['engine']!r}")
            self.base_cfg["engine"] = str(cfg["engine"])
        if "np" in cfg:
            n_ranks = cfg["np"]
            if isinstance(n_ranks, bool) or not isinstance(n_ranks, int) or n_ranks < 1:
                raise ConfigError(f"[engine]: key 'np': expected a whole number >= 1 (MPI ranks "
                                  f"of each LIGGGHTS or LAMMPS run); got {n_ranks!r}")
            self.base_cfg["external"]["np"] = n_ranks
        self.engine = str(self.base_cfg["engine"])
        if "n_threads" in cfg:
            self.base_cfg["n_threads"] = int(cfg["n_threads"])
        full_scale = self.config_file is not None or self.preset == "seed"
        k0 = float(self.base_cfg["contact"]["cohesion"])
        # the seed's calibrated 3.6e7 J/m^3 belongs to CoCr's modulus: the seed preset
        # (real sizes, softened modulus) transfers it keeping the SJKR pull-in force
        # (~ k^3 / E*^2); a coarse-grained preset's cohesion is its own calibration of it
        if self.config_file is not None:
            default_scale = 1.0
        elif self.preset == "seed":
            default_scale = (float(self.base_cfg["material"]["youngs_modulus"])
                             / _E_COCR) ** (2.0 / 3.0)
        else:
            default_scale = k0 / _K_SEED
        self.cohesion_scale = float(cfg.get("cohesion_scale", default_scale))
        self.speed_scale = float(cfg.get("speed_scale", 1.0 if self.config_file is not None else
                                         float(self.base_cfg["spread"]["speed"]) / _SPEED_X1))
        sc = self.base_cfg["spread"]
        stroke = float(sc["plate_length"]) / float(sc["speed"])
        # scale model: rest times of the ageing law fit into the preset's settling times
        self.ageing_time_scale = float(cfg.get("ageing_time_scale", 1.0 if full_scale else 1000.0))
        self.blade_time_scale = float(cfg.get("blade_time_scale",
                                              1.0 if full_scale else stroke / _STROKE_SEED))
        psd = self.base_cfg["psd"]
        self.capillary_scale = float(cfg.get("capillary_scale", float(psd["scale"]) ** 2))
        self.fines_scale = float(cfg.get("fines_scale",
                                         1.0 if full_scale else float(psd["d_min"]) / 28e-6))
        self.wide_box = float(cfg.get("wide_box", 0.01))
        for key in ("ageing_time_scale", "blade_time_scale", "capillary_scale", "fines_scale",
                    "wide_box"):
            v = getattr(self, key)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"[engine]: key {key!r} must be positive and finite; got {v!r}")
        # the experiment's set-up (the file's [conditions]): psd, layers, speed, platform, walls
        self.setup = getattr(design, "setup", None)
        if self.setup is not None and not self.setup.is_empty:
            self.base_cfg = setup_config(self.base_cfg, self.setup, design,
                                         speed_scale=self.speed_scale)
        self.jobs = int(cfg.get("jobs", 1))
        if self.jobs < 1:
            raise ConfigError(f"[engine]: key 'jobs' must be >= 1; got {self.jobs}")
        self.pile_dose = str(cfg.get("pile_dose", "volume"))
        if self.pile_dose not in ("volume", "count"):
            raise ConfigError(f"[engine]: key 'pile_dose': expected 'volume' or 'count'; got "
                              f"{self.pile_dose!r}")
        self._config = cfg
        self._memo: dict[str, dict] = {}   # prefetched calls' observations
        self.seed_offset = int(cfg.get("seed", 0))
        self.workdir = cfg.get("workdir")
        self.cache = Path(cfg["cache"]).expanduser() if cfg.get("cache") else None
        #: the code versions this simulator's cache entries are written and read under
        self.versions = code_versions() if self.cache is not None else {}
        #: read the cache's entries whatever code wrote them and never run the engine (a
        #: call not in the cache is an error): re-diagnosing a record from its own runs
        self.replay = False
        self.n_cached = 0
        # calls that ran the engine (here or in a worker), and a hook called after each
        # (``on_call(sim)``: a long validation says how far its twin has come)
        self.n_calls = 0
        self.on_call = None
        for m in design:
            try:
                observable_kind(m.kind)
            except ValueError as exc:
                raise ConfigError(f"observable {m.name!r}: kind {m.kind!r} not produced by the "
                                  f"engine ({exc})") from None
        self.n_runs = 0
        #: options (``{"section.option": value}``) set on every call after its base
        #: parameters, before its effects (a LIGGGHTS twin's withheld change)
        self.options: dict[str, Any] = {}

    # ------------------------------------------------------------------ config
    def run_config(self, base: Mapping[str, float], effects: Mapping[str, float], seed: int) -> dict:
        """The workflow configuration of one call (before per-observable conditions)."""
        cfg = copy.deepcopy(self.base_cfg)
        c = cfg["contact"]
        if "cohesion_energy_density" in base:
            c["cohesion"] = float(base["cohesion_energy_density"]) * self.cohesion_scale
        for key in ("friction", "rolling_friction", "restitution"):
            if key in base:
                c[key] = float(base[key])
        unknown = set(base) - {"cohesion_energy_density", "friction", "rolling_friction",
                               "restitution"}
        if unknown:
            raise ConfigError(f"base parameter {sorted(unknown)[0]!r} is not known to the engine "
                              "simulator (cohesion_energy_density, friction, rolling_friction, "
                              "restitution)")
        cfg = self.with_effects(with_options(cfg, self.options), effects)
        cfg["seed"] = int(seed) + self.seed_offset
        return self.same_dose(load_config(cfg))  # type checks and validation

    def same_dose(self, cfg: dict) -> dict:
        """``cfg`` with the spreading pile's sphere count set so that the pile's expected
        solid volume is the base configuration's.

        An effect that changes the size distribution (fines) changes the powder, not the
        amount of it dosed: a machine doses a volume of powder per layer, and the repose
        box is filled to a volume fraction already. Without this, fines at 8 % of the mass
        in a pile of a fixed number of spheres cut the powder spread by a third.
        """
        if self.pile_dose == "count":
            return cfg
        ref = self.__dict__.get("_dose_ref")
        if ref is None:
            base = load_config(with_options(copy.deepcopy(self.base_cfg), self.options))
            ref = self._dose_ref = (int(base["spread"]["pile_particles"]),
                                    self._mean_sphere_volume(base))
        n0, v0 = ref
        v = self._mean_sphere_volume(cfg)
        if v != v0:
            cfg["spread"]["pile_particles"] = max(1, int(round(n0 * v0 / v)))
        return cfg

    def _mean_sphere_volume(self, cfg) -> float:
        """Mean sphere volume of ``cfg``'s size distribution (200,000 draws), computed once
        per distribution: every call's configuration asks for it."""
        from ..workflows._common import mean_sphere_volume, psd_sampler
        memo = self.__dict__.setdefault("_volume_memo", {})
        key = json.dumps(cfg["psd"], sort_keys=True, default=float)
        if key not in memo:
            memo[key] = mean_sphere_volume(psd_sampler(cfg), 200_000)
        return memo[key]

    def relative_cost(self, base: Mapping[str, float], effects: Mapping[str, float]) -> float:
        """Expected cost of one call relative to the base configuration's: the ratio of their
        time steps (``Simulation.default_time_step`` at the smallest sphere of each size
        distribution), which sets the number of steps of every run of the call, times the
        ratio of their spreading piles' sphere counts (:meth:`same_dose`). Fines, for
        instance, shrink the smallest sphere and the step with it, and add spheres."""
        from ..dem import Simulation
        from ..workflows._common import contact_model, psd_sampler, typed

        def step(cfg):
            t = typed(cfg).time
            return Simulation.default_time_step(contact_model(cfg), psd_sampler(cfg).r_min,
                                                float(t.v_max), float(t.safety))

        def count(cfg):
            return float(cfg["spread"]["pile_particles"])

        ref = self.__dict__.get("_step_ref")
        if ref is None:
            cfg0 = self.run_config({}, {}, 0)
            ref = self._step_ref = (step(cfg0), count(cfg0))
        cfg = self.run_config(base, effects, 0)
        return ref[0] / step(cfg) * count(cfg) / ref[1]

    def with_effects(self, cfg: Mapping[str, Any], effects: Mapping[str, float], *,
                     replace=()) -> dict:
        """``cfg`` with the catalogue ``effects`` switched on (scale model).

        The options of the effects named in ``replace`` are first reset to the
        simulator's base configuration (an observable's own magnitude of an effect
        replaces the call's).
        """
        cfg = copy.deepcopy(dict(cfg))
        for name in replace:
            for dotted, *_ in effect(name).engine_map:
                section, _, key = dotted.partition(".")
                cfg[section][key] = copy.deepcopy(self.base_cfg[section][key])
        return with_options(cfg, self.scale_effects(effects_config(effects, cfg)))

    def scale_effects(self, fx: Mapping[str, Any]) -> dict:
        """Map the options of catalogue effects (``{"section.option": value}``, seed scale)
        to the preset's scale model.

        Ageing times are divided by ``ageing_time_scale``; the blade ramp time is
        multiplied and the vibration frequency divided by ``blade_time_scale`` (the
        same fraction of the stroke); the vibration amplitude and the ageing
        bond's break slip are multiplied by ``psd.scale`` (the same fraction of a
        particle); fines diameters by ``fines_scale`` (the same ratio to the
        preset's cut-off ``psd.d_min``); the capillary surface tension by
        ``capillary_scale`` and the film thickness by ``psd.scale`` (the bridge
        force per particle weight and the bridge volume per particle volume of
        the coarse-grained particles stay those of the seed powder).
        """
        out = dict(fx)
        ps = float(self.base_cfg["psd"]["scale"])
        rules = {"contact.ageing_time_constant": 1.0 / self.ageing_time_scale,
                 "contact.ageing_reference_rest_time": 1.0 / self.ageing_time_scale,
                 "spread.ramp_time": self.blade_time_scale,
                 "spread.vibration_frequency": 1.0 / self.blade_time_scale,
                 "spread.vibration_amplitude": ps,
                 "contact.ageing_break_slip": ps,
                 "psd.fines_median_diameter": self.fines_scale,
                 "psd.fines_min_diameter": self.fines_scale,
                 "contact.capillary_surface_tension": self.capillary_scale,
                 "contact.capillary_film_thickness": ps}
        for key, f in rules.items():
            if key in out and not isinstance(out[key], (bool, str)):
                out[key] = float(out[key]) * f
        return out

    # ------------------------------------------------------------------ cache
    def _spec(self, m) -> dict:
        """What an observable's simulated value depends on besides the run configuration
        (conditions the engine ignores or maps together are canonicalised, so that equal
        simulations share cache entries)."""
        c = m.conditions
        spec: dict[str, Any] = {"kind": m.kind}
        if m.kind == "static_angle":
            bw = c.get("box_width")
            spec["walled"] = bool(bw is not None and float(bw) < self.wide_box)
            rh = c.get("relative_humidity")
            spec["relative_humidity"] = None if rh is None else float(rh)
            spec["operator"] = "workflow-flanks/descending"   # no flank (a block): NaN
            rest = c.get("rest_time")
            if rest is not None and float(rest) > 0:  # (absent for an angle without rest)
                spec["rest_time"] = float(rest)
        elif m.kind == "psd" and c.get("stage", "before") == "before":
            pass
        else:
            n = len(self.base_cfg["spread"]["gaps"])
            spec["layer"] = n if c.layer is None else min(max(int(c.layer), 1), n)
            spec["speed"] = None if c.speed is None else round(float(c.speed), 12)
            if m.kind in ("packing_fraction", "coordination"):
                spec["region"] = _region_index(m)   # the index keeps the cache keys
        if m.kind == "psd":
            spec["stage"] = c.get("stage", "before")
        kind = observable_kind(m.kind)
        if kind.user:   # the function's module, name and source hash
            spec["function"] = kind.source
        if m.windows is not None:
            spec["windows"] = np.asarray(m.windows, float).round(12).tolist()
        if m.percentiles is not None:
            spec["percentiles"] = np.asarray(m.percentiles, float).tolist()
        return spec

    def cache_key(self, base: Mapping[str, float], effects: Mapping[str, float], seed: int) -> str:
        """Hash of one call (the fully resolved workflow configuration and the scale model)."""
        return call_key(self.run_config(base, effects, seed), wide_box=self.wide_box,
                        speed_scale=self.speed_scale)

    # ------------------------------------------------------------------- runs
    def _memo_key(self, base, effects, seed) -> str:
        return json.dumps([dict(base), dict(effects), int(seed)], sort_keys=True, default=float)

    def prefetch(self, calls, *, progress: bool = False) -> int:
        """Run a batch of calls ``(base, effects, seed)`` ahead, ``jobs`` at a time.

        With ``jobs`` > 1 the calls that are neither cached nor already fetched run in
        worker processes (:func:`bedstruct.diagnose.process_pool.run_calls`); the
        later ``sim(base, effects, seed)`` calls return their observations. With
        ``jobs = 1`` nothing is done (the calls run when asked for). ``progress``
        shows a bar over the batch. Returns the number of calls run.
        """
        if self.jobs <= 1 or self.replay:
            return 0
        todo, seen = [], set()
        for b, e, s in calls:
            k = self._memo_key(b, e, s)
            if k in seen or k in self._memo or self._fully_cached(b, e, s):
                continue
            seen.add(k)
            todo.append((dict(b), dict(e), int(s)))
        if len(todo) < 2:
            return 0
        users = _user_kinds(self.design)
        done = run_calls(engine_call, [(self.design, dict(self._config), b, e, s, users)
                                       for b, e, s in todo], self.jobs, progress=progress)
        for (b, e, s), (values, n_runs) in zip(todo, done):
            self._memo[self._memo_key(b, e, s)] = values
            self.n_runs += n_runs
        self._called(len(todo))
        return len(todo)

    def _called(self, n: int = 1) -> None:
        self.n_calls += n
        if self.on_call is not None:
            self.on_call(self)

    def _fully_cached(self, base, effects, seed) -> bool:
        if self.cache is None:
            return False
        cached = read_entry(self.cache, self.cache_key(base, effects, seed),
                            None if self.replay else self.versions)
        return all(json.dumps(self._spec(m), sort_keys=True) in cached for m in self.design)

    def __call__(self, base: Mapping[str, float], effects: Mapping[str, float], seed: int):
        fetched = self._memo.get(self._memo_key(base, effects, seed)) if self._memo else None
        if fetched is not None:
            return Observations({m.name: np.asarray(fetched[m.name], float) for m in self.design},
                                source="engine")
        cfg = self.run_config(base, effects, seed)
        key = self.cache_key(base, effects, seed) if self.cache is not None else ""
        cached = (read_entry(self.cache, key, None if self.replay else self.versions)
                  if key else {})
        specs = {m.name: json.dumps(self._spec(m), sort_keys=True) for m in self.design}
        values = {n: np.asarray(cached[sp]["value"], float) for n, sp in specs.items()
                  if sp in cached}
        todo = [m for m in self.design if m.name not in values]
        if todo and self.replay:
            raise ConfigError(f"replaying the engine cache {self.cache}: the call base="
                              f"{dict(base)}, effects={dict(effects)}, seed={seed} has no entry "
                              f"for {', '.join(m.name for m in todo)} (a replay never runs the "
                              f"engine)")
        if todo:
            root = Path(self.workdir).expanduser() if self.workdir else None
            if root is not None:
                root.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=root) as tmp:
                runs = CallRuns(self, cfg, effects, Path(tmp))
                for m in todo:
                    values[m.name] = runs.observe(m)
            if key:
                entries = dict(cached)
                for m in todo:  # NaN (unobservable in this run) is a result too
                    entries[specs[m.name]] = {"value": values[m.name].tolist(), "name": m.name}
                write_entry(self.cache, key, entries,
                            {"base": dict(base), "effects": dict(effects), "seed": int(seed),
                             "preset": self.preset, "overrides": self.overrides,
                             "versions": self.versions})
            self._called()
        else:
            self.n_cached += 1
        values = {m.name: values[m.name] for m in self.design}
        bad = [k for k, v in values.items() if not np.all(np.isfinite(v))]
        if bad:  # missing data, reported by the diagnosis (fingerprints and twins handle NaN)
            log.info("engine simulator: observable(s) %s not observable in this run (no fit: "
                        "e.g. a pile without flanks or no heap two diameters high with a free "
                        "toe) for base=%s, effects=%s, seed=%d: NaN", bad, dict(base),
                        dict(effects), seed)
        return Observations(values, source="engine")


def _user_kinds(design) -> tuple:
    """``(name, "module:function", unit)`` of the design's user kinds, for worker processes
    (started afresh: they register them again from the function's module)."""
    out = []
    for name in dict.fromkeys(m.kind for m in design):
        k = observable_kind(name)
        if k.user:
            where = k.source.split("#")[0]
            if where.startswith("__main__:") or "<locals>" in where:
                raise ConfigError(f"observable kind {name!r}: its function {where} cannot be "
                                  f"imported by worker processes; define it in a module, or "
                                  f"run with jobs = 1")
            out.append((name, where, k.unit))
    return tuple(out)


def engine_call(design, config: Mapping[str, Any], base, effects, seed, user_kinds=()):
    """One engine call in a worker process: its observations (lists) and its number of runs."""
    from .observables_registry import load_callable, register_observable
    for name, where, unit in user_kinds:
        register_observable(name, load_callable(where), unit=unit)
    sim = EngineSimulator(design, dict(config, jobs=1))
    obs = sim(base, effects, seed)
    return {k: v.tolist() for k, v in obs.values.items()}, sim.n_runs


def diagnosis_simulator(design, config: Mapping[str, Any] | None = None) -> EngineSimulator:
    """The engine simulator of a diagnosis design (the hook of ``kind = "engine"``).

    Parameters
    ----------
    design : MeasurementSet
        ``bedstruct.diagnose.diagnosis_design(measurements, effects)``.
    config : mapping, optional
        The ``[engine]`` table of the simulation configuration (see
        :class:`EngineSimulator`).

    Returns
    -------
    EngineSimulator
        ``sim(base, effects, seed) -> Observations``.

    Examples
    --------
    >>> from bedstruct.diagnose import measurement_from_dict, MeasurementSet
    >>> m = measurement_from_dict({"name": "psd", "kind": "psd", "role": "candidate",
    ...                            "uncertainty": 1e-6, "percentiles": [10, 50, 90],
    ...                            "conditions": {"stage": "before"}})
    >>> sim = diagnosis_simulator(MeasurementSet((m,)), {"preset": "tiny"})
    >>> obs = sim({}, {}, 0)
    >>> bool(40e-6 <= obs["psd"][0] < obs["psd"][2] <= 70e-6)
    True
    """
    if not math.isfinite(float((config or {}).get("cohesion_scale", 1.0))):
        raise ConfigError("[engine]: key 'cohesion_scale' must be finite")
    return EngineSimulator(design, config)
