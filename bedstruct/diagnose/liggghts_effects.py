"""The withheld effects of LIGGGHTS-made twins: effect records, deck rewriting and LIGGGHTS' law.

What an effect is (:class:`TwinEffect`), how it is written into a LIGGGHTS deck
(:func:`apply_effect`: :func:`with_rolling_friction`, :func:`with_capillary_bridges`),
and the ``cohesion easo/capillary/viscous`` force law as LIGGGHTS 3.8 computes it
(:func:`easo_capillary_force`; see the facts listed in
:mod:`bedstruct.diagnose.external_twins`).

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["TwinEffect", "null_effect", "rolling_friction_effect", "capillary_effect",
           "wall_friction_effect", "with_rolling_friction", "with_capillary_bridges",
           "with_wall_friction", "apply_effect",
           "easo_effective_contact_angle", "easo_bridge_volume", "easo_capillary_force",
           "willett_capillary_force", "TWIN_MARK"]

#: First line of every rewritten deck (the wrapper never rewrites a deck twice).
TWIN_MARK = "# bedstruct LIGGGHTS twin effect:"
_PARTICLE_TYPE = 1          # bedstruct's decks: particles are atom type 1, walls type 2
_MODEL_ORDER = ("tangential", "cohesion", "rolling_friction", "surface")


# --------------------------------------------------------------------------- effects

@dataclass(frozen=True)
class TwinEffect:
    """The physics a LIGGGHTS twin adds to the base decks (withheld from the diagnosis).

    Attributes
    ----------
    kind : {"none", "rolling_friction", "capillary", "wall_friction"}
    rolling_friction : float
        ``rolling_friction``: the EPSD2 coefficient of particle contacts
        (replaces the base value).
    wall_friction : float
        ``wall_friction``: the sliding friction coefficient of particle-wall contacts
        (replaces the base value, the particle-particle one).
    rolling_walls : bool
        Whether particle-wall contacts get it too (the particles' shape rolls on
        walls as well; default True).
    surface_tension : float, N/m
    liquid_volume_fraction : float
        Liquid volume per particle / particle volume (LIGGGHTS'
        ``surfaceLiquidContentInitial``, which 3.8 reads as a fraction).
    contact_angle : float, rad
        Written per atom type (in degrees, as LIGGGHTS 3.8 reads it); LIGGGHTS
        3.8 uses ``theta^2 / 2`` (rad) between equal types.
    fluid_viscosity : float, Pa s
    min_separation_ratio, max_separation_ratio : float
        LIGGGHTS' ``minSeparationDistanceRatio`` (viscous cut-off) and
        ``maxSeparationDistanceRatio`` (bridges break beyond
        ``(ratio - 1)(r_i + r_j)`` at the latest).
    """

    kind: str = "none"
    rolling_friction: float = 0.0
    wall_friction: float = 0.0
    rolling_walls: bool = True
    surface_tension: float = 0.0
    liquid_volume_fraction: float = 0.0
    contact_angle: float = math.radians(20.0)
    fluid_viscosity: float = 1e-3
    min_separation_ratio: float = 1.01
    max_separation_ratio: float = 1.1

    def __post_init__(self):
        if self.kind not in ("none", "rolling_friction", "capillary", "wall_friction"):
            raise ValueError(f"TwinEffect.kind: expected 'none', 'rolling_friction', "
                             f"'capillary' or 'wall_friction'; got {self.kind!r}")
        if self.kind == "wall_friction" and not self.wall_friction >= 0:
            raise ValueError(f"wall_friction must be >= 0; got {self.wall_friction!r}")
        if self.kind == "rolling_friction" and not self.rolling_friction > 0:
            raise ValueError(f"rolling_friction must be > 0; got {self.rolling_friction!r}")
        if self.kind == "capillary":
            if not (self.surface_tension > 0 and self.liquid_volume_fraction > 0):
                raise ValueError("capillary: surface_tension and liquid_volume_fraction must be > 0")
            if not 0 <= self.contact_angle < 0.5 * math.pi:
                raise ValueError(f"contact_angle must lie in [0, pi/2) rad; got {self.contact_angle}")
            if not 1.0 < self.min_separation_ratio < self.max_separation_ratio:
                raise ValueError("need 1 < min_separation_ratio < max_separation_ratio")

    @property
    def label(self) -> str:
        """Short description (``none``, ``rolling_friction 0.25``, ``capillary 0.072 N/m ...``)."""
        if self.kind == "rolling_friction":
            return f"rolling_friction {self.rolling_friction:g}"
        if self.kind == "wall_friction":
            return f"wall_friction {self.wall_friction:g}"
        if self.kind == "capillary":
            return (f"capillary {self.surface_tension:g} N/m, liquid {self.liquid_volume_fraction:g}"
                    f", theta {math.degrees(self.contact_angle):.0f} deg")
        return "none"

    def to_dict(self) -> dict:
        """JSON-ready fields."""
        return asdict(self)


def null_effect() -> TwinEffect:
    """No effect: the twin differs from the engine by the two codes' numerics only."""
    return TwinEffect()


def rolling_friction_effect(mu_r: float, *, walls: bool = True) -> TwinEffect:
    """EPSD2 rolling friction ``mu_r`` at particle (and wall) contacts.

    Examples
    --------
    >>> rolling_friction_effect(0.25).label
    'rolling_friction 0.25'
    """
    return TwinEffect("rolling_friction", rolling_friction=float(mu_r), rolling_walls=bool(walls))


def wall_friction_effect(mu_w: float) -> TwinEffect:
    """Particle-wall sliding friction ``mu_w`` (blade, platform and box walls).

    Examples
    --------
    >>> wall_friction_effect(0.8).label
    'wall_friction 0.8'
    """
    return TwinEffect("wall_friction", wall_friction=float(mu_w))


def capillary_effect(surface_tension: float = 0.072, liquid_volume_fraction: float = 1e-3, *,
                     contact_angle: float = math.radians(20.0),
                     fluid_viscosity: float = 1e-3) -> TwinEffect:
    """LIGGGHTS ``easo/capillary/viscous`` liquid bridges (default: water, 0.1 % liquid).

    Examples
    --------
    >>> capillary_effect().label
    'capillary 0.072 N/m, liquid 0.001, theta 20 deg'
    """
    return TwinEffect("capillary", surface_tension=float(surface_tension),
                      liquid_volume_fraction=float(liquid_volume_fraction),
                      contact_angle=float(contact_angle), fluid_viscosity=float(fluid_viscosity))


# --------------------------------------------------------------------------- deck rewriting

def _fmt(x: float) -> str:
    return f"{float(x):.10g}"


def _model_tokens(tokens: list[str]) -> tuple[int, int, dict]:
    """Start/end index of the ``model ...`` words in a split line and their keyword values."""
    i = tokens.index("model")
    words = {"model": tokens[i + 1]}
    j = i + 2
    while j + 1 < len(tokens) and tokens[j] in _MODEL_ORDER:
        words[tokens[j]] = tokens[j + 1]
        j += 2
    return i, j, words


def _set_model_word(line: str, key: str, value: str | None) -> str:
    """``line`` with ``key value`` set (None: removed) in its ``model ...`` words, in LIGGGHTS' order."""
    tokens = line.split()
    i, j, words = _model_tokens(tokens)
    if value is None:
        words.pop(key, None)
    else:
        words[key] = value
    model = ["model", words["model"]]
    for k in _MODEL_ORDER:
        if k in words:
            model += [k, words[k]]
    return " ".join(tokens[:i] + model + tokens[j:])


def _deck_lines(deck: str) -> list[str]:
    lines = deck.splitlines()
    if not lines or not lines[0].startswith("# bedstruct deck for liggghts"):
        raise ValueError("not a bedstruct LIGGGHTS deck (its first line must be "
                         "'# bedstruct deck for liggghts: ...')")
    if not any(ln.startswith("pair_style gran ") for ln in lines):
        raise ValueError("deck has no 'pair_style gran' line")
    return lines


def _n_types(lines: list[str]) -> int:
    for ln in lines:
        m = re.match(r"fix\s+\S+\s+\S+\s+property/global\s+\S+\s+peratomtypepair\s+(\d+)\s", ln)
        if m:
            return int(m.group(1))
    raise ValueError("deck has no 'property/global ... peratomtypepair' line (number of atom types)")


def _set_pair_entries(lines: list[str], prop: str, value: float, touched) -> bool:
    """Set the entries ``(i, j)`` with ``touched(i, j)`` of every ``property/global prop
    peratomtypepair`` line to ``value`` (in place); False when the deck has no such line."""
    n = _n_types(lines)
    pat = re.compile(r"(fix\s+\S+\s+\S+\s+property/global\s+" + re.escape(prop)
                     + r"\s+peratomtypepair\s+)(\d+)\s+(.*)$")
    found = False
    for k, ln in enumerate(lines):
        m = pat.match(ln)
        if m:
            found = True
            vals = m.group(3).split()
            if int(m.group(2)) != n or len(vals) != n * n:
                raise ValueError(f"{prop} line has {len(vals)} values for {m.group(2)} types: {ln!r}")
            for i in range(n):
                for j in range(n):
                    if touched(i, j):
                        vals[i * n + j] = _fmt(value)
            lines[k] = f"{m.group(1)}{n} " + " ".join(vals)
    return found


def _insert_after_properties(lines: list[str], new: list[str]) -> list[str]:
    last = max(i for i, ln in enumerate(lines) if "property/global" in ln)
    return lines[:last + 1] + new + lines[last + 1:]


def with_rolling_friction(deck: str, mu_r: float, *, walls: bool = True) -> str:
    """A LIGGGHTS deck with the EPSD2 rolling friction of particle contacts set to ``mu_r``.

    The ``coefficientRollingFriction`` entries of particle-particle pairs (type
    1-1) and, with ``walls``, particle-wall pairs (1-k) are replaced; wall-wall
    entries are kept. A deck without rolling friction gets the property line and
    ``rolling_friction epsd2`` in its ``pair_style gran`` model (and in its
    ``wall/gran`` models when ``walls``).

    Examples
    --------
    >>> deck = "\\n".join(["# bedstruct deck for liggghts: test",
    ...     "fix m4 all property/global coefficientFriction peratomtypepair 2 0.4 0.4 0.4 0.4",
    ...     "fix m5 all property/global coefficientRollingFriction peratomtypepair 2 0.05 0.05 0.05 0.05",
    ...     "pair_style gran model hertz tangential history rolling_friction epsd2"])
    >>> with_rolling_friction(deck, 0.3, walls=False).splitlines()[2].split()[-4:]
    ['0.3', '0.05', '0.05', '0.05']
    """
    if not mu_r >= 0:
        raise ValueError(f"mu_r must be >= 0; got {mu_r!r}")
    lines = _deck_lines(deck)
    n = _n_types(lines)
    p = _PARTICLE_TYPE - 1

    def touched(i, j):
        return (i == p and j == p) or (walls and (i == p) != (j == p))

    if not _set_pair_entries(lines, "coefficientRollingFriction", mu_r, touched):
        vals = [_fmt(mu_r) if touched(i, j) else "0" for i in range(n) for j in range(n)]
        lines = _insert_after_properties(lines, [
            "fix twr all property/global coefficientRollingFriction peratomtypepair "
            f"{n} " + " ".join(vals)])
        for k, ln in enumerate(lines):
            if ln.startswith("pair_style gran ") or (walls and " wall/gran " in f" {ln} "
                                                     and " model " in ln):
                lines[k] = _set_model_word(ln, "rolling_friction", "epsd2")
    return "\n".join(lines) + "\n"


def with_wall_friction(deck: str, mu_w: float) -> str:
    """A LIGGGHTS deck whose particle-wall sliding friction is ``mu_w``.

    The ``coefficientFriction`` entries of particle-wall pairs (type 1 with any other
    type: blade, platform and box walls) are replaced; particle-particle and wall-wall
    entries are kept. Rolling friction is unchanged, as in the catalogue's wall-friction
    effect (``mu_w = mu + d_mu``).

    Examples
    --------
    >>> deck = "\\n".join(["# bedstruct deck for liggghts: test",
    ...     "fix m4 all property/global coefficientFriction peratomtypepair 2 0.4 0.4 0.4 0.4",
    ...     "pair_style gran model hertz tangential history"])
    >>> with_wall_friction(deck, 0.8).splitlines()[1].split()[-4:]
    ['0.4', '0.8', '0.8', '0.4']
    """
    if not mu_w >= 0:
        raise ValueError(f"mu_w must be >= 0; got {mu_w!r}")
    lines = _deck_lines(deck)
    p = _PARTICLE_TYPE - 1
    if not _set_pair_entries(lines, "coefficientFriction", mu_w, lambda i, j: (i == p) != (j == p)):
        raise ValueError("deck has no 'property/global coefficientFriction peratomtypepair' line")
    return "\n".join(lines) + "\n"


def with_capillary_bridges(deck: str, *, surface_tension: float, liquid_volume_fraction: float,
                           contact_angle: float = math.radians(20.0), fluid_viscosity: float = 1e-3,
                           min_separation_ratio: float = 1.01,
                           max_separation_ratio: float = 1.1) -> str:
    """A LIGGGHTS deck whose particle contacts carry ``easo/capillary/viscous`` liquid bridges.

    The ``pair_style gran`` model's cohesion becomes ``easo/capillary/viscous``
    (LIGGGHTS 3.8 allows one cohesion model, so particle-particle SJKR is
    dropped); ``wall/gran`` lines are left as they are (the model is
    pair-only). The model's ``property/global`` entries are added:
    ``surfaceLiquidContentInitial`` (= ``liquid_volume_fraction``),
    ``surfaceTension``, ``fluidViscosity``, ``contactAngle`` (per atom type, in
    degrees: LIGGGHTS 3.8 reads degrees; ``contact_angle`` is in rad),
    ``minSeparationDistanceRatio`` and ``maxSeparationDistanceRatio``.

    Examples
    --------
    >>> deck = "\\n".join(["# bedstruct deck for liggghts: test",
    ...     "fix m4 all property/global coefficientFriction peratomtypepair 2 0.4 0.4 0.4 0.4",
    ...     "pair_style gran model hertz tangential history cohesion sjkr rolling_friction epsd2",
    ...     "fix w all wall/gran model hertz tangential history cohesion sjkr primitive type 2 zplane 0"])
    >>> out = with_capillary_bridges(deck, surface_tension=0.072, liquid_volume_fraction=1e-3)
    >>> [ln for ln in out.splitlines() if ln.startswith("pair_style")]
    ['pair_style gran model hertz tangential history cohesion easo/capillary/viscous rolling_friction epsd2']
    >>> "cohesion sjkr" in out.splitlines()[-1]      # the wall model keeps SJKR
    True
    """
    lines = _deck_lines(deck)
    n = _n_types(lines)
    props = [
        f"fix twc1 all property/global surfaceLiquidContentInitial scalar {_fmt(liquid_volume_fraction)}",
        f"fix twc2 all property/global surfaceTension scalar {_fmt(surface_tension)}",
        f"fix twc3 all property/global fluidViscosity scalar {_fmt(fluid_viscosity)}",
        "fix twc4 all property/global contactAngle peratomtype "
        + " ".join([_fmt(math.degrees(contact_angle))] * n),
        f"fix twc5 all property/global minSeparationDistanceRatio scalar {_fmt(min_separation_ratio)}",
        f"fix twc6 all property/global maxSeparationDistanceRatio scalar {_fmt(max_separation_ratio)}",
    ]
    lines = _insert_after_properties(lines, props)
    for k, ln in enumerate(lines):
        if ln.startswith("pair_style gran "):
            lines[k] = _set_model_word(ln, "cohesion", "easo/capillary/viscous")
    return "\n".join(lines) + "\n"


def apply_effect(deck: str, effect: TwinEffect) -> str:
    """Apply a :class:`TwinEffect` to a bedstruct LIGGGHTS deck; the result starts with
    :data:`TWIN_MARK` and the effect (a null effect changes nothing else).

    Examples
    --------
    >>> deck = "# bedstruct deck for liggghts: x\\npair_style gran model hertz tangential history\\n"
    >>> apply_effect(deck, null_effect()).splitlines()[:2]
    ['# bedstruct LIGGGHTS twin effect: none', '# bedstruct deck for liggghts: x']
    """
    if effect.kind == "rolling_friction":
        out = with_rolling_friction(deck, effect.rolling_friction, walls=effect.rolling_walls)
    elif effect.kind == "wall_friction":
        out = with_wall_friction(deck, effect.wall_friction)
    elif effect.kind == "capillary":
        out = with_capillary_bridges(
            deck, surface_tension=effect.surface_tension,
            liquid_volume_fraction=effect.liquid_volume_fraction,
            contact_angle=effect.contact_angle, fluid_viscosity=effect.fluid_viscosity,
            min_separation_ratio=effect.min_separation_ratio,
            max_separation_ratio=effect.max_separation_ratio)
    else:
        _deck_lines(deck)
        out = deck if deck.endswith("\n") else deck + "\n"
    return f"{TWIN_MARK} {effect.label}\n{out}"


# --------------------------------------------------------------------------- LIGGGHTS' law

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


def easo_bridge_volume(r_i, r_j, liquid_volume_fraction: float):
    """Bridge volume (m^3) of LIGGGHTS 3.8's easo model between spheres of radii ``r_i``, ``r_j``.

    Each particle gives ``V_p (1 - sqrt(1 - r_o^2 / (r_i + r_j)^2)) / 2`` of its
    liquid ``V_p = (4/3) pi r^3 liquid_volume_fraction`` (``r_o`` the other radius).

    Examples
    --------
    >>> v = easo_bridge_volume(1.0, 1.0, 1.0)
    >>> round(float(v) / (4 / 3 * math.pi), 4)   # 1 - sqrt(3)/2 of one particle's volume
    0.134
    """
    r_i, r_j = np.asarray(r_i, float), np.asarray(r_j, float)
    rs = r_i + r_j
    vi = 4.0 / 3.0 * np.pi * r_i ** 3 * liquid_volume_fraction
    vj = 4.0 / 3.0 * np.pi * r_j ** 3 * liquid_volume_fraction
    return 0.5 * vi * (1 - np.sqrt(1 - r_j ** 2 / rs ** 2)) + 0.5 * vj * (1 - np.sqrt(1 - r_i ** 2 / rs ** 2))


def easo_capillary_force(gap, r_i: float, r_j: float, *, surface_tension: float,
                         liquid_volume_fraction: float, contact_angle: float = math.radians(20.0),
                         max_separation_ratio: float = 1.1):
    """Attractive capillary force (N, positive) of LIGGGHTS 3.8's easo model (Soulie's law).

    ``F = pi gamma sqrt(r_i r_j) (exp(A s / R_2 + B) + C)`` with ``V* = V / R_2^3``,
    ``A = -1.1 V*^-0.53``, ``B = (-0.148 ln V* - 0.96) theta^2 - 0.0082 ln V* + 0.48``,
    ``C = 0.0018 ln V* + 0.078``, ``s = max(gap, 0)``, ``theta`` the effective angle
    (:func:`easo_effective_contact_angle` of two equal angles) and ``V``
    :func:`easo_bridge_volume`; zero beyond the rupture distance
    ``(1 + theta/2) V^(1/3)`` or the cut-off ``(max_separation_ratio - 1)(r_i + r_j)``.
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
