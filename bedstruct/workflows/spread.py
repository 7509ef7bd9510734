"""Multi-layer spreading workflow: pile, tool (blade/rake, plate or roller), platform lowered per layer.

Geometry (SI): a build platform (``platform``, a plate of length
``plate_length`` along x from x = 0) in a y-periodic strip of width
``width`` or, with ``spread.side_walls``, between fixed side walls at y = 0
and y = ``width`` (``side_ylo``, ``side_yhi``) that bound the platform, the pile
and the tool, a fixed back wall at x = 0 and, with ``spread.chamber`` (default),
a front wall at x = ``plate_length`` reaching up to the tool level, so that
the platform is a piston in a build chamber; powder pushed over the front wall
(or, without it, off the platform end) falls into the overflow and leaves the
domain (counted as removed). The
tool's lowest point stays at z = 0. Before layer k the platform is lowered
by ``gaps[k]`` at ``lower_speed`` (the bed follows under gravity), so the
tool skims ``H_k = gaps[0] + ... + gaps[k]`` above the platform. The pile is
generated once (raindrop insertion into a box, settled) and reinserted in
front of the tool before every layer, on what lies there once powder thrown
up by the previous stroke has landed (:func:`particles_in_flight`). The tool then crosses the platform at
``speed``; ``n_frames`` frames are recorded (atoms, contacts, wall states),
the dynamic angle of the heap and the mean coordination are measured on
each. After the tool has passed the end, the bed is measured per region
(start, centre, end): height above the platform, packing fraction,
coordination, fabric; the tool returns above the bed for the next layer.
"""

from __future__ import annotations

import logging
import time as _time
from dataclasses import replace

import numpy as np

from ..errors import ConfigError
from .._json import to_jsonable
from ._common import (check_engine, contact_model, frame_fingerprint, from_plain,
                      german_fit_values, progress_bar, psd_sampler, side_walls, tool_motion, typed,
                      width_bounds)
from ._resume import as_resumable, resumable_simulation, run_in_frames
from ._rundir import RunLayout, clear_run, marks_failure
from .config import check_run_geometry
from .external_spread import run_spread_external
from .spread_measure import (_MAX_LANDING_WAIT, _REGION_NAMES, LayerResult, SpreadResult,
                             _subset_contacts, bed_mask, frame_metrics, measure_layer,
                             mid_layer_segregation, particles_in_flight, spread_result_from_dict)
from .spread_pile import _run_pile, generate_pile, pile_key

__all__ = ["LayerResult", "SpreadResult", "run_spread", "generate_pile", "pile_key",
           "spread_result_from_dict"]

log = logging.getLogger(__name__)


def _tool_walls(cfg, x0, draw):
    from ..dem import Blade, Cylinder
    sc = cfg.spread
    tool = sc.tool
    if tool in ("blade", "rake", "plate"):
        bevel = 0.0 if tool == "plate" else float(sc.bevel_deg)
        w = Blade(gap=1e-12, speed=0.0, x0=x0, surface_z=0.0, thickness=float(sc.blade_thickness),
                  bevel_deg=bevel, height=float(sc.blade_height), y_center=0.5 * float(sc.width),
                  name="tool")
        w.velocity = (0.0, 0.0, 0.0)
        return w, 0.5 * float(sc.blade_thickness)
    R = float(sc.roller_radius)
    return Cylinder(point=(x0, 0.5 * float(sc.width), R), axis=(0, 1, 0), radius=R,
                    name="tool"), R



def _move(ctl, name, velocity, distance, speed):
    if distance <= 0:
        return
    ctl.do(lambda: ctl.sim.set_wall_motion(name, velocity=velocity))
    ctl.run_time(distance / speed)
    ctl.do(lambda: ctl.sim.set_wall_motion(name, velocity=(0.0, 0.0, 0.0)))


def run_spread(cfg, *, out=None, progress: bool = False, pile=None,
               overwrite: bool = False) -> SpreadResult:
    """Spread ``len(spread.gaps)`` layers with the configured tool and measure each.

    Parameters
    ----------
    cfg : dict or WorkflowConfig
        From :func:`~bedstruct.workflows.load_config` (section ``spread``), or its
        :func:`~bedstruct.workflows.typed_config`. A dict is loaded and checked once
        (:func:`~bedstruct.workflows.config.workflow_config`).
    out : path, optional
        Run directory (see :class:`~bedstruct.workflows.RunLayout`): stage
        ``pile`` (the generated pile) and ``layer01``, ``layer02``... with
        frames, contacts, wall states and ``bed.dump.gz`` /
        ``bed_contacts.dump.gz`` after the layer. The run checkpoints into
        ``progress.npz`` after every layer and every ``output.checkpoint_every`` steps.
    progress : bool, optional
        Show progress bars over the pile's generation and the layers (stderr; embedded
        engine).
    pile : Frame, optional
        The settled pile, as ``generate_pile(cfg, seed=seed)[0]`` returns it (``seed``: the
        configuration's)
        (default: generated here). Runs with the same :func:`pile_key` and seed (for
        example at different speeds) can share one.
    overwrite : bool, optional
        Replace an earlier run in ``out``. Without it, an earlier run of the same
        configuration (and pile) is resumed: a finished one gives its results back, an
        unfinished one restarts from its latest checkpoint (finished layers are not run
        again; the results equal an uninterrupted run's), and a run of another
        configuration is refused with a ConfigError.

    Returns
    -------
    SpreadResult

    Examples
    --------
    >>> from bedstruct.workflows import load_config, run_spread
    >>> res = run_spread(load_config(preset="tiny"))   # doctest: +SKIP
    >>> [round(h * 1e6) for h in res.bed_height_m]      # doctest: +SKIP
    [...]
    """
    from ..core import Frame

    cfg = typed(cfg)
    if cfg.engine != "embedded":  # every layer on LIGGGHTS/LAMMPS
        if pile is not None:
            raise ConfigError("run_spread: a given pile is for the embedded engine; LIGGGHTS and "
                              "LAMMPS decks generate their own")
        if overwrite and out is not None:
            clear_run(out)
        return run_spread_external(cfg, out=out)
    check_engine(cfg)
    check_run_geometry(cfg, "spread")
    if pile is not None:
        if not isinstance(pile, Frame):
            raise TypeError(f"run_spread: `pile` must be a Frame (from generate_pile); got "
                            f"{type(pile).__name__}")
        if pile.n_particles == 0:
            raise ConfigError("run_spread: the given pile has no particles")
    inputs = {} if pile is None else {"pile": frame_fingerprint(pile)}
    layout = (RunLayout(out, cfg, workflow="spread", inputs=inputs, overwrite=overwrite)
              if out is not None else None)
    _warn_pile_overhang(cfg, psd_sampler(cfg).r_max)
    with marks_failure(layout):
        return _spread_layers(cfg, layout, pile=pile, progress=progress)


def _warn_pile_overhang(cfg, r_max: float) -> None:
    """Log a warning when the pile, inserted in front of the tool, reaches past the platform."""
    sc = cfg.spread
    half = (0.5 * float(sc.blade_thickness) if sc.tool in ("blade", "rake", "plate")
            else float(sc.roller_radius))
    x_off = 2 * half + r_max
    over = x_off + float(sc.pile_length) - float(sc.plate_length)
    if over > 0:
        log.warning("spread: the pile (spread.pile_length %.4g m), inserted in front of the "
                    "tool at x = %.4g m, reaches %.4g m past the platform end "
                    "(spread.plate_length %.4g m): that part falls into the overflow before "
                    "the tool moves", float(sc.pile_length), x_off, over,
                    float(sc.plate_length))


def _spread_layers(cfg, layout, *, pile, progress) -> SpreadResult:
    """The embedded spreading run of :func:`run_spread` into ``layout`` (or None)."""
    from ..core import Box
    from ..dem import Plane, Rectangle
    sc = cfg.spread
    res = layout.reuse_results(spread_result_from_dict) if layout is not None else None
    if res is not None:
        (layout.path / "progress.npz").unlink(missing_ok=True)
        return res
    seed = int(cfg.seed)
    draw = psd_sampler(cfg)
    rmax = draw.r_max
    Lplat, W = float(sc.plate_length), float(sc.width)
    gaps = [float(g) for g in sc.gaps]
    speed = float(sc.speed)
    n_reg = int(sc.regions)
    names = _REGION_NAMES.get(n_reg, tuple(f"region{i}" for i in range(n_reg)))
    t_start = _time.perf_counter()

    pile = _run_pile(cfg, layout, seed=seed, draw=draw, pile=pile, progress=progress)
    n_pile = pile.n_particles
    pile_top = float(np.max(pile.positions[:, 2] + pile.radii))

    H_total = sum(gaps)
    depth = H_total + 6 * rmax
    _, half = _tool_walls(cfg, 0.0, draw)      # half thickness (blade) or radius (roller)
    x0 = half + 0.5 * rmax                     # the tool starts just in front of the back wall
    tool, half = _tool_walls(cfg, x0, draw)
    front0 = x0 + half
    x_end = Lplat + float(sc.stop_margin) + half
    walled = bool(sc.side_walls)
    ylo, yhi, ybound = width_bounds(W, walls=walled, margin=4 * rmax)
    box = Box([-2 * rmax - 2 * half, ylo, -depth],
              [x_end + half + 4 * rmax, yhi, max(pile_top * 3, float(sc.blade_height)) + depth],
              boundary=("ff", ybound, "ff"))
    walls = [Rectangle(center=(Lplat / 2, W / 2, 0.0), normal=(0, 0, 1), axis=(1, 0, 0),
                       half_sizes=(Lplat / 2, W), name="platform"),
             Plane((0.0, 0.0, 0.0), (1, 0, 0), name="back"), tool]
    if sc.chamber:
        # front wall of the build chamber: from below the lowest platform position up to the
        # tool level (z = 0); the excess is pushed over its top into the overflow
        zc = 0.5 * (depth - 2 * rmax)
        walls.append(Rectangle(center=(Lplat, W / 2, -zc), normal=(-1, 0, 0), axis=(0, 0, 1),
                               half_sizes=(zc, W), name="front"))
    if walled:  # across y: the side walls bound the platform, the pile and the tool
        walls += side_walls(W, x_range=(box.lo[0], box.hi[0]), z_range=(box.lo[2], box.hi[2]),
                            prefix="side")
    model = contact_model(cfg)
    folder = None if layout is None else layout.path
    ctl, sim = resumable_simulation(cfg, None if folder is None else folder / "progress.npz", box,
                                    model, walls, min_radius=draw.r_min, seed=seed, root=folder)
    z_plat = 0.0
    # spin about +y; the surface velocity is u + omega e_y x (R e_r), so omega = -speed/R
    # (factor -1) moves the bottom of the roller forwards: counter-rotating
    omega = float(sc.roller_omega_factor) * speed / float(sc.roller_radius)
    layers = []
    f_all, cn_all = [], []
    inserted_total = 0
    clear = 3 * rmax
    n_frames = int(sc.n_frames)
    i_mid = max(1, n_frames // 2)
    writer = None
    for k, gap in enumerate(progress_bar(gaps, desc="spread", unit="layer", progress=progress)):
        t_layer = _time.perf_counter()
        writer = layout.stage(f"layer{k + 1:02d}", reset=False) if layout is not None else None
        if writer is not None:
            ctl.do(writer.reset)
        # 1. lower the platform by this layer's gap; the bed follows under gravity
        _move(ctl, "platform", (0.0, 0.0, -float(sc.lower_speed)), gap, float(sc.lower_speed))
        z_plat -= gap
        ctl.run_time(min(float(sc.settle_time), 2 * gap / float(sc.lower_speed)))
        # 2. reinsert the pile in front of the tool, above whatever is there once powder
        #    thrown up by the stroke has landed (a pile inserted above particles in flight
        #    would fall from their height onto the bed)
        x_off = front0 + 0.5 * rmax
        foot_x = (x_off - 2 * rmax, x_off + float(sc.pile_length) + 2 * rmax)
        waited = _land_flyers(ctl, z_plat, foot_x, float(sc.settle_time), layer=k + 1)

        def insert_pile():
            foot = (sim.x[:, 0] > foot_x[0]) & (sim.x[:, 0] < foot_x[1])
            z_base = max(z_plat, float(np.max(sim.x[foot, 2] + sim.rad[foot]))
                         if foot.any() else z_plat)
            n_before = sim.n_particles
            sim.insert_frame(pile, offset=(x_off, 0.0, z_base + 0.25 * rmax))
            return sim.n_particles - n_before
        n_ins = int(ctl.value(insert_pile))
        inserted_total += n_ins
        ctl.run_time(float(sc.settle_time))
        # 3. spread, recording frames
        def start_tool():
            if sc.tool == "roller":
                tool_motion(sim, cfg, "tool", (speed, 0.0, 0.0), omega=omega)
            else:
                tool_motion(sim, cfg, "tool", (speed, 0.0, 0.0))
            sim.start_wall_load_average()
        ctl.do(start_tool)
        blade_pos, dyn, cn_series, seg = [], [], [], []

        def look():
            fr = sim.frame()
            ws = {w.name: w for w in sim.wall_states()}
            front = float(ws["tool"].origin[0]) + half
            d_, c_ = frame_metrics(fr, sim.contacts(), front, plate_length=Lplat, z_plat=z_plat,
                                   r_max=rmax)
            if writer is not None:
                writer.record(sim, frame=fr)
            s_ = (mid_layer_segregation(fr, front, Lplat, pile)
                  if len(blade_pos) + 1 == i_mid else None)
            return [front, d_, c_, s_]

        def on_frame():
            front, d_, c_, s_ = ctl.value(look)
            blade_pos.append(front)
            dyn.append(d_)
            cn_series.append(c_)
            if s_ is not None:
                seg.append(s_)
        run_in_frames(ctl, (x_end - x0) / speed, n_frames, on_frame)
        tool_force = ctl.value(lambda: sim.wall_load_average()["tool"])
        stop = {"omega": 0.0} if sc.tool == "roller" else {}
        ctl.do(lambda: sim.set_wall_motion("tool", velocity=(0.0, 0.0, 0.0), **stop))
        ctl.run_time(float(sc.settle_time))

        # 4. measure the bed
        def measure():
            fr = sim.frame()
            contacts_all = sim.contacts()
            keep = bed_mask(fr, Lplat, z_plat, rmax)
            if writer is not None:
                writer.write_frame("bed", fr.select(keep), _subset_contacts(contacts_all, keep))
            layer, pack, cnw = measure_layer(
                fr, contacts_all, cfg, index=k + 1, z_plat=z_plat, front0=front0, r_max=rmax,
                pile=pile, dyn=dyn, cn_series=cn_series, blade_pos=blade_pos, mid=[], bed=keep,
                segregation_values=seg[0] if seg else None, n_inserted=n_ins,
                n_removed=int(sim.n_removed), wall_time=_time.perf_counter() - t_layer)
            layer = replace(layer, landing_wait=waited,
                            tool_force=tuple(float(v) for v in tool_force))
            return [layer, pack, cnw]
        ld, pack, cnw = ctl.value(measure)
        layer = from_plain(LayerResult, ld)
        layers.append(layer)
        f_all.extend(float(v) for v in pack)
        cn_all.extend(float(v) for v in cnw)
        if not ctl.replaying:
            log.info("layer %d: bed height %.4g m (nominal %.4g), %d in bed", k + 1,
                     layer.bed_height_m, layer.nominal_height, layer.n_bed)
        # 5. return the tool above the bed to its start
        if k + 1 < len(gaps):
            vr = float(sc.return_speed)
            _move(ctl, "tool", (0.0, 0.0, vr), clear, vr)
            back = ctl.value(lambda: float(sim.wall_states()[sim.wall_names.index("tool")]
                                           .origin[0]) - x0)
            _move(ctl, "tool", (-vr, 0.0, 0.0), back, vr)
            _move(ctl, "tool", (0.0, 0.0, -vr), clear, vr)
        # the layer is done: a resumed run starts after it
        ctl.checkpoint()
        if writer is not None and cfg.output.checkpoint and k + 1 < len(gaps):
            ctl.do(lambda: sim.save_checkpoint(writer.path / "checkpoint.npz"))
    ga, gb, gr, gd = german_fit_values(f_all, cn_all)
    run_info = ctl.value(lambda: {"dt": sim.dt, "steps": sim.step,
                                  "n_particles_final": sim.n_particles})
    res = SpreadResult(layers=tuple(layers), tool=str(sc.tool), speed=speed, regions=tuple(names),
                       n_pile=n_pile, n_inserted_total=inserted_total, german_a=ga, german_b=gb,
                       german_r_squared=gr, german_determined=gd,
                       extra={"wall_time": _time.perf_counter() - t_start, **run_info})
    if layout is not None:
        if writer is not None:
            ctl.do(lambda: writer.final(sim, "final"))
        layout.write_results({"workflow": "spread", **res.to_dict()})
        ctl.finish()
    return res


def _land_flyers(sim, z_plat: float, foot, settle_time: float, *, layer: int) -> float:
    """Settle in intervals of ``settle_time`` while particles in flight over the pile's foot
    ``(xa, xb)`` (:func:`particles_in_flight`) would lift the pile by more than the largest
    radius above what rests there; returns the time waited (0: the state is untouched).

    ``sim`` is a :class:`~bedstruct.dem.Simulation` or the run's
    :class:`~bedstruct.workflows._resume.Resumable`."""
    ctl = as_resumable(sim)

    def n_flying():
        fr = ctl.sim.frame()
        flying = particles_in_flight(fr, z_plat, foot, gravity=ctl.sim.gravity)
        if flying.any():
            p, r = fr.positions, fr.radii
            top = p[:, 2] + r
            foot_mask = (p[:, 0] >= foot[0]) & (p[:, 0] <= foot[1]) & ~flying
            rest_top = max(z_plat, float(top[foot_mask].max()) if foot_mask.any() else z_plat)
            flying &= top > rest_top + float(r.max())
        return int(flying.sum())

    waited = 0.0
    for attempt in range(_MAX_LANDING_WAIT + 1):
        n_fly = ctl.value(n_flying)
        if not n_fly:
            if waited and not ctl.replaying:
                log.info("layer %d: waited %.3g s for powder thrown up by the stroke to land "
                         "before reinserting the pile", layer, waited)
            return waited
        if attempt == _MAX_LANDING_WAIT:
            if not ctl.replaying:
                log.warning("layer %d: %d particle(s) still in flight over the pile's foot "
                            "after %.3g s; the pile is reinserted above them", layer, n_fly,
                            waited)
            return waited
        ctl.run_time(settle_time)
        waited += settle_time
    raise AssertionError("unreachable")  # the last attempt returns
