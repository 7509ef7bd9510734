"""Physical bounds of the base contact parameters that recalibration may change.

A recalibration shift is fitted within these bounds (bounded least squares), so the
diagnosis never answers with a negative cohesion or a restitution above one; a fit that
ends on a bound says so. The bounds of the catalogue effects' magnitudes are their priors
(:attr:`bedstruct.diagnose.catalogue.Effect.prior`). A simulation configuration may narrow
a parameter's bounds (``[recalibrate] bounds``), never widen them past the physical ones.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from typing import Mapping

from ..errors import ConfigError

__all__ = ["PARAMETER_BOUNDS", "PARAMETER_UNITS", "parameter_bounds", "parameter_value_error"]

#: Physical bounds (lower, upper) of each base parameter, in its SI unit.
PARAMETER_BOUNDS: dict[str, tuple[float, float]] = {
    "cohesion_energy_density": (0.0, math.inf),   # J/m^3: cohesion attracts, never repels
    "friction": (0.0, math.inf),                  # sliding friction coefficient
    "rolling_friction": (0.0, math.inf),          # rolling friction coefficient
    "restitution": (0.0, 1.0),                    # coefficient of restitution, (0, 1]
}

#: Parameters whose lower bound is not a physical value (a restitution of 0, a perfectly
#: plastic contact, is refused by the engine): only a value above it is a base value.
OPEN_BELOW = frozenset({"restitution"})

#: Unit of each base parameter (as written in reports).
PARAMETER_UNITS: dict[str, str] = {"cohesion_energy_density": "J/m³", "friction": "",
                                   "rolling_friction": "", "restitution": ""}


def parameter_bounds(names, overrides: Mapping[str, tuple[float, float]] | None = None
                     ) -> dict[str, tuple[float, float]]:
    """Bounds of the parameters ``names``: the physical ones, narrowed by ``overrides``.

    Parameters
    ----------
    names : sequence of str
        Base parameters (SI units, as :data:`PARAMETER_BOUNDS`).
    overrides : mapping of str to (float, float), optional
        Narrower bounds per parameter (the configuration's ``[recalibrate] bounds``).

    Returns
    -------
    dict of str to (float, float)
        Lower and upper bound of each name; ``(-inf, inf)`` for a parameter without
        physical bounds (one the catalogue does not know, e.g. in a toy model).

    Raises
    ------
    ConfigError
        If an override is not two numbers ``lo < hi`` inside the physical bounds.

    Examples
    --------
    >>> parameter_bounds(["cohesion_energy_density", "restitution"])
    {'cohesion_energy_density': (0.0, inf), 'restitution': (0.0, 1.0)}
    >>> parameter_bounds(["friction"], {"friction": (0.2, 0.8)})
    {'friction': (0.2, 0.8)}
    """
    overrides = dict(overrides or {})
    unknown = set(overrides) - set(names)
    if unknown:
        raise ConfigError(f"[recalibrate] bounds: {sorted(unknown)[0]!r} is not a recalibrated "
                          f"parameter (recalibrated: {', '.join(names)})")
    out = {}
    for name in names:
        lo, hi = PARAMETER_BOUNDS.get(name, (-math.inf, math.inf))
        if name in overrides:
            try:
                olo, ohi = (float(v) for v in overrides[name])
            except (TypeError, ValueError):
                raise ConfigError(f"[recalibrate] bounds: {name!r}: expected [lower, upper]; "
                                  f"got {overrides[name]!r}") from None
            if not (lo <= olo < ohi <= hi):
                raise ConfigError(f"[recalibrate] bounds: {name!r}: expected lower < upper "
                                  f"within the physical bounds [{lo:g}, {hi:g}]; "
                                  f"got [{olo:g}, {ohi:g}]")
            lo, hi = olo, ohi
        out[name] = (float(lo), float(hi))
    return out


def parameter_value_error(name: str, value, *, closed: bool = False) -> str:
    """Why ``value`` is not a physical value of the base parameter ``name`` ('' when it is).

    Parameters
    ----------
    name : str
        A base parameter; one without physical bounds only needs a finite value.
    value : float
        Its value (SI).
    closed : bool
        Accept the lower bound of a parameter in :data:`OPEN_BELOW` too (a simulator
        asked at the edge of a recalibration's range).

    Returns
    -------
    str
        Empty when the value is finite and within :data:`PARAMETER_BOUNDS`, else what
        was expected.

    Examples
    --------
    >>> parameter_value_error("friction", 0.0)
    ''
    >>> parameter_value_error("restitution", 1.5)
    'expected 0 < restitution <= 1; got 1.5'
    >>> parameter_value_error("cohesion_energy_density", float("inf"))
    'expected a finite number >= 0 J/m³; got inf'
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        return f"expected a number; got {value!r}"
    lo, hi = PARAMETER_BOUNDS.get(name, (-math.inf, math.inf))
    unit = PARAMETER_UNITS.get(name, "")
    u = f" {unit}" if unit else ""
    open_lo = name in OPEN_BELOW and not closed
    if math.isfinite(v) and (lo < v if open_lo else lo <= v) and v <= hi:
        return ""
    if math.isinf(hi):
        what = "a finite number" if math.isinf(lo) else f"a finite number {'>' if open_lo else '>='} {lo:g}"
        return f"expected {what}{u}; got {v:g}"
    return f"expected {lo:g} {'<' if open_lo else '<='} {name} <= {hi:g}{u}; got {v:g}"
