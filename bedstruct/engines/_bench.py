"""Timing the external engines on a bed, and pouring beds to time them on."""

from __future__ import annotations

import logging
import math
import tempfile
from pathlib import Path

import numpy

from ._bed import bed_deck
from ._datafile import read_data_header, write_sphere_data
from ._launch import run_deck
from ._params import check_gravity, coefficient
from ._registry import dialect

__all__ = ["benchmark_external", "pour_bed", "loose_lattice", "cached_bed"]

log = logging.getLogger(__name__)


def benchmark_external(data_file, *, engine: str, np: int = 1, steps: int = 1000,
                       dt: float, model=None, gravity: float = 9.81, warmup_steps: int = 100,
                       workdir=None, cohesion_model: str | None = None,
                       timeout: float | None = None) -> dict:
    """Time LIGGGHTS or LAMMPS on a bed, excluding start-up and I/O.

    One deck reads the bed, runs ``warmup_steps`` steps (neighbour lists and
    contact histories form), then runs ``steps`` more with no dumps and thermo
    only at the end. The result comes from that second run's ``Loop time``
    line, so process start, ``read_data`` and setup are excluded.

    Parameters
    ----------
    data_file : str or os.PathLike
        A settled bed (sphere/granular data file), e.g. from :func:`pour_bed`.
    engine : {"liggghts", "lammps"}
    np : int
        MPI ranks.
    steps : int
        Timed steps.
    dt : float, s
        Time step.
    model : bedstruct.dem.ContactModel, optional
        Contact model of one particle type (default: the seed's,
        :func:`~bedstruct.dem.seed_contact_model`).
    gravity : float, m/s^2
        Magnitude of gravity along -z.
    warmup_steps : int
        Untimed steps before the timed run.
    workdir : str or os.PathLike, optional
        Where the deck and log go (default: a temporary folder, removed after).
    cohesion_model : {None, "dmt", "jkr"}
        LAMMPS only, for non-zero cohesion.
    timeout : float, s, optional
        Kill the run after this long.

    Returns
    -------
    dict
        ``engine`` (str), ``np`` (int), ``n_atoms`` (int), ``steps`` (int),
        ``dt`` (s), ``loop_time_s`` (s, timed run only), ``particle_steps_per_s``
        (n_atoms x steps / loop_time_s), ``ns_per_particle_step``,
        ``neighbors_per_atom`` (half-list neighbours per atom after the run, or
        NaN), ``kinetic_energy_j`` (final translational KE, J: a blown-up run
        shows here), ``wall_time_s`` (whole process), ``version`` (log header).

    Raises
    ------
    FileNotFoundError
        If the engine is not installed.
    EngineRunError
        If the run fails.
    """
    own = workdir is None
    tmp = tempfile.TemporaryDirectory(prefix=f"bedstruct-bench-{engine}-") if own else None
    wd = Path(tmp.name if own else workdir)
    wd.mkdir(parents=True, exist_ok=True)
    try:
        deck = bed_deck(data_file, model, engine=engine, steps=steps, dt=dt, gravity=gravity,
                        thermo_every=0,
                        warmup_steps=warmup_steps, cohesion_model=cohesion_model)
        deck_path = wd / f"bench_{engine}.in"
        deck_path.write_text(deck)
        res = run_deck(deck_path, engine=engine, np=np, cwd=wd, timeout=timeout)
        run = res.log.last
        if run.loop_time is None or run.n_steps != steps:
            raise RuntimeError(f"{engine} log has no Loop time line for the timed run of {steps} steps")
        loop = max(run.loop_time, 1e-12)
        pss = run.n_atoms * steps / loop
        try:
            ke = float(run.column("KinEng")[-1])
        except KeyError:
            ke = math.nan
        return {
            "engine": engine, "np": int(np), "n_atoms": int(run.n_atoms), "steps": int(steps),
            "dt": float(dt), "loop_time_s": float(run.loop_time), "particle_steps_per_s": pss,
            "ns_per_particle_step": 1e9 / pss,
            "neighbors_per_atom": (math.nan if run.neighbors_per_atom is None
                                   else run.neighbors_per_atom),
            "kinetic_energy_j": ke, "wall_time_s": res.wall_time, "version": res.log.version,
        }
    finally:
        if tmp is not None:
            tmp.cleanup()


def loose_lattice(n_particles: int, *, radius_range=(14e-6, 50e-6), width=(2e-3, 2e-3),
                  rng=None, spacing_factor: float = 1.02):
    """Random radii on a loose simple-cubic lattice, ready to be poured.

    Parameters
    ----------
    n_particles : int
    radius_range : (float, float), m
        Radii are uniform between the bounds (a simple polydisperse test
        powder; the seed's range is 14-50 um).
    width : (float, float), m
        Box extent in x and y (periodic); the height follows from the count.
    rng : numpy.random.Generator or int, optional
    spacing_factor : float
        Lattice spacing as a multiple of the largest diameter.

    Returns
    -------
    positions : (N, 3) ndarray, m
    radii : (N,) ndarray, m
    box_lo, box_hi : (3,) ndarray, m

    Examples
    --------
    >>> pos, rad, lo, hi = loose_lattice(100, rng=1)
    >>> pos.shape, bool(rad.min() >= 14e-6), bool(numpy.all(pos[:, 2] < hi[2]))
    ((100, 3), True, True)
    """
    rng = numpy.random.default_rng(rng)
    rmin, rmax = map(float, radius_range)
    a = spacing_factor * 2 * rmax
    nx, ny = max(1, int(width[0] // a)), max(1, int(width[1] // a))
    nz = int(math.ceil(n_particles / (nx * ny)))
    ax, ay = width[0] / nx, width[1] / ny
    ii, jj, kk = numpy.meshgrid(numpy.arange(nx), numpy.arange(ny), numpy.arange(nz), indexing="ij")
    order = numpy.argsort(kk.ravel(), kind="stable")[:n_particles]
    pos = numpy.column_stack([(ii.ravel()[order] + 0.5) * ax, (jj.ravel()[order] + 0.5) * ay,
                           (kk.ravel()[order] + 0.5) * a + rmax * 0.02])
    pos[:, :2] += rng.uniform(-0.05, 0.05, (n_particles, 2)) * a
    rad = rng.uniform(rmin, rmax, n_particles)
    lo = numpy.zeros(3)
    hi = numpy.array([width[0], width[1], (nz + 1) * a])
    return pos, rad, lo, hi


def pour_bed(out_data, *, n_particles: int = 20000, engine: str = "liggghts", np: int = 1,
             radius_range=(14e-6, 50e-6), width=(2.5e-3, 2.5e-3), model=None,
             gravity: float = 9.81, gravity_factor: float = 50.0, steps: int | None = None, dt: float | None = None,
             rng=0, workdir=None, timeout: float | None = None) -> Path:
    """Pour spheres from a loose lattice onto a plate and write the settled bed.

    A quick way to make a dense polydisperse bed for benchmarks: enhanced
    gravity (``gravity_factor`` x ``gravity``) and strong damping shorten the
    fall; a final quarter of the steps runs at normal gravity. The physics of
    the pour is not meant to match anything.

    Parameters
    ----------
    out_data : str or os.PathLike
        Data file to write (2 atom types: particles 1, walls 2).
    n_particles, radius_range, width, rng
        See :func:`loose_lattice`.
    engine, np
        Engine and MPI ranks.
    model : bedstruct.dem.ContactModel, optional
        One particle type. Default: the seed's
        (:func:`~bedstruct.dem.seed_contact_model`) without rolling friction.
    gravity : float, m/s^2
        Magnitude of normal gravity along -z.
    gravity_factor : float
        Gravity multiplier during the fall.
    steps : int, optional
        Total steps (3/4 enhanced gravity, 1/4 normal). Default: enough for
        1.5 x the free-fall time from the top of the lattice.
    dt : float, s, optional
        Default: 0.15 x the Rayleigh time of the smallest sphere.
    workdir : optional
        Folder for the deck and log (default: a temporary one).
    timeout : float, s, optional

    Returns
    -------
    pathlib.Path
        ``out_data``.
    """
    if model is None:
        from ..dem import seed_contact_model
        model = seed_contact_model(rolling_friction=0.0)
    model = dialect(engine).deck_model(model)
    gravity = check_gravity(gravity)
    pos, rad, lo, hi = loose_lattice(n_particles, radius_range=radius_range, width=width, rng=rng)
    if dt is None:
        dt = 0.15 * model.rayleigh_time(float(rad.min()))
    if steps is None:
        g_eff = max(gravity * gravity_factor, 1e-12)
        t_fall = math.sqrt(2.0 * hi[2] / g_eff)
        steps = int(math.ceil(1.5 * t_fall / dt / 0.75))
    out_data = Path(out_data).resolve()
    own = workdir is None
    tmp = tempfile.TemporaryDirectory(prefix="bedstruct-pour-") if own else None
    wd = Path(tmp.name if own else workdir)
    wd.mkdir(parents=True, exist_ok=True)
    try:
        init = write_sphere_data(wd / "lattice.data", pos, rad, box_lo=lo, box_hi=hi,
                                 density=coefficient(model, "density"), n_types=2,
                                 velocities=numpy.tile([0.0, 0.0, -0.2], (n_particles, 1)))
        fall = int(steps * 3 // 4)
        deck = bed_deck(init, model, gravity=gravity * gravity_factor, engine=engine, steps=fall,
                        dt=dt, thermo_every=max(fall // 10, 1))
        # second stage at normal gravity, then write the bed
        deck += (f"unfix gravi\nfix gravi2 all gravity {gravity:.10g} vector 0.0 0.0 -1.0\n"
                 f"run {steps - fall}\n"
                 f"{dialect(engine).write_data_line(out_data)}\n")
        deck_path = wd / "pour.in"
        deck_path.write_text(deck)
        res = run_deck(deck_path, engine=engine, np=np, cwd=wd, timeout=timeout)
        log.info("poured %d spheres with %s in %.1f s", n_particles, engine, res.wall_time)
    finally:
        if tmp is not None:
            tmp.cleanup()
    head = read_data_header(out_data)
    if head["atoms"] != n_particles:
        raise RuntimeError(f"pour lost particles: {head['atoms']} of {n_particles} remain")
    return out_data


def cached_bed(n_particles: int = 20000, *, cache_dir=None, engine: str | None = None,
               np: int = 2, rng=0, timeout: float | None = None) -> Path:
    """A poured benchmark bed, made once and cached on disk.

    The file is ``<cache_dir>/bed<n_particles>_seed<rng>.data`` (default
    cache folder: ``<tempdir>/bedstruct-engines``); it is poured with
    :func:`pour_bed` (default sizes, LAMMPS if installed, else LIGGGHTS) when
    missing. Pouring 20,000 spheres takes about 10 minutes on 2 busy cores.

    Parameters
    ----------
    n_particles : int
    cache_dir : str or os.PathLike, optional
    engine : {"lammps", "liggghts"}, optional
    np : int
        MPI ranks for the pour.
    rng : int
        Seed of the radii and lattice jitter (part of the file name).
    timeout : float, s, optional

    Returns
    -------
    pathlib.Path

    Raises
    ------
    FileNotFoundError
        If the bed is not cached and no engine is installed.
    """
    folder = Path(cache_dir) if cache_dir is not None else Path(tempfile.gettempdir()) / "bedstruct-engines"
    path = folder / f"bed{int(n_particles)}_seed{int(rng)}.data"
    if path.is_file():
        return path
    if engine is None:
        found = [name for name in ("lammps", "liggghts") if dialect(name).find() is not None]
        engine = found[0] if found else None
        if engine is None:
            raise FileNotFoundError(f"{path} is not cached and neither LAMMPS nor LIGGGHTS is "
                                    "installed to pour it (run .ci/install-engines.sh)")
    folder.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".partial")
    pour_bed(tmp, n_particles=n_particles, engine=engine, np=np, rng=rng, timeout=timeout)
    tmp.replace(path)
    return path
