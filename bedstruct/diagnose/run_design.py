"""The design of a run library: which simulator runs a diagnosis is served by.

:func:`design_spec` states the box of the varied base parameters (inside their physical
bounds, :data:`PHYSICAL_BOUNDS`), the catalogue effects and the sizes; :func:`design_points`
lays the points out. The design is space-filling: a Latin hypercube optimised for centred
discrepancy (:class:`scipy.stats.qmc.LatinHypercube`) over the box of the varied base
parameters (every effect off), and one such hypercube per catalogue effect over the base
box times the effect's prior range (one effect on at a time), plus anchor points the
diagnosis always asks for (the base point and each effect at half and full top of its
prior, at the base parameters). Every point is run at the same replicate seeds (common
random numbers, as the diagnosis runs them), whose scatter is the run-to-run noise.
:mod:`bedstruct.diagnose.run_library` runs a design into a folder.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.stats import qmc

from ..errors import ConfigError
from .catalogue import Effect, catalogue as _catalogue

__all__ = ["DesignSpec", "DesignPoint", "design_spec", "design_points", "PHYSICAL_BOUNDS"]


#: Physical bounds of the base parameters a design may vary (SI): cohesion energy density
#: (J/m^3), sliding and rolling friction coefficients (1) and restitution (1).
PHYSICAL_BOUNDS: dict[str, tuple[float, float]] = {
    "cohesion_energy_density": (0.0, math.inf),
    "friction": (0.0, math.inf),
    "rolling_friction": (0.0, math.inf),
    "restitution": (0.0, 1.0),
}


# ----------------------------------------------------------------------------- design
@dataclass(frozen=True)
class DesignSpec:
    """What a run library holds: the box of the varied parameters, the effects, the sizes.

    Parameters
    ----------
    base : dict of str to float
        Base parameters of the model (SI); those not in ``ranges`` are held at these values.
    ranges : dict of str to (float, float)
        Range ``(lo, hi)`` of each varied base parameter (SI), inside its physical bounds
        (:data:`PHYSICAL_BOUNDS`) and containing the base value.
    effects : tuple of str
        Catalogue effects, each varied over its prior range with the others off.
    priors : dict of str to (float, float)
        Magnitude range of each effect (its catalogue prior).
    n_base : int
        Space-filling points of the base sub-design (every effect off).
    n_per_effect : int
        Space-filling points of each effect's sub-design.
    replicates : int
        Seeds per point (``seed, seed + 1, ...``).
    seed : int
        First replicate seed, and the seed of the hypercubes.
    anchors : bool
        Add the base point and each effect at half and full top of its prior (the points
        a diagnosis always simulates).
    """

    base: dict
    ranges: dict
    effects: tuple
    priors: dict
    n_base: int = 16
    n_per_effect: int = 16
    replicates: int = 3
    seed: int = 0
    anchors: bool = True

    @property
    def varied(self) -> tuple[str, ...]:
        """Names of the varied base parameters, in input order."""
        return tuple(self.ranges)

    @property
    def input_names(self) -> tuple[str, ...]:
        """Emulator inputs: the varied base parameters, then the effect magnitudes."""
        return self.varied + tuple(self.effects)

    @property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corner of the design box over :attr:`input_names`."""
        lo = [self.ranges[k][0] for k in self.varied] + [self.priors[e][0] for e in self.effects]
        hi = [self.ranges[k][1] for k in self.varied] + [self.priors[e][1] for e in self.effects]
        return np.asarray(lo, float), np.asarray(hi, float)

    @property
    def seeds(self) -> tuple[int, ...]:
        return tuple(int(self.seed) + r for r in range(int(self.replicates)))

    def to_json(self) -> dict:
        return {"base": dict(self.base), "ranges": {k: list(v) for k, v in self.ranges.items()},
                "effects": list(self.effects), "priors": {k: list(v) for k, v in self.priors.items()},
                "n_base": self.n_base, "n_per_effect": self.n_per_effect,
                "replicates": self.replicates, "seed": self.seed, "anchors": self.anchors}

    @classmethod
    def from_json(cls, d: Mapping) -> "DesignSpec":
        return cls(base={k: float(v) for k, v in d["base"].items()},
                   ranges={k: (float(v[0]), float(v[1])) for k, v in d["ranges"].items()},
                   effects=tuple(d["effects"]),
                   priors={k: (float(v[0]), float(v[1])) for k, v in d["priors"].items()},
                   n_base=int(d["n_base"]), n_per_effect=int(d["n_per_effect"]),
                   replicates=int(d["replicates"]), seed=int(d["seed"]), anchors=bool(d["anchors"]))


def design_spec(base: Mapping[str, float], *, vary: Mapping[str, Any] | None = None,
                effects: Sequence[Effect | str] | None = None, n_base: int = 16,
                n_per_effect: int = 16, replicates: int = 3, seed: int = 0,
                anchors: bool = True) -> DesignSpec:
    """The design of a run library around ``base``.

    Parameters
    ----------
    base : mapping of str to float
        Base parameters of the calibrated model (SI), e.g.
        :data:`~bedstruct.diagnose.BASE_PARAMETERS`.
    vary : mapping, optional
        Base parameters the design varies (those a diagnosis recalibrates), each to a
        range ``(lo, hi)`` in SI units or to a relative half-width ``r`` (the range
        ``base * (1 - r), base * (1 + r)``). Default: the cohesion energy density by
        +-25 % (the diagnosis' default recalibration).
    effects : sequence of Effect or str, optional
        Catalogue effects (default: all), each varied over its prior range.
    n_base, n_per_effect : int
        Space-filling points of the base sub-design and of each effect's sub-design.
    replicates : int
        Seeds per point (>= 2: their scatter is the run-to-run noise).
    seed : int
        First replicate seed and seed of the hypercubes.
    anchors : bool
        Add the base point and each effect at half and full top of its prior.

    Returns
    -------
    DesignSpec

    Raises
    ------
    ConfigError
        A range outside a parameter's physical bounds, not containing its base value, or
        of an unknown parameter; fewer than two replicates.

    Examples
    --------
    >>> from bedstruct.diagnose import BASE_PARAMETERS
    >>> spec = design_spec(BASE_PARAMETERS, vary={"cohesion_energy_density": 0.25,
    ...                                           "friction": (0.3, 0.5)},
    ...                    effects=["wall_friction"], n_base=8, n_per_effect=8)
    >>> spec.input_names
    ('cohesion_energy_density', 'friction', 'wall_friction')
    >>> [float(x) for x in spec.box[0]]
    [27000000.0, 0.3, -0.2]
    """
    base = {k: float(v) for k, v in base.items()}
    vary = {"cohesion_energy_density": 0.25} if vary is None else dict(vary)
    ranges = {}
    for k, r in vary.items():
        if k not in base:
            raise ConfigError(f"vary: parameter {k!r} is not among the base parameters {sorted(base)}")
        if np.ndim(r) == 0:
            r = float(r)
            if not 0 < r:
                raise ConfigError(f"vary: relative half-width of {k!r} must be > 0; got {r}")
            lo, hi = base[k] - r * abs(base[k]), base[k] + r * abs(base[k])
        else:
            lo, hi = (float(x) for x in r)
        plo, phi = PHYSICAL_BOUNDS.get(k, (-math.inf, math.inf))
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ConfigError(f"vary: range of {k!r} must be finite with lo < hi; got ({lo}, {hi})")
        if lo < plo or hi > phi:
            raise ConfigError(f"vary: range of {k!r} ({lo:.6g}, {hi:.6g}) leaves its physical "
                              f"bounds ({plo}, {phi})")
        if not lo <= base[k] <= hi:
            raise ConfigError(f"vary: range of {k!r} ({lo:.6g}, {hi:.6g}) does not contain the "
                              f"base value {base[k]:.6g}")
        ranges[k] = (lo, hi)
    effs = tuple(_catalogue() if effects is None else
                 (_catalogue([e])[0] if isinstance(e, str) else e for e in effects))
    if int(replicates) < 2:
        raise ConfigError(f"replicates: need >= 2 seeds per point (their scatter is the run-to-run "
                          f"noise); got {replicates}")
    if int(n_base) < 0 or int(n_per_effect) < 0:
        raise ConfigError("n_base, n_per_effect: expected whole numbers >= 0")
    return DesignSpec(base=base, ranges=ranges, effects=tuple(e.name for e in effs),
                      priors={e.name: (float(e.prior[0]), float(e.prior[1])) for e in effs},
                      n_base=int(n_base), n_per_effect=int(n_per_effect),
                      replicates=int(replicates), seed=int(seed), anchors=bool(anchors))


@dataclass(frozen=True)
class DesignPoint:
    """One parameter point of a design (run at every replicate seed).

    Attributes
    ----------
    base : dict
        Base parameters of the run (SI; all of the spec's base, varied ones set).
    effects : dict
        The one effect switched on and its magnitude (empty: the base model).
    group : str
        ``"anchor"``, ``"base"`` or the effect's name (its sub-design).
    """

    base: dict
    effects: dict
    group: str


def _hypercube(d: int, n: int, seed: int) -> np.ndarray:
    if n == 0:
        return np.zeros((0, d))
    lhs = qmc.LatinHypercube(d, optimization="random-cd", rng=np.random.default_rng(seed))
    return lhs.random(n)


def design_points(spec: DesignSpec) -> tuple[DesignPoint, ...]:
    """The parameter points of a design, in a fixed order.

    Returns
    -------
    tuple of DesignPoint
        Anchors first (if any), then the base sub-design, then each effect's.

    Examples
    --------
    >>> from bedstruct.diagnose import BASE_PARAMETERS
    >>> spec = design_spec(BASE_PARAMETERS, effects=["wall_friction"], n_base=4, n_per_effect=4)
    >>> pts = design_points(spec)
    >>> len(pts), [p.group for p in pts][:4]
    (11, ['anchor', 'anchor', 'anchor', 'base'])
    >>> all(-0.2 <= p.effects.get("wall_friction", 0.0) <= 0.4 for p in pts)
    True
    """
    varied = spec.varied
    lo = np.asarray([spec.ranges[k][0] for k in varied], float)
    hi = np.asarray([spec.ranges[k][1] for k in varied], float)
    out: list[DesignPoint] = []
    if spec.anchors:
        out.append(DesignPoint(dict(spec.base), {}, "anchor"))
        for e in spec.effects:
            top = spec.priors[e][1]
            for m in (0.5 * top, top):
                out.append(DesignPoint(dict(spec.base), {e: float(m)}, "anchor"))

    def at(u):
        b = dict(spec.base)
        b.update({k: float(v) for k, v in zip(varied, lo + u * (hi - lo))})
        return b

    if varied:
        for u in _hypercube(len(varied), spec.n_base, spec.seed):
            out.append(DesignPoint(at(u), {}, "base"))
    for j, e in enumerate(spec.effects):
        elo, ehi = spec.priors[e]
        for u in _hypercube(len(varied) + 1, spec.n_per_effect, spec.seed + 1 + j):
            out.append(DesignPoint(at(u[:-1]), {e: float(elo + u[-1] * (ehi - elo))}, e))
    return tuple(out)
