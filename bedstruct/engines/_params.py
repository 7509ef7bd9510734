"""The SI contact parameters that every deck takes: :class:`GranularParams` and the
normaliser :func:`as_granular_params` (from a mapping or the embedded engine's
``ContactModel``).

Everything here is plain Python; no engine is needed to import it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError

__all__ = ["GranularParams", "as_granular_params", "ROLLING_MODELS"]


# --------------------------------------------------------------------------- parameters
#: Rolling resistance models an external deck can state.
ROLLING_MODELS = ("epsd2", "epsd", "cdt")


@dataclass(frozen=True)
class GranularParams:
    """The seed's contact model in SI units, as every deck generator takes it.

    One particle type (type 1); the walls use atom type 2 in LIGGGHTS decks so
    that their coefficients can differ. ``wall_*`` values default to the
    particle-particle ones.

    Parameters
    ----------
    youngs_modulus : float, Pa
        Young's modulus E of particles (and walls unless ``wall_youngs_modulus``).
    poisson_ratio : float, dimensionless
    density : float, kg/m^3
    restitution : float, dimensionless
        Normal coefficient of restitution e in (0, 1].
    friction : float, dimensionless
        Coulomb sliding friction mu.
    rolling_friction : float, dimensionless
        Rolling friction mu_r (0 disables it).
    rolling_model : {"epsd2", "epsd", "cdt"}
        Rolling resistance model: LIGGGHTS ``rolling_friction epsd2|epsd|cdt``; LAMMPS
        realises ``epsd2`` (as ``rolling sds``) only and refuses the others.
    cohesion_energy_density : float, J/m^3
        SJKR cohesion energy density k (0 disables cohesion).
    rolling_damping : float, dimensionless
        Viscous damping ratio of the ``epsd`` rolling model (LIGGGHTS
        ``coefficientRollingViscousDamping``; the embedded engine's ``rolling_damping``).
    gravity : float, m/s^2
        Magnitude of gravity along -z (0 disables it).
    wall_youngs_modulus, wall_poisson_ratio, wall_restitution, wall_friction,
    wall_rolling_friction, wall_cohesion_energy_density : float or None
        Particle-wall values (None: same as particle-particle).

    Examples
    --------
    >>> p = GranularParams(youngs_modulus=1e7, restitution=0.1)
    >>> p.wall("friction"), p.effective_youngs_modulus()
    (0.4, 5494505.494505495)
    """

    youngs_modulus: float = 1.0e7
    poisson_ratio: float = 0.3
    density: float = 8300.0
    restitution: float = 0.1
    friction: float = 0.4
    rolling_friction: float = 0.05
    cohesion_energy_density: float = 0.0
    gravity: float = 9.81
    wall_youngs_modulus: float | None = None
    wall_poisson_ratio: float | None = None
    wall_restitution: float | None = None
    wall_friction: float | None = None
    wall_rolling_friction: float | None = None
    wall_cohesion_energy_density: float | None = None
    rolling_model: str = "epsd2"
    rolling_damping: float = 0.3

    def __post_init__(self):
        if self.rolling_model not in ROLLING_MODELS:
            raise ValueError(f"`rolling_model` must be one of {', '.join(ROLLING_MODELS)}; "
                             f"got {self.rolling_model!r}")
        def check(name, lo, hi, lo_open=False):
            v = getattr(self, name)
            if v is None:
                return
            ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi
            if not ok:
                br = "(" if lo_open else "["
                raise ValueError(f"`{name}` must lie in {br}{lo}, {hi}]; got {v!r}")
        for name in ("youngs_modulus", "density", "wall_youngs_modulus"):
            check(name, 0.0, math.inf, lo_open=True)
        for name in ("poisson_ratio", "wall_poisson_ratio"):
            check(name, -1.0, 0.4999999)
        for name in ("restitution", "wall_restitution"):
            check(name, 0.0, 1.0, lo_open=True)
        for name in ("friction", "rolling_friction", "cohesion_energy_density", "gravity",
                     "rolling_damping",
                     "wall_friction", "wall_rolling_friction", "wall_cohesion_energy_density"):
            check(name, 0.0, math.inf)

    def wall(self, name: str) -> float:
        """Particle-wall value of ``name`` (e.g. ``"friction"``), defaulting to the particle one."""
        v = getattr(self, "wall_" + name)
        return getattr(self, name) if v is None else v

    def effective_youngs_modulus(self) -> float:
        """Particle-particle Hertz E* = E / (2 (1 - nu^2)) (Pa)."""
        return self.youngs_modulus / (2.0 * (1.0 - self.poisson_ratio ** 2))


def as_granular_params(model=None, **overrides) -> GranularParams:
    """Normalise contact parameters to :class:`GranularParams`.

    Parameters
    ----------
    model : GranularParams, mapping, bedstruct.dem ContactModel or None
        A mapping uses :class:`GranularParams` field names. An engine
        ``ContactModel`` (one particle type, ``materials``, ``restitution``,
        ``friction``, ``rolling_friction``, ``cohesion``, ``wall_*``) is
        converted; ``gravity`` then comes from ``overrides`` or the default.
    **overrides
        Field values that replace those of ``model``.

    Returns
    -------
    GranularParams

    Raises
    ------
    ValueError
        For an unknown key, or a multi-type ContactModel (the external decks
        support one particle type).
    bedstruct.errors.ConfigError
        For a ContactModel with what no contact parameter states: a rolling model
        no deck writes, capillary bridges or contact ageing (a dialect writes its own
        model of an effect: :meth:`~bedstruct.engines.Dialect.with_effects`).
    TypeError
        For an object of another kind.

    Examples
    --------
    >>> as_granular_params({"restitution": 0.5}, friction=0.3).friction
    0.3
    """
    names = {f.name for f in fields(GranularParams)}
    if model is None:
        base: dict[str, Any] = {}
    elif isinstance(model, GranularParams):
        base = {f: getattr(model, f) for f in names}
    elif isinstance(model, Mapping):
        base = dict(model)
    elif hasattr(model, "materials") and hasattr(model, "restitution"):
        mats = model.materials
        mats = tuple(mats) if isinstance(mats, (list, tuple)) else (mats,)
        if len(mats) != 1:
            raise ValueError(f"external decks support one particle type; the model has {len(mats)}")

        def scalar(name, v):
            if v is None:
                return None
            arr = np.asarray(v, dtype=np.float64)
            if arr.size != 1:
                raise ValueError(f"`{name}` must be a single value for one particle type; got {arr.shape}")
            return float(arr.reshape(-1)[0])
        m0 = mats[0]
        base = dict(youngs_modulus=m0.youngs_modulus, poisson_ratio=m0.poisson_ratio,
                    density=m0.density, restitution=scalar("restitution", model.restitution),
                    friction=scalar("friction", model.friction),
                    rolling_friction=scalar("rolling_friction", model.rolling_friction),
                    cohesion_energy_density=scalar("cohesion", model.cohesion),
                    wall_restitution=scalar("wall_restitution", getattr(model, "wall_restitution", None)),
                    wall_friction=scalar("wall_friction", getattr(model, "wall_friction", None)),
                    wall_rolling_friction=scalar("wall_rolling_friction",
                                                 getattr(model, "wall_rolling_friction", None)),
                    wall_cohesion_energy_density=scalar("wall_cohesion",
                                                        getattr(model, "wall_cohesion", None)))
        rm = getattr(model, "rolling_model", "epsd2")
        if rm not in ("none", *ROLLING_MODELS) and base["rolling_friction"]:
            raise ConfigError(f"external decks state rolling models {', '.join(ROLLING_MODELS)}; "
                              f"got {rm!r}")
        if rm in ROLLING_MODELS:
            base["rolling_model"] = rm
        if getattr(model, "rolling_damping", None) is not None:
            base["rolling_damping"] = float(model.rolling_damping)
        embedded_only = [k for k in ("capillary", "contact_ageing") if getattr(model, k, False)]
        if embedded_only:
            raise ConfigError(f"contact parameters cannot carry the model's "
                              f"{' and '.join(embedded_only)} (the embedded engine's models); an "
                              "engine with its own model writes it through its dialect: "
                              "Dialect.with_effects (LIGGGHTS' liquid bridges, "
                              "bedstruct.engines.LiquidBridges)")
        if rm == "none":
            base["rolling_friction"] = 0.0
        wm = getattr(model, "wall_material", None)
        if wm is not None:
            base["wall_youngs_modulus"] = wm.youngs_modulus
            base["wall_poisson_ratio"] = wm.poisson_ratio
    else:
        raise TypeError("`model` must be GranularParams, a mapping of its fields or a "
                        f"bedstruct.dem ContactModel; got {type(model).__name__}")
    base.update(overrides)
    unknown = set(base) - names
    if unknown:
        raise ValueError(f"unknown contact parameter(s) {sorted(unknown)}; expected some of "
                         f"{sorted(names)}")
    return GranularParams(**base)
