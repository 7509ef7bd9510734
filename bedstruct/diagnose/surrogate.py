"""A cheap analytic surrogate of the spreading/repose simulations, for tests and validation.

**This is not the DEM engine.** It maps base contact parameters and effect
magnitudes to observables through physically motivated scaling laws anchored on
the seed report (static angle vs cohesion energy density: 28.9 deg at 3.0e7 to
32.1 deg at 3.6e7 J/m^3; dynamic angle 27.3/29.6/38.3 deg at x1/x2/x5 speed;
packing fraction dropping 5 % from x1 to x5 and 3.5 % from start to end) plus
seeded noise that is partly common to runs with the same seed (common random
numbers, correlation ``correlation``) and partly run-specific, as replicate DEM
runs would be. Every output it produces is labelled ``source="surrogate"``.

Each effect has the signature documented in its catalogue entry: contact ageing
is a transient that decays within ~3 % of the stroke; capillary bridges act like
cohesion that barely weakens with speed; non-sphericity grows with speed and
lowers packing; fines change the PSD; wall friction raises the static angle in
the narrow simulated box and drags the pile; a blade start-up ramp lowers the
early-stroke angle, most at high speed.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
import zlib
from typing import Mapping

import numpy as np
from scipy.special import ndtr

from ..errors import ConfigError
from .catalogue import CATALOGUE
from .measurements import MeasurementSet, Observations, normalise_region
from .parameters import parameter_value_error

__all__ = ["SurrogateSimulator", "BASE_PARAMETERS", "SPEED_X1", "STROKE_LENGTH"]

#: Observable kinds the surrogate models.
_MODELLED = ("static_angle", "dynamic_angle_series", "bed_height", "packing_fraction", "psd",
             "roughness", "coordination", "tool_force_ratio")

#: Base contact parameters of the seed model after calibration (SI).
BASE_PARAMETERS: dict[str, float] = {
    "cohesion_energy_density": 3.6e7,   # J/m^3 (SJKR)
    "friction": 0.4,                    # particle-particle sliding friction
    "rolling_friction": 0.05,           # constant-torque rolling friction
    "restitution": 0.1,
}
SPEED_X1 = 0.0254          # m/s
STROKE_LENGTH = 18.9e-3    # m
_K_REF = 3.6e7
_REGION_X = {"start": 1 / 6, "center": 0.5, "end": 5 / 6}   # keys: normalise_region's spellings
_LAYERS_UM = (508.0, 508.0, 102.0, 127.0)
# The friction laws are logarithmic in the coefficient; below these floors a coefficient acts
# as the floor (a frictionless powder), so every coefficient >= 0 has finite observables.
_MU_FLOOR, _MU_R_FLOOR = 1e-3, 1e-4
# Simulated PSD (volume-weighted log-normal, truncated at 28 um diameter) and fines population.
_PSD_MU, _PSD_SIGMA, _PSD_CUT = math.log(52.5e-6), 0.385, 28e-6
_FINES_MU, _FINES_SIGMA = math.log(20e-6), 0.25


def _region_x(m) -> float:
    """Position along the stroke of ``m``'s region (strict: an unknown region is an error)."""
    try:
        return _REGION_X[normalise_region(m.conditions.region)]
    except (KeyError, ConfigError) as exc:
        raise ConfigError(f"observable {m.name!r}: conditions.region {m.conditions.region!r} is "
                          f"not a region of the surrogate (start, center, end)") from exc


def _cap(h: float) -> float:
    """Saturating capillary cohesion factor of relative humidity (0..~0.76)."""
    return h / (h + 0.25) if h > 0 else 0.0


def _steady_dynamic(s):
    return 25.3 + 1.85 * s + 0.15 * s * s


def _psd_quantiles(p, fines: float, stage_after: bool, seg: float) -> np.ndarray:
    """Volume percentiles (m) of the truncated simulated PSD mixed with a fines fraction."""
    d = np.exp(np.linspace(math.log(5e-6), math.log(200e-6), 2000))
    base = ndtr((np.log(d) - _PSD_MU) / _PSD_SIGMA)
    c0 = ndtr((math.log(_PSD_CUT) - _PSD_MU) / _PSD_SIGMA)
    base = np.clip((base - c0) / (1 - c0), 0.0, 1.0)
    f = min(fines * (1.3 if stage_after else 1.0), 0.5)
    cdf = (1 - f) * base + f * ndtr((np.log(d) - _FINES_MU) / _FINES_SIGMA)
    q = np.interp(np.asarray(p, float) / 100.0, cdf, d)
    return q * (1.0 + seg) if stage_after else q


class SurrogateSimulator:
    """Analytic stand-in for the DEM workflows, producing the observables of a design.

    Parameters
    ----------
    design : MeasurementSet
        The observables to produce (values are ignored; kinds and conditions used).
    noise : float
        Multiplier of the replicate noise (1 = documented levels, 0 = exact means).
    correlation : float
        Correlation of the noise between runs sharing a seed (common random numbers).

    Notes
    -----
    Call as ``sim(base, effects, seed) -> Observations``, the simulator interface
    the diagnosis uses. ``base`` holds the keys of :data:`BASE_PARAMETERS`
    (missing ones take their defaults), each within its physical bounds
    (:data:`~bedstruct.diagnose.parameters.PARAMETER_BOUNDS`, the bounds included: a
    cohesionless or frictionless powder is a valid point); ``effects`` maps catalogue
    names to magnitudes.

    Examples
    --------
    >>> from bedstruct.diagnose import measurement_from_dict, MeasurementSet
    >>> m = measurement_from_dict({"name": "aor", "kind": "static_angle", "role": "candidate",
    ...                            "uncertainty": 0.5})
    >>> sim = SurrogateSimulator(MeasurementSet((m,)), noise=0)
    >>> round(float(sim({}, {}, 0)["aor"][0]), 2)
    32.1
    >>> round(float(sim({"cohesion_energy_density": 3.0e7}, {}, 0)["aor"][0]), 2)
    28.9
    """

    name = "surrogate"

    def __init__(self, design: MeasurementSet, *, noise: float = 1.0, correlation: float = 0.5):
        self.design = design
        self.noise = float(noise)
        self.correlation = float(correlation)
        setup = getattr(design, "setup", None)
        if setup is not None and not setup.is_empty:
            raise ConfigError(f"{setup.where(setup.given()[0])}: the surrogate simulator models "
                              f"the seed's set-up only; expected no [conditions] table, or the "
                              f"engine simulator ([simulator] kind = \"engine\")")
        for m in design:
            self._check(m)

    @staticmethod
    def _check(m):
        if m.kind not in _MODELLED:
            raise ConfigError(f"observable {m.name!r}: key 'kind': the surrogate does not model "
                              f"{m.kind!r} (it models {sorted(_MODELLED)}); use the engine "
                              f"simulator")
        if m.conditions.region is not None:
            _region_x(m)   # an unknown region is an error now, not at the first call
        if m.kind == "bed_height" and m.conditions.layer is None:
            raise ConfigError(f"observable {m.name!r}: key 'conditions.layer': the surrogate needs "
                              f"the layer of a bed_height")

    # ------------------------------------------------------------------ public
    def __call__(self, base: Mapping[str, float], effects: Mapping[str, float], seed: int) -> Observations:
        p = self._params(base)
        e = self._effects(effects)
        out = {}
        for m in self.design:
            mean = self._mean(m, p, e)
            sd = self._sd(m, mean)
            if self.noise > 0:
                out[m.name] = mean + self.noise * sd * self._xi(m.name, len(mean), seed, p, e)
            else:
                out[m.name] = mean
        return Observations(out, source="surrogate")

    def noise_sd(self) -> dict[str, np.ndarray]:
        """Replicate standard deviation per observable at the base parameters."""
        p, e = self._params({}), self._effects({})
        return {m.name: self.noise * self._sd(m, self._mean(m, p, e)) for m in self.design}

    # ------------------------------------------------------------------ internals
    @staticmethod
    def _params(base):
        unknown = set(base) - set(BASE_PARAMETERS)
        if unknown:
            raise ConfigError(f"base: unknown parameter {sorted(unknown)[0]!r}; the surrogate knows "
                              f"{sorted(BASE_PARAMETERS)}")
        p = dict(BASE_PARAMETERS)
        p.update({k: float(v) for k, v in base.items()})
        for k, v in p.items():   # each physical value, the bounds of a recalibration included
            why = parameter_value_error(k, v, closed=True)
            if why:
                raise ConfigError(f"surrogate parameter {k!r}: {why}")
        return p

    @staticmethod
    def _effects(effects):
        known = {x.name for x in CATALOGUE}
        unknown = set(effects) - known
        if unknown:
            raise ConfigError(f"effects: unknown effect {sorted(unknown)[0]!r} (the surrogate "
                              f"implements {sorted(known)})")
        e = {k: 0.0 for k in known}
        e.update({k: float(v) for k, v in effects.items()})
        if e["blade_startup"] < 0 or e["capillary_bridges"] < 0 or e["missing_fines"] < 0:
            raise ConfigError("effects: ramp time, humidity and fines fraction must be >= 0")
        return e

    def _xi(self, name, n, seed, p, e):
        common = np.random.default_rng([int(seed), zlib.crc32(name.encode())]).standard_normal(n)
        key = repr((name, sorted((k, round(v, 12)) for k, v in p.items()),
                    sorted((k, round(v, 12)) for k, v in e.items()))).encode()
        own = np.random.default_rng([int(seed), zlib.crc32(key), 7]).standard_normal(n)
        rho = self.correlation
        return rho * common + math.sqrt(max(1 - rho * rho, 0.0)) * own

    @staticmethod
    def _sd(m, mean):
        k = m.kind
        if k == "static_angle":
            return np.full(len(mean), 0.35)
        if k == "dynamic_angle_series":
            s = (m.conditions.speed or SPEED_X1) / SPEED_X1
            w = m.windows[:, 1] - m.windows[:, 0]
            return (0.25 + 0.05 * s) * np.sqrt(0.1 / w) + 0.15
        if k == "bed_height":
            return 0.004 * np.abs(mean)
        if k == "packing_fraction":
            return np.full(len(mean), 0.003)
        if k == "psd":
            return 0.005 * np.abs(mean)
        if k == "roughness":
            return 0.03 * np.abs(mean)
        if k == "coordination":
            return np.full(len(mean), 0.05)
        if k == "tool_force_ratio":
            return np.full(len(mean), 0.035 if m.conditions.layer == 1 else 0.006)
        raise ValueError(k)  # pragma: no cover

    def _mean(self, m, p, e) -> np.ndarray:
        c = m.conditions
        s = (c.speed or SPEED_X1) / SPEED_X1
        rel_k = p["cohesion_energy_density"] / _K_REF - 1.0
        lmu = math.log(max(p["friction"], _MU_FLOOR) / 0.4)
        lmur = math.log(max(p["rolling_friction"], _MU_R_FLOOR) / 0.05)
        rh = c.get("relative_humidity")
        cap = _cap(rh if (rh is not None and e["capillary_bridges"] > 0) else e["capillary_bridges"])
        A, R, F, W, T = (e["contact_ageing"], e["non_sphericity"], e["missing_fines"],
                         e["wall_friction"], e["blade_startup"])
        xr = _region_x(m) if c.region is not None else 0.5
        k = m.kind
        if k == "static_angle":
            rest = float(c.get("rest_time", 0.0))
            width = float(c.get("box_width", 3e-3))
            th = (28.9 + 3.2 * (p["cohesion_energy_density"] - 3.0e7) / 0.6e7 + 2.0 * lmu + 1.0 * lmur
                  - 1.0 * (p["restitution"] - 0.1)
                  + 4.5 * cap
                  + A * (0.2 + 1.5 * math.log1p(rest / 10.0) / math.log(7.0))
                  + 14.0 * R + 12.0 * F + 10.0 * W * (3e-3 / max(width, 1e-4)))
            return np.array([th])
        if k == "dynamic_angle_series":
            rest = float(c.get("rest_time", 60.0))
            age = math.log1p(rest / 10.0) / math.log(7.0)
            out = []
            stroke_time = STROKE_LENGTH / (s * SPEED_X1)
            for t0, t1 in m.windows:
                base = (_steady_dynamic(s) + 12.0 * rel_k / (1 + 0.3 * s) + 3.0 * lmu + 2.0 * lmur)
                tau = 0.03
                transient = tau * (math.exp(-t0 / tau) - math.exp(-t1 / tau)) / (t1 - t0)
                val = (base + 3.5 * cap * (1 + 0.02 * s)
                       + A * age * (9.0 * transient + 0.1)
                       + 10.0 * R * (1 + 0.4 * s)
                       + 8.0 * F * (1 + 0.5 / s)
                       + 1.5 * W * (1 + 0.1 * s))
                if T > 0:
                    tt = t0 + (np.arange(64) + 0.5) / 64 * (t1 - t0)
                    u = 1.0 - np.exp(-tt * stroke_time / T)
                    val += float(np.mean(_steady_dynamic(s * u) - _steady_dynamic(s)))
                out.append(val)
            return np.asarray(out)
        if k == "bed_height":
            layer = c.layer
            nominal = sum(_LAYERS_UM[:min(layer, 4)]) + max(layer - 4, 0) * 127.0
            eps = (0.004 * rel_k - 0.02 * F + 0.03 * W * (1.0 if layer == 1 else 0.3)
                   + 0.01 * cap + 0.02 * R)
            return np.array([nominal * 1e-6 * (1 + eps)])
        if k == "packing_fraction":
            phi = (0.55 - 0.0125 * (s - 1) - 0.035 * xr - 0.03 * rel_k - 0.02 * lmu
                   - 0.08 * cap - 0.06 * R + 0.25 * F - 0.04 * W * xr
                   - 0.04 * (T / 0.25) * math.exp(-xr / 0.15) * s / 5
                   - 0.01 * A * math.exp(-xr / 0.1))
            return np.array([phi])
        if k == "psd":
            after = c.get("stage", "before") == "after"
            seg = 0.03 * (1 - 0.6 * cap) / math.sqrt(s) + 0.02 * R
            return _psd_quantiles(m.percentiles, F, after, seg)
        if k == "roughness":
            rq = 12e-6 * (1 + 0.15 * (s - 1)) * (1 + 0.5 * rel_k + 0.4 * cap + 1.5 * R - 1.0 * F + 0.3 * W
                                                 + 0.2 * (T / 0.25) * s / 5)
            return np.array([rq])
        if k == "coordination":
            phi = (0.55 - 0.0125 * (s - 1) - 0.035 * xr - 0.03 * rel_k - 0.08 * cap - 0.06 * R + 0.25 * F)
            return np.array([2 * 1.925 + 11 * 0.04545 * phi ** 2 + 0.5 * rel_k + 0.4 * cap
                             - 1.0 * R + 1.5 * F])
        if k == "tool_force_ratio":
            # vertical / horizontal load on the blade, schematic (no seed anchor): powder
            # dragged down its face by the wall friction, as on the tiny scale model (0.17 on a
            # powder bed, +0.03 at d_mu = +0.4, -0.05 at -0.2; about 0 over the bare platform
            # of layer 1; the small scale model's bevel reverses the sign)
            first = c.layer == 1
            ratio = ((0.005 if first else 0.17) + (0.4 if first else 0.1) * W
                     + 0.05 * lmu + 0.02 * lmur + 0.02 * rel_k + 0.02 * cap + 0.03 * R
                     - 0.002 * (s - 1))
            return np.array([ratio])
        raise ValueError(k)  # pragma: no cover
