"""Visibility scan of out-of-catalogue changes on LIGGGHTS twins (protocol calibration)."""
import json, sys
from pathlib import Path
from bedstruct.diagnose.blind import _emulator, _benchmark_bridge, _make_twin, diagnose_file
from bedstruct.diagnose.blind_twins import TwinSpec, benchmark_design
from concurrent.futures import ProcessPoolExecutor

SIM = "data/measurements/blind-engine-tiny-probed.sim.toml"
LIB = sys.argv[1]
OUT = Path(sys.argv[2])
POINTS = [("rolling_friction", 3.0), ("rolling_friction", 2.7), ("youngs_modulus", 0.1),
          ("youngs_modulus", 0.28), ("sliding_friction", 0.5), ("sliding_friction", 0.65),
          ("blade_bevel", 0.45), ("blade_bevel", 1.7)]
specs = [TwinSpec(f"scan-{i:02d}", "out_of_catalogue", c, m, 1.0, 900001 + i)
         for i, (c, m) in enumerate(POINTS)]
(OUT / "twins").mkdir(parents=True, exist_ok=True)
todo = [s for s in specs if not (OUT / "twins" / f"{s.twin}.toml").exists()]
with ProcessPoolExecutor(2) as pool:
    for f in [pool.submit(_make_twin, s, "liggghts", "tiny", OUT) for s in todo]:
        f.result()
em = _emulator(SIM, None, benchmark_design("liggghts"), LIB, 2, None, False)
br = _benchmark_bridge(SIM, None, benchmark_design("liggghts"), em, LIB, False)
rows = []
for s in specs:
    r = diagnose_file(OUT / "twins" / f"{s.twin}.toml", SIM, emulator=em, bridge=br)
    rows.append({"change": s.name, "magnitude": s.magnitude, "seed": s.seed,
                 "p_gap": r["p_gap"], "gap_significant": r["gap_significant"], "answer": r["answer"]})
    print(rows[-1], flush=True)
(OUT / "scan.json").write_text(json.dumps(rows, indent=1))
