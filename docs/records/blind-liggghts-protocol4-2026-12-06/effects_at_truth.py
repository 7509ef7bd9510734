"""The tenth batch's effect twins against the bridged model at their true magnitude.

Run from a checkout of the batch's frozen commit, after scoring (an analysis of the
answers, not part of the blind score):

    cd /tmp/frozen10 && PYTHONPATH=/tmp/frozen10 python \
        /work/main/docs/records/blind-liggghts-protocol4-2026-12-06/effects_at_truth.py OUT.json

The diagnosing model is read as the diagnosis reads it: the emulator of the batch's run
library and the LIGGGHTS bridge. For each effect twin and each observable component:

- ``measured``: the twin's value in the embedded engine's frame (LIGGGHTS' baseline offset
  taken off, as the diagnosis does: ``EngineBridge.apply``);
- ``model``: the emulator's mean at the twin's true magnitude and cohesion plus the bridge's
  shift for that effect (its response in LIGGGHTS), no noise drawn;
- ``z``: their difference over the file's stated uncertainty with the bridge's offset and
  shift uncertainties (the diagnosis also counts the run scatter of its simulated mean);
- ``emulator_sd``: the emulator's uncertainty of its own mean there.

``chi2`` sums ``z**2`` over the calibration and over the held-out components (with their
count and the chi-square p-value): how well the model fits the twin even at its truth.
``library_readings`` gives, per effect and observable, how many of the library's runs with
that effect on read it, and at which magnitudes.
"""
import json
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from bedstruct.diagnose.measurement_io import load_measurements
from bedstruct.diagnose.validation.blind import _benchmark_bridge, _emulator, _sim_config
from bedstruct.diagnose.validation.blind_twins import benchmark_design

HERE = Path(__file__).resolve().parent


def _round(a, nd=3):
    return [round(float(x), nd) for x in np.atleast_1d(a)]


def main(out: str) -> None:
    doc_truth = json.loads((HERE / "truth.json").read_text())
    truth = doc_truth["twins"]
    sim = doc_truth["settings"]["sim"]
    design = benchmark_design("liggghts")
    emu = _emulator(sim, None, design, HERE / "library", 1, None, False)
    bridge = _benchmark_bridge(sim, None, design, emu, HERE / "library", False, 1)
    cfg = _sim_config(sim, None)
    runs = [json.loads(p.read_text()) for p in sorted((HERE / "library" / "runs").glob("*.json"))]
    effects = sorted({s["effect"] for s in truth.values() if s.get("kind") == "effect"})
    readings = {}
    for e in effects:
        on = [r for r in runs if r["effects"].get(e, 0.0) > 0.0]
        readings[e] = {}
        for name in emu.names:
            read = [r["effects"][e] for r in on
                    if np.all(np.isfinite(np.asarray(r["observations"][name], float)))]
            if len(read) < len(on):
                readings[e][name] = {"runs": len(on), "read": len(read),
                                     "magnitudes_read": sorted({round(a, 4) for a in read})}
    doc = {"what": "each effect twin against the bridged model at its true magnitude and "
                   "cohesion (see effects_at_truth.py)",
           "library_readings": readings, "twins": {}}
    twins = sorted((t for t, s in truth.items() if s.get("kind") == "effect"),
                   key=lambda t: (truth[t]["effect"], truth[t]["magnitude"]))
    for t in twins:
        spec = truth[t]
        base = dict(cfg.base)
        base["cohesion_energy_density"] *= spec["cohesion_factor"]
        on = {spec["effect"]: spec["magnitude"]}
        p = emu.predict(base, on)
        mean, sd = emu.by_observable(p.mean), emu.by_observable(p.sd)
        shift, shift_sd = bridge.correction(on)
        ms = bridge.apply(load_measurements(HERE / "twins" / f"{t}.toml", check_range=False))
        res = json.loads((HERE / "results" / f"{t}.json").read_text())
        rows, chi = {}, {"calibrate": [0.0, 0], "validate": [0.0, 0]}
        for m in ms:
            if m.role not in chi:
                continue
            y = np.atleast_1d(np.asarray(m.values, float))
            model = mean[m.name] + shift.get(m.name, 0.0)
            s_known = np.sqrt(np.asarray(m.uncertainty, float) ** 2
                              + np.asarray(shift_sd.get(m.name, 0.0)) ** 2)
            z = (y - model) / s_known
            rows[m.name] = {"role": m.role, "measured": _round(y), "model": _round(model),
                            "z": _round(z, 2), "emulator_sd": _round(sd[m.name])}
            ok = np.isfinite(z)
            chi[m.role][0] += float(np.sum(z[ok] ** 2))
            chi[m.role][1] += int(ok.sum())
        fit = {role: {"chi2": round(c, 2), "n": k,
                      "p": float(stats.chi2.sf(c, k)) if k else None}
               for role, (c, k) in chi.items()}
        doc["twins"][t] = {"effect": spec["effect"], "magnitude": spec["magnitude"],
                           "answer": res["answer"], "partial": res["partial"],
                           "chi2": fit, "observables": rows}
        worst = sorted(((abs(c), k) for k, e in rows.items() for c in e["z"]), reverse=True)[:2]
        print(t, spec["effect"], round(spec["magnitude"], 3), res["answer"],
              f"p_cal={fit['calibrate']['p']:.2g} p_val={fit['validate']['p']:.2g}",
              [(k, round(c, 1)) for c, k in worst])
    Path(out).write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
