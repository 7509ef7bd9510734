"""The ninth batch's missing-fines twins against the bridged model at their true magnitude.

Run from a checkout of the batch's frozen commit, after scoring (an analysis of the misses,
not part of the blind score):

    cd /tmp/frozen && PYTHONPATH=/tmp/frozen python \
        /work/main/docs/records/blind-liggghts-heldout-2026-12-06/fines_at_truth.py OUT.json

For each missing-fines twin, the bridged emulator (the batch's run library and LIGGGHTS
bridge, as the diagnosis reads them) is evaluated at the twin's true fraction and true
cohesion, and each observable's departure from the twin's measured value is written in units
of the twin's stated uncertainty: what the diagnosis could not fit even at the truth.
"""
import json
import sys
from pathlib import Path

import numpy as np

from bedstruct.diagnose.emulator import EmulatedSimulator
from bedstruct.diagnose.measurement_io import load_measurements
from bedstruct.diagnose.validation.blind import _benchmark_bridge, _emulator, _sim_config
from bedstruct.diagnose.validation.blind_twins import benchmark_design

HERE = Path(__file__).resolve().parent
SIM = "data/measurements/blind-engine-tiny-probed2.sim.toml"


def main(out: str) -> None:
    truth = json.loads((HERE / "truth.json").read_text())["twins"]
    design = benchmark_design("liggghts")
    emu = _emulator(SIM, None, design, HERE / "library", 1, None, False)
    bridge = _benchmark_bridge(SIM, None, design, emu, HERE / "library", False, 1)
    cfg = _sim_config(SIM, None)
    model = bridge.simulator(EmulatedSimulator(emu))
    doc = {"what": "z = (measured - bridged model at the true fraction and cohesion) / stated "
                   "uncertainty, per observable component, for each missing-fines twin",
           "twins": {}}
    fines = sorted((t for t, s in truth.items() if s.get("effect") == "missing_fines"),
                   key=lambda t: truth[t]["magnitude"])
    for t in fines:
        spec = truth[t]
        base = dict(cfg.base)
        base["cohesion_energy_density"] *= spec["cohesion_factor"]
        pred = model(base, {"missing_fines": spec["magnitude"]}, 0)
        ms = load_measurements(HERE / "twins" / f"{t}.toml", check_range=False)
        res = json.loads((HERE / "results" / f"{t}.json").read_text())
        z = {}
        for m in ms:
            v = np.atleast_1d(np.asarray(m.values, float))
            p = np.atleast_1d(np.asarray(pred[m.name], float))
            u = np.atleast_1d(np.asarray(m.uncertainty, float))
            z[m.name] = {"role": m.role, "z": [round(float(x), 2) for x in (v - p) / u]}
        doc["twins"][t] = {"magnitude": spec["magnitude"], "answer": res["answer"],
                           "partial": res["partial"], "z": z}
        worst = sorted(((abs(c), k) for k, e in z.items() for c in e["z"]), reverse=True)[:3]
        print(t, round(spec["magnitude"], 3), res["answer"], [(k, round(c, 1)) for c, k in worst])
    Path(out).write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
