"""Benchmark: reading 6-digit LIGGGHTS dumps (plain, gz) and 17-digit engine dumps vs OVITO.

Generates a 15-column ``dump custom`` file (``id type x y z vx vy vz fx fy fz
omegax omegay omegaz radius``) with a few frames in a temporary folder, three ways:

* ``text``: 6 significant digits (``%g``), as LIGGGHTS writes;
* ``gz``: the same file gzip-compressed;
* ``text17``: the same values at full precision, written by ``bedstruct.write_dump`` (the
  writer of the embedded engine's ``RunDirectory``): Python's shortest round-trip ``repr``,
  mostly 16-17 significant digits. These numbers do not fit the parser's one-operation
  (Clinger) fast path; they take its Eisel-Lemire path (docs/formats.md);

and a ``dump local`` contact file of ``2 n`` contacts per frame (LIGGGHTS ``compute
pair/gran/local`` keywords ``pos id force contactArea``, 13 columns, ``%g``);

then reads each atom file with bedstruct and OVITO (the anchor: ``pip install -e
.[bench]``), and the two text files with MDAnalysis (a second anchor), in the same run.
Later frames are read in rounds: each round reads every later frame with both readers in
turn (which one goes first alternates), so both see the same machine load. Prints seconds
per frame (first frame including the scan; later frames: the median over rounds of each
round's mean), bedstruct's peak memory against the size of the arrays it returns, and a
final ``RESULT`` line with bedstruct's time over OVITO's (``ratio_text``, ``ratio_gz``,
``ratio_text17``: the median over rounds of the per-round ratio; nan when OVITO is not
installed) and over MDAnalysis's (``ratio_mda_text``, ``ratio_mda_text17``), bedstruct's
seconds per contact frame of ``read_dump_local`` (``bedstruct_local_s``: scan, parse and
join to atom frames read beforehand; the median over whole-file reads) and its time per MB
of text over the atom reader's (``local_per_mb_vs_text``; no OVITO or MDAnalysis counterpart
is timed), the number of threads bedstruct parsed with (``threads=``) and the machine's
1-minute load average at the start and the end (``load=``). A ratio below 1 means bedstruct
is faster.

Usage::

    python benchmarks/bench_read.py [--n 200000] [--frames 4] [--threads T] [--repeats 5]
                                    [--dir DIR] [--no-mdanalysis]

``--frames`` is 1 (first-frame times only) or at least 3: later frames are read in turn so
that no reader can answer from a cache of the last frame (OVITO keeps one). ``--threads``
sets numba's thread count (bedstruct's parser threads); ``--dir`` keeps the generated files
there and reuses them in later runs.

Numbers depend on the machine and its load; compare runs taken side by side.
"""

from __future__ import annotations

import argparse
import gzip
import math
import os
import shutil
import tempfile
import time
import tracemalloc
import warnings

import numpy as np

COLUMNS = "id type x y z vx vy vz fx fy fz omegax omegay omegaz radius"


def frame_data(n, frames, seed=0):
    """Per frame, an (n, 15) array of the COLUMNS (ids permuted, as a parallel run writes)."""
    rng = np.random.default_rng(seed)
    for _ in range(frames):
        ids = rng.permutation(n) + 1
        yield np.column_stack([
            ids, rng.integers(1, 3, n), rng.uniform(-0.05, 0.05, (n, 2)),
            rng.uniform(0, 0.15, n), rng.normal(0, 0.1, (n, 3)), rng.normal(0, 1e-3, (n, 3)),
            rng.normal(0, 10, (n, 3)), rng.uniform(1e-5, 3e-5, n)])


def generate(path, n, frames, seed=0):
    """The LIGGGHTS-style file: 6 significant digits (``%g``)."""
    fmt = "%d %d " + " ".join(["%g"] * 13)
    with open(path, "w") as fh:
        for k, data in enumerate(frame_data(n, frames, seed)):
            fh.write(f"ITEM: TIMESTEP\n{1000 * k}\nITEM: NUMBER OF ATOMS\n{n}\n"
                     "ITEM: BOX BOUNDS pp pp ff\n-0.05 0.05\n-0.05 0.05\n0 0.15\n"
                     f"ITEM: ATOMS {COLUMNS} \n")
            rows = data.tolist()
            fh.write("\n".join(fmt % tuple(r) for r in rows))
            fh.write("\n")


def generate_engine(path, n, frames, seed=0):
    """The same values at full precision, written as the embedded engine writes them
    (``bedstruct.write_dump``: shortest round-trip repr, up to 17 significant digits)."""
    from bedstruct import Box, Frame, write_dump
    box = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.15], boundary="pp pp ff")
    for k, data in enumerate(frame_data(n, frames, seed)):
        frame = Frame(data[:, 2:5], data[:, 14], box=box, timestep=1000 * k,
                      ids=data[:, 0].astype(np.int64), types=data[:, 1].astype(np.int64),
                      velocities=data[:, 5:8], forces=data[:, 8:11], omegas=data[:, 11:14])
        write_dump(path, frame, append=k > 0)


LOCAL_KEYWORDS = ("pos", "id", "force", "contactArea")


def generate_local(path, n, frames, seed=0):
    """A LIGGGHTS ``compute pair/gran/local`` contact file (keywords ``pos id force
    contactArea``: 13 columns, 6 significant digits) with ``2 n`` contacts per frame between
    random particles of the atom frames of :func:`frame_data` (same seed)."""
    rng = np.random.default_rng(seed + 1)
    fmt = " ".join(["%g"] * 6 + ["%d"] * 3 + ["%g"] * 4)
    with open(path, "w") as fh:
        for k, data in enumerate(frame_data(n, frames, seed)):
            m = 2 * n
            i, j = rng.integers(0, n, m), rng.integers(0, n, m)
            cols = np.column_stack([data[i, 2:5], data[j, 2:5], data[i, 0], data[j, 0],
                                    np.zeros(m), rng.normal(0, 1e-3, (m, 3)),
                                    rng.uniform(0, 1e-10, m)])
            fh.write(f"ITEM: TIMESTEP\n{1000 * k}\nITEM: NUMBER OF ENTRIES\n{m}\n"
                     "ITEM: BOX BOUNDS pp pp ff\n-0.05 0.05\n-0.05 0.05\n0 0.15\n"
                     "ITEM: ENTRIES " + " ".join(f"c_cout[{c + 1}]" for c in range(13)) + "\n")
            fh.write("\n".join(fmt % tuple(r) for r in cols.tolist()))
            fh.write("\n")


def bench_local(path, atoms_path, frames, repeats):
    """Seconds per contact frame of :func:`bedstruct.read_dump_local` (scan, parse and join
    to atom frames read beforehand): the median over rounds of whole-file reads."""
    import bedstruct
    traj = bedstruct.read_dump(atoms_path)
    atoms = [traj[k] for k in range(len(traj))]
    traj.close()
    bedstruct.read_dump_local(path, keywords=LOCAL_KEYWORDS, frames=atoms)
    rounds = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        got = bedstruct.read_dump_local(path, keywords=LOCAL_KEYWORDS, frames=atoms)
        rounds.append((time.perf_counter() - t0) / frames)
    assert len(got) == frames
    return float(np.median(rounds))


REPEATS = 5  # rounds of later-frame reads; the ratios are medians over rounds
OVITO_HINT = "pip install -e .[bench]  (or: pip install 'ovito>=3.10')"


def ovito_status():
    """(version string, None) when OVITO imports, else (None, reason)."""
    try:
        import ovito
        from ovito.io import import_file  # noqa: F401
    except Exception as exc:  # noqa: BLE001 - report any import failure
        return None, f"{type(exc).__name__}: {exc}"
    return ".".join(map(str, ovito.version)), None


def open_readers(path):
    """Open the file with bedstruct and OVITO; returns first-frame times and readers."""
    import bedstruct
    t0 = time.perf_counter()
    traj = bedstruct.read_dump(path)
    traj[0]
    b_first = time.perf_counter() - t0
    pipe, o_first = None, math.nan
    if ovito_status()[0] is not None:
        from ovito.io import import_file
        t0 = time.perf_counter()
        pipe = import_file(path)
        assert pipe.compute(0).particles.count > 0
        o_first = time.perf_counter() - t0
    return traj, b_first, pipe, o_first


def later_frames(traj, pipe, n_frames, repeats=REPEATS):
    """Seconds per later frame (1..) for bedstruct and OVITO, and their ratio.

    Each round reads every later frame with both readers in turn (which reader goes
    first alternates), so both see the same machine load and neither can answer
    from a one-frame cache. Per round, a reader's time is its mean over the frames;
    the results are the medians over rounds of those means and of the per-round
    ratio (bedstruct / OVITO), which a burst of load in one round does not move.
    """
    b_rounds, o_rounds, ratios = [], [], []
    for rnd in range(repeats):
        tb, to = [], []
        for k in range(1, n_frames):
            for who in ((0, 1) if (rnd + k) % 2 else (1, 0)):
                if who == 0:
                    t0 = time.perf_counter()
                    traj[k]
                    tb.append(time.perf_counter() - t0)
                elif pipe is not None:
                    t0 = time.perf_counter()
                    pipe.compute(k)
                    to.append(time.perf_counter() - t0)
        b_rounds.append(float(np.mean(tb)))
        if to:
            o_rounds.append(float(np.mean(to)))
            ratios.append(b_rounds[-1] / o_rounds[-1])
    med = (lambda v: float(np.median(v)) if v else math.nan)
    return med(b_rounds), med(o_rounds), med(ratios)


def frame_nbytes(f):
    arrays = [f.positions, f.radii, f.ids, f.types, f.velocities, f.omegas, f.forces, f.images,
              *f.columns.values()]
    return sum(a.nbytes for a in arrays if a is not None)


def bench_memory(path):
    import bedstruct
    traj = bedstruct.read_dump(path)
    traj[0]
    tracemalloc.start()
    f = traj[1 if len(traj) > 1 else 0]
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    traj.close()
    return peak, frame_nbytes(f)


def bench_mdanalysis(path, n_frames):
    try:
        import MDAnalysis as mda
    except ImportError:
        return math.nan, math.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        u = mda.Universe(path, topology_format="LAMMPSDUMP", format="LAMMPSDUMP")
        u.trajectory[0]
        first = time.perf_counter() - t0
        rounds = []
        for _ in range(REPEATS):
            t0 = time.perf_counter()
            for k in range(1, n_frames):
                u.trajectory[k]
            rounds.append((time.perf_counter() - t0) / max(1, n_frames - 1))
    return first, (float(np.median(rounds)) if n_frames > 1 else math.nan)


def _threads():
    from bedstruct._numba import get_num_threads
    return get_num_threads()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=200_000, help="particles per frame (200,000)")
    ap.add_argument("--frames", type=int, default=4, help="frames per file (4)")
    ap.add_argument("--no-mdanalysis", action="store_true", help="skip the MDAnalysis anchor")
    ap.add_argument("--threads", type=int, default=None,
                    help="threads bedstruct parses with (default: numba's default, the cores)")
    ap.add_argument("--repeats", type=int, default=REPEATS,
                    help=f"rounds of later-frame reads ({REPEATS}); ratios are medians")
    ap.add_argument("--dir", default=None,
                    help="folder for the generated files, kept and reused when present "
                         "(default: a temporary folder, removed)")
    args = ap.parse_args()
    if args.threads is not None:
        from bedstruct._numba import set_num_threads
        set_num_threads(args.threads)
    load0 = os.getloadavg()[0]
    if args.frames == 2:  # reads of frame 1 alone would be answered from OVITO's frame cache
        ap.error("--frames 2 is not supported: later-frame timings cycle through at least two "
                 "frames (OVITO keeps the last frame it read); use --frames 1 or >= 3")
    ovito_version, why = ovito_status()
    if ovito_version is None:
        print(f"OVITO is not installed ({why}): the ratios against OVITO (the anchor of this "
              f"benchmark) are nan. Install it with: {OVITO_HINT}")
    else:
        print(f"OVITO {ovito_version}")
    tmp = args.dir or tempfile.mkdtemp(prefix="bedstruct-bench-")
    os.makedirs(tmp, exist_ok=True)
    try:
        tag = f"{args.n}x{args.frames}"
        text = os.path.join(tmp, f"dump{tag}.liggghts")
        gz = text + ".gz"
        text17 = os.path.join(tmp, f"dump17_{tag}.liggghts")
        local = os.path.join(tmp, f"contacts_{tag}.local")
        t0 = time.perf_counter()
        if not (args.dir and all(os.path.exists(p) for p in (text, gz, text17))):
            generate(text, args.n, args.frames)
            with open(text, "rb") as src, gzip.open(gz, "wb", compresslevel=6) as dst:
                shutil.copyfileobj(src, dst, 1 << 24)
            generate_engine(text17, args.n, args.frames)
        if not (args.dir and os.path.exists(local)):
            generate_local(local, args.n, args.frames)
        sizes = {label: os.path.getsize(p) / 1e6 for label, p in
                 (("text", text), ("gz", gz), ("text17", text17), ("local", local))}
        print(f"generated {args.frames} frames x {args.n} particles x 15 columns: "
              f"{sizes['text']:.1f} MB text (%g), {sizes['gz']:.1f} MB gz, "
              f"{sizes['text17']:.1f} MB text17 (write_dump, 17 digits); "
              f"{2 * args.n} contacts x 13 columns per frame: {sizes['local']:.1f} MB dump local "
              f"(%g) ({time.perf_counter() - t0:.1f} s)")

        # load/compile the numba parser once, outside the timings
        import bedstruct
        t0 = time.perf_counter()
        small = os.path.join(tmp, "small.dump")
        bedstruct.write_dump(small, bedstruct.Frame([[0.1, 0.2, 0.3]], [0.1], box=[1, 1, 1]))
        bedstruct.read_dump(small)[0]
        print(f"bedstruct kernel load/compile: {time.perf_counter() - t0:.2f} s")

        try:
            import isal  # noqa: F401
            backend = "isal (ISA-L)"
        except ImportError:
            backend = "gzip (zlib)"
        print(f"bedstruct gz backend: {backend}; numba threads: {_threads()}")
        res = {}
        for label, path in (("text", text), ("gz", gz), ("text17", text17)):
            traj, b_first, pipe, o_first = open_readers(path)
            b_later, o_later, r_later = later_frames(traj, pipe, args.frames, args.repeats)
            assert traj[len(traj) - 1].n_particles == args.n
            traj.close()
            print(f"[{label}] bedstruct: first frame {b_first:.3f} s (incl. scan), later "
                  f"{b_later:.3f} s/frame")
            print(f"[{label}] ovito:     first frame {o_first:.3f} s (incl. scan), later "
                  f"{o_later:.3f} s/frame")
            res[f"bedstruct_{label}_s"] = b_later if args.frames > 1 else b_first
            res[f"ovito_{label}_s"] = o_later if args.frames > 1 else o_first
            res[f"ratio_{label}"] = r_later if args.frames > 1 else _ratio(b_first, o_first)
        for label, path in (("text", text), ("text17", text17)):
            m_first, m_later = (math.nan, math.nan) if args.no_mdanalysis else \
                bench_mdanalysis(path, args.frames)
            print(f"[{label}] mdanalysis: first frame {m_first:.3f} s (incl. scan), later "
                  f"{m_later:.3f} s/frame")
            res[f"mdanalysis_{label}_s"] = m_later if args.frames > 1 else m_first
        local_s = bench_local(local, text, args.frames, args.repeats)
        # per megabyte of text, against the atom reader's later frames
        local_per_mb = _ratio(local_s / (sizes["local"] / args.frames),
                              res["bedstruct_text_s"] / (sizes["text"] / args.frames))
        print(f"[local] bedstruct read_dump_local: {local_s:.3f} s/frame (scan, parse, join), "
              f"{local_per_mb:.2f}x the atom reader's time per MB")
        peak, nbytes = bench_memory(text)
        print(f"bedstruct peak traced memory while reading one frame: {peak / 1e6:.1f} MB for "
              f"{nbytes / 1e6:.1f} MB of returned arrays")
        ratio = {label: res[f"ratio_{label}"] for label in ("text", "gz", "text17")}
        mda = {label: _ratio(res[f"bedstruct_{label}_s"], res[f"mdanalysis_{label}_s"])
               for label in ("text", "text17")}
        slow_b = _ratio(res["bedstruct_text17_s"], res["bedstruct_text_s"])
        slow_o = _ratio(res["ovito_text17_s"], res["ovito_text_s"])
        print(f"17-digit over 6-digit text: bedstruct {slow_b:.2f}x, "
              + ("OVITO n/a" if math.isnan(slow_o) else f"OVITO {slow_o:.2f}x"))
        if ovito_version is None:
            print(f"OVITO is not installed: ratio_text, ratio_gz and ratio_text17 are nan "
                  f"({OVITO_HINT}); ratio_mda_* compare with MDAnalysis instead")
        print("RESULT " + " ".join([
            f"bedstruct_text_s={res['bedstruct_text_s']:.4f}",
            f"ovito_text_s={res['ovito_text_s']:.4f}",
            f"ratio_text={ratio['text']:.3f}",
            f"bedstruct_gz_s={res['bedstruct_gz_s']:.4f}",
            f"ovito_gz_s={res['ovito_gz_s']:.4f}",
            f"ratio_gz={ratio['gz']:.3f}",
            f"bedstruct_text17_s={res['bedstruct_text17_s']:.4f}",
            f"ovito_text17_s={res['ovito_text17_s']:.4f}",
            f"ratio_text17={ratio['text17']:.3f}",
            f"mdanalysis_text_s={res['mdanalysis_text_s']:.4f}",
            f"ratio_mda_text={mda['text']:.3f}",
            f"mdanalysis_text17_s={res['mdanalysis_text17_s']:.4f}",
            f"ratio_mda_text17={mda['text17']:.3f}",
            f"bedstruct_local_s={local_s:.4f}",
            f"local_per_mb_vs_text={local_per_mb:.3f}",
            f"peak_mem_ratio={peak / nbytes:.3f}",
            f"n={args.n}", f"frames={args.frames}",
            f"ovito={ovito_version or 'missing'}",
            f"threads={_threads()}",
            f"load={load0:.1f}-{os.getloadavg()[0]:.1f}",
        ]))
    finally:
        if not args.dir:
            shutil.rmtree(tmp, ignore_errors=True)


def _ratio(a, b):
    """a / b, nan when either is missing (nan) or b is 0."""
    return a / b if b > 0 and not (math.isnan(a) or math.isnan(b)) else math.nan


if __name__ == "__main__":
    main()
