"""Workflow decks for LIGGGHTS and LAMMPS: the angle-of-repose box of
:mod:`bedstruct.workflows.repose` with a sliding bottom plate.

The particles come from a data file (bedstruct writes the spheres that the
embedded engine's raindrop insertion places, so both engines start from the
same particles). Walls reproduce the embedded geometry: side plates of the
box (``x = 0`` and ``x = L``, and ``y = 0``, ``y = W`` unless y is periodic)
of height ``H``, a bottom plate covering ``[0, L]`` at ``z = 0`` that slides
towards ``-x``, and an optional fixed ledge at ``z = 0``.

* LIGGGHTS: every wall is a ``fix mesh/surface`` of a generated STL
  (:func:`repose_wall_stls`), all in one ``fix wall/gran ... mesh`` (LIGGGHTS
  accepts only one mesh wall fix);
  the plate moves with ``fix move/mesh ... linear -v 0 0`` during the slide
  (``unfix`` stops it).
* LAMMPS: every wall is a block region (thickness ``wall_thickness`` behind
  the contact face) with ``fix wall/gran/region granular``; the plate region
  moves by ``move v_px NULL NULL`` with ``px`` a ramp in ``step`` that starts
  and stops the slide.

Outputs (relative to the run folder): ``frames.dump`` (``dump custom``
:data:`~bedstruct.dem.backends.DUMP_COLUMNS`, ``n_frames`` frames over slide
and drain, the last one at the final step) and, with ``contacts=True``,
``contacts.dump`` (LIGGGHTS ``compute pair/gran/local pos id force
contactArea delta``; LAMMPS ``property/local patom1 patom2`` + ``pair/local
dist fx fy fz``) at the same steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._common import as_granular_params, read_data_header
from .decks import DUMP_COLUMNS, _contact_cols, _contact_computes, _path_word, _setup
from .lammps import REFERENCE_OVERLAP, REFERENCE_RADIUS, lammps_granular_coeffs
from .liggghts import liggghts_model_commands, liggghts_wall_model
from .stl import BladeGeometry, write_stl

__all__ = ["ReposeGeometry", "ReposeSchedule", "repose_deck", "repose_wall_stls", "SpreadGeometry",
           "SpreadSchedule", "spread_deck"]


@dataclass(frozen=True)
class ReposeGeometry:
    """The repose box (SI): ``[0, L] x [0, W] x [0, H]`` with a sliding plate.

    Parameters
    ----------
    length, width, height : float, m
        L, W, H of the box.
    periodic_width : bool
        y periodic over ``[0, W]`` (no y side plates).
    ledge_fraction : float
        Fixed ledge of ``ledge_fraction * L`` centred under the box (0: none).
    plate_speed : float, m/s
        Speed of the plate towards ``-x``.
    slide : float, m
        How far the plate slides.
    wall_thickness : float, m
        LAMMPS only: thickness of the block regions behind each wall face.

    Examples
    --------
    >>> g = ReposeGeometry(2.5e-3, 0.7e-3, 0.85e-3, periodic_width=True, ledge_fraction=0.6,
    ...                    plate_speed=0.5, slide=2.5e-3)
    >>> [round(v * 1e3, 3) for v in g.ledge]
    [0.5, 2.0]
    """

    length: float
    width: float
    height: float
    periodic_width: bool = True
    ledge_fraction: float = 0.0
    plate_speed: float = 0.05
    slide: float = 0.0
    wall_thickness: float = 1e-4

    def __post_init__(self):
        if not (self.length > 0 and self.width > 0 and self.height > 0):
            raise ValueError("`length`, `width` and `height` must be positive lengths (m)")
        if not 0 <= self.ledge_fraction < 1:
            raise ValueError(f"`ledge_fraction` must lie in [0, 1); got {self.ledge_fraction}")
        if not (self.plate_speed > 0 and self.slide >= 0 and self.wall_thickness > 0):
            raise ValueError("`plate_speed` and `wall_thickness` must be positive, `slide` >= 0")

    @property
    def ledge(self) -> tuple[float, float] | None:
        """x range of the ledge (m), or None."""
        if self.ledge_fraction <= 0:
            return None
        half = 0.5 * self.ledge_fraction * self.length
        return 0.5 * self.length - half, 0.5 * self.length + half


@dataclass(frozen=True)
class ReposeSchedule:
    """Steps of the three stages and the output interval.

    ``fill_steps`` settle the inserted spheres, ``slide_steps`` move the plate,
    ``drain_steps`` let the pile come to rest. ``every`` is the dump interval;
    :meth:`from_times` chooses it so that ``n_frames`` frames cover slide and
    drain and the last frame falls on the final step.

    Examples
    --------
    >>> s = ReposeSchedule.from_times(1e-6, fill=1e-4, slide=5e-5, drain=1e-4, n_frames=4)
    >>> (s.fill_steps + s.slide_steps + s.drain_steps) % s.every
    0
    """

    dt: float
    fill_steps: int
    slide_steps: int
    drain_steps: int
    every: int

    @classmethod
    def from_times(cls, dt: float, *, fill: float, slide: float, drain: float,
                   n_frames: int) -> "ReposeSchedule":
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"`dt` must be a positive number of seconds; got {dt!r}")

        def steps(t):
            return max(1, int(math.ceil(t / dt - 1e-9)))
        f, s, d = steps(fill), steps(slide), steps(drain)
        every = max(1, int(math.ceil((s + d) / max(1, int(n_frames)))))
        total = f + s + d
        d += (-total) % every
        return cls(float(dt), f, s, d, every)


def _rect(x0, x1, y0, y1, z0, z1):
    """Two triangles of an axis-aligned rectangle (one of the extents is zero)."""
    if z0 == z1:
        a, b, c, d = [x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0]
    elif x0 == x1:
        a, b, c, d = [x0, y0, z0], [x0, y1, z0], [x0, y1, z1], [x0, y0, z1]
    else:
        a, b, c, d = [x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]
    return [[a, b, c], [a, c, d]]


def _granular_head(data_file, p, *, engine: str, title: str, boundary: str, dt: float,
                   skin, cohesion_model, reference_radius, reference_overlap):
    """Deck lines up to gravity (setup, data file, neighbours, contact model, time step)
    shared by the workflow decks; returns ``(lines, wall_type)`` (LAMMPS: wall type None)."""
    head = read_data_header(data_file)
    if head["atom types"] < 2:
        raise ValueError("the data file must declare 2 atom types (walls use type 2); write it "
                         "with write_sphere_data(..., n_types=2)")
    if skin is None:
        from .decks import data_file_radii
        r = data_file_radii(data_file)
        skin = 0.2 * float(r.min()) if r.size else 1e-6
    lines = [f"# bedstruct deck for {engine}: {title}",
             *_setup(engine, boundary, "* 1 1"),
             f"read_data {_path_word(data_file)}",
             f"neighbor {skin:.10g} bin", "neigh_modify delay 0"]
    wt = None
    if engine == "liggghts":
        model, wt = liggghts_model_commands(p, n_types=head["atom types"])
        if min(p.youngs_modulus, p.wall("youngs_modulus")) < 5e6:
            # LIGGGHTS refuses E < 5e6 Pa in SI units unless told (softened moduli are deliberate)
            lines.append("soft_particles yes")
        lines += model
    else:
        coeffs = lammps_granular_coeffs(p, cohesion_model=cohesion_model,
                                        reference_radius=reference_radius,
                                        reference_overlap=reference_overlap)
        lines += ["pair_style granular", f"pair_coeff * * {coeffs}"]
    lines.append(f"timestep {dt:.10g}")
    if p.gravity > 0:
        lines.append(f"fix gravi all gravity {p.gravity:.10g} vector 0.0 0.0 -1.0")
    return lines, wt


def _liggghts_mesh_walls(meshes: dict, p, wt: int, *, back_plane: bool = False,
                         loaded=()) -> list[str]:
    """LIGGGHTS wall commands: one ``fix mesh/surface`` per mesh (name -> STL path), all in one
    ``fix wall/gran`` (LIGGGHTS allows one mesh wall/gran fix); with ``back_plane`` also the
    primitive plane ``x = 0``. Meshes named in ``loaded`` are ``mesh/surface/stress``: their
    fix's global vector holds the total force (and torque) of the particles on them."""
    wm = liggghts_wall_model(p)
    lines = [f"fix {name} all mesh/surface{'/stress' if name in loaded else ''} file "
             f"{_path_word(path)} type {wt} curvature_tolerant yes"
             for name, path in meshes.items()]
    lines.append(f"fix wmesh all wall/gran {wm} mesh n_meshes {len(meshes)} meshes "
                 + " ".join(meshes))
    if back_plane:
        lines.append(f"fix wback all wall/gran {wm} primitive type {wt} xplane 0.0")
    return lines


def _chamber_meshes(folder, length: float, width: float, z_platform: float,
                    chamber_depth: float) -> dict[str, Path]:
    """Spreading platform ``[0, L] x [0, W]`` at ``z_platform`` and, with a chamber, its front
    wall at ``x = L`` from ``-chamber_depth`` to 0, written as STL files into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    L, W = length, width
    # square-ish strips: LIGGGHTS 3.8 stops with "assertion failed (region_neighbor_list_I.h)"
    # on a platform of two long triangles (here from a 6 mm x 0.6 mm platform on)
    n = max(1, int(math.ceil(L / W - 1e-9)))
    xs = np.linspace(0.0, L, n + 1)
    strips = [t for a, b in zip(xs[:-1], xs[1:]) for t in _rect(a, b, 0.0, W, z_platform, z_platform)]
    meshes = {"platform": write_stl(folder / "platform.stl", strips, name="platform")}
    if chamber_depth > 0:
        meshes["front"] = write_stl(folder / "front.stl",
                                    _rect(L, L, 0.0, W, -chamber_depth, 0.0), name="front")
    return meshes


def _integrate_and_dump(engine: str, every: int, thermo: int, contacts: bool):
    """Integrator, thermo and (after the first run) the dumps ``frames.dump`` and
    ``contacts.dump`` every ``every`` steps; returns ``(lines, dumps)``."""
    lines = ["fix integr all nve/sphere",
             "compute rke all erotate/sphere",
             "thermo_style custom step atoms ke c_rke",
             f"thermo {thermo}",
             "thermo_modify lost ignore norm no flush yes"]
    dumps = [f"dump dmp all custom {every} frames.dump {DUMP_COLUMNS}"]
    if contacts:
        lines += _contact_computes(engine)
        dumps.append(f"dump dloc all local {every} contacts.dump {_contact_cols(engine)}")
    return lines, dumps


def repose_wall_stls(geometry: ReposeGeometry, folder) -> dict[str, Path]:
    """Write the LIGGGHTS wall meshes of ``geometry`` into ``folder``.

    Returns
    -------
    dict
        ``plate``, ``sides`` and (with a ledge) ``ledge`` -> STL path.

    Examples
    --------
    >>> import tempfile
    >>> g = ReposeGeometry(1e-3, 5e-4, 5e-4, ledge_fraction=0.5, slide=1e-3)
    >>> sorted(repose_wall_stls(g, tempfile.mkdtemp()))
    ['ledge', 'plate', 'sides']
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    L, W, H = geometry.length, geometry.width, geometry.height
    out = {"plate": write_stl(folder / "plate.stl", _rect(0.0, L, 0.0, W, 0.0, 0.0), name="plate")}
    sides = _rect(0.0, 0.0, 0.0, W, 0.0, H) + _rect(L, L, 0.0, W, 0.0, H)
    if not geometry.periodic_width:
        sides += _rect(0.0, L, 0.0, 0.0, 0.0, H) + _rect(0.0, L, W, W, 0.0, H)
    out["sides"] = write_stl(folder / "sides.stl", sides, name="sides")
    if geometry.ledge is not None:
        x0, x1 = geometry.ledge
        out["ledge"] = write_stl(folder / "ledge.stl", _rect(x0, x1, 0.0, W, 0.0, 0.0), name="ledge")
    return out


def _lammps_walls(geometry, p, schedule, *, cohesion_model, reference_radius, reference_overlap):
    coeffs = lammps_granular_coeffs(p, wall=True, cohesion_model=cohesion_model,
                                    reference_radius=reference_radius,
                                    reference_overlap=reference_overlap)
    L, W, H, t = geometry.length, geometry.width, geometry.height, geometry.wall_thickness
    v, dt = geometry.plate_speed, schedule.dt
    s0 = schedule.fill_steps
    s1 = s0 + schedule.slide_steps
    lines = [f"variable px equal -{v * dt:.12g}*((step-{s0})*(step>{s0})-(step-{s1})*(step>{s1}))",
             f"region plate block 0 {L:.10g} INF INF {-t:.10g} 0 side out move v_px NULL NULL "
             "units box"]
    regions = ["plate"]
    lines.append(f"region wxlo block {-t:.10g} 0 INF INF 0 {H:.10g} side out units box")
    lines.append(f"region wxhi block {L:.10g} {L + t:.10g} INF INF 0 {H:.10g} side out units box")
    regions += ["wxlo", "wxhi"]
    if not geometry.periodic_width:
        lines.append(f"region wylo block 0 {L:.10g} {-t:.10g} 0 0 {H:.10g} side out units box")
        lines.append(f"region wyhi block 0 {L:.10g} {W:.10g} {W + t:.10g} 0 {H:.10g} side out "
                     "units box")
        regions += ["wylo", "wyhi"]
    if geometry.ledge is not None:
        x0, x1 = geometry.ledge
        lines.append(f"region ledge block {x0:.10g} {x1:.10g} INF INF {-t:.10g} 0 side out units box")
        regions.append("ledge")
    lines += [f"fix w{r} all wall/gran/region granular {coeffs} region {r}" for r in regions]
    return lines


def repose_deck(data_file, params=None, *, engine: str, geometry: ReposeGeometry,
                schedule: ReposeSchedule, stl_folder=None, contacts: bool = True,
                thermo_every: int = 0, skin: float | None = None,
                cohesion_model: str | None = None, reference_radius: float = REFERENCE_RADIUS,
                reference_overlap: float = REFERENCE_OVERLAP) -> str:
    """The angle-of-repose deck: settle, slide the plate out, drain.

    Parameters
    ----------
    data_file : str or os.PathLike
        Spheres (``id type diameter density x y z``), 2 atom types (walls use
        type 2 in LIGGGHTS), box as the deck's domain: x and z fixed (spheres
        leaving are deleted: those falling into the reservoir below the plate),
        y periodic when ``geometry.periodic_width``.
    params : GranularParams, mapping or ContactModel, optional
        SI contact parameters (gravity along -z).
    engine : {"liggghts", "lammps"}
    geometry : ReposeGeometry
    schedule : ReposeSchedule
    stl_folder : path, optional
        LIGGGHTS only (required): where :func:`repose_wall_stls` writes the meshes.
    contacts : bool
        Also dump contacts (``contacts.dump``).
    thermo_every : int
        Thermo interval (0: ``schedule.every``).
    skin : float, m, optional
        Neighbour skin (default 0.2 x the smallest radius).
    cohesion_model, reference_radius, reference_overlap
        LAMMPS only; see :func:`~bedstruct.dem.backends.lammps_granular_coeffs`.

    Returns
    -------
    str
        Deck text; the first line is ``# bedstruct deck for <engine>: angle of repose``.

    Examples
    --------
    >>> import tempfile, os
    >>> from bedstruct.dem.backends import write_sphere_data
    >>> d = tempfile.mkdtemp()
    >>> g = ReposeGeometry(1e-3, 5e-4, 5e-4, slide=5e-4, plate_speed=0.5)
    >>> f = write_sphere_data(os.path.join(d, "a.data"), [[5e-4, 2.5e-4, 1e-4]], [5e-5],
    ...                       box_lo=[-2e-3, 0, -5e-4], box_hi=[2e-3, 5e-4, 1e-3], n_types=2)
    >>> s = ReposeSchedule.from_times(1e-6, fill=1e-5, slide=1e-3, drain=1e-5, n_frames=2)
    >>> deck = repose_deck(f, engine="lammps", geometry=g, schedule=s)
    >>> [l.split()[1] for l in deck.splitlines() if l.startswith("region")]
    ['plate', 'wxlo', 'wxhi']
    """
    if engine not in ("liggghts", "lammps"):
        raise ValueError(f"`engine` must be 'liggghts' or 'lammps'; got {engine!r}")
    p = as_granular_params(params)
    boundary = "f p f" if geometry.periodic_width else "f f f"
    lines, wt = _granular_head(data_file, p, engine=engine, boundary=boundary, dt=schedule.dt,
                               title="angle of repose (settle, slide the plate, drain)",
                               skin=skin, cohesion_model=cohesion_model,
                               reference_radius=reference_radius,
                               reference_overlap=reference_overlap)
    if engine == "liggghts":
        if stl_folder is None:
            raise ValueError("LIGGGHTS needs the walls as STL files: pass `stl_folder`")
        lines += _liggghts_mesh_walls(repose_wall_stls(geometry, stl_folder), p, wt)
    else:
        lines += _lammps_walls(geometry, p, schedule, cohesion_model=cohesion_model,
                               reference_radius=reference_radius,
                               reference_overlap=reference_overlap)
    every = int(schedule.every)
    out, dumps = _integrate_and_dump(engine, every, int(thermo_every) or every, contacts)
    lines += out
    lines.append(f"run {schedule.fill_steps}")
    lines += dumps
    if engine == "liggghts":
        lines += [f"fix mvplate all move/mesh mesh plate linear {-geometry.plate_speed:.10g} 0 0",
                  f"run {schedule.slide_steps}",
                  "unfix mvplate"]
    else:
        lines.append(f"run {schedule.slide_steps}")
    lines.append(f"run {schedule.drain_steps}")
    return "\n".join(lines) + "\n"



@dataclass(frozen=True)
class SpreadGeometry:
    """One spreading layer (SI): platform ``[0, L]`` at ``z = -gap``, tool bottom at ``z = 0``.

    Parameters
    ----------
    plate_length, width : float, m
        Platform length L along x; y period W.
    gap : float, m
        Layer thickness: the platform sits ``gap`` below the tool's lowest edge.
    blade : BladeGeometry
        The tool at t = 0 (``z_bottom = 0``; ``bevel_deg = 0`` for a flat plate).
    chamber_depth : float, m
        Front wall of the build chamber at ``x = L`` from ``z = -chamber_depth``
        up to 0 (0: no front wall). The back wall is the plane ``x = 0``.
    wall_thickness : float, m
        LAMMPS only: thickness of the block regions.
    """

    plate_length: float
    width: float
    gap: float
    blade: BladeGeometry
    chamber_depth: float = 0.0
    wall_thickness: float = 1e-4


@dataclass(frozen=True)
class SpreadSchedule:
    """Steps: ``settle_steps`` before and after the tool moves for ``spread_steps``;
    dumps every ``every`` steps from ``settle_steps`` on (the final step is a dump step).

    Examples
    --------
    >>> s = SpreadSchedule.from_times(1e-6, settle=1e-4, spread=1e-3, n_frames=6)
    >>> s.settle_steps % s.every, (s.spread_steps + s.settle_after) % s.every
    (0, 0)
    """

    dt: float
    settle_steps: int
    spread_steps: int
    settle_after: int
    every: int

    @classmethod
    def from_times(cls, dt: float, *, settle: float, spread: float, n_frames: int):
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"`dt` must be a positive number of seconds; got {dt!r}")

        def steps(t):
            return max(1, int(math.ceil(t / dt - 1e-9)))
        s, m = steps(settle), steps(spread)
        every = max(1, int(math.ceil(m / max(1, int(n_frames)))))
        m = every * int(math.ceil(m / every))
        s0 = every * int(math.ceil(s / every))
        s1 = every * int(math.ceil(s / every))
        return cls(float(dt), s0, m, s1, every)


def spread_deck(data_file, params=None, *, engine: str, geometry: SpreadGeometry,
                schedule: SpreadSchedule, stl_folder=None, contacts: bool = True,
                skin: float | None = None, cohesion_model: str | None = None,
                reference_radius: float = REFERENCE_RADIUS,
                reference_overlap: float = REFERENCE_OVERLAP) -> str:
    """One spreading layer: settle the pile, move the tool across the platform, settle.

    The pile (data file, 2 atom types, y periodic over ``[0, W]``) lies on
    the platform in front of the tool. LIGGGHTS: platform, front wall and the
    bevelled blade are meshes in one ``fix wall/gran`` (the blade STL without
    end caps, moved by ``fix move/mesh``), the back wall a primitive
    ``xplane``. LAMMPS: block regions with ``fix wall/gran/region``; the moving
    blade is the unbevelled slab (LAMMPS' wall/gran/region ignores the velocity
    of a moving intersect region; see docs/backends.md). Spheres pushed over
    the front wall fall out of the domain (deleted).

    Outputs: ``frames.dump`` (and ``contacts.dump``) every ``schedule.every``
    steps from the start of the tool motion to the end.
    """
    if engine not in ("liggghts", "lammps"):
        raise ValueError(f"`engine` must be 'liggghts' or 'lammps'; got {engine!r}")
    p = as_granular_params(params)
    g, b = geometry, geometry.blade
    L, W, t = g.plate_length, g.width, g.wall_thickness
    lines, wt = _granular_head(data_file, p, engine=engine, boundary="f p f", dt=schedule.dt,
                               title="one spreading layer (settle, spread, settle)", skin=skin,
                               cohesion_model=cohesion_model, reference_radius=reference_radius,
                               reference_overlap=reference_overlap)
    s0 = schedule.settle_steps
    s1 = s0 + schedule.spread_steps
    if engine == "liggghts":
        if stl_folder is None:
            raise ValueError("LIGGGHTS needs the walls as STL files: pass `stl_folder`")
        meshes = _chamber_meshes(stl_folder, L, W, -g.gap, g.chamber_depth)
        meshes["blade"] = b.write_stl(Path(stl_folder) / "blade.stl", 0.0, W, caps=False)
        lines += _liggghts_mesh_walls(meshes, p, wt, back_plane=True)
    else:
        wc = lammps_granular_coeffs(p, wall=True, cohesion_model=cohesion_model,
                                    reference_radius=reference_radius,
                                    reference_overlap=reference_overlap)
        dx = b.speed * schedule.dt
        x0, x1 = b.x0, b.x0 + b.thickness
        lines += [f"variable bx equal {dx:.12g}*((step-{s0})*(step>{s0})-(step-{s1})*(step>{s1}))",
                  f"region platform block 0 {L:.10g} INF INF {-g.gap - t:.10g} {-g.gap:.10g} "
                  "side out units box",
                  f"region blade block {x0:.10g} {x1:.10g} INF INF {b.z_bottom:.10g} "
                  f"{b.z_bottom + b.height:.10g} side out move v_bx NULL NULL units box",
                  f"fix wplatform all wall/gran/region granular {wc} region platform",
                  f"fix wblade all wall/gran/region granular {wc} region blade",
                  f"fix wback all wall/gran granular {wc} xplane 0.0 NULL"]
        if g.chamber_depth > 0:
            lines += [f"region front block {L:.10g} {L + t:.10g} INF INF {-g.chamber_depth:.10g} 0 "
                      "side out units box",
                      f"fix wfront all wall/gran/region granular {wc} region front"]
    every = int(schedule.every)
    out, dumps = _integrate_and_dump(engine, every, every, contacts)
    lines += out
    lines.append(f"run {schedule.settle_steps}")
    lines += dumps
    if engine == "liggghts":
        lines += [f"fix mvblade all move/mesh mesh blade linear {b.speed:.10g} 0 0",
                  f"run {schedule.spread_steps}", "unfix mvblade"]
    else:
        lines.append(f"run {schedule.spread_steps}")
    lines.append(f"run {schedule.settle_after}")
    return "\n".join(lines) + "\n"
