"""Settle the same bed with bedstruct, LIGGGHTS and LAMMPS and compare the statistics.

One initial state (a loose polydisperse lattice made by
:func:`bedstruct.engines.loose_lattice`, periodic in x and y, a plate at
z = 0) is written as a LAMMPS data file and run to rest under gravity by

* the embedded engine (``bedstruct.dem.Simulation``),
* LIGGGHTS 3.8 (``pair gran model hertz tangential history [cohesion sjkr]
  rolling_friction epsd2``, the seed's model), and
* LAMMPS (``pair_style granular hertz/material ... damping coeff_restitution
  tangential mindlin ... rolling sds``), without cohesion only (LAMMPS has no
  SJKR),

with identical parameters and time step. Recorded: kinetic energy (translational
plus rotational) against time, and the final state (``write_data`` in full
precision for the external engines). Compared: the peak kinetic energy, the
settling time (last time the kinetic energy exceeds 1e-3 of its peak), the
distance between log10 KE curves, and, at rest, the mean coordination number
(``bedstruct.coordination``, tolerance ``CONTACT_TOL``) and the packing fraction
in a fixed window (lower part of the bed).

Trajectories of granular beds are chaotic, so engines are compared through
statistics, against the spread of replicates of one engine whose initial
velocities differ by a tiny random perturbation (``perturbation`` m/s).

Usage: ``python benchmarks/compare_engines.py [--particles N] [--replicates K]
[--cohesion K] [--quick]``. Prints one table row per engine run and ends with
``RESULT ...`` (per-engine settling time, coordination and packing with and
without cohesion, and the replicate spreads).
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bedstruct import Box, Frame, coordination, packing_fraction
from bedstruct.dem import ContactModel, Plane, Simulation, rayleigh_time, seed_contact_model
from bedstruct.engines import (bed_deck, find_lammps, find_liggghts,
                               loose_lattice, run_deck, write_sphere_data)
from bedstruct.io import read_data

log = logging.getLogger("compare_engines")

#: Radii (m) of the test powder: uniform in this range.
RADIUS_RANGE = (15e-6, 30e-6)
#: Fraction of the peak kinetic energy that defines "settled".
SETTLED_FRACTION = 1e-3
#: Extra gap (m) still counted as a contact when computing coordination numbers.
CONTACT_TOL = 0.0
#: SJKR cohesion energy density (J/m^3) of the cohesive runs: at E = 1e7 Pa two
#: touching spheres rest at delta / R* = (3 pi k / (2 E*))^2 = 7e-4 (docs/backends.md).
COHESION = 3e4
#: Engine variants: "liggghts_tr" is LIGGGHTS with ``tangential_reduce on`` (SJKR
#: counted in the Coulomb and rolling limits, as bedstruct's engine does).
ENGINES = ("bedstruct", "liggghts", "liggghts_tr", "lammps")


@dataclass(frozen=True)
class Case:
    """One initial bed: positions, radii (m), box, initial velocities (m/s)."""

    positions: np.ndarray
    radii: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    velocities: np.ndarray


@dataclass(frozen=True)
class Settled:
    """Result of one settling run."""

    engine: str
    time: np.ndarray      # s
    ke: np.ndarray        # J, translational + rotational
    frame: Frame          # final state
    wall_time: float      # s

    @property
    def peak(self) -> float:
        return float(self.ke.max())

    @property
    def t_peak(self) -> float:
        return float(self.time[int(np.argmax(self.ke))])

    def t_below(self, fraction: float = SETTLED_FRACTION) -> float:
        """Time after which KE stays below ``fraction`` x its peak (s); inf if it never does."""
        above = np.nonzero(self.ke > fraction * self.peak)[0]
        if above[-1] == len(self.ke) - 1:
            return math.inf
        return float(self.time[above[-1] + 1])


#: Gravity along -z (m/s^2), in every engine.
GRAVITY = 9.81


def params(cohesion: float = 0.0) -> ContactModel:
    """The seed's soft contact model (E = 1e7 Pa, e = 0.1, mu = 0.4, mu_r = 0.05 epsd2)."""
    return seed_contact_model(cohesion=cohesion)


def time_step(p: ContactModel) -> float:
    """0.15 x the Rayleigh time of the smallest radius of ``RADIUS_RANGE`` (s)."""
    return 0.15 * rayleigh_time(RADIUS_RANGE[0], p.materials[0])


def make_case(n: int, *, width: float, seed: int = 0, perturbation: float = 0.0,
              perturb_seed: int = 0) -> Case:
    """A loose lattice of ``n`` spheres; velocities uniform in +-``perturbation`` (m/s)."""
    pos, rad, lo, hi = loose_lattice(n, radius_range=RADIUS_RANGE, width=(width, width), rng=seed)
    vel = np.random.default_rng(1000 + perturb_seed).uniform(-perturbation, perturbation, (n, 3))
    return Case(pos, rad, lo, hi, vel)


def window_top(case: Case) -> float:
    """Top (m) of the packing window: 70 % of the height of a bed at packing 0.6."""
    area = (case.hi[0] - case.lo[0]) * (case.hi[1] - case.lo[1])
    vol = float(np.sum(4.0 / 3.0 * np.pi * case.radii ** 3))
    return 0.7 * vol / (0.6 * area)


def statistics(res: Settled, case: Case) -> dict:
    """Settling time, mean coordination and windowed packing of a settled run."""
    f = res.frame
    cn = coordination(f, tolerance=CONTACT_TOL)
    top = window_top(case)
    window = ([case.lo[0], case.lo[1], case.lo[2]], [case.hi[0], case.hi[1], case.lo[2] + top])
    return dict(t_peak=res.t_peak, peak=res.peak, t_settle=res.t_below(SETTLED_FRACTION),
                t_1e2=res.t_below(1e-2),
                cn=float(cn.mean), cn_mech=float(cn.mechanical),
                packing=float(packing_fraction(f, window)),
                height=float(np.max(f.positions[:, 2] + f.radii)),
                ke_end=float(res.ke[-1]), n=int(f.n_particles if hasattr(f, "n_particles")
                                                  else len(f.radii)))


def run_bedstruct(case: Case, p: ContactModel, *, dt: float, steps: int, every: int) -> Settled:
    """Settle ``case`` with the embedded engine; KE every ``every`` steps."""
    box = Box(case.lo, case.hi, boundary="pp pp ff")
    sim = Simulation(box, p, walls=[Plane((0, 0, case.lo[2]), (0, 0, 1), name="plate")],
                     gravity=(0, 0, -GRAVITY), dt=dt, n_threads=1,
                     skin=0.2 * float(case.radii.min()))
    sim.add_particles(case.positions, case.radii, velocities=case.velocities)
    t, ke = [0.0], [sim.kinetic_energy()]
    t0 = time.perf_counter()
    done = 0
    while done < steps:
        k = min(every, steps - done)
        sim.run(k)
        done += k
        t.append(sim.time)
        ke.append(sim.kinetic_energy())
    wall = time.perf_counter() - t0
    if sim.n_removed:
        raise RuntimeError(f"bedstruct lost {sim.n_removed} particles")
    return Settled("bedstruct", np.array(t), np.array(ke), sim.frame(), wall)


def tangential_reduce_on(deck: str) -> str:
    """Add ``tangential_reduce on`` to the particle-particle ``pair_style gran`` of a deck.

    With it, LIGGGHTS' SJKR subtracts the cohesive force from the normal force
    used in the Coulomb and rolling-friction limits (default off: only Hertz +
    damping count). ``fix wall/gran`` refuses the keyword, so walls keep the
    default.
    """
    return "\n".join(line + " tangential_reduce on" if line.startswith("pair_style gran") else line
                     for line in deck.splitlines()) + "\n"


def run_external(engine: str, case: Case, p: ContactModel, *, dt: float, steps: int, every: int,
                 workdir) -> Settled:
    """Settle ``case`` with LIGGGHTS (``"liggghts"``, or ``"liggghts_tr"`` with
    ``tangential_reduce on``) or LAMMPS (one rank); thermo every ``every`` steps."""
    name = engine
    engine = "liggghts" if engine.startswith("liggghts") else engine
    wd = Path(workdir)
    wd.mkdir(parents=True, exist_ok=True)
    data = write_sphere_data(wd / "initial.data", case.positions, case.radii, box_lo=case.lo,
                             box_hi=case.hi, density=p.materials[0].density, n_types=2,
                             velocities=case.velocities)
    deck = bed_deck(data, p, engine=engine, steps=steps, dt=dt, gravity=GRAVITY, thermo_every=every,
                    write_data="final.data", skin=0.2 * float(case.radii.min()))
    if name == "liggghts_tr":
        deck = tangential_reduce_on(deck)
    (wd / "settle.in").write_text(deck)
    t0 = time.perf_counter()
    res = run_deck(wd / "settle.in", engine=engine, np=1, cwd=wd)
    wall = time.perf_counter() - t0
    run = res.log.last
    step = run.column("Step")
    ke = run.column("KinEng") if run.has_column("KinEng") else run.column("ke")
    ke = ke + run.column("c_rke")
    frame = read_data(wd / "final.data", boundary="pp pp ff")
    if len(frame.radii) != len(case.radii):
        raise RuntimeError(f"{engine} lost {len(case.radii) - len(frame.radii)} particles")
    return Settled(name, step * dt, ke, frame, wall)


def log_curve_distance(a: Settled, b: Settled, *, floor: float = SETTLED_FRACTION) -> float:
    """Median |log10 KE_a - log10 KE_b| over common times where both exceed ``floor`` x peak.

    Both curves must be sampled at the same times.
    """
    n = min(len(a.ke), len(b.ke))
    ka, kb = a.ke[:n], b.ke[:n]
    m = (ka > floor * a.peak) & (kb > floor * b.peak)
    if not np.any(m):
        return math.nan
    return float(np.median(np.abs(np.log10(ka[m]) - np.log10(kb[m]))))


def settle_steps(case: Case, p: ContactModel, dt: float) -> int:
    """Steps enough to settle: 3x the free-fall time from the top of the lattice."""
    ztop = float(np.max(case.positions[:, 2]))
    return int(math.ceil(3.0 * math.sqrt(2 * ztop / GRAVITY) / dt))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--width", type=float, default=0.6e-3, help="box width in x and y (m)")
    ap.add_argument("--replicates", type=int, default=3,
                    help="perturbed replicates per engine and cohesion")
    ap.add_argument("--perturbation", type=float, default=1e-4, help="m/s")
    ap.add_argument("--cohesion", type=float, default=COHESION, help="SJKR k (J/m^3)")
    ap.add_argument("--quick", action="store_true", help="300 particles, 3 replicates")
    ap.add_argument("--workdir", default=None)
    args = ap.parse_args(argv)
    if args.quick:
        args.particles, args.width, args.replicates = 300, 0.4e-3, 3
    logging.basicConfig(level=logging.WARNING)
    lig = find_liggghts() is not None
    have = {"bedstruct": True, "liggghts": lig, "liggghts_tr": lig,
            "lammps": find_lammps() is not None}
    tmp = tempfile.TemporaryDirectory(prefix="bedstruct-compare-") if args.workdir is None else None
    root = Path(tmp.name if tmp else args.workdir)
    rows = []
    for k in (0.0, args.cohesion):
        p = params(k)
        dt = time_step(p)
        # LAMMPS has no SJKR; tangential_reduce only matters with cohesion
        engines = [e for e in ENGINES if have[e] and not (e == "lammps" and k > 0)
                   and not (e == "liggghts_tr" and k == 0)]
        for rep in range(args.replicates):
            case = make_case(args.particles, width=args.width,
                             perturbation=args.perturbation if rep else 0.0, perturb_seed=rep)
            steps = settle_steps(case, p, dt)
            every = max(steps // 400, 1)
            for eng in engines:
                if eng == "bedstruct":
                    r = run_bedstruct(case, p, dt=dt, steps=steps, every=every)
                else:
                    r = run_external(eng, case, p, dt=dt, steps=steps, every=every,
                                     workdir=root / f"{eng}_k{k:g}_r{rep}")
                s = statistics(r, case)
                rows.append(dict(engine=eng, k=k, rep=rep, res=r, **s))
                print(f"{eng:11s} k={k:<7g} rep={rep} t_peak={s['t_peak'] * 1e3:6.2f} ms "
                      f"KE_peak={s['peak']:.3e} J t(1e-2)={s['t_1e2'] * 1e3:6.2f} ms "
                      f"t(1e-3)={s['t_settle'] * 1e3:6.2f} ms "
                      f"CN={s['cn']:.3f} CN_mech={s['cn_mech']:.3f} phi={s['packing']:.4f} "
                      f"h={s['height'] * 1e6:.1f} um wall={r.wall_time:.1f} s", flush=True)
    # summary: per engine and cohesion, mean over replicates; spread = max - min
    print()
    print(f"{'engine':11s} {'k (J/m3)':>9s} {'t(1e-2) ms':>13s} {'t(1e-3) ms':>13s} {'CN':>14s}"
          f" {'packing':>16s} {'logKE dist to bedstruct':>24s}")
    result = {}
    for k in (0.0, args.cohesion):
        ref = [r for r in rows if r["engine"] == "bedstruct" and r["k"] == k]
        for eng in ENGINES:
            sel = [r for r in rows if r["engine"] == eng and r["k"] == k]
            if not sel:
                continue
            ts = np.array([r["t_settle"] for r in sel])
            pk = np.array([r["peak"] for r in sel])
            t2 = np.array([r["t_1e2"] for r in sel])
            cn = np.array([r["cn"] for r in sel])
            ph = np.array([r["packing"] for r in sel])
            dist = [log_curve_distance(a["res"], b["res"]) for a, b in zip(sel, ref)
                    if a is not b]
            if eng == "bedstruct":  # replicate spread: perturbed runs against the unperturbed
                dist = [log_curve_distance(a["res"], sel[0]["res"]) for a in sel[1:]]
            d = float(np.median(dist)) if dist else math.nan
            print(f"{eng:11s} {k:9.3g} {t2.mean() * 1e3:7.2f}+-{np.ptp(t2) * 1e3:4.2f} "
                  f"{ts.mean() * 1e3:7.2f}+-{np.ptp(ts) * 1e3:4.2f} "
                  f"{cn.mean():7.3f}+-{np.ptp(cn):5.3f} {ph.mean():8.4f}+-{np.ptp(ph):6.4f} "
                  f"{d:24.3f}")
            tag = f"{eng}_{'coh' if k else 'dry'}"
            result[f"{tag}_ke_peak_J"] = pk.mean()
            result[f"{tag}_logke_dist"] = d
            result[f"{tag}_t1e2_ms"] = t2.mean() * 1e3
            result[f"{tag}_t1e3_ms"] = ts.mean() * 1e3
            result[f"{tag}_cn"] = cn.mean()
            result[f"{tag}_phi"] = ph.mean()
            if eng == "bedstruct":
                result[f"spread_{'coh' if k else 'dry'}_cn"] = np.ptp(cn)
                result[f"spread_{'coh' if k else 'dry'}_phi"] = np.ptp(ph)
                result[f"spread_{'coh' if k else 'dry'}_t1e2_ms"] = np.ptp(t2) * 1e3
    if tmp is not None:
        tmp.cleanup()
    print("RESULT " + " ".join(f"{key}={val:.4g}" for key, val in result.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
