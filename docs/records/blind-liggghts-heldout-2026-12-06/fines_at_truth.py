"""The ninth batch's missing-fines twins against the bridged model at their true magnitude.

Run from a checkout of the batch's frozen commit, after scoring (an analysis of the misses,
not part of the blind score):

    cd /tmp/frozen && PYTHONPATH=/tmp/frozen python \
        /work/main/docs/records/blind-liggghts-heldout-2026-12-06/fines_at_truth.py OUT.json

The diagnosing model is read as the diagnosis reads it: the emulator of the batch's run
library and the LIGGGHTS bridge. For each missing-fines twin and each observable component:

- ``measured``: the twin's value in the embedded engine's frame (LIGGGHTS' baseline offset
  taken off, as the diagnosis does: ``EngineBridge.apply``);
- ``model``: the emulator's mean at the twin's true fraction and cohesion plus the bridge's
  shift for missing fines (its response in LIGGGHTS), no noise drawn;
- ``z``: their difference over the file's stated uncertainty with the bridge's offset and
  shift uncertainties (the diagnosis also counts the run scatter of its simulated mean);
- ``emulator_sd``: the emulator's uncertainty of its own mean there, which the diagnosis does
  not count, and ``z_with_emulator_sd``: the difference with it counted.

``library_readings`` gives, per observable, how many of the library's runs with missing fines
on read it, and ``run_sd_base`` one run's scatter at the base point (the emulator's noise).
"""
import json
import sys
from pathlib import Path

import numpy as np

from bedstruct.diagnose.measurement_io import load_measurements
from bedstruct.diagnose.validation.blind import _benchmark_bridge, _emulator, _sim_config
from bedstruct.diagnose.validation.blind_twins import benchmark_design

HERE = Path(__file__).resolve().parent
SIM = "data/measurements/blind-engine-tiny-probed2.sim.toml"


def _round(a, nd=3):
    return [round(float(x), nd) for x in np.atleast_1d(a)]


def main(out: str) -> None:
    truth = json.loads((HERE / "truth.json").read_text())["twins"]
    design = benchmark_design("liggghts")
    emu = _emulator(SIM, None, design, HERE / "library", 1, None, False)
    bridge = _benchmark_bridge(SIM, None, design, emu, HERE / "library", False, 1)
    cfg = _sim_config(SIM, None)
    p0 = emu.predict(dict(cfg.base), {})
    run_sd = emu.by_observable(p0.noise_sd)
    runs = [json.loads(p.read_text()) for p in sorted((HERE / "library" / "runs").glob("*.json"))]
    fines_runs = [r for r in runs if r["effects"].get("missing_fines", 0.0) > 0.0]
    readings = {}
    for name in emu.names:
        read = [r["effects"]["missing_fines"] for r in fines_runs
                if np.all(np.isfinite(np.asarray(r["observations"][name], float)))]
        readings[name] = {"runs": len(fines_runs), "read": len(read),
                          "fractions_read": sorted({round(a, 4) for a in read})}
    doc = {"what": "each missing-fines twin against the bridged model at its true fraction and "
                   "cohesion (see fines_at_truth.py)",
           "library_readings": readings,
           "run_sd_base": {k: _round(v) for k, v in run_sd.items()},
           "twins": {}}
    fines = sorted((t for t, s in truth.items() if s.get("effect") == "missing_fines"),
                   key=lambda t: truth[t]["magnitude"])
    for t in fines:
        spec = truth[t]
        base = dict(cfg.base)
        base["cohesion_energy_density"] *= spec["cohesion_factor"]
        effects = {"missing_fines": spec["magnitude"]}
        p = emu.predict(base, effects)
        mean, sd = emu.by_observable(p.mean), emu.by_observable(p.sd)
        shift, shift_sd = bridge.correction(effects)
        ms = bridge.apply(load_measurements(HERE / "twins" / f"{t}.toml", check_range=False))
        res = json.loads((HERE / "results" / f"{t}.json").read_text())
        rows = {}
        for m in ms:
            y = np.atleast_1d(np.asarray(m.values, float))
            model = mean[m.name] + shift.get(m.name, 0.0)
            s_known = np.sqrt(np.asarray(m.uncertainty, float) ** 2
                              + np.asarray(shift_sd.get(m.name, 0.0)) ** 2)
            rows[m.name] = {"role": m.role, "measured": _round(y), "model": _round(model),
                            "z": _round((y - model) / s_known, 2),
                            "emulator_sd": _round(sd[m.name]),
                            "z_with_emulator_sd": _round((y - model)
                                                         / np.hypot(s_known, sd[m.name]), 2)}
        doc["twins"][t] = {"magnitude": spec["magnitude"], "answer": res["answer"],
                           "partial": res["partial"], "observables": rows}
        worst = sorted(((abs(c), k) for k, e in rows.items() for c in e["z"]), reverse=True)[:2]
        print(t, round(spec["magnitude"], 3), res["answer"], [(k, round(c, 1)) for c, k in worst])
    Path(out).write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
