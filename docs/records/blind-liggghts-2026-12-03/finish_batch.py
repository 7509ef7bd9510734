"""Finish the frozen LIGGGHTS blind batch with the frozen code (PYTHONPATH=/work/blind).

The frozen `run_benchmark` stops at the first twin whose diagnosis raises. This driver makes
exactly the frozen calls for every twin still without a result (the same `diagnose_file`,
simulation config, library emulator and record), and records a twin whose diagnosis raises
as an answer of its own, `error`, with the message, instead of stopping. Then it scores with
the frozen `score_benchmark` and writes summary.json as the frozen run would.
"""
import json
import sys
import time
from pathlib import Path

from bedstruct._json import write_json_atomic
from bedstruct.diagnose import blind
from bedstruct.diagnose.blind_twins import benchmark_design, draw_twins

OUT = Path("/work/blind-run/liggghts-tiny-n40")
SIM = "data/measurements/blind-engine-tiny.sim.toml"
LIB = "/work/blind-run/lib"

truth = json.loads((OUT / "truth.json").read_text())
seal = json.loads((OUT / "seal.json").read_text())
assert seal["truth_sha256"] == blind._sha256(OUT / "truth.json")
specs = draw_twins(40, 20261203, "liggghts")
assert [s.twin for s in specs] == sorted(truth["twins"])
rdir = OUT / "results"
emulator = None
for s in specs:
    rp = rdir / f"{s.twin}.json"
    if rp.exists():
        continue
    assert blind._sha256(OUT / "twins" / f"{s.twin}.toml") == seal["twins_sha256"][s.twin]
    if emulator is None:
        emulator = blind._emulator(SIM, None, benchmark_design("liggghts"), LIB, 2, None, False)
    t0 = time.perf_counter()
    try:
        rec = blind.diagnose_file(OUT / "twins" / f"{s.twin}.toml", SIM, settings=None,
                                  emulator=emulator)
    except Exception as exc:   # the frozen method gave no answer on this twin
        rec = {"twin": s.twin, "answer": "error", "verdict": "error", "effects": [],
               "magnitude": None, "interval": None, "shrink": None,
               "p_heldout_before": None, "n_heldout": 0, "shrink_measured": False,
               "reason": f"{type(exc).__name__}: {exc}", "simulator": None,
               "seconds": round(time.perf_counter() - t0, 2)}
    rec["twin_sha256"] = seal["twins_sha256"][s.twin]
    write_json_atomic(rp, rec)
    print(f"{s.twin}: {rec['answer']} ({rec['seconds']:.0f} s)", flush=True)
results = {p.stem: json.loads(p.read_text()) for p in sorted(rdir.glob("*.json"))}
summary = blind.score_benchmark(truth, results)
summary["truth_sha256"] = seal["truth_sha256"]
summary["sealed_at"] = seal["sealed_at"]
summary["out"] = str(OUT)
summary["errors"] = sorted(t for t, r in results.items() if r["verdict"] == "error")
write_json_atomic(OUT / "summary.json", summary)
print("summary written", file=sys.stderr)
