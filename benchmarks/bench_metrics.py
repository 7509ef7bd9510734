"""Benchmark: contacts + coordination + windowed packing on 1,000,000 polydisperse
particles in a ``pp pp ff`` box, with OVITO's neighbour finding on the same frame
(when the ``ovito`` package is installed) for the ratio.

Target: the whole chain under 5 s on 2 cores, memory under 2 GB. Run::

    python benchmarks/bench_metrics.py [--n 1000000] [--threads 2] [--repeat 2]

The bed is a jittered cubic arrangement (spacing 38 um, ~25 layers) with radii
drawn from the seed report's CoCr powder (D10/D50/D90 = 29.84/52.08/86.11 um,
25-105 um), giving a mean coordination number of about 4. Ends with
``RESULT n=... n_contacts=... contacts_s=... cn_s=... packing_s=... chain_s=...
chain_cpu_s=... peak_rss_mb=... ovito_s=... ovito_over_bedstruct=...`` (best of
``--repeat`` after a warm-up; ``chain_cpu_s`` is the process CPU time of the
chain summed over threads, a load-insensitive check on a shared machine).
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np


def make_bed(n, seed=0):
    from bedstruct import Box, Frame
    from bedstruct.analysis import psd_from_percentiles

    fit = psd_from_percentiles(29.84, 52.08, 86.11, (25.0, 105.0))
    radii = fit.sample_radii(n, seed=seed)
    nz = 25
    nxy = int(np.ceil(np.sqrt(n / nz)))
    s = 38.0
    rng = np.random.default_rng(seed + 1)
    k = np.arange(n)
    grid = np.stack([k % nxy, (k // nxy) % nxy, k // (nxy * nxy)], axis=1).astype(np.float64)
    pos = (grid + 0.5) * s + rng.normal(0, 4.0, (n, 3))
    pos[:, 2] = np.maximum(pos[:, 2], radii)
    box = Box([0, 0, 0], [nxy * s, nxy * s, (grid[:, 2].max() + 2) * s], boundary="pp pp ff")
    return Frame(pos, radii, box=box)


def ovito_neighbours(frame, chunk=100_000):
    """Radius-aware contacts through OVITO's CutoffNeighborFinder (cutoff 2 r_max)."""
    from ovito.data import CutoffNeighborFinder, DataCollection

    data = DataCollection()
    cell = np.zeros((3, 4))
    cell[:, :3] = frame.box.matrix
    cell[:, 3] = frame.box.lo
    data.create_cell(cell, pbc=frame.box.periodic)
    parts = data.create_particles(count=frame.n_particles)
    parts.create_property("Position", data=frame.positions)
    finder = CutoffNeighborFinder(2.0 * float(frame.radii.max()), data)
    total = 0
    for start in range(0, frame.n_particles, chunk):     # bounded memory: ~90 neighbours each
        idx, vec = finder.find_all(indices=np.arange(start, min(start + chunk, frame.n_particles)))
        keep = idx[:, 0] < idx[:, 1]
        idx, vec = idx[keep], vec[keep]
        d2 = np.einsum("ij,ij->i", vec, vec)
        rs = frame.radii[idx[:, 0]] + frame.radii[idx[:, 1]]
        total += int(np.count_nonzero(d2 <= rs * rs))
    return total


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=1_000_000)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--repeat", type=int, default=2)
    args = p.parse_args(argv)

    from bedstruct._numba import set_num_threads
    from bedstruct.analysis import coordination, find_contacts, packing_along

    set_num_threads(args.threads)
    frame = make_bed(args.n)
    # warm-up: compile or load the cached kernels on a small frame
    small = make_bed(2000)
    packing_along(small)
    coordination(small, find_contacts(small))

    best = dict(contacts=np.inf, cn=np.inf, packing=np.inf, chain=np.inf, cpu=np.inf)
    for _ in range(args.repeat):
        c0 = time.process_time()
        t0 = time.perf_counter()
        c = find_contacts(frame)
        t1 = time.perf_counter()
        cn = coordination(frame, c)
        t2 = time.perf_counter()
        prof = packing_along(frame, 3)
        t3 = time.perf_counter()
        c3 = time.process_time()
        for key, val in (("contacts", t1 - t0), ("cn", t2 - t1), ("packing", t3 - t2), ("chain", t3 - t0),
                         ("cpu", c3 - c0)):
            best[key] = min(best[key], val)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    # sanity: windows partition the bed volume, CN consistent with the contact count
    assert abs(prof.solid_volume.sum() / frame.particle_volume - 1) < 1e-9
    assert abs(cn.mean - 2 * c.n_contacts / frame.n_particles) < 1e-12

    ovito_s = ratio = float("nan")
    try:
        import ovito  # noqa: F401
    except ImportError:
        ovito_note = "ovito=not-installed"
    else:
        t0 = time.perf_counter()
        m = ovito_neighbours(frame)
        ovito_s = time.perf_counter() - t0
        ratio = ovito_s / best["contacts"]
        assert m == c.n_contacts, f"OVITO found {m} contacts, bedstruct {c.n_contacts}"
        ovito_note = "ovito=ok"
    print(f"RESULT n={frame.n_particles} n_contacts={c.n_contacts} mean_cn={cn.mean:.3f} "
          f"packing={','.join(f'{v:.4f}' for v in prof.fractions)} threads={args.threads} "
          f"contacts_s={best['contacts']:.3f} cn_s={best['cn']:.3f} packing_s={best['packing']:.3f} "
          f"chain_s={best['chain']:.3f} chain_cpu_s={best['cpu']:.3f} peak_rss_mb={peak_mb:.0f} ovito_s={ovito_s:.3f} "
          f"ovito_over_bedstruct={ratio:.2f} {ovito_note}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
