"""The engine behind ``bedstruct diagnose`` (``[simulator] kind = "engine"``).

:func:`diagnosis_simulator` turns a diagnosis design (a
:class:`~bedstruct.diagnose.MeasurementSet`) and the ``[engine]`` table of a
simulation configuration into the simulator callable the diagnosis expects,
``sim(base, effects, seed) -> Observations``. Each call runs the repose and
spreading workflows of the embedded DEM engine with the base contact parameters
and the catalogue effects switched on at their magnitudes (through the
``[effects]`` configuration section, whose keys are the catalogue's
``engine_map`` names), then applies the observation operators of
:mod:`bedstruct.diagnose.observables` to the runs.

Scaled presets (``tiny``, ``small``) are scale models: the base cohesion energy
density of the diagnosis (calibrated for the seed's stiff, fine powder) is
multiplied by ``cohesion_scale`` (default: the preset's cohesion / 3.6e7), rake
speeds are the preset's spreading speed times the ratio of the observable's speed
to the seed's x1 speed (0.0254 m/s), layers beyond the preset's are mapped to
its last layer, and lengths come out in the scale model's units. Numbers from
such runs test the wiring and the method on real contact physics; they are not
predictions for the seed powder.

.. versionadded:: 0.1
"""

from __future__ import annotations

import copy
import logging
import math
import tempfile
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError
from .config import load_config

__all__ = ["diagnosis_simulator", "EngineSimulator", "effects_config"]

log = logging.getLogger(__name__)

_SPEED_X1 = 0.0254          # m/s, the seed's x1 rake speed
_K_SEED = 3.6e7             # J/m^3, the diagnosis' base cohesion energy density
_REGIONS = {"start": 0, "center": 1, "centre": 1, "middle": 1, "end": 2}
_ENGINE_KEYS = {"preset", "overrides", "cohesion_scale", "speed_scale", "ageing_time_scale",
                "n_threads", "seed", "workdir"}


def effects_config(effects: Mapping[str, float], *, ageing_time_scale: float = 1.0) -> dict:
    """The ``[effects]`` configuration values of catalogue effects at their magnitudes.

    Effects at magnitude 0 (or absent) are left out, so the base model is
    reproduced exactly. Times of the ageing law are divided by
    ``ageing_time_scale`` (to fit rest times into short simulations).

    Parameters
    ----------
    effects : mapping of str to float
        Catalogue names to magnitudes.
    ageing_time_scale : float
        Divisor of ``ageing_time_constant`` and ``ageing_reference_rest_time``.

    Returns
    -------
    dict
        Keys of the ``effects`` configuration section.

    Examples
    --------
    >>> effects_config({"capillary_bridges": 0.0})
    {}
    >>> fx = effects_config({"wall_friction": 0.1, "blade_startup": 0.05})
    >>> fx["wall_friction_excess"], fx["blade_ramp_time"], fx["blade_vibration_frequency"]
    (0.1, 0.05, 120.0)
    """
    from ..diagnose.catalogue import effect
    out: dict[str, Any] = {}
    for name, m in effects.items():
        if float(m) == 0.0:
            continue
        for key, val in effect(name).engine_parameters(float(m)).items():
            if isinstance(val, (bool, np.bool_)):
                out[key] = bool(val)
            elif isinstance(val, str):
                out[key] = val
            else:
                out[key] = float(val)
    if ageing_time_scale != 1.0:
        for key in ("ageing_time_constant", "ageing_reference_rest_time"):
            if key in out:
                out[key] = out[key] / float(ageing_time_scale)
    return out


class EngineSimulator:
    """Simulator of a diagnosis design on the embedded DEM engine (see the module docstring).

    Parameters
    ----------
    design : MeasurementSet
        Observables to produce (kinds and conditions are used).
    config : mapping
        The ``[engine]`` table: ``preset`` (default ``"tiny"``), ``overrides``
        (list of ``section.key=value``), ``cohesion_scale``, ``speed_scale``
        (default: preset speed / 0.0254), ``ageing_time_scale`` (default 1),
        ``n_threads``, ``seed`` (offset added to the replicate seed),
        ``workdir`` (folder for run directories; default a temporary one).

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
        self.preset = str(cfg.get("preset", "tiny"))
        self.overrides = [str(s) for s in cfg.get("overrides", [])]
        self.base_cfg = load_config(preset=self.preset, overrides=self.overrides)
        if "n_threads" in cfg:
            self.base_cfg["n_threads"] = int(cfg["n_threads"])
        k0 = float(self.base_cfg["contact"]["cohesion"])
        self.cohesion_scale = float(cfg.get("cohesion_scale",
                                            1.0 if self.preset == "seed" else k0 / _K_SEED))
        self.speed_scale = float(cfg.get("speed_scale",
                                         float(self.base_cfg["spread"]["speed"]) / _SPEED_X1))
        self.ageing_time_scale = float(cfg.get("ageing_time_scale", 1.0))
        self.seed_offset = int(cfg.get("seed", 0))
        self.workdir = cfg.get("workdir")
        for m in design:
            if m.kind not in ("static_angle", "dynamic_angle_series", "bed_height",
                              "packing_fraction", "psd", "roughness", "coordination"):
                raise ConfigError(f"observable {m.name!r}: kind {m.kind!r} not produced by the engine")
        self.n_runs = 0

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
        cfg["effects"].update(effects_config(effects, ageing_time_scale=self.ageing_time_scale))
        cfg["seed"] = int(seed) + self.seed_offset
        return load_config(cfg)  # type checks and validation

    # ------------------------------------------------------------------- runs
    def __call__(self, base: Mapping[str, float], effects: Mapping[str, float], seed: int):
        from ..diagnose.measurements import Observations
        cfg = self.run_config(base, effects, seed)
        root = Path(self.workdir) if self.workdir else None
        with tempfile.TemporaryDirectory(dir=root) as tmp:
            runs = _Runs(self, cfg, effects, Path(tmp))
            values = {m.name: runs.observe(m) for m in self.design}
        bad = [k for k, v in values.items() if not np.all(np.isfinite(v))]
        if bad:  # the diagnosis' linear algebra cannot use them: say which and where
            raise ValueError(f"engine simulator: observable(s) {bad} not finite (no fit: e.g. a "
                             f"pile without flanks or a heap below two diameters) for "
                             f"base={dict(base)}, effects={dict(effects)}, seed={seed}; values "
                             f"{ {k: values[k].tolist() for k in bad} }")
        return Observations(values, source="engine")


class _Runs:
    """Workflow runs of one simulator call, shared between the observables that need them."""

    def __init__(self, owner: EngineSimulator, cfg: dict, effects, tmp: Path):
        self.owner = owner
        self.cfg = cfg
        self.effects = dict(effects)
        self.tmp = tmp
        self.cache: dict = {}

    def _repose(self, rh):
        key = ("repose", rh)
        if key not in self.cache:
            from .repose import run_repose
            cfg = self.cfg
            if rh is not None:  # the observable's humidity overrides the capillary magnitude
                eff = dict(self.effects, capillary_bridges=float(rh))
                cfg = copy.deepcopy(self.cfg)
                fx = copy.deepcopy(self.owner.base_cfg["effects"])
                fx.update(effects_config(eff, ageing_time_scale=self.owner.ageing_time_scale))
                cfg["effects"] = fx
            out = self.tmp / f"repose{len(self.cache)}"
            res = run_repose(cfg, out=out, replicates=1)
            self.owner.n_runs += 1
            self.cache[key] = (res, out)
        return self.cache[key]

    def _spread(self, speed):
        v = float(self.cfg["spread"]["speed"]) if speed is None else \
            float(speed) * self.owner.speed_scale
        key = ("spread", round(v, 12))
        if key not in self.cache:
            from .spread import run_spread
            cfg = copy.deepcopy(self.cfg)
            cfg["spread"]["speed"] = v
            cfg["time"]["v_max"] = max(float(cfg["time"]["v_max"]), 1.5 * v)
            out = self.tmp / f"spread{len(self.cache)}"
            res = run_spread(cfg, out=out)
            self.owner.n_runs += 1
            self.cache[key] = (res, out, cfg)
        return self.cache[key]

    def _layer(self, res, layer):
        n = len(res.layers)
        i = n if layer is None else min(max(int(layer), 1), n)
        return res.layers[i - 1]

    def observe(self, m) -> np.ndarray:
        from ..diagnose.observables import observe
        from ..io import read_dump
        c = m.conditions
        if m.kind == "static_angle":
            res, out = self._repose(c.get("relative_humidity"))
            fr = _last_frame(read_dump, out / "rep00" / "pile.dump.gz")
            try:
                val = observe("static_angle", fr)
            except Exception as exc:  # noqa: BLE001 - a pile the camera fit cannot read
                log.warning("static angle operator failed (%s); using the workflow's flank fit", exc)
                val = np.array([res.angle_deg])
            if not np.all(np.isfinite(val)):
                val = np.array([res.angle_deg])
            return val
        if m.kind == "psd" and c.get("stage", "before") == "before":
            from ._common import psd_sampler
            draw = psd_sampler(self.cfg)
            rng = np.random.default_rng(int(self.cfg["seed"]))
            d = 2.0 * draw(int(self.cfg["spread"]["pile_particles"]), rng) / float(self.cfg["psd"]["scale"])
            return observe("psd", {"diameters": d}, percentiles=m.percentiles)
        res, out, cfg = self._spread(c.speed)
        lay = self._layer(res, c.layer)
        if m.kind == "dynamic_angle_series":
            pos = np.asarray(lay.blade_positions, float)
            stroke = max(float(pos.max() - pos.min()), 1e-12) if pos.size else 1.0
            times = (pos - pos.min()) / stroke if pos.size else pos
            ang = np.asarray(lay.dynamic_angle_deg, float)
            ok = np.isfinite(ang)
            if not ok.any():
                return np.full(len(m.windows), np.nan)
            t_ok, a_ok = times[ok], ang[ok]
            vals = []
            for w in np.asarray(m.windows, float).reshape(-1, 2):
                inside = (t_ok >= w[0]) & (t_ok <= w[1])
                if inside.any():
                    vals.append(observe("dynamic_angle_series", {"times": t_ok, "angles": a_ok},
                                        windows=w[None, :])[0])
                else:  # few frames per scaled stroke: the frame nearest to the window
                    vals.append(float(a_ok[np.argmin(np.abs(t_ok - 0.5 * (w[0] + w[1])))]))
            return np.array(vals)
        if m.kind == "bed_height":
            return observe("bed_height", {"surface_heights": [lay.bed_height_m]})
        if m.kind in ("packing_fraction", "coordination"):
            r = _REGIONS.get(str(c.region or "center").lower(), 1)
            arr = lay.packing_fraction if m.kind == "packing_fraction" else lay.coordination
            return np.array([float(arr[min(r, len(arr) - 1)])])
        if m.kind == "roughness":
            return np.array([float(lay.roughness_sa_m)])
        if m.kind == "psd":  # after spreading: the particles on the platform after the layer
            idx = res.layers.index(lay) + 1
            fr = _last_frame(read_dump, out / f"layer{idx:02d}" / "final.dump.gz")
            x = np.asarray(fr.positions)[:, 0]
            on = (x >= 0.0) & (x <= float(cfg["spread"]["plate_length"]))
            d = 2.0 * np.asarray(fr.radii)[on] / float(cfg["psd"]["scale"])
            return observe("psd", {"diameters": d}, percentiles=m.percentiles)
        raise ConfigError(f"observable {m.name!r}: kind {m.kind!r} not produced by the engine")


def _last_frame(read_dump, path):
    traj = read_dump(path)
    return traj[len(traj) - 1]


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
    >>> from bedstruct.diagnose.measurements import measurement_from_dict, MeasurementSet
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
