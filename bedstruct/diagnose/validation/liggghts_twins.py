"""Validation twins whose "real" data come from LIGGGHTS, not from bedstruct's own engine.

The synthetic twins of :mod:`bedstruct.diagnose.validation.validate` are made with the
same simulator the diagnosis uses, so they cannot test what matters most with
real data: a gap that is partly the two codes' different numerics. A LIGGGHTS
twin is made like this:

1. The runs are the public external workflows
   (:func:`bedstruct.workflows.run_repose` / ``run_spread`` with
   ``engine = "liggghts"``, i.e. :mod:`bedstruct.workflows.external`), on one
   MPI rank.
2. The withheld effect is part of the configuration: values of its options
   (e.g. ``{"contact.wall_friction": 0.7}``), which the LIGGGHTS dialect
   writes into the decks as it states
   (:data:`bedstruct.engines.LIGGGHTS_REALISATIONS`): liquid bridges as LIGGGHTS'
   ``cohesion easo/capillary/viscous`` (its law: :mod:`bedstruct.diagnose.validation.liggghts_law`),
   rolling and wall friction as contact coefficients. An effect LIGGGHTS cannot
   realise is refused by name before any run.
3. The runs are observed by the engine simulator's own observation operators
   (:class:`bedstruct.diagnose.engine_simulator.EngineSimulator` with the
   LIGGGHTS engine; :func:`liggghts_simulator`), on several seeds (an experiment
   repeated ``n`` times), reading noise is drawn from the design's stated
   uncertainties, and the result is written as a measurement TOML file
   (:func:`make_liggghts_twin`). The diagnosis sees only that file; the truth is
   kept in ``truth.json`` beside it.

.. versionadded:: 0.1
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ...engines import dialect

__all__ = ["effects_label", "liggghts_simulator", "liggghts_twin_design", "LiggghtsTwin",
           "make_liggghts_twin"]

log = logging.getLogger(__name__)

_SPEED_X1 = 0.0254          # m/s, the seed's x1 speed (the engine simulator's reference)


# --------------------------------------------------------------------------- running

def effects_label(effects: Mapping[str, Any]) -> str:
    """Short description of a twin's option values (``none`` when empty).

    Examples
    --------
    >>> effects_label({"contact.wall_friction": 0.7})
    'contact.wall_friction=0.7'
    >>> effects_label({})
    'none'
    """
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                     for k, v in sorted(effects.items())) or "none"


def _options_overrides(options: Mapping[str, Any]) -> list[str]:
    """Workflow overrides ``section.option=value`` of option values."""
    out = []
    for k, v in sorted(options.items()):
        val = ("true" if v else "false") if isinstance(v, bool) else (
            repr(float(v)) if isinstance(v, (int, float)) else str(v))
        out.append(f"{k}={val}")
    return out


def liggghts_simulator(design, effects: Mapping[str, Any], *, preset: str = "tiny",
                       overrides: Sequence[str] = (), workdir=None):
    """A simulator ``sim(base, effects, seed) -> Observations`` running LIGGGHTS with ``effects``.

    It is :class:`~bedstruct.diagnose.engine_simulator.EngineSimulator` (same
    configuration, same observation operators) with ``engine = "liggghts"``, one
    MPI rank and the option values ``effects`` in its configuration, set after each
    call's base parameters (:attr:`EngineSimulator.options`); pass ``effects = {}``
    when calling it (the twin's effect is in its configuration).

    Parameters
    ----------
    design : MeasurementSet
        Observables to produce.
    effects : mapping
        Option values of the twin (``"section.option"``, SI), e.g.
        ``{"contact.capillary": True, "contact.capillary_film_thickness": 8.7e-9}``.
    preset : str
        Workflow preset (as the engine simulator's ``[engine] preset``).
    overrides : sequence of str
        Workflow ``section.key=value`` overrides (use the engine side's).
    workdir : path, optional
        Folder of the run folders (``runs/``; one temporary folder per call);
        default a new temporary folder.

    Returns
    -------
    EngineSimulator
        With ``name = "liggghts"``.

    Raises
    ------
    bedstruct.errors.ConfigError
        An effect LIGGGHTS cannot realise (named), or an unknown option.
    """
    import tempfile

    from ..engine_simulator import EngineSimulator, with_options
    from ...workflows.config import load_config
    ov = [*overrides, "engine=liggghts", "external.np=1", *_options_overrides(effects)]
    dialect("liggghts").check_effects(with_options(load_config(preset=preset, overrides=ov),
                                                   effects), spreading=True)
    root = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="bedstruct-lt-"))
    (root / "runs").mkdir(parents=True, exist_ok=True)
    sim = EngineSimulator(design, {"preset": preset, "overrides": ov, "n_threads": 1,
                                   "workdir": str(root / "runs")})
    sim.options = dict(effects)
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
    from ..measurements import MeasurementSet
    from ..measurement_io import measurement_from_dict
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
                          source="bedstruct.diagnose.validation.liggghts_twins.liggghts_twin_design")


@dataclass(frozen=True)
class LiggghtsTwin:
    """A LIGGGHTS twin: the measurement file the diagnosis reads, and the withheld truth.

    Attributes
    ----------
    path : Path
        Measurement TOML (values and stated uncertainties only).
    truth_path : Path
        ``truth.json`` beside it: effect, base, seeds, raw observations.
    effects : dict
        The twin's option values (its withheld effect; empty for a null twin).
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
    effects: dict
    base: dict
    seeds: tuple
    raw: dict = field(repr=False)
    seconds: float = 0.0


def _run_seeds(sim, base, seeds, *, replace_failed: int = 0):
    """Observations of every seed and the seeds used.

    A seed whose run leaves an observable unobserved (NaN: no heap, no fit) is
    repeated with ``seed + 7919 k``, k = 1 .. ``replace_failed`` (a failed
    experiment is repeated); after that its NaN stays, as missing data.
    """
    runs, used = [], []
    for s in seeds:
        for k in range(int(replace_failed) + 1):
            sd = int(s) + 7919 * k
            obs = sim(dict(base), {}, sd)
            lost = [n for n in obs.names if not np.all(np.isfinite(obs[n]))]
            if not lost or k == int(replace_failed):
                runs.append(obs)
                used.append(sd)
                break
            log.warning("LIGGGHTS twin: seed %d could not observe %s; trying %d", sd, lost,
                        int(s) + 7919 * (k + 1))
    return runs, used


def _twin_readings(measured, raw: Mapping[str, np.ndarray], *, rng, scatter=None):
    """Values and stated uncertainties of a twin from raw observations (n_seeds, n_comp).

    Repetitions that could not observe an observable (NaN) are left out of its mean;
    an observable no repetition observed is left out of the result.
    """
    values, stated = {}, {}
    for m in measured:
        obs = np.asarray(raw[m.name], float)
        readings = obs + m.uncertainty * rng.standard_normal(obs.shape)
        ok = np.all(np.isfinite(readings), axis=1)
        n = int(ok.sum())
        if n == 0:
            continue
        readings = readings[ok]
        values[m.name] = readings.mean(axis=0)
        s = readings.std(axis=0, ddof=1) if n > 1 else np.asarray((scatter or {}).get(m.name, 0.0), float)
        stated[m.name] = np.sqrt(np.asarray(s) ** 2 / n + m.uncertainty ** 2)
    return values, stated


def make_liggghts_twin(design, effects: Mapping[str, Any], *, base: Mapping[str, float], out,
                       seeds: Sequence[int] = (1000, 1001, 1002), noise_seed: int = 0,
                       scatter: Mapping[str, float] | None = None, preset: str = "tiny",
                       overrides: Sequence[str] = (), replace_failed: int = 0) -> LiggghtsTwin:
    """Run LIGGGHTS with ``effects`` on every seed and write the twin's measurement file.

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
    effects : mapping
        The twin's option values (:func:`liggghts_simulator`; empty: a null twin).
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
    from ..measurements import MeasurementSet, Observations
    from ..measurement_io import write_measurements
    if not isinstance(effects, Mapping):
        raise TypeError(f"effects: expected a mapping of option values; got "
                        f"{type(effects).__name__}")
    effects = dict(effects)
    if len(seeds) < 1:
        raise ValueError("seeds: need at least one LIGGGHTS seed")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    measured = design.select(("calibrate", "validate"))
    sim = liggghts_simulator(measured, effects, preset=preset, overrides=overrides, workdir=out)
    t0 = time.perf_counter()
    runs, used = _run_seeds(sim, base, seeds, replace_failed=replace_failed)
    seconds = time.perf_counter() - t0
    raw = {m.name: np.array([r[m.name] for r in runs], float) for m in measured}
    values, stated = _twin_readings(measured, raw, rng=np.random.default_rng([int(noise_seed), 4242]),
                                    scatter=scatter)
    n = len(seeds)
    prov = f"LIGGGHTS 3.8 runs, {n} repetitions, reading noise added"
    lost = [m.name for m in measured if m.name not in values]
    if lost:
        log.warning("LIGGGHTS twin %s: no repetition observed %s; left out of the file",
                    effects_label(effects), lost)
    seen = MeasurementSet(tuple(m for m in measured if m.name in values), measured.title)
    twin = seen.with_values(Observations(values, source="liggghts"),
                            uncertainty=Observations(stated), provenance=prov)
    twin = MeasurementSet(twin.measurements, title="LIGGGHTS twin",
                          source="bedstruct.diagnose.validation.liggghts_twins (withheld truth)",
                          notes=(f"not observed in any repetition: {', '.join(lost)}" if lost else ""))
    path = write_measurements(twin, out / "twin.toml")
    truth = {"effects": effects, "label": effects_label(effects), "base": dict(base),
             "seeds": [int(s) for s in seeds], "seeds_used": used, "noise_seed": int(noise_seed), "preset": preset,
             "overrides": list(overrides), "seconds": seconds,
             "raw": {k: v.tolist() for k, v in raw.items()}}
    truth_path = out / "truth.json"
    truth_path.write_text(json.dumps(truth, indent=1))
    log.info("LIGGGHTS twin %s: %d runs in %.0f s -> %s", effects_label(effects), n, seconds, path)
    return LiggghtsTwin(path, truth_path, effects, dict(base), tuple(used), raw, seconds)
