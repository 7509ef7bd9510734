"""Diagnose the committed twin files of four blind batches with and without the shrinkage
of the bridge's probe correction (NOSHRINK=1), at the LAMMPS batch's frozen commit
4dc8653 patched as in shrinkage.patch; writes one JSON of answers per setting."""
import json, os, sys, statistics
from pathlib import Path
from bedstruct.diagnose.validation.blind import _benchmark_bridge, _emulator, diagnose_file
from bedstruct.diagnose.validation.blind_twins import benchmark_design
RECORDS = Path(sys.argv[1])
out = {}
for folder in ("blind-liggghts-protocol4-2026-12-06", "blind-liggghts-replicate-2026-12-06",
               "blind-lammps-2026-12-06", "blind-liggghts-replicate2-2026-12-06"):
    here = RECORDS / folder
    truth = json.loads((here / "truth.json").read_text())
    sim = truth["settings"]["sim"]
    design = benchmark_design(truth["settings"]["twins_engine"])
    emu = _emulator(sim, None, design, here / "library", 1, None, False)
    bridge = _benchmark_bridge(sim, None, design, emu, here / "library", False, 1)
    rows = {}
    for t in sorted(truth["twins"]):
        tr = truth["twins"][t]
        r = diagnose_file(here / "twins" / f"{t}.toml", sim, emulator=emu, bridge=bridge)
        rows[t] = {"kind": tr["kind"], "truth": tr.get("effect") or tr.get("change"),
                   "truth_magnitude": tr["magnitude"], "answer": r["answer"],
                   "partial": r["partial"], "magnitude": r["magnitude"],
                   "interval": r["interval"], "shrink": r["shrink"]}
    out[folder] = rows
print(json.dumps({"shrink_probe_correction": not os.environ.get("NOSHRINK"), "batches": out}))
