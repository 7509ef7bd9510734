"""The angle-of-repose deck (:func:`repose_deck`): the box of
:mod:`bedstruct.workflows.repose` with a sliding bottom plate, for every engine.

The particles come from a data file (bedstruct writes the spheres that the
embedded engine's raindrop insertion places, so both engines start from the
same particles). Walls reproduce the embedded geometry: side plates of the
box (``x = 0`` and ``x = L``, and ``y = 0``, ``y = W`` unless y is periodic)
of height ``H``, a bottom plate covering ``[0, L]`` at ``z = 0`` that slides
towards ``-x``, and an optional fixed ledge at ``z = 0``.

The dialect writes the walls (:meth:`~bedstruct.engines.Dialect.repose_walls`):

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
:data:`~bedstruct.engines.DUMP_COLUMNS`, ``n_frames`` frames over slide
and drain, the last one at the final step) and, with ``contacts=True``,
``contacts.dump`` (LIGGGHTS ``compute pair/gran/local pos id force
contactArea delta``; LAMMPS ``property/local patom1 patom2`` + ``pair/local
dist fx fy fz``) at the same steps.
"""

from __future__ import annotations

from ._dialect import DUMP_COLUMNS
from ._registry import dialect
from ._scenarios import ReposeGeometry, ReposeSchedule

__all__ = ["repose_deck"]


def _integrate_and_dump(d, every: int, thermo: int, contacts: bool):
    """Integrator, thermo and (after the first run) the dumps ``frames.dump`` and
    ``contacts.dump`` every ``every`` steps; returns ``(lines, dumps)``."""
    lines = ["fix integr all nve/sphere",
             "compute rke all erotate/sphere",
             "thermo_style custom step atoms ke c_rke",
             f"thermo {thermo}",
             "thermo_modify lost ignore norm no flush yes"]
    dumps = [f"dump dmp all custom {every} frames.dump {DUMP_COLUMNS}"]
    if contacts:
        lines += d.contact_computes()
        dumps.append(f"dump dloc all local {every} contacts.dump {d.contact_columns()}")
    return lines, dumps


def repose_deck(data_file, model=None, *, engine: str, geometry: ReposeGeometry,
                schedule: ReposeSchedule, gravity: float = 9.81, stl_folder=None, contacts: bool = True,
                thermo_every: int = 0, skin: float | None = None,
                cohesion_model: str | None = None, reference_radius: float | None = None,
                reference_overlap: float | None = None, np: int = 1) -> str:
    """The angle-of-repose deck: settle, slide the plate out, drain.

    Parameters
    ----------
    data_file : str or os.PathLike
        Spheres (``id type diameter density x y z``), 2 atom types (walls use
        type 2 in LIGGGHTS), box as the deck's domain: x and z fixed (spheres
        leaving are deleted: those falling into the reservoir below the plate),
        y periodic when ``geometry.periodic_width``.
    model : bedstruct.dem.ContactModel, optional
        Contact model of one particle type, SI (default: the seed's,
        :func:`~bedstruct.dem.seed_contact_model`).
    engine : {"liggghts", "lammps"} or Dialect
    geometry : ReposeGeometry
    schedule : ReposeSchedule
    gravity : float, m/s^2
        Magnitude of gravity along -z.
    stl_folder : path, optional
        LIGGGHTS only (required): where :func:`repose_wall_stls` writes the meshes.
    contacts : bool
        Also dump contacts (``contacts.dump``).
    thermo_every : int
        Thermo interval (0: ``schedule.every``).
    skin : float, m, optional
        Neighbour skin (default 0.2 x the smallest radius).
    cohesion_model, reference_radius, reference_overlap
        LAMMPS only (:class:`~bedstruct.engines.LammpsDialect`; None: the dialect's,
        by default no cohesion model, ``REFERENCE_RADIUS`` and ``REFERENCE_OVERLAP``);
        see :func:`~bedstruct.engines.lammps_granular_coeffs`.
    np : int
        MPI ranks the deck is written for. On more than one the x slabs of the box share
        the powder, which lies over ``[0, L]`` of a box reaching past ``-L`` (the plate
        slides out there): LAMMPS balances them (``balance`` and ``fix balance ... shift
        x``), LIGGGHTS, which has no load balancing, centres the box on the powder
        (``change_box``; :meth:`~bedstruct.engines.Dialect.processors_grid`). A deck for
        one rank has none of these lines (and runs on several, unbalanced).

    Returns
    -------
    str
        Deck text; the first line is ``# bedstruct deck for <engine>: angle of repose``.

    Examples
    --------
    >>> import tempfile, os
    >>> from bedstruct.engines import ReposeGeometry, ReposeSchedule, write_sphere_data
    >>> d = tempfile.mkdtemp()
    >>> g = ReposeGeometry(1e-3, 5e-4, 5e-4, slide=5e-4, plate_speed=0.5)
    >>> f = write_sphere_data(os.path.join(d, "a.data"), [[5e-4, 2.5e-4, 1e-4]], [5e-5],
    ...                       box_lo=[-2e-3, 0, -5e-4], box_hi=[2e-3, 5e-4, 1e-3], n_types=2)
    >>> s = ReposeSchedule.from_times(1e-6, fill=1e-5, slide=1e-3, drain=1e-5, n_frames=2)
    >>> deck = repose_deck(f, engine="lammps", geometry=g, schedule=s)
    >>> [l.split()[1] for l in deck.splitlines() if l.startswith("region")]
    ['plate', 'wxlo', 'wxhi']
    """
    d = dialect(engine, cohesion_model=cohesion_model, reference_radius=reference_radius,
                reference_overlap=reference_overlap)
    m = d.deck_model(model)
    boundary = "f p f" if geometry.periodic_width else "f f f"
    lines, wt = d.workflow_head(data_file, m, boundary=boundary, dt=schedule.dt,
                                title="angle of repose (settle, slide the plate, drain)",
                                skin=skin, gravity=gravity, np=np, span=(0.0, geometry.length))
    lines += d.repose_walls(geometry, schedule, m, wt, stl_folder=stl_folder)
    every = int(schedule.every)
    out, dumps = _integrate_and_dump(d, every, int(thermo_every) or every, contacts)
    lines += out
    lines.append(f"run {schedule.fill_steps}")
    lines += dumps
    lines += d.moving_run("mvplate", "plate", f"{-geometry.plate_speed:.10g} 0 0",
                          schedule.slide_steps)
    lines.append(f"run {schedule.drain_steps}")
    return "\n".join(lines) + "\n"
