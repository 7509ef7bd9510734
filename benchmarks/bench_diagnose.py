"""Benchmark: a diagnosis served by a run library and its emulator (cold, warm, confirm).

Builds the run library of the seed measurement design (``data/measurements/seed.toml``,
read with ``load_measurements``) for a simulator, fits its emulator, runs
``bedstruct.diagnose.diagnose`` on the :class:`EmulatedSimulator` up to its answer, and
reruns the real simulator at the chosen point (the recalibrated base parameters plus the
attributed effects' magnitudes) to confirm it. Run::

    python benchmarks/bench_diagnose.py                          # the analytic surrogate
    python benchmarks/bench_diagnose.py --sim engine --preset tiny --workers 2
    python benchmarks/bench_diagnose.py --lib-dir LIB            # keep (and resume) the library

Ends with ``RESULT warm_s=... confirm_s=... cold_s=... library_runs=...
emulator_loo_rmse_sigma=... confirm_rmse_sigma=...``:

- ``cold_s``: building the library (every run still missing from ``--lib-dir``) and
  fitting the emulator, s;
- ``warm_s``: loading the library (its key checked), the emulator (stored
  hyperparameters) and the diagnosis on the emulated simulator up to its answer, s;
- ``confirm_s``: the real simulator's rerun at the chosen point (``--confirm-seeds``
  seeds on ``--workers`` processes), s;
- ``library_runs``: runs in the library;
- ``emulator_loo_rmse_sigma``: leave-one-point-out error of the emulator in units of its
  predictive sigma (1 = calibrated);
- ``confirm_rmse_sigma``: how well the emulator predicted the confirming rerun: the RMS over
  the observable components of (rerun mean - prediction) / predictive sd of that mean
  (1 = calibrated).

A line before it says what the diagnosis answered, the fraction of components within 2
predictive sd (``confirm_within_2sigma``) and the mean wall time of one library run.
Goal at the engine's ``tiny`` preset on 2 cores: warm <= 60 s, warm + confirm <= 3 min,
cold <= 15 min. On a shared machine the times are indicative only.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sim", choices=("surrogate", "engine"), default="surrogate")
    p.add_argument("--preset", default="tiny", help="engine preset (with --sim engine)")
    p.add_argument("--measurements", default=str(_ROOT / "data/measurements/seed.toml"))
    p.add_argument("--lib-dir", default=None, help="library folder (default: a temporary one)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--scheduler", default=None, help="Dask scheduler address (tcp://...)")
    p.add_argument("--n-base", type=int, default=None)
    p.add_argument("--n-per-effect", type=int, default=None)
    p.add_argument("--replicates", type=int, default=None)
    p.add_argument("--vary", type=float, default=0.25,
                   help="relative half-width of the cohesion energy density range")
    p.add_argument("--effects", default=None,
                   help="comma-separated catalogue effects (default: all; fewer for a reduced library)")
    p.add_argument("--confirm-seeds", type=int, default=None)
    p.add_argument("--progress", action="store_true")
    a = p.parse_args(argv)

    from bedstruct.diagnose import (BASE_PARAMETERS, SurrogateSimulator, catalogue, diagnose,
                                    diagnosis_design, load_measurements)
    from bedstruct.diagnose.amortised import confirming_runs
    from bedstruct.diagnose.confirm import RERUN_SEED_STRIDE
    from bedstruct.diagnose.emulator import EmulatedSimulator
    from bedstruct.diagnose.emulator_fit import fit_emulator
    from bedstruct.diagnose.run_design import design_spec
    from bedstruct.diagnose.run_library import build_library, load_library

    engine = a.sim == "engine"
    n_base = a.n_base if a.n_base is not None else (0 if engine else 16)
    n_eff = a.n_per_effect if a.n_per_effect is not None else (2 if engine else 16)
    reps = a.replicates if a.replicates is not None else (2 if engine else 3)
    n_confirm = a.confirm_seeds if a.confirm_seeds is not None else (2 if engine else 4)

    ms = load_measurements(a.measurements)
    effects = catalogue(a.effects.split(",") if a.effects else None)
    design = diagnosis_design(ms, effects)
    if engine:
        from bedstruct.diagnose.engine_simulator import diagnosis_simulator
        sim = diagnosis_simulator(design, {"preset": a.preset, "n_threads": 1})
    else:
        sim = SurrogateSimulator(design)
    base = dict(BASE_PARAMETERS)
    spec = design_spec(base, vary={"cohesion_energy_density": a.vary}, effects=effects,
                       n_base=n_base, n_per_effect=n_eff, replicates=reps)
    lib_dir = Path(a.lib_dir) if a.lib_dir else Path(tempfile.mkdtemp(prefix="bedstruct-lib-"))

    t0 = time.perf_counter()
    lib = build_library(sim, spec, lib_dir, workers=a.workers, scheduler=a.scheduler,
                        progress=a.progress)
    emu = fit_emulator(lib, progress=a.progress)
    cold_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    lib = load_library(lib_dir, sim)
    emu = fit_emulator(lib)
    esim = EmulatedSimulator(emu)
    d = diagnose(ms, esim, base=base, effects=effects, progress=a.progress)
    warm_s = time.perf_counter() - t0

    sh = d.shrink
    point = {k: base[k] + float(v) for k, v in sh.nuisance.items()}
    point = dict(base, **point)
    mags = {k: float(v) for k, v in sh.magnitudes.items()}
    seeds = [RERUN_SEED_STRIDE + i for i in range(n_confirm)]
    emu.predict(point, mags)          # the emulator's prediction, before the rerun tests it
    t0 = time.perf_counter()
    runs = confirming_runs(sim, point, mags, seeds, a.workers)
    confirm_s = time.perf_counter() - t0
    chk = emu.check(runs, point, mags)

    import numpy as np
    per_run = float(np.nanmean(lib.run_wall_s)) if lib.n_runs else float("nan")
    per_run_cpu = float(np.nanmean(lib.run_cpu_s)) if np.isfinite(lib.run_cpu_s).any() else float("nan")
    print(f"answer: verdict={d.attribution.verdict} model={sh.model or 'none'} "
          f"magnitudes={mags} recalibration_shift={ {k: float(v) for k, v in sh.nuisance.items()} } "
          f"gap_fraction_closed={sh.fraction:.3g}")
    print(f"sim={a.sim} preset={a.preset if engine else '-'} workers={a.workers} "
          f"lib_dir={lib_dir} "
          f"run_wall_s_mean={per_run:.3g} run_cpu_s_mean={per_run_cpu:.3g} loo_within_2sigma={emu.loo.loo_within_2sigma:.3f} "
          f"confirm_within_2sigma={chk.within_2sigma:.3f} "
          f"seed_correlation={emu.seed_correlation:.2f} load={os.getloadavg()[0]:.1f}")
    print(f"RESULT warm_s={warm_s:.3g} confirm_s={confirm_s:.3g} cold_s={cold_s:.3g} "
          f"library_runs={lib.n_runs} emulator_loo_rmse_sigma={emu.loo.loo_rmse_sigma:.3g} "
          f"confirm_rmse_sigma={chk.rmse_sigma:.3g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
