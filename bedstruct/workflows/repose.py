"""Angle-of-repose workflow: fill a box by raindrop insertion, slide the bottom plate out, measure the pile.

Geometry (SI, the box spans ``[0, L] x [0, W] x [0, H]``): side plates
(:func:`bedstruct.dem.repose_box`; across y the side walls of
:func:`~bedstruct.workflows._common.side_walls`, or y periodic with
``repose.periodic_width``), a bottom plate named ``plate`` and, when
``repose.pedestal_fraction > 0``, a fixed ledge of that fraction of ``L``
centred under the box. The box is filled to about ``fill_fraction`` of its
height by raindrop insertion and settles; the plate then slides towards
``-x`` at ``plate_speed`` by ``slide_fraction * L`` (by ``L`` with a ledge).
Particles that fall leave the domain through the reservoir below (they are
counted in ``n_fallen``). The remaining pile is measured with
:func:`bedstruct.analysis.angle_of_repose`: with a ledge it has two free
flanks (both fitted), without one a single free flank facing the opening.
"""

from __future__ import annotations

import logging
import time as _time

import numpy as np

from ..errors import ConfigError
from ._common import (check_engine, contact_model, insert_carrying, mean_sphere_volume,
                      progress_bar, psd_sampler, side_walls, typed, width_bounds)
from ._resume import resumable_simulation, run_in_frames
from ._rundir import RunLayout, clear_run, marks_failure
from .config import check_run_geometry
from .external import run_repose_external
from .repose_measure import (ReposeReplicate, ReposeResult, _finished_replicate,
                             _record_replicate, combine_replicates, measure_pile,
                             measure_replicate_pile, repose_result_from_dict)

__all__ = ["ReposeReplicate", "ReposeResult", "run_repose", "repose_replicate", "measure_pile",
           "repose_result_from_dict"]

log = logging.getLogger(__name__)


def _record_run(ctl, total_time, writer, n_frames):
    """Run ``total_time`` recording ``n_frames`` frames evenly (at least at the end)."""
    if writer is None or n_frames <= 0:
        ctl.run_time(total_time)
        return
    run_in_frames(ctl, total_time, n_frames, lambda: ctl.do(lambda: writer.record(ctl.sim)))


def repose_replicate(cfg, *, seed: int, cohesion: float | None = None, layout=None,
                     stage: str = "") -> ReposeReplicate:
    """Run one angle-of-repose simulation of configuration ``cfg`` (see :func:`run_repose`).

    With a ``layout`` and a ``stage`` the replicate checkpoints into
    ``<stage>/progress.npz`` every ``output.checkpoint_every`` steps and, when that file is
    there, restarts from it (the result is the uninterrupted run's). :func:`run_repose`
    records the finished replicate in ``<stage>/result.json`` and removes the checkpoint.
    """
    from ..core import Box
    from ..dem import Rectangle, box_walls

    cfg = typed(cfg)
    check_engine(cfg)
    rc = cfg.repose
    L, W, H = (float(v) for v in rc.box)
    model = contact_model(cfg, cohesion=cohesion)
    k = float(model.cohesion)
    draw = psd_sampler(cfg)
    rmax = draw.r_max
    periodic = bool(rc.periodic_width)
    depth = float(rc.reservoir_depth)
    margin = 4 * rmax
    ylo, yhi, ybound = width_bounds(W, walls=not periodic, margin=margin)
    box = Box([-margin - L, ylo, -depth], [L + margin, yhi, 2.0 * H],
              boundary=("ff", ybound, "ff"))
    walls = box_walls([0.0, 0.0, 0.0], [L, W, H], open_top=True, sides=("x",), prefix="box")
    walls[0].name = "plate"
    if not periodic:
        walls += side_walls(W, x_range=(0.0, L), z_range=(0.0, H))
    # the plate: wide enough along y to cover the periodic seam
    plate = walls[0]
    plate.half_sizes = (L / 2, W if periodic else W / 2)
    ped = float(rc.pedestal_fraction)
    if ped > 0:
        walls.append(Rectangle(center=(L / 2, W / 2, 0.0), normal=(0, 0, 1), axis=(1, 0, 0),
                               half_sizes=(ped * L / 2, W if periodic else W / 2), name="ledge"))
    writer = layout.stage(stage, reset=False) if layout is not None and stage else None
    folder = None if writer is None else writer.path
    ctl, sim = resumable_simulation(cfg, None if folder is None else folder / "progress.npz", box,
                                    model, walls, min_radius=draw.r_min, seed=seed, root=folder)
    if writer is not None:
        ctl.do(writer.reset)
    t0 = _time.perf_counter()
    n_want = int(rc.n_particles)
    if n_want <= 0:  # auto: fill_fraction of the box at a packing fraction of 0.6
        n_want = int(0.6 * L * W * H * float(rc.fill_fraction) / mean_sphere_volume(draw))
    region_top = H * 1.0
    n_inserted = 0   # every particle inserted, also those lost while the box fills

    def fill_round(top, carried):
        need = n_want - sim.n_particles
        if need <= 0:
            return [0, top]
        zlo = float(np.max(sim.x[:, 2] + sim.rad)) + 1e-9 if sim.n_particles else 0.0
        if top - zlo < 4 * rmax:
            top = zlo + max(0.5 * H, 4 * rmax)
        n0 = sim.n_particles
        # the radii a round found no room for go into the next one: the pile keeps the PSD
        left = insert_carrying(sim, need, carried, draw, ((0.0, 0.0, zlo), (L, W, top)))
        return [sim.n_particles - n0, top, need, left]

    carried = []
    for _ in range(6):
        got = ctl.value(lambda c=carried: fill_round(region_top, c))
        if len(got) == 2:  # the box holds n_want
            break
        n_inserted += int(got[0])
        region_top = got[1]
        carried = got[3]
        ctl.run_time(0.5 * rc.fill_time)
    if n_inserted < n_want and not ctl.replaying:
        log.warning("repose: inserted %d of %d particles (box full)", n_inserted, n_want)
    ctl.run_time(0.5 * rc.fill_time)
    if float(rc.rest_time) > 0.0:  # the settled pile rests: its contacts age (no steps)
        ctl.do(lambda: sim.age_contacts(float(rc.rest_time)))
    if writer is not None:
        ctl.do(lambda: writer.record(sim))
    slide = L if ped > 0 else float(rc.slide_fraction) * L
    v = float(rc.plate_speed)
    ctl.do(lambda: sim.set_wall_motion("plate", velocity=(-v, 0.0, 0.0)))
    _record_run(ctl, slide / v, writer, max(1, int(rc.n_frames) // 2))
    ctl.do(lambda: sim.set_wall_motion("plate", velocity=(0.0, 0.0, 0.0)))
    _record_run(ctl, float(rc.drain_time), writer,
                max(1, int(rc.n_frames) - int(rc.n_frames) // 2))

    def finish():
        frame = writer.final(sim, "pile") if writer is not None else sim.frame()
        a, s, left, right, top, note = measure_replicate_pile(
            frame, cfg, r_max=rmax, n_inserted=n_inserted, n_fallen=int(sim.n_removed),
            label=f"{stage or ''} (seed {int(seed)})")
        lost = int(sim.n_lost_nonfinite)
        if lost:
            log.warning("repose: %d particle(s) were lost to non-finite positions (a blow-up)",
                        lost)
        return dict(angle_deg=float(a), angle_std_deg=float(s), left_deg=float(left),
                    right_deg=float(right), n_remaining=int(frame.n_particles),
                    n_fallen=int(sim.n_removed), n_lost_nonfinite=lost, pile_height=float(top),
                    note=note)
    m = ctl.value(finish)
    rep = ReposeReplicate(seed=int(seed), cohesion=k, n_inserted=n_inserted,
                          wall_time=_time.perf_counter() - t0,
                          stage=stage if writer is not None else "", **m)
    return rep


def run_repose(cfg, *, out=None, cohesion: float | None = None, replicates: int | None = None,
               progress: bool = False, overwrite: bool = False) -> ReposeResult:
    """Static angle of repose of configuration ``cfg`` over replicate seeds.

    Parameters
    ----------
    cfg : dict or WorkflowConfig
        From :func:`~bedstruct.workflows.load_config` (section ``repose``,
        ``material``, ``contact``, ``psd``), or its
        :func:`~bedstruct.workflows.typed_config`. A dict is loaded and checked once
        (:func:`~bedstruct.workflows.config.workflow_config`).
    out : path, optional
        Run directory (see :class:`~bedstruct.workflows.RunLayout`); nothing
        is written without it.
    cohesion : float, J/m^3, optional
        Override ``contact.cohesion``.
    replicates : int, optional
        Override ``repose.replicates``; replicate ``i`` uses seed ``seed + i``.
    progress : bool, optional
        Show a progress bar over the replicates (stderr; embedded engine).
    overwrite : bool, optional
        Replace an earlier run in ``out``. Without it, an earlier run of the same
        configuration, cohesion and replicates is resumed (finished replicates are reused,
        an unfinished one restarts from its checkpoint) and one of another is refused
        with a ConfigError (:class:`~bedstruct.workflows.RunLayout`).

    Returns
    -------
    ReposeResult
        (:class:`~bedstruct.workflows.external.ExternalDecks` for an external
        engine with ``external.write_only``.) ``engine`` = ``liggghts``
        or ``lammps`` runs :func:`~bedstruct.workflows.external.run_repose_external`.

    Examples
    --------
    >>> from bedstruct.workflows import load_config, run_repose
    >>> cfg = load_config(preset="tiny")
    >>> res = run_repose(cfg, replicates=1)          # doctest: +SKIP
    >>> 10 < res.angle_deg < 60                      # doctest: +SKIP
    True
    """
    cfg = typed(cfg)
    if cfg.engine != "embedded":
        if overwrite and out is not None:
            clear_run(out)
        return run_repose_external(cfg, out=out, cohesion=cohesion, replicates=replicates)
    n = int(cfg.repose.replicates if replicates is None else replicates)
    if n < 1:
        raise ConfigError(f"config key `repose.replicates` must be >= 1; got {n}")
    k = float(cfg.contact.cohesion if cohesion is None else cohesion)
    if k < 0:
        raise ConfigError(f"config key `contact.cohesion` must be >= 0; got {k}")
    check_run_geometry(cfg, "repose")
    layout = (RunLayout(out, cfg, workflow="repose", inputs={"cohesion": k, "replicates": n},
                        overwrite=overwrite) if out is not None else None)
    res = layout.reuse_results(repose_result_from_dict) if layout is not None else None
    if res is not None:
        return res
    reps = []
    with marks_failure(layout):
        for i in progress_bar(range(n), desc="repose", unit="replicate", progress=progress):
            seed, stage = int(cfg.seed) + i, f"rep{i:02d}"
            rep = _finished_replicate(layout, stage, seed, k)
            if rep is None:
                rep = repose_replicate(cfg, seed=seed, cohesion=k, layout=layout, stage=stage)
                if layout is not None:  # finished: recorded, its checkpoint no longer needed
                    _record_replicate(layout, stage, rep)
            reps.append(rep)
    res = combine_replicates(reps, k)
    if layout is not None:
        layout.write_results({"workflow": "repose", **res.to_dict()})
    return res
