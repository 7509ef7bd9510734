"""Benchmark: transient heat conduction on a 1,000,000-particle contact network.

A simple cubic lattice of 100 x 100 x 100 CoCr spheres (20 um spacing,
radius 10.5 um) with random position and radius perturbations, so every
contact has its own conductance (~3 contacts per particle counted once, 6 per
particle). The seed's heat source (a 500 um hemisphere at 1300 C, switched off
at once) sits at the centre of the top surface; the bed is insulated. The
transient runs to ``--t-end`` with adaptive backward-Euler steps (step
doubling, Richardson extrapolation) solved by Jacobi-preconditioned CG on
``--threads`` numba threads. Target: under 60 s of solve time on 2 cores.

Usage::

    python benchmarks/bench_heat.py [--n 100] [--t-end 2e-3] [--threads 2]

Prints one line ``RESULT n_particles=... n_contacts=... solve_s=... steps=...
energy_error=...``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def perturbed_lattice(n: int, spacing: float = 20.0, radius: float = 10.5, jitter: float = 0.15,
                      seed: int = 0):
    """Frame and contacts of an n^3 perturbed simple cubic lattice (micrometres)."""
    from bedstruct.core import Box, Contacts, Frame, Units
    rng = np.random.default_rng(seed)
    g = np.arange(n)
    grid = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    pos = (grid + 0.5) * spacing + rng.normal(scale=jitter, size=grid.shape)
    radii = radius + rng.uniform(-0.1, 0.1, size=len(grid))
    idx = np.arange(len(grid)).reshape(n, n, n)
    ii, jj = [], []
    for ax in range(3):
        sl_a = [slice(None)] * 3
        sl_b = [slice(None)] * 3
        sl_a[ax] = slice(0, n - 1)
        sl_b[ax] = slice(1, n)
        ii.append(idx[tuple(sl_a)].ravel())
        jj.append(idx[tuple(sl_b)].ravel())
    i = np.concatenate(ii)
    j = np.concatenate(jj)
    box = Box([0, 0, 0], [n * spacing] * 3, boundary="ff ff ff")
    frame = Frame(pos, radii, box=box, units=Units("micro"))
    contacts = Contacts(i, j, pos[j] - pos[i], radii[i], radii[j], n_particles=len(pos))
    return frame, contacts


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=100, help="particles per lattice edge (n^3 in all)")
    p.add_argument("--t-end", type=float, default=2e-3, help="simulated time (s)")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--atol", type=float, default=1.0, help="local error tolerance per step (K)")
    args = p.parse_args(argv)

    from bedstruct._numba import set_num_threads
    from bedstruct.analysis.heat import HemisphereSource, conduct_heat, thermal_network
    set_num_threads(args.threads)

    t0 = time.perf_counter()
    frame, contacts = perturbed_lattice(args.n)
    net = thermal_network(frame, contacts)
    _ = net.weights, net.weight_sums
    build_s = time.perf_counter() - t0

    # compile the kernels on a tiny problem so that solve_s measures the solve
    small_f, small_c = perturbed_lattice(4)
    small = thermal_network(small_f, small_c)
    conduct_heat(small, t_end=1e-4, solver="cg", times=[1e-4])

    L = args.n * 20e-6
    src = HemisphereSource((L / 2, L / 2), diameter=500e-6, temperature=1573.15)
    t1 = time.perf_counter()
    res = conduct_heat(net, t_end=args.t_end, source=src, solver="cg", atol=args.atol,
                       times=[args.t_end])
    solve_s = time.perf_counter() - t1
    print(f"RESULT n_particles={net.n_particles} n_contacts={int(np.count_nonzero(net.conductance))} "
          f"solve_s={solve_s:.2f} build_s={build_s:.2f} steps={res.n_steps} "
          f"rejected={res.n_rejected} cg_iterations={res.n_iterations} "
          f"source_particles={res.source_nodes.size} "
          f"peak_end_C={res.final_temperature.max() - 273.15:.1f} "
          f"energy_error={res.energy.relative_error:.2e} threads={args.threads}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
