"""Benchmark: fabric tensors (ranks 2 and 4, all three kinds) and the real
spherical-harmonic expansion to l = 8 for 1,000,000 contact normals.

Target: under 1 s in total on 2 cores. Run::

    python benchmarks/bench_fabric.py [--n 1000000] [--l-max 8] [--threads 2] [--repeat 3]

Ends with ``RESULT n_contacts=... tensors_s=... harmonics_s=... total_s=...``
(best of ``--repeat`` runs after one warm-up that compiles the kernels).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=1_000_000)
    p.add_argument("--l-max", type=int, default=8)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--weighted", action="store_true", help="use random per-contact weights")
    args = p.parse_args(argv)

    from bedstruct._numba import set_num_threads
    from bedstruct.analysis.fabric import fabric_tensors
    from bedstruct.analysis.harmonics import harmonic_expansion

    set_num_threads(args.threads)
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(args.n, 3))          # not normalised: the kernels normalise
    weights = rng.random(args.n) if args.weighted else None

    # warm-up (numba compilation or cache load) on a small input
    fabric_tensors(normals[:1000], None if weights is None else weights[:1000])
    harmonic_expansion(normals[:1000], args.l_max, None if weights is None else weights[:1000])

    best_t = best_h = best_tot = np.inf
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        t = fabric_tensors(normals, weights)
        t1 = time.perf_counter()
        e = harmonic_expansion(normals, args.l_max, weights)
        t2 = time.perf_counter()
        best_t = min(best_t, t1 - t0)
        best_h = min(best_h, t2 - t1)
        best_tot = min(best_tot, t2 - t0)
    # a cheap sanity check so that the benchmark cannot time wrong numbers
    assert abs(np.trace(t.N2) - 1) < 1e-10 and abs(e.power[0] * 4 * np.pi - 1) < 1e-10
    assert t.anisotropy < 0.05, "isotropic sample should have small anisotropy"
    print(f"RESULT n_contacts={t.n_contacts} l_max={args.l_max} threads={args.threads} "
          f"tensors_s={best_t:.4f} harmonics_s={best_h:.4f} total_s={best_tot:.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
