"""Workflows on the external engines (``engine = "liggghts"`` or ``"lammps"``).

:func:`run_repose_external` runs the angle-of-repose workflow of
:mod:`bedstruct.workflows.repose` on LIGGGHTS 3.8 or LAMMPS: per replicate it
places the spheres with the embedded engine's raindrop insertion (same size
distribution, same seed: the first insertion round of an embedded run places
exactly these spheres), writes them as a data file, writes the deck
(:func:`bedstruct.dem.backends.repose_deck`, the same walls, contact model,
gravity and time step as the embedded run), runs it through MPI
(``external.np`` ranks, ``external.exe`` for a user's binary), reads the
dumps back with :func:`bedstruct.io.read_dump` and measures the pile with
:func:`bedstruct.workflows.repose.measure_pile`, the embedded run's code path.
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
frozen at a reference contact.

:func:`run_spread_external` spreads every layer with a blade, plate or roller
on either engine, all layers in one engine run so that contact histories carry
over between layers (:func:`bedstruct.dem.backends.spread_layers_deck`). A resumed
run reuses the finished pile and, when the engine run finished, its output.
"""

from __future__ import annotations

import gzip
import logging
import shutil
import time as _time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .._atomic import atomic_path
from ..errors import ConfigError
from ._common import contact_model, german_fit_values, psd_sampler
from ._rundir import RunLayout

__all__ = ["ExternalDecks", "engine_for", "run_repose_external", "repose_inputs",
           "run_spread_external"]

log = logging.getLogger(__name__)


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
        from ._common import to_jsonable
        return {"write_only": True, **to_jsonable(self)}


def engine_for(cfg: dict, *, required: bool = True):
    """The :class:`~bedstruct.dem.backends.EngineInfo` of ``cfg["engine"]``.

    ``external.exe`` names a user's binary. Raises :class:`ConfigError` when
    the engine is not installed and ``required`` (else returns None).
    """
    from ..dem.backends import find_lammps, find_liggghts
    name = cfg["engine"]
    if name not in ("liggghts", "lammps"):
        raise ConfigError(f"engine {name!r} is not an external engine (liggghts or lammps)")
    exe = cfg["external"]["exe"] or None
    info = find_liggghts(exe) if name == "liggghts" else find_lammps(exe)
    if info is None and required:
        where = f"`external.exe` = {exe!r} was not found" if exe else (
            f"{name} was not found (install it with .ci/install-engines.sh, or give the binary "
            "with --exe PATH / external.exe; set BEDSTRUCT_LIGGGHTS / BEDSTRUCT_LAMMPS)")
        raise ConfigError(f"engine {name!r} is not available: {where}")
    return info


def _check_effects(cfg: dict, *, spreading: bool = False) -> None:
    """Raise ConfigError for a diagnosis extension (``effects``) the decks do not write.

    Wall friction, missing fines and EPSD2 rolling friction are ordinary deck
    parameters; capillary bridges, contact ageing and the blade's start-up ramp
    and vibration exist in the embedded engine only, and a deck without them
    would be the base model under the extension's name.
    """
    fx = cfg.get("effects") or {}
    name = cfg.get("engine", "external")
    found = [k for k in ("capillary", "contact_ageing") if fx.get(k)]
    if spreading:
        found += [k for k in ("blade_ramp_time", "blade_vibration_amplitude")
                  if float(fx.get(k, 0.0)) > 0.0]
    if found:
        raise ConfigError(f"engine {name!r}: config key(s) {', '.join('effects.' + k for k in found)} "
                          "are extensions of the embedded engine, not written to the "
                          f"{name} decks; run them with --engine embedded (for LIGGGHTS-made "
                          "twins with liquid bridges see bedstruct.diagnose.external_twins)")


def _granular_params(cfg: dict, cohesion: float, *, spreading: bool = False):
    """GranularParams of ``cfg`` and the LAMMPS cohesion model (or None)."""
    from ..dem.backends import as_granular_params
    _check_effects(cfg, spreading=spreading)
    model = contact_model(cfg, cohesion=cohesion)
    p = as_granular_params(model)
    cm = cfg["external"]["cohesion_model"]
    coh = max(p.cohesion_energy_density, p.wall("cohesion_energy_density"))
    if cfg["engine"] == "lammps" and coh > 0:
        if cm == "none":
            log.warning("lammps: cohesion dropped (external.cohesion_model = none)")
            p = as_granular_params(p, cohesion_energy_density=0.0, wall_cohesion_energy_density=0.0)
            return p, None, model
        log.warning("lammps has no SJKR cohesion; using the %s stand-in (docs/backends.md)", cm)
        return p, cm, model
    return p, None, model


def repose_inputs(cfg: dict, *, seed: int):
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

    rc = cfg["repose"]
    L, W, H = (float(v) for v in rc["box"])
    model = contact_model(cfg)
    draw = psd_sampler(cfg)
    rmax = draw.r_max
    periodic = bool(rc["periodic_width"])
    depth = float(rc["reservoir_depth"])
    margin = 4 * rmax
    lo = [-margin - L, 0.0 if periodic else -margin, -depth]
    hi = [L + margin, W if periodic else W + margin, 2.0 * H]
    box = Box(lo, hi, boundary=("ff", "pp" if periodic else "ff", "ff"))
    sim = Simulation(box, model, walls=[], safety=cfg["time"]["safety"],
                     v_max=cfg["time"]["v_max"], min_radius=draw.r_min, n_threads=1, seed=seed)
    n_want = int(rc["n_particles"])
    if n_want <= 0:  # as repose_replicate: fill_fraction of the box at a packing fraction of 0.6
        r = draw(20000, np.random.default_rng(0))
        v_mean = float(np.mean(4.0 / 3.0 * np.pi * r ** 3))
        n_want = int(0.6 * L * W * H * float(rc["fill_fraction"]) / v_mean)
    sim.insert_raindrop(n_want, draw, region=((0.0, 0.0, 0.0), (L, W, H)))
    if sim.n_particles < n_want:
        sim.insert_raindrop(n_want - sim.n_particles, draw,
                            region=((0.0, 0.0, H + rmax), (L, W, 2.0 * H - 2 * rmax)))
    if sim.n_particles < n_want:
        log.warning("repose: inserted %d of %d particles (box full)", sim.n_particles, n_want)
    dt = min(cfg["time"]["safety"] * model.rayleigh_time(draw.r_min),
             0.1 * model.hertz_time(draw.r_min, cfg["time"]["v_max"]))
    return {"positions": np.array(sim.x), "radii": np.array(sim.rad), "box_lo": np.array(lo),
            "box_hi": np.array(hi), "dt": float(dt), "n_wanted": n_want, "r_max": float(rmax)}


def _reference_contact(p, radii, *, height: float) -> dict:
    """LAMMPS' reference contact for this bed: the median sphere under the weight of the bed.

    LAMMPS' rolling stiffness (and the DMT/JKR stand-in for SJKR) is frozen at
    one contact (docs/backends.md); the defaults describe the seed's 26 um
    spheres. Here: the median radius r, and the Hertz overlap of two such
    spheres pressed by the weight of a column of ``height`` (packing 0.6).
    """
    r = float(np.median(radii))
    rstar = r / 2
    estar = p.effective_youngs_modulus()
    m = 4.0 / 3.0 * np.pi * r ** 3 * p.density
    n_layers = max(1.0, 0.6 * height / (2 * r))
    force = n_layers * m * max(p.gravity, 1e-12)
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
    from ..dem.backends import (ReposeGeometry, ReposeSchedule, repose_deck, run_deck,
                                write_sphere_data)
    from ..io import read_dump, write_dump
    from .repose import ReposeReplicate, measure_pile

    rc = cfg["repose"]
    L, W, H = (float(v) for v in rc["box"])
    engine = cfg["engine"]
    p, cm, model = _granular_params(cfg, cohesion)
    inp = repose_inputs(cfg, seed=seed)
    # a replicate not recorded as finished starts over (no restart of a killed engine run):
    # none of an earlier attempt's dumps or log is mixed into this one
    if stage_dir.exists():
        shutil.rmtree(stage_dir)
    stage_dir.mkdir(parents=True)
    data = write_sphere_data(stage_dir / "initial.data", inp["positions"], inp["radii"],
                             box_lo=inp["box_lo"], box_hi=inp["box_hi"], density=p.density,
                             n_types=2, title=f"bedstruct repose seed {seed}")
    ped = float(rc["pedestal_fraction"])
    slide = L if ped > 0 else float(rc["slide_fraction"]) * L
    v = float(rc["plate_speed"])
    geom = ReposeGeometry(L, W, H, periodic_width=bool(rc["periodic_width"]), ledge_fraction=ped,
                          plate_speed=v, slide=slide, wall_thickness=4 * inp["r_max"])
    sched = ReposeSchedule.from_times(inp["dt"], fill=float(rc["fill_time"]), slide=slide / v,
                                      drain=float(rc["drain_time"]),
                                      n_frames=max(1, int(rc["n_frames"])))
    ref = _reference_contact(p, inp["radii"], height=float(rc["fill_fraction"]) * H)
    deck = repose_deck(data, p, engine=engine, geometry=geom, schedule=sched, stl_folder=stage_dir,
                       contacts=bool(cfg["output"]["contacts"]), cohesion_model=cm, **ref)
    deck_path = stage_dir / "in.repose"
    deck_path.write_text(deck)
    n_inserted = len(inp["radii"])
    if write_only:
        return deck_path
    timeout = float(cfg["external"]["timeout"]) or None
    t0 = _time.perf_counter()
    run_deck(deck_path, engine=info, np=int(cfg["external"]["np"]), cwd=stage_dir, timeout=timeout)
    wall = _time.perf_counter() - t0
    traj = read_dump(stage_dir / "frames.dump", units="si")
    frame = traj[len(traj) - 1]
    write_dump(stage_dir / ("pile.dump.gz" if cfg["output"]["compress"] else "pile.dump"), frame)
    if cfg["output"]["compress"]:
        for name in ("frames.dump", "contacts.dump"):
            if (stage_dir / name).exists():
                _gzip(stage_dir / name)
    if not cfg["output"]["frames"]:
        for name in ("frames.dump", "frames.dump.gz"):
            (stage_dir / name).unlink(missing_ok=True)
    a, s, left, right, top = measure_pile(frame, cfg, r_max=inp["r_max"])
    return ReposeReplicate(seed=int(seed), cohesion=float(model.cohesion), angle_deg=a,
                           angle_std_deg=s, left_deg=left, right_deg=right, n_inserted=n_inserted,
                           n_remaining=int(frame.n_particles),
                           n_fallen=int(n_inserted - frame.n_particles), pile_height=float(top),
                           wall_time=wall, stage=stage_dir.name)


def run_repose_external(cfg: dict, *, out=None, cohesion: float | None = None,
                        replicates: int | None = None):
    """Angle of repose of ``cfg`` on LIGGGHTS or LAMMPS (``cfg["engine"]``).

    Parameters are those of :func:`~bedstruct.workflows.run_repose`; the
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
    bedstruct.dem.backends.EngineRunError
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
    import tempfile

    from .repose import (_finished_replicate, _record_replicate, combine_replicates,
                         repose_result_from_dict)

    n = int(cfg["repose"]["replicates"] if replicates is None else replicates)
    if n < 1:
        raise ConfigError(f"config key `repose.replicates` must be >= 1; got {n}")
    write_only = bool(cfg["external"]["write_only"])
    _check_effects(cfg, spreading=False)
    info = engine_for(cfg, required=not write_only)
    k = float(cfg["contact"]["cohesion"] if cohesion is None else cohesion)
    tmp = None
    if out is None:
        tmp = tempfile.mkdtemp(prefix="bedstruct-repose-")
        out = tmp
    try:
        layout = RunLayout(out, cfg, workflow="repose", inputs={"cohesion": k, "replicates": n})
        if not write_only:
            res = layout.reuse_results(repose_result_from_dict)
            if res is not None:
                return res
        reps = []
        for i in range(n):
            seed, stage = int(cfg["seed"]) + i, f"rep{i:02d}"
            rep = None if write_only else _finished_replicate(layout, stage, seed, k)
            if rep is None:
                rep = _repose_replicate(cfg, seed=seed, cohesion=k, stage_dir=layout.path / stage,
                                        info=info, write_only=write_only)
                if not write_only:
                    _record_replicate(layout, stage, rep)
            reps.append(rep)
        if write_only:
            np_ = int(cfg["external"]["np"])
            cmds = []
            for d in reps:
                if info is not None:
                    argv = info.command(["-in", d.name, "-log", "in.log"], np=np_)
                else:
                    argv = ([] if np_ == 1 else ["mpirun", "-np", str(np_)]) + [
                        "liggghts" if cfg["engine"] == "liggghts" else "lmp", "-in", d.name]
                cmds.append(f"cd {d.parent} && " + " ".join(argv))
            res = ExternalDecks(cfg["engine"], "repose", tuple(str(d) for d in reps), tuple(cmds))
            layout.write_results({"workflow": "repose", "engine": cfg["engine"], **res.to_dict()})
            return res
        res = combine_replicates(reps, k)
        layout.write_results({"workflow": "repose", "engine": cfg["engine"],
                              "np": int(cfg["external"]["np"]), "executable": info.executable,
                              **res.to_dict()})
        return res
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)



def run_spread_external(cfg: dict, *, out=None):
    """Spread ``spread.gaps`` layers of ``cfg`` on LIGGGHTS or LAMMPS (``cfg["engine"]``).

    Tools ``blade``/``rake``/``plate`` and ``roller``. The pile is generated by
    the embedded engine (:func:`bedstruct.workflows.spread.generate_pile`, same
    seed). **All layers run in one engine run**
    (:func:`bedstruct.dem.backends.spread_layers_deck`), so that the contact
    histories (tangential and rolling springs) of the bed carry over from
    layer to layer as in the embedded run: the piles of layers 2, 3... wait
    parked above the working area and are moved in front of the tool before
    their layer, onto whatever lies there; the platform is lowered by the gap
    at ``lower_speed`` and the tool returns above the bed, as in the embedded
    run. The roller (LIGGGHTS: STL cylinder moved by ``fix move/mesh`` linear
    + rotate; LAMMPS: a moving, rotating cylinder region) spins at
    ``roller_omega_factor * speed / roller_radius``. Frames are read back with
    :func:`bedstruct.io.read_dump`, contacts found from the overlaps
    (:func:`bedstruct.analysis.find_contacts`), and every layer is measured by
    :func:`bedstruct.workflows.spread.measure_layer`, the embedded run's code.
    LAMMPS' moving blade is unbevelled (docs/backends.md).

    The same call on a folder holding this run resumes it: a complete run gives its
    results back without running anything; an unfinished one reuses the finished pile
    (``pile/pile.dump.gz``; a killed generation goes on from ``pile/progress.npz``, as
    in :func:`~bedstruct.workflows.run_spread`) and, when the engine run finished
    (:func:`_engine_finished`), its output: only the measurement runs again. An engine
    run that did not finish runs again from its start, its output removed first.

    Returns
    -------
    SpreadResult or ExternalDecks
        ExternalDecks (the deck of all layers) when ``external.write_only``.
    """
    import tempfile
    import warnings

    from ..analysis import find_contacts
    from ..dem.backends import (BladeGeometry, RollerGeometry, SpreadLayersPlan, landing_offsets,
                                run_deck, spread_layers_deck, tool_loads, write_sphere_data)
    from ..io import read_dump, write_dump
    from .spread import _MAX_LANDING_WAIT, SpreadResult, _run_pile, spread_result_from_dict
    from .spread_measure import _REGION_NAMES, frame_metrics, measure_layer

    sc = cfg["spread"]
    tool_name = sc["tool"]
    if tool_name not in ("blade", "rake", "plate", "roller"):
        raise ConfigError(f"spread.tool must be blade, rake, plate or roller; got {tool_name!r}")
    gaps = [float(g) for g in sc["gaps"]]
    write_only = bool(cfg["external"]["write_only"])
    _check_effects(cfg, spreading=True)  # before any run (the pile is generated first)
    info = engine_for(cfg, required=not write_only)
    tmp = None
    if out is None:
        tmp = tempfile.mkdtemp(prefix="bedstruct-spread-")
        out = tmp
    try:
        layout = RunLayout(out, cfg, workflow="spread")
        if not write_only:
            res = layout.reuse_results(spread_result_from_dict)
            if res is not None:
                return res
        root = layout.path
        t_start = _time.perf_counter()
        seed = int(cfg["seed"])
        draw = psd_sampler(cfg)
        rmax = draw.r_max
        p, cm, model = _granular_params(cfg, None, spreading=True)
        pile = _run_pile(cfg, layout, seed=seed, draw=draw)   # a resumed run's finished pile
        gz = ".dump.gz" if cfg["output"]["compress"] else ".dump"
        Lplat, W, speed = float(sc["plate_length"]), float(sc["width"]), float(sc["speed"])
        if tool_name == "roller":
            R = float(sc["roller_radius"])
            half = R
            x0 = half + 0.5 * rmax            # roller axis at t = 0, as the embedded run
            omega = float(sc["roller_omega_factor"]) * speed / R
            tool = RollerGeometry(x0=x0, z_bottom=0.0, radius=R, speed=speed, omega=omega)
            x_stop = Lplat + float(sc["stop_margin"]) + half
            tool_top = tool.top
        else:
            half = 0.5 * float(sc["blade_thickness"])
            x0 = half + 0.5 * rmax            # blade mid-plane at t = 0, as the embedded run
            bevel = 0.0 if tool_name == "plate" else float(sc["bevel_deg"])
            tool = BladeGeometry(x0=x0 - half, z_bottom=0.0, speed=speed,
                                 thickness=float(sc["blade_thickness"]),
                                 height=float(sc["blade_height"]), bevel_deg=bevel)
            x_stop = Lplat + float(sc["stop_margin"])   # trailing face; mid-plane at x_end
            tool_top = float(sc["blade_height"])
            if bevel > 0 and cfg["engine"] == "lammps":
                log.warning("lammps: the moving blade is the unbevelled slab (docs/backends.md)")
        front0 = x0 + half
        x_end = Lplat + float(sc["stop_margin"]) + half
        depth = sum(gaps) + 6 * rmax
        pile_top = float(np.max(pile.positions[:, 2] + pile.radii))
        x_off = front0 + 0.5 * rmax
        lift = 0.25 * rmax
        clear = 3 * rmax
        n, K = pile.n_particles, len(gaps)
        # piles 2.. wait above the tool's highest point (after it rises by `clear`)
        park0 = max(tool_top, pile_top) + clear + 4 * rmax
        parked = [0.0] + [park0 + (k - 1) * (pile_top + 4 * rmax) for k in range(1, K)]
        lo = [-2 * rmax - 2 * half, 0.0, -depth]
        hi = [x_end + half + 4 * rmax, W,
              max(pile_top * 3, tool_top + clear) + (parked[-1] + pile_top if K > 1 else 0.0)
              + 4 * rmax]
        pv = pile.velocities if pile.velocities is not None else np.zeros((n, 3))
        po = pile.omegas if pile.omegas is not None else np.zeros((n, 3))
        z_plat0 = -gaps[0]
        X = np.concatenate([pile.positions + np.array([x_off, 0.0, (z_plat0 + lift) if k == 0
                                                       else parked[k]]) for k in range(K)])
        R_ = np.tile(pile.radii, K)
        dt = min(cfg["time"]["safety"] * model.rayleigh_time(draw.r_min),
                 0.1 * model.hertz_time(draw.r_min, cfg["time"]["v_max"]))
        plan = SpreadLayersPlan(
            Lplat, W, tuple(gaps), tool, tuple((1 + k * n, (k + 1) * n) for k in range(K)),
            tuple(parked), (x_off - 2 * rmax, x_off + float(sc["pile_length"]) + 2 * rmax), dt,
            lower_speed=float(sc["lower_speed"]), speed=speed,
            return_speed=float(sc["return_speed"]), settle_time=float(sc["settle_time"]),
            pile_lift=lift, clear=clear, x_end=x_stop,
            chamber_depth=(depth - 2 * rmax) if sc["chamber"] else 0.0,
            n_frames=max(1, int(sc["n_frames"])), wall_thickness=4 * rmax,
            landing_intervals=_MAX_LANDING_WAIT, landing_margin=rmax)
        data = write_sphere_data(root / "initial.data", X, R_, box_lo=lo, box_hi=hi,
                                 density=p.density, n_types=2, velocities=np.tile(pv, (K, 1)),
                                 omegas=np.tile(po, (K, 1)),
                                 title=f"bedstruct spread seed {seed}: {K} piles")
        for k in range(K):
            (root / f"layer{k + 1:02d}").mkdir(parents=True, exist_ok=True)
        ref = _reference_contact(p, pile.radii, height=pile_top)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            deck = spread_layers_deck(data, p, engine=cfg["engine"], plan=plan, stl_folder=root,
                                      contacts=bool(cfg["output"]["contacts"]),
                                      cohesion_model=cm, **ref)
        deck_path = root / "in.spread"
        deck_path.write_text(deck)
        np_ = int(cfg["external"]["np"])
        if write_only:
            argv = (info.command(["-in", deck_path.name, "-log", "in.log"], np=np_) if info else
                    ["liggghts" if cfg["engine"] == "liggghts" else "lmp", "-in", deck_path.name])
            res = ExternalDecks(cfg["engine"], "spread", (str(deck_path),),
                                (f"cd {root} && " + " ".join(argv),))
            layout.write_results({"workflow": "spread", "engine": cfg["engine"], **res.to_dict()})
            return res
        contacts = bool(cfg["output"]["contacts"])
        if layout.resumed and _engine_finished(root, plan, contacts=contacts):
            log.info("%s: the engine run had finished; its output is measured again", root)
        else:
            _clear_engine_output(root, K)
            timeout = float(cfg["external"]["timeout"]) or None
            run_deck(deck_path, engine=info, np=np_, cwd=root, log_path="in.log", timeout=timeout)
        wall_run = _time.perf_counter() - t_start
        # the landing waits shift every later event off the planned steps
        offsets = landing_offsets(root / "in.log", K)
        loads = tool_loads(root / "in.log", K)      # NaN on LAMMPS
        steps = plan.shifted(offsets)
        total_steps = plan.total_steps + offsets[-1]
        n_reg = int(sc["regions"])
        names = _REGION_NAMES.get(n_reg, tuple(f"region{i}" for i in range(n_reg)))
        layers, f_all, cn_all = [], [], []
        final = None
        for k, ls in enumerate(steps):
            t_layer = _time.perf_counter()
            stage = root / f"layer{k + 1:02d}"
            z_plat = -sum(gaps[:k + 1])
            n_active = (k + 1) * n
            traj = read_dump(_engine_file(stage, "frames.dump"), units="si")
            blade_pos, dyn, cn_series, mid = [], [], [], []
            final = None
            for i in range(len(traj)):
                fr = traj[i]
                fr = fr.select(np.asarray(fr.ids) <= n_active)   # parked piles are not there yet
                step = int(fr.timestep)
                if step == ls.end:
                    final = fr
                if not (ls.spread < step <= ls.stop):
                    continue
                front = front0 + speed * dt * (step - ls.spread)
                d_, c_ = frame_metrics(fr, find_contacts(fr), front, plate_length=Lplat,
                                       z_plat=z_plat, r_max=rmax)
                blade_pos.append(front)
                dyn.append(d_)
                cn_series.append(c_)
                if len(blade_pos) == max(1, int(sc["n_frames"]) // 2):
                    mid.append((fr, front))
            if final is None:
                final = traj[len(traj) - 1]
                final = final.select(np.asarray(final.ids) <= n_active)
            if cfg["output"]["compress"]:
                for name in ("frames.dump", "contacts.dump", "start.dump", "start_contacts.dump"):
                    if (stage / name).exists():
                        _gzip(stage / name)
            write_dump(stage / f"final{gz}", final)
            layer, pack, cnw = measure_layer(
                final, find_contacts(final), cfg, index=k + 1, z_plat=z_plat, front0=front0,
                r_max=rmax, pile=pile, dyn=dyn, cn_series=cn_series, blade_pos=blade_pos, mid=mid,
                n_inserted=n, n_removed=n_active - final.n_particles,
                wall_time=(wall_run * (ls.end - ls.start) / total_steps
                           + _time.perf_counter() - t_layer))
            wait = offsets[k] - (offsets[k - 1] if k else 0)
            layers.append(replace(layer, landing_wait=wait * dt, tool_force=loads[k]))
            f_all.extend(np.asarray(pack, float).tolist())
            cn_all.extend(np.asarray(cnw, float).tolist())
            log.info("layer %d on %s: bed height %.4g m (nominal %.4g)", k + 1, cfg["engine"],
                     layer.bed_height_m, -z_plat)
        ga, gb, gr = german_fit_values(f_all, cn_all)
        res = SpreadResult(layers=tuple(layers), tool=str(tool_name), speed=speed,
                           regions=tuple(names), n_pile=n, n_inserted_total=K * n,
                           german_a=ga, german_b=gb, german_r_squared=gr,
                           extra={"wall_time": _time.perf_counter() - t_start,
                                  "engine_wall_time": wall_run, "dt": dt,
                                  "steps": total_steps, "engine": cfg["engine"],
                                  "n_particles_final": int(final.n_particles)})
        layout.write_results({"workflow": "spread", "engine": cfg["engine"], "np": np_,
                              **res.to_dict()})
        return res
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def _engine_finished(root: Path, plan, *, contacts: bool) -> bool:
    """Whether ``root`` holds the output of a finished engine run of ``plan`` (all layers).

    Its log ends with the deck's end marker (:func:`~bedstruct.dem.backends.run_finished`,
    printed once every dump is closed), and every layer's frames (as the engine wrote
    them, or compressed by the post-processing, :func:`_engine_file`) read back complete
    up to the layer's last step, its contacts and start frames beside them.
    """
    from ..dem.backends import landing_offsets, run_finished
    from ..errors import BedstructError
    from ..io import read_dump
    log_path = root / "in.log"
    n = len(plan.layers)
    if not run_finished(log_path, n):
        return False
    for k, ls in enumerate(plan.shifted(landing_offsets(log_path, n))):
        stage = root / f"layer{k + 1:02d}"
        names = (["contacts.dump"] if contacts else []) + (
            (["start.dump"] + (["start_contacts.dump"] if contacts else [])) if k else [])
        frames = _engine_file(stage, "frames.dump")
        if frames is None or any(_engine_file(stage, name) is None for name in names):
            return False
        try:
            steps = read_dump(frames, units="si").timesteps
        except (BedstructError, OSError, EOFError, ValueError):
            return False
        if not len(steps) or int(steps[-1]) != ls.end:
            return False
    return True


def _clear_engine_output(root: Path, n_layers: int) -> None:
    """Remove the log and layer folders of an earlier engine run in ``root`` that did not
    finish, so that none of its output is mixed into the run that starts over."""
    (root / "in.log").unlink(missing_ok=True)
    for k in range(n_layers):
        stage = root / f"layer{k + 1:02d}"
        if stage.exists():
            shutil.rmtree(stage)
        stage.mkdir()
