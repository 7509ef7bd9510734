"""Two threads or one on a busy machine: wall time per step of the same simulation (two
force chunks) executed by two threads and by one, on the settled 20,000-sphere bed of
``bench_engine.py``.

The chunks are the same either way, so the results are identical; only the wall time
differs. Runs alternate (``--steps`` steps each, ``--repeat`` times); the ratio is the
median of the per-repeat ratios. The load average is printed with the result: on an idle
machine two threads should win, on one whose cores are taken by other processes OpenMP's
spinning threads wait for each other and one thread wins.

Usage: ``python benchmarks/bench_busy_threads.py [--particles N] [--steps N] [--repeat N]``.
The last line is ``RESULT ms_per_step_2threads=... ms_per_step_1thread=...
speedup_2threads=... load=... cpus=...``.
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, default=20000)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cache-dir", default=str(Path(tempfile.gettempdir()) / "bedstruct-engines"))
    a = ap.parse_args(argv)
    data = be.settled_bed_data(a.particles, Path(a.cache_dir))
    loads = [os.getloadavg()[0]]
    sim = be.make_bedstruct(be.load_bed(data), n_threads=2, warmup=20)
    sim.yield_when_busy = False  # the choice is this benchmark's
    ms = {1: [], 2: []}
    for rep in range(a.repeat):
        for threads in ((2, 1) if rep % 2 == 0 else (1, 2)):
            sim.serial_below = 0 if threads == 2 else sim.n_particles + 1
            t0 = time.perf_counter()
            sim.run(a.steps)
            ms[threads].append((time.perf_counter() - t0) / a.steps * 1e3)
        loads.append(os.getloadavg()[0])
        print(f"# repeat {rep}: 2 threads {ms[2][-1]:.2f} ms/step, 1 thread {ms[1][-1]:.2f}, "
              f"load {loads[-1]:.2f}", flush=True)
    ratio = float(np.median(np.array(ms[1]) / np.array(ms[2])))
    print(f"RESULT ms_per_step_2threads={np.median(ms[2]):.4g} ms_per_step_1thread="
          f"{np.median(ms[1]):.4g} speedup_2threads={ratio:.3f} load={np.mean(loads):.2f} "
          f"cpus={os.cpu_count()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
