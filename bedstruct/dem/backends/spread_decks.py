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
  (``wall/gran/region``; the blade is the unbevelled slab, docs/backends.md).

The waits make the step of every later event depend on the run. The deck keeps
the plan's steps as *planned* steps: the equal-style variable ``off`` holds the
steps waited so far, LAMMPS' wall motions are functions of ``step - v_off``, the
frames are written every ``every`` steps from the layer's actual start of the
tool motion (``dump_modify every v_...``), and before each layer's tool motion
the deck prints ``BEDSTRUCT_OFFSET layer=K steps=N`` (the log's record of the
offset; :func:`~bedstruct.dem.backends.landing_offsets` reads it back): an event
of layer K happens at its planned step plus N.

Outputs per layer (folders ``layer01``... must exist): ``frames.dump``
(and ``contacts.dump``) from the start of the tool motion to the end of the
layer, every ``every`` steps; from layer 2 on also ``start.dump`` (and
``start_contacts.dump``), one frame as the layer starts (the bed at rest,
before the platform moves). Parked spheres appear in them (select by id:
pile ``k`` has ids ``pile_ids[k][0]..pile_ids[k][1]``). :class:`SpreadLayersPlan`
gives the step of each event so that frames can be matched to tool positions.
The deck's last command prints ``BEDSTRUCT_DONE layer=K`` (K layers), after every
dump is closed: :func:`~bedstruct.dem.backends.run_finished` tells a finished run
from a killed one by it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from ._common import as_granular_params
from .decks import DUMP_COLUMNS, _contact_cols, _contact_computes
from .lammps import REFERENCE_OVERLAP, REFERENCE_RADIUS, lammps_granular_coeffs
from .spread_logs import _DONE_LINE, _LOAD_LINE, _OFFSET_LINE
from .stl import BladeGeometry, RollerGeometry, write_stl
from .workflow_decks import _chamber_meshes, _granular_head, _liggghts_mesh_walls

__all__ = ["LayerSteps", "SpreadLayersPlan", "spread_layers_deck"]


@dataclass(frozen=True)
class LayerSteps:
    """Global time steps of one layer's events in a :func:`spread_layers_deck` run.

    ``start``: the layer begins (before the platform is lowered); ``spread``:
    the tool starts moving (first frame); ``stop``: the tool stops; ``end``: the
    final frame of the layer (after settling).
    """

    start: int
    spread: int
    stop: int
    end: int


@dataclass(frozen=True)
class SpreadLayersPlan:
    """Everything :func:`spread_layers_deck` needs besides the data file (SI).

    Parameters
    ----------
    plate_length, width : float, m
        Platform length (x from 0) and y period.
    gaps : tuple of float, m
        Layer thicknesses; before layer k the platform sits at ``-sum(gaps[:k+1])``
        below the tool's lowest point (z = 0).
    tool : BladeGeometry or RollerGeometry
        The tool at t = 0, its lowest point at z = 0.
    pile_ids : tuple of (int, int)
        Inclusive id range of the pile reinserted before each layer (one per gap).
    pile_parked_z : tuple of float, m
        z offset by which each pile was parked in the data file (0 for pile 1,
        which lies in place); ``displace_atoms`` moves pile k down by this much
        and up onto whatever lies in its footprint.
    pile_bottom : float, m
        Lowest sphere bottom of the pile as written for the first layer
        relative to its placement base (the pile's own z = 0).
    footprint : (float, float), m
        x range where the pile is placed (the highest sphere top there is its base).
    pile_lift : float, m
        Gap left between that base and the pile's z = 0.
    dt : float, s
    lower_speed, speed, return_speed : float, m/s
    settle_time : float, s
        Settling after the pile is placed and after the tool stops.
    clear : float, m
        How far the tool rises above the bed to return.
    x_end : float, m
        x of the tool's reference point (blade trailing face or roller axis)
        when it stops.
    chamber_depth : float, m
        Front wall at x = L from ``-chamber_depth`` up to 0 (0: none).
    n_frames : int
        Frames over the tool's travel.
    wall_thickness : float, m
        LAMMPS block regions' thickness.
    landing_intervals : int
        Before layers 2, 3...: at most this many intervals of ``settle_time`` are
        waited for spheres in flight over the footprint to land (0: never wait).
    landing_margin : float, m
        Spheres in flight count only when their top is more than this above the
        highest top of what rests in the footprint (the embedded run uses the
        largest radius).
    """

    plate_length: float
    width: float
    gaps: tuple
    tool: object
    pile_ids: tuple
    pile_parked_z: tuple
    footprint: tuple
    dt: float
    lower_speed: float = 0.05
    speed: float = 0.1
    return_speed: float = 0.5
    settle_time: float = 0.005
    pile_lift: float = 0.0
    clear: float = 1e-4
    x_end: float = 0.0
    chamber_depth: float = 0.0
    n_frames: int = 8
    wall_thickness: float = 1e-4
    landing_intervals: int = 0
    landing_margin: float = 0.0
    layers: tuple = field(default=(), init=False)
    every: int = field(default=0, init=False)

    def __post_init__(self):
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise ValueError(f"`dt` must be a positive number of seconds; got {self.dt!r}")
        n = len(self.gaps)
        if n < 1 or len(self.pile_ids) != n or len(self.pile_parked_z) != n:
            raise ValueError("`gaps`, `pile_ids` and `pile_parked_z` need one entry per layer")
        if not isinstance(self.tool, (BladeGeometry, RollerGeometry)):
            raise TypeError("`tool` must be a BladeGeometry or RollerGeometry")
        if int(self.landing_intervals) < 0 or not self.landing_margin >= 0:
            raise ValueError("`landing_intervals` and `landing_margin` must not be negative")
        spread = self._steps((self.x_end - self._tool_x()) / self.speed)
        every = max(1, int(math.ceil(spread / max(1, int(self.n_frames)))))
        s = 0
        layers = []
        for k in range(n):
            start = s
            s += self._lower_steps(k)
            s += self._steps(self.settle_time)
            s += (-s) % every                  # the first frame falls on a dump step
            end = s + spread + self._steps(self.settle_time)
            end += (-end) % every              # ... and so does the last
            layers.append(LayerSteps(start, s, s + spread, end))
            s = end + (self._return_steps() if k + 1 < n else 0)
        object.__setattr__(self, "layers", tuple(layers))
        object.__setattr__(self, "every", every)

    def _steps(self, t: float) -> int:
        return max(1, int(math.ceil(t / self.dt - 1e-9)))

    def _tool_x(self) -> float:
        return self.tool.x0

    def _lower_steps(self, k: int) -> int:
        """Lowering (platform, then settling) before layer k (none before layer 1)."""
        if k == 0:
            return 0
        g = float(self.gaps[k])
        return self._steps(g / self.lower_speed) + self._steps(
            min(self.settle_time, 2 * g / self.lower_speed))

    def _return_steps(self) -> int:
        return 2 * self._steps(self.clear / self.return_speed) + self._steps(
            self.travel / self.return_speed)

    @property
    def travel(self) -> float:
        """How far the tool moves in a layer (m): ``speed`` times the spreading steps."""
        return self.speed * self.dt * self._steps((self.x_end - self._tool_x()) / self.speed)

    @property
    def total_steps(self) -> int:
        """Steps of the whole run."""
        return self.layers[-1].end

    def shifted(self, offsets) -> tuple:
        """The layers' :class:`LayerSteps` of a run whose landing waits took ``offsets``.

        ``offsets[k]`` is the number of steps waited before layer ``k + 1``'s tool
        motion, in all (:func:`~bedstruct.dem.backends.landing_offsets`); the layer's
        start shifts by the previous layer's offset.
        """
        off = [int(o) for o in offsets]
        if len(off) != len(self.layers) or any(b < a for a, b in zip(off, off[1:])) or (
                off and off[0] < 0):
            raise ValueError(f"need {len(self.layers)} non-decreasing offsets; got {offsets!r}")
        prev = [0] + off[:-1]
        return tuple(LayerSteps(ls.start + p, ls.spread + o, ls.stop + o, ls.end + o)
                     for ls, p, o in zip(self.layers, prev, off))


_STEP = "(step-v_off)"   # the planned step: the run's step less the steps waited so far


def _ramp(a: int, b: int) -> str:
    """Planned steps elapsed in [a, b] as a LAMMPS/LIGGGHTS expression."""
    return f"(({_STEP}-{a})*({_STEP}>{a})-({_STEP}-{b})*({_STEP}>{b}))"


def spread_layers_deck(data_file, params=None, *, engine: str, plan: SpreadLayersPlan,
                       stl_folder=None, contacts: bool = True, skin: float | None = None,
                       cohesion_model: str | None = None,
                       reference_radius: float = REFERENCE_RADIUS,
                       reference_overlap: float = REFERENCE_OVERLAP) -> str:
    """The deck of every spreading layer of ``plan`` in one engine run.

    Parameters
    ----------
    data_file : str or os.PathLike
        All spheres (every pile; 2 atom types), y periodic over ``[0, W]``,
        x and z fixed (spheres pushed over the front wall fall out and are
        deleted).
    params : GranularParams, mapping or ContactModel, optional
    engine : {"liggghts", "lammps"}
    plan : SpreadLayersPlan
    stl_folder : path, optional
        LIGGGHTS: where the platform, front wall and tool STL files are written
        (required); the deck refers to them by path.
    contacts : bool
        Also dump contacts per layer (``layerNN/contacts.dump``).
    skin : float, m, optional
        Neighbour skin (default 0.2 x the smallest radius).
    cohesion_model, reference_radius, reference_overlap
        LAMMPS only; see :func:`~bedstruct.dem.backends.lammps_granular_coeffs`.

    Returns
    -------
    str
        The deck (run it from the folder that holds ``layer01``...).

    Examples
    --------
    >>> import tempfile, os
    >>> from bedstruct.dem.backends import BladeGeometry, write_sphere_data
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
    if engine not in ("liggghts", "lammps"):
        raise ValueError(f"`engine` must be 'liggghts' or 'lammps'; got {engine!r}")
    p = as_granular_params(params)
    pl, tool = plan, plan.tool
    roller = isinstance(tool, RollerGeometry)
    L, W = pl.plate_length, pl.width
    gaps = [float(g) for g in pl.gaps]
    z_plat0 = -gaps[0]
    dt = pl.dt
    lines, wt = _granular_head(
        data_file, p, engine=engine, boundary="f p f", dt=dt, skin=skin,
        title=(f"{len(gaps)} spreading layer(s) in one run ({'roller' if roller else 'blade'}); "
               "contact histories carry over between layers"),
        cohesion_model=cohesion_model, reference_radius=reference_radius,
        reference_overlap=reference_overlap)
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
    # ---- walls
    if engine == "liggghts":
        if stl_folder is None:
            raise ValueError("LIGGGHTS needs the walls as STL files: pass `stl_folder`")
        meshes = _chamber_meshes(stl_folder, L, W, z_plat0, pl.chamber_depth)
        folder = Path(stl_folder)
        if roller:
            meshes["tool"] = write_stl(folder / "tool.stl", tool.triangles(0.0, W), name="roller")
        else:
            meshes["tool"] = tool.write_stl(folder / "tool.stl", 0.0, W, caps=False)
        lines += _liggghts_mesh_walls(meshes, p, wt, back_plane=True, loaded=("tool",))
    else:
        lines += _lammps_walls(pl, p, cohesion_model=cohesion_model,
                               reference_radius=reference_radius,
                               reference_overlap=reference_overlap)
    x0f, x1f = pl.footprint
    flight = _flight_computes(pl, p.gravity)
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
        lines += _contact_computes(engine, tangential=True)
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
                             + _contact_cols(engine, tangential=True))
            lines += ["run 0", f"undump dst{tag}"] + ([f"undump dsc{tag}"] if contacts else [])
            if engine == "liggghts":
                vl = g / (n_low * dt)  # exactly the gap in n_low steps
                lines += [f"fix mvplat all move/mesh mesh platform linear 0 0 {-vl:.10g}",
                          f"run {n_low}", "unfix mvplat"]
            else:
                lines.append(f"run {n_low}")
            lines.append(f"run {pl._steps(min(pl.settle_time, 2 * g / pl.lower_speed))}")
            z_plat = -sum(gaps[:k + 1])
            lines.append("run 0")
            lines += _landing_wait(pl, k, z_plat, gravity=p.gravity)
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
                      + _contact_cols(engine, tangential=True),
                      f"dump_modify dloc{tag} every v_fnext{tag} first yes"]
        lines += dumps
        n_spread = ls.stop - ls.spread
        # the load on the tool averaged over every step of the stroke (a load cell): LIGGGHTS'
        # mesh/surface/stress force on the tool, LAMMPS' summed wall forces on the particles
        src, sign = ("f_tool", "") if engine == "liggghts" else ("c_toolsum", "-")
        lines.append(f"fix tload{tag} all ave/time 1 1 1 {src}[1] {src}[2] {src}[3] ave running")
        if engine == "liggghts":
            lines.append(f"fix mvtool all move/mesh mesh tool linear {pl.speed:.10g} 0 0")
            if roller and tool.omega != 0:
                # superposed on the translation: the rotation axis moves with the mesh
                per = 2 * math.pi / abs(tool.omega)
                sgn = 1 if tool.omega > 0 else -1
                lines.append(f"fix rottool all move/mesh mesh tool rotate origin {tool.x0:.10g} "
                             f"{0.5 * W:.10g} {tool.center_z:.10g} axis 0 {sgn} 0 period {per:.10g}")
                lines += [f"run {n_spread}", "unfix rottool", "unfix mvtool"]
            else:
                lines += [f"run {n_spread}", "unfix mvtool"]
        else:
            lines.append(f"run {n_spread}")
        lines += [f"variable tf{c}{tag} equal {sign}f_tload{tag}[{i}]"
                  for i, c in ((1, "x"), (2, "y"), (3, "z"))]
        lines += [f'print "{_LOAD_LINE} layer={k + 1} fx=${{tfx{tag}}} fy=${{tfy{tag}}} '
                  f'fz=${{tfz{tag}}}"', f"unfix tload{tag}"]
        lines.append(f"run {ls.end - ls.stop}")
        lines += [f"undump dmp{tag}"] + ([f"undump dloc{tag}"] if contacts else [])
        if k + 1 < len(pl.layers):
            n_up = pl._steps(pl.clear / pl.return_speed)
            n_back = pl._steps(pl.travel / pl.return_speed)
            if engine == "liggghts":
                back = pl.travel / (n_back * dt)   # back to the start exactly
                up = pl.clear / (n_up * dt)
                lines += [f"fix mvup all move/mesh mesh tool linear 0 0 {up:.10g}",
                          f"run {n_up}", "unfix mvup",
                          f"fix mvback all move/mesh mesh tool linear {-back:.10g} 0 0",
                          f"run {n_back}", "unfix mvback",
                          f"fix mvdown all move/mesh mesh tool linear 0 0 {-up:.10g}",
                          f"run {n_up}", "unfix mvdown"]
            else:
                lines += [f"run {n_up}", f"run {n_back}", f"run {n_up}"]
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


def tool_top(plan: SpreadLayersPlan) -> float:
    """Highest point of the tool at rest (m): parked piles must stay above it plus ``clear``."""
    t = plan.tool
    return t.top if isinstance(t, RollerGeometry) else t.z_bottom + t.height


def _lammps_walls(pl: SpreadLayersPlan, p, *, cohesion_model, reference_radius,
                  reference_overlap) -> list[str]:
    """Regions moved by step-ramp variables over the whole run (LAMMPS)."""
    wc = lammps_granular_coeffs(p, wall=True, cohesion_model=cohesion_model,
                                reference_radius=reference_radius,
                                reference_overlap=reference_overlap)
    gaps = [float(g) for g in pl.gaps]
    L, W, t, dt = pl.plate_length, pl.width, pl.wall_thickness, pl.dt
    pz, bx, bz, th = [], [], [], []
    for k, ls in enumerate(pl.layers):
        if k > 0:
            n_low = pl._steps(gaps[k] / pl.lower_speed)
            pz.append(f"-{gaps[k] / n_low:.12g}*{_ramp(ls.start, ls.start + n_low)}")
        bx.append(f"{pl.speed * dt:.12g}*{_ramp(ls.spread, ls.stop)}")
        th.append(f"{_ramp(ls.spread, ls.stop)}")
        if k + 1 < len(pl.layers):
            n_up = pl._steps(pl.clear / pl.return_speed)
            n_back = pl._steps(pl.travel / pl.return_speed)
            a = ls.end
            bz.append(f"{pl.clear / n_up:.12g}*{_ramp(a, a + n_up)}")
            bx.append(f"-{pl.travel / n_back:.12g}*{_ramp(a + n_up, a + n_up + n_back)}")
            bz.append(f"-{pl.clear / n_up:.12g}*{_ramp(a + n_up + n_back, a + 2 * n_up + n_back)}")
    z0 = -gaps[0]
    lines = [f"variable pz equal {'+'.join(pz) or '0'}",
             f"variable bx equal {'+'.join(bx)}",
             f"variable bz equal {'+'.join(bz) or '0'}",
             f"region platform block 0 {L:.10g} INF INF {z0 - t:.10g} {z0:.10g} side out "
             "move NULL NULL v_pz units box",
             f"fix wplatform all wall/gran/region granular {wc} region platform",
             f"fix wback all wall/gran granular {wc} xplane 0.0 NULL"]
    tool = pl.tool
    if isinstance(tool, RollerGeometry):
        rot = ""
        if tool.omega != 0:
            lines.append(f"variable th equal {tool.omega * dt:.12g}*({'+'.join(th)})")
            rot = (f" rotate v_th {tool.x0:.10g} {0.5 * W:.10g} {tool.center_z:.10g} 0 1 0")
        lines.append(f"region tool cylinder y {tool.x0:.10g} {tool.center_z:.10g} "
                     f"{tool.radius:.10g} INF INF side out move v_bx NULL v_bz{rot} units box")
    else:
        x0, x1 = tool.x0, tool.x0 + tool.thickness
        lines.append(f"region tool block {x0:.10g} {x1:.10g} INF INF {tool.z_bottom:.10g} "
                     f"{tool.z_bottom + tool.height:.10g} side out move v_bx NULL v_bz units box")
    # `contacts`: the per-atom wall forces, summed into the load on the tool (c_toolsum)
    lines += [f"fix wtool all wall/gran/region granular {wc} region tool contacts",
              "compute toolsum all reduce sum f_wtool[2] f_wtool[3] f_wtool[4]"]
    if pl.chamber_depth > 0:
        lines += [f"region front block {L:.10g} {L + t:.10g} INF INF {-pl.chamber_depth:.10g} 0 "
                  "side out units box",
                  f"fix wfront all wall/gran/region granular {wc} region front"]
    return lines
