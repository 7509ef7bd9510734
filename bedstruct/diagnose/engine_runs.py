"""One call of the engine simulator: its workflow runs and the observation operators.

:class:`CallRuns` runs the repose and spreading workflows one call of
:class:`~bedstruct.diagnose.engine_simulator.EngineSimulator` needs (each at most once,
shared between the observables that read it) and applies the observation operators of
:mod:`bedstruct.diagnose.observables` to them: what each observable kind means on the
scale model (which layer, region, window, box) lives here; the simulator around it
(configuration, scale mapping, cache, batches) lives in :mod:`bedstruct.diagnose.engine_simulator`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import copy
import logging
import math
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .measurements import normalise_region
from .observables_registry import observable_kind, observe

__all__ = ["CallRuns", "REGIONS"]

log = logging.getLogger("bedstruct.diagnose.engine_simulator")

#: Layer regions of the packing fraction and coordination, as indices of the layer's
#: start / centre / end windows.
REGIONS = {"start": 0, "center": 1, "centre": 1, "middle": 1, "end": 2}


def _region_index(m) -> int:
    """Index of ``m``'s region in the layer's start / centre / end windows (default centre).

    Strict: an unknown region is an error naming the observable, never the centre."""
    region = m.conditions.region
    try:
        return REGIONS[normalise_region("center" if region is None else region)]
    except (KeyError, ConfigError) as exc:
        raise ConfigError(f"observable {m.name!r}: conditions.region {region!r} is not a region "
                          f"of the layer (start, center, end)") from exc


class CallRuns:
    """Workflow runs of one simulator call, shared between the observables that need them."""

    def __init__(self, owner, cfg: dict, effects, tmp: Path):
        self.owner = owner
        self.cfg = cfg
        self.effects = dict(effects)
        self.tmp = tmp
        self.cache: dict = {}

    def _repose(self, rh, walled=False, rest=0.0):
        # a rest changes nothing without contact ageing (the settled pile is at rest): the
        # run without it is the same run
        ageing = bool(self.cfg["contact"]["ageing"]) and \
            float(self.cfg["contact"]["ageing_bond_ratio"]) > 0.0
        rest = float(rest or 0.0) if ageing else 0.0
        key = ("repose", rh, walled, rest)
        if key not in self.cache:
            from ..workflows.repose import run_repose
            cfg = copy.deepcopy(self.cfg)
            if rh is not None:  # the observable's humidity overrides the capillary magnitude
                cfg = self.owner.with_effects(cfg, {"capillary_bridges": float(rh)},
                                              replace=("capillary_bridges",))
            if walled:  # a narrow box: side walls at the preset's box width
                cfg["repose"]["periodic_width"] = False
            # the rest before the plate moves, on the scale model's ageing clock
            cfg["repose"]["rest_time"] = rest / self.owner.ageing_time_scale
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
            from ..workflows.spread import run_spread
            cfg = copy.deepcopy(self.cfg)
            cfg["spread"]["speed"] = v
            cfg["time"]["v_max"] = max(float(cfg["time"]["v_max"]), 1.5 * v)
            out = self.tmp / f"spread{len(self.cache)}"
            # LIGGGHTS and LAMMPS decks make their own pile
            embedded = cfg.get("engine", "embedded") == "embedded"
            res = run_spread(cfg, out=out, pile=self._pile(cfg) if embedded else None)
            self.owner.n_runs += 1
            self.cache[key] = (res, out, cfg)
        return self.cache[key]

    def _pile(self, cfg):
        # the spreading runs of one call differ in speed, which the pile does not depend on
        from ..workflows.spread import generate_pile, pile_key
        key = ("pile", pile_key(cfg))
        if key not in self.cache:
            self.cache[key] = generate_pile(cfg, seed=int(cfg["seed"]))[0]
        return self.cache[key]

    def _layer(self, res, layer):
        n = len(res.layers)
        i = n if layer is None else min(max(int(layer), 1), n)
        return res.layers[i - 1]

    def observe(self, m) -> np.ndarray:
        from ..io import read_dump
        c = m.conditions
        if m.kind == "static_angle":
            bw = c.get("box_width")
            walled = bw is not None and float(bw) < self.owner.wide_box
            res, out = self._repose(c.get("relative_humidity"), walled, c.get("rest_time"))
            # the repose workflow's flank fit (each flank of the pile fitted on its own, then
            # averaged): the side-view camera operator fits one straight surface and read a
            # two-flanked tiny pile (~8 diameters high) anywhere from 1.5 to 40 deg
            val = float(res.angle_deg)
            if not math.isfinite(val):
                # no flank to fit (e.g. a cohesive block standing on the plate): missing data.
                # A straight-line fit over the whole profile would read the flat top as ~0 deg,
                # the opposite of what such a pile is.
                log.info("static angle %r: no flank fitted (NaN)", m.name)
            return np.array([val])
        if m.kind == "psd" and c.get("stage", "before") == "before":
            from ..workflows._common import psd_sampler
            draw = psd_sampler(self.cfg)
            rng = np.random.default_rng(int(self.cfg["seed"]))
            d = 2.0 * draw(int(self.cfg["spread"]["pile_particles"]), rng) / float(self.cfg["psd"]["scale"])
            return observe("psd", {"diameters": d}, percentiles=m.percentiles)
        res, out, cfg = self._spread(c.speed)
        lay = self._layer(res, c.layer)
        if m.kind == "dynamic_angle_series":
            # stroke fraction over the platform: frames with the tool beyond the platform end
            # (the overrun) have no heap on the platform and are not part of the stroke
            pos = np.asarray(lay.blade_positions, float)
            ang = np.asarray(lay.dynamic_angle_deg, float)
            plate = float(cfg["spread"]["plate_length"])
            on = pos <= plate
            pos, ang = pos[on], ang[on]
            p0 = float(pos.min()) if pos.size else 0.0
            times = (pos - p0) / max(plate - p0, 1e-12)
            ok = np.isfinite(ang)
            if not ok.any():  # no heap two diameters high with a free toe in any frame
                log.info("observable %r: no dynamic angle in layer %d at %.3g m/s (a larger "
                         "pile or a longer platform would give one)", m.name, lay.index,
                         float(cfg["spread"]["speed"]))
                return np.full(len(np.asarray(m.windows, float).reshape(-1, 2)), np.nan)
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
            r = _region_index(m)
            arr = lay.packing_fraction if m.kind == "packing_fraction" else lay.coordination
            return np.array([float(arr[min(r, len(arr) - 1)])])
        if m.kind == "roughness":
            return np.array([float(lay.roughness_sa_m)])
        if m.kind == "segregation_index":
            # analysis.segregation_index of the bed deposited by mid-layer (the spreading
            # workflow's measurement, bedstruct.workflows.spread_measure.mid_layer_segregation)
            return np.array([float(lay.segregation_index)])
        kind = observable_kind(m.kind)
        if kind.user:
            # a user kind: its function of the beds after layers 1 .. the observable's layer
            n = res.layers.index(lay) + 1
            frames = [_last_frame(read_dump, _dump(out / f"layer{i:02d}", "bed"))
                      for i in range(1, n + 1)]
            return observe(m.kind, {"frames": frames})
        if m.kind == "tool_force_ratio":
            # the time-averaged load of the stroke; a ratio, the same on the scale model as
            # at the seed's scale
            return np.array([float(lay.tool_force_ratio)])
        if m.kind == "psd":  # after spreading: the particles on the platform after the layer
            idx = res.layers.index(lay) + 1
            fr = _last_frame(read_dump, _dump(out / f"layer{idx:02d}", "bed"))
            x = np.asarray(fr.positions)[:, 0]
            on = (x >= 0.0) & (x <= float(cfg["spread"]["plate_length"]))
            d = 2.0 * np.asarray(fr.radii)[on] / float(cfg["psd"]["scale"])
            return observe("psd", {"diameters": d}, percentiles=m.percentiles)
        raise ConfigError(f"observable {m.name!r}: kind {m.kind!r} not produced by the engine")


def _dump(folder: Path, name: str) -> Path:
    """``folder/name.dump.gz`` or ``folder/name.dump`` (output.compress on or off)."""
    for ext in (".dump.gz", ".dump"):
        if (folder / f"{name}{ext}").is_file():
            return folder / f"{name}{ext}"
    raise FileNotFoundError(f"engine simulator: no {name}.dump(.gz) in {folder}")


def _last_frame(read_dump, path):
    traj = read_dump(path)
    return traj[len(traj) - 1]
