"""Micro-benchmark of the engine's pair pass: blocked (gather-compute-scatter) against the
single loop, on a settled bed of 20,000 spheres, one thread, CPU time.

The bed is the one of ``bench_engine.py`` (poured and cached on first use, which takes a few
minutes); the model is the seed's (hertz, history, epsd2, SJKR cohesion). From one state
(every call from the same history) the two passes are run alternately, ``--calls`` calls
each per repeat, timed with the
process's CPU time (``time.process_time``: the machine may be shared); the speed-up is the
median of the per-repeat ratios. The passes' results from the same state (forces, torques,
histories) are compared first: ``identical=1`` when equal bit for bit, and the largest
difference relative to each quantity's largest magnitude. Whole steps are timed the same
way (``--steps`` per side and repeat, the simulation advancing).

Usage: ``python benchmarks/bench_pair_pass.py [--particles N] [--calls N] [--steps N]
[--repeat N]`` (about a minute at the defaults once compiled).
The last line is ``RESULT pair_ns_per_contact_old=... new=... speedup=... step_ms_old=...
step_ms_new=... step_speedup=... identical=... max_rel_diff=... contacts=... load=...``
(medians; ``load`` is the 1-minute load average).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_engine as be  # noqa: E402

from bedstruct import _numba  # noqa: E402


def _pass(sim, blocked, ht, hr, fb, tb):
    from bedstruct.dem import _kernels as K
    m = sim.model
    K.pair_forces((sim.x, sim.v, sim.om, sim.rad, sim.mass, sim.inv_i, sim.ptype),
                  (sim.pi, sim.pj, sim.psh), sim._L, (ht, hr), sim._qbounds, fb, tb,
                  sim._pair_tab, m.rolling_code, m.limit_force, float(m.rolling_damping), sim.dt,
                  False, sim._fn_out, sim._ft_out, None, None, sim._kr_fac, blocked=blocked)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, default=20000)
    ap.add_argument("--calls", type=int, default=200, help="pair passes per side and repeat")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--steps", type=int, default=50, help="whole steps per side and repeat")
    ap.add_argument("--cache-dir", default=str(Path(tempfile.gettempdir()) / "bedstruct-engines"))
    a = ap.parse_args(argv)
    data = be.settled_bed_data(a.particles, Path(a.cache_dir))
    load0 = os.getloadavg()[0]
    _numba.set_num_threads(1)
    sim = be.make_bedstruct(be.load_bed(data), n_threads=1, warmup=20)
    n_contacts = sim.contacts().n_contacts
    ht0, hr0 = sim.ht.copy(), sim.hr.copy()
    out = {}
    for blocked in (False, True):
        ht, hr = ht0.copy(), hr0.copy()
        fb, tb = np.zeros_like(sim._fbuf), np.zeros_like(sim._tbuf)
        _pass(sim, blocked, ht, hr, fb, tb)
        out[blocked] = (fb, tb, ht, hr)
    identical = all(np.array_equal(a, b) for a, b in zip(out[False], out[True]))
    # the largest difference relative to each quantity's largest magnitude
    max_rel = max(float(np.abs(b - a).max() / max(np.abs(a).max(), 1e-300))
                  for a, b in zip(out[False], out[True]))
    ratios, t_old, t_new = [], [], []
    for rep in range(a.repeat):  # interleaved, the order alternating between repeats
        times = {}
        for blocked in ((False, True) if rep % 2 == 0 else (True, False)):
            ht, hr = ht0.copy(), hr0.copy()
            fb, tb = np.zeros_like(sim._fbuf), np.zeros_like(sim._tbuf)
            cpu = 0.0
            for _ in range(a.calls):
                ht[:] = ht0  # every call from the same history (not timed)
                hr[:] = hr0
                c0 = time.process_time()
                _pass(sim, blocked, ht, hr, fb, tb)
                cpu += time.process_time() - c0
            times[blocked] = cpu / a.calls / n_contacts * 1e9
        t_old.append(times[False])
        t_new.append(times[True])
        ratios.append(times[False] / times[True])
        print(f"# repeat {rep}: old {times[False]:.1f} ns/contact, new {times[True]:.1f}, "
              f"ratio {ratios[-1]:.3f}", flush=True)
    step_ratios, s_old, s_new = [], [], []
    for rep in range(a.repeat):  # whole steps (the simulation advances), 1 thread, CPU time
        times = {}
        for blocked in ((False, True) if rep % 2 == 0 else (True, False)):
            sim.blocked_pairs = blocked
            c0 = time.process_time()
            sim.run(a.steps)
            times[blocked] = (time.process_time() - c0) / a.steps * 1e3
        s_old.append(times[False])
        s_new.append(times[True])
        step_ratios.append(times[False] / times[True])
    load = 0.5 * (load0 + os.getloadavg()[0])
    print(f"# {sim.n_particles} spheres, {n_contacts} contacts, {sim.n_pairs} pairs; one thread; "
          f"load average {load:.2f} on {os.cpu_count()} CPUs")
    print(f"RESULT pair_ns_per_contact_old={np.median(t_old):.4g} new={np.median(t_new):.4g} "
          f"speedup={np.median(ratios):.3f} step_ms_old={np.median(s_old):.4g} "
          f"step_ms_new={np.median(s_new):.4g} step_speedup={np.median(step_ratios):.3f} "
          f"identical={int(identical)} max_rel_diff={max_rel:.3g} contacts={n_contacts} "
          f"load={load:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
