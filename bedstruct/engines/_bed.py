"""Decks on a bed or a pair of spheres, from the same contact model (SI) for every engine:
a settled bed from a data file (:func:`bed_deck`), the bed with a moving blade
(:func:`moving_wall_deck`) and a head-on impact (:func:`impact_deck`,
read back by :func:`impact_result`).

Every writer takes ``engine`` (a name or a :class:`~bedstruct.engines.Dialect`) and
returns the deck as text whose first line is ``# bedstruct deck for <engine>`` (so
:func:`~bedstruct.engines.run_deck` knows the engine). Relative output names (dumps,
``write_data``) are relative to the run's working directory; input files (data
files, STL meshes) are written into the deck with absolute paths.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ._datafile import data_file_radii, read_data_header
from ._dialect import DUMP_COLUMNS, path_word
from ._logs import EngineLog
from ._params import coefficient, one_type_model
from ._registry import dialect
from ._stl import BladeGeometry

__all__ = ["bed_deck", "impact_deck", "moving_wall_deck", "impact_result", "ImpactResult",
           "hertz_contact_time"]


def bed_deck(data_file, model=None, *, engine: str, steps: int, dt: float,
             gravity: float = 9.81, thermo_every: int = 1000, dump: str | None = None, dump_every: int = 0,
             contacts: str | None = None, contacts_every: int | None = None,
             warmup_steps: int = 0, skin: float | None = None, write_data: str | None = None,
             boundary: str = "p p f", processors: str | None = "* * 1",
             cohesion_model: str | None = None, reference_radius: float | None = None,
             reference_overlap: float | None = None, fabric: bool = False,
             thermo_variables=None, _blade=None) -> str:
    """A deck that reads a settled bed, adds a bottom plane, gravity, and runs.

    The bed comes from a data file (``atom_style sphere``/``granular`` atoms
    ``id type diameter density x y z``); x and y are periodic, z fixed; a
    bottom plane sits at the box's ``zlo``; gravity acts along -z. The contact
    model is the embedded engine's (docs/backends.md gives the mapping).

    Parameters
    ----------
    data_file : str or os.PathLike
        The bed. If it declares 2 atom types, walls use type 2 in LIGGGHTS.
    model : bedstruct.dem.ContactModel, optional
        Contact model of one particle type, SI (default: the seed's,
        :func:`~bedstruct.dem.seed_contact_model`); what the engine cannot write is
        refused by name (:meth:`Dialect.deck_model`).
    engine : {"liggghts", "lammps"} or Dialect
    steps : int
        Steps of the main run.
    dt : float, s
        Time step.
    gravity : float, m/s^2
        Magnitude of gravity along -z (0 switches it off).
    thermo_every : int
        Thermo output interval (columns ``Step Atoms KinEng c_rke``; kinetic
        and rotational energy in J). 0 prints only the first and last line.
    dump, dump_every : str, int
        Per-particle dump file name and interval (columns :data:`DUMP_COLUMNS`).
    contacts, contacts_every : str, int
        Contact (``dump local``) file and interval (columns
        ``dialect(engine).contact_dump_columns``; LAMMPS lists every pair within the force
        cutoff, including touching-free ones with zero force).
    warmup_steps : int
        Steps of a first, separate ``run`` (its Loop time excludes setup, the
        main run's excludes both setup and warm-up).
    skin : float, m, optional
        Neighbour skin (default 0.1 x the smallest diameter).
    write_data : str, optional
        Write the final state to this data file.
    boundary : str
        LAMMPS boundary flags.
    processors : str or None
        ``processors`` grid (default ``* * 1``: beds are thin in z).
    cohesion_model : {None, "dmt", "jkr"}
        LAMMPS only: how to represent SJKR cohesion (see docs/backends.md).
    reference_radius, reference_overlap : float, optional
        LAMMPS only: the contact at which overlap-dependent LIGGGHTS
        coefficients are frozen (None: the dialect's, by default
        ``REFERENCE_RADIUS`` and ``REFERENCE_OVERLAP``).
    fabric : bool
        LAMMPS only (not with DMT/JKR): add ``compute fabric radius contact
        force/normal`` to the thermo output, columns ``c_fab[1]`` ...
        ``c_fab[12]``: the contact tensor xx yy zz xy xz yz, equal to
        (15/2) (sum n n / N_c - I/3) over particle-particle contacts (walls
        excluded), then the normal-force tensor in the same order.
    thermo_variables : mapping of str to str, optional
        Extra thermo columns: name -> equal-style expression (e.g.
        ``{"vx1": "vx[1]"}``), printed as ``v_name`` (LIGGGHTS prints ``name``;
        :meth:`ThermoRun.column` accepts both).

    Returns
    -------
    str

    Examples
    --------
    >>> import tempfile, os
    >>> from bedstruct.engines import write_sphere_data
    >>> p = write_sphere_data(os.path.join(tempfile.mkdtemp(), "b.data"), [[0, 0, 1e-4]], [5e-5],
    ...                       box_lo=[-1e-4, -1e-4, 0], box_hi=[1e-4, 1e-4, 4e-4], n_types=2)
    >>> deck = bed_deck(p, engine="liggghts", steps=10, dt=1e-7)
    >>> deck.splitlines()[0]
    '# bedstruct deck for liggghts: bed from data file, bottom plane, gravity'
    >>> [l for l in deck.splitlines() if l.startswith("pair_style")]
    ['pair_style gran model hertz tangential history rolling_friction epsd2']
    """
    d = dialect(engine, cohesion_model=cohesion_model, reference_radius=reference_radius,
                reference_overlap=reference_overlap)
    m = d.deck_model(model)
    fabric_lines = d.fabric_lines(m) if fabric else []
    steps, warmup_steps = int(steps), int(warmup_steps)
    if steps < 0 or warmup_steps < 0:
        raise ValueError("`steps` and `warmup_steps` must be >= 0")
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"`dt` must be a positive number of seconds; got {dt!r}")
    head = read_data_header(data_file)
    if skin is None:
        skin = 0.2 * float(data_file_radii(data_file).min())
    zlo = float(head["lo"][2])
    lines = [d.header("bed from data file, bottom plane, gravity"),
             *d.setup_lines(boundary, processors),
             f"read_data {path_word(data_file)}",
             f"neighbor {skin:.10g} bin", "neigh_modify delay 0"]
    model_lines, wt = d.model_lines(m, n_types=head["atom types"])
    lines += model_lines
    lines.append(f"timestep {dt:.10g}")
    lines += d.gravity_lines(gravity)
    lines += d.plane_wall(m, wt, zlo=zlo)
    if _blade is not None:
        lines += d.moving_blade(m, wt, _blade[0], stl_path=_blade[1])
    fab = ""
    if fabric:
        lines += fabric_lines
        fab = " " + " ".join(f"c_fab[{i}]" for i in range(1, 13))
    for name, expr in (thermo_variables or {}).items():
        if not str(name).isidentifier() or any(c.isspace() for c in str(expr)):
            raise ValueError(f"thermo variable {name!r} = {expr!r}: the name must be an "
                             "identifier and the expression contain no spaces")
        lines.append(f"variable {name} equal {expr}")
        fab += f" v_{name}"
    lines += ["fix integr all nve/sphere",
              "compute rke all erotate/sphere",
              "thermo_style custom step atoms ke c_rke" + fab,
              f"thermo {int(thermo_every)}",
              "thermo_modify lost ignore norm no flush yes"]
    dumps = []
    if contacts:  # LIGGGHTS wants pair/gran/local defined before the first run
        every = int(contacts_every or dump_every or max(steps, 1))
        lines += d.contact_computes()
        dumps.append(f"dump dloc all local {every} {contacts} {d.contact_columns()}")
    if dump and dump_every:
        dumps.insert(0, f"dump dmp all custom {int(dump_every)} {dump} {DUMP_COLUMNS}")
    if warmup_steps:
        lines.append(f"run {warmup_steps}")
    lines += dumps
    lines.append(f"run {steps}")
    if write_data:
        lines.append(d.write_data_line(write_data))
    return "\n".join(lines) + "\n"


def moving_wall_deck(data_file, model=None, *, engine: str, blade: BladeGeometry,
                     stl_path=None, steps: int, dt: float, **bed_kwargs) -> str:
    """:func:`bed_deck` plus a blade (or plate) moving along +x at constant speed.

    The dialect writes the blade (:meth:`Dialect.moving_blade`):
    LIGGGHTS: ``fix mesh/surface`` of the blade STL (write it first with
    ``blade.write_stl(stl_path, ylo, yhi)``) + ``fix move/mesh linear`` +
    ``fix wall/gran ... mesh``. LAMMPS: a block region moved by
    ``move v_bx NULL NULL`` (``bx = speed * time``) + ``fix wall/gran/region``;
    a static bevelled blade is the intersection of the slab block and the
    half-space above the bevel plane; a moving one is the unbevelled slab (with
    a :class:`~bedstruct.errors.BedstructWarning`), because LAMMPS' wall/gran/region
    does not see the velocity of moving parts of an intersect region.

    Parameters
    ----------
    data_file, model, engine, steps, dt
        As in :func:`bed_deck`.
    blade : BladeGeometry
        Blade position at t = 0, size, bevel and speed (SI).
    stl_path : str or os.PathLike
        LIGGGHTS only: the blade STL file (required for LIGGGHTS).
    **bed_kwargs
        Passed on to :func:`bed_deck`.

    Returns
    -------
    str
    """
    return bed_deck(data_file, model, engine=engine, steps=steps, dt=dt, _blade=(blade, stl_path),
                    **bed_kwargs)


def hertz_contact_time(radius1: float, radius2: float, model=None, *, speed: float) -> float:
    """Duration of an undamped head-on Hertz collision (s).

    .. math:: t_c = 2.868 \\left(\\frac{m^{*2}}{R^* E^{*2} v}\\right)^{1/5}

    with reduced mass m*, R* = r1 r2/(r1+r2), E* = E/(2(1-nu^2)) and relative
    approach speed v.

    Parameters
    ----------
    radius1, radius2 : float, m
    model : bedstruct.dem.ContactModel, optional
        One particle type; supplies E, nu and density (default: the seed's).
    speed : float, m/s
        Relative approach speed.

    Examples
    --------
    >>> from bedstruct.dem import seed_contact_model
    >>> t = hertz_contact_time(2e-5, 2e-5, seed_contact_model(youngs_modulus=1e8), speed=1.0)
    >>> round(t * 1e6, 3)  # microseconds
    2.624

    References
    ----------
    Johnson, K. L. (1985). Contact Mechanics, Cambridge University Press, sec. 11.4.
    """
    model = one_type_model(model, "impact")
    density = coefficient(model, "density")
    m1 = 4.0 / 3.0 * math.pi * radius1 ** 3 * density
    m2 = 4.0 / 3.0 * math.pi * radius2 ** 3 * density
    mstar = m1 * m2 / (m1 + m2)
    rstar = radius1 * radius2 / (radius1 + radius2)
    estar = float(model.tables().youngs[0, 0])   # E* = 1 / (2 (1 - nu^2) / E)
    return 2.868 * (mstar ** 2 / (rstar * estar ** 2 * speed)) ** 0.2


def impact_deck(model=None, *, engine: str, radius: float = 20e-6, radius2: float | None = None,
                speed: float = 1.0, dt: float | None = None, gap: float = 0.02,
                thermo_every: int = 1, target: str = "sphere") -> str:
    """A head-on impact of two spheres, or of one sphere on the bottom plane.

    ``target="sphere"``: sphere 1 (id 1) moves at +speed/2 along x, sphere 2
    at -speed/2, starting ``gap * (r1 + r2)`` apart; thermo ``v_dist`` is the
    centre distance, ``v_vx1``/``v_vx2`` their x velocities.
    ``target="wall"``: sphere 1 falls at ``speed`` onto the plane z = 0 (the
    particle-wall coefficients apply); ``v_dist`` is the centre height,
    ``v_vx1`` = vz, ``v_vx2`` = 0. Either way, read the result with
    ``impact_result(log, radius, radius2)`` where ``radius2 = 0`` for the wall.
    No gravity; thermo columns ``Step Time v_dist v_vx1 v_vx2 KinEng``.

    Parameters
    ----------
    model : bedstruct.dem.ContactModel, optional
        Contact model of one particle type (default: the seed's); cohesion and
        friction play no role head-on (cohesion is switched off).
    engine : {"liggghts", "lammps"}
    radius, radius2 : float, m
        Radii (``radius2`` defaults to ``radius``; unused for the wall).
    speed : float, m/s
        Relative approach speed.
    dt : float, s, optional
        Time step (default: the Hertz contact time / 400).
    gap : float, dimensionless
        Initial surface gap in units of r1 + r2 (of r1 for the wall).
    thermo_every : int
        Thermo interval in steps (1 resolves the contact best).
    target : {"sphere", "wall"}

    Returns
    -------
    str
    """
    if target not in ("sphere", "wall"):
        raise ValueError(f"`target` must be 'sphere' or 'wall'; got {target!r}")
    r1 = float(radius)
    r2 = float(radius if radius2 is None else radius2)
    wall = target == "wall"
    d = dialect(engine, reference_radius=r1 if wall else max(r1, r2))
    m = d.deck_model(model)
    m = dataclasses.replace(m, cohesion=0.0, wall_cohesion=0.0)
    density = coefficient(m, "density")
    if wall:
        e_wall = float(m.tables().youngs[0, m.n_types])
        mass = 4.0 / 3.0 * math.pi * r1 ** 3 * density
        tc = 2.868 * (mass ** 2 / (r1 * e_wall ** 2 * speed)) ** 0.2
        s = gap * r1
    else:
        tc = hertz_contact_time(r1, r2, m, speed=speed)
        s = gap * (r1 + r2)
    if dt is None:
        dt = tc / 400.0
    steps = int(math.ceil((s / speed + 3.0 * tc) / dt))
    half = 20 * (r1 + r2)
    n_types = 2 if wall else 1
    model_lines, wt = d.model_lines(m, n_types=n_types)
    lines = [d.header(f"head-on impact on a {target}"),
             *d.setup_lines("f f f", None),
             f"region reg block {-half:.10g} {half:.10g} {-half:.10g} {half:.10g} "
             f"{-half if not wall else -r1:.10g} {half:.10g} units box",
             f"create_box {n_types} reg",
             f"neighbor {0.1 * min(r1, r2 if not wall else r1):.10g} bin", "neigh_modify delay 0",
             *model_lines,
             f"timestep {dt:.10g}"]
    if wall:
        lines += d.plane_wall(m, wt, zlo=0.0)
        lines += [f"create_atoms 1 single 0 0 {r1 + s:.10g} units box",
                  f"set atom 1 diameter {2 * r1:.10g}",
                  f"set atom * density {density:.10g}",
                  "velocity all set 0 0 0 units box",
                  f"set atom 1 vz {-speed:.10g}",
                  "variable dist equal z[1]",
                  "variable vx1 equal vz[1]", "variable vx2 equal 0.0"]
    else:
        x1, x2 = -(r1 + s / 2), r2 + s / 2
        lines += [f"create_atoms 1 single {x1:.10g} 0 0 units box",
                  f"create_atoms 1 single {x2:.10g} 0 0 units box",
                  f"set atom 1 diameter {2 * r1:.10g}", f"set atom 2 diameter {2 * r2:.10g}",
                  f"set atom * density {density:.10g}",
                  "velocity all set 0 0 0 units box",
                  f"set atom 1 vx {speed / 2:.10g}", f"set atom 2 vx {-speed / 2:.10g}",
                  "variable dist equal x[2]-x[1]",
                  "variable vx1 equal vx[1]", "variable vx2 equal vx[2]"]
    lines += ["fix integr all nve/sphere",
              "thermo_style custom step time v_dist v_vx1 v_vx2 ke",
              f"thermo {int(thermo_every)}",
              d.impact_thermo_modify,
              f"run {steps}"]
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class ImpactResult:
    """Outcome of a head-on two-sphere impact.

    Parameters
    ----------
    restitution : float, dimensionless
        -(relative velocity after) / (relative velocity before).
    contact_time : float, s
        Time with centre distance below r1 + r2 (crossings interpolated).
    max_overlap : float, m
        Largest overlap r1 + r2 - dist printed.
    """

    restitution: float
    contact_time: float
    max_overlap: float


def impact_result(log: EngineLog, radius1: float, radius2: float | None = None) -> ImpactResult:
    """Restitution and contact time from the log of an :func:`impact_deck` run.

    Parameters
    ----------
    log : EngineLog
        Parsed log (``run_deck(...).log``).
    radius1, radius2 : float, m

    Returns
    -------
    ImpactResult

    Raises
    ------
    ValueError
        If the log does not show a complete contact (touch and separation).

    Examples
    --------
    >>> from bedstruct.engines import parse_log
    >>> text = ('LAMMPS (x)\\nStep Time v_dist v_vx1 v_vx2 KinEng\\n'
    ...         '0 0 2.2 1 -1 1\\n1 1 1.8 0 0 0\\n2 2 1.9 0 0 0\\n3 3 2.1 -0.5 0.5 1\\n'
    ...         'Loop time of 1 on 1 procs for 3 steps with 2 atoms\\n')
    >>> res = impact_result(parse_log(text), 1.0)
    >>> round(res.restitution, 6), round(res.contact_time, 6), round(res.max_overlap, 6)
    (0.5, 2.0, 0.2)
    """
    r2 = radius1 if radius2 is None else radius2
    t = log.column("Time")
    gap = log.column("v_dist") - (radius1 + r2)
    vrel = log.column("v_vx2") - log.column("v_vx1")
    inside = np.flatnonzero(gap < 0)
    if inside.size == 0 or inside[0] == 0 or inside[-1] == len(gap) - 1:
        raise ValueError("the log does not contain a complete contact (touch and separation)")
    i0, i1 = inside[0], inside[-1]

    def cross(a, b):
        return t[a] + (t[b] - t[a]) * gap[a] / (gap[a] - gap[b])
    t_in = cross(i0 - 1, i0)
    t_out = cross(i1, i1 + 1)
    v_before = vrel[i0 - 1]
    v_after = vrel[-1]
    return ImpactResult(restitution=float(-v_after / v_before), contact_time=float(t_out - t_in),
                        max_overlap=float(-gap.min()))
