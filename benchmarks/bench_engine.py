"""Benchmark the embedded DEM engine against LIGGGHTS and LAMMPS on the same bed.

A dense polydisperse bed (radii 14-50 um, the seed's soft CoCr model) is
poured and settled by bedstruct once, cached in ``<tempdir>/bedstruct-engines``
as a checkpoint and a LAMMPS data file, then timed with the same problem in
every engine: the seed's contact model with SJKR cohesion on
(:data:`BENCH_COHESION`), the bed's floor as the only wall, gravity, and the
same neighbour skin (0.1 d_min, the decks' default):

* bedstruct with 1 and 2 threads (compilation and I/O excluded: a warm-up run
  precedes the timed runs);
* LIGGGHTS with the seed's rolling model ``epsd2`` (which Debian's LIGGGHTS runs
  on its unoptimised, non-whitelisted path) and with ``cdt`` (whitelisted), 1 and
  2 MPI ranks; LAMMPS (``pair granular``, DMT cohesion: it has no SJKR) on 1 and 2
  ranks; nan where an engine is missing or fails (the reason is printed).

The machine is shared: the runs are interleaved, repeat by repeat, and every
ratio is the median of the per-repeat ratios (never each side's best). The
external engines' times are their ``Loop time`` (wall clock of the timed run),
so bedstruct's ratios use its wall-clock time of the same repeat; its CPU time
is printed too.

Memory: ``bytes_per_particle`` is the steady state (arrays held); the peak adds
what a neighbour rebuild touches on top, measured as the rise of the process's
resident-set high-water mark over one rebuild (``/proc/self/clear_refs``; Linux).

Usage: ``python benchmarks/bench_engine.py [--quick] [--steps N] [--particles N] [--profile]
[--repeat N] [--no-external] [--threading-layer omp|tbb|workqueue|default]``.
The last line is ``RESULT bedstruct_steps_per_s=... liggghts_steps_per_s=...
lammps_steps_per_s=... ratio_1core=... ratio_1core_cdt=... ratio_1core_180k=...
speedup_2threads=... bytes_per_particle_peak=... bytes_per_particle_peak_goal=...
memory_goal_met=yes|no ...`` (particle-steps per
second, medians over repeats; bedstruct_steps_per_s is the 2-thread figure;
ratio_1core is bedstruct over LIGGGHTS epsd2 on one core, ratio_1core_cdt over
LIGGGHTS cdt; ratio_1core_180k is measured only with ``--particles 180000``,
nan otherwise). A bed of ``k**2`` x 20,000 spheres is the 20,000-sphere bed
repeated k x k times in x and y (it is periodic there, so the copies fit together
at rest); ``--particles 180000`` uses k = 3. Where numba may use only one thread (``NUMBA_NUM_THREADS=1``,
or one CPU) the "2-thread" run executes its two chunks on one thread: the bench
prints a warning, reports ``speedup_2threads=nan`` and records
``numba_max_threads=1``.

Threading layer: importing bedstruct asks numba for OpenMP first, then workqueue, TBB last
(``bedstruct._numba.THREADING_LAYER_PRIORITY``); ``--threading-layer`` (default ``omp``)
overrides that order for this run, and the layer numba actually used is printed as
``threading_layer=``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bedstruct import Box
from bedstruct.dem import ContactModel, Plane, Simulation, seed_contact_model

R_MIN, R_MAX = 14e-6, 50e-6
WIDTH = 2e-3
#: SJKR cohesion energy density of the timed runs (J/m^3). Its cost per contact does not
#: depend on the value; a modest one leaves the settled bed at rest at the soft modulus.
BENCH_COHESION = 1e5


def seed_model(*, cohesion: float = 0.0) -> ContactModel:
    """The seed's contact model (soft CoCr; hertz, history, epsd2), SJKR ``cohesion`` (J/m^3)."""
    return seed_contact_model(cohesion=cohesion)


def pour(n: int, path: Path, *, n_threads: int = 1, log=print) -> Simulation:
    """Pour ``n`` spheres into a 2 x 2 mm periodic box and settle them (bedstruct only).

    Raindrop insertion at about 20 % packing, a pour at 5 g with a large skin, then
    settling at 1 g until the kinetic energy is below 1e-12 J per 20,000 spheres
    (or 30 ms). Takes a few minutes for 20,000 spheres.
    """
    rng = np.random.default_rng(0)
    radii = rng.uniform(R_MIN, R_MAX, n)
    vol = float(np.sum(4 / 3 * np.pi * radii ** 3))
    width = WIDTH * math.sqrt(n / 20000)
    height = vol / 0.32 / width ** 2
    box = Box([0, 0, 0], [width, width, 1.6 * height + 4 * R_MAX], boundary="pp pp ff")
    # a large skin and strong gravity make the pour cheap; the bed is re-timed later
    sim = Simulation(box, seed_model(), walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")],
                     gravity=(0, 0, -9.81 * 5), skin=0.5 * R_MIN * 2, n_threads=n_threads, seed=0)
    placed = 0
    z0 = 0.0
    while placed < n:  # raindrop in slabs until all are in
        k = sim.insert_raindrop(n - placed, radii[placed:],
                                region=((0, 0, z0), (width, width, 1.6 * height + 3 * R_MAX)))
        placed += k
        if k == 0:
            break
    log(f"# pouring {sim.n_particles} spheres, dt = {sim.dt if sim.dt else 0:.3g} s")
    t0 = time.perf_counter()
    for _ in range(200):
        sim.run(2000)
        ke = sim.kinetic_energy()
        log(f"#   t = {sim.time * 1e3:.2f} ms  KE = {ke:.3g} J  top = {sim.x[:, 2].max() * 1e3:.3f} mm"
            f"  ({time.perf_counter() - t0:.0f} s)")
        if ke < 1e-10 * sim.n_particles / 20000 and sim.time > 5e-3:
            break
    sim.gravity = np.array([0.0, 0.0, -9.81])
    for _ in range(45):  # settle at 1 g (about 30 ms) until the bed is at rest
        sim.run(2000)
        ke = sim.kinetic_energy()
        log(f"#   t = {sim.time * 1e3:.2f} ms  KE = {ke:.3g} J (1 g)")
        if ke < 1e-12 * sim.n_particles / 20000:
            break
    sim.save_checkpoint(path)
    return sim


def write_data_file(sim: Simulation, path: Path) -> Path:
    """The bed as a LAMMPS/LIGGGHTS data file (atom_style sphere, SI)."""
    from bedstruct.engines import write_sphere_data
    fr = sim.frame()
    top = float((fr.positions[:, 2] + fr.radii).max())
    write_sphere_data(path, fr.positions, fr.radii, box_lo=fr.box.lo,
                      box_hi=[fr.box.hi[0], fr.box.hi[1], max(fr.box.hi[2], top + 4 * R_MAX)],
                      density=8300.0)
    return path


def settled_bed_data(n: int, cache: Path) -> Path:
    """The data file of a settled bed of ``n`` spheres in ``cache``, poured by bedstruct on
    first use (:func:`pour`) and reused after."""
    cache.mkdir(parents=True, exist_ok=True)
    data = cache / f"bedstruct_bed{n}.data"
    if not data.exists():
        write_data_file(pour(n, cache / f"bedstruct_bed{n}.npz"), data)
    return data


def tiled_bed_data(data: Path, k: int, cache: Path) -> Path:
    """The bed of ``data`` repeated ``k`` x ``k`` times in x and y, as a data file in ``cache``.

    The bed is periodic in x and y, so its copies fit together as one settled bed
    ``k`` times as wide and long: every sphere keeps its neighbours (those across a
    periodic face now sit in the next copy), and the bed of ``k**2`` times as many
    spheres starts at rest without pouring it.
    """
    from bedstruct.engines import write_sphere_data
    out = cache / f"{data.stem}_tiled{k}.data"
    if out.exists():
        return out
    fr = load_bed(data)
    lo, hi = np.asarray(fr.box.lo, float), np.asarray(fr.box.hi, float)
    span = hi - lo
    shifts = np.array([(a * span[0], b * span[1], 0.0) for a in range(k) for b in range(k)])
    positions = (fr.positions[None, :, :] + shifts[:, None, :]).reshape(-1, 3)
    radii = np.tile(fr.radii, k * k)
    velocities = np.tile(fr.velocities, (k * k, 1)) if fr.velocities is not None else None
    omegas = np.tile(fr.omegas, (k * k, 1)) if fr.omegas is not None else None
    box_hi = lo + span * np.array([k, k, 1.0])
    write_sphere_data(out, positions, radii, box_lo=lo, box_hi=box_hi, density=8300.0,
                      velocities=velocities, omegas=omegas)
    return out


def load_bed(data: Path):
    """The bed of a data file as a Frame (SI, x/y periodic, z fixed)."""
    from bedstruct.io import read_data
    return read_data(data, boundary="pp pp ff")


def bench_skin(fr) -> float:
    """The neighbour skin of every engine: 0.1 x the smallest diameter (the decks' default)."""
    return 0.2 * float(fr.radii.min())


def make_bedstruct(fr, *, n_threads: int, warmup: int, dt: float | None = None) -> Simulation:
    """The bed on its floor with the benchmark's model and skin, warmed up (compiled,
    histories formed)."""
    sim = Simulation(fr.box, seed_model(cohesion=BENCH_COHESION),
                     walls=[Plane((0, 0, 0), (0, 0, 1), name="floor")], n_threads=n_threads,
                     dt=dt, force=dt is not None, skin=bench_skin(fr))
    sim.serial_below = 0  # use the threads even for the --quick bed
    sim.yield_when_busy = False  # the threads asked for, however busy the machine
    sim.add_particles(fr.positions, fr.radii, velocities=fr.velocities, omegas=fr.omegas)
    sim.run(warmup)
    return sim


def _rss_kib(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise KeyError(field)


def rebuild_peak_bytes(sim: Simulation) -> float:
    """Bytes a neighbour rebuild touches on top of the resident set (nan off Linux).

    The resident-set high-water mark is reset (``/proc/self/clear_refs``), one rebuild
    runs, and the rise of the mark over the resident set before it is returned.
    Memory the allocator had already mapped and freed is not seen, so this is a lower
    bound of the allocation.
    """
    try:
        Path("/proc/self/clear_refs").write_text("5")
        before = _rss_kib("VmRSS")
        sim._rebuild()
        return 1024.0 * max(_rss_kib("VmHWM") - before, 0)
    except (OSError, KeyError):
        return math.nan


def time_bedstruct(sim: Simulation, *, steps: int) -> dict:
    reb0 = sim.n_rebuilds
    c0 = time.process_time()
    stats = sim.run(steps)
    cpu = time.process_time() - c0
    c = sim.contacts()
    per_p, per_pair = sim.memory_bytes()
    n_contacts = c.n_contacts + c.walls.n_contacts
    return {"pss": stats.particle_steps_per_s, "n": sim.n_particles,
            "pss_cpu": sim.n_particles * steps / max(cpu, 1e-12),
            "rebuilds": sim.n_rebuilds - reb0,
            "contacts_per_particle": 2 * c.n_contacts / sim.n_particles,
            "contacts_total_per_particle": n_contacts / sim.n_particles,
            "pairs_per_particle": sim.n_pairs / sim.n_particles,
            "bytes_per_particle": per_p,
            "bytes_per_contact": per_pair * sim.n_pairs / max(n_contacts, 1),
            "bytes_per_pair": per_pair,
            "ns_per_contact": stats.wall_time / steps / max(c.n_contacts, 1) * 1e9,
            "dt": sim.dt, "kinetic_energy": sim.kinetic_energy()}


def profile_phases(sim: Simulation, *, steps: int) -> dict:
    """Milliseconds per step in each pass (unfused steps; uses the engine's private passes).

    ``kick`` half kick + drift, ``lists`` neighbour/wall-list rebuilds, ``pair`` the pair
    pass, ``finish`` reduction + walls + second half kick.
    """
    from bedstruct.dem import _kernels as K
    ph = dict(kick=0.0, lists=0.0, pair=0.0, finish=0.0)
    for _ in range(steps):
        s, dt = sim, sim.dt
        t0 = time.perf_counter()
        K.kick_drift(s.x, s.v, s.om, s.f, s.tq, s.inv_m, s.inv_i, s.x_ref, dt, s._pbounds, s._disp)
        t1 = time.perf_counter()
        if s._disp.max() > (0.5 * s.skin) ** 2:
            s._rebuild()
        elif s._wall_speed * (s.time + dt - s._wall_list_time) > 0.5 * s.skin:
            s.time += dt
            s._build_wall_list()
            s.time -= dt
        t2 = time.perf_counter()
        s._pair_pass(dt, s.ht, s.hr, s._fbuf, s._tbuf, False, s._fn_out, s._ft_out)
        t3 = time.perf_counter()
        s.step += 1
        s.time += dt
        s._finish_pass(dt, s.v, s.om, s.f, s.tq, s._fbuf, s._tbuf, s.wslot, s.whist, False,
                       s._wfn, s._wdel, s._wnrm)
        t4 = time.perf_counter()
        for key, val in zip(ph, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
            ph[key] += val
    return {key: val / steps * 1e3 for key, val in ph.items()}


def time_liggghts(data: Path, *, np_: int, steps: int, dt: float, skin: float,
                  rolling: str = "epsd2") -> float:
    """LIGGGHTS particle-steps/s of the timed run (its Loop time), or nan (reason printed)."""
    import tempfile as _tf

    from dataclasses import replace

    from bedstruct.engines import bed_deck, run_deck
    try:
        with _tf.TemporaryDirectory(prefix="bedstruct-bench-liggghts-") as wd:
            model = replace(seed_model(cohesion=BENCH_COHESION), rolling_model=rolling)
            deck = bed_deck(data, model, engine="liggghts", steps=steps, dt=dt,
                            thermo_every=0, warmup_steps=100, skin=skin)
            path = Path(wd) / "bench_liggghts.in"
            path.write_text(deck)
            run = run_deck(path, engine="liggghts", np=np_, cwd=wd, timeout=900).log.last
            if run.loop_time is None or run.n_steps != steps:
                raise RuntimeError(f"no Loop time line for the timed run of {steps} steps")
            return run.n_atoms * steps / max(run.loop_time, 1e-12)
    except Exception as exc:  # engine missing or failed: report nan, say why
        print(f"# liggghts {rolling} np={np_}: not timed ({type(exc).__name__}: {str(exc)[:160]})")
        return math.nan


def time_lammps(data: Path, *, np_: int, steps: int, dt: float) -> float:
    """LAMMPS particle-steps/s (``pair granular``, DMT cohesion), or nan (reason printed)."""
    try:
        from bedstruct.engines import benchmark_external
        res = benchmark_external(data, engine="lammps", np=np_, steps=steps, dt=dt,
                                 model=seed_model(cohesion=BENCH_COHESION),
                                 cohesion_model="dmt", warmup_steps=100, timeout=900)
        return float(res["particle_steps_per_s"])
    except Exception as exc:
        print(f"# lammps np={np_}: not timed ({type(exc).__name__}: {str(exc)[:160]})")
        return math.nan


def _median(values) -> float:
    vals = [v for v in values if not math.isnan(v)]
    return float(np.median(vals)) if vals else math.nan


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="4,000 spheres, 300 steps")
    ap.add_argument("--particles", type=int, default=None)
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--no-external", action="store_true", help="skip LIGGGHTS/LAMMPS")
    ap.add_argument("--repeat", type=int, default=None,
                    help="interleaved repeats; ratios are medians of per-repeat ratios (3)")
    ap.add_argument("--profile", action="store_true",
                    help="also print ms per step in each engine pass (1 thread, 200 steps)")
    ap.add_argument("--cache-dir", default=str(Path(tempfile.gettempdir()) / "bedstruct-engines"))
    ap.add_argument("--threading-layer", default="omp", choices=["omp", "tbb", "workqueue", "default"],
                    help="numba threading layer to prefer for this run, if available (default omp: "
                         "its worker threads spin between the engine's short parallel passes, "
                         "~1.8x on 2 idle cores against ~1.5x for tbb; spinning workers collapse "
                         "on cores shared with other jobs, see docs/performance.md). 'default' "
                         "changes nothing: bedstruct's own order, which importing bedstruct sets "
                         "(bedstruct._numba.THREADING_LAYER_PRIORITY: omp > workqueue > tbb), or "
                         "NUMBA_THREADING_LAYER / NUMBA_THREADING_LAYER_PRIORITY when set. The "
                         "layer used is printed as threading_layer= in the RESULT line")
    args = ap.parse_args(argv)
    if args.threading_layer != "default" and "NUMBA_THREADING_LAYER" not in os.environ:
        import numba

        from bedstruct._numba import THREADING_LAYER_PRIORITY
        # read when the first parallel kernel runs, which is after this point; the others
        # follow in bedstruct's order
        numba.config.THREADING_LAYER_PRIORITY = [args.threading_layer] + [
            name for name in THREADING_LAYER_PRIORITY if name != args.threading_layer]
    n = args.particles or (4000 if args.quick else 20000)
    steps = args.steps or (300 if args.quick else 1000)
    warmup = 100
    args.repeat = args.repeat or 3
    cache = Path(args.cache_dir)
    cache.mkdir(parents=True, exist_ok=True)
    data = cache / f"bedstruct_bed{n}.data"
    other = cache / f"bed{n}_seed0.data"  # poured by bedstruct.engines.cached_bed
    tile = math.isqrt(n // 20000) if n > 20000 and n % 20000 == 0 else 0
    if data.exists():
        origin = "poured by bedstruct"
    elif tile >= 2 and tile * tile * 20000 == n:  # the 20,000-sphere bed repeated in x and y
        data = tiled_bed_data(settled_bed_data(20000, cache), tile, cache)
        origin = f"the 20,000-sphere bed repeated {tile} x {tile} in x and y"
    elif other.exists():
        data, origin = other, "poured by LAMMPS/LIGGGHTS (bedstruct.engines.cached_bed)"
    else:
        data, origin = settled_bed_data(n, cache), "poured by bedstruct"
    import numba
    max_threads = int(numba.config.NUMBA_NUM_THREADS)
    one_thread_only = max_threads < 2
    if one_thread_only:  # the "2-thread" run would run its 2 chunks on one thread
        print(f"# WARNING: numba may use only {max_threads} thread here (NUMBA_NUM_THREADS="
              f"{os.environ.get('NUMBA_NUM_THREADS', 'unset')}, {os.cpu_count()} CPUs): the "
              "'2 threads' run executes its 2 chunks on one thread, so speedup_2threads is "
              "reported as nan and bedstruct_steps_per_s is a 1-thread figure", flush=True)
    fr = load_bed(data)
    skin = bench_skin(fr)
    print(f"# bed: {data} ({fr.n_particles} spheres, {origin}); {steps} timed steps after {warmup}; "
          f"cohesion {BENCH_COHESION:g} J/m^3, floor only, skin {skin:.3g} m in every engine; "
          f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())} "
          f"on {os.cpu_count()} CPUs at the start")
    s1 = make_bedstruct(fr, n_threads=1, warmup=warmup)
    s2 = make_bedstruct(fr, n_threads=2, warmup=warmup)
    dt = s1.dt
    runs = {key: [] for key in ("b1", "b2", "b1_cpu", "lig1", "lig2", "cdt1", "cdt2", "lmp1",
                                "lmp2")}
    first = None
    for rep in range(args.repeat):  # interleaved: every engine once per repeat
        r1 = time_bedstruct(s1, steps=steps)
        r2 = time_bedstruct(s2, steps=steps)
        first = first or r1
        runs["b1"].append(r1["pss"])
        runs["b1_cpu"].append(r1["pss_cpu"])
        runs["b2"].append(r2["pss"])
        print(f"# repeat {rep + 1}: bedstruct 1 thread {r1['pss']:.4g} (CPU time {r1['pss_cpu']:.4g}), "
              f"2 threads {r2['pss']:.4g} particle-steps/s", flush=True)
        if args.no_external:
            continue
        for key, rolling, np_ in (("lig1", "epsd2", 1), ("cdt1", "cdt", 1), ("lig2", "epsd2", 2),
                                  ("cdt2", "cdt", 2)):
            runs[key].append(time_liggghts(data, np_=np_, steps=steps, dt=dt, skin=skin,
                                           rolling=rolling))
            print(f"# repeat {rep + 1}: liggghts {rolling} np={np_}: {runs[key][-1]:.4g} "
                  "particle-steps/s", flush=True)
        for key, np_ in (("lmp1", 1), ("lmp2", 2)):
            runs[key].append(time_lammps(data, np_=np_, steps=steps, dt=dt))
            print(f"# repeat {rep + 1}: lammps np={np_}: {runs[key][-1]:.4g} particle-steps/s",
                  flush=True)
    if args.profile:
        from bedstruct import _numba
        _numba.set_num_threads(1)
        prof = profile_phases(s1, steps=200)
        print("# bedstruct 1 thread, ms per step by pass: "
              + " ".join(f"{k}={v:.3f}" for k, v in prof.items())
              + f" (sum {sum(prof.values()):.3f})")
    for k, v in first.items():
        print(f"# bedstruct 1 thread (first repeat): {k} = {v:.4g}")

    def ratio(a, b):  # median over repeats of the per-repeat ratio
        return _median([x / y if y > 0 else math.nan for x, y in zip(runs[a], runs[b])])

    n_rep = len(runs["b1"])
    ratio_lig = ratio("b1", "lig1") if runs["lig1"] else math.nan
    ratio_cdt = ratio("b1", "cdt1") if runs["cdt1"] else math.nan
    speedup = math.nan if one_thread_only else ratio("b2", "b1")
    if one_thread_only:
        print(f"# WARNING: speedup_2threads = nan: both bedstruct runs used one thread "
              f"(NUMBA_NUM_THREADS={max_threads}); measured 2-chunk/1-chunk = {ratio('b2', 'b1'):.3g}")
    peak = rebuild_peak_bytes(s1)
    steady = first["bytes_per_particle"] * s1.n_particles + first["bytes_per_pair"] * s1.n_pairs
    per_peak = (steady + peak) / s1.n_particles
    # the goal: peak memory <= 500 B per particle + 100 B per contact (walls included)
    goal_per_particle = 500.0 + 100.0 * first["contacts_total_per_particle"]
    big = s1.n_particles >= 150000
    med = {key: _median(vals) if vals else math.nan for key, vals in runs.items()}
    print(f"# medians over {n_rep} interleaved repeats; load average at the end "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"RESULT bedstruct_steps_per_s={med['b2']:.4g} liggghts_steps_per_s={med['lig1']:.4g} "
          f"lammps_steps_per_s={med['lmp1']:.4g} ratio_1core={ratio_lig:.3g} "
          f"ratio_1core_cdt={ratio_cdt:.3g} "
          f"ratio_1core_180k={ratio_lig if big else math.nan:.3g} "
          f"speedup_2threads={speedup:.3g} bedstruct_1thread_steps_per_s={med['b1']:.4g} "
          f"bedstruct_1thread_cpu_steps_per_s={med['b1_cpu']:.4g} "
          f"liggghts_cdt_steps_per_s={med['cdt1']:.4g} "
          f"liggghts_2rank_steps_per_s={med['lig2']:.4g} "
          f"liggghts_cdt_2rank_steps_per_s={med['cdt2']:.4g} "
          f"lammps_2rank_steps_per_s={med['lmp2']:.4g} n_particles={first['n']} steps={steps} "
          f"repeats={n_rep} rebuilds={first['rebuilds']} "
          f"bytes_per_particle={first['bytes_per_particle']:.0f} "
          f"bytes_per_particle_peak={per_peak:.0f} "
          f"bytes_per_particle_peak_goal={goal_per_particle:.0f} "
          f"memory_goal_met={'yes' if per_peak <= goal_per_particle else 'no'} "
          f"bytes_per_contact={first['bytes_per_contact']:.0f} bytes_per_pair={first['bytes_per_pair']:.0f} "
          f"threading_layer={_layer_used()} numba_max_threads={max_threads}")
    return 0


def _layer_used() -> str:
    import numba
    try:
        return str(numba.threading_layer())
    except ValueError:  # no parallel kernel has run
        return "none"


if __name__ == "__main__":
    sys.exit(main())
