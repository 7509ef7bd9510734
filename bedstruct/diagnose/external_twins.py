"""Validation twins whose "real" data come from LIGGGHTS, not from bedstruct's own engine.

The synthetic twins of :mod:`bedstruct.diagnose.validate` are made with the
same simulator the diagnosis uses, so they cannot test what matters most with
real data: a gap that is partly the two codes' different numerics. A LIGGGHTS
twin is made like this:

1. The decks come from the public external workflows
   (:func:`bedstruct.workflows.run_repose` / ``run_spread`` with
   ``engine = "liggghts"``, i.e. :mod:`bedstruct.workflows.external`), run on one
   MPI rank.
2. The withheld effect is added by a documented transformation of each deck
   (:func:`apply_effect`): a larger EPSD2 rolling friction coefficient
   (:func:`with_rolling_friction`), LIGGGHTS' ``cohesion easo/capillary/viscous``
   liquid bridges (:func:`with_capillary_bridges`), or nothing (a null twin).
   The workflow is pointed (``external.exe``) at a small wrapper executable
   (:func:`write_liggghts_wrapper`) that rewrites the deck it is asked to run,
   keeps the original as ``<deck>.base`` and then runs the real LIGGGHTS.
3. The runs are observed by the engine simulator's own observation operators
   (:class:`bedstruct.workflows.diagnosis_sim.EngineSimulator` with the
   LIGGGHTS engine; :func:`liggghts_simulator`), on several seeds (an experiment
   repeated ``n`` times), reading noise is drawn from the design's stated
   uncertainties, and the result is written as a measurement TOML file
   (:func:`make_liggghts_twin`). The diagnosis sees only that file; the truth is
   kept in ``truth.json`` beside it.

LIGGGHTS 3.8 (Debian) facts this module relies on, checked on a two-sphere run
(tests/diagnose/test_external_twins.py):

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
  ``0.05 (V_i + V_j)``);
- the effective contact angle is ``theta_i theta_j / 2`` (the manual says the
  mean): :func:`easo_effective_contact_angle`.

.. versionadded:: 0.1
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import shutil
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

__all__ = ["TwinEffect", "null_effect", "rolling_friction_effect", "capillary_effect",
           "with_rolling_friction", "with_capillary_bridges", "apply_effect",
           "easo_effective_contact_angle", "easo_bridge_volume", "easo_capillary_force",
           "willett_capillary_force", "write_liggghts_wrapper", "liggghts_simulator",
           "liggghts_twin_design", "LiggghtsTwin", "make_liggghts_twin"]

log = logging.getLogger(__name__)

#: First line of every rewritten deck (the wrapper never rewrites a deck twice).
TWIN_MARK = "# bedstruct LIGGGHTS twin effect:"
_SPEED_X1 = 0.0254          # m/s, the seed's x1 speed (the engine simulator's reference)
_PARTICLE_TYPE = 1          # bedstruct's decks: particles are atom type 1, walls type 2
_MODEL_ORDER = ("tangential", "cohesion", "rolling_friction", "surface")


# --------------------------------------------------------------------------- effects

@dataclass(frozen=True)
class TwinEffect:
    """The physics a LIGGGHTS twin adds to the base decks (withheld from the diagnosis).

    Attributes
    ----------
    kind : {"none", "rolling_friction", "capillary"}
    rolling_friction : float
        ``rolling_friction``: the EPSD2 coefficient of particle contacts
        (replaces the base value).
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
    rolling_walls: bool = True
    surface_tension: float = 0.0
    liquid_volume_fraction: float = 0.0
    contact_angle: float = math.radians(20.0)
    fluid_viscosity: float = 1e-3
    min_separation_ratio: float = 1.01
    max_separation_ratio: float = 1.1

    def __post_init__(self):
        if self.kind not in ("none", "rolling_friction", "capillary"):
            raise ValueError(f"TwinEffect.kind: expected 'none', 'rolling_friction' or "
                             f"'capillary'; got {self.kind!r}")
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

    pat = re.compile(r"(fix\s+\S+\s+\S+\s+property/global\s+coefficientRollingFriction\s+"
                     r"peratomtypepair\s+)(\d+)\s+(.*)$")
    found = False
    for k, ln in enumerate(lines):
        m = pat.match(ln)
        if m:
            found = True
            vals = m.group(3).split()
            if int(m.group(2)) != n or len(vals) != n * n:
                raise ValueError(f"coefficientRollingFriction line has {len(vals)} values for "
                                 f"{m.group(2)} types: {ln!r}")
            for i in range(n):
                for j in range(n):
                    if touched(i, j):
                        vals[i * n + j] = _fmt(mu_r)
            lines[k] = f"{m.group(1)}{n} " + " ".join(vals)
    if not found:
        vals = [_fmt(mu_r) if touched(i, j) else "0" for i in range(n) for j in range(n)]
        lines = _insert_after_properties(lines, [
            "fix twr all property/global coefficientRollingFriction peratomtypepair "
            f"{n} " + " ".join(vals)])
        for k, ln in enumerate(lines):
            if ln.startswith("pair_style gran ") or (walls and " wall/gran " in f" {ln} "
                                                     and " model " in ln):
                lines[k] = _set_model_word(ln, "rolling_friction", "epsd2")
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


# --------------------------------------------------------------------------- running

def write_liggghts_wrapper(folder, effect: TwinEffect, *, liggghts: str | None = None) -> Path:
    """Write the executable that applies ``effect`` to a deck and then runs LIGGGHTS.

    The workflows call it as they call LIGGGHTS (``external.exe``;
    ``... -in DECK -log LOG ...``): it rewrites ``DECK`` with :func:`apply_effect`
    (once; the original is kept as ``DECK.base``) and replaces itself with the
    real binary (``liggghts``, default :func:`bedstruct.dem.backends.find_liggghts`).

    Returns
    -------
    Path
        The executable (``folder/liggghts-twin``), beside ``twin-effect.json``.
    """
    from ..dem.backends import find_liggghts
    folder = Path(folder).resolve()
    folder.mkdir(parents=True, exist_ok=True)
    if liggghts is None:
        info = find_liggghts()
        if info is None:
            raise FileNotFoundError("liggghts is not installed (run .ci/install-engines.sh)")
        liggghts = info.executable
    spec = folder / "twin-effect.json"
    spec.write_text(json.dumps({"effect": effect.to_dict(), "liggghts": str(liggghts)}, indent=1))
    exe = folder / "liggghts-twin"
    exe.write_text(f"#!{sys.executable}\n# bedstruct: apply a twin effect to a LIGGGHTS deck, "
                   "then run LIGGGHTS\nimport sys\n"
                   "from bedstruct.diagnose.external_twins import _wrapped_main\n"
                   f"sys.exit(_wrapped_main({str(spec)!r}, sys.argv[1:]))\n")
    exe.chmod(0o755)
    return exe


def _wrapped_main(spec_path: str, args: list[str]) -> int:
    spec = json.loads(Path(spec_path).read_text())
    effect = TwinEffect(**spec["effect"])
    if "-in" in args:
        deck = Path(args[args.index("-in") + 1])
        text = deck.read_text()
        if not text.startswith(TWIN_MARK):
            shutil.copyfile(deck, deck.with_name(deck.name + ".base"))
            text = apply_effect(text, effect)
            deck.write_text(text)
            # the run folders are temporary: keep the last deck of each kind beside the wrapper
            (Path(spec_path).parent / f"last-{deck.name}").write_text(text)
    os.execv(spec["liggghts"], [spec["liggghts"], *args])
    return 1  # pragma: no cover - execv does not return


def liggghts_simulator(design, effect: TwinEffect, *, preset: str = "tiny",
                       overrides: Sequence[str] = (), workdir=None):
    """A simulator ``sim(base, effects, seed) -> Observations`` running LIGGGHTS with ``effect``.

    It is :class:`~bedstruct.workflows.diagnosis_sim.EngineSimulator` (same
    configuration, same observation operators) with ``engine = "liggghts"``, one
    MPI rank and ``external.exe`` set to :func:`write_liggghts_wrapper`'s
    executable; pass ``effects = {}`` when calling it (the effect is in the decks).

    Parameters
    ----------
    design : MeasurementSet
        Observables to produce.
    effect : TwinEffect
    preset : str
        Workflow preset (as the engine simulator's ``[engine] preset``).
    overrides : sequence of str
        Workflow ``section.key=value`` overrides (use the engine side's).
    workdir : path, optional
        Folder for the wrapper (``bin/``) and the run folders (``runs/``; one
        temporary folder per call); default a new temporary folder.

    Returns
    -------
    EngineSimulator
        With ``name = "liggghts"``.
    """
    import tempfile

    from ..workflows.diagnosis_sim import EngineSimulator
    root = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="bedstruct-lt-"))
    exe = write_liggghts_wrapper(root / "bin", effect)
    ov = [*overrides, "engine=liggghts", "external.np=1", f"external.exe={exe}"]
    (root / "runs").mkdir(parents=True, exist_ok=True)
    sim = EngineSimulator(design, {"preset": preset, "overrides": ov, "n_threads": 1,
                                   "workdir": str(root / "runs")})
    sim.name = "liggghts"
    return sim


def liggghts_twin_design():
    """The measured observables of a LIGGGHTS twin at the scale presets.

    What the engine simulator observes at ``tiny``: the static angle; the
    dynamic angle of layer 2 in two stroke windows; bed height of layers 1
    (calibrate) and 2 (held out); packing fraction of layer 1 at the start and
    end (calibrate) and centre (held out); coordination of layer 1 (centre, held
    out); Sa roughness of layer 1 (calibrate). All at the x1 speed. The
    uncertainties are *reading* errors; the twin adds the scatter of repeated
    runs (:func:`make_liggghts_twin`).

    Examples
    --------
    >>> d = liggghts_twin_design()
    >>> len(d), [m.name for m in d if m.role == "validate"]
    (9, ['bed_height_layer2', 'packing_fraction_x1_center', 'coordination_x1_center'])
    """
    from .measurements import MeasurementSet, measurement_from_dict
    x1 = dict(speed=_SPEED_X1)
    specs = [
        dict(name="static_angle", kind="static_angle", uncertainty=1.0, role="calibrate"),
        dict(name="dynamic_angle_x1", kind="dynamic_angle_series", windows=[[0.0, 0.5], [0.5, 1.0]],
             uncertainty=[1.0, 1.0], role="calibrate", conditions=dict(x1, layer=2)),
        dict(name="bed_height_layer1", kind="bed_height", uncertainty=5e-6, unit="m",
             role="calibrate", conditions=dict(x1, layer=1)),
        dict(name="bed_height_layer2", kind="bed_height", uncertainty=5e-6, unit="m",
             role="validate", conditions=dict(x1, layer=2)),
        dict(name="packing_fraction_x1_start", kind="packing_fraction", uncertainty=0.005,
             role="calibrate", conditions=dict(x1, layer=1, region="start")),
        dict(name="packing_fraction_x1_end", kind="packing_fraction", uncertainty=0.005,
             role="calibrate", conditions=dict(x1, layer=1, region="end")),
        dict(name="packing_fraction_x1_center", kind="packing_fraction", uncertainty=0.005,
             role="validate", conditions=dict(x1, layer=1, region="center")),
        dict(name="coordination_x1_center", kind="coordination", uncertainty=0.2,
             role="validate", conditions=dict(x1, layer=1, region="center")),
        dict(name="roughness_x1", kind="roughness", uncertainty=2e-6, unit="m",
             role="calibrate", conditions=dict(x1, layer=1)),
    ]
    ms = []
    for s in specs:
        d = dict(s, value=[0.0] * (2 if s["kind"] == "dynamic_angle_series" else 1))
        ms.append(measurement_from_dict(d))
    return MeasurementSet(tuple(ms), title="LIGGGHTS twin design",
                          source="bedstruct.diagnose.external_twins.liggghts_twin_design")


@dataclass(frozen=True)
class LiggghtsTwin:
    """A LIGGGHTS twin: the measurement file the diagnosis reads, and the withheld truth.

    Attributes
    ----------
    path : Path
        Measurement TOML (values and stated uncertainties only).
    truth_path : Path
        ``truth.json`` beside it: effect, base, seeds, raw observations.
    effect : TwinEffect
    base : dict
    seeds : tuple of int
        The seeds whose runs were used (see ``replace_failed``).
    raw : dict
        Observable name -> (n_seeds, n_components) LIGGGHTS observations (no noise).
    seconds : float
        Wall time of the LIGGGHTS runs.
    """

    path: Path
    truth_path: Path
    effect: TwinEffect
    base: dict
    seeds: tuple
    raw: dict = field(repr=False)
    seconds: float = 0.0


def _run_seeds(sim, base, seeds, *, replace_failed: int = 0):
    """Observations of every seed; a seed whose run cannot be observed (the engine
    simulator's ValueError: no heap, no fit) is replaced by ``seed + 7919 k``, k = 1 ..
    ``replace_failed``. Returns the observations and the seeds actually used."""
    runs, used = [], []
    for s in seeds:
        for k in range(int(replace_failed) + 1):
            try:
                runs.append(sim(dict(base), {}, int(s) + 7919 * k))
                used.append(int(s) + 7919 * k)
                break
            except ValueError as exc:
                if k == int(replace_failed):
                    raise
                log.warning("LIGGGHTS twin: seed %d not observable (%s); trying %d", int(s) + 7919 * k,
                            exc, int(s) + 7919 * (k + 1))
    return runs, used


def _twin_readings(measured, raw: Mapping[str, np.ndarray], *, rng, scatter=None):
    """Values and stated uncertainties of a twin from raw observations (n_seeds, n_comp)."""
    values, stated = {}, {}
    for m in measured:
        obs = np.asarray(raw[m.name], float)
        n = obs.shape[0]
        readings = obs + m.uncertainty * rng.standard_normal(obs.shape)
        values[m.name] = readings.mean(axis=0)
        s = readings.std(axis=0, ddof=1) if n > 1 else float((scatter or {}).get(m.name, 0.0))
        stated[m.name] = np.sqrt(np.asarray(s) ** 2 / n + m.uncertainty ** 2)
    return values, stated


def make_liggghts_twin(design, effect: TwinEffect, *, base: Mapping[str, float], out,
                       seeds: Sequence[int] = (1000, 1001, 1002), noise_seed: int = 0,
                       scatter: Mapping[str, float] | None = None, preset: str = "tiny",
                       overrides: Sequence[str] = (), replace_failed: int = 0) -> LiggghtsTwin:
    """Run LIGGGHTS with ``effect`` on every seed and write the twin's measurement file.

    Each seed is one repetition of the experiment. Each reading is the
    observation plus Gaussian reading noise of the design's stated uncertainty
    ``u``. The file gives the mean of the ``n`` readings and the uncertainty
    ``sqrt(s^2 / n + u^2)`` (``s`` the standard deviation of the readings: the
    format's rule for replicates plus a stated error). With one seed, ``s`` is
    taken from ``scatter`` (observable name -> standard deviation; default 0).

    Parameters
    ----------
    design : MeasurementSet
        Observables and reading uncertainties (:func:`liggghts_twin_design`).
    effect : TwinEffect
    base : mapping
        Base parameters of the engine simulator (SI; ``cohesion_energy_density`` ...).
    out : path
        Folder: ``twin.toml``, ``truth.json``, LIGGGHTS runs under ``runs/``.
    replace_failed : int
        A repetition whose run cannot be observed (e.g. no heap to fit) is rerun
        with seed ``s + 7919 k`` up to this many times (a failed experiment is
        repeated); the seeds used are in ``truth.json``. Default 0: raise.

    Returns
    -------
    LiggghtsTwin
    """
    from .measurements import MeasurementSet, Observations, write_measurements
    if not isinstance(effect, TwinEffect):
        raise TypeError(f"effect: expected a TwinEffect; got {type(effect).__name__}")
    if len(seeds) < 1:
        raise ValueError("seeds: need at least one LIGGGHTS seed")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    measured = design.select(("calibrate", "validate"))
    sim = liggghts_simulator(measured, effect, preset=preset, overrides=overrides, workdir=out)
    t0 = time.perf_counter()
    runs, used = _run_seeds(sim, base, seeds, replace_failed=replace_failed)
    seconds = time.perf_counter() - t0
    raw = {m.name: np.array([r[m.name] for r in runs], float) for m in measured}
    values, stated = _twin_readings(measured, raw, rng=np.random.default_rng([int(noise_seed), 4242]),
                                    scatter=scatter)
    n = len(seeds)
    prov = f"LIGGGHTS 3.8 runs, {n} repetitions, reading noise added"
    twin = measured.with_values(Observations(values, source="liggghts"),
                                uncertainty=Observations(stated), provenance=prov)
    twin = MeasurementSet(twin.measurements, title="LIGGGHTS twin",
                          source="bedstruct.diagnose.external_twins (withheld truth)")
    path = write_measurements(twin, out / "twin.toml")
    truth = {"effect": effect.to_dict(), "label": effect.label, "base": dict(base),
             "seeds": [int(s) for s in seeds], "seeds_used": used, "noise_seed": int(noise_seed), "preset": preset,
             "overrides": list(overrides), "seconds": seconds,
             "raw": {k: v.tolist() for k, v in raw.items()}}
    truth_path = out / "truth.json"
    truth_path.write_text(json.dumps(truth, indent=1))
    log.info("LIGGGHTS twin %s: %d runs in %.0f s -> %s", effect.label, n, seconds, path)
    return LiggghtsTwin(path, truth_path, effect, dict(base), tuple(used), raw, seconds)
