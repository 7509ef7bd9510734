"""LIGGGHTS 3.8's liquid-bridge law (``cohesion easo/capillary/viscous``) and Willett's.

The force, bridge volume and contact angle LIGGGHTS 3.8 computes, as measured on
two-sphere runs (tests/diagnose/test_external_twins.py), and Willett's closed form
that the embedded engine implements, for comparison. The LIGGGHTS decks write the
bridges through :class:`bedstruct.engines.LiquidBridges` (config ``contact.capillary``
on ``engine = "liggghts"``).

LIGGGHTS 3.8 (Debian) facts:

- a ``pair_style gran`` model has **one** cohesion model: the liquid bridges
  *replace* the particle-particle SJKR cohesion (walls keep theirs; the easo
  model is not allowed on walls);
- the capillary force is Soulie's law (:func:`easo_capillary_force`),
  ``F = pi gamma sqrt(r_i r_j) (exp(A s / R_2 + B) + C)`` for a gap ``s`` and the
  larger radius ``R_2``; the bridge forms on contact and breaks at
  ``min((1 + theta/2) V^(1/3), (maxSeparationDistanceRatio - 1)(r_i + r_j))``;
- ``surfaceLiquidContentInitial`` is read as a liquid/solid volume *fraction*
  (the manual says per cent), and the bridge volume is
  ``V = sum_i V_i (1 - sqrt(1 - r_j^2 / (r_i + r_j)^2)) / 2`` (the manual says
  ``0.05 (V_i + V_j)``): :func:`bedstruct.engines.easo_bridge_volume`;
- a bridge holding less than ``1e-17`` m^3 (``1000 V < 1e-14`` in SI) is skipped: no
  force at all (:data:`bedstruct.engines.EASO_MIN_BRIDGE_VOLUME`);
- the effective contact angle is ``theta_i theta_j / 2`` (the manual says the
  mean): :func:`easo_effective_contact_angle`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math

import numpy as np

from ...engines import EASO_MIN_BRIDGE_VOLUME, easo_bridge_volume

__all__ = ["easo_effective_contact_angle", "easo_capillary_force",
           "willett_capillary_force"]


def easo_effective_contact_angle(theta_i: float, theta_j: float) -> float:
    """The contact angle LIGGGHTS 3.8's easo model uses: ``theta_i theta_j / 2`` (rad).

    The manual states the mean; the 3.8 binary converts the per-type angles
    from degrees and takes the half product (measured on two-sphere runs with
    40 and 0.35 degrees, tests/diagnose/test_external_twins.py).

    Examples
    --------
    >>> easo_effective_contact_angle(0.4, 0.4)
    0.08000000000000002
    """
    return 0.5 * float(theta_i) * float(theta_j)


def easo_capillary_force(gap, r_i: float, r_j: float, *, surface_tension: float,
                         liquid_volume_fraction: float, contact_angle: float = math.radians(20.0),
                         max_separation_ratio: float = 1.1):
    """Attractive capillary force (N, positive) of LIGGGHTS 3.8's easo model (Soulie's law).

    ``F = pi gamma sqrt(r_i r_j) (exp(A s / R_2 + B) + C)`` with ``V* = V / R_2^3``,
    ``A = -1.1 V*^-0.53``, ``B = (-0.148 ln V* - 0.96) theta^2 - 0.0082 ln V* + 0.48``,
    ``C = 0.0018 ln V* + 0.078``, ``s = max(gap, 0)``, ``theta`` the effective angle
    (:func:`easo_effective_contact_angle` of two equal angles) and ``V``
    :func:`bedstruct.engines.easo_bridge_volume`; zero beyond the rupture distance
    ``(1 + theta/2) V^(1/3)`` or the cut-off ``(max_separation_ratio - 1)(r_i + r_j)``, and
    zero everywhere for a bridge smaller than :data:`bedstruct.engines.EASO_MIN_BRIDGE_VOLUME`.
    (A bridge exists only once the spheres have touched.)

    Examples
    --------
    >>> f0 = easo_capillary_force(0.0, 50e-6, 50e-6, surface_tension=0.072, liquid_volume_fraction=1.0)
    >>> round(float(f0) * 1e6, 2)    # uN
    19.18
    """
    gap = np.asarray(gap, dtype=float)
    theta = easo_effective_contact_angle(contact_angle, contact_angle)
    r2 = max(r_i, r_j)
    vol = float(easo_bridge_volume(r_i, r_j, liquid_volume_fraction))
    vs = vol / r2 ** 3
    a = -1.1 * vs ** -0.53
    b = (-0.148 * math.log(vs) - 0.96) * theta ** 2 - 0.0082 * math.log(vs) + 0.48
    c = 0.0018 * math.log(vs) + 0.078
    s = np.maximum(gap, 0.0)
    f = math.pi * surface_tension * math.sqrt(r_i * r_j) * (np.exp(a * s / r2 + b) + c)
    rupture = min((1 + 0.5 * theta) * vol ** (1.0 / 3.0), (max_separation_ratio - 1) * (r_i + r_j))
    if vol < EASO_MIN_BRIDGE_VOLUME:
        return np.zeros_like(f)
    return np.where(gap < rupture, f, 0.0)


def willett_capillary_force(gap, r_i: float, r_j: float, *, surface_tension: float,
                            volume: float, contact_angle: float = math.radians(20.0)):
    """Willett et al. (2000) closed form, ``2 pi R gamma cos(theta) / (1 + 2.1 S + 10 S^2)``.

    ``R = 2 r_i r_j / (r_i + r_j)``, ``S = (s / 2) sqrt(R / V)`` (no rupture
    applied): the law the embedded engine implements, for comparison.

    Examples
    --------
    >>> round(float(willett_capillary_force(0.0, 1.0, 1.0, surface_tension=1.0, volume=1e-3,
    ...                                     contact_angle=0.0)), 4)
    6.2832
    """
    R = 2.0 * r_i * r_j / (r_i + r_j)
    S = 0.5 * np.maximum(np.asarray(gap, float), 0.0) * math.sqrt(R / volume)
    return 2 * math.pi * R * surface_tension * math.cos(contact_angle) / (1 + 2.1 * S + 10 * S ** 2)
