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
   liquid bridges (:func:`with_capillary_bridges`), a particle-wall sliding friction
   other than the particle-particle one (:func:`with_wall_friction`), or nothing (a
   null twin).
   The workflow is pointed (``external.exe``) at a small wrapper executable
   (:func:`write_liggghts_wrapper`) that rewrites the deck it is asked to run,
   keeps the original as ``<deck>.base`` and then runs the real LIGGGHTS.
3. The runs are observed by the engine simulator's own observation operators
   (:class:`bedstruct.diagnose.engine_simulator.EngineSimulator` with the
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
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .liggghts_effects import TWIN_MARK, TwinEffect, apply_effect

__all__ = ["write_liggghts_wrapper", "liggghts_simulator", "liggghts_twin_design", "LiggghtsTwin",
           "make_liggghts_twin"]

log = logging.getLogger(__name__)

_SPEED_X1 = 0.0254          # m/s, the seed's x1 speed (the engine simulator's reference)


# --------------------------------------------------------------------------- running

def write_liggghts_wrapper(folder, effect: TwinEffect, *, liggghts: str | None = None) -> Path:
    """Write the executable that applies ``effect`` to a deck and then runs LIGGGHTS.

    The workflows call it as they call LIGGGHTS (``external.exe``;
    ``... -in DECK -log LOG ...``): it rewrites ``DECK`` with :func:`apply_effect`
    (once; the original is kept as ``DECK.base``) and replaces itself with the
    real binary (``liggghts``, default :func:`bedstruct.engines.find_liggghts`).

    Returns
    -------
    Path
        The executable (``folder/liggghts-twin``), beside ``twin-effect.json``.
    """
    from ..engines import find_liggghts
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

    It is :class:`~bedstruct.diagnose.engine_simulator.EngineSimulator` (same
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

    from .engine_simulator import EngineSimulator
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
    from .measurements import MeasurementSet
    from .measurement_io import measurement_from_dict
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
    from .measurements import MeasurementSet, Observations
    from .measurement_io import write_measurements
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
    lost = [m.name for m in measured if m.name not in values]
    if lost:
        log.warning("LIGGGHTS twin %s: no repetition observed %s; left out of the file",
                    effect.label, lost)
    seen = MeasurementSet(tuple(m for m in measured if m.name in values), measured.title)
    twin = seen.with_values(Observations(values, source="liggghts"),
                            uncertainty=Observations(stated), provenance=prov)
    twin = MeasurementSet(twin.measurements, title="LIGGGHTS twin",
                          source="bedstruct.diagnose.external_twins (withheld truth)",
                          notes=(f"not observed in any repetition: {', '.join(lost)}" if lost else ""))
    path = write_measurements(twin, out / "twin.toml")
    truth = {"effect": effect.to_dict(), "label": effect.label, "base": dict(base),
             "seeds": [int(s) for s in seeds], "seeds_used": used, "noise_seed": int(noise_seed), "preset": preset,
             "overrides": list(overrides), "seconds": seconds,
             "raw": {k: v.tolist() for k, v in raw.items()}}
    truth_path = out / "truth.json"
    truth_path.write_text(json.dumps(truth, indent=1))
    log.info("LIGGGHTS twin %s: %d runs in %.0f s -> %s", effect.label, n, seconds, path)
    return LiggghtsTwin(path, truth_path, effect, dict(base), tuple(used), raw, seconds)
