"""Twins of the blind benchmark: what is drawn, how each twin engine makes it, and its file.

A blind benchmark (:func:`bedstruct.diagnose.validation.blind.run_benchmark`) draws three kinds of
twins from one seed (:func:`draw_twins`):

- **effect** twins: one catalogue effect at a magnitude drawn uniformly over its prior
  range, the tenth of the range nearest 0 left out (a twin with no effect is a null twin);
  only effects the twin engine realises are drawn (:func:`~bedstruct.diagnose.engine_simulator.engine_realises`: LIGGGHTS and
  LAMMPS state theirs in :func:`bedstruct.engines.effect_realisations`). With
  ``ranges`` (:func:`detectable_ranges`) the magnitudes are drawn only where the
  diagnosing model detects the effect with 95 % power in a twin's noise, and an effect it
  detects nowhere in its prior is not drawn;
- **null** twins: the base model with no effect;
- **out-of-catalogue** twins: a physical change that the catalogue does not hold at all
  (:data:`OUT_OF_CATALOGUE`), at a magnitude drawn over its stated range. With ``ranges``
  (the detectable draw) a change is drawn only over the magnitudes where the twin engine's
  twins of it were seen to differ from the null twins on the benchmark's design
  (:attr:`OutOfCatalogueChange.visible`), and a change that the design cannot see at any
  plausible size there is left out; an engine without such a table draws the full ranges.

Every twin also carries the calibrated cohesion off by ``U(-2, 2)`` % (the diagnosis
recalibrates it), as the validation's twins do. Each change of :data:`OUT_OF_CATALOGUE`
says how each twin engine realises it (a base parameter the engine's simulator knows, or a
workflow configuration override); an engine that cannot realise a change refuses it by
name (:func:`realisation`), and the draw takes only the changes the twin engine realises.

A twin's measurement file (:func:`twin_measurements`) is the mean of ``repeats`` runs of
the twin engine at the twin's point plus reading noise drawn from the design's stated
uncertainties; it states the reading noise and one run's scatter, over the repeats, as a
lab that repeats a test would. It holds nothing of the truth.

.. versionadded:: 0.1
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping

import numpy as np

from ...errors import ConfigError
from ..catalogue import CATALOGUE
from ..engine_simulator import diagnosis_simulator, engine_realises
from ..measurement_io import measurement_from_dict, write_measurements
from ..measurements import MeasurementSet, Observations
from ..surrogate import BASE_PARAMETERS, SPEED_X1, SurrogateSimulator
from .design import engine_twin_design, twin_design

__all__ = ["TWIN_ENGINES", "OutOfCatalogueChange", "OUT_OF_CATALOGUE", "BENCHMARK_HELDOUT",
           "TwinSpec", "benchmark_design", "draw_twins", "realisation", "split_counts",
           "twin_simulator", "twin_measurements", "effect_magnitude_range", "detectable_ranges",
           "DETECT_POWER"]

#: Engines that can make the twins' "real" data.
TWIN_ENGINES = ("surrogate", "embedded", "liggghts", "lammps")

#: Fraction of an effect's prior range, nearest 0, left out of the magnitude draw.
_NEAR_ZERO = 0.10
#: Power with which the diagnosing model detects an effect twin at a magnitude of
#: :func:`detectable_ranges`.
DETECT_POWER = 0.95


@dataclass(frozen=True)
class OutOfCatalogueChange:
    """A physical change of a real machine or powder that the catalogue does not hold.

    Parameters
    ----------
    name : str
        Identifier in ``truth.json``.
    title : str
        In words.
    quantity : str
        What the magnitude is: ``"factor"`` (times the calibrated value) or ``"value"``
        (the parameter's value itself).
    ranges : tuple of (float, float)
        Intervals the magnitude is drawn from (uniformly in the log for factors): off the
        calibrated value on either side.
    realised : mapping
        Per twin engine, ``("base", key)`` (a base parameter of that engine's simulator,
        ``sim(base, effects, seed)``) or ``("override", "section.key")`` (a workflow
        configuration override of the engine's runs); engines absent here refuse it.
    refused : str
        Why the engines that lack it cannot realise it.
    visible : mapping
        Per twin engine, the parts of :attr:`ranges` where that engine's twins of the change
        were measured to leave a gap beyond a twin's noise on the benchmark's design at
        ``tiny`` (the "is there a gap" test at 5 %; the measurements are in
        ``docs/records/ooc-visibility/``). An empty tuple: no plausible size of the change
        is seen there. Engines absent here have not been measured.
    same_term : mapping
        Per twin engine, the catalogue effect that engine realises through the same model
        term (LIGGGHTS' one rolling model carries both the base rolling friction and the
        non-sphericity's extra one): there the change is that effect, not one outside the
        catalogue, and the detectable draw leaves it out.
    """

    name: str
    title: str
    quantity: str
    ranges: tuple[tuple[float, float], ...]
    realised: Mapping[str, tuple[str, str]] = field(default_factory=dict)
    refused: str = ""
    visible: Mapping[str, tuple[tuple[float, float], ...]] = field(default_factory=dict)
    same_term: Mapping[str, str] = field(default_factory=dict)

    def drawable(self, engine: str, detectable: bool) -> tuple[tuple[float, float], ...]:
        """The ranges a twin of ``engine`` is drawn over: in the detectable draw
        :attr:`visible` for that engine where it was measured and none where the engine
        realises the change as a catalogue effect (:attr:`same_term`); else :attr:`ranges`."""
        if detectable and engine in self.same_term:
            return ()
        if detectable and engine in self.visible:
            return tuple(self.visible[engine])
        return self.ranges

    def draw(self, rng: np.random.Generator, ranges=None) -> float:
        """One magnitude drawn over ``ranges`` (default :attr:`ranges`; width-weighted,
        log-uniform for factors)."""
        ranges = self.ranges if ranges is None else tuple(ranges)
        tr = (lambda x: math.log(x)) if self.quantity == "factor" else (lambda x: x)
        widths = np.array([tr(b) - tr(a) for a, b in ranges])
        k = int(rng.choice(len(ranges), p=widths / widths.sum()))
        a, b = ranges[k]
        u = rng.uniform(tr(a), tr(b))
        return float(math.exp(u) if self.quantity == "factor" else u)


def _contact(key: str) -> dict:
    # the engine simulators write the base parameters into contact.* on every call, so a
    # contact change is realised through the base parameter (a contact.* override would be
    # overwritten by the base value); the surrogate knows the same keys
    return {e: ("base", key) for e in TWIN_ENGINES}


def _override(key: str) -> dict:
    return {e: ("override", key) for e in ("embedded", "liggghts", "lammps")}


#: Changes outside the catalogue that out-of-catalogue twins are drawn from.
OUT_OF_CATALOGUE: tuple[OutOfCatalogueChange, ...] = (
    OutOfCatalogueChange(
        "restitution", "coefficient of restitution off the calibrated 0.1", "value",
        ((0.3, 0.7),), _contact("restitution"), visible={"liggghts": ()}),
    OutOfCatalogueChange(
        "sliding_friction", "particle-particle sliding friction off the calibrated value",
        "factor", ((0.5, 0.8), (1.25, 2.0)), _contact("friction"),
        visible={"liggghts": ((0.5, 0.65),)}),
    OutOfCatalogueChange(
        "rolling_friction", "rolling friction off the calibrated value", "factor",
        ((0.3, 0.6), (1.7, 3.0)), _contact("rolling_friction"),
        visible={"liggghts": ((2.5, 3.0),)},
        same_term={"liggghts": "non_sphericity", "lammps": "non_sphericity"}),
    OutOfCatalogueChange(
        "particle_density", "particle density error", "factor", ((0.8, 0.92), (1.08, 1.25)),
        _override("material.density"),
        refused="the surrogate has no particle density", visible={"liggghts": ()}),
    OutOfCatalogueChange(
        "youngs_modulus", "Young's modulus far from the calibrated one", "factor",
        ((0.1, 0.3), (3.0, 10.0)), _override("material.youngs_modulus"),
        refused="the surrogate has no Young's modulus", visible={"liggghts": ((0.1, 0.19),)}),
    OutOfCatalogueChange(
        "blade_bevel", "blade bevel angle off the nominal", "factor", ((0.3, 0.6), (1.7, 3.0)),
        {e: ("override", "spread.bevel_deg") for e in ("embedded", "liggghts")},
        refused="the surrogate has no blade geometry, and LAMMPS' moving blade is the "
                "unbevelled slab (docs/backends.md)",
        visible={"liggghts": ((0.34, 0.6), (1.7, 2.6))}),
    OutOfCatalogueChange(
        "second_psd_mode", "a second (coarse) mode in the particle size distribution",
        "value", ((0.05, 0.2),), {},
        refused="no engine's PSD is bimodal (the workflow PSD is one log-normal: d10/d50/d90)"),
    OutOfCatalogueChange(
        "rounded_blade_edge", "a rounded blade edge", "value", ((20e-6, 200e-6),), {},
        refused="no engine's blade has an edge radius"),
)

#: Held-out observables the benchmark adds to the surrogate's validation design
#: (:func:`~bedstruct.diagnose.validation.design.twin_design`): wall friction moves none of
#: its held-out observables beyond noise at half its prior top (0.2), so its held-out
#: shrink would go unmeasured; the blade's vertical/horizontal load ratio over a powder
#: layer (layer 2) moves 2.6 sigma there.
BENCHMARK_HELDOUT = (
    dict(name="tool_force_ratio_layer2", kind="tool_force_ratio", value=[0.0], uncertainty=0.005,
         role="validate", conditions=dict(layer=2, speed=SPEED_X1)),
)


@dataclass(frozen=True)
class TwinSpec:
    """One drawn twin (the truth): kind, effect or change, magnitude and the twin's point."""

    twin: str
    kind: str                      # "effect", "null", "out_of_catalogue"
    name: str | None               # the effect or the change (None for a null twin)
    magnitude: float | None
    cohesion_factor: float
    seed: int

    def as_dict(self) -> dict:
        return {"kind": self.kind, "effect" if self.kind == "effect" else "change": self.name,
                "magnitude": self.magnitude, "cohesion_factor": self.cohesion_factor,
                "seed": self.seed}


def benchmark_design(engine: str) -> MeasurementSet:
    """The observables of a benchmark twin's file for a twin engine.

    The surrogate: :func:`twin_design` plus :data:`BENCHMARK_HELDOUT`; the DEM engines:
    :func:`engine_twin_design` (``"seed"``), unchanged (not checked per effect here).
    """
    _check_engine(engine)
    if engine == "surrogate":
        d = twin_design()
        extra = tuple(measurement_from_dict(dict(s)) for s in BENCHMARK_HELDOUT)
        return replace(d, measurements=d.measurements + extra, title="blind benchmark twin design",
                       source="bedstruct.diagnose.validation.blind_twins.benchmark_design")
    return engine_twin_design("seed")


def _check_engine(engine: str) -> None:
    if engine not in TWIN_ENGINES:
        raise ConfigError(f"twins engine: expected one of {', '.join(TWIN_ENGINES)}; got {engine!r}")


def split_counts(n: int) -> tuple[int, int, int]:
    """``(effect, null, out_of_catalogue)`` twin counts for ``n`` twins.

    A quarter (rounded down) null, a quarter out-of-catalogue, the rest effect twins.

    Examples
    --------
    >>> split_counts(40), split_counts(4), split_counts(10)
    ((20, 10, 10), (2, 1, 1), (6, 2, 2))
    """
    if int(n) != n or n < 4:
        raise ConfigError(f"n: expected a whole number >= 4 (one twin of each kind at least); "
                          f"got {n!r}")
    q = int(n) // 4
    return int(n) - 2 * q, q, q


def effect_magnitude_range(effect) -> tuple[tuple[float, float], ...]:
    """Intervals an effect twin's magnitude is drawn from: its prior, the tenth nearest 0 left out."""
    lo, hi = effect.prior
    cut = _NEAR_ZERO * (hi - lo)
    out = []
    if lo < 0:
        out.append((lo, min(-cut, 0.0)))
    out.append((max(cut, 0.0), hi))
    return tuple((a, b) for a, b in out if b > a)


def detectable_ranges(fps, *, threshold: float, repeats: int = 3,
                      power: float = DETECT_POWER, grid: int = 129) -> dict[str, tuple]:
    """Per effect of ``fps``, the magnitudes at which the diagnosing model detects it.

    A twin's gap, with the part recalibration absorbs projected out, is about
    ``N(g(a), 1)`` in units of its noise, ``g(a)`` the fingerprint's projected gap at
    magnitude ``a``; the effect is selected when the gap's square exceeds ``threshold``
    (:func:`~bedstruct.diagnose.fingerprints.selection_threshold`). It is detected with
    ``power`` where ``g(a) >= sqrt(threshold) + z_power``. The noise is that of a twin of
    ``repeats`` repeated runs diagnosed against the base runs' mean: the design's reading
    uncertainty and the run scatter over ``repeats``, plus the base mean's.

    Parameters
    ----------
    fps : FingerprintSet
        Fingerprints of the diagnosing simulator on the benchmark's design.
    threshold : float
        The selection's chi-square threshold.
    repeats : int
        Runs averaged into a twin's file.
    power : float
        Detection probability asked for.
    grid : int
        Points per magnitude interval of :func:`effect_magnitude_range` searched.

    Returns
    -------
    dict of str to tuple of (float, float)
        Each effect's intervals (inside its drawable range); empty where no magnitude of
        its prior is detected with that power.
    """
    from scipy.stats import norm

    from .twins import _projected_gap
    need = math.sqrt(float(threshold)) + float(norm.ppf(power))
    n = np.maximum(np.sum(np.isfinite(fps.base_samples), axis=0), 1)
    sigma = np.sqrt(fps.sigma_meas ** 2 + fps.sim_var / int(repeats) + fps.sim_var / n)
    out = {}
    for f in fps.fingerprints:
        gap = _projected_gap(fps, f.name, sigma)
        parts = []
        for a, b in effect_magnitude_range(f.effect):
            xs = np.linspace(a, b, int(grid))
            ok = np.array([gap(x) >= need for x in xs])
            k = 0
            while k < len(xs):
                if not ok[k]:
                    k += 1
                    continue
                j = k
                while j + 1 < len(xs) and ok[j + 1]:
                    j += 1
                if j > k:
                    parts.append((float(xs[k]), float(xs[j])))
                k = j + 1
        out[f.name] = tuple(parts)
    return out


def realisation(change: OutOfCatalogueChange, engine: str) -> tuple[str, str]:
    """How ``engine`` realises ``change``: ``("base", key)`` or ``("override", key)``.

    Raises
    ------
    ConfigError
        Naming the change and the engine, when the engine cannot realise it.

    Examples
    --------
    >>> realisation(OUT_OF_CATALOGUE[0], "surrogate")
    ('base', 'restitution')
    >>> realisation(OUT_OF_CATALOGUE[3], "surrogate")
    Traceback (most recent call last):
    ...
    bedstruct.errors.ConfigError: twins engine 'surrogate' cannot realise the out-of-catalogue change 'particle_density' (the surrogate has no particle density)
    """
    _check_engine(engine)
    if engine not in change.realised:
        raise ConfigError(f"twins engine {engine!r} cannot realise the out-of-catalogue change "
                          f"{change.name!r} ({change.refused})")
    return tuple(change.realised[engine])


def draw_twins(n: int, seed: int, engine: str,
               ranges: Mapping[str, tuple] | None = None) -> list[TwinSpec]:
    """The ``n`` twins of a benchmark, drawn from ``seed`` (see the module docstring).

    Effects and changes are taken in turn over a shuffled order (each appears about
    equally often), the twins' order is shuffled, and ids are ``twin-000``... in that order.
    ``ranges`` (effect -> intervals, :func:`detectable_ranges`) replaces each effect's
    drawable range; an effect with no interval, or missing from it, is not drawn. With
    ``ranges`` the out-of-catalogue changes are drawn over their ranges visible in
    ``engine``'s twins (:meth:`OutOfCatalogueChange.drawable`); a change visible nowhere
    there is not drawn.
    """
    n_eff, n_null, n_ooc = split_counts(n)
    rng = np.random.default_rng([int(seed), 48])
    changes = [c for c in OUT_OF_CATALOGUE
               if engine in c.realised and c.drawable(engine, ranges is not None)]
    _check_engine(engine)
    if not changes:  # pragma: no cover - every engine realises the contact changes
        raise ConfigError(f"twins engine {engine!r} realises no out-of-catalogue change")
    effects = [e for e in CATALOGUE if engine == "surrogate" or engine_realises(e, engine)]
    if ranges is not None:
        effects = [e for e in effects if ranges.get(e.name)]
        if not effects:
            raise ConfigError(f"no catalogue effect that twins engine {engine!r} realises is "
                              f"detected by the diagnosing model at any magnitude of its prior "
                              f"on this design; there are no effect twins to draw")
    eff_order = rng.permutation(len(effects))
    ooc_order = rng.permutation(len(changes))
    drawn = []
    for i in range(n_eff):
        e = effects[int(eff_order[i % len(effects)])]
        parts = effect_magnitude_range(e) if ranges is None else tuple(ranges[e.name])
        widths = np.array([b - a for a, b in parts])
        a, b = parts[int(rng.choice(len(parts), p=widths / widths.sum()))]
        drawn.append(("effect", e.name, float(rng.uniform(a, b))))
    drawn += [("null", None, None)] * n_null
    for i in range(n_ooc):
        c = changes[int(ooc_order[i % len(changes)])]
        drawn.append(("out_of_catalogue", c.name,
                      c.draw(rng, c.drawable(engine, ranges is not None))))
    order = rng.permutation(len(drawn))
    out = []
    for j, k in enumerate(order):
        kind, name, mag = drawn[int(k)]
        out.append(TwinSpec(f"twin-{j:03d}", kind, name, mag,
                            float(1.0 + rng.uniform(-0.02, 0.02)),
                            int(rng.integers(1_000_000, 2**31 - 1))))
    return out


def _change(name: str) -> OutOfCatalogueChange:
    for c in OUT_OF_CATALOGUE:
        if c.name == name:
            return c
    raise ConfigError(f"unknown out-of-catalogue change {name!r}")


def _engine_value(engine: str, preset: str, key: str) -> float:
    """The value of workflow key ``section.key`` in ``engine``'s runs at ``preset``."""
    sim = twin_simulator(engine, engine_twin_design("seed"), preset=preset)
    section, k = key.split(".", 1)
    return float(sim.base_cfg[section][k])


def twin_point(spec: TwinSpec, engine: str, *, preset: str = "tiny") -> dict:
    """The twin's base parameters, effects and engine overrides (what its runs are given).

    Returns ``{"base": ..., "effects": ..., "overrides": [...]}``; the overrides apply to a
    DEM engine's workflow configuration (none on the surrogate).
    """
    base = dict(BASE_PARAMETERS)
    base["cohesion_energy_density"] *= spec.cohesion_factor
    effects, overrides = {}, []
    if spec.kind == "effect":
        effects = {spec.name: float(spec.magnitude)}
    elif spec.kind == "out_of_catalogue":
        c = _change(spec.name)
        how, key = realisation(c, engine)
        if how == "base":
            base[key] = (base[key] * spec.magnitude if c.quantity == "factor"
                         else float(spec.magnitude))
        else:
            v = (_engine_value(engine, preset, key) * spec.magnitude
                 if c.quantity == "factor" else float(spec.magnitude))
            overrides.append(f"{key}={v!r}")
    return {"base": base, "effects": effects, "overrides": overrides}


def twin_simulator(engine: str, design: MeasurementSet, *, preset: str = "tiny",
                   overrides=()):
    """The simulator that makes twins on ``engine`` (``sim(base, effects, seed)``).

    The surrogate: :class:`SurrogateSimulator` (``overrides`` must be empty). The DEM
    engines: :func:`bedstruct.diagnose.engine_simulator.diagnosis_simulator` on the workflow ``preset`` with
    ``engine=<name>`` and ``overrides``.
    """
    _check_engine(engine)
    if engine == "surrogate":
        if overrides:
            raise ConfigError(f"twins engine 'surrogate' takes no workflow overrides; got "
                              f"{list(overrides)}")
        return SurrogateSimulator(design)
    return diagnosis_simulator(design, {"preset": preset,
                                        "overrides": [f"engine={engine}", *overrides]})


def _read_mean(y) -> tuple[np.ndarray, np.ndarray]:
    """Mean over the rows of ``y`` that gave a reading (finite), per column, and their
    number (the mean is 0 where none did)."""
    ok = np.isfinite(y)
    n = ok.sum(axis=0)
    return np.where(ok, y, 0.0).sum(axis=0) / np.maximum(n, 1), n


def _run_scatter(readings) -> np.ndarray:
    """Sample standard deviation of the repeats' readings per component; 0 where fewer
    than two repeats gave a reading (no scatter can be estimated from one: such a component
    is left out of a DEM twin's file)."""
    y = np.array([np.atleast_1d(np.asarray(r, float)) for r in readings])
    mean, n = _read_mean(y)
    ss = (np.where(np.isfinite(y), y - mean, 0.0) ** 2).sum(axis=0)
    return np.where(n >= 2, np.sqrt(ss / np.maximum(n - 1, 1)), 0.0)


def twin_measurements(spec: TwinSpec, engine: str, design: MeasurementSet, path, *,
                      preset: str = "tiny", repeats: int | None = None,
                      title: str | None = None, source: str = "blind benchmark twin") -> Path:
    """Make twin ``spec`` on ``engine`` and write its measurement file to ``path``.

    The file states the mean of ``repeats`` runs (default 1 on the surrogate, 3 on a DEM
    engine) plus reading noise, with uncertainty ``sqrt(reading**2 + run_sd**2 / n)`` over
    the ``n`` runs that gave a reading, where ``run_sd`` is the surrogate's replicate
    scatter at the base point (:meth:`SurrogateSimulator.noise_sd`) or, on a DEM engine, the
    sample standard deviation of the twin's own repeats. An observable is left out of the
    file where no run read a component or, on a DEM engine, fewer than two did: one reading
    gives no scatter, and the reading noise alone would understate its uncertainty (a single
    dynamic-angle reading far from the others' typical value, stated to its reading noise,
    departs from any model by tens of that noise). The title (default the twin's id) and the file
    say nothing of the truth. The design's set-up (its ``[conditions]``: PSD, layers, blade
    speed, platform, side walls), which the DEM engines' runs reproduce, and its notes are
    written to the file; ``source`` is its ``[meta] source`` and every observable's
    provenance.
    """
    repeats = int(repeats or (1 if engine == "surrogate" else 3))
    point = twin_point(spec, engine, preset=preset)
    sim = twin_simulator(engine, design, preset=preset, overrides=point["overrides"])
    runs = [sim(point["base"], point["effects"], spec.seed + 7919 * k) for k in range(repeats)]
    rng = np.random.default_rng([spec.seed, 99])
    if engine == "surrogate":
        run_sd = sim.noise_sd()
    else:
        run_sd = {m.name: _run_scatter([r[m.name] for r in runs]) for m in design}
    values, stated = {}, {}
    for m in design:
        vals = np.array([np.asarray(r[m.name], float)
                         + m.uncertainty * rng.standard_normal(m.n_components) for r in runs])
        mean, n_read = _read_mean(vals)
        # no value where too few repeats gave a reading (the observable is left out below)
        values[m.name] = np.where(n_read >= (1 if engine == "surrogate" else 2), mean, np.nan)
        stated[m.name] = np.sqrt(m.uncertainty ** 2
                                 + np.asarray(run_sd[m.name]) ** 2 / np.maximum(n_read, 1))
    bad = [m.name for m in design if not np.all(np.isfinite(values[m.name]))]
    keep = tuple(m for m in design if m.name not in bad)
    ms = replace(design, measurements=keep, title=title or spec.twin, source=source, path=None)
    ms = ms.with_values(Observations({k: values[k] for k in ms.names}, source="twin"),
                        uncertainty=Observations({k: stated[k] for k in ms.names}),
                        provenance=source)
    return write_measurements(ms, path)
