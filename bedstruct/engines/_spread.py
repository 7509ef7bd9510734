"""Multi-layer spreading as **one** LIGGGHTS or LAMMPS run: every layer in one deck.

:func:`spread_layers_deck` writes the whole spreading experiment of
:func:`bedstruct.workflows.run_spread` (all layers, blade/plate or roller)
as a single deck, so that the contact histories (tangential and rolling
springs of particle-particle contacts) carry over from one layer to the next
as they do in the embedded engine; a deck per layer restarted them.

How the deck reproduces the embedded workflow:

* every pile is in the data file from the start; pile 1 lies in front of the
  tool, piles 2, 3... are *parked* above the working area (not integrated:
  ``fix nve/sphere`` acts on the group ``active`` only; left out of the pair
  lists by ``neigh_modify exclude group``) and are moved into
  place before their layer by ``displace_atoms``, their bottom
  ``pile_lift`` above the highest sphere in the pile's footprint (``compute
  reduce/region`` of ``z + radius``), as the embedded run places them;
* before layers 2, 3... the platform is lowered by the gap at ``lower_speed``
  and the bed settles, as in the embedded run; then, as the embedded run does,
  the deck settles in intervals of ``settle_time`` (at most
  ``landing_intervals``) while spheres in free flight over the pile's footprint
  (the total force on them is their weight within half of it) reach more than
  ``landing_margin`` above the highest sphere resting there, so that the pile
  is not placed on powder the stroke threw up (a loop of ``if``/``jump``);
* the tool crosses the platform at ``speed`` (LIGGGHTS: ``fix move/mesh
  linear``; the roller also ``rotate`` about its own axis, the superposed
  motion carrying the rotation axis along), settles, then returns above the
  bed (up, back, down at ``return_speed``) for the next layer;
* LAMMPS: block/cylinder regions moved by step-ramp variables
  (``wall/gran/region``; the blade is the unbevelled slab, docs/backends.md);
* with ``plan.side_walls`` y is not periodic: fixed planes at y = 0 and y = W
  (``fix wall/gran`` ``yplane``, the particle-wall contact of the other fixed
  walls) bound the platform, the piles and the tool.

The walls, the tool's motion and the source of its load come from the dialect
(:meth:`~bedstruct.engines.Dialect.spread_walls`, :meth:`~bedstruct.engines.Dialect.moving_run`,
:attr:`~bedstruct.engines.Dialect.tool_load`); the sequence is the same for every engine.

The waits make the step of every later event depend on the run. The deck keeps
the plan's steps as *planned* steps: the equal-style variable ``off`` holds the
steps waited so far, LAMMPS' wall motions are functions of ``step - v_off``, the
frames are written every ``every`` steps from the layer's actual start of the
tool motion (``dump_modify every v_...``), and before each layer's tool motion
the deck prints ``BEDSTRUCT_OFFSET layer=K steps=N`` (the log's record of the
offset; :func:`~bedstruct.engines.landing_offsets` reads it back): an event
of layer K happens at its planned step plus N.

Outputs per layer (folders ``layer01``... must exist): ``frames.dump``
(and ``contacts.dump``) from the start of the tool motion to the end of the
layer, every ``every`` steps; from layer 2 on also ``start.dump`` (and
``start_contacts.dump``), one frame as the layer starts (the bed at rest,
before the platform moves). Parked spheres appear in them (select by id:
pile ``k`` has ids ``pile_ids[k][0]..pile_ids[k][1]``). :class:`SpreadLayersPlan`
gives the step of each event so that frames can be matched to tool positions.
The deck's last command prints ``BEDSTRUCT_DONE layer=K`` (K layers), after every
dump is closed: :func:`~bedstruct.engines.run_finished` tells a finished run
from a killed one by it.
"""

from __future__ import annotations

import math

from ._dialect import DUMP_COLUMNS
from ._logs import _DONE_LINE, _LOAD_LINE, _OFFSET_LINE
from ._params import check_gravity
from ._registry import dialect
from ._scenarios import SpreadLayersPlan, tool_top
from ._stl import RollerGeometry

__all__ = ["spread_layers_deck"]


def spread_layers_deck(data_file, model=None, *, engine: str, plan: SpreadLayersPlan,
                       gravity: float = 9.81, stl_folder=None, contacts: bool = True, skin: float | None = None,
                       cohesion_model: str | None = None,
                       reference_radius: float | None = None,
                       reference_overlap: float | None = None, np: int = 1) -> str:
    """The deck of every spreading layer of ``plan`` in one engine run.

    Parameters
    ----------
    data_file : str or os.PathLike
        All spheres (every pile; 2 atom types), y periodic over ``[0, W]`` (with
        ``plan.side_walls``: y fixed, the box reaching the walls at 0 and ``W``),
        x and z fixed (spheres pushed over the front wall fall out and are
        deleted).
    model : bedstruct.dem.ContactModel, optional
        Contact model of one particle type, SI (default: the seed's,
        :func:`~bedstruct.dem.seed_contact_model`).
    engine : {"liggghts", "lammps"} or Dialect
    plan : SpreadLayersPlan
    gravity : float, m/s^2
        Magnitude of gravity along -z.
    stl_folder : path, optional
        LIGGGHTS: where the platform, front wall and tool STL files are written
        (required); the deck refers to them by path.
    contacts : bool
        Also dump contacts per layer (``layerNN/contacts.dump``).
    skin : float, m, optional
        Neighbour skin (default 0.2 x the smallest radius).
    cohesion_model, reference_radius, reference_overlap
        LAMMPS only (:class:`~bedstruct.engines.LammpsDialect`; None: the dialect's,
        by default no cohesion model, ``REFERENCE_RADIUS`` and ``REFERENCE_OVERLAP``);
        see :func:`~bedstruct.engines.lammps_granular_coeffs`.
    np : int
        MPI ranks the deck is written for. On more than one the x slabs of the box (which
        spans the platform) share the powder, a pile that the tool carries along x: LAMMPS
        moves the cuts between them with the powder (``balance`` and ``fix balance ...
        shift x``); LIGGGHTS, which has no load balancing, keeps the box's equal slabs (its
        deck is the same on any number of ranks). A deck for one rank has none of these
        lines.

    Returns
    -------
    str
        The deck (run it from the folder that holds ``layer01``...).

    Examples
    --------
    >>> import tempfile, os
    >>> from bedstruct.engines import BladeGeometry, SpreadLayersPlan, write_sphere_data
    >>> d = tempfile.mkdtemp()
    >>> f = write_sphere_data(os.path.join(d, "a.data"), [[1e-3, 2e-4, -1e-4], [1e-3, 2e-4, 3e-3]],
    ...                       [5e-5, 5e-5], box_lo=[-1e-3, 0, -1e-3], box_hi=[5e-3, 4e-4, 4e-3],
    ...                       n_types=2)
    >>> blade = BladeGeometry(x0=0.0, z_bottom=0.0, speed=0.1, height=1e-3)
    >>> plan = SpreadLayersPlan(3e-3, 4e-4, (2e-4, 2e-4), blade, ((1, 1), (2, 2)), (0.0, 3e-3),
    ...                         (5e-4, 2e-3), 1e-6, x_end=3.5e-3, n_frames=4)
    >>> deck = spread_layers_deck(f, engine="liggghts", plan=plan, stl_folder=d)
    >>> [l for l in deck.splitlines() if l.startswith("displace_atoms")]
    ['displace_atoms pile02 move 0 0 ${dz02} units box']
    >>> plan.layers[1].spread % plan.every, plan.total_steps == plan.layers[-1].end
    (0, True)
    """
    d = dialect(engine, cohesion_model=cohesion_model, reference_radius=reference_radius,
                reference_overlap=reference_overlap)
    m = d.deck_model(model)
    grav = check_gravity(gravity)
    pl, tool = plan, plan.tool
    roller = isinstance(tool, RollerGeometry)
    W = pl.width
    gaps = [float(g) for g in pl.gaps]
    dt = pl.dt
    lines, wt = d.workflow_head(
        data_file, m, gravity=grav, boundary="f f f" if pl.side_walls else "f p f", dt=dt, skin=skin,
        np=np,   # the box spans the platform: its x slabs need no centring on the powder
        title=(f"{len(gaps)} spreading layer(s) in one run ({'roller' if roller else 'blade'}); "
               "contact histories carry over between layers"))
    for k, (a, b) in enumerate(pl.pile_ids):
        lines.append(f"group pile{k + 1:02d} id {int(a)}:{int(b)}")
    lines.append("group active id " + f"{int(pl.pile_ids[0][0])}:{int(pl.pile_ids[0][1])}")
    # parked piles are left out of the pair lists (they would cost as much as the active ones)
    for k in range(len(gaps) - 1):
        lines.append(f"group wait{k + 1:02d} id {int(pl.pile_ids[k + 1][0])}:"
                     f"{int(pl.pile_ids[-1][1])}")
    if len(gaps) > 1:
        lines.append("neigh_modify exclude group wait01 all")
    lines.append("variable off equal 0")   # steps waited for flying powder so far
    lines += d.spread_walls(pl, m, wt, stl_folder=stl_folder)
    x0f, x1f = pl.footprint
    flight = _flight_computes(pl, grav)
    lines += ["fix integr active nve/sphere",
              "compute rke all erotate/sphere",
              "compute prad all property/atom radius",
              "variable ztop atom z+c_prad",
              f"region foot block {x0f:.10g} {x1f:.10g} INF INF INF {tool_top(pl):.10g} units box",
              "compute zfoot all reduce/region foot max v_ztop",
              *flight,
              # thermo invokes the reductions, so they are current for variables between runs
              "thermo_style custom step atoms ke c_rke c_zfoot"
              + (" c_zland[1] c_zland[2]" if flight else ""),
              f"thermo {pl.every}",
              "thermo_modify lost ignore norm no flush yes"]
    if contacts:  # defined before the first run (LIGGGHTS)
        lines += d.contact_computes(tangential=True)
    every = pl.every
    for k, ls in enumerate(pl.layers):
        tag = f"{k + 1:02d}"
        lines.append(f"# ---- layer {k + 1}")
        if k > 0:
            g = gaps[k]
            n_low = pl._steps(g / pl.lower_speed)
            # one frame (and its contacts) of the bed as the layer starts: with the contact
            # histories carried over, its tangential forces are those of the previous layer's end
            # (a dump writes at the setup of a run only on a multiple of its interval, so the
            # interval is the layer's actual start step)
            lines.append(f"variable st{tag} equal {ls.start}+v_off")
            lines.append(f"dump dst{tag} all custom ${{st{tag}}} layer{tag}/start.dump "
                         f"{DUMP_COLUMNS}")
            if contacts:
                lines.append(f"dump dsc{tag} all local ${{st{tag}}} layer{tag}/start_contacts.dump "
                             + d.contact_columns(tangential=True))
            lines += ["run 0", f"undump dst{tag}"] + ([f"undump dsc{tag}"] if contacts else [])
            vl = g / (n_low * dt)  # exactly the gap in n_low steps
            lines += d.moving_run("mvplat", "platform", f"0 0 {-vl:.10g}", n_low)
            lines.append(f"run {pl._steps(min(pl.settle_time, 2 * g / pl.lower_speed))}")
            z_plat = -sum(gaps[:k + 1])
            lines.append("run 0")
            lines += _landing_wait(pl, k, z_plat, gravity=grav)
            # the pile's base: the highest sphere top in its footprint, at least the platform
            lines += [f"variable zb{tag} equal {z_plat:.10g}+(c_zfoot-({z_plat:.10g}))"
                      f"*(c_zfoot>{z_plat:.10g})",
                      f"variable dz{tag} equal v_zb{tag}+{pl.pile_lift:.10g}"
                      f"-({pl.pile_parked_z[k]:.10g})",
                      f"displace_atoms pile{tag} move 0 0 ${{dz{tag}}} units box",
                      f"group active id {int(pl.pile_ids[k][0])}:{int(pl.pile_ids[k][1])}",
                      "neigh_modify exclude none"]
            if k + 1 < len(gaps):
                lines.append(f"neigh_modify exclude group wait{k + 1:02d} all")
            before = ls.start + n_low + pl._steps(min(pl.settle_time, 2 * g / pl.lower_speed))
        else:
            before = ls.start
        lines.append(f"run {ls.spread - before}")
        lines.append(f'print "{_OFFSET_LINE} layer={k + 1} steps=${{off}}"')
        # every `every` steps from the actual start of the tool motion (which the waits shift
        # off the multiples of `every`), that start included
        s0 = f"({ls.spread}+v_off)"
        lines.append(f"variable fnext{tag} equal {s0}+{every}*(floor((step-{s0})/{every})+1)"
                     f"*(step>={s0})")
        dumps = [f"dump dmp{tag} all custom {every} layer{tag}/frames.dump {DUMP_COLUMNS}",
                 f"dump_modify dmp{tag} every v_fnext{tag} first yes"]
        if contacts:
            dumps += [f"dump dloc{tag} all local {every} layer{tag}/contacts.dump "
                      + d.contact_columns(tangential=True),
                      f"dump_modify dloc{tag} every v_fnext{tag} first yes"]
        lines += dumps
        n_spread = ls.stop - ls.spread
        # the load on the tool averaged over every step of the stroke (a load cell): LIGGGHTS'
        # mesh/surface/stress force on the tool, LAMMPS' summed wall forces on the particles
        src, sign = d.tool_load
        lines.append(f"fix tload{tag} all ave/time 1 1 1 {src}[1] {src}[2] {src}[3] ave running")
        rotate = None
        if roller and tool.omega != 0:
            per = 2 * math.pi / abs(tool.omega)
            sgn = 1 if tool.omega > 0 else -1
            rotate = (f"origin {tool.x0:.10g} {0.5 * W:.10g} {tool.center_z:.10g} axis 0 {sgn} 0 "
                      f"period {per:.10g}")
        lines += d.moving_run("mvtool", "tool", f"{pl.speed:.10g} 0 0", n_spread, rotate=rotate)
        lines += [f"variable tf{c}{tag} equal {sign}f_tload{tag}[{i}]"
                  for i, c in ((1, "x"), (2, "y"), (3, "z"))]
        lines += [f'print "{_LOAD_LINE} layer={k + 1} fx=${{tfx{tag}}} fy=${{tfy{tag}}} '
                  f'fz=${{tfz{tag}}}"', f"unfix tload{tag}"]
        lines.append(f"run {ls.end - ls.stop}")
        lines += [f"undump dmp{tag}"] + ([f"undump dloc{tag}"] if contacts else [])
        if k + 1 < len(pl.layers):
            n_up = pl._steps(pl.clear / pl.return_speed)
            n_back = pl._steps(pl.travel / pl.return_speed)
            back = pl.travel / (n_back * dt)   # back to the start exactly
            up = pl.clear / (n_up * dt)
            lines += [*d.moving_run("mvup", "tool", f"0 0 {up:.10g}", n_up),
                      *d.moving_run("mvback", "tool", f"{-back:.10g} 0 0", n_back),
                      *d.moving_run("mvdown", "tool", f"0 0 {-up:.10g}", n_up)]
    # last: the run got to its end, every dump closed (run_finished reads it)
    lines.append(f'print "{_DONE_LINE} layer={len(pl.layers)}"')
    return "\n".join(lines) + "\n"


def _waits_for_landing(pl: SpreadLayersPlan, gravity: float) -> bool:
    """A later layer, a wait allowed, and gravity to fall by (free flight is weight only)."""
    return pl.landing_intervals > 0 and len(pl.gaps) > 1 and gravity > 0


def _flight_computes(pl: SpreadLayersPlan, gravity: float) -> list[str]:
    """Per-atom flags and the reduction that :func:`_landing_wait` tests (none if no wait).

    In free flight: the total force is the weight ``m g`` within half its size (no
    contact acts). ``c_zland[1]``: highest top of active spheres in flight over the
    footprint, above the platform (any height: the stroke throws powder far above the
    tool); ``c_zland[2]``: highest top of the others there (-1 m when none).
    """
    if not _waits_for_landing(pl, gravity):
        return []
    x0f, x1f = pl.footprint
    g = float(gravity)
    return [f"variable inflight atom sqrt(fx*fx+fy*fy+(fz+mass*{g:.10g})^2)<0.5*mass*{g:.10g}",
            "variable ztopfly atom v_inflight*v_ztop-(1-v_inflight)",
            "variable ztoprest atom (1-v_inflight)*v_ztop-v_inflight",
            f"region flight block {x0f:.10g} {x1f:.10g} INF INF INF INF units box",
            "compute zland active reduce/region flight max v_ztopfly v_ztoprest"]


def _landing_wait(pl: SpreadLayersPlan, k: int, z_plat: float, *, gravity: float) -> list[str]:
    """Settle in intervals of ``settle_time`` while powder in flight over the footprint would
    lift the pile of layer ``k + 1`` (the embedded run's rule); each interval adds to ``off``.

    Needs a ``run 0`` just before (computes are current only after a run). The planned step
    ``step - v_off`` stays within the still phase before the pile's placement: an interval is
    no longer than the settling that follows the placement.
    """
    if not _waits_for_landing(pl, gravity):
        return []
    tag = f"{k + 1:02d}"
    n = pl._steps(pl.settle_time)
    zp = f"{z_plat:.10g}"
    # rest: the highest top of what rests there, at least the platform
    rest = f"({zp}+(c_zland[2]-({zp}))*(c_zland[2]>{zp}))"
    return [f"variable land{tag} loop {int(pl.landing_intervals)}",
            f"label landing{tag}",
            f"variable fly{tag} equal (c_zland[1]>{zp})*(c_zland[1]>{rest}+"
            f"{pl.landing_margin:.10g})",
            f'if "${{fly{tag}}} > 0" then "run {n}" "variable off equal ${{off}}+{n}" '
            f'"run 0" "next land{tag}" "jump SELF landing{tag}"']
